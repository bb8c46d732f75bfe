"""Probes: each part of an engine measured on a motion with a closed-form answer.

:data:`REGISTRY` names every probe (``tippetop probe NAME``) and where its class is;
:func:`probe_class` loads one, :func:`probe_names` lists them. What a probe is:
:mod:`.base`; running them on engines: :mod:`.study`.
"""

from __future__ import annotations

import importlib

from tippetop.compare.measures.metrics import Metric, Tolerance
from tippetop.compare.probes.base import Probe, metric_name
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


def _metrics_of(cls: type[Probe]) -> dict[str, Metric]:
    out: dict[str, Metric] = {}
    for q in cls.quantities:
        mname = metric_name(cls.name, q.name)
        out[mname] = Metric(
            name=mname, unit=q.unit, meaning=f"{cls.name}: {q.what}", kinds=("probe",),
            tolerance=Tolerance("abs", q.baseline_tolerance, unit=q.unit,
                                why=q.baseline_why if q.baseline is not None else
                                "a tenth of its tolerance against the exact value: a move "
                                "that takes a tenth of that allowance is a change"),
            agreement=Tolerance("abs", q.tolerance, unit=q.unit, why=q.why),
            against="theory", label=q.name)
    return out


def probe_metrics() -> dict[str, Metric]:
    """Every probe quantity as a declared metric (``probe.<probe>.<quantity>``, kind ``probe``).

    Its agreement is with the theory (the closed form), within the quantity's tolerance; its
    tolerance against a baseline (the nightly, the matrix between engines, bisect) is a tenth
    of that.
    """
    return {k: m for name in REGISTRY for k, m in _metrics_of(probe_class(name)).items()}


def probe_metric(name: str) -> Metric:
    """The declared metric ``probe.<probe>.<quantity>``.

    Raises:
        KeyError: No such probe quantity.
    """
    _, probe, _q = name.split(".", 2) if name.count(".") >= 2 else ("", "", "")
    if probe not in REGISTRY:
        raise KeyError(name)
    return _metrics_of(probe_class(probe))[name]


__all__ = ["REGISTRY", "probe_class", "probe_metric", "probe_metrics", "probe_names"]
