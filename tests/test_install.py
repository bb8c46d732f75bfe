"""The install as the README gives it: one script for the Debian packages, a lock file for pip.

The script is run with fake ``apt-get``, ``sudo`` and ``id`` on PATH (this suite must not
install anything): as root it calls apt-get itself, as a user through sudo, always with
``apt-get update`` first and ``--no-install-recommends``, gfortran included. The lock file pins
every dependency of pyproject.toml (with its extras) within the ranges pyproject.toml states,
and ``.ci/run`` installs from it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "install-system-packages.sh"
LOCK = ROOT / "requirements.lock"


def _fake_bin(tmp_path: Path, uid: int, sudo: bool) -> tuple[Path, Path]:
    bin_dir, log = tmp_path / "bin", tmp_path / "log"
    bin_dir.mkdir()
    tools = {"apt-get": f'echo "apt-get $*" >> {log}',
             "id": f'if [ "$1" = "-u" ]; then echo {uid}; else /usr/bin/id "$@"; fi'}
    if sudo:
        tools["sudo"] = f'echo "sudo" >> {log}; "$@"'
    for name, body in tools.items():
        path = bin_dir / name
        path.write_text(f"#!/bin/sh\n{body}\n")
        path.chmod(0o755)
    return bin_dir, log


def _run(tmp_path: Path, uid: int, sudo: bool) -> tuple[subprocess.CompletedProcess, str]:
    bin_dir, log = _fake_bin(tmp_path, uid, sudo)
    # PATH: the fakes, then only the folders of bash and env (no real sudo or apt-get)
    env = {**os.environ, "PATH": f"{bin_dir}:/usr/bin:/bin"}
    if not sudo and Path("/usr/bin/sudo").exists():
        pytest.skip("a real sudo on /usr/bin would be found")
    res = subprocess.run(["bash", str(SCRIPT)], capture_output=True, text=True, env=env,
                         check=False)
    return res, log.read_text() if log.exists() else ""


@pytest.mark.parametrize(("uid", "sudo"), [(0, False), (1000, True)], ids=["root", "sudo"])
def test_the_script_updates_then_installs_without_recommends(tmp_path: Path, uid: int,
                                                             sudo: bool) -> None:
    res, log = _run(tmp_path, uid, sudo)
    assert res.returncode == 0, res.stderr
    calls = [line for line in log.splitlines() if line.startswith("apt-get")]
    assert calls[0] == "apt-get update -qq"
    install = calls[1].split()
    assert install[:2] == ["apt-get", "install"] and "--no-install-recommends" in install
    for pkg in ("libegl1", "libosmesa6", "chromium", "gfortran"):
        assert pkg in install
    assert log.count("sudo") == (2 if sudo else 0)


def test_a_user_without_sudo_is_told_in_one_line(tmp_path: Path) -> None:
    res, log = _run(tmp_path, 1000, sudo=False)
    assert res.returncode == 2 and log == ""
    assert res.stderr.count("\n") == 1 and "expected root or sudo" in res.stderr


def test_readme_and_ci_use_the_same_script_and_the_lock() -> None:
    ci = (ROOT / ".ci" / "run").read_text()
    readme = (ROOT / "README.md").read_text()
    for text in (ci, readme):
        assert "bash scripts/install-system-packages.sh" in text
        assert re.search(r"pip install (-q )?-r requirements\.lock", text)
    assert "apt-get install" not in ci  # only through the script
    assert "pip install -q --no-deps -e ." in ci



def test_ci_builds_the_docs_with_the_readmes_command_and_no_hidden_variable() -> None:
    # issue 29: the README's `mkdocs build --strict` printed Material's end-of-life notice and a
    # variable to hide it that only CI set. The site is built by ProperDocs, which prints
    # neither: CI runs the README's command as it stands (tests/test_docs.py checks what it
    # prints)
    ci = (ROOT / ".ci" / "run").read_text()
    readme = (ROOT / "README.md").read_text()
    assert "`properdocs build --strict`" in readme
    assert re.search(r"^properdocs build --strict$", ci, re.M)
    assert "NO_MKDOCS_2_WARNING" not in ci and "mkdocs build" not in ci

def _lock() -> dict[str, tuple[Version, str]]:
    """name -> (version, environment marker) of every pin that applies to this interpreter."""
    env = default_environment()
    pins = {}
    for line in LOCK.read_text().splitlines():
        if not line or line[0] in "# ":
            continue
        req = Requirement(line)
        if req.marker is None or req.marker.evaluate(env):
            (spec,) = req.specifier
            assert spec.operator == "==", line
            pins[canonicalize_name(req.name)] = (Version(spec.version), line)
    return pins


def test_the_lock_pins_every_dependency_within_pyprojects_ranges() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = list(project["dependencies"])
    for extra in ("test", "peers", "docs"):
        reqs += project["optional-dependencies"][extra]
    pins = _lock()
    for text in reqs:
        req = Requirement(text)
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} is not in requirements.lock: run the lock's command"
        version = pins[name][0]
        assert req.specifier.contains(version, prereleases=True), \
            f"requirements.lock pins {name} {version}, outside pyproject's {req.specifier}"
        for extra in req.extras:  # mujoco[sysid], dask[distributed]: the extras' packages too
            assert re.search(rf"# via .*\b{name}\b", LOCK.read_text()), (name, extra)


def test_the_lock_says_how_it_was_made() -> None:
    head = LOCK.read_text().splitlines()[:3]
    assert any("uv pip compile pyproject.toml" in line and "--extra docs" in line
               for line in head), head


def test_this_environment_runs_what_the_lock_pins() -> None:
    # CI installs from the lock: the suite then runs on exactly those versions (a developer's
    # open install may differ, and then this test says which packages do)
    from importlib import metadata

    if not os.environ.get("CI"):
        pytest.skip("checked in CI, which installs from the lock")
    differ = []
    for name, (version, _line) in _lock().items():
        try:
            got = Version(metadata.version(name))
        except metadata.PackageNotFoundError:
            differ.append(f"{name}: not installed")
            continue
        if got != version:
            differ.append(f"{name}: {got} installed, {version} locked")
    assert not differ, differ
    assert sys.version_info >= (3, 11)


def test_ci_installs_into_a_venv_of_its_own_before_any_pip() -> None:
    # CI's machine Python carries packages of its own (botocore wanting python-dateutil<3 was
    # one): installed there, the lock's python-dateutil 4 made `pip check` fail on a package
    # that is none of the project's. Every pip command must run in the venv .ci/run makes.
    lines = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()
             if ln.strip() and not ln.lstrip().startswith("#")]
    venv = lines.index("python3 -m venv .venv")
    activate = lines.index(". .venv/bin/activate")
    pips = [i for i, ln in enumerate(lines) if re.search(r"\bpip\b", ln)]
    assert venv < activate < min(pips)
    assert "/.venv/" in (ROOT / ".gitignore").read_text().splitlines()
