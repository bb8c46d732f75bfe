"""The MuJoCo model a plan runs, and what it runs, read back from the compiled model.

:func:`build_model` compiles a :class:`~tippetop.models.plan.MujocoPlan`'s MJCF text (every
option and contact setting is written in it) and checks that the compiled model holds the
plan's values. :func:`settings_that_ran` reads back what runs: the options from ``model.opt``
and the contact settings from the top's contact in an mjData (MuJoCo has mixed the two geoms'
values into it), so a summary reports what ran, never what was asked for.
"""

from __future__ import annotations

import warnings
from typing import Any

import mujoco
import numpy as np

from tippetop.models.errors import TippetopError
from tippetop.models.mjcf import CONES, INTEGRATORS
from tippetop.models.plan import MujocoPlan
from tippetop.mujoco_runner.model import TopModel, TopModelWarning, load_top


def build_model(plan: MujocoPlan) -> TopModel:
    """The compiled top of a plan: its MJCF text, compiled, checked against the plan.

    Raises:
        TippetopError: For MJCF MuJoCo rejects, or a compiled model that does not hold the
            plan's values (this MuJoCo compiles the text otherwise); nothing is simulated then.
    """
    if plan.source is None:
        with warnings.catch_warnings():  # a generated stem is asked for: nothing to warn of
            warnings.simplefilter("ignore", TopModelWarning)
            top_model = load_top(plan.mjcf)
    else:
        top_model = load_top(plan.mjcf)
    check_model(plan, top_model.model)
    return top_model


def check_model(plan: MujocoPlan, model: mujoco.MjModel) -> None:
    """Refuse a compiled model that does not hold the plan's options and contact settings.

    Raises:
        TippetopError: Naming the first values that differ.
    """
    differ = plan_differences(plan, model)
    if differ:
        raise TippetopError("mjcf: expected the compiled model to hold the plan's values, got "
                            + "; ".join(differ[:4]))


def plan_differences(plan: MujocoPlan, model: mujoco.MjModel) -> list[str]:
    """Where a compiled model's options and contact settings differ from the plan's."""
    opt = model.opt
    out = []
    have = {"timestep_s": float(opt.timestep), "integrator": integrator_name(int(opt.integrator)),
            "cone": cone_name(int(opt.cone)), "impratio": float(opt.impratio),
            "noslip_iterations": int(opt.noslip_iterations),
            "gravity_mps2": tuple(float(g) for g in opt.gravity),
            "iterations": int(opt.iterations), "tolerance": float(opt.tolerance),
            "contacts_on": contacts_enabled(model)}
    for key, value in have.items():
        if value != getattr(plan, key):
            out.append(f"{key} {value!r}, the plan's {getattr(plan, key)!r}")
    for c in plan.contacts:
        if c.element == "geom":
            got = (int(model.geom_condim[c.index]), model.geom_friction[c.index],
                   model.geom_solref[c.index], model.geom_solimp[c.index],
                   int(model.geom_contype[c.index]), int(model.geom_conaffinity[c.index]))
            want = (c.condim, c.friction, c.solref, c.solimp, c.contype, c.conaffinity)
        else:
            got = (int(model.pair_dim[c.index]), model.pair_friction[c.index],
                   model.pair_solref[c.index], model.pair_solimp[c.index],
                   model.pair_solreffriction[c.index])
            want = (c.condim, c.friction, c.solref, c.solimp, c.solreffriction or (0.0, 0.0))
        if not all(np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
                   for a, b in zip(got, want, strict=True)):
            out.append(f"{c.element} {c.name}'s contact settings")
    return out


def settings_that_ran(top_model: TopModel, data: mujoco.MjData) -> dict[str, Any]:
    """What runs, read back from the compiled model and from ``data``'s contacts.

    The contact settings are those of the top's first contact in ``data`` (after a forward
    pass: MuJoCo has mixed the two geoms' values into it); with no contact, those of the
    ball geom. Keys: ``timestep_s``, ``integrator``, ``cone``, ``impratio``,
    ``noslip_iterations``, ``condim``, ``mu``, ``torsional``, ``rolling``, ``solref``,
    ``solreffriction`` (None unless a contact pair sets it), ``solimp``, ``contact_source``.
    """
    model = top_model.model
    opt = model.opt
    out: dict[str, Any] = {
        "timestep_s": float(opt.timestep),
        "integrator": integrator_name(int(opt.integrator)),
        "cone": cone_name(int(opt.cone)),
        "impratio": float(opt.impratio),
        "noslip_iterations": int(opt.noslip_iterations),
        "gravity_mps2": float(-opt.gravity[2]),
        "iterations": int(opt.iterations),
        "tolerance": float(opt.tolerance),
        "contacts": contacts_enabled(model),
    }
    b = top_model.body_id
    for i in range(data.ncon):
        c = data.contact[i]
        if b in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]):
            fr = [float(v) for v in c.friction]
            out.update(friction_that_acts(int(c.dim), fr[0], fr[2], fr[3]),
                       solref=[float(v) for v in c.solref],
                       solreffriction=_solreffriction(c.solreffriction),
                       solimp=[float(v) for v in c.solimp], contact_source="contact at t = 0")
            return out
    g = top_model.ball_geom_id
    fr = [float(v) for v in model.geom_friction[g]]
    out.update(friction_that_acts(int(model.geom_condim[g]), *fr),
               solref=[float(v) for v in model.geom_solref[g]],
               solreffriction=None,  # a geom has none: only a <pair> sets it
               solimp=[float(v) for v in model.geom_solimp[g]],
               contact_source="ball geom (no contact at t = 0)")
    return out


def _solreffriction(values: Any) -> list[float] | None:
    """A contact's own solref of its friction rows, or None where it has none.

    [0, 0], MuJoCo's default, means the friction rows use solref; only an explicit ``<pair>``
    sets it.
    """
    out = [float(v) for v in values]
    return None if not any(out) else out


def contacts_enabled(model: mujoco.MjModel) -> bool:
    """False where the model disables contacts (``<flag contact="disable"/>``)."""
    return not int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)


def friction_that_acts(condim: int, mu: float, torsional: float,
                        rolling: float) -> dict[str, Any]:
    """Condim and the coefficients it uses; None for a coefficient with no friction row."""
    return {"condim": condim, "mu": mu if condim >= 3 else None,
            "torsional": torsional if condim >= 4 else None,
            "rolling": rolling if condim >= 6 else None}


def integrator_name(code: int) -> str:
    """MJCF spelling of an integrator code (``RK4``, ``Euler``, ...)."""
    name = mujoco.mjtIntegrator(code).name.removeprefix("mjINT_")
    return next((s for s in INTEGRATORS if s.upper() == name), name.lower())


def cone_name(code: int) -> str:
    """MJCF spelling of a friction cone code (``pyramidal``, ``elliptic``)."""
    name = mujoco.mjtCone(code).name.removeprefix("mjCONE_").lower()
    return next((s for s in CONES if s == name), name)


__all__ = ["build_model", "check_model", "cone_name", "friction_that_acts", "integrator_name",
           "plan_differences", "settings_that_ran"]
