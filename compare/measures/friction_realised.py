"""The friction law as an engine realises it, measured from its table (issue 22).

From the friction force at the contact (``FX``, ``FY``), the normal force ``N`` and the slip
(``vPX``, ``vPY``) of every sample that touches and slips: the effective coefficient
mu_eff = |F_t| / N against the slip speed |v_P|, the angle between F_t and -v_P, the creep
(samples whose |F_t| is below the law's value at their slip), and a least-squares fit of the
paper's modified Coulomb law mu |v| / sqrt(|v|^2 + Lambda^2) to what the engine realised. For
the reference and MuJoCo's paper mode the fit gives back the law's own mu and Lambda; for
MuJoCo's own friction it is a measurement.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from tippetop.models.numbers import MISSING, number_text

#: Slip speeds below this are not slipping for the fit and the angle (m/s): the direction of
#: a slip of 1e-9 m/s is round-off.
MIN_SLIP_MPS = 1e-9
#: A sample creeps when its |F_t| is below the law's value by more than this fraction.
CREEP_MARGIN = 0.01
#: A sample is on the law's plateau at this many Lambda of slip: there the law
#: mu v / sqrt(v^2 + Lambda^2) is 95 % of mu (v / Lambda = 0.95 / sqrt(1 - 0.95^2)).
PLATEAU_SLIP = 0.95 / math.sqrt(1.0 - 0.95**2)
#: Fewer usable samples than this: nothing is measured (the keys say None).
MIN_SAMPLES = 20


def law_mu(v: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """The paper's modified Coulomb law as a coefficient: mu v / sqrt(v^2 + Lambda^2)."""
    return mu * v / np.sqrt(v * v + lam * lam)


def samples(table: pd.DataFrame) -> pd.DataFrame:
    """The samples that touch and slip: slip speed, mu_eff, the angle to -v_P, and N."""
    cols = ("FX", "FY", "vPX", "vPY", "N")
    if table is None or not all(c in table for c in cols):
        return pd.DataFrame({"slip": [], "mu_eff": [], "angle": [], "N": []})
    t = table[list(cols)].to_numpy(dtype=float)
    FX, FY, vX, vY, N = t.T
    F, v = np.hypot(FX, FY), np.hypot(vX, vY)
    ok = np.isfinite(F) & np.isfinite(v) & np.isfinite(N) & (N > 0) & (v > MIN_SLIP_MPS)
    # the angle between F_t and -v_P, from its sine and cosine (accurate near 0)
    angle = np.arctan2(np.abs(FX * vY - FY * vX), -(FX * vX + FY * vY))
    angle = np.where(F > 0, angle, 0.0)
    return pd.DataFrame({"slip": v[ok], "mu_eff": (F / np.where(N > 0, N, 1.0))[ok],
                         "angle": angle[ok], "N": N[ok]})


def fit_law(slip: np.ndarray, mu_eff: np.ndarray, mu0: float,
            lam0: float, weight: np.ndarray | None = None) -> tuple[float, float, float]:
    """(mu, Lambda, residual): the modified Coulomb law fitted to (slip, mu_eff).

    Least squares on the coefficient, both parameters positive (scipy's ``least_squares``,
    Lambda on a log scale, from the law's own values); the residual is the RMS of mu_eff less
    the fitted law. ``weight``: each sample's weight (its normal force: see
    :func:`friction_realised`); None: all alike.
    """
    from scipy.optimize import least_squares

    root = None if weight is None else np.sqrt(np.asarray(weight) / np.mean(weight))

    def resid(x: np.ndarray) -> np.ndarray:
        r = law_mu(slip, x[0], math.exp(x[1])) - mu_eff
        return r if root is None else r * root

    lo = math.log(min(1e-12, lam0 / 10.0)) if lam0 > 0 else math.log(1e-12)
    hi = math.log(max(10.0, 10.0 * lam0))
    x0 = np.array([max(mu0, 1e-6), min(max(math.log(max(lam0, 1e-300)), lo), hi)])
    sol = least_squares(resid, x0, bounds=([0.0, lo], [np.inf, hi]),
                        x_scale=[max(mu0, 1e-3), 1.0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    mu, lam = float(sol.x[0]), float(math.exp(sol.x[1]))
    return mu, lam, float(np.sqrt(np.mean(resid(sol.x) ** 2)))


def _slip_reaching(slip: np.ndarray, mu_eff: np.ndarray, level: float) -> float | None:
    """The slip speed at which the median mu_eff first reaches ``level``; None if never.

    The samples are binned on log slip (40 bins); each bin is the point (its median slip, its
    median mu_eff), and the crossing is interpolated between the two bins around it.
    """
    if not len(slip):
        return None
    edges = np.logspace(math.log10(slip.min()), math.log10(slip.max()) + 1e-12, 41)
    idx = np.clip(np.searchsorted(edges, slip, side="right") - 1, 0, len(edges) - 2)
    points = [(float(np.median(slip[idx == b])), float(np.median(mu_eff[idx == b])))
              for b in range(len(edges) - 1) if np.any(idx == b)]
    for i, (x, y) in enumerate(points):
        if y >= level:
            if i == 0:
                return x
            x0, y0 = points[i - 1]
            f = (level - y0) / (y - y0)
            return float(math.exp(math.log(x0) + f * (math.log(x) - math.log(x0))))
    return None


def _plateau_share(slip: np.ndarray, N: np.ndarray, lam: float) -> float:
    """The share of the normal force in samples slipping at PLATEAU_SLIP Lambda or more."""
    total = float(np.sum(N))
    return float(np.sum(N[slip >= PLATEAU_SLIP * lam]) / total) if total > 0 else 0.0


def friction_realised(table: pd.DataFrame, mu: float, lam: float,
                      t_stem: float | None = None) -> dict[str, Any]:
    """``friction_realised`` of a run: the law the engine realised, against the paper's.

    Args:
        table: The run's forces against its slips: ``t``, ``FX``, ``FY``, ``vPX``, ``vPY``
            and ``N``, the force and the slip in any one horizontal frame (the fit reads
            magnitudes and the angle between them): the observables table, or a MuJoCo run's
            windows (:func:`window_pairs`: each window's mean force against its slip weighted
            as the force).
        mu: The law's mu (the scene's: what the engine was meant to realise).
        lam: The law's Lambda (m/s).
        t_stem: The stem's first contact (s): only the samples before it count, while the
            ball alone touches (after it the force is two points' and the slip one point's).

    Returns:
        ``mu_fit``, ``Lambda_fit_mps`` (each sample weighted by its normal force),
        ``residual`` (RMS of mu_eff less the fitted law, so weighted),
        ``half_mu_slip_mps`` and ``ninety_mu_slip_mps`` (the slip speeds at which the
        median |F_t| reaches half and 90 % of mu_fit N, measured in log-slip bins),
        ``law_half_mu_slip_mps`` (the paper's law's: Lambda / sqrt(3)), ``angle_rms_rad``
        (between F_t and -v_P), ``creep_fraction`` (samples with |F_t| more than
        :data:`CREEP_MARGIN` below the law's mu |v| / sqrt(|v|^2 + Lambda^2) N),
        ``plateau_share`` (the share of the normal force in samples slipping at
        :data:`PLATEAU_SLIP` Lambda_fit or more, where the fitted law is within 5 % of mu_fit:
        how much of the run measures mu itself; under a percent or so, only mu / Lambda is
        measured, and mu_fit and Lambda_fit alone are loose) and ``samples``; every number
        None when fewer than :data:`MIN_SAMPLES` samples slip.
    """
    if t_stem is not None and table is not None and "t" in table:
        table = table[table["t"] < t_stem]
    s = samples(table)
    out: dict[str, Any] = {"samples": int(len(s)), "mu_law": mu, "Lambda_law_mps": lam,
                           "law_half_mu_slip_mps": lam / math.sqrt(3.0),
                           "before_t_s": t_stem}
    keys = ("mu_fit", "Lambda_fit_mps", "residual", "half_mu_slip_mps",
            "ninety_mu_slip_mps", "angle_rms_rad", "creep_fraction", "plateau_share")
    if len(s) < MIN_SAMPLES:
        return {**out, **dict.fromkeys(keys)}
    slip, mu_eff = s["slip"].to_numpy(), s["mu_eff"].to_numpy()
    try:
        # each sample weighs as its normal force: a MuJoCo sample's F and N are its window's
        # means (the impulses over the steps since the sample before), so a window of k steps
        # weighs as its k steps would at every step, where the slip barely moves within it
        mu_fit, lam_fit, residual = fit_law(slip, mu_eff, mu, lam, weight=s["N"].to_numpy())
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return {**out, **dict.fromkeys(keys), "fit_error": str(exc)}
    law = law_mu(slip, mu, lam)
    out.update(mu_fit=mu_fit, Lambda_fit_mps=lam_fit, residual=residual,
               half_mu_slip_mps=_slip_reaching(slip, mu_eff, 0.5 * mu_fit),
               ninety_mu_slip_mps=_slip_reaching(slip, mu_eff, 0.9 * mu_fit),
               angle_rms_rad=float(np.sqrt(np.mean(s["angle"].to_numpy() ** 2))),
               creep_fraction=float(np.mean(mu_eff < (1.0 - CREEP_MARGIN) * law)),
               plateau_share=_plateau_share(slip, s["N"].to_numpy(), lam_fit))
    return out


def window_pairs(t: np.ndarray, N: np.ndarray, F: np.ndarray, slip: np.ndarray
                 ) -> pd.DataFrame:
    """A MuJoCo run's force-slip pairs for :func:`friction_realised`, one per window.

    Args:
        t: The samples' times (s).
        N: Each window's mean normal force (N).
        F: Each window's mean friction force, world frame (n, 2 or 3; N).
        slip: Each window's slip, world frame, weighted as its normal force: the sum of
            N v_P over its steps over the sum of N (n, 2 or 3; m/s). Paired with the mean
            force, a window weighs as its steps would one by one where the law is smooth,
            whatever the sample spacing; the slip at the sample, half a window after the
            force's mean, would turn the force away from it as the slip turns.

    Returns:
        ``t, FX, FY, vPX, vPY, N`` in the world's horizontal frame.
    """
    F, slip = np.asarray(F, dtype=float), np.asarray(slip, dtype=float)
    return pd.DataFrame({"t": np.asarray(t, dtype=float), "FX": F[:, 0], "FY": F[:, 1],
                         "vPX": slip[:, 0], "vPY": slip[:, 1],
                         "N": np.asarray(N, dtype=float)})


def not_refit(reason: str) -> dict[str, Any]:
    """``friction_realised["refit"]`` when no refit ran: every value None, and the reason.

    The refit itself (the reference rerun with the fitted law) is :mod:`.refit`'s.
    """
    return {"t_invert": None, "t_stem": None, "theta_asymp": None, "explains": None,
            "sentence": f"no refit: {reason}"}


def realised_sentence(name: str, fr: dict[str, Any]) -> str:
    """The friction law a run realised (``friction_realised``), four digits and their units.

    The one sentence every command and report says it in: ``NAME: the contact reaches half
    of mu N at a slip of 5.765 mm/s, the paper's law at 5.774 mm/s (fit: mu 0.1, Lambda
    10 mm/s, residual 1.1e-17 of |F_t|/N, RMS; F_t 0.17 rad from -v_P, RMS; creeping 84 % of
    the time)``; with too few slipping samples, how many there were.

    Args:
        name: Who realised it (a mode, ``the run``, ``fig3 native mujoco``).
        fr: The run's ``friction_realised`` (:func:`friction_realised`).
    """
    def mm_s(v: Any) -> str:
        return number_text(1e3 * float(v), "mm/s") if v is not None else MISSING

    if fr.get("mu_fit") is None:
        return (f"{name}: too few slipping samples ({number_text(fr.get('samples') or 0)}) "
                "to measure")
    half = fr.get("half_mu_slip_mps")
    where = (f"reaches half of mu N at a slip of {mm_s(half)}" if half is not None
             else "never reaches half of mu N")
    creep = fr.get("creep_fraction")
    return (f"{name}: the contact {where}, the paper's law at "
            f"{mm_s(fr.get('law_half_mu_slip_mps'))} (fit: mu {number_text(fr['mu_fit'])}, "
            f"Lambda {mm_s(fr.get('Lambda_fit_mps'))}, residual "
            f"{number_text(fr.get('residual'), 'relative')} of |F_t|/N, RMS; F_t "
            f"{number_text(fr.get('angle_rms_rad'), 'rad')} from -v_P, RMS; creeping "
            f"{number_text(100 * float(creep or 0.0))} % of the time)")


#: The realised-law sentence's terms, for a person reading it on a terminal.
SENTENCE_TERMS = (
    "half of mu N at a slip of: how fast the contact must slip before friction reaches half "
    "its full mu N (the paper's law: Lambda / sqrt(3)); fit: the paper's law fitted to the "
    "forces; residual: what the fit leaves, as a fraction of |F_t|/N; F_t ... rad from -v_P: "
    "how far the friction force turns away from straight against the slip (0 for the paper's "
    "law, and for Coulomb's); creeping: the share of samples whose force is more than 1 % "
    "below the paper's law at the same slip")

__all__ = ["CREEP_MARGIN", "MIN_SAMPLES", "MIN_SLIP_MPS", "SENTENCE_TERMS", "fit_law",
           "friction_realised", "law_mu", "not_refit", "realised_sentence", "samples",
           "window_pairs"]
