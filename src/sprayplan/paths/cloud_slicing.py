"""Slicing a point cloud into section polylines, and normals at sampling points (seed 003, sections 2.1, 3.2.2).

Seed 003 slices the preprocessed cloud with parallel planes ("plane and point cloud intersection"), builds a
polyline from each slice ("polyline construction includes patch data sorting and polyline orientation
adjustment") and estimates the normal of every sampling point from its neighbour triangles (section 3.2.2).

Slicing
-------
A slice is the slab of points within ``half_thickness_mm`` of a plane; they are projected onto the plane and
ordered into polylines in the plane's 2-D frame ``(u, v)``: ``u`` the travel direction, ``v = n x u``, so that
``(u, v, n)`` is right-handed and counter-clockwise in ``(u, v)`` is counter-clockwise seen from the tip of
``n``. The ordering (see :func:`order_section`):

1. **Pieces.** A minimum spanning forest over the points' short edges (the k nearest neighbours within
   ``gap_mm``, plus the shortest link <= ``gap_mm`` between pieces that the k-nearest-neighbour graph leaves
   apart, found Boruvka-style). Its connected pieces are the pieces of the section: two pieces are farther
   apart than ``gap_mm`` everywhere.
2. **Backbone.** The longest path (by length) through each piece's spanning tree, found with two
   single-source searches (the diameter of a tree). On a curve sampled densely compared with its own
   bends, the spanning tree is the curve plus short side branches made by the slab's width, so the diameter
   runs from one end of the curve to the other. It does not assume that the curve is a graph over any axis: a
   U or a closed ring (whose tree is the ring cut at one place) works the same way.
3. **Order.** The backbone is smoothed with the moving average below, every point of the piece (branch
   points too) is projected onto it, and the points are sorted by the arc length of their projection.
4. **Smoothing.** Points of a thin slab scatter across the curve (by ``half_thickness * cot`` of the angle
   between the surface and the plane) and, sorted, zig-zag along it. The ordered points are replaced by a
   centred moving average over ``smooth_points`` points (5 by default; the window shrinks at the ends of an
   open polyline so the end points stay, and wraps around on a closed one). On a curve of radius R sampled
   every h the average moves a point inwards by about ``(smooth_points * h)^2 / (24 R)``.
5. **Closed or open.** A piece is closed when its first and last points are within ``gap_mm`` and it goes
   round: its length is at least ``pi`` times that end distance and more than ``2 gap_mm`` (a shorter
   loop cannot be told from a blob at that gap). A closed polyline does not repeat its first point, turns
   counter-clockwise seen from the tip of the plane normal and starts at its point of smallest travel
   coordinate. An open polyline ends at a larger travel coordinate than it starts (ties: larger ``v``).

Pieces of one plane are listed by their smallest travel coordinate.

Normals
-------
:func:`neighbour_triangle_normals` is the seed's method (section 3.2.2), :func:`plane_fit_normals` the
least-squares plane it describes first. Both return unit normals of arbitrary overall sign: orient them
outward with :mod:`sprayplan.surface.normals` (``orient_propagate``).
"""

from __future__ import annotations

import logging

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from sprayplan.errors import ConfigError
from sprayplan.paths.cloudprep import check_points
from sprayplan.surface.normals import pca_fit, unit

log = logging.getLogger(__name__)

WEIGHTINGS = ("area", "inverse_area")


# ---------------------------------------------------------------------------------------------------- slicing


def slice_cloud(
    points: np.ndarray,
    plane_normal,
    offsets,
    half_thickness_mm: float,
    *,
    gap_mm: float,
    travel=None,
    smooth_points: int = 5,
    min_points: int = 3,
    k: int = 10,
) -> list[list[np.ndarray]]:
    """Section polylines of a point cloud cut by parallel planes (seed 003, section 2.1).

    Parameters
    ----------
    points : (n, 3) float, mm
        The (preprocessed) cloud.
    plane_normal : (3,) float
        Normal ``n`` of the planes; normalised here.
    offsets : (p,) float, mm
        The planes ``{x : x . n = offset}``.
    half_thickness_mm : float
        Points with ``|x . n - offset| <= half_thickness_mm`` belong to a plane's slice.
    gap_mm : float
        A gap in the slice wider than this splits the section: two pieces are everywhere farther apart than
        ``gap_mm``, and every piece is connected by steps of at most ``gap_mm``. Choose it well above the
        cloud's point spacing (a thin slab through a random sampling has gaps of several spacings) and below
        the holes that must split a pass.
    travel : (3,) float, optional
        The travel direction ``u``; its component along ``n`` is removed. Default: the principal direction
        of all points projected onto the plane, signed so that its largest component is positive.
    smooth_points : int
        Window of the moving average along each polyline (1: no smoothing).
    min_points : int
        Pieces with fewer points are dropped (stray points in the slab).
    k : int
        Nearest neighbours per point in the graph of step 1.

    Returns
    -------
    sections : list of list of (m, 3) float, mm
        One list per offset, in the order of ``offsets``: its polylines (points on the plane), sorted by
        their smallest travel coordinate. See the module's notes for their order and orientation.

    Raises
    ------
    ConfigError
        Bad points, a zero normal, a travel direction along the normal, or non-positive sizes.
    """
    points = check_points(points)
    normal = _unit_vector(plane_normal, "plane_normal")
    offsets = np.atleast_1d(np.asarray(offsets, dtype=float))
    if offsets.ndim != 1 or not np.isfinite(offsets).all():
        raise ConfigError(f"offsets must be a finite 1-D sequence, got shape {offsets.shape}")
    half_thickness_mm = _positive(half_thickness_mm, "half_thickness_mm")
    gap_mm = _positive(gap_mm, "gap_mm")
    smooth_points = _count(smooth_points, "smooth_points", 1)
    min_points = _count(min_points, "min_points", 1)
    k = _count(k, "k", 1)
    u, v = plane_frame(points, normal, travel)
    height = points @ normal
    sections = []
    for offset in offsets:
        inside = np.abs(height - offset) <= half_thickness_mm
        flat = np.stack([points[inside] @ u, points[inside] @ v], axis=1)
        pieces = order_section(flat, gap_mm, smooth_points=smooth_points, min_points=min_points, k=k)
        pieces.sort(key=lambda piece: float(piece[0][:, 0].min()))
        sections.append([offset * normal + p[:, :1] * u + p[:, 1:] * v for p, _ in pieces])
        log.debug("slice at %.4g mm: %d points, %d polylines", offset, len(flat), len(pieces))
    return sections


def plane_frame(points: np.ndarray, normal: np.ndarray, travel=None) -> tuple[np.ndarray, np.ndarray]:
    """The in-plane frame ``(u, v)``: ``u`` the travel direction, ``v = n x u`` (so ``u x v = n``).

    Parameters
    ----------
    points : (n, 3) float, mm
        Used for the default travel direction (their in-plane principal direction).
    normal : (3,) float
        Unit plane normal.
    travel : (3,) float, optional

    Returns
    -------
    u, v : (3,) float
        Unit vectors in the plane.
    """
    if travel is not None:
        t = np.asarray(travel, dtype=float).reshape(-1)
        if t.shape != (3,) or not np.isfinite(t).all():
            raise ConfigError(f"travel must be a finite 3-vector, got {np.asarray(travel).shape}")
        t = t - (t @ normal) * normal
        if np.linalg.norm(t) <= 1e-9 * max(np.linalg.norm(travel), 1e-300):
            raise ConfigError("travel must not be parallel to plane_normal")
        u = t / np.linalg.norm(t)
    else:
        centred = points - points.mean(axis=0) if len(points) else np.zeros((0, 3))
        flat = centred - np.outer(centred @ normal, normal)
        values, vectors = np.linalg.eigh(flat.T @ flat)
        u = vectors[:, 2]
        if values[2] <= 0 or abs(u @ normal) > 1e-6:  # no spread in the plane: any in-plane direction
            u = np.cross(normal, np.eye(3)[np.argmin(np.abs(normal))])
        u = u - (u @ normal) * normal
        u /= np.linalg.norm(u)
        if u[np.argmax(np.abs(u))] < 0:
            u = -u
    return u, np.cross(normal, u)


def order_section(
    flat: np.ndarray, gap_mm: float, *, smooth_points: int = 5, min_points: int = 3, k: int = 10
) -> list[tuple[np.ndarray, bool]]:
    """Order the points of one slice, in the plane's 2-D frame, into polylines (steps 1-5 of the module notes).

    Parameters
    ----------
    flat : (n, 2) float, mm
        Points in the plane's ``(u, v)`` frame; ``u`` is the travel coordinate.
    gap_mm : float
    smooth_points, min_points, k : int
        As in :func:`slice_cloud`.

    Returns
    -------
    pieces : list of ((m, 2) float, bool)
        Each polyline and whether it is closed, in no particular order.
    """
    flat = np.asarray(flat, dtype=float)
    if len(flat) == 0:
        return []
    forest = spanning_forest(flat, gap_mm, k)
    n_pieces, label = csgraph.connected_components(forest, directed=False)
    order = np.argsort(label, kind="stable")
    bounds = np.searchsorted(label[order], np.arange(n_pieces + 1))
    out = []
    for c in range(n_pieces):
        idx = order[bounds[c] : bounds[c + 1]]
        if len(idx) < min_points:
            continue
        tree = forest[idx][:, idx]
        out.append(_chain(flat[idx], tree, gap_mm, smooth_points))
    return out


def spanning_forest(flat: np.ndarray, gap_mm: float, k: int = 10) -> sparse.csr_matrix:
    """Minimum spanning forest of the points with edges no longer than ``gap_mm`` (step 1).

    Parameters
    ----------
    flat : (n, d) float, mm
    gap_mm : float
    k : int
        Nearest neighbours per point in the starting graph.

    Returns
    -------
    forest : (n, n) sparse float
        Symmetric; entries are edge lengths (at least 1e-12 so that coincident points stay joined).
    """
    n = len(flat)
    tree = cKDTree(flat)
    kk = int(min(k + 1, n))
    dist, idx = tree.query(flat, k=kk, distance_upper_bound=gap_mm)
    dist, idx = dist.reshape(n, kk), idx.reshape(n, kk)
    rows = np.repeat(np.arange(n), kk)
    cols, weight = idx.reshape(-1), dist.reshape(-1)
    ok = (cols < n) & (cols != rows)
    rows, cols, weight = rows[ok], cols[ok], weight[ok]
    final = np.zeros(n, dtype=bool)  # points of pieces with nothing else within gap_mm
    while True:
        graph = sparse.coo_matrix((np.maximum(weight, 1e-12), (rows, cols)), shape=(n, n)).tocsr()
        forest = csgraph.minimum_spanning_tree(graph.maximum(graph.T))
        forest = forest.maximum(forest.T).tocsr()
        n_pieces, label = csgraph.connected_components(forest, directed=False)
        if n_pieces == 1:
            return forest
        new = []
        for c in np.unique(label[~final]):
            mine = label == c
            others = np.flatnonzero(~mine)
            d, j = cKDTree(flat[others]).query(flat[mine], distance_upper_bound=gap_mm)
            best = int(np.argmin(d))
            if not np.isfinite(d[best]):
                final[mine] = True
                continue
            new.append((np.flatnonzero(mine)[best], others[j[best]], d[best]))
        if not new:
            return forest
        extra = np.array(new)
        rows = np.concatenate([rows, extra[:, 0].astype(np.int64)])
        cols = np.concatenate([cols, extra[:, 1].astype(np.int64)])
        weight = np.concatenate([weight, extra[:, 2]])


def _chain(xy: np.ndarray, tree: sparse.csr_matrix, gap_mm: float, window: int) -> tuple[np.ndarray, bool]:
    """One piece's points (m, 2) ordered along its spanning tree's longest path, smoothed and oriented."""
    m = len(xy)
    if m == 1:
        return xy.copy(), False
    start = int(np.argmax(csgraph.dijkstra(tree, directed=False, indices=0)))
    dist, pred = csgraph.dijkstra(tree, directed=False, indices=start, return_predecessors=True)
    node = int(np.argmax(dist))
    path = [node]
    while pred[node] >= 0:
        node = int(pred[node])
        path.append(node)
    backbone = moving_average(xy[path[::-1]], window, closed=False)
    seq = xy[np.argsort(_arc_parameter(xy, backbone), kind="stable")]
    end_gap = float(np.linalg.norm(seq[-1] - seq[0]))
    length = float(np.linalg.norm(np.diff(seq, axis=0), axis=1).sum())
    closed = m >= 4 and end_gap <= gap_mm and length >= np.pi * end_gap and length > 2 * gap_mm
    seq = moving_average(seq, window, closed=closed)
    if closed:
        x, y = seq[:, 0], seq[:, 1]
        if (x * np.roll(y, -1) - np.roll(x, -1) * y).sum() < 0:  # clockwise in (u, v)
            seq = seq[::-1]
        seq = np.roll(seq, -int(np.argmin(seq[:, 0])), axis=0)
    else:
        step = seq[-1] - seq[0]
        if step[0] < 0 or (step[0] == 0 and step[1] < 0):
            seq = seq[::-1]
    return seq, closed


def _arc_parameter(xy: np.ndarray, line: np.ndarray) -> np.ndarray:
    """(m,) arc length along the polyline ``line`` (b, 2) of each point's closest point on it.

    The first and last segments are extended beyond the ends (negative arc length before the start, more than
    the length after the end).
    """
    if len(line) == 1:
        return np.zeros(len(xy))
    seg = np.diff(line, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    arc = np.r_[0.0, np.cumsum(seg_len)]
    _, near = cKDTree(line).query(xy)
    best_s = np.zeros(len(xy))
    best_d = np.full(len(xy), np.inf)
    for first in (near - 1, near):  # the two segments that meet at the nearest vertex
        s = np.clip(first, 0, len(seg) - 1)
        rel = xy - line[s]
        t = np.einsum("ij,ij->i", rel, seg[s]) / np.maximum(seg_len[s] ** 2, 1e-300)
        # beyond the ends the line is extended straight, so points past an end keep their order
        t = np.clip(t, np.where(s == 0, -np.inf, 0.0), np.where(s == len(seg) - 1, np.inf, 1.0))
        d = np.linalg.norm(rel - t[:, None] * seg[s], axis=1)
        better = d < best_d
        best_d = np.where(better, d, best_d)
        best_s = np.where(better, arc[s] + t * seg_len[s], best_s)
    return best_s


def moving_average(seq: np.ndarray, window: int, *, closed: bool) -> np.ndarray:
    """Centred moving average over ``window`` points along an ordered sequence.

    Parameters
    ----------
    seq : (m, d) float
    window : int
        Points per average; an even window is used as ``window + 1``. 1 returns a copy.
    closed : bool
        Wrap around (closed polyline). Otherwise the window shrinks symmetrically near the ends, so the first
        and last points stay where they are.

    Returns
    -------
    (m, d) float
    """
    seq = np.asarray(seq, dtype=float)
    m = len(seq)
    half = int(window) // 2
    if half == 0 or m < 3:
        return seq.copy()
    if closed:
        half = min(half, (m - 1) // 2)
        padded = np.concatenate([seq[-half:], seq, seq[:half]]) if half else seq
        csum = np.concatenate([np.zeros((1, seq.shape[1])), np.cumsum(padded, axis=0)])
        return (csum[2 * half + 1 :] - csum[:m]) / (2 * half + 1)
    csum = np.concatenate([np.zeros((1, seq.shape[1])), np.cumsum(seq, axis=0)])
    i = np.arange(m)
    h = np.minimum(half, np.minimum(i, m - 1 - i))
    return (csum[i + h + 1] - csum[i - h]) / (2 * h + 1)[:, None]


# ---------------------------------------------------------------------------------------------------- normals


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
    k = _count(k, "k", 3)
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
    k = _count(k, "k", 3)
    if len(points) < 3:
        raise ConfigError("plane fit normals need at least 3 cloud points")
    if len(query) == 0:
        return np.zeros((0, 3))
    k = int(min(k, len(points)))
    return pca_fit(query, np.inf, max_neighbours=k, min_neighbours=k, center="mean", data=points)[0]


# ---------------------------------------------------------------------------------------------------- checks


def _unit_vector(vector, name: str) -> np.ndarray:
    out = np.asarray(vector, dtype=float).reshape(-1)
    if out.shape != (3,) or not np.isfinite(out).all() or np.linalg.norm(out) == 0:
        raise ConfigError(f"{name} must be a finite non-zero 3-vector, got {vector!r}")
    return out / np.linalg.norm(out)


def _positive(value, name: str) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ConfigError(f"{name} must be a positive number, got {value}")
    return value


def _count(value, name: str, least: int) -> int:
    if isinstance(value, bool) or int(value) != value or value < least:
        raise ConfigError(f"{name} must be an integer >= {least}, got {value!r}")
    return int(value)
