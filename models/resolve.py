"""The one resolution of a scene: (scene, engine) -> a run plan with every value resolved.

A scene says what the user asked for; :func:`resolve_plan` says exactly what an engine will run
(:mod:`tippetop.models.plan`), and no engine or command re-derives it. A ``--set`` key that the
chosen engine does not read is listed in :attr:`RunPlan.unused`. The rules (effects, paper and
native mode, a top loaded from an MJCF file, sampling): docs/design.md.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from tippetop.models import mjcf_document
from tippetop.models.calibrated import CALIBRATION_MU, calibrated_native_settings
from tippetop.models.contacts import ContactSetting, with_friction_pairs
from tippetop.models.engines import EngineSpec, parse_engine
from tippetop.models.errors import TippetopError, expect
from tippetop.models.frames import free_joint_start
from tippetop.models.mjcf import (
    BALL_GEOM,
    MUJOCO_DEFAULT_ROLLING,
    MUJOCO_DEFAULT_TORSIONAL,
    STEM_GEOM,
    TABLE_GEOM,
    MjcfContact,
    MjcfOption,
    make_mjcf,
)
from tippetop.models.modes import MODES, check_pair, scene_mode
from tippetop.models.options import GENERATED_NOSLIP_ITERATIONS, MujocoOptions
from tippetop.models.params import FrictionParams, InitialState, StemParams, TopParams
from tippetop.models.plan import (
    FileTop,
    MujocoPlan,
    OdePlan,
    RunPlan,
    check_mujoco_steps,
    check_samples,
    default_sample_dt,
    sample_grid,
)
from tippetop.models.scene import SCHEMA, Scene

#: Paper mode's contact time constant (s) unless the scene sets mujoco.solref: the paper's
#: contact is rigid, and MuJoCo's default 0.02 s lets the ball sink 0.37 mm (2.5 % of R),
#: which moves theta(t) by ~0.014 rad on Fig. 3; 0.5 ms sinks it < 1 um (~2e-4 rad). MuJoCo
#: raises a time constant below 2 dt to 2 dt by itself (refsafe), so coarse steps stay stable.
PAPER_SOLREF: tuple[float, float] = (5e-4, 1.0)
#: Paper mode's longest step, times the law's slip relaxation rate (see paper_max_timestep).
PAPER_LAW_MAX_DT_RATE = 1.0
#: Keys every engine reads.
_ALWAYS_USED = ("scene.*", "outputs.*", "expect.*", "init.*", "run.*", "effects.sliding",
                "effects.torsional", "effects.rolling", "effects.stem")
#: The scene's MuJoCo defaults (a generated top's values where the scene sets none).
_DEFAULT = MujocoOptions()
#: Geom ids of the generated top (:func:`~.mjcf.make_mjcf` writes table, ball, stem, marker).
_GENERATED_IDS = {TABLE_GEOM: 0, BALL_GEOM: 1, STEM_GEOM: 2}


# ---------------------------------------------------------------- small rules
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


def nice_step_below(limit_s: float) -> float:
    """The largest 1, 2 or 5 x 10^k seconds at or below ``limit_s``."""
    exp = math.floor(math.log10(limit_s))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0 ** exp <= limit_s * (1 + 1e-12):
            return m * 10.0 ** exp
    return 10.0 ** exp  # pragma: no cover - 1 x 10^floor(log10 x) <= x always


def generated_contact_reach_m(top: TopParams, stem: StemParams | None) -> float:
    """How far from G a contact on the generated top can be (m): the ball, or its stem.

    The stem geom runs from the ball's centre S to its end (:func:`~.mjcf.make_mjcf`): a
    capsule of radius r reaches L + r beyond S, a cylinder's rim corner sqrt(r^2 + (L/2)^2)
    beyond its centre L/2 out; G is a on the other side of S.
    """
    reach = top.R_m + top.a_m
    if stem is not None:
        L, r = stem.offset_m, stem.radius_m
        beyond = L + r if stem.kind == "sphere" else L / 2 + math.hypot(r, L / 2)
        reach = max(reach, top.a_m + beyond)
    return reach


def paper_max_timestep(law: FrictionParams, top: TopParams, reach_m: float) -> float | None:
    """The longest step paper mode follows ``law`` with on this top (s); None: any step.

    The callback applies the law once per stage from the state's slip: with a step longer than
    the slip's relaxation time (:meth:`FrictionParams.slip_relaxation_rate`, with the top's
    farthest contact point, a stem's, say) the slip overshoots zero every step and the force
    flips instead of relaxing. ``reach_m``: that farthest point's distance from G.
    """
    rate = law.slip_relaxation_rate(top, reach_m)
    return PAPER_LAW_MAX_DT_RATE / rate if rate > 0.0 else None


def _refuse_torsion(scene: Scene, who: str, fix: str) -> None:
    e = scene.effects
    if e.torsional or e.rolling:
        raise TippetopError(f"effects: {who} models sliding friction only, expected "
                            f"torsional = false and rolling = false{fix}, got "
                            f"torsional = {e.torsional}, rolling = {e.rolling}")


def _unused(set_keys: tuple[str, ...], used: set[str]) -> tuple[str, ...]:
    wild = {k[:-1] for k in used if k.endswith(".*")}
    return tuple(k for k in set_keys
                 if k not in used and not any(k.startswith(w) for w in wild))


# ---------------------------------------------------------------- the reference
def _ode_plan(scene: Scene, top: TopParams, init: InitialState, friction: FrictionParams,
              stem: StemParams | None) -> tuple[OdePlan, set[str]]:
    _refuse_torsion(scene, "the reference ODE", "")
    used = {"ode.formulation", "ode.rtol", "ode.atol", "ode.max_steps", "ode.method"}
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


# ---------------------------------------------------------------- MuJoCo
class _Wanted:
    """What the scene asks of MuJoCo's settings, and the scene keys that reads.

    ``values``: key -> value (None keeps a loaded file's own); ``used``: the keys read.
    """

    def __init__(self, scene: Scene, loaded: bool) -> None:
        self.scene, self.loaded = scene, loaded
        self.used: set[str] = {"mujoco.friction", "mujoco.noslip_iterations",
                               "mujoco.iterations", "mujoco.tolerance", "mujoco.contacts"}
        self.values: dict[str, Any] = {}

    def set_by_scene(self, key: str) -> bool:
        return self.scene.is_set(f"mujoco.{key}")

    def take(self, key: str, value: Any, *, read: bool = True) -> None:
        """The scene's value when it sets it (or any generated top's), else the file's (None).

        ``read``: the key counts as read by the engine (listed as unused otherwise).
        """
        if read:
            self.used.add(f"mujoco.{key}")
        self.values[key] = value if not self.loaded or self.set_by_scene(key) else None


def _paper_wanted(scene: Scene, friction: FrictionParams, want: _Wanted) -> FrictionParams | None:
    """Paper mode's settings into ``want``; the law the harness applies (None: no friction)."""
    mj, loaded = scene.mujoco, want.loaded
    _refuse_torsion(scene, "paper mode", " (use mujoco.friction=native)")
    expect(mj.condim in (None, 1), "mujoco.condim",
           "1 in paper mode (the harness applies the friction itself; frictionless "
           "contacts)", mj.condim)
    want.used |= {"mujoco.condim", "mujoco.fit_paper_timestep"}
    law = None
    if scene.effects.sliding:
        law = friction
        want.used |= friction_keys(law)
        if scene.is_set("mujoco.mu"):
            law = replace(law, mu=float(mj.mu))
            want.used.add("mujoco.mu")
            want.used.discard("friction.mu")
    for key in ("timestep_s", "integrator", "solimp"):
        want.take(key, getattr(mj, key))
    want.take("solref", mj.solref if want.set_by_scene("solref") else PAPER_SOLREF)
    # the cone and impratio shape friction rows only: a paper-mode contact has none
    for key in ("cone", "impratio"):
        want.take(key, getattr(mj, key), read=False)
    want.values.update(condim=1, mu=None if loaded else 0.0,
                       torsional=None if loaded else 0.0, rolling=None if loaded else 0.0)
    return law


def _native_wanted(scene: Scene, friction: FrictionParams, want: _Wanted) -> None:
    """Native mode's settings into ``want``: the scene's, the calibration's or the file's."""
    mj, e, loaded = scene.mujoco, scene.effects, want.loaded
    want.used.add("mujoco.calibrated")
    use_calibration = mj.calibrated if mj.calibrated is not None else not loaded
    calibrated = calibrated_native_settings() if use_calibration else {}
    keep_file = loaded and not use_calibration
    for key in ("timestep_s", "integrator", "cone", "impratio", "solref", "solimp"):
        want.used.add(f"mujoco.{key}")
        value = getattr(mj, key)
        if not want.set_by_scene(key):
            value = None if keep_file else calibrated.get(key, value)
        want.values[key] = value
    # a loaded file keeps its contacts unless the effects ask for more than sliding
    effects_set = not e.sliding or e.torsional or e.rolling or not keep_file
    want.used.add("mujoco.condim")
    if want.set_by_scene("condim"):
        condim = mj.condim
    elif not loaded or effects_set:
        condim = native_condim(scene)
    else:
        condim = None
    if want.set_by_scene("mu"):
        mu = float(mj.mu)
        want.used.add("mujoco.mu")
    elif keep_file:
        mu = None
    elif "mu" in calibrated:
        # the calibration fitted MuJoCo's mu for the reference's mu = CALIBRATION_MU: another
        # law's mu (a loaded file's, a scene's) is scaled by the same factor
        mu = (float(calibrated["mu"]) if friction.mu == CALIBRATION_MU
              else friction.mu * float(calibrated["mu"]) / CALIBRATION_MU)
        want.used.add("friction.mu")
    else:
        mu = friction.mu
        want.used.add("friction.mu")
    if not e.sliding:
        mu = 0.0
        want.used.discard("mujoco.mu")
        want.used.discard("friction.mu")
    torsional = rolling = None if loaded and not effects_set else 0.0
    if condim is not None and condim >= 4:
        torsional = e.torsional_mu if e.torsional_mu is not None else MUJOCO_DEFAULT_TORSIONAL
        want.used.add("effects.torsional_mu")
    if condim == 6:
        rolling = e.rolling_mu if e.rolling_mu is not None else MUJOCO_DEFAULT_ROLLING
        want.used.add("effects.rolling_mu")
    want.values.update(condim=condim, mu=mu, torsional=torsional, rolling=rolling)


def _generated_contacts(top: TopParams, stem: StemParams | None, condim: int,
                        friction: tuple[float, float, float], solref: tuple[float, ...],
                        solimp: tuple[float, ...]) -> tuple[ContactSetting, ...]:
    """The contacts :func:`~.mjcf.make_mjcf` writes: table, ball (and stem), all alike."""
    roles = [(TABLE_GEOM, "table"), (BALL_GEOM, "ball")]
    if stem is not None:
        roles.append((STEM_GEOM, "stem"))
    return tuple(ContactSetting("geom", _GENERATED_IDS[name], name, role, condim, friction,
                                solref, solimp, contype=1, conaffinity=1)
                 for name, role in roles)


def _full_solimp(solimp: tuple[float, ...]) -> tuple[float, ...]:
    """A solimp of 3 numbers completed with the default midpoint and power (MuJoCo's too)."""
    return tuple(solimp) + tuple(_DEFAULT.solimp[len(solimp):])


def _fitted_timestep(law: FrictionParams, limit: float | None, dt: float, scene: Scene,
                     loaded: bool) -> tuple[float, str | None]:
    """Paper mode's timestep: ``dt``, or below the law's ``limit``; and the note saying why.

    Raises:
        TippetopError: A step longer than the limit that is not to be fitted (the scene sets
            it itself, or ``mujoco.fit_paper_timestep`` is off).
    """
    if limit is None or dt <= limit:
        return dt, None
    own = scene.is_set("mujoco.timestep_s")
    if own or not scene.mujoco.fit_paper_timestep:
        raise TippetopError(
            f"mujoco.timestep_s: expected at most {limit:.3g} s for the paper's law on this "
            f"top (law {law.law}, mu {law.mu:g}: its slip relaxes in "
            f"{1e3 * limit / PAPER_LAW_MAX_DT_RATE:.3g} ms, and a longer step makes the "
            "force flip instead of relax; set mujoco.timestep_s"
            + ("" if own else ", or mujoco.fit_paper_timestep = true to run at the largest "
               "1-2-5 step below the limit") + f"), got {dt!r}")
    fitted = nice_step_below(limit)
    whose = "the file's" if loaded else "the scene's"
    return fitted, (f"ran at dt = {fitted:g} s, not {whose} {dt:g} s: the paper's law at "
                    f"mu = {law.mu:g} relaxes the slip in {1e3 * limit:.3g} ms on this top, "
                    "which a longer step cannot follow")


def _run_options(mj: MujocoOptions, w: dict[str, Any], top: TopParams,
                 file_top: FileTop | None) -> dict[str, Any]:
    """The options: the scene's, else the file's, else (a generated top) the scene's defaults."""
    noslip = mj.noslip_iterations
    if file_top is None:
        return {"timestep_s": w["timestep_s"], "integrator": w["integrator"],
                "cone": w["cone"], "impratio": w["impratio"],
                "noslip_iterations": GENERATED_NOSLIP_ITERATIONS if noslip is None else noslip,
                "gravity_mps2": (0.0, 0.0, -top.g_mps2),
                "iterations": 100 if mj.iterations is None else mj.iterations,
                "tolerance": 1e-8 if mj.tolerance is None else mj.tolerance}
    options = {key: (w[key] if w[key] is not None else getattr(file_top, key))
               for key in ("timestep_s", "integrator", "cone", "impratio")}
    options["noslip_iterations"] = file_top.noslip_iterations if noslip is None else noslip
    options["gravity_mps2"] = file_top.gravity_mps2
    options["iterations"] = file_top.iterations if mj.iterations is None else mj.iterations
    options["tolerance"] = file_top.tolerance if mj.tolerance is None else mj.tolerance
    return options


def _mujoco_plan(scene: Scene, top: TopParams, init: InitialState, keyframe: int | None,
                 friction: FrictionParams, stem: StemParams | None,
                 file_top: FileTop | None) -> tuple[MujocoPlan, set[str]]:
    mj = scene.mujoco
    loaded = file_top is not None
    # a loaded file runs its own friction unless the scene (or the mode) says otherwise
    friction_by = mj.friction if not loaded or scene.is_set("mujoco.friction") else "native"
    want = _Wanted(scene, loaded)
    law = None
    if friction_by == "paper":
        law = _paper_wanted(scene, friction, want)
    else:
        _native_wanted(scene, friction, want)
    w = want.values
    solref = None if w["solref"] is None else tuple(float(x) for x in w["solref"])
    # a solimp of three numbers: a generated top's midpoint and power are the defaults (as
    # MuJoCo's), a loaded file keeps its own
    solimp = None if w["solimp"] is None else tuple(float(x) for x in w["solimp"])
    options = _run_options(mj, w, top, file_top)
    if file_top is None:
        solimp = _full_solimp(solimp)
        coefficients = ((w["mu"], w["torsional"], w["rolling"]) if friction_by == "native"
                        else (0.0, 0.0, 0.0))
        contacts = _generated_contacts(top, stem, w["condim"], coefficients, solref, solimp)
        reach = generated_contact_reach_m(top, stem)
    else:
        stem_off = scene.effects.stem is False
        contacts = tuple(
            replace(c.with_values(condim=w["condim"], mu=w["mu"], torsional=w["torsional"],
                                  rolling=w["rolling"], solref=solref, solimp=solimp),
                    **({"contype": 0, "conaffinity": 0} if stem_off and c.role == "stem"
                       else {}))
            for c in file_top.contacts)
        reach = top.R_m + top.a_m if stem_off else file_top.contact_reach_m
    srf = mj.solreffriction if friction_by == "native" else None
    if srf is not None:
        want.used.add("mujoco.solreffriction")
        expect(options["cone"] == "elliptic", "mujoco.solreffriction",
               "an elliptic cone (mujoco.cone=elliptic): MuJoCo uses a pair's solreffriction "
               "only there", f"{list(srf)} in a {options['cone']} cone")
        contacts = with_friction_pairs(contacts, srf,
                                       0 if file_top is None else file_top.npair)
    # the timestep was checked where it came from: the scene, or the file
    limit = paper_max_timestep(law, top, reach) if law is not None else None
    dt, note = _fitted_timestep(law, limit, float(options["timestep_s"]), scene, loaded) \
        if law is not None else (float(options["timestep_s"]), None)
    options["timestep_s"] = dt
    options["contacts_on"] = (mj.contacts if file_top is None or scene.is_set("mujoco.contacts")
                              else file_top.contacts_on)
    check_samples(scene.run.t_end_s, scene.run.sample_dt_s if scene.run.sample_dt_s is not None
                  else default_sample_dt(scene.run.t_end_s))
    check_mujoco_steps(scene.run.t_end_s, dt)
    sample_dt, steps, n_intervals = sample_grid(scene.run.t_end_s, scene.run.sample_dt_s, dt)
    if file_top is None:
        contact = MjcfContact(
            friction_mode=friction_by, condim=w["condim"],
            mu=float(w["mu"] or 0.0) if friction_by == "native" else 0.0,
            torsional=float(w["torsional"] or 0.0), rolling=float(w["rolling"] or 0.0),
            solref=solref, solimp=solimp)
        option = MjcfOption(
            timestep_s=dt, integrator=options["integrator"], cone=options["cone"],
            impratio=options["impratio"], noslip_iterations=options["noslip_iterations"],
            iterations=int(options["iterations"]), tolerance=float(options["tolerance"]),
            contacts_on=bool(options["contacts_on"]))
        mjcf = make_mjcf(top, contact=contact, option=option, stem=stem)
        if srf is not None:
            root = mjcf_document.parse(mjcf)
            _add_new_pairs(root, contacts, 0)
            mjcf = mjcf_document.to_text(root)
        source, centre, quat = None, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)
    else:
        mjcf = _file_document(file_top, options, contacts)
        source = str(file_top.path)
        centre, quat = file_top.centre_body_m, file_top.paper_from_body_quat
    if keyframe is None:
        qpos, qvel = free_joint_start(top, init, np.array(quat), np.array(centre))
        start: dict[str, Any] = {"start_qpos": tuple(float(v) for v in qpos),
                                 "start_qvel": tuple(float(v) for v in qvel)}
    else:
        assert file_top is not None
        start = {"keyframe": keyframe,
                 "keyframe_name": file_top.keyframes[keyframe] or f"#{keyframe}"}
    plan = MujocoPlan(
        friction=friction_by, top=top, law=law, init=init, t_end_s=scene.run.t_end_s, timestep_s=dt,
        integrator=options["integrator"], cone=options["cone"],
        impratio=float(options["impratio"]),
        noslip_iterations=int(options["noslip_iterations"]),
        gravity_mps2=tuple(float(g) for g in options["gravity_mps2"]), contacts=contacts,
        sample_dt_s=sample_dt, steps_per_sample=steps, n_intervals=n_intervals, mjcf=mjcf,
        source=source, stem=stem, paper_max_timestep_s=limit,
        notes=() if note is None else (note,), iterations=int(options["iterations"]),
        tolerance=float(options["tolerance"]), contacts_on=bool(options["contacts_on"]),
        reference_law=friction, **start)
    return plan, want.used


def _file_document(file_top: FileTop, options: dict[str, Any],
                   contacts: tuple[ContactSetting, ...]) -> str:
    """The loaded file's document with the plan's options and contact settings written in."""
    root = mjcf_document.parse(file_top.text, str(file_top.path))
    folder = file_top.path.parent
    mjcf_document.inline_includes(root, folder)
    mjcf_document.absolute_asset_dirs(root, folder)
    fmt = mjcf_document.fmt
    option = {"timestep": fmt(options["timestep_s"]), "integrator": options["integrator"],
              "cone": options["cone"], "impratio": fmt(options["impratio"]),
              "noslip_iterations": str(int(options["noslip_iterations"])),
              "gravity": fmt(options["gravity_mps2"]),
              "iterations": str(int(options["iterations"])),
              "tolerance": fmt(options["tolerance"])}
    mjcf_document.write_flag(root, "contact",
                             "enable" if options["contacts_on"] else "disable")
    mjcf_document.write_values(
        root, option=option,
        geoms={c.index: c.to_attributes() for c in contacts if c.element == "geom"},
        pairs={c.index: c.to_attributes() for c in contacts
               if c.element == "pair" and c.index < file_top.npair},
        ngeom=file_top.ngeom, npair=file_top.npair)
    _add_new_pairs(root, contacts, file_top.npair)
    return mjcf_document.to_text(root)


def _add_new_pairs(root: Any, contacts: tuple[ContactSetting, ...], npair: int) -> None:
    """Write the plan's pairs from id ``npair`` on (the model's own come first) into ``root``."""
    mjcf_document.add_pairs(root, [(c.geoms[0], c.geoms[1], c.to_attributes())
                                   for c in contacts if c.element == "pair" and c.index >= npair])


# ---------------------------------------------------------------- the start
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
               "a file with named keyframes (this one has none)", scene.init_keyframe, names)
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


# ---------------------------------------------------------------- the one resolution
def resolve_plan(scene: Scene, engine: str | EngineSpec = "ode", mode: str | None = None, *,
                 file_top: FileTop | None = None) -> RunPlan:
    """The one resolution of a scene for an engine in a mode (its rules: docs/design.md).

    Args:
        scene: A validated scene.
        engine: The engine it runs on (``ode``, ``mujoco``, ``mujoco==3.3.7``, ``mjx`` ...):
            the reference's plan for ``ode``, MuJoCo's for every other.
        mode: How the contact force is made (:mod:`tippetop.models.modes`): its scene keys
            are set over the scene's. None: what the scene's own keys say
            (:func:`~tippetop.models.modes.scene_mode`).
        file_top: For a scene whose top is an MJCF file, what the file says
            (:func:`tippetop.mujoco_runner.state.file_top` reads it; this layer cannot).

    Raises:
        TippetopError: An unknown engine or mode, a mode the engine cannot run, or effects and
            settings the engine cannot run (one line).
    """
    spec = engine if isinstance(engine, EngineSpec) else parse_engine(engine)
    asked = scene.set_keys  # the user's --set keys: a mode's own keys are never "unused"
    if mode is None:
        mode = scene_mode(scene, spec.family)
    else:
        check_pair(spec.family, mode, spec.spec)
        scene = scene.with_overrides(list(MODES[mode].overrides(spec.family)))
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
    if spec.is_reference:
        ode, more = _ode_plan(scene, top, init, friction, stem)
    else:
        mujoco, more = _mujoco_plan(scene, top, init, keyframe, friction, stem, file_top)
    return RunPlan(scene=scene.name, engine=spec.spec, mode=mode, ode=ode, mujoco=mujoco,
                   unused=_unused(asked, used | more))


__all__ = ["PAPER_LAW_MAX_DT_RATE", "PAPER_SOLREF", "friction_keys",
           "generated_contact_reach_m", "native_condim", "nice_step_below",
           "paper_max_timestep", "resolve_plan"]
