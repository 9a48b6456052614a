"""The collision stage on whole plans: time to check and repair, and the waypoints in collision before repairs,
repaired and left flagged; the transfers in collision, re-routed by kind and left flagged, and the motions
flagged before and after the transfers were re-routed (docs/benchmarks.md, "The collision stage").

With ``--transfers`` each plan is also run with the transfer routes off (``retract_mm = []``,
``via_height_mm`` none, ``detour`` false), so that the routes' cost is the difference of the two medians;
"motions flagged before" counts them after the waypoint repairs, before the motion repairs and the routes.

Each part is planned to the ``refine`` stage once per way of choosing the stations' heights (no film target,
so no tuning): at seed 000's mid-cylinder height (``platform_search_mm = 0``) and at the heights the collision
model chooses (``collision.heights``, the default with the check on; its cost is in the ``stations`` column);
then the collision stage is timed ``--runs`` times on each plan (median wall and CPU time). ``--heights seed``
or ``chosen`` runs one of the two. Before the stage, the check of every reachable
waypoint of the plan (``CellCollision.check``: the gun, the links, the carriage and the column against the
part, the floor and each other) is timed on its own: waypoints checked per second, and part queries per second
(nine capsules, the gun and the eight links, against the part at each). Parts: the demo roof (``z > 1000``),
the reach part (``x > -250``), the reach part's 262-point scan (a point cloud: a ball about every point), and
with ``--large`` the DTC hull and the BMW body (from ``$SPRAYPLAN_TESTDATA`` or shared/testdata); ``--only``
picks the parts whose name starts with its text.

    PYTHONPATH=src python bench/bench_collision_stage.py [--runs 3] [--large]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import meshes_dir  # noqa: E402

from sprayplan.collision.cell import CellCollision  # noqa: E402
from sprayplan.collision.repair import collision_stage  # noqa: E402
from sprayplan.config import JobConfig  # noqa: E402
from sprayplan.demo import DEMO_REGION, car_roof  # noqa: E402
from sprayplan.job import run_job  # noqa: E402


def cases(large: bool):
    yield "demo roof (z > 1000)", car_roof(), JobConfig().replace(load={"region": DEMO_REGION})
    reach = REPO / "tests" / "data" / "meshes" / "reach_curved_part.ply"
    yield "reach part (x > -250)", reach, JobConfig().replace(load={"units": "m", "region": "x > -250"})
    scan = REPO / "tests" / "data" / "pointclouds" / "reach_part_normals_ascii.pcd"
    yield "reach scan (262-point cloud)", scan, JobConfig().replace(load={"units": "m"})
    if large:
        yield "DTC hull", meshes_dir() / "dtc_ship_hull_ascii.stl.gz", JobConfig().replace(load={"units": "m"})
        yield "BMW body", meshes_dir() / "bmw_m6_body_m_yup.ply", JobConfig().replace(load={"units": "m", "up": "y"})


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--large", action="store_true")
    parser.add_argument("--transfers", action="store_true", help="the transfer table (routes on and off)")
    parser.add_argument("--only", default=None, help="only the parts whose name starts with this")
    parser.add_argument("--heights", choices=("seed", "chosen", "both"), default="both")
    args = parser.parse_args(argv)
    if args.transfers:
        return transfer_table(args)
    print(
        "| part | heights | stations s | waypoints | unreachable | check waypoints/s | part queries/s | in collision before "
        "| repaired (branch/roll/tilt/platform) | flagged | motions | flagged motions "
        "| transfers in collision / re-routed (of them unwound) / flagged | stage wall s (median) "
        "| stage CPU s (median) | load |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    kinds = ("seed", "chosen") if args.heights == "both" else (args.heights,)
    for (name, source, job), heights in ((c, h) for c in cases(args.large) for h in kinds):
        if args.only and not name.startswith(args.only):
            continue
        search = {} if heights == "chosen" else {"platform_search_mm": 0.0}
        state = run_job(source, job.replace(collision={"check": True, **search}), until="refine")
        unreachable = sum(int((~st.reachable).sum()) for st in state.plan.stations)
        cell = CellCollision(state.gantry(), state.whole, state.job.collision)
        q9 = [st.q9[st.reachable] for st in state.plan.stations]
        cell.check(q9[0][:1])  # the surface samples and the grid, made once per plan
        began = time.perf_counter()
        for q in q9:
            cell.check(q)
        rate = sum(len(q) for q in q9) / (time.perf_counter() - began)
        times, cpu = [], []
        for _ in range(args.runs):
            began, began_cpu = time.perf_counter(), time.process_time()
            _, summary = collision_stage(state.plan, state.whole, state.job, state.gantry())
            times.append(time.perf_counter() - began)
            cpu.append(time.process_time() - began_cpu)
        by = summary["repaired_by"]
        print(
            f"| {name} | {heights} | {state.timings_s['stations']:.1f} | {summary['waypoints_checked']} | {unreachable} | "
            f"{rate:,.0f} | {9 * rate:,.0f} | "
            f"{summary['in_collision_before_repair']} | "
            f"{summary['repaired']} ({by['branch']}/{by['roll']}/{by['tilt']}/{by['platform']}) | "
            f"{summary['flagged_waypoints']} | {summary['motions_checked']} | {summary['flagged_motions']} | "
            f"{summary['transfers_in_collision']} / {summary['transfers_rerouted']} "
            f"({summary.get('transfers_unwound', 0)}) / {summary['transfers_flagged']} | "
            f"{statistics.median(times):.1f} | {statistics.median(cpu):.1f} | {os.getloadavg()[0]:.1f} |",
            flush=True,
        )
    return 0


def transfer_table(args) -> int:
    off = {"retract_mm": [], "via_height_mm": None, "detour": False}
    print(
        "| part | transfers in collision | of them with an end in collision | re-routed (retract/via/detour) | "
        "transfers flagged | motions flagged before / after | motions repaired in strokes | stage s, routes off | "
        "stage s, routes on (median) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, source, job in cases(args.large):
        if args.only and not name.startswith(args.only):
            continue
        state = run_job(source, job.replace(collision={"check": False}), until="refine")
        times = {}
        for label, settings in (("off", off), ("on", {})):
            run = state.job.replace(collision=settings) if settings else state.job
            times[label] = []
            for _ in range(args.runs):
                began = time.perf_counter()
                _, summary = collision_stage(state.plan, state.whole, run, state.gantry())
                times[label].append(time.perf_counter() - began)
        by = summary["transfers_rerouted_by"]
        print(
            f"| {name} | {summary['transfers_in_collision']} | {summary['transfers_end_in_collision']} | "
            f"{summary['transfers_rerouted']} ({by['retract']}/{by['via']}/{by['detour']}) | "
            f"{summary['transfers_flagged']} | {summary['flagged_motions_before_reroute']} / "
            f"{summary['flagged_motions']} | {summary['motions_repaired']} | "
            f"{statistics.median(times['off']):.1f} | {statistics.median(times['on']):.1f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
