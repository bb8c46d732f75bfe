"""A plan run by the worker in another Python is the in-process run; a broken worker is one
failed run with its reason.

The worker (the folder ``mujoco_runner/worker/``, started by path) needs nothing but ``mujoco``
and ``numpy``: it steps from Python one step at a time (``mj_step`` taken apart, each step's
forward pass added to its sample's window by ``worker.windows.WindowAccumulator``) with paper
mode's law as a Python passive callback, where an in-process run steps in the compiled loop
(its windows added by compiled code) with the compiled callback. In this very interpreter (the
same MuJoCo) both make the same C calls on the same states, so the states are compared bit for
bit and the windows' integers exactly, their floats to rounding: native and paper mode, RK4 and
Euler, a stem the law also acts at, a file's keyframe as the start.
"""

from __future__ import annotations

import ast
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import mujoco_plan
from tippetop.mujoco_runner import remote
from tippetop.mujoco_runner.model import MUJOCO_WARNINGS
from tippetop.mujoco_runner.results import MujocoResult
from tippetop.mujoco_runner.run import simulate_plan
from tippetop.mujoco_runner.worker.windows import FLOAT_FIELDS

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")
#: The table's columns made from the windows' floats (the rest are the states').
WINDOW_COLUMNS = ("N", "P_fric", "FX", "FY")
#: How far apart a window's float may be in the two loops, relative to its column's largest
#: value. Both add the same passes (the same C calls: ``mj_contactForce``, the law's output)
#: with the same products written out in the same order, so they are equal (measured: 0
#: apart in every case here); a compiler that fused or reordered the compiled loop's
#: arithmetic would move each pass's terms by a few ulps (1e-16 relative), summed over a
#: window's few passes. 1e-12 is four orders above that and still far below what a
#: different pass would change (a step or a contact apart moves them by 1e-6 and more).
ROUNDING = 1e-12


def assert_same_windows(there: MujocoResult, alone: MujocoResult) -> None:
    """The windows of two runs of one plan: integers equal, floats to :data:`ROUNDING`."""
    a, b = there.windows, alone.windows
    assert len(a) == len(b) >= 1
    np.testing.assert_array_equal(a.ints, b.ints)
    assert np.array_equal(np.isfinite(a.floats), np.isfinite(b.floats))
    finite = np.isfinite(b.floats)
    scale = np.nanmax(np.where(finite, np.abs(b.floats), np.nan), axis=0, initial=0.0)
    gap = np.where(finite, np.abs(a.floats - np.where(finite, b.floats, 0.0)), 0.0)
    assert np.array_equal(a.floats[~finite], b.floats[~finite])  # -inf: none, the same
    for k, name in enumerate(FLOAT_FIELDS):
        assert gap[:, k].max() <= ROUNDING * scale[k], (name, gap[:, k].max(), scale[k])


def assert_same_tables(there: MujocoResult, alone: MujocoResult) -> None:
    """The states' columns bit for bit, the windows' to :data:`ROUNDING` of their scale."""
    assert list(there.table.columns) == list(alone.table.columns)
    for name in there.table.columns:
        x, y = there.table[name].to_numpy(), alone.table[name].to_numpy()
        if name in WINDOW_COLUMNS:
            np.testing.assert_allclose(x, y, rtol=0.0,
                                       atol=ROUNDING * max(float(np.abs(y).max()), 1e-300))
        else:
            assert x.tobytes() == y.tobytes(), name


@pytest.mark.parametrize("over", [
    ("mujoco.friction=native",),
    ("mujoco.friction=paper",),
    ("mujoco.friction=paper", "friction.law='coulomb_viscous'", "mujoco.timestep_s=1e-5"),
    (f"top.mjcf={str(ROOT / 'examples' / 'capsule_stem_top.xml')!r}", "mujoco.friction=paper",
     "mujoco.timestep_s=2e-4", "init.theta0=2.0", "init.n0=60.0"),
    (f"top.mjcf={str(ROOT / 'examples' / 'cylinder_stem_ballast.xml')!r}",),
], ids=["native", "paper", "coulomb-viscous", "paper-stem", "keyframe"])
def test_a_worker_in_this_python_is_the_in_process_run(over: tuple[str, ...]) -> None:
    plan = mujoco_plan("run.t_end_s=0.3", *over)
    alone = simulate_plan(plan)
    reported: list[float] = []
    there, info = remote.simulate_in(sys.executable, plan, progress=reported.append)
    assert info.version == alone_version() and info.path == "plain loop"
    assert there.status == alone.status and there.n_steps == alone.n_steps
    assert there.message.split(" in ")[0] == alone.message.split(" in ")[0]
    assert there.ran == alone.ran
    assert_same_tables(there, alone)
    assert_same_windows(there, alone)
    assert there.contacts.tobytes() == alone.contacts.tobytes()
    assert reported and reported[-1] == pytest.approx(0.3)
    if "init.theta0=2.0" in over:  # turned over far enough: the stem touches, the law acts there
        assert there.t_stem is not None


@pytest.mark.parametrize("integrator", ["RK4", "Euler"])
@pytest.mark.parametrize("friction", ["native", "paper"])
def test_a_worker_in_this_python_has_the_in_process_windows(friction: str,
                                                            integrator: str) -> None:
    """Every step's pass in the worker's Python loop and in the compiled loop: the same windows.

    0.5 s of the Fig. 3 top (2,500 steps, 501 windows of 5 passes) from the harness's
    in-process run and from a worker in this very Python; the windows touch, the ball's gaps,
    the forces and the slip vary (a run whose windows were all alike could not tell a pass
    apart).
    """
    plan = mujoco_plan("run.t_end_s=0.5", f"mujoco.friction={friction!r}",
                       f"mujoco.integrator={integrator!r}")
    alone = simulate_plan(plan)
    there, _ = remote.simulate_in(sys.executable, plan)
    assert alone.engine["path"] == "compiled stepper" and there.engine["path"] == \
        "worker: plain loop"
    assert there.status == alone.status == "ok"
    assert_same_windows(there, alone)
    assert_same_tables(there, alone)
    w = alone.windows
    assert (w.int_column("passes")[1:] == plan.steps_per_sample).all()
    assert w.int_column("touch_passes").sum() > 0
    # the columns vary from window to window, so comparing them (every float column, in
    # assert_same_windows) tells passes apart: the contact's own friction power in native
    # mode; in paper mode (a frictionless contact) the law's, the Python callback's there and
    # the compiled one's here
    varied = ("n_sum", "gap_max", "gap_min", "slip_nx_sum", "slip_ny_sum") + (
        ("power_sum",) if friction == "native" else ("law_power_sum",))
    for name in varied:
        assert np.ptp(w.float_column(name)) > 0.0, name


def test_a_worker_steps_mj_step_whole_as_the_in_process_run(tmp_path: Path) -> None:
    """Where ``mj_step`` does more after its forward pass (here the forward-inverse
    comparison, an MJCF's flag), both call it whole and add its pass after it, with the
    motion before the step and the start's pass once (row 1 one pass short): the same
    windows, every column (the power and the slip read with the motion after the step
    would be 1e-3 apart here)."""
    import mujoco

    from tippetop.mujoco_runner.settings import build_model
    from tippetop.mujoco_runner.worker.windows import integrator_call

    text = (ROOT / "examples" / "capsule_stem_top.xml").read_text()
    option = '<option timestep="0.0005"/>'
    assert text.count(option) == 1
    path = tmp_path / "fwdinv.xml"
    path.write_text(text.replace(option, '<option timestep="0.0005"><flag fwdinv="enable"/>'
                                         '</option>'))
    plan = mujoco_plan(f"top.mjcf={str(path)!r}", "run.t_end_s=0.3")
    assert integrator_call(mujoco, build_model(plan).model) is None  # whole mj_step calls
    alone = simulate_plan(plan)
    there, _ = remote.simulate_in(sys.executable, plan)
    assert there.status == alone.status == "ok"
    assert_same_tables(there, alone)
    assert_same_windows(there, alone)
    steps = plan.steps_per_sample
    assert steps > 1 and list(there.windows.int_column("passes")[:3]) == [1, steps - 1, steps]
    assert np.abs(there.windows.float_column("slip_ny_sum")).max() > 0.0


def alone_version() -> str:
    import mujoco

    return mujoco.__version__


def test_a_diverging_run_fails_there_as_here(tmp_path: Path, monkeypatch) -> None:
    # MuJoCo's default handler would append its warnings to ./MUJOCO_LOG.TXT
    monkeypatch.chdir(tmp_path)
    plan = mujoco_plan("mujoco.friction=paper", "effects.sliding=false", "init.n0=1e11",
                       "run.t_end_s=0.1")
    # the worker first, with no warning kept here: its message quotes MuJoCo's text from there
    MUJOCO_WARNINGS.clear()
    there, _ = remote.simulate_in(sys.executable, plan)
    alone = simulate_plan(plan)
    assert alone.status == there.status == "diverged"
    assert "mjWARN_BADQVEL" in there.message and "Nan, Inf or huge value" in there.message
    assert there.message == alone.message
    assert_same_tables(there, alone)
    assert_same_windows(there, alone)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def _fake(tmp_path: Path, body: str) -> str:
    path = tmp_path / "python"
    path.write_text("#!/bin/sh\n" + body + "\n")
    path.chmod(0o755)
    return str(path)


@pytest.mark.parametrize(("body", "says"), [
    ("echo 'Traceback (most recent call last):' >&2; echo 'Segmentation fault' >&2; exit 139",
     "ended without its reply (exit status 139; last output: Segmentation fault)"),
    ("echo '{\"half a line'", "ended without its reply (no reply on its last line; last "
     "output: {\"half a line)"),
    ("echo 'hello'; echo '[1, 2]'", "ended without its reply"),
    ("echo '{\"status\": \"error\", \"message\": \"no GPU here\"}'", "failed: no GPU here"),
    ("echo '{\"status\": \"ok\", \"wall_s\": 1, \"ran\": {}}'", "wrote no readable results"),
    ("python3 -c \"import sys, zipfile, json; o = json.loads(sys.stdin.readline())['out']; "
     "zipfile.ZipFile(o, 'w').close()\"; echo '{\"status\": \"ok\", \"wall_s\": 1}'",
     "wrote results without qacc_warmstart, qfrc_constraint, qpos, qvel, time, warnings, "
     "windows_float, windows_int"),
], ids=["crash", "cut-off", "garbage", "error", "no-results", "no-windows"])
def test_a_broken_worker_is_one_failed_run_with_its_reason(tmp_path: Path, body: str,
                                                           says: str) -> None:
    plan = mujoco_plan("run.t_end_s=0.01")
    with pytest.raises(remote.WorkerFailed) as info:
        remote.simulate_in(_fake(tmp_path, body), plan)
    assert says in str(info.value) and "\n" not in str(info.value)


def test_a_hung_worker_is_stopped_at_its_budget(tmp_path: Path) -> None:
    import time

    plan = mujoco_plan("run.t_end_s=0.01")
    t0 = time.monotonic()
    with pytest.raises(remote.WorkerFailed, match="longer than its budget of 1 s"):
        remote.simulate_in(_fake(tmp_path, "sleep 60"), plan, budget_s=1.0)
    assert time.monotonic() - t0 < 10


def test_a_python_without_mujoco_says_so(tmp_path: Path) -> None:
    plan = mujoco_plan("run.t_end_s=0.01")
    python = "/usr/bin/python3" if Path("/usr/bin/python3").exists() else None
    if python is None:  # pragma: no cover - every Debian has one
        pytest.skip("no system Python")
    with pytest.raises(remote.WorkerFailed, match=r"expected mujoco and numpy in .*, got "
                       "ImportError"):
        remote.simulate_in(python, plan)
    with pytest.raises(remote.WorkerFailed, match="could not start"):
        remote.simulate_in(str(tmp_path / "no-such-python"), plan)


def test_the_worker_imports_nothing_but_mujoco_numpy_and_the_standard_library() -> None:
    files = sorted(remote.WORKER.glob("*.py"))
    own = {p.stem for p in files}
    assert {"__init__", "__main__"} <= own
    for path in files:
        tree = ast.parse(path.read_text())
        names = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level:  # its own files alone
                targets = {node.module} if node.module else {a.name for a in node.names}
                assert node.level == 1 and targets <= own, (path.name, node.module)
            elif isinstance(node, ast.ImportFrom):
                names.add((node.module or "").split(".")[0])
        assert names <= {"__future__", "contextlib", "importlib", "json", "math", "os", "sys",
                         "time", "traceback", "types", "typing", "mujoco", "numpy", "jax",
                         "warp", "mujoco_warp"}, (path.name, names)
        # MJX's and Warp's packages only where those engines run (a plain MuJoCo needs neither)
        top = {a.name.split(".")[0] for node in tree.body if isinstance(node, ast.Import)
               for a in node.names}
        top |= {(node.module or "").split(".")[0] for node in tree.body
                if isinstance(node, ast.ImportFrom) and not node.level}
        assert not top & {"mujoco", "numpy", "jax", "warp", "mujoco_warp"}, (path.name, top)


def test_the_worker_modules_shadow_nothing_it_imports() -> None:
    """Its modules are reached through its package alone (off ``sys.path`` when run by path);
    even so none is named like a module of the standard library or of the engines' packages."""
    own = {p.stem for p in remote.WORKER.glob("*.py")} - {"__init__", "__main__"}
    assert own == {"protocol", "serve", "paper_law", "mjx_stepper", "warp_stepper", "windows",
                   "probe_steps"}
    assert not own & (set(sys.stdlib_module_names) | {"mujoco", "numpy", "jax", "jaxlib",
                                                       "warp", "mujoco_warp", "glfw"})


def _python_without_tippetop(root: Path) -> tuple[str, Path]:
    """A Python that imports this one's ``mujoco`` and ``numpy`` (and what they import) but not
    tippetop: a virtual environment without pip whose ``.pth`` names a folder of links to those
    packages alone. Returns its interpreter and that folder."""
    import subprocess
    import venv

    import mujoco
    import numpy

    lean = root / "lean-site"
    lean.mkdir()
    site = Path(mujoco.__file__).parents[1]
    assert Path(numpy.__file__).parents[1] == site
    for entry in site.iterdir():  # the packages, their .libs and .dist-info folders
        if entry.name.lower().startswith(("mujoco", "numpy", "glfw")):
            (lean / entry.name).symlink_to(entry)
    venv.create(root / "venv", with_pip=False, symlinks=True)
    python = str(root / "venv" / "bin" / "python")
    purelib = subprocess.run([python, "-I", "-c", "import sysconfig; "
                              "print(sysconfig.get_path('purelib'))"], capture_output=True,
                             text=True, check=True, timeout=60).stdout.strip()
    (Path(purelib) / "lean.pth").write_text(f"{lean}\n")
    return python, lean


def test_the_worker_runs_from_its_files_alone_in_a_python_without_tippetop(
        tmp_path: Path, monkeypatch) -> None:
    """Its folder copied elsewhere and started by path, as the harness starts it, in a Python
    that cannot import tippetop, with modules of its modules' names on that Python's path: it
    answers the handshake, then runs a paper-mode plan as this process does, to the bit."""
    import json
    import shutil
    import subprocess

    python, lean = _python_without_tippetop(tmp_path)
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["MUJOCO_GL"] = "disable"
    bare = subprocess.run([python, "-I", "-c", "import mujoco, numpy, tippetop"],
                          capture_output=True, text=True, timeout=120, env=env)
    assert "No module named 'tippetop'" in bare.stderr, bare.stderr
    for name in ("protocol", "serve", "paper_law", "windows", "__main__"):  # never these
        (lean / f"{name}.py").write_text("raise SystemExit('shadowed: wrong module')\n")
    copy = tmp_path / "elsewhere" / "worker"
    shutil.copytree(remote.WORKER, copy, ignore=shutil.ignore_patterns("__pycache__"))
    said = subprocess.run([python, "-I", "-u", str(copy)], input='{"protocol": 4}\n',
                          capture_output=True, text=True, timeout=120, cwd=tmp_path, env=env)
    assert said.returncode == 0, said.stderr
    (line,) = said.stdout.splitlines()
    reply = json.loads(line)
    assert reply["protocol"] == remote.worker.PROTOCOL and reply["status"] == "error"
    assert reply["message"].startswith("ValueError: expected protocol 5, got 4")
    assert reply["executable"] == python and reply["version"] == alone_version()

    monkeypatch.setattr(remote, "WORKER", copy)
    plan = mujoco_plan("run.t_end_s=0.05", "mujoco.friction=paper")
    try:
        there, info = remote.simulate_in(python, plan, env=env)
    finally:
        remote.close_workers()
    alone = simulate_plan(plan)
    assert info.executable == python and info.path == "plain loop"
    assert there.status == alone.status == "ok" and there.ran == alone.ran
    assert_same_tables(there, alone)
    assert_same_windows(there, alone)
    assert there.contacts.tobytes() == alone.contacts.tobytes()


def test_a_worker_answers_one_request_after_another() -> None:
    """The second run in the same interpreter goes to the same worker, and is the same run.

    A worker that died between two requests is replaced; closing the workers ends them all.
    """
    import os
    import signal

    remote.close_workers()
    plan = mujoco_plan("run.t_end_s=0.05")
    first, _ = remote.simulate_in(sys.executable, plan)
    (pid,) = remote.live_workers()
    second, _ = remote.simulate_in(sys.executable, plan)
    assert remote.live_workers() == [pid]
    assert first.table.equals(second.table)
    os.kill(pid, signal.SIGKILL)
    third, _ = remote.simulate_in(sys.executable, plan)
    (new,) = remote.live_workers()
    assert new != pid and third.table.equals(first.table)
    remote.close_workers()
    assert remote.live_workers() == []


def test_no_worker_outlives_the_harness(tmp_path: Path) -> None:
    """A process that ran plans in workers and exits leaves none running (atexit)."""
    import os
    import subprocess

    code = ("import sys; from tests.conftest import mujoco_plan; "
            "from tippetop.mujoco_runner import remote; "
            "remote.simulate_in(sys.executable, mujoco_plan('run.t_end_s=0.02')); "
            "print(*remote.live_workers())")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=Path(__file__).resolve().parents[2])
    assert done.returncode == 0, done.stderr
    (pid,) = [int(p) for p in done.stdout.split()]
    import time

    for _ in range(50):  # the worker ends when its input does
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        raise AssertionError(f"worker {pid} still running after the harness exited")
