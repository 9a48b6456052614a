"""Benchmark of batches: jobs per minute of the local engine and of a Dask LocalCluster, 1 and 2 workers.

The batch: the tray plate (``meshes/tray_bottom_mm_ascii.stl``) with a sweep of ``--jobs`` stroke spacings
(100, 105, ... mm), no pictures, no film: small jobs, so that the engines' overhead shows. Each engine and
worker count runs the whole batch ``--repeat`` times into a fresh folder (``--force`` is not needed: a new
folder each time); the table gives the median wall time, jobs per minute, the ratio to the local engine
with one worker, the seconds a job takes inside its worker (``job_time_s`` of the rows, mean), the engine's
overhead a job (wall time x workers / jobs minus that: starting, shipping, collecting), the difference to
running the same jobs one after another in this process (``run_job``, no engine), and the median peak
memory of a job's process (``peak_memory_mb`` of the rows).

Usage::

    python bench/bench_batch.py [--jobs 20] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir


def batch_text(part: Path, jobs: int) -> str:
    spacings = ", ".join(str(100 + 5 * i) for i in range(jobs))
    return (
        f'[[job]]\nparts = "{part}"\n[job.output]\nviewer = false\nreport = false\n'
        f"[job.sweep]\npaths.spacing_mm = [{spacings}]\n"
    )


def direct_walls(batch, repeat: int) -> list[float]:
    """Wall seconds of the batch's jobs run directly (``run_job`` with its outputs, one after another in this
    process, after one warm-up job), ``repeat`` times."""
    from sprayplan.job import run_job

    walls = []
    with tempfile.TemporaryDirectory() as folder:
        run_job(batch.jobs[0].part, batch.jobs[0].config)
        for k in range(repeat):
            began = time.perf_counter()
            for job in batch.jobs:
                run_job(job.part, job.config, outdir=Path(folder) / f"{k}" / job.job_id)
            walls.append(time.perf_counter() - began)
    return walls


def timed(batch, engine: str, workers: int, repeat: int) -> tuple[list[float], float, list[float]]:
    """Wall seconds of each run, the median peak memory of a job, and each run's seconds spent inside the
    jobs (``job_time_s`` summed)."""
    from sprayplan.batch import run_batch

    walls, memory, inside = [], [], []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as folder:
            if engine == "local":
                began = time.perf_counter()
                result = run_batch(batch, Path(folder) / "out", workers=workers)
                walls.append(time.perf_counter() - began)
            else:
                from distributed import Client, LocalCluster

                with LocalCluster(n_workers=workers, threads_per_worker=1, dashboard_address=None) as cluster:
                    with Client(cluster) as client:
                        client.wait_for_workers(workers)
                        began = time.perf_counter()  # the cluster's start-up is not counted
                        result = run_batch(batch, Path(folder) / "out", client)
                        walls.append(time.perf_counter() - began)
        assert result.exit_code == 0, [r["error"] for r in result.rows if r["status"] != "ok"]
        memory += [r["peak_memory_mb"] for r in result.rows]
        inside.append(sum(r["job_time_s"] for r in result.rows))
    return walls, statistics.median(memory), inside


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    import tomllib

    from sprayplan.batch.spec import jobs_from_dict

    part = meshes_dir() / "tray_bottom_mm_ascii.stl"
    jobs, _ = jobs_from_dict(tomllib.loads(batch_text(part, args.jobs)), part.parent)
    from sprayplan.batch import Batch

    batch = Batch("bench", tuple(jobs))
    walls = direct_walls(batch, args.repeat)
    direct = statistics.median(walls) / args.jobs
    print(f"### Batches: {args.jobs} tray jobs (spacing sweep, no film, no pictures)\n")
    print(f"`python bench/bench_batch.py --jobs {args.jobs} --repeat {args.repeat}`\n")
    print("| engine | workers | runs (s) | median s | jobs/min | vs local 1 | s a job inside | overhead s/job "
          "| vs direct s/job | peak MB/job |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    runs = ", ".join(f"{w:.1f}" for w in walls)
    print(f"| direct `run_job` | 1 (this process) | {runs} | {statistics.median(walls):.1f} | "
          f"{60 / direct:.1f} | | {direct:.2f} | | | |", flush=True)  # fmt: skip
    base = None
    for engine in ("local", "dask"):
        for workers in (1, 2):
            walls, memory, inside = timed(batch, engine, workers, args.repeat)
            wall = statistics.median(walls)
            base = base or wall
            rate = 60 * args.jobs / wall
            k = walls.index(wall)
            job = inside[k] / args.jobs
            overhead = wall * workers / args.jobs - job  # the engine's time a job, outside the job itself
            runs = ", ".join(f"{w:.1f}" for w in walls)
            print(f"| {engine} | {workers} | {runs} | {wall:.1f} | {rate:.1f} | {base / wall:.2f}x | {job:.2f} | "
                  f"{overhead:+.2f} | {wall * workers / args.jobs - direct:+.2f} | {memory:.0f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
