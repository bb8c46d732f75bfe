"""Layers point one way, and no module imports itself back, not even lazily.

models < reference_ode < mujoco_runner < compare; inside compare the commands sit on top, and
the nightly and the report do not know each other. The import graph is built from the source
with ``ast`` (every ``import`` statement, at the top or inside a function), so a lazy import
counts like any other. No module takes another's private (``_name``) names.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("models", "reference_ode", "mujoco_runner", "compare")


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(["tippetop", *parts])


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for layer in LAYERS for p in sorted((ROOT / layer).rglob("*.py"))}


def _from_module(node: ast.ImportFrom, path: Path, name: str) -> str:
    """The module a ``from ... import`` statement of module ``name`` (at ``path``) names."""
    if not node.level:
        return node.module or ""
    base = name.split(".")
    base = base if path.name == "__init__.py" else base[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(path: Path, name: str, known: set[str]) -> set[str]:
    """The tippetop modules a file imports (a package import counts as its __init__)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            mod = _from_module(node, path, name)
            targets = [mod] + [f"{mod}.{a.name}" for a in node.names]
        else:
            continue
        for t in targets:
            # the longest known module named by the import
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    known = set(mods)
    return {m: _imports(p, m, known) for m, p in mods.items()}


def _layer(module: str) -> int:
    return LAYERS.index(module.split(".")[1])


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def test_graph_covers_every_module() -> None:
    graph = _graph()
    assert len(graph) > 40
    assert "tippetop.compare.cli" in graph and "tippetop.models.plan" in graph


def test_no_module_imports_a_higher_layer() -> None:
    upward = sorted(f"{m} -> {t}" for m, targets in _graph().items() for t in targets
                    if _layer(t) > _layer(m))
    assert upward == []


def test_no_import_cycles() -> None:
    graph = _graph()
    # Tarjan's strongly connected components; a package's __init__ importing its own
    # submodules is part of the graph like any other edge.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert cycles == []


def test_the_check_sees_a_lazy_upward_import(tmp_path: Path) -> None:
    src = "def f():\n    from tippetop.compare.theory import group\n    return group\n"
    p = tmp_path / "x.py"
    p.write_text(src)
    found = _imports(p, "tippetop.models.x", {"tippetop.compare.theory", "tippetop.compare"})
    assert found == {"tippetop.compare.theory"}


# ---------------------------------------------------------------- inside compare
COMMANDS = "tippetop.compare.commands"
#: The rooms of compare (its folders and top-level modules), each importing only those before
#: it: pure measurements at the bottom, the code that runs things above them, the commands and
#: the parser at the top. ``_lazy`` is a helper for packages' ``__init__`` at the very bottom.
ROOMS = ("_lazy", "measures", "running", "results", "probes", "presentation", "tuning", "studies",
         "report", "nightly", "commands", "cli", "__main__")
#: Rooms that must not know each other although the order puts one above the other: the
#: nightly command composes the nightly and the report.
APART = (("nightly", "report"),)


def _room(module: str) -> str | None:
    """The room of a module of compare: its folder, or its own name at compare's top."""
    parts = module.split(".")
    if parts[:2] != ["tippetop", "compare"] or len(parts) < 3:
        return None
    return parts[2]


def _room_graph() -> dict[str, dict[str, list[str]]]:
    """room -> the rooms it imports -> the module imports that make each arrow."""
    rooms: dict[str, dict[str, list[str]]] = {}
    for m, targets in _graph().items():
        a = _room(m)
        if a is None:
            continue
        rooms.setdefault(a, {})
        for t in targets:
            b = _room(t)
            if b is not None and b != a:
                rooms[a].setdefault(b, []).append(f"{m} -> {t}")
    return rooms


def test_every_room_of_compare_is_in_the_order() -> None:
    rooms = set(_room_graph())
    assert rooms <= set(ROOMS), sorted(rooms - set(ROOMS))
    assert {"measures", "running", "studies", "commands"} <= rooms


def test_the_rooms_of_compare_point_one_way() -> None:
    """A room imports only rooms before it in ROOMS (lazy imports included): no loops."""
    upward = sorted(arrow for a, targets in _room_graph().items() for b, arrows in
                    targets.items() if ROOMS.index(b) > ROOMS.index(a) for arrow in arrows)
    assert upward == []


def test_the_room_graph_of_compare_has_no_cycle() -> None:
    """Whatever the order says: the folder graph itself is acyclic (a depth-first search)."""
    graph = {a: set(t) for a, t in _room_graph().items()}
    state: dict[str, int] = {}
    cycle: list[str] = []

    def visit(v: str, path: list[str]) -> bool:
        state[v] = 1
        for w in sorted(graph.get(v, ())):
            if state.get(w) == 1:
                cycle.extend([*path, v, w])
                return True
            if w not in state and visit(w, [*path, v]):
                return True
        state[v] = 2
        return False

    for v in sorted(graph):
        if v not in state and visit(v, []):
            break
    assert cycle == []


def test_pure_measures_start_no_run() -> None:
    """measures imports nothing of compare, and none of the modules that run an engine."""
    runs = ("tippetop.reference_ode.solve", "tippetop.mujoco_runner.run",
            "tippetop.mujoco_runner.batch", "tippetop.mujoco_runner.remote")
    bad = sorted(f"{m} -> {t}" for m, targets in _graph().items()
                 if _room(m) == "measures" for t in targets
                 if (_room(t) not in (None, "measures")) or t in runs)
    assert bad == []


def test_the_room_check_sees_a_lazy_import_that_points_back(tmp_path: Path) -> None:
    src = "def f():\n    from tippetop.compare.nightly.outputs import slug\n"
    p = tmp_path / "x.py"
    p.write_text(src)
    found = _imports(p, "tippetop.compare.studies.x",
                     {"tippetop.compare.nightly.outputs", "tippetop.compare.nightly"})
    assert [_room(t) for t in found] == ["nightly"]
    assert ROOMS.index("nightly") > ROOMS.index("studies")


#: The longest a module of the four packages may be (lines): split by job past it.
MAX_MODULE_LINES = 700


def test_no_module_is_over_700_lines() -> None:
    long = sorted(f"{p.relative_to(ROOT)}: {n}" for p in _modules().values()
                  if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES)
    assert long == []


def test_no_room_of_compare_imports_a_command() -> None:
    """measures, running, presentation, the studies, the nightly and the report never import
    a command (only the parser does, and ``python -m tippetop.compare``)."""
    upward = sorted(f"{m} -> {t}" for m, targets in _graph().items() for t in targets
                    if _within(t, COMMANDS) and _room(m) not in ("commands", "cli",
                                                                 "__main__"))
    assert upward == []


def test_the_nightly_and_the_report_do_not_import_each_other() -> None:
    """The nightly command composes them (it passes the report's writer to ``run_nightly``)."""
    nightly, report = "tippetop.compare.nightly", "tippetop.compare.report"
    graph = _graph()
    assert any(_within(m, nightly) for m in graph) and any(_within(m, report) for m in graph)
    crossing = sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets
                      if (_within(m, nightly) and _within(t, report))
                      or (_within(m, report) and _within(t, nightly)))
    assert crossing == []


def test_the_check_sees_the_nightly_import_the_report_lazily(tmp_path: Path) -> None:
    src = "def f():\n    from tippetop.compare.report.build import build_report\n"
    p = tmp_path / "x.py"
    p.write_text(src)
    found = _imports(p, "tippetop.compare.nightly.x",
                     {"tippetop.compare.report.build", "tippetop.compare.report"})
    assert found == {"tippetop.compare.report.build"}


# ---------------------------------------------------------------- private names
def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _private_uses(path: Path, name: str, known: set[str]) -> list[str]:
    """``from <tippetop module> import _x`` and ``m._x`` for an imported tippetop module m."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found: list[str] = []
    modules: dict[str, str] = {}  # local name -> the tippetop module it names
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = _from_module(node, path, name)
            if mod.split(".")[0] != "tippetop":
                continue
            for a in node.names:
                if _private(a.name):
                    found.append(f"from {mod} import {a.name}")
                if f"{mod}.{a.name}" in known:
                    modules[a.asname or a.name] = f"{mod}.{a.name}"
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "tippetop":
                    modules[a.asname or a.name] = a.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            owner = ast.unparse(node.value)
            if owner in modules or owner in known:
                found.append(f"{modules.get(owner, owner)}.{node.attr}")
    return found


def test_no_module_imports_another_modules_private_names() -> None:
    """The four packages and the benchmarks use each other's public names only."""
    mods = _modules()
    known = set(mods)
    files = dict(mods)
    files.update({f"benchmarks.{p.stem}": p for p in sorted((ROOT / "benchmarks").glob("*.py"))})
    assert len(files) > len(mods)
    uses = sorted(f"{name}: {use}" for name, path in files.items()
                  for use in _private_uses(path, name, known))
    assert uses == []


def test_the_check_sees_private_names(tmp_path: Path) -> None:
    src = ("from tippetop.compare.running.runner import _local_pool\n"
           "import tippetop.mujoco_runner.run as mj_run\n"
           "from tippetop.compare.running import io\n"
           "from os import _exit\n"
           "mj_run._grid(1, 2, 3)\nio._tmp\nmj_run.__name__\n")
    p = tmp_path / "x.py"
    p.write_text(src)
    known = {"tippetop.compare.running.runner", "tippetop.mujoco_runner.run",
             "tippetop.compare.running.io"}
    assert sorted(_private_uses(p, "benchmarks.x", known)) == [
        "from tippetop.compare.running.runner import _local_pool",
        "tippetop.compare.running.io._tmp",
        "tippetop.mujoco_runner.run._grid",
    ]
