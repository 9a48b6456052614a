"""How much of a body no robot of ``line3`` reaches free of it (``cells.reach.reach_matrix`` with the collision
model, issue 18), with the gun along the normal and with the gun tilted about its target as well.

Each body is placed in ``line3`` and its painted surface found as ``sprayplan plan BODY --cell line3
--collisions`` finds it; the reach matrix is computed with the cell's collision model (the faces no robot
reaches free count as unreached, as in the plan), then again with every pose of the reach check tilted about
its target by +-20 and +-40 degrees about the pose's x and y axes (the gun stays at the standoff, aiming at
the same point): a face counts as reached when any of those tries is. The tilted reach is not what the plan
does today (its reach check keeps the gun along the normal; only the runs of strokes in collision are tilted,
``cells.repair.piece_tilts``): it measures what tilted tries in the reach check would give.

Usage::

    python bench/bench_reach_tilts.py
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
PARTS = {"suv": ("meshes/gazebo_suv_body_m.ply", "z"), "bmw": ("meshes/bmw_m6_body_m_yup.ply", "y")}
TILTS_DEG = (20.0, 40.0)


def _turn(axis: int, angle: float) -> np.ndarray:
    """(3, 3): a turn of ``angle`` rad about the x (0) or y (1) axis."""
    c, s = math.cos(angle), math.sin(angle)
    out = np.eye(3)
    if axis == 0:
        out[1:, 1:] = [[c, -s], [s, c]]
    else:
        out[0, 0], out[0, 2], out[2, 0], out[2, 2] = c, s, -s, c
    return out


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
    along_normal = reach.poses_at
    for name, (path, up) in PARTS.items():
        placed = place_part(load_part(testdata_dir() / path, units="m", up=up), cell)
        painted, _ = painted_surface(oriented_part(placed.part), job.collision)
        painted, _ = area_surface(painted)
        arms = cell_arms(cell, painted, job.collision)
        normals = segment_areas(painted).face_normals
        area = painted.face_areas
        start = time.perf_counter()
        best = reach.reach_matrix(cell, painted, normals, standoff, arms=arms)
        row = {"part": name, "area_m2": round(area.sum() / 1e6, 2), "seconds": round(time.perf_counter() - start, 1)}
        row["unreached_m2"] = {"none": round(area[best.max(axis=0) == 0].sum() / 1e6, 3)}
        for deg in TILTS_DEG:
            for axis in (0, 1):
                for sign in (1.0, -1.0):
                    turn = _turn(axis, math.radians(sign * deg))

                    def tilted(tips, face_normals, turn=turn):
                        poses = along_normal(tips, face_normals)
                        target = tips + standoff * poses[:, :3, 2]
                        poses[:, :3, :3] = poses[:, :3, :3] @ turn
                        poses[:, :3, 3] = target - standoff * poses[:, :3, 2]
                        return poses

                    reach.poses_at = tilted
                    try:
                        best = np.maximum(best, reach.reach_matrix(cell, painted, normals, standoff, arms=arms))
                    finally:
                        reach.poses_at = along_normal
            row["unreached_m2"][f"up to {deg:g} deg"] = round(area[best.max(axis=0) == 0].sum() / 1e6, 3)
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
