"""Benchmark of the tour solvers on the TSPLIB instances of shared/testdata: quality (length / optimum) and time.

Every length is measured with float Euclidean distances, the optimum too: the length of TSPLIB's optimal tour
(``NAME.opt.tour``, optimal on TSPLIB's rounded distances) measured with float distances, so a ratio below 1 is
possible by a hair.

Table 1 sets the default solver (``solve_tour()``: fast-tsp with its default budget) beside the seed's genetic
algorithm (seed 000 s5.2) run at reduced parameters: the paper's population of 5000 for 25,000 generations takes
minutes to hours per instance here, so the GA runs with population ``--ga-population`` (500) for up to the
paper's 25,000 generations, stopped by a wall-clock cap of ``--ga-seconds`` (60 s) per instance; the table
says how many generations ran. Table 2 compares the solvers behind ``solve_tour``: fast-tsp (MIT) at the default
budget, sprayplan's own iterated local search (the fallback) at its default budget, elkai (LKH-3 wrapper,
non-commercial licence, measured for reference only, not a dependency: ``pip install elkai``) with 1 run,
and the construction methods. Time-bounded or random solvers: median of ``--repeat`` (3) runs.

Usage::

    python bench/bench_tours.py [--repeat 3] [--ga-population 500] [--ga-seconds 60] [--instances berlin52,...]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import testdata_dir  # bench/ is on sys.path when run as a script

from sprayplan.ordering import GA_SEED, GAParams, default_time_limit, ga_tour, read_tsplib, solve_tour, tour_length
from sprayplan.ordering.backends import fast_tsp_available

COMMAND = "python bench/bench_tours.py"
INSTANCES = ["berlin52", "kroA100", "ch150", "a280", "pcb442", "pr1002"]


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def median_runs(fn, points, best, repeat):
    """Median ratio and median time of ``repeat`` runs of ``fn(seed) -> order``."""
    ratios, times = [], []
    for seed in range(repeat):
        order, seconds = timed(lambda s=seed: fn(s))
        ratios.append(tour_length(points, order) / best)
        times.append(seconds)
    return statistics.median(ratios), statistics.median(times), max(ratios)


def elkai_order(points):
    import elkai

    diff = points[:, None, :] - points[None, :, :]
    dist = np.rint(np.sqrt((diff**2).sum(axis=2)) * 1000).astype(np.int64)  # LKH takes integer weights
    return np.array(elkai.DistanceMatrix(dist.tolist()).solve_tsp(runs=1)[:-1])


def library_version(name):
    try:
        from importlib.metadata import version

        return version(name)
    except Exception:
        return None


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--ga-population", type=int, default=500)
    parser.add_argument("--ga-seconds", type=float, default=60.0)
    parser.add_argument("--instances", default=",".join(INSTANCES))
    args = parser.parse_args(argv)
    names = [n for n in args.instances.split(",") if n]
    folder = testdata_dir() / "tsplib"
    has_elkai = library_version("elkai") is not None
    ga_params = GAParams(
        population=args.ga_population,
        generations=GA_SEED.generations,
        crossover=GA_SEED.crossover,
        k1=GA_SEED.k1,
        k2=GA_SEED.k2,
    )

    rows_ga, rows_lib = [], []
    for name in names:
        points, optimum = read_tsplib(folder / f"{name}.tsp")
        n = len(points)
        best = tour_length(points, optimum)
        default, t_default = timed(lambda p=points: solve_tour(p))
        ga, t_ga = timed(lambda p=points: ga_tour(p, params=ga_params, time_limit_s=args.ga_seconds, seed=0))
        r_default, r_ga = default.length / best, ga.length / best
        rows_ga.append(
            f"| {name} | {n} | {r_default:.4f} | {t_default:.2f} | {r_ga:.4f} | {ga.generations:,} | {t_ga:.1f} "
            f"| {r_ga / r_default:.3f} | {t_ga / t_default:.0f} x |"
        )
        lib = {}
        if fast_tsp_available():
            lib["fast-tsp"] = median_runs(
                lambda s, p=points: solve_tour(p, method="fast-tsp", seed=s).order, points, best, args.repeat
            )
        lib["own local search"] = median_runs(
            lambda s, p=points: solve_tour(p, method="local", seed=s).order, points, best, args.repeat
        )
        if has_elkai:
            lib["elkai (1 run)"] = median_runs(lambda s, p=points: elkai_order(p), points, best, args.repeat)
        lib["2opt"] = median_runs(lambda s, p=points: solve_tour(p, method="2opt").order, points, best, 1)
        lib["nearest"] = median_runs(lambda s, p=points: solve_tour(p, method="nearest").order, points, best, 1)
        cells = " | ".join(f"{r:.4f} / {t:.2f}" for r, t, _ in lib.values())
        worst = max(w for key, (_, _, w) in lib.items() if key in ("fast-tsp", "own local search"))
        rows_lib.append(
            f"| {name} | {n} | {default_time_limit(n):.2f} / {default_time_limit(n, False):.2f} | {cells} "
            f"| {worst:.4f} |"
        )
        print(f"done {name}", file=sys.stderr, flush=True)

    print("# Tour solvers on TSPLIB\n")
    print(f"Reproduce: `{COMMAND}" + (f" --instances {args.instances}" if names != INSTANCES else "") + "`")
    versions = ", ".join(
        f"{lib} {library_version(lib)}" for lib in ("numpy", "fast-tsp", "elkai") if library_version(lib)
    )
    print(f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, {versions}")
    print("Lengths with float Euclidean distances, divided by the float length of TSPLIB's optimal tour.\n")
    print("## Default solver vs the seed's GA\n")
    print(
        f"GA at REDUCED parameters: population {ga_params.population} (paper: {GA_SEED.population}), up to "
        f"{ga_params.generations:,} generations (the paper's), capped at {args.ga_seconds:.0f} s per instance "
        f"(the 'generations' column says how many ran); Pc {ga_params.crossover}, K1 {ga_params.k1}, "
        f"K2 {ga_params.k2}, seed 0. Default solver: `solve_tour(points)`, one run.\n"
    )
    print(
        "| instance | n | default: length/opt | default: s | GA: length/opt | GA: generations | GA: s "
        "| GA/default length | GA/default time |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    print("\n".join(rows_ga))
    print(f"\n## Solvers behind solve_tour (median of {args.repeat} runs: length/opt / seconds)\n")
    heads = list(lib.keys())
    print("| instance | n | budget s (fast-tsp / own) | " + " | ".join(heads) + " | worst run (fast-tsp, own) |")
    print("| --- | ---: | ---: | " + " | ".join("---:" for _ in heads) + " | ---: |")
    print("\n".join(rows_lib))
    print("\n2opt and nearest are deterministic: one run. elkai has no time budget (RUNS = 1).")
    return 0


if __name__ == "__main__":
    sys.exit(main())
