"""What ``tippetop plan`` prints: what a run would run and where, without running it."""

from __future__ import annotations

from typing import TYPE_CHECKING

from tippetop.compare.presentation.terminal import fmt, fmt_value, ran_lines

if TYPE_CHECKING:
    from tippetop.models.plan import RunPlan


def print_plan(plan: RunPlan) -> None:
    """A plan for a person: what will run and where, in the lines a run's summary says."""
    said = plan.what_runs()
    rows: list[tuple[str, str]] = [("start", _start(plan))]
    mj = plan.mujoco
    if mj is None:
        print(f"{plan.scene} on engine {plan.engine} (the reference ODE) in mode {plan.mode}: "
              f"{fmt(plan.t_end_s, 's')} simulated, a sample every "
              f"{fmt(plan.ode.sample_dt_s, 's')}")
    else:
        print(f"{plan.scene} on engine {plan.engine} in mode {plan.mode}: "
              f"{fmt(mj.t_end_s, 's')} "
              f"simulated, {fmt(mj.n_steps)} steps of {fmt(mj.timestep_s, 's')}, a sample "
              f"every {fmt(mj.steps_per_sample)} steps ({fmt(mj.n_intervals + 1)} rows)")
        rows.append(("model", "generated from the scene's top" if mj.source is None else
                     f"{mj.source}, with the values here written into its document"))
        for c in mj.contacts:
            rows.append(("contact", f"{c.element} {c.name} ({c.role}): condim {c.condim}, "
                         f"friction {fmt_value('', list(c.friction))}, solref "
                         f"{fmt_value('solref', list(c.solref))}, solimp "
                         f"{fmt_value('solimp', list(c.solimp))}"
                         + (", solreffriction "
                            + fmt_value("solreffriction", list(c.solreffriction))
                            if c.solreffriction else "")
                         + ("" if c.collides else ", collides with nothing")))
        if mj.paper_max_timestep_s is not None:
            rows.append(("law's step", f"at most {fmt(mj.paper_max_timestep_s, 's')} (the "
                         "paper's law relaxes the slip in that time)"))
        rows += [("note", note) for note in mj.notes]
    width = max(max(len(k) for k in [*(k for k, _ in rows), "unused"]),
                max(len(k) + 2 for k in said))
    print("what will run:")
    print("\n".join(ran_lines(said, width)))
    for key, text in rows:
        print(f"{key:<{width}}  {text}")
    print(f"{'unused':<{width}}  {', '.join(plan.unused) or 'none'} (--set keys the engine "
          "would not read)")


def _start(plan: RunPlan) -> str:
    mj = plan.mujoco
    if mj is not None and mj.keyframe is not None:
        return f"keyframe '{mj.keyframe_name}' of the file (index {mj.keyframe})"
    ini = plan.init
    return (f"theta0 {fmt(ini.theta0, 'rad')}, n0 {fmt(ini.n0, 'rad/s')}, thetadot0 "
            f"{fmt(ini.thetadot0, 'rad/s')}, Omega0 {fmt(ini.Omega0, 'rad/s')}, uOX "
            f"{fmt(ini.uOX, 'm/s')}, uOY {fmt(ini.uOY, 'm/s')}")


__all__ = ["print_plan"]
