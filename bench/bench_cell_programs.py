"""Robot programs of a whole-body cell plan (issue 18, section 3: one program per robot): how large they are and
how long building, writing, reading back and checking them takes.

    python bench/bench_cell_programs.py [--body bmw] [--cell line3] [--thickness-um 50] [--repeat 3]

The body is planned once (``plan_cell``, as ``sprayplan plan BODY --cell CELL --thickness-um T`` does); then,
``--repeat`` times, every robot's RAPID programs (its maker's format) are built in memory
(``build_cell_programs``) and written, read back and checked in a temporary folder (``write_cell_programs``).
Printed per robot: files, moves, bytes, the waypoints left out and why, and the medians of the build and the
write-and-check seconds; one JSON line at the end.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir

BODIES = {"bmw": ("bmw_m6_body_m_yup.ply", {"units": "m", "up": "y"}), "suv": ("gazebo_suv_body_m.ply", {"units": "m"})}
FORMATS = ("rapid",)  # line3 and sides2 are ABB arms: RAPID (KRL is for KUKA arms)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--body", default="bmw", choices=list(BODIES))
    parser.add_argument("--cell", default="line3")
    parser.add_argument("--thickness-um", type=float, default=50.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    from sprayplan.cells import load_cell
    from sprayplan.cells.plan import plan_cell
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.programs.arms import build_cell_programs, write_cell_programs

    name, kw = BODIES[args.body]
    part = load_part(meshes_dir() / name, **kw)
    job = JobConfig().replace(coating={"thickness_um": args.thickness_um})
    start = time.perf_counter()
    plan = plan_cell(part, load_cell(args.cell), job)
    plan_s = time.perf_counter() - start
    build_s, write_s, summaries = [], [], []
    for _ in range(args.repeat):
        start = time.perf_counter()
        built = build_cell_programs(plan, plan.job, FORMATS)
        build_s.append(time.perf_counter() - start)
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            summaries = write_cell_programs(Path(tmp) / "programs", built, plan.job)
            write_s.append(time.perf_counter() - start)
    rows = []
    for data in summaries:
        left = {k: len(v) for k, v in data["left_out"].items()}
        rows.append(
            {
                "robot": data["robot"],
                "format": data["program_format"],
                "files": len(data["files"]),
                "moves": data["moves"],
                "bytes": data["bytes"],
                "left_out": left,
                "check": data.get("check", {}),
            }
        )
        print(
            f"{data['robot']:>6} {data['program_format']:<5} {len(data['files']):>3} files {data['moves']:>7} moves "
            f"{data['bytes'] / 1e6:7.2f} MB; left out {left}"
        )
    waypoints = {r.name: r.waypoints for r in plan.robots}
    reached = {r.name: int(r.reachable.sum()) for r in plan.robots}
    result = {
        "body": args.body,
        "cell": args.cell,
        "plan_s": round(plan_s, 1),
        "waypoints": waypoints,
        "reached": reached,
        "build_s_median": round(statistics.median(build_s), 2),
        "write_read_check_s_median": round(statistics.median(write_s), 2),
        "build_s": [round(v, 2) for v in build_s],
        "write_read_check_s": [round(v, 2) for v in write_s],
        "programs": rows,
    }
    print(
        f"plan {plan_s:.0f} s; programs of {len(plan.robots)} robots x {len(FORMATS)} formats: build "
        f"{result['build_s_median']} s, write + read back + check {result['write_read_check_s_median']} s (medians of "
        f"{args.repeat})"
    )
    print(json.dumps(result))


if __name__ == "__main__":
    main()
