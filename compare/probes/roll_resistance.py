"""roll-resistance: a ball rolling on a level table, slowed by MuJoCo's rolling friction.

A uniform ball (radius R, mass M, inertia I = k M R^2, k = 2/5) rolls without slipping along
x on a level table at v0 (spin w_y = v0 / R). MuJoCo's contact with ``condim`` 6 adds a
rolling friction torque about the tangent axes, bounded by the rolling coefficient mu_r (a
length: MuJoCo's docs read it as the depth of the deformation that dissipates) times the
normal force N = M g. With the rolling torque T against w_y and the table's tangential force F
along x keeping the slip zero (v = R w_y):

    M dv/dt = F,    I dw_y/dt = -F R - T    =>    dv/dt = -T R / (I + M R^2),  F = M dv/dt.

With T = mu_r N (the rolling law) the ball decelerates at

    a = mu_r g / (R (1 + k)) = 5/7 mu_r g / R

until it stops at v0 / a. The tangential force |F| = T / (R (1 + k)) shares the contact's
friction cone with T (MuJoCo's docs: elliptic f_n^2 >= sum f_i^2 / mu_i^2; pyramidal
sum |f_i| / mu_i <= f_n). With e = mu_r / (mu R (1 + k)) the cone's largest rolling torque is
T = mu_r N / sqrt(1 + e^2) (elliptic) or mu_r N / (1 + e) (pyramidal), and a scales with it:
a factor 0.9994 and 0.966 at the defaults (e = 0.036).

MuJoCo's friction is soft: below a spin w* it relaxes the rolling over its time constant
(viscously) instead of holding T at mu_r N. For an elliptic cone w* = mu_r N (A + R_r) / b
with A = 1/I, R_r = R_0 mu^2 / (mu_r^2 impratio), R_0 = (1 - d)/d / M and b = 2 / (solimp[1]
timeconst) (as spin-decay's): a rolling speed R w* of 0.1-0.2 m/s here. MuJoCo's default
mu_r = 0.0001 m puts it at 1-2 m/s for this ball: its rolling friction is a viscous drag at any
everyday speed. So the probe's mu_r is 0.001 m, v0 = 2 m/s, and the deceleration is fitted over
the fall of v from :data:`~.spin_decay.WINDOW` = (0.8, 0.2) v0, 1.6 to 0.4 m/s, 2-4x above the
relaxation and past the ball's settling onto the table.

What MuJoCo 4.0.0 does (measured): the elliptic cone meets the law to 0.1 %; the rolling ball
chatters on the table as spin-decay's does. The pyramidal cone's rolling torque relaxes from
about 1 m/s and lets the ball slip by centimetres per second: it decelerates at 0.81 of
5/7 mu_r g / R over 1.0-0.4 m/s, 0.975 above (past the pyramid's 0.966), 0.91 over the window.

Modes: ``condim6-pyramidal`` and ``condim6-elliptic``. MuJoCo's default sliding and torsional
friction (1, 0.005; the torsion is not asked for), impratio, solref and solimp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from tippetop.compare.probes.base import (
    G_MPS2,
    Curve,
    Measured,
    Probe,
    Quantity,
    Setup,
    fmt,
    sphere_inertia,
)
from tippetop.compare.probes.spin_decay import check_mode, check_params, fit_rate, off_table_note

if TYPE_CHECKING:
    from tippetop.mujoco_runner.probe_run import ProbeTrace

#: MuJoCo's default torsional coefficient (m): a rolling ball does not ask for it.
TORSION_COEFF_M = 0.005

_XML = """<mujoco model="roll-resistance">
  <option timestep="0.002" gravity="0 0 {g}" cone="{cone}"/>
  <worldbody>
    <geom name="table" type="plane" size="20 20 0.1" friction="{mu} {mu_t} {mu_r}"
          condim="6"/>
    <body name="ball" pos="0 0 {R}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{R}" mass="{M}" friction="{mu} {mu_t} {mu_r}"
            condim="6"/>
    </body>
  </worldbody>
</mujoco>"""

#: Each mode's cone.
_MODES = {"condim6-pyramidal": "pyramidal", "condim6-elliptic": "elliptic"}


@dataclass(frozen=True)
class RollResistance(Probe):
    """roll-resistance: a = 5/7 mu_r g / R, times the cone's share (module docstring)."""

    name: ClassVar[str] = "roll-resistance"
    title: ClassVar[str] = "a rolling ball slows at 5/7 mu_r g / R under condim-6 friction"
    modes: ClassVar[tuple[str, ...]] = tuple(_MODES)
    params: ClassVar[dict[str, float]] = {"mu": 1.0, "mu_r": 0.001, "v0": 2.0, "R": 0.02,
                                          "M": 0.05, "g": G_MPS2}
    quantities: ClassVar[tuple[Quantity, ...]] = (
        Quantity("roll_decel_mps2", "m/s^2", 0.0035,
                 "the rolling ball's deceleration, fitted over the fall of its speed from "
                 "0.8 to 0.2 v0",
                 "1 % of the default's 0.35: the window stays 2x above the speed where "
                 "MuJoCo's soft rolling friction relaxes, so the torque is on its cone "
                 "(mu_r N); 1 % for the chattering normal force's mean against M g"),
    )

    def k(self) -> float:
        """The ball's I / (M R^2), 2/5."""
        M, R = self.p("M"), self.p("R")
        return sphere_inertia(M, R) / (M * R * R)

    def cone_share(self, mode: str) -> float:
        """The cone's largest rolling torque over mu_r N while F keeps the slip zero."""
        e = self.p("mu_r") / (self.p("mu") * self.p("R") * (1.0 + self.k()))
        return 1.0 / math.sqrt(1.0 + e * e) if _MODES[mode] == "elliptic" else 1.0 / (1.0 + e)

    def decel(self, mode: str) -> float:
        """The rolling law's deceleration, mu_r g / (R (1 + k)) times the cone's share."""
        law = self.p("mu_r") * self.p("g") / (self.p("R") * (1.0 + self.k()))
        return law * self.cone_share(mode)

    def setup(self, mode: str) -> Setup:
        """The ball rolling along x at v0 (w_y = v0 / R); run to 1.2 times its stop.

        Raises:
            TippetopError: An unknown mode, a parameter that is not a finite number > 0.
        """
        check_mode(self, mode)
        check_params(self)
        R, v0 = self.p("R"), self.p("v0")
        mu_t = TORSION_COEFF_M
        xml = _XML.format(g=fmt(-self.p("g")), cone=_MODES[mode], mu=fmt(self.p("mu")),
                          mu_t=fmt(mu_t), mu_r=fmt(self.p("mu_r")), R=fmt(R),
                          M=fmt(self.p("M")))
        return Setup(xml, "ball", (0.0, 0.0, R, 1.0, 0.0, 0.0, 0.0),
                     (v0, 0.0, 0.0, 0.0, v0 / R, 0.0), 1.2 * v0 / self.decel(mode))

    @staticmethod
    def speed(trace: ProbeTrace) -> np.ndarray:
        """The centre's speed along x (m/s) at every step."""
        return np.asarray(trace.qvel[:, 0], dtype=float)

    def measure(self, mode: str, trace: ProbeTrace) -> list[Measured]:
        """The deceleration over the window against the rolling law's."""
        v0 = self.p("v0")
        v = self.speed(trace)
        decel, note = fit_rate(np.asarray(trace.time, dtype=float), v, v0)
        note = "; ".join(n for n in (note, off_table_note(trace, v, v0)) if n)
        return [Measured(self.quantity("roll_decel_mps2"), decel, self.decel(mode), note)]

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:
        """The speed against max(v0 - a t, 0)."""
        t = np.asarray(trace.time, dtype=float)
        exact = np.maximum(self.p("v0") - self.decel(mode) * t, 0.0)
        return Curve("rolling speed (m/s)", t, self.speed(trace), exact)


__all__ = ["TORSION_COEFF_M", "RollResistance"]
