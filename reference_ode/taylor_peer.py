"""heyoka's Taylor method as a peer of the reference integrator (``tippetop bench ode``).

heyoka (an optional extra: ``pip install -e '.[peers]'``) integrates a system given in its own
expressions, compiled by LLVM, with an adaptive Taylor method whose order follows the tolerance
(8 at 1e-6, 13 at 1e-10, 18 at 1e-14). :func:`vector_system` writes the vector formulation's
right-hand side (:func:`reference_ode.vector.vector_core`) for the ball on the table with the
paper's law (modified Coulomb, plus a viscous part if the law has one) in those expressions, term
by term; tests/reference_ode/test_taylor_peer.py checks it against the compiled one. Other
contacts (a rim, a stem) and the exact Coulomb law's ramp are not written: :func:`unsupported`
says so. Nothing here is imported by a run; only the benchmark uses it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from tippetop.reference_ode.friction import COULOMB_EXACT, COULOMB_MODIFIED
from tippetop.reference_ode.params_array import (
    P_A_OFF,
    P_COULOMB_KIND,
    P_CVISC,
    P_G,
    P_IA,
    P_IC,
    P_LAM,
    P_M,
    P_MU,
    P_OTHER,
    P_R,
    P_RIM,
    P_VISCOUS,
)
from tippetop.reference_ode.peers import PeerRun

#: The peer's name in the benchmark's tables.
HEYOKA = "heyoka Taylor"
#: What to say when heyoka cannot be imported.
HEYOKA_MISSING = "heyoka is not installed: pip install -e '.[peers]'"
#: The state's names, in the vector formulation's order (reference_ode.vector).
STATE_NAMES = ("x", "y", "vx", "vy", "qw", "qx", "qy", "qz", "wx", "wy", "wz")


def heyoka_missing() -> str | None:
    """None if heyoka can be imported, else the reason (one line)."""
    try:
        import heyoka  # noqa: F401
    except ImportError:
        return HEYOKA_MISSING
    return None


def unsupported(p: np.ndarray) -> str | None:
    """None if :func:`vector_system` writes this problem, else why not (one line)."""
    if p[P_RIM] != 0.0 or p[P_OTHER] >= 0.0:
        return "only the ball on the table is written in heyoka's expressions (no stem, no rim)"
    if int(p[P_COULOMB_KIND]) == COULOMB_EXACT:
        return "the exact Coulomb law's ramp (a max) is not written in heyoka's expressions"
    return None


def vector_system(p: np.ndarray) -> list:
    """The vector formulation's right-hand side in heyoka's expressions: [(variable, rate)].

    The same terms in the same order as :func:`reference_ode.vector.vector_core` for a sphere
    contact (X_P = a k - R e_z), the parameters taken as constants.
    """
    import heyoka as hy

    reason = unsupported(p)
    if reason is not None:
        raise ValueError(reason)
    R, a, M, A, C, g = (float(p[i]) for i in (P_R, P_A_OFF, P_M, P_IA, P_IC, P_G))
    mu, lam, c_visc = float(p[P_MU]), float(p[P_LAM]), float(p[P_CVISC])
    modified = int(p[P_COULOMB_KIND]) == COULOMB_MODIFIED
    viscous = p[P_VISCOUS] != 0.0
    x, y, vx, vy, qw, qx, qy, qz, wx, wy, wz = hy.make_vars(*STATE_NAMES)
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    kx = 2.0 * (qx * qz + qw * qy) * inv
    ky = 2.0 * (qy * qz - qw * qx) * inv
    kz = (qw * qw - qx * qx - qy * qy + qz * qz) * inv
    n = wx * kx + wy * ky + wz * kz
    kdx = wy * kz - wz * ky
    kdy = wz * kx - wx * kz
    kdz = wx * ky - wy * kx
    px, py, pz = a * kx, a * ky, a * kz - R
    vpx = vx + wy * pz - wz * py
    vpy = vy + wz * px - wx * pz
    if modified:
        s = mu / hy.sqrt(vpx * vpx + vpy * vpy + lam * lam)
        phix, phiy = -s * vpx, -s * vpy
    else:
        phix = phiy = hy.expression(0.0)
    if viscous:
        psix, psiy = -c_visc * vpx, -c_visc * vpy
    else:
        psix = psiy = hy.expression(0.0)
    t1x = py - pz * phiy
    t1y = pz * phix - px
    t1z = px * phiy - py * phix
    g0 = (C - A) * n
    t0x = -pz * psiy - g0 * kdx
    t0y = pz * psix - g0 * kdy
    t0z = px * psiy - py * psix - g0 * kdz
    iA = 1.0 / A
    dC = 1.0 / C - iA
    k1 = dC * (kx * t1x + ky * t1y + kz * t1z)
    ax_ = iA * t1x + k1 * kx
    ay_ = iA * t1y + k1 * ky
    k0 = dC * (kx * t0x + ky * t0y + kz * t0z)
    bx = iA * t0x + k0 * kx
    by = iA * t0y + k0 * ky
    wkd_z = wx * kdy - wy * kdx
    denom = 1.0 + M * a * (ax_ * ky - ay_ * kx)
    N = M * (g - a * ((bx * ky - by * kx) + wkd_z)) / denom
    Fx = N * phix + psix
    Fy = N * phiy + psiy
    return [(x, vx), (y, vy), (vx, Fx / M), (vy, Fy / M),
            (qw, -0.5 * (wx * qx + wy * qy + wz * qz)),
            (qx, 0.5 * (qw * wx + wy * qz - wz * qy)),
            (qy, 0.5 * (qw * wy + wz * qx - wx * qz)),
            (qz, 0.5 * (qw * wz + wx * qy - wy * qx)),
            (wx, N * ax_ + bx), (wy, N * ay_ + by),
            (wz, N * (iA * t1z + k1 * kz) + (iA * t0z + k0 * kz))]


@dataclass
class TaylorPeer:
    """heyoka's adaptive Taylor integrator for one problem and tolerance, compiled once.

    heyoka's tolerance is one number for the relative and absolute error of every variable;
    :meth:`run` integrates from ``y0`` to ``t_end`` and, with ``events``, records where the
    symmetry axis first falls through the horizontal (k_z from > 0 to <= 0: theta = pi/2, the
    reference's mark) as ``t_invert``.
    """

    p: np.ndarray
    tol: float
    events: bool = False

    def __post_init__(self) -> None:
        import heyoka as hy

        sys = vector_system(self.p)
        self.crossings: list[float] = []
        kw = {}
        if self.events:
            qw, qx, qy, qz = (v for v, _ in sys[4:8])

            def cb(ta, time, d_sgn) -> None:  # noqa: ARG001 - heyoka's signature
                self.crossings.append(float(time))

            kz = qw * qw - qx * qx - qy * qy + qz * qz  # k_z times |q|^2 (same sign)
            kw["nt_events"] = [hy.nt_event(kz, cb, direction=hy.event_direction.negative)]
        t0 = time.perf_counter()
        self.ta = hy.taylor_adaptive(sys, np.zeros(len(sys)), tol=float(self.tol),
                                     compact_mode=False, **kw)
        self.compile_s = time.perf_counter() - t0

    @property
    def order(self) -> int:
        """The Taylor order heyoka chose for the tolerance."""
        return int(self.ta.order)

    def run(self, y0: np.ndarray, t_end_s: float) -> PeerRun:
        """Integrate from (0, y0) to t_end; the CPU time of the propagation alone."""
        self.crossings.clear()
        self.ta.time = 0.0
        self.ta.state[:] = np.asarray(y0, dtype=float)
        t0 = time.process_time()
        res = self.ta.propagate_until(float(t_end_s))
        s = time.process_time() - t0
        outcome = res[0]
        ok = str(outcome).endswith("time_limit")
        # a Taylor step evaluates the whole jet once: its steps stand in n_rhs
        return PeerRun(y_final=np.array(self.ta.state), n_rhs=int(res[3]), s=s, success=ok)

    @property
    def t_invert(self) -> float:
        """The first crossing of the last :meth:`run` with ``events`` (NaN if none)."""
        return min(self.crossings) if self.crossings else math.nan
