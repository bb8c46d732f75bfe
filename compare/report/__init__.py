"""The model-validation report: one self-contained HTML page.

Everything is inline: figures are base64 PNG ``<img>`` tags, styles sit in one ``<style>``
element, there is no script, and a Content-Security-Policy forbids loading anything from
outside the page. Sections:

1. the verdict of the nightly checks (regressions and new metrics by name);
2. the scenes: parameters, group and the theory's numbers per case;
3. theta(t) and xi(t) with the xi_plus / xi_minus curves, every engine/mode of a scene
   overlaid (the paper's Figs. 3-8), and the slip trajectory (vPX, vPY) (Fig. 5);
4. theta_asymp against n0 with the theory curves theta_s(n0) (Figs. 9 and 10);
5. the group map in the (a/R, A/C) plane with the simulated outcomes;
6. the friction-law table with one sentence per row, written from the numbers;
7. the threshold table (theory against measured, per engine);
8. accuracy against cost (PNG files from a folder, when there are any);
9. every check, and the environment.

:func:`build_report` takes the nightly's results (the ``results.json`` dictionary or its
path). Run tables come from ``tables=`` or from the ``tables/`` files the nightly wrote beside
``results.json``. ``python -m tippetop.compare.report RESULTS.json [--out report.html]
[--accuracy-dir DIR]`` rebuilds a report from a nightly folder.

Modules: :mod:`.markup` (escaping, tables, inline PNG, the style sheet), :mod:`.sections` (the
text sections), :mod:`.figures` (time series and sweeps), :mod:`.groupmap`, :mod:`.friction`
(the friction-law table and its notes) and :mod:`.build` (:func:`render_report`,
:func:`build_report` and ``main``).
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
