"""Point-cloud preprocessing before slicing (seed 003, section 2.2), each step as an algorithm.

The seed does these steps by hand in a commercial tool (Imageware): deleting outliers (2.2.1), filling gaps in
scan lines (2.2.2, "Fill Gap"), smoothing (2.2.3) and streamlining by "space sampling" with a distance
tolerance of 0.4 mm (2.2.4). Here they are:

:func:`remove_outliers`
    Statistical outlier removal: a point whose mean distance to its k nearest neighbours is far above the
    cloud's typical value is dropped (the seed circles or picks the "abnormal points" by eye).
:func:`smooth`
    Each point is moved onto the least-squares plane of its neighbours within a radius (moving least squares
    of degree one), which removes noise across the surface and keeps the surface's shape.
:func:`space_sample`
    Greedy thinning in file order: a point is dropped when an earlier kept point lies within the tolerance, so
    overlapping scans collapse to one layer and no two kept points are closer than the tolerance.
:func:`fill_gaps`
    Linear interpolation across the small gaps of a scan line or section polyline; gaps wider than a limit are
    real holes and are left open.
:func:`preprocess`
    Outliers -> smoothing -> space sampling, chained.

All functions are pure: they return new arrays (or indices into the input) and never change their inputs.
Lengths are in mm.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.checks import check_points, check_positive
from sprayplan.errors import ConfigError
from sprayplan.surface.filling import poisson_disk_select

log = logging.getLogger(__name__)

#: The seed's distance tolerance for space sampling (section 2.2.4), mm.
SPACE_SAMPLING_TOLERANCE_MM = 0.4

#: Query points per block in :func:`smooth` (bounds the memory of the neighbour arrays).
_BLOCK = 20_000


def remove_outliers(points: np.ndarray, k: int = 16, std_ratio: float = 2.0) -> np.ndarray:
    """Statistical outlier removal (seed 003, section 2.2.1).

    For every point the mean distance ``d_i`` to its ``k`` nearest neighbours (itself excluded) is computed;
    a point is kept when ``d_i <= mean(d) + std_ratio * std(d)``, the mean and the standard deviation taken
    over the whole cloud.

    Parameters
    ----------
    points : (n, 3) float, mm
    k : int
        Neighbours per point (at least 1; reduced to ``n - 1`` for tiny clouds).
    std_ratio : float
        How many standard deviations above the mean a point's mean distance may lie (positive).

    Returns
    -------
    keep : (m,) int
        Indices of the kept points, increasing.

    Raises
    ------
    DataError
        ``points`` not (n, 3) and finite.
    ConfigError
        ``k < 1`` or ``std_ratio <= 0``.
    """
    points = check_points(points)
    if int(k) != k or k < 1:
        raise ConfigError(f"outlier k must be a positive integer, got {k}")
    std_ratio = check_positive(std_ratio, "outlier std_ratio")
    n = len(points)
    kk = int(min(k, n - 1))
    if kk < 1:
        return np.arange(n)
    dist, _ = cKDTree(points).query(points, k=kk + 1)
    mean_dist = dist[:, 1:].mean(axis=1)
    threshold = mean_dist.mean() + std_ratio * mean_dist.std()
    keep = np.flatnonzero(mean_dist <= threshold)
    log.debug("outlier removal: %d of %d points dropped (threshold %.4g mm)", n - len(keep), n, threshold)
    return keep


def smooth(points: np.ndarray, radius_mm: float, iterations: int = 1, *, max_neighbours: int = 64) -> np.ndarray:
    """Smoothing by projection onto the local least-squares plane (seed 003, section 2.2.3).

    In each iteration every point ``p`` is replaced by its orthogonal projection onto the plane through the
    mean ``c`` of its neighbourhood (the points within ``radius_mm``, ``p`` included) whose normal ``m`` is the
    eigenvector of the neighbourhood's covariance with the smallest eigenvalue (PCA):
    ``p' = p - ((p - c) . m) m``. Where the neighbours are collinear (a single scan line) the plane is not
    defined and ``p`` is projected onto the fitted line instead. Points with fewer than 4 other points within
    the radius stay where they are. All points of one iteration are computed from the previous iteration's
    cloud (Jacobi, so the result does not depend on the order of the points).

    Parameters
    ----------
    points : (n, 3) float, mm
    radius_mm : float
        Neighbourhood radius; a few times the point spacing (too large flattens real curvature).
    iterations : int
        Number of passes (0 returns a copy).
    max_neighbours : int
        At most this many nearest points within the radius are used per point.

    Returns
    -------
    smoothed : (n, 3) float, mm
        Same order as ``points``.

    Raises
    ------
    DataError
        Bad ``points``.
    ConfigError
        A non-positive radius, a negative number of iterations or ``max_neighbours < 5``.
    """
    points = check_points(points)
    radius_mm = check_positive(radius_mm, "smoothing radius_mm")
    if int(iterations) != iterations or iterations < 0:
        raise ConfigError(f"smoothing iterations must be a non-negative integer, got {iterations}")
    if int(max_neighbours) != max_neighbours or max_neighbours < 5:
        raise ConfigError(f"smoothing max_neighbours must be an integer >= 5, got {max_neighbours}")
    current = points
    n = len(points)
    if n < 5:
        return current
    k = int(min(max_neighbours, n))
    for _ in range(int(iterations)):
        tree = cKDTree(current)
        out = current.copy()
        for start in range(0, n, _BLOCK):
            block = current[start : start + _BLOCK]
            out[start : start + len(block)] = _project_block(block, current, tree, radius_mm, k)
        current = out
    return current


def _project_block(block, data, tree, radius, k):
    """Projections of ``block`` onto the PCA plane (or line) of their neighbours in ``data``."""
    dist, idx = tree.query(block, k=k, distance_upper_bound=radius)
    dist, idx = dist.reshape(len(block), k), idx.reshape(len(block), k)
    use = np.isfinite(dist)
    count = use.sum(axis=1)
    ok = count >= 5  # the point itself and at least 4 others
    out = block.copy()
    if not ok.any():
        return out
    rows = np.flatnonzero(ok)
    use = use[rows]
    nbr = data[np.minimum(idx[rows], len(data) - 1)]
    weight = use[..., None].astype(float)
    centre = (nbr * weight).sum(axis=1) / count[rows, None]
    local = (nbr - centre[:, None, :]) * weight
    values, vectors = np.linalg.eigh(local.transpose(0, 2, 1) @ local)
    p = block[rows]
    offset = p - centre
    normal = vectors[:, :, 0]
    plane = p - np.einsum("ij,ij->i", offset, normal)[:, None] * normal
    # collinear neighbours: the two smallest eigenvalues vanish; project onto the fitted line
    line_like = values[:, 1] <= 1e-10 * np.maximum(values[:, 2], 1e-300)
    axis = vectors[:, :, 2]
    line = centre + np.einsum("ij,ij->i", offset, axis)[:, None] * axis
    out[rows] = np.where(line_like[:, None], line, plane)
    return out


def space_sample(points: np.ndarray, tolerance_mm: float = SPACE_SAMPLING_TOLERANCE_MM) -> np.ndarray:
    """Space sampling with a distance tolerance (seed 003, section 2.2.4).

    Points are visited in file order; a point is kept unless an earlier kept point lies within
    ``tolerance_mm``. Afterwards no two kept points are within the tolerance of each other, and every dropped
    point lies within the tolerance of a kept one. Overlapping scans of the same area thus collapse to one
    layer while sparse areas keep every point.

    Parameters
    ----------
    points : (n, 3) float, mm
    tolerance_mm : float
        The distance tolerance; the seed uses 0.4 mm.

    Returns
    -------
    keep : (m,) int
        Indices of the kept points, increasing.
    """
    points = check_points(points)
    tolerance_mm = check_positive(tolerance_mm, "space sampling tolerance_mm")
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    return poisson_disk_select(points, tolerance_mm).astype(np.int64)


def fill_gaps(polyline: np.ndarray, max_gap_mm: float, step_mm: float, *, closed: bool = False) -> np.ndarray:
    """Fill the small gaps of a scan line or section polyline (seed 003, section 2.2.2, "Fill Gap").

    Where two consecutive points are more than ``step_mm`` but at most ``max_gap_mm`` apart, the fewest
    evenly spaced points that leave no step longer than ``step_mm`` are inserted on the straight segment
    between them (linear interpolation). Longer gaps are real holes (a slot in the part, the edge of a
    window) and are left open; shorter steps are left as they are.

    Parameters
    ----------
    polyline : (n, 3) float, mm
        Ordered points.
    max_gap_mm : float
        Widest gap that is filled.
    step_mm : float
        Largest distance between consecutive points inside a filled gap.
    closed : bool
        Also fill the gap from the last point back to the first (the first point is not repeated).

    Returns
    -------
    filled : (m, 3) float, mm
        The original points, in order, with the inserted points between them.

    Raises
    ------
    DataError
        Bad ``polyline``.
    ConfigError
        A non-positive step or a negative ``max_gap_mm``.
    """
    polyline = check_points(polyline, "polyline")
    step_mm = check_positive(step_mm, "fill step_mm")
    max_gap_mm = float(max_gap_mm)
    if not (np.isfinite(max_gap_mm) and max_gap_mm >= 0):
        raise ConfigError(f"fill max_gap_mm must be a non-negative number, got {max_gap_mm}")
    n = len(polyline)
    if n < 2:
        return polyline
    ends = np.roll(polyline, -1, axis=0) if closed else polyline[1:]
    starts = polyline if closed else polyline[:-1]
    length = np.linalg.norm(ends - starts, axis=1)
    fill = (length > step_mm) & (length <= max_gap_mm)
    extra = np.where(fill, np.ceil(length / step_mm - 1e-12).astype(np.int64) - 1, 0)
    per_point = np.ones(n, dtype=np.int64)  # each original point, followed by the points of its gap
    per_point[: len(extra)] += extra
    seg = np.repeat(np.arange(n), per_point)
    within = np.arange(len(seg)) - np.repeat(np.cumsum(per_point) - per_point, per_point)
    out = polyline[seg]
    inserted = within > 0
    i = seg[inserted]
    t = (within[inserted] / (extra[i] + 1))[:, None]
    out[inserted] = starts[i] + t * (ends[i] - starts[i])
    return out


def preprocess(
    points: np.ndarray,
    *,
    outlier_k: int = 16,
    outlier_std: float = 2.0,
    smooth_radius_mm: float | None = None,
    smooth_iterations: int = 1,
    tolerance_mm: float = SPACE_SAMPLING_TOLERANCE_MM,
) -> tuple[np.ndarray, np.ndarray]:
    """Outlier removal -> smoothing -> space sampling (seed 003, sections 2.2.1, 2.2.3, 2.2.4).

    Parameters
    ----------
    points : (n, 3) float, mm
    outlier_k, outlier_std
        :func:`remove_outliers`'s ``k`` and ``std_ratio``.
    smooth_radius_mm : float, optional
        :func:`smooth`'s radius. When not given: 2.5 times the median nearest-neighbour distance of the points
        left after outlier removal (about 15-20 neighbours on an evenly scanned surface).
    smooth_iterations : int
        Smoothing passes; 0 skips smoothing.
    tolerance_mm : float
        :func:`space_sample`'s distance tolerance (the seed's 0.4 mm by default).

    Returns
    -------
    points : (m, 3) float, mm
        The kept points after smoothing.
    kept : (m,) int
        For each returned point, the index of the input point it comes from (increasing).
    """
    points = check_points(points)
    kept = remove_outliers(points, k=outlier_k, std_ratio=outlier_std)
    cloud = points[kept]
    if smooth_iterations and len(cloud) >= 5:
        if smooth_radius_mm is None:
            nearest, _ = cKDTree(cloud).query(cloud, k=2)
            smooth_radius_mm = 2.5 * float(np.median(nearest[:, 1]))
            if smooth_radius_mm <= 0:  # more than half the points are duplicates
                smooth_radius_mm = tolerance_mm
        cloud = smooth(cloud, smooth_radius_mm, smooth_iterations)
    sampled = space_sample(cloud, tolerance_mm)
    log.debug("preprocess: %d -> %d -> %d points", len(points), len(kept), len(sampled))
    return cloud[sampled], kept[sampled]
