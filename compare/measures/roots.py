"""Brent's method, step for step as scipy's ``brentq``, for the theory's bracketed roots."""

from __future__ import annotations

import math
from collections.abc import Callable

#: Absolute ``xtol`` (in ``x = cos theta``) for every root found with :func:`brentq`.
ROOT_XTOL = 1e-14
#: Relative tolerance: 4 machine epsilons, scipy's smallest allowed rtol.
ROOT_RTOL = 4 * 2.220446049250313e-16
#: Most iterations.
ROOT_MAXITER = 200


def brentq(func: Callable[[float], float], xa: float, xb: float, *, xtol: float = ROOT_XTOL,
           rtol: float = ROOT_RTOL, maxiter: int = ROOT_MAXITER) -> float:
    """A root of ``func`` in ``[xa, xb]`` by Brent's method, step for step as scipy's ``brentq``.

    The same iteration as scipy's C ``brentq`` (Charles Harris's variant: inverse quadratic
    extrapolation, bisection when a step is not short enough), so it returns the same float as
    ``scipy.optimize.brentq(func, xa, xb, xtol=xtol, rtol=rtol, maxiter=maxiter)`` (a test
    checks it bit for bit) without importing scipy: ``tippetop theory`` starts in a third of
    the time. Written here because the theory's roots are all of this one bracketed kind.

    Args:
        func: A continuous function with ``func(xa)`` and ``func(xb)`` of opposite signs.
        xa: One end of the bracket.
        xb: The other end.
        xtol: Absolute tolerance on the root.
        rtol: Relative tolerance on the root.
        maxiter: Most iterations.

    Returns:
        The root.

    Raises:
        ValueError: ``func`` has the same sign at both ends, or no convergence in ``maxiter``.
    """
    xpre, xcur = float(xa), float(xb)
    xblk = fblk = spre = scur = 0.0
    fpre, fcur = float(func(xpre)), float(func(xcur))
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    if math.copysign(1.0, fpre) == math.copysign(1.0, fcur):
        raise ValueError("brentq: f(a) and f(b) must have different signs")
    for _ in range(maxiter):
        if fpre != 0.0 and fcur != 0.0 and math.copysign(1.0, fpre) != math.copysign(1.0, fcur):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (xtol + rtol * abs(xcur)) / 2.0
        sbis = (xblk - xcur) / 2.0
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:  # interpolate
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:  # extrapolate
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):  # good short step
                spre, scur = scur, stry
            else:  # bisect
                spre = scur = sbis
        else:  # bisect
            spre = scur = sbis
        xpre, fpre = xcur, fcur
        xcur += scur if abs(scur) > delta else (delta if sbis > 0 else -delta)
        fcur = float(func(xcur))
    raise ValueError(f"brentq: no convergence in {maxiter} iterations (last x = {xcur!r})")


__all__ = ["ROOT_MAXITER", "ROOT_RTOL", "ROOT_XTOL", "brentq"]
