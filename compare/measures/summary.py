"""A run's summary, typed, and what it says for a person and for a program.

:class:`RunSummary` is one run's summary: what it measured (each a metric of
:mod:`.metrics`), how it ended and what ran, read back from the engine (:data:`RAN_FIELDS`).
Frozen, as the plan is, with :meth:`~RunSummary.to_json` and :meth:`~RunSummary.from_json`;
it reads as a mapping of its JSON keys too (``summary["t_invert"]``), as the JSON does.

Whether a run finished (:func:`run_failed`), what ran in one line (:func:`describe_ran`), the
contact settings it ran as MJCF attributes (:func:`mjcf_attributes`) and as one block to paste
into its file, named with the file's own geoms (:func:`paste_block`), and the steps it took for
the cost model (:func:`measured_steps`). Nothing here starts a run.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from tippetop.models.contacts import ContactSetting, mix
from tippetop.models.engines import FAMILIES
from tippetop.models.errors import TippetopError
from tippetop.models.modes import LAW_MODES, run_label
from tippetop.models.numbers import number_text, solver_text
from tippetop.models.options import METHOD_TITLES, auto_text
from tippetop.models.plan import NATIVE_LAW

#: ``friction_law`` of a run on MuJoCo's own contact: today's, and the release before's.
NATIVE_LAWS = (NATIVE_LAW, "mujoco-native")

#: The summary keys of a failed run that would be numbers: a failed run reports none.
RESULT_KEYS = ("theta_final", "theta_asymp", "t_invert", "J_rel_drift", "energy_monotone",
               "energy_rise_rel")
#: The statuses of a run that ended as the physics says (the sphere leaving the table is an
#: end the model reports); any other status (MuJoCo's ``diverged``, the reference's
#: ``max_steps``, ``step_too_small``, ``singular``, ``chatter``, ``flat_end``) is a failed run.
FINISHED_STATUSES = ("ok", "contact_lost", "hop")


# ---------------------------------------------------------------- the typed summary
@dataclass(frozen=True)
class Phase:
    """A stretch of a run with the same contacts: ``ball``, ``stem``, ``both`` or ``none``."""

    contact: str
    t_start: float
    t_end: float

    def to_json(self) -> dict[str, Any]:
        """``{contact, t_start, t_end}``."""
        return {"contact": self.contact, "t_start": self.t_start, "t_end": self.t_end}


@dataclass(frozen=True)
class RanField:
    """One setting a run reports it ran with, read back from the engine (``what ran``).

    Attributes:
        name: The key (``timestep_s``).
        unit: Its unit (``s``, ``m``, ``relative`` ...) or ``""``.
        meaning: One sentence.
        engines: ``ode``, ``mujoco`` or both: whose runs report it.
    """

    name: str
    unit: str
    meaning: str
    engines: tuple[str, ...] = ("mujoco",)


#: What a run reports it ran with, read back from the engine (the order ``what ran`` lists it).
RAN_FIELDS: dict[str, RanField] = {f.name: f for f in (
    RanField("friction_law", "", "the friction law applied: the reference's (modified_coulomb, "
             "coulomb, viscous, coulomb_viscous, none), the law paper mode applies in MuJoCo, "
             f"or {NATIVE_LAW} (MuJoCo's own contact makes the friction)", FAMILIES),
    RanField("formulation", "", "the reference's equations: vector (regular at theta = 0 and "
             "pi) or paper (the paper's own variables)", ("ode",)),
    RanField("method", "", "the reference's integration method that ran, one of "
             + "; ".join(f"{m}: {t}" for m, t in METHOD_TITLES.items()) + ". "
             + auto_text()[0].upper() + auto_text()[1:], ("ode",)),
    RanField("rtol", "relative", "the reference integrator's relative tolerance", ("ode",)),
    RanField("atol", "", "the reference integrator's absolute tolerance, in each state "
             "variable's own unit", ("ode",)),
    RanField("stiff", "", "what ran for stiff friction: rolling (rolling phases where the law "
             "turns stiff), off, or none (why)", ("ode",)),
    RanField("law_mu", "", "the friction coefficient of the law paper mode applies"),
    RanField("timestep_s", "s", "MuJoCo's timestep"),
    RanField("integrator", "", "MuJoCo's integrator: Euler, implicit, implicitfast or RK4"),
    RanField("cone", "", "MuJoCo's friction cone: pyramidal or elliptic"),
    RanField("impratio", "", "MuJoCo's ratio of frictional to normal constraint impedance"),
    RanField("noslip_iterations", "", "MuJoCo's noslip solver iterations (0: off)"),
    RanField("condim", "", "the ball's contact dimensionality: 1 frictionless, 3 sliding, 4 "
             "with torsional, 6 with rolling friction"),
    RanField("mu", "", "the ball's contact's sliding friction coefficient, as MuJoCo mixed it"),
    RanField("torsional", "m", "the ball's contact's torsional friction coefficient"),
    RanField("rolling", "m", "the ball's contact's rolling friction coefficient"),
    RanField("solref", "", "the ball's contact's solref: time constant (s) and damping ratio, "
             "or (negative) stiffness and damping"),
    RanField("solreffriction", "", "the ball's contact's own solref of its friction rows, set "
             "only on an explicit contact pair (none: they use solref)"),
    RanField("solimp", "", "the ball's contact's solimp: d0, dwidth, width (m), midpoint, "
             "power"),
    RanField("gravity_mps2", "m/s^2", "the magnitude of gravity"),
    RanField("iterations", "", "MuJoCo's constraint solver's maximum iterations"),
    RanField("tolerance", "relative", "MuJoCo's constraint solver tolerance"),
    RanField("contacts", "", "whether contacts are on (off: the top falls freely)"),
    RanField("sample_dt_s", "s", "the spacing of the observables table's rows", FAMILIES),
    RanField("keyframe", "", "the keyframe of the file the run starts from (none: a state)"),
    RanField("implementation", "", "what stepped the run: mujoco (MuJoCo C), mjx or warp"),
    RanField("version", "", "the version of what stepped it (MuJoCo C's, mujoco-mjx's, "
             "mujoco-warp's)"),
    RanField("precision", "", "float64 or float32: the dtype of the engine's state"),
    RanField("device", "", "where it stepped (cpu)"),
    RanField("path", "", "how the steps were taken (the compiled stepper, a batch, a worker's "
             "loop, a captured graph ...)"),
    RanField("mujoco_c_version", "", "MuJoCo C's version beside an accelerated engine"),
    RanField("device_kind", "", "the accelerated engine's device kind"),
    RanField("contacts_from", "", "what an accelerated engine's windows read of its contacts "
             "and forces at each step (on the device, not MuJoCo C's mj_contactForce)"),
    RanField("warnings", "", "MuJoCo's warnings over the run"),
    RanField("law_applied", "", "how an accelerated engine applies paper mode's law"),
    RanField("note", "", "what an accelerated engine's run leaves out"),
)}

#: The keys of a run's summary in its JSON, in order, besides what ran (:data:`RAN_FIELDS`):
#: the results (each a metric of :mod:`.metrics`), then where and how the run ended.
SUMMARY_ORDER = ("engine", "mode", "theta_final", "theta_asymp", "t_invert", "J_rel_drift",
                 "energy_monotone", "energy_rise_rel", "contact_lost", "wall_s", "n_rhs",
                 "n_steps", "status", "message")
_AFTER_RAN = ("t_stem", "t_left_table", "flights", "phases", "rolling_phases", "stem",
              "max_penetration_m", "contact_energy_bound_J", "unused", "friction_realised")
#: Keys written only when the run has them (the reference's counters and rolling phases, MuJoCo's
#: counters and contact energy, a stem).
_OPTIONAL = ("n_rhs", "n_steps", "rolling_phases", "stem", "max_penetration_m",
             "contact_energy_bound_J", "flights")


@dataclass(frozen=True, eq=False)
class RunSummary(Mapping[str, Any]):
    """One run's summary: what it measured, how it ended and what ran, read back.

    Typed and frozen, as the plan is; :meth:`to_json` gives the JSON every command prints
    (``simulate --json``; its keys are a contract), :meth:`from_json` reads it back (a cache
    entry, a worker's reply) and says which key it does not know. It reads as the mapping of
    its JSON too (``s["t_invert"]``, ``s.get("n_steps")``, ``dict(s)``), and equals a mapping
    with the same keys and values.

    Attributes:
        engine: The engine the run ran on, as given (``mujoco==3.3.7``).
        mode: How the contact force was made (``native``).
        status: ``ok``, ``contact_lost`` or ``hop`` (the physics ended the run), else why it
            failed (``diverged``, ``max_steps`` ...).
        message: The same in words.
        theta_final: The tilt at the last sample (rad); None for a failed run.
        theta_asymp: The mean tilt over the run's last 10 % (rad).
        t_invert: The first time theta crosses pi/2 (s; MuJoCo's located to the step); None
            if never.
        J_rel_drift: Jellett's constant's largest relative change while the ball alone
            touches the table.
        energy_monotone: Whether E never rises beyond the integration's error.
        energy_rise_rel: E's largest rise above its running minimum, of E0.
        contact_lost: The reference stopped because the ball left the table.
        t_stem: The stem's first contact (s; MuJoCo's located to the step); None if never.
        t_left_table: The first time the ball leaves the table before the stem lands (s):
            the start of its first flight (:data:`~.series.HOP_MIN_S` or more without contact
            at any step, the ball risen :data:`~.series.FLIGHT_RISE_M`; shorter or lower
            stretches are its soft contact chattering) after the first 0.05 s; None if never
            (the reference: where it stopped because its ball left the table).
        flights: A MuJoCo run's stretches without contact before the stem lands, measured at
            every step, and its flights among them: ``{count, longest_s, airborne_s,
            t_first, height_m, hops, t_first_hop, longest_hop_s, hop_height_m, hop_min_s,
            rise_min_m, measured}`` (:func:`~.series.flights`); None: none (and for the
            reference, which stops at the first).
        wall_s: Wall time (s).
        n_rhs: The reference's right-hand-side evaluations.
        n_steps: MuJoCo's steps.
        max_penetration_m: MuJoCo's deepest penetration (m).
        contact_energy_bound_J: The most elastic energy MuJoCo's contacts held (J).
        ran: What ran, read back from the engine (keys of :data:`RAN_FIELDS`).
        phases: The contact phases.
        rolling_phases: The reference's rolling phases: ``{phases, t_s}``.
        stem: The stem the reference modelled: ``{kind, offset_m, radius_m}``.
        unused: ``--set`` keys the engine did not read.
        friction_realised: The friction law the run realised
            (:func:`~.friction_realised.friction_realised`), or None.
    """

    engine: str
    mode: str
    status: str = "ok"
    message: str = ""
    theta_final: float | None = None
    theta_asymp: float | None = None
    t_invert: float | None = None
    J_rel_drift: float | None = None
    energy_monotone: bool | None = None
    energy_rise_rel: float | None = None
    contact_lost: bool = False
    t_stem: float | None = None
    t_left_table: float | None = None
    flights: dict[str, Any] | None = None
    wall_s: float = 0.0
    n_rhs: int | None = None
    n_steps: int | None = None
    max_penetration_m: float | None = None
    contact_energy_bound_J: float | None = None
    ran: dict[str, Any] = field(default_factory=dict)
    phases: tuple[Phase, ...] = ()
    rolling_phases: dict[str, Any] | None = None
    stem: dict[str, Any] | None = None
    unused: tuple[str, ...] = ()
    friction_realised: dict[str, Any] | None = None
    _json: dict[str, Any] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_json", self.to_json())

    def __getitem__(self, key: str) -> Any:
        return self._json[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._json)

    def __len__(self) -> int:
        return len(self._json)

    def replace(self, **changes: Any) -> RunSummary:
        """A copy with ``changes`` (attributes, or keys of what ran)."""
        ran = {k: changes.pop(k) for k in list(changes) if k in RAN_FIELDS}
        data = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        data.update(changes)
        if ran:
            data["ran"] = {**self.ran, **ran}
        return RunSummary(**data)

    @property
    def failed(self) -> bool:
        """Whether the run failed (diverged, stopped short): it carries no numbers then."""
        return self.status not in FINISHED_STATUSES

    @property
    def is_reference(self) -> bool:
        """The reference ODE's run."""
        return self.engine == "ode"

    @property
    def label(self) -> str:
        """``ENGINE/MODE``."""
        return run_label(self.engine, self.mode)

    def setting(self, key: str, default: Any = None) -> Any:
        """What ran for ``key`` (:data:`RAN_FIELDS`), read back; ``default`` if not reported.

        Raises:
            KeyError: ``key`` is not a setting a run reports.
        """
        if key not in RAN_FIELDS:
            raise KeyError(f"{key!r} is not a setting a run reports (RAN_FIELDS)")
        return self.ran.get(key, default)

    def to_json(self) -> dict[str, Any]:
        """The summary as JSON-ready data, in :data:`SUMMARY_ORDER`, what ran, then the rest."""
        out: dict[str, Any] = {}
        for key in SUMMARY_ORDER:
            value = getattr(self, key)
            if key in _OPTIONAL and value is None:
                continue
            out[key] = value
        out.update({k: self.ran[k] for k in RAN_FIELDS if k in self.ran})
        for key in _AFTER_RAN:
            value = getattr(self, key)
            if key in _OPTIONAL and value is None:
                continue
            if key == "phases":
                value = [p.to_json() for p in value]
            elif key == "unused":
                value = list(value)
            out[key] = value
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RunSummary:
        """The summary :meth:`to_json` wrote (or the release before wrote: read as today's).

        The release before's summaries carried ``engine_spec`` beside an ``engine`` of
        ``mujoco`` (now the engine as given), the reference's rolling phases as ``rolling``
        (now ``rolling_phases``), and no mode for the reference (now its law's).

        Raises:
            TippetopError: Not a summary: a key it does not declare, or a missing engine.
        """
        d = dict(data)
        spec = d.pop("engine_spec", None)
        if spec not in (None, "mujoco", "ode") and d.get("engine") == "mujoco":
            d["engine"] = spec
        if isinstance(d.get("rolling"), dict):  # the reference's rolling phases, before
            d["rolling_phases"] = d.pop("rolling")
        if "mode" not in d:
            d["mode"] = LAW_MODES.get(str(d.get("friction_law")), "paper") \
                if d.get("engine") == "ode" else "paper"
        if d.get("friction_law") == "mujoco-native":
            d["friction_law"] = NATIVE_LAW
        names = {f.name for f in fields(cls) if f.init} - {"ran"}
        unknown = [k for k in d if k not in names and k not in RAN_FIELDS]
        if unknown or "engine" not in d:
            raise TippetopError(f"summary: expected the keys of a run's summary, got "
                                f"{', '.join(unknown) or 'no engine'}")
        kw = {k: d[k] for k in names if k in d}
        kw["phases"] = tuple(Phase(p["contact"], float(p["t_start"]), float(p["t_end"]))
                             for p in d.get("phases") or ())
        kw["unused"] = tuple(d.get("unused") or ())
        kw["ran"] = {k: d[k] for k in RAN_FIELDS if k in d}
        return cls(**kw)


def measured_steps(summaries: Iterable[dict[str, Any] | None],
                   spec: str = "mujoco") -> list[tuple[int, float]]:
    """``(n_steps, wall_s)`` of each finished MuJoCo run on the engine ``spec``.

    The runs of that engine only (a summary's ``engine``): each engine's steps cost what it
    does. For the cost model (:func:`tippetop.compare.running.cost.record_mujoco_runs`).
    """
    return [(int(s["n_steps"]), float(s["wall_s"])) for s in summaries
            if s is not None and s.get("engine") == spec and s.get("status") == "ok"
            and s.get("n_steps") and s.get("wall_s")]


def run_failed(summary: dict[str, Any]) -> bool:
    """Whether a run's summary is a failed run's (it carries no numbers, only the reason)."""
    return summary.get("status", "ok") not in FINISHED_STATUSES


def describe_ran(summary: dict[str, Any]) -> str:
    """One line on what a run's summary says ran (the settings read back, not those asked for).

    Example: ``MuJoCo RK4 at dt = 2e-4 s, native friction: pyramidal cone, condim 3,
    mu 0.106, impratio 1.03, solref [0.00144 s, 1], solimp [0.054, 0.95, 0.001 m, 0.5, 2]``
    (solref's time constant and solimp's width carry their units; with a negative solref,
    MuJoCo's stiffness and damping, none).
    """
    if summary.get("engine") == "ode":
        method = summary.get("method") or "(method not recorded)"
        return (f"reference ODE, {method} on the {summary.get('formulation')} formulation at "
                f"rtol {number_text(summary.get('rtol'))}, law {summary.get('friction_law')}")
    if summary.get("timestep_s") is None:
        return "MuJoCo (no settings recorded)"
    head = f"MuJoCo {summary.get('integrator')} at dt = {number_text(summary['timestep_s'], 's')}, "
    solref, solimp = (f"{k} [{solver_text(k, summary[k])}]" if summary.get(k) is not None
                      else f"{k} -" for k in ("solref", "solimp"))
    contact = f"condim {summary.get('condim')}, {solref}, {solimp}"
    law = summary.get("friction_law")
    native = law in NATIVE_LAWS or (law is None and summary.get("mode") != "paper")
    if not native:
        mu = summary.get("law_mu")
        applied = f"the paper-mode law {law}" + (f" (mu {number_text(mu)})" if mu is not None
                                                 else "")
        return f"{head}{applied} on a frictionless contact: {contact}"
    friction = [f"{summary.get('cone')} cone", f"condim {summary.get('condim')}"]
    for key, unit in (("mu", ""), ("torsional", "m"), ("rolling", "m")):
        if summary.get(key) is not None:
            friction.append(f"{key} {number_text(summary[key], unit if summary[key] else '')}")
    friction.append(f"impratio {number_text(summary.get('impratio'))}")
    friction.append(solref)
    if summary.get("solreffriction") is not None:
        srf = solver_text("solreffriction", summary["solreffriction"])
        friction.append(f"solreffriction [{srf}]")
    friction.append(solimp)
    return f"{head}native friction: " + ", ".join(friction)


def mjcf_attributes(summary: dict[str, Any]) -> tuple[str, str]:
    """The contact settings a MuJoCo run ran, as MJCF to paste.

    Returns:
        The ``<option .../>`` element (timestep, integrator, cone, impratio) and the contact's
        attributes (condim, friction with its torsional and rolling parts, solref, solimp),
        read from the run's summary.
    """
    s = summary
    return ((f'<option timestep="{s["timestep_s"]:g}" integrator="{s["integrator"]}" '
             f'cone="{s["cone"]}" impratio="{s["impratio"]:g}"/>'),
            (f'condim="{s.get("condim", 3)}" friction="{_nums(_coefficients(s))}" '
             f'solref="{_nums(s["solref"])}" solimp="{_nums(s["solimp"])}"'))


def _nums(v: Any) -> str:
    """Numbers as an MJCF attribute's value."""
    return " ".join(f"{x:g}" for x in v)


def _coefficients(s: dict[str, Any]) -> list[float]:
    """A run's (sliding, torsional, rolling) friction, MuJoCo's defaults where none acted."""
    return [s.get("mu") or 0.0, s.get("torsional") or 0.005, s.get("rolling") or 0.0001]


def mjcf_pair(summary: dict[str, Any]) -> str | None:
    """The contact pair of tippetop's own top where the run had its own solreffriction.

    MuJoCo takes ``solreffriction`` only on an explicit ``<pair>``: the ball's with the table,
    with the contact's own values (a generated top names its geoms ball, stem and table; a
    file's block names its own: :func:`paste_block`). None without one.
    """
    s = summary
    if s.get("solreffriction") is None:
        return None
    mu, tor, rol = _coefficients(s)
    return ("<contact>\n"
            f'  <pair geom1="{GENERATED_NAMES["ball"]}" geom2="{GENERATED_NAMES["table"]}" '
            f'condim="{s.get("condim", 3)}" friction="{_nums([mu, mu, tor, rol, rol])}"\n'
            f'        solref="{_nums(s["solref"])}" solimp="{_nums(s["solimp"])}" '
            f'solreffriction="{_nums(s["solreffriction"])}"/>\n'
            "</contact>")


# ---------------------------------------------------------------- the block to paste
#: The geom names of the top tippetop generates (models/mjcf.py), by role.
GENERATED_NAMES = {"ball": "ball", "stem": "stem", "table": "table"}
#: MuJoCo's geom types, by their number (``mjtGeom``), to say which geom has no name.
_GEOM_TYPES = ("plane", "hfield", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh",
               "sdf")


@dataclass(frozen=True)
class FileContacts:
    """A file's contacts as the block to paste names them (:func:`paste_block`).

    Attributes:
        contacts: The file's contact settings as a run plan reads them (its colliding geoms
            of the top and of the table, and its pairs of the top; :mod:`models.contacts`).
        geom_names: Every geom's name by id, ``""`` where it has none.
        geom_places: Every geom by id, in words a reader finds it by (``the plane, the 1st
            geom of <worldbody>``).
        geom_margins: Every geom's (margin, gap) by id (m).
        pair_margins: Every pair's (margin, gap) by id (m).
    """

    contacts: tuple[ContactSetting, ...]
    geom_names: tuple[str, ...]
    geom_places: tuple[str, ...]
    geom_margins: tuple[tuple[float, float], ...]
    pair_margins: tuple[tuple[float, float], ...] = ()

    @classmethod
    def of_model(cls, model: Any, contacts: Iterable[ContactSetting]) -> FileContacts:
        """Read from a compiled ``mujoco.MjModel`` and the plan's contacts of it."""
        def num(v: Any) -> tuple[float, float]:
            return float(v[0]), float(v[1])

        def place(g: int) -> str:
            t = int(model.geom_type[g])
            kind = _GEOM_TYPES[t] if 0 <= t < len(_GEOM_TYPES) else "geom"
            b = int(model.geom_bodyid[g])
            body = "<worldbody>" if b == 0 else f"body {model.body(b).name or '#' + str(b)}"
            return f"the {kind}, the {_ordinal(g - int(model.body_geomadr[b]) + 1)} geom of {body}"

        return cls(tuple(contacts),
                   tuple(model.geom(g).name for g in range(model.ngeom)),
                   tuple(place(g) for g in range(model.ngeom)),
                   tuple(num(v) for v in zip(model.geom_margin, model.geom_gap, strict=True)),
                   tuple(num(v) for v in zip(model.pair_margin, model.pair_gap, strict=True)))


@dataclass(frozen=True)
class PastePair:
    """One ``<pair>`` of the block: two geoms (ids) and the contact's values as they ran.

    ``replaces``: the file has its own pair of these geoms, which this one replaces.
    """

    geom1: int
    geom2: int
    condim: int
    friction: tuple[float, ...]
    solref: tuple[float, ...]
    solimp: tuple[float, ...]
    solreffriction: tuple[float, ...] = ()
    margin: float = 0.0
    gap: float = 0.0
    replaces: bool = False


def _collide(a: ContactSetting, b: ContactSetting) -> bool:
    """Whether MuJoCo's contact filter lets geoms ``a`` and ``b`` collide."""
    return bool(a.contype & b.conaffinity or b.contype & a.conaffinity)


def paste_pairs(ran: Mapping[str, Any], contacts: FileContacts, *,
                keeps_dims: bool = True) -> list[PastePair]:
    """Every contact of the top with the table as the run had it, one pair each.

    The run wrote its contact settings on every contact setting of the file (each colliding
    geom of the top and of the table, each pair of the top: ``ContactSetting.with_values``,
    as the plan does) and MuJoCo made each contact from them (:func:`~models.contacts.mix`)
    or took a pair's. Here the same, from the values the run read back (``ran``: mu, solref,
    solimp; with ``keeps_dims`` False condim, torsional and rolling too): the file's own pairs
    of the top first (in their order, each with its margin and gap), then one for each geom
    of the top and each table geom it can collide with that no pair covers (in geom order,
    the geoms' larger margin and gap, as MuJoCo's dynamic contact has them; none where the
    run set a solreffriction, whose pairs the plan writes without), as MuJoCo orders its
    contacts. A pair supersedes the two geoms' own contact, so with these pairs the contacts
    are the run's whatever the geoms say.

    Args:
        ran: The run's summary (what ran, read back: the ball's contact with the table).
        contacts: The file's contacts.
        keeps_dims: The run kept each geom's own condim, torsional and rolling friction (the
            tuning's candidates set mu, solref and solimp only); False: it set them on every
            geom (validate's calibrated run).
    """
    values: dict[str, Any] = {"mu": ran.get("mu"), "solref": ran.get("solref"),
                              "solimp": ran.get("solimp")}
    if not keeps_dims:
        values.update(condim=ran.get("condim"), torsional=ran.get("torsional") or 0.0,
                      rolling=ran.get("rolling") or 0.0)
    srf = tuple(float(v) for v in ran.get("solreffriction") or ())
    own = [c for c in contacts.contacts if c.element == "pair"]
    ball = next((c for c in contacts.contacts if c.role == "ball"), None)
    ball_pair = next((p for p in own if ball is not None and ball.index in p.geoms), None)
    # the run's solreffriction is its own (on every contact of the top) unless it is the
    # ball's pair's in the file, which the run kept
    srf_set = bool(srf) and (ball_pair is None or ball_pair.solreffriction != srf)
    margins = contacts.pair_margins
    table_ids = {c.index for c in contacts.contacts if c.role == "table"}
    out = []
    for p in own:
        q = p.with_values(**values)
        margin, gap = margins[p.index] if p.index < len(margins) else (0.0, 0.0)
        # the top's geom first, as the file's pairs are written (MuJoCo orders them itself)
        first, second = p.geoms if p.geoms[0] not in table_ids else p.geoms[::-1]
        out.append(PastePair(first, second, q.condim, q.friction, q.solref, q.solimp,
                             srf if srf_set else p.solreffriction, margin, gap, replaces=True))
    covered = {frozenset(p.geoms) for p in own}
    geoms = [c.with_values(**values) for c in contacts.contacts if c.element == "geom"]
    tables = [t for t in geoms if t.role == "table"]
    gm = contacts.geom_margins
    for g in geoms:
        if g.role not in ("ball", "stem") or not g.collides:
            continue
        for t in tables:
            if not _collide(g, t) or frozenset((g.index, t.index)) in covered:
                continue
            m = mix(t, g)
            # a dynamic contact's margin and gap are the geoms' larger; the pairs a run makes
            # for its solreffriction (models.contacts.with_friction_pairs) have none
            margin, gap = ((0.0, 0.0) if srf_set else
                           (max(gm[g.index][0], gm[t.index][0]),
                            max(gm[g.index][1], gm[t.index][1])))
            out.append(PastePair(g.index, t.index, m.condim, m.friction, m.solref, m.solimp,
                                 srf if srf_set else (), margin, gap))
    return out


def _exact(x: float) -> str:
    """A number as MJCF text that reads back as the same double (short where it can be)."""
    short = f"{float(x):g}"
    return short if float(short) == float(x) else repr(float(x))


def _exacts(v: Iterable[float]) -> str:
    return " ".join(_exact(x) for x in v)


def paste_option(ran: Mapping[str, Any]) -> str:
    """The run's ``<option>`` (timestep, integrator, cone, impratio), its numbers exact.

    Pasted beside the file's own, a second ``<option>`` sets only the attributes it names.
    """
    return (f'<option timestep="{_exact(ran["timestep_s"])}" integrator="{ran["integrator"]}" '
            f'cone="{ran["cone"]}" impratio="{_exact(ran["impratio"])}"/>')


def _names(contacts: FileContacts, pairs: list[PastePair]) -> tuple[dict[int, str], list[str]]:
    """The name of each geom of ``pairs``; a name for each unnamed one, and the line saying so."""
    roles = {c.index: c.role for c in contacts.contacts if c.element == "geom"}
    taken = set(contacts.geom_names)
    names: dict[int, str] = {}
    said = []
    for g in dict.fromkeys(i for p in pairs for i in (p.geom1, p.geom2)):
        name = contacts.geom_names[g] if g < len(contacts.geom_names) else ""
        if not name:
            role = roles.get(g, "geom")
            base = GENERATED_NAMES.get(role, "geom")
            name, k = base, 1
            while name in taken:
                k += 1
                name = f"{base}{k}"
            taken.add(name)
            where = contacts.geom_places[g] if g < len(contacts.geom_places) else f"geom #{g}"
            said.append(f'add name="{name}" to the {role}\'s geom ({where})')
        names[g] = name
    return names, said


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def paste_block(ran: Mapping[str, Any], contacts: FileContacts | None, *,
                keeps_dims: bool = True) -> str:
    """The settings a MuJoCo run ran, as one MJCF block to paste into its file as it is.

    For a file (``contacts``): a comment, the run's ``<option>`` (:func:`paste_option`) and a
    ``<contact>`` with one ``<pair>`` for each contact of the top with the table, named with
    the file's geoms and carrying the values the run had (:func:`paste_pairs`, every number
    exact): pasted inside the file's ``<mujoco>``, the model steps as the run did. A comment
    line says which of the file's own pairs the block replaces (to be removed: two pairs of
    the same geoms make two contacts), and one which unnamed geoms need the name the pairs
    give them. For a top tippetop generated (``contacts`` None): the option, the contact's
    attributes for the geoms and the line saying which geoms take them. ``""`` for a run
    that recorded no settings.
    """
    if ran.get("timestep_s") is None:
        return ""
    option = paste_option(ran)
    if contacts is None:
        _, geom = mjcf_attributes(dict(ran))
        pair = mjcf_pair(dict(ran))
        return "\n".join([
            "<!-- no file was read: tippetop's own top names its geoms ball, stem and table; "
            "in a file, the geom attributes go on its geoms that touch the table and on the "
            "table's, and a pair names its own -->",
            option, f"<geom ... {geom}/>", *([pair] if pair else [])])
    pairs = paste_pairs(ran, contacts, keeps_dims=keeps_dims)
    names, unnamed = _names(contacts, pairs)
    lines = ["<!-- tippetop: paste inside <mujoco>; this option sets only what it names, and each "
             "pair is one contact of the top with the table as it ran -->", option]
    replaced = [f"{names[p.geom1]} and {names[p.geom2]}" for p in pairs if p.replaces]
    if replaced:
        them = "them" if len(replaced) > 1 else "it"
        lines.append(f"<!-- remove the file's own pair{'s' if len(replaced) > 1 else ''} of "
                     f"{', of '.join(replaced)}: the pairs below replace {them} (two pairs of "
                     "the same geoms make two contacts) -->")
    if unnamed:
        lines.append(f"<!-- unnamed geoms: {'; '.join(unnamed)}: the pairs below name them "
                     "so -->")
    if not pairs:
        lines.append("<!-- no geom of the top can touch the table: no pair -->")
        return "\n".join(lines)
    lines.append("<contact>")
    for p in pairs:
        mu = p.friction
        extra = (f' solreffriction="{_exacts(p.solreffriction)}"' if p.solreffriction else "")
        if p.margin or p.gap:
            extra += f' margin="{_exact(p.margin)}" gap="{_exact(p.gap)}"'
        lines.append(f'  <pair geom1="{names[p.geom1]}" geom2="{names[p.geom2]}" '
                     f'condim="{p.condim}" friction="{_exacts(mu)}"')
        lines.append(f'        solref="{_exacts(p.solref)}" solimp="{_exacts(p.solimp)}"'
                     f"{extra}/>")
    lines.append("</contact>")
    return "\n".join(lines)


__all__ = ["FINISHED_STATUSES", "GENERATED_NAMES", "NATIVE_LAWS", "RESULT_KEYS", "FileContacts",
           "PastePair", "describe_ran", "measured_steps", "mjcf_attributes", "mjcf_pair",
           "paste_block", "paste_option", "paste_pairs", "run_failed"]
