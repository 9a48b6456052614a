"""The ``kinematics`` stage of the main job: the nine axes at every waypoint of every station.

Seed 000 sections 3-4: the closed-form UR inverse kinematics where the flange is inside the working
cylinder, the SQP fallback of eqs. 20-22 elsewhere (``gantry.solve_gantry_path``); the arm starts each
station from home, its "collision avoidance" of section 5.2. Unreachable waypoints are data in the plan.
"""

from __future__ import annotations

import math

import numpy as np

from sprayplan.config import JobConfig, KinematicsConfig
from sprayplan.ordering.stage import OrderedStations
from sprayplan.parallel import process_count, shared_map
from sprayplan.progress import Progress
from sprayplan.robots.gantry import Gantry, GantryPath, build_gantry, load_gun, solve_gantry_path
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Plan, StationPlan

#: The UR arm's "home" joints (rad), where each station starts.
HOME_JOINTS = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0])


def gantry_for(config: KinematicsConfig) -> Gantry:
    """The job's robot: the gantry carrying the configured arm (``robot_file``'s, else the preset), with the
    configured gun."""
    if config.robot_file is None:
        return build_gantry(config.arm, config.tool)
    return Gantry(robot=config.arm_model(), gun=load_gun(config.tool))


def solve_strokes(gantry: Gantry, strokes, platform_mm, config: KinematicsConfig, start_q=None) -> GantryPath:
    """The nine axes along strokes run in order from one gantry station, the arm starting at ``start_q``
    (home when None or not finite)."""
    start = HOME_JOINTS if start_q is None or not np.isfinite(start_q).all() else np.asarray(start_q, float)
    return solve_gantry_path(
        gantry,
        np.concatenate([stroke_poses(s) for s in strokes]),
        platform_mm,
        seed_q=start,
        k_d=config.k_d,
        position_tol_mm=config.position_tol_mm,
        axis_tol_rad=math.radians(config.axis_tol_deg),
    )


def station_plan(index: int, platform, strokes, path: GantryPath, after: StationPlan | None = None) -> StationPlan:
    """A station's plan from strokes and their joints (a ``GantryPath``), run after ``after``'s when given."""
    fields = (path.q9, path.reachable, path.method, path.position_error_mm, path.axis_error_deg, path.branch_change)
    if after is not None:
        before = (after.q9, after.reachable, after.method, after.position_error_mm, after.axis_error_deg)
        fields = tuple(np.concatenate([a, b]) for a, b in zip((*before, after.branch_change), fields))
        strokes = after.strokes + tuple(strokes)
    return StationPlan(index, platform, tuple(strokes), *fields)


def kinematics_stage(
    ordered: OrderedStations, job: JobConfig, gantry: Gantry, name: str = "", progress: Progress | None = None
) -> Plan:
    """The plan: every station of ``ordered`` with the nine axes at each of its waypoints, solved from home."""
    layout = ordered.layout
    report = progress or (lambda *_: None)
    items = [
        (gantry, strokes, platform, job.kinematics) for platform, strokes in zip(layout.platform_mm, ordered.strokes)
    ]
    processes = process_count(job.kinematics.processes)
    paths = shared_map(_solved_station, items, processes, done=lambda count: report("kinematics", count, len(items)))
    stations = [
        station_plan(k, platform, strokes, path)
        for k, platform, strokes, path in zip(layout.index, layout.platform_mm, ordered.strokes, paths)
    ]
    return Plan(tuple(stations), layout.home_mm, layout.unassigned, name)


def _solved_station(item) -> GantryPath:
    """``solve_strokes`` of one station's ``(gantry, strokes, platform_mm, config)``, from home (for
    ``parallel.shared_map``)."""
    gantry, strokes, platform, config = item
    return solve_strokes(gantry, strokes, platform, config)
