"""The ``collision`` stage: every waypoint and motion of a plan checked, waypoints in collision repaired first.

For each stroke with a waypoint in collision (spray passes, touch-ups and transfers alike), the repairs a
programmer would try, in this order, the first that frees the whole stroke kept (:data:`REPAIRS`):

``branch``
    The stroke solved again from each other analytic IK branch of its first pose (the solver then follows
    that branch along the stroke).
``roll``
    The gun turned about its own axis (:data:`ROLLS_DEG`): the spray is the same, the flange and the arm move.
``tilt``
    The gun axis tilted about the spray target by ``[collision] tilt_deg`` (default 80 % of the axis
    tolerance) toward four sides: the target stays, the axis error is the tilt.
``platform``
    For a station still flagged after the three above, the gantry station raised by ``platform_raise_mm``
    (once, twice, three times), the station solved again from home and its strokes repaired as above; kept
    when fewer of its waypoints are flagged and none that was reachable is lost.

A candidate is kept only when every waypoint the stroke reached before is still reached, within the seed's
position and axis tolerances against the *original* poses (``[kinematics] position_tol_mm``,
``axis_tol_deg``), and no waypoint of the stroke is in collision. What no repair frees stays flagged
(``StationPlan.collision``); nothing is silently kept.

Motions (:func:`flag_motions`): between two checked waypoints whose least slacks are ``S_a`` and ``S_b``
(distance minus the pair's gap, over every pair) and whose joint motion moves no body point more than ``B``
(``collision.motion``), every configuration in between keeps a slack of at least ``(S_a + S_b - B) / 2``: each
distance is 1-Lipschitz in the bodies' displacement, at most ``B s`` from one end and ``B (1 - s)`` from the
other. Where that is not negative the motion is free; the others are bisected, then checked on a fixed grid
(:func:`flag_motions`). A motion in collision flags the waypoint it arrives at
(``StationPlan.motion_collision``); transfers are not yet re-routed (retract, via pose, joint-space detour).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from sprayplan.collision.cell import CellCollision
from sprayplan.collision.motion import motion_bound_mm
from sprayplan.config import CollisionConfig, JobConfig, KinematicsConfig
from sprayplan.errors import InputError
from sprayplan.progress import Progress, counted
from sprayplan.robots.gantry import Gantry, pose_errors
from sprayplan.robots.model import TAU
from sprayplan.robots.stage import HOME_JOINTS
from sprayplan.robots.ur_ik import ur_ik
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import REPAIR_KINDS, Plan, StationPlan

log = logging.getLogger(__name__)

#: The repairs, in the order they are tried (``types.REPAIR_KINDS`` less the empty one).
REPAIRS = REPAIR_KINDS[:-1]
#: The rolls about the gun axis tried, degrees.
ROLLS_DEG = (90.0, -90.0, 180.0, 45.0, -45.0, 135.0, -135.0)
#: How many of a stroke's colliding waypoints a candidate is checked at before the whole stroke.
QUICK = 16
#: How many waypoints spread along a stroke the candidates left are checked at before any is checked at all.
SPREAD = 64


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    out = np.eye(4)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[i, i], out[i, j], out[j, i], out[j, j] = c, -s, s, c
    return out


def pair_names(cell: CellCollision) -> np.ndarray:
    """The cell's body pairs as ``StationPlan.collision_with`` names them, ``"elbow/part"``."""
    return np.array([f"{a}/{b}" for a, b in cell.pairs], dtype=object)


def _slices(st: StationPlan) -> list[slice]:
    out, start = [], 0
    for s in st.strokes:
        out.append(slice(start, start + len(s)))
        start += len(s)
    return out


@dataclasses.dataclass
class _Station:
    """A station's arrays while it is repaired (mutable, private)."""

    platform: np.ndarray
    q9: np.ndarray
    reachable: np.ndarray
    method: np.ndarray
    position: np.ndarray
    axis: np.ndarray
    branch_change: np.ndarray
    collision: np.ndarray
    distance: np.ndarray
    pair: np.ndarray
    slack: np.ndarray
    repair: np.ndarray
    changed: np.ndarray

    @classmethod
    def of(cls, st: StationPlan) -> _Station:
        n = len(st)
        return cls(
            np.array(st.platform_mm),
            np.array(st.q9),
            np.array(st.reachable),
            np.array(st.method, dtype=object),
            np.array(st.position_error_mm),
            np.array(st.axis_error_deg),
            np.array(st.branch_change),
            np.zeros(n, bool),
            np.full(n, np.nan),
            np.full(n, "", dtype=object),
            np.full(n, np.inf),
            np.full(n, "", dtype=object),
            np.zeros(n, bool),
        )

    def copy(self) -> _Station:
        """A copy whose arrays can be changed without changing this one's."""
        return dataclasses.replace(self, **{f.name: getattr(self, f.name).copy() for f in dataclasses.fields(self)})

    def check(self, cell: CellCollision, rows=None) -> None:
        rows = np.flatnonzero(self.reachable) if rows is None else rows
        self.collision[:] = False
        self.distance[:] = np.nan
        self.pair[:] = ""
        self.slack[:] = np.inf
        if not len(rows):
            return
        found = cell.check(self.q9[rows])
        self.collision[rows] = found.in_collision
        self.distance[rows] = found.distance_mm
        self.pair[rows] = pair_names(cell)[found.column]
        self.slack[rows] = found.slack_mm

    def plan(self, st: StationPlan, motion: np.ndarray) -> StationPlan:
        return StationPlan(
            st.index,
            self.platform,
            st.strokes,
            self.q9,
            self.reachable,
            self.method,
            self.position,
            self.axis,
            self.branch_change,
            collision=self.collision,
            motion_collision=motion,
            collision_distance_mm=self.distance,
            collision_with=self.pair,
            repair=self.repair,
        )


class Repairer:
    """The repairs of one plan's strokes (see the module docstring).

    Candidates are solved by the closed-form IK, all branches of a candidate's poses at once (one
    :func:`~sprayplan.robots.ur_ik.ur_ik` call), each branch followed along the stroke with whole turns chosen
    so that the path stays in the joint limits nearest the arm's previous joints; a branch is a candidate only
    where it is valid at every waypoint the stroke reached before and no joint steps more than
    ``[kinematics]``'s jump threshold between waypoints. The candidates are checked together at a few of the
    stroke's colliding waypoints first, then the first to pass at every waypoint.
    """

    JUMP_RAD = 0.5

    def __init__(self, cell: CellCollision, gantry: Gantry, kinematics: KinematicsConfig, config: CollisionConfig):
        self.cell, self.gantry, self.kin = cell, gantry, kinematics
        tilt = 0.8 * kinematics.axis_tol_deg if config.tilt_deg is None else config.tilt_deg
        self.tilt = math.radians(min(tilt, kinematics.axis_tol_deg))
        self.names = pair_names(cell)

    def _poses(self, base: np.ndarray):
        """(repair, poses) in the order tried: the stroke's own poses (other branches), rolled, tilted."""
        yield "branch", base
        for angle in ROLLS_DEG:
            yield "roll", base @ _rot(2, math.radians(angle))
        target2gun = self.gantry.gun.target2gun
        gun2target = np.linalg.inv(target2gun)
        for axis, sign in ((0, 1), (0, -1), (1, 1), (1, -1)):
            yield "tilt", base @ target2gun @ _rot(axis, sign * self.tilt) @ gun2target

    def _branches(self, poses: np.ndarray, platform: np.ndarray, start: np.ndarray) -> list[np.ndarray]:
        """The joint paths (n, 6) of every analytic branch valid along ``poses`` (module docstring)."""
        robot = self.gantry.robot
        flange = self.gantry.flange_targets(poses, platform)
        solutions = ur_ik(robot, flange)
        lower, upper = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
        out = []
        for b in range(solutions.q.shape[1]):
            if not solutions.valid[:, b].all():
                continue
            q = np.unwrap(solutions.q[:, b], axis=0)
            k_lo = np.ceil((lower - q.min(axis=0)) / TAU - 1e-12)
            k_hi = np.floor((upper - q.max(axis=0)) / TAU + 1e-12)
            if (k_lo > k_hi).any():
                continue
            k = np.clip(np.rint((start - q[0]) / TAU), k_lo, k_hi)
            q = q + TAU * k
            if len(q) > 1 and np.abs(np.diff(q, axis=0)).max() > self.JUMP_RAD:
                continue
            out.append(q)
        return out

    def candidates(self, base: np.ndarray, platform: np.ndarray, start: np.ndarray, rows: np.ndarray):
        """(repair, q9 (len(rows), 9)) for a stroke's reached waypoints ``rows``, in the order tried."""
        for repair, poses in self._poses(base):
            for q in self._branches(poses[rows], platform, start):
                yield repair, np.column_stack([q, np.broadcast_to(platform, (len(q), 3))])

    def best(self, base, platform, start, rows, colliding):
        """The first candidate free at every row, as ``(repair, q9, checks)``; else None.

        All candidates are checked together at a few of the ``colliding`` rows (indices into ``rows``), the
        survivors together at :data:`SPREAD` rows spread along the stroke, and only those left at every row, in
        the order tried, until one is free."""
        found = list(self.candidates(base, platform, start, rows))
        n = len(rows)
        quick = colliding[np.linspace(0, len(colliding) - 1, min(QUICK, len(colliding))).astype(int)]
        spread = np.unique(np.linspace(0, n - 1, min(SPREAD, n)).astype(int))
        for sample in (quick, spread):
            if not found or not len(sample):
                continue
            hit = self.cell.collides(np.concatenate([q9[sample] for _, q9 in found]))
            hit = hit.reshape(len(found), len(sample)).any(axis=1)
            found = [c for c, h in zip(found, hit) if not h]
        for repair, q9 in found:
            if not self.cell.collides(q9).any():
                return repair, q9, self.cell.check(q9)
        return None

    def repair_stroke(self, work: _Station, stroke, sl: slice, start: np.ndarray, platform=None) -> str:
        """Try the repairs on one stroke of ``work`` in place; returns the repair kept ('' when none)."""
        platform = work.platform if platform is None else platform
        reached = np.flatnonzero(work.reachable[sl])
        if not len(reached):
            return ""
        colliding = np.flatnonzero(work.collision[sl][reached])
        kept = self.best(stroke_poses(stroke), platform, start, reached, colliding)
        if kept is None:
            return ""
        repair, q9, checks = kept
        index = np.arange(sl.start, sl.stop)[reached]
        self._apply(work, index, q9, checks)
        was = index[colliding]
        work.repair[was] = repair
        return repair

    def _apply(self, work: _Station, index: np.ndarray, q9: np.ndarray, checks) -> None:
        work.q9[index] = q9
        work.method[index] = "analytic"
        work.branch_change[index] = False
        work.collision[index] = False
        work.distance[index] = checks.distance_mm
        work.pair[index] = self.names[checks.column]
        work.slack[index] = checks.slack_mm
        work.changed[index] = True

    def errors(self, work: _Station, st: StationPlan) -> None:
        """Position and axis errors of every reached waypoint against the poses the plan asked for."""
        wanted = np.concatenate([stroke_poses(s) for s in st.strokes]) @ self.gantry.gun.target2gun
        position, axis = pose_errors(self.gantry.target2world(work.q9), wanted)
        work.position = np.where(work.changed, position, work.position)
        work.axis = np.where(work.changed, np.degrees(axis), work.axis)

    def repair_station(self, work: _Station, st: StationPlan) -> None:
        """Every stroke of a station with a waypoint in collision, in order."""
        previous = HOME_JOINTS
        for stroke, sl in zip(st.strokes, _slices(st)):
            if work.collision[sl].any():
                self.repair_stroke(work, stroke, sl, previous)
            reached = np.flatnonzero(work.reachable[sl])
            if len(reached):
                previous = work.q9[sl][reached[-1], :6]


def _raised(repairer: Repairer, st: StationPlan, work: _Station, config: CollisionConfig) -> _Station:
    """The platform repair of a station still flagged: the station raised, each stroke's first free candidate
    there (or, for a stroke with none, its own branch there, flagged); the best raise kept when it flags fewer
    waypoints and reaches every waypoint reached before. ``work`` unchanged otherwise."""
    best = work
    slices = _slices(st)
    for k in (1, 2, 3):
        if config.platform_raise_mm <= 0:
            break
        platform = work.platform + np.array([0.0, 0.0, k * config.platform_raise_mm])
        trial = dataclasses.replace(work.copy(), platform=platform)
        previous, complete = HOME_JOINTS, True
        for stroke, sl in zip(st.strokes, slices):
            reached = np.flatnonzero(work.reachable[sl])
            if not len(reached):
                continue
            colliding = np.flatnonzero(work.collision[sl][reached])
            index = np.arange(sl.start, sl.stop)[reached]
            kept = repairer.best(stroke_poses(stroke), platform, previous, reached, colliding)
            if kept is None:
                complete = False
                break
            _, q9, checks = kept
            repairer._apply(trial, index, q9, checks)
            trial.repair[index[colliding]] = "platform"
            previous = q9[-1, :6]
        if not complete:
            continue
        best = trial
        break
    return best


#: The margin over their gaps within which pairs are measured exactly for the motions' proof, mm: slacks are
#: known up to about this, and a motion moving bodies less than twice it is proven free at once.
MOTION_MARGIN_MM = 100.0
#: Bisections of the motions not proven at once, before the rest are walked (``CellCollision.check_motion``).
BISECTIONS = 4


def flag_motions(cell: CellCollision, stations: list[_Station]) -> tuple[list[np.ndarray], int, int]:
    """Per station, the waypoints whose incoming motion is in collision (module docstring); and how many
    motions were checked and how many were in collision.

    A motion is proven free when ``(S_a + S_b - B) / 2 >= 0``; the rest are split at their middle (the halves'
    bounds are ``B / 2``) up to :data:`BISECTIONS` times, all midpoints of a level checked in one call; what is
    still unproven is checked on a grid of ``ceil(B / motion_step_mm)`` steps (``collision.motion``'s fixed
    grid: a configuration between two checks is within half a step of one, so each check must keep half a
    step over its gaps), all in one call. A motion that ends at a waypoint in collision is in collision.
    """
    flags = [np.zeros(len(w.q9), bool) for w in stations]
    rows = [(i, j) for i, w in enumerate(stations) for j in np.flatnonzero(w.reachable)]
    if len(rows) < 2:
        return flags, 0, 0
    q9 = np.array([stations[i].q9[j] for i, j in rows])
    hit_at = np.array([stations[i].collision[j] for i, j in rows])
    slack = cell.check(q9, margin_mm=MOTION_MARGIN_MM).slack_mm
    m = len(q9) - 1
    in_collision = hit_at[:-1] | hit_at[1:]
    # open motions as segments (index, s0, s1, slack at s0, slack at s1)
    index = np.flatnonzero(~in_collision)
    s0, s1 = np.zeros(len(index)), np.ones(len(index))
    a_slack, b_slack = slack[index], slack[index + 1]
    total = motion_bound_mm(q9[index], q9[index + 1], cell.reach_radii_mm)
    for level in range(BISECTIONS + 1):
        bound = total * (s1 - s0)
        open_ = (a_slack + b_slack - bound) / 2.0 < 0
        if not open_.any() or level == BISECTIONS:
            break
        index, s0, s1, a_slack, b_slack, total = (v[open_] for v in (index, s0, s1, a_slack, b_slack, total))
        mid = (s0 + s1) / 2.0
        q_mid = q9[index] + mid[:, None] * (q9[index + 1] - q9[index])
        mid_slack = cell.check(q_mid, margin_mm=MOTION_MARGIN_MM).slack_mm
        index = np.concatenate([index, index])
        s0, s1 = np.concatenate([s0, mid]), np.concatenate([mid, s1])
        a_slack, b_slack = np.concatenate([a_slack, mid_slack]), np.concatenate([mid_slack, b_slack])
        total = np.concatenate([total, total])
    else:  # pragma: no cover - the loop always breaks
        open_ = np.zeros(len(index), bool)
    # what is still open: every piece checked on a grid at most motion_step_mm of bound apart, all at once,
    # each check against its gaps plus half a step (every configuration between is within half a step of one)
    index, s0, s1, total = index[open_], s0[open_], s1[open_], total[open_]
    step = cell.config.motion_step_mm
    counts = np.maximum(1, np.ceil(total * (s1 - s0) / step - 1e-12)).astype(int)
    owner = np.repeat(np.arange(len(index)), counts + 1)
    within = np.arange(len(owner)) - np.repeat(np.cumsum(counts + 1) - (counts + 1), counts + 1)
    s = s0[owner] + (s1 - s0)[owner] * within / counts[owner]
    k = index[owner]
    if len(k):
        grid = q9[k] + s[:, None] * (q9[k + 1] - q9[k])
        hit = cell.collides(grid, extra_mm=step / 2.0)
        in_collision[np.unique(k[hit])] = True
    for k in np.flatnonzero(in_collision):
        i, j = rows[k + 1]
        flags[i][j] = True
    return flags, m, int(in_collision.sum())


def collision_stage(plan: Plan, whole, job: JobConfig, gantry: Gantry, progress: Progress | None = None):
    """The plan with every waypoint and motion checked against ``whole`` (the part before its region was cut,
    so the arm does not pass through the unpainted rest), the floor and the cell, waypoints in collision
    repaired first (module docstring). Returns the plan and a summary dict for the totals."""
    config = job.collision
    cell = CellCollision(gantry, whole, config)
    repairer = Repairer(cell, gantry, job.kinematics, config)
    step = counted(progress, "collision", len(plan.stations))
    works, before, by_repair = [], 0, dict.fromkeys(REPAIRS, 0)
    for st in plan.stations:
        work = _Station.of(st)
        work.check(cell)
        found = int(work.collision.sum())
        before += found
        if found and config.repair:
            repairer.repair_station(work, st)
            if work.collision.any():
                work = _raised(repairer, st, work, config)
        repairer.errors(work, st)
        for name in REPAIRS:
            by_repair[name] += int((work.repair == name).sum())
        works.append(work)
        step()
    motion_flags, motions, motion_hits = flag_motions(cell, works)
    stations = tuple(w.plan(st, m) for w, st, m in zip(works, plan.stations, motion_flags))
    flagged = sum(int(w.collision.sum()) for w in works)
    summary = {
        "checked": True,
        "clearance_mm": config.clearance_mm,
        "floor_z_mm": round(cell.floor_z_mm, 3),
        "waypoints_checked": int(sum(w.reachable.sum() for w in works)),
        "in_collision_before_repair": before,
        "repaired": int(sum(by_repair.values())),
        "repaired_by": by_repair,
        "flagged_waypoints": flagged,
        "motions_checked": motions,
        "flagged_motions": motion_hits,
    }
    if job.export.strict and (flagged or motion_hits):
        first = next((i, w) for i, w in enumerate(works) if w.collision.any()) if flagged else None
        where = ""
        if first is not None:
            i, w = first
            j = int(np.argmax(w.collision))
            where = f" (the first: station {i + 1}, waypoint {j}, {w.pair[j]} at {w.distance[j]:.1f} mm)"
        raise InputError(
            f"--strict: {flagged} waypoints and {motion_hits} motions in collision after repairs{where}: nothing written"
        )
    return dataclasses.replace(plan, stations=stations), summary
