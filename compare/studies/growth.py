"""Critical spins from growth rates: the spin where a steady state's tilt stops decaying.

Short runs near the upright or inverted state, a matrix-pencil fit of the symmetry axis's
motion, and a secant search on the fitted growth rate; the method is in docs/design.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.measures import theory
from tippetop.compare.measures.summary import run_failed
from tippetop.compare.results.threshold import FailedRun, ThresholdResult
from tippetop.compare.running.options import DEFAULT_RUN, RunOptions
from tippetop.compare.running.runner import Task, run_tasks
from tippetop.models.errors import TippetopError
from tippetop.models.params import TopParams
from tippetop.models.scene import Override

WHICH = ("n1", "n4", "nc")
#: Initial tilt from the steady state (rad): linear, yet well above MuJoCo's contact jitter.
TILT_RAD = 0.01
#: Length of each growth-rate run (s), and the start left out of the fit (s).
RUN_S = 2.0
SKIP_S = 0.1
#: Samples of z(t) the pencil uses, and the number of modes fitted.
FIT_POINTS = 600
FIT_MODES = 2
#: Columns of the Hankel matrix (the pencil's lag).
FIT_LAG = 100
#: A fit is clean when the first singular value left out is below this fraction of the
#: largest: two modes describe the run (measured 3e-6 in the reference, 7e-6 in MuJoCo).
CLEAN_FIT = 1e-3
#: Default relative tolerance on the threshold (the secant steps).
REL_TOL = 1e-5
#: A bracket wider than this ratio is bisected geometrically before false position starts.
WIDE_BRACKET = 1.25
#: Spins scanned (rad/s) when the theory has no value to start from (Group I's n1, III's n4).
SCAN_SPINS = (5.0, 15.0, 40.0, 100.0, 250.0, 600.0)


def tilt_signal(table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Times and ``z = k_x + i k_y``, the symmetry axis' horizontal components.

    From the orientation quaternion (body to world) that every engine records.
    """
    qw, qx, qy, qz = (table[c].to_numpy(dtype=float) for c in ("qw", "qx", "qy", "qz"))
    z = 2.0 * (qx * qz + qw * qy) + 1j * 2.0 * (qy * qz - qw * qx)
    return table["t"].to_numpy(dtype=float), z


def _pencil(z: np.ndarray, dt: float, modes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Matrix-pencil fit of ``z_k = sum_j A_j exp(p_j k dt)``.

    Returns the poles, the amplitudes and the singular values of the Hankel matrix.
    """
    n = len(z)
    lag = min(n // 3, FIT_LAG)
    hankel = np.lib.stride_tricks.sliding_window_view(z, lag + 1)
    # the right singular vectors from the small Gram matrix (lag+1 square): milliseconds,
    # where a full SVD of the Hankel matrix costs a second and more under a threaded BLAS
    gram = hankel.conj().T @ hankel
    w, vecs = np.linalg.eigh(gram)
    order = np.argsort(w)[::-1]
    sv = np.sqrt(np.clip(w[order], 0.0, None))
    v = vecs[:, order[:modes]].conj()  # the shifts of z are spanned by conj(V)
    lam = np.linalg.eigvals(np.linalg.pinv(v[:-1]) @ v[1:])
    poles = np.log(lam.astype(complex)) / dt
    basis = np.power.outer(lam, np.arange(n)).T
    amps = np.linalg.lstsq(basis, z, rcond=None)[0]
    return poles, amps, sv


def growth_fit(table: pd.DataFrame, skip_s: float = SKIP_S,
               modes: int = FIT_MODES) -> dict[str, Any]:
    """The growth rate of a run started near a steady state.

    Returns:
        ``rate_per_s`` (the largest real part of the fitted exponents, 1/s), ``modes`` (each
        ``{rate_per_s, omega_rad_s, amplitude}``), ``residual`` (the first singular value left
        out over the largest) and ``clean`` (``residual < CLEAN_FIT``).
    """
    t, z = tilt_signal(table)
    keep = t >= t[0] + skip_s
    t, z = t[keep], z[keep]
    if len(t) < 8 * modes or not np.all(np.isfinite(z)):
        raise TippetopError(f"growth rate: expected a finite run of at least {8 * modes} "
                            f"samples after {skip_s:g} s, got {len(t)}")
    step = max(1, len(t) // FIT_POINTS)
    z = z[::step]
    poles, amps, sv = _pencil(z, float(t[step] - t[0]), modes)
    residual = float(sv[modes] / sv[0]) if len(sv) > modes and sv[0] > 0 else 0.0
    order = np.argsort(-np.abs(amps))
    return {
        "rate_per_s": float(np.max(poles.real)),
        "modes": [{"rate_per_s": float(poles[i].real), "omega_rad_s": float(poles[i].imag),
                   "amplitude": float(abs(amps[i]))} for i in order],
        "residual": residual,
        "clean": residual < CLEAN_FIT,
    }


def state_overrides(state: str, n: float, run_s: float = RUN_S) -> tuple[Override, ...]:
    """Scene overrides for a run started ``TILT_RAD`` from the upright or inverted state."""
    theta0 = TILT_RAD if state == "upright" else math.pi - TILT_RAD
    return (Override.of("init.theta0", theta0), Override.of("init.thetadot0", 0.0),
            Override.of("init.Omega0", 0.0), Override.of("init.n0", n),
            Override.of("init.uOX", 0.0), Override.of("init.uOY", 0.0),
            Override.of("run.t_end_s", run_s))


def jellett_pi_to_zero(top: TopParams, n_pi: float) -> float:
    """The spin at ``theta = 0`` with the same Jellett constant as ``n_pi`` at ``theta = pi``."""
    return abs(n_pi) * (top.R_m + top.a_m) / (top.R_m - top.a_m)


RootSteps = Generator[list[float], list[float], tuple[float | None, list[float]]]


def _root_steps(start: tuple[float, float] | None, rel_tol: float, max_runs: int) -> RootSteps:
    """The spin where the rate changes sign, as a coroutine.

    It yields the spins it needs, is sent their rates, and returns (the root or None, the
    final bracket). A bracket around ``start`` (widened if its ends agree) or a scan of
    ``SCAN_SPINS``, then Illinois false position until a step is below ``rel_tol`` of the
    root.
    """
    if start is not None:
        lo, hi = start
        r_lo, r_hi = yield [lo, hi]
        for _ in range(4):  # widen until the ends disagree
            if r_lo * r_hi < 0:
                break
            lo, hi = lo * 0.6, hi * 1.6
            r_lo, r_hi = yield [lo, hi]
        else:
            start = None
    if start is None:
        spins = list(SCAN_SPINS)
        rs = yield spins
        pairs = [(spins[i], spins[i + 1], rs[i], rs[i + 1]) for i in range(len(spins) - 1)
                 if rs[i] * rs[i + 1] < 0]
        if not pairs:
            return None, [spins[0], spins[-1]]
        lo, hi, r_lo, r_hi = pairs[0]
    side, prev = 0, None
    for _ in range(max_runs):
        root = lo - r_lo * (hi - lo) / (r_hi - r_lo)
        if hi > WIDE_BRACKET * lo:  # a scan's wide bracket: halve it geometrically first
            root, side = math.sqrt(lo * hi), 0
        elif prev is not None and abs(root - prev) <= rel_tol * root:
            break
        prev = root
        (r,) = yield [root]
        if r == 0.0:
            return root, [root, root]
        if r * r_lo > 0:  # Illinois: halve the far end's value when one side repeats
            lo, r_lo = root, r
            if side == -1:
                r_hi *= 0.5
            side = -1
        else:
            hi, r_hi = root, r
            if side == 1:
                r_lo *= 0.5
            side = 1
    else:
        root = lo - r_lo * (hi - lo) / (r_hi - r_lo)
    return root, [lo, hi]


@dataclass
class Search:
    """The growth-rate zero of one steady state of one top in one engine.

    Attributes:
        scene: Scene name or file.
        engine: ``ode``, ``mujoco`` or a mode name.
        overrides: Scene overrides (the top, the engine's settings).
        state: ``upright`` or ``inverted``.
        start: A first bracket for the spin at the state (rad/s), or None to scan.
        rel_tol: Relative tolerance of the false-position steps.
        max_runs: False-position steps at most.
        run_s: Length of each run (s).
    """

    scene: str | None
    engine: str
    overrides: tuple[Override | str, ...]
    state: str
    start: tuple[float, float] | None
    rel_tol: float = REL_TOL
    max_runs: int = 12
    run_s: float = RUN_S
    mode: str | None = None
    points: dict[float, dict[str, Any]] = field(default_factory=dict)
    root: float | None = None
    bracket: list[float] = field(default_factory=list)
    done: bool = False
    failed: str | None = None

    def task(self, n: float) -> Task:
        """The run at spin ``n`` near the state."""
        return Task(self.scene, (*self.overrides, *state_overrides(self.state, n, self.run_s)),
                    self.engine, self.mode)


def run_searches(searches: list[Search], run: Callable[[list[Task]], list[Any]]) -> None:
    """Advance every search together: each round runs what all of them need in one batch."""
    steps: dict[int, RootSteps] = {}
    wanted: dict[int, list[float]] = {}
    for i, s in enumerate(searches):
        steps[i] = _root_steps(s.start, s.rel_tol, s.max_runs)
        wanted[i] = next(steps[i])
    while wanted:
        batch: list[tuple[int, float]] = [(i, n) for i, spins in wanted.items()
                                          for n in dict.fromkeys(spins)
                                          if n not in searches[i].points]
        results = run([searches[i].task(n) for i, n in batch]) if batch else []
        for (i, n), res in zip(batch, results, strict=True):
            s = searches[i]
            if res.error:
                raise TippetopError(f"growth rate at n0 = {n:.6g} rad/s: {res.error}")
            if run_failed(res.summary):  # kept as a failed point; its search stops there
                s.failed = (f"the {s.state} run at n0 = {n:.6g} rad/s failed: "
                            f"{res.summary.get('message') or res.summary.get('status')}")
                s.points[n] = {"n0": n, "state": s.state, "rate_per_s": math.nan,
                               "modes": [], "residual": math.nan, "clean": False,
                               "failed": s.failed, "wall_s": res.summary.get("wall_s")}
                continue
            s.points[n] = {"n0": n, "state": s.state, **growth_fit(res.table),
                           "wall_s": res.summary.get("wall_s")}
        for i in list(wanted):
            s = searches[i]
            if s.failed is not None:
                s.root, s.bracket, s.done = None, [], True
                del wanted[i]
                continue
            try:
                wanted[i] = steps[i].send([s.points[n]["rate_per_s"] for n in wanted[i]])
            except StopIteration as stop:
                s.root, s.bracket = stop.value
                s.done = True
                del wanted[i]


def settled(points: list[dict[str, Any]], roots: list[float | None],
            near: float = 0.1) -> bool:
    """Whether every fit within ``near`` (relative) of a root found is clean.

    Far from a threshold a state grows or decays fast and its tilt leaves the linear range
    within the run (a worse fit, the sign still plain); the answer rests on the runs near it.
    """
    found = [r for r in roots if r is not None]
    return all(p["clean"] for p in points
               if any(abs(p["n0"] / r - 1.0) <= near for r in found))


def state_start(top: TopParams, state: str) -> tuple[float, float] | None:
    """A first bracket for a state's critical spin: the theory's value +- 10 %, if it has one.

    Only a starting point: the bracket is widened, or the spins scanned, until the measured
    rates change sign.
    """
    guess = theory.n1(top) if state == "upright" else theory.n3(top)
    return (0.9 * guess, 1.1 * guess) if guess else None


@dataclass(frozen=True)
class GrowthOptions:
    """How finely :func:`measure_growth` searches; the defaults are ``tippetop threshold``'s.

    Attributes:
        rel_tol: Relative tolerance of the false-position steps on the spin.
        run_s: Length of each growth-rate run (s).
        max_runs: False-position steps at most, per steady state.
    """

    rel_tol: float = REL_TOL
    run_s: float = RUN_S
    max_runs: int = 12


def measure_growth(scene: str | None, engine: str, which: str,
                   overrides: tuple[Override | str, ...] = (), *,
                   search: GrowthOptions = GrowthOptions(),
                   run: RunOptions = DEFAULT_RUN,
                   label: str = "growth rates", mode: str | None = None) -> ThresholdResult:
    """Measure ``n1``, ``n4`` or ``nc`` of a scene's top on ``engine`` from growth rates.

    ``engine``: :mod:`tippetop.models.engines`; ``mode``: :mod:`tippetop.models.modes` (None:
    the scene's). ``search``: the tolerance, run length and step cap (:class:`GrowthOptions`);
    ``run``: where the runs run (``scheduler``, ``workers``, ``use_cache`` of
    :class:`~tippetop.compare.running.options.RunOptions`; the runner's bar shows on a
    terminal); ``label``: the progress bar's.

    Returns:
        The threshold of :func:`tippetop.compare.studies.threshold.measure_threshold`
        (:class:`~tippetop.compare.results.threshold.ThresholdResult`: ``which, engine, mode,
        scene, measured, theory, rel_diff, bracket, runs, n_runs, horizon_s, converged``)
        with ``method`` "growth", ``rates`` (each ``{n0, state, rate_per_s}``), ``settled``
        (every fit clean: two modes describe every run), and ``n1``/``n4`` (each measured or
        None) and ``n3`` (the inverted state's spin).
    """
    if which not in WHICH:
        raise TippetopError(f"--which: expected one of {', '.join(WHICH)}, got {which!r}")
    task = Task(scene or "fig11_n060", overrides, engine, mode)
    scene_obj = task.load()
    plan = task.plan(scene_obj)  # the engine and mode are checked here, before any run
    engine, mode, top = plan.engine, plan.mode, plan.top
    th_value = {"n1": theory.n1, "n4": theory.n4, "nc": theory.n_c}[which](top)
    if which == "nc" and th_value is None:
        raise TippetopError(f"--which: nc exists for Group II tops only, got a Group "
                            f"{theory.group(top)} top")

    def run_batch(tasks: list[Task]) -> list[Any]:
        return list(run_tasks(tasks, scheduler=run.scheduler, workers=run.workers,
                              use_cache=run.use_cache, label=label))

    states = {"n1": ("upright",), "n4": ("inverted",), "nc": ("upright", "inverted")}[which]
    searches = {state: Search(task.scene, engine, overrides, state, state_start(top, state),
                              search.rel_tol, search.max_runs, search.run_s, mode)
                for state in states}
    run_searches(list(searches.values()), run_batch)
    found = {state: s.root for state, s in searches.items()}
    brackets = {state: s.bracket for state, s in searches.items()}
    n1 = found.get("upright")
    n3 = found.get("inverted")
    n4 = jellett_pi_to_zero(top, n3) if n3 is not None else None
    if which == "n1":
        measured, bracket = n1, brackets["upright"]
    elif which == "n4":
        measured = n4
        bracket = [jellett_pi_to_zero(top, b) for b in brackets["inverted"]]
    else:
        measured = max(n1, n4) if n1 is not None and n4 is not None else None
        bracket = (brackets["upright"] if measured == n1 else
                   [jellett_pi_to_zero(top, b) for b in brackets["inverted"]])
    points = [p for sr in searches.values() for p in sr.points.values()]
    points.sort(key=lambda p: (p["state"], p["n0"]))
    out = ThresholdResult(
        which=which, engine=engine, mode=mode, scene=scene_obj.name, method="growth",
        measured=measured, theory=th_value,
        rel_diff=(measured / th_value - 1.0) if measured and th_value else None,
        bracket=tuple(bracket),
        runs=tuple({"n0": p["n0"], "state": p["state"], "rate_per_s": p["rate_per_s"],
                    "crossed": (p["rate_per_s"] > 0) == (p["state"] == "upright"),
                    "clean": p["clean"], "residual": p["residual"], "modes": p["modes"],
                    **({"failed": p["failed"]} if p.get("failed") else {})}
                   for p in points),
        horizon_s=search.run_s,
        settled=settled(points, [n1, n3]),
        converged=measured is not None and settled(points, [n1, n3]),
        n1=n1, n3=n3, n4=n4)
    failures = [sr.failed for sr in searches.values() if sr.failed is not None]
    if failures:
        return replace(out, measured=None, converged=False, rel_diff=None, settled=False,
                       failed_runs=tuple(FailedRun(p["n0"], p["failed"], p["state"])
                                         for p in points if p.get("failed")),
                       warning="; ".join(failures) + " (the runs before it are kept)")
    if measured is None:
        return replace(out, warning=(
            f"no sign change of the growth rate found for {which}: the "
            f"{'upright' if which == 'n1' else 'inverted'} state is "
            f"{'stable' if which == 'n1' else 'unstable'} at every spin tried "
            f"({', '.join(f'{n:g}' for n in SCAN_SPINS)} rad/s)"))
    return out
