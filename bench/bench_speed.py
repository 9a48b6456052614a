"""Car-scale speed of the main job (issue 17): the stage times, wall time and peak memory of three parts.

The parts, each with default settings and a 50 um film target (``--thickness-um 50``):

- ``bmw``: the whole BMW M6 body (``meshes/bmw_m6_body_m_yup.ply``, ``--units m --up y``),
- ``hull``: the DTC ship hull (``meshes/dtc_ship_hull_ascii.stl.gz``, ``--units m``),
- ``demo``: the demo roof as ``sprayplan demo`` plans it (z > 1000, 420 film samples),

and ``bmw-N`` for the painted-area study: the BMW body cut to ``x < N`` mm (the car starts at its nose).

Each run is a fresh process (``--child``) that runs ``job.run_job`` with an output folder (plan.json,
waypoints.csv, film, viewer and report files written) and prints one JSON line: wall seconds of every stage,
the total, the CPU seconds, peak resident memory (``resource.getrusage`` maxrss), the load average, and the plan's figures.
With ``--base DIR`` the same runs are made with the sprayplan of another checkout (``DIR/src``), interleaved
with this one's (this, base, this, base, ...; with ``--together`` each pair at the same time, so that both
see the same load on a busy machine), and the table gives both medians and their ratio.

Usage::

    python bench/bench_speed.py --parts demo,hull,bmw --repeat 3 --base ../wt-speed-base
    python bench/bench_speed.py --parts bmw-1200,bmw-2400,bmw-3600,bmw --repeat 1
    python bench/bench_speed.py --child hull --profile hull.prof     # one run under cProfile
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"


def part_and_job(name: str):
    """The part (a path or a Part) and its JobConfig for a case name."""
    sys.path.insert(0, str(HERE))
    from _data import meshes_dir

    from sprayplan.config import JobConfig

    film = {"coating": {"thickness_um": 50.0}}
    if name == "demo":
        from sprayplan.demo import DEMO_REGION, car_roof

        job = JobConfig().replace(
            load={"region": DEMO_REGION}, coating={"thickness_um": 50.0}, output={"simulate": True, "samples": 420}
        )
        return car_roof(), job
    if name == "hull":
        return str(meshes_dir() / "dtc_ship_hull_ascii.stl.gz"), JobConfig().replace(load={"units": "m"}, **film)
    if name == "bmw" or name.startswith("bmw-"):
        load = {"units": "m", "up": "y"}
        if name != "bmw":
            load["region"] = f"x < {float(name[4:]):g}"
        return str(meshes_dir() / "bmw_m6_body_m_yup.ply"), JobConfig().replace(load=load, **film)
    raise SystemExit(f"unknown part {name!r}: demo, hull, bmw or bmw-N")


def child(name: str, profile: str | None) -> None:
    import resource

    try:  # as the command line does (a checkout before sprayplan.heap: as its command line did)
        from sprayplan.heap import reuse_freed_memory

        reuse_freed_memory()
    except ImportError:
        pass

    from sprayplan.job import run_job

    source, job = part_and_job(name)
    cpu: dict[str, float] = {}  # CPU seconds of each stage (all threads), from the progress calls that start it
    last = [None, time.process_time()]

    def progress(stage, done, total):
        if done == 0 and total == 0 and stage != last[0]:
            now = time.process_time()
            if last[0] is not None:
                cpu[last[0]] = cpu.get(last[0], 0.0) + now - last[1]
            last[:] = [stage, now]

    together = _TogetherPeak()
    together.start()
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        if profile:
            import cProfile

            prof = cProfile.Profile()
            result = prof.runcall(run_job, source, job, outdir=tmp, progress=progress)
            prof.dump_stats(profile)
        else:
            result = run_job(source, job, outdir=tmp, progress=progress)
        wall = time.perf_counter() - start
    together.stop()
    progress(None, 0, 0)
    film = result.film
    totals = result.totals
    if film is not None:
        from sprayplan.export.film import film_report

        painted = film_report(film, result.job, result.job.output.samples, result.chosen)["painted"]
        film = {k: round(painted[k], 5) for k in ("mean_um", "cv", "share_in_spec")}
    try:  # the joint solves' helper process (sprayplan.parallel), stopped so that its use is counted
        from sprayplan.parallel import stop_helper

        stop_helper()
    except ImportError:
        pass
    helper = resource.getrusage(resource.RUSAGE_CHILDREN)
    report = {
        "part": name,
        "wall_s": round(wall, 2),
        "stages_s": result.timings_s,
        "stages_cpu_s": {k: round(v, 3) for k, v in cpu.items()},
        "cpu_s": round(sum(resource.getrusage(resource.RUSAGE_SELF)[:2]), 2),
        "maxrss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "helper_cpu_s": round(helper.ru_utime + helper.ru_stime, 2),
        "helper_maxrss_mb": round(helper.ru_maxrss / 1024, 1),
        "together_peak_mb": round(together.peak_mb, 1),
        "load": round(os.getloadavg()[0], 2),
        "stations": totals["stations"],
        "strokes": totals["strokes"],
        "waypoints": totals["waypoints"],
        "unreachable": totals["unreachable_waypoints"],
        "film": film,
        "digest": plan_digest(result.plan),
    }
    print(json.dumps(report))


class _TogetherPeak:
    """The largest resident size of this process and its helper process (``sprayplan.parallel``) at the same
    moment, sampled every 50 ms from /proc (Linux; 0 elsewhere)."""

    def __init__(self):
        import threading

        self.peak_mb = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    @staticmethod
    def _rss_mb(pid) -> float:
        try:
            with open(f"/proc/{pid}/status") as handle:
                for line in handle:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) / 1024
        except OSError:
            pass
        return 0.0

    def _run(self):
        while not self._stop.wait(0.05):
            total = self._rss_mb("self")
            try:
                from sprayplan import parallel

                helper = parallel._helper
                if helper is not None:
                    total += self._rss_mb(helper.process.pid)
            except (ImportError, AttributeError):
                pass
            self.peak_mb = max(self.peak_mb, total)

    def start(self):
        self._thread.start()

    def stop(self):
        self._stop.set()
        self._thread.join()


def plan_digest(plan) -> dict:
    """Figures of the plan that the same plan repeats: its strokes' points, and the analytic and SQP joints."""
    import hashlib

    import numpy as np

    points = hashlib.sha1()
    q_analytic, q_sqp, n_sqp = 0.0, 0.0, 0
    for st in plan.stations:
        points.update(np.round(st.platform_mm, 6).tobytes())
        for stroke in st.strokes:
            points.update(np.round(stroke.tcp, 6).tobytes())
        ana, sqp = st.method == "analytic", st.method == "sqp"
        q_analytic += float(np.abs(st.q9[ana, :6]).sum())
        q_sqp += float(np.abs(st.q9[sqp, :6]).sum())
        n_sqp += int(sqp.sum())
    return {
        "points": points.hexdigest()[:12],
        "q_analytic": round(q_analytic, 4),
        "q_sqp": round(q_sqp, 3),
        "n_sqp": n_sqp,
    }


def start(name: str, src: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(src)}
    return subprocess.Popen(
        [sys.executable, __file__, "--child", name], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def finish(process: subprocess.Popen) -> dict:
    out, err = process.communicate()
    if process.returncode:
        raise SystemExit(
            f"a benchmark run failed: {err.strip().splitlines()[-1] if err.strip() else process.returncode}"
        )
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="demo,hull,bmw")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--base", help="another checkout to compare with (its src/ is used)")
    parser.add_argument("--new", help="the checkout to measure (default: this one)")
    parser.add_argument("--together", action="store_true", help="run the two builds at the same time")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--profile", help="with --child: write a cProfile file")
    parser.add_argument("--json", help="append every run's JSON line to this file")
    args = parser.parse_args()
    if args.child:
        child(args.child, args.profile)
        return
    builds = {"new": Path(args.new).resolve() / "src" if args.new else SRC}
    if args.base:
        builds["base"] = Path(args.base).resolve() / "src"
    for name in args.parts.split(","):
        runs: dict[str, list[dict]] = {b: [] for b in builds}
        for _ in range(args.repeat):
            if args.together:  # both builds at once: the same load on each
                started = {build: start(name, src) for build, src in builds.items()}
                reports = {build: finish(process) for build, process in started.items()}
            else:  # one after the other, interleaved
                reports = {build: finish(start(name, src)) for build, src in builds.items()}
            for build, report in reports.items():
                report["build"] = build
                runs[build].append(report)
                print(json.dumps(report), file=sys.stderr)
                if args.json:
                    with open(args.json, "a") as fh:
                        fh.write(json.dumps(report) + "\n")
        table(name, runs)


def table(name: str, runs: dict[str, list[dict]]) -> None:
    builds = list(runs)
    stages = list(runs[builds[0]][0]["stages_s"])

    def med(build, key, field="stages_s"):
        return statistics.median(r.get(field, {}).get(key, 0.0) for r in runs[build])

    print(f"\n#### {name}\n")
    head = " | ".join(f"{b} wall s | {b} CPU s" for b in builds)
    head += " | new / base, wall | new / base, CPU" if "base" in runs else ""
    print(f"| stage | {head} |")
    print("|---" * (2 * len(builds) + 1 + 2 * ("base" in runs)) + "|")
    for stage in stages:
        has_cpu = {b: all("stages_cpu_s" in r for r in runs[b]) for b in builds}
        cells = [
            f"{med(b, stage):.2f} | " + (f"{med(b, stage, 'stages_cpu_s'):.2f}" if has_cpu[b] else "-") for b in builds
        ]
        if "base" in runs:
            for field in ("stages_s", "stages_cpu_s"):
                base = med("base", stage, field) if field == "stages_s" or has_cpu["base"] else 0.0
                cells.append(f"{med('new', stage, field) / base:.2f}" if base > 0.05 else "-")
        print(f"| {stage} | {' | '.join(cells)} |")
    for key, label in (
        ("wall_s", "wall s (whole run)"),
        ("cpu_s", "CPU s (user + system)"),
        ("helper_cpu_s", "helper process CPU s"),
        ("maxrss_mb", "peak RSS MB"),
        ("helper_maxrss_mb", "helper process peak RSS MB"),
        ("together_peak_mb", "both processes at once, peak RSS MB (sampled every 50 ms)"),
    ):
        vals = {b: statistics.median(r.get(key, 0.0) for r in runs[b]) for b in builds}
        cells = [f"{vals[b]:.1f} |" for b in builds]
        if "base" in runs:
            cells.append(f"{vals['new'] / vals['base']:.2f} |" if vals["base"] > 0 else "- |")
        print(f"| {label} | {' | '.join(cells)} |")
    loads = {b: ", ".join(f"{r['load']:.1f}" for r in runs[b]) for b in builds}
    print(f"\nload average (1 min) at the end of each run: {loads}")
    for b in builds:
        r = runs[b][0]
        print(f"{b}: {r['stations']} stations, {r['strokes']} strokes, {r['waypoints']} waypoints, film {r['film']}")


if __name__ == "__main__":
    main()
