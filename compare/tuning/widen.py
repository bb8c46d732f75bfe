"""The tuning's widening: where the fits and their seeds depart, the answer's neighbours.

The answer with one discrete choice changed at a time (integrator, step, cone), each verified
from every start, then a fit at the best of those, then draws in a small box about the best so
far (:func:`widen`, :func:`local_candidates`), from runs kept back for it
(:func:`widen_reserve`). Measured on the fidelity map before it existed
(docs/guide/fidelity.md, "Beyond the tuning"): of the four settings that the tuning missed
and a search over MuJoCo's whole contact space found, one was its own answer with Euler in
place of RK4, one a fit from it at Euler, one a local draw about it. With the neighbours and
the draws the map's tuning agrees at those three points and at a fourth where the search did
not; at the last, the search's settings lie far from the tuning's (impratio 24 against 0.6).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from tippetop.compare.measures.summary import FileContacts
from tippetop.compare.measures.verdict import FIRST_ORDER, run_entry
from tippetop.compare.tuning.calibrate.identify import (
    DAMPRATIO_BOUNDS,
    Bounds,
    FitStart,
    Problem,
    identify,
)
from tippetop.compare.tuning.calibrate.scoring import Candidate
from tippetop.compare.tuning.judge import (
    N_STARTS,
    WIDENED,
    agrees,
    departs,
    min_budget_runs,
    mjcf_block,
    passes,
    widening_step,
)
from tippetop.compare.tuning.sobol import sobol_unit

#: One run in this many of ``--budget-runs`` is kept back for the widening (:func:`widen`):
#: the fits and their seeds use the rest, so that at the default budget they have the 200
#: runs they had before there was a widening, and a file they agree on is tuned as then.
WIDEN_ONE_IN = 3
#: The widening's integrators (each at the fit's step) and its shorter step (this times the
#: fit's, at the fit's integrator). Measured on the fidelity map (docs/guide/fidelity.md,
#: "searches"): at A/C 1, a/R 0.25, mu 1 the fit's settings departed at RK4 and agreed from
#: every start with Euler; at mu 0.3 a fit at Euler agreed where the fit at RK4 departed.
WIDEN_INTEGRATORS = ("RK4", "Euler", "implicitfast")
WIDEN_STEP_FACTOR = 0.5
#: The local draw (:func:`local_candidates`): at most this many candidates, in a box of this
#: half-width (decades) about the best so far in each fitted setting and the damping ratio,
#: from a scrambled Sobol sequence with this seed; the refit leaves runs for this many.
#: Measured on the fidelity map before it existed: at A/C 1, a/R 0.25, mu 0.3, 2 of 16 such
#: draws about the refit at Euler (19 of 20 checks) agreed from every start, and the search
#: over MuJoCo's whole contact space found its agreeing settings within 0.15 decade of the
#: tuning's at A/C 0.8, a/R 0.25, mu 1 (docs/data/contact-searches.json).
LOCAL_MAX = 16
LOCAL_HALF_DECADES = 0.1
LOCAL_SEED = 0
LOCAL_KEEP = 8


def widen_reserve(budget_runs: int) -> int:
    """The runs of ``budget_runs`` kept for the widening (one in :data:`WIDEN_ONE_IN`).

    None below a widening's smallest use (two neighbours verified); the fits always keep at
    least :func:`min_budget_runs`.
    """
    reserve = min(budget_runs // WIDEN_ONE_IN, budget_runs - min_budget_runs())
    return reserve if reserve >= 2 * N_STARTS else 0


def widen_neighbours(best: Candidate, timestep: float, integrator: str,
                     A_over_C: float | None) -> list[tuple[str, Candidate, float, str]]:
    """The answer with one discrete choice changed at a time: ``(what, cand, step, integ)``.

    Each of :data:`WIDEN_INTEGRATORS` at the same step (a first-order one only on a top with
    A = C: elsewhere it moves Jellett's constant in proportion to dt, docs/design.md), the
    step times :data:`WIDEN_STEP_FACTOR`, and the other cone (a pyramidal one without the
    friction rows' own damping, which MuJoCo takes in an elliptic cone only).
    """
    isotropic = A_over_C is not None and abs(A_over_C - 1.0) <= 1e-9
    out = [(f"{integ} in place of {integrator}", best, timestep, integ)
           for integ in WIDEN_INTEGRATORS
           if integ != integrator and (isotropic or integ not in FIRST_ORDER)]
    out.append((f"the step {timestep * WIDEN_STEP_FACTOR:g} s in place of {timestep:g} s",
                best, timestep * WIDEN_STEP_FACTOR, integrator))
    other = "elliptic" if best.cone == "pyramidal" else "pyramidal"
    flipped = replace(best, cone=other,
                      frictiondamping=None if other == "pyramidal" else best.frictiondamping)
    out.append((f"the {other} cone in place of the {best.cone}", flipped, timestep,
                integrator))
    return out


def local_candidates(centre: Candidate, fitted: Sequence[str], bounds: Bounds, n: int,
                     timestep: float, seed: int = LOCAL_SEED,
                     half_decades: float = LOCAL_HALF_DECADES) -> list[Candidate]:
    """``n`` candidates in a box about ``centre``: each fitted setting and the damping ratio.

    Each setting of ``fitted`` (and the solref damping ratio where the solref is a time
    constant and a damping ratio) within ``half_decades`` of the centre's on a log scale,
    from a scrambled Sobol sequence seeded ``seed``; clipped to ``bounds`` (the damping ratio
    to the wide fit's), rounded to 3 significant digits, the time constant at least two steps
    (MuJoCo would stiffen a shorter one to two), the centre and repeats left out.
    """
    names = list(fitted)
    if "dampratio" not in names and centre.solref_direct is None:
        names.append("dampratio")
    limits = {**bounds.values, "dampratio": bounds.values.get("dampratio", DAMPRATIO_BOUNDS)}
    out: list[Candidate] = []
    if n <= 0:
        return out
    for row in sobol_unit(n, len(names), seed):
        values = {}
        for k, name in enumerate(names):
            lo, hi = limits.get(name, (0.0, math.inf))
            x = getattr(centre, name) * 10.0 ** ((2.0 * float(row[k]) - 1.0) * half_decades)
            values[name] = min(max(x, lo), hi)
        if "timeconst_s" in values:
            values["timeconst_s"] = max(values["timeconst_s"], 2.0 * timestep)
        cand = replace(centre, **values).rounded()
        cand = replace(cand, dampratio=float(f"{cand.dampratio:.3g}"))
        if cand != centre and cand not in out:
            out.append(cand)
    return out


@dataclass(frozen=True)
class Refit:
    """What the widening's fit shares with the tuning's: its start, threads and iterations.

    Attributes:
        start: The file's start as the tuning's fit follows it.
        threads: Threads of the fit's rollouts.
        ball_until: Per start, when the stem touches (s; inf: never): the ball alone before.
        max_iters: Levenberg-Marquardt iterations at most.
    """

    start: FitStart
    threads: int
    ball_until: list[float]
    max_iters: int


@dataclass(frozen=True)
class WidenRuns:
    """How the widening verifies, counts its runs and says what it does.

    Attributes:
        check: (candidate, step, integrator) -> every start's verification and its runs.
        left: The runs left to it (the budget's reserve, :func:`widen_reserve`).
        problems: Every fit's problem, whose rollouts count: its own fit joins them.
        say: Progress lines, or None.
        contacts: The file's contacts, which the blocks to paste name (None: a top tippetop
            generated; :func:`.judge.mjcf_block`).
    """

    check: Callable[[Candidate, float, str], tuple[list[dict[str, Any]], list[Any]]]
    left: Callable[[], int]
    problems: list[Problem]
    say: Callable[[str], None] | None
    contacts: FileContacts | None = None


def widen(best: Candidate, timestep: float, integrator: str, problem: Problem,
          A_over_C: float | None, refit_at: Refit, runs: WidenRuns) -> dict[str, Any]:
    """Where the fits and their seeds depart: their answer's discrete neighbours, a fit, draws.

    First the answer with one discrete choice changed at a time
    (:func:`widen_neighbours`), each verified from every start; the first that agrees is the
    answer. Else the contact is fitted again, from the answer, at the integrator, step and
    cone of the neighbour that passed the most checks, and verified. Else candidates drawn
    about the best so far (the most checks passed; the latest of equals) at its integrator
    and step (:func:`local_candidates`), each verified in turn, the first that agrees the
    answer. All within ``runs.left()`` runs (the budget's reserve, :func:`widen_reserve`).

    Args:
        best: The answer so far.
        timestep: Its step (s).
        integrator: Its integrator.
        problem: The fit it came from (its references, bounds and fitted settings).
        A_over_C: The top's A/C (a first-order integrator is tried only at 1).
        refit_at: What the widening's own fit shares with the tuning's.
        runs: Its verification, its runs left, the fits that count, its progress lines.

    Returns:
        ``{tried: [{settings, what, agrees, departs, passes, checks, mjcf}], answer,
        budget_spent}``; ``answer`` ``{cand, timestep_s, integrator, what, verified, mj}``
        or None.
    """
    n_starts = N_STARTS
    check, left, say = runs.check, runs.left, runs.say
    tried: list[dict[str, Any]] = []
    spent = False

    def record(what: str, cand: Candidate, step: float, integ: str,
               v: list[dict[str, Any]], mj: list[Any]) -> dict[str, Any]:
        row = {"settings": f"{cand.label()} {integ} dt={step:g}", "what": f"{WIDENED}{what}",
               "agrees": agrees(v), "departs": departs(v), **passes(v),
               "mjcf": mjcf_block(run_entry(mj[0]), runs.contacts), "cand": cand,
               "timestep_s": step,
               "integrator": integ, "verified": v, "mj": mj}
        tried.append(row)
        if say:
            say(f"widened, {what}: {row['passes']} of {row['checks']} checks pass")
        return row

    def answer(row: dict[str, Any]) -> dict[str, Any]:
        return {"tried": tried, "budget_spent": spent,
                "answer": {"cand": row["cand"], "timestep_s": row["timestep_s"],
                           "integrator": row["integrator"],
                           "what": widening_step(row["what"]),
                           "verified": row["verified"], "mj": row["mj"]}}

    for what, cand, step, integ in widen_neighbours(best, timestep, integrator, A_over_C):
        if left() < n_starts:
            spent = True
            break
        if cand.solref_direct is None and cand.timeconst_s < 2.0 * step:
            continue  # MuJoCo would stiffen it to two steps: not the same contact
        row = record(what, cand, step, integ, *check(cand, step, integ))
        if row["agrees"]:
            return answer(row)
    best_row = max(tried, key=lambda r: r["passes"], default=None)
    if best_row is None:
        return {"tried": tried, "answer": None, "budget_spent": spent}
    keep = LOCAL_KEEP * n_starts
    if left() >= 1 + 2 * n_starts + keep:  # a rollout, a fit's few, its verification, draws
        # a fit from the answer at the best neighbour's discrete choices
        step, integ, start_cand = (best_row["timestep_s"], best_row["integrator"],
                                   best_row["cand"])
        refit = Problem([refit_at.start], problem.references, step, integ, problem.bounds,
                        refit_at.threads, refit_at.ball_until, fitted=problem.fitted)
        runs.problems.append(refit)
        refit.budget = left() - n_starts - keep
        found = identify(refit, [start_cand], max_iters=refit_at.max_iters, say=say)
        spent = spent or found.budget_spent
        if found.best != start_cand:
            what = f"fitted again at {integ} dt={step:g} s, {found.best.cone} cone"
            row = record(what, found.best, step, integ, *check(found.best, step, integ))
            if row["agrees"]:
                return answer(row)
    # draws about the best so far, at its discrete choices
    centre = max(reversed(tried), key=lambda r: r["passes"])
    step, integ = centre["timestep_s"], centre["integrator"]
    done = {(r["cand"], r["timestep_s"], r["integrator"]) for r in tried}
    draws = [c for c in local_candidates(centre["cand"], problem.fitted, problem.bounds,
                                         min(LOCAL_MAX, left() // n_starts), step)
             if (c, step, integ) not in done]
    about = widening_step(centre["what"])
    for k, cand in enumerate(draws, start=1):
        if left() < n_starts:
            spent = True
            break
        what = (f"drawn ({k} of {len(draws)}) within {LOCAL_HALF_DECADES:g} decade of the "
                f"best so far ({about})")
        row = record(what, cand, step, integ, *check(cand, step, integ))
        if row["agrees"]:
            return answer(row)
    return {"tried": tried, "answer": None, "budget_spent": spent}


__all__ = ["LOCAL_HALF_DECADES", "LOCAL_KEEP", "LOCAL_MAX", "LOCAL_SEED", "WIDEN_INTEGRATORS",
           "WIDEN_ONE_IN", "WIDEN_STEP_FACTOR", "Refit", "WidenRuns", "local_candidates", "widen",
           "widen_neighbours", "widen_reserve"]
