"""Output folders are written all or nothing, and never over a user's files without --force."""

from __future__ import annotations

from pathlib import Path

import pytest

from tippetop.compare.running.io import check_output_dir, staged_output_dir
from tippetop.models.errors import TippetopError


def test_a_new_folder_appears_whole(tmp_path: Path) -> None:
    out = tmp_path / "report"
    with staged_output_dir(out) as stage:
        (stage / "tables").mkdir()
        (stage / "tables" / "a.csv").write_text("t\n0\n")
        (stage / "report.html").write_text("<html>")
        assert not out.exists()  # nothing at the destination while it is written
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*")) == [
        "report.html", "tables", "tables/a.csv"]
    assert [p.name for p in tmp_path.iterdir()] == ["report"]  # no staging folder left


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_an_interrupted_write_leaves_nothing(tmp_path: Path, error: type) -> None:
    out = tmp_path / "report"
    with pytest.raises(error), staged_output_dir(out) as stage:
        (stage / "results.json").write_text("{}")
        raise error
    assert list(tmp_path.iterdir()) == []


def test_force_writes_next_to_the_users_files(tmp_path: Path) -> None:
    out = tmp_path / "report"
    out.mkdir()
    (out / "mine.txt").write_text("the user's")
    with pytest.raises(TippetopError, match="--force"):
        check_output_dir(out, force=False)
    with staged_output_dir(check_output_dir(out, force=True)) as stage:
        (stage / "report.html").write_text("<html>")
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt", "report.html"]
    assert (out / "mine.txt").read_text() == "the user's"
