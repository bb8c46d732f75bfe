"""MuJoCo Warp steps a plan's sample intervals on Warp's default device, windows and all.

In float32. Each step is ``mjw.step`` taken apart as MuJoCo C's ``mj_step`` is in the harness (the
integrator, then the next step's forward pass, ``mjw.forward``), and that pass is added to
the sample's window on the device by a Warp kernel (:func:`warp_window_kernels`, the
arithmetic of :class:`.windows.WindowAccumulator`); the interval's steps are captured once as
a Warp graph (run in a loop where capture fails), so nothing is read back between two
samples. In paper mode a Warp kernel (:func:`warp_law_kernel`) puts the law's force into
``qfrc_applied`` before each forward pass, inside the graph.
"""

from __future__ import annotations

import sys
from typing import Any

from .protocol import PACKAGES, Refused, package_version, stdout_to_stderr
from .windows import FLOAT_START, INT_START, F, I, WindowTop

#: What Warp's windows read of each pass (the engine reply's ``contacts_from``).
WARP_CONTACTS_FROM = (
    "Warp's own forward pass at every step, its window added on the device: touch, depth and "
    "the stretches from the contacts Warp's collision wrote (d.nacon, as MuJoCo C's "
    "d.contact); N and the friction force from qfrc_constraint of the top's free joint (the "
    "world force of its contacts), friction torque not read (0), friction power and the "
    "slip (times N) at the ball's lowest point")

#: The window columns the kernel writes, in the order of its column arguments (``ic``, ``fc``:
#: their numbers in :mod:`.windows`' rows, looked up there); any other column keeps its start.
KERNEL_INTS = ("passes", "touch", "touch_passes", "first_touch", "last_touch", "inner_free",
               "inner_start", "lifts", "first_other", "flip")
KERNEL_FLOATS = ("gap_max", "lead_gap", "trail_gap", "inner_gap", "depth_max", "n_sum",
                 "fx_sum", "fy_sum", "power_sum", "law_fx_sum", "law_fy_sum", "law_power_sum",
                 "gap_min", "slip_nx_sum", "slip_ny_sum")


def warp_law_kernel(wp: Any) -> Any:
    """:func:`.paper_law.law_force` as a Warp kernel, one thread a world.

    The law's force goes into ``qfrc_applied``, from ``qpos``, ``qvel`` and the last
    evaluation's ``qfrc_constraint``, and its (Fx, Fy, power) into ``law_out`` (the
    windows' law columns). The same arithmetic as :class:`.paper_law.PaperLaw` in float32
    (Warp's ``float``), its branches on the state as Warp's dynamic ``if``; it runs in the
    captured graph before each forward pass.
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
                  qcon: wp.array2d(dtype=float), qfrc: wp.array2d(dtype=float),
                  law_out: wp.array2d(dtype=float), qa: int,
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
        power = F[0] * v1[0] + F[1] * v1[1]
        if stem_kind != 0:
            v2 = v0 + wp.cross(om, b)
            F2 = slip_force(v2[0], v2[1], N2, kind, viscous_on, mu, lam, visc, v_eps)
            f2 = wp.vec3(F2[0], F2[1], 0.0)
            f = f + f2
            tau = tau + wp.cross(b, f2)
            power = power + F2[0] * v2[0] + F2[1] * v2[1]
        tb = wp.transpose(rot) @ tau
        qfrc[i, va] = f[0]
        qfrc[i, va + 1] = f[1]
        qfrc[i, va + 2] = 0.0
        qfrc[i, va + 3] = tb[0]
        qfrc[i, va + 4] = tb[1]
        qfrc[i, va + 5] = tb[2]
        law_out[i, 0] = f[0]
        law_out[i, 1] = f[1]
        law_out[i, 2] = power

    return paper_law


def warp_window_kernels(wp: Any) -> tuple[Any, Any, Any]:
    """The windows' Warp kernels: ``(reset, add, keep)``, one thread (world 0).

    ``reset`` sets a window to its start (:data:`.windows.INT_START`, ``FLOAT_START``);
    ``add`` adds the data's last forward pass to it at an offset, as
    :class:`.windows.WindowAccumulator` does but reading what Warp has: the contacts Warp's
    collision wrote (``d.nacon`` of them, those of world 0 meant for the constraint solver,
    as MuJoCo C's ``d.contact``), and the forces of all the top's contacts at once from its
    free joint's ``qfrc_constraint`` (the first three dofs are the world force on the body:
    z is the normal force on the table, x and y the friction; no friction torque, the power
    and the slip at the ball's lowest point). The window's floats are float64, Warp's data
    float32. It writes the columns :data:`KERNEL_INTS` and :data:`KERNEL_FLOATS` (their
    numbers given as ``ic`` and ``fc``, each read once by its slot); any other keeps its
    start (``fz_sum`` and the torques: 0).
    ``keep`` copies world 0's ``qfrc_constraint`` (the record's, as the interval's last step
    left it).
    """

    @wp.kernel
    def reset(istart: wp.array(dtype=int), fstart: wp.array(dtype=wp.float64),
              wi: wp.array(dtype=int), wf: wp.array(dtype=wp.float64)):
        # (wp in each kernel's body: Warp reads the annotations with its closure's names)
        for k in range(wp.min(istart.shape[0], wi.shape[0])):
            wi[k] = istart[k]
        for k in range(wp.min(fstart.shape[0], wf.shape[0])):
            wf[k] = fstart[k]

    @wp.kernel
    def keep(qcon: wp.array2d(dtype=float), out: wp.array(dtype=float)):
        for k in range(wp.min(out.shape[0], qcon.shape[1])):
            out[k] = qcon[0, k]

    @wp.kernel
    def add(nacon: wp.array(dtype=int), naconmax: int, cdist: wp.array(dtype=float),
            cgeom: wp.array(dtype=wp.vec2i), cworld: wp.array(dtype=int),
            ctype: wp.array(dtype=int), gbody: wp.array(dtype=int),
            xmat: wp.array2d(dtype=wp.mat33), gxpos: wp.array2d(dtype=wp.vec3),
            qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float),
            qcon: wp.array2d(dtype=float), law_out: wp.array2d(dtype=float), law_on: int,
            body: int, ball: int, R: float, axis: wp.vec3, qa: int, va: int, offset: int,
            ic: wp.array(dtype=int), fc: wp.array(dtype=int),
            fstart: wp.array(dtype=wp.float64), wi: wp.array(dtype=int),
            wf: wp.array(dtype=wp.float64), prev: wp.array(dtype=wp.float64)):
        code = int(0)  # noqa: UP018 - Warp: a variable, not a constant
        depth = float(0.0)  # noqa: UP018
        nc = wp.min(nacon[0], naconmax)
        for k in range(nc):
            g = cgeom[k]
            if cworld[k] == 0 and (ctype[k] & 1) != 0 and g[0] >= 0 and g[1] >= 0:
                if gbody[g[0]] == body or gbody[g[1]] == body:
                    if g[0] == ball or g[1] == ball:
                        code = code | 1
                    else:
                        code = code | 2
                    depth = wp.max(depth, -cdist[k])
        rot = xmat[0, body]
        om = rot @ wp.vec3(qvel[0, va + 3], qvel[0, va + 4], qvel[0, va + 5])
        c = gxpos[0, ball]
        arm = c - wp.vec3(qpos[0, qa], qpos[0, qa + 1], qpos[0, qa + 2] + R)
        v = wp.vec3(qvel[0, va], qvel[0, va + 1], qvel[0, va + 2]) + wp.cross(om, arm)
        fx = qcon[0, va]
        fy = qcon[0, va + 1]
        n = qcon[0, va + 2]
        power = fx * v[0] + fy * v[1]
        gap = wp.float64(c[2] - R)
        kz = wp.float64(rot[2, 0] * axis[0] + rot[2, 1] * axis[1] + rot[2, 2] * axis[2])
        # the columns (KERNEL_INTS, KERNEL_FLOATS)
        passes = ic[0]
        touch = ic[1]
        touch_passes = ic[2]
        first = ic[3]
        last_touch = ic[4]
        inner = ic[5]
        inner_start = ic[6]
        lifts = ic[7]
        other = ic[8]
        flip = ic[9]
        gap_max = fc[0]
        lead = fc[1]
        trail_gap = fc[2]
        inner_gap = fc[3]
        depth_max = fc[4]
        n_sum = fc[5]
        fx_sum = fc[6]
        fy_sum = fc[7]
        power_sum = fc[8]
        law_fx = fc[9]
        law_fy = fc[10]
        law_power = fc[11]
        gap_min = fc[12]
        slip_nx = fc[13]
        slip_ny = fc[14]
        wi[passes] = wi[passes] + 1
        if code != 0:
            trail = wf[trail_gap]
            wf[trail_gap] = fstart[trail_gap]
            wi[touch] = wi[touch] | code
            wi[touch_passes] = wi[touch_passes] + 1
            if wi[first] < 0:
                wi[first] = offset
            last = wi[last_touch]
            if last >= 0 and offset - last - 1 > wi[inner]:
                wi[inner] = offset - last - 1
                wi[inner_start] = last + 1
                wf[inner_gap] = trail
            wi[last_touch] = offset
            if (code & 2) != 0 and wi[other] < 0:
                wi[other] = offset
        else:
            if prev[0] != wp.float64(0.0):
                wi[lifts] = wi[lifts] + 1
            wf[trail_gap] = wp.max(wf[trail_gap], gap)
            if wi[first] < 0:
                wf[lead] = wp.max(wf[lead], gap)
        if code != 0:
            prev[0] = wp.float64(1.0)
        else:
            prev[0] = wp.float64(0.0)
        if prev[1] > wp.float64(0.0) and kz <= wp.float64(0.0) and wi[flip] < 0:
            wi[flip] = offset
        prev[1] = kz
        wf[gap_max] = wp.max(wf[gap_max], gap)
        wf[gap_min] = wp.min(wf[gap_min], gap)
        wf[depth_max] = wp.max(wf[depth_max], wp.float64(depth))
        wf[n_sum] = wf[n_sum] + wp.float64(n)
        wf[fx_sum] = wf[fx_sum] + wp.float64(fx)
        wf[fy_sum] = wf[fy_sum] + wp.float64(fy)
        wf[power_sum] = wf[power_sum] + wp.float64(power)
        # the lowest point's slip times N (float32 each: their product exact in float64)
        wf[slip_nx] = wf[slip_nx] + wp.float64(n) * wp.float64(v[0])
        wf[slip_ny] = wf[slip_ny] + wp.float64(n) * wp.float64(v[1])
        if law_on != 0:
            wf[law_fx] = wf[law_fx] + wp.float64(law_out[0, 0])
            wf[law_fy] = wf[law_fy] + wp.float64(law_out[0, 1])
            wf[law_power] = wf[law_power] + wp.float64(law_out[0, 2])

    return reset, add, keep


class WarpStepper:
    """A plan's sample intervals stepped by MuJoCo Warp on Warp's default device.

    Each step is the model's integrator (``mjw.euler``, ``mjw.rungekutta4``,
    ``mjw.implicit``: what ``mjw.step`` calls after its forward pass), then the paper law's
    kernel (:func:`warp_law_kernel`) when ``law`` is given, then ``mjw.forward`` and the
    window's kernel (:func:`warp_window_kernels`): ``mjw.step`` taken apart, each step's
    forward pass done at the end of the step before, as the harness steps MuJoCo C, so the
    windows have MuJoCo C's offsets (``mjw.step`` itself would leave RK4's last stage's
    contacts and kinematics in the data). The interval's ``steps`` of them are captured once
    as a Warp graph and the graph launched per interval; where capture fails, they run in a
    loop. Row 0's one pass (:meth:`first`) runs outside the graph.

    What differs from MuJoCo C's windows (:data:`WARP_CONTACTS_FROM`): the forces are the
    free joint's ``qfrc_constraint`` (:func:`warp_window_kernels`), not ``mj_contactForce``
    per contact, in float32; a contact at dist exactly 0, which MuJoCo C keeps, Warp's
    collision does not write.
    """

    contacts_from = WARP_CONTACTS_FROM

    def __init__(self, mujoco, model, data, steps: int, precision: str,
                 law: dict | None, top: WindowTop, cache_dir: str | None = None) -> None:
        try:
            with stdout_to_stderr():
                import warp as wp
                wp.config.quiet = True
                import mujoco_warp as mjw
                wp.init()
        except ImportError as exc:
            raise Refused(f"engine warp: expected mujoco-warp and warp-lang in "
                          f"{sys.executable}, got ImportError: {exc}") from None
        import numpy as np

        self.wp, self.mjw, self.steps = wp, mjw, steps
        self.dev = wp.get_device()
        self.top = top
        qa, va = top.qpos_adr, top.dof_adr
        kind = int(model.opt.integrator)
        integ = mujoco.mjtIntegrator
        integrators = {int(integ.mjINT_EULER): mjw.euler, int(integ.mjINT_RK4): mjw.rungekutta4,
                       int(integ.mjINT_IMPLICIT): mjw.implicit,
                       int(integ.mjINT_IMPLICITFAST): mjw.implicit}
        if kind not in integrators:
            raise Refused(f"engine warp: expected the Euler, RK4, implicit or implicitfast "
                          f"integrator, got {integ(kind).name}")
        self.integrate = integrators[kind]
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
        self.reset_kernel, self.add_kernel, self.keep_kernel = warp_window_kernels(wp)
        with wp.ScopedDevice(self.dev):
            self.m = mjw.put_model(model)
            self.law_out = wp.zeros((1, 3), dtype=float)
            self.istart = wp.array(np.asarray(INT_START, dtype=np.int32), dtype=int)
            self.fstart = wp.array(np.asarray(FLOAT_START, dtype=np.float64), dtype=wp.float64)
            self.wi = wp.array(np.asarray(INT_START, dtype=np.int32), dtype=int)
            self.wf = wp.array(np.asarray(FLOAT_START, dtype=np.float64), dtype=wp.float64)
            # a run that starts without contact starts a stretch; no k_z before the first pass
            self.prev = wp.array(np.array([1.0, np.nan]), dtype=wp.float64)
            self.con = wp.zeros(model.nv, dtype=float)
            self.gbody = wp.array(np.asarray(model.geom_bodyid, dtype=np.int32), dtype=int)
            self.ic = wp.array(np.array([I[c] for c in KERNEL_INTS], dtype=np.int32), dtype=int)
            self.fc = wp.array(np.array([F[c] for c in KERNEL_FLOATS], dtype=np.int32),
                               dtype=int)
            warm = mjw.put_data(model, data)
            self._pass(warm, 0)  # compiles (or loads) the kernels outside any capture
            self._step(warm, 1, last=True)
            self.prev.assign(np.array([1.0, np.nan]))
            self.d = mjw.put_data(model, data)
            self.graph = None
            try:
                with wp.ScopedCapture() as cap:
                    self._interval(self.d)
                self.graph = cap.graph
            except Exception:  # noqa: BLE001 - no capture here: the plain loop
                self.d = mjw.put_data(model, data)
        self.version = package_version(PACKAGES["warp"])
        self.precision = str(self.d.qpos.numpy().dtype)
        self.device = str(self.dev.alias)
        self.device_kind = str(self.dev.name)
        self.path = ("warp: captured graph of integrate, forward, window"
                     if self.graph is not None else "warp: loop of integrate, forward, window")

    def _pass(self, d: Any, offset: int) -> None:
        """The law's force into ``qfrc_applied`` (paper mode), the forward pass, its window."""
        wp = self.wp
        law_on = 0
        if self.law is not None:
            kernel, p = self.law
            wp.launch(kernel, dim=d.qpos.shape[0],
                      inputs=[d.qpos, d.qvel, d.qfrc_constraint, d.qfrc_applied,
                              self.law_out, p["qa"], p["va"], p["centre"], p["axis"], p["R"],
                              p["stem_kind"], p["stem_l"], p["stem_r"], p["kind"],
                              p["viscous_on"], p["mu"], p["lam"], p["visc"], p["v_eps"]])
            law_on = 1
        self.mjw.forward(self.m, d)
        top = self.top
        c = d.contact
        wp.launch(self.add_kernel, dim=1,
                  inputs=[d.nacon, int(d.naconmax), c.dist, c.geom, c.worldid, c.type,
                          self.gbody, d.xmat, d.geom_xpos, d.qpos, d.qvel, d.qfrc_constraint,
                          self.law_out, law_on, int(top.body), int(top.ball),
                          float(top.radius_m), wp.vec3(*top.axis_body), int(top.qpos_adr),
                          int(top.dof_adr), int(offset), self.ic, self.fc, self.fstart,
                          self.wi, self.wf, self.prev])

    def _step(self, d: Any, offset: int, *, last: bool) -> None:
        """One step: the integrator, then the next step's pass (at ``offset``)."""
        self.integrate(self.m, d)
        if last:  # the record's qfrc_constraint, as the step left it
            self.wp.launch(self.keep_kernel, dim=1, inputs=[d.qfrc_constraint, self.con])
        self._pass(d, offset)

    def _reset(self) -> None:
        self.wp.launch(self.reset_kernel, dim=1,
                       inputs=[self.istart, self.fstart, self.wi, self.wf])

    def _interval(self, d: Any) -> None:
        """A sample interval: the window reset, then ``steps`` steps."""
        self._reset()
        for j in range(1, self.steps + 1):
            self._step(d, j, last=j == self.steps)

    def first(self) -> None:
        """Row 0: the one pass at the start's state, added to its window."""
        with self.wp.ScopedDevice(self.dev):
            self._reset()
            self.wp.launch(self.keep_kernel, dim=1, inputs=[self.d.qfrc_constraint, self.con])
            self._pass(self.d, 0)

    def advance(self) -> None:
        """Step one sample interval, each step's pass added to its window."""
        with self.wp.ScopedDevice(self.dev):
            if self.graph is not None:
                self.wp.capture_launch(self.graph)
            else:
                self._interval(self.d)

    def state(self) -> tuple[Any, ...]:
        """time, qpos, qvel, qacc_warmstart, qfrc_constraint, read back (float64 numpy).

        ``qfrc_constraint`` as the interval's last step left it, before the pass at the
        sample's state (MuJoCo C's record has it so).
        """
        import numpy as np

        d = self.d
        return (float(d.time.numpy()[0]),) + tuple(
            np.asarray(a.numpy()[0], dtype=np.float64) for a in (
                d.qpos, d.qvel, d.qacc_warmstart)) + (
            np.asarray(self.con.numpy(), dtype=np.float64),)

    def window(self) -> tuple[Any, Any]:
        """The last call's window: its integer and float columns (int64, float64 numpy)."""
        import numpy as np

        return (np.asarray(self.wi.numpy(), dtype=np.int64),
                np.asarray(self.wf.numpy(), dtype=np.float64))


__all__ = ["KERNEL_FLOATS", "KERNEL_INTS", "WARP_CONTACTS_FROM", "WarpStepper",
           "warp_law_kernel", "warp_window_kernels"]
