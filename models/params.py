"""Frozen parameter objects for the loaded-sphere tippe top, SI units inside.

The paper (Ueda, Sasaki & Watanabe, eq. 3.10) states its top in cgs units; those values enter
only through :meth:`TopParams.from_cgs`. Everything else is SI: metres, kilograms, seconds,
radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tippetop.models.errors import TippetopError, expect

# The paper's default top (eq. 3.10), cgs: R = 1.5 cm, M = 15 g, g = 980 cm/s^2.
PAPER_R_CM = 1.5  # (centimetres)
PAPER_M_G = 15.0  # (grams)
PAPER_G_CMPS2 = 980.0  # (cm / s^2)
PAPER_MU = 0.1  # (dimensionless)
PAPER_LAMBDA_CMPS = 1.0  # (cm / s)

_CM = 1e-2  # (metres per centimetre)
_G = 1e-3  # (kilograms per gram)

FRICTION_LAWS = ("modified_coulomb", "coulomb", "viscous", "coulomb_viscous", "none")

#: Half-width of the linear ramp that stands in for the set-valued exact Coulomb law at v_P = 0.
DEFAULT_COULOMB_V_EPS_MPS = 1e-5  # (m/s), 1000x below the paper's Lambda


def _finite_positive(name: str, value: float) -> float:
    expect(
        isinstance(value, (int, float)) and math.isfinite(value) and value > 0,
        name,
        "a finite number > 0",
        value,
    )
    return float(value)


def _finite(name: str, value: float) -> float:
    expect(
        isinstance(value, (int, float)) and math.isfinite(value), name, "a finite number", value
    )
    return float(value)


@dataclass(frozen=True)
class TopParams:
    """The loaded (eccentric) sphere.

    Attributes:
        R_m: Sphere radius (m).
        a_m: Distance from the sphere's centre down to the centre of mass along the symmetry
            axis (m), ``0 <= a < R``.
        M_kg: Mass (kg).
        A_kgm2: Transverse principal moment about the centre of mass (kg m^2).
        C_kgm2: Axial principal moment about the centre of mass (kg m^2).
        g_mps2: Gravitational acceleration (m/s^2).
    """

    R_m: float
    a_m: float
    M_kg: float
    A_kgm2: float
    C_kgm2: float
    g_mps2: float = 9.8

    def __post_init__(self) -> None:
        for name in ("R_m", "M_kg", "A_kgm2", "C_kgm2", "g_mps2"):
            object.__setattr__(self, name, _finite_positive(f"top.{name}", getattr(self, name)))
        a = _finite("top.a_m", self.a_m)
        expect(0 <= a < self.R_m, "top.a_m", f"0 <= a < R = {self.R_m:g} m", self.a_m)
        object.__setattr__(self, "a_m", a)
        expect(
            self.A_kgm2 >= 0.5 * self.C_kgm2 * (1 - 1e-12),
            "top.A_over_C",
            "A/C >= 1/2 (the bound for any axisymmetric body)",
            self.A_kgm2 / self.C_kgm2,
        )

    @classmethod
    def from_ratios(
        cls,
        A_over_C: float = 1.0,
        a_over_R: float = 0.1,
        C_factor: float = 1.0,
        *,
        R_m: float = PAPER_R_CM * _CM,
        M_kg: float = PAPER_M_G * _G,
        g_mps2: float = PAPER_G_CMPS2 * _CM,
    ) -> TopParams:
        """Build a top from the paper's ratios, with ``C = C_factor * (2/5) M R^2``."""
        A_over_C = _finite_positive("top.A_over_C", A_over_C)
        C_factor = _finite_positive("top.C_factor", C_factor)
        a_over_R = _finite("top.a_over_R", a_over_R)
        expect(0 <= a_over_R < 1, "top.a_over_R", "0 <= a/R < 1", a_over_R)
        R_m = _finite_positive("top.R_m", R_m)
        M_kg = _finite_positive("top.M_kg", M_kg)
        C = C_factor * 0.4 * M_kg * R_m * R_m  # inf on overflow, rejected below
        return cls(R_m=R_m, a_m=a_over_R * R_m, M_kg=M_kg, A_kgm2=A_over_C * C, C_kgm2=C,
                   g_mps2=g_mps2)

    @classmethod
    def from_cgs(
        cls,
        A_over_C: float = 1.0,
        a_cm: float = 0.15,
        C_factor: float = 1.0,
        *,
        R_cm: float = PAPER_R_CM,
        M_g: float = PAPER_M_G,
        g_cmps2: float = PAPER_G_CMPS2,
    ) -> TopParams:
        """The paper's cgs parameter set (eq. 3.10), converted once to SI here."""
        R_cm = _finite_positive("top.R_cm", R_cm)
        return cls.from_ratios(
            A_over_C,
            _finite("top.a_cm", a_cm) / R_cm,
            C_factor,
            R_m=R_cm * _CM,
            M_kg=_finite_positive("top.M_g", M_g) * _G,
            g_mps2=_finite_positive("top.g_cmps2", g_cmps2) * _CM,
        )

    @property
    def A_over_C(self) -> float:
        """Ratio of the transverse to the axial moment."""
        return self.A_kgm2 / self.C_kgm2

    @property
    def a_over_R(self) -> float:
        """Eccentricity of the centre of mass, in sphere radii."""
        return self.a_m / self.R_m

    @property
    def C_factor(self) -> float:
        """``C / ((2/5) M R^2)``."""
        return self.C_kgm2 / (0.4 * self.M_kg * self.R_m**2)


@dataclass(frozen=True)
class FrictionParams:
    """Sliding friction at the contact point.

    Attributes:
        law: One of ``modified_coulomb`` (the paper's eq. 2.12), ``coulomb``, ``viscous``,
            ``coulomb_viscous``, ``none`` (frictionless).
        mu: Coulomb coefficient (dimensionless, >= 0).
        Lambda_mps: The modified Coulomb law's regularising speed (m/s, > 0).
        viscous_Nspm: Viscous coefficient c in F = -c v_P (N s/m). ``None`` means
            ``mu M g / Lambda``, the slope of the paper's law at v_P = 0, so that the laws agree
            for small slip.
        coulomb_v_eps_mps: Exact Coulomb only: below this slip speed the set-valued law is
            replaced by a linear ramp (:mod:`reference_ode.friction`; docs/design.md).
    """

    law: str = "modified_coulomb"
    mu: float = PAPER_MU
    Lambda_mps: float = PAPER_LAMBDA_CMPS * _CM
    viscous_Nspm: float | None = None
    coulomb_v_eps_mps: float = DEFAULT_COULOMB_V_EPS_MPS

    def __post_init__(self) -> None:
        expect(self.law in FRICTION_LAWS, "friction.law", "one of " + "|".join(FRICTION_LAWS),
               self.law, FRICTION_LAWS)
        mu = _finite("friction.mu", self.mu)
        expect(mu >= 0, "friction.mu", "a finite number >= 0", self.mu)
        object.__setattr__(self, "mu", mu)
        object.__setattr__(self, "Lambda_mps", _finite_positive("friction.Lambda_mps",
                                                                self.Lambda_mps))
        object.__setattr__(
            self, "coulomb_v_eps_mps",
            _finite_positive("friction.coulomb_v_eps_mps", self.coulomb_v_eps_mps))
        if self.viscous_Nspm is not None:
            c = _finite("friction.viscous_Nspm", self.viscous_Nspm)
            expect(c >= 0, "friction.viscous_Nspm", "a finite number >= 0", self.viscous_Nspm)
            object.__setattr__(self, "viscous_Nspm", c)

    def viscous_coefficient(self, top: TopParams) -> float:
        """The viscous coefficient c (N s/m) for ``top``."""
        if self.viscous_Nspm is not None:
            return self.viscous_Nspm
        return self.mu * top.M_kg * top.g_mps2 / self.Lambda_mps

    def slip_relaxation_rate(self, top: TopParams, reach_m: float | None = None) -> float:
        """How fast the law drives the contact point's slip to zero near v_P = 0 (1/s).

        The law's slope at zero slip (N s/m: mu M g / Lambda for the paper's law, plus c for a
        viscous term) times the contact point's response to a tangential force, bounded above
        by 1/M + l^2 / A for a contact point at most l from G (``reach_m``; the ball's is
        R + a, a stem's is farther), turning about an axis through G of moment A.

        A law applied explicitly once per stage (MuJoCo's paper mode) follows the slip only
        with steps below about 1/rate: beyond, the slip overshoots zero every step and the
        force flips instead of relaxing (unstable for a viscous law, a chatter of amplitude
        ~ dt mu g M (1/M + l^2 / A) for a Coulomb-type one). The exact Coulomb law's ramp is a
        device of the reference's integrator, not of the law, and is left out. 0 for no
        friction.
        """
        slope = 0.0
        if self.law == "modified_coulomb":
            slope += self.mu * top.M_kg * top.g_mps2 / self.Lambda_mps
        if self.law in ("viscous", "coulomb_viscous"):
            slope += self.viscous_coefficient(top)
        reach = top.R_m + top.a_m if reach_m is None else max(reach_m, top.R_m + top.a_m)
        inv_mass = 1.0 / top.M_kg + reach**2 / top.A_kgm2
        return slope * inv_mass


STEM_KINDS = ("sphere", "cylinder")
#: A scene's default stem, in sphere radii: a rounded end 1.3 R from the ball's centre, of
#: radius 0.2 R (it touches the table at theta = 2.23 rad, 128 degrees).
DEFAULT_STEM_OFFSET_R = 1.3
DEFAULT_STEM_RADIUS_R = 0.2


@dataclass(frozen=True)
class StemParams:
    """The stem's end: a second contact surface on the symmetry axis, beyond the ball.

    The stem points along +k from the ball's centre S (away from the centre of mass): a real
    tippe top turns over onto it. Its end touches the table once the top has turned far enough.

    Attributes:
        kind: ``sphere`` (a rounded end: a sphere, or a capsule's cap) or ``cylinder`` (a flat
            end that touches with its rim).
        offset_m: Distance from S to the end's centre along k (m): the centre of the rounded
            end's sphere, or of the flat end's disc.
        radius_m: The rounded end's radius, or the flat end's rim radius (m).
    """

    kind: str
    offset_m: float
    radius_m: float

    def __post_init__(self) -> None:
        expect(self.kind in STEM_KINDS, "stem.kind", "|".join(STEM_KINDS), self.kind,
               STEM_KINDS)
        for name in ("offset_m", "radius_m"):
            object.__setattr__(self, name, _finite_positive(f"stem.{name}", getattr(self, name)))

    def touch_cos(self, R_m: float) -> float:
        """The cosine of theta at which the end touches the table with the ball on it.

        The end's lowest point is at height R + offset cos(theta) - r (rounded) or
        R + offset cos(theta) - r sin(theta) (flat, rim) above the table.
        """
        l, r = self.offset_m, self.radius_m
        if self.kind == "sphere":
            return (r - R_m) / l
        # R + l c = r sqrt(1 - c^2): squared, (l^2 + r^2) c^2 + 2 R l c + R^2 - r^2 = 0, whose
        # larger root is the first touch as the tilt grows (the smaller one solves
        # R + l c = -r sqrt(1 - c^2), the far side of the rim)
        aa, bb, cc = l * l + r * r, 2.0 * R_m * l, R_m * R_m - r * r
        disc = bb * bb - 4.0 * aa * cc
        return (-bb + math.sqrt(max(disc, 0.0))) / (2.0 * aa)

    def check_protrudes(self, R_m: float) -> None:
        """Raise unless the end reaches beyond the ball (else it can never touch the table)."""
        c = self.touch_cos(R_m)
        expect(-1.0 < c < 1.0 and self.offset_m + self.radius_m > R_m, "stem",
               f"an end that reaches beyond the ball of radius R = {R_m:g} m (offset + "
               "radius > R)", f"offset {self.offset_m:g} m, radius {self.radius_m:g} m")


@dataclass(frozen=True)
class InitialState:
    """Initial state in the paper's variables (Sec. 2).

    Attributes:
        theta0: Tilt of the symmetry axis from the vertical (rad), in [0, pi].
        thetadot0: Tilt rate (rad/s).
        Omega0: Precession rate of the plane Pi about the vertical (rad/s).
        n0: Spin, the angular velocity's component along the symmetry axis (rad/s).
        uOX: Centre-of-mass velocity along OX, horizontal in the plane Pi (m/s).
        uOY: Centre-of-mass velocity along OY, horizontal and normal to Pi (m/s).
    """

    theta0: float = 0.1
    thetadot0: float = 0.0
    Omega0: float = 0.0
    n0: float = 100.0
    uOX: float = 0.0
    uOY: float = 0.0

    def __post_init__(self) -> None:
        for name in ("thetadot0", "Omega0", "n0", "uOX", "uOY"):
            object.__setattr__(self, name, _finite(f"init.{name}", getattr(self, name)))
        theta0 = _finite("init.theta0", self.theta0)
        expect(0 <= theta0 <= math.pi, "init.theta0", "an angle in [0, pi] rad", self.theta0)
        object.__setattr__(self, "theta0", theta0)


__all__ = [
    "FRICTION_LAWS",
    "FrictionParams",
    "InitialState",
    "STEM_KINDS",
    "StemParams",
    "TippetopError",
    "TopParams",
]
