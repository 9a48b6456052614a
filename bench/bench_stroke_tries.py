"""How each cell robot's strokes are first solved (``cells.plan.solve_strokes``, step 5), this checkout against
another at the same time (issue 18: the transfers no route frees).

Each car body is placed in ``line3`` and its areas found and given to the robots as ``cells.plan.plan_cell``
does without ``--collisions`` (``--thickness-um 50``); then every robot's strokes are planned and solved (``cells.plan._robot_work``: paths and kinematics),
``--repeats`` times (the median time kept). Reported per robot: the time, the spray waypoints reached, the
transfers between two spray strokes whose joint move turns a joint by more than 90 deg (the arm turned over
between two runs, mostly at the surface: ``turn_overs``), the spray strokes with such a step between two of
their own waypoints (``jumps``), and the transfers' largest joint turn (median, deg).

    python bench/bench_stroke_tries.py --body suv --base ../wt-base
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))

from _data import CAR_BODIES, builds_at_once, testdata_dir  # noqa: E402

TURN_DEG = 90.0


def child(body: str, repeats: int) -> dict:
    from sprayplan.cells import load_cell
    from sprayplan.cells import plan as cells_plan
    from sprayplan.cells.reach import reach_matrix
    from sprayplan.cells.seams import SEAM_STEP_MM, SeamGuard
    from sprayplan.cells.spec import place_part
    from sprayplan.coating.stage import meet_thickness
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.areas import assign_areas, segment_areas
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import painted_surface

    path, up = CAR_BODIES[body]
    job = JobConfig()
    job, _ = meet_thickness(dataclasses.replace(job, coating=dataclasses.replace(job.coating, thickness_um=50.0)))
    placed = place_part(load_part(testdata_dir() / path, units="m", up=up), load_cell("line3"))
    cell = placed.cell
    painted, _ = painted_surface(oriented_part(placed.part), job.collision)
    painted, _ = cells_plan.area_surface(painted)
    areas = segment_areas(painted)
    reach = reach_matrix(cell, painted, areas.face_normals, job.paths.standoff_mm)
    assignment = assign_areas(areas, painted.face_areas, reach)
    labels = len(cell.robots) + 1
    guard = SeamGuard(painted, areas.face_area * labels + assignment.face_robot + 1, areas.face_normals, SEAM_STEP_MM)
    out = {}
    for i, robot in enumerate(cell.robots):
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            work = cells_plan._robot_work(robot, i, painted, areas, assignment, job, guard)
            times.append(time.perf_counter() - t0)
        starts = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
        turns, jumps, reached = [], 0, 0
        for k, s in enumerate(work.strokes):
            rows = np.arange(starts[k], starts[k + 1])
            ok = work.reachable[rows]
            if s.spray_on:
                reached += int(ok.sum())
                q = work.q[rows][ok]
                if len(q) > 1 and np.degrees(np.abs(np.diff(q, axis=0))).max() > TURN_DEG:
                    jumps += 1
            elif 0 < k < len(work.strokes) - 1 and ok.all() and len(rows) == 2:
                turns.append(float(np.degrees(np.abs(work.q[rows[1]] - work.q[rows[0]])).max()))
        turns = np.array(turns)
        out[robot.name] = {
            "seconds": round(float(np.median(times)), 2),
            "spray_waypoints_reached": reached,
            "transfers": len(turns),
            "turn_overs": int((turns > TURN_DEG).sum()),
            "jumps": jumps,
            "transfer_turn_median_deg": round(float(np.median(turns)), 1) if len(turns) else 0.0,
        }
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--body", choices=sorted(CAR_BODIES), default="suv")
    ap.add_argument("--base", help="another checkout, run at the same time")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.body, args.repeats)))
        return 0
    argv_child = [__file__, "--child", "--body", args.body, "--repeats", str(args.repeats)]
    for build, result in builds_at_once(argv_child, args.base):
        for name, entry in result.items():
            print(build, name, json.dumps(entry))
    return 0


if __name__ == "__main__":
    sys.exit(main())
