"""The ``paths`` stage: a part -> spray strokes in execution order (seed 003 sections 2-3, seed 000 eq. 6).

Pipeline for a mesh: outward faces and vertex normals -> slicing direction -> plane offsets (uniform, or
marched so that adjacent sections are the spacing apart on the surface) -> exact plane sections ->
segmentation at sharp feature points -> arc-length resampling at the step -> pieces of one layer joined across
gaps narrower than the spray diameter and split at wider ones -> lead-in / lead-out margins -> zig-zag order
-> spray-off transfers between strokes. A point cloud follows the same steps with slab sections
(``paths.cloud_slicing``) and streamlining.
"""

from __future__ import annotations

import functools
import logging
from types import SimpleNamespace

import numpy as np
from scipy.optimize import brentq
from scipy.spatial import cKDTree

from sprayplan.config import PathConfig
from sprayplan.errors import InputError
from sprayplan.paths import polyline as pl
from sprayplan.paths import segmentation
from sprayplan.paths.edges import (
    edge_pass_counts,
    layer_spacing,
    mesh_boundary,
    rim_lengths,
    with_edge_passes,
    with_inner_edge_passes,
)
from sprayplan.paths.pieces import MIN_PIECE_MM, Piece, in_travel_order, resample_piece, without_repeats
from sprayplan.paths.slicing import MeshSlicer
from sprayplan.surface import normals as nm
from sprayplan.types import Part, Paths, Stroke

log = logging.getLogger(__name__)

#: Surface-spacing marching never moves the plane by less than this fraction of the spacing: where the surface
#: runs nearly parallel to the planes (steeper than about 75 degrees to the strokes' plane), sections drift
#: apart quickly and another slicing direction is needed to paint it evenly.
MIN_PLANE_STEP = 0.25

#: With ``direction="auto"``, a part whose two largest principal variances are within this ratio has no clear
#: longest axis; its strokes then follow the nearest coordinate axis.
SQUARE_RATIO = 1.1

AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def covariance(points: np.ndarray) -> np.ndarray:
    """(3, 3) covariance of a point set (mm^2)."""
    d = points - points.mean(axis=0)
    return d.T @ d / max(len(points), 1)


def surface_covariance(triangles: np.ndarray) -> np.ndarray:
    """(3, 3) covariance of a triangulated surface with uniform area density, computed exactly.

    Over a triangle (a, b, c) of area A, the integral of x x^T is A / 12 (a a^T + b b^T + c c^T + s s^T) with
    s = a + b + c, and that of x is A s / 3.
    """
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    total = area.sum()
    s = a + b + c
    mean = (area[:, None] * s).sum(axis=0) / (3.0 * total)
    second = sum(np.einsum("n,ni,nj->ij", area, v, v) for v in (a, b, c, s)) / (12.0 * total)
    return second - np.outer(mean, mean)


def _axes(cov: np.ndarray) -> np.ndarray:
    """Rows: eigenvectors of a covariance, largest variance first, each with its largest component > 0."""
    _, vectors = np.linalg.eigh(cov)
    axes = vectors[:, ::-1].T.copy()
    for axis in axes:
        if axis[np.argmax(np.abs(axis))] < 0:
            axis *= -1
    return axes


def slicing_frame(cov: np.ndarray, direction) -> tuple[np.ndarray, np.ndarray]:
    """The planes' unit normal and the in-plane travel direction for a slicing direction setting.

    Parameters
    ----------
    cov : (3, 3) float
        The part's covariance (:func:`surface_covariance` or :func:`covariance`).
    direction : "auto", "x", "y", "z" or (3,) float

    Returns
    -------
    normal, travel : (3,) float
        ``auto``: the normal is the second principal axis (across the longest one) and strokes travel along
        the longest. Otherwise the normal is the given axis or vector, and the travel direction is the
        principal axis of the part's projection onto the planes.
    """
    if isinstance(direction, str) and direction == "auto":
        axes = _axes(cov)
        variance = np.sort(np.linalg.eigvalsh(cov))[::-1]
        if variance[0] <= SQUARE_RATIO * variance[1]:
            # no clear longest axis (a square panel): run the strokes along the coordinate axis nearest the
            # part's plane, as a programmer would
            span = axes[:2]
            candidates = span @ np.eye(3)  # (2, 3): each coordinate axis in the span's coordinates
            best = int(np.argmax(np.linalg.norm(candidates, axis=0)))
            travel = span.T @ candidates[:, best]
            travel /= np.linalg.norm(travel)
            normal = np.cross(axes[2], travel)
            if normal[np.argmax(np.abs(normal))] < 0:
                normal = -normal
            return normal, travel
        return axes[1], axes[0]
    normal = np.array(AXES[direction] if isinstance(direction, str) else direction, dtype=float)
    normal /= np.linalg.norm(normal)
    project = np.eye(3) - np.outer(normal, normal)
    travel = _axes(project @ cov @ project)[0]
    if abs(travel @ normal) > 0.5:  # the part has no extent across the normal: any in-plane axis will do
        travel = _axes(project)[0]
    travel = travel - (travel @ normal) * normal
    return normal, travel / np.linalg.norm(travel)


def plan_paths(part: Part, config: PathConfig | None = None) -> Paths:
    """Spray strokes over a part, in execution order.

    Parameters
    ----------
    part : Part
        A mesh or a point cloud (after ``load`` and ``region``), mm.
    config : PathConfig, optional

    Returns
    -------
    Paths
        Spray strokes (zig-zag: adjacent layers run in opposite directions) with spray-off transfer strokes
        between them. ``tcp = points + standoff * normals`` for every waypoint.

    Raises
    ------
    InputError
        When the part gives no section at all (a spacing larger than the part, or an empty part).
    """
    config = PathConfig() if config is None else config
    if part.is_mesh:
        layers = mesh_layers(part, config)
    else:
        from sprayplan.paths.cloud_planner import cloud_layers

        layers = cloud_layers(part, config)
    if not any(layers):
        raise InputError(f"{part.name}: no section of the part to paint (spacing {config.spacing:.4g} mm)")
    strokes = order_strokes(layers, config)
    return Paths(tuple(strokes), config.standoff_mm, config.spacing, part.name)


# ----------------------------------------------------------------------------------------------- meshes


def mesh_layers(part: Part, config: PathConfig) -> list[list[Piece]]:
    """Resampled pieces of every slicing layer of a mesh, in layer order."""
    faces, face_n = nm.outward_face_normals(part.vertices, part.faces)
    vertex_n = nm.vertex_normals(part.vertices, faces, face_n)
    normal, travel = slicing_frame(surface_covariance(part.vertices[faces]), config.direction)
    slicer = MeshSlicer(part.vertices, faces, normal, vertex_n, face_n)
    lo, hi = slicer.range
    d = layer_spacing(lo, hi, config)

    # the march asks for the same plane's crossing several times (its samples, distances to and from it)
    cached = SimpleNamespace(crossing=functools.lru_cache(maxsize=16)(slicer.crossing))

    def samples(offset):
        return _section_samples(cached, float(offset), config.spacing / 10)

    def distance(query, offset):
        return _median_distance(query, cached, float(offset))

    boundary = mesh_boundary(part.vertices, faces, d / 4)
    offsets = layer_offsets(lo, hi, config, samples, distance, closed_part=len(boundary) == 0)
    layers = []
    for offset in offsets:
        sections = [
            _section_pieces(section.points, section.normals, section.closed, travel, config)
            for section in slicer.section(offset)
        ]
        layers.append(in_travel_order(sections, travel))
    counts = edge_pass_counts(lo, hi, offsets, config, samples, distance)
    log.info("%s: %d layers along (%.3f, %.3f, %.3f), edge passes %d + %d", part.name, len(layers), *normal, *counts)
    layers = with_inner_edge_passes(layers, normal, travel, d, config, boundary)
    return with_edge_passes(layers, normal, counts, d, config, boundary)


def layer_offsets(
    lo: float, hi: float, config: PathConfig, samples, distance, closed_part: bool = False
) -> list[float]:
    """Plane offsets over a part spanning [lo, hi] along the planes' normal, as ``config`` asks.

    ``layers``: that many equal slices, a plane in the middle of each. ``uniform`` (or a part thinner than the
    spacing): planes the spacing apart, centred on the part. ``surface``: :func:`march_offsets` with the
    ``samples`` and ``distance`` callables of the mesh or cloud at hand; it closes the far end with a last
    layer when no edge pass will (``edge_passes = 0``, or a ``closed_part`` with no edge to pass).
    """
    span = hi - lo
    if config.layers is not None:
        return list(lo + span / config.layers * (np.arange(config.layers) + 0.5))
    d = config.spacing
    if config.spacing_mode == "uniform" or span <= d:
        count = max(1, int(np.ceil(span / d)))
        return list((lo + hi) / 2 - (count - 1) * d / 2 + d * np.arange(count))
    return march_offsets(lo, hi, d, samples, distance, close=config.edge_passes == 0 or closed_part)


def march_offsets(lo: float, hi: float, d: float, samples, distance, close: bool = True) -> list[float]:
    """Plane offsets such that each section lies ``d`` from the previous one, measured on the part.

    The first plane is ``d / 2`` in from the lowest offset; each next offset is found by root finding
    (Brent's method, to 0.1% of d) on the gap between the current section and the next: the smaller of the
    median distance from the current section's points to the next section and the median distance back
    (where the part's outline narrows, the far ends of the longer section would make the one-way distance
    too large). The gap is at least the planes' distance, so the root lies within one spacing. The planes move by
    at least ``MIN_PLANE_STEP * d``. With ``close``, a last layer at the far edge (closer than ``d``) is added
    when more than half a spacing of the part would otherwise be left; without, the march stops at the last
    layer a whole spacing from the previous one (edge passes then carry on past the edge).

    Parameters
    ----------
    lo, hi : float
        The part's extent along the planes' normal.
    d : float
        The spacing.
    samples : callable
        ``samples(offset) -> (k, 3)`` points along the section at ``offset``.
    distance : callable
        ``distance(points, offset) -> float`` median distance from points to the section at ``offset``.
    """
    eps = 1e-6 * max(hi - lo, 1.0)
    offsets = [lo + min(d / 2, (hi - lo) / 2)]
    while True:
        current = samples(offsets[-1])

        def gap(o, q=current, here=offsets[-1]):
            ahead = distance(q, o)
            there = samples(o)
            return min(ahead, distance(there, here)) if len(there) else ahead

        clamped = offsets[-1] + d > hi - eps
        upper = min(offsets[-1] + d, hi - eps)
        if len(current) == 0 or upper <= offsets[-1] + eps:
            break
        gap_at_upper = gap(upper)
        if gap_at_upper <= d * (1.0 + 1e-6):
            if not clamped:  # the surface is square to the planes here: one plane step is one spacing
                offsets.append(upper)
                continue
            # the rest of the part is closer than one spacing: one more layer only if over half is left
            if close and gap_at_upper > d / 2:
                offsets.append(upper)
            break
        lower = min(offsets[-1] + MIN_PLANE_STEP * d, upper)
        if gap(lower) >= d:
            # the surface runs nearly parallel to the planes here: do not crawl, take the smallest step
            offsets.append(lower)
            continue
        offsets.append(float(brentq(lambda o: gap(o) - d, lower, upper, xtol=1e-3 * d)))
    return offsets


def _section_samples(slicer: MeshSlicer, offset: float, step: float) -> np.ndarray:
    """Points along the section at one offset, about ``step`` apart (at most 400), for distance estimates."""
    _, seg, _, points, _ = slicer.crossing(offset)
    if len(seg) == 0:
        return np.zeros((0, 3))
    a, b = points[seg[:, 0]], points[seg[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    count = np.maximum(1, np.ceil(length / step).astype(int))
    idx = np.repeat(np.arange(len(seg)), count)
    t = (np.arange(len(idx)) - np.repeat(np.cumsum(count) - count, count) + 0.5) / np.repeat(count, count)
    samples = a[idx] + t[:, None] * (b[idx] - a[idx])
    if len(samples) > 400:
        samples = samples[np.linspace(0, len(samples) - 1, 400).astype(int)]
    return samples


def _median_distance(query: np.ndarray, slicer: MeshSlicer, offset: float) -> float:
    """Median distance from query points to the section polyline at ``offset`` (inf when there is none)."""
    _, seg, _, points, _ = slicer.crossing(offset)
    if len(seg) == 0:
        return np.inf
    return float(np.median(point_segment_distance(query, points[seg[:, 0]], points[seg[:, 1]])))


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


def _section_pieces(points, normals, closed, travel, config: PathConfig) -> list[Piece]:
    """Orient a section polyline, split it at sharp features, and resample it at the step."""
    if len(points) < 2:
        return []
    if not closed and (points[-1] - points[0]) @ travel < 0:
        points, normals = points[::-1], normals[::-1]
    if closed:
        start = int(np.argmin(points @ travel))
        points, normals = np.roll(points, -start, axis=0), np.roll(normals, -start, axis=0)
    parts = [(points, normals, closed)]
    if config.split_angle_deg is not None and len(points) >= 5:
        # sharp points: where the tangent turns by more than the angle (L = 0: the angle decides)
        sharp = segmentation.feature_points(points, 0.0, np.radians(config.split_angle_deg))
        if not closed:
            sharp = sharp[(sharp > 0) & (sharp < len(points) - 1)]
        if len(sharp):
            pieces = segmentation.split_at(points, sharp, closed=closed)
            normal_pieces = segmentation.split_at(normals, sharp, closed=closed)
            parts = [(p, n, False) for p, n in zip(pieces, normal_pieces)]
    out = []
    for p, n, is_closed in parts:
        if len(p) < 2 or pl.polyline_length(p, closed=is_closed) < MIN_PIECE_MM:
            continue
        out.append(resample_piece(p, n, is_closed, config))
    return out


# ----------------------------------------------------------------------------------------------- strokes


def order_strokes(layers: list[list[Piece]], config: PathConfig) -> list[Stroke]:
    """Join and split the pieces of each layer, add margins, zig-zag the layers, and add transfers.

    Layers run in slicing order. Within a layer, pieces run in travel order; each layer after the first is
    run forwards or backwards, whichever starts nearer the end of the previous layer (the zig-zag of 003
    section 3.2.2: "the sorting direction of patch data on adjacent layers is set in reverse order").
    """
    spray: list[Stroke] = []
    for k, pieces in enumerate(layers):
        strokes = [s for s in (_with_margins(p, config) for p in _join_gaps(pieces, config)) if len(s) >= 2]
        if not strokes:
            continue
        backward = [s.reversed() for s in strokes[::-1]]
        if spray:
            # zig-zag: start each layer at the end nearer to where the previous one finished (on a sheet this
            # alternates the direction; on a U-shaped section it still keeps the transfer short)
            here = spray[-1].tcp[-1]
            if np.linalg.norm(backward[0].tcp[0] - here) < np.linalg.norm(strokes[0].tcp[0] - here):
                strokes = backward
        for stroke in strokes:
            spray.append(Stroke(stroke.points, stroke.normals, stroke.tcp, True, stroke.on_part, k))
    return with_transfers(spray, config)


def with_transfers(strokes: list[Stroke], config: PathConfig) -> list[Stroke]:
    """Spray strokes in order with a spray-off transfer (:func:`transfer`) between each two."""
    out: list[Stroke] = []
    for stroke in strokes:
        if out:
            out.append(transfer(out[-1], stroke, config))
        out.append(stroke)
    return out


def _join_gaps(pieces: list[Piece], config: PathConfig) -> list[Piece]:
    """Open pieces of one layer, in travel order, joined by a straight sprayed bridge across gaps narrower
    than ``config.gap``; wider gaps separate strokes. Closed pieces stay as they are."""
    closed = [p for p in pieces if p.closed]
    open_ = [p for p in pieces if not p.closed]
    out: list[Piece] = []
    for piece in open_:
        if out and np.linalg.norm(piece.points[0] - out[-1].points[-1]) <= config.gap:
            prev = out[-1]
            bridge = _line(prev.points[-1], piece.points[0], config.step_mm)[1:-1]
            bridge_n = _slerp_normals(prev.normals[-1], piece.normals[0], len(bridge))
            out[-1] = Piece(
                np.vstack([prev.points, bridge, piece.points]),
                np.vstack([prev.normals, bridge_n, piece.normals]),
                np.concatenate([prev.on_part, np.zeros(len(bridge), bool), piece.on_part]),
                False,
            )
        else:
            out.append(piece)
    return out + closed


def _with_margins(piece: Piece, config: PathConfig) -> Stroke:
    """A stroke from a piece: lead-in and lead-out along the end tangents (open pieces), and the tcp.

    An end that turns over (a rim: see :func:`rim_lengths`) is not followed: the stroke leaves the face
    along its tangent and the lead goes on past the rim's edge by the margin, so that the face is painted up
    to its edge as a flat panel would be, instead of the gun swinging round the rim.
    """
    piece = without_repeats(piece)
    points, normals, on_part = piece.points, piece.normals, piece.on_part
    if piece.closed:
        points = np.vstack([points, points[:1]])
        normals = np.vstack([normals, normals[:1]])
        on_part = np.concatenate([on_part, on_part[:1]])
    elif len(points) >= 2:
        head, tail = rim_lengths(points, normals, config.rim)
        keep = slice(head, len(points) - tail)
        inner = points[keep]
        t0 = nm.unit((inner[0] - inner[1])[None])[0]
        t1 = nm.unit((inner[-1] - inner[-2])[None])[0]
        # how far the cut-off rims reach along the leads
        past0 = max(0.0, float(((points[:head] - inner[0]) @ t0).max())) if head else 0.0
        past1 = max(0.0, float(((points[len(points) - tail :] - inner[-1]) @ t1).max())) if tail else 0.0
        normals, on_part, points = normals[keep], on_part[keep], inner
        lead_in = _lead(points[0], t0, config.margin + past0 if config.margin > 0 else past0, config.step_mm)[::-1]
        lead_out = _lead(points[-1], t1, config.margin + past1 if config.margin > 0 else past1, config.step_mm)
        points = np.vstack([lead_in, points, lead_out])
        normals = np.vstack(
            [np.repeat(normals[:1], len(lead_in), 0), normals, np.repeat(normals[-1:], len(lead_out), 0)]
        )
        on_part = np.concatenate([np.zeros(len(lead_in), bool), on_part, np.zeros(len(lead_out), bool)])
    tcp = points + config.standoff_mm * normals
    return Stroke(points, normals, tcp, True, on_part)


def _lead(start: np.ndarray, direction: np.ndarray, length: float, step: float) -> np.ndarray:
    """Points from (not including) ``start`` out to ``length`` along ``direction``, about ``step`` apart."""
    if length <= 0:
        return np.zeros((0, 3))
    count = max(1, int(np.ceil(length / step)))
    return start + (length * np.arange(1, count + 1) / count)[:, None] * direction


def transfer(a: Stroke, b: Stroke, config: PathConfig) -> Stroke:
    """A spray-off move from the end of ``a`` to the start of ``b``: the gun tip on a straight line."""
    tcp = _line(a.tcp[-1], b.tcp[0], config.step_mm)
    normals = _slerp_normals(a.normals[-1], b.normals[0], len(tcp))
    points = tcp - config.standoff_mm * normals
    return Stroke(points, normals, tcp, False, np.zeros(len(tcp), bool), -1)


def _line(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    count = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
    t = np.linspace(0.0, 1.0, count + 1)[:, None]
    return a + t * (b - a)


def _slerp_normals(n0: np.ndarray, n1: np.ndarray, count: int) -> np.ndarray:
    if count <= 0:
        return np.zeros((0, 3))
    t = np.linspace(0.0, 1.0, count)[:, None]
    angle = np.arccos(np.clip(n0 @ n1, -1.0, 1.0))
    if angle < 1e-9:
        return np.repeat(n0[None], count, axis=0)
    if np.pi - angle < 1e-6:  # opposite normals: lerp through a perpendicular is undefined; switch halfway
        return np.where(t < 0.5, n0, n1)
    return (np.sin((1 - t) * angle) * n0 + np.sin(t * angle) * n1) / np.sin(angle)
