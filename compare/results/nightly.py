"""A nightly's result: what ``results.json`` holds (format ``tippetop-nightly-results/1``).

The cases' records, the videos, the environment, the calibrations, the tolerances, the counts
and the history's answer stay the dictionaries ``results.json`` holds (the report and the
history read them as such); the lists are tuples here and lists again in :meth:`to_json`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class NightlyResult:
    """One nightly run, start to verdict.

    Attributes:
        format: ``tippetop-nightly-results/1``.
        profile: The catalogue's profile that ran.
        profile_description: What the catalogue says of it.
        catalogue: The catalogue file.
        engines: ``--engines`` as given.
        case_patterns: ``--cases`` as given (empty: every case of the profile).
        models: ``--models``, as absolute paths.
        model_changed: Model case id -> how its file changed since its baseline (said, not
            compared).
        command: The command line (``tippetop nightly ...``).
        started: When it started.
        baseline_file: The baseline files in one line, or why there is none.
        baseline_files: Each engine's baseline file.
        not_run: The cases that cannot run on an engine asked for, said.
        no_baseline: ``--no-baseline``.
        baseline_update: ``--update-baseline``'s counts, else None.
        videos: The videos rendered (``requested``, ``status``, ``files`` ...).
        environment: The machine, the packages and the calibration this run used.
        calibration: ``this_run`` and each native case's ``baselines`` calibration.
        tolerances: Each metric's tolerance (``kind``, ``value``, ``floor``, ``unit``,
            ``text``, ``why``).
        cases: A record per case (its checks, values, status ...).
        crossval: A verdict row per run case, in catalogue order.
        counts: Case and check counts by status.
        verdict: ``OK``, ``REGRESSION``, ``ERROR`` ... (with why, when the report or the videos
            failed).
        finished: When it finished.
        wall_s: Its wall time (s).
        history: What the history append said (``file``, ``run``, ``error``, ``trends``),
            else None: not appended (``--no-history``; no ``history`` key).
        report_error: Why the report failed, else None (no ``report_error`` key).
    """

    format: str
    profile: str
    profile_description: str
    catalogue: str
    engines: tuple[str, ...]
    case_patterns: tuple[str, ...]
    models: tuple[str, ...]
    model_changed: dict[str, Any]
    command: tuple[str, ...]
    started: str
    baseline_file: str
    baseline_files: dict[str, str]
    not_run: tuple[str, ...]
    no_baseline: bool
    baseline_update: dict[str, int] | None
    videos: dict[str, Any]
    environment: dict[str, Any]
    calibration: dict[str, Any]
    tolerances: dict[str, dict[str, Any]]
    cases: tuple[dict[str, Any], ...]
    crossval: tuple[dict[str, Any], ...]
    counts: dict[str, int]
    verdict: str
    finished: str
    wall_s: float
    history: dict[str, Any] | None = None
    report_error: str | None = None

    @property
    def videos_failed(self) -> bool:
        """Some video was not rendered."""
        return bool(self.videos.get("failed"))

    def to_json(self) -> dict[str, Any]:
        """What ``results.json`` holds, key for key in its order.

        ``history`` and ``report_error`` only when there are.
        """
        out: dict[str, Any] = {
            "format": self.format,
            "profile": self.profile,
            "profile_description": self.profile_description,
            "catalogue": self.catalogue,
            "engines": list(self.engines),
            "case_patterns": list(self.case_patterns),
            "models": list(self.models),
            "model_changed": self.model_changed,
            "command": list(self.command),
            "started": self.started,
            "baseline_file": self.baseline_file,
            "baseline_files": self.baseline_files,
            "not_run": list(self.not_run),
            "no_baseline": self.no_baseline,
            "baseline_update": self.baseline_update,
            "videos": self.videos,
            "environment": self.environment,
            "calibration": self.calibration,
            "tolerances": self.tolerances,
            "cases": list(self.cases),
            "crossval": list(self.crossval),
            "counts": self.counts,
            "verdict": self.verdict,
            "finished": self.finished,
            "wall_s": self.wall_s,
        }
        if self.history is not None:
            out["history"] = self.history
        if self.report_error is not None:
            out["report_error"] = self.report_error
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> NightlyResult:
        """A nightly's result read back from its ``results.json``."""
        return cls(
            format=data["format"], profile=data["profile"],
            profile_description=data["profile_description"], catalogue=data["catalogue"],
            engines=tuple(data["engines"]), case_patterns=tuple(data["case_patterns"]),
            models=tuple(data["models"]), model_changed=data["model_changed"],
            command=tuple(data["command"]), started=data["started"],
            baseline_file=data["baseline_file"], baseline_files=data["baseline_files"],
            not_run=tuple(data["not_run"]), no_baseline=data["no_baseline"],
            baseline_update=data["baseline_update"], videos=data["videos"],
            environment=data["environment"], calibration=data["calibration"],
            tolerances=data["tolerances"], cases=tuple(data["cases"]),
            crossval=tuple(data["crossval"]), counts=data["counts"], verdict=data["verdict"],
            finished=data["finished"], wall_s=data["wall_s"], history=data.get("history"),
            report_error=data.get("report_error"))


__all__ = ["NightlyResult"]
