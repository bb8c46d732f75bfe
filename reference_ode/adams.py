"""A compiled variable-order, variable-step Adams PECE integrator (Shampine-Gordon's STEP).

The method of Shampine and Gordon's DE/STEP/INTRP (Computer Solution of Ordinary Differential
Equations, 1975; Hairer-Norsett-Wanner I, III.5 and III.7): Adams-Bashforth predictor of order
k, Adams-Moulton corrector of order k + 1 (local extrapolation) in modified divided-difference
form, one evaluation after the prediction and one after the correction (PECE, two evaluations
a step), orders 1..12 chosen from the error estimates of orders k-2..k+1, the step doubled or
cut to between 1/2 and 9/10 (so that long runs of equal steps keep the coefficients), and the
interpolating polynomial of the last step (INTRP) as dense output. Rounding is compensated as
STEP does for tight tolerances (phi's rows 15 and 16), always.

The contract is :func:`reference_ode.dop853.dop853_run`'s (statuses, ``stats`` slots, events,
samples, chunks). :func:`new_stats` appends the method's history (the divided differences, the
step sizes, the order, the coefficients) to the shared slots, so that a run split into chunks
takes the same steps as one call; ``stats[S_H] = 0`` starts afresh (order 1, no history).

The error is measured as dop853's: the RMS over the components of the estimate scaled by
``atol + rtol |y|`` (STEP's test ``err <= eps`` with ``eps = 1``; STEP itself uses the
2-norm, sqrt(n) times larger).

Stiffness: after the correction, ``L = |f(y_c) - f(y_p)| / |y_c - y_p|`` estimates the
Lipschitz constant in the direction the correction moved (the stiff direction when stability
limits the step). A step is flagged stiff (``S_NSTIFF``) when its order is at most
:data:`STIFF_MAX_ORDER` and ``h L`` exceeds :data:`STIFF_FRACTION` of the PECE pair's
stability boundary on the negative real axis at the step's order (:data:`STAB_BOUNDARY`,
computed for equal steps from the spectral radius of the recurrence of y' = lambda y;
tests/reference_ode/test_adams.py checks the table). Only low orders count because stiffness
drives an Adams code to them (their stability regions are the largest), while a non-stiff
oscillatory problem runs at high orders with h |lambda| beyond their small real-axis
boundaries: the oscillator of the tests is never flagged, y' = -1000 y has a third of its
steps flagged (all its order <= 4 steps), the stiff Fig. 3 top (Lambda = 1e-6 m/s) enters its
rolling phase at the same time as under DOP853. Adams' stability regions are smaller than
DOP853's (2.4 at most against ~6): the law at Lambda = 1e-4 m/s, which DOP853 never flags, is
stiff for Adams (a third of its steps flagged at rtol 1e-9). Had this flag decided on rolling
phases, ``stiff='auto'`` would roll there (Fig. 3, 8 s: theta 1.3e-5 rad off the law, the
rolling reduction's error, measured) where DOP853 integrates the law; so solve.py hands a stretch
this flag calls stiff over to DOP853, whose detector decides (``Method.hands_over_stiff``).
"""

from __future__ import annotations

from functools import cache
from types import ModuleType

import numba as nb
import numpy as np

from tippetop.reference_ode import driver
from tippetop.reference_ode.dop853 import (  # noqa: F401 (the contract's names, re-exported)
    N_STATS,
    RHS_TYPE,
    S_H,
    S_HLAMBDA_MAX,
    S_MONITOR_MIN,
    S_NREJECT,
    S_NRHS,
    S_NSTEPS,
    S_NSTIFF,
    S_STIFF_STOP,
    S_T_MARK,
    STATUS_GUARD,
    STATUS_MAX_STEPS,
    STATUS_MONITOR,
    STATUS_OK,
    STATUS_RUNNING,
    STATUS_STEP_TOO_SMALL,
    STATUS_STIFF,
    WATCH_TYPE,
)
from tippetop.reference_ode.dop853 import new_stats as _dop_stats
from tippetop.reference_ode.driver import Parts

MAX_ORDER = 12
LANES = 4  # the difference rows are padded to a multiple of 4 float64 (as dop853)

#: STEP's gstr: |gamma*_k|-like factors of the error estimates at orders k-2..k+1.
GSTR = np.array([0.0, 0.500, 0.0833, 0.0417, 0.0264, 0.0188, 0.0143, 0.0114, 0.00936,
                 0.00789, 0.00679, 0.00592, 0.00524, 0.00468])
#: 2^k (index k, 1-based as STEP's ``two``).
TWO = np.array([0.0] + [2.0 ** i for i in range(1, 14)])

#: -(the negative real axis' stability boundary) of the PECE pair at order k (index k): the
#: z = h lambda < 0 nearest 0 where the amplification of y' = lambda y with equal steps exceeds
#: 1 (AB_k predictor, order k+1 corrector, f evaluated at the corrected value).
STAB_BOUNDARY = np.array([0.0, 2.000, 2.400, 1.935, 1.412, 1.039, 0.773, 0.580, 0.439, 0.337,
                          0.264, 0.210, 0.0617])
#: A step is flagged stiff when h L > STIFF_FRACTION * STAB_BOUNDARY[k] (as dop853's 6.1 of
#: its boundary, about 0.9 of it).
STIFF_FRACTION = 0.9
#: ... and only at orders up to 4: stiffness drives an Adams code to low orders, whose
#: stability regions are the largest (DE's own test: 50 steps in a row at order <= 4), while a
#: non-stiff oscillatory problem runs at high orders with h |lambda| beyond their small
#: real-axis boundaries (lambda on the imaginary axis).
STIFF_MAX_ORDER = 4

_V = nb.types.float64[::1]
_M = nb.types.float64[:, ::1]
_F8 = nb.types.float64
_I8 = nb.types.int64
_OPTS = {"cache": True, "error_model": "numpy"}

# ---------------------------------------------------------------- the workspace in stats
# scalars after the shared slots, then the coefficient vectors (1-based, as STEP's), then phi
A_K = N_STATS  # the order of the next step
A_KOLD = N_STATS + 1  # the order of the last accepted step (0 before the first)
A_NS = N_STATS + 2  # steps taken with the current step size
A_HOLD = N_STATS + 3  # the last accepted step
A_PHASE1 = N_STATS + 4  # 1 while the start-up phase raises the order every step
_NV = 14  # length of each coefficient vector (indices 1..13 used)
A_PSI = N_STATS + 5
A_ALPHA = A_PSI + _NV
A_BETA = A_ALPHA + _NV
A_SIG = A_BETA + _NV
A_V = A_SIG + _NV
A_W = A_V + _NV
A_G = A_W + _NV
A_PHI = A_G + _NV
_NPHI = 17  # phi's rows 1..16 (row 0 unused)


def _padded(n: int) -> int:
    return (n + LANES - 1) // LANES * LANES


def new_stats(n: int) -> np.ndarray:
    """A fresh ``stats`` vector: dop853's slots, then the Adams history for a state of size n."""
    stats = np.zeros(A_PHI + _NPHI * _padded(n))
    stats[:N_STATS] = _dop_stats(n)
    return stats


# ---------------------------------------------------------------- dense output (INTRP)
@nb.njit(nb.types.none(_M, _V, _V, _I8, _F8, _V, _V), **_OPTS)
def interp(phi, psi, y, kold, hi, work, out):
    """The solution at ``t + hi`` on the last step's polynomial (STEP's INTRP).

    ``phi``, ``psi`` and ``kold`` as left by an accepted step ending at (t, ``y``); ``work``
    scratch of >= 42 entries; ``out`` receives the state (n entries).
    """
    n = out.size
    ki = kold + 1
    kip1 = ki + 1
    g = work[0:14]
    w = work[14:28]
    for i in range(1, ki + 1):
        w[i] = 1.0 / i
    g[1] = 1.0
    term = 0.0
    for j in range(2, ki + 1):
        psijm1 = psi[j - 1]
        gamma = (hi + term) / psijm1
        eta = hi / psijm1
        for i in range(1, kip1 - j + 1):
            w[i] = gamma * w[i] - eta * w[i + 1]
        g[j] = w[1]
        term = psijm1
    for l in range(n):
        out[l] = 0.0
    for j in range(1, ki + 1):
        i = kip1 - j
        gi = g[i]
        for l in range(n):
            out[l] += gi * phi[i, l]
    for l in range(n):
        out[l] = y[l] + hi * out[l]


# ---------------------------------------------------------------- the kernel's parts
# The driver (reference_ode/driver.py) writes the kernel from them. The dense output is
# INTRP on the last step's polynomial, read relative to the step's end.
#: The buffers and the history's views.
_SETUP = """
m = (n + LANES - 1) // LANES * LANES
phi = stats[A_PHI:A_PHI + _NPHI * m].reshape((_NPHI, m))
psi = stats[A_PSI:A_PSI + _NV]
alpha = stats[A_ALPHA:A_ALPHA + _NV]
beta = stats[A_BETA:A_BETA + _NV]
sig = stats[A_SIG:A_SIG + _NV]
v = stats[A_V:A_V + _NV]
w = stats[A_W:A_W + _NV]
g = stats[A_G:A_G + _NV]
yc = np.zeros(m)  # the state at t
pr = np.zeros(m)  # the prediction
fp = np.zeros(m)  # f(prediction)
fc = np.zeros(m)  # f(correction)
wt = np.zeros(m)  # 1 / (atol + rtol |y|), 0 in the padding
yt = np.zeros(m)
dy_pad = np.zeros(m)
work = np.zeros(42)
yc_v = yc[:n]
pr_v = pr[:n]
fp_v = fp[:n]
fc_v = fc[:n]
yt_v = yt[:n]
dy = dy_pad[:n]
"""

#: The start: afresh (STEP's block 0: order 1, a step from |f|) or the history carried.
_START = """
h = stats[S_H]
if not h > 0.0:
    # start afresh (STEP's block 0): order 1, phi(1) = f, a step from |f|
    for r in range(_NPHI):
        for i in range(m):
            phi[r, i] = 0.0
    s = 0.0
    for i in range(n):
        phi[1, i] = dy[i]
        s += (dy[i] / (atol + rtol * abs(yc[i]))) ** 2
    s = math.sqrt(s / n)
    h = t_end - t
    if 1.0 < 16.0 * s * h * h:
        h = 0.25 * math.sqrt(1.0 / s)
    h = max(h, 4.0 * abs(np.nextafter(t, np.inf) - t))
    k = 1
    kold = 0
    ns = 0
    hold = 0.0
    phase1 = True
else:
    k = int(stats[A_K])
    kold = int(stats[A_KOLD])
    ns = int(stats[A_NS])
    hold = stats[A_HOLD]
    phase1 = stats[A_PHASE1] > 0.0
g[1] = 1.0
g[2] = 0.5
sig[1] = 1.0
"""

#: STEP's blocks 1-4: the attempts until one is accepted, then the correction, the
#: stiffness flag and the next step's order and size.
_STEP = """
for i in range(n):
    wt[i] = 1.0 / (atol + rtol * abs(yc[i]))
if t + h > t_end:  # never beyond t_end (a changed step: STEP's ns restarts)
    h = t_end - t
ifail = 0
knew = k
erk = 0.0
erkm1 = 0.0
while True:
    if not h >= min_step:  # also a NaN step
        status = STATUS_STEP_TOO_SMALL
        break
    # --- block 1: the coefficients (those that change with h)
    kp1 = k + 1
    kp2 = k + 2
    km1 = k - 1
    km2 = k - 2
    if h != hold:
        ns = 0
    if ns <= kold:
        ns += 1
    nsp1 = ns + 1
    if k >= ns:
        beta[ns] = 1.0
        alpha[ns] = 1.0 / ns
        temp1 = h * ns
        sig[nsp1] = 1.0
        for i in range(nsp1, k + 1):
            temp2 = psi[i - 1]
            psi[i - 1] = temp1
            beta[i] = beta[i - 1] * psi[i - 1] / temp2
            temp1 = temp2 + h
            alpha[i] = h / temp1
            sig[i + 1] = i * alpha[i] * sig[i]
        psi[k] = temp1
        if ns <= 1:
            for iq in range(1, k + 1):
                v[iq] = 1.0 / (iq * (iq + 1))
                w[iq] = v[iq]
        else:
            if k > kold:
                v[k] = 1.0 / (k * kp1)
                for j in range(1, ns - 1):
                    i = k - j
                    v[i] = v[i] - alpha[j + 1] * v[i + 1]
            temp5 = alpha[ns]
            for iq in range(1, kp1 - ns + 1):
                v[iq] = v[iq] - temp5 * v[iq + 1]
                w[iq] = v[iq]
            g[nsp1] = w[1]
        for i in range(ns + 2, kp1 + 1):
            temp6 = alpha[i - 1]
            for iq in range(1, kp2 - i + 1):
                w[iq] = w[iq] - temp6 * w[iq + 1]
            g[i] = w[1]
    # --- block 2: predict (phi to phi*, the prediction, the predicted differences)
    for r in range(nsp1, k + 1):
        b = beta[r]
        for i in range(m):
            phi[r, i] = b * phi[r, i]
    for i in range(m):
        phi[kp2, i] = phi[kp1, i]
        phi[kp1, i] = 0.0
        yt[i] = 0.0
    for j in range(1, k + 1):
        r = kp1 - j
        gr = g[r]
        for i in range(m):
            yt[i] += gr * phi[r, i]
            phi[r, i] += phi[r + 1, i]
    for i in range(m):
        tau = h * yt[i] - phi[15, i]
        pr[i] = yc[i] + tau
        phi[16, i] = (pr[i] - yc[i]) - tau
    g_p = rhs(pr_v, p, fp_v)
    stats[S_NRHS] += 1
    # the error estimates at orders k, k-1, k-2 (as if the steps were equal)
    sk = 0.0
    skm1 = 0.0
    skm2 = 0.0
    # (rows k and k-1 exist for every k >= 1: row 0 is zeros; unused sums are dropped)
    for i in range(m):
        d = (fp[i] - phi[1, i]) * wt[i]
        e1 = phi[k, i] * wt[i] + d
        e2 = phi[km1, i] * wt[i] + d
        sk += d * d
        skm1 += e1 * e1
        skm2 += e2 * e2
    absh = abs(h)
    erkm2 = 0.0
    if km2 > 0:
        erkm2 = absh * sig[km1] * GSTR[km2] * math.sqrt(skm2 / n)
    if km2 >= 0:
        erkm1 = absh * sig[k] * GSTR[km1] * math.sqrt(skm1 / n)
    temp5 = absh * math.sqrt(sk / n)
    err = temp5 * (g[k] - g[kp1])
    erk = temp5 * sig[kp1] * GSTR[k]
    knew = k
    if km2 > 0:
        if max(erkm1, erkm2) <= erk:
            knew = km1
    elif km2 == 0:
        if erkm1 <= 0.5 * erk:
            knew = km1
    if err <= 1.0:
        break
    # --- block 3: rejected; restore phi and psi, halve (order 1 from the 3rd failure)
    stats[S_NREJECT] += 1
    phase1 = False
    for r in range(1, k + 1):
        b = 1.0 / beta[r]
        for i in range(m):
            phi[r, i] = b * (phi[r, i] - phi[r + 1, i])
    for r in range(2, k + 1):
        psi[r - 1] = psi[r] - h
    ifail += 1
    temp2 = 0.5
    if ifail > 3:
        if 0.5 < 0.25 * erk:
            temp2 = math.sqrt(0.5 / erk)
    if ifail >= 3:
        knew = 1
    h = temp2 * h
    k = knew
if status == STATUS_STEP_TOO_SMALL:
    break
# --- block 4: accepted; correct, evaluate, update the differences
kold = k
hold = h
temp1 = h * g[kp1]
for i in range(m):
    rho = temp1 * (fp[i] - phi[1, i]) - phi[16, i]
    yt[i] = pr[i] + rho  # the corrected state
    phi[15, i] = (yt[i] - pr[i]) - rho
g_c = rhs(yt_v, p, fc_v)
stats[S_NRHS] += 1
stats[S_NSTEPS] += 1
t_new = t + h
# stiffness: h |f(y_c) - f(y_p)| / |y_c - y_p|
st_num = 0.0
st_den = 0.0
for i in range(n):
    df = fc[i] - fp[i]
    dd = yt[i] - pr[i]
    st_num += df * df
    st_den += dd * dd
if st_den > 0.0:
    h_lambda = absh * math.sqrt(st_num / st_den)
    if h_lambda > stats[S_HLAMBDA_MAX]:
        stats[S_HLAMBDA_MAX] = h_lambda
    if k <= STIFF_MAX_ORDER and h_lambda > STIFF_FRACTION * STAB_BOUNDARY[k]:
        stats[S_NSTIFF] += 1
for i in range(m):
    phi[kp1, i] = fc[i] - phi[1, i]
    phi[kp2, i] = phi[kp1, i] - phi[kp2, i]
for r in range(1, k + 1):
    for i in range(m):
        phi[r, i] += phi[kp1, i]
for i in range(m):
    yc[i] = yt[i]
# the order and the step for the next step
erkp1 = 0.0
if knew == km1 or k == MAX_ORDER:
    phase1 = False
raise_k = False
lower_k = False
if phase1:
    raise_k = True
elif knew == km1:
    lower_k = True
elif kp1 <= ns:
    s = 0.0
    for i in range(n):
        e = phi[kp2, i] * wt[i]
        s += e * e
    erkp1 = absh * GSTR[kp1] * math.sqrt(s / n)
    if k <= 1:
        if erkp1 < 0.5 * erk:
            raise_k = True
    elif erkm1 <= min(erk, erkp1):
        lower_k = True
    elif not (erkp1 >= erk or k == MAX_ORDER):
        raise_k = True
if raise_k:
    k = kp1
    erk = erkp1
elif lower_k:
    k = km1
    erk = erkm1
hnew = h + h
if not phase1 and not (0.5 >= erk * TWO[k + 1]):
    hnew = h
    if not (0.5 >= erk):
        r = (0.5 / erk) ** (1.0 / (k + 1))
        hnew = max(absh * max(0.5, min(0.9, r)), 4.0 * abs(np.nextafter(t, np.inf) - t))
h = hnew
hs = t_new - t
"""

#: What the next chunk resumes from.
_FINISH = """
stats[S_H] = h
stats[A_K] = k
stats[A_KOLD] = kold
stats[A_NS] = ns
stats[A_HOLD] = hold
stats[A_PHASE1] = 1.0 if phase1 else 0.0
"""

#: The kernel's parameters (the method contract's).
_PARAMS = ("rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor, t_out, "
           "Y_out, i_out, stats")
_SIGNATURE = ("nb.types.Tuple((_I8, _F8, _I8))(RHS_TYPE, WATCH_TYPE, _V, _F8, _F8, _F8, _V, _F8, "
              "_F8, _I8, _F8, _V, _M, _I8, _V)")
_HEADER = """
from tippetop.reference_ode.adams import (
    A_ALPHA, A_BETA, A_G, A_HOLD, A_K, A_KOLD, A_NS, A_PHASE1, A_PHI, A_PSI, A_SIG, A_V, A_W,
    GSTR, LANES, MAX_ORDER, STAB_BOUNDARY, STIFF_FRACTION, STIFF_MAX_ORDER, TWO, _NPHI, _NV,
    interp)
"""

#: The parts of the Adams kernel (:class:`reference_ode.driver.Parts`).
PARTS = Parts(
    name="adams", header=_HEADER, params=_PARAMS, signature=_SIGNATURE, setup=_SETUP, f0="dy",
    start=_START, step=_STEP, y_new="yc_v", h="hs", guard_dip="not (min(g_p, g_c) > 0.0)",
    dense_prepare="", at_fraction="interp(phi, psi, yc_v, kold, ({x} - 1.0) * hs, work, {out})",
    at_time="interp(phi, psi, yc_v, kold, {t} - t_new, work, {out})",
    guard_stop="stats[S_H] = 0.0  # the history ends inside a step: a caller resumes afresh",
    advance="", finish=_FINISH, locate_params="phi, psi, yc_v, kold, work, hs",
    locate_signature="_M, _V, _V, _I8, _V, _F8")


@cache
def kernel() -> ModuleType:
    """The compiled kernel's module (:mod:`reference_ode.driver`): ``run`` and ``locate``."""
    return driver.load("adams", driver.kernel_source(PARTS))


def run(rhs, watch, y: np.ndarray, t: float, t_stop: float, t_end: float, p: np.ndarray,
        rtol: float, atol: float, max_steps: int, monitor_floor: float, t_out: np.ndarray,
        Y_out: np.ndarray, i_out: int, stats: np.ndarray) -> tuple[int, float, int]:
    """Integrate y' = rhs(y) from (t, y) until t >= t_stop; as :func:`dop853.dop853_run`.

    ``stats`` from :func:`new_stats` (n = y.size) carries the Adams history between calls;
    ``stats[S_H] = 0`` starts afresh. After a guard stop the history ends inside a step, so
    ``S_H`` is left 0 (a caller that continues from there restarts at order 1).
    """
    return kernel().run(rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps,
                        monitor_floor, t_out, Y_out, i_out, stats)

