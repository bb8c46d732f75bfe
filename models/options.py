"""How a scene is integrated: the reference ODE's options and MuJoCo's."""

from __future__ import annotations

import sys
from dataclasses import dataclass

from tippetop.models.errors import expect

FORMULATIONS = ("vector", "paper")
#: The reference's integration methods (``ode.method``; reference_ode/methods.py): ``auto``
#: picks one from the tolerance.
ODE_METHODS = ("auto", "dop853", "vern9", "adams", "taylor")
#: ``auto`` where the Taylor method runs (:func:`taylor_runs`): (method, the rtol it runs at per
#: rtol asked for). ``auto`` keeps what a tolerance has meant for this reference (the theta error
#: DOP853 reaches at it) and runs the method that reaches that error soonest. The Taylor method's
#: error per rtol is up to ~10x DOP853's on the Fig. 11 top (rtol 1e-8: 1.5e-9 rad against
#: 1.6e-10) and below it on Fig. 3, so it runs at a tenth of the rtol asked. Measured with
#: ``tippetop bench ode --sweep`` (docs/guide/accuracy.md): at equal error it takes 2-7x less CPU
#: time than DOP853 and 1.2-2.4x less than the Adams method on those tops.
AUTO_TAYLOR: tuple[str, float] = ("taylor", 0.1)
#: ``auto`` elsewhere (a stem, another law, the paper's formulation): (rtol at least, method,
#: the rtol it runs at per rtol asked for), the first whose rtol the tolerance asked for
#: reaches. The Adams method's error per rtol is 100-400x DOP853's on the Fig. 3 and Fig. 11
#: tops (at rtol 1e-9 DOP853 reaches 1.5e-11 rad on Fig. 11, Adams 3e-9; Adams at 1e-12 reaches
#: 4e-12, in a third of DOP853's time), so it runs at 1e-3 of the rtol asked:
#:
#: * rtol >= 1e-4: DOP853 (an error near 1e-5 rad; Adams is no faster there);
#: * 1e-4 > rtol >= 1e-10: Adams at rtol x 1e-3 (1.2-3.5x less CPU time than DOP853 at equal
#:   error, 1.9-4.6x less than LSODA);
#: * rtol < 1e-10: Verner 9(8) (DOP853's errors below ~1e-11 rad; Adams would need an rtol below
#:   1e-13, where its history's rounding leads).
AUTO_RULE: tuple[tuple[float, str, float], ...] = (
    (1e-4, "dop853", 1.0), (1e-10, "adams", 1e-3), (0.0, "vern9", 1.0))


#: The Taylor method's orders, and the rtol (the one it runs at) from which down each is used
#: (reference_ode/taylor.py, :func:`taylor_order`): on the Fig. 3 and Fig. 11 tops stability (the
#: slip's relaxation, eigenvalues near -400/s) sets the steps at loose tolerances, so the
#: cheapest stable jet wins; measured over orders 6-12 and rtol 1e-3..1e-11 (docs/design.md),
#: and again over orders 7-12 and rtol 1e-3..1e-8 with the jet of 2026-11-28 (its sums
#: reordered: the higher orders gained most), which moved order 9 to rtol 1e-5 and order 10 to
#: 1e-6 (at equal error on both tops as fast or faster than 7 and 9 there).
TAYLOR_ORDERS: tuple[tuple[float, int], ...] = ((1e-4, 7), (1e-5, 9), (1e-6, 10), (0.0, 12))


def taylor_orders_text() -> str:
    """The Taylor method's orders as words: "7, 9, 10 and 12" (:data:`TAYLOR_ORDERS`)."""
    orders = [str(o) for o in sorted({o for _, o in TAYLOR_ORDERS})]
    return orders[0] if len(orders) == 1 else f"{', '.join(orders[:-1])} and {orders[-1]}"


#: What each method of :data:`ODE_METHODS` is, in a few words (tables, run summaries, the
#: glossary; reference_ode/methods.py declares the methods with them).
METHOD_TITLES: dict[str, str] = {
    "dop853": "Dormand-Prince 8(5,3) (Hairer's DOP853)",
    "vern9": "Verner 9(8) (the most efficient pair, IIIXb)",
    "adams": "variable-order Adams PECE, orders 1-12",
    "taylor": f"adaptive Taylor series, orders {taylor_orders_text()} (the ball on the table, "
              "the modified Coulomb law)",
}


def auto_text() -> str:
    """What ``auto``, the default, runs, in words.

    Made from :data:`AUTO_TAYLOR` and :data:`AUTO_RULE`.
    """
    rule = []
    lower = None
    for limit, name, factor in AUTO_RULE:
        at = "" if factor == 1.0 else f" at {factor:g} x the rtol"
        where = (f"rtol >= {limit:g}" if lower is None else
                 f"{lower:g} > rtol >= {limit:g}" if limit > 0 else f"rtol < {lower:g}")
        rule.append(f"{name}{at} where {where}")
        lower = limit
    return (f"the default, auto, runs {AUTO_TAYLOR[0]} at {AUTO_TAYLOR[1]:g} x the rtol "
            "where it runs; elsewhere " + ", ".join(rule))


def taylor_order(rtol: float) -> int:
    """The Taylor method's order at the relative tolerance it runs at (:data:`TAYLOR_ORDERS`)."""
    for limit, order in TAYLOR_ORDERS:
        if rtol >= limit:
            return order
    return TAYLOR_ORDERS[-1][1]


def method_title(method: str, rtol: float) -> str:
    """The method as a run reports it: its name, with its order for the Taylor method."""
    return f"taylor (order {taylor_order(rtol)})" if method == "taylor" else method


def taylor_unsupported(formulation: str, law: str, stem: bool) -> str | None:
    """None if the Taylor method runs a problem, else why not (one line).

    It runs the vector formulation's ball on the table (no stem) with the modified Coulomb law
    (reference_ode/taylor.py; its kernel checks the same on the packed parameters).
    """
    if formulation != "vector":
        return "the Taylor method runs the vector formulation's ball on the table only"
    if stem:
        return "the Taylor method runs the ball on the table only, with no stem"
    if law != "modified_coulomb":
        return "the Taylor method runs the modified Coulomb law only"
    return None


def taylor_runs(formulation: str, law: str, stem: bool) -> bool:
    """Whether the Taylor method runs a problem (:func:`taylor_unsupported` is None)."""
    return taylor_unsupported(formulation, law, stem) is None


def auto_method(rtol: float, taylor: bool = False) -> tuple[str, float]:
    """What ``ode.method = auto`` runs at ``rtol``: (method, its tolerances per those asked).

    Args:
        rtol: The relative tolerance asked for.
        taylor: Whether the Taylor method runs the problem (:func:`taylor_runs`).
    """
    if taylor:
        return AUTO_TAYLOR
    for limit, name, factor in AUTO_RULE:
        if rtol >= limit:
            return name, factor
    return "dop853", 1.0


#: The largest ode.max_steps: the compiled integrator counts steps in a signed 64-bit integer.
MAX_STEPS_LIMIT = 2**63 - 1

#: The paper formulation divides by sin(theta); below this it stops and says so.
DEFAULT_SINGULAR_SIN = 1e-7


@dataclass(frozen=True)
class OdeOptions:
    """How the reference ODE is integrated.

    Attributes:
        formulation: ``vector`` (singularity-free, the default) or ``paper`` (Appendix A).
        rtol: Relative tolerance of the DOP853 error control.
        atol: Absolute tolerance (same units as each state component).
        max_steps: The run stops with status ``max_steps`` after this many accepted steps.
        singular_sin: Paper formulation: stop with status ``singular`` below this |sin theta|.
        method: The integration method (:data:`ODE_METHODS`); ``auto`` chooses from ``rtol``.
    """

    formulation: str = "vector"
    rtol: float = 1e-9
    atol: float = 1e-12
    max_steps: int = 20_000_000
    singular_sin: float = DEFAULT_SINGULAR_SIN
    method: str = "auto"

    def __post_init__(self) -> None:
        expect(self.formulation in FORMULATIONS, "ode.formulation", "|".join(FORMULATIONS),
               self.formulation, FORMULATIONS)
        expect(self.method in ODE_METHODS, "ode.method", "|".join(ODE_METHODS), self.method,
               ODE_METHODS)
        for name in ("rtol", "atol", "singular_sin"):
            v = getattr(self, name)
            expect(_positive(v), f"ode.{name}", "a finite number > 0", v)
        expect(self.rtol >= 1e-14, "ode.rtol", "a tolerance >= 1e-14 (double precision)",
               self.rtol)
        expect(isinstance(self.max_steps, int) and not isinstance(self.max_steps, bool)
               and 0 < self.max_steps <= MAX_STEPS_LIMIT, "ode.max_steps",
               f"a positive integer <= {MAX_STEPS_LIMIT}", self.max_steps)


#: A generated top's noslip iterations unless the scene sets them: none (MuJoCo's own default).
GENERATED_NOSLIP_ITERATIONS = 0

MUJOCO_FRICTION_MODES = ("paper", "native")
MUJOCO_INTEGRATORS = ("Euler", "implicit", "implicitfast", "RK4")
MUJOCO_CONES = ("pyramidal", "elliptic")


@dataclass(frozen=True)
class MujocoOptions:
    """How MuJoCo simulates a scene.

    Attributes:
        friction: ``paper`` (frictionless contact, the paper's law applied by the harness) or
            ``native`` (MuJoCo's own contact friction).
        timestep_s: Physics timestep (s).
        integrator: ``Euler``, ``implicit``, ``implicitfast`` or ``RK4``.
        cone: Friction cone, ``pyramidal`` or ``elliptic`` (native mode).
        condim: Contact dimensionality; None derives it from the scene's effects (1 in paper
            mode; 3 sliding, 4 with torsional, 6 with rolling friction in native mode).
        mu: Native sliding coefficient; None uses the scene's friction.mu.
        solref: Contact solref (time constant s, damping ratio), native mode.
        solimp: Contact solimp (d0, dwidth, width m, midpoint, power).
        impratio: Ratio of frictional to normal constraint impedance (native, elliptic cone).
        noslip_iterations: MuJoCo's noslip solver iterations (0: off; None: the model's: a
            loaded file's own, :data:`GENERATED_NOSLIP_ITERATIONS` for a generated top).
        calibrated: Native mode: take the calibrated settings (``models/calibrated_native.toml``)
            for every key the scene does not set. None: yes for a generated top, no for a top
            loaded from an MJCF file (which then runs with its own settings).
        fit_paper_timestep: Paper mode: when the timestep the scene does not set itself (a
            loaded file's own, say) is longer than the law can follow, run at the largest
            1-2-5 step below that limit and say so in the plan, instead of refusing the run.
        iterations: The constraint solver's maximum iterations (None: the model's: a loaded
            file's own, MuJoCo's default 100 for a generated top).
        tolerance: The constraint solver's tolerance (None: the model's; MuJoCo's 1e-8).
        solreffriction: Native mode, elliptic cone: the friction rows' own solref (time
            constant s, damping ratio, or -stiffness, -damping), which MuJoCo takes only on
            an explicit contact pair: the plan writes a pair for every geom of the top that
            touches the table (None: none; the friction rows use solref).
        contacts: False disables contacts altogether (MuJoCo's ``<flag contact="disable">``):
            the top falls freely. For attribution (``tippetop matrix``): does a difference
            between engines follow the contact, or the free body's integration?
    """

    friction: str = "paper"
    timestep_s: float = 2e-5
    integrator: str = "RK4"
    cone: str = "elliptic"
    condim: int | None = None
    mu: float | None = None
    solref: tuple[float, float] = (0.02, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.9, 0.95, 0.001, 0.5, 2.0)
    impratio: float = 1.0
    noslip_iterations: int | None = None
    calibrated: bool | None = None
    fit_paper_timestep: bool = False
    iterations: int | None = None
    tolerance: float | None = None
    contacts: bool = True
    solreffriction: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        expect(self.friction in MUJOCO_FRICTION_MODES, "mujoco.friction",
               "|".join(MUJOCO_FRICTION_MODES), self.friction, MUJOCO_FRICTION_MODES)
        expect(self.integrator in MUJOCO_INTEGRATORS, "mujoco.integrator",
               "|".join(MUJOCO_INTEGRATORS), self.integrator, MUJOCO_INTEGRATORS)
        expect(self.cone in MUJOCO_CONES, "mujoco.cone", "|".join(MUJOCO_CONES), self.cone,
               MUJOCO_CONES)
        expect(_positive(self.timestep_s), "mujoco.timestep_s", "a finite number > 0",
               self.timestep_s)
        expect(self.condim is None or self.condim in (1, 3, 4, 6), "mujoco.condim",
               "1, 3, 4 or 6", self.condim)
        expect(self.mu is None or (_positive(self.mu) or self.mu == 0), "mujoco.mu",
               "a finite number >= 0", self.mu)
        expect(_positive(self.impratio), "mujoco.impratio", "a finite number > 0",
               self.impratio)
        expect(self.noslip_iterations is None or (
            isinstance(self.noslip_iterations, int) and 0 <= self.noslip_iterations <= 10_000),
               "mujoco.noslip_iterations", "an integer from 0 to 10000", self.noslip_iterations)
        expect(self.iterations is None or (
            isinstance(self.iterations, int) and not isinstance(self.iterations, bool)
            and 1 <= self.iterations <= 100_000), "mujoco.iterations",
            "an integer from 1 to 100000", self.iterations)
        expect(self.tolerance is None or _positive(self.tolerance) or self.tolerance == 0,
               "mujoco.tolerance", "a finite number >= 0", self.tolerance)
        expect(isinstance(self.contacts, bool), "mujoco.contacts", "true or false",
               self.contacts)
        expect(len(self.solref) == 2 and all(_finite(v) for v in self.solref),
               "mujoco.solref", "two finite numbers [timeconst, dampratio]", self.solref)
        expect(self.solreffriction is None or (
            len(self.solreffriction) == 2 and all(_finite(v) for v in self.solreffriction)
            and (all(v > 0 for v in self.solreffriction)
                 or all(v < 0 for v in self.solreffriction))),
            "mujoco.solreffriction", "two finite numbers, both > 0 [timeconst, dampratio] or "
            "both < 0 [-stiffness, -damping]", self.solreffriction)
        expect(len(self.solimp) in (3, 5) and all(_finite(v) for v in self.solimp),
               "mujoco.solimp", "3 or 5 finite numbers [d0, dwidth, width, midpoint, power]",
               self.solimp)


def _finite(v: object) -> bool:
    """A real number a float can hold: not NaN, not inf, not an int like 10**400."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) \
        and -sys.float_info.max <= v <= sys.float_info.max


def _positive(v: object) -> bool:
    return _finite(v) and v > 0
