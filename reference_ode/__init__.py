"""The reference model: the paper's equations of motion, compiled, and their integrator."""

from tippetop.reference_ode._jit import configure_numba_cache

#: Where this process caches compiled code (None: ``NUMBA_CACHE_DIR`` decides).
NUMBA_CACHE_DIR = configure_numba_cache()
