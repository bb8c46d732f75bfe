"""Tuning: MuJoCo's contact settings fitted to the reference, verified, and calibrated.

The room between the measures and the runs below it and the studies above it. It holds:

- :mod:`.tune` (any top's contact tuned: ``validate``'s ``tuned`` key, ``calibrate --mjcf``):
  the fits from its seeds, the verification from starts the fit did not see, the answer;
- :mod:`.judge` (what the tuning verifies: its starts, a verification's verdict, the block to
  paste) and :mod:`.widen` (where the fits depart: the answer's neighbours, a refit, draws),
  with :mod:`.sobol` (the draws' seeded sequence);
- :mod:`.calibrate` (MuJoCo's native friction fitted for the catalogue: the candidates, the seeds
  and the scoring, MuJoCo's own identification, the grid and compass search, the TOML file).

The studies (validate, fidelity, the contact search) call it; it calls the runner and the
measures. Importing this package costs nothing: its modules load when used.
"""

from __future__ import annotations

#: ``tippetop validate`` and ``calibrate --mjcf``: MuJoCo runs the tuning may use
#: (``--budget-runs``): its seeds, its fits' rollouts and its verification runs. The paper's
#: top takes about 60. One in three is kept for the widening where the fits depart
#: (:func:`tippetop.compare.tuning.widen.widen_reserve`); at this many the tuning ends with
#: its best so far, verified.
TUNE_BUDGET_RUNS = 300
