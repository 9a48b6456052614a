"""Feature points and segmentation of a section polyline: one-sided derivatives (seed 003, section 2.1.3).

Conventions as in :mod:`sprayplan.paths.polyline` (``(n, 3)`` mm arrays, ``closed`` polylines do not repeat
their first point, radians). The PDF extraction of seed 003 lost primes and minus signs; each docstring says
how its equation was read.
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np

from sprayplan.checks import check_points
from sprayplan.errors import ConfigError
from sprayplan.paths.polyline import _check_angle, _norm


def _backward_difference(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """d/ds at p0 from p0 and the two points p1, p2 behind it (arc length by chords); NaN on zero chords."""
    h1 = _norm(p0 - p1)[:, None]
    h2 = _norm(p1 - p2)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        q1 = (p0 - p1) / h1
        q2 = (p1 - p2) / h2
        out = q1 + (q1 - q2) * (h1 / (h1 + h2))
    out[((h1 == 0) | (h2 == 0))[:, 0]] = np.nan
    return out


def _chord_difference(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    h = _norm(p0 - p1)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (p0 - p1) / h
    out[(h == 0)[:, 0]] = np.nan
    return out


def one_sided_derivatives(points, closed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Backward and forward tangents with respect to arc length (seed 003, section 2.1.3, eqs. 9-10).

    The printed eqs. 9-10 are garbled beyond recovery (the numerators mix the chords ``P_{j-1} - P_{j-2}`` and
    ``P_j - P_{j-2}``, the denominators sums of chord lengths and half chord lengths); what they describe, a
    first derivative at ``P_j`` from ``P_j`` and its two previous (eq. 9) or two next (eq. 10) points, is the
    standard one-sided 3-point difference on a non-uniform grid, with arc length measured along the chords.
    With ``h1 = |P_j P_{j-1}|``, ``h2 = |P_{j-1} P_{j-2}|``, ``q1 = (P_j - P_{j-1}) / h1``,
    ``q2 = (P_{j-1} - P_{j-2}) / h2``:

        C'(P_j-) = q1 + (q1 - q2) h1 / (h1 + h2)
                 = P_j (2 h1 + h2) / (h1 (h1 + h2)) - P_{j-1} (h1 + h2) / (h1 h2) + P_{j-2} h1 / (h2 (h1 + h2))

    and with ``h1 = |P_j P_{j+1}|``, ``h2 = |P_{j+1} P_{j+2}|``, ``q1 = (P_{j+1} - P_j) / h1``,
    ``q2 = (P_{j+2} - P_{j+1}) / h2``:

        C'(P_j+) = q1 - (q2 - q1) h1 / (h1 + h2)

    (the derivative at ``P_j`` of the quadratic through the three points; for equal spacing h they reduce to
    ``(3 P_j - 4 P_{j-1} + P_{j-2}) / 2h`` and ``(-3 P_j + 4 P_{j+1} - P_{j+2}) / 2h``). Second-order accurate:
    the error of the unit tangent falls as h^2. Where only one point exists on a side, the chord difference
    ``(P_j - P_{j-1}) / h1`` (or ``(P_{j+1} - P_j) / h1``) is used; where there is none, NaN. A zero-length
    chord also gives NaN (remove duplicates first, e.g. with :func:`streamline`).

    Parameters
    ----------
    points : (n, 3) float, mm
    closed : bool
        Wrap around (needs n >= 3; fewer points are treated as open).

    Returns
    -------
    d_minus, d_plus : (n, 3) float, dimensionless
        Backward and forward tangents, close to unit length.
    """
    pts = check_points(points)
    n = len(pts)
    d_minus = np.full((n, 3), np.nan)
    d_plus = np.full((n, 3), np.nan)
    if closed and n >= 3:
        d_minus = _backward_difference(pts, np.roll(pts, 1, axis=0), np.roll(pts, 2, axis=0))
        d_plus = -_backward_difference(pts, np.roll(pts, -1, axis=0), np.roll(pts, -2, axis=0))
        return d_minus, d_plus
    if n >= 2:
        d_minus[1] = _chord_difference(pts[1:2], pts[0:1])[0]
        d_plus[-2] = _chord_difference(pts[-1:], pts[-2:-1])[0]
    if n >= 3:
        d_minus[2:] = _backward_difference(pts[2:], pts[1:-1], pts[:-2])
        d_plus[:-2] = -_backward_difference(pts[:-2], pts[1:-1], pts[2:])
    return d_minus, d_plus


def feature_points(points, length_threshold: float, angle_threshold_rad: float, closed: bool = False) -> np.ndarray:
    """Indices of sharp points (seed 003, section 2.1.3).

    ``P_j`` is sharp if ``|C'(P_j-) - C'(P_j+)| > L`` and ``angle(C'(P_j-), C'(P_j+)) > alpha``, with the
    one-sided derivatives of :func:`one_sided_derivatives`. Points where either derivative is missing (the ends
    of an open polyline) are never sharp.

    Parameters
    ----------
    points : (n, 3) float, mm
    length_threshold : float, dimensionless
        L >= 0. The derivatives are unit tangents, so ``|d- - d+|`` lies in [0, 2] (``2 sin(theta / 2)`` for a
        turn of theta between straight neighbours).
    angle_threshold_rad : float, rad
        alpha in [0, pi].
    closed : bool

    Returns
    -------
    (k,) int
        Increasing indices of the sharp points.
    """
    pts = check_points(points)
    length = float(length_threshold)
    if not (math.isfinite(length) and length >= 0):
        raise ConfigError(f"length_threshold must be a number >= 0, got {length_threshold!r}")
    angle = _check_angle(angle_threshold_rad, "angle_threshold_rad")
    d_minus, d_plus = one_sided_derivatives(pts, closed=closed)
    valid = np.all(np.isfinite(d_minus), axis=1) & np.all(np.isfinite(d_plus), axis=1)
    dm, dp = d_minus[valid], d_plus[valid]
    gap = _norm(dm - dp)
    theta = np.arctan2(_norm(np.cross(dm, dp)), np.einsum("ij,ij->i", dm, dp))
    return np.flatnonzero(valid)[(gap > length) & (theta > angle)]


def split_at(points, indices, closed: bool = False) -> list[np.ndarray]:
    """Cut a polyline into pieces at the given points (seed 003, section 2.1.3, segmentation).

    Each cut point belongs to both pieces it separates. An open polyline with k interior cut points gives k + 1
    pieces (cuts at the end points are ignored); a closed one with k >= 1 cut points gives k open pieces, the
    last running through the closing segment back to the first cut point (with one cut point, a single piece
    that starts and ends there). Without cut points the polyline is returned whole (one copy).

    Parameters
    ----------
    points : (n, 3) float, mm
    indices : (k,) int
        Indices into ``points``, in any order; repeats are ignored.
    closed : bool

    Returns
    -------
    list of (m_i, 3) float, mm
        New arrays (never views of the input).
    """
    pts = check_points(points)
    n = len(pts)
    idx = np.asarray(indices).reshape(-1)
    if idx.size and not np.issubdtype(idx.dtype, np.integer):
        raise ConfigError(f"indices must be integers, got dtype {idx.dtype}")
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        raise ConfigError(f"indices must lie in [0, {n - 1}], got {idx.min()} .. {idx.max()}")
    cuts = np.unique(idx).tolist()
    if not closed:
        bounds = [0, *[c for c in cuts if 0 < c < n - 1], max(n - 1, 0)]
        return [pts[a : b + 1].copy() for a, b in pairwise(bounds)] if n > 1 else [pts.copy()]
    if not cuts:
        return [pts.copy()]
    pieces = [pts[a : b + 1].copy() for a, b in pairwise(cuts)]
    pieces.append(np.vstack([pts[cuts[-1] :], pts[: cuts[0] + 1]]))
    return pieces
