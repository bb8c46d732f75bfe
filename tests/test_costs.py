"""One number for each cost: what the README, the guides and the help quote is the stored one.

docs/data/costs.json (benchmarks/bench_costs.py measures it) holds each quoted cost; the docs
quote it through ``{{ cost KEY }}`` markers that the build fills in (docs/hooks/costs.py), the
README in the words :func:`cost_text` gives. Issue 43 found three figures for one cost (the
fidelity map's, a point's) and a README ratio (tuning, "about 3x") that a measurement put at
2.0x: a test here fails when a quoted figure and its stored source disagree.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from tippetop.compare.presentation.costs import MARKER, Cost, cost_text, expand, load

ROOT = Path(__file__).resolve().parents[1]
#: What the README quotes, each in :func:`cost_text`'s words.
README_COSTS = ("simulate_first_s", "simulate_s", "nightly_quick_s", "validate_no_tune_s",
                "validate_tune_ratio", "tests_fast_s", "tests_slow_s")
#: A cost in a page's words: "about 15 s", "about 2 min", "about 2.0x".
QUOTE = re.compile(r"about \d[\d.]*(?:-\d[\d.]*)? ?(?:s|min|minutes|x)\b")
#: The pages that quote the README's costs, through markers.
MARKED_PAGES = ("docs/getting-started.md", "docs/guide/validate.md", "docs/development/docs.md")


def test_the_stored_costs_read_back() -> None:
    costs, meta = load()
    assert set(README_COSTS) <= set(costs)
    assert all(c.value > 0 and c.unit in ("s", "x") for c in costs.values())
    raw = json.loads((ROOT / "docs" / "data" / "costs.json").read_text())
    assert all("measured" in v and "command" in v for v in raw["costs"].values())
    assert meta["format"] == "tippetop-costs/1"


@pytest.mark.parametrize(("value", "unit", "text"), [
    (14.6, "s", "about 15 s"), (1.46, "s", "about 1 s"), (0.2, "s", "about 1 s"),
    (69.0, "s", "about 70 s"), (99.0, "s", "about 100 s"), (634.5, "s", "about 11 min"),
    (1029.5, "s", "about 17 min"), (2.04, "x", "about 2.0x")])
def test_a_cost_is_worded_one_way(value: float, unit: str, text: str) -> None:
    assert cost_text(Cost("k", value, unit, "", "")) == text


def test_the_readme_quotes_the_stored_costs_and_no_other() -> None:
    costs, _ = load()
    readme = (ROOT / "README.md").read_text()
    wanted = {cost_text(costs[k]): k for k in README_COSTS}
    for text, key in wanted.items():
        assert text in readme, f"README.md: {key} is {costs[key].value:g} {costs[key].unit} " \
                               f"stored (docs/data/costs.json): expected {text!r} in it"
    others = [q for q in QUOTE.findall(readme) if q not in wanted]
    assert not others, f"README.md quotes costs with no stored source: {others}"


@pytest.mark.parametrize("page", MARKED_PAGES)
def test_the_pages_quote_costs_through_markers_only(page: str) -> None:
    costs, _ = load()
    text = (ROOT / page).read_text()
    keys = [m.group("key") for m in MARKER.finditer(text)]
    assert keys, f"{page}: no cost marker"
    assert set(keys) <= set(costs), set(keys) - set(costs)
    prose = re.sub(r"`[^`\n]*`", "", MARKER.sub("", text))  # an example in code is no claim
    left = QUOTE.findall(prose)
    assert not left, f"{page}: costs quoted without a marker: {left}"
    assert not MARKER.search(expand(text, costs))


def test_a_marker_naming_no_stored_cost_is_an_error() -> None:
    costs, _ = load()
    with pytest.raises(KeyError, match="no such cost"):
        expand("{{ cost no_such_cost_s }}", costs)


def test_the_fidelity_help_quotes_the_stored_map() -> None:
    """``fidelity --help`` quotes the default map's time and its points' range from the map's
    stored result (docs/data/fidelity-default.json), to the minute's tenth and the second."""
    from tippetop.compare.cli import build_parser

    data = json.loads((ROOT / "docs" / "data" / "fidelity-default.json").read_text())
    walls = [p["wall_s"] for p in data["points"]]
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    text = " ".join(sub.choices["fidelity"].format_help().split())
    assert f"took {data['wall_s'] / 60:.1f} minutes on 2 cores" in text, text
    assert f"{min(walls):.0f}-{max(walls):.0f} s a point" in text, text
