"""A run records states and windows, and computes the rest afterwards.

A run (:func:`mujoco_runner.run.run_compiled`) records the state at each sample and adds every
step's forward pass to its sample's window (:mod:`mujoco_runner.worker.windows`), in
:mod:`mujoco_runner.stepper`'s compiled loop or from Python
(:class:`~mujoco_runner.worker.windows.WindowAccumulator`); :func:`result_from_samples` computes
the contacts, forces, checks and the table afterwards. The states are compared exactly (``==``
on float64): the same C calls on the same states give the same bits, and any tolerance would
hide a change of what is stepped. So are the windows' integers, and their maxima and minimum
(each picks one of the same doubles). Their sums are sums of products: the compiled loop, the Python
loop and the oracle here (a per-pass contact reader, the old per-sample one) compute the same
exact value from the same doubles, the oracle with numpy's matrix products (BLAS may sum in
another order or fuse a multiply-add: it differs between machines and builds) and the loops
each as its compiler makes it; so they are compared within a rounding bound derived from the
same sums of absolute values (:func:`_window_gamma`, :func:`_assert_windows`). Where the two
loops only add the same doubles in the same order they are compared exactly.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tests.conftest import mujoco_plan
from tippetop.models.frames import quat_to_mat
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.mujoco_runner import checks, results, run, stepper, stepping
from tippetop.mujoco_runner.friction_callback import PaperFriction
from tippetop.mujoco_runner.model import TopModel, load_top
from tippetop.mujoco_runner.record import STATE_SPEC, SampleRecord, WindowRecord
from tippetop.mujoco_runner.settings import build_model
from tippetop.mujoco_runner.state import initial_qpos_qvel
from tippetop.mujoco_runner.worker import windows
from tippetop.mujoco_runner.worker.windows import FLOAT_FIELDS, INT_FIELDS, F, I

FIG3_TOP = TopParams.from_ratios(1.0, 0.1)
FIG3_INIT = InitialState(theta0=0.1, n0=100.0)
LAW = FrictionParams(law="modified_coulomb", mu=0.1, Lambda_mps=0.01)
CAPSULE = Path(__file__).resolve().parents[2] / "examples" / "capsule_stem_top.xml"

pytestmark = pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")


def _native_plan(integrator: str = "RK4", dt: float = 2e-4, *more: str):
    """The Fig. 3 top with MuJoCo's own friction (condim 3, mu 0.1, the scene's contact)."""
    return mujoco_plan("mujoco.friction='native'", "mujoco.calibrated=false", "mujoco.condim=3",
                       "mujoco.mu=0.1", f"mujoco.integrator={integrator!r}",
                       f"mujoco.timestep_s={dt!r}", *more)


def _paper_plan(dt: float = 2e-5, *more: str):
    """The Fig. 3 top in paper mode (its stiff contact)."""
    return mujoco_plan("mujoco.friction='paper'", f"mujoco.timestep_s={dt!r}", *more)


def _native(integrator: str = "RK4", dt: float = 2e-4):
    return build_model(_native_plan(integrator, dt))


def _paper(dt: float = 2e-5):
    return build_model(_paper_plan(dt))


def _start(tm, init=FIG3_INIT) -> mujoco.MjData:
    data = mujoco.MjData(tm.model)
    data.qpos[:7], data.qvel[:6] = initial_qpos_qvel(tm, init)
    return data


def _capsule_start() -> tuple[TopModel, mujoco.MjData]:
    """The capsule-stem top as its file says (its own Euler at 0.5 ms), at its keyframe."""
    tm = load_top(CAPSULE)
    data = mujoco.MjData(tm.model)
    mujoco.mj_resetDataKeyframe(tm.model, data, 0)
    return tm, data


def _armed(tm: TopModel, data: mujoco.MjData, law: FrictionParams | None, stem=None):
    return (PaperFriction(tm, data, law, stem=stem) if law is not None
            else contextlib.nullcontext())


# --- mj_step taken apart, the compiled loop ---------------------------------------------------


@pytest.mark.parametrize("integrator", ["RK4", "Euler", "implicitfast", "implicit"])
def test_mj_step_taken_apart_is_mj_step(integrator: str) -> None:
    # the run reads each step's forward pass from the pass that begins the step, done at the
    # end of the step before: mj_step split into its checks, mj_forward and the integrator must
    # be mj_step exactly
    tm = _native(integrator)
    whole, split = _start(tm), _start(tm)
    finish = windows.integrator_call(mujoco, tm.model)
    assert finish is not None
    for _ in range(200):
        mujoco.mj_step(tm.model, whole, 5)
        for check in (mujoco.mj_checkPos, mujoco.mj_checkVel, mujoco.mj_forward,
                      mujoco.mj_checkAcc):
            check(tm.model, split)
        finish(tm.model, split)
        mujoco.mj_step(tm.model, split, 4)
    for field in ("qpos", "qvel", "qacc_warmstart", "qfrc_constraint", "time"):
        assert np.array_equal(getattr(whole, field), getattr(split, field)), field


def test_the_compiled_stepper_checks_its_layout() -> None:
    ok, why = stepper.available()
    assert ok, why  # on this MuJoCo the compiled loop must run; the Python loop is the fallback


# --- the oracle: each pass read on its own, the windows built from the passes -----------------


def _gamma(k: int) -> float:
    """gamma_k = k u / (1 - k u), u = 2**-53: the bound on k roundings in float64.

    A sum of products computed with k roundings along its deepest chain, in any order and
    with or without fused multiply-adds, is within gamma_k times the same sum of absolute
    values of the exact result (Higham, Accuracy and Stability, 3.1-3.5).
    """
    u = 2.0**-53
    return k * u / (1 - k * u)


def _window_gamma(steps: int) -> float:
    """The bound on one window's sums, each computed by two of the loops (hence the 2).

    Per pass and contact the deepest chain is the power: omega from xmat (3 roundings), the
    arm (1), the cross product and v + it (3), the friction force (the oracle's frame^T f
    less its normal part: 5), its dot product with v (3), the torque's (6 in all), their sum
    (1): 11; the sum over a pass's contacts (<= 4: 3): 14 per pass. The slip times N is
    shallower: N (3), the slip (omega 3, the arm to the lowest point 2, the cross product and
    v + it 3), their product (1): 12. The window's sum over its
    ``steps`` passes adds steps - 1. 16 + steps covers it: gamma_66 = 7.3e-15 of the scale
    for 50 steps. A change of what is computed (a contact lost, a sign, a frame) is order 1.
    """
    return 2 * _gamma(16 + steps)


#: The window's float columns that are maxima or a minimum (exact: each picks one of the same
#: doubles), and its sums, with the per-pass quantity each one adds (and its component).
EXTREMA = ("gap_max", "lead_gap", "trail_gap", "inner_gap", "gap_min", "depth_max")
SUMS = {"n_sum": ("n", None), "fx_sum": ("f", 0), "fy_sum": ("f", 1), "fz_sum": ("f", 2),
        "tx_sum": ("tau", 0), "ty_sum": ("tau", 1), "tz_sum": ("tau", 2),
        "power_sum": ("power", None), "law_fx_sum": ("law", 0), "law_fy_sum": ("law", 1),
        "law_power_sum": ("law", 2), "slip_nx_sum": ("slip_n", 0), "slip_ny_sum": ("slip_n", 1)}
assert set(EXTREMA) | set(SUMS) == set(FLOAT_FIELDS) and not set(EXTREMA) & set(SUMS)


class _Reader:
    """The oracle: the top's contacts at one forward pass, read on their own.

    The per-sample contact reader the run used before it summed windows (now read at every
    pass): normal force, friction force and torque on the top, the friction power, which of
    the top's geoms touch and the deepest penetration, the ball's gap and the axis' k_z, the
    slip of the ball's lowest point (x, y) times the normal force; beside the sums the same
    expressions evaluated on absolute values (the scale of their rounding).
    Its arithmetic is its own (numpy's matrix products, the force less its normal part); its
    inputs are MuJoCo's (the contacts, mj_contactForce, the body's xmat: the rotation is
    checked against the quaternion's once per pass).
    """

    def __init__(self, top_model: TopModel, law_index: int | None = None, *,
                 consistent: bool = True) -> None:
        self.model = top_model.model
        self.consistent = consistent  # the body's rotation is its quaternion's
        self.body = top_model.body_id
        self.ball = top_model.ball_geom_id
        self.R = float(self.model.geom_size[self.ball, 0])  # the ball's own radius
        assert self.R == top_model.top.R_m
        self.axis = np.asarray(top_model.axis_body, dtype=float)
        self.qpos_adr, self.dof_adr = top_model.qpos_adr, top_model.dof_adr
        self.law_index = law_index
        self._f6 = np.zeros(6)
        self.rows: dict[str, list] = {k: [] for k in _PASS_KEYS}

    def read(self, data: mujoco.MjData) -> None:
        """Read the last forward pass of ``data`` as the next pass."""
        N, F, tau, power = 0.0, np.zeros(3), np.zeros(3), 0.0
        N_abs, F_abs, tau_abs, power_abs = 0.0, np.zeros(3), np.zeros(3), 0.0
        touching, depth = 0, 0.0
        qa, va = self.qpos_adr, self.dof_adr
        rot = data.xmat[self.body].reshape(3, 3)  # its k_z: the sign is what counts (a k_z
        # within rounding of 0 could read another sign than the loops': ~1e-16 a pass)
        # the body's rotation is the free joint's quaternion's (MuJoCo normalises it first)
        assert not self.consistent or np.all(
            np.abs(rot - quat_to_mat(data.qpos[qa + 3:qa + 7])) <= 1e-14)
        origin, v_origin = data.qpos[qa:qa + 3], data.qvel[va:va + 3]
        omega_local = data.qvel[va + 3:va + 6]
        omega = rot @ omega_local
        omega_abs = np.abs(rot) @ np.abs(omega_local)
        geoms, frames = data.contact.geom, data.contact.frame
        for i in range(data.ncon):
            b1, b2 = self.model.geom_bodyid[geoms[i]]
            if self.body not in (b1, b2):
                continue
            touching |= 1 if self.ball in geoms[i] else 2
            depth = max(depth, -float(data.contact.dist[i]))
            mujoco.mj_contactForce(self.model, data, i, self._f6)
            frame = frames[i].reshape(3, 3)  # rows: normal (geom1 -> geom2), tangents
            sign = 1.0 if b2 == self.body else -1.0  # the force acts on geom2 along +normal
            force = sign * (frame.T @ self._f6[:3])
            normal = sign * frame[0]
            N += self._f6[0]
            friction = force - self._f6[0] * normal
            torque = sign * (frame.T @ self._f6[3:])
            F += friction
            tau += torque
            arm = data.contact.pos[i] - origin
            v_point = v_origin + np.cross(omega, arm)
            power += float(friction @ v_point + torque @ omega)
            f_abs = np.abs(frame).T @ np.abs(self._f6[:3]) + abs(self._f6[0]) * np.abs(frame[0])
            t_abs = np.abs(frame).T @ np.abs(self._f6[3:])
            a = np.abs(data.contact.pos[i]) + np.abs(origin)  # arm = pos - origin
            v_abs = np.abs(v_origin) + _cross_abs(omega_abs, a)
            N_abs += abs(self._f6[0])
            F_abs += f_abs
            tau_abs += t_abs
            power_abs += float(f_abs @ v_abs + t_abs @ omega_abs)
        law = np.zeros(3)
        if self.law_index is not None:
            u = data.userdata[self.law_index:self.law_index + 4]
            law = np.array([u[0], u[1], u[3]])  # Fx, Fy, (N), the power
        centre = data.geom_xpos[self.ball]
        gap = float(centre[2]) - self.R  # the ball's centre less R
        # the slip of the ball's lowest point (its centre less R along z) times N
        lowest = centre - np.array([0.0, 0.0, self.R])
        slip = v_origin + np.cross(omega, lowest - origin)
        slip_abs = np.abs(v_origin) + _cross_abs(
            omega_abs, np.abs(centre) + np.array([0.0, 0.0, self.R]) + np.abs(origin))
        row = {"code": touching, "depth": depth, "gap": gap, "kz": float((rot @ self.axis)[2]),
               "n": N, "f": F, "tau": tau, "power": power,
               "law": law, "slip_n": N * slip[:2], "n_abs": N_abs, "f_abs": F_abs,
               "tau_abs": tau_abs, "power_abs": power_abs, "law_abs": np.abs(law),
               "slip_n_abs": N_abs * slip_abs[:2]}
        for key, value in row.items():
            self.rows[key].append(value)

    def passes(self) -> dict[str, np.ndarray]:
        """Every pass read so far, as arrays (pass p at row p)."""
        return {k: np.array(v) for k, v in self.rows.items()}


_PASS_KEYS = ("code", "depth", "gap", "kz", "n", "f", "tau", "power", "law", "slip_n", "n_abs",
              "f_abs", "tau_abs", "power_abs", "law_abs", "slip_n_abs")


def _cross_abs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The cross product's terms on absolute values: its rounding's scale (a, b >= 0)."""
    return np.array([a[1] * b[2] + a[2] * b[1], a[2] * b[0] + a[0] * b[2],
                     a[0] * b[1] + a[1] * b[0]])


def _passes(code, gap, kz=None, depth=None) -> dict[str, np.ndarray]:
    """A pass sequence of its own (no forces): the contact codes, gaps, k_z, depths."""
    code = np.asarray(code, dtype=np.int64)
    P = len(code)
    out = {"code": code, "gap": np.asarray(gap, dtype=float),
           "kz": np.ones(P) if kz is None else np.asarray(kz, dtype=float),
           "depth": np.zeros(P) if depth is None else np.asarray(depth, dtype=float)}
    for key in ("n", "power", "n_abs", "power_abs"):
        out[key] = np.zeros(P)
    for key in ("f", "tau", "law", "f_abs", "tau_abs", "law_abs"):
        out[key] = np.zeros((P, 3))
    for key in ("slip_n", "slip_n_abs"):
        out[key] = np.zeros((P, 2))
    return out


def _window_passes(r: int, steps: int, whole: bool = False) -> np.ndarray:
    """The run's pass numbers in window r: pass 0 in row 0, ((r-1) steps, r steps] in row r.

    ``whole``: ``mj_step`` called whole, each step's pass (at the state before it) added
    after it: [(r-1) steps, r steps) in row r, but pass 0 (row 0's) not again in row 1. Pass
    p is at offset p - (r-1) steps in row r > 0 either way (at t = p dt).
    """
    if r == 0:
        return np.array([0])
    if whole:
        return np.arange(max((r - 1) * steps, 1), r * steps)
    return np.arange((r - 1) * steps + 1, r * steps + 1)


def _row_of(p: int, steps: int) -> int:
    """The window that holds pass p."""
    return 0 if p == 0 else -(-p // steps)


def _top(values) -> float:
    """The largest of ``values``; -inf: none."""
    return float(np.max(values)) if len(values) else -math.inf


def _bottom(values) -> float:
    """The smallest of ``values``; +inf: none."""
    return float(np.min(values)) if len(values) else math.inf


def _expected_windows(p: dict[str, np.ndarray], steps: int, whole: bool = False
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(ints, floats, scale)``: the windows of a pass sequence, built from the whole list.

    Written from the spec (worker/windows.py's docstring) window by window, with the whole
    sequence in view, not as the accumulators' one-pass state machine; ``scale``: each sum's
    sum of absolute values (zero for the extrema). ``whole``: the passes of whole
    ``mj_step`` calls (:func:`_window_passes`; the pass at the last sample's state is
    never done).
    """
    code = np.asarray(p["code"])
    P = len(code)
    later = P - (0 if whole else 1)  # the passes after row 0's
    assert later % steps == 0
    n = 1 + later // steps
    touching = code != 0
    # a lift: a pass without contact after one with contact; the run's first pass counts
    lift = ~touching & np.concatenate(([True], touching[:-1]))
    kz = p["kz"]
    flip = np.concatenate(([False], (kz[:-1] > 0) & (kz[1:] <= 0)))
    ints = np.zeros((n, len(INT_FIELDS)), dtype=np.int64)
    floats = np.zeros((n, len(FLOAT_FIELDS)))
    scale = np.zeros_like(floats)
    for r in range(n):
        idx = _window_passes(r, steps, whole)
        off = idx if r == 0 else idx - (r - 1) * steps
        gap = p["gap"][idx]
        t = off[touching[idx]]  # the offsets of the passes with contact
        wi, wf = ints[r], floats[r]
        wi[I["passes"]] = len(idx)
        wi[I["touch"]] = np.bitwise_or.reduce(code[idx])
        wi[I["touch_passes"]] = len(t)
        wi[I["first_touch"]] = t[0] if len(t) else -1
        wi[I["last_touch"]] = t[-1] if len(t) else -1
        # the stretches between two touches of the window: the longest, the first of equals
        inner = [(b - a - 1, a + 1) for a, b in zip(t[:-1], t[1:], strict=True) if b - a > 1]
        if inner:
            length = max(x[0] for x in inner)
            start = next(s for k, s in inner if k == length)
            wi[I["inner_free"]], wi[I["inner_start"]] = length, start
            wf[F["inner_gap"]] = _top(gap[(off >= start) & (off < start + length)])
        else:
            wi[I["inner_free"]], wi[I["inner_start"]] = 0, -1
            wf[F["inner_gap"]] = -math.inf
        wi[I["lifts"]] = int(lift[idx].sum())
        other = off[(code[idx] & windows.OTHER) != 0]
        wi[I["first_other"]] = other[0] if len(other) else -1
        flips = off[flip[idx]]
        wi[I["flip"]] = flips[0] if len(flips) else -1
        wf[F["gap_max"]] = _top(gap)
        wf[F["gap_min"]] = _bottom(gap)
        wf[F["lead_gap"]] = _top(gap[off < t[0]] if len(t) else gap)
        wf[F["trail_gap"]] = _top(gap[off > t[-1]] if len(t) else gap)
        wf[F["depth_max"]] = max(0.0, _top(p["depth"][idx]))
        for name, (key, col) in SUMS.items():
            values = p[key][idx] if col is None else p[key][idx, col]
            absolute = p[f"{key}_abs"][idx] if col is None else p[f"{key}_abs"][idx, col]
            wf[F[name]] = math.fsum(values)  # exact, then rounded once
            scale[r, F[name]] = math.fsum(absolute)
    return ints, floats, scale


def _assert_windows(got: WindowRecord, ints: np.ndarray, floats: np.ndarray,
                    scale: np.ndarray, steps: int, what: str) -> None:
    """``got`` is these windows: integers and extrema exact, sums within the rounding bound."""
    assert got.ints.shape == ints.shape, what
    bad = np.argwhere(got.ints != ints)
    assert not bad.size, (what, [(int(r), INT_FIELDS[c], int(got.ints[r, c]), int(ints[r, c]))
                                 for r, c in bad[:5]])
    for name in EXTREMA:
        a, b = got.float_column(name), floats[:, F[name]]
        assert np.array_equal(a, b), (what, name, np.flatnonzero(a != b)[:5])
    bound = _window_gamma(steps) * scale
    for name in SUMS:
        k = F[name]
        off = np.abs(got.floats[:, k] - floats[:, k]) > bound[:, k]
        assert not off.any(), (what, name, np.flatnonzero(off)[:5])


def _by_hand(tm: TopModel, data: mujoco.MjData, steps: int, n_intervals: int,
             law_index: int | None = None) -> tuple[SampleRecord, dict[str, np.ndarray]]:
    """A run stepped one step at a time, mj_step taken apart, as SampleRecord's contract says.

    Two forward passes at the start (row 0's state after them), then each step's pass at the
    end of the step before it (row 0's window: the pass at the initial state), each added to
    its window with :class:`~.worker.windows.WindowAccumulator` and read by the oracle
    (:class:`_Reader`). Returns the record and every pass the oracle read.
    """
    model = tm.model
    finish = windows.integrator_call(mujoco, model)
    assert finish is not None
    u = data.userdata

    def law() -> tuple[float, float, float]:
        return float(u[law_index]), float(u[law_index + 1]), float(u[law_index + 3])

    acc = windows.WindowAccumulator(mujoco, np, model, data, stepping.window_top(tm),
                                    None if law_index is None else law)
    ints, floats = windows.new_windows(np, n_intervals + 1)
    reader = _Reader(tm, law_index)
    size = mujoco.mj_stateSize(model, STATE_SPEC)
    state = np.empty((n_intervals + 1, size))
    con = np.empty((n_intervals + 1, model.nv))
    warn = np.empty((n_intervals + 1, data.warning.number.size), dtype=np.int32)

    def sample(i: int) -> None:
        mujoco.mj_getState(model, data, state[i], STATE_SPEC)
        con[i], warn[i] = data.qfrc_constraint, data.warning.number

    def begin() -> None:
        for check in (mujoco.mj_checkPos, mujoco.mj_checkVel, mujoco.mj_forward,
                      mujoco.mj_checkAcc):
            check(model, data)

    mujoco.mj_forward(model, data)
    mujoco.mj_forward(model, data)
    sample(0)
    begin()
    acc.add(ints, floats, 0, 0)
    reader.read(data)
    for i in range(1, n_intervals + 1):
        for j in range(1, steps + 1):
            finish(model, data)
            if j == steps:
                sample(i)
            begin()
            acc.add(ints, floats, i, j)
            reader.read(data)
    nq, nv = model.nq, model.nv
    record = SampleRecord(time=state[:, 0], qpos=state[:, 1:1 + nq],
                          qvel=state[:, 1 + nq:1 + nq + nv],
                          qacc_warmstart=state[:, 1 + nq + nv:], qfrc_constraint=con,
                          windows=WindowRecord(ints, floats), warnings=warn,
                          path="by hand")
    return record, reader.passes()


STATE_FIELDS = ("time", "qpos", "qvel", "qacc_warmstart", "qfrc_constraint", "warnings")


def _recorded(tm: TopModel, data: mujoco.MjData, steps: int, n_intervals: int, *,
              compiled: bool, law_index: int | None = None) -> SampleRecord:
    mujoco.mj_forward(tm.model, data)
    rec, failure, _ = stepping.step_and_record(tm.model, data, steps, n_intervals, None,
                                               top=stepping.window_top(tm),
                                               law_index=law_index, compiled=compiled)
    assert failure is None
    return rec


# --- the loops against each other and against the oracle ---------------------------------------


@pytest.mark.parametrize("mode", ["paper", "native"])
def test_compiled_and_python_loops_record_the_same(mode: str) -> None:
    # native: condim 6, so the windows add torsional and rolling friction torques too
    tm = _paper() if mode == "paper" else build_model(_native_plan("RK4", 2e-4, "mujoco.condim=6"))
    law = LAW if mode == "paper" else None
    index = stepping.law_index(tm.model, law)
    steps, n_intervals = (50, 300) if mode == "paper" else (5, 300)
    records = []
    for compiled in (True, False):
        data = _start(tm)
        with _armed(tm, data, law):
            records.append(_recorded(tm, data, steps, n_intervals, compiled=compiled,
                                     law_index=index))
    data = _start(tm)
    with _armed(tm, data, law):
        hand, passes = _by_hand(tm, data, steps, n_intervals, index)
    a, b = records
    assert (a.path, b.path) == ("compiled stepper", "plain loop")
    assert len(a) == len(b) == n_intervals + 1
    for field in STATE_FIELDS:  # the same steps: the same bits, and as the contract says
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
        assert np.array_equal(getattr(a, field), getattr(hand, field)), field
    ints, floats, scale = _expected_windows(passes, steps)
    for rec in (a, b, hand):
        _assert_windows(rec.windows, ints, floats, scale, steps, rec.path)
    # the two loops against each other: the same expressions of the same doubles, so within
    # the bound of each against the exact value; the additions of the same doubles in the same
    # order (N, the law's copies: no product to fuse, no order to change) are the same bits
    _assert_windows(a.windows, b.windows.ints, b.windows.floats, scale, steps, "loops")
    for name in ("n_sum", "law_fx_sum", "law_fy_sum", "law_power_sum"):
        assert np.array_equal(a.windows.float_column(name), b.windows.float_column(name)), name
    w = a.windows
    assert (w.int_column("passes") == [1] + [steps] * n_intervals).all()
    if mode == "native":  # the ball touches in most windows (it hops), with friction
        assert (w.int_column("touch") == windows.BALL).sum() >= 0.8 * n_intervals
        assert np.abs(w.float_column("fx_sum")).max() > 0 and w.float_column("n_sum").max() > 0
        assert np.abs(w.floats[:, F["tx_sum"]:F["tz_sum"] + 1]).max(axis=0).min() > 0
        assert not w.float_column("law_fx_sum").any()
    else:  # the law acted, and the frictionless contact none
        assert np.abs(w.float_column("law_fx_sum")).max() > 0
        assert np.abs(w.float_column("law_power_sum")).max() > 0


@pytest.mark.parametrize("integrator", [
    "Euler", "implicitfast",
    # mj_RungeKutta ends with its last stage's forward pass in the mjData (its kinematics and
    # contacts at an intermediate state), which the loops read as the step's own pass
    pytest.param("RK4", marks=pytest.mark.xfail(
        strict=True, raises=AssertionError,
        reason="after a whole mj_step with RK4 the mjData holds its last stage's pass"))])
def test_whole_mj_step_loops_record_the_same(integrator: str) -> None:
    # where mj_step does more after its forward pass (here its forward-inverse comparison)
    # both loops call it whole and add its pass (at the state before the step, with the
    # motion the top had there) after it: row r's window holds the passes at the states from
    # sample r - 1 (offset 0) to the one before sample r, but row 1's first (the start's,
    # row 0's already): no pass twice
    tm = _native(integrator)
    tm.model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_FWDINV)
    assert windows.integrator_call(mujoco, tm.model) is None
    assert stepping.integrator_split(tm.model) is None
    steps, n_intervals = 5, 200
    a, b = (_recorded(tm, _start(tm), steps, n_intervals, compiled=c) for c in (True, False))
    assert (a.path, b.path) == ("compiled stepper", "plain loop")
    for field in STATE_FIELDS:
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    # the oracle: each step's pass read at the state before the step (its own mj_forward
    # there is the pass mj_step begins with, and changes none of the steps: no callback reads
    # the last evaluation in native mode), then the step whole; beside it what the loops
    # read before the fix, the step's pass with the motion after it
    data = _start(tm)
    mujoco.mj_forward(tm.model, data)
    mujoco.mj_forward(tm.model, data)
    reader, after = _Reader(tm), _Reader(tm, consistent=False)
    for _ in range(steps * n_intervals):
        mujoco.mj_forward(tm.model, data)
        reader.read(data)
        mujoco.mj_step(tm.model, data)
        after.read(data)
    assert np.array_equal(data.qpos, a.qpos[-1]) and np.array_equal(data.qvel, a.qvel[-1])
    passes = reader.passes()
    ints, floats, scale = _expected_windows(passes, steps, whole=True)
    for rec in (a, b):
        _assert_windows(rec.windows, ints, floats, scale, steps, rec.path)
    w = a.windows
    assert (w.int_column("passes") == [1, steps - 1] + [steps] * (n_intervals - 1)).all()
    assert w.int_column("first_touch")[2:].min() == 0 and w.int_column("last_touch").max() < steps
    # every pass once: the windows' N is the passes' (row 0's pass at the start not again)
    assert math.fsum(w.float_column("n_sum")) == pytest.approx(math.fsum(passes["n"]),
                                                                rel=1e-12)
    assert w.float_column("n_sum")[1] == pytest.approx(math.fsum(passes["n"][1:steps]),
                                                       rel=1e-12)
    # the motion after the step (the old reading) moves the power and the slip far beyond
    # the rounding: the comparison above tells the two apart
    _, old, _ = _expected_windows(after.passes(), steps, whole=True)
    bound = _window_gamma(steps) * scale
    for name in ("power_sum", "slip_nx_sum", "slip_ny_sum"):
        k = F[name]
        assert (np.abs(old[:, k] - floats[:, k]) > 1e3 * bound[:, k]).any(), name
        assert np.abs(floats[:, k]).max() > 0.0, name


@pytest.mark.parametrize("mode", ["paper", "native"])
def test_a_record_from_a_plain_loop_gives_the_run(mode: str) -> None:
    # SampleRecord's contract, as a batch or a worker fills it: the state after each sample
    # interval's steps (row 0: after two forward passes) and each window built from every
    # step's pass (mj_step taken apart, WindowAccumulator)
    steps, n_intervals = (50, 200) if mode == "paper" else (5, 400)
    over = ("run.sample_dt_s=1e-3", f"run.t_end_s={n_intervals * 1e-3!r}")
    plan = _paper_plan(2e-5, *over) if mode == "paper" else _native_plan("RK4", 2e-4, *over)
    assert (plan.steps_per_sample, plan.n_intervals) == (steps, n_intervals)
    tm = build_model(plan)
    result = run.run_compiled(tm, plan)
    data = stepping.start_data(tm, plan)
    with _armed(tm, data, plan.law, plan.stem):
        record, passes = _by_hand(tm, data, steps, n_intervals,
                                  stepping.law_index(tm.model, plan.law))
    again = results.result_from_samples(tm, record, plan, ran=result.ran)
    assert again.ok and result.ok, (again.message, result.message)
    # the windows: the run's and the plain loop's are each the oracle's, to rounding
    ints, floats, scale = _expected_windows(passes, steps)
    _assert_windows(result.windows, ints, floats, scale, steps, "run")
    _assert_windows(again.windows, result.windows.ints, result.windows.floats, scale, steps,
                    "plain loop")
    # with the run's windows the plain loop's record is the run, exactly (the same states)
    same = results.result_from_samples(tm, replace(record, windows=result.windows), plan,
                                       ran=result.ran)
    assert same.table.equals(result.table)
    for r in (same, again):
        assert np.array_equal(r.contacts, result.contacts)
        assert (r.max_penetration_m, r.n_steps, r.status) == (
            result.max_penetration_m, result.n_steps, result.status)
        assert r.t_stem == result.t_stem and r.t_invert == result.t_invert
    assert same.contact_energy_bound_J == result.contact_energy_bound_J
    # with its own windows: every column the states make exactly; the windows' means within
    # their sums' bound: N and P_fric a window's sum (within _window_gamma of its scale)
    # divided by its passes (one rounding each), FX and FY the mean force (its sums' bound,
    # one rounding) dotted with a unit vector (3 roundings: gamma_4 of |F| in all)
    forces = ["N", "FX", "FY", "P_fric"]
    assert again.table.drop(columns=forces).equals(result.table.drop(columns=forces))
    u = 2.0**-53
    passes = result.windows.int_column("passes")
    mean_a, mean_b = results.window_means(again.windows), results.window_means(result.windows)
    force = "law_F" if mode == "paper" else "F"
    sums = {"N": ["n_sum"], "P_fric": ["law_power_sum" if mode == "paper" else "power_sum"]}
    sums["FX"] = sums["FY"] = (["law_fx_sum", "law_fy_sum"] if mode == "paper"
                               else ["fx_sum", "fy_sum", "fz_sum"])
    for name in forces:
        x, y = again.table[name].to_numpy(), result.table[name].to_numpy()
        bound = _window_gamma(steps) * sum(scale[:, F[k]] for k in sums[name]) / passes
        if name in ("FX", "FY"):
            bound += _gamma(4) * (np.abs(mean_a[force]) + np.abs(mean_b[force])).sum(axis=1)
        else:
            bound += u * (np.abs(x) + np.abs(y))
        assert (np.abs(x - y) <= bound).all(), name
    if mode == "paper":  # N and the law's copies: the same doubles added in one order
        assert again.table.equals(result.table)


def test_windows_are_the_per_pass_reader() -> None:
    # a tippe top onto its stem (examples/capsule_stem_top.xml, its own Euler at 0.5 ms, 6.3
    # s): the ball, the stem, and both at once; the axis turns over; contacts lost for a step
    # or two. One step at a time, the oracle reads every pass; the windows of every sample
    # spacing are built from that one list (the steps are the same whatever the spacing)
    tm, data = _capsule_start()
    n_steps = 12600  # divisible by 1, 5 and 7
    _, passes = _by_hand(tm, data, 1, n_steps)
    code = passes["code"]
    assert set(np.unique(code)) == {0, 1, 2, 3}
    kz = passes["kz"]
    assert ((kz[:-1] > 0) & (kz[1:] <= 0)).any()  # the top turns over
    for steps in (1, 5, 7):
        ints, floats, scale = _expected_windows(passes, steps)
        n_intervals = n_steps // steps
        assert len(ints) == n_intervals + 1
        if steps > 2:  # the windows hold stretches between two touches
            assert ints[:, I["inner_free"]].max() > 0
            assert ints[:, I["lifts"]].max() >= 2
        for compiled in (True, False):
            tm, data = _capsule_start()
            rec = _recorded(tm, data, steps, n_intervals, compiled=compiled)
            _assert_windows(rec.windows, ints, floats, scale, steps, f"{steps} {rec.path}")
            assert rec.windows.first_pass("first_other", steps) == np.flatnonzero(code & 2)[0]


class _FakeContact:
    def __init__(self, geom1: int, geom2: int, dist: float, frame: np.ndarray,
                 pos: np.ndarray) -> None:
        self.geom1, self.geom2, self.dist = geom1, geom2, dist
        self.frame = frame.ravel()
        self.pos = pos


class _FakeData:
    """An mjData as WindowAccumulator reads it, made pass by pass from a random sequence.

    The table is geom 0 (body 0); the top is body 1 with its ball (geom 1) and a stem (geom
    2); a third body (geom 3) touches the table too, deeper, and must not count. Each of the
    top's contacts has a random frame, point and force (normal, tangential, torsional and
    rolling), the table as geom1 or as geom2; the top's origin, velocity and spin are random,
    its ball's centre off its origin, and its rotation a random matrix whose last row's z is
    the pass's k_z (the accumulator reads it, not its orthogonality).
    """

    geom_bodyid = np.array([0, 1, 1, 2])

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.qpos, self.qvel = np.zeros(7), np.zeros(6)
        self.xmat = np.zeros((3, 9))
        self.geom_xpos = np.zeros((4, 3))
        self.contact: list[_FakeContact] = []
        self.forces: list[np.ndarray] = []

    @property
    def ncon(self) -> int:
        return len(self.contact)

    def set(self, code: int, gap: float, kz: float, depth: float) -> dict:
        """Make the pass; return what the oracle adds of it (as :class:`_Reader` reads it)."""
        rng = self.rng
        self.qpos[:3] = origin = rng.normal(0, 1e-2, 3)
        self.qvel[:3] = v = rng.normal(0, 1, 3)
        self.qvel[3:6] = local = rng.normal(0, 10, 3)
        rot = rng.normal(0, 1, (3, 3))
        rot[2, 2] = kz  # k_z: the axis is the body's z
        self.xmat[1] = rot.ravel()
        omega, omega_abs = rot @ local, np.abs(rot) @ np.abs(local)
        centre = self.geom_xpos[1]
        centre[:2] = origin[:2] + rng.normal(0, 1e-2, 2)
        centre[2] = _FAKE_R + gap
        far = _FakeContact(0, 3, -2.0, np.eye(3), np.zeros(3))  # another body's, deeper
        self.contact, self.forces = [far], [rng.normal(0, 1, 6)]
        out = {"n": 0.0, "f": np.zeros(3), "tau": np.zeros(3), "power": 0.0, "n_abs": 0.0,
               "f_abs": np.zeros(3), "tau_abs": np.zeros(3), "power_abs": 0.0}
        mine = [g for g, bit in ((1, windows.BALL), (2, windows.OTHER)) if code & bit]
        for k, g in enumerate(mine):  # the deepest one last
            frame = np.linalg.qr(rng.normal(0, 1, (3, 3)))[0]
            flipped = bool(rng.random() < 0.5)  # the top as geom1: the force acts on it -f
            pos = origin + rng.normal(0, 1e-2, 3)
            c = _FakeContact(*((g, 0) if flipped else (0, g)), -depth * (k + 1) / len(mine),
                             frame, pos)
            f6 = rng.normal(0, 1, 6)
            f6[0] = abs(f6[0])
            self.contact.append(c)
            self.forces.append(f6)
            sign = -1.0 if flipped else 1.0
            friction = sign * (frame.T @ f6[:3]) - f6[0] * sign * frame[0]
            torque = sign * (frame.T @ f6[3:])
            f_abs = np.abs(frame).T @ np.abs(f6[:3]) + abs(f6[0]) * np.abs(frame[0])
            t_abs = np.abs(frame).T @ np.abs(f6[3:])
            v_point = v + np.cross(omega, pos - origin)
            v_abs = np.abs(v) + _cross_abs(omega_abs, np.abs(pos) + np.abs(origin))
            out["n"] += f6[0]
            out["f"] = out["f"] + friction
            out["tau"] = out["tau"] + torque
            out["power"] += float(friction @ v_point + torque @ omega)
            out["n_abs"] += f6[0]
            out["f_abs"] = out["f_abs"] + f_abs
            out["tau_abs"] = out["tau_abs"] + t_abs
            out["power_abs"] += float(f_abs @ v_abs + t_abs @ omega_abs)
        # the slip of the ball's lowest point times N (0 without contact)
        lowest = centre - np.array([0.0, 0.0, _FAKE_R])
        slip = v + np.cross(omega, lowest - origin)
        slip_abs = np.abs(v) + _cross_abs(
            omega_abs, np.abs(centre) + np.array([0.0, 0.0, _FAKE_R]) + np.abs(origin))
        out["slip_n"] = out["n"] * slip[:2]
        out["slip_n_abs"] = out["n_abs"] * slip_abs[:2]
        return out

    def contact_force(self, model, data, k: int, f6: np.ndarray) -> None:
        f6[:] = self.forces[k]


_FAKE_R = 0.02


def test_the_accumulator_is_the_spec_on_random_passes() -> None:
    # WindowAccumulator's one-pass state machine against the windows built from the whole
    # pass list (_expected_windows), on random sequences: stretches of every length between
    # and across windows, ties between stretches, the ball and the stem, k_z crossing zero both
    # ways, forces on the top as geom1 and as geom2, the top moving and spinning (the power at
    # each contact point, the slip at the ball's lowest point), the ball's gap negative and
    # positive (its smallest and largest), at several sample spacings (the compiled kernel is
    # the same arithmetic: the tests above hold it to this one on real runs)
    rng = np.random.default_rng(5)
    top = windows.WindowTop(body=1, ball=1, radius_m=_FAKE_R, axis_body=(0.0, 0.0, 1.0),
                            qpos_adr=0, dof_adr=0)
    for _ in range(150):
        steps = int(rng.choice([1, 2, 3, 5, 8]))
        n = int(rng.integers(1, 30))
        P = 1 + steps * (n - 1)
        code, gap = _random_passes(rng, P)
        gap = (_FAKE_R + gap) - _FAKE_R  # as the accumulator reads it back
        kz = np.cumsum(rng.normal(0, 0.3, P)) + rng.normal(0, 0.5)
        kz[rng.random(P) < 0.05] = 0.0  # k_z <= 0 counts as down
        depth = np.where(code != 0, rng.uniform(0, 1e-3, P), 0.0)
        data = _FakeData(rng)
        fake = type("mujoco", (), {"mj_contactForce": staticmethod(data.contact_force)})
        model = type("model", (), {"geom_bodyid": _FakeData.geom_bodyid})
        acc = windows.WindowAccumulator(fake, np, model, data, top)
        got = windows.new_windows(np, n)
        passes = _passes(code, gap, kz=kz, depth=depth)
        for q in range(P):
            for key, value in data.set(int(code[q]), float(gap[q]), float(kz[q]),
                                       float(depth[q])).items():
                passes[key][q] = value
            r = _row_of(q, steps)
            acc.add(*got, r, 0 if r == 0 else q - (r - 1) * steps)
        ints, floats, scale = _expected_windows(passes, steps)
        _assert_windows(WindowRecord(*got), ints, floats, scale, steps, f"steps {steps}")


# --- WindowRecord.gaps --------------------------------------------------------------------------


def _stretches(code: np.ndarray, gap: np.ndarray) -> list[tuple[int, int, float]]:
    """Every stretch of passes without contact: (start, passes, its largest gap)."""
    out, start = [], None
    for p, c in enumerate(list(code) + [1]):
        if c == 0 and start is None:
            start = p
        elif c != 0 and start is not None:
            out.append((start, p - start, float(np.max(gap[start:p]))))
            start = None
    return out


def _random_passes(rng: np.random.Generator, P: int) -> tuple[np.ndarray, np.ndarray]:
    """Contact codes in runs of random lengths (stretches of 1 pass to many), and gaps."""
    code = np.empty(P, dtype=np.int64)
    stay = rng.uniform(0.3, 0.97)
    c = int(rng.integers(0, 4))
    for p in range(P):
        if rng.random() > stay:
            c = int(rng.integers(0, 4)) if c == 0 else int(rng.choice([0, 0, 1, 2, 3]))
        code[p] = c
    gap = np.where(code == 0, rng.uniform(-1e-6, 1e-3, P), rng.uniform(-1e-4, 0, P))
    return code, gap


def test_gaps_are_the_stretches_without_contact() -> None:
    rng = np.random.default_rng(3)
    assert len(WindowRecord.empty().gaps(3)) == 0
    exact = partial = 0
    for trial in range(600):
        steps = int(rng.choice([1, 2, 3, 5, 8]))
        n = int(rng.integers(1, 40))
        P = 1 + steps * (n - 1)
        code, gap = _random_passes(rng, P)
        if trial % 50 == 0:  # never a contact, or always
            code[:] = 0 if trial % 100 else 1
        got = WindowRecord(*_expected_windows(_passes(code, gap), steps)[:2]).gaps(steps)
        got = [(int(s), int(k), float(h)) for s, k, h in got]
        assert got == sorted(got)
        true = _stretches(code, gap)
        kept, every = _kept_stretches(true, steps, P)
        assert got == kept, (steps, code.tolist())
        if every:
            assert got == true  # no window holds two: every stretch, exactly
            exact += 1
        else:
            partial += 1
        assert every or steps > 2  # two stretches between touches take 5 passes
    assert exact > 400 and partial > 20  # both cases exercised


def _kept_stretches(true: list, steps: int, P: int) -> tuple[list, bool]:
    """What :meth:`WindowRecord.gaps` keeps of the stretches of P passes, and if that is all.

    A stretch between two touches of one window is inner to it; the windows keep each one's
    longest (the first of equals), every other stretch (one that spans a window's edge, or
    the run's start or end) exactly.
    """
    inner: dict[int, list] = {}
    edge = []
    for s in true:
        start, length, _ = s
        if start > 0 and start + length < P and (
                _row_of(start - 1, steps) == _row_of(start + length, steps)):
            inner.setdefault(_row_of(start, steps), []).append(s)
        else:
            edge.append(s)
    kept = [max(v, key=lambda s: (s[1], -s[0])) for v in inner.values()]
    return sorted(edge + kept), all(len(v) == 1 for v in inner.values())


# --- the checks ---------------------------------------------------------------------------------


def _check_oracle(code, gap, energy, steps: int, dt: float, R: float, fix: str,
                  on_table: bool) -> tuple[int, str | None]:
    """The checks, pass by pass: (first failing sample, reason) or (n, None).

    Sink: the ball's gap below -MAX_PENETRATION_R R at a pass (its centre lower than R (1 -
    MAX_PENETRATION_R); a stem's contact however deep is not the ball sinking); its sample is
    the window's that holds it, which says the ball's deepest in it. The energy at a sample.
    Contact lost: a stretch without contact that lasts past MAX_AIRBORNE_S (its passes times
    dt, :func:`_past`), with the ball risen above CONTACT_GAP_M at some pass of it; its
    sample is the window's that holds its first pass past the limit. At one sample: sink,
    then energy, then lost.
    """
    n = len(energy)
    failures: dict[int, list] = {}  # sample -> [(order, reason)]

    def fail(row: int, order: int, reason: str) -> None:
        failures.setdefault(row, []).append((order, reason))

    if on_table:
        for p in range(len(code)):
            if -gap[p] > checks.MAX_PENETRATION_R * R:
                r = _row_of(p, steps)
                deepest = -min(gap[q] for q in _window_passes(r, steps))
                fail(r, 0, f"the ball sank {deepest * 1e3:.3g} mm into the table (bound "
                           f"{checks.MAX_PENETRATION_R:g} R); stiffen solref or {fix}")
        for start, length, height in _stretches(code, gap):
            if height <= checks.CONTACT_GAP_M:
                continue
            for p in range(start, start + length):
                if _past(p - start + 1, dt):  # the first pass past the limit
                    fail(_row_of(p, steps), 2,
                         f"contact lost: the top left the table at t = {start * dt:.6g} s "
                         f"for more than {checks.MAX_AIRBORNE_S:g} s (the model follows it on "
                         "the table only)")
                    break
    e0 = energy[0]
    for i in range(n):
        if energy[i] - e0 > checks.MAX_ENERGY_RISE * abs(e0):
            fail(i, 1, f"the energy rose {100 * (energy[i] / e0 - 1):.3g}% above its "
                       f"initial value (friction can only dissipate it); {fix}")
    if not failures:
        return n, None
    row = min(failures)
    return row, min(failures[row])[1]


def _past(passes: int, dt: float) -> bool:
    """Whether ``passes`` steps of dt last past MAX_AIRBORNE_S, beyond rounding.

    A stretch of exactly 0.05 s (5 steps of 0.01 s, 11 of 0.05/11 s: its dt and 0.05 each
    rounded, 11 dt is 0.05000000000000001) is not past it.
    """
    return passes * dt > checks.MAX_AIRBORNE_S * (1 + 1e-12)


def test_the_checks_are_the_per_pass_checks() -> None:
    rng = np.random.default_rng(14)
    top_model = _native()
    R = top_model.top.R_m
    deepest_ok = checks.MAX_PENETRATION_R * R  # as deep as allowed, and the next double
    seen: set[str] = set()
    deep_stem = 0  # trials with a contact deeper than the bound and the ball not sunk
    for trial in range(500):
        dt = float(rng.choice([0.01, 0.003, 0.007, 0.05 / 11]))
        limit = next(k for k in range(1, 100) if _past(k, dt))  # 6, 17, 8, 12 passes
        steps = int(rng.choice([1, 2, 3, 5]))  # <= limit: no window holds two long stretches
        n = int(rng.integers(2, 60))
        P = 1 + steps * (n - 1)
        code = np.ones(P, dtype=np.int64)
        gap = rng.uniform(-1e-4, 0, P)
        depth = rng.uniform(0, 0.15 * R, P)
        energy = 1.0 + rng.normal(0.0, 1e-3, n)
        for _ in range(int(rng.integers(0, 4))):  # stretches without contact, short or long
            start = int(rng.integers(0, P))
            length = int(rng.choice([1, limit - 1, limit, limit + 1, 3 * limit]))
            code[start:start + length] = 0
            risen = rng.random() < 0.8  # else the ball stays within CONTACT_GAP_M
            top = 1e-3 if risen else checks.CONTACT_GAP_M
            k = len(gap[start:start + length])
            gap[start:start + length] = rng.uniform(-1e-6, top, k)
            if not risen:  # at most CONTACT_GAP_M is not risen
                gap[start + int(rng.integers(0, k))] = checks.CONTACT_GAP_M
        depth[code == 0] = 0.0
        if rng.random() < 0.3:  # a contact of the stem deeper than the bound: not a sink
            depth[int(rng.integers(0, P))] = 1.5 * deepest_ok
        kind = rng.integers(0, 3)
        if kind == 0:  # the ball sinks at a pass, or goes exactly as deep as allowed
            gap[int(rng.integers(0, P))] = -rng.choice(
                [deepest_ok, np.nextafter(deepest_ok, 1.0), 1.05 * deepest_ok])
        elif kind == 1:  # the energy rises
            energy[int(rng.integers(1, n)):] += 0.2
        on_table = trial % 10 != 0
        if not on_table:
            code[:] = 0
        t = np.arange(n) * steps * dt
        w = WindowRecord(*_expected_windows(_passes(code, gap, depth=depth), steps)[:2])
        expected = _check_oracle(code, gap, energy, steps, dt, R, "FIX", on_table)
        got = checks.check_failure(top_model, t, w, steps, dt, energy, "FIX", on_table=on_table)
        assert got == expected, (trial, steps, dt)
        seen.add("ok" if expected[1] is None else expected[1].split(":")[0][:13])
        deep_stem += on_table and depth.max() > deepest_ok and -gap.min() <= deepest_ok
    # every outcome was exercised: no failure, and each kind of failure
    assert seen == {"ok", "the ball sank", "the energy ro", "contact lost"}
    assert deep_stem > 50


# --- failures ----------------------------------------------------------------------------------


def test_a_failure_found_afterwards_ends_the_run_at_its_sample() -> None:
    steps, n_intervals, dt = 5, 300, 2e-4
    plan = _native_plan("RK4", dt, "run.sample_dt_s=1e-3", "run.t_end_s=0.3")
    assert (plan.steps_per_sample, plan.n_intervals) == (steps, n_intervals)
    tm = build_model(plan)
    rec = _recorded(tm, _start(tm), steps, n_intervals, compiled=True)
    fix = "reduce timestep_s (now 0.0002 s)"
    full = results.result_from_samples(tm, rec, plan)
    assert full.ok and len(full.table) == n_intervals + 1

    bad = 117
    qvel = rec.qvel.copy()
    qvel[bad, 4] = math.nan
    res = results.result_from_samples(tm, replace(rec, qvel=qvel), plan)
    assert res.message == (f"diverged by t = {bad * steps * dt:.6g} s (native mode): NaN or "
                           f"Inf in qpos/qvel; {fix}")
    assert len(res.table) == len(res.contacts) == len(res.windows) == bad
    assert res.n_steps == bad * steps
    assert res.table.equals(full.table.iloc[:bad])
    # its window was not stepped to a state the run keeps: the bounds stop before it
    assert res.max_penetration_m == full.windows.float_column("depth_max")[:bad].max()

    warnings = rec.warnings.copy()
    warnings[bad:, int(mujoco.mjtWarning.mjWARN_BADQACC)] = 1
    res = results.result_from_samples(tm, replace(rec, warnings=warnings,
                                                  warning_text="WARNING: Bad qacc"), plan)
    assert res.message == (f"diverged by t = {bad * steps * dt:.6g} s (native mode): MuJoCo "
                           f"warning mjWARN_BADQACC (1x): Bad qacc, the integration is "
                           f"unstable; {fix}")
    assert len(res.table) == bad
    # counters stepped by another release are named by its enum (3.3.7 had mjWARN_VGEOMFULL
    # at code 3, so its code 5 is BADQVEL where 4.0's code 5 is BADQACC)
    old_names = ("mjWARN_INERTIA", "mjWARN_CONTACTFULL", "mjWARN_CNSTRFULL", "mjWARN_VGEOMFULL",
                 "mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")
    there = np.zeros((len(rec), len(old_names)), dtype=np.int64)
    there[bad:, 5] = 1
    res = results.result_from_samples(tm, replace(rec, warnings=there, warning_text="Bad qvel",
                                                  warning_names=old_names), plan)
    assert "MuJoCo warning mjWARN_BADQVEL (1x): Bad qvel," in res.message

    # a failure of the checks: its window was stepped, so the contact bounds cover it: sink
    # the ball in a window (its gap_min, and its contact's depth_max) deeper than any before
    depth = rec.windows.float_column("depth_max")
    deep = 200
    sunk = 0.3 * FIG3_TOP.R_m
    assert 0 < depth[:deep].max() < sunk
    assert -rec.windows.float_column("gap_min").min() < checks.MAX_PENETRATION_R * FIG3_TOP.R_m
    floats = rec.windows.floats.copy()
    floats[deep, F["depth_max"]] = sunk  # another geom's contact this deep: not a sink
    res = results.result_from_samples(
        tm, replace(rec, windows=WindowRecord(rec.windows.ints, floats)), plan)
    assert res.ok and res.max_penetration_m == sunk
    floats[deep, F["gap_min"]] = -sunk  # the ball's own
    res = results.result_from_samples(
        tm, replace(rec, windows=WindowRecord(rec.windows.ints, floats)), plan)
    assert res.message == (f"diverged by t = {deep * steps * dt:.6g} s (native mode): the "
                           f"ball sank {sunk * 1e3:.3g} mm into the table (bound "
                           f"{checks.MAX_PENETRATION_R:g} R); stiffen solref or {fix}")
    assert len(res.table) == len(res.windows) == deep and res.max_penetration_m == sunk
    assert res.table.equals(full.table.iloc[:deep])
    N = results.window_means(rec.windows)["N"]
    assert res.contact_energy_bound_J == max(np.max(N[:deep] * depth[:deep]), N[deep] * sunk)

    # stepping that stopped early (a batch's error), the record ending before the failure
    res = results.result_from_samples(tm, rec.head(bad), plan, failure="MuJoCo error: boom")
    assert res.message == (f"diverged by t = {bad * steps * dt:.6g} s (native mode): MuJoCo "
                           f"error: boom; {fix}")
    assert res.table.equals(full.table.iloc[:bad])


@pytest.mark.parametrize(
    ("A_over_C", "n0", "dt", "integrator"),
    [
        (1.0, 1e11, 2e-5, "RK4"),  # MuJoCo's warning: |qvel| over its bound, reset
        (0.95, 1000.0, 5e-3, "Euler"),  # contact lost
        (1.0, 100.0, 2e-2, "Euler"),  # the ball sinks through
    ],
)
def test_failures_end_at_the_same_sample_compiled_or_not(A_over_C, n0, dt, integrator,
                                                         tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warnings to ./MUJOCO_LOG.TXT
    plan = mujoco_plan("mujoco.friction='paper'", "effects.sliding=false",
                       "mujoco.solref=[0.02, 1.0]", f"top.A_over_C={A_over_C!r}",
                       f"init.n0={n0!r}", f"mujoco.timestep_s={dt!r}",
                       f"mujoco.integrator={integrator!r}", "run.t_end_s=2.0",
                       f"run.sample_dt_s={max(dt, 1e-3)!r}")
    assert plan.law is None  # no sliding: no law to arm
    tm = build_model(plan)
    init = InitialState(theta0=0.1, n0=n0)
    outs = []
    for compiled in (True, False):
        data = _start(tm, init)
        mujoco.mj_forward(tm.model, data)
        rec, failure, _ = stepping.step_and_record(
            tm.model, data, plan.steps_per_sample, plan.n_intervals, None,
            top=stepping.window_top(tm), law_index=stepping.law_index(tm.model, plan.law),
            compiled=compiled)
        outs.append(results.result_from_samples(tm, rec, plan, failure=failure))
    a, b = outs
    assert a.status == b.status == "diverged"
    assert a.message == b.message and a.table.equals(b.table) and a.n_steps == b.n_steps
    assert np.array_equal(a.windows.ints, b.windows.ints)


# --- paper mode's law, the events to the step ---------------------------------------------------


def test_paper_mode_law_columns() -> None:
    # the capsule top in paper mode: the law at the ball and at the stem's end (from t = 0.89
    # s), as its callback applied it at each pass
    plan = mujoco_plan(f"top.mjcf={str(CAPSULE)!r}", "mujoco.timestep_s=1e-4",
                       "mujoco.friction='paper'", "run.sample_dt_s=1e-3", "run.t_end_s=1.0")
    tm = build_model(plan)
    assert plan.law is not None and plan.stem is not None and plan.steps_per_sample == 10
    index = stepping.law_index(tm.model, plan.law)
    records = []
    for compiled in (True, False):
        data = stepping.start_data(tm, plan)
        with _armed(tm, data, plan.law, plan.stem):
            records.append(_recorded(tm, data, plan.steps_per_sample, plan.n_intervals,
                                     compiled=compiled, law_index=index))
    a, b = records
    for field in STATE_FIELDS:
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert np.array_equal(a.windows.ints, b.windows.ints)
    for name in ("law_fx_sum", "law_fy_sum", "law_power_sum"):
        x, y = a.windows.float_column(name), b.windows.float_column(name)
        assert np.array_equal(x, y), name  # copies summed in one order: the same bits
        assert np.count_nonzero(x) >= len(x) - 1, name  # at every pass but the first's
    assert (a.windows.float_column("law_power_sum")[1:] < 0).all()  # friction dissipates
    # the frictionless contact itself: no tangential force
    assert not a.windows.floats[:, F["fx_sum"]:F["tz_sum"] + 1].any()
    assert a.windows.first_pass("first_other", plan.steps_per_sample) is not None


@pytest.mark.parametrize("dt", [5e-4, 1e-4])
def test_t_stem_and_t_invert_are_located_to_the_step(dt: float) -> None:
    # the capsule top sampled every 1 ms and at every step: the same steps, bit for bit, so
    # the same first step of the stem and of the axis pointing down, and the same stretches
    # without contact
    common = (f"top.mjcf={str(CAPSULE)!r}", f"mujoco.timestep_s={dt!r}", "run.t_end_s=2.0")
    outs = []
    for sample_dt in (1e-3, dt):
        plan = mujoco_plan(*common, f"run.sample_dt_s={sample_dt!r}")
        outs.append(run.run_compiled(build_model(plan), plan))
    every_ms, every_step = outs
    assert every_ms.ok and every_step.ok
    assert (every_ms.steps_per_sample, every_step.steps_per_sample) == (round(1e-3 / dt), 1)
    # the states at the common samples (t is i * sample_dt, rounded each its own way; the
    # forces are the windows' means)
    states = [c for c in every_ms.table.columns if c not in ("t", "N", "FX", "FY", "P_fric")]
    thinned = every_step.table.iloc[::every_ms.steps_per_sample].reset_index(drop=True)
    assert thinned[states].equals(every_ms.table[states])
    assert every_ms.t_stem is not None and every_ms.t_invert is not None
    assert (every_ms.t_stem, every_ms.t_invert) == (every_step.t_stem, every_step.t_invert)
    assert 0 < every_ms.t_invert < every_ms.t_stem < 2.0
    # every step: every stretch without contact (a window of one pass holds none inside)
    true = [(int(a), int(k), float(h)) for a, k, h in every_step.windows.gaps(1)]
    P = len(every_step.windows)
    assert len(true) > 10 and sum(every_step.windows.int_column("lifts")) == len(true)
    kept, every = _kept_stretches(true, every_ms.steps_per_sample, P)
    got = [(int(a), int(k), float(h)) for a, k, h in every_ms.windows.gaps(
        every_ms.steps_per_sample)]
    assert got == kept
    # at the file's 0.5 ms a 1-ms window holds two passes: no stretch inside, all the same;
    # at 0.1 ms the contact flickers within a window, which keeps its longest stretch
    assert every == (dt == 5e-4)
    if every:
        g_ms, g_step = every_ms.gaps(), every_step.gaps()
        for key in ("t_start", "duration_s", "height_m"):
            assert np.array_equal(g_ms[key], g_step[key]), key
    # the counts of stretches and of passes without contact are the same either way
    assert every_ms.gaps()["count"].sum() == len(true)
    airborne = [(r.windows.int_column("passes") - r.windows.int_column("touch_passes")).sum()
                for r in outs]
    assert airborne[0] == airborne[1] == sum(k for _, k, _ in true)
