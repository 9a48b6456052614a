"""The robots of a line painting at the same time, kept apart in time (issue 18, section 3: "say how their work
zones are kept apart in time or space so that two arms never meet, and check it with the collision model").

Every face has one robot, but the spaces the arms sweep overlap where their areas meet (the roof robot's arm
over the upper edge of a side while the side robot paints below it; ``cells.collide``'s ``robot_gap_mm``), so
keeping them apart in space alone is not proven. :func:`schedule_cell` keeps them apart in time:

1. **Each robot's timeline** is its timing within its axes' limits (:mod:`~sprayplan.cells.timing`, with
   ``[timing] enabled``, the default), or else the plan's own timing, path length over speed
   (:meth:`RobotWork.cycle_time_s`'s rule): a spray segment at ``[motion] gun_speed_mm_s`` divided by its time
   factor, a transfer at ``transfer_speed_mm_s``, but no step faster than the arm's axis speeds (the maker's,
   ``robots.opw``) and the track's speed allow for its largest joint or track move; the joints and the track
   move linearly between waypoints. An unreached waypoint (no joints) holds the last reached configuration (the first reached one
   before any). A stretch's run-up and run-out (``cells.runups``) are rows of the timeline too, at the timing's
   times (:func:`with_leads`): the robot is at the run-up's start before its first waypoint, and a wait before
   a stroke that begins with a run-up is held there.
2. **Priority by the length of the work** (:func:`scheduled`): the robot whose timeline (step 1, no waits) is
   longest goes first and never waits, then the next longest, and so on (ties in the cell's order): every wait
   adds to the robot that waits, so the robots with the most slack to the cycle wait. (On the BMW in
   ``line3`` the roof robot, whose work is half as long as a side robot's, went first until session 14 (the
   cell's order): the side robots then waited out its routed transfers, the right one 223 s before a stroke
   70 strokes back, cycle 1,549.8 s, the schedule 370 s of work; with the sides first the roof robot waits
   63 s over 13 strokes, the right one 0.5 s, the cycle is 1,459.2 s (the left robot's own time: no schedule
   of these timelines is shorter), the schedule 2.6 s, and no sample is too close either way.)
   :func:`schedule_cell` takes any order (``priority``). Each later
   robot is scheduled against the timelines of the robots before it, stroke by stroke: before a stroke starts
   it may wait at the stroke's first waypoint, spray off (never in the middle of a stroke, where a stop would
   spoil the film), for the least whole number of ``WAIT_STEP_S`` that makes the wait and the stroke free of
   every robot before it. A robot that has finished holds its park (below); one that has not started holds
   its first waypoint, unless no wait there frees its first stroke (it would meet an earlier robot where both
   start): then it starts **parked** (:func:`park_joints` near its first waypoint), waits there, and its
   first move is the approach to its work. If no wait before a stroke frees it, a wait before each of the
   ``BACKTRACK`` strokes before it is tried, then before strokes ever farther back (each ``BACKTRACK_GROWTH``
   times farther, back to the first), then before every stroke between (:func:`_backtrack`), the strokes
   between moved with it: where an earlier robot's transfer sweeps through the place where this one would
   hold, it must be made to arrive there later. On the BMW in ``line3`` with the roof robot first (session 13)
   its routed transfers left 49 samples too close with six strokes back, 31 with the strokes far back tried
   sparsely, none with every stroke back tried (the right robot then waited 223 s before a stroke 70 strokes
   before the one in the way; with the longest work first no wait needs to go back). If none up to
   ``MAX_WAIT_S`` frees it, it is not delayed and its conflict is counted (data, as a
   collision is).
   When a robot has done its work it **parks** (:func:`park_joints`): a joint move, at its axis speeds, to the
   configuration of a small set (axis 1 turned 0, 90, -90 or 180 degrees, axes 2 and 3 folded back) farthest
   from the part, the floor and the other robots' work whose move there is free of the part and the floor, at
   its last track position or at either end of its track (the track at its speed, with the joints); of parks
   as far away, the one reached soonest. So a robot that has finished stands out of the way of one still
   painting: on the BMW in ``line3`` the roof robot, parked at its last track position, stood over the part
   of the body the left robot still painted (47 samples too close), and a track end frees it. A robot
   scheduled after others takes the first of its parks (in that order, up to :data:`PARK_TRIES`) whose move
   and hold, to the end of the earlier robots' work, keep clear of them in time (:func:`_park_clear`): on the
   BMW with the reach check's tilted tries (session 15) the roof robot's first park stood in the way of a
   transfer the right robot made 186 s after the roof robot had finished (12 samples too close), the next one
   is clear. The move to the park starts where the program's does, at the retract from the last waypoint
   (``backs``); where no park's joint move from there is free (:func:`move_free`: on session 26's BMW plan
   the right robot ended at the sill with its wrist under the body, and every park's move hit the side; its
   program's last move was in collision), the robot goes there through a route (``routers``,
   ``cells.routes.CellRouter.park_route``), the programs with it. The whole way (the retract, the route's
   nodes, the move, :func:`_park_way`) is what is checked against the earlier robots; where no park's way is
   clear when the work ends, the robot waits before one of its last strokes (:func:`_end_wait`) until the
   strokes after the wait, the way and the hold are clear together, for the first park that such a wait
   frees (on the SUV's plan of session 27 the roof robot's retract and park move, at the right robot's side,
   came within 8 mm of it: 6 samples too close; a wait of 0.5 s before its last stroke frees them).
3. **The check** samples the common time axis every ``DT_S`` and measures, at every sample, the least distance
   between any capsule of one robot and any capsule of the other (:func:`segment_distances`, exact for segments;
   the arms' own capsules, ``collision.arms``). Two robots may conflict where that distance is below the sum of
   the two radii, the ``[collision] clearance_mm``, and how far either robot's capsule ends move in the sampling
   intervals on both sides of the sample (so a touch between two samples cannot hide: no body point moves
   farther than its ends do under the linear joint motion within ``DT_S``, to within the curvature of a
   sub-``DT_S`` arc). The final count samples each such place again ``REFINE`` times finer, with the finer
   motion bounds, and counts the sample as a conflict only if that does not prove the clearance.

The result is data: each robot's waypoint times (``t_s``, the arrival) and each stroke's wait; the least
distance between every two robots over the scheduled cycle, the conflicts left, and the cell's cycle time,
the longest robot's with its waits.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

#: The time axis's sampling, s.
DT_S = 0.05
#: Waits are whole numbers of this, s.
WAIT_STEP_S = 0.5
#: The longest wait tried before a stroke, s.
MAX_WAIT_S = 600.0
#: A block's samples are checked this many at a time (:func:`_wait_for`: a wait is refused at its first chunk
#: too close).
WAIT_CHUNK = 64
#: How many strokes back a wait is tried, stroke by stroke, when none before the stroke itself frees it.
BACKTRACK = 6
#: Past those, the strokes back tried grow this much each time (:func:`_backtrack`).
BACKTRACK_GROWTH = 1.5


def _backtrack(j: int, first: int = 0) -> list[int]:
    """The strokes before which a wait is tried to free stroke ``j``, in order: ``j`` and the :data:`BACKTRACK`
    strokes before it, then ``j - d`` for ``d`` growing by :data:`BACKTRACK_GROWTH` (at least one stroke each
    time) down to ``first`` (the first stroke a wait may go before), then every stroke skipped, nearest first
    (a long block is dear to check, so the far strokes are tried sparsely first)."""
    out = list(range(j, max(first - 1, j - BACKTRACK - 1), -1))
    d = float(BACKTRACK)
    while out[-1] > first:
        d = max(d * BACKTRACK_GROWTH, d + 1.0)
        out.append(max(first, j - int(d)))
    tried = set(out)
    return out + [i for i in range(j, first - 1, -1) if i not in tried]


#: The park configurations tried at the end of a robot's work: axes 1, 2 and 3 (degrees), the wrist bent 30.
PARK_AXIS1_DEG = (0.0, 90.0, -90.0, 180.0)
PARK_AXIS2_DEG = (-60.0, -30.0, 0.0)
PARK_AXIS3_DEG = (-60.0, -30.0, 0.0)
#: A park move takes at least this long, s.
MIN_PARK_S = 0.5
#: Configurations checked along a park move.
PARK_STEPS = 40


def segment_distances(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """The least distances between segments ``p1-q1`` and ``p2-q2`` (arrays (..., 3) broadcast together), mm.

    The closest points minimise ``|p1 + s d1 - p2 - t d2|`` over ``s, t`` in [0, 1]: the unconstrained ``s``
    clamped, ``t`` for it clamped, then ``s`` again for the clamped ``t`` (exact for the convex problem; zero
    length segments are points)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("...i,...i->...", d1, d1)
    e = np.einsum("...i,...i->...", d2, d2)
    b = np.einsum("...i,...i->...", d1, d2)
    c = np.einsum("...i,...i->...", d1, r)
    f = np.einsum("...i,...i->...", d2, r)
    tiny = 1e-12
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(denom > tiny * np.maximum(a * e, tiny), np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        t = np.where(e > tiny, np.clip((b * s + f) / e, 0.0, 1.0), 0.0)
        s = np.where(a > tiny, np.clip((b * t - c) / a, 0.0, 1.0), 0.0)
    gap = r + d1 * s[..., None] - d2 * t[..., None]
    return np.sqrt(np.einsum("...i,...i->...", gap, gap))


def waypoint_times(
    work, speed_mm_s: float, transfer_speed_mm_s: float, max_speed=None, track_speed_mm_s: float | None = None
) -> np.ndarray:
    """(n,) s: when a robot reaches each waypoint of its plan without waits (module docstring, step 1).

    With the arm's axis speeds ``max_speed`` (rad/s, NaN where unknown) and the track's speed, a step takes at
    least as long as its largest joint or track move needs at those speeds (a change of branch between two
    strokes, a fast track move): the path's own speed alone would have it happen in no time."""
    dt = []
    for s in work.strokes:
        seg = np.linalg.norm(np.diff(s.tcp, axis=0), axis=1)
        if s.spray_on:
            dt.append(seg * (s.dwell[:-1] + s.dwell[1:]) / 2.0 / speed_mm_s)
        else:
            dt.append(seg / transfer_speed_mm_s)
        dt.append(np.zeros(1))  # from one stroke's last waypoint to the next's first (the same point)
    if not dt:
        return np.zeros(0)
    steps = np.concatenate(dt)[:-1]
    q, track = _held(np.asarray(work.q, dtype=float), np.asarray(work.track_mm, dtype=float), work.reachable)
    if max_speed is not None and len(q) > 1:
        speed = np.asarray(max_speed, dtype=float)
        known = np.isfinite(speed)
        if known.any():
            steps = np.maximum(steps, (np.abs(np.diff(q[:, known], axis=0)) / speed[known]).max(axis=1))
    if track_speed_mm_s and len(track) > 1:
        steps = np.maximum(steps, np.abs(np.diff(track)) / track_speed_mm_s)
    return np.r_[0.0, np.cumsum(steps)]


#: A park's gap to the other robots' work counts up to this much, mm: past it a park with a shorter move is as
#: good (:func:`park_joints`).
PARK_GAP_ENOUGH_MM = 1000.0
#: Parks whose gaps differ by less than this are ranked by their move's time, mm.
PARK_GAP_STEP_MM = 10.0


def park_joints(
    arm, q_last: np.ndarray, track_mm: float, away: np.ndarray | None = None, track_range=None, track_speed=None
) -> tuple[np.ndarray, float]:
    """The park of a robot whose last configuration is ``q_last`` at ``track_mm``: joints and track position
    (the first of :func:`park_candidates`)."""
    return next(park_candidates(arm, q_last, track_mm, away, track_range, track_speed))


def park_candidates(
    arm, q_last: np.ndarray, track_mm: float, away: np.ndarray | None = None, track_range=None, track_speed=None
):
    """The parks of a robot whose last configuration is ``q_last`` at ``track_mm``, ``(joints, track position)``
    in the order preferred (a generator: each move is checked only when the one before was not taken).

    Of the candidates (module docstring, within the joint limits; axes 4-6 as ``q_last`` but the wrist bent 30
    degrees) at ``track_mm``, and with ``track_range`` (lo, hi mm) at both ends of the track too, the one with
    the largest slack to the part and the floor (``arm.check``) whose move from ``q_last`` (joints and track
    linear together) is free of them too (checked at least every ``PARK_STEPS``-th of the move and every 25 mm
    of track); the largest slack if no move is. ``away`` (m, 4): points of the other robots' work with a
    radius each (their capsules' ends along their plans, :func:`work_points`): the slack is then the least of
    the slack to the part and the gap to those, so that a robot does not park in another's way. Slacks count
    up to :data:`PARK_GAP_ENOUGH_MM`, in steps of :data:`PARK_GAP_STEP_MM`; of equal ones the park reached
    soonest (:func:`_move_s`, with ``track_speed`` mm/s) is taken, the last track position first. The parks
    whose moves are free come in that order; if none is, only the one of the largest slack."""
    lower, upper = np.asarray(arm.params.lower, dtype=float), np.asarray(arm.params.upper, dtype=float)
    q_last = np.asarray(q_last, dtype=float)
    rows = []
    for a1, a2, a3 in itertools.product(PARK_AXIS1_DEG, PARK_AXIS2_DEG, PARK_AXIS3_DEG):
        q = np.array(q_last, dtype=float)
        q[:3] = np.radians([a1, a2, a3])
        q[4] = math.radians(30.0)
        if np.all(q >= lower - 1e-12) and np.all(q <= upper + 1e-12):
            rows.append(q)
    if not rows:
        yield q_last, float(track_mm)
        return
    tracks = [float(track_mm)]
    if track_range is not None:
        tracks += [float(t) for t in track_range if abs(float(t) - float(track_mm)) > 1e-9]
    rows = np.concatenate([rows] * len(tracks))
    where = np.repeat(tracks, len(rows) // len(tracks))
    slack = arm.check(rows, where).slack_mm
    if away is not None and len(away):
        from scipy.spatial import cKDTree

        segments = arm.segments(rows, where)  # (c, b, 2, 3)
        t = np.linspace(0.0, 1.0, 5)[None, None, :, None]
        points = segments[:, :, :1] + t * (segments[:, :, 1:] - segments[:, :, :1])  # (c, b, 5, 3)
        d, k = cKDTree(away[:, :3]).query(points.reshape(-1, 3))
        radii = np.broadcast_to(np.asarray(arm.radii, float)[None, :, None], points.shape[:3]).reshape(-1)
        gap = (d - away[k, 3] - radii).reshape(len(rows), -1).min(axis=1)
        slack = np.minimum(slack, gap)
    level = np.floor(np.minimum(slack, PARK_GAP_ENOUGH_MM) / PARK_GAP_STEP_MM)
    seconds = np.array([_move_s(arm, q_last, r, float(track_mm), float(w), track_speed) for r, w in zip(rows, where)])
    order = np.lexsort((seconds, -level))
    found = False
    for i in order:
        steps = max(PARK_STEPS, math.ceil(abs(where[i] - float(track_mm)) / 25.0) + 1)
        s = np.linspace(0.0, 1.0, steps)[:, None]
        if not arm.collides(q_last + s * (rows[i] - q_last), float(track_mm) + s[:, 0] * (where[i] - track_mm)).any():
            found = True
            yield rows[i], float(where[i])
    if not found:
        yield rows[order[0]], float(where[order[0]])


#: A robot scheduled after others tries at most this many parks (:func:`park_candidates`, in order) for one
#: whose move and hold are clear of the earlier robots (:func:`_park_clear`), else it takes the first.
PARK_TRIES = 12


def _park_clear(arm, times, q, track, earlier, horizon_s: float, clearance_mm: float) -> bool:
    """Whether a robot's way to its park (knots: ``times`` (m,) s, ``q`` (m, dof), ``track`` (m,) mm, the joints
    and the track linear between them: the retract, a route's nodes, the park last) and its hold at the park
    up to ``horizon_s`` (when the earlier robots are done) keep clear of every ``earlier`` robot (``_Sampled``)
    at the grid samples, with the motion bounds."""
    times, q, track = np.asarray(times, float), np.asarray(q, float), np.asarray(track, float)
    g = _grid(times[0], times[-1])
    if len(g):
        move = _Sampled.of(arm, *_configs(g * DT_S, times, q, track), first=int(g[0]))
        rows = np.arange(len(g))
        if any((_gaps(move, rows, other, other.rows(g), clearance_mm) < 0).any() for other in earlier):
            return False
    g = _grid(times[-1], horizon_s)
    if len(g):
        hold = _Sampled.of(arm, q[-1:], track[-1:])
        zero = np.zeros(len(g), dtype=int)
        for other in earlier:
            for c in range(0, len(g), 4096):
                part = g[c : c + 4096]
                if (_gaps(hold, zero[: len(part)], other, other.rows(part), clearance_mm) < 0).any():
                    return False
    return True


def _park_way(arm, q_end, track_end: float, back, park, at: float, track_speed, router):
    """A robot's way from its last timeline row (``q_end`` at ``track_end``) to a park (``park`` at ``at``), as
    its program makes it: the retract along the gun axis (``back``, :func:`_backed`), then a joint move to the
    park, or where that move is not free (:func:`move_free`) and ``router`` finds a way, the route's nodes
    (``CellRouter.park_route``) each reached by a joint move. Returns the knots after ``q_end`` (offsets from
    its time, s (m,); joints (m, dof); track (m,) mm; the park last) and the route (nodes, tracks) or None."""
    last, retract_s = _backed(back, q_end, track_end)
    offsets, qs, tracks = ([retract_s], [last], [track_end]) if retract_s > 0 else ([], [], [])
    route = None
    if router is not None and not move_free(arm, last, park, track_end, at):
        found = router.park_route(last, track_end, park, at)
        if found is not None:
            route = found[1:]
    legs_q = [last, *([] if route is None else route[0]), park]
    legs_t = [track_end, *([] if route is None else route[1]), at]
    clock = retract_s
    for j in range(1, len(legs_q)):
        clock += _move_s(arm, legs_q[j - 1], legs_q[j], legs_t[j - 1], legs_t[j], track_speed)
        offsets.append(clock)
        qs.append(legs_q[j])
        tracks.append(legs_t[j])
    return np.asarray(offsets), np.asarray(qs, float), np.asarray(tracks, float), route


def _way_knots(at_s: float, q_end, track_end: float, way):
    """The knots of a way to a park (:func:`_park_way`) that starts at ``q_end`` (``track_end``) at ``at_s``."""
    offsets, way_q, way_track, _ = way
    return np.r_[at_s, at_s + offsets], np.vstack([np.asarray(q_end, float)[None], way_q]), np.r_[track_end, way_track]


def _end_wait(arm, t0, q, track, starts, chosen, way, horizon_s: float, earlier, clearance_mm: float, parked=False):
    """Where a robot's way to its park (``way``: :func:`_park_way`'s knots) is not clear of the ``earlier``
    robots when it follows its last waypoint, the wait before one of its last :data:`BACKTRACK` + 1 strokes
    (the last first) that frees those strokes, the way and the hold at the park up to ``horizon_s`` together:
    ``(first, wait)``, or None if none does. ``parked``: the robot starts parked (row 0 is its park, and its
    first stroke's wait is made there, so ``first`` = 1 is not tried, as in :func:`schedule_cell`)."""
    offsets, way_q, way_track, _ = way
    t_all = np.r_[t0, t0[-1] + offsets]
    q_all, track_all = np.vstack([q, way_q]), np.r_[track, way_track]
    j = len(starts) - 1
    for first in range(j, max(j - BACKTRACK, 0) - 1, -1):
        if parked and first == 1:
            continue
        shift = float(chosen[:first].sum())
        t_x, q_x, track_x = t_all, q_all, track_all
        if horizon_s - shift > t_all[-1]:  # held at the park until the earlier robots are done
            t_x, q_x, track_x = (
                np.r_[t_all, horizon_s - shift],
                np.vstack([q_all, q_all[-1:]]),
                np.r_[track_all, track_all[-1]],
            )
        wait = _block_wait(arm, t_x, q_x, track_x, starts, chosen, first, j, earlier, clearance_mm)
        if wait is False:
            return None
        if wait is not None:
            return first, wait
    return None


#: The waypoints of a robot's plan whose capsules' ends :func:`work_points` takes: one in this many.
WORK_POINTS_EVERY = 10


def work_points(arm, q: np.ndarray, track: np.ndarray) -> np.ndarray:
    """(m, 4): the ends of a robot's capsules at every :data:`WORK_POINTS_EVERY`-th waypoint of its plan, each
    with its capsule's radius (what another robot's park keeps away from, :func:`park_joints`)."""
    take = slice(None, None, WORK_POINTS_EVERY)
    segments = arm.segments(np.asarray(q, float)[take], np.asarray(track, float)[take])  # (m, b, 2, 3)
    radii = np.broadcast_to(np.asarray(arm.radii, float)[None, :, None], segments.shape[:3])
    return np.column_stack([segments.reshape(-1, 3), radii.reshape(-1)])


def _move_s(arm, q_from: np.ndarray, q_to: np.ndarray, track_from=0.0, track_to=0.0, track_speed=None) -> float:
    """The time of a park move (a joint move at the arm's axis speeds, the track at its speed, at least
    :data:`MIN_PARK_S`), s."""
    speed = np.asarray(arm.params.max_speed, dtype=float)
    known = np.isfinite(speed)
    rail = abs(float(track_to) - float(track_from)) / track_speed if track_speed else 0.0
    return max(float((np.abs(q_to - q_from)[known] / speed[known]).max(initial=0.0)), rail, MIN_PARK_S)


def _held(q: np.ndarray, track: np.ndarray, reachable: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joints and track with every unreached waypoint holding the last reached configuration (the first
    reached one before any)."""
    idx = np.flatnonzero(reachable)
    if not len(idx):
        return np.zeros_like(q), np.zeros_like(track)
    last = np.maximum.accumulate(np.where(reachable, np.arange(len(q)), -1))
    last = np.where(last < 0, idx[0], last)
    return q[last], track[last]


@dataclass(frozen=True)
class Timeline:
    """One robot's motion in time: configuration knots (times strictly increasing, repeated configurations
    where it waits) and its waypoints' arrival times."""

    knot_t: np.ndarray  # (k,) s
    knot_q: np.ndarray  # (k, dof) rad
    knot_track: np.ndarray  # (k,) mm
    arrive_s: np.ndarray  # (n,) s
    wait_s: np.ndarray  # (strokes,) s
    park_route_q: np.ndarray | None = None  # (m, dof) rad: the nodes on the way to the park (a route), or None
    park_route_track: np.ndarray | None = None  # (m,) mm

    @property
    def end_s(self) -> float:
        return float(self.knot_t[-1]) if len(self.knot_t) else 0.0

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joints (m, dof) and track (m,) at times ``t`` (held before the start and after the end)."""
        return _configs(np.asarray(t, dtype=float), self.knot_t, self.knot_q, self.knot_track)


def with_leads(work, t0, q, track, starts):
    """A robot's timeline rows (times ``t0``, joints ``q``, track) with a row where each run-up starts, before
    its waypoint, and one where each run-out ends, after it (``RobotWork.lead_q``, their times from the timing's
    ``lead_s``), and the strokes' first rows (``starts``) moved to the run-up that begins a stroke, so that a
    wait before the stroke is held there (where the programs wait: at the end of the approach). Returns the
    new rows, starts, and which rows are the waypoints (n,) bool."""
    n = len(t0)
    if work.lead_q is None or work.lead_s is None or not n:
        return t0, q, track, starts, np.ones(n, bool)
    lead_q = np.asarray(work.lead_q, float)
    has = np.isfinite(lead_q).all(axis=2) & (np.asarray(work.lead_s, float) > 0)
    if not has.any():
        return t0, q, track, starts, np.ones(n, bool)
    dof = q.shape[1]
    before = has[:, 0].astype(int)
    row = np.arange(n) + np.cumsum(before) + np.r_[0, np.cumsum(has[:-1, 1])]  # each waypoint's new row
    size = n + int(has.sum())
    times, joints, tracks = np.zeros(size), np.zeros((size, dof)), np.zeros(size)
    keep = np.zeros(size, bool)
    times[row], joints[row], tracks[row], keep[row] = t0, q, track, True
    for side, sign in ((0, -1), (1, 1)):
        at = np.flatnonzero(has[:, side])
        where = row[at] + sign
        times[where] = t0[at] + sign * np.asarray(work.lead_s, float)[at, side]
        joints[where] = lead_q[at, side, :dof]
        tracks[where] = np.asarray(work.lead_track_mm, float)[at, side]
    # a transfer's last row (a copy of the next stroke's first waypoint) is reached at the run-up's start, where
    # the timing ends the move (``cells.timing``): there the robot is at the run-up's joints
    up = row[np.flatnonzero(has[:, 0])] - 1
    at = up[(up > 0) & keep[np.maximum(up - 1, 0)]]
    at = at[np.abs(times[at - 1] - times[at]) <= 1e-9]
    joints[at - 1], tracks[at - 1] = joints[at], tracks[at]
    return times, joints, tracks, row[starts] - before[starts], keep


def _knots(t0, q, track, starts, waits):
    """Knots of a timeline: waypoint ``i`` at ``t0[i]`` plus the waits of the strokes up to its own, each wait
    held at its stroke's first waypoint."""
    n = len(t0)
    shift = np.zeros(n)
    extra = np.zeros(n)
    for j, w in enumerate(waits):
        if w > 0:
            shift[starts[j] :] += w
            extra[starts[j]] = w
    arrive = t0 + shift - extra  # the arrival at a stroke's first waypoint is before its wait
    times, qs, tracks = [], [], []
    for i in range(n):
        times.append(arrive[i])
        qs.append(q[i])
        tracks.append(track[i])
        if extra[i] > 0:
            times.append(arrive[i] + extra[i])
            qs.append(q[i])
            tracks.append(track[i])
    times = np.asarray(times)
    if not n:  # a robot with no work (no area given to it)
        return times, np.asarray(q)[:0], np.zeros(0), arrive
    keep = np.r_[True, np.diff(times) > 1e-12]  # zero-length steps (a stroke's end and the next's start)
    return times[keep], np.asarray(qs)[keep], np.asarray(tracks)[keep], arrive


def _moves(segments: np.ndarray) -> np.ndarray:
    """(m,) how far any capsule end moves in the sampling intervals on either side of each sample, mm."""
    if len(segments) < 2:
        return np.zeros(len(segments))
    step = np.linalg.norm(np.diff(segments, axis=0), axis=-1).max(axis=(1, 2))
    return np.maximum(np.r_[step, 0.0], np.r_[0.0, step])


def pair_gaps(a_segments, a_radii, b_segments, b_radii) -> np.ndarray:
    """(m,) the least surface gap between any capsule of ``a`` and any of ``b`` at each of m samples, mm."""
    pa, qa = a_segments[:, :, None, 0], a_segments[:, :, None, 1]
    pb, qb = b_segments[:, None, :, 0], b_segments[:, None, :, 1]
    d = segment_distances(pa, qa, pb, qb) - a_radii[None, :, None] - b_radii[None, None, :]
    return d.reshape(len(d), -1).min(axis=1)


@dataclass(frozen=True)
class _Sampled:
    """A robot's capsules at grid samples ``first .. first + m - 1`` (times ``g * DT_S``): ends (m, b, 2, 3),
    radii (b,), the motion bound of each sample (m,), and each sample's box (m, 3) lo and hi, radius added."""

    first: int
    segments: np.ndarray
    radii: np.ndarray
    moves: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @classmethod
    def of(cls, arm, q, track, first: int = 0) -> _Sampled:
        segments = arm.segments(q, track)
        radii = np.asarray(arm.radii, dtype=float)
        grow = float(radii.max(initial=0.0))
        ends = segments.reshape(len(segments), -1, 3)
        return cls(first, segments, radii, _moves(segments), ends.min(axis=1) - grow, ends.max(axis=1) + grow)

    def rows(self, g: np.ndarray) -> np.ndarray:
        """Row of each grid sample ``g``, held at the first and the last outside them."""
        return np.clip(g - self.first, 0, len(self.segments) - 1)


def _gaps(a: _Sampled, ra: np.ndarray, b: _Sampled, rb: np.ndarray, clearance_mm: float) -> np.ndarray:
    """(m,) the gap less the clearance and both motion bounds at sample pairs (rows ``ra`` of ``a``, ``rb`` of
    ``b``): negative where the two robots may come too close. Pairs whose boxes are farther apart than that
    are not measured (their value is the box gap, a lower bound)."""
    need = clearance_mm + a.moves[ra] + b.moves[rb]
    box = np.maximum(np.maximum(a.lo[ra] - b.hi[rb], b.lo[rb] - a.hi[ra]), 0.0)
    gap = np.linalg.norm(box, axis=1) - need
    near = np.flatnonzero(gap < 0)
    if len(near):
        gap[near] = pair_gaps(a.segments[ra[near]], a.radii, b.segments[rb[near]], b.radii) - need[near]
    return gap


def _grid(lo: float, hi: float) -> np.ndarray:
    """Grid samples (integers g, times g * DT_S) in [lo, hi]."""
    return np.arange(math.ceil(lo / DT_S - 1e-9), math.floor(hi / DT_S + 1e-9) + 1)


def _configs(t, times, q, track):
    """Joints and track at times ``t``, linear between the knots (``times``, ``q``, ``track``)."""
    return np.stack([np.interp(t, times, q[:, c]) for c in range(q.shape[1])], axis=1), np.interp(t, times, track)


@dataclass(frozen=True)
class Schedule:
    """The cell's robots in time (module docstring).

    Attributes
    ----------
    timelines : tuple of Timeline
    least_gap_mm : dict
        ``"a-b"``: the least surface gap between robots a and b over the scheduled cycle (at the samples), mm.
    conflicts : dict
        ``"a-b"``: samples at which a and b are closer than the clearance with the motion bound.
    waits : dict
        Per robot: strokes delayed and the seconds waited.
    cycle_time_s : float
        The longest robot's time, waits included.
    priority : tuple of str
        The robots' names in the order they were scheduled in (the first never waits).
    """

    timelines: tuple
    least_gap_mm: dict
    conflicts: dict
    waits: dict
    cycle_time_s: float
    priority: tuple = ()

    def summary(self) -> dict:
        return {
            "rule": "robots in priority order; a later robot waits, spray off, before a stroke that would come "
            f"within the clearance of an earlier robot (samples every {DT_S:g} s, waits of {WAIT_STEP_S:g} s)",
            "priority": list(self.priority),
            "cycle_time_s": round(self.cycle_time_s, 3),
            "robot_time_s": {name: round(line.end_s, 3) for name, line in zip(self.waits, self.timelines)},
            "waits": self.waits,
            "least_gap_mm": self.least_gap_mm,
            "conflicts": self.conflicts,
            "kept_apart": not any(self.conflicts.values()),
        }


def _wait_for(stroke: _Sampled, hold: _Sampled, earlier, clearance_mm: float) -> float | None:
    """The least wait (a whole number of WAIT_STEP_S up to MAX_WAIT_S) before a stroke sampled at grid samples
    ``stroke.first ..`` that keeps it and the hold before it clear of every ``earlier`` robot; None if none
    does. The hold only grows with the wait, so the search ends at the first wait whose hold is not clear."""
    per = round(WAIT_STEP_S / DT_S)
    g0, m = stroke.first, len(stroke.segments)
    zero = np.zeros(1, dtype=int)
    chunks = [np.arange(c, min(c + WAIT_CHUNK, m)) for c in range(0, m, WAIT_CHUNK)]
    last = 0  # the chunk that failed last: a conflict most often lasts over several waits, so it is tried first
    for k in range(int(MAX_WAIT_S / WAIT_STEP_S) + 1):
        shift = k * per
        if shift:  # the hold's new samples, g0 + shift - per .. g0 + shift - 1
            new = np.arange(g0 + shift - per, g0 + shift)
            for other in earlier:
                if (_gaps(hold, np.repeat(zero, len(new)), other, other.rows(new), clearance_mm) < 0).any():
                    return None
        for c in [last, *range(last), *range(last + 1, len(chunks))]:
            rows = chunks[c]
            g = g0 + shift + rows
            if any((_gaps(stroke, rows, other, other.rows(g), clearance_mm) < 0).any() for other in earlier):
                last = c
                break
        else:
            return shift * DT_S
    return None


#: Sub-samples either side of a sample whose motion bound does not prove the clearance.
REFINE = 10


def _refined_conflict(line_a, arm_a, line_b, arm_b, t: float, clearance_mm: float) -> bool:
    """Whether two robots may come within the clearance in the sampling intervals either side of time ``t``,
    sampled again ``REFINE`` times finer (with the finer samples' motion bounds)."""
    times = t + DT_S * np.linspace(-1.0, 1.0, 2 * REFINE + 1)
    a = _Sampled.of(arm_a, *line_a.at(times))
    b = _Sampled.of(arm_b, *line_b.at(times))
    rows = np.arange(len(times))
    return bool((_gaps(a, rows, b, rows, clearance_mm) < 0).any())


def _block_wait(arm, t0, q, track, starts, chosen, first: int, j: int, earlier, clearance_mm: float):
    """The wait before stroke ``first`` (held at its first waypoint) that frees strokes ``first .. j`` of a
    robot's timeline (``t0``, ``q``, ``track`` at its waypoints; ``chosen``: the waits before ``first``) from
    the ``earlier`` robots: None when none does, False when there is nothing to sample."""
    shift = float(chosen[:first].sum())
    end = starts[j + 1] if j + 1 < len(starts) else len(t0) - 1
    g = _grid(t0[starts[first]] + shift, t0[end] + shift)
    if not len(g):
        return False
    block = _Sampled.of(arm, *_configs(g * DT_S - shift, t0, q, track), first=int(g[0]))
    hold = _Sampled.of(arm, q[starts[first]][None], track[starts[first] : starts[first] + 1])
    return _wait_for(block, hold, earlier, clearance_mm)


#: The largest joint step (rad) between two samples of a move checked by :func:`move_free`: the programs'
#: check's (``programs.arms.MOTION_STEP_RAD``, not imported: that would close an import cycle; a test holds
#: the two equal).
MOVE_STEP_RAD = 0.02


def move_free(arm, q_a, q_b, track_a: float, track_b: float) -> bool:
    """Whether the joint move from ``q_a`` at ``track_a`` to ``q_b`` at ``track_b`` (joints and track linear
    together) is free of the part and the floor, sampled at most :data:`MOVE_STEP_RAD` and 25 mm of track
    apart, as the programs' check samples it."""
    q_a, q_b = np.asarray(q_a, float), np.asarray(q_b, float)
    steps = max(
        1, math.ceil(np.abs(q_b - q_a).max(initial=0.0) / MOVE_STEP_RAD), math.ceil(abs(track_b - track_a) / 25.0)
    )
    s = np.linspace(0.0, 1.0, steps + 1)[:, None]
    return not arm.collides(q_a + s * (q_b - q_a), track_a + s[:, 0] * (track_b - track_a)).any()


def _backed(back, q: np.ndarray, track_mm: float) -> tuple[np.ndarray, float]:
    """The joints the programs back off to from a run's end at ``q`` (``back``, :func:`schedule_cell`) and
    the line's seconds; ``q`` and 0 without a back-off (none given, or none the arm reaches)."""
    found = None if back is None else back(np.r_[q, track_mm])
    if found is None:
        return np.asarray(q, float), 0.0
    return np.asarray(found[0], float)[: len(q)], float(found[1])


def schedule_cell(
    robots,
    arms,
    speed_mm_s: float,
    transfer_speed_mm_s: float,
    clearance_mm: float,
    track_speeds=None,
    times=None,
    track_ranges=None,
    priority=None,
    backs=None,
    routers=None,
) -> Schedule:
    """Schedule the robots' work (``RobotWork`` each) with their ``ArmCollision`` models
    (module docstring); ``track_speeds``: each robot's track speed, mm/s (None without a track); ``times``:
    each robot's timed arrival at its waypoints (``cells.timing``), in place of :func:`waypoint_times`;
    ``track_ranges``: each robot's track ends (lo, hi) mm or None, where its park may be too; ``priority``: the
    robots' indices in the order they are scheduled in (the first never waits; default: as given); ``backs``:
    each robot's programs' back-off at a run's end (``cells.timing.program_back_offs``: ``back(axes) -> (axes, s)``
    or None) or None: a robot that starts parked comes in to the approach pose of its first waypoint, and one
    that has done its work retracts from its last (a row of its timeline) before it parks, as its program
    does, and its parks are chosen for those moves; ``routers``: each robot's ``cells.routes.CellRouter`` or
    None: where the joint move from the end of a robot's work to its park is not free of the part (every park
    is reached only through it: an arm reaching in under the body), the first free way there is taken
    (``CellRouter.park_route``: the gun drawn out towards the base, then the transfers' routes), its nodes
    rows of the timeline (``Timeline.park_route_q``) that the programs move through. The timelines and the
    summary are in the robots' own order."""
    names = [w.name for w in robots]
    order = list(range(len(robots))) if priority is None else [int(k) for k in priority]
    timelines: list = [None] * len(robots)
    by_robot: list = [None] * len(robots)
    sampled: list[_Sampled] = []  # the robots scheduled so far, in priority order
    waited: dict = {}
    held = [_held(np.asarray(w.q, dtype=float), np.asarray(w.track_mm, dtype=float), w.reachable) for w in robots]
    points = [work_points(arm, *h) if len(h[0]) else np.zeros((0, 4)) for arm, h in zip(arms, held)]
    for rank, k in enumerate(order):
        w, arm = robots[k], arms[k]
        others = np.concatenate([p for i, p in enumerate(points) if i != k] or [np.zeros((0, 4))])
        track_speed = None if track_speeds is None else track_speeds[k]
        track_range = None if track_ranges is None else track_ranges[k]
        if times is not None:
            t0 = np.asarray(times[k], dtype=float)
        else:
            t0 = waypoint_times(w, speed_mm_s, transfer_speed_mm_s, arm.params.max_speed, track_speed)
        q, track = _held(np.asarray(w.q, dtype=float), np.asarray(w.track_mm, dtype=float), w.reachable)
        starts = np.cumsum([0] + [len(s) for s in w.strokes])[:-1]
        keep = np.ones(len(t0), bool)
        if times is not None:  # the run-ups' times are the timing's (none on the path-length timeline)
            t0, q, track, starts, keep = with_leads(w, t0, q, track, starts)
        chosen = np.zeros(len(starts))
        back = None if backs is None else backs[k]
        parked = False  # the robot starts parked, its first move the approach (the first stroke's hold fails)
        if rank and len(t0):
            # held at its first waypoint it would meet an earlier robot, whatever it waited: it starts parked
            if _block_wait(arm, t0, q, track, starts, chosen, 0, 0, sampled, clearance_mm) is None:
                # the program moves from the park to the approach pose, then along the gun axis to q[0]
                entry, entry_s = _backed(back, q[0], float(track[0]))
                home, _ = park_joints(arm, entry, float(track[0]), others)
                t0 = np.r_[t0[0], t0 + _move_s(arm, home, entry) + entry_s]
                q, track = np.vstack([home, q]), np.r_[track[0], track]
                starts = np.r_[0, starts + 1]
                chosen = np.zeros(len(starts))
                parked = True
            for j in range(len(starts)):
                for first in _backtrack(j):
                    if parked and first == 1:  # the first stroke's wait is made parked, before the approach
                        continue
                    # strokes first .. j as one block, waiting only before the first (the later waits dropped)
                    wait = _block_wait(arm, t0, q, track, starts, chosen, first, j, sampled, clearance_mm)
                    if wait is False:
                        break
                    if wait is not None:
                        chosen[first : j + 1] = 0.0
                        chosen[first] = wait
                        break
        route = None
        way = None
        if len(t0):
            # the park: the first whose way (the retract, the move or its route) and hold are clear of the
            # earlier robots (``_park_clear``); if none is, the first whose way a wait before one of the last
            # strokes frees (``_end_wait``); else the first at all
            last, _ = _backed(back, q[-1], float(track[-1]))
            horizon = max(((o.first + len(o.segments) - 1) * DT_S for o in sampled), default=0.0)
            tries = list(itertools.islice(
                park_candidates(arm, last, float(track[-1]), others, track_range, track_speed), PARK_TRIES
            ))  # fmt: skip
            done = float(t0[-1] + chosen.sum())
            router = None if routers is None else routers[k]
            ways = [None] * len(tries)  # each park's way, made when first asked for (a route takes a search)
            pick = 0
            if rank:
                pick = None
                for i, (cand, where) in enumerate(tries):
                    ways[i] = _park_way(arm, q[-1], float(track[-1]), back, cand, where, track_speed, router)
                    if _park_clear(
                        arm, *_way_knots(done, q[-1], float(track[-1]), ways[i]), sampled, horizon, clearance_mm
                    ):
                        pick = i
                        break
                if pick is None:
                    pick, best = 0, None
                    for i, way in enumerate(ways):
                        found = _end_wait(
                            arm, t0, q, track, starts, chosen, way, horizon, sampled, clearance_mm, parked
                        )
                        if found is not None:
                            best, pick = found, i
                            break
                    if best is not None:
                        chosen[best[0] :] = 0.0
                        chosen[best[0]] = best[1]
            if ways[pick] is None:
                ways[pick] = _park_way(arm, q[-1], float(track[-1]), back, *tries[pick], track_speed, router)
            way = ways[pick]
            route = way[3]
        knots = list(_knots(t0, q, track, starts, chosen))
        if way is not None:  # the retract, the route's nodes and the park: rows after the last waypoint
            done = float(knots[0][-1])
            knots[0] = np.r_[knots[0], done + way[0]]
            knots[1] = np.vstack([knots[1], way[1]])
            knots[2] = np.r_[knots[2], way[2]]
        if parked:  # the park at the start is not a waypoint; its wait is the first stroke's
            knots[3] = knots[3][1:]
            chosen = np.r_[chosen[0], chosen[2:]]
        knots[3] = knots[3][keep]  # the waypoints' arrivals, without the run-ups' and run-outs' rows
        line = Timeline(knots[0], knots[1], knots[2], knots[3], chosen, *(route if route is not None else (None, None)))
        timelines[k] = line
        g = _grid(0.0, line.end_s) if len(t0) else np.zeros(1, dtype=int)
        # a robot with no work (no area given to it) has no motion to keep apart: it is left out of the checks
        by_robot[k] = _Sampled.of(arm, *line.at(g * DT_S)) if len(t0) else None
        if by_robot[k] is not None:
            sampled.append(by_robot[k])
        waited[k] = {"strokes_delayed": int((chosen > 0).sum()), "waited_s": round(float(chosen.sum()), 3)}
    waits = {robots[k].name: waited[k] for k in range(len(robots))}
    cycle = max((tl.end_s for tl in timelines), default=0.0)
    everywhere = _grid(0.0, cycle)
    gaps, conflicts = {}, {}
    for (i, a), (j, b) in itertools.combinations(enumerate(by_robot), 2):
        key = f"{names[i]}-{names[j]}"
        if a is None or b is None:  # a robot with no work: no program, nothing of its motion to check
            gaps[key], conflicts[key] = None, 0
            continue
        ra, rb = a.rows(everywhere), b.rows(everywhere)
        found = _gaps(a, ra, b, rb, clearance_mm)
        least = math.inf
        for c in range(0, len(everywhere), 4096):
            part = slice(c, c + 4096)
            least = min(least, float(pair_gaps(a.segments[ra[part]], a.radii, b.segments[rb[part]], b.radii).min()))
        gaps[key] = None if math.isinf(least) else round(least, 1)
        suspects = everywhere[found < 0]
        conflicts[key] = sum(
            _refined_conflict(timelines[i], arms[i], timelines[j], arms[j], g * DT_S, clearance_mm) for g in suspects
        )
    return Schedule(tuple(timelines), gaps, conflicts, waits, cycle, tuple(robots[k].name for k in order))


def scheduled(cell, robots: tuple, arms, job, backs=None, routers=None) -> tuple[tuple, dict]:
    """The robots' work with its schedule's times and waits (:func:`schedule_cell`,
    with the ``[motion]`` speeds, the tracks' speeds and the ``[collision]`` clearance, the robot with the
    longest work first: module docstring, step 2; ``backs`` and ``routers`` as :func:`schedule_cell` takes
    them, ``cells.plan.schedule_aids``), and the schedule's summary."""

    tracks = [None if r.track is None else r.track.speed_mm_s for r in cell.robots]
    ranges = [None if r.track is None else tuple(r.track.range_mm) for r in cell.robots]
    timed = job.timing.enabled and all(r.t_s is not None for r in robots)
    times = [r.t_s for r in robots] if timed else None
    speed, transfer = job.motion.gun_speed_mm_s, job.motion.transfer_speed_mm_s
    own = [
        float(np.asarray(times[k])[-1:].sum())
        if times is not None
        else float(waypoint_times(r, speed, transfer, arms[k].params.max_speed, tracks[k])[-1:].sum())
        for k, r in enumerate(robots)
    ]
    plan = schedule_cell(
        robots,
        arms,
        speed,
        transfer,
        job.collision.clearance_mm,
        tracks,
        times=times,
        track_ranges=ranges,
        priority=sorted(range(len(robots)), key=lambda k: -own[k]),
        backs=backs,
        routers=routers,
    )
    out = tuple(
        replace(
            r,
            t_s=line.arrive_s.copy(),
            wait_s=line.wait_s.copy(),
            ends_q=line.knot_q[[0, -1]].copy() if len(line.knot_q) else None,
            ends_track_mm=line.knot_track[[0, -1]].copy() if len(line.knot_q) else None,
            park_route_q=line.park_route_q,
            park_route_track_mm=line.park_route_track,
        )
        for r, line in zip(robots, plan.timelines)
    )
    return out, plan.summary()
