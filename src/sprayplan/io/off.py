"""Strict readers of the two simple text mesh formats: OFF (Geomview) and OBJ (Wavefront; geometry only).

Written here rather than read through trimesh because trimesh trusts these files: an OFF face count of -3 or
4e9, a face line with fewer or more indices than its count, an OBJ face index 0 and a file cut short all
loaded. Here every declared count is checked against what the file holds and every face index against the
vertices, each fault a one-line :class:`~sprayplan.errors.PartFileError` naming the file and the line.
Polygons are split into triangles as fans, keeping the file's winding.
"""

from __future__ import annotations

import logging
import re

import numpy as np

from sprayplan.errors import PartFileError

__all__ = ["parse_obj", "parse_off"]

log = logging.getLogger(__name__)

_OFF_KEYWORD = re.compile(r"(ST)?C?N?(4)?(n)?OFF", re.IGNORECASE)


def _lines(data: bytes) -> list[tuple[int, list[bytes]]]:
    """``(line number, tokens)`` of every line that holds something once ``#`` comments are cut off."""
    out = []
    for number, raw in enumerate(data.split(b"\n"), start=1):
        cut = raw.find(b"#")
        tokens = (raw if cut < 0 else raw[:cut]).split()
        if tokens:
            out.append((number, tokens))
    return out


def _whole(token: bytes) -> int | None:
    return int(token) if token.isdigit() else None


def _numbers(rows: list[list[bytes]], numbers: list[int], path: str) -> np.ndarray:
    """``rows`` of 3 tokens each as an (n, 3) float64 array; a token that is not a plain number names its line."""
    try:
        if not any(b"_" in t for row in rows for t in row):
            return np.array(rows, dtype=np.float64).reshape(-1, 3)
    except (ValueError, OverflowError):
        pass
    for row, number in zip(rows, numbers):
        for token in row:
            try:
                if b"_" in token:
                    raise ValueError(token)
                float(token)
            except ValueError:
                raise PartFileError(path, f"line {number}: {token[:24].decode('latin-1')!r} is not a number") from None
    raise PartFileError(path, "the coordinates cannot be read")  # pragma: no cover


def _fans(polygons: list[list[int]]) -> np.ndarray:
    """Triangles of polygons (each a list of >= 3 vertex indices) as fans about each polygon's first vertex."""
    if polygons and all(len(p) == 3 for p in polygons):
        return np.array(polygons, dtype=np.int64).reshape(-1, 3)
    out = [(p[0], p[k], p[k + 1]) for p in polygons for k in range(1, len(p) - 1)]
    return np.array(out, dtype=np.int64).reshape(-1, 3)


def parse_off(data: bytes, path: str = "<bytes>") -> tuple[np.ndarray, np.ndarray]:
    """Parse the bytes of an OFF file: the ``OFF`` keyword (``COFF``, ``NOFF``, ``STOFF`` ... too), the counts
    ``vertices faces [edges]`` (on the keyword's line or the next), one vertex a line (x y z, then anything:
    colours, normals), one face a line (``k i1 ... ik``, then 0, 1, 3 or 4 colour values).

    Returns
    -------
    vertices : (n, 3) float64
        In the file's units (finiteness is checked by the caller).
    faces : (m, 3) int64
        Triangles, indices in ``[0, n)``; ``(0, 3)`` for a file of 0 faces (a point cloud).

    Raises
    ------
    PartFileError
        No ``OFF`` keyword, counts that are not whole numbers >= 0, fewer vertex or face lines than the
        counts declare (a file cut short) or more, a vertex line of fewer than 3 numbers, a face line with a
        different number of indices than its count, a face of fewer than 3 indices, an index outside the
        vertices; each naming the line.
    """
    lines = _lines(data)
    if not lines:
        raise PartFileError(path, "file is empty")
    number, tokens = lines[0]
    keyword = tokens[0].decode("latin-1")
    match = _OFF_KEYWORD.fullmatch(keyword)
    if match is None:
        raise PartFileError(path, f"line {number}: not an OFF file (it starts with {keyword[:24]!r}, not 'OFF')")
    if match.group(2) or match.group(3):
        raise PartFileError(path, f"line {number}: {keyword!r} files (not 3-D) are not supported")
    if len(tokens) > 1 and tokens[1].lower() == b"binary":
        raise PartFileError(path, f"line {number}: binary OFF files are not supported; convert to text OFF or PLY")
    if len(tokens) > 1:  # the counts on the keyword's line
        counts, rest, count_line = tokens[1:], lines[1:], number
    elif len(lines) > 1:
        count_line, counts = lines[1]
        rest = lines[2:]
    else:
        counts, rest, count_line = [], [], number
    if len(counts) not in (2, 3):
        raise PartFileError(path, f"line {count_line}: expected the counts 'vertices faces edges'")
    values = [_whole(c) for c in counts]
    if None in values:
        shown = " ".join(c.decode("latin-1")[:24] for c in counts)
        raise PartFileError(path, f"line {count_line}: the counts {shown!r} must be whole numbers >= 0")
    n_vertices, n_faces = values[0], values[1]
    if n_vertices == 0:
        raise PartFileError(path, f"line {count_line}: the file declares 0 vertices")
    if len(rest) < n_vertices + n_faces:
        last = rest[-1][0] if rest else count_line
        held_v = min(len(rest), n_vertices)
        held_f = max(len(rest) - n_vertices, 0)
        raise PartFileError(
            path,
            f"OFF file ends early at line {last}: line {count_line} declares {n_vertices} vertices and {n_faces} "
            f"faces, the file holds {held_v} and {held_f}",
        )
    if len(rest) > n_vertices + n_faces:
        number = rest[n_vertices + n_faces][0]
        raise PartFileError(
            path,
            f"line {number}: more lines than line {count_line} declares ({n_vertices} vertices and {n_faces} faces)",
        )
    vertex_lines = rest[:n_vertices]
    short = next(((n, t) for n, t in vertex_lines if len(t) < 3), None)
    if short is not None:
        raise PartFileError(path, f"line {short[0]}: a vertex needs 3 coordinates, the line has {len(short[1])} values")
    vertices = _numbers([t[:3] for _, t in vertex_lines], [n for n, _ in vertex_lines], path)
    polygons = []
    for number, tokens in rest[n_vertices:]:
        k = _whole(tokens[0])
        if k is None:
            raise PartFileError(
                path, f"line {number}: a face's index count {tokens[0][:24].decode('latin-1')!r} is not a whole number"
            )
        if k < 3:
            raise PartFileError(path, f"line {number}: a face of {k} indices: a face needs at least 3")
        extra = len(tokens) - 1 - k
        if extra < 0 or extra not in (0, 1, 3, 4):
            raise PartFileError(
                path,
                f"line {number}: the face declares {k} indices but the line has {len(tokens) - 1} values "
                "(indices, then 0, 1, 3 or 4 colour values)",
            )
        indices = [_whole(t) for t in tokens[1 : k + 1]]
        if None in indices:
            raise PartFileError(path, f"line {number}: a vertex index is not a whole number >= 0")
        if max(indices) >= n_vertices:
            raise PartFileError(
                path,
                f"line {number}: face refers to vertex {max(indices)}, the file has {n_vertices} (0 to {n_vertices - 1})",
            )
        polygons.append(indices)
    return vertices, _fans(polygons)


def parse_obj(data: bytes, path: str = "<bytes>") -> tuple[np.ndarray, np.ndarray]:
    """Parse the geometry of a Wavefront OBJ file: ``v x y z [w | r g b]`` and ``f`` lines.

    Face corners may be ``v``, ``v/vt``, ``v/vt/vn`` or ``v//vn``; indices start at 1, and a negative index
    counts back from the last vertex defined before the face (``-1`` is the latest). Other statements (groups,
    materials, texture coordinates, lines, smoothing) are read past; materials and textures are logged once.
    A line ending in ``\\`` continues on the next.

    Returns
    -------
    vertices : (n, 3) float64
    faces : (m, 3) int64
        ``(0, 3)`` for a file of vertices only (a point cloud).

    Raises
    ------
    PartFileError
        A vertex line of fewer than 3 numbers or with a value that is not a number, a face of fewer than 3
        corners, a face index 0, not a whole number, past the vertices or (negative) before the first; each
        naming the line.
    """
    if b"\\\n" in data or b"\\\r\n" in data:  # continuation lines: joined into one
        data = data.replace(b"\\\r\n", b" \r").replace(b"\\\n", b" \r")
    vertex_rows: list[list[bytes]] = []
    vertex_lines: list[int] = []
    polygons: list[list[int]] = []
    largest: tuple[int, int] = (0, 0)  # (1-based index, line) of the largest positive face index
    said_material = False
    for number, raw in enumerate(data.split(b"\n"), start=1):
        cut = raw.find(b"#")
        tokens = (raw if cut < 0 else raw[:cut]).split()
        if not tokens:
            continue
        key = tokens[0]
        if key == b"v":
            if len(tokens) < 4:
                raise PartFileError(
                    path, f"line {number}: a vertex needs 3 coordinates, the line has {len(tokens) - 1}"
                )
            vertex_rows.append(tokens[1:4])
            vertex_lines.append(number)
        elif key == b"f":
            if len(tokens) < 4:
                raise PartFileError(
                    path, f"line {number}: a face of {len(tokens) - 1} corners: a face needs at least 3"
                )
            seen = len(vertex_rows)
            corners = []
            for token in tokens[1:]:
                text = token.split(b"/", 1)[0]
                try:
                    index = int(text) if b"_" not in text else None
                except ValueError:
                    index = None
                if index is None:
                    raise PartFileError(
                        path, f"line {number}: face corner {token[:24].decode('latin-1')!r} is not a vertex index"
                    )
                if index == 0:
                    raise PartFileError(
                        path, f"line {number}: face index 0: OBJ indices start at 1 (or count back from -1)"
                    )
                if index < 0:
                    if -index > seen:
                        raise PartFileError(
                            path,
                            f"line {number}: face index {index} counts back past the first vertex ({seen} defined so far)",
                        )
                    corners.append(seen + index)
                else:
                    if index > largest[0]:
                        largest = (index, number)
                    corners.append(index - 1)
            polygons.append(corners)
        elif key in (b"mtllib", b"usemtl", b"map_Kd") and not said_material:
            log.info("%s: ignoring material/texture files (%s): only the geometry is used", path, key.decode())
            said_material = True
    if not vertex_rows:
        raise PartFileError(path, "OBJ file has no vertices ('v' lines)")
    if largest[0] > len(vertex_rows):
        raise PartFileError(
            path,
            f"line {largest[1]}: face index {largest[0]} is past the last vertex (the file has {len(vertex_rows)})",
        )
    return _numbers(vertex_rows, vertex_lines, path), _fans(polygons)
