"""MuJoCo Warp steps a plan's sample intervals on Warp's default device, in float32.

The interval's steps are captured once as a Warp graph (``mjw.step`` in a loop where capture
fails); in paper mode a Warp kernel (:func:`warp_law_kernel`) puts the law's force into
``qfrc_applied`` before each step, inside the graph.
"""

from __future__ import annotations

import sys
from typing import Any

from .protocol import PACKAGES, Refused, package_version, stdout_to_stderr


def warp_law_kernel(wp: Any) -> Any:
    """:func:`.paper_law.law_force` as a Warp kernel, one thread a world.

    The law's force goes into ``qfrc_applied``, from ``qpos``, ``qvel`` and the previous
    step's ``qfrc_constraint``. The same arithmetic as :class:`.paper_law.PaperLaw` in float32
    (Warp's ``float``), its branches on the state as Warp's dynamic ``if``; it runs in the
    captured graph before each step.
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
            with stdout_to_stderr():
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
        self.version = package_version(PACKAGES["warp"])
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


__all__ = ["WarpStepper", "warp_law_kernel"]
