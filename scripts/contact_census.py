"""What MuJoCo's soft contacts do between the samples: every stretch without contact, measured.

The justification of the flight rule (``compare/measures/series.py``: :data:`HOP_MIN_S` and
:data:`FLIGHT_RISE_M`) and of the fidelity map's causes. For each run it prints the longest
stretch of steps without contact and the ball's rise in it, the highest stretch, how many
last 10 ms or more, how many are flights by the rule, the inversion time, and which checks
of the verdict depart (against the reference from the same start). The runs:

- every point of a fidelity map that departs (default: the docs' map,
  docs/data/fidelity-default.json), with its own tuned settings, from its four starts (the
  fitted one, 1.15 and 0.9 times its spin, and twice its tilt: ``tune.starts_for``);
- the catalogue's scenes in MuJoCo's calibrated native contact;
- the tutorial top (tests/data/tutorial_tippe_top.xml) with its file's own contact.

Each stretch is measured at every step (the stepping adds each step's contact to its sample's
window), whatever the sample spacing.

Run: ``python scripts/contact_census.py [RESULTS.json] [--t-end-s 8]`` (about 5 minutes on 2
cores; the runs go through the run cache).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("fig3", "fig4", "fig6", "fig7a", "fig7b", "fig8a", "fig8b", "fig11_n040",
          "fig11_n070")
TUTORIAL = ROOT / "tests" / "data" / "tutorial_tippe_top.xml"


def _tuned(s: dict[str, Any]) -> tuple[str, ...]:
    return ("mujoco.friction=native", f"mujoco.cone={s['cone']}",
            f"mujoco.impratio={s['impratio']!r}", f"mujoco.mu={s['mu']!r}",
            f"mujoco.solref={json.dumps(s['solref'])}", f"mujoco.solimp={json.dumps(s['solimp'])}",
            f"mujoco.timestep_s={s['timestep_s']!r}", f"mujoco.integrator={s['integrator']}")


def main(argv: list[str]) -> int:
    """Print one line per run and the census's summary."""
    from tippetop.compare.measures.series import FLIGHT_RISE_M, HOP_MIN_S
    from tippetop.compare.measures.verdict import run_entry, verdict
    from tippetop.compare.running.runner import Task, run_tasks
    from tippetop.compare.studies.fidelity import point_overrides
    from tippetop.compare.tuning.tune import starts_for
    from tippetop.models.modes import REFERENCE_RUN, run_label

    p = argparse.ArgumentParser(prog="contact_census.py")
    p.add_argument("results", nargs="?", default=str(ROOT / "docs" / "data"
                                                     / "fidelity-default.json"))
    p.add_argument("--t-end-s", type=float, default=None)
    args = p.parse_args(argv)
    try:
        res = json.loads(Path(args.results).read_text(encoding="utf-8"))
        points = [q for q in res["points"] if not q["agrees"] and q.get("settings")]
        t_end = float(args.t_end_s or res["t_end_s"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"contact_census: expected a fidelity map's results.json, got {args.results} "
              f"({exc.__class__.__name__}: {exc})", file=sys.stderr)
        return 2
    cases: list[tuple[str, Task, Task]] = []
    for q in points:
        for s in starts_for(q["n0"], q["theta0"]):
            base = (*point_overrides(q["A_over_C"], q["a_over_R"], q["mu"], s.n0, s.theta0),
                    f"run.t_end_s={t_end!r}")
            name = (f"A/C {q['A_over_C']:g} a/R {q['a_over_R']:g} mu {q['mu']:g}, "
                    f"{s.label()} ({s.role})")
            cases.append((name, Task(None, base, "ode"),
                          Task(None, (*base, *_tuned(q["settings"])), "mujoco")))
    for scene in SCENES:
        cases.append((f"{scene}, calibrated native", Task(scene, (), "ode"),
                      Task(scene, (), "mujoco", "native")))
    tut = (f"top.mjcf={json.dumps(str(TUTORIAL))}",)
    cases.append(("tutorial top, its own contact", Task(None, tut, "ode"),
                  Task(None, tut, "mujoco", "file")))
    tasks = [t for _, ref, mj in cases for t in (ref, mj)]
    results = run_tasks(tasks, label="census")
    print(f"{'run':<68} {'longest':>8} {'its rise':>9} {'highest':>9} {'>=10ms':>6} "
          f"{'flights':>7} {'t_invert':>8}  departs")
    chatter: list[tuple[float, float]] = []
    flown: list[tuple[float, float]] = []
    for k, (name, _ref, _mj) in enumerate(cases):
        ref, run = results[2 * k], results[2 * k + 1]
        if run.error or ref.error:
            print(f"{name:<68} failed: {run.error or ref.error}")
            continue
        s = run.summary
        fl = s.get("flights") or {}
        gaps = _stretches(run)
        longest = max(gaps, default=(0.0, 0.0))
        highest = max(gaps, key=lambda g: g[1], default=(0.0, 0.0))
        long = [g for g in gaps if g[0] >= HOP_MIN_S * (1 - 1e-9)]
        tuned = run_label("mujoco", s.get("mode") or "native")
        runs = {REFERENCE_RUN: run_entry(ref), tuned: run_entry(run)}
        checks = [c for c in verdict(runs, runs[REFERENCE_RUN].get("outcome"))
                  if c["run"] == tuned and c["passed"] is False]
        flying = name.startswith("tutorial")  # the file's own contact: where flights are
        for dur, rise in gaps:
            if dur >= HOP_MIN_S * (1 - 1e-9) and rise >= FLIGHT_RISE_M:
                flown.append((dur, rise))
            elif not flying:
                chatter.append((dur, rise))
        t_inv = s.get("t_invert")
        print(f"{name:<68} {1e3 * longest[0]:>6.1f}ms {1e6 * longest[1]:>7.2f}um "
              f"{1e6 * highest[1]:>7.2f}um {len(long):>6} {fl.get('hops') or 0:>7} "
              f"{'-' if t_inv is None else f'{t_inv:.3f}':>8}  "
              + (", ".join(c["check"] for c in checks) or "-"))
    print(f"\nthe rule: a flight lasts {1e3 * HOP_MIN_S:g} ms or more and rises "
          f"{1e6 * FLIGHT_RISE_M:g} um or more")
    if chatter:
        longest = max(chatter)
        highest = max(chatter, key=lambda g: g[1])
        over5 = [g for g in chatter if g[0] >= 0.005]
        print(f"tuned and calibrated contacts: {len(chatter):,} stretches without contact; the "
              f"longest {1e3 * longest[0]:.1f} ms (risen {1e6 * longest[1]:.2f} um), the "
              f"highest risen {1e6 * highest[1]:.2f} um (in {1e3 * highest[0]:.1f} ms); those "
              f"of 5 ms or more rose at most "
              f"{1e6 * max((g[1] for g in over5), default=0.0):.2f} um")
    if flown:
        print(f"flights (the tutorial top's own contact): {len(flown)}, "
              f"{1e3 * min(flown)[0]:.1f}-{1e3 * max(flown)[0]:.1f} ms, risen "
              f"{1e6 * min(g[1] for g in flown):.0f}-{1e6 * max(g[1] for g in flown):.0f} um")
    return 0


def _stretches(result: Any) -> list[tuple[float, float]]:
    """(length s, rise m) of the run's stretches without contact, after settling.

    Before the stem lands; from the run stepped again (a cached summary keeps no stretches).
    """
    from tippetop.compare.measures.series import SETTLING_S
    from tippetop.mujoco_runner.run import simulate_plan

    plan = result.task.plan().mujoco
    res = simulate_plan(plan)
    g = res.gaps()
    stem = res.t_stem
    out = []
    for start, dur, rise in zip(g["t_start"], g["duration_s"], g["height_m"], strict=True):
        if start >= SETTLING_S and (stem is None or start < stem):
            out.append((float(dur), float(rise)))
    return out


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except KeyboardInterrupt:
        print("contact_census: interrupted", file=sys.stderr)
        sys.exit(130)
