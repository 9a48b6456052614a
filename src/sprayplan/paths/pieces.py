"""Pieces of sections: stretches of one slicing layer, resampled, the raw material of strokes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.config import PathConfig
from sprayplan.paths import polyline as pl
from sprayplan.paths.interpolation import interpolate_with_normals
from sprayplan.surface import normals as nm

#: Section pieces shorter than this (mm) are dropped: a plane grazing a corner.
MIN_PIECE_MM = 1.0


@dataclass(frozen=True)
class Piece:
    """A stretch of one section, resampled: the raw material of a stroke."""

    points: np.ndarray
    normals: np.ndarray
    on_part: np.ndarray
    closed: bool


def resample_piece(points, normals, closed, config: PathConfig) -> Piece:
    """Arc-length resampling (003 eq. 13), then optional line / arc interpolation (003 section 3.2.3).

    Resampled points lie on the section (so on the surface for a mesh) and take the normals interpolated
    along their segment. Interpolated points between them (``config.interpolate``) follow a straight line or
    the circle through three consecutive samples; they are marked ``on_part = False`` because a chord or an
    arc leaves the surface between samples.
    """
    if config.points_per_section is not None:
        new, seg, t = pl.resample(points, count=config.points_per_section, closed=closed)
    else:
        new, seg, t = pl.resample(points, step_mm=config.step_mm, closed=closed)
    nxt = (seg + 1) % len(points)
    n = nm.unit((1 - t)[:, None] * normals[seg] + t[:, None] * normals[nxt])
    on_part = np.ones(len(new), dtype=bool)
    if config.interpolate != "none" and len(new) >= 2:
        loop_p = np.vstack([new, new[:1]]) if closed else new
        loop_n = np.vstack([n, n[:1]]) if closed else n
        dense, dense_n = interpolate_with_normals(loop_p, loop_n, config.step_mm, config.interpolate)
        if closed:
            dense, dense_n = dense[:-1], dense_n[:-1]
        on_part = cKDTree(new).query(dense)[0] == 0.0
        new, n = dense, dense_n
    return Piece(new, n, on_part, closed)


def without_repeats(piece: Piece) -> Piece:
    """The piece with one point of each run of repeated points (and, when closed, without a last point equal
    to the first): a plane through a mesh vertex repeats a section point, and pieces split at a feature point
    and joined again share it; a repeat would give a lead no direction."""
    points = piece.points
    if len(points) < 2:
        return piece
    keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-9])
    if piece.closed and keep.sum() > 1 and np.linalg.norm(points[-1] - points[0]) <= 1e-9:
        keep[-1] = False
    if keep.all():
        return piece
    return Piece(points[keep], piece.normals[keep], piece.on_part[keep], piece.closed)


def in_travel_order(sections: list[list[Piece]], travel) -> list[Piece]:
    """The pieces of a layer's sections, section after section by where each starts along the travel
    direction (what joining across gaps expects: the slicer gives sections in no particular order), keeping
    the order of the pieces within a section (the order along its polyline)."""
    travel = np.asarray(travel, float)
    filled = [group for group in sections if group]
    filled.sort(key=lambda group: float(group[0].points[0] @ travel))
    return [piece for group in filled for piece in group]


def insert_in_travel_order(pieces: list[Piece], extra: list[Piece], travel) -> list[Piece]:
    """``pieces`` with each of ``extra`` put before the first open piece that starts farther along the travel
    direction (the rest keep their order)."""
    travel = np.asarray(travel, float)
    out = list(pieces)
    for piece in extra:
        key = float(piece.points[0] @ travel)
        at = next((i for i, p in enumerate(out) if not p.closed and float(p.points[0] @ travel) > key), len(out))
        out.insert(at, piece)
    return out


def smooth_normals(points: np.ndarray, normals: np.ndarray, half_width_mm: float, closed: bool = False) -> np.ndarray:
    """Normals along a polyline averaged over ``half_width_mm`` of arc length either side, then made unit.

    A scanned surface's normals turn by several degrees from one section point to the next; the gun, which
    follows them at the standoff, would then sweep its tip far more than the contact point moves. Averaging
    over a stretch shorter than the spray radius keeps the turns of the surface and drops the noise.
    """
    n = len(points)
    if half_width_mm <= 0 or n < 3:
        return normals
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    if closed:
        period = arc[-1] + float(np.linalg.norm(points[0] - points[-1]))
        arc = np.concatenate([arc - period, arc, arc + period])
        values = np.vstack([normals, normals, normals])
        centre = arc[n : 2 * n]
    else:
        values = normals
        centre = arc
    total = np.vstack([np.zeros((1, 3)), np.cumsum(values, axis=0)])
    lo = np.searchsorted(arc, centre - half_width_mm, side="left")
    hi = np.searchsorted(arc, centre + half_width_mm, side="right")
    mean = (total[hi] - total[lo]) / np.maximum(hi - lo, 1)[:, None]
    length = np.linalg.norm(mean, axis=1)
    return np.where(length[:, None] > 1e-9, mean / np.maximum(length, 1e-12)[:, None], normals)
