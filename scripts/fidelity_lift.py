"""Is it the lift? The tuned contact's lift-off slip at each point of a fidelity map that departs.

Against the reference's largest slip, and beside how close the reference comes to losing
contact.

The lift-off slip is the least slip at which a ball of the point's top (radius, mass), held at
that slip with the tuned settings, leaves the table for 10 ms
(:mod:`tippetop.mujoco_runner.contact_lift`); the reference's slip is its largest while the
ball alone touches (:func:`tippetop.compare.studies.lift.reference_slip`); N/Mg is the
reference's normal force over the weight, before any stem contact. A contact that lifts below
the reference's slip explains a point whose ball leaves the table; one that does not leaves
the cause open. Beside them, from the point's own start: the longest flight and the count of
flights of 10 ms or more of MuJoCo with the tuned settings, and of MuJoCo's paper mode (the
law applied by the harness on its stiff frictionless contact), with both inversion times.

Run: ``python scripts/fidelity_lift.py [RESULTS.json]`` (default: the docs' map,
docs/data/fidelity-default.json; ``tippetop fidelity --out DIR`` writes one). Each point runs
the reference again over the map's horizon (a few seconds a point on 2 cores).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    """Print one line per departing point."""
    from tippetop.compare.running.engines import run_engine
    from tippetop.compare.studies.fidelity import point_overrides
    from tippetop.compare.studies.lift import contact_of, reference_slip
    from tippetop.models.scene import load_scene
    from tippetop.mujoco_runner.contact_lift import Probe

    path = Path(argv[0]) if argv else ROOT / "docs" / "data" / "fidelity-default.json"
    try:
        res = json.loads(path.read_text(encoding="utf-8"))
        points = [p for p in res["points"] if not p["agrees"]]
        t_end = float(res["t_end_s"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"fidelity_lift: expected a fidelity map's results.json, got {path} "
              f"({exc.__class__.__name__}: {exc})", file=sys.stderr)
        return 2
    print(f"{'A/C':>5} {'a/R':>5} {'mu':>4}  {'ref slip m/s':>12}  {'lift-off m/s':>12}  "
          f"{'N/Mg min-max':>12}  {'lifts':>5}  tuned: longest flight, flights >= 10 ms, "
          "t_invert | paper mode: the same")
    for p in points:
        overrides = [*point_overrides(p["A_over_C"], p["a_over_R"], p["mu"], p["n0"],
                                      p["theta0"]), f"run.t_end_s={t_end!r}"]
        scene = load_scene(None, overrides)
        ref = run_engine(scene, "ode", "paper", progress=False)
        stem = ref.summary.get("t_stem")
        slip = reference_slip(ref.table, stem)
        contact = contact_of(p.get("settings") or {})
        top = scene.top
        lift = (Probe(contact, top.R_m, top.M_kg, top.g_mps2).lift_off_slip()
                if contact is not None else None)
        ball = ref.table["t"] < (stem if stem is not None else float("inf"))
        n = ref.table["N"][ball].to_numpy() / (top.M_kg * top.g_mps2)
        lifts = slip is not None and lift is not None and lift < slip[0]
        runs = []
        s = p.get("settings") or {}
        tuned = [f"mujoco.cone={s.get('cone')}", f"mujoco.impratio={s.get('impratio')!r}",
                 f"mujoco.mu={s.get('mu')!r}", f"mujoco.solref={json.dumps(s.get('solref'))}",
                 f"mujoco.solimp={json.dumps(s.get('solimp'))}",
                 f"mujoco.timestep_s={s.get('timestep_s')!r}",
                 f"mujoco.integrator={s.get('integrator')}"]
        for mode, extra in (("native", tuned), ("paper", [])):
            if mode == "native" and contact is None:
                runs.append("-")
                continue
            got = run_engine(load_scene(None, overrides + extra), "mujoco", mode,
                             progress=False).summary
            fl = got.get("flights") or {}
            t_inv = got.get("t_invert")
            runs.append(f"{1e3 * (fl.get('longest_s') or 0.0):.0f} ms, {fl.get('hops') or 0}, "
                        f"{'-' if t_inv is None else f'{t_inv:.3f} s'}")
        print(f"{p['A_over_C']:>5.3g} {p['a_over_R']:>5.3g} {p['mu']:>4.3g}  "
              f"{'-' if slip is None else f'{slip[0]:.3f}':>12}  "
              f"{'none' if lift is None else f'{lift:.3f}':>12}  "
              f"{f'{n.min():.2f}-{n.max():.2f}':>12}  {'yes' if lifts else 'no':>5}  "
              f"{runs[0]} | {runs[1]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
