"""``tippetop mjcf``: write the MuJoCo model a run compiles, to step without tippetop."""

from __future__ import annotations

import argparse
import os
import sys

from tippetop.compare.commands.options import (
    add_engine_option,
    add_force_option,
    add_json_option,
    add_mode_option,
    add_scene_options,
    add_set_option,
    engine_and_mode,
    load_scene,
    print_json,
)

DESCRIPTION = (
    "Write the MuJoCo model of a scene exactly as 'tippetop simulate' compiles and steps it: "
    "the mode, the contact settings (condim, friction, solref, solimp) and the "
    "options (timestep, integrator, cone, impratio, noslip iterations, gravity) of the run, "
    "with the run's initial state as the keyframe 'tippetop_start'. Loaded with "
    "mujoco.MjModel.from_xml_path, reset with mj_resetDataKeyframe and stepped with mj_step, "
    "a native-mode file IS the run, bit for bit. Paper mode's friction law is applied by "
    "tippetop's compiled callback and cannot be in a file: its contacts are frictionless "
    "(condim 1), and the file says so in a comment at its top (and a note on stderr).")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop mjcf`` and its options."""
    p = sub.add_parser("mjcf", help="write a scene's MuJoCo model as a run compiles it",
                       description=DESCRIPTION)
    add_scene_options(p)
    add_engine_option(p, default="mujoco", help="the MuJoCo engine whose run's model is "
                      "written: mujoco, mujoco==X.Y.Z, mujoco@PYTHON, mjx, mjx-f32 or warp (its "
                      "model is the plan's, compiled here)")
    add_mode_option(p)
    add_set_option(p)
    p.add_argument("--out", metavar="FILE.xml", required=True, help="the MJCF file to write, "
                   "in an existing folder (no default: required)")
    add_force_option(p, help="overwrite an existing --out file")
    add_json_option(p, help="print one JSON object on stdout instead of text: out, scene, "
                    "engine, mode, source, keyframe, keyframe_index, t_end_s (s), "
                    "friction_in_file, note and ran (the settings read back from the model)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop mjcf``: write the run's model; exit 2 for bad input, nothing written."""
    from tippetop.compare.running.io import check_output_path
    from tippetop.compare.running.mjcf_export import write_mjcf

    out = check_output_path(args.out, force=args.force, suffixes=(".xml",))
    spec, mode, extra = engine_and_mode(args, default="mujoco")
    scene = load_scene(args)
    if extra:
        scene = scene.with_overrides(list(extra))
    res = write_mjcf(scene, spec.spec, out, mode)
    if res["note"] and not res["friction_in_file"]:
        sys.stderr.write(f"tippetop: note: paper mode: {res['note']}\n")
    if args.json:
        print_json(res)
        return 0
    ran = res["ran"]

    def nums(v: list[float]) -> str:
        return "[" + ", ".join(f"{x:g}" for x in v) + "]"

    print(f"wrote {res['out']}: {res['scene']} on {res['engine']} in mode {res['mode']}, "
          f"keyframe '{res['keyframe']}' (index {res['keyframe_index']})")
    print(f"  {ran['integrator']} at dt = {ran['timestep_s']:g} s, {ran['cone']} cone, "
          f"impratio {ran['impratio']:g}, noslip_iterations {ran['noslip_iterations']}, "
          f"condim {ran['condim']}, mu {'-' if ran['mu'] is None else format(ran['mu'], 'g')}, "
          f"solref {nums(ran['solref'])}, solimp {nums(ran['solimp'])}, gravity "
          f"{ran['gravity_mps2']:g} m/s^2")
    print(f"  step it: m = mujoco.MjModel.from_xml_path({os.fspath(res['out'])!r}); "
          f"d = mujoco.MjData(m); mujoco.mj_resetDataKeyframe(m, d, {res['keyframe_index']}); "
          f"mujoco.mj_step(m, d) to t = {res['t_end_s']:g} s")
    return 0
