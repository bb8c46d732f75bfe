"""The fidelity map: where MuJoCo's own contact, tuned, follows the paper's law, and why not.

``tippetop fidelity``. At every point of a grid of tops (A/C, a/R: the paper's Groups I, II
and III) and friction coefficients mu, MuJoCo's native contact is fitted to the reference and
verified from held-out starts, exactly as ``tippetop validate`` tunes a file
(:func:`tippetop.compare.tuning.tune.tune`); a point *agrees* when the tuned settings pass
every check of the verdict from every start. A point that does not agree gets a cause, one
line made from the checks that departed (:func:`cause_of`; a better explanation plugs in as
``run_fidelity(..., explain=...)``).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tippetop.compare.measures import theory
from tippetop.compare.measures.verdict import predicted_outcome
from tippetop.compare.results.fidelity import FidelityPoint, FidelityResult, MapGrid, MapStart
from tippetop.compare.running.runner import Task
from tippetop.compare.studies.fidelity_processes import (
    NotATerminal,
    init_point_process,
    machine_cores,
    point_cores,
)
from tippetop.models.errors import RunFailedError, TippetopError
from tippetop.models.numbers import number_text
from tippetop.models.scene import Override

#: Every point starts as the paper's Fig. 3 top does: spin n0 (rad/s) at tilt theta0 (rad),
#: from rest otherwise; the spin is raised to :data:`ABOVE_THRESHOLD` x the top's highest
#: threshold (n1, n_c) where that is higher, so that the held-out starts (0.9 n0) stay above it.
START_N0 = 100.0
START_THETA0 = 0.1
ABOVE_THRESHOLD = 1.25
#: The verification runs' horizon (s): validate's.
DEFAULT_T_END_S = 8.0
#: The JSON's format name.
FORMAT = "tippetop-fidelity/1"


# the grids live with the parsers' defaults (importing them costs nothing): re-exported here
from tippetop.compare.studies.defaults import DEFAULT_GRID, GRIDS, Grid  # noqa: E402


def parse_values(text: str, option: str) -> tuple[float, ...]:
    """``0.8,1,1.3`` (or ``LO:HI:N``, N evenly spaced) -> the values, each finite and > 0.

    Raises:
        TippetopError: Not a list of numbers, or a value <= 0 (one line).
    """
    from tippetop.compare.studies.atlas import parse_grid

    text = text.strip()
    if ":" in text:
        return tuple(parse_grid(text, option))
    out = []
    for item in (s.strip() for s in text.split(",")):
        try:
            v = float(item)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and v > 0):
            raise TippetopError(f"{option}: expected comma-separated numbers > 0 (or "
                                f"LO:HI:N), got {text!r}")
        out.append(v)
    if not out or len(set(out)) != len(out):
        raise TippetopError(f"{option}: expected distinct numbers, got {text!r}")
    return tuple(out)


def make_grid(name: str | None, A_over_C: str | None = None, a_over_R: str | None = None,
              mu: str | None = None) -> Grid:
    """The grid asked for: a named one, with any of its three lists replaced by a given one.

    Raises:
        TippetopError: An unknown name, a bad list, or an a/R outside (0, 1) (one line).
    """
    from tippetop.models.errors import did_you_mean

    key = name or DEFAULT_GRID
    if key not in GRIDS:
        raise TippetopError(f"--grid: expected one of {', '.join(GRIDS)}, got "
                            f"{key!r}{did_you_mean(key, GRIDS)}")
    g = GRIDS[key]
    given = any(v is not None for v in (A_over_C, a_over_R, mu))
    out = Grid("custom" if given else g.name,
               parse_values(A_over_C, "--a-over-c") if A_over_C is not None else g.A_over_C,
               parse_values(a_over_R, "--a-over-r") if a_over_R is not None else g.a_over_R,
               parse_values(mu, "--mu") if mu is not None else g.mu)
    for e in out.a_over_R:
        if not 0.0 < e < 1.0:
            raise TippetopError(f"--a-over-r: expected values in (0, 1), got {e:g}")
    for m in out.mu:
        if m > 10.0:
            raise TippetopError(f"--mu: expected friction coefficients in (0, 10], got {m:g}")
    if len(out.points()) > 500:
        raise TippetopError(f"fidelity: expected at most 500 points, got "
                            f"{len(out.points())}")
    return out


def point_overrides(A_over_C: float, a_over_R: float, mu: float, n0: float,
                    theta0: float) -> tuple[Override, ...]:
    """The overrides of a grid point's top, table and start (the paper's top otherwise)."""
    return (Override.of("top.A_over_C", A_over_C), Override.of("top.a_over_R", a_over_R),
            Override.of("friction.mu", mu), Override.of("init.n0", n0),
            Override.of("init.theta0", theta0), Override.of("init.Omega0", 0.0),
            Override.of("init.thetadot0", 0.0))


def start_spin(top: Any) -> float:
    """A point's spin: :data:`START_N0`, or above its thresholds (:data:`ABOVE_THRESHOLD`)."""
    found = [v for v in (theory.n1(top), theory.n_c(top)) if v is not None and math.isfinite(v)]
    return max([START_N0, *(ABOVE_THRESHOLD * v for v in found)])


# ---------------------------------------------------------------- why a point departs
#: The order in which a failed check explains a point: the first found is its cause.
CAUSE_ORDER = ("completed", "stays_on_table", "outcome", "t_invert", "t_stem",
               "jellett_before_stem", "energy_never_rises")


def _check_phrase(c: dict[str, Any]) -> str:
    """One failed check as a short phrase with its number, the check's name in brackets."""
    name, v = c["check"], c.get("value")
    if name == "stays_on_table" and isinstance(v, int | float):
        text = f"the ball leaves the table at {number_text(v, 's')}"
    elif name in ("t_invert", "t_stem") and isinstance(v, int | float):
        what = "inverts" if name == "t_invert" else "the stem lands"
        text = f"{what} {number_text(abs(v), 's')} {'late' if v > 0 else 'early'}"
    elif name == "jellett_before_stem" and isinstance(v, int | float):
        text = f"Jellett drifts {number_text(v, 'relative')}"
    elif name == "energy_never_rises" and isinstance(v, int | float):
        text = f"the energy rises by {number_text(v, 'relative')} of E0"
    else:
        text = str(c.get("note") or "departs")
    return f"{text} ({name})"


def failed_checks(point: dict[str, Any]) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """(start, check) of every check that departed at a point, the fit's start first."""
    tuned = point.get("tuned") or {}
    return [(v, c) for v in tuned.get("verified") or [] for c in v.get("checks") or []
            if c.get("passed") is False]


def cause_of(point_result: dict[str, Any]) -> str:
    """Why a point does not agree, in one line; ``""`` where it agrees.

    Made from the verification's failed checks: the first in :data:`CAUSE_ORDER`, with the
    start it departs from, and how many more depart. The hook for a better explanation:
    pass another function of the same signature as ``run_fidelity(..., explain=...)``.

    Args:
        point_result: A point as :func:`run_point` returns it (``error`` and ``tuned``
            read).
    """
    if point_result.get("agrees"):
        return ""
    if point_result.get("error"):
        return f"not tuned: {point_result['error']}"
    tuned = point_result.get("tuned") or {}
    verified = tuned.get("verified") or []
    checked = [v for v in verified if v.get("passed") is not None]
    if not checked:
        notes = [v.get("note") for v in verified if v.get("note")]
        return "reference not verifiable" + (f": {notes[0]}" if notes else "")
    failed = failed_checks(point_result)
    if not failed:
        if not any(v.get("role") == "held-out" for v in checked):
            return "no held-out start could be verified (the reference stops there)"
        return "departs (no check names why)"
    rank = {name: i for i, name in enumerate(CAUSE_ORDER)}
    start, check = min(failed, key=lambda sc: (rank.get(sc[1]["check"], len(rank)),
                                                sc[0].get("role") != "fit"))
    where = (f"n0 = {number_text(start['n0'], 'rad/s')}, theta0 = "
             f"{number_text(start['theta0'], 'rad')}, {start.get('role')}")
    more = len(failed) - 1
    return (f"{_check_phrase(check)} from {where}"
            + (f"; {more} more check(s) depart" if more else ""))


# ---------------------------------------------------------------- one point, the map
def _point_top(A_over_C: float, a_over_R: float, mu: float) -> Any:
    """The point's top (raises :class:`TippetopError` for a top the scene does not admit)."""
    return Task(None, point_overrides(A_over_C, a_over_R, mu, START_N0, START_THETA0),
                "ode").load().top


def _is_the_tuning(tune_fn: Callable[..., Any]) -> bool:
    """Whether ``tune_fn`` is the real tuning (a stand-in is neither cached nor sent away)."""
    return getattr(tune_fn, "__module__", None) == "tippetop.compare.tuning.tune"


def compute_point(A_over_C: float, a_over_R: float, mu: float, *, t_end_s: float,
                  run_options: dict[str, Any], budget_runs: int | None = None,
                  progress: bool = False,
                  tune_fn: Callable[..., Any] | None = None,
                  threads: int | None = None,
                  reference_workers: int | None = None) -> dict[str, Any]:
    """The whole tuning of one point, from the point alone: the same answer wherever it runs.

    In this process, a point's process or a Dask worker; the point's cache and cause are the
    caller's. The arguments are :func:`run_point`'s; ``reference_workers``: the reference
    runs' worker processes (None: ``run_options``'; 1: in this process, which starts none).

    Returns:
        ``{"tuned", "error", "wall_s"}``: the tuning's answer (None where it stopped), why it
        stopped (None, or a :class:`TippetopError`'s one line) and the wall time (s).

    Raises:
        TippetopError: A top the scene does not admit (the caller has made its row).
    """
    from tippetop.compare.running.options import RunOptions
    from tippetop.compare.tuning.judge import TuneEffort, TuneFile

    if tune_fn is None:
        from tippetop.compare.tuning.tune import tune as tune_fn
    t0 = time.perf_counter()
    top = _point_top(A_over_C, a_over_R, mu)
    n0, theta0 = start_spin(top), START_THETA0
    base = point_overrides(A_over_C, a_over_R, mu, n0, theta0)

    def outcome_at(n: float, th0: float, role: str) -> tuple[float | None, str]:
        return predicted_outcome(top, float(theory.jellett_from_spin(top, n, th0, 0.0)))

    kwargs: dict[str, Any] = {
        "file": TuneFile(A_over_C=top.A_over_C, theory=outcome_at),
        "run": RunOptions(**run_options, progress=progress),
        "effort": TuneEffort(threads=threads, reference_workers=reference_workers),
        **({} if budget_runs is None else {"budget_runs": budget_runs})}
    tuned: dict[str, Any] | None = None
    error = None
    try:
        out = tune_fn(base, mu, n0, theta0, t_end_s, **kwargs)
        tuned = out.to_json() if hasattr(out, "to_json") else out  # a TuneResult, or a dict
    except (TippetopError, RunFailedError) as exc:
        error = " ".join(str(exc).split())
    return {"tuned": tuned, "error": error, "wall_s": time.perf_counter() - t0}


def _begin_point(A_over_C: float, a_over_R: float, mu: float, *, t_end_s: float,
                 budget_runs: int | None, use_cache: bool,
                 explain: Callable[[dict[str, Any]], str]) -> dict[str, Any]:
    """What a point is before its tuning: its top's group and start, and its cached tuning.

    Returns:
        ``{"point", "path", "tuned", "done", "wall_s"}``: the row so far, where its tuning is
        kept (None: nowhere), the cached tuning (None: to compute), whether the row is whole
        (a top the scene does not admit: a row, not a crash) and the time this took (s).
    """
    t0 = time.perf_counter()
    try:
        top = _point_top(A_over_C, a_over_R, mu)
    except TippetopError as exc:
        point = {"A_over_C": A_over_C, "a_over_R": a_over_R, "mu": mu, "group": None,
                 "n0": None, "theta0": None, "agrees": False, "settings": None,
                 "residual": None, "passes": None, "checks": None, "departs": [],
                 "runs": None, "chosen": None, "widened": None,
                 "error": " ".join(str(exc).split()), "cached": False, "tuned": None}
        point["cause"] = explain(point) or None
        point["wall_s"] = time.perf_counter() - t0
        return {"point": point, "path": None, "tuned": None, "done": True,
                "wall_s": point["wall_s"]}
    n0, theta0 = start_spin(top), START_THETA0
    point: dict[str, Any] = {"A_over_C": A_over_C, "a_over_R": a_over_R, "mu": mu,
                             "group": theory.group(top), "n0": n0, "theta0": theta0}
    path = (_cache_path(point_overrides(A_over_C, a_over_R, mu, n0, theta0), t_end_s,
                        budget_runs) if use_cache else None)
    tuned = None
    if path is not None and path.is_file():
        try:
            tuned = json.loads(path.read_text("utf-8"))
        except (OSError, ValueError):  # a damaged entry is computed again
            tuned = None
    tuned = tuned if isinstance(tuned, dict) and bool(tuned.get("fit")) else None
    return {"point": point, "path": path, "tuned": tuned, "done": False,
            "wall_s": time.perf_counter() - t0}


def _keep_tuning(path: Path | None, tuned: dict[str, Any] | None) -> None:
    """Write a computed tuning into the point's cache entry (atomically)."""
    if tuned is None or path is None:
        return
    from tippetop.compare.running.io import json_ready, write_atomic

    text = json.dumps(json_ready(tuned))
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, lambda tmp: tmp.write_text(text, "utf-8"))


def _finish_point(point: dict[str, Any], tuned: dict[str, Any] | None, error: str | None,
                  cached: bool, explain: Callable[[dict[str, Any]], str]) -> dict[str, Any]:
    """The point's row from its tuning (or why it stopped), its cause said."""
    fit = (tuned or {}).get("fit") or {}
    point.update({
        "agrees": bool(tuned and tuned.get("agrees")),
        "settings": (tuned or {}).get("settings"),
        "residual": fit.get("residual"),
        "passes": (tuned or {}).get("passes"), "checks": (tuned or {}).get("checks"),
        "departs": list((tuned or {}).get("departs") or []),
        "runs": fit.get("runs"), "chosen": fit.get("chosen"),
        # where the fits departed: each setting the widening verified, with its checks
        "widened": fit.get("widened"),
        "error": error, "cached": cached, "tuned": tuned,
    })
    point["cause"] = explain(point) or None
    return point


def run_point(A_over_C: float, a_over_R: float, mu: float, *, t_end_s: float,
              run_options: dict[str, Any], budget_runs: int | None = None,
              progress: bool = False,
              explain: Callable[[dict[str, Any]], str] = cause_of,
              tune_fn: Callable[..., Any] | None = None,
              threads: int | None = None) -> dict[str, Any]:
    """Tune MuJoCo's native contact at one point and verify it, as validate tunes a file.

    In this process: its cached tuning, or :func:`compute_point`'s (then kept).

    Args:
        A_over_C: The top's A/C.
        a_over_R: The top's a/R.
        mu: The friction coefficient (the law's; the fit's mu starts there).
        t_end_s: Horizon of the verification runs (s).
        run_options: Keyword arguments of :func:`run_tasks` (scheduler, workers, use_cache).
        budget_runs: MuJoCo runs the tuning of a point may use (None: the tuning's own).
        progress: The tuning's progress lines on a terminal.
        explain: point -> its cause (:func:`cause_of`).
        tune_fn: The tuning (default :func:`tippetop.compare.tuning.tune.tune`).
        threads: Threads of the fit's rollouts (None: every core).

    Returns:
        ``A_over_C, a_over_R, mu, group, n0, theta0, agrees, settings, residual, cause``
        and ``passes``, ``checks``, ``departs``, ``runs`` (the fit's rollouts), ``chosen``,
        ``error`` (None, or why the tuning stopped), ``wall_s``, ``cached`` and ``tuned``
        (the tuning's whole answer).
    """
    if tune_fn is None:
        from tippetop.compare.tuning.tune import tune as tune_fn
    t0 = time.perf_counter()
    begun = _begin_point(A_over_C, a_over_R, mu, t_end_s=t_end_s, budget_runs=budget_runs,
                         use_cache=bool(run_options.get("use_cache", True))
                         and _is_the_tuning(tune_fn), explain=explain)
    if begun["done"]:
        return begun["point"]
    tuned, error, cached = begun["tuned"], None, begun["tuned"] is not None
    if tuned is None:
        out = compute_point(A_over_C, a_over_R, mu, t_end_s=t_end_s, run_options=run_options,
                            budget_runs=budget_runs, progress=progress, tune_fn=tune_fn,
                            threads=threads)
        tuned, error = out["tuned"], out["error"]
        _keep_tuning(begun["path"], tuned)
    point = _finish_point(begun["point"], tuned, error, cached, explain)
    point["wall_s"] = time.perf_counter() - t0
    return point


def _cache_path(base: tuple[Override, ...], t_end_s: float, budget_runs: int | None) -> Path:
    """Where a point's tuning is kept: keyed by its plan, horizon, iterations and the code."""
    from tippetop.compare.running.cache import code_fingerprint
    from tippetop.compare.tuning.tune import source_digest
    from tippetop.models.resources import user_cache_dir

    plan = Task(None, base, "mujoco", "native").plan()
    own = source_digest()
    key = hashlib.sha256(json.dumps({"plan": plan.to_json(), "code": code_fingerprint(),
                                     "tune": own, "t_end_s": t_end_s, "budget_runs": budget_runs,
                                     "what": "fidelity/1"}, sort_keys=True,
                                    default=str).encode()).hexdigest()[:32]
    return user_cache_dir() / "fidelity" / f"{key}.json"


def _say(progress: bool) -> Callable[[str], None] | None:
    if not progress or not sys.stderr.isatty():
        return None
    return lambda line: print(f"fidelity: {line}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------- points at once
def _map_local(todo: list[tuple[int, float, float, float]], at_once: int,
               job: dict[str, Any], started: Callable[[int], None],
               finished: Callable[[int, dict[str, Any]], None]) -> None:
    """Tune ``todo``'s ``(index, A/C, a/R, mu)``, ``at_once`` at a time, a process each.

    The points start in ``todo``'s order (``started(i)``), the next as one ends
    (``finished(i, out)``, ``out`` :func:`compute_point`'s with ``job``'s keywords). Ctrl-C,
    or any error, ends every point's process at once. A point's process starts none of its
    own (``reference_workers=1``): a pool there would leave its semaphores to the resource
    tracker's warning when the process is ended, and hang its exit (measured).
    """
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool
    from multiprocessing import get_context

    from tippetop.compare.running.pool import sigint_blocked

    main = threading.current_thread() is threading.main_thread()
    pool = ProcessPoolExecutor(max_workers=at_once, mp_context=get_context("spawn"),
                               initializer=init_point_process,
                               initargs=(os.getpid(), main))
    queue = list(todo)
    going: dict[Any, int] = {}
    try:
        while queue or going:
            while queue and len(going) < at_once:
                i, r, e, m = queue.pop(0)
                started(i)
                with sigint_blocked():  # a process starting now ignores Ctrl-C from birth
                    going[pool.submit(compute_point, r, e, m, **job)] = i
            done, _ = wait(list(going), return_when=FIRST_COMPLETED)
            for fut in sorted(done, key=lambda f: going[f]):
                i = going.pop(fut)
                try:
                    out = fut.result()
                except BrokenProcessPool:
                    raise TippetopError(f"fidelity: the process tuning point {i + 1} ended "
                                        "without an answer (killed, or out of memory)") from None
                finished(i, out)
    except BaseException:  # the points' processes ended now, not at their next point
        procs = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            proc.terminate()
        raise
    pool.shutdown(wait=True)


def point_on_worker(A_over_C: float, a_over_R: float, mu: float, *, t_end_s: float,
                    use_cache: bool, budget_runs: int | None) -> dict[str, Any]:
    """:func:`compute_point` on a Dask worker: the whole tuning there, its runs local to it.

    The reference's four runs in the worker's own process, one after the other (a Dask worker
    is a daemon by default: it may not start processes), the fit's rollouts and the
    verification's runs on :func:`point_cores` threads.
    """
    threads_here = 1  # the points this worker tunes at once
    with contextlib.suppress(ImportError, ValueError):  # ValueError: not on a worker
        from distributed import get_worker

        threads_here = max(1, int(getattr(get_worker().state, "nthreads", 1) or 1))
    c = point_cores(machine_cores(), threads_here)
    before = sys.stderr
    sys.stderr = NotATerminal(before)  # no bars on the worker's terminal
    try:
        return compute_point(A_over_C, a_over_R, mu, t_end_s=t_end_s,
                             run_options={"scheduler": None, "workers": c,
                                          "use_cache": use_cache},
                             budget_runs=budget_runs, progress=False, threads=c,
                             reference_workers=1)
    finally:
        sys.stderr = before


def _map_dask(todo: list[tuple[int, float, float, float]], scheduler: str,
              job: dict[str, Any], finished: Callable[[int, dict[str, Any]], None]) -> None:
    """Tune ``todo``'s points on the Dask cluster at ``scheduler``: one task a point.

    The points are sent at once, the grid's first first (Dask's priority); a point whose
    task was lost (its workers died: ``KilledWorker``) is ``{"error": reason}``.

    Raises:
        SchedulerError: No scheduler or worker there, or it went away (one line).
    """
    import uuid

    from tippetop.compare.running.cluster import DaskCluster

    tag = uuid.uuid4().hex[:8]
    with DaskCluster.connect(scheduler) as cluster:
        futures = {cluster.client.submit(point_on_worker, r, e, m, **job, pure=False,
                                         priority=len(todo) - k,
                                         key=f"tippetop-fidelity-{tag}-{i}"): i
                   for k, (i, r, e, m) in enumerate(todo)}
        for i, out in cluster.results(futures):
            finished(i, out)


@dataclass(frozen=True)
class _MapJob:
    """What every point of a map is tuned with, and where its progress lines go."""

    pts: list[tuple[float, float, float]]
    t_end_s: float
    budget_runs: int | None
    use_cache: bool
    explain: Callable[[dict[str, Any]], str]
    say: Callable[[str], None] | None


def _settler(n: int, say: Callable[[str], None] | None
             ) -> tuple[list[dict[str, Any] | None], Callable[[int, dict[str, Any]], None]]:
    """The ``n`` rows (None until settled) and ``settle(i, point)``, said in the grid's order."""
    out: list[dict[str, Any] | None] = [None] * n
    said = [0]  # rows said so far, in the grid's order

    def settle(i: int, point: dict[str, Any]) -> None:
        out[i] = point
        while said[0] < n and out[said[0]] is not None:
            p = out[said[0]]
            said[0] += 1
            if say and p is not None:
                say(f"point {said[0]}/{n}: {'agrees' if p['agrees'] else 'departs'} "
                    f"({number_text(p['wall_s'], 's', 3)}{', cached' if p['cached'] else ''})")

    return out, settle


def _begin_points(job: _MapJob, at_once: int, scheduler: str | None
                  ) -> tuple[list[dict[str, Any]], list[tuple[int, float, float, float]], int]:
    """The points begun here, those left to tune away and how many at once (none: one by one)."""
    begun: list[dict[str, Any]] = []
    todo: list[tuple[int, float, float, float]] = []
    if at_once > 1 or scheduler is not None:  # the cache read here, the rest sent away
        begun = [_begin_point(r, e, m, t_end_s=job.t_end_s, budget_runs=job.budget_runs,
                              use_cache=job.use_cache, explain=job.explain)
                 for r, e, m in job.pts]
        todo = [(i, *job.pts[i]) for i, b in enumerate(begun) if not b["done"] and
                b["tuned"] is None]
        if scheduler is None and len(todo) < 2:  # nothing to tune at once: here
            begun, todo, at_once = [], [], 1
    return begun, todo, at_once


def _tune_begun(job: _MapJob, begun: list[dict[str, Any]],
                todo: list[tuple[int, float, float, float]],
                settle: Callable[[int, dict[str, Any]], None], scheduler: str | None,
                at_once: int, cores: int) -> int | None:
    """The points tuned at once (None: on Dask), once every begun point is settled."""
    say, pts, n = job.say, job.pts, len(job.pts)

    def finished(i: int, res: dict[str, Any]) -> None:
        b = begun[i]
        tuned = res.get("tuned")
        _keep_tuning(b["path"], tuned)
        point = _finish_point(b["point"], tuned, res.get("error"), False, job.explain)
        point["wall_s"] = float(res.get("wall_s") or 0.0)
        settle(i, point)

    for i, b in enumerate(begun):  # a top not admitted, or a tuning from the cache
        if b["done"] or b["tuned"] is not None:
            point = b["point"] if b["done"] else _finish_point(b["point"], b["tuned"],
                                                               None, True, job.explain)
            point["wall_s"] = b["wall_s"]
            settle(i, point)
    kw = {"t_end_s": job.t_end_s, "budget_runs": job.budget_runs}
    if scheduler is not None:
        if say and todo:
            say(f"{len(todo)} point(s) sent to the Dask cluster at {scheduler}, one task each")
        _map_dask(todo, scheduler, {**kw, "use_cache": job.use_cache}, finished)
        return None
    at_once = min(at_once, len(todo))
    c = point_cores(cores, at_once)

    def started(i: int) -> None:
        if say:
            r, e, m = pts[i]
            say(f"point {i + 1}/{n}: A/C = {r:g}, a/R = {e:g}, mu = {m:g} ... "
                f"({at_once} points at once)")

    _map_local(todo, at_once, {
        **kw, "run_options": {"scheduler": None, "workers": c, "use_cache": job.use_cache},
        "progress": False, "threads": c, "reference_workers": 1}, started, finished)
    return at_once


def run_fidelity(grid: Grid, *, t_end_s: float = DEFAULT_T_END_S,
                 scheduler: str | None = None, workers: int | None = None,
                 use_cache: bool = True, budget_runs: int | None = None,
                 progress: bool = True,
                 explain: Callable[[dict[str, Any]], str] = cause_of,
                 tune_fn: Callable[..., Any] | None = None,
                 points_at_once: int | None = None) -> FidelityResult:
    """Tune and verify MuJoCo's native contact at every point of ``grid``.

    Points are independent: one whose tuning stops (:class:`TippetopError`) is a point that
    does not agree, its cause said; the map goes on. Several are tuned at once, a process
    each, or each is one task on the Dask cluster at ``scheduler`` (its whole tuning); the
    answer is the same as one at a time here (``points_at_once=1``), and the rows and
    progress lines are in the grid's order. A stand-in ``tune_fn`` (a test's) runs here.

    Args:
        grid: The points.
        t_end_s: Horizon of the verification runs (s).
        scheduler: A Dask scheduler address: one task a point there; None: this machine.
        workers: This machine's cores the map uses (None: all): the points tuned at once
            unless ``points_at_once`` says; with one point at a time, the runs' workers.
        use_cache: Read and write the run cache (and each point's tuning).
        budget_runs: MuJoCo runs the tuning of a point may use (None: the tuning's own).
        progress: A line per point on a terminal.
        explain: point -> its cause (:func:`cause_of`).
        tune_fn: The tuning (default :func:`tippetop.compare.tuning.tune.tune`).
        points_at_once: Points tuned at once on this machine (None: ``workers``, else every
            core; 1: one at a time in this process, its runs on ``workers``).

    Returns:
        The map (:class:`FidelityResult`): its ``points`` (:func:`run_point`'s, ``tuned``
        left out), ``grid``, ``engine`` and ``mujoco_version`` (the MuJoCo that ran, read
        from the module), ``t_end_s``, ``start``, ``budget_runs``, ``wall_s``,
        ``points_at_once`` (1: in this process; None: on Dask) and ``scheduler``.

    Raises:
        TippetopError: A bad horizon or ``points_at_once`` (before any run); a Dask cluster
            that is not there or goes away (:class:`SchedulerError`, one line).
    """
    if not (math.isfinite(t_end_s) and 0 < t_end_s <= 600):
        raise TippetopError(f"--t-end-s: expected a number of seconds in (0, 600], got "
                            f"{t_end_s!r}")
    if points_at_once is not None and points_at_once < 1:
        raise TippetopError(f"fidelity: expected at least 1 point at once, got "
                            f"{points_at_once!r}")
    import mujoco

    if tune_fn is None:
        from tippetop.compare.tuning.tune import tune as tune_fn
    say = _say(progress)
    t0 = time.perf_counter()
    pts = grid.points()
    n = len(pts)
    real = _is_the_tuning(tune_fn)
    cores = machine_cores()
    at_once = points_at_once or workers or cores
    if not real or (scheduler is None and at_once <= 1):
        at_once, scheduler = 1, None  # one point at a time, here
    out, settle = _settler(n, say)
    job = _MapJob(pts, t_end_s, budget_runs, use_cache, explain, say)
    begun, todo, at_once = _begin_points(job, at_once, scheduler)
    if not begun:  # the points one after the other, here
        opts = {"scheduler": None, "workers": workers, "use_cache": use_cache}
        for i, (r, e, m) in enumerate(pts):
            if say:
                say(f"point {i + 1}/{n}: A/C = {r:g}, a/R = {e:g}, mu = {m:g} ...")
            settle(i, run_point(r, e, m, t_end_s=t_end_s, run_options=opts,
                                budget_runs=budget_runs, progress=progress, explain=explain,
                                tune_fn=tune_fn))
    else:
        at_once = _tune_begun(job, begun, todo, settle, scheduler, at_once, cores)
    done = [p for p in out if p is not None]
    return FidelityResult(
        format=FORMAT,
        points=tuple(FidelityPoint.from_json({k: v for k, v in p.items() if k != "tuned"})
                     for p in done),
        grid=MapGrid.from_json(grid.to_json()),
        engine="mujoco", mujoco_version=mujoco.__version__, mode="native",
        t_end_s=t_end_s,
        start=MapStart(START_N0, START_THETA0, ABOVE_THRESHOLD),
        budget_runs=budget_runs,
        wall_s=time.perf_counter() - t0,
        points_at_once=at_once,
        scheduler=scheduler,
    )


def summary_lines(result: FidelityResult | Mapping[str, Any]) -> list[str]:
    """Sentences: how many points agree, per mu and per group (a map, or its JSON)."""
    from tippetop.compare.presentation.fidelity import summary_lines as lines_of

    if not isinstance(result, FidelityResult):
        result = FidelityResult.from_json(result)
    return lines_of(result)


__all__ = ["CAUSE_ORDER", "DEFAULT_T_END_S", "GRIDS", "FidelityResult", "Grid", "cause_of",
           "compute_point", "failed_checks", "machine_cores", "make_grid", "parse_values",
           "point_cores", "point_on_worker", "point_overrides", "run_fidelity", "run_point",
           "start_spin", "summary_lines"]
