"""The figures of a plan a person compares: lengths, counts, errors and the cycle time."""

from __future__ import annotations

import numpy as np

from sprayplan.config import JobConfig
from sprayplan.paths.speed import stroke_time
from sprayplan.types import Plan


def plan_totals(plan_: Plan, job: JobConfig) -> dict:
    """Lengths (mm), counts and the cycle time (s) of a plan."""
    settings = job.motion
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
