"""Offscreen frames of a run and their H.264 MP4: the drawing half of ``tippetop render``.

Imported only when a video is asked for: :mod:`compare.render` chooses the OpenGL backend
(``MUJOCO_GL``) first, and this module creates the context of that backend explicitly, so it
works even when ``mujoco`` was imported earlier in the process with another ``MUJOCO_GL``.

* :func:`.drawn_model.render_model`: the model that is drawn.
* :class:`.poses.Track`: an engine's poses, interpolated at the frame times.
* :class:`.offscreen.OffscreenRenderer`: a context-managed EGL or OSMesa renderer of one model.
* :func:`render_frames`: frames at the given simulated times, one panel per track side by
  side, each with a text overlay (engine, t, theta, n); with two tracks (MuJoCo | reference) a
  comparison inset straddles the seam at the bottom: the readout of delta theta (first track's
  theta minus the second's) at that frame, and a small plot of theta(t) of both up to it.
* :func:`write_video`: those frames encoded by imageio-ffmpeg's bundled ffmpeg (libx264,
  yuv420p).

The picture: a camera low over the table (10 degrees) and to the side, following the top, so
that the stem shows beside the ball while the top turns over instead of hiding under it; the
table is drawn translucent, so that the stem still shows once it points into the table (the
paper's loaded sphere has no stem: the drawn one is a visual marker of the axis, 1.55 R long,
and the turned-over top's marker pokes through the table). Poses are set, never simulated, so
none of this touches the physics.
"""

from __future__ import annotations

import contextlib
import os
import re
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from tippetop.mujoco_runner.inset import ThetaInset
from tippetop.mujoco_runner.offscreen import OffscreenRenderer, tracking_camera
from tippetop.mujoco_runner.overlay import TextOverlay
from tippetop.mujoco_runner.poses import Track, set_pose

# H.264 settings: constant quality (x264's CRF, lower is better) and the encoder's speed preset.
_CRF = 20
_X264_PRESET = "veryfast"


# ---------------------------------------------------------------- encoder
class _Mp4Writer:
    """Streams RGB frames to ffmpeg (imageio-ffmpeg's bundled binary): H.264, yuv420p, MP4.

    ffmpeg's own messages go to a temporary file, not to our stderr: :meth:`reason` gives the
    gist of them when the encoder fails (``No space left on device``, say).
    """

    def __init__(self, path: Path, width: int, height: int, fps: float) -> None:
        import tempfile

        import imageio_ffmpeg

        self._log = tempfile.TemporaryFile()
        self._gen = imageio_ffmpeg.write_frames(
            str(path), (width, height), pix_fmt_in="rgb24", pix_fmt_out="yuv420p", fps=fps,
            codec="libx264", quality=None, macro_block_size=1, ffmpeg_log_level="error",
            output_params=["-crf", str(_CRF), "-preset", _X264_PRESET,
                           "-movflags", "+faststart", "-f", "mp4"])
        saved = os.dup(2)  # ffmpeg (started by the first send) inherits stderr: its log file
        try:
            os.dup2(self._log.fileno(), 2)
            self._gen.send(None)
        finally:
            os.dup2(saved, 2)
            os.close(saved)

    def reason(self) -> str:
        """What ffmpeg said went wrong, on one line ("" if nothing)."""
        self._log.seek(0)
        lines = [re.sub(r"^\[[^]]*\]\s*", "", ln).strip()
                 for ln in self._log.read().decode("utf-8", "replace").splitlines()]
        lines = [ln for ln in lines if ln]
        for ln in lines:
            if "No space left on device" in ln:
                return "No space left on device"
        return lines[0][:200] if lines else ""

    def write(self, rgb: np.ndarray) -> None:
        """Append one frame, uint8 RGB of shape (height, width, 3)."""
        self._gen.send(np.ascontiguousarray(rgb))

    def close(self) -> None:
        """Finish the file (waits for ffmpeg); once only, later calls do nothing."""
        gen, self._gen = self._gen, None
        if gen is not None:
            gen.close()

    def release(self) -> None:
        """Stop ffmpeg if it still runs (its errors already reported) and drop its log."""
        with contextlib.suppress(OSError):
            self.close()
        self._log.close()


# ---------------------------------------------------------------- the video
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
    writer = _Mp4Writer(path, width * len(tracks), height, fps)
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

