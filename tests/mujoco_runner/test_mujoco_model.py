"""MJCF generation and reading the paper's parameters back from compiled models."""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import pytest
from scipy.optimize import brentq

from tippetop.models.errors import TippetopError
from tippetop.models.mjcf import (
    BALL_GEOM,
    FREE_JOINT,
    MARKER_GEOM,
    STEM_GEOM,
    TABLE_GEOM,
    TOP_BODY,
    MjcfContact,
    MjcfOption,
    make_mjcf,
)
from tippetop.models.params import InitialState, StemParams, TopParams
from tippetop.mujoco_runner.model import (
    TopModelWarning,
    load_error,
    load_model,
    load_top,
    stem_from_model,
    touch_tilt,
)
from tippetop.mujoco_runner.state import initial_qpos_qvel, kinematics

TOPS = [
    TopParams.from_ratios(1.0, 0.1),  # Fig. 3 / Fig. 6: spherical inertia
    TopParams.from_ratios(0.95, 0.125),  # Fig. 9 (c)
    TopParams.from_ratios(1.25, 0.025, 0.8),  # Fig. 10 (a)
    TopParams(R_m=0.02, a_m=0.0, M_kg=0.03, A_kgm2=2e-6, C_kgm2=3e-6, g_mps2=9.81),  # a = 0
]


def _rel(x: float, y: float) -> float:
    return abs(x - y) / abs(y) if y else abs(x)


@pytest.mark.parametrize("top", TOPS)
def test_mjcf_round_trip_recovers_parameters(top: TopParams) -> None:
    # Every parameter passes through MJCF text and MuJoCo's compiler: 1e-9 relative is the
    # brief's bound; repr() floats make it exact to a few ulp.
    tm = load_top(make_mjcf(top))
    for name in ("R_m", "a_m", "M_kg", "A_kgm2", "C_kgm2", "g_mps2"):
        assert _rel(getattr(tm.top, name), getattr(top, name)) < 1e-9, name
    np.testing.assert_array_equal(tm.centre_body_m, 0.0)  # body origin = sphere centre
    np.testing.assert_allclose(tm.axis_body, [0, 0, 1], atol=1e-15)
    assert tm.warnings == ()


def test_inertia_comes_from_inertial_element_only() -> None:
    top = TopParams.from_ratios(0.95, 0.15)
    model = load_model(make_mjcf(top))
    b = model.body(TOP_BODY).id
    assert model.body_mass[b] == pytest.approx(top.M_kg, rel=1e-15)
    np.testing.assert_allclose(model.body_inertia[b], [top.A_kgm2, top.A_kgm2, top.C_kgm2],
                               rtol=1e-15)
    np.testing.assert_allclose(model.body_ipos[b], [0, 0, -top.a_m], rtol=1e-15)
    for geom in (BALL_GEOM, STEM_GEOM, MARKER_GEOM):
        assert model.geom(geom).bodyid[0] == b
    for geom in (STEM_GEOM, MARKER_GEOM):  # visual only
        assert model.geom(geom).contype[0] == 0 and model.geom(geom).conaffinity[0] == 0
    assert model.joint(FREE_JOINT).type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert model.geom(TABLE_GEOM).type[0] == mujoco.mjtGeom.mjGEOM_PLANE
    np.testing.assert_allclose(model.opt.gravity, [0, 0, -top.g_mps2])


@pytest.mark.parametrize(
    ("kwargs", "condim", "friction"),
    [
        ({}, 1, [0, 0, 0]),
        ({"friction_mode": "native"}, 3, [0.1, 0, 0]),
        ({"friction_mode": "native", "condim": 4, "mu": 0.3, "torsional": 0.005}, 4,
         [0.3, 0.005, 0]),
        ({"friction_mode": "native", "condim": 6, "torsional": 0.005, "rolling": 1e-4}, 6,
         [0.1, 0.005, 1e-4]),
    ],
)
def test_contact_parameters(kwargs: dict, condim: int, friction: list[float]) -> None:
    model = load_model(make_mjcf(TOPS[0], contact=MjcfContact(**kwargs)))
    for geom in (BALL_GEOM, TABLE_GEOM):
        assert model.geom(geom).condim[0] == condim
        np.testing.assert_allclose(model.geom(geom).friction, friction)


def test_options_from_arguments() -> None:
    model = load_model(make_mjcf(
        TOPS[0], contact=MjcfContact(solref=(0.01, 0.8), solimp=(0.8, 0.9, 0.002)),
        option=MjcfOption(timestep_s=1e-4, integrator="implicitfast", cone="pyramidal",
                          impratio=0.3)))
    assert model.opt.timestep == 1e-4
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert model.opt.impratio == pytest.approx(0.3)
    np.testing.assert_allclose(model.geom(BALL_GEOM).solref, [0.01, 0.8])
    np.testing.assert_allclose(model.geom(BALL_GEOM).solimp[:3], [0.8, 0.9, 0.002])


@pytest.mark.parametrize(
    ("settings", "what"),
    [
        (MjcfContact(friction_mode="coulomb"), "friction_mode"),
        (MjcfContact(condim=3), "condim"),  # paper mode is condim 1
        (MjcfContact(friction_mode="native", condim=2), "condim"),
        (MjcfContact(mu=-0.1), "mu"),
        (MjcfOption(timestep_s=0.0), "timestep_s"),
        (MjcfOption(integrator="rk4"), "integrator"),
        (MjcfOption(cone="round"), "cone"),
        (MjcfOption(impratio=math.nan), "impratio"),
        (MjcfContact(solref=(0.02,)), "solref"),
        (MjcfContact(solimp=(0.9, 1.5, 0.001)), "solimp"),
        (MjcfContact(torsional=-1.0), "torsional"),
        (MjcfOption(noslip_iterations=-1), "noslip_iterations"),
    ],
)
def test_bad_arguments_are_one_line_errors(settings: MjcfContact | MjcfOption,
                                           what: str) -> None:
    kind = "contact" if isinstance(settings, MjcfContact) else "option"
    with pytest.raises(TippetopError) as err:
        make_mjcf(TOPS[0], **{kind: settings})
    message = str(err.value)
    assert message.startswith(f"{what}: expected ") and ", got " in message
    assert "\n" not in message


# --- any MJCF top -------------------------------------------------------------------------

_R, _A_OFF, _M = 0.02, 0.003, 0.04
_I_A, _I_C = 3.0e-6, 4.0e-6


def _body_xml(inner: str, extra_world: str = "") -> str:
    return f"""<mujoco><option gravity="0 0 -9.81"/>
      <worldbody><geom name="floor" type="plane" size="1 1 .1"/>{extra_world}
        <body name="b" pos="0 0 0.1"><freejoint/>{inner}</body>
      </worldbody></mujoco>"""


def test_any_top_with_offset_rotated_body_frame() -> None:
    # Body origin at the centre of mass, symmetry axis along body x (C about x).
    xml = _body_xml(f'<inertial pos="0 0 0" mass="{_M}" diaginertia="{_I_C} {_I_A} {_I_A}"/>'
                    f'<geom type="sphere" size="{_R}" pos="{_A_OFF} 0 0"/>')
    with pytest.warns(TopModelWarning, match="origin is 3 mm from the ball's centre"):
        tm = load_top(xml)
    assert tm.top.R_m == pytest.approx(_R, rel=1e-12)
    assert tm.top.a_m == pytest.approx(_A_OFF, rel=1e-12)
    assert tm.top.A_kgm2 == pytest.approx(_I_A, rel=1e-12)
    assert tm.top.C_kgm2 == pytest.approx(_I_C, rel=1e-12)
    assert tm.top.g_mps2 == pytest.approx(9.81)
    np.testing.assert_allclose(tm.axis_body, [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(tm.centre_body_m, [_A_OFF, 0, 0])


def test_composed_inertia_of_several_geoms() -> None:
    # No <inertial>: MuJoCo composes a uniform ball and a dense inner bead below its centre.
    r2, d, rho1, rho2 = 0.004, 0.008, 1000.0, 8000.0
    xml = _body_xml(f'<geom type="sphere" size="{_R}" density="{rho1}"/>'
                    f'<geom type="sphere" size="{r2}" pos="0 0 {-d}" density="{rho2}" '
                    'contype="0" conaffinity="0"/>')
    m1, m2 = rho1 * 4 / 3 * math.pi * _R**3, rho2 * 4 / 3 * math.pi * r2**3
    a = m2 * d / (m1 + m2)
    C = 0.4 * m1 * _R**2 + 0.4 * m2 * r2**2
    A = C + m1 * a**2 + m2 * (d - a) ** 2
    tm = load_top(xml)
    assert _rel(tm.top.M_kg, m1 + m2) < 1e-9
    assert _rel(tm.top.a_m, a) < 1e-9
    assert _rel(tm.top.A_kgm2, A) < 1e-9
    assert _rel(tm.top.C_kgm2, C) < 1e-9


@pytest.mark.parametrize(
    ("xml", "fragment"),
    [
        ("<mujoco><worldbody><body><joint type='hinge'/><geom type='sphere' size='.01'/></body>"
         "</worldbody></mujoco>", "exactly one body with a free joint"),
        (_body_xml('<geom type="sphere" size="0.01"/>',
                   '<body><freejoint/><geom type="sphere" size="0.01"/></body>'),
         "exactly one body with a free joint"),
        (_body_xml('<geom type="box" size="0.01 0.01 0.01"/>'), "a colliding sphere geom"),
        (_body_xml(f'<inertial pos="0 0 0" mass="1" diaginertia="1e-4 1.1e-4 1.2e-4"/>'
                   f'<geom type="sphere" size="{_R}"/>'), "two equal principal moments"),
        (_body_xml(f'<inertial pos="0.001 0 -0.002" mass="1" diaginertia="1e-4 1e-4 1.5e-4"/>'
                   f'<geom type="sphere" size="{_R}"/>'), "centre of mass"),
        (_body_xml('<geom type="sphere" size="0.01"/><body><geom type="box" size=".1 .1 .1"/>'
                   '</body>'), "no child bodies"),
        ("<mujoco><worldbody><body><freejoint/></mujoco>", "valid MJCF"),
        ("/nonexistent/top.xml", "MJCF text or the path of an MJCF file"),
    ],
)
def test_unusable_models_are_rejected(xml: str, fragment: str) -> None:
    with pytest.raises(TippetopError, match=fragment) as err:
        load_top(xml)
    assert "\n" not in str(err.value)


def test_load_from_path(tmp_path) -> None:
    path = tmp_path / "top.xml"
    path.write_text(make_mjcf(TOPS[1]))
    assert load_top(path).top.a_m == pytest.approx(TOPS[1].a_m, rel=1e-12)


def test_off_centre_origin_shifts_the_normal_force() -> None:
    # MuJoCo's contact dynamics use J qacc without J-dot q-dot. With the body origin at S, the
    # normal row J qacc is exactly the gap's acceleration z_S''; with the origin at O it misses
    # the centripetal term a (omega x (omega x k))_z, so the soft contact's normal force shifts
    # by that over (A + R) (A = J M^-1 J^T, R the regulariser): checked here to 1e-9.
    top = TopParams.from_ratios(0.95, 0.125)
    body_at_com = f"""<mujoco><option gravity="0 0 -9.8"/><worldbody>
      <geom type="plane" size="1 1 .1" condim="1"/>
      <body pos="0 0 0.1"><freejoint/>
        <inertial pos="0 0 0" mass="{top.M_kg!r}"
                  diaginertia="{top.A_kgm2!r} {top.C_kgm2!r} {top.A_kgm2!r}"/>
        <geom type="sphere" size="{top.R_m!r}" pos="0 {-top.a_m!r} 0" condim="1"/>
      </body></worldbody></mujoco>"""
    with pytest.warns(TopModelWarning, match="origin"):
        generic = load_top(body_at_com)
    init = InitialState(theta0=0.4, thetadot0=1.0, Omega0=5.0, n0=100.0)
    forces = []
    for tm in (load_top(make_mjcf(top)), generic):
        model, data = tm.model, mujoco.MjData(tm.model)
        data.qpos[:], data.qvel[:] = initial_qpos_qvel(tm, init)
        data.qpos[tm.qpos_adr + 2] -= 1e-4  # press the ball 0.1 mm into the table
        mujoco.mj_forward(model, data)
        assert data.nefc == 1
        J = data.efc_J.reshape(1, model.nv).copy()
        MinvJ = np.zeros_like(J)
        mujoco.mj_solveM(model, data, MinvJ, J)
        forces.append((data.efc_force[0], float((J @ MinvJ.T)[0, 0]), data.efc_R[0]))
        kin = kinematics(tm, data.qpos, data.qvel)
    (N_s, A, R), (N_o, _, _) = forces
    w, k = kin.omega_radps[0], kin.k[0]
    predicted = top.a_m * np.cross(w, np.cross(w, k))[2] / (A + R)
    # a real effect: over 1% of the normal force here. Measured: 1.5% of M g for a = 1.9 mm,
    # n = 100 rad/s, theta = 0.4, origin at the centre of mass (an error of the normal force
    # ~ M |centre offset| |omega x (omega x k)|, the term MuJoCo omits with the body origin
    # away from the sphere's centre S, which load_top allows with a warning)
    assert abs(predicted) > 0.01 * N_s
    assert N_o - N_s == pytest.approx(predicted, rel=1e-9)


# --- extra colliding geoms ----------------------------------------------------------------

_BALL = f'<inertial pos="0 0 -0.002" mass="0.015" diaginertia="1.4e-6 1.4e-6 1.35e-6"/>' \
        f'<geom name="ball" type="sphere" size="{_R}"/>'


def _load_with(stem: str):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tm = load_top(_body_xml(_BALL + stem))
    return tm, [w for w in caught if issubclass(w.category, TopModelWarning)]


def test_capsule_stem_is_the_references_stem_and_does_not_warn() -> None:
    r, z2 = 0.1 * _R, 2 * _R
    tm, caught = _load_with(f'<geom name="stem" type="capsule" fromto="0 0 {0.5 * _R} 0 0 {z2}" '
                            f'size="{r}"/>')
    expected = math.acos(-(_R - r) / z2)  # the tip's hemisphere touches: R + z2 cos - r = 0
    stem = tm.model.geom("stem").id
    assert touch_tilt(tm, stem) == pytest.approx(expected, abs=1e-9)
    # the reference models it (a rounded end at z2 of radius r): expected, so no warning; the
    # stem's note says where it touches
    assert len(caught) == 0 and tm.warnings == ()
    end, note = stem_from_model(tm)
    assert end == StemParams("sphere", z2, r)
    assert "'stem'" in note and f"theta = {expected:.4f} rad" in note


@pytest.mark.parametrize(
    ("stem", "equation"),
    [
        # cylinder from 0.5R to 1.8R, radius 0.15R: the end disc's rim touches.
        (f'<geom name="stem" type="cylinder" fromto="0 0 {0.5 * _R} 0 0 {1.8 * _R}" '
         f'size="{0.15 * _R}"/>',
         lambda t: _R + 1.8 * _R * math.cos(t) - 0.15 * _R * math.sin(t)),
        # a knob on the axis.
        (f'<geom name="stem" type="sphere" pos="0 0 {1.5 * _R}" size="{0.2 * _R}"/>',
         lambda t: _R + 1.5 * _R * math.cos(t) - 0.2 * _R),
        # a square box on the axis: its corner (azimuth 45 deg) touches first.
        (f'<geom name="stem" type="box" pos="0 0 {1.2 * _R}" '
         f'size="{0.2 * _R} {0.2 * _R} {0.4 * _R}"/>',
         lambda t: _R + 1.6 * _R * math.cos(t) - math.sqrt(2) * 0.2 * _R * math.sin(t)),
    ],
)
def test_touch_tilt_matches_geometry(stem: str, equation) -> None:
    tm, caught = _load_with(stem)
    expected = brentq(equation, math.pi / 2, math.pi, xtol=1e-14)
    assert touch_tilt(tm, tm.model.geom("stem").id) == pytest.approx(expected, abs=1e-9)
    # a cylinder or sphere on the axis is the reference's stem; a box is said, with its tilt
    if 'type="box"' in stem:
        assert len(caught) == 1 and f"theta = {expected:.4f} rad" in tm.warnings[0]
    else:
        assert len(caught) == 0


def test_inner_colliding_geom_never_touches() -> None:
    tm, caught = _load_with(f'<geom name="bead" type="sphere" pos="0 0 {-0.5 * _R}" '
                            f'size="{0.2 * _R}"/>')
    assert touch_tilt(tm, tm.model.geom("bead").id) is None
    assert len(caught) == 1 and "never touches" in tm.warnings[0]


def test_visual_stem_does_not_warn() -> None:
    _, caught = _load_with(f'<geom name="stem" type="capsule" fromto="0 0 0 0 0 {2 * _R}" '
                           f'size="{0.1 * _R}" contype="0" conaffinity="0"/>')
    assert caught == []


# --- MuJoCo's errors, one line each (issue 29) ---------------------------------------------
@pytest.mark.parametrize(("message", "says"), [
    # MuJoCo's XML parser, on a document Python's parser reads: its line and its reason
    ("XML parse error 7:\nError=XML_ERROR_PARSING_ATTRIBUTE ErrorID=7 (0x7) Line number=9: "
     "XMLElement name=option\n", "got an XML error at line 9: a malformed attribute (<option>)"),
    ("XML Error: Schema violation: unrecognized attribute: 'colour'\nElement 'geom', line 12\n",
     "got a MuJoCo error at line 12 (<geom>): Schema violation: unrecognized attribute: "
     "'colour'"),
    ("XML Error: Error: repeated name 'ball' in geom\nElement 'geom', line 22\n",
     "got a MuJoCo error at line 22 (<geom>): repeated name 'ball' in geom"),
    ("Error: size 0 must be positive in geom\nElement name 'ball', id 1, line 22",
     "got a MuJoCo error at line 22 ('ball'): size 0 must be positive in geom"),
    ("Error: Error opening file 'nope.stl'", "got a MuJoCo error: Error opening file 'nope.stl'"),
    ("first\nsecond\n", "got a MuJoCo error: first; second"),
])
def test_mujoco_load_errors_are_one_line(message: str, says: str) -> None:
    line = load_error(message, None, "<mujoco/>")
    assert line == f"mjcf: expected a valid MJCF document, {says}"


def test_an_error_in_an_included_file_names_that_file(tmp_path) -> None:
    (tmp_path / "part.xml").write_text("<mujoco>\n  <option timestep=")
    main = tmp_path / "main.xml"
    main.write_text('<mujoco>\n  <include file="part.xml"/>\n  <worldbody/>\n</mujoco>\n')
    with pytest.raises(TippetopError) as err:
        load_top(str(main))
    assert str(err.value) == (f"{tmp_path / 'part.xml'} (included by {main} at line 2): "
                              "expected a valid MJCF document, got an XML error at line 2, "
                              "column 3: unclosed token")
