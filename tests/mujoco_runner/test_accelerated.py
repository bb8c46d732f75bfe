"""MuJoCo MJX (JAX) and MuJoCo Warp run a plan through the worker, on the CPU here.

Fast (no JAX, no Warp): the request carries the engine; an engine the worker cannot run is one
line; the paper's law written in array arithmetic (what MJX traces) is the Python callback's to
rounding, with a stem and without.

Slow (managed environments, JAX's and Warp's compilers): MJX in float64 against MuJoCo C of
the release MJX follows (``mujoco==3.17.0``, the same worker), in native and paper mode; MJX in
float32; Warp for 500 steps against the MuJoCo 4.0 installed here, and in paper mode (the
law as a Warp kernel in the captured graph). Each says what ran, read back. Measured on 2
shared CPU cores: MJX's worker takes 10 to 25 s a run, most of it compiling (setup ~5-9 s,
the first jitted call ~9-19 s; JAX's persistent cache under ``$TIPPETOP_CACHE/jax`` shortens
a rerun), then ~200 us a step; Warp compiles its kernels once (~30 s, kept in Warp's own
cache), then ~100 us a step as a captured graph.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import mujoco_plan
from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner import envs, remote, worker
from tippetop.mujoco_runner.settings import build_model

pytestmark = pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")

MJX64 = {"implementation": "mjx", "precision": "float64"}
MJX32 = {"implementation": "mjx", "precision": "float32"}
WARP = {"implementation": "warp", "precision": "float32"}


def test_the_request_carries_the_engine(tmp_path: Path) -> None:
    plan = mujoco_plan("run.t_end_s=0.01")
    top = build_model(plan)
    req = remote.request(plan, top, tmp_path / "x.npz", MJX32)
    assert req["protocol"] == worker.PROTOCOL == 4
    assert req["engine"] == MJX32
    assert remote.request(plan, top, tmp_path / "x.npz")["engine"] == remote.DEFAULT_ENGINE


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


@pytest.fixture(scope="module")
def mjx_python() -> str:
    return str(envs.accelerated_env_python("mjx"))


@pytest.fixture(scope="module")
def c_python() -> str:
    """MuJoCo C of the release MJX follows."""
    return str(envs.env_python(envs.MJX_VERSION))


@pytest.mark.slow
def test_mjx_float64_is_mujoco_c_of_its_release_on_the_cpu(mjx_python: str,
                                                           c_python: str) -> None:
    """MJX (JAX, float64, CPU) against MuJoCo C 3.17.0: 0.3 s of the default scene, native.

    Both run the same algorithms on the same compiled model (RK4 at dt = 2e-4 s, a pyramidal
    sphere-plane contact, the Newton solver to tolerance 1e-8): MJX is a JAX port of MuJoCo's
    pipeline, so what differs is floating-point order (XLA fuses and reorders sums; MJX's
    solver runs a fixed-shape loop), rounding-sized per step and grown by the contact's
    stiffness and the solver's tolerance. Measured: theta apart by 3.3e-9 rad at most, the
    positions by 2e-9 (quaternion) and 6e-12 m. Tolerance 1e-7 rad: 30x the measurement,
    still 1e5 times below the 1e-2 rad the nightly allows between engines, so a real
    difference (a collision or a solver MJX does differently) cannot hide in it.
    """
    plan = mujoco_plan("mujoco.friction=native", "run.t_end_s=0.3")
    mjx, info = remote.simulate_in(mjx_python, plan, engine=MJX64)
    c, _ = remote.simulate_in(c_python, plan)
    assert mjx.status == c.status == "ok" and info.version == envs.MJX_VERSION
    e = mjx.engine
    assert (e["implementation"], e["version"], e["precision"], e["device"]) == \
        ("mjx", envs.MJX_VERSION, "float64", "cpu")
    assert e["path"] == "worker: mjx: jit(fori_loop(step))"
    assert e["mujoco_c_version"] == envs.MJX_VERSION
    assert e["contacts_from"] == "MuJoCo C at the sample states"
    assert mjx.ran == c.ran and len(mjx.table) == len(c.table) == 301
    assert _theta_gap(mjx, c) < 1e-7
    assert np.max(np.abs(mjx.table[["x", "y", "z"]].to_numpy()
                         - c.table[["x", "y", "z"]].to_numpy())) < 1e-9


@pytest.mark.slow
def test_mjx_paper_mode_differs_from_c_only_by_when_the_law_is_evaluated(
        mjx_python: str, c_python: str) -> None:
    """Paper mode: MJX puts the law in ``qfrc_applied`` once a step, C calls it in each stage.

    With Euler (one evaluation a step in both, at the step's start state with the previous
    step's constraint force) the two agree to rounding: measured 5.8e-16 rad over 0.3 s
    (tolerance 1e-12). With RK4, C evaluates the law at each of the four stages while MJX holds
    the step's first one: measured 6.2e-5 rad over 0.3 s at dt = 2e-5 s. That difference
    follows the integrator and nothing else; it is asserted between 1e-6 and 1e-3 rad.
    """
    euler = mujoco_plan("mujoco.friction=paper", "run.t_end_s=0.3",
                        "mujoco.integrator='Euler'")
    mjx, _ = remote.simulate_in(mjx_python, euler, engine=MJX64)
    c, _ = remote.simulate_in(c_python, euler)
    assert mjx.status == c.status == "ok"
    assert "qfrc_applied" in mjx.engine["law_applied"]
    assert _theta_gap(mjx, c) < 1e-12
    # the law's output at the samples is filled (MuJoCo C's passes at MJX's states)
    assert np.abs(mjx.table["P_fric"].to_numpy()[1:]).max() > 0.0
    rk4 = mujoco_plan("mujoco.friction=paper", "run.t_end_s=0.3")
    mjx, _ = remote.simulate_in(mjx_python, rk4, engine=MJX64)
    c, _ = remote.simulate_in(c_python, rk4)
    assert mjx.status == c.status == "ok"
    assert 1e-6 < _theta_gap(mjx, c) < 1e-3


@pytest.mark.slow
def test_mjx_float32_runs_and_says_so(mjx_python: str, c_python: str) -> None:
    """MJX with x64 off: float32 read back; theta within 1e-3 rad of C (measured 6.6e-5).

    Float32's epsilon is 1.2e-7: over 1500 RK4 steps of a spin of 100 rad/s the rounding of
    the attitude alone reaches ~1e-5 rad, the contact's stiffness amplifies it; 1e-3 rad is
    15x the measurement.
    """
    plan = mujoco_plan("mujoco.friction=native", "run.t_end_s=0.3")
    mjx, _ = remote.simulate_in(mjx_python, plan, engine=MJX32)
    c, _ = remote.simulate_in(c_python, plan)
    assert mjx.status == "ok" and mjx.engine["precision"] == "float32"
    assert mjx.engine["implementation"] == "mjx" and mjx.engine["device"] == "cpu"
    assert 0.0 < _theta_gap(mjx, c) < 1e-3


@pytest.mark.slow
def test_warp_on_the_cpu_is_near_mujoco_40_in_float32() -> None:
    """MuJoCo Warp 4.0 on the CPU, 500 steps (0.1 s), against the MuJoCo 4.0 installed here.

    Warp follows MuJoCo 4.0's pipeline in float32: measured 5.1e-5 rad apart in theta over
    0.3 s (1500 steps), 1.2e-5 over these 500; tolerance 1e-3 rad as for MJX in float32.
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
    assert e["path"] in ("worker: warp: captured graph of step", "worker: warp: step loop")
    assert np.isfinite(warp.table.to_numpy(dtype=float)).all()
    assert _theta_gap(warp, here) < 1e-3
    assert math.isclose(float(warp.table["t"].iloc[-1]), 0.1)


@pytest.mark.slow
def test_warp_paper_mode_applies_the_law_in_its_graph() -> None:
    """Paper mode on Warp: the law's kernel before each step, in the captured graph.

    Against the compiled callback of the MuJoCo 4.0 here, 0.1 s at dt = 2e-5 s (5000 steps):
    measured 4.0e-6 rad apart in theta with Euler (float32 against float64 alone) and 3.6e-5
    with RK4 (the law held over the step against C's call at each stage, as MJX). Tolerance
    1e-4 rad for both; theta itself moves by far more over the run, so a law that did not act
    could not pass.
    """
    from tippetop.mujoco_runner.run import simulate_plan

    python = str(envs.accelerated_env_python("warp"))
    for integrator in ("Euler", "RK4"):
        plan = mujoco_plan("mujoco.friction=paper", "run.t_end_s=0.1",
                           f"mujoco.integrator={integrator!r}")
        warp, _ = remote.simulate_in(python, plan, engine=WARP)
        here = simulate_plan(plan)
        assert warp.status == here.status == "ok"
        assert warp.engine["path"] == "worker: warp: captured graph of step"
        assert "qfrc_applied" in warp.engine["law_applied"]
        gap = _theta_gap(warp, here)
        moved = float(np.ptp(here.table["theta"].to_numpy()))
        assert gap < 1e-4 and gap < 0.05 * moved, (integrator, gap, moved)


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
