"""One driver for the reference's integrators: the loop, the events and the samples, written once.

Every method of :mod:`reference_ode.methods` (DOP853, Verner 9(8), Adams and the Taylor method)
runs the same loop. A step is taken, the watch is read at its end (the mark and the monitor),
and the step is looked into on the method's dense output when it must be: a guard that dipped
inside it (found by a scan of :data:`GUARD_SCAN` points, then located by bisection, to
2^-:data:`BISECTION_ITERS` of the step), the mark's first crossing (located likewise), and the
samples that fall in it. Then the chunk's end, the step count, the monitor's floor and the
stiffness hook decide whether the run goes on. That loop, the event location and the way the
dense output is read are this module's; what a step is (the stages of a Runge-Kutta pair and
its error control, a predictor-corrector's differences, a Taylor jet) and how its dense output
is made are the method's, given as :class:`Parts`. The explicit Runge-Kutta pairs share their
step too, made from each pair's tableau (:mod:`reference_ode.explicit_rk`).

Why the kernel is written as source: the loop calls the method's step and dense output, and they
must be compiled into it (a call through a function argument, or an array handed to a helper
that numba does not inline, costs reference counting and a call per stage: 5-10 % of a step,
measured when the kernels were written). numba compiles one function per source; a closure
made by a factory does not reuse its compiled cache across processes (numba keys a closure's
cache entry by the functions it closes over, which are new objects in each process: measured,
every process compiled it again). So :func:`kernel_source` writes the method's kernel as one
module's source, :func:`load` writes it to the compiled-code cache and imports it, and numba
compiles it once (``cache=True``), as for a hand-written module.

The contract every kernel keeps is :func:`reference_ode.dop853.dop853_run`'s: the statuses, the
``stats`` slots, the events, the samples and the chunks (docs/design.md).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

#: Event location on the dense output: bisection to 2^-60 of a step.
BISECTION_ITERS = 60
#: A guard that dipped at a step's evaluations is looked for at this many points of the step.
GUARD_SCAN = 32
#: A step below this many ulp of t is an underflow (as scipy).
MIN_STEP_ULPS = 10.0


@dataclass(frozen=True)
class Parts:
    """What a method gives the driver: its step and its dense output, as source.

    Code is written without indentation; the driver indents it. Names the driver's code uses
    and the method's code must define: ``yc`` (the state at ``t``, at least n entries) and its
    view ``yc_v`` (n entries), ``yt_v`` and ``dy`` (scratch views of n entries), ``n``, ``m``;
    after ``step``: ``t_new``, the step's end state (:attr:`y_new`) and the step's length
    (:attr:`h`); ``g0`` is set by the driver from ``rhs(yc_v, p, <f0>)``.

    Attributes:
        name: The kernel module's name (a prefix; a hash of the source is appended).
        header: Module-level code: imports and constants the method's code uses.
        params: The kernel's parameters (after which ``y, t, t_stop, t_end, p, rtol, atol,
            max_steps, monitor_floor, t_out, Y_out, i_out, stats`` must all appear).
        signature: The kernel's numba signature (an expression of the header's names).
        setup: Function start: the buffers and views.
        f0: The view that receives f(y) at the start.
        start: After the start's guard: the first step size or the method's history.
        step: One accepted step from (t, yc) to (t_new, y_new), the rejected attempts included:
            it counts the step, and where it cannot step it sets ``status`` and breaks out of
            the run's loop.
        y_new: The name of the step's end state (a view of n entries).
        h: The name of the step's length (``t_new - t``).
        guard_dip: An expression: whether the guard was seen <= 0 inside the step.
        dense_prepare: Run once for a step that holds a sample or an event, before the dense
            output is read.
        at_fraction: A statement writing the dense output at ``{x}`` (a fraction of the step)
            into ``{out}``.
        at_time: A statement writing the dense output at time ``{t}`` into ``{out}``.
        guard_stop: After the state at the guard's crossing is in ``y``: what the method keeps
            (``stats[S_H]``) before the kernel returns.
        advance: After ``t = t_new``: the state and the first stage carried to the next step.
        finish: After the loop: what the method keeps for the next chunk.
        locate_params: The dense output's arguments of ``locate`` (parameters, with the names
            ``at_fraction`` reads).
        locate_signature: Their numba types, comma-separated.
        callables: How the kernel reaches ``rhs`` and ``watch``: ``arguments`` (function
            arguments, ``rhs`` and ``watch`` first in ``params``) or ``globals`` (imported by
            the header).
        sample_into_row: Write a sample's dense output into its row of ``Y_out`` (a view made
            per sample) rather than through ``yt_v`` and a copy: as each hand-written loop
            did. Through the scratch the Taylor method's Fig. 3 run (a third of it samples)
            took 2.4 % longer (1.075 ms against 1.047-1.052, best of 200, 2026-11-29).
    """

    name: str
    header: str
    params: str
    signature: str
    setup: str
    f0: str
    start: str
    step: str
    y_new: str
    h: str
    guard_dip: str
    dense_prepare: str
    at_fraction: str
    at_time: str
    guard_stop: str
    advance: str
    finish: str
    locate_params: str
    locate_signature: str
    callables: str = "arguments"
    sample_into_row: bool = False


_HEAD = '''
import math

import numba as nb
import numpy as np

from tippetop.reference_ode.dop853 import (
    RHS_TYPE, S_H, S_HLAMBDA_MAX, S_MONITOR_MIN, S_NREJECT, S_NRHS, S_NSTEPS, S_NSTIFF,
    S_STIFF_STOP, S_T_MARK, STATUS_GUARD, STATUS_MAX_STEPS, STATUS_MONITOR, STATUS_OK,
    STATUS_RUNNING, STATUS_STEP_TOO_SMALL, STATUS_STIFF, WATCH_TYPE)

BISECTION_ITERS = {bisection}
GUARD_SCAN = {guard_scan}
MIN_STEP_ULPS = {min_step_ulps!r}
_V = nb.types.float64[::1]
_M = nb.types.float64[:, ::1]
_F8 = nb.types.float64
_I8 = nb.types.int64
_B = nb.types.boolean
'''

_LOCATE = '''
@nb.njit(_F8({rhs_types}{locate_signature}, _B, _V, _V, _V, _F8, _F8),
         cache=True, error_model="numpy")
def locate({rhs_params}{locate_params}, use_guard, p, ytmp, dy, lo, hi):
    """Where in the step (a fraction in (lo, hi]) the guard (``use_guard``) or the mark falls
    from > 0 to <= 0, to 2^-BISECTION_ITERS of the step (the caller saw it > 0 at ``lo`` and
    <= 0 at ``hi``)."""
    for _ in range(BISECTION_ITERS):
        mid = 0.5 * (lo + hi)
{at_mid}
        if use_guard:
            v = rhs(ytmp, p, dy)
        else:
            v = watch(ytmp, p)[0]
        if v > 0.0:
            lo = mid
        else:
            hi = mid
    return hi
'''

_RUN = '''
@nb.njit({signature}, cache=True, error_model="numpy")
def run({params}):
    """The kernel (written by tippetop.reference_ode.driver: see its docstring)."""
    n = y.size
{setup}
    for i in range(n):
        yc[i] = y[i]
    g0 = rhs(yc_v, p, {f0})
    stats[S_NRHS] += 1
    if not g0 > 0.0:
        return STATUS_GUARD, t, i_out
{start}
    mark_old = watch(yc_v, p)[0]
    n_out = t_out.size
    while i_out < n_out and t_out[i_out] <= t:
        Y_out[i_out, :] = yc_v
        i_out += 1
    status = STATUS_RUNNING
    while t < t_stop:
        if stats[S_NSTEPS] >= max_steps:
            status = STATUS_MAX_STEPS
            break
        min_step = MIN_STEP_ULPS * abs(np.nextafter(t, np.inf) - t)
{step}
        # --- the events and the samples on the dense output (read only for a step that
        # holds a sample or an event)
        mark_new, monitor = watch({y_new}, p)
        if monitor < stats[S_MONITOR_MIN]:
            stats[S_MONITOR_MIN] = monitor
        guard_dip = {guard_dip}
        mark_hit = math.isnan(stats[S_T_MARK]) and mark_old > 0.0 and mark_new <= 0.0
        if guard_dip or mark_hit or (i_out < n_out and t_out[i_out] <= t_new):
{dense_prepare}
            t_final = t_new
            guard_hit = False
            if guard_dip:
                lo = 0.0
                for js in range(1, GUARD_SCAN + 1):
                    x = js / GUARD_SCAN
{at_x}
                    stats[S_NRHS] += 1
                    if not (rhs(yt_v, p, dy) > 0.0):
                        guard_hit = True
                        t_final = t + {h} * locate({locate_args}, True, p, yt_v, dy, lo, x)
                        stats[S_NRHS] += BISECTION_ITERS
                        break
                    lo = x
            if mark_hit:
                t_mark = t + {h} * locate({locate_args}, False, p, yt_v, dy, 0.0, 1.0)
                if t_mark <= t_final:
                    stats[S_T_MARK] = t_mark
            while i_out < n_out and t_out[i_out] <= t_final:
                if t_out[i_out] == t_new:
                    Y_out[i_out, :] = {y_new}
                else:
{at_sample}
                i_out += 1
            if guard_hit:
{at_final}
{guard_stop}
                return STATUS_GUARD, t_final, i_out
        t = t_new
{advance}
        mark_old = mark_new
        if monitor < monitor_floor:
            status = STATUS_MONITOR
            break
        if stats[S_NSTIFF] >= stats[S_STIFF_STOP]:  # the hook of solve.py's rolling phases
            status = STATUS_STIFF
            break
{finish}
    for i in range(n):
        y[i] = yc[i]
    if status == STATUS_RUNNING and t >= t_end:
        status = STATUS_OK
    return status, t, i_out
'''


def _block(code: str, level: int) -> str:
    """``code`` indented by ``level`` levels of 4 spaces (``pass`` for no code)."""
    code = textwrap.dedent(code).strip("\n") or "pass"
    return textwrap.indent(code, " " * (4 * level))


def _sample(parts: Parts) -> str:
    """A sample inside the step: into its row of ``Y_out`` directly, or through ``yt_v``."""
    if parts.sample_into_row:
        return parts.at_time.format(t="t_out[i_out]", out="Y_out[i_out]")
    return (parts.at_time.format(t="t_out[i_out]", out="yt_v")
            + "\nY_out[i_out, :] = yt_v")


def kernel_source(parts: Parts) -> str:
    """The kernel module's source: the method's header, ``locate`` and ``run``."""
    args = parts.callables == "arguments"
    loc_names = ", ".join(a.strip() for a in parts.locate_params.split(","))
    head = _HEAD.format(bisection=BISECTION_ITERS, guard_scan=GUARD_SCAN,
                        min_step_ulps=MIN_STEP_ULPS)
    locate = _LOCATE.format(
        rhs_types="RHS_TYPE, WATCH_TYPE, " if args else "",
        rhs_params="rhs, watch, " if args else "",
        locate_signature=parts.locate_signature, locate_params=parts.locate_params,
        at_mid=_block(parts.at_fraction.format(x="mid", out="ytmp"), 2))
    run = _RUN.format(
        signature=parts.signature, params=parts.params, setup=_block(parts.setup, 1),
        f0=parts.f0, start=_block(parts.start, 1), step=_block(parts.step, 2),
        y_new=parts.y_new, guard_dip=parts.guard_dip,
        dense_prepare=_block(parts.dense_prepare, 3), h=parts.h,
        at_x=_block(parts.at_fraction.format(x="x", out="yt_v"), 5),
        locate_args=("rhs, watch, " if args else "") + loc_names,
        at_sample=_block(_sample(parts), 5),
        at_final=_block(parts.at_time.format(t="t_final", out="y"), 4),
        guard_stop=_block(parts.guard_stop, 4), advance=_block(parts.advance, 2),
        finish=_block(parts.finish, 1))
    doc = (f'"""The {parts.name} kernel, written by tippetop.reference_ode.driver from the '
           'method\'s parts (do not edit)."""\n')
    return doc + head + "\n" + textwrap.dedent(parts.header).strip("\n") + "\n\n" + locate + run


def source_dir() -> Path:
    """Where the kernels' sources are written: beside the compiled-code cache."""
    from tippetop.models.resources import user_cache_dir
    from tippetop.reference_ode import NUMBA_CACHE_DIR

    env = os.environ.get("NUMBA_CACHE_DIR")
    base = Path(env) if env and NUMBA_CACHE_DIR is None else (
        NUMBA_CACHE_DIR or user_cache_dir() / "numba")
    return Path(base) / "kernels_src"


def module_path(name: str, source: str) -> Path:
    """The file a kernel's source is written to (named by a hash of the source)."""
    key = hashlib.sha256(source.encode()).hexdigest()[:12]
    return source_dir() / f"{name}_{key}.py"


def load(name: str, source: str) -> ModuleType:
    """The module of ``source``: written to the cache (once) and imported (compiled once)."""
    path = module_path(name, source)
    mod_name = path.stem
    if mod_name in sys.modules:
        return sys.modules[mod_name]
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != source:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        tmp.replace(path)
    spec = importlib.util.spec_from_file_location(mod_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    spec.loader.exec_module(module)
    return module


__all__ = ["BISECTION_ITERS", "GUARD_SCAN", "MIN_STEP_ULPS", "Parts", "kernel_source", "load",
           "module_path", "source_dir"]
