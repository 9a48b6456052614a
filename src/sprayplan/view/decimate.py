"""Fewer triangles and waypoints to draw (never to compute): what the viewer and the report thin before drawing.

A surface is thinned by vertex clustering: the vertices are binned in a cubic grid and, within a cell, by the
axis and sign of their normal's largest component (so that the two faces of a thin sheet, a panel's outside
and inside, never merge); each bin becomes one vertex at the area-weighted mean position, carrying the
area-weighted mean film and the sum of the areas; triangles whose corners fall in fewer than three bins are
dropped, and triangles repeated are drawn once. The cell grows by 15 % until the triangles fit the budget.
The film drawn is then a local area-weighted average over a cell (a few mm on a car part), which keeps the
painted area's mean film and its total area.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.view.scene import Surface


@dataclass(frozen=True)
class Thinned:
    """A surface as drawn, and how much it was thinned (``cell_mm`` 0: not thinned)."""

    surface: Surface
    cell_mm: float
    source_faces: int
    source_vertices: int


def _normal_bins(normals: np.ndarray) -> np.ndarray:
    axis = np.argmax(np.abs(normals), axis=1)
    sign = normals[np.arange(len(normals)), axis] >= 0
    return axis * 2 + sign


def cluster(surface: Surface, cell_mm: float) -> Surface:
    """The surface with its vertices clustered in cubes of ``cell_mm`` (see the module's note)."""
    v = surface.vertices
    key_cells = np.floor((v - v.min(axis=0)) / cell_mm).astype(np.int64)
    key_cells -= key_cells.min(axis=0)
    span = key_cells.max(axis=0) + 1
    key = ((key_cells[:, 0] * span[1] + key_cells[:, 1]) * span[2] + key_cells[:, 2]) * 6 + _normal_bins(
        surface.normals
    )
    unique, label = np.unique(key, return_inverse=True)
    k = len(unique)
    w = np.maximum(surface.area_mm2, 1e-12)
    weight = np.bincount(label, w, k)

    def mean(values):
        return np.bincount(label, values * w, k) / weight

    vertices = np.column_stack([mean(v[:, j]) for j in range(3)])
    normals = np.column_stack([np.bincount(label, surface.normals[:, j] * w, k) for j in range(3)])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    area = np.bincount(label, surface.area_mm2, k)
    thickness = None if surface.thickness_um is None else mean(surface.thickness_um)
    faces = label[surface.faces] if len(surface.faces) else np.zeros((0, 3), np.int64)
    if len(faces):
        keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
        faces = faces[keep]
        # a triangle's three bins in any order: drawn once (one int64 key per sorted triple)
        s = np.sort(faces, axis=1)
        _, first = np.unique((s[:, 0] * k + s[:, 1]) * k + s[:, 2], return_index=True)
        faces = faces[np.sort(first)]
    return Surface(vertices, faces, normals, area, thickness)


def thin_surface(surface: Surface, max_faces: int, max_points: int | None = None) -> Thinned:
    """The surface with at most ``max_faces`` triangles (a point cloud: at most ``max_points`` points,
    default ``max_faces``), clustered as the module's note says; unchanged when it already fits."""
    n_faces, n_vertices = len(surface.faces), len(surface.vertices)
    if n_faces:
        if n_faces <= max_faces:
            return Thinned(surface, 0.0, n_faces, n_vertices)
        count, budget = n_faces, max_faces
    else:
        budget = max_points or max_faces
        if n_vertices <= budget:
            return Thinned(surface, 0.0, n_faces, n_vertices)
        count = n_vertices
    extent = np.ptp(surface.vertices, axis=0)
    area = float(surface.area_mm2.sum()) or float(np.prod(np.sort(extent)[1:]))
    # a mesh has about twice as many triangles as vertices: ``budget`` triangles need cells of about
    # sqrt(2 area / budget); a cloud's points: sqrt(area / budget)
    cell = max(np.sqrt((2.0 if n_faces else 1.0) * area / budget), 1e-6 * float(extent.max() or 1.0))
    for _ in range(60):
        out = cluster(surface, cell)
        size = len(out.faces) if n_faces else len(out.vertices)
        if size <= budget:
            return Thinned(out, float(cell), n_faces, n_vertices)
        cell *= 1.15 if size < 2 * budget else float(np.sqrt(size / budget))
    raise AssertionError(f"could not thin {count} to {budget}")  # pragma: no cover - the cell grows without bound


def thin_indices(lengths, budget: int) -> list[np.ndarray]:
    """Which waypoints of each of several polylines to draw so that about ``budget`` are drawn in all: every
    k-th, each polyline's first and last always (all of them when they fit)."""
    lengths = [int(n) for n in lengths]
    total = sum(lengths)
    step = max(1, int(np.ceil(total / max(budget, 1))))
    out = []
    for n in lengths:
        if step == 1 or n <= 2:
            out.append(np.arange(n))
        else:
            out.append(np.unique(np.r_[np.arange(0, n, step), n - 1]))
    return out
