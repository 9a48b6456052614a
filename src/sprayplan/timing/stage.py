"""The ``timing`` stage of the main job: a time stamp for every waypoint and the cycle time the robot can make.

The robot runs the plan in order: from home (the arm at ``robots.stage.HOME_JOINTS``, the gantry at the
plan's ``home_mm``) to each station, through its strokes, and back home. Every stretch of a spray stroke
whose waypoints are reachable is timed along its joint path (:func:`sprayplan.timing.path.time_paths`, all
of them together: from rest to rest, within the axes' limits and never faster than the planned tip speed);
everything between them
is a point-to-point joint move from rest to rest (:func:`sprayplan.timing.moves.point_to_point`):

- a transfer (spray off) goes from the last joints before it to its own last reachable waypoint's joints, as
  the robot programs' joint moves do; its waypoints get the times at their share of its length; a transfer
  the collision stage re-routed (``collision.transfers``) is a joint move to each of its waypoints in turn,
  the legs its proof covers, each waypoint stamped when it is reached;
- the unreachable waypoints of a stroke are skipped by a joint move (no time stamp: NaN), and so is a jump of
  an arm joint by more than ``[timing] joint_jump_deg`` between two waypoints (a change of IK branch, an SQP
  solution far from its neighbours: no spline through it is a motion the arm should make while spraying);
- a station move goes from the last joints of one station (or home) to the first of the next (or home), the
  gantry's axes and the arm's together.

The film then takes the real speeds as time factors (``Stroke.dwell``): a waypoint's time is half of each
adjacent segment's, and its factor is that time over the time the same waypoint takes at the process speed
with factors 1, so the film model's time along every stroke is the timed one (:func:`real_plan`).
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
from dataclasses import dataclass

import numpy as np

from sprayplan.collision.transfers import is_route
from sprayplan.parallel import process_count, shared_map
from sprayplan.paths.speed import segment_speeds
from sprayplan.progress import Progress, counted
from sprayplan.robots.stage import HOME_JOINTS
from sprayplan.timing.limits import AxisLimits, gantry_limits
from sprayplan.timing.moves import point_to_point
from sprayplan.timing.path import time_paths
from sprayplan.types import Plan

log = logging.getLogger(__name__)

#: A spray waypoint is "slowed" when the robot reaches less than this share of its planned tip speed there.
SLOWED_SHARE = 0.99


@dataclass(frozen=True)
class PlanTiming:
    """The timed plan, per station in visiting order, one entry per waypoint of the station's strokes.

    Attributes
    ----------
    t_s : tuple of (n,) float
        Time of each waypoint from the start at home, s; NaN where unreachable.
    speed_mm_s : tuple of (n,) float
        The gun tip's speed the robot makes at each waypoint of a spray stroke (0 where a timed stretch
        starts or ends at rest), mm/s; NaN on transfers and unreachable waypoints.
    planned_speed_mm_s : tuple of (n,) float
        The planned tip speed at each waypoint of a spray stroke, the bound the timing keeps (the slower of
        its two segments' planned speeds), mm/s; NaN on transfers.
    dwell : tuple of (n,) float
        The time factors of the timed speeds (:func:`real_plan`): ``Stroke.dwell`` where the robot keeps the
        plan, larger where it is slower.
    stroke_time_s : tuple of (k,) float
        Each stroke's time (spray strokes: the timed stretches and the joint moves across unreachable
        waypoints; transfers: their joint move).
    planned_stroke_time_s : tuple of (k,) float
        Each stroke's time at its planned speeds (length over speed; transfers at ``[motion]
        transfer_speed_mm_s``).
    spray_time_s, transfer_time_s, station_move_time_s, cycle_time_s : float
        The sums: the timed stretches of the spray strokes, the joint moves inside a station (transfers, and
        the moves across unreachable waypoints and joint jumps, ``joint_moves`` in the summary), station moves
        (home to the first station, between stations, back home); the cycle time is their sum.
    worst : dict
        The largest ratio to its limit of axis speed, axis acceleration and tip speed over every timed
        stretch's dense check (at most 1); ``stretched``: stretches slowed uniformly after the rounds.
    """

    t_s: tuple
    speed_mm_s: tuple
    planned_speed_mm_s: tuple
    dwell: tuple
    stroke_time_s: tuple
    planned_stroke_time_s: tuple
    spray_time_s: float
    transfer_time_s: float
    station_move_time_s: float
    cycle_time_s: float
    worst: dict

    def summary(self, plan: Plan, job) -> dict:
        """The totals' ``timing`` entry: the times, and where the limits keep a stroke below its speed."""
        slowed = slowed_on_part = strokes_slowed = spray_waypoints = 0
        ratios, planned_spray, real_spray = [], 0.0, 0.0
        rows = zip(
            plan.stations, self.speed_mm_s, self.planned_speed_mm_s, self.stroke_time_s, self.planned_stroke_time_s
        )
        for st, speed, bound, times, planned in rows:
            start = 0
            for k, s in enumerate(st.strokes):
                sl = slice(start, start + len(s))
                start += len(s)
                if not s.spray_on:
                    continue
                ok = st.reachable[sl]
                low = ok & (speed[sl] < SLOWED_SHARE * bound[sl])
                spray_waypoints += int(ok.sum())
                slowed += int(low.sum())
                slowed_on_part += int((low & s.on_part).sum())
                strokes_slowed += bool((low & s.on_part).any())
                if times[k] > 0:
                    ratios.append(planned[k] / times[k])
                    planned_spray += planned[k]
                    real_spray += times[k]
        return {
            "spray_time_s": round(self.spray_time_s, 3),
            "transfer_time_s": round(self.transfer_time_s, 3),
            "station_move_time_s": round(self.station_move_time_s, 3),
            "spray_waypoints": spray_waypoints,
            "slowed_waypoints": slowed,
            "slowed_on_part_waypoints": slowed_on_part,
            "strokes_slowed": strokes_slowed,
            "min_stroke_speed_ratio": round(min(ratios), 4) if ratios else None,
            "spray_speed_ratio": round(planned_spray / real_spray, 4) if real_spray > 0 else None,
            "worst_limit_ratio": {k: round(v, 6) for k, v in self.worst.items()},
        }


def plan_limits(gantry, job) -> AxisLimits:
    """The job's nine axes' limits (``[timing]``, the arm's model, ``[motion] platform_speed_mm_s``)."""
    return gantry_limits(gantry.robot, job.timing, job.motion)


def time_plan(plan: Plan, job, gantry, progress: Progress | None = None) -> PlanTiming:
    """Time a plan: every waypoint's time stamp, the achievable tip speeds and the real cycle time."""
    limits = plan_limits(gantry, job)
    config = job.timing
    motion = job.motion

    # every timed stretch of every spray stroke at once (toppra's analysis runs on them together), in the
    # order the loop below takes them
    jump = np.radians(config.joint_jump_deg)
    stretches = [(st.q9[idx[run]], cap[run[:-1]]) for st, idx, cap, run in _spray_runs(plan, motion, jump)]
    # each stretch is timed on its own (time_paths: the same answer in any company), so the stretches are
    # shared with the helper process in a few consecutive parts
    processes = process_count(job.kinematics.processes)
    parts = _parts(stretches, 2 * TIMING_PARTS_PER_PROCESS if processes > 1 else 1)
    options = (limits, gantry, config.check_steps, config.max_rounds)
    timings = iter([t for part in shared_map(_timed_part, parts, processes, common=options) for t in part])
    step = counted(progress, "timing", len(plan.stations))
    current = np.concatenate([HOME_JOINTS, plan.home_mm])
    clock = 0.0
    totals = {"spray": 0.0, "transfer": 0.0, "station": 0.0}
    worst = {"velocity": 0.0, "acceleration": 0.0, "tip_speed": 0.0, "stretched": 0}
    out_t, out_speed, out_bound, out_time, out_planned = [], [], [], [], []
    for st in plan.stations:
        n = len(st)
        t = np.full(n, np.nan)
        speed = np.full(n, np.nan)
        bound = np.full(n, np.nan)
        stroke_time, planned_time = [], []
        reach = np.flatnonzero(st.reachable)
        if len(reach):
            move = point_to_point(current, st.q9[reach[0]], limits)
            clock += move.duration_s
            totals["station"] += move.duration_s
            current = st.q9[reach[0]]
        start = 0
        for s in st.strokes:
            idx = np.arange(start, start + len(s))
            start += len(s)
            began = clock
            ok = st.reachable[idx]
            if not s.spray_on:
                planned_time.append(s.length_mm / motion.transfer_speed_mm_s)
                if ok.any() and is_route(st.repair[idx]):
                    # a route the collision stage made: a joint move to each of its waypoints in turn
                    for k in idx[ok]:
                        move = point_to_point(current, st.q9[k], limits)
                        clock += move.duration_s
                        totals["transfer"] += move.duration_s
                        t[k] = clock
                        current = st.q9[k]
                elif ok.any():
                    last = idx[ok][-1]
                    move = point_to_point(current, st.q9[last], limits)
                    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(s.tcp, axis=0), axis=1))])
                    share = along / along[-1] if along[-1] > 0 else np.linspace(0.0, 1.0, len(s))
                    t[idx[ok]] = clock + move.duration_s * share[ok]
                    clock += move.duration_s
                    totals["transfer"] += move.duration_s
                    current = st.q9[last]
                stroke_time.append(clock - began)
                continue
            cap = _planned_speeds(s, motion)
            seg_len = np.linalg.norm(np.diff(s.tcp, axis=0), axis=1)
            planned_time.append(float((seg_len / cap).sum()) if len(cap) else 0.0)
            if len(cap):
                bound[idx] = np.minimum(np.concatenate([cap[:1], cap]), np.concatenate([cap, cap[-1:]]))
            else:
                bound[idx] = motion.gun_speed_mm_s
            local_t = np.full(len(s), np.nan)
            for run in joint_runs(ok, st.q9[idx, :6], jump):
                move = point_to_point(current, st.q9[idx[run[0]]], limits)
                clock += move.duration_s
                totals["transfer"] += move.duration_s
                if len(run) >= 2:
                    timed = next(timings)
                    local_t[run] = clock + timed.t_s
                    speed[idx[run]] = timed.speed_mm_s
                    clock += timed.duration_s
                    totals["spray"] += timed.duration_s
                    for key in ("velocity", "acceleration", "tip_speed"):
                        worst[key] = max(worst[key], timed.worst[key])
                    worst["stretched"] += timed.stretch > 1.0
                else:
                    local_t[run] = clock
                    speed[idx[run]] = 0.0
                current = st.q9[idx[run[-1]]]
            t[idx] = local_t
            stroke_time.append(clock - began)
        for a in (t, speed, bound):
            a.flags.writeable = False
        out_t.append(t)
        out_speed.append(speed)
        out_bound.append(bound)
        out_time.append(np.array(stroke_time, float))
        out_planned.append(np.array(planned_time, float))
        step()
    home = point_to_point(current, np.concatenate([HOME_JOINTS, plan.home_mm]), limits)
    clock += home.duration_s
    totals["station"] += home.duration_s
    return PlanTiming(
        tuple(out_t),
        tuple(out_speed),
        tuple(out_bound),
        timed_dwell(plan, out_t, job),
        tuple(out_time),
        tuple(out_planned),
        float(totals["spray"]),
        float(totals["transfer"]),
        float(totals["station"]),
        float(clock),
        worst,
    )


#: How many parts of the stretches each process takes on average (more: better balance, more round trips).
TIMING_PARTS_PER_PROCESS = 2


def _parts(items: list, count: int) -> list[list]:
    """``items`` in ``count`` consecutive parts of about the same number of waypoints (none empty)."""
    if count <= 1 or len(items) <= 1:
        return [items]
    sizes = np.cumsum([len(q) for q, _ in items])
    cuts = np.searchsorted(sizes, sizes[-1] * np.arange(1, count) / count, side="right")
    bounds = np.unique(np.r_[0, np.clip(cuts, 1, len(items) - 1), len(items)])
    return [items[a:b] for a, b in itertools.pairwise(bounds)]


def _timed_part(options, stretches) -> list:
    """``time_paths`` of some of a plan's stretches (for ``parallel.shared_map``)."""
    limits, gantry, check_steps, max_rounds = options
    return time_paths(
        stretches, limits, gantry.gun_tip, check_steps=check_steps, max_rounds=max_rounds, tip_rate=gantry.gun_tip
    )


def warm_up() -> None:
    """Time a short made-up stretch, so that the timing's compiled kernels are loaded (the helper process
    does this while it waits for work: ``parallel.HELPER_WARM_UPS``)."""
    from sprayplan.config import JobConfig
    from sprayplan.robots.gantry import Gantry

    gantry, job = Gantry(), JobConfig()
    q = np.tile(np.r_[HOME_JOINTS, 0.0, 0.0, 1500.0], (5, 1))
    q[:, 0] += np.linspace(0.0, 0.2, 5)
    _timed_part(
        (plan_limits(gantry, job), gantry, job.timing.check_steps, job.timing.max_rounds), [(q, np.full(4, 400.0))]
    )


def _planned_speeds(s, motion) -> np.ndarray:
    """A spray stroke's planned tip speed on each segment (its time factors included), mm/s."""
    return segment_speeds(s.tcp, s.points, motion.gun_speed_mm_s, motion.speed_along, motion.max_speed_ratio, s.dwell)


def _spray_runs(plan: Plan, motion, jump_rad: float):
    """Every stretch :func:`time_plan` times along its joint path, in its order: ``(station, waypoint indices
    of the stroke, the stroke's planned segment speeds, the stretch's run of indices into the stroke)``."""
    for st in plan.stations:
        for _, idx, cap, run in stroke_runs(st.strokes, st.reachable, st.q9[:, :6], motion, jump_rad):
            yield st, idx, cap, run


def stroke_runs(strokes, reachable: np.ndarray, q: np.ndarray, motion, jump_rad: float):
    """Every stretch of one robot's ``strokes`` (a station's, or a cell robot's) timed along its joint path, in
    order: the runs of at least two reachable waypoints of a spray stroke with no arm joint (``q``'s columns)
    jumping by more than ``jump_rad`` (:func:`joint_runs`), each as ``(stroke, its waypoint indices, its planned
    segment speeds with its time factors, the run's indices into the stroke)``."""
    start = 0
    for s in strokes:
        idx = np.arange(start, start + len(s))
        start += len(s)
        if not s.spray_on:
            continue
        cap = _planned_speeds(s, motion)
        for run in joint_runs(reachable[idx], q[idx], jump_rad):
            if len(run) >= 2:
                yield s, idx, cap, run


def joint_runs(ok: np.ndarray, q: np.ndarray, jump_rad: float) -> list[np.ndarray]:
    """The index runs of consecutive reachable waypoints, also cut where an arm joint (a column of ``q``: pass
    the arm's joints only) jumps by more than ``jump_rad`` from one waypoint to the next (a change of IK branch,
    an SQP solution far from its neighbours): the arm cannot follow the stroke across it and makes a joint move
    instead."""
    where = np.flatnonzero(ok)
    if not len(where):
        return []
    jump = np.abs(np.diff(q[where], axis=0)).max(axis=1) > jump_rad
    cuts = np.flatnonzero((np.diff(where) > 1) | jump) + 1
    return np.split(where, cuts)


def timed_dwell(plan: Plan, t_s, job) -> tuple:
    """Per station, each waypoint's time factor (``Stroke.dwell``) from the time stamps ``t_s`` (per station,
    NaN where unreachable): :func:`waypoint_dwell` of each station's strokes."""
    jump = np.radians(job.timing.joint_jump_deg)
    out = []
    for st, t in zip(plan.stations, t_s):
        dwell = waypoint_dwell(st.strokes, st.reachable, st.q9[:, :6], t, job.motion, jump)
        dwell.flags.writeable = False
        out.append(dwell)
    return tuple(out)


def waypoint_dwell(strokes, reachable: np.ndarray, q: np.ndarray, t: np.ndarray, motion, jump_rad: float) -> np.ndarray:
    """Each waypoint's time factor (``Stroke.dwell``) of one robot's ``strokes`` (a station's, or a cell
    robot's) from its time stamps ``t``: on a spray stroke's timed stretches (the runs :func:`joint_runs` cuts
    over ``reachable`` and the arm joints ``q``, as the timing times them), a waypoint's time (half of each
    adjacent segment's) over its time at the process speed with factors 1; the planned factor elsewhere and
    where a waypoint's time at the process speed is 0 (the tip does not move)."""
    dwell = np.concatenate([s.dwell for s in strokes]) if strokes else np.zeros(0)
    start = 0
    for s in strokes:
        idx = np.arange(start, start + len(s))
        start += len(s)
        if not s.spray_on or len(s) < 2:
            continue
        base = np.linalg.norm(np.diff(s.tcp, axis=0), axis=1) / segment_speeds(
            s.tcp, s.points, motion.gun_speed_mm_s, motion.speed_along, motion.max_speed_ratio
        )
        for run in joint_runs(reachable[idx], q[idx], jump_rad):
            if len(run) < 2:
                continue
            real = np.diff(t[idx[run]])
            share = np.zeros(len(run))
            share[:-1] += real / 2
            share[1:] += real / 2
            planned = np.zeros(len(run))
            planned[:-1] += base[run[:-1]] / 2
            planned[1:] += base[run[:-1]] / 2
            moving = planned > 1e-12
            dwell[idx[run[moving]]] = share[moving] / planned[moving]
    return dwell


def real_plan(plan: Plan, timing, job=None) -> Plan:
    """The plan with every spray stroke's time factors (``Stroke.dwell``) from its timing: what the film is
    predicted with; geometry and joints unchanged. ``timing``: a :class:`PlanTiming`, or the time stamps read
    back from plan.json (``export.plan_read.WaypointTimes``, then with the plan's ``job``)."""
    dwell = timing.dwell if isinstance(timing, PlanTiming) else timed_dwell(plan, timing.t_s, job)
    stations = []
    for st, w_station in zip(plan.stations, dwell):
        strokes, start = [], 0
        for s in st.strokes:
            w = w_station[start : start + len(s)]
            start += len(s)
            strokes.append(s.with_dwell(w) if s.spray_on else s)
        stations.append(dataclasses.replace(st, strokes=tuple(strokes)))
    return dataclasses.replace(plan, stations=tuple(stations))
