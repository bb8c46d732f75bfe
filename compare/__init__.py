"""The engines against each other and the theory: the ``tippetop`` command line and its rooms.

:mod:`.cli` and :mod:`.commands` (the commands), :mod:`.analysis`, :mod:`.running`,
:mod:`.presentation`, :mod:`.nightly` and :mod:`.report`.
"""

# before any module of this package imports mujoco: no OpenGL unless asked (see there)
import tippetop.mujoco_runner  # noqa: F401
