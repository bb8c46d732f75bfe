"""The reference follows a tippe top onto its stem: contact phases, impacts, two points.

The Fig. 3 top (A/C = 1, a/R = 0.1, n0 = 100 rad/s) with the scenes' default stem, a rounded
end 1.3 R from the ball's centre of radius 0.2 R: the end reaches the table at
cos theta = (r - R) / l = -0.8 / 1.3 (theta = 2.2337 rad), after the inversion (2.33 s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tippetop.models.errors import TippetopError
from tippetop.models.options import OdeOptions
from tippetop.models.params import InitialState, StemParams, TopParams
from tippetop.models.scene import load_scene
from tippetop.reference_ode.contacts import (
    ball_contact,
    contact_point,
    impact,
    normal_velocity,
    stem_contact,
)
from tippetop.reference_ode.solve import initial_state_vector, simulate_ode

T_END = 4.0  # s: the stem touches at 2.70 s; the top then rests on both points


def _run(*overrides: str, stem: bool = True, sample_dt_s: float | None = None):
    s = load_scene("fig3", [f"run.t_end_s={T_END}", *overrides])
    return s, simulate_ode(s.top, s.friction, s.init, t_end_s=s.run.t_end_s,
                           sample_dt_s=sample_dt_s, options=s.ode,
                           stem=s.stem if stem else None)


@pytest.fixture(scope="module")
def fig3_stem():
    return _run()


def test_the_stem_touches_where_its_geometry_says(fig3_stem) -> None:
    scene, run = fig3_stem
    stem, R = scene.stem, scene.top.R_m
    theta_touch = math.acos(stem.touch_cos(R))
    assert theta_touch == pytest.approx(math.acos(-0.8 / 1.3), rel=1e-15)
    # Until it touches the run is the stemless one; there, the end's lowest point, at
    # R + l cos(theta) - r above the table, reaches 0: locate that on the stemless run's
    # 0.1-ms samples (linear interpolation of a smooth theta: error << 1e-6 s)
    _, free = _run(stem=False, sample_dt_s=1e-4)
    t, th = free.table["t"].to_numpy(), free.table["theta"].to_numpy()
    g = R + stem.offset_m * np.cos(th) - stem.radius_m
    i = np.flatnonzero(g <= 0.0)[0]
    t_touch = t[i - 1] + (t[i] - t[i - 1]) * g[i - 1] / (g[i - 1] - g[i])
    assert run.t_stem == pytest.approx(t_touch, abs=1e-6)
    assert run.phases[0]["contact"] == "ball" and run.phases[0]["t_end"] == run.t_stem
    assert run.impacts[0]["to"] == "stem" and run.impacts[0]["t"] == run.t_stem


def test_on_both_points_the_tilt_is_fixed_and_the_weight_shared(fig3_stem) -> None:
    scene, run = fig3_stem
    assert run.status == "ok"
    both = [p for p in run.phases if p["contact"] == "both"]
    assert both and both[-1]["t_end"] == T_END  # it ends resting on the ball and the end
    tb = run.table
    on = tb[(tb["t"] > both[-1]["t_start"]) & (tb["t"] <= T_END)]
    theta_touch = math.acos(scene.stem.touch_cos(scene.top.R_m))
    # both points on the table fix theta (k_z'' = 0 holds it to the integrator's tolerance:
    # drift ~ rtol per unit time; 1e-8 rad bounds it over ~1.3 s)
    assert np.max(np.abs(on["theta"] - theta_touch)) < 1e-8
    # and the centre of mass's height, so N1 + N2 = M g (to round-off)
    Mg = scene.top.M_kg * scene.top.g_mps2
    assert np.max(np.abs(on["N"] / Mg - 1.0)) < 1e-10


def test_energy_only_falls_and_jellett_holds_within_each_single_point_phase(fig3_stem) -> None:
    _, run = fig3_stem
    E = run.table["E"].to_numpy()
    # friction dissipates and the impacts are inelastic: E never rises (the integrator's
    # error at rtol 1e-9: 100 rtol E0 is the harness's monotonicity allowance)
    assert np.max(E - np.minimum.accumulate(E)) <= 1e-7 * E[0]
    # J of the point that touches alone is conserved in its phase (rtol 1e-9: 1e-8)
    drifts = [p["J_rel_drift"] for p in run.phases if p["contact"] != "both"
              and p["t_end"] - p["t_start"] > 1e-3]
    assert drifts and max(drifts) < 1e-8
    assert all(p["J_rel_drift"] is None for p in run.phases if p["contact"] == "both")


def test_an_impact_stops_the_new_point_and_costs_the_inelastic_energy() -> None:
    """A perfectly inelastic, frictionless impact: the struck point's vertical velocity goes to
    0, the centre of mass's horizontal velocity is kept, and the kinetic energy falls by
    v^2 / (2 W) with W = 1/M + e_z . (I^-1 (X x e_z)) x X, the effective inverse mass at the
    point (exact: the impulse is linear)."""
    top = TopParams.from_ratios(1.0, 0.1)
    stem = StemParams("sphere", 1.3 * top.R_m, 0.2 * top.R_m)
    ball, end = ball_contact(top), stem_contact(top, stem)
    # a state just at the touching tilt, spinning and tilting further (the end approaching)
    init = InitialState(theta0=math.acos(stem.touch_cos(top.R_m)), thetadot0=3.0,
                        Omega0=40.0, n0=-50.0, uOX=0.01, uOY=-0.02)
    y = initial_state_vector(top, init)
    v_before = normal_velocity(y, ball, end)
    assert v_before < 0.0
    out = impact(y, top, ball, end)
    assert not out.both and out.approach_mps == pytest.approx(-v_before, rel=1e-15)
    assert abs(normal_velocity(out.y, end, end)) < 1e-14
    assert np.array_equal(out.y[:8], y[:8])  # positions, orientation, horizontal velocity

    k = np.array([math.sin(init.theta0), 0.0, math.cos(init.theta0)])  # phi = 0

    def kinetic(state, b_touching):
        # v_O's vertical part from the touching sphere's constraint: z_O = r - b k_z
        w = state[8:11]
        vz = -b_touching * np.cross(w, k)[2]
        n = w @ k
        return 0.5 * top.M_kg * (state[2] ** 2 + state[3] ** 2 + vz * vz) + 0.5 * (
            top.A_kgm2 * (w @ w) + (top.C_kgm2 - top.A_kgm2) * n * n)

    kk = k
    X = contact_point(kk, end)
    ez = np.array([0.0, 0.0, 1.0])
    A, C = top.A_kgm2, top.C_kgm2

    def inv_inertia(v):
        return v / A + (1 / C - 1 / A) * (kk @ v) * kk

    W = 1 / top.M_kg + np.cross(inv_inertia(np.cross(X, ez)), X)[2]
    loss = kinetic(y, ball.b_m) - kinetic(out.y, end.b_m)
    assert loss == pytest.approx(v_before ** 2 / (2 * W), rel=1e-9)


def test_a_flat_end_takes_the_top_onto_its_rim() -> None:
    """The tutorial-style top (a flat stem end, mu = 1, 200 rad/s): the reference rises onto
    the end and stays on it, the ball off the table (its last phase is the stem's)."""
    from pathlib import Path

    from tippetop.compare.running.engines import plan_for

    file = Path(__file__).resolve().parents[1] / "data" / "tutorial_tippe_top.xml"
    plan = plan_for(load_scene(None, [f"top.mjcf={str(file)!r}", "run.t_end_s=6"]), "ode")
    p = plan.ode
    assert p.stem == StemParams("cylinder", 0.028, 0.004)
    run = simulate_ode(p.top, p.friction, p.init, t_end_s=p.t_end_s, options=p.options,
                       stem=p.stem)
    assert run.status == "ok" and run.t_stem is not None
    assert run.phases[-1]["contact"] == "stem" and run.phases[-1]["J_rel_drift"] is None
    theta_touch = math.acos(p.stem.touch_cos(p.top.R_m))
    assert run.table["theta"].iloc[-1] > theta_touch + 0.3  # up on the end, toward pi


def test_a_stem_needs_the_vector_formulation() -> None:
    s = load_scene("fig3", ["effects.stem=true"])
    with pytest.raises(TippetopError, match="^ode.formulation: expected vector with a stem"):
        simulate_ode(s.top, s.friction, s.init, t_end_s=1.0,
                     options=OdeOptions(formulation="paper"), stem=s.stem)


def test_a_stem_that_cannot_reach_the_table_is_refused() -> None:
    with pytest.raises(TippetopError, match="^stem: expected an end that reaches beyond"):
        load_scene("fig3", ["effects.stem=true", "stem.offset_m=0.005", "stem.radius_m=0.002"])
