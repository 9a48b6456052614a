"""Collision checks of the industrial arms of a cell (:mod:`sprayplan.cells`): each arm against the part and
the floor, and the robots of a cell against each other.

The bodies
----------
An OPW arm (:mod:`sprayplan.robots.opw`) is a chain of capsules between points its forward kinematics gives,
in the arm's plane (``t = sign * q + offset``, ``t23 = t2 + t3``) and then turned by ``Rz(t1)``:

- ``base``: from the base origin up axis 1 to ``(0, 0, c1)``, the turret;
- ``shoulder``: from there to axis 2 at ``S = (a1, b, c1)``;
- ``upper_arm``: from ``S`` to axis 3 at ``E = S + c2 (sin t2, 0, cos t2)``;
- ``elbow``: from ``E`` across the forearm's offset to ``E' = E + a2 (cos t23, 0, -sin t23)``;
- ``forearm``: from ``E'`` along the forearm to the wrist centre ``C = E' + c3 (sin t23, 0, cos t23)``
  (these are the terms of the wrist centre's ``x', z'`` in :func:`~sprayplan.robots.opw.opw_fk`);
- ``wrist``: from ``C`` to the flange ``F = C + c4 R (0, 0, 1)``;
- ``gun``: the gun's capsule in the flange frame (:func:`~sprayplan.collision.bodies.gun_capsule`: from the
  flange centre toward the nozzle, ending one radius short of the nozzle's plane, so that the spray cone in
  front of the nozzle is free space).

A track moves every body by ``s * axis``. The radii (:data:`OPW_LINK_RADII`) are **envelope estimates, not
published figures**: the makers publish the axes' positions (the OPW lengths) and the working range, not the
castings' widths. They are rounded up from the arms' footprints and overall widths as drawn in the makers'
dimension drawings, and should be replaced from a drawing when one is at hand.

What is checked
---------------
- every body but the base against the part, with ``[collision] clearance_mm`` (the gun with its own
  ``gun_radius_mm``): lower bounds from the part's surface samples (:mod:`~sprayplan.collision.broadphase`),
  coal's exact distance where a bound leaves less than a margin;
- every body but the base against the floor (a base stands on it or on a pedestal), and the TCP;
- the motion between consecutive reached waypoints, at joint configurations no body point moves more than
  ``motion_step_mm`` between (:func:`~sprayplan.collision.motion.motion_checks`, the track as the moving base),
  so every configuration in between is within ``step / 2`` of a checked one;
- the robots against each other, **in space, whatever the timing** (:func:`separation`): every body of robot
  A at every checked configuration against every body of robot B at every one of its own. When that least
  gap is positive the two arms cannot meet whatever order or speed they paint in, which is how the robots of
  a line, painting at the same time, are kept apart. Where it is not, the report says which robots and how
  near, and the plan needs a schedule (not made here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.collision.bodies import gun_capsule
from sprayplan.collision.broadphase import SurfaceSamples, capsules_to_surface, segment_points, surface_samples
from sprayplan.errors import ConfigError
from sprayplan.types import Part

try:
    import coal
except ImportError:  # pragma: no cover
    coal = None

#: The bodies of an OPW arm, base to gun.
ARM_BODIES = ("base", "shoulder", "upper_arm", "elbow", "forearm", "wrist", "gun")

#: Capsule radii (mm) of the OPW presets' bodies ``base`` .. ``wrist``: envelope estimates (module docstring).
OPW_LINK_RADII = {
    "abb-irb4600-60-205": (300.0, 250.0, 160.0, 180.0, 130.0, 100.0),
    "abb-irb4600-40-255": (300.0, 250.0, 160.0, 180.0, 130.0, 100.0),
    "abb-irb2400-10": (220.0, 180.0, 110.0, 130.0, 90.0, 70.0),
    "kuka-kr6-r700-sixx": (110.0, 100.0, 60.0, 70.0, 50.0, 45.0),
}

#: Pairs whose lower bound leaves at least this much over their gap are not queried exactly, mm.
MARGIN_MM = 20.0
#: Lower bounds on the part's distances are kept up to this much over the clearance, mm: a waypoint's slack
#: proves the motions next to it free for as far as its bodies can move within it (:func:`check_robot`).
PROOF_MM = 150.0
#: The part's surface samples cover it to this radius, mm (it enters the lower bounds only).
COVER_MM = 15.0
#: Points along a capsule for the lower bounds at most this far apart, mm.
SPACING_MM = 20.0
#: Configurations bounded at once.
CHUNK = 4096


def _require_coal():
    if coal is None:  # pragma: no cover
        raise ImportError("collision checks need the 'coal' package: pip install 'sprayplan[collision]' (or coal)")


def arm_radii(model: str) -> np.ndarray:
    """(7,) mm: the radii of :data:`ARM_BODIES` but the gun's, and NaN for the gun.

    Raises
    ------
    ConfigError
        An arm without link sizes (one line naming the robot and the known ones).
    """
    if model not in OPW_LINK_RADII:
        raise ConfigError(
            f"robot {model!r} has no link sizes for collision checks: use one of {', '.join(OPW_LINK_RADII)}"
        )
    return np.array([*OPW_LINK_RADII[model], math.nan])


def opw_points(params, q: np.ndarray) -> np.ndarray:
    """(n, 8, 3) mm in the arm's base frame: the base origin, the turret's top, S, E, E', C, the flange F and
    the flange's x axis tip (F + R x, for the gun's frame), of joint values (n, 6) (module docstring)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    t = q * params.signs + params.offsets
    t1, t2, t23 = t[:, 0], t[:, 1], t[:, 1] + t[:, 2]
    n = len(q)
    plane = np.zeros((n, 6, 3))  # in the arm's plane, before Rz(t1)
    plane[:, 1] = (0.0, 0.0, params.c1)
    plane[:, 2] = (params.a1, params.b, params.c1)
    plane[:, 3] = plane[:, 2] + params.c2 * np.stack([np.sin(t2), np.zeros(n), np.cos(t2)], axis=1)
    plane[:, 4] = plane[:, 3] + params.a2 * np.stack([np.cos(t23), np.zeros(n), -np.sin(t23)], axis=1)
    plane[:, 5] = plane[:, 4] + params.c3 * np.stack([np.sin(t23), np.zeros(n), np.cos(t23)], axis=1)
    c, s = np.cos(t1), np.sin(t1)
    out = np.empty((n, 8, 3))
    out[:, :6, 0] = c[:, None] * plane[..., 0] - s[:, None] * plane[..., 1]
    out[:, :6, 1] = s[:, None] * plane[..., 0] + c[:, None] * plane[..., 1]
    out[:, :6, 2] = plane[..., 2]
    return out


@dataclass(frozen=True)
class ConfigCollisions:
    """The checks of n configurations of one robot.

    Attributes
    ----------
    collides : (n,) bool
    body : (n,) int
        The body (index into :data:`ARM_BODIES`) with the least slack.
    other : (n,) str array
        ``"part"``, ``"floor"`` or ``"tcp-floor"``: what that body comes nearest.
    distance_mm : (n,) float
        Its distance (a lower bound where it is not exact and far over its gap).
    slack_mm : (n,) float
        Distance minus the required gap; negative in collision.
    """

    collides: np.ndarray
    body: np.ndarray
    other: np.ndarray
    distance_mm: np.ndarray
    slack_mm: np.ndarray


class ArmCollision:
    """One industrial arm of a cell (an OPW arm, on a track or not) against a part and the floor.

    Parameters
    ----------
    cell_robot : sprayplan.cells.spec.CellRobot
    part : Part
        The part in the cell frame (a mesh).
    floor_z_mm : float
    clearance_mm, gun_radius_mm, motion_step_mm : float
        As ``[collision]``.
    samples : SurfaceSamples, optional
        The part's surface samples, to share them between the robots of a cell.
    mesh : coal.BVHModelOBBRSS, optional
        The part's BVH (:func:`part_mesh`), to share it between the robots of a cell.

    Raises
    ------
    ConfigError
        An arm that is not an OPW arm with link sizes, a gun too thin for its radius.
    """

    def __init__(
        self,
        cell_robot,
        part: Part,
        floor_z_mm: float,
        clearance_mm: float = 30.0,
        gun_radius_mm: float = 30.0,
        motion_step_mm: float = 10.0,
        samples: SurfaceSamples | None = None,
        mesh=None,
    ):
        from sprayplan.robots.gantry import load_gun
        from sprayplan.robots.interface import OPWArm

        _require_coal()
        arm = cell_robot.robot(0.0)
        if not isinstance(arm, OPWArm):
            raise ConfigError(
                f"robot {cell_robot.name!r} ({cell_robot.model}): cell collision checks know the industrial arms "
                f"({', '.join(OPW_LINK_RADII)})"
            )
        self.name = cell_robot.name
        self.params = arm.params
        self.base2cell = np.asarray(cell_robot.base2cell, dtype=float)
        self.axis = np.zeros(3) if cell_robot.track is None else np.asarray(cell_robot.track.axis, dtype=float)
        self.radii = arm_radii(cell_robot.model)
        gun = load_gun(cell_robot.tool)
        capsule = gun_capsule(gun, gun_radius_mm)
        self.radii[-1] = capsule.radius_mm
        self._gun_end = np.asarray(capsule.p1, dtype=float)  # in the flange frame (the capsule starts at F)
        self.tcp2flange = np.asarray(arm.tcp2flange, dtype=float)
        self.floor_z_mm = float(floor_z_mm)
        self.clearance_mm = float(clearance_mm)
        self.motion_step_mm = float(motion_step_mm)
        self.samples = surface_samples(part, COVER_MM) if samples is None else samples
        self._mesh = part_mesh(part) if mesh is None else mesh
        nozzle = float(np.linalg.norm(np.asarray(gun.gun2flange, dtype=float)[:3, 3]))
        self.reach_radii_mm = joint_reach_mm(self.params, max(float(np.linalg.norm(self._gun_end)), nozzle), self.radii)

    # ------------------------------------------------------------------------------------------ poses

    def segments(self, q, track_mm) -> np.ndarray:
        """(n, 7, 2, 3) mm in the cell frame: the ends of every body's segment (:data:`ARM_BODIES`)."""
        from sprayplan.robots.opw import opw_fk

        q = np.atleast_2d(np.asarray(q, dtype=float))
        track = np.broadcast_to(np.asarray(track_mm, dtype=float), (len(q),))
        points = opw_points(self.params, q)
        flange = opw_fk(self.params, q)  # (n, 4, 4) in the base frame
        points[:, 6] = flange[:, :3, 3]
        points[:, 7] = flange[:, :3, 3] + flange[:, :3, :3] @ self._gun_end
        rot, origin = self.base2cell[:3, :3], self.base2cell[:3, 3]
        cell = points @ rot.T + origin + track[:, None, None] * self.axis
        pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 6), (6, 7)]
        return np.stack([cell[:, [a, b]] for a, b in pairs], axis=1)

    def tcp(self, q, track_mm) -> np.ndarray:
        """(n, 3) mm: the TCP in the cell frame."""
        from sprayplan.robots.opw import opw_fk

        q = np.atleast_2d(np.asarray(q, dtype=float))
        track = np.broadcast_to(np.asarray(track_mm, dtype=float), (len(q),))
        tip = (opw_fk(self.params, q) @ self.tcp2flange)[:, :3, 3]
        return tip @ self.base2cell[:3, :3].T + self.base2cell[:3, 3] + track[:, None] * self.axis

    # ------------------------------------------------------------------------------------------ checks

    def check(self, q, track_mm) -> ConfigCollisions:
        """Check configurations (joints (n, 6) rad, track positions (n,) mm) against the part and the floor."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        track = np.broadcast_to(np.asarray(track_mm, dtype=float), (len(q),)).copy()
        parts = [self._check_chunk(q[i : i + CHUNK], track[i : i + CHUNK]) for i in range(0, len(q), CHUNK)]
        if not parts:
            empty = np.zeros(0)
            return ConfigCollisions(empty.astype(bool), empty.astype(int), empty.astype(str), empty, empty)
        return ConfigCollisions(*(np.concatenate([p[k] for p in parts]) for k in range(5)))

    def _check_chunk(self, q, track):
        n, b = len(q), len(ARM_BODIES)
        segments = self.segments(q, track)  # (n, 7, 2, 3)
        radii = self.radii
        upper = self.clearance_mm + PROOF_MM
        part = np.full((n, b), np.inf)
        for k in range(1, b):
            part[:, k] = capsules_to_surface(self.samples, segments[:, k], float(radii[k]), upper, SPACING_MM)
        rows, cols = np.nonzero(part - self.clearance_mm < MARGIN_MM)
        if len(rows):
            part[rows, cols] = self._exact(segments[rows, cols], radii[cols])
        floor = segments[..., 2].min(axis=2) - radii - self.floor_z_mm  # (n, 7)
        floor[:, 0] = np.inf
        tcp_floor = self.tcp(q, track)[:, 2] - self.floor_z_mm
        slack = np.concatenate([part - self.clearance_mm, floor, tcp_floor[:, None]], axis=1)
        distance = np.concatenate([part, floor, tcp_floor[:, None]], axis=1)
        column = np.argmin(slack, axis=1)
        rows = np.arange(n)
        kinds = np.array(["part"] * b + ["floor"] * b + ["tcp-floor"])
        body = np.where(column < 2 * b, column % b, b - 1)
        return slack[rows, column] < 0, body, kinds[column], distance[rows, column], slack[rows, column]

    def slack_bound(self, q, track_mm) -> np.ndarray:
        """(n,) mm: a lower bound on each configuration's slack (``check(q, track_mm).slack_mm``) from the
        surface samples' bounds alone, no exact query: enough to prove the motions next to a waypoint free for
        as far as its bodies can move within it (:func:`plan_collides`), if less far than the exact slack."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        track = np.broadcast_to(np.asarray(track_mm, dtype=float), (len(q),)).copy()
        out = np.empty(len(q))
        b = len(ARM_BODIES)
        for start in range(0, len(q), CHUNK):
            qc, tc = q[start : start + CHUNK], track[start : start + CHUNK]
            segments = self.segments(qc, tc)
            part = np.full((len(qc), b), np.inf)
            for k in range(1, b):
                part[:, k] = capsules_to_surface(
                    self.samples, segments[:, k], float(self.radii[k]), self.clearance_mm + PROOF_MM, SPACING_MM
                )
            floor = segments[..., 2].min(axis=2) - self.radii - self.floor_z_mm
            floor[:, 0] = np.inf
            tcp_floor = self.tcp(qc, tc)[:, 2] - self.floor_z_mm
            out[start : start + CHUNK] = np.minimum(
                (part - self.clearance_mm).min(axis=1), np.minimum(floor.min(axis=1), tcp_floor)
            )
        return out

    def collides(self, q, track_mm) -> np.ndarray:
        """(n,) bool: the same answer as ``check(q, track_mm).collides`` with fewer exact queries, for callers
        that want only yes or no (the repairs' screen). The floor first (exact by construction); then per row
        only the bodies whose lower bound on the part distance is below the clearance are measured, the least
        bound first, and a row is done at its first body in collision."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        track = np.broadcast_to(np.asarray(track_mm, dtype=float), (len(q),)).copy()
        out = np.zeros(len(q), bool)
        for start in range(0, len(q), CHUNK):
            out[start : start + CHUNK] = self._collides_chunk(q[start : start + CHUNK], track[start : start + CHUNK])
        return out

    def _collides_chunk(self, q, track) -> np.ndarray:
        b = len(ARM_BODIES)
        segments = self.segments(q, track)
        radii = self.radii
        floor = segments[..., 2].min(axis=2) - radii - self.floor_z_mm
        floor[:, 0] = np.inf
        hit = (floor < 0).any(axis=1) | (self.tcp(q, track)[:, 2] - self.floor_z_mm < 0)
        rows = np.flatnonzero(~hit)
        part = np.full((len(rows), b), np.inf)
        for k in range(1, b):
            part[:, k] = capsules_to_surface(
                self.samples, segments[rows, k], float(radii[k]), self.clearance_mm + PROOF_MM, SPACING_MM
            )
        near = part < self.clearance_mm
        order = np.argsort(np.where(near, part, np.inf), axis=1)
        done = np.zeros(len(rows), bool)
        for k in range(int(near.sum(axis=1).max(initial=0))):
            columns = order[:, k]
            todo = np.flatnonzero(~done & near[np.arange(len(rows)), columns])
            if not len(todo):
                break
            inside = self._within(segments[rows[todo], columns[todo]], radii[columns[todo]], self.clearance_mm)
            hit[rows[todo[inside]]] = True
            done[todo[inside]] = True
        return hit

    def _capsules(self, segments: np.ndarray, radii: np.ndarray, grow_mm: float = 0.0):
        """coal's capsules (segments (k, 2, 3), radii (k,) plus ``grow_mm``) with their poses in the cell frame."""
        axis = segments[:, 1] - segments[:, 0]
        length = np.linalg.norm(axis, axis=1)
        z = np.where(length[:, None] > 0, axis / np.maximum(length, 1e-12)[:, None], [0.0, 0.0, 1.0])
        rotations = _axis_poses(z)
        centres = segments.mean(axis=1)
        for i in range(len(segments)):
            yield (
                coal.Capsule(float(radii[i]) + grow_mm, float(length[i])),
                coal.Transform3s(rotations[i], centres[i]),
            )

    def _exact(self, segments: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """(k,) coal's signed distances of capsules (segments (k, 2, 3), radii (k,)) to the part's mesh."""
        request, identity = coal.DistanceRequest(), coal.Transform3s()
        return np.array(
            [
                coal.distance(capsule, pose, self._mesh, identity, request, coal.DistanceResult())
                for capsule, pose in self._capsules(segments, radii)
            ],
            dtype=float,
        )

    def _within(self, segments: np.ndarray, radii: np.ndarray, limit_mm: float) -> np.ndarray:
        """(k,) bool: the capsules (segments (k, 2, 3), radii (k,)) come nearer the part's mesh than
        ``limit_mm``, i.e. :meth:`_exact` ``< limit_mm``: coal's collision test of each capsule grown by
        ``limit_mm`` (it stops at the first triangle it meets, where the distance looks for the nearest: about
        a quarter of the time on the BMW's arms near the body, the same answers)."""
        request, identity = coal.CollisionRequest(), coal.Transform3s()
        return np.array(
            [
                coal.collide(capsule, pose, self._mesh, identity, request, coal.CollisionResult()) > 0
                for capsule, pose in self._capsules(segments, radii, float(limit_mm))
            ],
            dtype=bool,
        )

    def motion_bounds(self, q, track_mm, first: np.ndarray) -> np.ndarray:
        """(k,) mm: the bound on any body point's displacement over the motions from waypoint ``first`` to the
        next (:func:`~sprayplan.collision.motion.motion_bound_mm`, the track as the moving base)."""
        q = np.asarray(q, dtype=float)
        track = np.asarray(track_mm, dtype=float)
        dq = q[first + 1] - q[first]
        return np.abs(dq) @ self.reach_radii_mm + np.abs(track[first + 1] - track[first]) * np.linalg.norm(self.axis)

    def motion_configs(self, q, track_mm, reachable, slack=None, step_mm=None):
        """The configurations at which the motions between consecutive reached waypoints are checked, both
        ends left out (they are waypoints): joints (m, 6), track (m,) and the index of the motion's first
        waypoint (m,). Each motion is cut into ``k = ceil(bound / step)`` equal joint steps (``step``
        default ``motion_step_mm``). With the waypoints' slacks (n,), the configurations that the slack of an
        end proves free (no body point farther from that end than its slack) are left out, and so is every
        motion whose two ends' slacks add up to its bound."""
        q = np.asarray(q, dtype=float)
        track = np.asarray(track_mm, dtype=float)
        reachable = np.asarray(reachable, dtype=bool)
        step = self.motion_step_mm if step_mm is None else float(step_mm)
        first = np.flatnonzero(reachable[:-1] & reachable[1:])
        bound = self.motion_bounds(q, track, first)
        steps = np.maximum(1, np.ceil(bound / step - 1e-12).astype(np.int64))
        inner = steps - 1  # configurations strictly between the two waypoints
        owner = np.repeat(first, inner)
        k = np.repeat(steps, inner)
        j = np.arange(len(owner)) - np.repeat(np.cumsum(inner) - inner, inner) + 1  # 1 .. steps - 1
        s = j / k
        if slack is not None and len(owner):
            slack = np.nan_to_num(np.asarray(slack, dtype=float), nan=-np.inf)
            b = np.repeat(bound, inner)
            keep = (s * b > slack[owner]) & ((1.0 - s) * b > slack[owner + 1])
            owner, s = owner[keep], s[keep]
        s = s[:, None]
        joints = q[owner] + s * (q[owner + 1] - q[owner])
        tracks = track[owner] + s[:, 0] * (track[owner + 1] - track[owner])
        return joints, tracks, owner


def joint_reach_mm(params, gun_mm: float, radii: np.ndarray) -> np.ndarray:
    """(6,) mm: for each joint of an OPW arm, a bound on how far any body point it moves can be from its axis
    (``R_i`` of :mod:`~sprayplan.collision.motion`): the lengths of the chain beyond the joint, the gun's
    segment and the largest radius of the bodies it carries."""
    a1, a2, b, c2, c3, c4 = (abs(params.a1), abs(params.a2), abs(params.b), params.c2, abs(params.c3), abs(params.c4))
    r = np.asarray(radii, dtype=float)
    wrist = c4 + gun_mm
    return np.array(
        [
            a1 + b + c2 + a2 + c3 + wrist + float(np.nanmax(r[1:])),  # axis 1: everything but the turret
            c2 + a2 + c3 + wrist + float(np.nanmax(r[2:])),
            a2 + c3 + wrist + float(np.nanmax(r[3:])),
            wrist + float(np.nanmax(r[5:])),
            wrist + float(np.nanmax(r[5:])),
            gun_mm + float(r[6]),
        ]
    )


def _axis_poses(z: np.ndarray) -> np.ndarray:
    """(k, 3, 3): rotations whose z axes are the unit vectors ``z`` (k, 3)."""
    helper = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=2)


def part_mesh(part: Part):
    """coal's BVH of a mesh part's triangles."""
    _require_coal()
    mesh = coal.BVHModelOBBRSS()
    vertices = np.ascontiguousarray(part.vertices, dtype=float)
    faces = np.ascontiguousarray(part.faces, dtype=np.int64)
    mesh.beginModel(len(faces), len(vertices))
    mesh.addVertices(vertices)
    mesh.addTriangles(faces)
    mesh.endModel()
    return mesh


@dataclass(frozen=True)
class RobotCollisions:
    """One robot's plan checked: its reached waypoints, and the motions between consecutive ones.

    Attributes
    ----------
    waypoint : ConfigCollisions
        Of every waypoint of the robot's plan in order (unreached ones are not checked: ``collides`` False,
        slack NaN).
    motion_collides : (n,) bool
        True where the motion from waypoint i to i + 1 has a checked configuration in collision.
    motion_checked : int
        How many configurations between waypoints were checked.
    """

    waypoint: ConfigCollisions
    motion_collides: np.ndarray
    motion_checked: int

    def summary(self) -> dict:
        w = self.waypoint
        checked = np.isfinite(w.slack_mm)
        worst = int(np.nanargmin(w.slack_mm)) if checked.any() else -1
        hits = w.collides
        by = {}
        for name, kind in {(ARM_BODIES[b], o) for b, o in zip(w.body[hits], w.other[hits])}:
            by[f"{name}-{kind}"] = int((hits & (w.body == ARM_BODIES.index(name)) & (w.other == kind)).sum())
        return {
            "waypoints_checked": int(checked.sum()),
            "waypoints_in_collision": int(hits.sum()),
            "in_collision_by_pair": dict(sorted(by.items())),
            "motions_in_collision": int(self.motion_collides.sum()),
            "motion_configurations_checked": int(self.motion_checked),
            "least_slack_mm": None if worst < 0 else round(float(w.slack_mm[worst]), 1),
        }


def check_robot(arm: ArmCollision, q, track_mm, reachable) -> RobotCollisions:
    """Check one robot's waypoints and the motions between them (module docstring)."""
    q = np.asarray(q, dtype=float)
    reachable = np.asarray(reachable, dtype=bool)
    n = len(q)
    slack = np.full(n, np.nan)
    distance = np.full(n, np.nan)
    collides = np.zeros(n, bool)
    body = np.zeros(n, int)
    other = np.full(n, "", dtype="<U9")
    idx = np.flatnonzero(reachable)
    if len(idx):
        found = arm.check(q[idx], np.asarray(track_mm)[idx])
        collides[idx], body[idx], other[idx] = found.collides, found.body, found.other
        distance[idx], slack[idx] = found.distance_mm, found.slack_mm
    motion = np.zeros(max(n - 1, 0), bool)
    joints, tracks, owner = arm.motion_configs(q, track_mm, reachable, slack=np.where(collides, np.inf, slack))
    if len(joints):  # only whether each is in collision: the yes/no check (the full check's answer, for less)
        motion[np.unique(owner[arm.collides(joints, tracks)])] = True
    if n > 1:
        motion |= collides[:-1] | collides[1:]
    return RobotCollisions(ConfigCollisions(collides, body, other, distance, slack), motion, len(joints))


#: The motions' configurations are checked by :func:`plan_collides` this many at a time, stopping at the first
#: batch with one in collision.
MOTION_BATCH = 512


def plan_collides(arm: ArmCollision, q, track_mm, reachable) -> bool:
    """Whether :func:`check_robot` would find any waypoint or motion of the plan in collision, answered for
    less: the waypoints by the yes/no check (:meth:`ArmCollision.collides`, its answer with fewer exact
    queries), and only when they are all free, the motions' configurations in batches of
    :data:`MOTION_BATCH`, stopping at the first in collision. The motions are cut at the same configurations
    as :func:`check_robot` cuts them; those next to a waypoint are left out only as far as a lower bound on its
    slack proves them free (:meth:`ArmCollision.slack_bound`, where ``check_robot`` takes the exact slack), so
    every configuration left out is free and the answer is the same."""
    q = np.asarray(q, dtype=float)
    track = np.asarray(track_mm, dtype=float)
    reachable = np.asarray(reachable, dtype=bool)
    idx = np.flatnonzero(reachable)
    if not len(idx):
        return False
    if arm.collides(q[idx], track[idx]).any():
        return True
    slack = np.full(len(q), np.nan)
    slack[idx] = np.maximum(arm.slack_bound(q[idx], track[idx]), 0.0)
    joints, tracks, _ = arm.motion_configs(q, track, reachable, slack=slack)
    for start in range(0, len(joints), MOTION_BATCH):
        if arm.collides(joints[start : start + MOTION_BATCH], tracks[start : start + MOTION_BATCH]).any():
            return True
    return False


#: Voxel size of the swept volumes compared by :func:`separation`, mm.
SWEEP_VOXEL_MM = 25.0
#: The motions between waypoints are sampled for the swept volumes at most this far apart, mm.
SWEEP_STEP_MM = 50.0


def swept_points(arm: ArmCollision, q, track_mm, reachable) -> tuple[np.ndarray, np.ndarray, float]:
    """The space one robot's bodies sweep through its plan: points (k, 3) with a radius each (k,), and the
    most any body point of a configuration in the plan (waypoints and the motions between) can lie from the
    nearest point's ball, mm.

    The bodies are sampled at the waypoints and along the motions between them (no body point moves more than
    ``SWEEP_STEP_MM`` between two samples, so every configuration is within half of it of one), along each
    capsule at most ``SPACING_MM`` apart, and the samples are merged into voxels of ``SWEEP_VOXEL_MM`` (each
    voxel keeps its centre and the largest radius in it)."""
    q = np.asarray(q, dtype=float)
    reach = np.asarray(reachable, dtype=bool)
    joints, tracks, _ = arm.motion_configs(q, track_mm, reach, step_mm=SWEEP_STEP_MM)
    all_q = np.concatenate([q[reach], joints])
    all_t = np.concatenate([np.asarray(track_mm, dtype=float)[reach], tracks])
    keys, radii = [], []
    half = 0.0
    offset = np.int64(1 << 20)
    for i in range(0, len(all_q), CHUNK):
        segments = arm.segments(all_q[i : i + CHUNK], all_t[i : i + CHUNK])  # (m, 7, 2, 3)
        for k in range(len(ARM_BODIES)):
            points, h = segment_points(segments[:, k], SPACING_MM)
            half = max(half, h)
            cell = np.floor(points.reshape(-1, 3) / SWEEP_VOXEL_MM).astype(np.int64) + offset
            key = np.unique((cell[:, 0] << 42) | (cell[:, 1] << 21) | cell[:, 2])
            keys.append(key)
            radii.append(np.full(len(key), arm.radii[k]))
    if not keys:
        return np.zeros((0, 3)), np.zeros(0), 0.0
    key = np.concatenate(keys)
    r = np.concatenate(radii)
    order = np.lexsort((-r, key))  # by voxel, the largest radius first
    key, r = key[order], r[order]
    first = np.r_[True, key[1:] != key[:-1]]
    key, r = key[first], r[first]
    mask = np.int64((1 << 21) - 1)
    cells = np.stack([(key >> 42) & mask, (key >> 21) & mask, key & mask], axis=1) - offset
    points = (cells + 0.5) * SWEEP_VOXEL_MM
    error = half + SWEEP_VOXEL_MM * math.sqrt(3.0) / 2.0 + SWEEP_STEP_MM / 2.0
    return points, r, error


def separation(a: tuple, b: tuple) -> float:
    """A lower bound on the least gap, mm, between any body of one robot in any configuration of its plan and
    any body of another in any of its own: the least gap between the two sets of swept balls
    (:func:`swept_points`, exact over the pairs: one k-d tree per radius of ``b``), less both error bounds.
    Positive: the two robots can never touch, whatever their timing."""
    pa, ra, ea = a
    pb, rb, eb = b
    if not len(pa) or not len(pb):
        return math.inf
    best = math.inf
    for radius in np.unique(rb):
        d, _ = cKDTree(pb[rb == radius]).query(pa, k=1)
        best = min(best, float((d - ra - radius).min()))
    return best - ea - eb
