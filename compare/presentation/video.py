"""An offscreen H.264 MP4 of a scene's run, MuJoCo's, the reference's or both side by side.

:func:`render_scene` checks everything before it simulates, then draws, encodes and decodes
the file back before it replaces any; what the picture shows and how time maps to frames is
in docs/design.md. The drawing code is imported only when a video is asked for.
"""

from __future__ import annotations

import errno
import math
import os
import re
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from tippetop.models.errors import TippetopError, expect
from tippetop.models.numbers import number_text
from tippetop.mujoco_runner.gl import use_gl_backend

if TYPE_CHECKING:
    from tippetop.models.scene import Scene

#: ``--engine`` choices; ``both`` is MuJoCo (left) and the reference ODE (right).
RENDER_ENGINES: tuple[str, ...] = ("mujoco", "ode", "both")
#: Panel titles.
ENGINE_LABELS = {"mujoco": "MuJoCo", "ode": "reference ODE"}
#: The engines in the progress lines.
_ENGINE_NAMES = {"mujoco": "MuJoCo", "ode": "the reference ODE"}
#: Wall time between progress lines over the frames when stderr is not a terminal (s).
_FRAME_REPORT_S = 15.0
DEFAULT_FPS = 30.0  # (frames per second of video)
DEFAULT_SPEED = 0.25  # (simulated seconds per second of video: quarter-speed slow motion)
DEFAULT_SIZE = "640x480"  # (px, one panel)
DEFAULT_MAX_FRAMES = 3000
#: Panel sides (px) accepted by --size, before rounding down to even.
MIN_SIDE_PX, MAX_SIDE_PX = 16, 4096
VIDEO_SUFFIXES = (".mp4",)

_SIZE_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")
_FRAME_SLACK = 1e-9  # relative: a frame time within this of t_end still counts


class RunFailed(RuntimeError):
    """An engine's run diverged or stopped short: there is nothing (complete) to draw."""


class VideoWriteFailed(RuntimeError):
    """The MP4 could not be written, or does not decode to the frames drawn.

    A full disk or an encoder error; the output file, if there was one, is as it was.
    """


# ---------------------------------------------------------------- arguments
def parse_size(text: str) -> tuple[int, int]:
    """``"WIDTHxHEIGHT"`` -> (width, height) in px, each rounded down to an even number.

    Raises:
        TippetopError: If the text is not two whole numbers in [16, 4096] joined by ``x``.
    """
    m = _SIZE_RE.match(str(text))
    ok = m is not None and all(MIN_SIDE_PX <= int(v) <= MAX_SIDE_PX for v in m.groups())
    expect(ok, "--size", f"WIDTHxHEIGHT in px, each from {MIN_SIDE_PX} to {MAX_SIDE_PX} "
           "(e.g. 640x480)", text)
    w, h = (int(v) for v in m.groups())
    return w - w % 2, h - h % 2


def frame_count(t_end_s: float, fps: float, speed: float) -> int:
    """Frames of a run of ``t_end_s`` simulated seconds: t_k = k speed / fps for t_k <= t_end."""
    return int(math.floor(t_end_s * fps / speed * (1 + _FRAME_SLACK))) + 1


def speed_to_fit(t_end_s: float, fps: float, max_frames: int, *,
                 min_speed: float = 0.0) -> float:
    """The playback speed at which ``max_frames`` frames show the whole run, end included.

    The frames are those of :func:`frame_count`, the last one included: ``max_frames`` frames
    span ``max_frames - 1`` intervals, so the speed is ``t_end_s * fps / (max_frames - 1)``
    (or ``min_speed`` if that is faster): the video has at most ``max_frames`` frames, and its
    last frame shows ``t_end_s`` itself. (Taking ``t_end_s * fps / max_frames`` instead, the
    cap counted as intervals, gives one frame too many.)

    Args:
        t_end_s: Simulated time of the run (s), > 0.
        fps: Frames per second of the video, > 0.
        max_frames: The most frames allowed, >= 2.
        min_speed: Never slower than this (simulated seconds per second of video).

    Returns:
        Simulated seconds per second of video.

    Raises:
        ValueError: If ``max_frames < 2`` (one frame cannot show a run that lasts) or
            ``t_end_s`` or ``fps`` is not a finite number > 0.
    """
    if not max_frames >= 2:
        raise ValueError(f"max_frames: expected at least 2, got {max_frames!r}")
    if not (math.isfinite(t_end_s) and t_end_s > 0 and math.isfinite(fps) and fps > 0):
        raise ValueError(f"expected t_end_s and fps finite and > 0, got {t_end_s!r}, {fps!r}")
    speed = max(float(min_speed), t_end_s * fps / (max_frames - 1))
    while frame_count(t_end_s, fps, speed) > max_frames:  # rounding; never more than a step
        speed = math.nextafter(speed, math.inf)
    return speed


def _round_up(x: float, digits: int = 2) -> float:
    """``x`` > 0 rounded up to ``digits`` significant digits."""
    scale = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    return math.ceil(x / scale * (1 - 1e-12)) * scale


def _check_timing(t_end_s: float, fps: float, speed: float, max_frames: int) -> int:
    """Validate --fps, --speed and --max-frames; return the frame count."""
    expect(isinstance(fps, (int, float)) and math.isfinite(fps) and 0 < fps <= 1000, "--fps",
           "a number of frames per second > 0 and <= 1000", fps)
    expect(isinstance(speed, (int, float)) and math.isfinite(speed) and speed > 0, "--speed",
           "a number > 0 (simulated seconds per second of video; 0.25 = quarter speed)", speed)
    expect(isinstance(max_frames, int) and max_frames >= 1, "--max-frames", "a whole number >= 1",
           max_frames)
    n = frame_count(t_end_s, fps, speed)
    if n > max_frames:
        fits = "a larger --max-frames"
        if max_frames > 1:
            fit = _round_up(speed_to_fit(t_end_s, fps, max_frames))
            while frame_count(t_end_s, fps, fit) > max_frames:
                fit = _round_up(fit * (1 + 1e-3))
            fits = f"--speed {fit:g} or more, a larger --max-frames"
        raise TippetopError(
            f"--max-frames: expected at most {max_frames} frames, got {n} for "
            f"run.t_end_s = {t_end_s:g} s at --fps {fps:g} and --speed {speed:g} (video "
            f"{t_end_s / speed:g} s); use {fits} or a shorter --set run.t_end_s=...")
    return n


# ---------------------------------------------------------------- rendering a scene
@dataclass(frozen=True)
class RenderResult:
    """What :func:`render_scene` wrote.

    Attributes:
        path: The MP4 file.
        engine: ``mujoco``, ``ode`` or ``both``.
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
    engine: str
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
    engine: str = "mujoco",
    fps: float = DEFAULT_FPS,
    speed: float = DEFAULT_SPEED,
    size: str | tuple[int, int] = DEFAULT_SIZE,
    max_frames: int = DEFAULT_MAX_FRAMES,
    force: bool = False,
    progress: bool = True,
    say: Callable[[str], None] | None = None,
) -> RenderResult:
    """Simulate ``scene`` in the engine(s) and write an MP4 of the run.

    Every argument is checked, and the backend chosen, before anything is simulated.

    Args:
        scene: A :class:`models.scene.Scene`.
        out: The ``.mp4`` file to write.
        engine: ``"mujoco"``, ``"ode"`` or ``"both"`` (side by side, MuJoCo left).
        fps: Frames per second of the video.
        speed: Simulated seconds per second of video (0.25: quarter-speed slow motion).
        size: One panel, ``"WIDTHxHEIGHT"`` or (width, height) in px; rounded down to even.
        max_frames: Refuse to make more frames than this.
        force: Overwrite an existing ``out``.
        progress: Show progress bars on stderr when it is a terminal.
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

    expect(engine in RENDER_ENGINES, "--engine", "one of " + "|".join(RENDER_ENGINES), engine)
    width, height = parse_size(size if isinstance(size, str) else "x".join(map(str, size)))
    n_frames = _check_timing(scene.run.t_end_s, fps, speed, max_frames)
    path = check_output_path(out, force=force, suffixes=VIDEO_SUFFIXES)
    backend = use_gl_backend()  # before anything below imports mujoco

    from tippetop.compare.running.engines import plan_for, run_plan

    engines = ("mujoco", "ode") if engine == "both" else (engine,)
    plans = {name: plan_for(scene, name) for name in engines}  # bad input fails before runs
    tell = say or (lambda _line: None)
    tables = {}
    for name in engines:
        tell(f"simulating {scene.name} in {_ENGINE_NAMES[name]} "
             f"({plans[name].t_end_s:g} s simulated)...")
        run = run_plan(plans[name], progress=progress)
        if run.status not in ("ok", "contact_lost", "hop") or len(run.table) == 0:
            raise RunFailed(f"{name}: {run.message}")
        tables[name] = run.table

    from tippetop.compare.running.io import write_atomic
    from tippetop.mujoco_runner import video
    from tippetop.mujoco_runner.drawn_model import render_model
    from tippetop.mujoco_runner.poses import Track

    first = plans[engines[0]]
    top_model = render_model(first.top, scene.top_mjcf, width, height)
    tracks = [Track.from_table(tables[name], top_model, label=ENGINE_LABELS[name],
                               paper_frame=name == "ode") for name in engines]
    times = video.frame_times(n_frames, fps, speed)
    runs = " and ".join(("MuJoCo's run" if name == "mujoco" else "the reference's")
                        for name in engines)
    tell(f"replaying {runs} in the MJCF: {n_frames} frames of {width * len(engines)}x"
         f"{height}, {number_text(n_frames / fps, 's')} of video at speed {number_text(speed)} "
         f"({backend})...")
    stats: list[video.VideoStats] = []

    def write_checked(tmp: Path) -> None:
        """Encode into ``tmp``, then decode it: only a complete video replaces ``path``.

        A failure on a full filesystem is said to be one (ENOSPC), whatever the encoder or
        the decoder made of it: the free space is read while ``tmp`` still holds its bytes.
        """
        try:
            stats.append(video.write_video(tmp, tracks, times, fps=fps, width=width,
                                           height=height, backend=backend, on_frame=tick))
            video.verify_video(tmp, n_frames, width * len(engines), height)
        except (OSError, video.VideoCheckFailed) as exc:
            full = disk_full(exc, tmp.parent)
            if full is not None:
                raise full from exc
            raise

    try:
        with _frame_bar(n_frames if progress else 0, f"{scene.name} [{engine}] video",
                        say) as tick:
            write_atomic(path, write_checked)
    except (OSError, video.VideoCheckFailed) as exc:
        kept = "left as it was" if path.exists() else "not written"
        full = exc if _is_full(exc) else disk_full(exc, path.parent)
        if full is not None:
            raise VideoWriteFailed(f"could not write {path}: {full_text(full, path)}; {path} "
                                   f"{kept}") from exc
        what = (exc.strerror or " ".join(str(exc).split())) if isinstance(exc, OSError) \
            else str(exc)
        raise VideoWriteFailed(f"could not write {path}: {what[:300]}; {path} {kept}") \
            from exc
    s = stats[0]
    return RenderResult(path=path, engine=engine, backend=backend, n_frames=s.n_frames,
                        width=s.width, height=s.height, fps=float(fps), speed=float(speed),
                        video_s=n_frames / fps, render_wall_s=s.wall_s)


# ---------------------------------------------------------------- a full disk
#: The errnos of a filesystem with no room left for the file: no space, or the user's quota.
FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
#: After a failed write, less free space than this (bytes) on the file's filesystem means the
#: failure was the full disk: the encoder writes its buffer (tens of kB) at a time, so a write
#: that failed for want of room leaves less than that, and the decoder then finds a cut file.
FULL_BELOW_BYTES = 1 << 20
_NO_SPACE = "No space left on device"


def _is_full(exc: BaseException) -> bool:
    return isinstance(exc, OSError) and exc.errno in FULL_ERRNOS


def free_bytes(folder: Path) -> int | None:
    """Bytes this process may still write on ``folder``'s filesystem, or None if unknown.

    Root may write into the blocks a filesystem reserves (``f_bfree``), anyone else only into
    the rest (``f_bavail``, what :func:`shutil.disk_usage` calls free).
    """
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):  # no statvfs: another platform, a vanished folder
        return None
    blocks = st.f_bfree if hasattr(os, "geteuid") and os.geteuid() == 0 else st.f_bavail
    return int(blocks) * int(st.f_frsize)


def disk_full(exc: BaseException, folder: Path) -> OSError | None:
    """The full-disk error behind a failed write of a file in ``folder``, or None if it was not.

    Full when the error says so (errno ENOSPC or EDQUOT, or ffmpeg's ``No space left on
    device`` in its text), or when the filesystem has less than :data:`FULL_BELOW_BYTES` free
    right after the failure (ffmpeg may finish "successfully" on a full disk and leave a cut
    file that does not decode: that is what the user saw).

    Returns:
        An ``OSError`` with errno ENOSPC (or EDQUOT) and the free space in its text, or None.
    """
    free = free_bytes(folder)
    where = f"{_bytes(free)} free on the filesystem of {folder}" if free is not None else \
        f"the filesystem of {folder}"
    code = exc.errno if isinstance(exc, OSError) and exc.errno in FULL_ERRNOS else None
    if code is None and (_NO_SPACE.lower() in str(exc).lower()
                         or (free is not None and free < FULL_BELOW_BYTES)):
        code = errno.ENOSPC
    return OSError(code, os.strerror(code), where) if code is not None else None


def full_text(exc: OSError, path: Path) -> str:
    """One clause for a full disk: the errno's name and text, where, and what to do."""
    code = errno.errorcode.get(exc.errno or errno.ENOSPC, "ENOSPC")
    where = exc.filename or f"the filesystem of {path.parent}"
    return (f"{os.strerror(exc.errno or errno.ENOSPC)} ({code}: {where}); free space there or "
            f"write the video elsewhere")


def _bytes(n: int) -> str:
    """``0 bytes``, ``12 kB``, ``3.4 MB``: a size for a person."""
    if n < 1000:
        return f"{n} bytes"
    for unit, scale in (("kB", 1e3), ("MB", 1e6), ("GB", 1e9)):
        if n < scale * 1000:
            return f"{n / scale:.4g} {unit}"
    return f"{n / 1e12:.4g} TB"


@contextmanager
def _frame_bar(total: int, label: str, say: Callable[[str], None] | None = None
               ) -> Iterator[Callable[[], None] | None]:
    """Progress over the frames; yields its tick (call once a frame), or None.

    A tqdm bar on stderr when it is a terminal; otherwise, with ``say``, a line every
    ``_FRAME_REPORT_S`` seconds of wall time.
    """
    if total <= 0:
        yield None
        return
    if not sys.stderr.isatty():
        if say is None:
            yield None
            return
        start = time.perf_counter()
        state = {"done": 0, "next": start + _FRAME_REPORT_S}

        def tick() -> None:
            state["done"] += 1
            now = time.perf_counter()
            if now >= state["next"] and state["done"] < total:
                state["next"] = now + _FRAME_REPORT_S
                say(f"  {state['done']}/{total} frames drawn ({now - start:.0f} s)")

        yield tick
        return
    from tqdm import tqdm

    with tqdm(total=total, desc=label, unit="frame", leave=False) as bar:
        yield lambda: bar.update(1)


__all__ = [
    "DEFAULT_FPS",
    "DEFAULT_MAX_FRAMES",
    "DEFAULT_SIZE",
    "DEFAULT_SPEED",
    "ENGINE_LABELS",
    "RENDER_ENGINES",
    "RenderResult",
    "RunFailed",
    "VideoWriteFailed",
    "disk_full",
    "frame_count",
    "free_bytes",
    "parse_size",
    "render_scene",
    "speed_to_fit",
]
