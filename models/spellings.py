"""The release before's spellings, read for one more release: their one home.

Each old spelling is read as today's with one line on stderr, once per process, that gives
the new spelling (:func:`note_old`, ending in :data:`GOES`). The tables:

- :data:`OLD_NAMES`: compound run names (``mujoco-native``: ``--engine mujoco --mode
  native``), read by ``--engine``, ``--modes``, ``--engines``, a catalogue's ``modes`` and a
  case id (``paper/fig3[mujoco-native]``, :data:`OLD_CASE_ID`);
- :data:`OLD_ENGINE_WORDS`: ``--engine both`` of ``tippetop render`` (``--engines
  mujoco,ode``);
- :data:`OLD_OPTIONS`: options renamed (``--on X``: ``--engine X``);
- :data:`OLD_COMMANDS`: commands renamed (``python -m tippetop.compare.report``: ``tippetop
  report``).

This module sits below :mod:`tippetop.models.modes` (which reads the compound names in its
own parsers): it imports nothing of tippetop's.
"""

from __future__ import annotations

import re
import sys

#: How every note on an old spelling ends.
GOES = "(the old spelling goes in the next release)"

#: The release before's compound names: name -> (engine, mode or None for the scene's, the
#: scene keys it also set).
OLD_NAMES: dict[str, tuple[str, str | None, tuple[str, ...]]] = {
    "ode": ("ode", None, ()),
    "mujoco": ("mujoco", None, ()),
    "ode-paper-form": ("ode", "paper", ("ode.formulation=paper",)),
    "ode-coulomb": ("ode", "coulomb", ()),
    "ode-viscous": ("ode", "viscous", ()),
    "ode-coulomb_viscous": ("ode", "coulomb_viscous", ()),
    "mujoco-paper": ("mujoco", "paper", ()),
    "mujoco-native": ("mujoco", "native", ()),
    "mujoco-native-pyramidal": ("mujoco", "native-pyramidal", ()),
    "mujoco-native-elliptic": ("mujoco", "native-elliptic", ()),
    "mujoco-native-condim4": ("mujoco", "native-condim4", ()),
    "mujoco-native-condim6": ("mujoco", "native-condim6", ()),
    "mujoco-file": ("mujoco", "file", ()),
}
#: A case id of the release before: ``HEAD[COMPOUND]`` or ``HEAD[COMPOUND]@ENGINE``.
OLD_CASE_ID = re.compile(r"^(?P<head>.*)\[(?P<mode>[^\]/]+)\](?:@(?P<engine>.+))?$")
#: Words ``--engine`` took that name several engines: word -> the engines.
OLD_ENGINE_WORDS: dict[str, tuple[str, ...]] = {"both": ("mujoco", "ode")}
#: Options renamed: old -> today's.
OLD_OPTIONS: dict[str, str] = {"--on": "--engine"}
#: Commands renamed: old -> today's.
OLD_COMMANDS: dict[str, str] = {"python -m tippetop.compare.report": "tippetop report"}

_NOTED: set[str] = set()


def note(text: str) -> None:
    """One line on stderr, once per process: an old spelling and its new one."""
    if text in _NOTED:
        return
    _NOTED.add(text)
    sys.stderr.write(f"tippetop: note: {text}\n")
    sys.stderr.flush()


def note_old(old: str, now: str) -> None:
    """``OLD is now NOW (the old spelling goes in the next release)``, once per process."""
    note(f"{old} is now {now} {GOES}")


def old_spelling(name: str) -> tuple[str, str | None, tuple[str, ...]] | None:
    """(engine, mode, extra scene keys) of a compound name of the release before, or None."""
    return OLD_NAMES.get(name.strip())


def new_spelling(name: str, engine_option: str = "--engine",
                 mode_option: str = "--mode") -> str:
    """How the compound ``name`` is written now (``--engine mujoco --mode native``)."""
    engine, mode, extra = OLD_NAMES[name]
    parts = [f"{engine_option} {engine}"]
    if mode is not None:
        parts.append(f"{mode_option} {mode}")
    parts += [f"--set {o}" for o in extra]
    return " ".join(parts)


def old_engine_words(word: str | None) -> tuple[str, ...] | None:
    """The engines an old ``--engine`` word names (``both``), with a note; else None."""
    engines = OLD_ENGINE_WORDS.get(word or "")
    if engines is not None:
        note_old(f"--engine {word}", f"--engines {','.join(engines)}")
    return engines


def old_case_id(case_id: str) -> tuple[str, str, str | None, tuple[str, ...]] | None:
    """(head, engine, mode or None, extra keys) of a case id of the release before, or None.

    ``paper/fig3[mujoco-native]@mujoco==3.3.7`` -> ``("paper/fig3", "mujoco==3.3.7",
    "native", ())``; today's ids (``paper/fig3[mujoco/native]``) give None.
    """
    m = OLD_CASE_ID.match(case_id)
    if m is None or m["mode"] not in OLD_NAMES:
        return None
    family, mode, extra = OLD_NAMES[m["mode"]]
    return m["head"], m["engine"] or family, mode, extra


def note_old_command(old: str) -> None:
    """The note of a renamed command (:data:`OLD_COMMANDS`), as the release before said it."""
    note(f"'{old}' is now '{OLD_COMMANDS[old]}'; this spelling goes in the next release")


__all__ = ["GOES", "OLD_CASE_ID", "OLD_COMMANDS", "OLD_ENGINE_WORDS", "OLD_NAMES", "OLD_OPTIONS",
           "new_spelling", "note", "note_old", "note_old_command", "old_case_id",
           "old_engine_words", "old_spelling"]
