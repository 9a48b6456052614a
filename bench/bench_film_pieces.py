"""Where a car body's cell plan leaves its film out of spec, by mesh piece and by area (issue 18).

Reads a plan folder written by ``sprayplan plan BODY --cell line3 --thickness-um 50 -o OUT`` (its
``thickness.csv`` film samples and ``areas.csv``), places and cuts the body again as the plan did
(``bench_area_parts``: the painted surface, its connected pieces), gives each film sample to the face whose
centre is nearest and weights it by that face's area over the samples it got. Printed: the share of the
painted surface in spec so weighted (near the plan's own figure, which weights the samples by their own area),
then the pieces and the areas that lose the most: per piece or area its share of the surface, the share of the
whole surface it leaves out of spec, and of that the share bare (under 1 um), all in per cent of the whole.

    python bench/bench_film_pieces.py --body bmw OUT
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from bench_area_parts import BODIES, face_pieces, painted_in_cell

#: A sample under this many um is bare.
BARE_UM = 1.0


def losses(labels: np.ndarray, weight: np.ndarray, ok: np.ndarray, bare: np.ndarray, top: int) -> list:
    """The ``top`` labels that leave the most of the surface out of spec: (label, share of the surface, share
    out of spec, share bare), per cent of the whole."""
    total = weight.sum()
    rows = []
    for k in np.unique(labels):
        m = labels == k
        rows.append((str(k), 100 * weight[m].sum() / total, 100 * weight[m & ~ok].sum() / total,
                     100 * weight[m & bare].sum() / total))  # fmt: skip
    rows.sort(key=lambda r: -r[2])
    return [[r[0], *(round(x, 2) for x in r[1:])] for r in rows[:top]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", help="the plan folder")
    ap.add_argument("--body", default="bmw", choices=sorted(BODIES))
    ap.add_argument("--cell", default="line3")
    ap.add_argument("--target-um", type=float, default=50.0)
    ap.add_argument("--tolerance-um", type=float, default=5.0)
    ap.add_argument("--top", type=int, default=10)
    args = ap.parse_args()
    painted = painted_in_cell(args.body, args.cell)
    with open(Path(args.out) / "areas.csv", newline="") as handle:
        area_of = np.array([row["area"] for row in csv.DictReader(handle)])
    if len(area_of) != len(painted.faces):
        raise SystemExit(f"{args.out}: areas.csv has {len(area_of)} faces, the body cut again {len(painted.faces)}")
    film = np.loadtxt(Path(args.out) / "thickness.csv", delimiter=",", skiprows=1, ndmin=2)
    face = cKDTree(painted.triangles.mean(axis=1)).query(film[:, :3])[1]
    count = np.bincount(face, minlength=len(painted.faces))
    weight = painted.face_areas[face] / count[face]
    um = film[:, 3]
    ok = np.abs(um - args.target_um) <= args.tolerance_um
    bare = um < BARE_UM
    piece = face_pieces(painted)
    print(json.dumps({"out": args.out, "in_spec": round(100 * weight[ok].sum() / weight.sum(), 2),
                      "bare": round(100 * weight[bare].sum() / weight.sum(), 2),
                      "pieces": losses(piece[face], weight, ok, bare, args.top),
                      "areas": losses(area_of[face], weight, ok, bare, args.top)}))  # fmt: skip


if __name__ == "__main__":
    main()
