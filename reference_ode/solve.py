"""Run the reference ODE: assemble the compiled pieces, integrate, build the observables table."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from tippetop.models.errors import TippetopError, expect
from tippetop.models.frames import initial_rigid_state
from tippetop.models.observables import COLUMNS, EXTRA_COLUMNS, SIN_THETA_UNDEFINED
from tippetop.models.options import FORMULATIONS as _FORMULATION_NAMES
from tippetop.models.options import OdeOptions, method_title, taylor_unsupported
from tippetop.models.params import FrictionParams, InitialState, StemParams, TopParams
from tippetop.reference_ode import dop853 as _d
from tippetop.reference_ode.contacts import (
    GAP_TOL_R,
    MAX_SWITCHES,
    RIM_MIN_SIN,
    ZENO_SPEED_MPS,
    Contact,
    ball_contact,
    gap,
    impact,
    impact_both,
    normal_velocity,
    phase_params,
    stem_contact,
)
from tippetop.reference_ode.friction import COULOMB_EXACT
from tippetop.reference_ode.methods import METHODS, Method, get_method
from tippetop.reference_ode.params_array import (
    P_COULOMB_KIND,
    P_GAP_TOL,
    P_LAM,
    P_SING,
    P_VEPS,
    P_VISCOUS,
    friction_law_codes,
    pack_params,
)
from tippetop.reference_ode.rolling import (
    F_ENTER,
    ROLLING,
    SLIP_ENTER,
    contact_slip,
    rolling_params,
    rolling_state,
)
from tippetop.reference_ode.statuses import kernel_status_name, status_message
from tippetop.reference_ode.top import FORMULATIONS, TWO_CONTACT, Formulation, two_contact_forces

assert tuple(FORMULATIONS) == _FORMULATION_NAMES

#: Rows of the observables table when the caller gives no sample interval.
DEFAULT_MAX_SAMPLES = 20_000
#: Finest default sample interval (s).
DEFAULT_SAMPLE_DT_S = 1e-3
#: With a progress callback the run is integrated in this many pieces so that a progress bar
#: can advance (each piece costs ~0.1 ms of Python: the kernel's function arguments are
#: unboxed per call); without one, in one piece. The steps are the same either way.
N_CHUNKS = 50
#: ``stiff`` of :func:`simulate_ode`: ``auto`` switches to rolling phases where the law is stiff
#: (:mod:`reference_ode.rolling`), ``off`` integrates the law throughout.
STIFF_MODES = ("auto", "off")
#: The friction laws whose stiff limit is a rolling phase (Lambda, or the exact law's v_eps).
ROLLING_LAWS = ("modified_coulomb", "coulomb")
#: The kernel stops for a look at the slip after this many steps flagged stiff (Hairer's DOP853
#: warns after 15 flagged checks in a row); a look that finds no rolling doubles it, up to
#: :data:`STIFF_ARM_MAX`, so that a stiff stretch that cannot roll costs few stops.
STIFF_ARM = 16
STIFF_ARM_MAX = 1 << 16


@dataclass
class OdeResult:
    """A finished reference run.

    Attributes:
        table: The observables (``models.observables.COLUMNS`` then ``EXTRA_COLUMNS``).
        status: ``ok``, ``contact_lost``, ``singular``, ``max_steps`` or ``step_too_small``.
        message: One sentence on how the run ended.
        t_final: Time the run reached (s).
        t_invert: First time theta passed pi/2 (s), located on the dense output, or None.
        n_rhs: Right-hand-side evaluations.
        n_steps: Accepted steps.
        n_rejected: Rejected steps.
        wall_s: Wall time of the integration (s), compile time excluded.
        rtol: The relative tolerance the method ran at (``auto`` may run a method at tighter
            tolerances than asked: :data:`methods.AUTO_RULE`).
        min_sin_theta: Smallest |sin theta| seen at a step end (0 when a paper-formulation
            step ended with theta outside (0, pi): it passed through the singularity).
        states: The sampled raw states, shape (samples, state size).
        stiff_steps: Accepted steps whose stiffness estimate h lambda exceeded 6.1 (Hairer's
            DOP853 test, see docs/design.md): steps limited by stability, not by
            accuracy. A large share means the problem is stiff for an explicit method.
        h_lambda_max: The largest h lambda estimate of an accepted step.
        phases: The contact phases, each ``{"contact", "t_start", "t_end", "J_rel_drift"}``:
            ``contact`` is ``ball``, ``stem`` (its end alone) or ``both``. Jellett's constant
            of a point's contact, R_c L_z - b_c C n, is conserved only while that point alone
            touches, so ``J_rel_drift`` is that phase's own (None on both points, and on a
            flat end's rim, which keeps none). Without a stem: one ball phase.
        t_stem: First time the stem's end touched the table (s), or None.
        impacts: The impacts at the switches, ``{"t", "to", "impulse_Ns", "approach_mps"}``.
        stiff: What ran for stiff friction: ``rolling`` (the stiffness detector armed: rolling
            phases where the law is stiff and the slip below Lambda), ``off`` (asked for: the
            law throughout), or ``none (...)`` with the reason it does not apply (a law other
            than ``modified_coulomb`` or ``coulomb``, the paper formulation, a stem).
        rolling: The rolling phases, each ``{"t_start", "t_end"}`` (:mod:`reference_ode.rolling`).
        t_rolling_s: Simulated time spent in rolling phases (s).
        atol: The absolute tolerance the method ran at (``rtol``'s: ``auto`` may run a method
            at tighter tolerances than asked, :data:`methods.AUTO_RULE`).
        cpu_s: CPU time of the integration (s): as ``wall_s``, the observables table and the
            compile excluded; what the work-precision benchmark compares with its peers'
            solver calls.
        method: The integration method that ran (``ode.method``, ``auto`` resolved:
            :mod:`reference_ode.methods`), and where a method that hands stiff stretches over
            did so, ``"adams at rtol ..., then dop853 at rtol ... from t = ... s (...)"``.
    """

    table: pd.DataFrame
    status: str
    message: str
    t_final: float
    t_invert: float | None
    n_rhs: int
    n_steps: int
    n_rejected: int
    wall_s: float
    min_sin_theta: float
    rtol: float
    states: np.ndarray = field(repr=False)
    engine: str = "ode"
    stiff_steps: int = 0
    h_lambda_max: float = 0.0
    phases: list[dict] = field(default_factory=list)
    t_stem: float | None = None
    impacts: list[dict] = field(default_factory=list)
    stiff: str = "off"
    rolling: list[dict] = field(default_factory=list)
    t_rolling_s: float = 0.0
    method: str = "dop853"
    cpu_s: float = 0.0
    atol: float = 0.0


def initial_state_vector(top: TopParams, init: InitialState) -> np.ndarray:
    """The vector formulation's state for the paper's initial conditions, shape (11,)."""
    rs = initial_rigid_state(top, init)
    return np.concatenate([rs.com_m[:2], rs.v_com_mps[:2], rs.quat, rs.omega_radps])


def initial_state_paper(top: TopParams, init: InitialState) -> np.ndarray:
    """The paper formulation's state, shape (10,): phi = psi = 0, x = y = 0."""
    return np.array([init.theta0, init.thetadot0, init.Omega0, init.n0, init.uOX, init.uOY,
                     0.0, 0.0, 0.0, 0.0])


def sample_times(t_end_s: float, sample_dt_s: float | None) -> np.ndarray:
    """Uniform sample times 0, dt, 2 dt, ... up to and including t_end."""
    if sample_dt_s is None:
        sample_dt_s = max(DEFAULT_SAMPLE_DT_S, t_end_s / DEFAULT_MAX_SAMPLES)
    expect(math.isfinite(sample_dt_s) and sample_dt_s > 0, "run.sample_dt_s",
           "a finite number > 0", sample_dt_s)
    m = int(math.floor(t_end_s / sample_dt_s + 1e-9))
    t = np.arange(m + 1) * sample_dt_s
    if t[-1] < t_end_s * (1 - 1e-12):
        t = np.append(t, t_end_s)
    return t


def simulate_ode(
    top: TopParams,
    friction: FrictionParams,
    init: InitialState,
    *,
    t_end_s: float,
    sample_dt_s: float | None = None,
    options: OdeOptions | None = None,
    progress: Callable[[float], None] | None = None,
    stem: StemParams | None = None,
    stiff: str = "auto",
) -> OdeResult:
    """Integrate the reference model from ``init`` to ``t_end_s``.

    Args:
        top: The loaded sphere.
        friction: The sliding-friction law and its coefficients.
        init: Initial state in the paper's variables.
        t_end_s: Simulated time (s).
        sample_dt_s: Spacing of the observables table's rows (s); by default 1 ms, coarser for
            long runs so that the table has at most 20,000 rows.
        options: Integrator options (formulation, tolerances).
        progress: Called with the simulated time reached after each piece of the run.
        stem: The stem's end, a second contact surface (vector formulation only): the run
            switches between the ball and the stem's end as each reaches the table
            (:mod:`reference_ode.contacts`). None: the paper's loaded sphere.
        stiff: ``auto``: where the integrator's stiffness detector flags steps while the slip
            is below Lambda, the run switches to a rolling phase (:mod:`reference_ode.rolling`)
            and back to the law where the force reaches ``F_EXIT`` mu N; a run the detector
            never flags takes exactly the steps of ``off`` (the law throughout). Applies to the
            vector formulation with the ``modified_coulomb`` or ``coulomb`` law (v_eps in
            Lambda's place) and no stem.

    Returns:
        The run, with its observables table sampled on the dense output.
    """
    options = options or OdeOptions()
    expect(stiff in STIFF_MODES, "stiff", "|".join(STIFF_MODES), stiff)
    expect(math.isfinite(t_end_s) and t_end_s > 0, "run.t_end_s", "a finite number > 0",
           t_end_s)
    t_end_s = float(t_end_s)  # one compiled signature: every scalar crosses as float64
    form_name = options.formulation
    form = FORMULATIONS[form_name]
    p = pack_params(top, friction, options.singular_sin)
    start = _start(top, friction, init, options, p, stem, t_end_s, sample_dt_s)
    wall0 = time.perf_counter()
    cpu0 = time.process_time()
    phases = _Phases(top, p, stem, form, start.y)
    stiff_ran = _stiff_mode(stiff, form, friction, stem)
    if stiff_ran == "rolling":
        phases.arm(start.stats)
    stop = _integrate(start, phases, t_end_s, options, progress)
    wall = time.perf_counter() - wall0 - phases.compile_s
    cpu = time.process_time() - cpu0 - phases.compile_cpu_s
    return _result(start, stop, phases, friction, form_name, stiff_ran, wall, cpu)


@dataclass(frozen=True)
class _Start:
    """Where a run starts: its state, samples and counters, and the method it starts with."""

    y: np.ndarray
    monitor_floor: float
    t_out: np.ndarray
    Y: np.ndarray
    method: Method
    rtol: float
    atol: float
    max_steps: int
    stats: np.ndarray


@dataclass(frozen=True)
class _Stop:
    """Where a run stopped: its status, time and samples reached, its last method's counters."""

    status: int
    status_name: str
    t: float
    i_out: int
    stats: np.ndarray
    rtol: float
    atol: float
    handed_over: float | None


def _start(top: TopParams, friction: FrictionParams, init: InitialState, options: OdeOptions,
           p: np.ndarray, stem: StemParams | None, t_end_s: float,
           sample_dt_s: float | None) -> _Start:
    """The run's start, its method loaded (or compiled) by a call that takes no step."""
    form = FORMULATIONS[options.formulation]
    y, monitor_floor = _initial_state(top, friction, init, options, p, stem)
    t_out = sample_times(t_end_s, sample_dt_s)
    Y = np.full((t_out.size, y.size), np.nan)
    taylor_reason = taylor_unsupported(options.formulation, friction.law, stem is not None)
    if options.method == "taylor" and taylor_reason is not None:
        raise TippetopError(f"ode.method: expected auto or one of dop853, vern9, adams for this "
                            f"scene ({taylor_reason}), got 'taylor'")
    method, factor = get_method(options.method, float(options.rtol), taylor_reason is None)
    rtol = float(options.rtol) * factor  # auto: the tolerances the chosen method runs at
    atol = float(options.atol) * factor
    max_steps = int(options.max_steps)
    stats = method.new_stats(y.size)
    # load (or compile) the integrator before the clock starts: a call that takes no step
    method.run(form.rhs, form.watch, y.copy(), 0.0, 0.0, t_end_s, p, rtol, atol, 1,
               monitor_floor, t_out[:0], Y[:0], 0, stats.copy())
    return _Start(y, monitor_floor, t_out, Y, method, rtol, atol, max_steps, stats)


def _initial_state(top: TopParams, friction: FrictionParams, init: InitialState,
                   options: OdeOptions, p: np.ndarray,
                   stem: StemParams | None) -> tuple[np.ndarray, float]:
    """The formulation's initial state, checked to be finite, and its monitor floor."""
    form = FORMULATIONS[options.formulation]
    if stem is not None and form.singular:
        raise TippetopError("ode.formulation: expected vector with a stem (effects.stem; the "
                            "paper's equations have the ball only), got 'paper'")
    if form.singular:
        if abs(math.sin(init.theta0)) < options.singular_sin:
            raise TippetopError(
                f"init.theta0: expected |sin theta0| >= {options.singular_sin:g} for the paper "
                f"formulation (it is singular at theta = 0 and pi), got {init.theta0!r}; use "
                "ode.formulation=vector")
        y = initial_state_paper(top, init)
        monitor_floor = float(p[P_SING])
    else:
        y = initial_state_vector(top, init)
        monitor_floor = -math.inf
    dy0 = np.empty_like(y)
    N0 = form.rhs(y, p, dy0)
    row0 = observables_table(options.formulation, friction, p, np.zeros(1), y[None, :]).iloc[0]
    if not (np.all(np.isfinite(dy0)) and math.isfinite(N0) and math.isfinite(row0["E"])
            and math.isfinite(row0["J"])):
        raise TippetopError(
            "init: expected a start whose energy and accelerations are finite, got overflow at "
            f"t = 0 (n0 = {init.n0!r}, theta_dot0 = {init.thetadot0!r}, "
            f"uOX = {init.uOX!r}, uOY = {init.uOY!r}, mu = {friction.mu!r}, "
            f"g = {top.g_mps2!r}): the values are too large for double precision")
    return y, monitor_floor


def _integrate(start: _Start, phases: _Phases, t_end_s: float, options: OdeOptions,
               progress: Callable[[float], None] | None) -> _Stop:
    """Where the run stopped, integrated piece by piece with ``start.y`` advanced in place."""
    y, t_out, Y, stats = start.y, start.t_out, start.Y, start.stats
    method, rtol, atol, max_steps = start.method, start.rtol, start.atol, start.max_steps
    monitor_floor = start.monitor_floor
    t, i_out = 0.0, 0
    handed_over: float | None = None
    status = _d.STATUS_RUNNING
    status_name = ""
    n_chunks = N_CHUNKS if progress is not None else 1
    for k in range(1, n_chunks + 1):
        t_stop = t_end_s if k == n_chunks else t_end_s * k / n_chunks
        while t < t_stop:
            status, t, i_out = method.run(phases.form.rhs, phases.form.watch, y, t,
                                          float(t_stop), t_end_s, phases.p, rtol, atol,
                                          max_steps, phases.monitor_floor(monitor_floor),
                                          t_out, Y, i_out, stats)
            if status == _d.STATUS_STIFF and method.hands_over_stiff:
                stats = _hand_over(stats)  # DOP853 from here on, its detector armed afresh
                method = METHODS["dop853"]
                handed_over = t
                rtol, atol = float(options.rtol), float(options.atol)  # DOP853's meaning
                phases.arm(stats)
                status = _d.STATUS_OK if t >= t_end_s else _d.STATUS_RUNNING
                continue
            if status == _d.STATUS_STIFF:
                phases.on_stiff(y, t, i_out, stats)
                status = _d.STATUS_OK if t >= t_end_s else _d.STATUS_RUNNING
                continue
            if status == _d.STATUS_GUARD and phases.rolling_now:
                if phases.leave_rolling(y, t, i_out, stats):
                    status = _d.STATUS_OK if t >= t_end_s else _d.STATUS_RUNNING
                    continue
                break
            if status == _d.STATUS_GUARD and phases.can_switch():
                status_name = phases.on_guard(y, t, i_out, stats)
                if status_name:
                    break
                status = _d.STATUS_RUNNING
                continue
            break
        if progress is not None:
            progress(t)
        if status != _d.STATUS_RUNNING or status_name:
            break
    return _Stop(status, status_name, t, i_out, stats, rtol, atol, handed_over)


def _result(start: _Start, stop: _Stop, phases: _Phases, friction: FrictionParams,
            form_name: str, stiff_ran: str, wall: float, cpu: float) -> OdeResult:
    """The finished run; one that stopped early keeps the samples it reached and its end."""
    y, t_out, Y = start.y, start.t_out, start.Y
    t, i_out, stats, rtol, handed_over = stop.t, stop.i_out, stop.stats, stop.rtol, stop.handed_over
    status_name = stop.status_name or phases.status_name(phases.form, stop.status, y)
    if stop.status != _d.STATUS_OK or status_name != "ok":
        # keep the samples reached and add the final state at the stopping time
        t_out = np.append(t_out[:i_out], t)
        Y = np.vstack([Y[:i_out], y[None, :]])
    table = phases.table(friction, t_out, Y, t)
    t_inv = stats[_d.S_T_MARK]
    # the paper form's monitor is the signed sin theta: < 0 means the last step jumped across
    # theta = 0 (or pi), i.e. |sin theta| passed through 0
    min_sin = max(float(stats[_d.S_MONITOR_MIN]), 0.0)
    ran_method, ran_rtol = method_title(start.method.name, start.rtol), start.rtol
    return OdeResult(
        table=table,
        status=status_name,
        message=status_message(status_name, t, min_sin, form_name),
        t_final=float(t),
        t_invert=None if math.isnan(t_inv) else float(t_inv),
        n_rhs=int(stats[_d.S_NRHS]),
        n_steps=int(stats[_d.S_NSTEPS]),
        n_rejected=int(stats[_d.S_NREJECT]),
        wall_s=wall,
        cpu_s=cpu,
        min_sin_theta=min_sin,
        rtol=rtol,
        atol=stop.atol,
        states=Y,
        stiff_steps=int(stats[_d.S_NSTIFF]),
        h_lambda_max=float(stats[_d.S_HLAMBDA_MAX]),
        phases=phases.records,
        t_stem=phases.t_stem,
        impacts=phases.impacts,
        stiff=stiff_ran,
        rolling=phases.rolling,
        t_rolling_s=sum(r["t_end"] - r["t_start"] for r in phases.rolling),
        method=(ran_method if handed_over is None else
                f"{ran_method} at rtol {ran_rtol:g}, then dop853 at rtol {rtol:g} from t = "
                f"{handed_over:.6g} s (stiff for {ran_method}: rolling phases are DOP853's)"),
    )


def _hand_over(stats: np.ndarray) -> np.ndarray:
    """DOP853's ``stats`` from another method's: the shared counters kept, a fresh first step."""
    new = _d.new_stats()
    new[:] = stats[:_d.N_STATS]
    new[_d.S_H] = 0.0
    return new


def _stiff_mode(stiff: str, form: Formulation, friction: FrictionParams,
                stem: StemParams | None) -> str:
    """What runs for stiff friction (:attr:`OdeResult.stiff`)."""
    if stiff == "off":
        return "off"
    if friction.law not in ROLLING_LAWS:
        return (f"none (rolling phases follow the {' or '.join(ROLLING_LAWS)} law, not "
                f"{friction.law})")
    if form.singular:
        return "none (rolling phases need the vector formulation)"
    if stem is not None:
        return "none (rolling phases are on the ball alone; the scene has a stem)"
    return "rolling"


class _Phases:
    """The contact phases of a run: the ball alone, or the ball and the stem's end.

    A phase is on one point (``ball`` or ``stem``: :func:`vector_rhs` with that contact
    active, watching the other) or on both (``both``: :mod:`reference_ode.two_contact`).
    :attr:`form` and :attr:`p` are the current phase's; :meth:`on_guard` decides what a guard
    stop means and switches; :meth:`table` builds the observables phase by phase (each row
    computed with its own phase: N, the height, the energy and Jellett's constant are its
    contact's).
    """

    def __init__(self, top: TopParams, p: np.ndarray, stem: StemParams | None,
                 form: Formulation, y: np.ndarray) -> None:
        self.top = top
        self.base_p = p
        self.base_form = form
        self.records: list[dict] = []
        self.impacts: list[dict] = []
        self.t_stem: float | None = None
        self._bounds: list[int] = []  # the first row of each segment (a phase, or a rolling part)
        self._rec_bounds: list[int] = []  # the first row of each contact phase (:attr:`records`)
        self._phases: list[tuple[Formulation, np.ndarray]] = []
        self.rolling: list[dict] = []
        self.rolling_now = False
        self.compile_s = 0.0
        self.compile_cpu_s = 0.0
        self._arm = STIFF_ARM
        self._law: tuple[Formulation, np.ndarray] | None = None
        self.surfaces: tuple[Contact, ...] = (ball_contact(top),)
        self.active = 0
        self.both = False
        if stem is not None:
            ball, end = ball_contact(top), stem_contact(top, stem)
            self.surfaces = (ball, end)
            tol = GAP_TOL_R * top.R_m
            if gap(y, ball, end) < -tol:  # starting on the stem (the ball off the table)
                if gap(y, end, ball) < -tol:
                    raise TippetopError(
                        "init: expected a start with the ball or the stem's end on the table, "
                        f"got the stem's end {-1e3 * gap(y, ball, end):.3g} mm into it with "
                        "the ball on it")
                self.active = 1
        self._begin(0.0, 0, y)

    @property
    def name(self) -> str:
        """The current phase: ``ball``, ``stem`` or ``both``."""
        return "both" if self.both else self.surfaces[self.active].name

    def _begin(self, t: float, i_out: int, y: np.ndarray) -> None:
        active = self.surfaces[self.active]
        other = self.surfaces[1 - self.active] if len(self.surfaces) > 1 else None
        self.p = (self.base_p if other is None
                  else phase_params(self.base_p, active, other, self.top.R_m))
        if other is not None and not self.both:
            # the other point touches GAP_TOL below where it starts: a phase that begins
            # with it at the table (just struck, or lifted off) must not stop at once
            self.p[P_GAP_TOL] += max(0.0, -gap(y, active, other))
        self.form = TWO_CONTACT if self.both else self.base_form
        self._segment(i_out)
        self._rec_bounds.append(i_out)
        if self.records:
            self.records[-1]["t_end"] = t
        self.records.append({"contact": self.name, "t_start": t})
        if self.name != "ball" and self.t_stem is None:
            self.t_stem = t

    def arm(self, stats: np.ndarray) -> None:
        """Have the kernel stop after the next :attr:`_arm` steps flagged stiff."""
        stats[_d.S_STIFF_STOP] = stats[_d.S_NSTIFF] + self._arm

    def on_stiff(self, y: np.ndarray, t: float, i_out: int, stats: np.ndarray) -> None:
        """A stop on stiff steps: enter a rolling phase if the slip and the force allow it.

        Rolling starts where the slip is below Lambda (the law is then a steep viscous one)
        and the rolling force is below ``F_ENTER`` mu N (well inside the phase's exit at
        ``F_EXIT``). Otherwise the run goes on with the law, unchanged: the kernel resumes
        with its step size, and looks again after twice as many flagged steps.
        """
        q = rolling_params(self.p)
        if self.compile_s == 0.0:  # load (or compile) the rolling phase off the clock
            c0 = time.perf_counter()
            p0 = time.process_time()
            _d.dop853_run(ROLLING.rhs, ROLLING.watch, y.copy(), 0.0, 0.0, 1.0, q, 1e-9, 1e-12,
                          1, -math.inf, np.empty(0), np.empty((0, y.size)), 0, _d.new_stats())
            rolling_state(y, q)
            contact_slip(y, q)
            self.compile_s = time.perf_counter() - c0
            self.compile_cpu_s = time.process_time() - p0
        N, _, f0, _ = rolling_state(y, q)
        slip = contact_slip(y, self.p)
        scale = self.p[P_VEPS] if self.p[P_COULOMB_KIND] == COULOMB_EXACT else self.p[P_LAM]
        if N > 0.0 and slip < SLIP_ENTER * scale and f0 < F_ENTER:
            self._law = (self.form, self.p)
            self.form, self.p = ROLLING, q
            self.rolling_now = True
            self.rolling.append({"t_start": t})
            self._segment(i_out)
            stats[_d.S_STIFF_STOP] = math.inf
            stats[_d.S_H] = 0.0  # the rolling motion's steps are far longer: start afresh
            return
        self._arm = min(2 * self._arm, STIFF_ARM_MAX)
        self.arm(stats)

    def leave_rolling(self, y: np.ndarray, t: float, i_out: int, stats: np.ndarray) -> bool:
        """A guard stop in a rolling phase: back to the law (True), or contact lost (False)."""
        N, _, _, _ = rolling_state(y, self.p)
        if not N > 0.0:
            return False
        assert self._law is not None
        self.form, self.p = self._law
        self.rolling_now = False
        rec = self.rolling[-1]
        rec["t_end"] = t
        self._segment(i_out)
        stats[_d.S_H] = 0.0  # the law is stiff here: choose a new first step
        # a phase that rolled a while resets the detector's patience; a brief one does not
        self._arm = STIFF_ARM if t - rec["t_start"] > 0.01 else min(2 * self._arm,
                                                                    STIFF_ARM_MAX)
        self.arm(stats)
        return True

    def _segment(self, i_out: int) -> None:
        """Rows from ``i_out`` on are observed with the current formulation and parameters."""
        self._phases.append((self.form, self.p))
        self._bounds.append(i_out)

    def monitor_floor(self, base: float) -> float:
        """The run's monitor floor in this phase: a rim stops before lying face down."""
        rim = self.surfaces[self.active].rim or (self.both and any(c.rim for c in
                                                                   self.surfaces))
        return RIM_MIN_SIN if rim else base

    def can_switch(self) -> bool:
        """Whether there is a second surface (a guard stop may then be a switch)."""
        return len(self.surfaces) > 1

    def on_guard(self, y: np.ndarray, t: float, i_out: int, stats: np.ndarray) -> str:
        """What a guard stop at ``y`` means; switches the phase, or returns a status name.

        On one point, either the other point reached the table (an impact: on it alone, or
        on both) or the normal force fell to 0 (``contact_lost``). On both, the point whose
        force fell to 0 lifts (no impact: the top goes on on the other).
        """
        a, b = self.surfaces[self.active], self.surfaces[1 - self.active]
        if len(self.records) > MAX_SWITCHES:
            return "chatter"
        if self.both:
            N1, N2 = two_contact_forces(y, self.p)
            self.both = False
            if N1 <= N2:  # the active point lifts
                self.active = 1 - self.active
            self._restart(t, i_out, stats, y)
            return ""
        if gap(y, a, b) > -0.5 * GAP_TOL_R * self.top.R_m:
            if self.impacts and self.impacts[-1]["t"] == t:
                return "hop"  # the impact just now left the new point without a load
            return "contact_lost"
        imp = impact(y, self.top, a, b)
        if imp.both:
            y[:] = impact_both(y, self.top, a, b)
            self.both = True
        else:
            y[:] = imp.y
            lift = normal_velocity(y, b, a)
            if lift < ZENO_SPEED_MPS:
                trial = phase_params(self.base_p, b, a, self.top.R_m)
                if min(two_contact_forces(impact_both(y, self.top, b, a), trial)) > 0.0:
                    y[:] = impact_both(y, self.top, b, a)
                    self.both = True
        self.impacts.append({"t": t, "to": b.name, "impulse_Ns": float(imp.impulse_Ns),
                             "approach_mps": float(imp.approach_mps)})
        self.active = 1 - self.active  # the new point is the active one (also on both)
        self._restart(t, i_out, stats, y)
        return ""

    def _restart(self, t: float, i_out: int, stats: np.ndarray, y: np.ndarray) -> None:
        self._begin(t, i_out, y)
        stats[_d.S_H] = 0.0  # the motion changed abruptly: choose a new first step

    def status_name(self, form: Formulation, status: int, y: np.ndarray) -> str:
        """The run's status name (a rim's monitor stop is ``flat_end``)."""
        if status == _d.STATUS_MONITOR and not form.singular:
            return "flat_end"
        return kernel_status_name(form, status, y)

    def table(self, friction: FrictionParams, t: np.ndarray, Y: np.ndarray,
              t_final: float) -> pd.DataFrame:
        """The observables, each phase's rows with its own contact; closes :attr:`records`."""
        self.records[-1]["t_end"] = t_final
        if self.rolling and "t_end" not in self.rolling[-1]:
            self.rolling[-1]["t_end"] = t_final
        bounds = [*self._bounds, len(t)]
        parts = [_observables(form, friction, q, t[i0:i1], Y[i0:i1])
                 for (form, q), i0, i1 in zip(self._phases, bounds[:-1], bounds[1:],
                                              strict=True) if i1 > i0]
        table = pd.concat(parts, ignore_index=True) if len(parts) > 1 else parts[0]
        rec_bounds = [*self._rec_bounds, len(t)]
        for rec, i0, i1 in zip(self.records, rec_bounds[:-1], rec_bounds[1:], strict=True):
            J = table["J"].to_numpy()[i0:i1]
            conserved = rec["contact"] != "both" and not any(
                c.rim for c in self.surfaces if c.name == rec["contact"])
            rec["J_rel_drift"] = (float(np.max(np.abs(J - J[0])) / abs(J[0]))
                                  if conserved and len(J) and J[0] != 0 else None)
        return table


def scipy_rhs(top: TopParams, friction: FrictionParams,
              formulation: str = "vector") -> Callable[[float, np.ndarray], np.ndarray]:
    """The compiled right-hand side as a ``fun(t, y) -> dy`` for ``scipy.integrate.solve_ivp``.

    Every call runs the compiled, allocating right-hand side of the formulation (the one the
    reference integrator uses, friction law and parameters as :func:`pack_params`); it is
    compiled (or loaded) before this returns, so the first call costs no compilation.

    Args:
        top: The loaded sphere.
        friction: The sliding-friction law and its coefficients.
        formulation: ``vector`` (state of :func:`initial_state_vector`) or ``paper``
            (:func:`initial_state_paper`).

    Returns:
        ``fun(t, y)``, returning dy/dt as a new float64 array (t is ignored: autonomous).
    """
    expect(formulation in FORMULATIONS, "formulation", "|".join(FORMULATIONS), formulation)
    rhs_alloc = FORMULATIONS[formulation].rhs_alloc
    p = pack_params(top, friction)
    rhs_alloc(np.ones(FORMULATIONS[formulation].n_state), p)  # compile (or load) now

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        return rhs_alloc(y, p)

    return fun


def _observables(form: Formulation, friction: FrictionParams, p: np.ndarray, t: np.ndarray,
                 Y: np.ndarray) -> pd.DataFrame:
    """:func:`observables_table` for a :class:`Formulation` (a run's phase)."""
    if friction_law_codes(friction) != (p[P_COULOMB_KIND], p[P_VISCOUS]):
        raise ValueError(f"observables_table: p was packed for another friction law than "
                         f"{friction.law!r}")
    names = COLUMNS[1:] + EXTRA_COLUMNS
    out = np.empty((Y.shape[0], len(names)))
    form.observe_all(np.ascontiguousarray(Y), p, SIN_THETA_UNDEFINED, out)
    df = pd.DataFrame(out, columns=list(names))
    df.insert(0, "t", t)
    return df


def observables_table(formulation: str, friction: FrictionParams, p: np.ndarray,
                      t: np.ndarray, Y: np.ndarray) -> pd.DataFrame:
    """The observables table for sampled states ``Y`` (rows) at times ``t``.

    Args:
        formulation: ``vector`` or ``paper``, the layout of ``Y``'s rows.
        friction: The friction law; it must be the one packed in ``p`` (the compiled
            observables read the law from ``p``).
        p: The packed parameters (:func:`pack_params`).
        t: Sample times (s).
        Y: Sampled states, (len(t), state size).

    Returns:
        ``t`` then ``models.observables.COLUMNS[1:] + EXTRA_COLUMNS``, one row per sample.
    """
    return _observables(FORMULATIONS[formulation], friction, p, t, Y)
