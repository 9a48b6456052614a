"""Where two robots' pieces meet (issue 18, the seam rule ``feather`` of :func:`~sprayplan.cells.plan.plan_cell`):
a stroke's lead-in or lead-out, or an edge pass, that runs on over another piece's surface facing the same way
stops spraying there, as that surface is painted by its own strokes (:class:`SeamGuard`, :func:`feathered`);
and the waypoints of a piece's strokes that face away from their area are left out (:func:`facing_runs`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.paths.polyline import polyline_length
from sprayplan.surface.areas import OPPOSED_DEG
from sprayplan.types import Part, Stroke


def cut_stroke(stroke: Stroke, a: int, b: int) -> Stroke:
    """Waypoints ``a .. b - 1`` of a stroke."""
    return Stroke(
        stroke.points[a:b],
        stroke.normals[a:b],
        stroke.tcp[a:b],
        stroke.spray_on,
        stroke.on_part[a:b],
        stroke.layer,
        stroke.dwell[a:b],
        stroke.kind,
    )


def true_runs(mask: np.ndarray, min_len: int = 2) -> list[tuple[int, int]]:
    """``[a, b)`` index ranges of the runs of True in ``mask`` at least ``min_len`` long: the waypoints of a
    stroke to cut it to (:func:`cut_stroke`; a run of one waypoint paints nothing)."""
    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask).astype(np.int8), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2]) if b - a >= min_len]


class SeamGuard:
    """Where a stroke's extension lies over the surface of another piece (module docstring, the seam rule).

    The painted surface is sampled at most ``step_mm`` apart (a barycentric grid on every face), each sample
    labelled with its face's piece (area and robot) and normal. A waypoint off its own piece (``on_part``
    False: a lead-in or lead-out, an edge pass) is over another piece when a sample of another piece lies
    within ``step_mm`` of its aim point and faces the same way (normals within :data:`SEAM_ANGLE_DEG`): the
    surface goes on there, painted by its own strokes.
    """

    def __init__(self, part: Part, label: np.ndarray, normals: np.ndarray, step_mm: float):
        tri = part.triangles
        longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
        k = np.maximum(1, np.ceil(longest / step_mm)).astype(int)
        points, owner = [], []
        for level in np.unique(k):
            faces = np.flatnonzero(k == level)
            i, j = np.meshgrid(np.arange(level + 1), np.arange(level + 1), indexing="ij")
            keep = i + j <= level
            w = np.stack([i[keep], j[keep]], axis=1) / level
            bary = np.column_stack([1.0 - w.sum(axis=1), w])  # (p, 3)
            points.append(np.einsum("pk,fkd->fpd", bary, tri[faces]).reshape(-1, 3))
            owner.append(np.repeat(faces, len(bary)))
        owner = np.concatenate(owner)
        self.tree = cKDTree(np.concatenate(points))
        self.label = label[owner]
        self.normals = normals[owner]
        self.step_mm = step_mm

    def over_other(self, points: np.ndarray, normals: np.ndarray, label: int) -> np.ndarray:
        """(n,) bool: the points lie over a piece other than ``label`` (class docstring)."""
        if not len(points):
            return np.zeros(0, bool)
        near = self.tree.query_ball_point(points, self.step_mm)
        cos = math.cos(math.radians(SEAM_ANGLE_DEG))
        out = np.zeros(len(points), bool)
        for i, hits in enumerate(near):
            if hits:
                hits = np.asarray(hits)
                other = (self.label[hits] != label) & (self.normals[hits] @ normals[i] >= cos)
                out[i] = bool(other.any())
        return out


#: The sampling of the painted surface for :class:`SeamGuard`, mm.
SEAM_STEP_MM = 20.0
#: A stroke's extension is over another piece only where that piece faces within this angle of the stroke.
SEAM_ANGLE_DEG = 30.0


def feathered(strokes, guard: SeamGuard | None, label: int) -> list:
    """A piece's spray strokes with the spray taken off where they run on over another piece's surface
    (:class:`SeamGuard`; the planner's transfers are left out, they are made again between the strokes that
    remain).

    A stroke on the piece keeps its on-piece waypoints; at each end its lead-in or lead-out stops at the first
    waypoint over another piece, and nothing past it sprays. A stroke wholly off the piece (an edge pass)
    keeps its runs that are not over another piece. A run shorter than two waypoints is dropped.
    """
    out = []
    for s in strokes:
        if not s.spray_on:
            continue
        if guard is None or s.on_part.all():
            out.append(s)
            continue
        off = ~s.on_part
        over = np.zeros(len(s), bool)
        over[off] = guard.over_other(s.points[off], s.normals[off], label)
        on = np.flatnonzero(s.on_part)
        if len(on):
            head = np.flatnonzero(over[: on[0]])
            tail = np.flatnonzero(over[on[-1] + 1 :])
            a = int(head[-1]) + 1 if len(head) else 0
            b = int(on[-1]) + 1 + int(tail[0]) if len(tail) else len(s)
            runs = [(a, b)]
        else:
            runs = true_runs(~over)
        out.extend(cut_stroke(s, a, b) if (a, b) != (0, len(s)) else s for a, b in runs if b - a >= 2)
    return out


def facing_away(stroke, normal: np.ndarray, limit_deg: float = OPPOSED_DEG) -> np.ndarray:
    """(n,) bool: the waypoints of ``stroke`` whose outward normal is more than ``limit_deg`` from ``normal``
    (their area's mean outward normal); none for a zero ``normal``. They lie on the part's other side where a
    sliver of it joined the area, too small to be an area of its own (``surface.areas.OPPOSED_KEPT``), and the
    robot painting the area from its side would aim at them from inside the body. On the BMW in ``line3`` the
    left rear window's sill is sheet with both sides in the mesh, 2.5 mm apart, the inner side facing the cabin
    (0.02 m^2, in ``side +y 2``): the sections run along the outer side, round the sill's lip and back along the
    inner side, the gun turned over at the lip, inside the body."""
    normal = np.asarray(normal, dtype=float)
    size = np.linalg.norm(stroke.normals, axis=1) * np.linalg.norm(normal)
    cos = np.divide(stroke.normals @ normal, size, out=np.ones(len(size)), where=size > 0)
    return cos < math.cos(math.radians(limit_deg))


def facing_runs(stroke, normal: np.ndarray) -> tuple[list, float]:
    """``stroke`` cut to its runs of at least two waypoints that do not face away from ``normal``
    (:func:`facing_away`): the strokes (``stroke`` itself when nothing faces away), and the path left out
    (mm, along the aimed-at points)."""
    away = facing_away(stroke, normal)
    if not away.any():
        return [stroke], 0.0
    kept = [cut_stroke(stroke, a, b) for a, b in true_runs(~away)]
    return kept, polyline_length(stroke.points) - sum(polyline_length(k.points) for k in kept)
