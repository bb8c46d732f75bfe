"""The engines against each other and the theory: the ``tippetop`` command line and its rooms.

Its rooms, each importing only those before it: :mod:`.measures` (pure measurements and the
verdict), :mod:`.running` (plans run, in parallel and cached), :mod:`.presentation` (text,
figures and video frames for a person), :mod:`.studies` (the work behind each measuring
command), :mod:`.report` (the HTML reports) and :mod:`.nightly` (the regression suite),
:mod:`.commands` (the commands) and :mod:`.cli` (the ``tippetop`` parser).
``tests/test_layers.py`` holds the order.
"""

# before any module of this package imports mujoco: no OpenGL unless asked (see there)
import tippetop.mujoco_runner  # noqa: F401
