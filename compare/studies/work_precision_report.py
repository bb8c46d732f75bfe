"""``tippetop bench ode --sweep``: run the sweep on the tops, print the tables, write the figures.

Output folder (default ``./work-precision``; an existing one is replaced only with ``force``,
and nothing is written unless every top completed): ``<top>.png`` per top (error against CPU
time, log-log, one line per solver, a panel per metric), ``work-precision.json`` (what
``--json`` prints) and ``report.txt`` (the printed report).

JSON (``"format": "tippetop-work-precision/1"``): ``tops``, per top ``title``, ``t_end_s``,
``truth`` (the two truths' methods, rtol, values and differences ``theta_diff`` (rad) and
``t_invert_diff`` (s), and ``t_invert_locate_err``, the second truth's estimated error of
locating the inversion from samples), ``solvers`` (per solver its ``kind`` and ``points``: rtol,
atol, s (best CPU time), n_rhs, status, theta_err, t_invert_err, J_drift), ``skipped`` (solver:
why) and ``levels`` (per metric its unit, levels and ``rows``: ``times`` per solver (s or null:
not reached), ``smallest`` (the smallest error of those that do not reach it), ``best_reference``,
``best_peer``, ``ratio`` (the fastest peer's time over the fastest reference method's; "inf":
no peer reaches it) and ``ratio_auto`` (over ``auto``'s), ``met`` and ``met_auto`` (>= 1.2)).
"""

from __future__ import annotations

import json
import math
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path
from typing import Any

from tippetop.compare.presentation.bench import METRIC_TITLES, work_precision_report
from tippetop.compare.results.work_precision import (
    TARGET_RATIO,
    WorkPrecisionResult,
    WorkPrecisionTop,
)
from tippetop.compare.running.io import json_ready
from tippetop.compare.studies.frontier import ERROR_FLOOR
from tippetop.compare.studies.peer_runs import PEERS
from tippetop.compare.studies.work_precision import (
    SHORT_ROUNDS,
    SHORT_S,
    TOLERANCES,
    TOPS,
    make_top,
    reference_methods,
    sweep_top,
)
from tippetop.models.errors import TippetopError

DEFAULT_OUT = "work-precision"


def parse_tops(text: str) -> list[str]:
    """``--tops``: comma-separated names from :data:`TOPS` (TippetopError otherwise)."""
    names = [s.strip() for s in text.split(",") if s.strip()]
    bad = [n for n in names if n not in TOPS]
    if not names or bad:
        raise TippetopError(f"--tops: expected comma-separated names from {', '.join(TOPS)}, "
                            f"got {text!r}")
    return list(dict.fromkeys(names))


def check_out(out: str | Path, force: bool) -> Path:
    """The output folder, refused (before any work) if it exists and ``force`` is not set."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise TippetopError(f"--out: expected a folder, got the file {str(path)!r}")
    if path.exists() and not force:
        raise TippetopError(f"--out: expected a folder that does not exist yet (or --force to "
                            f"replace it), got {str(path)!r}")
    return path


def plot_top(res: WorkPrecisionTop, path: Path) -> None:
    """The top's figure: error against CPU time per metric, one line per solver."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = list(res.levels)
    fig, axes = plt.subplots(1, len(metrics), figsize=(5.2 * len(metrics), 4.4), squeeze=False)
    keys = {"theta": "theta_err", "t_invert": "t_invert_err", "J_drift": "J_drift"}
    colors = plt.get_cmap("tab20").colors  # one colour per solver, the same in every panel
    for ax, metric in zip(axes[0], metrics, strict=True):
        for i, (name, sv) in enumerate(res.solvers.items()):
            pts = sorted((p["rtol"], p["s"], p[keys[metric]]) for p in sv["points"]
                         if p["status"] == "ok" and p[keys[metric]] is not None
                         and math.isfinite(p[keys[metric]]))
            if not pts:
                continue
            ref = sv["kind"] == "reference"
            ax.loglog([p[1] for p in pts], [max(p[2], ERROR_FLOOR) for p in pts],
                      "-o" if ref else "--s", lw=2.0 if ref else 1.2, ms=3.5, label=name,
                      color=colors[(2 * i) % 20 if i < 10 else (2 * i + 1) % 20])
        for level in res.levels[metric]["levels"]:
            ax.axhline(level, color="0.8", lw=0.6, ls=":")
        ax.set_xlabel("CPU time (s), best of the rounds")
        ax.set_ylabel(METRIC_TITLES[metric])
        ax.grid(True, which="major", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"work-precision: {res.title}, {res.t_end_s:g} s", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def slow_peers() -> dict[str, tuple[int, float]]:
    """Per Python-driven peer, the tolerances of the full sweep it runs and its budget (s).

    The report says a slow peer with fewer points stopped over its budget.
    """
    return {n: (len(p.tolerances(TOLERANCES)), p.budget_s) for n, p in PEERS.items()
            if p.slow}


def run_work_precision(tops: Sequence[str], out: str | Path = DEFAULT_OUT, *,
                       rounds: int = 3, force: bool = False, t_end_s: float | None = None,
                       tolerances: Sequence[float] = TOLERANCES,
                       peers: Sequence[str] | None = None, write: bool = True
                       ) -> WorkPrecisionResult:
    """The benchmark on ``tops``: their sweeps, report and figures (all-or-nothing).

    Args:
        tops: Names from :data:`TOPS`.
        out: Output folder (refused if it exists, unless ``force``).
        rounds: Rounds of the compiled solvers (the Python-driven peers run one).
        force: Replace an existing ``out``.
        t_end_s: Cut every top to this time (s; tests); None: each top's own.
        tolerances: The sweep's rtol values.
        peers: Peer names; None: every available one.
        write: Write the folder (False: compute only).

    Returns:
        The benchmark: its ``to_json()`` is the JSON object (``tippetop-work-precision/1``),
        its printed text :func:`presentation.bench.work_precision_report` with
        :func:`slow_peers`.
    """
    names = [n for n in tops]
    for n in names:
        if n not in TOPS:
            raise TippetopError(f"--tops: expected names from {', '.join(TOPS)}, got {n!r}")
    if rounds < 1:
        raise TippetopError(f"--rounds: expected an integer >= 1, got {rounds}")
    path = check_out(out, force) if write else None
    t_start = time.perf_counter()
    results: dict[str, WorkPrecisionTop] = {}
    _, skipped = reference_methods()
    top_objs = [make_top(n, t_end_s) for n in names]
    bar = _bar()
    with bar as b:
        for top in top_objs:
            results[top.name] = sweep_top(top, rounds=rounds, tolerances=tolerances, peers=peers,
                                          tick=(lambda: b.update(1)) if b is not None else None,
                                          expect=_more(b) if b is not None else None)
    elapsed = time.perf_counter() - t_start
    _inf_as_text(results)
    res = WorkPrecisionResult(
        rounds=rounds, short_rounds=rounds * SHORT_ROUNDS, short_s=SHORT_S,
        timing="CPU time (time.process_time), best of the rounds (short_rounds for a compiled "
        "solver's point under short_s)",
        tolerances=tuple(tolerances), atol_per_rtol=1e-3, target_ratio=TARGET_RATIO,
        skipped_methods=skipped, tops=results, elapsed_s=elapsed)
    if path is not None:
        _write(path, res, force)
        res = replace(res, out=str(path))
    return res


def _bar():
    if not sys.stderr.isatty():
        return nullcontext(None)
    from tqdm import tqdm

    return tqdm(total=0, desc="work-precision runs", unit="run", leave=False)


def _more(bar: Any) -> Callable[[int], None]:
    """A sweep's ``expect``: the bar's total grows (or shrinks) by the runs it plans."""

    def more(k: int) -> None:
        bar.total += k
        bar.refresh()

    return more


def _write(path: Path, res: WorkPrecisionResult, force: bool) -> None:
    """Write everything to a temporary folder beside ``path``, then move it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        for name, top in res.tops.items():
            plot_top(top, tmp / f"{name}.png")
        (tmp / "work-precision.json").write_text(json.dumps(json_ready(res.to_json()),
                                                            indent=1))
        (tmp / "report.txt").write_text(work_precision_report(res, slow_peers()) + "\n")
        if path.exists():
            if not force:  # pragma: no cover - checked before the work
                raise TippetopError(f"--out: {str(path)!r} appeared during the run")
            shutil.rmtree(path)
        tmp.rename(path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _inf_as_text(results: dict[str, WorkPrecisionTop]) -> None:
    """A ratio of inf (no peer reaches the level) as the string ``"inf"`` in the JSON."""
    for res in results.values():
        for lv in res.levels.values():
            for row in lv["rows"]:
                for k in ("ratio", "ratio_auto"):
                    if row[k] is not None and math.isinf(row[k]):
                        row[k] = "inf"


def main(argv: list[str] | None = None) -> int:
    """``python -m tippetop.compare.studies.work_precision_report RESULTS.json TOP OUT.png``.

    One top's figure again, drawn from a sweep's work-precision.json (``tippetop bench ode
    --sweep --out DIR`` writes one; the docs draw today's from docs/data/work-precision.json).
    """
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3 or not args[2].endswith(".png"):
        print("work-precision figure: expected RESULTS.json TOP OUT.png, got "
              + (" ".join(args) or "nothing"), file=sys.stderr)
        return 2
    try:
        tops = WorkPrecisionResult.from_json(
            json.loads(Path(args[0]).read_text(encoding="utf-8"))).tops
    except (OSError, ValueError, KeyError, TypeError, AttributeError, TippetopError) as exc:
        print(f"work-precision figure: expected a sweep's work-precision.json, got {args[0]} "
              f"({exc.__class__.__name__}: {exc})", file=sys.stderr)
        return 2
    if args[1] not in tops:
        print(f"work-precision figure: expected a top of {args[0]} ({', '.join(tops)}), got "
              f"{args[1]!r}", file=sys.stderr)
        return 2
    plot_top(tops[args[1]], Path(args[2]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
