"""What one MuJoCo run records at its samples: the states, and what happened between them.

:class:`SampleRecord` holds the mjData state after each sample interval's steps and each
sample's window (:class:`WindowRecord`: every step's forward pass added to it, see
:mod:`.worker.windows`), what the post-processing (:mod:`.results`) needs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from tippetop.mujoco_runner.worker.windows import F, I, new_windows


@dataclass(frozen=True, eq=False)
class WindowRecord:
    """Each sample's window: what the forward passes of its steps computed, added at each step.

    The columns of :mod:`.worker.windows` (``INT_FIELDS``, ``FLOAT_FIELDS``), one row per
    sample: row r holds the passes at the states after each step from sample r - 1 to sample
    r (row 0: the initial state's).

    Attributes:
        ints: The integer columns, shape (n, len(INT_FIELDS)).
        floats: The float columns, shape (n, len(FLOAT_FIELDS)).
    """

    ints: np.ndarray
    floats: np.ndarray

    def __len__(self) -> int:
        """The number of windows (samples)."""
        return len(self.ints)

    def int_column(self, name: str) -> np.ndarray:
        """One integer column, by its name in ``INT_FIELDS``."""
        return self.ints[:, I[name]]

    def float_column(self, name: str) -> np.ndarray:
        """One float column, by its name in ``FLOAT_FIELDS``."""
        return self.floats[:, F[name]]

    def head(self, n: int) -> WindowRecord:
        """The first ``n`` windows (views)."""
        return WindowRecord(self.ints[:n], self.floats[:n])

    @classmethod
    def empty(cls, n: int = 0) -> WindowRecord:
        """``n`` windows before their first pass."""
        return cls(*new_windows(np, n))

    def passes_of(self, offsets: np.ndarray, steps: int) -> np.ndarray:
        """The run's pass numbers of offsets in their windows; -1 stays -1.

        Row r's offset j is pass ``(r - 1) steps + j`` (row 0's: j); pass p is at ``p dt``.
        """
        offsets = np.asarray(offsets, dtype=np.int64)
        rows = np.arange(len(offsets), dtype=np.int64)
        out = np.maximum(rows - 1, 0) * steps + offsets
        return np.where(offsets < 0, -1, out)

    def first_pass(self, name: str, steps: int) -> int | None:
        """The first pass at which an offset column is set; None: at none.

        ``first_other``, ``flip``, ``first_touch``: the windows' offsets of their events.
        """
        p = self.passes_of(self.int_column(name), steps)
        hit = np.flatnonzero(p >= 0)
        return int(p[hit[0]]) if hit.size else None

    def gaps(self, steps: int) -> np.ndarray:
        """The stretches of passes at which the top did not touch, located to the pass.

        Each is ``(start, passes, height_m)``: its first pass, how many passes it lasts and
        the largest gap between the ball and the table over its passes (m). Every stretch
        that spans a window's edge is here; within a window, only its longest stretch between
        two touches (``inner_free``): all of them when a window is shorter than the stretches
        that matter (the samples are 1-3 ms apart, a flight lasts 10 ms). A structured
        array, by start.
        """
        dtype = np.dtype([("start", np.int64), ("passes", np.int64), ("height_m", float)])
        n = len(self)
        if not n:
            return np.zeros(0, dtype=dtype)
        first = self.passes_of(self.int_column("first_touch"), steps)
        last = self.passes_of(self.int_column("last_touch"), steps)
        gap = self.float_column("gap_max")
        lead, trail = self.float_column("lead_gap"), self.float_column("trail_gap")
        end = (n - 1) * steps  # the last pass
        rows = np.flatnonzero(first >= 0)
        # between touching windows a < b (and before the first, after the last): the passes
        # after a's last touch, the windows between (no touch at all), b's before its first
        starts = np.concatenate(([0], last[rows] + 1))
        stops = np.concatenate((first[rows], [end + 1]))
        row_a = np.concatenate(([-1], rows))
        row_b = np.concatenate((rows, [n]))
        length = stops - starts
        keep = length > 0
        starts, length, row_a, row_b = starts[keep], length[keep], row_a[keep], row_b[keep]
        ext_gap = np.concatenate((gap, [-np.inf]))
        inside = _range_max(ext_gap, row_a + 1, np.maximum(row_b - 1, row_a + 1))
        inside = np.where(row_b - 1 >= row_a + 1, inside, -np.inf)
        edge_a = np.where(row_a >= 0, trail[np.maximum(row_a, 0)], -np.inf)
        edge_b = np.where(row_b < n, lead[np.minimum(row_b, n - 1)], -np.inf)
        height = np.maximum(np.maximum(edge_a, inside), edge_b)
        inner = self.int_column("inner_free")
        rows_in = np.flatnonzero(inner > 0)
        in_start = self.passes_of(self.int_column("inner_start"), steps)[rows_in]
        out = np.zeros(len(starts) + rows_in.size, dtype=dtype)
        out["start"] = np.concatenate((starts, in_start))
        out["passes"] = np.concatenate((length, inner[rows_in]))
        out["height_m"] = np.concatenate((height, self.float_column("inner_gap")[rows_in]))
        return np.sort(out, order="start")


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
        windows: Each sample's window: what every step's forward pass since the sample
            before computed (:class:`WindowRecord`).
        warnings: ``mjData.warning.number`` (cumulative counters), shape (n, mjNWARNING), int;
            None: not recorded (the caller checked them while stepping and stopped at the first
            sample with a warning, passing ``failure`` to :func:`result_from_samples`).
        warning_text: MuJoCo's text of the first warning (the run's message quotes it); None:
            the last one the warning handler kept.
        warning_names: The names of ``warnings``' columns (``mjtWarning``), from the release
            that stepped (its enum need not be this one's: 4.0 dropped ``mjWARN_VGEOMFULL``);
            None: this process's ``mujoco.mjtWarning``.
        path: How the samples were stepped: ``compiled stepper``, ``plain loop`` (Python),
            or a worker's (``worker: plain loop``).
    """

    time: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    qacc_warmstart: np.ndarray
    qfrc_constraint: np.ndarray
    windows: WindowRecord
    warnings: np.ndarray | None = None
    warning_text: str | None = None
    warning_names: tuple[str, ...] | None = None
    path: str = ""

    def __len__(self) -> int:
        """The number of recorded samples."""
        return len(self.time)

    def head(self, n: int) -> SampleRecord:
        """The first ``n`` samples (views)."""
        return replace(self, time=self.time[:n], qpos=self.qpos[:n], qvel=self.qvel[:n],
                       qacc_warmstart=self.qacc_warmstart[:n],
                       qfrc_constraint=self.qfrc_constraint[:n],
                       warnings=None if self.warnings is None else self.warnings[:n],
                       windows=self.windows.head(n))


def _range_max(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``values[lo[i]:hi[i] + 1].max()`` for many ranges (a sparse table of maxima)."""
    table = [np.asarray(values, dtype=float)]
    span = 1
    while 2 * span <= len(values):
        prev = table[-1]
        table.append(np.maximum(prev[:-span], prev[span:]))
        span *= 2
    size = hi - lo + 1
    level = np.floor(np.log2(size)).astype(np.int64)
    out = np.empty(len(lo))
    for k in np.unique(level):
        sel = level == k
        t = table[k]
        out[sel] = np.maximum(t[lo[sel]], t[hi[sel] - (1 << k) + 1])
    return out


#: What a run records of mjData's state per sample (with qfrc_constraint beside it).
STATE_SPEC = (mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_QPOS
               | mujoco.mjtState.mjSTATE_QVEL | mujoco.mjtState.mjSTATE_WARMSTART)


__all__ = ["STATE_SPEC", "SampleRecord", "WindowRecord"]
