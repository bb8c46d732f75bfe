"""``tippetop validate MODEL.xml``: the parser and the command (:mod:`.command`)."""

from __future__ import annotations

from tippetop.compare._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "add_validate_parser": "command",
    "cmd_validate": "command",
})

__all__ = ["add_validate_parser", "cmd_validate"]
