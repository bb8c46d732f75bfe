"""The calibrated native-friction settings shipped in ``models/calibrated_native.toml``."""

from __future__ import annotations

import tomllib
from functools import lru_cache
from pathlib import Path
from typing import Any

from tippetop.models.resources import data_path

#: The reference's mu in every calibration scene (the paper's): the calibrated mu is the one
#: that reproduces a law of this mu; for another, it is scaled in proportion.
CALIBRATION_MU = 0.1
#: Written by ``tippetop calibrate``; the defaults of ``mujoco.friction=native``.
CALIBRATION_FILE: Path = data_path("tippetop.models", "calibrated_native.toml")


@lru_cache(maxsize=1)
def calibrated_native_settings() -> dict[str, Any]:
    """The calibrated ``[settings]`` (mu, cone, impratio, solref, solimp, ...), or {} if none."""
    if not CALIBRATION_FILE.is_file():
        return {}
    with CALIBRATION_FILE.open("rb") as fh:
        data = tomllib.load(fh)
    out = dict(data.get("settings", {}))
    for key in ("solref", "solimp"):
        if key in out:
            out[key] = tuple(out[key])
    return out


@lru_cache(maxsize=1)
def calibration_label() -> str:
    """Which calibration the native mode runs with, in one line: when, how and what.

    Example: ``2026-11-27 sysid: pyramidal impratio=0.995 solref=[0.00138, 1] d0=0.0539
    mu=0.105 (objective 0.02829 rad)``; ``none`` if the file is missing.
    """
    if not CALIBRATION_FILE.is_file():
        return "none"
    with CALIBRATION_FILE.open("rb") as fh:
        data = tomllib.load(fh)
    s, prov = data.get("settings", {}), data.get("provenance", {})
    date = str(prov.get("date", "undated"))[:10]
    command = str(prov.get("command", ""))
    search = ("sysid" if "--search sysid" in command or str(prov.get("search", "")).startswith(
        "mujoco.sysid") else "compass")
    solref = s.get("solref", ["?", "?"])
    solimp = s.get("solimp", ["?"])
    objective = prov.get("objective")
    tail = f" (objective {objective:.4g} rad)" if isinstance(objective, float) else ""
    return (f"{date} {search}: {s.get('cone')} impratio={s.get('impratio'):g} "
            f"solref=[{solref[0]:g}, {solref[1]:g}] d0={solimp[0]:g} mu={s.get('mu'):g}{tail}")
