"""Offscreen OpenGL for MuJoCo's renderer: EGL or OSMesa, chosen before ``import mujoco``.

``MUJOCO_GL`` may name the backend (``egl`` or ``osmesa``); unset, EGL is used when its
libraries can open a device and OSMesa otherwise, and the choice is written to ``MUJOCO_GL``
(read by ``mujoco`` when it is imported). Only the standard library is imported here: the checks
use the C libraries through ctypes.
"""

from __future__ import annotations

import ctypes
import os

from tippetop.models.errors import TippetopError, expect
from tippetop.mujoco_runner import gl_requested

#: Offscreen OpenGL backends, in the order they are tried, with the Debian packages they need.
OFFSCREEN_BACKENDS: tuple[str, ...] = ("egl", "osmesa")
BACKEND_PACKAGES = {"egl": "libegl1 libopengl0 libgl1-mesa-dri", "osmesa": "libosmesa6"}

_EGL_PLATFORM_DEVICE_EXT = 0x313F  # EGL_EXT_platform_device
_EGL_MAX_DEVICES = 16


def _egl_problem() -> str | None:
    """None if EGL can open and initialise a device (checked with ctypes), else the reason.

    Uses the C library directly, not PyOpenGL, whose platform is fixed for the process once it
    is imported: a failed EGL attempt must leave OSMesa still possible.
    """
    try:
        egl = ctypes.CDLL("libEGL.so.1")
        ctypes.CDLL("libOpenGL.so.0")
    except OSError as exc:
        return str(exc)
    proc = egl.eglGetProcAddress
    proc.restype, proc.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
    query_addr = proc(b"eglQueryDevicesEXT")
    display_addr = proc(b"eglGetPlatformDisplayEXT")
    if not query_addr or not display_addr:
        return "libEGL has no device platform (EGL_EXT_device_enumeration)"
    query = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p),
                             ctypes.POINTER(ctypes.c_int))(query_addr)
    get_display = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p,
                                   ctypes.c_void_p)(display_addr)
    egl.eglInitialize.restype = ctypes.c_uint
    egl.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
    devices = (ctypes.c_void_p * _EGL_MAX_DEVICES)()
    count = ctypes.c_int(0)
    if not query(_EGL_MAX_DEVICES, devices, ctypes.byref(count)) or count.value < 1:
        return "no EGL device (Mesa's drivers missing?)"
    for i in range(count.value):
        display = get_display(_EGL_PLATFORM_DEVICE_EXT, devices[i], None)
        # Left initialised: the display of a device is shared in the process (mujoco.egl's
        # included), and initialising it again is a no-op, terminating it is not.
        if display and egl.eglInitialize(display, None, None):
            return None
    return f"none of {count.value} EGL devices could be initialised"


def _osmesa_problem() -> str | None:
    """None if the OSMesa library loads, else the reason."""
    try:
        ctypes.CDLL("libOSMesa.so.8")
    except OSError as exc:
        return str(exc)
    return None


def choose_gl_backend() -> str:
    """The offscreen backend: ``MUJOCO_GL`` if set, else egl if it works, else osmesa.

    Raises:
        TippetopError: If ``MUJOCO_GL`` names something other than egl or osmesa, or neither
            works; the message names the Debian packages to install.
    """
    requested = gl_requested()
    if requested:
        expect(requested in OFFSCREEN_BACKENDS, "MUJOCO_GL",
               "egl or osmesa (offscreen rendering), or unset to pick one", requested)
        return requested
    problems = []
    for backend, problem in (("egl", _egl_problem), ("osmesa", _osmesa_problem)):
        reason = problem()
        if reason is None:
            return backend
        problems.append(f"{backend}: {reason}")
    raise TippetopError(
        "MUJOCO_GL: expected a working offscreen OpenGL backend, got none ("
        + "; ".join(problems) + f"); install Debian's {BACKEND_PACKAGES['egl']} (EGL) or "
        f"{BACKEND_PACKAGES['osmesa']} (OSMesa)")


def use_gl_backend() -> str:
    """Choose the backend and write it to ``MUJOCO_GL`` (read by ``mujoco`` when imported)."""
    backend = choose_gl_backend()
    os.environ["MUJOCO_GL"] = backend
    return backend


__all__ = ["BACKEND_PACKAGES", "OFFSCREEN_BACKENDS", "choose_gl_backend", "use_gl_backend"]
