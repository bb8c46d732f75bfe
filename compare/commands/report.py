"""``tippetop report``: rebuild a nightly's report from its ``results.json``."""

from __future__ import annotations

import argparse

from tippetop.compare.commands.options import add_force_option


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop report`` and its options."""
    p = sub.add_parser("report", help="rebuild a nightly's report from its results.json",
                       description="Write the HTML report of a nightly's results.json again "
                       "(after an upgrade, or with the accuracy study's figures added): "
                       "report.html beside it, replaced when tippetop wrote it.")
    p.add_argument("results", metavar="RESULTS.json", help="results.json of a nightly run "
                   "(required)")
    p.add_argument("--out", metavar="FILE.html", help="the HTML file (default: report.html "
                   "beside RESULTS.json)")
    p.add_argument("--accuracy-dir", dest="accuracy_dir", metavar="DIR",
                   help="a folder of the accuracy study's PNG figures to add (default: none)")
    add_force_option(p, help="overwrite an existing --out, or a report.html beside "
                     "RESULTS.json that tippetop did not write")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop report``: print the file written; exit 2 for bad input."""
    from tippetop.compare.report.rebuild import rebuild_report

    print(rebuild_report(args.results, args.out, force=args.force,
                         accuracy_dir=args.accuracy_dir))
    return 0
