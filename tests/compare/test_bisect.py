"""``tippetop bisect``: which release moved a metric.

Over a fake release list with a fake runner (no environment is made): the number of runs is a
binary search's, a range that moves twice says so and names both moves, a release that fails
to install is skipped and named; bad input is one line and exit 2 through the command line.
One real bisect over three releases (slow).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pytest

from tippetop.compare.results.bisect import (
    BisectContext,
    BisectResult,
    MovePair,
    SkippedRelease,
)
from tippetop.compare.results.matrix import Attribution, MatrixDifference, MatrixResult
from tippetop.compare.studies.bisect import (
    FORMAT,
    Candidate,
    bisect,
    check_metrics,
    parse_registry,
    python_range,
    read_pythons,
    registry_releases,
    release_range,
)
from tippetop.compare.studies.matrix import COMPARED, differs
from tippetop.models.errors import TippetopError

#: A wheel every platform and Python takes, and one none here does.
ANY_WHEEL = "mujoco-{v}-py3-none-any.whl"
NO_WHEEL = "mujoco-{v}-cp27-cp27m-win32.whl"


def _registry(versions: Sequence[str], **special: str) -> dict[str, Any]:
    """A registry's JSON: every version with a wheel that fits, but those in ``special``."""
    out: dict[str, Any] = {}
    for v in versions:
        kind = special.get(v.replace(".", "_"), "")
        if kind == "yanked":
            out[v] = [{"filename": ANY_WHEEL.format(v=v), "yanked": True}]
        elif kind == "nowheel":
            out[v] = [{"filename": NO_WHEEL.format(v=v), "yanked": False},
                      {"filename": f"mujoco-{v}.tar.gz", "yanked": False}]
        else:
            out[v] = [{"filename": ANY_WHEEL.format(v=v), "yanked": False}]
    return {"releases": out}


def _names(n: int) -> list[str]:
    return [f"3.{i}.0" for i in range(n)]


class FakeRunner:
    """Runs nothing: each release's metrics from ``value(index)``; counts what it was asked."""

    def __init__(self, names: Sequence[str], value: Callable[[int], dict[str, Any]],
                 broken: Sequence[str] = ()) -> None:
        self.index = {f"mujoco=={n}": i for i, n in enumerate(names)}
        self.value = value
        self.broken = set(broken)
        self.prepared: list[str] = []
        self.measured: list[str] = []
        self.attributed: list[tuple[str, str]] = []

    def prepare(self, engine: str) -> str:
        self.prepared.append(engine)
        if engine in self.broken:
            raise TippetopError(f"engine {engine}: expected a release uv can install, got: "
                                "no wheel")
        return "made"

    def measure(self, engines: Sequence[str]) -> dict[str, dict[str, Any]]:
        self.measured.extend(engines)
        out = {}
        for e in engines:
            values = {m: None for m in COMPARED}
            values.update(status="ok", outcome="inverted", **self.value(self.index[e]))
            out[e] = {"version": e.removeprefix("mujoco=="), "status": "ok", "message": None,
                      "values": values}
        return out

    def attribute(self, a: str, b: str) -> MatrixResult:
        self.attributed.append((a, b))
        att = Attribution("the solver", (), (), (), "t_invert", (a, b), None)
        diff = MatrixDifference("fig3", "native", (a, b), "t_invert", (None, None), 0.1, "",
                                attribution=att)
        return MatrixResult((), (), (diff,), True, {}, ("native",), ("fig3",), {})


def _cands(n: int) -> list[Candidate]:
    return [Candidate(v, f"mujoco=={v}") for v in _names(n)]


def _step(at: int, low: float = 1.206, high: float = 1.042) -> Callable[[int], dict[str, Any]]:
    """t_invert moves once, from ``low`` to ``high``, at release ``at`` (0.164 s: over its
    0.1-s tolerance)."""
    return lambda i: {"t_invert": low if i < at else high}


# ---------------------------------------------------------------- the release list
def test_releases_are_in_release_order_without_pre_releases_yanked_or_foreign_ones() -> None:
    data = _registry(["3.10.0", "3.9.0", "3.2.7", "3.3.0rc1", "3.11.0", "3.8.1", "3.8.0",
                      "2.3.1.post1", "3.12.0.dev1"], **{"3_11_0": "yanked", "3_8_1": "nowheel"})
    rl = parse_registry(data)
    assert rl.releases == ("2.3.1.post1", "3.2.7", "3.8.0", "3.9.0", "3.10.0")
    assert rl.excluded["3.3.0rc1"] == rl.excluded["3.12.0.dev1"] == "a pre-release"
    assert rl.excluded["3.11.0"] == "yanked"
    assert rl.excluded["3.8.1"].startswith("no wheel for this platform")


def test_the_release_list_is_kept_in_the_cache_a_while(tmp_path: Path) -> None:
    path = tmp_path / f"mujoco-py{sys.version_info[0]}{sys.version_info[1]}-{sys.platform}.json"
    path.write_text(json.dumps({"fetched": time.time(), "source": "test",
                                "data": _registry(["3.3.7", "3.4.0"])}))
    rl = registry_releases("mujoco", cache_dir=tmp_path)
    assert rl.releases == ("3.3.7", "3.4.0") and rl.source.startswith("test (kept")
    given = registry_releases("mujoco", fetch=lambda _p: _registry(["1.0.0", "1.1.0"]))
    assert given.releases == ("1.0.0", "1.1.0")


def test_the_range_runs_the_installed_release_in_this_process() -> None:
    rl = parse_registry(_registry(["3.16.0", "3.17.0", "4.0.0"]))
    c = release_range(rl, "3.16.0", "mujoco==4.0.0", installed="4.0.0")
    assert [x.engine for x in c] == ["mujoco==3.16.0", "mujoco==3.17.0", "mujoco"]


@pytest.mark.parametrize(("a", "b", "says"), [
    ("3.17.0", "3.3.7", "expected A before B in release order, got 3.17.0 after 3.3.7"),
    ("3.3.7", "3.3.8", "expected a release on the package registry"),
    ("3.3.7", "3.3.7", "expected two different releases"),
    ("3.3.7", "3.5.0", "no wheel for this platform"),
])
def test_a_bad_range_is_one_line(a: str, b: str, says: str) -> None:
    rl = parse_registry(_registry(["3.3.7", "3.4.0", "3.5.0", "3.17.0"],
                                  **{"3_5_0": "nowheel"}))
    with pytest.raises(TippetopError, match=says.replace(".", r"\.")):
        release_range(rl, a, b)


def test_metrics_are_the_matrix_ones() -> None:
    assert check_metrics(None) == list(COMPARED)
    assert check_metrics("t_invert, status,t_invert") == ["t_invert", "status"]
    with pytest.raises(TippetopError, match="did you mean 't_invert'"):
        check_metrics("t_inverted")


# ---------------------------------------------------------------- the search
@pytest.mark.parametrize("n", [3, 16, 50])
def test_the_runs_are_a_binary_search_not_one_per_release(n: int) -> None:
    """Wherever the move is, at most ceil(log2(n - 1)) releases run between the ends."""
    bound = math.ceil(math.log2(n - 1)) + 2
    for at in range(1, n):
        runner = FakeRunner(_names(n), _step(at))
        res = bisect(_cands(n), ["t_invert"], runner)
        e = res.by_metric["t_invert"]
        assert e.moved and e.pair == MovePair(_names(n)[at - 1], _names(n)[at]), at
        assert e.values == (1.206, 1.042) and not e.moves_more_than_once
        assert len(runner.measured) == len(set(runner.measured)) == res.runs <= bound, at
        assert res.environments_made == res.runs
        assert e.attribution is not None and e.attribution.follows == "the solver"
        assert runner.attributed == [(f"mujoco=={_names(n)[at - 1]}",
                                      f"mujoco=={_names(n)[at]}")]


def test_no_move_runs_the_ends_only() -> None:
    runner = FakeRunner(_names(16), lambda i: {"t_invert": 1.2 + 1e-4 * i})
    res = bisect(_cands(16), ["t_invert"], runner)
    e = res.by_metric["t_invert"]
    assert not e.moved and e.pair is None and res.runs == 2
    assert runner.attributed == []


def test_a_range_that_moves_twice_says_so_and_names_both_moves() -> None:
    """1.5 s up to 3.4.0, 1.3 s from 3.5.0, 1.0 s from 3.11.0 (each step twice the 0.1-s
    tolerance or more)."""
    n = 16

    def value(i: int) -> dict[str, Any]:
        return {"t_invert": 1.5 if i < 5 else 1.3 if i < 11 else 1.0}

    runner = FakeRunner(_names(n), value)
    res = bisect(_cands(n), ["t_invert"], runner)
    e = res.by_metric["t_invert"]
    assert e.moves_more_than_once
    assert e.pair == MovePair("3.4.0", "3.5.0")
    moves = [(m.last_like_before, m.first_like_after) for m in e.moves]
    assert moves == [("3.4.0", "3.5.0"), ("3.10.0", "3.11.0")]
    assert all(m.resolved for m in e.moves)
    assert "more than once" in e.summary and "3.10.0 -> 3.11.0" in e.summary
    assert res.runs <= res.budget


def test_a_move_away_and_back_seen_by_another_metric_is_said() -> None:
    """theta_asymp's ends agree, but a release run for t_invert departs from both: its first
    move is bisected (3.5.0 -> 3.6.0), and its move back (3.9.0 -> 3.10.0) named."""
    n = 16

    def value(i: int) -> dict[str, Any]:
        return {"t_invert": 1.2 if i < 8 else 1.0,
                "theta_asymp": 3.0 if 6 <= i <= 9 else 2.9}  # 0.1 rad: 5x its tolerance

    res = bisect(_cands(n), ["t_invert", "theta_asymp"], FakeRunner(_names(n), value))
    e = res.by_metric["theta_asymp"]
    assert e.moved and len(e.moves) == 2 and e.moves_more_than_once
    assert e.pair == MovePair("3.5.0", "3.6.0")
    assert [(m.last_like_before, m.first_like_after) for m in e.moves] == [
        ("3.5.0", "3.6.0"), ("3.9.0", "3.10.0")]


def test_the_budget_bounds_the_search_for_further_moves() -> None:
    n = 50

    def value(i: int) -> dict[str, Any]:
        return {"t_invert": 5.0 - 0.25 * (i // 5)}  # a move every 5 releases

    res = bisect(_cands(n), ["t_invert"], FakeRunner(_names(n), value), budget=10)
    e = res.by_metric["t_invert"]
    assert res.runs <= 10 and e.moves_more_than_once
    assert e.pair == MovePair("3.4.0", "3.5.0")
    assert any(not m.resolved for m in e.moves)  # a further move narrowed, not named


def test_the_first_move_is_found_whatever_the_budget() -> None:
    n = 16
    res = bisect(_cands(n), ["t_invert"], FakeRunner(_names(n), _step(11)), budget=2)
    assert res.by_metric["t_invert"].pair == MovePair("3.10.0", "3.11.0")


def test_a_release_that_fails_to_install_is_skipped_and_named() -> None:
    n = 16
    names = _names(n)
    first = FakeRunner(names, _step(6))
    bisect(_cands(n), ["t_invert"], first)
    broken = first.measured[2]  # the first release the search runs between the ends
    runner = FakeRunner(names, _step(6), broken=[broken])
    lines: list[str] = []
    res = bisect(_cands(n), ["t_invert"], runner, say=lines.append)
    e = res.by_metric["t_invert"]
    assert e.pair == MovePair("3.5.0", "3.6.0")
    assert res.skipped == (SkippedRelease(broken.removeprefix("mujoco=="), broken,
                                          runner_reason(broken)),)
    assert broken not in runner.measured
    assert any(line.startswith(f"bisect: skipped {broken.removeprefix('mujoco==')}")
               for line in lines)


def test_a_scheduler_that_cannot_be_reached_stops_the_search_not_skips_releases() -> None:
    class Unreachable(FakeRunner):
        def measure(self, engines: Sequence[str]) -> dict[str, dict[str, Any]]:
            from tippetop.compare.running.tasks import SchedulerError

            raise SchedulerError("--scheduler: expected a reachable Dask scheduler, got 'x'")

    runner = Unreachable(_names(8), _step(3))
    with pytest.raises(TippetopError, match="--scheduler"):
        bisect(_cands(8), ["t_invert"], runner)
    assert len(runner.prepared) == 2  # the ends, then it stopped


def runner_reason(engine: str) -> str:
    return f"engine {engine}: expected a release uv can install, got: no wheel"


def test_a_pair_around_a_release_that_cannot_run_names_it() -> None:
    n = 8
    runner = FakeRunner(_names(n), _step(4), broken=["mujoco==3.3.0", "mujoco==3.4.0"])
    res = bisect(_cands(n), ["t_invert"], runner)
    e = res.by_metric["t_invert"]
    assert e.pair == MovePair("3.2.0", "3.5.0")
    assert e.moves[0].untested_between == ("3.3.0", "3.4.0")
    assert "could not run" in e.summary


def test_an_end_that_cannot_run_is_replaced_by_its_neighbour() -> None:
    n = 8
    res = bisect(_cands(n), ["t_invert"],
                 FakeRunner(_names(n), _step(5), broken=["mujoco==3.0.0"]))
    assert res.searched == ("3.1.0", "3.7.0") and res.notes
    pair = res.by_metric["t_invert"].pair
    assert pair is not None and pair.first_like_b == "3.5.0"


def test_the_result_keeps_every_run_for_the_history() -> None:
    n = 10
    res = bisect(_cands(n), ["t_invert"], FakeRunner(_names(n), _step(3))).to_json()
    for t in res["tested"]:
        assert {"release", "engine", "version", "status", "values", "environment"} <= set(t)
        assert set(t["values"]) == set(COMPARED)
    assert {"releases", "between", "tested", "environments_made", "skipped",
            "by_metric"} <= set(res)
    e = res["by_metric"]["t_invert"]
    assert {"moved", "pair", "values", "tolerance", "attribution", "moves_more_than_once",
            "moves"} <= set(e)
    # the pair's values differ by the matrix's rule, and each end is like its own side
    assert differs("t_invert", *e["values"])


def test_the_result_is_rebuilt_from_its_json() -> None:
    """from_json(to_json(r)) is r: the search alone, and with the command's context and
    history (a move attributed, one noted as a drift, a release skipped)."""
    n = 16

    def value(i: int) -> dict[str, Any]:
        return {"t_invert": 1.5 if i < 5 else 1.3 if i < 11 else 1.0,
                "theta_asymp": 3.0 if i < 9 else 2.9}

    res = bisect(_cands(n), ["t_invert", "theta_asymp"],
                 FakeRunner(_names(n), value, broken=["mujoco==3.7.0"]))
    assert res.skipped and res.by_metric["theta_asymp"].attribution_note
    assert res.by_metric["t_invert"].attribution is not None
    assert BisectResult.from_json(res.to_json()) == res
    assert "format" not in res.to_json()  # the search alone, as the study returned it
    full = dataclasses.replace(
        res, context=BisectContext("fig3", "native", ("run.t_end_s=1",), "given",
                                   "2026-01-01T00:00:00+00:00"),
        history={"file": "h.sqlite", "run": 1, "error": None})
    data = full.to_json()
    assert list(data)[:6] == ["format", "scene", "mode", "overrides", "source", "started"]
    assert data["format"] == FORMAT and list(data)[-1] == "history"
    assert BisectResult.from_json(data) == full
    assert BisectResult.from_json(json.loads(json.dumps(data))).to_json() == data


def test_pythons_file_reads_in_order_with_comments(tmp_path: Path) -> None:
    f = tmp_path / "builds.txt"
    exe = Path(sys.executable)
    link = tmp_path / "py-b"
    link.symlink_to(exe)
    f.write_text(f"# builds in commit order\n{exe}\n\n./py-b  # the fix\n")
    pys = read_pythons(f)
    assert pys == [str(exe), str(link)]
    assert [c.engine for c in python_range(pys, None)] == [f"mujoco@{exe}", f"mujoco@{link}"]
    with pytest.raises(TippetopError, match="A before B"):
        python_range(pys, [str(link), str(exe)])


# ---------------------------------------------------------------- the command line
def _cli(args: list[str], cache: Path, cwd: Path | None = None
         ) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "TIPPETOP_CACHE": str(cache)}
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "bisect", *args],
                          capture_output=True, text=True, timeout=300, env=env, cwd=cwd)


@pytest.fixture(scope="module")
def kept_list(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A cache holding a fresh release list (the registry is not asked)."""
    cache = tmp_path_factory.mktemp("cache")
    py = f"py{sys.version_info[0]}{sys.version_info[1]}"
    (cache / "registry").mkdir()
    (cache / "registry" / f"mujoco-{py}-{sys.platform}.json").write_text(json.dumps(
        {"fetched": time.time(), "source": "test",
         "data": _registry(["3.3.7", "3.4.0", "3.5.0", "3.17.0", "4.0.0rc1"])}))
    (cache / "one.txt").write_text(f"{sys.executable}\n")
    (cache / "missing.txt").write_text(f"{sys.executable}\n/no/such/python\n")
    return cache


#: Bad input, each with what its one line says.
BAD = [
    (["--between", "3.17.0", "3.3.7"], "expected A before B in release order"),
    (["--pythons", "missing.txt"], "expected an interpreter on line 2"),
    (["--between", "3.3.7", "3.3.8"], "expected a release on the package registry"),
    (["--between", "3.3.7", "4.0.0rc1"], "(a pre-release)"),
    (["--between", "3.4.0", "3.4.0"], "a range with no release to search"),
    (["--between", "3.3.7", "3.17.0", "--metric", "t_flip"], "--metric: expected one of"),
    (["--pythons", "one.txt"], "expected at least two interpreters"),
    (["--pythons", "nothere.txt"], "--pythons: expected a text file"),
    ([], "--between: expected two releases"),
]


@pytest.mark.parametrize(("args", "says"), BAD[:2])
def test_bad_input_is_one_line_exit_2_and_nothing_written(args: list[str], says: str,
                                                          kept_list: Path) -> None:
    """Through the command line, in a process of its own: no traceback, no --out folder."""
    out = kept_list / "out"
    done = _cli(["fig3", *args, "--out", str(out)], kept_list, cwd=kept_list)
    assert done.returncode == 2, done.stderr
    assert done.stdout == "" and len(done.stderr.splitlines()) == 1, done.stderr
    assert says in done.stderr and "Traceback" not in done.stderr
    assert not out.exists()


@pytest.mark.parametrize(("args", "says"), BAD[2:])
def test_every_bad_input_is_one_line(args: list[str], says: str, kept_list: Path,
                                     monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    """The same through ``main`` in this process (fast): exit 2, one line, nothing written."""
    from tippetop.compare.cli import main

    monkeypatch.setenv("TIPPETOP_CACHE", str(kept_list))
    monkeypatch.chdir(kept_list)
    out = kept_list / "out"
    assert main(["bisect", "fig3", *args, "--out", str(out)]) == 2
    err = capsys.readouterr()
    assert err.out == "" and len(err.err.splitlines()) == 1 and says in err.err, err.err
    assert not out.exists()


# ---------------------------------------------------------------- a real one
@pytest.mark.slow
def test_a_real_bisect_over_three_releases(tmp_path: Path) -> None:
    """3.16.0, 3.17.0 and 4.0.0 (this process's MuJoCo) on a short Fig. 3 run.

    What ran is read back from each run: the release asked, in its environment; the pair, if
    a metric moved, differs by the matrix's rule and each end is like its own side.
    """
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "bisect", "fig3",
                           "--between", "3.16.0", "4.0.0", "--set", "run.t_end_s=1.5",
                           "--no-attribution", "--out", str(out), "--json"],
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    res = json.loads(done.stdout)
    assert res["format"] == FORMAT and res["mode"] == "native"
    assert res["releases"] == ["3.16.0", "3.17.0", "4.0.0"]
    ran = {t["release"]: t for t in res["tested"]}
    assert {"3.16.0", "4.0.0"} <= set(ran) and res["runs"] <= 3
    assert ran["4.0.0"]["engine"] == "mujoco"  # the installed release, in this process
    for name, t in ran.items():
        assert t["version"] == name and t["status"] == "ok", t
        assert math.isfinite(t["values"]["J_rel_drift"])
    assert res["environments_made"] == len(ran) - 1
    for m, e in res["by_metric"].items():
        if e["moved"]:
            a, b = ran[e["pair"]["last_like_a"]], ran[e["pair"]["first_like_b"]]
            assert differs(m, a["values"][m], b["values"][m])
            assert not differs(m, a["values"][m], ran["3.16.0"]["values"][m])
    assert json.loads((out / "results.json").read_text()) == res
    assert (out / "report.html").read_text().startswith("<!doctype html>")


@pytest.mark.slow
def test_a_real_move_over_three_releases_is_found_attributed_and_kept(tmp_path: Path) -> None:
    """The stranger's Group II top at 1 ms: t_invert moves between MuJoCo 3.10.0 and 3.11.0.

    Measured while writing the guide (docs/guide/catching-a-change.md): 3.654 s on 3.10.0,
    3.356 s on 3.11.0 and after, a 0.30-s move against the nightly's 0.1-s tolerance, and
    under Euler or RK4 the two releases agree. Over 3.10.0, 3.11.0, 3.12.0 the search must run
    all three, name the pair (3.10.0, 3.11.0), attribute the move to implicitfast, and append
    every run to the history, where ``tippetop history`` finds them.
    """
    model = Path(__file__).resolve().parents[1] / "data" / "stranger" / \
        "group2_mu1_implicitfast.xml"
    hist = tmp_path / "h.sqlite"
    done = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "bisect", str(model),
                           "--between", "3.10.0", "3.12.0", "--metric", "t_invert",
                           "--set", "mujoco.timestep_s=0.001", "--history", str(hist),
                           "--json"], capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stderr
    res = json.loads(done.stdout)
    assert res["releases"] == ["3.10.0", "3.11.0", "3.12.0"] and res["runs"] == 3
    e = res["by_metric"]["t_invert"]
    assert e["moved"] and e["pair"] == {"last_like_a": "3.10.0", "first_like_b": "3.11.0"}
    a, b = e["values"]
    assert differs("t_invert", a, b) and a > b  # turns over later on 3.10.0
    assert "implicitfast" in e["attribution"]["follows"]
    assert not e["moves_more_than_once"]
    assert res["history"]["run"] is not None and res["history"]["error"] is None
    shown = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "history",
                            "--history", str(hist), "--metric", "t_invert", "--json"],
                           capture_output=True, text=True, timeout=300)
    assert shown.returncode == 0, shown.stderr
    series = json.loads(shown.stdout)["series"]
    engines = {s["engine"] for s in series}
    assert {"mujoco==3.10.0", "mujoco==3.11.0", "mujoco==3.12.0"} <= engines, engines
