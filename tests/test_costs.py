"""One number for each cost: what the README, the guides and the help quote is the stored one.

docs/data/costs.json (benchmarks/bench_costs.py measures it) holds each quoted cost; the docs
quote it through ``{{ cost KEY }}`` markers that the build fills in (docs/hooks/costs.py), the
README in the words :func:`cost_text` gives. Issue 43 found three figures for one cost (the
fidelity map's, a point's) and a README ratio (tuning, "about 3x") that a measurement put at
2.0x: a test here fails when a quoted figure and its stored source disagree, and when a page
quotes a cost typed by hand ("about 40 s", "~0.1 ms", "about 2.5-3x", "about 90 MB") instead
of through a marker. The figures of that form that are not costs (a simulated time, an error's
size, a count) or that the design record dates as a past measurement are listed in
:data:`NOT_QUOTED_COSTS`, each with its reason.
"""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

from tippetop.compare.presentation.costs import MARKER, Cost, cost_text, expand, load

ROOT = Path(__file__).resolve().parents[1]
#: What the README quotes, each in :func:`cost_text`'s words.
README_COSTS = ("simulate_first_s", "simulate_s", "nightly_quick_s", "validate_no_tune_s",
                "validate_tune_ratio", "tests_fast_s", "tests_slow_s")
#: A figure in a page's words that reads as a cost: "about 15 s", "about 2 min", "about 2.0x",
#: "~0.1 ms", "about 2.5-3x", "~20 ns", "about 90-140 MB", "about 1,000x"; a number in
#: exponent form too ("~1e-14 s"), so that such a figure is listed below as not a cost.
QUOTE = re.compile(
    r"(?:\babout|~)\s*\d[\d.,]*(?:e[-+]?\d+)?(?:\s*-\s*\d[\d.,]*(?:e[-+]?\d+)?)?\s*"
    r"(?:s|ms|us|µs|ns|min|minutes|seconds|h|hours|x|kB|MB|GB|MiB|GiB)\b")
#: Every page of the site.
PAGES = tuple(sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "docs").rglob("*.md")))
#: The pages that quote costs, each through markers (a page that loses its markers fails).
MARKED_PAGES = (
    "docs/design.md", "docs/development/docs.md", "docs/getting-started.md",
    "docs/guide/accuracy.md", "docs/guide/catching-a-change.md", "docs/guide/commands.md",
    "docs/guide/engines.md", "docs/guide/fidelity.md", "docs/guide/nightly.md",
    "docs/guide/performance.md", "docs/guide/plans.md", "docs/guide/thresholds.md",
    "docs/guide/validate.md", "docs/physics/friction.md", "docs/physics/reference.md")
#: Figures that read as costs but are not quoted costs: (page, the text around the figure, in
#: the page's words with its whitespace collapsed and inline code left out) -> why.
NOT_QUOTED_COSTS: dict[tuple[str, str], str] = {
    ("docs/design.md", "within about 4 ms on the paper's top"):
        "simulated time: how soon the contact slip relaxes",
    ("docs/design.md", "would compile it again, ~8 s when this was decided on 2026-11-22"):
        "a past measurement behind a decision, dated in the design record",
    ("docs/design.md", "measured on 2026-11-23: ~20 ns per evaluation, against ~60 ns"):
        "a past measurement behind a decision, dated in the design record",
    ("docs/design.md", "so the steps cannot pass ~11 ms and ~15 ms"):
        "step sizes in simulated time, from the stability boundary",
    ("docs/design.md", "is 1.05-1.09x faster on Fig. 3 but ~0.96x on Fig. 11 (its jet costs "
                       "~1.2-1.35x more)"):
        "the 2026-11-28 runs the paragraph dates, behind the orders table's decision",
    ("docs/design.md", "cost ~0.1 ms in numba's dispatcher when this was decided (measured on "
                       "2026-11-28)"):
        "a past measurement behind a decision, dated in the design record",
    ("docs/design.md", "its error per rtol is up to ~10x DOP853's"):
        "a ratio of errors, not of times",
    ("docs/design.md", "(about 1,000x the evaluations of"):
        "a ratio of evaluation counts (the physics' stiffness), not of times",
    ("docs/physics/reference.md", "(about 1,000x the evaluations of"):
        "a ratio of evaluation counts (the physics' stiffness), not of times",
    ("docs/physics/friction.md", "brakes the spin below n1 in about 0.12 s"):
        "simulated time of the motion",
    ("docs/guide/accuracy.md", "located to ~1e-14 s"):
        "the error of a located inversion time, not a cost",
    ("docs/guide/accuracy.md", "its error per rtol is up to ~10x DOP853's"):
        "a ratio of errors, not of times",
    ("docs/guide/accuracy.md", "RK4's error is about 100x smaller than"):
        "a ratio of errors, not of times",
    ("docs/guide/performance.md", "cost ~0.1 ms in numba's dispatcher when this was decided "
                                  "(measured on 2026-11-28)"):
        "a past measurement behind a decision, dated (the design notes record it)",
    ("docs/guide/fidelity.md", "would have taken about 921 s (15.3 min)"):
        "an estimate from the dated 2026-11-29 run of the table above, said to be one",
    ("docs/guide/fidelity.md", "that map would still have taken about 23 minutes"):
        "an estimate from the dated 2026-11-27 map, said to be one",
    ("docs/guide/fidelity.md", "(then about 10x a"):
        "the tuning's cost before issue 30, a past figure (validate.md records it)",
}


def _prose(text: str) -> str:
    """``text`` with its markers and inline code left out, whitespace collapsed; fenced blocks
    kept (a comment after a command quotes a cost too), their fences dropped."""
    parts, prose, fenced = [], [], False
    for line in MARKER.sub("", text).splitlines():
        if line.lstrip().startswith("```"):
            if not fenced:  # the prose before the block, its inline code left out
                parts.append(re.sub(r"`[^`]*`", "", "\n".join(prose)))
                prose = []
            fenced = not fenced
            continue
        (parts if fenced else prose).append(line)
    parts.append(re.sub(r"`[^`]*`", "", "\n".join(prose)))
    return " ".join(" ".join(parts).split())


def _unlisted(page: str, text: str) -> list[str]:
    """The quotes in ``text`` (a page's :func:`_prose`) that no listed figure covers."""
    spans = [(m.start(), m.start() + len(s)) for (p, s) in NOT_QUOTED_COSTS if p == page
             for m in re.finditer(re.escape(s), text)]
    return [m.group(0) for m in QUOTE.finditer(text)
            if not any(a <= m.start() and m.end() <= b for a, b in spans)]


def _bench_costs() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_costs",
                                                  ROOT / "benchmarks" / "bench_costs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[spec.name]
    return module


def test_the_stored_costs_read_back() -> None:
    costs, meta = load()
    assert set(README_COSTS) <= set(costs)
    assert all(c.value > 0 and c.unit in ("s", "ms", "MB", "x") for c in costs.values())
    assert all(c.high is None or c.high >= c.value for c in costs.values())
    raw = json.loads((ROOT / "docs" / "data" / "costs.json").read_text())
    assert all("measured" in v and "command" in v for v in raw["costs"].values())
    assert meta["format"] == "tippetop-costs/1"


def test_every_stored_cost_has_its_measurement() -> None:
    """Each stored key is one benchmarks/bench_costs.py measures (or reads from a CI log)."""
    bench = _bench_costs()
    costs, _ = load()
    assert set(costs) <= {*bench.KEYS, *bench.CI_KEYS}, set(costs) - {*bench.KEYS,
                                                                       *bench.CI_KEYS}


def test_the_costs_read_from_stored_results_are_those_results() -> None:
    """The costs copied from docs/data's long runs (the fidelity map, the work-precision
    sweep) equal what those files hold now: a new run of either moves the figure, and this
    fails until bench_costs copies it. Tolerance 5e-4: costs.json keeps 3 decimals."""
    bench = _bench_costs()
    costs, _ = load()
    for _keys, read in bench.STORED:
        for key, entry in read().items():
            assert key in costs, f"{key}: not in costs.json; run bench_costs --only {key}"
            assert costs[key].value == pytest.approx(entry["value"], abs=5e-4), key
            assert (costs[key].high is None) == (entry.get("high") is None), key
            if costs[key].high is not None:
                assert costs[key].high == pytest.approx(entry["high"], abs=5e-4), key


@pytest.mark.parametrize(("value", "unit", "high", "text"), [
    (14.6, "s", None, "about 15 s"), (1.46, "s", None, "about 1 s"), (0.2, "s", None, "about 1 s"),
    (69.0, "s", None, "about 70 s"), (99.0, "s", None, "about 100 s"),
    (634.5, "s", None, "about 11 min"), (1029.5, "s", None, "about 17 min"),
    (2.04, "x", None, "about 2.0x"), (986.7, "x", None, "about 990x"),
    (16.4, "ms", None, "about 16 ms"), (0.262, "ms", 0.542, "about 0.3-0.5 ms"),
    (85.2, "MB", 136.1, "about 85-140 MB"), (2.7, "x", 4.79, "about 2.7-4.8x"),
    (3.2, "s", 5.1, "about 3-5 s"), (1.0, "s", 1.3, "about 1 s"),
    (7.0, "s", 413.0, "about 7 s to 7 min")])
def test_a_cost_is_worded_one_way(value: float, unit: str, high: float | None,
                                  text: str) -> None:
    assert cost_text(Cost("k", value, unit, "", "", high)) == text


def test_a_cost_in_another_unit_is_an_error() -> None:
    with pytest.raises(ValueError, match="expected unit"):
        cost_text(Cost("k", 1.0, "h", "", ""))


def test_the_readme_quotes_the_stored_costs_and_no_other() -> None:
    costs, _ = load()
    readme = _prose((ROOT / "README.md").read_text())
    wanted = {cost_text(costs[k]): k for k in README_COSTS}
    for text, key in wanted.items():
        assert text in readme, f"README.md: {key} is {costs[key].value:g} {costs[key].unit} " \
                               f"stored (docs/data/costs.json): expected {text!r} in it"
    others = [q for q in QUOTE.findall(readme) if q not in wanted]
    assert not others, f"README.md quotes costs with no stored source: {others}"


@pytest.mark.parametrize("page", PAGES)
def test_the_pages_quote_costs_through_markers_only(page: str) -> None:
    costs, _ = load()
    text = (ROOT / page).read_text()
    keys = {m.group("key") for m in MARKER.finditer(text)}
    assert keys <= set(costs), f"{page}: markers naming no stored cost: {keys - set(costs)}"
    assert bool(keys) == (page in MARKED_PAGES), \
        f"{page}: {'markers, but not in MARKED_PAGES' if keys else 'no cost marker'}"
    left = _unlisted(page, _prose(text))
    assert not left, f"{page}: costs quoted without a marker (write {{{{ cost KEY }}}}, " \
                     f"measured by benchmarks/bench_costs.py): {left}"
    assert not MARKER.search(expand(text, costs))


def test_a_figure_typed_by_hand_is_found() -> None:
    """The check finds the forms a hand-typed cost takes, in prose and after a command."""
    page = "docs/guide/engines.md"
    for typed in ("(about 4 s)", "costs ~0.1 ms a call", "about 2.5-3x its time",
                  "(about 90 MB each)", "~20 ns a step", "\n$ tippetop simulate    # about 4 s\n"):
        text = f"Text\n\n```console{typed}```\n" if typed.startswith("\n") else f"Some {typed}."
        assert _unlisted(page, _prose(text)), typed
    assert not _unlisted(page, _prose("`# about 10 s` in code, {{ cost simulate_s }} marked"))


def test_every_listed_figure_is_on_its_page() -> None:
    """Each figure listed as not a cost is still on its page, and reads as one (a listing
    left behind by an edit fails)."""
    for (page, snippet), why in NOT_QUOTED_COSTS.items():
        assert why
        assert snippet in _prose((ROOT / page).read_text()), f"{page}: {snippet!r} is gone"
        assert QUOTE.search(snippet), f"{page}: {snippet!r} quotes nothing the check finds"


def test_a_marker_naming_no_stored_cost_is_an_error() -> None:
    costs, _ = load()
    with pytest.raises(KeyError, match="no such cost"):
        expand("{{ cost no_such_cost_s }}", costs)


def _help(command: str) -> str:
    from tippetop.compare.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return " ".join(sub.choices[command].format_help().split())


def test_the_fidelity_help_quotes_the_stored_map() -> None:
    """``fidelity --help`` quotes the default map's time and its points' range from the map's
    stored result (docs/data/fidelity-default.json), to the minute's tenth and the second."""
    data = json.loads((ROOT / "docs" / "data" / "fidelity-default.json").read_text())
    walls = [p["wall_s"] for p in data["points"]]
    text = _help("fidelity")
    assert f"took {data['wall_s'] / 60:.1f} minutes on 2 cores" in text, text
    assert f"{min(walls):.0f}-{max(walls):.0f} s a point" in text, text


def test_the_bench_help_quotes_the_stored_scipy_run() -> None:
    """``bench --help`` says what one of scipy's rounds costs at the defaults: the stored one."""
    costs, _ = load()
    text = _help("bench")
    assert f"({cost_text(costs['bench_ode_scipy_s'])} each at the defaults" in text, text
    assert not [q for q in QUOTE.findall(text)
                if q != cost_text(costs["bench_ode_scipy_s"])], text


def test_the_progress_priors_the_commands_page_quotes_are_the_code_s() -> None:
    """The progress bar's priors are settings, not measurements: the page says the code's."""
    from tippetop.compare.running.cost import MUJOCO_STEP_S, ODE_PER_SIM_S

    text = _prose((ROOT / "docs" / "guide" / "commands.md").read_text())
    assert f"{MUJOCO_STEP_S * 1e6:.0f} us until runs have measured it" in text
    assert f"the reference ODE a fixed {ODE_PER_SIM_S * 1e3:.0f} ms per simulated second" in text
