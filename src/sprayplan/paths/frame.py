"""The slicing frame and the plane offsets: which way a part is sliced and where its planes go.

Shared by every kind of section (``paths.layers`` marches them): the planes' normal and the strokes' travel
direction from the part's covariance (:func:`slicing_frame`), and the plane offsets, uniform or marched so
that adjacent sections are the spacing apart on the part (:func:`layer_offsets`, :func:`march_offsets`).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from sprayplan.checks import MAX_LAYERS
from sprayplan.config import PathConfig
from sprayplan.errors import ConfigError

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


#: The planes look for the far side of a gap in the part (:func:`march_offsets`) this many spacings apart.
GAP_PROBE = 0.05


def _past_gap(offset: float, hi: float, d: float, samples) -> float | None:
    """The plane offset at which the march goes on past a gap in the part that ``offset`` lies in: half a
    spacing past the gap's far edge (found to ``GAP_PROBE * d``), or the first offset with a section when the
    piece beyond is thinner than that; None when no section lies beyond ``offset`` (up to ``hi``)."""
    step = GAP_PROBE * d
    eps = 1e-6 * max(abs(hi), 1.0)
    for probe in np.arange(offset + step, hi, step):
        if len(samples(float(probe))):
            inside = float(min(probe - step + d / 2, hi - eps))
            return inside if len(samples(inside)) else float(probe)
    return None


def march_offsets(lo: float, hi: float, d: float, samples, distance, close: bool = True) -> list[float]:
    """Plane offsets such that each section lies ``d`` from the previous one, measured on the part.

    The first plane is ``d / 2`` in from the lowest offset; each next offset is found by root finding
    (Brent's method, to 0.1% of d) on the gap between the current section and the next: the smaller of the
    median distance from the current section's points to the next section and the median distance back
    (where the part's outline narrows, the far ends of the longer section would make the one-way distance
    too large). The gap is at least the planes' distance, so the root lies within one spacing. The planes move by
    at least ``MIN_PLANE_STEP * d``. With ``close``, a last layer at the far edge (closer than ``d``) is added
    when more than half a spacing of the part would otherwise be left; without, the march stops at the last
    layer a whole spacing from the previous one (edge passes then carry on past the edge). A plane that lands
    in a gap of the part (two pieces apart along the planes' normal, such as an area whose faces are not all
    joined) does not end the march: it goes on half a spacing past the gap's far edge (:func:`_past_gap`).

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
        if len(offsets) > MAX_LAYERS:
            raise ConfigError(
                f"paths.spacing_mm {d:.4g} would make more than {MAX_LAYERS} layers on this part ({hi - lo:.4g} mm"
                f" across the layers, where the surface runs along the planes): use a larger paths.spacing_mm"
                " or another paths.direction"
            )
        current = samples(offsets[-1])
        if len(current) == 0:
            # the plane stepped into a gap between two pieces of the part (apart along the planes' normal): the
            # march starts again past the gap, as it started at the part's lowest offset
            resumed = _past_gap(offsets[-1], hi, d, samples)
            if resumed is None:
                offsets.pop()
                break
            offsets[-1] = resumed
            continue

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
