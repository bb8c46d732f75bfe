"""Whether a MuJoCo contact can hold the top's ball on the table at the reference's slip.

``validate``'s ``lift`` key. MuJoCo's soft contact turns friction demand beyond mu N into
normal force (:mod:`tippetop.mujoco_runner.contact_lift`): above a slip that grows as the
contact softens and shrinks as mu grows, sliding alone pushes the ball off the table. The
paper's law never does. So a run whose contact lifts the ball below the largest slip the
reference reaches while the ball alone touches the table hops where the reference stays on,
whatever its other settings: that is the mechanism behind the hops on tops with mu = 1.

For each MuJoCo run of the file's top (its own settings, the calibrated ones, the tuned ones)
the lift-off slip of its contact, for a ball of the top's radius and mass, against the
reference's largest slip; with ``scan``, also whether any geom setting over MuJoCo's own
ranges that is as stiff as the paper's law keeps the ball on at that slip
(:func:`tippetop.mujoco_runner.contact_lift.limit_scan`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tippetop.compare.results.lift import LiftResult
from tippetop.compare.results.tune import Tuned, TuneResult
from tippetop.models.numbers import number_text

#: The runs whose contact is probed: MuJoCo's own contact (the paper's law is a callback and
#: lifts nothing).
PROBED_MODES = ("file", "native")


def reference_slip(table: Any, t_stem: float | None) -> tuple[float, float] | None:
    """The reference's largest slip while the ball alone touches, and when: (m/s, s)."""
    if table is None or "vPX" not in table or not len(table):
        return None
    t = table["t"].to_numpy()
    v = np.hypot(table["vPX"].to_numpy(), table["vPY"].to_numpy())
    keep = t < t_stem if t_stem is not None else np.ones_like(t, dtype=bool)
    keep &= np.isfinite(v)
    if not keep.any():
        return None
    i = int(np.argmax(np.where(keep, v, -np.inf)))
    return float(v[i]), float(t[i])


def contact_of(run: dict[str, Any]) -> Any:
    """The contact a run's summary says it ran with, or None if it does not say it all."""
    from tippetop.mujoco_runner.contact_lift import Contact

    keys = ("mu", "cone", "impratio", "solref", "solimp", "timestep_s")
    if any(run.get(k) is None for k in keys) or (run.get("condim") or 3) != 3:
        return None
    solref = tuple(float(x) for x in run["solref"])
    solimp = tuple(float(x) for x in run["solimp"])
    if len(solref) != 2 or len(solimp) != 5:
        return None
    srf = run.get("solreffriction")
    return Contact(float(run["mu"]), str(run["cone"]), float(run["impratio"]),
                   solref, solimp, float(run["timestep_s"]),  # type: ignore[arg-type]
                   None if srf is None else (float(srf[0]), float(srf[1])))


def lift(runs: dict[str, dict[str, Any]], tables: dict[str, Any], top: Any,
         reference: str, tuned: Tuned | None = None, *,
         mu: float | None = None, Lambda_mps: float = 0.01,
         scan: bool = False, agrees: Any = ()) -> LiftResult:
    """The lift-off slip of each MuJoCo run's contact against the reference's slip.

    Args:
        runs: validate's runs (``ENGINE/MODE`` -> summary).
        tables: Their observables (the reference's gives its slip).
        top: The top (its ball's radius, its mass, g).
        reference: The reference run's name.
        tuned: validate's ``tuned`` (its ``settings`` are probed as ``tuned``).
        mu: The paper's law's mu (for the scan; None: no scan).
        Lambda_mps: The paper's law's Lambda (for the scan's stiffness).
        scan: Where a probed run's contact lifts the ball below the reference's slip, also
            scan MuJoCo's ranges of geom settings at that slip.
        agrees: The runs that agree with the reference (no sentence for them: held at a
            slip above its lift-off one the ball would leave, but their top passes through
            such slips without leaving).

    Returns:
        The lift (:class:`LiftResult`): ``reference`` ({slip_mps, t_s}, or None), ``runs``
        (name -> {lift_off_slip_mps, lifts (below the reference's slip), contact}),
        ``sentences`` (one per run that lifts) and, with ``scan`` and a run that lifts,
        ``scan`` ({settings, stiff, stay, limit, closest, closest_lift_mps, sentence}).
    """
    from tippetop.mujoco_runner.contact_lift import Probe, limit_scan

    agreeing = set(agrees or ())

    ref = runs.get(reference) or {}
    slip = reference_slip(tables.get(reference), ref.get("t_stem"))
    by_run: dict[str, dict[str, Any]] = {}
    sentences: list[str] = []
    probed = [(name, r) for name, r in runs.items()
              if name.split("/", 1)[-1] in PROBED_MODES and name.split("/", 1)[0] == "mujoco"]
    if isinstance(tuned, TuneResult):
        probed.append(("tuned", tuned.settings.to_json()))
    for name, r in probed:
        c = contact_of(r)
        if c is None:
            continue
        v = Probe(c, top.R_m, top.M_kg, top.g_mps2).lift_off_slip()
        lifts = slip is not None and v is not None and v < slip[0]
        by_run[name] = {"lift_off_slip_mps": v, "lifts": lifts, "contact": c.label()}
        # the probe holds its slip for 0.1 s, the top's reference passes through it: a run
        # that agrees anyway is not explained by it, and nothing is said of it
        if lifts and name not in agreeing:
            sentences.append(
                f"{name}: its contact pushes the ball off the table above a slip of "
                f"{number_text(v, 'm/s')} (a ball of this top's radius and mass held at that "
                f"slip for 0.1 s: the soft contact turns friction beyond mu N into normal "
                f"force); the "
                f"reference slips at up to {number_text(slip[0], 'm/s')} (at "
                f"{number_text(slip[1], 's')}) before its stem lands")
    scanned = None
    if scan and slip is not None and mu is not None and any(
            r["lifts"] for r in by_run.values()):
        dt = min([float(r.get("timestep_s") or 2e-4) for _, r in probed] or [2e-4])
        res = limit_scan(float(mu), top.R_m, top.M_kg, Lambda_mps, slip[0], timestep_s=dt,
                         g_mps2=top.g_mps2)
        scanned = {"settings": res.settings, "stiff": res.stiff, "stay": len(res.stay),
                    "limit": res.limit,
                    "closest": res.closest.label() if res.closest else None,
                    "closest_lift_mps": res.closest_lift_mps,
                    "sentence": scan_sentence(res)}
    return LiftResult(None if slip is None else {"slip_mps": slip[0], "t_s": slip[1]},
                      by_run, tuple(sentences), scanned)


def scan_sentence(res: Any) -> str:
    """One sentence: whether MuJoCo's geom settings can both follow the law and stay on."""
    ranges = ("cone, impratio 0.02-1000, solref time constant 2 dt-20 ms, damping ratio 1 and "
              "4, solimp d0 1e-4-0.99")
    head = (f"of {res.settings} geom settings over MuJoCo's ranges ({ranges}) at mu = "
            f"{number_text(res.mu)}, {res.stiff} make friction as stiff as the paper's law "
            f"(half of mu N within 2x its {number_text(res.law_half_slip_mps, 'm/s')})")
    v = number_text(res.slip_mps, "m/s")
    if res.stiff == 0:
        return head
    if res.limit:
        best = ("never" if res.closest_lift_mps is None or math.isinf(res.closest_lift_mps)
                else f"above {number_text(res.closest_lift_mps, 'm/s')}")
        return (f"{head}, and every one of them pushes the ball off the table at the "
                f"reference's slip of {v} (the one that holds out longest lifts it {best}: "
                f"{res.closest.label()}): no geom setting can follow the reference here")
    return (f"{head}; {len(res.stay)} of them keep the ball on the table at the reference's "
            f"slip of {v} (for one: {res.stay[0].label()})")


__all__ = ["contact_of", "lift", "reference_slip", "scan_sentence"]
