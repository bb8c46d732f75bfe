"""The paper's friction law applied to a MuJoCo top by a compiled passive callback.

In paper mode the contact is frictionless (condim 1) and the scene's law, through the reference
ODE's own compiled terms, acts at the contact point P = S - R e_z. :class:`PaperFriction` arms
one mjData with the law (:func:`userdata_block`, the last :data:`USERDATA_SIZE` entries of its
``userdata``) and owns MuJoCo's process-global ``mjcb_passive`` while a context is open; open
and close contexts from the main thread only. How the callback reaches its state, the normal
force it uses (the previous evaluation's) and why runs on threads equal single runs:
docs/design.md.
"""

from __future__ import annotations

import contextlib
import threading
import warnings
from collections.abc import Iterator
from dataclasses import astuple

import mujoco
import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from tippetop.models.errors import expect
from tippetop.models.mjcf import HARNESS_USERDATA
from tippetop.models.params import FrictionParams, StemParams
from tippetop.mujoco_runner.layout import StructLayout, StructLayoutError, struct_layout
from tippetop.mujoco_runner.model import TopModel
from tippetop.reference_ode.friction import LAW_TERMS, friction_terms

#: Entries at the end of ``mjData.userdata`` that hold the callback's block.
USERDATA_SIZE = HARNESS_USERDATA

# Layout of the block (float64 entries; the marker and the model address are int64 bits).
_U_MAGIC, _U_MODEL, _U_COULOMB, _U_VISC_ON, _U_MU, _U_LAMBDA, _U_VISCOUS, _U_VEPS = range(8)
_U_R, _U_CENTRE = 8, 9  # centre: 9, 10, 11
_U_QPOS_ADR, _U_DOF_ADR = 12, 13
# the stem's end (a second contact point): kind 0 none, 1 rounded, 2 flat (rim); its offset
# from S along the axis and its radius; the axis k in the body frame (17, 18, 19)
_U_STEM_KIND, _U_STEM_L, _U_STEM_R, _U_AXIS = 14, 15, 16, 17
_U_LAST_FX, _U_LAST_FY, _U_LAST_N, _U_LAST_POWER, _U_LAST_N2, _U_CALLS = 20, 21, 22, 23, 24, 25
#: Where the callback leaves what it applied last in its block: Fx, Fy, N and the power, the
#: four entries from here (paper mode's compiled forward passes read Fx, Fy and the power).
LAST_OUTPUT = _U_LAST_FX
if (_U_LAST_FY, _U_LAST_N, _U_LAST_POWER) != (LAST_OUTPUT + 1, LAST_OUTPUT + 2,
                                               LAST_OUTPUT + 3):  # pragma: no cover
    raise ImportError("the callback's outputs must be Fx, Fy, N and the power in a row")
if _U_CALLS >= USERDATA_SIZE:  # pragma: no cover - a layout edit without the constant
    raise ImportError(f"the callback's block needs {_U_CALLS + 1} userdata entries, "
                      f"models.mjcf.HARNESS_USERDATA is {USERDATA_SIZE}")
#: The marker's bits (ASCII "TTopCB02", little-endian: a normal float64, never NaN). The last
#: two characters version the block's layout.
_MAGIC = int.from_bytes(b"TTopCB02", "little")


class StaleCallbackWarning(UserWarning):
    """numba's on-disk cache held a callback compiled for another struct layout."""


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


def _pointer_intrinsic(target: types.Type):
    """An intrinsic that turns an int64 address into a ``target*``."""

    @intrinsic
    def as_pointer(typingctx, address):
        sig = types.CPointer(target)(types.int64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(target)))

        return sig, codegen

    return as_pointer


_f64_ptr = _pointer_intrinsic(types.float64)
_i64_ptr = _pointer_intrinsic(types.int64)
_i32_ptr = _pointer_intrinsic(types.int32)


@intrinsic
def _address_of(typingctx, pointer):
    """A ``void*`` as an int64 address."""
    sig = types.int64(types.voidptr)

    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], context.get_value_type(types.int64))

    return sig, codegen


# The layout baked into the callback: set from struct_layout() before it is compiled (numba
# freezes global integers as constants). -1: not set yet.
_OFF_QPOS = _OFF_QVEL = _OFF_USERDATA = _OFF_QFRC_PASSIVE = _OFF_QFRC_CONSTRAINT = -1
_OFF_NUSERDATA = _NUSERDATA_WIDTH = -1
_BAKED = ("_OFF_QPOS", "_OFF_QVEL", "_OFF_USERDATA", "_OFF_QFRC_PASSIVE", "_OFF_QFRC_CONSTRAINT",
          "_OFF_NUSERDATA", "_NUSERDATA_WIDTH")  # the fields of StructLayout, in order
_N_BAKED = len(_BAKED)


def _passive(m, d):  # pragma: no cover - runs compiled, inside MuJoCo
    model, data = _address_of(m), _address_of(d)
    if model == 0:
        # Not a MuJoCo call (it never passes a NULL model): report the baked layout into the
        # int64[_N_BAKED] array at d.
        out = numba.carray(_i64_ptr(data), (_N_BAKED,))
        out[0], out[1], out[2] = _OFF_QPOS, _OFF_QVEL, _OFF_USERDATA
        out[3], out[4] = _OFF_QFRC_PASSIVE, _OFF_QFRC_CONSTRAINT
        out[5], out[6] = _OFF_NUSERDATA, _NUSERDATA_WIDTH
        return
    if _NUSERDATA_WIDTH == 8:
        nuserdata = _i64_ptr(model + _OFF_NUSERDATA)[0]
    else:
        nuserdata = np.int64(_i32_ptr(model + _OFF_NUSERDATA)[0])
    if nuserdata < USERDATA_SIZE:
        return
    block = _i64_ptr(data + _OFF_USERDATA)[0] + 8 * (nuserdata - USERDATA_SIZE)
    bits = numba.carray(_i64_ptr(block), (USERDATA_SIZE,))
    if bits[_U_MAGIC] != _MAGIC or bits[_U_MODEL] != model:
        return
    u = numba.carray(_f64_ptr(block), (USERDATA_SIZE,))
    qpos_adr, dof_adr = np.int64(u[_U_QPOS_ADR]), np.int64(u[_U_DOF_ADR])
    qpos = numba.carray(_f64_ptr(_i64_ptr(data + _OFF_QPOS)[0] + 8 * qpos_adr), (7,))
    qvel = numba.carray(_f64_ptr(_i64_ptr(data + _OFF_QVEL)[0] + 8 * dof_adr), (6,))
    qfrc = numba.carray(_f64_ptr(_i64_ptr(data + _OFF_QFRC_PASSIVE)[0] + 8 * dof_adr), (6,))
    qcon = numba.carray(_f64_ptr(_i64_ptr(data + _OFF_QFRC_CONSTRAINT)[0] + 8 * dof_adr), (6,))
    u[_U_CALLS] += 1.0
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
    cx, cy, cz = u[_U_CENTRE], u[_U_CENTRE + 1], u[_U_CENTRE + 2]
    ax = r00 * cx + r01 * cy + r02 * cz
    ay = r10 * cx + r11 * cy + r12 * cz
    az = r20 * cx + r21 * cy + r22 * cz - u[_U_R]
    N = qcon[2]
    if N < 0.0:
        N = 0.0
    ck, visc = np.int64(u[_U_COULOMB]), np.int64(u[_U_VISC_ON])
    mu, lam, cv, ve = u[_U_MU], u[_U_LAMBDA], u[_U_VISCOUS], u[_U_VEPS]
    N1, N2 = N, 0.0
    bx = by = bz = 0.0
    stem = u[_U_STEM_KIND]
    if stem != 0.0:
        # the stem's end: Q = S + l k; its lowest point Q - r e_z (rounded) or Q + r u (rim)
        kbx, kby, kbz = u[_U_AXIS], u[_U_AXIS + 1], u[_U_AXIS + 2]
        kx = r00 * kbx + r01 * kby + r02 * kbz
        ky = r10 * kbx + r11 * kby + r12 * kbz
        kz = r20 * kbx + r21 * kby + r22 * kbz
        sl, sr = u[_U_STEM_L], u[_U_STEM_R]
        bx, by, bz = ax + sl * kx, ay + sl * ky, az + u[_U_R] + sl * kz - sr
        if stem == 2.0:
            s = np.sqrt(kx * kx + ky * ky)
            if s > 0.0:
                bx += sr * kz * kx / s
                by += sr * kz * ky / s
                bz += sr - sr * s
            else:
                bz += sr
        # the normal force on each point: the constraint's force and torque (frictionless
        # contacts: normal forces only) split between the two points that touch the table
        z1, z2 = qpos[2] + az, qpos[2] + bz
        if z1 <= 0.0 and z2 <= 0.0:
            tx_b, ty_b, tz_b = qcon[3], qcon[4], qcon[5]
            tx = r00 * tx_b + r01 * ty_b + r02 * tz_b
            ty = r10 * tx_b + r11 * ty_b + r12 * tz_b
            # torque = N1 (a x e_z) + N2 (b x e_z), (x, y) x e_z = (y, -x); N1 + N2 = N
            ux, uy = by - ay, -(bx - ax)
            rx, ry = tx - N * ay, ty + N * ax
            den = ux * ux + uy * uy
            N2 = (rx * ux + ry * uy) / den if den > 0.0 else 0.5 * N
            N2 = min(max(N2, 0.0), N)
            N1 = N - N2
        elif z2 < z1:
            N1, N2 = 0.0, N
    # velocity of each material point: v_origin + omega x arm; F = law(v, N) at each
    fx = fy = power = 0.0
    tx = ty = tz = 0.0
    for point in range(2):
        if point == 0:
            px, py, pz, Np = ax, ay, az, N1
        else:
            if stem == 0.0:
                break
            px, py, pz, Np = bx, by, bz, N2
        vx = qvel[0] + oy * pz - oz * py
        vy = qvel[1] + oz * px - ox * pz
        Fx, Fy = friction_xy(vx, vy, Np, ck, visc, mu, lam, cv, ve)
        fx += Fx
        fy += Fy
        power += Fx * vx + Fy * vy
        # torque about the body origin: arm x F with F = (Fx, Fy, 0)
        tx += -pz * Fy
        ty += pz * Fx
        tz += px * Fy - py * Fx
    qfrc[0] += fx
    qfrc[1] += fy
    qfrc[3] += r00 * tx + r10 * ty + r20 * tz
    qfrc[4] += r01 * tx + r11 * ty + r21 * tz
    qfrc[5] += r02 * tx + r12 * ty + r22 * tz
    u[_U_LAST_FX], u[_U_LAST_FY], u[_U_LAST_N] = fx, fy, N
    u[_U_LAST_POWER], u[_U_LAST_N2] = power, N2


_SIGNATURE = types.void(types.voidptr, types.voidptr)
_compiled = None
_compile_lock = threading.Lock()


def baked_layout(callback: numba.core.ccallback.CFunc) -> StructLayout:
    """The struct layout a compiled callback was compiled with (it reports its constants)."""
    out = np.zeros(_N_BAKED, dtype=np.int64)
    callback.ctypes(None, out.ctypes.data)
    return StructLayout(*(int(v) for v in out))


def _compile(cache: bool) -> numba.core.ccallback.CFunc:
    return numba.cfunc(_SIGNATURE, cache=cache, error_model="numpy")(_passive)


def compiled_callback() -> numba.core.ccallback.CFunc:
    """The compiled passive callback: loaded from numba's on-disk cache, or compiled.

    Once per process. The first call finds the struct layout (:func:`struct_layout`) and bakes
    it in; a cached callback whose baked layout differs is compiled afresh instead.

    Warns:
        StaleCallbackWarning: If the on-disk cache held a callback for another layout.
    """
    global _compiled
    with _compile_lock:
        if _compiled is None:
            layout = struct_layout()
            globals().update(zip(_BAKED, astuple(layout), strict=True))
            callback = _compile(cache=True)
            baked = baked_layout(callback)
            if baked != layout:
                warnings.warn(
                    f"numba's cache ({numba.config.CACHE_DIR or 'next to the sources'}) held the "
                    f"paper-mode callback compiled for another MuJoCo struct layout ({baked}; "
                    f"this process: {layout}); compiling it afresh without the cache. Delete "
                    "that folder to stop this.", StaleCallbackWarning, stacklevel=2)
                callback = _compile(cache=False)
                if baked_layout(callback) != layout:  # pragma: no cover - numba misbehaving
                    raise StructLayoutError(f"the callback compiled with {baked_layout(callback)}"
                                            f", not this process's {layout}")
            _compiled = callback
    return _compiled


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


def _check_userdata(model: mujoco.MjModel) -> None:
    expect(model.nuserdata >= USERDATA_SIZE, "mjcf size nuserdata",
           f">= {USERDATA_SIZE} in paper mode (the callback keeps its parameters in the last "
           f"{USERDATA_SIZE} entries of mjData.userdata): load the model with "
           f'mujoco_runner.model.load_model, or declare <size nuserdata="{USERDATA_SIZE}"/>',
           int(model.nuserdata))


def userdata_block(top_model: TopModel, friction: FrictionParams, *,
                   mu: float | None = None, stem: StemParams | None = None) -> np.ndarray:
    """The :data:`USERDATA_SIZE` values that arm an mjData of ``top_model.model``.

    Write them into the LAST entries of its userdata (``data.userdata[-USERDATA_SIZE:]``, or
    ``batch.userdata[:, -USERDATA_SIZE:]`` for the rows of a ``mujoco.batch.Batch`` of your
    own); the
    callback then applies the law to that mjData whenever it is stepped with exactly this
    ``MjModel`` and the callback is installed (:func:`callback_installed`). Zeros disarm.

    Raises:
        TippetopError: If the model has fewer than :data:`USERDATA_SIZE` userdata entries.
    """
    _check_userdata(top_model.model)
    p = law_parameters(friction, top_model, mu)
    bits = np.zeros(USERDATA_SIZE, dtype=np.int64)
    bits[_U_MAGIC], bits[_U_MODEL] = _MAGIC, top_model.model._address
    block = bits.view(np.float64)
    block[_U_COULOMB], block[_U_VISC_ON] = p["coulomb_kind"], p["viscous_on"]
    block[_U_MU], block[_U_LAMBDA] = p["mu"], p["Lambda"]
    block[_U_VISCOUS], block[_U_VEPS] = p["viscous"], p["v_eps"]
    block[_U_R] = top_model.top.R_m
    block[_U_CENTRE:_U_CENTRE + 3] = top_model.centre_body_m
    block[_U_QPOS_ADR], block[_U_DOF_ADR] = top_model.qpos_adr, top_model.dof_adr
    if stem is not None:
        block[_U_STEM_KIND] = 2.0 if stem.kind == "cylinder" else 1.0
        block[_U_STEM_L], block[_U_STEM_R] = stem.offset_m, stem.radius_m
    block[_U_AXIS:_U_AXIS + 3] = top_model.axis_body
    return block


# The installed callback's reference count and the callback it replaced (main thread only).
_install_lock = threading.Lock()
_install_count = 0
_previous_callback = None
_armed: dict[int, PaperFriction] = {}  # data._address -> its open context


def _install() -> None:
    global _install_count, _previous_callback
    callback = compiled_callback()
    with _install_lock:
        if _install_count == 0:
            _previous_callback = mujoco.get_mjcb_passive()
            mujoco.set_mjcb_passive(callback.ctypes)
        _install_count += 1


def _uninstall() -> None:
    global _install_count, _previous_callback
    with _install_lock:
        _install_count -= 1
        if _install_count == 0:
            mujoco.set_mjcb_passive(_previous_callback)
            _previous_callback = None


@contextlib.contextmanager
def callback_installed() -> Iterator[numba.core.ccallback.CFunc]:
    """Install the compiled callback as MuJoCo's ``mjcb_passive`` for the ``with`` block.

    Reference counted with every :class:`PaperFriction`: the previous callback is restored
    when the last context closes. It acts only on mjData armed with :func:`userdata_block`.
    The thread pool (:mod:`.batch`) holds it open on the main thread while its threads step
    their own armed mjData; a ``mujoco.batch.Batch`` of your own (persistent, on the caller's
    model) whose rows' userdata you armed works too. Open and close it from the main thread,
    not while stepping elsewhere.

    Example:
        >>> batch = mujoco.batch.Batch(tm.model, nsim=8, nthread=2, persistent=True)
        >>> batch.set_models(tm.model)
        >>> batch.userdata[:, -USERDATA_SIZE:] = userdata_block(tm, FrictionParams())
        >>> with callback_installed():
        ...     batch.step(nstep=1000)
    """
    _install()
    try:
        yield compiled_callback()
    finally:
        _uninstall()


class PaperFriction:
    """Context manager that applies the paper's friction law to one mjData.

    On enter the compiled callback is installed (if no other context has) and ``data`` is
    armed: its userdata's last :data:`USERDATA_SIZE` entries get :func:`userdata_block`. On exit
    the marker is cleared and, when it was the last open context, the previous callback is
    restored. Several contexts may be open at once on different mjData (of the same model or
    not), each with its own law; the same mjData cannot be armed twice. Open and close them
    from the main thread only (see docs/design.md).

    Example:
        >>> with PaperFriction(top_model, data, FrictionParams()):
        ...     mujoco.mj_step(top_model.model, data, nstep=1000)
    """

    def __init__(self, top_model: TopModel, data: mujoco.MjData, friction: FrictionParams,
                 *, mu: float | None = None, stem: StemParams | None = None) -> None:
        """Prepare (not install) the callback for ``data`` of ``top_model.model``.

        With ``stem``, the law acts on the ball or on the stem's end, whichever touches the
        table, or on both, each with its share of the normal force (the constraint's force
        and torque on the top, split between the two points).

        Raises:
            TippetopError: If the model has fewer than :data:`USERDATA_SIZE` userdata entries.
            ValueError: If ``data`` does not have the sizes of an mjData of the model.
        """
        self.top_model = top_model
        self.data = data
        self.params = law_parameters(friction, top_model, mu)
        self._block = userdata_block(top_model, friction, mu=mu, stem=stem)
        model = top_model.model
        if data.userdata.size != model.nuserdata or data.qvel.size != model.nv:
            raise ValueError("data is not an mjData of top_model.model (sizes differ)")
        self._open = False

    def _userdata(self) -> np.ndarray:
        return self.data.userdata[-USERDATA_SIZE:]

    def __enter__(self) -> PaperFriction:
        """Install the compiled callback (reference counted) and arm this data."""
        address = self.data._address
        if address in _armed:
            raise RuntimeError("this MjData is already armed by an open PaperFriction context; "
                               "close that one first")
        _install()
        self._userdata()[:] = self._block
        _armed[address] = self
        self._open = True
        return self

    def __exit__(self, *exc_info: object) -> None:
        """Disarm this data; restore the previous callback if no other context is open."""
        if not self._open:
            return
        self._userdata().view(np.int64)[_U_MAGIC] = 0
        del _armed[self.data._address]
        self._open = False
        _uninstall()

    @property
    def n_calls(self) -> int:
        """How many times the callback acted on this data since the context opened."""
        return int(self._userdata()[_U_CALLS]) if self._open else 0

    @property
    def last_force(self) -> tuple[float, float, float]:
        """(Fx, Fy, N) of the callback's last call (N, N, N); zeros before the first."""
        u = self._userdata()
        return float(u[_U_LAST_FX]), float(u[_U_LAST_FY]), float(u[_U_LAST_N])

    @property
    def last_power(self) -> float:
        """The friction power of the callback's last call (W), over both points."""
        return float(self._userdata()[_U_LAST_POWER])

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
    "LAST_OUTPUT",
    "PaperFriction",
    "StaleCallbackWarning",
    "StructLayout",
    "StructLayoutError",
    "USERDATA_SIZE",
    "baked_layout",
    "callback_installed",
    "compiled_callback",
    "friction_xy",
    "law_force",
    "law_parameters",
    "struct_layout",
    "userdata_block",
]
