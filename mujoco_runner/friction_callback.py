"""The paper's friction law applied to a MuJoCo top by a compiled passive callback.

In "paper" mode the contact is frictionless (condim 1) and the friction force

    F = -mu N v_P / sqrt(|v_P|^2 + Lambda^2)          (paper eq. 2.12, ``modified_coulomb``)

(or any other law of :class:`models.params.FrictionParams`, through the reference ODE's own
compiled law terms, so both engines apply the same function) acts at the
contact point P = S - R e_z, with v_P the horizontal velocity of the material point at P. This
module owns MuJoCo's process-global ``mjcb_passive`` while a :class:`PaperFriction` context is
open, and restores the previous callback when it closes.

How the callback reaches mjData (no Python runs per step):

* The callback is one numba ``cfunc`` with MuJoCo's signature ``void(const mjModel*, mjData*)``,
  compiled once per process on first use (about 1-2 s; it is not cached on disk, because it
  embeds the addresses below).
* Two module-level numpy arrays, :data:`_SLOT_I` (int64) and :data:`_SLOT_F` (float64), are the
  only shared state. Their addresses are fixed for the life of the process and are baked into
  the cfunc as constants; a tiny numba intrinsic turns an integer address into a typed pointer,
  and ``numba.carray`` views it as an array.
* :meth:`PaperFriction.__enter__` writes into the slots: the ``mjData*`` and ``mjModel*``
  addresses (``data._address``, ``model._address``), the raw addresses of ``data.qpos``,
  ``data.qvel``, ``data.qfrc_passive`` and ``data.qfrc_constraint`` (``arr.ctypes.data``; the
  bindings' arrays are views of mjData's own buffers, which never move), the free joint's
  qpos/dof addresses, and the law's parameters. The callback compares the ``mjData*`` it is
  given with the stored one and does nothing for any other mjData (another model stepping in
  the same process, or the runner's scratch data), and nothing once the context is closed.
* The force is added to ``qfrc_passive`` (MuJoCo fills it before calling the callback, which
  must add, not overwrite) as the free joint's generalized force: the world force F on the
  translational dofs and the torque (P - body origin) x F, rotated into the body frame, on the
  rotational dofs. That is J^T F for the Jacobian of the material point at P, i.e. what
  ``mj_applyFT(F, 0, P)`` gives (a test checks this against a Python callback using
  ``mj_applyFT``).

The normal force N. Passive forces are computed before the constraint solve, so the current
evaluation's N is unknown. The callback reads the vertical component of the free joint's
``qfrc_constraint``, which still holds the result of the previous dynamics evaluation: with a
frictionless plane contact that is exactly the normal force (the contact normal is e_z and
the translational dofs take the world force). With RK4 (four evaluations per step) each stage
thus sees the N of the stage before it, and the first stage the N of the previous step's last
stage; with Euler it is the previous step's N. So N lags by one evaluation, an O(dt) error.
Any other constraint force on the body (another contact, an equality) would be counted in N;
a top whose only contact is the ball has none. N is clipped at 0.

The velocity used is the one in mjData at call time (the RK4 stage's velocity).
"""

from __future__ import annotations

import threading

import mujoco
import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from tippetop.models.params import FrictionParams
from tippetop.mujoco_runner.model import TopModel
from tippetop.reference_ode.friction import LAW_TERMS, friction_terms

# Slot layout. Integer slots:
_I_DATA, _I_MODEL, _I_QPOS, _I_QVEL, _I_QFRC_PASSIVE, _I_QFRC_CONSTRAINT = 0, 1, 2, 3, 4, 5
_I_QPOS_ADR, _I_DOF_ADR, _I_COULOMB, _I_CALLS, _I_VISC = 6, 7, 8, 9, 10
# Float slots:
_F_MU, _F_LAMBDA, _F_VISCOUS, _F_VEPS, _F_R, _F_CENTRE = 0, 1, 2, 3, 4, 5  # centre: 5, 6, 7
_F_LAST_FX, _F_LAST_FY, _F_LAST_N = 8, 9, 10
_NSLOT = 16

#: The callback's shared state (see the module docstring). Never reallocated.
_SLOT_I = np.zeros(_NSLOT, dtype=np.int64)
_SLOT_F = np.zeros(_NSLOT, dtype=np.float64)
_SLOT_I_ADDR = int(_SLOT_I.ctypes.data)
_SLOT_F_ADDR = int(_SLOT_F.ctypes.data)


@numba.njit(cache=True)
def friction_xy(vx, vy, N, coulomb_kind, viscous, mu, Lambda, c_visc, v_eps):
    """Horizontal friction force (Fx, Fy) (N) for the slip (vx, vy) (m/s) and normal force N.

    The same compiled law terms as the reference ODE (:func:`reference_ode.friction.
    friction_terms`): F = N phi(v_P) + psi(v_P), with the law given by its
    (``coulomb_kind``, ``viscous``) pair from :data:`reference_ode.friction.LAW_TERMS`.
    """
    phix, phiy, psix, psiy = friction_terms(coulomb_kind, viscous, vx, vy, mu, Lambda, c_visc,
                                            v_eps)
    return N * phix + psix, N * phiy + psiy


@numba.njit(cache=True)
def _friction_many(vx, vy, N, coulomb_kind, viscous, mu, Lambda, c_visc, v_eps):
    fx = np.empty(vx.size)
    fy = np.empty(vx.size)
    for i in range(vx.size):
        fx[i], fy[i] = friction_xy(vx[i], vy[i], N[i], coulomb_kind, viscous, mu, Lambda,
                                   c_visc, v_eps)
    return fx, fy





@intrinsic
def _f64_ptr(typingctx, address):
    """An int64 address as a ``float64*``."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return sig, codegen


@intrinsic
def _i64_ptr(typingctx, address):
    """An int64 address as an ``int64*``."""
    sig = types.CPointer(types.int64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))

    return sig, codegen


@intrinsic
def _address_of(typingctx, pointer):
    """A ``void*`` as an int64 address."""
    sig = types.int64(types.voidptr)

    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], context.get_value_type(types.int64))

    return sig, codegen


def _passive(m, d):  # pragma: no cover - runs compiled, inside MuJoCo
    si = numba.carray(_i64_ptr(_SLOT_I_ADDR), (_NSLOT,))
    sf = numba.carray(_f64_ptr(_SLOT_F_ADDR), (_NSLOT,))
    if si[_I_DATA] == 0 or si[_I_DATA] != _address_of(d) or si[_I_MODEL] != _address_of(m):
        return
    si[_I_CALLS] += 1
    qpos = numba.carray(_f64_ptr(si[_I_QPOS] + 8 * si[_I_QPOS_ADR]), (7,))
    qvel = numba.carray(_f64_ptr(si[_I_QVEL] + 8 * si[_I_DOF_ADR]), (6,))
    qfrc = numba.carray(_f64_ptr(si[_I_QFRC_PASSIVE] + 8 * si[_I_DOF_ADR]), (6,))
    qcon = numba.carray(_f64_ptr(si[_I_QFRC_CONSTRAINT] + 8 * si[_I_DOF_ADR]), (6,))
    # Body-to-world rotation from the (normalised) quaternion.
    w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
    inv = 1.0 / np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w * inv, x * inv, y * inv, z * inv
    r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    r10, r11, r12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    # World angular velocity, and the arm from the body origin to P = S - R e_z.
    wbx, wby, wbz = qvel[3], qvel[4], qvel[5]
    ox = r00 * wbx + r01 * wby + r02 * wbz
    oy = r10 * wbx + r11 * wby + r12 * wbz
    oz = r20 * wbx + r21 * wby + r22 * wbz
    cx, cy, cz = sf[_F_CENTRE], sf[_F_CENTRE + 1], sf[_F_CENTRE + 2]
    ax = r00 * cx + r01 * cy + r02 * cz
    ay = r10 * cx + r11 * cy + r12 * cz
    az = r20 * cx + r21 * cy + r22 * cz - sf[_F_R]
    # Velocity of the material point at P: v_origin + omega x arm.
    vx = qvel[0] + oy * az - oz * ay
    vy = qvel[1] + oz * ax - ox * az
    N = qcon[2]
    if N < 0.0:
        N = 0.0
    fx, fy = friction_xy(vx, vy, N, si[_I_COULOMB], si[_I_VISC], sf[_F_MU], sf[_F_LAMBDA],
                         sf[_F_VISCOUS], sf[_F_VEPS])
    # Torque about the body origin, arm x F with F = (fx, fy, 0), rotated into the body frame.
    tx, ty, tz = -az * fy, az * fx, ax * fy - ay * fx
    qfrc[0] += fx
    qfrc[1] += fy
    qfrc[3] += r00 * tx + r10 * ty + r20 * tz
    qfrc[4] += r01 * tx + r11 * ty + r21 * tz
    qfrc[5] += r02 * tx + r12 * ty + r22 * tz
    sf[_F_LAST_FX], sf[_F_LAST_FY], sf[_F_LAST_N] = fx, fy, N


_compiled = None
_compile_lock = threading.Lock()


def compiled_callback() -> numba.core.ccallback.CFunc:
    """The compiled passive callback (compiled on the first call, once per process)."""
    global _compiled
    with _compile_lock:
        if _compiled is None:
            _compiled = numba.cfunc(types.void(types.voidptr, types.voidptr),
                                    error_model="numpy")(_passive)
    return _compiled


_owner: PaperFriction | None = None


def law_parameters(friction: FrictionParams, top_model: TopModel,
                   mu: float | None = None) -> dict[str, float | int]:
    """The law's terms and parameters for :func:`friction_xy` (``mu`` overrides friction.mu)."""
    coulomb_kind, viscous = LAW_TERMS[friction.law]
    return {
        "coulomb_kind": coulomb_kind,
        "viscous_on": int(viscous),
        "mu": friction.mu if mu is None else float(mu),
        "Lambda": friction.Lambda_mps,
        "viscous": friction.viscous_coefficient(top_model.top),
        "v_eps": friction.coulomb_v_eps_mps,
    }


class PaperFriction:
    """Context manager that applies the paper's friction law to one mjData.

    While open, MuJoCo's global passive callback is the compiled one and acts on ``data`` only;
    on exit the previous callback is restored. Only one can be open at a time (the callback is
    process-global).

    Example:
        >>> with PaperFriction(top_model, data, FrictionParams()):
        ...     mujoco.mj_step(top_model.model, data, nstep=1000)
    """

    def __init__(self, top_model: TopModel, data: mujoco.MjData, friction: FrictionParams,
                 *, mu: float | None = None) -> None:
        """Prepare (not install) the callback for ``data`` of ``top_model.model``."""
        self.top_model = top_model
        self.data = data
        self.params = law_parameters(friction, top_model, mu)
        self._previous = None
        self._open = False

    def __enter__(self) -> PaperFriction:
        """Install the compiled callback for this data."""
        global _owner
        if _owner is not None:
            raise RuntimeError("a PaperFriction callback is already installed; MuJoCo's passive "
                               "callback is process-global, so close it first")
        callback = compiled_callback()
        model, data, tm = self.top_model.model, self.data, self.top_model
        p = self.params
        _SLOT_I[:] = 0
        _SLOT_F[:] = 0.0
        _SLOT_I[_I_MODEL] = model._address
        _SLOT_I[_I_QPOS] = data.qpos.ctypes.data
        _SLOT_I[_I_QVEL] = data.qvel.ctypes.data
        _SLOT_I[_I_QFRC_PASSIVE] = data.qfrc_passive.ctypes.data
        _SLOT_I[_I_QFRC_CONSTRAINT] = data.qfrc_constraint.ctypes.data
        _SLOT_I[_I_QPOS_ADR] = tm.qpos_adr
        _SLOT_I[_I_DOF_ADR] = tm.dof_adr
        _SLOT_I[_I_COULOMB] = p["coulomb_kind"]
        _SLOT_I[_I_VISC] = p["viscous_on"]
        _SLOT_F[_F_MU], _SLOT_F[_F_LAMBDA] = p["mu"], p["Lambda"]
        _SLOT_F[_F_VISCOUS], _SLOT_F[_F_VEPS] = p["viscous"], p["v_eps"]
        _SLOT_F[_F_R] = tm.top.R_m
        _SLOT_F[_F_CENTRE:_F_CENTRE + 3] = tm.centre_body_m
        self._previous = mujoco.get_mjcb_passive()
        _SLOT_I[_I_DATA] = data._address  # last: arms the callback
        mujoco.set_mjcb_passive(callback.ctypes)
        _owner = self
        self._open = True
        return self

    def __exit__(self, *exc_info: object) -> None:
        """Disarm the callback and restore the previous one."""
        global _owner
        if not self._open:
            return
        _SLOT_I[_I_DATA] = 0
        mujoco.set_mjcb_passive(self._previous)
        self._previous = None
        self._open = False
        _owner = None

    @property
    def n_calls(self) -> int:
        """How many times the callback acted on this data since the context opened."""
        return int(_SLOT_I[_I_CALLS]) if self._open else 0

    @property
    def last_force(self) -> tuple[float, float, float]:
        """(Fx, Fy, N) of the callback's last call (N, N, N); zeros before the first."""
        return (float(_SLOT_F[_F_LAST_FX]), float(_SLOT_F[_F_LAST_FY]),
                float(_SLOT_F[_F_LAST_N]))

    def force(self, v_P: np.ndarray, N: np.ndarray) -> np.ndarray:
        """The law's world force (n, 3) for slip velocities ``v_P`` (n, 3) and normal forces N."""
        return law_force(self.params, v_P, N)


def law_force(params: dict[str, float | int], v_P: np.ndarray, N: np.ndarray) -> np.ndarray:
    """The law's world force, shape (n, 3), for slip velocities (n, 3) and normal forces (n,)."""
    v_P = np.atleast_2d(v_P)
    N = np.broadcast_to(np.clip(np.asarray(N, dtype=float), 0.0, None), v_P[:, 0].shape)
    fx, fy = _friction_many(np.ascontiguousarray(v_P[:, 0], dtype=float),
                            np.ascontiguousarray(v_P[:, 1], dtype=float),
                            np.ascontiguousarray(N), params["coulomb_kind"],
                            params["viscous_on"], params["mu"], params["Lambda"],
                            params["viscous"], params["v_eps"])
    return np.stack([fx, fy, np.zeros_like(fx)], axis=1)


__all__ = [
    "PaperFriction",
    "compiled_callback",
    "friction_xy",
    "law_force",
    "law_parameters",
]
