"""Run one MuJoCo plan in another Python: a worker that needs nothing but ``mujoco`` and ``numpy``.

``PYTHON path/to/worker`` (this folder, started by path: :mod:`.__main__`) reads requests (JSON,
one line each) on stdin until its end; for each it steps the plan's model sample by sample as
the harness does from Python, and writes the samples, the contacts at each sample and paper
mode's forces to the ``.npz`` file the request names; stdout carries progress lines and then one
JSON line that says how the request ended (its reply). The harness keeps a worker for its next
request. The harness turns that into a run's result (:mod:`tippetop.mujoco_runner.remote`).
This folder imports nothing of tippetop's, so it runs in any interpreter that can ``import
mujoco`` (a managed environment, a user's own build), from its own files alone.

The request's optional ``engine`` (``{"implementation": "mujoco"|"mjx"|"warp", "precision":
"float64"|"float32"}``) picks what steps the plan: MuJoCo C (``mj_step``, the default), MuJoCo
MJX on JAX (one jitted ``fori_loop`` of ``mjx.step`` per sample interval; float32 unless
``jax_enable_x64``) or MuJoCo Warp (float32; the interval's steps captured once as a Warp
graph, or ``mjw.step`` in a loop where capture fails). Those two need their packages beside
``mujoco`` (a managed environment holds them). The model is compiled by MuJoCo C either way
and the start set and ``mj_forward``-ed there; the states are read back from the device at
each sample, and the contacts at each sample (and paper mode's law output) come from MuJoCo
C's ``mj_forward`` at those states. MJX and Warp have no warning counters (their column is
zeros). Paper mode's law is a force of the engine's own there: before each step the law's
force from the current state and the previous step's ``qfrc_constraint`` goes into
``qfrc_applied`` (MJX: the arithmetic of :class:`PaperLaw` in ``jax.numpy`` inside the jitted
loop; Warp: the same in a Warp kernel launched before each step, inside the captured graph).
C's callback is called at every stage of RK4, the applied force is held over the step: the
two agree to rounding with Euler. The request's optional ``compile_cache`` is JAX's persistent
compilation cache folder (a later run of the same model skips most of MJX's compile).

The reply's ``engine`` says what stepped, read back: ``implementation``, ``version`` (MuJoCo
C's, or ``mujoco-mjx``'s / ``mujoco-warp``'s package version), ``precision`` (the dtype of
the device's ``qpos``), ``device`` (JAX's platform, Warp's device alias); for MJX and Warp
also ``device_kind``, ``path``, ``mujoco_c_version``, ``warnings``, ``contacts_from``,
``setup_s`` and ``first_call_s`` (the compile), and ``law_applied`` in paper mode.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import time
import traceback
from typing import Any

#: The version of the request and reply formats (3: the request's ``engine``; 4: one request
#: per line, answered in turn until the input ends).
PROTOCOL = 4
#: What can step a plan: implementation -> the precisions it runs in.
ENGINES = {"mujoco": ("float64",), "mjx": ("float64", "float32"), "warp": ("float32",)}
#: Where the accelerated engines' PyPI packages are (their version is the reply's).
PACKAGES = {"mjx": "mujoco-mjx", "warp": "mujoco-warp"}
#: Forward passes per sample in paper mode (the law's N iterated to the state's own), as in
#: the harness's own runs.
N_FORCE_PASSES = 3
#: Wall time between progress lines (s).
PROGRESS_S = 0.2


#: Where progress lines and the reply go: the process's stdout as it was at the start (see
#: :func:`keep_stdout_for_replies`).
_OUT = sys.stdout


class Refused(ValueError):
    """A request this worker cannot run, its message the whole reply's reason (one line)."""


def _say(obj: dict) -> None:
    _OUT.write(json.dumps(obj) + "\n")
    _OUT.flush()


def keep_stdout_for_replies() -> None:
    """Keep fd 1 for the replies alone.

    Anything else printed (JAX's or Warp's banners, their kernels' compile lines, C
    libraries') goes to stderr.
    """
    global _OUT
    with contextlib.suppress(OSError, ValueError, AttributeError):
        sys.stdout.flush()
        _OUT = os.fdopen(os.dup(1), "w")
        os.dup2(2, 1)
        sys.stdout = sys.stderr


class PaperLaw:
    """The paper's friction law applied at the contact point(s) from ``mjcb_passive``.

    The same computation as the harness's compiled callback, in Python: the normal force is
    the previous evaluation's (the constraint force's vertical component at the free joint),
    split between the ball's point and the stem's when both touch; the force ``law(v, N)`` at
    each point's material velocity goes into ``qfrc_passive``. The last force and power are
    kept for the table.
    """

    def __init__(self, model, params: dict) -> None:
        self.model = model
        self.p = params
        self.qa, self.va = params["qpos_adr"], params["dof_adr"]
        self.last = (0.0, 0.0, 0.0, 0.0)  # fx, fy, N, power

    def force(self, vx: float, vy: float, N: float) -> tuple[float, float]:
        """The law's tangential force (Fx, Fy) = N phi + psi at the slip (vx, vy).

        The reference's own terms (``reference_ode.friction.friction_terms``) written out.
        """
        p = self.p
        phix = phiy = psix = psiy = 0.0
        kind = p["coulomb_kind"]
        if kind == 1:  # modified Coulomb
            s = p["mu"] / math.sqrt(vx * vx + vy * vy + p["Lambda"] * p["Lambda"])
            phix, phiy = -s * vx, -s * vy
        elif kind == 2:  # exact Coulomb, its linear ramp below v_eps
            speed = math.sqrt(vx * vx + vy * vy)
            s = p["mu"] / (speed if speed > p["v_eps"] else p["v_eps"])
            phix, phiy = -s * vx, -s * vy
        if p["viscous_on"]:
            psix, psiy = -p["viscous"] * vx, -p["viscous"] * vy
        return N * phix + psix, N * phiy + psiy

    def __call__(self, m, d) -> None:  # noqa: D102 - MuJoCo's callback
        if m is not self.model and m._address != self.model._address:
            return
        p = self.p
        qpos, qvel = d.qpos[self.qa:self.qa + 7], d.qvel[self.va:self.va + 6]
        w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
        inv = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * inv, x * inv, y * inv, z * inv
        r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        r10, r11, r12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        wbx, wby, wbz = qvel[3], qvel[4], qvel[5]
        ox = r00 * wbx + r01 * wby + r02 * wbz
        oy = r10 * wbx + r11 * wby + r12 * wbz
        oz = r20 * wbx + r21 * wby + r22 * wbz
        cx, cy, cz = p["centre"]
        R = p["R"]
        ax = r00 * cx + r01 * cy + r02 * cz
        ay = r10 * cx + r11 * cy + r12 * cz
        az = r20 * cx + r21 * cy + r22 * cz - R
        qcon = d.qfrc_constraint[self.va:self.va + 6]
        N = max(float(qcon[2]), 0.0)
        N1, N2 = N, 0.0
        bx = by = bz = 0.0
        stem = p["stem_kind"]
        if stem:
            kbx, kby, kbz = p["axis"]
            kx = r00 * kbx + r01 * kby + r02 * kbz
            ky = r10 * kbx + r11 * kby + r12 * kbz
            kz = r20 * kbx + r21 * kby + r22 * kbz
            sl, sr = p["stem_l"], p["stem_r"]
            bx, by, bz = ax + sl * kx, ay + sl * ky, az + R + sl * kz - sr
            if stem == 2:
                s = math.sqrt(kx * kx + ky * ky)
                if s > 0.0:
                    bx += sr * kz * kx / s
                    by += sr * kz * ky / s
                    bz += sr - sr * s
                else:
                    bz += sr
            z1, z2 = qpos[2] + az, qpos[2] + bz
            if z1 <= 0.0 and z2 <= 0.0:
                tx_b, ty_b, tz_b = qcon[3], qcon[4], qcon[5]
                tx = r00 * tx_b + r01 * ty_b + r02 * tz_b
                ty = r10 * tx_b + r11 * ty_b + r12 * tz_b
                ux, uy = by - ay, -(bx - ax)
                rx, ry = tx - N * ay, ty + N * ax
                den = ux * ux + uy * uy
                N2 = (rx * ux + ry * uy) / den if den > 0.0 else 0.5 * N
                N2 = min(max(N2, 0.0), N)
                N1 = N - N2
            elif z2 < z1:
                N1, N2 = 0.0, N
        fx = fy = power = 0.0
        tx = ty = tz = 0.0
        points = [(ax, ay, az, N1)] + ([(bx, by, bz, N2)] if stem else [])
        for px, py, pz, Np in points:
            vx = qvel[0] + oy * pz - oz * py
            vy = qvel[1] + oz * px - ox * pz
            Fx, Fy = self.force(vx, vy, Np)
            fx += Fx
            fy += Fy
            power += Fx * vx + Fy * vy
            tx += -pz * Fy
            ty += pz * Fx
            tz += px * Fy - py * Fx
        qfrc = d.qfrc_passive
        va = self.va
        qfrc[va] += fx
        qfrc[va + 1] += fy
        qfrc[va + 3] += r00 * tx + r10 * ty + r20 * tz
        qfrc[va + 4] += r01 * tx + r11 * ty + r21 * tz
        qfrc[va + 5] += r02 * tx + r12 * ty + r22 * tz
        self.last = (fx, fy, N, power)


def law_force(xp: Any, p: dict, qpos: Any, qvel: Any, qcon: Any) -> tuple[Any, ...]:
    """:class:`PaperLaw`'s force in array arithmetic (``xp``: ``numpy`` or ``jax.numpy``).

    The same operations as :meth:`PaperLaw.__call__` with its branches on the state written as
    ``xp.where`` (so it traces under ``jax.jit``); the branches on the law's parameters stay
    Python's.

    Args:
        xp: The array module.
        p: The law's parameters (the request's ``law``).
        qpos: The free joint's 7 positions.
        qvel: Its 6 velocities.
        qcon: Its 6 constraint forces (the previous evaluation's: N is their vertical one).

    Returns:
        ``(f6, fx, fy, N, power)``: the generalized force on the joint's 6 dofs, the law's
        horizontal force, the normal force it used and its power.
    """
    w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
    inv = 1.0 / xp.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w * inv, x * inv, y * inv, z * inv
    r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    r10, r11, r12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    wbx, wby, wbz = qvel[3], qvel[4], qvel[5]
    ox = r00 * wbx + r01 * wby + r02 * wbz
    oy = r10 * wbx + r11 * wby + r12 * wbz
    oz = r20 * wbx + r21 * wby + r22 * wbz
    cx, cy, cz = p["centre"]
    R = p["R"]
    ax = r00 * cx + r01 * cy + r02 * cz
    ay = r10 * cx + r11 * cy + r12 * cz
    az = r20 * cx + r21 * cy + r22 * cz - R
    N = xp.maximum(qcon[2], 0.0)
    N1, N2 = N, 0.0 * N
    stem = p["stem_kind"]
    bx = by = bz = 0.0 * N
    if stem:
        kbx, kby, kbz = p["axis"]
        kx = r00 * kbx + r01 * kby + r02 * kbz
        ky = r10 * kbx + r11 * kby + r12 * kbz
        kz = r20 * kbx + r21 * kby + r22 * kbz
        sl, sr = p["stem_l"], p["stem_r"]
        bx, by, bz = ax + sl * kx, ay + sl * ky, az + R + sl * kz - sr
        if stem == 2:
            s = xp.sqrt(kx * kx + ky * ky)
            pos = s > 0.0
            s_safe = xp.where(pos, s, 1.0)
            bx = bx + xp.where(pos, sr * kz * kx / s_safe, 0.0)
            by = by + xp.where(pos, sr * kz * ky / s_safe, 0.0)
            bz = bz + xp.where(pos, sr - sr * s, sr)
        z1, z2 = qpos[2] + az, qpos[2] + bz
        both = (z1 <= 0.0) & (z2 <= 0.0)
        tx_b, ty_b, tz_b = qcon[3], qcon[4], qcon[5]
        tx = r00 * tx_b + r01 * ty_b + r02 * tz_b
        ty = r10 * tx_b + r11 * ty_b + r12 * tz_b
        ux, uy = by - ay, -(bx - ax)
        rx, ry = tx - N * ay, ty + N * ax
        den = ux * ux + uy * uy
        split = xp.where(den > 0.0, (rx * ux + ry * uy) / xp.where(den > 0.0, den, 1.0),
                         0.5 * N)
        split = xp.minimum(xp.maximum(split, 0.0), N)
        stem_only = z2 < z1
        N1 = xp.where(both, N - split, xp.where(stem_only, 0.0, N))
        N2 = xp.where(both, split, xp.where(stem_only, N, 0.0))
    fx = fy = power = tx = ty = tz = 0.0 * N
    points = [(ax, ay, az, N1)] + ([(bx, by, bz, N2)] if stem else [])
    for px, py, pz, Np in points:
        vx = qvel[0] + oy * pz - oz * py
        vy = qvel[1] + oz * px - ox * pz
        phix = phiy = psix = psiy = 0.0 * N
        kind = p["coulomb_kind"]
        if kind == 1:  # modified Coulomb
            sc = p["mu"] / xp.sqrt(vx * vx + vy * vy + p["Lambda"] * p["Lambda"])
            phix, phiy = -sc * vx, -sc * vy
        elif kind == 2:  # exact Coulomb, its linear ramp below v_eps
            sc = p["mu"] / xp.maximum(xp.sqrt(vx * vx + vy * vy), p["v_eps"])
            phix, phiy = -sc * vx, -sc * vy
        if p["viscous_on"]:
            psix, psiy = -p["viscous"] * vx, -p["viscous"] * vy
        Fx, Fy = Np * phix + psix, Np * phiy + psiy
        fx, fy = fx + Fx, fy + Fy
        power = power + Fx * vx + Fy * vy
        tx, ty, tz = tx - pz * Fy, ty + pz * Fx, tz + px * Fy - py * Fx
    f6 = xp.stack([fx, fy, 0.0 * fx, r00 * tx + r10 * ty + r20 * tz,
                   r01 * tx + r11 * ty + r21 * tz, r02 * tx + r12 * ty + r22 * tz])
    return f6, fx, fy, N, power


@contextlib.contextmanager
def _stdout_to_stderr():
    """Python-level prints (MJX's ``Failed to import warp``) go to stderr meanwhile."""
    with contextlib.redirect_stdout(sys.stderr):
        yield


def _package_version(name: str) -> str:
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "?"


class MjxStepper:
    """A plan's sample intervals stepped by MuJoCo MJX (JAX) on JAX's default device.

    One jitted function does an interval's ``steps`` steps (``jax.lax.fori_loop`` of
    ``mjx.step``, with the paper's law put in ``qfrc_applied`` before each step when ``law``
    is given); the state is read back after each call.
    """

    def __init__(self, mujoco, model, data, steps: int, precision: str,
                 law: dict | None, qa: int, va: int, cache_dir: str | None = None) -> None:
        try:
            with _stdout_to_stderr():
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
        self.version = _package_version(PACKAGES["mjx"])
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


def warp_law_kernel(wp: Any) -> Any:
    """:func:`law_force` as a Warp kernel, one thread a world.

    The law's force goes into ``qfrc_applied``, from ``qpos``, ``qvel`` and the previous
    step's ``qfrc_constraint``. The same arithmetic as :class:`PaperLaw` in float32 (Warp's
    ``float``), its branches on the state as Warp's dynamic ``if``; it runs in the captured
    graph before each step.
    """

    @wp.func
    def slip_force(vx: float, vy: float, Np: float, kind: int, viscous_on: int, mu: float,
                   lam: float, visc: float, v_eps: float) -> wp.vec2:
        phix = float(0.0)  # noqa: UP018 - Warp: a variable, not a constant
        phiy = float(0.0)  # noqa: UP018
        if kind == 1:
            sc = mu / wp.sqrt(vx * vx + vy * vy + lam * lam)
            phix = -sc * vx
            phiy = -sc * vy
        elif kind == 2:
            sc = mu / wp.max(wp.sqrt(vx * vx + vy * vy), v_eps)
            phix = -sc * vx
            phiy = -sc * vy
        fx = Np * phix
        fy = Np * phiy
        if viscous_on != 0:
            fx = fx - visc * vx
            fy = fy - visc * vy
        return wp.vec2(fx, fy)

    @wp.kernel
    def paper_law(qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float),
                  qcon: wp.array2d(dtype=float), qfrc: wp.array2d(dtype=float), qa: int,
                  va: int, centre: wp.vec3, axis: wp.vec3, R: float, stem_kind: int,
                  stem_l: float, stem_r: float, kind: int, viscous_on: int, mu: float,
                  lam: float, visc: float, v_eps: float):
        i = wp.tid()
        q = wp.normalize(wp.vec4(qpos[i, qa + 3], qpos[i, qa + 4], qpos[i, qa + 5],
                                 qpos[i, qa + 6]))
        w, x, y, z = q[0], q[1], q[2], q[3]
        rot = wp.mat33(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z),
                       2.0 * (x * z + w * y),
                       2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z),
                       2.0 * (y * z - w * x),
                       2.0 * (x * z - w * y), 2.0 * (y * z + w * x),
                       1.0 - 2.0 * (x * x + y * y))
        om = rot @ wp.vec3(qvel[i, va + 3], qvel[i, va + 4], qvel[i, va + 5])
        a = rot @ centre - wp.vec3(0.0, 0.0, R)
        N = wp.max(qcon[i, va + 2], 0.0)
        N1 = N
        N2 = float(0.0)  # noqa: UP018 - Warp: a variable, not a constant
        b = wp.vec3(0.0, 0.0, 0.0)
        if stem_kind != 0:
            k = rot @ axis
            b = a + stem_l * k + wp.vec3(0.0, 0.0, R - stem_r)
            if stem_kind == 2:
                sk = wp.sqrt(k[0] * k[0] + k[1] * k[1])
                if sk > 0.0:
                    b = b + wp.vec3(stem_r * k[2] * k[0] / sk, stem_r * k[2] * k[1] / sk,
                                    stem_r - stem_r * sk)
                else:
                    b = b + wp.vec3(0.0, 0.0, stem_r)
            z1 = qpos[i, qa + 2] + a[2]
            z2 = qpos[i, qa + 2] + b[2]
            if z1 <= 0.0 and z2 <= 0.0:
                t = rot @ wp.vec3(qcon[i, va + 3], qcon[i, va + 4], qcon[i, va + 5])
                ux = b[1] - a[1]
                uy = -(b[0] - a[0])
                rx = t[0] - N * a[1]
                ry = t[1] + N * a[0]
                den = ux * ux + uy * uy
                split = 0.5 * N
                if den > 0.0:
                    split = (rx * ux + ry * uy) / den
                N2 = wp.min(wp.max(split, 0.0), N)
                N1 = N - N2
            elif z2 < z1:
                N1 = 0.0
                N2 = N
        v0 = wp.vec3(qvel[i, va], qvel[i, va + 1], 0.0)
        v1 = v0 + wp.cross(om, a)
        F = slip_force(v1[0], v1[1], N1, kind, viscous_on, mu, lam, visc, v_eps)
        f = wp.vec3(F[0], F[1], 0.0)
        tau = wp.cross(a, f)
        if stem_kind != 0:
            v2 = v0 + wp.cross(om, b)
            F2 = slip_force(v2[0], v2[1], N2, kind, viscous_on, mu, lam, visc, v_eps)
            f2 = wp.vec3(F2[0], F2[1], 0.0)
            f = f + f2
            tau = tau + wp.cross(b, f2)
        tb = wp.transpose(rot) @ tau
        qfrc[i, va] = f[0]
        qfrc[i, va + 1] = f[1]
        qfrc[i, va + 2] = 0.0
        qfrc[i, va + 3] = tb[0]
        qfrc[i, va + 4] = tb[1]
        qfrc[i, va + 5] = tb[2]

    return paper_law


class WarpStepper:
    """A plan's sample intervals stepped by MuJoCo Warp on Warp's default device.

    The interval's ``steps`` calls of ``mjw.step`` (each after the paper law's kernel,
    :func:`warp_law_kernel`, when ``law`` is given) are captured once as a Warp graph and the
    graph launched per interval; where capture fails, they run in a loop.
    """

    def __init__(self, mujoco, model, data, steps: int, precision: str,
                 law: dict | None, qa: int, va: int, cache_dir: str | None = None) -> None:
        try:
            with _stdout_to_stderr():
                import warp as wp
                wp.config.quiet = True
                import mujoco_warp as mjw
                wp.init()
        except ImportError as exc:
            raise Refused(f"engine warp: expected mujoco-warp and warp-lang in "
                          f"{sys.executable}, got ImportError: {exc}") from None
        self.wp, self.mjw, self.steps = wp, mjw, steps
        self.dev = wp.get_device()
        self.law = None
        if law is not None:
            kernel = warp_law_kernel(wp)
            self.law = (kernel, dict(
                qa=qa, va=va, centre=wp.vec3(*law["centre"]), axis=wp.vec3(*law["axis"]),
                R=float(law["R"]), stem_kind=int(law["stem_kind"]),
                stem_l=float(law["stem_l"]), stem_r=float(law["stem_r"]),
                kind=int(law["coulomb_kind"]), viscous_on=int(law["viscous_on"]),
                mu=float(law["mu"]), lam=float(law["Lambda"]), visc=float(law["viscous"]),
                v_eps=float(law["v_eps"])))
        with wp.ScopedDevice(self.dev):
            self.m = mjw.put_model(model)
            warm = mjw.put_data(model, data)
            self._step(warm)  # compiles (or loads) the kernels outside any capture
            self.d = mjw.put_data(model, data)
            self.graph = None
            try:
                with wp.ScopedCapture() as cap:
                    for _ in range(steps):
                        self._step(self.d)
                self.graph = cap.graph
            except Exception:  # noqa: BLE001 - no capture here: the plain loop
                self.d = mjw.put_data(model, data)
        self.version = _package_version(PACKAGES["warp"])
        self.precision = str(self.d.qpos.numpy().dtype)
        self.device = str(self.dev.alias)
        self.device_kind = str(self.dev.name)
        self.path = "warp: captured graph of step" if self.graph is not None else \
            "warp: step loop"

    def _step(self, d: Any) -> None:
        """One step: the law's force into ``qfrc_applied`` (paper mode), then ``mjw.step``."""
        if self.law is not None:
            kernel, p = self.law
            self.wp.launch(kernel, dim=d.qpos.shape[0],
                           inputs=[d.qpos, d.qvel, d.qfrc_constraint, d.qfrc_applied,
                                   p["qa"], p["va"], p["centre"], p["axis"], p["R"],
                                   p["stem_kind"], p["stem_l"], p["stem_r"], p["kind"],
                                   p["viscous_on"], p["mu"], p["lam"], p["visc"],
                                   p["v_eps"]])
        self.mjw.step(self.m, d)

    def advance(self) -> None:
        """Step one sample interval."""
        with self.wp.ScopedDevice(self.dev):
            if self.graph is not None:
                self.wp.capture_launch(self.graph)
            else:
                for _ in range(self.steps):
                    self._step(self.d)

    def state(self) -> tuple[Any, ...]:
        """time, qpos, qvel, qacc_warmstart, qfrc_constraint, read back (float64 numpy)."""
        import numpy as np

        d = self.d
        return (float(d.time.numpy()[0]),) + tuple(
            np.asarray(a.numpy()[0], dtype=np.float64) for a in (
                d.qpos, d.qvel, d.qacc_warmstart, d.qfrc_constraint))


def engine_of(request: dict) -> tuple[str, str]:
    """The request's ``(implementation, precision)``; MuJoCo C in float64 when it names none.

    Raises:
        Refused: Anything but one of :data:`ENGINES` (one line, with what was given).
    """
    engine = request.get("engine") or {}
    if not isinstance(engine, dict):
        raise Refused(f"engine: expected an object with implementation and precision, "
                         f"got {engine!r}")
    impl = engine.get("implementation", "mujoco")
    precision = engine.get("precision", "float64")
    if impl not in ENGINES:
        raise Refused(f"engine: expected an implementation of {', '.join(ENGINES)}, "
                         f"got {impl!r}")
    if precision not in ENGINES[impl]:
        raise Refused(f"engine: expected {impl} in {' or '.join(ENGINES[impl])}, "
                         f"got {precision!r}")
    return impl, precision


def _free_joint(mujoco, model) -> int:
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1:
        raise ValueError(f"expected one free joint, got {len(free)}")
    return free[0]


def _ran(mujoco, model, data, body: int, ball: int) -> dict:
    """What runs, read back from the model and from the top's first contact at t = 0.

    The ball geom's own values when nothing touches then.
    """
    opt = model.opt
    out = {"timestep_s": float(opt.timestep),
           "integrator": mujoco.mjtIntegrator(int(opt.integrator)).name,
           "cone": mujoco.mjtCone(int(opt.cone)).name, "impratio": float(opt.impratio),
           "noslip_iterations": int(opt.noslip_iterations),
           "gravity_mps2": float(-opt.gravity[2]), "iterations": int(opt.iterations),
           "tolerance": float(opt.tolerance),
           "contacts": not int(opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)}
    for i in range(data.ncon):
        c = data.contact[i]
        if body in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]):
            fr = [float(v) for v in c.friction]
            out.update(condim=int(c.dim), coefficients=[fr[0], fr[2], fr[3]],
                       solref=[float(v) for v in c.solref],
                       solimp=[float(v) for v in c.solimp], contact_source="contact at t = 0")
            return out
    out.update(condim=int(model.geom_condim[ball]),
               coefficients=[float(v) for v in model.geom_friction[ball]],
               solref=[float(v) for v in model.geom_solref[ball]],
               solimp=[float(v) for v in model.geom_solimp[ball]],
               contact_source="ball geom (no contact at t = 0)")
    return out


def run(request: dict) -> dict:
    """Run one request; the reply's fields (the arrays go to ``request['out']``)."""
    import mujoco
    import numpy as np

    impl, precision = engine_of(request)
    # MuJoCo's warnings, kept (one line each) as in-process runs keep them, instead of printed
    # on stdout (the reply's channel) and appended to ./MUJOCO_LOG.TXT
    kept: list[str] = []
    if hasattr(mujoco, "set_mju_user_warning"):
        mujoco.set_mju_user_warning(lambda message: kept.append(" ".join(str(message).split())))
    spec = mujoco.MjSpec.from_string(request["mjcf"]) if hasattr(mujoco, "MjSpec") else None
    if spec is not None:
        spec.nuserdata += request.get("userdata", 0)
        model = spec.compile()
    else:  # pragma: no cover - releases before MjSpec
        model = mujoco.MjModel.from_xml_string(request["mjcf"])
    joint = _free_joint(mujoco, model)
    qa, va = int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])
    body = int(model.jnt_bodyid[joint])
    data = mujoco.MjData(model)
    start = request["start"]
    if "keyframe" in start:
        mujoco.mj_resetDataKeyframe(model, data, int(start["keyframe"]))
    else:
        data.qpos[qa:qa + 7] = start["qpos"]
        data.qvel[va:va + 6] = start["qvel"]
    law = None
    if request.get("law") is not None:
        law = PaperLaw(model, {**request["law"], "qpos_adr": qa, "dof_adr": va})
        if impl == "mujoco":  # the others apply a force of their own, armed here afterwards
            mujoco.set_mjcb_passive(law)
    try:
        mujoco.mj_forward(model, data)
        ran = _ran(mujoco, model, data, body, int(request["ball_geom"]))
        steps, n_rows = int(request["steps_per_sample"]), int(request["n_intervals"]) + 1
        nq, nv = model.nq, model.nv
        counts = data.warning.number
        rec = {"time": np.empty(n_rows), "qpos": np.empty((n_rows, nq)),
               "qvel": np.empty((n_rows, nv)), "qacc_warmstart": np.empty((n_rows, nv)),
               "qfrc_constraint": np.empty((n_rows, nv)),
               "warnings": np.zeros((n_rows, len(counts)), dtype=np.int64)}
        mujoco.mj_forward(model, data)  # the contact force of the initial state, for N
        accel = None
        engine: dict[str, Any] = {"implementation": "mujoco", "version": mujoco.__version__,
                                  "precision": "float64", "device": "cpu"}
        if impl != "mujoco":
            t_setup = time.perf_counter()
            kind = MjxStepper if impl == "mjx" else WarpStepper
            accel = kind(mujoco, model, data, int(request["steps_per_sample"]), precision,
                         request.get("law"), qa, va, request.get("compile_cache"))
            engine = {"implementation": impl, "version": accel.version,
                      "precision": accel.precision, "device": accel.device,
                      "device_kind": accel.device_kind, "path": accel.path,
                      "mujoco_c_version": mujoco.__version__,
                      "warnings": f"none counted ({impl} has no warning counters)",
                      "contacts_from": "MuJoCo C at the sample states",
                      "setup_s": time.perf_counter() - t_setup}
            if getattr(accel, "note", None):
                engine["note"] = accel.note
            if law is not None:
                engine["law_applied"] = ("the paper's law in qfrc_applied before each step, "
                                         "from the step's start state and the previous "
                                         "step's qfrc_constraint")
        n, wall0 = 0, time.perf_counter()
        next_report = wall0
        dt = float(model.opt.timestep)
        first_call_s = None
        while True:
            if accel is None:
                rec["time"][n] = data.time
                rec["qpos"][n], rec["qvel"][n] = data.qpos, data.qvel
                rec["qacc_warmstart"][n] = data.qacc_warmstart
                rec["qfrc_constraint"][n] = data.qfrc_constraint
                rec["warnings"][n] = counts
            else:
                (rec["time"][n], rec["qpos"][n], rec["qvel"][n], rec["qacc_warmstart"][n],
                 rec["qfrc_constraint"][n]) = accel.state()
            n += 1
            bad = not (np.isfinite(rec["qpos"][n - 1]).all()
                       and np.isfinite(rec["qvel"][n - 1]).all())
            if bad or rec["warnings"][n - 1].any() or n == n_rows:
                break
            now = time.perf_counter()
            if now >= next_report:
                _say({"t": (n - 1) * steps * dt})
                next_report = now + PROGRESS_S
            if accel is None:
                mujoco.mj_step(model, data, steps)
            else:
                t_call = time.perf_counter()
                accel.advance()
                if first_call_s is None:  # MJX compiles its loop on the first call
                    first_call_s = time.perf_counter() - t_call
        wall_s = time.perf_counter() - wall0
        rec = {k: v[:n] for k, v in rec.items()}
        if accel is not None:
            engine["first_call_s"] = first_call_s
            if law is not None:  # the law's output at the samples, from MuJoCo C's passes
                mujoco.set_mjcb_passive(law)
        # the contacts (and paper mode's forces) at each sample's own state
        scratch = mujoco.MjData(model)
        c_sample, c_geom, c_dist, c_pos, c_frame, c_force = [], [], [], [], [], []
        law_out = np.zeros((n, 3))
        passes = N_FORCE_PASSES if law is not None else 1
        f6 = np.zeros(6)
        for i in range(n):
            scratch.time = rec["time"][i]
            scratch.qpos[:], scratch.qvel[:] = rec["qpos"][i], rec["qvel"][i]
            scratch.qacc_warmstart[:] = rec["qacc_warmstart"][i]
            scratch.qfrc_constraint[:] = rec["qfrc_constraint"][i]
            for k in range(passes):
                if k == 0:
                    mujoco.mj_forward(model, scratch)
                else:  # the same positions: only N and friction change
                    mujoco.mj_forwardSkip(model, scratch, int(mujoco.mjtStage.mjSTAGE_POS), 1)
            for j in range(scratch.ncon):
                c = scratch.contact[j]
                mujoco.mj_contactForce(model, scratch, j, f6)
                c_sample.append(i)
                c_geom.append((int(c.geom1), int(c.geom2)))
                c_dist.append(float(c.dist))
                c_pos.append(np.array(c.pos))
                c_frame.append(np.array(c.frame))
                c_force.append(f6.copy())
            if law is not None:
                fx, fy, _N, power = law.last
                law_out[i] = fx, fy, power
        arrays = {**rec, "contact_sample": np.array(c_sample, dtype=np.int64),
                  "contact_geom": np.array(c_geom, dtype=np.int64).reshape(-1, 2),
                  "contact_dist": np.array(c_dist), "contact_pos": np.array(c_pos).reshape(-1, 3),
                  "contact_frame": np.array(c_frame).reshape(-1, 9),
                  "contact_force": np.array(c_force).reshape(-1, 6), "law_out": law_out}
        np.savez(request["out"], **arrays)
        return {"status": "ok", "samples": n, "wall_s": wall_s, "ran": ran, "engine": engine,
                **({"version": engine["version"], "path": engine["path"]}
                   if accel is not None else {}),
                "warning_text": kept[-1] if kept else None,
                "warning_names": [mujoco.mjtWarning(i).name for i in range(len(counts))]}
    finally:
        if law is not None:
            mujoco.set_mjcb_passive(None)


def main() -> int:
    """Answer requests, one JSON line each on stdin, until its end (exit 0 either way).

    Each request's reply is one JSON line on stdout (after its progress lines): the harness
    keeps the worker for its next request, so the start and the imports are paid once.
    """
    try:
        import mujoco
        import numpy as np
    except ImportError as exc:
        _say({"status": "error", "message": f"expected mujoco and numpy in {sys.executable}, "
              f"got ImportError: {exc}"})
        return 0
    info = {"protocol": PROTOCOL, "version": mujoco.__version__, "numpy": np.__version__,
            "python": ".".join(map(str, sys.version_info[:3])), "executable": sys.executable,
            "path": "plain loop"}
    while True:
        line = sys.stdin.readline()
        if not line:
            return 0
        if line.strip():
            _say({**info, **answer(line)})


def answer(line: str) -> dict:
    """The reply to one request line (a failed run is a reply too, in one line)."""
    try:
        request = json.loads(line)
        if not isinstance(request, dict) or request.get("protocol") != PROTOCOL:
            got = request.get("protocol") if isinstance(request, dict) else request
            raise ValueError(f"expected protocol {PROTOCOL}, got {got!r}")
        return run(request)
    except Refused as exc:  # said as it is
        return {"status": "error", "message": str(exc)}
    except Exception as exc:  # noqa: BLE001 - one failed run, said in one line
        last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
        where = f" ({last[0].name}, line {last[0].lineno})" if last else ""
        # one line: JAX's and Warp's errors span several
        return {"status": "error",
                "message": " ".join(f"{type(exc).__name__}: {exc}{where}".split())[:2000]}

