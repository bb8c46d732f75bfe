"""The MP4 encoder of the frames: H.264 (libx264, yuv420p) by imageio-ffmpeg's bundled ffmpeg.

:class:`Mp4Writer` streams RGB frames to ffmpeg and keeps ffmpeg's own messages out of the
user's terminal, in a temporary file whose gist it gives when the encoder fails. imageio-ffmpeg
is imported when a writer is made.
"""

from __future__ import annotations

import contextlib
import os
import re
from pathlib import Path

import numpy as np

# H.264 settings: constant quality (x264's CRF, lower is better) and the encoder's speed preset.
_CRF = 20
_X264_PRESET = "veryfast"


class Mp4Writer:
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


__all__ = ["Mp4Writer"]
