"""Station partition of seed 000, section 5.1: envelope rectangle, circle cover, greedy assignment.

The gantry stops at a few stations; from each, the hanging UR5 paints what lies in its working cylinder
(radius R = 727.6 mm, see ``robots.gantry.Workspace``). Projected on the xy plane, the problem is to cover the
targets with the fewest circles of radius R (section 5.1):

1. The principal direction of the projected targets from their central moments (eqs. 28-29),
   ``theta = atan2(2 M11, M20 - M02) / 2``, and the targets' envelope rectangle along it (figure 15): length
   ``l_max`` along the principal direction, width ``h_max`` across it.
2. The filling model (figure 16, eq. 30): the rectangle is filled with rows of circles; a circle's effective
   rectangle is ``l x h`` with ``l^2 + h^2 = (2R)^2`` (inscribed in the circle). With m rows of height h,
   ``m h >= h_max``, each row has ``n = ceil(l_max / l)`` circles, ``l = sqrt(4 R^2 - h^2)``. (Eq. 30's
   ``n = [l_max / (sqrt 2 r)] + 1`` is the square case l = h = sqrt(2) r, and its ``sqrt(4 r^2 - l_i^2) >= h``
   is the inscribed-rectangle condition.) The fewest circles come first.
3. Among the layouts with the fewest circles, the row height h and the offsets ``Px``, ``Py`` of the circle
   grid against the rectangle are searched exhaustively (steps of ``search_step_mm``) for the fewest targets in
   the non-recommended area (figure 28): targets that no circle covers outside its 151 mm core.
4. Each station, in visiting order, takes every target still unassigned inside its circle ("includes as many
   target points as possible for each time of painting", section 5.2); targets no circle covers are
   reported.

The seed's roof (2635 x 1959 mm) gives 2 rows of 3 circles (six stations, table 2) with h = 980 mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sprayplan.errors import ConfigError, InputError
from sprayplan.types import read_only


def principal_angle(xy: np.ndarray) -> float:
    """Eq. 28-29: the angle of the principal direction of projected points from their central moments, rad."""
    d = xy - xy.mean(axis=0)
    m20, m02, m11 = (d[:, 0] ** 2).sum(), (d[:, 1] ** 2).sum(), (d[:, 0] * d[:, 1]).sum()
    return 0.5 * math.atan2(2.0 * m11, m20 - m02)


@dataclass(frozen=True)
class EnvelopeRectangle:
    """The targets' minimum envelope rectangle along their principal direction (figure 15).

    Attributes
    ----------
    angle : float, rad
        Direction of the rectangle's length from +x.
    origin : (2,) float, mm
        The corner with the smallest coordinates in the rectangle's frame, in world xy.
    length_mm, width_mm : float
        ``l_max`` along the principal direction, ``h_max`` across it.
    """

    angle: float
    origin: np.ndarray
    length_mm: float
    width_mm: float

    @property
    def axes(self) -> np.ndarray:
        """(2, 2): rows are the unit vectors along the length and across it."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        return np.array([[c, s], [-s, c]])

    def to_local(self, xy: np.ndarray) -> np.ndarray:
        """World xy -> rectangle frame (u along the length from the origin, v across)."""
        return (np.asarray(xy, dtype=float) - self.origin) @ self.axes.T

    def to_world(self, uv: np.ndarray) -> np.ndarray:
        """Rectangle frame -> world xy."""
        return np.asarray(uv, dtype=float) @ self.axes + self.origin


def envelope_rectangle(xy: np.ndarray) -> EnvelopeRectangle:
    """The targets' envelope rectangle (figure 15).

    Seed 000 takes the rectangle along the principal direction of eqs. 28-29. That direction is arbitrary for
    a square-ish outline (the two central moments nearly equal), so the rectangle of least area among that
    direction and the directions of the targets' convex hull edges is kept (the least-area rectangle has a
    side on a hull edge); for an elongated outline it is the seed's. The longer side is the length.
    """
    xy = np.asarray(xy, dtype=float)
    if len(xy) == 0:
        raise InputError("no targets to partition into stations")
    angles = [principal_angle(xy) if len(xy) > 1 else 0.0]
    if len(xy) >= 3:
        from scipy.spatial import ConvexHull, QhullError

        try:
            hull = xy[ConvexHull(xy).vertices]
            edges = np.roll(hull, -1, axis=0) - hull
            angles += list(np.arctan2(edges[:, 1], edges[:, 0]))
        except QhullError:  # collinear points: the principal direction is exact
            pass
    best = None
    for angle in angles:
        c, s = math.cos(angle), math.sin(angle)
        local = xy @ np.array([[c, -s], [s, c]])
        lo, hi = local.min(axis=0), local.max(axis=0)
        size = hi - lo
        area = size[0] * size[1]
        if best is None or area < best[0] * (1 - 1e-9):
            best = (area, angle, lo, size)
    _, angle, lo, size = best
    if size[1] > size[0]:  # the length is the longer side
        angle += math.pi / 2
        lo = np.array([lo[1], -(lo[0] + size[0])])
        size = size[::-1]
    c, s = math.cos(angle), math.sin(angle)
    origin = lo @ np.array([[c, s], [-s, c]])
    return EnvelopeRectangle(angle, origin, float(size[0]), float(size[1]))


@dataclass(frozen=True)
class CoverModel:
    """A circle cover of the envelope rectangle (figure 16): the station centres and the layout found.

    Attributes
    ----------
    centres : (k, 2) float, mm
        Station centres in world xy, row by row.
    rectangle : EnvelopeRectangle
    rows, per_row : int
        m rows of n circles.
    row_height_mm, circle_length_mm : float
        h and l, with l^2 + h^2 = (2R)^2.
    px_mm, py_mm : float
        Offsets of the circle grid before the rectangle's start along its length and width.
    non_recommended : int
        Targets no circle covers outside its core (the objective of figure 28).
    radius_mm, core_radius_mm : float
    """

    centres: np.ndarray
    rectangle: EnvelopeRectangle
    rows: int
    per_row: int
    row_height_mm: float
    circle_length_mm: float
    px_mm: float
    py_mm: float
    non_recommended: int
    radius_mm: float
    core_radius_mm: float


def _layout(radius, length, rows, h, px, py):
    """Circle centres (k, 2) in the rectangle frame for m rows of height h and offsets px, py."""
    l = math.sqrt(max(4.0 * radius**2 - h * h, 0.0))  # noqa: E741 - the seed's symbol
    n = max(1, math.ceil(length / l - 1e-9))
    u = -px + l * (np.arange(n) + 0.5)
    v = -py + h * (np.arange(rows) + 0.5)
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2), n, l


def _grid(lo: float, hi: float, step: float, max_values: int, include_end: bool = True) -> np.ndarray:
    """Values from lo toward hi every ``step`` (coarser when that would give more than ``max_values``)."""
    if hi <= lo:
        return np.array([lo])
    count = min(max_values, int((hi - lo) / step) + 1)
    if include_end:
        return np.linspace(lo, hi, max(count, 1))
    return lo + (hi - lo) * np.arange(count) / count


def circle_cover(
    xy: np.ndarray,
    radius_mm: float,
    core_radius_mm: float = 75.5,
    *,
    search_step_mm: float = 10.0,
    max_values: int = 20,
    max_targets: int = 1500,
    seed: int = 0,
) -> CoverModel:
    """The fewest circles of radius R covering the targets' envelope rectangle, placed to keep targets out of
    the circles' cores (seed 000, section 5.1.2, figure 16, eq. 30, figure 28).

    Parameters
    ----------
    xy : (n, 2) float, mm
        Projected targets.
    radius_mm : float
        R, the working cylinder's radius.
    core_radius_mm : float
        Radius of the non-recommended core (seed: 151 mm diameter).
    search_step_mm : float
        Step of the exhaustive search over the row height and the offsets.
    max_values : int
        At most this many values of each searched quantity (the step grows on large parts).
    max_targets : int
        The objective is counted on at most this many targets (a seeded random subset): the search is
        exhaustive over the layout, not over millions of points.
    seed : int

    Returns
    -------
    CoverModel
    """
    if not radius_mm > core_radius_mm >= 0:
        raise ConfigError("the working radius must exceed the core radius")
    xy = np.asarray(xy, dtype=float)
    rect = envelope_rectangle(xy)
    sample = xy
    if len(xy) > max_targets:
        sample = xy[np.random.default_rng(seed).choice(len(xy), max_targets, replace=False)]
    local = rect.to_local(sample)
    diameter = 2.0 * radius_mm
    length, width = max(rect.length_mm, 1e-9), max(rect.width_mm, 1e-9)
    best = None
    # fewest circles first: try row counts, and for each the row heights that fit, keep the smallest count
    # a row is at most one diameter high; the search stops once more rows stop paying (below), and looks at
    # no more than twice the fewest rows (each extra row adds at least ceil(l_max / 2R) circles)
    fewest_rows = max(1, math.ceil(width / diameter + 1e-9))
    for rows in range(fewest_rows, 2 * fewest_rows + 2):
        h_min = width / rows
        if h_min >= diameter:
            continue
        heights = _grid(h_min, diameter, search_step_mm, max_values, include_end=False)
        counts = [rows * max(1, math.ceil(length / math.sqrt(diameter**2 - h * h) - 1e-9)) for h in heights]
        fewest = min(counts)
        if best is not None and fewest > best[0]:
            break  # more rows only add circles from here on
        for h, count in zip(heights, counts):
            if count != fewest or (best is not None and count > best[0]):
                continue
            centres, n, cl = _layout(radius_mm, length, rows, h, 0.0, 0.0)
            slack_u, slack_v = n * cl - length, rows * h - width
            for px in _grid(0.0, slack_u, search_step_mm, max_values):
                for py in _grid(0.0, slack_v, search_step_mm, max_values):
                    grid = centres - np.array([px, py])
                    distance = np.linalg.norm(local[:, None, :] - grid[None], axis=2)
                    good = ((distance <= radius_mm) & (distance >= core_radius_mm)).any(axis=1)
                    bad = int((~good).sum())
                    key = (count, bad, abs(px - slack_u / 2) + abs(py - slack_v / 2))
                    if best is None or key < best[1]:
                        best = (count, key, rows, n, h, cl, px, py, bad)
    _, _, rows, n, h, cl, px, py, bad = best
    centres, _, _ = _layout(radius_mm, length, rows, h, px, py)
    return CoverModel(
        rect.to_world(centres), rect, rows, n, float(h), float(cl), float(px), float(py), bad, radius_mm, core_radius_mm
    )


@dataclass(frozen=True)
class StationAssignment:
    """Which station paints each target.

    Attributes
    ----------
    station : (n,) int
        Index into the station list, -1 for targets no station reaches.
    recommended : (n,) bool
        The target lies outside its station's core (analytic inverse kinematics).
    """

    station: np.ndarray
    recommended: np.ndarray

    def __post_init__(self):
        read_only(self)


def assign_greedy(
    xy: np.ndarray, centres: np.ndarray, order: np.ndarray, radius_mm: float, core_radius_mm: float
) -> StationAssignment:
    """Greedy assignment (section 5.2): stations in visiting order each take every unassigned target in their
    circle, first those outside their core; a target in a core is left for a later station that has it
    outside its core when there is one.
    """
    xy = np.asarray(xy, dtype=float)
    distance = np.linalg.norm(xy[:, None, :] - np.asarray(centres)[None], axis=2)
    inside = distance <= radius_mm
    outside_core = inside & (distance >= core_radius_mm)
    station = np.full(len(xy), -1)
    for k in order:  # first pass: the recommended annulus
        take = (station < 0) & outside_core[:, k]
        station[take] = k
    for k in order:  # second pass: what only a core reaches
        take = (station < 0) & inside[:, k]
        station[take] = k
    assigned = station >= 0
    recommended = np.zeros(len(xy), dtype=bool)
    recommended[assigned] = outside_core[np.flatnonzero(assigned), station[assigned]]
    return StationAssignment(station, recommended)
