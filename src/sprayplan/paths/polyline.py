"""Section polylines: streamlining, discrete curvature, feature points and resampling.

Seed 003 (point cloud slicing): section 2.1.1 (angle-method streamlining), 2.1.2 (curvature by the circle through
three points), 2.1.3 (one-sided derivatives and feature points) and 3.2.1 (average sampling, eq. 13); its
section 3.2.3 (line or arc interpolation of the gun path) is in ``interpolation``.

Conventions
-----------
A polyline is an ``(n, 3)`` float array of points in mm, in order. ``closed=True`` means that the last point
connects back to the first; the first point is *not* repeated at the end. Angles are in radians. Every function
is pure: it reads its inputs and returns new arrays. Bad arrays raise :class:`~sprayplan.errors.InputError`, bad
parameters :class:`~sprayplan.errors.ConfigError`.

The PDF extraction of seed 003 lost fraction bars, minus signs, norms and primes; each function's docstring says
how its equation was read.
"""

from __future__ import annotations

import logging
import math
from itertools import pairwise

import numpy as np

from sprayplan.errors import ConfigError, InputError

logger = logging.getLogger(__name__)

#: Sign reference for a best-fit plane normal (mostly +z, then +y, then +x; no axis-aligned or 45-degree normal
#: is perpendicular to it), so that an automatically chosen normal does not flip with rounding.
_NORMAL_REFERENCE = np.array([1.0, math.sqrt(2.0), 10.0])
#: Relative slack when counting pieces, so that a length that is a whole multiple of the step up to rounding
#: is not given one piece too many (a spacing may exceed the step by this relative amount at most).
_PIECE_SLACK = 1e-9

ENDPOINT_METHODS = ("circle", "seed")


# --------------------------------------------------------------------------------------------------- helpers


def _check_points(points, name: str = "points") -> np.ndarray:
    """A float copy of ``points`` after checking it is a finite (n, 3) array."""
    out = np.array(points, dtype=float, copy=True)
    if out.ndim != 2 or out.shape[1] != 3:
        raise InputError(f"{name} must have shape (n, 3), got {out.shape}")
    if not np.all(np.isfinite(out)):
        raise InputError(f"{name} must be finite numbers (found NaN or inf)")
    return out


def _check_positive(value, name: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(out) and out > 0):
        raise ConfigError(f"{name} must be a positive number, got {value!r}")
    return out


def _check_angle(value, name: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be an angle in [0, pi] rad, got {value!r}") from None
    if not 0.0 <= out <= math.pi:
        raise ConfigError(f"{name} must be an angle in [0, pi] rad, got {value!r}")
    return out


def _norm(vectors: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...i,...i->...", vectors, vectors))


def _unit(vectors: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length; zero rows stay zero."""
    length = _norm(vectors)[..., None]
    return np.divide(vectors, length, out=np.zeros_like(vectors), where=length > 0)


def _pieces(length: np.ndarray, step: float) -> np.ndarray:
    """Number of equal pieces (>= 1) so that each is at most ``step`` long (up to ``_PIECE_SLACK``)."""
    return np.maximum(np.ceil(np.asarray(length, dtype=float) / step * (1.0 - _PIECE_SLACK)), 1).astype(np.int64)


def _closed_chain(points: np.ndarray, closed: bool) -> np.ndarray:
    """The vertices of the segments in order: for a closed polyline the start is appended once more."""
    return np.vstack([points, points[:1]]) if closed and len(points) > 1 else points


def polyline_length(points, closed: bool = False) -> float:
    """Total length of a polyline.

    Parameters
    ----------
    points : (n, 3) float, mm
    closed : bool
        Include the closing segment from the last point back to the first.

    Returns
    -------
    float, mm
        Sum of the segment lengths (the numerator of seed 003 eq. 13); 0 for fewer than two points.
    """
    pts = _closed_chain(_check_points(points), closed)
    return float(_norm(np.diff(pts, axis=0)).sum()) if len(pts) > 1 else 0.0


# ------------------------------------------------------------------------------------ 2.1.1 streamlining


def streamline(
    points, alpha_min_rad: float, alpha_max_rad: float, closed: bool = False, *, duplicate_tol_mm: float = 0.0
) -> np.ndarray:
    """Indices of the points kept by the angle method (seed 003, section 2.1.1, eq. 1).

    The angle ``alpha`` at ``P_i`` between ``P_{i-1}`` and ``P_{i+1}`` comes from the law of cosines. The
    printed eq. 1 lost its fraction bar, norms and minus sign; it reads

        cos(alpha) = (|a|^2 + |b|^2 - |c|^2) / (2 |a| |b|),
        a = P_{i-1}P_i,  b = P_iP_{i+1},  c = P_{i-1}P_{i+1}.

    If ``|a|`` or ``|b|`` is 0 (a duplicate point), ``cos(alpha) = cos(alpha_max)``, so the point is deleted.
    If ``cos(alpha)`` is in ``[cos(alpha_max), cos(alpha_min)]`` (alpha in ``[alpha_min, alpha_max]``: the
    polyline is nearly straight at ``P_i``), ``P_i`` is deleted and the same position is tested again with the
    next point, i.e. the previous point is always the last *kept* one and the next point is the next input
    point; otherwise ``i`` advances. This is the seed's sequential loop, steps (b) to (d).

    Open polylines always keep both end points (the seed tests i = 1 .. n-2). Closed ones also test the start
    point, with ``P_{-1} = P_{n-1}``; the last point is tested against the first kept one, and a closed
    polyline never drops below 3 points. Corners (angles below ``alpha_min``) are always kept.

    Parameters
    ----------
    points : (n, 3) float, mm
    alpha_min_rad, alpha_max_rad : float, rad
        Angle thresholds, ``0 <= alpha_min <= alpha_max <= pi``; the seed uses obtuse angles such as
        [170 deg, 180 deg].
    closed : bool
        Whether the last point connects back to the first.
    duplicate_tol_mm : float, mm
        Segments at most this long count as zero length (duplicates). 0 (the seed): only exact duplicates.

    Returns
    -------
    (m,) int
        Increasing indices into ``points`` of the kept points.
    """
    pts = _check_points(points)
    lo = _check_angle(alpha_min_rad, "alpha_min_rad")
    hi = _check_angle(alpha_max_rad, "alpha_max_rad")
    if lo > hi:
        raise ConfigError(f"alpha_min_rad ({lo}) must not exceed alpha_max_rad ({hi})")
    tol = float(duplicate_tol_mm)
    if not (math.isfinite(tol) and tol >= 0):
        raise ConfigError(f"duplicate_tol_mm must be a number >= 0, got {duplicate_tol_mm!r}")
    n = len(pts)
    if n <= (3 if closed else 2):
        return np.arange(n)

    cos_lo = math.cos(hi)  # cos(alpha_max)
    cos_hi = math.cos(lo)  # cos(alpha_min)
    tol2 = tol * tol
    xyz = pts.tolist()  # Python floats: O(1) work per test without numpy overhead

    def straight(p, q, r) -> bool:
        ax, ay, az = q[0] - p[0], q[1] - p[1], q[2] - p[2]
        bx, by, bz = r[0] - q[0], r[1] - q[1], r[2] - q[2]
        a2 = ax * ax + ay * ay + az * az
        b2 = bx * bx + by * by + bz * bz
        if a2 <= tol2 or b2 <= tol2:
            cos_a = cos_lo
        else:
            cx, cy, cz = ax + bx, ay + by, az + bz
            cos_a = (a2 + b2 - (cx * cx + cy * cy + cz * cz)) / (2.0 * math.sqrt(a2 * b2))
            cos_a = min(1.0, max(-1.0, cos_a))
        return cos_lo <= cos_a <= cos_hi

    if not closed:
        kept = [0]
        for i in range(1, n - 1):
            if not straight(xyz[kept[-1]], xyz[i], xyz[i + 1]):
                kept.append(i)
        kept.append(n - 1)
    else:
        kept = []
        remaining = n
        for i in range(n):
            prev = xyz[kept[-1]] if kept else xyz[n - 1]
            nxt = xyz[i + 1] if i < n - 1 else xyz[kept[0]]
            if remaining > 3 and straight(prev, xyz[i], nxt):
                remaining -= 1
            else:
                kept.append(i)
    logger.debug("streamline: kept %d of %d points", len(kept), n)
    return np.asarray(kept, dtype=np.int64)


# ------------------------------------------------------------------------------------- 2.1.2 curvature


def _plane_normal(points: np.ndarray) -> np.ndarray:
    """Unit normal of the best-fit plane (smallest principal axis), signed by ``_NORMAL_REFERENCE``."""
    centred = points - points.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    return -normal if normal @ _NORMAL_REFERENCE < 0 else normal


def _three_point_curvature(a_pts: np.ndarray, b_pts: np.ndarray, c_pts: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Signed curvature ``4 S / (|AB| |BC| |AC|)`` of the circle through A, B, C (rows), eq. 2; 0 if degenerate."""
    ab = b_pts - a_pts
    bc = c_pts - b_pts
    cross = np.cross(ab, bc)
    den = _norm(ab) * _norm(bc) * _norm(c_pts - a_pts)
    magnitude = np.divide(2.0 * _norm(cross), den, out=np.zeros(len(den)), where=den > 0)  # 4 S = 2 |cross|
    return np.where(cross @ normal < 0, -magnitude, magnitude)


def _circle_center_eq7(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray | None:
    """Centre of the circle O1 through three 3D points by eqs. 6-7, in 2D coordinates of their plane.

    Eq. 7 as printed lost its minus signs and fraction bars; solving eq. 6 (two perpendicular bisectors,
    Cramer's rule) gives ``x_c = (a - b + c) / d`` and ``y_c = (f - e - g) / d`` with the printed a .. g.
    Returns None for collinear or coincident points.
    """
    e1 = p1 - p0
    l1 = math.sqrt(e1 @ e1)
    if l1 == 0.0:
        return None
    e1 = e1 / l1
    w = p2 - p0
    e2 = w - (w @ e1) * e1
    l2 = math.sqrt(e2 @ e2)
    if l2 <= 1e-12 * math.sqrt(w @ w):
        return None
    e2 = e2 / l2
    x0, y0, x1, y1, x2, y2 = 0.0, 0.0, l1, 0.0, float(w @ e1), l2
    a = (x0 + x1) * (x1 - x0) * (y2 - y1)
    b = (x2 + x1) * (x2 - x1) * (y1 - y0)
    c = (y0 - y2) * (y1 - y0) * (y2 - y1)
    d = 2.0 * ((x1 - x0) * (y2 - y1) - (x2 - x1) * (y1 - y0))
    e = (y1 + y0) * (y1 - y0) * (x2 - x1)
    f = (y2 + y1) * (y2 - y1) * (x1 - x0)
    g = (x0 - x2) * (x1 - x0) * (x2 - x1)
    xc = (a - b + c) / d
    yc = (f - e - g) / d
    return p0 + xc * e1 + yc * e2


def _seed_virtual_point(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray | None:
    """The seed's virtual point before ``p0`` (eqs. 5-7): on the tangent of circle O1 at ``p0``, away from p1."""
    centre = _circle_center_eq7(p0, p1, p2)
    if centre is None:
        return None
    r0 = p0 - centre  # O1P0
    v0 = np.cross(p2 - p0, p1 - p0)
    t0 = np.cross(r0, v0)
    t0 = t0 / math.sqrt(t0 @ t0)  # eq. 5; points along the travel direction P0 -> P1 on O1
    return p0 - 0.5 * math.sqrt((p1 - p0) @ (p1 - p0)) * t0


def curvature(points, closed: bool = False, endpoint: str = "circle", plane_normal=None) -> np.ndarray:
    """Discrete signed curvature by the circle through three points (seed 003, section 2.1.2, eqs. 2-7).

    Eq. 2: ``C_i = 1 / R_i = 4 S / (|P_{i-1}P_i| |P_iP_{i+1}| |P_{i-1}P_{i+1}|)`` with S the signed area of
    the triangle ``P_{i-1} P_i P_{i+1}``. The printed eq. 3 is Heron's formula
    ``S = sqrt(s (s - |P_{i-1}P_i|) (s - |P_iP_{i+1}|) (s - |P_{i-1}P_{i+1}|))`` (its root was lost), which has no
    sign; here ``|S| = |P_{i-1}P_i x P_iP_{i+1}| / 2`` and the sign is that of the cross product along the
    reference normal: positive when ``P_{i-1}, P_i, P_{i+1}`` turn counter-clockwise seen from the normal's tip.

    End points: closed polylines wrap around (``P_{-1} = P_{n-1}``). Open polylines:

    ``endpoint="circle"`` (default)
        ``P_0`` gets the curvature of the circle O1 through ``P_0, P_1, P_2`` and ``P_{n-1}`` that of the
        circle through the last three points (the same values as at ``P_1`` and ``P_{n-2}``); exact on a circle.
    ``endpoint="seed"``
        The seed's construction: the centre of O1 from eqs. 6-7 (solved in 2D coordinates of the plane of the
        three points; the printed eq. 7 reads ``x_c = (a - b + c) / d``, ``y_c = (f - e - g) / d``), the unit
        tangent ``t0 = r0 x v0 / |r0 x v0|`` (eq. 5) with ``r0 = O1P0`` and ``v0 = (P2 - P0) x (P1 - P0)``,
        which points along the travel direction ``P0 -> P1`` on O1; the virtual point
        ``P0- = P0 - t0 |P0P1| / 2`` (the seed asks only for ``|P0-P0| < |P0P1|``) lies on the tangent away
        from P1, and ``C_0`` is eq. 2 for ``(P0-, P0, P1)``. ``P_{n-1}`` likewise with
        ``(P_{n-2}, P_{n-1}, P_n+)``. On a finely sampled circle of radius R this gives about ``2 / (3 R)``,
        not ``1 / R``, because the virtual point lies on the tangent rather than on the circle.

    Collinear or coincident triples give 0; fewer than 3 points give zeros.

    Parameters
    ----------
    points : (n, 3) float, mm
    closed : bool
    endpoint : {"circle", "seed"}
        End-point rule for open polylines.
    plane_normal : (3,) float or None
        Reference normal for the sign. None: the normal of the best-fit plane of the points (smallest principal
        axis), signed to have a positive dot product with (1, sqrt 2, 10) so that it is deterministic (+z for a
        polyline in a horizontal plane).

    Returns
    -------
    (n,) float, 1/mm
        Signed curvature at each point.
    """
    pts = _check_points(points)
    if endpoint not in ENDPOINT_METHODS:
        raise ConfigError(f"endpoint must be one of {', '.join(ENDPOINT_METHODS)}, got {endpoint!r}")
    n = len(pts)
    out = np.zeros(n)
    if n < 3:
        return out
    if plane_normal is None:
        normal = _plane_normal(pts)
    else:
        normal = np.array(plane_normal, dtype=float).reshape(-1)
        if normal.shape != (3,) or not np.all(np.isfinite(normal)) or not np.any(normal):
            raise ConfigError(f"plane_normal must be three finite numbers, not all 0, got {plane_normal!r}")
    if closed:
        return _three_point_curvature(np.roll(pts, 1, axis=0), pts, np.roll(pts, -1, axis=0), normal)
    out[1:-1] = _three_point_curvature(pts[:-2], pts[1:-1], pts[2:], normal)
    if endpoint == "circle":
        out[0], out[-1] = out[1], out[-2]
        return out
    before = _seed_virtual_point(pts[0], pts[1], pts[2])
    after = _seed_virtual_point(pts[-1], pts[-2], pts[-3])
    if before is not None:
        out[0] = _three_point_curvature(before[None], pts[:1], pts[1:2], normal)[0]
    if after is not None:
        out[-1] = _three_point_curvature(pts[-2:-1], pts[-1:], after[None], normal)[0]
    return out


# ------------------------------------------------------------------------ 2.1.3 derivatives and features


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
    pts = _check_points(points)
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
    pts = _check_points(points)
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
    pts = _check_points(points)
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


# ------------------------------------------------------------------------------------ 3.2.1 resampling


def resample(
    points, *, step_mm: float | None = None, count: int | None = None, closed: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points equally spaced in arc length along a polyline (seed 003, section 3.2.1, eq. 13).

    Eq. 13 (its fraction bar and norm were lost) reads ``d_m = (sum_{i=0}^{N-1} |P_i P_{i+1}|) / num``: the
    total length over the number of samples. Here ``num`` counts the *intervals* between samples:

    - ``count``: open polylines get ``count`` points including both ends, so there are ``count - 1`` intervals
      and the spacing is ``L / (count - 1)`` (eq. 13 with ``num = count - 1``: with ``num`` intervals an open
      polyline needs ``num + 1`` points to keep both ends). Closed polylines get ``count`` points starting at
      the first input point and spacing ``L / count`` (eq. 13 with ``num = count``: a loop of ``count`` points
      has ``count`` intervals, the last one through the closing segment; the start is not repeated).
    - ``step_mm``: ``num = ceil(L / step)`` intervals of ``L / num <= step`` (up to 1e-9 relative rounding), so
      an open polyline gets ``num + 1`` points with both ends kept, a closed one ``max(num, 3)`` points.

    Parameters
    ----------
    points : (n, 3) float, mm
        n >= 2.
    step_mm : float, mm, optional
        Largest spacing. Give exactly one of ``step_mm`` and ``count``.
    count : int, optional
        Number of output points (>= 2 open, >= 3 closed).
    closed : bool
        Include the closing segment from the last point back to the first.

    Returns
    -------
    points : (m, 3) float, mm
        The samples, in order.
    segment_index : (m,) int
        Index i of the input segment ``[P_i, P_{i+1}]`` each sample lies on (for closed polylines ``i = n - 1``
        is the closing segment ``[P_{n-1}, P_0]``). Zero-length segments are never used except for a polyline
        of zero length.
    t : (m,) float
        Parameter in [0, 1] along that segment: ``sample = (1 - t) P_i + t P_{i+1}``.
    """
    pts = _check_points(points)
    if (step_mm is None) == (count is None):
        raise ConfigError("give exactly one of step_mm and count")
    if len(pts) < 2:
        raise InputError(f"resampling needs a polyline of at least 2 points, got {len(pts)}")
    chain = _closed_chain(pts, closed)
    seg_len = _norm(np.diff(chain, axis=0))
    total = float(seg_len.sum())
    least = 3 if closed else 2
    if count is not None:
        if isinstance(count, bool) or int(count) != count or count < least:
            raise ConfigError(f"count must be a whole number >= {least}, got {count!r}")
        num = int(count) if closed else int(count) - 1
    else:
        num = int(_pieces(total, _check_positive(step_mm, "step_mm")))
        if closed:
            num = max(num, 3)
    m = num if closed else num + 1
    arc = np.arange(m) * (total / num)
    used = np.flatnonzero(seg_len > 0)  # zero-length segments carry no arc length
    if used.size == 0:
        seg, t = np.zeros(m, dtype=np.int64), np.zeros(m)
    else:
        cum_used = np.concatenate([[0.0], np.cumsum(seg_len[used])])
        k = np.clip(np.searchsorted(cum_used, arc, side="right") - 1, 0, used.size - 1)
        seg = used[k]
        t = np.clip((arc - cum_used[k]) / seg_len[seg], 0.0, 1.0)
        if not closed:
            t[-1] = 1.0
    out = (1.0 - t)[:, None] * chain[seg] + t[:, None] * chain[seg + 1]
    return out, seg.astype(np.int64), t
