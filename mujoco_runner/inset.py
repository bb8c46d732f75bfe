"""The comparison inset of two tracks: delta theta and theta(t) of both, over their seam.

With two panels side by side (MuJoCo | reference), :class:`ThetaInset` draws at the bottom,
centred on the seam between them, the readout of delta theta (the first track's theta minus the
second's) at the frame's time and a small plot of theta(t) of both up to it; :func:`inset_layout`
says where it sits. Its text is written like the panels' (:mod:`.overlay`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tippetop.mujoco_runner.overlay import font_size_px, margin_px, overlay_font, spell
from tippetop.mujoco_runner.poses import Track, TrackSample

# The comparison inset of two tracks, centred on the seam between the panels, at the bottom.
_INSET_WIDTH_FRACTION = 0.75  # of a panel's width
_INSET_HEIGHT_FRACTION = 0.42  # of the height (at least what its text and a plot need)
_INSET_MIN_PLOT_PX = 24  # plot height
_INSET_OPACITY = 0.65  # its box darkens what is behind it
#: The theta(t) inset's trace colours (RGB): the first track (MuJoCo), the second (reference).
TRACE_RGB = ((255, 150, 40), (90, 200, 255))


@dataclass(frozen=True)
class InsetLayout:
    """Where the comparison inset of two panels sits, in the side-by-side frame (px).

    Attributes:
        box: (x0, y0, x1, y1) of the inset's darkened box (x1, y1 exclusive).
        plot: (x0, y0, x1, y1) of its theta(t) plot: x from t = 0 to the last frame's time,
            y from theta = pi (top) to 0 (bottom).
        header_lines: Text lines above the plot (the delta-theta readout, the legend).
    """

    box: tuple[int, int, int, int]
    plot: tuple[int, int, int, int]
    header_lines: int = 2


def inset_layout(width: int, height: int) -> InsetLayout:
    """The comparison inset of two panels of ``width x height`` px, centred on their seam.

    Its height is a fraction of the panel's, or what its two lines of text, a plot of at least
    ``_INSET_MIN_PLOT_PX`` and the time labels need, whichever is more.
    """
    font_px, m = font_size_px(height), margin_px(height)
    line = font_px + m
    w = max(4 * line, round(width * _INSET_WIDTH_FRACTION))
    h = min(height - 2 * m, max(round(height * _INSET_HEIGHT_FRACTION),
                                2 * line + _INSET_MIN_PLOT_PX + line + 3 * m))
    x0, y1 = width - w // 2, height - m
    x1, y0 = x0 + w, y1 - h
    label_w = round(2.2 * font_px)  # "π/2" (or "pi/2") and a gap
    plot = (x0 + m + label_w, y0 + 2 * m + 2 * line, x1 - 2 * m, y1 - line - m)
    return InsetLayout(box=(x0, y0, x1, y1), plot=plot)


class ThetaInset:
    """The comparison of two tracks drawn into a side-by-side frame (:func:`.video.render_frames`).

    At the bottom, centred on the seam between the panels: "delta theta" (the first track's
    theta minus the second's, at the frame's time) and theta(t) of both tracks from t = 0 up to
    the frame's time, on fixed axes (t from 0 to ``t_axis_s``, theta from 0 to pi). The traces
    are drawn as the band between each pixel column's least and greatest theta, so a nutation
    faster than a pixel shows as a band, not as a sampled line; the second track's trace is
    drawn wider, the first's over it, so both show where they agree.

    Args:
        tracks: The two tracks: the first (left panel, e.g. MuJoCo) and the second (right
            panel, e.g. the reference).
        t_axis_s: The end of the time axis (s): the last frame's time.
        width: Panel width (px).
        height: Panel height (px).

    Attributes:
        layout: Where the inset sits in the side-by-side frame.
    """

    def __init__(self, tracks: Sequence[Track], t_axis_s: float, width: int, height: int
                 ) -> None:
        from PIL import Image, ImageDraw

        self.layout = inset_layout(width, height)
        self._labels = (tracks[0].label, tracks[1].label)
        font_px = font_size_px(height)
        self._font, self._greek = overlay_font(font_px)
        self._m = margin_px(height)
        self._line = font_px + self._m
        bx0, by0, bx1, by1 = self.layout.box
        px0, py0, px1, py1 = self.layout.plot
        self._pw, self._ph = px1 - px0, py1 - py0
        self._t_axis = t_axis_s if t_axis_s > 0 else 1.0
        # plot offsets inside the box
        self._pox, self._poy = px0 - bx0, py0 - by0
        wide = max(1, round(height / 240))  # half-width (px) of the second track's trace
        self._half = (wide - 1, wide)
        self._masks = [self._trace_mask(tr, half) for tr, half in zip(tracks, self._half,
                                                                      strict=True)]
        # The static layer: grid, axis labels, legend (RGBA over the darkened box).
        static = Image.new("RGBA", (bx1 - bx0, by1 - by0), (0, 0, 0, 0))
        d = ImageDraw.Draw(static)
        ox, oy, pw, ph = self._pox, self._poy, self._pw, self._ph
        for frac, label in ((1.0, "π"), (0.5, "π/2"), (0.0, "0")):
            y = oy + self._y_of(frac * math.pi)
            d.line([(ox, y), (ox + pw - 1, y)], fill=(255, 255, 255, 70 if frac == 0.5 else 110))
            d.text((ox - self._m, y), spell(label, self._greek), font=self._font,
                   fill=(255, 255, 255, 230), anchor="rm")
        d.line([(ox, oy), (ox, oy + ph - 1)], fill=(255, 255, 255, 110))
        y_t = oy + ph + self._m // 2
        d.text((ox, y_t), "0", font=self._font, fill=(255, 255, 255, 230), anchor="lt")
        d.text((ox + pw - 1, y_t), f"{self._t_axis:.3g} s", font=self._font,
               fill=(255, 255, 255, 230), anchor="rt")
        d.text((ox + pw // 2, y_t), "t", font=self._font, fill=(255, 255, 255, 230),
               anchor="mt")
        # The legend and the readout: the longest forms that fit the box.
        room = bx1 - bx0 - 3 * self._m
        a, b = self._labels
        a1, b1 = a.split()[0], b.split()[0]  # "reference ODE" -> "reference"
        legends = [("θ(t):", f"■ {a}", f"■ {b}"), ("θ(t):", f"■ {a1}", f"■ {b1}"),
                   ("", f"■ {a1}", f"■ {b1}")]
        legend = next((pieces for pieces in legends if self._font.getlength(
            spell("  ".join(pieces), self._greek)) <= room), legends[-1])
        x = 2 * self._m
        y_legend = self._m + self._line
        for i, piece in enumerate(legend):
            text = spell(piece, self._greek) + "  " if piece else ""
            colour = (255, 255, 255, 230) if i == 0 else (*TRACE_RGB[i - 1], 255)
            d.text((x, y_legend), text, font=self._font, fill=colour)
            x += round(self._font.getlength(text))
        arr = np.asarray(static, dtype=np.float32)
        self._static_rgb, self._static_a = arr[..., :3], arr[..., 3:] / 255.0
        forms = [f"Δθ = θ {a} − θ {b} = {{}}", f"{a} − {b}: Δθ = {{}}",
                 f"Δθ ({a1} − {b1}) = {{}}", "Δθ = {}"]
        widest = "−8.8888 rad"
        self._readout = next((f for f in forms if self._font.getlength(
            spell(f.format(widest), self._greek)) <= room), forms[-1])

    def _y_of(self, theta: np.ndarray | float) -> np.ndarray | float:
        """Row (px, in the plot) of theta: pi at the top row, 0 at the bottom row."""
        frac = np.clip(np.asarray(theta, dtype=float) / math.pi, 0.0, 1.0)
        return np.rint((1.0 - frac) * (self._ph - 1)).astype(int)

    def _trace_mask(self, track: Track, half: int) -> np.ndarray:
        """Pixels (ph, pw) of a track's theta(t) band, ``half`` px thicker on each side."""
        pw, ph = self._pw, self._ph
        sub = int(np.clip(2 * math.ceil(len(track.t_s) * self._t_axis
                                        / max(track.t_end_s, 1e-12) / pw), 4, 64))
        tt = np.linspace(0.0, self._t_axis, pw * sub + 1)
        v = np.interp(tt, track.t_s, track.theta)
        v[tt > track.t_end_s * (1 + 1e-12) + 1e-12] = np.nan  # nothing past the run's end
        # column c spans samples c*sub ... (c+1)*sub: the shared edge joins the columns
        cols = np.stack([v[c * sub:(c + 1) * sub + 1] for c in range(pw)])
        present = ~np.all(np.isnan(cols), axis=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns
            lo, hi = np.nanmin(cols, axis=1), np.nanmax(cols, axis=1)
        top = np.where(present, self._y_of(np.nan_to_num(hi)) - half, ph)
        bottom = np.where(present, self._y_of(np.nan_to_num(lo)) + half, -1)
        rows = np.arange(ph)[:, None]
        return (rows >= top[None, :]) & (rows <= bottom[None, :])

    def draw(self, frame: np.ndarray, samples: Sequence[TrackSample]) -> None:
        """Draw the inset into ``frame`` (the side-by-side RGB frame), in place."""
        from PIL import Image, ImageDraw

        bx0, by0, bx1, by1 = self.layout.box
        box = frame[by0:by1, bx0:bx1].astype(np.float32) * (1.0 - _INSET_OPACITY)
        box = box * (1.0 - self._static_a) + self._static_rgb * self._static_a
        region = box.clip(0, 255).astype(np.uint8)
        t = samples[0].t_s
        ncol = int(np.clip(math.floor(t / self._t_axis * self._pw) + 1, 0, self._pw))
        ox, oy, pw, ph = self._pox, self._poy, self._pw, self._ph
        plot = region[oy:oy + ph, ox:ox + pw]
        for i in (1, 0):  # the second track's wider trace first, the first's over it
            view = plot[:, :ncol]
            view[self._masks[i][:, :ncol]] = TRACE_RGB[i]
        x_now = min(ncol, pw) - 1
        for i in (1, 0):  # the current point of each
            if x_now < 0 or samples[i].ended:
                continue
            y = int(self._y_of(samples[i].theta))
            r = self._half[i] + 1
            plot[max(0, y - r):y + r + 1, max(0, x_now - r):x_now + r + 1] = TRACE_RGB[i]
        delta = round(samples[0].theta - samples[1].theta, 4) + 0.0  # no "-0.0000"
        value = f"{delta:+.4f} rad".replace("-", "−")  # (a run that ended holds its last pose)
        image = Image.fromarray(region)
        ImageDraw.Draw(image).text((2 * self._m, self._m),
                                   spell(self._readout.format(value), self._greek),
                                   font=self._font, fill=(255, 255, 255))
        frame[by0:by1, bx0:bx1] = np.asarray(image)


__all__ = ["InsetLayout", "TRACE_RGB", "ThetaInset", "inset_layout"]
