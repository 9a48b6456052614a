"""Slab sections of a point cloud as a ``layers.SectionSource`` (seed 003 sections 2.1-2.2 and 3.2.2).

Before slicing, the cloud is cleaned (``paths.cloudprep``: statistical outlier removal, space sampling,
optional smoothing) and given outward normals (the file's, or PCA oriented by propagation). A plane's section
is the slab of points within the slab half-width of it, projected onto the plane and ordered into polylines
(``paths.cloud_slicing``), streamlined by the angle method (2.1.1), with normals at the section points by the
neighbour-triangle method (3.2.2, area weighted) or a plane fit, turned to agree with the nearest cloud points'
oriented normals and smoothed along the polyline. Distances between sections are to the slab's points.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.config import PathConfig
from sprayplan.paths import cloudprep
from sprayplan.paths import polyline as pl
from sprayplan.paths.cloud_normals import neighbour_triangle_normals, plane_fit_normals
from sprayplan.paths.cloud_slicing import slice_cloud
from sprayplan.paths.frame import covariance
from sprayplan.paths.pieces import smooth_normals
from sprayplan.surface import normals as nm
from sprayplan.types import Part

#: Streamlining thresholds used for clouds when the config sets none (degrees): nearly straight points go.
CLOUD_STREAMLINE_DEG = (175.0, 180.0)


def cloud_sections(part: Part, config: PathConfig) -> CloudSections | None:
    """The slab sections of a cleaned point cloud; None when too few points are left to slice."""
    points = part.vertices
    given = part.vertex_normals
    keep = cloudprep.remove_outliers(points)
    keep = keep[cloudprep.space_sample(points[keep])]
    points = points[keep]
    given = None if given is None else given[keep]
    if config.cloud_smooth_mm is not None:
        points = cloudprep.smooth(points, config.cloud_smooth_mm)
    if len(points) < 3:
        return None
    return CloudSections(part.name, points, given, config)


class CloudSections:
    """Slab sections of a cleaned cloud (see :func:`cloud_sections`).

    Parameters
    ----------
    name : str
    points : (n, 3) float, mm
        The cleaned cloud, n >= 3.
    given : (n, 3) float or None
        Outward normals from the file; None: PCA normals oriented by propagation.
    config : PathConfig
        ``slab_mm``, ``streamline_deg``, ``cloud_normals``, ``cloud_normal_smooth_mm``, ``spray_radius_mm``.
    """

    def __init__(self, name: str, points: np.ndarray, given, config: PathConfig):
        self.name = name
        self.points = points
        self.tree = tree = cKDTree(points)
        self.spacing = spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
        if given is not None:
            self.normals = nm.unit(given)
        else:
            pca = nm.pca_normals(points, 4 * spacing, tree=tree, center="mean")
            self.normals = nm.orient_propagate(points, pca, tree=tree)
        self.slab = config.slab_mm if config.slab_mm is not None else max(2.0 * spacing, 0.5)
        self.thresholds = np.radians(config.streamline_deg or CLOUD_STREAMLINE_DEG)
        radius = config.spray_radius_mm
        self.smooth = radius / 2 if config.cloud_normal_smooth_mm is None else config.cloud_normal_smooth_mm
        self.triangles = config.cloud_normals == "triangles"

    def covariance(self) -> np.ndarray:
        return covariance(self.points)

    def use_frame(self, normal, travel) -> tuple[float, float]:
        self.plane_normal, self.travel = normal, travel
        height = self.points @ normal
        self._order = np.argsort(height)
        self._sorted_h = height[self._order]
        return float(height.min()), float(height.max())

    def boundary(self, step: float) -> np.ndarray:
        """The cloud's edge points (:func:`cloud_boundary`); as dense as the cloud, whatever ``step``."""
        return self.points[cloud_boundary(self.points, self.normals, self.tree)]

    def _slab_points(self, offset: float) -> np.ndarray:
        i0, i1 = np.searchsorted(self._sorted_h, [offset - self.slab, offset + self.slab])
        chosen = self.points[self._order[i0:i1]]
        return chosen - np.outer(chosen @ self.plane_normal - offset, self.plane_normal)

    def samples(self, offset: float) -> np.ndarray:
        found = self._slab_points(offset)
        return found[np.linspace(0, len(found) - 1, min(len(found), 400)).astype(int)] if len(found) else found

    def distance(self, query: np.ndarray, offset: float) -> float:
        found = self._slab_points(offset)
        return float(np.median(cKDTree(found).query(query)[0])) if len(found) else np.inf

    def sections(self, offset: float) -> list[tuple[np.ndarray, np.ndarray, bool]]:
        gap = 5.0 * self.spacing
        (polylines,) = slice_cloud(self.points, self.plane_normal, [offset], self.slab, gap_mm=gap, travel=self.travel)
        out = []
        for line in polylines:
            closed = _is_closed(line, gap)
            if len(line) >= 3:
                line = line[pl.streamline(line, self.thresholds[0], self.thresholds[1], closed=closed)]
            if len(line) < 2:
                continue
            out.append((line, self._line_normals(line, closed), closed))
        return out

    def _line_normals(self, line: np.ndarray, closed: bool) -> np.ndarray:
        """003 section 3.2.2: the normal from the neighbour triangles around each section point (or a plane
        fit), turned to agree with the oriented normals of the nearest cloud points, smoothed along the line."""
        near = self.tree.query(line, k=min(8, len(self.points)))[1]
        if self.triangles:
            fitted = neighbour_triangle_normals(line, self.points, k=8)
        else:
            fitted = plane_fit_normals(line, self.points, k=12)
        line_n = nm.orient_like(fitted, self.normals[near].mean(axis=1))
        return smooth_normals(line, line_n, self.smooth, closed=closed)

    def describe(self) -> str:
        return f", cloud slab +-{self.slab:.3g} mm"


def cloud_boundary(points: np.ndarray, normals: np.ndarray, tree: cKDTree, k: int = 32) -> np.ndarray:
    """(n,) bool: cloud points on the scanned surface's open edge.

    A point inside the surface has its k nearest neighbours all round it; on an edge they lie to one side, so
    their mean, projected onto the tangent plane, moves away from the point: by about 0.6 of their mean
    distance for a straight edge (the centroid of a half disc), 0 inside (up to the scatter of k random
    neighbours: 32 keep it under 0.45 on an unevenly sampled plate). Points where it moves by more than 0.45
    of that distance are edge points.
    """
    k = min(k, len(points) - 1)
    if k < 3:
        return np.zeros(len(points), bool)
    _, index = tree.query(points, k + 1)
    offset = points[index[:, 1:]] - points[:, None, :]
    offset -= np.einsum("nkj,nj->nk", offset, normals)[:, :, None] * normals[:, None, :]
    shift = np.linalg.norm(offset.mean(axis=1), axis=1)
    spread = np.linalg.norm(offset, axis=2).mean(axis=1)
    return shift > 0.45 * np.maximum(spread, 1e-12)


def _is_closed(line: np.ndarray, gap: float) -> bool:
    return len(line) > 3 and np.linalg.norm(line[0] - line[-1]) <= gap and pl.polyline_length(line) > 4 * gap
