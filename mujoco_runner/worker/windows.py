"""What happens between two samples, accumulated at every step: the sample's window.

A run is recorded at samples, one every ``steps`` integration steps, but the contact can change
at every step: a soft contact that touches at some steps and not at others reads as a flight
wherever the sampled steps are the ones without contact. So every sample also carries its
**window**: what the forward passes of the steps since the sample before it computed. Row r's
window holds the forward passes at the states after each of the ``steps`` steps from sample
r - 1 to sample r, the last of them at sample r's own state (``mj_step`` taken apart: each
step's forward pass is done at the end of the step before, where it is the next step's own);
row 0's holds the one pass at the initial state. A pass's **offset** in its window is 1 ..
``steps`` (row 0's pass: 0), so the pass is at time ``t[r - 1] + offset * dt``.

Each window is one row of two arrays, integers (:data:`INT_FIELDS`) and floats
(:data:`FLOAT_FIELDS`), which every engine writes the same: the harness's compiled loop, the
Python loop (:class:`WindowAccumulator`, here and in the harness's own fallback) and a worker
in another Python. The top's contacts are the contacts of which one geom belongs to the top's
body; the ball is the top's ball geom, any other geom of the top is "other" (a stem).

Integer columns:

- ``passes``: forward passes in the window (``steps``; 1 in row 0);
- ``touch``: the contact codes of its passes or-ed: 1 the ball touched at some pass, 2 another
  geom of the top did, 3 both (at the same or other passes);
- ``touch_passes``: passes at which the top touched;
- ``first_touch``, ``last_touch``: the offsets of the first and the last pass at which the top
  touched (-1: none);
- ``inner_free``, ``inner_start``: the longest run of passes without contact between two
  passes of the window at which it touched, and the offset of its first pass (-1: none);
- ``lifts``: passes without contact right after a pass with contact (the starts of the
  stretches without contact; the run's first pass counts when it has no contact);
- ``first_other``: the offset of the first pass at which another geom of the top touched;
- ``flip``: the offset of the first pass at which the symmetry axis points down (``k_z <= 0``,
  theta >= pi/2) after a pass at which it pointed up (the top turning over; -1: none).

Float columns (forces on the top, world frame, SI; each a sum over the window's passes, so
the window's mean is the sum over ``passes`` and its impulse that mean times the window's
time):

- ``gap_max``: the largest gap between the ball and the table (m): the ball's centre height
  less its radius; the table is the plane z = 0;
- ``lead_gap``, ``trail_gap``, ``inner_gap``: the largest gap over the passes without contact
  before the window's first touch, after its last, and in its longest stretch between two
  (``inner_free``), so that each stretch without contact has its own height (-inf: none);
- ``gap_min``: the smallest gap between the ball and the table (m; negative: the ball sunk
  into it);
- ``depth_max``: the deepest penetration of the top's contacts (m, >= 0: -dist);
- ``n_sum``: the normal force of the top's contacts (N);
- ``fx_sum`` .. ``fz_sum``: their friction force (the contact force less its normal part);
- ``tx_sum`` .. ``tz_sum``: their friction torque (torsional and rolling);
- ``power_sum``: their friction power, F . v at each contact point plus tau . omega (W);
- ``law_fx_sum``, ``law_fy_sum``, ``law_power_sum``: paper mode's law as its callback applied
  it at the pass (zeros without a law);
- ``slip_nx_sum``, ``slip_ny_sum``: the slip of the ball's lowest point (its centre less R
  along z), world x and y, times the pass's normal force: over ``n_sum``, the window's slip
  weighted as its force (what the window's mean force is paired with when the friction law a
  run realised is fitted).

This module needs nothing but ``mujoco`` and ``numpy`` (a worker in another Python uses it).
"""

from __future__ import annotations

import math
from typing import NamedTuple

INT_FIELDS = ("passes", "touch", "touch_passes", "first_touch", "last_touch", "inner_free",
              "inner_start", "lifts", "first_other", "flip")
FLOAT_FIELDS = ("gap_max", "lead_gap", "trail_gap", "inner_gap", "depth_max", "n_sum", "fx_sum",
                "fy_sum", "fz_sum", "tx_sum", "ty_sum", "tz_sum", "power_sum", "law_fx_sum",
                "law_fy_sum", "law_power_sum", "gap_min", "slip_nx_sum", "slip_ny_sum")
#: Column numbers, by name.
I = {name: k for k, name in enumerate(INT_FIELDS)}
F = {name: k for k, name in enumerate(FLOAT_FIELDS)}
#: A new window's integers and floats, before its first pass.
INT_START = (0, 0, 0, -1, -1, 0, -1, 0, -1, -1)
FLOAT_START = tuple(-math.inf if name in ("gap_max", "lead_gap", "trail_gap", "inner_gap")
                    else math.inf if name == "gap_min" else 0.0 for name in FLOAT_FIELDS)
#: The contact code of the ball, and of any other geom of the top.
BALL, OTHER = 1, 2


class WindowTop(NamedTuple):
    """Whose contacts a window adds, and what it reads of that body.

    Attributes:
        body: The top's body id.
        ball: The ball geom's id.
        radius_m: The ball's radius (m).
        axis_body: The symmetry axis in the body frame (3 floats).
        qpos_adr: The free joint's first qpos address.
        dof_adr: Its first dof address.
    """

    body: int
    ball: int
    radius_m: float
    axis_body: tuple[float, float, float]
    qpos_adr: int
    dof_adr: int


def new_windows(np, n_rows: int):
    """``(ints, floats)``: ``n_rows`` windows before their first pass (numpy arrays)."""
    ints = np.empty((n_rows, len(INT_FIELDS)), dtype=np.int64)
    ints[:] = INT_START
    floats = np.empty((n_rows, len(FLOAT_FIELDS)))
    floats[:] = FLOAT_START
    return ints, floats


def integrator_call(mujoco, model):
    """The integrator ``mj_step`` calls after its forward pass, for this model; None: unknown.

    ``mj_step`` is ``mj_checkPos``, ``mj_checkVel``, ``mj_forward``, ``mj_checkAcc``, then the
    integrator; the harness steps it so taken apart (bit for bit the same) to read each
    step's forward pass. None where ``mj_step`` does more after its forward pass (the
    forward-inverse comparison, sleeping islands) or the integrator is not known here.
    """
    enabled = int(model.opt.enableflags)
    bits = mujoco.mjtEnableBit
    if enabled & (int(bits.mjENBL_FWDINV) | int(getattr(bits, "mjENBL_SLEEP", 0))):
        return None
    kind = int(model.opt.integrator)
    integ = mujoco.mjtIntegrator
    if kind == int(integ.mjINT_RK4):
        return lambda m, d: mujoco.mj_RungeKutta(m, d, 4)
    if kind == int(integ.mjINT_EULER):
        return mujoco.mj_Euler
    if kind in (int(integ.mjINT_IMPLICIT), int(getattr(integ, "mjINT_IMPLICITFAST", -1))):
        return getattr(mujoco, "mj_implicit", None)
    return None


class WindowAccumulator:
    """Adds each forward pass of one mjData to its window, from Python.

    The same arithmetic as the harness's compiled loop (``mujoco_runner.stepper``): a test
    holds the two equal to rounding.

    Args:
        mujoco: The ``mujoco`` module.
        np: The ``numpy`` module.
        model: The model.
        data: Its mjData (read after each forward pass).
        top: Whose contacts it adds.
        law_output: Paper mode: a function that gives the law's (Fx, Fy, power) as its
            callback applied it at the last forward pass; None: no law.
    """

    def __init__(self, mujoco, np, model, data, top: WindowTop, law_output=None) -> None:
        self.mujoco, self.np, self.model, self.data = mujoco, np, model, data
        self.body, self.ball, self.R = int(top.body), int(top.ball), float(top.radius_m)
        self.axis = np.asarray(top.axis_body, dtype=float)
        self.qa, self.va = int(top.qpos_adr), int(top.dof_adr)
        self.law = law_output
        self.geom_body = np.asarray(model.geom_bodyid, dtype=np.int64)
        self.f6 = np.zeros(6)
        self.prev_touch = True  # a run that starts without contact starts a stretch
        self.prev_kz = math.nan

    def add(self, ints, floats, row: int, offset: int, motion=None) -> None:
        """Add the mjData's last forward pass to window ``row`` as its pass at ``offset``.

        ``motion``: the free joint's (qpos, qvel) at the pass's state, where the mjData has
        moved on since the pass (a whole ``mj_step``: its pass was at the state before it);
        None: the mjData's own.
        """
        np, d = self.np, self.data
        code = 0
        depth = 0.0
        n = 0.0
        f = np.zeros(3)
        tau = np.zeros(3)
        power = 0.0
        xmat = d.xmat[self.body]
        qpos, qvel = motion if motion is not None else (d.qpos[self.qa:self.qa + 7],
                                                        d.qvel[self.va:self.va + 6])
        origin = qpos[0:3]
        v = qvel[0:3]
        wl = qvel[3:6]
        omega = np.array([xmat[0] * wl[0] + xmat[1] * wl[1] + xmat[2] * wl[2],
                          xmat[3] * wl[0] + xmat[4] * wl[1] + xmat[5] * wl[2],
                          xmat[6] * wl[0] + xmat[7] * wl[1] + xmat[8] * wl[2]])
        for k in range(d.ncon):
            c = d.contact[k]
            g1, g2 = int(c.geom1), int(c.geom2)
            b1, b2 = self.geom_body[g1], self.geom_body[g2]
            if b1 != self.body and b2 != self.body:
                continue
            code |= BALL if self.ball in (g1, g2) else OTHER
            depth = max(depth, -float(c.dist))
            self.mujoco.mj_contactForce(self.model, d, k, self.f6)
            s = 1.0 if b2 == self.body else -1.0
            fr = np.asarray(c.frame, dtype=float).reshape(3, 3)
            f6 = self.f6
            n += f6[0]
            friction = s * (f6[1] * fr[1] + f6[2] * fr[2])
            torque = s * (f6[3] * fr[0] + f6[4] * fr[1] + f6[5] * fr[2])
            rx, ry, rz = (float(p) - float(o) for p, o in zip(c.pos, origin, strict=True))
            ox, oy, oz = float(omega[0]), float(omega[1]), float(omega[2])
            ux = float(v[0]) + (oy * rz - oz * ry)  # v + omega x arm, written out as the
            uy = float(v[1]) + (oz * rx - ox * rz)  # compiled loop has it (np.cross and @
            uz = float(v[2]) + (ox * ry - oy * rx)  # cost most of a pass here)
            ax, ay, az = (float(e) for e in friction)
            bx, by, bz = (float(e) for e in torque)
            power += (ax * ux + ay * uy + az * uz) + (bx * ox + by * oy + bz * oz)
            f += friction
            tau += torque
        centre = d.geom_xpos[self.ball]
        gap = float(centre[2]) - self.R
        kz = float(xmat[6] * self.axis[0] + xmat[7] * self.axis[1] + xmat[8] * self.axis[2])
        # the slip of the ball's lowest point, v + omega x (centre - R z - origin)
        ox, oy, oz = float(omega[0]), float(omega[1]), float(omega[2])
        rx = float(centre[0]) - float(origin[0])
        ry = float(centre[1]) - float(origin[1])
        rz = gap - float(origin[2])
        slip_x = float(v[0]) + (oy * rz - oz * ry)
        slip_y = float(v[1]) + (oz * rx - ox * rz)
        wi, wf = ints[row], floats[row]
        wi[I["passes"]] += 1
        if code:
            trail = wf[F["trail_gap"]]
            wf[F["trail_gap"]] = -math.inf
            wi[I["touch"]] |= code
            wi[I["touch_passes"]] += 1
            if wi[I["first_touch"]] < 0:
                wi[I["first_touch"]] = offset
            last = wi[I["last_touch"]]
            if last >= 0 and offset - last - 1 > wi[I["inner_free"]]:
                wi[I["inner_free"]] = offset - last - 1
                wi[I["inner_start"]] = last + 1
                wf[F["inner_gap"]] = trail
            wi[I["last_touch"]] = offset
            if code & OTHER and wi[I["first_other"]] < 0:
                wi[I["first_other"]] = offset
        else:
            if self.prev_touch:
                wi[I["lifts"]] += 1
            wf[F["trail_gap"]] = max(wf[F["trail_gap"]], gap)
            if wi[I["first_touch"]] < 0:
                wf[F["lead_gap"]] = max(wf[F["lead_gap"]], gap)
        self.prev_touch = code != 0
        if self.prev_kz > 0.0 and kz <= 0.0 and wi[I["flip"]] < 0:
            wi[I["flip"]] = offset
        self.prev_kz = kz
        wf[F["gap_max"]] = max(wf[F["gap_max"]], gap)
        wf[F["gap_min"]] = min(wf[F["gap_min"]], gap)
        wf[F["depth_max"]] = max(wf[F["depth_max"]], depth)
        wf[F["slip_nx_sum"]] += n * slip_x
        wf[F["slip_ny_sum"]] += n * slip_y
        wf[F["n_sum"]] += n
        wf[F["fx_sum"]:F["fz_sum"] + 1] += f
        wf[F["tx_sum"]:F["tz_sum"] + 1] += tau
        wf[F["power_sum"]] += power
        if self.law is not None:
            fx, fy, p = self.law()
            wf[F["law_fx_sum"]] += fx
            wf[F["law_fy_sum"]] += fy
            wf[F["law_power_sum"]] += p


__all__ = ["BALL", "F", "FLOAT_FIELDS", "FLOAT_START", "I", "INT_FIELDS", "INT_START", "OTHER",
           "WindowAccumulator", "WindowTop", "integrator_call", "new_windows"]
