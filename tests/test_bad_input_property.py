"""Property: any parameter set either runs to a finite summary or is refused in one line.

Random ``--set`` overrides of the top, friction and initial-state keys (negative, zero, NaN,
infinite, out-of-range, non-numeric and very large values, alone or combined) go through
``compare.cli.main`` with a 0.05-s run. Every call must either exit 0 with one JSON summary
whose numbers are finite, or exit 2 (bad input) with exactly one line on stderr, or exit 1 (a
valid run that stopped short: step-size underflow, ``max_steps``) with exactly one
``tippetop: run failed: ...`` line; never a traceback, never NaN in a successful summary.

Each call runs in a forked copy of the test process (``_call_cli``): it keeps every module and
compiled function already loaded, so a call costs milliseconds, but a call that never returns
(compiled code cannot be interrupted from Python) is killed after ``CALL_TIMEOUT_S`` and
reported as a hang instead of freezing the suite. ``ode.max_steps`` is capped so that a valid
but absurd top (n0 = 1e6 rad/s, mu = 1e6) ends quickly with status ``max_steps``: the cap
bounds the test's cost and is not an input under test.
"""

from __future__ import annotations

import io
import json
import math
import os
import select
import signal
import time
import traceback
from contextlib import redirect_stderr, redirect_stdout

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from tippetop.compare.cli import main
from tippetop.models.params import FRICTION_LAWS

RUN = ["--set", "run.t_end_s=0.05", "--set", "ode.max_steps=20000"]
CALL_TIMEOUT_S = 5.0  # (s) a 0.05-s run capped at 20,000 steps takes well under 0.5 s
FLOAT_KEYS = [
    "top.A_over_C", "top.a_over_R", "top.C_factor", "top.R_m", "top.M_kg", "top.g_mps2",
    "friction.mu", "friction.Lambda_mps", "friction.viscous_Nspm",
    "friction.coulomb_v_eps_mps",
    "init.theta0", "init.thetadot0", "init.Omega0", "init.n0", "init.uOX", "init.uOY",
]
SUMMARY_NUMBERS = ("theta_final", "theta_asymp", "J_rel_drift", "wall_s", "n_rhs")
STATUSES = {"ok", "contact_lost", "singular", "max_steps", "step_too_small"}

SPECIAL = ["nan", "inf", "-inf", "+inf", "0", "-0.0", "-1", "1e-9", "abc", "true", "[1, 2]",
           "3.141592653589793", "0.999999", "0.5"]
LAWS = [*FRICTION_LAWS, "sticky", "Coulomb", "", "1"]


def _fmt(x: float) -> str:
    return repr(float(x))


#: Finite values up to 1e6 in magnitude: far beyond any physical top (n0 = 1e6 rad/s,
#: M = 1e6 kg), still inside what double precision handles without overflow.
moderate = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False).map(_fmt)
#: Floating-point extremes: magnitudes 1e150 ... 1e308 and 1e-308 ... 1e-150.
extreme = st.one_of(
    st.floats(min_value=1e150, max_value=1e308),
    st.floats(min_value=-1e308, max_value=-1e150),
    st.floats(min_value=1e-308, max_value=1e-150),
).map(_fmt)


def _overrides(values: st.SearchStrategy[str]) -> st.SearchStrategy[list[str]]:
    pair = st.one_of(
        st.tuples(st.sampled_from(FLOAT_KEYS), st.one_of(st.sampled_from(SPECIAL), values)),
        st.tuples(st.just("friction.law"), st.sampled_from(LAWS)),
    )
    return st.lists(pair, min_size=1, max_size=4, unique_by=lambda kv: kv[0]).map(
        lambda kvs: [f"{k}={v}" for k, v in kvs])


def _call_cli(argv: list[str]) -> tuple[int, str, str]:
    """``main(argv)`` in a forked child: (exit status, stdout, stderr); a hang fails."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: run, report through the pipe, never return into pytest
        try:
            os.close(r)
            out, err = io.StringIO(), io.StringIO()
            try:
                with redirect_stdout(out), redirect_stderr(err):
                    rc = main(argv)
            except SystemExit as exc:
                rc = exc.code if isinstance(exc.code, int) else 1
            except BaseException:  # noqa: BLE001 - the traceback is the finding
                err.write(traceback.format_exc())
                rc = -1
            with os.fdopen(w, "wb") as fh:
                fh.write(json.dumps([rc, out.getvalue(), err.getvalue()]).encode())
        finally:
            os._exit(0)
    os.close(w)
    chunks = []
    deadline = time.monotonic() + CALL_TIMEOUT_S
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([r], [], [], left)[0]:
                os.kill(pid, signal.SIGKILL)
                pytest.fail(f"hang: tippetop {' '.join(argv)} did not return within "
                            f"{CALL_TIMEOUT_S:g} s")
            chunk = os.read(r, 65536)
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(r)
        os.waitpid(pid, 0)
    rc, out, err = json.loads(b"".join(chunks).decode())
    return rc, out, err


def _check(sets: list[str]) -> None:
    argv = ["simulate", *RUN, *[a for kv in sets for a in ("--set", kv)], "--json"]
    rc, out, err = _call_cli(argv)
    where = f"tippetop {' '.join(argv)}"
    assert "Traceback" not in err, f"{where}\n{err}"
    lines = err.splitlines()
    if rc == 2:
        assert len(lines) == 1 and lines[0].startswith("tippetop: error: "), f"{where}\n{err}"
        assert out == "", where
        return
    if rc == 1:
        assert len(lines) == 1 and lines[0].startswith("tippetop: run failed: "), \
            f"{where}\n{err}"
        assert json.loads(out)["status"] in STATUSES - {"ok", "contact_lost"}, where
        return
    assert rc == 0, f"{where}: exit {rc}\n{err}"
    assert err == "", f"{where}\n{err}"
    summary = json.loads(out)
    assert summary["status"] in STATUSES, where
    for key in SUMMARY_NUMBERS:
        v = summary[key]
        assert isinstance(v, (int, float)) and math.isfinite(v), f"{where}: {key} = {v!r}"


@pytest.fixture(scope="module", autouse=True)
def _warm_up() -> None:
    """Load every friction law's compiled integrator in this process, before any fork."""
    for law in FRICTION_LAWS:
        assert main(["simulate", *RUN, "--set", f"friction.law={law}", "--json"]) == 0


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sets=_overrides(moderate))
def test_random_parameters_run_or_fail_cleanly(sets: list[str]) -> None:
    """Negative, zero, NaN, infinite, non-numeric and values up to 1e6 in magnitude, 1-4 keys
    at once: each call ends in a finite summary (exit 0) or one clean error line (exit 2).
    80 examples, about 10 s."""
    _check(sets)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example(sets=["top.R_m=1e300"])
@example(sets=["init.n0=1e300"])
@example(sets=["init.thetadot0=1e300"])
@example(sets=["init.n0=0"])
@given(sets=_overrides(extreme))
def test_extreme_parameters_run_or_fail_cleanly(sets: list[str]) -> None:
    """The same property with floating-point extremes (1e+-150 ... 1e+-308) and J0 = 0.

    The examples are the cases that once failed: an overflow traceback (R = 1e300), a
    division by zero in the starting step (n0 = 1e300), a hang on a NaN step (theta_dot0 =
    1e300) and a null Jellett drift for J0 = 0 (n0 = 0)."""
    _check(sets)
