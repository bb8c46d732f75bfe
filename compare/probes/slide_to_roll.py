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

Under the paper's law (its eq. 2.12, modified Coulomb: F = -mu N u / sqrt(u^2 + Lambda^2))
the slip never quite stops: with N = M g,

    du/dt = -7/2 mu g u / sqrt(u^2 + Lambda^2),

which separates: 7/2 mu g t = P(u0) - P(u), with
P(u) = sqrt(u^2 + Lambda^2) - Lambda ln((Lambda + sqrt(u^2 + Lambda^2)) / u). The time to
reach the slip u_end is that, exactly, and the speed is v = 5 v0 / 7 + 2 u / 7 at every slip u
(v0 - v = 2/7 (v0 - u) while only friction acts). The probe's ``paper`` mode runs MuJoCo with a
frictionless normal contact (condim 1) and the law applied at the ball's lowest point by MuJoCo
C's passive callback, as the harness's paper mode does for the top (the normal force the last
evaluation's constraint force): it measures MuJoCo's integrator, not its friction.

Modes: ``pyramidal`` and ``elliptic`` (MuJoCo's two friction cones, condim 3, impratio 1,
MuJoCo's default solref and solimp); ``paper`` (the paper's law, MuJoCo C only).
"""

from __future__ import annotations

import math
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
    <geom name="table" type="plane" size="5 5 0.1" friction="{mu} 0 0" condim="{condim}"/>
    <body name="ball" pos="0 0 {R}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{R}" mass="{M}" friction="{mu} 0 0" condim="{condim}"/>
    </body>
  </worldbody>
</mujoco>"""


@dataclass(frozen=True)
class SlideToRoll(Probe):
    """slide-to-roll: t_roll = 2 v0 / (7 mu g), then v = 5 v0 / 7 (module docstring)."""

    name: ClassVar[str] = "slide-to-roll"
    title: ClassVar[str] = "a ball launched sliding rolls after 2 v0 / (7 mu g) at 5 v0 / 7"
    modes: ClassVar[tuple[str, ...]] = ("pyramidal", "elliptic", "paper")
    params: ClassVar[dict[str, float]] = {"mu": 0.1, "v0": 1.0, "R": 0.02, "M": 0.05,
                                          "g": G_MPS2, "Lambda": 0.01}
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
        """The ball on its table, launched at v0 along x; run to 3 t_roll.

        ``paper``: a frictionless normal contact and the paper's law by the passive callback.
        """
        R = self.p("R")
        paper = mode == "paper"
        xml = _XML.format(g=fmt(-self.p("g")), cone="pyramidal" if paper else mode,
                          mu=fmt(self.p("mu")), R=fmt(R), M=fmt(self.p("M")),
                          condim=1 if paper else 3)
        law = ({"mu": self.p("mu"), "Lambda": self.p("Lambda"), "R": R} if paper else None)
        return Setup(xml, "ball", (0.0, 0.0, R, 1.0, 0.0, 0.0, 0.0),
                     (self.p("v0"), 0.0, 0.0, 0.0, 0.0, 0.0), 3.0 * self.t_roll(), law=law)

    def _P(self, u: np.ndarray | float) -> np.ndarray | float:
        """The paper's law's separated slip: P(u) = s - Lambda ln((Lambda + s) / u)."""
        lam = self.p("Lambda")
        sq = np.sqrt(np.asarray(u, dtype=float) ** 2 + lam * lam)
        return sq - lam * np.log((lam + sq) / np.asarray(u, dtype=float))

    def paper_time(self, u: float) -> float:
        """The paper's law: the time its slip takes from v0 to ``u`` (s)."""
        return float(self._P(self.p("v0")) - self._P(u)) / (3.5 * self.p("mu") * self.p("g"))

    def paper_slip(self, t: np.ndarray) -> np.ndarray:
        """The paper's law: the slip at times ``t``, P(u) = P(v0) - 7/2 mu g t solved for u.

        P is increasing in u, so a bisection in log u (60 halvings: to rounding).
        """
        target = float(self._P(self.p("v0"))) - 3.5 * self.p("mu") * self.p("g") * \
            np.asarray(t, dtype=float)
        lo = np.full(target.shape, math.log(1e-300))
        hi = np.full(target.shape, math.log(self.p("v0")))
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            above = self._P(np.exp(mid)) > target
            hi = np.where(above, mid, hi)
            lo = np.where(above, lo, mid)
        return np.exp(0.5 * (lo + hi))

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
        speed = float(np.hypot(trace.qvel[-1, 0], trace.qvel[-1, 1]))
        if mode == "paper":  # the law's own ODE, solved exactly
            exact_t = self.paper_time(u_end)
            u_last = float(self.paper_slip(np.array([trace.time[-1]]))[0])
            exact_v = 5.0 * v0 / 7.0 + 2.0 * u_last / 7.0
        else:
            exact_t = 2.0 * (v0 - u_end) / (7.0 * mu * g)
            exact_v = 5.0 * v0 / 7.0
        return [Measured(self.quantity("roll_time_s"), t_end, exact_t, note),
                Measured(self.quantity("roll_speed_mps"), speed, exact_v)]

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:
        """The slip against u(t) = max(v0 - 7/2 mu g t, 0), or the paper's law's u(t)."""
        v0, mu, g = self.p("v0"), self.p("mu"), self.p("g")
        exact = (self.paper_slip(trace.time) if mode == "paper"
                 else np.maximum(v0 - 3.5 * mu * g * trace.time, 0.0))
        return Curve("slip speed (m/s)", trace.time, self.slip(trace), exact)


__all__ = ["SLIP_FRACTION", "SlideToRoll"]
