"""What a difference between two engines follows, and which of the two is nearer the truth.

For every (scene, mode) where two engines differ (:mod:`.matrix`), each engine involved runs
the scene again with one subsystem changed at a time (:data:`CHANGES`: the integrator, contacts
off, friction off, the other cone, a tighter solver, a quarter of the timestep). Per
difference, :func:`attribute` says which changes make the pair agree and which do not, with
the metric's values and the largest theta(t) gap under each change; :func:`closer` says which
engine is nearer the reference ODE on that metric, and nearer its own converged answer (the
same engine at a quarter of the timestep).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.results.matrix import Attribution, Closer, Evidence
from tippetop.models.plan import MujocoPlan
from tippetop.models.scene import Override

#: The solver of "solver tighter": this many times the iterations, this tolerance.
SOLVER_ITERATIONS_FACTOR = 10
SOLVER_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Change:
    """One subsystem changed for attribution.

    Attributes:
        name: As reported (``integrator Euler``, ``friction off``, ...).
        overrides: The scene keys that make the change, from the plan that ran (None: the
            change does not apply to this plan, ``why_not`` says why).
        why_not: Why the change does not apply.
    """

    name: str
    overrides: tuple[Override, ...] | None
    why_not: str = ""


def changes_for(plan: MujocoPlan) -> list[Change]:
    """The changes of attribution for ``plan`` (the run as it ran on the first engine).

    The integrators other than the plan's own; contacts off; friction off; the other cone
    (native mode: paper mode's contact has no friction rows); a tighter solver; a quarter of
    the timestep.
    """
    out = [Change(f"integrator {name}", (Override.of("mujoco.integrator", name),))
           for name in ("Euler", "implicitfast", "RK4") if name != plan.integrator]
    out.append(Change("contacts off", (Override.of("mujoco.contacts", False),)))
    out.append(Change("friction off", (Override.of("effects.sliding", False),)))
    other = "pyramidal" if plan.cone == "elliptic" else "elliptic"
    out.append(Change(f"cone {other}", (Override.of("mujoco.cone", other),))
               if plan.friction == "native"
               else Change(f"cone {other}", None, "paper mode's contact has no friction rows"))
    it = max(SOLVER_ITERATIONS_FACTOR * plan.iterations, 1000)
    out.append(Change(f"solver {it} iterations, tolerance {SOLVER_TOLERANCE:g}",
                      (Override.of("mujoco.iterations", it),
                       Override.of("mujoco.tolerance", SOLVER_TOLERANCE))))
    out.append(Change("quarter timestep",
                      (Override.of("mujoco.timestep_s", plan.timestep_s / 4),)))
    return out


def theta_gap(a: pd.DataFrame | None, b: pd.DataFrame | None) -> float | None:
    """The largest |theta_a(t) - theta_b(t)| (rad) over the times both reached.

    B is interpolated onto A's samples (the grids are the same plan's, so this is exact when
    both ran to the end). None when either has no table.
    """
    if a is None or b is None or not len(a) or not len(b):
        return None
    t_end = min(float(a["t"].iloc[-1]), float(b["t"].iloc[-1]))
    ta = a["t"].to_numpy()
    keep = ta <= t_end + 1e-12
    if not keep.any():
        return None
    tb = np.interp(ta[keep], b["t"].to_numpy(), b["theta"].to_numpy())
    gap = np.abs(a["theta"].to_numpy()[keep] - tb)
    return float(np.nanmax(gap)) if np.isfinite(gap).any() else None


def value_gap(a: Any, b: Any) -> float | None:
    """|a - b| of two numbers; None when either is missing, a word or not finite."""
    if a is None or b is None or isinstance(a, str) or isinstance(b, str):
        return None
    a, b = float(a), float(b)
    return abs(a - b) if math.isfinite(a) and math.isfinite(b) else None


def attribute(metric: str, a_spec: str, b_spec: str,
              base_gap: float | None,
              evidence: list[Evidence],
              ran_integrator: str | None = None,
              precisions: tuple[str, str] | None = None) -> Attribution:
    """``attribution`` of one difference: what it follows, and the evidence.

    Args:
        metric: The metric that differs.
        a_spec: Engine A.
        b_spec: Engine B.
        base_gap: The largest theta(t) gap of the runs as they ran (rad).
        evidence: Per change, as both engines ran with it (or why it does not apply).
        ran_integrator: The integrator the runs as they ran used (they differ with it).
        precisions: A's and B's precision (``float64``, ``float32``): a difference no change
            removes between two precisions is said to be theirs.

    Returns:
        What it follows (a sentence with the numbers), the evidence, the changes that remove
        it and those that keep it; ``theta_gap_rad`` is ``base_gap``.
    """
    ran = [e for e in evidence if e.applies and e.failed is None]
    removed = [e.change for e in ran if e.agree]
    kept = [e.change for e in ran if not e.agree]
    failed = [e for e in evidence if e.failed]

    def gap_text(names: list[str]) -> str:
        gaps = [e.theta_gap_rad for e in ran if e.change in names
                and e.theta_gap_rad is not None]
        return f"{max(gaps):.2g} rad" if gaps else "n/a"

    integrators = [e for e in ran if e.change.startswith("integrator ")]
    if not ran:
        follows = "not attributed: no change could be run" + (
            f" ({failed[0].change}: {failed[0].failed})" if failed else "")
    elif not removed and precisions is not None and precisions[0] != precisions[1]:
        follows = (f"persists with every change ({len(kept)} tried): the two run in "
                   f"{precisions[0]} and {precisions[1]}, which no option changes")
    elif not removed:
        follows = (f"persists with every change ({len(kept)} tried): not one option of the "
                   "two engines but how each is built (collision, solver, stepping)")
    elif integrator_split(integrators, ran_integrator):
        differs, agrees = integrator_split(integrators, ran_integrator)
        within = gap_text([f"integrator {o}" for o in agrees])
        only = "only " if len(differs) == 1 else ""
        follows = (f"differs {only}with {' and '.join(differs)}"
                   + (f" (as run: {ran_integrator})" if ran_integrator in differs
                      and len(differs) > 1 else "")
                   + f": with {' and '.join(agrees)} the two agree on {metric} (theta(t) then "
                   f"within {within})")
        also = [c for c in removed if not c.startswith("integrator ")]
        if also:
            follows += f"; it also goes away with {', '.join(also)}"
    else:
        follows = (f"goes away with {', '.join(removed)}: the two agree on {metric} "
                   f"(theta(t) then within {gap_text(removed)})"
                   + (f"; stays with {', '.join(kept)}" if kept else "; and with every other "
                      "change too"))
    # the change that brings the two trajectories closest, against the runs as they ran
    gaps = [(e.theta_gap_rad, e.change) for e in ran if e.theta_gap_rad is not None
            and e.change != "contacts off"]
    if gaps and base_gap is not None and base_gap > 0:
        best_gap, best = min(gaps, key=lambda g: g[0])
        if best_gap < 0.1 * base_gap:
            follows += (f"; theta(t) closest with {best}: {best_gap:.2g}"
                        f" rad apart, against {base_gap:.2g} rad as run")
        else:
            follows += (f"; no single change brings theta(t) within a tenth of its "
                        f"{base_gap:.2g} rad gap as run")
    return Attribution(follows, tuple(evidence), tuple(removed), tuple(kept), metric,
                       (a_spec, b_spec), base_gap)


def integrator_split(integrators: list[Evidence],
                     ran_integrator: str | None) -> tuple[list[str], list[str]] | None:
    """(integrators the pair differs with, integrators it agrees with), when both are some.

    The integrator the runs used as they ran counts among those it differs with.
    """
    agrees = [e.change.removeprefix("integrator ") for e in integrators if e.agree]
    differs = [e.change.removeprefix("integrator ") for e in integrators if not e.agree]
    if ran_integrator is not None and ran_integrator not in differs + agrees:
        differs.insert(0, ran_integrator)
    return (differs, agrees) if differs and agrees else None


def closer(metric: str, values: tuple[Any, Any], reference: Any,
           converged: tuple[Any, Any], specs: tuple[str, str]) -> Closer:
    """Which of two engines is nearer the reference ODE, and nearer its own converged answer.

    Args:
        metric: The metric.
        values: A's and B's values as they ran.
        reference: The reference ODE's value on the scene.
        converged: A's and B's values at a quarter of the timestep (None: not run).
        specs: A's and B's specs.

    Returns:
        The engine nearer the reference (a spec, ``tie`` or None), both distances to it, each
        engine's distance to its converged answer and the one nearer it (a distance of an
        exact metric: 0 when it matches, 1 when not).
    """
    def dist(x: Any, y: Any) -> float | None:
        if x is None and y is None:
            return 0.0
        if x is None or y is None:
            return None if metric not in ("outcome", "status") else 1.0
        if isinstance(x, str) or isinstance(y, str):
            return 0.0 if x == y else 1.0
        return value_gap(x, y)

    def nearer(a: float | None, b: float | None) -> str | None:
        if a is None or b is None:
            return None
        return "tie" if a == b else specs[0] if a < b else specs[1]

    da, db = dist(values[0], reference), dist(values[1], reference)
    ca, cb = ((None, None) if converged == (None, None)  # not run
              else (dist(values[0], converged[0]), dist(values[1], converged[1])))
    return Closer(nearer(da, db), reference, (da, db), {specs[0]: ca, specs[1]: cb},
                  nearer(ca, cb))


__all__ = ["SOLVER_ITERATIONS_FACTOR", "SOLVER_TOLERANCE", "Change",
           "attribute", "changes_for", "closer", "integrator_split", "theta_gap", "value_gap"]
