"""Parameter objects: units, constructors, validation messages."""

from __future__ import annotations

import math

import pytest

from tippetop.models.errors import TippetopError
from tippetop.models.params import FrictionParams, InitialState, TopParams


def test_paper_cgs_set_is_converted_once_to_si() -> None:
    """Eq. 3.10: R = 1.5 cm, a = 0.15 cm, M = 15 g, g = 980 cm/s^2, A = C = (2/5) M R^2."""
    top = TopParams.from_cgs(A_over_C=1.0, a_cm=0.15)
    assert top.R_m == pytest.approx(0.015)
    assert top.a_m == pytest.approx(0.0015)
    assert top.M_kg == pytest.approx(0.015)
    assert top.g_mps2 == pytest.approx(9.8)
    assert top.C_kgm2 == pytest.approx(0.4 * 0.015 * 0.015**2)
    # eq. 3.10: A = C for the default top. The products of the cgs values and the unit factors
    # round differently from the SI literals, so 1e-15 relative (a few ulp), not equality.
    assert top.A_kgm2 == pytest.approx(0.4 * 0.015 * 0.015**2, rel=1e-15)
    ratios = TopParams.from_ratios(1.0, 0.1)
    for name in ("R_m", "a_m", "M_kg", "A_kgm2", "C_kgm2", "g_mps2"):
        assert getattr(top, name) == pytest.approx(getattr(ratios, name), rel=1e-12)


def test_ratio_properties_round_trip() -> None:
    top = TopParams.from_ratios(1.25, 0.15, 0.8)
    assert (top.A_over_C, top.a_over_R, top.C_factor) == pytest.approx((1.25, 0.15, 0.8))


def test_frozen() -> None:
    top = TopParams.from_ratios()
    with pytest.raises(AttributeError):
        top.M_kg = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        (dict(R_m=0.015, a_m=0.001, M_kg=-1, A_kgm2=1e-6, C_kgm2=1e-6), "top.M_kg"),
        (dict(R_m=0.015, a_m=0.015, M_kg=0.015, A_kgm2=1e-6, C_kgm2=1e-6), "0 <= a < R"),
        (dict(R_m=0.015, a_m=-0.001, M_kg=0.015, A_kgm2=1e-6, C_kgm2=1e-6), "top.a_m"),
        (dict(R_m=0.015, a_m=0.001, M_kg=0.015, A_kgm2=0.4e-6, C_kgm2=1e-6), "A/C >= 1/2"),
        (dict(R_m=math.nan, a_m=0.001, M_kg=0.015, A_kgm2=1e-6, C_kgm2=1e-6), "top.R_m"),
        (dict(R_m=0.015, a_m=0.001, M_kg=0.015, A_kgm2=math.inf, C_kgm2=1e-6), "top.A_kgm2"),
        (dict(R_m=0.015, a_m=0.001, M_kg=0.015, A_kgm2=1e-6, C_kgm2=0.0), "top.C_kgm2"),
    ],
)
def test_top_validation_names_the_value(kwargs: dict, fragment: str) -> None:
    with pytest.raises(TippetopError, match="expected") as exc:
        TopParams(**kwargs)
    assert fragment in str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_over_c_half_is_allowed() -> None:
    """A/C = 1/2 is the bound itself (a flat disc); it is valid."""
    assert TopParams.from_ratios(0.5, 0.1).A_over_C == pytest.approx(0.5)


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        (dict(law="stiction"), "friction.law"),
        (dict(mu=-0.1), "friction.mu"),
        (dict(Lambda_mps=0.0), "friction.Lambda_mps"),
        (dict(Lambda_mps=math.nan), "friction.Lambda_mps"),
        (dict(viscous_Nspm=-1.0), "friction.viscous_Nspm"),
    ],
)
def test_friction_validation(kwargs: dict, fragment: str) -> None:
    with pytest.raises(TippetopError, match=fragment):
        FrictionParams(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [(dict(theta0=-0.1), "init.theta0"), (dict(theta0=4.0), "init.theta0"),
     (dict(n0=math.nan), "init.n0"), (dict(uOX=math.inf), "init.uOX")],
)
def test_initial_state_validation(kwargs: dict, fragment: str) -> None:
    with pytest.raises(TippetopError, match=fragment):
        InitialState(**kwargs)
