"""A verdict does not move when only the sampling moves: MuJoCo's contact measured at every step.

A MuJoCo run is recorded at samples, but every step's forward pass is added to its sample's
window (mujoco_runner/worker/windows.py): whether and where the top touched, the ball's
largest gap, the deepest penetration, the contact's impulses, the stem's first touch and the
turn-over, each located to the step. So a run's checks give the same answers at any sample
spacing, and their values agree within their tolerances:

- the events (t_invert, t_stem, t_left_table) and the stretches without contact are located to
  the step, and the steps are the same bit for bit at any spacing: they are equal;
- theta_asymp is a mean over the run's last 10 % of samples: within its regression tolerance
  (0.02 rad, metrics.py) of the every-step value;
- Jellett's drift is a maximum over the samples before the stem or the first flight: a sparser
  sampling can only miss a peak, never add one, and J moves smoothly while the ball alone
  touches: within 10 % of the every-step value (or both below the 1e-3 agreement by far);
- the friction law realised (mu and Lambda of the fit): fitted to each window's mean force
  against the sample's slip, each sample weighted by its normal force (so a window weighs as
  its steps); within 2 % (mu) and 10 % (Lambda) of the every-step fit, the scatter of a fit
  on 8,000 against 40,000 points of the same run, where the run slips on the law's plateau;
  where it barely does (the creeping mu = 1 tops) or its Lambda is too sharp for any slip
  the run reaches, the two laws are compared at the slips the run reaches.

The property runs over the quick profile's native cases and the fidelity map's small grid with
each point's own tuned settings (slow); the fast tests hold the point that today's map reported
as "leaves the table" to what MuJoCo does at every step, and a real flight (a ball thrown up)
to its closed form.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tippetop.compare.measures.friction_realised import law_mu
from tippetop.compare.measures.series import FLIGHT_RISE_M, HOP_MIN_S, flights
from tippetop.compare.studies.crossval import compare_scene
from tippetop.compare.studies.fidelity import point_overrides

ROOT = Path(__file__).resolve().parents[2]
#: The stored default fidelity map: each point's tuned settings (the small grid is its subset).
MAP = ROOT / "docs" / "data" / "fidelity-default.json"
SMALL = {(0.8, 0.1), (0.8, 0.25), (1.3, 0.1), (1.3, 0.25)}
#: The tuned settings of A/C 1.0, a/R 0.25, mu 0.1 in the fidelity map of 2026-11-27 (its
#: results.json, commit c679843), from whose 1-ms samples the ball was said to leave the table.
SETTINGS_ISSUE_41 = {"mu": 0.101, "cone": "elliptic", "impratio": 0.0591, "solref": [0.0004, 1.0],
                     "solimp": [0.173, 0.95, 0.001, 0.5, 2.0], "timestep_s": 0.0002,
                     "integrator": "RK4"}
N0_ISSUE_41 = 105.24614282102553
#: What each spacing's row must match exactly (located to the step, or a class).
EXACT = ("outcome", "t_invert", "t_stem", "t_left_table")


def _tuned(settings: dict[str, Any]) -> tuple[str, ...]:
    """``--set`` strings of a fidelity point's tuned settings (MuJoCo's native contact)."""
    s = settings
    return ("mujoco.friction=native", f"mujoco.cone={s['cone']}",
            f"mujoco.impratio={s['impratio']!r}", f"mujoco.mu={s['mu']!r}",
            f"mujoco.solref={json.dumps(s['solref'])}", f"mujoco.solimp={json.dumps(s['solimp'])}",
            f"mujoco.timestep_s={s['timestep_s']!r}", f"mujoco.integrator={s['integrator']}")


def _point(A_over_C: float, a_over_R: float, mu: float) -> dict[str, Any]:
    points = json.loads(MAP.read_text(encoding="utf-8"))["points"]
    return next(p for p in points if (p["A_over_C"], p["a_over_R"], p["mu"])
                == (A_over_C, a_over_R, mu))


def _rows(scene: str | None, mode: str | None, overrides: tuple[str, ...], dt: float,
          extra: tuple[str, ...] = ()) -> dict[float, dict[str, Any]]:
    """The MuJoCo run's verdict row and summary at each spacing: dt, 5 dt, 1 ms and 3 ms."""
    out = {}
    for spacing in sorted({dt, 5 * dt, 1e-3, 3e-3}):
        res = compare_scene(scene, [("mujoco", mode, (*extra, f"run.sample_dt_s={spacing!r}"))],
                            overrides, use_cache=False, workers=1)
        row = res.crossval[-1]
        summary = next(r for r in res.runs if not r.get("reference"))
        out[spacing] = {"row": row, "summary": summary}
    return out


def _assert_same_verdict(rows: dict[float, dict[str, Any]]) -> None:
    spacings = sorted(rows)
    every = rows[spacings[0]]
    checks = {c["check"]: c["passed"] for c in every["row"]["checks"]}
    for spacing in spacings[1:]:
        other = rows[spacing]
        where = f"at {spacing:g} s samples against every step"
        assert {c["check"]: c["passed"] for c in other["row"]["checks"]} == checks, where
        assert other["row"]["agrees"] == every["row"]["agrees"], where
        for key in EXACT:
            a = every["row"].get(key) if key != "outcome" else every["row"]["outcome"]
            b = other["row"].get(key) if key != "outcome" else other["row"]["outcome"]
            assert a == b, (key, where)
        a_fl, b_fl = every["summary"].get("flights"), other["summary"].get("flights")
        assert (a_fl is None) == (b_fl is None), where
        if a_fl is not None:
            assert (a_fl["hops"], a_fl["t_first_hop"]) == (b_fl["hops"], b_fl["t_first_hop"])
            # every stretch that spans a window's edge is found exactly; within a window its
            # longest: the longest of all is the same
            assert a_fl["longest_s"] == pytest.approx(b_fl["longest_s"], abs=1e-12), where
        assert abs(other["row"]["theta_asymp"] - every["row"]["theta_asymp"]) <= 0.02, where
        ja, jb = every["row"]["J_rel_drift"], other["row"]["J_rel_drift"]
        if ja is not None and jb is not None and max(ja, jb) > 1e-4:
            assert jb <= ja * (1 + 1e-9) and jb >= 0.9 * ja, (ja, jb, where)
        fa, fb = every["summary"].get("friction_realised"), other["summary"].get(
            "friction_realised")
        if fa and fb and fa.get("mu_fit") is not None and fb.get("mu_fit") is not None:
            _assert_same_law(fa, fb, where)


def _assert_same_law(fa: dict[str, Any], fb: dict[str, Any], where: str) -> None:
    """Two fits of the law realised agree where the run measures them.

    mu itself within 2 % where the run slips on the law's plateau (a share of its normal force
    of 1 % or more at 3 Lambda and beyond, in both): the scatter of a fit on 8,000 against
    40,000 windows of one run. Where it barely does - the mu = 1 tops creep: at the map's
    A/C 0.8, a/R 0.25, mu 1.0 99.9 % of the force is at slips under 3 mm/s, and 17 of 40,000
    steps (2 of 2,666 3-ms windows) on the plateau - only mu / Lambda is measured, and mu and
    Lambda alone move together (mu 0.643 from every step, 0.625 from 3-ms samples, the laws
    then 0.2 % apart at 1 mm/s). Then the two laws are compared at the slips the run reaches:
    1 mm/s, about the slowest slipping samples' slip, and the every-step fit's knee, where it
    gives half of mu N (Lambda / sqrt(3)), each within 2 % of mu.
    """
    la, lb = fa["Lambda_fit_mps"], fb["Lambda_fit_mps"]
    # a Lambda under 5 % of the law's (0.5 mm/s against 10 mm/s) is a law as sharp as
    # Coulomb's at every slip the run reaches: the mu = 1 tops' fits end anywhere from 1e-8
    # to 1.3e-4 m/s, which no sample tells apart; such a law has no knee the run measures
    sharp = max(la, lb) <= 0.05 * fa["Lambda_law_mps"]
    if min(fa["plateau_share"], fb["plateau_share"]) >= 0.01:
        assert fb["mu_fit"] == pytest.approx(fa["mu_fit"], rel=0.02), where
        if not sharp:
            assert lb == pytest.approx(la, rel=0.1), where
            return
    for v in (1e-3,) if sharp else (1e-3, la / math.sqrt(3.0)):
        mu_a = law_mu(np.array([v]), fa["mu_fit"], la)[0]
        mu_b = law_mu(np.array([v]), fb["mu_fit"], lb)[0]
        assert abs(mu_b - mu_a) <= 0.02 * fa["mu_fit"], (v, where)


# ------------------------------------------------------------------------- fast
def test_the_point_reported_as_leaving_the_table_stays_on_it() -> None:
    # The fidelity map of 2026-11-27 said the ball leaves the table at 1.385 s at A/C 1.0,
    # a/R 0.25, mu 0.1 with its tuned settings, from samples every 1 ms: the contact was off
    # at the sampled steps of a 10-ms stretch. Stepped by hand, the ball's centre stays
    # within a micrometre of its resting height and no stretch without contact lasts over
    # 3.2 ms. At 1-ms samples the harness now says what every step says.
    # The settings are that map's, written out: the stored map is measured again as the
    # tuning changes, and this point's settings with it.
    over = (*point_overrides(1.0, 0.25, 0.1, N0_ISSUE_41, 0.1), "run.t_end_s=8.0")
    runs = []
    for spacing in (1e-3, 2e-4):
        res = compare_scene(None, [("mujoco", None, (*_tuned(SETTINGS_ISSUE_41),
                                                      f"run.sample_dt_s={spacing!r}"))],
                            over, use_cache=False, workers=1)
        runs.append(next(r for r in res.runs if not r.get("reference")))
    sampled, every = runs
    for s in runs:
        assert s["t_left_table"] is None
        assert s["flights"]["hops"] == 0
        assert s["flights"]["longest_s"] < 0.005
        assert s["flights"]["height_m"] < 0.1 * FLIGHT_RISE_M
    assert sampled["flights"]["longest_s"] == pytest.approx(every["flights"]["longest_s"])
    assert sampled["flights"]["height_m"] == pytest.approx(every["flights"]["height_m"])
    assert sampled["t_invert"] == every["t_invert"]


def test_a_ball_thrown_up_is_a_flight_with_its_height() -> None:
    # The paper's top spun upright and thrown up at v0 = 0.2 m/s from touching the table, in
    # MuJoCo's native contact: in the air its centre of mass rises v0^2 / (2 g) = 2.04 mm and
    # comes back after 2 v0 / g = 40.8 ms (the ball's centre with it: upright, the axis
    # keeps k_z = 1 to 1e-6). The flight is found at every spacing, with that length to a
    # step or two (the soft contact lets go and takes hold within a step or two of the
    # ball's touching height) and that height within 2 % (the contact's resting
    # penetration, 4e-5 m, is where the gap is counted from).
    from dataclasses import replace

    from tests.conftest import mujoco_plan
    from tippetop.mujoco_runner.run import simulate_plan

    v0, g = 0.2, 9.8
    found = []
    for spacing in (2e-4, 1e-3, 3e-3):
        plan = mujoco_plan("mujoco.friction=native", "init.theta0=0.0", "run.t_end_s=0.1",
                           f"run.sample_dt_s={spacing!r}")
        qvel = list(plan.start_qvel)
        qvel[2] = v0
        res = simulate_plan(replace(plan, start_qvel=tuple(qvel)))
        assert res.ok, res.message
        fl = flights(res.table["t"].to_numpy(), res.gaps(), None, settling_s=0.0)
        assert fl is not None and fl["hops"] == 1
        assert fl["longest_hop_s"] == pytest.approx(2 * v0 / g, abs=3 * res.dt_s)
        assert fl["hop_height_m"] == pytest.approx(v0**2 / (2 * g), rel=0.02)
        assert fl["longest_hop_s"] >= HOP_MIN_S and fl["hop_height_m"] >= FLIGHT_RISE_M
        found.append((fl["t_first_hop"], fl["longest_hop_s"], fl["hop_height_m"]))
    assert found[1] == found[0] and found[2] == found[0]  # the same steps at any spacing


# ------------------------------------------------------------------------- slow: the property
QUICK_NATIVE = [("fig3", "native", ()), ("fig3", "native-condim4", ()),
                ("fig3", "native-condim6", ()), ("fig3", "native-pyramidal", ())]


@pytest.mark.slow
@pytest.mark.parametrize(("scene", "mode", "extra"), QUICK_NATIVE,
                         ids=[f"{s}-{m}" for s, m, _ in QUICK_NATIVE])
def test_quick_profile_native_verdicts_do_not_depend_on_the_sampling(
        scene: str, mode: str, extra: tuple[str, ...]) -> None:
    _assert_same_verdict(_rows(scene, mode, (), 2e-4, extra))


SMALL_POINTS = sorted((r, e, m) for r, e in SMALL for m in (0.1, 1.0))


@pytest.mark.slow
@pytest.mark.parametrize(("A_over_C", "a_over_R", "mu"), SMALL_POINTS,
                         ids=[f"A{r}-e{e}-mu{m}" for r, e, m in SMALL_POINTS])
def test_fidelity_small_grid_verdicts_do_not_depend_on_the_sampling(
        A_over_C: float, a_over_R: float, mu: float) -> None:
    p = _point(A_over_C, a_over_R, mu)
    over = (*point_overrides(A_over_C, a_over_R, mu, p["n0"], p["theta0"]), "run.t_end_s=8.0")
    rows = _rows(None, None, over, float(p["settings"]["timestep_s"]), _tuned(p["settings"]))
    _assert_same_verdict(rows)
    assert not math.isnan(rows[min(rows)]["row"]["theta_asymp"])
