"""MuJoCo: MJCF loading, stepping in the requested friction mode, observables.

Importing this package (before any of its modules imports ``mujoco``) sets ``MUJOCO_GL`` to
:data:`NO_GL` when the user has not set it: the simulation needs no OpenGL, and with
``MUJOCO_GL`` unset ``import mujoco`` starts a subprocess per GLFW library it finds (what that
did to a stopped command: tests/compare/test_faults_signals.py). Worker processes inherit the
setting. Offscreen rendering picks its own backend (:mod:`.gl`), and reads :data:`NO_GL` as
unset (:func:`gl_requested`).
"""

from __future__ import annotations

import os as _os

#: What ``MUJOCO_GL`` is set to when the user leaves it unset: no OpenGL at ``import mujoco``.
NO_GL = "disable"

if not _os.environ.get("MUJOCO_GL", "").strip():
    _os.environ["MUJOCO_GL"] = NO_GL


def gl_requested() -> str:
    """The offscreen backend ``MUJOCO_GL`` asks for, lower case; ``""``: unset or :data:`NO_GL`."""
    value = _os.environ.get("MUJOCO_GL", "").strip().lower()
    return "" if value == NO_GL else value


__all__ = ["NO_GL", "gl_requested"]
