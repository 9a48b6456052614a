"""The collision model of the nine-axis cell, built once per plan: :class:`CellCollision`.

Bodies (sizes and sources in :mod:`sprayplan.collision.bodies`): the arm's eight link capsules and the gun's
capsule along the D-H chain, the gantry's carriage and column (boxes), the part (a BVH of its triangles,
OBB-RSS; for a point cloud, a ball about every point, :mod:`~sprayplan.collision.spheres`) and the floor (a
half-space ``z <= floor_z``). Distances come from ``coal`` (the Coal library, formerly HPP-FCL; the choice
against python-fcl is measured in docs/benchmarks.md and recorded in docs/ARCHITECTURE.md), a cloud's in
closed form. A distance is signed: negative where two bodies overlap (coal's penetration estimate;
only its sign is relied on).

Pairs tested and the gap each must keep (``required_mm``):

- the part against every link, the gun, the carriage and the column: ``clearance_mm``;
- the floor against the same bodies: 0 (no body below the floor), and the TCP (the nozzle) not below it;
- the carriage and the column against the forearm, the wrists and the gun, and the gun against the base, the
  shoulder, the upper arm, the elbow and the forearm: 0 (contact). Neighbouring links, which touch at their
  joints by construction, are not tested against each other.

The spray cone in front of the nozzle is free space: the gun's capsule ends at the nozzle's plane, and the
part is tested only against bodies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.collision.bodies import CapsuleBody, GantryBodies, gun_capsule, link_bodies, reach_radii_mm
from sprayplan.collision.broadphase import (
    capsules_to_surface,
    point_box_distance,
    segment_points,
    segments_gap,
    surface_samples,
)
from sprayplan.collision.motion import motion_bound_mm, motion_checks
from sprayplan.collision.settings import CollisionConfig
from sprayplan.collision.spheres import SphereSet, boxes_to_spheres, capsules_to_spheres, cloud_radius_mm, cloud_samples
from sprayplan.errors import ConfigError, DataError
from sprayplan.robots.gantry import Gantry
from sprayplan.robots.model import dh_transforms
from sprayplan.types import Part, Plan, read_only

try:  # pragma: no cover - the import is the dependency's presence
    import coal
except ImportError:  # pragma: no cover
    coal = None

#: The cell bodies tested against the part and the floor besides the arm's links and the gun.
GANTRY_NAMES = ("carriage", "column")
#: Arm bodies the gantry's boxes are tested against.
NEAR_GANTRY = ("forearm", "wrist_1", "wrist_2", "wrist_3", "gun")
#: Arm bodies the gun is tested against (not its neighbours wrist_2 and wrist_3, nor wrist_1).
NEAR_GUN = ("base", "shoulder", "upper_arm", "elbow", "forearm")


def _require_coal():
    if coal is None:  # pragma: no cover
        raise ImportError("collision checks need the 'coal' package: pip install 'sprayplan[collision]' (or coal)")


def capsule_local_pose(body: CapsuleBody) -> np.ndarray:
    """(4, 4): the pose in its D-H frame of a capsule whose axis is z and whose centre is the origin."""
    p0, p1 = np.asarray(body.p0, float), np.asarray(body.p1, float)
    out = np.eye(4)
    out[:3, 3] = (p0 + p1) / 2.0
    length = np.linalg.norm(p1 - p0)
    if length > 0:
        z = (p1 - p0) / length
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        out[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return out


@dataclass(frozen=True)
class BodyDistances:
    """Distances of every tested body pair at n joint vectors.

    Attributes
    ----------
    distance_mm : (n, p) float
        Signed distance of each pair (negative: overlapping); for ``("tcp", "floor")`` the nozzle's height
        above the floor.
    pairs : tuple of p (str, str)
        The bodies of each column.
    required_mm : (p,) float
        The gap each pair must keep.
    """

    distance_mm: np.ndarray
    pairs: tuple
    required_mm: np.ndarray

    def __post_init__(self):
        read_only(self)

    @property
    def slack_mm(self) -> np.ndarray:
        """(n, p): distance minus the required gap (negative: in collision)."""
        return self.distance_mm - self.required_mm

    def worst(self) -> tuple[np.ndarray, np.ndarray]:
        """Per row, the pair with the least slack: its column index (n,) and its distance (n,) mm."""
        column = np.argmin(self.slack_mm, axis=1)
        return column, self.distance_mm[np.arange(len(column)), column]


@dataclass(frozen=True)
class ConfigChecks:
    """The least slack of n joint vectors over every pair, exact where it matters (:meth:`CellCollision.check`).

    Attributes
    ----------
    in_collision : (n,) bool
        Some pair is closer than its required gap (decided by coal's exact distance, never by a bound).
    column : (n,) int
        The pair (an index into ``CellCollision.pairs``) with the least slack.
    distance_mm : (n,) float
        That pair's distance: exact where ``exact``, else a lower bound.
    slack_mm : (n,) float
        ``distance_mm`` minus the pair's required gap (a lower bound where not exact).
    exact : (n,) bool
        The distance is coal's (or the floor's, which is exact by construction); pairs whose lower bound
        leaves more than ``margin_mm`` over their gap are not queried.
    part_distance_mm : (n,) float
        The least distance of any link, the gun, the carriage or the column to the part (a lower bound where
        ``part_exact`` is False).
    part_exact : (n,) bool
    """

    in_collision: np.ndarray
    column: np.ndarray
    distance_mm: np.ndarray
    slack_mm: np.ndarray
    exact: np.ndarray
    part_distance_mm: np.ndarray
    part_exact: np.ndarray

    def __post_init__(self):
        read_only(self)


@dataclass(frozen=True)
class WaypointCollisions:
    """Every waypoint of a plan checked, stations in visiting order, waypoints in order within each.

    Attributes
    ----------
    station : (n,) int
        The station's position in the plan.
    checked : (n,) bool
        The waypoint is reachable and was checked (unreachable ones have no joints to check).
    in_collision : (n,) bool
        Some pair is closer than its required gap (the part: the clearance; the floor and the cell: 0).
    distance_mm : (n,) float
        The distance of the pair with the least slack (NaN where not checked): exact within
        ``CellCollision.MARGIN_MM`` of its gap, a lower bound beyond (:meth:`CellCollision.check`).
    body_a, body_b : (n,) str
        That pair's bodies (``""`` where not checked).
    part_distance_mm : (n,) float
        The smallest distance from any link, the gun, the carriage or the column to the part (exact within
        the margin of the clearance, a lower bound beyond).
    clearance_mm : float
        The clearance the part pairs were checked with.
    """

    station: np.ndarray
    checked: np.ndarray
    in_collision: np.ndarray
    distance_mm: np.ndarray
    body_a: np.ndarray
    body_b: np.ndarray
    part_distance_mm: np.ndarray
    clearance_mm: float

    def __post_init__(self):
        read_only(self)

    def __len__(self) -> int:
        return len(self.station)

    @property
    def count(self) -> int:
        """How many waypoints are in collision."""
        return int(self.in_collision.sum())


@dataclass(frozen=True)
class MotionCollisions:
    """The motions between consecutive waypoints of a plan checked (``sprayplan.collision.motion``).

    A motion joins two consecutive checked waypoints of one station, or the last checked waypoint of a
    station to the first of the next (the station move). Waypoint indices count all waypoints of the plan,
    stations in visiting order, as in :class:`WaypointCollisions`.

    Attributes
    ----------
    start, end : (m,) int
        The waypoints the motion joins.
    checks : (m,) int
        Joint vectors checked along it (its start always; its end unless a check before it was in collision).
    in_collision : (m,) bool
        Some check has a pair closer than ``max(gap, step_mm / 2)``.
    distance_mm : (m,) float
        The distance of the pair with the least slack over the motion's checks.
    body_a, body_b : (m,) str
    step_mm : float
        ``collision.motion_step_mm``: near a body no point moves more than this between two checks; where the
        distances leave room, checks are further apart (conservative advancement, ``collision.motion``).
    """

    start: np.ndarray
    end: np.ndarray
    checks: np.ndarray
    in_collision: np.ndarray
    distance_mm: np.ndarray
    body_a: np.ndarray
    body_b: np.ndarray
    step_mm: float

    def __post_init__(self):
        read_only(self)

    def __len__(self) -> int:
        return len(self.start)

    @property
    def count(self) -> int:
        """How many motions are in collision."""
        return int(self.in_collision.sum())


def _joint_vectors(q9) -> np.ndarray:
    q9 = np.asarray(q9, dtype=float)
    if q9.ndim == 1:
        q9 = q9[None]
    if q9.ndim != 2 or q9.shape[1] != 9 or not np.isfinite(q9).all():
        raise DataError(f"q9 must be finite joint vectors of shape (9,) or (n, 9), got shape {np.shape(q9)}")
    return q9


class CellCollision:
    """The cell's bodies for one plan: distances at joint vectors, checks of waypoints and motions.

    Parameters
    ----------
    gantry : Gantry
        The nine-axis robot (its arm's link sizes from :data:`~sprayplan.collision.bodies.UR_LINK_SIZES`).
    part : Part
        A mesh (a BVH of its triangles) or a point cloud (a ball about every point, of radius
        ``config.cloud_radius_mm`` or from the cloud's spacing: :mod:`~sprayplan.collision.spheres`).
    config : CollisionConfig
    gantry_bodies : GantryBodies

    Raises
    ------
    ConfigError
        A robot without link sizes; a gun radius too large for the gun; ``collision.floor_z_mm`` above the
        part's lowest point.
    DataError
        A point cloud of fewer than two distinct points.
    """

    def __init__(
        self,
        gantry: Gantry,
        part: Part,
        config: CollisionConfig | None = None,
        gantry_bodies: GantryBodies | None = None,
    ):
        _require_coal()
        config = CollisionConfig() if config is None else config
        lowest = float(part.bounds[0, 2])
        if config.floor_z_mm is None:
            floor_z = lowest - config.floor_offset_mm
        elif config.floor_z_mm > lowest:
            raise ConfigError(
                f"collision.floor_z_mm must not be above the part's lowest point ({lowest:g} mm), got {config.floor_z_mm:g}"
            )
        else:
            floor_z = config.floor_z_mm
        self.gantry = gantry
        self.config = config
        self.floor_z_mm = floor_z
        self.gantry_bodies = GantryBodies() if gantry_bodies is None else gantry_bodies
        self.capsules = link_bodies(gantry.robot) + (gun_capsule(gantry.gun, config.gun_radius_mm),)
        self._local = np.stack([capsule_local_pose(b) for b in self.capsules])
        self._frames = np.array([b.frame for b in self.capsules])
        box_sizes = (self.gantry_bodies.carriage_mm, self.gantry_bodies.column_mm)
        self._box_heights = np.array([self.gantry_bodies.centres_above_mount()[n] for n in GANTRY_NAMES])
        self.body_names = tuple(b.name for b in self.capsules) + GANTRY_NAMES
        geometries = [coal.Capsule(b.radius_mm, b.length_mm) for b in self.capsules]
        geometries += [coal.Box(*size) for size in box_sizes]
        vertices = np.ascontiguousarray(part.vertices, dtype=float)
        faces = np.ascontiguousarray(part.faces, dtype=np.int64)
        self._part_vertices, self._part_faces = vertices, faces
        #: The point cloud's balls (:mod:`~sprayplan.collision.spheres`), None for a mesh.
        self.spheres = None
        if part.is_mesh:
            self._mesh = coal.BVHModelOBBRSS()
            self._mesh.beginModel(len(faces), len(vertices))
            self._mesh.addVertices(vertices)
            self._mesh.addTriangles(faces)
            self._mesh.endModel()
        else:
            radius = cloud_radius_mm(vertices) if config.cloud_radius_mm is None else config.cloud_radius_mm
            self.spheres = SphereSet.of(vertices, radius)
            self._mesh = None
        self._floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), floor_z)
        self._geometries = geometries
        index = {name: i for i, name in enumerate(self.body_names)}
        pairs, required, other = [], [], []
        for i, name in enumerate(self.body_names):
            pairs.append((name, "part"))
            required.append(config.clearance_mm)
            other.append(("part", i))
        for i, name in enumerate(self.body_names):
            pairs.append((name, "floor"))
            required.append(0.0)
            other.append(("floor", i))
        for box in GANTRY_NAMES:
            for name in NEAR_GANTRY:
                pairs.append((name, box))
                required.append(0.0)
                other.append((index[box], index[name]))
        for name in NEAR_GUN:
            pairs.append(("gun", name))
            required.append(0.0)
            other.append((index[name], index["gun"]))
        pairs.append(("tcp", "floor"))
        required.append(0.0)
        self.reach_radii_mm = reach_radii_mm(gantry.robot, self.capsules)
        self.pairs = tuple(pairs)
        self.required_mm = np.array(required)
        self.required_mm.flags.writeable = False
        self._tests = tuple(other)  # per pair but the last: (static or body index, body index)
        self._request = coal.DistanceRequest()
        self._static = {
            "part": (self._mesh, coal.Transform3s()),  # a mesh's; a cloud's part pairs never reach coal
            "floor": (self._floor, coal.Transform3s()),
        }
        self._samples = None  # the part's surface samples for the lower bounds, made on first use
        self._radii = np.array([b.radius_mm for b in self.capsules])
        self._box_half = np.array(box_sizes, dtype=float) / 2.0

    # -------------------------------------------------------------------------------------- body poses

    def frames(self, q9) -> np.ndarray:
        """(n, 7, 4, 4): the arm's D-H frames 0..6 in the world (frame 0 the base, 6 the flange)."""
        q9 = np.atleast_2d(np.asarray(q9, dtype=float))
        links = dh_transforms(self.gantry.robot, q9[:, :6])
        out = np.empty((len(q9), 7, 4, 4))
        out[:, 0] = self.gantry.base2world(q9[:, 6:9])
        for i in range(6):
            out[:, i + 1] = out[:, i] @ links[:, i]
        return out

    def body_poses(self, q9) -> np.ndarray:
        """(n, b, 4, 4): the world pose of every body of :attr:`body_names` (a capsule's centre, its axis z;
        a box's centre, axis-aligned)."""
        q9 = np.atleast_2d(np.asarray(q9, dtype=float))
        frames = self.frames(q9)
        capsules = frames[:, self._frames] @ self._local
        boxes = np.broadcast_to(np.eye(4), (len(q9), len(GANTRY_NAMES), 4, 4)).copy()
        boxes[:, :, :3, 3] = q9[:, None, 6:9]
        boxes[:, :, 2, 3] += self._box_heights
        return np.concatenate([capsules, boxes], axis=1)

    def capsule_segments(self, q9) -> np.ndarray:
        """(n, c, 2, 3) mm: the world end points of every capsule's segment (links and gun)."""
        q9 = np.atleast_2d(np.asarray(q9, dtype=float))
        frames = self.frames(q9)[:, self._frames]
        ends = np.stack(
            [np.column_stack([np.array([b.p0, b.p1], float), np.ones(2)]) for b in self.capsules]
        )  # (c, 2, 4)
        return np.einsum("ncij,ckj->ncki", frames, ends)[..., :3]

    def tcp(self, q9) -> np.ndarray:
        """(n, 3) mm: the nozzle (TCP) in the world."""
        return self.gantry.gun2world(np.atleast_2d(np.asarray(q9, dtype=float)))[:, :3, 3]

    # -------------------------------------------------------------------------------------- distances

    def distances(self, q9) -> BodyDistances:
        """Signed distances of every pair of :attr:`pairs` at joint vectors ``q9`` (9,) or (n, 9).

        Raises
        ------
        DataError
            Joint vectors of the wrong shape or not finite.
        """
        q9 = _joint_vectors(q9)
        tcp_z = self.tcp(q9)[:, 2]
        out = np.empty((len(q9), len(self.pairs)))
        rows, columns = np.divmod(np.arange(len(q9) * len(self._tests)), len(self._tests))
        out[rows, columns] = self._exact(q9, rows, columns)
        out[:, -1] = tcp_z - self.floor_z_mm
        return BodyDistances(out, self.pairs, self.required_mm)

    #: Pairs whose lower bound leaves at least this much over their gap are not queried exactly, mm.
    MARGIN_MM = 20.0
    #: Points along a capsule for the lower bounds are at most this far apart, mm.
    SPACING_MM = 20.0
    #: The part's surface samples cover it to this radius, mm.
    COVER_MM = 8.0
    #: Joint vectors bounded at once (memory of the lower bounds).
    CHUNK = 2048

    def samples(self):
        """The part's :class:`~sprayplan.collision.broadphase.SurfaceSamples` (made once)."""
        if self._samples is None and self.spheres is not None:
            self._samples = cloud_samples(self.spheres)
        elif self._samples is None:
            vertices = np.asarray(self._part_vertices)
            self._samples = surface_samples(Part(vertices, self._part_faces), self.COVER_MM)
        return self._samples

    def check(self, q9, clearance_mm: float | None = None, margin_mm: float | None = None) -> ConfigChecks:
        """The least slack over every pair at joint vectors ``q9`` (9,) or (n, 9), coal queried only for the
        pairs whose lower bound (:mod:`~sprayplan.collision.broadphase`) leaves less than ``margin_mm`` over
        their gap. Gives the same ``in_collision`` as :meth:`distances` (tested), far faster.

        Raises
        ------
        DataError
            Joint vectors of the wrong shape or not finite.
        """
        q9 = _joint_vectors(q9)
        clearance = self._clearance(clearance_mm, motion=False)
        margin = self.MARGIN_MM if margin_mm is None else float(margin_mm)
        required = self._required(clearance)
        parts = [self._check_chunk(q9[i : i + self.CHUNK], required, margin) for i in range(0, len(q9), self.CHUNK)]
        if not parts:
            parts = [self._check_chunk(np.zeros((0, 9)), required, margin)]
        fields = [np.concatenate(f) for f in zip(*parts)]
        return ConfigChecks(*fields)

    def collides(self, q9, clearance_mm: float | None = None, extra_mm: float = 0.0) -> np.ndarray:
        """(n,) bool: at joint vectors ``q9`` (9,) or (n, 9), some pair is closer than its gap plus ``extra_mm``;
        the same answer as ``check(q9).in_collision`` (for ``extra_mm`` 0) at a fraction of the exact queries.

        Only the pairs whose lower bound is below their gap are measured, and a row's pairs are measured in
        rounds, the least bound first, until one is in collision or none is left: a row's answer needs one pair
        in collision, or every near pair clear.

        Raises
        ------
        DataError
            Joint vectors of the wrong shape or not finite.
        """
        q9 = _joint_vectors(q9)
        required = self._required(self._clearance(clearance_mm, motion=False)) + float(extra_mm)
        out = np.zeros(len(q9), bool)
        for start in range(0, len(q9), self.CHUNK):
            chunk = q9[start : start + self.CHUNK]
            bound, exact = self._bounds(chunk, float(required.max()))
            slack = bound - required
            hit = (exact & (slack < 0)).any(axis=1)
            open_ = ~exact & (slack < 0)
            open_[hit] = False
            order = np.argsort(np.where(open_, slack, np.inf), axis=1)  # each row's near pairs, least bound first
            for k in range(open_.sum(axis=1).max(initial=0)):
                columns = order[:, k]
                rows = np.flatnonzero(~hit & open_[np.arange(len(chunk)), columns])
                if not len(rows):
                    break
                distance = self._exact(chunk, rows, columns[rows])
                hit[rows[distance - required[columns[rows]] < 0]] = True
            out[start : start + len(chunk)] = hit
        return out

    def _bounds(self, q9: np.ndarray, upper_mm: float) -> tuple[np.ndarray, np.ndarray]:
        """(n, p) lower bounds on every pair's distance and (n, p) which of them are exact."""
        n, c = len(q9), len(self.capsules)
        segments = self.capsule_segments(q9)  # (n, c, 2, 3)
        radii = self._radii
        boxes = q9[:, None, 6:9] + np.array([[0.0, 0.0, h] for h in self._box_heights])[None]  # (n, 2, 3) centres
        bound = np.full((n, len(self.pairs)), np.inf)
        exact = np.zeros((n, len(self.pairs)), dtype=bool)
        samples = self.samples()
        centres = segments.mean(axis=2)  # (n, c, 3)
        reach = np.linalg.norm(segments[:, :, 1] - segments[:, :, 0], axis=2) / 2.0 + radii  # (n, c)

        for column, (a, b) in enumerate(self._tests):
            if a == "floor":
                if b < c:
                    bound[:, column] = segments[:, b, :, 2].min(axis=1) - radii[b] - self.floor_z_mm
                else:
                    box = b - c
                    bound[:, column] = boxes[:, box, 2] - self._box_half[box, 2] - self.floor_z_mm
                exact[:, column] = True
            elif a == "part":
                if b < c:
                    ends, radius = segments[:, b], float(radii[b])
                else:  # a box: inside the capsule along its vertical axis with its cross-section's half-diagonal
                    box = b - c
                    half = self._box_half[box]
                    ends = np.stack([boxes[:, box] - [0, 0, half[2]], boxes[:, box] + [0, 0, half[2]]], axis=1)
                    radius = float(np.hypot(half[0], half[1]))
                bound[:, column] = capsules_to_surface(samples, ends, radius, upper_mm, self.SPACING_MM, b >= c)
            elif b < c and a >= c:  # an arm body against a gantry box: its bounding sphere, then its points
                box = a - c
                coarse = point_box_distance(centres[:, b], boxes[:, box], self._box_half[box]) - reach[:, b]
                bound[:, column] = coarse
                rows = np.flatnonzero(coarse < upper_mm)
                if len(rows):
                    pts, half = segment_points(segments[rows, b], self.SPACING_MM)
                    distance = point_box_distance(pts, boxes[rows, box, None, :], self._box_half[box]).min(axis=1)
                    bound[rows, column] = np.maximum(coarse[rows], distance - half - radii[b])
            else:  # the gun (b) against a link (a): bounding spheres, then points
                coarse = np.linalg.norm(centres[:, a] - centres[:, b], axis=1) - reach[:, a] - reach[:, b]
                bound[:, column] = coarse
                rows = np.flatnonzero(coarse < upper_mm)
                if len(rows):
                    pts_a, half_a = segment_points(segments[rows, a], self.SPACING_MM)
                    pts_b, half_b = segment_points(segments[rows, b], self.SPACING_MM)
                    fine = segments_gap(pts_a, pts_b) - half_a - half_b - radii[a] - radii[b]
                    bound[rows, column] = np.maximum(coarse[rows], fine)
        bound[:, -1] = self.tcp(q9)[:, 2] - self.floor_z_mm
        exact[:, -1] = True
        return bound, exact

    def _exact(self, q9: np.ndarray, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """(k,) the signed distances of pairs ``columns`` (indices into :attr:`pairs`, not the TCP's) at joint
        vectors ``q9[rows]``: coal's, or for a cloud's part pairs the balls' closed form."""
        out = np.empty(len(rows))
        poses = self.body_poses(q9[np.unique(rows)]) if len(rows) else None
        pose_row = np.searchsorted(np.unique(rows), rows)
        c = len(self.capsules)
        todo = np.ones(len(rows), bool)
        if self.spheres is not None:
            other = np.array([b for _, b in self._tests])[columns]
            part = np.array([a == "part" for a, _ in self._tests])[columns]
            capsule = np.flatnonzero(part & (other < c))
            if len(capsule):
                segments = self.capsule_segments(q9[rows[capsule]])[np.arange(len(capsule)), other[capsule]]
                out[capsule] = capsules_to_spheres(self.spheres, segments, self._radii[other[capsule]])
            box = np.flatnonzero(part & (other >= c))
            if len(box):
                centres = poses[pose_row[box], other[box], :3, 3]
                out[box] = boxes_to_spheres(self.spheres, centres, self._box_half[other[box] - c])
            todo[part] = False
        geometries, static, request = self._geometries, self._static, self._request
        for i in np.flatnonzero(todo):
            a, b = self._tests[columns[i]]
            pose_b = poses[pose_row[i], b]
            if isinstance(a, str):
                geometry, transform = static[a]
            else:
                pose_a = poses[pose_row[i], a]
                geometry, transform = geometries[a], coal.Transform3s(pose_a[:3, :3], pose_a[:3, 3])
            result = coal.DistanceResult()
            out[i] = coal.distance(
                geometries[b], coal.Transform3s(pose_b[:3, :3], pose_b[:3, 3]), geometry, transform, request, result
            )
        return out

    def _check_chunk(self, q9: np.ndarray, required: np.ndarray, margin: float):
        n = len(q9)
        upper = float(required.max()) + margin
        bound, exact = self._bounds(q9, upper)
        rows, columns = np.nonzero(~exact & (bound - required < margin))
        if len(rows):
            bound[rows, columns] = self._exact(q9, rows, columns)
            exact[rows, columns] = True
        slack = bound - required
        column = np.argmin(slack, axis=1) if n else np.zeros(0, int)
        rows = np.arange(n)
        part_columns = np.array([i for i, (_, b) in enumerate(self.pairs) if b == "part"])
        part = bound[:, part_columns]
        part_best = np.argmin(part, axis=1) if n else np.zeros(0, int)
        return (
            slack[rows, column] < 0,
            column,
            bound[rows, column],
            slack[rows, column],
            exact[rows, column],
            part[rows, part_best],
            exact[:, part_columns][rows, part_best],
        )

    def check_waypoints(self, plan: Plan, clearance_mm: float | None = None) -> WaypointCollisions:
        """Every waypoint of every station of ``plan`` checked at the plan's joints.

        ``clearance_mm`` overrides the config's clearance for the part pairs.
        """
        clearance = self._clearance(clearance_mm, motion=False)
        station = np.concatenate([np.full(len(s.q9), i) for i, s in enumerate(plan.stations)] or [np.zeros(0, int)])
        q9 = np.concatenate([s.q9 for s in plan.stations] or [np.zeros((0, 9))])
        checked = np.concatenate([s.reachable for s in plan.stations] or [np.zeros(0, bool)])
        checked = checked & np.isfinite(q9).all(axis=1)
        n = len(q9)
        distance = np.full(n, np.nan)
        part_distance = np.full(n, np.nan)
        body_a = np.full(n, "", dtype=object)
        body_b = np.full(n, "", dtype=object)
        in_collision = np.zeros(n, dtype=bool)
        if checked.any():
            found = self.check(q9[checked], clearance)
            names = np.array(self.pairs, dtype=object)
            distance[checked] = found.distance_mm
            in_collision[checked] = found.in_collision
            body_a[checked] = names[found.column, 0]
            body_b[checked] = names[found.column, 1]
            part_distance[checked] = found.part_distance_mm
        return WaypointCollisions(
            station=station.astype(int),
            checked=checked,
            in_collision=in_collision,
            distance_mm=distance,
            body_a=body_a,
            body_b=body_b,
            part_distance_mm=part_distance,
            clearance_mm=clearance,
        )

    def _clearance(self, clearance_mm, motion: bool = True) -> float:
        """The config's clearance, or an override checked as :class:`CollisionConfig` checks it (with the
        motion step's rule only for motions)."""
        if clearance_mm is None:
            return self.config.clearance_mm
        step = self.config.motion_step_mm if motion else 1e-9
        return CollisionConfig(clearance_mm=clearance_mm, motion_step_mm=step).clearance_mm

    def _required(self, clearance_mm: float) -> np.ndarray:
        """(p,): the gap of each pair with the part pairs at ``clearance_mm``."""
        return np.array([clearance_mm if b == "part" else r for (_, b), r in zip(self.pairs, self.required_mm)])

    def motion_checks(self, q_a, q_b) -> np.ndarray:
        """(k + 1, 9): the joint vectors the motion from ``q_a`` to ``q_b`` is checked at, ends included."""
        return motion_checks(q_a, q_b, self.reach_radii_mm, self.config.motion_step_mm)

    def check_motion(self, q_a, q_b, clearance_mm: float | None = None):
        """The motion from ``q_a`` to ``q_b`` checked by conservative advancement (module
        :mod:`sprayplan.collision.motion`): returns ``(s, slack_mm, distance_mm, pair)``, the fractions of the
        motion checked (k,), the least slack at each (k,) against ``max(gap, step / 2)``, and the distance and
        body pair of the motion's least slack. Stops at the first check in collision."""
        clearance = self._clearance(clearance_mm)
        step = self.config.motion_step_mm
        required = np.maximum(self._required(clearance), step / 2.0)
        q_a, q_b = np.asarray(q_a, dtype=float), np.asarray(q_b, dtype=float)
        total = float(motion_bound_mm(q_a, q_b, self.reach_radii_mm)[0])
        fractions, slacks = [], []
        best = (np.inf, np.nan, ("", ""))
        s = 0.0
        while True:
            found = self._check_chunk((q_a + s * (q_b - q_a))[None], required, self.MARGIN_MM)
            column, slack = int(found[1][0]), float(found[3][0])
            fractions.append(s)
            slacks.append(slack)
            if slack < best[0]:
                best = (slack, float(found[2][0]), self.pairs[column])
            if slack < 0 or s >= 1.0 or total == 0:
                break
            advance = max(step, slack + step / 2.0)
            s = min(1.0, s + advance / total)
        return np.array(fractions), np.array(slacks), best[1], best[2]

    def check_motions(self, plan: Plan, clearance_mm: float | None = None) -> MotionCollisions:
        """Every motion between consecutive reachable waypoints of ``plan`` (and each station move) checked
        by :meth:`check_motion`."""
        clearance = self._clearance(clearance_mm)
        q9 = np.concatenate([s.q9 for s in plan.stations] or [np.zeros((0, 9))])
        checked = np.concatenate([s.reachable for s in plan.stations] or [np.zeros(0, bool)])
        checked = checked & np.isfinite(q9).all(axis=1)
        index = np.flatnonzero(checked)  # consecutive checked waypoints, across stations too (the station move)
        start, end = index[:-1], index[1:]
        m = len(start)
        distance = np.full(m, np.nan)
        body_a = np.full(m, "", dtype=object)
        body_b = np.full(m, "", dtype=object)
        in_collision = np.zeros(m, dtype=bool)
        counts = np.zeros(m, dtype=int)
        for i, (a, b) in enumerate(zip(start, end)):
            fractions, slacks, distance[i], (body_a[i], body_b[i]) = self.check_motion(q9[a], q9[b], clearance)
            counts[i] = len(fractions)
            in_collision[i] = slacks.min() < 0
        return MotionCollisions(
            start=start.astype(int),
            end=end.astype(int),
            checks=counts,
            in_collision=in_collision,
            distance_mm=distance,
            body_a=body_a,
            body_b=body_b,
            step_mm=self.config.motion_step_mm,
        )
