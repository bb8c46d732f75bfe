"""An MJCF document as text: its elements in MuJoCo's order, and values written into them.

A run plan carries the MJCF text that will be compiled (:class:`~tippetop.models.plan.
MujocoPlan`): for a loaded file, the file's own document with the plan's options and contact
settings written into its elements (numbers at full precision: ``repr`` parses back to the same
double), its ``<include>`` elements inlined and its asset folders made absolute, so that any
process can compile it from the text alone.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tippetop.models.errors import TippetopError

#: The attributes of ``<compiler>`` that name folders of asset files.
_ASSET_DIRS = ("assetdir", "meshdir", "texturedir")
#: Elements whose ``file`` attribute names an asset file.
_ASSET_TAGS = ("mesh", "texture", "hfield", "skin")


def fmt(values: Any) -> str:
    """Numbers (one, a sequence or an array) as MJCF text: ``repr``, the same doubles back."""
    return " ".join(repr(float(v)) for v in np.ravel(np.asarray(values, dtype=float)))


def _lax_comments(text: str) -> str:
    """``text`` with ``--`` inside comments made ``- -``: MuJoCo's parser takes it, XML not."""
    return re.sub(r"<!--(.*?)-->", lambda m: "<!--" + m.group(1).replace("--", "- -") + "-->",
                  text, flags=re.DOTALL)


def parse(text: str, source: str = "mjcf") -> ET.Element:
    """The document's element tree, its comments kept.

    Args:
        text: The document.
        source: What to call it in an error: its file, or ``mjcf``.

    Raises:
        TippetopError: The text is not XML (one line: where, and Python's parser's reason).
    """
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    try:
        return ET.fromstring(_lax_comments(text), parser=parser)
    except ET.ParseError as exc:
        raise TippetopError(f"{source}: expected a well-formed XML document, got "
                            f"{xml_error(exc)}") from None


def xml_error(exc: ET.ParseError) -> str:
    """Python's XML parser's error as ``an XML error at line L, column C: REASON``.

    The column counts from 1, as editors do (the parser's own counts from 0).
    """
    line, column = exc.position
    reason = re.sub(r": line \d+, column \d+$", "", str(exc))
    return f"an XML error at line {line}, column {column + 1}: {reason}"


def text_problem(data: bytes) -> str | None:
    """What makes ``data`` no XML text at all: empty, binary, not UTF-8; None: it is text.

    Returns:
        ``an empty file``, ``UTF-16 text``, ``binary data (a NUL byte at line L, column C)``
        or ``a byte that is not UTF-8 (0xE9) at line L, column C``; a UTF-8 byte-order mark is
        fine.
    """
    if not data.strip():
        return "an empty file"
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "UTF-16 text (MuJoCo reads UTF-8: save it as UTF-8)"
    if b"\0" in data:
        line, column = _position(data, data.index(b"\0"))
        return f"binary data (a NUL byte at line {line}, column {column})"
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, column = _position(data, exc.start)
        return (f"a byte that is not UTF-8 (0x{data[exc.start]:02X}) at line {line}, column "
                f"{column}")
    return None


def _position(data: bytes, offset: int) -> tuple[int, int]:
    """(line, column) of byte ``offset`` in ``data``, both from 1 (the column in bytes)."""
    start = data.rfind(b"\n", 0, offset) + 1
    return data.count(b"\n", 0, offset) + 1, offset - start + 1


def xml_problem(data: bytes) -> str | None:
    """What Python's XML parser finds wrong with a document; None if it reads it.

    Returns:
        :func:`text_problem`'s answer, or :func:`xml_error`'s.
    """
    problem = text_problem(data)
    if problem is not None:
        return problem
    try:
        ET.fromstring(_lax_comments(data.decode("utf-8-sig")))
    except ET.ParseError as exc:
        return xml_error(exc)
    return None


def read_text(path: str | os.PathLike[str]) -> str:
    """An MJCF file's text, read as UTF-8 (a byte-order mark dropped).

    Raises:
        TippetopError: The file is empty, binary or not UTF-8 (one line: the file, and where).
        OSError: It cannot be read.
    """
    data = Path(path).read_bytes()
    problem = text_problem(data)
    if problem is not None:
        raise TippetopError(f"{os.fspath(path)}: expected an MJCF (XML) text file in UTF-8, "
                            f"got {problem}")
    return data.decode("utf-8-sig")


def to_text(root: ET.Element, header: str = "") -> str:
    """The document as text, indented, after ``header`` (a comment, or nothing)."""
    ET.indent(root, space="  ")
    return header + ET.tostring(root, encoding="unicode") + "\n"


def comment(text: str) -> str:
    """``text`` as an XML comment on lines of its own (``--`` is not allowed inside one)."""
    while "--" in text:
        text = text.replace("--", "- -")
    return f"<!--\n{text}\n-->\n"


def _children(el: ET.Element, tag: str) -> list[ET.Element]:
    """``el``'s ``tag`` children, also those inside ``<frame>`` elements, in order."""
    out = []
    for child in el:
        if child.tag == tag:
            out.append(child)
        elif child.tag == "frame":
            out.extend(_children(child, tag))
    return out


def body_elements(root: ET.Element) -> list[list[ET.Element]]:
    """The bodies in MuJoCo's body order (depth first), each as the elements that make it.

    The world body is every ``<worldbody>`` element of the document (an included file adds
    one), in order; every other body is one ``<body>`` element.
    """
    out: list[list[ET.Element]] = []

    def walk(els: list[ET.Element]) -> None:
        out.append(els)
        for el in els:
            for child in _children(el, "body"):
                walk([child])

    walk(root.findall("worldbody"))
    return out


def geom_elements(root: ET.Element) -> list[ET.Element]:
    """Every ``<geom>`` element in MuJoCo's geom order (by body, then as written)."""
    return [g for body in body_elements(root) for el in body for g in _children(el, "geom")]


def pair_elements(root: ET.Element) -> list[ET.Element]:
    """Every ``<contact><pair>`` element, in MuJoCo's pair order."""
    return [p for c in root.findall("contact") for p in c.findall("pair")]


def add_pairs(root: ET.Element, pairs: Sequence[tuple[int, int, Mapping[str, str]]]) -> None:
    """Append contact pairs after the document's own: (geom id, geom id, attributes) each.

    A geom a pair names gets a name (``tippetop_geom_ID``) where the document gives it none:
    a ``<pair>`` refers to its geoms by name.
    """
    if not pairs:
        return
    geoms = geom_elements(root)

    def named(i: int) -> str:
        el = geoms[i]
        if not el.get("name"):
            el.set("name", f"tippetop_geom_{i}")
        return str(el.get("name"))

    contacts = root.findall("contact")
    contact = contacts[-1] if contacts else ET.SubElement(root, "contact")
    for g1, g2, attrs in pairs:
        ET.SubElement(contact, "pair", {"geom1": named(g1), "geom2": named(g2), **attrs})


def inline_includes(root: ET.Element, folder: Path) -> None:
    """Replace every ``<include file=...>`` by the children of the file's ``<mujoco>`` root.

    MuJoCo's own rule; a relative name is relative to ``folder`` (the including file's). The
    included files' own includes are inlined too.

    Raises:
        TippetopError: An included file is missing or not MJCF.
    """
    for parent in list(root.iter()):
        for i, child in reversed(list(enumerate(list(parent)))):
            if child.tag != "include":
                continue
            name = child.get("file", "")
            path = Path(name) if os.path.isabs(name) else folder / name
            try:
                sub = parse(read_text(path), str(path))
            except OSError as exc:
                raise TippetopError(f"mjcf: expected the included file {str(path)!r}, got "
                                    f"{type(exc).__name__}: {exc.strerror}") from None
            inline_includes(sub, path.parent)
            parent.remove(child)
            for j, el in enumerate(list(sub)):
                parent.insert(i + j, el)


def absolute_asset_dirs(root: ET.Element, folder: Path) -> None:
    """Make the document's asset files resolve from ``folder`` wherever it is compiled.

    MuJoCo looks for an asset file (a mesh, a texture, ...) named by a relative path in the
    model file's folder joined with ``meshdir``/``texturedir``/``assetdir``. Compiled from
    text there is no model file: each of those attributes that is relative is joined to
    ``folder``, and ``assetdir`` is set to ``folder`` where it is missing. A document that
    names no asset file is left as it is.
    """
    if not any(el.get("file") for tag in _ASSET_TAGS for el in root.iter(tag)):
        return
    compiler = root.find("compiler")
    if compiler is None:
        compiler = ET.Element("compiler")
        root.insert(0, compiler)
    for key in _ASSET_DIRS:
        value = compiler.get(key)
        if value is not None and not os.path.isabs(value):
            compiler.set(key, str(folder / value))
    if compiler.get("assetdir") is None:
        compiler.set("assetdir", str(folder))


def set_attributes(el: ET.Element, values: Mapping[str, str]) -> None:
    """Set ``values`` (attribute -> text) on one element."""
    for key, value in values.items():
        el.set(key, value)


def write_flag(root: ET.Element, flag: str, value: str) -> None:
    """Set ``<option><flag flag="value"/>`` (the option and flag elements made if missing)."""
    el = root.find("option")
    if el is None:
        el = ET.Element("option")
        root.insert(0, el)
    flag_el = el.find("flag")
    if flag_el is None:
        flag_el = ET.SubElement(el, "flag")
    flag_el.set(flag, value)


def write_values(root: ET.Element, *, option: Mapping[str, str],
                 geoms: Mapping[int, Mapping[str, str]], pairs: Mapping[int, Mapping[str, str]],
                 ngeom: int, npair: int) -> None:
    """Write option attributes and per-geom and per-pair attributes into the document.

    Args:
        root: The document.
        option: Attributes of ``<option>`` (made if missing).
        geoms: Geom id -> attributes, ids in MuJoCo's geom order.
        pairs: Pair id -> attributes.
        ngeom: The model's geom count (the document's ``<geom>`` elements must be as many).
        npair: Its pair count.

    Raises:
        TippetopError: The document's geoms or pairs do not map one to one onto the model's (a
            ``<replicate>`` or a composite makes some elsewhere).
    """
    el = root.find("option")
    if el is None:
        el = ET.Element("option")
        root.insert(0, el)
    set_attributes(el, option)
    geom_els, pair_els = geom_elements(root), pair_elements(root)
    if len(geom_els) != ngeom or len(pair_els) != npair:
        raise TippetopError(
            f"mjcf: expected a document whose <geom> and <pair> elements are the model's "
            f"({ngeom} geoms, {npair} pairs), got {len(geom_els)} and {len(pair_els)} (a "
            "<replicate> or composite makes others): its settings cannot be written exactly")
    for i, values in geoms.items():
        set_attributes(geom_els[i], values)
    for i, values in pairs.items():
        set_attributes(pair_els[i], values)


def add_keyframe(root: ET.Element, name: str, values: Iterable[tuple[str, Any]]) -> None:
    """Append ``<key name=...>`` with ``values`` ((attribute, numbers) pairs) to the document."""
    frames = root.findall("keyframe")
    parent = frames[-1] if frames else ET.SubElement(root, "keyframe")
    key = ET.SubElement(parent, "key", name=name)
    for attr, numbers in values:
        key.set(attr, fmt(numbers))


__all__ = ["absolute_asset_dirs", "add_keyframe", "body_elements", "comment", "fmt",
           "geom_elements", "inline_includes", "pair_elements", "parse", "read_text",
           "set_attributes", "text_problem", "to_text", "write_values", "xml_error",
           "xml_problem"]
