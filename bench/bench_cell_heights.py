"""Where a cell robot's base stands, and how many of its waypoints it can paint free (issue 18: no collisions).

Each car body is planned in a cell up to its strokes (``--cell``, as placed for the body: a lift at its height
over it; areas, their reach with the collision model and the tilted tries, the strokes and their first IK
solutions, no repairs); then ``--strokes`` of one robot's spray strokes are drawn at random (seeded), and with
that robot's base moved to each of ``--values`` along ``--axis`` (mm, the cell frame; the others stay), every
waypoint is solved at every track position and roll of ``cells.tries.stroke_tries`` and every IK branch and
checked against the part and the floor (``collision.arms.ArmCollision.collides``). Printed per value: the share
of the waypoints some try reaches (``reached``) and reaches with every body free (``free``): an upper bound
on what the repairs can paint untilted (docs/benchmarks.md, "Session 20"). Also, before the values: each
robot's spray waypoints in collision as first solved, by body and what it meets.

    python bench/bench_cell_heights.py --body suv --robot roof --axis z --values 3700,3900,3950,4000,4100
    python bench/bench_cell_heights.py --body bmw --robot left --axis y --values 2000,2300,2600
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import meshes_dir  # noqa: E402
from bench_cell_collisions import BODIES  # noqa: E402


def planned(body: str, cell_name: str):
    """The cell as placed for the body, its painted surface, the [collision] settings, and each robot's work as
    first solved (``cells.plan``'s steps up to the kinematics, no repairs)."""
    from sprayplan.cells import load_cell
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.plan import SEAM_STEP_MM, SeamGuard, _robot_work, area_surface
    from sprayplan.cells.reach import reach_matrix, reach_tilts
    from sprayplan.cells.spec import place_part
    from sprayplan.coating.stage import meet_thickness
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.areas import assign_areas, segment_areas
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import painted_surface

    name, load = BODIES[body]
    part = load_part(str(meshes_dir() / name), **load)
    job = JobConfig().replace(coating={"thickness_um": 50.0}, collision={"check": True})
    placed = place_part(part, load_cell(cell_name))
    cell = placed.cell
    painted, _ = painted_surface(oriented_part(placed.part), job.collision)
    painted, _ = area_surface(painted)
    job, _ = meet_thickness(job)
    arms = cell_arms(cell, painted, job.collision)
    areas = segment_areas(painted)
    tilts = reach_tilts(job.collision.piece_tilt_deg)
    reach = reach_matrix(cell, painted, areas.face_normals, job.paths.standoff_mm, arms=arms, tilts_deg=tilts)
    assignment = assign_areas(areas, painted.face_areas, reach)
    labels = len(cell.robots) + 1
    guard = SeamGuard(painted, areas.face_area * labels + assignment.face_robot + 1, areas.face_normals, SEAM_STEP_MM)
    works = [_robot_work(r, i, painted, areas, assignment, job, guard) for i, r in enumerate(cell.robots)]
    return cell, painted, job, arms, areas, works


def first_collisions(arms, areas, works) -> dict:
    """Per robot: spray waypoints, those in collision as first solved, by body and what it meets, and by area."""
    from sprayplan.collision.arms import check_robot

    out = {}
    for work, arm in zip(works, arms):
        found = check_robot(arm, work.q, work.track_mm, work.reachable)
        starts = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
        total, hit = collections.Counter(), collections.Counter()
        for i, s in enumerate(work.strokes):
            if s.spray_on:
                name = areas.names[work.area[i]]
                total[name] += len(s)
                hit[name] += int(found.waypoint.collides[starts[i] : starts[i + 1]].sum())
        out[work.name] = {
            "spray_waypoints": sum(total.values()),
            "in_collision": sum(hit.values()),
            "by_pair": found.summary()["in_collision_by_pair"],
            "by_area": {k: [total[k], hit[k]] for k in total},
        }
    return out


def free_shares(cell, index: int, arm, strokes) -> tuple[float, float]:
    """(reached, free): the shares of the strokes' waypoints some (track, roll, branch) try of robot ``index``
    reaches, and reaches free."""
    from sprayplan.cells.tries import rot_z, stroke_tries
    from sprayplan.surface.poses import stroke_poses

    cell_robot = cell.robots[index]
    robot = cell_robot.robot(0.0)
    axis = np.zeros(3) if cell_robot.track is None else cell_robot.track.axis
    total = reached = free = 0
    for s in strokes:
        poses = stroke_poses(s)
        got, hit = np.zeros(len(s), bool), np.zeros(len(s), bool)
        for t, roll in stroke_tries(cell_robot, s):
            moved = poses @ rot_z(roll)
            moved[:, :3, 3] -= t[:, None] * axis
            sol = robot.ik(moved)
            for b in range(sol.valid.shape[1]):
                ok = sol.valid[:, b] & ~got
                hit |= sol.valid[:, b]
                if ok.any():
                    rows = np.flatnonzero(ok)
                    got[rows[~arm.collides(sol.q[rows, b], t[rows])]] = True
        total += len(s)
        reached += int(hit.sum())
        free += int(got.sum())
    return reached / max(total, 1), free / max(total, 1)


def base_parser(doc: str, values: str) -> argparse.ArgumentParser:
    """The options of a bench that moves one robot's base: ``--body``, ``--cell``, ``--robot``, ``--axis``,
    ``--values`` (``values`` their default)."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--body", default="suv", choices=sorted(BODIES))
    parser.add_argument("--cell", default="line3")
    parser.add_argument("--robot", default="roof")
    parser.add_argument("--axis", default="z", choices=("x", "y", "z"))
    parser.add_argument("--values", default=values, help="base coordinates along --axis, mm")
    return parser


def robot_index(cell, name: str) -> int:
    """The index of robot ``name`` in ``cell`` (exit with a message when it has none)."""
    names = [r.name for r in cell.robots]
    if name not in names:
        raise SystemExit(f"--robot: {name!r} is not a robot of {cell.name} ({', '.join(names)})")
    return names.index(name)


def moved_cell(cell, index: int, axis: int, value: float):
    """``cell`` with robot ``index``'s base at ``value`` mm along cell axis ``axis`` (its lift dropped)."""
    moved = cell.robots[index].base2cell.copy()
    moved[axis, 3] = value
    robots = list(cell.robots)
    robots[index] = dataclasses.replace(robots[index], base2cell=moved, lift=None)
    return dataclasses.replace(cell, robots=tuple(robots))


def main() -> None:
    from sprayplan.cells.collide import cell_arms

    parser = base_parser(__doc__, "3700,3900,4100")
    parser.add_argument("--strokes", type=int, default=60)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    cell, painted, job, arms, areas, works = planned(args.body, args.cell)
    names = [r.name for r in cell.robots]
    index = robot_index(cell, args.robot)
    base = cell.robots[index].base2cell[:3, 3]
    print(json.dumps({"body": args.body, "cell": cell.name, "as_placed": {n: r.base2cell[:3, 3].round(1).tolist()
                      for n, r in zip(names, cell.robots)}, "first": first_collisions(arms, areas, works)}),
          flush=True)  # fmt: skip
    work = works[index]
    spray = [s for s in work.strokes if s.spray_on]
    rng = np.random.default_rng(args.seed)
    picked = [spray[k] for k in rng.choice(len(spray), min(args.strokes, len(spray)), replace=False)]
    axis = "xyz".index(args.axis)
    for value in (float(v) for v in args.values.split(",")):
        at = moved_cell(cell, index, axis, value)
        arm = cell_arms(at, painted, job.collision)[index]
        reached, free = free_shares(at, index, arm, picked)
        print(json.dumps({"robot": args.robot, args.axis: value, "as_placed": float(base[axis]),
                          "waypoints": sum(len(s) for s in picked), "reached": round(reached, 3),
                          "free": round(free, 3)}), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
