"""Whole bodies in a cell (issue 18, section 4; seed 003, section 5): both car bodies planned with ``line3``
for a 50 um film, in a fresh process each, and (``--gantry``) the same body as one job with the gantry cell.

    python bench/bench_cells.py [--bodies bmw,suv] [--cell line3] [--gantry]

For each body: wall seconds of each step (``CellPlan.timings_s``), peak memory of the process, the film over
the whole body, per robot, per seam, at the 420 measuring points; waypoints and cycle time per robot. With
``--gantry``: ``run_job`` on the same body (whole, no region) with the same target, its film and time.
Each run is its own process (``python bench/bench_cells.py --one BODY CELL`` or ``--one-gantry BODY``), so
the peak memory is that run's.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir

BODIES = {"bmw": ("bmw_m6_body_m_yup.ply", {"units": "m", "up": "y"}), "suv": ("gazebo_suv_body_m.ply", {"units": "m"})}


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2


def one(body: str, cell_name: str) -> dict:
    from sprayplan.cells import load_cell
    from sprayplan.cells.plan import plan_cell
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part

    name, kw = BODIES[body]
    start = time.perf_counter()
    part = load_part(meshes_dir() / name, **kw)
    job = JobConfig().replace(coating={"thickness_um": 50.0}, output={"samples": 420})
    plan = plan_cell(part, load_cell(cell_name), job)
    wall = time.perf_counter() - start
    film = plan.report["film"]
    keep = ("count", "area_mm2", "mean_um", "std_um", "share_in_spec", "min_um", "max_um")
    short = lambda d: {k: d[k] for k in keep if k in d}
    return {
        "body": body,
        "cell": cell_name,
        "wall_s": round(wall, 1),
        "steps_s": plan.timings_s,
        "peak_gb": round(_peak_gb(), 2),
        "whole": short(film["whole"]),
        "measuring_points": short(film["report"]["measuring_points"]),
        "per_robot": {k: short(v) for k, v in film["per_robot"].items()},
        "per_seam": {k: short(v) for k, v in film["per_seam"].items()},
        "per_area": {k: {**short(v), "robot": v["robot"]} for k, v in film["per_area"].items()},
        "unreached": short(film["unreached"]),
        "robots": plan.report["robots"],
        "cycle_time_s": plan.report["cycle_time_s"],
    }


def one_gantry(body: str) -> dict:
    from sprayplan.config import JobConfig
    from sprayplan.job import run_job

    name, kw = BODIES[body]
    start = time.perf_counter()
    job = JobConfig().replace(load=kw, coating={"thickness_um": 50.0}, output={"samples": 420})
    result = run_job(meshes_dir() / name, job)
    wall = time.perf_counter() - start
    from sprayplan.export.film import film_report

    full = film_report(result.film, job, samples=420) if result.film is not None else {}
    keep = ("count", "area_mm2", "mean_um", "std_um", "share_in_spec")
    report = {
        k: {x: v[x] for x in keep if x in v} for k, v in full.items() if k in ("painted", "all", "measuring_points")
    }
    return {
        "body": body,
        "cell": "gantry-ur5 (one job)",
        "wall_s": round(wall, 1),
        "steps_s": result.timings_s,
        "peak_gb": round(_peak_gb(), 2),
        "totals": {k: result.totals.get(k) for k in ("stations", "strokes", "waypoints", "unreachable_waypoints")},
        "film": report,
        "cycle_time_s": result.totals.get("cycle_time_s"),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bodies", default="bmw,suv")
    ap.add_argument("--cell", default="line3")
    ap.add_argument("--gantry", action="store_true")
    ap.add_argument("--one", nargs=2, metavar=("BODY", "CELL"))
    ap.add_argument("--one-gantry", metavar="BODY")
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(*args.one)))
        return
    if args.one_gantry:
        print(json.dumps(one_gantry(args.one_gantry), default=str))
        return
    for body in args.bodies.split(","):
        runs = [["--one", body, args.cell]] + ([["--one-gantry", body]] if args.gantry else [])
        for extra in runs:
            out = subprocess.run([sys.executable, __file__, *extra], capture_output=True, text=True, check=True)
            print(json.dumps(json.loads(out.stdout.strip().splitlines()[-1]), indent=1), flush=True)


if __name__ == "__main__":
    main()
