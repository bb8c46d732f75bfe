"""MuJoCo's friction force at the contact (``FX``, ``FY``), in the paper's frame (issue 22).

Paper mode: the harness's law, so |F| = mu N |v_P| / sqrt(|v_P|^2 + Lambda^2) against the
slip. Native mode: MuJoCo's own contact forces rotated out of each contact's frame: a
measurement, checked here for its frame (F . v_P is the friction power MuJoCo's contact
forces do, the table's P_fric) and its bound (|F| <= mu N: no force outside the cone).

A sample's forces are its window's means: every step's since the sample before
(mujoco_runner/worker/windows.py). Against the slip at the sample they are checked with a
sample at every step (a window of one step, at the sample's own state); coarser samples hold
the means of those rows.
"""

from __future__ import annotations

import numpy as np

from tests.conftest import mujoco_plan
from tippetop.models.scene import load_scene
from tippetop.mujoco_runner.run import simulate_plan


def _table(*overrides: str):
    over = ["run.t_end_s=2", *overrides]
    plan = mujoco_plan(*over, scene="fig3")
    return load_scene("fig3", over), plan, simulate_plan(plan).table


def _every_step(mode: str, dt: float) -> tuple[str, ...]:
    return (f"mujoco.friction={mode}", f"mujoco.timestep_s={dt!r}", f"run.sample_dt_s={dt!r}")


def test_paper_mode_force_is_the_law_against_the_slip() -> None:
    scene, _plan, t = _table(*_every_step("paper", 2e-5))
    t = t[t["N"] > 0].dropna(subset=["FX", "vPX"])
    F = np.hypot(t["FX"], t["FY"]).to_numpy()
    v = np.hypot(t["vPX"], t["vPY"]).to_numpy()
    N = t["N"].to_numpy()
    mu, lam = scene.friction.mu, scene.friction.Lambda_mps
    law = mu * N * v / np.sqrt(v * v + lam * lam)
    # the callback uses the normal force of the evaluation before (the constraint force it
    # has: RK4's last stage of the step before), the table the contact's at this step: they
    # differ by N's change over about a step, so |F - law| <= mu |Delta N| with the slip's
    # factor below 1; the change between two steps' passes bounds it within a factor 2
    # (measured 1.29 at most: the stages fall between the passes). The settling start, where
    # N changes by 3 % a step, is in the bound too.
    dN = np.abs(np.diff(N))
    assert np.all(np.abs(F - law)[2:] <= 2.0 * mu * dN[1:] + 1e-12 * np.max(law))
    after = t["t"].to_numpy() > 0.05  # settled: the lag is 2e-7 of the force at most
    assert np.max(np.abs(F - law)[after]) <= 1e-6 * np.max(law)
    cos = (t["FX"] * t["vPX"] + t["FY"] * t["vPY"]).to_numpy() / (F * v)
    assert np.max(np.abs(cos + 1.0)) < 1e-9


def test_native_force_is_the_contacts_own_in_the_paper_frame() -> None:
    _scene, plan, t = _table(*_every_step("native", 2e-4))
    t = t[t["N"] > 0].dropna(subset=["FX", "vPX"])
    assert len(t) > 1000
    # condim 3 (no torsion): the friction power is F . v_P, so F in the paper frame dotted
    # with the slip there gives the power MuJoCo's contact forces do (P_fric: each contact's
    # force at its own point). MuJoCo's contact point sits half the penetration above the
    # ball's lowest point P, where the slip differs by |omega| depth / 2: measured 1.6e-4 of
    # the largest power on this run, so 1e-3 bounds it; a frame turned by even 0.05 rad would
    # not pass (the force is nearly along the slip: the cos below)
    power = t["FX"] * t["vPX"] + t["FY"] * t["vPY"]
    assert np.max(np.abs(power - t["P_fric"])) <= 1e-3 * np.max(np.abs(t["P_fric"]))
    # inside the friction cone: |F_t| <= mu N (the pyramid's edges have slope mu)
    mu = plan.ball_contact.friction[0]
    assert np.all(np.hypot(t["FX"], t["FY"]) <= mu * t["N"] * (1 + 1e-9))
    # and it opposes the slip on the whole (it is MuJoCo's soft friction, not the law)
    assert np.median((t["FX"] * t["vPX"] + t["FY"] * t["vPY"])
                     / (np.hypot(t["FX"], t["FY"]) * np.hypot(t["vPX"], t["vPY"]))) < -0.9


def test_a_sample_holds_its_window_means() -> None:
    # 1-ms samples against a sample at every step of the same run (the same steps, bit for
    # bit): N, P_fric and the world friction force are the means of the five rows after each
    # step of the window; FX and FY are that mean in the sample's own paper frame. The sums
    # are the same numbers added in another order: 1e-12 of the scale bounds the rounding.
    _s, _p, every = _table("mujoco.friction=native", "mujoco.timestep_s=0.0002",
                           "run.sample_dt_s=0.0002")
    _s, _p, coarse = _table("mujoco.friction=native", "mujoco.timestep_s=0.0002")
    n = len(coarse) - 1
    for col in ("N", "P_fric"):
        means = every[col].to_numpy()[1:].reshape(n, 5).mean(axis=1)
        scale = np.max(np.abs(means))
        assert np.max(np.abs(coarse[col].to_numpy()[1:] - means)) <= 1e-12 * scale, col
        assert coarse[col].iloc[0] == every[col].iloc[0]
    # |F_t| of the mean is at most the mean of |F_t|, and equal where the force keeps its
    # direction over 1 ms (it turns with the precession, ~0.03 rad a millisecond here)
    F = np.hypot(coarse["FX"], coarse["FY"]).to_numpy()[1:]
    F_each = np.hypot(every["FX"], every["FY"]).to_numpy()[1:].reshape(n, 5).mean(axis=1)
    assert np.all(F <= F_each * (1 + 1e-12) + 1e-15)
    assert np.median(F / np.where(F_each > 0, F_each, 1.0)) > 0.999
