"""Compression of target points (seed 000, section 2.5, eq. 7).

Eq. 7 snaps every coordinate to a grid of step ``k = floor(d / sqrt(3))`` (a cube of side k has a diagonal of at
most d) and merges the points that meet. Rounding moves points off the surface by up to ``k sqrt(3) / 2``, so
the default here keeps, in each grid cell, the real point nearest to the cell's grid node instead: the same
cells, the same count, but every kept point still lies on the surface with its own normal.
"""

from __future__ import annotations

import math

import numpy as np

from sprayplan.errors import ConfigError
from sprayplan.surface.normals import unit

COMPRESS_METHODS = ("surface", "grid", "none")


def grid_step(spacing_mm: float) -> float:
    """Eq. 7: k = floor(d / sqrt(3)), mm."""
    k = math.floor(spacing_mm / math.sqrt(3.0))
    if k <= 0:
        raise ConfigError(
            f"grid compression needs a spacing of at least sqrt(3) = 1.73 mm (k = floor(d / sqrt 3)); got {spacing_mm}"
        )
    return float(k)


def _cells(points: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray]:
    node = np.round(points / k)
    _, inverse = np.unique(node, axis=0, return_inverse=True)
    return node, inverse.reshape(-1)


def compress_grid(points: np.ndarray, normals: np.ndarray, spacing_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The seed's eq. 7: ``P = round(P / k) * k`` per coordinate, equal points merged.

    Parameters
    ----------
    points : (n, 3) float, mm
    normals : (n, 3) float
    spacing_mm : float
        d in eq. 7.

    Returns
    -------
    points : (m, 3) float
        Grid nodes, multiples of k (off the surface by up to k sqrt(3) / 2).
    normals : (m, 3) float
        The normalised mean of the merged points' normals (the seed does not say; the mean keeps the spray
        axis of a merged node between those of its points).
    """
    k = grid_step(spacing_mm)
    node, inverse = _cells(points, k)
    m = int(inverse.max()) + 1 if len(inverse) else 0
    summed = np.stack([np.bincount(inverse, normals[:, a], m) for a in range(3)], axis=1)
    nodes = np.zeros((m, 3))
    nodes[inverse] = node * k
    return nodes, unit(summed)


def compress_surface(points: np.ndarray, spacing_mm: float) -> np.ndarray:
    """One real point per eq. 7 grid cell: the one nearest the cell's node.

    Parameters
    ----------
    points : (n, 3) float, mm
    spacing_mm : float

    Returns
    -------
    keep : (m,) int
        Indices of the kept points, in increasing order.
    """
    k = grid_step(spacing_mm)
    node, inverse = _cells(points, k)
    dist = np.linalg.norm(points - node * k, axis=1)
    order = np.lexsort((dist, inverse))  # by cell, nearest first
    first = np.r_[True, inverse[order][1:] != inverse[order][:-1]]
    return np.sort(order[first])
