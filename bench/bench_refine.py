"""The refine stage alone (issue 17): ``refine.stage.tune_plan`` on a plan made once, this checkout against another.

Each part (``demo``, ``hull``, ``bmw``, ``bmw-N``: the cases of ``bench_speed.py``) is planned once to the
kinematics stage with the current checkout and the job state is pickled (``--cache``, default the system's
temporary folder); then the refine stage runs on that same plan in fresh processes, this checkout's and, with
``--base DIR``, another checkout's (``DIR/src``), the pair started together (``--together``) or one after the
other. Each run prints one JSON line: wall and CPU seconds of ``tune_plan``, the process's peak resident
memory, the film figures over the tuned samples (area-weighted mean, std / mean, share in spec), the touch-up
strokes added and a digest of the refined plan's strokes (their TCP points and the stations), so that the two
builds can be seen to make the same plan.

Usage::

    python bench/bench_refine.py --parts demo,hull --repeat 3 --together --base ../wt-speed-base
    python bench/bench_refine.py --child hull --profile /tmp/refine_hull.prof
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"


def cache_file(name: str, cache: str | None) -> Path:
    return Path(cache or tempfile.gettempdir()) / f"sprayplan_refine_{name}.pkl"


def planned(name: str, cache: str | None):
    """The job state after the kinematics stage, made once and pickled."""
    path = cache_file(name, cache)
    if path.exists():
        with open(path, "rb") as fh:
            return pickle.load(fh)
    sys.path.insert(0, str(HERE))
    from bench_speed import part_and_job

    from sprayplan.job import run_job

    source, job = part_and_job(name)
    state = run_job(source, job, until="kinematics")
    with open(path.with_suffix(".tmp"), "wb") as fh:
        pickle.dump(state, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(path.with_suffix(".tmp"), path)
    return state


def child(name: str, cache: str | None, profile: str | None) -> None:
    import hashlib

    try:  # as the command line does (a checkout before sprayplan.heap: as its command line did)
        from sprayplan.heap import reuse_freed_memory

        reuse_freed_memory()
    except ImportError:
        pass

    import numpy as np

    from sprayplan.refine.stage import tune_plan

    state = planned(name, cache)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    if profile:
        import cProfile

        prof = cProfile.Profile()
        plan, summary, *_ = prof.runcall(tune_plan, state.part, state.plan, state.job)
        prof.dump_stats(profile)
    else:
        plan, summary, *_ = tune_plan(state.part, state.plan, state.job)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    digest = hashlib.sha1()
    for st in plan.stations:
        digest.update(np.round(st.platform_mm, 6).tobytes())
        for stroke in st.strokes:
            digest.update(np.round(stroke.tcp, 6).tobytes())
    after = summary.get("after", {})
    report = {
        "part": name,
        "wall_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "maxrss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "load": round(os.getloadavg()[0], 2),
        "stations": len(plan.stations),
        "strokes": sum(len(st.strokes) for st in plan.stations),
        "touch_up_strokes": summary.get("touch_up_strokes"),
        "film": {k: round(after[k], 6) for k in ("mean_um", "cv", "share_in_spec")} if after else None,
        "plan": digest.hexdigest()[:12],
    }
    print(json.dumps(report))


def start(name: str, src: Path, cache: str | None) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(src)}
    argv = [sys.executable, __file__, "--child", name] + (["--cache", cache] if cache else [])
    return subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(process: subprocess.Popen) -> dict:
    out, err = process.communicate()
    if process.returncode:
        raise SystemExit(f"a run failed: {err.strip().splitlines()[-1] if err.strip() else process.returncode}")
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="demo,hull")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--base", help="another checkout to compare with (its src/ is used)")
    parser.add_argument("--together", action="store_true", help="run the two builds at the same time")
    parser.add_argument("--cache", help="folder of the pickled plans (default: the temporary folder)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--profile", help="with --child: write a cProfile file of tune_plan")
    args = parser.parse_args()
    if args.child:
        child(args.child, args.cache, args.profile)
        return
    builds = {"new": SRC}
    if args.base:
        builds["base"] = Path(args.base).resolve() / "src"
    for name in args.parts.split(","):
        planned(name, args.cache)  # the plan, once, before any timed run
        runs: dict[str, list[dict]] = {b: [] for b in builds}
        for _ in range(args.repeat):
            if args.together:
                started = {b: start(name, src, args.cache) for b, src in builds.items()}
                reports = {b: finish(p) for b, p in started.items()}
            else:
                reports = {b: finish(start(name, src, args.cache)) for b, src in builds.items()}
            for build, report in reports.items():
                runs[build].append(report)
                print(json.dumps({"build": build, **report}), file=sys.stderr)
        print(f"\n{name}: medians of {args.repeat}")
        print("| build | refine wall s | refine CPU s | peak RSS MB | film mean um | std/mean | in spec | plan |")
        print("|---|---|---|---|---|---|---|---|")
        for build, rs in runs.items():
            med = {k: statistics.median(r[k] for r in rs) for k in ("wall_s", "cpu_s", "maxrss_mb")}
            f = rs[0]["film"] or {}
            print(
                f"| {build} | {med['wall_s']:.2f} | {med['cpu_s']:.2f} | {med['maxrss_mb']:.0f} | "
                f"{f.get('mean_um', float('nan')):.4f} | {f.get('cv', float('nan')):.5f} | "
                f"{f.get('share_in_spec', float('nan')):.5f} | {rs[0]['plan']} |"
            )
        if "base" in runs:
            for key in ("wall_s", "cpu_s"):
                ratio = statistics.median(r[key] for r in runs["new"]) / statistics.median(r[key] for r in runs["base"])
                print(f"new / base, {key}: {ratio:.3f}")


if __name__ == "__main__":
    main()
