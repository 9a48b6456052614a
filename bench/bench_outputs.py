"""The cost of writing a job's outputs (issue 17): ``job.write_outputs`` alone (plan.json, waypoints.csv, the film
files, plan.html and the report's pictures) on a finished job, this checkout against another.

The job of each part (``bench_speed.part_and_job``: ``demo``, ``hull``, ``bmw``, ``bmw-N``) is run once, without
outputs, and pickled into ``--state DIR`` (kept: a second call reuses it); then each run is a fresh process that
loads the pickle, imports matplotlib and plotly (not counted) and writes the outputs into a temporary folder,
printing its CPU seconds (``time.process_time``) and wall seconds. With ``--base DIR`` the same is done with the
sprayplan of another checkout (``DIR/src``), both started at the same time (the same load on a busy machine),
and the table gives medians and their ratio.

Usage::

    python bench/bench_outputs.py --parts demo,hull --repeat 3 --base ../wt-speed-base --state /tmp/states
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"


def make_state(name: str, path: Path) -> None:
    sys.path.insert(0, str(HERE))
    from bench_speed import part_and_job

    from sprayplan.job import run_job

    source, job = part_and_job(name)
    state = run_job(source, job)
    with open(path, "wb") as handle:
        pickle.dump(state, handle, protocol=pickle.HIGHEST_PROTOCOL)


def child(state_file: str) -> None:
    # imported before the clock starts: the imports are not what is measured
    import matplotlib.backends.backend_agg
    import matplotlib.figure  # noqa: F401
    import plotly.graph_objects  # noqa: F401

    from sprayplan.job import write_outputs

    with open(state_file, "rb") as handle:
        state = pickle.load(handle)
    with tempfile.TemporaryDirectory() as tmp:
        cpu, wall = time.process_time(), time.perf_counter()
        write_outputs(os.path.join(tmp, "out"), state)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    print(json.dumps({"cpu_s": round(cpu, 3), "wall_s": round(wall, 3), "load": round(os.getloadavg()[0], 2)}))


def start(state_file: Path, src: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(src)}
    return subprocess.Popen(
        [sys.executable, __file__, "--child", str(state_file)], env=env, stdout=subprocess.PIPE, text=True
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="demo,hull")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--base", help="another checkout to compare with (its src/ is used)")
    parser.add_argument("--new", help="the checkout to measure (default: this one)")
    parser.add_argument("--state", default=os.path.join(tempfile.gettempdir(), "sprayplan-bench-outputs"))
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    builds = {"new": Path(args.new).resolve() / "src" if args.new else SRC}
    if args.base:
        builds["base"] = Path(args.base).resolve() / "src"
    folder = Path(args.state)
    folder.mkdir(parents=True, exist_ok=True)
    for name in args.parts.split(","):
        state_file = folder / f"{name}.pkl"
        if not state_file.exists():
            make_state(name, state_file)
        runs: dict[str, list[dict]] = {b: [] for b in builds}
        for _ in range(args.repeat):
            started = {b: start(state_file, src) for b, src in builds.items()}
            for b, process in started.items():
                out, _ = process.communicate()
                if process.returncode:
                    raise SystemExit(f"a run of {b} on {name} failed")
                runs[b].append(json.loads(out.strip().splitlines()[-1]))
                print(json.dumps({"part": name, "build": b, **runs[b][-1]}), file=sys.stderr)
        print(f"\n#### {name}: write_outputs, medians of {args.repeat}\n")
        print("| build | CPU s | wall s | runs' CPU s | load at the end |")
        print("|---|---|---|---|---|")
        med = {b: statistics.median(r["cpu_s"] for r in runs[b]) for b in builds}
        for b in builds:
            wall = statistics.median(r["wall_s"] for r in runs[b])
            each = ", ".join(f"{r['cpu_s']:.2f}" for r in runs[b])
            loads = ", ".join(f"{r['load']:.1f}" for r in runs[b])
            print(f"| {b} | {med[b]:.2f} | {wall:.2f} | {each} | {loads} |")
        if "base" in builds:
            print(f"\nnew / base, CPU: {med['new'] / med['base']:.2f}")


if __name__ == "__main__":
    main()
