"""Benchmark of the targets stage: even sampling vs the seed's DFS point and line filling, on the same part.

Each method runs in a fresh process (so its peak memory is its own) several times; the table gives medians.
Times exclude loading the file (reported on its own line). Uniformity: the coefficient of variation of the
nearest-neighbour distance (lower is more even) and the 99th percentile of the distance from random surface
points to the nearest target, over the spacing (lower leaves fewer gaps).

Usage::

    python bench/bench_targets.py [--part PATH --units m] [--spacing-mm 5] [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from _data import meshes_dir  # bench/ is on sys.path when run as a script

METHODS = {
    "even + face normals": dict(fill="even", normals="face", compress="none"),
    "even + PCA normals": dict(fill="even", normals="pca", compress="none"),
    "DFS point filling (seed)": dict(fill="point", compress="none"),
    "DFS line filling (seed)": dict(fill="line", compress="none"),
}
DEFAULT_PART = "dtc_ship_hull_ascii.stl.gz"  # in the shared data's meshes/ (bench/_data.py)


def run_one(part_path: str, units: str, method: str, spacing: float) -> dict:
    import numpy as np
    from scipy.spatial import cKDTree

    from sprayplan.config import TargetsConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.filling import sample_uniform
    from sprayplan.surface.targets import make_targets

    start = time.perf_counter()
    part = load_part(part_path, units=units)
    load_s = time.perf_counter() - start
    options = dict(METHODS[method])
    if options["fill"] != "even":
        options["h_min_mm"] = spacing
    config = TargetsConfig(spacing_mm=spacing, **options)
    start = time.perf_counter()
    targets = make_targets(part, config)
    elapsed = time.perf_counter() - start
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    tree = cKDTree(targets.points)
    nn = tree.query(targets.points, k=2)[0][:, 1]
    probes, _ = sample_uniform(part.triangles, 200_000, np.random.default_rng(99))
    gap = tree.query(probes)[0]
    return {
        "points": len(targets),
        "time_s": elapsed,
        "load_s": load_s,
        "peak_mb": peak_mb,
        "nn_mean_over_spacing": float(nn.mean() / spacing),
        "nn_cv": float(nn.std() / nn.mean()),
        "gap_p99_over_spacing": float(np.percentile(gap, 99) / spacing),
        "area_m2": part.area / 1e6,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", help=f"default: {DEFAULT_PART} from the shared test data")
    parser.add_argument("--units", default="m")
    parser.add_argument("--spacing-mm", type=float, default=5.0)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.part is None:
        args.part = str(meshes_dir() / DEFAULT_PART)
    if args.one:
        print(json.dumps(run_one(args.part, args.units, args.one, args.spacing_mm)))
        return 0
    rows = {}
    for _ in range(args.repeat):  # interleave the methods so machine load affects all alike
        for method in METHODS:
            cmd = [
                sys.executable,
                __file__,
                "--part",
                args.part,
                "--units",
                args.units,
                "--spacing-mm",
                str(args.spacing_mm),
                "--one",
                method,
            ]
            result = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
            rows.setdefault(method, []).append(result)
    first = next(iter(rows.values()))[0]
    print(
        f"part {Path(args.part).name}: {first['area_m2']:.3f} m^2, spacing {args.spacing_mm} mm, "
        f"{args.repeat} runs each, medians; load {statistics.median(r['load_s'] for v in rows.values() for r in v):.2f} s"
    )
    base = statistics.median(r["time_s"] for r in rows["even + face normals"])
    print("| method | points | time s | time / even | peak MB | NN mean / d | NN CV | gap p99 / d |")
    print("|---|---|---|---|---|---|---|---|")
    for method, results in rows.items():
        med = {k: statistics.median(r[k] for r in results) for k in results[0]}
        print(
            f"| {method} | {med['points']:.0f} | {med['time_s']:.2f} | {med['time_s'] / base:.2f} | "
            f"{med['peak_mb']:.0f} | {med['nn_mean_over_spacing']:.2f} | {med['nn_cv']:.3f} | "
            f"{med['gap_p99_over_spacing']:.2f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
