"""The work-precision benchmark's peers: other solvers on the reference's compiled right-hand side.

Compiled drivers (:mod:`reference_ode.peers`): numbalsoda's DOP853 (Hairer's code) and LSODA
(ODEPACK). Python drivers calling the compiled right-hand side through a Python wrapper
(:func:`reference_ode.solve.scipy_rhs`): scipy's ``solve_ivp`` DOP853, Radau and LSODA, and
SUNDIALS' CVODE (Adams and BDF) through scikit-sundae when it is installed
(the ``peers`` extra). heyoka's Taylor method (:class:`HeyokaPeer`; its own
right-hand side in heyoka's expressions, :mod:`reference_ode.taylor_peer`). The Python
drivers are ``slow``: fewer tolerances, fewer rounds, a CPU budget per point and a hard
wall-time limit.

The inversion time of a peer (which has no events here) is found from its solution: the run's
own steps (scipy, CVODE) or a coarse grid of :data:`COARSE_SAMPLES` samples (numbalsoda)
bracket the first crossing of theta = pi/2; a second run samples the bracket at
:data:`FINE_SAMPLES` points and a cubic spline through them locates the root. For the
explicit Runge-Kutta methods (DOP853s) the samples are read from the dense output and do not
change the steps, so the time found is the timed run's. numbalsoda's LSODA does change its
steps with the samples (fig3, rtol 1e-6: 13,218 evaluations with 2001 samples, 12,168 with
201, 11,076 with 21, measured): its inversion time is that of a run at the same tolerance,
not exactly of the timed one. The location error is estimated as the
difference from the root found with half the samples (the spline's error falls as h^4: the
estimate bounds the finer one's by far).
"""

from __future__ import annotations

import ctypes
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from tippetop.compare.studies.accuracy.common import ATOL_PER_RTOL, HARD_LIMIT_FACTOR, OverBudget
from tippetop.reference_ode.peers import NUMBALSODA_METHODS, numbalsoda_missing, numbalsoda_solve
from tippetop.reference_ode.solve import observables_table, scipy_rhs

#: Samples of the coarse grid that brackets the inversion (numbalsoda).
COARSE_SAMPLES = 2001
#: Samples of the bracket for the spline (and half of them for its error estimate).
FINE_SAMPLES = 201
#: A slow peer's CPU budget per point (s): its sweep stops after a point over it.
SLOW_BUDGET_S = 2.0


@dataclass(frozen=True)
class PeerPoint:
    """One run of a solver at one tolerance.

    Attributes:
        s: CPU time of the solve (s).
        n_rhs: Right-hand-side evaluations.
        theta: theta(t_end) (rad), NaN if it failed.
        t_invert: First time theta passed pi/2 (s), or None (not found / not asked).
        J_drift: |J(t_end) / J(0) - 1|.
        status: ``ok`` or why not.
        method: The method that ran (the reference's, ``auto`` resolved).
        locate_err: Estimated error of locating ``t_invert`` from samples (s), or None.
        printed: Lines the solver's compiled code printed during the timed run (Hairer's
            DOP853: "the problem seems to become stiff"), kept off the terminal.
    """

    s: float
    n_rhs: int
    theta: float
    t_invert: float | None
    J_drift: float
    status: str
    method: str = ""
    locate_err: float | None = None
    printed: int = 0


def theta_of_states(Y: np.ndarray) -> np.ndarray:
    """Theta (rad) of vector-formulation states (rows)."""
    Y = np.atleast_2d(Y)
    q = Y[:, 4:8] / np.linalg.norm(Y[:, 4:8], axis=1)[:, None]
    qw, qx, qy, qz = q.T
    kz = qw * qw - qx * qx - qy * qy + qz * qz
    s = np.hypot(2 * (qx * qz + qw * qy), 2 * (qy * qz - qw * qx))
    return np.arctan2(s, kz)


def jellett_drift(top: Any, y_end: np.ndarray) -> float:
    """|J(t_end) / J(0) - 1| of a vector-formulation state at t_end (``top``: a ``Top``)."""
    tab = observables_table("vector", top.friction, top.p, np.array([0.0, top.t_end_s]),
                            np.vstack([top.y0, y_end]))
    J = tab["J"].to_numpy()
    return float(abs(J[1] / J[0] - 1.0))


def locate_crossing(t: np.ndarray, Y: np.ndarray,
                    solve: Callable[[np.ndarray], np.ndarray]) -> tuple[float | None,
                                                                         float | None]:
    """The first time theta reaches pi/2, and the estimated error of locating it.

    Args:
        t: Times of states ``Y`` (a grid or the solver's steps) that bracket the crossing.
        Y: The states there (rows).
        solve: ``solve(times) -> states`` at those times, from the same solver and tolerance.
    """
    th = np.nan_to_num(theta_of_states(Y), nan=-1.0)
    above = np.nonzero(th >= 0.5 * math.pi)[0]
    if above.size == 0 or above[0] == 0:
        return None, None
    a, b = float(t[above[0] - 1]), float(t[above[0]])
    tt = np.linspace(a, b, FINE_SAMPLES)
    f = theta_of_states(solve(tt)) - 0.5 * math.pi
    if not np.isfinite(f).all():  # the solver failed on the second run: not located
        return None, None
    roots = []
    for step in (1, 2):  # every sample, and every other one (for the error estimate)
        r = [x for x in CubicSpline(tt[::step], f[::step]).roots(extrapolate=False)
             if a <= x <= b]
        if not r:
            return None, None
        roots.append(float(r[0]))
    return roots[0], abs(roots[0] - roots[1])


class Peer:
    """A solver other than the reference's, run on the same compiled right-hand side."""

    slow = False
    budget_s: float | None = None

    def __init__(self, name: str) -> None:
        self.name = name

    def missing(self) -> str | None:
        """None if the solver can run here, else why not."""
        return None

    def tolerances(self, tols: Sequence[float]) -> Sequence[float]:
        """The sweep's tolerances this peer runs."""
        return tols[::2] if self.slow else tols

    def warm(self, top: Any) -> None:
        """Compile or load everything before timing."""
        self.run(top, 1e-3, locate_invert=False, t_end_s=min(top.t_end_s, 0.01))

    def solve(self, top: Any, rtol: float, t_eval: np.ndarray | None, t_end_s: float
              ) -> tuple[np.ndarray, np.ndarray, int, float, str]:
        """(times, states, n_rhs, CPU s, status); ``t_eval`` None: the steps or the end."""
        raise NotImplementedError

    def run(self, top: Any, rtol: float, *, locate_invert: bool,
            t_end_s: float | None = None) -> PeerPoint:
        """One timed run to t_end; with ``locate_invert``, the inversion time too (untimed).

        What the solver's compiled code prints is kept off the terminal (:func:`_captured_stdout`)
        and the timed run's lines are counted (``printed``).
        """
        T = top.t_end_s if t_end_s is None else t_end_s
        with _captured_stdout() as said:  # Hairer's DOP853: "the problem seems to become stiff"
            t, Y, n, s, status = self.solve(top, rtol, None, T)
        printed = len(said)
        if status != "ok" or not np.isfinite(Y[-1]).all() or abs(t[-1] - T) > 1e-9 * T:
            return PeerPoint(s=s, n_rhs=n, theta=math.nan, t_invert=None, J_drift=math.nan,
                             status=status if status != "ok" else "did not reach t_end",
                             printed=printed)
        t_inv = err = None
        y_end = Y[-1].copy()
        if locate_invert:
            with _captured_stdout():  # the untimed runs that locate the crossing, uncounted
                if t.size < 3:
                    t = np.linspace(0.0, T, COARSE_SAMPLES)[1:]  # solve() adds the start
                    Y = self.solve(top, rtol, t, T)[1]
                t_inv, err = locate_crossing(t, Y, lambda tt: self.solve(top, rtol, tt, T)[1])
        return PeerPoint(s=s, n_rhs=n, theta=float(theta_of_states(y_end)[0]), t_invert=t_inv,
                         J_drift=jellett_drift(top, y_end), status="ok", method=self.name,
                         locate_err=err, printed=printed)


@cache
def _gfortran() -> Any:
    """The gfortran runtime numbalsoda's DOP853 and LSODA are linked to, or None."""
    try:
        return ctypes.CDLL("libgfortran.so.5")
    except OSError:
        return None


def _flush_fortran() -> None:
    """Flush every gfortran unit: its writes to a file are buffered apart from C's."""
    lib = _gfortran()
    if lib is not None:
        lib._gfortran_flush_i4(None)  # FLUSH with no unit: all of them


@contextmanager
def _captured_stdout() -> Iterator[list[str]]:
    """What compiled code prints on file descriptor 1, kept off it.

    The list holds its lines after the block: --json's stdout stays clean, and a terminal is
    not filled with them.
    """
    sys.stdout.flush()
    saved = os.dup(1)
    lines: list[str] = []
    with tempfile.TemporaryFile() as sink:
        try:
            os.dup2(sink.fileno(), 1)
            yield lines
        finally:
            ctypes.CDLL(None).fflush(None)  # C's buffered stdout, while it still goes there
            _flush_fortran()  # and gfortran's own buffer (unit 6), which C's fflush misses
            os.dup2(saved, 1)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read().decode(errors="replace").splitlines())


class NumbalsodaPeer(Peer):
    """numbalsoda's DOP853 or LSODA (compiled; :mod:`reference_ode.peers`)."""

    def missing(self) -> str | None:
        """See :meth:`Peer.missing`."""
        return numbalsoda_missing()

    def solve(self, top, rtol, t_eval, t_end_s):
        """See :meth:`Peer.solve`."""
        te = np.array([0.0, t_end_s]) if t_eval is None else np.concatenate([[0.0], t_eval])
        Y, n, s, ok = numbalsoda_solve(self.name, top.y0, top.p, te, rtol, ATOL_PER_RTOL * rtol)
        if not ok:  # what numbalsoda leaves in the unreached rows is not a state
            Y = np.full_like(Y, np.nan)
        if t_eval is not None:
            return te[1:], Y[1:], n, s, "ok" if ok else "failed"
        return te, Y, n, s, "ok" if ok else "numbalsoda reported failure"


class _Limited:
    """The compiled right-hand side behind a hard wall-time limit, counting its calls."""

    def __init__(self, top: Any, limit_s: float) -> None:
        self.f = scipy_rhs(top.top, top.friction, "vector")
        self.limit_s = limit_s
        self.n = 0
        self.t0 = time.perf_counter()

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        self.n += 1
        if self.n % 1000 == 0 and time.perf_counter() - self.t0 > self.limit_s:
            raise OverBudget
        return self.f(t, y)


class ScipyPeer(Peer):
    """``scipy.integrate.solve_ivp`` with one of its methods (Python step loop)."""

    slow = True
    budget_s = SLOW_BUDGET_S

    def __init__(self, name: str, method: str) -> None:
        super().__init__(name)
        self.method = method

    def solve(self, top, rtol, t_eval, t_end_s):
        """See :meth:`Peer.solve`."""
        from scipy.integrate import solve_ivp

        fun = _Limited(top, HARD_LIMIT_FACTOR * self.budget_s)
        t0 = time.process_time()
        try:
            with np.errstate(over="ignore", invalid="ignore"):  # Radau's num_jac, see ode_study
                sol = solve_ivp(fun, (0.0, t_end_s), top.y0, method=self.method, rtol=rtol,
                                atol=ATOL_PER_RTOL * rtol, t_eval=t_eval)
        except OverBudget:
            s = time.process_time() - t0
            return (np.zeros(1), np.full((1, 11), np.nan), fun.n, s,
                    f"stopped over the hard limit ({fun.limit_s:g} s)")
        s = time.process_time() - t0
        return sol.t, np.ascontiguousarray(sol.y.T), int(sol.nfev), s, \
            "ok" if sol.status == 0 else f"failed: {sol.message}"


class CvodePeer(Peer):
    """SUNDIALS CVODE (Adams or BDF) through scikit-sundae (Python callback)."""

    slow = True
    budget_s = SLOW_BUDGET_S

    def __init__(self, name: str, method: str) -> None:
        super().__init__(name)
        self.method = method

    def missing(self) -> str | None:
        """See :meth:`Peer.missing`."""
        try:
            import sksundae  # noqa: F401
        except ImportError:
            return "scikit-sundae is not installed: pip install scikit-sundae"
        return None

    def solve(self, top, rtol, t_eval, t_end_s):
        """See :meth:`Peer.solve`."""
        from sksundae.cvode import CVODE

        f = _Limited(top, HARD_LIMIT_FACTOR * self.budget_s)
        over = [False]

        def rhs(t: float, y: np.ndarray, yp: np.ndarray) -> None:
            try:
                yp[:] = f(t, y)
            except OverBudget:
                over[0] = True
                yp[:] = np.nan

        solver = CVODE(rhs, method=self.method, rtol=rtol, atol=ATOL_PER_RTOL * rtol,
                       max_num_steps=10**8)
        te = np.array([0.0, t_end_s]) if t_eval is None else np.concatenate([[0.0], t_eval])
        t0 = time.process_time()
        sol = solver.solve(te, np.array(top.y0))
        s = time.process_time() - t0
        status = "ok" if sol.success else f"failed: {sol.message}"
        if over[0]:
            status = f"stopped over the hard limit ({f.limit_s:g} s)"
        t, Y = np.asarray(sol.t), np.asarray(sol.y)
        if t_eval is not None:
            t, Y = t[1:], Y[1:]
        return t, Y, int(sol.nfev), s, status


class HeyokaPeer(Peer):
    """heyoka's adaptive Taylor method (:mod:`reference_ode.taylor_peer`), compiled by LLVM.

    Its right-hand side is the vector formulation written in heyoka's expressions (checked
    against the compiled one there), its tolerance one number: ``tol = rtol``. One integrator
    is compiled per top and tolerance (off the clock); the inversion time comes from a second
    integrator with heyoka's event on k_z (untimed: the timed run has no event).
    """

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._cache: dict[tuple, Any] = {}

    def missing(self) -> str | None:
        """See :meth:`Peer.missing`."""
        from tippetop.reference_ode.taylor_peer import heyoka_missing

        return heyoka_missing()

    def _integrator(self, top: Any, rtol: float, events: bool) -> Any:
        from tippetop.reference_ode.taylor_peer import TaylorPeer

        key = (top.name, top.t_end_s, rtol, events)
        if key not in self._cache:
            self._cache[key] = TaylorPeer(top.p, rtol, events=events)
        return self._cache[key]

    def warm(self, top: Any) -> None:
        """Nothing: each tolerance compiles its own integrator on first use (off the clock)."""

    def run(self, top: Any, rtol: float, *, locate_invert: bool,
            t_end_s: float | None = None) -> PeerPoint:
        """One timed run to t_end; with ``locate_invert``, heyoka's event in a second run."""
        from tippetop.reference_ode.taylor_peer import unsupported

        why = unsupported(top.p)
        if why:
            return PeerPoint(s=math.nan, n_rhs=0, theta=math.nan, t_invert=None,
                             J_drift=math.nan, status=f"not supported: {why}")
        T = top.t_end_s if t_end_s is None else t_end_s
        run = self._integrator(top, rtol, False).run(top.y0, T)
        if not run.success or not np.isfinite(run.y_final).all():
            return PeerPoint(s=run.s, n_rhs=run.n_rhs, theta=math.nan, t_invert=None,
                             J_drift=math.nan, status="heyoka did not reach t_end")
        t_inv = None
        if locate_invert:
            ev = self._integrator(top, rtol, True)
            ev.run(top.y0, T)
            t_inv = None if math.isnan(ev.t_invert) else ev.t_invert
        return PeerPoint(s=run.s, n_rhs=run.n_rhs, theta=float(theta_of_states(run.y_final)[0]),
                         t_invert=t_inv, J_drift=jellett_drift(top, run.y_final), status="ok",
                         method=self.name, locate_err=0.0 if t_inv is not None else None)


#: Every peer, by its name in the tables.
PEERS: dict[str, Peer] = {p.name: p for p in (
    *(NumbalsodaPeer(n) for n in NUMBALSODA_METHODS),
    ScipyPeer("scipy DOP853", "DOP853"), ScipyPeer("scipy Radau", "Radau"),
    ScipyPeer("scipy LSODA", "LSODA"),
    CvodePeer("CVODE Adams", "Adams"), CvodePeer("CVODE BDF", "BDF"),
    HeyokaPeer("heyoka Taylor"),
)}


def available_peers() -> list[str]:
    """The peers that can run here."""
    return [n for n, p in PEERS.items() if p.missing() is None]
