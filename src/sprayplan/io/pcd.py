"""PCL's PCD point-cloud files: ascii, binary and binary_compressed (with an LZF decoder).

The reader returns the points in the file's own units and the per-point normals when the file stores them;
any broken input raises :class:`~sprayplan.errors.PartFileError` with a one-line message that names the file
(see :mod:`sprayplan.io.cloud`, whose helpers it shares).

Decisions worth knowing
-----------------------
* NaN coordinates are PCL's "no return" marker in organised clouds; such points are dropped and the count is
  logged. Infinite coordinates are an error.
* A kept point whose normal is NaN, infinite or of zero length is an error naming its line (ascii) or its
  index (binary): a normal the file gives is trusted as the surface's direction, so one without a direction
  cannot be used (PCL marks failed normal estimation with NaN; remove those points or the normal fields).
"""

from __future__ import annotations

import itertools
import logging
import os
import struct

import numpy as np

from sprayplan.checks import first_bad_normal
from sprayplan.errors import PartFileError
from sprayplan.io.cloud import _BOM, _NORMAL_NAMES, _SEPARATORS, _XYZ_NAMES, _parse_table, _show, read_file_bytes

__all__ = ["parse_pcd", "read_pcd"]

logger = logging.getLogger(__name__)

_PCD_KINDS = ("ascii", "binary", "binary_compressed")
_PCD_SIZES = {"F": (4, 8), "I": (1, 2, 4, 8), "U": (1, 2, 4, 8)}
_PCD_DTYPE_KIND = {"F": "f", "I": "i", "U": "u"}


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
    return parse_pcd(read_file_bytes(path), path)


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
        normals = np.column_stack([columns[name] for name in _NORMAL_NAMES[1]])
        row = first_bad_normal(normals[keep])
        if row is not None:
            row = int(np.flatnonzero(keep)[row])  # in the file's numbering, dropped points included
            where = f"line {lines[row]}" if lines is not None else f"point {row + 1} of {len(keep)}"
            what = "NaN or infinite" if not np.isfinite(normals[row]).all() else "zero-length"
            raise PartFileError(path, f"{where}: {what} normal, so no direction")
        normals = normals[keep]
    return np.ascontiguousarray(points), None if normals is None else np.ascontiguousarray(normals)
