"""Why the fidelity map's A/C 0.8, a/R 0.25, mu 0.3 departed: Jellett's drift is the soft contact's.

From its slower start (90 rad/s, theta0 0.1 rad, 32 s) the contact tuned before the widening's
draws keeps every check but Jellett's, which drifts 1.03e-3 against the verdict's 1e-3.
Measured (2026-11-29) with those settings (elliptic, impratio 0.495, solref [0.0004, 1], d0
0.0662, mu 0.297, RK4):

| step | solref time constant | largest penetration | J drift | t_invert |
|---|---|---|---|---|
| 0.2 ms | 0.4 ms | 139 um | 1.031e-3 | 7.42 s |
| 0.1 ms | 0.4 ms | 139 um | 1.025e-3 | 7.42 s |
| 0.05 ms | 0.4 ms | 139 um | 1.021e-3 | 7.42 s |
| 0.1 ms | 0.2 ms | 66 um | 3.9e-4 | 10.58 s |
| 0.05 ms | 0.1 ms | 20 um | 1.1e-4 | 19.02 s |

The reference turns over at 7.61 s. The drift does not move with the step (RK4's error would
fall 16x for half the step, a first-order one's 2x): it is not the integration's. It follows
the contact's penetration, 5-7e-6 per um; a stiffer contact that penetrates less turns over
late (10.6 s and 19 s), beyond the t_invert check. That is the trade the tuning met there. The
widening's draw that now agrees there (solref [0.000431, 1.05], mu 0.276, 0.1 ms) penetrates as
deep, 137 um, with less friction, and drifts 8.9e-4 (docs/guide/fidelity.md). Slow: three runs
of 32 s, about a minute on 2 cores.
"""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

import pytest

POINT = ("top.A_over_C=0.8", "top.a_over_R=0.25", "friction.mu=0.3", "init.n0=90.0",
         "init.theta0=0.1", "init.Omega0=0.0", "init.thetadot0=0.0", "run.t_end_s=32.0")
#: The map's tuned settings at the point (docs/data/fidelity-default.json), but the step and
#: the solref time constant, which the test varies.
TUNED = ("mujoco.friction=native", "mujoco.cone=elliptic", "mujoco.impratio=0.495",
         "mujoco.mu=0.297", "mujoco.solimp=[0.0662, 0.95, 0.001, 0.5, 2.0]",
         "mujoco.integrator=RK4")


def _run(dt: float, timeconst: float) -> dict[str, Any]:
    sets = [*POINT, *TUNED, f"mujoco.timestep_s={dt!r}", f"mujoco.solref=[{timeconst!r}, 1.0]"]
    args = [a for s in sets for a in ("--set", s)]
    proc = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "simulate", "--engine",
                           "mujoco", "--json", *args], capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    # what ran, read back from the compiled model
    assert out["timestep_s"] == pytest.approx(dt) and out["solref"][0] == pytest.approx(timeconst)
    return out


@pytest.mark.slow
def test_the_points_jellett_drift_is_its_contacts_penetration_not_its_step() -> None:
    tuned, half_step, stiffer = _run(2e-4, 4e-4), _run(1e-4, 4e-4), _run(1e-4, 2e-4)
    drift = {k: r["J_rel_drift"] for k, r in
             (("tuned", tuned), ("half_step", half_step), ("stiffer", stiffer))}
    pen = {k: r["max_penetration_m"] for k, r in
           (("tuned", tuned), ("half_step", half_step), ("stiffer", stiffer))}
    # at the verdict's bound (the departure the map reports), 1e-3 within 10 %
    assert 0.9e-3 < drift["tuned"] < 1.1e-3
    # not the integration's: half the step moves it by under 5 % (measured 0.6 %), where an
    # integration error of order 1 or more would fall by half or more
    assert drift["half_step"] == pytest.approx(drift["tuned"], rel=0.05)
    # the contact's: half the time constant more than halves the penetration and the drift,
    # and the drift per metre of penetration stays within a factor 1.5 (measured 1.25)
    assert pen["stiffer"] < 0.6 * pen["tuned"] and drift["stiffer"] < 0.5 * drift["tuned"]
    per = [drift[k] / pen[k] for k in ("tuned", "stiffer")]
    assert max(per) < 1.5 * min(per)
    # and the trade: the stiffer contact turns over more than 2 s later than the tuned one
    assert stiffer["t_invert"] > tuned["t_invert"] + 2.0
