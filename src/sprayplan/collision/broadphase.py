"""Lower bounds on the cell's distances, vectorised over many joint vectors: which pairs need an exact query.

A plan has tens of thousands of waypoints and each has some forty body pairs; nearly all of them are far apart
(the gun stands its standoff off the surface, the upper arm far above it). coal answers one pair at a time, so
:class:`~sprayplan.collision.cell.CellCollision` first bounds every pair from below here, in numpy, and asks
coal only for the pairs whose bound leaves less than a margin over their required gap. The bounds never
decide a collision on their own: a pair is in collision only by coal's distance.

The bounds (``s`` the spacing of points along a capsule's segment, so every segment point is within ``s / 2``
of one of them):

- capsule to part: the part's surface is sampled (:class:`SurfaceSamples`) so that every surface point lies
  within ``h`` of a sample; a point ``x`` whose nearest sample is ``d_s`` away is at least ``d_s - h`` from the
  surface. Over the segment's points: ``min d_s - h - s / 2 - r``. A voxel grid of distances
  (:class:`DistanceGrid`) bounds the capsule's bounding sphere and its pieces' first, far more cheaply, from
  below and from above; only the points it leaves near the surface go to the k-d tree, and a capsule it
  proves within the margin goes to the exact query at once (:func:`capsules_to_surface`). A point cloud's
  balls (:mod:`~sprayplan.collision.spheres`) are bounded the same way, their centres the samples and their
  radius the cover;
- capsule to box (the gantry's axis-aligned carriage and column): the capsule's bounding sphere, then the
  exact point-to-box distance of the segment's points, ``- s / 2 - r``;
- capsule to capsule: the two bounding spheres, then the least distance between the two segments' points,
  ``- s - r_a - r_b``;
- capsule or box to the floor (a half-space ``z <= floor``), and the TCP's height: exact (the lowest end's
  height minus the radius, the box's bottom).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.types import Part


@dataclass(frozen=True)
class DistanceGrid:
    """Distances from voxel centres to the nearest voxel holding a surface sample, for quick lower bounds.

    A point ``x`` in voxel ``i`` (centre ``c_i``, side ``v``) is at least ``EDT(i) - v sqrt(3) - cover`` from the
    surface: ``|x - c_i| <= v sqrt(3) / 2``, every surface point is within ``cover`` of a sample, and every
    sample within ``v sqrt(3) / 2`` of its voxel's centre, whose distance from ``c_i`` is at least ``EDT(i)``.
    Outside the grid (``pad_mm`` beyond the samples on every side) a point is at least ``pad_mm - cover`` away.
    """

    origin: np.ndarray
    voxel_mm: float
    edt_mm: np.ndarray
    pad_mm: float
    cover_mm: float

    def lower_bound_mm(self, flat: np.ndarray) -> np.ndarray:
        """(k,) lower bounds on the distances of points (k, 3) to the surface."""
        return self.bounds_mm(flat)[0]

    def bounds_mm(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k,) lower bounds on the distances of points (k, 3) to the surface, and (k,) upper bounds on their
        distances to the nearest sample (so to the surface, where the samples lie): ``EDT(i) + v sqrt(3)``
        inside the grid (the sample in the nearest held voxel is within ``v sqrt(3) / 2`` of its centre, the
        point within as much of its own), inf outside."""
        index = np.floor((flat - self.origin) / self.voxel_mm).astype(np.int64)
        shape = np.array(self.edt_mm.shape)
        inside = ((index >= 0) & (index < shape)).all(axis=1)
        lower = np.full(len(flat), self.pad_mm - self.cover_mm)
        upper = np.full(len(flat), np.inf)
        i = index[inside]
        edt = self.edt_mm[i[:, 0], i[:, 1], i[:, 2]].astype(float)
        lower[inside] = edt - self.voxel_mm * math.sqrt(3.0) - self.cover_mm
        upper[inside] = edt + self.voxel_mm * math.sqrt(3.0)
        return lower, upper


def distance_grid(points: np.ndarray, cover_mm: float, voxel_mm: float = 10.0, pad_mm: float = 200.0) -> DistanceGrid:
    """The :class:`DistanceGrid` of surface samples (scipy's exact Euclidean distance transform)."""
    from scipy.ndimage import distance_transform_edt

    origin = points.min(axis=0) - pad_mm
    shape = np.ceil((points.max(axis=0) + pad_mm - origin) / voxel_mm).astype(int) + 1
    free = np.ones(tuple(shape), dtype=bool)
    index = np.floor((points - origin) / voxel_mm).astype(np.int64)
    free[index[:, 0], index[:, 1], index[:, 2]] = False
    edt = distance_transform_edt(free, sampling=voxel_mm).astype(np.float32)
    return DistanceGrid(origin, float(voxel_mm), edt, float(pad_mm), float(cover_mm))


#: Queries of at least this many points use every core (``cKDTree.query(workers=-1)``).
PARALLEL_QUERIES = 50_000


@dataclass(frozen=True)
class SurfaceSamples:
    """Points on a mesh's surface with every surface point within ``cover_mm`` of one of them.

    Attributes
    ----------
    points : (m, 3) float, mm
    cover_mm : float
        The covering radius ``h`` (see the module docstring).
    tree : scipy.spatial.cKDTree
    grid : DistanceGrid
        Quick, looser bounds: only points it leaves near the surface are looked up in the tree.
    """

    points: np.ndarray
    cover_mm: float
    tree: cKDTree
    grid: DistanceGrid

    def lower_bound_mm(self, x: np.ndarray, upper_mm: float) -> np.ndarray:
        """(...) float: a lower bound on each point's distance to the surface, at most ``upper_mm`` (a cap that
        keeps it a lower bound): the grid's bound, and the tree's (``nearest sample - cover``) where the grid
        leaves less than ``upper_mm``."""
        x = np.asarray(x, dtype=float)
        flat = x.reshape(-1, 3)
        out = self.grid.lower_bound_mm(flat)
        near = np.flatnonzero(out < upper_mm)
        if len(near):
            workers = -1 if len(near) >= PARALLEL_QUERIES else 1  # threads cost more than they save on few points
            d, _ = self.tree.query(flat[near], k=1, distance_upper_bound=upper_mm + self.cover_mm, workers=workers)
            out[near] = np.maximum(out[near], np.minimum(d, upper_mm + self.cover_mm) - self.cover_mm)
        return np.minimum(out, upper_mm).reshape(x.shape[:-1])


def surface_samples(part: Part, cover_mm: float = 10.0) -> SurfaceSamples:
    """Sample a mesh part's triangles on barycentric grids fine enough that every surface point is within
    ``cover_mm`` of a sample.

    A triangle split into ``m x m`` similar sub-triangles has sub-edges at most ``e / m`` long (``e`` its
    longest edge). Every point of a triangle lies within ``e' / sqrt(3)`` of one of its corners, ``e'`` its
    longest edge (in an acute triangle the farthest point is the circumcentre, at ``R = e' / (2 sin A)`` with
    the angle ``A >= 60`` degrees opposite the longest edge; in a right or obtuse one it is no farther). So
    ``m = ceil(e / (sqrt(3) cover))`` and the grid's points (the sub-triangles' corners) cover the triangle.
    """
    vertices = np.asarray(part.vertices, dtype=float)
    faces = np.asarray(part.faces, dtype=np.int64)
    tri = vertices[faces]  # (f, 3, 3)
    edges = np.linalg.norm(tri - np.roll(tri, -1, axis=1), axis=2).max(axis=1)
    m = np.maximum(1, np.ceil(edges / (math.sqrt(3.0) * cover_mm) - 1e-9)).astype(int)
    chunks = [vertices]
    for level in np.unique(m[m > 1]):
        pick = tri[m == level]
        i, j = np.meshgrid(np.arange(level + 1), np.arange(level + 1), indexing="ij")
        keep = i + j <= level
        a, b = i[keep] / level, j[keep] / level
        interior = ~(((a == 0) & (b == 0)) | ((a == 1) & (b == 0)) | ((a == 0) & (b == 1)))  # corners are vertices
        a, b = a[interior], b[interior]
        weights = np.stack([1.0 - a - b, a, b], axis=1)  # (g, 3)
        chunks.append(np.einsum("gk,fkd->fgd", weights, pick).reshape(-1, 3))
    points = np.concatenate(chunks)
    return SurfaceSamples(points, float(cover_mm), cKDTree(points), distance_grid(points, cover_mm))


def segment_points(segments: np.ndarray, spacing_mm: float) -> tuple[np.ndarray, float]:
    """Points along segments ``(..., 2, 3)``, the same count on each, at most ``spacing_mm`` apart.

    Returns the points ``(..., k, 3)`` and half the largest gap between neighbours, the most any segment point
    lies from one of them.
    """
    length = np.linalg.norm(segments[..., 1, :] - segments[..., 0, :], axis=-1)
    longest = float(length.max()) if length.size else 0.0
    k = max(2, math.ceil(longest / spacing_mm) + 1)
    t = np.linspace(0.0, 1.0, k)
    points = segments[..., :1, :] + t[:, None] * (segments[..., 1:, :] - segments[..., :1, :])
    return points, longest / (k - 1) / 2.0


def capsules_to_surface(
    samples: SurfaceSamples,
    segments: np.ndarray,
    radius_mm: float,
    upper_mm: float,
    spacing_mm: float,
    envelope: bool = False,
) -> np.ndarray:
    """(n,) lower bounds on the distance from capsules (segments ``(n, 2, 3)``, one radius) to the sampled
    surface, capped near ``upper_mm``: bounding spheres of the whole segment, then of pieces about
    ``4 spacing`` long, then points ``spacing`` apart, each level only where the last left less than
    ``upper_mm``. Every level is a lower bound (a sphere of radius ``rho`` about ``c`` holds the capsule part,
    so its distance is at least ``lb(c) - rho``); the best of them is kept.

    A capsule is not refined further once a level proves it nearer than ``upper_mm``: a ball of the capsule's
    radius about a segment point ``x`` lies inside the capsule, so the capsule is at most ``d(x) - radius`` from
    the surface (``d(x)`` the distance to ``x``'s nearest sample, bounded from above by
    :meth:`DistanceGrid.bounds_mm`), and a capsule whose bound is below ``upper_mm`` for certain needs its exact
    distance whatever a finer bound would say. The two coarse levels use the grid alone (a k-d tree query far
    from a dense surface costs ten times one near it); the points, the tree where the grid leaves them near. ``envelope`` True: the capsule only encloses the body bounded (a box), whose distance it does not
    bound from above, so every level is refined."""
    start, end = segments[:, 0], segments[:, 1]
    length = np.linalg.norm(end - start, axis=1)
    reach = length / 2.0 + radius_mm
    lower, above = samples.grid.bounds_mm((start + end) / 2.0)
    out = np.minimum(lower - reach, upper_mm)
    near = np.flatnonzero((out < upper_mm) & (envelope | (above - radius_mm >= upper_mm)))
    if not len(near):
        return out
    pieces = max(1, math.ceil(float(length[near].max()) / (4.0 * spacing_mm)))
    t = (np.arange(pieces) + 0.5) / pieces
    centres = start[near, None] + t[None, :, None] * (end[near] - start[near])[:, None]  # (k, pieces, 3)
    piece_reach = (length[near] / pieces / 2.0 + radius_mm)[:, None]
    lower, above = samples.grid.bounds_mm(centres.reshape(-1, 3))
    level1 = np.minimum(lower.reshape(len(near), pieces) - piece_reach, upper_mm)  # (k, pieces)
    out[near] = np.maximum(out[near], level1.min(axis=1))
    settled = (
        np.zeros(len(near), bool) if envelope else above.reshape(len(near), pieces).min(axis=1) - radius_mm < upper_mm
    )
    rows, which = np.nonzero((level1 < upper_mm) & ~settled[:, None])
    if not len(rows):
        return out
    a = start[near[rows]] + (which / pieces)[:, None] * (end[near[rows]] - start[near[rows]])
    b = start[near[rows]] + ((which + 1) / pieces)[:, None] * (end[near[rows]] - start[near[rows]])
    points, half = segment_points(np.stack([a, b], axis=1), spacing_mm)
    fine = samples.lower_bound_mm(points, upper_mm + half + radius_mm).min(axis=1) - half - radius_mm
    # a piece's fine bound replaces its sphere's; the capsule's bound is the least over its pieces
    level1[rows, which] = np.maximum(level1[rows, which], fine)
    out[near] = np.maximum(out[near], level1.min(axis=1))
    return out


def point_box_distance(points: np.ndarray, centres: np.ndarray, half_sizes: np.ndarray) -> np.ndarray:
    """Distances from points ``(..., 3)`` to axis-aligned boxes (centres broadcast with the points, half sizes
    (3,)); 0 inside."""
    gap = np.maximum(np.abs(points - centres) - half_sizes, 0.0)
    return np.linalg.norm(gap, axis=-1)


def segments_gap(a_points: np.ndarray, b_points: np.ndarray) -> np.ndarray:
    """The least distance between two sets of points along segments: ``(n, ka, 3)`` and ``(n, kb, 3)`` -> (n,)."""
    diff = a_points[:, :, None, :] - b_points[:, None, :, :]
    return np.sqrt(np.einsum("nijd,nijd->nij", diff, diff).min(axis=(1, 2)))
