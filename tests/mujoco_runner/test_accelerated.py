"""MuJoCo MJX (JAX) and MuJoCo Warp run a plan through the worker, on the CPU here.

Fast (no JAX, no Warp): the request carries the engine and the top; an engine the worker
cannot run is one line; the paper's law written in array arithmetic (what MJX traces) is the
Python callback's to rounding, with a stem and without; the window's update in array
arithmetic (what MJX traces) is ``WindowAccumulator``'s pass for pass, and what it reads of a
pass is what MuJoCo C's passes give, to the bounds each test states.

Slow (managed environments, JAX's and Warp's compilers): MJX in float64 against MuJoCo C of
the release MJX follows (``mujoco==3.17.0``, the same worker), in native and paper mode; MJX in
float32; Warp for 500 steps against the MuJoCo 4.0 installed here, and in paper mode (the
law as a Warp kernel in the captured graph). Each says what ran, read back, and each checks
the windows added on the device at every step against MuJoCo C's. Measured on 2 shared CPU
cores: MJX's worker takes 10 to 55 s a run, most of it compiling (setup ~5-9 s, the first
jitted call ~9-40 s; JAX's persistent cache under ``$TIPPETOP_CACHE/jax`` shortens a rerun),
then ~200 us a step; Warp compiles its kernels once (~30 s, kept in Warp's own cache), then
~100 us a step as a captured graph.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import NamedTuple

import mujoco
import numpy as np
import pytest

from tests.conftest import mujoco_plan
from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner import envs, remote, worker
from tippetop.mujoco_runner.settings import build_model
from tippetop.mujoco_runner.stepping import start_data, window_top
from tippetop.mujoco_runner.worker.windows import new_windows

pytestmark = pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")

MJX64 = {"implementation": "mjx", "precision": "float64"}
MJX32 = {"implementation": "mjx", "precision": "float32"}
WARP = {"implementation": "warp", "precision": "float32"}


def test_the_request_carries_the_engine(tmp_path: Path) -> None:
    plan = mujoco_plan("run.t_end_s=0.01")
    top = build_model(plan)
    req = remote.request(plan, top, tmp_path / "x.npz", MJX32)
    assert req["protocol"] == worker.PROTOCOL == 5
    assert req["engine"] == MJX32
    assert remote.request(plan, top, tmp_path / "x.npz")["engine"] == remote.DEFAULT_ENGINE
    # whose contacts the windows add, as this process's model has them
    assert worker.window_top(req) == window_top(top)
    assert json.loads(json.dumps(req))["top"] == req["top"]


def test_a_request_without_its_top_is_one_line() -> None:
    plan = mujoco_plan("run.t_end_s=0.01")
    req = remote.request(plan, build_model(plan), Path("x.npz"))
    del req["top"]["ball"]
    reply = worker.answer(json.dumps(req))
    assert reply["status"] == "error" and reply["message"].startswith(
        "top: expected an object with body, ball, radius_m, axis_body, qpos_adr, dof_adr")


def test_the_device_windows_fill_every_column_they_can() -> None:
    """Every column of ``worker.windows`` but those the device does not read (the friction
    torque, and fz: the table is flat) is written by MJX's update and Warp's kernel; a column
    added there and not here fails this test (it would stay at its start on the device).

    MJX: ``table_pass`` and ``window_add`` (on numpy) over six made-up passes of one window
    that move every column (a lift, a touch of the ball, a stretch between touches, the stem,
    the axis turning over; forces, slip and the law nonzero): each column but those four
    leaves its start. Warp (not importable here): its kernel's column lists are the windows'
    but those four, and its source reads each of their slots.
    """
    import inspect
    import re

    from tippetop.mujoco_runner.worker import mjx_stepper, warp_stepper, windows

    unread = {"fz_sum", "tx_sum", "ty_sum", "tz_sum"}
    # MJX
    top = worker.WindowTop(body=1, ball=1, radius_m=0.015, axis_body=(0.0, 0.0, 1.0),
                           qpos_adr=0, dof_adr=0)
    geom_body = np.array([0, 1, 1])
    qpos = np.array([0.001, -0.002, 0.02, 1.0, 0.0, 0.0, 0.0])
    qvel = np.array([0.01, -0.02, 0.003, 4.0, -3.0, 90.0])
    qcon = np.array([-0.004, 0.003, 0.15, 0.0, 0.0, 0.0])
    wi, wf = (np.array(windows.INT_START, dtype=np.int64),
              np.array(windows.FLOAT_START, dtype=float))
    prev = (np.bool_(True), math.nan)
    # (the top's geoms touching, k_z): free (a lift), the ball, free, the stem (the stretch
    # between), the ball with the axis turned over, free (after the last touch)
    for offset, (touching, kz) in enumerate(
            [((), 0.9), ((1,), 0.8), ((), 0.7), ((2,), 0.1), ((1,), -0.2), ((), -0.3)],
            start=1):
        xmat = np.array([[1.0, 0.0, 0.0], [0.0, kz, -math.sqrt(1 - kz * kz)],
                         [0.0, math.sqrt(1 - kz * kz), kz]])
        ball = np.array([0.0015, -0.0025, 0.015 + (2e-4 if not touching else -1e-5)])
        geom = np.array([[0, g] for g in touching], dtype=np.int64).reshape(-1, 2)
        dist = np.full(len(touching), -1e-5)
        code, depth, forces, gap, slip, kz_read = mjx_stepper.table_pass(
            np, geom_body, top, dist, np.full(len(touching), np.inf), geom, xmat, ball, qpos,
            qvel, qcon)
        wi, wf, prev = mjx_stepper.window_add(np, wi, wf, prev, code, depth, forces, gap,
                                              slip, kz_read, (0.01, -0.02, -0.003), offset)
    moved_i = {name for name, k in windows.I.items() if wi[k] != windows.INT_START[k]}
    moved_f = {name for name, k in windows.F.items() if wf[k] != windows.FLOAT_START[k]}
    assert moved_i == set(windows.INT_FIELDS)
    assert moved_f == set(windows.FLOAT_FIELDS) - unread
    # Warp
    assert set(warp_stepper.KERNEL_INTS) == set(windows.INT_FIELDS)
    assert set(warp_stepper.KERNEL_FLOATS) <= set(windows.FLOAT_FIELDS)
    assert set(windows.FLOAT_FIELDS) - set(warp_stepper.KERNEL_FLOATS) == unread
    source = inspect.getsource(warp_stepper.warp_window_kernels)
    for slots, names in (("ic", warp_stepper.KERNEL_INTS), ("fc", warp_stepper.KERNEL_FLOATS)):
        read = {int(k) for k in re.findall(rf"\b{slots}\[(\d+)\]", source)}
        assert read == set(range(len(names))), (slots, read)


class _Contact(NamedTuple):
    geom1: int
    geom2: int
    dist: float
    frame: np.ndarray
    pos: np.ndarray


def test_the_device_window_update_is_the_accumulators_pass_for_pass() -> None:
    """What MJX traces (``table_pass`` and ``window_add`` on numpy) against
    ``WindowAccumulator``.

    Random passes of a made-up top (geom 1 its ball, geom 2 its stem, geom 0 the table):
    touching with either, both or neither in runs of random length, its axis turning over
    and back (k_z crossing 0 both ways), its ball's height and depth random, each contact
    with a random normal force and the law's output random; the top moving and spinning at
    random, its ball off its origin. 300 windows of 7 passes, the carry kept across them.
    Both make the same comparisons and the same products on the same numbers (N the
    contacts' normal forces summed in their order, the slip of the ball's lowest point
    written out alike), so every column is equal. No friction force here (0 on both sides):
    the next test has it.
    """
    rng = np.random.default_rng(11)
    top = worker.WindowTop(body=1, ball=1, radius_m=0.015, axis_body=(0.0, 0.0, 1.0),
                           qpos_adr=0, dof_adr=0)
    model = SimpleNamespace(geom_bodyid=np.array([0, 1, 1]))
    normals: list[float] = []

    def contact_force(m, d, k: int, f6: np.ndarray) -> None:
        f6.fill(0.0)
        f6[0] = normals[k]

    fake = SimpleNamespace(mj_contactForce=contact_force)
    data = SimpleNamespace(xmat=np.zeros((2, 9)), qpos=np.zeros(7), qvel=np.zeros(6), ncon=0,
                           contact=[], geom_xpos=np.zeros((3, 3)))
    law = np.zeros(3)
    acc = worker.WindowAccumulator(fake, np, model, data, top, lambda: tuple(law))
    rows, steps = 300, 7
    ints, floats = new_windows(np, rows)
    mine_i, mine_f = new_windows(np, rows)
    geom_body = model.geom_bodyid
    prev = (np.bool_(True), math.nan)
    theta, touching, run = 1.4, (), 0
    for r in range(rows):
        wi, wf = mine_i[r], mine_f[r]
        for j in [0] if r == 0 else range(1, steps + 1):
            if run == 0:  # a new stretch: touching with ...
                touching = [(), (1,), (2,), (1, 2)][rng.integers(4)]
                run = int(rng.integers(1, 12))
            run -= 1
            theta = float(np.clip(theta + rng.normal(0.0, 0.05), 1.2, 1.9))
            c, s = math.cos(theta), math.sin(theta)
            data.xmat[1] = [1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c]  # k_z = cos(theta)
            data.qpos[:3] = rng.normal(0.0, 1e-3, 3)
            data.qvel[:] = rng.normal(0.0, 1.0, 6) * [0.05, 0.05, 0.01, 5.0, 5.0, 80.0]
            data.geom_xpos[1] = data.qpos[:3] + rng.normal(0.0, 2e-3, 3)
            data.geom_xpos[1, 2] = top.radius_m + rng.normal(0.0, 1e-5)
            data.contact = [_Contact(0, g, -abs(rng.normal(0.0, 1e-5)), np.eye(3).ravel(),
                                     np.zeros(3)) for g in touching]
            data.ncon = len(data.contact)
            normals[:] = rng.uniform(0.0, 0.2, data.ncon)
            law[:] = rng.normal(0.0, 0.01, 3)
            acc.add(ints, floats, r, j)
            n = 0.0  # as the accumulator sums them (MJX: qfrc_constraint's z)
            for value in normals:
                n += value
            qcon = np.array([0.0, 0.0, n, 0.0, 0.0, 0.0])
            geoms = np.array([(con.geom1, con.geom2) for con in data.contact],
                             dtype=np.int64).reshape(-1, 2)
            code, depth, forces, gap, slip, kz = worker.mjx_stepper.table_pass(
                np, geom_body, top, np.array([con.dist for con in data.contact]),
                np.full(data.ncon, np.inf), geoms, data.xmat[1].reshape(3, 3),
                data.geom_xpos[1], data.qpos, data.qvel, qcon)
            assert code == sum(worker.windows.BALL if g == 1 else worker.windows.OTHER
                               for g in touching) and kz == c
            wi, wf, prev = worker.window_add(np, wi, wf, prev, code, depth, forces, gap, slip,
                                             kz, tuple(law), j)
        mine_i[r], mine_f[r] = wi, wf
    np.testing.assert_array_equal(mine_i, ints)
    np.testing.assert_array_equal(mine_f, floats)
    flips = ints[:, worker.windows.I["flip"]]
    assert (flips >= 0).sum() > 3 and (ints[:, worker.windows.I["first_other"]] >= 0).any()
    assert (ints[:, worker.windows.I["inner_free"]] > 0).any()
    F = worker.windows.F
    for name in ("gap_min", "slip_nx_sum", "slip_ny_sum", "n_sum", "law_power_sum"):
        assert np.ptp(floats[:, F[name]]) > 0.0, name  # the columns vary: a real comparison


def test_the_device_window_pass_reads_what_mujoco_c_passes_read() -> None:
    """``worker.table_pass`` and ``window_add`` (MJX's, on numpy) on MuJoCo C's own passes.

    0.2 s of the Fig. 3 top native (RK4, 1,000 passes, a contact that comes and goes) stepped
    here as the worker steps it, each pass added by ``WindowAccumulator`` and by the device's
    arithmetic from the same mjData (every contact of ``mjData.contact`` counting, as C's).
    The integers, gaps (the largest and the smallest) and depths are the same comparisons on
    the same numbers: equal. N and the friction force are the free joint's
    ``qfrc_constraint`` there and ``mj_contactForce`` per contact here: the same forces on a
    flat table, apart by rounding (measured 0 for N, 7e-18 N for the friction; bound 1e-12
    of the largest). The slip of the ball's lowest point is the same expression of the same
    state, so its sums times N are apart by N's rounding alone (measured 0; the same bound).
    The power is taken at the ball's
    lowest point there and at the contact point (the midpoint of the overlap) here: apart by
    at most |F| |omega| depth / 2 a pass (measured 3.4e-7 W on 0.019 W), which bounds it.
    """
    plan = mujoco_plan("mujoco.friction=native", "run.t_end_s=0.2")
    top_model = build_model(plan)
    model, top = top_model.model, window_top(top_model)
    data = start_data(top_model, plan)
    mujoco.mj_forward(model, data)
    steps, rows = plan.steps_per_sample, plan.n_intervals + 1
    ints, floats = new_windows(np, rows)
    mine_i, mine_f = new_windows(np, rows)
    slack = np.zeros(rows)
    acc = worker.WindowAccumulator(mujoco, np, model, data, top)
    geom_body = np.asarray(model.geom_bodyid)
    integrate = worker.windows.integrator_call(mujoco, model)
    prev = (np.bool_(True), math.nan)
    for r in range(rows):
        wi, wf = mine_i[r], mine_f[r]
        for j in [0] if r == 0 else range(1, steps + 1):
            if r:
                integrate(model, data)
            mujoco.mj_forward(model, data)
            acc.add(ints, floats, r, j)
            c = data.contact
            code, depth, forces, gap, slip, kz = worker.mjx_stepper.table_pass(
                np, geom_body, top, np.array(c.dist), np.full(data.ncon, np.inf),
                np.array(c.geom).reshape(-1, 2), data.xmat[top.body].reshape(3, 3),
                data.geom_xpos[top.ball], data.qpos, data.qvel, data.qfrc_constraint)
            omega = data.xmat[top.body].reshape(3, 3) @ data.qvel[top.dof_adr + 3:]
            slack[r] += math.hypot(forces[1], forces[2]) * np.linalg.norm(omega) * depth / 2
            wi, wf, prev = worker.window_add(np, wi, wf, prev, code, depth, forces, gap, slip,
                                             kz, (0.0, 0.0, 0.0), j)
        mine_i[r], mine_f[r] = wi, wf
    np.testing.assert_array_equal(mine_i, ints)
    touch = ints[:, worker.windows.I["touch_passes"]]
    assert 0 < touch.sum() < rows * steps and ints[:, worker.windows.I["lifts"]].sum() > 10
    F = worker.windows.F
    exact = ["gap_max", "lead_gap", "trail_gap", "inner_gap", "gap_min", "depth_max"]
    np.testing.assert_array_equal(mine_f[:, [F[k] for k in exact]],
                                  floats[:, [F[k] for k in exact]])
    for name in ("n_sum", "fx_sum", "fy_sum", "fz_sum", "slip_nx_sum", "slip_ny_sum"):
        k = F[name]
        np.testing.assert_allclose(mine_f[:, k], floats[:, k], rtol=0.0,
                                   atol=1e-12 * max(np.abs(floats[:, k]).max(), 1e-300))
    assert np.abs(floats[:, F["n_sum"]]).max() > 0.1
    assert min(np.abs(floats[:, F[k]]).max() for k in ("slip_nx_sum", "slip_ny_sum")) > 0.0
    power_gap = np.abs(mine_f[:, F["power_sum"]] - floats[:, F["power_sum"]])
    assert (power_gap <= slack * (1 + 1e-9) + 1e-15).all()
    assert power_gap.max() > 0.0  # the two points differ: the bound is what holds them


@pytest.mark.parametrize(("engine", "message"), [
    ({"implementation": "warp", "precision": "float64"},
     "engine: expected warp in float32, got 'float64'"),
    ({"implementation": "mujoco", "precision": "float32"},
     "engine: expected mujoco in float64, got 'float32'"),
    ({"implementation": "bullet", "precision": "float64"},
     "engine: expected an implementation of mujoco, mjx, warp, got 'bullet'"),
], ids=["warp-f64", "mujoco-f32", "unknown"])
def test_an_engine_the_worker_cannot_run_is_one_line(engine: dict, message: str) -> None:
    plan = mujoco_plan("run.t_end_s=0.01")
    with pytest.raises(remote.WorkerFailed) as info:
        remote.simulate_in(sys.executable, plan, engine=engine)
    assert str(info.value).endswith(f"failed: {message}") and "\n" not in str(info.value)


def test_warp_without_warp_is_one_line() -> None:
    try:
        import warp  # noqa: F401
        pytest.skip("this Python has Warp")
    except ImportError:
        pass
    with pytest.raises(remote.WorkerFailed) as info:
        remote.simulate_in(sys.executable, mujoco_plan("run.t_end_s=0.01"), engine=WARP)
    assert "engine warp: expected mujoco-warp and warp-lang in " in str(info.value)
    assert "\n" not in str(info.value)


def test_mjx_without_jax_is_one_line() -> None:
    pytest.importorskip("mujoco")
    try:
        import jax  # noqa: F401
        pytest.skip("this Python has JAX")
    except ImportError:
        pass
    with pytest.raises(remote.WorkerFailed) as info:
        remote.simulate_in(sys.executable, mujoco_plan("run.t_end_s=0.01"), engine=MJX64)
    assert "engine mjx: expected mujoco-mjx and jax in " in str(info.value)
    assert "\n" not in str(info.value)


def test_the_harness_runs_mjx_and_warp_in_managed_environments(monkeypatch) -> None:
    from tippetop.compare.running.engines import engine_python
    from tippetop.models.engines import parse_engine

    asked: list[str] = []
    monkeypatch.setattr(envs, "accelerated_env_python",
                        lambda impl, say=None: asked.append(impl) or Path(f"/envs/{impl}"))
    assert engine_python(parse_engine("mjx-f32")) == "/envs/mjx"
    assert engine_python(parse_engine("warp")) == "/envs/warp"
    assert asked == ["mjx", "warp"]
    assert envs.accelerated_packages("mjx")[0] == f"mjx-{envs.MJX_VERSION}"
    assert f"mujoco=={envs.MJX_VERSION}" in envs.accelerated_packages("mjx")[1]
    with pytest.raises(TippetopError, match="expected mjx or warp"):
        envs.accelerated_packages("mujoco")


@pytest.mark.parametrize("stem", [None, "sphere", "cylinder"])
def test_the_law_in_array_arithmetic_is_the_callbacks(stem: str | None) -> None:
    """What MJX traces (``worker.law_force`` on numpy) against the Python callback.

    Random states (both contacts touching, the ball alone, the stem alone), random constraint
    forces: the same operations in the same order, so equal to a few ulps.
    """
    import mujoco

    plan = mujoco_plan("mujoco.friction=paper", "run.t_end_s=0.01")
    top = build_model(plan)
    law = remote.request(plan, top, Path("x.npz"))["law"]
    law.update(coulomb_kind=2, viscous_on=1)  # every term of the law
    if stem is not None:
        law.update(stem_kind=1 if stem == "sphere" else 2, stem_l=0.02, stem_r=0.002)
    model = top.model
    qa, va = top.qpos_adr, top.dof_adr
    cb = worker.PaperLaw(model, {**law, "qpos_adr": qa, "dof_adr": va})
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = rng.normal(size=4)
        qpos = np.r_[rng.normal(size=2) * 1e-3, rng.uniform(-0.03, 0.03), q / np.linalg.norm(q)]
        qvel = rng.normal(size=6) * [0.05, 0.05, 0.01, 5, 5, 50]
        qcon = rng.normal(size=6) * [0.01, 0.01, 0.2, 1e-3, 1e-3, 1e-4]
        data.qpos[qa:qa + 7], data.qvel[va:va + 6] = qpos, qvel
        data.qfrc_constraint[va:va + 6] = qcon
        data.qfrc_passive[:] = 0.0
        cb(model, data)
        f6, fx, fy, N, power = worker.law_force(np, law, qpos, qvel, qcon)
        np.testing.assert_allclose(f6, data.qfrc_passive[va:va + 6], rtol=1e-12,
                                   atol=1e-18)
        assert (float(fx), float(fy), float(N), float(power)) == pytest.approx(
            (cb.last[0], cb.last[1], cb.last[2], cb.last[3]), rel=1e-12, abs=1e-18)


# ----------------------------------------------------------------------------- slow

def _theta_gap(a, b) -> float:
    return float(np.max(np.abs(a.table["theta"].to_numpy() - b.table["theta"].to_numpy())))


def _column_gap(a, b, name: str) -> tuple[float, float]:
    """(largest |difference| of a window float column, its largest |value| in ``b``)."""
    x, y = a.windows.float_column(name), b.windows.float_column(name)
    both = np.isfinite(x) & np.isfinite(y)
    return float(np.abs(x[both] - y[both]).max()), float(np.abs(y[both]).max())


def _mean_n(result) -> float:
    """The run's mean normal force over every pass (N)."""
    w = result.windows
    return float(w.float_column("n_sum").sum() / w.int_column("passes").sum())


def _mean_slip_y(result) -> float:
    """The run's slip of the ball's lowest point along y, weighted by N (m/s)."""
    w = result.windows
    return float(w.float_column("slip_ny_sum").sum() / w.float_column("n_sum").sum())


def _same_touch_after_the_start(a, c) -> None:
    """The touch codes of every window but row 0's, and row 0's difference.

    Row 0's one pass is at the start, where the ball rests on the table at dist exactly 0:
    MuJoCo C keeps that contact (dist <= margin), MJX's solver and Warp's collision do not
    (dist < margin).
    """
    x, y = a.windows.int_column("touch"), c.windows.int_column("touch")
    assert len(x) == len(y) > 1
    np.testing.assert_array_equal(x[1:], y[1:])
    assert (x[0], y[0]) == (0, 1)


@pytest.mark.slow
def test_mjx_float64_is_mujoco_c_of_its_release_on_the_cpu(mjx_python: str,
                                                           c_python: str) -> None:
    """MJX (JAX, float64, CPU) against MuJoCo C 3.17.0: 0.3 s of the default scene, native.

    Both run the same algorithms on the same compiled model (RK4 at dt = 2e-4 s, a pyramidal
    sphere-plane contact, the Newton solver to tolerance 1e-8): MJX is a JAX port of MuJoCo's
    pipeline, so what differs is floating-point order (XLA fuses and reorders sums; MJX's
    solver runs a fixed-shape loop), rounding-sized per step and grown by the contact's
    stiffness and the solver's tolerance. Measured: theta apart by 2.2e-11 rad at most.
    Tolerance 1e-7 rad, still 1e5 times below the 1e-2 rad the nightly allows between
    engines, so a real difference (a collision or a solver MJX does differently) cannot hide
    in it.

    The windows, added on the device at every step: the same touches pass for pass (every
    integer column equal after row 0, though the contact comes and goes within windows),
    the ball's gap (largest and smallest) to 5e-16 m (tolerance 1e-12 m), N summed per
    window to 4e-9 N on 1.3 N (tolerance 1e-6 of the largest) and the friction to 2e-9 N
    (the same bound): the free joint's constraint force against ``mj_contactForce`` per
    contact, the same forces on a flat table. The slip of the ball's lowest point times N,
    summed per window: 3.4e-11 on 2.1e-3 (x) and 2.9e-11 on 0.18 (y) m N/s (tolerance 1e-6
    of each one's largest). The power, taken at the ball's lowest point rather than the
    contact point, to 4e-7 W on 0.02 W (tolerance 1e-3 of the largest).
    """
    plan = mujoco_plan("mujoco.friction=native", "run.t_end_s=0.3")
    mjx, info = remote.simulate_in(mjx_python, plan, engine=MJX64)
    c, _ = remote.simulate_in(c_python, plan)
    assert mjx.status == c.status == "ok" and info.version == envs.MJX_VERSION
    e = mjx.engine
    assert (e["implementation"], e["version"], e["precision"], e["device"]) == \
        ("mjx", envs.MJX_VERSION, "float64", "cpu")
    assert e["path"] == "worker: mjx: jit(fori_loop(integrate, forward, window))"
    assert e["mujoco_c_version"] == envs.MJX_VERSION
    assert e["contacts_from"] == worker.mjx_stepper.MJX_CONTACTS_FROM
    assert mjx.ran == c.ran and len(mjx.table) == len(c.table) == 301
    assert _theta_gap(mjx, c) < 1e-7
    assert np.max(np.abs(mjx.table[["x", "y", "z"]].to_numpy()
                         - c.table[["x", "y", "z"]].to_numpy())) < 1e-9
    _same_touch_after_the_start(mjx, c)
    np.testing.assert_array_equal(mjx.windows.ints[1:], c.windows.ints[1:])
    assert 0 < c.windows.int_column("touch_passes").sum() < 1500  # it lifts off
    for name in ("gap_max", "gap_min"):
        assert _column_gap(mjx, c, name)[0] < 1e-12, name
    n_gap, n_scale = _column_gap(mjx, c, "n_sum")
    assert n_gap < 1e-6 * n_scale
    for name in ("fx_sum", "fy_sum"):
        assert _column_gap(mjx, c, name)[0] < 1e-6 * n_scale, name
    for name in ("slip_nx_sum", "slip_ny_sum"):
        s_gap, s_scale = _column_gap(mjx, c, name)
        assert s_gap < 1e-6 * s_scale and s_scale > 0.0, name
    p_gap, p_scale = _column_gap(mjx, c, "power_sum")
    assert 0.0 < p_gap < 1e-3 * p_scale


@pytest.mark.slow
def test_mjx_paper_mode_differs_from_c_only_by_when_the_law_is_evaluated(
        mjx_python: str, c_python: str) -> None:
    """Paper mode: MJX puts the law in ``qfrc_applied`` once a step, C calls it in each stage.

    With Euler (one evaluation a step in both, at the step's start state with the last
    evaluation's constraint force) the two agree to rounding: measured 5.1e-16 rad over 0.3
    s (tolerance 1e-12), and the law's force and power summed in each window to 1e-14 on
    0.74 N and 0.11 W (tolerance 1e-9 of the largest window), the slip times N to 3e-15 on
    1.1 m N/s (the same tolerance). With RK4, C evaluates the
    law at each of the four stages while MJX holds the step's first one: measured 6.2e-5
    rad over 0.3 s at dt = 2e-5 s, asserted between 1e-6 and 1e-3 rad; the law's power over
    the run apart by 1.1e-4 of itself (tolerance 1e-3), N's sum by 1.6e-7 (tolerance 1e-5).
    """
    euler = mujoco_plan("mujoco.friction=paper", "run.t_end_s=0.3",
                        "mujoco.integrator='Euler'")
    mjx, _ = remote.simulate_in(mjx_python, euler, engine=MJX64)
    c, _ = remote.simulate_in(c_python, euler)
    assert mjx.status == c.status == "ok"
    assert "qfrc_applied" in mjx.engine["law_applied"]
    assert _theta_gap(mjx, c) < 1e-12
    # the law's output at every pass, summed on the device
    assert np.abs(mjx.table["P_fric"].to_numpy()[1:]).max() > 0.0
    for name in ("law_fx_sum", "law_fy_sum", "law_power_sum", "slip_nx_sum", "slip_ny_sum"):
        gap, scale = _column_gap(mjx, c, name)
        assert gap < 1e-9 * scale and scale > 0.0, name
    _same_touch_after_the_start(mjx, c)
    rk4 = mujoco_plan("mujoco.friction=paper", "run.t_end_s=0.3")
    mjx, _ = remote.simulate_in(mjx_python, rk4, engine=MJX64)
    c, _ = remote.simulate_in(c_python, rk4)
    assert mjx.status == c.status == "ok"
    assert 1e-6 < _theta_gap(mjx, c) < 1e-3
    power = [float(r.windows.float_column("law_power_sum").sum()) for r in (mjx, c)]
    assert power[0] == pytest.approx(power[1], rel=1e-3)
    assert _mean_n(mjx) == pytest.approx(_mean_n(c), rel=1e-5)


@pytest.mark.slow
def test_mjx_float32_runs_and_says_so(mjx_python: str, c_python: str) -> None:
    """MJX with x64 off: float32 read back; theta within 1e-3 rad of C (measured 1.2e-5).

    Float32's epsilon is 1.2e-7: over 1500 RK4 steps of a spin of 100 rad/s the rounding of
    the attitude alone reaches ~1e-5 rad, the contact's stiffness amplifies it; 1e-3 rad is
    80x the measurement.

    Its windows: the ball touches in the same windows as in C (every window after row 0;
    within a window the passes that touch differ in 27 of 300: the contact comes and goes
    at different steps once float32 has moved the ball by 1e-7 m). N averaged over every
    pass of the run: 0.1473 N here, 0.1488 N in C (0.95% apart; M g = 0.147 N, the passes
    sample a chattering force), tolerance 3%.
    """
    plan = mujoco_plan("mujoco.friction=native", "run.t_end_s=0.3")
    mjx, _ = remote.simulate_in(mjx_python, plan, engine=MJX32)
    c, _ = remote.simulate_in(c_python, plan)
    assert mjx.status == "ok" and mjx.engine["precision"] == "float32"
    assert mjx.engine["implementation"] == "mjx" and mjx.engine["device"] == "cpu"
    assert 0.0 < _theta_gap(mjx, c) < 1e-3
    _same_touch_after_the_start(mjx, c)
    assert _mean_n(mjx) == pytest.approx(_mean_n(c), rel=0.03)


@pytest.mark.slow
def test_warp_on_the_cpu_is_near_mujoco_40_in_float32() -> None:
    """MuJoCo Warp 4.0 on the CPU, 500 steps (0.1 s), against the MuJoCo 4.0 installed here.

    Warp follows MuJoCo 4.0's pipeline in float32: measured 6.9e-5 rad apart in theta over
    0.3 s (1500 steps), 4.7e-5 over these 500; tolerance 1e-3 rad as for MJX in float32.
    Its windows, added by its kernel in the captured graph: touches in the same windows as
    C's after row 0, and N averaged over every pass 0.1483 N against C's 0.1524 N (2.7%
    apart; over 0.3 s 0.9%: the ball settles, and the passes sample a force that comes and
    goes from step to step at steps float32 has moved); tolerance 5%. The ball's smallest
    gap is in every window, at most its largest; the run's slip weighted by N (the slip
    sums over N's), along y (its larger component here): 0.0355 m/s against C's 0.0372 (4.6%
    apart, the same sampled force), tolerance 10%.
    """
    from tippetop.mujoco_runner.run import simulate_plan

    plan = mujoco_plan("mujoco.friction=native", "run.t_end_s=0.1")
    python = str(envs.accelerated_env_python("warp"))
    warp, info = remote.simulate_in(python, plan, engine=WARP)
    here = simulate_plan(plan)
    assert warp.status == "ok" and warp.n_steps == 500
    e = warp.engine
    assert (e["implementation"], e["version"], e["precision"], e["device"]) == \
        ("warp", envs.WARP_VERSION, "float32", "cpu")
    assert e["path"] in ("worker: warp: captured graph of integrate, forward, window",
                         "worker: warp: loop of integrate, forward, window")
    assert e["contacts_from"] == worker.warp_stepper.WARP_CONTACTS_FROM
    assert np.isfinite(warp.table.to_numpy(dtype=float)).all()
    assert _theta_gap(warp, here) < 1e-3
    assert math.isclose(float(warp.table["t"].iloc[-1]), 0.1)
    _same_touch_after_the_start(warp, here)
    assert (warp.windows.int_column("passes")[1:] == plan.steps_per_sample).all()
    assert _mean_n(warp) == pytest.approx(_mean_n(here), rel=0.05)
    low, high = warp.windows.float_column("gap_min"), warp.windows.float_column("gap_max")
    assert np.isfinite(low).all() and (low <= high).all()
    assert _mean_slip_y(warp) == pytest.approx(_mean_slip_y(here), rel=0.1)


@pytest.mark.slow
def test_warp_paper_mode_applies_the_law_in_its_graph() -> None:
    """Paper mode on Warp: the law's kernel before each forward pass, in the captured graph.

    Against the compiled callback of the MuJoCo 4.0 here, 0.1 s at dt = 2e-5 s (5000 steps):
    measured 4.0e-6 rad apart in theta with Euler (float32 against float64 alone) and 3.6e-5
    with RK4 (the law held over the step against C's call at each stage, as MJX). Tolerance
    1e-4 rad for both; theta itself moves by far more over the run, so a law that did not act
    could not pass. The law's power summed over the run's windows (its kernel's output at
    every pass) within 1e-3 of C's callback's (measured 1.7e-5 with Euler, 1.5e-4 with RK4),
    the mean N within 1e-4 (measured 1.2e-5 and 1.0e-5). The windows' smallest gap within
    1e-7 m of C's (measured 1.3e-8 and 1.2e-8 m on 2.7e-7), the run's slip times N along y
    (its larger component) within 1e-3 (measured 1.8e-5 and 1.1e-4).
    """
    from tippetop.mujoco_runner.run import simulate_plan

    python = str(envs.accelerated_env_python("warp"))
    for integrator in ("Euler", "RK4"):
        plan = mujoco_plan("mujoco.friction=paper", "run.t_end_s=0.1",
                           f"mujoco.integrator={integrator!r}")
        warp, _ = remote.simulate_in(python, plan, engine=WARP)
        here = simulate_plan(plan)
        assert warp.status == here.status == "ok"
        assert warp.engine["path"] == \
            "worker: warp: captured graph of integrate, forward, window"
        assert "qfrc_applied" in warp.engine["law_applied"]
        gap = _theta_gap(warp, here)
        moved = float(np.ptp(here.table["theta"].to_numpy()))
        assert gap < 1e-4 and gap < 0.05 * moved, (integrator, gap, moved)
        power = [float(r.windows.float_column("law_power_sum").sum()) for r in (warp, here)]
        assert power[0] == pytest.approx(power[1], rel=1e-3) and power[1] != 0.0
        assert _mean_n(warp) == pytest.approx(_mean_n(here), rel=1e-4)
        assert _column_gap(warp, here, "gap_min")[0] < 1e-7
        slip = [float(r.windows.float_column("slip_ny_sum").sum()) for r in (warp, here)]
        assert slip[0] == pytest.approx(slip[1], rel=1e-3) and slip[1] != 0.0
        _same_touch_after_the_start(warp, here)


@pytest.fixture(scope="module")
def mjx_python() -> str:
    return str(envs.accelerated_env_python("mjx"))


@pytest.fixture(scope="module")
def c_python() -> str:
    """MuJoCo C of the release MJX follows."""
    return str(envs.env_python(envs.MJX_VERSION))


@pytest.mark.slow
@pytest.mark.parametrize("implementation", ["mjx", "warp"])
def test_an_accelerated_environment_is_made_once_and_found_after(tmp_path: Path,
                                                                 implementation: str) -> None:
    """Made with uv once, then found again in well under a second without running anything.

    From uv's cache here: ~1 s, ~620 MB for MJX (JAX and jaxlib are most of it), ~510 MB for
    Warp (warp-lang's LLVM); the first download took ~3 s each.
    """
    import json
    import time

    said: list[str] = []
    python = envs.accelerated_env_python(implementation, root=tmp_path, say=said.append)
    name, packages = envs.accelerated_packages(implementation)
    folder = envs.named_folder(name, tmp_path)
    assert python == folder / "bin" / "python" and python.exists()
    assert said[0].startswith(f"tippetop: making an environment for {packages[0]} with uv")
    assert " MB in " in said[-1]
    ready = json.loads((folder / envs.READY).read_text())
    assert ready["packages"] == list(packages) and ready["size_mb"] > 0
    t0 = time.perf_counter()
    assert envs.accelerated_env_python(implementation, root=tmp_path, say=said.append) == python
    assert time.perf_counter() - t0 < 1.0 and len(said) == 2
