"""Cell layouts compared on a car body (issue 18: no collisions): the body planned in ``line3`` with the part's
skid height and the robots' base heights and distance changed, no film target, then every reached waypoint
checked against the part and the floor (no repairs, no motions): per robot the waypoints in collision by body
and what it meets, and the unreached surface, with and without the collision model in the areas' reach
(docs/benchmarks.md, "Cell layouts").

    PYTHONPATH=src python bench/bench_cell_layouts.py [--body bmw] [--layouts 0:500:2900:2000,500:0:3400:2000]

A layout is ``lift:side_z:roof_z:side_y`` in mm: the part's lift above the floor (its skid), the side robots'
base height, the roof robot's base height and the side robots' distance from the line's axis.
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
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import meshes_dir  # noqa: E402
from bench_cell_collisions import BODIES  # noqa: E402


def layout(base, lift: float, side_z: float, roof_z: float, side_y: float):
    """``base`` (line3) with the part lifted and the robots moved (the roof robot first, then left, right)."""
    robots = []
    for r in base.robots:
        m = r.base2cell.copy()
        if r.name == "roof":
            m[2, 3] = roof_z
        else:
            m[1, 3] = np.sign(m[1, 3]) * side_y
            m[2, 3] = side_z
        robots.append(dataclasses.replace(r, base2cell=m))
    return dataclasses.replace(base, robots=tuple(robots), lift_mm=lift)


def main() -> None:
    from sprayplan.cells import load_cell
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.plan import plan_cell
    from sprayplan.cells.reach import reach_matrix
    from sprayplan.cells.spec import place_part
    from sprayplan.collision.arms import ARM_BODIES
    from sprayplan.config import CollisionConfig, JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.areas import assign_areas, segment_areas
    from sprayplan.surface.region import drop_floor_facing

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--body", default="bmw", choices=sorted(BODIES))
    parser.add_argument("--layouts", default="0:500:2900:2000,500:500:3400:2000,500:0:3400:2000,500:600:3400:2700")
    args = parser.parse_args()
    name, load = BODIES[args.body]
    part = load_part(str(meshes_dir() / name), **load)
    job = JobConfig()
    for text in args.layouts.split(","):
        lift, side_z, roof_z, side_y = (float(v) for v in text.split(":"))
        cell = layout(load_cell("line3"), lift, side_z, roof_z, side_y)
        start = time.perf_counter()
        plan = plan_cell(part, cell, job)
        arms = cell_arms(cell, plan.part, CollisionConfig(check=True))
        out = {"layout": text, "unreached_mm2": plan.report["unreached_surface_mm2"]}
        for arm, work in zip(arms, plan.robots):
            idx = np.flatnonzero(work.reachable)
            found = arm.check(work.q[idx], work.track_mm[idx])
            pairs: dict = {}
            for b, o in zip(found.body[found.collides], found.other[found.collides]):
                key = f"{ARM_BODIES[b]}-{o}"
                pairs[key] = pairs.get(key, 0) + 1
            out[work.name] = {"waypoints": work.waypoints, "unreached": int((~work.reachable).sum()),
                              "in_collision": int(found.collides.sum()),
                              "by_pair": dict(sorted(pairs.items(), key=lambda kv: -kv[1]))}  # fmt: skip
        painted, _ = drop_floor_facing(place_part(part, cell).part, job.collision.floor_facing_deg)
        areas = segment_areas(painted)
        reach = reach_matrix(cell, painted, areas.face_normals, job.paths.standoff_mm, arms=arms)
        out["unreached_with_collision_model_mm2"] = round(
            assign_areas(areas, painted.face_areas, reach).unreached_mm2, 1
        )
        out["wall_s"] = round(time.perf_counter() - start, 1)
        print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
