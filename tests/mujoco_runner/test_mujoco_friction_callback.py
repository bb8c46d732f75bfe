"""The compiled passive callback that applies the paper's friction law."""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
import sys
import textwrap
from importlib.util import find_spec
from pathlib import Path

import mujoco
import numba
import numpy as np
import pytest

from tippetop.models.errors import TippetopError
from tippetop.models.mjcf import HARNESS_USERDATA, MjcfContact, MjcfOption, make_mjcf
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.models.resolve import PAPER_SOLREF
from tippetop.mujoco_runner import friction_callback
from tippetop.mujoco_runner.friction_callback import (
    USERDATA_SIZE,
    PaperFriction,
    baked_layout,
    callback_installed,
    compiled_callback,
    friction_xy,
    law_force,
    law_parameters,
    struct_layout,
    userdata_block,
)
from tippetop.mujoco_runner.model import TopModelWarning, load_model, load_top, top_from_model
from tippetop.mujoco_runner.state import initial_qpos_qvel, kinematics
from tippetop.reference_ode.friction import LAW_TERMS, friction_terms
from tippetop.reference_ode.params_array import (
    P_CVISC,
    P_LAM,
    P_MU,
    P_VEPS,
    friction_law,
    pack_params,
)
from tippetop.reference_ode.solve import observables_table

TOP = TopParams.from_ratios(0.95, 0.125)
INIT = InitialState(theta0=0.4, thetadot0=1.0, Omega0=5.0, n0=100.0, uOX=0.02, uOY=-0.01)
FRICTION = FrictionParams()
_GENERIC = """<mujoco><option timestep="2e-5" integrator="RK4" gravity="0 0 -9.8"/>
  <worldbody><geom type="plane" size="1 1 .1" condim="1"/>
  <body pos="0 0 0.1"><freejoint/>
    <inertial pos="0 0 0" mass="0.015" diaginertia="1.2825e-6 1.35e-6 1.2825e-6"/>
    <geom type="sphere" size="0.015" pos="0 -0.001875 0" condim="1"/>
  </body></worldbody></mujoco>"""
_GENERIC_USERDATA = _GENERIC.replace("<mujoco>", '<mujoco><size nuserdata="5"/>')


@pytest.fixture(autouse=True)
def _no_leftover_callback():
    yield
    assert friction_callback._install_count == 0, "a test left a callback context open"
    mujoco.set_mjcb_passive(None)


def _start(tm):
    data = mujoco.MjData(tm.model)
    data.qpos[:], data.qvel[:] = initial_qpos_qvel(tm, INIT)
    return data


def _python_reference(tm, data, params):
    """The plain path: same law, N and P, applied with MuJoCo's own mj_applyFT."""
    top = tm.top

    def callback(model, d):
        if d._address != data._address:
            return
        kin = kinematics(tm, d.qpos, d.qvel)
        N = max(d.qfrc_constraint[tm.dof_adr + 2], 0.0)
        force = law_force(params, kin.v_P_mps, np.array([N]))[0]
        point = kin.centre_m[0] - [0.0, 0.0, top.R_m]
        mujoco.mj_applyFT(model, d, force, np.zeros(3), point, tm.body_id, d.qfrc_passive)

    return callback


@pytest.mark.parametrize("xml", ["generated", "generic"])
def test_compiled_callback_matches_mj_applyFT_reference(xml: str) -> None:
    """The force is added to ``qfrc_passive`` (MuJoCo fills it before calling the callback,
    which must add, not overwrite) as the free joint's generalized force: the world force F on
    the translational dofs and the torque (P - body origin) x F, rotated into the body frame,
    on the rotational dofs. That is J^T F for the Jacobian of the material point at P, i.e.
    what ``mj_applyFT(F, 0, P)`` gives: checked here against a Python callback using
    ``mj_applyFT``."""
    # Same law, same N source, same point: the trajectories agree to rounding after 600
    # RK4 steps (2400 callback calls) through the tilted, spinning, sliding start.
    if xml == "generated":
        tm = load_top(make_mjcf(TOP))
    else:
        with pytest.warns(TopModelWarning, match="origin"):
            tm = load_top(_GENERIC)
    fast, slow = _start(tm), _start(tm)
    with PaperFriction(tm, fast, FRICTION):
        mujoco.mj_forward(tm.model, fast)
        mujoco.mj_step(tm.model, fast, 600)
    mujoco.set_mjcb_passive(_python_reference(tm, slow, law_parameters(FRICTION, tm)))
    mujoco.mj_forward(tm.model, slow)
    mujoco.mj_step(tm.model, slow, 600)
    mujoco.set_mjcb_passive(None)
    np.testing.assert_allclose(fast.qpos, slow.qpos, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(fast.qvel, slow.qvel, rtol=1e-10, atol=1e-12)
    assert np.abs(fast.qvel - _start(tm).qvel).max() > 1e-3  # friction did act


@pytest.mark.parametrize(("integrator", "calls_per_step"), [("RK4", 4), ("Euler", 1)])
def test_calls_per_step(integrator: str, calls_per_step: int) -> None:
    tm = load_top(make_mjcf(TOP, option=MjcfOption(integrator=integrator)))
    data = _start(tm)
    with PaperFriction(tm, data, FRICTION) as friction:
        mujoco.mj_step(tm.model, data, 100)
        assert friction.n_calls == calls_per_step * 100


def test_callback_acts_on_its_data_only_and_restores_previous() -> None:
    tm = load_top(make_mjcf(TOP))
    data, other = _start(tm), _start(tm)

    def previous(model, d):  # a user's callback, restored when the last context closes
        d.qfrc_passive[0] += 0.0

    mujoco.set_mjcb_passive(previous)
    with PaperFriction(tm, data, FRICTION):
        mujoco.mj_step(tm.model, data, 200)  # into the contact: N > 0
        mujoco.mj_step(tm.model, other, 200)
        assert np.abs(data.qfrc_passive).max() > 0
        np.testing.assert_array_equal(other.qfrc_passive, 0.0)
        with pytest.raises(RuntimeError, match="already armed"):
            PaperFriction(tm, data, FRICTION).__enter__()
        with PaperFriction(tm, other, FRICTION):  # several data may be armed at once
            assert mujoco.get_mjcb_passive() is not previous
        assert mujoco.get_mjcb_passive() is not previous  # data's context is still open
        mujoco.mj_forward(tm.model, other)  # disarmed again
        np.testing.assert_array_equal(other.qfrc_passive, 0.0)
    assert mujoco.get_mjcb_passive() is previous
    mujoco.mj_forward(tm.model, data)
    np.testing.assert_array_equal(data.qfrc_passive, 0.0)


def test_normal_force_is_the_previous_evaluation_constraint_force() -> None:
    # Euler: a step evaluates the forces at the state it starts from. After 499 steps (10 ms,
    # 20 time constants of paper mode's stiff contact, solref 0.5 ms: the contact has settled)
    # the 500th step's constraint force is the callback's N in the next evaluation, and it is
    # the contact force of the rigid-contact reference at the same state: the reference's
    # right-hand side solves N from the constraint (N = 0.977 M g here: the tilted, nutating
    # top is not in static balance). Measured: 7.7e-6 of M g apart (the ball's 0.27-um sink,
    # delta / R ~ 2e-5, and the callback's N one evaluation late); bound 1e-4 of M g. With
    # MuJoCo's default contact (solref 20 ms) still ringing at 10 ms, 3 % apart.
    tm = load_top(make_mjcf(TOP, contact=MjcfContact(solref=PAPER_SOLREF),
                            option=MjcfOption(integrator="Euler")))
    data = _start(tm)
    with PaperFriction(tm, data, FRICTION) as friction:
        mujoco.mj_step(tm.model, data, 499)
        qpos, qvel = data.qpos.copy(), data.qvel.copy()
        mujoco.mj_step(tm.model, data)
        before = data.qfrc_constraint[tm.dof_adr + 2]
        mujoco.mj_step(tm.model, data)
        assert friction.last_force[2] == before
    kin = kinematics(tm, qpos[None], qvel[None])
    y = np.concatenate([kin.com_m[0, :2], kin.v_com_mps[0, :2], qpos[3:7], kin.omega_radps[0]])
    ref = observables_table("vector", FRICTION, pack_params(TOP, FRICTION), np.zeros(1),
                            y[None, :]).iloc[0]
    weight = TOP.M_kg * TOP.g_mps2
    assert abs(ref["N"] / weight - 1.0) > 0.01  # a state where N differs from M g
    assert abs(before - ref["N"]) < 1e-4 * weight


def test_law_values() -> None:
    """The callback's law is the reference's: same terms, same numbers."""
    v = np.array([0.03, -0.04])  # |v| = 0.05 m/s
    N, mu, lam, c, eps = 0.147, 0.1, 0.01, 2.0, 1e-5

    def f(law: str, vx: float, vy: float) -> tuple[float, float]:
        ck, visc = LAW_TERMS[law]
        return friction_xy(vx, vy, N, ck, int(visc), mu, lam, c, eps)

    np.testing.assert_allclose(f("modified_coulomb", *v), -mu * N * v / np.sqrt(0.05**2 + lam**2),
                               rtol=1e-15)
    np.testing.assert_allclose(f("coulomb", *v), -mu * N * v / 0.05, rtol=1e-15)
    assert f("coulomb", 1e-6, 0.0)[0] == pytest.approx(-mu * N * 1e-6 / eps)  # the ramp
    np.testing.assert_allclose(f("viscous", *v), -c * v, rtol=1e-15)
    np.testing.assert_allclose(f("coulomb_viscous", *v), -mu * N * v / 0.05 - c * v, rtol=1e-14)
    assert f("none", *v) == (0.0, 0.0)


@pytest.mark.parametrize("law", sorted(LAW_TERMS))
def test_every_reference_law_is_the_references_force(law: str) -> None:
    # For every law, the callback's force from its parameters (law_parameters) equals the
    # reference ODE's friction terms from its packed parameters, at slips inside and outside
    # Lambda and the exact law's ramp: the two engines map a FrictionParams to the same force.
    # Non-default coefficients, so that a parameter mixed up or defaulted shows.
    tm = load_top(make_mjcf(TOP))
    fr = FrictionParams(law=law, mu=0.23, Lambda_mps=0.004, viscous_Nspm=0.7,
                        coulomb_v_eps_mps=3e-6)
    params = law_parameters(fr, tm)
    p = pack_params(TOP, fr)
    ck, visc = friction_law(p)
    N = 0.131
    for vx, vy in [(0.03, -0.04), (1e-6, 2e-6), (-2e-3, 5e-4), (0.0, 0.0), (-0.7, 0.2)]:
        fx, fy = friction_xy(vx, vy, N, params["coulomb_kind"], params["viscous_on"],
                             params["mu"], params["Lambda"], params["viscous"], params["v_eps"])
        phix, phiy, psix, psiy = friction_terms(ck, visc, vx, vy, p[P_MU], p[P_LAM],
                                                p[P_CVISC], p[P_VEPS])
        assert (fx, fy) == pytest.approx((N * phix + psix, N * phiy + psiy), rel=1e-15,
                                         abs=1e-300), (vx, vy)


def _run(tm, data, steps, model=None):
    """mj_forward (the runner's first N), then ``steps`` steps."""
    model = tm.model if model is None else model
    mujoco.mj_forward(model, data)
    mujoco.mj_step(model, data, steps)


def _bits(data) -> bytes:
    return data.qpos.tobytes() + data.qvel.tobytes() + data.qacc_warmstart.tobytes()


def test_the_callback_reads_the_mjdata_it_is_given() -> None:
    # Two mjData of one model, armed with different mu and stepped alternately, each equal its
    # own run alone bit for bit: each call reads and writes only the mjData it is given, so the
    # same floating-point operations run in the same order (no tolerance is needed or given).
    tm = load_top(make_mjcf(TOP))
    alone = {}
    for mu in (0.05, 0.3):
        data = _start(tm)
        with PaperFriction(tm, data, FRICTION, mu=mu) as f:
            _run(tm, data, 400)
            alone[mu] = (_bits(data), f.n_calls, f.last_force)
    a, b = _start(tm), _start(tm)
    with (PaperFriction(tm, a, FRICTION, mu=0.05) as fa,
          PaperFriction(tm, b, FRICTION, mu=0.3) as fb):
        mujoco.mj_forward(tm.model, a)
        mujoco.mj_forward(tm.model, b)
        for _ in range(8):
            mujoco.mj_step(tm.model, a, 50)
            mujoco.mj_step(tm.model, b, 50)
        assert (_bits(a), fa.n_calls, fa.last_force) == alone[0.05]
        assert (_bits(b), fb.n_calls, fb.last_force) == alone[0.3]
    assert alone[0.05][0] != alone[0.3][0]  # the two laws did differ


def test_unarmed_data_steps_frictionless() -> None:
    # The same model stepped with no callback at all, armed with the law "none" (a force of
    # exactly +0.0), and unarmed while another mjData is armed: bit-identical trajectories.
    tm = load_top(make_mjcf(TOP))
    bare = _start(tm)
    _run(tm, bare, 400)
    none = _start(tm)
    with PaperFriction(tm, none, FrictionParams(law="none")) as f:
        _run(tm, none, 400)
        assert f.n_calls == 4 * 400 + 1
    armed, unarmed = _start(tm), _start(tm)
    scratch = mujoco.MjData(tm.model)  # the runner's scratch copy: qpos and qvel only
    other_model = load_model(make_mjcf(TOP))  # same document, another mjModel
    foreign = mujoco.MjData(other_model)
    with PaperFriction(tm, armed, FRICTION):
        mujoco.mj_forward(tm.model, armed)
        scratch.qpos[:], scratch.qvel[:] = armed.qpos, armed.qvel
        foreign.qpos[:], foreign.qvel[:] = unarmed.qpos, unarmed.qvel
        foreign.userdata[:] = armed.userdata  # armed, but for tm.model: ignored
        copied = foreign.userdata.copy()
        _run(tm, unarmed, 400)
        _run(tm, foreign, 400, other_model)
        mujoco.mj_forward(tm.model, scratch)
        np.testing.assert_array_equal(scratch.qfrc_passive, 0.0)
        mujoco.mj_step(tm.model, armed, 400)
    assert _bits(none) == _bits(bare) == _bits(unarmed)
    assert _bits(foreign) == _bits(bare)
    assert foreign.userdata.tobytes() == copied.tobytes()  # not a call counted on it
    assert _bits(armed) != _bits(bare)


@pytest.mark.skipif(find_spec("mujoco.batch") is None, reason="this MuJoCo has no mujoco.batch")
def test_batch_on_two_threads_equals_single_runs() -> None:
    # mujoco.batch.Batch steps many simulations of one model on a thread pool, each from its
    # state row (which holds userdata, so each row is armed with its own mu). It must be
    # persistent (qfrc_constraint, the callback's N, is not in the state rows) and run on the
    # caller's model (set_models; its own copy has another address). Then: bit for bit.
    from mujoco import batch as mjbatch

    tm = load_top(make_mjcf(TOP))
    mus = (0.02, 0.1, 0.2, 0.4)
    inits = [InitialState(theta0=0.1 + 0.2 * i, n0=100.0, uOX=0.02 * (i - 1)) for i in range(4)]
    single = []
    for mu, init in zip(mus, inits, strict=True):
        data = mujoco.MjData(tm.model)
        data.qpos[:], data.qvel[:] = initial_qpos_qvel(tm, init)
        with PaperFriction(tm, data, FRICTION, mu=mu) as f:
            _run(tm, data, 400)
            single.append((data.qpos.copy(), data.qvel.copy(), f.n_calls))
    batch = mjbatch.Batch(tm.model, nsim=len(mus), nthread=2, persistent=True)
    batch.set_models(tm.model)
    for i, (mu, init) in enumerate(zip(mus, inits, strict=True)):
        batch.qpos[i], batch.qvel[i] = initial_qpos_qvel(tm, init)
        batch.userdata[i, -USERDATA_SIZE:] = userdata_block(tm, FRICTION, mu=mu)
    with callback_installed():
        batch.forward()
        for _ in range(4):
            batch.step(nstep=100)
    for i, (qpos, qvel, n_calls) in enumerate(single):
        assert batch.qpos[i].tobytes() == qpos.tobytes()
        assert batch.qvel[i].tobytes() == qvel.tobytes()
        assert batch.userdata[i, -1] == n_calls
    assert len({q.tobytes() for q, _, _ in single}) == len(mus)


def test_struct_layout_matches_the_bindings() -> None:
    # The offsets found on the probes hold this model's pointers and size too.
    with pytest.warns(TopModelWarning, match="origin"):
        tm = load_top(_GENERIC_USERDATA)
    data = mujoco.MjData(tm.model)
    mujoco.mj_forward(tm.model, data)
    layout = struct_layout()

    def word(address: int, offset: int) -> int:
        return ctypes.c_uint64.from_address(address + offset).value

    for name in ("qpos", "qvel", "userdata", "qfrc_passive", "qfrc_constraint"):
        assert word(data._address, getattr(layout, name)) == getattr(data, name).ctypes.data
    integer = {8: ctypes.c_int64, 4: ctypes.c_int32}[layout.nuserdata_width]
    assert integer.from_address(tm.model._address + layout.nuserdata).value == tm.model.nuserdata
    assert baked_layout(compiled_callback()) == layout


def _fields(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Every array and number of a model, its options, visual and statistics."""
    out = {}
    for prefix, obj in (("", model), ("opt.", model.opt), ("vis.", model.vis),
                        ("stat.", model.stat)):
        for name in dir(obj):
            value = getattr(obj, name, None) if not name.startswith("_") else None
            if isinstance(value, (np.ndarray, int, float)):
                out[prefix + name] = np.array(value, copy=True)
    for name in ("global_", "headlight", "map", "quality", "scale", "rgba"):
        sub = getattr(model.vis, name)
        for field in dir(sub):
            value = getattr(sub, field, None) if not field.startswith("_") else None
            if isinstance(value, (np.ndarray, int, float)):
                out[f"vis.{name}.{field}"] = np.array(value, copy=True)
    return out


@pytest.mark.parametrize("source", ["generated", "generic", "include"])
def test_loaded_model_differs_from_mujocos_only_in_nuserdata(source: str, tmp_path: Path) -> None:
    # load_model compiles through MjSpec to append the harness's userdata; everything else
    # (options, geoms, bodies, names, contacts...) equals MjModel.from_xml_path's, exactly.
    path = tmp_path / "top.xml"
    if source == "include":  # a file that includes another, with a user nuserdata
        (tmp_path / "parts").mkdir()
        (tmp_path / "parts" / "ball.xml").write_text(
            '<mujocoinclude><geom type="sphere" size="0.015" pos="0 -0.001875 0" condim="1"/>'
            "</mujocoinclude>")
        path.write_text(_GENERIC_USERDATA.replace(
            '<geom type="sphere" size="0.015" pos="0 -0.001875 0" condim="1"/>',
            '<include file="parts/ball.xml"/>'))
    else:
        path.write_text(make_mjcf(TOP) if source == "generated" else _GENERIC_USERDATA)
    ours, mujocos = load_model(path), mujoco.MjModel.from_xml_path(str(path))
    assert ours.nuserdata == mujocos.nuserdata + HARNESS_USERDATA
    assert mujocos.nuserdata == (HARNESS_USERDATA if source == "generated" else 5)
    a, b = _fields(ours), _fields(mujocos)
    assert a.keys() == b.keys() and len(a) > 500
    different = [k for k in a if a[k].shape != b[k].shape
                 or not np.array_equal(a[k], b[k], equal_nan=True)]
    assert different == ["nuserdata"]
    if source != "include":  # MJCF text takes the same path
        assert _fields(load_model(path.read_text())).keys() == a.keys()
        assert load_model(path.read_text()).nuserdata == ours.nuserdata


def test_users_own_userdata_is_left_in_front() -> None:
    with pytest.warns(TopModelWarning, match="origin"):
        tm = load_top(_GENERIC_USERDATA)
    assert tm.model.nuserdata == 5 + USERDATA_SIZE
    data = _start(tm)
    data.userdata[:5] = [1.0, 2.0, 3.0, 4.0, 5.0]
    with PaperFriction(tm, data, FRICTION) as f:
        _run(tm, data, 100)
        assert f.n_calls == 401
    np.testing.assert_array_equal(data.userdata[:5], [1.0, 2.0, 3.0, 4.0, 5.0])


def test_model_without_room_in_userdata_is_refused() -> None:
    with pytest.warns(TopModelWarning, match="origin"):
        tm = top_from_model(mujoco.MjModel.from_xml_string(_GENERIC))
    with pytest.raises(TippetopError, match=f"nuserdata: expected >= {USERDATA_SIZE}"):
        PaperFriction(tm, mujoco.MjData(tm.model), FRICTION)


_CACHE_SCRIPT = textwrap.dedent("""
    import json, sys, time, warnings
    from dataclasses import astuple

    import numba

    t0 = time.perf_counter()
    from numba.core import registry
    registry.cpu_target.target_context.refresh()  # numba's own start-up, paid by any jit use
    from tippetop.mujoco_runner import friction_callback as fc
    fc.struct_layout()
    if sys.argv[1] == "fake":  # compile (never run!) a callback for another struct layout
        real = fc.struct_layout()
        fake = fc.StructLayout(*(v + 8 for v in astuple(real)[:6]), real.nuserdata_width)
        fc.struct_layout = lambda: fake
    t1 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        callback = fc.compiled_callback()
    t2 = time.perf_counter()
    print(json.dumps({
        "seconds": t2 - t1, "cache_hits": callback.cache_hits,
        "baked": list(astuple(fc.baked_layout(callback))),
        "layout": list(astuple(fc.struct_layout())),
        "warnings": [type(w.message).__name__ for w in caught],
        "folder": str(numba.config.CACHE_DIR),
    }))
""")


def _subprocess(cache_dir: Path | None, mode: str = "real") -> dict:
    """Run :data:`_CACHE_SCRIPT` in a fresh process (``cache_dir`` None: the usual folder)."""
    env = dict(os.environ) | ({} if cache_dir is None else {"NUMBA_CACHE_DIR": str(cache_dir)})
    out = subprocess.run([sys.executable, "-c", _CACHE_SCRIPT, mode], env=env,
                         capture_output=True, text=True, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_callback_is_served_from_numbas_disk_cache(tmp_path: Path) -> None:
    # A fresh process with an empty cache compiles the callback (cache_hits 0) and saves it; a
    # second process loads it (cache_hits 1). Measured here: ~0.9 s against ~5 ms; the bound
    # (a third) leaves room for a loaded machine.
    first = _subprocess(tmp_path)
    second = _subprocess(tmp_path)
    assert (first["cache_hits"], second["cache_hits"]) == (0, 1)
    assert first["warnings"] == second["warnings"] == []
    assert first["baked"] == first["layout"] == second["baked"] == second["layout"]
    assert second["seconds"] < first["seconds"] / 3, (first, second)


def test_callback_is_cached_in_the_configured_folder() -> None:
    # Without NUMBA_CACHE_DIR: the folder reference_ode._jit configures. This process has the
    # callback (compiled and saved, or loaded): a fresh process loads it.
    compiled_callback()
    report = _subprocess(None)
    if report["folder"] != str(numba.config.CACHE_DIR):  # pragma: no cover
        pytest.skip("the reference sources changed during the test (a new cache folder)")
    assert report["cache_hits"] == 1


def test_stale_cache_is_compiled_afresh(tmp_path: Path) -> None:
    # A cache written for another layout (same sources, so numba would serve it) is detected
    # from the constants the cached callback reports, and the callback compiled afresh.
    stale = _subprocess(tmp_path, "fake")
    assert stale["cache_hits"] == 0 and stale["baked"] == stale["layout"]
    fresh = _subprocess(tmp_path)
    assert fresh["warnings"] == ["StaleCallbackWarning"]
    assert fresh["baked"] == fresh["layout"] != stale["baked"]
    assert fresh["cache_hits"] == 0  # the afresh compilation, not the stale entry
