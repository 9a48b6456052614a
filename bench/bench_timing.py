"""Timing within the joints' limits (issue 16, section 4): the timing stage's cost and the cycle time it finds.

    PYTHONPATH=src python bench/bench_timing.py [--runs 3] [--parts roof,reach,suv]
    PYTHONPATH=src python bench/bench_timing.py --parts roof --stations 1 --runs 1 --max-rounds 6,2,1

Each part is planned once to the kinematics stage with the default settings (``sprayplan plan``'s), then the
timing stage (``timing.stage.time_plan``) runs ``--runs`` times on that plan: the median wall time, the time
per 1000 waypoints, the cycle time by length over speed (the totals' ``cycle_time_length_over_speed_s``) and
the timed one (``cycle_time_s``) side by side with their ratio, the timed cycle's parts, and how many spray
waypoints the limits keep below their planned tip speed. Parts: the demo roof (``sprayplan demo``: the car
roof cut at z > 1000), the reach part (whole, in metres) and the SUV body (whole, in metres; a larger part).
"""

from __future__ import annotations

import argparse
import dataclasses
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
        "reach": (
            "reach part (whole)",
            meshes_dir() / "reach_curved_part.ply",
            JobConfig().replace(load={"units": "m"}),
        ),
        "suv": ("SUV body (whole)", meshes_dir() / "gazebo_suv_body_m.ply", JobConfig().replace(load={"units": "m"})),
    }


def _plan(key, stations):
    label, source, job = parts()[key]
    state = run_job(source, job, until="kinematics")
    plan = state.plan
    if stations is not None:
        plan = dataclasses.replace(plan, stations=plan.stations[:stations])
    return label, job, state, plan


def compare_rounds(args) -> int:
    """Wall time and timed cycle for each ``--max-rounds`` value on the same plan (median of ``--runs``)."""
    for key in args.parts.split(","):
        label, job, state, plan = _plan(key, args.stations)
        for rounds in (int(v) for v in args.max_rounds.split(",")):
            varied = job.replace(timing={"max_rounds": rounds})
            walls, timing = [], None
            for _ in range(args.runs):
                began = time.perf_counter()
                timing = time_plan(plan, varied, state.gantry())
                walls.append(time.perf_counter() - began)
            print(
                f"{label}, max_rounds {rounds}: {statistics.median(walls):.1f} s, timed cycle {timing.cycle_time_s:.2f} s"
            )
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--parts", default="roof,reach,suv")
    parser.add_argument("--stations", type=int, default=None, help="time only the plan's first N stations")
    parser.add_argument(
        "--max-rounds", default=None, help="compare [timing] max_rounds values (e.g. 6,2,1): wall and cycle of each"
    )
    args = parser.parse_args(argv)
    if args.max_rounds:
        return compare_rounds(args)
    rows = []
    for key in args.parts.split(","):
        began = time.perf_counter()
        label, job, state, plan = _plan(key, args.stations)
        planned_s = time.perf_counter() - began
        gantry = state.gantry()
        walls, timing = [], None
        for _ in range(args.runs):
            began = time.perf_counter()
            timing = time_plan(plan, job, gantry)
            walls.append(time.perf_counter() - began)
        before = plan_totals(plan, job)["cycle_time_s"]
        summary = timing.summary(plan, job)
        waypoints = sum(len(st) for st in plan.stations)
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
        print(
            f"{label}: planned in {planned_s:.1f} s; timing runs {', '.join(f'{w:.2f}' for w in walls)} s", flush=True
        )
    print()
    print(
        f"| part | waypoints | timing (median of {args.runs}) | per 1000 waypoints | cycle, length / speed |"
        " cycle, timed | timed / length-over-speed | spray / transfers / station moves (timed) |"
        " slowed spray waypoints (on the part) | strokes slowed | worst limit ratio (speed, acceleration, tip) |"
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
