"""The stored baselines: one JSON file per profile, changed only by ``--update-baseline``."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tippetop.compare.nightly.catalogue import migrate_case_id
from tippetop.compare.nightly.outputs import timestamp
from tippetop.compare.running.io import json_ready, write_atomic
from tippetop.models.errors import TippetopError
from tippetop.models.resources import data_path

#: Where the baselines live in the repository (one JSON file per profile).
BASELINE_DIR = data_path("tippetop.compare", "baselines")
#: The format written (2: case ids name the engine and the mode apart, ``[ENGINE/MODE]``).
BASELINE_FORMAT = "tippetop-nightly-baseline/2"
#: The formats read: the first one's case ids are migrated (:func:`migrate_case_id`).
READ_FORMATS = ("tippetop-nightly-baseline/1", BASELINE_FORMAT)


def baseline_file(directory: Path, profile: str) -> Path:
    """``DIR/<profile>.json``."""
    return directory / f"{profile}.json"


def load_baseline(path: Path, *, missing_ok: bool = False) -> dict[str, dict[str, Any]]:
    """Case id -> metric -> baseline value.

    Args:
        path: The baseline file (``DIR/<profile>.json``).
        missing_ok: A missing file is an empty baseline (``--update-baseline`` creates it);
            otherwise it is bad input.

    Raises:
        TippetopError: The file is missing (unless ``missing_ok``), unreadable, or not a
            baseline.
    """
    if not path.is_file():
        if missing_ok:
            return {}
        raise TippetopError(f"--baseline: expected a baseline file {str(path)!r} (or "
                            f"--no-baseline to run with none, --update-baseline to create "
                            f"it), got none")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, OSError) as exc:
        raise TippetopError(f"--baseline: expected a readable JSON baseline at {str(path)!r}, "
                            f"got: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get("cases"), dict):
        raise TippetopError(f"--baseline: expected a baseline file with a 'cases' object, got "
                            f"{str(path)!r} without one")
    fmt = data.get("format", READ_FORMATS[0])
    if fmt not in READ_FORMATS:
        raise TippetopError(f"--baseline: expected a baseline of format "
                            f"{' or '.join(READ_FORMATS)}, got {fmt!r} in {str(path)!r}")
    cases = {migrate_case_id(k): v for k, v in data["cases"].items()}
    for case_id, entry in cases.items():
        _check_entry(path, case_id, entry)
    return cases


def _number(v: Any) -> bool:
    return v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))


def _check_entry(path: Path, case_id: str, entry: Any) -> None:
    """A case's entry: metric -> value, a number where its tolerance compares numbers.

    Checked as the file is read, so that a hand-edited entry of the wrong type is one line
    and exit 2 before any run, not a traceback after them.
    """
    from tippetop.compare.measures.tolerances import TOLERANCES

    where = f"--baseline {str(path)!r}, case {case_id!r}"
    if not isinstance(entry, dict):
        raise TippetopError(f"{where}: expected an object of metric values, got "
                            f"{type(entry).__name__} {json.dumps(entry)[:60]}")
    for metric, v in entry.items():
        tol = TOLERANCES.get(metric)
        if tol is None or tol.kind == "exact":
            continue
        values = v.values() if isinstance(v, dict) else [v]
        bad = next((x for x in values if not _number(x)), None)
        if bad is not None or isinstance(v, list):
            shown = json.dumps(bad if bad is not None else v)[:60]
            raise TippetopError(f"{where}: expected a number (or null) for {metric!r}, got "
                                f"{shown}")


#: A native case's baseline entry says which calibration its values ran with under this key
#: (:func:`tippetop.models.calibrated.calibration_label`); it is not a metric.
CALIBRATION_KEY = "calibration"


def uses_calibration(case_id: str) -> bool:
    """Whether a case runs MuJoCo's native contact with the calibrated settings.

    Its id ends ``[ENGINE/MODE]`` with a MuJoCo engine and a ``native`` mode.
    """
    inside = case_id.rpartition("[")[2].rstrip("]")
    engine, _, mode = inside.partition("/")
    return engine != "ode" and mode.startswith("native")


def baseline_calibrations(baseline: dict[str, dict[str, Any]]) -> dict[str, str]:
    """Case id -> the calibration its stored values ran with, for every native case.

    A native case stored before baselines said it reads ``unrecorded``.
    """
    return {k: str(v.get(CALIBRATION_KEY) or "unrecorded") for k, v in baseline.items()
            if uses_calibration(k)}


#: A model case's baseline entry records the content hash of the model file its values ran
#: with (:func:`tippetop.compare.nightly.catalogue.model_hash`), the file as given, and where
#: the case came from (``catalogue`` or ``--models``) under these keys; they are not metrics.
MODEL_HASH_KEY = "model_sha256"
MODEL_FILE_KEY = "model_file"
MODEL_ORIGIN_KEY = "model_origin"


def model_file_changes(records: Sequence[dict[str, Any]],
                       baseline: dict[str, dict[str, Any]]) -> dict[str, str]:
    """Said, not compared: the model cases whose file changed since their baseline.

    A model case's record (``model`` from :func:`tippetop.compare.nightly.running.run_cases`)
    gains ``baseline_sha256`` and ``changed``. When its file's hash differs from the one its
    baseline entry records, each compared check becomes ``new`` (its value and the stored
    one both kept) with a message that says so, and the case's status follows: the values of
    another file are neither a regression nor a pass. An entry that records no hash (written
    by hand) is compared as it is.

    Returns:
        Case id -> one line saying what changed, for each such case.
    """
    from tippetop.compare.measures.tolerances import format_value
    from tippetop.compare.nightly.checks import case_status

    out: dict[str, str] = {}
    for rec in records:
        model = rec.get("model")
        if not model:
            continue
        entry = baseline.get(rec["id"]) or {}
        stored = entry.get(MODEL_HASH_KEY)
        model["baseline_sha256"] = stored
        model["changed"] = bool(stored) and stored != model["sha256"]
        if not model["changed"]:
            continue
        why = (f"the model file changed since its baseline ({model['given']}: sha256 "
               f"{str(stored)[:12]} in the baseline, {model['sha256'][:12]} now)")
        out[rec["id"]] = why
        for ch in rec["checks"]:
            if ch["status"] in ("pass", "fail"):
                unit = ch["tolerance"].get("unit", "")
                ch.update(status="new", message=(
                    f"{ch['metric']}: {format_value(ch['value'], unit)}, baseline "
                    f"{format_value(ch['baseline'], unit)}, not compared: {why}; "
                    f"--update-baseline stores this run's"))
        rec["status"] = case_status(rec["checks"])
    return out


def update_baseline(path: Path, profile: str, records: Sequence[dict[str, Any]],
                    profile_ids: set[str], environment: dict[str, Any]) -> dict[str, int]:
    """Write the baselines of the cases that ran, atomically.

    Cases that did not run this time (filtered out by ``--engines``/``--cases``, or failed)
    keep their stored values; ids no longer in the profile are dropped, except those
    ``nightly --models`` added (kept until a run of that file writes them again). A model
    case's entry also records its file's hash (:data:`MODEL_HASH_KEY`).

    Returns:
        Counts: ``written`` (cases whose values were stored), ``added`` (new ids), ``dropped``
        and ``kept``.
    """
    old = load_baseline(path, missing_ok=True)
    cases = {k: v for k, v in old.items()
             if k in profile_ids or v.get(MODEL_ORIGIN_KEY) == "--models"}
    written = added = 0
    for rec in records:
        if rec["error"] is not None:
            continue
        added += rec["id"] not in cases
        cases[rec["id"]] = {m: rec["values"].get(m) for m in rec["metrics"]}
        if uses_calibration(rec["id"]) and environment.get("calibration"):
            # which calibrated settings the native case's values were made with
            cases[rec["id"]][CALIBRATION_KEY] = environment["calibration"]
        if rec.get("model"):  # which file, with which content, the values ran with
            cases[rec["id"]].update({MODEL_HASH_KEY: rec["model"]["sha256"],
                                     MODEL_FILE_KEY: rec["model"]["given"],
                                     MODEL_ORIGIN_KEY: rec["model"]["origin"]})
        written += 1
    doc = {
        "format": BASELINE_FORMAT,
        "profile": profile,
        "updated": timestamp(),
        "note": "written by 'tippetop nightly --update-baseline'; never edit by hand except to "
                "test the regression check",
        "environment": environment,
        "cases": dict(sorted(cases.items())),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(json_ready(doc), indent=1, sort_keys=False) + "\n"
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return {"written": written, "added": added, "dropped": len(set(old) - set(cases)),
            "kept": len(cases) - written}
