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
    except ValueError as exc:  # an embedded NUL byte
        raise make(name, f"not a usable file name ({exc})") from None
    except OSError as exc:
        raise make(name, f"not a usable file ({exc.strerror or exc})") from None
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


# ------------------------------------------------------------------------------------------------ bounds of work
#: Largest amounts of work a setting may ask for (issue 13: no setting may ask for more time or memory than a
#: two-core, 24 GiB machine has). Each is far above the real cases: a whole car body (about 12 m^2) at a 40 mm
#: spacing and 5 mm steps makes about 500 layers and 60 000 waypoints; the DTC hull about 300 layers.
#: Slicing planes of one part (``paths.layers``, or the part's extent / ``paths.spacing_mm``).
MAX_LAYERS = 10_000
#: Waypoints of one part's strokes: 5e6 take about half a minute to slice and far longer to solve and film
#: (a whole car body at 0.5 mm steps stays below).
MAX_WAYPOINTS = 5_000_000
#: Random candidates of the even target sampling, and points of the DFS filling (24 bytes each, plus pairs).
MAX_CANDIDATES = 20_000_000
#: Surface or gun samples of one film simulation.
MAX_FILM_SAMPLES = 20_000_000
#: Edge passes past each of the first and the last layer (``paths.edge_passes``; auto gives 1 to 3).
MAX_EDGE_PASSES = 100
#: Points per section piece (``paths.points_per_section``; seed 003 samples a few tens).
MAX_POINTS_PER_SECTION = 100_000
#: Random measuring points of a film report (``output.samples``, ``simulate --samples``; seed 003: 420).
MAX_REPORT_SAMPLES = 1_000_000
#: Smallest step between waypoints or film samples, mm (a robot repeats to about 0.03 mm).
MIN_STEP_MM = 0.01
#: Largest coordinate of a part, mm (10 km): beyond it a part is in the wrong unit or broken, and products of
#: coordinates in the normals and covariances overflow or lose every digit.
MAX_COORDINATE_MM = 1e7


def check_at_most(value, limit, name: str) -> None:
    """Raise a one-line :class:`ConfigError` ``"{name} must be at most {limit}, got {value}"`` when value > limit."""
    if value is not None and value > limit:
        raise ConfigError(f"{name} must be at most {number_text(limit)}, got {value!r}")


def check_work(count: float, limit: float, what: str, setting: str, value, part: str = "", fix: str = "") -> None:
    """Raise a one-line :class:`ConfigError` when a setting would make more than ``limit`` of something.

    ``count`` is the estimated number of ``what`` (layers, waypoints, candidates) that ``setting = value`` makes
    on the part (``part``: a few words on its size); ``fix`` says which value is accepted, e.g.
    ``"use paths.step_mm >= 0.5"``. The message reads ``"paths.step_mm 1e-09 would make 4.2e+12 waypoints on
    this part (2635 x 1959 mm) (at most 2e+07): use paths.step_mm >= 0.5"``.
    """
    if not count <= limit:  # also NaN
        on = f" on this part ({part})" if part else ""
        tail = f": {fix}" if fix else ""
        shown = f"{value:.4g}" if isinstance(value, float) else repr(value)
        raise ConfigError(f"{setting} {shown} would make {count:.3g} {what}{on} (at most {limit:.3g}){tail}")


def size_text(points) -> str:
    """The size of a point set's bounding box, e.g. ``"2635 x 1959 x 340 mm"``."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if not len(pts):
        return "empty"
    size = pts.max(axis=0) - pts.min(axis=0)
    return " x ".join(f"{s:.4g}" for s in size) + " mm"


def check_poses(poses, name: str = "poses", *, tol: float = 1e-3, allow_nan: bool = False) -> np.ndarray:
    """A float64 ``(n, 4, 4)`` copy of homogeneous poses after checking each is a rigid motion.

    Each pose must hold finite numbers, a rotation block with orthonormal columns and determinant +1 (to
    ``tol``), and a last row ``0 0 0 1``; a single ``(4, 4)`` pose is taken as one row. A bad pose is a
    :class:`DataError` naming ``name`` and the row (``"poses row 3: the rotation has determinant -1 (a
    mirror), not +1"``). With ``allow_nan``, rows holding a NaN or inf are left as they are (inverse kinematics
    reports them as unreachable rows) and only the finite rows are checked.
    """
    try:
        out = np.array(poses, dtype=np.float64, copy=True)
    except (TypeError, ValueError):
        raise DataError(
            f"{name} must be (n, 4, 4) poses of finite numbers, got something that is not numbers"
        ) from None
    if out.shape == (4, 4):
        out = out[None]
    if out.ndim != 3 or out.shape[1:] != (4, 4):
        raise DataError(f"{name} must be (n, 4, 4) poses, got shape {out.shape}")
    finite = np.isfinite(out).all(axis=(1, 2))
    if not finite.all() and not allow_nan:
        raise DataError(f"{name} row {int(np.argmin(finite))}: NaN or inf in the pose")
    rot = out[:, :3, :3]
    with np.errstate(invalid="ignore", over="ignore"):  # rows with NaN give NaN here and are left out by `finite`
        gram = np.abs(np.matmul(rot.transpose(0, 2, 1), rot) - np.eye(3)).max(axis=(1, 2), initial=0.0)
        # det R = r0 . (r1 x r2) over the columns, in closed form (np.linalg.det factorises every matrix)
        det = np.einsum("ni,ni->n", rot[:, :, 0], np.cross(rot[:, :, 1], rot[:, :, 2]))
        bottom = np.abs(out[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1, initial=0.0)
        bad = ((gram > tol) | (np.abs(det - 1.0) > tol) | (bottom > tol)) & finite
    if bad.any():
        row = int(np.argmax(bad))
        if gram[row] <= tol and det[row] < 0:
            problem = f"the rotation has determinant {det[row]:.6g} (a mirror), not +1"
        elif gram[row] > tol or abs(det[row] - 1.0) > tol:
            problem = f"the rotation is not orthonormal (|R^T R - I| = {gram[row]:.3g}, det {det[row]:.6g})"
        else:
            problem = f"the last row must be 0 0 0 1, got {' '.join(f'{v:g}' for v in out[row, 3])}"
        raise DataError(f"{name} row {row}: {problem}")
    return out


def round_up(value: float) -> str:
    """``value`` rounded up to two significant digits, as text: the value a bound's message asks for."""
    if not value > 0:
        return "0"
    scale = 10.0 ** (math.floor(math.log10(value)) - 1)
    return f"{float(f'{math.ceil(value / scale - 1e-9) * scale:.2g}'):g}"


def number_text(value) -> str:
    """A bound as text: whole numbers in full (``1000000``), others by ``:g``."""
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e15 else f"{value:g}"
