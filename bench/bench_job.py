"""Benchmark of the main job's stages and of its progress display.

1. ``run_job`` on the demo roof (z > 1000) with a 50 um film target: wall seconds of every stage
   (``JobResult.timings_s``), median of ``--repeat`` runs, and how many progress calls each stage makes.
2. The progress display's cost: the time of one call of the command line's display (``cli.common.
   ProgressDisplay``: plain lines, and the tqdm bar of a terminal) measured over many calls, times the calls
   a stage makes, as a share of that stage's time. The display must cost under 1 % of a stage.

Usage::

    python bench/bench_job.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import collections
import io
import statistics
import sys
import time
from pathlib import Path

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def demo_job():
    from sprayplan.config import JobConfig
    from sprayplan.demo import DEMO_REGION, car_roof

    return car_roof(), JobConfig().replace(load={"region": DEMO_REGION}, coating={"thickness_um": 50.0})


def stage_times(repeat: int) -> tuple[dict, collections.Counter]:
    from sprayplan.job import STAGES, run_job

    part, job = demo_job()
    runs: dict[str, list[float]] = collections.defaultdict(list)
    calls: collections.Counter = collections.Counter()
    for i in range(repeat):
        counted: collections.Counter = collections.Counter()
        result = run_job(part, job, progress=lambda stage, done, total, c=counted: c.update([stage]))
        for name, seconds in result.timings_s.items():
            runs[name].append(seconds)
        if i == 0:
            calls = counted
    print("### Stages of the main job (demo roof z > 1000, 50 um target)\n")
    print(f"`python bench/bench_job.py --repeat {repeat}`: `run_job` in one process, wall s per stage.\n")
    print("| stage | runs (s) | median s | progress calls |")
    print("|---|---|---|---|")
    medians = {}
    for stage in [s.name for s in STAGES]:
        times = runs[stage]
        medians[stage] = statistics.median(times)
        print(f"| {stage} | {', '.join(f'{t:.2f}' for t in times)} | {medians[stage]:.2f} | {calls[stage]} |")
    total = [sum(r[i] for r in runs.values()) for i in range(repeat)]
    print(f"| all | {', '.join(f'{t:.1f}' for t in total)} | {statistics.median(total):.1f} | {sum(calls.values())} |")
    print()
    return medians, calls


def call_cost(tty: bool, calls: int = 20000, repeat: int = 5) -> float:
    """Median seconds of one display call (a counted stage's updates, as the job sends them)."""
    from sprayplan.cli.common import ProgressDisplay

    times = []
    for _ in range(repeat):
        display = ProgressDisplay(stream=io.StringIO(), tty=tty)
        if tty:  # the bar writes to stderr: keep it off the report
            saved, sys.stderr = sys.stderr, io.StringIO()
        try:
            start = time.perf_counter()
            display("bench", 0, 0)
            for done in range(1, calls + 1):
                display("bench", done, calls)
            display.close()
            times.append((time.perf_counter() - start) / (calls + 1))
        finally:
            if tty:
                sys.stderr = saved
    return statistics.median(times)


def display_cost(medians: dict, calls: collections.Counter) -> None:
    plain, bar = call_cost(tty=False), call_cost(tty=True)
    print("### Cost of the progress display\n")
    print("One call's median time over 20,000 calls (5 runs), times the calls each stage makes, over the stage's")
    print("median time from the table above.\n")
    print(f"Plain lines: {plain * 1e6:.2f} us a call; tqdm bar: {bar * 1e6:.2f} us a call.\n")
    print("| stage | calls | stage s | plain lines, share | tqdm bar, share |")
    print("|---|---|---|---|---|")
    for stage, seconds in medians.items():
        n = calls[stage]
        if seconds <= 0:
            continue
        print(
            f"| {stage} | {n} | {seconds:.2f} | {100 * n * plain / seconds:.4f} % | {100 * n * bar / seconds:.4f} % |"
        )
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    medians, calls = stage_times(args.repeat)
    display_cost(medians, calls)


if __name__ == "__main__":
    main()
