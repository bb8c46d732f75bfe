"""A cross-validation: one scene on engines and modes, against the theory and the reference."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Prediction:
    """The theory's prediction for the scene's top from its Jellett constant at t = 0.

    Attributes:
        theta_s: The steady tilt theta_s (rad; NaN where no run gave a Jellett constant).
        outcome: The predicted final state, or None (every run failed).
        theta_s_tol: How far theta_asymp may be from theta_s and agree (rad).
        theta_s_tol_why: Why the tolerance is what it is.
    """

    theta_s: float | None
    outcome: str | None
    theta_s_tol: float | None
    theta_s_tol_why: str | None

    def to_json(self) -> dict[str, Any]:
        """``{theta_s, outcome, theta_s_tol, theta_s_tol_why}``."""
        return {"theta_s": self.theta_s, "outcome": self.outcome,
                "theta_s_tol": self.theta_s_tol, "theta_s_tol_why": self.theta_s_tol_why}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Prediction:
        """A prediction read back from its JSON (a missing key reads as None)."""
        return cls(data.get("theta_s"), data.get("outcome"), data.get("theta_s_tol"),
                   data.get("theta_s_tol_why"))


@dataclass(frozen=True)
class CompareResult:
    """One scene run on every engine and mode asked for and on the reference, compared.

    Attributes:
        scene: The scene's name.
        group: The top's group (``I``, ``II``, ``III``).
        theory: The theory's prediction (None: not known, in a partial result).
        reference: The reference run (``ENGINE/MODE``).
        runs: One per run asked for, the reference first if asked: the simulate summary with
            ``engine``, ``mode``, ``run`` (``ENGINE/MODE``), ``outcome``, ``agrees``,
            ``against``, ``reasons``, ``matches_theory``, ``d_theta_asymp``,
            ``theta_trend_rad_s``, ``theta_rms_vs_ref``, ``reference``, ...
        crossval: One :func:`~tippetop.compare.measures.verdict.crossval_row` per run.
        differences: Each metric where a run departs from the reference beyond its tolerance
            (``engine, mode, run, metric, value, reference, tolerance`` and ``why`` or
            ``note``).
        tolerances: Metric -> its tolerance.
    """

    scene: str | None
    group: str | None
    theory: Prediction | None
    reference: str | None
    runs: tuple[dict[str, Any], ...]
    crossval: tuple[dict[str, Any], ...]
    differences: tuple[dict[str, Any], ...]
    tolerances: dict[str, float]

    def failed(self) -> list[str]:
        """The runs (``ENGINE/MODE``) that failed."""
        return [s["run"] for s in self.runs if s.get("outcome") == "failed"]

    def to_json(self) -> dict[str, Any]:
        """What ``tippetop compare --json`` prints."""
        return {"scene": self.scene, "group": self.group,
                "theory": self.theory.to_json() if self.theory is not None else None,
                "reference": self.reference, "runs": [dict(s) for s in self.runs],
                "crossval": [dict(r) for r in self.crossval],
                "differences": [dict(d) for d in self.differences],
                "tolerances": dict(self.tolerances)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> CompareResult:
        """A comparison read back from its JSON.

        A missing key (a partial result) reads as None or empty.
        """
        th = data.get("theory")
        return cls(data.get("scene"), data.get("group"),
                   Prediction.from_json(th) if th is not None else None, data.get("reference"),
                   tuple(dict(s) for s in data.get("runs") or ()),
                   tuple(dict(r) for r in data.get("crossval") or ()),
                   tuple(dict(d) for d in data.get("differences") or ()),
                   dict(data.get("tolerances") or {}))


__all__ = ["CompareResult", "Prediction"]
