"""Line and circular-arc interpolation between path points (seed 003, section 3.2.3).

The sampled points of a section are joined into a continuous gun path by straight lines or by circular arcs
through consecutive points; normals are interpolated by spherical linear interpolation.
"""

from __future__ import annotations

import math

import numpy as np

from sprayplan.checks import check_points, check_positive
from sprayplan.errors import ConfigError, InputError
from sprayplan.paths.polyline import (
    _norm,
    _pieces,
    _unit,
)

INTERPOLATION_METHODS = ("line", "arc")


def _segment_arcs(pts: np.ndarray, collinear_tol_rad: float):
    """Per segment i: whether it is an arc, and the arc's centre, radius, in-plane axes and swept angle.

    The circle for ``P_i -> P_{i+1}`` passes through ``P_{i-1}, P_i, P_{i+1}`` (``P_0, P_1, P_2`` for i = 0).
    Its normal ``(B - A) x (C - B)`` makes the traversal A -> B -> C counter-clockwise, so the arc from
    ``P_i`` to ``P_{i+1}`` is the counter-clockwise one: it continues the motion through the third point.
    """
    m = len(pts) - 1
    first = np.maximum(np.arange(m) - 1, 0)
    a_pts, b_pts, c_pts = pts[first], pts[first + 1], pts[first + 2]
    ab, bc = b_pts - a_pts, c_pts - b_pts
    turn = np.cross(ab, bc)
    lengths = _norm(ab) * _norm(bc)
    is_arc = (lengths > 0) & (_norm(turn) > math.sin(collinear_tol_rad) * lengths)
    ca, cb = a_pts - c_pts, b_pts - c_pts
    axb = np.cross(ca, cb)
    den = 2.0 * np.einsum("ij,ij->i", axb, axb)
    num = np.cross(np.einsum("ij,ij->i", ca, ca)[:, None] * cb - np.einsum("ij,ij->i", cb, cb)[:, None] * ca, axb)
    centre = c_pts + np.divide(num, den[:, None], out=np.zeros_like(num), where=is_arc[:, None])
    normal = _unit(turn)
    u = pts[:-1] - centre
    v = pts[1:] - centre
    radius = _norm(u)
    e1 = _unit(u)
    e2 = np.cross(normal, e1)
    sweep = np.mod(np.arctan2(np.einsum("ij,ij->i", np.cross(u, v), normal), np.einsum("ij,ij->i", u, v)), 2 * np.pi)
    is_arc &= sweep > 0
    return is_arc, centre, radius, e1, e2, sweep


def _interpolation(pts: np.ndarray, step_mm: float, method: str, collinear_tol_rad: float):
    """Output points, their segment index and their arc-length fraction along that segment."""
    step = check_positive(step_mm, "step_mm")
    if method not in INTERPOLATION_METHODS:
        raise ConfigError(f"method must be one of {', '.join(INTERPOLATION_METHODS)}, got {method!r}")
    tol = float(collinear_tol_rad)
    if not 0.0 <= tol < math.pi / 2:
        raise ConfigError(f"collinear_tol_rad must be in [0, pi/2), got {collinear_tol_rad!r}")
    n = len(pts)
    if n < 2:
        return pts.copy(), np.zeros(n, dtype=np.int64), np.zeros(n)
    m = n - 1
    chord = _norm(np.diff(pts, axis=0))
    if method == "arc" and n >= 3:
        is_arc, centre, radius, e1, e2, sweep = _segment_arcs(pts, tol)
        seg_len = np.where(is_arc, radius * sweep, chord)
    else:
        is_arc = np.zeros(m, dtype=bool)
        seg_len = chord
    pieces = _pieces(seg_len, step)
    seg = np.append(np.repeat(np.arange(m), pieces), m - 1)
    start = np.concatenate([[0], np.cumsum(pieces)[:-1]])
    j = np.arange(len(seg) - 1) - np.repeat(start, pieces)
    frac = np.append(j / np.repeat(pieces, pieces), 1.0)
    out = (1.0 - frac)[:, None] * pts[seg] + frac[:, None] * pts[seg + 1]
    on_arc = is_arc[seg] & (frac > 0) & (frac < 1)
    if np.any(on_arc):
        s = seg[on_arc]
        phi = frac[on_arc] * sweep[s]
        out[on_arc] = centre[s] + radius[s, None] * (np.cos(phi)[:, None] * e1[s] + np.sin(phi)[:, None] * e2[s])
    return out, seg, frac


def interpolate(points, step_mm: float, method: str = "line", *, collinear_tol_rad: float = 1e-6) -> np.ndarray:
    """Densify a path by line or circular-arc interpolation (seed 003, section 3.2.3).

    Consecutive points are joined by straight lines (``"line"``) or circular arcs (``"arc"``), and each
    connection is cut into the fewest equal pieces (in length along the line or arc) no longer than
    ``step_mm``; all input points are kept exactly. The arc for ``P_i -> P_{i+1}`` lies on the circle through
    ``P_{i-1}, P_i, P_{i+1}`` (``P_0, P_1, P_2`` for the first segment) and is the arc that continues the motion
    through the third point; its points are ``O + R (cos(phi) e1 + sin(phi) e2)`` with O the circumcentre, so
    they lie on that circle up to rounding. Where the three points are (nearly) collinear, or two coincide, or
    there are only two points, the line is used.

    Parameters
    ----------
    points : (n, 3) float, mm
    step_mm : float, mm
        Largest length of a piece (chords are never longer than the arc pieces).
    method : {"line", "arc"}
    collinear_tol_rad : float, rad
        Three points whose turning angle is within this of 0 or pi count as collinear.

    Returns
    -------
    (m, 3) float, mm
        The path with the input points and the inserted ones, in order.
    """
    return _interpolation(check_points(points), step_mm, method, collinear_tol_rad)[0]


def _slerp(n0: np.ndarray, n1: np.ndarray, frac: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation between unit rows n0 and n1 at fractions ``frac``."""
    dot = np.einsum("ij,ij->i", n0, n1)
    omega = np.arctan2(_norm(np.cross(n0, n1)), dot)
    f = frac[:, None]
    out = (1.0 - f) * n0 + f * n1  # nearly equal normals: linear, normalised below
    mid = (omega > 1e-9) & (omega < math.pi - 1e-6)
    if np.any(mid):
        w = omega[mid, None]
        out[mid] = (np.sin((1.0 - f[mid]) * w) * n0[mid] + np.sin(f[mid] * w) * n1[mid]) / np.sin(w)
    flip = omega >= math.pi - 1e-6
    if np.any(flip):
        # Opposite normals: no unique great circle; turn about the axis normal to n0 and the segment direction.
        axis = _unit(np.cross(n0[flip], direction[flip]))
        bad = _norm(axis) == 0
        if np.any(bad):
            helper = np.where(np.abs(n0[flip][bad, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
            axis[bad] = _unit(np.cross(n0[flip][bad], helper))
        angle = f[flip] * math.pi
        out[flip] = np.cos(angle) * n0[flip] + np.sin(angle) * np.cross(axis, n0[flip])
    return _unit(out)


def interpolate_with_normals(
    points, normals, step_mm: float, method: str = "line", *, collinear_tol_rad: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`interpolate`, carrying normals along by spherical linear interpolation (seed 003, section 3.2.3).

    Each inserted point at fraction f of the length of its line or arc gets
    ``slerp(n_i, n_{i+1}, f) = (sin((1 - f) w) n_i + sin(f w) n_{i+1}) / sin(w)`` with w the angle between the
    unit end normals. Input points keep their own (normalised) normals. Opposite end normals (w = pi) have no
    unique great circle: they turn about the axis perpendicular to ``n_i`` and the segment direction.

    Parameters
    ----------
    points : (n, 3) float, mm
    normals : (n, 3) float
        Non-zero; normalised before use.
    step_mm : float, mm
    method : {"line", "arc"}
    collinear_tol_rad : float, rad

    Returns
    -------
    points : (m, 3) float, mm
    normals : (m, 3) float
        Unit normals.
    """
    pts = check_points(points)
    nrm = check_points(normals, "normals")
    if nrm.shape != pts.shape:
        raise InputError(f"normals must have the shape of points {pts.shape}, got {nrm.shape}")
    if np.any(_norm(nrm) == 0):
        raise InputError("normals must not be zero vectors")
    nrm = _unit(nrm)
    out, seg, frac = _interpolation(pts, step_mm, method, collinear_tol_rad)
    if len(pts) < 2:
        return out, nrm
    out_normals = _slerp(nrm[seg], nrm[seg + 1], frac, pts[seg + 1] - pts[seg])
    starts = frac == 0
    out_normals[starts] = nrm[seg[starts]]
    out_normals[-1] = nrm[-1]
    return out, out_normals
