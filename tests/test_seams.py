"""Typed seams (issue 42): what passes between the rooms is a value, not text or a dictionary.

Overrides are :class:`tippetop.models.scene.Override` values outside the command line and
models/ (item 1); a study's entry point returns a result with fields (item 2).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.test_layers import ROOT, _modules

# ------------------------------------------------------------ overrides as values (item 1)
#: Scene-override text: a string literal (or an f-string's first part) ``section.key=...``.
_OVERRIDE_TEXT = re.compile(r"^(scene|top|friction|stem|effects|init|run|ode|mujoco|outputs|"
                            r"expect)\.[A-Za-z_0-9]+=")
#: Where override text belongs: the command line (``--set`` parsed once) and models/ (the
#: scene files' own language: the modes' settings, the parser).
_TEXT_ALLOWED = ("compare/commands/", "models/")
#: Modules of compare that still spell overrides as text (issue 42, item 1): none.
OVERRIDE_TEXT_TODO: frozenset[str] = frozenset()


def _override_texts(path: Path) -> list[int]:
    """Lines of a module with a string literal that spells a scene override."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.JoinedStr):
            first = node.values[0] if node.values else None
            text = first.value if isinstance(first, ast.Constant) else ""
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            text = node.value
        else:
            continue
        if isinstance(text, str) and _OVERRIDE_TEXT.match(text):
            lines.append(node.lineno)
    return sorted(set(lines))


def test_no_override_text_outside_the_commands_and_models() -> None:
    found = {str(p.relative_to(ROOT)): n for p in _modules().values()
             if not str(p.relative_to(ROOT)).startswith(_TEXT_ALLOWED)
             and (n := _override_texts(p))}
    assert sorted(set(found) - OVERRIDE_TEXT_TODO) == [], found
    assert sorted(OVERRIDE_TEXT_TODO - set(found)) == []


def test_the_override_check_sees_text_and_passes_a_value(tmp_path: Path) -> None:
    p = tmp_path / "x.py"
    p.write_text('a = f"top.A_over_C={r!r}"\nb = "mujoco.contacts=false"\n'
                 'c = Override.of("top.A_over_C", 1.2)\nd = "a.b=c is prose"\n')
    assert _override_texts(p) == [1, 2]


# ------------------------------------------------------------ results with fields (item 2)
#: Each measuring command's study: (file, function). Its result is what passes to the
#: printers, the reports and the JSON.
STUDY_ENTRIES = frozenset({
    ("compare/studies/sweep.py", "run_sweep"),
    ("compare/studies/atlas.py", "run_atlas"),
    ("compare/studies/matrix.py", "run_matrix"),
    ("compare/studies/crossval.py", "compare_scene"),
    ("compare/studies/threshold.py", "measure_threshold"),
    ("compare/studies/bisect.py", "bisect"),
    ("compare/studies/fidelity.py", "run_fidelity"),
    ("compare/studies/validate.py", "validate"),
    ("compare/studies/accuracy/study.py", "run_accuracy"),
    ("compare/tuning/tune.py", "tune"),
    ("compare/studies/bench.py", "bench_ode"),
    ("compare/studies/work_precision_report.py", "run_work_precision"),
})
#: The studies whose result is a frozen dataclass with ``to_json``/``from_json`` in
#: compare/results/ (issue 42, item 2). The rest still return a dictionary: this list may
#: only grow.
RESULTS_WITH_FIELDS = frozenset({
    ("compare/studies/sweep.py", "run_sweep"),
    ("compare/studies/atlas.py", "run_atlas"),
    ("compare/studies/matrix.py", "run_matrix"),
    ("compare/studies/crossval.py", "compare_scene"),
    ("compare/studies/threshold.py", "measure_threshold"),
    ("compare/studies/bisect.py", "bisect"),
    ("compare/studies/fidelity.py", "run_fidelity"),
    ("compare/studies/validate.py", "validate"),
    ("compare/studies/accuracy/study.py", "run_accuracy"),
    ("compare/tuning/tune.py", "tune"),
    ("compare/studies/bench.py", "bench_ode"),
    ("compare/studies/work_precision_report.py", "run_work_precision"),
})
DICT_RESULT_TODO = STUDY_ENTRIES - RESULTS_WITH_FIELDS


def _returns(rel: str, name: str) -> str:
    tree = ast.parse((ROOT / rel).read_text())
    found = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == name]
    assert found, (rel, name)
    return ast.unparse(found[0].returns) if found[0].returns is not None else ""


def test_no_study_returns_a_dictionary() -> None:
    as_dict = {(rel, name) for rel, name in STUDY_ENTRIES if "dict[" in _returns(rel, name)}
    assert sorted(as_dict - DICT_RESULT_TODO) == []
    assert sorted(DICT_RESULT_TODO - as_dict) == []


def test_a_result_says_itself_and_reads_itself_back() -> None:
    """Every result type of compare/results has to_json and from_json."""
    for path in sorted((ROOT / "compare" / "results").glob("*.py")):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ClassDef) and node.name.endswith("Result"):
                methods = {n.name for n in node.body if isinstance(n, ast.FunctionDef)}
                assert {"to_json", "from_json"} <= methods, (path.name, node.name)
                assert any(isinstance(d, ast.Call) and "frozen" in ast.unparse(d)
                           for d in node.decorator_list), (path.name, node.name)
