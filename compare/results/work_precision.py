"""The work-precision benchmark's result (``tippetop bench ode --sweep``): per top, per solver.

Its JSON is the format :data:`FORMAT` (``docs/data/work-precision.json`` holds one).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from tippetop.models.errors import TippetopError

#: The JSON's format key.
FORMAT = "tippetop-work-precision/1"
#: The target: the fastest peer's time over the reference's, at equal achieved error.
TARGET_RATIO = 1.2


@dataclass(frozen=True)
class WorkPrecisionTop:
    """One top's sweep: its truth, every solver's points, and the equal-error rows.

    Attributes:
        name: The top (``fig3``, ``fig11``, ``stiff``).
        title: Its title.
        t_end_s: Simulated time (s).
        stiff: Whether the reference runs its rolling phases (the stiff top).
        truth: The two truths: ``methods``, ``rtol``, ``atol``, ``theta``, ``theta_other``,
            ``theta_diff``, ``t_invert``, ``t_invert_other``, ``t_invert_diff``,
            ``t_invert_locate_err``, ``locator``, ``J_drift``.
        solvers: Per solver its ``kind`` (reference or peer), ``points`` (per rtol: rtol,
            atol, s, n_rhs, status, theta_err, t_invert_err, J_drift, method,
            t_invert_locate_err, printed) and ``stopped`` (the rtol its sweep stopped at).
        skipped: Solvers not run, and why.
        references: The reference's methods compared (``auto`` aside).
        auto: The reference's default among the solvers (or None).
        peers: The peers run.
        levels: Per metric (theta, t_invert, J_drift) its ``unit``, ``levels``, ``rows`` (one
            per level: times, smallest, best_reference, best_peer, ratio, ratio_auto, met,
            met_auto and their ``_steady`` twins) and ``cancellations``.
    """

    name: str
    title: str
    t_end_s: float
    stiff: bool
    truth: dict[str, Any]
    solvers: dict[str, dict[str, Any]]
    skipped: dict[str, str]
    references: tuple[str, ...]
    auto: str | None
    peers: tuple[str, ...]
    levels: dict[str, dict[str, Any]]

    def to_json(self) -> dict[str, Any]:
        """The top's entry of the JSON's ``tops``."""
        return {"name": self.name, "title": self.title, "t_end_s": self.t_end_s,
                "stiff": self.stiff, "truth": self.truth, "solvers": self.solvers,
                "skipped": self.skipped, "references": list(self.references),
                "auto": self.auto, "peers": list(self.peers), "levels": self.levels}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> WorkPrecisionTop:
        """A top read back from its JSON entry."""
        return cls(name=data["name"], title=data["title"], t_end_s=data["t_end_s"],
                   stiff=data["stiff"], truth=data["truth"], solvers=data["solvers"],
                   skipped=data["skipped"], references=tuple(data["references"]),
                   auto=data["auto"], peers=tuple(data["peers"]), levels=data["levels"])


@dataclass(frozen=True)
class WorkPrecisionResult:
    """The benchmark on its tops: how it was timed, and each top's sweep.

    Attributes:
        rounds: Rounds of the compiled solvers.
        short_rounds: Rounds of a compiled solver's point under ``short_s``.
        short_s: A short point's CPU time (s).
        timing: How the times are measured.
        tolerances: The sweep's rtol values.
        atol_per_rtol: atol / rtol.
        target_ratio: The target: the fastest peer's time over the reference's.
        skipped_methods: The reference's methods that do not import, and why.
        tops: Per top, its sweep.
        elapsed_s: Wall time of the whole benchmark (s).
        out: The folder written (None: not written; the stored JSON has none).
        format: :data:`FORMAT`.
    """

    rounds: int
    short_rounds: int
    short_s: float
    timing: str
    tolerances: tuple[float, ...]
    atol_per_rtol: float
    target_ratio: float
    skipped_methods: dict[str, str]
    tops: dict[str, WorkPrecisionTop]
    elapsed_s: float
    out: str | None = None
    format: str = FORMAT

    def to_json(self) -> dict[str, Any]:
        """What ``--json`` prints (``work-precision.json``: the same without ``out``)."""
        doc = {"format": self.format, "rounds": self.rounds, "short_rounds": self.short_rounds,
               "short_s": self.short_s, "timing": self.timing,
               "tolerances": list(self.tolerances), "atol_per_rtol": self.atol_per_rtol,
               "target_ratio": self.target_ratio, "skipped_methods": self.skipped_methods,
               "tops": {n: t.to_json() for n, t in self.tops.items()},
               "elapsed_s": self.elapsed_s}
        if self.out is not None:
            doc["out"] = self.out
        return doc

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> WorkPrecisionResult:
        """A result read back from its JSON (a ``work-precision.json``).

        Raises:
            TippetopError: if ``format`` is not :data:`FORMAT`.
        """
        if data.get("format") != FORMAT:
            raise TippetopError(f"work-precision: expected format {FORMAT!r}, got "
                                f"{data.get('format')!r}")
        return cls(rounds=data["rounds"], short_rounds=data["short_rounds"],
                   short_s=data["short_s"], timing=data["timing"],
                   tolerances=tuple(data["tolerances"]), atol_per_rtol=data["atol_per_rtol"],
                   target_ratio=data["target_ratio"], skipped_methods=data["skipped_methods"],
                   tops={n: WorkPrecisionTop.from_json(t) for n, t in data["tops"].items()},
                   elapsed_s=data["elapsed_s"], out=data.get("out"), format=data["format"])


__all__ = ["FORMAT", "TARGET_RATIO", "WorkPrecisionResult", "WorkPrecisionTop"]
