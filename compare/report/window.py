"""One stretch of MuJoCo's steps as a figure: what the samples see, and what the windows add.

For the docs' "Tuning MuJoCo's contact for your top" (made at build time by
``docs/hooks/images.py``) and for anyone who wants the picture:
``python -m tippetop.compare.report.window OUT.png``.

The fidelity map's point A/C 1.0, a/R 0.25, mu 0.1 with its tuned settings (elliptic cone,
impratio 0.0591, solref 0.4 ms, RK4 at 0.2 ms), from its own start, around 1.385 s: where a
sample every 1 ms (one step in five) found no contact ten samples in a row, and the harness
said the ball left the table for 10 ms. Top: each step's contact (a dot where the top
touches) and the ball's gap above the table, in micrometres; the samples' steps ringed.
Bottom: each step's normal force, and each sample's window mean (the table's N). The ball's
lowest point stays within a micrometre of the table; the contact is on at some steps and off
at others; each window touched.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

#: The point and its tuned settings (docs/data/fidelity-default.json of 2026-11-27).
POINT = (1.0, 0.25, 0.1)
SETTINGS = {"cone": "elliptic", "impratio": 0.0591, "mu": 0.101, "solref": [0.0004, 1.0],
            "solimp": [0.173, 0.95, 0.001, 0.5, 2.0], "timestep_s": 0.0002,
            "integrator": "RK4"}
N0, THETA0 = 105.24614282102553, 0.1
#: The stretch drawn (s).
SPAN_S = (1.376, 1.402)
#: The samples the old reading used: every 1 ms.
SAMPLE_DT_S = 1e-3


def steps_of() -> dict[str, Any]:
    """Each step's pass (a run sampled at every step) over :data:`SPAN_S`, and 1-ms windows."""
    from tippetop.compare.studies.fidelity import point_overrides
    from tippetop.models.resolve import resolve_plan
    from tippetop.models.scene import Override, load_scene
    from tippetop.mujoco_runner.results import window_means
    from tippetop.mujoco_runner.run import simulate_plan

    s = SETTINGS
    over = [*point_overrides(*POINT, N0, THETA0), Override.of("run.t_end_s", SPAN_S[1]),
            Override.of("mujoco.friction", "native"), Override.of("mujoco.cone", s["cone"]),
            Override.of("mujoco.impratio", s["impratio"]), Override.of("mujoco.mu", s["mu"]),
            Override.of("mujoco.solref", s["solref"]), Override.of("mujoco.solimp", s["solimp"]),
            Override.of("mujoco.timestep_s", s["timestep_s"]),
            Override.of("mujoco.integrator", s["integrator"])]
    out: dict[str, Any] = {}
    for key, spacing in (("step", s["timestep_s"]), ("sample", SAMPLE_DT_S)):
        plan = resolve_plan(load_scene(None, [*over, Override.of("run.sample_dt_s", spacing)]),
                            "mujoco").mujoco
        res = simulate_plan(plan)
        t = res.table["t"].to_numpy()
        keep = (t >= SPAN_S[0]) & (t <= SPAN_S[1])
        w = res.windows
        out[key] = {"t": t[keep], "touch": w.int_column("touch")[keep] > 0,
                    "gap_um": 1e6 * w.float_column("gap_max")[keep],
                    "N": window_means(w)["N"][keep]}
    return out


def draw(path: Path) -> None:
    """Write the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = steps_of()
    st, sa = d["step"], d["sample"]
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(9.0, 5.2), sharex=True,
                                 gridspec_kw={"height_ratios": [1.2, 1.0]})
    ms = 1e3 * st["t"]
    ax.plot(ms, st["gap_um"], color="0.35", lw=1.0, label="the ball's gap above the table")
    on = st["touch"]
    ax.plot(ms[on], st["gap_um"][on], "o", ms=3.5, color="tab:green",
            label="a step at which the top touches")
    ax.plot(ms[~on], st["gap_um"][~on], "o", ms=3.5, mfc="white", color="tab:red",
            label="a step without contact")
    k = st["t"] / SAMPLE_DT_S
    sampled = np.isclose(k, np.round(k), rtol=0.0, atol=1e-6)
    ax.plot(ms[sampled], st["gap_um"][sampled], "s", ms=9, mfc="none", color="tab:blue",
            label="the steps a 1-ms sample reads")
    for t0 in 1e3 * sa["t"]:
        ax.axvline(t0, color="tab:blue", lw=0.4, alpha=0.4)
        bx.axvline(t0, color="tab:blue", lw=0.4, alpha=0.4)
    ax.set_ylabel("gap (um)")
    ax.legend(loc="upper right", fontsize=7, ncol=2)
    ax.set_title("A/C 1.0, a/R 0.25, mu 0.1, tuned contact: each step's contact against the "
                 "1-ms samples", fontsize=9)
    bx.plot(ms, st["N"], ".-", ms=3, lw=0.6, color="0.35", label="N at each step")
    bx.step(1e3 * sa["t"], sa["N"], where="pre", color="tab:blue", lw=1.6,
            label="N of each 1-ms window: its steps' mean (the table's N)")
    bx.set_ylabel("normal force (N)")
    bx.set_xlabel("t (ms)")
    bx.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str]) -> int:
    """``python -m tippetop.compare.report.window OUT.png``."""
    if len(argv) != 1:
        print("usage: python -m tippetop.compare.report.window OUT.png", file=sys.stderr)
        return 2
    draw(Path(argv[0]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
