"""The slicing layers of a part, whatever kind of section cuts it (seed 003 sections 2.1 and 3.2).

One march for every part: the slicing frame from the part's covariance (``paths.frame``), the plane offsets
(uniform, or marched so that adjacent sections are the spacing apart on the part), each plane's section
polylines oriented along the travel direction, split at sharp features and resampled at the step, the pieces
of a layer in travel order, and edge passes past the part's open edges (``paths.edges``).

What differs between a mesh and a point cloud is only how a plane cuts the part: a :class:`SectionSource`
gives it. ``paths.mesh_sections`` cuts a mesh exactly; ``paths.cloud_sections`` cuts slabs of a cloud.
"""

from __future__ import annotations

import logging
from typing import Protocol

import numpy as np

from sprayplan.checks import MAX_LAYERS, MAX_WAYPOINTS, check_work, round_up
from sprayplan.config import PathConfig
from sprayplan.paths import polyline as pl
from sprayplan.paths import segmentation
from sprayplan.paths.edges import edge_pass_counts, layer_spacing, with_edge_passes, with_inner_edge_passes
from sprayplan.paths.frame import layer_offsets, slicing_frame
from sprayplan.paths.pieces import MIN_PIECE_MM, Piece, in_travel_order, resample_piece

log = logging.getLogger(__name__)


class SectionSource(Protocol):
    """How planes cut one prepared part (normals found, a cloud cleaned), for :func:`build_layers`.

    The march first asks for :meth:`covariance` to choose the slicing frame, then calls :meth:`use_frame`
    once, and after that only the other methods.
    """

    name: str

    def covariance(self) -> np.ndarray:
        """(3, 3) covariance of the part's surface (mm^2), for ``frame.slicing_frame``."""

    def use_frame(self, normal: np.ndarray, travel: np.ndarray) -> tuple[float, float]:
        """Slice with planes ``{x : x . normal = offset}``; returns the part's extent (lo, hi) along ``normal``."""

    def boundary(self, step: float) -> np.ndarray:
        """(k, 3) points along the part's open edges, about ``step`` apart or closer; empty for a closed part."""

    def samples(self, offset: float) -> np.ndarray:
        """(k, 3) points along the section at ``offset`` (at most 400), for distances on the part."""

    def distance(self, query: np.ndarray, offset: float) -> float:
        """Median distance from ``query`` (k, 3) to the section at ``offset``; inf when there is none."""

    def sections(self, offset: float) -> list[tuple[np.ndarray, np.ndarray, bool]]:
        """The section polylines at ``offset``: (points (m, 3), unit outward normals (m, 3), closed)."""

    def describe(self) -> str:
        """A few words on the sections for the log (e.g. the slab's width)."""


def build_layers(
    source: SectionSource, config: PathConfig, progress=None, area_mm2: float | None = None
) -> list[list[Piece]]:
    """Resampled pieces of every slicing layer, in layer order, edge passes included.

    Parameters
    ----------
    source : SectionSource
        The part's sections (a mesh's or a cloud's).
    config : PathConfig
    progress : callable, optional
        ``progress(done, total)`` after each layer's sections.
    area_mm2 : float, optional
        The part's surface area (a cloud's: about its outline's), to refuse before slicing a step or spacing
        that would make more than ``checks.MAX_WAYPOINTS`` waypoints (:func:`check_layer_work`).

    Returns
    -------
    list of list of Piece
        One list per layer (planes in offset order, edge passes before the first and after the last); the
        pieces of a layer in travel order.
    """
    normal, travel = slicing_frame(source.covariance(), config.direction)
    lo, hi = source.use_frame(normal, travel)
    check_layer_work(lo, hi, config, area_mm2)
    d = layer_spacing(lo, hi, config)
    boundary = source.boundary(d / 4)
    offsets = layer_offsets(lo, hi, config, source.samples, source.distance, closed_part=len(boundary) == 0)
    layers = []
    for offset in offsets:
        pieces = [section_pieces(p, n, closed, travel, config) for p, n, closed in source.sections(offset)]
        layers.append(in_travel_order(pieces, travel))
        if progress is not None:
            progress(len(layers), len(offsets))
    counts = edge_pass_counts(lo, hi, offsets, config, source.samples, source.distance)
    log.info(
        "%s: %d layers along (%.3f, %.3f, %.3f)%s, edge passes %d + %d",
        source.name,
        len(layers),
        *normal,
        source.describe(),
        *counts,
    )
    layers = with_inner_edge_passes(layers, normal, travel, d, config, boundary)
    return with_edge_passes(layers, normal, counts, d, config, boundary)


def check_layer_work(lo: float, hi: float, config: PathConfig, area_mm2: float | None = None) -> None:
    """Refuse, before any slicing, settings that would make more layers than ``MAX_LAYERS`` or more waypoints
    than ``MAX_WAYPOINTS`` on a part spanning [lo, hi] across the layers (surface area ``area_mm2``).

    Layers: the span over the spacing (``paths.layers`` is bounded by the config itself). Waypoints: the
    strokes' length (about area / spacing, plus two leads per layer and the edge passes) over ``step_mm``, or
    ``points_per_section`` per layer. Each message names the setting, its value, the part's size and the
    value that would be accepted.
    """
    span = max(float(hi - lo), 0.0)
    d = layer_spacing(lo, hi, config)
    spacing_name = (
        "paths.spacing_mm" if config.spacing_mm is not None else "paths.spacing_mm (from spray_radius_mm and overlap)"
    )
    if config.layers is None and span > 0:
        check_work(
            span / d,
            MAX_LAYERS,
            "layers",
            spacing_name,
            d,
            f"{span:.4g} mm across the layers",
            f"use paths.spacing_mm >= {round_up(span / MAX_LAYERS)}",
        )
    layers = (config.layers or max(1.0, span / d)) + (2 * config.edge_passes if config.edge_passes != "auto" else 6)
    if config.points_per_section is not None:
        check_work(
            layers * config.points_per_section,
            MAX_WAYPOINTS,
            "waypoints",
            "paths.points_per_section",
            config.points_per_section,
            f"{layers:.0f} layers",
            f"use paths.points_per_section <= {max(2, int(MAX_WAYPOINTS // layers))}",
        )
    if area_mm2 is None or not area_mm2 > 0:
        return
    width = area_mm2 / max(span, d)  # the sections' mean length
    length = layers * (width + 2 * config.margin)
    if config.points_per_section is not None and config.interpolate == "none":
        return
    check_work(
        length / config.step_mm,
        MAX_WAYPOINTS,
        "waypoints",
        "paths.step_mm",
        config.step_mm,
        f"{area_mm2:.4g} mm^2, {layers:.0f} layers of about {width:.4g} mm",
        f"use paths.step_mm >= {round_up(length / MAX_WAYPOINTS)}",
    )


def section_pieces(points, normals, closed, travel, config: PathConfig) -> list[Piece]:
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
