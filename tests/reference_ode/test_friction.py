"""The friction terms against their defining formulas."""

from __future__ import annotations

import math

import pytest

from tippetop.models.params import FrictionParams, TopParams
from tippetop.reference_ode.friction import LAW_TERMS, friction_terms
from tippetop.reference_ode.params_array import (
    P_CVISC,
    P_LAM,
    P_MU,
    P_VEPS,
    friction_law,
    pack_params,
)

MU, LAM, C, VEPS = 0.3, 0.01, 2.5, 1e-5


def force(law: str, vx: float, vy: float, N: float) -> tuple[float, float]:
    ck, visc = LAW_TERMS[law]
    phix, phiy, psix, psiy = friction_terms(ck, visc, vx, vy, MU, LAM, C, VEPS)
    return N * phix + psix, N * phiy + psiy


@pytest.mark.parametrize("v", [(0.02, -0.01), (1e-4, 3e-4), (-2.0, 0.5)])
def test_modified_coulomb_is_eq_2_12(v: tuple[float, float]) -> None:
    N = 0.147
    Fx, Fy = force("modified_coulomb", *v, N)
    den = math.sqrt(v[0] ** 2 + v[1] ** 2 + LAM**2)
    assert (Fx, Fy) == pytest.approx((-MU * N * v[0] / den, -MU * N * v[1] / den), rel=1e-14)


def test_exact_coulomb_magnitude_and_ramp() -> None:
    N = 0.2
    Fx, Fy = force("coulomb", 0.03, -0.04, N)
    assert math.hypot(Fx, Fy) == pytest.approx(MU * N, rel=1e-14)
    assert Fx / Fy == pytest.approx(0.03 / -0.04)
    # inside the ramp |F| = mu N |v| / v_eps, continuous at |v| = v_eps
    Fx, Fy = force("coulomb", 0.5 * VEPS, 0.0, N)
    assert Fx == pytest.approx(-0.5 * MU * N)
    assert force("coulomb", 0.0, 0.0, N) == (0.0, 0.0)


def test_viscous_and_sum() -> None:
    Fx, Fy = force("viscous", 0.02, -0.01, 123.0)  # independent of N
    assert (Fx, Fy) == pytest.approx((-C * 0.02, C * 0.01))
    cv = force("coulomb_viscous", 0.02, -0.01, 0.2)
    c = force("coulomb", 0.02, -0.01, 0.2)
    assert cv == pytest.approx((c[0] - C * 0.02, c[1] + C * 0.01))


def test_default_viscous_coefficient_matches_the_paper_law_slope() -> None:
    """The viscous law's default c is the slope of the paper's law at v_P = 0 with N = M g
    (so that the laws agree for small slip): a central difference of the modified Coulomb
    force through the reference's packed parameters, at h = 1e-6 m/s (truncation (h/Lambda)^2
    / 2 = 5e-9 relative), equals the viscous law's slope to 1e-7."""
    top = TopParams.from_ratios(1.0, 0.1)
    N = top.M_kg * top.g_mps2
    h = 1e-6

    def slope(law: str) -> float:
        p = pack_params(top, FrictionParams(law=law))
        ck, visc = friction_law(p)
        plus = friction_terms(ck, visc, h, 0.0, p[P_MU], p[P_LAM], p[P_CVISC], p[P_VEPS])
        minus = friction_terms(ck, visc, -h, 0.0, p[P_MU], p[P_LAM], p[P_CVISC], p[P_VEPS])
        return (N * (plus[0] - minus[0]) + (plus[2] - minus[2])) / (2 * h)

    paper, viscous = slope("modified_coulomb"), slope("viscous")
    assert paper < 0.0
    assert viscous == pytest.approx(paper, rel=1e-7)
