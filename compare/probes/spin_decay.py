"""spin-decay: a ball spinning about the vertical, on a level table.

A uniform ball (radius R, mass M, inertia I = 2/5 M R^2) rests on a level table, spinning at
w0 about the vertical, with no other motion. MuJoCo's contact with ``condim`` 4 adds a
torsional friction torque about the contact normal, bounded by its cone: the torsional
coefficient mu_t (a length: MuJoCo's docs read it as the contact patch's size) times the
normal force N. Both of MuJoCo's cones give |tau| <= mu_t N for a pure torsion (elliptic:
f_n^2 >= sum f_i^2 / mu_i^2; pyramidal: sum |f_i| / mu_i <= f_n), and a pure spin asks for no
tangential force, so while the ball spins the whole bound is the torque, N = M g and

    I dw/dt = -mu_t M g,    w(t) = w0 - (mu_t M g / I) t = w0 - 5/2 (mu_t g / R^2) t,

until it stops at t_stop = I w0 / (mu_t M g). With ``condim`` 3 nothing acts on a spin about
the vertical through the contact point (the tangential friction sees no slip there): w stays
w0 exactly.

MuJoCo's friction is soft: below a spin w* it relaxes the spin over its time constant
(viscously) instead of holding the torque at mu_t N. For an elliptic cone the torsional row's
unbounded torque is b w / (A + R_t), so w* = mu_t N (A + R_t) / b, with A = 1/I, R_t = R_0 mu^2
/ (mu_t^2 impratio) (MuJoCo's engine_core_constraint.c), R_0 = (1 - d)/d / M and b = 2 /
(solimp[1] timeconst): about 4-5 rad/s at the defaults here (d = 0.9-0.95, timeconst 0.02 s).
So the probe fits the decay rate over the spin's fall from :data:`WINDOW` = (0.8, 0.2) w0,
80 to 20 rad/s by default, 4x above w* and past the ball's settling onto the table.

What MuJoCo 4.0.0 does besides (measured): the spinning ball chatters on the table, off it
(by a fraction of a millimetre) on more than half of the window's steps: the friction rows
push along the normal, as a slipping contact does in MuJoCo's model. The decay rate is still
mu_t M g / I, the mean normal force being M g. The elliptic cone holds mu_t N down to
w* = 5 rad/s; the pyramidal cone's torque falls short of it from about twice that (its
tangential edges keep part of the normal force: 0.9 of the law at 10 rad/s, 0.5 at 5), so the
window ends at 20 rad/s.

Modes: ``condim4-pyramidal`` and ``condim4-elliptic`` (the decay rate), ``condim3`` (the spin
kept; MuJoCo's default pyramidal cone). MuJoCo's default friction (1, 0.005, 0.0001), impratio
1, solref and solimp.
"""

from __future__ import annotations

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
from tippetop.models.errors import TippetopError, did_you_mean

if TYPE_CHECKING:
    from tippetop.mujoco_runner.probe_run import ProbeTrace

#: The spin's fall the decay rate is fitted over, as fractions of w0 (from, to).
WINDOW = (0.8, 0.2)
#: MuJoCo's default rolling coefficient (m): a condim-4 contact does not use it.
ROLL_COEFF_M = 0.0001

_XML = """<mujoco model="spin-decay">
  <option timestep="0.002" gravity="0 0 {g}" cone="{cone}"/>
  <worldbody>
    <geom name="table" type="plane" size="5 5 0.1" friction="{mu} {mu_t} {mu_r}"
          condim="{condim}"/>
    <body name="ball" pos="0 0 {R}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{R}" mass="{M}" friction="{mu} {mu_t} {mu_r}"
            condim="{condim}"/>
    </body>
  </worldbody>
</mujoco>"""

#: Each mode's (condim, cone).
_MODES = {"condim4-pyramidal": (4, "pyramidal"), "condim4-elliptic": (4, "elliptic"),
          "condim3": (3, "pyramidal")}


def check_params(probe: Probe) -> None:
    """Every parameter of ``probe`` is a finite number > 0.

    Raises:
        TippetopError: One that is not (one line: what was expected, what was given).
    """
    for key in probe.params:
        v = probe.p(key)
        if not (np.isfinite(v) and v > 0):
            raise TippetopError(f"{probe.name}.{key}: expected a finite number > 0, got {v!r}")


def check_mode(probe: Probe, mode: str) -> None:
    """``mode`` is one of ``probe``'s.

    Raises:
        TippetopError: It is not (one line, with a did-you-mean).
    """
    if mode not in probe.modes:
        raise TippetopError(f"{probe.name}: expected a mode of {', '.join(probe.modes)}, "
                            f"got {mode!r}{did_you_mean(mode, probe.modes)}")


def fit_rate(t: np.ndarray, x: np.ndarray, x0: float) -> tuple[float, str]:
    """The rate x falls at over its fall from WINDOW[0] x0 to WINDOW[1] x0: (-slope, note).

    A least-squares line through every row of the window. NaN (with the reason) when fewer
    than three rows are in it; a note when the run ended before the window did.
    """
    hi, lo = WINDOW[0] * x0, WINDOW[1] * x0
    sel = np.isfinite(x) & (x <= hi) & (x >= lo)
    if int(sel.sum()) < 3:
        return float("nan"), f"fewer than 3 steps between {WINDOW[0]:g} and {WINDOW[1]:g} " \
                             "of the start's value: it hardly fell"
    note = "" if np.nanmin(x) < lo else f"the run ended before it fell to {WINDOW[1]:g} of " \
                                         "the start's value"
    return -float(np.polyfit(t[sel] - t[sel][0], x[sel], 1)[0]), note


def off_table_note(trace: ProbeTrace, x: np.ndarray, x0: float) -> str:
    """How often the ball left the table inside the window (the contacts read, C MuJoCo only)."""
    sel = (x <= WINDOW[0] * x0) & (x >= WINDOW[1] * x0) & (trace.ncon >= 0)
    if not sel.any():
        return ""
    off = float(np.mean(trace.ncon[sel] == 0))
    return f"off the table on {off:.0%} of the window's steps" if off > 0 else ""


@dataclass(frozen=True)
class SpinDecay(Probe):
    """spin-decay: w(t) = w0 - (mu_t M g / I) t with condim 4, w0 with condim 3 (module doc)."""

    name: ClassVar[str] = "spin-decay"
    title: ClassVar[str] = ("a ball spinning about the vertical slows at mu_t M g / I with "
                            "torsional friction, keeps its spin without")
    modes: ClassVar[tuple[str, ...]] = tuple(_MODES)
    params: ClassVar[dict[str, float]] = {"mu": 1.0, "mu_t": 0.005, "w0": 100.0, "R": 0.02,
                                          "M": 0.05, "g": G_MPS2}
    quantities: ClassVar[tuple[Quantity, ...]] = (
        Quantity("spin_decay_radps2", "rad/s^2", 3.0,
                 f"the spin's decay rate, fitted over its fall from {WINDOW[0]:g} to "
                 f"{WINDOW[1]:g} w0 (condim 4)",
                 "1 % of the default's 306.6: the window stays 4x above the spin where "
                 "MuJoCo's soft torsional friction relaxes, so the torque is on its cone "
                 "(mu_t N); 1 % for the chattering normal force's mean against M g"),
        Quantity("spin_final_radps", "rad/s", 1e-6,
                 "the spin at the end of the run (condim 3)",
                 "no torque acts on the spin (the contact point is on its axis): only "
                 "rounding moves it, 1e-8 of w0"),
    )

    def inertia(self) -> float:
        """The ball's moment of inertia, 2/5 M R^2 (kg m^2)."""
        return sphere_inertia(self.p("M"), self.p("R"))

    def rate(self) -> float:
        """The torsional law's decay rate, mu_t M g / I (rad/s^2)."""
        return self.p("mu_t") * self.p("M") * self.p("g") / self.inertia()

    def t_stop(self) -> float:
        """When the torsional law stops the spin, w0 / rate (s)."""
        return self.p("w0") / self.rate()

    def setup(self, mode: str) -> Setup:
        """The ball on its table spinning at w0 about z; run to 1.5 t_stop.

        Raises:
            TippetopError: An unknown mode, a parameter that is not a finite number > 0.
        """
        check_mode(self, mode)
        check_params(self)
        condim, cone = _MODES[mode]
        R = self.p("R")
        xml = _XML.format(g=fmt(-self.p("g")), cone=cone, mu=fmt(self.p("mu")),
                          mu_t=fmt(self.p("mu_t")), mu_r=fmt(ROLL_COEFF_M), condim=condim,
                          R=fmt(R), M=fmt(self.p("M")))
        return Setup(xml, "ball", (0.0, 0.0, R, 1.0, 0.0, 0.0, 0.0),
                     (0.0, 0.0, 0.0, 0.0, 0.0, self.p("w0")), 1.5 * self.t_stop())

    @staticmethod
    def spin(trace: ProbeTrace) -> np.ndarray:
        """The spin about z (rad/s) at every step.

        The free joint's body-frame w_z, which is the world's while the ball turns about z only.
        """
        return np.asarray(trace.qvel[:, 5], dtype=float)

    def quantities_of(self, mode: str) -> tuple[Quantity, ...]:
        """The quantity of a mode: the spin kept (condim 3), or its decay rate (condim 4)."""
        return (self.quantity("spin_final_radps" if _MODES[mode][0] == 3
                              else "spin_decay_radps2"),)

    def measure(self, mode: str, trace: ProbeTrace) -> list[Measured]:
        """The decay rate against mu_t M g / I (condim 4), the last spin against w0 (condim 3)."""
        w0 = self.p("w0")
        w = self.spin(trace)
        if _MODES[mode][0] == 3:
            return [Measured(self.quantity("spin_final_radps"), float(w[-1]), w0)]
        rate, note = fit_rate(np.asarray(trace.time, dtype=float), w, w0)
        note = "; ".join(n for n in (note, off_table_note(trace, w, w0)) if n)
        return [Measured(self.quantity("spin_decay_radps2"), rate, self.rate(), note)]

    def curve(self, mode: str, trace: ProbeTrace) -> Curve:
        """The spin against max(w0 - rate t, 0) (condim 4) or w0 (condim 3)."""
        t = np.asarray(trace.time, dtype=float)
        w0 = self.p("w0")
        if _MODES[mode][0] == 3:
            exact = np.full_like(t, w0)
        else:
            exact = np.maximum(w0 - self.rate() * t, 0.0)
        return Curve("spin about the vertical (rad/s)", t, self.spin(trace), exact)


__all__ = ["ROLL_COEFF_M", "WINDOW", "SpinDecay", "check_mode", "check_params", "fit_rate",
           "off_table_note"]
