"""The gun's axis smoothed along the strokes (``[paths] gun_smooth_mm``): a body planned in a cell at several
widths, each in a fresh process, and where the timed spray time goes.

    python bench/bench_gun_axis.py [--body bmw] [--cell line3] [--widths 0,50,100]

For each width: the planned film and the film at the timed speeds (whole body, mean / std / share in 50 +- 5
um, the 420 measuring points), the timed cycle per robot, the touch-ups; and per robot the timed spray time
split into the planned time, the extra time within 100 mm of a timed stretch's ends (where it starts and stops
at rest) and the extra time inside, and the share of the extra time on the segments where the gun's axis turns
faster than 0.2 deg/mm (read back from waypoints.csv: its nx, ny, nz are the gun's axes reversed).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from _data import meshes_dir

BODIES = {
    "bmw": ("bmw_m6_body_m_yup.ply", ["--units", "m", "--up", "y"]),
    "suv": ("gazebo_suv_body_m.ply", ["--units", "m"]),
}
ENDS_MM = 100.0
FAST_TURN_DEG_MM = 0.2


def where_time_goes(waypoints_csv: Path) -> dict:
    """Per robot: the timed stretches of the spray strokes (runs of reachable waypoints with time stamps); their
    planned time (each segment's length over the process speed times its ends' mean time factor), the timed
    time beyond it within ``ENDS_MM`` of a stretch's ends and inside, and the share of that extra time on the
    segments where the gun's axis turns faster than ``FAST_TURN_DEG_MM``."""
    strokes: dict = defaultdict(lambda: defaultdict(list))
    with open(waypoints_csv, newline="") as handle:
        for row in csv.DictReader(handle):
            if row["kind"] == "spray":
                strokes[row["robot"]][int(row["stroke"])].append(row)
    out = {}
    for robot, by_stroke in strokes.items():
        planned = near = inside = fast = 0.0
        stretches = 0
        for rows in by_stroke.values():
            if len(rows) < 2:
                continue
            p = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
            n = np.array([[float(r[k]) for k in ("nx", "ny", "nz")] for r in rows])
            t = np.array([float(r["t_s"]) if r["t_s"] else np.nan for r in rows])
            w = np.array([float(r["dwell"]) for r in rows])
            ok = np.array([r["reachable"] == "1" for r in rows])
            ds = np.linalg.norm(np.diff(p, axis=0), axis=1)
            dt = np.diff(t)
            plan_dt = ds * (w[1:] + w[:-1]) / 2.0 / SPEED_MM_S
            turn = np.degrees(np.arccos(np.clip(np.sum(n[1:] * n[:-1], axis=1), -1, 1))) / np.maximum(ds, 1e-9)
            good = np.flatnonzero(ok[1:] & ok[:-1] & np.isfinite(dt))
            if not len(good):
                continue
            arc = np.r_[0.0, np.cumsum(ds)]
            for run in np.split(good, np.flatnonzero(np.diff(good) > 1) + 1):
                stretches += 1
                centre = (arc[run] + arc[run + 1]) / 2.0
                by_end = (centre - arc[run[0]] < ENDS_MM) | (arc[run[-1] + 1] - centre < ENDS_MM)
                extra = dt[run] - plan_dt[run]
                planned += plan_dt[run].sum()
                near += extra[by_end].sum()
                inside += extra[~by_end].sum()
                fast += extra[turn[run] > FAST_TURN_DEG_MM].sum()
        out[robot] = {
            "stretches": stretches,
            "planned_s": round(planned, 1),
            "extra_near_ends_s": round(near, 1),
            "extra_inside_s": round(inside, 1),
            "extra_share_on_fast_turns": round(fast / max(near + inside, 1e-9), 3),
        }
    return out


SPEED_MM_S = 400.0  # the job's default [motion] gun_speed_mm_s, which the time factors scale


def one(body: str, cell: str, width: float, folder: Path) -> dict:
    name, flags = BODIES[body]
    config = folder / "gun.toml"
    config.write_text(f"[paths]\ngun_smooth_mm = {width}\n")
    out = folder / "out"
    command = [sys.executable, "-m", "sprayplan", "plan", str(meshes_dir() / name), *flags, "--cell", cell]
    command += ["--thickness-um", "50", "--samples", "420", "-c", str(config), "-o", str(out), "-q"]
    start = time.perf_counter()
    subprocess.run(command, check=True)
    wall = time.perf_counter() - start
    report = json.loads((out / "cell_plan.json").read_text())["report"]
    film, timed = report["film"], report["film"]["at_timed_speeds"]

    def brief(d):
        return {
            "mean_um": round(d["mean_um"], 1),
            "std_um": round(d["std_um"], 1),
            "in_spec": round(d["share_in_spec"], 3),
        }

    return {
        "width_mm": width,
        "wall_s": round(wall, 1),
        "planned": brief(film["whole"]),
        "planned_points_in_spec": round(film["report"]["measuring_points"]["share_in_spec"], 3),
        "timed": brief(timed["whole"]),
        "timed_points_in_spec": round(timed["measuring_points"]["share_in_spec"], 3),
        "cycle_s": round(report["cycle_time_s"], 1),
        "robot_cycle_s": {k: v["cycle_time_s"] for k, v in report["robots"].items()},
        "touch_up_strokes": report.get("touch_up_strokes"),
        "timed_spray": where_time_goes(out / "waypoints.csv"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--body", default="bmw", choices=sorted(BODIES))
    parser.add_argument("--cell", default="line3")
    parser.add_argument("--widths", default="0,50,100")
    args = parser.parse_args()
    for width in (float(w) for w in args.widths.split(",")):
        with tempfile.TemporaryDirectory() as tmp:
            print(json.dumps(one(args.body, args.cell, width, Path(tmp))), flush=True)


if __name__ == "__main__":
    main()
