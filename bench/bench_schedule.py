"""The cell's schedule alone (``cells.schedule``, issue 18), on a plan already made: samples too close, waits,
cycle time and the schedule's wall time, this checkout against another.

A cell plan folder written by ``sprayplan plan BODY --cell line3 --collisions`` holds every robot's work in
``cell_plan.json``. Each build reads it back, places the body in the cell again (the preset of the plan's cell,
for the skid), times every robot's work within its limits (``cells.timing``) and schedules the robots
(``cells.schedule.scheduled``). The builds run at once, one process each (a machine of two cores); each prints
one JSON line: the schedule's summary (samples too close per pair, least gaps, waits, each robot's time, the
cycle) and the seconds the timing and the schedule took; then each robot's RAPID program built from it, its
motions checked with the collision model (``programs.arms.motions_checked``: how many are in collision) and
how many nodes its way to the end park has (a build that routes parks, ``RobotWork.park_route_q``).

With ``--plan-times`` each robot keeps the waypoint times of the file, its waits taken off, in place of being
timed again: the plan's own inputs to its schedule (timing again from the file's joints, rounded to 1e-6 rad,
can differ: on the SUV's session 27 plan the right robot's retract at a wrist flip came out 0.39 s longer,
and its schedule had none of the plan's 6 samples too close).

Usage::

    python bench/bench_schedule.py OUT --part bmw --base ../wt-base [--plan-times]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PARTS = {"bmw": ("meshes/bmw_m6_body_m_yup.ply", "y"), "suv": ("meshes/gazebo_suv_body_m.ply", "z")}


def unwaited(work):
    """A robot's waypoint times as its plan's timing gave them, before the schedule: the file's arrival times
    (``t_s``) less the waits before every stroke up to its own (the arrival at a stroke's first waypoint is
    before that stroke's wait, unless the stroke starts with a run-up, where the wait is held:
    ``cells.schedule.with_leads``)."""
    import numpy as np

    t = np.asarray(work.t_s, float)
    if work.wait_s is None:
        return t
    sizes = [len(s) for s in work.strokes]
    waits = np.asarray(work.wait_s, float)
    through = np.repeat(np.cumsum(waits), sizes)  # the waits of the strokes up to each waypoint's own
    firsts = np.cumsum([0, *sizes[:-1]])
    up = np.zeros(len(firsts), bool)
    if work.lead_q is not None and work.lead_s is not None and len(t):
        lead = np.asarray(work.lead_q, float)[np.minimum(firsts, len(t) - 1), 0]
        up = np.isfinite(lead).all(axis=1) & (np.asarray(work.lead_s, float)[np.minimum(firsts, len(t) - 1), 0] > 0)
    through[firsts[~up]] -= waits[~up]
    return t - through


def child(folder: str, name: str, plan_times: bool = False) -> None:
    sys.path.insert(0, str(HERE))
    import inspect

    from _data import cell_plan_model

    from sprayplan.cells.schedule import scheduled
    from sprayplan.cells.timing import timed_cell

    plan, _, painted, _, arms = cell_plan_model(folder, name)
    unscheduled = {"t_s": None, "wait_s": None}
    if hasattr(plan.robots[0], "ends_q"):  # a build that keeps the schedule's ends
        unscheduled.update(ends_q=None, ends_track_mm=None)
    if hasattr(plan.robots[0], "park_route_q"):  # a build that routes parks
        unscheduled.update(park_route_q=None, park_route_track_mm=None)
    robots = tuple(dataclasses.replace(w, **unscheduled) for w in plan.robots)
    start = time.perf_counter()
    report = {"cycle_time_s": 0.0, "robots": {w.name: {"cycle_time_s": 0.0} for w in robots}}
    if plan_times:  # the plan's own timing, read back: the schedule's inputs as the plan had them
        robots = tuple(dataclasses.replace(r, t_s=unwaited(w)) for r, w in zip(robots, plan.robots))
    else:
        robots = timed_cell(plan.cell, robots, plan.job, report)
    timed = time.perf_counter() - start
    start = time.perf_counter()
    aids = ()
    if "routers" in inspect.signature(scheduled).parameters:  # a build that moves to the parks as the programs do
        from sprayplan.cells.plan import schedule_aids

        aids = schedule_aids(plan.cell, arms, painted, plan.job)
    robots, summary = scheduled(plan.cell, robots, arms, plan.job, *aids)
    took = time.perf_counter() - start
    keep = ("priority", "conflicts", "least_gap_mm", "waits", "robot_time_s", "cycle_time_s")
    kept = {k: summary[k] for k in keep if k in summary}  # an older build has no priority
    from sprayplan.programs.arms import build_cell_programs

    job = plan.job.replace(collision={"check": True})
    built = build_cell_programs(dataclasses.replace(plan, robots=robots, part=painted), job, ("rapid",))
    motions = {r.robot: r.builts[0].program.report["program_motions"]["motions_in_collision"] for r in built}
    nodes = {w.name: 0 if getattr(w, "park_route_q", None) is None else len(w.park_route_q) for w in robots}
    print(json.dumps({"timing_s": round(timed, 1), "schedule_s": round(took, 1), **kept,
                      "program_motions_in_collision": motions, "park_route_nodes": nodes}))  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="a cell plan folder written with --collisions")
    parser.add_argument("--part", default="bmw", choices=sorted(PARTS))
    parser.add_argument("--base", help="another checkout to compare with (its src/)")
    parser.add_argument(
        "--plan-times",
        action="store_true",
        help="the waypoint times of the plan's file, its waits taken off, in place of timing the work again",
    )
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.folder, args.part, args.plan_times)
        return
    sys.path.insert(0, str(HERE))
    from _data import builds_at_once

    extra = ["--plan-times"] if args.plan_times else []
    for build, result in builds_at_once([__file__, args.folder, "--part", args.part, "--child", *extra], args.base):
        print(json.dumps({"build": build, **result}), flush=True)
        print(
            f"{build}: {sum(result['conflicts'].values())} samples too close, cycle {result['cycle_time_s']} s, "
            f"schedule {result['schedule_s']} s, program motions in collision {result['program_motions_in_collision']}, "
            f"park route nodes {result['park_route_nodes']}",
            flush=True,
        )


if __name__ == "__main__":
    main()
