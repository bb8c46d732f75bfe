"""Every metric, declared once: its name, unit, meaning, kinds of case, tolerances and text.

A *metric* is a number (or a class, a flag) measured of a run, a threshold search, a sweep or
an atlas. Each is a :class:`Metric` in :data:`METRICS`, and everything that shows or compares
one reads it here: the terminal and the reports (:meth:`Metric.text`, the unit), the nightly
(the kinds of case it applies to, the tolerance against a baseline), the matrix (the same
tolerance between two engines), the verdict (how far from the theory or the reference a run
may be and still agree), ``tippetop metrics`` and the glossary of the documentation. A key an
output uses that is not declared here is a test failure (``tests/compare/test_metrics.py``).

Standard library only: the command line reads it to build its help.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from tippetop.models.numbers import MISSING, float_text, number_text

#: The kinds of case a metric can apply to (the nightly catalogue's ``kind``).
KINDS: tuple[str, ...] = ("run", "threshold", "sweep", "atlas")
#: How a metric's value is printed: a number with its unit (4 significant digits), a relative
#: quantity (2, and "(relative)"), a yes/no flag, a class (a word), a count, or one value per
#: point (a sweep's n0, an atlas's grid point).
STYLES: tuple[str, ...] = ("number", "relative", "flag", "class", "count", "per_point")


@dataclass(frozen=True)
class Tolerance:
    """How far two values of a metric may be apart and still be the same.

    Attributes:
        kind: ``exact`` (equal), ``abs`` (``|v - b| <= value``), ``rel``
            (``|v - b| <= max(value * |b|, floor)``), ``growth`` (one-sided:
            ``v <= max(value * b, floor)``, a smaller value always passes) or ``max`` (a
            value judged on its own: ``v <= value``).
        value: The bound (unit as the metric for ``abs``; a fraction for ``rel``; a factor for
            ``growth``).
        floor: Absolute allowance under ``rel`` and ``growth`` (unit of the metric).
        unit: The metric's unit, for messages.
        why: One line on why this bound.
    """

    kind: str
    value: float = 0.0
    floor: float = 0.0
    unit: str = ""
    why: str = ""

    def describe(self) -> str:
        """The bound in words, e.g. ``+-0.02 rad``."""
        u = f" {self.unit}" if self.unit and self.unit != "relative" else ""
        if self.kind == "exact":
            return "exact"
        if self.kind == "abs":
            return f"+-{self.value:g}{u}"
        if self.kind == "rel":
            extra = f" (at least {self.floor:g}{u})" if self.floor else ""
            return f"+-{100 * self.value:g} %{extra}"
        if self.kind == "max":
            return f"<= {self.value:g}{u}"
        return f"<= max({self.value:g} x baseline, {self.floor:g}{u})"

    def to_json(self) -> dict[str, Any]:
        """``{kind, value, floor, unit, text, why}``: as results.json and ``--json`` say it."""
        return {"kind": self.kind, "value": self.value, "floor": self.floor, "unit": self.unit,
                "text": self.describe(), "why": self.why}


#: How a metric's agreement bound is found for one run (:meth:`Metric.agreement_bound`):
#: ``fixed`` (the declared bound), ``event`` (max(the floor, the fraction x the reference's
#: time)) or ``per_family`` (:data:`J_TOL`, the reference's or an engine's).
AGREEMENT_RULES: tuple[str, ...] = ("fixed", "event", "per_family")


@dataclass(frozen=True)
class Wording:
    """How a run's difference from the reference is said (``compare``'s list of differences).

    The templates take ``{value}`` and ``{ref}`` (each as text, with the metric's unit) and
    ``{note}`` (the run's own note, else its value). Unset, a difference reads ``NAME VALUE
    against the reference's REF: GAP apart, over the NAME tolerance of TOL (WHY)``.

    Attributes:
        whole: The whole sentence (a failed run, a different outcome).
        run_none: The sentence where the run has no value and the reference has one.
        ref_none: The sentence where the reference has no value and the run has one.
        value: The run's value in words, in place of ``NAME VALUE against the reference's``.
        gap: Whether ``: GAP apart`` is said (not of a bound on the run's own value, an RMS).
        bound: What the bound is called: ``tolerance``, or ``limit`` (a bound on the run's own
            value).
        by_run: The run's value alone picks ``run_none`` or ``ref_none`` (a metric the
            reference never has a value of where the run's differs: the ball leaving the table).
    """

    whole: str = ""
    run_none: str = ""
    ref_none: str = ""
    value: str = ""
    gap: bool = True
    bound: str = "tolerance"
    by_run: bool = False


@dataclass(frozen=True)
class Metric:
    """One metric, declared once.

    Attributes:
        name: The key every output uses (``t_invert``).
        unit: ``rad``, ``s``, ``rad/s``, ``J``, ``m``, ``relative`` (a ratio to the quantity
            the meaning names), ``fraction`` or ``""`` (a class, a flag, a count).
        meaning: One sentence: what it measures and how.
        kinds: The kinds of case it applies to (:data:`KINDS`).
        tolerance: How far it may move between two runs of the same thing and still be the
            same: a run against its stored baseline (the nightly), two engines on the same
            scene (the matrix). None: not compared that way.
        agreement: How far a run's value may be from the reference's or the theory's and the
            run still agree (the verdict); None: not part of the verdict.
        against: What ``agreement`` compares with: ``theory``, ``reference``, ``itself`` (a
            bound on the run's own value) or ``""``.
        style: How its value is printed (:data:`STYLES`).
        label: A short heading for tables.
        none_means: What None means in a finished run's output, where ``-`` would hide it
            (``never (does not turn over)``); empty: None is ``-``.
        wording: How a difference from the reference is said (:class:`Wording`).
        agreement_rule: How ``agreement`` gives one run's bound (:data:`AGREEMENT_RULES`).
    """

    name: str
    unit: str
    meaning: str
    kinds: tuple[str, ...] = ("run",)
    tolerance: Tolerance | None = None
    agreement: Tolerance | None = None
    against: str = ""
    style: str = "number"
    label: str = ""
    none_means: str = ""
    wording: Wording = Wording()
    agreement_rule: str = "fixed"

    def agreement_bound(self, family: str = "mujoco", ref: float | None = None) -> float:
        """How far one run's value may be from the reference's or the theory's.

        Args:
            family: The run's engine family (``ode``: the reference; ``mujoco``: any other).
            ref: The reference's value (an event's time), for the ``event`` rule.

        Raises:
            KeyError: The metric is not part of the verdict (no ``agreement``).
        """
        if self.agreement_rule == "event":
            return event_tolerance(ref)
        if self.agreement_rule == "per_family":
            return J_TOL["ode" if family == "ode" else "mujoco"]
        if self.agreement is None:
            raise KeyError(f"{self.name}: not part of the verdict")
        return self.agreement.floor if self.agreement.kind == "rel" else self.agreement.value

    @property
    def table_unit(self) -> str:
        """The unit a compact table prints after the number (the matrix's, bisect's columns).

        The metric's own, or none for a ratio (``relative``, ``fraction``) or a text.
        """
        return "" if self.unit in ("relative", "fraction") else self.unit

    def text(self, value: Any) -> str:
        """The value as a person reads it, with its unit (``2.329 s``, ``1.3e-9 (relative)``)."""
        if value is None:
            return MISSING
        if self.style == "per_point" and isinstance(value, dict):
            return ", ".join(f"{k}: {self.point_text(v)}" for k, v in value.items()) or MISSING
        return self.point_text(value)

    def point_text(self, value: Any) -> str:
        """One value (of a point, for :data:`STYLES` ``per_point``), with its unit."""
        if value is None:
            return MISSING
        if isinstance(value, bool):
            return "yes" if value else "no"
        if isinstance(value, str):
            return value
        if isinstance(value, (int, float)):
            if not math.isfinite(float(value)):
                return float_text(float(value))
            if self.style == "relative" or self.unit == "relative":
                return f"{float_text(float(value), 2)} (relative)" if value else "0 (relative)"
            if self.unit == "fraction":
                return f"{number_text(100.0 * float(value))} %"
            if self.style == "count":
                return number_text(int(value))
            return number_text(float(value), self.unit)
        return str(value)

    def to_json(self) -> dict[str, Any]:
        """``{name, unit, meaning, kinds, tolerance, agreement, against, style, label}``."""
        return {"name": self.name, "unit": self.unit, "meaning": self.meaning,
                "kinds": list(self.kinds),
                "tolerance": None if self.tolerance is None else self.tolerance.to_json(),
                "agreement": None if self.agreement is None else self.agreement.to_json(),
                "against": self.against, "style": self.style,
                "label": self.label or self.name}


def _tol(kind: str, value: float = 0.0, unit: str = "", why: str = "",
         floor: float = 0.0) -> Tolerance:
    return Tolerance(kind, value, floor, unit, why)


#: The event agreement of a run with the reference: ``|dt| <= max(EVENT_TOL_S, EVENT_RTOL x
#: the reference's time)`` (s, fraction). A run's event time is as sensitive to the contact
#: model as 10 % of a slow rise (the calibrated native settings reach it on the paper's tops).
EVENT_TOL_S = 0.1
EVENT_RTOL = 0.1
#: Jellett's constant while the ball alone touches: conserved by any force through the contact
#: point (the paper's eq. 2.10). The reference's (its integration tolerance) and a MuJoCo
#: run's (a soft contact's sink moves the contact point; first-order integrators move J by
#: O(dt) on an A != C top).
J_TOL = {"ode": 1e-6, "mujoco": 1e-3}


def event_tolerance(ref: float | None) -> float:
    """How far an event time may be from the reference's ``ref`` (s): max(0.1 s, 10 %)."""
    return max(EVENT_TOL_S, EVENT_RTOL * ref) if ref is not None else EVENT_TOL_S

#: theta_asymp against the theory's theta_s (rad): a run's theta_asymp is a mean over its last
#: 10 %: the nutation left there after a start at theta0 = 0.1 or 0.01 moves it by under
#: 0.03 rad in the reference (Figs. 6-8, 11), and the paper prints Fig. 11's to 0.01 rad.
THETA_S_TOL = 0.05

_EVENT_WHY = ("an event time is as sensitive to the contact model as 10 % of a slow rise (the "
              "calibrated native settings reach it on the paper's tops), and no less than "
              f"{EVENT_TOL_S:g} s on a quick one")
_EVENT = Tolerance("rel", EVENT_RTOL, EVENT_TOL_S, "s", _EVENT_WHY)

#: Every metric, in the order the glossary lists them.
METRICS: dict[str, Metric] = {m.name: m for m in (
    # ------------------------------------------------------------ a run
    Metric("outcome", "", "the run's final state: upright, intermediate or inverted by "
           "theta_asymp, or inconclusive when theta still moves at the end (by more than "
           "0.02 rad between the last two 5 % windows of the run); failed when it did not "
           "finish", tolerance=_tol("exact", why="upright / intermediate / inverted / "
                                    "inconclusive is the paper's claim"),
           agreement=_tol("exact", why="the theory's outcome class for the run's Jellett "
                          "constant (the reference's outcome when the top reaches its stem)"),
           against="theory", style="class",
           wording=Wording(whole="ends {value} where the reference ends {ref} (a different "
                           "outcome)")),
    Metric("matches_expect", "", "whether the outcome is the scene file's [expect] outcome "
           "(none when the scene expects nothing or the case changes its physics)",
           tolerance=_tol("exact", why="agreement with the scene's [expect] outcome must not "
                          "be lost"), style="flag"),
    Metric("theta_asymp", "rad", "the mean tilt theta over the last 10 % of the run",
           kinds=("run",),
           tolerance=_tol("abs", 0.02, "rad", "the ODE repeats it to 1e-6 rad; 0.02 rad is "
                          "below the 0.05-rad agreement with theta_s, so real shifts show"),
           agreement=_tol("abs", THETA_S_TOL, "rad", "a mean over the run's last 10 %: the "
                          "nutation left there moves it by under 0.03 rad in the reference, "
                          "and the paper prints Fig. 11's to 0.01 rad"),
           against="theory"),
    Metric("theta_final", "rad", "the tilt theta at the last sample"),
    Metric("t_invert", "s", "the first time theta crosses pi/2 from below: the top turns "
           "over (none: it never does within the run); MuJoCo's located to the step",
           tolerance=_tol("abs", 0.1, "s", "~3 % of the Fig. 3 inversion time; the ODE locates "
                          "it to 1e-6 s and a MuJoCo timestep change moves it by milliseconds"),
           agreement=_EVENT, against="reference", agreement_rule="event",
           none_means="never (does not turn over)",
           wording=Wording(run_none="never turns over; the reference does at {ref}",
                           ref_none="turns over at {value}; the reference never does")),
    Metric("t_stem", "s", "the first time the stem touches the table (none: no stem, or it "
           "never does); MuJoCo's located to the step",
           tolerance=_tol("abs", 0.1, "s", "as t_invert: ~3 % of the Fig. 3 "
                                              "inversion time"),
           agreement=_EVENT, against="reference", agreement_rule="event",
           none_means="never (no stem contact)"),
    Metric("J_rel_drift", "relative", "the largest change of Jellett's constant J = R L_z - "
           "a C n while the ball alone touches the table (until the stem lands or the ball "
           "first leaves the table: J is conserved only while the force acts at the ball's "
           "contact point), relative to J at the start",
           tolerance=_tol("growth", 10.0, why="Jellett's constant is conserved: drift may "
                          "shrink freely, grow 10x at most, and below 1e-8 (10x the ODE's "
                          "rtol) it is noise", floor=1e-8),
           agreement=_tol("max", J_TOL["mujoco"], "relative", "conserved by any force "
                          "through the contact point (eq. 2.10): 1e-3 for MuJoCo (a soft "
                          "contact's sink, first-order integrators), 1e-6 for the reference "
                          "(its integration tolerance)"),
           against="itself", style="relative", label="J drift", agreement_rule="per_family",
           wording=Wording(gap=False, bound="limit")),
    Metric("energy_monotone", "", "whether the energy E never rises by more than the "
           "integration's own error (dE/dt = F . v_P <= 0 under every law)",
           tolerance=_tol("exact", why="dE/dt = F . v_P <= 0 under every law: a rise is a "
                          "bug"), style="flag"),
    Metric("energy_rise_rel", "relative", "the largest rise of E above its running minimum, "
           "as a fraction of E0",
           agreement=_tol("max", 1e-6, "relative", "friction and inelastic impacts only take "
                          "energy: MuJoCo's may rise by the elastic energy its soft contacts "
                          "held (force x depth) plus 1e-6 of E0; the reference's within its "
                          "integration tolerance"),
           against="itself", style="relative", label="energy rise"),
    Metric("energy_lost", "J", "E0 - E at the end: what friction took",
           tolerance=_tol("rel", 0.02, "J", "E0 - E_end sums the friction work; 2 % catches a "
                          "changed law, 1 uJ (~1e-4 of E0) ignores the upright tops' tiny "
                          "losses", floor=1e-6)),
    Metric("energy_dissipated_J", "J", "E0 - E at the end (compare's name for energy_lost)"),
    Metric("contact_lost", "", "whether the run stopped because the ball left the table: the "
           "reference's model does not follow a flight, so it stops there (a MuJoCo run "
           "follows its flights: t_left_table says when the ball first leaves)",
           tolerance=_tol("exact", why="leaving the table is a different regime, never a "
                          "tolerance"), style="flag"),
    Metric("t_left_table", "s", "the first time the ball leaves the table before the stem "
           "lands: the start of its first flight after the first 0.05 s (10 ms or more without "
           "contact at any step, the ball risen 10 um or more; a shorter or lower stretch is a "
           "soft contact chattering: see flights), located to the step; the reference's is "
           "where it stopped because its normal force reached 0 (none: the ball stays on)",
           tolerance=_tol("abs", 0.1, "s", "as t_invert: ~3 % of the Fig. 3 "
                                              "inversion time"),
           agreement=_tol("exact", why="a ball that leaves the table where the reference's "
                          "stays on departs: J is not kept in flight, and the paper's model "
                          "has the ball on the table"),
           against="reference", label="left the table",
           none_means="never (the ball stays on the table)",
           wording=Wording(run_none="the ball stays on the table; the reference's leaves it "
                           "at {ref}",
                           ref_none="the ball leaves the table at {value}; the reference's "
                           "stays on", by_run=True)),
    Metric("flights", "", "a MuJoCo run's stretches of steps without contact before the stem "
           "lands, measured at every step: how many, the longest and all of them together "
           "(s), the first's start and the highest's rise (m); and how many are flights "
           "(hops: 10 ms or more and risen 10 um or more, the ball leaving the table), the "
           "first's start, the longest and the highest",
           style="class", none_means="none (the ball never leaves the table)"),
    Metric("status", "", "how the run ended: ok, contact_lost or hop (the physics ended it), "
           "or why it failed (diverged, max_steps, step_too_small, singular ...)",
           tolerance=_tol("exact", why="ok / contact_lost / max_steps / singular must stay "
                          "what it was"), style="class",
           wording=Wording(whole="the run failed ({note}); the reference's status is {ref}")),
    Metric("theta_rms", "rad", "the RMS of theta(t) - theta_ref(t) over the run, against the "
           "reference's theta(t)",
           agreement=_tol("abs", 0.05, "rad", "RMS of theta(t) - theta_ref(t) over the run"),
           against="reference", label="theta RMS vs ref",
           wording=Wording(value="theta(t) departs from the reference's by {value} RMS",
                           gap=False)),
    Metric("theta_rms_vs_ref", "rad", "theta_rms of a run (compare's key)"),
    Metric("theta_s", "rad", "the theory's asymptotic angle for the run's Jellett constant: "
           "0 below n1 (upright), pi above n4 (inverted), the intermediate branch between (the "
           "paper's eq. 4.12)"),
    Metric("t_invert_ref", "s", "the reference's t_invert, beside a run's"),
    Metric("t_stem_ref", "s", "the reference's t_stem, beside a run's"),
    Metric("E0_J", "J", "the energy E at the start of the run"),
    Metric("t_span_s", "s", "the simulated time the run's table covers"),
    Metric("d_theta_asymp", "rad", "theta_asymp - theta_s: how far the run ends from the "
           "theory's angle"),
    Metric("d_t_invert", "s", "t_invert - the reference's t_invert"),
    Metric("theta_trend_rad_s", "rad/s", "how fast theta still moves at the end of the run: "
           "the mean of its last 5 % minus that of the 5 % before, per second"),
    Metric("wall_s", "s", "the wall time the run took"),
    Metric("n_rhs", "", "right-hand-side evaluations of the reference's integrator",
           style="count"),
    Metric("n_steps", "", "how many steps MuJoCo took over the run (mj_step calls)",
           style="count"),
    Metric("max_penetration_m", "m", "MuJoCo's deepest contact penetration over the run"),
    Metric("contact_energy_bound_J", "J", "the most elastic energy MuJoCo's soft contacts held "
           "over the run (normal force x depth)"),
    # ------------------------------------------------------------ a threshold search
    Metric("measured", "rad/s", "the critical spin measured (n1, n4 or n_c): the zero of a "
           "steady state's growth rate, or a bisection's bracket midpoint",
           kinds=("threshold",),
           tolerance=_tol("rel", 0.02, why="a critical spin from bisection: 2 %, or the case's "
                          "bracket width if coarser (one bisection step is its resolution)")),
    Metric("converged", "", "whether the threshold search closed within its tolerance (and, "
           "for a bisection, does not depend on the run length)", kinds=("threshold",),
           tolerance=_tol("exact", why="the bracket must still close within max_rounds"),
           style="flag"),
    # ------------------------------------------------------------ a sweep
    Metric("theta_asymp_vs_n0", "rad", "theta_asymp at each initial spin n0 of a sweep (the "
           "paper's Figs. 9 and 10)", kinds=("sweep",),
           tolerance=_tol("abs", 0.05, "rad", "per sweep point; near n1 and n4 the approach "
                          "outlasts the horizon, so theta_asymp there is more sensitive than a "
                          "single run's"), style="per_point"),
    Metric("outcomes_vs_n0", "", "the outcome at each initial spin n0 of a sweep",
           kinds=("sweep",),
           tolerance=_tol("exact", why="per sweep point: the classification of each n0"),
           style="per_point"),
    # ------------------------------------------------------------ an atlas
    Metric("groups_measured", "", "the group (I, II, III) the measured n1 and n4 imply at each "
           "point of the (A/C, a/R) grid", kinds=("atlas",),
           tolerance=_tol("exact", why="per atlas point: the group the measured n1 and n4 "
                          "imply"), style="per_point"),
    Metric("agreement", "fraction", "the fraction of atlas points whose measured group is the "
           "theory's", kinds=("atlas",),
           tolerance=_tol("abs", 1e-9, why="the fraction of atlas points whose group is the "
                          "theory's")),
    Metric("n1_measured", "rad/s", "n1 measured from growth rates at each atlas point",
           kinds=("atlas",),
           tolerance=_tol("rel", 1e-3, why="per atlas point: growth-rate thresholds repeat to "
                          "1e-9 and lie within 1e-4 of the theory in the reference, so 0.1 % "
                          "shows any real move"), style="per_point"),
    Metric("n4_measured", "rad/s", "n4 measured from growth rates (n3 carried to theta = 0 by "
           "Jellett's constant) at each atlas point", kinds=("atlas",),
           tolerance=_tol("rel", 1e-3, why="per atlas point, as n1_measured"),
           style="per_point"),
)}

#: The keys outputs carry beside the metrics and what ran (:data:`~.summary.RAN_FIELDS`):
#: who ran, in what words, in what structure. Nothing here is a number measured of a run; a
#: key an output uses that is in none of the three is a test failure.
RECORD_KEYS: dict[str, str] = {
    "engine": "the engine a run ran on, as given: ode (the reference), mujoco, mujoco==X.Y.Z, "
              "mujoco@PYTHON, mjx, mjx-f32 or warp",
    "mode": "how the contact force was made: paper, native and its variants, file, or one of "
            "the reference's other laws",
    "run": "a run's name, ENGINE/MODE (ode/paper, mujoco==3.3.7/native)",
    "scene": "the scene (a catalogue name, a scene file or an MJCF top) with its overrides",
    "message": "how a run ended, in words",
    "phases": "a run's contact phases: which of the top's geoms touched the table, from when "
              "to when",
    "rolling_phases": "the reference's rolling phases: how many, and their total time",
    "stem": "the stem the reference modelled: its kind, offset and radius",
    "unused": "--set keys the engine did not read",
    "friction_realised": "the friction law a run realised: the slip at which the contact "
                         "reaches half and 90 % of mu N, a fit of the paper's law, and its "
                         "refit in the reference",
    "reference": "whether the run is the reference's",
    "agrees": "the verdict: no check of the run departs",
    "against": "what a run's outcome was judged against: theory, or the reference where the "
               "top reaches its stem",
    "matches_theory": "compare's name before for agrees",
    "reasons": "why a run does not agree, one sentence per departing check",
    "notes": "the checks not judged, in words",
    "checks": "the verdict's checks of a run: check, passed, value, tolerance, note",
    "error": "why a run failed (none: it finished)",
    "still_moving": "theta still moves at the end of the run: not settled",
    "theory_outcome": "the theory's outcome for the run's start",
    "note": "why a run may depart from the paper's law where it does (its mode), or what was "
            "changed for it",
    "case": "a nightly case's id, CATEGORY/NAME[ENGINE/MODE]",
    "name": "a nightly case's name",
    "category": "a nightly case's category",
    "paper_theta_asymp": "the paper's printed theta_asymp for the scene, when it prints one",
    "expected_departure": "why the catalogue expects the run to depart, when it does",
    "ran": "what ran, in one line",
    "end_state": "how the top ends: its outcome, or on its stem, or on ball and stem",
}


#: ``measured`` of a growth-rate threshold: tighter than a bisection's.
GROWTH_MEASURED = Tolerance(
    "rel", 1e-3, why="a critical spin from growth rates: it repeats to 1e-9 and lies within 1e-4 "
    "of the theory in the reference, so 0.1 % shows any real move")


def metric(name: str) -> Metric:
    """The declaration of ``name``.

    Raises:
        KeyError: ``name`` is not a declared metric.
    """
    return METRICS[name]


def kind_metrics(kind: str) -> tuple[str, ...]:
    """The metrics a case of ``kind`` can check, in declaration order."""
    return tuple(m.name for m in METRICS.values() if kind in m.kinds)


#: The tolerance of every metric that has one, by name (the nightly's and the matrix's).
TOLERANCES: dict[str, Tolerance] = {n: m.tolerance for n, m in METRICS.items()
                                    if m.tolerance is not None}


__all__ = ["AGREEMENT_RULES", "EVENT_RTOL", "EVENT_TOL_S", "GROWTH_MEASURED", "J_TOL", "KINDS",
           "METRICS", "RECORD_KEYS", "STYLES", "THETA_S_TOL", "TOLERANCES", "Metric", "Tolerance",
           "Wording", "event_tolerance", "kind_metrics", "metric"]
