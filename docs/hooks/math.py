r"""MkDocs hook: the formulas as MathML, made at build time (no script, no network).

``pymdownx.arithmatex`` (generic mode) leaves each formula as ``\(...\)`` in a
``span.arithmatex`` (``\[...\]`` in a ``div`` for a displayed one); this hook converts each to
MathML with latex2mathml, which browsers draw natively, so the site shows its formulas opened
from disk as well as served. A formula latex2mathml cannot read is a warning naming the page and
the formula, which fails ``mkdocs build --strict``.
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


def on_page_content(content: str, page: Any, **kwargs: Any) -> str:
    """Replace every arithmatex formula of a page by its MathML."""
    def mathml(m: re.Match[str]) -> str:
        tex = html.unescape(m.group("tex")).strip()
        display = "block" if m.group("open") == "[" else "inline"
        try:
            return convert(tex, display=display)
        except Exception as exc:  # noqa: BLE001 - any parse failure is the formula's
            log.warning("math on %s: latex2mathml cannot read %r: %s", page.file.src_uri, tex,
                        exc)
            return m.group(0)

    return _MATH.sub(mathml, content)
