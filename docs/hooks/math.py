r"""MkDocs hook: the formulas as MathML, made at build time (no script, no network).

``pymdownx.arithmatex`` (generic mode) leaves each formula as ``\(...\)`` in a
``span.arithmatex`` (``\[...\]`` in a ``div`` for a displayed one); this hook converts each to
MathML with latex2mathml, which browsers draw natively, so the site shows its formulas opened
from disk as well as served. A formula latex2mathml cannot read is a warning naming the page and
the formula, which fails ``properdocs build --strict``.

A heading's formula also reaches the table of contents (the sidebars) and, in a page's first
heading, the page's title, which the toc extension takes as text, before this hook: there it
would show as raw ``\(\xi\)``. The table of contents gets the same MathML as the page
(:func:`toc_html`); the title, which the theme also puts in ``<title>``, where no markup goes,
gets the formula's text (:func:`title_text`: ``ξ``).
"""

from __future__ import annotations

import html
import logging
import re
from typing import Any

from latex2mathml.converter import convert

log = logging.getLogger("mkdocs.hooks.tippetop_math")

_MATH = re.compile(r'<(?P<tag>span|div) class="arithmatex">\s*\\(?P<open>[(\[])(?P<tex>.*?)'
                   r'\\[)\]]\s*</(?P=tag)>', re.S)
#: A formula as the toc extension leaves it in a heading's text (HTML-escaped, no span).
_TEXT_MATH = re.compile(r"\\(?P<open>[(\[])(?P<tex>.*?)\\(?P<close>[)\]])", re.S)
_TAG = re.compile(r"<[^>]*>")


def on_page_content(content: str, page: Any, **kwargs: Any) -> str:
    """Replace every arithmatex formula of a page by its MathML, in its headings' TOC too."""
    where = page.file.src_uri

    def mathml(m: re.Match[str]) -> str:
        tex = html.unescape(m.group("tex")).strip()
        display = "block" if m.group("open") == "[" else "inline"
        try:
            return convert(tex, display=display)
        except Exception as exc:  # noqa: BLE001 - any parse failure is the formula's
            log.warning("math on %s: latex2mathml cannot read %r: %s", where, tex, exc)
            return m.group(0)

    for item in _toc_items(page.toc):
        item.title = toc_html(item.title, where)
    # page.title is a property computed from the rendered first heading (or the nav, or the
    # page's metadata): an instance attribute set here takes its place
    title = page.title
    if title and _TEXT_MATH.search(title):
        page.title = title_text(title, where)
    return _MATH.sub(mathml, content)


def toc_html(title: str, where: str = "?") -> str:
    r"""A table-of-contents entry (HTML) with each ``\(...\)`` formula as inline MathML.

    Args:
        title: The entry as the toc extension made it: the heading's text, HTML-escaped.
        where: The page, for the warning when a formula cannot be read.

    Returns:
        The entry with MathML in place of each formula it can read (the others stay, with a
        warning).
    """
    return _TEXT_MATH.sub(lambda m: _convert(m, where) or m.group(0), title)


def title_text(title: str, where: str = "?") -> str:
    r"""A page title with each ``\(...\)`` formula as its text (``\xi_\pm`` as ``ξ±``).

    Args:
        title: The title as MkDocs took it from the first heading: text, HTML-escaped.
        where: The page, for the warning when a formula cannot be read.

    Returns:
        The title with the characters of each formula's MathML in its place, HTML-escaped
        (no markup: the theme also puts the title in ``<title>``).
    """
    def text(m: re.Match[str]) -> str:
        mathml = _convert(m, where)
        if mathml is None:
            return m.group(0)
        return html.escape(html.unescape(_TAG.sub("", mathml)), quote=False)

    return _TEXT_MATH.sub(text, title)


def _convert(m: re.Match[str], where: str) -> str | None:
    """A formula of a heading's text as inline MathML, or None (with a warning) if unreadable."""
    tex = html.unescape(m.group("tex")).strip()
    try:
        return convert(tex, display="inline")
    except Exception as exc:  # noqa: BLE001 - any parse failure is the formula's
        log.warning("math in a heading on %s: latex2mathml cannot read %r: %s", where, tex, exc)
        return None


def _toc_items(items: Any) -> list[Any]:
    """Every entry of a page's table of contents, depth first."""
    out = []
    for item in items:
        out.append(item)
        out.extend(_toc_items(item.children))
    return out
