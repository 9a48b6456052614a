"""SLSQP with exact gradients against finite differences (issue 17): the same SQP problems solved by two builds.

The SQP problems (``robots.gantry.solve_sqp`` calls: Newton first, SLSQP where Newton gives no answer) of the
main job on each part are collected from one run of this checkout (one process, so that the helper's share is
seen too), then every problem is solved again by this checkout and by the ``--base`` checkout (its ``src``),
each in a fresh process. The table gives, over the problems SLSQP solved (not Newton): the wall time of all
solves, the problems answered within eqs. 21-22 by each, those one answers and the other does not, and eq.
20's total over the problems both answer.

Usage::

    python bench/bench_sqp_gradients.py --parts demo,hull,bmw --base ../wt-base
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"


def collect(name: str, out: str) -> None:
    """Run the main job on a part with one process and pickle its SQP problems to ``out``."""
    sys.path.insert(0, str(HERE))
    from bench_speed import part_and_job

    import sprayplan.job  # noqa: F401  (the package first: its modules import each other)
    import sprayplan.robots.gantry as gantry_module
    from sprayplan.job import run_job

    problems = []
    solve = gantry_module.solve_sqp

    def recording(gantry, target2world, start_q9, **options):
        problems.append((gantry, target2world, start_q9, options))
        return solve(gantry, target2world, start_q9, **options)

    gantry_module.solve_sqp = recording
    source, job = part_and_job(name)
    with tempfile.TemporaryDirectory() as tmp:
        run_job(source, job.replace(kinematics={"processes": 1}), outdir=tmp)
    with open(out, "wb") as handle:
        pickle.dump(problems, handle)


def replay(problems_path: str) -> None:
    """Solve the pickled problems with the sprayplan on ``sys.path``; print one JSON line."""
    import sprayplan.job  # noqa: F401
    import sprayplan.robots.gantry as gantry_module

    with open(problems_path, "rb") as handle:
        problems = pickle.load(handle)
    answers = []
    start = time.perf_counter()
    for gantry, target2world, start_q9, options in problems:
        result = gantry_module.solve_sqp(gantry, target2world, start_q9, **options)
        reference = options.get("reference_q9")
        reference = start_q9 if reference is None else reference
        dq, dt = result.q9[:6] - reference[:6], result.q9[6:] - reference[6:]
        cost = float(dq @ dq + options.get("k_d", 0.1) * dt @ dt)
        answers.append((bool(result.success), cost, result.message.startswith("Newton")))
    print(json.dumps({"wall_s": time.perf_counter() - start, "answers": answers}))


def run(src: Path, problems_path: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src))
    done = subprocess.run(
        [sys.executable, __file__, "--replay", problems_path], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="demo,hull,bmw")
    parser.add_argument("--base", help="another checkout (its src) to compare with")
    parser.add_argument("--repeat", type=int, default=3, help="replays of each build (the median time is given)")
    parser.add_argument("--collect", nargs=2, metavar=("PART", "OUT"), help=argparse.SUPPRESS)
    parser.add_argument("--replay", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.collect:
        return collect(*args.collect)
    if args.replay:
        return replay(args.replay)
    if not args.base:
        raise SystemExit("--base DIR: the checkout to compare with")
    print(
        "| part | SQP problems (SLSQP's) | wall s new / base (ratio) | answered new / base | only new / only base "
        "| eq. 20 total where both answer, new / base |"
    )
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.parts.split(","):
            path = str(Path(tmp) / f"{name}.pkl")
            env = dict(os.environ, PYTHONPATH=str(SRC))
            subprocess.run([sys.executable, __file__, "--collect", name, path], env=env, check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
            new_runs, base_runs = [], []
            for _ in range(args.repeat):  # interleaved
                new_runs.append(run(SRC, path))
                base_runs.append(run(Path(args.base) / "src", path))
            new_s = sorted(r["wall_s"] for r in new_runs)[len(new_runs) // 2]
            base_s = sorted(r["wall_s"] for r in base_runs)[len(base_runs) // 2]
            new, base = new_runs[0]["answers"], base_runs[0]["answers"]
            slsqp = [i for i, (b, n) in enumerate(zip(base, new)) if not (b[2] and n[2])]
            ok_new = sum(new[i][0] for i in slsqp)
            ok_base = sum(base[i][0] for i in slsqp)
            only_new = sum(new[i][0] and not base[i][0] for i in slsqp)
            only_base = sum(base[i][0] and not new[i][0] for i in slsqp)
            both = [i for i in slsqp if new[i][0] and base[i][0]]
            cost_new, cost_base = sum(new[i][1] for i in both), sum(base[i][1] for i in both)
            print(
                f"| {name} | {len(new)} ({len(slsqp)}) | {new_s:.2f} / {base_s:.2f} ({new_s / base_s:.2f}) | "
                f"{ok_new} / {ok_base} | {only_new} / {only_base} | {cost_new:,.0f} / {cost_base:,.0f} |"
            )


if __name__ == "__main__":
    main()
