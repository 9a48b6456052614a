"""A plan as moves (:class:`~sprayplan.programs.model.CellProgram`): what every format's program does.

For each station in visiting order: a joint move home (the arm's home joints, where the plan solved each
station from), then each spray run, then home again (a cell robot whose work the cell's schedule timed: from
where the schedule has it when the cycle starts, to the park it ends at: :func:`plan_ends`). A *run* is a stretch of one spray stroke whose waypoints
the program reaches (docs/programs.md, "What the programs do"):

- a joint move (``transfer``) to the run's approach pose: its first waypoint moved back along the gun axis by
  ``[export] approach_mm``, the joints found on the plan's own branch there (closed-form IK, turns nearest the
  plan's joints), so the controller never picks a configuration;
- a linear ``approach`` to the first waypoint, the gun switched on ``lead_on_s`` before reaching it;
- one linear move per further waypoint at the plan's speed, blended (radius at most ``blend_mm`` and
  ``blend_share`` of the shorter neighbouring segment; 0 at the run's ends), the gun switched off
  ``lead_off_s`` before the last;
- a linear ``retract`` back along the gun axis;
- where a cell robot's plan has a run-up into the run's first waypoint (``cells.runups``), the transfer and the
  approach go to the run-up's start instead, and a linear ``run-up`` at the first segment's speed, blended
  into the first waypoint, follows the approach; where it has a run-out after the last waypoint, the last spray
  move is blended and a linear ``run-out`` at the last segment's speed comes before the retract, which backs
  off from the run-out's end (the gun is off on both);
- where the collision stage re-routed the transfer before a stroke (``collision.transfers``), a joint move
  (``route``) to each inner waypoint of the route before the stroke's first run.

Targets are the poses the plan's joints give the TCP (forward kinematics of ``q9``): equal to the plan's gun
poses where the analytic IK solved them, and what the arm really does where SQP did (within the plan's
``position_tol_mm``). A spray waypoint the plan marks unreachable splits its stroke: it is left out, with the gun
off over it. URScript cannot move the gantry during a station, so for it a waypoint where SQP moved the gantry
farther than ``[export] ur_gantry_offset_mm`` from the station's position is left out too (nearer ones are
sprayed with the plan's arm joints, the TCP off the plan's pose by the gantry's offset).

Speeds keep the plan's timing: the move into waypoint i takes the time the plan gives its segment (the gun
tip's ``tcp_speed_mm_s``), so its TCP speed is the TCP's path length over that time (the contact point's
speed, ``gun_speed_mm_s`` over the tuned time factor, when the standoff is the gun's spray distance). The main
job and ``sprayplan export`` give the plan at its timed speeds (``timing.stage.real_plan``: the time factors the
robot makes within its joints' limits), so the programs carry those.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np

from sprayplan.collision.transfers import is_route
from sprayplan.errors import InputError
from sprayplan.programs.model import (
    JOINT,
    LINEAR,
    Cell,
    CellProgram,
    Move,
    StationProgram,
    angle_between_deg,
    offset_along_z,
)
from sprayplan.robots.stage import gantry_for

#: The approach tried at the set distance, then at half, a quarter and an eighth of it.
APPROACH_TRIES = (1.0, 0.5, 0.25, 0.125)
#: Largest joint step (rad) between points 5 mm apart on an approach line: more means a singularity on the way.
LINE_STEP_RAD = 0.2
LINE_SAMPLE_MM = 5.0
#: Two consecutive waypoints whose targets are this close (mm and degrees: the read-back check's tolerances)
#: are one target: the program moves to it once, in the time the plan gives both segments (a controller could
#: not time a move of a few micrometres).
SAME_MM = 0.01
SAME_DEG = 0.01
#: The slowest TCP speed written (a move that is almost a pure reorientation about the TCP), mm/s.
MIN_SPEED_MM_S = 0.001
#: Blend radii are computed this much (mm) below their cap, so that the cap holds on the positions as written
#: (to 1e-4 mm) too.
BLEND_MARGIN_MM = 2e-4


@dataclass(frozen=True)
class Run:
    """Waypoints of one spray stroke that a program sprays in one go.

    Attributes
    ----------
    order : int
        The station's place in the visiting order.
    stroke : int
        The stroke's index in its station.
    index : (n,) int
        Waypoint indices in the station (``StationPlan.q9`` rows), in order.
    """

    order: int
    stroke: int
    index: np.ndarray


def run_limit(job, fmt: str) -> int:
    """Most waypoints of one run in ``fmt`` (a file holds at least one whole run: the runs are split beyond)."""
    cfg = job.export
    return {"urscript": cfg.ur_max_moves, "rapid": cfg.rapid_max_lines - 20, "krl": cfg.krl_max_moves}[fmt] - 10


def station_arrays(st, job) -> dict:
    """Per waypoint of a station: its stroke, whether it sprays, the plan's gun tip and normal, the gun tip's
    speed into it (``tcp_speed_mm_s``) and the time of the plan's segment into it (s; 0 for a stroke's first
    waypoint)."""
    from sprayplan.export.plan_json import tip_speeds

    stroke, spray, seconds, first, speed = [], [], [], [], []
    for i, s in enumerate(st.strokes):
        n = len(s)
        stroke.append(np.full(n, i))
        spray.append(np.full(n, s.spray_on))
        length = np.concatenate([[0.0], np.linalg.norm(np.diff(s.tcp, axis=0), axis=1)])
        speed.append(tip_speeds(s, job))
        seconds.append(length / speed[-1])
        first.append(np.arange(n) == 0)
    tcp = np.concatenate([s.tcp for s in st.strokes]) if st.strokes else np.zeros((0, 3))
    normals = np.concatenate([s.normals for s in st.strokes]) if st.strokes else np.zeros((0, 3))
    join = lambda parts, dtype: np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)
    return {
        "stroke": join(stroke, int),
        "spray": join(spray, bool),
        "seconds": join(seconds, float),
        "speed": join(speed, float),
        "first": join(first, bool),
        "tcp": tcp,
        "normals": normals,
    }


def wanted_targets(tcp: np.ndarray, normals: np.ndarray, spray_distance_mm: float) -> np.ndarray:
    """(n, 3) where the plan wants the TCP (the spray target): the gun tip plus the spray distance along the
    gun axis (``-normal``)."""
    return tcp - spray_distance_mm * normals


def _where(order: int, data: dict, k: int) -> dict:
    start = int(np.flatnonzero(data["stroke"] == data["stroke"][k])[0])
    return {"station": order, "stroke": int(data["stroke"][k]), "waypoint": int(k - start),
            "tcp_mm": [round(float(v), 3) for v in data["tcp"][k]]}  # fmt: skip


def spray_runs(plan, job, fmt: str, cell: Cell | None = None) -> tuple[list[list[Run]], dict]:
    """The runs of every station (in visiting order) and what was left out: ``unreachable_waypoints`` (spray
    waypoints the plan does not reach), ``gantry_offset_waypoints`` (URScript: the plan moves the gantry there
    farther than ``ur_gantry_offset_mm`` from the station),
    ``colliding_waypoints`` (a cell robot's waypoints still in collision after the plan's repairs), ``split_runs``
    (runs longer than a file allows, split with one waypoint in both parts), ``duplicate_waypoints`` (a target
    equal to the one before)."""
    cell = cell or Cell(gantry_for(job.kinematics))
    limit = run_limit(job, fmt)
    tol = job.export.ur_gantry_offset_mm + 1e-9
    report: dict = {"unreachable_waypoints": [], "gantry_offset_waypoints": [], "colliding_waypoints": [],
                    "split_runs": 0, "duplicate_waypoints": 0}  # fmt: skip
    out = []
    for order, st in enumerate(plan.stations):
        data = station_arrays(st, job)
        ok = st.reachable & data["spray"]
        for k in np.flatnonzero(data["spray"] & ~st.reachable):
            report["unreachable_waypoints"].append(_where(order, data, k))
        collides = getattr(st, "collides", None)  # a cell robot's waypoints still in collision after the repairs
        if collides is not None:
            for k in np.flatnonzero(ok & collides):
                report["colliding_waypoints"].append(_where(order, data, k))
            ok &= ~collides
        q9 = target_q9(st, fmt)
        poses = cell.poses(q9[:, :6], q9[:, 6:]) if len(q9) else np.zeros((0, 4, 4))
        if fmt == "urscript" and len(q9):
            off = ok & (np.linalg.norm(st.q9[:, 6:] - st.platform_mm, axis=1) > tol)
            for k in np.flatnonzero(off):
                report["gantry_offset_waypoints"].append(_where(order, data, k))
            ok &= ~off
        runs = []
        for stroke in np.unique(data["stroke"][data["spray"]]):
            index = np.flatnonzero(data["stroke"] == stroke)
            for piece in _pieces(index, ok[index]):
                piece = _without_duplicates(piece, poses, report)
                runs += [Run(order, int(stroke), part) for part in _split(piece, limit, report)]
        out.append(runs)
    return out, report


def target_q9(st, fmt: str) -> np.ndarray:
    """The nine axes a program drives at each waypoint: the plan's, with the gantry held at the station for
    URScript (which cannot move it)."""
    q9 = np.array(st.q9, dtype=float)
    if fmt == "urscript":
        q9[:, 6:] = st.platform_mm
    return q9


def _pieces(index: np.ndarray, ok: np.ndarray) -> list[np.ndarray]:
    """The stretches of consecutive reachable waypoints."""
    out, start = [], None
    for j, good in enumerate(ok):
        if good and start is None:
            start = j
        if not good and start is not None:
            out.append(index[start:j])
            start = None
    if start is not None:
        out.append(index[start:])
    return out


def _without_duplicates(index: np.ndarray, poses: np.ndarray, report: dict) -> np.ndarray:
    keep = [index[0]]
    for k in index[1:]:
        last = poses[keep[-1]]
        same = (
            np.linalg.norm(poses[k, :3, 3] - last[:3, 3]) <= SAME_MM
            and angle_between_deg(poses[k, :3, :3], last[:3, :3]) <= SAME_DEG
        )
        if same:
            report["duplicate_waypoints"] += 1
        else:
            keep.append(k)
    return np.array(keep, dtype=int)


def _split(index: np.ndarray, limit: int, report: dict) -> list[np.ndarray]:
    if len(index) <= limit:
        return [index]
    report["split_runs"] += 1
    parts, start = [], 0
    while start < len(index) - 1:
        parts.append(index[start : start + limit])
        start += limit - 1
    return parts


def build_program(plan, job, fmt: str, strict: bool | None = None, cell=None) -> CellProgram:
    """The moves of every station for ``fmt`` (``urscript``, ``rapid``, ``krl``), and the report of what was
    left out (the ``summary.json`` of the export). ``cell``: the robot the plan is for (default the job's
    gantry; a cell robot's is ``programs.arms.ArmCell``, whose plan is ``programs.arms.arm_plan``).

    Raises
    ------
    InputError
        With ``strict`` (default ``[export] strict``): a spray waypoint that is left out (unreachable, or for
        URScript a gantry move), or a run with no approach the arm can make; the message says how many and
        where the first is.
    """
    cfg = job.export
    strict = cfg.strict if strict is None else strict
    cell = cell or Cell(gantry_for(job.kinematics))
    runs, report = spray_runs(plan, job, fmt, cell)
    report.update({"unapproachable_waypoints": [], "shortened_approaches": 0, "single_waypoint_runs": 0,
                   "clipped_leads": 0, "unswitched_runs": 0, "run_ups": 0, "run_outs": 0,
                   "run_ups_left_out": 0})  # fmt: skip
    lead_on, lead_off = (0.0, 0.0) if fmt == "rapid" and cfg.rapid_paint else (cfg.lead_on_s, cfg.lead_off_s)
    stations = []
    for order, (st, st_runs) in enumerate(zip(plan.stations, runs)):
        data = station_arrays(st, job)
        q9 = target_q9(st, fmt)
        poses = cell.poses(q9[:, :6], q9[:, 6:]) if len(q9) else np.zeros((0, 4, 4))
        start, end = plan_ends(plan, cell, st.platform_mm)
        moves = [start]
        routed: set = set()
        waits = getattr(st, "wait_s", None)  # a cell robot's schedule: the wait before each stroke
        waited: set = set()
        leads = getattr(st, "leads", None)  # a cell robot's run-ups and run-outs (cells.runups)
        for run in st_runs:
            moves += route_moves(st, run, data, poses, q9, routed)
            run_moves = _run_moves(cell, cfg, run, data, poses, q9, lead_on, lead_off, report, leads)
            if waits is not None and run_moves and run.stroke not in waited:
                waited.add(run.stroke)
                if waits[run.stroke] > 0:
                    run_moves[1] = dataclasses.replace(run_moves[1], wait_s=float(waits[run.stroke]))
            moves += run_moves
        if order == len(plan.stations) - 1:
            moves += park_route_moves(plan, cell)
        moves.append(end)
        stations.append(StationProgram(order, st.index, np.array(st.platform_mm), tuple(moves)))
    if strict:
        _refuse(report)
    home, park = plan_ends(plan, cell, plan.home_mm)
    return CellProgram(
        tuple(stations),
        np.array(plan.home_mm),
        cell.home_joints,
        cell.tool2flange,
        plan.name,
        report,
        home,
        park=park,
        **getattr(cell, "program_fields", dict)(),
    )


def route_moves(st, run: Run, data, poses, q9, routed: set) -> list[Move]:
    """Joint moves (``route``) to the inner waypoints of the transfer before ``run``'s stroke when the collision
    stage re-routed it (``collision.transfers``; its ends are the strokes' own waypoints): before the stroke's
    first run only (``routed``: the strokes done)."""
    if run.stroke == 0 or run.stroke in routed:
        return []
    routed.add(run.stroke)
    before = np.flatnonzero(data["stroke"] == run.stroke - 1)
    if not len(before) or data["spray"][before].any() or not is_route(st.repair[before]):
        return []
    inner = [int(k) for k in before[1:-1] if st.reachable[k]]
    return [Move(JOINT, "route", poses[k], q9[k, :6].copy(), q9[k, 6:].copy()) for k in inner]


def park_route_moves(plan, cell: Cell) -> list[Move]:
    """Joint moves (``route``) through the nodes of the way to the end park where the cell's schedule routes it
    (``programs.arms.ArmPlan.park_route``: no joint move from the last run's retract to any park is free); []
    without."""
    route = getattr(plan, "park_route", None)
    if route is None:
        return []
    joints, external = route
    return [
        Move(JOINT, "route", cell.poses(q, mm)[0], np.array(q, float), np.array(mm, float))
        for q, mm in zip(joints, external)
    ]


def _refuse(report: dict) -> None:
    for key, what in (
        ("unreachable_waypoints", "spray waypoints the plan marks unreachable"),
        ("gantry_offset_waypoints", "spray waypoints where the plan moves the gantry (URScript cannot)"),
        ("colliding_waypoints", "spray waypoints the plan finds in collision after its repairs"),
        ("unapproachable_waypoints", "spray waypoints at a run's end the arm cannot back off from along the gun axis"),
    ):
        found = report[key]
        if found:
            first = found[0]
            raise InputError(
                f"--strict: {len(found)} {what} (the first: station {first['station'] + 1}, stroke "
                f"{first['stroke']}, waypoint {first['waypoint']}, at {tuple(first['tcp_mm'])} mm): no program "
                "written"
            )


def _home(cell: Cell, external_mm, joints=None) -> Move:
    home = cell.home_joints if joints is None else np.asarray(joints, float)
    pose = cell.poses(home, external_mm)[0]
    return Move(JOINT, "home", pose, home, np.array(external_mm, float))


def plan_ends(plan, cell: Cell, external_mm) -> tuple[Move, Move]:
    """The joint moves a program (or a station, ``external_mm`` its gantry position) starts and ends with: home
    (the arm's home joints at ``external_mm``), or, for a cell robot whose work is scheduled
    (``programs.arms.ArmPlan.ends_joints``), where the cell's schedule has it when the cycle starts (its first
    waypoint, or the park it starts from) and the park it ends at, with their track positions."""
    joints = getattr(plan, "ends_joints", None)
    if joints is None:
        return _home(cell, external_mm), _home(cell, external_mm)
    return _home(cell, plan.ends_mm[0], joints[0]), _home(cell, plan.ends_mm[1], joints[1])


def line_joints(cell: Cell, start: np.ndarray, end: np.ndarray, external_mm, q_start: np.ndarray):
    """Joints at ``end`` (4, 4) reached from ``start`` with joints ``q_start`` by a straight line of constant
    orientation, on ``q_start``'s branch: None when a point of the line (every 5 mm) is out of reach, beyond a
    limit, or the joints jump (a singularity)."""
    branch = int(cell.branches(q_start)[0])
    length = float(np.linalg.norm(end[:3, 3] - start[:3, 3]))
    steps = max(1, math.ceil(length / LINE_SAMPLE_MM))
    fractions = np.arange(1, steps + 1) / steps
    poses = np.repeat(end[None], steps, axis=0)
    poses[:, :3, 3] = start[:3, 3] + fractions[:, None] * (end[:3, 3] - start[:3, 3])
    solutions = cell.solutions(poses, external_mm)
    previous = np.asarray(q_start, float)
    from sprayplan.robots.ur_ik import nearest_equivalent

    for k in range(steps):
        q = nearest_equivalent(solutions.q[k, branch], previous, cell.lower, cell.upper)
        if not (solutions.valid[k, branch] and cell.within_limits(q[None])[0]):
            return None
        if np.abs(q - previous).max() > LINE_STEP_RAD:
            return None
        previous = q
    return previous


def _back_off(cell: Cell, cfg, poses, q9, k: int):
    """(distance, pose, joints) of the point ``approach_mm`` (or half, a quarter, an eighth of it) back along the
    gun axis from waypoint k that a straight line from k reaches on its branch; None when none does."""
    return _back_off_from(cell, cfg, poses[k], q9[k])


def _back_off_from(cell: Cell, cfg, pose, q9):
    """:func:`_back_off` from ``pose`` with the axes ``q9`` (joints, then the external axes) there."""
    for share in APPROACH_TRIES:
        distance = cfg.approach_mm * share
        back = offset_along_z(pose, distance)
        q = line_joints(cell, pose, back, q9[6:], q9[:6])
        if q is not None:
            return distance, back, q
    return None


def _lead(cell: Cell, cfg, leads, k: int, side: int, report, usable: bool = True):
    """``(pose, axes, back-off)`` of the run-up into waypoint k (side 0) or the run-out after it (side 1) where
    the plan has one (``cells.runups``) and the arm backs off from its end along the gun axis; else None. One
    the plan has but the program does not make (no back-off reaches it, or not ``usable``: its waypoint left
    out unapproachable, a run of one waypoint) is counted in ``run_ups_left_out``: the run then starts or ends
    at rest, as without."""
    if leads is None or not np.isfinite(leads[k, side]).all():
        return None
    axes = np.asarray(leads[k, side], float)
    pose = cell.poses(axes[:6], axes[6:])[0]
    back = _back_off_from(cell, cfg, pose, axes) if usable else None
    if back is None:
        report["run_ups_left_out"] += 1
        return None
    return pose, axes, back


def _run_moves(cell, cfg, run: Run, data, poses, q9, lead_on, lead_off, report, leads=None) -> list[Move]:
    """The moves of a run: transfer, approach, spray moves, retract. Waypoints at the run's ends from which the
    arm cannot back off along the gun axis are left out (``unapproachable_waypoints``); [] when none can."""
    index = run.index
    start = end = None
    for j in range(len(index)):
        start = _back_off(cell, cfg, poses, q9, int(index[j]))
        if start is not None:
            break
    if start is None:
        j = len(index)
    jend = len(index) - 1
    while start is not None and jend >= j:
        end = _back_off(cell, cfg, poses, q9, int(index[jend]))
        if end is not None:
            break
        jend -= 1
    for k in list(index[:j]) + list(index[jend + 1 :] if start is not None else []):
        report["unapproachable_waypoints"].append(_where(run.order, data, int(k)))
    if start is None or end is None:
        return []
    index = index[j : jend + 1]
    first = int(index[0])
    up = _lead(cell, cfg, leads, int(run.index[0]), 0, report, j == 0 and len(index) > 1)
    out = _lead(cell, cfg, leads, int(run.index[-1]), 1, report, jend == len(run.index) - 1 and len(index) > 1)
    if up is not None:
        start = up[2]
    if out is not None:
        end = out[2]
    distance, a_pose, q_a = start
    report["shortened_approaches"] += int(distance < cfg.approach_mm) + int(end[0] < cfg.approach_mm)
    v_app = cfg.approach_speed_mm_s if lead_on <= 0 else min(cfg.approach_speed_mm_s, distance / lead_on)
    lengths = np.linalg.norm(np.diff(poses[index, :3, 3], axis=0), axis=1)
    speeds = []
    for j in range(1, len(index)):
        k, prev = int(index[j]), int(index[j - 1])
        seconds = float(data["seconds"][prev + 1 : k + 1].sum())
        # the plan's time for the segment; where its gun tip stands still (it turns about itself) the plan's speed
        speed = lengths[j - 1] / seconds if seconds > 0 else float(data["speed"][k])
        speeds.append(max(speed, MIN_SPEED_MM_S))
    ext = q9[first, 6:].copy()
    if up is None:
        moves = [
            Move(JOINT, "transfer", a_pose, q_a, ext),
            Move(LINEAR, "approach", poses[first], q9[first, :6].copy(), ext, v_app, 0.0, source=(run.order, first)),
        ]  # fmt: skip
    else:  # the approach to the run-up's start, then the run-up at the first segment's speed, blended
        pose, axes, _ = up
        run_up = float(np.linalg.norm(poses[first, :3, 3] - pose[:3, 3]))
        moves = [
            Move(JOINT, "transfer", a_pose, q_a, axes[6:].copy()),
            Move(LINEAR, "approach", pose, axes[:6].copy(), axes[6:].copy(), v_app, 0.0),
            Move(LINEAR, "run-up", poses[first], q9[first, :6].copy(), ext, speeds[0],
                 _blend(cfg, run_up, lengths[0]), source=(run.order, first)),
        ]  # fmt: skip
        report["run_ups"] += 1
    for j in range(1, len(index)):
        k = int(index[j])
        after = lengths[j] if j < len(index) - 1 else None
        if after is None and out is not None:
            after = float(np.linalg.norm(out[0][:3, 3] - poses[k, :3, 3]))
        blend = 0.0 if after is None else _blend(cfg, lengths[j - 1], after)
        moves.append(Move(LINEAR, "spray", poses[k], q9[k, :6].copy(), q9[k, 6:].copy(), speeds[j - 1], blend,
                          source=(run.order, k)))  # fmt: skip
    if out is not None:
        pose, axes, _ = out
        moves.append(Move(LINEAR, "run-out", pose, axes[:6].copy(), axes[6:].copy(), speeds[-1], 0.0))
        report["run_outs"] += 1
    moves.append(Move(LINEAR, "retract", end[1], end[2], moves[-1].external_mm.copy(), cfg.approach_speed_mm_s, 0.0))
    if len(index) < 2:
        report["single_waypoint_runs"] += 1
        return moves
    return _with_gun_events(moves, distance, lead_on, lead_off, report, int(up is not None), int(out is not None))


def _blend(cfg, before_mm: float, after_mm: float) -> float:
    """The blend radius at a waypoint between segments of these lengths (module docstring)."""
    cap = min(cfg.blend_mm, cfg.blend_share * before_mm, cfg.blend_share * after_mm)
    return max(0.0, cap - BLEND_MARGIN_MM)


def _with_gun_events(
    moves: list[Move], approach_mm: float, lead_on: float, lead_off: float, report, run_up: int = 0, run_out: int = 0
) -> list[Move]:
    """The run's moves with the gun's on signal ``lead_on`` before the first spray waypoint (on the approach or
    the run-up) and its off signal where, ``lead_off`` before the last spray waypoint, the program's timing puts
    it (moves: transfer, approach, the run-up if ``run_up``, spray..., the run-out if ``run_out``, retract)."""
    chain = moves[1:-1]  # approach, run-up, spray moves and run-out: the gun switches on these
    lengths = [approach_mm] + [
        float(np.linalg.norm(b.pose[:3, 3] - a.pose[:3, 3])) for a, b in itertools.pairwise(chain)
    ]
    ends = np.cumsum([length / m.speed_mm_s for length, m in zip(lengths, chain)])
    t_on = ends[run_up] - lead_on
    t_off = ends[len(chain) - 1 - run_out] - lead_off
    if t_off < 0:
        report["clipped_leads"] += 1
        t_off = 0.0
    if t_off <= t_on + 1e-12:
        report["unswitched_runs"] += 1
        return moves
    events: dict[int, list] = {}
    for t, on in ((t_on, True), (t_off, False)):
        m = int(np.searchsorted(ends, t - 1e-12))  # the move during which (or at whose end) the signal is due
        m = min(m, len(chain) - 1)
        distance = max(0.0, (ends[m] - t) * chain[m].speed_mm_s)
        events.setdefault(m, []).append((min(distance, lengths[m]), on))
    for m, found in events.items():
        chain[m] = dataclasses.replace(chain[m], events=tuple(sorted(found, key=lambda e: -e[0])))
    return [moves[0], *chain, moves[-1]]
