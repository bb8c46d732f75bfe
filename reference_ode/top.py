"""The tippe top as a problem for the generic DOP853 kernel (:mod:`reference_ode.dop853`).

Each formulation (:data:`FORMULATIONS` by name, a :class:`Formulation` each) gives the kernel
``*_rhs(y, p, dy) -> N``, the equations of motion with the friction law packed in ``p``
(:func:`params_array.pack_params`), whose guard N stops the run where contact is lost, and
``*_watch(y, p) -> (cos theta, monitor)``, whose mark's first fall through 0 is the inversion
time; and an allocating right-hand side for scipy and the observables of a batch of states.
The monitors, and how the law and the equations are compiled in: docs/design.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba as nb
import numpy as np

from tippetop.reference_ode import paper as _paper
from tippetop.reference_ode import vector as _vector
from tippetop.reference_ode.paper import paper_core, paper_observe
from tippetop.reference_ode.params_array import P_GAP_TOL, P_OTHER, friction_law
from tippetop.reference_ode.two_contact import two_contact_core, two_contact_observe
from tippetop.reference_ode.vector import (
    IQW,
    IQX,
    IQY,
    IQZ,
    contact_height,
    other_gap,
    vector_core,
    vector_observe,
)


# ---------------------------------------------------------------- vector formulation
@nb.njit(cache=True, error_model="numpy")
def vector_rhs(y, p, dy):
    """dy/dt of the vector formulation; returns the guard.

    The guard is the normal force N, or, with another contact surface (a stem), the smaller
    of N and that surface's gap above the table plus ``P_GAP_TOL``: the run stops where
    contact is lost or where the other surface touches.
    """
    ck, visc = friction_law(p)
    N = vector_core(ck, visc, y, p, dy)[0]
    if p[P_OTHER] < 0.0:
        return N
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    kx = 2.0 * (qx * qz + qw * qy) * inv
    ky = 2.0 * (qy * qz - qw * qx) * inv
    kz = (qw * qw - qx * qx - qy * qy + qz * qz) * inv
    s = math.sqrt(kx * kx + ky * ky)
    gap = other_gap(p, kz, s, contact_height(p, kz, s)) + p[P_GAP_TOL]
    return N if N < gap else gap


@nb.njit(cache=True, error_model="numpy")
def vector_watch(y, p):
    """(cos theta, |sin theta|) of a vector state: the axis k's z and horizontal length."""
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    kx = 2.0 * (qx * qz + qw * qy) * inv
    ky = 2.0 * (qy * qz - qw * qx) * inv
    return (qw * qw - qx * qx - qy * qy + qz * qz) * inv, math.sqrt(kx * kx + ky * ky)


@nb.njit(cache=True, error_model="numpy")
def vector_rhs_alloc(y, p):
    """dy/dt of the vector formulation in a new array."""
    dy = np.empty_like(y)
    vector_rhs(y, p, dy)
    return dy


@nb.njit(cache=True, error_model="numpy")
def vector_observe_all(Y, p, sin_undefined, out):
    """Observables (``COLUMNS[1:] + EXTRA_COLUMNS``) of the vector states ``Y`` into ``out``."""
    ck, visc = friction_law(p)
    scratch = np.empty(Y.shape[1])
    for i in range(Y.shape[0]):
        vector_observe(ck, visc, Y[i], p, sin_undefined, out[i], scratch)


# ---------------------------------------------------------------- two points on the table
@nb.njit(cache=True, error_model="numpy")
def two_contact_rhs(y, p, dy):
    """dy/dt with the ball and the stem's end both on the table; the guard is min(N1, N2)."""
    ck, visc = friction_law(p)
    N1, N2, _, _, _ = two_contact_core(ck, visc, y, p, dy)
    return N1 if N1 < N2 else N2


@nb.njit(cache=True, error_model="numpy")
def two_contact_rhs_alloc(y, p):
    """dy/dt of a two-point state in a new array."""
    dy = np.empty_like(y)
    two_contact_rhs(y, p, dy)
    return dy


@nb.njit(cache=True, error_model="numpy")
def two_contact_forces(y, p):
    """(N1, N2): the active and the other contact's normal forces of a two-point state (N)."""
    ck, visc = friction_law(p)
    dy = np.empty_like(y)
    N1, N2, _, _, _ = two_contact_core(ck, visc, y, p, dy)
    return N1, N2


@nb.njit(cache=True, error_model="numpy")
def two_contact_observe_all(Y, p, sin_undefined, out):
    """Observables of the two-point states ``Y`` into ``out``."""
    ck, visc = friction_law(p)
    scratch = np.empty(Y.shape[1])
    for i in range(Y.shape[0]):
        two_contact_observe(ck, visc, Y[i], p, sin_undefined, out[i], scratch)


# ---------------------------------------------------------------- paper formulation
@nb.njit(cache=True, error_model="numpy")
def paper_rhs(y, p, dy):
    """dy/dt of the paper formulation; returns the normal force N (the guard)."""
    ck, visc = friction_law(p)
    return paper_core(ck, visc, y, p, dy)[0]


@nb.njit(cache=True, error_model="numpy")
def paper_watch(y, p):
    """(cos theta, sin theta) of a paper state; sin theta signed (< 0 outside (0, pi))."""
    return math.cos(y[0]), math.sin(y[0])


@nb.njit(cache=True, error_model="numpy")
def paper_rhs_alloc(y, p):
    """dy/dt of the paper formulation in a new array."""
    dy = np.empty_like(y)
    paper_rhs(y, p, dy)
    return dy


@nb.njit(cache=True, error_model="numpy")
def paper_observe_all(Y, p, sin_undefined, out):
    """Observables (``COLUMNS[1:] + EXTRA_COLUMNS``) of the paper states ``Y`` into ``out``."""
    ck, visc = friction_law(p)
    scratch = np.empty(Y.shape[1])
    for i in range(Y.shape[0]):
        paper_observe(ck, visc, Y[i], p, sin_undefined, out[i], scratch)


# ---------------------------------------------------------------- by name
@dataclass(frozen=True)
class Formulation:
    """One formulation's compiled functions (see the module docstring; docs/design.md).

    Attributes:
        name: ``vector`` or ``paper``.
        n_state: Size of the state vector.
        rhs: ``rhs(y, p, dy) -> N``.
        watch: ``watch(y, p) -> (cos theta, monitor)``.
        rhs_alloc: ``rhs_alloc(y, p) -> dy`` (a new array).
        observe_all: ``observe_all(Y, p, sin_undefined, out)``.
        singular: Whether the formulation has a singularity (the paper's at sin theta = 0): its
            runs pass ``monitor_floor = p[P_SING]``, the others ``-inf``.
    """

    name: str
    n_state: int
    rhs: Callable
    watch: Callable
    rhs_alloc: Callable
    observe_all: Callable
    singular: bool


#: The vector formulation on two points at once (:mod:`reference_ode.two_contact`); not a
#: formulation a scene picks, a phase of a run with a stem.
TWO_CONTACT = Formulation("vector", _vector.N_STATE, two_contact_rhs, vector_watch,
                          two_contact_rhs_alloc, two_contact_observe_all, singular=False)

FORMULATIONS: dict[str, Formulation] = {
    "vector": Formulation("vector", _vector.N_STATE, vector_rhs, vector_watch, vector_rhs_alloc,
                          vector_observe_all, singular=False),
    "paper": Formulation("paper", _paper.N_STATE, paper_rhs, paper_watch, paper_rhs_alloc,
                         paper_observe_all, singular=True),
}
