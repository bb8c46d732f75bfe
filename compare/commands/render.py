"""``tippetop render``: an offscreen H.264 MP4 of a run, MuJoCo's, the reference's or both.

``--engine mujoco`` or ``--engine ode`` draws one; ``--engines mujoco,ode`` both side by side;
``--mode`` is MuJoCo's mode.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from tippetop.compare.commands.options import (
    MODE_HELP,
    add_force_option,
    add_mode_option,
    add_set_option,
    load_scene,
)
from tippetop.compare.presentation.video import (
    DEFAULT_FPS,
    DEFAULT_MAX_FRAMES,
    DEFAULT_SIZE,
    DEFAULT_SPEED,
)
from tippetop.models.errors import TippetopError

if TYPE_CHECKING:
    from tippetop.compare.studies.render import RenderResult


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop render`` and its options."""
    p = sub.add_parser(
        "render", help="an offscreen H.264 MP4 of a run (MuJoCo, reference ODE or both)",
        description="Simulate a scene and write an MP4: MuJoCo's run, the reference ODE "
        "replayed in the same MJCF, or both side by side. Needs an offscreen OpenGL backend "
        "(MUJOCO_GL=egl or osmesa; unset picks one).")
    p.add_argument("scene", nargs="?", help="scene .toml file or catalogue name (default: the "
                   "paper's top and Fig. 3 start)")
    p.add_argument("--engine", metavar="ENGINE", help="the engine whose run is drawn: mujoco "
                   "(the MuJoCo installed with tippetop) or ode (the reference replayed in the "
                   "same MJCF) (default mujoco)")
    p.add_argument("--engines", metavar="ENGINE,...", help="the engines drawn side by side: "
                   "mujoco,ode, MuJoCo left, same time base and camera (default: --engine's "
                   "one)")
    add_mode_option(p, default="the scene's: paper for a generated top, file for an MJCF top",
                    help="MuJoCo's mode: " + MODE_HELP.removeprefix(
                        "how the contact force is made: ").split(", coulomb")[0])
    p.add_argument("--out", metavar="FILE", help="the .mp4 file (default: <scene name>.mp4 "
                   "in the current folder)")
    p.add_argument("--fps", type=float, default=DEFAULT_FPS, metavar="FPS",
                   help=f"frames per second of video (default {DEFAULT_FPS:g})")
    p.add_argument("--speed", type=float, default=DEFAULT_SPEED, metavar="X",
                   help="simulated seconds per second of video: 0.25 is quarter-speed slow "
                   f"motion, 1 real time (default {DEFAULT_SPEED:g})")
    p.add_argument("--size", default=DEFAULT_SIZE, metavar="WxH",
                   help=f"WIDTHxHEIGHT of one panel in px (default {DEFAULT_SIZE})")
    p.add_argument("--max-frames", dest="max_frames", type=int, default=DEFAULT_MAX_FRAMES,
                   metavar="N", help=f"refuse a video of more frames than this, before "
                   f"simulating (default {DEFAULT_MAX_FRAMES})")
    add_force_option(p)
    add_set_option(p, help="override a scene key, e.g. run.t_end_s=4; units as the key's "
                   "name says; repeatable (default: the scene as written)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop render``: simulate and write the video; exit 0, or 1 for a failed run."""
    from tippetop.compare.studies.render import (
        RunFailed,
        VideoOptions,
        VideoWriteFailed,
        render_scene,
    )

    engines = _engines(args)
    scene = load_scene(args)
    out = args.out if args.out else f"{scene.name}.mp4"
    try:
        res = render_scene(scene, out, engines=engines, mode=args.mode,
                           video=VideoOptions(fps=args.fps, speed=args.speed, size=args.size,
                                              max_frames=args.max_frames),
                           force=args.force, say=_say)
    except RunFailed as exc:
        sys.stderr.write(f"tippetop: run failed: {exc}\n")
        return 1
    except VideoWriteFailed as exc:
        sys.stderr.write(f"tippetop: video failed: {exc}\n")
        return 1
    print(summary_line(res, scene.run.t_end_s))
    return 0


def summary_line(res: RenderResult, t_end_s: float) -> str:
    """What was written, every number in four significant digits with its unit.

    ``wrote fig3.mp4: 29 frames 160x120, 0.9667 s of video at 30 fps for 8 s simulated
    (--speed 8.3); egl, 26.53 ms a frame``.

    Args:
        res: The video written (:func:`tippetop.compare.studies.render.render_scene`'s).
        t_end_s: The simulated time it shows (s).
    """
    from tippetop.compare.presentation.terminal import fmt, fmt_duration

    return (f"wrote {res.path}: {fmt(res.n_frames)} frames {res.width}x{res.height}, "
            f"{fmt(float(res.video_s), 's')} of video at {fmt(float(res.fps))} fps for "
            f"{fmt(float(t_end_s), 's')} simulated (--speed {res.speed:g}); {res.backend}, "
            f"{fmt_duration(res.ms_per_frame / 1e3)} a frame")


def _engines(args: argparse.Namespace) -> tuple[str, ...]:
    """The engines drawn, from ``--engine`` or ``--engines``.

    ``--engine both``, the release before's spelling of ``--engines mujoco,ode``, is read with
    a note.

    Raises:
        TippetopError: Both options at once (one line).
    """
    if args.engine and args.engines:
        raise TippetopError(f"--engines: expected --engine or --engines, got --engine "
                            f"{args.engine} and --engines {args.engines}")
    from tippetop.models.spellings import old_engine_words

    both = old_engine_words(args.engine)
    if both is not None:
        return both
    if args.engines:
        return tuple(e.strip() for e in args.engines.split(",") if e.strip())
    return (args.engine or "mujoco",)


def _say(line: str) -> None:
    """A progress line on stderr, at once."""
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
