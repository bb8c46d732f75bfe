"""Other integrators on the reference's compiled right-hand side (``tippetop bench ode``).

The peers a user would pick for a compiled ODE: numbalsoda's DOP853 (Hairer's C code) and
LSODA (ODEPACK, Fortran), driven by a numba ``cfunc`` that calls the SAME compiled right-hand
side as the reference kernel (:func:`reference_ode.top.vector_rhs`, the vector formulation)
and counts its evaluations (:data:`COUNTER_SLOT`). numbalsoda is an optional extra
(``pip install -e '.[peers]'``; it builds with gfortran): without it
:func:`numbalsoda_missing` says so and nothing here runs. numba compiles the ``cfunc`` on the
first call of :func:`run_numbalsoda` (and caches it on disk).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numba as nb
import numpy as np

from tippetop.reference_ode import dop853 as _d
from tippetop.reference_ode.params_array import N_PARAMS
from tippetop.reference_ode.top import FORMULATIONS, vector_rhs
from tippetop.reference_ode.vector import N_STATE

#: The peers, by the names the benchmark reports.
NUMBALSODA_METHODS = {"numbalsoda DOP853": "dop853", "numbalsoda LSODA": "lsoda"}
#: What to say when numbalsoda cannot be imported.
NUMBALSODA_MISSING = "numbalsoda is not installed: pip install -e '.[peers]' (needs gfortran)"
#: Slot of the data array that counts the right-hand-side evaluations (after the parameters).
COUNTER_SLOT = N_PARAMS

_DOUBLE_P = nb.types.CPointer(nb.types.float64)
#: numbalsoda's right-hand-side signature (``numbalsoda.lsoda_sig``; its DOP853 uses the same):
#: ``f(t, u, du, data)``.
PEER_RHS_SIG = nb.types.void(nb.types.float64, _DOUBLE_P, _DOUBLE_P, _DOUBLE_P)

_cfunc = None


def numbalsoda_missing() -> str | None:
    """None if numbalsoda can be imported, else the reason (one line)."""
    try:
        import numbalsoda  # noqa: F401
    except ImportError:
        return NUMBALSODA_MISSING
    return None


def _vector_rhs_cfunc():
    """The vector formulation's right-hand side as numbalsoda's ``cfunc`` (compiled once)."""
    global _cfunc
    if _cfunc is None:

        @nb.cfunc(PEER_RHS_SIG, cache=True, error_model="numpy")
        def vector_rhs_counted(t, u, du, data):  # pragma: no cover - runs compiled
            y = nb.carray(u, N_STATE)
            dy = nb.carray(du, N_STATE)
            p = nb.carray(data, N_PARAMS)
            counter = nb.carray(data, N_PARAMS + 1)
            counter[COUNTER_SLOT] += 1.0
            vector_rhs(y, p, dy)

        _cfunc = vector_rhs_counted
    return _cfunc


@dataclass(frozen=True)
class PeerRun:
    """One peer run from t = 0 to t_end.

    Attributes:
        y_final: The state at t_end (vector formulation).
        n_rhs: Right-hand-side evaluations (counted in the cfunc).
        s: CPU time of the solver call (s).
        success: What the solver reported.
    """

    y_final: np.ndarray
    n_rhs: int
    s: float
    success: bool


def numbalsoda_solve(name: str, y0: np.ndarray, p: np.ndarray, t_eval: np.ndarray,
                     rtol: float, atol: float, max_steps: int = 10**8
                     ) -> tuple[np.ndarray, int, float, bool]:
    """Integrate the vector formulation with a numbalsoda method, sampled at ``t_eval``.

    Args:
        name: ``numbalsoda DOP853`` or ``numbalsoda LSODA`` (:data:`NUMBALSODA_METHODS`).
        y0: The vector formulation's initial state, (11,).
        p: The packed parameters (:func:`params_array.pack_params`).
        t_eval: Increasing sample times (s), the first the start.
        rtol: Relative tolerance.
        atol: Absolute tolerance.
        max_steps: The solver's step limit (``mxstep``).

    Returns:
        The states at ``t_eval`` (rows), the evaluations, the CPU time of the solve (s) and
        numbalsoda's success flag. The first call also compiles the cfunc (call once to warm
        up before timing).
    """
    import numbalsoda

    solver = getattr(numbalsoda, NUMBALSODA_METHODS[name])
    data = np.zeros(N_PARAMS + 1)
    data[:N_PARAMS] = p
    u0 = np.ascontiguousarray(y0, dtype=np.float64).copy()
    address = _vector_rhs_cfunc().address
    t_eval = np.ascontiguousarray(t_eval, dtype=np.float64)
    t0 = time.process_time()
    usol, success = solver(address, u0, t_eval, data, rtol, atol, max_steps)
    s = time.process_time() - t0
    return np.asarray(usol), int(data[COUNTER_SLOT]), s, bool(success)


def run_numbalsoda(name: str, y0: np.ndarray, p: np.ndarray, t_end_s: float, rtol: float,
                   atol: float, max_steps: int = 10**8) -> PeerRun:
    """Integrate the vector formulation with a numbalsoda method, on the reference's RHS.

    Args:
        name: ``numbalsoda DOP853`` or ``numbalsoda LSODA`` (:data:`NUMBALSODA_METHODS`).
        y0: The vector formulation's initial state, (11,).
        p: The packed parameters (:func:`params_array.pack_params`).
        t_end_s: Simulated time (s).
        rtol: Relative tolerance.
        atol: Absolute tolerance.
        max_steps: The solver's step limit (``mxstep``).

    Returns:
        The run; the first call also compiles numbalsoda's driver and the cfunc (call once to
        warm up before timing).
    """
    usol, n_rhs, s, success = numbalsoda_solve(name, y0, p, np.array([0.0, float(t_end_s)]),
                                               rtol, atol, max_steps)
    return PeerRun(y_final=np.array(usol[-1]), n_rhs=n_rhs, s=s, success=success)


def run_reference_kernel(y0: np.ndarray, p: np.ndarray, t_end_s: float, rtol: float,
                         atol: float, max_steps: int = 10**8, method: str = "dop853") -> PeerRun:
    """One of the reference's kernels called as the peers are: one call, t = 0 to t_end.

    The ``method``'s kernel (:mod:`reference_ode.methods`; :func:`dop853.dop853_run` by
    default) with the vector formulation's compiled right-hand side and watch (as
    :func:`solve.simulate_ode` calls it, without building the observables table), at the
    tolerances given, the state sampled at t_end only. The first call in a process loads (or
    compiles) the kernel: call once to warm up before timing.
    """
    from tippetop.reference_ode.methods import METHODS

    kernel = METHODS[method]
    form = FORMULATIONS["vector"]
    y = np.ascontiguousarray(y0, dtype=np.float64).copy()
    t_out = np.array([float(t_end_s)])
    Y = np.full((1, y.size), np.nan)
    stats = kernel.new_stats(y.size)
    run = kernel.run
    t0 = time.process_time()
    status, _, _ = run(form.rhs, form.watch, y, 0.0, float(t_end_s), float(t_end_s), p,
                       float(rtol), float(atol), int(max_steps), -np.inf, t_out, Y, 0, stats)
    s = time.process_time() - t0
    return PeerRun(y_final=Y[-1].copy(), n_rhs=int(stats[_d.S_NRHS]), s=s,
                   success=status == _d.STATUS_OK)
