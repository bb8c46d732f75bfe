"""The reference's integration methods, behind one contract, and the default's choice.

Every method is a compiled kernel in its own module that exposes ``run`` and ``new_stats``:

* ``run(rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor, t_out, Y_out,
  i_out, stats) -> (status, t, i_out)``, called as :func:`reference_ode.dop853.dop853_run` is,
  with its statuses and its ``stats`` slots (``dop853.S_*``);
* ``new_stats(n)``: a fresh ``stats`` vector for a state of size n. A method may keep more after
  the shared slots (a multistep method's history). ``stats[S_H] = 0`` asks every method to start
  afresh (a new first step, no history): :mod:`reference_ode.solve` does so where the motion
  changes abruptly (an impact, a rolling phase's start or end).

A method's module is imported (its kernel loaded or compiled) only when a run asks for it, so
that a run compiles only what it runs (tests/reference_ode/test_compile_scope.py). The names are
:data:`models.options.ODE_METHODS`; ``auto`` picks one from the tolerance (:func:`choose_method`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tippetop.models.errors import TippetopError
from tippetop.models.options import (
    AUTO_RULE,
    AUTO_TAYLOR,
    METHOD_TITLES,
    ODE_METHODS,
    TAYLOR_ORDERS,
    auto_method,
)

__all__ = ["AUTO_RULE", "AUTO_TAYLOR", "METHODS", "Method", "choose_method", "get_method"]


@dataclass(frozen=True)
class Method:
    """One integration method of the reference.

    Attributes:
        name: Its name in ``ode.method`` (:data:`models.options.ODE_METHODS`).
        module: Its module under ``tippetop.reference_ode``.
        order: The order of the solution it carries (the highest, for a variable order).
        title: What it is, in a few words, for tables and run summaries.
        hands_over_stiff: Its stiffness flag does not decide on rolling phases: where it
            flags a stretch of steps as stiff (with rolling phases armed), the run goes on with
            DOP853 from there, whose detector decides (:func:`solve.simulate_ode`). The Adams
            method's flag is set by a stability boundary of about 2.4 against DOP853's 6.1, so
            it would roll where DOP853 integrates the law (Lambda = 1e-4 m/s on fig3).
    """

    name: str
    module: str
    order: int
    title: str
    hands_over_stiff: bool = False

    def _kernel(self):
        return importlib.import_module(f"tippetop.reference_ode.{self.module}")

    @property
    def run(self) -> Callable:
        """The kernel, called as :func:`dop853.dop853_run` (imports the method's module)."""
        return self._kernel().run

    def new_stats(self, n: int) -> np.ndarray:
        """A fresh ``stats`` vector for a state of size n."""
        return self._kernel().new_stats(n)


#: The methods there are, by name.
METHODS: dict[str, Method] = {m.name: m for m in (
    Method("dop853", "dop853", 8, METHOD_TITLES["dop853"]),
    Method("vern9", "verner", 9, METHOD_TITLES["vern9"]),
    Method("adams", "adams", 12, METHOD_TITLES["adams"], hands_over_stiff=True),
    Method("taylor", "taylor", max(o for _, o in TAYLOR_ORDERS), METHOD_TITLES["taylor"],
           hands_over_stiff=True),
)}
assert tuple(METHODS) == ODE_METHODS[1:]

def choose_method(rtol: float, taylor: bool = False) -> tuple[str, float]:
    """What ``auto`` runs at relative tolerance ``rtol``: (method, its rtol per rtol asked).

    The rule is :data:`models.options.AUTO_TAYLOR` where the Taylor method runs the problem
    (``taylor``), else :data:`models.options.AUTO_RULE` (a plan says what will run from them too).
    """
    return auto_method(rtol, taylor)


def get_method(name: str, rtol: float, taylor: bool = False) -> tuple[Method, float]:
    """What ``ode.method = name`` runs at ``rtol``: the method and the factor on the tolerances.

    ``auto`` resolved by :func:`choose_method` (``taylor``: whether the Taylor method runs the
    problem); a named method runs at the tolerances asked (factor 1).
    """
    factor = 1.0
    if name == "auto":
        name, factor = choose_method(rtol, taylor)
    if name not in METHODS:
        raise TippetopError(f"ode.method: expected one of {', '.join(ODE_METHODS)}, got "
                            f"{name!r}")
    return METHODS[name], factor
