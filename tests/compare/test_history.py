"""The history: a SQLite store two writers share, change-points, imports, bad files, the nightly.

Every test is fast: the store's tests write small made-up results (values chosen here, with the
steps and blips put in by hand), the two-writer test runs two processes of 25 appends each,
and the nightly's runs one 4-s reference run of Fig. 3 with no baseline.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from tippetop.compare.cli import main as cli_main
from tippetop.compare.commands import nightly as nightly_command
from tippetop.compare.nightly import history as h


def tippetop(*args: str) -> tuple[int, str, str]:
    """``tippetop ARGS`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli_main(list(args))
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def bisect_like(night: int, value: float, version: str, *, outcome: str = "inverted") -> dict:
    """Results in the generic ``rows`` form (as a bisect appends them): one case, two metrics."""
    return {"format": "tippetop-bisect/1", "started": f"2026-11-{night:02d}T02:00:00+00:00",
            "rows": [{"case": "fig3[mujoco/file]", "engine": "mujoco", "engine_version": version,
                      "mode": "file", "metric": "t_invert", "value": value},
                     {"case": "fig3[mujoco/file]", "engine": "mujoco", "engine_version": version,
                      "mode": "file", "metric": "outcome", "value": outcome}]}


# --------------------------------------------------------------------------- two writers
WRITER = textwrap.dedent("""
    import sys, time
    from tippetop.compare.nightly import history as h
    path, who, start = sys.argv[1], sys.argv[2], float(sys.argv[3])
    while time.time() < start:
        time.sleep(0.005)
    for i in range(25):
        rows = [{"case": f"{who}/case{k}", "engine": "mujoco", "engine_version": "3.3.7",
                 "metric": "t_invert", "value": i + k / 100} for k in range(40)]
        h.record_results("bisect", {"format": "tippetop-bisect/1", "rows": rows,
                                     "started": f"2026-11-01T00:00:{i:02d}+00:00",
                                     "environment": {"hostname": who}, "who": who, "i": i},
                         path=path)
""")


def test_two_processes_appending_at_once_keep_every_row(tmp_path: Path) -> None:
    path = tmp_path / "history.sqlite"
    start = time.time() + 2.0  # both processes are up before either writes
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(path), who, str(start)],
                              stderr=subprocess.PIPE, text=True) for who in ("a", "b")]
    errs = [p.communicate(timeout=120)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errs
    con = sqlite3.connect(path)
    try:
        assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        runs = con.execute("SELECT count(*) FROM runs").fetchone()[0]
        per_case = dict(con.execute("SELECT substr(case_id, 1, 1), count(*) FROM measures "
                                    "GROUP BY substr(case_id, 1, 1)").fetchall())
    finally:
        con.close()
    assert runs == 50  # 25 appends by each
    assert per_case == {"a": 25 * 40, "b": 25 * 40}  # no row lost, none doubled
    series, _ = h.load_series(path, cases=["a/case0", "b/case0"])
    assert [len(s.values) for s in series] == [25, 25]


def test_the_switch_to_wal_is_retried_while_another_process_holds_the_file() -> None:
    """SQLite answers "database is locked" at once, not after its busy timeout, when two
    connections opening a new history would wait on each other for the switch to WAL (seen as
    one of two nightlies failing; 4 of 80 trials of four processes opening one new file before
    the retry, 0 of 80 after). The switch is retried; another error is not."""

    class Con:
        def __init__(self, fails: int, message: str) -> None:
            self.fails, self.message, self.calls = fails, message, 0

        def execute(self, sql: str) -> None:
            assert sql == "PRAGMA journal_mode = WAL"
            self.calls += 1
            if self.calls <= self.fails:
                raise sqlite3.OperationalError(self.message)

    con = Con(3, "database is locked")
    h._switch_to_wal(con)
    assert con.calls == 4
    with pytest.raises(sqlite3.OperationalError, match="disk I/O"):
        h._switch_to_wal(Con(1, "disk I/O error"))


def test_a_new_history_read_while_it_is_created_is_one_snapshot(tmp_path: Path) -> None:
    """What the file is (its id, its format, its tables) is read as one snapshot. Here the
    creator commits right after the reader's first statement: reads in separate statements
    (autocommit) would see no id, then the tables ("not a tippetop history"); one snapshot sees
    the empty file (a new history), and the next read the finished one."""
    path = tmp_path / "history.sqlite"
    maker = sqlite3.connect(path, isolation_level=None)
    reader = sqlite3.connect(path, isolation_level=None)

    class CommitsAfterFirstRead:
        calls = 0

        def execute(self, sql: str):
            cursor = reader.execute(sql)
            row = cursor.fetchone()
            self.calls += 1
            if self.calls == 1:
                maker.execute("COMMIT")

            class Done:
                def fetchone(self):
                    return row
            return Done()

    try:
        maker.execute("BEGIN IMMEDIATE")
        for stmt in h._SCHEMA:
            maker.execute(stmt)
        maker.execute(f"PRAGMA application_id = {h.APPLICATION_ID}")
        maker.execute(f"PRAGMA user_version = {h.FORMAT_VERSION}")
        assert h._inspect(CommitsAfterFirstRead(), path) == 0  # the snapshot before the commit
        assert h._inspect(reader, path) == h.FORMAT_VERSION
    finally:
        maker.close()
        reader.close()


# --------------------------------------------------------------------------- change-points
def _step_history(path: Path) -> None:
    """Eight nights: t_invert 1.206 s, a one-night blip to 1.5 s on night 3, then a step to
    1.042 s on night 6 when MuJoCo goes from 3.3.7 to 3.17.0; the outcome never moves."""
    nights = [(1, 1.206, "3.3.7"), (2, 1.21, "3.3.7"), (3, 1.5, "3.3.7"), (4, 1.204, "3.3.7"),
              (5, 1.207, "3.3.7"), (6, 1.042, "3.17.0"), (7, 1.045, "3.17.0"),
              (8, 1.041, "3.17.0")]
    for night, value, version in nights:
        assert h.record_results("bisect", bisect_like(night, value, version), path=path)


def test_a_step_is_found_and_names_the_engine_version_and_a_blip_is_not_a_step(
        tmp_path: Path) -> None:
    path = tmp_path / "h.sqlite"
    _step_history(path)
    series, runs = h.load_series(path, metrics=["t_invert"])
    assert len(runs) == 8 and len(series) == 1
    s = series[0]
    changes = h.change_points([v.value for v in s.values], s.tolerance)
    # t_invert's tolerance is +-0.1 s: 1.5 s is one night away, 1.042 s stays
    assert [(c.type, c.index) for c in changes] == [("blip", 2), ("step", 5)]
    step = h.describe_change(s, changes[1])
    assert step["engine_version"] == ["3.3.7", "3.17.0"]
    assert "2026-11-06" in step["text"] and "mujoco 3.3.7 -> 3.17.0" in step["text"]
    blip = h.describe_change(s, changes[0])
    assert blip["type"] == "blip" and "not a step" in blip["text"]
    assert blip["engine_version"] is None  # the engine did not change that night
    # the outcome, a word, never moved
    out, _ = h.load_series(path, metrics=["outcome"])
    assert h.change_points([v.value for v in out[0].values], out[0].tolerance) == []

    code, text, err = tippetop("history", "--history", str(path), "--metric", "t_invert")
    assert code == 0, err
    assert "step: t_invert 1.207 -> 1.042 s on 2026-11-06 (mujoco 3.3.7 -> 3.17.0)" in text
    assert "blip: t_invert" in text
    code, text, err = tippetop("history", "--history", str(path), "--json", "--changed")
    assert code == 0, err
    data = json.loads(text)
    assert data["format"] == h.JSON_FORMAT and data["format_version"] == h.FORMAT_VERSION
    assert {"runs", "series", "history"} <= set(data)
    [ser] = data["series"]  # only t_invert changed
    assert ser["metric"] == "t_invert" and ser["tolerance"]["kind"] == "abs"
    assert [c["type"] for c in ser["changes"]] == ["blip", "step"]
    assert set(ser["values"][0]) == {"run", "started", "value", "engine_version", "commit",
                                     "status"}


@pytest.mark.parametrize(("values", "expected"), [
    ([1.0, 1.05, 0.97, 1.02], []),                    # within +-0.1 s: steady
    ([1.0, 1.0, 1.3], [("last", 2)]),                 # the last night: not yet a step
    ([1.0, 1.3, 1.6, 1.6], [("step", 1), ("step", 2)]),  # two steps in a row
    ([1.0, None, 1.0], [("blip", 1)]),                # a night without a value
])
def test_change_points_of_small_series(values: list, expected: list) -> None:
    tol = {"kind": "abs", "value": 0.1, "floor": 0.0}
    assert [(c.type, c.index) for c in h.change_points(values, tol)] == expected


def test_a_commit_is_named_when_the_engine_version_did_not_change(tmp_path: Path) -> None:
    path = tmp_path / "h.sqlite"
    for night, value, commit in ((1, 2.0, "a" * 40), (2, 2.0, "a" * 40), (3, 2.5, "b" * 40),
                                 (4, 2.5, "b" * 40)):
        res = bisect_like(night, value, "3.17.0")
        res["environment"] = {"git_commit": commit, "hostname": "ci", "packages": {}}
        h.record_results("bisect", res, path=path)
    [s], _ = h.load_series(path, metrics=["t_invert"])
    [c] = h.change_points([v.value for v in s.values], s.tolerance)
    text = h.describe_change(s, c)["text"]
    assert c.type == "step" and f"commit {'a' * 10} -> {'b' * 10}" in text
    assert "3.17.0 unchanged" in text


# --------------------------------------------------------------------------- import
def _nightly_results(started: str, t_invert: float) -> dict:
    tol = {"kind": "abs", "value": 0.1, "floor": 0.0, "unit": "s"}
    return {"format": "tippetop-nightly-results/1", "profile": "quick", "started": started,
            "command": ["tippetop", "nightly"], "verdict": "OK",
            "environment": {"git_commit": "c" * 40, "hostname": "box", "cpu_count": 2,
                            "platform": "Linux", "packages": {"mujoco": "3.3.7",
                                                              "tippetop": "0.1.0"}},
            "cases": [{"id": "paper/fig3[mujoco/paper]", "engine": "mujoco", "mode": "paper",
                       "summary": {"version": "3.3.7"},
                       "checks": [{"metric": "t_invert", "value": t_invert, "status": "pass",
                                   "tolerance": tol}]},
                      {"id": "sweeps/fig9a[ode/paper]", "engine": "ode", "mode": "paper",
                       "checks": [{"metric": "theta_asymp_vs_n0", "status": "new",
                                   "value": {"30": 0.1, "45": 2.9},
                                   "tolerance": {**tol, "value": 0.05, "unit": "rad"}}]}]}


def test_import_reads_nightly_and_matrix_results_with_their_dates(tmp_path: Path) -> None:
    nightly = tmp_path / "n1.json"
    nightly.write_text(json.dumps(_nightly_results("2026-10-01T03:00:00+00:00", 1.2)))
    matrix = tmp_path / "m.json"
    matrix.write_text(json.dumps({
        "format": "tippetop-matrix/2", "engines": [{"engine": "mujoco==3.17.0",
                                                    "version": "3.17.0"}],
        "tolerances": {"t_invert": {"kind": "abs", "value": 0.1, "floor": 0.0, "unit": "s"}},
        "reference": {"fig3": {"scene": "fig3", "engine": "ode", "mode": "paper",
                               "run": "ode/paper", "t_invert": 2.33}},
        "runs": [{"scene": "fig3", "engine": "mujoco==3.17.0", "mode": "file",
                  "run": "mujoco==3.17.0/file", "t_invert": 1.042, "version": "3.17.0"}]}))
    mtime = 1790000000  # 2026-09-21: the matrix's results have no date of their own
    os.utime(matrix, (mtime, mtime))
    path = tmp_path / "h.sqlite"
    code, out, err = tippetop("history", "--history", str(path), "--import", str(nightly),
                              str(matrix))
    assert code == 0, err
    assert "(nightly) as run" in out and "(matrix) as run" in out
    code, out, err = tippetop("history", "--history", str(path), "--import", str(nightly))
    assert code == 0 and "already in the history" in out  # kept once
    series, runs = h.load_series(path)
    assert [r["kind"] for r in runs] == ["matrix", "nightly"]  # in time order
    assert runs[0]["started"].startswith("2026-09-2") and runs[1]["started"] == \
        "2026-10-01T03:00:00+00:00"
    assert runs[1]["commit"] == "c" * 40 and runs[1]["hostname"] == "box"
    assert runs[1]["engines"] == {"mujoco": "3.3.7", "ode": "0.1.0"}
    by = {(s.case, s.metric, s.point): s for s in series}
    assert by["fig3[mujoco==3.17.0/file]", "t_invert", ""].values[0].engine_version == "3.17.0"
    assert by["fig3[ode/paper]", "t_invert", ""].values[0].value == pytest.approx(2.33)
    assert by["sweeps/fig9a[ode/paper]", "theta_asymp_vs_n0", "45"].values[0].value == \
        pytest.approx(2.9)
    # not results: one line, exit 2, nothing appended
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something-else"}')
    code, out, err = tippetop("history", "--history", str(path), "--import", str(bad))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "tippetop-matrix/2" in err
    assert len(h.load_series(path)[1]) == 2


def test_a_bisects_results_append_each_release_it_ran(tmp_path: Path) -> None:
    res = {"format": "tippetop-bisect/1", "scene": "top.xml", "mode": "file", "overrides": [],
           "started": "2026-11-27T10:00:00+00:00",
           "tested": [{"release": "3.10.0", "engine": "mujoco==3.10.0", "version": "3.10.0",
                       "status": "ok", "values": {"t_invert": 3.654, "outcome": "inverted"}},
                      {"release": "3.11.0", "engine": "mujoco==3.11.0", "version": "3.11.0",
                       "status": "ok", "values": {"t_invert": 3.356, "outcome": "inverted"}}]}
    path = tmp_path / "h.sqlite"
    assert h.record_results("bisect", res, path=path) == 1
    series, runs = h.load_series(path, metrics=["t_invert"])
    assert runs[0]["kind"] == "bisect"
    assert runs[0]["engines"] == {"mujoco==3.10.0": "3.10.0", "mujoco==3.11.0": "3.11.0"}
    assert [(s.case, s.values[0].engine_version, s.tolerance["kind"]) for s in series] == [
        ("top.xml[mujoco==3.10.0/file]", "3.10.0", "abs"),
        ("top.xml[mujoco==3.11.0/file]", "3.11.0", "abs")]


# --------------------------------------------------------------------------- bad files
def _newer(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA application_id = {h.APPLICATION_ID}")
    con.execute(f"PRAGMA user_version = {h.FORMAT_VERSION + 1}")
    con.execute("CREATE TABLE future (x)")
    con.commit()
    con.close()


def _other_app(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE notes (x)")
    con.commit()
    con.close()


@pytest.mark.parametrize(("make", "says"), [
    (lambda p: p.write_text("t_invert = 1.2\n"), "not a SQLite database"),
    (_newer, f"format {h.FORMAT_VERSION + 1}, newer"),
    (_other_app, "not a tippetop history"),
])
@pytest.mark.parametrize("args", [["history"], ["history", "--import", "{results}"],
                                  ["matrix", "fig3", "--engines", "mujoco"]])
def test_a_file_that_is_not_a_history_is_refused_in_one_line_untouched(
        tmp_path: Path, make, says: str, args: list[str]) -> None:
    path = tmp_path / "history.sqlite"
    make(path)
    before = (path.read_bytes(), path.stat().st_mtime_ns)
    results = tmp_path / "r.json"
    results.write_text(json.dumps(_nightly_results("2026-10-01T03:00:00+00:00", 1.2)))
    argv = [a.replace("{results}", str(results)) for a in args]
    code, out, err = tippetop(*argv, "--history", str(path))
    assert code == 2, out + err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and "expected a tippetop history" in lines[0]
    assert str(path) in lines[0] and "Traceback" not in err
    assert (path.read_bytes(), path.stat().st_mtime_ns) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["history.sqlite", "r.json"]


# --------------------------------------------------------------------------- the nightly
TINY = """
[profiles.tiny]
description = "test profile: one short reference run"

[[case]]
name = "fig3-short"
category = "paper"
kind = "run"
scene = "fig3"
set = ["run.t_end_s=4"]
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["outcome", "theta_asymp", "t_invert"]
"""
CASE = "paper/fig3-short[ode/paper]"


def run_nightly(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = nightly_command.main(list(args))
    return code, out.getvalue(), err.getvalue()


def test_the_nightly_appends_and_draws_the_metric_that_moved(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    cat = tmp_path / "tiny.toml"
    cat.write_text(TINY)
    path = tmp_path / "ci" / "history.sqlite"

    def nightly(out: str, *extra: str) -> tuple[int, str, str]:
        return run_nightly("--catalogue", str(cat), "--profile", "tiny", "--engines", "ode",
                           "--no-baseline", "--out", str(tmp_path / out), "--workers", "1",
                           "--cache", "--history", str(path), *extra)

    code, out, err = nightly("first")
    assert code == 0, out + err
    first = json.loads((tmp_path / "first" / "results.json").read_text())
    assert first["history"]["run"] == 1 and first["history"]["error"] is None
    assert f"history: appended to {path} (run 1)" in out
    [s], runs = h.load_series(path, metrics=["t_invert"])
    assert s.case == CASE and s.engine == "ode" and runs[0]["kind"] == "nightly"
    assert runs[0]["engines"]["ode"] and runs[0]["hostname"] and runs[0]["argv"][:2] == \
        ["tippetop", "nightly"]
    measured = first["cases"][0]["values"]["t_invert"]
    assert s.values[0].value == pytest.approx(measured, rel=1e-12)
    # three earlier nights at t_invert 0.5 s higher: tonight's value is a move beyond 0.1 s
    for night in (1, 2, 3):
        old = json.loads(json.dumps(first))
        old["started"] = f"2026-01-0{night}T02:00:00+00:00"
        old["cases"][0]["checks"] = [dict(ch, value=measured + 0.5)
                                     if ch["metric"] == "t_invert" else ch
                                     for ch in old["cases"][0]["checks"]]
        h.record_results("nightly", old, path=path)
    code, out, err = nightly("second")
    assert code == 0, out + err
    second = json.loads((tmp_path / "second" / "results.json").read_text())
    trends = second["history"]["trends"]
    assert [t["metric"] for t in trends] == ["t_invert"]  # the only series that moved
    assert [c["type"] for c in trends[0]["changes"]] == ["step"]  # night 4 stayed, tonight too
    html = (tmp_path / "second" / "report.html").read_text()
    section = html[html.index("id='trends'"):]
    section = section[:section.index("<h2", 5)]
    assert "<img" in section and "t_invert" in section and CASE in section
    assert "1 series moved or regressed" in out


def test_a_failed_append_is_said_and_the_results_are_kept(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    cat = tmp_path / "tiny.toml"
    cat.write_text(TINY)

    def broken(*args, **kw):
        raise sqlite3.OperationalError("disk I/O error")

    monkeypatch.setattr(h, "append_run", broken)
    code, out, err = run_nightly("--catalogue", str(cat), "--profile", "tiny", "--engines",
                                 "ode", "--no-baseline", "--out", str(tmp_path / "o"),
                                 "--workers", "1", "--history", str(tmp_path / "h.sqlite"))
    assert code == 0, out + err
    res = json.loads((tmp_path / "o" / "results.json").read_text())
    assert res["history"]["run"] is None and "disk I/O error" in res["history"]["error"]
    assert [ln for ln in err.splitlines() if "history not appended" in ln]
    assert "history: NOT appended" in out and (tmp_path / "o" / "report.html").is_file()
