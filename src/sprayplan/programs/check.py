"""Programs read back, compared move by move with the plan they were written from.

:func:`check_program` walks a :class:`~sprayplan.programs.model.ReadProgram` station by station and run by run
(a joint move, a linear approach, linear spray moves, a linear retract) and checks, against values it computes
from the plan itself:

- every linear target that stands for a plan waypoint is the pose the plan's joints give the TCP (forward
  kinematics) within 0.01 mm and 0.01 degree, and, where the analytic IK solved the waypoint, the plan's own
  spray target (gun tip plus the spray distance along the gun axis) and gun axis within the same;
- via points (URScript) lie on their segment, with the slerped orientation;
- approach and retract targets lie ``approach_mm`` (or a half, quarter, eighth of it) back along the gun axis;
- every joint target equals, within 1e-6 rad, the joints the plan's branch has there (the home joints at
  home), and its branch is the plan's;
- configuration data (RAPID cf1, cf4, cf6, cfx; KRL S, T) are those of the joints, and the target's IK on
  that configuration gives the plan's joints back;
- speeds equal the plan's (the TCP's path over the plan's time for the segment) within the written digits;
  every blend radius is within ``blend_share`` of both neighbouring segments and ``blend_mm``, 0 at a run's
  ends;
- external axes equal the plan's gantry positions;
- the gun, with its lead times, is open exactly from each run's first waypoint to its last (0.01 mm), and
  nowhere else.

Every failure is a line in :attr:`CheckResult.failures`; the largest deviations are kept for the tests and
the benchmark. :mod:`sprayplan.programs.film` compares the film of the program with the plan's.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from sprayplan.programs.build import (
    APPROACH_TRIES,
    MIN_SPEED_MM_S,
    plan_ends,
    station_arrays,
    target_q9,
    wanted_targets,
)
from sprayplan.programs.model import (
    JOINT,
    LINEAR,
    Cell,
    angle_between_deg,
    offset_along_z,
)
from sprayplan.robots.stage import gantry_for
from sprayplan.types import TRANSFER_REPAIRS

POSITION_MM = 0.01
ANGLE_DEG = 0.01
JOINT_RAD = 1e-6
#: Joints from a target's pose and configuration data: the pose is written to 1e-4 mm and 1e-9.
POSE_JOINT_RAD = 1e-4
SPEED_MM_S = 1e-4
EXTERNAL_MM = 1e-3
BLEND_SLACK_MM = 1e-4


@dataclass
class CheckResult:
    """What :func:`check_program` found.

    Attributes
    ----------
    failures : list of str
        One line per problem (``file:line: what``); empty when the program is the plan.
    via_moves : list of str
        The ``where`` of each via point (``film.program_paths`` joins a move's pieces there).
    moves, runs, waypoints, vias, duplicates : int
        Moves read, spray runs, plan waypoints the program moves to, via points, and waypoints the program
        reaches as one target with the waypoint before them (within 0.01 mm and 0.01 degree).
    left_out : list of (int, int)
        (station order, waypoint index) of reachable spray waypoints the program does not move to.
    max_position_mm, max_angle_deg, max_joint_rad, max_speed_mm_s, max_external_mm, max_gun_mm : float
        The largest deviations found (position and angle of waypoint targets from the plan's joints' poses,
        joint targets, speeds, external axes, gun switching points).
    max_blend_share : float
        The largest blend radius over its shorter neighbouring segment.
    """

    failures: list = field(default_factory=list)
    moves: int = 0
    runs: int = 0
    waypoints: int = 0
    vias: int = 0
    via_moves: list = field(default_factory=list)
    duplicates: int = 0
    left_out: list = field(default_factory=list)
    max_position_mm: float = 0.0
    max_angle_deg: float = 0.0
    max_joint_rad: float = 0.0
    max_speed_mm_s: float = 0.0
    max_external_mm: float = 0.0
    max_gun_mm: float = 0.0
    max_blend_share: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.failures

    def fail(self, move, text: str) -> None:
        where = getattr(move, "where", "") if move is not None else ""
        if len(self.failures) < 200:
            self.failures.append(f"{where}: {text}" if where else text)


def check_program(read, plan, job, cell=None) -> CheckResult:
    """Compare the moves of ``read`` (``stage.read_programs``) with ``plan`` and its settings ``job``; ``cell``
    the robot (default the job's gantry; ``programs.arms.ArmCell`` for a robot of a cell)."""
    result = CheckResult(moves=len(read.moves))
    cell = cell or Cell(gantry_for(job.kinematics))
    if np.abs(read.tool2flange - cell.tool2flange).max() > 1e-4:
        result.fail(None, f"the TCP is not the gun's spray target {cell.tool2flange[:3, 3].tolist()}")
    stations = _by_station(read, plan, cell, result)
    for order, moves in stations:
        _check_station(order, moves, read.fmt, plan, job, cell, result)
    return result


def _by_station(read, plan, cell: Cell, result: CheckResult) -> list:
    """The moves of each station (its home moves at both ends included), in visiting order."""
    moves = list(read.moves)
    if read.fmt == "urscript":
        out = []
        for order, st in enumerate(plan.stations):
            mine = [s for s in read.scripts if s["station"] == st.index]
            if not mine:
                result.fail(None, f"no script for station {order + 1} (plan station {st.index})")
                continue
            expected = np.linalg.inv(cell.gantry.base2world(st.platform_mm)[0])
            for s in mine:
                if (
                    np.abs(s["part_frame"] - expected).max() > 1e-3
                    or np.abs(s["gantry_mm"] - st.platform_mm).max() > EXTERNAL_MM
                ):
                    result.fail(None, f"{s['file']}: the part frame or gantry position is not station {order + 1}'s")
            out.append((order, [m for s in mine for m in moves[s["first"] : s["first"] + s["count"]]]))
        seen = [s["station"] for s in read.scripts]
        visits = [k for i, k in enumerate(seen) if i == 0 or seen[i - 1] != k]
        if visits != [st.index for st in plan.stations]:
            result.fail(None, f"the scripts visit the stations {visits}, the plan {[st.index for st in plan.stations]}")
        for order, station_moves in out:
            home = cell.home_joints
            if not station_moves or not (
                _is_home(station_moves[0], None, home) and _is_home(station_moves[-1], None, home)
            ):
                result.fail(
                    station_moves[0] if station_moves else None, f"station {order + 1} must begin and end at home"
                )
        return out
    if np.abs(read.frame - np.eye(4)).max() > 1e-6:
        result.fail(None, "the work object / base is not the part frame (identity in the plan's world)")
    ends = plan_ends(plan, cell, plan.home_mm)
    for end, home in zip((0, -1), ends):
        if not moves or not _is_home(moves[end], home.external_mm, home.joints):
            result.fail(moves[end] if moves else None, "the program must start and end at home (gantry at home_mm)")
            return []
    body, out, k = moves[1:-1], [], 0
    for order, st in enumerate(plan.stations):
        start, stop = plan_ends(plan, cell, st.platform_mm)
        if k >= len(body) or not _is_home(body[k], start.external_mm, start.joints):
            result.fail(
                body[k] if k < len(body) else None, f"station {order + 1} must begin at home at its gantry position"
            )
            return out
        end = next((j for j in range(k + 1, len(body)) if _is_home(body[j], stop.external_mm, stop.joints)), None)
        if end is None:
            result.fail(body[k], f"station {order + 1} never returns home")
            return out
        out.append((order, body[k : end + 1]))
        k = end + 1
    if k != len(body):
        result.fail(body[k], "moves after the last station")
    return out


def _is_home(move, external_mm, home_joints) -> bool:
    """A joint move to the home joints (with the gantry at ``external_mm`` where the format carries it)."""
    if move.kind != JOINT or np.abs(move.joints - home_joints).max() > JOINT_RAD:
        return False
    return (
        move.external_mm is None
        or external_mm is None
        or np.abs(move.external_mm - external_mm).max(initial=0.0) <= EXTERNAL_MM
    )


def is_route_rows(st) -> np.ndarray:
    """(n,) bool: the waypoints of a station's transfers that the collision stage re-routed."""
    return np.isin(st.repair, TRANSFER_REPAIRS) & st.reachable


class _Station:
    """The plan's side of one station: the waypoints' poses from the plan's joints, and what the plan wants."""

    def __init__(self, order, st, fmt, job, cell: Cell):
        self.order, self.st = order, st
        self.data = station_arrays(st, job)
        self.q9 = target_q9(st, fmt)
        n = len(self.q9)
        self.poses = cell.target_poses(self.q9) if n else np.zeros((0, 4, 4))  # the plan's own chain
        self.wanted = wanted_targets(self.data["tcp"], self.data["normals"], cell.spray_distance_mm)
        self.branch = cell.branches(self.q9[:, :6]) if n else np.zeros(0, int)
        self.spray = self.data["spray"] & st.reachable
        collides = getattr(st, "collides", None)  # a cell robot's waypoints left out in collision
        if collides is not None:
            self.spray &= ~collides
        # (move, joints, branch, gantry, exact pose) whose configuration data are checked at the end
        self.pending: list = []
        self.waited: set = set()  # the strokes whose first run was seen


def _check_station(order, moves, fmt, plan, job, cell, result: CheckResult) -> None:
    station = _Station(order, plan.stations[order], fmt, job, cell)
    cfg = job.export
    route = getattr(plan, "park_route", None)
    if route is not None and order == len(plan.stations) - 1:  # the way to the end park: the plan's nodes
        m = len(route[0])
        way = moves[-1 - m : -1]
        if len(moves) < m + 2 or not all(
            w.kind == JOINT
            and np.abs(w.joints - q).max() <= JOINT_RAD
            and (w.external_mm is None or np.abs(np.asarray(w.external_mm) - mm).max(initial=0.0) <= EXTERNAL_MM)
            for w, q, mm in zip(way, *route)
        ):
            result.fail(moves[-2] if len(moves) > 1 else None, "the moves to the end park are not the plan's route")
            return
        moves = [*moves[: -1 - m], moves[-1]]
    for home in (moves[0], moves[-1]):
        if any(on for _, on in home.events):
            result.fail(home, "the gun must not be switched on at home")
    matched = np.zeros(len(station.q9), bool)
    k, pointer = 1, 0
    routes = station.q9[is_route_rows(station.st)]
    while k < len(moves) - 1:
        if moves[k].kind != JOINT:
            result.fail(moves[k], "a run must begin with a joint move to its approach pose")
            return
        if moves[k + 1].kind == JOINT and k + 1 < len(moves) - 1:  # a joint move to a route's waypoint
            if not len(routes) or np.abs(routes[:, :6] - moves[k].joints).max(axis=1).min() > JOINT_RAD:
                result.fail(moves[k], "a joint move between runs to no waypoint of a transfer the plan re-routed")
                return
            k += 1
            continue
        j = k + 1
        while j < len(moves) - 1 and moves[j].kind == LINEAR:
            j += 1
        chain = moves[k + 1 : j]
        if len(chain) < 2:
            result.fail(moves[k], "a run needs an approach and a retract")
            return
        pointer = _check_run(station, moves[k], chain, fmt, cfg, cell, job, result, matched, pointer)
        if pointer is None:
            return
        result.runs += 1
        k = j
    _check_configs(station.pending, fmt, cell, result)
    left = np.flatnonzero(station.spray & ~matched)
    result.left_out += [(order, int(i)) for i in left]


def _match(station: _Station, pose, start: int, stroke: int | None = None, near: bool = False) -> int | None:
    """The first reachable spray waypoint at or after ``start`` (of ``stroke`` when given) whose pose (from the
    plan's joints) is ``pose``; a transfer's waypoints share their poses with the strokes' ends and are skipped.
    The next waypoint, then the next 64 are looked at first (a run's next target is almost always among them);
    with ``near`` only those."""
    if (
        start < len(station.poses)
        and station.spray[start]
        and (stroke is None or station.data["stroke"][start] == stroke)
    ):
        here = station.poses[start]
        if (
            np.linalg.norm(here[:3, 3] - pose[:3, 3]) <= POSITION_MM
            and angle_between_deg(here[:3, :3], pose[:3, :3]) <= ANGLE_DEG
        ):
            return start
    for stop in (start + 64,) if near else (start + 64, len(station.poses)):
        mask = station.spray[start:stop]
        if stroke is not None:
            mask = mask & (station.data["stroke"][start:stop] == stroke)
        rest = station.poses[start:stop]
        if len(rest):
            close = mask & (np.linalg.norm(rest[:, :3, 3] - pose[:3, 3], axis=1) <= POSITION_MM)
            found = np.flatnonzero(close)
            if len(found):
                ok = (
                    angle_between_deg(rest[found, :3, :3], np.broadcast_to(pose[:3, :3], (len(found), 3, 3)))
                    <= ANGLE_DEG
                )
                if ok.any():
                    return start + int(found[np.argmax(ok)])
        if stop >= len(station.poses):
            break
    return None


def _first_waypoint(station, chain, a: int, pointer: int, joints) -> int | None:
    """The waypoint a run's approach (``chain[a]``) ends at (:func:`_match` from ``pointer``). A run split for a
    file's size starts again at the waypoint the one before ended at (``pointer``, matched already), but so can
    a stroke the plan starts at the gun pose where the stroke before ended (a cell robot's run solved on its own
    with its free neighbour, ``cells.repair.resolved_piece``, on another branch or the same), and the stroke
    before may end one waypoint short of that pose in the program (its last waypoint left out: no retract from
    it on its branch, ``build.unapproachable_waypoints``), so that the first match is that unmatched waypoint.
    Of the first two waypoints with the approach's pose, the one whose stroke the run's next target continues
    is taken; if both or neither, the one whose joints are nearer the joint move's to the approach (the
    program's IK on the plan's branch there), the first on a tie."""
    first = _match(station, chain[a].pose, pointer)
    if first is None:
        return None
    later = _match(station, chain[a].pose, first + 1, near=True)  # such a stroke follows its transfer
    if later is None:
        return first
    candidates = [first, later]
    if a + 2 < len(chain):  # chain[a + 1] is a spray move (the chain's last is the retract)
        nexts = [_match(station, chain[a + 1].pose, c + 1, station.data["stroke"][c]) for c in candidates]
        fits = [k is not None and _only_duplicates(station, c, k) for c, k in zip(candidates, nexts)]
        if fits[0] != fits[1]:
            return candidates[fits.index(True)]
    near = np.abs(station.q9[candidates, :6] - np.asarray(joints, float)[None, :6]).max(axis=1)
    return later if near[1] < near[0] else first


def _starts_at_run_up(station, chain, a: int, here: int, pointer: int, cell) -> int:
    """1 where ``chain[a]`` is not the run's first waypoint but the start of its run-up into ``chain[a + 1]``
    that has the pose of a waypoint of another stroke before it (a stroke cut between two waypoints,
    ``cells.repair.free_work``: the piece after starts its run-up at the last waypoint of the piece before,
    which ran out to its first, ``cells.runups``); else 0. ``here``: the waypoint ``chain[a]``'s pose matched
    (:func:`_match` from ``pointer``). (The masked SUV's roof program, session 32: taken for that waypoint, the
    run was one waypoint off, 10 mm, 200 differences.)"""
    k = _match(station, chain[a + 1].pose, pointer + 1)
    if k is None or station.data["stroke"][k] == station.data["stroke"][here]:
        return 0
    up = _lead_of(station, cell, k, 0)
    return int(up is not None and _same_pose(chain[a].pose, up[0]))


def _check_run(station, transfer, chain, fmt, cfg, cell, job, result, matched, pointer):
    """One run: ``transfer`` (the joint move to the approach pose), then ``chain``: via points on the approach,
    the approach (to the run's first waypoint), spray moves and via points, the retract."""
    external = transfer.external_mm if transfer.external_mm is not None else station.st.platform_mm
    start_pose = cell.poses(transfer.joints, external)[0]
    matches = ((j, _match(station, m.pose, pointer)) for j, m in enumerate(chain[:-1]))
    a, here = next(((j, k) for j, k in matches if k is not None), (None, None))
    if a is not None and a + 2 < len(chain):
        a += _starts_at_run_up(station, chain, a, here, pointer, cell)
    first = None if a is None else _first_waypoint(station, chain, a, pointer, transfer.joints)
    if first is None:
        result.fail(chain[0], "the approach does not end at a reachable spray waypoint of the station (in order)")
        return None
    stroke = station.data["stroke"][first]
    up = _lead_of(station, cell, first, 0)
    if up is not None and not (a >= 1 and _same_pose(chain[a - 1].pose, up[0])):
        up = None  # the program makes no run-up here (the plan's has no back-off: build's run_ups_left_out)
    _check_wait(station, transfer, chain, a - 1 if up is not None else a, int(stroke), result)
    targets, indices, previous = [_PoseOnly(start_pose), *chain[: a + 1]], [-2] + [-1] * a + [first], first
    if up is not None:
        indices[a] = RUN_UP_START
        station.pending.append((chain[a - 1], up[1][:6], int(cell.branches(up[1][:6])[0]), up[1][6:], up[0]))
    body = chain[a + 1 : -1]
    out = None
    for n, move in enumerate(body):
        if n == len(body) - 1 and n > 0:
            out = _lead_of(station, cell, previous, 1)
            if out is not None and _same_pose(move.pose, out[0]):
                indices.append(RUN_OUT_END)
                targets.append(move)
                station.pending.append((move, out[1][:6], int(cell.branches(out[1][:6])[0]), out[1][6:], out[0]))
                break
            out = None
        k = _match(station, move.pose, previous + 1, stroke)
        if k is not None and _only_duplicates(station, previous, k):
            indices.append(k)
            result.duplicates += k - previous - 1
            matched[previous + 1 : k] = True  # one target with the waypoint before them
            previous = k
        elif fmt == "urscript":
            indices.append(-1)  # a via point (only URScript has them): checked against its segment
        else:  # not the next waypoint: compared with it (and taken for it)
            k = min(previous + 1, len(station.poses) - 1)
            indices.append(k)
            matched[k] = True
            previous = k
        targets.append(move)
    if indices[-1] == -1:
        result.fail(chain[-2], "a run must end at a plan waypoint, not a via point")
        return None
    result.vias += sum(i == -1 for i in indices)
    result.via_moves += [m.where for m, i in zip(targets, indices) if i == -1]
    for i in indices:
        if i >= 0:
            matched[i] = True
    result.waypoints += sum(i >= 0 for i in indices)
    _check_targets(station, targets, indices, fmt, cell, result)
    _check_vias(targets, indices, result)
    _check_speeds(station, targets, indices, a + 1, cfg, fmt, result)
    moves = targets[1:] + [chain[-1]]
    stops = {a - 1 if up is not None else a, len(moves) - 2, len(moves) - 1}  # where the robot must stop
    _check_blends(moves, stops, cfg, result)
    _check_backoff(station, transfer, first, cfg, cell, fmt, result, is_approach=True, lead=up)
    last = previous if out is not None else indices[-1]
    _check_backoff(station, chain[-1], last, cfg, cell, fmt, result, is_approach=False, lead=out)
    if abs(chain[-1].speed_mm_s - cfg.approach_speed_mm_s) > SPEED_MM_S:
        result.fail(chain[-1], f"the retract's speed is not approach_speed_mm_s ({cfg.approach_speed_mm_s:g} mm/s)")
    if chain[-1].events:
        result.fail(chain[-1], "the gun must not switch on the retract")
    _check_gun([start_pose, *(m.pose for m in chain[:-1])], chain[:-1], a, indices, cfg, fmt, result, transfer.events,
               off_at=len(chain) - 2 - (out is not None))  # fmt: skip
    return previous  # a run split for a file's size starts again at the waypoint this one ends at


#: ``indices`` of a run's targets that are not plan waypoints: the approach's end at a run-up's start, a
#: run-out's end (``cells.runups``; -1 is a via point, -2 the approach pose).
RUN_UP_START, RUN_OUT_END = -3, -4


def _lead_of(station, cell, k: int, side: int):
    """``(pose, axes)`` of the plan's run-up into waypoint k (side 0) or run-out after it (side 1), the pose by
    the plan's own chain; None where it has none."""
    leads = getattr(station.st, "leads", None)
    if leads is None or k < 0 or not np.isfinite(leads[k, side]).all():
        return None
    axes = np.asarray(leads[k, side], float)
    return cell.target_poses(axes[None])[0], axes


def _same_pose(a, b) -> bool:
    return bool(
        np.linalg.norm(a[:3, 3] - b[:3, 3]) <= POSITION_MM and angle_between_deg(a[:3, :3], b[:3, :3]) <= ANGLE_DEG
    )


def _check_wait(station, transfer, chain, a: int, stroke: int, result) -> None:
    """The schedule's wait before a stroke (a cell robot's, ``wait_s`` of its station) on the approach of the
    stroke's first run (``chain[a]``, 0.001 s, as written); no wait anywhere else."""
    waits = getattr(station.st, "wait_s", None)
    expected = 0.0
    if waits is not None and stroke not in station.waited:
        expected = float(waits[stroke])
    station.waited.add(stroke)
    for j, move in enumerate([transfer, *chain]):
        want = expected if j == a + 1 else 0.0
        got = float(getattr(move, "wait_s", 0.0))
        if abs(got - want) > 1e-3:
            result.fail(move, f"waits {got:g} s; the plan's schedule waits {want:g} s here")


class _PoseOnly:
    """The approach pose as the first 'target' of a run's list (its pose only)."""

    def __init__(self, pose):
        self.pose = pose
        self.where = ""


def _only_duplicates(station, a: int, b: int) -> bool:
    """Waypoints strictly between a and b have a's pose (a duplicate the program moves to once)."""
    between = station.poses[a + 1 : b]
    here = station.poses[a]
    return all(
        np.linalg.norm(p[:3, 3] - here[:3, 3]) <= POSITION_MM
        and angle_between_deg(p[:3, :3], here[:3, :3]) <= ANGLE_DEG
        for p in between
    )


def _check_targets(station, targets, indices, fmt, cell, result) -> None:
    use = [(m, i) for m, i in zip(targets, indices) if i >= 0]
    moves = [m for m, _ in use]
    k = np.array([i for _, i in use], int)
    poses = np.array([m.pose for m in moves])
    dp = np.linalg.norm(poses[:, :3, 3] - station.poses[k, :3, 3], axis=1)
    da = angle_between_deg(poses[:, :3, :3], station.poses[k, :3, :3])
    result.max_position_mm = max(result.max_position_mm, float(dp.max()))
    result.max_angle_deg = max(result.max_angle_deg, float(da.max()))
    for j in np.flatnonzero((dp > POSITION_MM) | (da > ANGLE_DEG)):
        result.fail(moves[j], f"waypoint {k[j]}: {dp[j]:.4g} mm, {da[j]:.4g} deg from the pose the plan's joints give")
    analytic = station.st.method[k] == "analytic"
    axis = -station.data["normals"][k]
    axis = axis / np.linalg.norm(axis, axis=1)[:, None]
    dw = np.linalg.norm(poses[:, :3, 3] - station.wanted[k], axis=1)
    dz = np.degrees(
        np.arctan2(np.linalg.norm(np.cross(poses[:, :3, 2], axis), axis=1), (poses[:, :3, 2] * axis).sum(1))
    )
    for j in np.flatnonzero(analytic & ((dw > POSITION_MM) | (dz > ANGLE_DEG))):
        result.fail(
            moves[j], f"waypoint {k[j]}: {dw[j]:.4g} mm, {dz[j]:.4g} deg from the plan's spray target and gun axis"
        )
    if fmt in ("rapid", "krl"):
        ext = np.abs(np.array([m.external_mm for m in moves]) - station.q9[k, 6:]).max(axis=1, initial=0.0)
        result.max_external_mm = max(result.max_external_mm, float(ext.max()))
        for j in np.flatnonzero(ext > EXTERNAL_MM):
            result.fail(
                moves[j], f"waypoint {k[j]}: external axes {moves[j].external_mm.tolist()} are not the gantry's"
            )
        station.pending += [
            (m, station.q9[i, :6], int(station.branch[i]), station.q9[i, 6:], station.poses[i]) for m, i in use
        ]


def _check_configs(pending, fmt, cell: Cell, result) -> None:
    """Every target's configuration data are those of its joints, and its pose solved on that configuration
    gives the joints back: RAPID's cfx names the branch and cf1, cf4, cf6 the turns of axes 1, 4, 6; KRL's S
    names the branch and T every joint's sign (which fixes its turn within +-2 pi). The pose solved is the one
    the joints give (which the target was checked to be, within 0.01 mm and 0.01 degree): the written pose's
    rounding would move the joints by more than 1e-4 rad near a singularity. All targets at once."""
    if not pending:
        return
    moves = [p[0] for p in pending]
    joints = np.array([p[1] for p in pending])
    config = np.array([tuple(m.config) for m in moves], int)
    expected = cell.config_data(joints, fmt)
    wrong = (config != expected).any(axis=1)
    for n in np.flatnonzero(wrong):
        result.fail(
            moves[n], f"configuration data {tuple(config[n])} are not those of the plan's joints {tuple(expected[n])}"
        )
    raw, ok = cell.config_solutions(np.array([p[4] for p in pending]), np.array([p[3] for p in pending]), config, fmt)
    q = _turns(raw, joints, config, fmt)
    error = np.where(np.isfinite(q).all(axis=1), np.abs(q - joints).max(axis=1), np.inf)
    for n in np.flatnonzero(~wrong & (~ok | (error > POSE_JOINT_RAD))):
        result.fail(moves[n], f"the pose solved on its configuration data is {error[n]:.3g} rad from the plan's joints")


def _turns(angle: np.ndarray, plan: np.ndarray, config: np.ndarray, fmt: str) -> np.ndarray:
    """(n, 6) the turns ``angle + 2 pi k`` the configuration data name for each joint (RAPID: the quadrant of
    axes 1, 4, 6; KRL: every axis's sign), the one nearest the plan's joint where they name none (RAPID's axes
    2, 3, 5); a joint on the border of two quadrants or signs (within the precision of a written pose) may take
    either side. NaN where none fits."""
    eps = POSE_JOINT_RAD
    candidates = angle[:, :, None] + 2 * np.pi * np.arange(-2, 3)  # (n, 6, 5)
    fits = np.ones(candidates.shape, bool)
    if fmt == "rapid":
        degrees = np.degrees(candidates[:, [0, 3, 5]])
        cf = config[:, :3, None].astype(float)
        fits[:, [0, 3, 5]] = (degrees >= 90.0 * cf - np.degrees(eps)) & (degrees < 90.0 * (cf + 1) + np.degrees(eps))
    else:
        negative = ((config[:, 1:2] >> np.arange(6)) & 1).astype(bool)[:, :, None]
        fits = np.where(negative, candidates < eps, candidates > -eps) & (np.abs(candidates) < 2 * np.pi + eps)
    distance = np.where(fits, np.abs(candidates - plan[:, :, None]), np.inf)
    best = np.argmin(distance, axis=2)
    out = np.take_along_axis(candidates, best[:, :, None], axis=2)[:, :, 0]
    return np.where(np.isfinite(np.min(distance, axis=2)), out, np.nan)


def _check_vias(targets, indices, result) -> None:
    from scipy.spatial.transform import Rotation, Slerp

    for j, (move, i) in enumerate(zip(targets, indices)):
        if i != -1:
            continue
        a = targets[j - 1].pose
        b = next(t.pose for t, k in zip(targets[j + 1 :], indices[j + 1 :]) if k >= 0)
        ab = b[:3, 3] - a[:3, 3]
        f = float((move.pose[:3, 3] - a[:3, 3]) @ ab / (ab @ ab))
        off = float(np.linalg.norm(a[:3, 3] + f * ab - move.pose[:3, 3]))
        slerp = Slerp([0.0, 1.0], Rotation.from_matrix([a[:3, :3], b[:3, :3]]))(min(max(f, 0.0), 1.0)).as_matrix()
        if not (0.0 < f < 1.0) or off > POSITION_MM or angle_between_deg(slerp, move.pose[:3, :3]) > ANGLE_DEG:
            result.fail(move, "a move that is neither the next plan waypoint nor a via point on its segment")


def _check_speeds(station, targets, indices, first, cfg, fmt, result) -> None:
    """The approach (and its via points) at ``approach_speed_mm_s``, slowed so that the gun's opening lead fits
    on it; the move into each further waypoint (and the via points before it) at the TCP's path over the plan's
    time for the segment (``targets[first]`` is the run's first waypoint)."""
    up = first >= 1 and indices[first - 1] == RUN_UP_START  # the approach ends at a run-up's start
    approach_end = first - 1 if up else first
    measured = float(np.linalg.norm(targets[approach_end].pose[:3, 3] - targets[0].pose[:3, 3]))
    approach = min((cfg.approach_mm * t for t in APPROACH_TRIES), key=lambda d: abs(d - measured))
    lead = 0.0 if fmt == "rapid" and cfg.rapid_paint else cfg.lead_on_s
    v_app = cfg.approach_speed_mm_s if lead <= 0 else min(cfg.approach_speed_mm_s, approach / lead)
    for m in targets[1 : approach_end + 1]:
        _speed(m, v_app, result)
    # a run-up at the first segment's speed, a run-out at the last's
    previous, pending, expected = indices[first], [targets[first]] if up else [], None
    for move, i in zip(targets[first + 1 :], indices[first + 1 :]):
        pending.append(move)
        if i < 0:
            continue
        seconds = float(station.data["seconds"][previous + 1 : i + 1].sum())
        length = float(np.linalg.norm(station.poses[i, :3, 3] - station.poses[previous, :3, 3]))
        expected = length / seconds if seconds > 0 else float(station.data["speed"][i])
        expected = max(expected, MIN_SPEED_MM_S)  # a near pure reorientation: the slowest speed written
        for m in pending:
            _speed(m, expected, result)
        pending, previous = [], i
    if indices[-1] == RUN_OUT_END and expected is not None:
        for m in pending:
            _speed(m, expected, result)


def _speed(move, expected: float, result) -> None:
    error = abs(move.speed_mm_s - expected)
    result.max_speed_mm_s = max(result.max_speed_mm_s, error)
    if error > SPEED_MM_S + 1e-9 * expected:
        result.fail(move, f"speed {move.speed_mm_s:.4f} mm/s, the plan's is {expected:.4f} mm/s")


def _check_blends(moves, stops: set, cfg, result) -> None:
    """``moves``: the run's linear moves from the first (a via point on the approach, or the approach) to the
    retract; the robot stops at the moves of index ``stops`` (the approach's end, the last waypoint or the
    run-out's end, the retract)."""
    positions = [m.pose[:3, 3] for m in moves]
    lengths = [float(np.linalg.norm(b - a)) for a, b in itertools.pairwise(positions)]
    for j, move in enumerate(moves):
        if j in stops:
            if move.blend_mm != 0:
                result.fail(move, f"blend {move.blend_mm} mm where the robot must stop (a run's end)")
            continue
        shorter = min(lengths[j - 1], lengths[j]) if j > 0 else lengths[j]
        share = move.blend_mm / shorter if shorter > 0 else math.inf
        result.max_blend_share = max(result.max_blend_share, share)
        if move.blend_mm > cfg.blend_share * shorter + BLEND_SLACK_MM or move.blend_mm > cfg.blend_mm + BLEND_SLACK_MM:
            result.fail(
                move,
                f"blend {move.blend_mm:.4f} mm exceeds {cfg.blend_share:g} of the shorter segment ({shorter:.4f} mm)",
            )


def _check_backoff(station, move, i, cfg, cell, fmt, result, is_approach: bool, lead=None) -> None:
    """An approach pose (the transfer's joints) or a retract target: ``approach_mm`` (or a fraction of it)
    back along the gun axis from waypoint ``i`` (or from ``lead``'s pose, a run-up's start or run-out's end
    there: ``(pose, axes)``), with the joints of the plan's branch there."""
    base, axes = (station.poses[i], station.q9[i]) if lead is None else lead
    if is_approach:
        pose = cell.poses(move.joints, axes[6:])[0]
        if move.external_mm is not None and np.abs(move.external_mm - axes[6:]).max(initial=0.0) > EXTERNAL_MM:
            result.fail(move, "the joint move's external axes are not the gantry's at its run")
    else:
        pose = move.pose
    back = base[:3, 3] - pose[:3, 3]
    distance = float(back @ base[:3, 2])
    off_axis = float(np.linalg.norm(back - distance * base[:3, 2]))
    tries = [cfg.approach_mm * t for t in APPROACH_TRIES]
    if off_axis > POSITION_MM or min(abs(distance - d) for d in tries) > POSITION_MM:
        result.fail(move, f"not {cfg.approach_mm:g} mm (or a half, quarter, eighth) back along the gun axis")
        return
    if angle_between_deg(pose[:3, :3], base[:3, :3]) > ANGLE_DEG:
        result.fail(move, "an approach or retract must keep the waypoint's orientation")
    branch = int(station.branch[i]) if lead is None else int(cell.branches(axes[:6])[0])
    distance = min(tries, key=lambda d: abs(distance - d))  # the back-off the program means, not as read back
    q, ok = cell.joints_on_branch(offset_along_z(base, distance)[None], axes[6:], branch, axes[:6])
    if is_approach:
        error = float(np.abs(move.joints - q[0]).max())
        result.max_joint_rad = max(result.max_joint_rad, error)
        if not ok[0] or error > JOINT_RAD:
            result.fail(move, f"the joint target is {error:.3g} rad from the plan's branch at the approach pose")
    elif fmt in ("rapid", "krl"):
        station.pending.append((move, q[0], branch, axes[6:], offset_along_z(base, distance)))


def _check_gun(poses, chain, approach: int, indices, cfg, fmt, result, at_start=(), off_at: int = -1) -> None:
    """With its leads, the gun is open from the run's first waypoint (``chain[approach]``'s target) to its last
    (``chain[off_at]``'s: the last move's, or the one before a run-out), nowhere else. ``poses``: the approach
    pose, then each move's target; ``at_start``: the events of the joint move before the chain (URScript: at
    its end, where the robot stands)."""
    paint = fmt == "rapid" and cfg.rapid_paint
    lead = {True: 0.0 if paint else cfg.lead_on_s, False: 0.0 if paint else cfg.lead_off_s}
    positions = [p[:3, 3] for p in poses]
    lengths = [float(np.linalg.norm(b - a)) for a, b in itertools.pairwise(positions)]
    ends = np.cumsum([0.0, *lengths])  # path position of the approach pose, then of each move's target
    times = np.cumsum([0.0] + [length / m.speed_mm_s for length, m in zip(lengths, chain)])
    events = [(times[j + 1] - d / m.speed_mm_s + lead[on], on, m) for j, m in enumerate(chain) for d, on in m.events]
    events = [(lead[on], on, chain[0]) for _, on in at_start] + events
    if sum(i >= 0 for i in indices) < 2:
        if events:
            result.fail(chain[0], "a run of one waypoint must not switch the gun")
        return
    ons = [e for e in events if e[1]]
    offs = [e for e in events if not e[1]]
    if len(ons) != 1 or len(offs) != 1:
        result.fail(chain[0], f"a run must switch the gun on once and off once, got {len(ons)} on and {len(offs)} off")
        return

    def path(t):  # where the program is at time t; before and after the chain at its first and last speed
        if t < 0:
            return t * chain[0].speed_mm_s
        if t > times[-1]:
            return ends[-1] + (t - times[-1]) * chain[-1].speed_mm_s
        return float(np.interp(t, times, ends))

    last = off_at % len(chain)
    for (t, _, move), target in ((ons[0], times[approach + 1]), (offs[0], times[last + 1])):
        error = abs(path(t) - path(target))
        result.max_gun_mm = max(result.max_gun_mm, error)
        if error > POSITION_MM:
            result.fail(move, f"with its lead the gun switches {error:.4g} mm from the run's end waypoint")
