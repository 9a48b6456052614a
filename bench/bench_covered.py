"""The covered faces' search alone (``surface.region.covered_faces``, issue 17): this checkout against another.

Each part (``bmw``, ``suv``, ``hull``: the car bodies in line3's placement and orientation, the DTC hull as
loaded) is timed in fresh processes, this checkout's and, with ``--base DIR``, another's (``DIR/src``), one after
the other in turn, ``--repeat`` times; a process times the search twice and keeps the second (the first pays
for imports and caches). Each run prints one JSON line (wall seconds, the faces found covered, a digest of the
result, so that the two builds can be seen to give the same faces); the summary gives the medians and their
ratio.

Usage::

    python bench/bench_covered.py --parts bmw,hull --repeat 5 --base ../wt-base
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
PARTS = {
    "bmw": ("meshes/bmw_m6_body_m_yup.ply", "y", True),
    "suv": ("meshes/gazebo_suv_body_m.ply", "z", True),
    "hull": ("meshes/dtc_ship_hull_ascii.stl.gz", "z", False),
}


def child(name: str) -> None:
    sys.path.insert(0, str(HERE))
    from _data import testdata_dir

    from sprayplan.cells.spec import load_cell, place_part
    from sprayplan.io.load import load_part
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import covered_faces

    path, up, in_cell = PARTS[name]
    part = load_part(testdata_dir() / path, units="m", up=up)
    if in_cell:
        part = place_part(part, load_cell("line3")).part
    part = oriented_part(part)
    covered_faces(part, 20.0)
    start = time.perf_counter()
    found = covered_faces(part, 20.0)
    wall = time.perf_counter() - start
    digest = hashlib.sha256(found.tobytes()).hexdigest()[:12]
    print(json.dumps({"part": name, "wall_s": round(wall, 3), "covered": int(found.sum()), "digest": digest}))


def run(name: str, src: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src))
    out = subprocess.run(
        [sys.executable, __file__, "--child", name], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="bmw,hull")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--base", help="another checkout to compare with (its src/)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    builds = {"new": SRC} | ({"base": Path(args.base).resolve() / "src"} if args.base else {})
    for name in args.parts.split(","):
        runs: dict[str, list] = {b: [] for b in builds}
        for _ in range(args.repeat):
            for build, src in builds.items():
                result = run(name, src)
                runs[build].append(result)
                print(json.dumps({"build": build, **result}), flush=True)
        medians = {b: statistics.median(r["wall_s"] for r in rs) for b, rs in runs.items()}
        same = len({r["digest"] for rs in runs.values() for r in rs}) == 1
        line = ", ".join(f"{b} {m:.2f} s" for b, m in medians.items())
        ratio = f"; new / base {medians['new'] / medians['base']:.2f}" if "base" in medians else ""
        print(f"{name}: median of {args.repeat}: {line}{ratio}; same faces: {same}")


if __name__ == "__main__":
    main()
