"""Each cell robot's first solve on a car body, checked against the body before any repair (issue 18: how much a
layout or a solve leaves the collision step to do), the collision step itself skipped.

    python bench/bench_first_solve.py --body suv [--cell line3] [--mask REGION ...]

Plans the body as ``sprayplan plan BODY --cell CELL --collisions`` does up to its collision step, then prints per
robot, from ``collision.arms.check_robot`` on the first solve: the spray waypoints, those reached, those in
collision, the motions in collision, the transfers, those in collision and those turning a joint by more than
``cells.tries.JOINT_JUMP_RAD`` (90 deg: the arm turned over, the transfers no route frees, docs/benchmarks.md
"Session 26"), and the share of reached spray waypoints with the third axis below -90 deg (the elbow folded
back). About 1.5 min for the SUV in ``line3``, against the collision step's 45-75 min: a cheap first look at a
layout. ``--cell`` is a preset name or a cell file, ``--mask`` as the plan's.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import CAR_BODIES, testdata_dir  # noqa: E402


class _Done(BaseException):
    """Stops the plan at its collision step (a BaseException: the command line's error handling lets it by)."""


def first_solve_figures(work, arm) -> dict:
    """The figures of one robot's first solve (module docstring)."""
    from sprayplan.cells.tries import JOINT_JUMP_RAD
    from sprayplan.collision.arms import check_robot

    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    spray = np.concatenate([np.full(len(s), s.spray_on) for s in work.strokes]).astype(bool)
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    transfers = [int(starts[i]) for i, s in enumerate(work.strokes) if not s.spray_on and len(s) == 2]
    turned = [a for a in transfers if np.abs(work.q[a + 1] - work.q[a]).max() > JOINT_JUMP_RAD]
    reached = spray & work.reachable
    return {
        "spray_waypoints": int(spray.sum()),
        "reached": int(reached.sum()),
        "in_collision": int((found.waypoint.collides & spray).sum()),
        "motions_in_collision": int(found.motion_collides.sum()),
        "transfers": len(transfers),
        "transfers_in_collision": int(sum(bool(found.motion_collides[a]) for a in transfers)),
        "transfers_turning_over": len(turned),
        "elbow_folded_back": round(float((work.q[reached, 2] < -math.pi / 2).mean()), 3) if reached.any() else 0.0,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--body", choices=sorted(CAR_BODIES), default="suv")
    ap.add_argument("--cell", default="line3", help="a preset name or a cell file (default line3)")
    ap.add_argument("--mask", action="append", default=[], help="a mask as the plan's --mask (repeatable)")
    args = ap.parse_args(argv)

    from sprayplan.cells import collide
    from sprayplan.cli import main as cli_main

    got: dict = {}
    t0 = time.perf_counter()

    def first(cell, robots, arms, *rest, **kw):
        got["seconds_to_first_solve"] = round(time.perf_counter() - t0, 1)
        for cell_robot, work, arm in zip(cell.robots, robots, arms):
            got[cell_robot.name] = first_solve_figures(work, arm)
        raise _Done

    collide.freed_cell = first  # cells.plan imports it at its collision step
    path, up = CAR_BODIES[args.body]
    with tempfile.TemporaryDirectory() as tmp:
        try:
            code = cli_main(
                ["-q", "plan", str(testdata_dir() / path), "--units", "m", "--up", up, "--cell", args.cell,
                 "--thickness-um", "50", "--collisions", *(f"--mask={m}" for m in args.mask),
                 "-o", str(Path(tmp) / "out")]
            )  # fmt: skip
        except _Done:
            code = 0
    if not got:
        print(f"no collision step ran (the plan's exit code {code})", file=sys.stderr)
        return 2
    print(json.dumps({"body": args.body, "cell": args.cell, "mask": args.mask, **got}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
