"""Behaviour stays as it was: today's outputs against those stored before issue 42 began.

tests/stored/outputs.py says what is stored (the quick profile, validate on the three examples,
the fidelity map's small grid and the bisect fixture), from which commit, and how they are
compared: keys and texts exactly, numbers to a relative 1e-5 (the quick profile's MuJoCo growth
fits moved by up to 1.4e-6 between two runs of the same code; a change of behaviour moves a
verdict, a sentence or a number by far more). The bisect fixture runs in seconds; the others run the
commands and are slow (the quick nightly ~4 min on 2 cores, validate ~1 min an example, the
fidelity grid ~3 min).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "stored"))

import outputs  # noqa: E402  (tests/stored/outputs.py)
from bisect_fixture import CASES  # noqa: E402


def _check(name: str, tmp_path: Path) -> None:
    now = outputs.run_case(name, tmp_path)
    diffs = outputs.same(now, outputs.stored(name), name)
    assert diffs == [], "\n".join(diffs[:30])


@pytest.mark.parametrize("case", sorted(CASES))
def test_bisect_fixture_as_stored(case: str, tmp_path: Path) -> None:
    _check(f"bisect_{case}", tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("example", outputs.EXAMPLES)
def test_validate_on_the_examples_as_stored(example: str, tmp_path: Path) -> None:
    _check(f"validate_{example}", tmp_path)


@pytest.mark.slow
def test_the_quick_profile_as_stored(tmp_path: Path) -> None:
    _check("quick", tmp_path)


@pytest.mark.slow
def test_fidelity_on_its_small_grid_as_stored(tmp_path: Path) -> None:
    _check("fidelity_small", tmp_path)


def test_the_comparison_sees_a_changed_number_key_and_text() -> None:
    stored = {"a": 1.0, "b": [1, "x"], "c": {"d": None}}
    assert outputs.same({"a": 1.0 + 2e-6, "b": [1, "x"], "c": {"d": None}}, stored) == []
    assert outputs.same({"a": 1.0001, "b": [1, "x"], "c": {"d": None}}, stored)
    assert outputs.same({"a": 1.0, "b": [1, "y"], "c": {"d": None}}, stored)
    assert outputs.same({"a": 1.0, "b": [1, "x"], "c": {"e": None}}, stored)
    assert outputs.same({"a": 1.0, "b": [1], "c": {"d": None}}, stored)


def test_the_machine_is_left_out_and_paths_are_spelt_alike() -> None:
    out = outputs.normalised({"wall_s": 3.2, "t_end_s": 8.0, "started": "x",
                              "file": "/tmp/run/x.xml",
                              "message": "40,000 steps to t = 8 s in 0.18 s"}, ["/tmp/run"])
    assert out == {"t_end_s": 8.0, "file": "<ROOT>/x.xml",
                   "message": "40,000 steps to t = 8 s in <wall>"}
