"""A first run compiles only what it runs (issue 14: a fresh checkout's first ``simulate``).

Each case runs ``tippetop simulate`` in a fresh process on an empty compile cache and reads
back which functions numba compiled (one index file per compiled function in the cache
folder). What a run needs is the integrator's kernel and the functions of the one formulation
(and contact phase) it integrates; nothing of the other formulation, the two-point phase of a
stem it does not have, the rolling phases of a stiff law it does not meet, MuJoCo's stepper or
callback, or the benchmark's peers. Slow: each case compiles the kernel (10-20 s).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

#: DOP853's small functions, compiled when its module is imported (every method takes the
#: kernel contract's names from it, and the dense output's): its kernel is not among them.
DOP853 = {"dop853.dense_coeffs", "dop853.dense_eval", "dop853.initial_step"}
#: DOP853's kernel (a module the driver writes to the cache, reference_ode/driver.py: its
#: name's hash of its source dropped here), compiled when DOP853 runs: asked for, or taking
#: over a stretch the Taylor or the Adams method finds stiff.
KERNEL = {"dop853.run", "dop853.locate"}
#: The Taylor method's kernel of order 12 for a sphere's inertia (fig3's A = C): what ``auto``
#: runs at the scenes' rtol 1e-9 (at 1e-10) on the ball on the table, a module written to the
#: cache as DOP853's.
TAYLOR = {"taylor_p12_sym.jet", "taylor_p12_sym.dense_eval", "taylor_p12_sym.locate",
          "taylor_p12_sym.run"}
#: The Adams method's kernel: what ``auto`` runs at rtol 1e-9 where the Taylor method does not
#: (the paper's formulation, a stem).
ADAMS = {"adams.run", "adams.interp", "adams.locate"}
VECTOR = {"top.vector_rhs", "top.vector_watch", "top.vector_observe_all",
          "vector.vector_observe"}
PAPER = {"top.paper_rhs", "top.paper_watch", "top.paper_observe_all", "paper.paper_observe"}
TWO_POINTS = {"top.two_contact_rhs", "top.two_contact_forces", "top.two_contact_observe_all",
              "two_contact.two_contact_observe"}


def _compiled(tmp_path: Path, *overrides: str) -> set[str]:
    env = dict(os.environ, TIPPETOP_CACHE=str(tmp_path))
    env.pop("NUMBA_CACHE_DIR", None)
    args = [sys.executable, "-m", "tippetop.compare.cli", "simulate", "fig3", "--json"]
    for o in overrides:
        args += ["--set", o]
    subprocess.run(args, env=env, check=True, capture_output=True, text=True)
    names = {re.sub(r"^([a-z0-9_]+?)_[0-9a-f]{12}\.", r"\1.",
                    re.sub(r"-\d+\.py\d+\.nbi$", "", p.name))
             for p in tmp_path.rglob("*.nbi")}
    assert names, "nothing was cached: the run did not use the cache folder it was given"
    return names


@pytest.mark.slow
@pytest.mark.parametrize(("overrides", "expected"), [
    ((), DOP853 | TAYLOR | VECTOR),
    (("ode.formulation=paper",), DOP853 | ADAMS | PAPER),
    (("effects.stem=true",), DOP853 | ADAMS | VECTOR | TWO_POINTS),
    (("ode.method=dop853",), DOP853 | KERNEL | VECTOR),
], ids=["vector", "paper", "stem", "dop853"])
def test_a_first_run_compiles_only_what_it_runs(tmp_path: Path, overrides: tuple[str, ...],
                                                expected: set[str]) -> None:
    assert _compiled(tmp_path, *overrides) == expected
