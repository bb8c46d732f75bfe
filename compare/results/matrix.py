"""A matrix's result: every scene on every engine in every mode, and what differs between them.

What :func:`tippetop.compare.studies.matrix.run_matrix` returns. Its JSON
(:meth:`MatrixResult.to_json`) is what ``tippetop matrix --json`` prints, ``results.json``
holds and the history reads; the runs' tables are not in it (``run_matrix`` hands them over
apart). A difference's attribution (:class:`Attribution`) and which engine is nearer the truth
(:class:`Closer`) are made by :mod:`tippetop.compare.studies.attribution`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

#: The format of ``results.json`` (2: a run's ``engine`` and ``mode`` apart, ``engines`` by
#: ``engine``).
FORMAT = "tippetop-matrix/2"
#: The statuses of a run that ran to its end (any other: the run failed).
RAN_STATUSES = ("ok", "contact_lost", "hop")


@dataclass(frozen=True)
class MatrixEngine:
    """An engine of the matrix, its version read back from its runs.

    Attributes:
        engine: The spec (``mujoco``, ``mujoco==3.3.7``, ``mjx-f32`` ...).
        implementation: ``mujoco``, ``mjx`` or ``warp``.
        version: The version its runs read back (else the spec's, None if it names none).
        precision: ``float64`` or ``float32``.
        device: Where it ran (``cpu``).
    """

    engine: str
    implementation: str
    version: str | None
    precision: str
    device: str

    #: The JSON's keys, in order (the fields' names).
    KEYS: ClassVar[tuple[str, ...]] = ("engine", "implementation", "version", "precision",
                                       "device")

    def to_json(self) -> dict[str, Any]:
        """``{engine, implementation, version, precision, device}``."""
        return {k: getattr(self, k) for k in self.KEYS}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> MatrixEngine:
        """An engine read back from :meth:`to_json`."""
        return cls(**{k: data[k] for k in cls.KEYS})


@dataclass(frozen=True)
class MatrixRun:
    """One run: what it measured, and its verdict against the theory (or the reference).

    Attributes:
        scene: The scene as named (a catalogue name, a scene file or an MJCF top).
        engine: The engine's spec (``ode`` for the reference).
        mode: The mode it ran in.
        run: ``ENGINE/MODE``.
        status: The run's status (``failed`` when it raised).
        message: The run's message (or its error).
        t_invert: When it turned over (s), None if it did not.
        t_stem: When the stem landed (s), None if it did not.
        t_left_table: When it left the table (s), None if it did not.
        theta_final: theta at the end (rad).
        theta_asymp: The asymptotic tilt (rad), None when the run failed.
        J_rel_drift: Jellett's constant's relative drift.
        agrees: Every check of the verdict passed.
        against: What it was judged against (``theory`` or ``reference``).
        outcome: Its outcome (``inverted``, ``upright``, ..., ``failed``).
        theta_s: The theory's theta_s for the scene (rad), None without one.
        theory_outcome: The theory's outcome for the scene.
        reasons: Why it departs, one sentence a failed check.
        checks: The verdict's checks (``{check, run, engine, mode, passed, ...}``).
        version: The engine's version read back from the run.
        path: Where the run's table is kept.
        friction_realised: The friction law as the engine realised it (``samples``, fit ...),
            None without one.
    """

    scene: str
    engine: str
    mode: str
    run: str
    status: str | None
    message: str | None = None
    t_invert: float | None = None
    t_stem: float | None = None
    t_left_table: float | None = None
    theta_final: float | None = None
    theta_asymp: float | None = None
    J_rel_drift: float | None = None
    agrees: bool = False
    against: str | None = None
    outcome: str | None = None
    theta_s: float | None = None
    theory_outcome: str | None = None
    reasons: tuple[str, ...] = ()
    checks: tuple[dict[str, Any], ...] = ()
    version: str | None = None
    path: str | None = None
    friction_realised: dict[str, Any] | None = None

    #: The JSON's keys, in order (the fields' names).
    KEYS: ClassVar[tuple[str, ...]] = (
        "scene", "engine", "mode", "run", "status", "message", "t_invert", "t_stem",
        "t_left_table", "theta_final", "theta_asymp", "J_rel_drift", "agrees", "against",
        "outcome", "theta_s", "theory_outcome", "reasons", "checks", "version", "path",
        "friction_realised")

    @property
    def ran(self) -> bool:
        """Whether the run ran to its end (its status one of :data:`RAN_STATUSES`)."""
        return self.status in RAN_STATUSES

    def value(self, metric: str) -> Any:
        """The run's value of a metric the matrix compares (``status``, ``t_invert`` ...)."""
        return getattr(self, metric)

    def to_json(self) -> dict[str, Any]:
        """``{scene, engine, mode, run, status, message, t_invert, ..., friction_realised}``."""
        out = {k: getattr(self, k) for k in self.KEYS}
        out["reasons"], out["checks"] = list(self.reasons), list(self.checks)
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> MatrixRun:
        """A run read back from :meth:`to_json`."""
        kw = {k: data[k] for k in cls.KEYS if k in data}  # an older file may lack some
        kw["reasons"] = tuple(kw.get("reasons", ()))
        kw["checks"] = tuple(kw.get("checks", ()))
        return cls(**kw)


@dataclass(frozen=True)
class Evidence:
    """One change of attribution, as both engines ran with it (or why it did not apply).

    Attributes:
        change: The change (``integrator Euler``, ``friction off`` ...).
        applies: Whether it applies to the plan (False: it did not run, ``why`` says why).
        why: Why it does not apply (None when it does).
        a: Engine A's value of the metric with the change.
        b: Engine B's value of the metric with the change.
        difference: |a - b| (None when either is missing, a word or not finite).
        theta_gap_rad: The largest |theta_a(t) - theta_b(t)| with the change (rad).
        agree: Whether the two agree on the metric with the change (the matrix's rule).
        failed: The message of a rerun that failed (None: neither did).
    """

    change: str
    applies: bool = True
    why: str | None = None
    a: Any = None
    b: Any = None
    difference: float | None = None
    theta_gap_rad: float | None = None
    agree: bool = False
    failed: str | None = None

    def to_json(self) -> dict[str, Any]:
        """``{change, a, b, difference, theta_gap_rad, agree}`` (and ``failed``).

        A change that does not apply: ``{change, applies: False, why}``.
        """
        if not self.applies:
            return {"change": self.change, "applies": False, "why": self.why}
        out = {"change": self.change, "a": self.a, "b": self.b, "difference": self.difference,
               "theta_gap_rad": self.theta_gap_rad, "agree": self.agree}
        if self.failed is not None:
            out["failed"] = self.failed
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Evidence:
        """Evidence read back from :meth:`to_json`."""
        if not data.get("applies", True):
            return cls(data["change"], applies=False, why=data["why"])
        return cls(data["change"], a=data["a"], b=data["b"], difference=data["difference"],
                   theta_gap_rad=data["theta_gap_rad"], agree=data["agree"],
                   failed=data.get("failed"))


@dataclass(frozen=True)
class Attribution:
    """What a difference between two engines follows, and the reruns' evidence.

    Attributes:
        follows: One sentence, with the numbers.
        evidence: Per change, as both engines ran with it.
        removed_by: The changes that make the two agree.
        kept_by: The changes that leave them apart.
        metric: The metric that differs.
        engines: Engines A and B.
        theta_gap_rad: The largest theta(t) gap of the runs as they ran (rad).
    """

    follows: str
    evidence: tuple[Evidence, ...]
    removed_by: tuple[str, ...]
    kept_by: tuple[str, ...]
    metric: str
    engines: tuple[str, str]
    theta_gap_rad: float | None

    def to_json(self) -> dict[str, Any]:
        """``{follows, evidence, removed_by, kept_by, metric, engines, theta_gap_rad}``."""
        return {"follows": self.follows, "evidence": [e.to_json() for e in self.evidence],
                "removed_by": list(self.removed_by), "kept_by": list(self.kept_by),
                "metric": self.metric, "engines": list(self.engines),
                "theta_gap_rad": self.theta_gap_rad}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Attribution:
        """An attribution read back from :meth:`to_json`."""
        a, b = data["engines"]
        return cls(data["follows"], tuple(Evidence.from_json(e) for e in data["evidence"]),
                   tuple(data["removed_by"]), tuple(data["kept_by"]), data["metric"], (a, b),
                   data["theta_gap_rad"])


@dataclass(frozen=True)
class Closer:
    """Which of two engines is nearer the reference ODE, and nearer its own converged answer.

    A distance of an exact metric is 0 when it matches, 1 when not.

    Attributes:
        reference: The engine nearer the reference, ``tie``, or None (a value is missing).
        reference_value: The reference ODE's value on the scene.
        reference_distance: A's and B's distances to it.
        converged: Per engine, its distance to its own answer at a quarter of the timestep
            (None: not run).
        converged_nearer: The engine nearer its own converged answer, ``tie``, or None.
    """

    reference: str | None
    reference_value: Any
    reference_distance: tuple[float | None, float | None]
    converged: dict[str, float | None]
    converged_nearer: str | None

    def to_json(self) -> dict[str, Any]:
        """``{reference, reference_value, reference_distance, converged, converged_nearer}``."""
        return {"reference": self.reference, "reference_value": self.reference_value,
                "reference_distance": list(self.reference_distance),
                "converged": dict(self.converged), "converged_nearer": self.converged_nearer}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Closer:
        """A verdict read back from :meth:`to_json`."""
        da, db = data["reference_distance"]
        return cls(data["reference"], data["reference_value"], (da, db),
                   dict(data["converged"]), data["converged_nearer"])


@dataclass(frozen=True)
class MatrixDifference:
    """A metric on which two engines differ beyond the nightly's tolerance, in one scene and mode.

    Attributes:
        scene: The scene.
        mode: The mode.
        engines: Engines A and B.
        metric: The metric.
        values: A's and B's values.
        tolerance: The tolerance's value (None for an exact metric).
        why: The tolerance's reason.
        attribution: What it follows (None: not attributed).
        closer: Which engine is nearer the truth (None: not attributed).
    """

    scene: str
    mode: str
    engines: tuple[str, str]
    metric: str
    values: tuple[Any, Any]
    tolerance: float | None
    why: str
    attribution: Attribution | None = None
    closer: Closer | None = None

    def to_json(self) -> dict[str, Any]:
        """``{scene, mode, engines, metric, values, tolerance, why, attribution, closer}``."""
        return {"scene": self.scene, "mode": self.mode, "engines": list(self.engines),
                "metric": self.metric, "values": list(self.values),
                "tolerance": self.tolerance, "why": self.why,
                "attribution": None if self.attribution is None else self.attribution.to_json(),
                "closer": None if self.closer is None else self.closer.to_json()}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> MatrixDifference:
        """A difference read back from :meth:`to_json`."""
        (a, b), (va, vb) = data["engines"], data["values"]
        att, near = data.get("attribution"), data.get("closer")
        return cls(data["scene"], data["mode"], (a, b), data["metric"], (va, vb),
                   data["tolerance"], data["why"],
                   None if att is None else Attribution.from_json(att),
                   None if near is None else Closer.from_json(near))


@dataclass(frozen=True)
class MatrixResult:
    """Every scene on every engine in every mode, the reference once per scene.

    Attributes:
        engines: The MuJoCo engines, their versions read back from the runs.
        runs: A run per scene, mode and engine (the reference's apart, in ``reference``).
        differences: Every metric on which two engines differ beyond its tolerance.
        attribution: Whether the differences were attributed (reruns with one subsystem
            changed at a time).
        reference: The reference ODE's run per scene.
        modes: The modes run, in order.
        scenes: The scenes, as named.
        tolerances: Per compared metric, its tolerance (``{kind, value, floor, why, ...}``).
        started: When the command started (None: not said; the command sets it).
        history: The history append (``{file, run, error}``; None: not appended).
    """

    engines: tuple[MatrixEngine, ...]
    runs: tuple[MatrixRun, ...]
    differences: tuple[MatrixDifference, ...]
    attribution: bool
    reference: dict[str, MatrixRun]
    modes: tuple[str, ...]
    scenes: tuple[str, ...]
    tolerances: dict[str, dict[str, Any]]
    started: str | None = None
    history: dict[str, Any] | None = None

    def failed_runs(self) -> list[MatrixRun]:
        """The runs that did not run to their end."""
        return [r for r in self.runs if not r.ran]

    def to_json(self) -> dict[str, Any]:
        """What ``tippetop matrix --json`` prints: ``{format, engines, runs, ...}``.

        ``format``, ``engines``, ``runs``, ``differences``, ``attribution``, ``reference``,
        ``modes``, ``scenes``, ``tolerances`` (and ``started``, ``history`` when set).
        """
        out: dict[str, Any] = {
            "format": FORMAT, "engines": [e.to_json() for e in self.engines],
            "runs": [r.to_json() for r in self.runs],
            "differences": [d.to_json() for d in self.differences],
            "attribution": self.attribution,
            "reference": {k: r.to_json() for k, r in self.reference.items()},
            "modes": list(self.modes), "scenes": list(self.scenes),
            "tolerances": {k: dict(v) for k, v in self.tolerances.items()}}
        if self.started is not None:
            out["started"] = self.started
        if self.history is not None:
            out["history"] = dict(self.history)
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> MatrixResult:
        """A matrix read back from :meth:`to_json` (``results.json``)."""
        return cls(tuple(MatrixEngine.from_json(e) for e in data["engines"]),
                   tuple(MatrixRun.from_json(r) for r in data["runs"]),
                   tuple(MatrixDifference.from_json(d) for d in data["differences"]),
                   data["attribution"],
                   {k: MatrixRun.from_json(r) for k, r in data["reference"].items()},
                   tuple(data["modes"]), tuple(data["scenes"]),
                   {k: dict(v) for k, v in data["tolerances"].items()},
                   data.get("started"), data.get("history"))


__all__ = ["FORMAT", "RAN_STATUSES", "Attribution", "Closer", "Evidence", "MatrixDifference",
           "MatrixEngine", "MatrixResult", "MatrixRun"]
