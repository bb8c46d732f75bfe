"""A tuning's result: the file's contact settings fitted, verified from every start, judged.

What :func:`tippetop.compare.tuning.tune.tune` returns (validate's ``tuned``, ``tippetop
calibrate --mjcf``'s, a fidelity point's): the settings as the verification ran them, the MJCF
to paste, the fit's record and each start's verification. Its JSON (:meth:`TuneResult.to_json`)
is what ``--json`` prints and the tuning cache keeps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from tippetop.models.numbers import number_text


def start_label(n0: float, theta0: float) -> str:
    """A start as every line and report names it: ``n0 = 150 rad/s, theta0 = 0.04 rad``."""
    return f"n0 = {number_text(n0, 'rad/s')}, theta0 = {number_text(theta0, 'rad')}"


@dataclass(frozen=True)
class TunedSettings:
    """The tuned contact settings as the verification run ran them (read back).

    Attributes:
        mu: Friction coefficient.
        cone: ``pyramidal`` or ``elliptic``.
        impratio: MuJoCo's impratio.
        solref: MuJoCo's solref (two numbers).
        solimp: MuJoCo's solimp (five numbers).
        timestep_s: The step (s).
        integrator: The integrator.
        condim: The contact's dimension.
        solreffriction: The contact pairs' friction rows' own solref (the lift-free family),
            else None.
    """

    mu: float
    cone: str
    impratio: float
    solref: tuple[float, ...]
    solimp: tuple[float, ...]
    timestep_s: float
    integrator: str
    condim: int
    solreffriction: tuple[float, ...] | None = None

    def to_json(self) -> dict[str, Any]:
        """The settings by their MJCF names (solref, solimp, solreffriction as lists)."""
        return {"mu": self.mu, "cone": self.cone, "impratio": self.impratio,
                "solref": list(self.solref), "solimp": list(self.solimp),
                "timestep_s": self.timestep_s, "integrator": self.integrator,
                "condim": self.condim,
                "solreffriction": (None if self.solreffriction is None
                                   else list(self.solreffriction))}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TunedSettings:
        """Settings read back from :meth:`to_json`."""
        srf = data.get("solreffriction")
        return cls(data["mu"], data["cone"], data["impratio"], tuple(data["solref"]),
                   tuple(data["solimp"]), data["timestep_s"], data["integrator"],
                   data["condim"], None if srf is None else tuple(srf))


@dataclass(frozen=True)
class FittedStart:
    """The start the fit followed: spin n0 (rad/s), tilt theta0 (rad), horizon (s)."""

    n0: float
    theta0: float
    t_end_s: float

    def to_json(self) -> dict[str, Any]:
        """``{n0, theta0, t_end_s}``."""
        return {"n0": self.n0, "theta0": self.theta0, "t_end_s": self.t_end_s}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> FittedStart:
        """A start read back from :meth:`to_json`."""
        return cls(data["n0"], data["theta0"], data["t_end_s"])


@dataclass(frozen=True)
class TuneNeed:
    """An integrator and step tried with the fitted contact: kept, or why not.

    Attributes:
        integrator: The integrator.
        timestep_s: The step (s).
        rms_rad: Its rollout's residual at the file's start (rad), None if not rolled out.
        kept: Its verification passed from every start.
        why: Why it was not kept ("" where nothing is to say).
    """

    integrator: str
    timestep_s: float
    rms_rad: float | None
    kept: bool
    why: str

    def to_json(self) -> dict[str, Any]:
        """``{integrator, timestep_s, rms_rad, kept, why}``."""
        return {"integrator": self.integrator, "timestep_s": self.timestep_s,
                "rms_rad": self.rms_rad, "kept": self.kept, "why": self.why}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TuneNeed:
        """A need read back from :meth:`to_json`."""
        return cls(data["integrator"], data["timestep_s"], data["rms_rad"], data["kept"],
                   data["why"])


@dataclass(frozen=True)
class TuneAlternative:
    """Settings the tuning verified besides its answer: another fit, a seed, a widening.

    Attributes:
        settings: The settings in one line.
        what: What they are (another family's fit, the widening's step); None for a seed.
        agrees: They pass from every start.
        departs: Each check that departs (``CHECK from START (ROLE): NOTE``).
        passes: Checks that pass over every start.
        checks: Checks over every start.
        mjcf: The settings as MJCF to paste.
        calibrated: They are the calibrated settings.
    """

    settings: str
    what: str | None
    agrees: bool
    departs: tuple[str, ...]
    passes: int
    checks: int
    mjcf: str
    calibrated: bool

    def to_json(self) -> dict[str, Any]:
        """``{settings, what, agrees, departs, passes, checks, mjcf, calibrated}``.

        ``what`` is absent for a seed.
        """
        head: dict[str, Any] = {"settings": self.settings}
        if self.what is not None:
            head["what"] = self.what
        return {**head, "agrees": self.agrees, "departs": list(self.departs),
                "passes": self.passes, "checks": self.checks, "mjcf": self.mjcf,
                "calibrated": self.calibrated}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TuneAlternative:
        """An alternative read back from :meth:`to_json`."""
        return cls(data["settings"], data.get("what"), data["agrees"],
                   tuple(data["departs"]), data["passes"], data["checks"], data["mjcf"],
                   data["calibrated"])


@dataclass(frozen=True)
class TuneFit:
    """The fit's record: where and how it fitted, what it tried, what it spent.

    Attributes:
        starts: The start fitted (one: the file's own).
        residual: The fit's residual (rad; ``residual_definition``).
        residual_definition: What ``residual`` measures, in words.
        runs: MuJoCo runs spent (rollouts and verification runs).
        rollouts: The fits' rollouts.
        verify_runs: The verifications' runs.
        budget_runs: The runs it could spend (``--budget-runs``).
        seeds: Each seed scored: ``{cone, settings, rms_rad}``.
        fits: Each fit run: ``{cone, from, from_rms_rad, to, rms_rad, rollouts,
            iterations, ...}``.
        cones: Each family's best cone, in the order fitted.
        tried: What each family fitted was, in words.
        timestep_s: The fit's step (s).
        integrator: The fit's integrator.
        needs: The file's own integrators and steps tried with the fitted contact.
        chosen: Which settings are the answer: ``fit``, ``seed: ...`` or ``widened: ...``.
        alternatives: The settings verified besides the answer.
        bounds: Each fitted setting's bounds: name -> [low, high].
        method: How it fitted, in words.
        widened: The widening's rows (``{settings, what, agrees, passes, checks}``), or None
            if it did not run.
        wall_s: Wall-clock time of the tuning (s).
    """

    starts: tuple[FittedStart, ...]
    residual: float
    residual_definition: str
    runs: int
    rollouts: int
    verify_runs: int
    budget_runs: int
    seeds: tuple[dict[str, Any], ...]
    fits: tuple[dict[str, Any], ...]
    cones: tuple[str, ...]
    tried: tuple[str, ...]
    timestep_s: float
    integrator: str
    needs: tuple[TuneNeed, ...]
    chosen: str
    alternatives: tuple[TuneAlternative, ...]
    bounds: dict[str, tuple[float, ...]]
    method: str
    widened: tuple[dict[str, Any], ...] | None
    wall_s: float

    def to_json(self) -> dict[str, Any]:
        """The fit's keys, in the order :meth:`TuneResult.to_json` has always given them."""
        return {"starts": [s.to_json() for s in self.starts], "residual": self.residual,
                "residual_definition": self.residual_definition, "runs": self.runs,
                "rollouts": self.rollouts, "verify_runs": self.verify_runs,
                "budget_runs": self.budget_runs, "seeds": list(self.seeds),
                "fits": list(self.fits), "cones": list(self.cones), "tried": list(self.tried),
                "timestep_s": self.timestep_s, "integrator": self.integrator,
                "needs": [n.to_json() for n in self.needs], "chosen": self.chosen,
                "alternatives": [a.to_json() for a in self.alternatives],
                "bounds": {k: list(v) for k, v in self.bounds.items()},
                "method": self.method,
                "widened": None if self.widened is None else list(self.widened),
                "wall_s": self.wall_s}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TuneFit:
        """A fit read back from :meth:`to_json`."""
        widened = data.get("widened")
        return cls(tuple(FittedStart.from_json(s) for s in data["starts"]), data["residual"],
                   data["residual_definition"], data["runs"], data["rollouts"],
                   data["verify_runs"], data["budget_runs"], tuple(data["seeds"]),
                   tuple(data["fits"]), tuple(data["cones"]), tuple(data["tried"]),
                   data["timestep_s"], data["integrator"],
                   tuple(TuneNeed.from_json(n) for n in data["needs"]), data["chosen"],
                   tuple(TuneAlternative.from_json(a) for a in data["alternatives"]),
                   {k: tuple(v) for k, v in data["bounds"].items()}, data["method"],
                   None if widened is None else tuple(widened), data["wall_s"])


@dataclass(frozen=True)
class TuneVerification:
    """One start's verification: the tuned settings run from it, checked by validate's verdict.

    Attributes:
        n0: The start's spin (rad/s).
        theta0: The start's tilt (rad).
        role: ``fit`` (the file's own start) or ``held-out``.
        t_end_s: Its horizon (s): longer than the tuning's where its reference still moved.
        theory_outcome: The theory's outcome from it (None: not verifiable).
        checks: The verdict's checks of the tuned run (:func:`verdict`'s dictionaries).
        passed: Every check passed; None: not verifiable (the reference stops).
        note: Why it is not verifiable (only where ``passed`` is None).
        friction_realised: The law the tuned run realised (only where verified).
        left_table_s: When the tuned run's ball left the table (s), None if never (only where
            verified).
    """

    n0: float
    theta0: float
    role: str
    t_end_s: float
    theory_outcome: str | None
    checks: tuple[dict[str, Any], ...]
    passed: bool | None
    note: str | None = None
    friction_realised: dict[str, Any] | None = None
    left_table_s: float | None = None

    def label(self) -> str:
        """The start: ``n0 = 150 rad/s, theta0 = 0.04 rad`` (:func:`start_label`)."""
        return start_label(self.n0, self.theta0)

    def failed_checks(self) -> list[str]:
        """The names of the checks that depart."""
        return [c["check"] for c in self.checks if c["passed"] is False]

    def to_json(self) -> dict[str, Any]:
        """``{n0, theta0, role, t_end_s, theory_outcome, checks, passed, ...}``.

        Then ``note`` (not verifiable) or ``friction_realised`` and ``left_table_s``.
        """
        out = {"n0": self.n0, "theta0": self.theta0, "role": self.role,
               "t_end_s": self.t_end_s, "theory_outcome": self.theory_outcome,
               "checks": list(self.checks), "passed": self.passed}
        if self.passed is None:
            return {**out, "note": self.note}
        return {**out, "friction_realised": self.friction_realised,
                "left_table_s": self.left_table_s}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TuneVerification:
        """A verification read back from :meth:`to_json`."""
        return cls(data["n0"], data["theta0"], data["role"], data["t_end_s"],
                   data["theory_outcome"], tuple(data["checks"]), data["passed"],
                   data.get("note"), data.get("friction_realised"), data.get("left_table_s"))


@dataclass(frozen=True)
class TuneResult:
    """A tuning: the settings, their MJCF, the fit's record and every start's verification.

    Attributes:
        settings: The tuned settings as the verification ran them.
        mjcf: The settings as MJCF to paste.
        fit: The fit's record.
        verified: Each start's verification, the file's own first.
        agrees: Every start checked passes, a held-out one among them.
        departs: Each check that departs, over every start.
        passes: Checks that pass over every start.
        checks: Checks over every start.
        budget_limited: The run budget ended the tuning before it was done.
        note: One sentence: paste them, or why they depart.
        cached: Read from the tuning cache (True) or computed (False); None where the caller
            does not say (the tuning itself).
    """

    settings: TunedSettings
    mjcf: str
    fit: TuneFit
    verified: tuple[TuneVerification, ...]
    agrees: bool
    departs: tuple[str, ...]
    passes: int
    checks: int
    budget_limited: bool
    note: str
    cached: bool | None = None

    def checked(self) -> list[TuneVerification]:
        """The starts verified (their reference's model holds there)."""
        return [v for v in self.verified if v.passed is not None]

    def to_json(self) -> dict[str, Any]:
        """``{settings, mjcf, fit, verified, agrees, departs, passes, checks, ...}``.

        Then ``budget_limited`` and ``note``, and ``cached`` where it is known.
        """
        out = {"settings": self.settings.to_json(), "mjcf": self.mjcf,
               "fit": self.fit.to_json(), "verified": [v.to_json() for v in self.verified],
               "agrees": self.agrees, "departs": list(self.departs), "passes": self.passes,
               "checks": self.checks, "budget_limited": self.budget_limited,
               "note": self.note}
        return out if self.cached is None else {**out, "cached": self.cached}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TuneResult:
        """A tuning read back from :meth:`to_json` (a ``--json`` output, a cache entry)."""
        return cls(TunedSettings.from_json(data["settings"]), data["mjcf"],
                   TuneFit.from_json(data["fit"]),
                   tuple(TuneVerification.from_json(v) for v in data["verified"]),
                   data["agrees"], tuple(data["departs"]), data["passes"], data["checks"],
                   data["budget_limited"], data["note"], data.get("cached"))


@dataclass(frozen=True)
class TuneSkipped:
    """A tuning that did not run, and why.

    Attributes:
        skipped: Why (``--no-tune``, a failed reference, the tuning's error).
        agrees: False where it was asked for and could not run; None for ``--no-tune``
            (then absent from the JSON).
    """

    skipped: str
    agrees: bool | None = None

    def to_json(self) -> dict[str, Any]:
        """``{skipped}``, with ``agrees`` where it is said."""
        return ({"skipped": self.skipped} if self.agrees is None
                else {"skipped": self.skipped, "agrees": self.agrees})

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TuneSkipped:
        """A skipped tuning read back from :meth:`to_json`."""
        return cls(data["skipped"], data.get("agrees"))


#: validate's ``tuned``: a tuning, or why there is none.
Tuned = TuneResult | TuneSkipped


def tuned_from_json(data: dict[str, Any]) -> Tuned:
    """Validate's ``tuned`` read back: a :class:`TuneSkipped` where it says ``skipped``."""
    return TuneSkipped.from_json(data) if "skipped" in data else TuneResult.from_json(data)


@dataclass(frozen=True)
class TuneOnlyResult:
    """``tippetop calibrate --mjcf FILE``: the file's start and its contact settings tuned.

    Attributes:
        file: The MJCF file.
        mu: The file's mu (None if it gives none).
        n0: The file's spin (rad/s).
        theta0: The file's tilt (rad).
        t_end_s: The verification's horizon (s).
        tuned: The tuning, or why it did not run.
    """

    file: str
    mu: float | None
    n0: float
    theta0: float
    t_end_s: float
    tuned: Tuned

    def to_json(self) -> dict[str, Any]:
        """``{file, mu, n0, theta0, t_end_s, tuned}``: ``calibrate --mjcf --json``'s."""
        return {"file": self.file, "mu": self.mu, "n0": self.n0, "theta0": self.theta0,
                "t_end_s": self.t_end_s, "tuned": self.tuned.to_json()}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TuneOnlyResult:
        """A result read back from :meth:`to_json`."""
        return cls(data["file"], data["mu"], data["n0"], data["theta0"], data["t_end_s"],
                   tuned_from_json(data["tuned"]))


__all__ = ["FittedStart", "TuneAlternative", "TuneFit", "TuneNeed", "TuneOnlyResult",
           "TuneResult", "TuneSkipped", "TuneVerification", "TunedSettings", "Tuned",
           "start_label", "tuned_from_json"]
