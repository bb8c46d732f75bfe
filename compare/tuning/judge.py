"""What the tuning verifies and how it judges: its starts, and a verification's verdict.

The starts (the file's own, fitted, and the held-out ones), the smallest run budget that
verifies them, and the verdict over a verification (every start's checks): shared by the
tuning (:mod:`.tune`) and its widening (:mod:`.widen`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from tippetop.compare.measures.summary import FileContacts, paste_block
from tippetop.compare.results.tune import start_label
from tippetop.compare.tuning.calibrate.identify import MAX_ITERS
from tippetop.models.scene import Override

#: Held-out starts, relative to the file's: (spin factor, tilt factor); a tilt at least
#: :data:`MIN_TILT_STEP_RAD` above the file's. Near the file's start, where its settings are
#: meant to hold: a faster spin, a slower one, a larger tilt.
HELD_OUT: tuple[tuple[float, float], ...] = ((1.15, 1.0), (0.9, 1.0), (1.0, 2.0))
MIN_TILT_STEP_RAD = 0.05
#: Starts each verification runs: the file's own and the held-out ones.
N_STARTS = 1 + len(HELD_OUT)
#: How an answer the widening found is named (a tuning's ``chosen``, a tried row's ``what``):
#: this, then what the widening did (``widened: Euler in place of RK4``).
WIDENED = "widened: "


@dataclass(frozen=True)
class TuneStart:
    """A start: spin n0 (rad/s) and tilt theta0 (rad), and whether the fit used it."""

    n0: float
    theta0: float
    role: str  # "fit" or "held-out"

    def overrides(self) -> tuple[Override, ...]:
        """The overrides of this start.

        None for the file's own (its keyframe as it is); a held-out one's spin and tilt
        (from rest otherwise: no precession, no slip).
        """
        if self.role == "fit":
            return ()
        return (Override.of("init.n0", self.n0), Override.of("init.theta0", self.theta0),
                Override.of("init.Omega0", 0.0), Override.of("init.thetadot0", 0.0))

    def label(self) -> str:
        """``n0 = 150 rad/s, theta0 = 0.04 rad`` (:func:`start_label`)."""
        return start_label(self.n0, self.theta0)


@dataclass(frozen=True)
class TuneFile:
    """What the tuning knows of the file besides its start: its own run, its top, the theory.

    Attributes:
        run: The file's own run as validate has it (its settings seed the fit).
        timestep_s: The file's timestep (s).
        integrator: The file's integrator.
        A_over_C: The top's A/C (names a first-order integrator's Jellett drift).
        theory: (n0, theta0, role) -> the theory's theta_s and outcome at that start
            (``fit``: the file's own start, with its precession); None: the reference's
            outcome, no theta_s.
        contacts: The file's contacts, which the blocks to paste name (:func:`mjcf_block`);
            None: a top tippetop generated.
    """

    run: dict[str, Any] | None = None
    timestep_s: float | None = None
    integrator: str | None = None
    A_over_C: float | None = None
    theory: Callable[[float, float, str], tuple[float | None, str]] | None = None
    contacts: FileContacts | None = None


#: A file the tuning knows nothing of besides its start (every field None).
NO_FILE = TuneFile()


@dataclass(frozen=True)
class TuneEffort:
    """How far the tuning's fits go and what its runs run on.

    Only ``max_iters`` can change the answer: the threads and processes do not.

    Attributes:
        max_iters: Levenberg-Marquardt iterations per fit at most.
        threads: Threads of the fit's rollouts (None: every core this process may use); each
            rollout is stepped alone.
        reference_workers: Local worker processes of the reference's runs (None: the run
            options' own; 1: in this process, which then starts none).
    """

    max_iters: int = MAX_ITERS
    threads: int | None = None
    reference_workers: int | None = None


#: The tuning's own effort: :data:`MAX_ITERS` iterations, every core, the runs' processes.
DEFAULT_EFFORT = TuneEffort()


def starts_for(n0: float, theta0: float) -> list[TuneStart]:
    """The file's start (fitted) and the held-out ones (:data:`HELD_OUT`)."""
    out = [TuneStart(n0, theta0, "fit")]
    for f, g in HELD_OUT:
        tilt = theta0 if g == 1.0 else max(g * theta0, theta0 + MIN_TILT_STEP_RAD)
        out.append(TuneStart(n0 * f, tilt, "held-out"))
    return out

def min_budget_runs() -> int:
    """The smallest ``--budget-runs``: one seed scored, then every start verified with it."""
    return 1 + N_STARTS

def widening_step(chosen: str) -> str | None:
    """What the widening did, of an answer it found (``widened: X`` -> ``X``); else None."""
    return chosen.removeprefix(WIDENED) if chosen.startswith(WIDENED) else None


def passes(verified: list[dict[str, Any]]) -> dict[str, int]:
    """``{passes, checks}``: the checks that pass over every start verified, and all of them."""
    checks = [c for v in verified for c in v["checks"]]
    return {"passes": sum(c["passed"] is not False for c in checks), "checks": len(checks)}


def agrees(verified: list[dict[str, Any]]) -> bool:
    """Every start checked passes, and at least one held-out start was checked."""
    checked = [v for v in verified if v["passed"] is not None]
    return (bool(checked) and all(v["passed"] for v in checked)
            and any(v["role"] == "held-out" for v in checked))

def departs(verified: list[dict[str, Any]]) -> list[str]:
    """Each check that departs, over every start: ``CHECK from START (ROLE): NOTE``."""
    return [f"{c['check']} from {TuneStart(v['n0'], v['theta0'], v['role']).label()} "
            f"({v['role']}): {c['note']}"
            for v in verified for c in v["checks"] if c["passed"] is False]

def mjcf_block(ran: dict[str, Any], contacts: FileContacts | None = None) -> str:
    """A tuning's settings as they ran, one MJCF block to paste (:func:`paste_block`).

    Named with the file's geoms (``contacts``, :attr:`TuneFile.contacts`); the tuning's
    candidates set mu, solref and solimp and keep each geom's own condim, torsional and
    rolling friction. ``""`` for a run that recorded no settings.
    """
    return paste_block(ran, contacts, keeps_dims=True)


__all__ = ["DEFAULT_EFFORT", "HELD_OUT", "MIN_TILT_STEP_RAD", "NO_FILE", "N_STARTS", "WIDENED",
           "TuneEffort", "TuneFile", "TuneStart", "agrees", "departs", "min_budget_runs",
           "mjcf_block", "passes", "start_label", "starts_for", "widening_step"]
