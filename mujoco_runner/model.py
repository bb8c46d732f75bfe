"""Load an MJCF tippe top and read the paper's parameters (R, a, A, C, M) from the compiled model.

"Any MJCF top" is a model with exactly one body on a free joint, with no child bodies, that
carries a colliding sphere geom: the ball that touches the table (the largest colliding sphere
if there are several). The table is the plane z = 0 and gravity points along -z; the inertia
must be axisymmetric about the line through the centre of mass and the sphere's centre.
:func:`load_top` loads one as a :class:`TopModel`. The rules in full, and what is allowed
with a warning (a stem, a body origin off the ball's centre): docs/design.md.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np

from tippetop.models import mjcf_document
from tippetop.models.errors import TippetopError, expect
from tippetop.models.frames import quat_to_mat
from tippetop.models.mjcf import HARNESS_USERDATA
from tippetop.models.params import StemParams, TopParams

#: MuJoCo's own warning texts in this process, newest last. MuJoCo would print each as
#: ``WARNING: ...`` lines on stderr, beside the run's one-line message; a run reports the
#: warning in that message instead (from ``mjData.warning``, :mod:`mujoco_runner.checks`).
MUJOCO_WARNINGS: deque[str] = deque(maxlen=20)


def _keep_mujoco_warning(message: str) -> None:
    """MuJoCo's warning handler: keep the text (one line) instead of printing it."""
    MUJOCO_WARNINGS.append(" ".join(str(message).split()))


#: Relative tolerance for "A1 == A2" and for "the centre of mass is on the axis" (in units of R).
AXISYMMETRY_RTOL = 1e-9

# Geom types whose lowest point :func:`touch_tilt` computes in closed form (support functions).
_SUPPORTED_TOUCH_TYPES = {
    int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
    int(mujoco.mjtGeom.mjGEOM_BOX): "box",
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
}
_ORIGIN_RTOL = 1e-12  # body origin "at" the sphere's centre, in units of R
_TILT_GRID = 2001  # tilt samples on [0, pi] before bisection
_AZIMUTH_GRID = 360  # azimuth samples (1 degree) for geoms that are not axisymmetric about k
_BISECTIONS = 60  # refines the first touching tilt to ~1e-15 rad


class TopModelWarning(UserWarning):
    """The MJCF top departs from the paper's loaded sphere in a way that changes the results."""


@dataclass(frozen=True, eq=False)
class TopModel:
    """A compiled MJCF top with the paper's parameters and where they sit in the body.

    Attributes:
        model: The compiled model.
        top: R, a, A, C, M and g read from the model (SI).
        body_id: Id of the free body.
        joint_id: Id of its free joint.
        qpos_adr: Address of the free joint in ``qpos`` (7 numbers: position, w x y z).
        dof_adr: Address of the free joint in ``qvel`` (6 numbers: world linear velocity of the
            body origin, body-frame angular velocity).
        ball_geom_id: Id of the colliding sphere geom.
        centre_body_m: The sphere's centre S in the body frame, shape (3,) (zero for
            :func:`models.mjcf.make_mjcf` models).
        axis_body: The unit symmetry axis k (from O towards S) in the body frame, shape (3,).
        paper_from_body_quat: Quaternion (w, x, y, z) of the rotation taking body-frame vectors
            to the paper's body frame (whose z axis is k), shape (4,). Identity for
            :func:`models.mjcf.make_mjcf` models.
        warnings: Messages about extra colliding geoms and an off-centre body origin (also
            issued with ``warnings.warn`` as :class:`TopModelWarning`).
    """

    model: mujoco.MjModel
    top: TopParams
    body_id: int
    joint_id: int
    qpos_adr: int
    dof_adr: int
    ball_geom_id: int
    centre_body_m: np.ndarray
    axis_body: np.ndarray
    paper_from_body_quat: np.ndarray
    warnings: tuple[str, ...] = field(default=())


def load_model(mjcf: str | os.PathLike[str]) -> mujoco.MjModel:
    """Compile MJCF given as text (starts with ``<``) or as a file path.

    The document is parsed into an :class:`mujoco.MjSpec` and compiled from it, with
    :data:`models.mjcf.HARNESS_USERDATA` entries appended to the ``nuserdata`` it declares: the
    paper-mode callback keeps its parameters there (the last entries of ``mjData.userdata``;
    see :mod:`mujoco_runner.friction_callback`), and the document's own userdata stays in
    front, untouched. Nothing else differs from ``mujoco.MjModel.from_xml_path`` (or
    ``from_xml_string``) on the same document.

    Raises:
        TippetopError: If the file is missing or MuJoCo rejects the document.
    """
    mujoco.set_mju_user_warning(_keep_mujoco_warning)  # every run loads its model here
    is_text = isinstance(mjcf, str) and mjcf.lstrip().startswith("<")
    try:
        if is_text:
            spec = mujoco.MjSpec.from_string(mjcf)
        else:
            path = os.fspath(mjcf)
            expect(os.path.isfile(path), "mjcf", "MJCF text or the path of an MJCF file", path)
            spec = mujoco.MjSpec.from_file(path)
        spec.nuserdata += HARNESS_USERDATA
        return spec.compile()
    except ValueError as exc:
        if isinstance(exc, TippetopError):
            raise
        path = None if is_text else os.fspath(mjcf)
        raise TippetopError(load_error(str(exc), path, mjcf if is_text else None)) from None


#: The errors of MuJoCo's XML parser (tinyxml2) in words, for a document Python's XML parser
#: reads (which says what is wrong, and where, better: :func:`load_error` asks it first).
_TINYXML_REASONS = {
    "XML_ERROR_PARSING_ELEMENT": "a malformed element",
    "XML_ERROR_PARSING_ATTRIBUTE": "a malformed attribute",
    "XML_ERROR_PARSING_TEXT": "malformed text",
    "XML_ERROR_PARSING_CDATA": "a malformed CDATA section",
    "XML_ERROR_PARSING_COMMENT": "a malformed comment",
    "XML_ERROR_PARSING_DECLARATION": "a malformed declaration",
    "XML_ERROR_PARSING_UNKNOWN": "a malformed <!...> element",
    "XML_ERROR_EMPTY_DOCUMENT": "no element",
    "XML_ERROR_MISMATCHED_ELEMENT": "a closing tag that does not match",
    "XML_ELEMENT_DEPTH_EXCEEDED": "elements nested too deep",
}
#: MuJoCo's messages: its XML parser's (multi-line), an included file's, an element's, and
#: the compiler's.
_PARSE_ERROR = re.compile(r"XML parse error \d+:\s*Error=(\w+).*?Line number=(\d+)"
                          r"(?::\s*XMLElement name=(\S+))?", re.DOTALL)
_INCLUDE_ERROR = re.compile(r"^XML Error: Include error: '(.*)'\s*Element 'include', line "
                            r"(\d+)\s*$", re.DOTALL)
_ELEMENT_ERROR = re.compile(r"^(?:XML )?Error: (.*?)\s*\n\s*Element '([^']*)', line (\d+)\s*$",
                            re.DOTALL)
_COMPILE_ERROR = re.compile(r"^Error: (.*?)\s*\n\s*Element name '([^']*)', id \d+, line "
                            r"(\d+)\s*$", re.DOTALL)
#: MuJoCo's compiler on a keyframe with more numbers than the model has room for (qpos, qvel
#: and act say how many they got; ctrl, mpos and mquat do not). The keyframe is named by
#: name or by id, then by its element's name and id (no line).
_KEY_SIZE_ERROR = re.compile(r"^Error: keyframe (?:'[^']*'|\d+): invalid (\w+) size, expected "
                             r"(?:length )?(\d+)(?:, got (\d+))?\s*\n\s*Element name '([^']*)', "
                             r"id (\d+)(?:, line (\d+))?\s*$", re.DOTALL)
#: What a keyframe's numbers of each kind are for (the hint of a keyframe with too many).
_KEY_FIELDS = {"qpos": "joints", "qvel": "joints", "act": "actuators with an activation",
               "ctrl": "actuators", "mpos": "mocap bodies", "mquat": "mocap bodies"}


def load_error(message: str, path: str | None, text: str | None = None, *,
               label: str | None = None) -> str:
    """MuJoCo's error loading a document as one line: the file, the line, the reason.

    MuJoCo's messages run over several lines, and its XML parser's name no reason a reader
    knows (``XML parse error 7: Error=XML_ERROR_PARSING_ATTRIBUTE ... Line number=9``): such
    a document is read again with Python's XML parser, which names the line, the column and
    the reason (``unclosed token``); an empty, binary or non-UTF-8 file is said to be one. An
    error in an included file names that file, and the line that includes it.

    Args:
        message: MuJoCo's message (its ``ValueError``).
        path: The file loaded; None for a document given as text.
        text: The document given as text (when ``path`` is None).
        label: What to call the document (default: ``path``, or ``mjcf`` for text).

    Returns:
        ``FILE: expected a valid MJCF document, got ...``.
    """
    where = label or (path if path is not None else "mjcf")
    included = _INCLUDE_ERROR.match(message.strip())
    if included is not None:
        inner, line = included.group(1), int(included.group(2))
        by = f"included by {where} at line {line}"
        name = _included_name(path, text, line)
        if name is None:
            return load_error(inner, None, label=f"the file {by}")
        # MuJoCo's rule: an included file's name is relative to the main file's folder
        sub = name if path is None else os.path.join(os.path.dirname(path), name)
        return load_error(inner, sub if os.path.isfile(sub) else None, label=f"{sub} ({by})")
    return f"{where}: expected a valid MJCF document, got {_mujoco_reason(message, path, text)}"


def _included_name(path: str | None, text: str | None, line: int) -> str | None:
    """The file named by the ``<include>`` on line ``line`` of the document, if it says."""
    try:
        source = Path(path).read_text(encoding="utf-8", errors="replace") if path is not None \
            else (text or "")
    except OSError:
        return None
    lines = source.splitlines()
    found = re.search(r"""<include\s[^>]*?file\s*=\s*["']([^"']*)["']""",
                      lines[line - 1] if 0 < line <= len(lines) else "")
    return found.group(1) if found else None


def _mujoco_reason(message: str, path: str | None, text: str | None) -> str:
    """What :func:`load_error` says went wrong (after ``got``)."""
    message = message.strip()
    parse_error = _PARSE_ERROR.search(message)
    if parse_error is not None or "empty file" in message:
        data = b""
        try:
            data = Path(path).read_bytes() if path is not None else (text or "").encode()
        except OSError:
            pass
        problem = mjcf_document.xml_problem(data)
        if problem is not None and parse_error is not None:
            code, line, element = parse_error.groups()
            if code == "XML_ERROR_MISMATCHED_ELEMENT" and element and \
                    problem.endswith("mismatched tag"):
                problem += f" (expected the end of the <{element}> of line {line})"
        if problem is not None:
            return problem
    if parse_error is not None:
        code, line, element = parse_error.groups()
        reason = _TINYXML_REASONS.get(code, code.removeprefix("XML_ERROR_").replace("_", " ")
                                      .lower())
        return f"an XML error at line {line}: {reason}" + (f" (<{element}>)" if element else "")
    found = _KEY_SIZE_ERROR.match(message)
    if found is not None:
        return _keyframe_reason(found, path, text)
    found = _ELEMENT_ERROR.match(message)
    if found is not None:
        reason, element, line = found.groups()
        return f"a MuJoCo error at line {line} (<{element}>): {reason.removeprefix('Error: ')}"
    found = _COMPILE_ERROR.match(message)
    if found is not None:
        reason, name, line = found.groups()
        return f"a MuJoCo error at line {line}" + (f" ('{name}')" if name else "") + \
            f": {reason}"
    lines = [" ".join(ln.split()) for ln in message.splitlines() if ln.strip()]
    return "a MuJoCo error: " + ("; ".join(lines).removeprefix("Error: ") or "(no message)")


def _keyframe_reason(found: re.Match[str], path: str | None, text: str | None) -> str:
    """A keyframe with too many numbers of a kind, with its line and a hint (``got`` of load_error).

    MuJoCo names neither the line nor what the extra numbers were for; the commonest cause is
    a keyframe left behind when the free joint (7 qpos, 6 qvel numbers) was removed.
    """
    kind, room, got, name, index, line = found.groups()
    keys, includes = _key_elements(path, text)
    key = None
    if name:
        named = [k for k in keys if k[0] == name]
        key = named[0] if len(named) == 1 else None
    elif not includes and int(index) < len(keys):
        key = keys[int(index)]  # keyframes compile in document order
    if got is None and key is not None and kind in key[2]:
        got = str(len(key[2][kind].split()))
    if line is None and key is not None:
        line = str(key[1])
    where = f"a MuJoCo error at line {line} (<key>)" if line else "a MuJoCo error"
    who = f"keyframe '{name}'" if name else f"keyframe {index} (no name)"
    many = f"{got} {kind} numbers" if got is not None else f"more {kind} numbers"
    n_room, extra = int(room), (int(got) - int(room) if got is not None else 0)
    per_free = {"qpos": 7, "qvel": 6}.get(kind)
    if per_free and extra > 0 and extra % per_free == 0:
        n = extra // per_free
        meant = "a free joint that is" if n == 1 else f"{n} free joints that are"
    else:
        meant = f"{_KEY_FIELDS.get(kind, kind)} that are"
    return (f"{where}: {who} has {many} but the model has {n_room}: a keyframe written for "
            f"{meant} no longer there? Remove the keyframe or fix its {kind}")


def _key_elements(path: str | None, text: str | None
                  ) -> tuple[list[tuple[str, int, dict[str, str]]], bool]:
    """The document's ``<key>`` elements (name, line, attributes) and whether it includes files.

    Only the document itself is read (an included file's keyframes are not listed); a
    document Python's XML parser cannot read has none.
    """
    from xml.parsers import expat

    try:
        data = Path(path).read_bytes() if path is not None else (text or "").encode()
    except OSError:
        return [], False
    keys: list[tuple[str, int, dict[str, str]]] = []
    includes = False
    parser = expat.ParserCreate()

    def start(tag: str, attrs: dict[str, str]) -> None:
        nonlocal includes
        if tag == "key":
            keys.append((attrs.get("name", ""), parser.CurrentLineNumber, attrs))
        includes = includes or tag == "include"

    parser.StartElementHandler = start
    try:
        parser.Parse(data, True)
    except expat.ExpatError:
        return [], False
    return keys, includes


def load_top(mjcf: str | os.PathLike[str]) -> TopModel:
    """Compile MJCF (text or path) and read the top's parameters; see :func:`top_from_model`.

    A file's messages name it (as given); text's name ``mjcf``.
    """
    is_text = isinstance(mjcf, str) and mjcf.lstrip().startswith("<")
    return top_from_model(load_model(mjcf), source=None if is_text else os.fspath(mjcf))


def top_from_mjcf_file(path: str | os.PathLike[str]) -> TopParams:
    """The paper's parameters (R, a, A, C, M, g) of the top in an MJCF file or text."""
    return load_top(path).top


def _name(model: mujoco.MjModel, obj: mujoco.mjtObj, i: int) -> str:
    return mujoco.mj_id2name(model, obj, i) or f"#{i}"


def quat_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of the smallest rotation taking unit u to unit v."""
    d = float(np.dot(u, v))
    if d < -1 + 1e-12:
        # Half turn about any axis perpendicular to u.
        axis = np.cross(u, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(u, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.array([0.0, *axis])
    q = np.array([1.0 + d, *np.cross(u, v)])
    return q / np.linalg.norm(q)


def _symmetry_axis(
    model: mujoco.MjModel, b: int, centre_body: np.ndarray, R: float,
    source: str | None = None,
) -> tuple[np.ndarray, float, float]:
    """The unit axis k (body frame, O -> S) and the moments (A, C); raise if not axisymmetric.

    ``source``: the file the model came from, named in the message (None: text).
    """
    body = _in(source, f"body '{_name(model, mujoco.mjtObj.mjOBJ_BODY, b)}'")
    moments = np.array(model.body_inertia[b], dtype=float)
    axes = quat_to_mat(model.body_iquat[b])  # columns: principal axes in the body frame
    offset = centre_body - np.array(model.body_ipos[b], dtype=float)  # S - O, body frame
    a = float(np.linalg.norm(offset))
    pairs = [(i, j, 3 - i - j) for i, j in ((0, 1), (0, 2), (1, 2))]
    equal = [
        (i, j, c) for i, j, c in pairs
        if abs(moments[i] - moments[j]) <= AXISYMMETRY_RTOL * max(moments[i], moments[j])
    ]
    expect(bool(equal), f"{body} inertia",
           f"two equal principal moments (axisymmetric to {AXISYMMETRY_RTOL:g} relative)",
           tuple(float(m) for m in moments))
    if len(equal) == 3:  # spherical inertia: any axis is principal; take O -> S
        A = C = float(np.mean(moments))
        axis = offset / a if a > 0 else axes[:, 2]
        return axis, A, C
    i, j, c = equal[0]
    A, C = 0.5 * float(moments[i] + moments[j]), float(moments[c])
    axis = axes[:, c] / np.linalg.norm(axes[:, c])
    off_axis = float(np.linalg.norm(offset - np.dot(offset, axis) * axis))
    expect(off_axis <= AXISYMMETRY_RTOL * R, f"{body} centre of mass",
           "on the principal C axis through the sphere's centre (off by <= "
           f"{AXISYMMETRY_RTOL:g} R)", f"{off_axis:.3e} m off the axis")
    if a > 0 and np.dot(offset, axis) < 0:
        axis = -axis
    return axis, A, C


def _lowest_offsets(model: mujoco.MjModel, g: int, centre_body: np.ndarray,
                    ups: np.ndarray) -> np.ndarray | None:
    """Min over geom g of ``up . (x - S)`` for each body-frame up vector (rows of ``ups``).

    Returns None for geom types without a closed-form support function.
    """
    kind = _SUPPORTED_TOUCH_TYPES.get(int(model.geom_type[g]))
    if kind is None:
        return None
    size = np.array(model.geom_size[g], dtype=float)
    rot = quat_to_mat(model.geom_quat[g])  # geom frame -> body frame
    centre = ups @ (np.array(model.geom_pos[g], dtype=float) - centre_body)
    proj = ups @ rot  # (n, 3): components of up along the geom's axes
    if kind == "sphere":
        reach = np.full(len(ups), size[0])
    elif kind == "capsule":
        reach = size[0] + size[1] * np.abs(proj[:, 2])
    elif kind == "cylinder":
        reach = size[1] * np.abs(proj[:, 2]) + size[0] * np.sqrt(
            np.clip(1.0 - proj[:, 2] ** 2, 0.0, None))
    elif kind == "box":
        reach = np.abs(proj) @ size
    else:  # ellipsoid
        reach = np.sqrt(((proj * size) ** 2).sum(axis=1))
    return centre - reach


def _ups(tilt: np.ndarray, azimuth: np.ndarray, paper_from_body: np.ndarray) -> np.ndarray:
    """World up e_z in the body frame for every (tilt, azimuth) pair, shape (n, 3).

    Body orientation: Ry(tilt) Rz(azimuth) Q, with Q the paper-from-body rotation.
    """
    t, p = np.meshgrid(tilt, azimuth, indexing="ij")
    up_paper = np.stack([-np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    return up_paper.reshape(-1, 3) @ quat_to_mat(paper_from_body)  # Q^T u, row-wise


def _axisymmetric_about_k(top_model: TopModel, g: int) -> bool:
    """A sphere, capsule or cylinder centred on the symmetry axis and aligned with it."""
    model, k = top_model.model, top_model.axis_body
    kind = _SUPPORTED_TOUCH_TYPES.get(int(model.geom_type[g]))
    offset = np.array(model.geom_pos[g], dtype=float) - top_model.centre_body_m
    on_axis = np.linalg.norm(offset - np.dot(offset, k) * k) <= 1e-12 * top_model.top.R_m
    if kind == "sphere":
        return bool(on_axis)
    if kind in ("capsule", "cylinder"):
        return bool(on_axis and abs(abs(quat_to_mat(model.geom_quat[g])[:, 2] @ k) - 1) < 1e-12)
    return False


def stem_geoms(top_model: TopModel) -> list[int]:
    """The top's colliding geoms other than the ball (a stem, say), in id order."""
    model, b = top_model.model, top_model.body_id
    return [g for g in range(model.ngeom)
            if g != top_model.ball_geom_id and model.geom_bodyid[g] == b
            and (model.geom_contype[g] != 0 or model.geom_conaffinity[g] != 0)]


def _stem_search(top_model: TopModel) -> tuple[tuple[float, StemParams, str, int] | None,
                                                 list[str]]:
    """The stem the reference models and the colliding geoms that cannot be one.

    Returns:
        ((tilt, stem, geom name, geom id) or None; the names of the other colliding geoms
        that cannot be a stem). See :func:`stem_from_model`.
    """
    model, k, S = top_model.model, top_model.axis_body, top_model.centre_body_m
    R = top_model.top.R_m
    found: list[tuple[float, StemParams, str, int]] = []
    others: list[str] = []
    for g in stem_geoms(top_model):
        name = _name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        kind = _SUPPORTED_TOUCH_TYPES.get(int(model.geom_type[g]))
        if kind not in ("sphere", "capsule", "cylinder") or not _axisymmetric_about_k(
                top_model, g):
            others.append(name)
            continue
        along = float((np.array(model.geom_pos[g], dtype=float) - S) @ k)
        r = float(model.geom_size[g, 0])
        half = 0.0 if kind == "sphere" else float(model.geom_size[g, 1])
        stem = StemParams(kind="cylinder" if kind == "cylinder" else "sphere",
                          offset_m=along + half, radius_m=r) if along + half > 0 else None
        if stem is None or not (stem.offset_m + stem.radius_m > R):
            continue  # inside the ball, or on the ballast's side: never the stem
        c = stem.touch_cos(R)
        if -1.0 < c < 1.0:
            found.append((math.acos(c), stem, name, g))
    return (min(found, key=lambda f: f[0]) if found else None), others


def stem_from_model(top_model: TopModel) -> tuple[StemParams | None, str]:
    """The stem's end as the reference models it, from the top's colliding geoms.

    A sphere, capsule or cylinder on the symmetry axis and aligned with it, beyond the ball's
    centre along k, gives the end: a sphere's centre and radius, a capsule's far cap, a
    cylinder's far face and rim. Of several, the one that reaches the table first (the
    smallest tilt). Other colliding geoms (a box, an off-axis geom) cannot be a stem of the
    reference: their presence is said in the returned note.

    Returns:
        (the stem, or None; a one-line note on what was found).
    """
    best, others = _stem_search(top_model)
    if best is None:
        note = "no stem: no colliding sphere, capsule or cylinder on the axis reaches beyond " \
               "the ball" + (f" (other colliding geoms: {', '.join(others)})" if others else "")
        return None, note
    tilt, stem, name, _g = best
    note = (f"stem: geom '{name}', a {'flat' if stem.kind == 'cylinder' else 'rounded'} end "
            f"{stem.offset_m * 1e3:.4g} mm from the ball's centre, radius "
            f"{stem.radius_m * 1e3:.4g} mm, touching at theta = {tilt:.4f} rad")
    if others:
        note += f"; not modelled by the reference: {', '.join(others)}"
    return stem, note


def touch_tilt(top_model: TopModel, geom_id: int) -> float | None:
    """Smallest tilt theta (rad) at which a geom of the top touches the table.

    The ball rests on the table (its centre at height R); the geom touches when its lowest
    point reaches z = 0. Geoms that are not axisymmetric about k (anything but a sphere,
    capsule or cylinder centred on and aligned with k) are checked every degree of azimuth
    about k, and the worst azimuth counts.

    Supported geom types: sphere, capsule, cylinder, box, ellipsoid (any position and
    orientation in the body). Others raise TippetopError.

    Returns:
        The tilt in [0, pi] (0 if it already touches upright), or None if it never touches.
    """
    model, g = top_model.model, geom_id
    kind = _SUPPORTED_TOUCH_TYPES.get(int(model.geom_type[g]))
    expect(kind is not None, f"geom '{_name(model, mujoco.mjtObj.mjOBJ_GEOM, g)}' type",
           "one of " + "|".join(_SUPPORTED_TOUCH_TYPES.values()), int(model.geom_type[g]))
    R, c_b, q = top_model.top.R_m, top_model.centre_body_m, top_model.paper_from_body_quat
    n_azimuth = 1 if _axisymmetric_about_k(top_model, g) else _AZIMUTH_GRID
    azimuth = np.linspace(0.0, 2 * math.pi, n_azimuth, endpoint=False)

    def clearance(tilts: np.ndarray) -> np.ndarray:
        low = _lowest_offsets(model, g, c_b, _ups(tilts, azimuth, q))
        return R + low.reshape(len(tilts), len(azimuth)).min(axis=1)

    tilts = np.linspace(0.0, math.pi, _TILT_GRID)
    gap = clearance(tilts)
    hits = np.flatnonzero(gap <= 0)
    if hits.size == 0:
        return None
    if hits[0] == 0:
        return 0.0
    lo, hi = float(tilts[hits[0] - 1]), float(tilts[hits[0]])
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if clearance(np.array([mid]))[0] <= 0:
            hi = mid
        else:
            lo = mid
    return hi


def _extra_geom_warnings(top_model: TopModel) -> tuple[str, ...]:
    model, b = top_model.model, top_model.body_id
    best, _others = _stem_search(top_model)
    stem_id = None if best is None else best[3]  # the stem the reference follows: expected
    out = []
    for g in range(model.ngeom):
        if g in (top_model.ball_geom_id, stem_id) or model.geom_bodyid[g] != b:
            continue
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        name = _name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        kind = _SUPPORTED_TOUCH_TYPES.get(int(model.geom_type[g]))
        head = f"geom '{name}' on the top also collides"
        if kind is None:
            msg = (f"{head}; the tilt at which it touches the table is not computed for its type "
                   f"({int(model.geom_type[g])}; supported: "
                   + ", ".join(_SUPPORTED_TOUCH_TYPES.values()) + ")")
        else:
            tilt = touch_tilt(top_model, g)
            if tilt is None:
                msg = f"{head} ({kind}) but never touches the table at any tilt"
            else:
                msg = (f"{head} ({kind}): it touches the table at tilt theta = {tilt:.4f} rad "
                       f"({math.degrees(tilt):.1f} deg), where the paper's loaded sphere has "
                       "nothing, and the reference does not model it (only one sphere, "
                       "capsule or cylinder on the axis, beyond the ball, is its stem)")
        out.append(msg)
    return tuple(out)


def _in(source: str | None, what: str, text_what: str | None = None) -> str:
    """What a message names: ``FILE: what`` for a file, else ``text_what`` (default ``what``)."""
    if source is None:
        return what if text_what is None else text_what
    return f"{source}: {what}"


def top_from_model(model: mujoco.MjModel, *, source: str | None = None) -> TopModel:
    """Read the paper's parameters of the one free body of a compiled model.

    Args:
        model: The compiled model.
        source: The file it was compiled from, named in every message (None: ``mjcf``, a
            document given as text).

    Raises:
        TippetopError: If the model has not exactly one free body, the free body has child
            bodies or no colliding sphere geom (or several of the same largest radius),
            gravity is not along -z, or the inertia is not axisymmetric about the sphere's
            centre line.

    Warns:
        TopModelWarning: For each other colliding geom on the top, and for a body origin away
            from the sphere's centre (also listed in :attr:`TopModel.warnings`).
    """
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1:
        bodies = ", ".join(f"'{_name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.jnt_bodyid[j]))}'"
                           for j in free)
        got = (f"{len(free)} free joints (bodies {bodies})" if free else
               "0 free joints (the top's <body> needs a <freejoint/>)")
        raise TippetopError(f"{source or 'mjcf'}: expected exactly one body with a free joint, "
                            f"got {got}")
    j = free[0]
    b = int(model.jnt_bodyid[j])
    body = _name(model, mujoco.mjtObj.mjOBJ_BODY, b)
    children = [_name(model, mujoco.mjtObj.mjOBJ_BODY, c) for c in range(model.nbody)
                if c != b and model.body_parentid[c] == b]
    expect(not children, _in(source, f"body '{body}'"),
           "no child bodies (put every geom in the one body)", children)
    spheres = [
        g for g in range(model.ngeom)
        if model.geom_bodyid[g] == b and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
        and (model.geom_contype[g] != 0 or model.geom_conaffinity[g] != 0)
    ]
    radii = sorted((float(model.geom_size[g, 0]), g) for g in spheres)
    expect(len(spheres) == 1 or (len(spheres) > 1 and radii[-1][0] > radii[-2][0]),
           _in(source, f"body '{body}'"),
           "a colliding sphere geom (the ball; the largest if several)",
           [_name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in spheres])
    ball = radii[-1][1]
    timestep = float(model.opt.timestep)  # MuJoCo compiles 0 (or less); no run can take it
    expect(np.isfinite(timestep) and timestep > 0,
           _in(source, "option timestep", "mjcf option timestep"),
           "a step in seconds > 0", timestep)
    gravity = np.array(model.opt.gravity, dtype=float)
    expect(gravity[0] == 0 and gravity[1] == 0 and gravity[2] < 0,
           _in(source, "option gravity", "mjcf option gravity"),
           "(0, 0, -g) with g > 0 (the table is the plane z = 0)", tuple(gravity))
    R = float(model.geom_size[ball, 0])
    centre_body = np.array(model.geom_pos[ball], dtype=float)
    axis, A, C = _symmetry_axis(model, b, centre_body, R, source)
    a = float(np.linalg.norm(centre_body - model.body_ipos[b]))
    top = TopParams(R_m=R, a_m=a, M_kg=float(model.body_mass[b]), A_kgm2=A, C_kgm2=C,
                    g_mps2=float(-gravity[2]))
    top_model = TopModel(
        model=model, top=top, body_id=b, joint_id=j, qpos_adr=int(model.jnt_qposadr[j]),
        dof_adr=int(model.jnt_dofadr[j]), ball_geom_id=ball, centre_body_m=centre_body,
        axis_body=axis, paper_from_body_quat=quat_between(axis, np.array([0.0, 0.0, 1.0])),
    )
    messages = _extra_geom_warnings(top_model)
    offset = float(np.linalg.norm(centre_body))
    if offset > _ORIGIN_RTOL * R:
        messages += (
            f"body '{body}' origin is {offset * 1e3:.4g} mm from the ball's centre: MuJoCo's "
            "contact dynamics omit the velocity-product term, so the normal force is then off "
            "by ~ M offset |omega|^2; put the body origin at the sphere's centre",)
    for msg in messages:
        warnings.warn(msg, TopModelWarning, stacklevel=2)
    return replace(top_model, warnings=messages)


__all__ = [
    "AXISYMMETRY_RTOL",
    "TopModelWarning",
    "TopModel",
    "load_error",
    "load_model",
    "load_top",
    "quat_between",
    "top_from_mjcf_file",
    "stem_from_model",
    "stem_geoms",
    "top_from_model",
    "touch_tilt",
]
