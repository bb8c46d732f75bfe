"""A probe's run: one small model stepped from a given state, every step recorded.

A probe (``tippetop probe``) is a motion with a closed-form answer: a model of one body
(its MJCF text), its start (``qpos``, ``qvel``) and a duration. :func:`step_probe` compiles
it, sets the integrator and the step the request names (read back into ``ran``), steps it
with plain ``mj_step`` and records **every** step: the time, ``qpos``, ``qvel``, the number
of contacts of the probed body and their summed normal force (``mj_contactForce``), and
MuJoCo's warning counters. What happens between samples is there: nothing is sampled.

MJX and Warp step it on their own arrays (``mjx.step`` in a ``jax.lax.scan``;
``mujoco_warp.step`` in a loop); they record the same columns, the contacts' normal force from
``efc_force`` being MuJoCo C's alone (their columns are NaN there, said in ``engine``).

This module needs ``mujoco`` and ``numpy`` only: the worker runs it in another Python (a
release, a build of the user's own, MJX, Warp), and the harness calls it in its own process
for the MuJoCo installed beside it, so both are the same code.
"""

from __future__ import annotations

import time
from typing import Any

from .protocol import Refused, engine_of
from .windows import integrator_call

#: The arrays :func:`step_probe` returns, one row per step and one for the start.
PROBE_ARRAYS = ("time", "qpos", "qvel", "ncon", "normal_N", "warnings")
#: Most steps a probe may take (a probe is seconds at a millisecond or so).
MAX_STEPS = 2_000_000


def _integrator(mujoco, name: str) -> Any:
    """MuJoCo's enum value for ``name`` (``Euler``, ``RK4``, ...), or Refused (one line)."""
    members = {k.removeprefix("mjINT_").lower(): v
               for k, v in mujoco.mjtIntegrator.__members__.items()}
    if name.lower() not in members:
        raise Refused(f"integrator: expected one of MuJoCo {mujoco.__version__}'s "
                      f"({', '.join(sorted(members))}), got {name!r}")
    return members[name.lower()]


def compile_probe(mujoco, request: dict):
    """The request's model with its integrator and step set: (model, body id)."""
    model = mujoco.MjModel.from_xml_string(request["mjcf"])
    if request.get("integrator"):
        model.opt.integrator = _integrator(mujoco, str(request["integrator"]))
    if request.get("timestep_s") is not None:
        dt = float(request["timestep_s"])
        if not dt > 0:
            raise Refused(f"timestep: expected a positive step in s, got {dt!r}")
        model.opt.timestep = dt
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, str(request["body"]))
    if body < 0:
        raise Refused(f"body: expected a body of the probe's model, got {request['body']!r}")
    return model, body


def ran_options(mujoco, model) -> dict:
    """What runs, read back from the compiled model."""
    opt = model.opt
    return {"timestep_s": float(opt.timestep),
            "integrator": mujoco.mjtIntegrator(int(opt.integrator)).name.removeprefix("mjINT_"),
            "cone": mujoco.mjtCone(int(opt.cone)).name.removeprefix("mjCONE_").lower(),
            "impratio": float(opt.impratio), "noslip_iterations": int(opt.noslip_iterations),
            "gravity_mps2": [float(v) for v in opt.gravity],
            "condim": [int(v) for v in model.geom_condim],
            "friction": [[float(v) for v in row] for row in model.geom_friction]}


def _ball_law(model, body: int, law: dict):
    """Paper mode's law (:class:`.paper_law.PaperLaw`) at the lowest point of the ball ``body``.

    The ball's centre is the body's origin; the normal force is the last evaluation's
    constraint force on the free joint, as paper mode's.
    """
    from .paper_law import PaperLaw

    jnt = int(model.body_jntadr[body])
    if jnt < 0 or int(model.jnt_type[jnt]) != 0:  # mjJNT_FREE
        raise Refused("law: expected the probed body to have a free joint, got none")
    params = {"coulomb_kind": 1, "mu": float(law["mu"]), "Lambda": float(law["Lambda"]),
              "v_eps": 1e-5, "viscous_on": 0, "viscous": 0.0, "R": float(law["R"]),
              "centre": (0.0, 0.0, 0.0), "axis": (0.0, 0.0, 1.0), "stem_kind": 0,
              "stem_l": 0.0, "stem_r": 0.0, "qpos_adr": int(model.jnt_qposadr[jnt]),
              "dof_adr": int(model.jnt_dofadr[jnt])}
    return PaperLaw(model, params)


def _start(mujoco, model, request: dict):
    data = mujoco.MjData(model)
    data.qpos[:] = request["qpos"]
    data.qvel[:] = request["qvel"]
    ctrl = request.get("ctrl") or []
    if len(ctrl) != model.nu:
        raise Refused(f"ctrl: expected {model.nu} controls for the model's actuators, "
                      f"got {len(ctrl)}")
    if model.nu:
        data.ctrl[:] = ctrl
    mujoco.mj_forward(model, data)
    return data


def _contacts(mujoco, np, model, data, body: int, f6) -> tuple[int, float]:
    """The contacts that touch ``body`` and their summed normal force (N)."""
    n, normal = 0, 0.0
    for i in range(data.ncon):
        c = data.contact[i]
        if body in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]) and c.efc_address >= 0:
            mujoco.mj_contactForce(model, data, i, f6)
            n += 1
            normal += float(f6[0])
    return n, normal


def step_probe(mujoco, np, request: dict, progress=None) -> tuple[dict, dict, dict]:
    """Run the probe ``request``: (arrays, ran, engine).

    Args:
        mujoco: The ``mujoco`` module that steps it.
        np: ``numpy``.
        request: ``mjcf``, ``body`` (the probed body's name), ``qpos``, ``qvel``,
            ``duration_s``, and optionally ``integrator``, ``timestep_s``, ``ctrl`` (held
            over the run) and ``engine``
            (:func:`.protocol.engine_of`).
        progress: Called with the simulated time now and then.

    Returns:
        The arrays of :data:`PROBE_ARRAYS` (rows up to the last finite one: a run that
        diverges stops there), what ran (:func:`ran_options`) and what stepped it.

    Raises:
        Refused: An integrator the release does not have, a bad step or body (one line).
    """
    impl, precision = engine_of(request)
    model, body = compile_probe(mujoco, request)
    data = _start(mujoco, model, request)
    dt = float(model.opt.timestep)
    steps = int(round(float(request["duration_s"]) / dt))
    if not 0 < steps <= MAX_STEPS:
        raise Refused(f"duration: expected 1 to {MAX_STEPS} steps of {dt:g} s, got {steps}")
    ran = ran_options(mujoco, model)
    law = None
    if request.get("law"):
        if impl != "mujoco":
            raise Refused(f"law: the paper's law is MuJoCo C's passive callback here, not "
                          f"{impl}'s")
        law = _ball_law(model, body, request["law"])
        ran["friction_law"] = "modified_coulomb (the paper's, by mjcb_passive)"
    engine = {"implementation": impl, "version": mujoco.__version__, "precision": "float64",
              "device": "cpu"}
    t0 = time.perf_counter()
    if law is not None:
        mujoco.set_mjcb_passive(law)
    try:
        if impl == "mujoco":
            arrays = _step_c(mujoco, np, model, data, body, steps, progress)
        elif impl == "mjx":
            arrays, engine = _step_mjx(mujoco, np, model, data, steps, precision)
        else:
            arrays, engine = _step_warp(mujoco, np, model, data, steps)
    finally:
        if law is not None:
            mujoco.set_mjcb_passive(None)
    engine["wall_s"] = time.perf_counter() - t0
    return arrays, ran, engine


def _step_c(mujoco, np, model, data, body: int, steps: int, progress) -> dict:
    """Step MuJoCo C, each row's contacts from its own state's forward pass.

    ``mj_step`` is taken apart (bit for bit the same: :func:`.windows.integrator_call`);
    where the split is not known, ``mj_step`` whole and one more ``mj_forward`` at the
    recorded state (which writes no warm start: the next step is the same).
    """
    n_rows = steps + 1
    out = {"time": np.empty(n_rows), "qpos": np.empty((n_rows, model.nq)),
           "qvel": np.empty((n_rows, model.nv)), "ncon": np.zeros(n_rows, dtype=np.int64),
           "normal_N": np.zeros(n_rows),
           "warnings": np.zeros((n_rows, len(data.warning.number)), dtype=np.int64)}
    f6 = np.zeros(6)
    integrate = integrator_call(mujoco, model)
    check_pos, check_vel, check_acc = mujoco.mj_checkPos, mujoco.mj_checkVel, mujoco.mj_checkAcc
    forward = mujoco.mj_forward
    next_report = time.perf_counter() + 0.2
    n = 0
    while True:
        if integrate is not None:  # mj_step's own forward pass, at the state recorded
            check_pos(model, data)
            check_vel(model, data)
            forward(model, data)
            check_acc(model, data)
        else:
            forward(model, data)
        out["time"][n] = data.time
        out["qpos"][n] = data.qpos
        out["qvel"][n] = data.qvel
        out["ncon"][n], out["normal_N"][n] = _contacts(mujoco, np, model, data, body, f6)
        out["warnings"][n] = data.warning.number
        finite = np.isfinite(out["qpos"][n]).all() and np.isfinite(out["qvel"][n]).all()
        n += 1
        if n == n_rows or not finite:
            return {k: v[:n] for k, v in out.items()}
        if integrate is not None:
            integrate(model, data)
        else:
            mujoco.mj_step(model, data)
        if progress is not None and time.perf_counter() >= next_report:
            progress(float(data.time))
            next_report = time.perf_counter() + 0.2


def _step_mjx(mujoco, np, model, data, steps: int, precision: str) -> tuple[dict, dict]:
    import jax

    jax.config.update("jax_enable_x64", precision == "float64")
    from mujoco import mjx

    m = mjx.put_model(model)
    d = mjx.put_data(model, data)

    def body(d, _):
        new = mjx.step(m, d)
        # the carry keeps its types (under x64 a step's contact indices come back int64)
        new = jax.tree_util.tree_map(lambda a, b: a.astype(b.dtype) if hasattr(a, "astype")
                                     else a, new, d)
        return new, (new.time, new.qpos, new.qvel)

    t0 = time.perf_counter()
    _, (t, qpos, qvel) = jax.jit(lambda d: jax.lax.scan(body, d, None, length=steps))(d)
    t, qpos, qvel = (np.asarray(a, dtype=float) for a in (t, qpos, qvel))
    arrays = _accelerated_rows(np, data, t, qpos, qvel)
    import importlib.metadata as md

    engine = {"implementation": "mjx", "version": md.version("mujoco-mjx"),
              "precision": str(np.asarray(d.qpos).dtype), "device": jax.default_backend(),
              "mujoco_c_version": mujoco.__version__, "first_call_s": time.perf_counter() - t0,
              "contacts_from": "none: the contact columns are MuJoCo C's alone (NaN here)"}
    return arrays, engine


def _step_warp(mujoco, np, model, data, steps: int) -> tuple[dict, dict]:
    import mujoco_warp as mjw
    import warp as wp

    m = mjw.put_model(model)
    d = mjw.put_data(model, data)
    t = np.empty(steps)
    qpos = np.empty((steps, model.nq))
    qvel = np.empty((steps, model.nv))
    for i in range(steps):
        mjw.step(m, d)
        qpos[i], qvel[i] = d.qpos.numpy()[0], d.qvel.numpy()[0]
        t[i] = float(data.time) + (i + 1) * float(model.opt.timestep)
    import importlib.metadata as md

    engine = {"implementation": "warp", "version": md.version("mujoco-warp"),
              "precision": "float32", "device": str(wp.get_device()),
              "mujoco_c_version": mujoco.__version__,
              "contacts_from": "none: the contact columns are MuJoCo C's alone (NaN here)"}
    return _accelerated_rows(np, data, t, qpos, qvel), engine


def _accelerated_rows(np, data, t, qpos, qvel) -> dict:
    """The start's row and the stepped rows, in :data:`PROBE_ARRAYS` (contacts unknown)."""
    n = len(t) + 1
    out = {"time": np.concatenate([[data.time], t]),
           "qpos": np.vstack([data.qpos[None, :], qpos]),
           "qvel": np.vstack([data.qvel[None, :], qvel]),
           "ncon": np.full(n, -1, dtype=np.int64), "normal_N": np.full(n, np.nan),
           "warnings": np.zeros((n, len(data.warning.number)), dtype=np.int64)}
    finite = np.isfinite(out["qpos"]).all(axis=1) & np.isfinite(out["qvel"]).all(axis=1)
    last = int(np.argmin(finite)) + 1 if not finite.all() else n
    return {k: v[:last] for k, v in out.items()}


def answer_probe(request: dict) -> dict:
    """The worker's reply to a probe request; its arrays go to ``request['out']``."""
    import mujoco
    import numpy as np

    from .protocol import say

    arrays, ran, engine = step_probe(mujoco, np, request,
                                     progress=lambda t: say({"t": t}))
    np.savez(request["out"], **arrays)
    return {"status": "ok", "kind": "probe", "ran": ran, "engine": engine,
            "samples": int(len(arrays["time"])),
            "warning_names": [mujoco.mjtWarning(i).name
                              for i in range(arrays["warnings"].shape[1])]}


__all__ = ["MAX_STEPS", "PROBE_ARRAYS", "answer_probe", "compile_probe", "ran_options",
           "step_probe"]
