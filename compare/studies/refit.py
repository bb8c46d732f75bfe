"""Does the realised law explain the trajectory? The reference rerun with the fitted law.

An engine's own friction realises some law at the contact (:mod:`.friction_realised` fits
the paper's mu |v| / sqrt(|v|^2 + Lambda^2) to it). Running the reference with that fitted
(mu, Lambda) and everything else the same asks whether the friction law is the whole
difference: if the refit reference reproduces the engine's inversion time, first stem contact
and final tilt within the nightly's tolerances, the difference from the reference is the
friction law, and it is now quantified; if not, something else remains (the soft contact's
sink, the integration) and :func:`refit_result` says what, with numbers.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pandas as pd

from tippetop.compare.measures.friction_realised import not_refit
from tippetop.compare.measures.series import first_inversion_time, theta_asymp
from tippetop.compare.measures.tolerances import TOLERANCES
from tippetop.models.numbers import number_text
from tippetop.models.scene import Override

#: The nightly's tolerances the refit's events are held to: t_invert and t_stem within
#: ``TOLERANCES["t_invert"]`` (0.1 s), theta_asymp within ``TOLERANCES["theta_asymp"]``.
T_TOL_S = TOLERANCES["t_invert"].value
THETA_TOL_RAD = TOLERANCES["theta_asymp"].value


def refit_overrides(fr: dict[str, Any]) -> tuple[Override, ...] | None:
    """The overrides that run the reference with the fitted law; None without a fit."""
    mu, lam = fr.get("mu_fit"), fr.get("Lambda_fit_mps")
    if mu is None or lam is None or not (mu > 0 and lam > 0):
        return None
    return (Override.of("friction.law", "modified_coulomb"), Override.of("friction.mu", mu),
            Override.of("friction.Lambda_mps", lam))


def events(summary: dict[str, Any], table: pd.DataFrame | None) -> dict[str, float | None]:
    """t_invert, t_stem (s) and theta_asymp (rad) of a run, from its summary and table."""
    t_inv = summary.get("t_invert")
    if t_inv is None and table is not None and len(table):
        t_inv = first_inversion_time(table)
    return {"t_invert": t_inv, "t_stem": summary.get("t_stem"),
            "theta_asymp": (theta_asymp(table) if table is not None and len(table) > 2
                            else None)}


def _diff(a: float | None, b: float | None, tol: float) -> tuple[float | None, bool]:
    if a is None and b is None:
        return None, True
    if a is None or b is None:
        return None, False
    return a - b, abs(a - b) <= tol


def refit_result(fr: dict[str, Any], engine: dict[str, float | None],
                 reference: dict[str, float | None], refit: dict[str, float | None],
                 ran: dict[str, Any]) -> dict[str, Any]:
    """``friction_realised.refit``: the refit reference against the engine's run.

    Args:
        fr: The engine run's ``friction_realised`` (its mu_fit, Lambda_fit_mps).
        engine: The engine run's :func:`events`.
        reference: The reference's events with the scene's own law.
        refit: The reference's events with the fitted law.
        ran: The engine run's summary (its timestep, integrator, sink and Jellett drift name
            what remains).

    Returns:
        ``t_invert``, ``t_stem``, ``theta_asymp`` (the refit reference's), ``explains`` (all
        three within the nightly's tolerances of the engine's), ``mu``, ``Lambda_mps`` (the
        law it ran), ``engine`` and ``reference`` (their events), ``differences`` (refit less
        engine, per event), ``held`` (the events ``explains`` holds: theta_asymp only when
        no stem touches, since the law is fitted on the ball's phase),
        ``explained_fraction`` (of the engine's t_invert difference from the reference, the
        share the fitted law reproduces; None without one), ``tolerances``, ``sentence``
        (what it means, with numbers, under 300 characters) and ``remains`` (when it does
        not explain: what else differs between the engine and the reference, each with its
        number: the contact's sink, Jellett's drift, which a torque off the contact point
        or a first-order integrator on a top with A != C makes, the integration).
    """
    tols = {"t_invert": T_TOL_S, "t_stem": T_TOL_S, "theta_asymp": THETA_TOL_RAD}
    diffs, ok = {}, {}
    for key, tol in tols.items():
        diffs[key], ok[key] = _diff(refit.get(key), engine.get(key), tol)
    # the law is fitted on the ball's phase: once the stem touches, the final tilt is the
    # stem's contact's (another point, another model), which the fit says nothing about
    on_stem = engine.get("t_stem") is not None or refit.get("t_stem") is not None
    held = [k for k in tols if not (on_stem and k == "theta_asymp")]
    explains = all(ok[k] for k in held)
    ok = {k: ok[k] for k in held}
    frac = None
    e, r, f = engine.get("t_invert"), reference.get("t_invert"), refit.get("t_invert")
    if e is not None and r is not None and f is not None and abs(e - r) > T_TOL_S:
        frac = 1.0 - abs(e - f) / abs(e - r)
    law = (f"the reference with the realised law (mu {number_text(fr['mu_fit'])}, Lambda "
           f"{number_text(1e3 * fr['Lambda_fit_mps'], 'mm/s')})")

    def when(ev: dict[str, float | None]) -> str:
        t = ev.get("t_invert")
        return "does not turn over" if t is None else f"turns over at {number_text(t, 's')}"

    if explains:
        sentence = (f"{law} {when(refit)}, the engine {when(engine)}: the friction law "
                    f"explains the run (the reference with the scene's law "
                    f"{when(reference)})")
    else:
        misses = [k for k, v in ok.items() if not v]
        remains = []
        sink = ran.get("max_penetration_m")
        if sink is not None:
            remains.append(f"the contact's sink (up to {number_text(1e3 * sink, 'mm')})")
        j = ran.get("J_rel_drift")
        if j is not None:
            remains.append(f"Jellett's drift ({number_text(j, 'relative')} relative)")
        if ran.get("integrator") and ran.get("timestep_s"):
            remains.append(f"the integration ({ran['integrator']} at dt = "
                           f"{number_text(ran['timestep_s'], 's')})")
        share = ("" if frac is None else
                 f"; it accounts for {number_text(100 * max(frac, 0.0))} % of the "
                 f"engine's {number_text(abs(e - r), 's')} from the reference's inversion")
        sentence = (f"{law} {when(refit)}, the engine {when(engine)}: the law does not "
                    f"explain it ({', '.join(misses)} beyond tolerance{share})")
    return {"t_invert": refit.get("t_invert"), "t_stem": refit.get("t_stem"),
            "theta_asymp": refit.get("theta_asymp"), "explains": explains,
            "mu": fr.get("mu_fit"), "Lambda_mps": fr.get("Lambda_fit_mps"),
            "engine": dict(engine), "reference": dict(reference), "differences": diffs,
            "explained_fraction": frac, "held": held,
            "remains": [] if explains else (remains or ["not measured"]),
            "tolerances": {"t_invert_s": T_TOL_S, "t_stem_s": T_TOL_S,
                           "theta_asymp_rad": THETA_TOL_RAD},
            "sentence": sentence}


def attach_refits(runs: dict[str, dict[str, Any]], tables: dict[str, pd.DataFrame],
                  ref_key: str, task_for: Callable[[tuple[str, ...]], Any],
                  run_options: dict[str, Any]) -> None:
    """Set each run's ``friction_realised["refit"]``: the reference rerun with its law.

    Args:
        runs: Run key -> summary (with ``friction_realised``); the reference among them.
        tables: Run key -> observables.
        ref_key: The reference's key.
        task_for: The reference's task with these overrides added (the fitted law).
        run_options: Keyword arguments of :func:`run_tasks` (the refits run together, cached
            as every run).

    A law fitted equal to the reference's (paper mode: mu and Lambda to 1e-6) is the
    reference's own run, not run again.
    """
    from tippetop.compare.running.runner import run_tasks

    ref = runs.get(ref_key) or {}
    if ref.get("theta_final") is None or ref_key not in tables:
        for key, r in runs.items():
            if key != ref_key and r.get("friction_realised"):
                r["friction_realised"]["refit"] = not_refit("the reference run failed")
        return
    ref_events = events(ref, tables[ref_key])
    law = ref.get("friction_realised") or {}
    todo: list[tuple[str, Any]] = []
    for key, r in runs.items():
        fr = r.get("friction_realised")
        if key == ref_key or not fr:
            continue
        ov = refit_overrides(fr)
        if ov is None:
            fr["refit"] = not_refit(f"no law fitted ({fr.get('samples', 0)} slipping "
                                    "samples)")
            continue
        same = all(math.isclose(fr[k], law.get(k) or math.nan, rel_tol=1e-6)
                   for k in ("mu_fit", "Lambda_fit_mps"))
        if same:
            fr["refit"] = refit_result(fr, events(r, tables.get(key)), ref_events, ref_events,
                                       r)
        else:
            todo.append((key, task_for(ov)))
    if not todo:
        return
    results = run_tasks([t for _, t in todo], label="refit", **run_options)
    for (key, _task), res in zip(todo, results, strict=True):
        r = runs[key]
        if res.error or res.summary is None or res.table is None:
            r["friction_realised"]["refit"] = not_refit(f"the refit reference failed: "
                                                        f"{res.error}")
            continue
        r["friction_realised"]["refit"] = refit_result(
            r["friction_realised"], events(r, tables.get(key)), ref_events,
            events(res.summary, res.table), r)


__all__ = ["THETA_TOL_RAD", "T_TOL_S", "attach_refits", "events", "not_refit",
           "refit_overrides", "refit_result"]
