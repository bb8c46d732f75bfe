"""MkDocs hook: the glossary's tables, made from tippetop's own declarations at build time.

``docs/glossary.md`` marks where each table goes (``<!-- glossary:metrics -->``);
:func:`tippetop.compare.presentation.glossary.expand` makes it from the declarations (the
engines, the modes, what a run reports it ran, every metric, the verdict's checks), so the page
cannot fall behind the code.
"""

from __future__ import annotations

from typing import Any

from tippetop.compare.presentation.glossary import expand


def on_page_markdown(markdown: str, page: Any, **kwargs: Any) -> str:
    """The page with its glossary markers replaced by their tables."""
    return expand(markdown) if "glossary:" in markdown else markdown
