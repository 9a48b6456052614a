"""Benchmark of the main job and of the station tours.

1. ``sprayplan plan`` end to end (load, region, paths, stations, ordering, kinematics, writing plan.json and
   waypoints.csv) on the demo roof and on the DTC hull (a large object), 3 runs each in fresh processes.
2. For each station of the demo roof in points mode (the seed's target points, 49.19 mm apart): the station's
   tour by the seed's GA (reduced: population 200, 2000 generations, the seed's rates; the seed's 5000 x 25,000
   would take hours) against the default solver, in the same run: tour lengths and times as ratios.

Usage::

    python bench/bench_plan.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir  # bench/ is on sys.path when run as a script


def end_to_end(repeat: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "sprayplan", "demo", "-o", tmp], check=True, capture_output=True)
        cases = {
            "demo roof (z > 1000)": [f"{tmp}/roof.stl", "--region", "z > 1000"],
            "DTC hull (116k faces, 6.3 m)": [str(meshes_dir() / "dtc_ship_hull_ascii.stl.gz"), "--units", "m"],
        }
        print("| part | runs (s) | median s | result |")
        print("|---|---|---|---|")
        for name, args in cases.items():
            times, summary = [], ""
            for _ in range(repeat):
                start = time.perf_counter()
                out = subprocess.run(
                    [sys.executable, "-m", "sprayplan", "plan", *args, "-o", f"{tmp}/out"],
                    check=True,
                    capture_output=True,
                    text=True,
                )
                times.append(time.perf_counter() - start)
                # the last line is the summary; the lines before it are the progress display's (stdout, not a tty)
                summary = out.stdout.strip().splitlines()[-1].split(" -> ")[0]
            runs = ", ".join(f"{t:.1f}" for t in times)
            print(f"| {name} | {runs} | {statistics.median(times):.1f} | {summary} |")


def station_tours() -> None:
    from sprayplan.config import JobConfig, LoadConfig, OrderingConfig
    from sprayplan.demo import DEMO_REGION, car_roof
    from sprayplan.job import run_job
    from sprayplan.ordering import solve_tour
    from sprayplan.ordering.genetic import GAParams, ga_tour

    def plan(part, job):
        return run_job(part, job, until="kinematics").plan

    from sprayplan.surface.region import select_region

    roof = select_region(car_roof(), DEMO_REGION)
    job = JobConfig(mode="points", load=LoadConfig(region=DEMO_REGION), ordering=OrderingConfig(tour="keep"))
    result = plan(roof, job)
    params = GAParams(population=200, generations=2000)
    print(
        "| station | targets | GA length mm | default length mm | GA / default length | GA s | default s | GA / default time |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for st in result.stations:
        tcp = np.vstack([s.tcp for s in st.strokes if s.spray_on])
        start = time.perf_counter()
        ga = ga_tour(tcp, params=params, closed=False, seed=0)
        ga_s = time.perf_counter() - start
        start = time.perf_counter()
        default = solve_tour(tcp, method="auto", closed=False, seed=0)
        auto_s = time.perf_counter() - start
        print(
            f"| {st.index} | {len(tcp)} | {ga.length:.0f} | {default.length:.0f} | {ga.length / default.length:.3f} | "
            f"{ga_s:.2f} | {auto_s:.2f} | {ga_s / auto_s:.1f} |"
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    print(f"Reproduce: `python bench/bench_plan.py --repeat {args.repeat}`\n")
    end_to_end(args.repeat)
    print()
    station_tours()
    return 0


if __name__ == "__main__":
    sys.exit(main())
