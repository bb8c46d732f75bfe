"""The contact's lift: each MuJoCo run's lift-off slip against the reference's largest slip.

What :func:`tippetop.compare.studies.lift.lift` returns (validate's ``lift``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class LiftResult:
    """Whether each probed MuJoCo contact pushes the top's ball off at the reference's slip.

    Attributes:
        reference: The reference's largest slip while the ball alone touches, ``{slip_mps,
            t_s}``, or None without one.
        runs: Each probed run (``ENGINE/MODE``, ``tuned``) -> ``{lift_off_slip_mps, lifts,
            contact}``.
        sentences: One per run that lifts the ball and does not agree.
        scan: The scan of MuJoCo's geom settings at the reference's slip (``{settings,
            stiff, stay, limit, closest, closest_lift_mps, sentence}``), or None where it
            did not run.
    """

    reference: dict[str, float] | None
    runs: dict[str, dict[str, Any]] = field(default_factory=dict)
    sentences: tuple[str, ...] = ()
    scan: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """``{reference, runs, sentences}``, and ``scan`` where it ran."""
        out = {"reference": self.reference, "runs": dict(self.runs),
               "sentences": list(self.sentences)}
        return out if self.scan is None else {**out, "scan": self.scan}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> LiftResult:
        """A lift read back from :meth:`to_json`."""
        return cls(data["reference"], dict(data["runs"]), tuple(data["sentences"]),
                   data.get("scan"))


__all__ = ["LiftResult"]
