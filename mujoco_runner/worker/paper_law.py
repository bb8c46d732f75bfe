"""The paper's friction law in the worker, for MuJoCo C and in array arithmetic.

:class:`PaperLaw` is paper mode's law as MuJoCo C's passive callback (``mjcb_passive``): it
steps the plan in a plain MuJoCo, and gives the law's output at the samples of every engine.
:func:`law_force` is the same arithmetic on arrays, which MJX traces in its jitted loop
(:mod:`.mjx_stepper`); Warp's kernel (:mod:`.warp_stepper`) writes it out once more in Warp.
"""

from __future__ import annotations

import math
from typing import Any


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


__all__ = ["PaperLaw", "law_force"]
