"""incline: a box and a ball on a slope, below the friction angle (stay put) and above (slide).

The slope is made by tilting gravity, not the table: g = g (sin alpha, 0, -cos alpha), so the
table stays the plane z = 0 and "down the slope" is +x. A box (half-side H, mass M_box) and
a uniform ball (radius R, mass M, inertia I = 2/5 M R^2) rest on it, side by side (they cannot
touch each other), both at rest at the start; both are in every mode's model, the box is the
probed body (its contacts are recorded).

Under Coulomb's friction (coefficient mu, friction angle atan mu):

- **The box below the friction angle** (tan alpha < mu) needs a friction force M_box g sin alpha,
  within mu M_box g cos alpha: static friction holds it, and it does not move: its creep speed
  is exactly 0.
- **The box above it** slides; kinetic friction mu N with N = M_box g cos alpha gives

      a = g (sin alpha - mu cos alpha).

- **The ball** cannot stay still on a slope with condim 3: nothing resists rolling (holding a
  ball needs rolling friction, condim 6: the roll-resistance probe). For a ball, *staying
  put* means that its contact does not slip: it rolls without slipping, with
  M a = M g sin alpha - F and I a / R = F R, so

      a = g sin alpha / (1 + I / (M R^2)) = 5/7 g sin alpha,    F = 2/7 M g sin alpha,

  which friction can give while tan alpha <= 7/2 mu; the contact point's slip speed,
  v - w x r, is exactly 0.

MuJoCo's friction has no stick state: its friction rows have a velocity reference only
(aref = -b v, b = 2 / (d_max timeconst) at damping ratio 1). With the elliptic cone, inside
the cone, each row's force is D_f (aref - J a) (D_f = 1 / R_f, the row's regulariser), so in
steady creep (J a = 0) a tangential load F is held at the slip

    v = F / (b sum D_f)      (over the body's contacts' rows along the slip),

and a resting body *creeps* (google-deepmind/mujoco#3328: 50-155 um/s for a pinched capsule
with the elliptic cone at impratio 10, ~1/impratio, cut ~110x by noslip). impratio divides
R_f (with the pyramidal cone, every row's: each is normal and friction together), so the
elliptic creep falls as exactly 1/impratio; the noslip solver (``noslip_iterations``) removes
the slip after the main solve. The probe reports the creep of the box's centre and of the
ball's contact point (MuJoCo's, midway through the penetration: (R + z) / 2 below the centre
at height z), against Coulomb's 0. The rolling acceleration of steady rolling is exact in
MuJoCo's model too (a steady slip changes no acceleration), but for the lever: the contact
point sits pen/2 inside the ball, which lowers it by 2/7 pen/R.

All quantities are read over :data:`WINDOW_S` after :data:`SETTLE_S` (the contacts' settling,
many of their 0.02 s time constants): each creep as the mean, over every step of the window,
of the sliding velocity (the distance crept over the window, divided by its length); each
acceleration as the slope of a least-squares line through every step's speed down the slope.

Measured (the defaults, Euler at 2 ms; the same digits on MuJoCo 2.3.7, 3.10.0 and 4.0.0),
creep in um/s, box / ball's contact: pyramidal 648 / 732, pyramidal-impratio10 65 / 73,
elliptic 508 / 506, elliptic-impratio10 51 / 51 (#3328's 50-155), elliptic-noslip 0.02 /
3e-5. With the pyramidal cone noslip holds the ball's one contact (0.003 um/s) but not the
box's four: it sticks, then rocks forward a little at a time, walking down at 463 um/s (67 at
impratio 10; 95 um/s with RK4 at 0.5 ms). The slides meet a = g (sin - mu cos) to 0.3 %.

Modes: ``pyramidal`` and ``elliptic`` (MuJoCo's two friction cones, condim 3), each at impratio 1
and 10 (``-impratio10``, #3328's grasping recipe) and with or without the noslip solver
(``-noslip``: :data:`NOSLIP_ITERATIONS` iterations, #3328's), the slope at ``alpha``, below the
friction angle; ``slide-pyramidal`` and ``slide-elliptic``: impratio 1, the slope at
``alpha_slide``, above it. The defaults keep the slide slow (under 0.5 m/s): at
alpha_slide = 0.61 rad the box, reaching 2 m/s, hops off the table on its corners (measured),
which is the lift-off probe's part (MuJoCo's soft contact lifts a fast-sliding body), not this
one's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from tippetop.compare.probes.base import G_MPS2, Curve, Measured, Probe, Quantity, Setup, fmt
from tippetop.models.errors import TippetopError, did_you_mean

if TYPE_CHECKING:
    from tippetop.mujoco_runner.probe_run import ProbeTrace

#: The contacts settle over this (s) before anything is read: their time constant is 0.02 s
#: (MuJoCo's default solref; 2 steps when the step is longer than 10 ms, which MuJoCo's
#: refsafe enforces), so over 10 of them at the default step.
SETTLE_S = 0.25
#: Everything is read over this window after :data:`SETTLE_S` (s).
WINDOW_S = 1.0
#: The noslip solver's iterations in the ``-noslip`` modes (google-deepmind/mujoco#3328's).
NOSLIP_ITERATIONS = 10
#: The impratio of the ``-impratio10`` modes (#3328's "documented grasping recipe").
IMPRATIO_HARD = 10.0
#: A creep a user would notice: this far (m) over a simulated minute.
NOTICED_DRIFT_M = 1e-3
#: ... over this long (s).
MINUTE_S = 60.0
#: The creep speeds' tolerance (um/s): :data:`NOTICED_DRIFT_M` per :data:`MINUTE_S`.
CREEP_TOL_UMPS = 1e6 * NOTICED_DRIFT_M / MINUTE_S

#: Each mode: (cone, impratio, noslip iterations, above the friction angle).
MODE_SETTINGS: dict[str, tuple[str, float, int, bool]] = {
    "pyramidal": ("pyramidal", 1.0, 0, False),
    "pyramidal-impratio10": ("pyramidal", IMPRATIO_HARD, 0, False),
    "pyramidal-noslip": ("pyramidal", 1.0, NOSLIP_ITERATIONS, False),
    "pyramidal-impratio10-noslip": ("pyramidal", IMPRATIO_HARD, NOSLIP_ITERATIONS, False),
    "elliptic": ("elliptic", 1.0, 0, False),
    "elliptic-impratio10": ("elliptic", IMPRATIO_HARD, 0, False),
    "elliptic-noslip": ("elliptic", 1.0, NOSLIP_ITERATIONS, False),
    "elliptic-impratio10-noslip": ("elliptic", IMPRATIO_HARD, NOSLIP_ITERATIONS, False),
    "slide-pyramidal": ("pyramidal", 1.0, 0, True),
    "slide-elliptic": ("elliptic", 1.0, 0, True),
}

# The table collides with both bodies (the box's contype 1 and the ball's 2 are both in its
# conaffinity 3); the box and the ball never touch each other (their conaffinity is 0).
_XML = """<mujoco model="incline">
  <option timestep="0.002" gravity="{gx} 0 {gz}" cone="{cone}" impratio="{impratio}"
          noslip_iterations="{noslip}"/>
  <worldbody>
    <geom name="table" type="plane" size="5 5 0.1" friction="{mu} 0 0" contype="3"
          conaffinity="3"/>
    <body name="box" pos="0 0 {H}">
      <freejoint/>
      <geom name="box" type="box" size="{H} {H} {H}" mass="{Mb}" friction="{mu} 0 0"
            condim="3" contype="1" conaffinity="0"/>
    </body>
    <body name="ball" pos="0 {y} {R}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{R}" mass="{M}" friction="{mu} 0 0" condim="3"
            contype="2" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>"""

# Where each body's coordinates are in qpos (box then ball: 7 each) and qvel (6 each).
_BALL_Q, _BALL_V = 7, 6


def _rotate(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """Each row of ``vec`` turned by its row of ``quat`` (w, x, y, z): body frame to world."""
    w, u = quat[:, :1], quat[:, 1:]
    uv = np.cross(u, vec)
    return vec + 2.0 * w * uv + 2.0 * np.cross(u, uv)


@dataclass(frozen=True)
class Incline(Probe):
    """incline: creep 0 below the friction angle, a = g (sin - mu cos) above (module docstring)."""

    name: ClassVar[str] = "incline"
    title: ClassVar[str] = ("a box and a ball on a slope: no creep below the friction angle, "
                            "a = g (sin alpha - mu cos alpha) above")
    modes: ClassVar[tuple[str, ...]] = tuple(MODE_SETTINGS)
    params: ClassVar[dict[str, float]] = {"mu": 0.5, "alpha": 0.2, "alpha_slide": 0.5,
                                          "H": 0.05, "M_box": 1.0, "R": 0.05, "M": 1.0,
                                          "g": G_MPS2}
    quantities: ClassVar[tuple[Quantity, ...]] = (
        Quantity("box_creep_umps", "um/s", CREEP_TOL_UMPS,
                 "the box's speed below the friction angle (mean over the window)",
                 "a judgement: 1 mm over a simulated minute, a drift a user sees (#3328 calls "
                 "9 mm/min an object sinking out of a grip); Coulomb's is 0"),
        Quantity("ball_creep_umps", "um/s", CREEP_TOL_UMPS,
                 "the slip speed of the ball's contact point (mean over the window)",
                 "as the box's: 1 mm over a simulated minute; rolling without slipping is 0"),
        Quantity("ball_roll_accel_mps2", "m/s^2", 0.02,
                 "the ball's acceleration down the slope (a line fit over the window)",
                 "0.6 % of 5/7 g sin(alpha_slide) = 3.4 m/s^2, three times the 2/7 pen/R "
                 "(0.2 %) by which MuJoCo's contact point, midway through the 0.4 mm "
                 "penetration, shortens friction's lever"),
        Quantity("slide_accel_mps2", "m/s^2", 0.04,
                 "the box's acceleration down the slope above the friction angle (line fit)",
                 "1 % of the friction's mu g cos(alpha_slide) = 4.3 m/s^2: a friction force "
                 "1 % off shows; the box rocking on its corner contacts averages out"),
    )

    def settings(self, mode: str) -> tuple[str, float, int, bool]:
        """(cone, impratio, noslip iterations, above the friction angle) of ``mode``.

        Raises:
            TippetopError: Not one of the probe's modes (one line, with a did-you-mean).
        """
        if mode not in MODE_SETTINGS:
            raise TippetopError(f"incline: expected a mode of {', '.join(MODE_SETTINGS)}, "
                                f"got {mode!r}{did_you_mean(mode, MODE_SETTINGS)}")
        return MODE_SETTINGS[mode]

    def check(self) -> None:
        """The parameters make the motion the docstring's.

        Raises:
            TippetopError: A parameter that is not positive, a slope not below the friction
                angle (``alpha``) or not above it (``alpha_slide``), a slope on which the
                ball would slip or the box would tip over (one line each).
        """
        for key in self.params:
            value = self.p(key)
            if not (math.isfinite(value) and value > 0):
                raise TippetopError(f"incline: expected {key} > 0, got {value!r}")
        mu = self.p("mu")
        friction_angle = math.atan(mu)
        tip = math.pi / 4  # a cube on a slope tips over its lower edge beyond 45 degrees
        if not self.p("alpha") < min(friction_angle, tip):
            raise TippetopError(
                f"incline: expected alpha below the friction angle atan(mu) = "
                f"{friction_angle:.6g} rad and below pi/4 (the box tips), got "
                f"{self.p('alpha')!r}")
        roll_limit = math.atan(3.5 * mu)  # beyond it the ball slips as well as rolls
        if not friction_angle < self.p("alpha_slide") < min(roll_limit, tip):
            raise TippetopError(
                f"incline: expected alpha_slide above the friction angle atan(mu) = "
                f"{friction_angle:.6g} rad and below {min(roll_limit, tip):.6g} rad (the "
                f"ball rolls without slipping, the box does not tip), got "
                f"{self.p('alpha_slide')!r}")

    def slope(self, mode: str) -> float:
        """The slope's angle in ``mode`` (rad)."""
        return self.p("alpha_slide") if self.settings(mode)[3] else self.p("alpha")

    def roll_accel(self, mode: str) -> float:
        """The ball's rolling acceleration, 5/7 g sin alpha (m/s^2)."""
        return 5.0 / 7.0 * self.p("g") * math.sin(self.slope(mode))

    def slide_accel(self, mode: str) -> float:
        """The box's sliding acceleration, g (sin alpha - mu cos alpha) (m/s^2)."""
        a = self.slope(mode)
        return self.p("g") * (math.sin(a) - self.p("mu") * math.cos(a))

    def setup(self, mode: str) -> Setup:
        """Both bodies at rest on the table, gravity tilted by the mode's slope; run 1.25 s."""
        cone, impratio, noslip, _ = self.settings(mode)
        self.check()
        a, g, H, R = self.slope(mode), self.p("g"), self.p("H"), self.p("R")
        y = 3.0 * (H + R)  # side by side, across the slope
        xml = _XML.format(gx=fmt(g * math.sin(a)), gz=fmt(-g * math.cos(a)), cone=cone,
                          impratio=fmt(impratio), noslip=noslip, mu=fmt(self.p("mu")),
                          H=fmt(H), Mb=fmt(self.p("M_box")), y=fmt(y), R=fmt(R),
                          M=fmt(self.p("M")))
        rest = (1.0, 0.0, 0.0, 0.0)
        return Setup(xml, "box", (0.0, 0.0, H, *rest, 0.0, y, R, *rest), (0.0,) * 12,
                     SETTLE_S + WINDOW_S)

    def ball_slip(self, trace: ProbeTrace) -> np.ndarray:
        """The ball's contact point's velocity in the table's plane (m/s), one row per step.

        MuJoCo's contact point is midway through the penetration: (R + z) / 2 below the
        centre (z the centre's height); its velocity is v + w x (0, 0, -(R + z) / 2), with w
        turned from the free joint's body frame into the world's.
        """
        q, v = trace.qpos[:, _BALL_Q:_BALL_Q + 7], trace.qvel[:, _BALL_V:_BALL_V + 6]
        w = _rotate(q[:, 3:7], v[:, 3:6])
        lever = 0.5 * (self.p("R") + q[:, 2])
        return np.column_stack([v[:, 0] - lever * w[:, 1], v[:, 1] + lever * w[:, 0]])

    @staticmethod
    def window(trace: ProbeTrace) -> np.ndarray:
        """Which rows are read: from :data:`SETTLE_S` on."""
        return trace.time >= SETTLE_S - 1e-9

    @staticmethod
    def _creep_umps(v: np.ndarray) -> float:
        """The mean of in-plane velocities ``v`` (rows), as a speed in um/s (NaN: no rows)."""
        if len(v) == 0:
            return math.nan
        return 1e6 * float(np.hypot(*v.mean(axis=0)))

    @staticmethod
    def _fit_slope(t: np.ndarray, v: np.ndarray) -> float:
        """The least-squares line's slope through (t, v) (NaN: fewer than 3 rows)."""
        if len(t) < 3:
            return math.nan
        return float(np.polyfit(t, v, 1)[0])

    def quantities_of(self, mode: str) -> tuple[Quantity, ...]:
        """A slide mode: the slide and the roll; a stay mode: the creeps and the roll."""
        names = (("slide_accel_mps2",) if self.settings(mode)[3]
                 else ("box_creep_umps", "ball_creep_umps")) + ("ball_roll_accel_mps2",)
        return tuple(self.quantity(n) for n in names)

    def measure(self, mode: str, trace: ProbeTrace) -> list[Measured]:
        """The box's creep (or slide) and the ball's creep and roll against Coulomb's."""
        sliding = self.settings(mode)[3]
        w = self.window(trace)
        t = trace.time[w]
        note = "" if len(t) >= 3 else f"no rows after the settling ({SETTLE_S:g} s)"
        out = []
        if sliding:
            out.append(Measured(self.quantity("slide_accel_mps2"),
                                self._fit_slope(t, trace.qvel[w, 0]), self.slide_accel(mode),
                                note))
        else:
            out.append(Measured(self.quantity("box_creep_umps"),
                                self._creep_umps(trace.qvel[w, 0:2]), 0.0, note))
            out.append(Measured(self.quantity("ball_creep_umps"),
                                self._creep_umps(self.ball_slip(trace)[w]), 0.0, note))
        out.append(Measured(self.quantity("ball_roll_accel_mps2"),
                            self._fit_slope(t, trace.qvel[w, _BALL_V]), self.roll_accel(mode),
                            note))
        return out

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:
        """Below the friction angle the box's travel (um) against 0; above, its speed vs a t."""
        if self.settings(mode)[3]:
            return Curve("box speed down the slope (m/s)", trace.time, trace.qvel[:, 0],
                         self.slide_accel(mode) * trace.time)
        travel = 1e6 * (trace.qpos[:, 0] - trace.qpos[0, 0])
        return Curve("box travel down the slope (um)", trace.time, travel,
                     np.zeros_like(trace.time))


__all__ = ["CREEP_TOL_UMPS", "IMPRATIO_HARD", "MODE_SETTINGS", "NOSLIP_ITERATIONS", "SETTLE_S",
           "WINDOW_S", "Incline"]
