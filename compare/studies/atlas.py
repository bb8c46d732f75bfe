"""The paper's group diagram, measured: n1 and n4 at every point of an (A/C, a/R) grid.

Each engine's thresholds from growth rates, the group they imply against the theory's
(docs/design.md), in parallel, cached batches of short runs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from tippetop.compare.measures import theory
from tippetop.compare.results.atlas import POINT_COLUMNS, AtlasPoint, AtlasResult
from tippetop.compare.running.runner import Task, run_tasks
from tippetop.compare.studies.defaults import (  # noqa: F401 - re-exported
    DEFAULT_A_OVER_C,
    DEFAULT_A_OVER_R,
    DEFAULT_ENGINES_TEXT,
    DEFAULT_MODES_TEXT,
)
from tippetop.compare.studies.growth import (
    SCAN_SPINS,
    Search,
    jellett_pi_to_zero,
    run_searches,
    settled,
    state_start,
)
from tippetop.compare.studies.sweep import Run
from tippetop.models.engines import parse_engine
from tippetop.models.errors import TippetopError
from tippetop.models.modes import run_label
from tippetop.models.scene import Override

#: The top every grid point starts from (R, M, mu, Lambda of the paper's eq. 3.10).
ATLAS_SCENE = "fig11_n060"
#: The runs the atlas measures by default: the reference, and MuJoCo in both of its main modes.
DEFAULT_RUNS: tuple[Run, ...] = (("ode", "paper", ()), ("mujoco", "paper", ()),
                                 ("mujoco", "native", ()))
#: Relative tolerance of each threshold in the atlas (a group needs far less than n1's 1e-5).
ATLAS_REL_TOL = 1e-4
#: A measured threshold "moves" when it is this far from the theory's (relative).
MOVE_REL = 2e-3


def parse_grid(text: str, name: str) -> list[float]:
    """``LO:HI:N`` -> N evenly spaced values from LO to HI (N = 1: LO alone)."""
    parts = text.split(":")
    try:
        lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
        if len(parts) != 3:
            raise ValueError
    except (ValueError, IndexError):
        raise TippetopError(f"{name}: expected LO:HI:N (N points from LO to HI), got "
                            f"{text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo > 0 and hi >= lo and 1 <= n <= 50):
        raise TippetopError(f"{name}: expected 0 < LO <= HI and 1 <= N <= 50, got {text!r}")
    return [lo] if n == 1 else [float(x) for x in np.linspace(lo, hi, n)]


def group_of(n1: float | None, n4: float | None) -> str:
    """The group implied by measured thresholds: I without n1, II with both, III without n4."""
    if n1 is None:
        return "I"
    return "II" if n4 is not None else "III"


def run_atlas(A_over_C: Sequence[float], a_over_R: Sequence[float],
              runs: Sequence[Run] = DEFAULT_RUNS, overrides: tuple[Override, ...] = (), *,
              rel_tol: float = ATLAS_REL_TOL, scheduler: str | None = None,
              workers: int | None = None, use_cache: bool = True) -> AtlasResult:
    """Measure n1 and n4 at every grid point on every engine and mode, against the theory.

    Args:
        A_over_C: The grid's A/C values.
        a_over_R: The grid's a/R values (each in (0, 1)).
        runs: (engine, mode, more scene keys) to measure in: any engine
            (:mod:`tippetop.models.engines`: ``ode``, ``mujoco``, ``mujoco==X.Y.Z``,
            ``mujoco@PYTHON``, ``mjx``, ``mjx-f32``, ``warp``).
        overrides: Scene overrides applied at every point (e.g. a MuJoCo timestep).
        rel_tol: Relative tolerance of each threshold.
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes.
        use_cache: Read and write the run cache.

    Returns:
        An :class:`~tippetop.compare.results.atlas.AtlasResult`: ``points`` (one
        :class:`~tippetop.compare.results.atlas.AtlasPoint` per grid point and run:
        ``A_over_C, a_over_R, engine, mode, run, group_theory, group_measured, n1_theory,
        n1_measured, n4_theory, n4_measured``, and ``agrees``, ``n_runs``, ``settled``),
        ``agreement`` (run, ``ENGINE/MODE`` -> fraction of points whose group matches),
        ``findings`` (sentences: where a run moves a threshold or a group boundary, with the
        numbers), ``runs``, the grid (``A_over_C``, ``a_over_R``) and ``n_runs``.
    """
    labels = []
    for engine, mode, _extra in runs:
        parse_engine(engine)  # a bad engine is one line before any run
        if mode is None:
            raise TippetopError(f"atlas: expected a mode for engine {engine!r}, got none")
        labels.append(run_label(engine, mode))
    for e in a_over_R:
        if not 0.0 < e < 1.0:
            raise TippetopError(f"--a-over-R: expected values in (0, 1), got {e:g}")
    cells: list[tuple[float, float, str, Search, Search, Any]] = []
    for r in A_over_C:
        for e in a_over_R:
            over = (Override.of("top.A_over_C", r), Override.of("top.a_over_R", e), *overrides)
            top = Task(ATLAS_SCENE, over, "ode").load().top
            for (engine, mode, extra), label in zip(runs, labels, strict=True):
                more = (*over, *extra)
                up = Search(ATLAS_SCENE, engine, more, "upright", state_start(top, "upright"),
                            rel_tol, mode=mode)
                inv = Search(ATLAS_SCENE, engine, more, "inverted",
                             state_start(top, "inverted"), rel_tol, mode=mode)
                cells.append((r, e, label, up, inv, top))

    def run(tasks: list[Task]) -> list[Any]:
        return list(run_tasks(tasks, scheduler=scheduler, workers=workers,
                              use_cache=use_cache, label="atlas"))

    run_searches([s for c in cells for s in c[3:5]], run)
    points = []
    for r, e, label, up, inv, top in cells:
        n1 = up.root
        n4 = jellett_pi_to_zero(top, inv.root) if inv.root is not None else None
        g_th, g_me = theory.group(top), group_of(n1, n4)
        fits = [p for s in (up, inv) for p in s.points.values()]
        points.append(AtlasPoint(
            A_over_C=r, a_over_R=e, engine=up.engine, mode=up.mode, run=label,
            group_theory=g_th, group_measured=g_me,
            n1_theory=theory.n1(top), n1_measured=n1,
            n4_theory=theory.n4(top), n4_measured=n4,
            agrees=g_th == g_me, n_runs=len(fits),
            settled=settled(fits, [up.root, inv.root]),
        ))
    agreement = {lab: float(np.mean([p.agrees for p in points if p.run == lab]))
                 for lab in labels}
    return AtlasResult(tuple(points), agreement, tuple(findings([p.to_json() for p in points])),
                       tuple(A_over_C), tuple(a_over_R), tuple(labels), tuple(SCAN_SPINS))


def _rel(measured: float | None, th: float | None) -> float | None:
    return measured / th - 1.0 if measured is not None and th else None


def findings(points: Sequence[dict[str, Any]]) -> list[str]:
    """Sentences on where each run departs from the theory: groups, then moved thresholds.

    From the points' records (:meth:`AtlasPoint.to_json`, or an atlas.json's, as the report
    reads them).
    """
    out = []
    for eng in dict.fromkeys(p["run"] for p in points):
        mine = [p for p in points if p["run"] == eng]
        wrong = [p for p in mine if not p["agrees"]]
        if wrong:
            where = "; ".join(f"A/C = {p['A_over_C']:.3g}, a/R = {p['a_over_R']:.3g}: "
                              f"{p['group_measured']} where the theory says "
                              f"{p['group_theory']}" for p in wrong)
            out.append(f"{eng} moves a group boundary at {len(wrong)} of {len(mine)} points "
                       f"({where}).")
        for key in ("n1", "n4"):
            rel = [(p, _rel(p[f"{key}_measured"], p[f"{key}_theory"])) for p in mine]
            rel = [(p, x) for p, x in rel if x is not None]
            if not rel:
                continue
            worst_p, worst = max(rel, key=lambda px: abs(px[1]))
            median = float(np.median([x for _, x in rel]))
            if abs(worst) > MOVE_REL:
                out.append(f"{eng} moves {key}: by {100 * median:+.2f} % (median over "
                           f"{len(rel)} points), at most {100 * worst:+.2f} % (A/C = "
                           f"{worst_p['A_over_C']:.3g}, a/R = {worst_p['a_over_R']:.3g}).")
            else:
                out.append(f"{eng} keeps {key} within {100 * abs(worst):.3f} % of the theory "
                           f"at all {len(rel)} points (median {100 * median:+.4f} %).")
    return out


def atlas_table(result: AtlasResult) -> Any:
    """The points as a pandas DataFrame (the atlas.csv columns)."""
    import pandas as pd

    return pd.DataFrame([p.to_json() for p in result.points], columns=list(POINT_COLUMNS))
