"""Rebuild a nightly's report from its ``results.json`` (``tippetop report RESULTS.json``)."""

from __future__ import annotations

from pathlib import Path

from tippetop.compare.report.build import build_report
from tippetop.compare.report.markup import made_by_tippetop
from tippetop.models.errors import TippetopError


def rebuild_report(results: str | Path, out: str | Path | None = None, *, force: bool = False,
                   accuracy_dir: str | Path | None = None) -> Path:
    """Write the report of a nightly's ``results.json`` again; the file written.

    Args:
        results: A nightly's ``results.json``.
        out: The HTML file (default: ``report.html`` beside ``results``, replaced when
            tippetop wrote it).
        force: Overwrite an existing ``out``, or a ``report.html`` beside ``results`` that
            tippetop did not write.
        accuracy_dir: A folder of PNG figures to add.

    Raises:
        TippetopError: An existing ``out`` without ``force``, or a results file that is not a
            nightly's (one line).
    """
    beside = Path(results).parent / "report.html"
    path = Path(out) if out else beside
    if path.exists() and not force:
        if out:
            raise TippetopError(f"--out: expected a path that does not exist yet (or "
                                f"--force), got existing {str(path)!r}")
        if not made_by_tippetop(path):
            raise TippetopError(f"{str(path)!r} exists and tippetop did not write it: "
                                f"expected --force to replace it, or --out FILE")
    build_report(str(results), path, accuracy_dir=accuracy_dir)
    return path


__all__ = ["rebuild_report"]
