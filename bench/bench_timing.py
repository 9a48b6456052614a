"""Timing within the joints' limits (issue 16, section 4): the timing stage's cost and the cycle time it finds.

    PYTHONPATH=src python bench/bench_timing.py [--runs 3] [--parts roof,reach,suv]

Each part is planned once to the kinematics stage with the default settings (``sprayplan plan``'s), then the
timing stage (``timing.stage.time_plan``) runs ``--runs`` times on that plan: the median wall time, the time
per 1000 waypoints, the cycle time by length over speed (the totals' ``cycle_time_length_over_speed_s``) and
the timed one (``cycle_time_s``) side by side with their ratio, the timed cycle's parts, and how many spray
waypoints the limits keep below their planned tip speed. Parts: the demo roof (``sprayplan demo``: the car
roof cut at z > 1000), the reach part (whole, in metres) and the SUV body (whole, in metres; a larger part).
"""

from __future__ import annotations

import argparse
import statistics
import time

from _data import meshes_dir

from sprayplan.config import JobConfig
from sprayplan.demo import DEMO_REGION, car_roof
from sprayplan.export.summary import plan_totals
from sprayplan.job import run_job
from sprayplan.timing.stage import time_plan


def parts():
    return {
        "roof": ("demo roof (z > 1000)", car_roof(), JobConfig().replace(load={"region": DEMO_REGION})),
        "reach": ("reach part (whole)", meshes_dir() / "reach_curved_part.ply", JobConfig().replace(load={"units": "m"})),
        "suv": ("SUV body (whole)", meshes_dir() / "gazebo_suv_body_m.ply", JobConfig().replace(load={"units": "m"})),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--parts", default="roof,reach,suv")
    args = parser.parse_args(argv)
    rows = []
    for key in args.parts.split(","):
        label, source, job = parts()[key]
        began = time.perf_counter()
        state = run_job(source, job, until="kinematics")
        planned_s = time.perf_counter() - began
        gantry = state.gantry()
        walls, timing = [], None
        for _ in range(args.runs):
            began = time.perf_counter()
            timing = time_plan(state.plan, job, gantry)
            walls.append(time.perf_counter() - began)
        before = plan_totals(state.plan, job)["cycle_time_s"]
        summary = timing.summary(state.plan, job)
        waypoints = sum(len(st) for st in state.plan.stations)
        wall = statistics.median(walls)
        rows.append(
            (
                label,
                waypoints,
                wall,
                1000.0 * wall / waypoints,
                before,
                timing.cycle_time_s,
                timing.spray_time_s,
                timing.transfer_time_s,
                timing.station_move_time_s,
                summary,
                planned_s,
            )
        )
        print(f"{label}: planned in {planned_s:.1f} s; timing runs {', '.join(f'{w:.2f}' for w in walls)} s", flush=True)
    print()
    print(
        "| part | waypoints | timing (median of %d) | per 1000 waypoints | cycle, length / speed | cycle, timed |"
        " timed / length-over-speed | spray / transfers / station moves (timed) | slowed spray waypoints (on the part) |"
        " strokes slowed | worst limit ratio (speed, acceleration, tip) |" % args.runs
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for label, n, wall, per, before, after, spray, transfer, station, summary, _ in rows:
        worst = summary["worst_limit_ratio"]
        print(
            f"| {label} | {n:,} | {wall:.1f} s | {per:.2f} s | {before:,.0f} s | {after:,.0f} s | {after / before:.2f} |"
            f" {spray:,.0f} / {transfer:,.0f} / {station:,.0f} s |"
            f" {summary['slowed_waypoints']:,} of {summary['spray_waypoints']:,} ({summary['slowed_on_part_waypoints']:,}) |"
            f" {summary['strokes_slowed']} | {worst['velocity']:.3f}, {worst['acceleration']:.3f}, {worst['tip_speed']:.3f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
