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

#: ``rows`` written by :func:`advance` when it stopped because its contact buffers were full.
NEED_ROOM = -1

# integrator codes for the kernel
INTEG_STEP = 0  # no split: mj_step whole
INTEG_RK4 = 1  # mj_RungeKutta(m, d, 4)
INTEG_PLAIN = 2  # a (m, d) integrator: mj_Euler, mj_implicit

# slots of the function-address vector
_F_STEP, _F_FORWARD, _F_CHECKPOS, _F_CHECKVEL, _F_CHECKACC = 0, 1, 2, 3, 4
_F_RK, _F_PLAIN, _F_GETSTATE, _F_CONTACTFORCE, _F_SETSTATE, _F_FORWARDSKIP = 5, 6, 7, 8, 9, 10
_FUNCTIONS = ("mj_step", "mj_forward", "mj_checkPos", "mj_checkVel", "mj_checkAcc",
              "mj_RungeKutta", "mj_Euler", "mj_getState", "mj_contactForce", "mj_setState",
              "mj_forwardSkip")


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
def _c_ppii(typingctx, fn, a, b, c, e):
    """``fn(void* a, void* b, int c, int e)``."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        _emit(builder, "ppii", args[0], args[1:])
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
def _f64_put(typingctx, address, value):
    """Store the double ``value`` at ``address``."""
    sig = types.void(types.int64, types.float64)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.DoubleType().as_pointer())
        builder.store(args[1], ptr)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _i64_at(typingctx, address):
    """The 64-bit integer (a pointer) at ``address``."""
    sig = types.int64(types.int64)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.IntType(64).as_pointer())
        return builder.load(ptr)

    return sig, codegen


@intrinsic
def _u8_at(typingctx, address):
    """The byte at ``address``."""
    sig = types.uint8(types.int64)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.IntType(8).as_pointer())
        return builder.load(ptr)

    return sig, codegen


_I8 = types.int64
_ADVANCE_SIG = types.UniTuple(_I8, 3)(
    types.int64[::1],  # fns: function addresses
    _I8, _I8,  # model, data
    _I8, _I8, types.boolean, types.boolean,  # steps, integrator, first, resume
    _I8, _I8, _I8,  # row0, nrows, state spec
    types.float64[:, ::1], types.float64[:, ::1], types.int32[:, ::1],  # state, con, warn
    _I8, _I8, _I8,  # addresses: qfrc_constraint, warning numbers, their stride
    _I8, _I8, _I8,  # contacts (0: none), ncon address, arena-pointer address
    types.uint8[::1], types.float64[:, ::1], types.int64[:, ::1],  # contact bytes, forces, counts
    _I8, _I8,  # contacts used, counts used
)


def _advance(fns, m, d, steps, integ, first, resume, row0, nrows, spec, state, con, warn,
             con_addr, warn_addr, warn_stride, contact_size, ncon_addr, arena_addr,
             cbytes, cforce, counts, cused, nused):  # pragma: no cover - compiled
    nv = con.shape[1]
    nw = warn.shape[1]
    for r in range(row0, row0 + nrows):
        if resume and r == row0:  # row0 is recorded and its forward pass done: its contacts
            ncon = np.int64(_i32_at(ncon_addr))
            if cused + ncon > cforce.shape[0]:
                return r, cused, nused
            arena = _i64_at(arena_addr)
            start = cused * contact_size
            for b in range(ncon * contact_size):
                cbytes[start + b] = _u8_at(arena + b)
            for k in range(ncon):
                _c_ppip(fns[_F_CONTACTFORCE], m, d, k, cforce[cused + k].ctypes.data)
            counts[nused, 0] = r
            counts[nused, 1] = ncon
            cused += ncon
            nused += 1
            continue
        if r > row0 or not first:  # step from row r - 1 to row r
            if integ == INTEG_RK4:
                _c_ppi(fns[_F_RK], m, d, 4)  # the rest of the step the forward pass began
                for _ in range(steps - 1):
                    _c_pp(fns[_F_STEP], m, d)
            elif integ == INTEG_PLAIN:
                _c_pp(fns[_F_PLAIN], m, d)
                for _ in range(steps - 1):
                    _c_pp(fns[_F_STEP], m, d)
            else:
                for _ in range(steps):
                    _c_pp(fns[_F_STEP], m, d)
        _c_pppi(fns[_F_GETSTATE], m, d, state[r].ctypes.data, spec)
        for j in range(nv):
            con[r, j] = _f64_at(con_addr + 8 * j)
        for j in range(nw):
            warn[r, j] = _i32_at(warn_addr + warn_stride * j)
        if contact_size:
            # mj_step's own start: its forward pass at this row's state
            _c_pp(fns[_F_CHECKPOS], m, d)
            _c_pp(fns[_F_CHECKVEL], m, d)
            _c_pp(fns[_F_FORWARD], m, d)
            _c_pp(fns[_F_CHECKACC], m, d)
            ncon = np.int64(_i32_at(ncon_addr))
            if ncon > 0:
                if cused + ncon > cforce.shape[0]:
                    return r, cused, nused  # row r is recorded but not its contacts
                arena = _i64_at(arena_addr)  # d->arena: the contacts start there
                start = cused * contact_size
                for b in range(ncon * contact_size):
                    cbytes[start + b] = _u8_at(arena + b)
                for k in range(ncon):
                    _c_ppip(fns[_F_CONTACTFORCE], m, d, k, cforce[cused + k].ctypes.data)
                counts[nused, 0] = r
                counts[nused, 1] = ncon
                cused += ncon
                nused += 1
    return row0 + nrows, cused, nused


_PASSES_SIG = types.UniTuple(_I8, 3)(
    types.int64[::1], _I8, _I8,  # fns, model, scratch data
    _I8, _I8, _I8, _I8,  # row0, state spec, passes, skip stage of passes 2..
    types.float64[:, ::1], types.float64[:, ::1],  # state rows, qfrc_constraint rows
    _I8, _I8, types.float64[:, ::1],  # scratch qfrc_constraint, law outputs (-1: none), out
    _I8, _I8, _I8,  # contact size, ncon address, arena-pointer address
    types.uint8[::1], types.float64[:, ::1], types.int64[:, ::1], _I8, _I8,
)


def _passes(fns, m, d, row0, spec, passes, skip, state, con, con_addr, law_addr, law_out,
            contact_size, ncon_addr, arena_addr, cbytes, cforce, counts, cused,
            nused):  # pragma: no cover - compiled
    nv = con.shape[1]
    for r in range(row0, state.shape[0]):
        _c_pppi(fns[_F_SETSTATE], m, d, state[r].ctypes.data, spec)
        for j in range(nv):
            _f64_put(con_addr + 8 * j, con[r, j])
        _c_pp(fns[_F_FORWARD], m, d)
        for _ in range(passes - 1):
            _c_ppii(fns[_F_FORWARDSKIP], m, d, skip, 1)
        if law_addr >= 0:  # the callback's (Fx, Fy, power) of the last pass
            law_out[r, 0] = _f64_at(law_addr)
            law_out[r, 1] = _f64_at(law_addr + 8)
            law_out[r, 2] = _f64_at(law_addr + 24)
        ncon = np.int64(_i32_at(ncon_addr))
        if ncon > 0:
            if cused + ncon > cforce.shape[0]:
                return r, cused, nused  # this row again, with more room
            arena = _i64_at(arena_addr)
            start = cused * contact_size
            for b in range(ncon * contact_size):
                cbytes[start + b] = _u8_at(arena + b)
            for k in range(ncon):
                _c_ppip(fns[_F_CONTACTFORCE], m, d, k, cforce[cused + k].ctypes.data)
            counts[nused, 0] = r
            counts[nused, 1] = ncon
            cused += ncon
            nused += 1
    return state.shape[0], cused, nused


@functools.cache
def _compiled_passes():
    """:func:`_passes` compiled (or loaded from numba's disk cache) on first use."""
    return nb.njit(_PASSES_SIG, cache=True, error_model="numpy", nogil=True)(_passes)


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
    """Check the layout and compile (or load) both loops now, in this thread; True if usable.

    Call it before steppers are made on other threads: each of these is done once per
    process, and two threads doing it at once would do it twice.
    """
    if not available()[0]:
        return False
    _compiled_advance()
    _compiled_passes()
    return True


class CompiledStepper:
    """Steps one mjData of one model in :func:`_advance` and keeps what it records.

    Args:
        model: The model.
        data: Its mjData (kept alive by this object).
        steps: Integration steps per sample interval.
        n_rows: Samples to hold.
        integrator: :data:`INTEG_STEP` (whole ``mj_step`` calls, no contacts) or, to read each
            sample's contacts from the step's own forward pass, :data:`INTEG_RK4` or
            :data:`INTEG_PLAIN` (with ``plain``, the model's ``mj_Euler``/``mj_implicit``).
        plain: The C name of the (m, d) integrator for :data:`INTEG_PLAIN`.
        spec: The ``mjtState`` of the state rows.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, *, steps: int, n_rows: int,
                 integrator: int, plain: str = "mj_Euler", spec: int) -> None:
        layout, why = _checked()
        if layout is None:
            raise RuntimeError(why)
        load()  # both loops compiled or loaded before any clock runs
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
        self.layout = layout
        self.contacts = integrator != INTEG_STEP
        size = layout.dtype.itemsize
        self._csize = size if self.contacts else 0
        cap = 256 if self.contacts else 0
        self.cbytes = np.zeros(cap * size, dtype=np.uint8)
        self.cforce = np.zeros((cap, 6))
        self.counts = np.zeros((n_rows if self.contacts else 0, 2), dtype=np.int64)
        self.cused = self.nused = 0

    def _grow(self) -> None:
        cap = 2 * len(self.cforce)
        cbytes = np.zeros(cap * self.layout.dtype.itemsize, dtype=np.uint8)
        cbytes[:len(self.cbytes)] = self.cbytes
        cforce = np.zeros((cap, 6))
        cforce[:len(self.cforce)] = self.cforce
        self.cbytes, self.cforce = cbytes, cforce

    def advance(self, row0: int, nrows: int, *, first: bool) -> None:
        """Record rows ``row0 .. row0 + nrows - 1``, stepping into each.

        With ``first`` it does not step into ``row0``: the data is at that row's state already.
        """
        row, end, resume = row0, row0 + nrows, False
        while row < end:
            done, self.cused, self.nused = _compiled_advance()(
                self.fns, self.model._address, self.data._address, self.steps,
                self.integrator, first, resume, row, end - row, self.spec, self.state, self.con,
                self.warn, self._con_addr, self._warn_addr, self._warn_stride, self._csize,
                self.data._address + self.layout.ncon_offset,
                self.data._address + self.layout.arena_offset, self.cbytes, self.cforce,
                self.counts, self.cused, self.nused)
            if done == end:
                return
            # row ``done`` is recorded and its forward pass done, its contacts not copied
            self._grow()
            row, first, resume = done, True, True

    def contact_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(sample of each contact, the contact structs (layout dtype), forces (m, 6))."""
        counts = self.counts[:self.nused]
        rows = np.frombuffer(self.cbytes[:self.cused * self.layout.dtype.itemsize].tobytes(),
                             dtype=self.layout.dtype)
        return (np.repeat(counts[:, 0], counts[:, 1]), rows, self.cforce[:self.cused].copy())


def forward_passes(model: mujoco.MjModel, scratch: mujoco.MjData, state: np.ndarray,
                   con: np.ndarray, *, spec: int, passes: int, law_index: int | None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Forward passes at many states on one scratch mjData, in one compiled loop.

    For each row i: ``mj_setState(state[i], spec)``, ``qfrc_constraint = con[i]``, then
    ``mj_forward`` and ``passes - 1`` times ``mj_forwardSkip`` past the position stage (the
    same positions: only the forces change), then its contacts (as :class:`CompiledStepper`)
    and, if ``law_index`` is given, the three doubles of ``scratch.userdata`` at
    ``law_index``, ``+ 1`` and ``+ 3`` (the paper-mode callback's last Fx, Fy and power).

    Returns:
        (sample of each contact, the contact structs, forces (m, 6), law outputs (n, 3) or
        None).
    """
    layout, why = _checked()
    if layout is None:
        raise RuntimeError(why)
    kernel = _compiled_passes()
    fns = _function_addresses()
    n = len(state)
    size = layout.dtype.itemsize
    cap = max(256, 2 * n)
    cbytes, cforce = np.zeros(cap * size, dtype=np.uint8), np.zeros((cap, 6))
    counts = np.zeros((n, 2), dtype=np.int64)
    law_out = np.zeros((n, 3))
    law_addr = -1 if law_index is None else scratch.userdata.ctypes.data + 8 * law_index
    state = np.ascontiguousarray(state, dtype=np.float64)
    con = np.ascontiguousarray(con, dtype=np.float64)
    row = cused = nused = 0
    while True:
        row, cused, nused = kernel(
            fns, model._address, scratch._address, row, int(spec), passes,
            int(mujoco.mjtStage.mjSTAGE_POS), state, con, scratch.qfrc_constraint.ctypes.data,
            law_addr, law_out, size, scratch._address + layout.ncon_offset,
            scratch._address + layout.arena_offset, cbytes, cforce, counts, cused, nused)
        if row == n:
            break
        cap *= 2  # row ``row`` did not fit: grow, and do it again from its state
        more_bytes, more_force = np.zeros(cap * size, dtype=np.uint8), np.zeros((cap, 6))
        more_bytes[:len(cbytes)], more_force[:len(cforce)] = cbytes, cforce
        cbytes, cforce = more_bytes, more_force
    counts = counts[:nused]
    rows = np.frombuffer(cbytes[:cused * size].tobytes(), dtype=layout.dtype)
    return (np.repeat(counts[:, 0], counts[:, 1]), rows, cforce[:cused].copy(),
            None if law_index is None else law_out)
