"""A compiled adaptive Taylor method for the ball on the table (the reference's ``taylor``).

Each step computes the solution's Taylor series to order P at the step's start (the jet,
:mod:`reference_ode.taylor_jet`: the vector formulation's right-hand side differentiated in
Taylor mode, compiled as straight-line code for one order) and sums it at the step's end by
Horner's rule. The series is also the step's dense output: samples, the mark (the inversion)
and the guard are found on it.

The step size follows the tolerances a priori (no rejected steps): the last two coefficients
stand for the local error, h = SAFETY min((max_i |y_i,P| / sc_i)^(-1/P),
(max_i |y_i,P-1| / sc_i)^(-1/(P-1))) with sc_i = atol + rtol |y_i| (Jorba and Zou's rule, with
the other methods' component scales in place of one tolerance). The order follows the
tolerance asked (``models.options.taylor_order``: on the Fig. 3 and Fig. 11 tops the steps at
loose tolerances are set by stability, the friction law's slip relaxation near -400/s, so the
cheapest jet whose steps stay stable wins: order 7, 0.23 us a jet, to rtol 1e-4, order 9 at
1e-5, 10 at 1e-6, order 12, 0.55 us, below (2026-11-28's machine); measured over orders 6-12
and rtol 1e-3..1e-11 on both tops, order 16 slower than 12 at every rtol down to 1e-12).
Where stability limits the step (the friction law relaxes the slip at up to ~mu g / Lambda,
and an excited fast mode's coefficients grow until they bound h), the same rule holds the step
near the series' stability boundary.

Stiffness: a step is flagged (``S_NSTIFF``) when the law relaxes the slip over
:data:`STIFF_SEPARATION` times faster than the top turns, mu g / sqrt(|v_P|^2 + Lambda^2) >
STIFF_SEPARATION |w| at the step's start: there every explicit method runs at its stability
limit, DOP853's at 12 evaluations a step far more cheaply than a jet. The method hands such
stretches over to DOP853 (``Method.hands_over_stiff``), whose detector decides on rolling
phases. (A Lipschitz estimate from two evaluations an error apart, DOP853's, does not tell the
two regimes apart for this method: on the Fig. 11 top, not stiff for DOP853, the Taylor steps
already run at h lambda ~10-16 by that estimate, held by the series' stability as a stiff
stretch's would be; the ratio of the law's rate to the rotation's is ~15 there, ~10^5 on the
stiff top once its slip is small.) ``S_HLAMBDA_MAX`` stays 0.

What it runs: the vector formulation's ball on the table (no rim, no other contact surface) with
the modified Coulomb law and no viscous part (:func:`unsupported` says why not otherwise):
asked for by name elsewhere, :mod:`reference_ode.solve` ends the run in one line saying why,
and ``auto`` runs its other rule there (:data:`models.options.AUTO_RULE`).
The kernel of each order is written to a module in the compiled-code cache and compiled there
once (``cache=True``): :func:`kernel`.

The contract is :func:`reference_ode.dop853.dop853_run`'s (statuses, ``stats`` slots, events,
samples, chunks); a jet counts as one evaluation in ``S_NRHS`` (as the heyoka peer's steps),
the events' evaluations of the right-hand side as one each.
"""

from __future__ import annotations

from functools import cache
from types import ModuleType

import numpy as np

from tippetop.models.options import taylor_order
from tippetop.reference_ode import driver
from tippetop.reference_ode.driver import Parts
from tippetop.reference_ode.friction import COULOMB_MODIFIED
from tippetop.reference_ode.params_array import (
    P_COULOMB_KIND,
    P_OTHER,
    P_RIM,
    P_VISCOUS,
)
from tippetop.reference_ode.taylor_jet import N_ROWS, ROW_N, ROW_U, jet_source

#: Step-size safety factor on the a-priori step.
SAFETY = 1.0
#: A step is flagged stiff when the law relaxes the slip this many times faster than the top
#: turns: mu g / sqrt(|v_P|^2 + Lambda^2) > STIFF_SEPARATION |w|.
STIFF_SEPARATION = 1000.0


def unsupported(rhs, p: np.ndarray) -> str | None:
    """None if the kernel runs this problem, else why not (one line).

    The kernel's own guard, on the compiled right-hand side and the packed parameters. Which
    scenes run the method is decided from the plan's inputs
    (``models.options.taylor_unsupported``), which says the same for every problem a scene
    makes.
    """
    from tippetop.reference_ode.top import vector_rhs

    if rhs is not vector_rhs:
        return "the Taylor method runs the vector formulation's ball on the table only"
    if p[P_RIM] != 0.0 or p[P_OTHER] >= 0.0:
        return "the Taylor method runs the ball on the table only, with no stem or rim"
    if int(p[P_COULOMB_KIND]) != COULOMB_MODIFIED or p[P_VISCOUS] != 0.0:
        return "the Taylor method runs the modified Coulomb law only, with no viscous part"
    return None


_HEADER = '''
from tippetop.reference_ode.params_array import (
    P_A_OFF, P_G, P_IA, P_IC, P_LAM, P_M, P_MU, P_R)
from tippetop.reference_ode.top import vector_rhs as rhs
from tippetop.reference_ode.top import vector_watch as watch

ORDER = {order}
N_ROWS = {n_rows}
ROW_N = {row_n}
ROW_U = {row_u}
SAFETY = {safety!r}
STIFF_SEPARATION = {stiff!r}


@nb.njit(nb.types.none(_V, _V, _M), cache=True, error_model="numpy", fastmath={{"contract"}})
{jet}

@nb.njit(nb.types.none(_M, _F8, _V), cache=True, error_model="numpy", fastmath={{"contract"}})
{dense}
'''

#: Buffers; the driver's names (``yc_v``, ``yt_v``) for the state and the scratch.
_SETUP = """
T = np.zeros((N_ROWS, ORDER + 1))
yc = np.empty(n)
y_new = np.empty(n)
f1 = np.empty(n)
ytmp = np.empty(n)
dy = np.empty(n)
yc_v = yc
yt_v = ytmp
"""

_START = """
mu_g2 = (p[P_MU] * p[P_G]) ** 2
sep2 = STIFF_SEPARATION * STIFF_SEPARATION
inv_p = 1.0 / ORDER
inv_pm1 = 1.0 / (ORDER - 1)
h = 0.0
"""

#: A step: the jet, the step from its last two coefficients, the sum, the stiffness flag and
#: the guard N on its series at the step's end and middle.
_STEP = """
jet(yc, p, T)
stats[S_NRHS] += 1
r1 = 0.0
r2 = 0.0
for i in range(n):
    inv_sc = 1.0 / (atol + rtol * abs(yc[i]))
    a1 = abs(T[i, ORDER]) * inv_sc
    a2 = abs(T[i, ORDER - 1]) * inv_sc
    if a1 > r1:
        r1 = a1
    if a2 > r2:
        r2 = a2
h_abs = math.inf
if r1 > 0.0:
    h_abs = r1 ** -inv_p
if r2 > 0.0:
    h_abs = min(h_abs, r2 ** -inv_pm1)
h_abs *= SAFETY
t_new = t + h_abs if h_abs < t_end - t else t_end
h = t_new - t
if not h >= min_step:  # also a NaN jet
    status = STATUS_STEP_TOO_SMALL
    break
dense_eval(T, h, y_new)
finite = True
for i in range(n):
    finite = finite and math.isfinite(y_new[i])
if not finite:  # an overflowing series: as DOP853's steps shrinking to nothing
    status = STATUS_STEP_TOO_SMALL
    break
stats[S_NSTEPS] += 1
# stiff: the law relaxes the slip STIFF_SEPARATION times faster than the top turns,
# mu g / sqrt(|v_P|^2 + Lambda^2) > STIFF_SEPARATION |w|
w2 = yc[8] * yc[8] + yc[9] * yc[9] + yc[10] * yc[10]
if mu_g2 > sep2 * w2 * T[ROW_U, 0]:
    stats[S_NSTIFF] += 1
g_end = T[ROW_N, ORDER]
g_mid = T[ROW_N, ORDER]
for k in range(ORDER - 1, -1, -1):
    g_end = g_end * h + T[ROW_N, k]
    g_mid = g_mid * (0.5 * h) + T[ROW_N, k]
"""


def dense_source(order: int, n: int = 11) -> str:
    """Source of ``dense_eval(T, h, out)``: the state's series (rows 0..n-1 of ``T``) at h.

    Unrolled for one order, each row by Estrin's pairs (c_k + c_{k+1} h, summed by Horner in
    h^2): the rows' chains are half as long as Horner's and interleave as straight-line code.
    At order 12 a sample takes ~24 ns against the row loop's ~35 (/tmp measurement,
    2026-11-28); at order 7 both ~20 ns. The samples are a third of a Fig. 3 run's time (1 ms
    apart, ~8 a step).
    """
    lines = ["def dense_eval(T, h, out):",
             '    """The series of the state summed at h (Estrin\'s pairs, unrolled)."""',
             "    h2 = h * h"]
    for i in range(n):
        k = order - 1 if order % 2 == 0 else order
        e = f"T[{i}, {order}]" if order % 2 == 0 else None
        while k >= 1:
            pair = f"(T[{i}, {k}] * h + T[{i}, {k - 1}])"
            e = pair if e is None else f"({e}) * h2 + {pair}"
            k -= 2
        lines.append(f"    out[{i}] = {e}")
    return "\n".join(lines) + "\n"


def parts(order: int, symmetric: bool) -> Parts:
    """The driver's parts of the kernel of one order (:mod:`reference_ode.driver`).

    The right-hand side and the watch are the vector formulation's, called directly (no
    function arguments: the kernel runs that problem only).
    """
    header = _HEADER.format(order=order, n_rows=N_ROWS, row_n=ROW_N, row_u=ROW_U,
                            safety=SAFETY, stiff=STIFF_SEPARATION,
                            jet=jet_source(order, symmetric), dense=dense_source(order))
    return Parts(
        name=f"taylor_p{order}_{'sym' if symmetric else 'gen'}", header=header,
        params=("y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor, t_out, Y_out, "
                "i_out, stats"),
        signature=("nb.types.Tuple((_I8, _F8, _I8))(_V, _F8, _F8, _F8, _V, _F8, _F8, _I8, _F8, "
                   "_V, _M, _I8, _V)"),
        setup=_SETUP, f0="f1", start=_START, step=_STEP, y_new="y_new", h="h",
        guard_dip="not (g_end > 0.0) or not (g_mid > 0.0)", dense_prepare="",
        at_fraction="dense_eval(T, {x} * h, {out})", at_time="dense_eval(T, {t} - t, {out})",
        guard_stop="stats[S_H] = h", advance="for i in range(n):\n    yc[i] = y_new[i]",
        finish="stats[S_H] = h", locate_params="T, h", locate_signature="_M, _F8",
        callables="globals", sample_into_row=True)


def kernel_source(order: int, symmetric: bool) -> str:
    """The source of the compiled module of one order (jet, dense output, events, driver)."""
    return driver.kernel_source(parts(order, symmetric))


@cache
def kernel(order: int, symmetric: bool) -> ModuleType:
    """The compiled module of one order: written to the cache and imported (compiled once)."""
    p = parts(order, symmetric)
    return driver.load(p.name, driver.kernel_source(p))


def is_symmetric(p: np.ndarray) -> bool:
    """Whether the top's inertia is a sphere's (A = C): the jet without the 1/C - 1/A terms."""
    from tippetop.reference_ode.params_array import P_IA, P_IC

    return bool(p[P_IA] == p[P_IC])


def new_stats(n: int) -> np.ndarray:
    """A fresh ``stats`` vector (DOP853's slots: the method keeps no history)."""
    from tippetop.reference_ode.dop853 import new_stats as _new

    return _new(n)


def run(rhs, watch, y: np.ndarray, t: float, t_stop: float, t_end: float, p: np.ndarray,
        rtol: float, atol: float, max_steps: int, monitor_floor: float, t_out: np.ndarray,
        Y_out: np.ndarray, i_out: int, stats: np.ndarray) -> tuple[int, float, int]:
    """The method contract's ``run`` (:func:`reference_ode.dop853.dop853_run`'s arguments).

    Raises:
        ValueError: The problem is not one the method runs (:func:`unsupported`).
    """
    reason = unsupported(rhs, p)
    if reason is not None:
        raise ValueError(reason)
    mod = kernel(taylor_order(rtol), is_symmetric(p))
    return mod.run(y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor, t_out, Y_out,
                   i_out, stats)
