"""The robots of a cell timed within their axes' limits (issue 18: "joint-limited timing for a cell's arms").

Each robot's work is timed as the main job times the gantry (:mod:`sprayplan.timing.stage`), on its own axes:
its arm's joints and, on a track, the track position (mm) as one more axis. From its first reached
configuration (time 0) it runs its strokes in order:

- every stretch of a spray stroke whose waypoints it reaches, and where no arm joint jumps by more than
  ``[timing] joint_jump_deg`` between two waypoints, along its joint path, time-optimal from rest to rest within
  the axes' speeds and accelerations and never faster than the planned gun-tip speed (its time factors
  included): :func:`sprayplan.timing.path.time_paths`, toppra with the dense check, every stretch of every robot
  of the cell together;
- a stretch's run-up and run-out (``cells.runups``, ``[timing] run_up_mm``) are part of its path: it starts at
  rest where the run-up starts, passes its first waypoint at speed, and comes to rest where its run-out ends;
  the run-up at the stretch's first planned speed, the run-out at its last;
- between them, the moves the programs make (``programs.build``), each from rest to rest: the retract from a
  run's end (its last waypoint, or its run-out's end), the gun backed off along its axis by ``[export]
  approach_mm`` (or the first shorter share the arm reaches, as the programs back off); a point-to-point joint
  move (ruckig, :func:`sprayplan.timing.moves.point_to_point`) to every row of a transfer in turn (a routed
  transfer's nodes are joint moves to fine points); then to the approach pose of the next run's start (its
  first waypoint or its run-up's start) and the approach along the gun axis. A back-off line takes the longer
  of its rest-to-rest joint move and its length at ``[export] approach_speed_mm_s`` (:func:`program_back_offs`). A
  transfer's rows are stamped when the robot reaches them.

A waypoint the robot does not reach gets the time at which it passes on (it holds its last configuration), so
that every waypoint has a time, as the schedule needs.

The limits (:func:`cell_limits`): the arm's joint speeds are ``[timing] arm_max_velocity_deg_s`` when given,
else the maker's (``robots.opw`` presets; the UR and R5150 models' own), and its accelerations
``[timing] arm_max_acceleration_deg_s2`` when given, else the model's (the UR arms' 80.2 deg/s^2, the R5150's
assumed 180 deg/s^2), else, for the industrial arms whose makers publish none, an assumption: each axis reaches
its top speed in ``ACCELERATION_TIME_S``. The track runs at its ``speed_mm_s`` (the cell file) and accelerates
at ``[timing] track_max_acceleration_mm_s2``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sprayplan.errors import ConfigError
from sprayplan.paths.speed import segment_speeds
from sprayplan.timing.limits import AxisLimits
from sprayplan.timing.moves import point_to_point
from sprayplan.timing.path import time_paths
from sprayplan.timing.stage import joint_runs, stroke_runs

#: An industrial arm without published accelerations is assumed to reach each axis's top speed in this time, s.
ACCELERATION_TIME_S = 0.5
#: A spray waypoint is "slowed" where the robot makes less than this share of the planned tip speed.
SLOWED_SHARE = 0.99


@dataclass(frozen=True)
class WorkTiming:
    """One robot's work timed within its limits.

    Attributes
    ----------
    t_s : (n,) float
        When the robot reaches each waypoint (an unreached one: when it passes on), s from its start.
    speed_mm_s : (n,) float
        The gun tip's timed speed at each spray waypoint it follows (NaN elsewhere).
    spray_s, move_s : float
        Time along the spray stretches (their run-ups and run-outs included), and in the joint moves between
        them (transfers, moves across unreached waypoints and joint jumps).
    cycle_s : float
        The whole work's time (its last waypoint's).
    slowed : int
        Spray waypoints where the robot makes less than ``SLOWED_SHARE`` of the planned tip speed (a stretch's
        two ends, at rest, among them, as the gantry's timing counts them).
    worst : dict
        The largest ratio to each limit over the stretches (velocity, acceleration, tip speed) and how many
        stretches were slowed uniformly to hold them (``stretched``).
    lead_s : (n, 2) float or None
        How long the run-up into each waypoint and the run-out after it take (0 without one), s.
    """

    t_s: np.ndarray
    speed_mm_s: np.ndarray
    spray_s: float
    move_s: float
    cycle_s: float
    slowed: int
    worst: dict
    lead_s: np.ndarray | None = None

    def summary(self) -> dict:
        return {
            "cycle_time_s": round(self.cycle_s, 3),
            "spray_s": round(self.spray_s, 3),
            "moves_s": round(self.move_s, 3),
            "run_ups_s": round(float(self.lead_s.sum()), 3) if self.lead_s is not None else 0.0,
            "slowed_spray_waypoints": self.slowed,
            "worst_ratio": {k: (round(v, 4) if isinstance(v, float) else v) for k, v in self.worst.items()},
        }


def cell_limits(robot, timing) -> AxisLimits:
    """The axes' limits of a cell robot (``cells.spec.CellRobot``): its arm's joints, then its track if it has
    one (module docstring)."""
    arm = robot.robot(0.0)
    model = getattr(arm, "model", None)
    if timing.arm_max_velocity_deg_s is not None and arm.dof == len(timing.arm_max_velocity_deg_s):
        velocity = np.radians(np.asarray(timing.arm_max_velocity_deg_s, float))
    elif hasattr(arm, "max_speed"):
        velocity = np.asarray(arm.max_speed, float)
    else:
        velocity = None if model is None else model.max_velocity
    if velocity is None or not np.isfinite(velocity).all():
        raise ConfigError(
            f"robot {robot.name} ({robot.model}): its axis speeds are not known: set [timing] arm_max_velocity_deg_s"
        )
    if timing.arm_max_acceleration_deg_s2 is not None and arm.dof == len(timing.arm_max_acceleration_deg_s2):
        acceleration = np.radians(np.asarray(timing.arm_max_acceleration_deg_s2, float))
    elif model is not None and model.max_acceleration is not None:
        acceleration = np.asarray(model.max_acceleration, float)
    else:
        acceleration = velocity / ACCELERATION_TIME_S
    if robot.track is not None:
        velocity = np.r_[velocity, robot.track.speed_mm_s]
        acceleration = np.r_[acceleration, timing.track_max_acceleration_mm_s2]
    return AxisLimits(velocity, acceleration)


class _Axes:
    """A cell robot's axes as the timing sees them: joints, then the track (mm); the gun tip by forward
    kinematics with the base moved along the track."""

    def __init__(self, robot):
        self.arm = robot.robot(0.0)
        self.dof = self.arm.dof
        self.axis = None if robot.track is None else np.asarray(robot.track.axis, float)

    def of(self, work) -> np.ndarray:
        q = np.asarray(work.q, float)[:, : self.dof]
        if self.axis is None:
            return q
        return np.column_stack([q, np.asarray(work.track_mm, float)])

    def tip(self, q) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, float))
        out = self.arm.fk(q[:, : self.dof])[:, :3, 3]
        if self.axis is not None:
            out = out + q[:, self.dof : self.dof + 1] * self.axis
        return out


def _leads(work, axes: _Axes) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2, axes) the run-up start before and the run-out end after every waypoint on the timing's axes
    (joints, then the track), and (n, 2) bool: where there is one (``cells.runups``; none without them)."""
    n = len(work.reachable)
    width = axes.dof + (axes.axis is not None)
    if work.lead_q is None:
        return np.full((n, 2, width), np.nan), np.zeros((n, 2), bool)
    lead = np.asarray(work.lead_q, float)[:, :, : axes.dof]
    if axes.axis is not None:
        lead = np.concatenate([lead, np.asarray(work.lead_track_mm, float)[:, :, None]], axis=2)
    return lead, np.isfinite(lead).all(axis=2)


def _stretches(work, axes: _Axes, q: np.ndarray, motion, jump_rad: float):
    """Every stretch the timing follows along its joint path, in the order :func:`_timed` takes them:
    (its path's rows on the timing's axes, the planned tip speeds of its segments, its waypoint indices, whether
    it has a run-up and a run-out). A run-up is the path's first segment and takes the stretch's first planned
    speed; a run-out its last, at the last planned speed."""
    lead, has = _leads(work, axes)
    for _, idx, cap, run in stroke_runs(work.strokes, work.reachable, q[:, : axes.dof], motion, jump_rad):
        way, speeds = idx[run], cap[run[:-1]]
        up, out = bool(has[way[0], 0]), bool(has[way[-1], 1])
        rows = [lead[way[0], 0][None]] * up + [q[way]] + [lead[way[-1], 1][None]] * out
        speeds = np.r_[speeds[:1]] if up else np.zeros(0), speeds, np.r_[speeds[-1:]] if out else np.zeros(0)
        yield np.vstack(rows), np.concatenate(speeds), way, up, out


def time_cell(cell, robots, job, back_offs: dict | None = None) -> list[WorkTiming]:
    """Each robot's work (``RobotWork``, in the cell's order) timed within its limits (module docstring); the
    spray stretches of all robots go to toppra's analysis together. ``back_offs``: a dict kept by the caller
    between timings of the same plan at other speeds (``cells.fit``): the programs' back-offs found
    (:func:`program_back_offs`, which depend on the joints, the limits and ``[export]`` alone) are kept in it per
    robot and not solved again."""
    timing, motion = job.timing, job.motion
    jump = math.radians(timing.joint_jump_deg)
    plans = []
    for robot, work in zip(cell.robots, robots):
        axes, limits = _Axes(robot), cell_limits(robot, timing)
        q = axes.of(work)
        stretches = list(_stretches(work, axes, q, motion, jump))
        timed = time_paths(
            [(path, cap) for path, cap, *_ in stretches],
            limits,
            axes.tip,
            check_steps=timing.check_steps,
            max_rounds=timing.max_rounds,
        ) if stretches else []  # fmt: skip
        by_first = {int(way[0]): (tm, up, out) for (_, _, way, up, out), tm in zip(stretches, timed)}
        back = program_back_offs(
            robot, job, limits, None if back_offs is None else back_offs.setdefault(robot.name, {})
        )
        plans.append(_timed(work, q, axes, limits, by_first, motion, jump, back))
    return plans


def program_back_offs(robot, job, limits, cache: dict | None = None):
    """``back(axes) -> (axes backed off, seconds) or None``: the programs' approach to (or retract from) a run's
    end at ``axes`` (joints, then the track): the gun moved straight back along its axis by ``[export]
    approach_mm`` or the first shorter share of it the arm reaches on the same branch
    (``programs.build._back_off_from``, the programs' own), and the time of that line: the longer of the
    rest-to-rest joint move and the line's length at ``[export] approach_speed_mm_s``. None for a robot that
    is not a six-axis arm, or with ``approach_mm`` 0. ``cache``: the answers by joints, kept between calls."""
    if job.export.approach_mm <= 0 or robot.is_gantry or robot.robot(0.0).dof != 6:
        return None
    from sprayplan.programs.arms import ArmCell
    from sprayplan.programs.build import _back_off_from

    cell = ArmCell(robot, job.paths.standoff_mm)
    speed = float(job.export.approach_speed_mm_s)
    cache = {} if cache is None else cache

    def back(axes):
        key = np.asarray(axes, float).tobytes()
        if key not in cache:
            pose = cell.target_poses(np.asarray(axes, float)[None])[0]
            found = _back_off_from(cell, job.export, pose, np.asarray(axes, float))
            if found is None:
                cache[key] = None
            else:
                distance, _, joints = found
                moved = np.r_[joints, np.asarray(axes, float)[6:]]
                n = len(limits.velocity)  # a robot without a track may be given one at 0 (the schedule's rows)
                seconds = point_to_point(np.asarray(axes, float)[:n], moved[:n], limits).duration_s
                cache[key] = moved, max(seconds, distance / speed)
        return cache[key]

    return back


def _timed(work, q, axes: _Axes, limits, timed: dict, motion, jump_rad: float, back=None) -> WorkTiming:
    """The time stamps of one robot's work, given its stretches' timings by their first waypoint (each with
    whether it has a run-up and a run-out: the robot moves to the run-up's start, and on from the run-out's
    end). ``back`` (:func:`program_back_offs`): the programs' approach and retract at every run's ends, timed as part
    of the moves between runs."""
    n = len(q)
    t = np.full(n, np.nan)
    speed = np.full(n, np.nan)
    lead_s = np.zeros((n, 2))
    lead, _ = _leads(work, axes)
    reached = np.flatnonzero(work.reachable)
    clock, spray, moves, slowed = 0.0, 0.0, 0.0, 0
    worst = {"velocity": 0.0, "acceleration": 0.0, "tip_speed": 0.0, "stretched": 0}
    current = q[reached[0]] if len(reached) else None
    if len(reached) and np.isfinite(lead[reached[0], 0]).all():
        current = lead[reached[0], 0]  # the work starts where the first waypoint's run-up does
    start = 0
    at_end = False  # the robot stands at a run's end (it retracts before it moves on)

    def leave() -> float:
        """The retract from the run's end the robot stands at (``back``): its seconds; ``current`` moved."""
        nonlocal current, at_end
        found = back(current) if back is not None and at_end else None
        at_end = False
        if found is None:
            return 0.0
        current = found[0]
        return found[1]

    def enter(goal) -> float:
        """A joint move from ``current`` to the approach pose of the run starting at ``goal``, then the
        approach (``back``; without a back-off the joint move to ``goal``): its seconds; ``current`` at goal."""
        nonlocal current
        found = back(goal) if back is not None else None
        seconds = 0.0
        if found is not None:
            seconds += point_to_point(current, found[0], limits).duration_s + found[1]
        else:
            seconds += point_to_point(current, goal, limits).duration_s
        current = goal
        return seconds

    for s in work.strokes:
        idx = np.arange(start, start + len(s))
        start += len(s)
        ok = work.reachable[idx]
        if current is None or not ok.any():
            continue
        if not s.spray_on:
            # a joint move to every row after the first, in turn, from rest to rest (the programs' routes are
            # joint moves to fine points, ``programs.build.route_moves``); the first row is where the stroke
            # before ended, the robot there or at its run-out's end (``current``), from where it retracts;
            # the last is the next stroke's first waypoint (where that has a run-up, the run-up's start),
            # reached by the approach
            rows = idx[ok]
            legs = rows[1:] if len(rows) > 1 else rows
            t[rows[0]] = clock
            move = leave()
            for r in legs:
                if r == rows[-1]:
                    goal = lead[start, 0] if start < n and np.isfinite(lead[start, 0]).all() else q[r]
                    move += enter(goal)
                else:
                    move += point_to_point(current, q[r], limits).duration_s
                    current = q[r]
                clock += move
                moves += move
                move = 0.0
                t[r] = clock
            continue
        cap = segment_speeds(
            s.tcp, s.points, motion.gun_speed_mm_s, motion.speed_along, motion.max_speed_ratio, s.dwell
        )
        bound = np.minimum(np.r_[cap[:1], cap], np.r_[cap, cap[-1:]]) if len(cap) else np.full(len(s), np.inf)
        for run in joint_runs(ok, q[idx, : axes.dof], jump_rad):
            found = timed.get(int(idx[run[0]])) if len(run) >= 2 else None
            stretch, up, out = found if found is not None else (None, False, False)
            first, last = int(idx[run[0]]), int(idx[run[-1]])
            goal = lead[first, 0] if up else q[first]
            move = 0.0
            if np.abs(goal - current).max(initial=0.0) > 0:  # (after a transfer the robot is there already)
                move = leave() + enter(goal)
            at_end = False
            clock += move
            moves += move
            current = q[last]
            at_end = True
            if stretch is None:
                t[idx[run]] = clock
                continue
            inner = slice(int(up), len(stretch.t_s) - int(out))  # the waypoints' samples, without run-up and -out
            t[idx[run]] = clock + stretch.t_s[inner]
            speed[idx[run]] = stretch.speed_mm_s[inner]
            if up:
                lead_s[first, 0] = stretch.t_s[1] - stretch.t_s[0]
            if out:
                lead_s[last, 1] = stretch.t_s[-1] - stretch.t_s[-2]
                current = lead[last, 1]
            slowed += int((stretch.speed_mm_s[inner] < SLOWED_SHARE * bound[run]).sum())
            clock += stretch.duration_s
            spray += stretch.duration_s
            for key in ("velocity", "acceleration", "tip_speed"):
                worst[key] = max(worst[key], float(stretch.worst[key]))
            worst["stretched"] += int(stretch.stretch > 1.0)
    # unreached waypoints: when the robot passes on (its last time before them; 0 before any)
    filled = np.where(np.isnan(t), -np.inf, t)
    t = np.maximum.accumulate(filled) if n else filled
    t = np.where(np.isfinite(t), t, 0.0)
    end = max(float(t[-1]) if n else 0.0, clock if n else 0.0)  # a last stretch's run-out ends after its waypoint
    return WorkTiming(t, speed, float(spray), float(moves), end, slowed, worst, lead_s)


def timed_cell(cell, robots, job, report: dict, timed: list | None = None) -> tuple:
    """The robots' work (``RobotWork``) with the timed arrival at every waypoint (``t_s``; no waits: ``wait_s``
    0), timed by :func:`time_cell` (or as ``timed`` gives it, that call's answer); ``report`` (the cell plan's)
    gets each robot's timed cycle and timing summary beside its length over speed, and the cell's timed cycle,
    the longest robot's."""
    timed = time_cell(cell, robots, job) if timed is None else timed
    for r, tm in zip(robots, timed):
        entry = report["robots"][r.name]
        entry["length_over_speed_s"] = entry["cycle_time_s"]
        entry["cycle_time_s"] = round(tm.cycle_s, 3)
        entry["timing"] = tm.summary()
    report["cycle_time_length_over_speed_s"] = report["cycle_time_s"]
    report["cycle_time_s"] = max((round(tm.cycle_s, 3) for tm in timed), default=0.0)
    report["cycle_time_rule"] = (
        "each robot timed within its axes' limits (toppra along the spray stretches, ruckig between them); "
        "the cell's is the longest robot's"
    )
    return with_times(robots, timed)


def with_times(robots, timed) -> tuple:
    """The robots' work with the time stamps of their timings (``WorkTiming``), no waits; the run-ups' and
    run-outs' times where they have them."""
    return tuple(
        dataclasses.replace(
            r,
            t_s=tm.t_s.copy(),
            wait_s=np.zeros(len(r.strokes)),
            lead_s=None if r.lead_q is None or tm.lead_s is None else tm.lead_s.copy(),
        )
        for r, tm in zip(robots, timed)
    )


def timed_factors(robots, job) -> list[np.ndarray]:
    """Per robot, each waypoint's time factor at the timed speeds (``timing.stage.waypoint_dwell`` over its
    ``t_s``, as the gantry's film at the timed speeds takes them): the planned factor off the timed stretches."""
    from sprayplan.timing.stage import waypoint_dwell

    jump = math.radians(job.timing.joint_jump_deg)
    return [waypoint_dwell(r.strokes, r.reachable, r.q, r.t_s, job.motion, jump) for r in robots]
