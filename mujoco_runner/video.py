"""Offscreen frames of a run and their H.264 MP4: the drawing half of ``tippetop render``.

Imported only when a video is asked for: :mod:`mujoco_runner.render` chooses the OpenGL backend
(``MUJOCO_GL``) first, and this module creates the context of that backend explicitly, so it
works even when ``mujoco`` was imported earlier in the process with another ``MUJOCO_GL``.

* :func:`render_model`: the model that is drawn. For a scene's own top it is
  :func:`models.mjcf.make_mjcf` with a two-colour checker texture on the ball (visual only: the
  mass, inertia and geometry are those of the MJCF, and poses are set, never simulated). A
  scene with ``top.mjcf`` is drawn as its file says.
* :class:`Track`: an engine's sampled poses (the table's x, y, z, qw, qx, qy, qz), theta and n,
  interpolated at any time (position linearly, orientation by slerp) and mapped to the free
  joint's qpos. Replaying a track is kinematic: qpos is set, then ``mj_forward``.
* :class:`OffscreenRenderer`: a context-managed EGL or OSMesa renderer of one model.
* :func:`write_video`: frames at the given simulated times, one panel per track side by side,
  each with a text overlay (engine, t, theta, n), encoded by imageio-ffmpeg's bundled ffmpeg
  (libx264, yuv420p).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import mujoco
import numpy as np
import pandas as pd

from tippetop.models.errors import TippetopError
from tippetop.models.frames import quat_mul, quat_to_mat
from tippetop.models.mjcf import make_mjcf
from tippetop.models.params import TopParams
from tippetop.mujoco_runner.gl import BACKEND_PACKAGES
from tippetop.mujoco_runner.model import TopModel, TopModelWarning, load_top, top_from_model

# The camera follows the top's centre of mass at a fixed bearing (it translates, never turns).
_CAM_DISTANCE_R = 9.0  # (sphere radii) from the centre of mass
_CAM_ELEVATION_DEG = -25.0  # looking down at the table
_CAM_AZIMUTH_DEG = 120.0
# The ball's checker texture, so that spin shows in any orientation (visual only).
_BALL_TEXTURE = "render_ball_checks"
_BALL_RGB = ((0.85, 0.3, 0.15), (0.96, 0.92, 0.82))
_BALL_TEXTURE_PX = 64  # per cube face
# A sky instead of black above the horizon (visual only).
_SKY_TEXTURE = "render_sky"
_SKY_RGB = ((0.62, 0.75, 0.9), (0.95, 0.96, 0.98))
_SKY_TEXTURE_PX = 128
# Shadow map (px): MuJoCo's default 4096 triples the time of a 640x480 frame on a CPU renderer.
_SHADOW_PX = 1024
# Multisampling (anti-aliasing) samples: MuJoCo's default 4 more than doubles the time of a
# frame on a CPU renderer; H.264 softens the edges anyway.
_OFFSAMPLES = 0
_MAX_GEOM = 1000  # drawn geoms: make_mjcf has 4, an MJCF top may have more
# Text overlay, relative to the panel height.
_FONT_FRACTION = 1 / 22  # font size
_MIN_FONT_PX = 9
_TEXT_MARGIN_FRACTION = 1 / 60
_TEXT_BOX_OPACITY = 0.55  # the text's box darkens what is behind it
# H.264 settings: constant quality (x264's CRF, lower is better) and the encoder's speed preset.
_CRF = 20
_X264_PRESET = "veryfast"


# ---------------------------------------------------------------- the model that is drawn
def render_model(top: TopParams, mjcf: Path | None, width: int, height: int) -> TopModel:
    """The top to draw, with an offscreen buffer of at least ``width x height``.

    Args:
        top: The top's parameters (a run plan's): drawn as :func:`models.mjcf.make_mjcf` makes
            it, with a checker texture on the ball, unless ``mjcf`` is given.
        mjcf: A loaded top's MJCF file, drawn as is.
        width: Panel width (px).
        height: Panel height (px).

    Returns:
        The compiled model and where the top sits in it.
    """
    if mjcf is not None:
        load_top(mjcf)  # validates the file with the harness's messages
        spec = mujoco.MjSpec.from_file(str(mjcf))
    else:
        spec = mujoco.MjSpec.from_string(make_mjcf(top))
        ball_mat = next((m for m in spec.materials if m.name == "ball_mat"), None)
        if ball_mat is not None:
            spec.add_texture(name=_BALL_TEXTURE, type=mujoco.mjtTexture.mjTEXTURE_CUBE,
                             builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                             width=_BALL_TEXTURE_PX, height=_BALL_TEXTURE_PX,
                             rgb1=list(_BALL_RGB[0]), rgb2=list(_BALL_RGB[1]))
            textures = list(ball_mat.textures)
            textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = _BALL_TEXTURE
            ball_mat.textures = textures
            ball_mat.rgba = [1.0, 1.0, 1.0, 1.0]
    if not any(t.type == mujoco.mjtTexture.mjTEXTURE_SKYBOX for t in spec.textures):
        spec.add_texture(name=_SKY_TEXTURE, type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=_SKY_TEXTURE_PX,
                         height=_SKY_TEXTURE_PX, rgb1=list(_SKY_RGB[0]), rgb2=list(_SKY_RGB[1]))
    with warnings.catch_warnings():  # load_top has warned about this top already
        warnings.simplefilter("ignore", TopModelWarning)
        top_model = top_from_model(spec.compile())
    top_model.model.vis.quality.shadowsize = _SHADOW_PX
    top_model.model.vis.quality.offsamples = _OFFSAMPLES
    vis = top_model.model.vis.global_
    vis.offwidth = max(int(vis.offwidth), width)
    vis.offheight = max(int(vis.offheight), height)
    return top_model


# ---------------------------------------------------------------- poses from a table
def _slerp(q0: np.ndarray, q1: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Row-wise spherical interpolation of unit quaternions (n, 4) at fractions alpha (n,).

    Takes the shorter arc (q and -q are the same rotation); alpha = 0 returns q0 exactly.
    """
    dot = np.einsum("ni,ni->n", q0, q1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot).clip(max=1.0)
    angle = np.arccos(dot)
    small = angle < 1e-8
    sin = np.where(small, 1.0, np.sin(angle))
    w0 = np.where(small, 1.0 - alpha, np.sin((1.0 - alpha) * angle) / sin)
    w1 = np.where(small, alpha, np.sin(alpha * angle) / sin)
    q = w0[:, None] * q0 + w1[:, None] * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


@dataclass(frozen=True)
class TrackSample:
    """An engine's state at one frame time.

    Attributes:
        t_s: The frame's simulated time (s).
        qpos: The free joint's qpos (7,) in the drawn model: body origin (m), quaternion.
        theta: Tilt of the symmetry axis (rad).
        n: Spin about the symmetry axis (rad/s).
        ended: True past the end of the engine's table (the last pose is held).
    """

    t_s: float
    qpos: np.ndarray
    theta: float
    n: float
    ended: bool


@dataclass(frozen=True)
class Track:
    """An engine's sampled poses, interpolated at frame times.

    Attributes:
        label: The panel's title, e.g. ``"MuJoCo"``.
        t_s: Sample times (s), increasing, shape (m,).
        com_m: Centre of mass O (m), shape (m, 3).
        quat: Orientation (w, x, y, z) of the drawn model's body, unit, shape (m, 4).
        theta: Tilt (rad), shape (m,).
        n: Spin (rad/s), shape (m,).
        top_model: The drawn model (where S and k sit in its body).
    """

    label: str
    t_s: np.ndarray
    com_m: np.ndarray
    quat: np.ndarray
    theta: np.ndarray
    n: np.ndarray
    top_model: TopModel

    @classmethod
    def from_table(cls, table: pd.DataFrame, top_model: TopModel, *, label: str,
                   paper_frame: bool) -> Track:
        """A track from an observables table.

        Args:
            table: Columns t, theta, n, x, y, z, qw, qx, qy, qz (:mod:`models.observables`).
            top_model: The drawn model.
            label: The panel's title.
            paper_frame: True when the table's quaternion is the paper's body frame (z axis = k,
                the reference ODE's); False when it is the MJCF body's own frame (MuJoCo's).

        Raises:
            TippetopError: If the table has no rows.
        """
        if len(table) == 0:
            raise TippetopError(f"{label} table: expected at least one row to draw, got none")
        quat = np.array(table[["qw", "qx", "qy", "qz"]], dtype=float)
        if paper_frame:
            quat = np.array([quat_mul(q, top_model.paper_from_body_quat) for q in quat])
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        return cls(label=label, t_s=table["t"].to_numpy(dtype=float),
                   com_m=table[["x", "y", "z"]].to_numpy(dtype=float), quat=quat,
                   theta=table["theta"].to_numpy(dtype=float),
                   n=table["n"].to_numpy(dtype=float), top_model=top_model)

    @property
    def t_end_s(self) -> float:
        """The last sample time (s)."""
        return float(self.t_s[-1])

    def _qpos(self, com_m: np.ndarray, quat: np.ndarray) -> np.ndarray:
        """Free-joint qpos (n, 7) of centre-of-mass positions (n, 3) and body quaternions (n, 4).

        The body origin is S - rot c, with S = O + a k the sphere's centre, k = rot k_body and
        c the sphere's centre in the body frame (zero for make_mjcf tops, where qpos[:3] = S).
        """
        tm = self.top_model
        rot = np.array([quat_to_mat(q) for q in quat])  # (n, 3, 3), body to world
        k = np.einsum("nij,j->ni", rot, tm.axis_body)
        origin = com_m + tm.top.a_m * k - np.einsum("nij,j->ni", rot, tm.centre_body_m)
        return np.concatenate([origin, quat], axis=1)

    def at(self, times_s: Sequence[float] | np.ndarray) -> list[TrackSample]:
        """The interpolated state at each time; past the last sample the last one is held."""
        t = np.asarray(times_s, dtype=float)
        ts = self.t_s
        if len(ts) == 1:
            i = np.zeros(len(t), dtype=int)
            j, alpha = i, np.zeros(len(t))
        else:
            i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
            j = i + 1
            alpha = np.clip((t - ts[i]) / (ts[j] - ts[i]), 0.0, 1.0)
        com = self.com_m[i] + alpha[:, None] * (self.com_m[j] - self.com_m[i])
        quat = _slerp(self.quat[i], self.quat[j], alpha)
        theta = self.theta[i] + alpha * (self.theta[j] - self.theta[i])
        n = self.n[i] + alpha * (self.n[j] - self.n[i])
        qpos = self._qpos(com, quat)
        ended = t > self.t_end_s * (1 + 1e-12) + 1e-12
        return [TrackSample(float(t[r]), qpos[r], float(theta[r]), float(n[r]), bool(ended[r]))
                for r in range(len(t))]


def set_pose(top_model: TopModel, data: mujoco.MjData, qpos: np.ndarray) -> None:
    """Put the top at ``qpos`` (7,), at rest, and compute positions (``mj_forward``)."""
    adr = top_model.qpos_adr
    data.qpos[adr:adr + 7] = qpos
    data.qvel[:] = 0.0
    mujoco.mj_forward(top_model.model, data)


# ---------------------------------------------------------------- the renderer
def _gl_context_class(backend: str) -> type:
    """The GLContext class (from mujoco) of an offscreen backend (``egl`` or ``osmesa``)."""
    try:
        if backend == "egl":
            from mujoco.egl import GLContext
        elif backend == "osmesa":
            from mujoco.osmesa import GLContext
        else:
            raise TippetopError(f"MUJOCO_GL: expected egl or osmesa, got {backend!r}")
    except ImportError as exc:
        raise backend_error(backend, exc) from None
    return GLContext


def backend_error(backend: str, exc: BaseException) -> TippetopError:
    """The one-line error for a backend that does not work, naming the packages to install."""
    first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    other = "osmesa" if backend == "egl" else "egl"
    return TippetopError(
        f"MUJOCO_GL={backend}: expected a working offscreen OpenGL context, got "
        f"{type(exc).__name__}: {first} (install Debian's {BACKEND_PACKAGES[backend]}, or "
        f"{BACKEND_PACKAGES[other]} and set MUJOCO_GL={other})")


class OffscreenRenderer:
    """Draws one model into an RGB array with an EGL or OSMesa context.

    Like ``mujoco.Renderer``, but the OpenGL context is that of ``backend`` whatever
    ``MUJOCO_GL`` was when ``mujoco`` was imported. Use it as a context manager (or call
    :meth:`close`) to free the OpenGL resources.

    Args:
        model: The model (its offscreen buffer must be at least width x height).
        width: Image width (px).
        height: Image height (px).
        backend: ``"egl"`` or ``"osmesa"``.

    Raises:
        TippetopError: If the backend's context cannot be created.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, backend: str) -> None:
        self._gl = None
        self._con = None
        self._model = model
        self.width, self.height = width, height
        context_class = _gl_context_class(backend)
        try:
            self._gl = context_class(width, height)
            self._gl.make_current()
            self._con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100.value)
        except Exception as exc:  # any failure of the native libraries is a missing backend
            self.close()
            raise backend_error(backend, exc) from None
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._con)
        self._scene = mujoco.MjvScene(model, maxgeom=_MAX_GEOM)
        self._option = mujoco.MjvOption()
        self._rect = mujoco.MjrRect(0, 0, width, height)

    def render(self, data: mujoco.MjData, camera: mujoco.MjvCamera) -> np.ndarray:
        """The picture of ``data`` seen by ``camera``: uint8 RGB, shape (height, width, 3)."""
        if self._con is None:
            raise RuntimeError("render called after close")
        self._gl.make_current()
        mujoco.mjv_updateScene(self._model, data, self._option, None, camera,
                               mujoco.mjtCatBit.mjCAT_ALL.value, self._scene)
        mujoco.mjr_render(self._rect, self._scene, self._con)
        rgb = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(rgb, None, self._rect, self._con)
        return np.flipud(rgb)

    def close(self) -> None:
        """Free the MuJoCo render context and the OpenGL context (idempotent)."""
        if self._con is not None:
            if self._gl is not None:
                with self._gl.as_current():
                    self._con.free()
            else:
                self._con.free()
        self._con = None
        if self._gl is not None:
            self._gl.free()
        self._gl = None

    def __enter__(self) -> OffscreenRenderer:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def tracking_camera(top_model: TopModel) -> mujoco.MjvCamera:
    """A camera that follows the top's centre of mass, looking down at it from a fixed bearing."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    cam.trackbodyid = top_model.body_id
    cam.distance = _CAM_DISTANCE_R * top_model.top.R_m
    cam.elevation = _CAM_ELEVATION_DEG
    cam.azimuth = _CAM_AZIMUTH_DEG
    return cam


# ---------------------------------------------------------------- overlay
class _Overlay:
    """Draws a panel's title and t, theta and n into the top-left corner of a frame."""

    def __init__(self, height: int) -> None:
        from PIL import ImageFont

        self._size = max(_MIN_FONT_PX, round(height * _FONT_FRACTION))
        self._font = ImageFont.load_default(size=self._size)
        self._margin = max(2, round(height * _TEXT_MARGIN_FRACTION))

    def draw(self, rgb: np.ndarray, label: str, s: TrackSample) -> np.ndarray:
        """A copy of ``rgb`` (h, w, 3) with the text drawn on a darkened box."""
        from PIL import Image, ImageDraw

        lines = [label, f"t = {s.t_s:.3f} s", f"theta = {s.theta:.3f} rad",
                 f"n = {s.n:.1f} rad/s"]
        if s.ended:
            lines.append("(run ended)")
        text = "\n".join(lines)
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


# ---------------------------------------------------------------- encoder
class _Mp4Writer:
    """Streams RGB frames to ffmpeg (imageio-ffmpeg's bundled binary): H.264, yuv420p, MP4."""

    def __init__(self, path: Path, width: int, height: int, fps: float) -> None:
        import imageio_ffmpeg

        self._gen = imageio_ffmpeg.write_frames(
            str(path), (width, height), pix_fmt_in="rgb24", pix_fmt_out="yuv420p", fps=fps,
            codec="libx264", quality=None, macro_block_size=1, ffmpeg_log_level="error",
            output_params=["-crf", str(_CRF), "-preset", _X264_PRESET,
                           "-movflags", "+faststart", "-f", "mp4"])
        self._gen.send(None)

    def write(self, rgb: np.ndarray) -> None:
        """Append one frame, uint8 RGB of shape (height, width, 3)."""
        self._gen.send(np.ascontiguousarray(rgb))

    def close(self) -> None:
        """Finish the file (waits for ffmpeg)."""
        self._gen.close()


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

    Returns:
        Frame count, size and wall time.
    """
    top_model = tracks[0].top_model
    model = top_model.model
    datas = [mujoco.MjData(model) for _ in tracks]
    cameras = [tracking_camera(top_model) for _ in tracks]
    samples = [track.at(times_s) for track in tracks]
    overlay = _Overlay(height)
    start = time.perf_counter()
    with OffscreenRenderer(model, width, height, backend) as renderer:
        writer = _Mp4Writer(path, width * len(tracks), height, fps)
        try:
            for f in range(len(times_s)):
                panels = []
                for track, data, cam, track_samples in zip(tracks, datas, cameras, samples,
                                                            strict=True):
                    s = track_samples[f]
                    set_pose(top_model, data, s.qpos)
                    panels.append(overlay.draw(renderer.render(data, cam), track.label, s))
                writer.write(np.concatenate(panels, axis=1))
                if on_frame is not None:
                    on_frame()
        finally:
            writer.close()
    return VideoStats(len(times_s), width * len(tracks), height, time.perf_counter() - start)


def frame_times(n_frames: int, fps: float, speed: float) -> np.ndarray:
    """Simulated time of each frame (s): frame k shows t = k speed / fps."""
    return np.arange(n_frames) * (speed / fps)


__all__ = [
    "OffscreenRenderer",
    "Track",
    "TrackSample",
    "VideoStats",
    "backend_error",
    "frame_times",
    "render_model",
    "set_pose",
    "tracking_camera",
    "write_video",
]

