"""The ``targets`` stage: target points with outward normals on a part (seed 000, section 2)."""

from __future__ import annotations

import logging
import math

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.checks import MAX_CANDIDATES, check_work, round_up
from sprayplan.config import TargetsConfig
from sprayplan.errors import InputError
from sprayplan.surface import compress as compress_mod
from sprayplan.surface import filling
from sprayplan.surface import normals as nm
from sprayplan.types import Part, Targets

log = logging.getLogger(__name__)


def make_targets(part: Part, config: TargetsConfig | None = None) -> Targets:
    """Target points on a part's surface with unit outward normals.

    Meshes
        ``fill="even"``: Poisson-disk points at the spacing, each with its (outward) face normal.
        ``fill="point"`` / ``"line"``: the seed's DFS filling at ``h_min_mm``; fill points take their
        face's normal and the mesh's vertices take a PCA normal from the target points within
        ``normal_radius_mm`` (seed 000, section 2.3), oriented as ``config.orient`` says.
    Point clouds
        The cloud's points, with the file's normals when it has them, else PCA normals oriented by
        propagation over the neighbour graph (or eq. 4 with ``orient="centroid"``).

    Then the points are compressed (``config.compress``, eq. 7 or its on-surface variant).

    Parameters
    ----------
    part : Part
    config : TargetsConfig, optional
        Defaults to ``TargetsConfig()``.

    Returns
    -------
    Targets
    """
    config = TargetsConfig() if config is None else config
    spacing = config.spacing
    if part.is_mesh:
        check_target_work(part, config)
    if part.is_mesh:
        points, normals, face_index = _mesh_targets(part, config, spacing)
    else:
        points, normals, face_index = _cloud_targets(part, config, spacing)
    if config.compress == "grid":
        points, normals = compress_mod.compress_grid(points, normals, spacing)
        face_index = np.full(len(points), -1)
    elif config.compress == "surface":
        keep = compress_mod.compress_surface(points, spacing)
        points, normals, face_index = points[keep], normals[keep], face_index[keep]
    if len(points) == 0:
        raise InputError(f"{part.name}: no target points (is the spacing {spacing:.4g} mm larger than the part?)")
    return Targets(points, normals, face_index)


def check_target_work(part: Part, config: TargetsConfig) -> None:
    """Refuse, before sampling, a spacing (even fill) or ``h_min_mm`` (DFS fill) that would make more than
    ``checks.MAX_CANDIDATES`` points on the part: the message names the setting, the part's area and the
    smallest value accepted."""
    area = float(part.area)
    if config.fill == "even":
        spacing = config.spacing
        name = (
            "targets.spacing_mm"
            if config.spacing_mm is not None
            else "targets.spacing_mm (from spray_radius_mm and overlap)"
        )
        count = filling.EVEN_OVERSAMPLE * area / spacing**2
        lowest = math.sqrt(filling.EVEN_OVERSAMPLE * area / MAX_CANDIDATES)
        check_work(
            count,
            MAX_CANDIDATES,
            "candidates of the even sampling",
            name,
            spacing,
            f"{area:.4g} mm^2",
            f"use targets.spacing_mm >= {round_up(lowest)} or a smaller region",
        )
    else:
        h_min = config.h_min_mm or config.spacing / 2.0
        name = "targets.h_min_mm" if config.h_min_mm is not None else "targets.h_min_mm (None: half the spacing)"
        # the filling splits a triangle while its smallest height is h_min or more: at most about
        # 2 area / h_min^2 triangles of the last level, each with a centroid or the points along its medians
        count = filling.dfs_point_estimate(area, h_min, config.fill)
        lowest = math.sqrt(count / MAX_CANDIDATES) * h_min
        check_work(
            count,
            MAX_CANDIDATES,
            f"points of the {config.fill} filling",
            name,
            h_min,
            f"{area:.4g} mm^2",
            f"use targets.h_min_mm >= {round_up(lowest)} or a smaller region",
        )


def _mesh_targets(part: Part, config: TargetsConfig, spacing: float):
    orient = config.orient or "mesh"
    faces, face_n = nm.part_outward(part)
    triangles = part.vertices[faces]
    if config.fill == "even":
        points, face_index = filling.sample_even(triangles, spacing, seed=config.seed)
        normals = face_n[face_index]
        if config.normals == "pca":
            radius = config.normal_radius_mm or 2.0 * spacing
            normals = nm.orient_like(nm.pca_fit(points, radius, center="mean")[0], normals)
    else:
        fill_points, fill_index = filling.fill_dfs(triangles, config.h_min_mm or spacing / 2.0, config.fill)
        points = np.vstack([fill_points, part.vertices])
        face_index = np.concatenate([fill_index, np.full(len(part.vertices), -1)])
        radius = config.normal_radius_mm or 2.0 * spacing
        tree = cKDTree(points)
        vertex_pca, eigenvalues = nm.pca_fit(part.vertices, radius, tree=tree, data=points)
        reference = nm.vertex_normals(part.vertices, faces, face_n)
        vertex_pca = nm.orient_like(vertex_pca, reference)
        # too few or collinear neighbours (skinny triangles stop the DFS early): no plane to fit
        degenerate = eigenvalues[:, 1] < 1e-2 * eigenvalues[:, 2]
        if degenerate.any():
            log.info(
                "%s: %d vertices have no fitting plane within %.4g mm; they take the mesh's vertex normal",
                part.name,
                int(degenerate.sum()),
                radius,
            )
            vertex_pca[degenerate] = reference[degenerate]
        normals = np.vstack([face_n[fill_index], vertex_pca])
    if orient == "centroid":
        normals = nm.orient_centroid(points, normals)
    elif orient == "propagate":
        normals = nm.orient_propagate(points, normals)
    return points, normals, face_index


def _cloud_targets(part: Part, config: TargetsConfig, spacing: float):
    points = part.vertices
    if len(points) < 3:
        raise InputError(f"{part.name}: a point cloud needs at least 3 points for normals, it has {len(points)}")
    if part.vertex_normals is not None and config.orient is None:
        normals = nm.unit(part.vertex_normals)
        log.info("%s: using the normals given in the file", part.name)
    else:
        radius = config.normal_radius_mm or 2.0 * spacing
        tree = cKDTree(points)
        normals = nm.pca_normals(points, radius, tree=tree, center="mean")
        if (config.orient or "propagate") == "centroid":
            normals = nm.orient_centroid(points, normals)
        else:
            normals = nm.orient_propagate(points, normals, tree=tree)
    return points, normals, np.full(len(points), -1)
