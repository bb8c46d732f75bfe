"""``python -m tippetop.compare.nightly [options]``: the same as ``tippetop nightly``."""

from tippetop.compare.commands.nightly import main
from tippetop.compare.running.interrupt import own_process

own_process()
raise SystemExit(main())
