"""Checks of the arrays and numbers handed to sprayplan's functions: one message for one fault.

A bad point array (not numbers, the wrong shape, NaN or inf, too few points) is a :class:`DataError` that
names the argument and the shape it must have; a size that must be a positive number is a
:class:`ConfigError`.
"""

from __future__ import annotations

import math
import os
import stat

import numpy as np

from sprayplan.errors import ConfigError, DataError, PartFileError


def _allowed(dim) -> tuple[int, ...] | None:
    return None if dim is None else (dim,) if isinstance(dim, int) else tuple(dim)


def check_points(
    points, name: str = "points", dim: int | tuple[int, ...] | None = 3, min_count: int = 0, *, empty_list: bool = False
) -> np.ndarray:
    """A new float64 ``(n, d)`` array of ``points`` after checking it holds ``min_count`` or more finite points.

    Parameters
    ----------
    points : array_like, (n, d)
    name : str
        The argument's name, for the message.
    dim : int, tuple of int or None
        The allowed numbers of coordinates ``d`` (None: any).
    min_count : int
        The fewest points allowed (0: an empty ``(0, d)`` array is fine).
    empty_list : bool
        Also take an empty 1-D input (``[]``) as zero points of the first allowed dimension.

    Returns
    -------
    (n, d) float64
        A copy: the caller may write to it.

    Raises
    ------
    DataError
        ``"{name} must be an {shape} array of finite numbers, got ..."``: not numbers, another shape, a NaN
        or inf, or fewer than ``min_count`` points.
    """
    allowed = _allowed(dim)
    shape = "(n, d)" if allowed is None else " or ".join(f"(n, {d})" for d in allowed)

    def fault(got: str) -> DataError:
        need = f" with at least {min_count} point{'s' * (min_count != 1)}" if min_count > 0 else ""
        return DataError(f"{name} must be an {shape} array of finite numbers{need}, got {got}")

    try:
        out = np.array(points, dtype=np.float64, copy=True)
    except (TypeError, ValueError):
        raise fault("something that is not numbers") from None
    if empty_list and out.ndim == 1 and out.size == 0:
        out = out.reshape(0, allowed[0] if allowed else 0)
    if out.ndim != 2 or out.shape[1] not in (allowed or range(1, out.shape[1] + 1)):
        raise fault(f"shape {out.shape}")
    if not np.isfinite(out).all():
        raise fault("NaN or inf")
    if len(out) < min_count:
        raise fault(f"{len(out)} point" + ("" if len(out) == 1 else "s"))
    return out


def check_positive(value, name: str) -> float:
    """``value`` as a float after checking it is a finite number > 0; :class:`ConfigError` naming ``name``."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(out) and out > 0):
        raise ConfigError(f"{name} must be a positive number, got {value!r}")
    return out


def check_count(value, name: str, least: int) -> int:
    """``value`` as an int after checking it is a whole number >= ``least``; :class:`ConfigError` naming ``name``."""
    if isinstance(value, bool) or int(value) != value or value < least:
        raise ConfigError(f"{name} must be an integer >= {least}, got {value!r}")
    return int(value)


#: Smallest time factor of a waypoint (``Stroke.dwell``) the speed tuning may choose, and 1 / this the largest:
#: a gun 20 times faster or slower than planned is a different plan, not a correction.
MIN_DWELL = 0.05


def check_dwell_bounds(min_dwell, max_dwell, where: str = "") -> None:
    """Raise a one-line ``ConfigError`` unless ``MIN_DWELL <= min_dwell <= 1 <= max_dwell <= 1 / MIN_DWELL``
    (the bounds of the speed tuning's time factors); ``where`` starts the message (a config section)."""
    if not (MIN_DWELL <= min_dwell <= 1.0 <= max_dwell <= 1.0 / MIN_DWELL):
        lead = f"{where}: " if where else ""
        raise ConfigError(
            f"{lead}need {MIN_DWELL} <= min_dwell <= 1 <= max_dwell <= {1 / MIN_DWELL:g}, got {min_dwell}, {max_dwell}"
        )


def check_input_file(path, error=None) -> str:
    """``path`` as a str after checking, with ``os.stat`` and before anything opens it, that it is a regular file.

    A folder, a named pipe (opening one for reading blocks until a writer comes, so a FIFO given as a part
    would hang the command), a socket or a device is refused. Symbolic links are followed.

    Parameters
    ----------
    path : str or os.PathLike
        An input file.
    error : callable (path, problem) -> Exception, optional
        The exception to raise; :class:`~sprayplan.errors.PartFileError` by default.

    Raises
    ------
    PartFileError
        ``"{path}: no such file"``, ``"... is a folder, not a file"``, ``"... is a named pipe, not a regular
        file"`` (and the same for sockets and devices), ``"... permission denied"`` or another OS reason.
    """
    make = PartFileError if error is None else error
    try:
        name = os.fspath(path)
    except TypeError:
        raise make(str(path), "not a file name") from None
    try:
        info = os.stat(name)
    except FileNotFoundError:
        raise make(name, "no such file (file not found)") from None
    except PermissionError:
        raise make(name, "cannot read the file: permission denied") from None
    except (OSError, ValueError) as exc:  # ValueError: an embedded NUL byte
        reason = getattr(exc, "strerror", None) or exc
        raise make(name, f"not a usable file ({reason})") from None
    mode = info.st_mode
    if stat.S_ISREG(mode):
        return name
    if stat.S_ISDIR(mode):
        kind = "is a folder (directory)"
    elif stat.S_ISFIFO(mode):
        kind = "is a named pipe (FIFO)"
    elif stat.S_ISSOCK(mode):
        kind = "is a socket"
    elif stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        kind = "is a device"
    else:
        kind = "is not a regular file"
    raise make(name, f"{kind}, not a regular file")


#: A normal stored in a file shorter than this (or not finite) has no direction.
MIN_NORMAL_LENGTH = 1e-9


def first_bad_normal(normals: np.ndarray) -> int | None:
    """The index of the first normal of zero (below ``MIN_NORMAL_LENGTH``) or non-finite length, or None."""
    with np.errstate(over="ignore", invalid="ignore"):
        length = np.sqrt(np.einsum("ij,ij->i", normals, normals))
    bad = ~(np.isfinite(length) & (length >= MIN_NORMAL_LENGTH))
    return int(np.argmax(bad)) if bad.any() else None
