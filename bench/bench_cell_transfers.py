"""A cell robot's moves between strokes as its base moves (issue 18: why runs are dropped with --collisions).

Each car body is planned in a cell up to its strokes (``bench_cell_heights.planned``: areas, reach with the
collision model, strokes, first IK solutions, no repairs); then, with ``--robot``'s base moved to each of
``--values`` along ``--axis`` (mm, the cell frame), its spray strokes are solved again in plan order
(``cells.plan.solve_strokes``: one try a stroke, no repairs) and printed per value: the stroke ends (first and
last reached waypoint) free of the part and the floor, the ends whose back-off along the gun axis is free as the
programs make it (``CellRouter.backs_free`` at ``[export] approach_mm``), and the straight joint moves from one
stroke's end to the next one's start that are free (``CellRouter._edges_free``): the transfers that need no
route; and the ends by the way the surface faces there, with the share of each in collision
(docs/benchmarks.md, "Session 21").

    python bench/bench_cell_transfers.py --body suv --values 3700,3942,4300
    python bench/bench_cell_transfers.py --body bmw --values 3343,3700,3900
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from bench_cell_heights import base_parser, moved_cell, planned, robot_index  # noqa: E402


def stroke_ends(strokes, solved) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(ends (2k, dof + 1), transfer starts (m, dof + 1), transfer ends (m, dof + 1), normals (2k, 3)): the
    joints and track position at the first and last reached waypoint of every stroke reached at two or more,
    the moves from each such stroke's last to the next one's first (none across a stroke not reached), and
    the surface normal at each end."""
    ends, a, b, normals = [], [], [], []
    last = None
    for stroke, (track, _, q, ok) in zip(strokes, solved):
        k = np.flatnonzero(ok)
        if len(k) < 2:
            last = None
            continue
        first = np.r_[q[k[0]], track[k[0]]]
        ends += [first, np.r_[q[k[-1]], track[k[-1]]]]
        normals += [stroke.normals[k[0]], stroke.normals[k[-1]]]
        if last is not None:
            a.append(last)
            b.append(first)
        last = ends[-1]
    width = solved[0][2].shape[1] + 1 if solved else 1
    shaped = [np.array(x).reshape(-1, width) for x in (ends, a, b)]
    return shaped[0], shaped[1], shaped[2], np.array(normals).reshape(-1, 3)


def by_facing(normals: np.ndarray, hit: np.ndarray) -> dict:
    """Per way the surface faces at a stroke end (the normal's largest component: ``+x`` ... ``-z``): the ends
    and the share of them in collision."""
    axis = np.argmax(np.abs(normals), axis=1)
    sign = np.sign(normals[np.arange(len(normals)), axis])
    out = {}
    for k, name in enumerate("xyz"):
        for s_, label in ((1, "+"), (-1, "-")):
            m = (axis == k) & (sign == s_)
            if m.any():
                out[label + name] = [int(m.sum()), round(float(hit[m].mean()), 3)]
    return out


def main() -> None:
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.plan import solve_strokes
    from sprayplan.cells.routes import CellRouter

    args = base_parser(__doc__, "3700,3942,4300").parse_args()
    cell, painted, job, _, _, works = planned(args.body, args.cell)
    index = robot_index(cell, args.robot)
    spray = [s for s in works[index].strokes if s.spray_on]
    axis = "xyz".index(args.axis)
    for value in (float(v) for v in args.values.split(",")):
        at = moved_cell(cell, index, axis, value)
        router = CellRouter(at.robots[index], cell_arms(at, painted, job.collision)[index], painted, job.collision)
        ends, a, b, normals = stroke_ends(spray, solve_strokes(at.robots[index], spray))
        free = router._states_free(ends) if len(ends) else np.zeros(0, bool)
        backs = router.backs_free(ends[:, :-1], ends[:, -1], job.export.approach_mm) if len(ends) else free
        straight = router._edges_free(a, b) if len(a) else np.zeros(0, bool)
        print(json.dumps({"body": args.body, "robot": args.robot, args.axis: value, "spray_strokes": len(spray),
                          "stroke_ends": len(ends), "ends_free": round(float(free.mean()), 3) if len(free) else None,
                          "backs_free": round(float(backs.mean()), 3) if len(backs) else None,
                          "transfers": len(a),
                          "straight_free": round(float(straight.mean()), 3) if len(a) else None,
                          "ends_by_facing_and_share_in_collision": by_facing(normals, ~free)}),
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
