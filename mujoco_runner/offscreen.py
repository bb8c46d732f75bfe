"""Offscreen pictures of one MuJoCo model, and the camera that follows the top.

:class:`OffscreenRenderer` creates the OpenGL context of the backend it is given (EGL or OSMesa,
chosen by :mod:`.gl`) explicitly, so it works even when ``mujoco`` was imported earlier in the
process with another ``MUJOCO_GL``; a backend that does not work is one line that names the
Debian packages to install (:func:`backend_error`). :func:`tracking_camera` looks at the top low
over the table and from the side, so that the stem of a top that turns over shows beside the ball
instead of hiding under it.
"""

from __future__ import annotations

from types import TracebackType

import mujoco
import numpy as np

from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner.gl import BACKEND_PACKAGES
from tippetop.mujoco_runner.model import TopModel

# The camera follows the top's centre of mass at a fixed bearing (it translates, never turns).
# Low and to the side: from above (25 degrees, as before) the stem of a top that turns over
# hides under the ball; from 10 degrees it shows beside it.
_CAM_DISTANCE_R = 9.0  # (sphere radii) from the centre of mass
_CAM_ELEVATION_DEG = -10.0  # looking down at the table, just
_CAM_AZIMUTH_DEG = 60.0
_MAX_GEOM = 1000  # drawn geoms: make_mjcf has 4, an MJCF top may have more


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


__all__ = ["OffscreenRenderer", "backend_error", "tracking_camera"]
