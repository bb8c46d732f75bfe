"""Behaviour stays as it was: today's outputs against those stored before issue 42 began.

tests/stored/outputs.py says what is stored (the quick profile, validate on the three examples,
the fidelity map's small grid and the bisect fixture), from which commit, and how they are
compared: keys and words exactly, numbers (in texts too) to a relative 1e-4 or 1e-10 absolute
(the quick profile's MuJoCo growth fits moved by up to 1.03e-5 between runs of the same code; a
change of behaviour moves a verdict, a sentence or a number by far more). The bisect fixture
runs in seconds; the others run the commands and are slow (the quick nightly ~2 min on 2
cores, validate ~1 min an example, the fidelity grid ~3 min).
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
    assert outputs.same({"a": 1.0 + 2e-5, "b": [1, "x"], "c": {"d": None}}, stored) == []
    assert outputs.same({"a": 1.001, "b": [1, "x"], "c": {"d": None}}, stored)
    assert outputs.same({"a": 1.0, "b": [1, "y"], "c": {"d": None}}, stored)
    assert outputs.same({"a": 1.0, "b": [1, "x"], "c": {"e": None}}, stored)
    assert outputs.same({"a": 1.0, "b": [1], "c": {"d": None}}, stored)


def test_numbers_in_a_text_are_compared_as_numbers_and_its_words_exactly() -> None:
    """As the fresh clone's CI saw them: n1 in a check's sentence, 1e-13 apart."""
    stored = "n1_measured: {'A/C=1,a/R=0.05': 38.395787710911726} (no baseline yet)"
    assert outputs.same("n1_measured: {'A/C=1,a/R=0.05': 38.395787710914504} (no baseline yet)",
                        stored) == []
    assert outputs.same("n1_measured: {'A/C=1,a/R=0.05': 38.5} (no baseline yet)", stored)
    assert outputs.same("n4_measured: {'A/C=1,a/R=0.05': 38.395787710911726} (no baseline yet)",
                        stored)
    assert outputs.same("residual 1.6679905525307798e-06", "residual 1.667973395415568e-06") == []


def test_the_machine_is_left_out_and_paths_are_spelt_alike() -> None:
    out = outputs.normalised({"wall_s": 3.2, "t_end_s": 8.0, "started": "x",
                              "file": "/tmp/run/x.xml",
                              "message": "40,000 steps to t = 8 s in 0.18 s"}, ["/tmp/run"])
    assert out == {"t_end_s": 8.0, "file": "<ROOT>/x.xml",
                   "message": "40,000 steps to t = 8 s in <wall>"}
