"""What a calibration reports: findings in words and the TOML file."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from typing import Any

from tippetop.compare.tuning.calibrate.scoring import J_MAX, Candidate, Residual
from tippetop.models.numbers import number_text, signed_text

#: Held-out theta_asymp error that counts as "not reproduced" (rad); the same margin as the
#: outcome classes (:data:`compare.analysis.metrics.OUTCOME_MARGIN`).
ASYMP_TOL = 0.15
#: Held-out inversion-time error that counts as "not reproduced": more than 0.5 s and more than
#: 10 % of the reference's t_invert. A slow rise (Fig. 11, n0 = 50 rad/s, 15 s) crosses pi/2 at
#: a shallow angle, so its crossing time is as sensitive as 10 % of the whole rise; 10 % of
#: Fig. 3's 2.3 s is 0.23 s.
T_INV_TOL_S = 0.5
T_INV_RTOL = 0.1


def findings(holdout: list[Residual], default: list[Residual]) -> list[str]:
    """Plain statements of what the calibrated native friction does and does not reproduce."""
    out: list[str] = []
    for r, d in zip(holdout, default, strict=True):
        if r.error:
            out.append(f"{r.scene}: the calibrated run failed ({r.error})")
            continue
        bad = []
        if not r.outcome_match:
            bad.append(f"outcome {r.outcome_mujoco} vs the reference's {r.outcome_ode}")
        if abs(r.theta_asymp_err) > ASYMP_TOL:
            bad.append(f"theta_asymp {number_text(r.theta_asymp_mujoco, 'rad')} vs "
                       f"{number_text(r.theta_asymp_ode, 'rad')} (error "
                       f"{signed_text(r.theta_asymp_err, 'rad')})")
        if (r.t_invert_err_s is not None
                and abs(r.t_invert_err_s) > max(T_INV_TOL_S, T_INV_RTOL * r.t_invert_ode)):
            bad.append(f"inverts at {number_text(r.t_invert_mujoco, 's')} vs "
                       f"{number_text(r.t_invert_ode, 's')}")
        elif r.t_invert_err_s is None and (r.t_invert_ode is None) != (r.t_invert_mujoco is None):
            who = "MuJoCo" if r.t_invert_mujoco is not None else "the reference"
            bad.append(f"only {who} turns over within {r.t_end_s:g} s")
        base = (f"(MuJoCo defaults: RMS {number_text(d.rms_rad, 'rad')}, theta_asymp "
                f"{number_text(d.theta_asymp_mujoco, 'rad')}, {d.outcome_mujoco})")
        if r.J_rel_drift > J_MAX:
            base += (f"; Jellett drift {number_text(r.J_rel_drift, 'relative')} over "
                     f"{r.t_end_s:g} s, above {number_text(J_MAX, 'relative')}")
        if bad:
            out.append(f"{r.scene} over {r.t_end_s:g} s NOT reproduced: {'; '.join(bad)}; "
                       f"theta RMS {number_text(r.rms_rad, 'rad')} {base}")
        else:
            inv = ("" if r.t_invert_err_s is None else
                   f"t_invert error {signed_text(r.t_invert_err_s, 's')} of "
                   f"{number_text(r.t_invert_ode, 's')}, ")
            out.append(f"{r.scene} over {r.t_end_s:g} s reproduced: outcome "
                       f"{r.outcome_mujoco}, {inv}theta_asymp error "
                       f"{signed_text(r.theta_asymp_err, 'rad')}, theta RMS "
                       f"{number_text(r.rms_rad, 'rad')} {base}")
    return out


# ---------------------------------------------------------------- TOML output
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()
                                if x is not None) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_table(header: str, body: dict[str, Any]) -> list[str]:
    lines = [header]
    lines += [f"{k} = {_toml_value(v)}" for k, v in body.items() if v is not None]
    return lines + [""]


def settings_table(c: Candidate, timestep_s: float, integrator: str) -> dict[str, Any]:
    """The ``[settings]`` table: what :func:`calibrated_native_settings` applies."""
    return {"mu": c.mu, "cone": c.cone, "impratio": c.impratio, "solref": c.solref,
            "solimp": c.solimp, "timestep_s": timestep_s, "integrator": integrator}


def residual_dict(r: Residual, role: str, default: Residual | None) -> dict[str, Any]:
    """A ``[[residual]]`` table: a held-out or calibration residual (and MuJoCo's defaults')."""
    d = {"role": role, **asdict(r)}
    if not d["error"]:
        del d["error"]
    if default is not None:
        d.update({"default_rms_rad": default.rms_rad,
                  "default_t_invert_mujoco": default.t_invert_mujoco,
                  "default_theta_asymp_mujoco": default.theta_asymp_mujoco,
                  "default_outcome_mujoco": default.outcome_mujoco})
    return d


def render_toml(report: dict[str, Any]) -> str:
    """The calibration file: a header comment, ``[settings]``, ``[provenance]``, residuals."""
    lines = [
        "# MuJoCo native-friction settings calibrated against the reference ODE.",
        "# Written by `tippetop calibrate` (compare/calibrate/); the [settings] are the",
        "# defaults of mujoco.friction=native for every key a scene does not set itself.",
        "# Reproduce with the [provenance] command. Residuals: role = \"holdout\" scenes were",
        "# not used by the fit; role = \"calibration\" scenes were.",
        "",
    ]
    lines += _toml_table("[settings]", report["settings"])
    lines += _toml_table("[provenance]", report["provenance"])
    for d in report["residuals"]:
        lines += _toml_table("[[residual]]", d)
    return "\n".join(lines)



def path_text(step: dict[str, Any]) -> str:
    """One step of the search path, as the provenance lists it."""
    text = f"{step['stage']}: objective {step['objective']:.4f}"
    if "settings" in step:
        text += f", {step['settings']}"
    if "steps" in step:
        text += ", steps " + "/".join(f"{v:.3g}" for v in step["steps"].values()) + " decades"
    return text
