"""Nightly videos: a short side-by-side MP4 per paper scene, linked from the report.

Every requested video is rendered; one that fails, for whatever reason (a bad scene, a run
that diverged, no OpenGL, ffmpeg, a bug), is listed in ``failed`` with a one-line reason and
leaves no file (nor a temporary one) in the videos folder, and the others are still rendered.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from tippetop.compare.nightly.catalogue import Case
from tippetop.compare.nightly.outputs import slug
from tippetop.models.errors import TippetopError
from tippetop.models.scene import Override

#: Nightly videos: small, side by side (MuJoCo | reference), at most this many frames each.
VIDEO_SIZE = (320, 240)
VIDEO_FPS = 15.0
VIDEO_MAX_FRAMES = 240
VIDEO_MIN_SPEED = 0.25  # (simulated s per s of video): never slower than quarter speed
# paper mode is within 3e-4 rad of 1.25e-5 s
VIDEO_OVERRIDES = (Override.of("mujoco.timestep_s", 1e-4),)


def video_speed(t_end_s: float) -> float:
    """The playback speed of a nightly video of a run of ``t_end_s`` simulated seconds.

    The slowest speed (at least ``VIDEO_MIN_SPEED``) whose video at ``VIDEO_FPS`` has at most
    ``VIDEO_MAX_FRAMES`` frames, its last frame (at ``t_end_s``) included.
    """
    from tippetop.compare.presentation.video import speed_to_fit

    return speed_to_fit(t_end_s, VIDEO_FPS, VIDEO_MAX_FRAMES, min_speed=VIDEO_MIN_SPEED)


def video_scenes(cases: Sequence[Case]) -> list[str]:
    """The scenes that get a video: those of the ``paper`` run cases, sorted."""
    return sorted({c.scene for c in cases
                   if c.kind == "run" and c.category == "paper" and not c.model})


def _one_line(exc: BaseException) -> str:
    """A failure's reason on one line.

    The message, after the exception's type unless it is one of the harness's own errors,
    whose messages stand alone.
    """
    text = " ".join(str(exc).split())
    if isinstance(exc, TippetopError) and text:
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _remove_leftovers(path: Path) -> None:
    """Remove ``path`` and the temporary files of an atomic write of it, if there are any."""
    for p in [path, *path.parent.glob(f".{path.name}.*.tmp")]:
        p.unlink(missing_ok=True)


def render_videos(cases: Sequence[Case], out_dir: Path,
                  log: Callable[[str], None]) -> dict[str, Any]:
    """Render one short side-by-side video per scene of the profile's ``paper`` run cases.

    The playback speed (:func:`video_speed`) gives at most ``VIDEO_MAX_FRAMES`` frames (at
    least quarter-speed slow motion). A video that fails for any reason is logged and listed
    with its reason, leaves no file, and does not stop the others.

    Args:
        cases: The nightly's selected cases.
        out_dir: The nightly's output folder; the videos go to its ``videos/``.
        log: Prints one progress line.

    Returns:
        ``{"requested": True, "status": "<k> written[, <m> failed]", "files": {scene:
        path relative to out_dir}, "failed": {scene: one-line reason}}``.
    """
    from tippetop.compare.presentation.video import frame_count
    from tippetop.compare.running.options import RunOptions
    from tippetop.compare.studies.render import VideoOptions, render_scene
    from tippetop.models.scene import load_scene

    scenes = video_scenes(cases)
    files: dict[str, str] = {}
    failed: dict[str, str] = {}
    for name in scenes:
        rel = f"videos/{slug(name)}.mp4"
        path = out_dir / rel

        def say(line: str, rel: str = rel) -> None:
            log(f"nightly: {rel}: {line.strip()}")

        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            scene = load_scene(name, list(VIDEO_OVERRIDES))
            speed = video_speed(scene.run.t_end_s)
            n_frames = frame_count(scene.run.t_end_s, VIDEO_FPS, speed)
            say(f"{n_frames} frames at {VIDEO_FPS:g} fps, speed {speed:.3g}")
            res = render_scene(scene, path, engines=("mujoco", "ode"),
                               video=VideoOptions(fps=VIDEO_FPS, speed=speed, size=VIDEO_SIZE,
                                                  max_frames=VIDEO_MAX_FRAMES),
                               force=True, run=RunOptions(progress=False), say=say)
            if res.n_frames != n_frames or not path.is_file() or path.stat().st_size == 0:
                raise RuntimeError(f"expected {n_frames} frames in {rel}, got "
                                   f"{res.n_frames} frames and "
                                   f"{path.stat().st_size if path.is_file() else 'no'} bytes")
            files[name] = rel
            say(f"written ({res.n_frames} frames, {res.render_wall_s:.0f} s drawing)")
        except Exception as exc:  # every failure is listed, whatever it is
            _remove_leftovers(path)
            failed[name] = _one_line(exc)
            log(f"nightly: {rel}: FAILED: {failed[name]}")
    status = f"{len(files)} written" + (f", {len(failed)} failed" if failed else "")
    return {"requested": True, "status": status, "files": files, "failed": failed}


__all__ = ["VIDEO_FPS", "VIDEO_MAX_FRAMES", "VIDEO_MIN_SPEED", "VIDEO_OVERRIDES", "VIDEO_SIZE",
           "render_videos", "video_scenes", "video_speed"]
