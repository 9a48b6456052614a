"""The ``paths`` stage: a part -> spray strokes in execution order (seed 003 sections 2-3, seed 000 eq. 6).

A part's slicing layers come from one march (``paths.layers.build_layers``) over the part's kind of section:
exact plane sections of a mesh (``paths.mesh_sections``) or slab sections of a point cloud
(``paths.cloud_sections``). Each layer's pieces are then joined across gaps narrower than the spray diameter
and split at wider ones, given lead-in / lead-out margins, the layers zig-zagged, and spray-off transfers put
between the strokes (here).
"""

from __future__ import annotations

import logging

import numpy as np

from sprayplan.config import PathConfig
from sprayplan.errors import InputError
from sprayplan.paths.cloud_sections import cloud_sections
from sprayplan.paths.edges import rim_lengths
from sprayplan.paths.layers import build_layers
from sprayplan.paths.mesh_sections import MeshSections
from sprayplan.paths.pieces import Piece, smooth_normals, without_repeats
from sprayplan.surface import normals as nm
from sprayplan.types import Part, Paths, Stroke

log = logging.getLogger(__name__)


def plan_paths(part: Part, config: PathConfig | None = None, progress=None) -> Paths:
    """Spray strokes over a part, in execution order.

    Parameters
    ----------
    part : Part
        A mesh or a point cloud (after ``load`` and ``region``), mm.
    config : PathConfig, optional
    progress : callable, optional
        ``progress(done, total)`` after each slicing layer.

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
    source = MeshSections(part, config.spacing) if part.is_mesh else cloud_sections(part, config)
    layers = build_layers(source, config, progress, area_mm2=_area(part)) if source is not None else []
    if not any(layers):
        raise InputError(f"{part.name}: no section of the part to paint (spacing {config.spacing:.4g} mm)")
    strokes = order_strokes(layers, config)
    return Paths(tuple(strokes), config.standoff_mm, config.spacing, part.name)


def _area(part: Part) -> float:
    """The part's surface area, mm^2 (a cloud's: its bounding box's two largest sides' product)."""
    if part.is_mesh:
        return float(part.area)
    if not len(part.vertices):
        return 0.0
    size = np.sort(np.ptp(part.vertices, axis=0))
    return float(size[1] * size[2])


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
        normals = gun_axes(points, normals, config, closed=True)
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
        normals = gun_axes(points, normals, config)
        lead_in = _lead(points[0], t0, config.margin + past0 if config.margin > 0 else past0, config.step_mm)[::-1]
        lead_out = _lead(points[-1], t1, config.margin + past1 if config.margin > 0 else past1, config.step_mm)
        points = np.vstack([lead_in, points, lead_out])
        normals = np.vstack(
            [np.repeat(normals[:1], len(lead_in), 0), normals, np.repeat(normals[-1:], len(lead_out), 0)]
        )
        on_part = np.concatenate([np.zeros(len(lead_in), bool), on_part, np.zeros(len(lead_out), bool)])
    tcp = points + config.standoff_mm * normals
    return Stroke(points, normals, tcp, True, on_part)


def gun_axes(points: np.ndarray, normals: np.ndarray, config: PathConfig, closed: bool = False) -> np.ndarray:
    """The gun's axis at each point of a stroke: the normals averaged over ``config.gun_smooth_mm`` of arc
    length either side with a triangle weight (two box averages of half that width), made unit; by default
    the spray's diameter."""
    width = 2.0 * config.spray_radius_mm if config.gun_smooth_mm is None else config.gun_smooth_mm
    if width <= 0:
        return normals
    once = smooth_normals(points, normals, width / 2.0, closed=closed)
    return smooth_normals(points, once, width / 2.0, closed=closed)


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
