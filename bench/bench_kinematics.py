"""The kinematics stage of the main job (issue 17): CPU seconds, against another checkout, and the plans compared.

Each run is a fresh process (``--child``) that plans a part up to the ordering stage (not timed), then runs
``robots.stage.kinematics_stage`` (timed: CPU and wall seconds) and saves the plan's joints, methods and
errors. With ``--base DIR`` the same runs are made with another checkout's sprayplan (``DIR/src``), each pair
started at the same time (so that both see the same load). The parts are ``bench_speed``'s (``demo``,
``hull``, ``bmw``, ``bmw-N``).

The plans are compared the way issue 17 asks: reachable waypoints, the waypoints whose method differs, the
analytic waypoints whose joints differ by more than 1e-6 rad, the eq. 20 cost summed over the SQP waypoints
(each against the previous reachable waypoint's joints and the station's gantry position, home at a
station's start), and the largest position and axis errors of the SQP waypoints.

Usage::

    python bench/bench_kinematics.py --parts demo,hull --repeat 3 --base ../wt-speed-base
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
HOME = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0])


def child(name: str, out: str) -> None:
    sys.path.insert(0, str(HERE))
    from bench_speed import part_and_job

    from sprayplan.job import run_job
    from sprayplan.robots.stage import kinematics_stage

    source, job = part_and_job(name)
    state = run_job(source, job, until="ordering")
    gantry = state.gantry()
    wall, cpu = time.perf_counter(), time.process_time()
    plan = kinematics_stage(state.ordered, state.job, gantry)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    arrays = {}
    for k, station in enumerate(plan.stations):
        arrays[f"q9_{k}"] = station.q9
        arrays[f"reachable_{k}"] = station.reachable
        arrays[f"method_{k}"] = station.method.astype(str)
        arrays[f"position_{k}"] = station.position_error_mm
        arrays[f"axis_{k}"] = station.axis_error_deg
        arrays[f"platform_{k}"] = np.asarray(station.platform_mm, dtype=float)
    np.savez(out, **arrays)
    print(json.dumps({"part": name, "cpu_s": cpu, "wall_s": wall, "stations": len(plan.stations)}))


def start(name: str, src: Path, out: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(src)}
    command = [sys.executable, __file__, "--child", name, "--out", out]
    return subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(process: subprocess.Popen) -> dict:
    out, err = process.communicate()
    if process.returncode:
        raise SystemExit(f"a run failed: {err.strip().splitlines()[-1] if err.strip() else process.returncode}")
    return json.loads(out.strip().splitlines()[-1])


def stations(path: str) -> list[dict]:
    data = np.load(path)
    count = len([k for k in data.files if k.startswith("q9_")])
    fields = ("q9", "reachable", "method", "position", "axis", "platform")
    return [{f: data[f"{f}_{k}"] for f in fields} for k in range(count)]


def eq20_total(station: dict, k_d: float = 0.1) -> float:
    previous, total = HOME, 0.0
    for i in np.flatnonzero(station["reachable"]):
        q = station["q9"][i]
        if station["method"][i] == "sqp":
            total += float(((q[:6] - previous) ** 2).sum() + k_d * ((q[6:] - station["platform"]) ** 2).sum())
        previous = q[:6]
    return total


def compare(new: list[dict], base: list[dict]) -> dict:
    out = {"reachable": [0, 0], "method_differs": 0, "analytic": 0, "analytic_differs": 0, "eq20": [0.0, 0.0]}
    out["sqp"] = [0, 0]
    worst = [0.0, 0.0]
    for a, b in zip(new, base, strict=True):
        out["reachable"][0] += int(a["reachable"].sum())
        out["reachable"][1] += int(b["reachable"].sum())
        out["sqp"][0] += int((a["method"] == "sqp").sum())
        out["sqp"][1] += int((b["method"] == "sqp").sum())
        out["method_differs"] += int((a["method"] != b["method"]).sum())
        both = (a["method"] == "analytic") & (b["method"] == "analytic")
        out["analytic"] += int(both.sum())
        out["analytic_differs"] += int((np.abs(a["q9"][both] - b["q9"][both]).max(axis=1, initial=0) > 1e-6).sum())
        out["eq20"][0] += eq20_total(a)
        out["eq20"][1] += eq20_total(b)
        sqp = a["method"] == "sqp"
        if sqp.any():
            worst = [max(worst[0], float(a["position"][sqp].max())), max(worst[1], float(a["axis"][sqp].max()))]
    out["new_sqp_worst_mm_deg"] = worst
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="demo,hull")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--base", help="another checkout to compare with (its src/ is used)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.out)
        return
    builds = {"new": SRC}
    if args.base:
        builds["base"] = Path(args.base).resolve() / "src"
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.parts.split(","):
            cpu: dict[str, list[float]] = {b: [] for b in builds}
            for r in range(args.repeat):
                outs = {b: str(Path(tmp) / f"{name}_{b}_{r}.npz") for b in builds}
                started = {b: start(name, src, outs[b]) for b, src in builds.items()}
                for b, process in started.items():
                    report = finish(process)
                    cpu[b].append(report["cpu_s"])
                    print(json.dumps({**report, "build": b, "load_1min": os.getloadavg()[0]}), file=sys.stderr)
            line = f"{name}: kinematics CPU s, median of {args.repeat}: new {statistics.median(cpu['new']):.2f}"
            if "base" in builds:
                ratio = statistics.median(cpu["new"]) / statistics.median(cpu["base"])
                line += f", base {statistics.median(cpu['base']):.2f}, new / base {ratio:.2f}"
                line += f" (runs: new {[round(c, 2) for c in cpu['new']]}, base {[round(c, 2) for c in cpu['base']]})"
                print(line)
                print(
                    f"{name}: plans, new against base:",
                    json.dumps(compare(stations(outs["new"]), stations(outs["base"]))),
                )
            else:
                print(line)


if __name__ == "__main__":
    main()
