"""Discrete curvature of a section polyline: the circle through three points (seed 003, section 2.1.2).

Conventions as in :mod:`sprayplan.paths.polyline` (``(n, 3)`` mm arrays, ``closed`` polylines do not repeat
their first point, radians). The PDF extraction of seed 003 lost fraction bars and norms; each docstring says
how its equation was read.
"""

from __future__ import annotations

import math

import numpy as np

from sprayplan.checks import check_points
from sprayplan.errors import ConfigError
from sprayplan.paths.polyline import _norm

#: Sign reference for a best-fit plane normal (mostly +z, then +y, then +x; no axis-aligned or 45-degree normal
#: is perpendicular to it), so that an automatically chosen normal does not flip with rounding.
_NORMAL_REFERENCE = np.array([1.0, math.sqrt(2.0), 10.0])

ENDPOINT_METHODS = ("circle", "seed")


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
    pts = check_points(points)
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
