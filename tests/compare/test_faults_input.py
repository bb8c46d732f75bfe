"""Bad input and failed runs end in one line, never a traceback (tracker issue 13).

Each case runs ``python -m tippetop.compare.cli`` in a subprocess and checks the exit status
(2 for bad input, 1 for a failed run), that stderr is exactly one line starting with
``tippetop: error:`` or ``tippetop: run failed:`` with no traceback, and that no output file
was written. Every run is tiny (``run.t_end_s=0.05``) or stops before any work.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

BIG_INT = "1" + "0" * 400  # an integer no float can hold
SHORT = ("--set", "run.t_end_s=0.05")


def _run(*args: str, env: dict[str, str] | None = None, cwd: Path | None = None,
         stdout: object = subprocess.PIPE, timeout: float = 60) -> subprocess.CompletedProcess:
    """``python -m tippetop.compare.cli ARGS`` with text output captured."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args], cwd=cwd,
                          env=full_env, stdout=stdout, stderr=subprocess.PIPE, text=True,
                          timeout=timeout, check=False)


def _one_line(stderr: str, prefix: str) -> str:
    """The single line of ``stderr``, checked to start with ``prefix`` and hold no traceback."""
    assert "Traceback" not in stderr, stderr
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith(prefix), stderr
    return lines[0]


def _bad_input(*args: str, **kw: object) -> str:
    """Run, expect exit 2 and one ``tippetop: error:`` line; return the line."""
    r = _run(*args, **kw)  # type: ignore[arg-type]
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert not r.stdout, r.stdout
    return _one_line(r.stderr, "tippetop: error:")


# ---------------------------------------------------------------- numbers too large
@pytest.mark.parametrize("override, key", [
    ("init.n0=1e400", "init.n0"),
    (f"init.n0={BIG_INT}", "init.n0"),
    (f"ode.rtol={BIG_INT}", "ode.rtol"),
    ("ode.max_steps=99999999999999999999999999", "ode.max_steps"),
    (f"mujoco.solref=[{BIG_INT}, 1]", "mujoco.solref"),
])
def test_set_number_too_large(tmp_path: Path, override: str, key: str) -> None:
    out = tmp_path / "t.csv"
    line = _bad_input("simulate", "fig3", "--set", override, *SHORT, "--out", str(out))
    assert key in line
    assert not out.exists()


@pytest.mark.parametrize("digits, says", [(BIG_INT, "init.n0"),
                                          ("1" * 5000, "4300 digits")])
def test_scene_file_integer_too_large(tmp_path: Path, digits: str, says: str) -> None:
    """400 digits: no float holds it; 5000: past Python's limit on reading an integer."""
    scene = tmp_path / "big.toml"
    scene.write_text(f"[init]\nn0 = {digits}\n[run]\nt_end_s = 0.05\n")
    line = _bad_input("simulate", str(scene))
    assert says in line


def test_set_integer_past_pythons_digit_limit() -> None:
    assert "init.n0" in _bad_input("simulate", "fig3", "--set", "init.n0=" + "1" * 5000, *SHORT)


# ---------------------------------------------------------------- the nightly catalogue
@pytest.mark.parametrize("text, says", [
    ("case = 3\n[profiles.quick]\n", "case"),
    ("case = [1, 2]\n[profiles.quick]\n", "expected a table"),
    ("profiles = 3\n", "profiles"),
    ('[profiles.quick]\n[[case]]\nname = "a"\ncategory = "c"\nkind = "threshold"\n'
     'scene = "fig3"\nengines = ["ode"]\nmodes = ["paper"]\nprofiles = ["quick"]\n'
     'metrics = ["measured"]\n'
     f'which = "n1"\nmethod = "bisect"\nrel_tol = {BIG_INT}\n', "rel_tol"),
    ("[profiles.quick]\nx = " + "1" * 5000 + "\n", "4300 digits"),
])
def test_catalogue_of_the_wrong_shape(tmp_path: Path, text: str, says: str) -> None:
    cat = tmp_path / "cat.toml"
    cat.write_text(text)
    out = tmp_path / "report"
    line = _bad_input("nightly", "--catalogue", str(cat), "--out", str(out))
    assert says in line
    assert not out.exists()


# ---------------------------------------------------------------- failed reference-ODE runs
STOP_SHORT = ("--set", "ode.max_steps=10", "--set", "run.t_end_s=0.05", "--no-cache", "--workers",
              "1")


def test_failed_ode_run_prints_no_numbers(tmp_path: Path) -> None:
    """max_steps reached: null results in --json, one 'run failed' line, exit 1, no table."""
    out = tmp_path / "t.csv"
    r = _run("simulate", "fig3", *STOP_SHORT[:4], "--json", "--out", str(out))
    assert r.returncode == 1, r.stderr
    line = _one_line(r.stderr, "tippetop: run failed:")
    assert "ode.max_steps" in line
    d = json.loads(r.stdout)
    assert d["status"] == "max_steps"
    assert all(d[k] is None for k in ("theta_final", "theta_asymp", "t_invert", "J_rel_drift"))
    assert not out.exists()


def test_failed_runs_inside_compare_are_reported_per_run() -> None:
    r = _run("compare", "fig3", "--engines", "ode", "--modes", "paper,coulomb", *STOP_SHORT,
             "--json")
    assert r.returncode == 1, r.stderr
    _one_line(r.stderr, "tippetop: run failed:")
    runs = {s["run"]: s for s in json.loads(r.stdout)["runs"]}
    assert set(runs) == {"ode/paper", "ode/coulomb"}  # every run kept, each with its reason
    assert all(s["outcome"] == "failed" and s["status"] == "max_steps" and
               s["theta_asymp"] is None for s in runs.values())


def test_failed_runs_inside_sweep_are_rows(tmp_path: Path) -> None:
    r = _run("sweep", "fig3", "--n0", "50:60:10", *STOP_SHORT, "--json")
    assert r.returncode == 1, r.stderr
    _one_line(r.stderr, "tippetop: run failed:")
    rows = json.loads(r.stdout)["rows"]
    assert [row["status"] for row in rows] == ["max_steps", "max_steps"]


def test_failed_run_inside_threshold_is_a_failed_run() -> None:
    # the runs are reported (the failed ones said so), no threshold is claimed: '-'
    r = _run("threshold", "fig3", "--which", "n1", *STOP_SHORT)
    assert r.returncode == 1, r.stderr
    assert "max_steps" in _one_line(r.stderr, "tippetop: run failed:")
    measured = next(x for x in r.stdout.splitlines() if x.strip().startswith("measured"))
    assert measured.split()[1] == "-" and "failed" in r.stdout


# ---------------------------------------------------------------- command-line options
@pytest.mark.parametrize("address", ["tcp://localhost:99999", "tcp://host:notaport",
                                     "tcp://host:", "localhost:8786"])
def test_scheduler_with_a_bad_port_is_refused_before_any_work(tmp_path: Path,
                                                              address: str) -> None:
    out = tmp_path / "sweep"
    line = _bad_input("sweep", "fig3", "--n0", "50:60:10", "--scheduler", address,
                      "--out", str(out))
    assert "--scheduler" in line and address in line
    assert not out.exists()


@pytest.mark.parametrize("n", ["0", "-1"])
def test_workers_below_one_is_refused(n: str) -> None:
    assert "--workers" in _bad_input("compare", "fig3", "--workers", n)


# ---------------------------------------------------------------- stdout full or closed
THEORY = ("theory", "--A-over-C", "0.8", "--a-over-R", "0.3", "--json")


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_stdout_full_is_one_line_exit_1() -> None:
    with open("/dev/full", "w") as full:
        r = _run(*THEORY, stdout=full)
    assert r.returncode == 1
    assert "No space left" in _one_line(r.stderr, "tippetop: failed:")


def test_stdout_closed_pipe_is_one_line_exit_1() -> None:
    """The reader went away before the output (``| head -c 10`` that already exited)."""
    read, write = os.pipe()
    os.close(read)
    try:
        r = _run(*THEORY, stdout=write)
    finally:
        os.close(write)
    assert r.returncode == 1
    _one_line(r.stderr, "tippetop: failed:")


# ---------------------------------------------------------------- the cache folder
@pytest.mark.parametrize("command", [("simulate", "fig3", *SHORT),
                                     ("sweep", "fig3", "--n0", "50:60:10", *SHORT)])
def test_cache_pointing_at_a_file_is_bad_input(tmp_path: Path, command: tuple[str, ...]) -> None:
    cache = tmp_path / "cache"
    cache.write_text("not a folder")
    out = tmp_path / "out"
    line = _bad_input(*command, "--out", str(out) + (".csv" if command[0] == "simulate" else ""),
                      env={"TIPPETOP_CACHE": str(cache)})
    assert "TIPPETOP_CACHE" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache"]


# ---------------------------------------------------------------- an MJCF with timestep 0
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "paper_loaded_sphere.xml"


@pytest.mark.parametrize("command", [("simulate", "--engine", "mujoco", *SHORT, "--mjcf"),
                                     ("theory", "--mjcf"),
                                     ("validate", "--t-end-s", "0.05", "--out", "OUT")])
def test_mjcf_with_timestep_0_is_bad_input(tmp_path: Path, command: tuple[str, ...]) -> None:
    text = EXAMPLE.read_text()
    assert 'timestep="0.0002"' in text
    xml = tmp_path / "ts0.xml"
    xml.write_text(text.replace('timestep="0.0002"', 'timestep="0"'))
    out = tmp_path / "out"
    args = [str(out) if a == "OUT" else a for a in command]
    line = _bad_input(*args, str(xml)) if command[0] != "validate" else \
        _bad_input("validate", str(xml), *args[1:])
    assert "timestep" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ts0.xml"]


# ---------------------------------------------------------------- MuJoCo's own warnings
def test_mujoco_warning_is_folded_into_the_one_line() -> None:
    """MuJoCo's 'WARNING: Nan, Inf or huge value in QVEL ...' is not printed beside the line."""
    r = _run("simulate", "fig3", "--engine", "mujoco", "--mode", "native", "--set",
             "init.n0=1e150",
             *SHORT, "--json")
    assert r.returncode == 1, r.stderr
    line = _one_line(r.stderr, "tippetop: run failed:")
    assert "mjWARN_BADQVEL" in line and "huge value in QVEL" in line  # MuJoCo's own text
    assert json.loads(r.stdout)["theta_final"] is None


def test_diverged_mujoco_run_inside_compare_keeps_the_others() -> None:
    r = _run("compare", "fig3", "--engines", "ode,mujoco", "--modes", "native,coulomb",
             "--set", "mujoco.integrator=Euler", "--set", "mujoco.timestep_s=0.02", "--set",
             "run.t_end_s=0.3", "--no-cache", "--workers", "1", "--json")
    assert r.returncode == 1, r.stderr
    assert "mujoco/native" in _one_line(r.stderr, "tippetop: run failed:")
    runs = {s["run"]: s for s in json.loads(r.stdout)["runs"]}
    assert runs["mujoco/native"]["outcome"] == "failed"
    assert runs["mujoco/native"]["status"] == "diverged"
    assert runs["ode/coulomb"]["outcome"] != "failed"
    assert runs["ode/coulomb"]["theta_final"] is not None


@pytest.mark.parametrize(("entry", "says"), [
    ([1, 2], "expected an object of metric values"),
    ({"theta_asymp": "3.1"}, "expected a number (or null) for 'theta_asymp'"),
    ({"theta_asymp": [3.1]}, "expected a number (or null) for 'theta_asymp'"),
])
def test_baseline_entry_of_the_wrong_type(tmp_path: Path, entry: object, says: str) -> None:
    # a hand-edited baseline is refused as it is read, before the nightly runs anything
    from tippetop.compare.nightly.baselines import BASELINE_DIR

    data = json.loads((BASELINE_DIR / "quick.json").read_text())
    data["cases"]["paper/fig3[ode/paper]"] = entry
    (tmp_path / "base").mkdir()
    (tmp_path / "base" / "quick.json").write_text(json.dumps(data))
    line = _bad_input("nightly", "--baseline", str(tmp_path / "base"), "--cases",
                      "paper/fig3[ode/paper]", "--out", str(tmp_path / "out"))
    assert says in line and "paper/fig3[ode/paper]" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args", [
    ("simulate", "fig3", "--out", "/proc/tippetop-x.csv"),
    ("sweep", "fig3", "--n0", "40:50:10", "--engines", "ode", "--out", "/proc/tippetop-x"),
    ("threshold", "--which", "n1", "--out", "/proc/tippetop-x"),
    ("atlas", "--engines", "ode", "--out", "/proc/tippetop-x"),
    ("render", "fig3", "--out", "/proc/tippetop-x.mp4"),
    ("bench", "accuracy", "--out", "/proc/tippetop-x"),
    ("nightly", "--out", "/proc/tippetop-x"),
])
def test_out_in_a_place_no_file_can_be_made(args: tuple[str, ...]) -> None:
    # /proc takes no new files: refused before any run (each of these would run for minutes)
    line = _bad_input(*args, timeout=60)
    assert "expected a folder tippetop can write into" in line and "'/proc'" in line


def test_out_naming_a_folder_where_a_file_is_needed(tmp_path: Path) -> None:
    (tmp_path / "t.csv").mkdir()
    line = _bad_input("simulate", "fig3", "--out", str(tmp_path / "t.csv"))
    assert "expected a file, got the folder" in line


def test_failed_runs_inside_threshold_are_reported_per_run() -> None:
    # every growth-rate run stops at max_steps: each is listed (JSON keeps them), no
    # threshold is claimed, and the failure is one line with exit 1
    r = _run("threshold", "--which", "n1", "--set", "ode.max_steps=10", "--json",
             "--no-cache")
    assert r.returncode == 1, r.stderr
    _one_line(r.stderr, "tippetop: run failed:")
    data = json.loads(r.stdout)
    assert data["measured"] is None and not data["converged"] and not data["settled"]
    assert len(data["failed_runs"]) == 2 and all(x.get("failed") for x in data["runs"])
    assert "max_steps" in data["failed_runs"][0]["message"]


def test_a_start_too_fast_for_double_precision_is_one_line() -> None:
    # the reference refuses it as bad input; MuJoCo runs it and it diverges at once: one line
    # each, without numpy's overflow warnings beside it
    line = _bad_input("simulate", "fig3", "--set", "init.uOX=1e200", *SHORT)
    assert "too large for double precision" in line
    r = _run("simulate", "fig3", "--engine", "mujoco", "--set", "init.uOX=1e200", *SHORT)
    assert r.returncode == 1
    assert "diverged" in _one_line(r.stderr, "tippetop: run failed:")


def test_failed_runs_inside_a_bisection_are_reported_per_run() -> None:
    r = _run("threshold", "--which", "n1", "--method", "bisect", "--set", "ode.max_steps=10",
             "--json", "--no-cache")
    assert r.returncode == 1, r.stderr
    _one_line(r.stderr, "tippetop: run failed:")
    data = json.loads(r.stdout)
    assert data["measured"] is None and data["method"] == "bisect" and not data["converged"]
    assert data["failed_runs"] and all(x.get("failed") for x in data["runs"])


def test_a_full_disk_while_writing_an_output_is_one_line(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture) -> None:
    # the table's writer hits ENOSPC: one line, exit 1, no file and no temporary file left
    import errno

    import pandas as pd

    from tippetop.compare.cli import main

    def full(self: object, path: object, *a: object, **k: object) -> None:
        Path(str(path)).write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(pd.DataFrame, "to_csv", full)
    out = tmp_path / "t.csv"
    assert main(["simulate", "fig3", *SHORT, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tippetop: failed: could not write")
    assert "No space left on device" in err and list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- a name mistyped
def _bad_input_in_process(args: list[str], capsys: pytest.CaptureFixture) -> str:
    """``main(args)`` in this process: exit 2, no output, one ``tippetop: error:`` line."""
    from tippetop.compare.cli import main

    try:
        status = main(args)
    except SystemExit as exc:  # argparse's errors
        status = exc.code
    out, err = capsys.readouterr()
    assert status == 2, (status, err)
    assert not out, out
    return _one_line(err, "tippetop: error:")


@pytest.mark.parametrize(("args", "says"), [
    (["simulate", "fig3", "--set", "run.t_end=4"], "'run.t_end' (did you mean 'run.t_end_s'?)"),
    (["simulate", "fig3", "--set", "Run.T_END_S=4"], "'Run.T_END_S' (did you mean 'run.t_end_s'?)"),
    (["simulate", "fig3", "--set", "t_end_s=4"], "got 't_end_s' (did you mean 'run.t_end_s'?)"),
    (["simulate", "fig33"], "got 'fig33' (did you mean 'fig3'?)"),
    (["simulate", "fig3", "--engine", "mujoco-nativ"],
     "got 'mujoco-nativ' (did you mean --engine mujoco --mode native?)"),
    (["simulate", "fig3", "--engine", "mujoco", "--mode", "nativ"],
     "got 'nativ' (did you mean 'native'?)"),
    (["compare", "fig3", "--modes", "paper,nativ"], "got 'nativ' (did you mean 'native'?)"),
    (["compare", "fig3", "--engines", "ode,mujocoo"], "got 'mujocoo' (did you mean 'mujoco'?)"),
    (["plan", "fig3", "--engine", "mujoco-papr"],
     "(did you mean --engine mujoco --mode paper?)"),
    (["simulate", "fig3", "--engine", "mujoco", "--on", "mjxx"],
     "got 'mjxx' (did you mean 'mjx'?)"),
    (["simulate", "fig3", "--engine", "mujoco", "--on", "warpp"],
     "got 'warpp' (did you mean 'warp'?)"),
    (["simulate", "fig3", "--engine", "mujoco", "--on", "mujoco=3.3.7"],
     "got 'mujoco=3.3.7' (did you mean 'mujoco==X.Y.Z'?)"),
    (["simulate", "fig3", "--set", "friction.law=coulmb"],
     "got 'coulmb' (did you mean 'coulomb'?)"),
    (["simulate", "fig3", "--set", "mujoco.integrator=rk4"], "got 'rk4' (did you mean 'RK4'?)"),
    (["simulat", "fig3"], "invalid choice: 'simulat' (did you mean 'simulate'?)"),
    (["threshold", "--which", "N1"], "invalid choice: 'N1' (did you mean 'n1'?)"),
    (["nightly", "--profile", "quik"], "got 'quik' (did you mean 'quick'?)"),
    (["nightly", "--engines", "ode,mjxx"], "got 'mjxx' (did you mean 'mjx'?)"),
    (["nightly", "--cases", "paper/fig33[ode/paper]"],
     "(did you mean 'paper/fig3[ode/paper]'?)"),
])
def test_a_mistyped_name_says_which_was_meant(args: list[str], says: str,
                                              capsys: pytest.CaptureFixture) -> None:
    """Issue 29: one line, the name given and then the name meant."""
    line = _bad_input_in_process(args, capsys)
    assert says in line
    assert "did you mean" in line


def test_a_mistyped_scene_key_lists_its_section_not_every_key(
        capsys: pytest.CaptureFixture) -> None:
    line = _bad_input_in_process(["simulate", "fig3", "--set", "run.t_end=4"], capsys)
    assert line == ("tippetop: error: --set: unknown key 'run.t_end' (did you mean "
                    "'run.t_end_s'?) (expected one of the [run] keys: run.t_end_s, "
                    "run.sample_dt_s)")
    # nothing close and no section known: every key, as before
    line = _bad_input_in_process(["simulate", "fig3", "--set", "foo.bar=4"], capsys)
    assert "did you mean" not in line and "init.n0" in line and "mujoco.cone" in line


def test_a_mistyped_key_in_a_scene_file(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    scene = tmp_path / "s.toml"
    scene.write_text("[run]\nt_end = 0.05\n")
    line = _bad_input_in_process(["simulate", str(scene)], capsys)
    assert "scene s.toml: unknown key 'run.t_end' (did you mean 'run.t_end_s'?)" in line
    scene.write_text("[rn]\nt_end_s = 0.05\n")
    line = _bad_input_in_process(["simulate", str(scene)], capsys)
    assert "unknown section [rn] (did you mean 'run'?)" in line


def test_a_name_nothing_is_close_to_gets_no_suggestion(capsys: pytest.CaptureFixture) -> None:
    line = _bad_input_in_process(["simulate", "zzz"], capsys)
    assert "got 'zzz'" in line and "did you mean" not in line


# ---------------------------------------------------------------- a broken MJCF file
def _line(text: str, needle: str) -> int:
    """The line (from 1) of the first ``needle`` in ``text``."""
    return text[:text.index(needle)].count("\n") + 1


def _broken(name: str, text: str) -> tuple[bytes, list[str]]:
    """The example top broken as ``name`` says, and what the one line must say."""
    option, body, world = _line(text, "<option"), _line(text, "<body"), \
        _line(text, "</worldbody>")
    if name == "truncated":  # cut in the middle of <option ...>
        return text[:text.index("<option") + 30].encode(), [
            f"an XML error at line {option}, column 3: unclosed token"]
    if name == "missing closing tag":
        cut = text.rindex("</body>")
        return (text[:cut] + text[cut + len("</body>"):]).encode(), [
            f"an XML error at line {world}, column 5: mismatched tag (expected the end of the "
            f"<body> of line {body})"]
    if name == "unknown attribute":
        return text.replace("<geom friction=", '<geom colour="red" friction=', 1).encode(), [
            f"a MuJoCo error at line {_line(text, '<geom friction=')} (<geom>): Schema "
            "violation: unrecognized attribute: 'colour'"]
    if name == "empty":
        return b"", ["got an empty file"]
    if name == "binary":
        return bytes(range(256)) * 4, ["got binary data (a NUL byte at line 1, column 1)"]
    if name == "utf-16":
        return text.encode("utf-16"), ["got UTF-16 text"]
    if name == "include of a missing file":
        return text.replace("<worldbody>", '<include file="no_such_part.xml"/><worldbody>',
                            1).encode(), [
            f"a MuJoCo error at line {_line(text, '<worldbody>')} (<include>): Error opening "
            "file 'no_such_part.xml'"]
    assert name == "include of a truncated file"
    return text.replace("<worldbody>", '<include file="cut_part.xml"/><worldbody>',
                        1).encode(), [
        "cut_part.xml (included by ", f"at line {_line(text, '<worldbody>')}): expected a "
        "valid MJCF document, got an XML error at line 2, column 3: unclosed token"]


BROKEN = ["truncated", "missing closing tag", "unknown attribute", "empty", "binary", "utf-16",
          "include of a missing file", "include of a truncated file"]
MJCF_COMMANDS = {
    "simulate": ["simulate", "--engine", "mujoco", *SHORT, "--out", "OUT/t.csv", "--mjcf"],
    "validate": ["validate", "--no-tune", "--t-end-s", "0.05", "--out", "OUT/v", "FILE"],
    "theory": ["theory", "--mjcf"],
}


@pytest.mark.parametrize("command", sorted(MJCF_COMMANDS))
@pytest.mark.parametrize("broken", BROKEN)
def test_a_broken_mjcf_file_is_one_line_with_its_line_number(
        tmp_path: Path, broken: str, command: str, capsys: pytest.CaptureFixture) -> None:
    """Issue 29: the file, the line and column, and the reason; not MuJoCo's first line."""
    data, says = _broken(broken, EXAMPLE.read_text())
    xml = tmp_path / "top.xml"
    xml.write_bytes(data)
    (tmp_path / "cut_part.xml").write_text("<mujoco>\n  <option timestep=")
    (tmp_path / "OUT").mkdir()
    args = [str(tmp_path / a) if a.startswith("OUT") else a for a in MJCF_COMMANDS[command]]
    args = [str(xml) if a == "FILE" else a for a in args]
    if str(xml) not in args:
        args.append(str(xml))
    line = _bad_input_in_process(args, capsys)
    for fragment in says:
        assert fragment in line, line
    if not broken.startswith("include of a truncated"):
        assert f"{xml}: expected a valid MJCF document, got " in line
    assert "XML_ERROR" not in line and "ErrorID" not in line
    # nothing written; validate's lock on its --out folder goes when the process exits
    assert [p.name for p in (tmp_path / "OUT").iterdir()
            if not p.name.endswith(".tippetop.lock")] == []


@pytest.mark.parametrize(("name", "change", "says"), [
    # MuJoCo's parser reads these; tippetop, which writes the run's settings into the
    # document, reads it with Python's stricter one
    ("not UTF-8", lambda t: t.replace("paper loaded sphere", "caf\u00e9 top").encode("latin-1"),
     "expected an MJCF (XML) text file in UTF-8, got a byte that is not UTF-8 (0xE9) at line "),
    ("an unescaped &", lambda t: t.replace("paper loaded sphere", "a & b").encode(),
     "expected a well-formed XML document, got an XML error at line "),
])
def test_a_file_mujoco_reads_but_xml_does_not_is_one_line(
        tmp_path: Path, name: str, change: object, says: str,
        capsys: pytest.CaptureFixture) -> None:
    text = EXAMPLE.read_text()
    xml = tmp_path / "top.xml"
    xml.write_bytes(change(text))  # type: ignore[operator]
    out = tmp_path / "t.csv"
    line = _bad_input_in_process(["simulate", "--engine", "mujoco", *SHORT, "--mjcf", str(xml),
                                  "--out", str(out)], capsys)
    assert f"{xml}: {says}{_line(text, '<mujoco model=')}, column " in line
    assert not out.exists()


def test_a_file_with_a_byte_order_mark_runs(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from tippetop.compare.cli import main

    xml = tmp_path / "bom.xml"
    xml.write_bytes(b"\xef\xbb\xbf" + EXAMPLE.read_bytes())
    assert main(["theory", "--mjcf", str(xml), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)


def test_a_truncated_mjcf_file_through_the_command(tmp_path: Path) -> None:
    """The same, as a user runs it: one line on stderr, exit 2, nothing on stdout."""
    text = EXAMPLE.read_text()
    xml = tmp_path / "cut.xml"
    xml.write_text(text[:text.index("<option") + 30])
    line = _bad_input("theory", "--mjcf", str(xml))
    assert line == (f"tippetop: error: {xml}: expected a valid MJCF document, got an XML error "
                    f"at line {_line(text, '<option')}, column 3: unclosed token")
