"""torque-free: a free axisymmetric body spinning about its symmetry axis, in zero gravity.

A free rigid body with principal moments (A, A, C) about its centre of mass, in zero gravity and
touching nothing, spins at w3 about its symmetry axis with a small transverse spin w_perp. With
no torque, Euler's equations in the body's principal frame are

    A dw1/dt = (A - C) w3 w2,    A dw2/dt = (C - A) w3 w1,    C dw3/dt = 0,

so w3 is constant and the transverse spin turns in the body frame at constant magnitude:

    w1 + i w2 = w_perp e^{i Omega t},    Omega = (C - A) / A * w3

(counter-clockwise about the symmetry axis for an oblate body, C > A, like the tippe top's).
The kinetic energy E = (A w_perp^2 + C w3^2) / 2 is constant, and so is the angular momentum
in the world frame, L = R(q) diag(A, A, C) w: its size and its direction. This is the
gyroscopic part of the tippe top's motion (its nutation), the part its inversion lives on.

MuJoCo's free joint holds the angular velocity in the body's own frame (``qvel[3:6]``: the
probe's test checks it against ``cvel``, which is in the world's), so w1, w2, w3 are read
straight from the trace and L is turned into the world frame with each row's quaternion.

What MuJoCo's integrators do with it (measured on 2.3.7, 3.10.0, 3.11.0, 3.12.0, 3.16.0, 3.17.0
and 4.0.0). ``Euler`` (every release, and ``implicitfast`` in 2.3.7) advances w with the
gyroscopic torque of the step's start: each step h turns (w1, w2) by atan(Omega h) and
stretches it by sqrt(1 + (Omega h)^2), so w_perp grows as exp(Omega^2 h t / 2), x 3.5 over the
default 2 s at 2 ms, and E with it. ``implicit`` (every release) and ``implicitfast`` from
3.11.0 on shrink it by the same factor (x 0.29): 3.11.0's "tumbling motion is now mildly
damped". ``implicitfast`` in 3.10.0 keeps E, |L| and w_perp to rounding (a midpoint rotation,
2 atan(Omega h / 2) a step). The precession rate is right to (Omega h)^2 / 3 in every case, so
it is the size of the transverse spin, not its rate, that a first-order step gets wrong. RK4's
errors are O(h^4).

The probe's own setting is ``implicitfast`` at 2 ms: MuJoCo's step, and the integrator it has
recommended for all new models since 2.3.3 (``Euler``, the MJCF default, gains energy on every
release: ``--integrator Euler`` shows it).

Modes: ``free`` (the one setting: nothing touches the body, no contact option applies).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from tippetop.compare.measures.metrics import J_TOL
from tippetop.compare.probes.base import Curve, Measured, Probe, Quantity, Setup, fmt
from tippetop.models.errors import TippetopError

if TYPE_CHECKING:
    from tippetop.mujoco_runner.probe_run import ProbeTrace

#: The budget every quantity of this probe gets, relative: MuJoCo's for a conserved quantity
#: of the top (``J_TOL["mujoco"]``, the drift of Jellett's constant a MuJoCo run may have).
#: A free body has no soft contact to spend any of it, so the integrator alone must keep it.
BUDGET = J_TOL["mujoco"]
#: The start's tilt of the symmetry axis from world z, about world x (rad): the paper's theta0,
#: so the body frame is not the world's and a frame mix-up shows in L's direction.
TILT_RAD = 0.1

_XML = """<mujoco model="torque-free">
  <compiler inertiafromgeom="false"/>
  <option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
  <worldbody>
    <body name="body" pos="0 0 0">
      <freejoint/>
      <inertial pos="0 0 0" mass="{M}" diaginertia="{A} {A} {C}"/>
      <geom name="body" type="ellipsoid" size="{rx} {rx} {rz}" contype="0" conaffinity="0"
            rgba="0.8 0.4 0.2 1"/>
    </body>
  </worldbody>
</mujoco>"""


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of quaternions (n, 4) in MuJoCo's order (w, x, y, z).

    Each quaternion is normalised first (MuJoCo keeps them unit to rounding).
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def _largest(x: np.ndarray) -> float:
    """The entry of ``x`` largest in size, with its sign (NaN for an empty array)."""
    return float(x[int(np.argmax(np.abs(x)))]) if len(x) else float("nan")


@dataclass(frozen=True)
class TorqueFree(Probe):
    """torque-free: E, |L| and |w_perp| constant, Omega = (C - A) / A w3 (module docstring)."""

    name: ClassVar[str] = "torque-free"
    title: ClassVar[str] = ("a free spinning body keeps E and L; its transverse spin precesses "
                            "at (C - A) / A w3")
    modes: ClassVar[tuple[str, ...]] = ("free",)
    #: The paper's top: M = 15 g, C = 2/5 M R^2 at R = 1.5 cm, spin n0 = 100 rad/s; A/C = 0.8
    #: (oblate, so Omega = 25 rad/s); the transverse spin 5 % of w3; T: 8 precession periods.
    params: ClassVar[dict[str, float]] = {"M": 0.015, "C": 1.35e-6, "A_over_C": 0.8,
                                          "w3": 100.0, "w1": 5.0, "T": 2.0}
    quantities: ClassVar[tuple[Quantity, ...]] = (
        Quantity("energy_drift", "relative", BUDGET,
                 "the kinetic energy's largest relative change over the run, signed "
                 "(+ gained, - lost)",
                 "E is conserved: 1e-3, MuJoCo's budget for the top's conserved Jellett "
                 "constant, none of it a contact's here"),
        Quantity("momentum_drift", "relative", BUDGET,
                 "|L|'s largest relative change over the run, signed",
                 "|L| is conserved: the same 1e-3 budget as E"),
        Quantity("momentum_turn_rad", "rad", BUDGET,
                 "the largest angle between the world-frame L and its start (L from each "
                 "row's quaternion)",
                 "L's direction is conserved: 1e-3 rad, the same budget as an angle"),
        Quantity("precession_radps", "rad/s", BUDGET * 25.0,
                 "the rate at which (w1, w2) turns in the body frame: a straight-line fit of "
                 "its unwrapped phase over every step",
                 "1e-3 of the default Omega = 25 rad/s (the same relative budget; fixed when "
                 "--set changes Omega): 0.05 rad of phase over the 2 s run"),
        Quantity("transverse_drift", "relative", BUDGET,
                 "|w_perp| = hypot(w1, w2): its largest relative change over the run, signed",
                 "|w_perp| is conserved (the nutation's size): the same 1e-3 budget; a "
                 "first-order step moves its log by Omega^2 h T / 2 (1.25 at 2 ms)"),
    )

    def inertia(self) -> tuple[float, float]:
        """The principal moments (A, C) (kg m^2)."""
        C = self.p("C")
        return self.p("A_over_C") * C, C

    def omega(self) -> float:
        """The body-frame precession rate of the transverse spin, (C - A) / A w3 (rad/s)."""
        A, C = self.inertia()
        return (C - A) / A * self.p("w3")

    def check(self) -> None:
        """The parameters make the motion the closed form describes.

        Raises:
            TippetopError: One that does not (one line: what was expected, what was given).
        """
        rules = {"M": ("a mass > 0 kg", lambda v: v > 0),
                 "C": ("a moment > 0 kg m^2", lambda v: v > 0),
                 "A_over_C": ("A/C >= 1/2 (any axisymmetric body's bound)", lambda v: v >= 0.5),
                 "w1": ("a transverse spin > 0 rad/s (its phase is what is measured)",
                        lambda v: v > 0),
                 "w3": ("a finite spin in rad/s", lambda v: True),
                 "T": ("a duration > 0 s", lambda v: v > 0)}
        for key, (expected, ok) in rules.items():
            v = self.p(key)
            if not (np.isfinite(v) and ok(v)):
                raise TippetopError(f"{self.name}.{key}: expected {expected}, got {v!r}")

    def setup(self, mode: str) -> Setup:
        """The body tilted by :data:`TILT_RAD`, spinning at (w1, 0, w3) in its own frame.

        Raises:
            TippetopError: A parameter out of range (:meth:`check`).
        """
        self.check()
        A, C = self.inertia()
        M = self.p("M")
        # a uniform ellipsoid of these moments (drawn only: the inertial is explicit)
        rx = float(np.sqrt(2.5 * C / M))
        rz = float(np.sqrt(max(5.0 * A / M - rx * rx, 1e-3 * rx * rx)))
        xml = _XML.format(M=fmt(M), A=fmt(A), C=fmt(C), rx=fmt(rx), rz=fmt(rz))
        half = 0.5 * TILT_RAD
        qpos = (0.0, 0.0, 0.0, float(np.cos(half)), float(np.sin(half)), 0.0, 0.0)
        qvel = (0.0, 0.0, 0.0, self.p("w1"), 0.0, self.p("w3"))
        return Setup(xml, "body", qpos, qvel, self.p("T"), timestep_s=0.002,
                     integrator="implicitfast")

    def spin(self, trace: ProbeTrace) -> np.ndarray:
        """The angular velocity in the body frame, (n, 3) (rad/s): the free joint's own."""
        return np.asarray(trace.qvel[:, 3:6], dtype=float)

    def momentum(self, trace: ProbeTrace) -> np.ndarray:
        """The angular momentum about the centre of mass in the world frame, (n, 3) (kg m^2/s)."""
        A, C = self.inertia()
        body = self.spin(trace) * np.array([A, A, C])
        return np.einsum("nij,nj->ni", quat_to_mat(trace.qpos[:, 3:7]), body)

    def measure(self, mode: str, trace: ProbeTrace) -> list[Measured]:
        """E, |L|, L's direction and |w_perp| against their start; the precession against Omega."""
        A, C = self.inertia()
        w = self.spin(trace)
        wp2 = w[:, 0] ** 2 + w[:, 1] ** 2
        energy = 0.5 * (A * wp2 + C * w[:, 2] ** 2)
        L = self.momentum(trace)
        size = np.linalg.norm(L, axis=1)
        cos = np.clip(L @ L[0] / (size * size[0]), -1.0, 1.0)
        turn = np.arccos(cos)
        wperp = np.sqrt(wp2)
        phase = np.unwrap(np.arctan2(w[:, 1], w[:, 0]))
        t = np.asarray(trace.time, dtype=float)
        note = "" if trace.finished else "the run diverged; measured up to its last finite row"
        if len(t) >= 2:
            rate = float(np.polyfit(t - t[0], phase, 1)[0])
        else:
            rate, note = float("nan"), "fewer than two rows"
        if np.any(wperp[1:] < 1e-6 * max(wperp[0], 1e-300)):
            note = note or "the transverse spin fell to ~0: its phase is undefined there"
        q = self.quantity
        return [
            Measured(q("energy_drift"), _largest(energy / energy[0] - 1.0), 0.0, note),
            Measured(q("momentum_drift"), _largest(size / size[0] - 1.0), 0.0, note),
            Measured(q("momentum_turn_rad"), float(np.max(turn)), 0.0, note),
            Measured(q("precession_radps"), rate, self.omega(), note),
            Measured(q("transverse_drift"), _largest(wperp / wperp[0] - 1.0), 0.0, note),
        ]

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:
        """w1 (body frame) against w_perp cos(Omega t)."""
        t = np.asarray(trace.time, dtype=float)
        exact = self.p("w1") * np.cos(self.omega() * (t - t[0]))
        return Curve("transverse spin w1, body frame (rad/s)", t, self.spin(trace)[:, 0], exact)


__all__ = ["BUDGET", "TILT_RAD", "TorqueFree", "quat_to_mat"]
