"""The HTML reports: a nightly's model-validation report and ``tippetop validate``'s page.

:mod:`.markup` (escaping, tables, inline PNG, the style sheet), :mod:`.sections` (the text
sections), :mod:`.figures` (time series and sweeps), :mod:`.groupmap`, :mod:`.atlas`,
:mod:`.friction` (the friction-law table and its notes), :mod:`.build` (:func:`render_report`,
:func:`build_report`) and :mod:`.validate` (the page of ``tippetop validate``).
``python -m tippetop.compare.report RESULTS.json`` rebuilds a report; docs/design.md lists
its sections.
"""

from __future__ import annotations

from tippetop.compare._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "build_report": "build",
    "render_report": "build",
    "PLOT_ROWS": "figures",
    "FRICTION_MODES": "friction",
    "FRICTION_SCENE": "friction",
    "friction_note": "friction",
})

__all__ = ["FRICTION_MODES", "FRICTION_SCENE", "PLOT_ROWS", "build_report", "friction_note",
           "render_report"]
