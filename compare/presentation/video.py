"""A video's arguments, timing and progress, and what a full disk did to it, in words.

How simulated time maps to frames (:func:`frame_count`, :func:`speed_to_fit`), the checks of
the size and timing, the frame bar, and a failed write said as a full disk when it was one.
:func:`tippetop.compare.studies.render.render_scene` runs the scene and draws it (what the
picture shows: docs/design.md).
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
from pathlib import Path

from tippetop.models.errors import TippetopError, expect

#: The engines a video draws: the MuJoCo installed here, and the reference replayed in the same
#: MJCF; ``--engines mujoco,ode`` draws both side by side, MuJoCo left.
RENDER_ENGINES: tuple[str, ...] = ("mujoco", "ode")
#: Panel titles.
ENGINE_LABELS = {"mujoco": "MuJoCo", "ode": "reference ODE"}
#: Wall time between progress lines over the frames when stderr is not a terminal (s).
FRAME_REPORT_S = 15.0
DEFAULT_FPS = 30.0  # (frames per second of video)
DEFAULT_SPEED = 0.25  # (simulated seconds per second of video: quarter-speed slow motion)
DEFAULT_SIZE = "640x480"  # (px, one panel)
DEFAULT_MAX_FRAMES = 3000
#: Panel sides (px) accepted by --size, before rounding down to even.
MIN_SIDE_PX, MAX_SIDE_PX = 16, 4096
VIDEO_SUFFIXES = (".mp4",)

_SIZE_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")
_FRAME_SLACK = 1e-9  # relative: a frame time within this of t_end still counts


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


def check_timing(t_end_s: float, fps: float, speed: float, max_frames: int) -> int:
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


# ---------------------------------------------------------------- a full disk
#: The errnos of a filesystem with no room left for the file: no space, or the user's quota.
FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
#: After a failed write, less free space than this (bytes) on the file's filesystem means the
#: failure was the full disk: the encoder writes its buffer (tens of kB) at a time, so a write
#: that failed for want of room leaves less than that, and the decoder then finds a cut file.
FULL_BELOW_BYTES = 1 << 20
_NO_SPACE = "No space left on device"


def is_full(exc: BaseException) -> bool:
    """Whether ``exc`` is the filesystem's own no-room error (ENOSPC, EDQUOT)."""
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
def frame_bar(total: int, label: str, say: Callable[[str], None] | None = None
               ) -> Iterator[Callable[[], None] | None]:
    """Progress over the frames; yields its tick (call once a frame), or None.

    A tqdm bar on stderr when it is a terminal; otherwise, with ``say``, a line every
    ``FRAME_REPORT_S`` seconds of wall time.
    """
    if total <= 0:
        yield None
        return
    if not sys.stderr.isatty():
        if say is None:
            yield None
            return
        start = time.perf_counter()
        state = {"done": 0, "next": start + FRAME_REPORT_S}

        def tick() -> None:
            state["done"] += 1
            now = time.perf_counter()
            if now >= state["next"] and state["done"] < total:
                state["next"] = now + FRAME_REPORT_S
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
    "FRAME_REPORT_S",
    "RENDER_ENGINES",
    "VIDEO_SUFFIXES",
    "check_timing",
    "disk_full",
    "frame_bar",
    "frame_count",
    "free_bytes",
    "full_text",
    "is_full",
    "parse_size",
    "speed_to_fit",
]
