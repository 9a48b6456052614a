"""The run-ups of a cell plan found again with the collision model (``cells.runups.robot_run_ups``, issue 18):
the seconds each robot's run-ups take, and, with ``--base``, the same with another checkout's
``cells/runups.py``, the two compared run for run (the same run-ups and counts expected).

A cell plan folder written by ``sprayplan plan BODY --cell line3 --collisions`` holds every robot's work in
``cell_plan.json``. The body is placed in the cell again, the painted surface and the collision model built as
the plan builds them, and each robot's run-ups are found with the lines checked against the body and the
programs' back-off from each far end (``CellRouter.backs_free``): this checkout's, then the base's, then this
checkout's again (so that a load that changes during the run shows). Prints one JSON line per robot.

Usage::

    python bench/bench_runups.py OUT --part bmw --base ../wt-base
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="a cell plan folder written with --collisions")
    parser.add_argument("--part", default="bmw", choices=("bmw", "suv"))
    parser.add_argument("--base", help="another checkout whose src/sprayplan/cells/runups.py to compare with")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from _data import cell_plan_model

    from sprayplan.cells import runups
    from sprayplan.cells.routes import CellRouter

    builds = [("this", runups)]
    if args.base:
        spec = importlib.util.spec_from_file_location(
            "base_runups", Path(args.base) / "src" / "sprayplan" / "cells" / "runups.py"
        )
        base = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(base)
        builds += [("base", base), ("this again", runups)]
    plan, _, painted, config, arms = cell_plan_model(args.folder, args.part)
    job = plan.job
    for cell_robot, work, arm in zip(plan.cell.robots, plan.robots, arms):
        router = CellRouter(cell_robot, arm, painted, config)

        def backs(q, t, router=router):
            return router.backs_free(q, t, job.export.approach_mm)

        found = {}
        for name, module in builds:
            start = time.perf_counter()
            lead_q, lead_track, counts = module.robot_run_ups(
                cell_robot, work, job.timing.run_up_mm, job.paths.standoff_mm, arm, backs
            )
            found[name] = (lead_q, lead_track, counts, round(time.perf_counter() - start, 2))
        row = {"robot": work.name, "counts": found["this"][2], "seconds": {k: v[3] for k, v in found.items()}}
        if "base" in found:
            this, other = found["this"], found["base"]
            row["same_as_base"] = bool(
                np.array_equal(this[0], other[0], equal_nan=True)
                and np.array_equal(this[1], other[1], equal_nan=True)
                and this[2] == other[2]
            )
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
