"""Point-cloud readers: text XYZ files here, PCL's PCD files (ascii, binary, binary_compressed) in ``pcd``.

Both readers return the points in the file's own units (no scaling here) and the per-point normals when the
file stores them. Any broken input raises :class:`~sprayplan.errors.PartFileError` with a one-line message
that names the file and, for text, the line; nothing else escapes, whatever the bytes. The helpers shared by
both (reading the bytes, tokens, numeric tables, column names) live here.

Written here rather than taken from a library because the checks are the point: a truncated binary block, a
corrupt LZF stream, a stray word in line 70,000 of a text file must each say what is wrong and where.

Decisions worth knowing
-----------------------
* XYZ: a NaN or infinite value in a column that is used (x, y, z or a normal) is an error with its line
  number; values in ignored columns are not checked.
* XYZ and PCD: a stored normal of zero length (below ``checks.MIN_NORMAL_LENGTH``) or with a NaN or infinite
  component is an error naming the line (or, in binary PCD, the point).
* XYZ with exactly 6 numeric columns and no header: columns 3-5 are taken as normals when at least
  ``NORMAL_SHARE`` of the rows have unit length within 1e-3 (the rest are then bad normals: an error naming
  the first one's line); otherwise they are ignored (they may be colours or anything else).
* PCD: see :mod:`sprayplan.io.pcd`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sprayplan.checks import check_input_file, first_bad_normal
from sprayplan.errors import PartFileError

__all__ = ["parse_xyz", "read_xyz"]

_BOM = b"\xef\xbb\xbf"
# Separators other than space and newline become spaces; after this, a token is a run of other bytes.
_SEPARATORS = bytes.maketrans(b"\t,\r\x0b\x0c", b"     ")
_UNIT_TOLERANCE = 1e-3
_XYZ_NAMES = ("x", "y", "z")
_NORMAL_NAMES = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"))


# --------------------------------------------------------------------------------------------------------
# shared helpers


def read_file_bytes(path: str | os.PathLike) -> bytes:
    """Read a whole input file, turning every reason it cannot be read into a PartFileError.

    Every reader of an input file goes through here (or through :func:`sprayplan.checks.check_input_file`,
    which this calls first): a folder, a named pipe, a socket or a device is refused by ``os.stat`` before
    anything opens it, so a FIFO given as a part cannot block the command.
    """
    name = check_input_file(path)
    try:
        return Path(name).read_bytes()
    except FileNotFoundError:  # removed between the check and the read
        raise PartFileError(name, "no such file (file not found)") from None
    except IsADirectoryError:
        raise PartFileError(name, "is a folder (directory), not a regular file") from None
    except PermissionError:
        raise PartFileError(name, "cannot read the file: permission denied") from None
    except OSError as exc:
        raise PartFileError(name, f"cannot read the file ({exc.strerror or exc})") from None
    except MemoryError:
        raise PartFileError(name, "the file is too large to read into memory") from None


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


#: Share of the rows of a headerless 6-column XYZ file whose columns 3-5 must have unit length for those columns
#: to be read as normals (so that one broken normal is reported, not taken for colours).
NORMAL_SHARE = 0.9


def _mostly_unit_length(vectors: np.ndarray) -> bool:
    """True if at least ``NORMAL_SHARE`` of the rows of ``vectors`` (n, 3) are finite with length 1 within
    ``_UNIT_TOLERANCE``."""
    with np.errstate(over="ignore", invalid="ignore"):
        lengths = np.sqrt(np.einsum("ij,ij->i", vectors, vectors))
        return bool(np.mean(np.abs(lengths - 1.0) <= _UNIT_TOLERANCE) >= NORMAL_SHARE)


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
    return parse_xyz(read_file_bytes(path), path)


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
    elif columns == 6 and _mostly_unit_length(values[:, 3:6]):
        normal_cols = [3, 4, 5]

    used = coords + (normal_cols or [])
    _check_finite(path, values[:, used], lines)
    points = np.ascontiguousarray(values[:, coords])
    normals = None if normal_cols is None else np.ascontiguousarray(values[:, normal_cols])
    if normals is not None:
        row = first_bad_normal(normals)
        if row is not None:
            raise PartFileError(path, f"line {lines[row]}: the normal has zero length, so no direction")
    return points, normals
