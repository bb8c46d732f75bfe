"""The paper's closed-form analysis of the loaded-sphere tippe top, as plain functions.

Groups I-III, the critical spins ``n1 .. n4`` and ``n_c``, the intermediate steady states,
their stability, ``xi_+-`` and the reduced energy; SI in and out, ``None`` for a quantity a top
does not have. Equations are cited by their LaTeX label (docs/design.md says why).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tippetop.compare.measures.roots import ROOT_RTOL, ROOT_XTOL, brentq
from tippetop.models.params import TopParams

#: Relative tolerance under which ``A/C`` is taken to sit exactly on a group border.
BORDER_RTOL = 1e-12

_SIGN_RTOL = 1e-12

__all__ = [
    "BORDER_RTOL",
    "ROOT_RTOL",
    "ROOT_XTOL",
    "D",
    "D_sign_at_theta_s",
    "E1",
    "F",
    "H_sign_pi",
    "H_sign_zero",
    "f1",
    "f2",
    "group",
    "jellett_from_spin",
    "brentq",
    "kappa",
    "n1",
    "n2",
    "n3",
    "n4",
    "n_c",
    "r_c",
    "summary",
    "theta_c",
    "theta_d",
    "theta_f",
    "theta_s",
    "theta_s_curve",
    "xi_minus",
    "xi_plus",
]


# --------------------------------------------------------------------------------------------
# Small helpers
# --------------------------------------------------------------------------------------------


def _close(u: float, v: float) -> bool:
    """True when ``u`` and ``v`` agree to :data:`BORDER_RTOL` relative to the larger one."""
    return abs(u - v) <= BORDER_RTOL * max(abs(u), abs(v))


def _out(value: NDArray[np.float64]) -> float | NDArray[np.float64]:
    """Return a Python float for a 0-d result and the array otherwise."""
    return float(value) if np.ndim(value) == 0 else value


def _sign(value: float, scale: float) -> int:
    """Sign of ``value``, with ``|value| <= _SIGN_RTOL * scale`` counted as 0."""
    if abs(value) <= _SIGN_RTOL * scale:
        return 0
    return 1 if value > 0 else -1


def _root(func: Callable[[float], float], lo: float, hi: float) -> float:
    """The root of ``func`` in ``[lo, hi]`` (a sign change is assumed), to :data:`ROOT_XTOL`."""
    return brentq(func, lo, hi)


def _g(top: TopParams, x: float, kap: float) -> float:
    """``f2(x) - kappa f1(x)``: same sign as ``F(x) - kappa`` where ``f1 > 0``, and no pole."""
    return float(f2(top, x)) - kap * float(f1(top, x))


# --------------------------------------------------------------------------------------------
# Classification (Sec. 3.2)
# --------------------------------------------------------------------------------------------


def group(top: TopParams) -> str:
    """The paper's group of the top (Sec. 3.2).

    ``"I"`` if ``A/C < 1 - a/R``, ``"II"`` if ``1 - a/R < A/C < 1 + a/R`` and ``"III"`` if
    ``A/C > 1 + a/R``.

    Borders: ``A/C == 1 - a/R`` counts as ``"I"`` (``n1`` is infinite there: no finite spin makes
    the state at ``theta = 0`` unstable), and ``A/C == 1 + a/R`` counts as ``"III"``
    (``theta_f = pi`` and ``n3`` is infinite). "Equal" means equal to a relative tolerance of
    :data:`BORDER_RTOL` (1e-12), so that a border built from floats (``1 - 0.15``) lands on the
    border rule. With ``a = 0`` both borders coincide at ``A/C = 1``, which is ``"I"``.

    Args:
        top: The top.

    Returns:
        ``"I"``, ``"II"`` or ``"III"``.
    """
    r, e = top.A_over_C, top.a_over_R
    lo, hi = 1.0 - e, 1.0 + e
    if r < lo or _close(r, lo):
        return "I"
    if r > hi or _close(r, hi):
        return "III"
    return "II"


def _cos_crossing(top: TopParams) -> float | None:
    """``a / (R (1 - A/C))`` clipped to ``[-1, 1]``; ``None`` when ``a = 0`` and ``A = C``.

    On a group border (to :data:`BORDER_RTOL`) it is exactly ``+1`` or ``-1``.
    """
    e, r = top.a_over_R, top.A_over_C
    if 1.0 - r == 0.0:
        return None
    if e > 0.0 and _close(r, 1.0 - e):
        return 1.0
    if e > 0.0 and _close(r, 1.0 + e):
        return -1.0
    return float(np.clip(e / (1.0 - r), -1.0, 1.0))


def theta_c(top: TopParams) -> float | None:
    """The critical angle of a Group I top (ThetaCritical), ``arccos(a / (R (1 - A/C)))``.

    The reduced slip ``v~_PY`` (VPYTilde) changes sign there: below it ``theta`` falls back to
    0, above it ``theta`` rises to ``pi``. It lies in ``[0, pi/2]``: 0 on the border
    ``A/C = 1 - a/R``, ``pi/2`` when ``a = 0``.

    Args:
        top: The top.

    Returns:
        The angle (rad), or ``None`` outside Group I, and for the degenerate ``a = 0, A = C`` top
        (where the sign of ``v_PY`` never changes and no critical angle exists).
    """
    if group(top) != "I":
        return None
    x = _cos_crossing(top)
    return None if x is None else float(np.arccos(x))


def theta_f(top: TopParams) -> float | None:
    """The fixed point of a Group III top (ThetaFixed), in ``(pi/2, pi]``.

    ``pi`` exactly on the border ``A/C = 1 + a/R``; ``pi/2`` when ``a = 0``.

    Args:
        top: The top.

    Returns:
        The angle (rad), or ``None`` outside Group III.
    """
    if group(top) != "III":
        return None
    x = _cos_crossing(top)
    return None if x is None else float(np.arccos(x))


# --------------------------------------------------------------------------------------------
# Critical spins (Sec. 4.2, 4.3)
# --------------------------------------------------------------------------------------------


def _mga_over_c(top: TopParams) -> float:
    """``M g a / C`` (1/s^2)."""
    return top.M_kg * top.g_mps2 * top.a_m / top.C_kgm2


def n1(top: TopParams) -> float | None:
    """Spin above which the vertical state at ``theta = 0`` is unstable (zeroStability4).

    ``n1 = sqrt(M g a / (C (A/C - (1 - a/R)))) (1 - a/R)``.

    Args:
        top: The top.

    Returns:
        ``n1`` (rad/s) for Groups II and III, ``None`` for Group I (stable for every spin).
    """
    if group(top) == "I":
        return None
    e, r = top.a_over_R, top.A_over_C
    return math.sqrt(_mga_over_c(top) / (r - (1.0 - e))) * (1.0 - e)


def n2(top: TopParams) -> float:
    """Spin below which no real precession exists at ``theta = pi`` (StabilityOmegaPi).

    Args:
        top: The top.

    Returns:
        ``n2 = 2 sqrt(A M g a) / C`` (rad/s); always defined (0 when ``a = 0``).
    """
    return 2.0 * math.sqrt(top.A_kgm2 * top.M_kg * top.g_mps2 * top.a_m) / top.C_kgm2


def n3(top: TopParams) -> float | None:
    """Spin ``|n(theta = pi)|`` above which the inverted state is stable (piStability4).

    ``n3 = sqrt(M g a / (C ((1 + a/R) - A/C))) (1 + a/R)``.

    Args:
        top: The top.

    Returns:
        ``n3`` (rad/s) where ``A/C < 1 + a/R`` (Groups I and II), ``None`` for Group III (the
        inverted state is unstable for every spin).
    """
    if group(top) == "III":
        return None
    e, r = top.a_over_R, top.A_over_C
    return math.sqrt(_mga_over_c(top) / ((1.0 + e) - r)) * (1.0 + e)


def n4(top: TopParams) -> float | None:
    """Spin at ``theta = 0`` that leaves ``|n(pi)| = n3`` after inversion (n4, critical1).

    Jellett's constant gives ``n(pi) = -(R - a)/(R + a) n(0)``, so ``n4 = n3 (1 + a/R)/(1 - a/R)``.

    Args:
        top: The top.

    Returns:
        ``n4`` (rad/s) where ``A/C < 1 + a/R`` (Groups I and II), else ``None``.
    """
    v = n3(top)
    if v is None:
        return None
    e = top.a_over_R
    return v * (1.0 + e) / (1.0 - e)


def r_c(top: TopParams) -> float:
    """The ratio ``A/C`` at which ``F(-1) = F(1)`` (rc); depends on ``a/R`` only.

    ``r_c = 1 - (a/R) ((1 + a/R)^4 - (1 - a/R)^4) / ((1 + a/R)^4 + (1 - a/R)^4)``.

    Args:
        top: The top (only ``a/R`` is used).

    Returns:
        ``r_c``, always defined, in ``(1 - a/R, 1]``.
    """
    e = top.a_over_R
    p, m = (1.0 + e) ** 4, (1.0 - e) ** 4
    return 1.0 - e * (p - m) / (p + m)


def n_c(top: TopParams) -> float | None:
    """Critical spin for full inversion of a Group II top (Sec. 4.3).

    ``n_c = n4`` for ``r_c < A/C < 1 + a/R`` and ``n1`` for ``1 - a/R < A/C <= r_c`` (at
    ``A/C = r_c`` the two coincide).

    Args:
        top: The top.

    Returns:
        ``n_c`` (rad/s) for Group II, otherwise ``None``.
    """
    if group(top) != "II":
        return None
    return n4(top) if top.A_over_C > r_c(top) else n1(top)


# --------------------------------------------------------------------------------------------
# The steady-state equation F(x) = kappa (Sec. 4.2.3)
# --------------------------------------------------------------------------------------------


def f1(top: TopParams, x: ArrayLike) -> float | NDArray[np.float64]:
    """``f1(x) = (A/C - 1) x + a/R`` (f1).

    Args:
        top: The top.
        x: ``cos(theta)``, scalar or array.

    Returns:
        ``f1`` with the shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    return _out((top.A_over_C - 1.0) * x + top.a_over_R)


def _sqrt_f2(top: TopParams, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sqrt(f2(x)) = (x - a/R)^2 + (A/C)(1 - x^2)``, positive for ``|x| <= 1``."""
    return (x - top.a_over_R) ** 2 + top.A_over_C * (1.0 - x * x)


def f2(top: TopParams, x: ArrayLike) -> float | NDArray[np.float64]:
    """``f2(x) = ((x - a/R)^2 + (A/C)(1 - x^2))^2`` (f2).

    Args:
        top: The top.
        x: ``cos(theta)``, scalar or array.

    Returns:
        ``f2`` with the shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    return _out(_sqrt_f2(top, x) ** 2)


def F(top: TopParams, x: ArrayLike) -> float | NDArray[np.float64]:
    """``F(x) = f2(x) / f1(x)`` (EqForIntermediate2).

    The intermediate steady states solve ``F(x) = kappa`` (EqForIntermediate3).

    Args:
        top: The top.
        x: ``cos(theta)``, scalar or array.

    Returns:
        ``F`` with the shape of ``x`` (``inf``/``nan`` where ``f1 = 0``, following numpy).
    """
    x = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(np.asarray(f2(top, x)) / np.asarray(f1(top, x)))


def kappa(top: TopParams, J: ArrayLike) -> float | NDArray[np.float64]:
    """The dimensionless Jellett constant ``kappa = J^2 / (M g a C R^2)`` (EqForIntermediate).

    Args:
        top: The top.
        J: Jellett's constant (kg m^3/s), scalar or array.

    Returns:
        ``kappa`` with the shape of ``J``; ``inf`` when ``a = 0`` (``nan`` if also ``J = 0``).
    """
    J = np.asarray(J, dtype=float)
    den = top.M_kg * top.g_mps2 * top.a_m * top.C_kgm2 * top.R_m**2
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(J * J / den)


def jellett_from_spin(
    top: TopParams, n0: ArrayLike, theta0: ArrayLike = 0.0, Omega0: ArrayLike = 0.0
) -> float | NDArray[np.float64]:
    """Jellett's constant from a spin state (JellettConstant3).

    ``J = C n (R cos theta - a) + A Omega R sin^2 theta``.

    Args:
        top: The top.
        n0: Spin about the symmetry axis (rad/s).
        theta0: Tilt from the vertical (rad).
        Omega0: Precession rate (rad/s).

    Returns:
        ``J`` (kg m^3/s), broadcast over the arguments.
    """
    n0, theta0, Omega0 = (np.asarray(v, dtype=float) for v in (n0, theta0, Omega0))
    J = top.C_kgm2 * n0 * (top.R_m * np.cos(theta0) - top.a_m) + (
        top.A_kgm2 * Omega0 * top.R_m * np.sin(theta0) ** 2
    )
    return _out(J)


def D(top: TopParams, x: ArrayLike) -> float | NDArray[np.float64]:
    """The stability function ``D(x) = 4 f1(x)^2 + (A/C - 1) sqrt(f2(x))`` (Dxs, Appendix B).

    ``F'(x) = -sqrt(f2) D / f1^2`` (Appendix B), so ``D > 0`` where ``F`` decreases. An
    intermediate state at ``x_s`` is stable when ``D(x_s) > 0``.

    Args:
        top: The top.
        x: ``cos(theta)``, scalar or array.

    Returns:
        ``D`` with the shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    fx = np.asarray(f1(top, x))
    return _out(4.0 * fx * fx + (top.A_over_C - 1.0) * _sqrt_f2(top, x))


def _x_d(top: TopParams) -> float | None:
    """``cos(theta_d)`` for Group II tops with ``r_c < A/C < 1`` and ``F'(1) > 0``, else None."""
    if group(top) != "II":
        return None
    r = top.A_over_C
    if not (r_c(top) < r < 1.0):
        return None
    # F is convex (DerivDerivG). F'(1) > 0 <=> D(1) < 0: only then has F a minimum inside (-1, 1),
    # and with F(-1) > F(1) a second solution of F(x) = F(1).
    if float(D(top, 1.0)) >= 0.0 or float(D(top, -1.0)) <= 0.0:
        return None
    x_min = _root(lambda x: float(D(top, x)), -1.0, 1.0)
    F1 = float(F(top, 1.0))
    lo_val = _g(top, -1.0, F1)
    if lo_val <= 0.0:  # F(-1) <= F(1) up to rounding
        return None
    return _root(lambda x: _g(top, x, F1), -1.0, x_min)


def theta_d(top: TopParams) -> float | None:
    """The jump angle ``theta_d`` of a Group II top with ``r_c < A/C < 1`` (Sec. 4.2.3, 4.4).

    ``theta_d`` in ``(0, pi)`` solves ``F(cos theta_d) = F(1)`` with ``cos theta_d != 1``. It
    exists only when ``F`` has its minimum inside ``(-1, 1)``, i.e. ``F'(1) > 0``; a top with
    ``r_c < A/C < 1`` but ``F'(1) <= 0`` (e.g. Fig. 9 (b), ``A/C = 0.95, a/R = 0.15``) has a
    monotone ``F`` and no ``theta_d``: its ``theta_s`` rises continuously from 0.

    Args:
        top: The top.

    Returns:
        ``theta_d`` (rad), or ``None`` when it does not exist.
    """
    x = _x_d(top)
    return None if x is None else float(np.arccos(x))


def _asymptote(top: TopParams, n0: float) -> tuple[str, float]:
    """Classify the end state from ``theta ~ 0`` with spin ``n0``.

    Returns:
        ``("zero", 1.0)``, ``("pi", -1.0)`` or ``("intermediate", x_s)``.
    """
    n0 = abs(float(n0))
    grp = group(top)
    if grp == "I":
        return "zero", 1.0
    v1 = n1(top)
    assert v1 is not None
    if n0 <= v1:
        return "zero", 1.0
    if top.a_m == 0.0:  # Group III with a = 0: n1 = 0, kappa infinite, x_s -> x_f = 0.
        return "intermediate", 0.0
    J = float(jellett_from_spin(top, n0))
    kap = float(kappa(top, J))
    if _g(top, 1.0, kap) >= 0.0:  # kappa <= F(1) up to rounding: still stable at theta = 0
        return "zero", 1.0
    if grp == "III":
        x_f = _cos_crossing(top)
        assert x_f is not None
        # g(x_f) = f2(x_f) > 0 because f1(x_f) = 0; g(1) < 0. F diverges at x_f, g does not.
        return "intermediate", _root(lambda x: _g(top, x, kap), x_f, 1.0)
    # Group II: f1 > 0 on [-1, 1].
    if top.A_over_C < r_c(top) or _g(top, -1.0, kap) <= 0.0:  # no state, or kappa >= F(-1)
        return "pi", -1.0
    x_d = _x_d(top)
    hi = 1.0 if x_d is None else x_d
    return "intermediate", _root(lambda x: _g(top, x, kap), -1.0, hi)


def theta_s(top: TopParams, n0: float) -> float:
    """Predicted asymptotic angle for a start near ``theta = 0`` with spin ``n0`` (Sec. 4.2-4.4).

    ``J = C n0 (R - a)``. The answer is 0 for Group I or ``|n0| <= n1``. For Group II it is ``pi``
    if ``kappa >= F(-1)`` (``n0 >= n4``) or if ``A/C < r_c`` (then ``n_c = n1``); otherwise it is
    ``arccos(x_s)`` with ``x_s`` the root of ``F(x) = kappa`` reached from ``theta = 0``: the
    unique root in ``(-1, 1)`` for ``A/C >= 1``, the root in ``(-1, x_d)`` for ``r_c < A/C < 1``
    (so ``theta_s > theta_d``). For Group III ``x_s`` is the unique root in ``(x_f, 1)``, so
    ``0 < theta_s < theta_f``. The spin's sign does not matter (mirror image): ``|n0|`` is used.

    Args:
        top: The top.
        n0: Initial spin at ``theta ~ 0`` (rad/s).

    Returns:
        ``theta_s`` (rad) in ``[0, pi]``.
    """
    kind, x = _asymptote(top, n0)
    if kind == "zero":
        return 0.0
    if kind == "pi":
        return math.pi
    return float(np.arccos(np.clip(x, -1.0, 1.0)))


def theta_s_curve(top: TopParams, n0_values: ArrayLike) -> NDArray[np.float64]:
    """:func:`theta_s` for each spin in ``n0_values``.

    Args:
        top: The top.
        n0_values: Initial spins (rad/s), any shape.

    Returns:
        ``theta_s`` (rad) with the shape of ``n0_values``.
    """
    n0 = np.asarray(n0_values, dtype=float)
    return np.array([theta_s(top, v) for v in n0.ravel()], dtype=float).reshape(n0.shape)


# --------------------------------------------------------------------------------------------
# Stability signs (Sec. 4.2)
# --------------------------------------------------------------------------------------------


def H_sign_zero(top: TopParams, n: float) -> int:
    """Sign of ``H`` for the vertical state at ``theta = 0`` with spin ``n`` (zeroStability2).

    Stable (``H < 0``) iff ``n^2 (A/C - (1 - a/R)) < (M g a / C)(1 - a/R)^2``.

    Args:
        top: The top.
        n: Spin at ``theta = 0`` (rad/s).

    Returns:
        ``+1`` unstable, ``-1`` stable, ``0`` on the border (the two sides equal to a relative
        1e-12, e.g. ``n = n1``).
    """
    e, r = top.a_over_R, top.A_over_C
    lhs = n * n * (r - (1.0 - e))
    rhs = _mga_over_c(top) * (1.0 - e) ** 2
    return _sign(lhs - rhs, max(abs(lhs), abs(rhs)))


def H_sign_pi(top: TopParams, n_pi: float) -> int:
    """Sign of ``H`` for the inverted state at ``theta = pi`` with spin ``n_pi`` (piStability2).

    Stable (``H < 0``) iff ``n^2 ((1 + a/R) - A/C) > (M g a / C)(1 + a/R)^2``, with ``n = |n_pi|``
    (after an inversion from ``theta = 0`` the spin is negative).

    Args:
        top: The top.
        n_pi: Spin at ``theta = pi`` (rad/s), either sign.

    Returns:
        ``+1`` unstable, ``-1`` stable, ``0`` on the border (e.g. ``|n_pi| = n3``).
    """
    e, r = top.a_over_R, top.A_over_C
    n = abs(n_pi)
    lhs = n * n * ((1.0 + e) - r)
    rhs = _mga_over_c(top) * (1.0 + e) ** 2
    return _sign(rhs - lhs, max(abs(lhs), abs(rhs)))


def D_sign_at_theta_s(top: TopParams, n0: float) -> int | None:
    """Sign of ``D(x_s)`` at the intermediate state reached with spin ``n0`` (Appendix B).

    ``D(x_s) > 0`` means the intermediate state is stable.

    Args:
        top: The top.
        n0: Initial spin at ``theta ~ 0`` (rad/s).

    Returns:
        ``+1``, ``-1`` or ``0``, or ``None`` when the top ends at 0 or ``pi`` (no intermediate
        state).
    """
    kind, x = _asymptote(top, n0)
    if kind != "intermediate":
        return None
    val = float(D(top, x))
    scale = 4.0 * float(f1(top, x)) ** 2 + abs(top.A_over_C - 1.0) * float(_sqrt_f2(top, x))
    return _sign(val, scale)


# --------------------------------------------------------------------------------------------
# xi curves (Sec. 3.3) and the reduced energy (Appendix C)
# --------------------------------------------------------------------------------------------


def _xi_pair(
    top: TopParams, theta: ArrayLike, J: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Both roots of ``V(xi, theta, J) = 0`` (xiSolution), each in a cancellation-free form."""
    theta = np.asarray(theta, dtype=float)
    J = np.asarray(J, dtype=float)
    R, a = top.R_m, top.a_m
    amg = top.A_kgm2 * top.M_kg * top.g_mps2
    c = R * np.cos(theta) - a
    h = R - a * np.cos(theta)
    disc = J * J + 4.0 * amg * c * h * a
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
        # q = J + sign(J) sqrt(disc) never cancels; the roots are q/(2c) and -2 A M g a h / q.
        s = np.where(J < 0.0, -1.0, 1.0)
        q = J + s * sq
        big = np.where(c != 0.0, q / (2.0 * c), np.nan)
        small = np.where(q != 0.0, -2.0 * amg * a * h / q, np.nan)
        plus = np.where(J < 0.0, small, big)
        minus = np.where(J < 0.0, big, small)
    return plus, minus


def xi_plus(top: TopParams, theta: ArrayLike, J: ArrayLike) -> float | NDArray[np.float64]:
    """``xi_+ = (J + sqrt(D)) / (2 (R cos theta - a))`` (xiSolution, ``N = M g``).

    ``D = J^2 + 4 A M g (R cos theta - a) h a`` with ``h = R - a cos theta``. For ``J < 0`` the
    same value is evaluated as ``-2 A M g a h / (J - sqrt(D))`` to avoid cancellation.

    Args:
        top: The top.
        theta: Tilt (rad), scalar or array.
        J: Jellett's constant (kg m^3/s), scalar or an array broadcastable with ``theta``.

    Returns:
        ``xi_+`` (kg m^2/s); NaN where ``D < 0`` or where the formula divides by zero
        (``R cos theta = a`` for ``J >= 0``).
    """
    return _out(_xi_pair(top, theta, J)[0])


def xi_minus(top: TopParams, theta: ArrayLike, J: ArrayLike) -> float | NDArray[np.float64]:
    """``xi_- = (J - sqrt(D)) / (2 (R cos theta - a))`` (xiSolution), cancellation-free.

    Evaluated as ``-2 A M g a h / (J + sqrt(D))`` (``J >= 0``; for ``J < 0`` the direct form has
    no cancellation and is used). Approaches ``-A M g a R / J`` for small ``a`` (xiSolutionMinus).

    Args:
        top: The top.
        theta: Tilt (rad), scalar or array.
        J: Jellett's constant (kg m^3/s), scalar or an array broadcastable with ``theta``.

    Returns:
        ``xi_-`` (kg m^2/s); NaN where ``D < 0`` or where the formula divides by zero.
    """
    return _out(_xi_pair(top, theta, J)[1])


def E1(top: TopParams, theta: ArrayLike, J: ArrayLike) -> float | NDArray[np.float64]:
    """The reduced energy ``E^(1)`` of Ebenfeld & Scheck as written in Appendix C.

    ``E1 = J^2 / (2 A R^2 G(eta)) + M g R (1 - (a/R) eta)``, with
    ``G = 1 - eta^2 + (C/A)(eta - a/R)^2`` and ``eta = cos theta``. Its stationary points in
    ``theta`` are the steady states; a minimum is stable.

    Args:
        top: The top.
        theta: Tilt (rad), scalar or array.
        J: Jellett's constant (kg m^3/s), scalar or an array broadcastable with ``theta``.

    Returns:
        ``E^(1)`` (J) with the broadcast shape.
    """
    eta = np.cos(np.asarray(theta, dtype=float))
    J = np.asarray(J, dtype=float)
    e = top.a_over_R
    G = 1.0 - eta * eta + (eta - e) ** 2 / top.A_over_C
    kinetic = J * J / (2.0 * top.A_kgm2 * top.R_m**2 * G)
    return _out(kinetic + top.M_kg * top.g_mps2 * top.R_m * (1.0 - e * eta))


# --------------------------------------------------------------------------------------------
# Summary
# --------------------------------------------------------------------------------------------


def summary(top: TopParams, n0: float | None = None) -> dict[str, str | float | None]:
    """All the paper's characteristic numbers for ``top`` in one JSON-ready dict.

    Args:
        top: The top.
        n0: If given, also ``theta_s`` for a start near ``theta = 0`` with this spin (rad/s).

    Returns:
        Keys ``group, n1, n2, n3, n4, nc, rc, theta_c, theta_f, theta_d`` (and ``theta_s`` only
        when ``n0`` is given); values are floats, ``None`` where a quantity does not exist, and a
        string for ``group``.
    """
    out: dict[str, str | float | None] = {
        "group": group(top),
        "n1": n1(top),
        "n2": n2(top),
        "n3": n3(top),
        "n4": n4(top),
        "nc": n_c(top),
        "rc": r_c(top),
        "theta_c": theta_c(top),
        "theta_f": theta_f(top),
        "theta_d": theta_d(top),
    }
    if n0 is not None:
        out["theta_s"] = theta_s(top, n0)
    return out
