"""Critical spins measured in an engine, against the theory: growth rates or bisection on n0.

How a run "crosses" in the bisection is in docs/design.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from tippetop.compare.measures import theory
from tippetop.compare.measures.series import OUTCOME_MARGIN, classify_outcome, theta_asymp
from tippetop.compare.measures.summary import run_failed
from tippetop.compare.results.threshold import FailedRun, HorizonCheck, ThresholdResult
from tippetop.compare.running.options import DEFAULT_RUN, RunOptions
from tippetop.compare.running.runner import Task, run_tasks
from tippetop.models.errors import TippetopError
from tippetop.models.scene import Override

if TYPE_CHECKING:
    from tippetop.models.scene import Scene

WHICH = ("n1", "n4", "nc")
#: A bisection run for n_c that is still moving at its end is continued over twice, then four
#: times its horizon until it settles (``classify_outcome`` not ``inconclusive``).
SETTLE_DOUBLINGS = 2
#: ``growth`` (the default for every threshold: :mod:`tippetop.compare.studies.growth`) or
#: ``bisect``.
METHODS = ("growth", "bisect")
#: Default scene: the Fig. 9 (a) / Fig. 11 top from theta0 = 0.01 with a 60-s horizon.
DEFAULT_SCENE = "fig11_n060"


@dataclass(frozen=True)
class BisectOptions:
    """How :func:`bisect_threshold` bisects; the defaults are ``--method bisect``'s.

    Attributes:
        rel_tol: Stop when the bracket is this narrow, relative to its midpoint.
        max_rounds: Bisection rounds at most.
        points_per_round: Spins run in each round (None: the workers, at least 2).
        horizon_check: Run the final bracket's ends again over twice the scene's horizon.
    """

    rel_tol: float = 0.005
    max_rounds: int = 10
    points_per_round: int | None = None
    horizon_check: bool = True


def left_vertical(table: pd.DataFrame) -> bool:
    """True if theta grows away from the vertical over the second half of the run."""
    t = table["t"].to_numpy()
    th = table["theta"].to_numpy()
    T = t[-1]
    late = th[t >= 0.9 * T].mean()
    mid = th[(t >= 0.4 * T) & (t < 0.5 * T)].mean()
    return bool(late > mid or theta_asymp(table) > OUTCOME_MARGIN)


def crossed(which: str, table: pd.DataFrame) -> bool:
    """Whether a run is above the threshold ``which``."""
    if which == "n1":
        return left_vertical(table)
    return classify_outcome(table) == "inverted"


def theory_value(which: str, scene_top: Any) -> float:
    """The theory's n1 or n_c for a top; a clear error where it does not exist."""
    value = theory.n1(scene_top) if which == "n1" else theory.n_c(scene_top)
    if value is None:
        g = theory.group(scene_top)
        raise TippetopError(f"--which: {which} does not exist for a Group {g} top "
                            f"(n1 exists for Groups II and III, nc for Group II)")
    return float(value)


def measure_threshold(
    scene: str | None,
    engine: str,
    which: str,
    overrides: tuple[Override | str, ...] = (),
    *,
    method: str | None = None,
    rel_tol: float | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    use_cache: bool = True,
    mode: str | None = None,
    **bisect_options: Any,
) -> ThresholdResult:
    """Measure the critical spin ``which`` of a scene's top on ``engine`` in ``mode``.

    Args:
        scene: A scene name or file (default: the Fig. 9 (a) top, ``DEFAULT_SCENE``).
        engine: The engine (``ode``, ``mujoco``, ``mujoco==X.Y.Z``, ``mujoco@PYTHON``,
            ``mjx``, ``mjx-f32``, ``warp``: :mod:`tippetop.models.engines`).
        which: ``n1``, ``n4`` or ``nc``.
        overrides: Scene overrides.
        method: ``growth`` (default: the zero of a steady state's growth rate, from short
            runs; :func:`tippetop.compare.studies.growth.measure_growth`) or ``bisect`` (the
            outcome of full runs over the scene's horizon, :func:`bisect_threshold`; n1 and nc).
        rel_tol: Relative tolerance (default 1e-5 for growth, 0.005 for bisect).
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes.
        use_cache: Read and write the run cache.
        mode: How the contact force is made (:mod:`tippetop.models.modes`); None: the
            scene's.
        **bisect_options: ``max_rounds``, ``points_per_round``, ``horizon_check`` (bisect).

    Raises:
        TippetopError: A bad ``which``, ``method``, option, engine or mode, or a mode the
            engine cannot run (one line each).

    Returns:
        The measured spin against the theory's (:class:`ThresholdResult`: ``which, engine,
        mode, scene, measured, theory, rel_diff, bracket, runs, n_runs, horizon_s,
        converged``, ``method``, ``rates`` (growth: each {n0, state, rate_per_s}; bisect:
        none), ``settled`` (growth: every fit clean; bisect: no run still moving and the
        answer does not depend on the horizon), and each method's own fields).
    """
    from tippetop.compare.studies.growth import GrowthOptions, measure_growth

    if which not in WHICH:
        raise TippetopError(f"--which: expected one of {', '.join(WHICH)}, got {which!r}")
    method = method or "growth"
    if method not in METHODS:
        raise TippetopError(f"--method: expected one of {', '.join(METHODS)}, got {method!r}")
    run = RunOptions(scheduler=scheduler, workers=workers, use_cache=use_cache)
    if method == "growth":
        if bisect_options:
            raise TippetopError(f"--method growth: {', '.join(bisect_options)} apply to "
                                f"--method bisect only")
        search = GrowthOptions(rel_tol=rel_tol) if rel_tol else GrowthOptions()
        res = measure_growth(scene, engine, which, overrides, search=search, run=run, mode=mode)
        if res.measured is None and not res.failed_runs:
            raise TippetopError(f"threshold: {res.warning}")
        return res  # with failed_runs: the caller reports them (exit 1), the others kept
    if which == "n4":
        raise TippetopError("--method bisect: expected --which n1 or nc (n4 is measured from "
                            "growth rates), got n4")
    return bisect_threshold(scene, engine, which, overrides,
                            search=BisectOptions(rel_tol=rel_tol or 0.005, **bisect_options),
                            run=run, mode=mode)


def bisect_threshold(
    scene: str | None,
    engine: str,
    which: str,
    overrides: tuple[Override | str, ...] = (),
    *,
    search: BisectOptions = BisectOptions(),
    run: RunOptions = DEFAULT_RUN,
    mode: str | None = None,
) -> ThresholdResult:
    """Bisect on n0 for the critical spin ``which`` (``n1`` or ``nc``) on ``engine``.

    ``search``: the tolerance, rounds, spins per round and horizon check
    (:class:`BisectOptions`); ``run``: where the runs run (``scheduler``, ``workers``,
    ``use_cache`` of :class:`~tippetop.compare.running.options.RunOptions`; the runner's bar
    shows on a terminal). With ``search.horizon_check``, the two ends of the final bracket are
    run again over twice the scene's horizon; if either changes side, the answer depends on
    the run length: it is reported with ``depends_on_horizon`` true, a ``warning``, and
    ``converged`` false.

    Returns:
        A :class:`ThresholdResult` with ``method`` ``bisect``: ``measured`` (bracket midpoint,
        rad/s), ``theory``, ``rel_diff`` (measured / theory - 1), ``bracket`` (low, high),
        ``runs`` (each n0 with its result), ``n_runs``, ``horizon_s``, ``bracket_converged``,
        ``horizon_check`` (:class:`HorizonCheck` or None), ``depends_on_horizon``, ``warning``
        and ``converged`` (the bracket is within rel_tol AND does not depend on the horizon).
    """
    if which not in ("n1", "nc"):
        raise TippetopError(f"--which: expected n1|nc, got {which!r}")
    scene = scene or DEFAULT_SCENE
    task = Task(scene, overrides, engine, mode)
    base = task.load()
    plan = task.plan(base)  # the engine and mode are checked here, before any run
    engine, mode = plan.engine, plan.mode
    n_th = theory_value(which, plan.top)
    k = search.points_per_round or max(2, run.workers or 2)
    runs: list[dict[str, Any]] = []
    unsettled: list[float] = []

    def evaluate(n0s: list[float], extra: tuple[Override, ...] = (),
                 record: bool = True) -> list[bool]:
        def batch(spins: list[float], more: tuple[Override, ...]) -> list[Any]:
            tasks = [Task(scene, (*overrides, *more, Override.of("init.n0", n0)), engine, mode)
                     for n0 in spins]
            out = run_tasks(tasks, scheduler=run.scheduler, workers=run.workers,
                            use_cache=run.use_cache, label=f"{which} bisection")
            for res in out:
                if res.error:
                    raise TippetopError(res.error)
            return list(out)

        results = dict(zip(n0s, batch(n0s, extra), strict=True))
        _stop_if_failed(which, results, runs)
        horizon_here = next((float(x.value) for x in reversed(extra)
                             if x.name == "run.t_end_s"), base.run.t_end_s)
        # n_c: a run whose final state is still moving is continued (the horizon doubled, at
        # most SETTLE_DOUBLINGS times) until it settles; one that never does stays unsettled
        for k in range(1, SETTLE_DOUBLINGS + 1 if which == "nc" else 1):
            moving = [n0 for n0, r in results.items()
                      if classify_outcome(r.table) == "inconclusive"]
            if not moving:
                break
            longer = (*extra, Override.of("run.t_end_s", horizon_here * 2**k))
            results.update(zip(moving, batch(moving, longer), strict=True))
        flags = []
        for n0 in n0s:
            res = results[n0]
            flag = crossed(which, res.table)
            if classify_outcome(res.table) == "inconclusive":
                unsettled.append(n0)
            if record:
                runs.append({"n0": n0, "crossed": flag,
                             "theta_asymp": res.summary["theta_asymp"],
                             "t_end_s": float(res.table["t"].iloc[-1]),
                             "settled": classify_outcome(res.table) != "inconclusive",
                             "status": res.summary.get("status", "ok")})
            flags.append(flag)
        return flags

    try:
        return replace(_bisect(evaluate, which, scene_name=base.name, engine=engine, n_th=n_th,
                               search=search, k=k, horizon=base.run.t_end_s, runs=runs,
                               unsettled=unsettled), mode=mode)
    except _Failed as exc:  # every run so far is kept; no threshold is claimed
        return _failed_answer(exc, which, engine, mode, base, n_th, runs, unsettled)


class _Failed(Exception):
    """A bisection run failed: the bisection stops, what ran is reported."""

    def __init__(self, runs: list[dict[str, Any]]) -> None:
        super().__init__(runs[0]["message"])
        self.runs = runs


def _stop_if_failed(which: str, results: dict[float, Any], runs: list[dict[str, Any]]) -> None:
    """None if every run of ``results`` completed; else raises _Failed, each kept in ``runs``."""
    failed = [(n0, r) for n0, r in results.items() if run_failed(r.summary)]
    if failed:
        for n0, r in results.items():
            ok = not run_failed(r.summary)
            runs.append({"n0": n0, "crossed": crossed(which, r.table) if ok else None,
                         "status": r.summary.get("status", "ok"),
                         **({} if ok else {"failed": r.summary.get("message")})})
        raise _Failed([{"n0": n0, "message": f"the run at n0 = {n0:.6g} rad/s failed: "
                                             f"{r.summary.get('message')}"}
                       for n0, r in failed])


def _failed_answer(exc: _Failed, which: str, engine: str, mode: str | None, base: Scene,
                   n_th: float, runs: list[dict[str, Any]],
                   unsettled: list[float]) -> ThresholdResult:
    """The result of a bisection stopped by a failed run: its runs so far, no threshold."""
    return ThresholdResult(
        which=which, engine=engine, mode=mode, scene=base.name, method="bisect",
        measured=None, theory=n_th, rel_diff=None, bracket=(),
        runs=tuple(sorted(runs, key=lambda r: r["n0"])), horizon_s=base.run.t_end_s,
        converged=False, settled=False, unsettled_n0=tuple(sorted(unsettled)),
        failed_runs=tuple(FailedRun(r["n0"], r["message"]) for r in exc.runs),
        warning="; ".join(r["message"] for r in exc.runs) + " (the runs before it are kept)")


def _bisect(evaluate: Callable[..., list[bool]], which: str, *, scene_name: str, engine: str,
            n_th: float, search: BisectOptions, k: int, horizon: float,
            runs: list[dict[str, Any]], unsettled: list[float]) -> ThresholdResult:
    """The bisection itself, on ``evaluate`` (True where a run is above the threshold).

    ``search``'s ``rel_tol``, ``max_rounds`` and ``horizon_check`` apply; ``k`` spins a round.
    The result's ``mode`` is None: the caller puts it in.
    """
    lo, hi = 0.8 * n_th, 1.25 * n_th
    for _ in range(4):  # widen the bracket until its ends disagree
        f_lo, f_hi = evaluate([lo, hi])
        if not f_lo and f_hi:
            break
        if f_lo:
            lo *= 0.7
        if not f_hi:
            hi *= 1.4
    else:
        raise TippetopError(f"threshold: expected the outcome to change between n0 = {lo:.4g} "
                            f"and {hi:.4g} rad/s, got the same outcome at both ends")
    rounds = 0
    while (hi - lo) / (0.5 * (hi + lo)) > search.rel_tol and rounds < search.max_rounds:
        pts = [float(x) for x in np.linspace(lo, hi, k + 2)[1:-1]]
        flags = evaluate(pts)
        grid = [lo, *pts, hi]
        res = [False, *flags, True]
        # first crossing from False to True (monotone outcome assumed; the first flip is kept)
        j = next(i for i in range(1, len(res)) if res[i])
        lo, hi = grid[j - 1], grid[j]
        rounds += 1
    measured = 0.5 * (lo + hi)
    bracket_ok = (hi - lo) / measured <= search.rel_tol
    # Near a threshold the approach slows without bound: the ends of the final bracket run
    # again over twice the horizon must keep their sides, or the answer is the horizon's
    if search.horizon_check:
        again = evaluate([lo, hi], (Override.of("run.t_end_s", 2.0 * horizon),), record=False)
        depends = again != [False, True]
        check = HorizonCheck(2.0 * horizon, again[0], again[1], depends)
    else:
        depends, check = False, None
    warning = None
    if depends:
        moved = "the low end crosses" if check and check.low_crossed else \
            "the high end no longer crosses"
        warning = (f"the answer depends on the run length: over {2.0 * horizon:g} s instead of "
                   f"{horizon:g} s {moved}, so {which} lies outside [{lo:.4g}, {hi:.4g}] rad/s "
                   f"(a longer run.t_end_s moves it)")
    return ThresholdResult(
        which=which, engine=engine, mode=None, scene=scene_name, method="bisect",
        measured=measured, theory=n_th, rel_diff=measured / n_th - 1.0, bracket=(lo, hi),
        runs=tuple(sorted(runs, key=lambda r: r["n0"])), horizon_s=horizon,
        converged=bracket_ok and not depends, settled=not depends and not unsettled,
        warning=warning, bracket_converged=bracket_ok, horizon_check=check,
        depends_on_horizon=depends, unsettled_n0=tuple(sorted(unsettled)))


