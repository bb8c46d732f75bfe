"""Run one MuJoCo plan in another Python: a script that needs nothing but ``mujoco`` and ``numpy``.

``PYTHON worker.py`` reads one request (JSON) on stdin, steps the plan's model sample by sample
as the harness does from Python, and writes the samples, the contacts at each sample and paper
mode's forces to the ``.npz`` file the request names; stdout carries progress lines and one last
JSON line that says how it ended. The harness turns that into a run's result
(:mod:`tippetop.mujoco_runner.remote`). This file imports nothing of tippetop's, so it runs in
any interpreter that can ``import mujoco`` (a managed environment, a user's own build).
"""

from __future__ import annotations

import json
import math
import sys
import time
import traceback

#: The version of the request and reply formats.
PROTOCOL = 2
#: Forward passes per sample in paper mode (the law's N iterated to the state's own), as in
#: the harness's own runs.
N_FORCE_PASSES = 3
#: Wall time between progress lines (s).
PROGRESS_S = 0.2


def _say(obj: dict) -> None:
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


class PaperLaw:
    """The paper's friction law applied at the contact point(s) from ``mjcb_passive``.

    The same computation as the harness's compiled callback, in Python: the normal force is
    the previous evaluation's (the constraint force's vertical component at the free joint),
    split between the ball's point and the stem's when both touch; the force ``law(v, N)`` at
    each point's material velocity goes into ``qfrc_passive``. The last force and power are
    kept for the table.
    """

    def __init__(self, model, params: dict) -> None:
        self.model = model
        self.p = params
        self.qa, self.va = params["qpos_adr"], params["dof_adr"]
        self.last = (0.0, 0.0, 0.0, 0.0)  # fx, fy, N, power

    def force(self, vx: float, vy: float, N: float) -> tuple[float, float]:
        """The law's tangential force (Fx, Fy) = N phi + psi at the slip (vx, vy).

        The reference's own terms (``reference_ode.friction.friction_terms``) written out.
        """
        p = self.p
        phix = phiy = psix = psiy = 0.0
        kind = p["coulomb_kind"]
        if kind == 1:  # modified Coulomb
            s = p["mu"] / math.sqrt(vx * vx + vy * vy + p["Lambda"] * p["Lambda"])
            phix, phiy = -s * vx, -s * vy
        elif kind == 2:  # exact Coulomb, its linear ramp below v_eps
            speed = math.sqrt(vx * vx + vy * vy)
            s = p["mu"] / (speed if speed > p["v_eps"] else p["v_eps"])
            phix, phiy = -s * vx, -s * vy
        if p["viscous_on"]:
            psix, psiy = -p["viscous"] * vx, -p["viscous"] * vy
        return N * phix + psix, N * phiy + psiy

    def __call__(self, m, d) -> None:  # noqa: D102 - MuJoCo's callback
        if m is not self.model and m._address != self.model._address:
            return
        p = self.p
        qpos, qvel = d.qpos[self.qa:self.qa + 7], d.qvel[self.va:self.va + 6]
        w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
        inv = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * inv, x * inv, y * inv, z * inv
        r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        r10, r11, r12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        wbx, wby, wbz = qvel[3], qvel[4], qvel[5]
        ox = r00 * wbx + r01 * wby + r02 * wbz
        oy = r10 * wbx + r11 * wby + r12 * wbz
        oz = r20 * wbx + r21 * wby + r22 * wbz
        cx, cy, cz = p["centre"]
        R = p["R"]
        ax = r00 * cx + r01 * cy + r02 * cz
        ay = r10 * cx + r11 * cy + r12 * cz
        az = r20 * cx + r21 * cy + r22 * cz - R
        qcon = d.qfrc_constraint[self.va:self.va + 6]
        N = max(float(qcon[2]), 0.0)
        N1, N2 = N, 0.0
        bx = by = bz = 0.0
        stem = p["stem_kind"]
        if stem:
            kbx, kby, kbz = p["axis"]
            kx = r00 * kbx + r01 * kby + r02 * kbz
            ky = r10 * kbx + r11 * kby + r12 * kbz
            kz = r20 * kbx + r21 * kby + r22 * kbz
            sl, sr = p["stem_l"], p["stem_r"]
            bx, by, bz = ax + sl * kx, ay + sl * ky, az + R + sl * kz - sr
            if stem == 2:
                s = math.sqrt(kx * kx + ky * ky)
                if s > 0.0:
                    bx += sr * kz * kx / s
                    by += sr * kz * ky / s
                    bz += sr - sr * s
                else:
                    bz += sr
            z1, z2 = qpos[2] + az, qpos[2] + bz
            if z1 <= 0.0 and z2 <= 0.0:
                tx_b, ty_b, tz_b = qcon[3], qcon[4], qcon[5]
                tx = r00 * tx_b + r01 * ty_b + r02 * tz_b
                ty = r10 * tx_b + r11 * ty_b + r12 * tz_b
                ux, uy = by - ay, -(bx - ax)
                rx, ry = tx - N * ay, ty + N * ax
                den = ux * ux + uy * uy
                N2 = (rx * ux + ry * uy) / den if den > 0.0 else 0.5 * N
                N2 = min(max(N2, 0.0), N)
                N1 = N - N2
            elif z2 < z1:
                N1, N2 = 0.0, N
        fx = fy = power = 0.0
        tx = ty = tz = 0.0
        points = [(ax, ay, az, N1)] + ([(bx, by, bz, N2)] if stem else [])
        for px, py, pz, Np in points:
            vx = qvel[0] + oy * pz - oz * py
            vy = qvel[1] + oz * px - ox * pz
            Fx, Fy = self.force(vx, vy, Np)
            fx += Fx
            fy += Fy
            power += Fx * vx + Fy * vy
            tx += -pz * Fy
            ty += pz * Fx
            tz += px * Fy - py * Fx
        qfrc = d.qfrc_passive
        va = self.va
        qfrc[va] += fx
        qfrc[va + 1] += fy
        qfrc[va + 3] += r00 * tx + r10 * ty + r20 * tz
        qfrc[va + 4] += r01 * tx + r11 * ty + r21 * tz
        qfrc[va + 5] += r02 * tx + r12 * ty + r22 * tz
        self.last = (fx, fy, N, power)


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
           "gravity_mps2": float(-opt.gravity[2])}
    for i in range(data.ncon):
        c = data.contact[i]
        if body in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]):
            fr = [float(v) for v in c.friction]
            out.update(condim=int(c.dim), coefficients=[fr[0], fr[2], fr[3]],
                       solref=[float(v) for v in c.solref],
                       solimp=[float(v) for v in c.solimp], contact_source="contact at t = 0")
            return out
    out.update(condim=int(model.geom_condim[ball]),
               coefficients=[float(v) for v in model.geom_friction[ball]],
               solref=[float(v) for v in model.geom_solref[ball]],
               solimp=[float(v) for v in model.geom_solimp[ball]],
               contact_source="ball geom (no contact at t = 0)")
    return out


def run(request: dict) -> dict:
    """Run one request; the reply's fields (the arrays go to ``request['out']``)."""
    import mujoco
    import numpy as np

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
        n, wall0 = 0, time.perf_counter()
        next_report = wall0
        dt = float(model.opt.timestep)
        while True:
            rec["time"][n] = data.time
            rec["qpos"][n], rec["qvel"][n] = data.qpos, data.qvel
            rec["qacc_warmstart"][n] = data.qacc_warmstart
            rec["qfrc_constraint"][n] = data.qfrc_constraint
            rec["warnings"][n] = counts
            n += 1
            bad = not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all())
            if bad or counts.any() or n == n_rows:
                break
            now = time.perf_counter()
            if now >= next_report:
                _say({"t": (n - 1) * steps * dt})
                next_report = now + PROGRESS_S
            mujoco.mj_step(model, data, steps)
        wall_s = time.perf_counter() - wall0
        rec = {k: v[:n] for k, v in rec.items()}
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
        return {"status": "ok", "samples": n, "wall_s": wall_s, "ran": ran,
                "warning_text": kept[-1] if kept else None,
                "warning_names": [mujoco.mjtWarning(i).name for i in range(len(counts))]}
    finally:
        if law is not None:
            mujoco.set_mjcb_passive(None)


def main() -> int:
    """Read a request on stdin, run it, say how it ended on stdout (exit 0 either way)."""
    try:
        import mujoco
        import numpy as np
    except ImportError as exc:
        _say({"status": "error", "message": f"expected mujoco and numpy in {sys.executable}, "
              f"got ImportError: {exc}"})
        return 0
    info = {"protocol": PROTOCOL, "version": mujoco.__version__, "numpy": np.__version__,
            "python": ".".join(map(str, sys.version_info[:3])), "executable": sys.executable,
            "path": "plain loop"}
    try:
        request = json.loads(sys.stdin.read())
        if request.get("protocol") != PROTOCOL:
            raise ValueError(f"expected protocol {PROTOCOL}, got {request.get('protocol')!r}")
        reply = run(request)
    except Exception as exc:  # noqa: BLE001 - one failed run, said in one line
        last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
        where = f" ({last[0].name}, line {last[0].lineno})" if last else ""
        reply = {"status": "error", "message": f"{type(exc).__name__}: {exc}{where}"}
    _say({**info, **reply})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
