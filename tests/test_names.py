"""Each meaning of "engine" has one home, under a name that says which meaning it holds; the
release before's spellings have one home too.

Issue 42: ``ENGINES`` was declared five times with three meanings (the engine families, the
worker's implementations and their precisions, the spellings with their descriptions). The
families are :data:`tippetop.models.engines.FAMILIES`, the spellings
:data:`tippetop.models.engines.ENGINE_MEANINGS`, the worker's precisions
:data:`tippetop.mujoco_runner.worker.protocol.PRECISIONS`. Read from the source with ``ast``.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("models", "reference_ode", "mujoco_runner", "compare")


def _module_assignments() -> list[tuple[Path, str, ast.AST]]:
    """Every module-level assignment of the package: (file, name, value)."""
    out = []
    for layer in LAYERS:
        for path in sorted((ROOT / layer).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            for node in tree.body:
                if isinstance(node, ast.Assign):
                    out += [(path, t.id, node.value) for t in node.targets
                            if isinstance(t, ast.Name)]
                elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) \
                        and node.value is not None:
                    out.append((path, node.target.id, node.value))
    return out


def test_no_module_declares_a_name_as_vague_as_engines() -> None:
    where = [str(p.relative_to(ROOT)) for p, name, _ in _module_assignments()
             if name == "ENGINES"]
    assert where == []


def test_the_engine_families_are_declared_once() -> None:
    """The families' literal, ("ode", "mujoco") in any order, is written in one place."""
    families = []
    for path, name, value in _module_assignments():
        if isinstance(value, (ast.Tuple, ast.List)) and all(
                isinstance(e, ast.Constant) for e in value.elts):
            if sorted(str(e.value) for e in value.elts) == ["mujoco", "ode"]:
                families.append((str(path.relative_to(ROOT)), name))
    # the renderer's engines hold a meaning of their own (what a video can draw, MuJoCo first)
    assert sorted(families) == [("compare/presentation/video.py", "RENDER_ENGINES"),
                        ("models/engines.py", "FAMILIES")]
    from tippetop.models.engines import FAMILIES, IMPLEMENTATIONS
    from tippetop.mujoco_runner.worker.protocol import PRECISIONS

    # every implementation the worker steps is one an engine spec can name, of the MuJoCo family
    assert set(PRECISIONS) <= set(IMPLEMENTATIONS) - {"ode"} and set(FAMILIES) <= {"ode", "mujoco"}


def test_the_old_spellings_have_one_home() -> None:
    """Issue 42: the release before's spellings were read in 6 modules in 4 folders. Their
    tables (module-level ``OLD_*``) and the words every note on them ends with are in
    models/spellings.py alone; the readers elsewhere take them from there."""
    tables = sorted((str(p.relative_to(ROOT)), name) for p, name, _ in _module_assignments()
                    if name.lstrip("_").startswith("OLD_"))
    assert {path for path, _ in tables} == {"models/spellings.py"}, tables
    said = []
    for layer in LAYERS:
        for path in sorted((ROOT / layer).rglob("*.py")):
            if "goes in the next release" in path.read_text(encoding="utf-8"):
                said.append(str(path.relative_to(ROOT)))
    assert said == ["models/spellings.py"]
    from tippetop.models.spellings import GOES, OLD_NAMES, new_spelling, old_case_id

    # each compound name reads as today's engine and mode
    assert new_spelling("mujoco-native") == "--engine mujoco --mode native"
    assert old_case_id("paper/fig3[mujoco-native]@mujoco==3.3.7") == (
        "paper/fig3", "mujoco==3.3.7", "native", ())
    assert old_case_id("paper/fig3[mujoco/native]") is None
    assert GOES.startswith("(") and all(e in ("ode", "mujoco") for e, _, _ in OLD_NAMES.values())
