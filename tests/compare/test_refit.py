"""The refit: the reference rerun with the law an engine realised (issue 22).

The question the refit answers is whether the friction law is the whole difference between an
engine's run and the reference. It is tested where the answer is known: a "run" made by the
reference itself with another law (mu 0.07, Lambda 4 mm/s on the Fig. 3 top) realises exactly
that law, so the refit must find it, rerun it and reproduce the run's events (explains); the
reference with the paper's law against the same run does not (its events are seconds apart).
The verdict's rules (tolerances, the final tilt held only before the stem) are tested on
hand-made events.
"""

from __future__ import annotations

import math

import pytest

from tippetop.compare.measures.friction_realised import friction_realised
from tippetop.compare.running.engines import run_engine
from tippetop.compare.studies.refit import (
    T_TOL_S,
    THETA_TOL_RAD,
    events,
    refit_overrides,
    refit_result,
)
from tippetop.models.scene import load_scene

FR = {"mu_fit": 0.09, "Lambda_fit_mps": 0.008}


def _ev(t_invert: float | None, t_stem: float | None = None,
        theta: float | None = 3.1) -> dict[str, float | None]:
    return {"t_invert": t_invert, "t_stem": t_stem, "theta_asymp": theta}


def test_events_within_the_nightly_tolerances_are_explained() -> None:
    # the nightly's t_invert tolerance is 0.1 s and theta_asymp's 0.02 rad
    assert T_TOL_S == pytest.approx(0.1) and THETA_TOL_RAD == pytest.approx(0.02)
    r = refit_result(FR, _ev(2.00), _ev(1.0), _ev(2.09, theta=3.115), {})
    assert r["explains"] is True and r["explained_fraction"] == pytest.approx(0.91)
    r = refit_result(FR, _ev(2.00), _ev(1.0), _ev(2.11), {})
    assert r["explains"] is False and "t_invert" in r["sentence"]


def test_after_the_stem_the_final_tilt_is_not_the_balls_law() -> None:
    # the law is fitted while the ball alone touches: once the stem touches, the final tilt is
    # the stem contact's, so it is reported but not held
    r = refit_result(FR, _ev(1.0, 1.2, 2.0), _ev(0.9, 1.1, 2.1), _ev(1.02, 1.25, 2.3), {})
    assert r["explains"] is True and r["held"] == ["t_invert", "t_stem"]
    assert r["differences"]["theta_asymp"] == pytest.approx(0.3)
    r = refit_result(FR, _ev(None, None, 0.1), _ev(None), _ev(None, None, 0.15), {})
    assert r["explains"] is False and "theta_asymp" in r["held"]


def test_one_event_on_one_side_only_does_not_explain() -> None:
    r = refit_result(FR, _ev(2.0), _ev(1.0), _ev(None), {"max_penetration_m": 2e-5,
                                                         "J_rel_drift": 3e-4,
                                                         "integrator": "Euler",
                                                         "timestep_s": 5e-4})
    assert r["explains"] is False
    # what remains is named with numbers
    remains = "; ".join(r["remains"])
    assert "0.02 mm" in remains and "Jellett's drift (3e-4 relative)" in remains
    assert "Euler at dt = 5e-4 s" in remains and len(r["sentence"]) < 300


def test_the_sentence_has_four_digits_and_a_unit_after_every_number() -> None:
    """Four significant digits as the terminal prints them, and what each number is in: the
    sentence said "turns over at 2.45 s", "Lambda 8.12 mm/s" and "Jellett's drift (1.4e-06:"."""
    fr = {"mu_fit": 0.0944612, "Lambda_fit_mps": 0.00812345}
    ran = {"max_penetration_m": 2.74412e-7, "J_rel_drift": 1.4321e-6, "integrator": "RK4",
           "timestep_s": 2e-4}
    r = refit_result(fr, _ev(2.39612), _ev(1.32912), _ev(2.71234), ran)
    s = r["sentence"]
    assert s.startswith("the reference with the realised law (mu 0.09446, Lambda 8.123 mm/s) "
                        "turns over at 2.712 s, the engine turns over at 2.396 s: the law does "
                        "not explain it"), s
    assert "it accounts for 70.36 % of the engine's 1.067 s from the reference's" in s, s
    assert len(s) < 300  # a sentence a person reads on one or two lines, not a paragraph
    assert r["remains"] == ["the contact's sink (up to 2.744e-4 mm)",
                            "Jellett's drift (1.4e-6 relative)",
                            "the integration (RK4 at dt = 2e-4 s)"]
    # explained: the same numbers, the same digits
    r = refit_result(fr, _ev(2.39612), _ev(2.32912), _ev(2.40123), {})
    assert r["sentence"] == ("the reference with the realised law (mu 0.09446, Lambda 8.123 "
                             "mm/s) turns over at 2.401 s, the engine turns over at 2.396 s: "
                             "the friction law explains the run (the reference with the "
                             "scene's law turns over at 2.329 s)")


def test_no_fit_no_refit() -> None:
    assert refit_overrides({"mu_fit": None, "Lambda_fit_mps": None}) is None
    assert refit_overrides({"mu_fit": 0.1, "Lambda_fit_mps": 0.0}) is None


@pytest.mark.parametrize("t_end", [4.0])
def test_the_refit_reproduces_a_run_whose_law_it_found(t_end: float) -> None:
    base = [f"run.t_end_s={t_end}"]
    # the "engine": the reference itself with another law, which it realises exactly
    other = ["friction.mu=0.07", "friction.Lambda_mps=0.004"]
    scene = load_scene("fig3", base + other)
    engine = run_engine(scene, "ode", progress=False)
    fr = friction_realised(engine.table, 0.1, 0.01, t_stem=engine.summary.get("t_stem"))
    # the fit finds the run's law, not the scene's (to the fit's 1e-6)
    assert fr["mu_fit"] == pytest.approx(0.07, rel=1e-6)
    assert fr["Lambda_fit_mps"] == pytest.approx(0.004, rel=1e-6)
    ref = run_engine(load_scene("fig3", base), "ode", progress=False)
    ov = list(refit_overrides(fr) or ())
    refit = run_engine(load_scene("fig3", base + ov), "ode", progress=False)
    e, r_ev = events(engine.summary, engine.table), events(ref.summary, ref.table)
    res = refit_result(fr, e, r_ev, events(refit.summary, refit.table), engine.summary)
    # the paper's law turns this top over seconds earlier than mu 0.07 does ...
    assert e["t_invert"] is not None and r_ev["t_invert"] is not None
    assert abs(e["t_invert"] - r_ev["t_invert"]) > 0.5
    # ... and the refit, rerunning the law it found, reproduces the run's inversion
    assert res["explains"] is True
    assert abs(res["differences"]["t_invert"]) < 1e-3
    assert res["explained_fraction"] == pytest.approx(1.0, abs=1e-3)
    # and the scene's own law, as a refit, does not explain it
    other_res = refit_result(fr, e, r_ev, r_ev, engine.summary)
    assert other_res["explains"] is False
    assert math.isclose(other_res["explained_fraction"], 0.0, abs_tol=1e-12)


def test_compare_gives_each_mujoco_mode_its_refit() -> None:
    from tippetop.compare.studies.crossval import compare_scene

    res = compare_scene("fig3", [("mujoco", "native", ())], ("run.t_end_s=8.0",), workers=1)
    native = next(s for s in res.runs if s["run"] == "mujoco/native")
    refit = native["friction_realised"]["refit"]
    assert {"t_invert", "t_stem", "theta_asymp", "explains", "sentence"} <= set(refit)
    # the calibrated native law on Fig. 3 over 8 s (mu 0.0945, Lambda 10.2 mm/s, measured) is
    # near the paper's: the refit reference turns over within the nightly's 0.1 s of the run
    # (0.055 s) and settles within its 0.02 rad (3e-4); over 3 s the top is still rising and
    # the mean tilt of the last 10 % is not yet a final state
    assert refit["explains"] is True
    assert abs(refit["t_invert"] - native["t_invert"]) <= 0.1
