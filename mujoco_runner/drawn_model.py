"""The model that :mod:`.video` draws: a top compiled for the picture, never simulated.

:func:`render_model` compiles a scene's own top as :func:`models.mjcf.make_mjcf` makes it, with
a checker texture on the ball so that spin shows (a ``top.mjcf`` top is drawn as its file
says), adds a sky, draws the table translucent so that a stem pointing into it still shows (the
paper's loaded sphere has no stem: the drawn one is a visual marker of the axis, which pokes
through the table once the top has turned over), and sets the offscreen buffer and the render
quality. All of it is visual: the mass, inertia and geometry are those of the MJCF, and poses
are set on the model, never simulated.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np

from tippetop.models.mjcf import make_mjcf
from tippetop.models.params import TopParams
from tippetop.mujoco_runner.model import TopModel, TopModelWarning, load_top, top_from_model

# The table is translucent (visual only), so that a stem pointing into it still shows; the
# emission makes up for the light a translucent plane loses.
_TABLE_ALPHA = 0.5
_TABLE_EMISSION = 0.6
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
    _translucent_table(top_model.model)
    top_model.model.vis.quality.shadowsize = _SHADOW_PX
    top_model.model.vis.quality.offsamples = _OFFSAMPLES
    vis = top_model.model.vis.global_
    vis.offwidth = max(int(vis.offwidth), width)
    vis.offheight = max(int(vis.offheight), height)
    return top_model


def _translucent_table(model: mujoco.MjModel) -> None:
    """Make the world's planes (the table) translucent, in place: a stem below shows through."""
    planes = np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
                            & (model.geom_bodyid == 0))
    for g in planes:
        mat = int(model.geom_matid[g])
        if mat >= 0:
            model.mat_rgba[mat, 3] = _TABLE_ALPHA
            model.mat_reflectance[mat] = 0.0  # a mirror under a translucent plane: confusing
            model.mat_emission[mat] = max(float(model.mat_emission[mat]), _TABLE_EMISSION)
        else:
            model.geom_rgba[g, 3] = _TABLE_ALPHA


__all__ = ["render_model"]
