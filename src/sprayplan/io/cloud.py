"""Point-cloud readers: text XYZ files and PCL's PCD files (ascii, binary and binary_compressed).

Both readers return the points in the file's own units (no scaling here) and the per-point normals when the
file stores them. Any broken input raises :class:`~sprayplan.errors.PartFileError` with a one-line message
that names the file and, for text, the line; nothing else escapes, whatever the bytes.

Written here rather than taken from a library because the checks are the point: a truncated binary block, a
corrupt LZF stream, a stray word in line 70,000 of a text file must each say what is wrong and where.

Decisions worth knowing
-----------------------
* XYZ: a NaN or infinite value in a column that is used (x, y, z or a normal) is an error with its line
  number; values in ignored columns are not checked.
* XYZ with exactly 6 numeric columns and no header: columns 3-5 are taken as normals only if every one of
  them has unit length within 1e-3; otherwise they are ignored (they may be colours or anything else).
* PCD: NaN coordinates are PCL's "no return" marker in organised clouds; such points are dropped and the
  count is logged. Infinite coordinates are an error. If the normals of the kept points are not all finite
  (PCL marks failed normal estimation with NaN), the normals are dropped as a whole (``None``) with a
  warning, so that the caller estimates them itself.
"""

from __future__ import annotations

import itertools
import logging
import os
import struct
from pathlib import Path

import numpy as np

from sprayplan.errors import PartFileError

__all__ = ["parse_pcd", "parse_xyz", "read_pcd", "read_xyz"]

logger = logging.getLogger(__name__)

_BOM = b"\xef\xbb\xbf"
# Separators other than space and newline become spaces; after this, a token is a run of other bytes.
_SEPARATORS = bytes.maketrans(b"\t,\r\x0b\x0c", b"     ")
_UNIT_TOLERANCE = 1e-3
_XYZ_NAMES = ("x", "y", "z")
_NORMAL_NAMES = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"))
_PCD_KINDS = ("ascii", "binary", "binary_compressed")
_PCD_SIZES = {"F": (4, 8), "I": (1, 2, 4, 8), "U": (1, 2, 4, 8)}
_PCD_DTYPE_KIND = {"F": "f", "I": "i", "U": "u"}


# --------------------------------------------------------------------------------------------------------
# shared helpers


def _read_bytes(path: str | os.PathLike) -> bytes:
    """Read a whole file, turning every reason it cannot be read into a PartFileError."""
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise PartFileError(path, "file not found") from None
    except IsADirectoryError:
        raise PartFileError(path, "is a directory, not a file") from None
    except PermissionError:
        raise PartFileError(path, "cannot read the file: permission denied") from None
    except OSError as exc:
        raise PartFileError(path, f"cannot read the file ({exc.strerror or exc})") from None
    except ValueError as exc:  # e.g. a path with an embedded NUL byte
        raise PartFileError(path, f"not a usable file name ({exc})") from None


def _show(token: bytes) -> str:
    """A short, printable, single-line rendering of a token for an error message."""
    text = token[:24].decode("utf-8", "replace")
    text = "".join(ch if ch.isprintable() else "?" for ch in text)
    return repr(text + ("..." if len(token) > 24 else ""))


def _is_number(token: bytes) -> bool:
    """True if ``token`` is a number the table parser accepts (Python float syntax, no underscores)."""
    if b"_" in token:
        return False
    try:
        float(token)
    except ValueError:
        return False
    return True


def _first_bad_token(text: bytes, first_line: int) -> tuple[int, bytes] | None:
    """Slow scan: the line number and token of the first value that is not a number, or None."""
    for index, line in enumerate(text.split(b"\n")):
        for token in line.split():
            if not _is_number(token):
                return first_line + index, token
    return None


def _parse_table(path: str | os.PathLike, text: bytes, first_line: int) -> tuple[np.ndarray, np.ndarray]:
    """Parse whitespace-separated numbers into a table with the same number of columns in every row.

    Parameters
    ----------
    path : str or os.PathLike
        The file, for error messages.
    text : bytes
        Data whose only separators are ``b" "`` and ``b"\\n"`` (see ``_SEPARATORS``); blank lines are skipped.
    first_line : int
        The 1-based line number in the file of the first line of ``text``.

    Returns
    -------
    values : (rows, columns) float64
        The numbers; ``(0, 0)`` if ``text`` holds no token.
    lines : (rows,) int64
        The 1-based line number in the file of each row.
    """
    buf = np.frombuffer(text, dtype=np.uint8)
    newline = buf == 10
    in_token = ~(newline | (buf == 32))
    starts = in_token.copy()
    starts[1:] &= ~in_token[:-1]
    start_pos = np.flatnonzero(starts)
    if start_pos.size == 0:
        return np.zeros((0, 0)), np.zeros(0, dtype=np.int64)
    newline_pos = np.flatnonzero(newline)
    line_of_token = np.searchsorted(newline_pos, start_pos)  # 0-based line of each token
    per_line = np.bincount(line_of_token, minlength=newline_pos.size + 1)
    rows = np.flatnonzero(per_line)
    columns = int(per_line[rows[0]])
    uneven = rows[per_line[rows] != columns]
    if uneven.size:
        bad = int(uneven[0])
        raise PartFileError(
            path,
            f"line {first_line + bad} has {per_line[bad]} values but line {first_line + int(rows[0])} "
            f"has {columns}: every row needs the same number of columns",
        )
    tokens = text.split()
    values = None
    if len(tokens) == start_pos.size and b"_" not in text:
        try:
            values = np.array(tokens, dtype=np.float64)
        except (ValueError, OverflowError):
            values = None
    if values is None:
        found = _first_bad_token(text, first_line)
        if found is None:  # cannot happen with consistent separators; keep the promise anyway
            raise PartFileError(path, "the numbers cannot be read")
        line, token = found
        raise PartFileError(path, f"line {line}: {_show(token)} is not a number")
    return values.reshape(rows.size, columns), rows.astype(np.int64) + first_line


def _check_finite(path: str | os.PathLike, values: np.ndarray, lines: np.ndarray) -> None:
    """Raise for the first row of ``values`` (rows, k) holding a NaN or an infinity."""
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        row = int(np.argmax(bad))
        what = "NaN" if np.isnan(values[row]).any() else "an infinite value"
        raise PartFileError(path, f"line {lines[row]}: {what} where a coordinate or normal is expected")


def _all_unit_length(vectors: np.ndarray) -> bool:
    """True if every row of ``vectors`` (n, 3) is finite with length 1 within ``_UNIT_TOLERANCE``."""
    with np.errstate(over="ignore", invalid="ignore"):
        lengths = np.sqrt(np.einsum("ij,ij->i", vectors, vectors))
        return bool(np.all(np.abs(lengths - 1.0) <= _UNIT_TOLERANCE))


# --------------------------------------------------------------------------------------------------------
# XYZ text


def _blank_comment_lines(text: bytes) -> bytes:
    """Empty every line whose first non-space bytes are ``#`` or ``//``, keeping its newline.

    Lines are blanked rather than removed so that line numbers in messages stay right. Only the places where
    a marker occurs are visited, so a large file with a few comments costs a few ``find`` calls.
    """
    keep: list[bytes] = []
    copied = 0  # text[:copied] is already in keep (or blanked)
    next_hash = text.find(b"#")
    next_slashes = text.find(b"//")
    while next_hash >= 0 or next_slashes >= 0:
        marker = min(at for at in (next_hash, next_slashes) if at >= 0)
        line_start = text.rfind(b"\n", 0, marker) + 1
        line_end = text.find(b"\n", marker)
        line_end = len(text) if line_end < 0 else line_end
        if not text[line_start:marker].strip(b" "):
            keep.append(text[copied:line_start])
            copied = line_end
        pos = line_end
        if 0 <= next_hash < pos:
            next_hash = text.find(b"#", pos)
        if 0 <= next_slashes < pos:
            next_slashes = text.find(b"//", pos)
    if not keep:
        return text
    keep.append(text[copied:])
    return b"".join(keep)


def read_xyz(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a text point cloud (``.xyz``, ``.txt``, ``.csv``): one point a line.

    Values are separated by any mix of runs of spaces, tabs and commas; lines end in LF or CRLF; a UTF-8 BOM
    is skipped; blank lines and lines starting with ``#`` or ``//`` are skipped. The first other line may be
    a header of column names (a line in which no value is a number): names ``x``, ``y``, ``z`` choose the
    coordinate columns and ``nx``, ``ny``, ``nz`` (or ``normal_x``, ``normal_y``, ``normal_z``) the normal
    columns, case-insensitively. Without such names, columns 0-2 are x, y, z and further columns are ignored,
    except that a file of exactly 6 columns without a header has its columns 3-5 taken as normals when all
    of them have unit length within 1e-3.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    points : (n, 3) float64
        Point coordinates in the file's units, n >= 1, all finite.
    normals : (n, 3) float64 or None
        Per-point normals as stored in the file (not re-normalised), all finite; None if the file has none.

    Raises
    ------
    PartFileError
        For a missing, unreadable or empty file, a file without points, a value that is not a number, a NaN
        or infinite coordinate or normal, rows with different numbers of columns, or fewer than 3 columns.
        The message names the file and the line.
    """
    return parse_xyz(_read_bytes(path), path)


def parse_xyz(data: bytes, path: str | os.PathLike = "<bytes>") -> tuple[np.ndarray, np.ndarray | None]:
    """Parse the bytes of a text point cloud; see :func:`read_xyz` for the format.

    Parameters
    ----------
    data : bytes
        The whole file.
    path : str or os.PathLike
        The file's name, used in error messages only.

    Returns
    -------
    points : (n, 3) float64
        Point coordinates in the file's units.
    normals : (n, 3) float64 or None
        Per-point normals, or None.
    """
    data = data.removeprefix(_BOM)
    if not data.strip():
        raise PartFileError(path, "file is empty")
    if b"\n" not in data and b"\r" in data:  # old Mac line ends: CR alone
        data = data.replace(b"\r", b"\n")
    text = data.translate(_SEPARATORS)
    text = _blank_comment_lines(text)

    names: list[str] | None = None
    header_line = 0
    start = len(text) - len(text.lstrip(b" \n"))
    if start < len(text):
        end = text.find(b"\n", start)
        end = len(text) if end < 0 else end
        first = text[start:end].split()
        if not any(_is_number(token) for token in first):
            names = [token.decode("utf-8", "replace").strip("\"'").lower() for token in first]
            header_line = text.count(b"\n", 0, start) + 1
            text = text[:start] + text[end:]

    values, lines = _parse_table(path, text, 1)
    if values.shape[0] == 0:
        if names is not None:
            raise PartFileError(path, f"no points: line {header_line} is a header but no data rows follow")
        raise PartFileError(path, "no points: the file has only comments and blank lines")
    columns = values.shape[1]
    if columns < 3:
        raise PartFileError(path, f"line {lines[0]}: {columns} value(s) a row, need at least 3 (x y z)")

    coords = [0, 1, 2]
    normal_cols: list[int] | None = None
    if names is not None:
        named_xyz = all(name in names for name in _XYZ_NAMES)
        named_normals = next((triple for triple in _NORMAL_NAMES if all(n in names for n in triple)), None)
        if named_xyz or named_normals:
            if len(names) != columns:
                raise PartFileError(
                    path,
                    f"header (line {header_line}) names {len(names)} columns but line {lines[0]} has {columns} values",
                )
            if named_xyz:
                coords = [names.index(name) for name in _XYZ_NAMES]
            if named_normals:
                normal_cols = [names.index(name) for name in named_normals]
    elif columns == 6 and _all_unit_length(values[:, 3:6]):
        normal_cols = [3, 4, 5]

    used = coords + (normal_cols or [])
    _check_finite(path, values[:, used], lines)
    points = np.ascontiguousarray(values[:, coords])
    normals = None if normal_cols is None else np.ascontiguousarray(values[:, normal_cols])
    return points, normals


# --------------------------------------------------------------------------------------------------------
# PCD


class _CorruptBlock(ValueError):
    """An LZF block that cannot be decoded; the message says why."""


def _lzf_decompress(block: bytes, size: int) -> bytes:
    """Decode a liblzf block that must expand to exactly ``size`` bytes.

    Parameters
    ----------
    block : bytes
        The compressed stream.
    size : int
        The declared uncompressed size in bytes.

    Returns
    -------
    bytes
        The ``size`` decoded bytes.

    Raises
    ------
    _CorruptBlock
        If a literal run or a back-reference reads past the end of ``block``, a back-reference points before
        the start of the output, or the output would be longer or shorter than ``size``.
    """
    out = bytearray()
    end = len(block)
    pos = 0
    while pos < end:
        control = block[pos]
        pos += 1
        if control < 32:  # literal run of control + 1 bytes
            run = control + 1
            if pos + run > end:
                raise _CorruptBlock(f"a literal run at byte {pos - 1} goes past the end of the block")
            if len(out) + run > size:
                raise _CorruptBlock(f"it decodes to more than the declared {size} bytes")
            out += block[pos : pos + run]
            pos += run
            continue
        length = control >> 5
        if length == 7:
            if pos >= end:
                raise _CorruptBlock("a back-reference is cut off at the end of the block")
            length += block[pos]
            pos += 1
        length += 2
        if pos >= end:
            raise _CorruptBlock("a back-reference is cut off at the end of the block")
        distance = ((control & 0x1F) << 8) + block[pos] + 1
        pos += 1
        start = len(out) - distance
        if start < 0:
            raise _CorruptBlock(f"a back-reference at byte {pos - 2} points before the start of the data")
        if len(out) + length > size:
            raise _CorruptBlock(f"it decodes to more than the declared {size} bytes")
        if distance >= length:
            out += out[start : start + length]
        else:  # overlapping copy: byte-by-byte copying repeats the last `distance` bytes
            pattern = out[start:]
            out += (pattern * (length // distance + 1))[:length]
    if len(out) != size:
        raise _CorruptBlock(f"it decodes to {len(out)} bytes, but its header declares {size}")
    return bytes(out)


def read_pcd(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a PCL point-cloud file (PCD v0.5/v0.7) with ``DATA ascii``, ``binary`` or ``binary_compressed``.

    The header must give ``FIELDS`` (with ``x``, ``y`` and ``z``) and ``DATA``; binary data also need
    ``SIZE`` and ``TYPE``. ``COUNT`` defaults to 1 a field; the number of points is ``POINTS``, else
    ``WIDTH * HEIGHT`` (ascii data without either: the number of rows). Types ``F`` (4 or 8 bytes), ``I`` and
    ``U`` (1, 2, 4 or 8 bytes), little-endian. Fields other than ``x``, ``y``, ``z`` and ``normal_x``,
    ``normal_y``, ``normal_z`` (rgb, curvature, intensity, padding ``_`` ...) are skipped. ``VIEWPOINT`` is
    not applied, as PCL does not apply it either.

    Points with a NaN coordinate (PCL's "no return" in organised clouds) are dropped, and how many is logged.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    points : (n, 3) float64
        Point coordinates in the file's units, n >= 1, all finite.
    normals : (n, 3) float64 or None
        Per-point normals of the kept points as stored in the file, all finite; None if the file has no
        ``normal_x``/``normal_y``/``normal_z`` fields or if any kept point's normal is not finite.

    Raises
    ------
    PartFileError
        For a missing, unreadable or empty file, a header without ``DATA``, ``FIELDS`` or x/y/z fields, an
        inconsistent header, an unknown ``DATA`` kind, truncated binary data, a corrupt compressed block, a
        value that is not a number (with its line), an infinite coordinate, or no finite point at all.
    """
    return parse_pcd(_read_bytes(path), path)


def _header_ints(path: str | os.PathLike, key: str, values: list[str], line: int, minimum: int) -> list[int]:
    try:
        numbers = [int(value) for value in values]
    except ValueError:
        numbers = None
    if numbers is None or any(number < minimum for number in numbers):
        raise PartFileError(path, f"header line {line}: {key} needs whole numbers >= {minimum}")
    return numbers


def _check_one_per_field(path: str | os.PathLike, key: str, values: list, line: int, names: list[str]) -> None:
    if len(values) != len(names):
        raise PartFileError(path, f"header line {line}: {key} has {len(values)} values for {len(names)} fields")


def _parse_pcd_header(path: str | os.PathLike, data: bytes) -> tuple[dict[str, tuple[list[str], int]], str, int, int]:
    """Split off the header: its entries by keyword, the DATA kind, where data start, and their line."""
    entries: dict[str, tuple[list[str], int]] = {}
    pos = 0
    line = 0
    while pos < len(data):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        words = data[pos:end].decode("latin-1").split()
        pos = end + 1
        line += 1
        if not words or words[0].startswith("#"):
            continue
        key = words[0].upper()
        if key == "DATA":
            kind = words[1].lower() if len(words) > 1 else ""
            if kind not in _PCD_KINDS:
                shown = _show(words[1].encode("latin-1")) if len(words) > 1 else "nothing"
                raise PartFileError(
                    path,
                    f"header line {line}: unknown DATA kind {shown} (expected ascii, binary or binary_compressed)",
                )
            return entries, kind, min(pos, len(data)), line + 1
        entries[key] = (words[1:], line)
    raise PartFileError(path, "not a PCD file: the header has no DATA line")


def parse_pcd(data: bytes, path: str | os.PathLike = "<bytes>") -> tuple[np.ndarray, np.ndarray | None]:
    """Parse the bytes of a PCD file; see :func:`read_pcd` for the format and the results.

    Parameters
    ----------
    data : bytes
        The whole file.
    path : str or os.PathLike
        The file's name, used in error messages only.

    Returns
    -------
    points : (n, 3) float64
        Point coordinates in the file's units.
    normals : (n, 3) float64 or None
        Per-point normals, or None.
    """
    data = data.removeprefix(_BOM)
    if not data.strip():
        raise PartFileError(path, "file is empty")
    entries, kind, data_start, data_line = _parse_pcd_header(path, data)

    if "FIELDS" in entries:
        names, names_line = entries["FIELDS"]
    elif "COLUMNS" in entries:  # PCD v0.5 spelling
        names, names_line = entries["COLUMNS"]
    else:
        raise PartFileError(path, "header has no FIELDS line")
    if not names:
        raise PartFileError(path, f"header line {names_line}: FIELDS names no field")
    missing = [name for name in _XYZ_NAMES if name not in names]
    if missing:
        raise PartFileError(path, f"header FIELDS has no {', '.join(missing)} field: x, y and z are required")

    counts = [1] * len(names)
    if "COUNT" in entries:
        values, line = entries["COUNT"]
        counts = _header_ints(path, "COUNT", values, line, 1)
        _check_one_per_field(path, "COUNT", counts, line, names)
    sizes: list[int] | None = None
    types: list[str] | None = None
    if "SIZE" in entries:
        values, line = entries["SIZE"]
        sizes = _header_ints(path, "SIZE", values, line, 1)
        _check_one_per_field(path, "SIZE", sizes, line, names)
    if "TYPE" in entries:
        values, line = entries["TYPE"]
        types = [value.upper() for value in values]
        _check_one_per_field(path, "TYPE", types, line, names)
        for index, letter in enumerate(types):
            if letter not in _PCD_SIZES:
                shown = _show(values[index].encode("latin-1"))
                raise PartFileError(path, f"header line {line}: unknown TYPE {shown} (expected F, I or U)")
            if sizes is not None and sizes[index] not in _PCD_SIZES[letter]:
                raise PartFileError(
                    path,
                    f"header line {line}: field {names[index]} of TYPE {letter} cannot have SIZE {sizes[index]}",
                )
    if kind != "ascii" and (sizes is None or types is None):
        missing_key = "SIZE" if sizes is None else "TYPE"
        raise PartFileError(path, f"header has no {missing_key} line, needed for {kind} data")

    wanted = {name: names.index(name) for name in _XYZ_NAMES}
    for name, index in wanted.items():
        if counts[index] != 1:
            raise PartFileError(path, f"header: field {name} has COUNT {counts[index]}, expected 1")
    normal_fields = _NORMAL_NAMES[1]
    has_normals = all(name in names for name in normal_fields) and all(
        counts[names.index(name)] == 1 for name in normal_fields
    )
    if has_normals:
        wanted.update({name: names.index(name) for name in normal_fields})

    points_declared: int | None = None
    if "POINTS" in entries:
        values, line = entries["POINTS"]
        if len(values) != 1:
            raise PartFileError(path, f"header line {line}: POINTS needs one whole number")
        points_declared = _header_ints(path, "POINTS", values, line, 0)[0]
    elif "WIDTH" in entries and "HEIGHT" in entries:
        (width_values, width_line), (height_values, height_line) = entries["WIDTH"], entries["HEIGHT"]
        if len(width_values) != 1 or len(height_values) != 1:
            raise PartFileError(path, f"header line {width_line}: WIDTH and HEIGHT need one whole number each")
        width = _header_ints(path, "WIDTH", width_values, width_line, 0)[0]
        height = _header_ints(path, "HEIGHT", height_values, height_line, 0)[0]
        points_declared = width * height
    elif kind != "ascii":
        raise PartFileError(path, "header has no POINTS (nor WIDTH and HEIGHT) line")
    if points_declared == 0:
        raise PartFileError(path, "no points: the header declares 0 points")

    body = data[data_start:]
    if kind == "ascii":
        columns, lines = _pcd_ascii(path, body, data_line, counts, wanted, points_declared)
    else:
        assert sizes is not None and types is not None
        columns = _pcd_binary(path, body, kind, points_declared, sizes, types, counts, wanted)
        lines = None
    return _pcd_result(path, columns, lines, has_normals)


def _pcd_ascii(
    path: str | os.PathLike,
    body: bytes,
    first_line: int,
    counts: list[int],
    wanted: dict[str, int],
    points_declared: int | None,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Columns of the wanted fields (each (n,) float64) from ascii PCD data."""
    values, lines = _parse_table(path, body.translate(_SEPARATORS), first_line)
    if values.shape[0] == 0:
        raise PartFileError(path, "no points: the DATA section is empty")
    total = sum(counts)
    if values.shape[1] != total:
        raise PartFileError(
            path,
            f"line {lines[0]}: {values.shape[1]} values, but the header's FIELDS and COUNT describe {total}",
        )
    if points_declared is not None and values.shape[0] != points_declared:
        raise PartFileError(path, f"header declares {points_declared} points but the data has {values.shape[0]} rows")
    offsets = np.concatenate([[0], np.cumsum(counts)])
    columns = {name: values[:, int(offsets[index])] for name, index in wanted.items()}
    return columns, lines


def _pcd_binary(
    path: str | os.PathLike,
    body: bytes,
    kind: str,
    n: int,
    sizes: list[int],
    types: list[str],
    counts: list[int],
    wanted: dict[str, int],
) -> dict[str, np.ndarray]:
    """Columns of the wanted fields (each (n,) float64) from binary or binary_compressed PCD data."""
    widths = [size * count for size, count in zip(sizes, counts)]
    record = sum(widths)
    offsets = [0, *itertools.accumulate(widths)][:-1]  # byte offset of each field in a record
    need = n * record
    if kind == "binary":
        if len(body) < need:
            raise PartFileError(
                path,
                f"binary data is truncated: {n} points of {record} bytes need {need} bytes, the file has {len(body)}",
            )
        buffer = body
        starts, steps = offsets, [record] * len(widths)  # row-major records
    else:
        if len(body) < 8:
            raise PartFileError(
                path,
                f"compressed data is truncated: expected an 8-byte size header, the file has {len(body)} bytes",
            )
        compressed, uncompressed = struct.unpack_from("<II", body)
        if compressed > len(body) - 8:
            raise PartFileError(
                path,
                f"compressed data is truncated: expected {compressed} bytes, the file has {len(body) - 8}",
            )
        if uncompressed != need:
            raise PartFileError(
                path,
                f"compressed block is corrupt: it declares {uncompressed} bytes, but {n} points of {record} "
                f"bytes need {need}",
            )
        try:
            buffer = _lzf_decompress(body[8 : 8 + compressed], uncompressed)
        except _CorruptBlock as exc:
            raise PartFileError(path, f"compressed block is corrupt: {exc}") from None
        starts, steps = [n * offset for offset in offsets], widths  # column-major: field after field
    columns = {}
    for name, index in wanted.items():
        dtype = np.dtype(f"<{_PCD_DTYPE_KIND[types[index]]}{sizes[index]}")
        view = np.ndarray((n,), dtype=dtype, buffer=buffer, offset=starts[index], strides=(steps[index],))
        columns[name] = view.astype(np.float64)
    return columns


def _pcd_result(
    path: str | os.PathLike, columns: dict[str, np.ndarray], lines: np.ndarray | None, has_normals: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    """Drop NaN points, reject infinities, and assemble ``(points, normals)``."""
    points = np.column_stack([columns[name] for name in _XYZ_NAMES])
    nan = np.isnan(points).any(axis=1)
    infinite = np.isinf(points).any(axis=1)
    if infinite.any():
        row = int(np.argmax(infinite))
        where = f"line {lines[row]}" if lines is not None else f"point {row + 1} of {len(points)}"
        raise PartFileError(path, f"{where}: infinite coordinate")
    keep = ~nan
    kept = int(keep.sum())
    if kept == 0:
        raise PartFileError(path, f"no points: all {len(points)} points have NaN coordinates")
    if kept < len(points):
        logger.info("%s: dropped %d of %d points with NaN coordinates", path, len(points) - kept, len(points))
        points = points[keep]
    normals = None
    if has_normals:
        normals = np.column_stack([columns[name] for name in _NORMAL_NAMES[1]])[keep]
        if not np.isfinite(normals).all():
            bad = int((~np.isfinite(normals).all(axis=1)).sum())
            logger.warning("%s: %d points have NaN or infinite normals; ignoring the file's normals", path, bad)
            normals = None
    return np.ascontiguousarray(points), None if normals is None else np.ascontiguousarray(normals)
