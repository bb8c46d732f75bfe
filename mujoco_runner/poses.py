"""An engine's poses from its observables table, interpolated at frame times, for the picture.

:class:`Track` holds an engine's sampled poses (the table's x, y, z, qw, qx, qy, qz), theta and
n, and interpolates them at any time (position linearly, orientation by slerp), mapped to the
drawn model's free-joint qpos. Replaying a track is kinematic: :func:`set_pose` sets qpos, then
``mj_forward``; nothing is simulated.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import pandas as pd

from tippetop.models.errors import TippetopError
from tippetop.models.frames import quat_mul, quat_to_mat
from tippetop.mujoco_runner.model import TopModel


def _slerp(q0: np.ndarray, q1: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Row-wise spherical interpolation of unit quaternions (n, 4) at fractions alpha (n,).

    Takes the shorter arc (q and -q are the same rotation); alpha = 0 returns q0 exactly.
    """
    dot = np.einsum("ni,ni->n", q0, q1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot).clip(max=1.0)
    angle = np.arccos(dot)
    small = angle < 1e-8
    sin = np.where(small, 1.0, np.sin(angle))
    w0 = np.where(small, 1.0 - alpha, np.sin((1.0 - alpha) * angle) / sin)
    w1 = np.where(small, alpha, np.sin(alpha * angle) / sin)
    q = w0[:, None] * q0 + w1[:, None] * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


@dataclass(frozen=True)
class TrackSample:
    """An engine's state at one frame time.

    Attributes:
        t_s: The frame's simulated time (s).
        qpos: The free joint's qpos (7,) in the drawn model: body origin (m), quaternion.
        theta: Tilt of the symmetry axis (rad).
        n: Spin about the symmetry axis (rad/s).
        ended: True past the end of the engine's table (the last pose is held).
    """

    t_s: float
    qpos: np.ndarray
    theta: float
    n: float
    ended: bool


@dataclass(frozen=True)
class Track:
    """An engine's sampled poses, interpolated at frame times.

    Attributes:
        label: The panel's title, e.g. ``"MuJoCo"``.
        t_s: Sample times (s), increasing, shape (m,).
        com_m: Centre of mass O (m), shape (m, 3).
        quat: Orientation (w, x, y, z) of the drawn model's body, unit, shape (m, 4).
        theta: Tilt (rad), shape (m,).
        n: Spin (rad/s), shape (m,).
        top_model: The drawn model (where S and k sit in its body).
    """

    label: str
    t_s: np.ndarray
    com_m: np.ndarray
    quat: np.ndarray
    theta: np.ndarray
    n: np.ndarray
    top_model: TopModel

    @classmethod
    def from_table(cls, table: pd.DataFrame, top_model: TopModel, *, label: str,
                   paper_frame: bool) -> Track:
        """A track from an observables table.

        Args:
            table: Columns t, theta, n, x, y, z, qw, qx, qy, qz (:mod:`models.observables`).
            top_model: The drawn model.
            label: The panel's title.
            paper_frame: True when the table's quaternion is the paper's body frame (z axis = k,
                the reference ODE's); False when it is the MJCF body's own frame (MuJoCo's).

        Raises:
            TippetopError: If the table has no rows.
        """
        if len(table) == 0:
            raise TippetopError(f"{label} table: expected at least one row to draw, got none")
        quat = np.array(table[["qw", "qx", "qy", "qz"]], dtype=float)
        if paper_frame:
            quat = np.array([quat_mul(q, top_model.paper_from_body_quat) for q in quat])
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        return cls(label=label, t_s=table["t"].to_numpy(dtype=float),
                   com_m=table[["x", "y", "z"]].to_numpy(dtype=float), quat=quat,
                   theta=table["theta"].to_numpy(dtype=float),
                   n=table["n"].to_numpy(dtype=float), top_model=top_model)

    @property
    def t_end_s(self) -> float:
        """The last sample time (s)."""
        return float(self.t_s[-1])

    def _qpos(self, com_m: np.ndarray, quat: np.ndarray) -> np.ndarray:
        """Free-joint qpos (n, 7) of centre-of-mass positions (n, 3) and body quaternions (n, 4).

        The body origin is S - rot c, with S = O + a k the sphere's centre, k = rot k_body and
        c the sphere's centre in the body frame (zero for make_mjcf tops, where qpos[:3] = S).
        """
        tm = self.top_model
        rot = np.array([quat_to_mat(q) for q in quat])  # (n, 3, 3), body to world
        k = np.einsum("nij,j->ni", rot, tm.axis_body)
        origin = com_m + tm.top.a_m * k - np.einsum("nij,j->ni", rot, tm.centre_body_m)
        return np.concatenate([origin, quat], axis=1)

    def at(self, times_s: Sequence[float] | np.ndarray) -> list[TrackSample]:
        """The interpolated state at each time; past the last sample the last one is held."""
        t = np.asarray(times_s, dtype=float)
        ts = self.t_s
        if len(ts) == 1:
            i = np.zeros(len(t), dtype=int)
            j, alpha = i, np.zeros(len(t))
        else:
            i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
            j = i + 1
            alpha = np.clip((t - ts[i]) / (ts[j] - ts[i]), 0.0, 1.0)
        com = self.com_m[i] + alpha[:, None] * (self.com_m[j] - self.com_m[i])
        quat = _slerp(self.quat[i], self.quat[j], alpha)
        theta = self.theta[i] + alpha * (self.theta[j] - self.theta[i])
        n = self.n[i] + alpha * (self.n[j] - self.n[i])
        qpos = self._qpos(com, quat)
        ended = t > self.t_end_s * (1 + 1e-12) + 1e-12
        return [TrackSample(float(t[r]), qpos[r], float(theta[r]), float(n[r]), bool(ended[r]))
                for r in range(len(t))]


def set_pose(top_model: TopModel, data: mujoco.MjData, qpos: np.ndarray) -> None:
    """Put the top at ``qpos`` (7,), at rest, and compute positions (``mj_forward``)."""
    adr = top_model.qpos_adr
    data.qpos[adr:adr + 7] = qpos
    data.qvel[:] = 0.0
    mujoco.mj_forward(top_model.model, data)


__all__ = ["Track", "TrackSample", "set_pose"]
