"""The main job: part -> paths (or target points) -> stations -> ordering -> kinematics -> a Plan.

paths or targets      spray strokes over the part (seed 003) or target points (seed 000 section 2)
stations              the flange positions projected on xy, covered by the fewest working circles,
                      each waypoint given greedily to a station (seed 000 section 5.1)
platform tour         from home back to home over the stations, exact, Manhattan metric (section 5.1.3)
ordering              strokes of a station (each either way round) or, in points mode, its targets as a
                      travelling-salesman tour (section 5.2, the seed's GA on request)
kinematics            nine axes at every waypoint: analytic IK in the recommended region, SQP elsewhere;
                      the arm starts each station from home (collision avoidance, section 5.2)
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass

import numpy as np

from sprayplan.config import JobConfig
from sprayplan.errors import InputError
from sprayplan.paths.planner import plan_paths, with_transfers
from sprayplan.paths.speed import stroke_time
from sprayplan.robots.gantry import Gantry, load_gun, solve_gantry_path
from sprayplan.robots.model import load_robot
from sprayplan.stations import assign_greedy, circle_cover
from sprayplan.surface.poses import rotation_from_z
from sprayplan.types import Part, Plan, StationPlan, Stroke

log = logging.getLogger(__name__)

#: Tour method of the plan's "auto": the deterministic nearest neighbour + 2-opt + Or-opt descent, so that the
#: same part and settings give the same plan on any machine (the time-bounded solvers' results depend on the
#: machine's speed). Order strokes with ``tour="exact"`` (up to 6) for the optimum.
REPRODUCIBLE = "2opt"

HOME_JOINTS = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0])


def gun_poses(stroke: Stroke) -> np.ndarray:
    """(n, 4, 4) gun poses along a stroke: origin at the tcp, z along -normal, turned about z as seed 000's
    eq. 5 (Rodrigues from (0, 0, 1)).

    The roll about the gun's own axis does not change the spray, so it is not tied to the direction of travel:
    a stroke run backwards keeps its poses, and the flange (offset sideways from the gun axis by T_tool)
    stays where the station assignment put it.
    """
    poses = np.zeros((len(stroke), 4, 4))
    poses[:, :3, :3] = rotation_from_z(-stroke.normals)
    poses[:, :3, 3] = stroke.tcp
    poses[:, 3, 3] = 1.0
    return poses


def _split_by_station(stroke: Stroke, station: np.ndarray) -> list[tuple[int, Stroke]]:
    """Contiguous runs of a stroke's waypoints that belong to the same station (-1 runs dropped).

    A run handed over to another station goes on to that station's first waypoint, so that the segment
    between the two is sprayed too (by the first station); without it every hand-over would leave a stripe
    one step wide with less paint.
    """
    out = []
    edges = np.flatnonzero(np.diff(station)) + 1
    for start, stop in zip(np.r_[0, edges], np.r_[edges, len(station)]):
        k = int(station[start])
        if k < 0:
            continue
        handed_over = stop < len(station) and station[stop] >= 0
        sl = slice(start, stop + 1 if handed_over else stop)
        out.append((k, stroke.part(sl)))
    return out


@dataclass(frozen=True)
class _Work:
    """Spray strokes to place, with the flange xy of every waypoint."""

    strokes: list
    flange_xy: np.ndarray
    flange_z: np.ndarray
    owner: np.ndarray  # stroke index of each waypoint


def _spray_work(part: Part, job: JobConfig, gantry: Gantry) -> _Work:
    if job.plan.mode == "paths":
        strokes = list(plan_paths(part, job.paths).spray_strokes)
    else:
        from sprayplan.surface.targets import make_targets

        targets = make_targets(part, job.targets)
        standoff = job.paths.standoff_mm
        strokes = [
            Stroke(p[None], n[None], (p + standoff * n)[None], True, None, -1)
            for p, n in zip(targets.points, targets.normals)
        ]
    if not strokes:
        raise InputError(f"{part.name}: nothing to paint")
    poses = np.concatenate([gun_poses(s) for s in strokes])
    flange = poses @ np.linalg.inv(gantry.gun.gun2flange)
    owner = np.concatenate([np.full(len(s), i) for i, s in enumerate(strokes)])
    return _Work(strokes, flange[:, :2, 3], flange[:, 2, 3], owner)


def plan(part: Part, job: JobConfig | None = None) -> Plan:
    """Plan a whole spray program for a part (already loaded and cut to its region).

    Returns
    -------
    Plan
        Stations in visiting order, each with its ordered strokes and the nine axes at every waypoint;
        waypoints no station reaches are in ``Plan.unassigned``; unreachable waypoints are flagged, not
        raised.
    """
    from sprayplan.ordering import order_strokes, solve_tour

    job = JobConfig() if job is None else job
    settings = job.plan
    gantry = Gantry(robot=load_robot("ur5"), gun=load_gun(settings.tool))
    work = _spray_work(part, job, gantry)
    space = gantry.workspace
    cover = circle_cover(work.flange_xy, space.radius_mm, space.core_diameter_mm / 2, seed=settings.seed)
    centres = cover.centres
    home = np.array(settings.home_mm)
    if settings.platform_z_mm is not None:
        platform_z = float(settings.platform_z_mm)
    else:  # the flange positions' mean height at the middle of the working cylinder
        platform_z = gantry.platform_z_for(float(work.flange_z.mean()))
    platforms = np.column_stack([centres, np.full(len(centres), platform_z)])
    # platform tour: home -> stations -> home, exact for few stations, Manhattan (the axes move separately)
    nodes = np.vstack([home, platforms])
    method = "exact" if len(nodes) <= 12 else "2opt"
    tour = solve_tour(nodes, method=method, closed=True, start=0, metric="manhattan", seed=settings.seed)
    visit = [int(i) - 1 for i in tour.order if i != 0]
    assignment = assign_greedy(work.flange_xy, centres, np.array(visit), space.radius_mm, space.core_diameter_mm / 2)
    # pieces of strokes per station
    per_station: dict[int, list[Stroke]] = {k: [] for k in visit}
    offsets = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
    for i, stroke in enumerate(work.strokes):
        for k, piece in _split_by_station(stroke, assignment.station[offsets[i] : offsets[i + 1]]):
            per_station[k].append(piece)
    unassigned_mask = assignment.station < 0
    all_points = np.concatenate([s.points for s in work.strokes])
    stations = []
    paths_config = job.paths
    for k in visit:
        pieces = per_station[k]
        if not pieces:
            continue
        ordered = _order_station(pieces, settings, platforms[k], order_strokes, solve_tour)
        strokes = with_transfers(ordered, paths_config)
        poses = np.concatenate([gun_poses(s) for s in strokes])
        result = solve_gantry_path(
            gantry,
            poses,
            platforms[k],
            seed_q=HOME_JOINTS,
            k_d=settings.k_d,
            position_tol_mm=settings.position_tol_mm,
            axis_tol_rad=math.radians(settings.axis_tol_deg),
        )
        stations.append(_station(k, platforms[k], strokes, result))
    log.info("%s: %d stations, %d waypoints unassigned", part.name, len(stations), int(unassigned_mask.sum()))
    return Plan(tuple(stations), home, all_points[unassigned_mask], part.name)


#: How many stations, nearest first, an added stroke's stretches are offered to (``with_added_strokes``).
ADDED_STROKE_STATIONS = 2


def with_added_strokes(plan_: Plan, strokes: list[Stroke], job: JobConfig, new_stations: int = 0) -> Plan:
    """The plan with extra spray strokes (touch-ups), each run at the end of the station whose gantry position
    is nearest its flange positions (in xy), after a transfer, either way round (the nearer end first), with
    the nine axes solved from that station as in :func:`plan`.

    A stroke the arm cannot follow all the way is cut to the stretches it reaches (at least a spray radius
    long) and solved again. The stretches it does not reach are offered to the next nearest station, up to
    ``ADDED_STROKE_STATIONS`` stations in all. What these miss goes to up to ``new_stations`` new stations at
    the plan's gantry height, placed where the arm reaches it (``stations.added``; a surface facing sideways or
    down is sprayed from beside the part), each inserted into the platform tour where it adds the least
    travel. What no station reaches is left out, so every added spray waypoint is reachable."""
    if not strokes or not plan_.stations:
        return plan_
    gantry = Gantry(robot=load_robot("ur5"), gun=load_gun(job.plan.tool))
    stations = list(plan_.stations)
    centres = np.array([st.platform_mm[:2] for st in stations])
    accepted: dict[int, list[tuple[Stroke, frozenset]]] = {}
    solved: dict[int, tuple] = {}
    pending = [(stroke, frozenset()) for stroke in strokes]
    for _ in range(min(ADDED_STROKE_STATIONS, len(stations))):
        offers: dict[int, list[tuple[Stroke, frozenset]]] = {}
        for stroke, tried in pending:
            flange_xy = (gun_poses(stroke) @ np.linalg.inv(gantry.gun.gun2flange))[:, :2, 3].mean(axis=0)
            for k in np.argsort(np.linalg.norm(centres - flange_xy, axis=1), kind="stable"):
                if int(k) not in tried:
                    offers.setdefault(int(k), []).append((stroke, tried | {int(k)}))
                    break
        pending = []
        for k, offered in offers.items():
            candidates = accepted.get(k, []) + offered
            kept, missed, new, result = _fit_to_station(gantry, stations[k], candidates, job)
            accepted[k] = kept
            if kept:
                solved[k] = (new, result)
            else:
                solved.pop(k, None)
            pending += missed
        if not pending:
            break
    for k, (new, result) in solved.items():
        st = stations[k]
        stations[k] = _station(st.index, st.platform_mm, new, result, after=st)
    count = sum(len(kept) for kept in accepted.values())
    if pending and new_stations > 0:
        for station in _new_stations(gantry, plan_, [stroke for stroke, _ in pending], job, new_stations):
            count += sum(1 for s in station.strokes if s.spray_on)
            _insert_in_tour(stations, station, plan_.home_mm)
    log.info("%s: %d strokes added (%d asked for; cut to what the arm reaches)", plan_.name, count, len(strokes))
    return Plan(tuple(stations), plan_.home_mm, plan_.unassigned, plan_.name)


def _new_stations(gantry, plan_: Plan, strokes: list[Stroke], job: JobConfig, most: int) -> list[StationPlan]:
    """Up to ``most`` new stations, at the plan's gantry height, for strokes its stations do not reach: each
    with the strokes (cut to what the arm reaches) and their joints, started from home."""
    from sprayplan.stations.added import stations_for_strokes

    height = float(np.median([st.platform_mm[2] for st in plan_.stations]))
    placed = stations_for_strokes(gantry, [gun_poses(s) for s in strokes], height, max_stations=most)
    index = max(st.index for st in plan_.stations) + 1
    out = []
    for place in placed:
        empty = StationPlan(index, place.platform_mm, (), *_PATH_EMPTY)
        taken = _nearest_first([strokes[i] for i in place.strokes])
        kept, _, new, result = _fit_to_station(gantry, empty, [(s, frozenset()) for s in taken], job)
        if kept:
            out.append(_station(index, place.platform_mm, new, result))
            index += 1
    return out


#: A StationPlan's per-waypoint fields for no waypoints (q9, reachable, method, errors, branch changes).
_PATH_EMPTY = (np.zeros((0, 9)), np.zeros(0, bool), np.zeros(0, object), np.zeros(0), np.zeros(0), np.zeros(0, bool))


def _station(index: int, platform, strokes, path, after: StationPlan | None = None) -> StationPlan:
    """A station's plan from strokes and their joints (a ``GantryPath``), run after ``after``'s when given."""
    fields = (path.q9, path.reachable, path.method, path.position_error_mm, path.axis_error_deg, path.branch_change)
    if after is not None:
        before = (after.q9, after.reachable, after.method, after.position_error_mm, after.axis_error_deg)
        fields = tuple(np.concatenate([a, b]) for a, b in zip((*before, after.branch_change), fields))
        strokes = after.strokes + tuple(strokes)
    return StationPlan(index, platform, tuple(strokes), *fields)


def _insert_in_tour(stations: list[StationPlan], station: StationPlan, home: np.ndarray) -> None:
    """Insert a station into the visiting order where it adds the least platform travel (Manhattan, from home
    back to home, as the platform tour)."""
    stops = [np.asarray(home), *[st.platform_mm for st in stations], np.asarray(home)]
    extra = [
        np.abs(a - station.platform_mm).sum() + np.abs(station.platform_mm - b).sum() - np.abs(a - b).sum()
        for a, b in itertools.pairwise(stops)
    ]
    stations.insert(int(np.argmin(extra)), station)


def _fit_to_station(gantry, st: StationPlan, candidates: list[tuple[Stroke, frozenset]], job: JobConfig):
    """Strokes appended to one station, cut until the arm reaches every waypoint of them.

    Returns the strokes kept (each with the stations it has been offered to), the stretches of the candidates
    the first solve found out of reach (to offer elsewhere), and the appended strokes with their joints.
    """
    strokes = [stroke for stroke, _ in candidates]
    tried = [t for _, t in candidates]
    new, result, reached, first = _solved_additions(gantry, st, strokes, job)
    missed = [
        (run, t) for stroke, mask, t in zip(new[first::2], reached, tried) for run in _reached_runs(stroke, ~mask, job)
    ]
    for _ in range(5):  # cut to the runs the arm reaches, and solve again
        if all(mask.all() for mask in reached):
            return list(zip(strokes, tried)), missed, new, result
        cut = [
            (run, t)
            for stroke, mask, t in zip(new[first::2], reached, tried)
            for run in _reached_runs(stroke, mask, job)
        ]
        if not cut:
            break
        strokes, tried = [c[0] for c in cut], [c[1] for c in cut]
        new, result, reached, first = _solved_additions(gantry, st, strokes, job)
    return [], missed, new, result


def _solved_additions(gantry, st: StationPlan, added: list[Stroke], job: JobConfig):
    """Strokes appended to a station (nearer end first, transfers between) and their joints; for each added
    stroke whether the arm reaches its waypoints; and where the added strokes start among the new strokes
    (1 after a transfer from the station's last stroke, 0 at a new station; transfers alternate with them)."""
    settings = job.plan
    ordered = []
    here = st.strokes[-1].tcp[-1] if st.strokes else None
    for stroke in added:
        if here is not None and np.linalg.norm(stroke.tcp[-1] - here) < np.linalg.norm(stroke.tcp[0] - here):
            stroke = stroke.reversed()
        ordered.append(stroke)
        here = stroke.tcp[-1]
    if st.strokes:  # new = transfer, stroke, transfer, stroke, ...
        new, first = with_transfers([st.strokes[-1], *ordered], job.paths)[1:], 1
    else:  # a new station: stroke, transfer, stroke, ..., started from home
        new, first = with_transfers(ordered, job.paths), 0
    last = st.q9[-1, :6] if len(st.q9) else HOME_JOINTS
    result = solve_gantry_path(
        gantry,
        np.concatenate([gun_poses(s) for s in new]),
        st.platform_mm,
        seed_q=last if np.isfinite(last).all() else HOME_JOINTS,
        k_d=settings.k_d,
        position_tol_mm=settings.position_tol_mm,
        axis_tol_rad=math.radians(settings.axis_tol_deg),
    )
    bounds = np.r_[0, np.cumsum([len(s) for s in new])]
    reached = [result.reachable[a:b] for a, b in itertools.pairwise(bounds)]
    return new, result, reached[first::2], first


def _nearest_first(strokes: list[Stroke]) -> list[Stroke]:
    """Strokes in nearest-neighbour order from the first, each run from its end nearer the previous one's."""
    left, out = list(strokes[1:]), list(strokes[:1])
    while left:
        end = out[-1].tcp[-1]
        gaps = [np.linalg.norm(s.tcp[[0, -1]] - end, axis=1) for s in left]
        k = min(range(len(left)), key=lambda i: gaps[i].min())
        stroke = left.pop(k)
        out.append(stroke.reversed() if gaps[k][1] < gaps[k][0] else stroke)
    return out


def _reached_runs(stroke: Stroke, reached: np.ndarray, job: JobConfig) -> list[Stroke]:
    """The stretches of a stroke where ``reached`` holds at every waypoint, at least a spray radius long."""
    edges = np.flatnonzero(np.diff(np.r_[0, reached.astype(int), 0]))
    runs = [stroke.part(slice(a, b)) for a, b in zip(edges[::2], edges[1::2]) if b - a >= 2]
    return [run for run in runs if run.length_mm >= job.paths.spray_radius_mm]


def _order_station(pieces, settings, platform, order_strokes, solve_tour) -> list[Stroke]:
    if settings.mode == "points":
        tcp = np.concatenate([p.tcp for p in pieces])
        if len(pieces) == 1:
            return pieces
        from sprayplan.ordering import EXACT_MAX_N

        method = {"keep": REPRODUCIBLE, "auto": REPRODUCIBLE}.get(settings.tour, settings.tour)
        if method == "exact" and len(tcp) > EXACT_MAX_N:
            method = REPRODUCIBLE
        order = solve_tour(tcp, method=method, closed=False, seed=settings.seed).order
        points = np.concatenate([p.points for p in pieces])[order]
        normals = np.concatenate([p.normals for p in pieces])[order]
        dwell = np.concatenate([p.dwell for p in pieces])[order]
        return [Stroke(points, normals, tcp[order], True, None, -1, dwell)]
    if settings.tour == "keep" or len(pieces) == 1:
        return pieces
    starts = np.array([p.tcp[0] for p in pieces])
    ends = np.array([p.tcp[-1] for p in pieces])
    method = (
        "exact" if settings.tour == "exact" and len(pieces) <= 6 else "ga" if settings.tour == "ga" else REPRODUCIBLE
    )
    order, reverse, _ = order_strokes(starts, ends, start_point=None, method=method, seed=settings.seed)
    return [pieces[i].reversed() if r else pieces[i] for i, r in zip(order, reverse)]


def plan_totals(plan_: Plan, job: JobConfig) -> dict:
    """Lengths (mm), counts and the cycle time (s) of a plan."""
    settings = job.plan
    spray = sum(s.length_mm for st in plan_.stations for s in st.strokes if s.spray_on)
    spray_time = sum(
        stroke_time(s.tcp, s.points, settings.gun_speed_mm_s, settings.speed_along, settings.max_speed_ratio, s.dwell)
        for st in plan_.stations
        for s in st.strokes
        if s.spray_on
    )
    moves = sum(s.length_mm for st in plan_.stations for s in st.strokes if not s.spray_on)
    stops = [plan_.home_mm, *[st.platform_mm for st in plan_.stations], plan_.home_mm]
    platform = float(sum(np.abs(np.diff(np.array(stops), axis=0)).sum(axis=1)))
    reachable = np.concatenate([st.reachable for st in plan_.stations]) if plan_.stations else np.zeros(0, bool)
    errors = np.concatenate([st.position_error_mm for st in plan_.stations]) if plan_.stations else np.zeros(0)
    axes = np.concatenate([st.axis_error_deg for st in plan_.stations]) if plan_.stations else np.zeros(0)
    methods = np.concatenate([st.method for st in plan_.stations]) if plan_.stations else np.zeros(0, str)
    cycle = spray_time + moves / settings.transfer_speed_mm_s + platform / settings.platform_speed_mm_s
    return {
        "stations": len(plan_.stations),
        "strokes": int(sum(1 for st in plan_.stations for s in st.strokes if s.spray_on)),
        "waypoints": len(reachable),
        "unreachable_waypoints": int((~reachable).sum()),
        "unassigned_points": len(plan_.unassigned),
        "sqp_waypoints": int((methods == "sqp").sum()),
        "spray_length_mm": round(float(spray), 3),
        "transfer_length_mm": round(float(moves), 3),
        "platform_travel_mm": round(platform, 3),
        "max_position_error_mm": float(np.nanmax(errors)) if reachable.any() else None,
        "max_axis_error_deg": float(np.nanmax(axes)) if reachable.any() else None,
        "cycle_time_s": round(float(cycle), 3),
    }
