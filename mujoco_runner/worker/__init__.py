"""Run one MuJoCo plan in another Python: a worker that needs nothing but ``mujoco`` and ``numpy``.

``PYTHON path/to/worker`` (this folder, started by path: :mod:`.__main__`) reads requests (JSON,
one line each) on stdin until its end; for each it steps the plan's model sample by sample as
the harness does from Python, and writes the samples, the contacts at each sample and paper
mode's forces to the ``.npz`` file the request names; stdout carries progress lines and then one
JSON line that says how the request ended (its reply). The harness keeps a worker for its next
request. The harness turns that into a run's result (:mod:`tippetop.mujoco_runner.remote`).
This folder imports nothing of tippetop's, so it runs in any interpreter that can ``import
mujoco`` (a managed environment, a user's own build), from its own files alone.

Its files, by job:

- ``__main__.py``: the start, by path (the folder loaded as a package of its own name);
- :mod:`.protocol`: the requests and replies, their channel, a refused request;
- :mod:`.serve`: the loop over the requests, and one plan's run (MuJoCo C's stepping, or an
  accelerated engine's; the contacts at the samples; the arrays and the reply);
- :mod:`.paper_law`: the paper's law, as MuJoCo C's passive callback and in array arithmetic;
- :mod:`.mjx_stepper` and :mod:`.warp_stepper`: MuJoCo MJX and MuJoCo Warp.

The request's optional ``engine`` picks what steps the plan (:mod:`.serve` says how, and what
the reply says of it).
"""

from __future__ import annotations

from .mjx_stepper import MjxStepper
from .paper_law import PaperLaw, law_force
from .protocol import (
    ENGINES,
    PACKAGES,
    PROGRESS_S,
    PROTOCOL,
    Refused,
    engine_of,
    keep_stdout_for_replies,
)
from .serve import N_FORCE_PASSES, answer, main, run
from .warp_stepper import WarpStepper, warp_law_kernel

__all__ = ["ENGINES", "N_FORCE_PASSES", "PACKAGES", "PROGRESS_S", "PROTOCOL", "MjxStepper",
           "PaperLaw", "Refused", "WarpStepper", "answer", "engine_of",
           "keep_stdout_for_replies", "law_force", "main", "run", "warp_law_kernel"]
