"""The accuracy study's result: the files each engine wrote, its Pareto entries and counts."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class AccuracyReference:
    """The reference a scene's points are scored against.

    Attributes:
        method: The ODE method of the reference.
        rtol: Its relative tolerance.
        atol: Its absolute tolerance.
        floor: A bound on its own theta error (rad).
        wall_s: Its wall time (s).
        n_rhs: Its right-hand side evaluations.
    """

    method: str
    rtol: float
    atol: float
    floor: float
    wall_s: float
    n_rhs: int

    def to_json(self) -> dict[str, Any]:
        """``{method, rtol, atol, floor, wall_s, n_rhs}``."""
        return {"method": self.method, "rtol": self.rtol, "atol": self.atol,
                "floor": self.floor, "wall_s": self.wall_s, "n_rhs": self.n_rhs}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> AccuracyReference:
        """A reference read back from its JSON."""
        return cls(data["method"], data["rtol"], data["atol"], data["floor"], data["wall_s"],
                   data["n_rhs"])


@dataclass(frozen=True)
class ParetoEntry:
    """For a scene, an engine and a threshold: the cheapest point whose theta error meets it.

    Attributes:
        engine: ``ode``, ``stiff`` or ``mujoco``.
        scene: The scene's name.
        threshold: The bound on max |theta error| (rad).
        method: The method (None: no point meets it).
        setting: ``rtol ...`` or ``dt = ... s in MODE mode`` (None: likewise).
        rtol: The ODE's tolerance (None: MuJoCo, or none met).
        timestep_s: MuJoCo's timestep (s; None: the ODE, or none met).
        wall_s: The point's wall time (s).
        wall_per_sim_s: Its wall time per simulated second.
        n_rhs_per_sim_s: Its right-hand side evaluations per simulated second.
        n_steps_per_sim_s: Its steps per simulated second.
        theta_max_err: Its max |theta error| (rad).
        text: The sentence: "to get theta right to X rad, use ...".
        best_theta_max_err: The smallest error of any completed point (None: none completed).
        best_method: That point's method.
        best_setting: That point's setting.
    """

    engine: str
    scene: str
    threshold: float
    method: str | None
    setting: str | None
    rtol: float | None
    timestep_s: float | None
    wall_s: float | None
    wall_per_sim_s: float | None
    n_rhs_per_sim_s: float | None
    n_steps_per_sim_s: float | None
    theta_max_err: float | None
    text: str
    best_theta_max_err: float | None
    best_method: str | None
    best_setting: str | None

    def to_json(self) -> dict[str, Any]:
        """The entry as :func:`~tippetop.compare.studies.accuracy.pareto.pareto_table` makes it."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ParetoEntry:
        """An entry read back from its JSON."""
        return cls(**{f.name: data.get(f.name) for f in fields(cls)})


@dataclass(frozen=True)
class EngineOutput:
    """What one engine of the study wrote, and its points by outcome.

    Attributes:
        csv: Its CSV of every point.
        figures: Its figures, one per scene.
        pareto_md: Its Pareto table (Markdown).
        n_points: Its points.
        n_ok: Those that completed.
        n_skipped: Those over the wall-time budget.
        n_diverged: Those that diverged (MuJoCo).
        n_failed: The others.
    """

    csv: str
    figures: tuple[str, ...]
    pareto_md: str
    n_points: int
    n_ok: int
    n_skipped: int
    n_diverged: int
    n_failed: int

    def to_json(self) -> dict[str, Any]:
        """``{csv, figures, pareto_md, n_points, n_ok, n_skipped, n_diverged, n_failed}``."""
        return {"csv": self.csv, "figures": list(self.figures), "pareto_md": self.pareto_md,
                "n_points": self.n_points, "n_ok": self.n_ok, "n_skipped": self.n_skipped,
                "n_diverged": self.n_diverged, "n_failed": self.n_failed}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> EngineOutput:
        """An engine's output read back from its JSON."""
        return cls(data["csv"], tuple(data["figures"]), data["pareto_md"], data["n_points"],
                   data["n_ok"], data["n_skipped"], data["n_diverged"], data["n_failed"])


@dataclass(frozen=True)
class AccuracyResult:
    """The work-precision study (``tippetop bench accuracy``): its files, entries and counts.

    Attributes:
        csv: The first engine's CSV (the ODE's when it ran).
        figures: Every engine's figures.
        pareto_md: The first engine's Pareto table.
        references: The reference of each scene (the stiff case's too).
        pareto: The Pareto entries of every engine.
        n_points: Points of every engine.
        n_ok: Those that completed.
        n_skipped: Those over the wall-time budget.
        n_failed: The others (diverged MuJoCo points among them).
        engines: Each engine's output (``ode``, ``stiff``, ``mujoco``), in the order run.
        report: The printable report: a line per file written and per Pareto entry.
    """

    csv: str
    figures: tuple[str, ...]
    pareto_md: str
    references: dict[str, AccuracyReference]
    pareto: tuple[ParetoEntry, ...]
    n_points: int
    n_ok: int
    n_skipped: int
    n_failed: int
    engines: dict[str, EngineOutput]
    report: str

    def to_json(self) -> dict[str, Any]:
        """The study's JSON, ``report`` included (``bench accuracy --json`` leaves it out)."""
        return {
            "csv": self.csv, "figures": list(self.figures), "pareto_md": self.pareto_md,
            "references": {k: r.to_json() for k, r in self.references.items()},
            "pareto": [e.to_json() for e in self.pareto],
            "n_points": self.n_points, "n_ok": self.n_ok, "n_skipped": self.n_skipped,
            "n_failed": self.n_failed,
            "engines": {k: e.to_json() for k, e in self.engines.items()},
            "report": self.report,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> AccuracyResult:
        """A study read back from its JSON (``report`` empty where the JSON has none)."""
        return cls(data["csv"], tuple(data["figures"]), data["pareto_md"],
                   {k: AccuracyReference.from_json(r) for k, r in data["references"].items()},
                   tuple(ParetoEntry.from_json(e) for e in data["pareto"]),
                   data["n_points"], data["n_ok"], data["n_skipped"], data["n_failed"],
                   {k: EngineOutput.from_json(e) for k, e in data["engines"].items()},
                   data.get("report", ""))


__all__ = ["AccuracyReference", "AccuracyResult", "EngineOutput", "ParetoEntry"]
