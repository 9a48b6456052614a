"""Benchmark of the robot programs (issue 15): export time, file sizes, moves written per second, and the
read-back check's time, for the demo roof, the reach part and the DTC hull, in every format.

Each part is planned once (``run_job(..., until="kinematics")``, default settings; not timed). Then, per format,
``--repeat`` times: the export (``programs.stage.export_plan``: build the moves, write the files into a staged
folder, read them back with the format's strict reader, check them against the plan, summary.json, move into
place), and on their own the read-back (``stage.read_programs``) and the check (``check.check_program``).
Medians are reported; the film comparison (``programs.film``) is timed once (RAPID) for the demo roof and the
reach part, with the occlusion model off and on.

Usage::

    python bench/bench_programs.py [--repeat 3] [--parts roof,reach,hull]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir  # bench/ is on sys.path when run as a script

FORMATS = ("urscript", "rapid", "krl")


def parts(names):
    from sprayplan.config import JobConfig
    from sprayplan.demo import DEMO_REGION, car_roof
    from sprayplan.io.load import load_part

    for name in names:
        if name == "roof":
            yield "demo roof (z > 1000)", car_roof(), JobConfig().replace(load={"region": DEMO_REGION})
        elif name == "reach":
            part = load_part(meshes_dir() / "reach_curved_part.ply", units="m")
            yield "reach part", part, JobConfig().replace(load={"units": "m"})
        elif name == "hull":
            part = load_part(meshes_dir() / "dtc_ship_hull_ascii.stl.gz", units="m")
            yield "DTC hull (116k faces, 6.3 m)", part, JobConfig().replace(load={"units": "m"})


def median(values) -> float:
    return statistics.median(values)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--parts", default="roof,reach,hull")
    args = parser.parse_args()
    from sprayplan.job import run_job
    from sprayplan.programs.check import check_program
    from sprayplan.programs.film import compare, program_paths, reference_paths, simulate_paths
    from sprayplan.programs.stage import export_plan, read_programs
    from sprayplan.surface.region import select_region

    print(f"`python bench/bench_programs.py --repeat {args.repeat}`: medians of {args.repeat} runs in one process.\n")
    print(
        "| part | waypoints | format | files | bytes | moves | export s (runs) | moves/s | read s | check s | check |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    films = []
    for label, part, job in parts(args.parts.split(",")):
        state = run_job(part, job, until="kinematics")
        plan, job = state.plan, state.job
        waypoints = sum(len(st) for st in plan.stations)
        for fmt in FORMATS:
            runs, reads, checks = [], [], []
            with tempfile.TemporaryDirectory() as tmp:
                for k in range(args.repeat):
                    folder = Path(tmp) / f"run{k}"
                    start = time.perf_counter()
                    (_built,), (summary,) = export_plan(plan, job, [fmt], folder)
                    runs.append(time.perf_counter() - start)
                    start = time.perf_counter()
                    read = read_programs(folder / fmt, job, fmt)
                    reads.append(time.perf_counter() - start)
                    start = time.perf_counter()
                    result = check_program(read, plan, job)
                    checks.append(time.perf_counter() - start)
                if fmt == "rapid" and not label.startswith("DTC"):
                    cut = select_region(part, job.load.region)
                    for occlusion in ("none", job.coating.occlusion):
                        filmed = job.replace(coating={"occlusion": occlusion})
                        start = time.perf_counter()
                        found = compare(
                            simulate_paths(cut, *program_paths(read, job, vias=result.via_moves), filmed),
                            simulate_paths(cut, *reference_paths(plan, job, fmt, result.left_out), filmed),
                        )
                        films.append((label, fmt, occlusion, time.perf_counter() - start, found))
            moves = summary["moves"]
            state_text = "ok" if result.ok else f"{len(result.failures)} failures"
            left = sum(len(v) for v in summary["left_out"].values())
            print(
                f"| {label} | {waypoints} | {fmt} | {len(summary['files'])} | {summary['bytes']} | {moves} | "
                f"{median(runs):.2f} ({', '.join(f'{t:.2f}' for t in runs)}) | {moves / median(runs):.0f} | "
                f"{median(reads):.2f} | {median(checks):.2f} | {state_text}, {left} spray waypoints left out |"
            )
    if films:
        print("\nFilm of the program read back against the plan's (as its joints run it), one run each:\n")
        print(
            "| part | format | occlusion | seconds (both films) | largest difference / thickest film | deposit difference |"
        )
        print("|---|---|---|---|---|---|")
        for label, fmt, occlusion, seconds, found in films:
            print(
                f"| {label} | {fmt} | {occlusion} | {seconds:.1f} | {found['max_difference']:.2e} | "
                f"{found['volume_difference']:.2e} |"
            )


if __name__ == "__main__":
    main()
