"""The part's edges: extra passes past the edges that run with the strokes, and rims the strokes do not follow.

A film tapers where the spray stops: along the first and the last layer (half the neighbouring strokes are
missing) and where a stroke swings round a rolled edge. Edge passes carry the layers on past the part, the
spacing apart on the surface extended flat; rims are cut from the strokes' ends, which then leave the face
along its tangent (``planner._with_margins``).
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.config import PathConfig
from sprayplan.paths import polyline as pl
from sprayplan.paths.pieces import MIN_PIECE_MM, Piece, insert_in_travel_order, resample_piece

log = logging.getLogger(__name__)

#: An end of a stroke whose normals turn more than this (degrees) from the face's within ``rim_mm`` is a rim
#: (a hemmed or rolled edge) and is not followed (:func:`rim_lengths`).
RIM_ANGLE_DEG = 45.0

#: A point of a layer with no point of the neighbouring layer within this many spacings lies on an edge of
#: the part that runs between the two layers (:func:`with_inner_edge_passes`).
NEIGHBOUR_REACH = 1.5

#: Edge passes go only where the layer passes within this many spacings of the part's open edge.
EDGE_REACH = 2.0


def layer_spacing(lo: float, hi: float, config: PathConfig) -> float:
    """The distance between adjacent layers: the spacing, or the slice width with ``layers``."""
    return (hi - lo) / config.layers if config.layers is not None else config.spacing


def edge_pass_counts(lo: float, hi: float, offsets, config: PathConfig, samples, distance) -> tuple[int, int]:
    """How many edge passes go past the first and past the last layer (``config.edge_passes``).

    ``auto``: a pass ``j`` spacings out from an outer layer that lies ``s`` from the part's edge (measured on
    the part: the median distance from the extreme section, at the part's lowest or highest offset, to the
    outer layer's section; at least the planes' distance) is ``j d - s`` past the edge, and still paints the
    part while that is less than the spray radius R: ``ceil((R + s) / d) - 1`` passes.
    """
    if not offsets:
        return 0, 0
    if config.edge_passes != "auto":
        return int(config.edge_passes), int(config.edge_passes)
    d = layer_spacing(lo, hi, config)
    eps = 1e-6 * max(hi - lo, 1.0)
    counts = []
    for outer, edge in ((offsets[0], lo + eps), (offsets[-1], hi - eps)):
        s = abs(outer - edge)
        at_edge = samples(edge)
        if len(at_edge):
            measured = distance(at_edge, outer)
            if np.isfinite(measured):
                s = max(s, float(measured))
        counts.append(max(0, int(np.ceil((config.spray_radius_mm + s) / d - 1e-9)) - 1))
    return counts[0], counts[1]


def mesh_boundary(vertices: np.ndarray, faces: np.ndarray, step: float) -> np.ndarray:
    """(k, 3) points along a mesh's open boundary (edges that one triangle alone uses), at most ``step``
    apart; empty for a closed mesh."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    key = edges[:, 0].astype(np.int64) * len(vertices) + edges[:, 1]
    unique, count = np.unique(key, return_counts=True)
    single = unique[count == 1]
    open_ = np.column_stack([single // len(vertices), single % len(vertices)])
    if len(open_) == 0:
        return np.zeros((0, 3))
    a, b = vertices[open_[:, 0]], vertices[open_[:, 1]]
    parts = max(1, int(np.ceil(np.linalg.norm(b - a, axis=1).max() / step)))
    t = np.linspace(0.0, 1.0, parts + 1)
    return (a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]).reshape(-1, 3)


def with_edge_passes(
    layers: list[list[Piece]],
    plane_normal,
    counts: tuple[int, int],
    d: float,
    config: PathConfig,
    boundary: np.ndarray | None = None,
) -> list[list[Piece]]:
    """The layers with ``counts`` edge passes before the first and after the last non-empty layer.

    Edge pass ``j`` of an end is the outer layer moved ``j d`` along the surface extended flat: every point
    moves within its tangent plane, along the planes' normal (pointing away from the part) projected onto
    that plane, and keeps its normal; the moved polyline is resampled at the step. Its points are off the
    part (``on_part`` False). With ``boundary`` (points along the part's open edges; a mesh's from
    :func:`mesh_boundary`), only the stretches of the outer layer within ``EDGE_REACH`` spacings of an edge get
    passes: a closed surface (a hull sliced across its beam) has no edge to pass.
    """
    real = [[p for p in pieces if p.on_part.any()] for pieces in layers]
    filled = [k for k, pieces in enumerate(real) if pieces]
    if not filled:
        return layers
    normal = np.asarray(plane_normal, float)
    step = dataclasses.replace(config, points_per_section=None, interpolate="none")
    near = _EdgeFilter(boundary, d)
    first = [q for p in real[filled[0]] for q in near.stretches(p)]
    last = [q for p in real[filled[-1]] for q in near.stretches(p)]
    before = [_moved_layer(first, -normal, j * d, step) for j in range(counts[0], 0, -1)]
    after = [_moved_layer(last, normal, j * d, step) for j in range(1, counts[1] + 1)]
    return [b for b in before if b] + layers + [a for a in after if a]


class _EdgeFilter:
    """Which stretches of a piece lie near the part's open edges (all of it when the edges are unknown)."""

    def __init__(self, boundary: np.ndarray | None, d: float):
        self.known = boundary is not None
        self.tree = cKDTree(boundary) if self.known and len(boundary) else None
        self.d = d

    def mask(self, piece: Piece) -> np.ndarray:
        if not self.known:
            return np.ones(len(piece.points), bool)
        if self.tree is None:  # a closed surface: no edge anywhere
            return np.zeros(len(piece.points), bool)
        return self.tree.query(piece.points)[0] <= EDGE_REACH * self.d

    def stretches(self, piece: Piece) -> list[Piece]:
        near = self.mask(piece)
        if near.all():
            return [piece]
        out = []
        for a, b in _runs(near):
            if b - a >= 2 and pl.polyline_length(piece.points[a:b]) >= self.d:
                out.append(Piece(piece.points[a:b], piece.normals[a:b], piece.on_part[a:b], False))
        return out


def with_inner_edge_passes(
    layers: list[list[Piece]], plane_normal, travel, d: float, config: PathConfig, boundary: np.ndarray | None = None
) -> list[list[Piece]]:
    """The layers with edge passes along the edges that run between two layers.

    Where the part's outline is not square to the layers (a notch, a curved or slanted end, a hole wider
    than the gaps sprayed across), a stretch of a layer has no neighbour on one side: no point of the
    neighbouring layer within ``NEIGHBOUR_REACH`` spacings. That stretch, moved one spacing towards the
    neighbour (as :func:`with_edge_passes` moves an outer layer), becomes a piece of the neighbouring layer,
    off the part; it joins that layer's own pieces when the gap between them is one that is sprayed across.
    The first and the last layer's outer sides are left to :func:`with_edge_passes`. With ``boundary``,
    only stretches within ``EDGE_REACH`` spacings of the part's open edges count (elsewhere a missing neighbour
    is the march's widest step where the surface runs along the planes, not an edge). Off with
    ``edge_passes = 0``.
    """
    if config.edge_passes == 0 or len(layers) < 2:
        return layers
    normal = np.asarray(plane_normal, float)
    travel = np.asarray(travel, float)
    step = dataclasses.replace(config, points_per_section=None, interpolate="none")
    trees = []
    for pieces in layers:
        on = [p.points[p.on_part] for p in pieces]
        trees.append(cKDTree(np.vstack(on)) if on and sum(map(len, on)) else None)
    edge = _EdgeFilter(boundary, d)
    added: list[list[Piece]] = [[] for _ in layers]
    for k, pieces in enumerate(layers):
        for side, near in ((-1.0, k - 1), (1.0, k + 1)):
            if not 0 <= near < len(layers):
                continue
            for piece in pieces:
                far = piece.on_part.copy()
                if not piece.closed:  # a rim is not followed by the stroke: it has no edge pass either
                    head, tail = rim_lengths(piece.points, piece.normals, config.rim)
                    far[:head] = False
                    far[len(far) - tail :] = False
                if trees[near] is not None:
                    far &= trees[near].query(piece.points)[0] > NEIGHBOUR_REACH * d
                if far.any():
                    far &= edge.mask(piece)
                for a, b in _runs(far):
                    if pl.polyline_length(piece.points[a:b]) < d:
                        continue  # the corner of an outline slanting across the layers: the leads cover it
                    if not _plain(piece.points[a:b], piece.normals[a:b], travel):
                        continue  # a folded or rolled edge: moved flat, it would not paint the part evenly
                    run = Piece(piece.points[a:b], piece.normals[a:b], piece.on_part[a:b], False)
                    added[near].extend(_moved_layer([run], side * normal, d, step))
    out = []
    for pieces, extra in zip(layers, added):
        out.append(insert_in_travel_order(pieces, extra, travel) if extra else pieces)
    if any(added):
        log.info("inner edge passes: %d pieces", sum(map(len, added)))
    return out


def _plain(points: np.ndarray, normals: np.ndarray, travel: np.ndarray) -> bool:
    """Whether a stretch runs one way along the travel direction and its normals stay within
    ``RIM_ANGLE_DEG`` of their mean (no fold, no rim)."""
    ahead = np.diff(points, axis=0) @ travel
    if (ahead > 0).any() and (ahead < 0).any():
        return False
    mean = normals.mean(axis=0)
    mean /= max(float(np.linalg.norm(mean)), 1e-12)
    return bool((normals @ mean >= np.cos(np.radians(RIM_ANGLE_DEG))).all())


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the runs of True in a boolean array."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _moved_layer(pieces: list[Piece], outward: np.ndarray, distance: float, config: PathConfig) -> list[Piece]:
    out = []
    for piece in pieces:
        n = piece.normals
        direction = outward - (n @ outward)[:, None] * n
        length = np.linalg.norm(direction, axis=1)
        # where the surface faces along the planes' normal (the outer layer runs over a cap), move across the
        # stroke within the tangent plane instead
        tangent = np.gradient(piece.points, axis=0) if len(piece.points) > 1 else np.zeros_like(n)
        across = np.cross(n, tangent)
        across *= np.where(across @ outward < 0, -1.0, 1.0)[:, None]
        across_len = np.linalg.norm(across, axis=1)
        use_across = (length < 0.3) & (across_len > 1e-9)
        direction = np.where(
            use_across[:, None],
            across / np.maximum(across_len, 1e-12)[:, None],
            direction / np.maximum(length, 1e-12)[:, None],
        )
        direction = np.where(((length < 1e-9) & ~use_across)[:, None], outward, direction)
        points = piece.points + distance * direction
        if len(points) < 2 or pl.polyline_length(points, closed=piece.closed) < MIN_PIECE_MM:
            continue
        moved = resample_piece(points, n, piece.closed, config)
        out.append(Piece(moved.points, moved.normals, np.zeros(len(moved.points), bool), piece.closed))
    return out


def rim_lengths(points: np.ndarray, normals: np.ndarray, rim_mm: float) -> tuple[int, int]:
    """How many points at the start and at the end of a piece belong to a rim.

    A rim is an end stretch, at most ``rim_mm`` long, whose normals turn more than ``RIM_ANGLE_DEG`` away
    from the normal ``rim_mm`` in from the end: a hemmed or rolled edge, or the side of a thin panel. The
    reference point must lie on the piece, and at least two points are always kept.
    """
    n = len(points)
    if rim_mm <= 0 or n < 4:
        return 0, 0
    cos_max = np.cos(np.radians(RIM_ANGLE_DEG))
    out = []
    for pts, nrm in ((points, normals), (points[::-1], normals[::-1])):
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        ref = int(np.searchsorted(arc, rim_mm))
        if ref >= n - 2:
            out.append(0)
            continue
        turned = np.flatnonzero(nrm[:ref] @ nrm[ref] < cos_max)
        out.append(int(turned[-1]) + 1 if len(turned) else 0)
    head, tail = out
    if head + tail > n - 2:
        return 0, 0
    return head, tail
