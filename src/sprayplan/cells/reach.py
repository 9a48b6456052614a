"""Which robot of a cell reaches which face of a placed part: the input of
:func:`sprayplan.surface.areas.assign_areas` (issue 18, "each area given to the robot that reaches all of it
best").

For every face, the gun stands at ``centroid + standoff * normal`` with its axis along ``-normal`` (the pose
a stroke over the face would take), turned about its own axis by each of ``rolls`` angles (the roll is free for
the spray). A robot on a track tries its base at the track position nearest the face and at ``track_offsets_mm``
either side of it (clipped to the track). The score of a (robot, face) is the share of those (track position,
roll) tries that the robot's inverse kinematics solves within its joint limits on any branch: 0 where none
does (not reached), 1 where every try does (the face is reached whichever way the gun is turned and from
anywhere near it on the track, a measure of dexterity).

With the cell's collision model (``arms``: one :class:`~sprayplan.collision.arms.ArmCollision` a robot, when
``[collision] check`` is on), a face also needs one try whose joints are free of the part and the floor: the
valid branches of each try are checked in order until one is free, and a face with none scores 0 for that
robot (it is reached only through the body: the inner face of a sill under the car, a wheel arch's far wall).
The score of a face that has a free try stays its share of tries reached, as without the model.

With ``tilts_deg`` (the plan passes ``[collision] piece_tilt_deg`` when the collision model is on), a face with
no try along its normal that is reached (and free, with the model) is tried again with the gun tilted about its
target (:func:`reach_tilts`: half and all of the angle, either way, about the pose's x and then its y axis; the
gun stays at the standoff and aims at the same point), at every track position and roll: a face reached so
scores :data:`~sprayplan.surface.areas.TILTED`, reached but below any face reached straight (whose score is at
least twice that), so that an area still goes to the robot that paints it along the normal. The plan paints
such faces with a tilted gun where the stroke over them is solved again piece by piece
(``cells.repair.resolved_piece``). On the SUV in ``line3`` the tilted tries take the surface no robot reaches
free from 5.52 to 0.27 m^2, on the BMW from 0.65 to 0.27 m^2 (``bench/bench_reach_tilts.py``).

A car body has tens of thousands of faces, and neighbouring faces of one direction are reached alike: faces
are grouped by ``cluster_mm`` cubes of their centres and by the :data:`~sprayplan.surface.areas.DIRECTIONS`
class of their normals, and the largest face of each group stands for it (its score is the group's). The
groups are small against a robot's reach (50 mm against 2 m), so only the seams between robots move, by at
most a group's size; ``cluster_mm = 0`` tries every face.
"""

from __future__ import annotations

import math

import numpy as np

from sprayplan.cells.spec import Cell
from sprayplan.surface.areas import DIRECTIONS, TILTED
from sprayplan.surface.pairs import unique_rows
from sprayplan.surface.poses import poses_at
from sprayplan.types import Part

#: Rolls about the gun axis tried, degrees.
ROLLS_DEG = (0.0, 90.0, 180.0, 270.0)
#: Track positions tried either side of the one nearest a face, mm.
TRACK_OFFSETS_MM = (0.0, -500.0, 500.0)
#: The size of the cubes faces are grouped by, mm.
CLUSTER_MM = 50.0


def face_groups(centres: np.ndarray, normals: np.ndarray, face_area: np.ndarray, cluster_mm: float):
    """The faces grouped by ``cluster_mm`` cubes and normal direction class: (the representative face of each
    group, (g,) int; the group of each face, (m,) int). Every face is its own group when ``cluster_mm`` is 0."""
    m = len(centres)
    if cluster_mm <= 0 or m == 0:
        return np.arange(m), np.arange(m)
    basis = np.array(list(DIRECTIONS.values()))
    cube = np.floor((centres - centres.min(axis=0)) / cluster_mm).astype(np.int64)
    key = np.column_stack([cube, np.argmax(normals @ basis.T, axis=1)])
    _, _, group = unique_rows(key)
    # the largest face of each group (ties: the lowest index)
    order = np.lexsort((np.arange(m), -face_area, group))
    first = np.r_[True, group[order][1:] != group[order][:-1]]
    return order[first], group


def _rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    return out


def reach_tilts(max_deg: float) -> tuple:
    """The ``(axis, degrees)`` tilts of the reach check for ``[collision] piece_tilt_deg`` (the pose's x axis 0,
    its y axis 1), in the order tried: half of ``max_deg`` and all of it, either way, about x, then about y;
    () for 0. The poses' x and y are not tied to a stroke's direction (the strokes are not planned yet), so both
    are tried, as the repairs try sideways and along the travel (``cells.repair.piece_tilts``)."""
    if max_deg <= 0:
        return ()
    return tuple((axis, a) for axis in (0, 1) for a in (max_deg / 2, -max_deg / 2, max_deg, -max_deg))


def tilted_poses(poses: np.ndarray, standoff_mm: float, axis: int, angle_deg: float) -> np.ndarray:
    """(n, 4, 4): gun poses ``poses`` (z from the gun to the surface, the target ``standoff_mm`` along it)
    turned by ``angle_deg`` about their own x (``axis`` 0) or y (1) axis through the target: the gun stays at
    the standoff and aims at the same point."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    turn = np.eye(3)
    if axis == 0:
        turn[1:, 1:] = [[c, -s], [s, c]]
    else:
        turn[0, 0], turn[0, 2], turn[2, 0], turn[2, 2] = c, s, -s, c
    out = poses.copy()
    target = poses[:, :3, 3] + standoff_mm * poses[:, :3, 2]
    out[:, :3, :3] = poses[:, :3, :3] @ turn
    out[:, :3, 3] = target - standoff_mm * out[:, :3, 2]
    return out


def _free_branch(arm, sols, track: np.ndarray, todo: np.ndarray) -> np.ndarray:
    """(n,) bool: poses ``todo`` with a valid branch of ``sols`` free of collisions, the branches checked in
    order and a pose done at its first free one."""
    n, k = sols.valid.shape
    found = np.zeros(n, bool)
    for b in range(k):
        rows = np.flatnonzero(todo & ~found & sols.valid[:, b])
        if len(rows):
            found[rows] = ~arm.collides(sols.q[rows, b], track[rows])
    return found


def reach_matrix(
    cell: Cell,
    part: Part,
    face_normals: np.ndarray,
    standoff_mm: float,
    rolls_deg=ROLLS_DEG,
    track_offsets_mm=TRACK_OFFSETS_MM,
    cluster_mm: float = CLUSTER_MM,
    arms=None,
    tilts_deg: tuple = (),
) -> np.ndarray:
    """(robots, faces) float in [0, 1]: how well each robot reaches each face (module docstring).

    ``arms``, optional: per robot an object with ``collides(q (n, dof), track_mm (n,)) -> (n,) bool`` (the cell's
    :class:`~sprayplan.collision.arms.ArmCollision`) or None; where given, faces the robot reaches only in
    collision score 0 for it. ``tilts_deg``: the ``(axis, degrees)`` tilts (:func:`reach_tilts`) tried on the
    faces no try along the normal reaches (free); those they reach score
    :data:`~sprayplan.surface.areas.TILTED`.

    ``part`` is in the cell frame (:func:`~sprayplan.cells.spec.place_part`); ``face_normals`` its outward
    unit face normals; ``cluster_mm`` groups faces (module docstring). A gantry cell's robot reaches everything its stations will be placed for (score 1): its
    reach is decided by the stations stage.
    """
    all_centres = part.triangles.mean(axis=1)
    all_normals = np.asarray(face_normals, dtype=float)
    rep, group = face_groups(all_centres, all_normals, part.face_areas, cluster_mm)
    centres, normals = all_centres[rep], all_normals[rep]
    tips = centres + standoff_mm * normals
    base_poses = poses_at(tips, normals)
    out = np.zeros((len(cell.robots), len(centres)))
    for i, cr in enumerate(cell.robots):
        if cr.is_gantry:
            out[i] = 1.0
            continue
        robot = cr.robot(0.0)
        origin = cr.base2cell[:3, 3]
        # faces beyond the reach sphere of the whole track are not tried
        if cr.track is None:
            shifts = [np.zeros(len(tips))]
        else:
            along = (tips - origin) @ cr.track.axis
            lo, hi = cr.track.range_mm
            shifts = [np.clip(along + d, lo, hi) for d in track_offsets_mm]
        arm = None if arms is None else arms[i]
        placements = []  # per track position: (base offsets (n, 4, 4), track mm (n,), faces near enough (n,))
        for s in shifts:
            offset = np.zeros((len(tips), 4, 4))
            if cr.track is not None:
                offset[:, :3, 3] = -s[:, None] * cr.track.axis
            base_at = origin + (0 if cr.track is None else s[:, None] * cr.track.axis)
            placements.append((offset, s, np.linalg.norm(tips - base_at, axis=1) <= cr.reach_mm + 1e-9))
        free = np.zeros(len(tips), bool)  # a try found reached (and, with ``arm``, free of collisions)
        tries = 0
        for offset, s, near in placements:
            for roll in rolls_deg:
                tries += 1
                if not near.any():
                    continue
                poses = base_poses[near] @ _rot_z(math.radians(roll)) + offset[near]
                sols = robot.ik(poses)
                hit = np.zeros(len(tips), bool)
                hit[near] = sols.valid.any(axis=1)
                out[i] += hit
                if arm is not None:
                    free[near] |= _free_branch(arm, sols, s[near], ~free[near])
                else:
                    free |= hit
        out[i] /= max(tries, 1)
        out[i] = np.where(free, np.maximum(out[i], 2 * TILTED), 0.0)
        straight = free.copy()
        for axis, angle in tilts_deg:
            if free.all():
                break
            turned = tilted_poses(base_poses, standoff_mm, axis, angle)
            for offset, s, near in placements:
                for roll in rolls_deg:
                    rows = np.flatnonzero(near & ~free)
                    if not len(rows):
                        continue
                    sols = robot.ik(turned[rows] @ _rot_z(math.radians(roll)) + offset[rows])
                    if arm is not None:
                        free[rows] |= _free_branch(arm, sols, s[rows], np.ones(len(rows), bool))
                    else:
                        free[rows] |= sols.valid.any(axis=1)
        out[i, free & ~straight] = TILTED
    return out[:, group]
