"""Run the reference ODE: assemble the compiled pieces, integrate, build the observables table."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numba as nb
import numpy as np
import pandas as pd

from tippetop.models.errors import TippetopError, expect
from tippetop.models.frames import initial_rigid_state
from tippetop.models.observables import COLUMNS, EXTRA_COLUMNS, SIN_THETA_UNDEFINED
from tippetop.models.options import FORMULATIONS as _FORMULATION_NAMES
from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode import dop853 as _d
from tippetop.reference_ode import paper as _paper
from tippetop.reference_ode import vector as _vector
from tippetop.reference_ode.friction import LAW_TERMS
from tippetop.reference_ode.params_array import pack_params

FORMULATIONS = dict(zip(_FORMULATION_NAMES, (_d.FORM_VECTOR, _d.FORM_PAPER), strict=True))

#: Rows of the observables table when the caller gives no sample interval.
DEFAULT_MAX_SAMPLES = 20_000
#: Finest default sample interval (s).
DEFAULT_SAMPLE_DT_S = 1e-3
#: The run is integrated in this many pieces so that a progress bar can advance.
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
        min_sin_theta: Smallest |sin theta| seen at a step end.
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


@nb.njit(cache=True)
def _observe_all(form, coulomb_kind, viscous, Y, p, sin_undefined, out):
    scratch = np.empty(Y.shape[1])
    for i in range(Y.shape[0]):
        if form == _d.FORM_VECTOR:
            _vector.vector_observe(coulomb_kind, viscous, Y[i], p, sin_undefined, out[i],
                                   scratch)
        else:
            _paper.paper_observe(coulomb_kind, viscous, Y[i], p, sin_undefined, out[i],
                                 scratch)


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
    ck, visc = LAW_TERMS[friction.law]
    visc = int(visc)
    p = pack_params(top, friction, options.singular_sin)
    if form == _d.FORM_VECTOR:
        y = initial_state_vector(top, init)
    else:
        if abs(math.sin(init.theta0)) < options.singular_sin:
            raise TippetopError(
                f"init.theta0: expected |sin theta0| >= {options.singular_sin:g} for the paper "
                f"formulation (it is singular at theta = 0 and pi), got {init.theta0!r}; use "
                "ode.formulation=vector")
        y = initial_state_paper(top, init)
    dy0 = np.empty_like(y)
    N0 = _d.rhs(form, ck, visc, y, p, dy0)
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
    stats = np.zeros(_d.N_STATS)
    stats[_d.S_T_INVERT] = np.nan
    stats[_d.S_MIN_SIN] = np.inf
    t = 0.0
    i_out = 0
    # load (or compile) the integrator before the clock starts: a call that takes no step
    _d.dop853_run(form, ck, visc, y.copy(), 0.0, 0.0, t_end_s, p, float(options.rtol),
                  float(options.atol), 1, t_out[:0], Y[:0], 0, stats.copy())
    wall0 = time.perf_counter()
    status = _d.STATUS_RUNNING
    for k in range(1, N_CHUNKS + 1):
        t_stop = t_end_s if k == N_CHUNKS else t_end_s * k / N_CHUNKS
        if t >= t_stop:
            continue
        status, t, i_out = _d.dop853_run(form, ck, visc, y, t, float(t_stop), t_end_s, p,
                                         float(options.rtol), float(options.atol),
                                         int(options.max_steps),
                                         t_out, Y, i_out, stats)
        if progress is not None:
            progress(t)
        if status != _d.STATUS_RUNNING:
            break
    wall = time.perf_counter() - wall0
    status_name = _d.STATUS_NAMES[status]
    if status != _d.STATUS_OK:
        # keep the samples reached and add the final state at the stopping time
        t_out = np.append(t_out[:i_out], t)
        Y = np.vstack([Y[:i_out], y[None, :]])
    table = observables_table(form_name, friction, p, t_out, Y)
    t_inv = stats[_d.S_T_INVERT]
    return OdeResult(
        table=table,
        status=status_name,
        message=_message(status_name, t, stats[_d.S_MIN_SIN], form_name),
        t_final=float(t),
        t_invert=None if math.isnan(t_inv) else float(t_inv),
        n_rhs=int(stats[_d.S_NRHS]),
        n_steps=int(stats[_d.S_NSTEPS]),
        n_rejected=int(stats[_d.S_NREJECT]),
        wall_s=wall,
        min_sin_theta=float(stats[_d.S_MIN_SIN]),
        rtol=options.rtol,
        states=Y,
        stiff_steps=int(stats[_d.S_NSTIFF]),
        h_lambda_max=float(stats[_d.S_HLAMBDA_MAX]),
    )


def observables_table(formulation: str, friction: FrictionParams, p: np.ndarray,
                      t: np.ndarray, Y: np.ndarray) -> pd.DataFrame:
    """The observables table for sampled states ``Y`` (rows) at times ``t``."""
    ck, visc = LAW_TERMS[friction.law]
    names = COLUMNS[1:] + EXTRA_COLUMNS
    out = np.empty((Y.shape[0], len(names)))
    _observe_all(FORMULATIONS[formulation], ck, int(visc), np.ascontiguousarray(Y), p,
                 SIN_THETA_UNDEFINED, out)
    df = pd.DataFrame(out, columns=list(names))
    df.insert(0, "t", t)
    return df
