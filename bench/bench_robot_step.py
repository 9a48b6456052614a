"""One cell robot's collision step as ``sprayplan plan --cell line3 --collisions`` runs it (issue 18: why runs
are dropped), the other robots skipped: its repairs, cut, routes and drops on a car body, and then the
transfers no route freed, decoded (how far the gun tip moves, how far a joint turns).

    python bench/bench_robot_step.py --body suv --robot roof [--mask REGION ...]

Prints the step's counts and time (``cells.collide``'s entry: ``runs_dropped``, ``runs_dropped_mm``, ...), the
drop rounds (``cells.collide``'s log line), and over the failed transfers the 10/50/90 % quantiles of the tip's move (mm) and of the
largest joint turn (deg). The step stops the plan after that robot (nothing is written). ``--mask`` as the
plan's.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import CAR_BODIES, testdata_dir  # noqa: E402


class _Done(Exception):
    pass


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--body", choices=sorted(CAR_BODIES), default="suv")
    ap.add_argument("--robot", default="roof")
    ap.add_argument("--mask", action="append", default=[], help="a mask as the plan's --mask (repeatable)")
    args = ap.parse_args(argv)

    from sprayplan.cells import collide, each, load_cell

    names = [r.name for r in load_cell("line3").robots]
    if args.robot not in names:
        print(f"--robot: one of {', '.join(names)}, got {args.robot!r}", file=sys.stderr)
        return 2
    from sprayplan.cli import main as cli_main

    plain_each, plain_freed = each.each_robot, collide._freed_robot
    each.each_robot = lambda calls, workers, sizes: plain_each(calls, 1, sizes)  # in this process
    got = {}

    def one(cell_robot, work, arm, *rest):
        if cell_robot.name != args.robot:
            return work, {}, rest[4]  # (its failed transfers, unchanged)
        t0 = time.perf_counter()
        out = plain_freed(cell_robot, work, arm, *rest)
        got.update(
            seconds=round(time.perf_counter() - t0, 1), counts=out[1], failed=out[2], cell_robot=cell_robot, arm=arm
        )
        raise _Done

    collide._freed_robot = one
    rounds = logging.getLogger("sprayplan.cells.collide")  # its "N runs dropped in R rounds"
    rounds.addHandler(logging.StreamHandler(sys.stdout))
    rounds.setLevel(logging.INFO)
    path, up = CAR_BODIES[args.body]
    with tempfile.TemporaryDirectory() as tmp:
        try:
            cli_main(
                ["-q", "plan", str(testdata_dir() / path), "--units", "m", "--up", up, "--cell", "line3",
                 "--thickness-um", "50", "--collisions", *(f"--mask={m}" for m in args.mask),
                 "-o", str(Path(tmp) / "out")]
            )  # fmt: skip
        except _Done:
            pass
    if not got:
        print(f"robot {args.robot!r} not in line3 or no collision step ran", file=sys.stderr)
        return 2
    from sprayplan.collision.arms import ARM_BODIES

    arm = got["arm"]
    moves, turns, ends, bodies = [], [], [], {}
    for key in got["failed"] or ():
        a = np.frombuffer(key, dtype=float).reshape(2, -1)
        tips = arm.tcp(a[:, :-1], a[:, -1])  # the gun tip at both ends, cell frame
        moves.append(float(np.linalg.norm(tips[1] - tips[0])))
        turns.append(float(np.degrees(np.abs(a[1, :-1] - a[0, :-1])).max()))
        ends.append(tips)
        s = np.linspace(0.0, 1.0, 41)[:, None]
        hit = arm.check(a[0, :-1] + s * (a[1, :-1] - a[0, :-1]), a[0, -1] + s[:, 0] * (a[1, -1] - a[0, -1]))
        for body in set(hit.body[hit.collides].tolist()):
            bodies[ARM_BODIES[body]] = bodies.get(ARM_BODIES[body], 0) + 1
    counts = {k: (int(v) if isinstance(v, (int, np.integer)) else v) for k, v in got["counts"].items()}
    print(json.dumps({"robot": args.robot, "seconds": got["seconds"], **counts}))
    if moves:
        q = [10, 50, 90]
        print(
            f"{len(moves)} transfers no route freed: tip move {np.percentile(moves, q).round(0).tolist()} mm, "
            f"largest joint turn {np.percentile(turns, q).round(0).tolist()} deg (10/50/90 %)"
        )
        tips = np.concatenate(ends)
        print(
            f"their ends' gun tips: x {np.percentile(tips[:, 0], q).round(0).tolist()}, y "
            f"{np.percentile(tips[:, 1], q).round(0).tolist()}, z {np.percentile(tips[:, 2], q).round(0).tolist()} mm"
            f" (10/50/90 %); |y| < 300 mm: {int((np.abs(tips[:, 1]) < 300).sum())} of {len(tips)}; bodies in "
            f"collision along the joint move (transfers): {dict(sorted(bodies.items(), key=lambda kv: -kv[1]))}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
