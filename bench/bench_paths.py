"""Benchmark of the paths stage: mesh slicing on large meshes, and mesh vs point-cloud slicing side by side.

Each case runs in a fresh process several times (interleaved); the tables give medians. Times are the paths
stage alone (``plan_paths``), without reading the file; peak memory is the process's, loading included.

Usage::

    python bench/bench_paths.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time

from _data import meshes_dir  # bench/ is on sys.path when run as a script

CASES = {
    "DTC hull, 116k faces, 50 mm": ("dtc_ship_hull_ascii.stl.gz", "m", 0, "mesh", 50.0),
    "DTC hull subdivided, 464k faces, 50 mm": ("dtc_ship_hull_ascii.stl.gz", "m", 1, "mesh", 50.0),
    "reach part subdivided, 259k faces, 50 mm": ("reach_curved_part.ply", "m", 3, "mesh", 50.0),
    "reach part mesh, 4k faces, 50 mm": ("reach_curved_part.ply", "m", 0, "mesh", 50.0),
    "reach part as a 3 mm cloud, 50 mm": ("reach_curved_part.ply", "m", 0, "cloud", 50.0),
}


def run_one(name: str) -> dict:
    import numpy as np

    from sprayplan.config import PathConfig
    from sprayplan.io.load import load_part
    from sprayplan.paths.planner import plan_paths
    from sprayplan.surface.filling import sample_even
    from sprayplan.types import Part

    file, units, subdivisions, kind, spacing = CASES[name]
    part = load_part(meshes_dir() / file, units=units)
    if subdivisions:
        import trimesh

        vertices, faces = part.vertices, part.faces
        for _ in range(subdivisions):
            vertices, faces = trimesh.remesh.subdivide(vertices, faces)
        part = Part(vertices, faces, None, part.name)
    if kind == "cloud":
        points, _ = sample_even(part.triangles, 3.0, seed=0)
        part = Part(points, np.zeros((0, 3)), None, "cloud")
    size = len(part.faces) if part.is_mesh else len(part.vertices)
    start = time.perf_counter()
    paths = plan_paths(part, PathConfig(spacing_mm=spacing))
    elapsed = time.perf_counter() - start
    return {
        "size": size,
        "time_s": elapsed,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "strokes": len(paths.spray_strokes),
        "spray_m": paths.spray_length_mm / 1000.0,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:
        print(json.dumps(run_one(args.one)))
        return 0
    rows = {}
    for _ in range(args.repeat):
        for name in CASES:
            out = subprocess.run([sys.executable, __file__, "--one", name], check=True, capture_output=True, text=True)
            rows.setdefault(name, []).append(json.loads(out.stdout))
    print(f"{args.repeat} runs each, medians")
    print("| case | faces or points | paths time s | peak MB | strokes | spray length m |")
    print("|---|---|---|---|---|---|")
    for name, results in rows.items():
        med = {k: statistics.median(r[k] for r in results) for k in results[0]}
        print(
            f"| {name} | {med['size']:.0f} | {med['time_s']:.2f} | {med['peak_mb']:.0f} | {med['strokes']:.0f} | {med['spray_m']:.1f} |"
        )
    mesh = statistics.median(r["time_s"] for r in rows["reach part mesh, 4k faces, 50 mm"])
    cloud = statistics.median(r["time_s"] for r in rows["reach part as a 3 mm cloud, 50 mm"])
    print(f"\ncloud slicing / mesh slicing on the reach part: {cloud / mesh:.1f}x the time")
    return 0


if __name__ == "__main__":
    sys.exit(main())
