"""Timing within the joints' limits (issue 16, section 4): the timing stage's cost and the cycle time it finds.

    PYTHONPATH=src python bench/bench_timing.py [--runs 3] [--parts roof,reach,suv]
    PYTHONPATH=src python bench/bench_timing.py --parts roof --stations 1 --runs 1 --max-rounds 6,2,1

    PYTHONPATH=src python bench/bench_timing.py --parts roof --runs 3 --base ../wt-speed-base

Each part is planned once to the kinematics stage with the default settings (``sprayplan plan``'s), then the
timing stage (``timing.stage.time_plan``) runs ``--runs`` times on that plan: the median wall time, the time
per 1000 waypoints, the cycle time by length over speed (the totals' ``cycle_time_length_over_speed_s``) and
the timed one (``cycle_time_s``) side by side with their ratio, the timed cycle's parts, and how many spray
waypoints the limits keep below their planned tip speed. Parts: the demo roof (``sprayplan demo``: the car
roof cut at z > 1000), the reach part (whole, in metres) and the SUV body (whole, in metres; a larger part).

With ``--base DIR`` the timing stage of this checkout and of another one (``DIR/src``, e.g. the commit before a
change) time the same plan (planned once here, pickled) in fresh processes, started at the same time in pairs
so that both see the same load, ``--runs`` pairs: the medians of each one's CPU and wall seconds, their ratio,
the time per 1000 waypoints of both, and how far the two timings differ (time stamps and tip speeds, largest
relative difference).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _data import meshes_dir

from sprayplan.config import JobConfig
from sprayplan.demo import DEMO_REGION, car_roof
from sprayplan.export.summary import plan_totals
from sprayplan.job import run_job
from sprayplan.timing.stage import time_plan


def parts():
    return {
        "roof": ("demo roof (z > 1000)", car_roof(), JobConfig().replace(load={"region": DEMO_REGION})),
        "reach": (
            "reach part (whole)",
            meshes_dir() / "reach_curved_part.ply",
            JobConfig().replace(load={"units": "m"}),
        ),
        "suv": ("SUV body (whole)", meshes_dir() / "gazebo_suv_body_m.ply", JobConfig().replace(load={"units": "m"})),
    }


def _plan(key, stations):
    label, source, job = parts()[key]
    state = run_job(source, job, until="kinematics")
    plan = state.plan
    if stations is not None:
        plan = dataclasses.replace(plan, stations=plan.stations[:stations])
    return label, job, state, plan


def compare_rounds(args) -> int:
    """Wall time and timed cycle for each ``--max-rounds`` value on the same plan (median of ``--runs``)."""
    for key in args.parts.split(","):
        label, job, state, plan = _plan(key, args.stations)
        for rounds in (int(v) for v in args.max_rounds.split(",")):
            varied = job.replace(timing={"max_rounds": rounds})
            walls, timing = [], None
            for _ in range(args.runs):
                began = time.perf_counter()
                timing = time_plan(plan, varied, state.gantry())
                walls.append(time.perf_counter() - began)
            print(
                f"{label}, max_rounds {rounds}: {statistics.median(walls):.1f} s, timed cycle {timing.cycle_time_s:.2f} s"
            )
    return 0


def _child(plan_file: str, out_file: str) -> int:
    """Time the pickled plan once in this process (whichever sprayplan is on the path): CPU and wall seconds,
    and the time stamps and tip speeds to ``out_file``."""
    with open(plan_file, "rb") as f:
        plan, job, gantry = pickle.load(f)
    cpu, wall = time.process_time(), time.perf_counter()
    timing = time_plan(plan, job, gantry)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    np.savez(out_file, t=np.concatenate(timing.t_s), speed=np.concatenate(timing.speed_mm_s))
    print(json.dumps({"cpu_s": cpu, "wall_s": wall, "cycle_s": timing.cycle_time_s}))
    return 0


def _largest_difference(a: np.ndarray, b: np.ndarray) -> float:
    """The largest relative difference of two arrays with their NaNs at the same places."""
    assert (np.isnan(a) == np.isnan(b)).all()
    ok = ~np.isnan(a)
    return float((np.abs(a[ok] - b[ok]) / np.maximum(np.abs(b[ok]), 1e-9)).max(initial=0.0))


def compare_base(args) -> int:
    """This checkout's timing stage and ``--base``'s, side by side on one plan per part."""
    here = Path(__file__).resolve().parents[1] / "src"
    base = Path(args.base).resolve() / "src"
    with tempfile.TemporaryDirectory() as tmp:
        for key in args.parts.split(","):
            label, job, state, plan = _plan(key, args.stations)
            gantry = state.gantry()
            plan_file = os.path.join(tmp, f"{key}.pkl")
            with open(plan_file, "wb") as f:
                pickle.dump((plan, job, gantry), f)
            waypoints = sum(len(st) for st in plan.stations)
            rows = {"new": [], "base": []}
            for run in range(args.runs):
                procs = {}
                for name, src in (("new", here), ("base", base)):
                    out = os.path.join(tmp, f"{key}-{name}-{run}.npz")
                    env = dict(os.environ, PYTHONPATH=str(src))
                    procs[name] = (
                        subprocess.Popen(
                            [sys.executable, __file__, "--child", plan_file, out],
                            env=env,
                            stdout=subprocess.PIPE,
                            text=True,
                        ),
                        out,
                    )
                for name, (proc, out) in procs.items():
                    stdout, _ = proc.communicate()
                    if proc.returncode != 0:
                        raise SystemExit(f"bench_timing: the {name} run failed")
                    rows[name].append((json.loads(stdout.strip().splitlines()[-1]), np.load(out)))
                print(
                    f"{label}, pair {run + 1}: "
                    + ", ".join(
                        f"{n} {rows[n][-1][0]['cpu_s']:.2f} CPU s / {rows[n][-1][0]['wall_s']:.2f} wall s" for n in rows
                    ),
                    flush=True,
                )
            med = {n: {k: statistics.median(r[0][k] for r in rows[n]) for k in ("cpu_s", "wall_s")} for n in rows}
            new, old = rows["new"][-1][1], rows["base"][-1][1]
            print()
            print("| part | waypoints | | CPU s (median) | wall s (median) | CPU s per 1000 waypoints |")
            print("|---|---|---|---|---|---|")
            for n, name in (("base", f"before ({args.base})"), ("new", "after")):
                print(
                    f"| {label} | {waypoints:,} | {name} | {med[n]['cpu_s']:.2f} | {med[n]['wall_s']:.2f} |"
                    f" {1000 * med[n]['cpu_s'] / waypoints:.3f} |"
                )
            print(
                f"| | | after / before | {med['new']['cpu_s'] / med['base']['cpu_s']:.2f} |"
                f" {med['new']['wall_s'] / med['base']['wall_s']:.2f} | |"
            )
            print(
                f"\nlargest relative difference, time stamps {_largest_difference(new['t'], old['t']):.2g},"
                f" tip speeds {_largest_difference(new['speed'], old['speed']):.2g};"
                f" cycle {rows['new'][-1][0]['cycle_s']:.6f} s after, {rows['base'][-1][0]['cycle_s']:.6f} s before"
            )
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--parts", default="roof,reach,suv")
    parser.add_argument("--stations", type=int, default=None, help="time only the plan's first N stations")
    parser.add_argument(
        "--max-rounds", default=None, help="compare [timing] max_rounds values (e.g. 6,2,1): wall and cycle of each"
    )
    parser.add_argument("--base", default=None, help="another checkout: its timing stage beside this one's")
    parser.add_argument("--child", nargs=2, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return _child(*args.child)
    if args.base:
        return compare_base(args)
    if args.max_rounds:
        return compare_rounds(args)
    rows = []
    for key in args.parts.split(","):
        began = time.perf_counter()
        label, job, state, plan = _plan(key, args.stations)
        planned_s = time.perf_counter() - began
        gantry = state.gantry()
        walls, timing = [], None
        for _ in range(args.runs):
            began = time.perf_counter()
            timing = time_plan(plan, job, gantry)
            walls.append(time.perf_counter() - began)
        before = plan_totals(plan, job)["cycle_time_s"]
        summary = timing.summary(plan, job)
        waypoints = sum(len(st) for st in plan.stations)
        wall = statistics.median(walls)
        rows.append(
            (
                label,
                waypoints,
                wall,
                1000.0 * wall / waypoints,
                before,
                timing.cycle_time_s,
                timing.spray_time_s,
                timing.transfer_time_s,
                timing.station_move_time_s,
                summary,
                planned_s,
            )
        )
        print(
            f"{label}: planned in {planned_s:.1f} s; timing runs {', '.join(f'{w:.2f}' for w in walls)} s", flush=True
        )
    print()
    print(
        f"| part | waypoints | timing (median of {args.runs}) | per 1000 waypoints | cycle, length / speed |"
        " cycle, timed | timed / length-over-speed | spray / transfers / station moves (timed) |"
        " slowed spray waypoints (on the part) | strokes slowed | worst limit ratio (speed, acceleration, tip) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for label, n, wall, per, before, after, spray, transfer, station, summary, _ in rows:
        worst = summary["worst_limit_ratio"]
        print(
            f"| {label} | {n:,} | {wall:.1f} s | {per:.2f} s | {before:,.0f} s | {after:,.0f} s | {after / before:.2f} |"
            f" {spray:,.0f} / {transfer:,.0f} / {station:,.0f} s |"
            f" {summary['slowed_waypoints']:,} of {summary['spray_waypoints']:,} ({summary['slowed_on_part_waypoints']:,}) |"
            f" {summary['strokes_slowed']} | {worst['velocity']:.3f}, {worst['acceleration']:.3f}, {worst['tip_speed']:.3f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
