"""heyoka's Taylor method as a peer (reference_ode/taylor_peer.py): the same equations.

The right-hand side written in heyoka's expressions must be the compiled one's: at random
states of two tops and two laws the rates agree to 1e-12 relative to the largest rate (both
evaluate the same terms in the same order in double precision; a different association of a
sum of ~10 terms of size |f| leaves a few ulp, 1e-15, so 1e-12 has room and still catches any
wrong term, whose size is at least ~1e-6 of |f| at these states). A run then agrees with the
reference's at a tight tolerance on theta(t_end) and the inversion time.
"""

from __future__ import annotations

import numpy as np
import pytest

from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode.params_array import pack_params
from tippetop.reference_ode.solve import initial_state_vector, simulate_ode
from tippetop.reference_ode.taylor_peer import heyoka_missing, unsupported, vector_system
from tippetop.reference_ode.top import FORMULATIONS

pytestmark = pytest.mark.skipif(heyoka_missing() is not None, reason="heyoka not installed")


@pytest.mark.parametrize(("law", "ratios"), [("modified_coulomb", (1.0, 0.15)),
                                              ("modified_coulomb", (0.8, 0.3)),
                                              ("viscous", (0.8, 0.3))])
def test_the_heyoka_system_is_the_compiled_rhs(law: str, ratios: tuple[float, float]) -> None:
    import heyoka as hy

    top = TopParams.from_ratios(*ratios)
    fr = FrictionParams(law=law)
    p = pack_params(top, fr)
    sys = vector_system(p)
    f = hy.cfunc([r for _, r in sys], vars=[v for v, _ in sys])
    rhs = FORMULATIONS["vector"].rhs
    rng = np.random.default_rng(7)
    for _ in range(20):
        y = initial_state_vector(top, InitialState(theta0=rng.uniform(0.1, 3.0), n0=60.0))
        y[2:4] = rng.normal(0.0, 0.05, 2)  # a slip of a few cm/s
        y[8:11] += rng.normal(0.0, 5.0, 3)
        dy = np.empty(11)
        rhs(y.copy(), p, dy)
        got = f(y)
        assert np.max(np.abs(got - dy)) <= 1e-12 * np.max(np.abs(dy))


def test_a_stem_or_the_exact_law_is_said_unsupported() -> None:
    top = TopParams.from_ratios(1.0, 0.15)
    assert unsupported(pack_params(top, FrictionParams(law="coulomb"))) is not None
    assert unsupported(pack_params(top, FrictionParams())) is None


def test_a_run_agrees_with_the_reference() -> None:
    """Fig. 11 top, 10 s: heyoka at tol 1e-13 and the reference at rtol 1e-13 (atol 1e-16).

    Each is measured (bench ode --sweep) within ~1e-12 rad of the converged theta(t_end) at
    these tolerances; 1e-9 rad and 1e-9 s leave three orders of room and still catch a wrong
    term (which moves theta by far more over 10 s).
    """
    from tippetop.reference_ode.taylor_peer import TaylorPeer

    top = TopParams.from_ratios(1.0, 0.15)
    fr = FrictionParams()
    init = InitialState(theta0=0.01, n0=60.0)
    p = pack_params(top, fr)
    peer = TaylorPeer(p, 1e-13, events=True)
    run = peer.run(initial_state_vector(top, init), 10.0)
    ref = simulate_ode(top, fr, init, t_end_s=10.0, sample_dt_s=10.0,
                       options=OdeOptions(rtol=1e-13, atol=1e-16))
    q = run.y_final[4:8] / np.linalg.norm(run.y_final[4:8])
    kz = q[0] ** 2 - q[1] ** 2 - q[2] ** 2 + q[3] ** 2
    theta = np.arctan2(np.sqrt(max(0.0, 1.0 - kz * kz)), kz)
    assert run.success
    assert abs(theta - ref.table["theta"].iloc[-1]) < 1e-9
    assert ref.t_invert is not None and abs(peer.t_invert - ref.t_invert) < 1e-9
