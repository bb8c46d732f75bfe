"""Is it a limit of MuJoCo? A search over MuJoCo's whole contact space at one point.

Issue 41, item 4: a point of the fidelity map may be called a limit of MuJoCo only after a
search over MuJoCo's whole contact space fails there, and the search is reported. This module
holds that search's space, candidates and verification; the search (an even draw, then a
dense stage) is :mod:`.contact_search_refine`'s. At one point (a top's A/C and a/R, the
table's mu) stage 1 draws candidates space-filling (a scrambled, seeded Sobol sequence) over
every contact setting MuJoCo has, within MuJoCo's own bounds (:func:`space`): the cone,
impratio, solref (time constant and damping ratio, or direct stiffness and damping), solimp
(d0, dmax, width, midpoint, power), the friction rows' own solref on contact pairs (elliptic
cone), noslip iterations, condim, the integrator and the step, and mu within a factor 2 of
the law's. The point's tuned settings (where given) and the calibrated settings are always
among them, and the first of them with each choice changed alone (:func:`neighbours`).

Each candidate is verified exactly as the tuning verifies (:mod:`tippetop.compare.tuning.tune`):
run by the harness (cache, local workers or Dask) from the fit's start and the three held-out
starts (:func:`tippetop.compare.tuning.tune.starts_for`), each run judged with the verdict
against the reference from the same start and the theory's outcome for it
(:func:`.fidelity.compute_point`'s). A candidate *agrees* when every check passes from every
start that can be verified, a held-out one among them (:class:`PointRuns`). The candidates are
ranked (:func:`rank_key`) and the checks that depart attributed to the parts of the space
(:func:`attribution`).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from tippetop.compare.measures import series, theory
from tippetop.compare.measures.verdict import predicted_outcome, run_entry, verdict
from tippetop.compare.running.runner import Task, run_tasks
from tippetop.compare.studies.fidelity import (
    CAUSE_ORDER,
    START_N0,
    START_THETA0,
    cause_of,
    point_overrides,
    start_spin,
)
from tippetop.compare.tuning.sobol import sobol_unit
from tippetop.compare.tuning.tune import TuneStart, settled_references, starts_for
from tippetop.models.calibrated import CALIBRATION_MU, calibrated_native_settings
from tippetop.models.errors import RunFailedError, TippetopError
from tippetop.models.modes import REFERENCE_RUN, run_label
from tippetop.models.scene import Override

#: The JSON's format name.
FORMAT = "tippetop-contact-search/1"
DEFAULT_CANDIDATES = 112  # with the baselines, half of the two-stage default budget
DEFAULT_T_END_S = 8.0
#: Candidates verified per call of the runner (its progress and memory stay bounded).
BATCH = 16
#: The space's choices.
CONES = ("pyramidal", "elliptic")
CONDIMS = (3, 4, 6)
INTEGRATORS = ("RK4", "implicitfast", "implicit", "Euler")
TIMESTEPS_S = (2e-4, 1e-4, 5e-5)
NOSLIP_ITERATIONS = (0, 1, 5, 20)
#: Continuous ranges (log-uniform unless said).
IMPRATIO = (0.02, 1000.0)
TIMECONST_MAX_S = 0.05  # its least is 2 steps: MuJoCo clamps a shorter one (refsafe)
DAMPRATIO = (0.3, 4.0)
#: Direct solref: stiffness k (the time constant's range spans about 25 to 7e7 at 2e-4 s),
#: damping b = 2 z sqrt(k) with z the damping ratio drawn.
DIRECT_STIFFNESS = (1e2, 1e8)
#: MuJoCo's impedance floor and ceiling (mjMINIMP, mjMAXIMP); d0 up to 0.99 as the brief asks.
IMP_MIN, IMP_MAX = 1e-4, 0.9999
D0 = (1e-4, 0.99)
WIDTH_M = (1e-4, 1e-2)
MIDPOINT = (0.05, 0.95)  # linear
POWER = (1.0, 6.0)  # linear; MuJoCo takes power >= 1
FRICTION_DAMPING = (0.1, 100.0)  # solreffriction (-1, -b): a friction row has no position
MU_FACTOR = 2.0
#: Shares of the draw (exact, by rank): direct solref, constant impedance (dmax = d0), and
#: contact pairs with solreffriction among the elliptic candidates.
DIRECT_SHARE = 0.25
CONSTANT_IMPEDANCE_SHARE = 0.25
PAIRS_SHARE = 0.5
#: The unit cube's dimensions, in order.
DIMENSIONS = ("cone", "condim", "integrator", "timestep_s", "noslip_iterations",
              "solref_form", "impratio", "stiffness", "dampratio", "d0", "impedance", "dmax",
              "width_m", "midpoint", "power", "pairs", "friction_damping", "mu_factor")
#: How many candidates the top list keeps.
TOP = 10


@dataclass(frozen=True)
class ContactCandidate:
    """One point of MuJoCo's contact space, as the scene's ``mujoco.*`` keys set it.

    Attributes:
        cone: ``pyramidal`` or ``elliptic``.
        impratio: Frictional-to-normal impedance ratio.
        solref: (time constant s, damping ratio), or direct (-stiffness, -damping).
        solimp: (d0, dmax, width m, midpoint, power).
        mu: MuJoCo's sliding coefficient.
        condim: 3, 4 (torsional friction) or 6 (and rolling).
        integrator: MuJoCo's integrator.
        timestep_s: The step (s).
        noslip_iterations: MuJoCo's noslip iterations (0: off).
        solreffriction: The friction rows' own solref on contact pairs (elliptic cone), or
            None.
        origin: ``drawn``, ``tuned``, ``calibrated`` or ``neighbour`` (:func:`neighbours`).
    """

    cone: str
    impratio: float
    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]
    mu: float
    condim: int = 3
    integrator: str = "RK4"
    timestep_s: float = 2e-4
    noslip_iterations: int = 0
    solreffriction: tuple[float, float] | None = None
    origin: str = "drawn"

    def overrides(self) -> tuple[Override, ...]:
        """The overrides that select exactly these settings (nothing left to defaults)."""
        out = (Override.of("mujoco.friction", "native"), Override.of("mujoco.cone", self.cone),
               Override.of("mujoco.impratio", self.impratio), Override.of("mujoco.mu", self.mu),
               Override.of("mujoco.solref", self.solref[:2]),
               Override.of("mujoco.solimp", self.solimp),
               Override.of("mujoco.timestep_s", self.timestep_s),
               Override.of("mujoco.integrator", self.integrator),
               Override.of("mujoco.condim", self.condim),
               Override.of("mujoco.noslip_iterations", self.noslip_iterations))
        if self.solreffriction is not None:
            out += (Override.of("mujoco.solreffriction", self.solreffriction[:2]),)
        return out

    def label(self) -> str:
        """A short line: ``elliptic impratio=300 solref=[-1e+05, -632] d0=dmax=0.0001 ...``."""
        d0, dmax, width, mid, power = self.solimp
        imp = (f"d0=dmax={d0:.3g}" if d0 == dmax else f"d0={d0:.3g} dmax={dmax:.3g}")
        text = (f"{self.cone} condim={self.condim} impratio={self.impratio:.3g} "
                f"solref=[{self.solref[0]:.3g}, {self.solref[1]:.3g}] {imp} "
                f"width={width:.3g} mid={mid:.2g} power={power:.2g} mu={self.mu:.3g}")
        if self.solreffriction is not None:
            text += (f" solreffriction=[{self.solreffriction[0]:.3g}, "
                     f"{self.solreffriction[1]:.3g}] (pairs)")
        return (f"{text} noslip={self.noslip_iterations} {self.integrator} "
                f"dt={self.timestep_s:g}")

    def to_json(self) -> dict[str, Any]:
        """The settings as the scene's keys name them, and the candidate's origin."""
        return {"cone": self.cone, "impratio": self.impratio, "solref": list(self.solref),
                "solimp": list(self.solimp), "mu": self.mu, "condim": self.condim,
                "integrator": self.integrator, "timestep_s": self.timestep_s,
                "noslip_iterations": self.noslip_iterations,
                "solreffriction": None if self.solreffriction is None
                else list(self.solreffriction), "origin": self.origin}


# ---------------------------------------------------------------- the space and the draw
def space(mu: float) -> dict[str, Any]:
    """Each dimension of the search: its choices or range, its scale, and why that range."""
    return {
        "cone": {"choices": list(CONES)},
        "condim": {"choices": list(CONDIMS), "note": "4: torsional friction, 6: and rolling "
                   "(MuJoCo's default coefficients)"},
        "integrator": {"choices": list(INTEGRATORS)},
        "timestep_s": {"choices": list(TIMESTEPS_S)},
        "noslip_iterations": {"choices": list(NOSLIP_ITERATIONS)},
        "impratio": {"range": list(IMPRATIO), "scale": "log"},
        "solref": {"forms": {"time constant": 1.0 - DIRECT_SHARE, "direct": DIRECT_SHARE},
                   "timeconst_s": {"range": ["2 dt", TIMECONST_MAX_S], "scale": "log",
                                   "note": "MuJoCo clamps a time constant below 2 dt"},
                   "dampratio": {"range": list(DAMPRATIO), "scale": "log"},
                   "direct_stiffness": {"range": list(DIRECT_STIFFNESS), "scale": "log",
                                        "note": "solref = [-k, -2 z sqrt(k)], z the damping "
                                                "ratio drawn; not clamped to 2 dt"}},
        "solimp": {"d0": {"range": list(D0), "scale": "log"},
                   "dmax": {"range": ["d0", IMP_MAX], "scale": "log",
                            "note": f"dmax = d0 (a constant impedance) in "
                                    f"{CONSTANT_IMPEDANCE_SHARE:.0%} of the draw"},
                   "width_m": {"range": list(WIDTH_M), "scale": "log"},
                   "midpoint": {"range": list(MIDPOINT), "scale": "linear"},
                   "power": {"range": list(POWER), "scale": "linear"}},
        "solreffriction": {"value": "[-1, -b] on a contact pair for each geom of the top",
                           "b": {"range": list(FRICTION_DAMPING), "scale": "log"},
                           "note": f"elliptic cone only (MuJoCo takes it there only), in "
                                   f"{PAIRS_SHARE:.0%} of the elliptic candidates"},
        "mu": {"range": [mu / MU_FACTOR, mu * MU_FACTOR], "scale": "log"},
    }


def by_rank(u: np.ndarray, choices: Sequence[Any], weights: Sequence[float] | None = None
            ) -> list[Any]:
    """A categorical dimension from a column: by rank, each choice its exact share."""
    n = len(u)
    w = np.asarray(weights if weights is not None else [1.0] * len(choices), dtype=float)
    edges = np.cumsum(w / w.sum())
    ranks = np.empty(n, dtype=int)
    ranks[np.argsort(u, kind="stable")] = np.arange(n)
    idx = np.searchsorted(edges, (ranks + 0.5) / n)
    return [choices[min(int(i), len(choices) - 1)] for i in idx]


def _log(u: float, lo: float, hi: float) -> float:
    return float(math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))))


def _sig(x: float, digits: int = 4) -> float:
    return float(f"{x:.{digits - 1}e}")


#: The forms a candidate's continuous settings take (:func:`candidate_at`'s ``forms``).
FORMS = ("solref_form", "impedance", "pairs")


def candidate_at(u: dict[str, float], cell: dict[str, Any], mu: float,
                 origin: str = "drawn") -> ContactCandidate:
    """The candidate at unit coordinates ``u`` of the continuous dimensions, in ``cell``.

    Args:
        u: A value in [0, 1] for each continuous name of :data:`DIMENSIONS`, scaled into its
            range (log-uniform unless :func:`space` says linear; the time constant from 2 dt).
        cell: ``cone``, ``condim``, ``integrator``, ``timestep_s``, ``noslip_iterations`` and
            the :data:`FORMS`: ``solref_form`` (``time constant`` or ``direct``),
            ``impedance`` (``ramp`` or ``constant``) and ``pairs`` (solreffriction on
            contact pairs, taken in an elliptic cone only).
        mu: The law's friction coefficient.
        origin: The candidate's origin.
    """
    dt = float(cell["timestep_s"])
    z = _log(u["dampratio"], *DAMPRATIO)
    if cell["solref_form"] == "direct":
        k = _log(u["stiffness"], *DIRECT_STIFFNESS)
        solref = (-_sig(k), -_sig(2.0 * z * math.sqrt(k)))
    else:
        solref = (_sig(_log(u["stiffness"], 2.0 * dt, TIMECONST_MAX_S)), _sig(z))
    d0 = _sig(_log(u["d0"], *D0))
    dmax = d0 if cell["impedance"] == "constant" else \
        _sig(min(IMP_MAX, _log(u["dmax"], d0, IMP_MAX)))
    solimp = (d0, max(d0, dmax), _sig(_log(u["width_m"], *WIDTH_M)),
              _sig(MIDPOINT[0] + u["midpoint"] * (MIDPOINT[1] - MIDPOINT[0])),
              _sig(POWER[0] + u["power"] * (POWER[1] - POWER[0])))
    cone = str(cell["cone"])
    srf = ((-1.0, -_sig(_log(u["friction_damping"], *FRICTION_DAMPING)))
           if cone == "elliptic" and cell["pairs"] else None)
    return ContactCandidate(
        cone=cone, impratio=_sig(_log(u["impratio"], *IMPRATIO)), solref=solref,
        solimp=solimp, mu=_sig(_log(u["mu_factor"], mu / MU_FACTOR, mu * MU_FACTOR)),
        condim=int(cell["condim"]), integrator=str(cell["integrator"]), timestep_s=dt,
        noslip_iterations=int(cell["noslip_iterations"]), solreffriction=srf, origin=origin)


def _inv_log(x: float, lo: float, hi: float) -> float:
    if not (x > 0 and hi > lo > 0):
        return 0.5
    return float(min(1.0, max(0.0, (math.log(x) - math.log(lo)) / (math.log(hi) - math.log(lo)))))


def _inv_lin(x: float, lo: float, hi: float) -> float:
    return float(min(1.0, max(0.0, (x - lo) / (hi - lo))))


def unit_of(c: ContactCandidate, mu: float) -> tuple[dict[str, float], dict[str, Any]]:
    """A candidate's unit coordinates and its cell and forms: :func:`candidate_at`'s inverse.

    Settings outside the search's ranges are clipped to them.
    """
    direct = c.solref[0] < 0
    if direct:
        k = -c.solref[0]
        u_k = _inv_log(k, *DIRECT_STIFFNESS)
        u_z = _inv_log(-c.solref[1] / (2.0 * math.sqrt(k)), *DAMPRATIO)
    else:
        u_k = _inv_log(c.solref[0], 2.0 * c.timestep_s, TIMECONST_MAX_S)
        u_z = _inv_log(c.solref[1], *DAMPRATIO)
    d0, dmax, width, mid, power = c.solimp
    u = {"impratio": _inv_log(c.impratio, *IMPRATIO), "stiffness": u_k, "dampratio": u_z,
         "d0": _inv_log(d0, *D0),
         "dmax": _inv_log(dmax, d0, IMP_MAX) if d0 < IMP_MAX else 1.0,
         "width_m": _inv_log(width, *WIDTH_M),
         "midpoint": _inv_lin(mid, *MIDPOINT), "power": _inv_lin(power, *POWER),
         "friction_damping": (_inv_log(-c.solreffriction[1], *FRICTION_DAMPING)
                              if c.solreffriction else 0.5),
         "mu_factor": _inv_log(c.mu, mu / MU_FACTOR, mu * MU_FACTOR)}
    cell = {"cone": c.cone, "condim": c.condim, "integrator": c.integrator,
            "timestep_s": c.timestep_s, "noslip_iterations": c.noslip_iterations,
            "solref_form": "direct" if direct else "time constant",
            "impedance": "constant" if d0 == dmax else "ramp",
            "pairs": c.solreffriction is not None}
    return u, cell


def draw_candidates(n: int, mu: float, seed: int = 0) -> list[ContactCandidate]:
    """``n`` candidates over MuJoCo's whole contact space (:func:`space`), space-filling.

    A scrambled Sobol sequence seeded with ``seed``; each categorical dimension takes its
    choices by rank (each its share exactly, every choice present once ``n`` reaches their
    number), each continuous one is scaled into its range (:func:`candidate_at`).

    Raises:
        TippetopError: ``n`` < 0 or ``mu`` not > 0 (one line).
    """
    if not isinstance(n, int) or isinstance(n, bool) or n < 0:
        raise TippetopError(f"--candidates: expected a whole number >= 0, got {n!r}")
    if not (isinstance(mu, (int, float)) and math.isfinite(mu) and mu > 0):
        raise TippetopError(f"mu: expected a finite number > 0, got {mu!r}")
    if n == 0:
        return []
    u = sobol_unit(n, len(DIMENSIONS), seed)
    col = {name: u[:, k] for k, name in enumerate(DIMENSIONS)}
    cats = {"cone": by_rank(col["cone"], CONES), "condim": by_rank(col["condim"], CONDIMS),
            "integrator": by_rank(col["integrator"], INTEGRATORS),
            "timestep_s": by_rank(col["timestep_s"], TIMESTEPS_S),
            "noslip_iterations": by_rank(col["noslip_iterations"], NOSLIP_ITERATIONS),
            **form_columns(col)}
    return [candidate_at({k: float(v[i]) for k, v in col.items()},
                         {k: v[i] for k, v in cats.items()}, mu) for i in range(n)]


def form_columns(col: dict[str, np.ndarray]) -> dict[str, list[Any]]:
    """The :data:`FORMS` of a draw from its columns, by rank at their shares."""
    return {"solref_form": by_rank(col["solref_form"], ("time constant", "direct"),
                                   (1.0 - DIRECT_SHARE, DIRECT_SHARE)),
            "impedance": by_rank(col["impedance"], ("ramp", "constant"),
                                 (1.0 - CONSTANT_IMPEDANCE_SHARE, CONSTANT_IMPEDANCE_SHARE)),
            "pairs": by_rank(col["pairs"], (False, True), (1.0 - PAIRS_SHARE, PAIRS_SHARE))}


def candidate_from_settings(settings: dict[str, Any], origin: str) -> ContactCandidate:
    """A candidate from settings as the tuning writes them (``mu``, ``cone``, ``solref``, ...).

    Raises:
        TippetopError: A key missing or of the wrong kind (one line).
    """
    try:
        solimp = [float(v) for v in settings["solimp"]]
        if len(solimp) == 3:  # MuJoCo's midpoint and power
            solimp += [0.5, 2.0]
        srf = settings.get("solreffriction")
        return ContactCandidate(
            cone=str(settings["cone"]), impratio=float(settings.get("impratio", 1.0)),
            solref=(float(settings["solref"][0]), float(settings["solref"][1])),
            solimp=tuple(solimp),  # type: ignore[arg-type]
            mu=float(settings["mu"]), condim=int(settings.get("condim") or 3),
            integrator=str(settings.get("integrator") or "RK4"),
            timestep_s=float(settings.get("timestep_s") or 2e-4),
            noslip_iterations=int(settings.get("noslip_iterations") or 0),
            solreffriction=None if not srf else (float(srf[0]), float(srf[1])), origin=origin)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise TippetopError(f"tuned settings: expected mu, cone, impratio, solref, solimp, "
                            f"got {settings!r} ({exc.__class__.__name__}: {exc})") from None


def calibrated_candidate(mu: float) -> ContactCandidate | None:
    """The calibrated settings, mu scaled as native mode scales it; None without a file."""
    cal = calibrated_native_settings()
    if not cal:
        return None
    return candidate_from_settings({**cal, "mu": float(cal["mu"]) * mu / CALIBRATION_MU,
                                    "condim": 3, "noslip_iterations": 0}, "calibrated")


def neighbours(c: ContactCandidate) -> list[ContactCandidate]:
    """``c`` with one choice changed at a time: cone, condim, integrator, step, noslip.

    A pyramidal cone drops solreffriction (MuJoCo takes it in an elliptic one only); an
    elliptic ``c`` without it gains the lift-free family's pairs (damping 2.6) as well.
    """
    out = []
    for name, choices in (("cone", CONES), ("condim", CONDIMS), ("integrator", INTEGRATORS),
                          ("timestep_s", TIMESTEPS_S), ("noslip_iterations", NOSLIP_ITERATIONS)):
        for v in choices:
            if v != getattr(c, name):
                srf = None if (name, v) == ("cone", "pyramidal") else c.solreffriction
                out.append(replace(c, **{name: v}, solreffriction=srf, origin="neighbour"))
    if c.cone == "elliptic" and c.solreffriction is None:
        out.append(replace(c, solreffriction=(-1.0, -2.6), origin="neighbour"))
    return out


def tuned_settings_from(results: dict[str, Any], A_over_C: float, a_over_R: float,
                        mu: float) -> dict[str, Any] | None:
    """A point's tuned settings in a fidelity map's JSON (``tippetop fidelity --json``)."""
    for p in results.get("points") or []:
        if all(math.isclose(float(p.get(k) or math.nan), v, rel_tol=1e-9)
               for k, v in (("A_over_C", A_over_C), ("a_over_R", a_over_R), ("mu", mu))):
            return p.get("settings") or None
    return None


# ---------------------------------------------------------------- judging and scoring
def theta_rms(ref_table: Any, table: Any) -> float | None:
    """RMS of theta less the reference's, on the reference's samples both runs cover (rad).

    :func:`tippetop.compare.measures.series.theta_rms`, or None where a run is missing, they
    share fewer than two samples or a theta is not finite (a run that diverged).
    """
    if table is None or ref_table is None or len(table) < 2 or len(ref_table) < 2:
        return None
    if np.count_nonzero(ref_table["t"].to_numpy() <= table["t"].iloc[-1]) < 2 or not (
            np.all(np.isfinite(table["theta"].to_numpy()))
            and np.all(np.isfinite(ref_table["theta"].to_numpy()))):
        return None
    return series.theta_rms(table, ref_table)


def judge_start(start: TuneStart, ref: Any, run: Any, outcome_at: Callable[..., Any],
                A_over_C: float) -> dict[str, Any]:
    """One start of one candidate, judged as the tuning judges it (``tune``'s verification).

    Args:
        start: The start.
        ref: The reference's result from it (a :class:`TaskResult`).
        run: The candidate's result from it.
        outcome_at: (n0, theta0, role) -> the theory's (theta_s, outcome).
        A_over_C: The top's.

    Returns:
        ``{n0, theta0, role, passed, checks, note, left_table_s, theta_rms_rad}``;
        ``passed`` None where the reference's model stops (not verifiable).
    """
    label = run_label("mujoco", (run.summary or {}).get("mode") or "native")
    runs = {REFERENCE_RUN: run_entry(ref), label: run_entry(run)}
    head = {"n0": start.n0, "theta0": start.theta0, "role": start.role}
    if runs[REFERENCE_RUN].get("status") != "ok":
        return {**head, "passed": None, "checks": [], "left_table_s": None,
                "theta_rms_rad": None, "note": f"not verifiable: the reference stops "
                f"({runs[REFERENCE_RUN].get('message')})"}
    theta_s, outcome = outcome_at(start.n0, start.theta0, start.role)
    checks = [{k: c.get(k) for k in ("check", "passed", "value", "note")}
              for c in verdict(runs, outcome, A_over_C, theta_s=theta_s) if c["run"] == label]
    ran = not any(c["check"] == "completed" and c["passed"] is False for c in checks)
    return {**head, "passed": all(c["passed"] is not False for c in checks), "checks": checks,
            "note": None, "left_table_s": (run.summary or {}).get("t_left_table"),
            "theta_rms_rad": theta_rms(ref.table, run.table) if ran else None}


def check_passes(verified: list[dict[str, Any]]) -> dict[str, bool]:
    """Check -> whether it passes from every verifiable start where it was judged.

    A run that completed passes ``completed`` (the verdict lists that check only where it
    fails); a run that did not is judged by ``completed`` alone.
    """
    out: dict[str, bool] = {}
    for v in verified:
        if v.get("passed") is None:
            continue
        got = {"completed": True, **{c["check"]: c["passed"] is not False
                                     for c in v["checks"]}}
        for name, ok in got.items():
            out[name] = out.get(name, True) and ok
    return {name: out[name] for name in (*CAUSE_ORDER, *sorted(set(out) - set(CAUSE_ORDER)))
            if name in out}


def score(verified: list[dict[str, Any]]) -> dict[str, Any]:
    """A candidate's score from its starts (the tuning's rule).

    Returns:
        ``agrees`` (every verifiable start passes, a held-out one among them), ``passes``
        and ``checks`` (over every start), ``departures`` (checks that fail),
        ``first_departing`` (the first in :data:`.fidelity.CAUSE_ORDER`, the fit's start
        first), ``cause`` (its phrase, as the fidelity map says it; None where it agrees),
        ``by_check`` (:func:`check_passes`) and ``theta_rms_rad`` (over the starts; None if
        a run has none).
    """
    checked = [v for v in verified if v.get("passed") is not None]
    checks = [c for v in verified for c in v["checks"]]
    failed = [(v, c) for v in verified for c in v["checks"] if c["passed"] is False]
    agrees = (bool(checked) and all(v["passed"] for v in checked)
              and any(v["role"] == "held-out" for v in checked))
    rank = {name: i for i, name in enumerate(CAUSE_ORDER)}
    first = (min(failed, key=lambda vc: (rank.get(vc[1]["check"], len(rank)),
                                         vc[0]["role"] != "fit")) if failed else None)
    rms = [v.get("theta_rms_rad") for v in checked]
    return {"agrees": agrees, "passes": sum(c["passed"] is not False for c in checks),
            "checks": len(checks), "departures": len(failed),
            "first_departing": None if first is None else
            {"check": first[1]["check"], "n0": first[0]["n0"], "theta0": first[0]["theta0"],
             "role": first[0]["role"]},
            "cause": None if agrees else cause_of({"agrees": False,
                                                   "tuned": {"verified": verified}}),
            "by_check": check_passes(verified),
            "theta_rms_rad": (float(math.sqrt(sum(r * r for r in rms) / len(rms)))
                              if rms and all(r is not None for r in rms) else None)}


def rank_key(row: dict[str, Any]) -> tuple[Any, ...]:
    """Best first: agreeing, most checks passing, fewest departures, smallest theta RMS."""
    rms = row.get("theta_rms_rad")
    return (not row["agrees"], -row["passes"], row["departures"],
            math.inf if rms is None else rms)


def _dimension_values(c: dict[str, Any], mu: float) -> dict[str, str]:
    """A candidate's value of each attributed dimension (a choice, or a third of a range)."""
    def third(x: float, lo: float, hi: float) -> str:
        f = (math.log(x) - math.log(lo)) / (math.log(hi) - math.log(lo))
        edges = [lo * (hi / lo) ** (k / 3) for k in range(4)]
        k = min(2, max(0, int(f * 3)))
        return f"{('low', 'mid', 'high')[k]} [{edges[k]:.3g}, {edges[k + 1]:.3g}]"

    solref, solimp = c["solref"], c["solimp"]
    direct = solref[0] < 0
    return {
        "cone": c["cone"], "condim": str(c["condim"]), "integrator": c["integrator"],
        "timestep_s": f"{c['timestep_s']:g}", "noslip_iterations": str(c["noslip_iterations"]),
        "solref_form": "direct" if direct else "time constant",
        "solreffriction": "pairs" if c.get("solreffriction") else "none",
        "impedance": "constant" if solimp[0] == solimp[1] else "ramp",
        "impratio": third(c["impratio"], *IMPRATIO),
        "dampratio": third(min(max(abs(solref[1]) / (2 * math.sqrt(-solref[0])) if direct
                                   else solref[1], DAMPRATIO[0]), DAMPRATIO[1]), *DAMPRATIO),
        "d0": third(min(max(solimp[0], D0[0]), D0[1]), *D0),
        "mu": third(min(max(c["mu"], mu / MU_FACTOR), mu * MU_FACTOR), mu / MU_FACTOR,
                    mu * MU_FACTOR),
    }


def attribution(rows: list[dict[str, Any]], mu: float) -> dict[str, dict[str, Any]]:
    """Per dimension and value: how many candidates, how many agree, each check's pass share.

    Only the drawn candidates (a sample of the whole space; the baselines are not). A check's
    share is over the candidates where it was judged (:func:`check_passes`).

    Returns:
        dimension -> value -> ``{n, agree, passes_share, checks: {check: share}, worst}``
        (``worst``: the check passing least often there).
    """
    drawn = [r for r in rows if r["settings"].get("origin") == "drawn"]
    out: dict[str, dict[str, Any]] = {}
    for r in drawn:
        for dim, val in _dimension_values(r["settings"], mu).items():
            cell = out.setdefault(dim, {}).setdefault(val, {"rows": []})
            cell["rows"].append(r)
    for dim, vals in out.items():
        for val, cell in list(vals.items()):
            mine = cell.pop("rows")
            shares = {}
            for name in CAUSE_ORDER:
                judged = [r["by_check"][name] for r in mine if name in r["by_check"]]
                if judged:
                    shares[name] = sum(judged) / len(judged)
            total = sum(r["checks"] for r in mine)
            vals[val] = {"n": len(mine), "agree": sum(r["agrees"] for r in mine),
                         "passes_share": sum(r["passes"] for r in mine) / total if total
                         else None, "checks": shares,
                         "worst": min(shares, key=lambda k: shares[k]) if shares else None}
        out[dim] = dict(sorted(vals.items(), key=lambda kv: _value_order(dim, kv[0])))
    return out


def _value_order(dim: str, value: str) -> tuple[int, str]:
    """A dimension's values in the space's order (a range's thirds low, mid, high)."""
    choices = {"cone": CONES, "condim": CONDIMS, "integrator": INTEGRATORS,
               "timestep_s": TIMESTEPS_S, "noslip_iterations": NOSLIP_ITERATIONS,
               "solref_form": ("time constant", "direct"), "solreffriction": ("none", "pairs"),
               "impedance": ("ramp", "constant")}.get(dim)
    order = ([f"{c:g}" if isinstance(c, float) else str(c) for c in choices] if choices
             else ["low", "mid", "high"])
    head = value.split(" ", 1)[0] if choices is None else value
    return (order.index(head) if head in order else len(order), value)


# ---------------------------------------------------------------- the study
def say_to_terminal(progress: bool) -> Callable[[str], None] | None:
    """Where progress lines go: stderr on a terminal (``contact search: ...``), else None."""
    if not progress or not sys.stderr.isatty():
        return None
    return lambda line: print(f"contact search: {line}", file=sys.stderr, flush=True)


@dataclass
class PointRuns:
    """A point's starts and the reference's runs from them; it verifies candidates there.

    Attributes:
        point: ``A_over_C``, ``a_over_R``, ``mu``, ``group``, ``n0`` and ``theta0``.
        t_end_s: Horizon of the runs (s); a start whose reference is still moving at its end
            runs over a longer one, as the tuning verifies it (``horizons``).
        top: The point's top.
        base: The overrides of the point's top, table and fit start.
        starts: The fit's start and the held-out ones
            (:func:`tippetop.compare.tuning.tune.starts_for`).
        refs: The reference's results from them, each over its start's horizon.
        options: Keyword arguments of :func:`run_tasks`.
        horizons: Each start's horizon (s): :func:`tippetop.compare.tuning.tune.settled_references`.
        runs: MuJoCo runs made so far (every candidate's starts, cached or not).
        cached: Of those, served by the cache.
    """

    point: dict[str, Any]
    t_end_s: float
    top: Any
    base: tuple[Override, ...]
    starts: list[TuneStart]
    refs: list[Any]
    options: dict[str, Any]
    horizons: list[float] = field(default_factory=list)
    runs: int = 0
    cached: int = 0

    def outcome_at(self, n: float, th0: float, role: str = "") -> tuple[float | None, str]:
        """The theory's (theta_s, outcome) from a start."""
        return predicted_outcome(self.top, float(theory.jellett_from_spin(self.top, n, th0,
                                                                          0.0)))

    def verify(self, cands: Sequence[ContactCandidate], first_index: int = 0,
               batch: int = BATCH, say: Callable[[str], None] | None = None,
               label: str = "search") -> list[dict[str, Any]]:
        """Each candidate run from every start and judged: one row each (``verified`` kept)."""
        rows: list[dict[str, Any]] = []
        horizons = self.horizons or [self.t_end_s] * len(self.starts)
        for k in range(0, len(cands), batch):
            part = cands[k:k + batch]
            if say:
                say(f"{label}: candidates {k + 1}-{k + len(part)} of {len(cands)} ...")
            tasks = [Task(None, (*self.base, *s.overrides(), Override.of("run.t_end_s", t_end),
                                 *c.overrides()), "mujoco")
                     for c in part for s, t_end in zip(self.starts, horizons, strict=True)]
            got = run_tasks(tasks, label=f"{label} {k + 1}-{k + len(part)}/{len(cands)}",
                            **self.options)
            self.runs += len(got)
            self.cached += sum(r.cached for r in got)
            n = len(self.starts)
            for j, c in enumerate(part):
                mine = got[j * n:(j + 1) * n]
                verified = [judge_start(s, ref, run, self.outcome_at, self.top.A_over_C)
                            for s, ref, run in zip(self.starts, self.refs, mine, strict=True)]
                rows.append({"index": first_index + k + j, "settings": c.to_json(),
                             "label": c.label(), **score(verified), "verified": verified,
                             "errors": [r.error for r in mine if r.error]})
        return rows


def prepare_point(A_over_C: float, a_over_R: float, mu: float, *, n0: float | None = None,
                  theta0: float = START_THETA0, t_end_s: float = DEFAULT_T_END_S,
                  run_options: dict[str, Any] | None = None,
                  say: Callable[[str], None] | None = None) -> PointRuns:
    """The point's top and starts, and the reference run from each (checked first).

    Raises:
        TippetopError: Bad input or a top the scene does not admit (one line), before any
            run.
        RunFailedError: A reference run that failed.
    """
    if not (isinstance(t_end_s, (int, float)) and math.isfinite(t_end_s)
            and 0 < t_end_s <= 600):
        raise TippetopError(f"--t-end-s: expected a number of seconds in (0, 600], got "
                            f"{t_end_s!r}")
    if n0 is not None and not (math.isfinite(n0) and n0 > 0):
        raise TippetopError(f"--n0: expected a spin > 0 rad/s, got {n0!r}")
    if not (math.isfinite(theta0) and 0 < theta0 < math.pi):
        raise TippetopError(f"--theta0: expected a tilt in (0, pi) rad, got {theta0!r}")
    top = Task(None, point_overrides(A_over_C, a_over_R, mu, START_N0, START_THETA0),
               "ode").load().top
    n0 = start_spin(top) if n0 is None else float(n0)
    base = point_overrides(A_over_C, a_over_R, mu, n0, theta0)
    starts = starts_for(n0, theta0)
    opts = dict(run_options or {})
    if say:
        say(f"A/C = {A_over_C:g}, a/R = {a_over_R:g}, mu = {mu:g}: the reference from "
            f"{len(starts)} starts ...")
    horizon = Override.of("run.t_end_s", float(t_end_s))
    refs = run_tasks([Task(None, (*base, *s.overrides(), horizon), "ode", "paper")
                      for s in starts], label="search reference", **opts)
    for s, r in zip(starts, refs, strict=True):
        if r.error or r.table is None:
            raise RunFailedError(f"contact search: the reference run from {s.label()} "
                                 f"failed: {r.error}")
    horizons, refs = settled_references(base, starts, refs, float(t_end_s), opts)
    return PointRuns({"A_over_C": A_over_C, "a_over_R": a_over_R, "mu": mu,
                      "group": theory.group(top), "n0": n0, "theta0": theta0},
                     float(t_end_s), top, base, starts, refs, opts, horizons)


def baselines(tuned: dict[str, Any] | None, mu: float,
              with_neighbours: bool = True) -> list[ContactCandidate]:
    """The tuned (where given) and calibrated settings, and the first's :func:`neighbours`."""
    pool = [c for c in (None if tuned is None else candidate_from_settings(tuned, "tuned"),
                        calibrated_candidate(mu)) if c is not None]
    return pool + (neighbours(pool[0]) if pool and with_neighbours else [])


__all__ = ["BATCH", "CONDIMS", "CONES", "DEFAULT_CANDIDATES", "DEFAULT_T_END_S",
           "DIMENSIONS", "FORMAT", "FORMS", "INTEGRATORS", "NOSLIP_ITERATIONS", "TIMESTEPS_S",
           "TOP", "ContactCandidate", "PointRuns", "attribution", "baselines", "by_rank",
           "calibrated_candidate", "candidate_at", "candidate_from_settings", "check_passes",
           "draw_candidates", "form_columns", "judge_start", "neighbours", "prepare_point",
           "rank_key", "say_to_terminal", "score", "sobol_unit", "space", "theta_rms",
           "tuned_settings_from", "unit_of"]
