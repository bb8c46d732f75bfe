"""A bisect's result: which release (or interpreter) moved each metric, and what ran.

What :func:`tippetop.compare.studies.bisect.bisect` returns (the search), and, with the
command's :class:`BisectContext`, what ``tippetop bisect --json`` prints, ``results.json``
holds and the history reads (:meth:`BisectResult.to_json`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from tippetop.compare.results.matrix import Attribution, Closer

#: The format of the result (``--json``, ``results.json``).
FORMAT = "tippetop-bisect/1"


@dataclass(frozen=True)
class TestedRelease:
    """A release (or interpreter) of the range that ran, and what it measured.

    Attributes:
        release: The release's name (an interpreter's path with ``--pythons``).
        engine: The engine that ran it (``mujoco==X.Y.Z``, ``mujoco``, ``mujoco@PYTHON``).
        version: The MuJoCo version read back from the run.
        status: The run's status.
        message: The run's message.
        environment: How its engine was made ready: ``made``, ``found``, ``workers``, ``none``.
        step: The search's step that ran it.
        values: Per metric the matrix compares, its value.
    """

    __test__ = False  # not a pytest test class, whatever its name

    release: str
    engine: str
    version: str | None
    status: str | None
    message: str | None
    environment: str
    step: int
    values: dict[str, Any]

    #: The JSON's keys, in order (the fields' names).
    KEYS: ClassVar[tuple[str, ...]] = ("release", "engine", "version", "status", "message",
                                       "environment", "step", "values")

    def to_json(self) -> dict[str, Any]:
        """``{release, engine, version, status, message, environment, step, values}``."""
        out = {k: getattr(self, k) for k in self.KEYS}
        out["values"] = dict(self.values)
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TestedRelease:
        """A release read back from :meth:`to_json`."""
        kw = {k: data[k] for k in cls.KEYS}
        kw["values"] = dict(kw["values"])
        return cls(**kw)


@dataclass(frozen=True)
class SkippedRelease:
    """A release of the range that could not run, and why."""

    release: str
    engine: str
    reason: str

    def to_json(self) -> dict[str, Any]:
        """``{release, engine, reason}``."""
        return {"release": self.release, "engine": self.engine, "reason": self.reason}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> SkippedRelease:
        """A skipped release read back from :meth:`to_json`."""
        return cls(data["release"], data["engine"], data["reason"])


@dataclass(frozen=True)
class Move:
    """A metric's move between two consecutive runs of the range.

    Attributes:
        last_like_before: The last release run with the value before the move.
        first_like_after: The first release run with the value after it.
        values: The metric's values at the two.
        resolved: Every release between the two could not run (or there is none): the move
            is pinned to the pair.
        untested_between: The releases between the two.
    """

    last_like_before: str
    first_like_after: str
    values: tuple[Any, Any]
    resolved: bool
    untested_between: tuple[str, ...]

    def to_json(self) -> dict[str, Any]:
        """``{last_like_before, first_like_after, values, resolved, untested_between}``."""
        return {"last_like_before": self.last_like_before,
                "first_like_after": self.first_like_after, "values": list(self.values),
                "resolved": self.resolved, "untested_between": list(self.untested_between)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Move:
        """A move read back from :meth:`to_json`."""
        va, vb = data["values"]
        return cls(data["last_like_before"], data["first_like_after"], (va, vb),
                   data["resolved"], tuple(data["untested_between"]))


@dataclass(frozen=True)
class MovePair:
    """The pair of a metric's first move: the last release like A, the first like B."""

    last_like_a: str
    first_like_b: str

    def to_json(self) -> dict[str, Any]:
        """``{last_like_a, first_like_b}``."""
        return {"last_like_a": self.last_like_a, "first_like_b": self.first_like_b}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> MovePair:
        """A pair read back from :meth:`to_json`."""
        return cls(data["last_like_a"], data["first_like_b"])


@dataclass(frozen=True)
class MetricFinding:
    """One metric's finding: its first move from A's value, every move seen, a sentence.

    Attributes:
        moved: Whether it departs from A's value somewhere in the range.
        pair: The first move's pair (None: no move).
        values: The metric's values at the pair (None: no move).
        a_value: Its value at the range's first release run.
        b_value: Its value at the range's last release run.
        tolerance: Its tolerance (``{kind, value, floor, why, text}``).
        moves_more_than_once: More than one move was seen.
        moves: Every move seen, in range order.
        attribution: What the first move follows (the matrix's at the pair; None: not
            attributed, or the matrix found no difference there).
        closer: Which end of the pair is nearer the truth (the matrix's; None likewise).
        summary: The finding in one sentence.
        attribution_note: Why there is no attribution though one was asked (None: there is
            one, or none was asked).
    """

    moved: bool
    pair: MovePair | None
    values: tuple[Any, Any] | None
    a_value: Any
    b_value: Any
    tolerance: dict[str, Any]
    moves_more_than_once: bool
    moves: tuple[Move, ...]
    attribution: Attribution | None
    closer: Closer | None
    summary: str
    attribution_note: str | None = None

    def to_json(self) -> dict[str, Any]:
        """``{moved, pair, values, a_value, b_value, tolerance, moves_more_than_once, ...}``.

        Then ``moves``, ``attribution``, ``closer``, ``summary`` (and ``attribution_note``
        when there is one).
        """
        out = {"moved": self.moved, "pair": None if self.pair is None else self.pair.to_json(),
               "values": None if self.values is None else list(self.values),
               "a_value": self.a_value, "b_value": self.b_value,
               "tolerance": dict(self.tolerance),
               "moves_more_than_once": self.moves_more_than_once,
               "moves": [m.to_json() for m in self.moves],
               "attribution": None if self.attribution is None else self.attribution.to_json(),
               "closer": None if self.closer is None else self.closer.to_json(),
               "summary": self.summary}
        if self.attribution_note is not None:
            out["attribution_note"] = self.attribution_note
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> MetricFinding:
        """A finding read back from :meth:`to_json`."""
        pair, values, att, near = (data["pair"], data["values"], data["attribution"],
                                   data["closer"])
        return cls(data["moved"], None if pair is None else MovePair.from_json(pair),
                   None if values is None else (values[0], values[1]),
                   data["a_value"], data["b_value"], dict(data["tolerance"]),
                   data["moves_more_than_once"],
                   tuple(Move.from_json(m) for m in data["moves"]),
                   None if att is None else Attribution.from_json(att),
                   None if near is None else Closer.from_json(near),
                   data["summary"], data.get("attribution_note"))


@dataclass(frozen=True)
class BisectContext:
    """What the command bisected: the scene, its mode and settings, where the range came from.

    Attributes:
        scene: The scene as named (a catalogue name, a scene file or an MJCF top).
        mode: The mode it ran in.
        overrides: The ``--set`` settings, as given.
        source: Where the range came from (the registry's address, ``--pythons FILE`` ...).
        started: When the command started.
    """

    scene: str
    mode: str
    overrides: tuple[str, ...]
    source: str
    started: str

    def to_json(self) -> dict[str, Any]:
        """``{scene, mode, overrides, source, started}``."""
        return {"scene": self.scene, "mode": self.mode, "overrides": list(self.overrides),
                "source": self.source, "started": self.started}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> BisectContext:
        """The context read back from :meth:`to_json` (or a whole result's JSON)."""
        return cls(data["scene"], data["mode"], tuple(data["overrides"]), data["source"],
                   data["started"])


@dataclass(frozen=True)
class BisectResult:
    """A bisect over a range of releases (or interpreters): what ran, and each metric's moves.

    Attributes:
        releases: The range, in order.
        between: The range's first and last.
        kind: ``releases`` or ``interpreters``.
        searched: The first and last that ran (the ends, or their neighbours if an end
            could not run).
        tested: Every release that ran, in range order.
        runs: How many ran.
        environments_made: Runs in a managed environment (made now, found or the workers').
        environments_new: Managed environments made now.
        steps: The search's steps.
        budget: The most runs for further moves.
        skipped: Every release that could not run, and why.
        metrics: The metrics searched.
        by_metric: Each metric's finding.
        notes: What the search noticed (an end that could not run, a version read back
            unlike its release).
        context: What the command bisected (None: the search alone, as ``bisect`` returns it).
        history: The history append (``{file, run, error}``; None: not appended).
    """

    releases: tuple[str, ...]
    between: tuple[str, str]
    kind: str
    searched: tuple[str, str]
    tested: tuple[TestedRelease, ...]
    runs: int
    environments_made: int
    environments_new: int
    steps: int
    budget: int
    skipped: tuple[SkippedRelease, ...]
    metrics: tuple[str, ...]
    by_metric: dict[str, MetricFinding]
    notes: tuple[str, ...]
    context: BisectContext | None = None
    history: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """``{releases, between, kind, searched, tested, runs, environments_made, ...}``.

        With a context, ``{format, scene, mode, overrides, source, started}`` first (what the
        command prints); ``history`` last when set.
        """
        out: dict[str, Any] = {}
        if self.context is not None:
            out = {"format": FORMAT, **self.context.to_json()}
        out.update({
            "releases": list(self.releases), "between": list(self.between), "kind": self.kind,
            "searched": list(self.searched), "tested": [t.to_json() for t in self.tested],
            "runs": self.runs, "environments_made": self.environments_made,
            "environments_new": self.environments_new, "steps": self.steps,
            "budget": self.budget, "skipped": [s.to_json() for s in self.skipped],
            "metrics": list(self.metrics),
            "by_metric": {m: f.to_json() for m, f in self.by_metric.items()},
            "notes": list(self.notes)})
        if self.history is not None:
            out["history"] = dict(self.history)
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> BisectResult:
        """A bisect read back from :meth:`to_json` (``results.json``, or the search alone)."""
        (a, b), (sa, sb) = data["between"], data["searched"]
        return cls(tuple(data["releases"]), (a, b), data["kind"], (sa, sb),
                   tuple(TestedRelease.from_json(t) for t in data["tested"]), data["runs"],
                   data["environments_made"], data["environments_new"], data["steps"],
                   data["budget"], tuple(SkippedRelease.from_json(s) for s in data["skipped"]),
                   tuple(data["metrics"]),
                   {m: MetricFinding.from_json(f) for m, f in data["by_metric"].items()},
                   tuple(data["notes"]),
                   BisectContext.from_json(data) if "scene" in data else None,
                   data.get("history"))


__all__ = ["FORMAT", "BisectContext", "BisectResult", "MetricFinding", "Move", "MovePair",
           "SkippedRelease", "TestedRelease"]
