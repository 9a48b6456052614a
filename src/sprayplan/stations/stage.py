"""The ``stations`` stage of the main job: where the gantry stops, in what order, and what each stop paints.

Seed 000 section 5.1: the flange positions of every spray waypoint projected on xy are covered by the fewest
working circles (``partition.circle_cover``); the platform tour runs from home over the stations back home,
exact for up to 11 stations, in the Manhattan metric (the gantry's axes move one at a time, section 5.1.3);
each waypoint goes greedily to the first station in visiting order that reaches it (``assign_greedy``), and a
stroke is cut into the runs that belong to one station.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from sprayplan.config import JobConfig, StationsConfig
from sprayplan.errors import InputError
from sprayplan.stations.partition import assign_greedy, circle_cover
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Stroke

log = logging.getLogger(__name__)

#: Most stations (home included) whose platform tour is solved exactly; more take the 2-opt descent.
EXACT_TOUR_NODES = 12


@dataclass(frozen=True)
class SprayWork:
    """What the stations share out: the spray strokes and each waypoint's flange position.

    Attributes
    ----------
    strokes : tuple of Stroke
        Spray strokes (from the paths stage) or one-waypoint strokes at the target points (points mode).
    flange_mm : (n, 3) float
        The flange position of every waypoint of all strokes in order, mm.
    """

    strokes: tuple
    flange_mm: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "strokes", tuple(self.strokes))
        flange = np.array(self.flange_mm, dtype=float).reshape(-1, 3)
        if len(flange) != sum(len(s) for s in self.strokes):
            raise ValueError("flange_mm must have one row per waypoint of the strokes")
        flange.flags.writeable = False
        object.__setattr__(self, "flange_mm", flange)


@dataclass(frozen=True)
class StationLayout:
    """The stations' result: gantry stops in visiting order and the pieces of stroke each one paints.

    Attributes
    ----------
    index : tuple of int
        Each station's number in the circle cover, in visiting order.
    platform_mm : (k, 3) float
        Gantry positions in visiting order, mm.
    pieces : tuple of tuple of Stroke
        For each station (visiting order), the runs of spray strokes it paints, in the order of the paths.
    home_mm : (3,) float
        Where the gantry starts and ends.
    unassigned : (m, 3) float
        Contact points no station reaches (reported, not painted).
    """

    index: tuple
    platform_mm: np.ndarray
    pieces: tuple
    home_mm: np.ndarray
    unassigned: np.ndarray

    def __post_init__(self):
        platform = np.array(self.platform_mm, dtype=float).reshape(-1, 3)
        if not (len(self.index) == len(platform) == len(self.pieces)):
            raise ValueError("index, platform_mm and pieces must have one entry per station")
        for name, value in (
            ("platform_mm", platform),
            ("home_mm", np.array(self.home_mm, dtype=float).reshape(3)),
            ("unassigned", np.array(self.unassigned, dtype=float).reshape(-1, 3)),
        ):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "index", tuple(int(i) for i in self.index))
        object.__setattr__(self, "pieces", tuple(tuple(p) for p in self.pieces))


def spray_work(strokes, gantry, name: str = "") -> SprayWork:
    """The strokes to share out and their flange positions (``gun2flange`` of the gantry's gun).

    Raises
    ------
    InputError
        No strokes: nothing to paint.
    """
    strokes = tuple(strokes)
    if not strokes:
        raise InputError(f"{name or 'part'}: nothing to paint")
    poses = np.concatenate([stroke_poses(s) for s in strokes])
    flange = poses @ np.linalg.inv(gantry.gun.gun2flange)
    return SprayWork(strokes, flange[:, :3, 3])


def target_strokes(targets, standoff_mm: float) -> tuple:
    """Target points (points mode) as one-waypoint spray strokes at the standoff."""
    return tuple(
        Stroke(p[None], n[None], (p + standoff_mm * n)[None], True, None, -1)
        for p, n in zip(targets.points, targets.normals)
    )


def place_stations(work: SprayWork, config: StationsConfig, gantry, name: str = "") -> StationLayout:
    """Gantry stations for the work: circle cover, platform tour from home, greedy assignment (seed 000 5.1).

    Parameters
    ----------
    work : SprayWork
    config : StationsConfig
        Home position, gantry height (None: the flange positions' mean height at the middle of the working
        cylinder) and the cover's seed.
    gantry : robots.gantry.Gantry
        Its working cylinder sizes the circles.
    """
    from sprayplan.ordering import solve_tour

    space = gantry.workspace
    flange_xy = work.flange_mm[:, :2]
    cover = circle_cover(flange_xy, space.radius_mm, space.core_diameter_mm / 2, seed=config.seed)
    centres = cover.centres
    home = np.array(config.home_mm)
    if config.platform_z_mm is not None:
        platform_z = float(config.platform_z_mm)
    else:
        platform_z = gantry.platform_z_for(float(work.flange_mm[:, 2].mean()))
    platforms = np.column_stack([centres, np.full(len(centres), platform_z)])
    nodes = np.vstack([home, platforms])
    method = "exact" if len(nodes) <= EXACT_TOUR_NODES else "2opt"
    tour = solve_tour(nodes, method=method, closed=True, start=0, metric="manhattan", seed=config.seed)
    visit = [int(i) - 1 for i in tour.order if i != 0]
    assignment = assign_greedy(flange_xy, centres, np.array(visit), space.radius_mm, space.core_diameter_mm / 2)
    per_station: dict[int, list[Stroke]] = {k: [] for k in visit}
    offsets = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
    for i, stroke in enumerate(work.strokes):
        for k, piece in split_by_station(stroke, assignment.station[offsets[i] : offsets[i + 1]]):
            per_station[k].append(piece)
    kept = [k for k in visit if per_station[k]]
    all_points = np.concatenate([s.points for s in work.strokes])
    unassigned = all_points[assignment.station < 0]
    log.info("%s: %d stations, %d waypoints unassigned", name, len(kept), len(unassigned))
    return StationLayout(
        tuple(kept),
        platforms[kept].reshape(-1, 3),
        tuple(tuple(per_station[k]) for k in kept),
        home,
        unassigned,
    )


def split_by_station(stroke: Stroke, station: np.ndarray) -> list[tuple[int, Stroke]]:
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


def stations_stage(strokes, job: JobConfig, gantry, name: str = "") -> StationLayout:
    """The stage as the main job runs it: the strokes' flange positions, then :func:`place_stations`."""
    return place_stations(spray_work(strokes, gantry, name), job.stations, gantry, name)
