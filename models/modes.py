"""Modes: how the contact force is made, apart from the engine that integrates the run.

An *engine* (:mod:`tippetop.models.engines`) is what integrates: ``ode``, ``mujoco``,
``mujoco==X.Y.Z`` ... A *mode* is how the contact force is made: the paper's law (``paper``),
MuJoCo's own contact and its variants (``native``, ``native-pyramidal``, ``native-elliptic``,
``native-condim4``, ``native-condim6``, ``file``), or one of the reference's other laws
(``coulomb``, ``viscous``, ``coulomb_viscous``). Each mode runs on engines of some families
(the reference ``ode``, or ``mujoco``: MuJoCo C, MJX, Warp) and is the scene keys it sets; a
pairing that cannot run (the native mode on the reference, a reference law on MuJoCo) is one
line (:func:`check_pair`). A run is named ``ENGINE/MODE`` (:func:`run_label`).

The compound names of the release before (``mujoco-native``, ``ode-coulomb`` ...) are read
for one more release (:mod:`tippetop.models.spellings`, their home), with the new spelling.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from tippetop.models.errors import TippetopError, did_you_mean
from tippetop.models.spellings import GOES, OLD_NAMES, new_spelling, note

if TYPE_CHECKING:
    from tippetop.models.engines import EngineSpec
    from tippetop.models.scene import Scene


@dataclass(frozen=True)
class Mode:
    """One way of making the contact force.

    Attributes:
        name: As written on the command line and in every output (``native-condim4``).
        families: The engine families that can run it: ``ode`` (the reference) and/or
            ``mujoco`` (MuJoCo C, MJX, Warp).
        ode: The scene keys it sets on the reference (``section.key=value``).
        mujoco: The scene keys it sets on a MuJoCo engine.
        meaning: One sentence: what makes the force.
    """

    name: str
    families: tuple[str, ...]
    ode: tuple[str, ...] = ()
    mujoco: tuple[str, ...] = ()
    meaning: str = ""

    def overrides(self, family: str) -> tuple[str, ...]:
        """The scene keys this mode sets on an engine of ``family``."""
        return self.ode if family == "ode" else self.mujoco


_NATIVE = ("mujoco.friction=native", "mujoco.calibrated=true")

#: Every mode, in the order the help lists them.
MODES: dict[str, Mode] = {m.name: m for m in (
    Mode("paper", ("ode", "mujoco"), ("friction.law=modified_coulomb",),
         ("mujoco.friction=paper",),
         "the paper's law, F = -mu N v_P / sqrt(|v_P|^2 + Lambda^2): integrated by the "
         "reference; in MuJoCo applied by the harness at the contact point, on a frictionless "
         "contact, with the previous step's normal force (a scene's friction.law may name "
         "another law for MuJoCo to apply)"),
    Mode("native", ("mujoco",), mujoco=_NATIVE,
         meaning="MuJoCo's own soft contact friction, with the calibrated settings "
         "(models/calibrated_native.toml) for every contact key the scene does not set"),
    Mode("native-pyramidal", ("mujoco",), mujoco=(*_NATIVE, "mujoco.cone=pyramidal"),
         meaning="MuJoCo's own contact, calibrated, with a pyramidal friction cone (mu N along "
         "each pyramid edge, mu N / sqrt(2) along a diagonal)"),
    Mode("native-elliptic", ("mujoco",), mujoco=(*_NATIVE, "mujoco.cone=elliptic"),
         meaning="MuJoCo's own contact, calibrated, with an elliptic friction cone (|F| <= mu N "
         "in every direction)"),
    Mode("native-condim4", ("mujoco",), mujoco=(*_NATIVE, "effects.torsional=true"),
         meaning="MuJoCo's own contact, calibrated, with torsional friction (condim 4): a "
         "torque about the normal that is not through the contact point"),
    Mode("native-condim6", ("mujoco",), mujoco=(*_NATIVE, "effects.torsional=true",
                                                 "effects.rolling=true"),
         meaning="MuJoCo's own contact, calibrated, with torsional and rolling friction "
         "(condim 6)"),
    Mode("file", ("mujoco",), mujoco=("mujoco.friction=native", "mujoco.calibrated=false"),
         meaning="MuJoCo's own contact friction with the model's own settings: a loaded MJCF "
         "file as it says, a generated top with the scene's [mujoco] values"),
    Mode("coulomb", ("ode",), ("friction.law=coulomb",),
         meaning="the reference with exact Coulomb friction: the full mu N down to v_P = 0"),
    Mode("viscous", ("ode",), ("friction.law=viscous",),
         meaning="the reference with viscous friction of the paper's slope at v_P = 0"),
    Mode("coulomb_viscous", ("ode",), ("friction.law=coulomb_viscous",),
         meaning="the reference with exact Coulomb friction plus the viscous term"),
)}

#: The mode of a reference run whose scene names this friction law (no mode asked for).
LAW_MODES: dict[str, str] = {"modified_coulomb": "paper", "coulomb": "coulomb",
                             "viscous": "viscous", "coulomb_viscous": "coulomb_viscous"}

#: The engine families in words, for messages.
FAMILY_WORDS = {"ode": "the reference ODE", "mujoco": "a MuJoCo engine"}

def _choices() -> str:
    return ", ".join(MODES)


def parse_mode(text: str, option: str = "--mode") -> str:
    """The mode ``text`` names.

    Raises:
        TippetopError: Not a mode (one line, with what was given).
    """
    name = text.strip()
    if name in MODES:
        return name
    hint = ""
    if name in OLD_NAMES and name not in ("ode", "mujoco"):
        hint = f" ({name!r} names an engine and a mode: {new_spelling(name)})"
    elif name in ("ode", "mujoco"):
        hint = f" ({name!r} is an engine: --engine {name})"
    raise TippetopError(f"{option}: expected a mode ({_choices()}), got "
                        f"{text!r}{hint or did_you_mean(name, MODES)}")


def parse_modes(text: str, option: str = "--modes") -> list[str]:
    """A comma-separated list of modes, each at most once.

    Raises:
        TippetopError: An empty list, a bad mode or one given twice (one line).
    """
    names = [parse_mode(m, option) for m in text.split(",") if m.strip()]
    if not names:
        raise TippetopError(f"{option}: expected at least one mode ({_choices()}), got "
                            f"{text!r}")
    twice = sorted({m for m in names if names.count(m) > 1})
    if twice:
        raise TippetopError(f"{option}: expected each mode once, got {', '.join(twice)} twice")
    return names


def runs_on(mode: str) -> str:
    """The engines a mode runs on, in words (``MuJoCo engines only``)."""
    fams = MODES[mode].families
    if fams == ("ode",):
        return "the reference ODE only"
    if fams == ("mujoco",):
        return "MuJoCo engines only"
    return "every engine"


def check_pair(family: str, mode: str, engine: str | None = None) -> None:
    """Refuse a mode that an engine of ``family`` cannot run (one line).

    Args:
        family: ``ode`` or ``mujoco`` (:attr:`~tippetop.models.engines.EngineSpec.family`).
        mode: A mode name.
        engine: The engine as given, for the message (default: the family).

    Raises:
        TippetopError: An unknown mode, or one the engine cannot run.
    """
    parse_mode(mode)
    m = MODES[mode]
    if family in m.families:
        return
    can = [n for n, other in MODES.items() if family in other.families]
    what = ("MuJoCo's own contact" if mode in ("file",) or mode.startswith("native")
            else "a law of the reference's")
    raise TippetopError(f"--mode: expected a mode {FAMILY_WORDS[family]} runs "
                        f"({', '.join(can)}), got {mode!r} on engine {engine or family!r}: "
                        f"{mode!r} is {what}, run on {runs_on(mode)}")


def scene_mode(scene: Scene, family: str) -> str:
    """The mode a scene runs in when none is asked for: what its keys say.

    The reference: its friction law's mode. MuJoCo: ``paper`` when the harness applies the
    law (``mujoco.friction = paper``); ``native`` with the calibrated settings; ``file``
    with the model's own (a loaded MJCF file's, unless the scene sets ``mujoco.calibrated``).
    """
    if family == "ode":
        return LAW_MODES.get(scene.friction.law, "paper")
    mj = scene.mujoco
    loaded = scene.top_mjcf is not None
    friction = mj.friction if not loaded or scene.is_set("mujoco.friction") else "native"
    if friction == "paper":
        return "paper"
    calibrated = mj.calibrated if mj.calibrated is not None else not loaded
    return "native" if calibrated else "file"


def run_label(engine: str, mode: str) -> str:
    """A run's name: ``ENGINE/MODE`` (``ode/paper``, ``mujoco==3.3.7/native``)."""
    return f"{engine}/{mode}"


#: The reference's run: the ODE in the paper's law, every other run is compared with.
REFERENCE_RUN = "ode/paper"


def split_label(label: str) -> tuple[str, str]:
    """(engine, mode) of a run's name (:func:`run_label`); the mode never holds a ``/``."""
    engine, _, mode = label.rpartition("/")
    return engine, mode


def pairs(engines: Sequence[EngineSpec], modes: Sequence[str]) -> list[tuple[str, str]]:
    """Every (engine, mode) of ``engines`` x ``modes`` that can run, in that order.

    Raises:
        TippetopError: A mode that none of the engines can run, or an engine that runs none of
            the modes (one line each: what to give instead).
    """
    out = [(e.spec, m) for e in engines for m in modes if e.family in MODES[m].families]
    for m in modes:
        if not any(e.family in MODES[m].families for e in engines):
            given = ",".join(e.spec for e in engines)
            raise TippetopError(f"--modes: expected modes the engines given ({given}) can run, "
                                f"got {m!r}, which runs on {runs_on(m)}")
    for e in engines:
        if not any(e.family in MODES[m].families for m in modes):
            can = [n for n, other in MODES.items() if e.family in other.families]
            raise TippetopError(f"--engines: expected engines that run one of the modes "
                                f"given ({','.join(modes)}), got {e.spec!r}, which runs "
                                f"{', '.join(can)}")
    return out


def read_old_list(items: Iterable[str], option: str) -> list[tuple[str, str | None,
                                                                     tuple[str, ...]]] | None:
    """A list of the release before's compound names read as runs, with one note; else None.

    ``--modes ode,mujoco-paper`` (``compare``, ``sweep``) and ``--engines ode,mujoco-native``
    (``atlas``) named runs with compound names. If any item of ``items`` is one (and not a
    mode or engine of today), every item is read that way and one line says the new spelling.
    """
    names = [i.strip() for i in items if i.strip()]
    engines_too = option == "--engines"  # there ode and mujoco are today's engines
    if not any(n in OLD_NAMES and n not in MODES
               and not (engines_too and n in ("ode", "mujoco")) for n in names):
        return None
    bad = [n for n in names if n not in OLD_NAMES]
    if bad:
        raise TippetopError(f"{option}: expected engines and modes apart (--engines "
                            f"ode,mujoco --modes paper,native), got {','.join(names)!r}")
    runs = [OLD_NAMES[n] for n in names]
    engines = ",".join(dict.fromkeys(e for e, _, _ in runs))
    modes = ",".join(dict.fromkeys(m for _, m, _ in runs if m is not None))
    note(f"{option} {','.join(names)} names engines and modes together: now --engines "
         f"{engines}" + (f" --modes {modes}" if modes else "")
         + f" {GOES}")
    return runs


__all__ = ["FAMILY_WORDS", "LAW_MODES", "MODES", "REFERENCE_RUN", "Mode", "check_pair",
           "pairs", "parse_mode", "parse_modes",
           "read_old_list", "run_label", "runs_on", "scene_mode", "split_label"]
