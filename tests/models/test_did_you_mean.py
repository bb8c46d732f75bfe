"""did_you_mean: the known name a mistyped one meant, for one-line error messages."""

from __future__ import annotations

import pytest

from tippetop.models.errors import TippetopError, closest_name, did_you_mean, expect
from tippetop.models.modes import MODES
from tippetop.models.scene import SCHEMA, catalogue_names

KEYS = [f"{s}.{k}" for s in SCHEMA for k in SCHEMA[s]]


@pytest.mark.parametrize(("given", "meant"), [
    ("run.t_end", "run.t_end_s"),  # a close key in the same section
    ("Run.T_END_S", "run.t_end_s"),  # another case
    ("rn.t_end_s", "run.t_end_s"),  # a mistyped section
    ("run.n0", "init.n0"),  # the same key in another section
    ("run.mu", "friction.mu"),
    ("init.t_end", "run.t_end_s"),  # a close key in another section
    ("top.M", "top.M_kg"),  # the one key of the section that starts so
    ("mujoco.noslip", "mujoco.noslip_iterations"),
    ("init.omega0", "init.Omega0"),
    ("init.theta", "init.theta0"),  # theta0 and thetadot0 both start so: the closer one
    ("friction.lambda", "friction.Lambda_mps"),
    ("t_end_s", "run.t_end_s"),  # a key without its section
    ("n0", "init.n0"),
])
def test_scene_keys(given: str, meant: str) -> None:
    assert closest_name(given, KEYS) == meant
    assert did_you_mean(given, KEYS) == f" (did you mean '{meant}'?)"


@pytest.mark.parametrize("given", [
    "foo.bar",  # nothing like it
    "top.mass",  # 'top.R_m' and 'ode.max_steps' only look alike
    "run.",  # either of the section's keys
])
def test_scene_keys_without_a_close_one(given: str) -> None:
    assert did_you_mean(given, KEYS) == ""


@pytest.mark.parametrize(("given", "choices", "meant"), [
    ("fig33", catalogue_names(), "fig3"),
    ("FIG3", catalogue_names(), "fig3"),
    ("fig7", catalogue_names(), "fig7a"),  # of two as close, the first
    ("nativ", MODES, "native"),
    ("native_pyramidal", MODES, "native-pyramidal"),
    ("coulomb-viscous", MODES, "coulomb_viscous"),
    ("mjxx", ("mujoco", "mjx", "mjx-f32", "warp"), "mjx"),
    ("warpp", ("mujoco", "mjx", "mjx-f32", "warp"), "warp"),
    ("MJX", ("mujoco", "mjx", "mjx-f32", "warp"), "mjx"),
    ("mujoco=3.3.7", ("mujoco", "mujoco==X.Y.Z", "mjx"), "mujoco==X.Y.Z"),
])
def test_names(given: str, choices: tuple[str, ...], meant: str) -> None:
    assert did_you_mean(given, choices) == f" (did you mean '{meant}'?)"


@pytest.mark.parametrize("given", ["fig3", "xyz", "", "  ", 3, None])
def test_a_known_name_or_nothing_close_gets_nothing(given: object) -> None:
    assert did_you_mean(given, catalogue_names()) == ""  # type: ignore[arg-type]


def test_no_choices() -> None:
    assert did_you_mean("fig3", []) == ""


def test_expect_with_choices() -> None:
    with pytest.raises(TippetopError) as info:
        expect(False, "friction.law", "one of coulomb|viscous", "coulmb", ("coulomb", "viscous"))
    assert str(info.value) == ("friction.law: expected one of coulomb|viscous, got 'coulmb' "
                               "(did you mean 'coulomb'?)")
    with pytest.raises(TippetopError) as info:
        expect(False, "mujoco.condim", "1, 3, 4 or 6", 5, ("1", "3"))
    assert str(info.value) == "mujoco.condim: expected 1, 3, 4 or 6, got 5"
