"""Sample-by-sample stepping of one mjData in a compiled loop that calls MuJoCo's C API.

:class:`CompiledStepper` steps a run one sample interval at a time and records the state at
each sample in one numba-compiled loop over many samples (:func:`_advance`), which calls
MuJoCo's own functions in the very ``libmujoco`` the Python bindings use: the same C calls on
the same structs, so the same numbers, without Python between them, and with the GIL
released. :func:`available` says whether it can run in this process (else the caller steps
from Python). What it saves, and what it reads of MuJoCo's structs: docs/design.md.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os

import mujoco
import numba as nb
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

import tippetop.reference_ode  # noqa: F401  (sets numba's cache folder, reference_ode._jit)
from tippetop.mujoco_runner.worker.windows import (
    FLOAT_FIELDS,
    INT_FIELDS,
    WindowTop,
    new_windows,
)

# integrator codes for the kernel
INTEG_STEP = 0  # no split: mj_step whole
INTEG_RK4 = 1  # mj_RungeKutta(m, d, 4)
INTEG_PLAIN = 2  # a (m, d) integrator: mj_Euler, mj_implicit

# slots of the function-address vector
_F_STEP, _F_FORWARD, _F_CHECKPOS, _F_CHECKVEL, _F_CHECKACC = 0, 1, 2, 3, 4
_F_RK, _F_PLAIN, _F_GETSTATE, _F_CONTACTFORCE = 5, 6, 7, 8
_FUNCTIONS = ("mj_step", "mj_forward", "mj_checkPos", "mj_checkVel", "mj_checkAcc",
              "mj_RungeKutta", "mj_Euler", "mj_getState", "mj_contactForce")


def _emit(builder, kinds: str, fnaddr, llargs) -> None:
    """Call the C function at ``fnaddr``: 'p' args are pointers, 'i' args C ints."""
    i8p = ir.IntType(8).as_pointer()
    tys = [i8p if k == "p" else ir.IntType(32) for k in kinds]
    fnty = ir.FunctionType(ir.VoidType(), tys)
    ptr = builder.inttoptr(fnaddr, fnty.as_pointer())
    vals = [builder.inttoptr(v, i8p) if k == "p" else builder.trunc(v, ir.IntType(32))
            for k, v in zip(kinds, llargs, strict=True)]
    builder.call(ptr, vals)


@intrinsic
def _c_pp(typingctx, fn, a, b):
    """``fn(void* a, void* b)``; all arguments int64."""
    sig = types.void(types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        _emit(builder, "pp", args[0], args[1:])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _c_ppi(typingctx, fn, a, b, c):
    """``fn(void* a, void* b, int c)``."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        _emit(builder, "ppi", args[0], args[1:])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _c_pppi(typingctx, fn, a, b, c, e):
    """``fn(void* a, void* b, void* c, int e)``."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        _emit(builder, "pppi", args[0], args[1:])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _c_ppip(typingctx, fn, a, b, c, e):
    """``fn(void* a, void* b, int c, void* e)``."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        _emit(builder, "ppip", args[0], args[1:])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _i32_at(typingctx, address):
    """The C int at ``address``."""
    sig = types.int32(types.int64)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.IntType(32).as_pointer())
        return builder.load(ptr)

    return sig, codegen


@intrinsic
def _f64_at(typingctx, address):
    """The double at ``address``."""
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.DoubleType().as_pointer())
        return builder.load(ptr)

    return sig, codegen


@intrinsic
def _i64_at(typingctx, address):
    """The 64-bit integer (a pointer) at ``address``."""
    sig = types.int64(types.int64)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.IntType(64).as_pointer())
        return builder.load(ptr)

    return sig, codegen


_I8 = types.int64

# slots of the integer parameters of :func:`_accumulate` (``ip``)
(_P_NCON, _P_ARENA, _P_CSIZE, _P_DIST, _P_POS, _P_FRAME, _P_GEOM, _P_BODY, _P_BALL, _P_QPOS,
 _P_QVEL, _P_XMAT, _P_BALLZ, _P_LAW) = range(14)
# columns of the windows (worker/windows.py's INT_FIELDS and FLOAT_FIELDS, in their order)
(_W_PASSES, _W_TOUCH, _W_TOUCH_PASSES, _W_FIRST, _W_LAST, _W_INNER, _W_INNER_START, _W_LIFTS,
 _W_OTHER, _W_FLIP) = range(10)
(_W_GAP, _W_LEAD, _W_TRAIL, _W_INNER_GAP, _W_DEPTH, _W_N, _W_FX, _W_FY, _W_FZ, _W_TX, _W_TY,
 _W_TZ, _W_POWER, _W_LFX, _W_LFY, _W_LPOWER, _W_GAP_MIN, _W_SLIP_X, _W_SLIP_Y) = range(19)


def _accumulate(fns, m, d, ip, fp, gbody, wi, wf, carry, f6, r, j, qp,
                qv):  # pragma: no cover
    """Add the mjData's last forward pass to window ``r`` as its pass at offset ``j``.

    The arithmetic of :class:`~.worker.windows.WindowAccumulator`, over the raw structs;
    ``qp``, ``qv``: the addresses of the free joint's qpos and qvel at the pass's state.
    """
    body, ball = ip[_P_BODY], ip[_P_BALL]
    size = ip[_P_CSIZE]
    ncon = np.int64(_i32_at(ip[_P_NCON]))
    arena = _i64_at(ip[_P_ARENA])
    xm = ip[_P_XMAT]
    m0, m1, m2 = _f64_at(xm), _f64_at(xm + 8), _f64_at(xm + 16)
    m3, m4, m5 = _f64_at(xm + 24), _f64_at(xm + 32), _f64_at(xm + 40)
    m6, m7, m8 = _f64_at(xm + 48), _f64_at(xm + 56), _f64_at(xm + 64)
    vx, vy, vz = _f64_at(qv), _f64_at(qv + 8), _f64_at(qv + 16)
    lx, ly, lz = _f64_at(qv + 24), _f64_at(qv + 32), _f64_at(qv + 40)
    ox = m0 * lx + m1 * ly + m2 * lz
    oy = m3 * lx + m4 * ly + m5 * lz
    oz = m6 * lx + m7 * ly + m8 * lz
    px, py, pz = _f64_at(qp), _f64_at(qp + 8), _f64_at(qp + 16)
    code = 0
    depth = 0.0
    n = fx = fy = fz = tx = ty = tz = power = 0.0
    for k in range(ncon):
        base = arena + k * size
        g1 = np.int64(_i32_at(base + ip[_P_GEOM]))
        g2 = np.int64(_i32_at(base + ip[_P_GEOM] + 4))
        b1, b2 = gbody[g1], gbody[g2]
        if b1 != body and b2 != body:
            continue
        code |= 1 if (g1 == ball or g2 == ball) else 2
        depth = max(depth, -_f64_at(base + ip[_P_DIST]))
        _c_ppip(fns[_F_CONTACTFORCE], m, d, k, f6.ctypes.data)
        s = 1.0 if b2 == body else -1.0
        fr = base + ip[_P_FRAME]
        f0, f1, f2, f3, f4, f5 = f6[0], f6[1], f6[2], f6[3], f6[4], f6[5]
        ax = s * (f1 * _f64_at(fr + 24) + f2 * _f64_at(fr + 48))
        ay = s * (f1 * _f64_at(fr + 32) + f2 * _f64_at(fr + 56))
        az = s * (f1 * _f64_at(fr + 40) + f2 * _f64_at(fr + 64))
        bx = s * (f3 * _f64_at(fr) + f4 * _f64_at(fr + 24) + f5 * _f64_at(fr + 48))
        by = s * (f3 * _f64_at(fr + 8) + f4 * _f64_at(fr + 32) + f5 * _f64_at(fr + 56))
        bz = s * (f3 * _f64_at(fr + 16) + f4 * _f64_at(fr + 40) + f5 * _f64_at(fr + 64))
        cp = base + ip[_P_POS]
        rx, ry, rz = _f64_at(cp) - px, _f64_at(cp + 8) - py, _f64_at(cp + 16) - pz
        ux = vx + (oy * rz - oz * ry)
        uy = vy + (oz * rx - ox * rz)
        uz = vz + (ox * ry - oy * rx)
        power += (ax * ux + ay * uy + az * uz) + (bx * ox + by * oy + bz * oz)
        n += f0
        fx += ax
        fy += ay
        fz += az
        tx += bx
        ty += by
        tz += bz
    ball_x = ip[_P_BALLZ]  # the ball's centre, x y z
    gap = _f64_at(ball_x + 16) - fp[0]
    kz = m6 * fp[1] + m7 * fp[2] + m8 * fp[3]
    # the slip of the ball's lowest point, v + omega x (centre - R z - origin)
    rx, ry, rz = _f64_at(ball_x) - px, _f64_at(ball_x + 8) - py, gap - pz
    slip_x = vx + (oy * rz - oz * ry)
    slip_y = vy + (oz * rx - ox * rz)
    wi[r, _W_PASSES] += 1
    if code:
        trail = wf[r, _W_TRAIL]
        wf[r, _W_TRAIL] = -np.inf
        wi[r, _W_TOUCH] |= code
        wi[r, _W_TOUCH_PASSES] += 1
        if wi[r, _W_FIRST] < 0:
            wi[r, _W_FIRST] = j
        last = wi[r, _W_LAST]
        if last >= 0 and j - last - 1 > wi[r, _W_INNER]:
            wi[r, _W_INNER] = j - last - 1
            wi[r, _W_INNER_START] = last + 1
            wf[r, _W_INNER_GAP] = trail
        wi[r, _W_LAST] = j
        if code & 2 and wi[r, _W_OTHER] < 0:
            wi[r, _W_OTHER] = j
    else:
        if carry[0] != 0.0:
            wi[r, _W_LIFTS] += 1
        wf[r, _W_TRAIL] = max(wf[r, _W_TRAIL], gap)
        if wi[r, _W_FIRST] < 0:
            wf[r, _W_LEAD] = max(wf[r, _W_LEAD], gap)
    carry[0] = 1.0 if code else 0.0
    if carry[1] > 0.0 and kz <= 0.0 and wi[r, _W_FLIP] < 0:
        wi[r, _W_FLIP] = j
    carry[1] = kz
    wf[r, _W_GAP] = max(wf[r, _W_GAP], gap)
    wf[r, _W_GAP_MIN] = min(wf[r, _W_GAP_MIN], gap)
    wf[r, _W_DEPTH] = max(wf[r, _W_DEPTH], depth)
    wf[r, _W_SLIP_X] += n * slip_x
    wf[r, _W_SLIP_Y] += n * slip_y
    wf[r, _W_N] += n
    wf[r, _W_FX] += fx
    wf[r, _W_FY] += fy
    wf[r, _W_FZ] += fz
    wf[r, _W_TX] += tx
    wf[r, _W_TY] += ty
    wf[r, _W_TZ] += tz
    wf[r, _W_POWER] += power
    law = ip[_P_LAW]
    if law >= 0:
        wf[r, _W_LFX] += _f64_at(law)
        wf[r, _W_LFY] += _f64_at(law + 8)
        wf[r, _W_LPOWER] += _f64_at(law + 24)


if (INT_FIELDS.index("flip"), FLOAT_FIELDS.index("law_power_sum"),
        FLOAT_FIELDS.index("slip_ny_sum"), len(FLOAT_FIELDS)) != (
        _W_FLIP, _W_LPOWER, _W_SLIP_Y, 19):  # pragma: no cover - one list edited alone
    raise RuntimeError("stepper's window columns are not worker/windows.py's")

_accumulate_jit = nb.njit(inline="always", error_model="numpy", nogil=True,
                          cache=True)(_accumulate)

_ADVANCE_SIG = types.void(
    types.int64[::1],  # fns: function addresses
    _I8, _I8,  # model, data
    _I8, _I8, types.boolean,  # steps, integrator, first
    _I8, _I8, _I8,  # row0, nrows, state spec
    types.float64[:, ::1], types.float64[:, ::1], types.int32[:, ::1],  # state, con, warn
    _I8, _I8, _I8,  # addresses: qfrc_constraint, warning numbers, their stride
    types.int64[::1], types.float64[::1], types.int64[::1],  # ip, fp (R, axis), geom bodies
    types.int64[:, ::1], types.float64[:, ::1],  # the windows: integers, floats
    types.float64[::1], types.float64[::1],  # carry (touched, k_z at the last pass), scratch
    types.float64[::1],  # the free joint's qpos and qvel before a whole mj_step (13)
)


def _advance(fns, m, d, steps, integ, first, row0, nrows, spec, state, con, warn,
             con_addr, warn_addr, warn_stride, ip, fp, gbody, wi, wf, carry,
             f6, before):  # pragma: no cover - compiled
    nv = con.shape[1]
    nw = warn.shape[1]
    split = integ != INTEG_STEP
    qp, qv = ip[_P_QPOS], ip[_P_QVEL]
    bp, bv = before.ctypes.data, before.ctypes.data + 56
    for r in range(row0, row0 + nrows):
        if r > row0 or not first:  # step from row r - 1 to row r, each step's pass added
            for j in range(1, steps + 1):
                if integ == INTEG_RK4:
                    _c_ppi(fns[_F_RK], m, d, 4)  # the rest of the step its pass began
                elif integ == INTEG_PLAIN:
                    _c_pp(fns[_F_PLAIN], m, d)
                else:  # whole: its pass is at the state before it, kept for the window
                    for q in range(7):
                        before[q] = _f64_at(qp + 8 * q)
                    for q in range(6):
                        before[7 + q] = _f64_at(qv + 8 * q)
                    _c_pp(fns[_F_STEP], m, d)
                if j == steps:
                    _c_pppi(fns[_F_GETSTATE], m, d, state[r].ctypes.data, spec)
                    for q in range(nv):
                        con[r, q] = _f64_at(con_addr + 8 * q)
                    for q in range(nw):
                        warn[r, q] = _i32_at(warn_addr + warn_stride * q)
                if split:  # mj_step's own start: its forward pass at the new state
                    _c_pp(fns[_F_CHECKPOS], m, d)
                    _c_pp(fns[_F_CHECKVEL], m, d)
                    _c_pp(fns[_F_FORWARD], m, d)
                    _c_pp(fns[_F_CHECKACC], m, d)
                    _accumulate_jit(fns, m, d, ip, fp, gbody, wi, wf, carry, f6, r, j, qp, qv)
                elif r > 1 or j > 1:  # the step's own pass, at the state before it (the
                    # first step's is the start's, row 0's already)
                    _accumulate_jit(fns, m, d, ip, fp, gbody, wi, wf, carry, f6, r, j - 1,
                                    bp, bv)
        else:
            _c_pppi(fns[_F_GETSTATE], m, d, state[r].ctypes.data, spec)
            for q in range(nv):
                con[r, q] = _f64_at(con_addr + 8 * q)
            for q in range(nw):
                warn[r, q] = _i32_at(warn_addr + warn_stride * q)
            if split:
                _c_pp(fns[_F_CHECKPOS], m, d)
                _c_pp(fns[_F_CHECKVEL], m, d)
                _c_pp(fns[_F_FORWARD], m, d)
                _c_pp(fns[_F_CHECKACC], m, d)
            _accumulate_jit(fns, m, d, ip, fp, gbody, wi, wf, carry, f6, r, 0, qp, qv)


@functools.cache
def _compiled_advance():
    """:func:`_advance` compiled (or loaded from numba's disk cache) on first use."""
    return nb.njit(_ADVANCE_SIG, cache=True, error_model="numpy", nogil=True)(_advance)


@functools.cache
def _library() -> ctypes.CDLL:
    """The libmujoco the Python bindings load (the same file: one library in the process)."""
    folder = os.path.dirname(mujoco.__file__)
    paths = sorted(glob.glob(os.path.join(folder, "libmujoco.so*"))
                   + glob.glob(os.path.join(folder, "libmujoco*.dylib")))
    if not paths:
        raise OSError(f"no libmujoco next to the bindings in {folder}")
    return ctypes.CDLL(paths[0])


def _function_addresses() -> np.ndarray:
    lib = _library()
    return np.array([ctypes.cast(getattr(lib, name), ctypes.c_void_p).value
                     for name in _FUNCTIONS], dtype=np.int64)


_PROBE_XML = """<mujoco><option><flag warmstart="enable"/></option><worldbody>
  <geom type="plane" size="1 1 0.1"/>
  <body pos="0 0 0.09"><freejoint/><geom size="0.1"/></body>
  <body pos="0.5 0 0.09"><freejoint/><geom size="0.1"/></body>
  </worldbody></mujoco>"""


class ContactLayout:
    """Where an mjData keeps ncon and its contacts, and the contact structs' fields."""

    def __init__(self, ncon_offset: int, arena_offset: int, dtype: np.dtype) -> None:
        self.ncon_offset, self.arena_offset, self.dtype = ncon_offset, arena_offset, dtype


def _layout(data: mujoco.MjData) -> tuple[int, int]:
    """(offset of ncon, offset of the arena pointer) in ``data``'s struct (docs/design.md)."""
    timer = data.timer.duration
    ncon = timer.ctypes.data + timer.strides[0] * timer.shape[0] - data._address
    energy = data.energy
    arena = energy.ctypes.data + 2 * energy.itemsize + ctypes.sizeof(ctypes.c_void_p)
    return ncon, arena - data._address


@functools.cache
def _checked() -> tuple[ContactLayout | None, str]:
    """The layout, checked on probe data against the bindings' values; or (None, why not)."""
    try:
        lib = _library()
        _function_addresses()
    except (OSError, AttributeError) as exc:
        return None, f"libmujoco's C API not reachable ({exc})"
    model = mujoco.MjModel.from_xml_string(_PROBE_XML)
    data = mujoco.MjData(model)
    ncon_off, arena_off = _layout(data)
    fields = ("dist", "pos", "frame", "geom")
    dtype = None
    # ncon 1, 0, 2 and 3 (the balls on the table and touching each other)
    for z1, z2, x2 in ((0.09, 1.0, 0.5), (1.0, 1.0, 0.5), (0.09, 0.09, 0.5), (0.09, 0.09, 0.19)):
        mujoco.mj_resetData(model, data)
        data.qpos[2], data.qpos[9], data.qpos[7] = z1, z2, x2
        mujoco.mj_forward(model, data)
        if ctypes.c_int.from_address(data._address + ncon_off).value != data.ncon:
            return None, "mjData.ncon is not where mjdata.h puts it"
        if not data.ncon:
            continue
        c = data.contact
        arena = ctypes.c_void_p.from_address(data._address + arena_off).value
        if c.dist.ctypes.data != arena:
            return None, "the contacts are not at the start of mjData's arena"
        views = [getattr(c, name) for name in fields]
        layout = np.dtype({"names": list(fields),
                           "formats": [("f8", ()), ("f8", (3,)), ("f8", (9,)), ("i4", (2,))],
                           "offsets": [v.ctypes.data - arena for v in views],
                           "itemsize": c.dist.strides[0]})
        if dtype is not None and layout != dtype:
            return None, "the contact struct's layout is not stable"
        dtype = layout
        raw = np.frombuffer(ctypes.string_at(arena, data.ncon * layout.itemsize), dtype=layout)
        for name, view in zip(fields, views, strict=True):
            if not np.array_equal(raw[name], view):
                return None, f"mjContact.{name} is not where the bindings read it"
    # the library is the bindings' own (callbacks and the warning handler are its globals):
    # the file is loaded already (RTLD_NOLOAD), and it sees the bindings' warning handler
    try:
        ctypes.CDLL(lib._name, mode=os.RTLD_NOLOAD | os.RTLD_LAZY)
    except OSError:
        return None, "the ctypes libmujoco is not the one the bindings loaded"
    if mujoco.get_mju_user_warning() is not None and not ctypes.c_void_p.in_dll(
            lib, "mju_user_warning").value:
        return None, "the ctypes libmujoco is not the one the bindings use"
    return ContactLayout(ncon_off, arena_off, dtype), ""


def available() -> tuple[bool, str]:
    """Whether :func:`advance` can run in this process, and if not, why."""
    layout, why = _checked()
    return layout is not None, why


def load() -> bool:
    """Check the layout and compile (or load) the loop now, in this thread; True if usable.

    Call it before steppers are made on other threads: each of these is done once per
    process, and two threads doing it at once would do it twice.
    """
    if not available()[0]:
        return False
    _compiled_advance()
    return True


class CompiledStepper:
    """Steps one mjData of one model in :func:`_advance` and keeps what it records.

    Each sample's state, and its window: every step's forward pass added to it
    (:mod:`.worker.windows`).

    Args:
        model: The model.
        data: Its mjData (kept alive by this object).
        steps: Integration steps per sample interval.
        n_rows: Samples to hold.
        integrator: :data:`INTEG_RK4` or :data:`INTEG_PLAIN` (with ``plain``, the model's
            ``mj_Euler``/``mj_implicit``): ``mj_step`` taken apart, each step's forward pass
            done at the end of the step before and added to the window there; or
            :data:`INTEG_STEP`, whole ``mj_step`` calls, each step's pass (at the state
            before it) added after it.
        plain: The C name of the (m, d) integrator for :data:`INTEG_PLAIN`.
        spec: The ``mjtState`` of the state rows.
        top: Whose contacts the windows add, and what they read of it.
        law_index: Paper mode: where the callback leaves its last (Fx, Fy, N, power) in
            ``data.userdata``; None: no law.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, *, steps: int, n_rows: int,
                 integrator: int, plain: str = "mj_Euler", spec: int, top: WindowTop,
                 law_index: int | None = None) -> None:
        layout, why = _checked()
        if layout is None:
            raise RuntimeError(why)
        load()  # compiled or loaded before any clock runs
        self.model, self.data = model, data
        self.steps, self.integrator, self.spec = steps, integrator, int(spec)
        self.fns = _function_addresses()
        self.fns[_F_PLAIN] = ctypes.cast(getattr(_library(), plain), ctypes.c_void_p).value
        self.state = np.empty((n_rows, mujoco.mj_stateSize(model, spec)))
        self.con = np.empty((n_rows, model.nv))
        counters = data.warning.number
        self.warn = np.zeros((n_rows, counters.size), dtype=np.int32)
        self._warn_addr, self._warn_stride = counters.ctypes.data, counters.strides[0]
        self._con_addr = data.qfrc_constraint.ctypes.data
        self.ints, self.floats = new_windows(np, n_rows)
        offsets = layout.dtype.fields
        base = data._address
        self.ip = np.array([
            base + layout.ncon_offset, base + layout.arena_offset, layout.dtype.itemsize,
            offsets["dist"][1], offsets["pos"][1], offsets["frame"][1], offsets["geom"][1],
            top.body, top.ball, data.qpos.ctypes.data + 8 * top.qpos_adr,
            data.qvel.ctypes.data + 8 * top.dof_adr, data.xmat.ctypes.data + 72 * top.body,
            data.geom_xpos.ctypes.data + 24 * top.ball,
            -1 if law_index is None else data.userdata.ctypes.data + 8 * law_index],
            dtype=np.int64)
        self.fp = np.array([top.radius_m, *top.axis_body], dtype=np.float64)
        self.gbody = np.ascontiguousarray(model.geom_bodyid, dtype=np.int64)
        self.carry = np.array([1.0, np.nan])  # a run that starts without contact starts a gap
        self.f6 = np.zeros(6)
        self.before = np.zeros(13)

    def advance(self, row0: int, nrows: int, *, first: bool) -> None:
        """Record rows ``row0 .. row0 + nrows - 1``, stepping into each.

        With ``first`` it does not step into ``row0``: the data is at that row's state already
        (after a forward pass).
        """
        _compiled_advance()(
            self.fns, self.model._address, self.data._address, self.steps, self.integrator,
            first, row0, nrows, self.spec, self.state, self.con, self.warn, self._con_addr,
            self._warn_addr, self._warn_stride, self.ip, self.fp, self.gbody, self.ints,
            self.floats, self.carry, self.f6, self.before)
