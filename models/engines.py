"""Engines: what integrates a run, from where, at what precision.

An *engine* is what integrates (a *mode*, :mod:`tippetop.models.modes`, is how the contact
force is made). ``ode`` is the reference ODE; ``mujoco`` the MuJoCo installed beside tippetop,
in this process; ``mujoco==X.Y.Z`` a release in a managed environment; ``mujoco@PYTHON`` the
``mujoco`` that interpreter imports (a build from source, a nightly wheel); ``mjx`` and
``mjx-f32`` MuJoCo MJX on JAX in float64 and float32; ``warp`` MuJoCo Warp (float32).
:func:`parse_engine` reads one. Every engine but ``ode`` runs MuJoCo's plans: its *family* is
``mujoco``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from tippetop.models.errors import TippetopError, did_you_mean

#: The implementations an engine spec can name.
IMPLEMENTATIONS: tuple[str, ...] = ("ode", "mujoco", "mjx", "warp")
#: The engine families: which plan an engine runs (the reference's, or MuJoCo's).
FAMILIES: tuple[str, ...] = ("ode", "mujoco")
#: How to write an engine, for messages.
SPEC_FORMS = "ode, mujoco, mujoco==X.Y.Z, mujoco@PYTHON, mjx, mjx-f32 or warp"
#: How to write a MuJoCo engine (every engine but the reference), for messages.
MUJOCO_SPEC_FORMS = "mujoco, mujoco==X.Y.Z, mujoco@PYTHON, mjx, mjx-f32 or warp"
#: Every engine that can be named without an argument, for suggestions.
NAMED: tuple[str, ...] = ("ode", "mujoco", "mjx", "mjx-f32", "warp")
_VERSION = re.compile(r"^\d+\.\d+\.\d+$")
#: Each way of naming an engine, with what it is (``tippetop --help``, the glossary).
ENGINE_MEANINGS: dict[str, str] = {
    "ode": "the reference: the paper's equations, compiled (the default)",
    "mujoco": "the MuJoCo installed with tippetop, in this process",
    "mujoco==X.Y.Z": "a MuJoCo release, in an environment made with uv on first use",
    "mujoco@PYTHON": "the mujoco that interpreter imports (a build of your own): a path, or a "
                     "command on PATH",
    "mjx, mjx-f32": "MuJoCo MJX on JAX, float64 and float32, on the CPU here",
    "warp": "MuJoCo Warp, float32, on the CPU here",
}


@dataclass(frozen=True)
class EngineSpec:
    """One engine.

    Attributes:
        spec: As written (``mujoco==3.3.7``).
        implementation: ``ode`` (the reference), ``mujoco`` (MuJoCo C), ``mjx`` or ``warp``.
        version: A release to install in a managed environment (``3.3.7``); None: the one
            that is there (beside tippetop, or in ``python``).
        python: ``mujoco@PYTHON``'s interpreter; None otherwise.
        precision: ``float64`` or ``float32``.
    """

    spec: str
    implementation: str
    version: str | None = None
    python: str | None = None
    precision: str = "float64"

    @property
    def in_process(self) -> bool:
        """The reference, or the MuJoCo installed beside tippetop: run in this process."""
        return (self.implementation in ("ode", "mujoco") and self.version is None
                and self.python is None)

    @property
    def is_reference(self) -> bool:
        """The reference ODE."""
        return self.implementation == "ode"

    @property
    def family(self) -> str:
        """``ode`` for the reference; ``mujoco`` for every engine that runs MuJoCo's plans."""
        return "ode" if self.is_reference else "mujoco"


def parse_engine(text: str) -> EngineSpec:
    """The engine ``text`` names.

    Raises:
        TippetopError: Anything but one of :data:`SPEC_FORMS` (one line, with what was given).
    """
    spec = text.strip()
    if spec == "ode":
        return EngineSpec(spec, "ode")
    if spec == "mujoco":
        return EngineSpec(spec, "mujoco")
    if spec.startswith("mujoco=="):
        version = spec.removeprefix("mujoco==")
        if _VERSION.match(version):
            return EngineSpec(spec, "mujoco", version=version)
        raise TippetopError(f"engine: expected mujoco==X.Y.Z with a release number such as "
                            f"3.3.7, got {text!r}")
    if spec.startswith("mujoco@"):
        python = spec.removeprefix("mujoco@")
        if python:
            return EngineSpec(spec, "mujoco", python=python)
    if spec == "mjx":
        return EngineSpec(spec, "mjx")
    if spec == "mjx-f32":
        return EngineSpec(spec, "mjx", precision="float32")
    if spec == "warp":
        return EngineSpec(spec, "warp", precision="float32")
    raise TippetopError(f"engine: expected {SPEC_FORMS}, got {text!r}"
                        f"{did_you_mean(spec, (*NAMED, 'mujoco==X.Y.Z', 'mujoco@PYTHON'))}")


def parse_engines(text: str, *, mujoco_only: bool = False) -> list[EngineSpec]:
    """A comma-separated list of engines (``--engines``), each at most once.

    Args:
        text: The list as given.
        mujoco_only: Only MuJoCo engines (a command whose reference always runs, such as
            ``validate``): ``ode``, or any engine but the MuJoCo forms, is one line.

    Raises:
        TippetopError: An empty list, a bad engine or one given twice.
    """
    forms = MUJOCO_SPEC_FORMS if mujoco_only else SPEC_FORMS
    specs = []
    for s in text.split(","):
        if not s.strip():
            continue
        try:
            spec = parse_engine(s)
        except TippetopError as e:
            if not mujoco_only:
                raise
            hint = did_you_mean(s.strip(), (*NAMED[1:], "mujoco==X.Y.Z", "mujoco@PYTHON"))
            raise TippetopError(f"engine: expected {forms}, got {s.strip()!r}{hint}") from e
        if mujoco_only and spec.is_reference:
            raise TippetopError(f"engine: expected {forms}, got 'ode' (the reference runs "
                                "anyway: it is what every engine is checked against)")
        specs.append(spec)
    if not specs:
        raise TippetopError(f"--engines: expected at least one of {forms}, got {text!r}")
    seen = [s.spec for s in specs]
    twice = sorted({s for s in seen if seen.count(s) > 1})
    if twice:
        raise TippetopError(f"--engines: expected each engine once, got {', '.join(twice)} "
                            "twice")
    return specs


__all__ = ["ENGINE_MEANINGS", "FAMILIES", "IMPLEMENTATIONS", "MUJOCO_SPEC_FORMS", "NAMED",
           "SPEC_FORMS", "EngineSpec", "parse_engine", "parse_engines"]
