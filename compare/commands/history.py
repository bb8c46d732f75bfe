"""``tippetop history``: each case's metrics over the nights, and the nights they changed.

The store is :mod:`tippetop.compare.nightly.history`; the nightly and the matrix append to it.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from tippetop.compare.commands.options import (
    add_json_option,
    comma_list,
    print_json,
    worker_count,
)

HISTORY_HELP = ("the history file, a SQLite database (default: $TIPPETOP_CACHE/history.sqlite, "
                "in the cache)")


def add_history_options(p: argparse.ArgumentParser, what: str) -> None:
    """``--history FILE`` and ``--no-history`` of a command that appends (nightly, matrix)."""
    p.add_argument("--history", metavar="FILE", help=f"append {what} to this history file, a "
                   "SQLite database safe with two writers, e.g. on a CI's persistent disk "
                   "(default: $TIPPETOP_CACHE/history.sqlite)")
    p.add_argument("--no-history", dest="no_history", action="store_true",
                   help="append nothing to the history (default: append)")


def record_command(kind: str, res: dict[str, Any], args: argparse.Namespace, *,
                   profile: str | None = None) -> dict[str, Any]:
    """Append a command's results to the history: ``{file, run, error}`` (never raises).

    A failed append is said in one line on stderr; the command's results are kept whatever
    happens (``kind``: matrix or bisect, the command's name).
    """
    from tippetop.compare.nightly.history import history_path, record_results
    from tippetop.compare.running.io import json_ready

    path = history_path(args.history)
    try:
        run_id = record_results(kind, json_ready(res), path=path, profile=profile, argv=[
            "tippetop", kind, *(getattr(args, "_argv", None) or sys.argv[2:])],
            settings=tuple(getattr(args, "set", None) or ()))
    except Exception as exc:  # noqa: BLE001 - the command's results are kept whatever happens
        error = " ".join(f"{type(exc).__name__}: {exc}".split())
        sys.stderr.write(f"tippetop: history not appended to {path}: {error} (the results "
                         "are kept)\n")
        return {"file": str(path), "run": None, "error": error}
    return {"file": str(path), "run": run_id, "error": None}


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop history`` and its options."""
    p = sub.add_parser(
        "history", help="each metric over the nights, and the nights it changed",
        description="Print, for each case, engine and metric the nightlies and matrices "
        "appended to the history, its values over time and the runs where it changed: a step "
        "(it moved beyond the nightly's tolerance from its level and stayed), a blip (one run, "
        "then back), or a move on the last run; each names the engine version that changed on "
        "that run, else the commit. --import adds old results.json files.")
    p.add_argument("--history", metavar="FILE", help=HISTORY_HELP)
    p.add_argument("--import", dest="import_files", nargs="+", metavar="RESULTS.json",
                   help="append these nightly, matrix or bisect results.json files (dated by "
                   "their 'started' field, else the file's time) and print what was added "
                   "(default: none)")
    p.add_argument("--case", metavar="GLOBS", help="only case ids matching these comma-"
                   "separated globs, e.g. 'paper/fig3*' (default: every case)")
    p.add_argument("--metric", metavar="NAME,...", help="only these comma-separated metrics, "
                   "e.g. t_invert,theta_asymp (default: every metric)")
    p.add_argument("--engine", metavar="ENGINE,...", help="only these comma-separated engine "
                   "specs; mujoco also matches mujoco==X.Y.Z (default: every engine)")
    p.add_argument("--kind", metavar="KIND,...", help="only the runs of these comma-separated "
                   "kinds: nightly, matrix, bisect (default: every kind)")
    p.add_argument("--last", type=worker_count, metavar="N", help="only the last N runs of "
                   "each kind (default: every run)")
    p.add_argument("--changed", action="store_true", help="only the series that changed")
    add_json_option(p, help="print one JSON object instead: format, history, format_version, "
                    "runs, series (each with values and changes); with --import, imported")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop history``: print the series; exit 2 for a file that is not a history."""
    from tippetop.compare.nightly import history as h
    from tippetop.models.errors import TippetopError

    path = h.history_path(args.history)
    kinds = comma_list(args.kind or "")
    for k in kinds:
        if k not in ("nightly", "matrix", "bisect"):
            raise TippetopError(f"--kind: expected nightly, matrix or bisect, got {k!r}")
    if args.import_files:
        done = h.import_results(args.import_files, path)
        if args.json:
            print_json({"format": h.JSON_FORMAT, "history": str(path),
                        "imported": [{"file": str(f), "kind": k, "run": r}
                                     for f, k, r in done]})
        else:
            for f, k, r in done:
                print(f"imported {f} ({k}) as run {r}" if r is not None else
                      f"{f} ({k}): already in the history, not added again")
            print(f"history: {path}")
        return 0
    h.check_history(path)
    if not path.is_file():
        if args.history:
            raise TippetopError(f"--history: expected an existing history file, got "
                                f"{str(path)!r} (no such file: a nightly or a matrix makes "
                                "it, and --import adds old results)")
        if args.json:
            print_json(_json(path, [], []))
        else:
            print(f"history: none yet at {path} (each nightly and matrix appends to it; "
                  "--import adds old results.json files)")
        return 0
    series, runs = h.load_series(path, kinds=kinds, cases=comma_list(args.case or ""),
                                 engines=comma_list(args.engine or ""),
                                 metrics=comma_list(args.metric or ""), last=args.last)
    found = [(s, h.change_points([v.value for v in s.values], s.tolerance)) for s in series]
    if args.changed:
        found = [(s, c) for s, c in found if c]
    if args.json:
        print_json(_json(path, runs, found))
        return 0
    from tippetop.compare.presentation.history import print_history

    print_history(path, runs, [(s, c, h.series_text(s, c)) for s, c in found])
    return 0


def _json(path: Any, runs: list[dict], found: list[tuple[Any, list[Any]]]) -> dict[str, Any]:
    from tippetop.compare.nightly import history as h

    return {"format": h.JSON_FORMAT, "history": str(path), "format_version": h.FORMAT_VERSION,
            "runs": runs, "series": [h.series_json(s, c) for s, c in found]}
