"""What a probe is: a small motion with a closed-form answer, and the quantities it measures.

A probe (:class:`Probe`) declares

- its **modes**: the contact or model settings it is run under (``pyramidal``,
  ``elliptic-impratio10``, ``condim4``, ...), each one run of the engine;
- its **parameters** (:attr:`Probe.params`, SI; ``--set KEY=VALUE`` changes them), with a
  default for each;
- its **quantities** (:class:`Quantity`): each a declared metric with its unit and its
  tolerance, and the reason for that tolerance;
- :meth:`Probe.setup`: the model (MJCF text), the probed body, its start and the duration,
  for one mode and parameter set;
- :meth:`Probe.measure`: from every step of the run (:class:`~tippetop.mujoco_runner.
  probe_run.ProbeTrace`), each quantity's value against its exact value
  (:class:`Measured`);
- :meth:`Probe.curve`: the motion against its exact curve, for the figure.

The exact values are closed forms stated in each probe's docstring (and docs/physics/probes.md).
An error within the tolerance passes; a run that diverges is a failed row with its reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

if TYPE_CHECKING:
    from tippetop.mujoco_runner.probe_run import ProbeTrace

#: Standard gravity (m/s^2): every probe's, unless its ``g`` is set.
G_MPS2 = 9.81


@dataclass(frozen=True)
class Quantity:
    """A quantity a probe measures: a declared metric.

    Attributes:
        name: Its metric name, ``probe.<probe>.<name>`` in ``tippetop metrics``
            (``roll_time_s``).
        unit: Its unit (``s``, ``m/s``, ``um/s``, ``rad/s``, ``1``).
        tolerance: The largest error that passes, in ``unit`` (absolute).
        what: One line: what it is.
        why: One line: why that tolerance (what the engine's model allows, or the step's
            order).
        baseline: How far it may move between two runs (the nightly against its baseline,
            the matrix and bisect between engines), in ``unit``; None: a tenth of
            ``tolerance``.
        baseline_why: Why that bound, when ``baseline`` is given.
    """

    name: str
    unit: str
    tolerance: float
    what: str
    why: str
    baseline: float | None = None
    baseline_why: str = ""

    @property
    def baseline_tolerance(self) -> float:
        """:attr:`baseline`, or a tenth of :attr:`tolerance`."""
        return self.tolerance / 10 if self.baseline is None else self.baseline


@dataclass(frozen=True)
class Measured:
    """One quantity of one run against its exact value."""

    quantity: Quantity
    value: float
    exact: float
    note: str = ""

    @property
    def error(self) -> float:
        """``value - exact`` (NaN when either is not finite)."""
        return self.value - self.exact

    @property
    def passed(self) -> bool:
        """Finite, and within the quantity's tolerance."""
        e = self.error
        return math.isfinite(e) and abs(e) <= self.quantity.tolerance


@dataclass(frozen=True)
class Setup:
    """One run of a probe as the engine gets it.

    Attributes:
        mjcf: The model's MJCF text (its own option: gravity, cone, impratio, ...).
        body: The probed body's name.
        qpos: The start's positions.
        qvel: The start's velocities.
        duration_s: Simulated time.
        timestep_s: The probe's own step (``--timestep`` overrides it).
        integrator: The probe's own integrator (``--integrator`` overrides it).
        ctrl: The actuators' controls, held over the run (a model without actuators: ()).
        law: The paper's friction law applied at the probed ball's lowest point by MuJoCo
            C's passive callback (``{"mu", "Lambda", "R"}``: the worker's ``PaperLaw``, paper
            mode's), or None: the model's own contact friction.
    """

    mjcf: str
    body: str
    qpos: tuple[float, ...]
    qvel: tuple[float, ...]
    duration_s: float
    timestep_s: float = 0.002
    integrator: str = "Euler"
    ctrl: tuple[float, ...] = ()
    law: dict[str, float] | None = None


@dataclass(frozen=True)
class Curve:
    """The motion against its exact curve (one figure panel).

    Attributes:
        label: What is drawn (``slip speed (m/s)``).
        t: Times (s).
        value: The run's value at ``t``.
        exact: The exact value at ``t`` (NaN where there is none).
    """

    label: str
    t: np.ndarray
    value: np.ndarray
    exact: np.ndarray


@dataclass(frozen=True)
class Probe:
    """A probe's declaration; subclasses implement :meth:`setup`, :meth:`measure`, :meth:`curve`.

    Attributes:
        name: The probe's name on the command line (``slide-to-roll``).
        title: One line.
        modes: The settings it runs under, each one run (the first is the default's first).
        params: Its parameters (SI) and their defaults.
        quantities: What it measures.
    """

    name: ClassVar[str] = ""
    title: ClassVar[str] = ""
    modes: ClassVar[tuple[str, ...]] = ()
    params: ClassVar[dict[str, float]] = {}
    quantities: ClassVar[tuple[Quantity, ...]] = ()
    values: dict[str, float] = field(default_factory=dict)

    def p(self, key: str) -> float:
        """Parameter ``key``: as set, else its default."""
        return float(self.values.get(key, self.params[key]))

    def quantity(self, name: str) -> Quantity:
        """The declared quantity ``name``."""
        return next(q for q in self.quantities if q.name == name)

    def quantities_of(self, mode: str) -> tuple[Quantity, ...]:
        """The quantities ``mode``'s run measures (default: all of them)."""
        return self.quantities

    def setup(self, mode: str) -> Setup:  # pragma: no cover - abstract
        """The model, start and duration for ``mode``."""
        raise NotImplementedError

    def measure(self, mode: str, trace: ProbeTrace) -> list[Measured]:  # pragma: no cover
        """Each quantity of ``mode``'s run against its exact value."""
        raise NotImplementedError

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:  # pragma: no cover
        """The motion against its exact curve."""
        raise NotImplementedError


def metric_name(probe: str, quantity: str) -> str:
    """A probe quantity's metric name: ``probe.<probe>.<quantity>``."""
    return f"probe.{probe}.{quantity}"


def sphere_inertia(mass_kg: float, radius_m: float) -> float:
    """A uniform ball's moment of inertia about a diameter, 2/5 M R^2 (kg m^2)."""
    return 0.4 * mass_kg * radius_m * radius_m


def fmt(x: float) -> str:
    """A float for MJCF text: full precision (``repr``)."""
    return repr(float(x))


__all__ = ["G_MPS2", "Curve", "Measured", "Probe", "Quantity", "Setup", "fmt", "metric_name",
           "sphere_inertia"]
