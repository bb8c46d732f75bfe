"""Named engine/friction modes: an engine plus the scene overrides that select it."""

from __future__ import annotations

from tippetop.models.errors import TippetopError, did_you_mean

#: mode -> (engine, overrides). Every mode is a plain scene run, so it caches like one.
MODES: dict[str, tuple[str, tuple[str, ...]]] = {
    "ode": ("ode", ()),
    "ode-paper-form": ("ode", ("ode.formulation=paper",)),
    "ode-coulomb": ("ode", ("friction.law=coulomb",)),
    "ode-viscous": ("ode", ("friction.law=viscous",)),
    "ode-coulomb_viscous": ("ode", ("friction.law=coulomb_viscous",)),
    "mujoco-paper": ("mujoco", ("mujoco.friction=paper",)),
    "mujoco-native": ("mujoco", ("mujoco.friction=native", "mujoco.calibrated=true")),
    "mujoco-native-pyramidal": ("mujoco", ("mujoco.friction=native", "mujoco.calibrated=true",
                                           "mujoco.cone=pyramidal")),
    "mujoco-native-elliptic": ("mujoco", ("mujoco.friction=native", "mujoco.calibrated=true",
                                          "mujoco.cone=elliptic")),
    "mujoco-native-condim4": ("mujoco", ("mujoco.friction=native", "mujoco.calibrated=true",
                                         "effects.torsional=true")),
    "mujoco-native-condim6": ("mujoco", ("mujoco.friction=native", "mujoco.calibrated=true",
                                         "effects.torsional=true", "effects.rolling=true")),
    # MuJoCo's own friction with the model's own settings: a loaded MJCF file as it says; a
    # generated top with the scene's [mujoco] values (no calibration)
    "mujoco-file": ("mujoco", ("mujoco.friction=native", "mujoco.calibrated=false")),
}


def parse_modes(text: str) -> list[str]:
    """Split ``ode,mujoco-paper`` into known mode names."""
    modes = [m.strip() for m in text.split(",") if m.strip()]
    for m in modes:
        if m not in MODES:
            raise TippetopError(f"--modes: expected a comma-separated list of "
                                f"{', '.join(MODES)}, got {m!r}{did_you_mean(m, MODES)}")
    if not modes:
        raise TippetopError(f"--modes: expected at least one mode, got {text!r}")
    return modes


def mode_task_parts(mode: str) -> tuple[str, tuple[str, ...]]:
    """(engine, overrides) of a mode."""
    return MODES[mode]
