"""``tippetop bench ode --sweep``: the frontier logic, the truth check, the output (not timed).

The speed figures are the benchmark's to print; these tests check how it reads them (on
synthetic points with known answers), that the two truths are checked, and that a tiny real
sweep runs end to end and writes what it says.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

from tippetop.compare.cli import main
from tippetop.compare.presentation.bench import format_ratio, work_precision_report
from tippetop.compare.results.work_precision import WorkPrecisionResult
from tippetop.compare.studies.frontier import (
    cancellations,
    compare_at_levels,
    frontier,
    level_table,
    smallest_error,
    time_at_error,
    without_cancellations,
)
from tippetop.compare.studies.peer_runs import PeerPoint
from tippetop.compare.studies.work_precision import (
    FORMAT,
    TRUTH_THETA_AGREEMENT,
    check_truths,
    make_top,
    reference_methods,
)
from tippetop.compare.studies.work_precision_report import run_work_precision, slow_peers
from tippetop.models.errors import TippetopError

#: (error, time) points: (2e-5 at 3.5 s) is dominated (the 2-s point reaches less error, for
#: less) and must leave the frontier; (5e-6 at 3 s) is not (nothing cheaper reaches it).
POINTS = [(1e-3, 1.0), (1e-5, 2.0), (5e-6, 3.0), (2e-5, 3.5), (1e-7, 4.0)]


def test_frontier_is_the_monotone_hull() -> None:
    assert frontier(POINTS) == [(1e-3, 1.0), (1e-5, 2.0), (5e-6, 3.0), (1e-7, 4.0)]
    assert frontier([(math.nan, 1.0), (1e-4, math.inf)]) == []


def test_time_at_error_interpolates_log_log_and_says_not_reached() -> None:
    # between (1e-3, 1 s) and (1e-5, 2 s): log t linear in log e, 1e-4 halfway -> sqrt(2) s
    assert time_at_error(POINTS, 1e-4) == pytest.approx(math.sqrt(2.0), rel=1e-12)
    # between (5e-6, 3 s) and (1e-7, 4 s): w = log(1e-6/5e-6) / log(1e-7/5e-6)
    w = math.log(0.2) / math.log(0.02)
    assert time_at_error(POINTS, 1e-6) == pytest.approx(3.0 * (4.0 / 3.0) ** w, rel=1e-12)
    assert time_at_error(POINTS, 1e-7) == pytest.approx(4.0, rel=1e-12)  # a point itself
    assert time_at_error(POINTS, 1e-2) == 1.0  # above the cheapest point: its time
    assert time_at_error(POINTS, 1e-8) is None  # not reached
    assert smallest_error(POINTS) == 1e-7
    assert time_at_error([], 1e-4) is None


def test_compare_at_levels_ratios() -> None:
    pts = {"ours": [(1e-4, 1.0), (1e-8, 2.0)], "auto": [(1e-4, 1.5), (1e-6, 3.0)],
           "peer": [(1e-4, 2.0), (1e-6, 4.0)]}
    rows = compare_at_levels(pts, ["ours"], "auto", ["peer"], [1e-4, 1e-6, 1e-8, 1e-10])
    assert rows[0]["ratio"] == pytest.approx(2.0) and rows[0]["met"]
    assert rows[0]["ratio_auto"] == pytest.approx(2.0 / 1.5) and rows[0]["met_auto"]
    # at 1e-6, halfway (in log) from 1e-4 to 1e-8, ours interpolates to sqrt(1 * 2) s
    assert rows[1]["ratio"] == pytest.approx(4.0 / math.sqrt(2.0))
    # at 1e-8 only ours reaches it: inf, met; auto does not: None, not met
    assert rows[2]["ratio"] == math.inf and rows[2]["met"]
    assert rows[2]["ratio_auto"] is None and not rows[2]["met_auto"]
    assert rows[2]["smallest"]["peer"] == 1e-6
    # at 1e-10 no one: None, NOT met
    assert rows[3]["ratio"] is None and not rows[3]["met"]


def test_a_cancellation_is_an_error_below_the_next_tighter_tolerance_s() -> None:
    """heyoka's Jellett drift on Fig. 3 (2026-11-28): 6.9e-9 at tol 1e-5 but 8.3e-9 at 1e-6,
    and 6.9e-15 at 1e-9 but 1.6e-14 at 1e-10: the two loose points are cancellations; the
    rest falls with the tolerance. Two points at the error floor are not one."""
    pts = [(1e-4, 3.3e-6, 0.34), (1e-5, 6.9e-9, 0.395), (1e-6, 8.3e-9, 0.445),
           (1e-7, 2.7e-10, 0.565), (1e-8, 2.8e-12, 0.637), (1e-9, 6.9e-15, 0.716),
           (1e-10, 1.6e-14, 1.23), (1e-11, 1e-17, 1.4), (1e-12, 0.0, 1.7),
           (1e-13, math.nan, 2.0)]
    assert cancellations(pts) == [1e-5, 1e-9]
    assert cancellations(list(reversed(pts))) == [1e-5, 1e-9]  # order given does not matter
    kept = without_cancellations(pts)
    assert (6.9e-9, 0.395) not in kept and (6.9e-15, 0.716) not in kept and len(kept) == 8
    # at 1e-8 the peer read with its cancellation is 0.40 ms; without it, on the line from
    # (3.3e-6, 0.34) to (8.3e-9, 0.445): w = log(1e-8/3.3e-6) / log(8.3e-9/3.3e-6)
    w = math.log(1e-8 / 3.3e-6) / math.log(8.3e-9 / 3.3e-6)
    steady = time_at_error(kept, 1e-8)
    assert steady == pytest.approx(0.34 * (0.445 / 0.34) ** w, rel=1e-12)
    assert time_at_error([(e, t) for _, e, t in pts], 1e-8) < steady


def test_the_table_shows_the_steady_ratio_and_the_cancellations() -> None:
    rows = compare_at_levels({"ours": [(1e-6, 1.0)], "peer": [(1e-6, 1.1)]}, ["ours"], None,
                             ["peer"], [1e-6])
    rows[0].update(ratio_steady=1.3, met_steady=True)
    text = level_table("t", "rad", rows, ["ours", "peer"], {"peer": [1e-5, 1e-9]})
    assert "steady" in text and "1.30x" in text and "NOT met (met without cancellations)" in text
    assert "peer at rtol 1e-05, 1e-09" in text
    plain = level_table("t", "rad", compare_at_levels({"ours": [(1e-6, 1.0)]}, ["ours"], None,
                                                      [], [1e-6]), ["ours"])
    assert "steady" not in plain and "cancellations" not in plain


def _point(theta: float, t_inv: float | None = 2.0) -> PeerPoint:
    return PeerPoint(s=1.0, n_rhs=1, theta=theta, t_invert=t_inv, J_drift=0.0, status="ok")


def test_truths_that_disagree_fail_loudly() -> None:
    ok = check_truths("x", {"a": _point(1.0), "b": _point(1.0 + 0.5 * TRUTH_THETA_AGREEMENT)},
                      1e-14)
    assert ok["theta_diff"] == pytest.approx(0.5 * TRUTH_THETA_AGREEMENT, rel=1e-3)
    with pytest.raises(TippetopError, match="disagree"):
        check_truths("x", {"a": _point(1.0), "b": _point(1.0 + 1e-9)}, 1e-14)
    with pytest.raises(TippetopError, match="t_invert"):
        check_truths("x", {"a": _point(1.0, 2.0), "b": _point(1.0, 2.0 + 1e-8)}, 1e-14)
    with pytest.raises(TippetopError, match="inverts"):
        check_truths("x", {"a": _point(1.0, 2.0), "b": _point(1.0, None)}, 1e-14)


def test_a_method_that_does_not_import_is_skipped(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "tippetop.reference_ode.verner", None)
    ok, skipped = reference_methods()
    assert "vern9" not in ok and "dop853" in ok
    assert "does not import" in skipped["tippetop vern9"]


def test_a_short_point_runs_more_rounds_and_the_bar_counts_every_run(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A compiled solver's point under SHORT_S runs SHORT_ROUNDS x the rounds (its best CPU
    time then as steady as a longer point's); a longer one, and a Python-driven peer's, do
    not; the runs the sweep says it plans (``expect``) are the runs it makes (``tick``)."""
    import tippetop.compare.studies.work_precision as wp
    from tippetop.compare.studies.peer_runs import Peer

    runs: dict[tuple[str, float], int] = {}
    #: CPU time (s) per rtol: the two loose points are short, the tight ones long
    times = {1e-3: 0.001, 1e-4: 0.002, 1e-5: 0.02, 1e-6: 0.04}

    def point(name: str, rtol: float) -> PeerPoint:
        runs[name, rtol] = runs.get((name, rtol), 0) + 1
        return PeerPoint(s=times[rtol], n_rhs=1, theta=1.0 + rtol, t_invert=None,
                         J_drift=rtol, status="ok", method=name)

    class Fake(Peer):
        def warm(self, top: object) -> None:
            pass

        def run(self, top: object, rtol: float, *, locate_invert: bool,
                t_end_s: float | None = None) -> PeerPoint:
            return point(self.name, rtol)

    class Slow(Fake):
        slow = True

    fakes = {"fast": Fake("fast"), "slow": Slow("slow")}
    monkeypatch.setattr(wp, "PEERS", fakes)
    monkeypatch.setattr(wp, "compute_truth", lambda top: {"theta": 1.0, "t_invert": None})
    monkeypatch.setattr(wp, "run_reference", lambda top, m, rtol: point(m, rtol))
    planned: list[int] = []
    ticks: list[int] = []
    res = wp.sweep_top(make_top("fig3", 0.01), rounds=2, tolerances=tuple(times),
                       peers=list(fakes), methods=["dop853"],
                       tick=lambda: ticks.append(1), expect=planned.append)
    short, long_ = 2 * wp.SHORT_ROUNDS, 2
    for name in ("fast", "dop853"):
        # the reference's warm-up run at the loosest rtol is off the count (one more run)
        warm = 1 if name == "dop853" else 0
        assert [runs[name, t] for t in times] == [short + warm, short, long_, long_]
    assert [runs.get(("slow", t), 0) for t in times] == [1, 0, 1, 0]  # every other rtol
    assert sum(planned) == len(ticks) == sum(runs.values()) - 1
    assert planned[0] == 4 + 4 + 2  # the first round, as planned before it
    assert {p["s"] for p in res.solvers["fast"]["points"]} == set(times.values())


@pytest.mark.parametrize("args", [
    ["bench", "ode", "--sweep", "--tops", "fig3,nope"],
    ["bench", "ode", "--sweep", "--tops", ","],
    ["bench", "accuracy", "--sweep"],
    ["bench", "ode", "--sweep", "--rounds", "0"],
    ["bench", "ode", "--sweep", "--t-end-s", "-1"],
    ["bench", "ode", "--sweep", "fig3"],
])
def test_bad_input_is_one_line_exit_2_nothing_written(
        args: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "wp"
    with pytest.raises(SystemExit) as exc:
        sys.exit(main([*args, "--out", str(out)]))
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_an_existing_folder_is_kept_without_force(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "wp"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    assert main(["bench", "ode", "--sweep", "--tops", "fig11", "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert (out / "mine.txt").read_text() == "keep"


@pytest.mark.slow
def test_a_tiny_sweep_runs_end_to_end(tmp_path: Path) -> None:
    """fig3 cut to 2.6 s (it inverts at ~2.33 s), three tolerances, the compiled peers."""
    pytest.importorskip("numbalsoda")
    out = tmp_path / "wp"
    doc = run_work_precision(["fig3"], out, rounds=1, t_end_s=2.6,
                             tolerances=(1e-5, 1e-8, 1e-11),
                             peers=["numbalsoda DOP853", "numbalsoda LSODA"])
    assert doc.format == FORMAT
    assert doc.out == str(out)
    assert (out / "fig3.png").stat().st_size > 1000
    saved = json.loads((out / "work-precision.json").read_text())
    assert saved["format"] == FORMAT
    # the result reads back from its JSON, and from the file written (without ``out``)
    assert WorkPrecisionResult.from_json(doc.to_json()) == doc
    assert WorkPrecisionResult.from_json(saved).to_json() == saved
    res = doc.tops["fig3"]
    tr = res.truth
    assert tr["theta_diff"] <= TRUTH_THETA_AGREEMENT
    assert tr["t_invert"] == pytest.approx(2.33, abs=0.05)
    # the peers' inversion time is located from samples far below the smallest level (1e-10 s)
    assert tr["t_invert_locate_err"] < 1e-12
    assert set(res.levels) == {"theta", "t_invert", "J_drift"}
    for sv in res.solvers.values():
        assert [p["rtol"] for p in sv["points"]] == [1e-5, 1e-8, 1e-11]
        assert all(p["status"] == "ok" for p in sv["points"])
    # every method's error falls as its tolerance tightens (a smooth problem: by >= 10x
    # over the 6 decades from 1e-5 to 1e-11, a loose bound for any convergent method)
    for name, sv in res.solvers.items():
        e = [p["theta_err"] for p in sv["points"]]
        assert e[-1] < 0.1 * e[0], name
    for name in ("tippetop dop853", "numbalsoda DOP853"):  # an event; a located crossing
        assert all(p["t_invert_err"] < 1e-3 for p in res.solvers[name]["points"]), name
    rows = res.levels["theta"]["rows"]
    assert [r["level"] for r in rows] == [1e-4, 1e-6, 1e-8, 1e-10]
    report = work_precision_report(doc, slow_peers())
    assert "theta(t_end) error" in report and "peer/ref" in report
    assert (out / "report.txt").read_text() == report + "\n"
    with pytest.raises(TippetopError, match="--force"):
        run_work_precision(["fig3"], out, rounds=1, t_end_s=2.6, tolerances=(1e-5,))


@pytest.mark.slow  # compiles every reference method in a fresh process (~30-90 s here)
def test_the_json_keys(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """The CLI's --json on a very short run of one top with the compiled solvers only."""
    pytest.importorskip("numbalsoda")
    doc = run_work_precision(["fig11"], tmp_path / "wp", rounds=1, t_end_s=0.05,
                             tolerances=(1e-4, 1e-8), peers=["numbalsoda DOP853"]).to_json()
    assert {"format", "rounds", "timing", "tolerances", "atol_per_rtol", "target_ratio",
            "skipped_methods", "tops", "elapsed_s", "out"} <= set(doc)
    res = doc["tops"]["fig11"]
    assert {"title", "t_end_s", "truth", "solvers", "skipped", "levels", "references",
            "auto", "peers"} <= set(res)
    assert {"methods", "rtol", "theta", "theta_other", "theta_diff", "t_invert",
            "t_invert_diff"} <= set(res["truth"])
    assert set(res["levels"]) == {"theta", "J_drift"}  # it does not invert in 0.05 s
    for row in res["levels"]["theta"]["rows"]:
        assert {"level", "times", "smallest", "best_reference", "best_peer", "ratio",
                "ratio_auto", "met", "met_auto"} <= set(row)
        assert row["ratio"] is None or row["ratio"] == "inf" or row["ratio"] > 0
    for sv in res["solvers"].values():
        for p in sv["points"]:
            assert {"rtol", "atol", "s", "n_rhs", "status", "theta_err", "t_invert_err",
                    "J_drift"} <= set(p)
    saved = json.loads((tmp_path / "wp" / "work-precision.json").read_text())
    assert saved["format"] == FORMAT and set(saved["tops"]) == {"fig11"}


def test_the_stored_json_reads_back() -> None:
    """docs/data/work-precision.json (the docs' figures are drawn from it) reads back as a
    result that gives the same JSON, and prints (its ratios of "inf" as inf)."""
    path = Path(__file__).resolve().parents[2] / "docs" / "data" / "work-precision.json"
    data = json.loads(path.read_text(encoding="utf-8"))
    res = WorkPrecisionResult.from_json(data)
    assert res.to_json() == data
    assert WorkPrecisionResult.from_json(res.to_json()) == res
    assert res.out is None and set(res.tops) == set(data["tops"])
    report = work_precision_report(res, slow_peers())
    assert report.count("\n== ") == len(res.tops) and "peer/ref" in report
    assert format_ratio("inf") == format_ratio(math.inf) == "inf"
    assert format_ratio(None) == "-" and format_ratio(1.5) == "1.50x"
    with pytest.raises(TippetopError, match="format"):
        WorkPrecisionResult.from_json({**data, "format": "something/2"})


def test_tops() -> None:
    assert make_top("fig11").t_end_s == 60.0
    assert make_top("stiff").stiff and make_top("stiff").friction.Lambda_mps == 1e-6
    with pytest.raises(TippetopError):
        make_top("nope")


def test_what_a_peer_s_fortran_prints_is_counted_not_shown(
        capfd: pytest.CaptureFixture[str]) -> None:
    """Hairer's DOP853 (numbalsoda, gfortran) prints "the problem seems to become stiff" on
    file descriptor 1 in its own buffer: 216 lines in a terminal over one stiff-top sweep. The
    run keeps them off both descriptors, even after it ends (gfortran flushes its buffer
    later unless told), and counts them."""
    pytest.importorskip("numbalsoda")
    from tippetop.compare.studies.peer_runs import PEERS

    peer = PEERS["numbalsoda DOP853"]
    top = make_top("stiff", 0.2)  # its detector fires once at rtol 1e-5 (measured: 1 line)
    capfd.readouterr()
    point = peer.run(top, 1e-5, locate_invert=False)
    peer.run(top, 1e-3, locate_invert=False)  # a later run, to flush anything still held
    out, err = capfd.readouterr()
    assert point.status == "ok" and point.printed >= 1
    assert "stiff" not in out and "stiff" not in err
