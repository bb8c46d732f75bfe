"""A MuJoCo run's result from its recorded samples: contacts, forces, checks, the table.

:func:`result_from_samples` computes everything a run reports besides the states, after the
stepping and vectorised over the samples; the single run and every run of a batch call it.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import pandas as pd

from tippetop.models.numbers import float_text
from tippetop.models.params import FrictionParams, StemParams
from tippetop.models.plan import MujocoPlan
from tippetop.mujoco_runner import stepper
from tippetop.mujoco_runner.checks import check_failure, divergence_fix, step_failure
from tippetop.mujoco_runner.friction_callback import LAST_OUTPUT, USERDATA_SIZE, PaperFriction
from tippetop.mujoco_runner.model import TopModel
from tippetop.mujoco_runner.observables import observables_table
from tippetop.mujoco_runner.record import STATE_SPEC, ContactLog, ContactRecord, SampleRecord
from tippetop.mujoco_runner.settings import integrator_name
from tippetop.mujoco_runner.state import rotations

#: The top's contacts at a sample: none, the ball, another geom (the stem), both.
CONTACT_LABELS = ("none", "ball", "stem", "both")
#: Forward passes per sample in paper mode that bring the recorded normal force to the state's
#: own (the callback uses the previous evaluation's N; see docs/design.md).
N_FORCE_PASSES = 3


@dataclass(frozen=True, eq=False)
class MujocoResult:
    """The outcome of one MuJoCo run.

    Attributes:
        table: ``models.observables.COLUMNS + EXTRA_COLUMNS``, one row per sample at t = 0,
            sample_dt, ...; on divergence only the samples before it.
        n_steps: Integration steps taken.
        wall_s: Wall-clock time of the run (s): the stepping with its recording, and the
            post-processing (:func:`result_from_samples`).
        status: ``"ok"`` or ``"diverged"``.
        message: One line: what was run, or why it failed and what to change.
        mode: ``"paper"`` or ``"native"``.
        warnings: Warnings about the model (extra colliding geoms).
        ran: What ran, read back from the compiled model and the top's contact
            (:func:`settings_that_ran`), and the row spacing ``sample_dt_s``.
        contacts: Per sample, which of the top's geoms touched the table (a code of
            :data:`CONTACT_LABELS`).
        max_penetration_m: The deepest penetration of the top's contacts over the samples (m).
        engine: What ran the steps, read back: ``implementation`` (``mujoco``), ``version``
            (its ``mujoco.__version__``), ``precision``, ``device`` and ``path`` (how the
            samples were stepped, :attr:`~.record.SampleRecord.path`).
        contact_energy_bound_J: The most elastic energy the soft contacts held at a sample,
            bounded by the normal force times the deepest contact's depth (J; the force grows
            with depth). E, the rigid body's energy, leaves it out and may rise by it when a
            contact springs back.
    """

    table: pd.DataFrame
    n_steps: int
    wall_s: float
    status: str
    message: str
    mode: str
    warnings: tuple[str, ...] = field(default=())
    ran: dict[str, Any] = field(default_factory=dict)
    contacts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))
    max_penetration_m: float = 0.0
    contact_energy_bound_J: float = 0.0
    engine: dict[str, Any] = field(default_factory=dict)

    def phases(self) -> list[dict[str, Any]]:
        """The sampled contact phases: runs of samples with the same contacts.

        Each is ``{"contact", "t_start", "t_end"}``, ``contact`` one of :data:`CONTACT_LABELS`.
        """
        t = self.table["t"].to_numpy()
        out: list[dict[str, Any]] = []
        for i, code in enumerate(self.contacts):
            label = CONTACT_LABELS[int(code)]
            if out and out[-1]["contact"] == label:
                out[-1]["t_end"] = float(t[i])
            else:
                out.append({"contact": label, "t_start": float(t[i]), "t_end": float(t[i])})
        return out

    @property
    def t_stem(self) -> float | None:
        """First sampled time another geom of the top (the stem) touched the table, or None."""
        hit = np.flatnonzero(self.contacts & 2)
        return float(self.table["t"].iloc[hit[0]]) if hit.size else None

    @property
    def ok(self) -> bool:
        """True when the run reached t_end without diverging."""
        return self.status == "ok"


def scratch_contacts(top_model: TopModel, record: SampleRecord, law: FrictionParams | None,
                     stem: StemParams | None, *, compiled: bool | None = None
                     ) -> tuple[ContactRecord, np.ndarray | None, np.ndarray | None]:
    """Forward passes at each sample's state on a scratch mjData.

    Returns its contacts, and in paper mode with a law the law's (Fx, Fy) (n, 2) and power
    (n,) as the callback applied them at the last pass (else None, None).

    The scratch copy is armed like the run's data: its passes apply the same friction, so N is
    the contact force with friction acting. The callback's N is the previous evaluation's: the
    first pass starts from the step's last one (``qfrc_constraint``), then each pass iterates
    to the state's own (friction moves N by ~1 %, so each pass gains about two digits).

    In :func:`.stepper.forward_passes`'s compiled loop when it is available (``compiled``:
    None), else (``compiled=False``) from Python: the same C calls.
    """
    model = top_model.model
    scratch = mujoco.MjData(model)
    log = ContactLog(model, scratch)
    n = len(record)
    law_xy = np.empty((n, 2)) if law is not None else None
    law_power = np.empty(n) if law is not None else None
    spec = STATE_SPEC
    state = np.empty((n, mujoco.mj_stateSize(model, spec)))
    nq, nv = model.nq, model.nv
    state[:, 0] = record.time
    state[:, 1:1 + nq] = record.qpos
    state[:, 1 + nq:1 + nq + nv] = record.qvel
    state[:, 1 + nq + nv:] = record.qacc_warmstart
    passes = N_FORCE_PASSES if law is not None else 1
    forward, forward_skip = mujoco.mj_forward, mujoco.mj_forwardSkip
    skip_pos = int(mujoco.mjtStage.mjSTAGE_POS)
    with contextlib.ExitStack() as stack:
        scratch_law = None
        if law is not None:
            scratch_law = stack.enter_context(PaperFriction(top_model, scratch, law,
                                                            stem=stem))
        if compiled is None:
            compiled = stepper.available()[0]
        if compiled:
            law_index = None
            if law is not None:  # the callback's block: the last USERDATA_SIZE entries
                law_index = model.nuserdata - USERDATA_SIZE + LAST_OUTPUT
            sample, rows, force, out = stepper.forward_passes(
                model, scratch, state, record.qfrc_constraint, spec=int(spec), passes=passes,
                law_index=law_index)
            contacts = ContactRecord(sample, rows["geom"].astype(np.int64),
                                     rows["dist"].copy(), rows["pos"].copy(),
                                     rows["frame"].copy(), force)
            if out is None:
                return contacts, None, None
            return contacts, out[:, :2].copy(), out[:, 2].copy()
        con = scratch.qfrc_constraint
        for i in range(n):
            mujoco.mj_setState(model, scratch, state[i], spec)
            con[:] = record.qfrc_constraint[i]
            forward(model, scratch)
            for _ in range(passes - 1):  # the same positions: only N and friction change
                forward_skip(model, scratch, skip_pos, 1)
            log.add(i, scratch)
            if scratch_law is not None:
                fx, fy, _n = scratch_law.last_force
                law_xy[i] = fx, fy
                law_power[i] = scratch_law.last_power
    return log.record(), law_xy, law_power


def contact_sums(top_model: TopModel, contacts: ContactRecord, qpos: np.ndarray,
                  qvel: np.ndarray, n: int) -> dict[str, np.ndarray]:
    """Per sample: N, F (n, 3), tau (n, 3), power, touching code, deepest penetration.

    Sums over the top's contacts in MuJoCo's order.
    ``qpos``/``qvel``: the top's free joint (n, 7), (n, 6).
    """
    model, body, ball = top_model.model, top_model.body_id, top_model.ball_geom_id
    N, F, tau = np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3))
    power, depth = np.zeros(n), np.zeros(n)
    touching = np.zeros(n, dtype=np.int8)
    keep = contacts.sample < n
    geom = contacts.geom[keep]
    b1, b2 = model.geom_bodyid[geom[:, 0]], model.geom_bodyid[geom[:, 1]]
    mine = (b1 == body) | (b2 == body)
    s = contacts.sample[keep][mine]
    if not s.size:
        return {"N": N, "F": F, "tau": tau, "power": power, "touching": touching,
                "depth": depth}
    geom, b2 = geom[mine], b2[mine]
    f6 = contacts.force[keep][mine]
    frame = contacts.frame[keep][mine].reshape(-1, 3, 3)
    pos = contacts.pos[keep][mine]
    dist = contacts.dist[keep][mine]
    code = np.where((geom[:, 0] == ball) | (geom[:, 1] == ball), 1, 2).astype(np.int8)
    np.bitwise_or.at(touching, s, code)
    np.maximum.at(depth, s, -dist)
    sign = np.where(b2 == body, 1.0, -1.0)[:, None]  # the force acts on geom2 along +normal
    frame_t = np.swapaxes(frame, 1, 2)
    force = sign * _matvec(frame_t, f6[:, :3])
    normal = sign * frame[:, 0]
    friction = force - f6[:, :1] * normal
    torque = sign * _matvec(frame_t, f6[:, 3:])
    # the same operations as one sample's (matrix products, 3-term sums left to right), so
    # the same numbers to the last bit
    rot = rotations(qpos[s, 3:7])
    origin, v_origin = qpos[s, 0:3], qvel[s, 0:3]
    omega = _matvec(rot, qvel[s, 3:6])
    v_point = v_origin + np.cross(omega, pos - origin)
    p = _dot(friction, v_point) + _dot(torque, omega)
    np.add.at(N, s, f6[:, 0])
    np.add.at(F, s, friction)
    np.add.at(tau, s, torque)
    np.add.at(power, s, p)
    return {"N": N, "F": F, "tau": tau, "power": power, "touching": touching, "depth": depth}


def _matvec(mats: np.ndarray, vecs: np.ndarray) -> np.ndarray:
    """Row-wise ``mats[i] @ vecs[i]``, (n, 3, 3) x (n, 3) -> (n, 3), as numpy does one."""
    return (mats @ vecs[:, :, None])[:, :, 0]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise ``a[i] @ b[i]`` of (n, 3) arrays, summed left to right as numpy does one."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def gap_energy_many(top_model: TopModel, qpos: np.ndarray, qvel: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Gaps (m) and mechanical energies (J) of n samples at once, shape (n,) each.

    The gap is the height of the ball's lowest point above the table;
    :func:`observables_table` computes E again, for the table.
    """
    top = top_model.top
    n = len(qpos)
    rot = rotations(qpos[:, 3:7])
    k = _matvec(rot, np.broadcast_to(top_model.axis_body, (n, 3)))
    arm = _matvec(rot, np.broadcast_to(top_model.centre_body_m, (n, 3)))  # S - body origin
    o = _matvec(rot, qvel[:, 3:6])
    ox, oy, oz = o[:, 0], o[:, 1], o[:, 2]
    r = arm - top.a_m * k  # O - body origin
    rx, ry, rz = r[:, 0], r[:, 1], r[:, 2]
    vx = qvel[:, 0] + oy * rz - oz * ry
    vy = qvel[:, 1] + oz * rx - ox * rz
    vz = qvel[:, 2] + ox * ry - oy * rx
    spin = ox * k[:, 0] + oy * k[:, 1] + oz * k[:, 2]
    kinetic = 0.5 * top.M_kg * (vx * vx + vy * vy + vz * vz) + 0.5 * (
        top.A_kgm2 * (ox * ox + oy * oy + oz * oz) + (top.C_kgm2 - top.A_kgm2) * spin * spin)
    centre_z = qpos[:, 2] + arm[:, 2]
    energy = kinetic + top.M_kg * top.g_mps2 * (centre_z - top.a_m * k[:, 2])
    return centre_z - top.R_m, energy


def result_from_samples(
    top_model: TopModel,
    record: SampleRecord,
    plan: MujocoPlan,
    *,
    failure: str | None = None,
    wall_s: float = 0.0,
    ran: dict[str, Any] | None = None,
    law_forces: tuple[np.ndarray, np.ndarray] | None = None,
    version: str | None = None,
) -> MujocoResult:
    """The :class:`MujocoResult` of one simulation from its recorded samples.

    Everything a run reports besides the states is computed here, after the stepping: the
    contacts and forces at each sample's own state (from ``record.contacts``, or forward
    passes on a scratch mjData: one, or :data:`N_FORCE_PASSES` in paper mode with a law,
    armed with the same law), the checks that end a run (a non-finite state or a MuJoCo
    warning at a sample; then the ball sinking more than :data:`MAX_PENETRATION_R`, the
    energy rising more than :data:`MAX_ENERGY_RISE`, contact lost longer than
    :data:`MAX_AIRBORNE_S`, in that order at one sample), and the observables table. The run
    ends at the first failed sample, which is not in the table, with its one-line reason.

    Args:
        top_model: The top the record was stepped on (the plan's compiled model).
        record: The samples, row i at t = i * steps * dt (see :class:`SampleRecord`).
        plan: The plan that ran: its mode, law (the callback's; None: no friction), steps
            per sample, sample intervals (``len(record) - 1`` when it ran to the end) and stem
            (where paper mode's law also acts).
        failure: Why the stepping stopped after the last recorded sample (the sample after it
            failed: e.g. :data:`NONFINITE_REASON`, :func:`warning_reason`, a MuJoCo error);
            None: it did not stop early. The reason is followed by ``; <what to change>``.
        wall_s: Wall time of the stepping (s); the post-processing's own time is added.
        ran: The run's :func:`~.stepping.ran_settings`.
        law_forces: Paper mode: the law's (Fx, Fy) (n, 2) and power (n,) at each sample's own
            state, where ``record.contacts`` was computed too (by a worker in another Python,
            :mod:`.remote`); None: computed here, from forward passes.
        version: The MuJoCo release that stepped the samples (default this process's).

    Returns:
        The run's result.
    """
    mode, law, stem = plan.friction, plan.law, plan.stem
    steps, n_intervals = plan.steps_per_sample, plan.n_intervals
    start = time.perf_counter()
    model = top_model.model
    dt = float(model.opt.timestep)
    fix = divergence_fix(model)
    integrator = integrator_name(int(model.opt.integrator))
    qa, va = top_model.qpos_adr, top_model.dof_adr
    n_step_ok, reason = step_failure(record)
    if reason is not None:
        reason = f"{reason}; {fix}"
    elif failure is not None:
        reason = f"{failure}; {fix}"
    rec = record.head(n_step_ok)
    n = len(rec)
    law_xy = law_power = None
    contacts = rec.contacts
    if law_forces is not None and contacts is not None:
        law_xy, law_power = law_forces[0][:n], law_forces[1][:n]
    elif contacts is None or law is not None:
        contacts, law_xy, law_power = scratch_contacts(top_model, rec, law, stem)
    qpos, qvel = rec.qpos[:, qa:qa + 7], rec.qvel[:, va:va + 6]
    sums = contact_sums(top_model, contacts, qpos, qvel, n)
    t_check = np.arange(n) * steps * dt  # as the checks always had it: (i * steps) * dt
    gap, energy = gap_energy_many(top_model, qpos, qvel)
    n_good, check = check_failure(top_model, t_check, gap, energy,
                                   (sums["touching"] & 2) > 0, fix,
                                   on_table=plan.contacts_on)
    if check is not None:
        reason = check
    status = "ok" if reason is None else "diverged"
    t_s = np.arange(n_good) * (steps * dt)
    qpos, qvel = qpos[:n_good], qvel[:n_good]
    N = sums["N"][:n_good]
    power = sums["power"][:n_good]  # as applied: the callback's, or each contact's
    if law is not None:
        F = np.zeros((n_good, 3))
        F[:, :2] = law_xy[:n_good]
        tau, power = None, law_power[:n_good]
    elif mode == "paper":
        F, tau, power = np.zeros((n_good, 3)), None, np.zeros(n_good)
    else:
        F, tau = sums["F"][:n_good], sums["tau"][:n_good]
    # the contact bounds cover the failed sample too when the checks failed it (its contacts
    # were read), not when it failed while stepping (it has none)
    held = n_good + 1 if check is not None else n_good
    depth = sums["depth"][:held]
    bound = sums["N"][:held] * depth
    table = observables_table(top_model, t_s, qpos, qvel, N, F, tau, power=power)
    n_steps = n_intervals * steps if status == "ok" else n_good * steps
    wall = wall_s + (time.perf_counter() - start)
    if status == "ok":
        message = (f"{mode} mode: {n_steps:,} steps of {integrator} at dt = {float_text(dt)} s to "
                   f"t = {float_text(n_intervals * steps * dt)} s in {float_text(wall)} s")
    else:
        message = f"diverged by t = {n_good * steps * dt:.6g} s ({mode} mode): {reason}"
    return MujocoResult(table=table, n_steps=n_steps, wall_s=wall, status=status,
                        message=message, mode=mode, warnings=top_model.warnings,
                        ran=dict(ran or {}), contacts=sums["touching"][:n_good].copy(),
                        max_penetration_m=float(np.fmax.reduce(depth, initial=0.0)),
                        contact_energy_bound_J=float(np.fmax.reduce(bound, initial=0.0)),
                        engine={"implementation": "mujoco",
                                "version": version or mujoco.__version__,
                                "precision": "float64", "device": "cpu",
                                "path": record.path or "?"})


__all__ = ["CONTACT_LABELS", "N_FORCE_PASSES", "MujocoResult", "contact_sums",
           "gap_energy_many", "result_from_samples", "scratch_contacts"]
