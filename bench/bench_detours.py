"""The transfers a cell plan leaves in collision, and how many a longer detour search frees (``cells.routes``,
issue 18: "no collisions").

A cell plan folder written by ``sprayplan plan BODY --cell line3 --collisions`` holds every robot's work in
``cell_plan.json``. The body is placed in the cell again and the cell's collision model built as the plan built
it; each robot's transfers (the spray-off joint moves between two runs) are checked, those in collision are
counted by what they join (two touch-ups, a stroke and a touch-up, two planned strokes), and each is given to
the router (``CellRouter.route``: retract, via, then the seeded RRT-Connect detour) with ``[collision]
cell_detour_iterations`` at each of ``--iterations``, the seed the transfer's place in that list. Prints one JSON line per robot and
setting: transfers in collision, freed, by route kind, and the seconds the search took.

Usage::

    python bench/bench_detours.py OUT --part bmw --iterations 200,1000,4000
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _kind(stroke) -> str:
    return "touch-up" if stroke.kind == "touch-up" else "stroke"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="a cell plan folder written with --collisions")
    parser.add_argument("--part", default="bmw", choices=("bmw", "suv"))
    parser.add_argument("--iterations", default="200,1000,4000", help="detour iterations to try, comma-separated")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from _data import cell_plan_model

    from sprayplan.cells.routes import CellRouter

    plan, placed, _, config, arms = cell_plan_model(args.folder, args.part)
    for cell_robot, work, arm in zip(plan.cell.robots, plan.robots, arms):
        starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
        router = CellRouter(cell_robot, arm, placed.part, config)
        stuck = []  # (transfer index, joined kinds)
        for i, s in enumerate(work.strokes):
            if s.spray_on or i == 0 or i + 1 >= len(work.strokes):
                continue
            a, b = starts[i], starts[i + 1]
            q, t = work.q[a:b], work.track_mm[a:b]
            if router.free(q[0], t[0], q[1:-1], t[1:-1], q[-1], t[-1]):
                continue
            kinds = sorted((_kind(work.strokes[i - 1]), _kind(work.strokes[i + 1])))
            stuck.append((i, " / ".join(kinds)))
        joined = {}
        for _, k in stuck:
            joined[k] = joined.get(k, 0) + 1
        for iterations in [int(x) for x in args.iterations.split(",")]:
            router.config = dataclasses.replace(config, cell_detour_iterations=iterations)
            freed, kinds = 0, {}
            start = time.perf_counter()
            for n, (i, _) in enumerate(stuck):
                a, b = starts[i], starts[i + 1] - 1
                found = router.route(work.q[a], work.track_mm[a], work.q[b], work.track_mm[b], seed=n)
                if found is not None:
                    freed += 1
                    kinds[found[0]] = kinds.get(found[0], 0) + 1
            row = {
                "robot": work.name,
                "iterations": iterations,
                "in_collision": len(stuck),
                "joined": joined,
                "freed": freed,
                "by_route": kinds,
                "seconds": round(time.perf_counter() - start, 1),
            }
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
