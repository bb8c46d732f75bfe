"""The costs the README and the guides quote, measured: writes docs/data/costs.json.

Each cost is the wall time of a command as a newcomer runs it, in a fresh process:

* ``simulate_first_s``: ``tippetop simulate fig3`` in an empty ``$TIPPETOP_CACHE`` (it
  compiles the reference's integrator); ``simulate_s``: the same again (compiled);
  ``simulate_mujoco_s``: ``--engine mujoco --mode native``, compiled, no runs cached;
* ``nightly_quick_s``: ``tippetop nightly --profile quick --out DIR``, compiled code warm, an
  empty run cache;
* ``validate_no_tune_s``: ``tippetop validate examples/paper_loaded_sphere.xml --no-tune``,
  as the README runs it, compiled code warm, an empty run cache; ``validate_tune_s``: the same
  with the tuning, and ``validate_tune_ratio`` the two's ratio; ``validate_stem_tune_s``:
  ``validate examples/capsule_stem_top.xml`` with its tuning;
* ``docs_build_s``: ``properdocs build --strict`` with its pictures (``--docs``; the docs'
  own cache warm, as a second build finds it), and ``docs_build_no_pictures_s`` with
  ``TIPPETOP_DOCS_IMAGES=0``;
* ``tests_fast_s`` and ``tests_slow_s``: read from a ``.ci/run`` log (``--ci-log FILE``:
  pytest's ``N passed ... in S s`` lines, the slow suite first), not run here.

Each command runs ``--repeats`` times (default 1) and keeps the median. Costs not measured in
this run keep their stored value and its date. Run: ``python benchmarks/bench_costs.py
[--repeats N] [--docs] [--ci-log FILE] [--only KEY,...]``; a bad option is one line, exit 2.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "data" / "costs.json"
FORMAT = "tippetop-costs/1"
MODEL = "examples/paper_loaded_sphere.xml"
STEM_MODEL = "examples/capsule_stem_top.xml"


def _say(line: str) -> None:
    if sys.stderr.isatty():
        print(f"bench_costs: {line}", file=sys.stderr, flush=True)


def _timed(args: list[str], env: dict[str, str], ok: tuple[int, ...] = (0,)) -> float:
    t0 = time.monotonic()
    proc = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.monotonic() - t0
    if proc.returncode not in ok:
        raise SystemExit(f"bench_costs: {' '.join(args)}: exit {proc.returncode}: "
                         f"{proc.stderr.strip().splitlines()[-1:]}")
    return wall


def _env(cache: Path, numba: Path | None) -> dict[str, str]:
    env = {**os.environ, "TIPPETOP_CACHE": str(cache)}
    env.pop("NUMBA_CACHE_DIR", None)
    if numba is not None:
        env["NUMBA_CACHE_DIR"] = str(numba)
    return env


def _median(fn, repeats: int) -> float:
    return statistics.median(fn() for _ in range(repeats))


def measure(keys: set[str], repeats: int, tmp: Path) -> dict[str, dict[str, Any]]:
    """The costs of ``keys`` (those this run measures), each its value, unit, what and how."""
    tt = [sys.executable, "-m", "tippetop.compare.cli"]
    warm = tmp / "warm-numba"
    out: dict[str, dict[str, Any]] = {}

    def fresh(name: str) -> Path:
        d = Path(tempfile.mkdtemp(prefix=f"{name}-", dir=tmp))
        return d

    def cost(key: str, value: float, unit: str, what: str, command: str) -> None:
        out[key] = {"value": round(value, 3), "unit": unit, "what": what, "command": command}
        _say(f"{key}: {value:.3g} {unit}")

    if keys & {"simulate_first_s", "simulate_s"}:
        def first() -> float:
            return _timed([*tt, "simulate", "fig3"], _env(fresh("sim"), None))
        cost("simulate_first_s", _median(first, repeats), "s",
             "the first run in an empty cache, compiling the reference's integrator",
             "tippetop simulate fig3 (empty $TIPPETOP_CACHE)")
        cache = fresh("sim")
        _timed([*tt, "simulate", "fig3"], _env(cache, None))
        cost("simulate_s", _median(lambda: _timed([*tt, "simulate", "fig3"],
                                                  _env(cache, None)), repeats), "s",
             "a run once compiled", "tippetop simulate fig3 (a second time)")
        mj = [*tt, "simulate", "fig3", "--engine", "mujoco", "--mode", "native"]
        _timed(mj, _env(cache, None))
        compiled = next((cache / "numba").iterdir())  # $TIPPETOP_CACHE/numba/<key>
        cost("simulate_mujoco_s", _median(lambda: _timed(mj, _env(fresh("mj"), compiled)),
                                          repeats), "s",
             "a MuJoCo run in its calibrated native mode, compiled, not cached",
             "tippetop simulate fig3 --engine mujoco --mode native")
    # compiled code for the rest (untimed)
    _timed([*tt, "validate", MODEL, "--no-tune", "--json"], _env(fresh("warm"), warm), (0, 1))
    if "nightly_quick_s" in keys:
        def nightly() -> float:
            folder = fresh("nightly")
            return _timed([*tt, "nightly", "--profile", "quick", "--out",
                           str(folder / "report")], _env(folder, warm), (0, 1))
        cost("nightly_quick_s", _median(nightly, repeats), "s",
             "the quick nightly, compiled code warm, no runs cached",
             "tippetop nightly --profile quick --out DIR")
    if keys & {"validate_no_tune_s", "validate_tune_s", "validate_tune_ratio"}:
        no_tune = _median(lambda: _timed([*tt, "validate", MODEL, "--no-tune", "--json"],
                                         _env(fresh("vnt"), warm), (0, 1)), repeats)
        tune = _median(lambda: _timed([*tt, "validate", MODEL, "--json"],
                                      _env(fresh("vt"), warm), (0, 1)), repeats)
        cost("validate_no_tune_s", no_tune, "s", "validate without its tuning, no runs cached",
             f"tippetop validate {MODEL} --no-tune")
        cost("validate_tune_s", tune, "s", "validate with its tuning, no runs cached",
             f"tippetop validate {MODEL}")
        cost("validate_tune_ratio", tune / no_tune, "x",
             "validate with its tuning against --no-tune, each with no runs cached",
             f"tippetop validate {MODEL} against --no-tune")
    if "validate_stem_tune_s" in keys:
        stem = [*tt, "validate", STEM_MODEL, "--json"]
        cost("validate_stem_tune_s", _median(lambda: _timed(stem, _env(fresh("vs"), warm),
                                                            (0, 1)), repeats), "s",
             "validate with its tuning on a top with a stem, no runs cached",
             f"tippetop validate {STEM_MODEL}")
    if keys & {"docs_build_s", "docs_build_no_pictures_s"}:
        exe = shutil.which("properdocs") or "properdocs"
        site = tmp / "site"
        env = {**os.environ}
        env.pop("TIPPETOP_DOCS_IMAGES", None)
        _timed([exe, "build", "--strict", "--site-dir", str(site)], env)  # the docs cache warm
        cost("docs_build_s", _median(lambda: _timed(
            [exe, "build", "--strict", "--site-dir", str(site)], env), repeats), "s",
             "the docs build with its pictures, the docs' own cache warm",
             "properdocs build --strict")
        env["TIPPETOP_DOCS_IMAGES"] = "0"
        cost("docs_build_no_pictures_s", _median(lambda: _timed(
            [exe, "build", "--strict", "--site-dir", str(site)], env), repeats), "s",
             "the docs build without its pictures", "TIPPETOP_DOCS_IMAGES=0 properdocs build")
    return out


_SUITE = re.compile(r"^=*\s*(\d+) passed.* in ([0-9.]+)s", re.M)


def from_ci_log(path: Path) -> dict[str, dict[str, Any]]:
    """The two suites' times from a ``.ci/run`` log: the slow suite's line first."""
    found = [float(m.group(2)) for m in _SUITE.finditer(path.read_text(errors="replace"))]
    if len(found) < 2:
        raise SystemExit(f"bench_costs: {path}: expected two pytest summary lines (the slow "
                         f"suite, then the fast one), got {len(found)}")
    slow, fast = found[-2], found[-1]
    when = datetime.date.fromtimestamp(path.stat().st_mtime).isoformat()
    return {"tests_slow_s": {"value": slow, "unit": "s", "what": "the slow suite",
                             "command": f"pytest -m slow (in .ci/run: {path.name})",
                             "measured": when},
            "tests_fast_s": {"value": fast, "unit": "s", "what": "the default suite",
                             "command": f"pytest -m 'not slow' (in .ci/run: {path.name})",
                             "measured": when}}


KEYS = ("simulate_first_s", "simulate_s", "simulate_mujoco_s", "nightly_quick_s",
        "validate_no_tune_s", "validate_tune_s", "validate_tune_ratio", "validate_stem_tune_s",
        "docs_build_s", "docs_build_no_pictures_s")


def _store(new: dict[str, dict[str, Any]]) -> None:
    """The stored costs with ``new`` (measured today) in place of theirs, written atomically."""
    stored = json.loads(OUT.read_text()) if OUT.is_file() else {"costs": {}}
    today = datetime.date.today().isoformat()
    costs = dict(stored.get("costs", {}))
    for key, entry in new.items():
        costs[key] = {**entry, "measured": entry.get("measured", today)}
    data = {"format": FORMAT, "machine": f"{os.cpu_count()} cores", "costs": costs}
    tmp_out = OUT.with_suffix(".json.tmp")
    tmp_out.write_text(json.dumps(data, indent=1) + "\n")
    tmp_out.replace(OUT)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_costs", description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=1)
    p.add_argument("--docs", action="store_true", help="measure the docs build too")
    p.add_argument("--ci-log", type=Path, default=None)
    p.add_argument("--only", default=None, help="comma-separated keys to measure")
    args = p.parse_args(argv)
    if args.repeats < 1:
        p.error(f"--repeats: expected at least 1, got {args.repeats}")
    keys = set(KEYS) if args.only is None else set(args.only.split(","))
    if bad := keys - set(KEYS):
        p.error(f"--only: expected keys among {', '.join(KEYS)}, got {', '.join(sorted(bad))}")
    if not args.docs:
        keys -= {"docs_build_s", "docs_build_no_pictures_s"}
    new: dict[str, dict[str, Any]] = {}
    if args.ci_log is not None:
        new.update(from_ci_log(args.ci_log))
    docs = {"docs_build_s", "docs_build_no_pictures_s"}
    with tempfile.TemporaryDirectory(prefix="tt-bench-costs-") as tmp:
        try:  # the commands' costs first, stored: the docs build reads them
            new.update(measure(keys - docs, args.repeats, Path(tmp)))
            _store(new)
            if keys & docs:
                # the pages quote the build's own cost: a first measurement needs a value
                # to build with (the one it then replaces)
                stored = json.loads(OUT.read_text())["costs"]
                _store({k: {"value": 1.0, "unit": "s", "what": "not yet measured",
                            "command": "", "measured": "never"}
                        for k in docs if k not in stored and k not in new} | new)
                new.update(measure(keys & docs, args.repeats, Path(tmp)))
                _store(new)
        except KeyboardInterrupt:
            print("bench_costs: interrupted", file=sys.stderr)
            return 130
    for key in sorted(new):
        print(f"{key:28s} {new[key]['value']:10.3f} {new[key]['unit']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
