"""A strict PLY reader (ascii, binary_little_endian, binary_big_endian): vertices and polygon faces.

Written here rather than read through trimesh because trimesh's PLY loader trusts the file: a binary file cut
in the middle, fewer rows than the header declares, a face whose list is shorter than its count, or a face
element with no rows at all (silently a point cloud) all loaded. Here the header is the contract: every
element must hold exactly the rows it declares, every list the number of entries its count says, and nothing
may follow the last element; each fault is a one-line :class:`~sprayplan.errors.PartFileError` naming the file
and the element and row.

Only ``x``, ``y``, ``z`` of the ``vertex`` element and the index list of the ``face`` element
(``vertex_indices`` or ``vertex_index``) are used; other elements and properties are read past. Polygons are
split into triangles as fans (the file's winding kept).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.errors import PartFileError

__all__ = ["parse_ply"]

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_INDEX_NAMES = ("vertex_indices", "vertex_index")


@dataclass
class _Property:
    name: str
    dtype: str  # the value's (or a list's entries') numpy type code, without byte order
    count_dtype: str | None = None  # a list's count type; None for a scalar


@dataclass
class _Element:
    name: str
    count: int
    line: int
    properties: list[_Property]


def _header(data: bytes, path: str) -> tuple[str | None, list[_Element], int]:
    """The byte order (None: ascii), the elements, and where the body starts."""
    if not data.startswith(b"ply"):
        raise PartFileError(path, "not a PLY file: it does not start with 'ply'")
    end = data.find(b"end_header")
    if end < 0:
        raise PartFileError(path, "PLY header has no 'end_header' line")
    body = data.find(b"\n", end)
    body = len(data) if body < 0 else body + 1
    if data[end + len(b"end_header") : body].strip():
        line = data.count(b"\n", 0, end) + 1
        raise PartFileError(path, f"line {line}: text after 'end_header'")
    order: str | None = None
    fmt_seen = False
    elements: list[_Element] = []
    for number, raw in enumerate(data[:end].split(b"\n")[1:], start=2):
        words = raw.decode("latin-1").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        key = words[0]
        if key == "format":
            if len(words) < 2 or words[1] not in _FORMATS:
                raise PartFileError(path, f"line {number}: unknown PLY format {' '.join(words[1:])!r}")
            order, fmt_seen = _FORMATS[words[1]], True
        elif key == "element":
            if len(words) != 3:
                raise PartFileError(path, f"line {number}: 'element' needs a name and a count")
            count = _whole(words[2])
            if count is None:
                raise PartFileError(
                    path, f"line {number}: element {words[1]!r} count {words[2]!r} is not a whole number >= 0"
                )
            if any(e.name == words[1] for e in elements):
                raise PartFileError(path, f"line {number}: element {words[1]!r} is declared twice")
            elements.append(_Element(words[1], count, number, []))
        elif key == "property":
            if not elements:
                raise PartFileError(path, f"line {number}: 'property' before any 'element'")
            element = elements[-1]
            if len(words) == 5 and words[1] == "list":
                if words[2] not in _TYPES or words[3] not in _TYPES or _TYPES[words[2]][0] == "f":
                    raise PartFileError(path, f"line {number}: bad list property types {words[2]!r} {words[3]!r}")
                prop = _Property(words[4], _TYPES[words[3]], _TYPES[words[2]])
            elif len(words) == 3 and words[1] in _TYPES:
                prop = _Property(words[2], _TYPES[words[1]])
            else:
                raise PartFileError(path, f"line {number}: bad property line {' '.join(words)!r}")
            if any(p.name == prop.name for p in element.properties):
                raise PartFileError(
                    path, f"line {number}: property {prop.name!r} of {element.name!r} is declared twice"
                )
            element.properties.append(prop)
        else:
            raise PartFileError(path, f"line {number}: unknown PLY header keyword {key[:24]!r}")
    if not fmt_seen:
        raise PartFileError(path, "PLY header has no 'format' line")
    return order, elements, body


def _whole(text: str) -> int | None:
    return int(text) if text.isdigit() else None


def parse_ply(data: bytes, path: str = "<bytes>") -> tuple[np.ndarray, np.ndarray]:
    """Parse the bytes of a PLY file into vertices and triangles.

    Parameters
    ----------
    data : bytes
        The whole file.
    path : str
        The file's name, used in error messages only.

    Returns
    -------
    vertices : (n, 3) float64
        ``x, y, z`` of the ``vertex`` element, in the file's units (not checked for finiteness here).
    faces : (m, 3) int64
        Triangles (polygons split as fans), every index in ``[0, n)``; ``(0, 3)`` when the file declares no
        face element or one of 0 rows (a point cloud).

    Raises
    ------
    PartFileError
        A broken header, an element with fewer rows than declared (a file cut short), a list shorter than its
        count, data after the last element, a value that is not a number, a face of fewer than 3 indices, an
        index that is not a whole number or outside the vertices, no vertex element or no ``x, y, z``.
    """
    order, elements, start = _header(data, path)
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        raise PartFileError(path, "PLY header declares no 'vertex' element")
    names = [p.name for p in vertex.properties]
    missing = [axis for axis in "xyz" if axis not in names]
    if missing:
        raise PartFileError(path, f"PLY vertex element has no {', '.join(missing)} property")
    if any(p.count_dtype is not None for p in vertex.properties if p.name in "xyz"):
        raise PartFileError(path, "PLY vertex x, y, z must be scalar properties, not lists")
    face = next((e for e in elements if e.name == "face"), None)
    index_name = None
    if face is not None and face.count > 0:
        lists = [p.name for p in face.properties if p.count_dtype is not None]
        index_name = next((n for n in _INDEX_NAMES if n in lists), lists[0] if lists else None)
        if index_name is None:
            raise PartFileError(path, "PLY face element has no list of vertex indices")
    reader = _AsciiBody(data, start, path) if order is None else _BinaryBody(data, start, order, path)
    vertices = faces = None
    for element in elements:
        wanted = ["x", "y", "z"] if element is vertex else [index_name] if element is face and index_name else []
        columns = reader.element(element, wanted)
        if element is vertex:
            with np.errstate(invalid="ignore"):  # a signalling NaN is no warning: the loader refuses it (load_part)
                vertices = np.column_stack([np.asarray(columns[a], dtype=np.float64) for a in "xyz"])
        elif element is face and index_name is not None:
            faces = columns[index_name]
    reader.finish(elements[-1])
    if len(vertices) == 0:
        raise PartFileError(path, "PLY file has no vertices (element vertex 0)")
    triangles = np.zeros((0, 3), dtype=np.int64) if faces is None else _triangles(faces, len(vertices), path)
    return vertices, triangles


def _triangles(faces, n_vertices: int, path: str) -> np.ndarray:
    """Fans of the faces' index lists: an (m, k) array (all faces of k indices) or a list of 1-D arrays."""
    if isinstance(faces, np.ndarray):
        sizes = np.full(len(faces), faces.shape[1])
        flat = faces.reshape(-1)
    else:
        sizes = np.array([len(f) for f in faces], dtype=np.int64)
        flat = np.concatenate(faces) if len(faces) else np.zeros(0)
    short = np.flatnonzero(sizes < 3)
    if short.size:
        row = int(short[0])
        raise PartFileError(path, f"face {row + 1} has {sizes[row]} indices: a face needs at least 3")
    flat = np.asarray(flat)
    if flat.dtype.kind == "f":
        fractional = ~np.isfinite(flat) | (flat != np.floor(flat))
        if fractional.any():
            row = int(np.searchsorted(np.cumsum(sizes), int(np.argmax(fractional)), side="right"))
            raise PartFileError(path, f"face {row + 1}: a vertex index is not a whole number")
    bad = (flat < 0) | (flat >= n_vertices)
    if bad.any():
        at = int(np.argmax(bad))
        row = int(np.searchsorted(np.cumsum(sizes), at, side="right"))
        raise PartFileError(
            path,
            f"face {row + 1} refers to vertex {flat[at]:.0f}, but the file has {n_vertices} (0 to {n_vertices - 1})",
        )
    flat = flat.astype(np.int64)
    if isinstance(faces, np.ndarray) and faces.shape[1] == 3:
        return flat.reshape(-1, 3)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    fans = sizes - 2
    owner = np.repeat(np.arange(len(sizes)), fans)
    step = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans)
    first = starts[owner]
    return np.stack([flat[first], flat[first + step + 1], flat[first + step + 2]], axis=1)


class _BinaryBody:
    def __init__(self, data: bytes, start: int, order: str, path: str):
        self.data, self.pos, self.order, self.path = data, start, order, path

    def _short(self, element: _Element, row: int) -> PartFileError:
        return PartFileError(
            self.path,
            f"binary PLY ends early: element {element.name!r} declares {element.count} rows but the file ends "
            f"in row {row + 1} ({len(self.data)} bytes)",
        )

    def element(self, element: _Element, wanted: list[str]) -> dict:
        props = element.properties
        if element.count == 0:
            return {name: np.zeros((0, 3) if name not in "xyz" else 0) for name in wanted}
        if all(p.count_dtype is None for p in props):
            dtype = np.dtype([(p.name, self.order + p.dtype) for p in props])
            need = element.count * dtype.itemsize
            if self.pos + need > len(self.data):
                whole = (len(self.data) - self.pos) // max(dtype.itemsize, 1)
                raise self._short(element, whole)
            table = np.frombuffer(self.data, dtype, element.count, self.pos)
            self.pos += need
            return {name: table[name] for name in wanted}
        lengths = self._first_row_lengths(element)
        fields = []
        for p, length in zip(props, lengths):
            if p.count_dtype is None:
                fields.append((p.name, self.order + p.dtype))
            else:
                fields += [("#" + p.name, self.order + p.count_dtype), (p.name, self.order + p.dtype, (length,))]
        dtype = np.dtype(fields)
        need = element.count * dtype.itemsize
        rows = min(element.count, (len(self.data) - self.pos) // dtype.itemsize)
        table = np.frombuffer(self.data, dtype, rows, self.pos)
        if all((table["#" + p.name] == n).all() for p, n in zip(props, lengths) if p.count_dtype is not None):
            if rows < element.count:  # every whole row alike, and the file ends before the last
                raise self._short(element, rows)
            self.pos += need
            return {name: table[name].reshape(element.count, -1) for name in wanted}
        return self._row_by_row(element, wanted)

    def _first_row_lengths(self, element: _Element) -> list[int]:
        pos, lengths = self.pos, []
        for p in element.properties:
            if p.count_dtype is None:
                lengths.append(1)
                pos += int(p.dtype[1])
                continue
            size = int(p.count_dtype[1])
            if pos + size > len(self.data):
                raise self._short(element, 0)
            (count,) = np.frombuffer(self.data, self.order + p.count_dtype, 1, pos)
            lengths.append(int(count))
            pos += size + int(count) * int(p.dtype[1])
        return lengths

    def _row_by_row(self, element: _Element, wanted: list[str]) -> dict:
        """Rows whose lists differ in length (a mesh of triangles and quads), one at a time."""
        out: dict[str, list] = {name: [] for name in wanted}
        data, pos, order = self.data, self.pos, self.order
        for row in range(element.count):
            for p in element.properties:
                if p.count_dtype is None:
                    size = int(p.dtype[1])
                    if pos + size > len(data):
                        raise self._short(element, row)
                    if p.name in out:
                        out[p.name].append(np.frombuffer(data, order + p.dtype, 1, pos)[0])
                    pos += size
                    continue
                size = int(p.count_dtype[1])
                if pos + size > len(data):
                    raise self._short(element, row)
                count = int(np.frombuffer(data, order + p.count_dtype, 1, pos)[0])
                pos += size
                item = int(p.dtype[1])
                if pos + count * item > len(data):
                    raise self._short(element, row)
                if p.name in out:
                    out[p.name].append(np.frombuffer(data, order + p.dtype, count, pos))
                pos += count * item
        self.pos = pos
        return {name: (np.array(v) if name in "xyz" else v) for name, v in out.items()}

    def finish(self, last: _Element) -> None:
        rest = self.data[self.pos :]
        if rest.strip(b" \t\r\n"):
            raise PartFileError(
                self.path,
                f"binary PLY has {len(rest)} bytes after its last element ({last.name!r}): the header declares "
                "fewer rows than the file holds",
            )


class _AsciiBody:
    def __init__(self, data: bytes, start: int, path: str):
        self.tokens = data[start:].split()
        self.at = 0
        self.path = path

    def _short(self, element: _Element, row: int) -> PartFileError:
        return PartFileError(
            self.path,
            f"PLY ends early: element {element.name!r} declares {element.count} rows but the file ends in row "
            f"{row + 1}",
        )

    def _numbers(self, tokens: list[bytes], element: _Element, first_row: int, width: int) -> np.ndarray:
        try:
            if not any(b"_" in t for t in tokens):
                return np.array(tokens, dtype=np.float64)
        except (ValueError, OverflowError):
            pass
        for index, token in enumerate(tokens):
            try:
                if b"_" in token:
                    raise ValueError(token)
                float(token)
            except ValueError:
                row = first_row + index // max(width, 1)
                shown = token[:24].decode("latin-1")
                raise PartFileError(
                    self.path, f"element {element.name!r} row {row + 1}: {shown!r} is not a number"
                ) from None
        raise PartFileError(self.path, f"element {element.name!r}: the numbers cannot be read")  # pragma: no cover

    def element(self, element: _Element, wanted: list[str]) -> dict:
        props = element.properties
        if element.count == 0:
            return {name: np.zeros((0, 3) if name not in "xyz" else 0) for name in wanted}
        lengths = []
        at = self.at
        for p in props:  # the first row decides the width the fast path tries
            if p.count_dtype is None:
                lengths.append(1)
                at += 1
            else:
                if at >= len(self.tokens):
                    raise self._short(element, 0)
                count = self._numbers([self.tokens[at]], element, 0, 1)[0]
                if count != int(count) or count < 0:
                    raise PartFileError(
                        self.path, f"element {element.name!r} row 1: list count {count:g} is not a whole number"
                    )
                lengths.append(int(count))
                at += 1 + int(count)
        width = at - self.at
        need = element.count * width
        if self.at + need <= len(self.tokens):
            table = self._numbers(self.tokens[self.at : self.at + need], element, 0, width).reshape(
                element.count, width
            )
            offsets = np.cumsum([0] + [n + (p.count_dtype is not None) for p, n in zip(props, lengths)])
            same = all(
                (table[:, offsets[i]] == lengths[i]).all() for i, p in enumerate(props) if p.count_dtype is not None
            )
            if same:
                self.at += need
                out = {}
                for i, p in enumerate(props):
                    if p.name in wanted:
                        first = offsets[i] + (p.count_dtype is not None)
                        block = table[:, first : first + lengths[i]]
                        out[p.name] = block[:, 0] if p.count_dtype is None else block
                return out
        return self._row_by_row(element, wanted)

    def _row_by_row(self, element: _Element, wanted: list[str]) -> dict:
        out: dict[str, list] = {name: [] for name in wanted}
        tokens, at = self.tokens, self.at
        for row in range(element.count):
            for p in element.properties:
                if at >= len(tokens):
                    raise self._short(element, row)
                if p.count_dtype is None:
                    if p.name in out:
                        out[p.name].append(self._numbers([tokens[at]], element, row, 1)[0])
                    at += 1
                    continue
                count = self._numbers([tokens[at]], element, row, 1)[0]
                if count != int(count) or count < 0:
                    raise PartFileError(
                        self.path, f"element {element.name!r} row {row + 1}: list count {count:g} is not a whole number"
                    )
                count = int(count)
                if at + 1 + count > len(tokens):
                    raise self._short(element, row)
                if p.name in out:
                    out[p.name].append(self._numbers(tokens[at + 1 : at + 1 + count], element, row, count + 1))
                at += 1 + count
        self.at = at
        return {name: (np.array(v) if name in "xyz" else v) for name, v in out.items()}

    def finish(self, last: _Element) -> None:
        extra = len(self.tokens) - self.at
        if extra:
            raise PartFileError(
                self.path,
                f"PLY has {extra} values after its last element ({last.name!r}): the header declares fewer rows "
                "than the file holds",
            )
