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
_VERTEX = re.compile(rb"vertex[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)")
_FACET = re.compile(rb"\bfacet\b")
_ENDFACET = re.compile(rb"\bendfacet\b")


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
    triangles = records["vertices"].astype(np.float64)
    _check_finite(triangles, path, lambda i: f"facet {i + 1}")
    return triangles


def _ascii(data: bytes, path: str) -> np.ndarray:
    matches = _VERTEX.findall(data)
    n_facets = len(_FACET.findall(data))
    n_end = len(_ENDFACET.findall(data))
    if n_facets == 0 and not matches:
        raise PartFileError(path, "ASCII STL has no facets")
    if n_end != n_facets:
        raise PartFileError(
            path, f"ASCII STL is truncated or broken: {n_facets} 'facet' but {n_end} 'endfacet' keywords"
        )
    if len(matches) != 3 * n_facets:
        raise PartFileError(
            path, f"ASCII STL has {n_facets} facets but {len(matches)} vertices: every facet needs exactly 3"
        )
    try:
        values = np.array(matches, dtype=np.float64)
    except ValueError:
        values = None
    if values is None:
        line, token = _first_bad_number(data)
        raise PartFileError(path, f"line {line}: {token!r} is not a number")
    triangles = values.reshape(-1, 3, 3)
    _check_finite(triangles, path, lambda i: f"line {_line_of_vertex(data, 3 * i)}")
    return triangles


def _check_finite(triangles: np.ndarray, path: str, where) -> None:
    bad = ~np.isfinite(triangles).all(axis=(1, 2))
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise PartFileError(path, f"{where(first)}: NaN or infinite coordinate ({int(bad.sum())} facets affected)")


def _first_bad_number(data: bytes) -> tuple[int, str]:
    for match in _VERTEX.finditer(data):
        for group in match.groups():
            try:
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
