"""``python -m tippetop.compare.nightly [options]``: the same as ``tippetop nightly``."""

from tippetop.compare.commands.nightly import main

raise SystemExit(main())
