"""The one exception type a user can cause.

Every error that bad input can trigger (a bad parameter, scene key, engine or file) is a
:class:`TippetopError`. The command line prints its message as one line and exits 2; nothing
else is caught there, so a real bug still shows its traceback.

A name checked against a list of known names (a scene key, a scene, a mode, an engine) says
which one was meant when one is close: :func:`did_you_mean`.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

#: How alike two names must be (difflib's ratio, 0 to 1) for one to be suggested for the other.
SIMILARITY_CUTOFF = 0.6
#: As alike, for a key given in one section and suggested from another (``run.n0`` ->
#: ``init.n0`` is the same key; ``top.mass`` -> ``ode.max_steps`` is not what was meant).
STRICT_CUTOFF = 0.75


class TippetopError(ValueError):
    """Bad input: the message says what was expected and what was given."""


def did_you_mean(given: str, choices: Iterable[str]) -> str:
    """`` (did you mean 'NAME'?)``: the known name closest to a mistyped one, or ``""``.

    Put it right after the name given in a message: ``f"got {given!r}{did_you_mean(given,
    known)}"``. The name is the one :func:`closest_name` finds.

    Args:
        given: The name as given (anything but a string gets no suggestion).
        choices: The known names.

    Returns:
        ``" (did you mean 'NAME'?)"``, with a leading space; ``""`` when ``given`` is one of
        ``choices`` or nothing is close.
    """
    best = closest_name(given, choices)
    return f" (did you mean {best!r}?)" if best is not None else ""


def closest_name(given: str, choices: Iterable[str]) -> str | None:
    """The known name a mistyped one most likely meant; None if it is known or none is close.

    The name is looked for, in this order: as written but in another case (``FIG3`` ->
    ``fig3``); for a ``section.key`` name in a known section, the one key of the section that
    starts with the key given (``top.M`` -> ``top.M_kg``) or the closest key of the section
    (``run.t_end`` -> ``run.t_end_s``), then the same key or a very close one in another
    section (``run.n0`` -> ``init.n0``); for a bare name among ``section.key`` names, the
    closest key (``t_end_s`` -> ``run.t_end_s``); otherwise the closest name of all
    (``fig33`` -> ``fig3``). Close: difflib's ratio at least :data:`SIMILARITY_CUTOFF`.

    Args:
        given: The name as given (anything but a string gets None).
        choices: The known names.
    """
    if not isinstance(given, str):
        return None
    names = [c for c in dict.fromkeys(choices) if isinstance(c, str) and c]
    text = given.strip()
    if not text or text in names:
        return None
    return _closest(text, names)


def _close(word: str, candidates: dict[str, str], cutoff: float = SIMILARITY_CUTOFF
           ) -> str | None:
    """The value of ``candidates`` (folded name -> name) whose key is most like ``word``.

    At least ``cutoff`` alike (difflib's ratio); of equally close ones, the first.
    """
    best, best_ratio = None, cutoff
    for folded, name in candidates.items():
        ratio = difflib.SequenceMatcher(None, word, folded).ratio()
        if ratio > best_ratio or (best is None and ratio == best_ratio):
            best, best_ratio = name, ratio
    return best


def _closest(text: str, names: list[str]) -> str | None:
    """The name of ``names`` meant by ``text`` (not one of them), or None; see did_you_mean."""
    folded: dict[str, str] = {}
    for n in names:
        folded.setdefault(n.casefold(), n)
    word = text.casefold()
    if word in folded:
        return folded[word]
    dotted = [(n.casefold().partition("."), n) for n in names if "." in n]
    if not dotted:
        return _close(word, folded)
    keys: dict[str, str] = {}  # key -> its first section.key
    for (_, _, k), n in dotted:
        keys.setdefault(k, n)
    if "." not in word:  # a bare name: one of the others, or a key without its section
        return _close(word, {**{f: n for f, n in folded.items() if "." not in f}, **keys})
    section, _, key = word.partition(".")
    same = {k: n for (s, _, k), n in dotted if s == section}
    if not same:  # an unknown section: the closest name of all
        return _close(word, folded)
    # a known section: the one key there that starts with the key given, or a close one;
    # else the key itself or a close one elsewhere. Keys are compared without the section,
    # whose name would make them all look alike ("top.mass" is not "top.R_m").
    raw_key = text.partition(".")[2]
    for starts in ([n for n in same.values() if n.partition(".")[2].startswith(raw_key)],
                   [n for k, n in same.items() if k.startswith(key)]):
        if len(starts) == 1:
            return starts[0]
    return _close(key, same) or keys.get(key) or _close(key, keys, STRICT_CUTOFF)


def expect(condition: bool, what: str, expected: str, got: object,
           choices: Iterable[str] = ()) -> None:
    """Raise :class:`TippetopError` unless ``condition`` holds.

    Args:
        condition: The check that must hold.
        what: The name of the checked value, e.g. ``"top.M_kg"``.
        expected: What a valid value looks like, e.g. ``"a finite number > 0"``.
        got: The value received (shown with ``repr``).
        choices: The valid names, when ``got`` must be one of them: a close one is suggested
            (:func:`did_you_mean`).
    """
    if not condition:
        hint = did_you_mean(got, choices) if isinstance(got, str) else ""
        raise TippetopError(f"{what}: expected {expected}, got {got!r}{hint}")


class RunFailedError(RuntimeError):
    """A valid run that failed (diverged, stopped short): the message says why.

    The command line prints it as one line, ``tippetop: run failed: ...``, and exits 1.
    """
