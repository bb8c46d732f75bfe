"""What every ``tippetop`` command shares: the parser, exit statuses, JSON output, options.

An option that several commands take is declared here once (its name, dest, type, default and
help), asv-style: a command calls ``add_..._option(parser)``, in the place of its help listing
where the option should appear, and passes its own ``help`` only where its wording differs.

This module imports only the standard library, :mod:`tippetop.models.errors` and
:mod:`tippetop.compare.running.interrupt` (standard library only), so building the command line
stays cheap.
"""

from __future__ import annotations

import argparse
import errno
import json
import math
import os
import sys
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NoReturn

from tippetop.compare.running.interrupt import EXIT_BOUND_S
from tippetop.models.errors import RunFailedError, TippetopError, did_you_mean

if TYPE_CHECKING:
    from tippetop.models.scene import Override

EXIT_OK = 0
EXIT_RUN_FAILED = 1  # a run that diverged or stopped short: reported, never as numbers
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # Ctrl-C: one line, the runs going are stopped
EXIT_TERMINATED = 143  # SIGTERM: as Ctrl-C (128 + the signal's number, as a shell says it)

#: Every exit status of ``tippetop`` and what it means (``tippetop --help`` lists them).
EXIT_STATUSES: dict[int, str] = {
    EXIT_OK: "done: the run finished, the nightly found no regression, validate agrees",
    EXIT_RUN_FAILED: "a run failed (diverged or stopped short; one line says why), stdout "
                     "could not be written, the nightly found a regression, or a validate "
                     "check departs",
    EXIT_BAD_INPUT: "bad input: one line on stderr, nothing written",
    EXIT_INTERRUPTED: "interrupted (Ctrl-C): the runs going are stopped, nothing "
                      f"half-written, the process gone within {EXIT_BOUND_S:g} s",
    EXIT_TERMINATED: "stopped by SIGTERM: as 130",
}

#: Help of the shared options, where every command words them the same.
SCHEDULER_HELP = "tcp://HOST:PORT of a Dask scheduler to run on (default: local processes)"
WORKERS_HELP = "local worker processes (default: all cores)"
NO_CACHE_HELP = ("neither read nor write the run cache ($TIPPETOP_CACHE; default: reuse runs "
                 "already made with the same physics and code)")
FORCE_HELP = "overwrite an existing --out file"
SET_HELP = ("override a scene key, e.g. init.n0=60 or run.t_end_s=4; units as the key's name "
            "says (_s seconds, _m metres, n0 rad/s); repeatable (default: the scene as written)")
JSON_HELP = "print one JSON object on stdout instead of text (the keys are a contract)"


class HelpFormatter(argparse.HelpFormatter):
    """Help at the terminal's width (at most 100 columns), the options' help beside them."""

    def __init__(self, prog: str) -> None:
        import shutil

        width = max(60, min(100, shutil.get_terminal_size((100, 24)).columns) - 2)
        super().__init__(prog, max_help_position=30, width=width)


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit 2, and help as wide as the terminal."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        """Check a value against the option's ``choices`` (a command's name too), as argparse.

        The error names the choice meant when one is close: ``invalid choice: 'simulat' (did
        you mean 'simulate'?) (choose from ...)``.
        """
        try:
            super()._check_value(action, value)
        except argparse.ArgumentError as exc:
            hint = did_you_mean(value, action.choices or ()) if isinstance(value, str) else ""
            given = repr(value)
            if not hint or given not in exc.message:
                raise
            raise argparse.ArgumentError(action, exc.message.replace(given, given + hint, 1)) \
                from None

    def error(self, message: str) -> NoReturn:
        """Write ``tippetop: error: MESSAGE (see 'PROG --help')`` and exit 2."""
        sys.stderr.write(f"tippetop: error: {message} (see '{self.prog} --help')\n")
        raise SystemExit(EXIT_BAD_INPUT)


_SHOWN: set[str] = set()


def _one_line_warning(message: Warning | str, category: type[Warning], filename: str,
                      lineno: int, file: Any = None, line: str | None = None) -> None:
    """Show a warning as ``tippetop: warning: ...`` on one line (no source line)."""
    text = " ".join(str(message).split())
    if text in _SHOWN:
        return
    _SHOWN.add(text)
    sys.stderr.write(f"tippetop: warning: {text}\n")


class StdoutFailedError(Exception):
    """Writing to stdout failed (a closed pipe, a full disk, a closed descriptor)."""


class _GuardedStdout:
    """``sys.stdout`` whose failed writes raise :class:`StdoutFailedError` (one line, exit 1).

    Without it a full disk (``> /dev/full``) ends in an ``OSError`` traceback, and a reader
    that went away (``| head -c 10``) in a ``BrokenPipeError``.
    """

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def _guard(self, method: str, *a: Any) -> Any:
        if self._stream is None:
            raise StdoutFailedError("stdout is closed")
        try:
            return getattr(self._stream, method)(*a)
        except (OSError, ValueError) as exc:  # ValueError: a closed file
            raise StdoutFailedError(getattr(exc, "strerror", None) or str(exc)) from None

    def write(self, text: str) -> int:
        """Write ``text``; a failure raises :class:`StdoutFailedError`."""
        return self._guard("write", text)

    def flush(self) -> None:
        """Flush; a failure raises :class:`StdoutFailedError`."""
        self._guard("flush")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _silence_stdout(stream: Any) -> None:
    """Point a failed stdout at /dev/null, so the flush at exit cannot fail a second time."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, stream.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass


def run_command(args: argparse.Namespace) -> int:
    """Call the parsed command's ``func``; bad input becomes one line on stderr and exit 2.

    A failed run (:class:`RunFailedError`) becomes one ``tippetop: run failed:`` line and
    exit 1; so does stdout that cannot be written (``tippetop: failed: ...``: a closed pipe,
    a full disk).

    Warnings (a model that departs from the paper's top, say) are one line each, shown once.
    """
    func: Callable[[argparse.Namespace], int] = args.func
    with warnings.catch_warnings():
        # ours (and libraries' user-facing ones) once each; Python's ResourceWarning and
        # DeprecationWarning stay at their defaults (hidden): they are not the user's business
        warnings.simplefilter("once", UserWarning)
        warnings.showwarning = _one_line_warning
        real_stdout = sys.stdout
        sys.stdout = _GuardedStdout(real_stdout)
        try:
            status = func(args)
            sys.stdout.flush()  # a full disk may say so only here
            return status
        except TippetopError as exc:
            sys.stderr.write(f"tippetop: error: {exc}\n")
            return EXIT_BAD_INPUT
        except RunFailedError as exc:
            sys.stderr.write(f"tippetop: run failed: {exc}\n")
            return EXIT_RUN_FAILED
        except StdoutFailedError as exc:
            _silence_stdout(real_stdout)
            sys.stderr.write(f"tippetop: failed: could not write the output to stdout "
                             f"({exc})\n")
            return EXIT_RUN_FAILED
        except OSError as exc:
            if exc.errno not in _WRITE_ERRNOS:
                raise
            where = f" {exc.filename}" if exc.filename else ""
            sys.stderr.write(f"tippetop: failed: could not write{where} ({exc.strerror}); "
                             f"no partial file was left\n")
            return EXIT_RUN_FAILED
        finally:
            sys.stdout = real_stdout


#: Errors of a write that the disk or the system refused (full, read-only, no permission,
#: over quota, too large): one line and exit 1, not a traceback. Outputs are written
#: atomically, so none is left half-written.
_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                 errno.EIO, errno.EFBIG}


def run_main(args: argparse.Namespace) -> int:
    """An entry point's run: Ctrl-C as one line and exit 130, SIGTERM the same with 143.

    Once interrupted, the process ends within :data:`~tippetop.compare.running.interrupt.
    EXIT_BOUND_S` whatever its exit waits on, and at once on a second signal.
    """
    from tippetop.compare.running.interrupt import (
        Terminated,
        exit_at_next_signal,
        install_sigterm_handler,
        outputs_complete,
    )

    install_sigterm_handler()  # SIGTERM stops the runs as Ctrl-C does, and exits 143
    try:
        status = run_command(args)
        outputs_complete()  # the work is done: no interrupt in the interpreter's exit
        return status
    except KeyboardInterrupt as exc:
        status = EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED
        # the runs are stopped: a signal from here on ends the process at once, and the
        # interpreter's exit may take EXIT_BOUND_S at most
        exit_at_next_signal(status)
        sys.stderr.write("tippetop: interrupted\n" if status == EXIT_INTERRUPTED
                         else "tippetop: stopped by SIGTERM\n")
        return status
    except BrokenPipeError:  # e.g. piped into head
        sys.stderr.close()
        return EXIT_OK


# ---------------------------------------------------------------- types
def number(text: str) -> float:
    """An argparse type: any float (the command checks the range, NaN included)."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def finite_float(text: str) -> float:
    """An argparse type: a finite float."""
    v = number(text)
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def comma_list(text: str) -> tuple[str, ...]:
    """The non-empty, stripped items of a comma-separated option value (``--engines``)."""
    return tuple(s.strip() for s in text.split(",") if s.strip())


def worker_count(text: str) -> int:
    """An argparse type: an integer >= 1 (the one check of ``--workers``)."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return n


def scheduler_address(text: str) -> str:
    """An argparse type: ``tcp://HOST:PORT`` (or ``tls://``), the port an integer 1-65535.

    Checked as the option is read, before any work: a bad port would otherwise surface deep
    in Dask as a traceback (``notaport``) or after a 10-s connection timeout (``99999``).
    """
    scheme, sep, rest = text.partition("://")
    host, colon, port = rest.rpartition(":")
    ok = (sep and scheme in ("tcp", "tls") and colon and host.strip("[]")
          and port.isascii() and port.isdigit() and 1 <= int(port) <= 65535)
    if not ok:
        raise argparse.ArgumentTypeError(
            f"expected tcp://HOST:PORT with a port from 1 to 65535, got {text!r}")
    return text


def engine_spec(text: str) -> str:
    """An argparse type: an engine (``--engine``, ``--on``), checked as the option is read.

    A compound name of the release before (``mujoco-native``) passes: :func:`engine_and_mode`
    reads it as its engine and mode and says the new spelling.
    """
    from tippetop.models.engines import NAMED, parse_engine
    from tippetop.models.errors import closest_name
    from tippetop.models.modes import MODES
    from tippetop.models.spellings import OLD_NAMES, new_spelling, old_spelling

    if old_spelling(text) is not None:
        return text.strip()
    try:
        return parse_engine(text).spec
    except TippetopError as exc:
        msg = str(exc).removeprefix("engine: ")
        name = text.strip()
        if name in MODES:
            msg += f", which is a mode: give --mode {name}"
        else:  # closer to a compound name of the release before: today's spelling of it
            from difflib import SequenceMatcher

            old = closest_name(name, [n for n in OLD_NAMES if n not in NAMED])
            now = closest_name(name, NAMED)

            def ratio(other: str | None) -> float:
                return SequenceMatcher(None, name, other).ratio() if other else 0.0

            if old is not None and ratio(old) > ratio(now):
                msg = msg.split(" (did you mean")[0] + f" (did you mean {new_spelling(old)}?)"
        raise argparse.ArgumentTypeError(msg) from None


def mode_name(text: str) -> str:
    """An argparse type: a mode (``--mode``), checked as the option is read."""
    from tippetop.models.engines import NAMED
    from tippetop.models.modes import MODES

    name = text.strip()
    if name in MODES:
        return name
    hint = (f", which is an engine: give --engine {name}" if name in NAMED
            else did_you_mean(name, MODES))
    raise argparse.ArgumentTypeError(f"expected a mode ({', '.join(MODES)}), got "
                                     f"{text!r}{hint}")


#: ``--engine``'s help: what each engine is.
ENGINE_HELP = ("the engine that integrates the run: ode (the reference), mujoco (the MuJoCo "
               "installed with tippetop), mujoco==X.Y.Z (a release, in an environment made "
               "with uv on first use), mujoco@PYTHON (the mujoco that interpreter imports: a "
               "path, or a command on PATH), mjx, mjx-f32 (MuJoCo MJX, float64 and float32) or "
               "warp (MuJoCo Warp)")
#: ``--mode``'s help: what each mode is (``tippetop --help`` lists them).
MODE_HELP = ("the mode, how the contact force is made: paper (the paper's law, every engine), "
             "native, native-pyramidal, native-elliptic, native-condim4, native-condim6 "
             "(MuJoCo's own contact, calibrated), file (MuJoCo's own contact as the model file "
             "sets it), coulomb, viscous, coulomb_viscous (the reference's other laws)")


def add_engine_option(p: argparse.ArgumentParser, *, default: str = "ode",
                      help: str = ENGINE_HELP) -> None:
    """``--engine ENGINE`` (dest ``engine``, None when not given: ``default`` is said only).

    With ``--on``, the release before's spelling of ``--engine`` for a MuJoCo engine, hidden
    from the help and read by :func:`engine_and_mode` with a note.
    """
    p.add_argument("--engine", type=engine_spec, metavar="ENGINE",
                   help=f"{help} (default {default})")
    p.add_argument("--on", type=engine_spec, metavar="ENGINE", help=argparse.SUPPRESS)


def add_mode_option(p: argparse.ArgumentParser, *, default: str = "what the scene says: "
                    "paper, or file for an MJCF top on MuJoCo", help: str = MODE_HELP) -> None:
    """``--mode MODE`` (dest ``mode``, None when not given: the scene's)."""
    p.add_argument("--mode", type=mode_name, metavar="MODE", help=f"{help} (default: "
                   f"{default})")


def engine_and_mode(args: argparse.Namespace, default: str = "ode"
                    ) -> tuple[Any, str | None, tuple[str, ...]]:
    """The engine and mode a command runs in, from ``--engine`` and ``--mode``.

    The release before's spellings are read for one more release, each with one line on
    stderr giving the new one: a compound name (``--engine mujoco-native``), and ``--on
    SPEC`` for a MuJoCo engine.

    Returns:
        The engine (:class:`~tippetop.models.engines.EngineSpec`), the mode (None: the
        scene's) and the scene keys an old compound name also set (``ode-paper-form``'s
        formulation).

    Raises:
        TippetopError: Both spellings at once, the reference on another engine, or a mode
            the engine cannot run (one line).
    """
    from tippetop.models.engines import parse_engine
    from tippetop.models.modes import check_pair
    from tippetop.models.spellings import OLD_OPTIONS, new_spelling, note_old, old_spelling

    engine = getattr(args, "engine", None)
    mode = getattr(args, "mode", None)
    on = getattr(args, "on", None)
    extra: tuple[str, ...] = ()
    old = old_spelling(engine) if engine else None
    if old is not None and engine not in ("ode", "mujoco"):
        if mode is not None:
            raise TippetopError(f"--engine: expected an engine beside --mode {mode}, got "
                                f"{engine!r}, which names an engine and a mode: "
                                f"{new_spelling(engine)}")
        note_old(f"--engine {engine}", new_spelling(engine))
        engine, mode, extra = old
    if on is not None:
        if old_spelling(on) is not None and on not in ("ode", "mujoco"):
            raise TippetopError(f"--on: expected an engine, got {on!r}")
        note_old(f"--on {on}", f"{OLD_OPTIONS['--on']} {on}")
        if engine not in (None, "mujoco"):
            if parse_engine(engine).is_reference:
                raise TippetopError(f"--on: expected a MuJoCo run to go on {on}, got the "
                                    "reference ODE (--engine ode)")
            raise TippetopError(f"--on: expected --engine once, got --engine {engine} and "
                                f"--on {on}: give --engine {on}")
        if parse_engine(on).is_reference:
            raise TippetopError("--on: expected a MuJoCo engine, got 'ode'")
        engine = on
    spec = parse_engine(engine or default)
    if mode is not None:
        check_pair(spec.family, mode, spec.spec)
    return spec, mode, extra


def engines_and_modes(args: argparse.Namespace, *, engines: str, modes: str,
                      old_option: str = "--modes") -> list[tuple[str, str | None,
                                                                   tuple[str, ...]]]:
    """The runs of ``--engines`` x ``--modes`` that can run: (engine, mode, extra keys).

    A list of the release before's compound names in ``old_option`` (``compare --modes
    ode,mujoco-native``, ``atlas --engines ode,mujoco-paper``) is read as its runs, with one
    line on stderr giving the new spelling.

    Args:
        args: The parsed options (``engines`` and ``modes``, None when not given).
        engines: The default ``--engines``.
        modes: The default ``--modes``.
        old_option: The option that took compound names before.

    Raises:
        TippetopError: A bad engine or mode, a mode none of the engines runs, or an engine
            that runs none of the modes (one line).
    """
    from tippetop.models.engines import parse_engines
    from tippetop.models.modes import MODES, pairs, parse_modes, read_old_list

    given = getattr(args, "modes" if old_option == "--modes" else "engines", None)
    if given:
        old = read_old_list(given.split(","), old_option)
        if old is not None:
            other = getattr(args, "engines" if old_option == "--modes" else "modes", None)
            if other:
                raise TippetopError(f"{old_option}: expected engines and modes apart, got "
                                    f"compound names beside --"
                                    f"{'engines' if old_option == '--modes' else 'modes'}")
            return old
    given_engines, given_modes = getattr(args, "engines", None), getattr(args, "modes", None)
    specs = parse_engines(given_engines or engines)
    names = parse_modes(given_modes or modes)
    # a default that cannot pair with what was given is left out, not an error: --engines ode
    # runs the reference's modes of the default ones, --modes coulomb the engines that can
    if not given_modes:
        names = [m for m in names if any(e.family in MODES[m].families for e in specs)] or names
    if not given_engines:
        specs = [e for e in specs if any(e.family in MODES[m].families for m in names)] or specs
    return [(e, m, ()) for e, m in pairs(specs, names)]


# ---------------------------------------------------------------- input
def load_scene(args: argparse.Namespace) -> Any:
    """The scene a command names: ``args.scene`` with ``--set``, ``--mjcf`` and ``--keyframe``.

    A relative ``--mjcf`` path is relative to the working folder, not to the scene file.

    Returns:
        The validated :class:`tippetop.models.scene.Scene`.
    """
    from tippetop.models.scene import Override
    from tippetop.models.scene import load_scene as load

    overrides = list(set_overrides(args))
    if getattr(args, "mjcf", None):
        # relative to the working folder, not to the scene file
        overrides.append(Override.of("top.mjcf", os.path.abspath(args.mjcf)))
    if getattr(args, "keyframe", None):
        overrides.append(Override.of("init.keyframe", args.keyframe))
    return load(args.scene, overrides)


def set_overrides(args: argparse.Namespace) -> tuple[Override, ...]:
    """``--set`` text, parsed once, here, into values.

    Returns:
        The :class:`tippetop.models.scene.Override` of each ``--set``, in order: what the
        studies pass down.
    """
    from tippetop.models.scene import Override

    return tuple(Override.parse(item) for item in (args.set or []))


# ---------------------------------------------------------------- output
def json_text(obj: Any, indent: int | None = None) -> str:
    """One JSON object as text: NaN and inf as null, numpy scalars as numbers."""
    from tippetop.compare.running.io import json_ready

    return json.dumps(json_ready(obj), indent=indent)


def print_json(obj: Any) -> None:
    """Print one JSON object on stdout."""
    print(json_text(obj))


# ---------------------------------------------------------------- options
def add_scheduler_option(p: argparse.ArgumentParser) -> None:
    """``--scheduler ADDRESS`` (dest ``scheduler``, default None: local processes)."""
    p.add_argument("--scheduler", type=scheduler_address, metavar="ADDRESS",
                   help=SCHEDULER_HELP)


def add_workers_option(p: argparse.ArgumentParser, help: str = WORKERS_HELP) -> None:
    """``--workers N`` (dest ``workers``, default None: all cores), checked to be >= 1."""
    p.add_argument("--workers", type=worker_count, metavar="N", help=help)


def add_parallel_options(p: argparse.ArgumentParser, *, no_cache: bool = True) -> None:
    """``--scheduler``, ``--workers`` and (unless ``no_cache=False``) ``--no-cache``."""
    add_scheduler_option(p)
    add_workers_option(p)
    if no_cache:
        p.add_argument("--no-cache", action="store_true", help=NO_CACHE_HELP)


def add_set_option(p: argparse.ArgumentParser, help: str = SET_HELP) -> None:
    """``--set KEY=VALUE``, repeatable (dest ``set``: a list, or None when not given)."""
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help=help)


def add_scene_options(p: argparse.ArgumentParser) -> None:
    """``SCENE`` (optional), ``--mjcf FILE`` and ``--keyframe NAME``: what load_scene reads.

    A scene, and a loaded MJCF top that replaces its top.
    """
    p.add_argument("scene", nargs="?", help="scene .toml file or catalogue name (default: the "
                   "paper's top and Fig. 3 start)")
    p.add_argument("--mjcf", metavar="FILE", help="a loaded MJCF top instead of the scene's: "
                   "as its file says (options, contacts, first keyframe) unless --set says "
                   "otherwise (default: the scene's top)")
    p.add_argument("--keyframe", metavar="NAME", help="with --mjcf: start from this keyframe "
                   "of the file (default: its first, unless --set init.* sets the state)")


def add_force_option(p: argparse.ArgumentParser, help: str = FORCE_HELP) -> None:
    """``--force`` (dest ``force``): write over existing output."""
    p.add_argument("--force", action="store_true", help=help)


def add_json_option(p: argparse.ArgumentParser, help: str = JSON_HELP) -> None:
    """``--json`` (dest ``json``): print one JSON object instead of text."""
    p.add_argument("--json", action="store_true", help=help)
