"""The tuning of any top's contact settings (issue 22): its starts, horizons and choices.

The fit itself is tested end to end in ``test_validate.py`` (the paper's top: tuned settings
that pass every check from held-out starts) and, slow, on a stranger's file here.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tippetop.compare.results.tune import (
    FittedStart,
    TuneAlternative,
    TunedSettings,
    TuneFit,
    TuneNeed,
    TuneOnlyResult,
    TuneResult,
    TuneSkipped,
    TuneVerification,
    tuned_from_json,
)
from tippetop.compare.tuning.calibrate.identify import Bounds
from tippetop.compare.tuning.tune import (
    FIT_INTEGRATOR,
    HELD_OUT,
    LIFT_FREE,
    MIN_FIT_S,
    _cheaper,
    cone_order,
    fit_horizon,
    fit_order,
    min_budget_runs,
    seeds,
    starts_for,
)
from tippetop.compare.tuning.widen import (
    LOCAL_HALF_DECADES,
    local_candidates,
    widen_neighbours,
    widen_reserve,
)
from tippetop.models.scene import as_override

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "paper_loaded_sphere.xml"


def test_held_out_starts_differ_from_the_fit() -> None:
    starts = starts_for(150.0, 0.04)
    assert starts[0].role == "fit" and starts[0].overrides() == ()  # the file's own start
    held = starts[1:]
    assert len(held) == len(HELD_OUT) and all(s.role == "held-out" for s in held)
    assert {(s.n0, s.theta0) for s in held}.isdisjoint({(150.0, 0.04)})
    # a faster and a slower spin, a larger tilt (at least 0.05 rad more)
    assert max(s.n0 for s in held) > 150.0 > min(s.n0 for s in held)
    assert max(s.theta0 for s in held) >= 0.04 + 0.05
    assert held[0].overrides()[0].name == "init.n0"


def test_the_fit_follows_the_ball_phase() -> None:
    assert fit_horizon({"t_stem": 0.9, "t_invert": 0.75}, 8.0) == pytest.approx(1.35)
    assert fit_horizon({"t_stem": None, "t_invert": 2.33}, 8.0) == pytest.approx(3.495)
    assert fit_horizon({"t_stem": None, "t_invert": 0.2}, 8.0) == MIN_FIT_S
    assert fit_horizon({}, 8.0) == 8.0  # nothing happens: the whole run


def test_cheaper_options_are_the_files_own() -> None:
    assert _cheaper("Euler", 5e-4, 2e-4) == [("Euler", 5e-4), (FIT_INTEGRATOR, 5e-4)]
    assert _cheaper("RK4", 2e-4, 2e-4) == []
    assert _cheaper("implicitfast", 1e-4, 1e-4) == [("implicitfast", 1e-4)]


def test_the_widening_keeps_the_fits_budget() -> None:
    """At the default budget the fits keep the 200 runs they had before the widening (so a
    file they agree on is tuned as then); a budget too small for two neighbours keeps none,
    and the fits never fall below one seed and one verification."""
    from tippetop.compare.tuning import TUNE_BUDGET_RUNS

    assert TUNE_BUDGET_RUNS - widen_reserve(TUNE_BUDGET_RUNS) == 200
    n_starts = 1 + len(HELD_OUT)
    for budget in range(min_budget_runs(), 1000):
        r = widen_reserve(budget)
        assert r == 0 or r >= 2 * n_starts
        assert budget - r >= min_budget_runs()
    assert widen_reserve(6) == 0 and widen_reserve(min_budget_runs()) == 0


def test_the_widenings_neighbours_change_one_choice_each() -> None:
    from tippetop.compare.tuning.calibrate.scoring import Candidate

    best = Candidate("elliptic", 0.5, 0.004, 0.3, 1.0, frictiondamping=2.6)
    iso = widen_neighbours(best, 2e-4, "RK4", 1.0)
    integs = [(c, dt, i) for _, c, dt, i in iso if c == best and dt == 2e-4]
    assert sorted(i for _, _, i in integs) == ["Euler", "implicitfast"]
    assert (best, 1e-4, "RK4") in [(c, dt, i) for _, c, dt, i in iso]
    flipped = [c for _, c, _, _ in iso if c.cone != best.cone]
    # MuJoCo takes the friction rows' own solref in an elliptic cone only
    assert len(flipped) == 1 and flipped[0].cone == "pyramidal"
    assert flipped[0].frictiondamping is None and flipped[0].mu == best.mu
    # a top with A != C: a first-order step drifts Jellett's constant, none is tried
    aniso = widen_neighbours(best, 2e-4, "RK4", 0.8)
    assert {i for _, _, _, i in aniso} == {"RK4"} and len(aniso) == 2
    # the answer's own integrator is not a neighbour of itself
    assert all(i != "Euler" or dt != 2e-4 or c != best
               for _, c, dt, i in widen_neighbours(best, 2e-4, "Euler", 1.0))


def test_the_widenings_draws_fill_a_small_box_about_the_best() -> None:
    """The draws stay within LOCAL_HALF_DECADES of the centre in each fitted setting and the
    damping ratio (a 3-digit rounding's 0.5 % beside), inside the bounds, with a time constant
    of at least two steps; they reach both sides of the centre in each setting (a draw that
    only shrank one setting would not be a box); the rest of the contact is the centre's."""
    from tippetop.compare.tuning.calibrate.identify import FITTED
    from tippetop.compare.tuning.calibrate.scoring import Candidate

    centre = Candidate("pyramidal", 1.28, 0.000929, 0.0894, 0.35)
    bounds = Bounds.around(0.3, 2e-4)
    draws = local_candidates(centre, FITTED, bounds, 16, 2e-4)
    assert 12 <= len(draws) <= 16 and len(set(draws)) == len(draws) and centre not in draws
    factor = 10.0 ** LOCAL_HALF_DECADES * 1.005
    for name in (*FITTED, "dampratio"):
        ratios = [getattr(c, name) / getattr(centre, name) for c in draws]
        assert all(1.0 / factor <= r <= factor for r in ratios), name
        assert min(ratios) < 0.9 and max(ratios) > 1.1, name  # both sides, not only near
        lo, hi = bounds.values.get(name, (0.0, math.inf))
        assert all(lo <= getattr(c, name) <= hi for c in draws), name
    assert all(c.cone == centre.cone and c.solimp_tail == centre.solimp_tail for c in draws)
    # the same seed draws the same candidates; another seed others
    assert local_candidates(centre, FITTED, bounds, 16, 2e-4) == draws
    assert local_candidates(centre, FITTED, bounds, 16, 2e-4, seed=1) != draws
    assert local_candidates(centre, FITTED, bounds, 0, 2e-4) == []
    # at a bound and at two steps: clipped, never past them
    edge = Candidate("pyramidal", 1.0, 4e-4, 0.1, 0.3 * 2.0)
    near = local_candidates(edge, FITTED, bounds, 16, 2e-4)
    assert max(c.mu for c in near) <= bounds.values["mu"][1] + 1e-12
    assert min(c.timeconst_s for c in near) >= 4e-4 - 1e-12
    # a direct solref has no damping ratio to vary
    direct = Candidate("elliptic", 300.0, 0.02, 1e-4, 1.0, solref_direct=(-1e5, -632.0),
                       frictiondamping=2.6)
    lift = local_candidates(direct, ("impratio", "frictiondamping"), Bounds.lift_free(), 8,
                            2e-4)
    assert lift and all(c.dampratio == direct.dampratio and c.solref_direct == (-1e5, -632.0)
                        for c in lift)


def test_seeds_are_at_the_files_mu_in_both_cones() -> None:
    s = seeds(0.3, {"cone": "elliptic", "impratio": 1.0, "solref": [1e-4, 1.0],
                    "solimp": [0.9, 0.95, 0.001, 0.5, 2.0]}, 2e-4)
    assert {c.cone for c in s} == {"pyramidal", "elliptic"}
    # a low impratio in each cone (a creep like the paper's Lambda)
    assert {c.cone for c in s if c.impratio < 1} >= {"pyramidal", "elliptic"}
    # the calibrated mu (0.106 at the paper's 0.1) scaled to 0.3; the others at 0.3
    from tippetop.models.calibrated import CALIBRATION_MU, calibrated_native_settings

    scaled = 0.3 * float(calibrated_native_settings()["mu"]) / CALIBRATION_MU
    assert s[0].mu == pytest.approx(scaled) and all(c.mu == 0.3 for c in s[1:])
    # a file's time constant below two steps is raised to it (MuJoCo's own floor)
    assert s[-1].timeconst_s == pytest.approx(4e-4)


def test_bounds_keep_mu_the_materials() -> None:
    b = Bounds.around(0.3, 2e-4)
    assert b.values["mu"] == (0.15, 0.6)
    assert b.values["timeconst_s"][0] == pytest.approx(4e-4)
    assert math.isclose(b.values["timeconst_s"][1], 0.05)


@pytest.mark.slow
def test_a_strangers_mu_1_top_is_tuned_to_follow_the_reference(tmp_path: Path) -> None:
    """Issue 30: a Group II top written as a stranger would (mu = 1, a capsule stem,
    implicitfast at MuJoCo's 2 ms). Neither cone's fit keeps its ball on the table (the
    elliptic one passed 14 of 24 checks); the lift-free family does, from the file's start
    and the three held-out ones, over validate's 8 s (measured: 24 of 24 checks, impratio
    301, solreffriction [-1, -2.61] on pairs, 84 MuJoCo runs, 139 s on 2 cores). The answer
    to paste carries the contact pair; RK4 is kept (implicitfast is first order and this
    top's A != C)."""
    xml = ROOT / "tests" / "data" / "stranger" / "group2_mu1_implicitfast.xml"
    proc = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "validate", str(xml),
                           "--json"], capture_output=True, text=True, timeout=1800, cwd=ROOT)
    assert proc.returncode in (0, 1), proc.stderr
    res = json.loads(proc.stdout)
    t = res["tuned"]
    assert "skipped" not in t, t
    assert t["settings"]["integrator"] == "RK4"
    assert any("first order" in n.get("why", "") for n in t["fit"]["needs"])
    assert t["agrees"], t["note"]
    assert len([v for v in t["verified"] if v["passed"]]) == 4
    assert "lift-free" in t["fit"]["tried"][-1]
    answer = res["answer"]
    assert answer["agrees"] and answer["source"] == "tuned"
    assert 'solreffriction="-1 -' in answer["mjcf"] and "<pair" in answer["mjcf"]


def test_the_files_cone_is_fitted_first() -> None:
    assert cone_order({"cone": "elliptic"}) == ["elliptic", "pyramidal"]
    assert cone_order({"cone": "pyramidal"}) == ["pyramidal", "elliptic"]
    assert cone_order(None) == ["pyramidal", "elliptic"]  # MuJoCo's default cone
    # at mu >= 0.5 the elliptic cone first: a pyramidal one lifts a sliding ball soonest
    assert cone_order({"cone": "pyramidal"}, wide=True) == ["elliptic", "pyramidal"]


def test_the_wide_fit_tries_the_lift_free_family_before_the_pyramid() -> None:
    assert fit_order({"cone": "pyramidal"}) == ["pyramidal", "elliptic"]  # mu < 0.5: cones
    assert fit_order({"cone": "pyramidal"}, wide=True) == ["elliptic", LIFT_FREE, "pyramidal"]


def test_a_lift_free_seed_is_a_plan_with_pairs() -> None:
    """The family's candidates reach the model through the harness's plan: an elliptic cone,
    the constant minimal impedance, the direct solref, and solreffriction on a pair for the
    ball and one for the stem (the Group II file's two geoms that touch the table)."""
    from tests.conftest import mujoco_plan
    from tippetop.compare.tuning.calibrate.identify import (
        LIFT_FREE_SOLREF,
        Bounds,
        lift_free_seeds,
    )

    g2 = ROOT / "tests" / "data" / "stranger" / "group2_mu1_implicitfast.xml"
    seed = lift_free_seeds(1.0)[0]
    assert Bounds.lift_free().clip(seed) == seed
    assert "solreffriction=[-1, -2.6] (pairs)" in seed.label()
    plan = mujoco_plan(f"top.mjcf={str(g2)!r}", *seed.overrides(2e-4, "RK4"))
    ran = plan.what_runs()
    assert ran["cone"] == "elliptic" and ran["impratio"] == 300
    assert ran["solref"] == list(LIFT_FREE_SOLREF) and ran["solimp"][:2] == [1e-4, 1e-4]
    pairs = [c for c in plan.contacts if c.element == "pair"]
    assert len(pairs) == 2 and all(p.solreffriction == (-1.0, -2.6) for p in pairs)


@pytest.mark.slow
def test_mujocos_tutorial_top_at_mu_1_is_tuned_to_follow_the_reference() -> None:
    """Issue 30: on MuJoCo's own tutorial top (mu = 1, its default contact), the tuning with
    the damping ratio and impratio up to 1000 fitted (mu >= 0.5) finds settings that pass
    every check from the file's start and from the held-out starts the reference can follow
    (measured: elliptic, impratio 1.7, solref [8.56 ms, 0.508], d0 0.0974, mu 0.981, at the
    file's own 2 ms step; 48 fit runs); the answer is those settings, and the file's own
    contact, which the lift explains, still departs."""
    xml = ROOT / "tests" / "data" / "tutorial_tippe_top.xml"
    proc = _cli("validate", str(xml), "--json", "--t-end-s", "3", timeout=1500)
    assert proc.returncode == 1, proc.stderr  # the file's own settings depart
    res = json.loads(proc.stdout)
    t = res["tuned"]
    assert t["agrees"], t["note"]
    assert t["settings"]["cone"] == "elliptic"
    verified = [v for v in t["verified"] if v["passed"] is not None]
    assert len(verified) >= 3 and any(v["role"] == "held-out" for v in verified)
    assert res["answer"]["agrees"] and res["answer"]["source"] == "tuned"
    assert any(c["check"] == "stays_on_table" for v in verified for c in v["checks"])
    assert res["lift"]["runs"]["mujoco/file"]["lifts"]


def _cli(*args: str, env: dict[str, str] | None = None,
         timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT, env=env)


def test_a_budget_below_one_verification_is_one_line() -> None:
    for cmd in (["validate", str(EXAMPLE)], ["calibrate", "--mjcf", str(EXAMPLE)]):
        proc = _cli(*cmd, "--budget-runs", str(min_budget_runs() - 1))
        assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
        assert proc.stderr.strip().splitlines()[-1].endswith(
            f"--budget-runs: expected at least {min_budget_runs()} MuJoCo runs (one seed "
            f"scored, then every start verified), got {min_budget_runs() - 1}")


def _own_cache(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """An empty run cache whose compiled code is the session's (nothing to compile)."""
    from tippetop.models.resources import user_cache_dir

    cache = tmp_path / "cache"
    cache.mkdir()
    (user_cache_dir() / "numba").mkdir(parents=True, exist_ok=True)
    (cache / "numba").symlink_to(user_cache_dir() / "numba", target_is_directory=True)
    return cache, {**os.environ, "TIPPETOP_CACHE": str(cache)}


def test_a_tiny_budget_ends_with_an_answer() -> None:
    # 6 runs: two seeds scored, no fit, the best of them verified from every start: the
    # tuning ends (no hang), with settings to paste and every start checked, labelled
    proc = _cli("calibrate", "--mjcf", str(EXAMPLE), "--budget-runs", "6", "--json",
                "--no-cache")
    assert proc.returncode in (0, 1), proc.stderr
    data = json.loads(proc.stdout)
    t = data["tuned"]
    # the printed JSON is the result's, read back to the same JSON
    assert TuneOnlyResult.from_json(data).to_json() == data
    assert t["budget_limited"] is True and "budget-limited" in t["note"]
    assert t["fit"]["runs"] <= 6 and t["fit"]["budget_runs"] == 6
    assert len(t["verified"]) == 1 + len(HELD_OUT) and t["mjcf"]
    assert 1 <= len(t["fit"]["seeds"]) and not t["fit"]["fits"]


def test_ctrl_c_while_tuning_leaves_nothing(tmp_path: Path) -> None:
    """SIGINT during the fit: exit 130, no --out folder, no tuning entry in the cache."""
    cache, env = _own_cache(tmp_path)
    # validate's own runs into the cache first, so that the second run reaches the tuning
    # at once; its reference runs of the held-out starts are the sign that it has
    first = _cli("validate", str(EXAMPLE), "--no-tune", "--json", env=env)
    assert first.returncode in (0, 1), first.stderr
    before = set(cache.glob("[0-9a-f][0-9a-f]/*"))
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "tippetop.compare.cli", "validate",
                             str(EXAMPLE), "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    while not set(cache.glob("[0-9a-f][0-9a-f]/*")) - before:
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.2)
    time.sleep(2.0)  # the held-out references written: the seeds and the fit are running
    assert proc.poll() is None, proc.communicate()
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert stderr.strip().splitlines()[-1] == "tippetop: interrupted"
    assert "Traceback" not in stderr and stdout == ""
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["cache"]
    assert not (cache / "tune").exists() or not list((cache / "tune").iterdir())
    assert not list(cache.rglob("*.tmp"))


def test_the_pair_to_paste_is_mjcf() -> None:
    """The lift-free answer's contact pairs (solreffriction has no geom attribute) parse as
    XML and carry the run's values, one for each geom of the file's top that touches its
    table, named as the file names them (issue 43: the block said BALL and TABLE); a
    generated top's names its own geoms; a run without one has none."""
    import xml.etree.ElementTree as ET

    from tests.conftest import mujoco_plan
    from tippetop.compare.measures.summary import mjcf_pair
    from tippetop.compare.studies.validate import plan_file_info
    from tippetop.compare.tuning.calibrate.identify import lift_free_seeds
    from tippetop.compare.tuning.judge import mjcf_block
    from tippetop.models.scene import Override

    g2 = ROOT / "tests" / "data" / "stranger" / "group2_mu1_implicitfast.xml"
    seed = lift_free_seeds(1.0)[0]
    ran = mujoco_plan(f"top.mjcf={str(g2)!r}", *seed.overrides(2e-4, "RK4")).what_runs()
    contacts = plan_file_info((Override.of("top.mjcf", str(g2)),))["contacts"]
    root = ET.fromstring(f"<mujoco>{mjcf_block(ran, contacts)}</mujoco>")
    pairs = root.findall("contact/pair")
    assert [(p.get("geom1"), p.get("geom2")) for p in pairs] == [("ball", "floor"),
                                                                  ("stem", "floor")]
    for pair in pairs:
        assert pair.get("solreffriction") == "-1 -2.6"
        assert [float(v) for v in pair.get("solref", "").split()] == ran["solref"]
        assert pair.get("friction", "").split()[:2] == ["1", "1"]
    generated = ET.fromstring(f"<mujoco>{mjcf_pair(ran)}</mujoco>").find("contact/pair")
    assert generated is not None and generated.get("geom1") == "ball"
    assert mjcf_pair({**ran, "solreffriction": None}) is None


def test_a_start_whose_reference_is_still_moving_is_verified_over_a_longer_horizon(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # Two runs still rising at their end say nothing of the contact: a start whose reference
    # is inconclusive at t_end is run again over twice, then four times the horizon, until
    # its reference settles (here: one settles by 16 s, one never does: it keeps 32 s, the
    # cap); a settled start and a reference that stopped keep theirs.
    import numpy as np
    import pandas as pd

    from tippetop.compare.running.runner import TaskResult
    from tippetop.compare.tuning import tune as tune_module

    def table(t_end: float, settles_by: float | None) -> pd.DataFrame:
        t = np.linspace(0.0, t_end, 801)
        rising = 0.1 + 0.3 * t  # still moving at the end
        if settles_by is None or t_end < settles_by:
            return pd.DataFrame({"t": t, "theta": rising})
        # settled: flat from half its settling time on
        return pd.DataFrame({"t": t, "theta": np.minimum(rising, 0.1 + 0.15 * settles_by)})

    settles = {"a": 10.0, "b": None, "c": 0.0}
    calls: list[float] = []

    def fake(tasks, **_opts):
        out = []
        for task in tasks:
            t_end = float(next(as_override(o).value for o in task.overrides
                               if not str(o).startswith("key=")
                               and as_override(o).name == "run.t_end_s"))
            calls.append(t_end)
            key = next(o for o in task.overrides if str(o).startswith("key=")).split("=")[1]
            out.append(TaskResult(task, "k", {"status": "ok"}, table(t_end, settles[key]),
                                  None, False))
        return out

    class Start:
        def __init__(self, key: str) -> None:
            self.key = key

        def overrides(self) -> tuple[str, ...]:
            return (f"key={self.key}",)

        def label(self) -> str:
            return self.key

    monkeypatch.setattr(tune_module, "run_tasks", fake)
    starts = [Start("a"), Start("b"), Start("c"), Start("c")]
    first = fake([tune_module.Task(None, (*s.overrides(), "run.t_end_s=8.0"), "ode")
                  for s in starts])
    stopped = TaskResult(first[3].task, "k", {"status": "contact_lost"}, first[3].table, None,
                         False)
    first[3] = stopped
    calls.clear()
    horizons, refs = tune_module.settled_references((), starts, first, 8.0, {})
    assert horizons == [16.0, 32.0, 8.0, 8.0]
    assert calls == [16.0, 16.0, 32.0]  # a and b doubled together, then b again
    assert refs[3] is stopped and refs[2] is first[2]
    assert tune_module.HORIZON_FACTOR_MAX == 4.0


def test_a_cached_tuning_is_keyed_by_all_of_the_tunings_code(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """validate's and fidelity's cached tunings are keyed by :func:`source_digest`: a change to
    the widening, its draws, the verification's judge or the result (its start labels, its
    JSON; modules of their own) is a new key."""
    from tippetop.compare.results import tune as result
    from tippetop.compare.tuning import judge, sobol, tune, widen
    from tippetop.compare.tuning.tune import source_digest

    before = source_digest()
    for module in (tune, judge, widen, sobol, result):
        real = Path.read_bytes
        path = Path(str(module.__file__))

        def edited(self: Path, real=real, path=path) -> bytes:
            data = real(self)
            return data + b"\n# edited\n" if self == path else data

        with monkeypatch.context() as m:
            m.setattr(Path, "read_bytes", edited)
            assert source_digest() != before, module.__name__
    assert source_digest() == before


def _hand_built_tuning(*, cached: bool | None = None) -> TuneResult:
    """A tuning with every form its JSON takes: a start verified and one not verifiable, an
    alternative with and without ``what``, a widening, a lift-free contact."""
    check = {"check": "outcome", "run": "mujoco/file", "engine": "mujoco", "mode": "file",
             "passed": False, "value": None, "tolerance": "same", "note": "upright",
             "against": "theory"}
    fit = TuneFit(
        starts=(FittedStart(100.0, 0.1, 3.49),), residual=0.024, residual_definition="rms",
        runs=42, rollouts=30, verify_runs=12, budget_runs=300,
        seeds=({"cone": "elliptic", "settings": "s", "rms_rad": 1.4},),
        fits=({"cone": "elliptic", "from": "s", "from_rms_rad": 0.2, "to": "t",
               "rms_rad": 0.02, "rollouts": 32, "iterations": 5, "stop": "converged"},),
        cones=("elliptic",), tried=("the fit in the elliptic cone",), timestep_s=2e-4,
        integrator="RK4",
        needs=(TuneNeed("implicitfast", 2e-3, None, False, "first order"),
               TuneNeed("RK4", 2e-3, 0.03, True, "")),
        chosen="widened: Euler in place of RK4",
        alternatives=(TuneAlternative("seed a", None, False, ("outcome from x",), 3, 5, "<m/>",
                                      True),
                      TuneAlternative("w", "widened: Euler", True, (), 5, 5, "<m/>", False)),
        bounds={"mu": (0.05, 0.2), "impratio": (0.02, 1000.0)}, method="lm",
        widened=({"settings": "w", "what": "widened: Euler", "agrees": True, "passes": 5,
                  "checks": 5},),
        wall_s=28.1)
    return TuneResult(
        settings=TunedSettings(1.0, "elliptic", 300.0, (-1e5, -632.0), (1e-4, 1e-4, 0.1, 0.5, 2.0),
                               2e-4, "RK4", 3, (-1.0, -2.61)),
        mjcf="<option/>", fit=fit,
        verified=(TuneVerification(100.0, 0.1, "fit", 8.0, "inverted", (check,), False,
                                   friction_realised={"mu_fit": 0.1}, left_table_s=None),
                  TuneVerification(115.0, 0.1, "held-out", 16.0, None, (), None,
                                   note="not verifiable: the reference stops")),
        agrees=False, departs=("outcome from n0 = 100 rad/s (fit): upright",), passes=0,
        checks=1, budget_limited=True, note="no setting", cached=cached)


def test_a_tuning_reads_itself_back_from_its_json() -> None:
    """from_json(to_json(r)) == r for every form; the JSON's keys keep their order (the
    verified start's friction and the unverifiable one's note; a seed without ``what``)."""
    for cached in (None, True, False):
        r = _hand_built_tuning(cached=cached)
        data = r.to_json()
        assert TuneResult.from_json(data) == r
        assert TuneResult.from_json(json.loads(json.dumps(data))) == r  # through JSON text
        assert ("cached" in data) == (cached is not None)
    data = _hand_built_tuning().to_json()
    assert list(data) == ["settings", "mjcf", "fit", "verified", "agrees", "departs", "passes",
                          "checks", "budget_limited", "note"]
    assert list(data["verified"][0])[-2:] == ["friction_realised", "left_table_s"]
    assert list(data["verified"][1])[-1] == "note" and "friction_realised" not in \
        data["verified"][1]
    assert "what" not in data["fit"]["alternatives"][0]
    assert list(data["fit"]["alternatives"][1])[:2] == ["settings", "what"]
    assert data["settings"]["solreffriction"] == [-1.0, -2.61]
    for skipped in (TuneSkipped("--no-tune"), TuneSkipped("no reference", False)):
        assert tuned_from_json(skipped.to_json()) == skipped
    assert TuneSkipped("--no-tune").to_json() == {"skipped": "--no-tune"}
    only = TuneOnlyResult("top.xml", 0.1, 100.0, 0.1, 8.0, _hand_built_tuning(cached=False))
    assert TuneOnlyResult.from_json(only.to_json()) == only
