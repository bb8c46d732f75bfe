"""Whole commands of two installations, paired: the code before the vocabulary change and today's.

The target (the issue's): the engine/mode vocabulary change costs whole commands at most 1.05x
of the code before it. Timed, as fresh processes (``subprocess``), the wall time of:

* ``simulate fig3 --json``: the reference ODE, 8 s simulated;
* ``simulate fig3 --engine mujoco --set run.t_end_s=2 --json``: MuJoCo in the scene's mode
  (paper), 2 s;
* MuJoCo's own contact, 2 s: ``--engine mujoco --mode native`` where the installation's
  ``simulate --help`` has ``--mode``, else the old spelling ``--engine mujoco-native``;
* ``nightly --profile quick --out DIR``: the whole quick catalogue (it recomputes every run
  unless ``--cache``), a new ``DIR`` each run, removed after.

Paired: in each pair the command runs on ``--before`` and then on ``--after`` (A B A B ...,
all the commands of a part in each pair), each pair gives a ratio after/before, and the table
shows each side's median time and the median, min and max of the pair ratios; the machine is
shared, so a pair's two runs see about the same load, which the ratio cancels. A run's slot in
its pair may matter by itself (the second run of a pair can meet the machine in another
state): ``--order abba`` runs every other pair after-then-before, so that such an effect
cancels. Run the same installation as both sides to see the method's own spread (an A/A run:
on the shared 2-core machine its medians of 7 pairs came within 1.03x, single pairs
0.67x-1.48x). For reference,
the same table is printed for the CPU time (user + system) of each run's process and of the
processes it waited for (the nightly's workers), which the machine's load moves less; and for
``simulate``, the run's own integration time (``wall_s`` of its ``--json``) is split off.

Caches. The harness keeps its run cache and numba's compiled code under ``$TIPPETOP_CACHE``
(the runs as ``<2 hex>/<key>.json|.parquet`` at its top, the compiled code in
``numba/<hash of the sources>/``, the MuJoCo step cost in ``step_cost.json``). Each side has a
warm folder, ``<tmp>/tt-bench-before`` and ``<tmp>/tt-bench-after``, holding only ``numba/``;
every run gets a fresh, empty ``$TIPPETOP_CACHE`` in a temporary folder whose ``numba`` is a
link to its side's warm one (``NUMBA_CACHE_DIR`` is unset, so the code finds its compiled code
as a user's run does), and runs there as its working folder; the folder is removed after. So
no run finds a cached run, a step cost or an earlier run's output, and none compiles: every
command runs once on each side first (untimed: the warm-up compiles what it needs), and the
warm ``numba`` folders are listed (names, sizes, mtimes) before and after the timed runs: any
change means a timed run compiled, and is printed as such.

Same work: every timed run must exit as its warm-up did; ``simulate``'s ``--json`` must give
the same ``t_invert``, ``theta_asymp`` and ``theta_final`` (to 1e-9 relative; both None counts
as equal) and, for the reference, the same ``n_rhs`` on both sides and in every run; the
nightly's exit status and its last stdout lines (durations and the ``--out`` folder written as
placeholders) must match. Disagreement is printed and the exit status is 1.

Run: ``python benchmarks/bench_vocabulary.py --before /work/wt-before/.venv/bin/tippetop
[--after /work/wt-bench/.venv/bin/tippetop] [--pairs N] [--order ab|abba]
[--only simulate|nightly] [--json]``
(default pairs: 7 for simulate, 3 for the nightly; ``--after`` defaults to the ``tippetop``
beside this Python). A missing or broken installation is one line and exit 2.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import resource
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: The issue's target: today's command at most this many times the one before.
MAX_RATIO = 1.05
#: Relative tolerance on the numbers both sides must agree on.
REL_TOL = 1e-9
#: ``simulate --json`` keys that must agree (floats, or None for a top that does not invert).
SIMULATE_KEYS = ("t_invert", "theta_asymp", "theta_final")
#: Default pairs of each part.
DEFAULT_PAIRS = {"simulate": 7, "nightly": 3}
#: The nightly's last stdout lines compared.
NIGHTLY_TAIL = 4
#: How each ``--order`` runs a pair, as the header says it.
ORDERS = {"ab": "each pair before then after (A B A B ...)",
          "abba": "pairs before-after and after-before in turn (A B B A ...)"}
#: Timeouts of one run (s): a stuck command stops the benchmark.
TIMEOUT_S = {"simulate": 900, "nightly": 3600}


@dataclass(frozen=True)
class Side:
    """One installation.

    Attributes:
        name: ``before`` or ``after``.
        exe: Its ``tippetop`` script.
        warm: Its warm cache folder (``numba/`` only).
        has_mode: Whether its ``simulate`` takes ``--mode`` (the new vocabulary).
    """

    name: str
    exe: Path
    warm: Path
    has_mode: bool


@dataclass(frozen=True)
class Command:
    """One command timed on both sides.

    Attributes:
        name: Its label in the table.
        part: ``simulate`` or ``nightly``.
        args: Its arguments on each side (``{out}`` stands for the run's output folder).
    """

    name: str
    part: str
    args: dict[str, list[str]]


@dataclass
class Run:
    """One run of a command on one side.

    Attributes:
        wall_s: Its wall time, the process's start to its end (s).
        cpu_s: The CPU time (user + system) of its process and every process it waited for
            (the nightly's workers) (s).
        returncode: Its exit status.
        stdout: What it printed on stdout.
        stderr: What it printed on stderr.
        out: The ``--out`` folder it was given (already removed), for normalising its output.
    """

    wall_s: float
    cpu_s: float
    returncode: int
    stdout: str
    stderr: str
    out: str


@dataclass
class Times:
    """A command's timed runs, pair by pair.

    Attributes:
        before: Wall times of the ``before`` side (s).
        after: Wall times of the ``after`` side (s).
        cpu: CPU times (user + system, the process tree) by side (s).
        run_wall: The runs' own integration ``wall_s`` (simulate only), by side.
        problems: Each disagreement found between the runs' outputs.
    """

    before: list[float] = field(default_factory=list)
    after: list[float] = field(default_factory=list)
    cpu: dict[str, list[float]] = field(default_factory=lambda: {"before": [], "after": []})
    run_wall: dict[str, list[float]] = field(default_factory=lambda: {"before": [],
                                                                      "after": []})
    problems: list[str] = field(default_factory=list)

    @property
    def ratios(self) -> list[float]:
        """After/before of each pair."""
        return [a / b for b, a in zip(self.before, self.after, strict=True)]


def fail(message: str) -> SystemExit:
    """The one line and exit 2 for a missing or broken installation (or a failed warm-up)."""
    print(f"bench_vocabulary: {message}", file=sys.stderr)
    return SystemExit(2)


def find_side(name: str, given: str | None) -> Side:
    """Check an installation and read which vocabulary its ``simulate`` speaks.

    Args:
        name: ``before`` or ``after``.
        given: The ``tippetop`` script given (``--after`` defaults to the one beside this
            Python).

    Raises:
        SystemExit: Exit 2 with one line: no such executable, or it does not run.
    """
    exe = Path(given) if given else Path(sys.executable).parent / "tippetop"
    warm = Path(tempfile.gettempdir()) / f"tt-bench-{name}"
    if not (exe.is_file() and os.access(exe, os.X_OK)):
        raise fail(f"--{name} {exe}: no such executable (give a venv's bin/tippetop)")
    try:
        out = subprocess.run([str(exe), "simulate", "--help"], capture_output=True, text=True,
                             timeout=300, cwd=tempfile.gettempdir(), env=child_env(warm))
    except (OSError, subprocess.TimeoutExpired) as err:
        raise fail(f"--{name} {exe}: does not run ({err})") from None
    if out.returncode != 0:
        last = (out.stderr.strip().splitlines() or ["no output"])[-1]
        raise fail(f"--{name} {exe}: 'tippetop simulate --help' exited {out.returncode}: {last}")
    return Side(name, exe.absolute(), warm, re.search(r"--mode\b", out.stdout) is not None)


def commands(sides: dict[str, Side], only: str | None) -> list[Command]:
    """The commands timed, each spelt in each side's vocabulary."""
    def native(side: Side) -> list[str]:
        return ["--engine", "mujoco", "--mode", "native"] if side.has_mode else \
            ["--engine", "mujoco-native"]

    two = ["--set", "run.t_end_s=2", "--json"]
    out = [
        Command("simulate fig3 (ode, 8 s)", "simulate",
                {n: ["simulate", "fig3", "--json"] for n in sides}),
        Command("simulate fig3 mujoco paper, 2 s", "simulate",
                {n: ["simulate", "fig3", "--engine", "mujoco", *two] for n in sides}),
        Command("simulate fig3 mujoco native, 2 s", "simulate",
                {n: ["simulate", "fig3", *native(s), *two] for n, s in sides.items()}),
        Command("nightly --profile quick", "nightly",
                {n: ["nightly", "--profile", "quick", "--out", "{out}"] for n in sides}),
    ]
    return [c for c in out if only in (None, c.part)]


def child_env(cache: Path) -> dict[str, str]:
    """This environment with ``$TIPPETOP_CACHE`` at ``cache`` and ``NUMBA_CACHE_DIR`` unset."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["TIPPETOP_CACHE"] = str(cache)
    return env


def run(side: Side, cmd: Command) -> Run:
    """One fresh process of ``cmd`` on ``side``, in an empty run cache (compiled code linked).

    The run's folder (its ``$TIPPETOP_CACHE``, working folder and ``--out``) is removed after.
    """
    (side.warm / "numba").mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f"tt-bench-{side.name}-run-"))
    try:
        (tmp / "numba").symlink_to(side.warm / "numba", target_is_directory=True)
        out = tmp / "out"
        argv = [str(side.exe), *(a.replace("{out}", str(out)) for a in cmd.args[side.name])]
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        # a session of its own: a timeout or Ctrl-C ends the command with its workers
        with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              cwd=tmp, env=child_env(tmp), start_new_session=True) as proc:
            try:
                stdout, stderr = proc.communicate(timeout=TIMEOUT_S[cmd.part])
            except BaseException as err:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
                if isinstance(err, subprocess.TimeoutExpired):
                    raise fail(f"{side.name}: {' '.join(argv[1:])} took over "
                               f"{TIMEOUT_S[cmd.part]} s") from None
                raise
        wall = time.perf_counter() - start
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime
        return Run(wall, cpu, proc.returncode, stdout, stderr, str(out))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def listing(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``folder``: its size and mtime (ns), by relative path."""
    found = {}
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            st = p.stat()
            found[p.relative_to(folder).as_posix()] = (st.st_size, st.st_mtime_ns)
    return found


def close(a: Any, b: Any) -> bool:
    """Both None, or both numbers within :data:`REL_TOL` relative (equal NaNs count)."""
    if a is None or b is None:
        return a is None and b is None
    if not (isinstance(a, (int, float)) and isinstance(b, (int, float))):
        return a == b
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b or abs(a - b) <= REL_TOL * max(abs(a), abs(b))


def simulate_outcome(r: Run) -> dict[str, Any]:
    """What a ``simulate --json`` run must agree on, and its own integration time.

    Raises:
        ValueError: Its stdout is not one JSON object.
    """
    doc = json.loads(r.stdout)
    if not isinstance(doc, dict):
        raise ValueError("not a JSON object")
    keys = [*SIMULATE_KEYS, "n_rhs"] if doc.get("engine") == "ode" else list(SIMULATE_KEYS)
    return {"status": doc.get("status"), **{k: doc.get(k) for k in keys},
            "wall_s": doc.get("wall_s")}


_SECONDS = re.compile(r"\d+(?:\.\d+)?(?:e[-+]?\d+)?\s*(?:s|ms|min)\b")
_DATE = re.compile(r"\d{4}-\d{2}-\d{2}[ T]\d{2}:\d{2}(?::\d{2})?")
#: The folders of an absolute path (the installation's own, e.g. its baselines' folder).
_FOLDERS = re.compile(r"/[^\s()'\"]+/")


def nightly_outcome(r: Run) -> dict[str, Any]:
    """A nightly run's exit status and its last stdout lines, made comparable.

    The ``--out`` folder is written ``<out>``, the folders of other absolute paths (the
    baselines' folder is each installation's own) ``<dir>/``, durations ``<t>``, dates
    ``<date>``.
    """
    lines = [ln.rstrip() for ln in r.stdout.splitlines() if ln.strip()][-NIGHTLY_TAIL:]
    tail = [_DATE.sub("<date>", _SECONDS.sub("<t>", _FOLDERS.sub("<dir>/", ln.replace(
        r.out, "<out>")))) for ln in lines]
    return {"returncode": r.returncode, "tail": tail}


def outcome(cmd: Command, r: Run) -> dict[str, Any]:
    """What a run of ``cmd`` must agree on (a failed simulate: its status and stderr's end)."""
    if cmd.part == "nightly":
        return nightly_outcome(r)
    if r.returncode != 0:
        return {"returncode": r.returncode,
                "stderr": (r.stderr.strip().splitlines() or [""])[-1]}
    try:
        return {"returncode": 0, **simulate_outcome(r)}
    except ValueError as err:
        return {"returncode": 0, "stdout": f"not JSON ({err})"}


def differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """The keys on which two outcomes disagree (the run's own ``wall_s`` aside)."""
    keys = sorted((set(a) | set(b)) - {"wall_s"})
    return [f"{k}: {a.get(k)!r} vs {b.get(k)!r}" for k in keys if not close(a.get(k), b.get(k))]


def measure(sides: dict[str, Side], cmds: list[Command], pairs: int, order: str,
            say: Callable[[str], None]) -> tuple[dict[str, Times], dict[str, dict[str, Any]],
                                                  list[str]]:
    """Warm up, then time ``pairs`` pairs of every command; check the outputs as it goes.

    Args:
        sides: The installations, ``before`` first.
        cmds: The commands.
        pairs: Timed pairs of each.
        order: ``ab``: each pair runs ``before`` then ``after``; ``abba``: every other pair
            the other way round, so that a slot's own effect cancels.
        say: Where progress goes.

    Returns:
        The times by command, the warm-up outcomes by command and side, and what changed in
        the warm compile caches during the timed runs (empty: nothing compiled).
    """
    reference: dict[str, dict[str, Any]] = {}
    for cmd in cmds:  # warm-up: compiles what each side needs; outputs read, not timed
        reference[cmd.name] = {}
        for name, side in sides.items():
            say(f"warm-up: {cmd.name} on {name}")
            r = run(side, cmd)
            if cmd.part == "simulate" and r.returncode != 0:
                tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
                raise fail(f"{name}: {' '.join(cmd.args[name])} exited {r.returncode}: {tail}")
            reference[cmd.name][name] = outcome(cmd, r)
    before = {n: listing(s.warm / "numba") for n, s in sides.items()}
    times = {cmd.name: Times() for cmd in cmds}
    for i in range(pairs):
        for cmd in cmds:
            t = times[cmd.name]
            slots = list(sides.items())
            if order == "abba" and i % 2:
                slots.reverse()
            for name, side in slots:
                r = run(side, cmd)
                getattr(t, name).append(r.wall_s)
                t.cpu[name].append(r.cpu_s)
                got = outcome(cmd, r)
                if got.get("wall_s") is not None:
                    t.run_wall[name].append(float(got["wall_s"]))
                for d in differences(reference[cmd.name]["before"], got):
                    t.problems.append(f"pair {i + 1}, {name} vs before's warm-up: {d}")
            say(f"pair {i + 1}/{pairs}: {cmd.name}: before {t.before[-1]:.2f} s, after "
                f"{t.after[-1]:.2f} s, {t.ratios[-1]:.3f}x")
    changed = []
    for n, s in sides.items():
        after = listing(s.warm / "numba")
        new = [p for p in after if before[n].get(p) != after[p]]
        if new:
            changed.append(f"{n}: {len(new)} compiled-code files written during the timed "
                           f"runs ({', '.join(sorted(new)[:3])}...): those runs compiled")
    return times, reference, changed


def main(argv: list[str] | None = None) -> int:
    """Time the commands on both installations, pair by pair, and print the table."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--before", required=True, metavar="TIPPETOP",
                   help="the tippetop script of the code before the change (a venv's "
                        "bin/tippetop)")
    p.add_argument("--after", metavar="TIPPETOP",
                   help="the tippetop script of today's code (default: the one beside this "
                        "Python)")
    p.add_argument("--pairs", type=int, metavar="N",
                   help="timed pairs of each command (default: 7 for simulate, 3 for the "
                        "nightly)")
    p.add_argument("--order", choices=("ab", "abba"), default="ab",
                   help="ab: each pair runs before then after; abba: every other pair after "
                        "then before, to cancel an effect of the slot (default ab)")
    p.add_argument("--only", choices=("simulate", "nightly"),
                   help="time only these commands (default: both parts)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    if args.pairs is not None and args.pairs < 1:
        p.error("--pairs: at least 1")
    sides = {"before": find_side("before", args.before), "after": find_side("after", args.after)}
    if sides["before"].exe.resolve() == sides["after"].exe.resolve():
        print("bench_vocabulary: note: --before and --after are the same installation",
              file=sys.stderr)
    load_before = os.getloadavg()[0]

    def say(line: str) -> None:
        print(f"  {line}", file=sys.stderr, flush=True)

    parts = [args.only] if args.only else ["simulate", "nightly"]
    times: dict[str, Times] = {}
    reference: dict[str, dict[str, Any]] = {}
    changed: list[str] = []
    all_cmds = commands(sides, args.only)
    for part in parts:
        cmds = [c for c in all_cmds if c.part == part]
        pairs = args.pairs or DEFAULT_PAIRS[part]
        t, ref, ch = measure(sides, cmds, pairs, args.order, say)
        times.update(t)
        reference.update(ref)
        changed += ch
    for cmd in all_cmds:  # the two sides' warm-ups against each other
        for d in differences(reference[cmd.name]["before"], reference[cmd.name]["after"]):
            times[cmd.name].problems.insert(0, f"warm-ups, after vs before: {d}")
    rows = []
    for cmd in all_cmds:
        t = times[cmd.name]
        ratio = statistics.median(t.ratios)
        rows.append({"command": cmd.name, "pairs": len(t.ratios),
                     "argv": {n: cmd.args[n] for n in sides},
                     "before_s": t.before, "after_s": t.after, "ratios": t.ratios,
                     "before_median_s": statistics.median(t.before),
                     "after_median_s": statistics.median(t.after),
                     "ratio_median": ratio, "ratio_min": min(t.ratios),
                     "ratio_max": max(t.ratios), "within": ratio <= MAX_RATIO,
                     "cpu_before_s": t.cpu["before"], "cpu_after_s": t.cpu["after"],
                     "cpu_ratios": [a / b for b, a in zip(t.cpu["before"], t.cpu["after"],
                                                          strict=True)],
                     "run_wall_median_s": {n: statistics.median(v) if v else None
                                           for n, v in t.run_wall.items()},
                     "outputs": reference[cmd.name], "problems": t.problems})
    same = not any(r["problems"] for r in rows)
    res = {"before": str(sides["before"].exe), "after": str(sides["after"].exe),
           "target_ratio": MAX_RATIO, "order": args.order, "rows": rows, "same_outputs": same,
           "compiled_during_timing": changed, "load_before": load_before,
           "load_after": os.getloadavg()[0]}
    if args.json:
        print(json.dumps(res))
        return 0 if same else 1
    print(f"before: {sides['before'].exe} ({'--mode' if sides['before'].has_mode else 'old'} "
          f"vocabulary)\nafter:  {sides['after'].exe} "
          f"({'--mode' if sides['after'].has_mode else 'old'} vocabulary)")
    print(f"whole commands, fresh processes, an empty run cache each, compiled code warm; "
          f"{ORDERS[args.order]}; {os.cpu_count()} cores, load average {load_before:.2f} "
          f"before, {res['load_after']:.2f} after")
    w = max(len(r["command"]) for r in rows)
    print(f"  {'command':<{w}} {'pairs':>5} {'before (s)':>10} {'after (s)':>10}   "
          f"{'after/before: median':>20} {'min':>6} {'max':>6}")
    for r in rows:
        print(f"  {r['command']:<{w}} {r['pairs']:>5} {r['before_median_s']:>10.2f} "
              f"{r['after_median_s']:>10.2f}   {r['ratio_median']:>19.3f}x "
              f"{r['ratio_min']:>5.3f}x {r['ratio_max']:>5.3f}x")
    print("for reference, CPU time (user + system, the process and the ones it waited for; "
          "less sensitive to the machine's load than wall time):")
    for r in rows:
        c, med = r["cpu_ratios"], statistics.median
        print(f"  {r['command']:<{w}} {r['pairs']:>5} {med(r['cpu_before_s']):>10.2f} "
              f"{med(r['cpu_after_s']):>10.2f}   {med(c):>19.3f}x "
              f"{min(c):>5.3f}x {max(c):>5.3f}x")
    for r in rows:
        rw = r["run_wall_median_s"]
        if rw["before"] is not None and rw["after"] is not None:
            print(f"  {r['command']}: of it the integration's own wall_s (median) before "
                  f"{rw['before']:.2f} s, after {rw['after']:.2f} s; the rest before "
                  f"{r['before_median_s'] - rw['before']:.2f} s, after "
                  f"{r['after_median_s'] - rw['after']:.2f} s")
    print("same work:")
    for r in rows:
        o = r["outputs"]["before"]
        if "tail" in o:
            shown = f"exit {o['returncode']}, last lines {o['tail']}"
        else:
            shown = ", ".join(f"{k} {v!r}" for k, v in o.items() if k != "wall_s")
        agree = "DIFFERENT" if r["problems"] else "same on both sides and in every run"
        print(f"  {r['command']}: {agree} ({shown})")
        for line in r["problems"][:10]:
            print(f"    {line}")
    for line in changed:
        print(f"WARNING: {line}")
    if not changed:
        print("compiled code: the warm numba folders unchanged across the timed runs (none "
              "compiled)")
    for r in rows:
        verdict = "within" if r["within"] else "OVER"
        print(f"verdict: {r['command']}: after/before {r['ratio_median']:.3f}x (median of "
              f"{r['pairs']} pairs): {verdict} the target of at most {MAX_RATIO:g}x")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
