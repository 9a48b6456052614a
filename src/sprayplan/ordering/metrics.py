"""Distances and tour lengths: the checked inputs every tour solver of :mod:`sprayplan.ordering` shares.

Conventions
-----------
A *tour* over ``n`` points is an ``(n,)`` int permutation of ``range(n)``. ``closed=True`` means the tour
returns from its last point to its first, and its length includes that closing edge; ``closed=False`` is an
open path. Two metrics are known:

- ``"euclidean"``: the straight-line distance (a robot tool moving in a straight line);
- ``"manhattan"``: the sum of the absolute coordinate differences (seed 000 s5.1.3: a gantry whose axes are
  driven by separate motors, so that a move costs the travel of each axis added up).

Every function is pure. Bad arrays raise :class:`~sprayplan.errors.InputError`, bad options
:class:`~sprayplan.errors.ConfigError`.
"""

from __future__ import annotations

import math

import numpy as np

from sprayplan.checks import check_points
from sprayplan.errors import ConfigError, InputError

METRICS = ("euclidean", "manhattan")


def check_metric(metric: str) -> str:
    """``metric`` after checking it is one of :data:`METRICS`; raises ConfigError otherwise."""
    if metric not in METRICS:
        raise ConfigError(f"metric must be one of {METRICS}, got {metric!r}")
    return metric


def pair_distances(a: np.ndarray, b: np.ndarray, metric: str = "euclidean") -> np.ndarray:
    """Distances between matching rows of two point arrays.

    Parameters
    ----------
    a, b : (..., d) float
        Points, broadcast against each other.
    metric : {"euclidean", "manhattan"}

    Returns
    -------
    distances : (...) float
    """
    diff = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if check_metric(metric) == "manhattan":
        return np.abs(diff).sum(axis=-1)
    return np.sqrt(np.einsum("...i,...i->...", diff, diff))


def distance_matrix(points, metric: str = "euclidean") -> np.ndarray:
    """The full matrix of distances between points.

    Parameters
    ----------
    points : (n, 2) or (n, 3) float
    metric : {"euclidean", "manhattan"}

    Returns
    -------
    matrix : (n, n) float
        Symmetric, zero on the diagonal. Built in row blocks so that the temporary arrays stay small.
    """
    pts = check_points(points, dim=(2, 3), empty_list=True)
    check_metric(metric)
    n = len(pts)
    out = np.empty((n, n))
    block = max(1, 2_000_000 // max(1, n * pts.shape[1]))
    for lo in range(0, n, block):
        out[lo : lo + block] = pair_distances(pts[lo : lo + block, None, :], pts[None, :, :], metric)
    np.fill_diagonal(out, 0.0)
    return out


def check_order(order, n: int, name: str = "order") -> np.ndarray:
    """``order`` as an int array after checking it is a permutation of ``range(n)``; raises InputError."""
    arr = np.asarray(order)
    if arr.ndim != 1 or len(arr) != n:
        raise InputError(f"{name} must have shape ({n},), got {arr.shape}")
    if n and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{name} must hold integers, got dtype {arr.dtype}")
    arr = arr.astype(np.intp)
    if n and not np.array_equal(np.sort(arr), np.arange(n)):
        raise InputError(f"{name} must be a permutation of range({n})")
    return arr


def tour_length(points, order, closed: bool = True, metric: str = "euclidean") -> float:
    """Length of a tour (or an open path) through points in a given order.

    Parameters
    ----------
    points : (n, 2) or (n, 3) float
    order : (n,) int
        A permutation of ``range(n)``.
    closed : bool
        Whether the length includes the edge from the last point back to the first.
    metric : {"euclidean", "manhattan"}

    Returns
    -------
    length : float
        In the unit of the coordinates. 0 for fewer than two points.
    """
    pts = check_points(points, dim=(2, 3), empty_list=True)
    idx = check_order(order, len(pts))
    if len(idx) < 2:
        return 0.0
    seq = pts[idx]
    length = float(pair_distances(seq[1:], seq[:-1], metric).sum())
    if closed:
        length += float(pair_distances(seq[0], seq[-1], metric))
    return length


def matrix_path_length(dist: np.ndarray, order: np.ndarray, closed: bool) -> float:
    """Length of a tour given by ``order`` on a distance matrix (no checks: internal use)."""
    if len(order) < 2:
        return 0.0
    length = float(dist[order[:-1], order[1:]].sum())
    if closed:
        length += float(dist[order[-1], order[0]])
    return length


def check_ends(n: int, closed: bool, start, end) -> tuple[int | None, int | None]:
    """``start`` and ``end`` as ints (or None) after checking they are valid indices of ``n`` points.

    Raises
    ------
    ConfigError
        If an index is not an integer in ``[0, n)``, or ``start == end`` with more than one point (with one
        point, ``start == end == 0`` is accepted and returned as ``(0, None)``).
    """
    out = []
    for name, value in (("start", start), ("end", end)):
        if value is None:
            out.append(None)
            continue
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise ConfigError(f"{name} must be an integer index or None, got {value!r}")
        if not 0 <= int(value) < n:
            raise ConfigError(f"{name} must be an index in [0, {n}), got {value}")
        out.append(int(value))
    if out[0] is not None and out[0] == out[1]:
        if n == 1:
            return out[0], None
        kind = "closed tour" if closed else "open path"
        raise ConfigError(f"start and end must differ for a {kind} of {n} points, both are {out[0]}")
    return out[0], out[1]


def check_time_limit(time_limit_s) -> float | None:
    """``time_limit_s`` as a float (or None) after checking it is a positive number of seconds."""
    if time_limit_s is None:
        return None
    try:
        value = float(time_limit_s)
    except (TypeError, ValueError):
        raise ConfigError(f"time_limit_s must be a positive number of seconds or None, got {time_limit_s!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"time_limit_s must be a positive number of seconds or None, got {time_limit_s!r}")
    return value


def check_distance_matrix(dist, name: str = "dist") -> np.ndarray:
    """A float copy of ``dist`` after checking it is a square, finite, non-negative, symmetric matrix."""
    out = np.array(dist, dtype=float, copy=True)
    if out.ndim != 2 or out.shape[0] != out.shape[1]:
        raise InputError(f"{name} must be a square (n, n) matrix, got shape {out.shape}")
    if not np.all(np.isfinite(out)) or np.any(out < 0):
        raise InputError(f"{name} must hold finite, non-negative distances")
    if not np.allclose(out, out.T, rtol=1e-12, atol=0.0):
        raise InputError(f"{name} must be symmetric (the tour solvers assume d(a, b) == d(b, a))")
    return out
