"""Automatic areas (issue 18): time to place, segment and assign both car bodies, and what each robot gets.

    python bench/bench_areas.py [--repeat 3]

For each body (BMW M6, y up; the Gazebo SUV) and cell (line3, sides2): the median wall time of segmentation
and of the reach matrix over ``--repeat`` runs, the areas and their robots, the surface each robot paints,
the unreached surface; and the reach matrix with every face tried (``cluster_mm = 0``) beside the grouped one
once, as a ratio, with the share of faces whose robot differs.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir

from sprayplan.cells import load_cell, place_part
from sprayplan.cells.reach import reach_matrix
from sprayplan.io.load import load_part
from sprayplan.surface.areas import assign_areas, segment_areas
from sprayplan.surface.region import drop_floor_facing

BODIES = {"bmw": ("bmw_m6_body_m_yup.ply", {"units": "m", "up": "y"}), "suv": ("gazebo_suv_body_m.ply", {"units": "m"})}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    for body, (name, kw) in BODIES.items():
        part = load_part(meshes_dir() / name, **kw)
        for cell_name in ("line3", "sides2"):
            cell = load_cell(cell_name)
            painted, _ = drop_floor_facing(place_part(part, cell).part, 45.0)
            seg, rch = [], []
            for _ in range(args.repeat):
                t = time.perf_counter()
                areas = segment_areas(painted)
                seg.append(time.perf_counter() - t)
                t = time.perf_counter()
                reach = reach_matrix(cell, painted, areas.face_normals, 113.0)
                rch.append(time.perf_counter() - t)
            got = assign_areas(areas, painted.face_areas, reach)
            t = time.perf_counter()
            exact = reach_matrix(cell, painted, areas.face_normals, 113.0, cluster_mm=0.0)
            t_exact = time.perf_counter() - t
            got_exact = assign_areas(areas, painted.face_areas, exact)
            differ = (got.face_robot != got_exact.face_robot) @ painted.face_areas / painted.area
            names = [r.name for r in cell.robots]
            print(
                f"{body} {cell_name}: {len(painted.faces)} faces, {painted.area / 1e6:.2f} m^2; segment "
                f"{statistics.median(seg):.2f} s, reach {statistics.median(rch):.2f} s (every face: {t_exact:.2f} s,"
                f" {t_exact / statistics.median(rch):.1f}x; {100 * differ:.2f} % of the surface to another robot)"
            )
            for k, area_name in enumerate(areas.names):
                r = got.area_robot[k]
                print(
                    f"   {area_name:10s} {areas.area_mm2[k] / 1e6:6.3f} m^2 -> {names[r] if r >= 0 else '-':6s} "
                    f"{100 * got.area_share[k]:5.1f} %{' split' if got.split[k] else ''}"
                )
            per = ", ".join(f"{n} {a / 1e6:.2f}" for n, a in zip(names, got.robot_area_mm2))
            print(
                f"   per robot (m^2): {per}; unreached {got.unreached_mm2 / 1e6:.3f} m^2 "
                f"({100 * got.unreached_mm2 / painted.area:.2f} %)"
            )


if __name__ == "__main__":
    main()
