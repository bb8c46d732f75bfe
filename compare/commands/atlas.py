"""``tippetop atlas``: the paper's group diagram measured in each engine, printed or written."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from tippetop.compare.commands.options import (
    add_force_option,
    add_json_option,
    add_parallel_options,
    add_set_option,
    engines_and_modes,
    json_text,
    print_json,
    set_overrides,
)
from tippetop.compare.studies.defaults import (
    DEFAULT_A_OVER_C,
    DEFAULT_A_OVER_R,
    DEFAULT_ENGINES_TEXT,
    DEFAULT_MODES_TEXT,
)

if TYPE_CHECKING:
    from tippetop.compare.results.atlas import AtlasResult


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop atlas`` and its options."""
    p = sub.add_parser(
        "atlas", help="the paper's group diagram measured: n1, n4 and the group at every "
        "(A/C, a/R) point on each engine and mode",
        description="At every point of an (A/C, a/R) grid, measure n1 (the upright state's "
        "growth rate crosses zero) and n4 (the inverted state's, carried to theta = 0 by "
        "Jellett's constant) in each engine's own dynamics, in every mode of --modes it can "
        "run, the group they imply (I: no n1; II: n1 and n4; III: n1, no n4), against the "
        "theory's group and thresholds. It runs on any engine: the reference, the MuJoCo "
        "installed here, a release (mujoco==X.Y.Z), a build (mujoco@PYTHON), MJX or Warp.")
    p.add_argument("--A-over-C", dest="A_over_C", default=DEFAULT_A_OVER_C, metavar="LO:HI:N",
                   help=f"A/C values: N evenly spaced from LO to HI (default "
                   f"{DEFAULT_A_OVER_C})")
    p.add_argument("--a-over-R", dest="a_over_R", default=DEFAULT_A_OVER_R, metavar="LO:HI:N",
                   help=f"a/R values, in (0, 1): N evenly spaced from LO to HI (default "
                   f"{DEFAULT_A_OVER_R})")
    p.add_argument("--engines", metavar="ENGINE,...", help=f"comma-separated engines: ode "
                   f"(the reference), mujoco (the MuJoCo installed with tippetop), "
                   f"mujoco==X.Y.Z, mujoco@PYTHON, mjx, mjx-f32, warp "
                   f"(default {DEFAULT_ENGINES_TEXT})")
    p.add_argument("--modes", metavar="MODE,...", help=f"comma-separated modes: paper, "
                   f"native, native-pyramidal, native-elliptic, native-condim4, "
                   f"native-condim6, file, coulomb, viscous, coulomb_viscous (default "
                   f"{DEFAULT_MODES_TEXT})")
    add_set_option(p)
    p.add_argument("--out", metavar="DIR", help="folder for atlas.csv, atlas.png and "
                   "atlas.json, new or empty, or --force (default: none, printed only)")
    add_force_option(p, help="write into a non-empty --out")
    add_parallel_options(p)
    add_json_option(p, help="print {points, agreement, findings, grid, n_runs} as JSON "
                    "instead of the summary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop atlas``: measure the group diagram and print or write it (exit 0).

    An engine departing from the theory is a finding, printed and written, not a failure.
    """
    from tippetop.compare.presentation.atlas import print_atlas
    from tippetop.compare.studies.atlas import parse_grid, run_atlas

    ac = parse_grid(args.A_over_C, "--A-over-C")
    ar = parse_grid(args.a_over_R, "--a-over-R")
    runs = engines_and_modes(args, engines=DEFAULT_ENGINES_TEXT, modes=DEFAULT_MODES_TEXT,
                             old_option="--engines")
    out_dir = None
    if args.out:
        from tippetop.compare.running.io import check_output_dir, hold_output_lock

        out_dir = check_output_dir(args.out, force=args.force)  # before any run
        hold_output_lock(out_dir)
    res = run_atlas(ac, ar, runs, set_overrides(args), scheduler=args.scheduler,
                    workers=args.workers, use_cache=not args.no_cache)
    files = write_atlas(res, out_dir) if out_dir is not None else []
    if args.json:
        data = res.to_json()
        print_json({k: data[k] for k in ("points", "agreement", "findings", "grid", "n_runs")})
    else:
        print_atlas(res)
        if files:
            print("wrote " + ", ".join(str(f) for f in files))
    return 0


def write_atlas(result: AtlasResult, out_dir: str | Path) -> list[Path]:
    """Write atlas.csv, atlas.png and atlas.json into ``out_dir``, all or nothing.

    The folder is checked (new, empty or ``--force``) by the caller before the work.
    """
    from tippetop.compare.presentation.figures import atlas_figure, pyplot
    from tippetop.compare.running.io import staged_output_dir
    from tippetop.compare.studies.atlas import atlas_table

    names = ["atlas.csv", "atlas.png", "atlas.json"]
    with staged_output_dir(Path(out_dir)) as tmp:
        atlas_table(result).to_csv(tmp / "atlas.csv", index=False)
        data = result.to_json()
        fig = atlas_figure(data)
        fig.savefig(tmp / "atlas.png", dpi=110)
        pyplot().close(fig)
        (tmp / "atlas.json").write_text(json_text(data, indent=1), encoding="utf-8")
    return [Path(out_dir) / n for n in names]
