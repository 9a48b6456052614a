"""Run-ups and run-outs of a cell robot's spray stretches (``[timing] run_up_mm``).

A stretch of a spray stroke (its consecutive waypoints the robot reaches and paints free of the body) that
starts and ends at rest has its gun slow near both ends, where it leaves more paint than the plan predicts:
on the BMW body in ``line3`` the robots took 1.34 to 1.42 times the planned time within 100 mm of a stretch's
ends, against 1.02 to 1.08 inside (``bench/bench_timed_speeds.py``, session 23), and most stretches end
inside the surface (at a seam between two areas, beside waypoints cut away in collision), not past an edge. A
painter's program runs the gun up to speed before the trigger and out after it. So every stretch gets:

- a **run-up**: the gun's pose at its first waypoint moved ``run_up_mm`` straight back along the stretch's
  first segment (the spray target's line, the orientation kept), spray off, so that the timing passes the
  first waypoint at speed;
- a **run-out**: the pose at its last waypoint moved as far on along its last segment.

Each is a straight line the arm makes on the branch of the stretch's end waypoint with the track held there
(``programs.build.line_joints``: every 5 mm within reach and limits, no joint jumping): the programs move it
with a linear move. With the collision model (``[collision] check``) the line's joints are checked against the
part and the floor (sampled at most ``MOTION_STEP_RAD`` apart, as the programs' own motions are), and, with
``[collision] repair``, the programs' approach to the run-up's start and retract from the run-out's end too
(the back-offs the collision step asks of a run's ends). Where the full length cannot be made, a half and a
quarter are tried; where none can, the end has none (and with the collision model, the run-out and run-up
either side of the programs' joint move between two runs are dropped where their back-offs put that move in
collision and the plain ends' do not: :func:`freed_junctions`) and its stretch
starts (or stops) there at rest, as without run-ups. Stretches are cut as the programs cut their runs: at
unreached waypoints and waypoints left in collision; a stretch the timing cuts at a joint jump has no run-up
or run-out at the cut (the programs move across it).

Only six-axis arms of a cell get them (the arms the programs drive; a five-axis R5150 or a gantry in a cell
makes none).
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

log = logging.getLogger(__name__)

#: The run-up's length tried: the set one, then a half and a quarter of it.
RUN_UP_TRIES = (1.0, 0.5, 0.25)
#: The largest joint step (rad) between two samples of a run-up checked for collisions.
MOTION_STEP_RAD = 0.02
#: A segment shorter than this (mm) gives no direction: its end gets no run-up.
MIN_SEGMENT_MM = 1e-6


def stretch_ends(work) -> list[tuple[int, int, int]]:
    """Every end of every stretch of ``work``'s spray strokes (runs of consecutive reached waypoints not in
    collision, at least two long): ``(waypoint, its neighbour inside the stretch, side)``, side 0 for a
    stretch's first waypoint (its run-up), 1 for its last (its run-out)."""
    ok = np.asarray(work.reachable, bool).copy()
    if work.collides is not None:
        ok &= ~np.asarray(work.collides, bool)
    out = []
    start = 0
    for s in work.strokes:
        idx = np.arange(start, start + len(s))
        start += len(s)
        if not s.spray_on:
            continue
        where = idx[ok[idx]]
        if len(where) < 2:
            continue
        for run in np.split(where, np.flatnonzero(np.diff(where) > 1) + 1):
            if len(run) >= 2:
                out.append((int(run[0]), int(run[1]), 0))
                out.append((int(run[-1]), int(run[-2]), 1))
    return out


def _line_samples(q_a: np.ndarray, q_b: np.ndarray) -> np.ndarray:
    """Joints from ``q_a`` to ``q_b`` linearly, at most :data:`MOTION_STEP_RAD` apart, both ends included."""
    steps = max(1, int(np.ceil(np.abs(q_b - q_a).max() / MOTION_STEP_RAD)))
    t = np.linspace(0.0, 1.0, steps + 1)[:, None]
    return q_a + t * (q_b - q_a)


def robot_run_ups(cell_robot, work, length_mm: float, standoff_mm: float, arm=None, backs=None):
    """``(lead_q, lead_track_mm, counts)`` of one robot's work (``RobotWork``; module docstring): the joints and
    track position where each run-up starts and each run-out ends (NaN elsewhere), and how many ends got their
    full length, a shortened one, or none. ``arm``: the robot's ``collision.arms.ArmCollision``, or None
    (not checked); ``backs(q (m, dof), track (m,)) -> (m,) bool``: whether the programs' approach or retract
    from there is free (``cells.routes.CellRouter.backs_free``), or None (not checked)."""
    from sprayplan.programs.arms import ArmCell
    from sprayplan.programs.build import line_joints

    n, dof = np.asarray(work.q).shape if work.waypoints else (0, 6)
    lead_q = np.full((n, 2, dof), np.nan)
    lead_track = np.full((n, 2), np.nan)
    counts = {"full": 0, "shortened": 0, "none": 0, "in_collision": 0, "back_off_not_free": 0}
    ends = stretch_ends(work)
    if not ends or length_mm <= 0:
        counts["none"] = len(ends)
        return lead_q, lead_track, counts
    cell = ArmCell(cell_robot, standoff_mm)
    q = np.asarray(work.q, float)
    track = np.asarray(work.track_mm, float)
    external = track[:, None] if cell.external_axes else np.zeros((n, 0))
    index = np.array([e[0] for e in ends] + [e[1] for e in ends])
    poses = cell.target_poses(np.column_stack([q[index], track[index]]) if cell.external_axes else q[index])
    here, there = poses[: len(ends)], poses[len(ends) :]
    pending = []  # (k, side, pose, direction) of the ends still to place
    for (k, _, side), pose, other in zip(ends, here, there):
        direction = pose[:3, 3] - other[:3, 3]
        norm = float(np.linalg.norm(direction))
        if norm < MIN_SEGMENT_MM:
            counts["none"] += 1
            continue
        pending.append((k, side, pose, direction / norm))
    # each length in turn for every end still without a run-up; the collision and back-off checks of all the
    # lines of a length in one call each (an end takes the first length whose line passes all three)
    for share in RUN_UP_TRIES:
        tried = []
        for entry in pending:
            k, _, pose, direction = entry
            end = pose.copy()
            end[:3, 3] += share * length_mm * direction
            got = line_joints(cell, pose, end, external[k], q[k])
            if got is not None:
                tried.append((entry, got))
        if arm is not None and tried:
            lines = [_line_samples(q[entry[0]], got) for entry, got in tried]
            tracks = np.concatenate([np.full(len(line), track[entry[0]]) for (entry, _), line in zip(tried, lines)])
            hit = arm.collides(np.concatenate(lines), tracks)
            owner = np.repeat(np.arange(len(tried)), [len(line) for line in lines])
            bad = np.zeros(len(tried), bool)
            bad[owner[hit]] = True
            counts["in_collision"] += int(bad.sum())
            tried = [t for t, b in zip(tried, bad) if not b]
        if backs is not None and tried:
            free = np.asarray(
                backs(np.array([got for _, got in tried]), np.array([track[entry[0]] for entry, _ in tried])), bool
            )
            counts["back_off_not_free"] += int((~free).sum())
            tried = [t for t, f in zip(tried, free) if f]
        placed = set()
        for (k, side, _, _), got in tried:
            counts["full" if share == 1.0 else "shortened"] += 1
            lead_q[k, side] = got
            lead_track[k, side] = track[k]
            placed.add((k, side))
        pending = [entry for entry in pending if (entry[0], entry[1]) not in placed]
    counts["none"] += len(pending)
    return lead_q, lead_track, counts


def freed_junctions(work, lead_q, router, approach_mm: float) -> tuple[np.ndarray, int]:
    """``lead_q`` without the run-out and the run-up on either side of a move between two stretches that their
    back-offs put in collision where the plain ends' did not, and how many such moves. The programs move from
    one run's retract to the next run's approach by a joint move; with run-ups those are the back-offs of the
    run-out's end and the run-up's start, which the collision step (checking the plan's transfers waypoint to
    waypoint) does not see. Checked here as ``CellRouter._edges_free`` between the states
    ``CellRouter._programs_back`` gives; moves through a routed transfer's waypoints, and ends the programs
    cannot back off from, are left to the collision step and the programs."""
    from sprayplan.programs.arms import routed_rows

    ends = stretch_ends(work)
    routed = routed_rows(work.strokes) != ""
    q, track = np.asarray(work.q, float), np.asarray(work.track_mm, float)
    lead_q = lead_q.copy()
    dropped = 0

    def free(a, qa, b, qb) -> bool | None:
        sa = router._programs_back(qa, float(track[a]), approach_mm)
        sb = router._programs_back(qb, float(track[b]), approach_mm)
        if sa is None or sb is None:
            return None
        return bool(router._edges_free(sa[None], sb[None])[0])

    for (a, _, side_a), (b, _, side_b) in zip(ends[1::2], ends[2::2]):
        if side_a != 1 or side_b != 0 or routed[a + 1 : b].any():
            continue
        has = np.isfinite(lead_q[a, 1]).all(), np.isfinite(lead_q[b, 0]).all()
        if not any(has) or free(a, lead_q[a, 1] if has[0] else q[a], b, lead_q[b, 0] if has[1] else q[b]) is not False:
            continue
        if free(a, q[a], b, q[b]):
            lead_q[a, 1] = np.nan
            lead_q[b, 0] = np.nan
            dropped += 1
    return lead_q, dropped


def with_run_ups(cell, robots: tuple, job, arms=None, part=None) -> tuple[tuple, dict]:
    """The robots' work (``RobotWork``, in the cell's order) with their run-ups and run-outs
    (:func:`robot_run_ups`; ``arms``: their collision models, or None), and the report's entry: the length and
    per robot the counts. Robots that are not six-axis arms keep none. With ``arms``, ``part`` (the painted
    surface in the cell frame) and ``[collision] repair``, a run-up's start and a run-out's end also need the
    programs' approach or retract from there free, as the collision step asks of a run's end waypoints
    (``cells.collide.freed_cell``'s back-offs). With ``arms`` the robots are worked on side by side
    (``cells.each``, ``[collision] workers``)."""
    from sprayplan.cells.each import each_robot

    length = float(job.timing.run_up_mm)
    report: dict = {"run_up_mm": length, "tries": list(RUN_UP_TRIES), "robots": {}}
    calls = [
        (_robot_leads, (cr, work, job, None if arms is None else arms[k], part))
        for k, (cr, work) in enumerate(zip(cell.robots, robots))
    ]
    workers = job.collision.workers if arms is not None else 1
    out = []
    for cr, (work, counts) in zip(cell.robots, each_robot(calls, workers, [len(w.q) for w in robots])):
        out.append(work)
        if counts is None:
            continue
        report["robots"][cr.name] = counts
        log.info(
            "run-ups of %s: %d made (%d full, %d shortened, %d none; %d tries in collision, %d without a free "
            "back-off, %d pairs dropped at moves between runs)",
            cr.name, counts["made"], counts["full"], counts["shortened"], counts["none"], counts["in_collision"],
            counts["back_off_not_free"], counts.get("dropped_at_moves_between_runs", 0),
        )  # fmt: skip
    return tuple(out), report


def _robot_leads(cr, work, job, arm, part):
    """One robot's share of :func:`with_run_ups`: its work with its run-ups and their counts (None for a robot
    that gets none)."""
    from sprayplan.cells.routes import CellRouter

    length = float(job.timing.run_up_mm)
    approach = float(job.export.approach_mm)
    if cr.is_gantry or cr.robot(0.0).dof != 6 or length <= 0:
        return work, None
    backs = router = None
    if arm is not None and part is not None and job.collision.repair and approach > 0:
        router = CellRouter(cr, arm, part, job.collision)

        def backs(q, t):
            return router.backs_free(q, t, approach)

    lead_q, lead_track, counts = robot_run_ups(cr, work, length, job.paths.standoff_mm, arm, backs)
    if router is not None:  # (full and shortened count the ends before these drops)
        lead_q, counts["dropped_at_moves_between_runs"] = freed_junctions(work, lead_q, router, approach)
        lead_track = np.where(np.isfinite(lead_q).all(axis=2), lead_track, np.nan)
    counts["made"] = int(np.isfinite(lead_q).all(axis=2).sum())
    return dataclasses.replace(work, lead_q=lead_q, lead_track_mm=lead_track), counts
