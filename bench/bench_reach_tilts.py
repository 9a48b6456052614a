"""How much of a body no robot of ``line3`` reaches free of it (``cells.reach.reach_matrix`` with the collision
model, issue 18), with the gun along the normal only and with tilted tries (``tilts_deg=reach_tilts(deg)``: the
gun turned about the pose's x and y axes through its target by half of ``deg`` and all of it, either way; the
plan tries ``reach_tilts([collision] piece_tilt_deg)``, 40 by default, and paints those faces with the pieces
of its strokes solved again tilted, ``cells.repair.resolved_piece``).

Each body is placed in ``line3`` and its painted surface found as ``sprayplan plan BODY --cell line3
--collisions`` finds it.

Usage::

    python bench/bench_reach_tilts.py
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PARTS = {"suv": ("meshes/gazebo_suv_body_m.ply", "z"), "bmw": ("meshes/bmw_m6_body_m_yup.ply", "y")}
TILTS_DEG = (20.0, 40.0)


def main() -> None:
    sys.path.insert(0, str(HERE))
    from _data import testdata_dir

    import sprayplan.cells.reach as reach
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.plan import area_surface
    from sprayplan.cells.spec import load_cell, place_part
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.areas import segment_areas
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import painted_surface

    job = JobConfig().replace(coating={"thickness_um": 50.0}, collision={"check": True})
    standoff = job.paths.standoff_mm
    cell = load_cell("line3")
    for name, (path, up) in PARTS.items():
        placed = place_part(load_part(testdata_dir() / path, units="m", up=up), cell)
        painted, _ = painted_surface(oriented_part(placed.part), job.collision)
        painted, _ = area_surface(painted)
        arms = cell_arms(cell, painted, job.collision)
        normals = segment_areas(painted).face_normals
        area = painted.face_areas
        row = {"part": name, "area_m2": round(area.sum() / 1e6, 2), "unreached_m2": {}, "seconds": {}}
        for deg in (0.0, *TILTS_DEG):
            start = time.perf_counter()
            got = reach.reach_matrix(cell, painted, normals, standoff, arms=arms, tilts_deg=reach.reach_tilts(deg))
            key = "none" if deg == 0 else f"up to {deg:g} deg"
            row["seconds"][key] = round(time.perf_counter() - start, 1)
            row["unreached_m2"][key] = round(area[got.max(axis=0) == 0].sum() / 1e6, 3)
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
