"""The runs in collision solved on their own with a tilted gun (``cells.repair.resolved_piece``, issue 18): how
many spray waypoints each set of tilts leaves out in collision, and what it costs.

A body (``bmw``, ``suv``) is planned in ``line3`` with ``--collisions`` and 50 um, as ``sprayplan plan BODY
--units m --cell line3 --thickness-um 50 --collisions`` does, up to the collision step (the reach of the areas
with the collision model included); there the plan is taken, each robot's strokes repaired
(``cells.repair.repaired_work``) and checked, and then cut to its free runs (``cells.repair.free_work``) with
the runs in collision solved on their own under each set of tilts (``resolved_piece``'s ``tilts``): none,
sideways only (20, -20, 40, -40 degrees about the travel), sideways and forward/back (``piece_tilts(40)``, the
default ``[collision] piece_tilt_deg``), and the same with 60 degrees sideways too. Prints one JSON line per robot and set: the waypoints left out in collision, the pieces
solved and tilted, and the cut's wall seconds.

Usage::

    python bench/bench_piece_tilts.py --part bmw
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PARTS = {"bmw": ("meshes/bmw_m6_body_m_yup.ply", "y"), "suv": ("meshes/gazebo_suv_body_m.ply", "z")}
SIDEWAYS = tuple((False, a) for a in (20.0, -20.0, 40.0, -40.0))
ACROSS = tuple((True, a) for a in (20.0, -20.0, 40.0, -40.0))
SETS = {
    "none": (),
    "sideways": SIDEWAYS,
    "sideways+across": SIDEWAYS + ACROSS,
    "sideways+across+60": SIDEWAYS + ((False, 60.0), (False, -60.0)) + ACROSS,
}


class _Taken(Exception):
    """Raised by the hook once it has the collision step's arguments."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", default="bmw", choices=sorted(PARTS))
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from _data import testdata_dir

    import sprayplan.cells.collide as collide
    import sprayplan.cells.repair as repair
    from sprayplan.cells.plan import plan_cell
    from sprayplan.cells.spec import load_cell
    from sprayplan.collision.arms import check_robot
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part

    taken = {}

    def hook(cell, robots, arms, config, repair_=None, part=None, standoff_mm=0.0, failed=None, since=None):
        taken.update(cell=cell, robots=robots, arms=arms, standoff=standoff_mm, repair=repair_)
        raise _Taken

    collide.freed_cell = hook
    path, up = PARTS[args.part]
    job = JobConfig().replace(coating={"thickness_um": 50.0}, collision={"check": True})
    start = time.perf_counter()
    try:
        plan_cell(load_part(testdata_dir() / path, units="m", up=up), load_cell("line3"), job)
    except _Taken:
        pass
    print(json.dumps({"planned_s": round(time.perf_counter() - start, 1)}), flush=True)
    for cell_robot, work, arm in zip(taken["cell"].robots, taken["robots"], taken["arms"]):
        work, _ = taken["repair"](cell_robot, work, arm)
        found = check_robot(arm, work.q, work.track_mm, work.reachable)
        for name, tilts in SETS.items():
            start = time.perf_counter()
            _, counts = repair.free_work(
                work,
                found,
                lambda p, s, r=cell_robot, a=arm, t=tilts: repair.resolved_piece(r, a, p, s, taken["standoff"], t),
            )
            row = {"robot": work.name, "tilts": name, "cut_s": round(time.perf_counter() - start, 1)}
            print(json.dumps({**row, **counts}), flush=True)


if __name__ == "__main__":
    main()
