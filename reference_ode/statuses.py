"""How a reference run ends: the kernel's statuses under the tippe top's names, in a sentence."""

from __future__ import annotations

import math

import numpy as np

from tippetop.reference_ode import dop853 as _d
from tippetop.reference_ode.top import Formulation

#: The kernel's statuses under the tippe top's names: the guard is the normal force (contact
#: lost), the monitor the paper formulation's sin theta (its singularity).
STATUS_NAMES = {
    _d.STATUS_OK: "ok",
    _d.STATUS_GUARD: "contact_lost",
    _d.STATUS_MONITOR: "singular",
    _d.STATUS_MAX_STEPS: "max_steps",
    _d.STATUS_STEP_TOO_SMALL: "step_too_small",
}
#: A step-size underflow of the paper formulation with |sin theta| below this is reported as
#: its singularity (``singular``), not as ``step_too_small``.
SINGULAR_UNDERFLOW_SIN = 1e-3


def status_message(status: str, t: float, min_sin: float, form: str) -> str:
    """One sentence on how a run ended in ``status`` at ``t`` (``form``: its formulation)."""
    if status == "ok":
        return "completed"
    if status == "hop":
        return (f"at t = {t:.6g} s the stem's end struck the table and the top left it (a "
                "hop: the point that took the impact carries no load after it); the model "
                "does not follow a flight, so the run stopped there")
    if status == "chatter":
        return (f"by t = {t:.6g} s the contact had switched between the ball and the stem's "
                "end too often (a chatter of ever shorter bounces): the run stopped there")
    if status == "flat_end":
        return (f"at t = {t:.6g} s the stem's flat end came to lie face down on the table "
                f"(|sin theta| = {min_sin:.2e}): its rim contact degenerates there, so the run "
                "stopped")
    if status == "contact_lost":
        return (f"contact lost at t = {t:.6g} s (the normal force reached 0): the model assumes "
                "the sphere stays on the table, so the run stopped there")
    if status == "singular":
        return (f"the paper formulation reached its singularity at theta = 0 or pi "
                f"(|sin theta| = {min_sin:.2e}) at t = {t:.6g} s; use ode.formulation=vector")
    if status == "max_steps":
        return f"stopped at t = {t:.6g} s after the maximum number of steps (ode.max_steps)"
    return (f"step size underflow at t = {t:.6g} s ({form} formulation): the problem is too "
            "stiff or singular for this tolerance")


def kernel_status_name(form: Formulation, status: int, y: np.ndarray) -> str:
    """The tippe top's name of a kernel status; ``y`` is the state where the run stopped."""
    if (status == _d.STATUS_STEP_TOO_SMALL and form.singular
            and abs(math.sin(y[0])) < SINGULAR_UNDERFLOW_SIN):
        return "singular"
    return STATUS_NAMES[status]
