"""The observables table (models.observables.COLUMNS + EXTRA_COLUMNS) from sampled MuJoCo states.

:func:`observables_table` computes every column from the sampled free-joint qpos/qvel and the
contact's forces, in the table frame and SI (see :mod:`models.observables` and
:mod:`models.frames`). How each column is defined, with the paper's equations: docs/design.md.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tippetop.models.observables import COLUMNS, EXTRA_COLUMNS
from tippetop.mujoco_runner.model import TopModel
from tippetop.mujoco_runner.state import kinematics, paper_angles


def observables_table(
    top_model: TopModel,
    t_s: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    N: np.ndarray,
    F_fric: np.ndarray,
    tau_fric: np.ndarray | None = None,
    *,
    power: np.ndarray | None = None,
) -> pd.DataFrame:
    """The observables table for n sampled states.

    Args:
        top_model: The top.
        t_s: Sample times (s), shape (n,).
        qpos: Free-joint positions, shape (n, 7).
        qvel: Free-joint velocities, shape (n, 6).
        N: Contact normal force on the top (N), shape (n,).
        F_fric: Friction force on the top at P, world frame (N), shape (n, 3).
        tau_fric: Friction torque on the top (torsional and rolling, N m), world frame, shape
            (n, 3); None means zero.
        power: The friction power (W), shape (n,), when it is known as applied (the paper
            mode's callback, at each point it acted on); None: F . v_P at the ball's P.

    Returns:
        A DataFrame with exactly ``COLUMNS + EXTRA_COLUMNS``, one row per sample.
    """
    top = top_model.top
    R, a, A, C, M, g = top.R_m, top.a_m, top.A_kgm2, top.C_kgm2, top.M_kg, top.g_mps2
    n_rows = len(t_s)
    if n_rows == 0:
        return pd.DataFrame({name: np.zeros(0) for name in COLUMNS + EXTRA_COLUMNS})
    kin = kinematics(top_model, qpos, qvel)
    ang = paper_angles(kin)
    theta, n, Omega = ang["theta"], ang["n"], ang["Omega"]
    cos_t = kin.k[:, 2]
    omega = kin.omega_radps
    L = A * omega + (C - A) * n[:, None] * kin.k
    J = R * L[:, 2] - a * C * n
    h = R - a * cos_t
    lever = R * cos_t - a
    with np.errstate(invalid="ignore", divide="ignore"):
        disc = J * J + 4 * A * M * g * lever * h * a
        root = np.sqrt(np.where(disc >= 0, disc, np.nan))
        xi_plus = (J + root) / (2 * lever)
        xi_minus = -2 * A * M * g * a * h / (J + root)
    xi_plus[~np.isfinite(xi_plus)] = np.nan
    xi_minus[~np.isfinite(xi_minus)] = np.nan
    v_com = kin.v_com_mps
    E = (0.5 * M * np.einsum("ni,ni->n", v_com, v_com) + 0.5 * np.einsum("ni,ni->n", omega, L)
         + M * g * kin.com_m[:, 2])
    v_P = kin.v_P_mps
    P_fric = np.einsum("ni,ni->n", np.asarray(F_fric, dtype=float), v_P)
    if tau_fric is not None:
        P_fric = P_fric + np.einsum("ni,ni->n", np.asarray(tau_fric, dtype=float), omega)
    if power is not None:
        P_fric = np.asarray(power, dtype=float)
    quat = qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1, keepdims=True)
    columns = {
        "t": np.asarray(t_s, dtype=float),
        "theta": theta,
        "theta_dot": ang["theta_dot"],
        "Omega": Omega,
        "n": n,
        "xi": C * n - A * Omega * cos_t,
        "xi_plus": xi_plus,
        "xi_minus": xi_minus,
        "J": J,
        "E": E,
        "vPX": np.einsum("ni,ni->n", v_P, kin.e_X),
        "vPY": np.einsum("ni,ni->n", v_P, kin.e_Y),
        "N": np.asarray(N, dtype=float),
        "uOX": np.einsum("ni,ni->n", v_com, kin.e_X),
        "uOY": np.einsum("ni,ni->n", v_com, kin.e_Y),
        "x": kin.com_m[:, 0],
        "y": kin.com_m[:, 1],
        "z": kin.com_m[:, 2],
        "qw": quat[:, 0],
        "qx": quat[:, 1],
        "qy": quat[:, 2],
        "qz": quat[:, 3],
        "P_fric": P_fric,
        "FX": np.einsum("ni,ni->n", np.asarray(F_fric, dtype=float), kin.e_X),
        "FY": np.einsum("ni,ni->n", np.asarray(F_fric, dtype=float), kin.e_Y),
    }
    names = COLUMNS + EXTRA_COLUMNS
    # one float block, as the reference's table (a frame from a dict of 23 columns costs
    # ~1 ms of pandas per table: a third of a short run's post-processing)
    block = np.empty((len(names), n_rows))
    for i, name in enumerate(names):
        block[i] = columns[name]
    return pd.DataFrame(block.T, columns=list(names))


__all__ = ["observables_table"]
