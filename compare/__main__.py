"""``python -m tippetop.compare``: the ``tippetop`` command (:mod:`tippetop.compare.cli`)."""

from tippetop.compare.cli import entry

raise SystemExit(entry())
