"""Strokes added to a finished plan (touch-ups): run from the planned stations that reach them, or from new
gantry stations placed for them, the nine axes solved as in the kinematics stage.
"""

from __future__ import annotations

import itertools
import logging

import numpy as np

from sprayplan.config import JobConfig
from sprayplan.parallel import process_count, shared_map
from sprayplan.paths.planner import with_transfers
from sprayplan.robots.stage import gantry_for, solve_strokes, station_plan
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Plan, StationPlan, Stroke

log = logging.getLogger(__name__)


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
    gantry = gantry_for(job.kinematics)
    stations = list(plan_.stations)
    centres = np.array([st.platform_mm[:2] for st in stations])
    accepted: dict[int, list[tuple[Stroke, frozenset]]] = {}
    solved: dict[int, tuple] = {}
    pending = [(stroke, frozenset()) for stroke in strokes]
    for _ in range(min(ADDED_STROKE_STATIONS, len(stations))):
        offers: dict[int, list[tuple[Stroke, frozenset]]] = {}
        for stroke, tried in pending:
            flange_xy = (stroke_poses(stroke) @ np.linalg.inv(gantry.gun.gun2flange))[:, :2, 3].mean(axis=0)
            for k in np.argsort(np.linalg.norm(centres - flange_xy, axis=1), kind="stable"):
                if int(k) not in tried:
                    offers.setdefault(int(k), []).append((stroke, tried | {int(k)}))
                    break
        pending = []
        asked = [(gantry, stations[k], accepted.get(k, []) + offered, job) for k, offered in offers.items()]
        fitted = shared_map(_fitted, asked, process_count(job.kinematics.processes))
        for k, (kept, missed, new, result) in zip(offers, fitted):
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
        stations[k] = station_plan(st.index, st.platform_mm, new, result, after=st)
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
    from sprayplan.refine.added_stations import stations_for_strokes

    height = float(np.median([st.platform_mm[2] for st in plan_.stations]))
    placed = stations_for_strokes(gantry, [stroke_poses(s) for s in strokes], height, max_stations=most)
    index = max(st.index for st in plan_.stations) + 1
    asked = []
    for place in placed:
        empty = StationPlan(index, place.platform_mm, (), *_PATH_EMPTY)  # its index set below
        taken = _nearest_first([strokes[i] for i in place.strokes])
        asked.append((gantry, empty, [(s, frozenset()) for s in taken], job))
    out = []
    for place, (kept, _, new, result) in zip(
        placed, shared_map(_fitted, asked, process_count(job.kinematics.processes))
    ):
        if kept:
            out.append(station_plan(index, place.platform_mm, new, result))
            index += 1
    return out


#: A StationPlan's per-waypoint fields for no waypoints (q9, reachable, method, errors, branch changes).
_PATH_EMPTY = (np.zeros((0, 9)), np.zeros(0, bool), np.zeros(0, object), np.zeros(0), np.zeros(0), np.zeros(0, bool))


def _insert_in_tour(stations: list[StationPlan], station: StationPlan, home: np.ndarray) -> None:
    """Insert a station into the visiting order where it adds the least platform travel (Manhattan, from home
    back to home, as the platform tour)."""
    stops = [np.asarray(home), *[st.platform_mm for st in stations], np.asarray(home)]
    extra = [
        np.abs(a - station.platform_mm).sum() + np.abs(station.platform_mm - b).sum() - np.abs(a - b).sum()
        for a, b in itertools.pairwise(stops)
    ]
    stations.insert(int(np.argmin(extra)), station)


def _fitted(item):
    """:func:`_fit_to_station` of one ``(gantry, station, candidates, job)`` (for ``parallel.shared_map``)."""
    return _fit_to_station(*item)


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
    last = st.q9[-1, :6] if len(st.q9) else None
    result = solve_strokes(gantry, new, st.platform_mm, job.kinematics, start_q=last)
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
