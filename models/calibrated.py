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
