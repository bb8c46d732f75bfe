"""A validation's result: one MJCF top against the theory and the reference, and what to paste.

What :func:`tippetop.compare.studies.validate.validate` returns. Its JSON
(:meth:`ValidateResult.to_json`) is what ``tippetop validate --json`` prints and
``results.json`` holds; the runs' tables are not in it (the command writes them as CSV).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

from tippetop.compare.results.lift import LiftResult
from tippetop.compare.results.tune import Tuned, tuned_from_json


@dataclass(frozen=True)
class ValidateModel:
    """The top as read from the file, its start, and the theory's numbers for it.

    Attributes:
        file: The MJCF file.
        R_m: The ball's radius (m).
        a_m: The centre of mass below the ball's centre (m).
        A: The transverse moment of inertia (kg m^2).
        C: The axial moment of inertia (kg m^2).
        M_kg: The mass (kg).
        A_over_C: A/C.
        a_over_R: a/R.
        mu: The ball's friction on the table (None: the file gives none).
        group: The paper's group (``I``, ``II``, ``III``).
        n1: The theory's n1 (rad/s), None where the group has none.
        n4: The theory's n4 (rad/s), None where the group has none.
        nc: The theory's critical spin (rad/s), None where the group has none.
        theta_s: The theory's asymptotic tilt for this spin (rad), None where there is none.
        theory_outcome: The theory's outcome for this start.
        n0: The start's spin (rad/s).
        theta0: The start's tilt (rad).
        keyframe: The file's keyframe started from (None: the scene's state).
        stem: The stem as read (``{kind, offset_m, radius_m}``), None without one.
        stem_note: What the loader found of a stem, in words.
        timestep_s: The file's timestep (s), None if it gives none.
    """

    file: str
    R_m: float
    a_m: float
    A: float
    C: float
    M_kg: float
    A_over_C: float
    a_over_R: float
    mu: float | None
    group: str
    n1: float | None
    n4: float | None
    nc: float | None
    theta_s: float | None
    theory_outcome: str
    n0: float
    theta0: float
    keyframe: str | None
    stem: dict[str, Any] | None
    stem_note: str | None
    timestep_s: float | None

    #: The JSON's keys, in order (the fields' names).
    KEYS: ClassVar[tuple[str, ...]] = (
        "file", "R_m", "a_m", "A", "C", "M_kg", "A_over_C", "a_over_R", "mu", "group", "n1",
        "n4", "nc", "theta_s", "theory_outcome", "n0", "theta0", "keyframe", "stem",
        "stem_note", "timestep_s")

    def to_json(self) -> dict[str, Any]:
        """``{file, R_m, a_m, A, C, M_kg, A_over_C, a_over_R, mu, group, n1, n4, nc, ...}``."""
        return {k: getattr(self, k) for k in self.KEYS}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ValidateModel:
        """The model read back from :meth:`to_json`."""
        return cls(**{k: data[k] for k in cls.KEYS})


@dataclass(frozen=True)
class SettingChange:
    """A setting the calibrated run changes from the file's, as both ran."""

    setting: str
    file: Any
    calibrated: Any

    def to_json(self) -> dict[str, Any]:
        """``{setting, file, calibrated}``."""
        return {"setting": self.setting, "file": self.file, "calibrated": self.calibrated}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> SettingChange:
        """A change read back from :meth:`to_json`."""
        return cls(data["setting"], data["file"], data["calibrated"])


@dataclass(frozen=True)
class Suggestion:
    """The calibrated native settings as they ran, as MJCF to paste, and whether they agree.

    Attributes:
        option: The ``<option>`` element to paste.
        geom: The geoms' contact attributes to paste.
        where: Which geoms take them.
        changes: Where they differ from the file's own settings.
        agrees: Every check of the calibrated run passed.
        departs: The checks it fails.
        note: One sentence: a fix, or why the calibration does not fix it.
    """

    option: str
    geom: str
    where: str
    changes: tuple[SettingChange, ...]
    agrees: bool
    departs: tuple[str, ...]
    note: str

    def to_json(self) -> dict[str, Any]:
        """``{option, geom, where, changes, agrees, departs, note}``."""
        return {"option": self.option, "geom": self.geom, "where": self.where,
                "changes": [c.to_json() for c in self.changes], "agrees": self.agrees,
                "departs": list(self.departs), "note": self.note}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Suggestion:
        """A suggestion read back from :meth:`to_json`."""
        return cls(data["option"], data["geom"], data["where"],
                   tuple(SettingChange.from_json(c) for c in data["changes"]), data["agrees"],
                   tuple(data["departs"]), data["note"])


@dataclass(frozen=True)
class ValidateCandidate:
    """A set of contact settings validate tried for the file.

    Attributes:
        name: ``tuned``, ``seed`` or ``calibrated``.
        what: What they are, in words.
        agrees: They pass every check they were run through.
        passes: The checks that pass.
        checks: The checks run.
        mjcf: The settings as MJCF to paste.
        departs: The checks that do not pass.
        changes: The settings they change from the file's (the calibrated ones only; else
            None).
        note: Why the calibration does not carry over (the calibrated ones, where they
            depart; else None).
    """

    name: str
    what: str
    agrees: bool
    passes: int
    checks: int
    mjcf: str
    departs: tuple[str, ...]
    changes: tuple[SettingChange, ...] | None = None
    note: str | None = None

    def to_json(self) -> dict[str, Any]:
        """``{name, what, agrees, passes, checks, mjcf, departs}``, then ``changes``, ``note``.

        ``changes`` and ``note`` only where they are said (not None).
        """
        out: dict[str, Any] = {"name": self.name, "what": self.what, "agrees": self.agrees,
                               "passes": self.passes, "checks": self.checks,
                               "mjcf": self.mjcf, "departs": list(self.departs)}
        if self.changes is not None:
            out["changes"] = [c.to_json() for c in self.changes]
        if self.note is not None:
            out["note"] = self.note
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ValidateCandidate:
        """A candidate read back from :meth:`to_json`."""
        changes = data.get("changes")
        return cls(data["name"], data["what"], data["agrees"], data["passes"], data["checks"],
                   data["mjcf"], tuple(data["departs"]),
                   None if changes is None else tuple(SettingChange.from_json(c)
                                                      for c in changes),
                   data.get("note"))


@dataclass(frozen=True)
class FileChecks:
    """The file's own runs' checks: all pass (``agrees``), how many pass, of how many."""

    agrees: bool
    passes: int
    checks: int

    def to_json(self) -> dict[str, Any]:
        """``{agrees, passes, checks}``."""
        return {"agrees": self.agrees, "passes": self.passes, "checks": self.checks}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> FileChecks:
        """The checks read back from :meth:`to_json`."""
        return cls(data["agrees"], data["passes"], data["checks"])


@dataclass(frozen=True)
class ValidateAnswer:
    """The one answer to paste: the file's own settings, the best candidate, or none and why.

    Attributes:
        candidates: Every set of settings tried, best evidence first.
        file: The file's own runs' checks.
        agrees: What to paste follows the reference (also when nothing needs pasting).
        source: ``file`` (the file as it is), the chosen candidate's ``name``, or None.
        mjcf: The MJCF to paste, None when nothing is.
        why: None, or why nothing agreeing is pasted.
        label: One line: what it is and whether it agrees.
    """

    candidates: tuple[ValidateCandidate, ...]
    file: FileChecks
    agrees: bool
    source: str | None
    mjcf: str | None
    why: str | None
    label: str

    def to_json(self) -> dict[str, Any]:
        """``{candidates, file, agrees, source, mjcf, why, label}``."""
        return {"candidates": [c.to_json() for c in self.candidates],
                "file": self.file.to_json(), "agrees": self.agrees, "source": self.source,
                "mjcf": self.mjcf, "why": self.why, "label": self.label}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ValidateAnswer:
        """The answer read back from :meth:`to_json`."""
        return cls(tuple(ValidateCandidate.from_json(c) for c in data["candidates"]),
                   FileChecks.from_json(data["file"]), data["agrees"], data["source"],
                   data["mjcf"], data["why"], data["label"])


@dataclass(frozen=True)
class ValidateResult:
    """A validation: the file's top, its runs, the verdict, the tuning and what to paste.

    Attributes:
        model: The top as read from the file, and the theory's numbers.
        t_end_s: Simulated time of every run (s).
        engines: The engines the MuJoCo runs ran on.
        runs: Each run (``ENGINE/MODE``) -> its entry (:func:`run_entry`: the summary's keys,
            ``outcome``, ``end_state``, ``ran``, ``error``, ``note``, ``friction_realised``
            with its ``refit``).
        verdict: The checks (:func:`verdict`'s dictionaries).
        agrees: No check departs.
        findings: What the file's own settings get wrong, with numbers.
        suggestion: The calibrated settings as they ran (None: that run failed before it
            ran).
        tuned: The file's contact settings tuned, or why not.
        answer: The one MJCF block to paste, or none and why.
        lift: The contacts' lift against the reference's slip.
        tables: Each run's observables (not in the JSON: the command writes them).
    """

    FORMAT: ClassVar[str] = "tippetop-validate/1"

    model: ValidateModel
    t_end_s: float
    engines: tuple[str, ...]
    runs: dict[str, dict[str, Any]]
    verdict: tuple[dict[str, Any], ...]
    agrees: bool
    findings: tuple[str, ...]
    suggestion: Suggestion | None
    tuned: Tuned
    answer: ValidateAnswer
    lift: LiftResult
    tables: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    def to_json(self) -> dict[str, Any]:
        """What ``tippetop validate --json`` prints and ``results.json`` holds (no tables)."""
        return {"format": self.FORMAT, "model": self.model.to_json(), "t_end_s": self.t_end_s,
                "engines": list(self.engines), "runs": dict(self.runs),
                "verdict": list(self.verdict), "agrees": self.agrees,
                "findings": list(self.findings),
                "suggestion": {} if self.suggestion is None else self.suggestion.to_json(),
                "tuned": self.tuned.to_json(), "answer": self.answer.to_json(),
                "lift": self.lift.to_json()}

    @classmethod
    def from_json(cls, data: dict[str, Any],
                  tables: dict[str, Any] | None = None) -> ValidateResult:
        """A validation read back from its JSON, with its tables if the caller has them."""
        if data.get("format") != cls.FORMAT:
            raise ValueError(f"expected a {cls.FORMAT} result, got format "
                             f"{data.get('format')!r}")
        sug = data.get("suggestion")
        return cls(ValidateModel.from_json(data["model"]), data["t_end_s"],
                   tuple(data["engines"]), dict(data["runs"]), tuple(data["verdict"]),
                   data["agrees"], tuple(data["findings"]),
                   Suggestion.from_json(sug) if sug else None, tuned_from_json(data["tuned"]),
                   ValidateAnswer.from_json(data["answer"]), LiftResult.from_json(data["lift"]),
                   dict(tables or {}))


__all__ = ["FileChecks", "SettingChange", "Suggestion", "ValidateAnswer", "ValidateCandidate",
           "ValidateModel", "ValidateResult"]
