"""Nightly videos: a short side-by-side MP4 per paper scene, linked from the report."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from tippetop.compare.nightly.catalogue import Case
from tippetop.compare.nightly.outputs import slug
from tippetop.models.errors import TippetopError

#: Nightly videos: small, side by side (MuJoCo | reference), at most this many frames each.
VIDEO_SIZE = (320, 240)
VIDEO_FPS = 15.0
VIDEO_MAX_FRAMES = 240
VIDEO_OVERRIDES = ("mujoco.timestep_s=1e-4",)  # paper mode is within 3e-4 rad of 1.25e-5 s


def render_videos(cases: Sequence[Case], out_dir: Path,
                  log: Callable[[str], None]) -> dict[str, Any]:
    """Render one short side-by-side video per scene of the profile's ``paper`` run cases.

    The playback speed is chosen so that a video has at most ``VIDEO_MAX_FRAMES`` frames (at
    least quarter-speed slow motion). Returns what the report links: scene -> relative path.
    """
    from tippetop.compare.render import render_scene
    from tippetop.models.scene import load_scene

    scenes = sorted({c.scene for c in cases if c.kind == "run" and c.category == "paper"})
    (out_dir / "videos").mkdir(parents=True, exist_ok=True)
    files: dict[str, str] = {}
    failed: dict[str, str] = {}
    for name in scenes:
        scene = load_scene(name, list(VIDEO_OVERRIDES))
        speed = max(0.25, scene.run.t_end_s * VIDEO_FPS / VIDEO_MAX_FRAMES)
        rel = f"videos/{slug(name)}.mp4"
        log(f"nightly: rendering {rel} (speed {speed:.3g})")
        try:
            render_scene(scene, out_dir / rel, engine="both", fps=VIDEO_FPS, speed=speed,
                         size=VIDEO_SIZE, max_frames=VIDEO_MAX_FRAMES, force=True,
                         progress=False)
            files[name] = rel
        except TippetopError as exc:
            failed[name] = str(exc)
    status = f"{len(files)} written" + (f", {len(failed)} failed" if failed else "")
    return {"requested": True, "status": status, "files": files, "failed": failed}
