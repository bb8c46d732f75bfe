"""Overrides as values (issue 42, item 1): a study builds them from numbers, the command line
parses ``--set`` text once into the same value, and both give the same scene."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tippetop.models.errors import TippetopError
from tippetop.models.scene import Override, as_override, load_scene, override_texts


def test_a_value_and_its_text_give_the_same_scene() -> None:
    values = [Override.of("top.A_over_C", 1.2), Override.of("init.n0", 150),
              Override.of("mujoco.solref", [0.004, 1.0]), Override.of("mujoco.cone", "elliptic"),
              Override.of("mujoco.calibrated", True)]
    texts = ["top.A_over_C=1.2", "init.n0=150", "mujoco.solref=[0.004, 1.0]",
             "mujoco.cone=elliptic", "mujoco.calibrated=true"]
    a, b = load_scene("fig3", values), load_scene("fig3", texts)
    assert a.raw == b.raw and a.set_keys == b.set_keys
    assert a.top == b.top and a.mujoco == b.mujoco and a.init == b.init
    # the values are the same as parsing the text: one form, two spellings
    assert [as_override(t) for t in texts] == values


def test_text_is_the_set_form_a_user_can_paste() -> None:
    assert Override.of("top.A_over_C", 1.2).text() == "top.A_over_C=1.2"
    assert Override.of("mujoco.solref", [0.004, 1]).text() == "mujoco.solref=[0.004, 1]"
    assert Override.of("mujoco.calibrated", False).text() == "mujoco.calibrated=false"
    assert Override.of("mujoco.cone", "elliptic").text() == 'mujoco.cone="elliptic"'
    assert override_texts([Override.of("init.n0", 60.0), "run.t_end_s=1"]) == \
        ["init.n0=60.0", "run.t_end_s=1"]


@given(st.floats(allow_nan=False, allow_infinity=True))
def test_a_float_reads_back_exactly(x: float) -> None:
    o = Override.of("init.n0", x)
    back = Override.parse(o.text())
    assert back.value == x and math.copysign(1.0, back.value) == math.copysign(1.0, x)


def test_an_unknown_key_is_one_clear_error() -> None:
    with pytest.raises(TippetopError, match=r"unknown key 'top\.A_over_c'.*did you mean"):
        Override.of("top.A_over_c", 1.0)
    with pytest.raises(TippetopError, match="expected a number"):
        load_scene("fig3", [Override.of("top.A_over_C", "big")])


def test_overrides_are_hashable_and_compare_by_value() -> None:
    a = Override.of("mujoco.solimp", [0.9, 0.95, 0.001, 0.5, 2.0])
    assert hash(a) == hash(Override.of("mujoco.solimp", (0.9, 0.95, 0.001, 0.5, 2.0)))
    assert isinstance(a.value, tuple)
