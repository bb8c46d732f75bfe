"""A run plan: exactly what an engine will run, every value resolved, as data.

:func:`tippetop.models.resolve.resolve_plan` turns a scene into a :class:`RunPlan`; every
engine and command takes the plan and decides nothing itself. A plan holds every value a run
uses (MuJoCo's options, every contact's settings, the MJCF text that will be compiled, the
initial state, the sampling grid), and round-trips through JSON exactly (:meth:`RunPlan.
to_json`, :meth:`RunPlan.from_json`), so another process, another Python environment or
another machine can run it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import types
import typing
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

from tippetop.models.contacts import ContactSetting, MixedContact, ball_table_contact
from tippetop.models.errors import TippetopError, expect
from tippetop.models.modes import LAW_MODES
from tippetop.models.options import OdeOptions, auto_method, method_title, taylor_runs
from tippetop.models.params import FrictionParams, InitialState, StemParams, TopParams

#: The ``format`` of a plan's JSON (2: the engine it runs on and its mode); another is refused.
PLAN_FORMAT = "tippetop-plan/2"
#: The formats read: the first one's plans run on the family's own engine, in the mode their
#: settings say.
READ_FORMATS = ("tippetop-plan/1", PLAN_FORMAT)
#: Finest default row spacing of the observables table (s).
DEFAULT_SAMPLE_DT_S = 1e-3
#: Longest default table (rows): long runs get a coarser default spacing.
DEFAULT_MAX_SAMPLES = 20_000
#: Relative tolerance for "a whole number of timesteps" and for the last sample falling on
#: t_end (the one place the sample grid is checked).
GRID_RTOL = 1e-9
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


# ---------------------------------------------------------------- sampling and budgets
def default_sample_dt(t_end_s: float) -> float:
    """1 ms, coarser for long runs so that a table has at most 20,000 rows (s)."""
    return max(DEFAULT_SAMPLE_DT_S, t_end_s / DEFAULT_MAX_SAMPLES)


def sample_grid(t_end_s: float, requested_s: float | None,
                timestep_s: float) -> tuple[float, int, int]:
    """The sample grid of a MuJoCo run: (row spacing s, steps per sample, sample intervals).

    The spacing is a whole number of timesteps: ``run.sample_dt_s`` if the scene sets it
    (within :data:`GRID_RTOL`), else :func:`default_sample_dt` rounded to one.

    Raises:
        TippetopError: A requested spacing that is not a whole number of timesteps, or a run
            shorter than one sample interval.
    """
    if requested_s is None:
        steps = max(1, round(default_sample_dt(t_end_s) / timestep_s))
    else:
        steps = round(requested_s / timestep_s)
        expect(steps >= 1 and abs(steps * timestep_s - requested_s) <= GRID_RTOL * requested_s,
               "run.sample_dt_s", f"a whole multiple of the timestep {timestep_s:g} s",
               requested_s)
    sample_dt = steps * timestep_s
    n_intervals = math.floor(t_end_s / sample_dt * (1 + GRID_RTOL))
    expect(n_intervals >= 1, "run.t_end_s", f">= the sample interval {sample_dt:g} s", t_end_s)
    return sample_dt, steps, n_intervals


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

    Raises:
        TippetopError: Over :func:`samples_budget_gib`.
    """
    if not (t_end_s > 0 and sample_dt_s > 0):
        return  # the scene's checks say what is wrong with these
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


# ---------------------------------------------------------------- what a file says
@dataclass(frozen=True)
class FileTop:
    """What a plan needs to know of a top loaded from an MJCF file: everything it reads there.

    Read by :func:`tippetop.mujoco_runner.state.file_top` (this layer cannot compile MJCF).

    Attributes:
        top: R, a, A, C, M and g read from the compiled model.
        path: The file.
        text: Its MJCF document.
        timestep_s: The file's timestep (s).
        integrator: Its integrator (``Euler``, ``RK4``, ``implicit``, ``implicitfast``).
        cone: Its friction cone.
        impratio: Its impratio.
        noslip_iterations: Its noslip iterations.
        gravity_mps2: Its gravity vector (m/s^2).
        contacts: Every colliding geom of the top and of the static world, and every contact
            pair of the top, as the file sets them.
        ngeom: The model's geom count (the document's ``<geom>`` elements are as many).
        npair: Its contact pair count.
        contact_reach_m: The farthest a contact on the top can be from its centre of mass,
            over its colliding geoms (m).
        centre_body_m: The ball's centre S in the body frame (m).
        paper_from_body_quat: The rotation (w, x, y, z) from the body frame to the paper's
            body frame (whose z axis is the symmetry axis).
        keyframes: The file's keyframe names, in file order (``""`` for an unnamed one).
        keyframe_inits: The paper's state of each keyframe, or None where it has none (the
            ball off the table, say).
        mu: The sliding friction coefficient of the ball's contact with the table, as MuJoCo
            mixes it: the friction laws' mu unless the scene sets ``friction.mu``. None: the
            ball touches no static geom.
        stem: The stem's end as the reference models it, from the file's colliding geoms
            (None: the file has none the reference can model).
        stem_note: One line on what was found (which geom, or why none).
        iterations: Its constraint solver's maximum iterations.
        tolerance: Its solver tolerance.
        contacts_on: False where the file disables contacts (``<flag contact="disable">``).
    """

    top: TopParams
    path: Path
    text: str
    timestep_s: float
    integrator: str
    cone: str
    impratio: float
    noslip_iterations: int
    gravity_mps2: tuple[float, float, float]
    contacts: tuple[ContactSetting, ...]
    ngeom: int
    npair: int
    contact_reach_m: float
    centre_body_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    paper_from_body_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    keyframes: tuple[str, ...] = ()
    keyframe_inits: tuple[InitialState | None, ...] = ()
    mu: float | None = None
    stem: StemParams | None = None
    stem_note: str = ""
    iterations: int = 100
    tolerance: float = 1e-8
    contacts_on: bool = True


# ---------------------------------------------------------------- the plans
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

    def what_runs(self) -> dict[str, Any]:
        """What will run, under the keys a run's summary reports what ran with."""
        method, factor = self.options.method, 1.0
        if method == "auto":
            method, factor = auto_method(
                self.options.rtol, taylor_runs(self.options.formulation, self.friction.law,
                                               self.stem is not None))
        return {"friction_law": self.friction.law, "formulation": self.options.formulation,
                "method": method_title(method, self.options.rtol * factor),
                "rtol": self.options.rtol * factor,
                "atol": self.options.atol * factor, "sample_dt_s": self.sample_dt_s}


@dataclass(frozen=True)
class MujocoPlan:
    """What MuJoCo runs: every value resolved, and the MJCF text that holds them.

    Attributes:
        friction: Who makes the friction: ``paper`` (the harness applies ``law`` at the
            contact point) or ``native`` (MuJoCo's own contact friction); the scene's
            ``mujoco.friction``.
        top: The top's parameters (the scene's, or those read from its file).
        law: Paper mode: the law the harness applies at the contact point (its mu resolved);
            None when no friction is applied by the harness (native mode, or sliding off).
        init: The initial state in the paper's variables (for the reference and the reports).
        t_end_s: Simulated time (s).
        timestep_s: Physics timestep (s).
        integrator: ``Euler``, ``implicit``, ``implicitfast`` or ``RK4``.
        cone: ``pyramidal`` or ``elliptic``.
        impratio: Frictional-to-normal impedance ratio.
        noslip_iterations: MuJoCo's noslip solver iterations.
        gravity_mps2: The gravity vector (m/s^2).
        contacts: Every colliding geom of the top and of the table, and every contact pair of
            the top, with the values the model has (:class:`~.contacts.ContactSetting`).
        sample_dt_s: Row spacing of the observables table (s), ``steps_per_sample`` steps.
        steps_per_sample: Timesteps per sample interval.
        n_intervals: Sample intervals to t_end (the table has one more row).
        mjcf: The MJCF text that is compiled: the options and contacts above written in.
        source: The loaded file (its path), or None for the top generated from ``top``.
        keyframe: Start from this keyframe of ``mjcf`` (its index; a loaded file's own); None:
            from ``start_qpos``/``start_qvel``.
        keyframe_name: That keyframe's name (``#index`` if it has none).
        start_qpos: The free joint's qpos (7: position, quaternion w x y z) at t = 0, from
            ``init``; () when the run starts from ``keyframe``.
        start_qvel: The free joint's qvel (6: world linear, body angular velocity) at t = 0.
        stem: The stem's end (the reference's reading of it), where paper mode's law also
            acts when it touches the table; None: no stem.
        paper_max_timestep_s: Paper mode: the longest step the law can be followed with on
            this top (s); None without a law.
        notes: What the plan chose that the scene did not ask for, and why: a sentence each.
        iterations: The constraint solver's maximum iterations.
        tolerance: The solver's tolerance.
        contacts_on: False: contacts disabled (the top falls freely).
        reference_law: The law the reference runs on this scene (its mu resolved): what the
            friction MuJoCo realises is measured against (``friction_realised``), in native
            mode too.
    """

    friction: str
    top: TopParams
    law: FrictionParams | None
    init: InitialState
    t_end_s: float
    timestep_s: float
    integrator: str
    cone: str
    impratio: float
    noslip_iterations: int
    gravity_mps2: tuple[float, float, float]
    contacts: tuple[ContactSetting, ...]
    sample_dt_s: float
    steps_per_sample: int
    n_intervals: int
    mjcf: str
    source: str | None = None
    keyframe: int | None = None
    keyframe_name: str | None = None
    start_qpos: tuple[float, ...] = ()
    start_qvel: tuple[float, ...] = ()
    stem: StemParams | None = None
    paper_max_timestep_s: float | None = None
    notes: tuple[str, ...] = field(default=())
    iterations: int = 100
    tolerance: float = 1e-8
    contacts_on: bool = True
    reference_law: FrictionParams | None = None

    @property
    def ball_contact(self) -> MixedContact | None:
        """The ball's contact with the table as MuJoCo makes it from ``contacts``."""
        return ball_table_contact(self.contacts)

    @property
    def n_steps(self) -> int:
        """Timesteps the run takes to t_end."""
        return self.n_intervals * self.steps_per_sample

    def what_runs(self) -> dict[str, Any]:
        """What will run, under the keys a run's summary reports what ran with.

        The contact is the ball's with the table (:attr:`ball_contact`), where a run reads
        back the top's first contact at t = 0 (the same one, unless another geom of the top
        starts on the table).
        """
        law = self.law
        out: dict[str, Any] = {
            "timestep_s": self.timestep_s, "integrator": self.integrator,
            "cone": self.cone, "impratio": self.impratio,
            "noslip_iterations": self.noslip_iterations, "gravity_mps2": -self.gravity_mps2[2],
            "iterations": self.iterations, "tolerance": self.tolerance,
            "contacts": self.contacts_on}
        contact = self.ball_contact
        if contact is not None:
            out.update(contact.acting())
        out["friction_law"] = (NATIVE_LAW if self.friction == "native"
                               else law.law if law is not None else "none")
        if law is not None:
            out["law_mu"] = law.mu
        out["sample_dt_s"] = self.sample_dt_s
        out["keyframe"] = self.keyframe_name
        return out


@dataclass(frozen=True)
class RunPlan:
    """A scene resolved for one engine in one mode: what runs, and where.

    Attributes:
        scene: The scene's name.
        engine: The engine it runs on, as given (``ode``, ``mujoco``, ``mujoco==3.3.7``,
            ``mjx`` ...: :mod:`tippetop.models.engines`).
        mode: How the contact force is made (``paper``, ``native`` ...:
            :mod:`tippetop.models.modes`).
        ode: The reference's plan (engine ``ode``), else None.
        mujoco: MuJoCo's plan (every other engine), else None.
        unused: ``--set`` keys the engine does not read, in the order given.
    """

    scene: str
    engine: str
    mode: str
    ode: OdePlan | None
    mujoco: MujocoPlan | None
    unused: tuple[str, ...] = ()

    @property
    def is_reference(self) -> bool:
        """The reference ODE's plan (else MuJoCo's)."""
        return self.ode is not None

    @property
    def family(self) -> str:
        """``ode`` or ``mujoco``: which of the two plans this is."""
        return "ode" if self.ode is not None else "mujoco"

    @property
    def sub(self) -> OdePlan | MujocoPlan:
        """The engine's own plan."""
        sub = self.ode if self.ode is not None else self.mujoco
        assert sub is not None
        return sub

    @property
    def top(self) -> TopParams:
        """The top that runs (for the theory's predictions)."""
        return self.sub.top

    @property
    def init(self) -> InitialState:
        """The initial state that runs."""
        return self.sub.init

    @property
    def t_end_s(self) -> float:
        """Simulated time (s)."""
        return self.sub.t_end_s

    def what_runs(self) -> dict[str, Any]:
        """What will run, as a summary's ``what ran`` keys say it (its engine's)."""
        return {"mode": self.mode, **self.sub.what_runs()}

    def physics(self) -> dict[str, Any]:
        """Everything that defines the run's numbers, JSON-ready (the runs cache's key).

        The family's plan; not the engine (the cache adds it where it is not this process's
        own) nor the mode's name (two names of the same settings are the same run).
        """
        return {"family": self.family, "plan": to_data(self.sub)}

    def to_json(self) -> str:
        """The plan as JSON text: ``format`` (:data:`PLAN_FORMAT`) and every field."""
        return json.dumps({"format": PLAN_FORMAT, **to_data(self)}, indent=1,
                          allow_nan=False)

    @classmethod
    def from_json(cls, text: str) -> RunPlan:
        """The plan of :meth:`to_json`'s text, equal to the one written.

        Raises:
            TippetopError: Not a plan's JSON (another format, missing or unknown fields).
        """
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise TippetopError(f"plan: expected JSON, got: {exc}") from None
        got = data.get("format") if isinstance(data, dict) else type(data).__name__
        expect(isinstance(data, dict) and got in READ_FORMATS, "plan format",
               " or ".join(repr(f) for f in READ_FORMATS), got)
        body = {k: v for k, v in data.items() if k != "format"}
        if got == "tippetop-plan/1":
            body = _from_first_format(body)
        return from_data(cls, body, "plan")


#: ``friction_law`` of a run whose friction is MuJoCo's own contact (no law is applied).
NATIVE_LAW = "mujoco_contact"


def _from_first_format(body: dict[str, Any]) -> dict[str, Any]:
    """A ``tippetop-plan/1`` body as the second format has it (the same run).

    The first format's ``engine`` was ``ode`` or ``mujoco`` (the family, on its own engine)
    and it had no mode: the mode is what the settings say (the reference's law; MuJoCo's
    ``mode``, now ``friction``, with ``native`` for MuJoCo's own contact).
    """
    out = dict(body)
    mj = out.get("mujoco")
    if isinstance(mj, dict) and "mode" in mj:
        mj = dict(mj)
        mj["friction"] = mj.pop("mode")
        out["mujoco"] = mj
    if "mode" not in out:
        if isinstance(mj, dict):
            out["mode"] = "paper" if mj.get("friction") == "paper" else "native"
        else:
            law = ((out.get("ode") or {}).get("friction") or {}).get("law")
            out["mode"] = LAW_MODES.get(str(law), "paper")
    return out


# ---------------------------------------------------------------- JSON
def to_data(obj: Any) -> Any:
    """A plan (or any of its parts) as JSON-ready data: dataclasses become dicts."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_data(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_data(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    return obj


@cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def from_data(kind: Any, data: Any, where: str) -> Any:
    """The value of type ``kind`` that :func:`to_data` made ``data`` from.

    Raises:
        TippetopError: ``data`` does not fit ``kind`` (named by ``where``).
    """
    origin = typing.get_origin(kind)
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(kind)
        if data is None and type(None) in options:
            return None
        real = [k for k in options if k is not type(None)]
        return from_data(real[0], data, where)
    if origin is tuple:
        expect(isinstance(data, list), where, "a list", data)
        args = typing.get_args(kind)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(from_data(args[0], v, f"{where}[{i}]") for i, v in enumerate(data))
        expect(len(data) == len(args), where, f"{len(args)} values", data)
        return tuple(from_data(a, v, f"{where}[{i}]")
                     for i, (a, v) in enumerate(zip(args, data, strict=True)))
    if dataclasses.is_dataclass(kind):
        expect(isinstance(data, dict), where, f"an object ({kind.__name__})", data)
        hints = _hints(kind)
        names = {f.name for f in dataclasses.fields(kind) if f.init}
        unknown = sorted(set(data) - names)
        expect(not unknown, where, f"the fields of {kind.__name__}", unknown)
        try:
            return kind(**{k: from_data(hints[k], v, f"{where}.{k}") for k, v in data.items()})
        except TypeError as exc:  # a field missing
            raise TippetopError(f"{where}: expected the fields of {kind.__name__}, got "
                                f"{exc}") from None
    if kind is float:
        expect(isinstance(data, (int, float)) and not isinstance(data, bool), where,
               "a number", data)
        return float(data)
    if kind is int:
        expect(isinstance(data, int) and not isinstance(data, bool), where, "an integer", data)
        return data
    if kind is bool:
        expect(isinstance(data, bool), where, "true or false", data)
        return data
    if kind is str:
        expect(isinstance(data, str), where, "a string", data)
        return data
    if kind is Path:
        expect(isinstance(data, str), where, "a path", data)
        return Path(data)
    return data


__all__ = ["DEFAULT_MAX_SAMPLES", "DEFAULT_SAMPLE_DT_S", "GRID_RTOL",
           "MUJOCO_MAX_STEPS", "NATIVE_LAW", "PLAN_FORMAT", "READ_FORMATS", "SAMPLE_BUDGET_ENV",
           "SAMPLE_BUDGET_GIB", "SAMPLE_COLUMNS", "FileTop", "MujocoPlan", "OdePlan", "RunPlan",
           "check_mujoco_steps", "check_samples", "default_sample_dt", "from_data",
           "sample_grid", "samples_budget_gib", "to_data"]
