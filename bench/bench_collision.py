"""Collision checks (issue 16, part 1): coal against python-fcl, same bodies, same queries, one run.

    PYTHONPATH=src python bench/bench_collision.py [--runs 5] [--sample 400]

For the demo roof (``z > 1000``) and the reach part (``x > -250``), each planned to the kinematics stage:

- distance queries per second of the arm's eight link capsules and the gun's capsule against the part's
  mesh (a BVH in both libraries: coal's OBB-RSS, fcl's default OBB-RSS), at ``--sample`` reachable
  waypoints spread over the plan, median of ``--runs`` runs, and the two libraries' largest disagreement;
- the same nine queries at every waypoint of the plan (the part pairs of a waypoint check), both libraries;
- ``CellCollision.check_waypoints`` (coal; every pair: part, floor, gantry and gun pairs) and
  ``check_motions`` on the reach plan;
- the installed size of each library with the packages it pulls in (from the wheels' file lists).

python-fcl is imported only here, optionally: without it the coal figures are still printed.
"""

from __future__ import annotations

import argparse
import importlib.metadata as md
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sprayplan.collision.cell import CellCollision
from sprayplan.config import JobConfig
from sprayplan.demo import DEMO_REGION, car_roof
from sprayplan.io.load import load_part
from sprayplan.job import run_job
from sprayplan.robots.gantry import build_gantry
from sprayplan.surface.region import select_region

try:
    import fcl
except ImportError:  # pragma: no cover
    fcl = None
import coal

REPO = Path(__file__).resolve().parents[1]


def installed_mb(name: str, seen: set | None = None) -> float:
    """MB of a distribution's installed files and of every distribution it requires (each counted once)."""
    seen = set() if seen is None else seen
    key = name.lower().replace("_", "-")
    if key in seen:
        return 0.0
    seen.add(key)
    try:
        dist = md.distribution(name)
    except md.PackageNotFoundError:
        return 0.0
    total = 0
    for f in dist.files or ():
        path = Path(dist.locate_file(f))
        if path.is_file():
            total += path.stat().st_size
    for req in dist.requires or ():
        if "extra ==" in req:
            continue
        dep = re.split(r"[ ;<>=!~\[(]", req, maxsplit=1)[0]
        if dep.lower() not in {"numpy"}:
            total += installed_mb(dep, seen) * 1e6
    return total / 1e6


def plans():
    roof = run_job(car_roof(), JobConfig().replace(load={"region": DEMO_REGION}), until="kinematics")
    reach_path = REPO / "tests" / "data" / "meshes" / "reach_curved_part.ply"
    job = JobConfig().replace(load={"units": "m", "region": "x > -250"})
    reach = run_job(reach_path, job, until="kinematics")
    reach_part = select_region(load_part(reach_path, units="m"), "x > -250")
    return [("demo roof (z > 1000)", roof.part, roof.plan), ("reach part (x > -250)", reach_part, reach.plan)]


class CoalQueries:
    def __init__(self, cell: CellCollision):
        self.mesh = cell._mesh
        self.capsules = [coal.Capsule(b.radius_mm, b.length_mm) for b in cell.capsules]
        self.request = coal.DistanceRequest()
        self.identity = coal.Transform3s()

    def run(self, poses: np.ndarray) -> np.ndarray:
        out = np.empty(poses.shape[:2])
        for i, row in enumerate(poses):
            for j, pose in enumerate(row):
                tf = coal.Transform3s(pose[:3, :3], pose[:3, 3])
                out[i, j] = coal.distance(
                    self.capsules[j], tf, self.mesh, self.identity, self.request, coal.DistanceResult()
                )
        return out


class FclQueries:
    def __init__(self, cell: CellCollision, part):
        model = fcl.BVHModel()
        model.beginModel(len(part.vertices), len(part.faces))
        model.addSubModel(np.asarray(part.vertices, float), np.asarray(part.faces, np.int32))
        model.endModel()
        self.mesh = fcl.CollisionObject(model, fcl.Transform())
        self.capsules = [
            fcl.CollisionObject(fcl.Capsule(b.radius_mm, b.length_mm), fcl.Transform()) for b in cell.capsules
        ]
        self.request = fcl.DistanceRequest()

    def run(self, poses: np.ndarray) -> np.ndarray:
        out = np.empty(poses.shape[:2])
        for i, row in enumerate(poses):
            for j, pose in enumerate(row):
                body = self.capsules[j]
                body.setTransform(fcl.Transform(pose[:3, :3], pose[:3, 3]))
                out[i, j] = fcl.distance(body, self.mesh, self.request, fcl.DistanceResult())
        return out


FCL_FLOOR = """
import numpy as np, fcl
capsule = fcl.CollisionObject(fcl.Capsule(10.0, 100.0), fcl.Transform(np.eye(3), np.array([0.0, 0.0, 200.0])))
floor = fcl.CollisionObject(fcl.{shape}(np.array([0.0, 0.0, 1.0]), 0.0), fcl.Transform())
print(fcl.distance(capsule, floor, fcl.DistanceRequest(), fcl.DistanceResult()))
"""


def fcl_floor_query(shape: str) -> str:
    """python-fcl's capsule-vs-``shape`` (Plane, Halfspace) distance in a child process: its answer or how it died
    (the exact answer is 140 mm)."""
    done = subprocess.run([sys.executable, "-c", FCL_FLOOR.format(shape=shape)], capture_output=True, text=True)
    if done.returncode < 0:
        return f"killed by signal {-done.returncode}"
    return done.stdout.strip() or done.stderr.strip().splitlines()[-1]


def timed(fn, runs: int, *args):
    times, result = [], None
    for _ in range(runs):
        t = time.perf_counter()
        result = fn(*args)
        times.append(time.perf_counter() - t)
    return statistics.median(times), result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--sample", type=int, default=400)
    args = parser.parse_args(argv)
    gantry = build_gantry("ur5")
    print(f"coal {md.version('coal')}, python-fcl {md.version('python-fcl') if fcl else 'not installed'}")
    print("| part | triangles | waypoints | coal queries/s | fcl queries/s | coal/fcl | max abs diff mm |")
    rows = []
    for name, part, plan in plans():
        cell = CellCollision(gantry, part)
        q9 = np.concatenate([s.q9 for s in plan.stations])
        reachable = np.concatenate([s.reachable for s in plan.stations])
        q_ok = q9[reachable]
        pick = np.linspace(0, len(q_ok) - 1, min(args.sample, len(q_ok))).astype(int)
        poses = cell.body_poses(q_ok[pick])[:, : len(cell.capsules)]
        coal_q = CoalQueries(cell)
        t_coal, d_coal = timed(coal_q.run, args.runs, poses)
        rate_coal = poses.shape[0] * poses.shape[1] / t_coal
        if fcl is not None:
            fcl_q = FclQueries(cell, part)
            t_fcl, d_fcl = timed(fcl_q.run, args.runs, poses)
            rate_fcl = poses.shape[0] * poses.shape[1] / t_fcl
            both = (d_coal > 0) & (d_fcl > 0)
            diff = float(np.abs(d_coal - d_fcl)[both].max()) if both.any() else float("nan")
            signs = int(((d_coal <= 0) != (d_fcl <= 0)).sum())
            fcl_text = f"{rate_fcl:,.0f} | {rate_coal / rate_fcl:.2f} | {diff:.1e} ({signs} sign disagreements)"
        else:
            fcl_text = "- | - | -"
        print(f"| {name} | {len(part.faces)} | {len(q9)} | {rate_coal:,.0f} | {fcl_text} |", flush=True)
        rows.append((name, cell, plan, q_ok, part))
    print()
    print(
        "| part | reachable waypoints | part queries, coal s | part queries, fcl s | check_waypoints (coal, all pairs) s | in collision |"
    )
    runs = max(1, min(3, args.runs))
    for name, cell, plan, q_ok, part in rows:
        poses = cell.body_poses(q_ok)[:, : len(cell.capsules)]
        t_coal, _ = timed(CoalQueries(cell).run, runs, poses)
        if fcl is not None:
            fcl_q = FclQueries(cell, part)
            t_fcl_text = f"{timed(fcl_q.run, runs, poses)[0]:.2f}"
        else:
            t_fcl_text = "-"
        t_check, result = timed(cell.check_waypoints, runs, plan)
        pairs = {}
        for a, b in zip(result.body_a[result.in_collision], result.body_b[result.in_collision]):
            pairs[f"{a}-{b}"] = pairs.get(f"{a}-{b}", 0) + 1
        top = ", ".join(f"{k} {v}" for k, v in sorted(pairs.items(), key=lambda kv: -kv[1])[:4])
        print(
            f"| {name} | {len(q_ok)} | {t_coal:.2f} | {t_fcl_text} | {t_check:.2f} | {result.count} ({top}) |",
            flush=True,
        )
    name, cell, plan, _, _ = rows[-1]
    t_motion, motions = timed(cell.check_motions, 1, plan)
    print()
    print(
        f"check_motions, {name}: {len(motions)} motions, {int(motions.checks.sum())} checks, "
        f"{motions.count} in collision, {t_motion:.2f} s (one run)"
    )
    print()
    if fcl is not None:
        answers = ", ".join(f"{shape} {fcl_floor_query(shape)}" for shape in ("Plane", "Halfspace"))
        print(f"python-fcl capsule-vs-floor distance (exact: 140 mm): {answers}")
        capsule = coal.Capsule(10.0, 100.0)
        lifted = coal.Transform3s(np.eye(3), np.array([0.0, 0.0, 200.0]))
        floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
        found = coal.distance(capsule, lifted, floor, coal.Transform3s(), coal.DistanceRequest(), coal.DistanceResult())
        print(f"coal capsule-vs-Halfspace distance: {found}")
    print(f"installed: coal with its requirements {installed_mb('coal'):.0f} MB", end="")
    if fcl is not None:
        cython = installed_mb("Cython")
        print(
            f"; python-fcl {installed_mb('python-fcl', {'cython'}):.0f} MB (+ Cython {cython:.0f} MB, a declared requirement)"
        )
    else:
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
