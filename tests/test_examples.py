"""The MJCF tops in ``examples/``: read as their files say, and validated.

The loader's reading of each file is checked against the file itself (its printed sizes and
masses, and for the cylinder top the inertia computed by hand from its geoms), not against the
loader's own output.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from tippetop.compare.measures import theory
from tippetop.mujoco_runner.model import load_top, stem_from_model
from tippetop.mujoco_runner.state import file_top

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_at_least_three_examples() -> None:
    names = {p.name for p in EXAMPLES.glob("*.xml")}
    assert {"paper_loaded_sphere.xml", "capsule_stem_top.xml",
            "cylinder_stem_ballast.xml"} <= names


@pytest.mark.parametrize("name", ["paper_loaded_sphere.xml", "capsule_stem_top.xml",
                                  "cylinder_stem_ballast.xml"])
def test_examples_load_without_warnings(name: str) -> None:
    # the stem each top has is the one the reference models; the ballast does not collide
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ft = file_top(EXAMPLES / name)
    assert ft.keyframes and all(init is not None for init in ft.keyframe_inits)


def test_capsule_stem_is_read_from_the_file() -> None:
    # fromto z = 12 .. 29 mm, radius 4 mm: a rounded end, its centre 29 mm from the ball's
    stem, note = stem_from_model(load_top(EXAMPLES / "capsule_stem_top.xml"))
    assert stem is not None and stem.kind == "sphere"
    assert math.isclose(stem.offset_m, 0.029, rel_tol=1e-9)
    assert math.isclose(stem.radius_m, 0.004, rel_tol=1e-9)
    assert "geom 'stem'" in note


def test_cylinder_top_inertia_by_hand() -> None:
    # ball: solid sphere r 18 mm, 16 g at the origin; stem: cylinder r 3.5 mm, length 20 mm,
    # 0.5 g centred at z = 22 mm; ballast: box half-sizes 11 x 11 x 1.5 mm, 16 g at z = -6 mm
    m_b, r_b = 0.016, 0.018
    m_s, r_s, l_s, z_s = 0.0005, 0.0035, 0.020, 0.022
    m_x, hx, hz, z_x = 0.016, 0.011, 0.0015, -0.006
    M = m_b + m_s + m_x
    z_G = (m_s * z_s + m_x * z_x) / M
    C = 0.4 * m_b * r_b**2 + 0.5 * m_s * r_s**2 + m_x * (hx**2 + hx**2) / 3
    A = (0.4 * m_b * r_b**2 + m_b * z_G**2
         + m_s * (3 * r_s**2 + l_s**2) / 12 + m_s * (z_s - z_G) ** 2
         + m_x * (hx**2 + hz**2) / 3 + m_x * (z_x - z_G) ** 2)
    ft = file_top(EXAMPLES / "cylinder_stem_ballast.xml")
    top = ft.top
    assert math.isclose(top.M_kg, M, rel_tol=1e-9)
    assert math.isclose(top.a_m, -z_G, rel_tol=1e-9)
    assert math.isclose(top.C_kgm2, C, rel_tol=1e-9)
    assert math.isclose(top.A_kgm2, A, rel_tol=1e-9)
    # the file's comment: A/C = 0.99, a/R = 0.15, Group II; the pair's mu; both keyframes
    assert (round(top.A_over_C, 2), round(top.a_over_R, 2)) == (0.99, 0.15)
    assert theory.summary(top)["group"] == "II"
    assert ft.mu == pytest.approx(0.2) and ft.keyframes == ("fast", "slow")
    assert ft.stem is not None and ft.stem.kind == "cylinder"
    assert math.isclose(ft.stem.offset_m, 0.032, rel_tol=1e-9)
    assert math.isclose(ft.stem.radius_m, 0.0035, rel_tol=1e-9)


def test_capsule_top_validates_through_the_stem(tmp_path: Path) -> None:
    """The paper's law in MuJoCo follows the reference onto a capsule stem it was not tuned on.

    Tolerances are the validator's: event times within max(0.1 s, 10 %) of the reference's,
    Jellett's drift before the stem <= 1e-3 (MuJoCo) and 1e-6 (the reference).
    """
    proc = subprocess.run(
        [sys.executable, "-m", "tippetop.compare.cli", "validate",
         str(EXAMPLES / "capsule_stem_top.xml"), "--json", "--out", str(tmp_path / "v"),
         "--no-tune"],
        capture_output=True, text=True, timeout=600)
    assert proc.returncode in (0, 1), proc.stderr
    res = json.loads(proc.stdout)
    assert res["model"]["group"] == "II" and res["model"]["theory_outcome"] == "inverted"
    for run in ("ode/paper", "mujoco/paper"):
        mine = [c for c in res["verdict"] if c["run"] == run]
        assert {c["check"] for c in mine} >= {"outcome", "jellett_before_stem"}
        assert all(c["passed"] for c in mine), mine
    ode, paper = res["runs"]["ode/paper"], res["runs"]["mujoco/paper"]
    assert ode["t_stem"] is not None and paper["t_stem"] is not None
    assert paper["note"].startswith("ran at dt = 0.0002 s")  # the file's 0.5 ms is too long
