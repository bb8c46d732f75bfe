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
#: file has one more), paths and text (bookkeeping, never read by mj_step).
_SKIP_PREFIXES = ("name_", "names", "key_", "text_", "tex_pathadr", "mesh_pathadr",
                  "hfield_pathadr", "skin_pathadr", "signature")
#: Model sizes that may differ (the keyframe, the names, the harness's userdata block).
_SKIP_SIZES = ("nkey", "nnames", "nnames_map", "nuserdata", "npaths", "ntext", "ntextdata",
               "narena", "nbuffer", "signature")


def _keyframe_name(model: Any) -> str:
    import mujoco

    taken = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) for k in range(model.nkey)}
    name, i = KEYFRAME, 2
    while name in taken:
        name, i = f"{KEYFRAME}_{i}", i + 1
    return name


def _start_key(model: Any, data: Any) -> list[tuple[str, Any]]:
    """The attributes of a ``<key>`` that holds ``data``'s state (every state a key can hold)."""
    values: list[tuple[str, Any]] = [("time", data.time), ("qpos", data.qpos),
                                     ("qvel", data.qvel)]
    if model.na:
        values.append(("act", data.act))
    if model.nu:
        values.append(("ctrl", data.ctrl))
    if model.nmocap:
        values += [("mpos", data.mocap_pos), ("mquat", data.mocap_quat)]
    return values


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
def _header(scene: str, run_plan: Any, run: dict[str, Any], key: str,
            key_index: int, note: str | None) -> str:
    from importlib import metadata

    import mujoco

    try:
        version = metadata.version("tippetop")
    except metadata.PackageNotFoundError:  # pragma: no cover - the package is installed
        version = "?"
    plan = run_plan.mujoco
    steps = plan.n_steps
    lines = [
        f"Written by 'tippetop mjcf' (tippetop {version}, MuJoCo {mujoco.__version__}): "
        f"scene {scene}, engine {run_plan.engine}, mode {run_plan.mode}.",
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
    from tippetop.models.mjcf_document import comment

    return comment("\n".join(lines))


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


def write_mjcf(scene_obj: Any, engine: str, out: Path, mode: str | None = None
               ) -> dict[str, Any]:
    """Write the model of a run of ``scene_obj`` (on ``engine`` in ``mode``) to ``out``.

    Returns what was written (the ``tippetop mjcf --json`` keys).

    Raises:
        TippetopError: ``engine`` is not a MuJoCo one, or the model cannot be written exactly.
    """
    import warnings

    import mujoco

    from tippetop.compare.running.engines import plan_for
    from tippetop.compare.running.io import write_atomic
    from tippetop.models import mjcf_document
    from tippetop.mujoco_runner.model import TopModelWarning, top_from_model
    from tippetop.mujoco_runner.settings import build_model, settings_that_ran
    from tippetop.mujoco_runner.stepping import start_data

    # what a run refuses (e.g. a timestep the paper's law cannot be followed with), so does
    # its file: the plan refuses it
    run_plan = plan_for(scene_obj, engine, mode)
    if run_plan.mujoco is None:
        raise TippetopError(f"--engine: expected a MuJoCo engine, got {run_plan.engine!r} "
                            "(the reference ODE has no MuJoCo model)")
    plan = run_plan.mujoco
    top_model = build_model(plan)  # the run's own model: the plan's MJCF text
    model = top_model.model
    root = mjcf_document.parse(plan.mjcf)
    if plan.source is None:  # the harness's callback block: without the callback nothing reads it
        size = root.find("size")
        if size is not None:
            size.attrib.pop("nuserdata", None)
            if not size.attrib:
                root.remove(size)
    data = start_data(top_model, plan)  # the run's initial state, set as the run sets it
    key = _keyframe_name(model)
    mjcf_document.add_keyframe(root, key, _start_key(model, data))

    mujoco.mj_forward(model, data)
    ran = settings_that_ran(top_model, data)
    ran.pop("contact_source", None)
    ran["sample_dt_s"] = plan.sample_dt_s
    note = _paper_note(plan) if plan.friction == "paper" else None
    key_index = model.nkey  # appended after the file's own keyframes
    text = mjcf_document.to_text(root, _header(scene_obj.name, run_plan, ran, key, key_index,
                                               note))

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
    return {"out": str(out), "scene": scene_obj.name, "engine": run_plan.engine,
            "mode": run_plan.mode,
            "source": "generated" if plan.source is None else plan.source,
            "keyframe": key, "keyframe_index": key_index, "t_end_s": plan.t_end_s,
            "friction_in_file": plan.friction == "native" or plan.law is None,
            "note": note, "ran": ran}


__all__ = ["KEYFRAME", "model_differences", "write_mjcf"]
