"""The contact's lift as a figure: MuJoCo's normal force against the slip, at mu = 0.1 and 1.

For the docs' "Tuning MuJoCo's contact for your top" (made at build time by
``docs/hooks/images.py``) and for anyone who wants the picture:
``python -m tippetop.compare.report.lift OUT.png``.

Left: the lift-off slip (a ball of the tutorial top's size, R = 2 cm, M = 55.5 g, held at
that slip, leaves the table) against mu, for MuJoCo's default contact and the calibrated
settings (mu scaled as the law's), with the largest slips the reference reaches on the paper's
top (mu = 0.1) and on MuJoCo's tutorial top (mu = 1) as stars. A point missing from a line:
that contact does not lift the ball below 10 m/s.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

#: The ball probed: MuJoCo's tutorial tippe top's.
BALL_R_M, BALL_M_KG = 0.02, 0.0555
#: The tops whose reference slips are drawn (relative to the repository's root).
TOPS = {"the paper's top (mu = 0.1)": "examples/paper_loaded_sphere.xml",
        "MuJoCo's tutorial top (mu = 1)": "tests/data/tutorial_tippe_top.xml"}


#: The friction coefficients of the lift-off curve.
MUS = (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0)


def settings(mu: float) -> dict[str, Any]:
    """MuJoCo's default contact and the calibrated settings (mu scaled as the law's) at mu."""
    from tippetop.models.calibrated import CALIBRATION_MU, calibrated_native_settings
    from tippetop.mujoco_runner.contact_lift import Contact

    cal = calibrated_native_settings()
    return {"MuJoCo's default contact": Contact(mu, timestep_s=2e-4),
            "the calibrated settings": Contact(mu * float(cal["mu"]) / CALIBRATION_MU,
                                               str(cal["cone"]), float(cal["impratio"]),
                                               tuple(cal["solref"]), tuple(cal["solimp"]),
                                               2e-4)}


def curves() -> dict[str, Any]:
    """Each contact's lift-off slip over :data:`MUS`."""
    from tippetop.mujoco_runner.contact_lift import Probe

    lift: dict[str, list[float]] = {}
    for mu in MUS:
        for name, c in settings(mu).items():
            probe = Probe(c, BALL_R_M, BALL_M_KG)
            v = probe.lift_off_slip()
            lift.setdefault(name, []).append(np.nan if v is None else v)
    return {"lift": lift}


def reference_slips(root: Path) -> dict[str, float]:
    """The largest slip each top's reference reaches while the ball alone touches (m/s)."""
    from tippetop.compare.running.runner import Task, run_tasks
    from tippetop.compare.studies.lift import reference_slip
    from tippetop.models.scene import Override

    names = list(TOPS)
    tasks = [Task(None, (Override.of("top.mjcf", str(root / TOPS[n])),
                         Override.of("run.t_end_s", 3)), "ode", "paper")
             for n in names]
    out = {}
    for name, res in zip(names, run_tasks(tasks, label="lift figure"), strict=True):
        got = reference_slip(res.table, (res.summary or {}).get("t_stem"))
        if got is not None:
            out[name] = got[0]
    return out


def lift_figure(path: Path, root: Path) -> Path:
    """Write the figure (PNG) and return its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data, slips = curves(), reference_slips(root)
    fig, ax = plt.subplots(figsize=(7.5, 5.0), layout="constrained")
    colours = {"MuJoCo's default contact": "tab:grey", "the calibrated settings": "tab:blue"}
    for name, v in data["lift"].items():
        ax.loglog(MUS, v, "o-", color=colours[name], label=f"{name}: the ball leaves above")
    for (top, v), mu, colour in zip(slips.items(), (0.1, 1.0), ("tab:green", "tab:red"),
                                    strict=False):
        ax.loglog([mu], [v], "*", ms=13, color=colour,
                  label=f"{top}: its reference slips up to {v:.2g} m/s")
    ax.set_xlabel("mu")
    ax.set_ylabel("slip at the contact (m/s)")
    ax.set_title("the slip above which MuJoCo's contact lifts the ball off the table\n"
                 "(a star above a line: that contact hops where the reference stays on)",
                 fontsize=9)
    fig.legend(fontsize=7, loc="outside lower center", ncols=2)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """``python -m tippetop.compare.report.lift OUT.png [ROOT]``."""
    args = sys.argv[1:] if argv is None else argv
    if not args or not args[0].endswith(".png"):
        print("lift figure: expected OUT.png [ROOT], got " + (" ".join(args) or "nothing"),
              file=sys.stderr)
        return 2
    root = Path(args[1]) if len(args) > 1 else Path.cwd()
    print(lift_figure(Path(args[0]), root))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
