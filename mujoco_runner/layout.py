"""Byte offsets of the mjModel / mjData fields the paper-mode callback reads.

The Python bindings give the arrays but not where the struct keeps their pointers; a compiled
callback that is handed ``mjModel*`` / ``mjData*`` needs those offsets. :func:`struct_layout`
finds them once per process by scanning probe structs (see there) and fails loudly
(:class:`StructLayoutError`) if anything is ambiguous, rather than guessing.
"""

from __future__ import annotations

import ctypes
import functools
import mmap
import sys
from dataclasses import dataclass

import mujoco
import numpy as np


class StructLayoutError(RuntimeError):
    """The mjModel/mjData field offsets could not be found unambiguously in this MuJoCo."""



@dataclass(frozen=True)
class StructLayout:
    """Byte offsets of the fields the callback reads, in MuJoCo's ``mjModel`` and ``mjData``.

    Attributes:
        qpos: ``mjData.qpos`` (a ``mjtNum*``).
        qvel: ``mjData.qvel``.
        userdata: ``mjData.userdata``.
        qfrc_passive: ``mjData.qfrc_passive``.
        qfrc_constraint: ``mjData.qfrc_constraint``.
        nuserdata: ``mjModel.nuserdata`` (an integer of ``nuserdata_width`` bytes).
        nuserdata_width: 8 (``mjtSize``, MuJoCo >= 3.3) or 4 (``int``).
    """

    qpos: int
    qvel: int
    userdata: int
    qfrc_passive: int
    qfrc_constraint: int
    nuserdata: int
    nuserdata_width: int


#: mjData pointer fields the callback reads, in their declaration order in mjdata.h.
_DATA_FIELDS = ("qpos", "qvel", "userdata", "qfrc_passive", "qfrc_constraint")
# Probe models. The data probe has an actuator with activation dynamics so that no zero-sized
# array sits in front of userdata (act_dot, na) in mjData's buffer: a zero-sized array shares
# the address of the next one, and would make userdata's value appear twice. Its ball touches
# the plane, so that the constraint arrays (the last pointer fields) are allocated and the scan
# reaches the end of the struct. Two probes with different sizes must give the same offsets.
_DATA_PROBE_XML = """<mujoco><size nuserdata="{nuserdata}"/>
  <worldbody><geom type="plane" size="1 1 0.1"/>
    <body pos="0 0 0.09"><freejoint/><geom size="0.1"/></body>
    <body pos="1 0 0"><joint name="hinge" type="hinge"/><geom size="0.1"/>{extra}</body>
  </worldbody>
  <actuator><general joint="hinge" dyntype="filter" dynprm="1"/></actuator>
  <sensor><jointpos joint="hinge"/></sensor></mujoco>"""
_DATA_PROBES = (dict(nuserdata=3, extra=""),
                dict(nuserdata=7, extra='<body pos="0 1 0"><joint/><geom size="0.1"/></body>'))
# Two model probes that differ only in nuserdata (values unlike any other size of the probe).
_MODEL_PROBE_XML = ('<mujoco><size nuserdata="{}"/><worldbody><body><freejoint/>'
                    '<geom size="0.1"/></body></worldbody></mujoco>')
_MODEL_PROBE_NUSERDATA = (1013, 2029)
# The introspected C types of mjModel.nuserdata that this module knows the width of.
_INT_WIDTHS = {"int": 4, "int32_t": 4, "mjtSize": 8, "int64_t": 8}


def _words(address: int, start: int, stop: int) -> np.ndarray:
    """The uint64 words at ``address + [start, stop)`` (a copy)."""
    return np.frombuffer(ctypes.string_at(address + start, stop - start), dtype=np.uint64).copy()


def _data_words(data: mujoco.MjData, known: np.ndarray) -> np.ndarray:
    """The words of ``data``'s struct, up to its ``signature`` field, never past a mapped page.

    The head of the struct (sizes and statistics, up to the inline ``energy`` array) lies in
    it by construction. Past it MuJoCo declares the pointer fields, and ``signature`` last; each
    of the ``known`` array addresses of ``data`` is stored in one of them, so the struct
    reaches at least 8 bytes per known address past the head, and past every word found to
    hold one. Memory is read a page at a time, and a page only if a byte known to be in the
    struct lies in it, so the scan cannot fault; if the signature lies beyond, the words up to
    the last known one are returned.
    """
    address, page = data._address, mmap.PAGESIZE
    if address % 8:  # pragma: no cover - MuJoCo aligns its allocations
        raise StructLayoutError("scanning mjData: the struct is not 8-byte aligned")
    head = data.energy.ctypes.data + data.energy.nbytes - address
    known = known[(known < address) | (known >= address + head)]  # not the head's own arrays
    signature = np.uint64(data.signature)
    # Bytes [0, reach) are known to be in the struct.
    chunks, pos, reach = [], 0, head + 8 * known.size
    while True:
        stop = ((address + reach - 1) // page + 1) * page - address
        if stop <= pos:  # no signature where the scan may read: stop at the known extent
            return np.concatenate(chunks)[:reach // 8]
        chunk = _words(address, pos, stop)
        offsets = pos + 8 * np.arange(chunk.size)
        end = np.flatnonzero((chunk == signature) & (offsets >= head))
        if end.size:
            chunks.append(chunk[:end[0] + 1])
            return np.concatenate(chunks)
        chunks.append(chunk)
        pointers = offsets[np.isin(chunk, known)]
        if pointers.size:
            reach = max(reach, int(pointers[-1]) + 8)
        pos = stop


def _data_offsets(data: mujoco.MjData) -> tuple[int, ...]:
    """Offsets of :data:`_DATA_FIELDS` in mjData, from one probe ``data``."""
    known = set()
    for name in dir(data):
        value = getattr(data, name, None) if not name.startswith("_") else None
        if isinstance(value, np.ndarray) and value.size:
            known.add(value.ctypes.data)
    words = _data_words(data, np.array(sorted(known), dtype=np.uint64))
    offsets = []
    for name in _DATA_FIELDS:
        value = np.uint64(getattr(data, name).ctypes.data)
        hits = [8 * int(i) for i in np.flatnonzero(words == value)]
        # mjData.buffer points at the start of the main buffer, which is qpos (its first
        # array): that value is expected in two fields, buffer and then qpos.
        expected = (1, 2) if name == "qpos" else (1,)
        if len(hits) not in expected:
            raise StructLayoutError(
                f"scanning mjData: the address of {name} is stored in {len(hits)} fields "
                f"(offsets {hits}), expected {' or '.join(map(str, expected))}: cannot tell "
                f"which one is mjData.{name}")
        offsets.append(hits[-1])
    if offsets != sorted(set(offsets)):
        raise StructLayoutError(
            f"scanning mjData: fields {_DATA_FIELDS} found at offsets {offsets}, not in their "
            "declaration order")
    return tuple(offsets)


def _declared_width(struct: str, field: str) -> int | None:
    """Byte width of an integer field as MuJoCo's introspection declares it, or None."""
    try:
        from mujoco.introspect import structs
    except ImportError:  # pragma: no cover - shipped with the bindings
        return None
    for f in structs.STRUCTS[struct].fields:
        if f.name == field:
            return _INT_WIDTHS.get(getattr(f.type, "name", None))
    return None  # pragma: no cover


def _nuserdata_offset() -> tuple[int, int]:
    """(offset, width) of mjModel.nuserdata, by diffing two probe models' size fields."""
    a, b = (mujoco.MjModel.from_xml_string(_MODEL_PROBE_XML.format(n))
            for n in _MODEL_PROBE_NUSERDATA)
    # The sizes come first in mjModel, before the inline mjOption: read only that head.
    head = min(m.opt.gravity.ctypes.data - m._address for m in (a, b)) // 8 * 8
    raw_a = np.frombuffer(ctypes.string_at(a._address, head), dtype=np.uint8)
    raw_b = np.frombuffer(ctypes.string_at(b._address, head), dtype=np.uint8)
    changed = np.flatnonzero(raw_a != raw_b)
    declared = _declared_width("mjModel", "nuserdata")
    hits: list[tuple[int, int]] = []
    for width in (declared,) if declared else (8, 4):
        dtype = np.int64 if width == 8 else np.int32
        at = np.flatnonzero((raw_a.view(dtype) == _MODEL_PROBE_NUSERDATA[0])
                            & (raw_b.view(dtype) == _MODEL_PROBE_NUSERDATA[1]))
        hits += [(width * int(i), width) for i in at]
        if hits:
            break
    if len(hits) != 1:
        raise StructLayoutError(
            "diffing two probe mjModels: nuserdata's values found at "
            f"{len(hits)} places ({hits}), expected 1")
    offset, width = hits[0]
    if not changed.size or changed.min() < offset or changed.max() >= offset + width:
        raise StructLayoutError(
            "diffing two probe mjModels that differ only in nuserdata: bytes "
            f"{changed.tolist()} differ, expected those of one {width}-byte integer at {offset}")
    return offset, width


@functools.cache
def struct_layout() -> StructLayout:
    """The field offsets the callback reads, found once per process.

    mjData: two probe ``MjData`` (of probe models with different sizes) are scanned as words,
    from ``data._address`` to their last field, for the addresses the bindings give for
    ``qpos``, ``qvel``, ``userdata``, ``qfrc_passive`` and ``qfrc_constraint``
    (``arr.ctypes.data``). Each must be stored in exactly one field (qpos: also in
    ``mjData.buffer``, which points at it), in that declaration order, at the same offset in
    both probes. mjModel: two probe models that differ only in ``<size nuserdata>`` are diffed
    over their size fields; exactly the bytes of one integer must differ, holding the two
    values, with the width MuJoCo's introspection declares for ``nuserdata``.

    Raises:
        StructLayoutError: If a scan is ambiguous or inconsistent (another MuJoCo layout).
    """
    if sys.byteorder != "little":  # pragma: no cover
        raise StructLayoutError("the callback's struct scan assumes a little-endian machine")
    found = set()
    for probe in _DATA_PROBES:
        model = mujoco.MjModel.from_xml_string(_DATA_PROBE_XML.format(**probe))
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        found.add(_data_offsets(data))
    if len(found) != 1:
        raise StructLayoutError(f"scanning mjData: the probes disagree: {sorted(found)}")
    offset, width = _nuserdata_offset()
    return StructLayout(*found.pop(), nuserdata=offset, nuserdata_width=width)


__all__ = ["StructLayout", "StructLayoutError", "struct_layout"]
