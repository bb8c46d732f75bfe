"""Data loss and silent corruption (issue 13): a full disk under ``render``, two nightlies into
one folder, a missing baseline, and a cache entry that was edited.

Every run here is tiny (a 0.05-0.2 s reference run, a few 96x64 frames), so each test takes a
few seconds at most.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pandas as pd
import pytest

from tippetop.compare import cli
from tippetop.compare.commands import nightly as nightly_command
from tippetop.compare.running.io import lock_path, locked_output_dir
from tippetop.compare.running.runner import ResultCache, Task, TaskResult, run_tasks
from tippetop.models.errors import TippetopError

TINY = """
[profiles.tiny]
description = "test profile: one very short ODE run"

[[case]]
name = "fig3-tiny"
category = "paper"
kind = "run"
scene = "fig3"
set = ["run.t_end_s=0.05"]
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["theta_asymp", "J_rel_drift"]
"""


def run_nightly(*args: str) -> tuple[int, str, str]:
    """``tippetop nightly ARGS`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = nightly_command.main(list(args))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def tiny(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, Path]:
    """The one-case catalogue, an empty baseline folder and a private run cache."""
    cat = tmp_path / "tiny.toml"
    cat.write_text(TINY)
    (tmp_path / "baselines").mkdir()
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    return {"catalogue": cat, "baselines": tmp_path / "baselines", "root": tmp_path}


def _args(t: dict[str, Path], out: Path, *extra: str) -> list[str]:
    return ["--catalogue", str(t["catalogue"]), "--profile", "tiny", "--engines", "ode",
            "--baseline", str(t["baselines"]), "--out", str(out), "--workers", "1", *extra]


# ---------------------------------------------------------------- the output folder's lock
def _hold_lock(out: Path) -> subprocess.Popen[str]:
    """Another process holding ``out``'s lock (as a running command does) until its stdin
    closes; returned once it holds it."""
    holder = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(f"""
            import sys
            from tippetop.compare.running.io import locked_output_dir
            with locked_output_dir({str(out)!r}):
                print("locked", flush=True)
                sys.stdin.read()
            """)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
    return holder


def test_lock_helper_refuses_a_second_holder_and_names_the_pid(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with locked_output_dir(out) as lock:
        assert lock == lock_path(out) and lock.parent == tmp_path  # beside: out stays absent
        assert lock.read_text().strip() == str(os.getpid())
        assert not out.exists()
        with pytest.raises(TippetopError) as info, locked_output_dir(out):
            pass
        msg = str(info.value)
        assert "\n" not in msg and str(out) in msg and f"pid {os.getpid()}" in msg
    assert not lock.exists()  # released and removed
    with locked_output_dir(out):  # free again
        pass


def test_second_nightly_into_a_locked_folder_exits_2_and_leaves_it_alone(
        tiny: dict[str, Path], tmp_path: Path) -> None:
    """Another process holds the folder's lock (as a running nightly does): refused, exit 2."""
    out = tmp_path / "out"
    holder = _hold_lock(out)
    try:
        code, stdout, err = run_nightly(*_args(tiny, out, "--no-baseline"))
        assert code == 2, stdout + err
        assert err.count("\n") == 1 and err.startswith("tippetop: error: --out:"), err
        assert str(out) in err and f"pid {holder.pid}" in err, err
        assert not out.exists()
    finally:
        holder.communicate("", timeout=30)
    assert holder.returncode == 0
    # the lock is gone with its holder: the same command now runs
    code, stdout, err = run_nightly(*_args(tiny, out, "--no-baseline"))
    assert code == 0, stdout + err
    assert not lock_path(out).exists()


# ---------------------------------------------------------------- a missing baseline
def test_missing_baseline_file_exits_2(tiny: dict[str, Path], tmp_path: Path) -> None:
    code, out, err = run_nightly(*_args(tiny, tmp_path / "out"))
    assert code == 2, out + err
    assert err.count("\n") == 1 and "--baseline" in err and "tiny.json" in err, err
    assert "--no-baseline" in err
    assert not (tmp_path / "out").exists()


def test_no_baseline_runs_with_every_check_new(tiny: dict[str, Path], tmp_path: Path) -> None:
    code, out, err = run_nightly(*_args(tiny, tmp_path / "out", "--no-baseline"))
    assert code == 0, out + err
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert res["no_baseline"] is True
    assert res["counts"]["checks_new"] == 2 and res["counts"]["checks_pass"] == 0
    assert "--no-baseline" in out and "every check is new" in out
    assert not (tiny["baselines"] / "tiny.json").exists()  # nothing written
    # --no-baseline ignores an existing file too, and refuses --update-baseline
    code, out, err = run_nightly(*_args(tiny, tmp_path / "o2", "--no-baseline",
                                        "--update-baseline"))
    assert code == 2 and err.count("\n") == 1 and "--no-baseline" in err, err


def test_update_baseline_still_creates_a_missing_file(tiny: dict[str, Path],
                                                      tmp_path: Path) -> None:
    code, out, err = run_nightly(*_args(tiny, tmp_path / "out", "--update-baseline"))
    assert code == 0, out + err
    assert (tiny["baselines"] / "tiny.json").is_file()
    code, out, err = run_nightly(*_args(tiny, tmp_path / "o2"))
    assert code == 0, out + err
    res = json.loads((tmp_path / "o2" / "results.json").read_text())
    assert res["counts"]["checks_pass"] == 2 and res["counts"]["checks_new"] == 0


def test_no_baseline_help_says_its_default() -> None:
    out = subprocess.run([sys.executable, "-m", "tippetop.compare", "nightly", "--help"],
                         capture_output=True, text=True, timeout=60).stdout
    flat = " ".join(out.split())
    assert "--no-baseline run with no baseline on purpose" in flat
    assert "(default: off; a missing baseline file is an error, exit 2)" in flat


# ---------------------------------------------------------------- render on a full disk
RENDER = ["render", "fig3", "--engine", "ode", "--set", "run.t_end_s=0.2", "--speed", "1",
          "--fps", "20", "--size", "96x64"]


@pytest.fixture
def good_video(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A good 5-frame video at ``tmp_path/v.mp4``, made by the command itself."""
    from tippetop.mujoco_runner import gl

    monkeypatch.setenv("MUJOCO_GL", gl.choose_gl_backend())
    monkeypatch.chdir(tmp_path)
    assert cli.main([*RENDER, "--out", "v.mp4"]) == 0
    return tmp_path / "v.mp4"


def _fails_and_keeps(good: Path, capsys: pytest.CaptureFixture[str], says: str) -> None:
    before = good.read_bytes()
    capsys.readouterr()
    assert cli.main([*RENDER, "--out", good.name, "--force"]) == 1
    out, err = capsys.readouterr()
    last = err.splitlines()[-1]
    assert "wrote" not in out and err.count("tippetop:") == 1, err
    assert last.startswith("tippetop: video failed: could not write v.mp4: "), err
    assert says in last and last.endswith("v.mp4 left as it was"), err
    assert good.read_bytes() == before  # the old video is intact
    assert sorted(p.name for p in good.parent.iterdir()) == ["v.mp4"]  # no temporary left
    assert iio.imread(good, index=None, plugin="FFMPEG").shape == (5, 64, 96, 3)


def test_disk_full_midway_keeps_the_old_video_and_exits_1(
        good_video: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from tippetop.mujoco_runner import mp4

    real_write = mp4.Mp4Writer.write
    written = []

    def write(self: mp4.Mp4Writer, rgb: np.ndarray) -> None:
        if len(written) == 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        written.append(1)
        real_write(self, rgb)

    monkeypatch.setattr(mp4.Mp4Writer, "write", write)
    _fails_and_keeps(good_video, capsys, "No space left on device")


def test_truncated_video_is_never_put_in_place(
        good_video: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The encoder reports success but the file is cut short (a full disk that ffmpeg did not
    notice): the check after writing catches it before anything is replaced."""
    from tippetop.mujoco_runner import video

    real = video.write_video

    def write_truncated(path: Path, *args: object, **kwargs: object) -> video.VideoStats:
        stats = real(path, *args, **kwargs)
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
        return stats

    monkeypatch.setattr(video, "write_video", write_truncated)
    _fails_and_keeps(good_video, capsys, "the file does not decode (")


def test_video_with_too_few_frames_is_refused(good_video: Path) -> None:
    from tippetop.mujoco_runner import video

    video.verify_video(good_video, 5, 96, 64)
    with pytest.raises(video.VideoCheckFailed, match="expected 6 frames, decoded 5"):
        video.verify_video(good_video, 6, 96, 64)
    with pytest.raises(video.VideoCheckFailed, match="expected frames of 64x96"):
        video.verify_video(good_video, 5, 64, 96)


# ---------------------------------------------------------------- cache entries that lie
def _tiny_task() -> Task:
    return Task("fig3", ("run.t_end_s=0.05",), "ode")


def _entry_paths(cache: Path, key: str) -> tuple[Path, Path]:
    return cache / key[:2] / f"{key}.json", cache / key[:2] / f"{key}.parquet"


@pytest.fixture
def fresh(tmp_path: Path) -> TaskResult:
    """One tiny reference run, computed and cached in ``tmp_path/cache``."""
    res = run_tasks([_tiny_task()], workers=1, cache_dir=tmp_path / "cache")[0]
    assert res.error is None and not res.cached
    again = run_tasks([_tiny_task()], workers=1, cache_dir=tmp_path / "cache")[0]
    assert again.cached and again.summary == res.summary  # a verified entry is served
    return res


def _same(a: TaskResult, b: TaskResult) -> None:
    assert a.summary is not None and b.summary is not None
    drop = {"wall_s"}  # the one thing a rerun may change
    assert {k: v for k, v in a.summary.items() if k not in drop} == \
        {k: v for k, v in b.summary.items() if k not in drop}
    pd.testing.assert_frame_equal(a.table, b.table)


def test_edited_number_in_a_cache_entry_is_recomputed(fresh: TaskResult,
                                                      tmp_path: Path) -> None:
    js, _ = _entry_paths(tmp_path / "cache", fresh.key)
    entry = json.loads(js.read_text())
    assert entry["key"] == fresh.key and len(entry["summary_sha256"]) == 64
    entry["summary"]["theta_final"] += 0.5  # the checksums left as they were
    js.write_text(json.dumps(entry))
    res = run_tasks([_tiny_task()], workers=1, cache_dir=tmp_path / "cache")[0]
    assert not res.cached
    _same(res, fresh)
    assert json.loads(js.read_text())["summary"]["theta_final"] == fresh.summary["theta_final"]
    assert run_tasks([_tiny_task()], workers=1, cache_dir=tmp_path / "cache")[0].cached


def test_edited_table_in_a_cache_entry_is_recomputed(fresh: TaskResult,
                                                     tmp_path: Path) -> None:
    _, pq = _entry_paths(tmp_path / "cache", fresh.key)
    table = pd.read_parquet(pq)
    table.loc[len(table) // 2, "theta"] += 0.5
    table.to_parquet(pq, index=False)
    res = run_tasks([_tiny_task()], workers=1, cache_dir=tmp_path / "cache")[0]
    assert not res.cached
    _same(res, fresh)


@pytest.mark.parametrize("text", ["{}", "[]", "null", '"x"', "3", '{"summary": []}', "{",
                                  "\udcff"])
def test_cache_entry_of_the_wrong_shape_is_recomputed(text: str, fresh: TaskResult,
                                                      tmp_path: Path) -> None:
    js, _ = _entry_paths(tmp_path / "cache", fresh.key)
    js.write_bytes(text.encode("utf-8", "surrogateescape"))
    res = run_tasks([_tiny_task()], workers=1, cache_dir=tmp_path / "cache")[0]
    assert not res.cached
    _same(res, fresh)


def test_old_entry_without_checksums_or_for_another_key_is_recomputed(
        fresh: TaskResult, tmp_path: Path) -> None:
    js, _ = _entry_paths(tmp_path / "cache", fresh.key)
    entry = json.loads(js.read_text())
    js.write_text(json.dumps(entry["summary"]))  # the format before checksums: the bare summary
    assert ResultCache(tmp_path / "cache").get(fresh.key) is None
    js.write_text(json.dumps({**entry, "key": "0" * 64}))  # vouches for another key
    assert ResultCache(tmp_path / "cache").get(fresh.key) is None
    js.write_text(json.dumps(entry))
    assert ResultCache(tmp_path / "cache").get(fresh.key) is not None
    js.write_text(json.dumps(entry["summary"]))
    res = run_tasks([_tiny_task()], workers=1, cache_dir=tmp_path / "cache")[0]
    assert not res.cached
    _same(res, fresh)


@pytest.mark.parametrize("command", [
    ("atlas", "--engines", "ode", "--A-over-C", "1:1:1", "--a-over-R", "0.1:0.1:1"),
    ("threshold", "--which", "n1"),
    ("sweep", "fig3", "--n0", "40:50:10", "--engines", "ode"),
    ("validate", str(Path(__file__).resolve().parents[2] / "examples"
                     / "paper_loaded_sphere.xml")),
])
def test_every_out_folder_is_locked_while_a_command_writes_it(
        tmp_path: Path, command: tuple[str, ...]) -> None:
    """A second command into a folder another run holds is refused at its start (exit 2,
    one line naming the holder), before any run: its files are never mixed into the first's."""
    out = tmp_path / "out"
    holder = _hold_lock(out)
    try:
        r = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *command, "--out",
                            str(out)], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2, r.stderr
        assert r.stderr.count("\n") == 1 and f"pid {holder.pid}" in r.stderr, r.stderr
        assert not out.exists()
    finally:
        holder.communicate("", timeout=30)


def test_a_nightly_stopped_while_writing_leaves_no_folder(
        tiny: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C while the nightly writes its folder (here: during the report): no --out folder,
    no staging folder, no lock file; the same command then runs without --force."""
    from tippetop.compare.report import build as report_build

    def interrupted(*a: object, **k: object) -> None:
        raise KeyboardInterrupt

    out = tmp_path / "out"
    monkeypatch.setattr(report_build, "build_report", interrupted)
    code, _, err = run_nightly(*_args(tiny, out, "--no-baseline"))
    assert code == 130 and err.splitlines()[-1] == "tippetop: interrupted", err
    assert not out.exists()
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".out")]
    monkeypatch.undo()
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    code, stdout, err = run_nightly(*_args(tiny, out, "--no-baseline"))
    assert code == 0, stdout + err
    assert (out / "report.html").is_file() and (out / "results.json").is_file()


def test_a_cache_entry_reads_back_as_written(tmp_path: Path) -> None:
    """The table comes back exactly as stored (Parquet keeps float64 bits), read by Arrow from
    memory of its own (:func:`~tippetop.compare.running.cache.read_parquet_bytes`), not from
    the Python bytes: an Arrow thread releasing a Python buffer after the interpreter began
    to exit aborted a complete ``tippetop compare`` (exit 134, in CI and 3 of 150 runs here)."""
    import numpy as np
    import pandas as pd

    from tippetop.compare.running.cache import read_parquet_bytes

    rng = np.random.default_rng(3)
    table = pd.DataFrame(rng.standard_normal((257, 6)), columns=list("abcdef"))
    table["a"] = np.where(rng.random(257) < 0.1, np.nan, table["a"])
    cache = ResultCache(tmp_path / "c")
    cache.put("ab" * 12, {"status": "ok"}, table)
    _js, pq = cache._paths("ab" * 12)
    data = pq.read_bytes()
    back = read_parquet_bytes(data)
    pd.testing.assert_frame_equal(back, table, check_exact=True)
    pd.testing.assert_frame_equal(back, pd.read_parquet(pq), check_exact=True)
