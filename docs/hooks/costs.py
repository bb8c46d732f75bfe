"""MkDocs hook: the costs the pages quote, read from the stored benchmark result at build time.

A page writes ``{{ cost KEY }}`` where it quotes a cost (``{{ cost nightly_quick_s }}``);
:func:`tippetop.compare.presentation.costs.expand` fills in the figure from
``docs/data/costs.json`` (``benchmarks/bench_costs.py`` measures it), so the README, the guides
and the help say one number for each cost. A marker naming no stored cost fails the build.
"""

from __future__ import annotations

from typing import Any

from tippetop.compare.presentation.costs import expand, load


def on_page_markdown(markdown: str, page: Any, **kwargs: Any) -> str:
    """The page with its cost markers replaced by the stored figures."""
    if "{{" not in markdown:
        return markdown
    costs, _ = load()
    return expand(markdown, costs)
