"""Normals at the sampling points of a scanned cloud (seed 003, section 3.2.2).

:func:`neighbour_triangle_normals` is the seed's method, :func:`plane_fit_normals` the least-squares plane it
describes first. Both return unit normals of arbitrary overall sign: orient them outward with
:mod:`sprayplan.surface.normals` (``orient_propagate``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.checks import check_count, check_points
from sprayplan.errors import ConfigError
from sprayplan.surface.normals import pca_fit, unit

WEIGHTINGS = ("area", "inverse_area")


def neighbour_triangle_normals(
    query: np.ndarray,
    points: np.ndarray,
    k: int = 8,
    *,
    weighting: str = "area",
    min_fan_angle_rad: float = np.radians(10.0),
) -> np.ndarray:
    """Normals of sampling points from their neighbour triangles (seed 003, section 3.2.2, figure 9).

    Around each query point Q its ``k`` nearest cloud points P_j (points coincident with Q excluded) are
    sorted by angle around Q in the tangent plane of a PCA of the neighbours. The fan of triangles
    (Q, P_j, P_j+1), P_k+1 = P_1, gives unit normals ``n_j = (P_j - Q) x (P_j+1 - Q) / |...|``, combined as
    ``n = sum(sigma_j n_j) / |sum(sigma_j n_j)|`` (the seed's eqs. 15-16).

    Weighting
    ---------
    ``"inverse_area"``, ``sigma_j = 1 / S_j``
        The seed's weight as printed (S_j the triangle's area). It gives the most weight to the smallest
        triangles, which are the thin, nearly degenerate ones whose normal is the most sensitive to noise
        (a triangle spanned by two nearly collinear neighbours can point anywhere).
    ``"area"`` (default), ``sigma_j = S_j``
        The common choice: ``sum(S_j n_j) = 1/2 sum((P_j - Q) x (P_j+1 - Q))`` is the vector area of the fan,
        which for a full fan does not depend on Q at all (the Q terms cancel round the loop), so noise in Q
        and thin triangles do not tilt it.

    The fan is cleaned the way a triangulation's 1-ring would be: a neighbour seen from Q within
    ``min_fan_angle_rad`` of a nearer neighbour's direction is hidden behind it and dropped (on a grid, the
    second point of a row would otherwise make a needle triangle Q, P_1, P_2 of almost zero area, which the
    inverse-area weight lets dominate the sum). Triangles of zero area are skipped, and so are triangles whose
    angle at Q is ``pi - min_fan_angle_rad`` or more: such a triangle is either a needle with Q on its long
    side or, at an angle of pi or more, Q lies on the cloud's boundary and the closing triangle P_m, Q, P_1
    would wrap the outside of the surface and point the other way.

    Parameters
    ----------
    query : (q, 3) float, mm
        The sampling points (they need not be cloud points).
    points : (n, 3) float, mm
        The cloud.
    k : int
        Neighbours m in the fan (at least 3).
    weighting : {"area", "inverse_area"}
    min_fan_angle_rad : float
        Smallest angle at Q between consecutive fan neighbours (0 keeps every neighbour).

    Returns
    -------
    normals : (q, 3) float
        Unit normals, each with a non-negative dot product with its PCA normal (whose sign is arbitrary); a
        point with no usable triangle gets its PCA normal. Orient them outward afterwards.
    """
    query = check_points(query, "query")
    points = check_points(points)
    k = check_count(k, "k", 3)
    if weighting not in WEIGHTINGS:
        raise ConfigError(f"weighting must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    min_fan_angle_rad = float(min_fan_angle_rad)
    if not 0 <= min_fan_angle_rad < np.pi / 2:
        raise ConfigError(f"min_fan_angle_rad must lie in [0, pi/2), got {min_fan_angle_rad}")
    if len(points) < 3:
        raise ConfigError("neighbour triangle normals need at least 3 cloud points")
    if len(query) == 0:
        return np.zeros((0, 3))
    kq = int(min(k + 1, len(points)))
    dist, idx = cKDTree(points).query(query, k=kq)
    dist, idx = dist.reshape(len(query), kq), idx.reshape(len(query), kq)
    scale = max(float(np.ptp(points, axis=0).max()), 1e-300)
    valid = dist > 1e-12 * scale
    # keep the first k valid neighbours of each row (the nearest ones), invalid ones moved to the back
    pick = np.argsort(~valid, axis=1, kind="stable")[:, :k]
    idx = np.take_along_axis(idx, pick, axis=1)
    valid = np.take_along_axis(valid, pick, axis=1)
    rel = points[idx] - query[:, None, :]  # (q, k, 3)
    count = valid.sum(axis=1)
    w = valid[..., None].astype(float)
    centre = (rel * w).sum(axis=1) / np.maximum(count, 1)[:, None]
    local = (rel - centre[:, None, :]) * w
    _, vectors = np.linalg.eigh(local.transpose(0, 2, 1) @ local)
    pca = vectors[:, :, 0]
    a = vectors[:, :, 2]
    b = np.cross(pca, a)  # a x b = pca: counter-clockwise about the PCA normal
    angle = np.arctan2(np.einsum("qkj,qj->qk", rel, b), np.einsum("qkj,qj->qk", rel, a))
    rel, angle, valid, turn = _fan(rel, angle, valid)
    # a neighbour seen within min_fan_angle_rad of a nearer one is hidden behind it: drop it, and fan again
    for _ in range(3):
        hidden = valid & (turn < min_fan_angle_rad) & (valid.sum(axis=1) > 2)[:, None]
        if not hidden.any():
            break
        dist2 = np.einsum("qkj,qkj->qk", rel, rel)
        nxt = _next_in_fan(valid)
        next_farther = np.take_along_axis(dist2, nxt, axis=1) >= dist2
        drop = hidden & ~next_farther
        rows, cols = np.nonzero(hidden & next_farther)
        drop[rows, nxt[rows, cols]] = True
        rel, angle, valid, turn = _fan(rel, angle, valid & ~drop)
    nxt = _next_in_fan(valid)
    rel_next = np.take_along_axis(rel, nxt[..., None], axis=1)
    count = valid.sum(axis=1)
    cross = np.cross(rel, rel_next)
    area = 0.5 * np.linalg.norm(cross, axis=2)
    size = np.einsum("qkj,qkj->qk", rel, rel).max(axis=1)
    flat_angle = np.pi - min_fan_angle_rad  # at Q: wider is a needle (Q on P_j P_j+1) or wraps the outside
    use = valid & (count[:, None] >= 2) & (turn < flat_angle) & (area > 1e-12 * size[:, None])
    normal_j = unit(cross)
    if weighting == "area":
        sigma = area
    else:
        sigma = 1.0 / np.where(use, area, 1.0)
    total = (normal_j * np.where(use, sigma, 0.0)[..., None]).sum(axis=1)
    length = np.linalg.norm(total, axis=1)
    normals = np.where(length[:, None] > 0, total / np.maximum(length, 1e-300)[:, None], pca)
    sign = np.where(np.einsum("ij,ij->i", normals, pca) < 0, -1.0, 1.0)
    return normals * sign[:, None]


def _next_in_fan(valid: np.ndarray) -> np.ndarray:
    """(q, k) index of the next neighbour round the fan; the valid ones come first in each row."""
    count = valid.sum(axis=1)[:, None]
    pos = np.arange(valid.shape[1])[None, :]
    return np.where(pos + 1 < count, pos + 1, 0)


def _fan(rel, angle, valid):
    """Neighbours sorted by angle round Q (invalid ones last) and the angle from each to the next (0..2 pi)."""
    angle = np.where(valid, angle, np.inf)
    order = np.argsort(angle, axis=1, kind="stable")
    rel = np.take_along_axis(rel, order[..., None], axis=1)
    angle = np.take_along_axis(angle, order, axis=1)
    valid = np.take_along_axis(valid, order, axis=1)
    finite = np.where(valid, angle, 0.0)
    turn = np.mod(np.take_along_axis(finite, _next_in_fan(valid), axis=1) - finite, 2 * np.pi)
    return rel, angle, valid, np.where(valid, turn, 0.0)


def plane_fit_normals(query: np.ndarray, points: np.ndarray, k: int = 12) -> np.ndarray:
    """Normals of the least-squares plane of the k nearest cloud points (seed 003, section 3.2.2, first method).

    The plane through the mean of the ``k`` nearest points of each query point (a cloud point counts as its
    own neighbour), with the normal of the smallest principal axis (PCA; wraps
    :func:`sprayplan.surface.normals.pca_fit` with ``center="mean"``).

    Parameters
    ----------
    query : (q, 3) float, mm
    points : (n, 3) float, mm
    k : int
        Neighbours per plane (at least 3).

    Returns
    -------
    normals : (q, 3) float
        Unit normals of arbitrary sign (the seed's "ambiguity"): orient them outward afterwards.
    """
    query = check_points(query, "query")
    points = check_points(points)
    k = check_count(k, "k", 3)
    if len(points) < 3:
        raise ConfigError("plane fit normals need at least 3 cloud points")
    if len(query) == 0:
        return np.zeros((0, 3))
    k = int(min(k, len(points)))
    return pca_fit(query, np.inf, max_neighbours=k, min_neighbours=k, center="mean", data=points)[0]
