"""Space-filling draws: a scrambled, seeded Sobol sequence (:mod:`scipy.stats.qmc`)."""

from __future__ import annotations

import inspect
import math

import numpy as np


def sobol_unit(n: int, d: int, seed: int) -> np.ndarray:
    """``n`` points of a scrambled, seeded Sobol sequence in [0, 1)^d (a power-of-2 prefix)."""
    from scipy.stats import qmc

    key = "rng" if "rng" in inspect.signature(qmc.Sobol).parameters else "seed"
    sampler = qmc.Sobol(d, scramble=True, **{key: np.random.default_rng(seed)})
    return sampler.random_base2(max(0, math.ceil(math.log2(max(n, 1)))))[:n]


__all__ = ["sobol_unit"]
