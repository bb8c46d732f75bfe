"""The note before runs that compile code: what is compiled, where, and about how long.

The reference ODE and MuJoCo's stepper are numba code, compiled on first use and cached on disk
(:mod:`tippetop.reference_ode._jit`). In a fresh cache the first run sits for seconds with
nothing to show; a person at a terminal is told once, before the runs start.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any, TextIO

#: Compiled parts: (module, what it is, seconds to compile on a 2-core machine). Measured in a
#: fresh ``TIPPETOP_CACHE`` against a second time: ``tippetop simulate fig3`` (the Taylor method)
#: 18.0 s against 1.5 s, ``--set ode.method=dop853`` 11.3 s against 1.3 s, ``vern9`` 13.3 s
#: against 1.5 s, ``adams`` 11.2 s against 1.4 s (of each, about 4 s the equations of motion);
#: ``--set ode.formulation=paper`` 2.8 s against 1.4 s; MuJoCo's paper mode 3.9 s against 3.0 s,
#: native mode 3.3 s against 2.4 s.
PARTS: tuple[tuple[str, str, float], ...] = (
    ("tippetop.reference_ode.top", "the equations of motion", 4.0),
    ("tippetop.reference_ode.paper", "the paper's Appendix A equations", 1.5),
    ("tippetop.mujoco_runner.stepper", "MuJoCo's stepper", 1.0),
    ("tippetop.mujoco_runner.friction_callback", "the paper's law as a MuJoCo callback", 1.0),
)
#: The reference's integrators, by the method that runs (the plan's, ``auto`` resolved): the
#: kernel's name in the compiled-code cache (:mod:`tippetop.reference_ode.driver`; the Taylor
#: method's carries its order) and seconds to compile it, its helpers included (the measured
#: totals above, less the equations of motion).
INTEGRATOR_S: dict[str, float] = {"taylor": 12.5, "dop853": 6.0, "vern9": 8.0, "adams": 6.0}
#: Below this many seconds of compiling nothing is said: the run's own output follows soon.
QUIET_BELOW_S = 3.0
#: A reference run that enters a rolling phase compiles it then (measured: about 6 s more).
ROLLING_S = 6.0

_said = False


def _integrator(plan: Any) -> tuple[str, str, float]:
    """The reference's integrator that ``plan`` runs: (kernel name prefix, what, seconds)."""
    ran = plan.ode.what_runs()
    title = ran["method"]  # e.g. 'taylor (order 12)'
    name = title.split(" ")[0]
    prefix = name
    if name == "taylor":
        prefix = f"taylor_p{title.split('order ')[1].rstrip(')')}"
    return (f"kernel:{prefix}", f"the reference's integrator ({title})",
            INTEGRATOR_S.get(name, 6.0))


def _needs(plan: Any) -> set[str]:
    """The modules of :data:`PARTS` a run of ``plan`` compiles (the in-process engines')."""
    if plan.ode is not None:
        out = {"tippetop.reference_ode.top"}
        if plan.ode.options.formulation == "paper":
            out.add("tippetop.reference_ode.paper")
        return out
    out = {"tippetop.mujoco_runner.stepper"}
    if plan.mujoco.friction == "paper" and plan.mujoco.law is not None:
        out.add("tippetop.mujoco_runner.friction_callback")
    return out


def _kernel_compiled(prefix: str) -> bool:
    """Whether the compiled-code cache holds a kernel named ``prefix``_HASH.

    Any of its hashes: the kernel's source, and so its hash, is known only once its module is
    imported, which compiles.
    """
    from tippetop.reference_ode._jit import is_compiled
    from tippetop.reference_ode.driver import source_dir

    return any(is_compiled(f) for f in source_dir().glob(f"{prefix}_*.py"))


def _todo(plans: Sequence[Any]) -> list[tuple[str, str, float]]:
    """The parts that running ``plans`` here would compile (not yet cached)."""
    from importlib.util import find_spec

    from tippetop.reference_ode._jit import is_compiled

    needed: set[str] = set()
    integrators: dict[str, tuple[str, str, float]] = {}
    for p in plans:
        needed |= _needs(p)
        if p.ode is not None:
            key, what, seconds = _integrator(p)
            integrators.setdefault(key, (key, what, seconds))
    todo = [part for key, part in integrators.items()
            if not _kernel_compiled(key.removeprefix("kernel:"))]
    for module, what, seconds in PARTS:
        if module not in needed:
            continue
        spec = find_spec(module)  # not imported: importing a module compiles it
        if spec is not None and spec.origin and not is_compiled(spec.origin):
            todo.append((module, what, seconds))
    return todo


def compile_s(plans: Sequence[Any]) -> float:
    """About how long running ``plans`` here compiles first (s); 0 under :data:`QUIET_BELOW_S`.

    The progress bar says it while the workers compile (before any run has moved).
    """
    total = sum(s for _, _, s in _todo(plans))
    return total if total >= QUIET_BELOW_S else 0.0


def compile_note(plans: Sequence[Any]) -> str | None:
    """The line to print before running ``plans`` in this process's engines, or None.

    Args:
        plans: Run plans (:class:`tippetop.models.plan.RunPlan`) of the installed engines.

    Returns:
        ``tippetop: compiling the reference's integrator (taylor (order 12)) and the equations
        of motion into FOLDER, once for this code: about 16 s (...)``, or None when the cache
        holds the code or compiling takes under :data:`QUIET_BELOW_S`.
    """
    from tippetop.reference_ode import NUMBA_CACHE_DIR

    todo = _todo(plans)
    total = sum(s for _, _, s in todo)
    if total < QUIET_BELOW_S:
        return None
    where = f" into {NUMBA_CACHE_DIR}" if NUMBA_CACHE_DIR is not None else ""
    rolling = (f" ({ROLLING_S:.0f} s more if a run enters a rolling phase)"
               if any(m == "tippetop.reference_ode.top" for m, _, _ in todo) else "")
    names = [w for _, w, _ in todo]
    what = names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"
    return (f"tippetop: compiling {what}{where}, once for this code: about {total:.0f} s"
            f"{rolling}")


def say_compile(plans: Sequence[Any], stream: TextIO | None = None) -> None:
    """Print :func:`compile_note` once per process, on a terminal only (stderr by default)."""
    global _said
    out = stream or sys.stderr
    if _said or not out.isatty():
        return
    note = compile_note(plans)
    if note is not None:
        _said = True
        out.write(note + "\n")
        out.flush()


__all__ = ["INTEGRATOR_S", "PARTS", "QUIET_BELOW_S", "compile_note", "compile_s", "say_compile"]
