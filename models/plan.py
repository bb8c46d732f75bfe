"""One resolution of a scene: (scene, engine) -> a frozen run plan.

A scene says what the user asked for; a plan says exactly what an engine will run. Every
engine and command takes a plan from :func:`resolve_plan` and none re-derives it: which
friction law the reference integrates, which contact settings, condim, timestep, integrator
and initial state MuJoCo gets, and how often the run is sampled. The rules, in one place:

* Effects. ``effects.sliding = false`` removes sliding friction in every engine: the
  reference integrates law ``none``, MuJoCo's paper mode applies no law (no callback is even
  installed) and native mode gets mu = 0. Torsional and rolling friction exist only in
  MuJoCo's native mode (condim 4 and 6); the reference and paper mode refuse them.
* Paper mode (``mujoco.friction = "paper"``): frictionless contacts (condim 1) and the scene's
  law applied at the contact point by the harness; ``mujoco.mu``, when set, replaces the law's
  mu. The generated top's contact is stiff (:data:`PAPER_SOLREF`) unless ``mujoco.solref`` is
  set: the paper's contact is rigid.
* Native mode: MuJoCo's own friction. For a generated top every setting the scene does not
  set itself comes from the calibration shipped in ``models/calibrated_native.toml`` (its mu
  scaled by friction.mu / 0.1: it was fitted for the paper's mu = 0.1); condim follows the
  effects (3 sliding, 4 with torsional, 6 with rolling, 1 with none).
* A top loaded from an MJCF file runs as its file says: MuJoCo runs its own friction (native
  mode) unless the scene sets ``mujoco.friction``; its timestep, integrator, cone, impratio,
  noslip iterations and contacts are kept (``None`` in the plan) unless the scene sets them
  explicitly (a ``[mujoco]`` key; for condim, also effects other than plain sliding), or asks
  for the calibrated settings (``mujoco.calibrated = true``, the mode ``mujoco-native``). Paper
  mode makes its contacts frictionless (condim 1), which is what paper mode means. It starts
  from the file's first keyframe (or ``init.keyframe``) unless the scene sets ``init.*``; the
  reference starts from the paper's state of that keyframe. The friction laws (the
  reference's, paper mode's) take the ball's mu from the file unless the scene sets
  ``friction.mu``.
* Sampling: ``run.sample_dt_s`` if set, else :func:`default_sample_dt`; in MuJoCo it must be
  a whole number of timesteps (a set value that is not is an error; the default is rounded).

A ``--set`` key that the chosen engine does not read is listed in :attr:`RunPlan.unused`.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from tippetop.models.calibrated import CALIBRATION_MU, calibrated_native_settings
from tippetop.models.errors import TippetopError, expect
from tippetop.models.mjcf import MUJOCO_DEFAULT_ROLLING, MUJOCO_DEFAULT_TORSIONAL
from tippetop.models.modes import MODES
from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams, InitialState, StemParams, TopParams
from tippetop.models.scene import SCHEMA, Scene

#: The engines a plan can be made for.
ENGINES: tuple[str, ...] = ("ode", "mujoco")
#: Paper mode's contact time constant (s) unless the scene sets mujoco.solref: the paper's
#: contact is rigid, and MuJoCo's default 0.02 s lets the ball sink 0.37 mm (2.5 % of R),
#: which moves theta(t) by ~0.014 rad on Fig. 3; 0.5 ms sinks it < 1 um (~2e-4 rad). MuJoCo
#: raises a time constant below 2 dt to 2 dt by itself (refsafe), so coarse steps stay stable.
PAPER_SOLREF: tuple[float, float] = (5e-4, 1.0)
#: Finest default row spacing of the observables table (s).
DEFAULT_SAMPLE_DT_S = 1e-3
#: Longest default table (rows): long runs get a coarser default spacing.
DEFAULT_MAX_SAMPLES = 20_000
#: Relative tolerance for "a whole number of timesteps".
_GRID_RTOL = 1e-9
#: Largest observables table a run may need, in GiB (2**30 bytes), unless
#: :data:`SAMPLE_BUDGET_ENV` says otherwise: a tiny ``run.sample_dt_s`` over a long run is
#: refused before it starts instead of failing to allocate.
SAMPLE_BUDGET_GIB = 4.0
#: Environment variable that sets the samples budget (GiB, a number > 0).
SAMPLE_BUDGET_ENV = "TIPPETOP_MAX_SAMPLES_GIB"
#: Values per row the engines hold for a sample (the table's columns and the extra ones).
SAMPLE_COLUMNS = 23
#: Most MuJoCo steps a run may take: MuJoCo counts them in a C int
#: (``mjData.timer[mjTIMER_STEP].number``), and ``mj_step``'s ``nstep`` is one too.
MUJOCO_MAX_STEPS = 2**31 - 1

#: Keys every engine reads.
_ALWAYS_USED = ("scene.*", "outputs.*", "expect.*", "init.*", "run.*", "effects.sliding",
                "effects.torsional", "effects.rolling", "effects.stem")


def default_sample_dt(t_end_s: float) -> float:
    """1 ms, coarser for long runs so that a table has at most 20,000 rows (s)."""
    return max(DEFAULT_SAMPLE_DT_S, t_end_s / DEFAULT_MAX_SAMPLES)


def sample_interval(t_end_s: float, requested_s: float | None, timestep_s: float) -> float:
    """The row spacing of a MuJoCo run: a whole number of timesteps (s).

    Args:
        t_end_s: Simulated time (s).
        requested_s: ``run.sample_dt_s`` if the scene sets it, else None.
        timestep_s: The timestep that runs (s).

    Raises:
        TippetopError: If a requested spacing is not a whole number of timesteps.
    """
    if requested_s is None:
        steps = max(1, round(default_sample_dt(t_end_s) / timestep_s))
        return steps * timestep_s
    steps = round(requested_s / timestep_s)
    expect(steps >= 1 and abs(steps * timestep_s - requested_s) <= _GRID_RTOL * requested_s,
           "run.sample_dt_s", f"a whole multiple of the timestep {timestep_s:g} s",
           requested_s)
    return steps * timestep_s


def samples_budget_gib() -> float:
    """The samples budget (GiB): ``$TIPPETOP_MAX_SAMPLES_GIB``, else :data:`SAMPLE_BUDGET_GIB`.

    Raises:
        TippetopError: If the variable is set to something other than a number > 0.
    """
    raw = os.environ.get(SAMPLE_BUDGET_ENV, "").strip()
    if not raw:
        return SAMPLE_BUDGET_GIB
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    expect(math.isfinite(value) and value > 0, SAMPLE_BUDGET_ENV,
           "a number of GiB > 0", raw)
    return value


def check_samples(t_end_s: float, sample_dt_s: float) -> None:
    """Refuse a run whose samples would need more memory than the budget.

    The estimate: ``t_end / sample_dt + 1`` rows of :data:`SAMPLE_COLUMNS` float64 values.

    Args:
        t_end_s: Simulated time (s).
        sample_dt_s: Row spacing (s).

    Raises:
        TippetopError: Over :func:`samples_budget_gib`.
    """
    if not (t_end_s > 0 and sample_dt_s > 0):
        return  # the engines say what is wrong with these
    rows = t_end_s / sample_dt_s + 1
    gib = rows * SAMPLE_COLUMNS * 8 / 2**30
    budget = samples_budget_gib()
    if gib > budget:
        raise TippetopError(
            f"run.sample_dt_s: expected at most {budget:g} GiB of samples (the budget, "
            f"settable by {SAMPLE_BUDGET_ENV}), got an estimated {gib:.3g} GiB ({rows:.3g} "
            f"rows of {SAMPLE_COLUMNS} values: run.t_end_s = {t_end_s:g} s every "
            f"{sample_dt_s:g} s); set a longer run.sample_dt_s or a shorter run.t_end_s")


def check_mujoco_steps(t_end_s: float, timestep_s: float) -> None:
    """Refuse a MuJoCo run of more steps than MuJoCo's step counter holds.

    Args:
        t_end_s: Simulated time (s).
        timestep_s: The timestep that runs (s).

    Raises:
        TippetopError: Over :data:`MUJOCO_MAX_STEPS` steps.
    """
    if not (t_end_s > 0 and timestep_s > 0):
        return
    steps = t_end_s / timestep_s
    if steps > MUJOCO_MAX_STEPS:
        raise TippetopError(
            f"run.t_end_s: expected at most {MUJOCO_MAX_STEPS} MuJoCo steps (its step counter "
            f"is a C int), got an estimated {steps:.3g} ({t_end_s:g} s at a timestep of "
            f"{timestep_s:g} s); set a shorter run.t_end_s or a longer mujoco.timestep_s")


@dataclass(frozen=True)
class FileTop:
    """What a plan needs to know of a top loaded from an MJCF file.

    Read by :func:`tippetop.mujoco_runner.model.file_top` (this layer cannot compile MJCF).

    Attributes:
        top: R, a, A, C, M and g read from the compiled model.
        keyframes: The file's keyframe names, in file order (``""`` for an unnamed one).
        keyframe_inits: The paper's state of each keyframe, or None where it has none (the
            ball off the table, say).
        mu: The sliding friction coefficient of the ball's contact with the table, as MuJoCo
            mixes it (the larger of the two geoms', or the contact pair's): the friction
            laws' mu unless the scene sets ``friction.mu``. None: not known.
        stem: The stem's end as the reference models it, from the file's colliding geoms
            (None: the file has none the reference can model).
        stem_note: One line on what was found (which geom, or why none).
        timestep_s: The file's own timestep (s); None: not known.
    """

    top: TopParams
    keyframes: tuple[str, ...] = ()
    keyframe_inits: tuple[InitialState | None, ...] = ()
    mu: float | None = None
    stem: StemParams | None = None
    stem_note: str = ""
    timestep_s: float | None = None


@dataclass(frozen=True)
class OdePlan:
    """What the reference ODE integrates.

    Attributes:
        top: The loaded sphere (from the scene, or read from its MJCF file).
        friction: The law integrated (``none`` when the scene's sliding is off).
        init: Initial state in the paper's variables.
        options: Formulation and tolerances.
        t_end_s: Simulated time (s).
        sample_dt_s: Row spacing of the observables table (s).
        stem: The stem's end, a second contact surface (``effects.stem``), or None.
    """

    top: TopParams
    friction: FrictionParams
    init: InitialState
    options: OdeOptions
    t_end_s: float
    sample_dt_s: float
    stem: StemParams | None = None


@dataclass(frozen=True)
class MujocoPlan:
    """What MuJoCo runs. ``None`` keeps the loaded file's own value.

    Attributes:
        mode: ``paper`` (the harness applies ``law``) or ``native`` (MuJoCo's friction).
        top: The top's parameters (the scene's, or those read from ``mjcf``).
        mjcf: The MJCF file of a loaded top; None for the model generated from ``top``.
        law: Paper mode: the law the harness applies at the contact point (its mu resolved);
            None when no friction is applied by the harness (native mode, or sliding off).
        init: Initial state in the paper's variables.
        t_end_s: Simulated time (s).
        sample_dt_s: Row spacing (s), a whole number of timesteps; None for a loaded top whose
            timestep the plan leaves to the file (the runner applies :func:`sample_interval`
            to the timestep that runs).
        requested_sample_dt_s: ``run.sample_dt_s`` if the scene sets it, else None.
        timestep_s: Physics timestep (s).
        integrator: ``Euler``, ``implicit``, ``implicitfast`` or ``RK4``.
        cone: ``pyramidal`` or ``elliptic``.
        impratio: Frictional-to-normal impedance ratio.
        condim: Contact dimensionality of the top's contacts.
        mu: Sliding coefficient of the top's contacts.
        solref: Contact solref (time constant s, damping ratio).
        solimp: Contact solimp (d0, dwidth, width m[, midpoint, power]).
        torsional: Torsional coefficient (m), condim >= 4.
        rolling: Rolling coefficient (m), condim 6.
        noslip_iterations: MuJoCo's noslip solver iterations.
        keyframe: Start from this keyframe of the loaded file (its index), not from ``init``
            (which then holds the keyframe's paper state, for the reference and the reports).
        stem: The stem's end (``effects.stem``): a generated top gets a colliding stem of this
            shape; for a loaded file, the reference's reading of the file's stem geom.
        stem_collides: A loaded file's colliding geoms other than the ball: None keeps them,
            False makes them non-colliding (``effects.stem = false``).
    """

    mode: str
    top: TopParams
    mjcf: Path | None
    law: FrictionParams | None
    init: InitialState
    t_end_s: float
    sample_dt_s: float | None
    requested_sample_dt_s: float | None
    timestep_s: float | None
    integrator: str | None
    cone: str | None
    impratio: float | None
    condim: int | None
    mu: float | None
    solref: tuple[float, ...] | None
    solimp: tuple[float, ...] | None
    torsional: float | None
    rolling: float | None
    noslip_iterations: int | None = None
    keyframe: int | None = None
    stem: StemParams | None = None
    stem_collides: bool | None = None


@dataclass(frozen=True)
class RunPlan:
    """A scene resolved for one engine.

    Attributes:
        scene: The scene's name.
        engine: ``ode`` or ``mujoco``.
        ode: The reference's plan (engine ``ode``), else None.
        mujoco: MuJoCo's plan (engine ``mujoco``), else None.
        unused: ``--set`` keys the engine does not read, in the order given.
    """

    scene: str
    engine: str
    ode: OdePlan | None
    mujoco: MujocoPlan | None
    unused: tuple[str, ...] = ()

    @property
    def top(self) -> TopParams:
        """The top that runs (for the theory's predictions)."""
        sub = self.ode if self.ode is not None else self.mujoco
        assert sub is not None
        return sub.top

    @property
    def init(self) -> InitialState:
        """The initial state that runs."""
        sub = self.ode if self.ode is not None else self.mujoco
        assert sub is not None
        return sub.init

    @property
    def t_end_s(self) -> float:
        """Simulated time (s)."""
        sub = self.ode if self.ode is not None else self.mujoco
        assert sub is not None
        return sub.t_end_s

    def physics(self) -> dict[str, Any]:
        """Everything that defines the run's numbers, JSON-ready (the runs cache's key)."""
        sub = self.ode if self.ode is not None else self.mujoco
        return {"engine": self.engine, "plan": _jsonable(asdict(sub))}


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    return obj


# ---------------------------------------------------------------- resolution
def friction_keys(friction: FrictionParams) -> set[str]:
    """The ``friction.*`` keys a law reads."""
    keys = {"friction.law"}
    if friction.law == "modified_coulomb":
        keys |= {"friction.mu", "friction.Lambda_mps"}
    if friction.law in ("coulomb", "coulomb_viscous"):
        keys |= {"friction.mu", "friction.coulomb_v_eps_mps"}
    if friction.law in ("viscous", "coulomb_viscous"):
        keys.add("friction.viscous_Nspm")
        if friction.viscous_Nspm is None:  # the default slope is mu M g / Lambda
            keys |= {"friction.mu", "friction.Lambda_mps"}
    return keys


def native_condim(scene: Scene) -> int:
    """Native mode's contact dimensionality from the scene's effects."""
    e = scene.effects
    if e.rolling:
        return 6
    if e.torsional:
        return 4
    return 3 if e.sliding else 1


def _refuse_torsion(scene: Scene, who: str, fix: str) -> None:
    e = scene.effects
    if e.torsional or e.rolling:
        raise TippetopError(f"effects: {who} models sliding friction only, expected "
                            f"torsional = false and rolling = false{fix}, got "
                            f"torsional = {e.torsional}, rolling = {e.rolling}")


def _ode_plan(scene: Scene, top: TopParams, init: InitialState, friction: FrictionParams,
              stem: StemParams | None) -> tuple[OdePlan, set[str]]:
    _refuse_torsion(scene, "the reference ODE", "")
    used = {"ode.formulation", "ode.rtol", "ode.atol", "ode.max_steps"}
    if scene.ode.formulation == "paper":
        used.add("ode.singular_sin")
    if scene.effects.sliding:
        used |= friction_keys(friction)
    else:
        friction = replace(friction, law="none")
    t_end = scene.run.t_end_s
    dt = scene.run.sample_dt_s if scene.run.sample_dt_s is not None else default_sample_dt(t_end)
    if stem is not None:
        expect(scene.ode.formulation == "vector", "ode.formulation",
               "vector with a stem (effects.stem; the paper's equations have the ball only)",
               scene.ode.formulation)
    check_samples(t_end, dt)
    return OdePlan(top=top, friction=friction, init=init, options=scene.ode,
                   t_end_s=t_end, sample_dt_s=dt, stem=stem), used


def _mujoco_plan(scene: Scene, top: TopParams, init: InitialState, keyframe: int | None,
                 friction: FrictionParams, stem: StemParams | None
                 ) -> tuple[MujocoPlan, set[str]]:
    mj = scene.mujoco
    loaded = scene.top_mjcf is not None
    used = {"mujoco.friction", "mujoco.noslip_iterations"}
    # a loaded file runs its own friction unless the scene picks a mode
    mode = mj.friction if not loaded or scene.is_set("mujoco.friction") else "native"

    def own(key: str, value: Any) -> Any:
        """The scene's value; for a loaded top only when the scene sets it explicitly."""
        used.add(f"mujoco.{key}")
        return value if not loaded or scene.is_set(f"mujoco.{key}") else None

    stem_collides = None
    if loaded and scene.effects.stem is False:
        stem_collides = False
    common = {"top": top, "mjcf": scene.top_mjcf, "init": init, "keyframe": keyframe,
              "stem": stem, "stem_collides": stem_collides,
              "t_end_s": scene.run.t_end_s,
              "requested_sample_dt_s": scene.run.sample_dt_s,
              "noslip_iterations": mj.noslip_iterations}
    if mode == "paper":
        _refuse_torsion(scene, "paper mode", " (use mujoco.friction=native)")
        expect(mj.condim in (None, 1), "mujoco.condim",
               "1 in paper mode (the harness applies the friction itself; frictionless "
               "contacts)", mj.condim)
        used |= {"mujoco.condim", "mujoco.timestep_s", "mujoco.integrator", "mujoco.solref",
                 "mujoco.solimp"}
        law = None
        if scene.effects.sliding:
            law = friction
            used |= friction_keys(law)
            if scene.is_set("mujoco.mu"):
                law = replace(law, mu=float(mj.mu))
                used.add("mujoco.mu")
                used.discard("friction.mu")
        solref = mj.solref if scene.is_set("mujoco.solref") else PAPER_SOLREF
        plan = MujocoPlan(
            mode="paper", law=law,
            timestep_s=own("timestep_s", mj.timestep_s),
            integrator=own("integrator", mj.integrator),
            # the cone and impratio shape friction rows only: a paper-mode contact has none
            cone=mj.cone if not loaded or scene.is_set("mujoco.cone") else None,
            impratio=mj.impratio if not loaded or scene.is_set("mujoco.impratio") else None,
            condim=1, mu=None if loaded else 0.0,
            solref=solref if not loaded or scene.is_set("mujoco.solref") else None,
            solimp=own("solimp", mj.solimp),
            torsional=None if loaded else 0.0, rolling=None if loaded else 0.0,
            sample_dt_s=None, **common)
        used.discard("mujoco.cone")
        used.discard("mujoco.impratio")
        return _with_sampling(plan, scene.run.sample_dt_s), used
    # native: MuJoCo's own friction, the calibrated settings or the file's own
    e = scene.effects
    used.add("mujoco.calibrated")
    use_calibration = mj.calibrated if mj.calibrated is not None else not loaded
    calibrated = calibrated_native_settings() if use_calibration else {}
    keep_file = loaded and not use_calibration

    def setting(key: str, value: Any) -> Any:
        used.add(f"mujoco.{key}")
        if scene.is_set(f"mujoco.{key}"):
            return value
        if keep_file:
            return None
        return calibrated.get(key, value)

    # a loaded file keeps its contacts unless the effects ask for something else than sliding
    effects_set = not e.sliding or e.torsional or e.rolling or not keep_file
    used.add("mujoco.condim")
    if scene.is_set("mujoco.condim"):
        condim = mj.condim
    elif not loaded or effects_set:
        condim = native_condim(scene)
    else:
        condim = None
    if scene.is_set("mujoco.mu"):
        mu = float(mj.mu)
        used.add("mujoco.mu")
    elif keep_file:
        mu = None
    elif "mu" in calibrated:
        # the calibration fitted MuJoCo's mu for the reference's mu = CALIBRATION_MU: another
        # law's mu (a loaded file's, a scene's) is scaled by the same factor
        mu = (float(calibrated["mu"]) if friction.mu == CALIBRATION_MU
              else friction.mu * float(calibrated["mu"]) / CALIBRATION_MU)
        used.add("friction.mu")
    else:
        mu = friction.mu
        used.add("friction.mu")
    if not e.sliding:
        mu = 0.0
        used.discard("mujoco.mu")
        used.discard("friction.mu")
    torsional = rolling = None if loaded and not effects_set else 0.0
    if condim is not None and condim >= 4:
        torsional = e.torsional_mu if e.torsional_mu is not None else MUJOCO_DEFAULT_TORSIONAL
        used.add("effects.torsional_mu")
    if condim == 6:
        rolling = e.rolling_mu if e.rolling_mu is not None else MUJOCO_DEFAULT_ROLLING
        used.add("effects.rolling_mu")
    plan = MujocoPlan(
        mode="native", law=None,
        timestep_s=setting("timestep_s", mj.timestep_s),
        integrator=setting("integrator", mj.integrator),
        cone=setting("cone", mj.cone), impratio=setting("impratio", mj.impratio),
        condim=condim, mu=mu,
        solref=_tuple(setting("solref", mj.solref)), solimp=_tuple(setting("solimp", mj.solimp)),
        torsional=torsional, rolling=rolling, sample_dt_s=None, **common)
    return _with_sampling(plan, scene.run.sample_dt_s), used


def _tuple(v: Any) -> tuple[float, ...] | None:
    return None if v is None else tuple(float(x) for x in v)


def _with_sampling(plan: MujocoPlan, requested_s: float | None) -> MujocoPlan:
    """Resolve the row spacing where the timestep is known (every generated top).

    Also refuses a run over the samples budget or MuJoCo's step counter (with the file's own
    timestep, :mod:`tippetop.mujoco_runner.run` checks the steps when it knows it).
    """
    check_samples(plan.t_end_s, requested_s if requested_s is not None
                  else default_sample_dt(plan.t_end_s))
    if plan.timestep_s is None:
        return plan
    check_mujoco_steps(plan.t_end_s, plan.timestep_s)
    return replace(plan, sample_dt_s=sample_interval(plan.t_end_s, requested_s,
                                                     plan.timestep_s))


def _unused(set_keys: tuple[str, ...], used: set[str]) -> tuple[str, ...]:
    wild = {k[:-1] for k in used if k.endswith(".*")}
    return tuple(k for k in set_keys
                 if k not in used and not any(k.startswith(w) for w in wild))


_STATE_KEYS = ("theta0", "thetadot0", "Omega0", "n0", "uOX", "uOY")


def _start(scene: Scene, file_top: FileTop | None) -> tuple[InitialState, int | None]:
    """The initial state, and the loaded file's keyframe it comes from (None: the scene's)."""
    state_set = [k for k in _STATE_KEYS if scene.is_set(f"init.{k}")]
    if file_top is None or (scene.init_keyframe is None and (state_set or
                                                              not file_top.keyframes)):
        return scene.init, None
    if scene.init_keyframe is not None:
        expect(not state_set, "init", "either init.keyframe or the state (init.theta0, ...), "
               "not both", f"init.keyframe and {', '.join('init.' + k for k in state_set)}")
        names = file_top.keyframes
        expect(scene.init_keyframe in names, "init.keyframe",
               "the name of one of the file's keyframes (" + ", ".join(
                   repr(n) for n in names if n) + ")" if any(names) else
               "a file with named keyframes (this one has none)", scene.init_keyframe)
        index = names.index(scene.init_keyframe)
    else:
        index = 0
    init = file_top.keyframe_inits[index]
    label = file_top.keyframes[index] or f"#{index}"
    if init is None:
        raise TippetopError(f"init.keyframe: expected a keyframe whose ball touches the table "
                            f"(the paper's state of the top is defined there), got {label!r}; "
                            "set the state with init.* instead")
    return init, index


def resolve_plan(scene: Scene, engine: str, *, file_top: FileTop | None = None) -> RunPlan:
    """The one resolution of a scene for an engine (see the module docstring).

    Args:
        scene: A validated scene.
        engine: ``ode`` or ``mujoco`` (which MuJoCo mode: the scene's ``mujoco.friction``; the
            file's own friction for a loaded top that does not set it).
        file_top: For a scene whose top is an MJCF file, what the file says about it
            (:func:`tippetop.mujoco_runner.model.file_top` reads it; this layer cannot).

    Raises:
        TippetopError: An unknown engine, or effects and settings the engine cannot run.
    """
    expect(engine in ENGINES, "--engine", "|".join(ENGINES), engine)
    if scene.top_mjcf is not None:
        if file_top is None:
            raise TypeError("resolve_plan: a scene with top.mjcf needs file_top")
        top = file_top.top
        used = {"top.mjcf"}
    else:
        file_top = None
        top = scene.top
        used = {f"top.{k}" for k in SCHEMA["top"] if k != "mjcf"}
    used |= set(_ALWAYS_USED)
    init, keyframe = _start(scene, file_top)
    friction = scene.friction
    if file_top is not None and file_top.mu is not None and not scene.is_set("friction.mu"):
        friction = replace(friction, mu=file_top.mu)  # the law's mu: the file's, by default
    # the stem: a scene's own when effects.stem; a loaded file's unless effects.stem = false
    if file_top is not None:
        stem = file_top.stem if scene.effects.stem is not False else None
        if scene.effects.stem and stem is None:
            raise TippetopError(f"effects.stem: expected a file whose stem the reference can "
                                f"model, got {file_top.stem_note}")
    else:
        stem = scene.stem if scene.effects.stem else None
        if stem is not None:
            used.add("stem.*")
    ode = mujoco = None
    if engine == "ode":
        ode, more = _ode_plan(scene, top, init, friction, stem)
    else:
        mujoco, more = _mujoco_plan(scene, top, init, keyframe, friction, stem)
    return RunPlan(scene=scene.name, engine=engine, ode=ode, mujoco=mujoco,
                   unused=_unused(scene.set_keys, used | more))


def mode_engine(mode: str) -> tuple[str, tuple[str, ...]]:
    """(engine, overrides) of a mode name, or of a bare engine name (no overrides)."""
    if mode in ENGINES:
        return mode, ()
    if mode not in MODES:
        raise TippetopError(f"mode: expected an engine ({', '.join(ENGINES)}) or a mode "
                            f"({', '.join(MODES)}), got {mode!r}")
    return MODES[mode]


__all__ = ["DEFAULT_MAX_SAMPLES", "DEFAULT_SAMPLE_DT_S", "ENGINES", "MUJOCO_MAX_STEPS",
           "SAMPLE_BUDGET_ENV", "SAMPLE_BUDGET_GIB", "SAMPLE_COLUMNS", "FileTop", "MujocoPlan",
           "OdePlan",
           "PAPER_SOLREF", "RunPlan", "check_mujoco_steps", "check_samples", "default_sample_dt",
           "friction_keys", "mode_engine", "native_condim", "resolve_plan", "sample_interval"]
