"""``python -m tippetop.compare.report RESULTS.json``: now ``tippetop report RESULTS.json``.

Kept for one release: it says the new spelling on stderr, then rebuilds the report as
``tippetop report`` does (:func:`tippetop.compare.report.rebuild.rebuild_report`).
"""

from __future__ import annotations

import argparse
import sys

from tippetop.compare.report.rebuild import rebuild_report
from tippetop.models.errors import TippetopError
from tippetop.models.spellings import note_old_command

#: Bad input: one line on stderr, nothing written (``tippetop``'s own status for it).
EXIT_BAD_INPUT = 2


def main(argv: list[str] | None = None) -> int:
    """Rebuild a nightly's report from its ``results.json``; the exit status."""
    p = argparse.ArgumentParser(prog="python -m tippetop.compare.report",
                                description="Rebuild the validation report from a nightly's "
                                "results.json (now 'tippetop report').")
    p.add_argument("results", help="results.json of a nightly run")
    p.add_argument("--out", help="HTML file (default: report.html beside results.json, "
                   "replaced when tippetop wrote it)")
    p.add_argument("--accuracy-dir", dest="accuracy_dir", help="folder of PNG figures")
    p.add_argument("--force", action="store_true", help="overwrite an existing --out, or a "
                   "report.html beside results.json that tippetop did not write")
    args = p.parse_args(argv)
    note_old_command("python -m tippetop.compare.report")
    try:
        out = rebuild_report(args.results, args.out, force=args.force,
                             accuracy_dir=args.accuracy_dir)
    except TippetopError as exc:
        sys.stderr.write(f"tippetop: error: {exc}\n")
        return EXIT_BAD_INPUT
    print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
