"""The distribution installs its packages under one name, tippetop.*.

``import models`` and ``import compare`` are other PyPI packages' names: they must not resolve to
this project outside its checkout, and a ``models.py`` or ``compare.py`` in the working folder
must not shadow the tool.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOP_LEVEL = ("models", "reference_ode", "mujoco_runner", "compare")


def _python(code: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=120)


def test_bare_names_do_not_import_outside_the_checkout(tmp_path: Path) -> None:
    for name in TOP_LEVEL:
        r = _python(f"import {name}", tmp_path)
        assert r.returncode != 0 and "ModuleNotFoundError" in r.stderr, (name, r.stderr)
        r = _python(f"import tippetop.{name}", tmp_path)
        assert r.returncode == 0, (name, r.stderr)


def test_modules_named_like_the_folders_in_the_working_folder_do_not_shadow_it(
        tmp_path: Path) -> None:
    # `python -c` puts the working folder first on sys.path: these would win a bare import
    for name in TOP_LEVEL:
        (tmp_path / f"{name}.py").write_text("raise SystemExit('shadowed: wrong module')\n")
    code = ("from tippetop.compare.cli import main; "
            "raise SystemExit(main(['theory', '--A-over-C', '1', '--a-over-R', '0.1', "
            "'--json']))")
    r = _python(code, tmp_path)
    assert r.returncode == 0, r.stderr
    assert '"group": "II"' in r.stdout


def test_every_package_folder_is_installed() -> None:
    """A subpackage missing from pyproject.toml works in an editable install but not in a wheel."""
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(conf["packages"])
    mapping = conf["package-dir"]
    data = conf["package-data"]
    found = set()
    for top in TOP_LEVEL:
        assert mapping[f"tippetop.{top}"] == top
        for folder in [ROOT / top, *(ROOT / top).rglob("*")]:
            if not folder.is_dir() or folder.name == "__pycache__":
                continue
            name = ".".join(("tippetop", top, *folder.relative_to(ROOT / top).parts))
            found.add(name)
            if not (folder / "__init__.py").is_file():
                # a data folder (scenes, baselines): listed too, or setuptools warns that it
                # "would be ignored"; its files go in through package-data
                assert not list(folder.glob("*.py")), f"{folder}: Python files without __init__"
                assert data.get(name), f"{name}: a data folder with no package-data patterns"
    assert listed == found


def test_lazy_exports_do_not_share_a_name_with_a_submodule() -> None:
    """Once a submodule is imported it becomes the package attribute of its name, so a lazily
    exported function of the same name would turn into the module."""
    import importlib

    for pkg in ("tippetop.compare.nightly", "tippetop.compare.tuning.calibrate",
                "tippetop.compare.studies.accuracy", "tippetop.compare.report"):
        mod = importlib.import_module(pkg)
        folder = Path(mod.__file__).parent
        submodules = {p.stem for p in folder.glob("*.py")}
        for name in mod.__all__:
            assert name not in submodules, (pkg, name)
            assert callable(getattr(mod, name)) or not isinstance(getattr(mod, name), type(mod))


def test_the_files_that_shape_a_cached_result_exist() -> None:
    """The cache key hashes these files (cache.MODULES); a file moved away would silently
    drop out of it, and an edit to it would serve stale cached runs."""
    from tippetop.compare.running import cache
    from tippetop.models.resources import data_path

    for pkg, name in cache.MODULES:
        assert data_path(pkg, name).is_file(), (pkg, name)


def test_the_suite_keeps_to_its_own_cache() -> None:
    """Issue 43: the tests use their own cache and history, never the user's: conftest.py sets
    ``TIPPETOP_CACHE`` to the suite's folder before tippetop is imported, so the runs, the
    history and the compiled code of this process and of every command a test starts (they
    inherit the environment) go there."""
    import os

    from tests.conftest import TEST_CACHE, USER_CACHE
    from tippetop.compare.nightly.history import history_path
    from tippetop.models.resources import user_cache_dir

    assert os.environ["TIPPETOP_CACHE"] == str(TEST_CACHE)
    assert user_cache_dir() == TEST_CACHE
    assert history_path().parent == TEST_CACHE
    assert TEST_CACHE != Path.home() / ".cache" / "tippetop"
    assert USER_CACHE is None or Path(USER_CACHE) != TEST_CACHE
