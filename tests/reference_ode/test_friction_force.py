"""The friction force at the contact (``FX``, ``FY``), in the paper's frame, in the reference.

Issue 22: every engine's table carries the friction force beside the slip. In the reference
it is the law the equations integrate, so from the table alone |F| = mu N |v_P| / sqrt(|v_P|^2
+ Lambda^2) (modified Coulomb) and F points against v_P, to round-off; while the stem touches
too the two points' forces are summed (the horizontal momentum balance M u_O' = F holds).
"""

from __future__ import annotations

import numpy as np
import pytest

from tippetop.models.scene import load_scene
from tippetop.reference_ode.solve import simulate_ode


def _run(scene: str, *overrides: str, stem: bool = False):
    s = load_scene(scene, list(overrides))
    res = simulate_ode(s.top, s.friction, s.init, t_end_s=s.run.t_end_s, options=s.ode,
                       stem=s.stem if stem else None)
    return s, res.table


@pytest.mark.parametrize("formulation", ["vector", "paper"])
def test_the_reference_force_is_its_law_against_the_slip(formulation: str) -> None:
    s, t = _run("fig3", "run.t_end_s=4", f"ode.formulation={formulation}")
    t = t.dropna(subset=["FX", "FY", "vPX", "vPY"])
    F = np.hypot(t["FX"], t["FY"])
    v = np.hypot(t["vPX"], t["vPY"])
    mu, lam = s.friction.mu, s.friction.Lambda_mps
    law = mu * t["N"] * v / np.sqrt(v * v + lam * lam)
    # the same double-precision expressions evaluated twice (in the kernel and here): a few
    # ulps of the largest force
    assert np.max(np.abs(F - law)) <= 1e-13 * np.max(law)
    # against the slip: cos(F, v_P) = -1 and no sideways part, to round-off
    cos = (t["FX"] * t["vPX"] + t["FY"] * t["vPY"]) / (F * v)
    assert np.max(np.abs(cos + 1.0)) < 1e-12
    # and the power column is F . v_P
    assert np.allclose(t["P_fric"], t["FX"] * t["vPX"] + t["FY"] * t["vPY"], rtol=1e-12,
                       atol=1e-15 * np.max(np.abs(t["P_fric"])))


def test_with_the_stem_the_force_is_both_points_and_moves_the_centre() -> None:
    """On ball and stem the force is the sum of both points' laws: M du_O/dt = F.

    Checked on the table's centre-of-mass velocity (uOX, uOY are in the rotating paper frame,
    so the world-frame velocity is differenced instead): a central difference of x, y twice
    over 1-ms samples, against F / M rotated back, within the difference's O(dt^2) error.
    """
    s, t = _run("fig3", "run.t_end_s=4", "effects.stem=true", stem=True)
    on = t[t["t"] > 3.0]  # resting on the ball and the stem's end (from 2.70 s)
    assert on["FX"].notna().all()
    M = s.top.M_kg
    ts, x, y = on["t"].to_numpy(), on["x"].to_numpy(), on["y"].to_numpy()
    dt = ts[1] - ts[0]
    ax = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2
    ay = (y[2:] - 2 * y[1:-1] + y[:-2]) / dt**2
    # the paper frame's X axis: along the symmetry axis's horizontal projection
    q = on[["qw", "qx", "qy", "qz"]].to_numpy()[1:-1]
    kx = 2 * (q[:, 1] * q[:, 3] + q[:, 0] * q[:, 2])
    ky = 2 * (q[:, 2] * q[:, 3] - q[:, 0] * q[:, 1])
    s_ = np.hypot(kx, ky)
    ex, ey = kx / s_, ky / s_
    FX, FY = on["FX"].to_numpy()[1:-1], on["FY"].to_numpy()[1:-1]
    fx, fy = FX * ex - FY * ey, FX * ey + FY * ex
    scale = np.max(np.hypot(fx, fy))
    assert np.max(np.hypot(M * ax - fx, M * ay - fy)) < 2e-3 * scale
