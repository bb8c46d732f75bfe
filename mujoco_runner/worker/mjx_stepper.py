"""MuJoCo MJX (JAX) steps a plan's sample intervals on JAX's default device, windows and all.

One jitted loop per sample interval, in float32 unless ``jax_enable_x64`` (the request's
float64): each step is ``mjx.step`` taken apart as MuJoCo C's ``mj_step`` is in the harness
(the integrator, then the next step's forward pass, ``mjx.forward``), and that pass is added
to the sample's window on the device (:func:`window_add`, the arithmetic of
:class:`.windows.WindowAccumulator`), so nothing is read back between two samples. In paper
mode the law's force (:func:`.paper_law.law_force` in ``jax.numpy``) goes into
``qfrc_applied`` before each forward pass, inside the loop. The request's ``compile_cache`` is
JAX's persistent compilation cache folder.
"""

from __future__ import annotations

import sys
from typing import Any

from .paper_law import law_force
from .protocol import PACKAGES, Refused, package_version, stdout_to_stderr
from .windows import BALL, FLOAT_START, INT_START, OTHER, F, I, WindowTop

#: What MJX's windows read of each pass (the engine reply's ``contacts_from``).
MJX_CONTACTS_FROM = (
    "MJX's own forward pass at every step, its window added on the device: touch, depth and "
    "the stretches from the contacts MJX's solver includes (dist < includemargin); N and the "
    "friction force from qfrc_constraint of the top's free joint (the world force of its "
    "contacts), friction torque not read (0), friction power and the slip (times N) at the "
    "ball's lowest point")


def window_add(xp: Any, wi: Any, wf: Any, prev: tuple[Any, Any], code: Any, depth: Any,
               forces: tuple[Any, ...], gap: Any, slip: tuple[Any, Any], kz: Any,
               law: tuple[Any, Any, Any], offset: Any) -> tuple[Any, Any, tuple[Any, Any]]:
    """One pass added to a window, in array arithmetic (``xp``: ``numpy`` or ``jax.numpy``).

    :meth:`.windows.WindowAccumulator.add`'s update with its branches written as ``xp.where``
    (so it traces under ``jax.jit``), on what the pass read rather than on an mjData. Any
    column of :mod:`.windows` it does not know keeps its value.

    Args:
        xp: The array module.
        wi: The window's integer columns (:data:`.windows.INT_FIELDS`).
        wf: Its float columns (:data:`.windows.FLOAT_FIELDS`).
        prev: The carry from the run's pass before: (it touched, its k_z).
        code: The pass's contact code (:data:`.windows.BALL` | :data:`.windows.OTHER`).
        depth: Its deepest penetration (m, >= 0).
        forces: Its ``(n, fx, fy, fz, tx, ty, tz, power)`` (the float sums' terms).
        gap: The ball's centre height less its radius (m).
        slip: The velocity of the ball's lowest point, world (x, y) (m/s); the window sums
            it times the pass's ``n``.
        kz: The symmetry axis' z component.
        law: Paper mode's ``(fx, fy, power)`` at the pass (zeros without a law).
        offset: The pass's offset in its window.

    Returns:
        The window's new ``(wi, wf)`` and the carry for the next pass.
    """
    prev_touch, prev_kz = prev
    touched = xp.not_equal(code, 0).astype(bool)  # strongly typed: the carry's jit key
    free = xp.logical_not(touched)
    first, last = wi[I["first_touch"]], wi[I["last_touch"]]
    trail = wf[F["trail_gap"]]
    widen = touched & (last >= 0) & (offset - last - 1 > wi[I["inner_free"]])
    ints = {
        "passes": wi[I["passes"]] + 1,
        "touch": wi[I["touch"]] | code,
        "touch_passes": wi[I["touch_passes"]] + xp.where(touched, 1, 0),
        "first_touch": xp.where(touched & (first < 0), offset, first),
        "last_touch": xp.where(touched, offset, last),
        "inner_free": xp.where(widen, offset - last - 1, wi[I["inner_free"]]),
        "inner_start": xp.where(widen, last + 1, wi[I["inner_start"]]),
        "lifts": wi[I["lifts"]] + xp.where(free & prev_touch, 1, 0),
        "first_other": xp.where(touched & ((code & OTHER) != 0) & (wi[I["first_other"]] < 0),
                                offset, wi[I["first_other"]]),
        "flip": xp.where((prev_kz > 0.0) & (kz <= 0.0) & (wi[I["flip"]] < 0), offset,
                         wi[I["flip"]]),
    }
    lead = wf[F["lead_gap"]]
    n, fx, fy, fz, tx, ty, tz, power = forces
    floats = {
        "gap_max": xp.maximum(wf[F["gap_max"]], gap),
        "gap_min": xp.minimum(wf[F["gap_min"]], gap),
        "lead_gap": xp.where(free & (first < 0), xp.maximum(lead, gap), lead),
        "trail_gap": xp.where(touched, -xp.inf, xp.maximum(trail, gap)),
        "inner_gap": xp.where(widen, trail, wf[F["inner_gap"]]),
        "depth_max": xp.maximum(wf[F["depth_max"]], depth),
        "n_sum": wf[F["n_sum"]] + n, "fx_sum": wf[F["fx_sum"]] + fx,
        "fy_sum": wf[F["fy_sum"]] + fy, "fz_sum": wf[F["fz_sum"]] + fz,
        "tx_sum": wf[F["tx_sum"]] + tx, "ty_sum": wf[F["ty_sum"]] + ty,
        "tz_sum": wf[F["tz_sum"]] + tz, "power_sum": wf[F["power_sum"]] + power,
        "law_fx_sum": wf[F["law_fx_sum"]] + law[0], "law_fy_sum": wf[F["law_fy_sum"]] + law[1],
        "law_power_sum": wf[F["law_power_sum"]] + law[2],
        "slip_nx_sum": wf[F["slip_nx_sum"]] + n * slip[0],
        "slip_ny_sum": wf[F["slip_ny_sum"]] + n * slip[1],
    }
    # a column of :mod:`.windows` not written here keeps its value
    new_i = xp.stack([xp.asarray(ints.get(name, wi[k]), dtype=wi.dtype)
                      for name, k in I.items()])
    new_f = xp.stack([xp.asarray(floats.get(name, wf[k]), dtype=wf.dtype)
                      for name, k in F.items()])
    return new_i, new_f, (touched, kz)


def table_pass(xp: Any, geom_body: Any, top: WindowTop, dist: Any, includemargin: Any,
               geom: Any, xmat: Any, ball_xpos: Any, qpos: Any, qvel: Any,
               qcon: Any) -> tuple[Any, Any, tuple[Any, ...], Any, tuple[Any, Any], Any]:
    """What a window adds of one MJX forward pass: ``(code, depth, forces, gap, slip, kz)``.

    The arrays are the pass's (one world): the contacts' ``dist``, ``includemargin`` and
    ``geom`` (all of MJX's fixed contact slots: a slot is a contact where its solver
    includes it, dist < includemargin), the top body's ``xmat`` (3 x 3), the ball geom's
    centre, the model's ``qpos``, ``qvel`` and ``qfrc_constraint``. The forces are those of
    all the top's constraints at once, read from ``qfrc_constraint`` of its free joint: its
    first three dofs are the world force on the body, so ``n`` (its z) is the contacts'
    normal force on the table z = 0 and ``fx``, ``fy`` their friction; ``fz`` and the
    friction torque are 0, and the power is the friction force times the velocity of the
    ball's lowest point, its ``slip`` (x, y; written out as MuJoCo C's windows have it, so
    the same doubles from the same state). MuJoCo C's windows
    (:class:`.windows.WindowAccumulator`) sum ``mj_contactForce`` per contact instead: the
    same on a flat table, but for the torque (and a contact point's offset from the lowest
    point, the depth over two, in the power).
    """
    qa, va = top.qpos_adr, top.dof_adr
    if dist.shape[0]:
        body = geom_body[geom]
        mine = (dist < includemargin) & ((body[:, 0] == top.body) | (body[:, 1] == top.body))
        is_ball = (geom[:, 0] == top.ball) | (geom[:, 1] == top.ball)
        code = (xp.where(xp.any(mine & is_ball), BALL, 0)
                | xp.where(xp.any(mine & xp.logical_not(is_ball)), OTHER, 0))
        depth = xp.maximum(xp.max(xp.where(mine, -dist, 0.0)), 0.0)
    else:  # nothing can touch
        code, depth = xp.asarray(0), xp.asarray(0.0, dtype=qpos.dtype)
    fx, fy, n = qcon[va], qcon[va + 1], qcon[va + 2]
    lx, ly, lz = qvel[va + 3], qvel[va + 4], qvel[va + 5]
    ox = xmat[0, 0] * lx + xmat[0, 1] * ly + xmat[0, 2] * lz  # omega, world
    oy = xmat[1, 0] * lx + xmat[1, 1] * ly + xmat[1, 2] * lz
    oz = xmat[2, 0] * lx + xmat[2, 1] * ly + xmat[2, 2] * lz
    gap = ball_xpos[2] - top.radius_m
    # the arm to the ball's lowest point, centre - R z - origin
    ax, ay, az = ball_xpos[0] - qpos[qa], ball_xpos[1] - qpos[qa + 1], gap - qpos[qa + 2]
    vx = qvel[va] + (oy * az - oz * ay)
    vy = qvel[va + 1] + (oz * ax - ox * az)
    zero = 0.0 * n
    forces = (n, fx, fy, zero, zero, zero, zero, fx * vx + fy * vy)
    a0, a1, a2 = top.axis_body
    kz = xmat[2, 0] * a0 + xmat[2, 1] * a1 + xmat[2, 2] * a2
    return code, depth, forces, gap, (vx, vy), kz


def _import_jax(precision: str, cache_dir: str | None) -> tuple[Any, Any, Any]:
    """JAX (set to ``precision``, with its compilation cache in ``cache_dir``), jnp and MJX."""
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
    return jax, jnp, mjx


def _put_model(mujoco: Any, mjx: Any, model: Any) -> tuple[Any, str | None]:
    """MJX's copy of ``model`` on the device, and a note where its cone is not the model's."""
    note = None
    cone = int(model.opt.cone)
    colliding = (model.geom_contype | model.geom_conaffinity) != 0
    if (cone == int(mujoco.mjtCone.mjCONE_ELLIPTIC) and model.npair == 0
            and (model.geom_condim[colliding] == 1).all()):
        # MJX (3.17) fails tracing an elliptic cone whose contacts are all condim 1 (an
        # empty float index in its solver); a frictionless contact is the same one row
        # with either cone, so MJX gets the pyramidal one
        model.opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
        note = ("cone pyramidal on the device: every contact is condim 1 "
                "(frictionless, the cone changes nothing) and MJX fails on an "
                "elliptic cone of condim-1 contacts")
    try:
        m = mjx.put_model(model, impl="jax")
    finally:
        model.opt.cone = cone
    return m, note


class MjxStepper:
    """A plan's sample intervals stepped by MuJoCo MJX (JAX) on JAX's default device.

    One jitted function does an interval's ``steps`` steps (a ``jax.lax.fori_loop``; each
    step the integrator, then the paper's law put in ``qfrc_applied`` when ``law`` is given,
    then ``mjx.forward`` and its pass added to the window, :func:`table_pass` and
    :func:`window_add`); the state and the window are read back after each call. The same
    function with its first step's integrator skipped does row 0's one pass
    (:meth:`first`).

    What differs from MuJoCo C's windows (:data:`MJX_CONTACTS_FROM`): the contacts that count
    are those MJX's solver includes (dist < includemargin) where MuJoCo C counts every contact
    of ``mjData.contact`` (dist < margin: the same where no geom has a ``gap``, but for a
    contact at dist exactly 0, which C keeps); the forces are the free joint's
    ``qfrc_constraint`` (:func:`table_pass`), not ``mj_contactForce`` per contact.
    ``mjx.step`` itself would leave RK4's last stage's contacts and kinematics in its data
    (``rungekutta4`` returns the last stage's forward pass), so the steps are taken apart.
    """

    contacts_from = MJX_CONTACTS_FROM

    def __init__(self, mujoco, model, data, steps: int, precision: str,
                 law: dict | None, top: WindowTop, cache_dir: str | None = None) -> None:
        jax, jnp, mjx = _import_jax(precision, cache_dir)
        import numpy as np

        self.jax = jax
        qa, va = top.qpos_adr, top.dof_adr
        m, self.note = _put_model(mujoco, mjx, model)
        d = mjx.put_data(model, data, impl="jax")
        kind = int(model.opt.integrator)
        integrators = {int(mujoco.mjtIntegrator.mjINT_EULER): mjx.euler,
                       int(mujoco.mjtIntegrator.mjINT_RK4): mjx.rungekutta4,
                       int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): mjx.implicit}
        if kind not in integrators:
            raise Refused(f"engine mjx: expected the Euler, RK4 or implicitfast integrator, "
                          f"got {mujoco.mjtIntegrator(kind).name}")
        integrate = integrators[kind]
        geom_body = jnp.asarray(np.asarray(model.geom_bodyid))

        def integrate_d(d):
            return integrate(m, d)

        def forward(d):
            """The law into qfrc_applied (paper mode), then the forward pass."""
            out = (0.0, 0.0, 0.0)
            if law is not None:
                f6, fx, fy, _n, power = law_force(jnp, law, d.qpos[qa:qa + 7],
                                                  d.qvel[va:va + 6],
                                                  d.qfrc_constraint[va:va + 6])
                d = d.replace(qfrc_applied=d.qfrc_applied.at[va:va + 6].set(
                    f6.astype(d.qfrc_applied.dtype)))
                out = (fx, fy, power)
            return mjx.forward(m, d), out

        # put_data's fields need not have the loop's dtypes (int32 against int64 with x64):
        # cast to what a forward pass returns (RK4's stages are its carry), then to what a
        # step returns, or fori_loop and cond refuse their carry
        for stage in (lambda d: forward(d)[0], lambda d: forward(integrate_d(d))[0]):
            shapes = jax.eval_shape(stage, d)
            d = jax.tree_util.tree_map(
                lambda x, o: x.astype(o.dtype) if x.dtype != o.dtype else x, d, shapes)
        fdt = d.qpos.dtype
        idt = jnp.asarray(0).dtype  # int64 with x64, else int32
        int_start = jnp.asarray(INT_START, dtype=idt)
        float_start = jnp.asarray(FLOAT_START, dtype=fdt)

        def body(i, carry):
            d, wi, wf, prev, con, first = carry
            skip = first & (i == 0)  # row 0: its one pass, at the start's state
            d = jax.lax.cond(skip, lambda d: d, integrate_d, d)
            con = d.qfrc_constraint  # as the step left it (RK4: its last stage's)
            d, out = forward(d)
            # MJX 3.17 keeps the contacts in its JAX implementation's data (d.contact is
            # deprecated there); an older MJX has them on d
            contact = getattr(d, "_impl", d).contact
            code, depth, forces, gap, slip, kz = table_pass(
                jnp, geom_body, top, contact.dist, contact.includemargin, contact.geom,
                d.xmat[top.body], d.geom_xpos[top.ball], d.qpos, d.qvel, d.qfrc_constraint)
            offset = jnp.where(first, i, i + 1).astype(idt)
            wi, wf, prev = window_add(jnp, wi, wf, prev, code, depth, forces, gap, slip, kz,
                                      out, offset)
            return d, wi, wf, prev, con, first

        def interval(d, prev, n, first):
            carry = (d, int_start, float_start, prev, d.qfrc_constraint, first)
            d, wi, wf, prev, con, _ = jax.lax.fori_loop(0, n, body, carry)
            return d, wi, wf, prev, con

        self.d = d
        device = next(iter(self.d.qpos.devices()))
        # a run that starts without contact starts a stretch; no k_z before the first pass.
        # On d's device, as the loop's output is: a carry that is not (uncommitted) would be
        # another jit key, and the second call would compile the loop again
        self.prev = jax.device_put((jnp.asarray(True), jnp.asarray(jnp.nan, dtype=fdt)),
                                   device)
        self.con = d.qfrc_constraint
        self.wi, self.wf = int_start, float_start
        self.steps = steps
        self.interval = jax.jit(interval)
        self.version = package_version(PACKAGES["mjx"])
        self.precision = str(self.d.qpos.dtype)
        self.device = str(device.platform)
        self.device_kind = str(device.device_kind)
        self.path = "mjx: jit(fori_loop(integrate, forward, window))"

    def _call(self, n: int, first: bool) -> None:
        self.d, self.wi, self.wf, self.prev, self.con = self.interval(
            self.d, self.prev, n, first)

    def first(self) -> None:
        """Row 0: the one pass at the start's state, added to its window (compiles the loop)."""
        self._call(1, True)

    def advance(self) -> None:
        """Step one sample interval, each step's pass added to its window."""
        self._call(self.steps, False)

    def state(self) -> tuple[Any, ...]:
        """time, qpos, qvel, qacc_warmstart, qfrc_constraint, read back (float64 numpy).

        ``qfrc_constraint`` as the interval's last step left it, before the pass at the
        sample's state (MuJoCo C's record has it so).
        """
        import numpy as np

        d = self.d
        return (float(d.time),) + tuple(np.asarray(a, dtype=np.float64) for a in (
            d.qpos, d.qvel, d.qacc_warmstart, self.con))

    def window(self) -> tuple[Any, Any]:
        """The last call's window: its integer and float columns (int64, float64 numpy)."""
        import numpy as np

        return np.asarray(self.wi, dtype=np.int64), np.asarray(self.wf, dtype=np.float64)


__all__ = ["MJX_CONTACTS_FROM", "MjxStepper", "table_pass", "window_add"]
