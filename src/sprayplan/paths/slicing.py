"""Exact plane sections of a triangle mesh, chained into oriented polylines (seed 003, section 2.1, for meshes).

Every section point lies on a mesh edge, and every section segment inside one face, so the polylines lie on
the surface exactly. Segments are chained through the mesh edges they share (topology, not a distance
tolerance), and oriented by the face winding: along ``plane_normal x face_normal``, which on a consistently
wound mesh makes every polyline of every plane run the same way round.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.surface.normals import unit
from sprayplan.surface.pairs import unique_pairs


@dataclass(frozen=True)
class Section:
    """One polyline of a plane section of a mesh.

    Attributes
    ----------
    points : (m, 3) float, mm
        Points where the plane crosses mesh edges, in order.
    normals : (m, 3) float
        Unit outward normals at the points (vertex normals interpolated along the edge).
    faces : (m - 1,) or (m,) int
        The face each segment lies in (``m`` segments when closed: the last closes the loop).
    closed : bool
    """

    points: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    closed: bool


class MeshSlicer:
    """Plane sections of one mesh along one direction; build once, slice at many offsets.

    Parameters
    ----------
    vertices : (n, 3) float, mm
    faces : (m, 3) int
        Consistently wound, outward (see ``surface.normals.outward_face_normals``).
    plane_normal : (3,) float
        The planes are ``{p : p . plane_normal = offset}``.
    vertex_normals : (n, 3) float
        Unit outward vertex normals, interpolated to the section points.
    face_normals : (m, 3) float
        Unit outward face normals, orienting the segments.
    """

    def __init__(self, vertices, faces, plane_normal, vertex_normals, face_normals):
        self.vertices = np.asarray(vertices, dtype=float)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.normal = unit(np.asarray(plane_normal, dtype=float).reshape(1, 3))[0]
        self.vertex_normals = vertex_normals
        self.face_normals = face_normals
        self.height = self.vertices @ self.normal
        face_h = self.height[self.faces]
        self.face_min = face_h.min(axis=1)
        self.face_max = face_h.max(axis=1)
        edges = np.sort(np.stack([self.faces, np.roll(self.faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
        self.edges, inverse = unique_pairs(edges, return_inverse=True)
        self.face_edges = inverse.reshape(-1, 3)  # edge k of face f joins corners k and k+1
        self.travel = unit(np.cross(self.normal[None, :], self.face_normals))

    @property
    def range(self) -> tuple[float, float]:
        """Lowest and highest offset at which a plane meets the mesh."""
        return float(self.height.min()), float(self.height.max())

    def crossing(self, offset: float):
        """The raw section at one offset: segments as pairs of crossing points, unordered.

        Returns
        -------
        seg_faces : (k,) int
            Faces the plane crosses.
        seg_edges : (k, 2) int
            The two crossed edges of each face, ordered along the travel direction.
        edge_ids : (j,) int
            The crossed edges.
        edge_points : (j, 3) float
            Where the plane crosses them.
        edge_t : (j,) float
            The parameter along each edge (from its lower-index vertex).
        """
        crossing = np.flatnonzero((self.face_max >= offset) & (self.face_min < offset))
        above = self.height >= offset
        corners = self.faces[crossing]
        side = above[corners]
        # edge k (corners k, k+1) is crossed when its ends are on different sides
        crossed = side != np.roll(side, -1, axis=1)
        fe = self.face_edges[crossing]
        # each crossing face has exactly two crossed edges
        first = np.argmax(crossed, axis=1)
        second = 2 - np.argmax(crossed[:, ::-1], axis=1)
        e1 = fe[np.arange(len(fe)), first]
        e2 = fe[np.arange(len(fe)), second]
        edge_ids, inverse = np.unique(np.concatenate([e1, e2]), return_inverse=True)
        a, b = self.edges[edge_ids, 0], self.edges[edge_ids, 1]
        ha, hb = self.height[a], self.height[b]
        t = (offset - ha) / (hb - ha)
        points = self.vertices[a] + t[:, None] * (self.vertices[b] - self.vertices[a])
        k = len(crossing)
        i1, i2 = inverse[:k], inverse[k:]
        forward = np.einsum("ij,ij->i", points[i2] - points[i1], self.travel[crossing]) >= 0
        seg = np.where(forward[:, None], np.stack([i1, i2], 1), np.stack([i2, i1], 1))
        return crossing, seg, edge_ids, points, t

    def section(self, offset: float) -> list[Section]:
        """The polylines of the plane section at ``offset``, oriented along the travel direction."""
        seg_faces, seg, edge_ids, points, t = self.crossing(offset)
        if len(seg_faces) == 0:
            return []
        a, b = self.edges[edge_ids, 0], self.edges[edge_ids, 1]
        normals = unit((1 - t)[:, None] * self.vertex_normals[a] + t[:, None] * self.vertex_normals[b])
        chains = _chain(seg)
        out = []
        for nodes, segs, closed in chains:
            out.append(Section(points[nodes], normals[nodes], seg_faces[segs], closed))
        return out


def _chain(seg: np.ndarray):
    """Chain directed segments (start node, end node) into paths and cycles.

    Returns a list of (nodes, segment indices, closed). A node with more than one outgoing or incoming segment
    (a non-manifold or inconsistently wound spot) ends the chain there.
    """
    n_nodes = int(seg.max()) + 1
    out_count = np.bincount(seg[:, 0], minlength=n_nodes)
    in_count = np.bincount(seg[:, 1], minlength=n_nodes)
    next_seg = np.full(n_nodes, -1)
    ok = out_count[seg[:, 0]] == 1
    next_seg[seg[ok, 0]] = np.flatnonzero(ok)
    has_pred = np.zeros(len(seg), dtype=bool)
    has_pred[:] = (in_count[seg[:, 0]] == 1) & (out_count[seg[:, 0]] == 1)
    # a segment whose start node has exactly one incoming segment continues that one
    used = np.zeros(len(seg), dtype=bool)
    chains = []
    starts = np.flatnonzero(~has_pred)
    for start in np.concatenate([starts, np.arange(len(seg))]):
        if used[start]:
            continue
        nodes, segs = [int(seg[start, 0])], []
        current = int(start)
        closed = False
        while True:
            used[current] = True
            segs.append(current)
            end = int(seg[current, 1])
            nxt = int(next_seg[end]) if in_count[end] == 1 else -1
            if nxt == int(start) and start not in starts:
                closed = True
                break
            nodes.append(end)
            if nxt < 0 or used[nxt]:
                break
            current = nxt
        chains.append((np.array(nodes), np.array(segs), closed))
    return chains
