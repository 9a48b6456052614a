"""Benchmark of the OPW inverse kinematics (all 8 branches) against the UR solver on the same number of poses.

Each solver gets n random reachable poses (forward kinematics of joint vectors drawn uniformly: within the
preset's joint limits for the OPW arms, in +-2 pi for the UR5) and solves them in one call; the runs of the
solvers are interleaved (UR, then each OPW arm, ``--repeat`` rounds) so that a busy machine slows them alike,
and the table gives each one's median. Two levels are timed:

- the bare solvers, ``ur_ik`` (branches and validity) and ``opw_ik`` (branches, validity, joint limits with
  turns and a reason string per branch);
- the robot interface, ``URArm.ik`` and ``OPWArm.ik`` (pose checks, base and TCP, reasons for both).

Every result is checked: fk of each valid branch of the first 20,000 poses against its pose, and the share of
poses whose generating joints are among the valid solutions.

Usage::

    python bench/bench_opw.py [--poses 200000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from sprayplan.robots.interface import robot_from_name
from sprayplan.robots.model import fk, load_robot
from sprayplan.robots.opw import PRESETS, load_opw, opw_fk, opw_ik
from sprayplan.robots.ur_ik import ur_ik

COMMAND = "python bench/bench_opw.py"
CHECK = 20_000


def rotation_angle(r_a, r_b):
    e = np.einsum("nji,njk->nik", r_a, r_b)
    v = np.stack([e[:, 2, 1] - e[:, 1, 2], e[:, 0, 2] - e[:, 2, 0], e[:, 1, 0] - e[:, 0, 1]], axis=1) / 2
    return np.arctan2(np.linalg.norm(v, axis=1), (np.trace(e, axis1=1, axis2=2) - 1) / 2)


def in_chunks(function, q, size=100_000):
    return np.concatenate([function(q[i : i + size]) for i in range(0, len(q), size)])


def check(fk_of, q_true, poses, q, valid) -> dict:
    """fk error of every valid branch of the first CHECK poses; generating joints found (modulo 2 pi)."""
    part = slice(0, CHECK)
    rows, cols = np.nonzero(valid[part])
    got = fk_of(q[part][rows, cols])
    pos = float(np.linalg.norm(got[:, :3, 3] - poses[part][rows, :3, 3], axis=1).max())
    rot = float(rotation_angle(got[:, :3, :3], poses[part][rows, :3, :3]).max())
    turned = np.abs((q - q_true[:, None, :] + math.pi) % (2 * math.pi) - math.pi).max(axis=-1)
    found = float(((turned < 1e-7) & valid).any(axis=1).mean())
    return {"pos": pos, "rot": rot, "found": found, "valid": float(valid.sum(axis=1).mean())}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=200_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    n = args.poses
    rng = np.random.default_rng(1)

    ur = load_robot("ur5")
    cases = {}  # label -> (solve, fk of joints, q_true, poses)
    q_ur = rng.uniform(-2 * math.pi, 2 * math.pi, (n, 6))
    poses_ur = in_chunks(lambda q: fk(ur, q), q_ur)
    cases["`ur_ik` ur5"] = (lambda p: ur_ik(ur, p), lambda q: fk(ur, q), q_ur, poses_ur)
    for name in PRESETS:
        params = load_opw(name)
        q = rng.uniform(params.lower, params.upper, (n, 6))
        poses = in_chunks(lambda q, params=params: opw_fk(params, q), q)
        cases[f"`opw_ik` {name}"] = (
            lambda p, params=params: opw_ik(params, p),
            lambda q, params=params: opw_fk(params, q),
            q,
            poses,
        )
    for name, q, poses in (("ur5", q_ur, poses_ur), ("abb-irb2400-10", *cases["`opw_ik` abb-irb2400-10"][2:])):
        robot = robot_from_name(name)
        kind = "URArm" if name == "ur5" else "OPWArm"
        cases[f"`{kind}.ik` {name}"] = (robot.ik, robot.fk, q, poses)

    times = {label: [] for label in cases}
    cpu = {label: [] for label in cases}
    results = {}
    for _ in range(args.repeat):
        for label, (solve, _fk, _q, poses) in cases.items():
            results[label] = None  # free the previous result first
            start, start_cpu = time.perf_counter(), time.process_time()
            results[label] = solve(poses)
            times[label].append(time.perf_counter() - start)
            cpu[label].append(time.process_time() - start_cpu)
    checks = {label: check(c[1], c[2], c[3], results[label].q, results[label].valid) for label, c in cases.items()}

    print("# OPW inverse kinematics\n")
    extra = argv if argv is not None else sys.argv[1:]
    print(f"Reproduce: `{' '.join([COMMAND, *extra])}`")
    print(
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"numpy {np.__version__}; load average {os.getloadavg()[0]:.1f} at the end"
    )
    print(f"Poses: {n:,} per solver, fk of random joints (seed 1); runs interleaved, median of {args.repeat}.\n")
    print(
        "| solver | median time (s) | poses/s | vs UR | median CPU time (s) | CPU vs UR | valid branches per pose "
        "| generating q found | fk error (mm, rad) |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |")
    for label in cases:
        ref = "`URArm.ik` ur5" if ".ik`" in label else "`ur_ik` ur5"
        median, median_cpu = statistics.median(times[label]), statistics.median(cpu[label])
        ratio = statistics.median(times[ref]) / median
        ratio_cpu = statistics.median(cpu[ref]) / median_cpu
        c = checks[label]
        print(
            f"| {label} | {median:.3f} | {n / median:,.0f} | {ratio:.2f} | {median_cpu:.3f} | {ratio_cpu:.2f} | "
            f"{c['valid']:.2f} | {100 * c['found']:.3f} % | {c['pos']:.1e}, {c['rot']:.1e} |"
        )
    print()
    print(
        "vs UR: poses/s over the UR solver's at the same level (`ur_ik` for the bare solvers, `URArm.ik` for the "
        "interface rows); CPU: process time, less disturbed by other work on the machine than the wall clock."
    )
    for label in cases:
        print(
            f"- {label} runs (s): {', '.join(f'{t:.3f}' for t in times[label])}; "
            f"CPU {', '.join(f'{t:.3f}' for t in cpu[label])}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
