"""The video of a run: its frames drawn offscreen, and their H.264 MP4 (``tippetop render``).

Imported only when a video is asked for: :mod:`compare.presentation.video` chooses the OpenGL
backend (``MUJOCO_GL``) first. :func:`render_frames` draws each track (:class:`.poses.Track`: an
engine's poses) at the given simulated times in the model of :mod:`.drawn_model`, seen by
:func:`.offscreen.tracking_camera`, one panel per track side by side, each with its text overlay
(:mod:`.overlay`: engine, t, theta, n); with two tracks (MuJoCo | reference) the comparison inset
(:mod:`.inset`) straddles the seam at the bottom. :func:`write_video` encodes the frames
(:mod:`.mp4`); :func:`verify_video` decodes the file and checks that it holds them. Poses are
set, never simulated, so none of this touches the physics.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from tippetop.mujoco_runner.inset import ThetaInset
from tippetop.mujoco_runner.mp4 import Mp4Writer
from tippetop.mujoco_runner.offscreen import OffscreenRenderer, tracking_camera
from tippetop.mujoco_runner.overlay import TextOverlay
from tippetop.mujoco_runner.poses import Track, set_pose


@dataclass(frozen=True)
class VideoStats:
    """What :func:`write_video` did.

    Attributes:
        n_frames: Frames written.
        width: Video width (px): the panel width times the number of panels.
        height: Video height (px).
        wall_s: Wall time of drawing and encoding (s).
    """

    n_frames: int
    width: int
    height: int
    wall_s: float

    @property
    def ms_per_frame(self) -> float:
        """Wall time per frame (ms)."""
        return 1e3 * self.wall_s / max(1, self.n_frames)


def render_frames(
    tracks: Sequence[Track],
    times_s: np.ndarray,
    *,
    width: int,
    height: int,
    backend: str,
    inset: bool = True,
) -> Iterator[np.ndarray]:
    """Draw every track at every time: the frames, panels side by side, one at a time.

    Args:
        tracks: One panel each, left to right; all share one drawn model (that of the first).
        times_s: Simulated time of each frame (s), shape (n_frames,).
        width: Panel width (px).
        height: Panel height (px).
        backend: ``"egl"`` or ``"osmesa"``.
        inset: With two tracks, draw the comparison inset (delta theta, theta(t) of both;
            :func:`.inset.inset_layout` says where).

    Yields:
        uint8 RGB frames of shape (height, width * len(tracks), 3). The OpenGL context lives
        while the generator does: exhaust or close it.
    """
    top_model = tracks[0].top_model
    model = top_model.model
    datas = [mujoco.MjData(model) for _ in tracks]
    cameras = [tracking_camera(top_model) for _ in tracks]
    samples = [track.at(times_s) for track in tracks]
    overlay = TextOverlay(height)
    t_axis = float(times_s[-1]) if len(times_s) else 0.0
    compare = (ThetaInset(tracks, t_axis, width, height)
               if inset and len(tracks) == 2 else None)
    with OffscreenRenderer(model, width, height, backend) as renderer:
        for f in range(len(times_s)):
            panels = []
            for track, data, cam, track_samples in zip(tracks, datas, cameras, samples,
                                                        strict=True):
                s = track_samples[f]
                set_pose(top_model, data, s.qpos)
                panels.append(overlay.draw(renderer.render(data, cam), track.label, s))
            frame = np.concatenate(panels, axis=1)
            if compare is not None:
                compare.draw(frame, [track_samples[f] for track_samples in samples])
            yield frame


def write_video(
    path: Path,
    tracks: Sequence[Track],
    times_s: np.ndarray,
    *,
    fps: float,
    width: int,
    height: int,
    backend: str,
    on_frame: Callable[[], None] | None = None,
    inset: bool = True,
) -> VideoStats:
    """Draw every track at every time and encode the frames side by side into ``path``.

    Args:
        path: The MP4 file to write (any suffix: the container is forced to MP4).
        tracks: One panel each, left to right; all share one drawn model (that of the first).
        times_s: Simulated time of each frame (s), shape (n_frames,).
        fps: Frames per second of the video.
        width: Panel width (px), even.
        height: Panel height (px), even.
        backend: ``"egl"`` or ``"osmesa"``.
        on_frame: Called after each frame (for a progress bar).
        inset: With two tracks, draw the comparison inset (:func:`render_frames`).

    Returns:
        Frame count, size and wall time.
    """
    start = time.perf_counter()
    frames = render_frames(tracks, times_s, width=width, height=height, backend=backend,
                           inset=inset)
    writer = Mp4Writer(path, width * len(tracks), height, fps)
    try:
        try:
            for frame in frames:
                writer.write(frame)
                if on_frame is not None:
                    on_frame()
        finally:
            frames.close()  # frees the OpenGL context even when a frame failed
        writer.close()
    except OSError as exc:  # a full disk: ffmpeg stops, its pipe breaks; say why it stopped
        raise OSError(exc.errno, writer.reason() or exc.strerror or str(exc)) from exc
    finally:
        writer.release()
    return VideoStats(len(times_s), width * len(tracks), height, time.perf_counter() - start)


class VideoCheckFailed(RuntimeError):
    """A written MP4 does not decode, or does not hold the frames that were drawn."""


def verify_video(path: Path, n_frames: int, width: int, height: int) -> None:
    """Decode ``path`` with imageio; check it holds ``n_frames`` frames of width x height.

    What a full disk or a killed encoder leaves (a truncated file) fails. The frames are
    decoded one at a time (a long video never sits in memory).

    Args:
        path: The MP4 file.
        n_frames: The frames that were drawn.
        width: Video width (px).
        height: Video height (px).

    Raises:
        VideoCheckFailed: The file does not decode, or has other frames or another size.
    """
    import imageio.v3 as iio

    count = 0
    try:  # (imageio-ffmpeg leaves its pipes to ffmpeg for the collector at the file's end)
        with warnings.catch_warnings(), iio.imopen(path, "r", plugin="FFMPEG",
                                                   extension=".mp4") as reader:
            warnings.simplefilter("ignore", ResourceWarning)
            for frame in reader.iter():
                if frame.shape[:2] != (height, width):
                    raise VideoCheckFailed(f"expected frames of {width}x{height}, got "
                                           f"{frame.shape[1]}x{frame.shape[0]}")
                count += 1
    except VideoCheckFailed:
        raise
    except Exception as exc:  # noqa: BLE001 - whatever the decoder says, the file is bad
        first = (str(exc).split("===")[0].strip().splitlines() or [""])[0]  # not ffmpeg's log
        text = first.strip()[:200] or type(exc).__name__
        raise VideoCheckFailed(f"the file does not decode ({text})") from exc
    if count != n_frames:
        raise VideoCheckFailed(f"expected {n_frames} frames, decoded {count}")


def frame_times(n_frames: int, fps: float, speed: float) -> np.ndarray:
    """Simulated time of each frame (s): frame k shows t = k speed / fps."""
    return np.arange(n_frames) * (speed / fps)


__all__ = [
    "VideoCheckFailed",
    "VideoStats",
    "frame_times",
    "render_frames",
    "verify_video",
    "write_video",
]

