"""The measured group diagram: n1, n4 and the group at every (A/C, a/R) point, per run."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

#: An atlas point's keys, in order (the atlas.csv columns).
POINT_COLUMNS = ("A_over_C", "a_over_R", "engine", "mode", "run", "group_theory",
                 "group_measured", "n1_theory", "n1_measured", "n4_theory", "n4_measured",
                 "agrees", "n_runs", "settled")


@dataclass(frozen=True)
class AtlasPoint:
    """One grid point measured on one run (engine and mode), against the theory.

    Attributes:
        A_over_C: The point's A/C.
        a_over_R: The point's a/R.
        engine: The engine measured on.
        mode: The mode measured in.
        run: ``ENGINE/MODE``.
        group_theory: The theory's group (``I``, ``II``, ``III``).
        group_measured: The group the measured thresholds imply.
        n1_theory: The theory's n1 (rad/s), or None.
        n1_measured: The measured n1 (rad/s), or None (none found).
        n4_theory: The theory's n4 (rad/s), or None.
        n4_measured: The measured n4 (rad/s), or None (none found).
        agrees: The measured group is the theory's.
        n_runs: Growth-rate runs made at the point.
        settled: Every fit near a measured threshold is clean.
    """

    A_over_C: float
    a_over_R: float
    engine: str
    mode: str | None
    run: str
    group_theory: str
    group_measured: str
    n1_theory: float | None
    n1_measured: float | None
    n4_theory: float | None
    n4_measured: float | None
    agrees: bool
    n_runs: int
    settled: bool

    def to_json(self) -> dict[str, Any]:
        """The point's record: its fields in order (the atlas.csv columns)."""
        return {k: getattr(self, k) for k in POINT_COLUMNS}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> AtlasPoint:
        """A point read back from its record."""
        return cls(**{k: data[k] for k in POINT_COLUMNS})


@dataclass(frozen=True)
class AtlasResult:
    """n1, n4 and the group at every grid point on every run, and where the runs depart.

    Attributes:
        points: One per grid point and run.
        agreement: Run (``ENGINE/MODE``) -> fraction of its points whose group matches.
        findings: Sentences: where a run moves a threshold or a group boundary, with numbers.
        A_over_C: The grid's A/C values.
        a_over_R: The grid's a/R values.
        runs: The runs measured (``ENGINE/MODE``), in order.
        scan_spins: The spins scanned where the theory has no value to start from (rad/s).
    """

    points: tuple[AtlasPoint, ...]
    agreement: dict[str, float]
    findings: tuple[str, ...]
    A_over_C: tuple[float, ...]
    a_over_R: tuple[float, ...]
    runs: tuple[str, ...]
    scan_spins: tuple[float, ...]

    @property
    def n_runs(self) -> int:
        """Growth-rate runs made over every point."""
        return sum(p.n_runs for p in self.points)

    def to_json(self) -> dict[str, Any]:
        """``{points, agreement, findings, grid, runs, scan_spins, n_runs}``: atlas.json."""
        return {"points": [p.to_json() for p in self.points], "agreement": dict(self.agreement),
                "findings": list(self.findings),
                "grid": {"A_over_C": list(self.A_over_C), "a_over_R": list(self.a_over_R)},
                "runs": list(self.runs), "scan_spins": list(self.scan_spins),
                "n_runs": self.n_runs}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> AtlasResult:
        """An atlas read back from its JSON (``n_runs`` follows the points)."""
        return cls(tuple(AtlasPoint.from_json(p) for p in data["points"]),
                   dict(data["agreement"]), tuple(data["findings"]),
                   tuple(data["grid"]["A_over_C"]), tuple(data["grid"]["a_over_R"]),
                   tuple(data["runs"]), tuple(data["scan_spins"]))


__all__ = ["POINT_COLUMNS", "AtlasPoint", "AtlasResult"]
