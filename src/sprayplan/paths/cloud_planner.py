"""Slicing layers of a point cloud (seed 003 sections 2.1-2.2 and 3.2): the cloud half of the paths stage."""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.config import PathConfig
from sprayplan.paths import cloudprep
from sprayplan.paths import polyline as pl
from sprayplan.paths.cloud_normals import neighbour_triangle_normals, plane_fit_normals
from sprayplan.paths.cloud_slicing import slice_cloud
from sprayplan.paths.edges import edge_pass_counts, layer_spacing, with_edge_passes, with_inner_edge_passes
from sprayplan.paths.pieces import Piece, in_travel_order, smooth_normals
from sprayplan.paths.planner import _section_pieces, covariance, layer_offsets, slicing_frame
from sprayplan.surface import normals as nm
from sprayplan.types import Part

log = logging.getLogger(__name__)

#: Streamlining thresholds used for clouds when the config sets none (degrees): nearly straight points go.
CLOUD_STREAMLINE_DEG = (175.0, 180.0)


def cloud_layers(part: Part, config: PathConfig) -> list[list[Piece]]:
    """Resampled pieces of every slicing layer of a point cloud, in layer order.

    Steps: statistical outlier removal and space sampling (003 section 2.2), outward normals (the file's, or
    PCA oriented by propagation), slab sections ordered into polylines (003 section 2.1), angle-method
    streamlining (2.1.1), normals at the section points by the neighbour-triangle method (3.2.2, area
    weighted) turned to agree with the nearest cloud points' oriented normals, then the same segmentation and
    resampling as for meshes.
    """
    points = part.vertices
    given = part.vertex_normals
    keep = cloudprep.remove_outliers(points)
    keep = keep[cloudprep.space_sample(points[keep])]
    points = points[keep]
    given = None if given is None else given[keep]
    if config.cloud_smooth_mm is not None:
        points = cloudprep.smooth(points, config.cloud_smooth_mm)
    if len(points) < 3:
        return []
    tree = cKDTree(points)
    spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
    if given is not None:
        normals = nm.unit(given)
    else:
        normals = nm.orient_propagate(points, nm.pca_normals(points, 4 * spacing, tree=tree, center="mean"), tree=tree)
    plane_normal, travel = slicing_frame(covariance(points), config.direction)
    height = points @ plane_normal
    lo, hi = float(height.min()), float(height.max())
    slab = config.slab_mm if config.slab_mm is not None else max(2.0 * spacing, 0.5)
    order = np.argsort(height)
    sorted_h = height[order]

    def slab_points(offset):
        i0, i1 = np.searchsorted(sorted_h, [offset - slab, offset + slab])
        chosen = points[order[i0:i1]]
        return chosen - np.outer(chosen @ plane_normal - offset, plane_normal)

    def samples(offset):
        found = slab_points(offset)
        return found[np.linspace(0, len(found) - 1, min(len(found), 400)).astype(int)] if len(found) else found

    def distance(query, offset):
        found = slab_points(offset)
        return float(np.median(cKDTree(found).query(query)[0])) if len(found) else np.inf

    boundary = points[cloud_boundary(points, normals, tree)]
    offsets = layer_offsets(lo, hi, config, samples, distance, closed_part=len(boundary) == 0)
    sections = slice_cloud(points, plane_normal, offsets, slab, gap_mm=5.0 * spacing, travel=travel)
    thresholds = np.radians(config.streamline_deg or CLOUD_STREAMLINE_DEG)
    smooth = config.spray_radius_mm / 2 if config.cloud_normal_smooth_mm is None else config.cloud_normal_smooth_mm
    layers = []
    for polylines in sections:
        sections = []
        for line in polylines:
            closed = _is_closed(line, 5.0 * spacing)
            if len(line) >= 3:
                line = line[pl.streamline(line, thresholds[0], thresholds[1], closed=closed)]
            if len(line) < 2:
                continue
            # 003 section 3.2.2: the normal from the neighbour triangles around each section point, turned to
            # agree with the oriented normals of the nearest cloud points
            near = tree.query(line, k=min(8, len(points)))[1]
            fitted = (
                neighbour_triangle_normals(line, points, k=8)
                if config.cloud_normals == "triangles"
                else plane_fit_normals(line, points, k=12)
            )
            line_n = nm.orient_like(fitted, normals[near].mean(axis=1))
            line_n = smooth_normals(line, line_n, smooth, closed=closed)
            sections.append(_section_pieces(line, line_n, closed, travel, config))
        layers.append(in_travel_order(sections, travel))
    counts = edge_pass_counts(lo, hi, offsets, config, samples, distance)
    log.info("%s: %d cloud layers, slab +-%.3g mm, edge passes %d + %d", part.name, len(layers), slab, *counts)
    d = layer_spacing(lo, hi, config)
    layers = with_inner_edge_passes(layers, plane_normal, travel, d, config, boundary)
    return with_edge_passes(layers, plane_normal, counts, d, config, boundary)


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
