"""Exact plane sections of a mesh as a ``layers.SectionSource`` (seed 003 section 2.1, for meshes).

The polylines come from ``paths.slicing.MeshSlicer``: on the surface exactly, with the vertex normals
interpolated along the crossed edges. Distances between sections (for the surface-spacing march and the edge
passes) are measured to the section's segments.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.paths.edges import mesh_boundary
from sprayplan.paths.frame import surface_covariance
from sprayplan.paths.slicing import MeshSlicer
from sprayplan.surface import normals as nm
from sprayplan.types import Part


class MeshSections:
    """Plane sections of a mesh (outward faces and vertex normals found once).

    Parameters
    ----------
    part : Part
        A mesh, mm.
    spacing : float
        The strokes' spacing (mm): distance estimates sample the sections a tenth of it apart.
    """

    def __init__(self, part: Part, spacing: float):
        self.name = part.name
        self.vertices = part.vertices
        self.faces, self.face_normals = nm.part_outward(part)
        self.vertex_normals = nm.vertex_normals(part.vertices, self.faces, self.face_normals)
        self.step = spacing / 10
        self.slicer: MeshSlicer | None = None

    def covariance(self) -> np.ndarray:
        return surface_covariance(self.vertices[self.faces])

    def use_frame(self, normal, travel) -> tuple[float, float]:
        self.slicer = MeshSlicer(self.vertices, self.faces, normal, self.vertex_normals, self.face_normals)
        # the march asks for the same plane's crossing several times (its samples, distances to and from it)
        self._crossing = functools.lru_cache(maxsize=16)(self.slicer.crossing)
        return self.slicer.range

    def boundary(self, step: float) -> np.ndarray:
        return mesh_boundary(self.vertices, self.faces, step)

    def samples(self, offset: float) -> np.ndarray:
        """Points along the section, about ``step`` apart (at most 400)."""
        _, seg, _, points, _ = self._crossing(float(offset))
        if len(seg) == 0:
            return np.zeros((0, 3))
        a, b = points[seg[:, 0]], points[seg[:, 1]]
        length = np.linalg.norm(b - a, axis=1)
        count = np.maximum(1, np.ceil(length / self.step).astype(int))
        idx = np.repeat(np.arange(len(seg)), count)
        t = (np.arange(len(idx)) - np.repeat(np.cumsum(count) - count, count) + 0.5) / np.repeat(count, count)
        samples = a[idx] + t[:, None] * (b[idx] - a[idx])
        if len(samples) > 400:
            samples = samples[np.linspace(0, len(samples) - 1, 400).astype(int)]
        return samples

    def distance(self, query: np.ndarray, offset: float) -> float:
        _, seg, _, points, _ = self._crossing(float(offset))
        if len(seg) == 0:
            return np.inf
        return float(np.median(point_segment_distance(query, points[seg[:, 0]], points[seg[:, 1]])))

    def sections(self, offset: float) -> list[tuple[np.ndarray, np.ndarray, bool]]:
        return [(s.points, s.normals, s.closed) for s in self.slicer.section(offset)]

    def describe(self) -> str:
        return ""


def point_segment_distance(query: np.ndarray, a: np.ndarray, b: np.ndarray, k: int = 8) -> np.ndarray:
    """(n,) distance from each query point to the nearest of the segments [a_i, b_i]."""
    tree = cKDTree((a + b) / 2)
    kk = int(min(k, len(a)))
    _, idx = tree.query(query, k=kk)
    idx = idx.reshape(len(query), kk)
    sa, sb = a[idx], b[idx]
    ab = sb - sa
    denom = np.maximum(np.einsum("nki,nki->nk", ab, ab), 1e-300)
    t = np.clip(np.einsum("nki,nki->nk", query[:, None, :] - sa, ab) / denom, 0.0, 1.0)
    closest = sa + t[..., None] * ab
    return np.linalg.norm(closest - query[:, None, :], axis=2).min(axis=1)
