"""The report's friction-law table: each law and MuJoCo mode on the Fig. 3 top, with a note."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from tippetop.compare.measures.summary import describe_ran
from tippetop.compare.measures.verdict import calibrated_native_text
from tippetop.compare.presentation.verdict import run_of
from tippetop.compare.report.markup import Html, esc, fmt_num, html_table
from tippetop.models.numbers import number_text

#: Order of the rows of the friction-law table (runs, ``ENGINE/MODE``), with what each is.
FRICTION_MODES: dict[str, str] = {
    "ode/paper": "reference ODE, modified Coulomb (the paper's eq. 2.12)",
    "ode/coulomb": "reference ODE, exact Coulomb",
    "ode/viscous": "reference ODE, viscous F = -c v_P",
    "ode/coulomb_viscous": "reference ODE, Coulomb + viscous",
    "mujoco/paper": "MuJoCo, the paper's law applied at the contact point",
    "mujoco/native": f"MuJoCo native friction, the calibrated settings "
                     f"({calibrated_native_text()})",
    "mujoco/file": "MuJoCo native friction, the model's own settings",
    "mujoco/native-elliptic": "MuJoCo native friction, elliptic cone",
    "mujoco/native-pyramidal": "MuJoCo native friction, pyramidal cone",
    "mujoco/native-condim4": "MuJoCo native friction + torsional (condim 4)",
    "mujoco/native-condim6": "MuJoCo native friction + torsional + rolling (condim 6)",
}
#: The scene whose runs fill the friction-law table.
FRICTION_SCENE = "fig3"
#: Why a run departs from the paper's law (used when its numbers depart), and why it agrees.
_WHY_DEPART: dict[str, str] = {
    "ode/coulomb": "exact Coulomb has no smoothing at v_P = 0, so the slip dies out, the top "
                   "sticks into rolling and the sliding friction that lifts it vanishes",
    "ode/viscous": "viscous friction has the paper's slope at v_P = 0 (c = mu M g / Lambda) "
                   "but does not saturate at mu N, so it is stronger at large slip and lifts "
                   "the top faster; it still vanishes with v_P, so the final state is the "
                   "paper's (its Sec. 4.4 argument)",
    "ode/coulomb_viscous": "its Coulomb part is discontinuous at v_P = 0 like exact Coulomb, so "
                           "the slip dies out and the top sticks into rolling",
    "mujoco/paper": "the law is the paper's, but MuJoCo's soft contact (penetration, its "
                    "normal force) and the fixed timestep change N and the contact point",
    "mujoco/native": "MuJoCo's own friction is a soft-constraint Coulomb cone whose behaviour "
                     "at small slip is set by solref/impratio, not by Lambda",
    "mujoco/native-elliptic": "MuJoCo's own friction is a soft-constraint Coulomb cone whose "
                              "behaviour at small slip is set by solref/impratio, not by Lambda",
    "mujoco/native-pyramidal": "a soft-constraint Coulomb cone as in native mode, here "
                               "pyramidal (friction depends on the slip direction), whose "
                               "behaviour at small slip is set by solref/impratio, not by "
                               "Lambda",
    "mujoco/native-condim4": "torsional friction adds a torque about the contact normal that "
                             "the paper's model does not have: it brakes the spin and J",
    "mujoco/native-condim6": "torsional and rolling friction add torques the paper's model "
                             "does not have: rolling resistance opposes the motion that lifts "
                             "the top",
}
_WHY_AGREE: dict[str, str] = {
    "ode/coulomb": "exact Coulomb differs from the paper's law only below Lambda",
    "ode/viscous": "viscous friction is continuous and vanishes with v_P like the paper's law, "
                   "so the steady states are the same (the paper's Sec. 4.4 argument) and only "
                   "the rate differs",
    "ode/coulomb_viscous": "the viscous part keeps the law continuous near v_P = 0",
    "mujoco/paper": "the paper's law applied at MuJoCo's contact point",
    "mujoco/native": "MuJoCo's own friction, calibrated against the reference",
    "mujoco/native-elliptic": "MuJoCo's own friction, calibrated against the reference",
    "mujoco/native-pyramidal": "the pyramidal cone's anisotropy is small here",
    "mujoco/native-condim4": "the torsional torque is small against the sliding friction",
    "mujoco/native-condim6": "the torsional and rolling torques are small against the sliding "
                             "friction",
}


def _friction_rows(results: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    rows = [r for r in results.get("cases", []) if r["kind"] == "run"
            and r["scene"] == FRICTION_SCENE and not r.get("set") and run_of(r) in
            FRICTION_MODES and r.get("error") is None]
    seen: dict[str, Mapping[str, Any]] = {}
    for r in rows:
        seen.setdefault(run_of(r), r)
    return [seen[m] for m in FRICTION_MODES if m in seen]


def friction_note(row: Mapping[str, Any], ref: Mapping[str, Any] | None) -> str:
    """One sentence on where and why a friction law or MuJoCo mode departs from the paper's.

    The sentence is built from the row's numbers against the reference row (the paper's law in
    the reference ODE): whether it inverts, when, the final angle, J drift and the energy lost.
    """
    v = row["values"]
    mode = run_of(row)
    if ref is None or row is ref:
        return ("The paper's law in the reference ODE: the row the others are compared with"
                + (f"; it inverts at {number_text(v['t_invert'], 's')}."
                   if v.get("t_invert") is not None
                   else "."))
    rv = ref["values"]
    t, rt = v.get("t_invert"), rv.get("t_invert")
    same_outcome = v.get("outcome") == rv.get("outcome")
    close_time = (t is None and rt is None) or (t is not None and rt is not None
                                                and abs(t / rt - 1) < 0.05)
    j, rj = v.get("J_rel_drift") or 0.0, rv.get("J_rel_drift") or 0.0
    j_bad = j > max(100 * rj, 1e-6)
    agree = same_outcome and close_time and not j_bad
    why = (_WHY_AGREE if agree else _WHY_DEPART).get(mode, "")
    facts = []
    if t is None and rt is not None:
        facts.append(f"it does not invert within {row['params']['t_end_s']:g} s "
                     f"(theta_asymp = {number_text(v['theta_asymp'], 'rad')}, the paper's law "
                     f"inverts at {number_text(rt, 's')})")
    elif t is not None and rt is None:
        facts.append(f"it inverts at {number_text(t, 's')} where the paper's law does not")
    elif t is not None and rt is not None:
        facts.append(f"it inverts at {number_text(t, 's')} against {number_text(rt, 's')} "
                     f"({100 * (t / rt - 1):+.0f} %), theta_asymp "
                     f"{number_text(v['theta_asymp'], 'rad')} against "
                     f"{number_text(rv['theta_asymp'], 'rad')}")
    else:
        facts.append(f"theta_asymp {number_text(v['theta_asymp'], 'rad')} against "
                     f"{number_text(rv['theta_asymp'], 'rad')}")
    e0 = row.get("E0")
    el, rel_ = v.get("energy_lost"), rv.get("energy_lost")
    if el is not None and rel_:
        pct = f" ({number_text(100 * el / e0, '%')} of E0)" if e0 else ""
        facts.append(f"it dissipates {number_text(el * 1e3, 'mJ')}{pct} against "
                     f"{number_text(rel_ * 1e3, 'mJ')}")
    stick, rstick = row.get("slip_small_frac"), ref.get("slip_small_frac")
    if stick is not None and rstick is not None and abs(stick - rstick) > 0.2:
        lead = "the slip dies out: " if stick > 0.8 else ""
        facts.append(f"{lead}|v_P| stays below Lambda/10 in {number_text(100 * stick, '%')} of "
                     f"the samples (paper's law: {number_text(100 * rstick, '%')})")
    if j_bad:
        facts.append(f"Jellett's J drifts by {number_text(j, 'relative')} (paper's law "
                     f"{number_text(rj, 'relative')})")
    head = FRICTION_MODES.get(mode, mode)
    text = f"{head}: {why}; " if why else f"{head}: "
    return text + "; ".join(facts) + "."


def friction_section(results: Mapping[str, Any]) -> str:
    """The friction-law table of the Fig. 3 runs, one note per row."""
    rows = _friction_rows(results)
    parts = ["<h2 id='friction'>Friction laws</h2>",
             f"<p class='note'>The Fig. 3 top ({FRICTION_SCENE}: A/C = 1, a/R = 0.1, theta0 = "
             "0.1, n0 = 100 rad/s, 8 s) under each law and MuJoCo mode. Energy dissipated is "
             "E0 - E_end. The note compares each row with the paper's law in the reference "
             "ODE (first row).</p>"]
    if not rows:
        parts.append("<p>No friction-law runs in these results.</p>")
        return "".join(parts)
    ref = next((r for r in rows if run_of(r) == "ode/paper"), None)
    table_rows = []
    for r in rows:
        v = r["values"]
        inverts = v.get("t_invert") is not None
        table_rows.append((
            run_of(r), Html(f"{esc(FRICTION_MODES[run_of(r)])}<br><small>ran: "
                            f"{esc(describe_ran(r['summary']) if r.get('summary') else '-')}"
                            "</small>"), "yes" if inverts else "no",
            v.get("t_invert"), v.get("theta_asymp"), v.get("outcome"),
            Html(fmt_num(v.get("J_rel_drift"), ".2e")), v.get("energy_lost"),
            Html(esc(friction_note(r, ref)))))
    parts.append(html_table(["run (engine/mode)", "law / contact", "inverts", "t_invert (s)",
                             "theta_asymp (rad)", "outcome", "J drift", "E0 - E_end (J)", "note"],
                            table_rows))
    return "".join(parts)

