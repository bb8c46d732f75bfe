"""The text drawn over the pictures: a panel's title and t, theta and n, and the fonts for it.

:class:`TextOverlay` writes them into a panel's top-left corner on a darkened box. The font is
DejaVu Sans (matplotlib's copy, which has the Greek letters) or, without it, Pillow's default,
with the Greek then spelled in ASCII (:func:`spell`). Font size and margin follow the panel's
height (:func:`font_size_px`, :func:`margin_px`); the theta(t) inset (:mod:`.inset`) writes
with the same.
"""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tippetop.mujoco_runner.poses import TrackSample

if TYPE_CHECKING:
    from PIL.ImageFont import FreeTypeFont, ImageFont

# Text overlay, relative to the panel height.
_FONT_FRACTION = 1 / 22  # font size
_MIN_FONT_PX = 9
_TEXT_MARGIN_FRACTION = 1 / 60
_TEXT_BOX_OPACITY = 0.55  # the text's box darkens what is behind it
# Matplotlib's DejaVu Sans has the Greek letters; Pillow's default font does not.
_FONT_FILE = ("mpl-data", "fonts", "ttf", "DejaVuSans.ttf")
_ASCII = {"Δθ": "dtheta", "θ": "theta", "π": "pi", "−": "-", "■": "#"}


@functools.cache
def overlay_font(size_px: int) -> tuple[FreeTypeFont | ImageFont, bool]:
    """DejaVu Sans (matplotlib's copy) at ``size_px``, and whether it has Greek letters.

    Falls back to Pillow's default font (no Greek: the text is then spelled in ASCII).
    """
    from PIL import ImageFont

    spec = importlib.util.find_spec("matplotlib")
    if spec is not None and spec.origin is not None:
        path = Path(spec.origin).parent.joinpath(*_FONT_FILE)
        if path.is_file():
            return ImageFont.truetype(str(path), size_px), True
    return ImageFont.load_default(size=size_px), False


def spell(text: str, greek: bool) -> str:
    """``text`` as is when the font has Greek letters, else with them spelled in ASCII."""
    if not greek:
        for symbol, word in _ASCII.items():
            text = text.replace(symbol, word)
    return text


def font_size_px(height: int) -> int:
    """The overlay's font size (px) for a panel ``height`` px high."""
    return max(_MIN_FONT_PX, round(height * _FONT_FRACTION))


def margin_px(height: int) -> int:
    """The overlay's margin (px) for a panel ``height`` px high."""
    return max(2, round(height * _TEXT_MARGIN_FRACTION))


class TextOverlay:
    """Draws a panel's title and t, theta and n into the top-left corner of a frame."""

    def __init__(self, height: int) -> None:
        self._font, self._greek = overlay_font(font_size_px(height))
        self._margin = margin_px(height)

    def draw(self, rgb: np.ndarray, label: str, s: TrackSample) -> np.ndarray:
        """A copy of ``rgb`` (h, w, 3) with the text drawn on a darkened box."""
        from PIL import Image, ImageDraw

        lines = [label, f"t = {s.t_s:.3f} s", f"θ = {s.theta:.3f} rad",
                 f"n = {s.n:.1f} rad/s"]
        if s.ended:
            lines.append("(run ended)")
        text = spell("\n".join(lines), self._greek)
        m = self._margin
        box = ImageDraw.Draw(Image.new("L", (1, 1))).multiline_textbbox(
            (2 * m, 2 * m), text, font=self._font, spacing=m)
        x1, y1 = min(rgb.shape[1], box[2] + m), min(rgb.shape[0], box[3] + m)
        out = np.array(rgb)  # a writable copy
        region = out[m:y1, m:x1]
        region[...] = (region * (1.0 - _TEXT_BOX_OPACITY)).astype(np.uint8)  # darken behind
        image = Image.fromarray(out[:y1, :x1])
        ImageDraw.Draw(image).multiline_text((2 * m, 2 * m), text, font=self._font,
                                             fill=(255, 255, 255), spacing=m)
        out[:y1, :x1] = np.asarray(image)
        return out


__all__ = ["TextOverlay", "font_size_px", "margin_px", "overlay_font", "spell"]
