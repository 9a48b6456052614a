"""Areas found automatically: a part's surface split into patches of one surface direction, and each patch given
to the robot that reaches it best (issue 18; seed 003, section 5, where the split was made by hand).

Seed 003 paints a car body with three ABB robots on one line. The body is divided "into three parts: the roof
and rear, the left side of the body, and the right side of the body", each painted by its own robot with its
own slicing direction, and the seed names the hand-made split its weakness. Here the split is made in two
steps, both over the mesh itself:

1. :func:`segment_areas`: each face is labelled with the *direction class* its outward normal is nearest to
   (:data:`DIRECTIONS`, in the cell frame: the part's length along x, z up; ``side +y`` is a car's left side
   when its front faces +x). Faces of one class that share an edge grow into one patch (connected components over
   the mesh's edges). A patch under ``min_share`` of the surface is an island (a door handle, a panel gap,
   a wheel arch lip): it is merged into the neighbouring patch it shares the longest edge length with, the
   smallest island first, until none is left, but never into a patch whose mean normal is more than
   :data:`OPPOSED_DEG` from its own (a bumper's face into its back, which it meets along the bumper's lower
   edge: no robot paints both from one side, and an area holding both had its strokes wrap from the face
   onto the back, where the arm meets the body); an island whose neighbours all face away stays an area (a
   sliver under :data:`OPPOSED_KEPT` of the island share joins one anyway); an island that shares no edge
   with anything (a separate shell of a mesh that is not welded) joins the patch nearest to it in space. The
   patches that remain are the areas: the roof, hood and boot lid face up (``top``), the two sides face +-y, the two ends face +-x.
2. :func:`assign_areas`: given which robot reaches which face (:func:`reach_matrix` from the robots'
   inverse kinematics, a score in [0, 1] a face), each area goes to the robot that reaches the largest
   share of its surface with the gun along the normal (a face reached only with a tilted gun scores at most
   :data:`TILTED` and counts only where that share ties, such as an area no robot reaches straight; ties
   beyond that: the larger share reached at all, the higher mean score, then the lower robot index). An area no single robot
   reaches whole is split along the seam where the reach changes: its faces the chosen robot does not reach
   go to the robot that reaches them best, and so do its faces the chosen robot reaches only at the edge of
   its reach (a score under :data:`ROBUST`) where another robot scores more, so that the seam lies where both
   reach well, not where one of them stretches; faces no robot reaches are left out (``-1``) and reported as
   data (:attr:`AreaAssignment.unreached_mm2`), never an exception.

Every step is deterministic: no random numbers are drawn.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from sprayplan.errors import ConfigError
from sprayplan.surface.normals import part_outward
from sprayplan.surface.pairs import unique_pairs
from sprayplan.types import Part, read_only

log = logging.getLogger(__name__)

#: The direction classes, unit vectors in the cell frame (x along the part, z up). They are named by the cell's
#: axes, not the part's: which end of a car is its front depends on how it stands in the cell (``side +y`` is
#: the car's left side when its front faces +x).
DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "top": (0.0, 0.0, 1.0),
    "side +y": (0.0, 1.0, 0.0),
    "side -y": (0.0, -1.0, 0.0),
    "end +x": (1.0, 0.0, 0.0),
    "end -x": (-1.0, 0.0, 0.0),
    "bottom": (0.0, 0.0, -1.0),
}
#: ``min_share`` by default: a patch under 3 % of the surface is an island.
MIN_SHARE = 0.03
#: An island under this share of ``min_share`` (0.3 % of the surface by default) joins a neighbour facing away
#: from it too (``_merge_islands``): kept apart, the slivers along a car body's sharp edges made 16 areas of
#: under 0.1 m^2 on the BMW.
OPPOSED_KEPT = 0.1
#: An island joins no neighbour whose mean outward normal is more than this from its own (``_merge_islands``).
OPPOSED_DEG = 120.0


@dataclass(frozen=True)
class Areas:
    """A part's surface split into areas of one direction class.

    Attributes
    ----------
    face_area : (m,) int
        The area of each face of the part (an index into the other attributes).
    names : tuple of str
        ``"top"``, ``"side +y"``, ... in order of decreasing area; a class with more than one area numbers them
        (``"top"``, ``"top 2"``).
    direction : tuple of str
        The direction class of each area (a key of :data:`DIRECTIONS`).
    area_mm2 : (k,) float
    normal : (k, 3) float
        The area-weighted mean outward normal of each area, unit length (zero when the normals cancel).
    face_normals : (m, 3) float
        The outward unit normal of every face.
    """

    face_area: np.ndarray
    names: tuple
    direction: tuple
    area_mm2: np.ndarray
    normal: np.ndarray
    face_normals: np.ndarray

    def __post_init__(self):
        read_only(self)

    def __len__(self) -> int:
        return len(self.names)


@dataclass(frozen=True)
class AreaAssignment:
    """Which robot paints which face.

    Attributes
    ----------
    face_robot : (m,) int
        The robot of each face, ``-1`` where no robot reaches it.
    area_robot : (k,) int
        The robot each area was given to (the one reaching the largest share of it); ``-1`` when none
        reaches any of it.
    area_share : (k,) float
        The share of each area's surface its robot reaches, 0..1.
    split : (k,) bool
        The area was split: some of its faces went to another robot.
    robot_area_mm2 : (r,) float
        The surface each robot paints.
    unreached_mm2 : float
        The surface no robot reaches (left out, reported).
    """

    face_robot: np.ndarray
    area_robot: np.ndarray
    area_share: np.ndarray
    split: np.ndarray
    robot_area_mm2: np.ndarray
    unreached_mm2: float

    def __post_init__(self):
        read_only(self)


def face_adjacency(faces: np.ndarray, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of faces that share an edge, ((p, 2) int, each pair once with the lower face first), and the
    length of the shared edge, (p,) mm. Where more than two faces share an edge (a non-manifold edge), each
    face is paired with the next one around it in index order."""
    faces = np.asarray(faces, dtype=np.int64)
    m = len(faces)
    if m == 0:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    edges = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(m), 3)
    keys, inverse = unique_pairs(edges, return_inverse=True)
    order = np.lexsort((owner, inverse))
    same = inverse[order][1:] == inverse[order][:-1]
    a, b = owner[order][:-1][same], owner[order][1:][same]
    distinct = a != b
    a, b = a[distinct], b[distinct]
    edge = keys[inverse[order][1:][same][distinct]]
    length = np.linalg.norm(vertices[edge[:, 0]] - vertices[edge[:, 1]], axis=1)
    pairs = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    return pairs, length


def _cos(u: np.ndarray, v: np.ndarray) -> float:
    """The cosine of the angle between two vectors (1 where either is zero: no direction opposes it)."""
    norm = float(np.linalg.norm(u) * np.linalg.norm(v))
    return float(u @ v) / norm if norm > 0 else 1.0


def _components(m: int, pairs: np.ndarray) -> np.ndarray:
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    return csgraph.connected_components(graph, directed=False)[1]


def _merge_islands(
    comp: np.ndarray,
    face_area: np.ndarray,
    pairs: np.ndarray,
    length: np.ndarray,
    centres: np.ndarray,
    limit: float,
    facing: np.ndarray | None = None,
) -> np.ndarray:
    """Patches under ``limit`` mm^2 merged into the neighbour they share the most edge length with (smallest
    first), then patches with no neighbour into the nearest patch in space. Returns the merged labels.

    ``facing`` (n, 3), each patch's area-weighted sum of outward normals (summed again as patches merge): an
    island never joins a patch whose mean normal is more than :data:`OPPOSED_DEG` from its own, so that no area
    holds both sides of a thin part (a bumper's face and its back, which meet along its lower edge: one slicing
    direction and one robot's side cannot paint both). An island whose neighbours all face away stays an
    area of its own, unless it is under :data:`OPPOSED_KEPT` of ``limit`` (a sliver along a sharp edge)."""
    n = int(comp.max()) + 1
    facing = np.zeros((n, 3)) if facing is None else np.array(facing, dtype=float)
    opposed = math.cos(math.radians(OPPOSED_DEG))
    area = np.bincount(comp, face_area, n)
    # boundary length between patches, as a dict of dicts (patches of a car body: a few thousand at most)
    ca, cb = comp[pairs[:, 0]], comp[pairs[:, 1]]
    cross = ca != cb
    key, inverse = unique_pairs(np.sort(np.stack([ca[cross], cb[cross]], axis=1), axis=1), return_inverse=True)
    shared = np.bincount(inverse, length[cross], len(key))
    border: list[dict[int, float]] = [{} for _ in range(n)]
    for (u, v), w in zip(key.tolist(), shared.tolist()):
        border[u][v] = w
        border[v][u] = w
    parent = np.arange(n)
    alive = np.ones(n, bool)

    def joinable(i: int) -> list:
        if area[i] < OPPOSED_KEPT * limit:  # a sliver: into any neighbour, as it makes no area of its own
            return list(border[i].items())
        return [(k, w) for k, w in border[i].items() if _cos(facing[i], facing[k]) >= opposed]

    while True:
        small = np.flatnonzero(alive & (area < limit))
        small = small[[bool(joinable(i)) for i in small]] if len(small) else small
        if not len(small):
            break
        i = int(small[np.lexsort((small, area[small]))[0]])
        j = max(joinable(i), key=lambda item: (item[1], -item[0]))[0]
        # i joins j
        for k, w in border[i].items():
            if k == j:
                continue
            border[j][k] = border[j].get(k, 0.0) + w
            border[k][j] = border[j][k]
            del border[k][i]
        del border[j][i]
        border[i] = {}
        parent[i] = j
        area[j] += area[i]
        facing[j] += facing[i]
        area[i] = 0.0
        alive[i] = False
    # follow the merges to their roots
    while True:
        step = parent[parent]
        if np.array_equal(step, parent):
            break
        parent = step
    merged = parent[comp]
    # islands without neighbours: into the nearest patch in space that is not one (an island kept because its
    # neighbours all face away from it has neighbours, and stays)
    final_area = np.bincount(merged, face_area, n)
    bordered = np.array([bool(b) for b in border])
    big = (final_area[merged] >= limit) | bordered[merged]
    if big.any() and not big.all():
        tree = cKDTree(centres[big])
        _, nearest = tree.query(centres[~big])
        lone = np.flatnonzero(~big)
        target = merged[np.flatnonzero(big)[nearest]]
        # a whole island goes where the majority of its faces' nearest neighbours are
        for island in np.unique(merged[lone]):
            mine = merged[lone] == island
            votes = np.bincount(target[mine], face_area[lone][mine])
            merged[lone[mine]] = int(np.argmax(votes))
    return merged


def segment_areas(part: Part, min_share: float = MIN_SHARE, directions: dict | None = None) -> Areas:
    """The part's surface split into areas of one direction class (module docstring, step 1).

    Parameters
    ----------
    part : Part
        A mesh in the cell frame (x along the part, z up).
    min_share : float
        A patch under this share of the surface is an island, merged into a neighbour; in [0, 1).
    directions : dict of str to (3,) float, optional
        The direction classes; :data:`DIRECTIONS` by default.

    Raises
    ------
    ConfigError
        For a point cloud, a part without area, or ``min_share`` out of range.
    """
    if not part.is_mesh:
        raise ConfigError(f"part {part.name!r}: areas are found on meshes only (this is a point cloud)")
    if not (0.0 <= float(min_share) < 1.0):
        raise ConfigError(f"min_share: must be in [0, 1), got {min_share!r}")
    directions = dict(DIRECTIONS if directions is None else directions)
    names = list(directions)
    basis = np.array([directions[k] for k in names], dtype=float)
    basis /= np.linalg.norm(basis, axis=1, keepdims=True)
    faces, normals = part_outward(part)
    face_area = part.face_areas
    total = float(face_area.sum())
    if not total > 0:
        raise ConfigError(f"part {part.name!r}: no surface area to split into areas")
    label = np.argmax(normals @ basis.T, axis=1)
    pairs, length = face_adjacency(faces, part.vertices)
    same = label[pairs[:, 0]] == label[pairs[:, 1]]
    comp = _components(len(faces), pairs[same])
    centres = part.triangles.mean(axis=1)
    facing = np.zeros((int(comp.max()) + 1, 3))
    np.add.at(facing, comp, normals * face_area[:, None])
    comp = _merge_islands(comp, face_area, pairs, length, centres, min_share * total, facing)
    # areas in order of decreasing surface, labelled by their area-weighted majority class
    roots, inverse = np.unique(comp, return_inverse=True)
    area = np.bincount(inverse, face_area, len(roots))
    order = np.lexsort((roots, -area))
    rank = np.empty(len(roots), np.int64)
    rank[order] = np.arange(len(roots))
    face_rank = rank[inverse]
    k = len(roots)
    area = area[order]
    votes = np.zeros((k, len(names)))
    np.add.at(votes, (face_rank, label), face_area)
    cls = np.argmax(votes, axis=1)
    weighted = np.zeros((k, 3))
    np.add.at(weighted, face_rank, normals * face_area[:, None])
    norm = np.linalg.norm(weighted, axis=1, keepdims=True)
    mean_normal = np.divide(weighted, norm, out=np.zeros_like(weighted), where=norm > 0)
    seen: dict[str, int] = {}
    area_names = []
    for c in cls:
        name = names[c]
        seen[name] = seen.get(name, 0) + 1
        area_names.append(name if seen[name] == 1 else f"{name} {seen[name]}")
    log.info("areas of %s: %s", part.name, ", ".join(f"{n} {a / 1e6:.2f} m^2" for n, a in zip(area_names, area)))
    return Areas(
        face_area=face_rank,
        names=tuple(area_names),
        direction=tuple(names[c] for c in cls),
        area_mm2=area,
        normal=mean_normal,
        face_normals=normals,
    )


#: The score of a face a robot reaches only with its gun tilted off the normal
#: (``cells.reach.reach_matrix``'s tilted tries): reached, but below any face reached along the normal, so that
#: an area goes to the robot that paints it straight (:func:`assign_areas`).
TILTED = 0.01

#: In an area split between robots, a face stays with the area's robot only where it scores at least this, or
#: no other robot scores more (:func:`assign_areas`).
ROBUST = 0.5


def assign_areas(areas: Areas, face_area_mm2: np.ndarray, reach: np.ndarray, robust: float = ROBUST) -> AreaAssignment:
    """Each area given to the robot that reaches it best, split where none reaches it whole (module
    docstring, step 2).

    Parameters
    ----------
    areas : Areas
    face_area_mm2 : (m,) float
        The part's face areas (``Part.face_areas``).
    reach : (r, m) float or bool
        How well robot ``i`` reaches face ``j``: 0 (not at all) to 1; a face counts as reached where it is
        above 0, and as reached straight (along its normal) where it is above :data:`TILTED`.
    """
    reach = np.asarray(reach, dtype=float)
    face_area_mm2 = np.asarray(face_area_mm2, dtype=float)
    m = len(areas.face_area)
    if reach.ndim != 2 or reach.shape[1] != m or len(face_area_mm2) != m:
        raise ValueError(
            f"reach must be (robots, {m}) and face_area_mm2 ({m},), got {reach.shape}, {face_area_mm2.shape}"
        )
    if not np.isfinite(reach).all():
        raise ValueError("reach must be finite")
    r, k = len(reach), len(areas)
    reached = reach > 0
    face_robot = np.full(m, -1, np.int64)
    area_robot = np.full(k, -1, np.int64)
    share = np.zeros(k)
    split = np.zeros(k, bool)
    for a in range(k):
        mine = areas.face_area == a
        w = face_area_mm2[mine]
        total = w.sum()
        if not r or total <= 0:
            continue
        covered = reached[:, mine] @ w / total
        straight = (reach[:, mine] > TILTED) @ w / total
        score = (reach[:, mine] * reached[:, mine]) @ w / total
        best = int(np.lexsort((np.arange(r), -score, -covered, -straight))[0])
        if covered[best] <= 0:
            continue
        area_robot[a], share[a] = best, covered[best]
        faces = np.flatnonzero(mine)
        own = reached[best, faces]
        if covered[best] < 1.0 and r > 1:
            # a split area: its seam moves in from the edge of the robot's reach to where it reaches well,
            # wherever another robot reaches better
            others = np.delete(reach[:, faces], best, axis=0).max(axis=0)
            own &= (reach[best, faces] >= robust) | (others <= reach[best, faces])
        face_robot[faces[own]] = best
        rest = faces[~own]
        if len(rest):
            others = np.where(reached[:, rest], reach[:, rest], -np.inf)
            pick = np.argmax(others, axis=0)
            ok = np.isfinite(others[pick, np.arange(len(rest))])
            face_robot[rest[ok]] = pick[ok]
            split[a] = bool(ok.any())
    robot_area = np.bincount(face_robot[face_robot >= 0], face_area_mm2[face_robot >= 0], r) if r else np.zeros(0)
    unreached = float(face_area_mm2[face_robot < 0].sum())
    return AreaAssignment(
        face_robot=face_robot,
        area_robot=area_robot,
        area_share=share,
        split=split,
        robot_area_mm2=robot_area,
        unreached_mm2=unreached,
    )
