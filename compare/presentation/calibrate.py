"""What ``tippetop calibrate`` prints: the settings, the objective and the residuals' table."""

from __future__ import annotations

from typing import Any

from tippetop.compare.presentation.terminal import fmt_duration
from tippetop.models.numbers import number_text


def print_report(report: dict[str, Any]) -> None:
    """The settings, the objective and a table of residuals, as ``tippetop calibrate`` prints."""
    p = report["provenance"]
    s = report["settings"]
    print(f"settings: {', '.join(f'{k}={v}' for k, v in s.items())}")
    print(f"objective {number_text(p['objective'], 'rad')} on "
          f"{', '.join(p['calibration_set'])} (MuJoCo defaults "
          f"{number_text(p['objective_mujoco_defaults'], 'rad')}); {p['runs_used']} runs, "
          f"{p['candidates_evaluated']} candidates, stop: {p['stop_reason']}")
    print(f"MuJoCo defaults: {p['mujoco_defaults']}")
    hdr = (f"{'scene':<12} {'role':<11} {'rms':>7} {'t_inv ode':>9} {'t_inv mj':>9} "
           f"{'asymp ode':>9} {'asymp mj':>9} {'outcome':<24} {'J drift':>8}")
    print(hdr)
    for r in report["residuals"]:
        def f(v: Any) -> str:
            return "-" if v is None else f"{v:.3f}"
        outcome = f"{r['outcome_mujoco']}/{r['outcome_ode']}"
        print(f"{r['scene']:<12} {r['role']:<11} {f(r['rms_rad']):>7} {f(r['t_invert_ode']):>9} "
              f"{f(r['t_invert_mujoco']):>9} {f(r['theta_asymp_ode']):>9} "
              f"{f(r['theta_asymp_mujoco']):>9} {outcome:<24} {r['J_rel_drift']:>8.1e}")
    for line in p["findings"]:
        print(f"- {line}")
    print(f"wrote {report['out']} in {fmt_duration(p['wall_s'])}")


__all__ = ["print_report"]
