"""A sweep's result: a row per run and n0, and the theory's theta_s(n0)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.measures import theory
from tippetop.models.params import TopParams


@dataclass(frozen=True)
class SweepResult:
    """A sweep: a row per run and n0, the theory's curve, and what the cache served.

    Attributes:
        table: A row per run: ``engine``, ``mode``, ``run`` (``ENGINE/MODE``), ``n0``,
            ``theta_asymp``, ``outcome``, ``t_invert``, ``J_rel_drift``, ``status``,
            ``cached``.
        theory: theta_s(n0) on 400 points over the swept range (``n0``, ``theta_s``).
        top: The top swept.
        scene: The scene's name.
        computed: Runs computed.
        cached: Runs served by the cache.
    """

    table: pd.DataFrame
    theory: pd.DataFrame
    top: TopParams
    scene: str
    computed: int
    cached: int

    def failed(self) -> pd.DataFrame:
        """The rows of runs that failed."""
        return self.table[self.table["outcome"] == "failed"] if len(self.table) else self.table

    def to_json(self) -> dict[str, Any]:
        """``{scene, computed, cached, rows}``: what ``tippetop sweep --json`` prints."""
        return {"scene": self.scene, "computed": self.computed, "cached": self.cached,
                "rows": self.table.to_dict(orient="records")}

    @classmethod
    def from_json(cls, data: dict[str, Any], top: TopParams) -> SweepResult:
        """A sweep read back from its JSON, with its top (the theory's curve recomputed)."""
        table = pd.DataFrame(data["rows"])
        return cls(table, theory_curve(top, list(table["n0"]) if len(table) else [0.0]), top,
                   data["scene"], int(data["computed"]), int(data["cached"]))


def theory_curve(top: TopParams, n0_values: list[float]) -> pd.DataFrame:
    """theta_s(n0) on 400 points from the smallest to the largest n0."""
    grid = np.linspace(min(n0_values), max(n0_values), 400)
    return pd.DataFrame({"n0": grid, "theta_s": theory.theta_s_curve(top, grid)})


__all__ = ["SweepResult", "theory_curve"]
