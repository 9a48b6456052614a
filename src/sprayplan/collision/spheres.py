"""A point cloud as a solid body: every point a sphere of one radius (:class:`SphereSet`).

A scanned part has no triangles to put in a BVH; its collision body is the union of balls of radius ``r``
about its points. That body holds the scanned surface when every surface point lies within ``r`` of a scan
point (``r`` at least the cloud's covering radius), so a distance to it is never larger than the distance to
the surface it samples: a body kept ``clearance`` from the balls is at least ``clearance`` from the surface.
The radius is ``[collision] cloud_radius_mm``, or by default :func:`cloud_radius_mm` from the spacing.

Why balls and not a reconstructed surface: a reconstruction (Poisson, ball pivoting) needs a heavy library or
much code, invents surface across holes and fails on thin or noisy scans, and its distances are exact only to
a surface that is itself a guess. The balls use the cloud as measured, and they fit the lower-bound path of
:mod:`~sprayplan.collision.broadphase` unchanged: the nearest point minus ``r`` *is* the distance to the balls
(:func:`cloud_samples`), so the voxel grid and the k-d tree bound capsules and boxes against them exactly as
they bound them against a mesh's surface samples.

Exact distances near the gap (:func:`capsules_to_spheres`, :func:`boxes_to_spheres`) are closed-form: the
distance from a capsule (a segment swept by a ball) to a ball is the distance from the ball's centre to the
segment minus both radii, and from an axis-aligned box to a ball the point-to-box distance minus ``r``. The
k-d tree finds the points that can be nearest: with ``u`` the distance from one point ``c`` of the body's core
(the segment's or the box's) to its nearest cloud point, the nearest cloud point to the core lies within
``u + rho`` of the core's centre (``rho`` the core's half-length or half-diagonal), and only those are measured.
The tests compare these distances with coal's sphere-to-capsule and sphere-to-box distances.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.collision.broadphase import SurfaceSamples, distance_grid
from sprayplan.errors import DataError


def cloud_radius_mm(points: np.ndarray) -> float:
    """The default ball radius of a cloud, mm: ``s / sqrt(2)``, ``s`` the median of its points'
    nearest-neighbour distances.

    On a square grid of spacing ``s`` the farthest a surface point lies from a grid point is ``s / sqrt(2)`` (on
    a triangular grid ``s / sqrt(3)``), so the balls hold the surface of a regular scan. Where a scan is
    sparser than its median (a gap of ``g > s``), the surface in the gap can lie up to about
    ``g / sqrt(2) - r`` outside the balls, and a distance to them is that much too large there: set
    ``[collision] cloud_radius_mm`` for an uneven scan. The median rather than a high quantile, because the
    balls also swell the surface by ``r`` where it is well sampled: on a sparse cloud (the bundled reach part's
    262 points, ``s`` = 63 mm, 99 mm at the 95th percentile) balls of the 95th percentile reach most of the
    way to the gun at its 113 mm standoff and every waypoint would be in collision.

    Raises
    ------
    DataError
        Fewer than two distinct points.
    """
    points = np.asarray(points, dtype=float)
    unique = np.unique(points, axis=0)
    if len(unique) < 2:
        raise DataError("a point cloud needs at least two distinct points for its collision body")
    distance, _ = cKDTree(unique).query(unique, k=2)
    return float(np.median(distance[:, 1])) / math.sqrt(2.0)


@dataclass(frozen=True)
class SphereSet:
    """A point cloud's collision body: a ball of ``radius_mm`` about every point.

    Attributes
    ----------
    points : (m, 3) float, mm
    radius_mm : float
    tree : scipy.spatial.cKDTree
        Of ``points``.
    """

    points: np.ndarray
    radius_mm: float
    tree: cKDTree

    @classmethod
    def of(cls, points: np.ndarray, radius_mm: float) -> SphereSet:
        points = np.ascontiguousarray(points, dtype=float)
        return cls(points, float(radius_mm), cKDTree(points))


def cloud_samples(spheres: SphereSet) -> SurfaceSamples:
    """The balls as :class:`~sprayplan.collision.broadphase.SurfaceSamples`: the points with ``cover_mm`` the
    radius, so that ``nearest point - cover`` (the samples' lower bound) is the distance to the balls."""
    return SurfaceSamples(
        spheres.points, spheres.radius_mm, spheres.tree, distance_grid(spheres.points, spheres.radius_mm)
    )


def _point_segment_mm(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k,) distances from points (k, 3) to the segment a-b."""
    ab = b - a
    length2 = float(ab @ ab)
    t = np.zeros(len(points)) if length2 == 0 else np.clip((points - a) @ ab / length2, 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


def _near_points(spheres: SphereSet, centres: np.ndarray, reach: np.ndarray) -> list:
    """Per core (centres (k, 3); ``reach`` (k,) the farthest any core point is from its centre), the indices
    of the points that can be nearest to the core: those within ``u + reach`` of the centre, ``u`` the centre's
    nearest point's distance. The core's least distance ``D`` is at most ``u``, and the point at ``D`` from
    some core point ``x`` is within ``D + |x - centre| <= u + reach`` of the centre."""
    u, _ = spheres.tree.query(centres, k=1)
    return spheres.tree.query_ball_point(centres, u + reach + 1e-9)


def capsules_to_spheres(spheres: SphereSet, segments: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(k,) float, mm: the exact signed distance from capsules (segments (k, 2, 3), radii (k,)) to the balls:
    the least centre-to-segment distance minus the two radii (negative: overlapping)."""
    segments = np.asarray(segments, dtype=float).reshape(-1, 2, 3)
    radii = np.broadcast_to(np.asarray(radii, dtype=float), (len(segments),))
    centres = segments.mean(axis=1)
    half = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1) / 2.0
    out = np.empty(len(segments))
    for i, near in enumerate(_near_points(spheres, centres, half)):
        core = _point_segment_mm(spheres.points[near], segments[i, 0], segments[i, 1]).min()
        out[i] = core - radii[i] - spheres.radius_mm
    return out


def boxes_to_spheres(spheres: SphereSet, centres: np.ndarray, half_sizes: np.ndarray) -> np.ndarray:
    """(k,) float, mm: the exact signed distance from axis-aligned boxes (centres (k, 3), half sizes (k, 3)) to
    the balls. Inside a box a point's distance counts as 0 (then the result is ``-radius``: overlapping)."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 3)
    half_sizes = np.broadcast_to(np.asarray(half_sizes, dtype=float), centres.shape)
    out = np.empty(len(centres))
    reach = np.linalg.norm(half_sizes, axis=1)
    for i, near in enumerate(_near_points(spheres, centres, reach)):
        gap = np.maximum(np.abs(spheres.points[near] - centres[i]) - half_sizes[i], 0.0)
        out[i] = float(np.sqrt((gap * gap).sum(axis=1)).min()) - spheres.radius_mm
    return out
