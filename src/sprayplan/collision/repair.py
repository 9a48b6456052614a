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

Motions (:func:`flag_motions`): every motion between consecutive reached waypoints proven free in bulk or
checked on a grid (:func:`sprayplan.collision.proof.motion_hits`). A motion in collision flags the waypoint it
arrives at (``StationPlan.motion_collision``). A spray stroke whose waypoints are all free but a motion between
two of them is not gets the same repairs (:func:`repair_motions`). Then the transfers in collision are re-routed
(:mod:`sprayplan.collision.transfers`: a longer retract, via poses at a safe height, a joint-space detour); a
transfer no route frees stays flagged. Motions inside a spray stroke cannot be re-routed (the path is fixed):
what the repairs do not free stays flagged.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from types import SimpleNamespace

import numpy as np

from sprayplan.collision.cell import CellCollision
from sprayplan.collision.proof import MOTION_MARGIN_MM, end_slacks, motion_hits
from sprayplan.collision.transfers import Router, route_stroke
from sprayplan.config import CollisionConfig, JobConfig, KinematicsConfig
from sprayplan.errors import InputError
from sprayplan.progress import Progress, counted
from sprayplan.robots.gantry import Gantry, pose_errors
from sprayplan.robots.model import TAU
from sprayplan.robots.stage import HOME_JOINTS
from sprayplan.robots.ur_ik import ur_ik
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import TRANSFER_REPAIRS, WAYPOINT_REPAIRS, Plan, StationPlan

log = logging.getLogger(__name__)

#: The waypoint repairs, in the order they are tried (``types.WAYPOINT_REPAIRS``; transfers are re-routed
#: after them, ``collision.transfers``).
REPAIRS = WAYPOINT_REPAIRS
#: The repairs of a stroke in place, also tried for a spray stroke whose only problem is a motion
#: (:func:`repair_motions`).
MOTION_REPAIRS = ("branch", "roll", "tilt")
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
    motion_repaired: np.ndarray

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

    def spliced(self, sl: slice, rows: _Station) -> _Station:
        """This station's arrays with the rows ``sl`` replaced by ``rows``'s (the platform kept)."""
        out = {
            f.name: np.concatenate(
                [getattr(self, f.name)[: sl.start], getattr(rows, f.name), getattr(self, f.name)[sl.stop :]]
            )
            for f in dataclasses.fields(self)
            if f.name != "platform"
        }
        return _Station(platform=self.platform, **out)

    def plan(self, st: StationPlan, motion: np.ndarray, strokes=None) -> StationPlan:
        return StationPlan(
            st.index,
            self.platform,
            st.strokes if strokes is None else strokes,
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
        radii = self.cell.reach_radii_mm
        for repair, poses in self._poses(base):
            branches = self._branches(poses[rows], platform, start)
            # nearest first: the stroke then starts where the arm is, not across a branch change
            branches.sort(key=lambda q: float(np.abs(q[0] - start) @ radii))
            for q in branches:
                yield repair, np.column_stack([q, np.broadcast_to(platform, (len(q), 3))])

    def best(self, base, platform, start, rows, colliding, keep=None):
        """The first candidate free at every row, as ``(repair, q9, checks)``; else None.

        All candidates are checked together at a few of the ``colliding`` rows (indices into ``rows``), the
        survivors together at :data:`SPREAD` rows spread along the stroke, and only those left at every row, in
        the order tried, until one is free. ``keep``: a further test ``(q9, checks) -> bool`` a candidate free
        at every row must pass (its checks then exact within the motions' margin,
        :data:`~sprayplan.collision.proof.MOTION_MARGIN_MM`, as the motions' proof needs them)."""
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
        margin = None if keep is None else MOTION_MARGIN_MM
        for repair, q9 in found:
            if self.cell.collides(q9).any():  # the yes/no check first: cheap, and most candidates fail it
                continue
            checks = self.cell.check(q9, margin_mm=margin)
            if not checks.in_collision.any() and (keep is None or keep(q9, checks)):
                return repair, q9, checks
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


def repair_motions(
    repairer: Repairer, st: StationPlan, work: _Station, motion: np.ndarray, q_prev=None, next_move=None
) -> dict:
    """The waypoint repairs for the spray strokes of a station whose waypoints are all free but a motion
    between two of them is in collision (``motion``: the station's motion flags, :func:`flag_motions`);
    ``work`` changed in place. Returns how many such motions were freed, by repair.

    A candidate (another branch, a roll, a tilt: the stroke's poses within the seed's tolerances, as
    :meth:`Repairer.repair_stroke` keeps them) is kept when its waypoints are free, every motion between them
    is proven free, and the motions into and out of the stroke (from the last reached waypoint before it, to
    the first after it; across the station moves, ``q_prev`` the last reached joints of the station before and
    ``next_move`` the first of the one after with its motion flag) flag fewer motions in all than before. The waypoints the freed motions arrive at take
    the repair's name (``StationPlan.repair``), marked as motion repairs (``_Station.motion_repaired``) where
    they had none; the stroke's waypoints a branch, roll or tilt freed before take the new one's name."""
    freed = dict.fromkeys(MOTION_REPAIRS, 0)
    rows = np.flatnonzero(work.reachable)
    previous = HOME_JOINTS
    for stroke, sl in zip(st.strokes, _slices(st)):
        reached = np.flatnonzero(work.reachable[sl])
        index = np.arange(sl.start, sl.stop)[reached]
        inner = np.flatnonzero(motion[index][1:]) + 1  # into index[1:], within the stroke
        if stroke.spray_on and len(inner) and not work.collision[index].any():
            before = rows[rows < index[0]]
            after = rows[rows > index[-1]]
            q_in = work.q9[before[-1]] if len(before) else q_prev
            q_out, out_flag = (work.q9[after[0]], motion[after[0]]) if len(after) else (next_move or (None, False))
            flagged = len(inner) + int(q_in is not None and motion[index[0]]) + int(q_out is not None and out_flag)

            def keep(q9, checks, q_in=q_in, q_out=q_out, flagged=flagged):
                if motion_hits(repairer.cell, q9[:-1], q9[1:], checks.slack_mm[:-1], checks.slack_mm[1:]).any():
                    return False
                ends = [(q_in, q9[0]), (q9[-1], q_out)]
                legs = [(a, b) for a, b in ends if a is not None and b is not None]
                if not legs:
                    return True
                a, b = (np.array(v) for v in zip(*legs))
                return int(motion_hits(repairer.cell, a, b).sum()) < flagged

            kept = repairer.best(stroke_poses(stroke), work.platform, previous, reached, inner, keep)
            if kept is not None:
                repair, q9, checks = kept
                repairer._apply(work, index, q9, checks)
                # waypoints freed before by another candidate of the stroke are now freed by this one
                redone = index[np.isin(work.repair[index], MOTION_REPAIRS)]
                work.repair[redone] = repair
                arrived = index[inner][work.repair[index[inner]] == ""]
                work.repair[arrived] = repair
                work.motion_repaired[arrived] = True
                freed[repair] += len(inner)
        if len(reached):
            previous = work.q9[sl][reached[-1], :6]
    return freed


def flag_motions(cell: CellCollision, stations: list[_Station], known=None) -> tuple[list[np.ndarray], int, int]:
    """Per station, the waypoints whose incoming motion is in collision (module docstring); and how many
    motions were checked and how many were in collision.

    The motions join consecutive reachable waypoints, across stations too (the station move), and are proven
    or checked by :func:`sprayplan.collision.proof.motion_hits`. A motion that ends at a waypoint in
    collision is in collision. ``known``: ``(flags, moved)``, the flags found before and per station the
    waypoints moved since; only the motions with an end moved are checked again.
    """
    flags = [np.zeros(len(w.q9), bool) for w in stations]
    rows = [(i, j) for i, w in enumerate(stations) for j in np.flatnonzero(w.reachable)]
    if len(rows) < 2:
        return flags, 0, 0
    q9 = np.array([stations[i].q9[j] for i, j in rows])
    hit_at = np.array([stations[i].collision[j] for i, j in rows])
    m = len(q9) - 1
    in_collision = hit_at[:-1] | hit_at[1:]
    todo = ~in_collision
    if known is not None:
        before, moved = known
        in_collision = np.array([before[i][j] for i, j in rows[1:]])
        at = np.array([moved[i][j] for i, j in rows])
        todo = at[:-1] | at[1:]
        in_collision[todo] = (hit_at[:-1] | hit_at[1:])[todo]
        todo &= ~in_collision
    index = np.flatnonzero(todo)
    ends = np.unique(np.concatenate([index, index + 1]))
    slack = np.zeros(len(q9))
    slack[ends] = end_slacks(cell, q9[ends])
    in_collision[index] = motion_hits(cell, q9[index], q9[index + 1], slack[index], slack[index + 1])
    for k in np.flatnonzero(in_collision):
        i, j = rows[k + 1]
        flags[i][j] = True
    return flags, m, int(in_collision.sum())


def _reroute(
    router: Router, repairer: Repairer, st: StationPlan, work: _Station, motion: np.ndarray, job, place, counts
):
    """A station's transfers in collision re-routed (``collision.transfers``): returns its strokes, its
    arrays and its motion flags with every route found in place of its transfer; ``counts`` updated.

    A transfer is in collision when a waypoint of it, a motion into one or the motion into the stroke after
    it is. Its route runs from the last reached joints of the stroke before to the first of the stroke after
    (both must be free); the route's legs are proven free, so no motion of it, nor the one into the stroke
    after, is flagged. Transfers are taken last to first, so that the rows of those before stay put.

    A transfer whose ends differ by whole turns of a joint (the arm turning a joint round, through the part,
    between two strokes that need no such turn) is first routed with those turns taken out of the station's
    rows after it, or else out of all those before it, or else out of the stroke before it, whose own transfer
    in is taken next (:func:`unwound`: the same poses, within the joint limits); the shift is kept only with a
    route found (``transfers_unwound`` counts them)."""
    strokes = list(st.strokes)
    slices = _slices(st)
    standoff = job.paths.standoff_mm
    work = work.copy()
    shifted = False
    for k in range(len(strokes) - 2, 0, -1):
        if strokes[k].spray_on:
            continue
        sl = slices[k]
        before = np.flatnonzero(work.reachable[slices[k - 1]])
        after = np.flatnonzero(work.reachable[slices[k + 1]])
        if not len(before) or not len(after):
            continue
        ia, ib = slices[k - 1].start + before[-1], slices[k + 1].start + after[0]
        if not (work.collision[sl].any() or motion[sl].any() or motion[ib]):
            continue
        counts["in_collision"] += 1
        found = None
        if work.collision[ia] or work.collision[ib]:  # no route can free an end
            counts["end_in_collision"] += 1
        else:
            # the same poses on one side of the transfer, without its whole turns of a joint: the rows after it
            # shifted, or else all the rows before it, or else the stroke before it (whose own transfer in is
            # taken next)
            later = ib + np.flatnonzero(work.reachable[ib:])
            earlier = np.flatnonzero(work.reachable[: ia + 1])
            stroke_before = slices[k - 1].start + before
            robot = repairer.gantry.robot
            for rows, turns in (
                (later, unwound(robot, work.q9[ia], work.q9[later])),
                (earlier, unwound(robot, work.q9[ib], work.q9[earlier[::-1]])),
                (stroke_before, unwound(robot, work.q9[ib], work.q9[stroke_before[::-1]])),
            ):
                if turns is None:
                    continue
                q_a, q_b = (work.q9[ia], work.q9[ib] + turns) if rows is later else (work.q9[ia] + turns, work.q9[ib])
                found = router.route(q_a, q_b, seed=[job.collision.seed, place, k])
                if found is not None:
                    work.q9[rows] += turns
                    work.changed[rows] = True
                    shifted = True
                    counts["unwound"] += 1
                    if rows is stroke_before:
                        # the move into the stroke before changed: checked again now, so that its own transfer
                        # (taken next) is routed when the shift put it in collision
                        inner = np.flatnonzero(work.reachable[: rows[0]])
                        if len(inner):
                            motion[rows[0]] = bool(
                                motion_hits(repairer.cell, work.q9[inner[-1:]], work.q9[rows[:1]])[0]
                            )
                    break
            if found is None:
                found = router.route(work.q9[ia], work.q9[ib], seed=[job.collision.seed, place, k])
        if found is None:
            counts["flagged"] += 1
            continue
        counts["rerouted_by"][found.kind] += 1
        q9 = np.vstack([work.q9[ia], found.nodes, work.q9[ib]])
        n = len(q9)
        checks = repairer.cell.check(q9)
        rows = _Station(
            work.platform,
            q9,
            np.ones(n, bool),
            np.array([work.method[ia], *["analytic"] * (n - 2), work.method[ib]], dtype=object),
            np.zeros(n),
            np.zeros(n),
            np.zeros(n, bool),
            checks.in_collision.copy(),
            checks.distance_mm.copy(),
            repairer.names[checks.column],
            checks.slack_mm.copy(),
            np.full(n, found.kind, dtype=object),
            np.ones(n, bool),
            np.zeros(n, bool),
        )
        work = work.spliced(sl, rows)
        motion = np.concatenate([motion[: sl.start], np.zeros(n, bool), motion[sl.stop :]])
        motion[ib + n - (sl.stop - sl.start)] = False
        strokes[k] = route_stroke(repairer.gantry, q9[0], found.nodes, q9[-1], standoff)
    if any(a is not b for a, b in zip(strokes, st.strokes)):
        repairer.errors(work, SimpleNamespace(strokes=strokes))
    return tuple(strokes), work, motion, shifted


def unwound(robot, q_a: np.ndarray, after: np.ndarray) -> np.ndarray | None:
    """The whole turns (9,) (multiples of 2 pi on the arm's joints, 0 on the gantry's axes) that bring the first of
    the joint vectors ``after`` (n, 9) nearest ``q_a`` (9,), when they are not all 0 and every row of ``after``
    shifted by them stays in ``robot``'s joint limits; else None. A revolute joint turned a whole turn puts its
    links where they were, so the shifted rows keep their poses and their motions among themselves: only the
    move from ``q_a`` into them changes (a transfer that turned a joint round, through the part, no longer does)."""
    k = np.rint((q_a[:6] - after[0, :6]) / TAU)
    if not k.any():
        return None
    turns = np.concatenate([TAU * k, np.zeros(3)])
    if not robot.within_limits(after[:, :6] + turns[:6]).all():
        return None
    return turns


def collision_stage(
    plan: Plan,
    whole,
    job: JobConfig,
    gantry: Gantry,
    progress: Progress | None = None,
    cell: CellCollision | None = None,
):
    """The plan with every waypoint and motion checked against ``whole`` (the part before its region was cut,
    so the arm does not pass through the unpainted rest), the floor and the cell, waypoints in collision
    repaired first (module docstring). Returns the plan and a summary dict for the totals. ``cell``: the
    collision model of ``whole`` and ``gantry`` with ``job.collision``'s settings, when one was made before."""
    config = job.collision
    cell = CellCollision(gantry, whole, config) if cell is None else cell
    repairer = Repairer(cell, gantry, job.kinematics, config)
    step = counted(progress, "collision", len(plan.stations))
    works, before = [], 0
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
        works.append(work)
        step()
    motion_flags, _, motion_hits_before = flag_motions(cell, works)
    motions_freed = dict.fromkeys(MOTION_REPAIRS, 0)
    if config.repair:
        was = [w.q9.copy() for w in works]
        firsts = [np.flatnonzero(w.reachable)[:1] for w in works]
        for i, (st, work, flags) in enumerate(zip(plan.stations, works, motion_flags)):
            earlier = [w.q9[np.flatnonzero(w.reachable)[-1]] for w in works[:i] if w.reachable.any()]
            later = [
                (w.q9[f[0]], bool(m[f[0]]))
                for w, f, m in zip(works[i + 1 :], firsts[i + 1 :], motion_flags[i + 1 :])
                if len(f)
            ]
            found = repair_motions(
                repairer, st, work, flags, earlier[-1] if earlier else None, later[0] if later else None
            )
            for name, count in found.items():
                motions_freed[name] += count
        if any(motions_freed.values()):
            for st, work in zip(plan.stations, works):
                repairer.errors(work, st)
            moved = [(w.q9 != q).any(axis=1) for w, q in zip(works, was)]
            motion_flags, _, _ = flag_motions(cell, works, (motion_flags, moved))
    strokes = [st.strokes for st in plan.stations]
    transfers = {
        "in_collision": 0,
        "rerouted_by": dict.fromkeys(TRANSFER_REPAIRS, 0),
        "flagged": 0,
        "end_in_collision": 0,
        "unwound": 0,
    }
    if config.repair:
        router = Router(cell, whole)
        moved = []
        for place, st in enumerate(plan.stations):
            strokes[place], works[place], motion_flags[place], shifted = _reroute(
                router, repairer, st, works[place], motion_flags[place], job, place, transfers
            )
            # whole turns taken out of a station's first or last rows change its moves from the station before and
            # to the one after: checked again
            ends = np.zeros(len(works[place].q9), bool)
            if shifted and works[place].reachable.any():
                ends[np.flatnonzero(works[place].reachable)[[0, -1]]] = True
            moved.append(ends)
        if any(m.any() for m in moved):
            motion_flags, _, _ = flag_motions(cell, works, (motion_flags, moved))
    stations = tuple(w.plan(st, m, s) for w, st, m, s in zip(works, plan.stations, motion_flags, strokes))
    by_repair = {name: sum(int(((w.repair == name) & ~w.motion_repaired).sum()) for w in works) for name in REPAIRS}
    flagged = sum(int(w.collision.sum()) for w in works)
    motion_hits = sum(int(m.sum()) for m in motion_flags)
    reached = int(sum(w.reachable.sum() for w in works))
    summary = {
        "checked": True,
        "clearance_mm": config.clearance_mm,
        "floor_z_mm": round(cell.floor_z_mm, 3),
        "waypoints_checked": reached,
        "in_collision_before_repair": before,
        "repaired": int(sum(by_repair.values())),
        "repaired_by": by_repair,
        "flagged_waypoints": flagged,
        "motions_checked": max(0, reached - 1),
        "flagged_motions": motion_hits,
        "flagged_motions_before_reroute": motion_hits_before,
        "motions_repaired": int(sum(motions_freed.values())),
        "motions_repaired_by": motions_freed,
        "transfers_in_collision": transfers["in_collision"],
        "transfers_rerouted": int(sum(transfers["rerouted_by"].values())),
        "transfers_rerouted_by": transfers["rerouted_by"],
        "transfers_flagged": transfers["flagged"],
        "transfers_end_in_collision": transfers["end_in_collision"],
        "transfers_unwound": transfers["unwound"],
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
