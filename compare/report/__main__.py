"""``python -m tippetop.compare.report RESULTS.json [--out FILE] [--accuracy-dir DIR]``.

An entry point, like :mod:`tippetop.compare.cli`: it may use the command line's shared options.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tippetop.compare.commands.options import EXIT_BAD_INPUT, add_force_option
from tippetop.compare.report.build import build_report
from tippetop.compare.report.markup import made_by_tippetop
from tippetop.models.errors import TippetopError


def main(argv: list[str] | None = None) -> int:
    """Rebuild a nightly's report from its ``results.json``; the exit status."""
    p = argparse.ArgumentParser(prog="python -m tippetop.compare.report",
                                description="Rebuild the validation report from a nightly's "
                                "results.json.")
    p.add_argument("results", help="results.json of a nightly run")
    p.add_argument("--out", help="HTML file (default: report.html beside results.json, "
                   "replaced when tippetop wrote it)")
    p.add_argument("--accuracy-dir", dest="accuracy_dir", help="folder of PNG figures")
    add_force_option(p, help="overwrite an existing --out, or a report.html beside "
                     "results.json that tippetop did not write")
    args = p.parse_args(argv)
    beside = Path(args.results).parent / "report.html"
    out = Path(args.out) if args.out else beside
    try:
        if out.exists() and not args.force:
            if args.out:
                raise TippetopError(f"--out: expected a path that does not exist yet (or "
                                    f"--force), got existing {str(out)!r}")
            if not made_by_tippetop(out):
                raise TippetopError(f"{str(out)!r} exists and tippetop did not write it: "
                                    f"expected --force to replace it, or --out FILE")
        build_report(args.results, out, accuracy_dir=args.accuracy_dir)
    except TippetopError as exc:
        sys.stderr.write(f"tippetop: error: {exc}\n")
        return EXIT_BAD_INPUT
    print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
