"""The worker's work: each request's plan run, its arrays written and its reply, in turn.

:func:`main` answers the requests on stdin one after another (:func:`answer`); :func:`run`
steps one plan and writes its arrays: the state at each sample and each sample's **window**,
what every step's forward pass since the sample before computed (:mod:`.windows`: the
columns and their meaning, the same the harness records in process).

The request's optional ``engine`` (``{"implementation": "mujoco"|"mjx"|"warp", "precision":
"float64"|"float32"}``) picks what steps the plan:

- MuJoCo C (the default), one step at a time as the harness steps from Python
  (``stepping.step_python``): ``mj_step`` taken apart where the model's split is known
  (:func:`.windows.integrator_call`: ``mj_checkPos``, ``mj_checkVel``, ``mj_forward``,
  ``mj_checkAcc``, then the integrator; bit for bit ``mj_step``), each step's forward pass
  done at the end of the step before and added to the window there at offsets 1 ..
  ``steps``; else ``mj_step`` whole, its pass (at the state before it) added after it at
  offsets 0 .. ``steps`` - 1. Each pass is added by :class:`.windows.WindowAccumulator`
  (``mj_contactForce`` per contact of the top); paper mode's law is :class:`.PaperLaw`, a
  Python ``mjcb_passive``, and its output at each pass goes to the law's columns.
- MuJoCo MJX on JAX (:mod:`.mjx_stepper`: one jitted loop per sample interval; float32
  unless ``jax_enable_x64``) or MuJoCo Warp (:mod:`.warp_stepper`: float32; the interval's
  steps captured once as a Warp graph, or run in a loop where capture fails). Each step is
  split on the device as MuJoCo C's is (the integrator, then the next step's forward pass,
  its window added on the device), so the windows have MuJoCo C's offsets; what they read
  of each pass differs from MuJoCo C's (the steppers' docstrings, and the reply's
  ``contacts_from``). Those two need their packages beside ``mujoco`` (a managed
  environment holds them); they have no warning counters (their column is zeros). Paper
  mode's law is a force of the engine's own there: before each forward pass the law's
  force from the current state and the last evaluation's ``qfrc_constraint`` goes into
  ``qfrc_applied`` (MJX: the arithmetic of :class:`PaperLaw` in ``jax.numpy`` inside the
  jitted loop; Warp: the same in a Warp kernel, inside the captured graph). C's callback is
  called at every stage of RK4, the applied force is held over the step: the two agree to
  rounding with Euler. The request's optional ``compile_cache`` is JAX's persistent
  compilation cache folder (a later run of the same model skips most of MJX's compile).

The model is compiled by MuJoCo C either way, and the start set and ``mj_forward``-ed there
twice (paper mode's law armed, as the harness does: the law's N is the last pass's), which
is the state every engine starts from. The request's ``top`` says whose contacts the windows
add (:class:`.windows.WindowTop`'s fields).

The reply's ``engine`` says what stepped, read back: ``implementation``, ``version`` (MuJoCo
C's, or ``mujoco-mjx``'s / ``mujoco-warp``'s package version), ``precision`` (the dtype of
the device's ``qpos``), ``device`` (JAX's platform, Warp's device alias); for MJX and Warp
also ``device_kind``, ``path``, ``mujoco_c_version``, ``warnings``, ``contacts_from``,
``setup_s`` and ``first_call_s`` (the compile), and ``law_applied`` in paper mode.

The arrays (``request['out']``, ``.npz``): ``time``, ``qpos``, ``qvel``, ``qacc_warmstart``,
``qfrc_constraint`` and ``warnings`` per sample, and ``windows_int`` and ``windows_float``
(one row per sample, the columns of :data:`.windows.INT_FIELDS` and
:data:`.windows.FLOAT_FIELDS`).
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
from .windows import WindowAccumulator, WindowTop, integrator_call, new_windows


def window_top(request: dict) -> WindowTop:
    """The request's ``top``: whose contacts the windows add (:class:`.windows.WindowTop`).

    Raises:
        Refused: No ``top``, or one without :class:`.windows.WindowTop`'s fields (one line).
    """
    top = request.get("top")
    fields = WindowTop._fields
    if not isinstance(top, dict) or set(top) != set(fields):
        raise Refused(f"top: expected an object with {', '.join(fields)}, got {top!r}")
    return WindowTop(body=int(top["body"]), ball=int(top["ball"]),
                     radius_m=float(top["radius_m"]),
                     axis_body=tuple(float(v) for v in top["axis_body"]),
                     qpos_adr=int(top["qpos_adr"]), dof_adr=int(top["dof_adr"]))


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
    top = window_top(request)
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
    qa, va = top.qpos_adr, top.dof_adr
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
        # armed for the start's passes in every engine (the law's N iterated as the
        # harness's); MJX and Warp then apply a force of their own
        mujoco.set_mjcb_passive(law)
    try:
        mujoco.mj_forward(model, data)
        ran = _ran(mujoco, model, data, top.body, top.ball)
        steps, n_rows = int(request["steps_per_sample"]), int(request["n_intervals"]) + 1
        nq, nv = model.nq, model.nv
        counts = data.warning.number
        rec = {"time": np.empty(n_rows), "qpos": np.empty((n_rows, nq)),
               "qvel": np.empty((n_rows, nv)), "qacc_warmstart": np.empty((n_rows, nv)),
               "qfrc_constraint": np.empty((n_rows, nv)),
               "warnings": np.zeros((n_rows, len(counts)), dtype=np.int64)}
        ints, floats = new_windows(np, n_rows)
        mujoco.mj_forward(model, data)  # the contact force of the initial state, for N
        accel = None
        engine: dict[str, Any] = {"implementation": "mujoco", "version": mujoco.__version__,
                                  "precision": "float64", "device": "cpu"}
        if impl != "mujoco":
            if law is not None:
                mujoco.set_mjcb_passive(None)
            t_setup = time.perf_counter()
            kind = MjxStepper if impl == "mjx" else WarpStepper
            accel = kind(mujoco, model, data, steps, precision, request.get("law"), top,
                         request.get("compile_cache"))
            engine = {"implementation": impl, "version": accel.version,
                      "precision": accel.precision, "device": accel.device,
                      "device_kind": accel.device_kind, "path": accel.path,
                      "mujoco_c_version": mujoco.__version__,
                      "warnings": f"none counted ({impl} has no warning counters)",
                      "contacts_from": accel.contacts_from,
                      "setup_s": time.perf_counter() - t_setup}
            if getattr(accel, "note", None):
                engine["note"] = accel.note
            if law is not None:
                engine["law_applied"] = ("the paper's law in qfrc_applied before each "
                                         "forward pass, from its state and the last "
                                         "evaluation's qfrc_constraint, held over the step")
            wall0 = time.perf_counter()
            n, first_call_s = _step_accelerated(np, accel, rec, ints, floats, steps,
                                                float(model.opt.timestep))
            wall_s = time.perf_counter() - wall0
            engine["first_call_s"] = first_call_s
        else:
            wall0 = time.perf_counter()
            n = _step_mujoco(mujoco, np, model, data, rec, ints, floats, steps, top, law)
            wall_s = time.perf_counter() - wall0
        arrays = {**{k: v[:n] for k, v in rec.items()},
                  "windows_int": ints[:n], "windows_float": floats[:n]}
        np.savez(request["out"], **arrays)
        return {"status": "ok", "samples": n, "wall_s": wall_s, "ran": ran, "engine": engine,
                **({"version": engine["version"], "path": engine["path"]}
                   if accel is not None else {}),
                "warning_text": kept[-1] if kept else None,
                "warning_names": [mujoco.mjtWarning(i).name for i in range(len(counts))]}
    finally:
        if law is not None:
            mujoco.set_mjcb_passive(None)


def _ended(np, rec: dict, n: int) -> bool:
    """Whether row ``n`` ends the run: not finite, or a warning counted (it is kept)."""
    return not (np.isfinite(rec["qpos"][n]).all() and np.isfinite(rec["qvel"][n]).all()) \
        or bool(rec["warnings"][n].any())


def _step_mujoco(mujoco, np, model, data, rec: dict, ints, floats, steps: int,
                 top: WindowTop, law: PaperLaw | None) -> int:
    """Step MuJoCo C sample by sample, each step's pass added to its window; the rows made.

    The harness's ``stepping.step_python`` (the same C calls in the same order, so the same
    states to the bit), with the law's output read from :class:`PaperLaw`. Stops after the
    first row that is not finite or has a warning (kept), as the harness reads it.
    """
    n_rows = len(rec["time"])
    law_output = None if law is None else (lambda: (law.last[0], law.last[1], law.last[3]))
    acc = WindowAccumulator(mujoco, np, model, data, top, law_output)
    add = acc.add
    qa, va = top.qpos_adr, top.dof_adr
    integrate = integrator_call(mujoco, model)
    step, forward = mujoco.mj_step, mujoco.mj_forward
    check_pos, check_vel, check_acc = mujoco.mj_checkPos, mujoco.mj_checkVel, mujoco.mj_checkAcc
    counts = data.warning.number
    t, qpos, qvel = rec["time"], rec["qpos"], rec["qvel"]
    warm, con, warn = rec["qacc_warmstart"], rec["qfrc_constraint"], rec["warnings"]
    dt = float(model.opt.timestep)
    next_report = time.perf_counter()

    def record(n: int) -> None:
        t[n] = data.time
        qpos[n], qvel[n] = data.qpos, data.qvel
        warm[n], con[n] = data.qacc_warmstart, data.qfrc_constraint
        warn[n] = counts

    n = 0
    while True:
        if n == 0:
            record(0)
            if integrate is not None:  # mj_step's own start: its forward pass
                check_pos(model, data)
                check_vel(model, data)
                forward(model, data)
                check_acc(model, data)
            add(ints, floats, 0, 0)
        elif integrate is not None:  # each step's pass done at the end of the step before
            for j in range(1, steps + 1):
                integrate(model, data)
                if j == steps:
                    record(n)
                check_pos(model, data)
                check_vel(model, data)
                forward(model, data)
                check_acc(model, data)
                add(ints, floats, n, j)
        else:  # mj_step whole: its pass, at the state before it, added after it with the
            for j in range(1, steps + 1):  # motion it had there
                motion = (data.qpos[qa:qa + 7].copy(), data.qvel[va:va + 6].copy())
                step(model, data)
                if j == steps:
                    record(n)
                if n > 1 or j > 1:  # the first step's pass is the start's, row 0's already
                    add(ints, floats, n, j - 1, motion)
        n += 1
        if _ended(np, rec, n - 1) or n == n_rows:
            return n
        now = time.perf_counter()
        if now >= next_report:
            say({"t": (n - 1) * steps * dt})
            next_report = now + PROGRESS_S


def _step_accelerated(np, accel: Any, rec: dict, ints, floats, steps: int,
                      dt: float) -> tuple[int, float]:
    """Step MJX or Warp sample by sample, the windows added on the device; (rows, first call).

    The first call (row 0's pass, which compiles MJX's loop) is timed apart.
    """
    n_rows = len(rec["time"])
    next_report = time.perf_counter()
    first_call_s = 0.0
    n = 0
    while True:
        if n == 0:
            t_call = time.perf_counter()
            accel.first()
            first_call_s = time.perf_counter() - t_call
        else:
            accel.advance()
        (rec["time"][n], rec["qpos"][n], rec["qvel"][n], rec["qacc_warmstart"][n],
         rec["qfrc_constraint"][n]) = accel.state()
        ints[n], floats[n] = accel.window()
        n += 1
        if _ended(np, rec, n - 1) or n == n_rows:
            return n, first_call_s
        now = time.perf_counter()
        if now >= next_report:
            say({"t": (n - 1) * steps * dt})
            next_report = now + PROGRESS_S


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
        if request.get("kind") == "probe":  # tippetop probe: one small model, every step
            from .probe_steps import answer_probe

            return answer_probe(request)
        return run(request)
    except Refused as exc:  # said as it is
        return {"status": "error", "message": str(exc)}
    except Exception as exc:  # noqa: BLE001 - one failed run, said in one line
        last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
        where = f" ({last[0].name}, line {last[0].lineno})" if last else ""
        # one line: JAX's and Warp's errors span several
        return {"status": "error",
                "message": " ".join(f"{type(exc).__name__}: {exc}{where}".split())[:2000]}


__all__ = ["answer", "main", "run", "window_top"]
