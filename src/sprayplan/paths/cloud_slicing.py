"""Slicing a point cloud into section polylines (seed 003, section 2.1).

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

The normals at the sampling points (section 3.2.2) are in ``cloud_normals``.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from sprayplan.checks import check_count, check_points, check_positive
from sprayplan.errors import ConfigError

log = logging.getLogger(__name__)


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
    DataError
        Bad points.
    ConfigError
        A zero normal, a travel direction along the normal, or non-positive sizes.
    """
    points = check_points(points)
    normal = _unit_vector(plane_normal, "plane_normal")
    offsets = np.atleast_1d(np.asarray(offsets, dtype=float))
    if offsets.ndim != 1 or not np.isfinite(offsets).all():
        raise ConfigError(f"offsets must be a finite 1-D sequence, got shape {offsets.shape}")
    half_thickness_mm = check_positive(half_thickness_mm, "half_thickness_mm")
    gap_mm = check_positive(gap_mm, "gap_mm")
    smooth_points = check_count(smooth_points, "smooth_points", 1)
    min_points = check_count(min_points, "min_points", 1)
    k = check_count(k, "k", 1)
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


# ---------------------------------------------------------------------------------------------------- checks


def _unit_vector(vector, name: str) -> np.ndarray:
    out = np.asarray(vector, dtype=float).reshape(-1)
    if out.shape != (3,) or not np.isfinite(out).all() or np.linalg.norm(out) == 0:
        raise ConfigError(f"{name} must be a finite non-zero 3-vector, got {vector!r}")
    return out / np.linalg.norm(out)
