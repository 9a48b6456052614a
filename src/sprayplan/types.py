"""The data that flows between stages, defined once.

Every stage is a function that takes and returns these small frozen dataclasses of numpy arrays. Arrays are
made read-only on construction, so a stage can never change its input in place.

Units: mm for lengths, rad for angles, s for time. Normals point out of the part.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _frozen(array, dtype, shape_tail: tuple[int, ...], name: str) -> np.ndarray:
    out = np.array(array, dtype=dtype, copy=True)
    if out.ndim != 1 + len(shape_tail) or out.shape[1:] != shape_tail:
        want = ", ".join(["n", *map(str, shape_tail)])
        raise ValueError(f"{name} must have shape ({want}), got {out.shape}")
    out.flags.writeable = False
    return out


def read_only(result) -> None:
    """Make every numpy array field of a frozen dataclass read-only (in place, without a copy): for the
    stage results that are built from arrays their stage owns (film, samples, tuning, joints)."""
    for name in getattr(result, "__dataclass_fields__", {}):
        value = getattr(result, name)
        if isinstance(value, np.ndarray):
            value.flags.writeable = False


def _check_part_arrays(vertices: np.ndarray, faces: np.ndarray, name: str) -> None:
    """A part's coordinates are finite and within ``checks.MAX_COORDINATE_MM`` of the origin, its faces index
    its vertices: anything else is a one-line ``DataError`` naming the part and the row (beyond 1e7 mm the
    products in normals and covariances overflow or lose every digit)."""
    from sprayplan.checks import MAX_COORDINATE_MM
    from sprayplan.errors import DataError

    who = f"{name}: " if name else ""
    if len(vertices):
        size = np.abs(vertices).max(axis=1)
        bad = ~(size <= MAX_COORDINATE_MM)  # NaN too
        if bad.any():
            row = int(np.argmax(bad))
            raise DataError(
                f"{who}vertex {row} is ({', '.join(f'{v:g}' for v in vertices[row])}) mm: coordinates must be finite"
                f" and within {MAX_COORDINATE_MM:g} mm of the origin (is the unit right?)"
            )
    if len(faces):
        bad = (faces < 0).any(axis=1) | (faces >= len(vertices)).any(axis=1)
        if bad.any():
            row = int(np.argmax(bad))
            raise DataError(
                f"{who}face {row} ({' '.join(map(str, faces[row]))}) refers to a vertex that does not exist"
                f" ({len(vertices)} vertices)"
            )


@dataclass(frozen=True)
class Part:
    """A part in the part frame, in mm, z up.

    Attributes
    ----------
    vertices : (n, 3) float, mm
        Mesh vertices, or the points of a point cloud.
    faces : (m, 3) int
        Triangles as indices into ``vertices``; ``(0, 3)`` for a point cloud.
    vertex_normals : (n, 3) float or None
        Unit normals given by the file (point clouds with normals); None when the file has none.
    name : str
        Where the part came from (a file name, or ``"demo:roof"``).
    oriented : bool
        The faces are wound outward already (``surface.normals.oriented_part``): the stages take the winding
        as it is (``surface.normals.part_outward``) instead of orienting the pieces again, so that a piece cut
        from the whole (a robot's share of a body) keeps the whole's orientation.
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_normals: np.ndarray | None = None
    name: str = ""
    oriented: bool = False

    def __post_init__(self):
        object.__setattr__(self, "vertices", _frozen(self.vertices, np.float64, (3,), "vertices"))
        faces = np.asarray(self.faces).reshape(-1, 3) if np.size(self.faces) == 0 else self.faces
        object.__setattr__(self, "faces", _frozen(faces, np.int64, (3,), "faces"))
        _check_part_arrays(self.vertices, self.faces, self.name)
        if self.vertex_normals is not None:
            normals = _frozen(self.vertex_normals, np.float64, (3,), "vertex_normals")
            if len(normals) != len(self.vertices):
                raise ValueError("vertex_normals must have one row per vertex")
            object.__setattr__(self, "vertex_normals", normals)

    @property
    def is_mesh(self) -> bool:
        """True when the part has triangles, False for a point cloud."""
        return len(self.faces) > 0

    @property
    def triangles(self) -> np.ndarray:
        """(m, 3, 3) float, mm: the vertex coordinates of each face."""
        return self.vertices[self.faces]

    @property
    def face_areas(self) -> np.ndarray:
        """(m,) float, mm^2."""
        tri = self.triangles
        return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)

    @property
    def area(self) -> float:
        """Total surface area in mm^2 (0 for a point cloud)."""
        return float(self.face_areas.sum()) if self.is_mesh else 0.0

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float, mm: the lower and upper corners of the axis-aligned bounding box."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])


@dataclass(frozen=True)
class Targets:
    """Target points on the surface with their outward normals.

    Attributes
    ----------
    points : (n, 3) float, mm
        Points on the part's surface.
    normals : (n, 3) float
        Unit normals pointing out of the part.
    face_index : (n,) int
        The face each point lies on; -1 for points that are mesh vertices or cloud points.
    """

    points: np.ndarray
    normals: np.ndarray
    face_index: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self):
        points = _frozen(self.points, np.float64, (3,), "points")
        normals = _frozen(self.normals, np.float64, (3,), "normals")
        if len(normals) != len(points):
            raise ValueError("points and normals must have the same length")
        index = np.full(len(points), -1) if self.face_index is None else self.face_index
        index = _frozen(np.asarray(index).reshape(-1), np.int64, (), "face_index")
        if len(index) != len(points):
            raise ValueError("face_index must have one entry per point")
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "normals", normals)
        object.__setattr__(self, "face_index", index)

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, index) -> Targets:
        """The targets selected by an index array or boolean mask, in that order."""
        return Targets(self.points[index], self.normals[index], self.face_index[index])


#: What a stroke is for (``Stroke.kind``).
STROKE_KINDS = ("spray", "transfer", "touch-up")

#: How a waypoint's joints were found (``StationPlan.method``): the closed-form IK, the SQP fallback, or not at
#: all (unreachable).
IK_METHODS = ("analytic", "sqp", "")

#: How the collision stage freed a waypoint of a stroke in place (``StationPlan.repair``).
WAYPOINT_REPAIRS = ("branch", "roll", "tilt", "platform")
#: How it re-routed a transfer (every waypoint of the new transfer carries the kind).
TRANSFER_REPAIRS = ("retract", "via", "detour")
#: Every value of ``StationPlan.repair``: a waypoint repair, a transfer route, or empty.
REPAIR_KINDS = WAYPOINT_REPAIRS + TRANSFER_REPAIRS + ("",)


@dataclass(frozen=True)
class Stroke:
    """One continuous move of the gun: a spray pass, or a spray-off transfer between passes.

    Attributes
    ----------
    points : (n, 3) float, mm
        Surface contact points: where the gun's axis meets the part (for transfers and lead-in/out, points
        on the extension of the surface).
    normals : (n, 3) float
        Unit outward normals at the points; the gun's z axis is ``-normals``.
    tcp : (n, 3) float, mm
        Gun tip positions, ``points + standoff * normals``.
    spray_on : bool
        True for a spray pass, False for a transfer move.
    on_part : (n,) bool
        True where the point lies on the part's surface (False on lead-in/lead-out extensions, on straight
        bridges across small gaps, and on transfers).
    layer : int
        The slicing layer (section plane) the stroke comes from; -1 for transfers, touch-ups and targets.
    dwell : (n,) float
        Time factor at each waypoint (all 1 unless the speeds were tuned to the film,
        ``sprayplan.refine.tuning``): the gun crosses the segment from waypoint i to i + 1 at the planned
        speed divided by ``(dwell[i] + dwell[i + 1]) / 2``, so 2 is half speed and twice the paint.
    kind : {"spray", "transfer", "touch-up"}
        What the stroke is for: a planned spray pass, a spray-off move between passes, or a spray pass added
        after planning to touch up a patch the film model finds under-painted (``sprayplan.refine``). Empty:
        ``spray`` or ``transfer`` after ``spray_on``. ``spray_on`` is False exactly for transfers.
    """

    points: np.ndarray
    normals: np.ndarray
    tcp: np.ndarray
    spray_on: bool = True
    on_part: np.ndarray = field(default=None)  # type: ignore[assignment]
    layer: int = -1
    dwell: np.ndarray = field(default=None)  # type: ignore[assignment]
    kind: str = ""

    def __post_init__(self):
        points = _frozen(self.points, np.float64, (3,), "points")
        normals = _frozen(self.normals, np.float64, (3,), "normals")
        tcp = _frozen(self.tcp, np.float64, (3,), "tcp")
        if not (len(points) == len(normals) == len(tcp)):
            raise ValueError("points, normals and tcp must have the same length")
        flags = np.ones(len(points), dtype=bool) if self.on_part is None else self.on_part
        flags = _frozen(np.asarray(flags).reshape(-1), bool, (), "on_part")
        if len(flags) != len(points):
            raise ValueError("on_part must have one entry per point")
        dwell = np.ones(len(points)) if self.dwell is None else self.dwell
        dwell = _frozen(np.asarray(dwell, dtype=float).reshape(-1), np.float64, (), "dwell")
        if len(dwell) != len(points):
            raise ValueError("dwell must have one entry per point")
        if not (np.isfinite(dwell).all() and (dwell > 0).all()):
            raise ValueError("dwell must be positive and finite")
        object.__setattr__(self, "dwell", dwell)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "normals", normals)
        object.__setattr__(self, "tcp", tcp)
        object.__setattr__(self, "on_part", flags)
        object.__setattr__(self, "spray_on", bool(self.spray_on))
        object.__setattr__(self, "layer", int(self.layer))
        kind = self.kind or ("spray" if self.spray_on else "transfer")
        if kind not in STROKE_KINDS:
            raise ValueError(f"kind must be one of {', '.join(STROKE_KINDS)}, got {kind!r}")
        if (kind == "transfer") == self.spray_on:
            raise ValueError(f"a {kind} stroke must have spray_on {kind != 'transfer'}")
        object.__setattr__(self, "kind", kind)

    def __len__(self) -> int:
        return len(self.points)

    @property
    def length_mm(self) -> float:
        """Length of the gun tip's path, mm."""
        return float(np.linalg.norm(np.diff(self.tcp, axis=0), axis=1).sum()) if len(self.tcp) > 1 else 0.0

    def reversed(self) -> Stroke:
        """The same stroke run the other way."""
        return Stroke(
            self.points[::-1],
            self.normals[::-1],
            self.tcp[::-1],
            self.spray_on,
            self.on_part[::-1],
            self.layer,
            self.dwell[::-1],
            self.kind,
        )

    def part(self, index) -> Stroke:
        """The waypoints selected by a slice or an index array, in that order (a stretch of the stroke)."""
        return Stroke(
            self.points[index],
            self.normals[index],
            self.tcp[index],
            self.spray_on,
            self.on_part[index],
            self.layer,
            self.dwell[index],
            self.kind,
        )

    def with_dwell(self, dwell) -> Stroke:
        """The same stroke with other time factors at its waypoints."""
        return Stroke(self.points, self.normals, self.tcp, self.spray_on, self.on_part, self.layer, dwell, self.kind)


@dataclass(frozen=True)
class Paths:
    """Strokes in execution order, spray passes and the transfers between them.

    Attributes
    ----------
    strokes : tuple of Stroke
    standoff_mm : float
        Gun tip to surface distance along the normal.
    spacing_mm : float
        Distance between adjacent spray passes.
    name : str
        The part the paths were planned on.
    """

    strokes: tuple
    standoff_mm: float
    spacing_mm: float
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "strokes", tuple(self.strokes))

    @property
    def spray_strokes(self) -> tuple:
        """The spray passes only, in order."""
        return tuple(s for s in self.strokes if s.spray_on)

    @property
    def spray_length_mm(self) -> float:
        """Total gun tip path length with the spray on, mm."""
        return float(sum(s.length_mm for s in self.strokes if s.spray_on))

    @property
    def transfer_length_mm(self) -> float:
        """Total gun tip path length with the spray off, mm."""
        return float(sum(s.length_mm for s in self.strokes if not s.spray_on))


@dataclass(frozen=True)
class StationPlan:
    """What the robot does from one gantry station: ordered strokes and the nine axes at every waypoint.

    Attributes
    ----------
    index : int
        The station's number in the cover (its position in the visiting order is its place in ``Plan``).
    platform_mm : (3,) float
        Gantry position.
    strokes : tuple of Stroke
        Spray passes and transfers, in execution order.
    q9 : (n, 9) float
        q1..q6 (rad) and tx, ty, tz (mm) for the n waypoints of all strokes in order.
    reachable : (n,) bool
    method : (n,) str
        ``analytic``, ``sqp`` or empty (unreachable).
    position_error_mm, axis_error_deg : (n,) float
        NaN where unreachable.
    branch_change : (n,) bool
    collision : (n,) bool
        The robot at this waypoint is closer to the part, the floor or the cell than allowed
        (``sprayplan.collision``; all False until the ``collision`` stage checks the plan).
    motion_collision : (n,) bool
        The motion into this waypoint from the previous checked one is in collision.
    collision_distance_mm : (n,) float
        The distance of the closest pair (exact within the check's margin of its gap, a lower bound beyond);
        NaN where not checked.
    collision_with : (n,) str
        That pair, ``"elbow/part"``; empty where not checked.
    repair : (n,) str
        How a waypoint found in collision, or the motion into it inside a spray stroke, was freed: ``branch``,
        ``roll``, ``tilt`` or ``platform`` (:data:`WAYPOINT_REPAIRS`); on a transfer the collision stage re-routed, the route's kind on each of its
        waypoints: ``retract``, ``via`` or ``detour`` (:data:`TRANSFER_REPAIRS`); empty where nothing was
        repaired.
    """

    index: int
    platform_mm: np.ndarray
    strokes: tuple
    q9: np.ndarray
    reachable: np.ndarray
    method: np.ndarray
    position_error_mm: np.ndarray
    axis_error_deg: np.ndarray
    branch_change: np.ndarray
    collision: np.ndarray = None  # type: ignore[assignment]
    motion_collision: np.ndarray = None  # type: ignore[assignment]
    collision_distance_mm: np.ndarray = None  # type: ignore[assignment]
    collision_with: np.ndarray = None  # type: ignore[assignment]
    repair: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self):
        object.__setattr__(self, "index", int(self.index))
        platform = np.array(self.platform_mm, dtype=np.float64, copy=True).reshape(-1)
        if platform.shape != (3,) or not np.isfinite(platform).all():
            raise ValueError(f"platform_mm must be three finite numbers, got {self.platform_mm!r}")
        platform.flags.writeable = False
        object.__setattr__(self, "platform_mm", platform)
        strokes = tuple(self.strokes)
        if not all(isinstance(s, Stroke) for s in strokes):
            raise ValueError("strokes must be Stroke objects")
        object.__setattr__(self, "strokes", strokes)
        n = sum(len(s) for s in strokes)
        object.__setattr__(self, "q9", _frozen(np.asarray(self.q9, dtype=float).reshape(-1, 9), np.float64, (9,), "q9"))
        if len(self.q9) != n:
            raise ValueError(f"q9 must have one row per waypoint ({n}), got {len(self.q9)}")
        method = np.asarray(self.method, dtype=object).reshape(-1)
        if len(method) != n:
            raise ValueError(f"method must have one entry per waypoint ({n}), got {len(method)}")
        bad = sorted({str(m) for m in method} - set(IK_METHODS))
        if bad:
            raise ValueError(f"method must be one of analytic, sqp or empty, got {', '.join(map(repr, bad))}")
        method = np.array([str(m) for m in method], dtype=object)
        method.flags.writeable = False
        object.__setattr__(self, "method", method)
        for name, dtype in (
            ("reachable", bool),
            ("position_error_mm", np.float64),
            ("axis_error_deg", np.float64),
            ("branch_change", bool),
        ):
            value = _frozen(np.asarray(getattr(self, name)).reshape(-1), dtype, (), name)
            if len(value) != n:
                raise ValueError(f"{name} must have one entry per waypoint ({n}), got {len(value)}")
            object.__setattr__(self, name, value)
        if (self.reachable != (method != "")).any():
            raise ValueError("a waypoint is reachable exactly when it has a method (analytic or sqp)")
        defaults = {
            "collision": (False, bool),
            "motion_collision": (False, bool),
            "collision_distance_mm": (np.nan, np.float64),
        }
        for name, (empty, dtype) in defaults.items():
            value = getattr(self, name)
            value = np.full(n, empty, dtype=dtype) if value is None else np.asarray(value).reshape(-1)
            value = _frozen(value, dtype, (), name)
            if len(value) != n:
                raise ValueError(f"{name} must have one entry per waypoint ({n}), got {len(value)}")
            object.__setattr__(self, name, value)
        for name in ("collision_with", "repair"):
            value = getattr(self, name)
            value = np.full(n, "", dtype=object) if value is None else np.asarray(value, dtype=object).reshape(-1)
            if len(value) != n:
                raise ValueError(f"{name} must have one entry per waypoint ({n}), got {len(value)}")
            value = np.array([str(v) for v in value], dtype=object)
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        bad = sorted(set(self.repair) - set(REPAIR_KINDS))
        if bad:
            raise ValueError(f"repair must be one of {', '.join(REPAIR_KINDS[:-1])} or empty, got {bad[0]!r}")

    def __len__(self) -> int:
        return len(self.q9)


@dataclass(frozen=True)
class Plan:
    """A whole spray program: stations in visiting order, and what no station could take.

    Attributes
    ----------
    stations : tuple of StationPlan
        In visiting order (the gantry starts and ends at ``home_mm``).
    home_mm : (3,) float
    unassigned : (k, 3) float
        Contact points no station reaches (reported, not painted).
    name : str
    """

    stations: tuple
    home_mm: np.ndarray
    unassigned: np.ndarray
    name: str = ""

    def __post_init__(self):
        stations = tuple(self.stations)
        if not all(isinstance(st, StationPlan) for st in stations):
            raise ValueError("stations must be StationPlan objects")
        object.__setattr__(self, "stations", stations)
        home = np.array(self.home_mm, dtype=np.float64, copy=True).reshape(-1)
        if home.shape != (3,) or not np.isfinite(home).all():
            raise ValueError(f"home_mm must be three finite numbers, got {self.home_mm!r}")
        home.flags.writeable = False
        object.__setattr__(self, "home_mm", home)
        unassigned = np.asarray(self.unassigned, dtype=float).reshape(-1, 3)
        object.__setattr__(self, "unassigned", _frozen(unassigned, np.float64, (3,), "unassigned"))
        object.__setattr__(self, "name", str(self.name))

    @property
    def strokes(self) -> tuple:
        """Every stroke, station after station, in execution order."""
        return tuple(s for st in self.stations for s in st.strokes)
