"""The collision step of a cell plan alone (``sprayplan plan --cell ... --collisions``, issue 18): what is left in
collision, and its time, this checkout against another.

Each body (``bmw``, ``suv``) is planned in the cell (``--cell``, default ``line3``) up to the kinematics, with the
spacing and gun speed for 50 um but no film (so that the run is the plan and the collision step alone), then
the collision step runs on it: in this checkout the repairs, the cut to the free runs and the transfers' routes
(``cells.collide.freed_cell``), then the check (``cells.collide.check_cell``); in a checkout that has no
``freed_cell`` (``--base DIR``, before the cut), the check with the repairs. The two builds run at once, one
process each (a machine of two cores); each prints one JSON line with the step's wall seconds and per robot
the waypoints and motions in collision, the strokes repaired, the waypoints left out and the transfers routed.

Usage::

    python bench/bench_collision_step.py --parts bmw --base ../wt-base
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
KEYS = (
    "waypoints_in_collision", "motions_in_collision", "strokes_in_collision", "strokes_repaired",
    "left_out_in_collision", "left_out_unreached", "left_out_alone", "transfers_routed", "routed_retract",
    "routed_via", "routed_detour",
)  # fmt: skip


def child(name: str, cell_name: str) -> None:
    sys.path.insert(0, str(HERE))
    from _data import testdata_dir

    import sprayplan.cells.collide as collide
    from sprayplan.cells.plan import plan_cell, repaired_work
    from sprayplan.cells.spec import load_cell
    from sprayplan.coating.stage import meet_thickness
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part

    path, up = PARTS[name]
    job = JobConfig()
    job = dataclasses.replace(job, coating=dataclasses.replace(job.coating, thickness_um=50.0))
    job, _ = meet_thickness(job)
    job = dataclasses.replace(
        job,
        coating=dataclasses.replace(job.coating, thickness_um=None),
        timing=dataclasses.replace(job.timing, enabled=False),
    )
    start = time.perf_counter()
    plan = plan_cell(load_part(testdata_dir() / path, units="m", up=up), load_cell(cell_name), job)
    planned = time.perf_counter() - start
    config = dataclasses.replace(job.collision, check=True)
    start = time.perf_counter()
    arms = collide.cell_arms(plan.cell, plan.part, config)
    extra = {}
    if hasattr(collide, "freed_cell"):
        robots, extra = collide.freed_cell(
            plan.cell, plan.robots, arms, config, repaired_work, plan.part, job.paths.standoff_mm
        )
        _, report = collide.check_cell(dataclasses.replace(plan, robots=robots), config, arms=arms)
    else:
        _, report = collide.check_cell(plan, config, repaired_work, arms=arms)
    wall = time.perf_counter() - start
    robots = {}
    for robot, entry in report["robots"].items():
        entry = {**entry, **extra.get(robot, {})}
        robots[robot] = {k: entry[k] for k in KEYS if k in entry}
    print(
        json.dumps(
            {"part": name, "cell": cell_name, "plan_s": round(planned, 1), "collision_step_s": round(wall, 1),
             "robots": robots, "robot_gap_mm": report["robot_gap_mm"]}
        )
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="bmw")
    parser.add_argument("--cell", default="line3")
    parser.add_argument("--base", help="another checkout to compare with (its src/)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.cell)
        return
    sys.path.insert(0, str(HERE))
    from _data import builds_at_once

    for name in args.parts.split(","):
        for build, result in builds_at_once([__file__, "--child", name, "--cell", args.cell], args.base):
            print(json.dumps({"build": build, **result}), flush=True)
            total = {k: sum(r.get(k, 0) for r in result["robots"].values()) for k in KEYS[:2]}
            print(f"{name} {build}: {result['collision_step_s']} s; in collision after it: {total}", flush=True)


if __name__ == "__main__":
    main()
