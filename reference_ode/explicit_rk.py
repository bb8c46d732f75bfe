"""The explicit Runge-Kutta pairs' step, made from a pair's tableau, for the driver.

DOP853 and Verner 9(8) differ in their tableau, their error estimate, their interpolant and
where f(y_new) is evaluated; the rest of their step is the same and is written here once: the
attempts (the stages, each sum over the tableau's non-zero entries in their order, written out
so that no array is handed to a helper per stage), the step-size control (accept when the
error norm is < 1; grow by SAFETY err^ERROR_EXPONENT, at most MAX_FACTOR, not after a
rejection; shrink by at least MIN_FACTOR; a non-finite norm shrinks by MIN_FACTOR), the
stiffness detector (h lambda from the last stage and f(y_new), Hairer's), fixed steps for the
tests, and the carry of f(y_new) to the next step's first stage. A :class:`Pair` names the
rest; :func:`parts` gives the driver (:mod:`reference_ode.driver`) what it writes the kernel
from.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from tippetop.reference_ode import driver
from tippetop.reference_ode.driver import Parts

#: The kernel's parameters (the method contract's, then the fixed step and the stage buffer
#: that the tests read).
PARAMS = ("rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor, t_out, "
          "Y_out, i_out, stats, h_fixed, K_out")
SIGNATURE = ("nb.types.Tuple((_I8, _F8, _I8))(RHS_TYPE, WATCH_TYPE, _V, _F8, _F8, _F8, _V, "
             "_F8, _F8, _I8, _F8, _V, _M, _I8, _V, _F8, _M)")


@dataclass(frozen=True)
class Pair:
    """An explicit Runge-Kutta pair, as the driver needs it.

    Attributes:
        name: The method's name (the kernel module's prefix).
        module: The module that holds the tableau (``A``, ``B``, the error weights), the
            constants (``N_STAGES``, ``N_K``, ``SAFETY``, ``MIN_FACTOR``, ``MAX_FACTOR``,
            ``ERROR_EXPONENT``, ``STIFF_HLAMBDA``) and the dense output (``dense_coeffs``,
            ``dense_eval``, ``initial_step``, ``padded``).
        a: The stage coefficients (the stages' sums are written over their non-zero entries).
        b: The solution's weights.
        weights: The error estimate's weight vectors by their name in ``module`` (each sum
            is written over its non-zero entries).
        n_stages: Stages per step, the first (f(y)) included; f(y_new) is row ``n_stages``.
        n_k: Rows of the stage buffer K (the stages, f(y_new), the interpolant's stages).
        fsal: Whether f(y_new) is evaluated in every attempt (its guard and its value in the
            error estimate: DOP853) or once the step is accepted (Verner).
        error: The error norm ``err`` of an attempt, given a function that writes a weight
            vector's sum over the stages (``wsum("E")`` -> ``E[0] * K[0, i] + ...``).
        buffers: Extra buffers the error norm uses (code).
        imports: The names ``error`` uses from ``module`` (the weights' names included).
        dense_prepare: The interpolant's coefficients for the step (code), before it is read.
        dense_stages: The extra evaluations ``dense_prepare`` makes (counted in ``S_NRHS``).
        interp_rows: Rows of the interpolant's coefficients ``F``.
    """

    name: str
    module: str
    a: np.ndarray
    b: np.ndarray
    weights: Mapping[str, np.ndarray]
    n_stages: int
    n_k: int
    fsal: bool
    error: Callable[[Callable[[str], str]], str]
    buffers: str
    imports: tuple[str, ...]
    dense_prepare: str
    dense_stages: str
    interp_rows: str


def _terms(name: str, coef: np.ndarray, row: int | None = None) -> str:
    """``name[row, j] * K[j, i] + ...`` over the non-zero entries of ``coef`` (row or vector)."""
    idx = [j for j, c in enumerate(coef) if c != 0.0]
    at = (lambda j: f"{name}[{row}, {j}]") if row is not None else (lambda j: f"{name}[{j}]")
    return " + ".join(f"{at(j)} * K[{j}, i]" for j in idx)


def _wrap(line: str, indent: str) -> str:
    """``line`` split at its ``+`` signs to lines of at most 99 characters."""
    parts = line.split(" + ")
    out, cur = [], indent + parts[0]
    for p in parts[1:]:
        if len(cur) + len(p) + 3 > 99:
            out.append(cur)
            cur = indent + "    + " + p
        else:
            cur += " + " + p
    out.append(cur)
    return "\n".join(out)


def _stages(pair: Pair) -> str:
    """The attempt's stages 1..n_stages-1: each point, then its derivative into K[s]."""
    lines = []
    for s in range(1, pair.n_stages):
        lines.append("for i in range(m):")
        lines.append(_wrap(f"yt[i] = yc[i] + h * ({_terms('A', pair.a[s, :s], s)})", "    "))
        lines.append(f"g_min = min(g_min, rhs(yt_v, p, k{s}))")
    return "\n".join(lines)


def _f_new() -> str:
    return "g_new = rhs(y_new_v, p, f_new)\ng_min = min(g_min, g_new)"


def _step(pair: Pair) -> str:
    """One accepted step: the attempts, the step-size control, the stiffness detector."""
    y_new = _wrap(f"y_new[i] = yc[i] + h * ({_terms('B', pair.b)})", "    ")
    count = "stats[S_NRHS] += N_STAGES" if pair.fsal else "stats[S_NRHS] += N_STAGES - 1"
    in_attempt = f"\n{_f_new()}" if pair.fsal else ""
    after = "" if pair.fsal else f"{_f_new()}\nstats[S_NRHS] += 1\n"
    error = pair.error(lambda name: _terms(name, pair.weights[name]))
    return f"""
rejected = False
while True:
    if not h_abs >= min_step:  # also catches a NaN step size
        status = STATUS_STEP_TOO_SMALL
        break
    t_new = t + h_abs
    if t_new > t_end:
        t_new = t_end
    h = t_new - t
    # --- the stages (K[1:N_STAGES]); each sum over the tableau's non-zero entries
    g_min = np.inf
{_indent(_stages(pair), 1)}
    for i in range(m):
{_indent(y_new, 1)}{_indent(in_attempt, 1)}
    {count}
    if h_fixed > 0.0:
        break
    # --- the error norm (< 1: accept; NaN or inf: overflow)
{_indent(error, 1)}
    if err < 1.0:
        if err == 0.0:
            factor = MAX_FACTOR
        else:
            factor = min(MAX_FACTOR, SAFETY * err ** ERROR_EXPONENT)
        if rejected:
            factor = min(1.0, factor)
        h_abs *= factor
        break
    # rejected (a non-finite error estimate also lands here and shrinks the step)
    if math.isfinite(err):
        h_abs *= max(MIN_FACTOR, SAFETY * err ** ERROR_EXPONENT)
    else:
        h_abs *= MIN_FACTOR
    rejected = True
    stats[S_NREJECT] += 1
if status == STATUS_STEP_TOO_SMALL:
    break
{after}stats[S_NSTEPS] += 1
if h_fixed > 0.0 and K_out.shape[0] > 0:
    for r in range(N_STAGES + 1):
        for i in range(n):
            K_out[r, i] = K[r, i]
# --- stiffness: yt holds the last stage's point (c = 1, t + h), K[N_STAGES - 1] its
# derivative; h lambda ~ h |f(y_new) - k_last| / |y_new - yt| (Hairer)
st_num = 0.0
st_den = 0.0
for i in range(n):
    dk = K[N_STAGES, i] - K[N_STAGES - 1, i]
    dyv = y_new[i] - yt[i]
    st_num += dk * dk
    st_den += dyv * dyv
if st_den > 0.0:
    h_lambda = h * math.sqrt(st_num / st_den)
    if h_lambda > stats[S_HLAMBDA_MAX]:
        stats[S_HLAMBDA_MAX] = h_lambda
    if h_lambda > STIFF_HLAMBDA:
        stats[S_NSTIFF] += 1
"""


def _indent(code: str, level: int) -> str:
    return "\n".join(("    " * level + ln) if ln.strip() else ln for ln in code.split("\n"))


def parts(pair: Pair) -> Parts:
    """The driver's parts of a pair's kernel."""
    names = ", ".join(("A", "B", "N_K", "N_STAGES", "SAFETY", "MIN_FACTOR", "MAX_FACTOR",
                       "ERROR_EXPONENT", "STIFF_HLAMBDA", "dense_coeffs", "dense_eval",
                       "initial_step", "padded", *pair.imports))
    views = "\n".join(f"k{s} = K[{s}][:n]" for s in range(1, pair.n_stages))
    setup = f"""
m = padded(n)
# the stage buffer K and the states, padded to m with zeros (rhs writes the first n entries,
# so the padding stays 0); rhs and watch see views of the first n entries, made once here
K = np.zeros((N_K, m))
yc = np.zeros(m)  # the state at t
y_new = np.zeros(m)
yt = np.zeros(m)  # a stage's point; after a step the last one (c = 1)
{pair.buffers}
yc_v = yc[:n]
y_new_v = y_new[:n]
yt_v = yt[:n]
f = K[0][:n]  # f(y) at t
{views}
f_new = K[N_STAGES][:n]  # f(y_new)
F = np.empty(({pair.interp_rows}, n))
dy = np.empty(n)
"""
    start = """
h_abs = stats[S_H]
if h_fixed > 0.0:
    h_abs = h_fixed
elif not h_abs > 0.0:
    h_abs = initial_step(rhs, t, yc_v, f, t_end, p, rtol, atol)
    stats[S_NRHS] += 1
"""
    return Parts(
        name=pair.name,
        header=f"from {pair.module} import (\n    {names})",
        params=PARAMS, signature=SIGNATURE, setup=setup, f0="f", start=start,
        step=_step(pair), y_new="y_new_v", h="h", guard_dip="not (g_min > 0.0)",
        dense_prepare=f"{pair.dense_prepare}\nstats[S_NRHS] += {pair.dense_stages}",
        at_fraction="dense_eval(F, yc_v, {x}, {out})",
        at_time="dense_eval(F, yc_v, ({t} - t) / h, {out})",
        guard_stop="stats[S_H] = h_abs",
        advance="for i in range(m):\n    yc[i] = y_new[i]\n    K[0, i] = K[N_STAGES, i]",
        finish="stats[S_H] = h_abs",
        locate_params="F, yc_v", locate_signature="_M, _V")


_KERNELS: dict[str, ModuleType] = {}
_NO_K_OUT = np.empty((0, 0))


def kernel(pair: Pair) -> ModuleType:
    """The pair's compiled kernel module (:mod:`reference_ode.driver`): ``run`` and ``locate``.

    ``run(rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor, t_out,
    Y_out, i_out, stats, h_fixed, K_out)`` is the method contract's ``run`` with, for
    ``h_fixed`` > 0, steps of that size and no error control (every step accepted: for tests
    of the method's order and dense output; a ``K_out`` of shape (``n_k``, n) then receives
    each step's stage buffer). Written and imported once per process.
    """
    if pair.name not in _KERNELS:
        _KERNELS[pair.name] = driver.load(pair.name, driver.kernel_source(parts(pair)))
    return _KERNELS[pair.name]


def run(pair: Pair, *contract: object) -> tuple[int, float, int]:
    """One call of the pair's compiled kernel with error control.

    ``contract`` is the method contract's arguments (``rhs, watch, y, t, t_stop, t_end, p,
    rtol, atol, max_steps, monitor_floor, t_out, Y_out, i_out, stats``:
    :func:`reference_ode.dop853.dop853_run`), passed on as they are.
    """
    return kernel(pair).run(*contract, 0.0, _NO_K_OUT)


def fixed_steps(pair: Pair, rhs, watch, y: np.ndarray, p: np.ndarray, h: float, n_steps: int,
                t_out: np.ndarray | None, stats: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n_steps`` steps of size ``h`` from (0, ``y``), no error control (for tests).

    ``y`` (float64) is advanced in place; ``stats`` is a fresh vector of the method's.

    Returns:
        (the state after the steps, the samples at ``t_out`` on the dense output, the last
        step's stage buffer K, (``n_k``, n)).
    """
    t_out = np.empty(0) if t_out is None else np.ascontiguousarray(t_out, dtype=float)
    Y = np.full((t_out.size, y.size), np.nan)
    K = np.zeros((pair.n_k, y.size))
    t_end = float(h * n_steps)
    kernel(pair).run(rhs, watch, y, 0.0, t_end, t_end, np.ascontiguousarray(p, dtype=float),
                     1.0, 1.0, n_steps, -np.inf, t_out, Y, 0, stats, float(h), K)
    return y, Y, K
