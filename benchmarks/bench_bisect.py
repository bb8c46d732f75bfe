"""``tippetop bisect``: the environments it makes against the releases in its range, in one run.

Two measurements:

* real: the guide's example, ``tippetop bisect tests/data/stranger/group2_mu1_implicitfast.xml
  --between 3.3.7 3.17.0 --metric t_invert --set mujoco.timestep_s=0.001`` (the registry's
  releases; environments made with uv under ``$TIPPETOP_CACHE/envs`` the first time): the
  managed environments it needed, those it made now, and the pair it names;
* search: the same search over a fake range of every size from 3 to the real range's, with the
  move at every position (no run), the most releases run against ``ceil(log2(n - 1)) + 2``.

It prints each as a ratio of environments to releases in the range (target for the real one:
at most ``(ceil(log2(n - 1)) + 2) / n``, 6/16 = 0.375 for the 16 releases from 3.3.7 to
3.17.0).

Run: ``python benchmarks/bench_bisect.py [--no-real] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from tippetop.compare.results.matrix import MatrixResult
from tippetop.compare.studies.bisect import (
    Candidate,
    MatrixRunner,
    bisect,
    registry_releases,
    release_range,
)
from tippetop.compare.studies.matrix import COMPARED

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "tests" / "data" / "stranger" / "group2_mu1_implicitfast.xml"


class _Fake:
    """A runner that runs nothing: t_invert steps from 1.2 s to 1.0 s at release ``at``."""

    def __init__(self, at: int) -> None:
        self.at = at

    def prepare(self, engine: str) -> str:
        return "made"

    def measure(self, engines: list[str]) -> dict[str, dict[str, Any]]:
        out = {}
        for e in engines:
            i = int(e.split(".")[1])
            values: dict[str, Any] = dict.fromkeys(COMPARED)
            values.update(status="ok", t_invert=1.2 if i < self.at else 1.0)
            out[e] = {"version": e, "status": "ok", "message": None, "values": values}
        return out

    def attribute(self, a: str, b: str) -> MatrixResult:
        return MatrixResult((), (), (), True, {}, (), (), {})


def _search(n_max: int) -> None:
    print(f"search over fake ranges (n = 3 ... {n_max}, the move at every position):")
    print(f"  {'n':>3s} {'most run':>9s} {'bound':>6s} {'ratio':>6s}")
    worst_over = 0
    for n in range(3, n_max + 1):
        cands = [Candidate(f"1.{i}.0", f"mujoco==1.{i}.0") for i in range(n)]
        most = max(bisect(cands, ["t_invert"], _Fake(at), attribution=False).runs
                   for at in range(1, n))
        bound = math.ceil(math.log2(n - 1)) + 2
        worst_over = max(worst_over, most - bound)
        if n in (3, 4, 8, 9, 16, n_max):
            print(f"  {n:3d} {most:9d} {bound:6d} {most / n:6.3f}")
    print(f"  most runs over the bound ceil(log2(n - 1)) + 2: {worst_over}")


def _real(workers: int | None) -> None:
    releases = registry_releases("mujoco")
    cands = release_range(releases, "3.3.7", "3.17.0")
    lines: list[str] = []
    runner = MatrixRunner(str(MODEL), "file", ("mujoco.timestep_s=0.001",), workers=workers,
                          say=lines.append)
    t0 = time.perf_counter()
    res = bisect(cands, ["t_invert"], runner, say=lines.append)
    wall = time.perf_counter() - t0
    n = len(cands)
    e = res.by_metric["t_invert"]
    bound = math.ceil(math.log2(n - 1)) + 2
    print(f"real: {MODEL.name} in mode file at 1 ms, t_invert, {n} releases from "
          f"{cands[0].name} to {cands[-1].name}")
    print(f"  ran {', '.join(t.release for t in res.tested)}")
    print(f"  pair: {e.pair and e.pair.to_json()}, values {e.values and list(e.values)} s")
    print(f"  environments {res.environments_made} ({res.environments_new} made now) "
          f"for {n} releases: ratio {res.environments_made / n:.3f} "
          f"(target <= {bound}/{n} = {bound / n:.3f}); wall {wall:.0f} s")


def main() -> None:
    """Run both and print the ratios."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--no-real", action="store_true", help="skip the real bisect (it makes "
                   "about 6 environments with uv the first time)")
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: "
                   "all cores)")
    args = p.parse_args()
    _search(16)
    if not args.no_real:
        _real(args.workers)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
