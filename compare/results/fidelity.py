"""A fidelity map's result: a row per point of the grid, and what ran."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class FidelityPoint:
    """One point of the map: its top, whether MuJoCo's tuned native contact agrees, and why not.

    Attributes:
        A_over_C: The top's A/C.
        a_over_R: The top's a/R.
        mu: The friction coefficient.
        group: The paper's group (``I``, ``II``, ``III``; None: a top the scene refuses).
        n0: The fit's start spin (rad/s; None: not started).
        theta0: The fit's start tilt (rad; None: not started).
        agrees: Every check passed from every start.
        settings: The tuned settings verified (None: not tuned).
        residual: The fit's residual (None: not tuned).
        passes: Checks passed (None: not tuned).
        checks: Checks judged (None: not tuned).
        departs: A line per check that departed.
        runs: The fit's rollouts (None: not tuned).
        chosen: How the answer was found (``fit``, a seed, the widening's step).
        widened: Each setting the widening verified, with its checks (None: no widening).
        error: Why the tuning stopped (None: it did not).
        cached: The tuning came from the cache.
        cause: Why the point does not agree (None where it agrees).
        wall_s: The point's wall time (s).
    """

    A_over_C: float
    a_over_R: float
    mu: float
    group: str | None
    n0: float | None
    theta0: float | None
    agrees: bool
    settings: dict[str, Any] | None
    residual: float | None
    passes: int | None
    checks: int | None
    departs: tuple[Any, ...]
    runs: int | None
    chosen: str | None
    widened: tuple[Any, ...] | None
    error: str | None
    cached: bool
    cause: str | None
    wall_s: float

    def to_json(self) -> dict[str, Any]:
        """The point's row, as ``tippetop fidelity --json`` prints it."""
        return {"A_over_C": self.A_over_C, "a_over_R": self.a_over_R, "mu": self.mu,
                "group": self.group, "n0": self.n0, "theta0": self.theta0,
                "agrees": self.agrees, "settings": self.settings, "residual": self.residual,
                "passes": self.passes, "checks": self.checks, "departs": list(self.departs),
                "runs": self.runs, "chosen": self.chosen,
                "widened": None if self.widened is None else list(self.widened),
                "error": self.error, "cached": self.cached, "cause": self.cause,
                "wall_s": self.wall_s}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> FidelityPoint:
        """A point read back from its row (a row without a key has its value None)."""
        widened = data.get("widened")
        return cls(data["A_over_C"], data["a_over_R"], data["mu"], data.get("group"),
                   data.get("n0"), data.get("theta0"), data.get("agrees"),
                   data.get("settings"), data.get("residual"), data.get("passes"),
                   data.get("checks"), tuple(data.get("departs") or ()), data.get("runs"),
                   data.get("chosen"), None if widened is None else tuple(widened),
                   data.get("error"), data.get("cached"), data.get("cause"),
                   data.get("wall_s"))


@dataclass(frozen=True)
class MapGrid:
    """The grid a map covered.

    Attributes:
        name: The grid's name (``default``, ``small``, ``custom``).
        points: How many points it has.
        A_over_C: Its A/C values (None: a grid given by its points only).
        a_over_R: Its a/R values (None: likewise).
        mu: Its friction coefficients (None: likewise).
    """

    name: str
    points: int
    A_over_C: tuple[float, ...] | None = None
    a_over_R: tuple[float, ...] | None = None
    mu: tuple[float, ...] | None = None

    def to_json(self) -> dict[str, Any]:
        """``{name, A_over_C, a_over_R, mu, points}`` (the lists where known)."""
        lists = {k: list(v) for k, v in (("A_over_C", self.A_over_C),
                                         ("a_over_R", self.a_over_R), ("mu", self.mu))
                 if v is not None}
        return {"name": self.name, **lists, "points": self.points}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> MapGrid:
        """A grid read back from its JSON."""
        def values(key: str) -> tuple[float, ...] | None:
            return None if data.get(key) is None else tuple(data[key])

        return cls(data["name"], data["points"], values("A_over_C"), values("a_over_R"),
                   values("mu"))


@dataclass(frozen=True)
class MapStart:
    """How every point of a map starts.

    Attributes:
        n0: The spin (rad/s), raised to ``above_threshold`` x the top's highest threshold
            where that is higher.
        theta0: The tilt (rad).
        above_threshold: The factor over the top's highest threshold.
    """

    n0: float
    theta0: float
    above_threshold: float

    def to_json(self) -> dict[str, Any]:
        """``{n0, theta0, above_threshold}``."""
        return {"n0": self.n0, "theta0": self.theta0, "above_threshold": self.above_threshold}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> MapStart:
        """A start rule read back from its JSON."""
        return cls(data["n0"], data["theta0"], data["above_threshold"])


@dataclass(frozen=True)
class FidelityResult:
    """The fidelity map: a row per point, the grid, and what ran.

    Attributes:
        format: The JSON's format name (``tippetop-fidelity/1``).
        points: A row per point, in the grid's order.
        grid: The grid.
        engine: The engine tuned (``mujoco``).
        mujoco_version: The MuJoCo that ran.
        mode: The mode tuned (``native``).
        t_end_s: The verification runs' horizon (s).
        start: How every point starts.
        budget_runs: MuJoCo runs a point's tuning may use (None: the tuning's own).
        wall_s: The map's wall time (s).
        points_at_once: Points tuned at once (1: in this process; None: on Dask).
        scheduler: The Dask scheduler's address (None: this machine).
    """

    format: str
    points: tuple[FidelityPoint, ...]
    grid: MapGrid
    engine: str
    mujoco_version: str | None
    mode: str | None
    t_end_s: float
    start: MapStart
    budget_runs: int | None
    wall_s: float
    points_at_once: int | None
    scheduler: str | None

    @property
    def agree(self) -> int:
        """How many points agree."""
        return sum(bool(p.agrees) for p in self.points)

    @property
    def runs(self) -> int:
        """The fit rollouts of every point."""
        return sum(p.runs or 0 for p in self.points)

    @property
    def cached(self) -> int:
        """How many points' tunings came from the cache."""
        return sum(bool(p.cached) for p in self.points)

    def to_json(self) -> dict[str, Any]:
        """What ``tippetop fidelity --json`` prints and results.json holds."""
        return {
            "format": self.format,
            "points": [p.to_json() for p in self.points],
            "grid": self.grid.to_json(),
            "agreement": {"agree": self.agree, "points": len(self.points)},
            "engine": self.engine, "mujoco_version": self.mujoco_version,
            "mode": self.mode,
            "t_end_s": self.t_end_s,
            "start": self.start.to_json(),
            "budget_runs": self.budget_runs,
            "runs": self.runs,
            "wall_s": self.wall_s,
            "points_at_once": self.points_at_once,
            "scheduler": self.scheduler,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> FidelityResult:
        """A map read back from its JSON (``agreement`` and ``runs`` recounted from the points)."""
        return cls(data["format"], tuple(FidelityPoint.from_json(p) for p in data["points"]),
                   MapGrid.from_json(data["grid"]), data["engine"],
                   data.get("mujoco_version"), data.get("mode"), data["t_end_s"],
                   MapStart.from_json(data["start"]), data.get("budget_runs"),
                   data.get("wall_s"), data.get("points_at_once"), data.get("scheduler"))


__all__ = ["FidelityPoint", "FidelityResult", "MapGrid", "MapStart"]
