"""What one MuJoCo run records at its samples: the states, and the contacts at them.

:class:`SampleRecord` holds the mjData state after each sample interval's steps (what the
post-processing, :mod:`.results`, needs); :class:`ContactRecord` the top's contacts at the
samples' own states, collected by :class:`ContactLog` one memory copy per sample.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, replace

import mujoco
import numpy as np


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
CONTACT_FIELDS = (("dist", "f8", ()), ("pos", "f8", (3,)), ("frame", "f8", (9,)),
                   ("geom", "i4", (2,)))


class ContactLog:
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
        fields = [getattr(c, name) for name, _, _ in CONTACT_FIELDS]
        if min(f.ctypes.data for f in fields) != base:  # pragma: no cover - a new layout
            raise RuntimeError("mjContact no longer starts with dist")
        self._dtype = np.dtype({
            "names": [name for name, _, _ in CONTACT_FIELDS],
            "formats": [(kind, shape) for _, kind, shape in CONTACT_FIELDS],
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
    :func:`~.stepping.step_top_model`). Every array has one row per recorded sample, n rows; the
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
            the first forward pass at the sample's state (see docs/design.md).
        warnings: ``mjData.warning.number`` (cumulative counters), shape (n, mjNWARNING), int;
            None: not recorded (the caller checked them while stepping and stopped at the first
            sample with a warning, passing ``failure`` to :func:`result_from_samples`).
        warning_text: MuJoCo's text of the first warning (the run's message quotes it); None:
            the last one the warning handler kept.
        warning_names: The names of ``warnings``' columns (``mjtWarning``), from the release
            that stepped (its enum need not be this one's: 4.0 dropped ``mjWARN_VGEOMFULL``);
            None: this process's ``mujoco.mjtWarning``.
        contacts: The contacts at each sample's own state, if the stepping computed them (a
            forward pass at the sample's state); None: :func:`result_from_samples` computes
            them with forward passes on a scratch mjData.
        path: How the samples were stepped: ``compiled stepper``, ``plain loop`` (Python),
            ``mujoco.batch``, or a worker's (``worker: plain loop``).
    """

    time: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    qacc_warmstart: np.ndarray
    qfrc_constraint: np.ndarray
    warnings: np.ndarray | None = None
    warning_text: str | None = None
    warning_names: tuple[str, ...] | None = None
    contacts: ContactRecord | None = None
    path: str = ""

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


#: What a run records of mjData's state per sample (with qfrc_constraint beside it).
STATE_SPEC = (mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_QPOS
               | mujoco.mjtState.mjSTATE_QVEL | mujoco.mjtState.mjSTATE_WARMSTART)


__all__ = ["CONTACT_FIELDS", "STATE_SPEC", "ContactLog", "ContactRecord", "SampleRecord"]
