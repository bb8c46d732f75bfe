"""MJCF text for the loaded-sphere tippe top on a table.

One template, filled by :func:`make_mjcf`: the plane ``table`` at z = 0 and the body ``top`` on
the free joint ``top_free``, whose origin is the sphere's centre S and whose z axis is the
symmetry axis k (see :mod:`models.frames`); ``ball``, the sphere of radius R, is the only geom
of the top that collides unless a stem is asked for. Every element the model holds, and why
the contact settings are written as they are: docs/design.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from tippetop.models.errors import expect
from tippetop.models.options import GENERATED_NOSLIP_ITERATIONS, MujocoOptions
from tippetop.models.params import StemParams, TopParams

#: The scene's MuJoCo defaults, the one place they are written (:class:`MujocoOptions`).
_DEFAULT = MujocoOptions()

#: Friction modes: "paper" = frictionless contact plus the paper's law applied by the harness;
#: "native" = MuJoCo's own contact friction.
FRICTION_MODES: tuple[str, ...] = ("paper", "native")
#: MuJoCo's integrators, as spelled in MJCF.
INTEGRATORS: tuple[str, ...] = ("Euler", "RK4", "implicit", "implicitfast")
#: MuJoCo's friction cones.
CONES: tuple[str, ...] = ("pyramidal", "elliptic")
#: Contact dimensionalities: 1 frictionless, 3 sliding, 4 adds torsional, 6 adds rolling.
CONDIMS: tuple[int, ...] = (1, 3, 4, 6)

#: MuJoCo's own default torsional and rolling coefficients (geom friction "1 0.005 0.0001").
MUJOCO_DEFAULT_TORSIONAL = 0.005  # (m)
MUJOCO_DEFAULT_ROLLING = 0.0001  # (m)

#: Entries of ``mjData.userdata`` the paper-mode callback reserves at the END of the vector for
#: its parameters and outputs (:mod:`mujoco_runner.friction_callback` defines their layout).
HARNESS_USERDATA = 26

#: Element names, shared with the runner (read quantities by name, never by index).
TABLE_GEOM = "table"
TOP_BODY = "top"
FREE_JOINT = "top_free"
BALL_GEOM = "ball"
STEM_GEOM = "stem"
MARKER_GEOM = "spin_marker"

# Visual-only geometry, in sphere radii (it has no mass and never collides).
_STEM_FROM_R = 0.8  # stem starts inside the ball, on the axis
_STEM_TO_R = 1.55  # stem tip above the ball's surface
_STEM_RADIUS_R = 0.12
_MARKER_HALF_R = (0.22, 0.05, 0.05)  # a flag at the stem tip, off the axis: shows the spin


def _num(x: float) -> str:
    """A float as MJCF text that parses back to the same double."""
    return repr(float(x))


def _nums(xs: Sequence[float]) -> str:
    return " ".join(_num(x) for x in xs)


def _finite_seq(what: str, values: Sequence[float], lengths: tuple[int, ...]) -> tuple:
    ok = (
        isinstance(values, (tuple, list))
        and len(values) in lengths
        and all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)
    )
    expect(ok, what, f"{' or '.join(map(str, lengths))} finite numbers", values)
    return tuple(float(v) for v in values)


@dataclass(frozen=True)
class MjcfContact:
    """The contact every colliding geom carries (the table, the ball, a colliding stem).

    Checked by :func:`make_mjcf` (one-line errors that name the field), not here.

    Attributes:
        friction_mode: ``"paper"``: frictionless contact (condim 1); the harness applies the
            paper's law (see :mod:`mujoco_runner.friction_callback`). ``"native"``: MuJoCo's
            own contact friction.
        condim: Contact dimensionality; ``None`` means 1 in paper mode and 3 in native mode.
            Native mode takes 1 (frictionless), 3 (sliding), 4 (adds torsional) or 6 (adds
            rolling).
        mu: Sliding friction coefficient, native mode only (the paper mode writes 0).
        torsional: Torsional friction coefficient (m), used when condim >= 4. Zero by default:
            pass :data:`MUJOCO_DEFAULT_TORSIONAL` for MuJoCo's own default.
        rolling: Rolling friction coefficient (m), used when condim == 6. Zero by default:
            pass :data:`MUJOCO_DEFAULT_ROLLING` for MuJoCo's own default.
        solref: Contact ``solref`` (timeconst in s, dampratio), or (-stiffness, -damping).
        solimp: Contact ``solimp`` (dmin, dmax, width in m[, midpoint, power]).
    """

    friction_mode: str = "paper"
    condim: int | None = None
    mu: float = 0.1
    torsional: float = 0.0
    rolling: float = 0.0
    solref: Sequence[float] = _DEFAULT.solref
    solimp: Sequence[float] = _DEFAULT.solimp


@dataclass(frozen=True)
class MjcfOption:
    """The model's ``<option>`` element: the integration, the solver and the contact flag.

    Checked by :func:`make_mjcf` (one-line errors that name the field), not here.

    Attributes:
        timestep_s: Integration step (s).
        integrator: One of :data:`INTEGRATORS`.
        cone: Friction cone, ``"pyramidal"`` or ``"elliptic"``.
        impratio: Ratio of frictional to normal constraint impedance.
        noslip_iterations: MuJoCo's noslip solver iterations (0: none).
        iterations: The constraint solver's maximum iterations (MuJoCo's default 100).
        tolerance: The solver's tolerance (MuJoCo's default 1e-8).
        contacts_on: False disables contacts (``<flag contact="disable"/>``).
    """

    timestep_s: float = _DEFAULT.timestep_s
    integrator: str = _DEFAULT.integrator
    cone: str = _DEFAULT.cone
    impratio: float = _DEFAULT.impratio
    noslip_iterations: int = GENERATED_NOSLIP_ITERATIONS
    iterations: int = 100
    tolerance: float = 1e-8
    contacts_on: bool = True


#: :func:`make_mjcf`'s defaults: the paper mode's frictionless contact, the scene's options.
DEFAULT_CONTACT = MjcfContact()
DEFAULT_OPTION = MjcfOption()


def _validate(contact: MjcfContact, option: MjcfOption) -> int:
    """Check the arguments of :func:`make_mjcf`; return the effective condim."""
    friction_mode, condim = contact.friction_mode, contact.condim
    expect(friction_mode in FRICTION_MODES, "friction_mode", "one of " + "|".join(FRICTION_MODES),
           friction_mode, FRICTION_MODES)
    if condim is None:
        condim = 1 if friction_mode == "paper" else 3
    expect(isinstance(condim, int) and condim in CONDIMS, "condim",
           "one of " + "|".join(map(str, CONDIMS)), condim)
    expect(friction_mode != "paper" or condim == 1, "condim",
           "1 in paper mode (the harness applies the friction itself)", condim)
    for name in ("mu", "torsional", "rolling"):
        value = getattr(contact, name)
        expect(isinstance(value, (int, float)) and math.isfinite(value) and value >= 0, name,
               "a finite number >= 0", value)
    timestep_s, impratio = option.timestep_s, option.impratio
    expect(isinstance(timestep_s, (int, float)) and math.isfinite(timestep_s) and timestep_s > 0,
           "timestep_s", "a finite number > 0 (seconds)", timestep_s)
    expect(option.integrator in INTEGRATORS, "integrator", "one of " + "|".join(INTEGRATORS),
           option.integrator, INTEGRATORS)
    expect(option.cone in CONES, "cone", "one of " + "|".join(CONES), option.cone, CONES)
    expect(isinstance(impratio, (int, float)) and math.isfinite(impratio) and impratio > 0,
           "impratio", "a finite number > 0", impratio)
    ref = _finite_seq("solref", contact.solref, (2,))
    expect(ref[0] != 0, "solref", "(timeconst > 0, dampratio > 0) or (-stiffness, -damping)",
           contact.solref)
    imp = _finite_seq("solimp", contact.solimp, (3, 5))
    expect(0 < imp[0] < 1 and 0 < imp[1] < 1 and imp[2] > 0, "solimp",
           "(dmin, dmax, width, ...) with 0 < dmin, dmax < 1 and width > 0 (m)", contact.solimp)
    noslip = option.noslip_iterations
    expect(isinstance(noslip, int) and not isinstance(noslip, bool) and noslip >= 0,
           "noslip_iterations", "an integer >= 0", noslip)
    return condim


def _contact_attributes(contact: MjcfContact, condim: int) -> str:
    """The contact as MJCF attributes: condim, friction (zero in paper mode), solref, solimp."""
    if contact.friction_mode == "paper":
        friction = (0.0, 0.0, 0.0)
    else:
        friction = (contact.mu, contact.torsional, contact.rolling)
    return (
        f'condim="{condim}" friction="{_nums(friction)}" solref="{_nums(contact.solref)}" '
        f'solimp="{_nums(contact.solimp)}"'
    )


def _top_body(top: TopParams, contact: str, stem: StemParams | None) -> str:
    """The body ``top`` as MJCF text: its inertia, the ball, the stem and the spin marker."""
    R, a = top.R_m, top.a_m
    stem_from, stem_to, stem_r = _STEM_FROM_R * R, _STEM_TO_R * R, _STEM_RADIUS_R * R
    if stem is None:
        stem_geom = (f'type="cylinder" fromto="0 0 {_num(stem_from)} 0 0 {_num(stem_to)}" '
                     f'size="{_num(stem_r)}" mass="0" contype="0" conaffinity="0" group="1"')
    else:
        stem_to, stem_r = stem.offset_m, stem.radius_m
        stem_geom = (f'type="{"capsule" if stem.kind == "sphere" else "cylinder"}" '
                     f'fromto="0 0 0 0 0 {_num(stem_to)}" size="{_num(stem_r)}" mass="0" '
                     f'{contact}')
    marker_pos = (_MARKER_HALF_R[0] * R + stem_r, 0.0, stem_to - _MARKER_HALF_R[2] * R)
    marker_size = tuple(h * R for h in _MARKER_HALF_R)
    return f"""    <body name="{TOP_BODY}" pos="0 0 {_num(R)}">
      <freejoint name="{FREE_JOINT}"/>
      <inertial pos="0 0 {_num(-a)}" mass="{_num(top.M_kg)}"
                diaginertia="{_nums((top.A_kgm2, top.A_kgm2, top.C_kgm2))}"/>
      <geom name="{BALL_GEOM}" type="sphere" size="{_num(R)}" mass="0" material="ball_mat"
            {contact}/>
      <geom name="{STEM_GEOM}" {stem_geom} material="stem_mat"/>
      <geom name="{MARKER_GEOM}" type="box" pos="{_nums(marker_pos)}" size="{_nums(marker_size)}"
            mass="0" contype="0" conaffinity="0" group="1" material="marker_mat"/>
    </body>"""


def make_mjcf(
    top: TopParams,
    *,
    contact: MjcfContact = DEFAULT_CONTACT,
    option: MjcfOption = DEFAULT_OPTION,
    stem: StemParams | None = None,
) -> str:
    """MJCF text of the loaded sphere on a table.

    Args:
        top: The loaded sphere (SI).
        contact: The contact of the table, the ball and a colliding stem (:class:`MjcfContact`:
            friction mode, condim, coefficients, solref, solimp).
        option: The ``<option>`` element (:class:`MjcfOption`: timestep, integrator, cone,
            impratio, noslip and solver iterations, tolerance, contacts on or off).
        stem: A colliding stem with this end (a capsule for a rounded end, a cylinder for a
            flat one, from the ball's centre to the end, massless, with the ball's contact
            settings). None: the stem is visual only (the paper's loaded sphere).

    Returns:
        The MJCF document as text.

    Raises:
        TippetopError: If a setting is out of range (one line: what, expected, got), checked
            in the order of :class:`MjcfContact`'s friction mode, condim and coefficients, then
            :class:`MjcfOption`'s timestep, integrator, cone and impratio, then the solref, the
            solimp and the noslip iterations.
    """
    condim = _validate(contact, option)
    R = top.R_m
    attributes = _contact_attributes(contact, condim)
    body = _top_body(top, attributes, stem)
    cam_dist = 12 * R
    o = option
    return f"""<mujoco model="tippetop">
  <compiler angle="radian" inertiafromgeom="false"/>
  <size nuserdata="{HARNESS_USERDATA}"/>
  <option timestep="{_num(o.timestep_s)}" integrator="{o.integrator}" cone="{o.cone}"
          impratio="{_num(o.impratio)}" noslip_iterations="{int(o.noslip_iterations)}"
          iterations="{int(o.iterations)}" tolerance="{_num(o.tolerance)}"
          gravity="0 0 {_num(-top.g_mps2)}">
    <flag contact="{'enable' if o.contacts_on else 'disable'}"/>
  </option>
  <visual>
    <global offwidth="1280" offheight="720"/>
    <headlight ambient="0.3 0.3 0.3" diffuse="0.6 0.6 0.6"/>
  </visual>
  <asset>
    <texture name="checker" type="2d" builtin="checker" rgb1="0.82 0.82 0.78"
             rgb2="0.55 0.6 0.65" width="512" height="512"/>
    <material name="table_mat" texture="checker" texrepeat="20 20" reflectance="0.05"/>
    <material name="ball_mat" rgba="0.85 0.3 0.15 1"/>
    <material name="stem_mat" rgba="0.2 0.2 0.25 1"/>
    <material name="marker_mat" rgba="0.95 0.85 0.1 1"/>
  </asset>
  <worldbody>
    <light name="key_light" pos="0 -0.3 0.6" dir="0 0.45 -1" directional="false"/>
    <camera name="side" pos="0 {_num(-cam_dist)} {_num(2 * R)}" xyaxes="1 0 0 0 0 1"/>
    <geom name="{TABLE_GEOM}" type="plane" size="0.5 0.5 0.01" material="table_mat" {attributes}/>
{body}
  </worldbody>
</mujoco>
"""


__all__ = [
    "BALL_GEOM",
    "CONDIMS",
    "CONES",
    "DEFAULT_CONTACT",
    "DEFAULT_OPTION",
    "FREE_JOINT",
    "FRICTION_MODES",
    "HARNESS_USERDATA",
    "INTEGRATORS",
    "MARKER_GEOM",
    "MUJOCO_DEFAULT_ROLLING",
    "MUJOCO_DEFAULT_TORSIONAL",
    "MjcfContact",
    "MjcfOption",
    "STEM_GEOM",
    "TABLE_GEOM",
    "TOP_BODY",
    "make_mjcf",
]
