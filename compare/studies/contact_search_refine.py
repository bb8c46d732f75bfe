"""Is it a limit of MuJoCo? The two-stage search over MuJoCo's whole contact space at one point.

Stage 1 is :mod:`.contact_search`'s even draw over the whole space, with the baselines (the
tuned and calibrated settings and the first one's neighbours). An even draw is thin evidence:
noslip >= 1 stops the inversion and condim 4 and 6 break Jellett's constant (measured), so
only about one in twelve of its candidates lands where a candidate can work. Stage 2 reads
stage 1's evidence to rule categorical cells out (:func:`rule_cells`), and searches the cells
it keeps densely: a Sobol draw over the continuous settings' whole ranges spread evenly over
the kept cells (:func:`dense_draw`); the tuning's own sysid fit
(:mod:`tippetop.compare.tuning.calibrate.identify`)
from the best candidate of each of the :data:`FIT_CELLS` best kept cells, its result verified;
then :data:`ROUNDS` rounds of a local draw around the best candidates so far, in a box in the
unit (log) space that halves each round (:func:`local_draw`), ranked by :func:`.rank_key`.
Every candidate is verified from the point's four starts as the tuning verifies. The whole
search stays within ``budget_runs`` MuJoCo runs (four per candidate, one per fit rollout), and
the first candidate that agrees ends it.

**The rule.** A cell is one choice of each of cone, condim, noslip, integrator and step. A
choice (one value of one of those dimensions, e.g. noslip = 5) is ruled out when

1. at least :data:`MIN_EVIDENCE` of its stage-1 candidates ran (completed from a verifiable
   start; for the reason "diverges", every candidate counts);
2. one reason, a check failing from some start (the turn-over and the stem's landing split
   into "missing" and "mistimed"), is shown by every one of them ("at every draw");
3. the reason is tied to the choice: at least one candidate with another value of the same
   dimension does not show it (a reason every candidate shows, such as the outcome where the
   reference itself ends inconclusive, says nothing about the choice); and
4. the reason is not explained by another choice: at least :data:`MIN_CLEAN` of those
   candidates have no other choice that 1-3 rule out for the same reason.

A cell is kept when none of its choices is ruled out, and always when it is the tuned
settings' or that of one of the :data:`BEST_CELLS` best stage-1 candidates.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from tippetop.compare.studies import contact_search as cs
from tippetop.compare.studies.contact_search import ContactCandidate, PointRuns, rank_key
from tippetop.compare.studies.fidelity import CAUSE_ORDER, START_THETA0
from tippetop.compare.tuning.calibrate.identify import (
    MAX_ITERS,
    Bounds,
    FitStart,
    Problem,
    identify,
    reference_theta,
)
from tippetop.compare.tuning.calibrate.scoring import Candidate
from tippetop.compare.tuning.tune import HELD_OUT, fit_horizon
from tippetop.models.errors import TippetopError
from tippetop.models.scene import Override

#: MuJoCo runs a search may use by default (``--budget-runs``): about 10 min on 2 cores at
#: 8-s runs (1199 runs took 795 s at a load of 4 to 5 from other work, 666 runs 300 s at 2
#: to 3; measured at A/C 1, a/R 0.1, mu 0.3).
DEFAULT_BUDGET_RUNS = 1000
#: Stage 1 takes at most this share of the budget (its draw shrinks to fit; the rest is
#: stage 2's).
STAGE1_SHARE = 0.5
#: The categorical dimensions that make a cell, and their choices.
CELL_DIMENSIONS = ("cone", "condim", "noslip_iterations", "integrator", "timestep_s")
CHOICES: dict[str, tuple[Any, ...]] = {
    "cone": cs.CONES, "condim": cs.CONDIMS, "noslip_iterations": cs.NOSLIP_ITERATIONS,
    "integrator": cs.INTEGRATORS, "timestep_s": cs.TIMESTEPS_S}
#: The rule's thresholds (module docstring): candidates that ran, and candidates without
#: another ruled-out choice.
MIN_EVIDENCE = 3
MIN_CLEAN = 3
#: The cells of this many best stage-1 candidates are always kept.
BEST_CELLS = 3
#: Stage 2's shares: the fits (of the runs left after stage 1), then the Sobol draw (of the
#: candidates left); the local rounds take the rest.
FIT_SHARE = 0.3
DENSE_SHARE = 0.5
#: Fits from the best candidate of this many kept cells, each within this many rollouts.
FIT_CELLS = 3
FIT_ROLLOUTS = 40
#: Local rounds, the candidates each is centred on, and the box's half-width per round
#: (unit coordinates: log space for log-scaled settings).
ROUNDS = 3
ELITES = 3
BOX = (0.2, 0.1, 0.05)
#: The continuous dimensions (unit coordinates) the local draw moves.
CONTINUOUS = tuple(d for d in cs.DIMENSIONS if d not in (*CELL_DIMENSIONS, "solref_form",
                                                       "impedance", "pairs"))
#: Each reason in words.
REASONS = {"completed": "the run diverges", "stays_on_table": "the ball leaves the table",
           "outcome": "the outcome departs", "t_invert": "it turns over at another time",
           "t_invert: missing": "it does not turn over (the reference does)",
           "t_invert: extra": "it turns over (the reference does not)",
           "t_stem": "the stem lands at another time",
           "t_stem: missing": "the stem does not land (the reference's does)",
           "t_stem: extra": "the stem lands (the reference's does not)",
           "jellett_before_stem": "Jellett's constant drifts",
           "energy_never_rises": "the energy rises"}


# ---------------------------------------------------------------- the rule
def cell_of(settings: dict[str, Any]) -> tuple[Any, ...]:
    """A candidate's cell (:data:`CELL_DIMENSIONS`) from its settings."""
    return tuple(settings[d] for d in CELL_DIMENSIONS)


def cell_json(cell: Sequence[Any]) -> dict[str, Any]:
    """A cell as its dimensions name it."""
    return dict(zip(CELL_DIMENSIONS, cell, strict=True))


def reasons(row: dict[str, Any]) -> set[str]:
    """Why a candidate departs: each check failing from some verifiable start (:data:`REASONS`).

    An event check without the run's event is ``t_invert: missing`` (the reference has it) or
    ``t_invert: extra`` (the run only), with one ``t_invert``.
    """
    out = set()
    for v in row["verified"]:
        for c in v["checks"] if v.get("passed") is not None else ():
            if c["passed"] is False:
                name = c["check"]
                if name in ("t_invert", "t_stem") and c.get("value") is None:
                    name += (": missing" if "the reference only" in (c.get("note") or "")
                             else ": extra")
                out.add(name)
    return out


def ran(row: dict[str, Any]) -> bool:
    """Whether a candidate completed from at least one verifiable start."""
    return any(v.get("passed") is not None
               and not any(c["check"] == "completed" and c["passed"] is False
                           for c in v["checks"]) for v in row["verified"])


def _reason_order(r: str) -> int:
    head = r.split(":")[0]
    return CAUSE_ORDER.index(head) if head in CAUSE_ORDER else len(CAUSE_ORDER)


def rule_cells(rows: list[dict[str, Any]], pinned: Sequence[tuple[Sequence[Any], str]] = ()
               ) -> dict[str, Any]:
    """The cells stage 2 keeps, from stage 1's rows (``verified`` kept), by the module's rule.

    Args:
        rows: Stage 1's candidates, verified.
        pinned: (cell, why) always kept: the tuned settings' and the best candidates'.

    Returns:
        ``rule`` (the rule in words), ``choices`` ([{dimension, value, candidates, ran,
        ruled_out, reason, counts, why}]), ``kept_values`` ({dimension: [values]}), ``cells``
        ([{cone, condim, noslip_iterations, integrator, timestep_s, why}]), ``cells_kept``
        and ``cells_total``.
    """
    info = [(cell_of(r["settings"]), reasons(r), ran(r)) for r in rows]
    every = set().union(*(x[1] for x in info)) if info else set()

    def pool(k: int, value: Any, r: str, same: bool) -> list[tuple[Any, ...]]:
        return [x for x in info if (x[0][k] == value) == same and (r == "completed" or x[2])]

    tied: dict[tuple[str, Any], dict[str, dict[str, int]]] = {}
    for k, dim in enumerate(CELL_DIMENSIONS):
        for value in CHOICES[dim]:
            for r in sorted(every, key=lambda s: (_reason_order(s), s)):
                ev, others = pool(k, value, r, True), pool(k, value, r, False)
                if (len(ev) >= MIN_EVIDENCE and all(r in x[1] for x in ev)
                        and any(r not in x[1] for x in others)):
                    tied.setdefault((dim, value), {})[r] = {
                        "shows": len(ev), "of": len(ev),
                        "elsewhere_shows": sum(r in x[1] for x in others),
                        "elsewhere_of": len(others)}
    choices = []
    kept_values: dict[str, list[Any]] = {}
    for k, dim in enumerate(CELL_DIMENSIONS):
        for value in CHOICES[dim]:
            mine = [x for x in info if x[0][k] == value]
            found = {}
            for r, counts in tied.get((dim, value), {}).items():
                clean = [x for x in pool(k, value, r, True)
                         if not any(r in tied.get((d2, x[0][k2]), {})
                                    for k2, d2 in enumerate(CELL_DIMENSIONS) if k2 != k)]
                found[r] = {**counts, "clean": len(clean)}
            good = {r: c for r, c in found.items() if c["clean"] >= MIN_CLEAN}
            reason = (min(good, key=lambda r: (good[r]["elsewhere_shows"]
                                               / max(1, good[r]["elsewhere_of"]),
                                               _reason_order(r), r)) if good else None)
            n_ran = sum(x[2] for x in mine)
            choices.append({"dimension": dim, "value": value, "candidates": len(mine),
                            "ran": n_ran, "ruled_out": reason is not None, "reason": reason,
                            "counts": good.get(reason) if reason else None,
                            "why": _why(mine, n_ran, reason, good, found, every,
                                        sum(x[2] for x in info) - n_ran)})
            if reason is None:
                kept_values.setdefault(dim, []).append(value)
    kept = {c: "no choice of it ruled out" for c in itertools.product(
        *(kept_values.get(d, []) for d in CELL_DIMENSIONS))}
    for cell, why in pinned:
        cell = tuple(cell)
        if cell not in kept:
            kept[cell] = f"kept as {why}"
    return {"rule": RULE, "choices": choices, "kept_values": kept_values,
            "cells": [{**cell_json(c), "why": w} for c, w in kept.items()],
            "cells_kept": len(kept), "cells_total": math.prod(len(v) for v in CHOICES.values())}


RULE = (f"a choice (a value of cone, condim, noslip, integrator or step) is ruled out when at "
        f"least {MIN_EVIDENCE} of its stage-1 candidates ran and every one of them departs "
        f"for one reason (a check failing from some start), at least one candidate with "
        f"another value of that dimension does not, and at least {MIN_CLEAN} of them have no "
        f"other choice ruled out for that reason; a cell is kept when none of its choices "
        f"is ruled out, and always for the tuned settings and the {BEST_CELLS} best stage-1 "
        f"candidates")


def _why(mine: list[Any], n_ran: int, reason: str | None, good: dict[str, Any],
         found: dict[str, Any], every: set[str], others_ran: int) -> str:
    """A choice's verdict in words, with the counts it rests on."""
    if reason is not None:
        c = good[reason]
        return (f"ruled out: {REASONS.get(reason, reason)} in all {c['of']} of its candidates "
                f"that ran, in {c['elsewhere_shows']} of {c['elsewhere_of']} elsewhere; "
                f"{c['clean']} of them have no other choice ruled out for it")
    if found:
        r, c = next(iter(found.items()))
        return (f"kept: {REASONS.get(r, r)} in all {c['of']} of its candidates that ran, but "
                f"only {c['clean']} of them have no other choice ruled out for it (the rule "
                f"needs {MIN_CLEAN})")
    if n_ran < MIN_EVIDENCE:
        return (f"kept: {n_ran} of its {len(mine)} candidates ran, too few to rule it out "
                f"(the rule needs {MIN_EVIDENCE})")
    common = [r for r in sorted(every, key=_reason_order)
              if all(r in x[1] for x in mine if x[2])]
    if common:
        return (f"kept: {REASONS.get(common[0], common[0])} in all {n_ran} of its candidates "
                f"that ran, but also in all {others_ran} that ran elsewhere: not tied to it")
    return f"kept: no reason is shared by all {n_ran} of its candidates that ran"


# ---------------------------------------------------------------- the dense and local draws
def dense_draw(cells: Sequence[dict[str, Any]], n: int, mu: float,
               seed: int) -> list[ContactCandidate]:
    """``n`` candidates over the continuous settings' whole ranges, the cells by rank.

    A scrambled Sobol sequence (seeded ``seed``) as in stage 1: each cell takes an equal share
    (by rank of one column), the forms their shares, each continuous setting its whole range.
    """
    if n <= 0 or not cells:
        return []
    u = cs.sobol_unit(n, len(cs.DIMENSIONS), seed)
    col = {name: u[:, k] for k, name in enumerate(cs.DIMENSIONS)}
    where = cs.by_rank(col["cone"], list(range(len(cells))))
    forms = cs.form_columns(col)
    return [cs.candidate_at({k: float(v[i]) for k, v in col.items()},
                            {**{d: cells[where[i]][d] for d in CELL_DIMENSIONS},
                             **{f: v[i] for f, v in forms.items()}}, mu, origin="dense")
            for i in range(n)]


def local_draw(elites: Sequence[ContactCandidate], n: int, mu: float, seed: int,
               half_width: float) -> list[ContactCandidate]:
    """``n`` candidates around the elites: each its share, in its cell and forms.

    Sobol points in a box of ``half_width`` about each elite's unit coordinates (log space for
    the log-scaled settings), clipped to the unit cube: inside the search's ranges.
    """
    if n <= 0 or not elites:
        return []
    out: list[ContactCandidate] = []
    for j, e in enumerate(elites):
        m = n // len(elites) + (j < n % len(elites))
        if m == 0:
            continue
        u0, cell = cs.unit_of(e, mu)
        box = cs.sobol_unit(m, len(CONTINUOUS), seed * 1000 + j)
        for row in box:
            u = dict(u0)
            for k, name in enumerate(CONTINUOUS):
                u[name] = float(min(1.0, max(0.0, u0[name] + (2.0 * row[k] - 1.0) * half_width)))
            out.append(cs.candidate_at(u, cell, mu, origin="local"))
    return out


def _continuous_key(c: ContactCandidate) -> tuple[Any, ...]:
    """The continuous settings of a candidate (to tell near-copies in other cells apart)."""
    j = c.to_json()
    return tuple(json_key(j[k]) for k in ("cone", "impratio", "solref", "solimp", "mu",
                                          "solreffriction"))


def json_key(v: Any, exact: bool = False) -> Any:
    """A hashable form of a JSON value: lists as tuples, floats at 3 significant digits.

    With ``exact``, floats as they are.
    """
    if isinstance(v, list | tuple):
        return tuple(json_key(x, exact) for x in v)
    return float(f"{v:.2e}") if isinstance(v, float) and not exact else v


def elites_of(rows: list[dict[str, Any]], cells: set[tuple[Any, ...]],
              n: int = ELITES) -> list[ContactCandidate]:
    """The ``n`` best candidates in the kept cells, near-copies (other cell only) left out."""
    out: list[ContactCandidate] = []
    seen: set[tuple[Any, ...]] = set()
    for r in sorted(rows, key=rank_key):
        c = cs.candidate_from_settings(r["settings"], r["settings"]["origin"])
        key = _continuous_key(c)
        if cell_of(r["settings"]) in cells and key not in seen:
            seen.add(key)
            out.append(c)
            if len(out) == n:
                break
    return out


# ---------------------------------------------------------------- the fit
def fit_candidate(seed: ContactCandidate,
                  mu: float) -> tuple[Candidate, tuple[str, ...], Bounds]:
    """The sysid fit's seed, the settings it varies and their bounds, from a candidate.

    It varies mu, impratio, d0 (a ramp's), the time constant and damping ratio (not a direct
    solref's) and the friction rows' damping (on pairs), within the search's ranges (mu
    within a factor 2 of the law's ``mu``); the rest stays the seed's.
    """
    d0, dmax, *tail = seed.solimp
    direct = seed.solref[0] < 0
    cand = Candidate(seed.cone, seed.impratio, 0.02 if direct else seed.solref[0], d0,
                     seed.mu, dampratio=1.0 if direct else seed.solref[1],
                     solimp_tail=(dmax, *tail),  # type: ignore[arg-type]
                     solref_direct=seed.solref if direct else None,
                     frictiondamping=None if seed.solreffriction is None
                     else -seed.solreffriction[1])
    bounds = {"mu": (mu / cs.MU_FACTOR, mu * cs.MU_FACTOR), "impratio": cs.IMPRATIO}
    if d0 < dmax:
        bounds["d0"] = (cs.D0[0], min(cs.D0[1], dmax))
    if not direct:
        bounds["timeconst_s"] = (2.0 * seed.timestep_s, cs.TIMECONST_MAX_S)
        bounds["dampratio"] = cs.DAMPRATIO
    if seed.solreffriction is not None:
        bounds["frictiondamping"] = cs.FRICTION_DAMPING
    return cand, tuple(bounds), Bounds(dict(bounds))


def from_fit(found: Candidate, seed: ContactCandidate) -> ContactCandidate:
    """The fit's settings as a candidate in the seed's cell (origin ``fit``)."""
    srf = found.solreffriction
    return replace(seed, impratio=found.impratio, mu=found.mu,
                   solref=tuple(found.solref),  # type: ignore[arg-type]
                   solimp=tuple(found.solimp),  # type: ignore[arg-type]
                   solreffriction=None if srf is None else (srf[0], srf[1]), origin="fit")


def run_fit(pr: PointRuns, seed: ContactCandidate, rollouts: int, max_iters: int,
            threads: int) -> tuple[ContactCandidate, dict[str, Any]]:
    """The tuning's sysid fit (:func:`.identify`) from ``seed`` at the fit's start.

    Returns:
        The fitted candidate and ``{from, to, rms_from_rad, rms_rad, rollouts, iterations,
        stop}``.
    """
    ref = pr.refs[0]
    start = pr.starts[0]
    t_fit = fit_horizon(ref.summary or {}, pr.t_end_s)
    fs = FitStart(start.label(), None,
                  (*pr.base, *start.overrides(), Override.of("run.t_end_s", t_fit),
                   Override.of("mujoco.condim", seed.condim),
                   Override.of("mujoco.noslip_iterations", seed.noslip_iterations)), t_fit)
    cand, fitted, bounds = fit_candidate(seed, pr.point["mu"])
    stem = (ref.summary or {}).get("t_stem")
    problem = Problem([fs], [reference_theta(ref.table, t_fit)], seed.timestep_s,
                      seed.integrator, bounds, threads, [math.inf if stem is None
                                                         else float(stem)], fitted=fitted)
    problem.budget = rollouts
    found = identify(problem, [cand], max_iters=max_iters)
    fit = found.fits[0] if found.fits else {}
    out = from_fit(found.best, seed)
    return out, {"from": seed.label(), "to": out.label(), "fitted": list(fitted),
                 "rms_from_rad": found.seeds[0]["rms_rad"] if found.seeds else None,
                 "rms_rad": found.rms_rad, "rollouts": problem.rollouts,
                 "iterations": fit.get("iterations", 0), "stop": fit.get("stop", "budget")}


# ---------------------------------------------------------------- the search
@dataclass(frozen=True)
class SearchOptions:
    """How :func:`search_two_stage` searches: its draw, its budget, its stages and fits.

    Checked by :func:`search_two_stage` (one line naming the script's option), not here.

    Attributes:
        candidates: Candidates stage 1 draws besides the baselines (fewer where its share
            of the budget, :data:`STAGE1_SHARE`, is smaller).
        seed: The draws' seed (stage 2's Sobol draw takes ``seed + 1``).
        batch: Candidates verified per call of the runner.
        with_neighbours: Also the first baseline's neighbours (each choice changed alone).
        budget_runs: MuJoCo runs the whole search may use: four per candidate (cached or
            not), one per fit rollout.
        stages: 1 (the even draw alone, the whole budget its) or 2.
        fit: Run the sysid fits of stage 2.
        fit_rollouts: Rollouts each fit may use.
        fit_iters: Levenberg-Marquardt iterations per fit at most.
        stop_on_agree: End the search after the part (of stage 1 or 2) in which a candidate
            agrees.
    """

    candidates: int = cs.DEFAULT_CANDIDATES
    seed: int = 0
    batch: int = cs.BATCH
    with_neighbours: bool = True
    budget_runs: int = DEFAULT_BUDGET_RUNS
    stages: int = 2
    fit: bool = True
    fit_rollouts: int = FIT_ROLLOUTS
    fit_iters: int = MAX_ITERS
    stop_on_agree: bool = True


DEFAULT_SEARCH = SearchOptions()


def search_two_stage(A_over_C: float, a_over_R: float, mu: float, *, n0: float | None = None,
                     theta0: float = START_THETA0, t_end_s: float = cs.DEFAULT_T_END_S,
                     tuned: dict[str, Any] | None = None,
                     options: SearchOptions = DEFAULT_SEARCH,
                     run_options: dict[str, Any] | None = None, progress: bool = False
                     ) -> dict[str, Any]:
    """Search MuJoCo's whole contact space at one point: the even draw, then the dense stage.

    Args:
        A_over_C: The top's A/C.
        a_over_R: The top's a/R.
        mu: The law's friction coefficient.
        n0: The fit's start spin (rad/s; None: the fidelity map's).
        theta0: The fit's start tilt (rad).
        t_end_s: Horizon of every run (s).
        tuned: The point's tuned settings (a fidelity map's ``settings``): a baseline.
        options: The draw, the budget, the stages and the fits (:class:`SearchOptions`).
        run_options: Keyword arguments of :func:`.run_tasks` (scheduler, workers, use_cache).
        progress: A line per batch on a terminal.

    Returns:
        :func:`assemble`'s keys, and ``stages`` (each with its candidates, runs, wall time,
        cells kept and why, and best), ``limit`` (one line) and ``budget_runs``.

    Raises:
        TippetopError: Bad input (one line), before any run.
        RunFailedError: A reference run that failed.
    """
    budget_runs, stages, batch = options.budget_runs, options.stages, options.batch
    candidates, seed = options.candidates, options.seed
    n_starts = 1 + len(HELD_OUT)  # the fit's start and the held-out ones (.tune.starts_for)
    if not isinstance(budget_runs, int) or budget_runs < n_starts:
        raise TippetopError(f"--budget-runs: expected at least {n_starts} (one candidate "
                            f"from its {n_starts} starts), got {budget_runs!r}")
    if stages not in (1, 2):
        raise TippetopError(f"--stages: expected 1 or 2, got {stages!r}")
    if batch < 1:
        raise TippetopError(f"batch: expected at least 1 candidate, got {batch!r}")
    if not isinstance(candidates, int) or isinstance(candidates, bool) or candidates < 0:
        raise TippetopError(f"--candidates: expected a whole number >= 0, got {candidates!r}")
    cs.draw_candidates(0, mu, seed)  # checks mu
    cap = budget_runs // n_starts
    cap1 = cap if stages == 1 else max(1, int(STAGE1_SHARE * cap))
    base = cs.baselines(tuned, mu, options.with_neighbours)[:cap1]
    drawn = cs.draw_candidates(min(candidates, cap1 - len(base)), mu, seed)
    say = cs.say_to_terminal(progress)
    t0 = time.perf_counter()
    pr = cs.prepare_point(A_over_C, a_over_R, mu, n0=n0, theta0=theta0, t_end_s=t_end_s,
                       run_options=run_options, say=say)
    seen: set[Any] = set()
    rows: list[dict[str, Any]] = []

    def verify(cands: list[ContactCandidate], stage: int, label: str) -> list[dict[str, Any]]:
        fresh = []
        for c in cands:
            key = json_key([v for k, v in c.to_json().items() if k != "origin"], exact=True)
            if key not in seen:
                seen.add(key)
                fresh.append(c)
        got = pr.verify(fresh, len(rows), batch, say, label)
        for r in got:
            r["stage"] = stage
        rows.extend(got)
        return got

    verify(base + drawn, 1, "stage 1")
    first = {"stage": 1, "name": "even draw", "candidates": len(rows), "drawn": len(drawn),
             "drawn_asked": candidates,
             "baselines": {o: sum(r["settings"]["origin"] == o for r in rows)
                           for o in dict.fromkeys(c.origin for c in base)},
             "runs": pr.runs, "wall_s": time.perf_counter() - t0,
             "cells": {"kept": math.prod(len(v) for v in CHOICES.values()),
                       "of": math.prod(len(v) for v in CHOICES.values()),
                       "why": "the whole space: the draw takes every choice by rank"},
             "best": brief(min(rows, key=rank_key)) if rows else None}
    fit_runs = [0]
    second = (_stage_two(pr, rows, verify, base, options, n_starts, fit_runs, say)
              if stages == 2 else None)
    out = assemble(pr, rows, drawn=len(drawn), seed=seed, wall_s=time.perf_counter() - t0)
    out["runs"].update(mujoco=pr.runs + fit_runs[0], candidate_runs=pr.runs,
                       fit_rollouts=fit_runs[0])
    out["budget_runs"] = budget_runs
    out["stages"] = [first] + ([second] if second else [])
    out["limit"] = limit_line(out)
    return out


def _stage_two(pr: PointRuns, rows: list[dict[str, Any]],
               verify: Callable[[list[ContactCandidate], int, str], list[dict[str, Any]]],
               base: list[ContactCandidate], options: SearchOptions, n_starts: int,
               fit_runs: list[int], say: Callable[[str], None] | None) -> dict[str, Any]:
    """Stage 2 (module docstring): the rule, the dense draw, the fits, the local rounds."""
    budget_runs, seed, stop_on_agree = options.budget_runs, options.seed, options.stop_on_agree
    fit, fit_rollouts, fit_iters = options.fit, options.fit_rollouts, options.fit_iters
    t0 = time.perf_counter()
    runs0 = pr.runs
    n1 = len(rows)
    mu = pr.point["mu"]
    head: dict[str, Any] = {"stage": 2, "name": "dense"}
    if stop_on_agree and any(r["agrees"] for r in rows):
        return {**head, "skipped": f"stage 1 found {sum(r['agrees'] for r in rows)} "
                                   f"agreeing candidate(s)"}
    left = budget_runs - pr.runs
    per_fit = fit_rollouts + n_starts
    n_fit = min(FIT_CELLS, int(FIT_SHARE * left) // per_fit) if fit and fit_rollouts > 0 else 0
    if left < n_starts:
        return {**head, "skipped": f"the budget ({budget_runs} runs) was spent by stage 1"}
    pinned = [(cell_of(c.to_json()), "the tuned settings' cell") for c in base
              if c.origin == "tuned"]
    pinned += [(cell_of(r["settings"]), f"the cell of stage 1's best #{k + 1}")
               for k, r in enumerate(sorted(rows, key=rank_key)[:BEST_CELLS])]
    rule = rule_cells(rows, pinned)
    kept = {cell_of(c) for c in rule["cells"]}
    parts = []

    def agreed() -> bool:
        return stop_on_agree and any(r["agrees"] for r in rows)

    n_dense = math.ceil(DENSE_SHARE * ((left - n_fit * per_fit) // n_starts))
    got = verify(dense_draw(rule["cells"], n_dense, mu, seed + 1), 2, "stage 2 dense")
    parts.append({"part": "dense", "seed": seed + 1, "candidates": len(got),
                  "cells": len(kept)})
    fits = []
    best_of: dict[tuple[Any, ...], dict[str, Any]] = {}
    for r in sorted(rows, key=rank_key):  # the best candidate of each kept cell, best first
        if cell_of(r["settings"]) in kept:
            best_of.setdefault(cell_of(r["settings"]), r)
    for k, row in enumerate(list(best_of.values())[:n_fit if not agreed() else 0]):
        if budget_runs - pr.runs - fit_runs[0] < per_fit or agreed():
            break
        start = cs.candidate_from_settings(row["settings"], "fit")
        if say:
            say(f"stage 2 fit {k + 1}/{n_fit} from {start.label()} ...")
        from tippetop.mujoco_runner.batch import default_threads

        threads = int(pr.options.get("workers") or 0) or default_threads()
        found, info = run_fit(pr, start, fit_rollouts, fit_iters, threads)
        fit_runs[0] += info["rollouts"]
        got = verify([found], 2, "stage 2 fit")
        fits.append({**info, "duplicate": not got,
                     "passes": got[0]["passes"] if got else None,
                     "checks": got[0]["checks"] if got else None,
                     "agrees": got[0]["agrees"] if got else None})
    if n_fit:
        parts.append({"part": "fit", "candidates": len(fits), "fits": fits,
                      "rollouts": sum(f["rollouts"] for f in fits)})
    for k in range(ROUNDS):
        room = (budget_runs - pr.runs - fit_runs[0]) // n_starts
        if agreed() or room < 1:
            break
        elites = elites_of(rows, kept)
        got = verify(local_draw(elites, room // (ROUNDS - k), mu, seed + 2 + k, BOX[k]), 2,
                     f"stage 2 local {k + 1}")
        parts.append({"part": f"local {k + 1}", "half_width": BOX[k], "seed": seed + 2 + k,
                      "elites": [e.label() for e in elites], "candidates": len(got)})
    mine = rows[n1:]
    return {**head, "candidates": len(mine), "runs": pr.runs - runs0 + fit_runs[0],
            "fit_rollouts": fit_runs[0], "wall_s": time.perf_counter() - t0, "cells": rule,
            "parts": parts, "best": brief(min(mine, key=rank_key)) if mine else None}


# ---------------------------------------------------------------- the answer
def departing(row: dict[str, Any]) -> dict[str, int]:
    """Each check that departs, and from how many starts (the fidelity map's order first).

    From a row's ``verified`` starts, or else from its ``departs`` (a top row's).
    """
    out: dict[str, int] = {}
    failed = ([c for v in row["verified"] for c in v["checks"] if c["passed"] is False]
              if "verified" in row else row.get("departs") or [])
    for c in failed:
        out[c["check"]] = out.get(c["check"], 0) + 1
    order = {n: i for i, n in enumerate(CAUSE_ORDER)}
    return dict(sorted(out.items(), key=lambda kv: (order.get(kv[0], len(order)), kv[0])))


def brief(row: dict[str, Any]) -> dict[str, Any]:
    """A candidate in short: settings, origin, stage, checks passing, what departs."""
    return {"label": row["label"], "origin": row["settings"]["origin"],
            "stage": row.get("stage"), "agrees": row["agrees"], "passes": row["passes"],
            "checks": row["checks"], "departures": row["departures"],
            "departing": departing(row), "theta_rms_rad": row["theta_rms_rad"],
            "cause": row["cause"]}


def assemble(pr: PointRuns, rows: list[dict[str, Any]], *, drawn: int, seed: int,
             wall_s: float) -> dict[str, Any]:
    """The search's answer from its rows (every candidate verified), best first.

    Returns:
        ``format``, ``point``, ``starts``, ``space``, ``seed``, ``method``, ``t_end_s``,
        ``engine``, ``mujoco_version``, ``candidates_evaluated``, ``drawn``, ``origins``
        ({origin: count}), ``runs`` ({mujoco, reference, cached}), ``wall_s``, ``agrees``,
        ``agreeing``, ``best``, ``top`` (the :data:`.TOP` best, with their departing checks),
        ``candidates`` (every row, best first) and ``attribution`` (of stage 1's drawn
        ones).
    """
    import mujoco

    from tippetop.compare.measures.verdict import run_entry

    ordered = sorted(rows, key=rank_key)
    top_rows = [{**{k: v for k, v in r.items() if k != "verified"},
                 "departs": [{"check": c["check"], "role": v["role"], "n0": v["n0"],
                              "theta0": v["theta0"], "value": c["value"], "note": c["note"]}
                             for v in r["verified"] for c in v["checks"]
                             if c["passed"] is False]} for r in ordered[:cs.TOP]]
    agreeing = [r for r in rows if r["agrees"]]
    mu = pr.point["mu"]
    origins = dict.fromkeys(r["settings"]["origin"] for r in rows)
    return {
        "format": cs.FORMAT, "point": dict(pr.point),
        "starts": [{"n0": s.n0, "theta0": s.theta0, "role": s.role, "label": s.label(),
                    "theory": dict(zip(("theta_s", "outcome"), pr.outcome_at(s.n0, s.theta0),
                                       strict=True)),
                    "reference": {k: f.get(k) for k in ("status", "outcome", "theta_asymp",
                                                        "t_invert", "t_stem", "t_left_table")}}
                   for s, f in zip(pr.starts, map(run_entry, pr.refs), strict=True)],
        "space": cs.space(mu), "seed": seed,
        "method": "stage 1: scrambled Sobol (scipy.stats.qmc) over the whole space, "
                  "categorical dimensions by rank; stage 2: the cells the rule keeps, a Sobol "
                  "draw over the continuous settings' ranges, sysid fits from the best cells, "
                  "local Sobol draws in a halving box about the best (rank_key)",
        "t_end_s": pr.t_end_s, "engine": "mujoco", "mujoco_version": mujoco.__version__,
        "candidates_evaluated": len(rows), "drawn": drawn,
        "origins": {o: sum(r["settings"]["origin"] == o for r in rows) for o in origins},
        "runs": {"mujoco": pr.runs, "reference": len(pr.refs), "cached": pr.cached},
        "wall_s": wall_s, "agrees": bool(agreeing), "agreeing": len(agreeing),
        "best": top_rows[0] if top_rows else None, "top": top_rows,
        "candidates": [{k: v for k, v in r.items() if k != "verified"} for r in ordered],
        "attribution": cs.attribution(rows, mu),
    }


def limit_line(result: dict[str, Any]) -> str:
    """The search's statement in one line: what agrees, or that nothing does and how close."""
    n = result["candidates_evaluated"]
    if result["agreeing"]:
        b = result["best"]
        return (f"agrees: {b['label']} (stage {b.get('stage', 1)}, {b['settings']['origin']}; "
                f"{result['agreeing']} of {n} candidates agree)")
    parts = []
    for s in result.get("stages") or []:
        if s.get("skipped"):
            parts.append(f"stage {s['stage']}: not run, {s['skipped']}")
        elif s["stage"] == 1:
            parts.append(f"stage 1: {s['candidates']} candidates, {s['drawn']} of them drawn "
                         f"evenly over all {s['cells']['of']} cells")
        else:
            pieces = {p["part"].split(" ")[0]: 0 for p in s["parts"]}
            for p in s["parts"]:
                pieces[p["part"].split(" ")[0]] += p["candidates"]
            parts.append(f"stage 2: {s['candidates']} in the {s['cells']['cells_kept']} cells "
                         f"kept (" + ", ".join(f"{v} {k}" for k, v in pieces.items()) + ")")
    best = result["best"]
    if best is None:
        return f"no candidate was evaluated ({'; '.join(parts)})"
    dep = departing(best)
    return (f"no candidate of {n} over the whole space ({'; '.join(parts)}) agrees; the "
            f"closest passes {best['passes']} of {best['checks']} checks, departing on "
            + ", ".join(f"{k} (from {v} start{'s' if v > 1 else ''})" for k, v in dep.items())
            + f": {best['label']}")


__all__ = ["BEST_CELLS", "BOX", "CELL_DIMENSIONS", "CHOICES", "DEFAULT_BUDGET_RUNS",
           "DEFAULT_SEARCH", "DENSE_SHARE", "ELITES", "FIT_CELLS", "FIT_ROLLOUTS", "FIT_SHARE",
           "MIN_CLEAN", "MIN_EVIDENCE", "REASONS", "ROUNDS", "RULE", "STAGE1_SHARE",
           "SearchOptions", "assemble", "brief", "cell_json", "cell_of", "dense_draw",
           "departing", "elites_of", "fit_candidate", "from_fit", "json_key", "limit_line",
           "local_draw", "ran", "reasons", "rule_cells", "run_fit", "search_two_stage"]
