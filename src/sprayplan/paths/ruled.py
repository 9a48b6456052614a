"""Spray paths on ruled surfaces between two boundary curves (seed 001).

A ruled surface is swept by straight segments (rulings) between two boundary curves A and B::

    S(u, v) = (1 - v) A(u) + v B(u),    u, v in [0, 1]

where both curves are parametrised by normalised arc length u, so the ruling at u joins the points at the same
fraction of each curve's length. Curves: a line, an arc (centre and angles, or three points), a circle, a point
(the rulings then form a fan or cone) and a 2D/3D polyline. Give A and B in matching directions: rulings join
A(0) to B(0) and A(1) to B(1), and opposite directions make a twisted, self-intersecting surface (logged).

Normals are ``dS/du x dS/dv`` (analytic derivatives), made unit and turned toward the gun side: by default
``gun_side = [0, 0, 1]``, i.e. every normal has a non-negative z component (the seed's gun looks straight down);
with ``outward_from = [x, y, z]`` a normal points away from that point instead (a cylinder band's outside).
The choice is made point by point; where the normal is perpendicular to the gun side the parametrisation's sign
is kept and a warning is logged. Where the cross product vanishes (a cone's apex, where the curves touch) the
normal is the limit from a point 1e-6 inside the parameter square.

The TOML file that describes a job is read by ``ruled_toml.load_ruled`` (its schema is there).

Spacing, measured along the boundary curves. ``rulings``: the passes are the rulings at parameters u_k, the same
on both curves; their distance along the longer curve (length L) is ``(u_{k+1} - u_k) L``, so on the shorter one
it is less. With ``overlap``, the passes are exactly d apart along the longer curve: ``N = floor(L / d) + 1``
passes, centred, leaving an equal margin under d / 2 (inside the spot's radius) at both ends; when both curves
are closed (a band between two circles, a cone) ``N = ceil(L / d)`` passes go all the way round, L / N apart.
With ``passes = N``: u_k = k / (N - 1), the first and last passes on the surface's edges (closed: u_k = k / N).
``across``: the same rules along the longest ruling (length W, sampled): passes at v_k are ``(v_{k+1} - v_k) W``
apart there, and closer on shorter rulings. Adjacent passes run in opposite directions (zig-zag); between them
a spray-off transfer stroke (layer -1) runs over the surface, straight in (u, v), at the standoff.

The seed's tables 4 and 5 (what they show, and what this module reproduces):

* The column headers are shuffled in the extracted text. Table 4's rows satisfy the R5150 forward kinematics
  (d1 = 255.55, a2 = a3 = 190, d5 = 115 mm; eq. 3) to within 3e-4 mm when read as x = "X", y = "q2", z = "q3",
  theta1 = "q4" (= atan2(y, x)), theta2 = "q5", theta3 = "Z", theta4 = "Y", with theta2 + theta3 + theta4 = 0
  (tool straight down); "q1" is 90 in every row. Its points are (150,100,150), (150,300,150), (180,290,160),
  (180,110,160), (210,120,170), (210,280,170), (240,270,180), (240,130,180), (270,140,190), (270,260,190): five
  rulings, zig-zag, between the lines A (150,100,150)-(270,140,190) and B (150,300,150)-(270,260,190) (a plane
  trapezoid). ``examples/ruled/case1_table4.toml`` (``passes = 5``) gives these ten points exactly, in order.
* Table 5 lists rows 1-3 and 10 only: (172,162,300), (300,162,300), (192,182,300), (300,255.4,300). Its joint
  columns, read in the printed order as theta1..theta4 (the only order, of all orders and signs of the five
  columns, that comes within 6.9 mm of any row), give under eq. 3 the positions (171.88, 164.20, 296.25),
  (299.04, 161.89, 297.13), (192.89, 182.53, 299.23), (300.02, 255.42, 299.96): row 10 is met to 0.05 mm (the
  angles' rounding), rows 1-3 miss by 4.35, 3.02 and 1.29 mm. Their theta1 (43.69, 28.43, 43.42, 40.41 deg) is
  not atan2(y, x) of the listed points (43.29, 28.37, 43.47, 40.41), so those joint rows belong to other points
  (or carry typos); and theta2 + theta3 + theta4 is 44.11, 44.38, 44.83, 44.99 deg: the tool is tilted about
  45 deg from vertical and the tilt is not constant, unlike table 4. The elbow-up inverse kinematics of the
  listed points with a 45 deg tilt is (43.29, 97.38, -116.64, 64.26), (28.37, 66.45, -81.22, 59.76),
  (43.47, 88.67, -108.41, 64.74), (40.41, 49.43, -55.03, 50.60) deg.
  Rows 2 -> 3 jump back from x = 300 to x = 192, so table 5 lists every ruling from A to B (one way), not a
  zig-zag. ``examples/ruled/case2_table5.toml`` assumes two lines in the plane z = 300, A from (172,162) to
  (252,242) and B from (300,162) to (300,255.4), 5 passes, ``zigzag = false``: rows 2k-1 and 2k are A(u_k) and
  B(u_k) with u_k = (k - 1) / 4. It meets the four listed rows exactly; its unlisted rows 4-9 are assumptions:
  (300,185.35), (212,202), (300,208.7), (232,222), (300,232.05), (252,242), all at z = 300.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from sprayplan.checks import MAX_LAYERS, MAX_WAYPOINTS, MIN_STEP_MM, check_work, round_up
from sprayplan.errors import ConfigError
from sprayplan.paths.ruled_surface import (  # noqa: F401 - re-exported: the curve types are part of this API
    _NO_BREAKS,
    DIRECTIONS,
    Arc,
    Curve,
    Line,
    PointCurve,
    Polyline,
    RuledSurface,
    _params,
    _unit,
    _vector3,
    _warn_normals,
    plane_basis,
)
from sprayplan.surface.coverage import spacing_for_overlap
from sprayplan.types import Paths, Stroke

log = logging.getLogger(__name__)


# ------------------------------------------------------------------------------------------------ settings


@dataclass(frozen=True)
class RuledPathConfig:
    """How the passes over a ruled surface are laid out (the ``[path]`` table; see the module docstring).

    Attributes
    ----------
    spot_diameter_mm : float or None
        Paint spot diameter on the surface; required unless ``passes`` is given.
    overlap : float
        Overlap ratio of neighbouring spots in [0, 1) (seed 000's eq. 6); unused with ``passes``.
    passes : int or None
        Exactly this many passes, the outer ones on the surface's edges.
    standoff_mm : float
        Gun tip to surface along the normal.
    direction : {"rulings", "across"}
    step_mm : float or None
        Distance between the points of a pass; None: rulings: the two ends; across: the pass spacing.
    zigzag : bool
        Adjacent passes in opposite directions (True) or all the same way.
    gun_axis : (3,) float or None
        The gun held along this direction at every waypoint (seed 001's tables hold it straight down,
        ``(0, 0, -1)``, on a tilted surface); the strokes' ``normals`` are then ``-gun_axis`` (the gun's z is
        ``-normal``) and the gun tip stands ``standoff_mm`` back along it. None: the gun along each point's
        ``-normal``.
    """

    spot_diameter_mm: float | None = None
    overlap: float = 0.4
    passes: int | None = None
    standoff_mm: float = 0.0
    direction: str = "rulings"
    step_mm: float | None = None
    zigzag: bool = True
    gun_axis: tuple | None = None

    def __post_init__(self):
        if self.gun_axis is not None:
            axis = np.asarray(self.gun_axis, dtype=float).reshape(-1)
            if axis.shape != (3,) or not np.isfinite(axis).all() or not np.linalg.norm(axis) > 0:
                raise ConfigError(f"gun_axis must be three finite numbers, not all 0, got {self.gun_axis!r}")
            object.__setattr__(self, "gun_axis", tuple(float(v) for v in axis / np.linalg.norm(axis)))
        if self.spot_diameter_mm is None and self.passes is None:
            raise ConfigError("give spot_diameter_mm (with overlap) or passes")
        for name in ("spot_diameter_mm", "step_mm"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, got {value}")
        if not 0.0 <= self.overlap < 1.0:
            raise ConfigError(f"overlap must be in [0, 1), got {self.overlap}")
        if self.passes is not None and (
            isinstance(self.passes, bool) or int(self.passes) != self.passes or self.passes < 1
        ):
            raise ConfigError(f"passes must be a whole number >= 1, got {self.passes}")
        if self.passes is not None and self.passes > MAX_LAYERS:
            raise ConfigError(f"passes must be at most {MAX_LAYERS}, got {self.passes!r}")
        if self.step_mm is not None and self.step_mm < MIN_STEP_MM:
            raise ConfigError(f"step_mm must be a number >= {MIN_STEP_MM:g}, got {self.step_mm!r}")
        if not (math.isfinite(self.standoff_mm) and self.standoff_mm >= 0):
            raise ConfigError(f"standoff_mm must be a number >= 0, got {self.standoff_mm}")
        if self.direction not in DIRECTIONS:
            raise ConfigError(f"direction must be one of {', '.join(DIRECTIONS)}, got {self.direction!r}")

    @property
    def spacing_mm(self) -> float | None:
        """The pass spacing d from the spot and overlap (inverse of eq. 6), mm; None when ``passes`` is set."""
        if self.passes is not None:
            return None
        return spacing_for_overlap(self.overlap, self.spot_diameter_mm / 2.0)


@dataclass(frozen=True)
class RuledJob:
    """A ruled surface and the settings of its paths, as read from one TOML file."""

    surface: RuledSurface
    config: RuledPathConfig
    name: str = ""


# ------------------------------------------------------------------------------------------------ paths


def _pass_positions(extent_mm: float, closed: bool, config: RuledPathConfig) -> tuple[np.ndarray, float]:
    """Pass parameters in [0, 1] and their spacing in mm, over an extent measured in mm (module docstring)."""
    if config.passes is not None:
        n = int(config.passes)
        if closed:
            return np.arange(n) / n, extent_mm / n
        if n == 1:
            return np.array([0.5]), extent_mm
        return np.linspace(0.0, 1.0, n), extent_mm / (n - 1)
    d = config.spacing_mm
    check_work(
        extent_mm / d,
        MAX_LAYERS,
        "passes",
        "path.spot_diameter_mm",
        config.spot_diameter_mm,
        f"{extent_mm:.4g} mm across the passes, overlap {config.overlap:g}",
        f"use path.spot_diameter_mm >= {round_up(config.spot_diameter_mm * extent_mm / d / MAX_LAYERS)}",
    )
    if closed:
        n = max(1, math.ceil(extent_mm / d - 1e-9))
        return np.arange(n) / n, extent_mm / n
    n = math.floor(extent_mm / d + 1e-9) + 1
    margin = max(extent_mm - (n - 1) * d, 0.0) / 2.0
    return (margin + np.arange(n) * d) / extent_mm, d


def _count(length_mm: float, step_mm: float) -> int:
    return max(2, math.ceil(length_mm / step_mm - 1e-9) + 1)


def _with_breaks(t: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    lo, hi = min(t[0], t[-1]), max(t[0], t[-1])
    inner = breaks[(breaks > lo) & (breaks < hi)]
    out = np.unique(np.concatenate([t, inner]))
    return out if t[-1] >= t[0] else out[::-1]


def _polyline_length(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def _stroke(
    surface: RuledSurface, u, v, standoff: float, spray_on: bool, layer: int, counts: list, gun_axis=None
) -> Stroke:
    points = surface.evaluate(u, v)
    normals, no_normal, undecided = surface._normals(u, v)
    counts[0] += no_normal
    counts[1] += undecided
    if gun_axis is not None:
        normals = np.tile(-np.asarray(gun_axis, dtype=float), (len(points), 1))
    on_part = np.full(len(points), spray_on)
    return Stroke(points, normals, points + standoff * normals, spray_on, on_part, layer)


def ruled_paths(job: RuledJob) -> Paths:
    """Zig-zag spray passes over a ruled surface, with spray-off transfers between them.

    Parameters
    ----------
    job : RuledJob

    Returns
    -------
    Paths
        Strokes in execution order: pass 0, transfer, pass 1, ... Pass k has ``layer = k``; transfers have
        ``spray_on = False``, ``layer = -1``, ``on_part`` False. With ``zigzag = False`` every pass runs the same
        way (A to B, or u = 0 to 1). ``spacing_mm`` is the pass spacing along the longer boundary curve
        (rulings) or the longest ruling (across); for a single pass (``passes = 1``) that length itself.
    """
    surface, config = job.surface, job.config
    breaks = surface.breaks
    fine = _with_breaks(np.linspace(0.0, 1.0, 1025), breaks)
    if config.direction == "rulings":
        extent = max(surface.curve_a.length_mm, surface.curve_b.length_mm)
        positions, spacing = _pass_positions(extent, surface.closed, config)
    else:
        extent = float(surface.ruling_length(fine).max())
        positions, spacing = _pass_positions(extent, False, config)
    step = config.step_mm
    longest = max(surface.curve_a.length_mm, surface.curve_b.length_mm, float(surface.ruling_length(fine).max()))
    if step is not None or config.direction == "across":
        along = step or spacing
        check_work(
            len(positions) * longest / along,
            MAX_WAYPOINTS,
            "waypoints",
            "path.step_mm",
            along,
            f"{len(positions)} passes up to {longest:.4g} mm long",
            f"use path.step_mm >= {round_up(len(positions) * longest / MAX_WAYPOINTS)}",
        )
    params = []
    for k, p in enumerate(positions):
        if config.direction == "rulings":
            w = float(surface.ruling_length(p)[0])
            v = np.array([0.0, 1.0]) if step is None else np.linspace(0.0, 1.0, _count(w, step))
            u = np.full(len(v), p)
        else:
            length = _polyline_length(surface.evaluate(fine, p))
            u = _with_breaks(np.linspace(0.0, 1.0, _count(length, step or spacing)), breaks)
            v = np.full(len(u), p)
        if config.zigzag and k % 2 == 1:
            u, v = u[::-1], v[::-1]
        params.append((u, v))
    strokes, counts = [], [0, 0]
    for k, (u, v) in enumerate(params):
        if k > 0:
            (u0, v0), (u1, v1) = (params[k - 1][0][-1], params[k - 1][1][-1]), (u[0], v[0])
            t = np.linspace(0.0, 1.0, 65)
            length = _polyline_length(surface.evaluate(u0 + t * (u1 - u0), v0 + t * (v1 - v0)))
            t = np.linspace(0.0, 1.0, _count(length, step or spacing))
            if u1 != u0:
                t = _with_breaks(t, (breaks - u0) / (u1 - u0))
            strokes.append(
                _stroke(
                    surface,
                    u0 + t * (u1 - u0),
                    v0 + t * (v1 - v0),
                    config.standoff_mm,
                    False,
                    -1,
                    counts,
                    config.gun_axis,
                )
            )
        strokes.append(_stroke(surface, u, v, config.standoff_mm, True, k, counts, config.gun_axis))
    _warn_normals(*counts)
    log.info("ruled %s: %d passes (%s), spacing %.3f mm", job.name, len(params), config.direction, spacing)
    return Paths(tuple(strokes), config.standoff_mm, spacing, job.name)


def cartesian_table(paths: Paths) -> np.ndarray:
    """The gun tip positions of the spray passes in execution order (the seed's tables 4 and 5).

    Returns
    -------
    (m, 3) float, mm
        ``tcp`` of every spray stroke, concatenated (transfers left out); with standoff 0 the surface points.
    """
    rows = [stroke.tcp for stroke in paths.spray_strokes]
    return np.vstack(rows) if rows else np.zeros((0, 3))
