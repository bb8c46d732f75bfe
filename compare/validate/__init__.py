"""``tippetop validate MODEL.xml``: the model-validation report of one MJCF top.

Modules: :mod:`.run` (the runs, the verdict, the findings, :class:`ValidateConfig`),
:mod:`.report` (the HTML page, the verdict first) and :mod:`.command` (the parser).
"""

from __future__ import annotations

from tippetop.compare._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "MODES": "run",
    "ValidateConfig": "run",
    "validate": "run",
    "render": "report",
    "add_validate_parser": "command",
    "cmd_validate": "command",
})

__all__ = ["MODES", "ValidateConfig", "add_validate_parser", "cmd_validate", "render",
           "validate"]
