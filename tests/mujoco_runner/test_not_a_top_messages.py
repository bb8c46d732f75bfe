"""MJCF files that MuJoCo compiles but that are not a top: one line that names the file.

Tracker issue 43, item 6. Each case writes a file the way someone else would (their own
names, a floor called something else, comments), runs the real command line on it in a
subprocess and checks: exit 2, nothing on stdout, exactly one ``tippetop: error:`` line on
stderr with no traceback, the file's name in that line, what was expected, and (for a
keyframe left behind by a removed free joint) the hint. The messages from text say ``mjcf``
and from a file name it: checked on :func:`load_top` directly.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner.model import load_error, load_top

_HEAD = """<?xml version="1.0"?>
<!-- {comment} -->
<mujoco model="{model}">
  <option gravity="0 0 -9.81" timestep="0.0005"/>
  <worldbody>
    <light pos="0 0 1"/>
    <!-- the table -->
    <geom name="workbench" type="plane" size="0.4 0.4 0.02" rgba=".7 .6 .5 1"/>
"""
_TAIL = """  </worldbody>
</mujoco>
"""

#: A brick sitting on the bench: no joint at all, so it is welded to the world.
WELDED_BRICK = _HEAD.format(comment="a brick, welded to the world", model="brick") + """\
    <body name="brick" pos="0 0 0.05">
      <geom name="brick_geom" type="box" size="0.05 0.03 0.02" rgba=".8 .2 .2 1"/>
    </body>
""" + _TAIL

#: Two tops on the same bench: two free bodies.
TWO_TOPS = _HEAD.format(comment="a pair of tops racing", model="race") + """\
    <body name="red_top" pos="-0.1 0 0.02">
      <freejoint name="red_free"/>
      <geom name="red_ball" type="sphere" size="0.02"/>
    </body>
    <body name="blue_top" pos="0.1 0 0.02">
      <freejoint name="blue_free"/>
      <geom name="blue_ball" type="sphere" size="0.02"/>
    </body>
""" + _TAIL

#: A marble whose free joint was deleted, keeping the keyframe written for it.
STALE_KEYFRAME = _HEAD.format(comment="marble: free joint removed while debugging",
                              model="marble") + """\
    <body name="marble" pos="0 0 0.012">
      <!-- <freejoint/> taken out for now -->
      <geom name="glass" type="sphere" size="0.012"/>
    </body>
""" + _TAIL.replace("</mujoco>", """\
  <keyframe>
    <key name="spinning" qpos="0 0 0.012 1 0 0 0" qvel="0 0 0 0 0 150"/>
  </keyframe>
</mujoco>""")
STALE_KEY_LINE = 15
assert "<key " in STALE_KEYFRAME.splitlines()[STALE_KEY_LINE - 1]

#: A top built of two bodies: the stem is a child body of the ball.
CHILD_BODY = _HEAD.format(comment="top with the stem as its own body", model="twopiece") + """\
    <body name="shell" pos="0 0 0.015">
      <freejoint/>
      <geom name="shell_ball" type="sphere" size="0.015"/>
      <body name="handle" pos="0 0 0.015">
        <geom name="handle_rod" type="cylinder" size="0.002 0.01"/>
      </body>
    </body>
""" + _TAIL


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``python -m tippetop.compare.cli ARGS`` in ``cwd``, output captured as text."""
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args], cwd=cwd,
                          env=dict(os.environ), capture_output=True, text=True, timeout=120,
                          check=False)


def _bad_input_line(r: subprocess.CompletedProcess[str]) -> str:
    """The one ``tippetop: error:`` line of a run that must end with exit 2."""
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("tippetop: error: "), r.stderr
    assert r.stdout == "", r.stdout
    return lines[0]


CASES = {
    "welded_brick": (WELDED_BRICK, "my brick.xml",
                     ["expected exactly one body with a free joint",
                      "got 0 free joints", "needs a <freejoint/>"]),
    "two_tops": (TWO_TOPS, "race.xml",
                 ["expected exactly one body with a free joint",
                  "got 2 free joints (bodies 'red_top', 'blue_top')"]),
    "stale_keyframe": (STALE_KEYFRAME, "marble.xml",
                       [f"line {STALE_KEY_LINE}",
                        "keyframe 'spinning' has 7 qpos numbers but the model has 0",
                        "a keyframe written for a free joint that is no longer there?",
                        "Remove the keyframe or fix its qpos"]),
    "child_body": (CHILD_BODY, "twopiece.xml",
                   ["body 'shell': expected no child bodies", "['handle']"]),
}


@pytest.mark.parametrize("command", ["simulate", "validate"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_a_file_that_is_not_a_top_is_one_line_naming_the_file(tmp_path: Path, case: str,
                                                               command: str) -> None:
    text, name, fragments = CASES[case]
    (tmp_path / name).write_text(text)
    out = tmp_path / "result.csv"
    args = (["simulate", "--mjcf", name, "--out", str(out)] if command == "simulate"
            else ["validate", name, "--no-tune"])
    line = _bad_input_line(_cli(*args, cwd=tmp_path))
    # the file named, as the one thing the message is about (its path, then what is wrong)
    assert f"{name}: " in line, line
    for fragment in fragments:
        assert fragment in line, (fragment, line)
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # nothing written


def test_the_stale_keyframe_without_its_hint_was_mujocos_raw_message(tmp_path: Path) -> None:
    """What MuJoCo says of the stale keyframe (no line, no hint) is what load_error reads."""
    import mujoco

    path = tmp_path / "marble.xml"
    path.write_text(STALE_KEYFRAME)
    with pytest.raises(ValueError, match="invalid qpos size, expected 0, got 7") as raw:
        mujoco.MjModel.from_xml_path(str(path))
    assert "line" not in str(raw.value) and "Remove" not in str(raw.value)
    line = load_error(str(raw.value), str(path))
    assert line.startswith(f"{path}: expected a valid MJCF document, got a MuJoCo error at "
                           f"line {STALE_KEY_LINE} (<key>): keyframe 'spinning' has 7 qpos")


@pytest.mark.parametrize("case", sorted(CASES))
def test_load_top_names_a_file_and_says_mjcf_for_text(tmp_path: Path, case: str) -> None:
    text, name, fragments = CASES[case]
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(TippetopError) as from_file:
        load_top(path)
    with pytest.raises(TippetopError) as from_text:
        load_top(text)
    file_msg, text_msg = str(from_file.value), str(from_text.value)
    assert file_msg.startswith(f"{path}: ") and "\n" not in file_msg, file_msg
    assert str(tmp_path) not in text_msg and "\n" not in text_msg, text_msg
    for fragment in fragments:
        assert fragment in file_msg and fragment in text_msg, fragment
    # the same words, only the name of what was read differs
    assert file_msg.removeprefix(f"{path}: ") == text_msg.removeprefix("mjcf: "), \
        (file_msg, text_msg)


@pytest.mark.parametrize(("key", "said"), [
    # an unnamed keyframe: by its index, still with its line and hint
    ('<key qpos="0 0 0.012 1 0 0 0"/>', "keyframe 0 (no name) has 7 qpos numbers but the "
     "model has 0: a keyframe written for a free joint that is no longer there? Remove the "
     "keyframe or fix its qpos"),
    # its velocity too: 6 qvel numbers are the free joint's
    ('<key name="v" qvel="0 0 0 0 0 150"/>', "keyframe 'v' has 6 qvel numbers but the model "
     "has 0: a keyframe written for a free joint that is no longer there? Remove the keyframe "
     "or fix its qvel"),
    # MuJoCo does not say how many ctrl numbers it got: they are counted in the file
    ('<key name="c" ctrl="1 2"/>', "keyframe 'c' has 2 ctrl numbers but the model has 0: a "
     "keyframe written for actuators that are no longer there? Remove the keyframe or fix "
     "its ctrl"),
])
def test_other_oversized_keyframes_get_the_line_and_a_hint(key: str, said: str) -> None:
    text = STALE_KEYFRAME.replace(
        '<key name="spinning" qpos="0 0 0.012 1 0 0 0" qvel="0 0 0 0 0 150"/>', key)
    assert key in text
    with pytest.raises(TippetopError) as err:
        load_top(text)
    assert str(err.value) == (f"mjcf: expected a valid MJCF document, got a MuJoCo error at line "
                              f"{STALE_KEY_LINE} (<key>): {said}")


def test_a_keyframe_with_one_number_too_many_for_a_free_joint(tmp_path: Path) -> None:
    """A top with its free joint and 8 qpos numbers: not "a free joint no longer there"."""
    text = STALE_KEYFRAME.replace("<!-- <freejoint/> taken out for now -->", "<freejoint/>") \
        .replace('qpos="0 0 0.012 1 0 0 0"', 'qpos="0 0 0.012 1 0 0 0 0"')
    with pytest.raises(TippetopError) as err:
        load_top(text)
    msg = str(err.value)
    assert "keyframe 'spinning' has 8 qpos numbers but the model has 7: a keyframe written " \
           "for joints that are no longer there?" in msg, msg
    assert "free joint" not in msg
