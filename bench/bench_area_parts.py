"""What each automatic area of a car body is made of (issue 18: why the SUV's ends are painted so badly).

Each body is placed in ``--cell`` and cut to its painted surface as ``sprayplan plan --cell`` does (the surface
facing the floor and the covered surface left out; ``cells.plan.area_surface``), then split into areas
(``surface.areas.segment_areas``). Printed: the painted surface's connected pieces (faces joined by shared
edges), each with its area and bounds in the cell frame, largest first; and per area its surface, how much of
it lies on each piece, and how far its faces agree on a direction: the length of the area-weighted mean of its
unit normals (1 for a flat panel, near 0 for faces turned every way, such as a box's sides together).

    python bench/bench_area_parts.py --body suv
    python bench/bench_area_parts.py --body bmw
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir
from bench_cell_collisions import BODIES


def face_pieces(part) -> np.ndarray:
    """(m,) int: the connected piece of each face of a mesh ``Part``, faces joined where they share an edge
    (``surface.areas.face_adjacency``), pieces numbered by decreasing face count."""
    from sprayplan.surface.areas import face_adjacency

    m = len(part.faces)
    pairs, _ = face_adjacency(part.faces, part.vertices)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    _, label = connected_components(graph, directed=False)
    counts = np.bincount(label)
    rank = np.empty_like(counts)
    rank[np.argsort(-counts, kind="stable")] = np.arange(len(counts))
    return rank[label]


def painted_in_cell(body: str, cell_name: str):
    """The body placed in the cell and cut to the surface ``sprayplan plan --cell`` paints (the surface facing
    the floor and the covered surface left out, long faces split: ``cells.plan.area_surface``)."""
    from sprayplan.cells import load_cell
    from sprayplan.cells.plan import area_surface
    from sprayplan.cells.spec import place_part
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import painted_surface

    name, load = BODIES[body]
    placed = place_part(load_part(str(meshes_dir() / name), **load), load_cell(cell_name))
    painted, _ = painted_surface(oriented_part(placed.part), JobConfig().collision)
    return area_surface(painted)[0]


def main() -> None:
    from sprayplan.surface.areas import segment_areas

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--body", default="suv", choices=sorted(BODIES))
    ap.add_argument("--cell", default="line3")
    args = ap.parse_args()
    painted = painted_in_cell(args.body, args.cell)
    areas = segment_areas(painted)
    piece = face_pieces(painted)
    fa = painted.face_areas
    pieces = []
    for p in range(piece.max() + 1):
        mine = piece == p
        tri = painted.triangles[mine].reshape(-1, 3)
        pieces.append({"piece": p, "faces": int(mine.sum()), "m2": round(float(fa[mine].sum()) / 1e6, 3),
                       "lo_mm": tri.min(axis=0).round(0).tolist(), "hi_mm": tri.max(axis=0).round(0).tolist()})  # fmt: skip
    print(json.dumps({"body": args.body, "painted_m2": round(float(fa.sum()) / 1e6, 3), "pieces": pieces}))
    for a, label in enumerate(areas.names):
        mine = areas.face_area == a
        w = fa[mine]
        agree = float(np.linalg.norm((areas.face_normals[mine] * w[:, None]).sum(axis=0)) / w.sum())
        on = np.bincount(piece[mine], weights=w, minlength=piece.max() + 1) / w.sum()
        print(json.dumps({"area": label, "m2": round(float(w.sum()) / 1e6, 3), "normals_agree": round(agree, 3),
                          "share_on_piece": {int(p): round(float(s), 3) for p, s in enumerate(on) if s >= 0.005}}))  # fmt: skip


if __name__ == "__main__":
    main()
