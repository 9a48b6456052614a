"""STL reader (ASCII and binary) with the checks a user needs when a file is broken.

Written here rather than taken from trimesh because the checks are the point: a truncated binary file, a
binary file whose 80-byte header starts with ``solid``, several ``solid`` blocks, CRLF line ends, and a bad
number must each give a one-line message that names the file and the place.
"""

from __future__ import annotations

import re

import numpy as np

from sprayplan.errors import PartFileError

BINARY_HEADER_BYTES = 80
BINARY_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])  # 50 bytes a facet
# Every facet of a solid block: exactly three vertices, keywords in any case, any whitespace between tokens;
# the nine vertex coordinates are captured.
_FACET = (
    rb"(?<!\S)facet\s+normal\s+\S+\s+\S+\s+\S+\s+outer\s+loop"
    rb"\s+vertex\s+(\S+)\s+(\S+)\s+(\S+)\s+vertex\s+(\S+)\s+(\S+)\s+(\S+)\s+vertex\s+(\S+)\s+(\S+)\s+(\S+)"
    rb"\s+endloop\s+endfacet(?!\S)"
)
_FACET_SPLIT = re.compile(_FACET, re.IGNORECASE)
_BODY = re.compile(rb"(?:\s*" + _FACET + rb")*\s*", re.IGNORECASE)
_VERTEX = re.compile(rb"\bvertex\s+(\S+)\s+(\S+)\s+(\S+)", re.IGNORECASE)
_FACET_TOKENS = (
    [b"facet", b"normal", None, None, None, b"outer", b"loop"]
    + [b"vertex", None, None, None] * 3
    + [
        b"endloop",
        b"endfacet",
    ]
)


def parse_stl(data: bytes, path: str = "<bytes>") -> np.ndarray:
    """Parse the bytes of an STL file into triangles.

    Parameters
    ----------
    data : bytes
        The whole file.
    path : str
        The file's name, used in error messages only.

    Returns
    -------
    triangles : (m, 3, 3) float64
        Vertex coordinates of each facet in the file's units. The normals stored in the file are not used:
        they are recomputed from the winding, which is what CAD systems also trust.

    Raises
    ------
    PartFileError
        Empty file, truncated binary file, ASCII facets without exactly three vertices, a value that is not a
        number, or a NaN/infinite coordinate.
    """
    if len(data) == 0:
        raise PartFileError(path, "file is empty")
    if len(data) >= BINARY_HEADER_BYTES + 4:
        count = int(np.frombuffer(data, "<u4", count=1, offset=BINARY_HEADER_BYTES)[0])
        expected = BINARY_HEADER_BYTES + 4 + BINARY_RECORD.itemsize * count
        # A binary file is recognised by its size, whatever its header says: many exporters write "solid" there.
        if len(data) == expected:
            return _binary(data, count, path)
    else:
        count, expected = None, None
    if data.lstrip()[:5].lower() == b"solid":
        return _ascii(data, path)
    if count is None:
        raise PartFileError(path, f"not an STL file: {len(data)} bytes is too short for a binary STL")
    raise PartFileError(
        path,
        f"truncated or corrupt binary STL: the header declares {count} facets "
        f"({expected} bytes) but the file has {len(data)} bytes",
    )


def _binary(data: bytes, count: int, path: str) -> np.ndarray:
    records = np.frombuffer(data, BINARY_RECORD, count=count, offset=BINARY_HEADER_BYTES + 4)
    with np.errstate(invalid="ignore"):  # a signalling NaN is no warning: refused just below
        triangles = records["vertices"].astype(np.float64)
    _check_finite(triangles, path, lambda i: f"facet {i + 1}")
    return triangles


def _ascii(data: bytes, path: str) -> np.ndarray:
    """Triangles of an ASCII STL: one or more ``solid NAME ... endsolid NAME`` blocks of facets.

    A solid's name is the rest of its ``solid`` line, whatever words it holds. Each block's body is split by
    one regular expression for a whole facet (exactly three vertices, every keyword in place, in any case):
    anything left between two facets breaks the structure, so a facet with two vertices beside one with four
    cannot pair up into triangles. Where it breaks, the facet is walked token by token to name the line.
    """
    blocks = []  # (start, end) of each solid's body
    pos = 0
    open_at: int | None = None
    for at, ending, line_end in _solid_lines(data):
        if open_at is None:
            if ending:
                raise PartFileError(path, f"line {_line(data, at)}: 'endsolid' without a 'solid' before it")
            _expect_blank(data, pos, at, path, "before 'solid'")
            open_at, body_start = at, line_end
        elif ending:
            blocks.append((body_start, at))
            pos = line_end
            open_at = None
        # a 'solid' line inside an open block is left to the facet check, which names its line
    if open_at is not None:
        last = _line(data, len(data.rstrip()))
        raise PartFileError(
            path,
            f"ASCII STL is truncated: it ends at line {last} without 'endsolid' for the 'solid' of line "
            f"{_line(data, open_at)}",
        )
    if not blocks:
        raise PartFileError(path, "ASCII STL has no 'solid' line")
    _expect_blank(data, pos, len(data), path, "after the last 'endsolid'")
    columns: list[list[bytes]] = [[] for _ in range(9)]
    underscore = False
    for start, end in blocks:
        pieces = _FACET_SPLIT.split(data[start:end])
        if b"".join(pieces[0::10]).strip():  # something that is not a whole facet
            bad = _BODY.match(data, start, end).end()
            raise PartFileError(path, _facet_problem(data, bad, end))
        for k in range(9):
            columns[k].extend(pieces[k + 1 :: 10])
        underscore = underscore or data.find(b"_", start, end) >= 0
    if not columns[0]:
        raise PartFileError(path, "ASCII STL has no facets")
    values = None
    if not underscore:  # Python's float (and numpy's) takes 1_000; a CAD file's number never has one
        try:
            values = np.column_stack([np.array(column, dtype=np.float64) for column in columns])
        except (ValueError, OverflowError):
            values = None
    if values is None:
        line, token = _first_bad_number(data)
        raise PartFileError(path, f"line {line}: {token!r} is not a number")
    triangles = values.reshape(-1, 3, 3)
    _check_finite(triangles, path, lambda i: f"line {_line_of_vertex(data, 3 * i)}")
    return triangles


def _solid_lines(data: bytes):
    """``(start, is_endsolid, end of line)`` of every line whose first word is ``solid`` or ``endsolid``."""
    lower = data.lower()
    at = lower.find(b"solid")
    while at >= 0:
        line_start = lower.rfind(b"\n", 0, at) + 1
        ending = lower[max(at - 3, line_start) : at] == b"end"
        word_start = at - 3 if ending else at
        after = lower[at + 5 : at + 6]
        if not lower[line_start:word_start].strip(b" \t") and (not after or after.isspace()):
            line_end = lower.find(b"\n", at)
            line_end = len(data) if line_end < 0 else line_end + 1
            yield word_start, ending, line_end
            at = lower.find(b"solid", line_end)
        else:
            at = lower.find(b"solid", at + 5)


def _line(data: bytes, pos: int) -> int:
    return data.count(b"\n", 0, pos) + 1


def _expect_blank(data: bytes, start: int, end: int, path: str, where: str) -> None:
    text = data[start:end]
    if text.strip():
        at = start + len(text) - len(text.lstrip())
        word = text.split()[0][:24].decode("latin-1")
        raise PartFileError(path, f"line {_line(data, at)}: unexpected {word!r} {where}")


def _facet_problem(data: bytes, start: int, end: int) -> str:
    """The message for the first broken facet of a solid body, which starts at ``start``."""
    tokens = list(re.finditer(rb"\S+", data[start:end]))
    for index, expected in enumerate(_FACET_TOKENS):
        if index >= len(tokens):
            last = _line(data, end)
            return f"line {last}: the facet of line {_line(data, start)} is cut short before 'endsolid'"
        token = tokens[index]
        word = token.group().lower()
        line = _line(data, start + token.start())
        if expected is None:
            if word in (b"vertex", b"endloop", b"endfacet", b"facet", b"outer"):
                return f"line {line}: {token.group().decode('latin-1')!r} where a number is expected"
            continue
        if word == expected:
            continue
        shown = token.group()[:24].decode("latin-1")
        if expected == b"vertex" and word == b"endloop":
            count = (index - 7) // 4
            return f"line {line}: the facet has {count} vertices: every facet needs exactly 3"
        if expected == b"endloop" and word == b"vertex":
            return f"line {line}: a 4th vertex: every facet needs exactly 3"
        wanted = "'facet' or 'endsolid'" if index == 0 else repr(expected.decode())
        return f"line {line}: {shown!r} where {wanted} is expected"
    token = tokens[len(_FACET_TOKENS)] if len(tokens) > len(_FACET_TOKENS) else tokens[-1]
    shown = token.group()[:24].decode("latin-1")
    return f"line {_line(data, start + token.start())}: {shown!r} where 'facet' or 'endsolid' is expected"


def _check_finite(triangles: np.ndarray, path: str, where) -> None:
    bad = ~np.isfinite(triangles).all(axis=(1, 2))
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise PartFileError(path, f"{where(first)}: NaN or infinite coordinate ({int(bad.sum())} facets affected)")


def _first_bad_number(data: bytes) -> tuple[int, str]:
    for match in _VERTEX.finditer(data):
        for group in match.groups():
            try:
                if b"_" in group:  # Python's float takes 1_000; a CAD file's number never has one
                    raise ValueError(group)
                float(group)
            except ValueError:
                line = data.count(b"\n", 0, match.start()) + 1
                return line, group.decode("latin-1")
    return 0, "?"  # pragma: no cover - only called after a failed conversion


def _line_of_vertex(data: bytes, index: int) -> int:
    for i, match in enumerate(_VERTEX.finditer(data)):
        if i == index:
            return data.count(b"\n", 0, match.start()) + 1
    return 0  # pragma: no cover - index always exists
