"""The MJCF file of the model a run compiles, to step without tippetop (``tippetop mjcf``).

:func:`write_mjcf` writes it and checks that it compiles to the run's model, array by array;
docs/design.md says what the file holds.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from tippetop.models.errors import TippetopError

#: The name of the keyframe that holds the run's initial state.
KEYFRAME = "tippetop_start"
#: Model arrays that may differ between the file and the run's model: names, keyframes (the
#: file has one more), paths and text (bookkeeping, never read by mj_step), and the bounding-
#: volume trees of the collision midphase, which MuJoCo builds at compile time from the geoms
#: that collide then: a run that turns a stem's collisions off on the compiled model
#: (effects.stem = false) keeps the stem in its tree, where the collision filter drops it, and
#: the file compiles without it (the test steps such a file to the run's states bit for bit).
_SKIP_PREFIXES = ("name_", "names", "key_", "text_", "tex_pathadr", "mesh_pathadr",
                  "hfield_pathadr", "skin_pathadr", "signature", "bvh_", "body_bvh")
#: Model sizes that may differ (the keyframe, the names, the harness's userdata block, the
#: midphase trees).
_SKIP_SIZES = ("nkey", "nnames", "nnames_map", "nuserdata", "npaths", "ntext", "ntextdata",
               "narena", "nbuffer", "signature", "nbvh", "nbvhstatic", "nbvhdynamic")

# ---------------------------------------------------------------- the document
def _fmt(values: Any) -> str:
    """Numbers as MJCF text that parses back to the same doubles (``repr``)."""
    import numpy as np

    flat = np.atleast_1d(np.asarray(values, dtype=float)).ravel()
    return " ".join(repr(float(v)) for v in flat)


def _parse(text: str) -> Any:
    """The document's element tree, its comments kept."""
    import re
    import xml.etree.ElementTree as ET

    # MuJoCo's parser takes "--" inside a comment (strict XML does not): keep such comments
    text = re.sub(r"<!--(.*?)-->", lambda m: "<!--" + m.group(1).replace("--", "- -") + "-->",
                  text, flags=re.DOTALL)
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    try:
        return ET.fromstring(text, parser=parser)
    except ET.ParseError as exc:
        raise TippetopError(f"mjcf: expected an MJCF (XML) document, got: {exc}") from None


def _body_elements(root: Any) -> list[Any]:
    """``<worldbody>`` and the ``<body>`` elements, in MuJoCo's body order (depth first)."""
    world = root.find("worldbody")
    out: list[Any] = []

    def walk(el: Any) -> None:
        out.append(el)
        for child in _children(el, "body"):
            walk(child)

    if world is not None:
        walk(world)
    return out


def _children(el: Any, tag: str) -> list[Any]:
    """``el``'s ``tag`` children, also those inside ``<frame>`` elements, in order."""
    out = []
    for child in el:
        if child.tag == tag:
            out.append(child)
        elif child.tag == "frame":
            out.extend(_children(child, tag))
    return out


def _geom_elements(root: Any) -> list[Any]:
    """Every ``<geom>`` element in MuJoCo's geom order (by body, then as written)."""
    return [g for body in _body_elements(root) for g in _children(body, "geom")]


def _set(el: Any, **attrs: str) -> None:
    for k, v in attrs.items():
        el.set(k, v)


def _write_back(root: Any, model: Any, generated: bool) -> None:
    """Write the compiled model's options and contact values onto the document's elements.

    Raises:
        TippetopError: The document's geoms or pairs do not map one to one onto the model's
            (an ``<include>``, ``<replicate>`` or a composite made them elsewhere).
    """
    import mujoco

    from tippetop.mujoco_runner.settings import integrator_name

    opt = model.opt
    option = root.find("option")
    if option is None:
        import xml.etree.ElementTree as ET

        option = ET.Element("option")
        root.insert(0, option)
    _set(option, timestep=_fmt(opt.timestep), integrator=integrator_name(int(opt.integrator)),
         cone="pyramidal" if int(opt.cone) == int(mujoco.mjtCone.mjCONE_PYRAMIDAL)
         else "elliptic", impratio=_fmt(opt.impratio),
         noslip_iterations=str(int(opt.noslip_iterations)), gravity=_fmt(opt.gravity))
    geoms = _geom_elements(root)
    pairs = [p for c in root.findall("contact") for p in c.findall("pair")]
    if len(geoms) != model.ngeom or len(pairs) != model.npair:
        raise TippetopError(
            f"mjcf: expected a document whose <geom> and <pair> elements are the model's "
            f"({model.ngeom} geoms, {model.npair} pairs), got {len(geoms)} and {len(pairs)} "
            "(an <include>, <replicate> or composite makes others): it cannot be written back "
            "exactly")
    for g, el in enumerate(geoms):
        _set(el, contype=str(int(model.geom_contype[g])),
             conaffinity=str(int(model.geom_conaffinity[g])),
             condim=str(int(model.geom_condim[g])), friction=_fmt(model.geom_friction[g]),
             solref=_fmt(model.geom_solref[g]), solimp=_fmt(model.geom_solimp[g]))
    for p, el in enumerate(pairs):
        _set(el, condim=str(int(model.pair_dim[p])), friction=_fmt(model.pair_friction[p]),
             solref=_fmt(model.pair_solref[p]), solimp=_fmt(model.pair_solimp[p]))
    if generated:  # the harness's callback block: without the callback nothing reads it
        size = root.find("size")
        if size is not None:
            size.attrib.pop("nuserdata", None)
            if not size.attrib:
                root.remove(size)


def _keyframe_name(model: Any) -> str:
    import mujoco

    taken = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) for k in range(model.nkey)}
    name, i = KEYFRAME, 2
    while name in taken:
        name, i = f"{KEYFRAME}_{i}", i + 1
    return name


def _add_keyframe(root: Any, model: Any, data: Any, name: str) -> None:
    """The run's initial state as ``<key name=...>`` (every state the key can hold)."""
    import xml.etree.ElementTree as ET

    frames = root.findall("keyframe")
    parent = frames[-1] if frames else ET.SubElement(root, "keyframe")
    key = ET.SubElement(parent, "key", name=name, time=_fmt(data.time), qpos=_fmt(data.qpos),
                        qvel=_fmt(data.qvel))
    if model.na:
        key.set("act", _fmt(data.act))
    if model.nu:
        key.set("ctrl", _fmt(data.ctrl))
    if model.nmocap:
        key.set("mpos", _fmt(data.mocap_pos))
        key.set("mquat", _fmt(data.mocap_quat))


def _comment(text: str) -> str:
    """``text`` as an XML comment (``--`` is not allowed inside one)."""
    while "--" in text:
        text = text.replace("--", "- -")
    return f"<!--\n{text}\n-->\n"


def model_differences(run_model: Any, file_model: Any) -> list[str]:
    """The fields in which two compiled models differ (names, keyframes, userdata aside).

    Every array of ``MjModel``, every size and every option is compared exactly (NaN equal
    to NaN).
    """
    import numpy as np

    out = []
    for name in dir(run_model):
        if name.startswith("_") or name.startswith(_SKIP_PREFIXES) or name in _SKIP_SIZES:
            continue
        a = getattr(run_model, name)
        if isinstance(a, np.ndarray):
            b = getattr(file_model, name)
            if a.shape != b.shape or not np.array_equal(a, b, equal_nan=a.dtype.kind == "f"):
                out.append(name)
        elif isinstance(a, int) and not isinstance(a, bool):
            if a != getattr(file_model, name):
                out.append(name)
    for name in dir(run_model.opt):
        if name.startswith("_"):
            continue
        a, b = getattr(run_model.opt, name), getattr(file_model.opt, name)
        if isinstance(a, np.ndarray):
            same = np.array_equal(a, b)
        elif isinstance(a, (int, float)):
            same = a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))
        else:
            continue
        if not same:
            out.append(f"opt.{name}")
    return out


# ---------------------------------------------------------------- the command
def _header(scene: str, engine: str, plan: Any, run: dict[str, Any], key: str,
            key_index: int, note: str | None) -> str:
    from importlib import metadata

    import mujoco

    try:
        version = metadata.version("tippetop")
    except metadata.PackageNotFoundError:  # pragma: no cover - the package is installed
        version = "?"
    steps = round(plan.t_end_s / run["timestep_s"])
    lines = [
        f"Written by 'tippetop mjcf' (tippetop {version}, MuJoCo {mujoco.__version__}): "
        f"scene {scene}, {engine}, {plan.mode} mode.",
        "This is the model 'tippetop simulate' compiles and steps, every option and contact "
        "setting as it runs:",
        f"  {run['integrator']} at timestep {run['timestep_s']!r} s, {run['cone']} cone, "
        f"impratio {run['impratio']!r}, noslip_iterations {run['noslip_iterations']}, "
        f"condim {run['condim']}.",
        f"The run starts from keyframe '{key}' (index {key_index}: "
        f"mujoco.mj_resetDataKeyframe(m, d, {key_index})) and steps mj_step to "
        f"t = {plan.t_end_s!r} s ({steps} steps); tippetop samples every "
        f"{run['sample_dt_s']!r} s.",
    ]
    if note:
        lines += ["", "PAPER MODE: " + note]
    else:
        lines.append("Its friction is MuJoCo's own (native mode): stepping this file alone is "
                     "the run.")
    return _comment("\n".join(lines))


def _paper_note(plan: Any) -> str:
    law = plan.law
    if law is None:
        return ("the contacts are frictionless (condim 1) and this run applies no friction law "
                "(effects.sliding = false): stepping this file alone is the run.")
    extra = f", Lambda {law.Lambda_mps!r} m/s" if law.law in ("modified_coulomb",) else ""
    return (f"the contacts here are frictionless (condim 1); the paper's friction law "
            f"({law.law}, mu {law.mu!r}{extra}) is applied at the contact point by tippetop's "
            "compiled passive callback (mujoco.set_mjcb_passive), which no MJCF file can carry: "
            "stepping this file alone gives a frictionless top, not the run.")


def write_mjcf(scene_obj: Any, engine: str, out: Path) -> dict[str, Any]:
    """Write the run's model of ``scene_obj`` in ``engine`` to ``out``; what was written.

    Raises:
        TippetopError: ``engine`` is not a MuJoCo one, or the model cannot be written exactly.
    """
    import warnings

    import mujoco

    from tippetop.compare.running.engines import plan_for
    from tippetop.compare.running.io import write_atomic
    from tippetop.models.plan import mode_engine, sample_interval
    from tippetop.mujoco_runner.model import TopModelWarning, top_from_model
    from tippetop.mujoco_runner.run import run_grid
    from tippetop.mujoco_runner.settings import build_model, generated_mjcf, settings_that_ran
    from tippetop.mujoco_runner.state import initial_qpos_qvel

    if mode_engine(engine)[0] != "mujoco":
        raise TippetopError(f"--engine: expected mujoco or a mujoco-* mode, got {engine!r} "
                            "(the reference ODE has no MuJoCo model)")
    plan = plan_for(scene_obj, engine).mujoco
    assert plan is not None
    top_model = build_model(plan)  # the run's own model, every setting applied
    model = top_model.model
    sample_dt = sample_interval(plan.t_end_s, plan.requested_sample_dt_s,
                                float(model.opt.timestep))
    # what a run refuses (e.g. a timestep the paper's law cannot be followed with), so does
    # its file: the run's own checks
    run_grid(top_model, plan.law, mode=plan.mode, t_end_s=plan.t_end_s, sample_dt_s=sample_dt)
    if plan.mjcf is None:
        source = generated_mjcf(plan)
    else:
        source = Path(plan.mjcf).read_text(encoding="utf-8")
    root = _parse(source)
    _write_back(root, model, generated=plan.mjcf is None)

    # the run's initial state, set as the run sets it
    data = mujoco.MjData(model)
    if plan.keyframe is None:
        qa, va = top_model.qpos_adr, top_model.dof_adr
        data.qpos[qa:qa + 7], data.qvel[va:va + 6] = initial_qpos_qvel(top_model, plan.init)
    else:
        mujoco.mj_resetDataKeyframe(model, data, plan.keyframe)
    key = _keyframe_name(model)
    _add_keyframe(root, model, data, key)

    mujoco.mj_forward(model, data)
    ran = settings_that_ran(top_model, data)
    ran.pop("contact_source", None)
    ran["sample_dt_s"] = sample_dt
    note = _paper_note(plan) if plan.mode == "paper" else None
    key_index = model.nkey  # appended after the file's own keyframes
    import xml.etree.ElementTree as ET

    ET.indent(root, space="  ")
    text = (_header(scene_obj.name, engine, plan, ran, key, key_index, note)
            + ET.tostring(root, encoding="unicode") + "\n")

    def write(tmp: Path) -> None:
        tmp.write_text(text, encoding="utf-8")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", TopModelWarning)
                written = mujoco.MjModel.from_xml_path(str(tmp))
                top_from_model(written)
        except ValueError as exc:
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise TippetopError(f"mjcf: the file written does not compile where it is ({first}"
                                "); a file that refers to others (meshes, includes) by "
                                "relative paths must be written into its own folder") from None
        diff = model_differences(model, written)
        if diff:
            raise TippetopError(f"mjcf: expected the file to compile to the run's model, but "
                                f"it differs in {', '.join(diff[:6])}: not written")
        check = mujoco.MjData(written)
        mujoco.mj_resetDataKeyframe(written, check, written.nkey - 1)
        if not (check.qpos.tobytes() == data.qpos.tobytes()
                and check.qvel.tobytes() == data.qvel.tobytes()):
            raise TippetopError("mjcf: the keyframe written does not hold the run's initial "
                                "state exactly: not written")

    write_atomic(out, write)
    return {"out": str(out), "scene": scene_obj.name, "engine": engine, "mode": plan.mode,
            "source": "generated" if plan.mjcf is None else str(plan.mjcf),
            "keyframe": key, "keyframe_index": key_index, "t_end_s": plan.t_end_s,
            "friction_in_file": plan.mode == "native" or plan.law is None,
            "note": note, "ran": ran}


__all__ = ["KEYFRAME", "model_differences", "write_mjcf"]
