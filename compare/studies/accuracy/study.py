"""``tippetop bench accuracy``: both engines' work-precision study, written to a folder."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from tippetop.compare.results.accuracy import (
    AccuracyReference,
    AccuracyResult,
    EngineOutput,
    ParetoEntry,
)
from tippetop.compare.running.io import check_writable, hold_output_lock, write_atomic
from tippetop.compare.running.options import DEFAULT_RUN, RunOptions
from tippetop.compare.studies.accuracy.common import (
    DEFAULT_THRESHOLDS,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_SKIPPED,
    cut_scene,
    reference_run,
)
from tippetop.compare.studies.accuracy.figures import (
    mujoco_work_precision_figure,
    work_precision_figure,
)
from tippetop.compare.studies.accuracy.mujoco_study import (
    DEFAULT_INTEGRATORS,
    DEFAULT_MODES,
    DEFAULT_MUJOCO_BUDGET_S,
    DEFAULT_TIMESTEPS,
    check_mujoco_args,
    mujoco_frame,
    mujoco_rows,
)
from tippetop.compare.studies.accuracy.ode_study import (
    DEFAULT_BUDGET_S,
    DEFAULT_TOLERANCES,
    STIFF_LAMBDA_MPS,
    STIFF_SCENE,
    ode_work_precision,
    stiff_scene,
    stiff_work_precision,
)
from tippetop.compare.studies.accuracy.pareto import (
    mujoco_pareto_markdown,
    pareto_markdown,
    pareto_table,
)
from tippetop.models.engines import FAMILIES
from tippetop.models.errors import TippetopError, expect
from tippetop.models.scene import Scene


@dataclass(frozen=True)
class OdeGrid:
    """The reference ODE's points of the study; the defaults are ``tippetop bench accuracy``'s.

    Attributes:
        tolerances: The rtol ladder.
        methods: The methods run (None: ``default_methods()``, with numbalsoda's DOP853 and
            LSODA when it is installed).
        budget_s: Per-point wall-time budget (s).
        stiff: Also the stiff case on its own frontier: Fig. 3 at Lambda = 1e-6 m/s
            (:func:`stiff_work_precision`: the reference with its rolling phases and the law
            throughout, scored against the law at rtol 1e-11), written as
            ``accuracy_ode_stiff.csv``, ``accuracy_ode_<scene>_Lambda1e-06.png`` and
            ``pareto_ode_stiff.md`` (``stiff`` in the returned ``engines``).
    """

    tolerances: Sequence[float] = DEFAULT_TOLERANCES
    methods: Sequence[str] | None = None
    budget_s: float = DEFAULT_BUDGET_S
    stiff: bool = True


@dataclass(frozen=True)
class MujocoGrid:
    """MuJoCo's points of the study; the defaults are ``tippetop bench accuracy``'s.

    Attributes:
        integrators: The integrators.
        timesteps: The timesteps (s).
        modes: The friction modes.
        budget_s: Per-point wall-time budget (s).
    """

    integrators: Sequence[str] = DEFAULT_INTEGRATORS
    timesteps: Sequence[float] = DEFAULT_TIMESTEPS
    modes: Sequence[str] = DEFAULT_MODES
    budget_s: float = DEFAULT_MUJOCO_BUDGET_S


@dataclass(frozen=True)
class _Gathered:
    """What the engines' studies wrote and found, gathered as each engine finishes."""

    references: dict[str, dict] = field(default_factory=dict)
    per_engine: dict[str, dict[str, Any]] = field(default_factory=dict)
    entries: list[dict[str, Any]] = field(default_factory=list)
    report: list[str] = field(default_factory=list)
    frames: list[pd.DataFrame] = field(default_factory=list)


def _check_engines(engines: Sequence[str] | str) -> tuple[str, ...]:
    """The engines asked for, each once, in order; a TippetopError for an unknown one."""
    if isinstance(engines, str):
        engines = tuple(e.strip() for e in engines.split(","))
    engines = tuple(dict.fromkeys(engines))
    expect(len(engines) > 0, "--engines", "ode and/or mujoco", list(engines))
    for e in engines:
        expect(e in FAMILIES, "--engines",
               f"a comma-separated list of {', '.join(FAMILIES)}", e)
    return engines


def _output_files(out: Path, engines: tuple[str, ...], scenes: list[Scene], stiff: bool,
                  t_end_s: float | None) -> dict[str, tuple[Path, Path, list[Path]]]:
    """Each engine's CSV, Pareto table and figures in ``out`` (the stiff case's too)."""
    files = {e: (out / f"accuracy_{e}.csv", out / f"pareto_{e}.md",
                 [out / f"accuracy_{e}_{s.name}.png" for s in scenes]) for e in engines}
    if stiff and "ode" in engines:
        hard = stiff_scene(STIFF_SCENE, STIFF_LAMBDA_MPS, t_end_s)
        files["stiff"] = (out / "accuracy_ode_stiff.csv", out / "pareto_ode_stiff.md",
                          [out / f"accuracy_ode_{hard.name}.png"])
    return files


def _claim_output(out: Path, files: dict[str, tuple[Path, Path, list[Path]]],
                  force: bool) -> None:
    """Checks that the outputs may be written, then locks and creates the folder ``out``."""
    for csv_p, md_p, figs in files.values():
        for p in [csv_p, md_p, *figs]:
            if p.exists() and not force:
                raise TippetopError(f"--out: expected a folder without {p.name} (or --force to "
                                    f"overwrite), got existing {str(p)!r}")
    base = out if out.is_dir() else out.parent
    if not base.is_dir():
        raise TippetopError(f"--out: expected an existing parent folder, got {str(base)!r}")
    check_writable(base)  # before the runs, not after them
    hold_output_lock(out)  # a second study into it is refused now
    out.mkdir(parents=True, exist_ok=True)


def _engine_counts(all_df: pd.DataFrame) -> dict[str, int]:
    """An engine's points by outcome: all, ok, skipped, diverged and failed."""
    status = all_df["status"]
    n_ok = int((status == STATUS_OK).sum())
    n_skipped = int((status == STATUS_SKIPPED).sum())
    n_div = int(status.str.startswith(STATUS_DIVERGED).sum())
    return {"n_points": len(all_df), "n_ok": n_ok, "n_skipped": n_skipped,
            "n_diverged": n_div, "n_failed": len(all_df) - n_ok - n_skipped - n_div}


def _finish(done: _Gathered, engine: str, dfs: list[pd.DataFrame],
            paths: tuple[Path, Path, list[Path]], thresholds: Sequence[float]) -> None:
    """Writes one engine's figures, CSV and Pareto table, and gathers its results."""
    csv_path, md_path, fig_paths = paths
    references = done.references
    for df, fig_path in zip(dfs, fig_paths, strict=True):
        references[str(df["scene"].iloc[0])] = df.attrs["reference"]
        if engine in ("ode", "stiff"):
            work_precision_figure(df, fig_path)
        else:
            mujoco_work_precision_figure(df, fig_path)
    all_df = pd.concat(dfs, ignore_index=True)
    all_df.attrs = {}
    entries = pareto_table(all_df, thresholds)
    write_atomic(csv_path, lambda tmp: all_df.to_csv(tmp, index=False, float_format="%.6g"))
    md = (pareto_markdown(entries, references) if engine in ("ode", "stiff")
          else mujoco_pareto_markdown(entries, references, all_df))
    write_atomic(md_path, lambda tmp: tmp.write_text(md + "\n"))
    done.per_engine[engine] = {
        "csv": str(csv_path), "figures": [str(p) for p in fig_paths],
        "pareto_md": str(md_path), **_engine_counts(all_df)}
    done.entries.extend(entries)
    done.frames.append(all_df)
    done.report.append(f"wrote {csv_path}, {md_path} and {len(fig_paths)} figure(s)")
    tag = "" if engine in ("ode", "stiff") else f" [{engine}]"
    done.report.extend(f"{e['scene']}{tag}: {e['text']}" for e in entries)


def _summary(done: _Gathered, engines: tuple[str, ...]) -> AccuracyResult:
    """The study's result: the first engine's files, every engine's figures, the totals."""
    first = done.per_engine[engines[0]]
    status = pd.concat(done.frames, ignore_index=True)["status"]
    n_ok = int((status == STATUS_OK).sum())
    n_skipped = int((status == STATUS_SKIPPED).sum())
    return AccuracyResult(
        csv=first["csv"],
        figures=tuple(f for e in engines for f in done.per_engine[e]["figures"]),
        pareto_md=first["pareto_md"],
        references={k: AccuracyReference.from_json(r) for k, r in done.references.items()},
        pareto=tuple(ParetoEntry.from_json(e) for e in done.entries),
        n_points=len(status), n_ok=n_ok, n_skipped=n_skipped,
        n_failed=len(status) - n_ok - n_skipped,
        engines={k: EngineOutput.from_json(e) for k, e in done.per_engine.items()},
        report="\n".join(done.report),
    )


def run_accuracy(
    scene_names: Sequence[str] = ("fig3", "fig11_n060"),
    out_dir: str | Path = ".",
    *,
    engines: Sequence[str] = ("ode",),
    ode: OdeGrid = OdeGrid(),
    mujoco: MujocoGrid = MujocoGrid(),
    thresholds: Sequence[float] = DEFAULT_THRESHOLDS,
    t_end_s: float | None = None,
    force: bool = False,
    run: RunOptions = DEFAULT_RUN,
    log: Callable[[str], None] | None = None,
) -> AccuracyResult:
    """Work-precision study; writes the CSV, the figures and the table of each engine.

    Files (each written atomically into ``out_dir``), per engine in ``engines``: ODE
    ``accuracy_ode.csv`` (every point), ``accuracy_ode_<scene>.png`` (one per scene) and
    ``pareto_ode.md``; MuJoCo ``accuracy_mujoco.csv``, ``accuracy_mujoco_<scene>.png`` and
    ``pareto_mujoco.md``. Both engines are scored against one :func:`reference_run` per scene.
    The ODE points run in this process, one at a time (their timings are sub-second); then the
    MuJoCo series run on ``run.workers`` processes.

    Args:
        scene_names: Scene files or catalogue names.
        out_dir: An existing folder (created if missing).
        engines: ``ode`` and/or ``mujoco`` (default: the ODE only, as before the MuJoCo half;
            the command line runs both).
        ode: The ODE's rtol ladder, methods, budget and stiff case (:class:`OdeGrid`).
        mujoco: MuJoCo's integrators, timesteps, modes and budget (:class:`MujocoGrid`).
        thresholds: Pareto thresholds on max |theta error| (rad).
        t_end_s: Cut every scene's run to this time (s); None keeps each scene's.
        force: Overwrite existing output files.
        run: Its ``workers``: processes for the MuJoCo series (None: all cores). The points
            are timed, so they run on this machine and are never cached: the other fields are
            not read.
        log: Called with one line per finished point.

    Returns:
        The study (:class:`AccuracyResult`): ``csv``, ``pareto_md`` (the ODE's when it ran,
        else MuJoCo's), ``figures`` (all), ``references`` (per scene), ``pareto`` (the
        :func:`pareto_table` entries of every engine), ``n_points``, ``n_ok``, ``n_skipped``,
        ``n_failed`` (totals; diverged MuJoCo points count as failed), ``engines`` (per
        engine: ``csv``, ``figures``, ``pareto_md``, ``n_points``, ``n_ok``, ``n_skipped``,
        ``n_diverged``, ``n_failed``) and a printable ``report``.

    Raises:
        TippetopError: bad scene or engine, an existing output without ``force``, or a
            reference run that does not complete.
    """
    if isinstance(scene_names, str):
        scene_names = (scene_names,)
    engines = _check_engines(engines)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise TippetopError(f"--out: expected a folder, got the file {str(out_dir)!r}")
    scenes = [cut_scene(name, t_end_s) for name in scene_names]
    expect(len(scenes) > 0, "scene", "at least one scene", list(scene_names))
    if "mujoco" in engines:
        dts = check_mujoco_args(mujoco.integrators, mujoco.modes, mujoco.timesteps,
                                mujoco.budget_s)
    files = _output_files(out, engines, scenes, ode.stiff, t_end_s)
    _claim_output(out, files, force)
    refs = [reference_run(s) for s in scenes]
    done = _Gathered()
    if "ode" in engines:
        _finish(done, "ode", [ode_work_precision(s, tolerances=ode.tolerances,
                                                 methods=ode.methods, budget_s=ode.budget_s,
                                                 reference=ref, log=log)
                              for s, ref in zip(scenes, refs, strict=True)],
                files["ode"], thresholds)
    if "stiff" in files:
        _finish(done, "stiff", [stiff_work_precision(STIFF_SCENE, Lambda_mps=STIFF_LAMBDA_MPS,
                                                     t_end_s=t_end_s,
                                                     tolerances=ode.tolerances,
                                                     budget_s=ode.budget_s, log=log)],
                files["stiff"], thresholds)
    if "mujoco" in engines:
        rows = mujoco_rows(list(zip(scenes, refs, strict=True)), mujoco.integrators,
                           mujoco.modes, dts, mujoco.budget_s, run.workers, log)
        _finish(done, "mujoco", [mujoco_frame(r, ref) for r, ref in zip(rows, refs, strict=True)],
                files["mujoco"], thresholds)
    return _summary(done, engines)
