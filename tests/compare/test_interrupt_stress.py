"""Ctrl-C at 20 random moments of a quick nightly: every run ends in time, nothing is lost.

Issue 43: Ctrl-C to a quick nightly hung in 2 of 42 tries on a loaded machine. Here the quick
profile's reference runs (``--engines ode``, about 30 s on 2 cores) are interrupted at 20
moments drawn uniformly over a clean run's length (seeded: the same moments every time), each
in a fresh process group sharing one cache and one history, as a person pressing Ctrl-C at a
terminal would. Each run must end (no process of its group left) within ``STOP_S`` of the
signal, with 130, or with the nightly's own status when the signal came after its folder was
in place; its output folder is complete (results.json, report.html) or absent, with no staging
folder beside it. A run afterwards, on each cache and history the interrupted runs left, must
give the same results.json as a run on a fresh cache (tests/stored/outputs.py's comparison:
keys and words exactly, numbers to 1e-4; clocks and paths left out), and the history must
read.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import session_processes
from tests.stored.outputs import normalised, same
from tippetop.reference_ode import NUMBA_CACHE_DIR

#: From the signal to no process of the group left (s): the exit's bound (3 s) and the
#: runs' stopping, on a loaded machine (the signal tests' limit, test_faults_signals.py).
STOP_S = 5.0
#: How many moments.
MOMENTS = 20
ARGS = ["nightly", "--profile", "quick", "--engines", "ode", "--no-baseline"]


def _env(cache: Path) -> dict[str, str]:
    env = {**os.environ, "TIPPETOP_CACHE": str(cache)}
    if NUMBA_CACHE_DIR is not None:  # this session's compiled code: no compiling
        env["NUMBA_CACHE_DIR"] = str(NUMBA_CACHE_DIR)
    return env


def _run(out: Path, cache: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *ARGS, "--out",
                           str(out)], capture_output=True, text=True, env=_env(cache),
                          timeout=1200)


def _alive(sid: int) -> dict[int, tuple[int, str]]:
    return {pid: ps for pid, ps in session_processes(sid).items() if ps[1] != "Z"}


def _results(out: Path) -> dict:
    data = json.loads((out / "results.json").read_text())
    data.pop("environment", None)  # the machine, its packages and the commit
    for key in ("run", "file"):  # its number in the history (how many ran before), and where
        data.get("history", {}).pop(key, None)
    return normalised(data, [str(out), str(out.parent)])  # the folder's own name too


def _interrupt_at(moment: float, out: Path, cache: Path) -> tuple[int, float, str]:
    """A nightly into ``out`` on ``cache``, Ctrl-C to its group after ``moment`` s: (its exit
    status, seconds from the signal to no process of the group left, its stderr)."""
    proc = subprocess.Popen([sys.executable, "-m", "tippetop.compare.cli", *ARGS, "--out",
                             str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=_env(cache), start_new_session=True)
    time.sleep(moment)
    signalled = time.monotonic()
    try:
        os.killpg(proc.pid, signal.SIGINT)
    except ProcessLookupError:  # it had finished
        pass
    while (proc.poll() is None or _alive(proc.pid)) \
            and time.monotonic() - signalled < STOP_S + 60:
        time.sleep(0.05)
    took = time.monotonic() - signalled
    left = _alive(proc.pid)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    _, stderr = proc.communicate(timeout=60)
    assert not left, f"moment {moment:.1f} s: still running after {took:.1f} s: {left}"
    return proc.returncode, took, stderr


@pytest.mark.slow
def test_ctrl_c_at_random_moments_of_a_quick_nightly(tmp_path: Path) -> None:
    """Half the moments on a cache that starts empty and fills as the interrupted runs write
    to it (drawn over a run's length on an empty cache), half on the clean run's cache, where
    every run is cached (drawn over a run's length there, shorter): so that most signals meet
    a run going, in its runs and in the writing of its outputs alike."""
    t0 = time.monotonic()
    clean = _run(tmp_path / "clean", tmp_path / "clean-cache")
    length_s = {"filling": time.monotonic() - t0}
    assert clean.returncode in (0, 1), clean.stderr[-2000:]
    t0 = time.monotonic()
    warm = _run(tmp_path / "warm", tmp_path / "clean-cache")
    length_s["warm"] = time.monotonic() - t0
    assert warm.returncode == clean.returncode, warm.stderr[-2000:]
    caches = {"filling": tmp_path / "cache", "warm": tmp_path / "clean-cache"}

    rng = random.Random(43)
    ends = []
    for i in range(MOMENTS):
        kind = ("filling", "warm")[i % 2]
        out = tmp_path / f"run{i}"
        moment = rng.uniform(0.0, length_s[kind])
        code, took, stderr = _interrupt_at(moment, out, caches[kind])
        ends.append((kind, round(moment, 1), code, round(took, 2)))
        assert took < STOP_S, f"moment {moment:.1f} s: ended {took:.1f} s after Ctrl-C"
        assert "Traceback" not in stderr and "Exception ignored" not in stderr, stderr
        if code == 130:
            assert stderr.strip().splitlines()[-1] == "tippetop: interrupted", stderr
            assert not out.exists() or (out / "results.json").is_file()
        else:  # the signal came once its folder was in place: the nightly's own status
            assert code in (0, 1), (moment, code, stderr[-2000:])
            assert (out / "results.json").is_file() and (out / "report.html").is_file()
        staged = [p.name for p in tmp_path.iterdir() if p.name.startswith(f".run{i}.")]
        assert not staged, staged
    print("lengths (s):", length_s, "(cache, moment s, exit status, seconds to end):", ends)
    assert sum(code == 130 for _, _, code, _ in ends) >= MOMENTS // 2  # most met a run going

    for kind, cache in caches.items():  # what the interrupted runs left gives the same results
        again = _run(tmp_path / f"again-{kind}", cache)
        assert again.returncode == clean.returncode, again.stderr[-2000:]
        assert same(_results(tmp_path / "clean"), _results(tmp_path / f"again-{kind}")) == []
        history = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "history"],
                                 capture_output=True, text=True, env=_env(cache), timeout=300)
        assert history.returncode == 0 and "Traceback" not in history.stderr, history.stderr
