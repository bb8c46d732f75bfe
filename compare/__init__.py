"""The paper's theory as formulas, metrics, cross-engine checks and the command line."""

# before any module of this package imports mujoco: no OpenGL unless asked (see there)
import tippetop.mujoco_runner  # noqa: F401
