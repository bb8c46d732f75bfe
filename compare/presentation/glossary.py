"""The glossary's tables, made from the declarations: engines, modes, what ran, metrics, checks.

``docs/glossary.md`` holds the prose and a marker per table (``<!-- glossary:metrics -->``);
the docs build (``docs/hooks/glossary.py``) replaces each marker with :func:`expand`'s table,
so the documentation says what the code declares: a metric added to
:mod:`tippetop.compare.measures.metrics` is in the glossary on the next build.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence

_MARKER = re.compile(r"<!--\s*glossary:(?P<name>[a-z_]+)\s*-->")


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def engines_table() -> str:
    """Each way of naming an engine and what it is."""
    from tippetop.models.engines import ENGINE_MEANINGS

    return _table(("engine", "what integrates"),
                  ((f"`{k}`", v) for k, v in ENGINE_MEANINGS.items()))


def modes_table() -> str:
    """Each mode: the engines that run it and what makes the force."""
    from tippetop.models.modes import MODES

    words = {"ode": "the reference (`ode`)", "mujoco": "MuJoCo engines"}
    return _table(("mode", "runs on", "how the contact force is made"),
                  ((f"`{m.name}`", ", ".join(words[f] for f in m.families), m.meaning)
                   for m in MODES.values()))


def ran_table() -> str:
    """Each setting a run reports it ran with, read back from the engine."""
    from tippetop.compare.measures.summary import RAN_FIELDS

    return _table(("key", "unit", "reported by", "what ran"),
                  ((f"`{f.name}`", f.unit or "-", ", ".join(f.engines), f.meaning)
                   for f in RAN_FIELDS.values()))


def metrics_table() -> str:
    """Each metric: unit, kinds, meaning, tolerance against a baseline, agreement."""
    from tippetop.compare.measures.metrics import METRICS

    def agreement(m: object) -> str:
        tol = getattr(m, "agreement", None)
        if tol is None:
            return "-"
        against = getattr(m, "against", "")
        who = "on its own" if against == "itself" else f"with the {against}"
        return f"{tol.describe()} {who}"

    return _table(("metric", "unit", "kinds", "meaning", "against a baseline",
                   "agrees"),
                  ((f"`{m.name}`", m.unit or "-", ", ".join(m.kinds), m.meaning,
                    m.tolerance.describe() if m.tolerance is not None else "-",
                    agreement(m)) for m in METRICS.values()))


def checks_table() -> str:
    """The verdict's checks of a run."""
    from tippetop.compare.measures.verdict import CHECK_MEANINGS

    return _table(("check", "passes when"), ((f"`{k}`", v) for k, v in CHECK_MEANINGS.items()))


def records_table() -> str:
    """The keys outputs carry beside the metrics and what ran."""
    from tippetop.compare.measures.metrics import RECORD_KEYS

    return _table(("key", "what it is"), ((f"`{k}`", v) for k, v in RECORD_KEYS.items()))


def old_names_table() -> str:
    """The compound names of the release before, and how each is written now."""
    from tippetop.models.spellings import OLD_NAMES, new_spelling

    return _table(("the release before", "now"),
                  ((f"`{k}`", f"`{new_spelling(k)}`") for k in OLD_NAMES))


#: The tables a marker can name.
TABLES: dict[str, Callable[[], str]] = {
    "engines": engines_table, "modes": modes_table, "ran": ran_table,
    "metrics": metrics_table, "checks": checks_table, "records": records_table,
    "old_names": old_names_table,
}


def expand(markdown: str) -> str:
    """``markdown`` with each ``<!-- glossary:NAME -->`` marker replaced by its table.

    Raises:
        KeyError: A marker names no table (the docs build then fails, as it should).
    """
    return _MARKER.sub(lambda m: TABLES[m.group("name")](), markdown)


__all__ = ["TABLES", "checks_table", "engines_table", "expand", "metrics_table",
           "modes_table", "old_names_table", "ran_table", "records_table"]
