"""Points on a triangle mesh: the seed's DFS triangle filling and an even (blue-noise) sampling.

Seed 000, section 2.2: a triangle S with centroid o is split into the three triangles (o, v1, v2),
(o, v2, v3), (o, v3, v1), depth first, while its smallest height is at least h_min. *Point filling* records the
centroid of every triangle that is split; *line filling* records points on the three segments from that centroid
to the triangle's vertices, every h_min, which fills the "unfilled lines" of the seed's figure 4a.

The even mode is not in the seed: it draws many random points on the surface (area-uniform) and keeps a
maximal subset in which no two points are closer than the spacing (Poisson-disk sampling by greedy elimination
in a random order), so the targets cover the surface evenly whatever the triangulation.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.checks import MAX_CANDIDATES
from sprayplan.errors import ConfigError

#: No filling may produce more points than this (protects against a spacing far too small for the part).
MAX_POINTS = MAX_CANDIDATES
#: Candidates of the even sampling per spacing^2 of area (``sample_even``'s default).
EVEN_OVERSAMPLE = 3.0
#: Points the DFS filling makes per (area / h_min^2), measured on plates and the demo roof (point: 0.2-0.5,
#: line: 2.6-3.2), rounded up: ``dfs_point_estimate``.
_DFS_POINTS_PER_H2 = {"point": 0.5, "line": 4.0}


def dfs_point_estimate(area_mm2: float, h_min_mm: float, mode: str = "point") -> float:
    """About how many points :func:`fill_dfs` makes on ``area_mm2`` at ``h_min_mm`` (an upper estimate)."""
    return _DFS_POINTS_PER_H2.get(mode, 4.0) * area_mm2 / h_min_mm**2


def triangle_area_heron(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Areas by Heron's formula (seed 000, eq. 2) and the longest side of each triangle.

    Heron's formula as printed loses all precision on needle triangles, which the centroid split produces at
    every level; this is the algebraically identical form of Kahan (sides sorted a >= b >= c)::

        S = 1/4 sqrt((a + (b + c)) (c - (a - b)) (c + (a - b)) (a + (b - c)))

    Parameters
    ----------
    triangles : (m, 3, 3) float

    Returns
    -------
    area : (m,) float
    longest : (m,) float
    """
    sides = np.stack(
        [
            np.linalg.norm(triangles[:, 1] - triangles[:, 0], axis=1),
            np.linalg.norm(triangles[:, 2] - triangles[:, 1], axis=1),
            np.linalg.norm(triangles[:, 0] - triangles[:, 2], axis=1),
        ],
        axis=1,
    )
    c, b, a = np.sort(sides, axis=1).T
    product = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return 0.25 * np.sqrt(np.maximum(product, 0.0)), a


def fill_dfs(triangles: np.ndarray, h_min_mm: float, mode: str = "point") -> tuple[np.ndarray, np.ndarray]:
    """The seed's DFS triangle filling (seed 000, section 2.2, eqs. 1-3, figures 2-4).

    A triangle is split when its smallest height ``2 S / max(l1, l2, l3)`` is at least ``h_min``, which is
    eq. 1 read as ``S >= max(l1, l2, l3) * h_min / 2``. (The printed eq. 3, ``S >= 2 max(l) h_min``, has lost
    the division: with it a triangle would need a height of 4 h_min to be split, contradicting the text's "the
    minimum height ... is less than the specified minimum height" stop rule.) A split triangle records its
    centroid (``mode="point"``) or the points every ``h_min`` along the segments from the centroid to its three
    vertices, the vertices themselves excluded (``mode="line"``). The recursion is evaluated one depth level at
    a time over all triangles at once; the set of points equals that of the depth-first recursion.

    Parameters
    ----------
    triangles : (m, 3, 3) float, mm
    h_min_mm : float
        The minimum triangle height h_min.
    mode : {"point", "line"}

    Returns
    -------
    points : (k, 3) float, mm
    face_index : (k,) int
        Index into ``triangles`` of the triangle each point lies in.
    """
    if not h_min_mm > 0:
        raise ConfigError(f"h_min must be positive, got {h_min_mm}")
    if mode not in ("point", "line"):
        raise ConfigError(f"fill mode must be 'point' or 'line', got {mode!r}")
    current = np.asarray(triangles, dtype=float)
    owner = np.arange(len(current))
    points, index, total = [], [], 0
    while len(current):
        area, longest = triangle_area_heron(current)
        split = area >= 0.5 * longest * h_min_mm
        current, owner = current[split], owner[split]
        if not len(current):
            break
        if total + 3 * len(current) > 3 * MAX_POINTS:  # the next level's triangles alone would not fit
            _too_many(h_min_mm)
        centroid = current.mean(axis=1)
        if mode == "point":
            new, new_owner = centroid, owner
        else:
            new, new_owner = _segment_points(centroid, current, owner, h_min_mm, MAX_POINTS - total)
        total += len(new)
        if total > MAX_POINTS:
            _too_many(h_min_mm)
        points.append(new)
        index.append(new_owner)
        o = centroid[:, None, :]
        v1, v2, v3 = current[:, 0:1], current[:, 1:2], current[:, 2:3]
        current = np.concatenate(
            [np.concatenate([o, v1, v2], 1), np.concatenate([o, v2, v3], 1), np.concatenate([o, v3, v1], 1)]
        )
        owner = np.concatenate([owner, owner, owner])
    if not points:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(points), np.concatenate(index).astype(np.int64)


def _too_many(h_min_mm):
    raise ConfigError(
        f"targets.h_min_mm {h_min_mm:g}: the filling would make more than {MAX_POINTS} points: use a larger"
        " targets.h_min_mm (or targets.spacing_mm, whose half it is by default)"
    )


def _segment_points(centroid, triangles, owner, step, budget):
    """Points every ``step`` from each centroid towards each vertex (the centroid once, vertices excluded)."""
    starts = np.repeat(centroid, 3, axis=0)
    ends = triangles.reshape(-1, 3)
    owners = np.repeat(owner, 3)
    length = np.linalg.norm(ends - starts, axis=1)
    count = np.ceil(length / step - 1e-9)  # k = 1 .. count-1 lie strictly before the vertex
    count = np.maximum(count - 1, 0)
    if count.sum() + len(centroid) > budget:
        _too_many(step)
    count = count.astype(np.int64)
    seg = np.repeat(np.arange(len(starts)), count)
    k = np.arange(len(seg)) - np.repeat(np.cumsum(count) - count, count) + 1
    t = (k * step / np.maximum(length[seg], 1e-300))[:, None]
    along = starts[seg] + t * (ends[seg] - starts[seg])
    return np.concatenate([centroid, along]), np.concatenate([owner, owners[seg]])


def sample_uniform(triangles: np.ndarray, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Area-uniform random points on triangles.

    Returns
    -------
    points : (count, 3) float
    face_index : (count,) int
    """
    e1 = triangles[:, 1] - triangles[:, 0]
    e2 = triangles[:, 2] - triangles[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    cumulative = np.cumsum(area)
    face = np.searchsorted(cumulative, rng.random(count) * cumulative[-1], side="right")
    face = np.minimum(face, len(triangles) - 1)
    u, v = rng.random(count), rng.random(count)
    fold = u + v > 1.0
    u[fold], v[fold] = 1.0 - u[fold], 1.0 - v[fold]
    points = triangles[face, 0] + u[:, None] * e1[face] + v[:, None] * e2[face]
    return points, face


def sample_even(
    triangles: np.ndarray, spacing_mm: float, *, seed: int = 0, oversample: float = EVEN_OVERSAMPLE
) -> tuple[np.ndarray, np.ndarray]:
    """Even sampling: points on the surface, no two closer than ``spacing_mm``, leaving no large gaps.

    ``oversample * area / spacing^2`` random candidates are drawn (area-uniform) and visited in a random order;
    a candidate is kept unless a kept candidate lies within the spacing (Poisson-disk sampling by dart throwing
    over a finite pool). The greedy pass is computed in parallel rounds over the conflict graph (a candidate is
    decided once every conflicting candidate that comes earlier is decided), which gives exactly the sequential
    result in a handful of vectorised rounds.

    Parameters
    ----------
    triangles : (m, 3, 3) float, mm
    spacing_mm : float
        The smallest distance between two points (the Poisson-disk radius).
    seed : int
        Random seed: the same seed gives the same points.
    oversample : float
        Candidates per spacing^2 of area. 3 leaves few gaps (see docs/benchmarks.md); more costs time.

    Returns
    -------
    points : (k, 3) float, mm
    face_index : (k,) int
    """
    if not spacing_mm > 0:
        raise ConfigError(f"spacing must be positive, got {spacing_mm}")
    triangles = np.asarray(triangles, dtype=float)
    area = (
        0.5
        * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]), axis=1).sum()
    )
    count = int(np.ceil(oversample * area / spacing_mm**2)) + 1
    if count > MAX_POINTS:
        lowest = math.sqrt(oversample * area / MAX_POINTS)
        raise ConfigError(
            f"targets.spacing_mm {spacing_mm:g}: even sampling needs {count} candidates on {area:.4g} mm^2 (at most"
            f" {MAX_POINTS}): use targets.spacing_mm >= {lowest:.3g} (or a larger spray_radius_mm / overlap)"
        )
    rng = np.random.default_rng(seed)
    candidates, face = sample_uniform(triangles, count, rng)
    keep = poisson_disk_select(candidates, spacing_mm)
    return candidates[keep], face[keep]


def poisson_disk_select(points: np.ndarray, radius: float) -> np.ndarray:
    """Greedy maximal subset with no two points within ``radius``, visiting points in index order.

    Parameters
    ----------
    points : (n, 3) float
        Candidates, already in a random order.
    radius : float

    Returns
    -------
    keep : (k,) int
        Indices of the kept points, increasing.
    """
    n = len(points)
    tree = cKDTree(points, balanced_tree=False, compact_nodes=False)
    pairs = tree.query_pairs(radius, output_type="ndarray")
    state = np.zeros(n, dtype=np.int8)  # 0 undecided, 1 kept, -1 removed
    if len(pairs) == 0:
        return np.arange(n)
    lo, hi = pairs.min(axis=1), pairs.max(axis=1)  # lo comes before hi in the visiting order
    has_earlier = np.zeros(n, dtype=bool)
    has_earlier[hi] = True
    state[~has_earlier] = 1
    while True:
        # an undecided point with a kept earlier neighbour is removed
        hit = np.zeros(n, dtype=bool)
        hit[hi[state[lo] == 1]] = True
        state[(state == 0) & hit] = -1
        undecided = state == 0
        if not undecided.any():
            return np.flatnonzero(state == 1)
        live = undecided[hi]
        lo, hi = lo[live], hi[live]
        # an undecided point whose earlier neighbours are all decided (so all removed) is kept
        blocked = np.zeros(n, dtype=bool)
        blocked[hi[undecided[lo]]] = True
        state[undecided & ~blocked] = 1
