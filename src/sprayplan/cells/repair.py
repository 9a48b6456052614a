"""The repairs of a cell robot's strokes in collision (``sprayplan plan --cell ... --collisions``): every track
position and roll of the stroke (:func:`~sprayplan.cells.tries.stroke_tries`) and every IK branch, screened in
batched yes/no checks, the first free kept (:func:`repaired_work`); a run of waypoints still in collision, or
unreached, solved on its own, with the gun tilted about its targets (sideways, then forward or back) when no
untilted try reaches it free (:func:`resolved_piece`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from sprayplan.cells.tries import JOINT_JUMP_RAD, rot_z, start_joints, stroke_tries
from sprayplan.surface.poses import stroke_poses

#: The waypoints of a stroke at which every repair candidate is screened before any is checked in full: up to
#: this many of those in collision before, then up to :data:`SCREEN_SPREAD` spread along the stroke.
SCREEN_QUICK = 16
SCREEN_SPREAD = 64


def piece_tilts(max_deg: float) -> tuple:
    """The tilts of the gun tried for a piece in collision that no untilted try frees (``[collision]
    piece_tilt_deg``), ``(across, degrees)`` in the order tried: half of ``max_deg`` and all of it, either way,
    sideways (about the direction of travel), then leaning forward or back (about the axis across it;
    ``refine.touchup.tilted``: the targets stay, the gun moves round them at the standoff); () for 0. On the BMW
    in ``line3`` (40 degrees) the sideways tilts left 231 of the 350 spray waypoints of the planned strokes in
    collision, with the leaning ones 153; tilts of 60 degrees sideways freed none more
    (``bench/bench_piece_tilts.py``)."""
    if max_deg <= 0:
        return ()
    return tuple((across, a) for across in (False, True) for a in (max_deg / 2, -max_deg / 2, max_deg, -max_deg))


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


def _candidates(cell_robot, robot, stroke, seed: np.ndarray, need: np.ndarray, smooth: bool = False) -> list:
    """Every (track position, roll) try of ``stroke`` (:func:`~sprayplan.cells.tries.stroke_tries`) and every
    IK branch that reaches at least the waypoints ``need`` (and as many), each followed from ``seed`` by whole
    turns: ``(joints (n, dof), reached (n,), track (n,), roll)``, in the order tried: those with no joint
    jumping by more than :data:`~sprayplan.cells.tries.JOINT_JUMP_RAD` from ``seed`` to their first waypoint
    or between two of their waypoints first, then those that jump only from ``seed``, then the rest; within
    each, the tries in their order and the branches of a try by their first joints' distance from ``seed``.

    ``smooth``: only the first kind (no jump from ``seed``, none along), nearest ``seed`` first (the largest joint
    step from it), whatever the try (:func:`rescued_run`).

    A repair that keeps a try turning the arm over from the joints before it (the first free one, whatever
    its branch) leaves a transfer that the programs' retract and approach make through the part and that no
    route frees, and its run is dropped: over the SUV's roof in ``line3`` (session 27) the roof robot's 98
    runs dropped were such transfers, median largest joint turn 220 deg, the forearm, wrist and gun meeting the
    roof (``bench/bench_robot_step.py``)."""
    from sprayplan.robots.interface import nearest_turns

    axis = np.zeros(3) if cell_robot.track is None else cell_robot.track.axis
    tries = stroke_tries(cell_robot, stroke)
    poses = stroke_poses(stroke)
    blocks = []
    for t, r in tries:
        moved = poses @ rot_z(r)
        moved[:, :3, 3] -= t[:, None] * axis
        blocks.append(moved)
    sols = robot.ik(np.concatenate(blocks))
    n = len(stroke)
    ordered = []
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
            start = qb[np.flatnonzero(ok)[0]]
            along = qb[ok]
            jumps = len(along) > 1 and np.abs(np.diff(along, axis=0)).max() > JOINT_JUMP_RAD
            rank = 2 if jumps else int(np.abs(start - seed).max() > JOINT_JUMP_RAD)
            if smooth and rank:
                continue
            key = float(np.abs(start - seed).max()) if smooth else float(((start - seed) ** 2).sum())
            candidates.append((key, branch, qb, ok, rank))
        ordered += [
            (key if smooth else k, rank, (qb, ok, t, r))
            for key, _, qb, ok, rank in sorted(candidates, key=lambda c: c[0])
        ]
    return [c for _, _, c in sorted(ordered, key=lambda c: (c[1], c[0]))]


def resolved_piece(cell_robot, arm, piece, seed: np.ndarray, standoff_mm: float = 0.0, tilts: tuple = ()):
    """A piece of a stroke (a run of its waypoints in collision or unreached, with a free waypoint either side
    where there is one) solved on its own: the first (track position, roll) try and IK branch (:func:`_candidates`, from
    ``seed``) that reaches every waypoint with no waypoint and no motion in collision; failing that, the same
    for the piece with its gun tilted by each of ``tilts`` (:func:`piece_tilts`) in turn at ``standoff_mm`` (the
    plan's), sideways or along the travel (near a mirror or in a recess the gun leans away from what it would
    touch, and still aims at the same targets). ``(joints, track, roll_deg, piece)`` (the piece as painted,
    tilted or not) or None."""
    from sprayplan.collision.arms import plan_collides
    from sprayplan.refine.touchup import tilted

    robot = cell_robot.robot(0.0)
    need = np.ones(len(piece), bool)
    for across, angle in ((False, 0.0), *tilts):
        aimed = tilted(piece, angle, standoff_mm, across) if angle else piece
        if angle and aimed is piece:  # a piece without a direction of travel does not tilt
            break
        ordered = _candidates(cell_robot, robot, aimed, seed, need)
        for qb, ok, t, r in _screened(arm, ordered, need):
            if not plan_collides(arm, qb, t, ok):
                return qb, t, r, aimed
    return None


def rescued_run(cell_robot, arm, run, seed: np.ndarray, backs=None):
    """A spray run solved again continuous with the run before it, ahead of being dropped
    (``cells.collide.dropped_unrouted``: the transfer into it, or out of it, is one no route frees): the
    candidates of :func:`_candidates` with ``smooth`` (no joint jumping by more than
    :data:`~sprayplan.cells.tries.JOINT_JUMP_RAD` from ``seed``, the joints at the end of the run before, nor
    along the run; nearest ``seed`` first, whatever the try) that reach every waypoint with no waypoint and no
    motion in collision and, with ``backs(q (m, dof), track (m,)) -> (m,) bool``
    (``cells.routes.CellRouter.backs_free``), the programs' approach at its first waypoint and retract at its
    last free. ``(joints (n, dof), track (n,), roll_deg)`` or None.

    Each run is solved on its own by the repairs (:func:`repaired_work`, :func:`resolved_piece`: the first free
    try, in the try order), and a try that suits the run may leave the arm turned over from where the run before
    ended (over the SUV's roof in ``line3`` the transfers no route frees turned a joint by 220 deg, median,
    ``bench/bench_robot_step.py``): the transfer then sweeps the arm through the body whatever the route."""
    from sprayplan.collision.arms import plan_collides

    robot = cell_robot.robot(0.0)
    need = np.ones(len(run), bool)
    ordered = _candidates(cell_robot, robot, run, seed, need, smooth=True)
    for qb, ok, t, r in _screened(arm, ordered, need):
        if plan_collides(arm, qb, t, ok):
            continue
        if backs is not None and not backs(qb[[0, -1]], t[[0, -1]]).all():
            continue
        return qb, t, float(r)
    return None


def repaired_work(cell_robot, work, arm) -> tuple:
    """A robot's plan with its strokes in collision solved again, as a programmer would: every (track
    position, roll) try of the stroke (:func:`~sprayplan.cells.tries.stroke_tries`) and every IK branch, in the
    order of :func:`_candidates` (those that do not turn the arm over from the joints before the stroke
    first), keeping the first that reaches at least the waypoints reached before with no waypoint and no
    motion in collision.

    The transfers are joined to their neighbours (``cells.work.joined_transfers``): a transfer is the joint move
    from the end of one spray stroke to the start of the next, so it belongs to the stroke after it. A stroke is
    flagged when its waypoints, its motions or the transfer before it collide; a try is checked from the joints
    before that transfer, and through the transfer after it where that was free before (a repair does not move
    a collision to the next transfer); the transfers' ends follow the kept try. Transfers are not solved again
    on their own: that would turn the arm over in place at their ends. What no try frees stays as it was, and
    is flagged by the check after.

    ``work`` is the robot's ``cells.work.RobotWork``, ``arm`` its :class:`~sprayplan.collision.arms.ArmCollision`.
    Returns the work and ``{"strokes_in_collision", "strokes_repaired"}``.
    """
    from sprayplan.cells.work import joined_transfers
    from sprayplan.collision.arms import check_robot, plan_collides

    robot = cell_robot.robot(0.0)
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    q, track, roll, reach = work.q.copy(), work.track_mm.copy(), work.roll_deg.copy(), work.reachable.copy()
    flagged = repaired = 0
    strokes = work.strokes
    for i, stroke in enumerate(strokes):
        if not stroke.spray_on:
            continue
        a, b = starts[i], starts[i + 1]
        joined_before = i > 0 and not strokes[i - 1].spray_on
        first = max(a - 2 if joined_before else a - 1, 0)  # the first motion this stroke answers for
        if not (found.waypoint.collides[a:b].any() or found.motion_collides[first : b - 1].any()):
            continue
        flagged += 1
        before = first if a > 0 and reach[first] else None
        seed = q[before] if before is not None else start_joints(robot.dof)
        need = reach[a:b].copy()
        after = None  # the start of the stroke after the transfer after this one, where that transfer was free
        if i + 2 < len(strokes) and not strokes[i + 1].spray_on and reach[b + 1]:
            if not found.motion_collides[b : b + 1].any():
                after = b + 1
        ordered = _candidates(cell_robot, robot, stroke, seed, need)
        lead = [] if before is None else [before]
        trail = [] if after is None else [after]
        for qb, ok, t, r in _screened(arm, ordered, found.waypoint.collides[a:b]):
            test_q = np.concatenate([q[lead], qb, q[trail]])
            test_t = np.concatenate([track[lead], t, track[trail]])
            test_ok = np.concatenate([reach[lead], ok, reach[trail]])
            if plan_collides(arm, test_q, test_t, test_ok):  # check_robot's answer, found for less
                continue
            q[a:b], track[a:b], reach[a:b], roll[a:b] = qb, t, ok, r
            ends = [(a - 1, a)] if joined_before else []  # the transfers' ends follow (joined_transfers)
            if i + 1 < len(strokes) and not strokes[i + 1].spray_on:
                ends.append((b, b - 1))
            for mine, theirs in ends:
                if reach[theirs]:
                    q[mine], track[mine], roll[mine], reach[mine] = q[theirs], track[theirs], roll[theirs], True
            repaired += 1
            break
    work = joined_transfers(dataclasses.replace(work, q=q, track_mm=track, roll_deg=roll, reachable=reach))
    return work, {"strokes_in_collision": flagged, "strokes_repaired": repaired}


#: A piece in collision that no try frees whole is tried again in halves (sharing their middle waypoint), and
#: those in halves, down to this many levels (:func:`free_work`)...
SPLIT_DEPTH = 2
#: ... and halves of at least this many waypoints.
SPLIT_MIN = 3

#: The waypoints at each end of a run whose back-off is checked first (:func:`free_work`'s ``backs``); the rest
#: only when none of those is free.
END_PROBE = 4


def _approachable(runs: list, backs, work, a: int) -> tuple[list, int]:
    """The runs ``(s, e, solved)`` of a stroke (waypoints ``a + s .. a + e - 1`` of ``work``, or ``solved``'s
    joints and piece) each cut to run from its first to its last waypoint at which ``backs(q, track)`` holds
    (the programs' approach and retract there free), runs of fewer than two left out; and how many waypoints
    were cut. The :data:`END_PROBE` waypoints at each end are checked first, the rest only when needed."""
    out, cut = [], 0
    for s, e, solved in runs:
        n = e - s
        q, t = (work.q[a + s : a + e], work.track_mm[a + s : a + e]) if solved is None else solved[:2]
        k = min(END_PROBE, n)
        head, tail = np.arange(k), np.arange(n - k, n)
        rows = np.unique(np.r_[head, tail])
        ok = np.zeros(n, bool)
        ok[rows] = backs(q[rows], t[rows])
        if not (ok[head].any() and ok[tail].any()):
            rest = np.setdiff1d(np.arange(n), rows)
            if len(rest):
                ok[rest] = backs(q[rest], t[rest])
        hits = np.flatnonzero(ok)
        if len(hits) < 2:
            cut += n
            continue
        lo, hi = int(hits[0]), int(hits[-1]) + 1
        cut += n - (hi - lo)
        if solved is not None and (lo, hi) != (0, n):
            from sprayplan.cells.seams import cut_stroke

            solved = (solved[0][lo:hi], solved[1][lo:hi], solved[2], cut_stroke(solved[3], lo, hi))
        out.append((s + lo, s + hi, solved))
    return out, cut


def free_work(work, found, resolve=None, backs=None, since: int = 0) -> tuple:
    """A robot's plan cut to what it can paint free of the part and the floor (``--collisions``): every spray
    stroke cut to its runs of waypoints that are reached, free (``found``: the robot's
    :class:`~sprayplan.collision.arms.RobotCollisions`) and joined by free motions, runs of one waypoint left
    out (they spray nothing), and the runs joined again by transfers, each the one joint move from the end of a
    run to the start of the next (``cells.work.joined_transfers``); a transfer between two strokes kept whole
    stays as it was (a route ``cells.routes`` gave it included).

    With ``resolve(piece, seed) -> (joints, track, roll_deg, piece) or None`` (:func:`resolved_piece`), each run
    of waypoints in collision or unreached is first solved again on its own, with a free waypoint either side
    where there is one (so that the spray goes on without a gap), from the joints of the last reached waypoint
    before it: the stroke is then painted in pieces, each with its
    own track position, roll and branch (and the piece as returned: its gun tilted, if it had to be), joined
    by transfers. A stroke's one try must suit all of it; a run near a mirror or in a recess often has a try of
    its own that is free. A piece no try frees whole is tried in halves (sharing their middle waypoint), down
    to :data:`SPLIT_DEPTH` levels: one try seldom suits a long piece round a mirror, a shorter one may.

    A waypoint in collision or unreached is not painted through, as a programmer leaves out what the arm cannot
    reach or cannot reach without touching the body: the robot's programs leave such waypoints out with the gun
    off, so the film is predicted without them, and the move over them (which a program makes as one motion)
    is a transfer of the plan, checked like any other.

    With ``backs(q (m, dof), track (m,)) -> (m,) bool`` (``cells.routes.CellRouter.backs_free``: the programs'
    approach or retract line there free), each run of the strokes from ``since`` on is then cut to start and
    end where the gun backs off free, as the programs start and end a run with an approach and a retract line:
    a run end whose retract would meet the body is not painted (counted as ``"left_out_unapproachable"``).

    Returns the work (``collides`` None: not checked yet)
    and the counts of the spray waypoints left out: ``{"left_out_in_collision", "left_out_unreached",
    "left_out_alone"}`` (the last: free and reached, but alone between others left out), and with ``resolve``
    ``"pieces_resolved"``, ``"waypoints_resolved"`` and ``"pieces_tilted"``.
    """
    from sprayplan.cells.seams import cut_stroke
    from sprayplan.cells.work import RobotWork, transfer_stroke

    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    free = work.reachable & ~found.waypoint.collides
    # the last reached waypoint at or before each one (-1: none), the joints an unreached run is solved from
    last_reached = np.maximum.accumulate(np.where(work.reachable, np.arange(len(free)), -1)) if len(free) else free
    counts = {"left_out_in_collision": 0, "left_out_unreached": 0, "left_out_alone": 0}
    if backs is not None:
        counts["left_out_unapproachable"] = 0
    if resolve is not None:
        counts.update(pieces_resolved=0, waypoints_resolved=0, pieces_tilted=0)
    strokes, area, arrays = [], [], []  # arrays: (joints, track, roll) of each stroke's waypoints
    whole = -1  # the stroke the last run kept is, when it kept the whole of it as it was
    for i, stroke in enumerate(work.strokes):
        if not stroke.spray_on:
            continue
        a, b = starts[i], starts[i + 1]
        n = b - a
        ok = free[a:b]
        joins = ok[:-1] & ok[1:] & ~found.motion_collides[a : b - 1]  # a free motion between two free waypoints
        edges = np.flatnonzero(np.diff(np.r_[0, joins.astype(np.int8), 0]))
        runs = [(int(s), int(e) + 1, None) for s, e in zip(edges[::2], edges[1::2])]  # waypoints s .. e
        covered = np.zeros(n, bool)
        for s, e, _ in runs:
            covered[s:e] = True
        if resolve is not None:
            edges = np.flatnonzero(np.diff(np.r_[0, (~ok).astype(np.int8), 0]))
            for s, e in zip(edges[::2], edges[1::2]):
                lo, hi = max(int(s) - 1, 0), min(int(e) + 1, n)
                if hi - lo < 2:
                    continue
                pending = [(lo, hi, SPLIT_DEPTH)]
                while pending:
                    lo, hi, depth = pending.pop(0)
                    k = last_reached[a + lo]  # the piece's first waypoint where reached (the run's free neighbour)
                    seed = work.q[k] if k >= 0 else start_joints(work.q.shape[1])
                    cut = cut_stroke(stroke, lo, hi)
                    solved = resolve(cut, seed)
                    if solved is None:
                        if depth > 0 and hi - lo >= 2 * SPLIT_MIN:  # halves sharing their middle waypoint
                            mid = (lo + hi) // 2
                            pending += [(lo, mid + 1, depth - 1), (mid, hi, depth - 1)]
                        continue
                    runs.append((lo, hi, solved))
                    counts["pieces_resolved"] += 1
                    counts["pieces_tilted"] += int(solved[3] is not cut)
                    counts["waypoints_resolved"] += int((~ok[lo:hi] & ~covered[lo:hi]).sum())
                    covered[lo:hi] = True
            runs.sort(key=lambda run: (run[0], run[1]))
        counts["left_out_in_collision"] += int((work.reachable[a:b] & ~ok & ~covered).sum())
        counts["left_out_unreached"] += int((~work.reachable[a:b] & ~covered).sum())
        counts["left_out_alone"] += int((ok & ~covered).sum())
        if backs is not None and i >= since:
            runs, cut = _approachable(runs, backs, work, a)
            counts["left_out_unapproachable"] += cut
        for s, e, solved in runs:
            as_was = solved is None and (s, e) == (0, n)  # the whole stroke, as it was solved
            if solved is None:
                rows = np.arange(a + s, a + e)
                piece = cut_stroke(stroke, s, e)
                solved = (work.q[rows], work.track_mm[rows], work.roll_deg[rows])
            else:
                piece = solved[3]
                solved = (solved[0], solved[1], np.full(e - s, float(solved[2])))
            if strokes:
                kept = whole == i - 2 and as_was and not work.strokes[i - 1].spray_on
                if kept:  # the transfer between two strokes kept whole stays as it was (a route too)
                    rows = np.arange(starts[i - 1], starts[i])
                    strokes.append(work.strokes[i - 1])
                    arrays.append((work.q[rows], work.track_mm[rows], work.roll_deg[rows]))
                else:
                    strokes.append(transfer_stroke(strokes[-1], piece))
                    arrays.append(tuple(np.stack([x[-1], y[0]]) for x, y in zip(arrays[-1], solved)))
                area.append(-1)
            whole = i if as_was else -1
            strokes.append(piece)
            area.append(int(work.area[i]))
            arrays.append(solved)
    dof = work.q.shape[1]
    freed = RobotWork(
        name=work.name,
        model=work.model,
        strokes=tuple(strokes),
        area=np.array(area, dtype=np.int64),
        track_mm=np.concatenate([x[1] for x in arrays]) if arrays else np.zeros(0),
        roll_deg=np.concatenate([x[2] for x in arrays]) if arrays else np.zeros(0),
        q=np.concatenate([np.reshape(x[0], (-1, dof)) for x in arrays]) if arrays else np.zeros((0, dof)),
        reachable=np.ones(sum(len(s) for s in strokes), bool),
    )
    return freed, counts
