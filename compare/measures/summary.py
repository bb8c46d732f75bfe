"""What a run's summary says, for a person and for a program: pure functions of it.

Whether a run finished (:func:`run_failed`), what ran in one line (:func:`describe_ran`), the
contact settings it ran as MJCF to paste (:func:`mjcf_attributes`), and the steps it took for
the cost model (:func:`measured_steps`). Nothing here starts a run.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from tippetop.models.numbers import number_text, solver_text
from tippetop.models.plan import NATIVE_LAW

#: ``friction_law`` of a run on MuJoCo's own contact: today's, and the release before's.
NATIVE_LAWS = (NATIVE_LAW, "mujoco-native")

#: The summary keys of a failed run that would be numbers: a failed run reports none.
RESULT_KEYS = ("theta_final", "theta_asymp", "t_invert", "J_rel_drift", "energy_monotone",
               "energy_rise_rel")
#: The statuses of a run that ended as the physics says (the sphere leaving the table is an
#: end the model reports); any other status (MuJoCo's ``diverged``, the reference's
#: ``max_steps``, ``step_too_small``, ``singular``, ``chatter``, ``flat_end``) is a failed run.
FINISHED_STATUSES = ("ok", "contact_lost", "hop")


def measured_steps(summaries: Iterable[dict[str, Any] | None],
                   spec: str = "mujoco") -> list[tuple[int, float]]:
    """``(n_steps, wall_s)`` of each finished MuJoCo run on the engine ``spec``.

    The runs of that engine only (a summary's ``engine``): each engine's steps cost what it
    does. For the cost model (:func:`tippetop.compare.running.cost.record_mujoco_runs`).
    """
    return [(int(s["n_steps"]), float(s["wall_s"])) for s in summaries
            if s is not None and s.get("engine") == spec and s.get("status") == "ok"
            and s.get("n_steps") and s.get("wall_s")]


def run_failed(summary: dict[str, Any]) -> bool:
    """Whether a run's summary is a failed run's (it carries no numbers, only the reason)."""
    return summary.get("status", "ok") not in FINISHED_STATUSES


def describe_ran(summary: dict[str, Any]) -> str:
    """One line on what a run's summary says ran (the settings read back, not those asked for).

    Example: ``MuJoCo RK4 at dt = 2e-4 s, native friction: pyramidal cone, condim 3,
    mu 0.104, impratio 1.41, solref [0.002 s, 1], solimp [0.05, 0.95, 0.001 m, 0.5, 2]``
    (solref's time constant and solimp's width carry their units; with a negative solref,
    MuJoCo's stiffness and damping, none).
    """
    if summary.get("engine") == "ode":
        return (f"reference ODE, DOP853 on the {summary.get('formulation')} formulation at "
                f"rtol {number_text(summary.get('rtol'))}, law {summary.get('friction_law')}")
    if summary.get("timestep_s") is None:
        return "MuJoCo (no settings recorded)"
    head = f"MuJoCo {summary.get('integrator')} at dt = {number_text(summary['timestep_s'], 's')}, "
    solref, solimp = (f"{k} [{solver_text(k, summary[k])}]" if summary.get(k) is not None
                      else f"{k} -" for k in ("solref", "solimp"))
    contact = f"condim {summary.get('condim')}, {solref}, {solimp}"
    law = summary.get("friction_law")
    native = law in NATIVE_LAWS or (law is None and summary.get("mode") != "paper")
    if not native:
        mu = summary.get("law_mu")
        applied = f"the paper-mode law {law}" + (f" (mu {number_text(mu)})" if mu is not None
                                                 else "")
        return f"{head}{applied} on a frictionless contact: {contact}"
    friction = [f"{summary.get('cone')} cone", f"condim {summary.get('condim')}"]
    for key, unit in (("mu", ""), ("torsional", "m"), ("rolling", "m")):
        if summary.get(key) is not None:
            friction.append(f"{key} {number_text(summary[key], unit if summary[key] else '')}")
    friction.append(f"impratio {number_text(summary.get('impratio'))}")
    friction += [solref, solimp]
    return f"{head}native friction: " + ", ".join(friction)


def mjcf_attributes(summary: dict[str, Any]) -> tuple[str, str]:
    """The contact settings a MuJoCo run ran, as MJCF to paste.

    Returns:
        The ``<option .../>`` element (timestep, integrator, cone, impratio) and the contact's
        attributes (condim, friction with its torsional and rolling parts, solref, solimp),
        read from the run's summary.
    """
    def nums(v: Any) -> str:
        return " ".join(f"{x:g}" for x in v)

    s = summary
    friction = [s.get("mu") or 0.0, s.get("torsional") or 0.005, s.get("rolling") or 0.0001]
    return ((f'<option timestep="{s["timestep_s"]:g}" integrator="{s["integrator"]}" '
             f'cone="{s["cone"]}" impratio="{s["impratio"]:g}"/>'),
            (f'condim="{s.get("condim", 3)}" friction="{nums(friction)}" '
             f'solref="{nums(s["solref"])}" solimp="{nums(s["solimp"])}"'))


__all__ = ["FINISHED_STATUSES", "NATIVE_LAWS", "RESULT_KEYS", "describe_ran", "measured_steps",
           "mjcf_attributes", "run_failed"]
