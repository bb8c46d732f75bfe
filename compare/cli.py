"""The ``tippetop`` command line: the top-level parser, ``--version``, the epilog and ``main``.

Each command is a module of :mod:`tippetop.compare.commands` (:data:`COMMANDS`); the options
they share, the exit statuses and the error handling are in
:mod:`tippetop.compare.commands.options`.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from tippetop.compare.commands import (
    atlas,
    bench,
    bisect,
    calibrate,
    compare,
    fidelity,
    history,
    matrix,
    metrics,
    mjcf,
    nightly,
    plan,
    probe,
    render,
    report,
    simulate,
    sweep,
    theory,
    threshold,
    validate,
)
from tippetop.compare.commands.options import EXIT_OK, EXIT_STATUSES, Parser, run_main
from tippetop.models.engines import ENGINE_MEANINGS

#: The command modules, in the order ``tippetop --help`` lists them; each has
#: ``add_parser(sub)`` and ``run(args) -> int``.
COMMANDS = (theory, simulate, plan, compare, matrix, bisect, threshold, sweep, bench, nightly,
            history, report, calibrate, render, validate, atlas, fidelity, mjcf, probe, metrics)


#: The environment variables ``tippetop`` reads, with what they do (``tippetop --help``).
ENVIRONMENT: dict[str, str] = {
    "TIPPETOP_CACHE": "folder of the run cache and the compiled code (default "
                      "~/.cache/tippetop); delete it to start afresh",
    "MUJOCO_GL": "offscreen OpenGL for render: egl or osmesa (default: EGL if it opens, else "
                 "OSMesa)",
    "NUMBA_CACHE_DIR": "where numba caches the compiled code instead (default: "
                       "$TIPPETOP_CACHE/numba/<key>)",
    "TIPPETOP_MAX_SAMPLES_GIB": "the most memory a run's table of samples may take, in GiB "
                                "(default 4); a larger run is refused before it starts",
}


def version_text() -> str:
    """``tippetop 0.1.0 (MuJoCo 3.2.7, Python 3.11.7)``: the installed versions."""
    from importlib import metadata

    def ver(name: str) -> str:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return "not installed"

    py = ".".join(str(v) for v in sys.version_info[:3])
    return f"tippetop {ver('tippetop')} (MuJoCo {ver('mujoco')}, Python {py})"


class _VersionAction(argparse.Action):
    """``--version``: print :func:`version_text` and exit 0 (read only when asked)."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS,
                 default: Any = argparse.SUPPRESS, help: str | None = None) -> None:
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        print(version_text())
        parser.exit(EXIT_OK)


def _natural(name: str) -> tuple[Any, ...]:
    """``fig3`` before ``fig11_n030``: digits compare as numbers."""
    import re

    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def scene_catalogue() -> list[tuple[str, str]]:
    """The catalogue's scenes (``models/scenes/*.toml``): name and description, in order."""
    import tomllib

    from tippetop.models.scene import SCENES_DIR, catalogue_names

    out = []
    for name in sorted(catalogue_names(), key=_natural):
        try:
            with open(SCENES_DIR / f"{name}.toml", "rb") as f:
                desc = str(tomllib.load(f).get("scene", {}).get("description", ""))
        except (OSError, tomllib.TOMLDecodeError):
            desc = ""
        out.append((name, desc))
    return out


def _help_width() -> int:
    """The width argparse wraps help at (the terminal's, at most 100)."""
    import shutil

    return max(60, min(100, shutil.get_terminal_size((100, 24)).columns) - 2)


def top_epilog() -> str:
    """The end of ``tippetop --help``: scenes, engines, modes, environment and exit statuses."""
    import textwrap

    from tippetop.models.modes import MODES, runs_on

    width = _help_width()

    def wrap(text: str, first: str = "", rest: str = "  ") -> list[str]:
        return textwrap.wrap(text, width=width, initial_indent=first, subsequent_indent=rest,
                             break_on_hyphens=False, break_long_words=False)

    def block(title: str, rows: list[tuple[str, str]]) -> list[str]:
        w = max(len(k) for k, _ in rows) + 2
        lines = wrap(title)
        for k, text in rows:
            lines += wrap(text or "-", f"  {k:<{w}}", " " * (w + 2))
        return lines

    lines = block("scenes (SCENE is one of these or a scene .toml file; without one, simulate "
                  "and render run the paper's eq. 3.10 top from the Fig. 3 start):",
                  scene_catalogue())
    lines += [""] + block("engines (--engine, --engines: what integrates a run):",
                          list(ENGINE_MEANINGS.items()))
    lines += [""] + block("modes (--mode, --modes: how the contact force is made):",
                          [(name, f"{m.meaning} ({runs_on(name)})")
                           for name, m in MODES.items()])
    lines += [""] + wrap("a run is named ENGINE/MODE (mujoco/native, ode/paper); a pairing "
                         "that cannot run (native on ode, coulomb on mujoco) is refused in one "
                         "line")
    lines += [""] + block("environment:", list(ENVIRONMENT.items()))
    lines += [""] + block("exit status:", [(str(k), v) for k, v in EXIT_STATUSES.items()])
    lines += [""] + wrap("'tippetop COMMAND --help' lists a command's options, each with its "
                         "unit and default.")
    return "\n".join(lines)


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """The epilog as written; the command names and their help on one line each.

    argparse measures the subcommands' names without their extra indent, so the longest of
    them (``threshold``) would go on a line of its own.
    """

    def __init__(self, prog: str) -> None:
        super().__init__(prog, max_help_position=30, width=_help_width())

    def add_argument(self, action: argparse.Action) -> None:
        """Measure a subcommand's name with the indent it is printed at."""
        super().add_argument(action)
        if isinstance(action, argparse._SubParsersAction) and action.help is not \
                argparse.SUPPRESS:
            longest = max((len(a.metavar or a.dest) for a in action._get_subactions()),
                          default=0)
            self._action_max_length = max(self._action_max_length,
                                          longest + self._current_indent + 2 * 2)


class _TopParser(Parser):
    """The top-level parser: its epilog (the catalogue, read from disk) is built when shown."""

    def format_help(self) -> str:
        """The help, with :func:`top_epilog` at its end."""
        if self.epilog is None:
            self.epilog = top_epilog()
        return super().format_help()


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and docs)."""
    p = _TopParser(prog="tippetop", description="Tippe-top cross-validation harness: the "
                   "paper's reference ODE, its theory, and MuJoCo.",
                   formatter_class=_Formatter)
    p.add_argument("--version", action=_VersionAction,
                   help="print the installed versions of tippetop, MuJoCo and Python, and exit")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser,
                           metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tippetop`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_main(args)


def command_line() -> list[str]:
    """The words that start this installation's ``tippetop`` in a new process.

    The ``tippetop`` script beside this Python, run by this Python (as a user types it, and not
    through a shell shim), else ``python -m tippetop.compare.cli``.
    """
    from pathlib import Path

    script = Path(sys.executable).parent / "tippetop"
    if script.is_file():
        return [sys.executable, str(script)]
    return [sys.executable, "-m", "tippetop.compare.cli"]


def entry() -> int:
    """The ``tippetop`` script: :func:`main` in a process of its own (see ``own_process``)."""
    from tippetop.compare.running.interrupt import own_process

    own_process()
    return main()


if __name__ == "__main__":
    raise SystemExit(entry())
