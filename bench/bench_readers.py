"""Benchmark of the strict readers (issue 13): load time per part, and what the checks cost.

For every mesh of the shared data: the whole ``load_part`` (median of ``--repeat`` runs), the reader alone
(``read_part_file``: bytes -> arrays, including the structural checks that are part of parsing), the shared
post-load checks alone (``check_part_arrays``: finite, the 1e7 mm bound, face indices, normals), and, for
PLY files, trimesh's lenient loader that the own reader replaced (``trimesh.load(process=False)``).

Usage::

    python bench/bench_readers.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

from _data import meshes_dir  # bench/ is on sys.path when run as a script

PARTS = [
    ("dtc_ship_hull_ascii.stl.gz", "m"),
    ("tray_bottom_mm_ascii.stl", "mm"),
    ("featuretype_binary.stl", "in"),
    ("bmw_m6_body_m_yup.ply", "m"),
    ("noether_raw_scan_mesh.ply", "m"),
    ("reach_curved_part.ply", "m"),
    ("gazebo_suv_body_m.ply", "m"),
]


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    import trimesh

    from sprayplan.io.load import check_part_arrays, load_part, read_part_file

    print("| part | triangles | load_part ms | reader ms | post-load checks ms | checks / load | trimesh ms |")
    print("|---|---|---|---|---|---|---|")
    for name, units in PARTS:
        path = str(meshes_dir() / name)
        vertices, faces, normals = read_part_file(path)
        load = median_time(lambda p=path, u=units: load_part(p, units=u), args.repeat)
        read = median_time(lambda p=path: read_part_file(p), args.repeat)
        checks = median_time(
            lambda v=vertices, f=faces, n=normals, p=path, u=units: check_part_arrays(v, f, n, p, u), args.repeat * 4
        )
        old = "-"
        if name.endswith(".ply"):
            old = f"{1e3 * median_time(lambda p=path: trimesh.load(p, process=False), args.repeat):.1f}"
        print(
            f"| {name} | {len(faces)} | {1e3 * load:.1f} | {1e3 * read:.1f} | {1e3 * checks:.2f} | "
            f"{100 * checks / load:.2f} % | {old} |"
        )


if __name__ == "__main__":
    main()
