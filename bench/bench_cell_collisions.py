"""Collision checks of whole-body cell plans (issue 18: no collisions; the robots kept apart): each car body
planned in ``line3`` (default settings, no film target, so no touch-ups), then ``cells.collide.check_cell``
run on the plan without and with the stroke repairs (``cells.plan.repaired_work``): per robot the waypoints
checked, in collision (by body and what it meets), motions in collision, strokes repaired, the least gap
between every two robots' swept spaces, and the wall and CPU seconds of the check (docs/benchmarks.md,
"Collisions of the cell arms").

    PYTHONPATH=src python bench/bench_cell_collisions.py [--bodies bmw,suv] [--cell line3]

With ``--as-cli`` each body is planned instead as ``sprayplan plan --cell CELL --collisions`` plans it
(``plan_cell`` with ``[collision] check``: the areas' reach with the collision model, the check and repairs,
then the schedule, ``cells.schedule``), and the report's collisions, schedule, unreached surface and step
times are printed, with the CPU seconds of the whole plan.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import meshes_dir  # noqa: E402

BODIES = {
    "bmw": ("bmw_m6_body_m_yup.ply", {"units": "m", "up": "y"}),
    "suv": ("gazebo_suv_body_m.ply", {"units": "m"}),
}


def main() -> None:
    from sprayplan.cells import load_cell
    from sprayplan.cells.collide import check_cell
    from sprayplan.cells.plan import plan_cell, repaired_work
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", default="bmw,suv")
    parser.add_argument("--cell", default="line3")
    parser.add_argument("--as-cli", action="store_true", help="plan_cell with the check on, as --collisions")
    args = parser.parse_args()
    cell = load_cell(args.cell)
    for body in args.bodies.split(","):
        name, load = BODIES[body]
        part = load_part(str(meshes_dir() / name), **load)
        job = JobConfig()
        if args.as_cli:
            wall, cpu = time.perf_counter(), time.process_time()
            plan = plan_cell(part, cell, job.replace(collision={"check": True}))
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            r = plan.report
            print(json.dumps({"body": body, "cell": cell.name, "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
                              "timings_s": plan.timings_s, "unreached_surface_mm2": r["unreached_surface_mm2"],
                              "robots": r["robots"], "collisions": r["collisions"], "schedule": r["schedule"],
                              "cycle_time_s": r["cycle_time_s"]}), flush=True)  # fmt: skip
            continue
        start = time.perf_counter()
        plan = plan_cell(part, cell, job)
        print(f"## {body} in {cell.name}: planned in {time.perf_counter() - start:.1f} s", flush=True)
        for repair in (False, True):
            config = dataclasses.replace(job.collision, repair=repair)
            wall, cpu = time.perf_counter(), time.process_time()
            _, report = check_cell(plan, config, repaired_work if repair else None)
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            print(json.dumps({"body": body, "repair": repair, "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
                              **report}), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
