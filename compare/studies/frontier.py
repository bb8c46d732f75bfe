"""Work-precision frontiers: a solver's time at an error level, and solvers at equal error.

A solver's points are (error, CPU time) pairs, one per tolerance. Its frontier is the monotone
hull of its points: sorted by time, the points that reach a smaller error than every cheaper
point (the Pareto staircase). Its time at an error level is read on that frontier by
interpolating log(time) linearly in log(error) between the two frontier points that bracket
the level: the cheapest time at which the solver reaches at most that error. A level below the
smallest error it reached is "not reached"; a level above its cheapest point's error is read
as the cheapest point's time (the frontier is not extrapolated towards cheaper runs).

An end-point error can be small by a cancellation: a run at a loose tolerance whose error
happens to pass near zero at t_end (heyoka's Jellett drift on Fig. 3: 6.9e-9 at tol 1e-5, 8.3e-9
at 1e-6). :func:`cancellations` finds such points (an error below the next tighter tolerance's),
and the benchmark reads every level a second time without them, for every solver alike.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

# the tables are printed by compare.presentation.bench (named here too, as before)
from tippetop.compare.presentation.bench import format_ratio, level_table
from tippetop.compare.results.work_precision import TARGET_RATIO

#: Errors below this are plotted and interpolated as this (a point equal to the truth).
ERROR_FLOOR = 1e-16


def frontier(points: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
    """The monotone (Pareto) hull of (error, time) points, sorted by increasing time.

    Points with a non-finite error or time are dropped; errors are floored at
    :data:`ERROR_FLOOR`. Each point kept has a strictly smaller error than every cheaper one.
    """
    pts = sorted((t, max(e, ERROR_FLOOR)) for e, t in points
                 if math.isfinite(e) and math.isfinite(t) and t > 0)
    out: list[tuple[float, float]] = []
    for t, e in pts:
        if not out or e < out[-1][0]:
            out.append((e, t))
    return out


def time_at_error(points: Iterable[tuple[float, float]], level: float) -> float | None:
    """The time the solver needs to reach at most ``level`` on its frontier; None: not reached.

    Args:
        points: (error, time) pairs.
        level: The error level (> 0).
    """
    hull = frontier(points)
    if not hull or hull[-1][0] > level:
        return None
    if hull[0][0] <= level:
        return hull[0][1]
    for (e0, t0), (e1, t1) in zip(hull, hull[1:], strict=False):
        if e0 > level >= e1:
            w = (math.log(level) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + w * (math.log(t1) - math.log(t0)))
    return None  # pragma: no cover - the hull is monotone, a bracket exists


def smallest_error(points: Iterable[tuple[float, float]]) -> float | None:
    """The smallest finite error among the points (None without one)."""
    errs = [e for e, t in points if math.isfinite(e) and math.isfinite(t)]
    return min(errs) if errs else None


def cancellations(points: Sequence[tuple[float, float, float]]) -> list[float]:
    """The tolerances of a solver's points whose error looks like a cancellation.

    Args:
        points: (rtol, error, time) of one solver, in any order; non-finite errors are left
            out.

    Returns:
        The rtol of each point whose error is below the error at the next tighter tolerance
        (errors floored at :data:`ERROR_FLOOR`, so two points at the floor are not one).
    """
    pts = sorted(((r, max(e, ERROR_FLOOR)) for r, e, _ in points if math.isfinite(e)),
                 reverse=True)
    return [r for (r, e), (_, e_next) in zip(pts, pts[1:], strict=False) if e < e_next]


def without_cancellations(points: Sequence[tuple[float, float, float]]
                          ) -> list[tuple[float, float]]:
    """(error, time) of the points that are not :func:`cancellations`."""
    drop = set(cancellations(points))
    return [(e, t) for r, e, t in points if r not in drop]


def compare_at_levels(points: Mapping[str, Sequence[tuple[float, float]]],
                      references: Sequence[str], auto: str | None, peers: Sequence[str],
                      levels: Sequence[float]) -> list[dict]:
    """Every solver's time at each error level, and the peers' best over the reference's.

    Args:
        points: Per solver, its (error, time) points.
        references: The reference's methods (its time at a level: the fastest of them).
        auto: The reference's default (``auto``) among ``points``, or None.
        peers: The peers.
        levels: The error levels.

    Returns:
        One row per level: ``level``, ``times`` (per solver, s or None), ``smallest`` (per
        solver that does not reach it, its smallest error), ``best_reference`` and
        ``best_peer`` (names or None), ``ratio`` (the fastest peer's time over the fastest
        reference method's; ``inf`` when no peer reaches the level and the reference does;
        None when the reference does not), ``ratio_auto`` (the same over ``auto``'s time),
        ``met`` and ``met_auto`` (ratio >= :data:`TARGET_RATIO`; False when None).
    """
    rows = []
    for level in levels:
        times = {n: time_at_error(p, level) for n, p in points.items()}
        smallest = {n: smallest_error(p) for n, p in points.items() if times[n] is None}

        def best(names: Sequence[str], times: dict = times) -> str | None:
            got = [n for n in names if times.get(n) is not None]
            return min(got, key=lambda n: times[n]) if got else None

        ref, peer = best(references), best(peers)

        def ratio(ours: str | None, peer: str | None = peer, times: dict = times
                  ) -> float | None:
            if ours is None or times.get(ours) is None:
                return None
            return math.inf if peer is None else times[peer] / times[ours]

        r, ra = ratio(ref), ratio(auto)
        rows.append({"level": level, "times": times, "smallest": smallest,
                     "best_reference": ref, "best_peer": peer, "ratio": r, "ratio_auto": ra,
                     "met": r is not None and r >= TARGET_RATIO,
                     "met_auto": ra is not None and ra >= TARGET_RATIO})
    return rows


__all__ = ["ERROR_FLOOR", "TARGET_RATIO", "cancellations", "compare_at_levels", "format_ratio",
           "frontier", "level_table", "smallest_error", "time_at_error",
           "without_cancellations"]
