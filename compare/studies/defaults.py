"""Defaults that a command's parser shows and its work uses: importing this costs nothing."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

#: ``tippetop atlas``: the grid, A/C and a/R as ``LO:HI:N``, and the engines and modes measured
#: (every pairing of the two that can run).
DEFAULT_A_OVER_C = "0.8:1.4:4"
DEFAULT_A_OVER_R = "0.05:0.25:3"
DEFAULT_ENGINES_TEXT = "ode,mujoco"
DEFAULT_MODES_TEXT = "paper,native"

#: ``tippetop validate``: simulated seconds of every run unless --t-end-s says otherwise.
DEFAULT_T_END_S = 8.0

#: ``tippetop fidelity``: its grids (:mod:`tippetop.compare.studies.fidelity`).
@dataclass(frozen=True)
class Grid:
    """The points of a fidelity map: every A/C x a/R x mu.

    Attributes:
        name: The grid's name (``default``, ``small``, or ``custom`` for a given one).
        A_over_C: The tops' A/C values.
        a_over_R: The tops' a/R values, each in (0, 1).
        mu: The friction coefficients.
    """

    name: str
    A_over_C: tuple[float, ...]
    a_over_R: tuple[float, ...]
    mu: tuple[float, ...]

    def points(self) -> list[tuple[float, float, float]]:
        """(A/C, a/R, mu) of every point, mu slowest (one figure panel per mu)."""
        return [(r, e, m) for m in self.mu for e in self.a_over_R for r in self.A_over_C]

    def to_json(self) -> dict[str, Any]:
        """``{name, A_over_C, a_over_R, mu, points}``."""
        return {"name": self.name, "A_over_C": list(self.A_over_C),
                "a_over_R": list(self.a_over_R), "mu": list(self.mu),
                "points": len(self.points())}


#: The named grids. ``default``: A/C 0.8, 1, 1.3 at a/R 0.1 (Groups I, II, III) and 0.25 (II,
#: II, III), at mu 0.1 (the paper's), 0.3 and 1; ``small``: 2 x 2 x 2, every group at mu 0.1
#: and 1.
GRIDS: dict[str, Grid] = {
    "default": Grid("default", (0.8, 1.0, 1.3), (0.1, 0.25), (0.1, 0.3, 1.0)),
    "small": Grid("small", (0.8, 1.3), (0.1, 0.25), (0.1, 1.0)),
}
DEFAULT_GRID = "default"
