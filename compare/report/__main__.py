"""``python -m tippetop.compare.report RESULTS.json [--out FILE] [--accuracy-dir DIR]``."""

from tippetop.compare.report.build import main

raise SystemExit(main())
