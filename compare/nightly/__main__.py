"""``python -m tippetop.compare.nightly [options]``: the same as ``tippetop nightly``."""

from tippetop.compare.nightly.command import main

raise SystemExit(main())
