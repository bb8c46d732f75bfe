"""HTML pieces of the report: escaping, numbers, tables, figures as inline PNG, the style sheet."""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from tippetop.compare.presentation.figures import pyplot

#: Resolution of the embedded figures.
FIG_DPI = 90

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:1.5em auto;
max-width:1280px;padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.6em}h2{border-bottom:2px solid #ddd;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;margin:.6em 0;font-size:.86em;display:block;overflow-x:auto}
td.wide{min-width:18em}
th,td{border:1px solid #ccc;padding:.25em .5em;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums}
.pass{background:#e8f5e9}.fail{background:#ffebee;font-weight:600}.new{background:#fff8e1}
.error{background:#fce4ec;font-weight:600}.verdict{font-size:1.3em;padding:.3em .8em;
display:inline-block;border-radius:4px}.ok{background:#c8e6c9}.bad{background:#ffcdd2}
img{max-width:100%;height:auto;display:block;margin:.5em 0}figure{margin:1em 0}
figcaption{font-size:.88em;color:#444}code{background:#f5f5f5;padding:0 .2em}
.note{font-size:.9em;color:#333;max-width:40em}nav ul{columns:3;font-size:.9em;margin:.3em 0}
h1{margin:.1em 0;font-size:1.35em}h1 small{font-size:.6em;font-weight:normal;color:#555}
.badge{margin:.3em 0}.badge .verdict{font-size:1em;padding:.1em .5em}
section#verdict h2{margin:.3em 0 .1em;font-size:1.2em;border:0}
.legend{font-size:.75em;color:#333;margin:.2em 0}
table.verdict-table{font-size:10.5px;line-height:1.15;margin:.3em 0;display:table}
table.verdict-table td{padding:.1em .35em;white-space:nowrap}
table.verdict-table th{padding:.1em .35em}
table.verdict-table thead th{font-size:10.5px;vertical-align:bottom}
table.verdict-table tbody th{max-width:10.5em;font-weight:600}
table.verdict-table td:nth-child(2){padding:.1em .35em;background:#f7f7f7}
.j{color:#555;font-size:.92em}
.agree{background:#c8e6c9}.depart{background:#ffcdd2;font-weight:600}
.expected{background:#e0e0e0}.inconclusive{background:#fff3c4}.failed{background:#f8bbd0;font-weight:600}
td.na{background:repeating-linear-gradient(45deg,#fafafa,#fafafa 4px,#eee 4px,#eee 8px)}
"""


def png(fig: Any) -> str:
    """The figure as an ``<img>`` with a base64 PNG data URI; closes the figure."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=FIG_DPI)
    pyplot().close(fig)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img alt="figure" src="data:image/png;base64,{data}">'


def esc(x: Any) -> str:
    """HTML-escaped text of any value."""
    return html.escape(str(x))


def fmt_num(v: Any, fmt: str = ".4g", unit: str = "") -> str:
    """A cell value: a number in ``fmt`` (with ``unit``), yes/no, ``-`` when missing."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return f"{v:{fmt}}{(' ' + unit) if unit else ''}"
    return esc(v)


def html_table(header: Sequence[str], rows: Iterable[Sequence[Any]],
               classes: Iterable[str] | None = None) -> str:
    """An HTML table; cells are pre-rendered HTML strings or plain values (escaped)."""
    out = ["<table><thead><tr>", *(f"<th>{esc(h)}</th>" for h in header), "</tr></thead><tbody>"]
    cls_iter = iter(classes) if classes is not None else None
    for row in rows:
        cls = next(cls_iter, "") if cls_iter is not None else ""
        out.append(f'<tr class="{esc(cls)}">' if cls else "<tr>")
        for cell in row:
            if isinstance(cell, Cell) and cell.cls:
                out.append(f'<td class="{esc(cell.cls)}">{cell}</td>')
            elif isinstance(cell, Html):
                out.append(f"<td>{cell}</td>")
            elif isinstance(cell, (int, float)) and not isinstance(cell, bool):
                out.append(f'<td class="num">{fmt_num(cell)}</td>')
            else:
                out.append(f"<td>{fmt_num(cell)}</td>")
        out.append("</tr>")
    out.append("</tbody></table>")
    return "".join(out)


class Html(str):
    """A table cell that is already HTML."""


class Cell(Html):
    """A table cell that is already HTML, shaded by a class of its own (``pass``, ``fail``)."""

    cls: str

    def __new__(cls, html: str, shade: str = "") -> Cell:
        """``html`` in a cell of class ``shade`` (none: unshaded)."""
        obj = super().__new__(cls, html)
        obj.cls = shade
        return obj


#: Marks a page as tippetop's own, so that rebuilding it may replace it (report/__main__.py).
GENERATOR = "<meta name='generator' content='tippetop'>"


def made_by_tippetop(path: Path) -> bool:
    """Whether the HTML file at ``path`` is a page :func:`page` wrote."""
    try:
        with path.open("rb") as f:
            return GENERATOR.encode() in f.read(4096)
    except OSError:
        return False


def page(title: str, body: Iterable[str]) -> str:
    """A self-contained HTML page: inline CSS and data-URI images only (its CSP forbids more)."""
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            "<meta http-equiv='Content-Security-Policy' content=\"default-src 'none'; "
            "img-src data:; style-src 'unsafe-inline'\">"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"{GENERATOR}<title>{esc(title)}</title><style>{CSS}</style></head><body>"
            + "\n".join(body) + "</body></html>\n")
