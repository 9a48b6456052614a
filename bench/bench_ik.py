"""Benchmark of the closed-form UR5 inverse kinematics (all 8 branches) against robotics-toolbox-python.

sprayplan's ``ur_ik`` solves 1,000,000 random reachable poses (``fk`` of joint vectors uniform in +-2 pi) in
one call, 5 times; the table gives the median. robotics-toolbox-python (a development-only comparison, not a
dependency: ``pip install roboticstoolbox-python``) solves a subset of 2,000 of the same poses with its analytic
solver for the same D-H table (``DHRobot.analytic_ik().solve``: all solutions of one pose per call); if it is
missing, the table says so. If it has no analytic solver, its numerical ``ikine_LM`` (one solution per pose)
is timed instead and labelled as such. Both results are checked: fk of every valid branch against its pose,
and the solution sets of the two libraries against each other.

Usage::

    python bench/bench_ik.py [--poses 1000000] [--repeat 5] [--rtb-poses 2000] [--path-poses 100000]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from sprayplan.robots.model import fk, load_robot
from sprayplan.robots.ur_ik import ik_path, ur_ik

COMMAND = "python bench/bench_ik.py"


def random_poses(model, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n joint vectors uniform in +-2 pi and their flange poses (fk in chunks, to bound memory)."""
    q = np.random.default_rng(seed).uniform(-2 * math.pi, 2 * math.pi, (n, 6))
    poses = np.empty((n, 4, 4))
    for start in range(0, n, 100_000):
        poses[start : start + 100_000] = fk(model, q[start : start + 100_000])
    return q, poses


def pose_error(model, q: np.ndarray, poses: np.ndarray) -> tuple[float, float]:
    """Largest position (mm) and rotation (rad) error of fk(q) against the poses."""
    got = fk(model, q)
    pos = np.linalg.norm(got[:, :3, 3] - poses[:, :3, 3], axis=1)
    e = np.einsum("nji,njk->nik", got[:, :3, :3], poses[:, :3, :3])
    v = np.stack([e[:, 2, 1] - e[:, 1, 2], e[:, 0, 2] - e[:, 2, 0], e[:, 1, 0] - e[:, 0, 1]], axis=1) / 2
    rot = np.arctan2(np.linalg.norm(v, axis=1), (np.trace(e, axis1=1, axis2=2) - 1) / 2)
    return float(pos.max()), float(rot.max())


def same_angles(a: np.ndarray, b: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """Rows of a and b equal up to whole turns."""
    return (np.abs((a - b + math.pi) % (2 * math.pi) - math.pi) < tol).all(axis=-1)


def bench_sprayplan(model, poses, q_true, repeat: int) -> dict:
    times = []
    sols = None
    for _ in range(repeat):
        sols = None  # free the previous result before the next run
        start = time.perf_counter()
        sols = ur_ik(model, poses)
        times.append(time.perf_counter() - start)
    check = slice(0, 20_000)
    rows, cols = np.nonzero(sols.valid[check])
    pos, rot = pose_error(model, sols.q[check][rows, cols], poses[check][rows])
    found = (same_angles(sols.q, q_true[:, None, :]) & sols.valid).any(axis=1).mean()
    return {
        "median_s": statistics.median(times),
        "times": times,
        "valid_per_pose": float(sols.valid.sum(axis=1).mean()),
        "found": float(found),
        "pos_err": pos,
        "rot_err": rot,
        "sols": sols,
    }


def rtb_robot(model):
    """A robotics-toolbox DHRobot with the model's D-H table (metres) and joint limits."""
    import roboticstoolbox as rtb

    links = [
        rtb.RevoluteDH(
            d=model.d[i] / 1000.0,
            a=model.a[i] / 1000.0,
            alpha=model.alpha[i],
            offset=model.theta_offset[i],
            qlim=[model.lower[i], model.upper[i]],
        )
        for i in range(6)
    ]
    return rtb.DHRobot(links, name=model.name)


def bench_rtb(model, poses, mine) -> dict:
    """Time robotics-toolbox on the poses; compare its solution sets with ours."""
    try:
        import roboticstoolbox as rtb
    except ImportError as exc:
        return {"error": f"roboticstoolbox-python is not installed ({exc}); pip install roboticstoolbox-python"}
    robot = rtb_robot(model)
    poses_m = poses.copy()
    poses_m[:, :3, 3] /= 1000.0
    out = {"version": rtb.__version__}
    if not hasattr(robot, "analytic_ik"):
        return out | bench_rtb_lm(robot, model, poses_m, poses)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. "python-flint is not installed" (slower derivation only)
        start = time.perf_counter()
        solver = robot.analytic_ik()
        out["derive_s"] = time.perf_counter() - start
    start = time.perf_counter()
    results = [solver.solve(t) for t in poses_m]
    out["time_s"] = time.perf_counter() - start
    out["method"] = "analytic (`DHRobot.analytic_ik().solve`, all solutions)"
    # agreement: every rtb solution is one of our valid branches, and the counts match
    counts_equal = 0
    rtb_in_ours = 0
    rtb_total = 0
    rtb_only, ours_only = [], []  # (pose index, q) of the solutions only one library found
    for i, res in enumerate(results):
        q_rtb = np.atleast_2d(np.asarray(res.q, dtype=float)) if res.success else np.zeros((0, 6))
        ours = mine.q[i][mine.valid[i]]
        ours_unique = [row for k, row in enumerate(ours) if not any(same_angles(row, ours[:k]))]
        counts_equal += len(q_rtb) == len(ours_unique)
        for row in q_rtb:
            rtb_total += 1
            if len(ours) and same_angles(row, ours).any():
                rtb_in_ours += 1
            else:
                rtb_only.append((i, row))
        ours_only += [(i, row) for row in ours_unique if not (len(q_rtb) and same_angles(row, q_rtb).any())]
    out["counts_equal"] = counts_equal / len(results)
    out["rtb_in_ours"] = rtb_in_ours / max(rtb_total, 1)
    out["solutions_per_pose"] = rtb_total / len(results)
    for key, found in (("rtb_only", rtb_only), ("ours_only", ours_only)):
        if found:
            idx = np.array([i for i, _ in found])
            q = np.array([row for _, row in found])
            out[key] = (len(found), *pose_error(model, q, poses[idx]))
    return out


def bench_rtb_lm(robot, model, poses_m, poses) -> dict:
    """Fallback: robotics-toolbox's numerical ikine_LM, one solution per pose."""
    n = min(len(poses_m), 200)
    start = time.perf_counter()
    results = [robot.ikine_LM(t) for t in poses_m[:n]]
    elapsed = time.perf_counter() - start
    ok = np.array([r.success for r in results])
    q = np.array([r.q for r in results])
    pos, rot = pose_error(model, q[ok], poses[:n][ok]) if ok.any() else (math.nan, math.nan)
    return {
        "time_s": elapsed,
        "n": n,
        "method": "NUMERICAL `ikine_LM` (no analytic UR5 solver in this version), one solution per pose",
        "success": float(ok.mean()),
        "pos_err": pos,
        "rot_err": rot,
    }


def bench_path(model, n: int) -> float:
    """Seconds for ik_path along a smooth random walk of n waypoints."""
    rng = np.random.default_rng(2)
    q = np.cumsum(rng.normal(0, 0.01, (n, 6)), axis=0) + np.array([0.4, -1.3, 1.7, -1.9, -1.4, 0.6])
    poses = fk(model, q)
    start = time.perf_counter()
    ik_path(model, poses, seed_q=q[0])
    return time.perf_counter() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--rtb-poses", type=int, default=2000)
    parser.add_argument("--path-poses", type=int, default=100_000)
    args = parser.parse_args(argv)

    model = load_robot("ur5")
    q_true, poses = random_poses(model, args.poses, seed=1)
    mine = bench_sprayplan(model, poses, q_true, args.repeat)
    mine_rate = args.poses / mine["median_s"]
    n_rtb = min(args.rtb_poses, args.poses)
    sub = type(mine["sols"])(
        q=mine["sols"].q[:n_rtb], valid=mine["sols"].valid[:n_rtb], wrist_singular=mine["sols"].wrist_singular[:n_rtb]
    )
    rtb = bench_rtb(model, poses[:n_rtb], sub)
    path_s = bench_path(model, args.path_poses) if args.path_poses else math.nan

    print("# UR5 inverse kinematics, all branches\n")
    extra = argv if argv is not None else sys.argv[1:]
    print(f"Reproduce: `{' '.join([COMMAND, *extra])}`")
    print(
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"numpy {np.__version__}" + (f", robotics-toolbox-python {rtb['version']}" if "version" in rtb else "")
    )
    print("Poses: fk of joint vectors uniform in +-2 pi (seed 1), UR5 preset table (mm).\n")
    print("| solver | poses | solutions | median time (s) | poses/s | vs robotics-toolbox |")
    print("| --- | ---: | --- | ---: | ---: | ---: |")
    rtb_rate = None
    if "time_s" in rtb:
        n_done = rtb.get("n", n_rtb)
        rtb_rate = n_done / rtb["time_s"]
    ratio = f"{mine_rate / rtb_rate:,.0f} x" if rtb_rate else "n/a"
    print(
        f"| sprayplan `ur_ik` (numpy, vectorised) | {args.poses:,} | all 8 branches | {mine['median_s']:.3f} "
        f"| {mine_rate:,.0f} | {ratio} |"
    )
    if rtb_rate:
        print(
            f"| robotics-toolbox {rtb['method']} | {rtb.get('n', n_rtb):,} | "
            f"{'all' if 'analytic' in rtb['method'] else 'one'} | {rtb['time_s']:.3f} (1 run) | {rtb_rate:,.0f} | 1 x |"
        )
    else:
        print(f"| robotics-toolbox | - | - | - | - | {rtb['error']} |")
    if args.path_poses:
        print(
            f"| sprayplan `ik_path` (ur_ik + sequential branch choice) | {args.path_poses:,} | one per waypoint "
            f"| {path_s:.3f} (1 run) | {args.path_poses / path_s:,.0f} | |"
        )
    print()
    print(f"- sprayplan runs (s): {', '.join(f'{t:.3f}' for t in mine['times'])}")
    print(
        f"- sprayplan checks: {mine['valid_per_pose']:.2f} valid branches per pose; generating q found in "
        f"{100 * mine['found']:.3f} % of poses; fk of every valid branch of the first 20,000 poses within "
        f"{mine['pos_err']:.1e} mm and {mine['rot_err']:.1e} rad"
    )
    if "derive_s" in rtb:
        print(
            f"- robotics-toolbox: one-off symbolic derivation {rtb['derive_s']:.1f} s (not timed above); "
            f"{rtb['solutions_per_pose']:.2f} solutions per pose; {100 * rtb['rtb_in_ours']:.2f} % of its "
            f"solutions are among sprayplan's valid branches; same number of distinct solutions for "
            f"{100 * rtb['counts_equal']:.2f} % of poses"
        )
        for key, who in (("ours_only", "found by sprayplan only"), ("rtb_only", "found by robotics-toolbox only")):
            if key in rtb:
                count, pos, rot = rtb[key]
                print(f"- {count} solutions {who}: largest fk error {pos:.1e} mm, {rot:.1e} rad")
    elif "success" in rtb:
        print(f"- robotics-toolbox ikine_LM: success {100 * rtb['success']:.1f} %, fk error {rtb['pos_err']:.1e} mm")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
