"""Scene files: what to simulate, and nothing more.

One TOML file names the top, the table's friction, the effects that are on, the initial state,
the run and the outputs wanted; :func:`load_scene` reads and validates it (with ``--set``
overrides) into a :class:`Scene`. :data:`SCHEMA` lists every key with its type; docs/scenes.md
says what each one means, with its unit and default, and shows an example file.
"""

from __future__ import annotations

import hashlib
import json
import sys
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tippetop.models.errors import TippetopError, closest_name, did_you_mean, expect
from tippetop.models.options import MujocoOptions, OdeOptions
from tippetop.models.params import (
    DEFAULT_STEM_OFFSET_R,
    DEFAULT_STEM_RADIUS_R,
    FrictionParams,
    InitialState,
    StemParams,
    TopParams,
)
from tippetop.models.resources import data_path

SCENES_DIR = data_path("tippetop.models", "scenes")

_F, _I, _S, _B, _L = "float", "int", "str", "bool", "list"

#: section -> key -> type. The contract for scene files and ``--set`` keys.
SCHEMA: dict[str, dict[str, str]] = {
    "scene": {"name": _S, "description": _S, "source": _S},
    "top": {"A_over_C": _F, "a_over_R": _F, "C_factor": _F, "R_m": _F, "M_kg": _F,
            "g_mps2": _F, "mjcf": _S},
    "friction": {"law": _S, "mu": _F, "Lambda_mps": _F, "viscous_Nspm": _F,
                 "coulomb_v_eps_mps": _F},
    "stem": {"kind": _S, "offset_m": _F, "radius_m": _F},
    "effects": {"sliding": _B, "torsional": _B, "rolling": _B, "stem": _B, "torsional_mu": _F,
                "rolling_mu": _F},
    "init": {"theta0": _F, "thetadot0": _F, "Omega0": _F, "n0": _F, "uOX": _F, "uOY": _F,
             "keyframe": _S},
    "run": {"t_end_s": _F, "sample_dt_s": _F},
    "ode": {"formulation": _S, "rtol": _F, "atol": _F, "max_steps": _I, "singular_sin": _F,
            "method": _S},
    "mujoco": {"friction": _S, "timestep_s": _F, "integrator": _S, "cone": _S, "condim": _I,
               "mu": _F, "solref": _L, "solimp": _L, "impratio": _F, "noslip_iterations": _I,
               "calibrated": _B, "fit_paper_timestep": _B, "iterations": _I, "tolerance": _F,
               "contacts": _B, "solreffriction": _L},
    "outputs": {"table": _S, "summary": _B},
    "expect": {"outcome": _S, "theta_asymp": _F, "theta_asymp_tol": _F, "t_invert_max_s": _F,
               "note": _S},
}

OUTCOMES = ("upright", "intermediate", "inverted")
DEFAULT_T_END_S = 8.0  # (s) long enough for the paper's Fig. 3 top to invert


@dataclass(frozen=True)
class Effects:
    """Contact effects a scene switches on. Only these are simulated.

    Attributes:
        sliding: Sliding friction at the contact point (both engines).
        torsional: Torsional friction about the contact normal (MuJoCo, condim 4).
        rolling: Rolling friction (MuJoCo, condim 6).
        stem: The stem's end is a second contact surface (both engines): the top can turn
            over onto it. Off: the paper's loaded sphere. None: off, except for a top loaded
            from an MJCF file, which has a stem when its file does.
        torsional_mu: MuJoCo torsional coefficient (m); None keeps MuJoCo's default.
        rolling_mu: MuJoCo rolling coefficient (m); None keeps MuJoCo's default.
    """

    sliding: bool = True
    torsional: bool = False
    rolling: bool = False
    stem: bool | None = None
    torsional_mu: float | None = None
    rolling_mu: float | None = None


@dataclass(frozen=True)
class RunSpec:
    """Length and sampling of a run.

    Attributes:
        t_end_s: Simulated time (s).
        sample_dt_s: Row spacing of the observables table (s); None picks 1 ms, coarser for long
            runs (at most 20,000 rows).
    """

    t_end_s: float = DEFAULT_T_END_S
    sample_dt_s: float | None = None

    def __post_init__(self) -> None:
        expect(_is_num(self.t_end_s) and self.t_end_s > 0, "run.t_end_s", "a finite number > 0",
               self.t_end_s)
        expect(self.sample_dt_s is None or (_is_num(self.sample_dt_s) and self.sample_dt_s > 0),
               "run.sample_dt_s", "a finite number > 0", self.sample_dt_s)


@dataclass(frozen=True)
class Outputs:
    """What a run writes. Nothing is written that is not named.

    Attributes:
        table: Path of the observables table (.csv or .parquet), relative to the scene file.
        summary: Print the summary JSON.
    """

    table: str | None = None
    summary: bool = True


@dataclass(frozen=True)
class Scene:
    """A validated scene."""

    name: str
    description: str
    source: str
    top: TopParams
    friction: FrictionParams
    effects: Effects
    init: InitialState
    run: RunSpec
    ode: OdeOptions
    mujoco: MujocoOptions
    outputs: Outputs
    expect: dict[str, Any]
    raw: dict[str, dict[str, Any]] = field(repr=False)
    path: Path | None = None
    top_mjcf: Path | None = None
    set_keys: tuple[str, ...] = ()
    stem: StemParams | None = None
    init_keyframe: str | None = None

    def content_hash(self) -> str:
        """A hash of everything that defines the run (for caches), not of names or paths."""
        keep = {k: v for k, v in self.raw.items() if k not in ("scene", "outputs", "expect")}
        text = json.dumps(keep, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def is_set(self, key: str) -> bool:
        """Whether ``section.key`` was given (in the file or by ``--set``), not defaulted."""
        section, name = key.split(".", 1)
        return name in self.raw.get(section, {})

    def with_overrides(self, overrides: Sequence[str | Override]) -> Scene:
        """This scene with more overrides (values or ``--set`` text), validated as at load."""
        data = {k: dict(v) for k, v in self.raw.items()}
        keys = [*self.set_keys, *_apply(data, overrides)]
        return scene_from_dict(data, path=self.path, set_keys=tuple(dict.fromkeys(keys)))


def _is_num(v: object) -> bool:
    """A finite number a float can hold (an int like 10**400 is not one)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) \
        and -sys.float_info.max <= v <= sys.float_info.max


def _check_type(key: str, kind: str, value: Any) -> Any:
    if kind == _F:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        expect(ok, key, "a number", value)
        # an int too large for a float: say so here, not as float()'s OverflowError
        expect(not isinstance(value, int) or _is_num(value), key,
               "a number a float can hold (|x| <= 1.8e308)", value)
        return float(value)
    if kind == _I:
        expect(isinstance(value, int) and not isinstance(value, bool), key, "an integer", value)
        # every integer key reaches compiled code or MuJoCo as a signed 64-bit integer
        expect(-2**63 <= value < 2**63, key, "an integer within 64 bits (|n| < 9.2e18)",
               value)
        return value
    if kind == _S:
        expect(isinstance(value, str), key, "a string", value)
        return value
    if kind == _B:
        expect(isinstance(value, bool), key, "true or false", value)
        return value
    expect(isinstance(value, list) and all(_is_num(v) for v in value), key,
           "a list of numbers", value)
    return [float(v) for v in value]


def _validate_raw(raw: dict[str, Any], origin: str) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for section, body in raw.items():
        if section not in SCHEMA:
            raise TippetopError(
                f"{origin}: unknown section [{section}]{did_you_mean(section, SCHEMA)} "
                f"(expected one of: {', '.join(SCHEMA)})")
        if not isinstance(body, dict):
            raise TippetopError(f"{origin}: [{section}] must be a table, got {body!r}")
        out[section] = {}
        for key, value in body.items():
            if key not in SCHEMA[section]:
                raise unknown_key_error(origin, f"{section}.{key}")
            out[section][key] = _check_type(f"{section}.{key}", SCHEMA[section][key], value)
    return out


def scene_keys(section: str | None = None) -> list[str]:
    """Every ``section.key`` name of :data:`SCHEMA`, or those of one section."""
    return [f"{s}.{k}" for s in SCHEMA for k in SCHEMA[s] if section in (None, s)]


def unknown_key_error(origin: str, key: str) -> TippetopError:
    """The error for a ``section.key`` that :data:`SCHEMA` does not have (one line).

    It names the key meant when one is close (:func:`~.errors.did_you_mean`), then the keys
    of the section given (or of the section of the key meant); the whole list of keys only when
    neither is known. ``[scene]`` and ``[expect]``, which no run reads, are left out of that
    list, not out of the keys suggested.
    """
    meant = closest_name(key, scene_keys())
    section = key.partition(".")[0]
    if section not in SCHEMA and meant is not None:
        section = meant.partition(".")[0]
    hint = f" (did you mean {meant!r}?)" if meant is not None else ""
    if section in SCHEMA:
        known = f"one of the [{section}] keys: {', '.join(scene_keys(section))}"
    else:
        known = "one of: " + ", ".join(k for k in scene_keys()
                                       if not k.startswith(("scene.", "expect.")))
    return TippetopError(f"{origin}: unknown key {key!r}{hint} (expected {known})")


def parse_override(item: str) -> tuple[str, str, Any]:
    """Parse ``section.key=value``; the value is read as TOML, else taken as a bare string."""
    if "=" not in item:
        raise TippetopError(f"--set: expected KEY=VALUE (e.g. init.n0=60), got {item!r}")
    key, text = item.split("=", 1)
    key = key.strip()
    if key.count(".") != 1:
        raise TippetopError(f"--set: expected a key of the form section.key, got {key!r}"
                            f"{did_you_mean(key, scene_keys())}")
    section, name = key.split(".")
    if section not in SCHEMA or name not in SCHEMA[section]:
        raise unknown_key_error("--set", key)
    text = text.strip()
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except ValueError:  # not TOML (a bare word), or an integer of over 4300 digits
        value = text
    if SCHEMA[section][name] == _S and not isinstance(value, str):
        value = text
    return section, name, value


def _toml_text(value: Any) -> str:
    """A value as TOML text that reads back to the same value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_text(v) for v in value) + "]"
    return repr(value)


@dataclass(frozen=True)
class Override:
    """One scene setting as a value: ``section.key`` and what it is set to.

    Studies build overrides from numbers (``Override.of("top.A_over_C", 1.2)``) and pass them
    down; ``--set`` text is parsed once, at the command line, into the same value
    (:meth:`parse`). :meth:`text` is the ``--set`` form, for commands a user can paste. A list
    value is held as a tuple (the override is hashable, as a :class:`Task` is).

    Attributes:
        section: The scene file's section (``top``, ``init``, ``mujoco``, ...).
        key: The key within it.
        value: The value, not yet type-checked (:func:`load_scene` checks it).
    """

    section: str
    key: str
    value: Any

    def __post_init__(self) -> None:
        """Check the key against :data:`SCHEMA`; hold a list as a tuple."""
        if self.section not in SCHEMA or self.key not in SCHEMA[self.section]:
            raise unknown_key_error("override", f"{self.section}.{self.key}")
        if isinstance(self.value, list):
            object.__setattr__(self, "value", tuple(self.value))

    @classmethod
    def of(cls, name: str, value: Any) -> Override:
        """The override of ``section.key`` to ``value``."""
        section, _, key = name.partition(".")
        return cls(section, key, value)

    @classmethod
    def parse(cls, item: str) -> Override:
        """``section.key=value`` text (``--set``), read as :func:`parse_override` reads it."""
        return cls(*parse_override(item))

    @property
    def name(self) -> str:
        """``section.key``."""
        return f"{self.section}.{self.key}"

    def text(self) -> str:
        """The ``--set`` text that gives this override."""
        return f"{self.name}={_toml_text(self.value)}"


def as_override(item: str | Override) -> Override:
    """An override given as a value or as ``--set`` text, as a value."""
    return item if isinstance(item, Override) else Override.parse(item)


def override_texts(items: Sequence[str | Override]) -> list[str]:
    """Overrides as ``--set`` text, for a command a user can paste or a JSON file."""
    return [i.text() if isinstance(i, Override) else i for i in items]


def _apply(data: dict[str, dict[str, Any]], overrides: Sequence[str | Override]) -> list[str]:
    """Apply overrides to a scene's sections, type-checked; the keys they set, in order."""
    keys = []
    for item in overrides:
        o = as_override(item)
        value = list(o.value) if isinstance(o.value, tuple) else o.value
        data.setdefault(o.section, {})[o.key] = _check_type(o.name, SCHEMA[o.section][o.key],
                                                            value)
        keys.append(o.name)
    return keys


def read_scene_file(path: str | Path) -> dict[str, Any]:
    """Read a scene TOML file into a dictionary (no validation)."""
    p = Path(path)
    if not p.is_file():
        raise TippetopError(f"scene: expected an existing .toml file, got {str(path)!r}")
    try:
        with p.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        msg = f"scene {p.name}: expected valid TOML, got a parse error: {exc}"
        raise TippetopError(msg) from None
    except UnicodeDecodeError:
        msg = f"scene {p.name}: expected a UTF-8 TOML text file, got binary data"
        raise TippetopError(msg) from None
    except ValueError as exc:  # Python's limit on an integer's digits (4300)
        raise TippetopError(f"scene {p.name}: expected numbers Python can read, got: "
                            f"{exc}") from None


def resolve_scene_path(name_or_path: str) -> Path:
    """A scene file path, or the name of a catalogue scene (``fig3`` -> models/scenes/fig3.toml)."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return p
    cand = SCENES_DIR / f"{name_or_path}.toml"
    if cand.is_file():
        return cand
    names = catalogue_names()
    raise TippetopError(
        f"scene: expected a .toml file or a catalogue name ({', '.join(names)}), got "
        f"{name_or_path!r}{did_you_mean(name_or_path, names)}")


def catalogue_names() -> list[str]:
    """Names of the scenes shipped in ``models/scenes``."""
    return sorted(p.stem for p in SCENES_DIR.glob("*.toml"))


def load_scene(path: str | Path | None = None,
               overrides: Sequence[str | Override] | None = None) -> Scene:
    """Load and validate a scene file (or the default scene), with ``--set`` overrides.

    Args:
        path: A scene file, a catalogue name, or None for the paper's default top and start.
        overrides: Overrides (values, or ``section.key=value`` text) applied before
            validation.
    """
    if path is None:
        raw: dict[str, Any] = {}
        origin = "default scene"
        file_path = None
    else:
        file_path = resolve_scene_path(str(path))
        raw = read_scene_file(file_path)
        origin = f"scene {file_path.name}"
    data = _validate_raw(raw, origin)
    keys = _apply(data, overrides or [])
    return scene_from_dict(data, path=file_path, set_keys=tuple(dict.fromkeys(keys)))


def scene_from_dict(data: dict[str, dict[str, Any]], path: Path | None = None,
                    set_keys: tuple[str, ...] = ()) -> Scene:
    """Build a :class:`Scene` from an already type-checked dictionary.

    Args:
        data: section -> key -> value, type-checked against :data:`SCHEMA`.
        path: The scene file (relative ``top.mjcf`` paths are relative to its folder).
        set_keys: The ``section.key`` names given by ``--set`` (reported when unused).
    """
    sec = {s: dict(data.get(s, {})) for s in SCHEMA}
    meta = sec["scene"]
    top_d = sec["top"]
    mjcf = top_d.pop("mjcf", None)
    top_mjcf = None
    if mjcf is not None:
        top_mjcf = Path(mjcf) if path is None or Path(mjcf).is_absolute() else path.parent / mjcf
    top = TopParams.from_ratios(**top_d)
    friction = FrictionParams(**sec["friction"])
    effects = Effects(**sec["effects"])
    keyframe = sec["init"].pop("keyframe", None)
    if keyframe is not None:
        expect(top_mjcf is not None, "init.keyframe",
               "a top loaded from an MJCF file (top.mjcf or --mjcf), whose keyframe it names",
               keyframe)
    init = InitialState(**sec["init"])
    run = RunSpec(**sec["run"])
    ode = OdeOptions(**sec["ode"])
    mj = sec["mujoco"]
    for k in ("solref", "solimp", "solreffriction"):
        if mj.get(k) is not None:
            mj[k] = tuple(mj[k])
    mujoco = MujocoOptions(**mj)
    st = sec["stem"]
    stem = StemParams(kind=st.get("kind", "sphere"),
                      offset_m=st.get("offset_m", DEFAULT_STEM_OFFSET_R * top.R_m),
                      radius_m=st.get("radius_m", DEFAULT_STEM_RADIUS_R * top.R_m))
    if effects.stem and top_mjcf is None:
        stem.check_protrudes(top.R_m)
    outputs = Outputs(**sec["outputs"])
    exp = sec["expect"]
    if "outcome" in exp:
        expect(exp["outcome"] in OUTCOMES, "expect.outcome", "|".join(OUTCOMES), exp["outcome"],
               OUTCOMES)
    name = meta.get("name") or (path.stem if path is not None else "default")
    return Scene(
        name=name,
        description=meta.get("description", ""),
        source=meta.get("source", ""),
        top=top,
        friction=friction,
        effects=effects,
        init=init,
        run=run,
        ode=ode,
        mujoco=mujoco,
        outputs=outputs,
        expect=exp,
        raw={s: v for s, v in data.items() if v},
        path=path,
        top_mjcf=top_mjcf,
        set_keys=set_keys,
        init_keyframe=keyframe,
        stem=stem,
    )
