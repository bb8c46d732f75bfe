"""The worker's work: each request's plan run, its arrays written and its reply, in turn.

:func:`main` answers the requests on stdin one after another (:func:`answer`); :func:`run`
steps one plan and writes its arrays.

The request's optional ``engine`` (``{"implementation": "mujoco"|"mjx"|"warp", "precision":
"float64"|"float32"}``) picks what steps the plan: MuJoCo C (``mj_step``, the default), MuJoCo
MJX on JAX (one jitted ``fori_loop`` of ``mjx.step`` per sample interval; float32 unless
``jax_enable_x64``) or MuJoCo Warp (float32; the interval's steps captured once as a Warp
graph, or ``mjw.step`` in a loop where capture fails). Those two need their packages beside
``mujoco`` (a managed environment holds them). The model is compiled by MuJoCo C either way
and the start set and ``mj_forward``-ed there; the states are read back from the device at
each sample, and the contacts at each sample (and paper mode's law output) come from MuJoCo
C's ``mj_forward`` at those states. MJX and Warp have no warning counters (their column is
zeros). Paper mode's law is a force of the engine's own there: before each step the law's
force from the current state and the previous step's ``qfrc_constraint`` goes into
``qfrc_applied`` (MJX: the arithmetic of :class:`PaperLaw` in ``jax.numpy`` inside the jitted
loop; Warp: the same in a Warp kernel launched before each step, inside the captured graph).
C's callback is called at every stage of RK4, the applied force is held over the step: the
two agree to rounding with Euler. The request's optional ``compile_cache`` is JAX's persistent
compilation cache folder (a later run of the same model skips most of MJX's compile).

The reply's ``engine`` says what stepped, read back: ``implementation``, ``version`` (MuJoCo
C's, or ``mujoco-mjx``'s / ``mujoco-warp``'s package version), ``precision`` (the dtype of
the device's ``qpos``), ``device`` (JAX's platform, Warp's device alias); for MJX and Warp
also ``device_kind``, ``path``, ``mujoco_c_version``, ``warnings``, ``contacts_from``,
``setup_s`` and ``first_call_s`` (the compile), and ``law_applied`` in paper mode.
"""

from __future__ import annotations

import json
import sys
import time
import traceback
from typing import Any

from .mjx_stepper import MjxStepper
from .paper_law import PaperLaw
from .protocol import PROGRESS_S, PROTOCOL, Refused, engine_of, say
from .warp_stepper import WarpStepper

#: Forward passes per sample in paper mode (the law's N iterated to the state's own), as in
#: the harness's own runs.
N_FORCE_PASSES = 3


def _free_joint(mujoco, model) -> int:
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1:
        raise ValueError(f"expected one free joint, got {len(free)}")
    return free[0]


def _ran(mujoco, model, data, body: int, ball: int) -> dict:
    """What runs, read back from the model and from the top's first contact at t = 0.

    The ball geom's own values when nothing touches then.
    """
    opt = model.opt
    out = {"timestep_s": float(opt.timestep),
           "integrator": mujoco.mjtIntegrator(int(opt.integrator)).name,
           "cone": mujoco.mjtCone(int(opt.cone)).name, "impratio": float(opt.impratio),
           "noslip_iterations": int(opt.noslip_iterations),
           "gravity_mps2": float(-opt.gravity[2]), "iterations": int(opt.iterations),
           "tolerance": float(opt.tolerance),
           "contacts": not int(opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)}
    for i in range(data.ncon):
        c = data.contact[i]
        if body in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]):
            fr = [float(v) for v in c.friction]
            srf = [float(v) for v in getattr(c, "solreffriction", ())]  # a pair's, if any
            out.update(condim=int(c.dim), coefficients=[fr[0], fr[2], fr[3]],
                       solref=[float(v) for v in c.solref],
                       solreffriction=srf if any(srf) else None,
                       solimp=[float(v) for v in c.solimp], contact_source="contact at t = 0")
            return out
    out.update(condim=int(model.geom_condim[ball]),
               coefficients=[float(v) for v in model.geom_friction[ball]],
               solref=[float(v) for v in model.geom_solref[ball]], solreffriction=None,
               solimp=[float(v) for v in model.geom_solimp[ball]],
               contact_source="ball geom (no contact at t = 0)")
    return out


def run(request: dict) -> dict:
    """Run one request; the reply's fields (the arrays go to ``request['out']``)."""
    import mujoco
    import numpy as np

    impl, precision = engine_of(request)
    # MuJoCo's warnings, kept (one line each) as in-process runs keep them, instead of printed
    # on stdout (the reply's channel) and appended to ./MUJOCO_LOG.TXT
    kept: list[str] = []
    if hasattr(mujoco, "set_mju_user_warning"):
        mujoco.set_mju_user_warning(lambda message: kept.append(" ".join(str(message).split())))
    spec = mujoco.MjSpec.from_string(request["mjcf"]) if hasattr(mujoco, "MjSpec") else None
    if spec is not None:
        spec.nuserdata += request.get("userdata", 0)
        model = spec.compile()
    else:  # pragma: no cover - releases before MjSpec
        model = mujoco.MjModel.from_xml_string(request["mjcf"])
    joint = _free_joint(mujoco, model)
    qa, va = int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])
    body = int(model.jnt_bodyid[joint])
    data = mujoco.MjData(model)
    start = request["start"]
    if "keyframe" in start:
        mujoco.mj_resetDataKeyframe(model, data, int(start["keyframe"]))
    else:
        data.qpos[qa:qa + 7] = start["qpos"]
        data.qvel[va:va + 6] = start["qvel"]
    law = None
    if request.get("law") is not None:
        law = PaperLaw(model, {**request["law"], "qpos_adr": qa, "dof_adr": va})
        if impl == "mujoco":  # the others apply a force of their own, armed here afterwards
            mujoco.set_mjcb_passive(law)
    try:
        mujoco.mj_forward(model, data)
        ran = _ran(mujoco, model, data, body, int(request["ball_geom"]))
        steps, n_rows = int(request["steps_per_sample"]), int(request["n_intervals"]) + 1
        nq, nv = model.nq, model.nv
        counts = data.warning.number
        rec = {"time": np.empty(n_rows), "qpos": np.empty((n_rows, nq)),
               "qvel": np.empty((n_rows, nv)), "qacc_warmstart": np.empty((n_rows, nv)),
               "qfrc_constraint": np.empty((n_rows, nv)),
               "warnings": np.zeros((n_rows, len(counts)), dtype=np.int64)}
        mujoco.mj_forward(model, data)  # the contact force of the initial state, for N
        accel = None
        engine: dict[str, Any] = {"implementation": "mujoco", "version": mujoco.__version__,
                                  "precision": "float64", "device": "cpu"}
        if impl != "mujoco":
            t_setup = time.perf_counter()
            kind = MjxStepper if impl == "mjx" else WarpStepper
            accel = kind(mujoco, model, data, int(request["steps_per_sample"]), precision,
                         request.get("law"), qa, va, request.get("compile_cache"))
            engine = {"implementation": impl, "version": accel.version,
                      "precision": accel.precision, "device": accel.device,
                      "device_kind": accel.device_kind, "path": accel.path,
                      "mujoco_c_version": mujoco.__version__,
                      "warnings": f"none counted ({impl} has no warning counters)",
                      "contacts_from": "MuJoCo C at the sample states",
                      "setup_s": time.perf_counter() - t_setup}
            if getattr(accel, "note", None):
                engine["note"] = accel.note
            if law is not None:
                engine["law_applied"] = ("the paper's law in qfrc_applied before each step, "
                                         "from the step's start state and the previous "
                                         "step's qfrc_constraint")
        n, wall0 = 0, time.perf_counter()
        next_report = wall0
        dt = float(model.opt.timestep)
        first_call_s = None
        while True:
            if accel is None:
                rec["time"][n] = data.time
                rec["qpos"][n], rec["qvel"][n] = data.qpos, data.qvel
                rec["qacc_warmstart"][n] = data.qacc_warmstart
                rec["qfrc_constraint"][n] = data.qfrc_constraint
                rec["warnings"][n] = counts
            else:
                (rec["time"][n], rec["qpos"][n], rec["qvel"][n], rec["qacc_warmstart"][n],
                 rec["qfrc_constraint"][n]) = accel.state()
            n += 1
            bad = not (np.isfinite(rec["qpos"][n - 1]).all()
                       and np.isfinite(rec["qvel"][n - 1]).all())
            if bad or rec["warnings"][n - 1].any() or n == n_rows:
                break
            now = time.perf_counter()
            if now >= next_report:
                say({"t": (n - 1) * steps * dt})
                next_report = now + PROGRESS_S
            if accel is None:
                mujoco.mj_step(model, data, steps)
            else:
                t_call = time.perf_counter()
                accel.advance()
                if first_call_s is None:  # MJX compiles its loop on the first call
                    first_call_s = time.perf_counter() - t_call
        wall_s = time.perf_counter() - wall0
        rec = {k: v[:n] for k, v in rec.items()}
        if accel is not None:
            engine["first_call_s"] = first_call_s
            if law is not None:  # the law's output at the samples, from MuJoCo C's passes
                mujoco.set_mjcb_passive(law)
        # the contacts (and paper mode's forces) at each sample's own state
        scratch = mujoco.MjData(model)
        c_sample, c_geom, c_dist, c_pos, c_frame, c_force = [], [], [], [], [], []
        law_out = np.zeros((n, 3))
        passes = N_FORCE_PASSES if law is not None else 1
        f6 = np.zeros(6)
        for i in range(n):
            scratch.time = rec["time"][i]
            scratch.qpos[:], scratch.qvel[:] = rec["qpos"][i], rec["qvel"][i]
            scratch.qacc_warmstart[:] = rec["qacc_warmstart"][i]
            scratch.qfrc_constraint[:] = rec["qfrc_constraint"][i]
            for k in range(passes):
                if k == 0:
                    mujoco.mj_forward(model, scratch)
                else:  # the same positions: only N and friction change
                    mujoco.mj_forwardSkip(model, scratch, int(mujoco.mjtStage.mjSTAGE_POS), 1)
            for j in range(scratch.ncon):
                c = scratch.contact[j]
                mujoco.mj_contactForce(model, scratch, j, f6)
                c_sample.append(i)
                c_geom.append((int(c.geom1), int(c.geom2)))
                c_dist.append(float(c.dist))
                c_pos.append(np.array(c.pos))
                c_frame.append(np.array(c.frame))
                c_force.append(f6.copy())
            if law is not None:
                fx, fy, _N, power = law.last
                law_out[i] = fx, fy, power
        arrays = {**rec, "contact_sample": np.array(c_sample, dtype=np.int64),
                  "contact_geom": np.array(c_geom, dtype=np.int64).reshape(-1, 2),
                  "contact_dist": np.array(c_dist), "contact_pos": np.array(c_pos).reshape(-1, 3),
                  "contact_frame": np.array(c_frame).reshape(-1, 9),
                  "contact_force": np.array(c_force).reshape(-1, 6), "law_out": law_out}
        np.savez(request["out"], **arrays)
        return {"status": "ok", "samples": n, "wall_s": wall_s, "ran": ran, "engine": engine,
                **({"version": engine["version"], "path": engine["path"]}
                   if accel is not None else {}),
                "warning_text": kept[-1] if kept else None,
                "warning_names": [mujoco.mjtWarning(i).name for i in range(len(counts))]}
    finally:
        if law is not None:
            mujoco.set_mjcb_passive(None)


def main() -> int:
    """Answer requests, one JSON line each on stdin, until its end (exit 0 either way).

    Each request's reply is one JSON line on stdout (after its progress lines): the harness
    keeps the worker for its next request, so the start and the imports are paid once.
    """
    try:
        import mujoco
        import numpy as np
    except ImportError as exc:
        say({"status": "error", "message": f"expected mujoco and numpy in {sys.executable}, "
             f"got ImportError: {exc}"})
        return 0
    info = {"protocol": PROTOCOL, "version": mujoco.__version__, "numpy": np.__version__,
            "python": ".".join(map(str, sys.version_info[:3])), "executable": sys.executable,
            "path": "plain loop"}
    while True:
        line = sys.stdin.readline()
        if not line:
            return 0
        if line.strip():
            say({**info, **answer(line)})


def answer(line: str) -> dict:
    """The reply to one request line (a failed run is a reply too, in one line)."""
    try:
        request = json.loads(line)
        if not isinstance(request, dict) or request.get("protocol") != PROTOCOL:
            got = request.get("protocol") if isinstance(request, dict) else request
            raise ValueError(f"expected protocol {PROTOCOL}, got {got!r}")
        return run(request)
    except Refused as exc:  # said as it is
        return {"status": "error", "message": str(exc)}
    except Exception as exc:  # noqa: BLE001 - one failed run, said in one line
        last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
        where = f" ({last[0].name}, line {last[0].lineno})" if last else ""
        # one line: JAX's and Warp's errors span several
        return {"status": "error",
                "message": " ".join(f"{type(exc).__name__}: {exc}{where}".split())[:2000]}


__all__ = ["N_FORCE_PASSES", "answer", "main", "run"]
