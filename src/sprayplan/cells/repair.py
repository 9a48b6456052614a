"""The repairs of a cell robot's strokes in collision (``sprayplan plan --cell ... --collisions``): every track
position and roll of the stroke (:func:`~sprayplan.cells.tries.stroke_tries`) and every IK branch, screened in
batched yes/no checks, the first free kept (:func:`repaired_work`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from sprayplan.cells.tries import rot_z, start_joints, stroke_tries
from sprayplan.surface.poses import stroke_poses

#: The waypoints of a stroke at which every repair candidate is screened before any is checked in full: up to
#: this many of those in collision before, then up to :data:`SCREEN_SPREAD` spread along the stroke.
SCREEN_QUICK = 16
SCREEN_SPREAD = 64


def _screened(arm, ordered: list, colliding: np.ndarray) -> list:
    """The candidates of ``ordered`` (``(joints (n, 6), reached (n,), track (n,), roll)``, in the order tried)
    whose waypoints are free at a few rows (:data:`SCREEN_QUICK` of the stroke's ``colliding`` waypoints, then
    :data:`SCREEN_SPREAD` spread along it), by one batched yes/no check (``ArmCollision.collides``) per round:
    a candidate dropped here would fail the full check, so the first to pass that is the same."""
    n = len(colliding)
    hit_rows = np.flatnonzero(colliding)
    quick = hit_rows[np.linspace(0, len(hit_rows) - 1, min(SCREEN_QUICK, len(hit_rows))).astype(int)]
    spread = np.unique(np.linspace(0, n - 1, min(SCREEN_SPREAD, n)).astype(int))
    for rows in (quick, spread):
        if not ordered or not len(rows):
            continue
        picked = [rows[ok[rows]] for _, ok, _, _ in ordered]
        joints = np.concatenate([qb[p] for (qb, _, _, _), p in zip(ordered, picked)])
        tracks = np.concatenate([t[p] for (_, _, t, _), p in zip(ordered, picked)])
        if not len(joints):
            continue
        hit = arm.collides(joints, tracks)
        owner = np.repeat(np.arange(len(ordered)), [len(p) for p in picked])
        bad = np.zeros(len(ordered), bool)
        bad[owner[hit]] = True
        ordered = [c for c, h in zip(ordered, bad) if not h]
    return ordered


def repaired_work(cell_robot, work, arm) -> tuple:
    """A robot's plan with its strokes in collision solved again, as a programmer would: every (track
    position, roll) try of the stroke (:func:`~sprayplan.cells.tries.stroke_tries`) and every IK branch, the branches of a try in the order of
    their first joints' distance from the joints before the stroke, keeping the first that reaches at least the
    waypoints reached before with no waypoint and no motion in collision (the motion from the joints before
    the stroke included). What no try frees stays as it was, and is flagged by the check after.

    ``work`` is the robot's ``cells.plan.RobotWork``, ``arm`` its :class:`~sprayplan.collision.arms.ArmCollision`.
    Returns the work and ``{"strokes_in_collision", "strokes_repaired"}``.
    """
    from sprayplan.collision.arms import check_robot, plan_collides
    from sprayplan.robots.interface import nearest_turns

    robot = cell_robot.robot(0.0)
    axis = np.zeros(3) if cell_robot.track is None else cell_robot.track.axis
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    q, track, roll, reach = work.q.copy(), work.track_mm.copy(), work.roll_deg.copy(), work.reachable.copy()
    flagged = repaired = 0
    for i, stroke in enumerate(work.strokes):
        a, b = starts[i], starts[i + 1]
        motions = found.motion_collides[max(a - 1, 0) : b - 1]
        if not (found.waypoint.collides[a:b].any() or motions.any()):
            continue
        flagged += 1
        before = a - 1 if a > 0 and reach[a - 1] else None
        seed = q[before] if before is not None else start_joints(robot.dof)
        need = reach[a:b].copy()
        tries = stroke_tries(cell_robot, stroke)
        poses = stroke_poses(stroke)
        blocks = []
        for t, r in tries:
            moved = poses @ rot_z(r)
            moved[:, :3, 3] -= t[:, None] * axis
            blocks.append(moved)
        sols = robot.ik(np.concatenate(blocks))
        n = b - a
        ordered = []  # (joints, reached, track, roll) in the order tried
        for k, (t, r) in enumerate(tries):
            valid = sols.valid[k * n : (k + 1) * n]  # (n, branches)
            joints = sols.q[k * n : (k + 1) * n]
            candidates = []
            for branch in range(valid.shape[1]):
                ok = valid[:, branch]
                if ok.sum() < need.sum() or not ok[need].all() or not ok.any():
                    continue
                qb = np.zeros((n, robot.dof))
                prev = seed
                for j in np.flatnonzero(ok):
                    prev = qb[j] = nearest_turns(robot, joints[j, branch], prev)
                first = qb[np.flatnonzero(ok)[0]]
                candidates.append((float(((first - seed) ** 2).sum()), branch, qb, ok))
            ordered += [(qb, ok, t, r) for _, _, qb, ok in sorted(candidates, key=lambda c: c[0])]
        lead = [] if before is None else [before]
        for qb, ok, t, r in _screened(arm, ordered, found.waypoint.collides[a:b]):
            test_q = np.concatenate([q[lead], qb])
            test_t = np.concatenate([track[lead], t])
            test_ok = np.concatenate([reach[lead], ok])
            if plan_collides(arm, test_q, test_t, test_ok):  # check_robot's answer, found for less
                continue
            q[a:b], track[a:b], reach[a:b], roll[i] = qb, t, ok, r
            repaired += 1
            break
    work = dataclasses.replace(work, q=q, track_mm=track, roll_deg=roll, reachable=reach)
    return work, {"strokes_in_collision": flagged, "strokes_repaired": repaired}
