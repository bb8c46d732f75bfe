"""A MuJoCo run's result from its recorded samples: contacts, forces, checks, the table.

:func:`result_from_samples` computes everything a run reports besides the states, after the
stepping and vectorised over the samples; the single run and every run of a batch call it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import pandas as pd

from tippetop.models.numbers import float_text
from tippetop.models.plan import MujocoPlan
from tippetop.mujoco_runner.checks import check_failure, divergence_fix, step_failure
from tippetop.mujoco_runner.model import TopModel
from tippetop.mujoco_runner.observables import observables_table
from tippetop.mujoco_runner.record import SampleRecord, WindowRecord
from tippetop.mujoco_runner.settings import integrator_name
from tippetop.mujoco_runner.state import rotations
from tippetop.mujoco_runner.worker.windows import F

#: The top's contacts in a sample's window: none, the ball, another geom (the stem), both.
CONTACT_LABELS = ("none", "ball", "stem", "both")


@dataclass(frozen=True, eq=False)
class MujocoResult:
    """The outcome of one MuJoCo run.

    Attributes:
        table: ``models.observables.COLUMNS + EXTRA_COLUMNS``, one row per sample at t = 0,
            sample_dt, ...; on divergence only the samples before it. Its forces (N, FX, FY)
            and friction power (P_fric) are each sample's window's means (every step's
            forward pass since the sample before, :mod:`.worker.windows`), not one step's.
        n_steps: Integration steps taken.
        wall_s: Wall-clock time of the run (s): the stepping with its recording, and the
            post-processing (:func:`result_from_samples`).
        status: ``"ok"`` or ``"diverged"``.
        message: One line: what was run, or why it failed and what to change.
        mode: ``"paper"`` or ``"native"``.
        warnings: Warnings about the model (extra colliding geoms).
        ran: What ran, read back from the compiled model and the top's contact
            (:func:`settings_that_ran`), and the row spacing ``sample_dt_s``.
        contacts: Per sample, which of the top's geoms touched the table at any step of its
            window (a code of :data:`CONTACT_LABELS`).
        max_penetration_m: The deepest penetration of the top's contacts at any step (m).
        engine: What ran the steps, read back: ``implementation`` (``mujoco``), ``version``
            (its ``mujoco.__version__``), ``precision``, ``device`` and ``path`` (how the
            samples were stepped, :attr:`~.record.SampleRecord.path`).
        contact_energy_bound_J: The most elastic energy the soft contacts held in a window,
            bounded by the window's largest mean normal force times its deepest contact's depth
            (J; the force grows with depth). E, the rigid body's energy, leaves it out and may
            rise by it when a contact springs back.
        windows: Each sample's window (:class:`~.record.WindowRecord`), the table's rows.
        steps_per_sample: Integration steps between two samples.
        dt_s: The timestep that ran (s): pass p of the windows is at time p dt.
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
    windows: WindowRecord = field(default_factory=WindowRecord.empty)
    steps_per_sample: int = 1
    dt_s: float = 0.0

    def phases(self) -> list[dict[str, Any]]:
        """The contact phases: runs of samples whose windows touched with the same geoms.

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

    def _time_of(self, name: str) -> float | None:
        p = self.windows.first_pass(name, self.steps_per_sample)
        return None if p is None else p * self.dt_s

    @property
    def t_stem(self) -> float | None:
        """The first step at which another geom of the top (the stem) touched the table (s)."""
        return self._time_of("first_other")

    @property
    def t_invert(self) -> float | None:
        """The first step at which the axis points down after pointing up (s), or None.

        theta crosses pi/2 from below there.
        """
        return self._time_of("flip")

    def gaps(self) -> dict[str, np.ndarray]:
        """The stretches of steps without any contact of the top, located to the step.

        ``{"t_start", "duration_s", "height_m"}`` (arrays, by start): when each began, how
        long it lasted (its steps times dt) and the largest gap between the ball and the
        table over it (m). Also ``count`` (every stretch, :data:`~.worker.windows` ``lifts``)
        and ``airborne_s`` per sample window, for sums over a part of the run.
        """
        g = self.windows.gaps(self.steps_per_sample)
        w = self.windows
        return {"t_start": g["start"] * self.dt_s, "duration_s": g["passes"] * self.dt_s,
                "height_m": g["height_m"],
                "count": w.int_column("lifts").copy(),
                "airborne_s": (w.int_column("passes") - w.int_column("touch_passes"))
                * self.dt_s}

    def force_and_slip(self) -> dict[str, np.ndarray]:
        """Each window's mean friction force against its slip: what a realised law is fit to.

        ``{"t", "N", "F", "slip"}``: the samples' times (s), each window's mean normal force
        (N), its mean friction force on the ball in the world's horizontal plane (n, 2; N:
        the contacts' own in native mode, the law's in paper mode) and the slip of the
        ball's lowest point there, each step's weighted by its normal force (n, 2; m/s; NaN
        where no step had any).
        """
        means = window_means(self.windows)
        n = len(self.table)
        force = means["law_F"] if self.mode == "paper" else means["F"][:, :2]
        w = self.windows.floats
        total = w[:, F["n_sum"]]
        with np.errstate(invalid="ignore", divide="ignore"):
            slip = np.stack([w[:, F["slip_nx_sum"]], w[:, F["slip_ny_sum"]]], axis=1) / \
                np.where(total > 0, total, np.nan)[:, None]
        return {"t": self.table["t"].to_numpy(), "N": means["N"][:n], "F": force[:n],
                "slip": slip[:n]}

    @property
    def ok(self) -> bool:
        """True when the run reached t_end without diverging."""
        return self.status == "ok"


def window_means(windows: WindowRecord) -> dict[str, np.ndarray]:
    """Each window's means over its passes, with its touching code and deepest penetration.

    N, F (n, 3), tau (n, 3), power, and the law's F (n, 2) and power.
    """
    passes = np.maximum(windows.int_column("passes"), 1).astype(float)
    f = windows.floats

    def mean(*names: str) -> np.ndarray:
        cols = [f[:, F[name]] / passes for name in names]
        return cols[0] if len(cols) == 1 else np.stack(cols, axis=1)

    return {"N": mean("n_sum"), "F": mean("fx_sum", "fy_sum", "fz_sum"),
            "tau": mean("tx_sum", "ty_sum", "tz_sum"), "power": mean("power_sum"),
            "law_F": mean("law_fx_sum", "law_fy_sum"), "law_power": mean("law_power_sum"),
            "touching": windows.int_column("touch").astype(np.int8),
            "depth": windows.float_column("depth_max")}


def _matvec(mats: np.ndarray, vecs: np.ndarray) -> np.ndarray:
    """Row-wise ``mats[i] @ vecs[i]``, (n, 3, 3) x (n, 3) -> (n, 3), as numpy does one."""
    return (mats @ vecs[:, :, None])[:, :, 0]


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
    version: str | None = None,
) -> MujocoResult:
    """The :class:`MujocoResult` of one simulation from its recorded samples and windows.

    Everything a run reports besides the states is computed here, after the stepping: the
    forces and contacts from each sample's window (every step's forward pass since the sample
    before: :mod:`.worker.windows`), the checks that end a run (a non-finite state or a
    MuJoCo warning at a sample; then the top sinking more than :data:`MAX_PENETRATION_R` at
    any step, the energy rising more than :data:`MAX_ENERGY_RISE` at a sample, no contact
    at any step for longer than :data:`MAX_AIRBORNE_S` with the ball risen, in that order at
    one sample), and the observables table. The run ends at the first failed sample, which is
    not in the table, with its one-line reason.

    Args:
        top_model: The top the record was stepped on (the plan's compiled model).
        record: The samples, row i at t = i * steps * dt (see :class:`SampleRecord`).
        plan: The plan that ran: its mode, law (the callback's; None: no friction), steps
            per sample and sample intervals (``len(record) - 1`` when it ran to the end).
        failure: Why the stepping stopped after the last recorded sample (the sample after it
            failed: e.g. :data:`NONFINITE_REASON`, :func:`warning_reason`, a MuJoCo error);
            None: it did not stop early. The reason is followed by ``; <what to change>``.
        wall_s: Wall time of the stepping (s); the post-processing's own time is added.
        ran: The run's :func:`~.stepping.ran_settings`.
        version: The MuJoCo release that stepped the samples (default this process's).

    Returns:
        The run's result.
    """
    mode, law = plan.friction, plan.law
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
    qpos, qvel = rec.qpos[:, qa:qa + 7], rec.qvel[:, va:va + 6]
    means = window_means(rec.windows)
    t_check = np.arange(n) * steps * dt  # as the checks always had it: (i * steps) * dt
    _gap, energy = gap_energy_many(top_model, qpos, qvel)
    n_good, check = check_failure(top_model, t_check, rec.windows, steps, dt, energy, fix,
                                   on_table=plan.contacts_on)
    if check is not None:
        reason = check
    status = "ok" if reason is None else "diverged"
    t_s = np.arange(n_good) * (steps * dt)
    qpos, qvel = qpos[:n_good], qvel[:n_good]
    N = means["N"][:n_good]
    power = means["power"][:n_good]  # as applied: the callback's, or each contact's
    if law is not None:
        F = np.zeros((n_good, 3))
        F[:, :2] = means["law_F"][:n_good]
        tau, power = None, means["law_power"][:n_good]
    elif mode == "paper":
        F, tau, power = np.zeros((n_good, 3)), None, np.zeros(n_good)
    else:
        F, tau = means["F"][:n_good], means["tau"][:n_good]
    # the contact bounds cover the failed sample too when the checks failed it (its window
    # was stepped), not when it failed while stepping
    held = n_good + 1 if check is not None else n_good
    depth = means["depth"][:held]
    bound = means["N"][:held] * depth
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
                        ran=dict(ran or {}), contacts=means["touching"][:n_good].copy(),
                        max_penetration_m=float(np.fmax.reduce(depth, initial=0.0)),
                        contact_energy_bound_J=float(np.fmax.reduce(bound, initial=0.0)),
                        engine={"implementation": "mujoco",
                                "version": version or mujoco.__version__,
                                "precision": "float64", "device": "cpu",
                                "path": record.path or "?"},
                        windows=rec.windows.head(n_good), steps_per_sample=steps, dt_s=dt)


__all__ = ["CONTACT_LABELS", "MujocoResult", "gap_energy_many", "result_from_samples",
           "window_means"]
