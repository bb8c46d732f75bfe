"""The contact search (issue 41, item 4): MuJoCo's whole contact space at one point.

Fast: the draw stays within MuJoCo's bounds and covers every choice; the scoring, the ranking
and the attribution on made-up verdicts; stage 2's cell rule on made-up stage-1 rows, its
dense and local draws inside the bounds and the kept cells, the budget, the statement
(``limit``) both ways; bad input is one line; one tiny real two-stage search (0.5-s runs, no
cache, the fit included) runs end to end.
"""

from __future__ import annotations

import importlib.util
import json
import math
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from tippetop.compare.running.io import json_ready
from tippetop.compare.running.runner import Task
from tippetop.compare.studies import contact_search as cs
from tippetop.compare.studies import contact_search_refine as rf
from tippetop.compare.studies.fidelity import point_overrides
from tippetop.models.errors import TippetopError

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "contact_search.py"


def _script() -> Any:
    spec = importlib.util.spec_from_file_location("contact_search_script", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _inside_bounds(c: cs.ContactCandidate, mu: float) -> None:
    """Every setting of ``c`` within MuJoCo's bounds and the search's ranges."""
    assert c.cone in cs.CONES and c.condim in cs.CONDIMS
    assert c.integrator in cs.INTEGRATORS and c.timestep_s in cs.TIMESTEPS_S
    assert c.noslip_iterations in cs.NOSLIP_ITERATIONS
    assert cs.IMPRATIO[0] <= c.impratio <= cs.IMPRATIO[1]
    assert mu / cs.MU_FACTOR <= c.mu <= mu * cs.MU_FACTOR
    a, b = c.solref
    if a > 0:  # time constant: MuJoCo clamps below 2 dt
        assert 2 * c.timestep_s <= a <= cs.TIMECONST_MAX_S
        assert cs.DAMPRATIO[0] <= b <= cs.DAMPRATIO[1]
    else:  # direct: -stiffness, -damping
        assert b < 0 and cs.DIRECT_STIFFNESS[0] <= -a <= cs.DIRECT_STIFFNESS[1]
        z = -b / (2 * math.sqrt(-a))
        assert cs.DAMPRATIO[0] * 0.999 <= z <= cs.DAMPRATIO[1] * 1.001
    d0, dmax, width, mid, power = c.solimp
    assert cs.IMP_MIN <= d0 <= cs.D0[1] and d0 <= dmax <= cs.IMP_MAX
    assert cs.WIDTH_M[0] <= width <= cs.WIDTH_M[1]
    assert 0 < mid < 1 and power >= 1
    if c.solreffriction is not None:  # MuJoCo takes it on an elliptic pair only
        assert c.cone == "elliptic" and c.solreffriction[0] == -1.0
        assert cs.FRICTION_DAMPING[0] <= -c.solreffriction[1] <= cs.FRICTION_DAMPING[1]


# ---------------------------------------------------------------- the draw
def test_the_draw_stays_inside_mujocos_bounds_and_covers_every_choice() -> None:
    mu = 0.3
    drawn = cs.draw_candidates(64, mu, seed=0)
    assert len(drawn) == 64
    for c in drawn:
        assert c.origin == "drawn"
        _inside_bounds(c, mu)
    for name, choices in (("cone", cs.CONES), ("condim", cs.CONDIMS),
                          ("integrator", cs.INTEGRATORS), ("timestep_s", cs.TIMESTEPS_S),
                          ("noslip_iterations", cs.NOSLIP_ITERATIONS)):
        assert {getattr(c, name) for c in drawn} == set(choices), name
    assert any(c.solref[0] < 0 for c in drawn) and any(c.solref[0] > 0 for c in drawn)
    assert any(c.solimp[0] == c.solimp[1] for c in drawn)
    assert any(c.solreffriction is not None for c in drawn)
    assert all(c.solreffriction is None for c in drawn if c.cone == "pyramidal")
    # seeded: the same draw again, another with another seed
    assert cs.draw_candidates(64, mu, seed=0) == drawn
    assert cs.draw_candidates(64, mu, seed=1) != drawn


def test_every_candidate_is_a_plan_the_harness_runs() -> None:
    """Each candidate's --set strings load and plan (a pair written where solreffriction)."""
    base = point_overrides(1.0, 0.1, 0.3, 100.0, 0.1)
    for c in cs.draw_candidates(16, 0.3, seed=3):
        plan = Task(None, (*base, "run.t_end_s=0.5", *c.overrides()), "mujoco").plan()
        mj = plan.mujoco
        assert mj is not None and mj.cone == c.cone and mj.integrator == c.integrator
        assert mj.noslip_iterations == c.noslip_iterations
        assert ("<pair" in mj.mjcf) == (c.solreffriction is not None)


def test_baselines_are_the_tuned_and_the_calibrated_settings() -> None:
    tuned = cs.candidate_from_settings(
        {"mu": 0.101, "cone": "elliptic", "impratio": 0.0591, "solref": [0.0004, 1.0],
         "solimp": [0.173, 0.95, 0.001], "timestep_s": 0.0002, "integrator": "RK4",
         "condim": 3}, "tuned")
    assert tuned.solimp == (0.173, 0.95, 0.001, 0.5, 2.0) and tuned.origin == "tuned"
    cal = cs.calibrated_candidate(0.3)
    assert cal is not None and cal.origin == "calibrated"
    assert cal.mu == pytest.approx(3 * cs.calibrated_native_settings()["mu"])
    with pytest.raises(TippetopError, match="tuned settings"):
        cs.candidate_from_settings({"cone": "elliptic"}, "tuned")
    assert cs.tuned_settings_from({"points": [{"A_over_C": 1.0, "a_over_R": 0.25, "mu": 0.1,
                                               "settings": {"mu": 0.1}}]},
                                  1.0, 0.25, 0.1) == {"mu": 0.1}


def test_neighbours_change_one_choice_at_a_time() -> None:
    cal = cs.calibrated_candidate(0.3)
    assert cal is not None and cal.cone == "pyramidal"
    near = cs.neighbours(cal)
    fields = ("cone", "condim", "integrator", "timestep_s", "noslip_iterations")
    assert len(near) == sum(len(ch) - 1 for ch in (cs.CONES, cs.CONDIMS, cs.INTEGRATORS,
                                                    cs.TIMESTEPS_S, cs.NOSLIP_ITERATIONS))
    for n in near:
        assert n.origin == "neighbour"
        assert sum(getattr(n, f) != getattr(cal, f) for f in fields) == 1
        assert (n.impratio, n.solref, n.solimp, n.mu) == (cal.impratio, cal.solref,
                                                           cal.solimp, cal.mu)
    ell = next(n for n in near if n.cone == "elliptic")
    back = cs.neighbours(ell)
    assert any(n.solreffriction == (-1.0, -2.6) for n in back)  # the pairs, in elliptic only
    assert all(n.solreffriction is None for n in back if n.cone == "pyramidal")


# ---------------------------------------------------------------- scoring on fake verdicts
def _c(name: str, passed: bool | None, value: Any = None) -> dict[str, Any]:
    return {"check": name, "passed": passed, "value": value, "note": f"{name} note"}


def _start(role: str, checks: list[dict[str, Any]] | None, n0: float = 100.0,
           rms: float | None = 0.01) -> dict[str, Any]:
    if checks is None:  # the reference stops: not verifiable
        return {"n0": n0, "theta0": 0.1, "role": role, "passed": None, "checks": [],
                "theta_rms_rad": None}
    return {"n0": n0, "theta0": 0.1, "role": role, "checks": checks, "theta_rms_rad": rms,
            "passed": all(c["passed"] is not False for c in checks)}


GOOD = [_c("outcome", True), _c("t_invert", True, 0.01), _c("stays_on_table", True),
        _c("jellett_before_stem", True, 1e-5), _c("energy_never_rises", True, 0.0)]


def _bad(name: str, value: Any = 1.0) -> list[dict[str, Any]]:
    return [c if c["check"] != name else _c(name, False, value) for c in GOOD]


def test_scoring_follows_the_tunings_rule() -> None:
    ok = cs.score([_start("fit", GOOD), _start("held-out", GOOD, 115.0)])
    assert ok["agrees"] and ok["passes"] == ok["checks"] == 10 and ok["cause"] is None
    assert ok["first_departing"] is None and all(ok["by_check"].values())
    assert ok["by_check"]["completed"] is True  # a run that completed passes it
    # the first departing check in the fidelity map's order, the fit's start first
    two = cs.score([_start("fit", _bad("t_invert", 0.3)),
                    _start("held-out", _bad("stays_on_table", 1.18), 115.0)])
    assert not two["agrees"] and two["passes"] == 8 and two["departures"] == 2
    assert two["first_departing"]["check"] == "stays_on_table"
    assert two["first_departing"]["role"] == "held-out"
    assert "leaves the table at 1.18 s" in two["cause"] and "1 more" in two["cause"]
    assert two["by_check"]["stays_on_table"] is False and two["by_check"]["outcome"] is True
    # a run that diverged is judged by completed alone from its start
    dead = cs.score([_start("fit", [_c("completed", False, "diverged")], rms=None),
                     _start("held-out", _bad("outcome"), 115.0)])
    assert not dead["agrees"] and dead["first_departing"]["check"] == "completed"
    assert dead["by_check"]["completed"] is False and dead["by_check"]["outcome"] is False
    assert dead["by_check"]["stays_on_table"] is True and "t_stem" not in dead["by_check"]
    assert dead["theta_rms_rad"] is None
    # only the fit's start verifiable: no held-out start checked, so it does not agree
    alone = cs.score([_start("fit", GOOD), _start("held-out", None, 115.0)])
    assert not alone["agrees"] and alone["departures"] == 0


def test_ranking_is_agreement_then_passes_then_departures_then_theta() -> None:
    rows = [{"name": "a", "agrees": False, "passes": 9, "departures": 1, "theta_rms_rad": 0.2},
            {"name": "b", "agrees": False, "passes": 9, "departures": 1, "theta_rms_rad": 0.1},
            {"name": "c", "agrees": False, "passes": 9, "departures": 2, "theta_rms_rad": 0.0},
            {"name": "d", "agrees": True, "passes": 8, "departures": 0, "theta_rms_rad": 0.5},
            {"name": "e", "agrees": False, "passes": 10, "departures": 0,
             "theta_rms_rad": None}]
    assert [r["name"] for r in sorted(rows, key=cs.rank_key)] == ["d", "e", "b", "a", "c"]


def test_attribution_says_which_part_of_the_space_fails_where() -> None:
    drawn = cs.draw_candidates(8, 0.3, seed=0)
    rows = []
    for c in drawn:  # made up: the pyramidal cone leaves the table, the elliptic one agrees
        start = GOOD if c.cone == "elliptic" else _bad("stays_on_table", 0.5)
        rows.append({"settings": c.to_json(), "label": c.label(),
                     **cs.score([_start("fit", start), _start("held-out", start, 115.0)])})
    rows.append({**rows[0], "settings": {**rows[0]["settings"], "origin": "tuned"}})
    att = cs.attribution(rows, 0.3)
    cone = att["cone"]
    n_ell = sum(c.cone == "elliptic" for c in drawn)
    assert cone["elliptic"]["n"] == cone["elliptic"]["agree"] == n_ell  # the baseline not
    assert cone["pyramidal"]["agree"] == 0
    assert cone["pyramidal"]["checks"]["stays_on_table"] == 0.0
    assert cone["pyramidal"]["worst"] == "stays_on_table"
    assert cone["elliptic"]["checks"]["stays_on_table"] == 1.0
    assert set(att) >= {"cone", "condim", "integrator", "timestep_s", "noslip_iterations",
                        "solref_form", "solreffriction", "impedance", "impratio", "d0", "mu"}
    assert list(att["impratio"])[0].startswith("low")
    lines = _script().attribution_lines({"attribution": att})
    assert lines[0].split()[:3] == ["dimension", "value", "agree"] and "table" in lines[0]
    row = lines[1].split()
    assert row[:2] == ["cone", "pyramidal"] and row[2].startswith("0/")
    assert row[3 + lines[0].split()[3:].index("table")] == "0%"


# ---------------------------------------------------------------- bad input, one line
@pytest.mark.parametrize("argv, says", [
    (["--point", "1,0.1"], "--point"),
    (["--point", "1,1.5,0.3"], "a/R"),
    (["--point", "1,0.1,0.3", "--candidates", "-1"], "--candidates"),
    (["--point", "1,0.1,0.3", "--t-end-s", "0"], "--t-end-s"),
    (["--point", "1,0.1,0.3", "--tuned", "/no/such/file.json"], "--tuned"),
    (["--point", "1,0.1,0.3", "--out", "/no/such/folder/x.json"], "--out"),
    (["--point", "1,0.1,0.3", "--bogus"], "unrecognized"),
    (["--point", "1,0.1,0.3", "--budget-runs", "3"], "--budget-runs"),
    (["--point", "1,0.1,0.3", "--stages", "3"], "--stages"),
])
def test_bad_input_is_one_line(argv: list[str], says: str,
                               capsys: pytest.CaptureFixture[str]) -> None:
    assert _script().main(argv) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and says in err
    assert err.startswith("contact_search: ")


def test_the_script_says_bad_input_in_one_line_and_exits_2() -> None:
    proc = subprocess.run([sys.executable, str(SCRIPT), "--point", "x"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "--point" in proc.stderr


def test_ctrl_c_is_one_line_and_exit_130(tmp_path: Path) -> None:
    out = tmp_path / "search.json"
    proc = subprocess.Popen([sys.executable, str(SCRIPT), "--point", "1,0.1,0.3",
                             "--candidates", "4", "--no-cache", "--tuned", "none",
                             "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    time.sleep(3.0)  # in its runs by now
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130 and stdout == ""
    assert stderr.splitlines()[-1] == "contact_search: interrupted" and not out.exists()


# ---------------------------------------------------------------- stage 2: the cell rule
MISSING = {"check": "t_invert", "passed": False, "value": None,
           "note": "turns over (theta = pi/2): the reference only"}
OUT = _bad("outcome")  # every candidate's: the reference itself ends inconclusive
J_OUT = [c for c in OUT if c["check"] != "jellett_before_stem"] + [
    _c("jellett_before_stem", False, 0.5)]
NO_TURN = [*OUT, MISSING]
DIVERGED = [_c("completed", False, "diverged")]


def _row(checks: list[dict[str, Any]], origin: str = "drawn", **cell: Any) -> dict[str, Any]:
    """A made-up stage-1 row in ``cell`` departing with ``checks`` from both its starts."""
    c = cs.ContactCandidate(**{"cone": "pyramidal", "impratio": 1.0, "solref": (0.01, 1.0),
                               "solimp": (0.1, 0.95, 0.001, 0.5, 2.0), "mu": 0.3, **cell},
                            origin=origin)
    rms = None if checks is DIVERGED else 0.01
    verified = [_start("fit", checks, rms=rms), _start("held-out", checks, 115.0, rms=rms)]
    return {"settings": c.to_json(), "label": c.label(), **cs.score(verified),
            "verified": verified}


def _stage_one() -> list[dict[str, Any]]:
    integ = ("RK4", "implicitfast", "implicit")
    rows = [_row(OUT, cone=cs.CONES[k % 2], integrator=integ[k % 3],
                 timestep_s=cs.TIMESTEPS_S[k % 3]) for k in range(6)]  # condim 3, noslip 0
    # condim 4 breaks J; Euler only ever drawn with it (confounded)
    rows += [_row(J_OUT, condim=4, integrator=i)
             for i in ("Euler", "Euler", "Euler", "RK4", "implicit", "implicitfast")]
    rows += [_row(NO_TURN, noslip_iterations=5, timestep_s=dt) for dt in cs.TIMESTEPS_S]
    rows += [_row(NO_TURN, noslip_iterations=5, cone="elliptic"),
             _row(DIVERGED, noslip_iterations=5)]  # a diverged one is no evidence of a turn
    rows += [_row(NO_TURN, noslip_iterations=1) for _ in range(2)]  # too few
    return rows


def test_reasons_tell_a_missing_turn_over_from_a_late_one() -> None:
    late = _row([*OUT, _c("t_invert", False, 0.4)])
    assert rf.reasons(late) == {"outcome", "t_invert"} and rf.ran(late)
    assert rf.reasons(_row(NO_TURN)) == {"outcome", "t_invert: missing"}
    dead = _row(DIVERGED)
    assert rf.reasons(dead) == {"completed"} and not rf.ran(dead)


def test_the_rule_rules_a_choice_out_only_with_the_counts_it_rests_on() -> None:
    rows = _stage_one()
    euler_cell = ("pyramidal", 4, 0, "Euler", 2e-4)
    res = rf.rule_cells(rows, [(euler_cell, "the cell of stage 1's best #1")])
    ch = {(c["dimension"], c["value"]): c for c in res["choices"]}
    # condim 4: J fails in all 6 that ran, in none of the 12 elsewhere; 3 are not Euler
    c4 = ch[("condim", 4)]
    assert c4["ruled_out"] and c4["reason"] == "jellett_before_stem"
    assert c4["counts"] == {"shows": 6, "of": 6, "elsewhere_shows": 0, "elsewhere_of": 12,
                            "clean": 3}
    assert "in all 6 of its candidates that ran, in 0 of 12 elsewhere" in c4["why"]
    # noslip 5: no turn-over in all 4 that ran (the diverged one is not evidence); 2 of 14
    # elsewhere (noslip 1's)
    n5 = ch[("noslip_iterations", 5)]
    assert n5["ruled_out"] and n5["reason"] == "t_invert: missing"
    assert n5["candidates"] == 5 and n5["ran"] == 4
    assert n5["counts"] == {"shows": 4, "of": 4, "elsewhere_shows": 2, "elsewhere_of": 14,
                            "clean": 4}
    assert "does not turn over" in n5["why"]
    # kept: too few (noslip 1), confounded (Euler: every one is condim 4), a reason shared
    # by every candidate (the outcome), none drawn (condim 6)
    assert not ch[("noslip_iterations", 1)]["ruled_out"]
    assert "2 of its 2 candidates ran, too few" in ch[("noslip_iterations", 1)]["why"]
    eu = ch[("integrator", "Euler")]
    assert not eu["ruled_out"] and "only 0 of them have no other choice" in eu["why"]
    n0 = ch[("noslip_iterations", 0)]
    assert not n0["ruled_out"] and "the outcome departs" in n0["why"]
    assert "not tied to it" in n0["why"]
    assert not ch[("condim", 6)]["ruled_out"]
    assert all(c["reason"] != "outcome" for c in res["choices"])
    # the cells: the kept values' product, and the pinned one though its condim is out
    kept = res["kept_values"]
    assert kept["condim"] == [3, 6] and kept["noslip_iterations"] == [0, 1, 20]
    assert len(kept["integrator"]) == 4 and len(kept["cone"]) == 2
    assert res["cells_total"] == 288 and res["cells_kept"] == 2 * 2 * 3 * 4 * 3 + 1
    cells = {rf.cell_of(c): c["why"] for c in res["cells"]}
    assert cells[euler_cell] == "kept as the cell of stage 1's best #1"
    assert all(c[1] != 4 and c[2] != 5 for c in cells if c != euler_cell)
    assert str(rf.MIN_EVIDENCE) in res["rule"] and str(rf.MIN_CLEAN) in res["rule"]


# ---------------------------------------------------------------- stage 2: the draws
def test_unit_coordinates_invert_the_draw() -> None:
    for c in cs.draw_candidates(32, 0.3, seed=5):
        u, cell = cs.unit_of(c, 0.3)
        back = cs.candidate_at(u, cell, 0.3)
        assert (back.cone, back.condim, back.integrator, back.timestep_s,
                back.noslip_iterations) == (c.cone, c.condim, c.integrator, c.timestep_s,
                                            c.noslip_iterations)
        assert (back.solimp[0] == back.solimp[1]) == (c.solimp[0] == c.solimp[1])
        pairs = ((back.impratio, c.impratio), (back.mu, c.mu),
                 *zip(back.solref, c.solref, strict=True), *zip(back.solimp, c.solimp,
                                                                  strict=True))
        for x, y in pairs:
            assert x == pytest.approx(y, rel=2e-3)


def test_the_dense_and_local_draws_stay_inside_the_bounds_and_the_kept_cells() -> None:
    mu = 0.3
    cells = [rf.cell_json(c) for c in (("pyramidal", 3, 0, "RK4", 2e-4),
                                       ("elliptic", 3, 0, "implicitfast", 1e-4),
                                       ("elliptic", 3, 0, "Euler", 5e-5))]
    dense = rf.dense_draw(cells, 24, mu, seed=1)
    assert len(dense) == 24 and {c.origin for c in dense} == {"dense"}
    got = [rf.cell_of(c.to_json()) for c in dense]
    assert sorted(got.count(rf.cell_of(c)) for c in cells) == [8, 8, 8]  # each its share
    for c in dense:
        _inside_bounds(c, mu)
    assert any(c.solreffriction for c in dense) and any(c.solref[0] < 0 for c in dense)
    elites = dense[:2] + [cs.calibrated_candidate(mu)]
    for half in rf.BOX:
        local = rf.local_draw(elites, 10, mu, seed=2, half_width=half)
        assert len(local) == 10 and {c.origin for c in local} == {"local"}
        for k, c in enumerate(local):
            e = elites[0] if k < 4 else elites[1] if k < 7 else elites[2]  # 4, 3, 3
            _inside_bounds(c, mu)
            assert rf.cell_of(c.to_json()) == rf.cell_of(e.to_json())
            assert (c.solref[0] < 0, c.solimp[0] == c.solimp[1], c.solreffriction is None) \
                == (e.solref[0] < 0, e.solimp[0] == e.solimp[1], e.solreffriction is None)
            u, _ = cs.unit_of(c, mu)
            u0, _ = cs.unit_of(e, mu)
            assert all(abs(u[d] - u0[d]) <= half + 2e-3 for d in rf.CONTINUOUS)
    assert rf.local_draw(elites, 0, mu, 0, 0.1) == [] and rf.dense_draw([], 5, mu, 0) == []


def test_the_fit_takes_a_candidate_and_gives_it_back() -> None:
    base = cs.calibrated_candidate(0.3)
    assert base is not None
    for c in (base, *cs.draw_candidates(16, 0.3, seed=4)):
        cand, fitted, bounds = rf.fit_candidate(c, 0.3)
        assert rf.from_fit(cand, c) == replace(c, origin="fit")
        assert {"mu", "impratio"} <= set(fitted) == set(bounds.values)
        assert ("timeconst_s" in fitted) == (c.solref[0] > 0)
        assert ("d0" in fitted) == (c.solimp[0] < c.solimp[1])
        assert ("frictiondamping" in fitted) == (c.solreffriction is not None)
        for k in fitted:  # the seed inside its bounds (but for a time constant below 2 dt)
            lo, hi = bounds.values[k]
            assert lo * 0.999 <= getattr(cand, k) <= hi * 1.001, (k, c)


# ---------------------------------------------------------------- stage 2: the budget
class _FakePoint:
    """Stands for :class:`cs.PointRuns`: every candidate departs on the outcome, 4 runs each."""

    def __init__(self) -> None:
        self.point = {"A_over_C": 1.0, "a_over_R": 0.1, "mu": 0.3, "group": "II",
                      "n0": 100.0, "theta0": 0.1}
        self.runs = self.cached = 0
        self.options: dict[str, Any] = {}

    def verify(self, cands: list[cs.ContactCandidate], first_index: int = 0, batch: int = 16,
               say: Any = None, label: str = "") -> list[dict[str, Any]]:
        self.runs += 4 * len(cands)
        out = []
        for c in cands:
            checks = (J_OUT if c.condim != 3 else OUT) + ([MISSING] if c.noslip_iterations
                                                            else [])
            verified = [_start("fit", checks), _start("held-out", checks, 115.0)]
            out.append({"settings": c.to_json(), "label": c.label(), **cs.score(verified),
                        "verified": verified})
        return out


@pytest.mark.parametrize("budget", [4, 16, 41, 400, rf.DEFAULT_BUDGET_RUNS])
def test_the_budget_caps_every_run_of_the_search(budget: int,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    fits: list[int] = []
    seen: list[dict[str, Any]] = []

    def fake_fit(pr: Any, seed: cs.ContactCandidate, rollouts: int, max_iters: int,
                 threads: int) -> tuple[cs.ContactCandidate, dict[str, Any]]:
        fits.append(rollouts)
        return replace(seed, impratio=seed.impratio * 1.01, origin="fit"), {
            "rollouts": rollouts, "to": seed.label()}

    def fake_assemble(pr: Any, rows: list[dict[str, Any]], **_: Any) -> dict[str, Any]:
        best = min(rows, key=cs.rank_key)
        seen.extend(rows)
        return {"candidates_evaluated": len(rows), "agreeing": 0, "runs": {},
                "best": {**best, "departs": [c for v in best["verified"]
                                             for c in v["checks"] if c["passed"] is False]}}

    monkeypatch.setattr(cs, "prepare_point", lambda *a, **k: _FakePoint())
    monkeypatch.setattr(rf, "run_fit", fake_fit)
    monkeypatch.setattr(rf, "assemble", fake_assemble)
    res = rf.search_two_stage(1.0, 0.1, 0.3, tuned=None,
                              options=rf.SearchOptions(budget_runs=budget))
    one, *two = res["stages"]
    assert res["runs"]["mujoco"] == res["runs"]["candidate_runs"] + sum(fits) <= budget
    assert one["runs"] <= max(4, budget // 2)
    if budget >= 400:  # every part: the dense draw, the fits, the local rounds
        parts = [p["part"] for p in two[0]["parts"]]
        assert parts == ["dense", "fit", "local 1", "local 2", "local 3"]
        assert budget - res["runs"]["mujoco"] < 4 * rf.ROUNDS  # the budget used
        assert len(fits) == (3 if budget == rf.DEFAULT_BUDGET_RUNS else 1)
        kept = {rf.cell_of(c) for c in two[0]["cells"]["cells"]}
        assert all(rf.cell_of(r["settings"]) in kept for r in seen if r["stage"] == 2)
    if budget == rf.DEFAULT_BUDGET_RUNS:  # condim 4/6 and noslip >= 1 ruled out by stage 1
        rule = two[0]["cells"]
        assert rule["kept_values"]["condim"] == [3]
        assert rule["kept_values"]["noslip_iterations"] == [0]
        assert one["candidates"] == 1 + 11 + cs.DEFAULT_CANDIDATES
        assert two[0]["candidates"] >= 90
    if budget == 4:
        assert two == [{"stage": 2, "name": "dense",
                        "skipped": "the budget (4 runs) was spent by stage 1"}]
        assert "stage 2: not run" in res["limit"]


def test_the_limit_line_says_what_agrees_or_how_close_the_closest_comes() -> None:
    best = {"label": "pyramidal condim=3 ...", "settings": {"origin": "local"}, "stage": 2,
            "passes": 15, "checks": 20,
            "departs": [{"check": "outcome"}] * 4 + [{"check": "t_invert"}]}
    stages = [{"stage": 1, "candidates": 78, "drawn": 64, "cells": {"of": 288}},
              {"stage": 2, "candidates": 100, "cells": {"cells_kept": 25},
               "parts": [{"part": "dense", "candidates": 50}, {"part": "fit", "candidates": 3},
                         {"part": "local 1", "candidates": 16},
                         {"part": "local 2", "candidates": 16}]}]
    res = {"candidates_evaluated": 178, "agreeing": 0, "best": best, "stages": stages}
    line = rf.limit_line(res)
    assert line.startswith("no candidate of 178 over the whole space (stage 1: 78 candidates, "
                           "64 of them drawn evenly over all 288 cells; stage 2: 100 in the "
                           "25 cells kept (50 dense, 3 fit, 32 local)) agrees; the closest "
                           "passes 15 of 20 checks, departing on outcome (from 4 starts), "
                           "t_invert (from 1 start): pyramidal condim=3 ...")
    ok = rf.limit_line({**res, "agreeing": 2, "best": {**best, "agrees": True}})
    assert ok == "agrees: pyramidal condim=3 ... (stage 2, local; 2 of 178 candidates agree)"


# ---------------------------------------------------------------- one tiny real search
def test_a_tiny_two_stage_search_runs_end_to_end() -> None:
    budget = 64
    options = rf.SearchOptions(candidates=3, seed=0, with_neighbours=False,
                               budget_runs=budget, fit_rollouts=4, fit_iters=2,
                               stop_on_agree=False)
    res = rf.search_two_stage(1.0, 0.1, 0.3, t_end_s=0.5, options=options,
                              run_options={"use_cache": False, "workers": 2})
    assert res["format"] == cs.FORMAT and res["budget_runs"] == budget
    one, two = res["stages"]
    assert one["candidates"] == 4 and one["baselines"] == {"calibrated": 1}
    assert res["runs"]["reference"] == 4 and res["runs"]["cached"] == 0
    assert res["runs"]["mujoco"] == (res["runs"]["candidate_runs"]
                                     + res["runs"]["fit_rollouts"]) <= budget
    assert [p["part"] for p in two["parts"]][:2] == ["dense", "fit"]
    fit = two["parts"][1]["fits"][0]
    assert 1 <= fit["rollouts"] <= 4 and fit["rms_rad"] <= fit["rms_from_rad"]
    kept = {rf.cell_of(c) for c in two["cells"]["cells"]}
    stage2 = [r for r in res["candidates"] if r["stage"] == 2]
    assert len(stage2) == two["candidates"] >= 3
    assert all(rf.cell_of(r["settings"]) in kept for r in stage2)
    assert [s["role"] for s in res["starts"]] == ["fit", "held-out", "held-out", "held-out"]
    assert res["agrees"] == any(r["agrees"] for r in res["candidates"])
    keys = [cs.rank_key(r) for r in res["candidates"]]
    assert keys == sorted(keys) and res["best"] == res["top"][0]
    for r in res["top"]:
        assert r["checks"] >= 4 and 0 <= r["passes"] <= r["checks"]
        assert len(r["departs"]) == r["departures"]
    assert res["limit"].startswith("agrees: " if res["agrees"] else "no candidate of ")
    json.dumps(json_ready(res))  # JSON-ready
    lines = _script().summary(res, "none")
    assert lines[0].startswith("contact search at A/C = 1, a/R = 0.1, mu = 0.3")
    assert any(ln.startswith("stage 2 (dense, ") for ln in lines)
    assert f"limit: {res['limit']}" in lines


def test_theta_rms_is_the_gap_on_the_samples_both_runs_cover() -> None:
    # a run 0.01 rad above the reference at every sample, ending at half the reference's
    # time: the RMS is 0.01 rad over the shared half; a theta that is not finite, or fewer
    # than two shared samples, is no number
    import numpy as np
    import pandas as pd

    from tippetop.compare.studies.contact_search import theta_rms

    t = np.linspace(0.0, 1.0, 101)
    ref = pd.DataFrame({"t": t, "theta": np.sin(t)})
    run = pd.DataFrame({"t": t[:51], "theta": np.sin(t[:51]) + 0.01})
    assert theta_rms(ref, run) == pytest.approx(0.01, rel=1e-9)
    assert theta_rms(ref, run.assign(theta=np.where(t[:51] > 0.3, np.nan, run["theta"]))) is None
    assert theta_rms(ref, run.iloc[:1]) is None and theta_rms(None, run) is None
