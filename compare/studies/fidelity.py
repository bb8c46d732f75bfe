"""The fidelity map: where MuJoCo's own contact, tuned, follows the paper's law, and why not.

``tippetop fidelity``. At every point of a grid of tops (A/C, a/R: the paper's Groups I, II
and III) and friction coefficients mu, MuJoCo's native contact is fitted to the reference and
verified from held-out starts, exactly as ``tippetop validate`` tunes a file
(:func:`tippetop.compare.studies.tune.tune`); a point *agrees* when the tuned settings pass
every check of the verdict from every start. A point that does not agree gets a cause, one
line made from the checks that departed (:func:`cause_of`; a better explanation plugs in as
``run_fidelity(..., explain=...)``).
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tippetop.compare.measures import theory
from tippetop.compare.measures.verdict import predicted_outcome
from tippetop.compare.running.runner import Task
from tippetop.models.errors import RunFailedError, TippetopError
from tippetop.models.numbers import number_text

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
                    theta0: float) -> tuple[str, ...]:
    """``--set`` strings of a grid point's top, table and start (the paper's top otherwise)."""
    return (f"top.A_over_C={A_over_C!r}", f"top.a_over_R={a_over_R!r}", f"friction.mu={mu!r}",
            f"init.n0={n0!r}", f"init.theta0={theta0!r}", "init.Omega0=0.0",
            "init.thetadot0=0.0")


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
def run_point(A_over_C: float, a_over_R: float, mu: float, *, t_end_s: float,
              run_options: dict[str, Any], budget_runs: int | None = None,
              progress: bool = False,
              explain: Callable[[dict[str, Any]], str] = cause_of,
              tune_fn: Callable[..., dict[str, Any]] | None = None) -> dict[str, Any]:
    """Tune MuJoCo's native contact at one point and verify it, as validate tunes a file.

    Args:
        A_over_C: The top's A/C.
        a_over_R: The top's a/R.
        mu: The friction coefficient (the law's; the fit's mu starts there).
        t_end_s: Horizon of the verification runs (s).
        run_options: Keyword arguments of :func:`run_tasks` (scheduler, workers, use_cache).
        budget_runs: MuJoCo runs the tuning of a point may use (None: the tuning's own).
        progress: The tuning's progress lines on a terminal.
        explain: point -> its cause (:func:`cause_of`).
        tune_fn: The tuning (default :func:`tippetop.compare.studies.tune.tune`).

    Returns:
        ``A_over_C, a_over_R, mu, group, n0, theta0, agrees, settings, residual, cause``
        and ``passes``, ``checks``, ``departs``, ``runs`` (the fit's rollouts), ``chosen``,
        ``error`` (None, or why the tuning stopped), ``wall_s``, ``cached`` and ``tuned``
        (the tuning's whole answer).
    """
    if tune_fn is None:
        from tippetop.compare.studies.tune import tune as tune_fn
    t0 = time.perf_counter()
    try:
        top = Task(None, point_overrides(A_over_C, a_over_R, mu, START_N0, START_THETA0),
                   "ode").load().top
    except TippetopError as exc:  # a top the scene does not admit: a row, not a crash
        point = {"A_over_C": A_over_C, "a_over_R": a_over_R, "mu": mu, "group": None,
                 "n0": None, "theta0": None, "agrees": False, "settings": None,
                 "residual": None, "passes": None, "checks": None, "departs": [],
                 "runs": None, "chosen": None, "error": " ".join(str(exc).split()),
                 "cached": False, "tuned": None}
        point["cause"] = explain(point) or None
        point["wall_s"] = time.perf_counter() - t0
        return point
    n0, theta0 = start_spin(top), START_THETA0
    base = point_overrides(A_over_C, a_over_R, mu, n0, theta0)

    def outcome_at(n: float, th0: float, role: str) -> tuple[float | None, str]:
        return predicted_outcome(top, float(theory.jellett_from_spin(top, n, th0, 0.0)))

    kwargs: dict[str, Any] = {"run_options": run_options, "progress": progress,
                              "theory": outcome_at, "A_over_C": top.A_over_C}
    if budget_runs is not None:
        kwargs["budget_runs"] = budget_runs
    point: dict[str, Any] = {"A_over_C": A_over_C, "a_over_R": a_over_R, "mu": mu,
                             "group": theory.group(top), "n0": n0, "theta0": theta0}
    tuned: dict[str, Any] | None = None
    error = None
    path = (_cache_path(base, t_end_s, budget_runs) if run_options.get("use_cache", True)
            and tune_fn.__module__ == "tippetop.compare.studies.tune" else None)
    cached = False
    if path is not None and path.is_file():
        try:
            tuned = json.loads(path.read_text("utf-8"))
            cached = isinstance(tuned, dict) and bool(tuned.get("fit"))
        except (OSError, ValueError):  # a damaged entry is computed again
            tuned = None
        tuned = tuned if cached else None
    if tuned is None:
        try:
            tuned = tune_fn(base, mu, n0, theta0, t_end_s, **kwargs)
        except (TippetopError, RunFailedError) as exc:
            error = " ".join(str(exc).split())
        if tuned is not None and path is not None:
            from tippetop.compare.running.io import json_ready, write_atomic

            text = json.dumps(json_ready(tuned))
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, lambda tmp: tmp.write_text(text, "utf-8"))
    fit = (tuned or {}).get("fit") or {}
    point.update({
        "agrees": bool(tuned and tuned.get("agrees")),
        "settings": (tuned or {}).get("settings"),
        "residual": fit.get("residual"),
        "passes": (tuned or {}).get("passes"), "checks": (tuned or {}).get("checks"),
        "departs": list((tuned or {}).get("departs") or []),
        "runs": fit.get("runs"), "chosen": fit.get("chosen"),
        "error": error, "cached": cached, "tuned": tuned,
    })
    point["cause"] = explain(point) or None
    point["wall_s"] = time.perf_counter() - t0
    return point


def _cache_path(base: tuple[str, ...], t_end_s: float, budget_runs: int | None) -> Path:
    """Where a point's tuning is kept: keyed by its plan, horizon, iterations and the code."""
    from tippetop.compare.measures import verdict as verdict_rule
    from tippetop.compare.running.cache import code_fingerprint
    from tippetop.compare.studies import tune
    from tippetop.compare.studies.calibrate import identify, scoring
    from tippetop.models.resources import user_cache_dir

    plan = Task(None, base, "mujoco", "native").plan()
    own = hashlib.sha256(b"".join(Path(m.__file__).read_bytes()
                                  for m in (tune, verdict_rule, identify, scoring))).hexdigest()
    key = hashlib.sha256(json.dumps({"plan": plan.to_json(), "code": code_fingerprint(),
                                     "tune": own, "t_end_s": t_end_s, "budget_runs": budget_runs,
                                     "what": "fidelity/1"}, sort_keys=True,
                                    default=str).encode()).hexdigest()[:32]
    return user_cache_dir() / "fidelity" / f"{key}.json"


def _say(progress: bool) -> Callable[[str], None] | None:
    if not progress or not sys.stderr.isatty():
        return None
    return lambda line: print(f"fidelity: {line}", file=sys.stderr, flush=True)


def run_fidelity(grid: Grid, *, t_end_s: float = DEFAULT_T_END_S,
                 scheduler: str | None = None, workers: int | None = None,
                 use_cache: bool = True, budget_runs: int | None = None,
                 progress: bool = True,
                 explain: Callable[[dict[str, Any]], str] = cause_of,
                 tune_fn: Callable[..., dict[str, Any]] | None = None) -> dict[str, Any]:
    """Tune and verify MuJoCo's native contact at every point of ``grid``.

    Points are independent: one whose tuning stops (:class:`TippetopError`) is a point that
    does not agree, its cause said; the map goes on. Each point's runs go through the
    harness's runner (cache, workers, Dask) inside the tuning.

    Args:
        grid: The points.
        t_end_s: Horizon of the verification runs (s).
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes (None: all cores).
        use_cache: Read and write the run cache (and each point's tuning).
        budget_runs: MuJoCo runs the tuning of a point may use (None: the tuning's own).
        progress: A line per point on a terminal.
        explain: point -> its cause (:func:`cause_of`).
        tune_fn: The tuning (default :func:`tippetop.compare.studies.tune.tune`).

    Returns:
        ``format``, ``points`` (:func:`run_point`, ``tuned`` left out), ``grid``,
        ``agreement`` ({agree, points}), ``engine`` (the MuJoCo that ran, read from the
        module), ``t_end_s``, ``start``, ``budget_runs``, ``runs`` and ``wall_s``.

    Raises:
        TippetopError: A bad horizon (before any run).
    """
    if not (math.isfinite(t_end_s) and 0 < t_end_s <= 600):
        raise TippetopError(f"--t-end-s: expected a number of seconds in (0, 600], got "
                            f"{t_end_s!r}")
    import mujoco

    say = _say(progress)
    opts = {"scheduler": scheduler, "workers": workers, "use_cache": use_cache}
    t0 = time.perf_counter()
    pts = grid.points()
    out = []
    for i, (r, e, m) in enumerate(pts, start=1):
        if say:
            say(f"point {i}/{len(pts)}: A/C = {r:g}, a/R = {e:g}, mu = {m:g} ...")
        p = run_point(r, e, m, t_end_s=t_end_s, run_options=opts, budget_runs=budget_runs,
                      progress=progress, explain=explain, tune_fn=tune_fn)
        if say:
            say(f"point {i}/{len(pts)}: {'agrees' if p['agrees'] else 'departs'} "
                f"({number_text(p['wall_s'], 's', 3)}{', cached' if p['cached'] else ''})")
        out.append(p)
    return {
        "format": FORMAT,
        "points": [{k: v for k, v in p.items() if k != "tuned"} for p in out],
        "grid": grid.to_json(),
        "agreement": {"agree": sum(p["agrees"] for p in out), "points": len(out)},
        "engine": "mujoco", "mujoco_version": mujoco.__version__,
        "mode": "native",
        "t_end_s": t_end_s,
        "start": {"n0": START_N0, "theta0": START_THETA0, "above_threshold": ABOVE_THRESHOLD},
        "budget_runs": budget_runs,
        "runs": sum(p["runs"] or 0 for p in out),
        "wall_s": time.perf_counter() - t0,
    }


def summary_lines(result: dict[str, Any]) -> list[str]:
    """Sentences: how many points agree, per mu and per group."""
    pts = result["points"]
    lines = [f"MuJoCo's native contact, tuned, follows the paper's law at "
             f"{sum(p['agrees'] for p in pts)} of {len(pts)} points"]
    for key, label in (("mu", "mu"), ("group", "Group")):
        parts = []
        for v in dict.fromkeys(p[key] for p in pts):
            mine = [p for p in pts if p[key] == v]
            name = f"{v:g}" if isinstance(v, float) else v or "-"
            parts.append(f"{label} {name}: {sum(p['agrees'] for p in mine)}/{len(mine)}")
        lines.append("; ".join(parts))
    return lines


__all__ = ["CAUSE_ORDER", "DEFAULT_T_END_S", "GRIDS", "Grid", "cause_of", "failed_checks",
           "make_grid", "parse_values", "point_overrides", "run_fidelity", "run_point",
           "start_spin", "summary_lines"]
