"""Where a cell plan's film is short, could any robot paint there at all? (issue 18: 95 % in spec)

Reads a cell plan's ``thickness.csv`` (x, y, z, thickness), draws samples below spec at random, and gives each
the gun on the surface's outward normal at the standoff; then every robot of the cell tries it at every track
position (``--track-step`` apart over the track's range), every roll of ``cells.tries.ROLL_TRIES_DEG`` and
every IK branch, checked against the part and the floor (``collision.arms.ArmCollision.collides``). Those no
robot reaches free are tried again with the gun tilted round its target (``cells.reach.reach_tilts``: half of
``--tilt-deg`` and all of it, either way, about the pose's x then y axis). The shares say how much of the
deficit the cell itself cannot paint (no free pose) and how much the planning loses (docs/benchmarks.md,
"Session 18").

    python bench/bench_film_reach.py OUT/thickness.csv --body bmw [--cell line3] [--samples 1500]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import meshes_dir  # noqa: E402
from bench_cell_collisions import BODIES  # noqa: E402


def reached_free(cell, arms, poses: np.ndarray, track_step_mm: float, todo: np.ndarray) -> np.ndarray:
    """(n,) bool: the poses of ``todo`` that some robot reaches with every body free at some track position,
    roll and branch."""
    from sprayplan.cells.tries import ROLL_TRIES_DEG, rot_z

    got = ~todo.copy()
    reached = np.zeros(len(poses), bool)
    for cell_robot, arm in zip(cell.robots, arms):
        robot = cell_robot.robot(0.0)
        if cell_robot.track is None:
            axis, positions = np.zeros(3), np.zeros(1)
        else:
            lo, hi = cell_robot.track.range_mm
            axis, positions = np.asarray(cell_robot.track.axis, float), np.arange(lo, hi + 1e-9, track_step_mm)
        for t in positions:
            for roll in ROLL_TRIES_DEG:
                moved = poses @ rot_z(roll)
                moved[:, :3, 3] -= t * axis
                found = robot.ik(moved)
                for b in range(found.valid.shape[1]):
                    reached |= found.valid[:, b]
                    rows = np.flatnonzero(found.valid[:, b] & ~got)
                    if len(rows):
                        hit = arm.collides(found.q[rows, b], np.full(len(rows), t))
                        got[rows[~hit]] = True
    return got & todo, reached


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("thickness", help="a cell plan's thickness.csv")
    parser.add_argument("--body", choices=sorted(BODIES), default="bmw")
    parser.add_argument("--cell", default="line3")
    parser.add_argument("--samples", type=int, default=1500)
    parser.add_argument("--track-step", type=float, default=250.0, help="mm between the track positions tried")
    parser.add_argument("--tilt-deg", type=float, default=40.0)
    parser.add_argument("--low-um", type=float, default=45.0, help="below this is below spec")
    args = parser.parse_args()

    import trimesh

    from sprayplan.cells import load_cell
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.reach import reach_tilts, tilted_poses
    from sprayplan.cells.spec import place_part
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.normals import part_outward
    from sprayplan.surface.poses import poses_at

    started = time.perf_counter()
    name, load = BODIES[args.body]
    cell = load_cell(args.cell)
    part = place_part(load_part(str(meshes_dir() / name), **load), cell).part
    faces, normals = part_outward(part)
    mesh = trimesh.Trimesh(part.vertices, faces, process=False)
    data = np.loadtxt(args.thickness, delimiter=",", skiprows=1, ndmin=2)
    below = np.flatnonzero(data[:, 3] < args.low_um)
    picked = np.random.default_rng(0).choice(below, min(args.samples, len(below)), replace=False)
    points = data[picked, :3]
    _, _, face = trimesh.proximity.closest_point(mesh, points)
    n = normals[face]
    job = JobConfig()
    standoff = job.paths.standoff_mm
    poses = poses_at(points + standoff * n, n)
    arms = cell_arms(cell, part, job.collision)
    everything = np.ones(len(poses), bool)
    free, reached = reached_free(cell, arms, poses, args.track_step, everything)
    untilted = free.copy()
    for axis, angle in reach_tilts(args.tilt_deg):
        todo = ~free
        if not todo.any():
            break
        tilted = tilted_poses(poses, standoff, axis, angle)
        more, _ = reached_free(cell, arms, tilted, args.track_step, todo)
        free |= more
    share_below = len(below) / len(data)
    directions = {
        "up": n[:, 2] > 0.5,
        "down": n[:, 2] < -0.5,
        "ends": np.abs(n[:, 0]) > 0.5,
        "sides": np.abs(n[:, 1]) > 0.5,
    }
    result = {
        "samples": len(data),
        "below_spec": round(share_below, 4),
        "probed": len(picked),
        "reached_untilted": round(float(reached.mean()), 4),
        "reached_free_untilted": round(float(untilted.mean()), 4),
        "reached_free_tilted": round(float(free.mean()), 4),
        "below_spec_and_never_free": round(share_below * (1 - float(free.mean())), 4),
        "by_direction": {
            key: {"share": round(float(m.mean()), 3), "free_untilted": round(float(untilted[m].mean()), 3)}
            for key, m in directions.items()
            if m.any()
        },
        "seconds": round(time.perf_counter() - started, 1),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
