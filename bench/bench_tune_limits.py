"""Speeds tuned within the joints' limits (issue 16, section 4): the film at the timed speeds before and after.

    PYTHONPATH=src python bench/bench_tune_limits.py [--parts roof,reach,suv] [--runs 1] [--accel-deg-s2 2000]

Each part is planned once to the refine stage with a 50 um film target (the tuning at the planned speeds), then
on that plan, side by side:

- before: the timing stage (``timing.stage.time_plan``) on the tuned plan, and the film at the speeds it finds
  (``refine.limits.film_of``, the tuning's deposit matrix at the timed time factors);
- after: ``refine.limits.tune_within_limits`` (``[tuning] limit_rounds`` rounds of tuning again with the timed
  caps, each timed again), and the film at its timed speeds; its wall time is the median of ``--runs``.

Film figures are over the tuning's samples (area-weighted mean, cv, share within 50 +- 5 um). With
``--accel-deg-s2`` the arm's joint accelerations are set to that value (``[timing]
arm_max_acceleration_deg_s2``) in place of the model's 80.2 deg/s^2 (URScript ``movej``'s default).
Parts: the demo roof (``sprayplan demo``'s job: z > 1000, 420 film samples), the reach part (x > -700, in
metres, as tests/test_coating_plan.py) and the SUV body (whole, in metres).
"""

from __future__ import annotations

import argparse
import statistics
import time

from _data import meshes_dir

from sprayplan.config import JobConfig
from sprayplan.demo import DEMO_REGION, car_roof
from sprayplan.job import run_job
from sprayplan.refine.limits import film_of, tune_within_limits
from sprayplan.timing.stage import time_plan

TARGET = {"thickness_um": 50.0}
OUT = {"viewer": False, "report": False, "samples": 420}


def parts():
    return {
        "roof": ("demo roof (z > 1000)", car_roof(), JobConfig().replace(load={"region": DEMO_REGION})),
        "reach": (
            "reach part (x > -700)",
            meshes_dir() / "reach_curved_part.ply",
            JobConfig().replace(load={"units": "m", "region": "x > -700"}),
        ),
        "suv": ("SUV body (whole)", meshes_dir() / "gazebo_suv_body_m.ply", JobConfig().replace(load={"units": "m"})),
    }


def _stats(film, tuned) -> str:
    import numpy as np

    rows = tuned.tuned
    area = tuned.area_mm2[rows]
    t = film.thickness_um[rows]
    mean = float(np.average(t, weights=area))
    cv = float(np.sqrt(np.average((t - mean) ** 2, weights=area))) / mean
    inside = float(area[np.abs(t - 50.0) <= 5.0].sum() / area.sum())
    return f"{mean:.1f} um, cv {cv:.3f}, {100 * inside:.1f} % in spec"


def _summary(stats: dict) -> str:
    return f"{stats['mean_um']:.1f} um, cv {stats['cv']:.3f}, {100 * stats['share_in_spec']:.1f} % in spec"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="roof,reach,suv")
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--accel-deg-s2", type=float, default=None)
    args = parser.parse_args()
    print(
        "| part | arm acceleration | tuning at planned speeds: film predicted | before: film at timed speeds | "
        "before: cycle timed | after: film predicted | after: film at timed speeds | after: cycle timed | "
        "rounds | capped waypoints | over spec (area share, max um) | within-limits wall (median) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for key in args.parts.split(","):
        label, source, job = parts()[key]
        timing = {} if args.accel_deg_s2 is None else {"arm_max_acceleration_deg_s2": [args.accel_deg_s2] * 6}
        job = job.replace(coating=TARGET, output=OUT, timing=timing)
        state = run_job(source, job, until="collision")
        job, gantry = state.job, state.gantry()
        before = time_plan(state.plan, job, gantry)
        film_before = film_of(state.tuned, state.plan, before, job)
        walls, done = [], None
        for _ in range(args.runs):
            began = time.perf_counter()
            done = tune_within_limits(
                state.part, state.plan, state.tuned, job, lambda p, j=job, g=gantry: time_plan(p, j, g)
            )
            walls.append(time.perf_counter() - began)
        s = done.summary
        accel = "80.2 deg/s^2" if args.accel_deg_s2 is None else f"{args.accel_deg_s2:g} deg/s^2"
        over = s["over_spec"]
        print(
            f"| {label} | {accel} | {_stats(state.film, state.tuned)} | {_stats(film_before, state.tuned)} | "
            f"{before.cycle_time_s:.1f} s | {_summary(s['predicted'])} | "
            f"{_stats(done.film, done.tuning)} | {done.timing.cycle_time_s:.1f} s | {s['rounds']} | "
            f"{s['capped_waypoints']} | {over['share']:.3f}, {over['max_um']} | {statistics.median(walls):.1f} s "
            f"({', '.join(f'{w:.1f}' for w in walls)}) |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
