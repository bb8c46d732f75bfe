"""Sizes: no function over 100 lines outside the compiled kernels; parameters past 10 shrink.

Issue 42, item 7. A function's length is its ``def`` line through its last line (the
docstring included, decorators not), less the lines of the compiled kernels nested in it (a
factory of Warp kernels is measured without its kernels). A compiled kernel is a function
decorated by a compiler (numba's ``njit``/``jit``/``cfunc``, Warp's ``kernel``/``func``) or one
named in :data:`COMPILED_BY_CALL`, which the module compiles with a call (``njit(...)(f)``);
a kernel is one loop that the compiler sees whole, and it is long for that reason.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.test_layers import ROOT, _modules

#: The longest a function outside the compiled kernels may be (lines).
MAX_FUNCTION_LINES = 100
#: The most parameters a function outside the compiled kernels may take.
MAX_PARAMETERS = 10
#: Decorator names that compile the function they decorate.
COMPILERS = frozenset({"njit", "jit", "cfunc", "kernel", "func", "vectorize"})
#: Functions a module compiles with a call rather than a decorator: (file, name).
COMPILED_BY_CALL = frozenset({
    ("mujoco_runner/friction_callback.py", "_passive"),
    ("mujoco_runner/stepper.py", "_accumulate"),
    ("mujoco_runner/stepper.py", "_advance"),
})
#: Functions that still take more than MAX_PARAMETERS parameters (issue 42, item 7: option
#: objects in their place). The list may only shrink: a function that leaves it must leave it
#: here too, and no function may join it.
OVER_PARAMETERS_TODO = frozenset({
    ("mujoco_runner/worker/mjx_stepper.py", "table_pass"),
    ("mujoco_runner/worker/mjx_stepper.py", "window_add"),
    ("reference_ode/adams.py", "run"),
    ("reference_ode/taylor.py", "run"),
    ("reference_ode/verner.py", "run"),
    ("reference_ode/dop853.py", "dop853_run"),
})

_FUNCS = (ast.FunctionDef, ast.AsyncFunctionDef)


def _decorator_name(node: ast.expr) -> str:
    while isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute):
        return node.attr
    return node.id if isinstance(node, ast.Name) else ""


def _is_kernel(node: ast.AST, rel: str) -> bool:
    return isinstance(node, _FUNCS) and (
        any(_decorator_name(d) in COMPILERS for d in node.decorator_list)
        or (rel, node.name) in COMPILED_BY_CALL)


def _functions() -> list[tuple[str, ast.FunctionDef, bool]]:
    """(file, function, is a compiled kernel) for every function of the four packages."""
    out = []
    for path in _modules().values():
        rel = str(path.relative_to(ROOT))
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, _FUNCS):
                out.append((rel, node, _is_kernel(node, rel)))
    return out


def _length(node: ast.FunctionDef, rel: str) -> int:
    """Lines of a function, less those of the compiled kernels nested in it."""
    n = node.end_lineno - node.lineno + 1
    for inner in ast.walk(node):
        if inner is not node and _is_kernel(inner, rel):
            first = min([inner.lineno] + [d.lineno for d in inner.decorator_list])
            n -= inner.end_lineno - first + 1
    return n


def _parameters(node: ast.FunctionDef) -> int:
    a = node.args
    names = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    return len([n for n in names if n not in ("self", "cls")])


def test_no_function_is_over_100_lines_outside_the_kernels() -> None:
    long = sorted(f"{rel}: {node.name} ({_length(node, rel)} lines)"
                  for rel, node, kernel in _functions()
                  if not kernel and _length(node, rel) > MAX_FUNCTION_LINES)
    assert long == []


def test_the_functions_compiled_by_a_call_are_compiled_there() -> None:
    """Each entry of COMPILED_BY_CALL exists and its module passes it to a compiler's call."""
    for rel, name in sorted(COMPILED_BY_CALL):
        text = (ROOT / rel).read_text()
        assert re.search(rf"^def {name}\(", text, re.M), (rel, name)
        assert re.search(rf"(njit|cfunc|jit)\([^()]*(\([^()]*\)[^()]*)*\)\({name}\)", text), \
            (rel, name)


def test_no_function_joins_those_over_10_parameters() -> None:
    over = {(rel, node.name) for rel, node, kernel in _functions()
            if not kernel and _parameters(node) > MAX_PARAMETERS}
    assert sorted(over - OVER_PARAMETERS_TODO) == []
    # a function mended leaves the list: it may only shrink
    assert sorted(OVER_PARAMETERS_TODO - over) == []


def test_the_size_check_sees_a_long_function_and_skips_a_kernel(tmp_path: Path) -> None:
    body = "".join(f"    x{i} = {i}\n" for i in range(101))
    src = (f"def long():\n{body}\n\n@nb.njit(cache=True)\ndef kern():\n{body}\n\n"
           f"def factory(wp):\n    @wp.kernel\n    def k():\n{body.replace('    ', '        ')}"
           f"    return k\n")
    tree = ast.parse(src)
    funcs = {n.name: n for n in ast.walk(tree) if isinstance(n, _FUNCS)}
    assert _length(funcs["long"], "x.py") == 102 and not _is_kernel(funcs["long"], "x.py")
    assert _is_kernel(funcs["kern"], "x.py") and _is_kernel(funcs["k"], "x.py")
    assert _length(funcs["factory"], "x.py") == 2
