"""Scene files: the catalogue, unknown keys, overrides."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tippetop.compare.measures import theory
from tippetop.models.errors import TippetopError
from tippetop.models.scene import SCHEMA, catalogue_names, load_scene, parse_override

SCENES_MD = Path(__file__).resolve().parents[2] / "docs" / "scenes.md"


def test_catalogue_has_the_papers_cases() -> None:
    names = set(catalogue_names())
    assert {"fig3", "fig4", "fig6", "fig7a", "fig7b", "fig8a", "fig8b"} <= names
    assert {f"fig11_n0{n}" for n in range(30, 90, 10)} <= names


@pytest.mark.parametrize("name", catalogue_names())
def test_every_catalogue_scene_loads(name: str) -> None:
    s = load_scene(name)
    assert s.name == name
    assert s.run.t_end_s > 0
    assert s.expect.get("outcome") in ("upright", "intermediate", "inverted")


def test_catalogue_groups_match_the_paper() -> None:
    """Figs. 3-6, 11: Group II; Fig. 7: Group I; Fig. 8: Group III."""
    groups = {n: theory.group(load_scene(n).top) for n in catalogue_names()}
    assert groups["fig7a"] == groups["fig7b"] == "I"
    assert groups["fig8a"] == groups["fig8b"] == "III"
    assert all(g == "II" for n, g in groups.items() if n.startswith(("fig3", "fig4", "fig6",
                                                                      "fig11")))


def test_default_scene_is_the_papers_top() -> None:
    s = load_scene(None)
    assert s.top.A_over_C == pytest.approx(1.0)
    assert s.top.a_over_R == pytest.approx(0.1)
    assert (s.init.theta0, s.init.n0) == (0.1, 100.0)
    assert s.friction.law == "modified_coulomb"


def test_unknown_key_is_named(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text("[top]\nA_over_C = 1.0\nmass = 3\n")
    with pytest.raises(TippetopError, match="unknown key 'top.mass'"):
        load_scene(f)


def test_unknown_section_is_named(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text("[tops]\nA_over_C = 1.0\n")
    with pytest.raises(TippetopError, match=r"unknown section \[tops\]"):
        load_scene(f)


def test_malformed_and_missing_files(tmp_path: Path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text("[top\nA_over_C = \n")
    with pytest.raises(TippetopError, match="valid TOML"):
        load_scene(f)
    with pytest.raises(TippetopError, match="existing .toml"):
        load_scene(tmp_path / "missing.toml")


def test_wrong_type_is_named(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text('[init]\nn0 = "fast"\n')
    with pytest.raises(TippetopError, match="init.n0: expected a number"):
        load_scene(f)


def test_overrides() -> None:
    s = load_scene("fig3", ["init.n0=60", "friction.law=coulomb", "mujoco.solref=[0.01, 1]",
                            "ode.formulation=paper", "top.A_over_C=0.95"])
    assert s.init.n0 == 60.0
    assert s.friction.law == "coulomb"
    assert s.mujoco.solref == (0.01, 1.0)
    assert s.ode.formulation == "paper"
    assert s.top.A_over_C == pytest.approx(0.95)


@pytest.mark.parametrize("item", ["init.n0", "n0=3", "init.spin=3", "a.b.c=1"])
def test_bad_overrides(item: str) -> None:
    with pytest.raises(TippetopError):
        parse_override(item)


def test_issue_set_keys_exist() -> None:
    """The --set keys the command-line contract promises."""
    for key in ("top.A_over_C", "top.a_over_R", "top.C_factor", "top.R_m", "top.M_kg",
                "friction.law", "friction.mu", "friction.Lambda_mps", "init.theta0", "init.n0",
                "run.t_end_s", "ode.rtol", "ode.atol", "ode.formulation", "mujoco.friction",
                "mujoco.timestep_s", "mujoco.integrator", "mujoco.cone", "mujoco.condim",
                "mujoco.mu", "mujoco.solref", "mujoco.solimp", "mujoco.impratio"):
        section, name = key.split(".")
        assert name in SCHEMA[section], key


def test_content_hash_tracks_physics_not_names() -> None:
    a = load_scene("fig3")
    assert a.content_hash() == load_scene("fig3").content_hash()
    assert a.content_hash() != load_scene("fig3", ["init.n0=99"]).content_hash()


def test_docs_scenes_md_documents_every_key() -> None:
    """docs/scenes.md has a section per SCHEMA section and, in it, a table row per key.

    And no row for a key SCHEMA does not have: the page documents exactly the contract.
    """
    text = SCENES_MD.read_text()
    parts = re.split(r"^## `\[(\w+)\]`.*$", text, flags=re.MULTILINE)
    sections = dict(zip(parts[1::2], parts[2::2], strict=True))
    documented = {s: re.findall(r"^\| `(\w+)` \|", body, flags=re.MULTILINE)
                  for s, body in sections.items()}
    missing = [f"{s}.{k}" for s in SCHEMA for k in SCHEMA[s] if k not in documented.get(s, [])]
    assert not missing, f"keys of SCHEMA missing from docs/scenes.md: {missing}"
    extra = [f"{s}.{k}" for s, keys in documented.items() for k in keys
             if k not in SCHEMA.get(s, {})]
    assert not extra, f"keys in docs/scenes.md that SCHEMA does not have: {extra}"
