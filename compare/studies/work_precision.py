"""``tippetop bench ode --sweep``: every solver's error against a converged truth, and its cost.

Tops (:data:`TOPS`): the paper's Fig. 3 top (the catalogue's ``fig3``, 8 s), the Fig. 11 top
(A/C = 1, a/R = 0.15, theta0 = 0.01, n0 = 60 rad/s, 60 s: what ``bench ode`` runs) and the
stiff top (``fig3`` at Lambda = 1e-6 m/s, cut to :data:`STIFF_T_END_S`: the law throughout
takes ~8M evaluations a simulated second at any tolerance, so the truth stays affordable).

Solvers: the reference's methods (:data:`reference_ode.methods.METHODS`, each that imports, and
``auto``) through :func:`simulate_ode` (with its rolling phases on the stiff top); the peers on
the same compiled right-hand side (:mod:`compare.studies.peer_runs`). Every point is run at
rtol in :data:`TOLERANCES` with atol = ``ATOL_PER_RTOL`` rtol, its CPU time the best of the
rounds (the solvers alternate within a round; everything is compiled before the first). A
compiled solver's point shorter than :data:`SHORT_S` runs :data:`SHORT_ROUNDS` times as many
rounds: the Fig. 3 top's runs take 0.2-2 ms, where the best of 3 still moves by ~5 %.

Errors, against the truth (:func:`compute_truth`, two methods shown to agree): |theta(t_end) -
theta_truth| (rad), |t_invert - t_invert_truth| (s) where the top inverts, and Jellett's drift
|J(t_end) / J(0) - 1| (the law conserves J exactly on a sphere: the drift is the error). Each
level is read twice: on every point, and without each solver's cancellations (a point whose
error is below the next tighter tolerance's, :func:`frontier.cancellations`): ``ratio_steady``.
"""

from __future__ import annotations

import importlib
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tippetop.compare.results.work_precision import FORMAT, WorkPrecisionTop
from tippetop.compare.studies.accuracy.common import (
    ATOL_PER_RTOL,
    REFERENCE_RTOL,
    cut_scene,
    ode_plan,
)
from tippetop.compare.studies.accuracy.ode_study import STIFF_LAMBDA_MPS, STIFF_SCENE, stiff_scene
from tippetop.compare.studies.frontier import (
    cancellations,
    compare_at_levels,
    without_cancellations,
)
from tippetop.compare.studies.peer_runs import PEERS, Peer, PeerPoint, available_peers
from tippetop.models.errors import TippetopError
from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode.methods import METHODS
from tippetop.reference_ode.params_array import pack_params
from tippetop.reference_ode.solve import initial_state_vector, simulate_ode

#: The sweep's relative tolerances (atol = ATOL_PER_RTOL rtol), loose to tight.
TOLERANCES: tuple[float, ...] = tuple(10.0**-k for k in range(3, 14))
#: A compiled solver's point whose first run is shorter than this (s) ...
SHORT_S = 0.01
#: ... runs this many times the rounds asked (its best CPU time is then as steady as a longer
#: point's: a few ms of runs in all).
SHORT_ROUNDS = 5
#: The stiff top's simulated time (s).
STIFF_T_END_S = 1.0
#: Error levels per metric: theta(t_end) in rad, t_invert in s, Jellett's drift (relative).
LEVELS: dict[str, tuple[float, ...]] = {
    "theta": (1e-4, 1e-6, 1e-8, 1e-10),
    "t_invert": (1e-4, 1e-6, 1e-8, 1e-10),
    "J_drift": (1e-6, 1e-8, 1e-10, 1e-12),
}
UNITS = {"theta": "rad", "t_invert": "s", "J_drift": ""}
#: The two truths must agree to this in theta (rad): a tenth of the smallest level.
TRUTH_THETA_AGREEMENT = 1e-11
#: ... and in the inversion time (s).
TRUTH_T_INVERT_AGREEMENT = 1e-11
#: The truths' tolerance (the reference's at its tightest; the second truth's too).
TRUTH_RTOL = REFERENCE_RTOL
#: The stiff top's truths: the law at its stability limit costs about the same at any rtol.
STIFF_TRUTH_RTOL = 1e-13
#: How the reference appears in tables.
REF_PREFIX = "tippetop "
AUTO = REF_PREFIX + "auto"


@dataclass(frozen=True)
class Top:
    """One top of the benchmark."""

    name: str
    title: str
    top: TopParams
    friction: FrictionParams
    init: InitialState
    t_end_s: float
    stiff: bool = False

    @property
    def y0(self) -> np.ndarray:
        """The vector formulation's initial state."""
        return initial_state_vector(self.top, self.init)

    @property
    def p(self) -> np.ndarray:
        """The packed parameters."""
        return pack_params(self.top, self.friction)


def make_top(name: str, t_end_s: float | None = None) -> Top:
    """``fig3``, ``fig11`` or ``stiff`` (:data:`TOPS`), cut to ``t_end_s`` if given."""
    if name == "fig3":
        p = ode_plan(cut_scene("fig3", t_end_s))
        return Top("fig3", "Fig. 3 top (catalogue scene fig3)", p.top, p.friction, p.init,
                   p.t_end_s)
    if name == "fig11":
        T = 60.0 if t_end_s is None else float(t_end_s)
        return Top("fig11", "Fig. 11 top (A/C = 1, a/R = 0.15, theta0 = 0.01, n0 = 60 rad/s)",
                   TopParams.from_ratios(1.0, 0.15), FrictionParams(),
                   InitialState(theta0=0.01, n0=60.0), T)
    if name == "stiff":
        p = ode_plan(stiff_scene(STIFF_SCENE, STIFF_LAMBDA_MPS,
                                 STIFF_T_END_S if t_end_s is None else t_end_s))
        return Top("stiff", f"stiff top ({STIFF_SCENE} at Lambda = {STIFF_LAMBDA_MPS:g} m/s; "
                   "truth: the law throughout)", p.top, p.friction, p.init, p.t_end_s,
                   stiff=True)
    raise TippetopError(f"--tops: expected names from {', '.join(TOPS)}, got {name!r}")


TOPS = ("fig3", "fig11", "stiff")


def reference_methods() -> tuple[list[str], dict[str, str]]:
    """The reference's methods whose modules import, and why the others are skipped."""
    ok, skipped = [], {}
    for name, m in METHODS.items():
        try:
            importlib.import_module(f"tippetop.reference_ode.{m.module}")
        except Exception as exc:  # noqa: BLE001 - a method being written may fail any way
            skipped[REF_PREFIX + name] = f"module reference_ode.{m.module} does not import " \
                                         f"({type(exc).__name__}: {exc})"
        else:
            ok.append(name)
    return ok, skipped


def run_reference(top: Top, method: str, rtol: float, stiff: str = "auto") -> PeerPoint:
    """One reference run (``simulate_ode``, the table sampled at 0 and t_end only)."""
    opts = OdeOptions(method=method, rtol=rtol, atol=ATOL_PER_RTOL * rtol)
    t0 = time.process_time()
    res = simulate_ode(top.top, top.friction, top.init, t_end_s=top.t_end_s,
                       sample_dt_s=top.t_end_s, options=opts, stiff=stiff)
    s = time.process_time() - t0  # noqa: F841 - kept for a failed run's row
    if res.status != "ok":
        return PeerPoint(s=s, n_rhs=res.n_rhs, theta=math.nan, t_invert=None,
                         J_drift=math.nan, status=f"{res.status}: {res.message}")
    J = res.table["J"].to_numpy()
    # the integration's CPU time (its kernel calls and phase switches: OdeResult.cpu_s), not
    # the call's fixed ~3 ms of building tables: the peers' times are their solver calls alone
    return PeerPoint(s=res.cpu_s, n_rhs=res.n_rhs, theta=float(res.table["theta"].iloc[-1]),
                     t_invert=res.t_invert, J_drift=float(abs(J[-1] / J[0] - 1.0)),
                     status="ok", method=res.method)


def compute_truth(top: Top, second: Peer | None = None) -> dict:
    """The truth, twice: the reference's DOP853 and a second method, both at their tightest.

    The stiff top's truth is the law throughout (``stiff="off"``; the peers integrate the law
    too). The second is ``second`` (default: the reference's Verner 9(8), another method, of
    another order, with its own error estimate and step sequence).

    Raises:
        TippetopError: if a truth run fails, or the two disagree by more than
            :data:`TRUTH_THETA_AGREEMENT` in theta (or :data:`TRUTH_T_INVERT_AGREEMENT` in the
            inversion time): no error below that could be measured.
    """
    rtol = STIFF_TRUTH_RTOL if top.stiff else TRUTH_RTOL
    a = run_reference(top, "dop853", rtol, stiff="off")
    if second is None:
        b, second_name = run_reference(top, "vern9", rtol, stiff="off"), "tippetop vern9"
    else:
        b, second_name = second.run(top, rtol, locate_invert=True), second.name
    for name, run in (("tippetop dop853", a), (second_name, b)):
        if run.status != "ok":
            raise TippetopError(f"work-precision: expected the truth run of {top.name} "
                                f"({name}, rtol {rtol:g}) to complete, got {run.status}")
    truth = check_truths(top.name, {"tippetop dop853": a, second_name: b}, rtol)
    if truth["t_invert"] is not None and truth["t_invert_locate_err"] is None:
        # how well a peer without events locates the inversion (from its samples): measured on
        # the first peer there is, at the truth's tolerance
        names = available_peers()
        locator = next((n for n in ("numbalsoda DOP853", "scipy DOP853") if n in names), None)
        if locator is not None:
            run = PEERS[locator].run(top, rtol, locate_invert=True)
            truth.update(t_invert_locate_err=run.locate_err, locator=locator)
    return truth


def check_truths(top_name: str, runs: dict[str, PeerPoint], rtol: float) -> dict:
    """The truth's summary from two runs, or a TippetopError when they disagree."""
    (na, a), (nb, b) = runs.items()
    d_theta = abs(a.theta - b.theta)
    if not d_theta <= TRUTH_THETA_AGREEMENT:
        raise TippetopError(
            f"work-precision: the two truths of {top_name} disagree: theta(t_end) "
            f"{a.theta!r} ({na}) vs {b.theta!r} ({nb}), |diff| = {d_theta:.2e} rad > "
            f"{TRUTH_THETA_AGREEMENT:g}: errors below that cannot be measured")
    d_inv = None
    if (a.t_invert is None) != (b.t_invert is None):
        raise TippetopError(f"work-precision: the two truths of {top_name} disagree on "
                            f"whether the top inverts ({a.t_invert} vs {b.t_invert})")
    if a.t_invert is not None and b.t_invert is not None:
        d_inv = abs(a.t_invert - b.t_invert)
        if not d_inv <= TRUTH_T_INVERT_AGREEMENT:
            raise TippetopError(
                f"work-precision: the two truths of {top_name} disagree: t_invert "
                f"{a.t_invert!r} ({na}) vs {b.t_invert!r} ({nb}), |diff| = {d_inv:.2e} s > "
                f"{TRUTH_T_INVERT_AGREEMENT:g}")
    return {"methods": [na, nb], "rtol": rtol, "atol": ATOL_PER_RTOL * rtol,
            "theta": a.theta, "theta_other": b.theta, "theta_diff": d_theta,
            "t_invert": a.t_invert, "t_invert_other": b.t_invert, "t_invert_diff": d_inv,
            "t_invert_locate_err": b.locate_err, "locator": nb, "J_drift": a.J_drift}


def _errors(run: PeerPoint, truth: dict) -> dict:
    th = abs(run.theta - truth["theta"]) if run.status == "ok" else math.nan
    ti = math.nan
    if run.status == "ok" and truth["t_invert"] is not None and run.t_invert is not None:
        ti = abs(run.t_invert - truth["t_invert"])
    return {"theta_err": th, "t_invert_err": ti,
            "J_drift": run.J_drift if run.status == "ok" else math.nan}


@dataclass(frozen=True)
class _Sweep:
    """One top's sweep under way: its solvers, tolerances and rounds, and the points made."""

    top: Top
    truth: dict
    tols: list[float]
    names: list[str]
    solvers: dict[str, dict]
    rounds: int
    slow_rounds: int
    budget_s: float | None


def _solver_names(peers: Sequence[str] | None, methods: Sequence[str] | None
                  ) -> tuple[list[str], list[str], dict[str, str]]:
    """The reference's methods and the peers to run, and why the others are skipped."""
    ref_names, skipped = reference_methods()
    if methods is not None:
        ref_names = [m for m in methods if m in ref_names or m == "auto"]
    elif "auto" not in ref_names:
        ref_names = [*ref_names, "auto"]
    peer_names = list(available_peers() if peers is None else peers)
    missing = {n: PEERS[n].missing() for n in PEERS if n not in peer_names}
    skipped.update({n: why for n, why in missing.items() if why})
    return ref_names, peer_names, skipped


def _warm_up(top: Top, ref_names: Sequence[str], peer_names: Sequence[str],
             tols: Sequence[float]) -> None:
    """Runs every solver once (compiling it) off the clock."""
    for m in ref_names:  # the loosest tolerance: cheap, and it visits the rolling phases
        run_reference(top, m, tols[0])
    for n in peer_names:
        PEERS[n].warm(top)


def _run_one(sw: _Sweep, name: str, rtol: float, first: bool) -> PeerPoint:
    """One run of a solver at ``rtol`` (the first at it locates the inversion, if any)."""
    if name.startswith(REF_PREFIX):
        return run_reference(sw.top, name[len(REF_PREFIX):], rtol)
    locate = first and sw.truth["t_invert"] is not None
    return PEERS[name].run(sw.top, rtol, locate_invert=locate)


def _rounds_of(sw: _Sweep, n: str, rtol: float) -> int:
    """The rounds a solver's point runs: more for a short one, fewer for a slow peer."""
    if n in PEERS and PEERS[n].slow:
        return sw.slow_rounds
    first = sw.solvers[n]["points"].get(rtol)
    short = first is not None and first["s"] < SHORT_S
    return sw.rounds * SHORT_ROUNDS if short else sw.rounds


def _planned(sw: _Sweep) -> int:
    """The number of runs of the first round."""
    return sum(len(PEERS[n].tolerances(sw.tols)) if n in PEERS else len(sw.tols)
               for n in sw.names)


def _replanned(sw: _Sweep, planned: int) -> int:
    """The number of runs more (or fewer) than planned, once the first round is done."""
    made = sum(len(sv["points"]) for sv in sw.solvers.values())
    later = sum(_rounds_of(sw, n, q["rtol"]) - 1 for n, sv in sw.solvers.items()
                for q in sv["points"].values() if q["status"] == "ok")
    return later - (planned - made)


def _skips(sw: _Sweep, n: str, rtol: float, r: int) -> bool:
    """Whether solver ``n`` sits out round ``r`` at ``rtol``."""
    sv = sw.solvers[n]
    slow = n in PEERS and PEERS[n].slow
    if (r >= _rounds_of(sw, n, rtol)
            or (slow and rtol not in PEERS[n].tolerances(sw.tols))
            or (sv["stopped"] and rtol < sv["stopped"])):
        return True
    return r > 0 and (rtol not in sv["points"] or sv["points"][rtol]["status"] != "ok")


def _record(sw: _Sweep, n: str, rtol: float, run: PeerPoint) -> None:
    """Records a solver's first run at ``rtol``; a failed or over-budget one ends its sweep."""
    sv = sw.solvers[n]
    slow = n in PEERS and PEERS[n].slow
    sv["points"][rtol] = {"rtol": rtol, "atol": ATOL_PER_RTOL * rtol,
                          "s": run.s, "n_rhs": run.n_rhs,
                          "status": run.status, **_errors(run, sw.truth),
                          "method": run.method,
                          "t_invert_locate_err": run.locate_err,
                          "printed": run.printed}
    limit = PEERS[n].budget_s if n in PEERS else None
    limit = sw.budget_s if (sw.budget_s is not None and slow) else limit
    if run.status != "ok" or (limit is not None and run.s > limit):
        sv["stopped"] = rtol


def _run_rounds(sw: _Sweep, tick: Callable[[], None] | None,
                expect: Callable[[int], None] | None) -> None:
    """Runs the rounds, the solvers taking turns, each point keeping its best CPU time."""
    planned = _planned(sw)
    if expect is not None:
        expect(planned)
    names = sw.names
    for r in range(max(sw.rounds * SHORT_ROUNDS, sw.slow_rounds)):
        if r == 1 and expect is not None:  # the first round told which points run again
            expect(_replanned(sw, planned))
        for k, rtol in enumerate(sw.tols):
            order = names[(r + k) % len(names):] + names[:(r + k) % len(names)]
            for n in order:
                if _skips(sw, n, rtol, r):
                    continue
                run = _run_one(sw, n, rtol, r == 0)
                if tick is not None:
                    tick()
                if r == 0:
                    _record(sw, n, rtol, run)
                else:
                    p = sw.solvers[n]["points"][rtol]
                    p["s"] = min(p["s"], run.s)


def _level(metric: str, key: str, solvers: dict[str, dict], refs: list[str],
           auto: str | None, peer_names: list[str]) -> dict:
    """One metric's equal-error rows, on every point and without the cancellations."""
    by_rtol = {n: [(p["rtol"], p[key], p["s"]) for p in sv["points"]
                   if p["status"] == "ok" and p[key] is not None]
               for n, sv in solvers.items()}
    pts = {n: [(e, t) for _, e, t in ps] for n, ps in by_rtol.items()}
    rows = compare_at_levels(pts, refs, auto, peer_names, LEVELS[metric])
    # the same levels with every solver's cancellations set aside (frontier.cancellations)
    steady = compare_at_levels({n: without_cancellations(ps) for n, ps in by_rtol.items()},
                               refs, auto, peer_names, LEVELS[metric])
    for row, st in zip(rows, steady, strict=True):
        row.update(ratio_steady=st["ratio"], ratio_auto_steady=st["ratio_auto"],
                   met_steady=st["met"], best_peer_steady=st["best_peer"])
    cancelled = {n: c for n, ps in by_rtol.items() if (c := cancellations(ps))}
    return {"unit": UNITS[metric], "levels": list(LEVELS[metric]),
            "rows": rows, "cancellations": cancelled}


def sweep_top(top: Top, *, rounds: int = 3, slow_rounds: int = 1,
              tolerances: Sequence[float] = TOLERANCES, peers: Sequence[str] | None = None,
              methods: Sequence[str] | None = None, budget_s: float | None = None,
              tick: Callable[[], None] | None = None,
              expect: Callable[[int], None] | None = None) -> WorkPrecisionTop:
    """One top's sweep: the truth, every solver's points, and the equal-error tables' rows.

    Args:
        top: The top.
        rounds: Rounds of the compiled solvers (each point keeps its best CPU time); a point
            shorter than :data:`SHORT_S` runs :data:`SHORT_ROUNDS` times as many.
        slow_rounds: Rounds of the peers that call a Python wrapper (scipy, CVODE).
        tolerances: rtol values of the compiled solvers; the slow peers run every other one.
        peers: Peer names (default: the available ones).
        methods: The reference's methods (default: those that import, then ``auto``).
        budget_s: A slow peer's sweep stops after a point over this CPU time (s); default
            the peer's own.
        tick: Called after each run (progress).
        expect: Called with the number of runs planned (before the first round), then with
            the number more or fewer (after it: the rounds of each point it leaves).
    """
    ref_names, peer_names, skipped = _solver_names(peers, methods)
    truth = compute_truth(top)
    tols = sorted({float(t) for t in tolerances}, reverse=True)
    _warm_up(top, ref_names, peer_names, tols)
    names = [REF_PREFIX + m for m in ref_names] + peer_names
    solvers: dict[str, dict] = {}
    for n in names:
        solvers[n] = {"kind": "reference" if n.startswith(REF_PREFIX) else "peer",
                      "points": {}, "stopped": None}
    _run_rounds(_Sweep(top=top, truth=truth, tols=tols, names=names, solvers=solvers,
                       rounds=rounds, slow_rounds=slow_rounds, budget_s=budget_s), tick, expect)
    for sv in solvers.values():
        sv["points"] = list(sv["points"].values())
    refs = [REF_PREFIX + m for m in ref_names if m != "auto"]
    auto = AUTO if AUTO in solvers else None
    levels = {}
    for metric, key in (("theta", "theta_err"), ("t_invert", "t_invert_err"),
                        ("J_drift", "J_drift")):
        if metric == "t_invert" and truth["t_invert"] is None:
            continue
        levels[metric] = _level(metric, key, solvers, refs, auto, peer_names)
    return WorkPrecisionTop(name=top.name, title=top.title, t_end_s=top.t_end_s,
                            stiff=top.stiff, truth=truth, solvers=solvers, skipped=skipped,
                            references=tuple(refs), auto=auto, peers=tuple(peer_names),
                            levels=levels)


__all__ = ["AUTO", "FORMAT", "LEVELS", "REF_PREFIX", "SHORT_ROUNDS", "SHORT_S", "STIFF_T_END_S",
           "STIFF_TRUTH_RTOL", "TOLERANCES", "TOPS", "TRUTH_RTOL", "TRUTH_THETA_AGREEMENT",
           "TRUTH_T_INVERT_AGREEMENT", "UNITS", "Top", "WorkPrecisionTop", "check_truths",
           "compute_truth", "make_top", "reference_methods", "run_reference", "sweep_top"]
