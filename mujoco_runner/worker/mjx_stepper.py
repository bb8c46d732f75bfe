"""MuJoCo MJX (JAX) steps a plan's sample intervals on JAX's default device.

One jitted ``fori_loop`` of ``mjx.step`` per sample interval, in float32 unless
``jax_enable_x64`` (the request's float64); in paper mode the law's force
(:func:`.paper_law.law_force` in ``jax.numpy``) goes into ``qfrc_applied`` before each step,
inside the loop. The request's ``compile_cache`` is JAX's persistent compilation cache folder.
"""

from __future__ import annotations

import sys
from typing import Any

from .paper_law import law_force
from .protocol import PACKAGES, Refused, package_version, stdout_to_stderr


class MjxStepper:
    """A plan's sample intervals stepped by MuJoCo MJX (JAX) on JAX's default device.

    One jitted function does an interval's ``steps`` steps (``jax.lax.fori_loop`` of
    ``mjx.step``, with the paper's law put in ``qfrc_applied`` before each step when ``law``
    is given); the state is read back after each call.
    """

    def __init__(self, mujoco, model, data, steps: int, precision: str,
                 law: dict | None, qa: int, va: int, cache_dir: str | None = None) -> None:
        try:
            with stdout_to_stderr():
                import jax
                jax.config.update("jax_enable_x64", precision == "float64")
                if cache_dir:  # a later run of the same model loads its compiled loop
                    jax.config.update("jax_compilation_cache_dir", cache_dir)
                import jax.numpy as jnp
                from mujoco import mjx
        except ImportError as exc:
            raise Refused(f"engine mjx: expected mujoco-mjx and jax in {sys.executable}, "
                          f"got ImportError: {exc}") from None
        self.jax = jax
        self.note = None
        cone = int(model.opt.cone)
        colliding = (model.geom_contype | model.geom_conaffinity) != 0
        if (cone == int(mujoco.mjtCone.mjCONE_ELLIPTIC) and model.npair == 0
                and (model.geom_condim[colliding] == 1).all()):
            # MJX (3.17) fails tracing an elliptic cone whose contacts are all condim 1 (an
            # empty float index in its solver); a frictionless contact is the same one row
            # with either cone, so MJX gets the pyramidal one
            model.opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
            self.note = ("cone pyramidal on the device: every contact is condim 1 "
                         "(frictionless, the cone changes nothing) and MJX fails on an "
                         "elliptic cone of condim-1 contacts")
        try:
            m = mjx.put_model(model, impl="jax")
        finally:
            model.opt.cone = cone
        d = mjx.put_data(model, data, impl="jax")

        def one(_i, d):
            if law is not None:
                f6 = law_force(jnp, law, d.qpos[qa:qa + 7], d.qvel[va:va + 6],
                               d.qfrc_constraint[va:va + 6])[0]
                d = d.replace(qfrc_applied=d.qfrc_applied.at[va:va + 6].set(
                    f6.astype(d.qfrc_applied.dtype)))
            return mjx.step(m, d)

        # put_data's integer fields need not have step's dtypes (int32 against int64 with
        # x64): cast to what a step returns, or fori_loop refuses its carry
        shapes = jax.eval_shape(lambda d: one(0, d), d)
        self.d = jax.tree_util.tree_map(
            lambda x, o: x.astype(o.dtype) if x.dtype != o.dtype else x, d, shapes)
        self.advance_fn = jax.jit(lambda d: jax.lax.fori_loop(0, steps, one, d))
        device = next(iter(self.d.qpos.devices()))
        self.version = package_version(PACKAGES["mjx"])
        self.precision = str(self.d.qpos.dtype)
        self.device = str(device.platform)
        self.device_kind = str(device.device_kind)
        self.path = "mjx: jit(fori_loop(step))"

    def advance(self) -> None:
        """Step one sample interval."""
        self.d = self.advance_fn(self.d)

    def state(self) -> tuple[Any, ...]:
        """time, qpos, qvel, qacc_warmstart, qfrc_constraint, read back (float64 numpy)."""
        import numpy as np

        d = self.d
        return (float(d.time),) + tuple(np.asarray(a, dtype=np.float64) for a in (
            d.qpos, d.qvel, d.qacc_warmstart, d.qfrc_constraint))


__all__ = ["MjxStepper"]
