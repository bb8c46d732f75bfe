"""slide-to-roll: a uniform ball launched sliding without spin, until it rolls.

A uniform ball (radius R, mass M, inertia I = 2/5 M R^2) on a level table is launched at
v0 along x with no spin. Under Coulomb's friction (coefficient mu) the table's force on it
is -mu M g along x while it slides, so

    v(t) = v0 - mu g t,    R w(t) = (M R^2 / I) mu g t = 5/2 mu g t,

and the contact's slip u = v - R w falls linearly, u(t) = v0 - 7/2 mu g t, until it is zero
at t_roll = 2 v0 / (7 mu g); then the ball rolls at v = 5 v0 / 7 (friction vanishes, and
with condim 3 nothing resists rolling).

MuJoCo's soft contact reaches mu N only once the slip is large against what its friction
rows' reference acceleration asks for; at the end of the slide it lets the slip relax over
its time constant instead of stopping it at once. So the probe reads the time at which the
slip falls to :data:`SLIP_FRACTION` of v0, whose exact value is
t(u) = 2 (v0 - u) / (7 mu g), and the speed after the slide has ended.

Modes: ``pyramidal`` and ``elliptic`` (MuJoCo's two friction cones, condim 3, impratio 1,
MuJoCo's default solref and solimp).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from tippetop.compare.probes.base import G_MPS2, Curve, Measured, Probe, Quantity, Setup, fmt

if TYPE_CHECKING:
    from tippetop.mujoco_runner.probe_run import ProbeTrace

#: The slip, as a fraction of v0, at which the slide counts as over.
SLIP_FRACTION = 0.01

_XML = """<mujoco model="slide-to-roll">
  <option timestep="0.002" gravity="0 0 {g}" cone="{cone}"/>
  <worldbody>
    <geom name="table" type="plane" size="5 5 0.1" friction="{mu} 0 0"/>
    <body name="ball" pos="0 0 {R}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{R}" mass="{M}" friction="{mu} 0 0" condim="3"/>
    </body>
  </worldbody>
</mujoco>"""


@dataclass(frozen=True)
class SlideToRoll(Probe):
    """slide-to-roll: t_roll = 2 v0 / (7 mu g), then v = 5 v0 / 7 (module docstring)."""

    name: ClassVar[str] = "slide-to-roll"
    title: ClassVar[str] = "a ball launched sliding rolls after 2 v0 / (7 mu g) at 5 v0 / 7"
    modes: ClassVar[tuple[str, ...]] = ("pyramidal", "elliptic")
    params: ClassVar[dict[str, float]] = {"mu": 0.1, "v0": 1.0, "R": 0.02, "M": 0.05,
                                          "g": G_MPS2}
    quantities: ClassVar[tuple[Quantity, ...]] = (
        Quantity("roll_time_s", "s", 0.01,
                 f"time for the slip to fall to {SLIP_FRACTION:g} v0",
                 "MuJoCo's default friction relaxes the last of the slip over its time "
                 "constant, 0.02 s; half of it"),
        Quantity("roll_speed_mps", "m/s", 0.005,
                 "the ball's speed once it rolls (at the end of the run)",
                 "0.5 % of v0 = 1 m/s: the speed lost while the soft contact relaxes"),
    )

    def t_roll(self) -> float:
        """Coulomb's roll time, 2 v0 / (7 mu g) (s)."""
        return 2.0 * self.p("v0") / (7.0 * self.p("mu") * self.p("g"))

    def setup(self, mode: str) -> Setup:
        """The ball on its table, launched at v0 along x; run to 3 t_roll."""
        R = self.p("R")
        xml = _XML.format(g=fmt(-self.p("g")), cone=mode, mu=fmt(self.p("mu")), R=fmt(R),
                          M=fmt(self.p("M")))
        return Setup(xml, "ball", (0.0, 0.0, R, 1.0, 0.0, 0.0, 0.0),
                     (self.p("v0"), 0.0, 0.0, 0.0, 0.0, 0.0), 3.0 * self.t_roll())

    def slip(self, trace: ProbeTrace) -> np.ndarray:
        """The contact point's slip along x, v - R w_y (m/s), at every step."""
        return trace.qvel[:, 0] - self.p("R") * trace.qvel[:, 4]

    def measure(self, mode: str, trace: ProbeTrace) -> list[Measured]:
        """The slide's end against t(u) = 2 (v0 - u) / (7 mu g), the speed against 5 v0 / 7."""
        v0, mu, g = self.p("v0"), self.p("mu"), self.p("g")
        u_end = SLIP_FRACTION * v0
        slip = self.slip(trace)
        below = np.flatnonzero(slip <= u_end)
        if len(below):
            i = int(below[0])
            if i > 0:  # linear between the two steps around the crossing
                s0, s1 = slip[i - 1], slip[i]
                t0, t1 = trace.time[i - 1], trace.time[i]
                t_end = float(t0 + (s0 - u_end) / (s0 - s1) * (t1 - t0))
            else:
                t_end = float(trace.time[0])
            note = ""
        else:
            t_end, note = float("nan"), "the slip never fell to the threshold"
        exact_t = 2.0 * (v0 - u_end) / (7.0 * mu * g)
        speed = float(np.hypot(trace.qvel[-1, 0], trace.qvel[-1, 1]))
        return [Measured(self.quantity("roll_time_s"), t_end, exact_t, note),
                Measured(self.quantity("roll_speed_mps"), speed, 5.0 * v0 / 7.0)]

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:
        """The slip against u(t) = max(v0 - 7/2 mu g t, 0)."""
        v0, mu, g = self.p("v0"), self.p("mu"), self.p("g")
        exact = np.maximum(v0 - 3.5 * mu * g * trace.time, 0.0)
        return Curve("slip speed (m/s)", trace.time, self.slip(trace), exact)


__all__ = ["SLIP_FRACTION", "SlideToRoll"]
