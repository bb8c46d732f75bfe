"""The one exception type a user can cause.

Every error that bad input can trigger (a bad parameter, scene key, engine or file) is a
:class:`TippetopError`. The command line prints its message as one line and exits 2; nothing
else is caught there, so a real bug still shows its traceback.
"""

from __future__ import annotations


class TippetopError(ValueError):
    """Bad input: the message says what was expected and what was given."""


def expect(condition: bool, what: str, expected: str, got: object) -> None:
    """Raise :class:`TippetopError` unless ``condition`` holds.

    Args:
        condition: The check that must hold.
        what: The name of the checked value, e.g. ``"top.M_kg"``.
        expected: What a valid value looks like, e.g. ``"a finite number > 0"``.
        got: The value received (shown with ``repr``).
    """
    if not condition:
        raise TippetopError(f"{what}: expected {expected}, got {got!r}")


class RunFailedError(RuntimeError):
    """A valid run that failed (diverged, stopped short): the message says why.

    The command line prints it as one line, ``tippetop: run failed: ...``, and exits 1.
    """
