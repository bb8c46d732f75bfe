"""lift-off: a ball driven to slide ever faster, until its contact pushes it off the table.

A uniform ball (radius R, mass M, inertia I = 2/5 M R^2) rests on a level table; from t = 0
a constant torque tau about the horizontal y axis drives its spin. Under Coulomb's friction
(coefficient mu) it slides at once, the table's force on it being mu M g against the slip and
exactly M g up, so its centre stays at height R and

    v' = mu g,    w' = (tau - mu M g R) / I,
    u' = R w' - v' = R tau / I - (1 + M R^2 / I) mu g = R tau / I - 7/2 mu g

for the contact point's slip u = R w - v. The probe drives it with
tau = I / R (u_max / T + 7/2 mu g), so the slip grows linearly, u(t) = u_max t / T, through
the ramp's largest slip u_max at t = T, while the normal force stays M g: **the ball never
leaves the table**, at any slip (nor under the paper's law, whose friction is horizontal too).

MuJoCo's contact force is the projection, onto its friction cone, of the force that would bring
the contact's accelerations to their reference values (MuJoCo's computation docs); the friction
rows' demand grows with the slip, and once it exceeds what the cone holds, the projection
raises the normal force too (:mod:`tippetop.mujoco_runner.contact_lift`). Ramped slowly, the
ball first rises out of its resting penetration; beyond the slip at which MuJoCo's normal
force at zero penetration exceeds M g it can no longer rest on the table: it hovers, touching
it part of the time, or is thrown off it. Quantities, from every step of the run:

- ``lift_off_slip_mps``: the slip at which the ball first leaves the table, as the harness
  counts a flight (no contact for :data:`FLIGHT_S` or longer, risen :data:`FLIGHT_RISE_M`
  above touching meanwhile; the slip read at its last step in contact). Coulomb's exact value
  is *never*: written as the ramp's largest slip u_max, which the value is, exactly, when the
  ball does not leave while its slip is at most u_max (no float beyond u_max is read).
- ``normal_excess``: the normal force averaged over the steps in contact while the slip is at
  most u_max, over M g, minus 1; Coulomb's is 0. By the ball's vertical momentum it is
  (1 + dv_z / (g T_r)) / f - 1, f the share of those steps in contact and T_r their span: it
  reads how much of the slide the contact keeps the ball in the air.

Against :func:`tippetop.mujoco_runner.contact_lift.lift_off_slip`: that holds the ball at one
slip from rest at its resting penetration (a step onset, whose transient throws it); here the
slip rises slowly and the ball hovers before it flies, if it does: the two lift-off slips are
not the same number (see the tests for both, measured).

Modes: ``pyramidal`` and ``elliptic``, MuJoCo's default contact (mu = 1, MuJoCo's default
friction; solref, solimp, impratio not written) at MuJoCo's default step, 2 ms, Euler;
``pyramidal-mu0.1``, ``elliptic-mu0.1``, the same at the paper's mu; ``calibrated``, the
calibrated native settings (``models/calibrated_native.toml``: cone, impratio, solref, solimp,
mu, and their own step and integrator).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
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
from tippetop.models.errors import TippetopError, did_you_mean
from tippetop.mujoco_runner.contact_lift import FLIGHT_RISE_M, FLIGHT_S

if TYPE_CHECKING:
    from tippetop.mujoco_runner.probe_run import ProbeTrace

#: MuJoCo's default step and integrator (what a model that sets neither runs with).
MUJOCO_DT_S, MUJOCO_INTEGRATOR = 0.002, "Euler"
#: The run lasts this many ramp times: the slip passes u_max, and a flight that begins at the
#: ramp's end has its 10 ms.
RUN_RAMPS = 1.05

_XML = """<mujoco model="lift-off">
  <option timestep="{dt}" gravity="0 0 {g}" cone="{cone}"{impratio}/>
  <worldbody>
    <geom name="table" type="plane" size="5 5 0.1" friction="{mu} 0 0"{solver}/>
    <body name="ball" pos="0 0 {R}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{R}" mass="{M}" friction="{mu} 0 0" condim="3"{solver}/>
      <site name="drive"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="drive" site="drive" gear="0 0 0 0 1 0" ctrllimited="false"/>
  </actuator>
</mujoco>"""


@dataclass(frozen=True)
class Contact:
    """One mode's contact, and the step it runs at.

    Attributes:
        mu: Sliding friction coefficient.
        cone: ``pyramidal`` or ``elliptic``.
        impratio: None: MuJoCo's default (not written).
        solref: None: MuJoCo's default (not written).
        solimp: None: MuJoCo's default (not written).
        timestep_s: The mode's step.
        integrator: The mode's integrator.
    """

    mu: float
    cone: str
    impratio: float | None = None
    solref: tuple[float, ...] | None = None
    solimp: tuple[float, ...] | None = None
    timestep_s: float = MUJOCO_DT_S
    integrator: str = MUJOCO_INTEGRATOR


def _calibrated() -> Contact:
    from tippetop.models.calibrated import CALIBRATION_FILE, calibrated_native_settings

    cal = calibrated_native_settings()
    try:
        return Contact(float(cal["mu"]), str(cal["cone"]), float(cal["impratio"]),
                       tuple(float(v) for v in cal["solref"]),
                       tuple(float(v) for v in cal["solimp"]), float(cal["timestep_s"]),
                       str(cal["integrator"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise TippetopError(f"lift-off calibrated: expected the calibrated settings (mu, cone, "
                            f"impratio, solref, solimp, timestep_s, integrator) in "
                            f"{CALIBRATION_FILE}, got {cal or 'no file'} ({exc})") from None


def mode_contact(mode: str) -> Contact:
    """The contact and step of ``mode`` (one line, with a did-you-mean, for an unknown one)."""
    fixed = {"pyramidal": Contact(1.0, "pyramidal"), "elliptic": Contact(1.0, "elliptic"),
             "pyramidal-mu0.1": Contact(0.1, "pyramidal"),
             "elliptic-mu0.1": Contact(0.1, "elliptic")}
    if mode in fixed:
        return fixed[mode]
    if mode == "calibrated":
        return _calibrated()
    raise TippetopError(f"lift-off: expected a mode of {', '.join(LiftOff.modes)}, got "
                        f"{mode!r}{did_you_mean(mode, LiftOff.modes)}")


def _numbers(values: tuple[float, ...]) -> str:
    return " ".join(fmt(v) for v in values)


def _head(trace: ProbeTrace, rows: int) -> ProbeTrace:
    """The trace's first ``rows`` rows."""
    return replace(trace, **{k: getattr(trace, k)[:rows]
                             for k in ("time", "qpos", "qvel", "ncon", "normal_N", "warnings")})


def _rest_penetration(mjcf: str, radius_m: float, weight_N: float) -> float:
    """The depth at which the model's contact holds the ball's weight at rest (m).

    ``mj_forward`` at rest (no drive) and bisection on the depth, to 1e-6 of it, as
    :meth:`tippetop.mujoco_runner.contact_lift.Probe.rest_penetration` does; the MuJoCo
    installed beside tippetop computes it (the contact's model is the same in every release
    the probes run on).
    """
    import mujoco

    model = mujoco.MjModel.from_xml_string(mjcf)
    data = mujoco.MjData(model)
    f6 = np.zeros(6)

    def normal(depth: float) -> float:
        mujoco.mj_resetData(model, data)
        data.qpos[2] = radius_m - depth
        mujoco.mj_forward(model, data)
        total = 0.0
        for i in range(data.ncon):
            mujoco.mj_contactForce(model, data, i, f6)
            total += float(f6[0])
        return total

    lo, hi = 1e-9, 0.5 * radius_m
    if normal(lo) >= weight_N:
        return lo
    for _ in range(80):
        mid = math.sqrt(lo * hi)
        if normal(mid) < weight_N:
            lo = mid
        else:
            hi = mid
        if hi / lo < 1.0 + 1e-6:
            break
    return hi


@dataclass(frozen=True)
class LiftOff(Probe):
    """lift-off: a ball whose slip is ramped stays on the table under Coulomb (docstring)."""

    name: ClassVar[str] = "lift-off"
    title: ClassVar[str] = ("a ball driven to slide ever faster stays on the table: its contact "
                            "pushes up with M g")
    modes: ClassVar[tuple[str, ...]] = ("pyramidal", "elliptic", "pyramidal-mu0.1",
                                        "elliptic-mu0.1", "calibrated")
    #: R, M: MuJoCo's tutorial tippe top's ball (contact_lift's); slip_max: the ramp's largest
    #: slip, above the 0.88 m/s the tutorial top's reference slips at (docs/guide/tuning.md);
    #: ramp_s: the time it takes, 50 of MuJoCo's default contact time constants (0.02 s).
    params: ClassVar[dict[str, float]] = {"R": 0.02, "M": 0.0555, "g": G_MPS2, "slip_max": 1.0,
                                          "ramp_s": 1.0}
    quantities: ClassVar[tuple[Quantity, ...]] = (
        Quantity("lift_off_slip_mps", "m/s", 0.0,
                 "the slip at which the ball first leaves the table (no contact for 10 ms, "
                 "risen 10 um); the ramp's largest slip if it does not leave within the ramp",
                 "none: Coulomb's ball never leaves, written as the ramp's largest slip, which "
                 "the value is, the same float, only when no flight begins within the ramp",
                 baseline=0.01, baseline_why="1 % of the ramp's 1 m/s: the slip moves 2 mm/s "
                 "a step at 2 ms, so 5 steps' worth; a flight a few steps sooner is no change"),
        Quantity("normal_excess", "relative", 0.01,
                 "the normal force averaged over the steps in contact, while the slip is at "
                 "most the ramp's largest, over M g, minus 1",
                 "a ball that keeps its contact has (1 + dv_z / (g T)): its vertical speed in "
                 "contact is at most its penetration (< 0.4 mm) per time constant, 0.02 m/s, "
                 "against g T = 9.8 m/s: 0.002; 0.01 is five times that"),
    )

    def contact(self, mode: str) -> Contact:
        """``mode``'s contact and step."""
        return mode_contact(mode)

    def drive_torque(self, mu: float) -> float:
        """Coulomb's torque for the ramp u(t) = u_max t / T: I / R (u_max / T + 7/2 mu g)."""
        R, M, g = self.p("R"), self.p("M"), self.p("g")
        rate = self.p("slip_max") / self.p("ramp_s")
        return sphere_inertia(M, R) / R * (rate + 3.5 * mu * g)

    def mjcf(self, mode: str) -> str:
        """``mode``'s model: the ball on its table, a motor on its centre about y."""
        c = self.contact(mode)
        solver = ""
        if c.solref is not None:
            solver += f' solref="{_numbers(c.solref)}"'
        if c.solimp is not None:
            solver += f' solimp="{_numbers(c.solimp)}"'
        impratio = "" if c.impratio is None else f' impratio="{fmt(c.impratio)}"'
        return _XML.format(dt=fmt(c.timestep_s), g=fmt(-self.p("g")), cone=c.cone,
                           impratio=impratio, mu=fmt(c.mu), solver=solver, R=fmt(self.p("R")),
                           M=fmt(self.p("M")))

    def setup(self, mode: str) -> Setup:
        """The ball at rest at its resting depth, driven from t = 0; run to 1.05 T."""
        c = self.contact(mode)
        R = self.p("R")
        xml = self.mjcf(mode)
        depth = _rest_penetration(xml, R, self.p("M") * self.p("g"))
        return Setup(xml, "ball", (0.0, 0.0, R - depth, 1.0, 0.0, 0.0, 0.0), (0.0,) * 6,
                     RUN_RAMPS * self.p("ramp_s"), c.timestep_s, c.integrator,
                     (self.drive_torque(c.mu),))

    def slip(self, trace: ProbeTrace) -> np.ndarray:
        """The contact point's horizontal speed, |v + w x (0, 0, -R)| (m/s), at every step."""
        q = trace.qpos[:, 3:7]
        w_local = trace.qvel[:, 3:6]
        # the free joint's angular velocity is in the ball's frame: rotate it to the world's
        u, s = q[:, 1:4], q[:, :1]
        t = 2.0 * np.cross(u, w_local)
        w = w_local + s * t + np.cross(u, t)
        R = self.p("R")
        sx = trace.qvel[:, 0] - R * w[:, 1]
        sy = trace.qvel[:, 1] + R * w[:, 0]
        return np.hypot(sx, sy)

    def touching(self, trace: ProbeTrace) -> np.ndarray:
        """Whether the ball touches the table at each step.

        The engine's contacts; where it reads none (-1), the ball's gap (a sphere on a plane
        with no margin touches at gap <= 0).
        """
        gap = trace.qpos[:, 2] - self.p("R")
        return np.where(trace.ncon >= 0, trace.ncon > 0, gap <= 0.0)

    def first_flight(self, trace: ProbeTrace) -> int | None:
        """The row of the last contact before the first flight (None: no flight)."""
        touch = self.touching(trace)
        gap = trace.qpos[:, 2] - self.p("R")
        t = trace.time
        dt = float(t[1] - t[0]) if len(t) > 1 else 0.0
        n, i = len(touch), 1
        while i < n:
            if touch[i]:
                i += 1
                continue
            j = i
            while j < n and not touch[j]:
                j += 1
            airborne = (t[j] if j < n else t[-1] + dt) - t[i]
            if airborne >= FLIGHT_S - 1e-12 and float(gap[i:j].max()) >= FLIGHT_RISE_M:
                return i - 1
            i = j
        return None

    def measure(self, mode: str, trace: ProbeTrace) -> list[Measured]:
        """The lift-off slip against the ramp's largest (never), the normal excess against 0."""
        u_max = self.p("slip_max")
        notes = []
        if not trace.finished:  # its last row is the first non-finite one: read up to it
            notes.append(f"the run diverged at {trace.time[-1]:.4g} s")
            trace = _head(trace, len(trace.time) - 1)
        slip = self.slip(trace)
        over = np.flatnonzero(slip > u_max)
        end = int(over[0]) if len(over) else len(slip)
        takeoff = self.first_flight(trace)
        if takeoff is not None and takeoff < end:
            lift = float(slip[takeoff])
            lift_note = f"left the table at {trace.time[takeoff + 1]:.4g} s"
        elif len(over):
            lift, lift_note = u_max, "never left the table within the ramp"
        else:
            lift = float(np.max(slip)) if len(slip) else float("nan")
            lift_note = f"the ramp reached only {lift:.4g} m/s"
        touch = self.touching(trace)[:end]
        normal = trace.normal_N[:end][touch] / (self.p("M") * self.p("g"))
        share = float(np.mean(touch)) if end else float("nan")
        if not np.isfinite(normal).all() or not len(normal):
            excess = float("nan")
            excess_note = ("no contact within the ramp" if not len(normal) else
                           "the engine reports no contact forces")
        else:
            excess = float(np.mean(normal)) - 1.0
            excess_note = f"in contact {100.0 * share:.1f} % of the ramp's steps"
        join = "; ".join
        return [Measured(self.quantity("lift_off_slip_mps"), lift, u_max,
                         join([lift_note, *notes])),
                Measured(self.quantity("normal_excess"), excess, 0.0,
                         join([excess_note, *notes]))]

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:
        """The normal force over M g at every step against Coulomb's, 1."""
        value = trace.normal_N / (self.p("M") * self.p("g"))
        return Curve("normal force / M g", trace.time, value, np.ones_like(trace.time))


__all__ = ["Contact", "LiftOff", "mode_contact"]
