"""The friction terms against their defining formulas."""

from __future__ import annotations

import math

import pytest

from tippetop.models.params import FrictionParams, TopParams
from tippetop.reference_ode.friction import LAW_TERMS, friction_terms

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
    """c defaults to mu M g / Lambda, the slope of the paper's law at v_P = 0 with N = M g."""
    top = TopParams.from_ratios(1.0, 0.1)
    fr = FrictionParams()
    assert fr.viscous_coefficient(top) == pytest.approx(
        fr.mu * top.M_kg * top.g_mps2 / fr.Lambda_mps)
