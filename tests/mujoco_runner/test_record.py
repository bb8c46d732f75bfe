"""A run records states and computes the rest afterwards: the same numbers as sample by sample.

A run (:func:`mujoco_runner.run.run_compiled`) records the state at each sample (in
:mod:`mujoco_runner.stepper`'s compiled loop, or from Python) and :func:`result_from_samples`
computes contacts, forces, checks and the table afterwards, vectorised. Every comparison here is
exact (``==`` on float64): the same C calls on the same states, and the same floating-point
operations in the same order, give the same bits; any tolerance would hide a change of what is
computed. One exception: the per-sample contact reader kept as the oracle of the vectorised
contact sums computes with numpy's matrix and dot products, which BLAS may evaluate in another
order or with fused multiply-adds (it differs between machines and numpy builds), so its
forces, torques and power are compared within a rounding bound the test derives from the same
sums of absolute values.
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
from tippetop.mujoco_runner.record import SampleRecord
from tippetop.mujoco_runner.settings import build_model
from tippetop.mujoco_runner.state import initial_qpos_qvel

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


@pytest.mark.parametrize("integrator", ["RK4", "Euler", "implicitfast", "implicit"])
def test_mj_step_taken_apart_is_mj_step(integrator: str) -> None:
    # the run reads each sample's contacts from the forward pass that begins the next step:
    # mj_step split into its checks, mj_forward and the integrator must be mj_step exactly
    tm = _native(integrator)
    whole, split = _start(tm), _start(tm)
    finish = stepping.integrator_step(tm.model)
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


@pytest.mark.parametrize("mode", ["paper", "native"])
def test_compiled_and_python_loops_record_the_same(mode: str) -> None:
    tm = _paper() if mode == "paper" else _native()
    steps = 50 if mode == "paper" else 5
    records = []
    for compiled in (True, False):
        data = _start(tm)
        armed = (PaperFriction(tm, data, LAW) if mode == "paper" else contextlib.nullcontext())
        with armed:
            mujoco.mj_forward(tm.model, data)
            rec, failure, _ = stepping.step_and_record(tm.model, data, steps, 300, None,
                                                       contacts=mode == "native",
                                                       compiled=compiled)
        assert failure is None
        records.append(rec)
    a, b = records
    for field in ("time", "qpos", "qvel", "qacc_warmstart", "qfrc_constraint", "warnings"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert len(a) == 301
    if mode == "native":
        assert len(a.contacts.sample) >= 300  # the ball touches at (nearly) every sample
        for field in ("sample", "geom", "dist", "pos", "frame", "force"):
            assert np.array_equal(getattr(a.contacts, field), getattr(b.contacts, field)), field
    else:
        assert a.contacts is None and b.contacts is None  # paper mode: passes afterwards


@pytest.mark.parametrize("mode", ["paper", "native"])
def test_a_record_from_a_plain_loop_gives_the_run(mode: str) -> None:
    # SampleRecord's contract, as a batch would fill it: the state after each sample
    # interval's mj_step (row 0: after two forward passes), nothing else
    steps, n_intervals = (50, 200) if mode == "paper" else (5, 400)
    over = ("run.sample_dt_s=1e-3", f"run.t_end_s={n_intervals * 1e-3!r}")
    plan = _paper_plan(2e-5, *over) if mode == "paper" else _native_plan("RK4", 2e-4, *over)
    assert (plan.steps_per_sample, plan.n_intervals) == (steps, n_intervals)
    tm = build_model(plan)
    law = plan.law
    result = run.run_compiled(tm, plan)
    data = _start(tm)
    rows = {k: [] for k in ("time", "qpos", "qvel", "qacc_warmstart", "qfrc_constraint")}
    armed = PaperFriction(tm, data, law) if law is not None else contextlib.nullcontext()
    with armed:
        mujoco.mj_forward(tm.model, data)
        mujoco.mj_forward(tm.model, data)
        for i in range(n_intervals + 1):
            if i:
                mujoco.mj_step(tm.model, data, steps)
            for key, value in rows.items():
                value.append(np.copy(getattr(data, key)))
    record = SampleRecord(**{k: np.array(v) for k, v in rows.items()})
    again = results.result_from_samples(tm, record, plan, ran=result.ran)
    assert again.ok and result.ok, (again.message, result.message)
    assert again.table.equals(result.table)
    assert np.array_equal(again.contacts, result.contacts)
    assert (again.max_penetration_m, again.contact_energy_bound_J, again.n_steps) == (
        result.max_penetration_m, result.contact_energy_bound_J, result.n_steps)


def test_contact_sums_are_the_per_sample_reader() -> None:
    # a tippe top onto its stem (examples/capsule_stem_top.xml, its own Euler at 0.5 ms, 6 s):
    # the ball, the stem, and both at once (two contacts in one sample)
    tm = load_top(CAPSULE)
    steps, n_intervals = 1, 12000
    data = mujoco.MjData(tm.model)
    mujoco.mj_resetDataKeyframe(tm.model, data, 0)
    mujoco.mj_forward(tm.model, data)
    rec, _, _ = stepping.step_and_record(tm.model, data, steps, n_intervals, None,
                                         contacts=True)
    qa, va = tm.qpos_adr, tm.dof_adr
    n = len(rec)
    sums = results.contact_sums(tm, rec.contacts, rec.qpos[:, qa:qa + 7],
                                rec.qvel[:, va:va + 6], n)
    assert set(np.unique(sums["touching"])) >= {1, 2, 3}
    assert np.bincount(rec.contacts.sample).max() >= 2
    reader = _ContactReader(tm)
    scratch = mujoco.MjData(tm.model)
    for i in range(n):
        scratch.qpos[:], scratch.qvel[:], scratch.time = rec.qpos[i], rec.qvel[i], rec.time[i]
        scratch.qacc_warmstart[:] = rec.qacc_warmstart[i]
        mujoco.mj_forward(tm.model, scratch)
        N, F, tau = reader.read(scratch)
        # N (MuJoCo's numbers added in MuJoCo's contact order), which geoms touch and the
        # deepest penetration are the same operations on the same numbers: exact
        assert (N, reader.touching, reader.depth) == (
            sums["N"][i], sums["touching"][i], sums["depth"][i]), i
        # F, tau and the power are rotations, cross and dot products: the reader's go through
        # numpy's BLAS, which may sum in another order or fuse a multiply-add. Each such
        # result is within gamma_k = k u / (1 - k u) (u the unit roundoff) of the exact one,
        # times the same expression evaluated on absolute values (the reader's *_abs), k the
        # roundings along the deepest chain: the rotation from the quaternion (4), omega (3),
        # the cross product (2), the contact point's velocity (1), the dot products (3), the
        # sum over contacts (1): 14 <= 16, for each path, hence twice gamma_16 between them.
        # Any change of what is computed (a contact lost, a sign, a frame) is order 1, not
        # 1e-15 of the scale.
        assert np.all(np.abs(F - sums["F"][i]) <= 2 * _GAMMA_16 * reader.F_abs), i
        assert np.all(np.abs(tau - sums["tau"][i]) <= 2 * _GAMMA_16 * reader.tau_abs), i
        assert abs(reader.power - sums["power"][i]) <= 2 * _GAMMA_16 * reader.power_abs, i


#: gamma_16 = 16 u / (1 - 16 u), u = 2**-53: the bound on 16 roundings in float64.
_GAMMA_16 = 16 * 2.0**-53 / (1 - 16 * 2.0**-53)


class _ContactReader:
    """The per-sample contact reader the run used before its contacts were summed afterwards
    (kept here as the oracle of :func:`results.contact_sums`): normal force, friction force and
    friction torque on the top, from one mjData; beside them the same expressions evaluated on
    absolute values (the scale of their rounding errors)."""

    def __init__(self, top_model: TopModel) -> None:
        self.model = top_model.model
        self.body = top_model.body_id
        self.ball = top_model.ball_geom_id
        self.qpos_adr, self.dof_adr = top_model.qpos_adr, top_model.dof_adr
        #: the friction power of the last :meth:`read` (W): each contact's tangential force
        #: and torque on the material point it acts on
        self.power = 0.0
        self._f6 = np.zeros(6)
        #: which of the top's geoms touched at the last :meth:`read`: code of
        #: :data:`CONTACT_LABELS` (0 none, 1 the ball, 2 another geom: the stem, 3 both)
        self.touching = 0
        #: the deepest penetration of the top's contacts at the last :meth:`read` (m, >= 0)
        self.depth = 0.0
        #: F, tau and the power of the last :meth:`read` evaluated on absolute values
        self.F_abs, self.tau_abs, self.power_abs = np.zeros(3), np.zeros(3), 0.0

    def read(self, data: mujoco.MjData) -> tuple[float, np.ndarray, np.ndarray]:
        """(N, F (3,), tau (3,)) on the top, world frame, summed over its contacts."""
        N, F, tau = 0.0, np.zeros(3), np.zeros(3)
        self.touching = 0
        self.power = 0.0
        self.depth = 0.0
        self.F_abs, self.tau_abs, self.power_abs = np.zeros(3), np.zeros(3), 0.0
        if data.ncon == 0:
            return N, F, tau
        qa, va = self.qpos_adr, self.dof_adr
        rot = quat_to_mat(data.qpos[qa + 3:qa + 7])
        origin, v_origin = data.qpos[qa:qa + 3], data.qvel[va:va + 3]
        omega = rot @ data.qvel[va + 3:va + 6]
        # each entry of a rotation from a unit quaternion is a sum of products whose absolute
        # values add up to at most 3 (1 + 2 (y^2 + z^2), 2 (|x y| + |w z|), ...)
        omega_abs = np.full(3, 3.0 * np.abs(data.qvel[va + 3:va + 6]).sum())
        geoms, frames = data.contact.geom, data.contact.frame
        for i in range(data.ncon):
            b1, b2 = self.model.geom_bodyid[geoms[i]]
            if self.body not in (b1, b2):
                continue
            self.touching |= 1 if self.ball in geoms[i] else 2
            self.depth = max(self.depth, -float(data.contact.dist[i]))
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
            self.power += float(friction @ v_point + torque @ omega)
            f_abs = np.abs(frame).T @ np.abs(self._f6[:3]) + abs(self._f6[0]) * np.abs(frame[0])
            t_abs = np.abs(frame).T @ np.abs(self._f6[3:])
            a = np.abs(data.contact.pos[i]) + np.abs(origin)  # arm = pos - origin
            v_abs = np.abs(v_origin) + np.array([
                omega_abs[1] * a[2] + omega_abs[2] * a[1],
                omega_abs[2] * a[0] + omega_abs[0] * a[2],
                omega_abs[0] * a[1] + omega_abs[1] * a[0]])
            self.F_abs += f_abs
            self.tau_abs += t_abs
            self.power_abs += float(f_abs @ v_abs + t_abs @ omega_abs)
        return N, F, tau


class _SampleChecks:
    """The per-sample divergence checks the run used before they ran vectorised afterwards
    (kept here as the oracle of :func:`checks.check_failure`): penetration, energy rise, lost
    contact."""

    def __init__(self, R_m: float, fix: str) -> None:
        self.R_m, self.fix = R_m, fix
        self.energy0: float | None = None
        self.airborne_since: float | None = None

    def failure(self, t: float, gap: float, energy: float, other_touching: bool = False
                ) -> str | None:
        """A one-line reason if the sample at time t (s) shows a failed run, else None.

        ``other_touching``: another geom of the top (a stem) is on the table: the ball may be
        off it then (a real tippe top's stem takes over), and that is not a lost contact.
        """
        if self.energy0 is None:
            self.energy0 = energy
        if gap < -checks.MAX_PENETRATION_R * self.R_m:
            return (f"the ball sank {-gap * 1e3:.3g} mm into the table (bound "
                    f"{checks.MAX_PENETRATION_R:g} R); stiffen solref or {self.fix}")
        if energy - self.energy0 > checks.MAX_ENERGY_RISE * abs(self.energy0):
            return (f"the energy rose {100 * (energy / self.energy0 - 1):.3g}% above its "
                    f"initial value (friction can only dissipate it); {self.fix}")
        if gap <= checks.CONTACT_GAP_M or other_touching:
            self.airborne_since = None
            return None
        if self.airborne_since is None:
            self.airborne_since = t
        if t - self.airborne_since > checks.MAX_AIRBORNE_S:
            return (f"contact lost: the top left the table at t = {self.airborne_since:.6g} s "
                    f"for more than {checks.MAX_AIRBORNE_S:g} s (the model follows it on the table "
                    "only)")
        return None


def _sequences(rng: np.random.Generator, n: int, R: float):
    """Gap, energy and stem-contact sequences that fail in each way (or not) at random."""
    t = np.arange(n) * 7 * 2e-4
    gap = rng.normal(0.0, 1e-6, n) - 2e-7
    energy = 1.0 + rng.normal(0.0, 1e-3, n)
    other = rng.random(n) < 0.05
    kind = rng.integers(0, 4)
    at = int(rng.integers(1, n))
    if kind == 0:  # the ball sinks
        gap[at] = -(checks.MAX_PENETRATION_R + 0.01) * R
    elif kind == 1:  # the energy rises
        energy[at:] += 0.2
    elif kind == 2:  # airborne for longer than MAX_AIRBORNE_S, possibly interrupted
        gap[at:] = 1e-3
        other[at:] = rng.random(n - at) < 0.002
    return t, gap, energy, other


def test_vectorised_checks_are_the_per_sample_checks() -> None:
    rng = np.random.default_rng(14)
    R = FIG3_TOP.R_m
    top_model = _native()
    seen: set[str] = set()
    for _ in range(300):
        t, gap, energy, other = _sequences(rng, int(rng.integers(2, 400)), R)
        oracle = _SampleChecks(R, "FIX")
        expected = (len(t), None)
        for i in range(len(t)):
            reason = oracle.failure(float(t[i]), float(gap[i]), float(energy[i]),
                                    other_touching=bool(other[i]))
            if reason:
                expected = (i, reason)
                break
        assert checks.check_failure(top_model, t, gap, energy, other, "FIX") == expected
        seen.add("ok" if expected[1] is None else expected[1].split(":")[0][:13])
    # every outcome was exercised: no failure, and each kind of failure
    assert seen == {"ok", "the ball sank", "the energy ro", "contact lost"}


def test_a_failure_found_afterwards_ends_the_run_at_its_sample() -> None:
    steps, n_intervals, dt = 5, 300, 2e-4
    plan = _native_plan("RK4", dt, "run.sample_dt_s=1e-3", "run.t_end_s=0.3")
    assert (plan.steps_per_sample, plan.n_intervals) == (steps, n_intervals)
    tm = build_model(plan)
    data = _start(tm)
    mujoco.mj_forward(tm.model, data)
    rec, _, _ = stepping.step_and_record(tm.model, data, steps, n_intervals, None,
                                         contacts=True)
    fix = "reduce timestep_s (now 0.0002 s)"
    full = results.result_from_samples(tm, rec, plan)
    assert full.ok and len(full.table) == n_intervals + 1

    bad = 117
    qvel = rec.qvel.copy()
    qvel[bad, 4] = math.nan
    res = results.result_from_samples(tm, replace(rec, qvel=qvel), plan)
    assert res.message == (f"diverged by t = {bad * steps * dt:.6g} s (native mode): NaN or "
                           f"Inf in qpos/qvel; {fix}")
    assert len(res.table) == len(res.contacts) == bad and res.n_steps == bad * steps
    assert res.table.equals(full.table.iloc[:bad])

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

    # a failure of the checks: its sample's contacts were read, so the contact bounds cover it
    # (as when each sample was read and then checked): sink the ball where it was deepest
    depth = np.zeros(len(rec))
    np.maximum.at(depth, rec.contacts.sample, -rec.contacts.dist)
    deep = int(np.argmax(depth))
    assert deep > 0 and depth[deep] > depth[:deep].max()
    qpos = rec.qpos.copy()
    qpos[deep, 2] -= 0.3 * FIG3_TOP.R_m
    res = results.result_from_samples(tm, replace(rec, qpos=qpos), plan)
    assert res.message.startswith(f"diverged by t = {deep * steps * dt:.6g} s (native mode): "
                                  "the ball sank")
    assert len(res.table) == deep and res.max_penetration_m == depth[deep]

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
    tm = build_model(plan)
    init = InitialState(theta0=0.1, n0=n0)
    outs = []
    for compiled in (True, False):
        data = _start(tm, init)
        mujoco.mj_forward(tm.model, data)
        rec, failure, _ = stepping.step_and_record(tm.model, data, plan.steps_per_sample,
                                                   plan.n_intervals, None, contacts=True,
                                                   compiled=compiled)
        outs.append(results.result_from_samples(tm, rec, plan, failure=failure))
    a, b = outs
    assert a.status == b.status == "diverged"
    assert a.message == b.message and a.table.equals(b.table) and a.n_steps == b.n_steps


@pytest.mark.parametrize("top", ["fig3", "capsule"])
def test_compiled_and_python_passes_give_the_same(top: str) -> None:
    # paper mode's forward passes afterwards (N iterated to the state's own, the law's force
    # and power as the callback applied them); the capsule top with its stem: two points
    if top == "fig3":
        tm, stem, dt, law = _paper(), None, 2e-5, LAW
        data = _start(tm)
    else:
        plan = mujoco_plan(f"top.mjcf={str(CAPSULE)!r}", "mujoco.timestep_s=1e-4",
                           "mujoco.friction='paper'")
        tm, stem, dt, law = build_model(plan), plan.stem, 1e-4, plan.law
        assert stem is not None
        data = mujoco.MjData(tm.model)
        mujoco.mj_resetDataKeyframe(tm.model, data, plan.keyframe)
    steps = round(1e-3 / dt)
    with PaperFriction(tm, data, law, stem=stem):
        mujoco.mj_forward(tm.model, data)
        rec, _, _ = stepping.step_and_record(tm.model, data, steps, 3000 if stem else 200, None)
    outs = [results.scratch_contacts(tm, rec, law, stem, compiled=c) for c in (True, False)]
    (ca, xy_a, p_a), (cb, xy_b, p_b) = outs
    assert np.array_equal(xy_a, xy_b) and np.array_equal(p_a, p_b)
    for field in ("sample", "geom", "dist", "pos", "frame", "force"):
        assert np.array_equal(getattr(ca, field), getattr(cb, field)), field
    assert np.abs(xy_a).max() > 0  # the law acted
    if stem is not None:  # ball and stem on the table at once (from t = 0.89 s)
        assert np.bincount(ca.sample).max() >= 2
