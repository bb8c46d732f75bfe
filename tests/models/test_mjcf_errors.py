"""A broken MJCF document is named by its line and column (issue 29)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tippetop.models import mjcf_document
from tippetop.models.errors import TippetopError

DOC = '<mujoco model="top">\n  <option timestep="0.0002"/>\n  <worldbody/>\n</mujoco>\n'


@pytest.mark.parametrize(("data", "says"), [
    (DOC.encode(), None),
    (b"\xef\xbb\xbf" + DOC.encode(), None),  # a byte-order mark
    (b"", "an empty file"),
    (b" \n\t\n", "an empty file"),
    (b"<mujoco>\x00</mujoco>", "binary data (a NUL byte at line 1, column 9)"),
    (DOC.encode("utf-16"), "UTF-16 text (MuJoCo reads UTF-8: save it as UTF-8)"),
    (DOC.replace("top", "caf\u00e9").encode("latin-1"),
     "a byte that is not UTF-8 (0xE9) at line 1, column 19"),
])
def test_text_problem(data: bytes, says: str | None) -> None:
    assert mjcf_document.text_problem(data) == says


@pytest.mark.parametrize(("text", "says"), [
    (DOC, None),
    (DOC[:30], "an XML error at line 2, column 3: unclosed token"),
    (DOC.replace("<worldbody/>", "<worldbody>"),
     "an XML error at line 4, column 3: mismatched tag"),
    (DOC.replace('"top"', '"a & b"'),  # the parser stops at the space after the '&'
     "an XML error at line 1, column 19: not well-formed (invalid token)"),
    ("<mujoco><!-- MuJoCo takes -- in a comment --></mujoco>", None),
    ("", "an empty file"),
])
def test_xml_problem(text: str, says: str | None) -> None:
    assert mjcf_document.xml_problem(text.encode()) == says


def test_parse_names_the_source_line_and_column() -> None:
    with pytest.raises(TippetopError) as info:
        mjcf_document.parse(DOC[:30], "/tmp/top.xml")
    assert str(info.value) == ("/tmp/top.xml: expected a well-formed XML document, got an XML "
                               "error at line 2, column 3: unclosed token")


def test_read_text(tmp_path: Path) -> None:
    f = tmp_path / "top.xml"
    f.write_bytes(b"\xef\xbb\xbf" + DOC.encode())
    assert mjcf_document.read_text(f) == DOC
    f.write_bytes(DOC.replace("top", "caf\u00e9").encode("latin-1"))
    with pytest.raises(TippetopError) as info:
        mjcf_document.read_text(f)
    assert str(info.value) == (f"{f}: expected an MJCF (XML) text file in UTF-8, got a byte "
                               "that is not UTF-8 (0xE9) at line 1, column 19")


def test_an_included_file_that_is_not_utf8_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "part.xml").write_bytes("<mujoco><!-- caf\u00e9 --></mujoco>".encode("latin-1"))
    root = mjcf_document.parse('<mujoco><include file="part.xml"/></mujoco>')
    with pytest.raises(TippetopError, match=r"part\.xml: expected an MJCF \(XML\) text file in "
                       r"UTF-8, got a byte that is not UTF-8 \(0xE9\) at line 1, column 17$"):
        mjcf_document.inline_includes(root, tmp_path)
