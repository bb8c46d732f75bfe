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
from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode import dop853 as _d
from tippetop.reference_ode.params_array import (
    P_COULOMB_KIND,
    P_SING,
    P_VISCOUS,
    friction_law_codes,
    pack_params,
)
from tippetop.reference_ode.top import FORMULATIONS, Formulation

assert tuple(FORMULATIONS) == _FORMULATION_NAMES

#: The kernel's statuses under the tippe top's names: the guard is the normal force (contact
#: lost), the monitor the paper formulation's sin theta (its singularity).
STATUS_NAMES = {
    _d.STATUS_OK: "ok",
    _d.STATUS_GUARD: "contact_lost",
    _d.STATUS_MONITOR: "singular",
    _d.STATUS_MAX_STEPS: "max_steps",
    _d.STATUS_STEP_TOO_SMALL: "step_too_small",
}
#: A step-size underflow of the paper formulation with |sin theta| below this is reported as
#: its singularity (``singular``), not as ``step_too_small``.
SINGULAR_UNDERFLOW_SIN = 1e-3

#: Rows of the observables table when the caller gives no sample interval.
DEFAULT_MAX_SAMPLES = 20_000
#: Finest default sample interval (s).
DEFAULT_SAMPLE_DT_S = 1e-3
#: With a progress callback the run is integrated in this many pieces so that a progress bar
#: can advance (each piece costs ~0.1 ms of Python: the kernel's function arguments are
#: unboxed per call); without one, in one piece. The steps are the same either way.
N_CHUNKS = 50


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
        min_sin_theta: Smallest |sin theta| seen at a step end (0 when a paper-formulation
            step ended with theta outside (0, pi): it passed through the singularity).
        states: The sampled raw states, shape (samples, state size).
        stiff_steps: Accepted steps whose stiffness estimate h lambda exceeded 6.1 (Hairer's
            DOP853 test, see :mod:`reference_ode.dop853`): steps limited by stability, not by
            accuracy. A large share means the problem is stiff for an explicit method.
        h_lambda_max: The largest h lambda estimate of an accepted step.
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


def _message(status: str, t: float, min_sin: float, form: str) -> str:
    if status == "ok":
        return "completed"
    if status == "contact_lost":
        return (f"contact lost at t = {t:.6g} s (the normal force reached 0): the model assumes "
                "the sphere stays on the table, so the run stopped there")
    if status == "singular":
        return (f"the paper formulation reached its singularity at theta = 0 or pi "
                f"(|sin theta| = {min_sin:.2e}) at t = {t:.6g} s; use ode.formulation=vector")
    if status == "max_steps":
        return f"stopped at t = {t:.6g} s after the maximum number of steps (ode.max_steps)"
    return (f"step size underflow at t = {t:.6g} s ({form} formulation): the problem is too "
            "stiff or singular for this tolerance")


def simulate_ode(
    top: TopParams,
    friction: FrictionParams,
    init: InitialState,
    *,
    t_end_s: float,
    sample_dt_s: float | None = None,
    options: OdeOptions | None = None,
    progress: Callable[[float], None] | None = None,
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

    Returns:
        The run, with its observables table sampled on the dense output.
    """
    options = options or OdeOptions()
    expect(math.isfinite(t_end_s) and t_end_s > 0, "run.t_end_s", "a finite number > 0",
           t_end_s)
    t_end_s = float(t_end_s)  # one compiled signature: every scalar crosses as float64
    form_name = options.formulation
    form = FORMULATIONS[form_name]
    p = pack_params(top, friction, options.singular_sin)
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
    row0 = observables_table(form_name, friction, p, np.zeros(1), y[None, :]).iloc[0]
    if not (np.all(np.isfinite(dy0)) and math.isfinite(N0) and math.isfinite(row0["E"])
            and math.isfinite(row0["J"])):
        raise TippetopError(
            "init: expected a start whose energy and accelerations are finite, got overflow at "
            f"t = 0 (n0 = {init.n0!r}, theta_dot0 = {init.thetadot0!r}, "
            f"uOX = {init.uOX!r}, uOY = {init.uOY!r}, mu = {friction.mu!r}, "
            f"g = {top.g_mps2!r}): the values are too large for double precision")
    t_out = sample_times(t_end_s, sample_dt_s)
    Y = np.full((t_out.size, y.size), np.nan)
    stats = _d.new_stats()
    t = 0.0
    i_out = 0
    rtol = float(options.rtol)
    atol = float(options.atol)
    max_steps = int(options.max_steps)
    # load (or compile) the integrator before the clock starts: a call that takes no step
    _d.dop853_run(form.rhs, form.watch, y.copy(), 0.0, 0.0, t_end_s, p, rtol, atol, 1,
                  monitor_floor, t_out[:0], Y[:0], 0, stats.copy())
    wall0 = time.perf_counter()
    status = _d.STATUS_RUNNING
    n_chunks = N_CHUNKS if progress is not None else 1
    for k in range(1, n_chunks + 1):
        t_stop = t_end_s if k == n_chunks else t_end_s * k / n_chunks
        if t >= t_stop:
            continue
        status, t, i_out = _d.dop853_run(form.rhs, form.watch, y, t, float(t_stop), t_end_s, p,
                                         rtol, atol, max_steps, monitor_floor, t_out, Y, i_out,
                                         stats)
        if progress is not None:
            progress(t)
        if status != _d.STATUS_RUNNING:
            break
    wall = time.perf_counter() - wall0
    status_name = _status_name(form, status, y)
    if status != _d.STATUS_OK:
        # keep the samples reached and add the final state at the stopping time
        t_out = np.append(t_out[:i_out], t)
        Y = np.vstack([Y[:i_out], y[None, :]])
    table = observables_table(form_name, friction, p, t_out, Y)
    t_inv = stats[_d.S_T_MARK]
    # the paper form's monitor is the signed sin theta: < 0 means the last step jumped across
    # theta = 0 (or pi), i.e. |sin theta| passed through 0
    min_sin = max(float(stats[_d.S_MONITOR_MIN]), 0.0)
    return OdeResult(
        table=table,
        status=status_name,
        message=_message(status_name, t, min_sin, form_name),
        t_final=float(t),
        t_invert=None if math.isnan(t_inv) else float(t_inv),
        n_rhs=int(stats[_d.S_NRHS]),
        n_steps=int(stats[_d.S_NSTEPS]),
        n_rejected=int(stats[_d.S_NREJECT]),
        wall_s=wall,
        min_sin_theta=min_sin,
        rtol=options.rtol,
        states=Y,
        stiff_steps=int(stats[_d.S_NSTIFF]),
        h_lambda_max=float(stats[_d.S_HLAMBDA_MAX]),
    )


def _status_name(form: Formulation, status: int, y: np.ndarray) -> str:
    """The tippe top's name of a kernel status; ``y`` is the state where the run stopped."""
    if (status == _d.STATUS_STEP_TOO_SMALL and form.singular
            and abs(math.sin(y[0])) < SINGULAR_UNDERFLOW_SIN):
        return "singular"
    return STATUS_NAMES[status]


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
    if friction_law_codes(friction) != (p[P_COULOMB_KIND], p[P_VISCOUS]):
        raise ValueError(f"observables_table: p was packed for another friction law than "
                         f"{friction.law!r}")
    names = COLUMNS[1:] + EXTRA_COLUMNS
    out = np.empty((Y.shape[0], len(names)))
    FORMULATIONS[formulation].observe_all(np.ascontiguousarray(Y), p, SIN_THETA_UNDEFINED, out)
    df = pd.DataFrame(out, columns=list(names))
    df.insert(0, "t", t)
    return df
