"""``tippetop metrics``: every metric, as it is declared once (name, unit, meaning, tolerances)."""

from __future__ import annotations

import argparse
import shutil
import textwrap
from typing import Any

from tippetop.compare.commands.options import add_json_option, print_json


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop metrics`` and its options."""
    p = sub.add_parser("metrics", help="list every metric: its unit, meaning, the kinds of "
                       "case it applies to and its tolerances",
                       description="Every metric a run, a threshold search, a sweep or an "
                       "atlas reports, as declared once in tippetop: its unit, what it "
                       "measures, the kinds of nightly case that can check it, how far it may "
                       "move from a baseline (the nightly, the matrix between engines) and how "
                       "far a run may be from the theory or the reference and still agree (the "
                       "verdict). Then the verdict's checks.")
    p.add_argument("names", nargs="*", metavar="NAME", help="only these metrics, or patterns "
                   "such as 'probe.*' (default: all)")
    p.add_argument("--kind", choices=("run", "threshold", "sweep", "atlas", "probe"),
                   help="only the metrics of this kind of case (default: every kind)")
    add_json_option(p, help="print a JSON list of {name, unit, meaning, kinds, tolerance, "
                    "agreement, against, style, label} instead")
    p.set_defaults(func=run)


def selected(names: list[str], kind: str | None) -> list[Any]:
    """The declarations asked for, in declaration order.

    Raises:
        TippetopError: A name that is not a declared metric (one line, with the closest).
    """
    import fnmatch

    from tippetop.compare.measures.metrics import METRICS as RUN_METRICS
    from tippetop.compare.probes import probe_metrics
    from tippetop.models.errors import TippetopError, did_you_mean

    METRICS = {**RUN_METRICS, **probe_metrics()}  # noqa: N806 - every declared metric
    wanted: set[str] = set()
    for n in names:
        found = fnmatch.filter(METRICS, n) if any(c in n for c in "*?[") else \
            [n] if n in METRICS else []
        if not found:
            raise TippetopError(f"NAME: expected a metric or a pattern such as probe.* ("
                                f"{', '.join(METRICS)}), got {n!r}"
                                f"{did_you_mean(n, tuple(METRICS))}")
        wanted.update(found)
    return [m for m in METRICS.values() if (not names or m.name in wanted)
            and (kind is None or kind in m.kinds)]


def run(args: argparse.Namespace) -> int:
    """``tippetop metrics``: print the declarations; exit 2 for an unknown name."""
    chosen = selected(args.names, args.kind)
    if args.json:
        print_json([m.to_json() for m in chosen])
        return 0
    width = max(60, min(100, shutil.get_terminal_size((100, 24)).columns))

    def wrap(text: str, indent: str = "    ") -> str:
        return textwrap.fill(text, width, initial_indent=indent, subsequent_indent=indent)

    for i, m in enumerate(chosen):
        if i:
            print()
        unit = f" ({m.unit})" if m.unit else ""
        print(f"{m.name}{unit}: {', '.join(m.kinds)}")
        print(wrap(m.meaning))
        if m.tolerance is not None:
            print(wrap(f"against a baseline: {m.tolerance.describe()} ({m.tolerance.why})"))
        if m.agreement is not None:
            whom = "on its own" if m.against == "itself" else f"with the {m.against}"
            print(wrap(f"agrees {whom}: {m.agreement.describe()} ({m.agreement.why})"))
    if not args.names and args.kind in (None, "run"):
        from tippetop.compare.measures.verdict import CHECK_MEANINGS

        print("\nthe verdict's checks (a run agrees when none departs):")
        w = max(len(c) for c in CHECK_MEANINGS)
        for check, meaning in CHECK_MEANINGS.items():
            lines = textwrap.wrap(meaning, width - w - 4)
            print(f"  {check:<{w}}  {lines[0]}")
            for line in lines[1:]:
                print(f"  {'':<{w}}  {line}")
    return 0
