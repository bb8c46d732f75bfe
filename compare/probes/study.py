"""Run probes on engines: each quantity against its exact value, one row each.

:func:`run_probes` runs every (probe, mode, engine) once - the installed MuJoCo in this
process, every other engine through its worker (:mod:`tippetop.mujoco_runner.probe_run`) -
and measures each of the probe's quantities (:class:`ProbeRow`). What ran (the integrator and
the step) is read back from the compiled model, never taken from what was asked. A run that
diverges, or that MuJoCo warned about, is a failed row for each quantity, with the reason.
Runs are cached (``$TIPPETOP_CACHE/probes``, keyed by the request, the engine and the code) as
every other run is, unless ``use_cache`` is False.

The JSON (:meth:`ProbeResult.to_json`) is ``format: tippetop-probe/1`` with ``results``, one
object per row: ``probe, engine, version, mode, integrator, timestep_s, quantity, value,
exact, error, unit, tolerance, passed`` (and ``reason``, ``note``, ``metric``).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tippetop.compare.probes import probe_class, probe_names
from tippetop.compare.probes.base import Curve, Measured, Probe, metric_name
from tippetop.models.engines import EngineSpec
from tippetop.models.errors import TippetopError, did_you_mean
from tippetop.models.mjcf import INTEGRATORS

#: The result's format.
FORMAT = "tippetop-probe/1"
#: The keys of a row, in order: a contract (issue 44).
ROW_KEYS = ("probe", "engine", "version", "mode", "integrator", "timestep_s", "quantity",
            "value", "exact", "error", "unit", "tolerance", "passed")


@dataclass(frozen=True)
class ProbeRow:
    """One quantity of one run against its exact value."""

    probe: str
    engine: str
    version: str
    mode: str
    integrator: str
    timestep_s: float
    quantity: str
    value: float
    exact: float
    unit: str
    tolerance: float
    passed: bool
    reason: str | None = None
    note: str = ""
    wall_s: float = 0.0

    @property
    def error(self) -> float:
        """``value - exact``."""
        return self.value - self.exact

    @property
    def metric(self) -> str:
        """Its metric name (``probe.<probe>.<quantity>``)."""
        return metric_name(self.probe, self.quantity)

    def to_json(self) -> dict[str, Any]:
        """The row's contract keys (non-finite numbers as null), then reason, note, metric."""
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        out: dict[str, Any] = {
            "probe": self.probe, "engine": self.engine, "version": self.version,
            "mode": self.mode, "integrator": self.integrator,
            "timestep_s": num(self.timestep_s), "quantity": self.quantity,
            "value": num(self.value), "exact": num(self.exact), "error": num(self.error),
            "unit": self.unit, "tolerance": self.tolerance, "passed": self.passed}
        out.update(reason=self.reason, note=self.note, metric=self.metric,
                   wall_s=round(self.wall_s, 4))
        return out


@dataclass(frozen=True)
class ProbeRun:
    """One (probe, mode, engine) run: its rows and its curve (None: it did not run)."""

    probe: str
    mode: str
    engine: str
    rows: tuple[ProbeRow, ...]
    curve: Curve | None
    ran: dict[str, Any] = field(default_factory=dict)
    engine_ran: dict[str, Any] = field(default_factory=dict)
    cached: bool = False


@dataclass(frozen=True)
class ProbeResult:
    """Every probe run asked for."""

    runs: tuple[ProbeRun, ...]
    probes: tuple[str, ...]
    engines: tuple[str, ...]
    integrator: str | None
    timestep_s: float | None
    params: dict[str, dict[str, float]]
    skipped: tuple[str, ...] = ()
    wall_s: float = 0.0

    @property
    def rows(self) -> list[ProbeRow]:
        """Every row, run by run."""
        return [r for run in self.runs for r in run.rows]

    def failed(self) -> list[ProbeRow]:
        """The rows that did not pass."""
        return [r for r in self.rows if not r.passed]

    def to_json(self) -> dict[str, Any]:
        """``format: tippetop-probe/1``, ``results`` (one object per row) and what ran."""
        return {"format": FORMAT, "results": [r.to_json() for r in self.rows],
                "probes": list(self.probes), "engines": list(self.engines),
                "asked": {"integrator": self.integrator, "timestep_s": self.timestep_s},
                "params": self.params, "skipped": list(self.skipped),
                "runs": [{"probe": r.probe, "mode": r.mode, "engine": r.engine,
                          "ran": r.ran, "engine_ran": r.engine_ran, "cached": r.cached}
                         for r in self.runs],
                "passed": sum(r.passed for r in self.rows), "total": len(self.rows),
                "wall_s": round(self.wall_s, 3)}


def integrator_name(text: str) -> str:
    """The harness's spelling of an integrator (``rk4`` -> ``RK4``).

    Raises:
        TippetopError: Not one of MuJoCo's integrators (one line, with a did-you-mean).
    """
    for name in INTEGRATORS:
        if name.lower() == text.strip().lower():
            return name
    raise TippetopError(f"--integrator: expected one of {', '.join(INTEGRATORS)}, got "
                        f"{text!r}{did_you_mean(text, INTEGRATORS)}")


def _spelled(ran_name: str) -> str:
    """MuJoCo's enum name (``EULER``, ``IMPLICITFAST``) in the harness's spelling."""
    return next((n for n in INTEGRATORS if n.upper() == ran_name.upper()), ran_name)


def probes_for(names: Sequence[str], sets: Sequence[str] = ()) -> list[Probe]:
    """The probes named (all when none), with ``--set KEY=VALUE`` applied.

    ``KEY`` is ``PROBE.PARAM`` (one probe) or ``PARAM`` (every probe named that has it).

    Raises:
        TippetopError: An unknown probe, a malformed or unknown key, a value that is not a
            finite number (one line each).
    """
    chosen = list(names) or list(probe_names())
    classes = [probe_class(n) for n in chosen]
    values: dict[str, dict[str, float]] = {c.name: {} for c in classes}
    for item in sets:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise TippetopError(f"--set: expected KEY=VALUE (such as mu=0.5 or "
                                f"slide-to-roll.v0=2), got {item!r}")
        try:
            value = float(raw)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise TippetopError(f"--set {key}: expected a finite number, got {raw!r}")
        probe, dot, param = key.rpartition(".")
        targets = [c for c in classes if (not dot or c.name == probe) and param in c.params]
        if not targets:
            known = sorted({f"{c.name}.{p}" for c in classes for p in c.params}
                           | {p for c in classes for p in c.params})
            raise TippetopError(f"--set: expected a parameter of the probes run ("
                                f"{', '.join(known)}), got {key!r}{did_you_mean(key, known)}")
        for c in targets:
            values[c.name][param] = value
    return [c(values=values[c.name]) for c in classes]


def check_modes(probes: Sequence[Probe], modes: Sequence[str] | None) -> None:
    """Each mode asked for is a mode of at least one probe run (else one line)."""
    known = sorted({m for p in probes for m in p.modes})
    for m in modes or ():
        if m not in known:
            raise TippetopError(f"--modes: expected modes of the probes run ({', '.join(known)}"
                                f"), got {m!r}{did_you_mean(m, known)}")


def _cache_key(request: dict[str, Any], spec: EngineSpec) -> str:
    from tippetop.compare.running.cache import code_fingerprint

    payload = {"request": request, "code": code_fingerprint(), "kind": "probe"}
    if not spec.in_process:
        payload["engine"] = spec.spec
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:24]


class ProbeCache:
    """One checksummed ``.npz`` and ``.json`` per probe run, under ``root`` (atomic writes).

    An entry that does not verify (cut short, edited) is a miss: the run is made again.
    """

    FORMAT = "tippetop-probe-cache/1"

    def __init__(self, root: Path) -> None:
        self.root = root

    def _paths(self, key: str) -> tuple[Path, Path]:
        return self.root / f"{key}.json", self.root / f"{key}.npz"

    def get(self, key: str) -> Any:
        """The cached :class:`ProbeTrace`, or None."""
        from tippetop.mujoco_runner.probe_run import PROBE_ARRAYS, ProbeTrace

        js, nz = self._paths(key)
        try:
            entry = json.loads(js.read_text("utf-8"))
            data = nz.read_bytes()
        except (OSError, ValueError):
            return None
        if not (isinstance(entry, dict) and entry.get("format") == self.FORMAT
                and entry.get("key") == key
                and entry.get("npz_sha256") == hashlib.sha256(data).hexdigest()):
            return None
        with np.load(io.BytesIO(data)) as z:
            arrays = {k: z[k] for k in z.files}
        if set(PROBE_ARRAYS) - set(arrays):
            return None
        return ProbeTrace(**{k: arrays[k] for k in PROBE_ARRAYS}, ran=entry["ran"],
                          engine=entry["engine"], warning_names=tuple(entry["warning_names"]))

    def put(self, key: str, trace: Any) -> None:
        """Store a run: the arrays, then the entry that vouches for them."""
        from tippetop.compare.running.io import write_atomic
        from tippetop.mujoco_runner.probe_run import PROBE_ARRAYS

        js, nz = self._paths(key)
        js.parent.mkdir(parents=True, exist_ok=True)
        buf = io.BytesIO()
        np.savez(buf, **{k: getattr(trace, k) for k in PROBE_ARRAYS})
        data = buf.getvalue()
        entry = {"format": self.FORMAT, "key": key, "ran": trace.ran, "engine": trace.engine,
                 "warning_names": list(trace.warning_names),
                 "npz_sha256": hashlib.sha256(data).hexdigest()}
        write_atomic(nz, lambda tmp: tmp.write_bytes(data))
        write_atomic(js, lambda tmp: tmp.write_text(json.dumps(entry), "utf-8"))


def _failure(trace: Any) -> str | None:
    """Why a finished run cannot be measured: it diverged, or MuJoCo warned."""
    if not trace.finished:
        return f"diverged: not finite at t = {float(trace.time[-1]):.4g} s"
    counts = np.asarray(trace.warnings)
    if counts.size and counts[-1].any():
        first = int(np.argmax(counts.any(axis=1)))
        names = [trace.warning_names[i] if i < len(trace.warning_names) else str(i)
                 for i in np.flatnonzero(counts[-1])]
        # MuJoCo resets the state (and its clock) on some warnings: the step says when
        dt = float(trace.ran.get("timestep_s", 0.0))
        return (f"MuJoCo warned ({', '.join(names)}) at step {first} (t = {first * dt:.4g} "
                "s): the run is not the model's motion from there")
    return None


def run_one(probe: Probe, mode: str, spec: EngineSpec, *, integrator: str | None,
            timestep_s: float | None, cache: ProbeCache | None,
            python: str | None = None,
            progress: Callable[[float], None] | None = None) -> ProbeRun:
    """Run ``probe`` in ``mode`` on ``spec`` and measure it.

    Raises:
        TippetopError: The engine cannot run it as asked (an integrator that release does
            not have, a worker that cannot start): one line.
    """
    from tippetop.mujoco_runner.probe_run import ProbeRefused, ProbeRequest, run_here, run_in
    from tippetop.mujoco_runner.remote import WorkerFailed

    s = probe.setup(mode)
    req = ProbeRequest(s.mjcf, s.body, s.qpos, s.qvel, s.duration_s,
                       integrator or s.integrator,
                       timestep_s if timestep_s is not None else s.timestep_s, s.ctrl, s.law)
    engine_req = {"implementation": spec.implementation, "precision": spec.precision}
    key = _cache_key(req.as_json(engine_req), spec)
    use = cache is not None and not spec.spec.startswith("mujoco@")
    trace = cache.get(key) if use else None
    cached = trace is not None
    reason: str | None = None
    if trace is None:
        try:
            if spec.in_process:
                trace = run_here(req, progress)
            else:
                from tippetop.compare.running.engines import engine_python

                trace = run_in(python or engine_python(spec), req, engine_req,
                               progress=progress)
        except ProbeRefused as exc:
            if not str(exc).startswith("law:"):
                raise TippetopError(f"engine {spec.spec}: {exc}") from None
            reason = f"not run: {str(exc).removeprefix('law: ')}"
        except WorkerFailed as exc:
            reason = f"the engine failed: {exc}"
        if trace is not None and use:
            cache.put(key, trace)
    asked_integrator = integrator or s.integrator
    asked_dt = timestep_s if timestep_s is not None else s.timestep_s
    if trace is None:
        ran: dict[str, Any] = {}
        engine_ran: dict[str, Any] = {}
        version = spec.version or "?"
        integ, dt = asked_integrator + " (asked)", asked_dt
    else:
        ran, engine_ran = trace.ran, trace.engine
        version = str(engine_ran.get("version", "?"))
        integ, dt = _spelled(str(ran.get("integrator", "?"))), float(ran["timestep_s"])
        reason = _failure(trace)
    wall = float(engine_ran.get("wall_s", 0.0))

    def row(m: Measured, why: str | None) -> ProbeRow:
        q = m.quantity
        value = m.value if why is None else math.nan
        return ProbeRow(probe.name, spec.spec, version, mode, integ, dt, q.name, value,
                        m.exact, q.unit, q.tolerance, why is None and m.passed, why, m.note,
                        wall)

    curve = None
    if trace is not None and reason is None:
        measured = probe.measure(mode, trace)
        rows = tuple(row(m, None) for m in measured)
        curve = probe.curve(mode, trace)
    else:
        nan = math.nan
        rows = tuple(ProbeRow(probe.name, spec.spec, version, mode, integ, dt, q.name, nan,
                              nan, q.unit, q.tolerance, False, reason, "", wall)
                     for q in probe.quantities)
        if trace is not None and len(trace.time) > 1:
            with np.errstate(all="ignore"):
                curve = probe.curve(mode, trace)
    return ProbeRun(probe.name, mode, spec.spec, rows, curve, ran, engine_ran, cached)


def run_probes(names: Sequence[str], engines: Sequence[EngineSpec], *,
               modes: Sequence[str] | None = None, integrator: str | None = None,
               timestep_s: float | None = None, sets: Sequence[str] = (),
               use_cache: bool = True, progress: bool = False) -> ProbeResult:
    """Run each named probe (all when none) in each of its modes (those asked) on each engine.

    Raises:
        TippetopError: Bad input (a probe, mode, parameter, integrator or step), or an engine
            that cannot run it as asked: one line.
    """
    from tippetop.compare.running.cache import default_cache_dir

    t0 = time.perf_counter()
    probes = probes_for(names, sets)
    integ = integrator_name(integrator) if integrator else None
    if timestep_s is not None and not (math.isfinite(timestep_s) and timestep_s > 0):
        raise TippetopError(f"--timestep: expected a positive step in s, got {timestep_s!r}")
    check_modes(probes, modes)
    plan = [(p, m, e) for p in probes for m in p.modes if not modes or m in modes
            for e in engines]
    skipped = tuple(p.name for p in probes if modes and not set(p.modes) & set(modes))
    cache = ProbeCache(default_cache_dir() / "probes") if use_cache else None
    pythons: dict[str, str] = {}
    bar = None
    if progress:
        from tippetop.compare.running.progress import WorkProgress

        bar = WorkProgress("probe", [1.0] * len(plan))
    runs = []
    try:
        for i, (p, m, e) in enumerate(plan):
            if not e.in_process and e.spec not in pythons:
                from tippetop.compare.running.engines import engine_python

                pythons[e.spec] = engine_python(e)
            runs.append(run_one(p, m, e, integrator=integ, timestep_s=timestep_s,
                                cache=cache, python=pythons.get(e.spec)))
            if bar is not None:
                bar.finished(i)
    finally:
        if bar is not None:
            bar.close()
    return ProbeResult(tuple(runs), tuple(p.name for p in probes),
                       tuple(e.spec for e in engines), integ, timestep_s,
                       {p.name: {k: p.p(k) for k in p.params} for p in probes}, skipped,
                       time.perf_counter() - t0)


@dataclass(frozen=True)
class ProbeMove:
    """A probe quantity that differs between two engines beyond its baseline tolerance.

    That tolerance is a tenth of its tolerance against the exact value.
    """

    probe: str
    mode: str
    quantity: str
    engines: tuple[str, str]
    values: tuple[float, float]
    exact: float
    tolerance: float

    def to_json(self) -> dict[str, Any]:
        """The move's keys (non-finite values as null)."""
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {"probe": self.probe, "mode": self.mode, "quantity": self.quantity,
                "metric": metric_name(self.probe, self.quantity),
                "engines": list(self.engines), "values": [num(v) for v in self.values],
                "exact": num(self.exact), "tolerance": self.tolerance,
                "nearer_exact": (self.engines[0] if abs(self.values[0] - self.exact)
                                 <= abs(self.values[1] - self.exact) else self.engines[1])
                if all(math.isfinite(v) for v in self.values) else None}


def probe_moves(res: ProbeResult) -> list[ProbeMove]:
    """The probe quantities that moved between each pair of the result's engines.

    A quantity moves when the two values differ by more than its baseline tolerance (a tenth
    of its tolerance against the exact value), or one of them is missing (a failed run).
    """
    from itertools import combinations

    from tippetop.compare.probes import probe_metric

    by = {(r.probe, r.mode, r.quantity, r.engine): r for r in res.rows}
    keys = list(dict.fromkeys((r.probe, r.mode, r.quantity) for r in res.rows))
    out = []
    for a, b in combinations(res.engines, 2):
        for probe, mode, q in keys:
            ra, rb = by.get((probe, mode, q, a)), by.get((probe, mode, q, b))
            if ra is None or rb is None:
                continue
            tol = probe_metric(metric_name(probe, q)).tolerance
            bound = tol.value if tol is not None else ra.tolerance
            va, vb = ra.value, rb.value
            moved = (math.isfinite(va) != math.isfinite(vb)
                     or (math.isfinite(va) and abs(va - vb) > bound))
            if moved:
                out.append(ProbeMove(probe, mode, q, (a, b), (va, vb), ra.exact, bound))
    return out


__all__ = ["FORMAT", "ROW_KEYS", "ProbeCache", "ProbeMove", "ProbeResult", "ProbeRow", "ProbeRun",
           "check_modes", "integrator_name", "probe_moves", "probes_for", "run_one",
           "run_probes"]
