"""Section polylines: length, streamlining and resampling.

Seed 003 (point cloud slicing): section 2.1.1 (angle-method streamlining) and 3.2.1 (average sampling, eq. 13).
Its section 2.1.2 (curvature by the circle through three points) is in ``curvature``, 2.1.3 (one-sided
derivatives, feature points and segmentation) in ``segmentation``, and 3.2.3 (line or arc interpolation of the
gun path) in ``interpolation``; they share this module's conventions and checks.

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

import numpy as np

from sprayplan.checks import check_points, check_positive
from sprayplan.errors import ConfigError, InputError

logger = logging.getLogger(__name__)

#: Relative slack when counting pieces, so that a length that is a whole multiple of the step up to rounding
#: is not given one piece too many (a spacing may exceed the step by this relative amount at most).
_PIECE_SLACK = 1e-9


# --------------------------------------------------------------------------------------------------- helpers


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
    pts = _closed_chain(check_points(points), closed)
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
    pts = check_points(points)
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
    pts = check_points(points)
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
        num = int(_pieces(total, check_positive(step_mm, "step_mm")))
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
