"""What the calibration minimises: candidates, scenes, the residual of a run and the objective.

The objective and its weights are explained in docs/design.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import pandas as pd

from tippetop.compare.measures.series import classify_outcome, theta_asymp
from tippetop.compare.running.runner import TaskResult
from tippetop.models.calibrated import CALIBRATION_MU
from tippetop.models.errors import TippetopError
from tippetop.models.scene import Override, load_scene

#: Objective weights (see the module docstring).
W_T = 0.2  # rad per second of inversion-time error
W_J = 0.5  # rad per decade of Jellett drift above J_MAX
J_MAX = 1e-4
FAIL_COST = 10.0  # rad, a failed run
GRID_DT_S = 0.01  # s, the grid theta(t) is compared on
#: Fixed parts of solref and solimp during the search.
DAMPRATIO = 1.0
SOLIMP_TAIL = (0.95, 0.001, 0.5, 2.0)


def _round_sig(x: float, digits: int = 3) -> float:
    """``x`` rounded to ``digits`` significant digits."""
    if x == 0 or not math.isfinite(x):
        return x
    return float(f"{x:.{digits - 1}e}")


@dataclass(frozen=True)
class Candidate:
    """One set of native contact settings.

    Attributes:
        cone: ``pyramidal`` or ``elliptic``.
        impratio: Frictional-to-normal impedance ratio.
        timeconst_s: solref time constant (s).
        d0: solimp d0 (impedance at zero penetration).
        mu: Sliding friction coefficient.
        dampratio: solref damping ratio.
        solimp_tail: solimp (dmax, width m, midpoint, power).
        solref_direct: A direct (negative) solref, (-stiffness, -damping), in place of the
            time constant and damping ratio; None: those.
        frictiondamping: The friction rows' own damping b: solreffriction (-1, -b) on contact
            pairs (an elliptic cone only); None: the friction rows use solref.
    """

    cone: str
    impratio: float
    timeconst_s: float
    d0: float
    mu: float
    dampratio: float = DAMPRATIO
    solimp_tail: tuple[float, float, float, float] = SOLIMP_TAIL
    solref_direct: tuple[float, float] | None = None
    frictiondamping: float | None = None

    def rounded(self) -> Candidate:
        """The same candidate with its continuous settings at 3 significant digits."""
        return replace(self, impratio=_round_sig(self.impratio),
                       timeconst_s=_round_sig(self.timeconst_s), d0=_round_sig(self.d0),
                       mu=_round_sig(self.mu),
                       frictiondamping=None if self.frictiondamping is None
                       else _round_sig(self.frictiondamping))

    @property
    def solref(self) -> list[float]:
        """MuJoCo solref (time constant s, damping ratio), or the direct one."""
        if self.solref_direct is not None:
            return [float(v) for v in self.solref_direct]
        return [self.timeconst_s, self.dampratio]

    @property
    def solreffriction(self) -> list[float] | None:
        """MuJoCo solreffriction (-1, -damping) of the contact pairs, or None."""
        return None if self.frictiondamping is None else [-1.0, -self.frictiondamping]

    @property
    def solimp(self) -> list[float]:
        """MuJoCo solimp (d0, dmax, width m, midpoint, power)."""
        return [self.d0, *self.solimp_tail]

    def overrides(self, timestep_s: float, integrator: str) -> tuple[Override, ...]:
        """The overrides that select exactly these settings (nothing left to defaults)."""
        out = (Override.of("mujoco.friction", "native"), Override.of("mujoco.cone", self.cone),
               Override.of("mujoco.impratio", self.impratio), Override.of("mujoco.mu", self.mu),
               Override.of("mujoco.solref", self.solref),
               Override.of("mujoco.solimp", self.solimp),
               Override.of("mujoco.timestep_s", timestep_s),
               Override.of("mujoco.integrator", integrator))
        if self.solreffriction is not None:
            out += (Override.of("mujoco.solreffriction", self.solreffriction),)
        return out

    def label(self) -> str:
        """A short human-readable form."""
        ref = ", ".join(f"{v:g}" for v in self.solref)
        text = f"{self.cone} impratio={self.impratio:g} solref=[{ref}]"
        if self.solimp_tail[0] == self.d0:
            text += f" solimp d0=dmax={self.d0:g}"
        else:
            text += f" d0={self.d0:g}"
        text += f" mu={self.mu:g}"
        if self.solreffriction is not None:
            text += f" solreffriction=[-1, {-self.frictiondamping:g}] (pairs)"
        return text


#: A model with one geom and nothing set: everything in it is MuJoCo's default.
_BARE_MJCF = '<mujoco><worldbody><geom size="1"/></worldbody></mujoco>'


@lru_cache(maxsize=8)
def mujoco_defaults(mu: float = CALIBRATION_MU) -> Candidate:
    """MuJoCo's own contact settings, read from a freshly compiled model, at friction ``mu``.

    The cone and ``impratio`` are the compiled model's ``opt`` (MuJoCo's default cone is
    pyramidal); ``solref`` (time constant, damping ratio) and ``solimp`` (d0 and its tail) are
    those of its one geom, to which nothing was set. Nothing is written down here: a MuJoCo
    with other defaults gives other values.

    The friction coefficient is not MuJoCo's (its default sliding friction is 1): the
    calibration compares every candidate with the reference at the paper's mu
    (:data:`models.calibrated.CALIBRATION_MU` = 0.1), and so are MuJoCo's defaults compared.

    Args:
        mu: Sliding friction coefficient; the paper's 0.1 by default.

    Returns:
        The defaults as a :class:`Candidate`.
    """
    import mujoco  # lazily: building the parser must not import MuJoCo

    model = mujoco.MjModel.from_xml_string(_BARE_MJCF)
    cone = mujoco.mjtCone(int(model.opt.cone)).name.removeprefix("mjCONE_").lower()
    solref = [float(x) for x in model.geom_solref[0]]
    solimp = [float(x) for x in model.geom_solimp[0]]
    return Candidate(cone=cone, impratio=float(model.opt.impratio), timeconst_s=solref[0],
                     d0=solimp[0], mu=float(mu), dampratio=solref[1],
                     solimp_tail=(solimp[1], solimp[2], solimp[3], solimp[4]))


def standard_seeds(mu: float = CALIBRATION_MU) -> list[Candidate]:
    """Where a sysid fit starts (:mod:`.identify`).

    The shipped calibrated settings, if any, with their mu scaled to ``mu`` as the paper's 0.1
    is, then MuJoCo's defaults at ``mu`` in both cones (:func:`mujoco_defaults`).
    """
    from tippetop.models.calibrated import calibrated_native_settings

    out = []
    cal = calibrated_native_settings()
    if cal:
        out.append(Candidate(cal["cone"], float(cal["impratio"]), float(cal["solref"][0]),
                             float(cal["solimp"][0]), mu * float(cal["mu"]) / CALIBRATION_MU))
    d = mujoco_defaults(mu)
    return [*out, d, replace(d, cone="elliptic" if d.cone == "pyramidal" else "pyramidal")]


def mujoco_defaults_label(mu: float = CALIBRATION_MU) -> str:
    """What :func:`mujoco_defaults` is, in words, with the MuJoCo version it was read from."""
    import mujoco

    d = mujoco_defaults(mu)
    tail = ", ".join(f"{x:g}" for x in d.solimp_tail)
    mu_note = "mu is the paper's" if mu == CALIBRATION_MU else "mu as given"
    return (f"{d.label()} solimp tail=[{tail}] (read from MuJoCo {mujoco.__version__}; "
            f"{mu_note})")


def __getattr__(name: str) -> Candidate:
    """``MUJOCO_DEFAULTS``: :func:`mujoco_defaults` at the paper's mu, read from MuJoCo."""
    if name == "MUJOCO_DEFAULTS":
        return mujoco_defaults()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True)
class SceneSpec:
    """A scene (a catalogue name or a scene file's path) and the horizon it is compared over."""

    name: str
    t_end_s: float

    def overrides(self) -> tuple[Override, ...]:
        """The horizon override."""
        return (Override.of("run.t_end_s", self.t_end_s),)

    def text(self) -> str:
        """``NAME:T_END_S``."""
        return f"{self.name}:{self.t_end_s:g}"


def parse_scene_list(text: str, option: str) -> list[SceneSpec]:
    """Parse ``fig3:6,fig11_n070`` (a missing horizon means the scene's own ``run.t_end_s``).

    A name is a catalogue scene or a scene file (``my_top.toml:6``).

    Raises:
        TippetopError: An unknown scene, a bad horizon, a repeated or an empty list.
    """
    out: list[SceneSpec] = []
    for item in (p.strip() for p in text.split(",")):
        if not item:
            continue
        name, _, horizon = item.partition(":")
        scene = load_scene(name.strip())  # unknown names fail here with the catalogue listed
        if horizon:
            try:
                t_end = float(horizon)
            except ValueError:
                t_end = math.nan
            if not (math.isfinite(t_end) and t_end > 0):
                raise TippetopError(f"{option}: expected NAME or NAME:T_END_S with T_END_S > 0, "
                                    f"got {item!r}")
        else:
            t_end = scene.run.t_end_s
        # the name as given: a scene file's path loads again in the workers
        out.append(SceneSpec(name.strip(), t_end))
    if not out:
        raise TippetopError(f"{option}: expected a comma-separated list of scenes, got {text!r}")
    names = [s.name for s in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise TippetopError(f"{option}: expected each scene once, got {', '.join(dup)} twice")
    return out


@dataclass
class Residual:
    """How one MuJoCo run differs from the reference on one scene.

    Attributes:
        scene: Scene name.
        t_end_s: Horizon (s).
        rms_rad: RMS of theta_mujoco - theta_ode over the run (rad).
        t_invert_ode: First time theta > pi/2 in the reference (s), None if never.
        t_invert_mujoco: The same in MuJoCo (s), None if never.
        t_invert_err_s: t_invert_mujoco - t_invert_ode (s) when both turn over, else None.
        t_invert_penalty_s: The inversion-time error the objective uses (s).
        theta_asymp_ode: Mean theta over the last 10 % of the reference run (rad).
        theta_asymp_mujoco: The same in MuJoCo (rad).
        theta_asymp_err: theta_asymp_mujoco - theta_asymp_ode (rad).
        outcome_ode: ``upright``, ``intermediate``, ``inverted`` or ``inconclusive``.
        outcome_mujoco: The same in MuJoCo.
        outcome_match: Whether the two outcomes agree.
        J_rel_drift: MuJoCo's max |J/J0 - 1| over the run.
        cost: rms_rad + W_T * t_invert_penalty_s (rad), or FAIL_COST for a failed run.
        error: The failure message of a failed MuJoCo run, else "".
    """

    scene: str
    t_end_s: float
    rms_rad: float
    t_invert_ode: float | None
    t_invert_mujoco: float | None
    t_invert_err_s: float | None
    t_invert_penalty_s: float
    theta_asymp_ode: float
    theta_asymp_mujoco: float
    theta_asymp_err: float
    outcome_ode: str
    outcome_mujoco: str
    outcome_match: bool
    J_rel_drift: float
    cost: float
    error: str = ""


def _theta_on_grid(table: pd.DataFrame, t_end_s: float) -> np.ndarray:
    grid = np.arange(0.0, t_end_s + 0.5 * GRID_DT_S, GRID_DT_S)
    grid = grid[grid <= t_end_s + 1e-12]
    return np.interp(grid, table["t"].to_numpy(), table["theta"].to_numpy())


def residual(spec: SceneSpec, ode: TaskResult, mj: TaskResult) -> Residual:
    """Compare a MuJoCo run with the reference run of the same scene (see the objective)."""
    if ode.error or ode.table is None or ode.summary is None:
        raise TippetopError(f"calibrate: the reference run of {spec.name} failed: {ode.error}")
    ode_asymp = theta_asymp(ode.table)
    ode_outcome = classify_outcome(ode.table)
    t_ode = ode.summary.get("t_invert")
    if mj.error or mj.table is None or mj.summary is None:
        return Residual(spec.name, spec.t_end_s, math.nan, t_ode, None, None, math.nan,
                        ode_asymp, math.nan, math.nan, ode_outcome, "failed", False, math.nan,
                        FAIL_COST, error=mj.error or "no result")
    th_ode = _theta_on_grid(ode.table, spec.t_end_s)
    th_mj = _theta_on_grid(mj.table, spec.t_end_s)
    rms = float(np.sqrt(np.mean((th_mj - th_ode) ** 2)))
    t_mj = mj.summary.get("t_invert")
    if t_ode is not None and t_mj is not None:
        err: float | None = float(t_mj - t_ode)
        penalty = abs(err)
    elif t_ode is None and t_mj is None:
        err, penalty = None, 0.0
    else:
        err = None
        penalty = spec.t_end_s - float(t_ode if t_ode is not None else t_mj)
    mj_asymp = theta_asymp(mj.table)
    mj_outcome = classify_outcome(mj.table)
    return Residual(
        scene=spec.name, t_end_s=spec.t_end_s, rms_rad=rms, t_invert_ode=t_ode,
        t_invert_mujoco=t_mj, t_invert_err_s=err, t_invert_penalty_s=float(penalty),
        theta_asymp_ode=ode_asymp, theta_asymp_mujoco=mj_asymp,
        theta_asymp_err=mj_asymp - ode_asymp, outcome_ode=ode_outcome,
        outcome_mujoco=mj_outcome, outcome_match=mj_outcome == ode_outcome,
        J_rel_drift=float(mj.summary["J_rel_drift"]), cost=rms + W_T * penalty)


def objective(residuals: Sequence[Residual]) -> float:
    """The calibration objective (rad) of one candidate's residuals (see the module docstring)."""
    cost = float(np.mean([r.cost for r in residuals]))
    drifts = [r.J_rel_drift for r in residuals if math.isfinite(r.J_rel_drift)]
    worst = max(drifts, default=0.0)
    if worst > J_MAX:
        cost += W_J * math.log10(worst / J_MAX)
    return cost
