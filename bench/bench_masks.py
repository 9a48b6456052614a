"""Masks on the car bodies (``plan --mask``, ``surface.region.mask_out``): the time to cut each mask out of the
painted surface, the area it takes and the faces it leaves, against the plain region cut (``select_region``) of
the same box, median of several runs.

    python bench/bench_masks.py [--runs 5]

The SUV's mask is the box round its running gear that docs/cells.md gives; the BMW's a box round the lower air
intake of its nose (a grille a shop would mask), both in the file's own frame (mm after the unit and the up axis).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _data import CAR_BODIES, testdata_dir  # noqa: E402

MASKS = {
    "suv": "box(-930, -1700, 0, 870, 1970, 660)",
    "bmw": "box(-2450, -300, -600, -2000, 300, -300)",
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args(argv)

    from sprayplan.config import CollisionConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import mask_out, painted_surface, select_region

    print(
        "| body | mask | painted surface | masked | faces before / after | mask_out | select_region (inside) | ratio |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for body, mask in MASKS.items():
        path, up = CAR_BODIES[body]
        painted, _ = painted_surface(
            oriented_part(load_part(testdata_dir() / path, units="m", up=up)), CollisionConfig()
        )
        cut, plain = [], []
        for _ in range(args.runs):
            t0 = time.perf_counter()
            kept, left = mask_out(painted, [mask])
            cut.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            select_region(painted, mask)
            plain.append(time.perf_counter() - t0)
        a, b = statistics.median(cut), statistics.median(plain)
        print(
            f"| {body} | `{mask}` | {painted.area / 1e6:.3f} m^2 | {left / 1e6:.3f} m^2 | {len(painted.faces):,} / "
            f"{len(kept.faces):,} | {1e3 * a:.1f} ms | {1e3 * b:.1f} ms | {a / b:.1f}x |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
