"""``tippetop bench ode``: its keys and its peers' answers, with small settings (not timed).

The speed figures themselves are the benchmark's to print (ratios measured in one run); these
tests check what it reports and that every solver integrated the same problem.
"""

from __future__ import annotations

import json
import sys

import pytest

from tippetop.compare.cli import main
from tippetop.compare.commands.options import json_text
from tippetop.compare.presentation.bench import bench_ode_report
from tippetop.compare.results.bench import BenchOdeResult
from tippetop.compare.studies.bench import EQUAL_ACCURACY_RAD, bench_ode
from tippetop.compare.studies.frontier import ERROR_FLOOR, time_at_error
from tippetop.reference_ode.peers import NUMBALSODA_METHODS, NUMBALSODA_MISSING
from tippetop.reference_ode.taylor_peer import HEYOKA, heyoka_missing

SMALL = ["--t-end-s", "0.3", "--rounds", "1"]
#: Keys ``bench ode --json`` had before the peers, kept.
OLD_KEYS = {"n0", "t_end_s", "rtol", "atol", "ours_s", "ours_n_rhs", "scipy_s", "scipy_n_rhs",
            "speedup", "theta_final_ours", "theta_final_scipy", "theta_final_abs_diff",
            "ours_ns_per_rhs", "scipy_ns_per_rhs", "target_speedup_met", "target_theta_met"}
NEW_KEYS = {"peers", "speedup_vs_best_peer", "best_peer", "ours_kernel_s", "ours_kernel_n_rhs",
            "theta_final_kernel", "rounds", "scipy_rounds", "timing"}
#: The default (auto at rtol 1e-9: the Taylor method at rtol 1e-10) and numbalsoda's DOP853
#: at rtol 1e-9 are each within ~1e-12 rad of the converged theta after 0.3 s (measured:
#: 5.9e-12 apart after 10 s): the bound is the benchmark's own equal-accuracy criterion, 100x that.
DOP853_THETA_TOL = EQUAL_ACCURACY_RAD
#: heyoka's Taylor method at tol 1e-9 over 0.3 s: measured 2.6e-11 rad from the default after
#: 10 s; 1e-9 (its tolerance) bounds it, and a wrong term moves theta by >= 1e-4 rad.
HEYOKA_THETA_TOL = 1e-9
#: LSODA is another method (Adams/BDF) whose error estimate only keeps its local errors near
#: rtol = 1e-9 of the state (quaternion entries ~1, so ~1e-9 rad a step); its global error
#: grows with the run (measured 9e-12 rad after 0.3 s, 1.1e-6 after 60 s). 100 rtol bounds the
#: short run with room; a right-hand side wired to other parameters or another state layout
#: is off by >= 1e-4 rad within 0.3 s.
LSODA_THETA_TOL = 1e-7


def _bench_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict:
    assert main(["bench", "ode", "--json", *args]) == 0
    return json.loads(capsys.readouterr().out)


def test_bench_ode_json_has_the_peers_and_their_answers_agree(
        capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("numbalsoda")
    out = _bench_json(capsys, *SMALL)
    assert OLD_KEYS | NEW_KEYS <= set(out)
    peers = out["peers"]
    assert peers["available"] is True
    assert set(NUMBALSODA_METHODS) <= set(peers["solvers"]) <= {*NUMBALSODA_METHODS, HEYOKA}
    if heyoka_missing() is None:
        assert peers["solvers"][HEYOKA]["theta_abs_diff"] <= HEYOKA_THETA_TOL
    for name, sv in peers["solvers"].items():
        assert {"s", "n_rhs", "theta_final"} <= set(sv), name
        assert sv["success"] and sv["s"] > 0.0 and sv["n_rhs"] > 0, name
        assert sv["theta_abs_diff"] == pytest.approx(
            abs(sv["theta_final"] - out["theta_final_kernel"]), abs=1e-18)
    dop = peers["solvers"]["numbalsoda DOP853"]
    lsoda = peers["solvers"]["numbalsoda LSODA"]
    assert dop["theta_abs_diff"] <= DOP853_THETA_TOL
    assert lsoda["theta_abs_diff"] <= LSODA_THETA_TOL
    # the default is the method auto names at this rtol, at the tolerances it names
    assert (out["method"], out["method_rtol"]) == ("taylor", pytest.approx(1e-10))
    # the kernel call and simulate_ode are the same integration
    assert out["ours_kernel_n_rhs"] == out["ours_n_rhs"]
    assert out["theta_final_kernel"] == pytest.approx(out["theta_final_ours"], abs=1e-15)
    # the verdict is at equal achieved error: each peer's time at our error against the
    # truth, read on its own frontier (a sweep of rtol), over ours
    assert out["theta_final_kernel"] == pytest.approx(peers["theta_truth"],
                                                      abs=DOP853_THETA_TOL)
    assert peers["ours_theta_err"] == pytest.approx(
        max(abs(out["theta_final_kernel"] - peers["theta_truth"]), ERROR_FLOOR), rel=1e-12)
    for name, sv in peers["solvers"].items():
        assert len(sv["sweep"]) >= 2, name
        t_eq = time_at_error([(q["theta_err"], q["s"]) for q in sv["sweep"]],
                             peers["ours_theta_err"])
        assert sv["equal_accuracy"] is (t_eq is not None), name
        assert sv["s_at_equal_error"] == t_eq, name
    equal = [n for n, sv in peers["solvers"].items() if sv["equal_accuracy"]]
    assert set(peers["not_equal_accuracy"]) == set(peers["solvers"]) - set(equal)
    best = min(equal, key=lambda n: peers["solvers"][n]["s_at_equal_error"]) if equal else None
    assert out["best_peer"] == peers["best_equal_accuracy"] == best
    if best is None:
        assert out["speedup_vs_best_peer"] is None
    else:
        assert out["speedup_vs_best_peer"] == pytest.approx(
            peers["solvers"][best]["s_at_equal_error"] / out["ours_kernel_s"], rel=1e-12)


def test_bench_ode_without_numbalsoda_says_so(monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """numbalsoda cannot be imported: no peer is run, the JSON says why, the speed-up against
    the peers is null (never a number), and the table says it."""
    monkeypatch.setitem(sys.modules, "numbalsoda", None)  # import numbalsoda -> ImportError
    out = _bench_json(capsys, *SMALL)
    assert out["peers"] == {"available": False, "reason": NUMBALSODA_MISSING}
    assert out["speedup_vs_best_peer"] is None and out["best_peer"] is None
    assert OLD_KEYS <= set(out)
    assert main(["bench", "ode", *SMALL]) == 0
    text = capsys.readouterr().out
    assert NUMBALSODA_MISSING in text and "numbalsoda DOP853" not in text
    assert "scipy solve_ivp(DOP853)" in text and "tippetop taylor" in text


def test_bench_ode_table_has_a_row_per_solver() -> None:
    pytest.importorskip("numbalsoda")
    res = bench_ode(t_end_s=0.1, rounds=1)
    report = res.report
    # the result reads back from its JSON, and its report is the printer's, from its fields
    assert BenchOdeResult.from_json(res.to_json()) == res
    assert BenchOdeResult.from_json(json.loads(json_text(res))) == res
    assert bench_ode_report(res) == report
    rows = {line.split("  ")[1].strip() for line in report.splitlines()[2:7]}
    want = {"tippetop taylor", "numbalsoda DOP853", "numbalsoda LSODA", "scipy solve_ivp(DOP853)"}
    if heyoka_missing() is None:
        want.add(HEYOKA)
    assert want <= rows
    # the default runs the Taylor method: its cost is said per jet, not per rhs evaluation
    assert "per jet (a Taylor step)" in report and "counts its jets" in report
