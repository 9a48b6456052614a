"""Boundary curves and ruled surfaces of seed 001 (the geometry behind ``paths.ruled``).

Curves are evaluated by normalised arc length u in [0, 1]: lines, arcs (by centre and angles or by three
points), circles, points (a cone or fan) and 2D/3D polylines. A ruled surface joins two of them,
``S(u, v) = (1 - v) A(u) + v B(u)``, with its normal oriented toward the gun.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from sprayplan.errors import ConfigError

log = logging.getLogger(__name__)

DIRECTIONS = ("rulings", "across")
_NO_BREAKS = np.zeros(0)


def _params(u) -> np.ndarray:
    """Parameters as a (n,) float array (a scalar gives n = 1)."""
    return np.atleast_1d(np.asarray(u, dtype=float)).reshape(-1)


def _vector3(value, name: str) -> np.ndarray:
    out = np.array(value, dtype=float).reshape(-1)
    if out.shape != (3,) or not np.all(np.isfinite(out)):
        raise ConfigError(f"{name} must be three finite numbers, got {value!r}")
    out.flags.writeable = False
    return out


def _unit(value, name: str) -> np.ndarray:
    vector = _vector3(value, name)
    norm = float(np.linalg.norm(vector))
    if norm == 0.0:
        raise ConfigError(f"{name} must not be the zero vector")
    out = vector / norm
    out.flags.writeable = False
    return out


def plane_basis(normal) -> tuple[np.ndarray, np.ndarray]:
    """The in-plane axes (e1, e2) of the plane with the unit ``normal``, right-handed: e1 x e2 = normal.

    e1 is world x projected onto the plane (world y when the normal is parallel to x).

    Parameters
    ----------
    normal : (3,) float
        Unit normal.

    Returns
    -------
    e1, e2 : (3,) float
    """
    normal = np.asarray(normal, dtype=float)
    ref = np.array([1.0, 0.0, 0.0])
    if np.linalg.norm(np.cross(normal, ref)) < 1e-12:
        ref = np.array([0.0, 1.0, 0.0])
    e1 = ref - np.dot(ref, normal) * normal
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(normal, e1)


# ------------------------------------------------------------------------------------------------ curves


@dataclass(frozen=True, eq=False)
class Line:
    """The segment from ``start`` to ``end``, (3,) float, mm."""

    start: np.ndarray
    end: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "start", _vector3(self.start, "start"))
        object.__setattr__(self, "end", _vector3(self.end, "end"))
        if self.length_mm == 0.0:
            raise ConfigError("a line's start and end must differ (use a point curve for a single point)")

    closed = False
    breaks = _NO_BREAKS

    @property
    def length_mm(self) -> float:
        return float(np.linalg.norm(self.end - self.start))

    def evaluate(self, u) -> np.ndarray:
        """Points at normalised arc lengths ``u`` ((n,) in [0, 1]): (n, 3) float, mm."""
        u = _params(u)
        return self.start + u[:, None] * (self.end - self.start)

    def derivative(self, u) -> np.ndarray:
        """d/du of :meth:`evaluate`: (n, 3) float, mm (its norm is the curve's length)."""
        return np.tile(self.end - self.start, (len(_params(u)), 1))


@dataclass(frozen=True, eq=False)
class Arc:
    """A circular arc; a full circle when ``|sweep_rad| = 2 pi``.

    Attributes
    ----------
    center : (3,) float, mm
    radius_mm : float
    normal : (3,) float
        The axis; angles run counter-clockwise about it (made unit).
    start_angle_rad : float
        From the axis e1 of :func:`plane_basis`.
    sweep_rad : float
        Signed: positive counter-clockwise about ``normal``; 0 < |sweep| <= 2 pi.
    """

    center: np.ndarray
    radius_mm: float
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    start_angle_rad: float = 0.0
    sweep_rad: float = 2.0 * math.pi

    def __post_init__(self):
        object.__setattr__(self, "center", _vector3(self.center, "center"))
        object.__setattr__(self, "normal", _unit(self.normal, "normal"))
        if not (math.isfinite(self.radius_mm) and self.radius_mm > 0):
            raise ConfigError(f"radius must be a positive number, got {self.radius_mm}")
        if not (math.isfinite(self.start_angle_rad) and math.isfinite(self.sweep_rad)):
            raise ConfigError("arc angles must be finite")
        if not 0.0 < abs(self.sweep_rad) <= 2.0 * math.pi + 1e-12:
            raise ConfigError(f"an arc's sweep must be in (0, 360] deg, got {math.degrees(self.sweep_rad):g}")
        object.__setattr__(self, "_basis", plane_basis(self.normal))

    @classmethod
    def through_points(cls, start, mid, end) -> Arc:
        """The arc from ``start`` through ``mid`` to ``end`` ((3,) float each, mm, not collinear)."""
        a, b, c = (_vector3(p, name) for p, name in ((start, "start"), (mid, "mid"), (end, "end")))
        ab, ac = b - a, c - a
        axis = np.cross(ab, ac)
        area2 = float(np.dot(axis, axis))
        if area2 <= 1e-18 * max(np.dot(ab, ab), np.dot(ac, ac)) ** 2:
            raise ConfigError("an arc's start, mid and end points must not be collinear")
        center = a + (np.dot(ac, ac) * np.cross(axis, ab) + np.dot(ab, ab) * np.cross(ac, axis)) / (2.0 * area2)
        normal = axis / math.sqrt(area2)  # a -> b -> c runs counter-clockwise about it
        e1, e2 = plane_basis(normal)
        angle_a = math.atan2(np.dot(a - center, e2), np.dot(a - center, e1))
        angle_c = math.atan2(np.dot(c - center, e2), np.dot(c - center, e1))
        sweep = (angle_c - angle_a) % (2.0 * math.pi)
        return cls(center, float(np.linalg.norm(a - center)), normal, angle_a, sweep)

    @property
    def closed(self) -> bool:
        return abs(abs(self.sweep_rad) - 2.0 * math.pi) < 1e-12

    breaks = _NO_BREAKS

    @property
    def length_mm(self) -> float:
        return self.radius_mm * abs(self.sweep_rad)

    def evaluate(self, u) -> np.ndarray:
        """Points at normalised arc lengths ``u`` ((n,) in [0, 1]): (n, 3) float, mm."""
        e1, e2 = self._basis
        t = self.start_angle_rad + _params(u) * self.sweep_rad
        return self.center + self.radius_mm * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)

    def derivative(self, u) -> np.ndarray:
        """d/du of :meth:`evaluate`: (n, 3) float, mm."""
        e1, e2 = self._basis
        t = self.start_angle_rad + _params(u) * self.sweep_rad
        return self.radius_mm * self.sweep_rad * (-np.sin(t)[:, None] * e1 + np.cos(t)[:, None] * e2)


@dataclass(frozen=True, eq=False)
class PointCurve:
    """A boundary shrunk to one point ``point`` ((3,) float, mm): the rulings form a fan or a cone."""

    point: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "point", _vector3(self.point, "point"))

    closed = True
    breaks = _NO_BREAKS
    length_mm = 0.0

    def evaluate(self, u) -> np.ndarray:
        """(n, 3) float, mm: the point, n times."""
        return np.tile(self.point, (len(_params(u)), 1))

    def derivative(self, u) -> np.ndarray:
        """(n, 3) zeros."""
        return np.zeros((len(_params(u)), 3))


@dataclass(frozen=True, eq=False)
class Polyline:
    """Straight segments through ``vertices`` ((k, 3) float, mm; repeated consecutive vertices are dropped)."""

    vertices: np.ndarray

    def __post_init__(self):
        vertices = np.array(self.vertices, dtype=float)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.all(np.isfinite(vertices)):
            raise ConfigError("polyline vertices must be a (k, 3) array of finite numbers")
        keep = np.ones(len(vertices), dtype=bool)
        keep[1:] = np.any(vertices[1:] != vertices[:-1], axis=1)
        vertices = vertices[keep]
        if len(vertices) < 2:
            raise ConfigError("a polyline needs at least two distinct points")
        cumulative = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(vertices, axis=0), axis=1))])
        vertices.flags.writeable = False
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "_length", float(cumulative[-1]))
        object.__setattr__(self, "_s", cumulative / cumulative[-1])

    @property
    def closed(self) -> bool:
        return bool(np.all(self.vertices[0] == self.vertices[-1]))

    @property
    def breaks(self) -> np.ndarray:
        """(k - 2,) float: the normalised arc lengths of the inner vertices (the corners)."""
        return self._s[1:-1]

    @property
    def length_mm(self) -> float:
        return self._length

    def evaluate(self, u) -> np.ndarray:
        """Points at normalised arc lengths ``u`` ((n,) in [0, 1]): (n, 3) float, mm."""
        u = _params(u)
        return np.stack([np.interp(u, self._s, self.vertices[:, i]) for i in range(3)], axis=1)

    def derivative(self, u) -> np.ndarray:
        """d/du of :meth:`evaluate`, (n, 3) float, mm; at a corner, that of the segment after it."""
        i = np.clip(np.searchsorted(self._s, _params(u), side="right") - 1, 0, len(self._s) - 2)
        return (self.vertices[i + 1] - self.vertices[i]) / (self._s[i + 1] - self._s[i])[:, None]


Curve = Line | Arc | PointCurve | Polyline


# ------------------------------------------------------------------------------------------------ surface


def _warn_normals(no_normal: int, undecided: int) -> None:
    if no_normal:
        log.warning("%d surface points have no normal (degenerate surface there): the gun side is used", no_normal)
    if undecided:
        log.warning(
            "%d normals are perpendicular to the gun side: their side is the parametrisation's "
            "(set gun_side or outward_from)",
            undecided,
        )


@dataclass(frozen=True, eq=False)
class RuledSurface:
    """S(u, v) = (1 - v) A(u) + v B(u), with unit normals turned toward the gun.

    Attributes
    ----------
    curve_a, curve_b : Curve
    gun_side : (3,) float
        The normals satisfy ``n . gun_side >= 0`` (made unit; default +z).
    outward_from : (3,) float, mm, or None
        When given, used instead of ``gun_side``: ``n . (S - outward_from) >= 0``.
    """

    curve_a: Curve
    curve_b: Curve
    gun_side: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    outward_from: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "gun_side", _unit(self.gun_side, "gun_side"))
        if self.outward_from is not None:
            object.__setattr__(self, "outward_from", _vector3(self.outward_from, "outward_from"))
        u = np.linspace(0.0, 1.0, 65)
        rulings = np.linalg.norm(self.curve_b.evaluate(u) - self.curve_a.evaluate(u), axis=1)
        scale = max(self.curve_a.length_mm, self.curve_b.length_mm, float(rulings.max()))
        object.__setattr__(self, "_tol", 1e-12 * scale * scale)
        uu, vv = np.meshgrid(u, [0.0, 0.5, 1.0])
        su, sv = self.tangents(uu.ravel(), vv.ravel())
        if scale == 0.0 or not np.any(np.linalg.norm(np.cross(su, sv), axis=1) > self._tol):
            raise ConfigError("the two curves span no surface (they coincide, or lie on one line)")
        a_ends, b_ends = self.curve_a.evaluate([0.0, 1.0]), self.curve_b.evaluate([0.0, 1.0])
        straight = np.linalg.norm(a_ends - b_ends, axis=1).sum()
        crossed = np.linalg.norm(a_ends - b_ends[::-1], axis=1).sum()
        if not self.closed and crossed < straight - 1e-9 * scale:
            log.warning("curves A and B run in opposite directions: the rulings cross (reverse one curve)")

    @property
    def closed(self) -> bool:
        """True when the surface closes on itself in u (both curves closed: a band, a cone)."""
        return bool(self.curve_a.closed and self.curve_b.closed)

    @property
    def breaks(self) -> np.ndarray:
        """Sorted u of the boundary curves' corners."""
        return np.unique(np.concatenate([self.curve_a.breaks, self.curve_b.breaks]))

    def evaluate(self, u, v) -> np.ndarray:
        """Surface points at parameters ``u``, ``v`` ((n,) each, in [0, 1]): (n, 3) float, mm."""
        u, v = np.broadcast_arrays(_params(u), _params(v))
        return (1.0 - v)[:, None] * self.curve_a.evaluate(u) + v[:, None] * self.curve_b.evaluate(u)

    def tangents(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """The partial derivatives dS/du and dS/dv: (n, 3) float each, mm."""
        u, v = np.broadcast_arrays(_params(u), _params(v))
        s_u = (1.0 - v)[:, None] * self.curve_a.derivative(u) + v[:, None] * self.curve_b.derivative(u)
        return s_u, self.curve_b.evaluate(u) - self.curve_a.evaluate(u)

    def ruling_length(self, u) -> np.ndarray:
        """(n,) float, mm: |B(u) - A(u)|."""
        return np.linalg.norm(self.curve_b.evaluate(u) - self.curve_a.evaluate(u), axis=1)

    def normals(self, u, v) -> np.ndarray:
        """Unit normals toward the gun at ``u``, ``v`` ((n,) each): (n, 3) float.

        Where dS/du x dS/dv vanishes, the normal is taken 1e-6 further inside the parameter square (v first,
        then u, then both); if it still vanishes, the gun side is used. Both cases, and normals perpendicular to
        the gun side, are logged as warnings.
        """
        normals, no_normal, undecided = self._normals(u, v)
        _warn_normals(no_normal, undecided)
        return normals

    def _normals(self, u, v) -> tuple[np.ndarray, int, int]:
        """:meth:`normals`, and the counts of points without a normal and of normals the gun side left open."""
        u, v = (np.array(a, dtype=float) for a in np.broadcast_arrays(_params(u), _params(v)))
        raw = np.cross(*self.tangents(u, v))
        h = 1e-6
        for du, dv in ((0.0, h), (h, 0.0), (h, h)):
            bad = np.linalg.norm(raw, axis=1) <= self._tol
            if not bad.any():
                break
            ub = u[bad] + du * np.where(u[bad] < 0.5, 1.0, -1.0)
            vb = v[bad] + dv * np.where(v[bad] < 0.5, 1.0, -1.0)
            raw[bad] = np.cross(*self.tangents(ub, vb))
        bad = np.linalg.norm(raw, axis=1) <= self._tol
        raw[bad] = self.gun_side
        normals = raw / np.linalg.norm(raw, axis=1)[:, None]
        if self.outward_from is None:
            toward = np.broadcast_to(self.gun_side, normals.shape)
        else:
            toward = self.evaluate(u, v) - self.outward_from
        dots = np.einsum("ij,ij->i", normals, toward)
        normals[dots < 0] *= -1.0
        undecided = np.abs(dots) <= 1e-9 * np.linalg.norm(toward, axis=1)
        return normals, int(bad.sum()), int(undecided.sum())

    def grid(self, n_u: int, n_v: int) -> tuple[np.ndarray, np.ndarray]:
        """Points and normals on a regular (u, v) grid: (n_u, n_v, 3) float each (mm, unit)."""
        uu, vv = np.meshgrid(np.linspace(0.0, 1.0, n_u), np.linspace(0.0, 1.0, n_v), indexing="ij")
        points = self.evaluate(uu.ravel(), vv.ravel()).reshape(n_u, n_v, 3)
        return points, self.normals(uu.ravel(), vv.ravel()).reshape(n_u, n_v, 3)
