"""Probes: each part of an engine measured on a motion with a closed-form answer.

:data:`REGISTRY` names every probe (``tippetop probe NAME``) and where its class is;
:func:`probe_class` loads one, :func:`probe_names` lists them. What a probe is:
:mod:`.base`; running them on engines: :mod:`.study`.
"""

from __future__ import annotations

import importlib

from tippetop.compare.probes.base import Probe
from tippetop.models.errors import TippetopError, did_you_mean

#: Each probe's name -> ``module:Class`` under this package, in the order they run.
REGISTRY: dict[str, str] = {
    "slide-to-roll": "slide_to_roll:SlideToRoll",
    "incline": "incline:Incline",
    "spin-decay": "spin_decay:SpinDecay",
    "roll-resistance": "roll_resistance:RollResistance",
    "lift-off": "lift_off:LiftOff",
    "torque-free": "torque_free:TorqueFree",
}


def probe_names() -> tuple[str, ...]:
    """Every probe's name, in the order they run."""
    return tuple(REGISTRY)


def probe_class(name: str) -> type[Probe]:
    """The probe called ``name``.

    Raises:
        TippetopError: No probe of that name (one line, with a did-you-mean).
    """
    if name not in REGISTRY:
        raise TippetopError(f"probe: expected one of {', '.join(REGISTRY)}, got {name!r}"
                            f"{did_you_mean(name, REGISTRY)}")
    module, cls = REGISTRY[name].split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), cls)


__all__ = ["REGISTRY", "probe_class", "probe_names"]
