"""Run a MuJoCo tippe top from a plan and return the shared observables table.

:func:`simulate_plan` takes a :class:`~tippetop.models.plan.MujocoPlan` (made by
:func:`tippetop.models.plan.resolve_plan`, the one place a scene is resolved): it builds the
generated top (:func:`tippetop.models.mjcf.make_mjcf`) or loads the MJCF file and applies the
settings the plan sets (a ``None`` keeps the file's), runs it, and reports what ran, read back
from the compiled model and from the top's contact at t = 0 (:func:`settings_that_ran`).
Friction is either the paper's law applied by the compiled callback (``mode="paper"``,
frictionless condim-1 contacts; no callback at all when the plan applies no law) or MuJoCo's
own contact friction (``mode="native"``). :func:`simulate_mujoco` is the same for a top given
by its parameters and keyword settings; :func:`simulate_top_model` runs a compiled top as is.

A run has two parts. The stepping (:func:`_step_and_record`) advances the top one sample
interval at a time and records the state at each sample (:class:`SampleRecord`): in one
compiled loop over many samples that calls MuJoCo's C functions (:mod:`.stepper`; from Python
if that is not available), checking the new samples for NaN and MuJoCo warnings once per
:data:`PROGRESS_INTERVAL_S` of wall time. Without the paper-mode callback each sample's contacts
are read from the forward pass that begins the next step (``mj_step`` taken apart, bit for
bit), so they cost no extra pass. Then :func:`result_from_samples` computes the rest from the
record, vectorised: the contacts and forces at each sample's own state (paper mode: forward
passes on a scratch copy armed with the same law, iterated to the state's own N), the checks
(penetration, energy, lost contact) and the observables table. A run that diverges ends with
``status == "diverged"``, a one-line message, and only the samples before the failure: the
same sample and message whichever part finds it. A batch of simulations (``mujoco.batch``)
records its own samples and calls :func:`result_from_samples` for each.
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import mujoco
import numpy as np
import pandas as pd

from tippetop.models.errors import expect
from tippetop.models.mjcf import FRICTION_MODES
from tippetop.models.params import FrictionParams, InitialState, StemParams, TopParams
from tippetop.models.plan import MujocoPlan, check_mujoco_steps, sample_interval
from tippetop.mujoco_runner import stepper
from tippetop.mujoco_runner.friction_callback import (
    LAST_OUTPUT,
    USERDATA_SIZE,
    PaperFriction,
    compiled_callback,
    law_parameters,
)
from tippetop.mujoco_runner.model import MUJOCO_WARNINGS, TopModel
from tippetop.mujoco_runner.observables import observables_table
from tippetop.mujoco_runner.settings import build_model, integrator_name, settings_that_ran
from tippetop.mujoco_runner.state import initial_qpos_qvel, rotations

#: The top's contacts at a sample: none, the ball, another geom (the stem), both.
CONTACT_LABELS = ("none", "ball", "stem", "both")
#: Deepest admissible penetration of the ball into the table, in radii (the soft contact sinks
#: ~0.025 R at rest with the default solref; more than this means the contact failed).
MAX_PENETRATION_R = 0.2
#: The ball's lowest point more than this above the table counts as "no contact" (m).
CONTACT_GAP_M = 1e-6
#: Longer than this without contact is "contact lost" (s); the paper assumes permanent contact.
MAX_AIRBORNE_S = 0.05
#: A rise of the mechanical energy by more than this fraction of its initial value marks an
#: unstable integration (friction and the contact can only dissipate energy).
MAX_ENERGY_RISE = 0.1
#: Wall time between calls of the progress callback (s).
PROGRESS_INTERVAL_S = 0.2
#: Forward passes per sample in paper mode that bring the recorded normal force to the state's
#: own (the callback uses the previous evaluation's N; see :mod:`.friction_callback`).
_N_FORCE_PASSES = 3
#: Paper mode's longest step, times the law's slip relaxation rate (see _check_law_resolved).
PAPER_LAW_MAX_DT_RATE = 1.0
#: Relative tolerance for "sample_dt_s is a whole number of timesteps".
_GRID_RTOL = 1e-9


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


def simulate_mujoco(
    top: TopParams,
    friction: FrictionParams,
    init: InitialState,
    *,
    t_end_s: float,
    sample_dt_s: float,
    mode: str = "paper",
    timestep_s: float = 2e-5,
    integrator: str = "RK4",
    cone: str = "elliptic",
    condim: int | None = None,
    mu: float | None = None,
    solref: Sequence[float] = (0.02, 1.0),
    solimp: Sequence[float] = (0.9, 0.95, 0.001, 0.5, 2.0),
    impratio: float = 1.0,
    torsional: float = 0.0,
    rolling: float = 0.0,
    progress: Callable[[float], None] | None = None,
) -> MujocoResult:
    """Simulate the loaded sphere in MuJoCo (a :class:`MujocoPlan` built from arguments).

    Args:
        top: The loaded sphere (SI).
        friction: The friction law. Paper mode applies it (any law of
            :class:`~tippetop.models.params.FrictionParams`; ``none`` applies nothing);
            native mode uses only ``friction.mu``.
        init: The paper's initial state.
        t_end_s: Simulated time (s).
        sample_dt_s: Sampling interval (s), a whole number of timesteps.
        mode: ``"paper"`` or ``"native"``.
        timestep_s: Integration step (s).
        integrator: MuJoCo integrator (``Euler``, ``RK4``, ``implicit``, ``implicitfast``).
        cone: ``"pyramidal"`` or ``"elliptic"`` (native mode).
        condim: Contact dimensionality (None: 1 in paper mode, 3 in native mode).
        mu: Sliding coefficient; None means ``friction.mu`` (both modes).
        solref: Contact solref.
        solimp: Contact solimp.
        impratio: Frictional-to-normal impedance ratio (native mode).
        torsional: Torsional coefficient (m), native condim >= 4.
        rolling: Rolling coefficient (m), native condim 6.
        progress: Called with the simulated time (s) now and then (at most every
            :data:`PROGRESS_INTERVAL_S` of wall time, and at the end).

    Returns:
        The run's :class:`MujocoResult`.

    Raises:
        TippetopError: For bad arguments (nothing is simulated then).
    """
    expect(mode in FRICTION_MODES, "mode", "one of " + "|".join(FRICTION_MODES), mode)
    for name, value in (("sample_dt_s", sample_dt_s), ("t_end_s", t_end_s)):
        expect(isinstance(value, (int, float)) and math.isfinite(value) and value > 0, name,
               "a finite number > 0 (seconds)", value)
    mu_eff = friction.mu if mu is None else float(mu)
    if condim is None:
        condim = 1 if mode == "paper" else 3
    law = None
    if mode == "paper" and friction.law != "none":
        law = FrictionParams(friction.law, mu_eff, friction.Lambda_mps, friction.viscous_Nspm,
                             friction.coulomb_v_eps_mps)
    plan = MujocoPlan(
        mode=mode, top=top, mjcf=None, law=law, init=init, t_end_s=float(t_end_s),
        sample_dt_s=None, requested_sample_dt_s=float(sample_dt_s), timestep_s=timestep_s,
        integrator=integrator, cone=cone, impratio=impratio, condim=condim,
        mu=0.0 if mode == "paper" else mu_eff, solref=tuple(solref), solimp=tuple(solimp),
        torsional=torsional, rolling=rolling)
    return simulate_plan(plan, progress=progress)


def simulate_plan(plan: MujocoPlan, *,
                  progress: Callable[[float], None] | None = None) -> MujocoResult:
    """Run a plan (:func:`tippetop.models.plan.resolve_plan`).

    Args:
        plan: What to run.
        progress: Called with the simulated time (s) now and then (at most every
            :data:`PROGRESS_INTERVAL_S` of wall time, and at the end).

    Returns:
        The run, with ``ran`` read back from the model that ran.

    Raises:
        TippetopError: For settings the model cannot take (nothing is simulated then).
    """
    top_model = build_model(plan)
    dt = float(top_model.model.opt.timestep)
    sample_dt = sample_interval(plan.t_end_s, plan.requested_sample_dt_s, dt)
    # a run that blows up says so in its status and one-line message; numpy's overflow
    # warnings on the way (energies of a diverging state) would only add a second line
    with np.errstate(over="ignore", invalid="ignore"):
        return simulate_top_model(top_model, plan.law, plan.init, t_end_s=plan.t_end_s,
                                  sample_dt_s=sample_dt, mode=plan.mode, progress=progress,
                                  keyframe=plan.keyframe, stem=plan.stem)


def _check_paper_contacts(top_model: TopModel) -> None:
    """Paper mode needs frictionless contacts on the ball (else friction is applied twice)."""
    model, ball = top_model.model, top_model.ball_geom_id
    dims = {int(model.geom_condim[ball])}
    for g in range(model.ngeom):
        static = model.body_weldid[model.geom_bodyid[g]] == 0
        if static and (model.geom_contype[g] or model.geom_conaffinity[g]):
            dims.add(int(model.geom_condim[g]))
    for p in range(model.npair):
        if ball in (model.pair_geom1[p], model.pair_geom2[p]):
            dims.add(int(model.pair_dim[p]))
    expect(dims == {1}, "mode", "paper mode on a model whose ball and table contacts have "
           "condim 1 (frictionless)", f"condims {sorted(dims)}")


def contact_reach_m(top_model: TopModel) -> float:
    """How far from the centre of mass a contact on the top can be (m).

    Over its colliding geoms, the distance of the geom's centre from G plus its bounding radius.
    """
    model, b = top_model.model, top_model.body_id
    reach = top_model.top.R_m + top_model.top.a_m
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == b and (model.geom_contype[g] or model.geom_conaffinity[g]):
            d = float(np.linalg.norm(model.geom_pos[g] - model.body_ipos[b]))
            reach = max(reach, d + float(model.geom_rbound[g]))
    return reach


def paper_law_max_timestep(law: FrictionParams, top_model: TopModel) -> float | None:
    """The longest step paper mode follows ``law`` with on this top (s); None: any step.

    The callback applies the law once per stage from the state's slip: with a step longer than
    the slip's relaxation time (:meth:`FrictionParams.slip_relaxation_rate`, with the top's
    farthest contact point, a stem's, say) the slip overshoots zero every step and the force
    flips instead of relaxing (a viscous law diverges; the paper's law chatters and drives the
    top with the wrong force: on tests/data/tutorial_tippe_top.xml, mu = 1, at dt = 2e-3 s,
    14x the limit, it turned over 20 % early, and at 2e-4 s, 1.4x, it stuck on ball and stem
    where the reference rises onto the stem). At dt <= 1/rate both agree with the reference.
    """
    rate = law.slip_relaxation_rate(top_model.top, contact_reach_m(top_model))
    return PAPER_LAW_MAX_DT_RATE / rate if rate > 0.0 else None


def _check_law_resolved(law: FrictionParams, top_model: TopModel, dt: float) -> None:
    """Refuse a timestep the paper-mode law cannot be followed with (fail loudly, not wrong)."""
    limit = paper_law_max_timestep(law, top_model)
    if limit is None:
        return
    expect(dt <= limit, "mujoco.timestep_s",
           f"at most {limit:.3g} s for the paper's law on this top (law {law.law}, mu "
           f"{law.mu:g}: its slip relaxes in {1e3 * limit / PAPER_LAW_MAX_DT_RATE:.3g} ms, "
           "and a longer step makes the force flip instead of relax; set mujoco.timestep_s)",
           dt)


def _grid(sample_dt_s: float, t_end_s: float, timestep_s: float) -> tuple[int, int]:
    """(steps per sample, number of sample intervals)."""
    for name, value in (("sample_dt_s", sample_dt_s), ("t_end_s", t_end_s)):
        expect(isinstance(value, (int, float)) and math.isfinite(value) and value > 0, name,
               "a finite number > 0 (seconds)", value)
    steps = round(sample_dt_s / timestep_s)
    expect(steps >= 1 and abs(steps * timestep_s - sample_dt_s) <= _GRID_RTOL * sample_dt_s,
           "sample_dt_s", f"a whole multiple of the timestep {timestep_s:g} s", sample_dt_s)
    n_intervals = math.floor(t_end_s / sample_dt_s * (1 + _GRID_RTOL))
    expect(n_intervals >= 1, "t_end_s", f">= sample_dt_s = {sample_dt_s:g} s", t_end_s)
    check_mujoco_steps(t_end_s, timestep_s)  # a loaded file's timestep is known only here
    return steps, n_intervals


#: The failure reason of a sample whose qpos or qvel is not finite (``; fix`` follows).
NONFINITE_REASON = "NaN or Inf in qpos/qvel"


def warning_reason(counts: np.ndarray, text: str | None = None) -> str:
    """The failure reason for MuJoCo's warning counters ``counts`` (``mjData.warning.number``).

    ``text``: MuJoCo's own text of the warning (default: the last one the warning handler kept,
    :data:`~mujoco_runner.model.MUJOCO_WARNINGS`).
    """
    counts = np.asarray(counts)
    i = int(np.flatnonzero(counts)[0])
    if text is None:
        text = MUJOCO_WARNINGS[-1] if MUJOCO_WARNINGS else ""
    text = f": {text.removeprefix('WARNING: ')}" if text else ""
    return (f"MuJoCo warning {mujoco.mjtWarning(i).name} ({int(counts[i])}x){text}, "
            "the integration is unstable")


@dataclass(frozen=True, eq=False)
class ContactRecord:
    """The top's contacts, as MuJoCo computed them at the samples' own states: one row each.

    A forward pass (``mj_forward``) at sample i's state gives its contacts; each of them that
    touches the top's body is a row here, in MuJoCo's contact order within a sample, samples
    in increasing order. Contacts of other bodies may be rows too (they are filtered out).

    Attributes:
        sample: The sample index of each contact, shape (m,), int, non-decreasing.
        geom: ``mjContact.geom`` (geom1, geom2), shape (m, 2), int.
        dist: ``mjContact.dist`` (m; negative: penetration), shape (m,).
        pos: ``mjContact.pos``, world frame (m), shape (m, 3).
        frame: ``mjContact.frame`` (rows: normal from geom1 to geom2, two tangents), (m, 9).
        force: ``mj_contactForce`` in the contact frame (normal, tangential, then torques),
            shape (m, 6).
    """

    sample: np.ndarray
    geom: np.ndarray
    dist: np.ndarray
    pos: np.ndarray
    frame: np.ndarray
    force: np.ndarray

    @classmethod
    def empty(cls) -> ContactRecord:
        """No contacts."""
        return cls(np.zeros(0, dtype=np.int64), np.zeros((0, 2), dtype=np.int64), np.zeros(0),
                   np.zeros((0, 3)), np.zeros((0, 9)), np.zeros((0, 6)))


#: The fields of ``mjContact`` a :class:`ContactRecord` keeps.
_CONTACT_FIELDS = (("dist", "f8", ()), ("pos", "f8", (3,)), ("frame", "f8", (9,)),
                   ("geom", "i4", (2,)))


class _ContactLog:
    """Collects :class:`ContactRecord` rows from one mjData, sample by sample.

    MuJoCo keeps an mjData's contacts at the start of its arena (``mj_clearEfc`` sets
    ``d->contact = d->arena`` before each collision pass), so once the first contact shows its
    address and layout, each sample's contacts are one memory copy of ``ncon`` structs into
    this log's buffer (no Python object per field and sample), and ``mj_contactForce`` per
    contact.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.model, self.data = model, data
        self.counts: list[tuple[int, int]] = []  # (sample, ncon)
        self._dtype: np.dtype | None = None
        self._base = 0
        self._rows = np.zeros(0)
        self._force = np.empty((0, 6))
        self._used = 0

    def _layout(self) -> None:
        """Find the contact structs' address and layout from the bindings' views."""
        c = self.data.contact
        base = c.dist.ctypes.data
        fields = [getattr(c, name) for name, _, _ in _CONTACT_FIELDS]
        if min(f.ctypes.data for f in fields) != base:  # pragma: no cover - a new layout
            raise RuntimeError("mjContact no longer starts with dist")
        self._dtype = np.dtype({
            "names": [name for name, _, _ in _CONTACT_FIELDS],
            "formats": [(kind, shape) for _, kind, shape in _CONTACT_FIELDS],
            "offsets": [f.ctypes.data - base for f in fields],
            "itemsize": c.dist.strides[0]})
        self._base = base
        self._grow(256)

    def _grow(self, need: int) -> None:
        size = max(need, 2 * len(self._rows))
        rows, force = np.empty(size, dtype=self._dtype), np.empty((size, 6))
        rows[:self._used] = self._rows[:self._used]
        force[:self._used] = self._force[:self._used]
        self._rows, self._force = rows, force

    def add(self, i: int, data: mujoco.MjData) -> None:
        """Append the contacts of the log's mjData (after a forward pass) as sample ``i``'s."""
        ncon = data.ncon
        if not ncon:
            return
        if self._dtype is None:
            self._layout()
        used = self._used
        if used + ncon > len(self._rows):
            self._grow(used + ncon)
        size = self._dtype.itemsize
        ctypes.memmove(self._rows.ctypes.data + used * size, self._base, ncon * size)
        force = self._force
        for k in range(ncon):
            mujoco.mj_contactForce(self.model, data, k, force[used + k])
        self._used = used + ncon
        self.counts.append((i, ncon))

    def record(self) -> ContactRecord:
        """Everything added, as one record."""
        if not self.counts:
            return ContactRecord.empty()
        counts = np.array(self.counts, dtype=np.int64)
        rows = self._rows[:self._used]
        return ContactRecord(np.repeat(counts[:, 0], counts[:, 1]),
                             rows["geom"].astype(np.int64), rows["dist"].copy(),
                             rows["pos"].copy(), rows["frame"].copy(),
                             self._force[:self._used].copy())


@dataclass(frozen=True, eq=False)
class SampleRecord:
    """The recorded states of ONE simulation at its samples t = 0, sample_dt, 2 sample_dt, ...

    Row i is the mjData right after the i-th sample interval's ``mj_step(model, data, steps)``
    returned (row 0: the initial state after the run's two ``mj_forward`` passes, see
    :func:`simulate_top_model`). Every array has one row per recorded sample, n rows; the
    model's whole qpos/qvel (not only the top's free joint).

    Attributes:
        time: ``mjData.time`` (s), shape (n,).
        qpos: ``mjData.qpos``, shape (n, nq).
        qvel: ``mjData.qvel``, shape (n, nv).
        qacc_warmstart: ``mjData.qacc_warmstart`` (the warm start the next forward pass starts
            its constraint solve from), shape (n, nv).
        qfrc_constraint: ``mjData.qfrc_constraint`` as the step left it: the constraint force
            of the step's LAST dynamics evaluation (with RK4 its last stage's, not the sample
            state's), shape (n, nv). Paper mode's callback takes its normal force from it in
            the first forward pass at the sample's state (see :mod:`.friction_callback`).
        warnings: ``mjData.warning.number`` (cumulative counters), shape (n, mjNWARNING), int;
            None: not recorded (the caller checked them while stepping and stopped at the first
            sample with a warning, passing ``failure`` to :func:`result_from_samples`).
        warning_text: MuJoCo's text of the first warning (the run's message quotes it); None:
            the last one the warning handler kept.
        contacts: The contacts at each sample's own state, if the stepping computed them (a
            forward pass at the sample's state); None: :func:`result_from_samples` computes
            them with forward passes on a scratch mjData.
    """

    time: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    qacc_warmstart: np.ndarray
    qfrc_constraint: np.ndarray
    warnings: np.ndarray | None = None
    warning_text: str | None = None
    contacts: ContactRecord | None = None

    def __len__(self) -> int:
        """The number of recorded samples."""
        return len(self.time)

    def head(self, n: int) -> SampleRecord:
        """The first ``n`` samples (views)."""
        contacts = self.contacts
        if contacts is not None:
            keep = contacts.sample < n
            contacts = ContactRecord(*(getattr(contacts, f)[keep] for f in
                                       ("sample", "geom", "dist", "pos", "frame", "force")))
        return replace(self, time=self.time[:n], qpos=self.qpos[:n], qvel=self.qvel[:n],
                       qacc_warmstart=self.qacc_warmstart[:n],
                       qfrc_constraint=self.qfrc_constraint[:n],
                       warnings=None if self.warnings is None else self.warnings[:n],
                       contacts=contacts)


def _fix(model: mujoco.MjModel) -> str:
    """What to change when a run diverges."""
    dt = float(model.opt.timestep)
    integrator = integrator_name(int(model.opt.integrator))
    return f"reduce timestep_s (now {dt:g} s)" + (
        "" if integrator == "RK4" else f" or use integrator RK4 (now {integrator})")


def ran_settings(top_model: TopModel, data: mujoco.MjData, *, mode: str,
                 law: FrictionParams | None, mu: float | None = None, steps: int,
                 keyframe: int | None = None) -> dict[str, Any]:
    """The ``ran`` dict of a run (:attr:`MujocoResult.ran`).

    :func:`settings_that_ran` of ``data`` at t = 0 (after a forward pass), plus the friction
    law, its mu, the row spacing and the keyframe.
    """
    model = top_model.model
    ran = settings_that_ran(top_model, data)
    ran["friction_law"] = ("mujoco-native" if mode == "native"
                           else law.law if law is not None else "none")
    if law is not None:
        ran["law_mu"] = float(law_parameters(law, top_model, mu)["mu"])
    ran["sample_dt_s"] = steps * float(model.opt.timestep)
    ran["keyframe"] = None if keyframe is None else (
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, keyframe) or f"#{keyframe}")
    return ran


def _step_failure(record: SampleRecord) -> tuple[int, str | None]:
    """(first sample that failed while stepping, its reason) or (len(record), None)."""
    n = len(record)
    bad = ~(np.isfinite(record.qpos).all(axis=1) & np.isfinite(record.qvel).all(axis=1))
    warned = (np.zeros(n, dtype=bool) if record.warnings is None
              else np.asarray(record.warnings).any(axis=1))
    hits = np.flatnonzero(bad | warned)
    if not hits.size:
        return n, None
    i = int(hits[0])
    if bad[i]:
        return i, NONFINITE_REASON
    return i, warning_reason(record.warnings[i], record.warning_text)


def _scratch_contacts(top_model: TopModel, record: SampleRecord, law: FrictionParams | None,
                      mu: float | None, stem: StemParams | None, *, compiled: bool | None = None
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
    log = _ContactLog(model, scratch)
    n = len(record)
    law_xy = np.empty((n, 2)) if law is not None else None
    law_power = np.empty(n) if law is not None else None
    spec = _STATE_SPEC
    state = np.empty((n, mujoco.mj_stateSize(model, spec)))
    nq, nv = model.nq, model.nv
    state[:, 0] = record.time
    state[:, 1:1 + nq] = record.qpos
    state[:, 1 + nq:1 + nq + nv] = record.qvel
    state[:, 1 + nq + nv:] = record.qacc_warmstart
    passes = _N_FORCE_PASSES if law is not None else 1
    forward, forward_skip = mujoco.mj_forward, mujoco.mj_forwardSkip
    skip_pos = int(mujoco.mjtStage.mjSTAGE_POS)
    with contextlib.ExitStack() as stack:
        scratch_law = None
        if law is not None:
            scratch_law = stack.enter_context(PaperFriction(top_model, scratch, law, mu=mu,
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


#: What a run records of mjData's state per sample (with qfrc_constraint beside it).
_STATE_SPEC = (mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_QPOS
               | mujoco.mjtState.mjSTATE_QVEL | mujoco.mjtState.mjSTATE_WARMSTART)


def _contact_sums(top_model: TopModel, contacts: ContactRecord, qpos: np.ndarray,
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


def _gap_energy_many(top_model: TopModel, qpos: np.ndarray, qvel: np.ndarray
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


def _check_failure(top_model: TopModel, t: np.ndarray, gap: np.ndarray, energy: np.ndarray,
                   other_touching: np.ndarray, fix: str) -> tuple[int, str | None]:
    """The divergence checks over all samples: (first failing sample, reason) or (n, None).

    A sample fails when the ball sank more than :data:`MAX_PENETRATION_R` R into the table,
    when the energy rose more than :data:`MAX_ENERGY_RISE` above the first sample's, or when
    the ball has been off the table (gap above :data:`CONTACT_GAP_M`, no other geom of the top
    touching) for more than :data:`MAX_AIRBORNE_S`.
    """
    n = len(t)
    if not n:
        return 0, None
    R = top_model.top.R_m
    e0 = energy[0]
    sink = gap < -MAX_PENETRATION_R * R
    with np.errstate(invalid="ignore"):
        rise = energy - e0 > MAX_ENERGY_RISE * abs(e0)
    ok = (gap <= CONTACT_GAP_M) | other_touching
    idx = np.arange(n)
    last_ok = np.maximum.accumulate(np.where(ok, idx, -1))
    start = np.minimum(last_ok + 1, n - 1)
    since = t[start]
    lost = ~ok & (t - since > MAX_AIRBORNE_S)
    hits = np.flatnonzero(sink | rise | lost)
    if not hits.size:
        return n, None
    i = int(hits[0])
    if sink[i]:
        return i, (f"the ball sank {-gap[i] * 1e3:.3g} mm into the table (bound "
                   f"{MAX_PENETRATION_R:g} R); stiffen solref or {fix}")
    if rise[i]:
        return i, (f"the energy rose {100 * (energy[i] / e0 - 1):.3g}% above its "
                   f"initial value (friction can only dissipate it); {fix}")
    return i, (f"contact lost: the top left the table at t = {since[i]:.6g} s "
               f"for more than {MAX_AIRBORNE_S:g} s (the model follows it on the table only)")


def result_from_samples(
    top_model: TopModel,
    record: SampleRecord,
    *,
    mode: str,
    law: FrictionParams | None,
    steps: int,
    n_intervals: int,
    mu: float | None = None,
    stem: StemParams | None = None,
    failure: str | None = None,
    wall_s: float = 0.0,
    ran: dict[str, Any] | None = None,
) -> MujocoResult:
    """The :class:`MujocoResult` of one simulation from its recorded samples.

    Everything a run reports besides the states is computed here, after the stepping: the
    contacts and forces at each sample's own state (from ``record.contacts``, or forward
    passes on a scratch mjData: one, or :data:`_N_FORCE_PASSES` in paper mode with a law,
    armed with the same law), the checks that end a run (a non-finite state or a MuJoCo
    warning at a sample; then the ball sinking more than :data:`MAX_PENETRATION_R`, the
    energy rising more than :data:`MAX_ENERGY_RISE`, contact lost longer than
    :data:`MAX_AIRBORNE_S`, in that order at one sample), and the observables table. The run
    ends at the first failed sample, which is not in the table, with its one-line reason.

    Args:
        top_model: The top the record was stepped on (the same compiled model).
        record: The samples, row i at t = i * steps * dt (see :class:`SampleRecord`).
        mode: ``"paper"`` or ``"native"``.
        law: Paper mode: the law the callback applied (None: no friction). Native: None.
        steps: Integration steps per sample interval.
        n_intervals: Sample intervals the run was to step (``len(record) - 1`` when it ran
            to the end).
        mu: Paper mode: the coefficient that overrode ``law.mu``, if any.
        stem: Paper mode: the stem's end the law also acts at.
        failure: Why the stepping stopped after the last recorded sample (the sample after it
            failed: e.g. :data:`NONFINITE_REASON`, :func:`warning_reason`, a MuJoCo error);
            None: it did not stop early. The reason is followed by ``; <what to change>``.
        wall_s: Wall time of the stepping (s); the post-processing's own time is added.
        ran: The run's :func:`ran_settings`.

    Returns:
        The run's result.
    """
    expect(mode in FRICTION_MODES, "mode", "one of " + "|".join(FRICTION_MODES), mode)
    start = time.perf_counter()
    model = top_model.model
    dt = float(model.opt.timestep)
    fix = _fix(model)
    integrator = integrator_name(int(model.opt.integrator))
    qa, va = top_model.qpos_adr, top_model.dof_adr
    n_step_ok, reason = _step_failure(record)
    if reason is not None:
        reason = f"{reason}; {fix}"
    elif failure is not None:
        reason = f"{failure}; {fix}"
    rec = record.head(n_step_ok)
    n = len(rec)
    law_xy = law_power = None
    contacts = rec.contacts
    if contacts is None or law is not None:
        contacts, law_xy, law_power = _scratch_contacts(top_model, rec, law, mu, stem)
    qpos, qvel = rec.qpos[:, qa:qa + 7], rec.qvel[:, va:va + 6]
    sums = _contact_sums(top_model, contacts, qpos, qvel, n)
    t_check = np.arange(n) * steps * dt  # as the checks always had it: (i * steps) * dt
    gap, energy = _gap_energy_many(top_model, qpos, qvel)
    n_good, check = _check_failure(top_model, t_check, gap, energy,
                                   (sums["touching"] & 2) > 0, fix)
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
        message = (f"{mode} mode: {n_steps} steps of {integrator} at dt = {dt:g} s to "
                   f"t = {n_intervals * steps * dt:g} s in {wall:.3g} s")
    else:
        message = f"diverged by t = {n_good * steps * dt:.6g} s ({mode} mode): {reason}"
    return MujocoResult(table=table, n_steps=n_steps, wall_s=wall, status=status,
                        message=message, mode=mode, warnings=top_model.warnings,
                        ran=dict(ran or {}), contacts=sums["touching"][:n_good].copy(),
                        max_penetration_m=float(np.fmax.reduce(depth, initial=0.0)),
                        contact_energy_bound_J=float(np.fmax.reduce(bound, initial=0.0)))


def run_grid(top_model: TopModel, friction: FrictionParams | None, *, mode: str,
             t_end_s: float, sample_dt_s: float, mu: float | None = None
             ) -> tuple[int, int, FrictionParams | None]:
    """Check a run of ``top_model`` before anything is simulated; its grid and its law.

    The checks of :func:`simulate_top_model` (and of every run of a batch,
    :mod:`mujoco_runner.batch`): the mode, the sample grid, paper mode's frictionless
    contacts, and the law's parameters and its slip relaxation against the timestep.

    Returns:
        ``(steps, n_intervals, law)``: timesteps per sample, sample intervals, and the law the
        callback applies (None in native mode, or when paper mode applies no law).

    Raises:
        TippetopError: For a run that cannot be made as asked (one line).
    """
    expect(mode in FRICTION_MODES, "mode", "one of " + "|".join(FRICTION_MODES), mode)
    dt = float(top_model.model.opt.timestep)
    steps, n_intervals = _grid(sample_dt_s, t_end_s, dt)
    law = friction if mode == "paper" and friction is not None and friction.law != "none" \
        else None
    if mode == "paper":
        _check_paper_contacts(top_model)
    if law is not None:
        law_parameters(law, top_model, mu)
        _check_law_resolved(law if mu is None else replace(law, mu=mu), top_model, dt)
    return steps, n_intervals, law


def simulate_top_model(
    top_model: TopModel,
    friction: FrictionParams | None,
    init: InitialState,
    *,
    t_end_s: float,
    sample_dt_s: float,
    mode: str = "paper",
    mu: float | None = None,
    progress: Callable[[float], None] | None = None,
    keyframe: int | None = None,
    stem: StemParams | None = None,
) -> MujocoResult:
    """Simulate a compiled top as it is (integrator, timestep and contacts from its model).

    The stepping records the state at each sample (:class:`SampleRecord`) and checks it for
    NaN and MuJoCo warnings once per :data:`PROGRESS_INTERVAL_S` of wall time (stopping at
    the first failed sample); :func:`result_from_samples` computes everything else afterwards.

    Args:
        top_model: From :func:`mujoco_runner.model.load_top`.
        friction: Paper mode: the law applied by the callback; None (or law ``none``) applies
            no friction and installs no callback. Native mode: unused (the model's friction
            applies).
        init: The paper's initial state (:func:`mujoco_runner.state.initial_qpos_qvel`).
        t_end_s: Simulated time (s).
        sample_dt_s: Sampling interval (s), a whole number of timesteps.
        mode: ``"paper"`` (needs condim-1 contacts) or ``"native"``.
        mu: Paper mode: overrides ``friction.mu``.
        progress: Called with the simulated time (s) now and then (at most every
            :data:`PROGRESS_INTERVAL_S` of wall time, and at the end).
        keyframe: Start from this keyframe of the model exactly (``mj_resetDataKeyframe``),
            not from ``init``.
        stem: Paper mode: the stem's end, where the law also acts when it touches the table.

    Returns:
        The run's :class:`MujocoResult`.
    """
    steps, n_intervals, law = run_grid(top_model, friction, mode=mode, t_end_s=t_end_s,
                                       sample_dt_s=sample_dt_s, mu=mu)
    record, failure, wall_s, ran = step_top_model(
        top_model, law, init, steps=steps, n_intervals=n_intervals, mode=mode, mu=mu,
        progress=progress, keyframe=keyframe, stem=stem)
    result = result_from_samples(top_model, record, mode=mode, law=law, steps=steps,
                                 n_intervals=n_intervals, mu=mu, stem=stem, failure=failure,
                                 wall_s=wall_s, ran=ran)
    if progress is not None and len(result.table):
        progress(float(result.table["t"].iloc[-1]))
    return result


def step_top_model(
    top_model: TopModel,
    law: FrictionParams | None,
    init: InitialState,
    *,
    steps: int,
    n_intervals: int,
    mode: str,
    mu: float | None = None,
    progress: Callable[[float], None] | None = None,
    keyframe: int | None = None,
    stem: StemParams | None = None,
) -> tuple[SampleRecord, str | None, float, dict[str, Any]]:
    """The stepping half of :func:`simulate_top_model`, after :func:`run_grid`.

    Starts a new mjData as the run does (initial state or keyframe, the callback armed with
    ``law``, a forward pass for what ran) and steps it sample by sample. Touches nothing
    shared but the process-wide callback, so runs of a thread pool may each call it on
    their own mjData (the compiled stepper runs without the GIL).

    Returns:
        ``(record, failure, wall_s, ran)``: the samples, why the stepping stopped early
        (None), its wall time and :func:`ran_settings`, for :func:`result_from_samples`.
    """
    model = top_model.model
    data = mujoco.MjData(model)
    qa, va = top_model.qpos_adr, top_model.dof_adr
    if keyframe is None:
        data.qpos[qa:qa + 7], data.qvel[va:va + 6] = initial_qpos_qvel(top_model, init)
    else:
        mujoco.mj_resetDataKeyframe(model, data, keyframe)
    callback = contextlib.ExitStack()
    if law is not None:
        callback.enter_context(PaperFriction(top_model, data, law, mu=mu, stem=stem))
        compiled_callback()  # compiled (or loaded) once per process; kept out of wall_s
    mujoco.mj_forward(model, data)
    ran = ran_settings(top_model, data, mode=mode, law=law, mu=mu, steps=steps,
                       keyframe=keyframe)
    with callback:
        record, failure, wall_s = _step_and_record(model, data, steps, n_intervals, progress,
                                                   contacts=law is None)
    return record, failure, wall_s, ran


def contacts_from_steps(model: mujoco.MjModel, law: FrictionParams | None) -> bool:
    """Whether a run reads each sample's contacts from its own steps (no passes afterwards).

    True for a run without paper mode's law on a model whose ``mj_step`` is known to split
    after its forward pass (:func:`_integrator_split`); the others' contacts come from
    forward passes at the recorded states in :func:`result_from_samples`.
    """
    return law is None and _integrator_split(model) is not None


def _integrator_split(model: mujoco.MjModel) -> tuple[int, str] | None:
    """How ``mj_step`` ends after its forward pass, for this model; None: not known.

    ``mj_step`` is ``mj_checkPos``, ``mj_checkVel``, ``mj_forward``, ``mj_checkAcc``, then the
    integrator (tests/mujoco_runner/test_record.py checks the split is bit-identical): a
    :mod:`.stepper` integrator code and the C name of a (m, d) integrator.
    """
    enabled = int(model.opt.enableflags)
    if enabled & (int(mujoco.mjtEnableBit.mjENBL_FWDINV) | int(mujoco.mjtEnableBit.mjENBL_SLEEP)):
        return None
    kind = int(model.opt.integrator)
    if kind == int(mujoco.mjtIntegrator.mjINT_RK4):
        return stepper.INTEG_RK4, "mj_Euler"
    if kind == int(mujoco.mjtIntegrator.mjINT_EULER):
        return stepper.INTEG_PLAIN, "mj_Euler"
    if kind in (int(mujoco.mjtIntegrator.mjINT_IMPLICIT),
                int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST)):
        return stepper.INTEG_PLAIN, "mj_implicit"
    return None


def _integrator_step(model: mujoco.MjModel) -> Callable[[mujoco.MjModel, mujoco.MjData],
                                                       None] | None:
    """:func:`_integrator_split` as a Python call; None: not known."""
    split = _integrator_split(model)
    if split is None:
        return None
    if split[0] == stepper.INTEG_RK4:
        return lambda m, d: mujoco.mj_RungeKutta(m, d, 4)
    return getattr(mujoco, split[1])


def _step_and_record(model: mujoco.MjModel, data: mujoco.MjData, steps: int, n_intervals: int,
                     progress: Callable[[float], None] | None, *, contacts: bool = False,
                     compiled: bool | None = None
                     ) -> tuple[SampleRecord, str | None, float]:
    """Step ``data`` sample by sample, recording each; (record, failure, wall time).

    In :mod:`.stepper`'s compiled loop when it is available (``compiled``: None, the
    default), else (or with ``compiled=False``) from Python: the same C calls either way.
    """
    if compiled is None:
        compiled = stepper.available()[0]
    if compiled:
        return _step_compiled(model, data, steps, n_intervals, progress, contacts=contacts)
    return _step_python(model, data, steps, n_intervals, progress, contacts=contacts)


def _chunk_failure(state: np.ndarray, warn: np.ndarray, nq: int, nv: int) -> int | None:
    """The first of these rows whose qpos/qvel is not finite or that has a warning, or None."""
    good = np.isfinite(state[:, 1:1 + nq + nv]).all(axis=1) & ~warn.any(axis=1)
    bad = np.flatnonzero(~good)
    return int(bad[0]) if bad.size else None


def _step_compiled(model: mujoco.MjModel, data: mujoco.MjData, steps: int, n_intervals: int,
                   progress: Callable[[float], None] | None, *, contacts: bool
                   ) -> tuple[SampleRecord, str | None, float]:
    """:func:`_step_python` in :class:`.stepper.CompiledStepper` calls of many samples each.

    Each call lasts about half of :data:`PROGRESS_INTERVAL_S` (its length adapts), so the
    checks and the progress reports keep the single loop's pace.
    """
    n_rows = n_intervals + 1
    split = _integrator_split(model) if contacts else None
    integ, plain = split if split is not None else (stepper.INTEG_STEP, "mj_Euler")
    run = stepper.CompiledStepper(model, data, steps=steps, n_rows=n_rows, integrator=integ,
                                  plain=plain, spec=int(_STATE_SPEC))
    nq, nv = model.nq, model.nv
    dt = float(model.opt.timestep)
    text = None
    wall0 = time.perf_counter()
    next_report = wall0  # report t = 0 at once
    mujoco.mj_forward(model, data)  # the contact force of the initial state, for N
    n, chunk, first = 0, 1, True
    while n < n_rows:
        k = min(chunk, n_rows - n)
        start = time.perf_counter()
        run.advance(n, k, first=first)
        elapsed = time.perf_counter() - start
        first = False
        bad = _chunk_failure(run.state[n:n + k], run.warn[n:n + k], nq, nv)
        if bad is not None:
            n += bad + 1
            if MUJOCO_WARNINGS:
                text = MUJOCO_WARNINGS[-1]
            break
        n += k
        now = time.perf_counter()
        if progress is not None and now >= next_report and n < n_rows:
            progress((n - 1) * steps * dt)
            next_report = time.perf_counter() + PROGRESS_INTERVAL_S
        chunk = max(1, min(4 * k, int(k * 0.5 * PROGRESS_INTERVAL_S / max(elapsed, 1e-9))))
    wall_s = time.perf_counter() - wall0
    state = run.state[:n]
    record_contacts = None
    if run.contacts:
        sample, rows, force = run.contact_rows()
        keep = sample < n
        rows = rows[keep]
        record_contacts = ContactRecord(sample[keep], rows["geom"].astype(np.int64),
                                        rows["dist"].copy(), rows["pos"].copy(),
                                        rows["frame"].copy(), force[keep])
    record = SampleRecord(time=state[:, 0], qpos=state[:, 1:1 + nq],
                          qvel=state[:, 1 + nq:1 + nq + nv],
                          qacc_warmstart=state[:, 1 + nq + nv:], qfrc_constraint=run.con[:n],
                          warnings=run.warn[:n], warning_text=text, contacts=record_contacts)
    return record, None, wall_s


def _step_python(model: mujoco.MjModel, data: mujoco.MjData, steps: int, n_intervals: int,
                 progress: Callable[[float], None] | None, *, contacts: bool = False
                 ) -> tuple[SampleRecord, str | None, float]:
    """Step ``data`` sample by sample from Python, recording each.

    The state (time, qpos, qvel, warm start), qfrc_constraint and the warning counters
    are copied at each sample; once per :data:`PROGRESS_INTERVAL_S` of wall time the new rows
    are checked (finite, no warning) and the stepping stops at the first failed one, which is
    kept in the record (:func:`result_from_samples` ends the run there).

    With ``contacts`` (for a model without the paper-mode callback, whose forward pass at a
    state depends on nothing the record leaves out), each sample interval's first step is
    ``mj_step`` taken apart: its forward pass at the sample's state is the one the table's
    contacts need, so they are read from ``data`` there (:attr:`SampleRecord.contacts`) and
    the run needs no second forward pass per sample. Models whose ``mj_step`` is not known to
    split so are stepped whole (then ``contacts`` is None and the post-processing computes
    them).
    """
    n_rows = n_intervals + 1
    spec = _STATE_SPEC
    state = np.empty((n_rows, mujoco.mj_stateSize(model, spec)))
    con = np.empty((n_rows, model.nv))
    counts = data.warning.number  # a live view of the counters
    warn = np.zeros((n_rows, counts.size), dtype=counts.dtype)
    nq, nv = model.nq, model.nv
    data_con = data.qfrc_constraint
    integrate = _integrator_step(model) if contacts else None
    log = _ContactLog(model, data) if integrate is not None else None
    wall0 = time.perf_counter()
    next_report = wall0  # report t = 0 at once
    n = 0  # rows recorded
    checked = 0  # rows checked
    text = None
    mujoco.mj_forward(model, data)  # the contact force of the initial state, for N
    get_state, step, forward = mujoco.mj_getState, mujoco.mj_step, mujoco.mj_forward
    check_pos, check_vel, check_acc = mujoco.mj_checkPos, mujoco.mj_checkVel, mujoco.mj_checkAcc
    while True:
        get_state(model, data, state[n], spec)
        con[n] = data_con
        warn[n] = counts
        if log is not None:  # the next step's own start: its forward pass at this state
            check_pos(model, data)
            check_vel(model, data)
            forward(model, data)
            check_acc(model, data)
            log.add(n, data)
        n += 1
        now = time.perf_counter()
        if n == n_rows or now >= next_report:
            rows = state[checked:n]
            good = (np.isfinite(rows[:, 1:1 + nq + nv]).all(axis=1)
                    & ~warn[checked:n].any(axis=1))
            bad = np.flatnonzero(~good)
            if bad.size:
                n = checked + int(bad[0]) + 1
                if MUJOCO_WARNINGS:
                    text = MUJOCO_WARNINGS[-1]
                break
            checked = n
            if n == n_rows:
                break
            if progress is not None:
                progress((n - 1) * steps * float(model.opt.timestep))
            next_report = time.perf_counter() + PROGRESS_INTERVAL_S
        if integrate is not None:
            integrate(model, data)  # the rest of the step begun above
            if steps > 1:
                step(model, data, steps - 1)
        else:
            step(model, data, steps)
    wall_s = time.perf_counter() - wall0
    state = state[:n]
    record = SampleRecord(time=state[:, 0], qpos=state[:, 1:1 + nq],
                          qvel=state[:, 1 + nq:1 + nq + nv],
                          qacc_warmstart=state[:, 1 + nq + nv:], qfrc_constraint=con[:n],
                          warnings=warn[:n], warning_text=text,
                          contacts=None if log is None else log.record())
    return record, None, wall_s


__all__ = [
    "CONTACT_GAP_M",
    "ContactRecord",
    "NONFINITE_REASON",
    "SampleRecord",
    "ran_settings",
    "result_from_samples",
    "warning_reason",
    "MAX_AIRBORNE_S",
    "MAX_ENERGY_RISE",
    "MAX_PENETRATION_R",
    "MujocoResult",
    "PROGRESS_INTERVAL_S",
    "simulate_mujoco",
    "simulate_plan",
    "simulate_top_model",
    "step_top_model",
    "contacts_from_steps",
    "run_grid",
    "paper_law_max_timestep",
    "contact_reach_m",
]
