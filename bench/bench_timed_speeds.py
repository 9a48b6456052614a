"""Where a cell plan's robots are slower than planned (issue 18: the film at the timed speeds).

The body is planned in ``--cell`` as ``sprayplan plan --cell ... --thickness-um 50`` does (no collision model),
with the flow the fit keeps (or ``--share``: the flow and gun speed times that share of the process's, the fit
off). Then each robot's spray stretches (the runs of reached waypoints the timing follows along the joint path,
``cells.timing``) are timed again, and printed per robot:

- the stretches' lengths (10th / 50th / 90th percentile, mm) and toppra's uniform stretch after its refinements;
- the planned and timed time within ``--ends`` mm of a stretch's two ends and inside it;
- the segments inside a stretch timed over 1.1 times their planned time, by what holds them back: an axis
  within 0.8 of its speed limit (arm joints, then the track), or none (the accelerations);
- the spray waypoints whose timed time factor is over 1.1 times the planned one, by kind of stroke (spray,
  touch-up), with the median planned factor.

    python bench/bench_timed_speeds.py --body bmw
    python bench/bench_timed_speeds.py --body suv --share 0.35
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir
from bench_cell_collisions import BODIES


def where_slower(cell, plan, job, ends_mm: float) -> dict:
    """The figures of the module docstring, per robot, for a plan's robots timed within ``job``'s limits."""
    from sprayplan.cells import timing as cell_timing
    from sprayplan.timing.path import time_paths

    jump = math.radians(job.timing.joint_jump_deg)
    timed_work = cell_timing.time_cell(cell, plan.robots, job)
    factors = cell_timing.timed_factors(cell_timing.with_times(plan.robots, timed_work), job)
    out = {}
    for robot, work, timed_factor in zip(cell.robots, plan.robots, factors):
        axes, limits = cell_timing._Axes(robot), cell_timing.cell_limits(robot, job.timing)
        q = axes.of(work)
        stretches = list(cell_timing._stretches(work, axes, q, job.motion, jump))
        timings = time_paths(
            [(path, cap) for path, cap, *_ in stretches],
            limits,
            axes.tip,
            check_steps=job.timing.check_steps,
            max_rounds=job.timing.max_rounds,
        )
        lengths, time = [], {"ends_planned": 0.0, "ends_timed": 0.0, "inside_planned": 0.0, "inside_timed": 0.0}
        held_back = np.zeros(q.shape[1] + 1, int)
        for (_, caps, idx, up, run_out), t in zip(stretches, timings):
            # the stretch's own waypoints (its run-up and run-out, spray off, left out of the figures)
            cap = caps[int(up) : len(caps) - int(run_out)]
            t_s = t.t_s[int(up) : len(t.t_s) - int(run_out)]
            step = np.linalg.norm(np.diff(axes.tip(q[idx]), axis=0), axis=1)
            along = np.r_[0.0, np.cumsum(step)]
            lengths.append(along[-1])
            middle = (along[:-1] + along[1:]) / 2
            at_end = (middle < ends_mm) | (middle > along[-1] - ends_mm)
            real, planned = np.diff(t_s), step / cap
            time["ends_planned"] += planned[at_end].sum()
            time["ends_timed"] += real[at_end].sum()
            time["inside_planned"] += planned[~at_end].sum()
            time["inside_timed"] += real[~at_end].sum()
            slow = ~at_end & (real > 1.1 * planned)
            speed = np.abs(np.diff(q[idx], axis=0)) / np.maximum(real, 1e-12)[:, None] / limits.velocity
            for k in np.flatnonzero(slow):
                axis = int(speed[k].argmax())
                held_back[axis if speed[k, axis] > 0.8 else -1] += 1
        planned_factor = np.concatenate([s.dwell for s in work.strokes])
        kind = np.concatenate([[s.kind] * len(s) for s in work.strokes])
        spray = np.concatenate([[s.spray_on] * len(s) for s in work.strokes]) & work.reachable
        by_kind = {}
        for name in np.unique(kind[spray]):
            mine = spray & (kind == name)
            by_kind[str(name)] = {
                "waypoints": int(mine.sum()),
                "slowed_share": round(float(np.mean(timed_factor[mine] > 1.1 * planned_factor[mine])), 3),
                "median_planned_factor": round(float(np.median(planned_factor[mine])), 3),
            }
        stretch = np.array([t.stretch for t in timings])
        names = [f"joint {j + 1}" for j in range(axes.dof)] + (["track"] if axes.axis is not None else [])
        out[robot.name] = {
            "stretches": len(stretches),
            "length_mm_p10_p50_p90": np.percentile(lengths, [10, 50, 90]).round(0).tolist() if lengths else [],
            "uniform_stretch_p50_max": [round(float(np.median(stretch)), 4), round(float(stretch.max()), 4)]
            if len(stretch)
            else [],
            **{k: round(v, 1) for k, v in time.items()},
            "slowed_inside_segments": int(held_back.sum()),
            "held_back_by": {**dict(zip(names, held_back[:-1].tolist())), "accelerations": int(held_back[-1])},
            "slowed_spray_waypoints": by_kind,
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--body", choices=sorted(BODIES), default="bmw")
    parser.add_argument("--cell", default="line3")
    parser.add_argument("--share", type=float, default=None, help="flow and gun speed share (the fit off)")
    parser.add_argument("--ends", type=float, default=100.0, help="mm from a stretch's ends counted as its ends")
    args = parser.parse_args()

    from sprayplan.cells import load_cell
    from sprayplan.cells.fit import scaled_job
    from sprayplan.cells.plan import plan_cell
    from sprayplan.coating.stage import job_paint
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part

    name, load = BODIES[args.body]
    part = load_part(str(meshes_dir() / name), **load)
    job = JobConfig().replace(coating={"thickness_um": 50.0}, output={"samples": 420})
    if args.share is not None:
        job = job.replace(timing={"fit_flow": False})
    plan = plan_cell(part, load_cell(args.cell), job)
    job = plan.job
    if args.share is not None:
        job = scaled_job(job, args.share, job_paint(job).flow_ml_min)
    report = {
        "body": args.body,
        "gun_speed_mm_s": round(job.motion.gun_speed_mm_s, 3),
        "flow_ml_min": round(job_paint(job).flow_ml_min, 3),
        "robots": where_slower(plan.cell, dataclasses.replace(plan, job=job), job, args.ends),
    }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
