"""A measured critical spin (n1, n4 or n_c) against the theory's, by growth rates or bisection."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class HorizonCheck:
    """A bisection's final bracket run again over twice the scene's horizon.

    Attributes:
        horizon_s: The longer horizon (s).
        low_crossed: Whether the bracket's low end crossed over it (None: not recorded).
        high_crossed: Whether the bracket's high end crossed over it (None: not recorded).
        depends_on_horizon: Either end changed side: the answer is the run length's.
    """

    horizon_s: float
    low_crossed: bool | None
    high_crossed: bool | None
    depends_on_horizon: bool

    def to_json(self) -> dict[str, Any]:
        """``{horizon_s, low_crossed, high_crossed, depends_on_horizon}``."""
        return {"horizon_s": self.horizon_s, "low_crossed": self.low_crossed,
                "high_crossed": self.high_crossed, "depends_on_horizon": self.depends_on_horizon}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> HorizonCheck:
        """A horizon check read back from its JSON."""
        return cls(data["horizon_s"], data.get("low_crossed"), data.get("high_crossed"),
                   data["depends_on_horizon"])


@dataclass(frozen=True)
class FailedRun:
    """A run that failed and stopped the measurement.

    Attributes:
        n0: Its spin (rad/s).
        message: What failed, in a sentence.
        state: ``upright`` or ``inverted`` (growth rates), or None (bisection).
    """

    n0: float
    message: str
    state: str | None = None

    def to_json(self) -> dict[str, Any]:
        """``{n0, state, message}`` (growth) or ``{n0, message}`` (bisection)."""
        return {"n0": self.n0, **({} if self.state is None else {"state": self.state}),
                "message": self.message}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> FailedRun:
        """A failed run read back from its JSON."""
        return cls(data["n0"], data["message"], data.get("state"))


@dataclass(frozen=True)
class ThresholdResult:
    """A critical spin measured on an engine in a mode, against the theory's.

    Attributes:
        which: ``n1``, ``n4`` or ``nc``.
        engine: The engine it was measured on.
        mode: The mode (how the contact force is made).
        scene: The scene's name.
        method: ``growth`` (the zero of a steady state's growth rate) or ``bisect``.
        measured: The measured spin (rad/s; None if none was found or a run failed).
        theory: The theory's value (rad/s; None where the theory has none).
        rel_diff: measured / theory - 1, or None.
        bracket: The final bracket (low, high) in rad/s; empty after a failed run.
        runs: Each run's record as in the JSON: growth ``{n0, state, rate_per_s, crossed,
            clean, residual, modes}``; bisect ``{n0, crossed, theta_asymp, t_end_s, settled,
            status}``; a failed run with ``failed`` (its message).
        horizon_s: The length of each run (s): growth's run length or the scene's horizon.
        converged: The answer is to be trusted (see each method).
        settled: Growth: every fit near a root is clean; bisect: no run still moving and the
            answer does not depend on the horizon.
        warning: Why the answer is not to be trusted, or None.
        failed_runs: The runs that failed and stopped the measurement (empty: none did).
        n1: Growth: the upright state's measured spin, or None.
        n3: Growth: the inverted state's measured spin, or None.
        n4: Growth: n3 carried to theta = 0 by Jellett's constant, or None.
        bracket_converged: Bisect: the bracket is within rel_tol (None after a failed run).
        horizon_check: Bisect: the final bracket over twice the horizon, or None.
        depends_on_horizon: Bisect: the horizon check moved the answer (None after a failed
            run).
        unsettled_n0: Bisect: the spins whose runs were still moving at their end.
    """

    which: str
    engine: str
    mode: str | None
    scene: str
    method: str
    measured: float | None
    theory: float | None
    rel_diff: float | None
    bracket: tuple[float, ...]
    runs: tuple[dict[str, Any], ...]
    horizon_s: float
    converged: bool
    settled: bool
    warning: str | None = None
    failed_runs: tuple[FailedRun, ...] = ()
    n1: float | None = None
    n3: float | None = None
    n4: float | None = None
    bracket_converged: bool | None = None
    horizon_check: HorizonCheck | None = None
    depends_on_horizon: bool | None = None
    unsettled_n0: tuple[float, ...] = ()

    @property
    def n_runs(self) -> int:
        """The runs made (each in :attr:`runs`)."""
        return len(self.runs)

    @property
    def rates(self) -> list[dict[str, Any]]:
        """Growth: each run's ``{n0, state, rate_per_s}``; bisect: none."""
        if self.method != "growth":
            return []
        return [{"n0": r["n0"], "state": r["state"], "rate_per_s": r["rate_per_s"]}
                for r in self.runs]

    def to_json(self) -> dict[str, Any]:
        """What ``tippetop threshold --json`` prints, in each method's key order."""
        return self._growth_json() if self.method == "growth" else self._bisect_json()

    def _growth_json(self) -> dict[str, Any]:
        out = {"which": self.which, "engine": self.engine, "mode": self.mode,
               "scene": self.scene, "method": self.method, "measured": self.measured,
               "theory": self.theory, "rel_diff": self.rel_diff, "bracket": list(self.bracket),
               "runs": [dict(r) for r in self.runs], "rates": self.rates,
               "n_runs": self.n_runs, "horizon_s": self.horizon_s, "settled": self.settled,
               "converged": self.converged, "n1": self.n1, "n3": self.n3, "n4": self.n4}
        if self.failed_runs:
            out["failed_runs"] = [f.to_json() for f in self.failed_runs]
        if self.warning is not None:
            out["warning"] = self.warning
        return out

    def _bisect_json(self) -> dict[str, Any]:
        head = {"which": self.which, "engine": self.engine}
        tail = {"measured": self.measured, "theory": self.theory, "rel_diff": self.rel_diff,
                "bracket": list(self.bracket), "runs": [dict(r) for r in self.runs],
                "n_runs": self.n_runs, "horizon_s": self.horizon_s}
        if self.failed_runs:  # stopped by a failed run: no bracket, no horizon check
            return {**head, "mode": self.mode, "scene": self.scene, **tail,
                    "converged": self.converged, "method": self.method, "rates": self.rates,
                    "settled": self.settled, "unsettled_n0": list(self.unsettled_n0),
                    "failed_runs": [f.to_json() for f in self.failed_runs],
                    "warning": self.warning}
        check = self.horizon_check.to_json() if self.horizon_check is not None else None
        return {**head, "scene": self.scene, **tail,
                "bracket_converged": self.bracket_converged, "horizon_check": check,
                "depends_on_horizon": self.depends_on_horizon, "warning": self.warning,
                "converged": self.converged, "method": self.method, "rates": self.rates,
                "settled": self.settled, "unsettled_n0": list(self.unsettled_n0),
                "mode": self.mode}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ThresholdResult:
        """A threshold read back from its JSON (``n_runs`` and ``rates`` follow ``runs``).

        The keys one method or an older result lacks take their defaults (``method``:
        ``bisect``, the only one once).
        """
        check = data.get("horizon_check")
        return cls(
            which=data["which"], engine=data["engine"], mode=data.get("mode"),
            scene=data["scene"], method=data.get("method", "bisect"),
            measured=data["measured"], theory=data["theory"], rel_diff=data["rel_diff"],
            bracket=tuple(data["bracket"]), runs=tuple(dict(r) for r in data["runs"]),
            horizon_s=data["horizon_s"], converged=data["converged"],
            settled=data.get("settled", False), warning=data.get("warning"),
            failed_runs=tuple(FailedRun.from_json(f) for f in data.get("failed_runs") or ()),
            n1=data.get("n1"), n3=data.get("n3"), n4=data.get("n4"),
            bracket_converged=data.get("bracket_converged"),
            horizon_check=HorizonCheck.from_json(check) if check is not None else None,
            depends_on_horizon=data.get("depends_on_horizon"),
            unsettled_n0=tuple(data.get("unsettled_n0") or ()))


__all__ = ["FailedRun", "HorizonCheck", "ThresholdResult"]
