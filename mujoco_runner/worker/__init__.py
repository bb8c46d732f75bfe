"""Run one MuJoCo plan in another Python: a worker that needs nothing but ``mujoco`` and ``numpy``.

``PYTHON path/to/worker`` (this folder, started by path: :mod:`.__main__`) reads requests (JSON,
one line each) on stdin until its end; for each it steps the plan's model sample by sample as
the harness does from Python, and writes the samples and each sample's window (what every
step's forward pass since the sample before computed: contacts, gaps, forces, paper mode's
law) to the ``.npz`` file the request names; stdout carries progress lines and then one JSON
line that says how the request ended (its reply). The harness keeps a worker for its next
request. The harness turns that into a run's result (:mod:`tippetop.mujoco_runner.remote`).
This folder imports nothing of tippetop's, so it runs in any interpreter that can ``import
mujoco`` (a managed environment, a user's own build), from its own files alone.

Its files, by job:

- ``__main__.py``: the start, by path (the folder loaded as a package of its own name);
- :mod:`.protocol`: the requests and replies, their channel, a refused request;
- :mod:`.serve`: the loop over the requests, and one plan's run (MuJoCo C's stepping, or an
  accelerated engine's; the arrays and the reply);
- :mod:`.windows`: what a sample's window holds, and its accumulation from MuJoCo C's passes
  (the harness's in-process runs use it too);
- :mod:`.paper_law`: the paper's law, as MuJoCo C's passive callback and in array arithmetic;
- :mod:`.mjx_stepper` and :mod:`.warp_stepper`: MuJoCo MJX and MuJoCo Warp.

The request's optional ``engine`` picks what steps the plan (:mod:`.serve` says how, and what
the reply says of it).
"""

from __future__ import annotations

from .mjx_stepper import MjxStepper, window_add
from .paper_law import PaperLaw, law_force
from .protocol import (
    PACKAGES,
    PRECISIONS,
    PROGRESS_S,
    PROTOCOL,
    Refused,
    engine_of,
    keep_stdout_for_replies,
)
from .serve import answer, main, run, window_top
from .warp_stepper import WarpStepper, warp_law_kernel, warp_window_kernels
from .windows import WindowAccumulator, WindowTop

__all__ = ["PRECISIONS", "PACKAGES", "PROGRESS_S", "PROTOCOL", "MjxStepper", "PaperLaw", "Refused",
           "WarpStepper", "WindowAccumulator", "WindowTop", "answer", "engine_of",
           "keep_stdout_for_replies", "law_force", "main", "run", "warp_law_kernel",
           "warp_window_kernels", "window_add", "window_top"]
