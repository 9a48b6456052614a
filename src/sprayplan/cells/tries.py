"""The tries a cell robot makes for a stroke (``cells.plan``'s step 5 and ``cells.repair``): track positions about
the stroke's middle and rolls of the gun about its own axis, and the joints an arm starts from."""

from __future__ import annotations

import math

import numpy as np

from sprayplan.types import Stroke

#: Track positions tried about the one nearest a stroke's middle, mm.
TRACK_TRIES_MM = (0.0, -300.0, 300.0, -600.0, 600.0)
#: Rolls of the gun about its own axis tried, degrees.
ROLL_TRIES_DEG = (0.0, 90.0, 180.0, 270.0)
#: The joints a six-axis robot starts from (rad): the wrist bent (ABB's zero is a straight, singular wrist).
START_JOINTS = np.radians([0.0, 0.0, 0.0, 0.0, 30.0, 0.0])
#: A joint step this large between two waypoints of a stroke (rad) is a jump (``cells.plan.solve_strokes``,
#: ``cells.repair._candidates``): the arm turned over, or a first joint at its limit turned back by a whole
#: turn (over the SUV in ``line3`` the roof robot's first joint turned by 344 deg between two waypoints 6 mm
#: apart where its strokes crossed the roof's middle).
JOINT_JUMP_RAD = math.radians(90.0)
#: A try whose flange passes nearer than this to the robot's first axis is tried after the others, mm
#: (:func:`stroke_tries`).
AXIS_ONE_CLEARANCE_MM = 300.0


def start_joints(dof: int) -> np.ndarray:
    """:data:`START_JOINTS` for an arm of ``dof`` axes (the first ``dof``, zeros beyond six)."""
    return np.r_[START_JOINTS, np.zeros(max(0, dof - 6))][:dof]


def rot_z(angle_deg: float) -> np.ndarray:
    """(4, 4): a turn of ``angle_deg`` about z (the gun's roll about its own axis)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    return out


def stroke_tries(cell_robot, stroke: Stroke) -> list[tuple[np.ndarray, float]]:
    """The (track positions at the waypoints (n,) mm, roll deg) tries of a stroke, in the order they are
    preferred; offsets that the track's ends make the same as an earlier one are left out.

    On a track, first the track held still through the stroke, at the middle of the stroke's extent along it
    plus each offset of :data:`TRACK_TRIES_MM`; then the track following the gun, at the gun tip's own
    position along it plus each offset. Held still, the stroke is the arm's alone and the track moves between
    strokes: a track that follows the gun has to speed up and slow down with every change of the gun's speed
    along it, at an acceleration far below the arm's (``[timing] track_max_acceleration_mm_s2``), which slows
    the whole stroke (docs/benchmarks.md, "Session 23": on the BMW body the film at the timed speeds 62.4 ->
    71.5 % in spec). A stroke longer than the arm reaches from one place (4 m along a car's side) falls to the
    following tries. Tries whose flange passes near the robot's first axis go last
    (:func:`_off_axis_one_first`)."""
    if cell_robot.track is None:
        return _off_axis_one_first(cell_robot, stroke, [(np.zeros(len(stroke)), r) for r in ROLL_TRIES_DEG])
    lo, hi = cell_robot.track.range_mm
    along = (stroke.tcp - cell_robot.base2cell[:3, 3]) @ cell_robot.track.axis
    middle = 0.5 * (along.min() + along.max()) if len(along) else 0.0
    tracks: list[np.ndarray] = []
    for base in (np.full(len(along), middle), along):
        for d in TRACK_TRIES_MM:
            s = np.clip(base + d, lo, hi)
            if not any(np.array_equal(s, t) for t in tracks):
                tracks.append(s)
    return _off_axis_one_first(cell_robot, stroke, [(t, r) for t in tracks for r in ROLL_TRIES_DEG])


def _off_axis_one_first(cell_robot, stroke: Stroke, tries: list) -> list:
    """``tries`` with those whose flange passes within :data:`AXIS_ONE_CLEARANCE_MM` of the robot's first axis
    moved after the others, each group in its order.

    On the first axis (the shoulder singularity) the first joint is not fixed by the pose: a stroke that passes
    under the base of a robot hung over the roof turns the arm about its first axis fastest right there (across
    the roof, held at the stroke's middle, 17.9 deg a 30 mm step against 4.4 with the track 300 mm off), and its
    IK branch or roll may change there. Alone this order made the SUV's roof robot worse (67 transfers turning
    a joint by more than 90 deg against 27: the tries off the axis alternated ahead of and behind the gun);
    with the strokes solved in order from where the one before ends (``cells.plan.solve_strokes``) it is 19
    (docs/benchmarks.md, "Session 26")."""
    if cell_robot.is_gantry or not len(stroke) or not tries:
        return tries
    from sprayplan.surface.poses import stroke_poses

    robot = cell_robot.robot(0.0)
    base = np.asarray(robot.base2world, dtype=float)
    up, origin = base[:3, 2], base[:3, 3]
    axis = np.zeros(3) if cell_robot.track is None else np.asarray(cell_robot.track.axis, dtype=float)
    flange2tcp = np.linalg.inv(np.asarray(robot.tcp2flange, dtype=float))
    poses = stroke_poses(stroke)
    flanges = {}
    for _, r in tries:
        if r not in flanges:
            flanges[r] = (poses @ rot_z(r) @ flange2tcp)[:, :3, 3]
    far, near = [], []
    for t, r in tries:
        d = flanges[r] - origin - t[:, None] * axis
        across = d - (d @ up)[:, None] * up
        (far if np.linalg.norm(across, axis=1).min() >= AXIS_ONE_CLEARANCE_MM else near).append((t, r))
    return far + near
