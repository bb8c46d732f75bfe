"""Contact settings fitted with MuJoCo's own identification, :mod:`mujoco.sysid`.

The machinery of ``tippetop calibrate`` (the paper's tops) and of the tuning of any top
(``tippetop validate MODEL.xml``, ``tippetop calibrate --mjcf FILE``): the reference's theta(t)
at each start is the measurement, MuJoCo's native contact the model, and mu, the solref time
constant, impratio and the solimp d0 (on a log10 scale, within the calibration's bounds) the
parameters of a bounded Levenberg-Marquardt fit (``mujoco.sysid.optimize``, MuJoCo's own
``mujoco.minimize.least_squares``) whose Jacobian columns are rolled out together on every
core (``mujoco.rollout``).

What sysid does not do is done around it (measured, README): the cone is categorical (one fit
per cone); the fit is local on a rough objective (a top's inversion time moves in steps), so
it starts from the best of a few seeds per cone, with a finite-difference step of 0.01 decade
(its default 1.5e-8 sees only the roughness); and the model of each candidate is the harness's
own plan of the start with those settings (:func:`tippetop.compare.running.engines.plan_for`:
geoms or the file's contact pairs, as every run), with a site on the symmetry axis and a
``framezaxis`` sensor added: the sensor's z is cos theta.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from tippetop.compare.tuning.calibrate.scoring import GRID_DT_S, Candidate
from tippetop.models.errors import TippetopError
from tippetop.models.numbers import number_text
from tippetop.models.scene import Override

#: The fitted settings, in the order of the parameter vector.
FITTED = ("mu", "timeconst_s", "impratio", "d0")
#: On a top with a large mu (at least :data:`WIDE_MU`) the fit also varies the solref damping
#: ratio, within :data:`DAMPRATIO_BOUNDS`, and impratio up to :data:`WIDE_IMPRATIO_MAX`
#: (MuJoCo bounds neither): the contact's lift (mujoco_runner/contact_lift.py) grows as mu^2,
#: and a damping ratio of 4 alone moved the tutorial top's inversion from 0.776 s to 1.182 s
#: against the reference's 1.272 s without a hop (issue 30's measurements).
FITTED_WIDE = (*FITTED, "dampratio")
WIDE_MU = 0.5
DAMPRATIO_BOUNDS = (0.5, 4.0)
WIDE_IMPRATIO_MAX = 1000.0
#: The lift-free family (issue 30), tried in the wide fit when neither cone agrees: MuJoCo's
#: contact turns excess friction demand into normal force (mujoco_runner/contact_lift.py),
#: unless the normal row is far softer than the friction rows. That takes a constant minimal
#: impedance (solimp d0 = dmax = mjMINIMP, 1e-4), a direct normal solref, a large impratio,
#: and the friction rows' own damping (solreffriction on contact pairs, elliptic cone). Set
#: by hand (impratio 300, damping 2.6) it follows the reference on the Group II mu = 1 top
#: from its start and three held-out ones (tests/compare/test_lift_free_contact.py); the fit
#: varies impratio and the friction damping, the rest fixed at those values.
LIFT_FREE_FITTED = ("impratio", "frictiondamping")
LIFT_FREE_IMPEDANCE = 1e-4
LIFT_FREE_SOLREF = (-1e5, -632.0)
LIFT_FREE_SOLIMP_TAIL = (LIFT_FREE_IMPEDANCE, 0.1, 0.5, 2.0)
LIFT_FREE_IMPRATIO_BOUNDS = (10.0, WIDE_IMPRATIO_MAX)
FRICTIONDAMPING_BOUNDS = (0.3, 30.0)
#: (impratio, friction damping) seeds: on the Group II top 300 and 2.6 follow, and impratio
#: and the damping trade against each other (100 and 6 invert as 300 and 2.2 do)
LIFT_FREE_SEEDS = ((300.0, 2.6), (100.0, 8.0), (1000.0, 1.0))
#: Finite-difference step of the Jacobian (decades): the objective is rough below ~1e-3
#: decade (a 1-D scan around the optimum is V-shaped and irregular there), so a step of
#: 1e-2 decade sees its slope; the default 1.5e-8 does not.
FD_STEP_DECADES = 1e-2
#: Levenberg-Marquardt iterations per fit at most (each: one rollout per fitted setting and
#: start, together, plus at least one trial point).
MAX_ITERS = 20
#: A fit stops when two iterations together lowered its RMS by less than this fraction: the
#: objective is rough, and past that point its steps creep (on the paper's top 18 more
#: iterations took the RMS from 0.0278 to 0.0221 rad, and the settings verified the same).
STALL_FRACTION = 0.03
#: The damping of MuJoCo's Levenberg-Marquardt (``mujoco.minimize.least_squares``): its own
#: defaults (1e-6, x1.26) spent 40 serial trial rollouts raising the damping on a first step
#: of the paper's top; from 1e-3 in steps of x4 it takes 3 to 5 (measured).
LM_MU_MIN = 1e-3
LM_MU_FACTOR = 4.0
#: The site and sensors the fit adds to each model: the site's z is the symmetry axis k (the
#: framezaxis sensor's z component is cos theta); its x and y axes and its angular velocity
#: (gyro) give Jellett's constant J = L_G . (R e_z - a k) with L_G = (A w_x, A w_y, C w_z)
#: in the site's frame.
SENSOR = "tippetop_axis"
SENSORS = {"z": "mjSENS_FRAMEZAXIS", "x": "mjSENS_FRAMEXAXIS", "y": "mjSENS_FRAMEYAXIS",
           "w": "mjSENS_GYRO"}
#: Weight of Jellett's constant in the residual (rad per unit of relative drift), while the
#: ball alone touches: an RMS drift of 1e-3 weighs as 0.1 rad of theta. A soft contact's
#: drift grows with time, and validate holds its maximum over a longer run to 1e-3: with a
#: weight of 10 the fit on the paper's top kept a drift of 1.2e-3 over 3.5 s for 0.001 rad
#: of theta (measured).
W_JELLETT = 100.0
#: The relative drift counted is clipped here: a top that hops off the table (a stiff contact
#: at a large mu) changes J by orders of magnitude, which would drown theta (a seed on a mu = 1
#: top scored 70 rad); 0.05 weighs 5 rad, more than any theta error.
J_CLIP = 0.05


def require_sysid() -> Any:
    """``mujoco.sysid``, or a one-line error naming the extra to install."""
    try:
        from mujoco import sysid
    except ImportError:  # pragma: no cover - MuJoCo 4 ships it
        sysid = None
    if sysid is None or not hasattr(sysid, "optimize"):
        raise TippetopError("tune: expected MuJoCo's identification (mujoco.sysid: pip install "
                            "'mujoco[sysid]'), got a mujoco without its dependencies")
    return sysid


@dataclass(frozen=True)
class FitStart:
    """One start the fit follows: a scene (or an MJCF top) from one state, over a horizon.

    Attributes:
        label: How it is named in reports (``fig3``, ``n0 = 150 rad/s, theta0 = 0.04 rad``).
        scene: A catalogue name or scene file, or None (the overrides name the MJCF top).
        overrides: ``--set`` strings of the top, its start and the horizon (no contact
            settings: the candidate adds them).
        t_end_s: The horizon compared (s).
    """

    label: str
    scene: str | None
    overrides: tuple[Override, ...]
    t_end_s: float


#: mu may move this factor either way from the top's own: its friction coefficient is the
#: material's, and the contact settings (not a tenfold mu) are what the fit is for.
MU_FACTOR = 2.0


@dataclass
class Bounds:
    """Bounds of the fitted settings (linear values)."""

    values: dict[str, tuple[float, float]]

    @classmethod
    def around(cls, mu: float, timestep_s: float) -> Bounds:
        """The calibration's bounds, mu within :data:`MU_FACTOR` of ``mu``.

        The others are :data:`.fit.BOUNDS`, the time constant at least two timesteps.
        """
        from tippetop.compare.tuning.calibrate.fit import BOUNDS

        out = dict(BOUNDS)
        out["mu"] = (mu / MU_FACTOR, mu * MU_FACTOR)
        out["timeconst_s"] = (max(BOUNDS["timeconst_s"][0], 2.0 * timestep_s),
                              BOUNDS["timeconst_s"][1])
        return cls(out)

    @classmethod
    def wide(cls, mu: float, timestep_s: float) -> Bounds:
        """:meth:`around`, with the damping ratio and impratio up to the wide fit's."""
        out = dict(cls.around(mu, timestep_s).values)
        out["dampratio"] = DAMPRATIO_BOUNDS
        out["impratio"] = (out["impratio"][0], WIDE_IMPRATIO_MAX)
        return cls(out)

    @classmethod
    def lift_free(cls) -> Bounds:
        """The lift-free family's: impratio and the friction rows' damping."""
        return cls({"impratio": LIFT_FREE_IMPRATIO_BOUNDS,
                    "frictiondamping": FRICTIONDAMPING_BOUNDS})

    def clip(self, c: Candidate) -> Candidate:
        """``c`` with every fitted setting inside its bounds."""
        return replace(c, **{k: min(max(getattr(c, k), lo), hi)
                             for k, (lo, hi) in self.values.items()})


def lift_free_seeds(mu: float) -> list[Candidate]:
    """The lift-free family's seeds at friction ``mu`` (:data:`LIFT_FREE_SEEDS`)."""
    return [Candidate("elliptic", imp, 0.02, LIFT_FREE_IMPEDANCE, mu,
                      solimp_tail=LIFT_FREE_SOLIMP_TAIL, solref_direct=LIFT_FREE_SOLREF,
                      frictiondamping=b) for imp, b in LIFT_FREE_SEEDS]


class BudgetSpent(Exception):
    """The fit's rollouts reached :attr:`Problem.budget`: it ends with its best so far."""


class _Stalled(Exception):
    """A fit's RMS stopped falling (:data:`STALL_FRACTION`)."""


@dataclass
class Identified:
    """What :func:`identify` found.

    Attributes:
        best: The settings with the smallest RMS.
        rms_rad: Its RMS of theta less the reference's, over every start's grid (rad).
        per_start_rms_rad: The same per start.
        rollouts: MuJoCo rollouts used (every start of every candidate, Jacobians included).
        seeds: The seeds scored: [{cone, settings, rms_rad}].
        fits: The fits run: [{cone, from, to, rms_rad, rollouts, iterations}].
        wall_s: Wall time (s).
        fit_seeds: The settings each fit started from, in ``fits``' order.
        budget_spent: The rollout budget (:attr:`Problem.budget`) cut the seeds or a fit short.
    """

    best: Candidate
    rms_rad: float
    per_start_rms_rad: list[float]
    rollouts: int
    seeds: list[dict[str, Any]] = field(default_factory=list)
    fits: list[dict[str, Any]] = field(default_factory=list)
    wall_s: float = 0.0
    fit_seeds: list[Candidate] = field(default_factory=list)
    budget_spent: bool = False


def reference_theta(table: Any, t_end_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The reference's theta on the fit's grid (every ``GRID_DT_S`` from 0 to the horizon)."""
    grid = np.arange(GRID_DT_S, t_end_s + 0.5 * GRID_DT_S, GRID_DT_S)
    grid = grid[grid <= t_end_s + 1e-12]
    return grid, np.interp(grid, table["t"].to_numpy(), table["theta"].to_numpy())


class Problem:
    """The fit's models and measurements: one start per sysid sequence.

    Args:
        starts: The starts followed.
        references: The reference's theta on each start's grid, :func:`reference_theta`.
        timestep_s: MuJoCo timestep of every rollout (s).
        integrator: MuJoCo integrator of every rollout.
        bounds: The fitted settings' bounds.
        threads: Rollout threads.
        ball_until: Per start, the reference's first stem contact (or inversion) (s): the
            residual holds Jellett's constant before it (None: the whole horizon).
    """

    def __init__(self, starts: Sequence[FitStart],
                 references: Sequence[tuple[np.ndarray, np.ndarray]], timestep_s: float,
                 integrator: str, bounds: Bounds, threads: int,
                 ball_until: Sequence[float] | None = None,
                 fitted: Sequence[str] = FITTED) -> None:
        self.sysid = require_sysid()
        #: the settings varied, in the parameter vector's order
        self.fitted = tuple(fitted)
        self.starts = list(starts)
        self.references = list(references)
        self.timestep_s = timestep_s
        self.integrator = integrator
        self.bounds = bounds
        self.threads = threads
        self.rollouts = 0
        #: rollouts the seeds and fits may reach (None: no limit); a fit that would pass it
        #: ends with its best point so far, seeds beyond it are not scored
        self.budget: int | None = None
        #: per start, until when the ball alone touches in the reference (Jellett's constant
        #: is held in the residual before then)
        self.ball_until = list(ball_until) if ball_until else [math.inf] * len(self.starts)
        self._top = (1.0, 1.0, 1.0, 0.0)
        self._measured: dict[int, int] = {}  # id of a start's measurement -> the start
        self._cone = "pyramidal"
        self._template = Candidate("pyramidal", 1.0, 0.02, 0.9, 0.1)

    # -- models -------------------------------------------------------------------------
    def model(self, cand: Candidate, start: FitStart) -> tuple[Any, np.ndarray, np.ndarray]:
        """The harness's model of ``start`` with ``cand``'s settings, sensor added; its start."""
        import mujoco

        from tippetop.compare.running.engines import plan_for
        from tippetop.models.scene import load_scene
        from tippetop.mujoco_runner.model import quat_between
        from tippetop.mujoco_runner.settings import build_model
        from tippetop.mujoco_runner.stepping import start_data

        scene = load_scene(start.scene, [*start.overrides,
                                         *cand.overrides(self.timestep_s, self.integrator)])
        plan = plan_for(scene, "mujoco").mujoco
        assert plan is not None
        top_model = build_model(plan)
        data = start_data(top_model, plan)
        spec = mujoco.MjSpec.from_string(plan.mjcf)
        name = mujoco.mj_id2name(top_model.model, mujoco.mjtObj.mjOBJ_BODY, top_model.body_id)
        body = spec.body(name) if name else spec.bodies[top_model.body_id]
        site = body.add_site(name=SENSOR, pos=[0.0, 0.0, 0.0],
                             quat=quat_between(np.array([0.0, 0.0, 1.0]),
                                                np.asarray(top_model.axis_body, dtype=float)))
        for key, kind in SENSORS.items():
            spec.add_sensor(name=f"{SENSOR}_{key}", type=getattr(mujoco.mjtSensor, kind),
                            objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site.name)
        model = spec.compile()
        top = top_model.top
        self._top = (top.A_kgm2, top.C_kgm2, top.R_m, top.a_m)
        return model, data.qpos.copy(), data.qvel.copy()

    def jellett(self, data: np.ndarray, adr: dict[str, int]) -> np.ndarray:
        """Jellett's constant J = L_G . (R e_z - a k) from the sensors (site frame)."""
        A, C, R, a = self._top
        w = data[:, adr["w"]:adr["w"] + 3]
        # e_z in the site's frame: the world z components of its x, y, z axes
        ez = np.stack([data[:, adr["x"] + 2], data[:, adr["y"] + 2], data[:, adr["z"] + 2]],
                      axis=1)
        L = np.stack([A * w[:, 0], A * w[:, 1], C * w[:, 2]], axis=1)
        return R * np.einsum("ni,ni->n", L, ez) - a * L[:, 2]

    def _sequence_of(self, meas: Any) -> int:
        """The start whose measurement ``meas`` is (sysid hands back the object it was given)."""
        return self._measured[id(meas)]

    def _candidate(self, params: Any) -> Candidate:
        values = {k: float(10.0 ** params[k].value[0]) for k in self.fitted}
        return replace(self._template, cone=self._cone, **values)

    def sequences(self, seed: Candidate) -> list[Any]:
        """One ``ModelSequences`` per start, measured: the reference's cos theta."""
        sysid = self.sysid
        self._measured.clear()  # the previous fit's sequences are done with
        out = []
        for i, (start, (grid, theta)) in enumerate(zip(self.starts, self.references,
                                                       strict=True)):
            model, qpos, qvel = self.model(seed, start)
            x0 = sysid.create_initial_state(model, qpos, qvel)
            steps = np.arange(0.0, grid[-1] + 0.5 * self.timestep_s, self.timestep_s)
            control = sysid.TimeSeries(steps, np.zeros((len(steps), 0)))
            data = np.zeros((len(grid), model.nsensordata))
            data[:, model.sensor(f"{SENSOR}_z").adr[0] + 2] = np.cos(theta)
            meas = sysid.TimeSeries.from_names(grid, data, model)  # every sensor, in order
            spec = _Key(i, model)
            self._measured[id(meas)] = i
            out.append(sysid.ModelSequences(start.label, spec, "theta", x0, control, meas))
        return out

    def _build(self, params: Any, spec: _Key) -> Any:
        self.rollouts += 1
        return self.model(self._candidate(params), self.starts[spec.index])[0]

    def residual_fn(self, cone: str, seed: Candidate) -> tuple[Callable[..., Any], Any]:
        """Sysid's residual closure for ``cone`` and the parameters from ``seed``."""
        sysid = self.sysid
        self._cone = cone
        self._template = replace(seed, cone=cone)
        n = len(self.starts)

        def theta_residual(params: Any, pred: Any, meas: Any, model: Any,
                           return_pred_all: bool, state: Any = None, **_: Any) -> Any:
            del params, model, return_pred_all, state
            pred = pred.resample(meas.times)
            pred = sysid.TimeSeries(pred.times, pred.data, meas.signal_mapping)
            th_p = np.arccos(np.clip(pred.data[:, adr["z"] + 2], -1.0, 1.0))
            th_m = np.arccos(np.clip(meas.data[:, adr["z"] + 2], -1.0, 1.0))
            # sum of squares over all starts = the mean of the starts' squared RMS
            r_theta = (th_p - th_m) / math.sqrt(len(th_m) * n)
            J = self.jellett(pred.data, adr)
            ball = meas.times < self.ball_until[self._sequence_of(meas)]
            drift = np.clip(J[ball] / J[0] - 1.0, -J_CLIP, J_CLIP) if J[0] != 0 else None
            r_J = (W_JELLETT * drift / math.sqrt(max(1, ball.sum()) * n)
                   if drift is not None and ball.any() else np.zeros(0))
            return np.concatenate([r_theta, r_J])[:, None], pred, meas

        seqs = self.sequences(seed)
        first = seqs[0].spec.compile()
        adr = {k: int(first.sensor(f"{SENSOR}_{k}").adr[0]) for k in SENSORS}
        fn = sysid.build_residual_fn(models_sequences=seqs,
                                     build_model=self._build, modify_residual=theta_residual,
                                     n_threads=self.threads)
        params = sysid.ParameterDict()
        for k in self.fitted:
            lo, hi = self.bounds.values[k]
            p = sysid.Parameter(k, nominal=math.log10(getattr(seed, k)),
                                min_value=math.log10(lo), max_value=math.log10(hi))
            params.add(p)
        return fn, params

    def left(self) -> int | None:
        """Rollouts the budget still allows (None: no limit)."""
        return None if self.budget is None else max(0, self.budget - self.rollouts)

    def _rms_of(self, res: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Per column of a batched residual: the RMS over every start, and per start (rad)."""
        n = len(self.starts)
        per = np.stack([np.sqrt(n * np.sum(np.asarray(r).reshape(len(r), -1) ** 2, axis=0))
                        for r in res], axis=1)  # (columns, starts)
        return np.sqrt(np.mean(per ** 2, axis=1)), per

    def score(self, cands: Sequence[Candidate]) -> list[tuple[float, list[float]]]:
        """The RMS over every start, and per start (rad), of each candidate.

        The candidates of a cone are rolled out together, one residual call on every thread.
        Raises :class:`BudgetSpent` if they do not all fit the budget.
        """
        left = self.left()
        if left is not None and left < len(cands) * len(self.starts):
            raise BudgetSpent()
        out: dict[int, tuple[float, list[float]]] = {}
        for cone in dict.fromkeys(c.cone for c in cands):
            idx = [i for i, c in enumerate(cands) if c.cone == cone]
            fn, params = self.residual_fn(cone, cands[idx[0]])
            x = np.stack([[math.log10(getattr(cands[i], k)) for k in self.fitted] for i in idx],
                         axis=1)
            total, per = self._rms_of(fn(x, params)[0])
            for col, i in enumerate(idx):
                out[i] = (float(total[col]), [float(v) for v in per[col]])
        return [out[i] for i in range(len(cands))]

    def rms(self, cand: Candidate) -> tuple[float, list[float]]:
        """The RMS over every start, and per start (rad), of ``cand``."""
        fn, params = self.residual_fn(cand.cone, cand)
        res = fn(params.as_vector(), params)[0]
        n = len(self.starts)
        per = [float(math.sqrt(n * float(np.sum(r ** 2)))) for r in res]
        return float(math.sqrt(float(np.mean(np.square(per))))), per

    def fit(self, seed: Candidate, max_iters: int = MAX_ITERS) -> tuple[Candidate, int]:
        """Levenberg-Marquardt from ``seed`` (its cone kept); the fitted settings, iterations.

        See :meth:`fit_best`, which also gives the fitted settings' RMS and why it stopped.
        """
        found, _rms, _per, iters, _stop = self.fit_best(seed, max_iters)
        return found, iters

    def fit_best(self, seed: Candidate, max_iters: int = MAX_ITERS,
                 stall: float = STALL_FRACTION) -> tuple[Candidate, float, list[float], int, str]:
        """Levenberg-Marquardt from ``seed`` (its cone kept), ended by a rule.

        MuJoCo's bounded Levenberg-Marquardt (``mujoco.minimize.least_squares``, what
        ``mujoco.sysid.optimize`` runs) on sysid's residual, its Jacobian's columns rolled out
        together; it stops after ``max_iters`` iterations, when two iterations together
        lowered the RMS by less than ``stall``, or when the next residual call would pass the
        budget. The answer is the best point any rollout of the fit reached.

        Returns:
            The fitted settings (rounded), their RMS over every start and per start (rad),
            the iterations run, and why it stopped: ``converged`` (the rule), ``iterations``
            (``max_iters``, or the optimizer's own tolerances) or ``budget``.
        """
        import mujoco.minimize as lm

        fn, params = self.residual_fn(seed.cone, seed)
        x0 = params.as_vector()
        best: dict[str, Any] = {"rms": math.inf, "per": [], "x": x0}
        history: list[float] = []

        def residual(x: np.ndarray) -> np.ndarray:
            cols = 1 if x.ndim == 1 else x.shape[1]
            left = self.left()
            if left is not None and left < cols * len(self.starts):
                raise BudgetSpent()
            res = fn(x, params)[0]
            total, per = self._rms_of(res)
            k = int(np.argmin(np.where(np.isfinite(total), total, np.inf)))
            if total[k] < best["rms"]:
                best.update(rms=float(total[k]), per=[float(v) for v in per[k]],
                            x=(x if x.ndim == 1 else x[:, k]).copy())
            return np.concatenate(res)

        def rule(trace: list[Any]) -> None:
            last = trace[-1]
            history.append(math.sqrt(max(0.0, 2.0 * float(last.objective - last.reduction))))
            if len(history) >= 3 and history[-1] > (1.0 - stall) * history[-3]:
                raise _Stalled()

        stop = "iterations"
        try:
            lm.least_squares(x0, residual, bounds=params.get_bounds(), eps=FD_STEP_DECADES,
                             mu_min=LM_MU_MIN, mu_factor=LM_MU_FACTOR, max_iter=max_iters,
                             verbose=lm.Verbosity.SILENT, iter_callback=rule)
        except _Stalled:
            stop = "converged"
        except BudgetSpent:
            stop = "budget"
        params.update_from_vector(np.asarray(best["x"], dtype=float).ravel())
        # the optimizer's last log (after its loop ends of itself) is no iteration
        iters = len(history) - (stop == "iterations")
        return self._candidate(params).rounded(), best["rms"], best["per"], iters, stop


@dataclass(eq=False)
class _Key:
    """Stands for a start's MjSpec in sysid's sequences: the model is built per candidate.

    sysid compiles the spec once for the sequence's layout (``compile``): the seed's model.
    """

    index: int
    seed_model: Any

    def compile(self) -> Any:
        """The seed's compiled model."""
        return self.seed_model


def identify(problem: Problem, seeds: Sequence[Candidate], *, fits_per_cone: int = 1,
             max_iters: int = MAX_ITERS,
             say: Callable[[str], None] | None = None) -> Identified:
    """Score the seeds, fit from the best per cone, keep the best of all.

    Args:
        problem: The starts, references and rollout settings.
        seeds: Starting settings (each with its cone); clipped to the bounds.
        fits_per_cone: Fits run per cone, from its best seeds.
        max_iters: Levenberg-Marquardt iterations per fit.
        say: Where progress lines go (None: nowhere).

    Returns:
        :class:`Identified`.
    """
    t0 = time.perf_counter()
    todo = list(dict.fromkeys(problem.bounds.clip(s).rounded() for s in seeds))
    spent = False
    left = problem.left()
    if left is not None and left < len(todo) * len(problem.starts):
        todo = todo[:max(1, left // max(1, len(problem.starts)))]  # the first ones, in order
        spent = True
    scored = [(rms, per, s) for (rms, per), s in zip(problem.score(todo), todo, strict=True)]
    for rms, _per, s in scored:
        if say:
            say(f"seed {s.label()}: residual {number_text(rms, 'rad')}")
    scored.sort(key=lambda x: x[0] if math.isfinite(x[0]) else math.inf)
    best = scored[0]
    fits = []
    fit_seeds: list[Candidate] = []
    for cone in dict.fromkeys(s.cone for _, _, s in scored):
        for rms0, _per0, seed in [x for x in scored if x[2].cone == cone][:fits_per_cone]:
            left = problem.left()
            if left is not None and left < 2 * len(problem.starts):
                spent = True
                break
            before = problem.rollouts
            found, rms, per, iters, stop = problem.fit_best(seed, max_iters)
            spent = spent or stop == "budget"
            fit_seeds.append(seed)
            fits.append({"cone": cone, "from": seed.label(), "from_rms_rad": rms0,
                         "to": found.label(), "rms_rad": rms,
                         "rollouts": problem.rollouts - before, "iterations": iters,
                         "stop": stop})
            if say:
                say(f"fit ({cone}): residual {number_text(rms0, 'rad')} -> "
                    f"{number_text(rms, 'rad')}, {found.label()} ({iters} iterations, "
                    f"{problem.rollouts - before} rollouts)")
            if rms < best[0]:
                best = (rms, per, found)
    return Identified(best=best[2], rms_rad=best[0], per_start_rms_rad=best[1],
                      rollouts=problem.rollouts,
                      seeds=[{"cone": s.cone, "settings": s.label(), "rms_rad": r}
                             for r, _, s in scored],
                      fits=fits, wall_s=time.perf_counter() - t0, fit_seeds=fit_seeds,
                      budget_spent=spent)


__all__ = ["DAMPRATIO_BOUNDS", "FD_STEP_DECADES", "FITTED", "FITTED_WIDE", "FRICTIONDAMPING_BOUNDS",
           "LIFT_FREE_FITTED", "LIFT_FREE_SEEDS", "LIFT_FREE_SOLREF", "WIDE_IMPRATIO_MAX",
           "lift_free_seeds",
           "WIDE_MU", "MAX_ITERS", "STALL_FRACTION", "Bounds", "BudgetSpent",
           "FitStart", "Identified", "Problem", "identify", "reference_theta",
           "require_sysid"]
