"""``tippetop bisect --probe``: the runs of one probe in one mode, as the search's runner.

:class:`ProbeRunner` is :class:`~.bisect.Runner` for a probe: each release runs the probe through
its worker (:func:`~tippetop.compare.probes.study.run_probes`), and its quantities are the
metrics the search compares (``probe.<probe>.<quantity>``, each within its baseline tolerance:
:func:`~.matrix.metric_tolerance`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from tippetop.compare.results.matrix import MatrixResult
from tippetop.compare.studies.bisect import MatrixRunner
from tippetop.models.errors import TippetopError, did_you_mean


@dataclass
class ProbeRunner:
    """The runs of one probe in one mode (``bisect --probe``): its quantities are the metrics.

    Each release runs the probe through its worker (:func:`~tippetop.compare.probes.study.
    run_probes`); the values are the probe's metrics (``probe.<probe>.<quantity>``). A probe
    has no subsystems to switch off one at a time: its moves are not attributed.
    """

    probe: str
    mode: str
    integrator: str | None = None
    timestep_s: float | None = None
    sets: tuple[str, ...] = ()
    use_cache: bool = True
    say: Callable[[str], None] | None = None

    def prepare(self, engine: str) -> str:
        """Make or find the engine's managed environment."""
        return MatrixRunner("", "", say=self.say).prepare(engine)

    def measure(self, engines: Sequence[str]) -> dict[str, dict[str, Any]]:
        """Run the probe on each engine; each its version, status and quantities' values."""
        from tippetop.compare.probes.study import run_probes
        from tippetop.models.engines import parse_engine

        res = run_probes([self.probe], [parse_engine(e) for e in engines], modes=[self.mode],
                         integrator=self.integrator, timestep_s=self.timestep_s,
                         sets=self.sets, use_cache=self.use_cache)
        out: dict[str, dict[str, Any]] = {}
        for run in res.runs:
            reasons = [r.reason for r in run.rows if r.reason]
            version = run.rows[0].version if run.rows else None
            out[run.engine] = {
                "version": None if version in (None, "?") else version,
                "status": "failed" if reasons else "ok",
                "message": reasons[0] if reasons else "",
                "values": {r.metric: (r.value if math.isfinite(r.value) else None)
                           for r in run.rows}}
        return out

    def attribute(self, a: str, b: str) -> MatrixResult:  # pragma: no cover - never called
        """Not done for a probe (bisect runs it with ``attribution=False``)."""
        raise NotImplementedError("a probe's move is not attributed")


def probe_metrics_of(probe: str, text: str | None) -> list[str]:
    """``--metric`` for ``--probe``: the probe's quantities, full or bare (default: all).

    Raises:
        TippetopError: A quantity the probe does not have (one line).
    """
    from tippetop.compare.probes import probe_class
    from tippetop.compare.probes.base import metric_name

    names = [metric_name(probe, q.name) for q in probe_class(probe).quantities]
    if not text:
        return names
    out = []
    for m in (s.strip() for s in text.split(",") if s.strip()):
        full = m if m.startswith("probe.") else metric_name(probe, m)
        if full not in names:
            raise TippetopError(f"--metric: expected quantities of probe {probe} ("
                                f"{', '.join(n.rsplit('.', 1)[1] for n in names)}), got {m!r}"
                                f"{did_you_mean(m, [n.rsplit('.', 1)[1] for n in names])}")
        if full not in out:
            out.append(full)
    return out


__all__ = ["ProbeRunner", "probe_metrics_of"]
