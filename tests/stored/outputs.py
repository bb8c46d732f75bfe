"""The stored outputs: what each command printed just before issue 42's work began.

Issue 42 reshaped what passes between the rooms (overrides as values, results with fields,
metrics' meanings in their declarations) and promised no change in behaviour: every command
gives the same output and JSON as on the commit before it began (``BASE``). The outputs of that
commit are stored under tests/stored/data/ (:func:`make`), and tests/test_stored_outputs.py runs
the same commands on today's code and compares.

The cases:
- ``validate_<example>``: ``tippetop validate examples/<example>.xml --no-tune --json``.
- ``quick``: ``tippetop nightly --profile quick --no-baseline``'s results.json.
- ``fidelity_small``: ``tippetop fidelity --grid small --budget-runs 40 --t-end-s 3 --workers 2
  --json``.
- ``bisect_<case>``: bisect over tests/stored/bisect_fixture.py's fake ranges.

What is compared (:func:`same`): every key exactly, every text exactly but for the numbers in
it, and every number (in a text too) to a relative 1e-4, or 1e-10 absolute near zero. Not
closer: on one machine with the same packages, today's code met the stored quick profile to
1e-9 in one run and missed it in the next two (fresh clones' CI) by up to 1.4e-6 and 1.03e-5
relative, in the MuJoCo growth fits of its threshold cases (rates near 1e-7/s, residuals near
2e-6, 2e-11 apart) and the critical spins they give (1e-13 apart, in a check's sentence): a
float compared with ``==`` across two runs is a test of luck. A change of behaviour moves a
verdict, a sentence or a number by far more: the nightly's own tolerances start at 1e-3.
Left out, being the machine's and not the code's: wall-clock times, absolute paths
(:func:`normalised`) and the nightly's environment (the machine, its packages, the commit).

To make them again (only when an output is meant to change, with the reason in the commit):
``python tests/stored/outputs.py [CASE ...]`` from the repository's root.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data"
#: The commit whose outputs are stored: the last before issue 42's work began.
BASE = "f3c8f8f"
EXAMPLES = ("capsule_stem_top", "cylinder_stem_ballast", "paper_loaded_sphere")
FIDELITY_ARGS = ("fidelity", "--grid", "small", "--budget-runs", "40", "--t-end-s", "3",
                 "--workers", "2")
#: Keys whose value is the machine's, not the code's: wall-clock times and dates.
VOLATILE = re.compile(r"(^|_)(wall|elapsed|started|finished|timestamp|created|date|host|"
                      r"machine|duration|cpu)(_|$)")
#: A wall-clock time in a sentence ("... to t = 8 s in 0.18 s").
WALL_IN_TEXT = re.compile(r" in [0-9][0-9.,]*(?:e[-+]?[0-9]+)? (?:s|ms)\b")
#: Numbers agree to this, relative (see the module's docstring) ...
REL = 1e-4
#: ... or to this, absolute.
ABS = 1e-10
#: A number in a text (compared as a number, the words between exactly).
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _cli(args: list[str], cache: Path, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "TIPPETOP_CACHE": str(cache), "PYTHONUNBUFFERED": "1"}
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, env=env, cwd=cwd or ROOT,
                          timeout=3600)


def _json(done: subprocess.CompletedProcess, what: str) -> Any:
    if done.returncode not in (0, 1):
        raise RuntimeError(f"{what}: exit {done.returncode}: {done.stderr[-2000:]}")
    return json.loads(done.stdout)


def run_case(name: str, work: Path) -> Any:
    """The case's output on the code this process imports, normalised."""
    cache = work / "cache"
    if name.startswith("validate_"):
        example = ROOT / "examples" / f"{name.removeprefix('validate_')}.xml"
        out = _json(_cli(["validate", str(example), "--no-tune", "--json"], cache), name)
    elif name == "quick":
        folder = work / "quick"
        done = _cli(["nightly", "--profile", "quick", "--no-baseline", "--out", str(folder)],
                    cache)
        if done.returncode not in (0, 1):
            raise RuntimeError(f"quick: exit {done.returncode}: {done.stderr[-2000:]}")
        out = json.loads((folder / "results.json").read_text())
        out.pop("environment", None)  # the machine, its packages and the commit
    elif name == "fidelity_small":
        out = _json(_cli([*FIDELITY_ARGS, "--json"], cache), name)
    elif name.startswith("bisect_"):
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from bisect_fixture import run_case as bisect_case

        out = bisect_case(name.removeprefix("bisect_"))
    else:
        raise KeyError(name)
    return normalised(out, [str(work), str(_package_root()), str(ROOT)])


def _package_root() -> Path:
    """The folder of the tippetop package this process imports (its files' paths)."""
    import tippetop.compare

    return Path(tippetop.compare.__file__).resolve().parents[1]


def cases() -> list[str]:
    """Every case's name."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bisect_fixture import CASES

    return ([f"validate_{e}" for e in EXAMPLES] + ["quick", "fidelity_small"]
            + [f"bisect_{c}" for c in CASES])


def normalised(x: Any, roots: list[str]) -> Any:
    """``x`` without wall-clock keys or times in its sentences, its folders spelt ``<ROOT>``."""
    if isinstance(x, dict):
        return {k: normalised(v, roots) for k, v in x.items() if not VOLATILE.search(str(k))}
    if isinstance(x, list | tuple):
        return [normalised(v, roots) for v in x]
    if isinstance(x, str):
        for r in roots:
            x = x.replace(r, "<ROOT>")
        return WALL_IN_TEXT.sub(" in <wall>", x)
    return x


def same(a: Any, b: Any, where: str = "") -> list[str]:
    """Where ``a`` and ``b`` differ (keys and words exactly, numbers to :data:`REL`)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{where}: keys {sorted(set(a) ^ set(b))}"] if set(a) != set(b) else []
        for k in sorted(set(a) & set(b)):
            out += same(a[k], b[k], f"{where}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items, stored {len(b)}"]
        return [d for i, (u, v) in enumerate(zip(a, b, strict=True))
                for d in same(u, v, f"{where}[{i}]")]
    numbers = (int, float)
    if (isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool)
            and not isinstance(b, bool)):
        if _close(a, b):
            return []
        return [f"{where}: {a!r}, stored {b!r}"]
    if isinstance(a, str) and isinstance(b, str) and a != b and _same_text(a, b):
        return []
    return [] if a == b else [f"{where}: {a!r}, stored {b!r}"]


def _close(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=REL, abs_tol=ABS)


def _same_text(a: str, b: str) -> bool:
    """The words of ``a`` and ``b`` the same and their numbers close (:func:`_close`)."""
    if NUMBER.split(a) != NUMBER.split(b):
        return False
    na, nb = NUMBER.findall(a), NUMBER.findall(b)
    return len(na) == len(nb) and all(_close(float(x), float(y)) for x, y in zip(na, nb,
                                                                                   strict=True))


def stored(name: str) -> Any:
    """The stored output of a case (normalised again: the rules may have grown since)."""
    return normalised(json.loads((DATA / f"{name}.json").read_text()), [])


def make(names: list[str]) -> None:
    """Run the cases on the code this process imports and store their outputs."""
    DATA.mkdir(exist_ok=True)
    for name in names:
        with tempfile.TemporaryDirectory() as tmp:
            out = run_case(name, Path(tmp))
        (DATA / f"{name}.json").write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
        print(f"stored {name}", flush=True)


if __name__ == "__main__":
    make(sys.argv[1:] or cases())
