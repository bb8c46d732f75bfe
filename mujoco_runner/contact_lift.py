"""How MuJoCo's soft contact turns friction into normal force: the lift-off slip, measured.

A rigid contact with Coulomb's friction, and the paper's law, push a sliding ball up with
exactly M g: friction is horizontal. MuJoCo's contact force is the projection, onto its friction
cone, of the force that would bring the contact's accelerations to their reference values
(MuJoCo's computation docs, "Parameters"); its friction rows aim to stop the slip, so their
demand grows with the slip. Once the demand exceeds what the cone holds at the present normal
force, the projection raises the normal force too (a pyramidal cone at once: each of its rows
is normal and friction together). The extra normal force grows with the slip and with mu: at
a large enough slip it exceeds M g at zero penetration, and sliding alone pushes the ball off
the table. That slip is the contact's *lift-off slip*.

Measured without time stepping, on a uniform ball of the top's radius and mass resting on a
plane with the contact's settings (``mj_forward`` at a given penetration and slip; the slip is
a spin about a horizontal axis, so the contact point moves and the centre does not):

- :func:`lift_off_slip`: the slip above which MuJoCo's normal force at zero penetration
  exceeds M g (None: not below :data:`MAX_SLIP_MPS`);
- :func:`half_mu_slip`: the slip at which the friction force reaches half of mu M g at the
  resting penetration (the paper's law: Lambda / sqrt(3));
- :func:`limit_scan`: over MuJoCo's own ranges of the settings a geom can carry, the largest
  lift-off slip among the settings whose friction is as stiff as the paper's law within a
  factor (:data:`STIFF_FACTOR`): whether any geom setting can both follow the law and keep the
  ball on the table at the reference's slip.

Measured on MuJoCo 4.0.0 (R = 2 cm, M = 55.5 g, the tutorial top's ball): MuJoCo's default
contact at mu = 1 lifts the ball above 0.40 m/s, the calibrated settings scaled to mu = 1
above 0.63 m/s; the tutorial top's reference slips at up to 0.88 m/s before its stem lands.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

#: The slips the curve is read at (m/s): 1e-4 to 10 m/s, log-spaced.
SLIPS_MPS = np.logspace(-4, 1, 61)
#: Slips beyond this are not searched (m/s): a tippe top's contact slips at most ~ R n.
MAX_SLIP_MPS = 10.0
#: "Zero" penetration (m): touching, no spring force.
TOUCH_M = 1e-9
#: A setting's friction is "as stiff as the paper's law" if it reaches half of mu N within this
#: factor of the law's slip for it, Lambda / sqrt(3).
STIFF_FACTOR = 2.0
#: The grid of :func:`limit_scan`, within MuJoCo's own bounds: impratio > 0 (no upper bound;
#: the menagerie's models use up to 100), the solref time constant >= 2 dt (MuJoCo clamps a
#: shorter one), the impedance d0 in [1e-4, 0.9999] (mjMINIMP, mjMAXIMP), damping ratio > 0.
SCAN_IMPRATIO = (0.02, 0.1, 1.0, 10.0, 100.0, 1000.0)
SCAN_TIMECONST_S = (None, 0.002, 0.02)  # None: 2 dt, MuJoCo's shortest
SCAN_D0 = (1e-4, 0.05, 0.9, 0.99)
SCAN_DAMPRATIO = (1.0, 4.0)

#: The probe: a uniform ball of the top's radius and mass (its inertia 2/5 M R^2, as MuJoCo's
#: sphere of that mass has it: the contact's effective mass, which shapes MuJoCo's soft force,
#: is a ball's). While it slides, a torque equal and opposite to the friction's own holds the
#: slip, as a spinning top's contact is held at its slip by its spin.
_XML = """<mujoco><option timestep="{dt}" cone="{cone}" impratio="{impratio}"
 integrator="{integrator}"/>
<worldbody><geom name="floor" type="plane" size="1 1 .01" {contact}/>
<body pos="0 0 {R}"><freejoint/><geom name="ball" type="sphere" size="{R}" mass="{M}"
 {contact}/></body>
</worldbody>{pairs}</mujoco>"""
#: How long the probe slides at one slip (s), and the flight that counts as leaving the table:
#: the harness's own (:data:`tippetop.compare.measures.series.HOP_MIN_S`, 10 ms, and
#: :data:`~tippetop.compare.measures.series.FLIGHT_RISE_M`, 10 um), no contact at any step for
#: that long with the ball risen that high.
SLIDE_S = 0.1
FLIGHT_S = 0.01
FLIGHT_RISE_M = 1e-5


@dataclass(frozen=True)
class Contact:
    """The contact settings a geom carries, and the model options that shape its force.

    Attributes:
        mu: Sliding friction coefficient.
        cone: ``pyramidal`` or ``elliptic``.
        impratio: Friction-to-normal impedance ratio.
        solref: (time constant s, damping ratio), or negative (-stiffness, -damping).
        solimp: (d0, dmax, width m, midpoint, power).
        timestep_s: The model's step (MuJoCo clamps a time constant below 2 dt).
        solreffriction: The friction rows' own solref, on a contact pair (elliptic cone);
            None: they use solref.
    """

    mu: float
    cone: str = "pyramidal"
    impratio: float = 1.0
    solref: tuple[float, float] = (0.02, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.9, 0.95, 0.001, 0.5, 2.0)
    timestep_s: float = 0.002
    solreffriction: tuple[float, float] | None = None

    def label(self) -> str:
        """One line: the settings as MJCF attributes say them."""
        sr = " ".join(f"{v:.4g}" for v in self.solref)
        si = " ".join(f"{v:.4g}" for v in self.solimp)
        out = (f"{self.cone} impratio={self.impratio:.4g} solref=\"{sr}\" solimp=\"{si}\" "
               f"mu={self.mu:.4g}")
        if self.solreffriction is not None:
            out += " solreffriction=\"" + " ".join(f"{v:.4g}" for v in self.solreffriction) + "\""
        return out


class Probe:
    """A uniform ball of the top's radius and mass on a plane, with one contact setting."""

    def __init__(self, contact: Contact, radius_m: float, mass_kg: float,
                 g_mps2: float = 9.81, integrator: str = "RK4") -> None:
        import mujoco

        self._mj = mujoco
        c = contact
        solver = (f'solref="{c.solref[0]!r} {c.solref[1]!r}" '
                  f'solimp="{" ".join(repr(float(v)) for v in c.solimp)}"')
        attrs = f'friction="{c.mu!r} 0.005 0.0001" condim="3" {solver}'
        pairs = ""
        if c.solreffriction is not None:
            # MuJoCo takes solreffriction only on a pair (five friction coefficients there)
            srf = " ".join(repr(float(v)) for v in c.solreffriction)
            pairs = (f'<contact><pair geom1="ball" geom2="floor" condim="3" '
                     f'friction="{c.mu!r} {c.mu!r} 0.005 0.0001 0.0001" {solver} '
                     f'solreffriction="{srf}"/></contact>')
        xml = _XML.format(dt=repr(c.timestep_s), cone=c.cone, impratio=repr(c.impratio),
                          integrator=integrator, contact=attrs, R=repr(radius_m),
                          M=repr(mass_kg), pairs=pairs)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.model.opt.gravity[:] = (0.0, 0.0, -g_mps2)
        self.data = mujoco.MjData(self.model)
        self.contact = contact
        self.radius_m = radius_m
        self.weight_N = mass_kg * g_mps2
        self._f6 = np.zeros(6)
        self._rest: float | None = None

    def forces(self, penetration_m: float, slip_mps: float) -> tuple[float, float]:
        """MuJoCo's normal and friction force (N) at a penetration and a slip, at rest."""
        mj, m, d = self._mj, self.model, self.data
        mj.mj_resetData(m, d)
        d.qpos[2] = self.radius_m - penetration_m
        d.qvel[3] = slip_mps / self.radius_m  # spin about x: the contact point slips along y
        mj.mj_forward(m, d)
        N = F = 0.0
        for i in range(d.ncon):
            mj.mj_contactForce(m, d, i, self._f6)
            N += float(self._f6[0])
            F += math.hypot(float(self._f6[1]), float(self._f6[2]))
        return N, F

    def rest_penetration(self) -> float:
        """The penetration at which the contact holds the ball's weight at rest (m)."""
        if self._rest is None:
            self._rest = self._find_rest()
        return self._rest

    def _find_rest(self) -> float:
        if self.forces(TOUCH_M, 0.0)[0] >= self.weight_N:
            return TOUCH_M
        lo, hi = TOUCH_M, 0.5 * self.radius_m
        if self.forces(hi, 0.0)[0] < self.weight_N:
            return hi
        for _ in range(60):
            mid = math.sqrt(lo * hi)
            if self.forces(mid, 0.0)[0] < self.weight_N:
                lo = mid
            else:
                hi = mid
            if hi / lo < 1.0 + 1e-6:
                break
        return hi

    def leaves_table(self, slip_mps: float) -> bool:
        """Whether the ball, held at this slip, leaves the table within :data:`SLIDE_S`.

        It starts at its resting penetration and slides, its slip held by a torque against
        the friction's; it leaves if it has no contact at any step for :data:`FLIGHT_S` or
        more and rises :data:`FLIGHT_RISE_M` or more meanwhile (a flight, as the harness
        counts one).
        """
        mj, m, d = self._mj, self.model, self.data
        mj.mj_resetData(m, d)
        d.qpos[2] = self.radius_m - self.rest_penetration()
        d.qvel[3] = slip_mps / self.radius_m
        dt = m.opt.timestep
        airborne, rise = 0.0, 0.0
        for _ in range(round(SLIDE_S / dt)):
            # hold the slip: a torque on the ball against the friction's about its centre
            torque = np.zeros(3)
            for i in range(d.ncon):
                c = d.contact[i]
                mj.mj_contactForce(m, d, i, self._f6)
                force = c.frame.reshape(3, 3).T @ self._f6[:3]  # contact frame to world
                torque += np.cross(c.pos - d.qpos[:3], force)
            d.xfrc_applied[1, 3:] = -torque
            mj.mj_step(m, d)
            gap = float(d.qpos[2]) - self.radius_m
            if gap > 0.0:  # no contact: the ball is above the table
                airborne += dt
                rise = max(rise, gap)
                if airborne >= FLIGHT_S - 1e-12 and rise >= FLIGHT_RISE_M:
                    return True
            else:
                airborne, rise = 0.0, 0.0
        return False

    def lift_off_slip(self) -> float | None:
        """The least slip at which the ball leaves the table (m/s; :meth:`leaves_table`).

        None if it does not within :data:`MAX_SLIP_MPS`. Found on :data:`SLIPS_MPS` and
        refined by bisection to 1 %.
        """
        return _least_slip(self.leaves_table, SLIPS_MPS[::2], 1e-2)

    def half_mu_slip(self) -> float | None:
        """The slip at which |F_t| reaches mu M g / 2 at the resting penetration (m/s)."""
        pen = self.rest_penetration()
        target = 0.5 * self.contact.mu * self.weight_N
        return _least_slip(lambda v: self.forces(pen, v)[1] >= target, SLIPS_MPS, 1e-3)

    def curve(self, slips: Iterable[float] = SLIPS_MPS) -> np.ndarray:
        """Rows of (slip m/s, N/Mg at rest penetration, |F_t|/(mu Mg) there, N/Mg touching)."""
        pen = self.rest_penetration()
        rows = []
        for v in slips:
            N, F = self.forces(pen, float(v))
            N0, _ = self.forces(TOUCH_M, float(v))
            rows.append((float(v), N / self.weight_N, F / (self.contact.mu * self.weight_N),
                         N0 / self.weight_N))
        return np.array(rows)


def _least_slip(holds: Callable[[float], bool], slips: Iterable[float],
                rel: float) -> float | None:
    """The least slip at which ``holds`` turns true (m/s), or None if it never does.

    The first of ``slips`` (ascending) where it does, refined by bisection against the one
    before it to ``rel`` of its value.
    """
    below = 0.0
    for v in slips:
        if holds(float(v)):
            lo, hi = below, float(v)
            while hi - lo > rel * hi:
                mid = 0.5 * (lo + hi)
                if holds(mid):
                    hi = mid
                else:
                    lo = mid
            return hi
        below = float(v)
    return None


def lift_off_slip(contact: Contact, radius_m: float, mass_kg: float,
                  g_mps2: float = 9.81) -> float | None:
    """The slip above which this contact pushes a sliding ball off the table (m/s), or None."""
    return Probe(contact, radius_m, mass_kg, g_mps2).lift_off_slip()


def half_mu_slip(contact: Contact, radius_m: float, mass_kg: float,
                 g_mps2: float = 9.81) -> float | None:
    """The slip at which this contact's friction reaches half of mu M g (m/s), or None."""
    return Probe(contact, radius_m, mass_kg, g_mps2).half_mu_slip()


@dataclass(frozen=True)
class ScanResult:
    """:func:`limit_scan`'s answer.

    Attributes:
        mu: The friction coefficient scanned.
        slip_mps: The slip the ball is held at (the reference's largest, say).
        law_half_slip_mps: The paper's law's half-mu slip, Lambda / sqrt(3).
        settings: How many geom settings were scanned.
        stiff: How many of them reach half of mu N within :data:`STIFF_FACTOR` of the law.
        stay: The stiff settings that keep the ball on the table at the slip.
        closest: Among the stiff settings, the one that keeps it on the longest slip (the
            best of those that stay, or else the one with the largest lift-off slip).
        closest_lift_mps: Its lift-off slip (None: not below :data:`MAX_SLIP_MPS`).
    """

    mu: float
    slip_mps: float
    law_half_slip_mps: float
    settings: int
    stiff: int
    stay: tuple[Contact, ...]
    closest: Contact | None
    closest_lift_mps: float | None

    @property
    def limit(self) -> bool:
        """Every setting stiff enough for the law lifts the ball at the slip (and some are)."""
        return self.stiff > 0 and not self.stay


def scan_grid(mu: float, timestep_s: float) -> list[Contact]:
    """Every geom setting :func:`limit_scan` tries (see the ``SCAN_`` constants)."""
    out = []
    for cone, imp, tc, d0, dr in itertools.product(
            ("pyramidal", "elliptic"), SCAN_IMPRATIO, SCAN_TIMECONST_S, SCAN_D0, SCAN_DAMPRATIO):
        tc = 2.0 * timestep_s if tc is None else max(tc, 2.0 * timestep_s)
        dmax = max(d0, 0.95)
        out.append(Contact(mu, cone, imp, (tc, dr), (d0, dmax, 0.001, 0.5, 2.0), timestep_s))
    return list(dict.fromkeys(out))


def limit_scan(mu: float, radius_m: float, mass_kg: float, Lambda_mps: float,
               slip_mps: float, timestep_s: float = 2e-4, g_mps2: float = 9.81,
               grid: Sequence[Contact] | None = None) -> ScanResult:
    """Whether any geom setting stiff enough for the law keeps a ball on the table at a slip.

    Args:
        mu: The top's friction coefficient.
        radius_m: The ball's radius.
        mass_kg: The top's mass.
        Lambda_mps: The paper's law's Lambda.
        slip_mps: The slip the ball is held at (the reference's largest while the ball alone
            touches).
        timestep_s: The step (bounds the time constant below: MuJoCo clamps it to 2 dt).
        g_mps2: Gravity.
        grid: The settings tried (default :func:`scan_grid`).

    Returns:
        :class:`ScanResult`.
    """
    law = Lambda_mps / math.sqrt(3.0)
    settings = list(grid) if grid is not None else scan_grid(mu, timestep_s)
    stiff: list[Probe] = []
    for c in settings:
        probe = Probe(c, radius_m, mass_kg, g_mps2)
        half = probe.half_mu_slip()
        if half is not None and half <= STIFF_FACTOR * law:
            stiff.append(probe)
    stay = tuple(p.contact for p in stiff if not p.leaves_table(slip_mps))
    closest, closest_lift = None, None
    if stiff:
        pool = [p for p in stiff if p.contact in stay] or stiff
        lifts = [(p.lift_off_slip(), p.contact) for p in pool[:1]] if stay else []
        if not stay:  # the stiff settings all lift: the one that holds out longest
            # a coarse look first (the slips of the grid), then the best refined
            lifts = [(p.lift_off_slip(), p.contact) for p in pool]
        key = [(math.inf if v is None else v, c) for v, c in lifts]
        best = max(key, key=lambda x: x[0]) if key else None
        if best is not None:
            closest, closest_lift = best[1], None if math.isinf(best[0]) else best[0]
    return ScanResult(mu, slip_mps, law, len(settings), len(stiff), stay, closest, closest_lift)


__all__ = ["Contact", "Probe", "ScanResult", "half_mu_slip", "lift_off_slip", "limit_scan",
           "scan_grid"]
