"""An offscreen H.264 MP4 of a scene's run: MuJoCo's, the reference's, or both side by side.

:func:`render_scene` checks everything before it simulates, then runs the scene, draws,
encodes and decodes the file back before it replaces any; what the picture shows and how time
maps to frames is in docs/design.md. The drawing code is imported only when a video is asked
for.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from tippetop.compare.presentation.video import (
    DEFAULT_FPS,
    DEFAULT_MAX_FRAMES,
    DEFAULT_SIZE,
    DEFAULT_SPEED,
    ENGINE_LABELS,
    RENDER_ENGINES,
    VIDEO_SUFFIXES,
    check_timing,
    disk_full,
    frame_bar,
    full_text,
    is_full,
    parse_size,
)
from tippetop.compare.running.options import DEFAULT_RUN, RunOptions
from tippetop.models.errors import expect
from tippetop.models.numbers import number_text
from tippetop.mujoco_runner.gl import use_gl_backend

if TYPE_CHECKING:
    import pandas as pd

    from tippetop.models.plan import RunPlan
    from tippetop.models.scene import Scene
    from tippetop.mujoco_runner.poses import Track

#: The engines in the progress lines.
_ENGINE_NAMES = {"mujoco": "MuJoCo", "ode": "the reference ODE"}


class RunFailed(RuntimeError):
    """An engine's run diverged or stopped short: there is nothing (complete) to draw."""


class VideoWriteFailed(RuntimeError):
    """The MP4 could not be written, or does not decode to the frames drawn.

    A full disk or an encoder error; the output file, if there was one, is as it was.
    """


@dataclass(frozen=True)
class VideoOptions:
    """How a video is made; the defaults are ``tippetop render``'s.

    Attributes:
        fps: Frames per second of the video.
        speed: Simulated seconds per second of video (0.25: quarter-speed slow motion).
        size: One panel, ``"WIDTHxHEIGHT"`` or (width, height) in px; rounded down to even.
        max_frames: Refuse to make more frames than this.
    """

    fps: float = DEFAULT_FPS
    speed: float = DEFAULT_SPEED
    size: str | tuple[int, int] = DEFAULT_SIZE
    max_frames: int = DEFAULT_MAX_FRAMES


@dataclass(frozen=True)
class RenderResult:
    """What :func:`render_scene` wrote.

    Attributes:
        path: The MP4 file.
        engines: The engines drawn, left to right: ``("mujoco",)``, ``("ode",)`` or
            ``("mujoco", "ode")`` (side by side).
        backend: The OpenGL backend used (``egl`` or ``osmesa``).
        n_frames: Frames in the video.
        width: Video width (px; two panels for ``both``).
        height: Video height (px).
        fps: Frames per second.
        speed: Simulated seconds per second of video.
        video_s: Length of the video (s).
        render_wall_s: Wall time of drawing and encoding (s), the simulations excluded.
    """

    path: Path
    engines: tuple[str, ...]
    backend: str
    n_frames: int
    width: int
    height: int
    fps: float
    speed: float
    video_s: float
    render_wall_s: float

    @property
    def ms_per_frame(self) -> float:
        """Drawing and encoding wall time per frame (ms)."""
        return 1e3 * self.render_wall_s / self.n_frames


def render_scene(
    scene: Scene,
    out: str | Path,
    *,
    engines: tuple[str, ...] = ("mujoco",),
    mode: str | None = None,
    video: VideoOptions = VideoOptions(),
    force: bool = False,
    run: RunOptions = DEFAULT_RUN,
    say: Callable[[str], None] | None = None,
) -> RenderResult:
    """Simulate ``scene`` in the engine(s) and write an MP4 of the run.

    Every argument is checked, and the backend chosen, before anything is simulated.

    Args:
        scene: A :class:`models.scene.Scene`.
        out: The ``.mp4`` file to write.
        engines: The engines drawn side by side, left to right: ``mujoco`` (the MuJoCo
            installed here) and/or ``ode`` (the reference replayed in the same MJCF).
        mode: MuJoCo's mode (:mod:`tippetop.models.modes`); None: the scene's. The reference
            runs the scene's own law.
        video: The frame rate, speed, panel size and frame cap (:class:`VideoOptions`).
        force: Overwrite an existing ``out``.
        run: Its ``progress``: show progress bars on stderr when it is a terminal. The runs
            are the scene's own, in this process and uncached: the other fields are not read.
        say: Called with one line before each step (each engine's run, the frames) and, when
            stderr is not a terminal, every 15 s of drawing; None says nothing.

    Returns:
        The file written and its frame count, size and render time.

    Raises:
        TippetopError: For bad arguments, an existing ``out`` without ``force``, or no working
            OpenGL backend (no file is written).
        RunFailed: If an engine's run diverged or stopped short (no file is written).
        VideoWriteFailed: If writing failed (OSError: a full disk, said as ENOSPC with the
            free space, :func:`disk_full`) or the file written does not decode to
            ``n_frames`` frames: the temporary file is removed and an existing ``out`` is
            left as it was.
    """
    from tippetop.compare.running.io import check_output_path

    fps, speed, size = video.fps, video.speed, video.size
    engines = _checked_engines(engines)
    width, height = parse_size(size if isinstance(size, str) else "x".join(map(str, size)))
    n_frames = check_timing(scene.run.t_end_s, fps, speed, video.max_frames)
    path = check_output_path(out, force=force, suffixes=VIDEO_SUFFIXES)
    backend = use_gl_backend()  # before anything below imports mujoco

    from tippetop.compare.running.engines import plan_for

    # bad input fails before runs
    plans = {name: plan_for(scene, name, mode if name != "ode" else None) for name in engines}
    tell = say or (lambda _line: None)
    tables = _simulate(scene, plans, tell, run.progress)

    from tippetop.compare.running.io import write_atomic
    from tippetop.mujoco_runner import video as mj_video

    tracks = _tracks(scene, plans, tables, engines, width, height)
    times = mj_video.frame_times(n_frames, fps, speed)
    tell(_replay_line(engines, n_frames, width, height, fps, speed, backend))
    stats: list[mj_video.VideoStats] = []

    def write_checked(tmp: Path) -> None:
        """Encode into ``tmp``, then decode it: only a complete video replaces ``path``.

        A failure on a full filesystem is said to be one (ENOSPC), whatever the encoder or
        the decoder made of it: the free space is read while ``tmp`` still holds its bytes.
        """
        try:
            stats.append(mj_video.write_video(tmp, tracks, times, fps=fps, width=width,
                                              height=height, backend=backend, on_frame=tick))
            mj_video.verify_video(tmp, n_frames, width * len(engines), height)
        except (OSError, mj_video.VideoCheckFailed) as exc:
            full = disk_full(exc, tmp.parent)
            if full is not None:
                raise full from exc
            raise

    try:
        with frame_bar(n_frames if run.progress else 0, f"{scene.name} [{','.join(engines)}] video",
                        say) as tick:
            write_atomic(path, write_checked)
    except (OSError, mj_video.VideoCheckFailed) as exc:
        raise _write_failure(exc, path) from exc
    s = stats[0]
    return RenderResult(path=path, engines=engines, backend=backend, n_frames=s.n_frames,
                        width=s.width, height=s.height, fps=float(fps), speed=float(speed),
                        video_s=n_frames / fps, render_wall_s=s.wall_s)


def _checked_engines(engines: tuple[str, ...]) -> tuple[str, ...]:
    """The engines as a tuple, each a render engine and given once (else TippetopError)."""
    engines = tuple(engines)
    for engine in engines:
        expect(engine in RENDER_ENGINES, "--engine", "one of " + "|".join(RENDER_ENGINES)
               + " (the MuJoCo installed here, and the reference replayed)", engine)
    expect(0 < len(engines) == len(set(engines)), "--engines",
           "mujoco, ode or mujoco,ode (each once)", ",".join(engines))
    return engines


def _simulate(scene: Scene, plans: dict[str, RunPlan], tell: Callable[[str], None],
              progress: bool) -> dict[str, pd.DataFrame]:
    """Each engine's table of its run of ``plans`` (RunFailed for a run cut short)."""
    from tippetop.compare.running.engines import run_plan

    tables = {}
    for name, plan in plans.items():
        tell(f"simulating {scene.name} in {_ENGINE_NAMES[name]} "
             f"({plan.t_end_s:g} s simulated)...")
        run = run_plan(plan, progress=progress)
        if run.status not in ("ok", "contact_lost", "hop") or len(run.table) == 0:
            raise RunFailed(f"{name}: {run.message}")
        tables[name] = run.table
    return tables


def _tracks(scene: Scene, plans: dict[str, RunPlan], tables: dict[str, pd.DataFrame],
            engines: tuple[str, ...], width: int, height: int) -> list[Track]:
    """The engines' poses to replay, left to right, in the model drawn from the first plan."""
    from tippetop.mujoco_runner.drawn_model import render_model
    from tippetop.mujoco_runner.poses import Track

    first = plans[engines[0]]
    top_model = render_model(first.top, scene.top_mjcf, width, height)
    return [Track.from_table(tables[name], top_model, label=ENGINE_LABELS[name],
                             paper_frame=name == "ode") for name in engines]


def _replay_line(engines: tuple[str, ...], n_frames: int, width: int, height: int,
                 fps: float, speed: float, backend: str) -> str:
    """The progress line said before the frames are drawn."""
    runs = " and ".join(("MuJoCo's run" if name == "mujoco" else "the reference's")
                        for name in engines)
    return (f"replaying {runs} in the MJCF: {n_frames} frames of {width * len(engines)}x"
            f"{height}, {number_text(n_frames / fps, 's')} of video at speed "
            f"{number_text(speed)} ({backend})...")


def _write_failure(exc: Exception, path: Path) -> VideoWriteFailed:
    """The error for a video not written to ``path``: a full disk said as one, else ``exc``."""
    kept = "left as it was" if path.exists() else "not written"
    full = exc if is_full(exc) else disk_full(exc, path.parent)
    if full is not None:
        return VideoWriteFailed(f"could not write {path}: {full_text(full, path)}; {path} "
                                f"{kept}")
    what = (exc.strerror or " ".join(str(exc).split())) if isinstance(exc, OSError) \
        else str(exc)
    return VideoWriteFailed(f"could not write {path}: {what[:300]}; {path} {kept}")


__all__ = ["RenderResult", "RunFailed", "VideoWriteFailed", "render_scene"]
