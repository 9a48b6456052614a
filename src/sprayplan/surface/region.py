"""The ``region`` stage: keep the part of a part that lies inside a convex region of half-spaces.

A region is written as conditions on x, y, z (mm, part frame) joined by ``and``::

    z > 1000
    x >= -500 and x <= 500 and z > 1000
    -500 < x < 500 and z > 1000          (chained comparison)
    box(-500, -400, 1000, 500, 400, 1500)  (xmin, ymin, zmin, xmax, ymax, zmax)

Seed 000 (section 6.1) paints "the part of the car roof where z > 1000 mm". Triangles that straddle a
boundary are clipped to it, so nothing sampled from the result lies outside the region; the cut vertices are
placed exactly on the boundary plane.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass

import numpy as np

from sprayplan.errors import RegionError
from sprayplan.surface.pairs import unique_pairs
from sprayplan.types import Part

log = logging.getLogger(__name__)

_AXES = {"x": 0, "y": 1, "z": 2}
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_TOKEN = re.compile(rf"\s*(?:(?P<num>{_NUMBER})|(?P<axis>[xyzXYZ])\b|(?P<op><=|>=|<|>))\s*")
_BOX = re.compile(rf"^\s*box\s*\(\s*((?:{_NUMBER}\s*,\s*){{5}}{_NUMBER})\s*\)\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class Region:
    """An intersection of axis-aligned half-spaces ``sign * p[axis] <= sign * value``.

    Attributes
    ----------
    axis : (k,) int
        0, 1, 2 for x, y, z.
    sign : (k,) float
        +1 for an upper bound (``p[axis] <= value``), -1 for a lower bound (``p[axis] >= value``).
    value : (k,) float, mm
    text : str
        The expression it was parsed from.
    """

    axis: np.ndarray
    sign: np.ndarray
    value: np.ndarray
    text: str = ""

    def contains(self, points: np.ndarray, tol_mm: float = 0.0) -> np.ndarray:
        """(n,) bool: which points lie in the region (within ``tol_mm``)."""
        points = np.asarray(points, dtype=float)
        inside = np.ones(len(points), dtype=bool)
        for axis, sign, value in zip(self.axis, self.sign, self.value):
            inside &= sign * (points[:, axis] - value) <= tol_mm
        return inside


def parse_region(text: str) -> Region:
    """Parse a region expression (see the module docstring).

    Raises
    ------
    RegionError
        With the clause that could not be read.
    """
    axes, signs, values = [], [], []
    if not text or not text.strip():
        raise RegionError("empty region expression")
    for clause in re.split(r"\band\b|&&|&|,(?![^()]*\))", text, flags=re.IGNORECASE):
        if not clause.strip():
            raise RegionError(f"region {text!r}: empty condition around 'and'")
        box = _BOX.match(clause)
        if box:
            lo_hi = [float(v) for v in box.group(1).split(",")]
            lo, hi = np.array(lo_hi[:3]), np.array(lo_hi[3:])
            if np.any(lo > hi):
                raise RegionError(f"region {text!r}: box minimum exceeds maximum")
            for axis in range(3):
                axes += [axis, axis]
                signs += [-1.0, 1.0]
                values += [lo[axis], hi[axis]]
            continue
        for axis, sign, value in _parse_comparison(clause, text):
            axes.append(axis)
            signs.append(sign)
            values.append(value)
    values_arr = np.array(values, dtype=float)
    if not np.isfinite(values_arr).all():
        raise RegionError(f"region {text!r}: bounds must be finite numbers")
    return Region(np.array(axes, dtype=int), np.array(signs, dtype=float), values_arr, text.strip())


def _parse_comparison(clause: str, text: str):
    tokens, pos = [], 0
    while pos < len(clause):
        match = _TOKEN.match(clause, pos)
        if not match or match.end() == pos:
            raise RegionError(
                f"region {text!r}: cannot read {clause[pos:].strip()!r} "
                "(write conditions like 'z > 1000' joined by 'and', or box(x0,y0,z0,x1,y1,z1))"
            )
        kind = match.lastgroup
        tokens.append((kind, match.group(kind)))
        pos = match.end()
    kinds = [k for k, _ in tokens]
    if len(tokens) < 3 or len(tokens) % 2 == 0 or any(k != "op" for k in kinds[1::2]) or "op" in kinds[0::2]:
        raise RegionError(f"region {text!r}: {clause.strip()!r} is not a comparison like 'z > 1000'")
    out = []
    for i in range(1, len(tokens), 2):
        (lk, lv), (_, op), (rk, rv) = tokens[i - 1], tokens[i], tokens[i + 1]
        if lk == "axis" and rk == "num":
            axis, value, upper = _AXES[lv.lower()], float(rv), op.startswith("<")
        elif lk == "num" and rk == "axis":
            axis, value, upper = _AXES[rv.lower()], float(lv), op.startswith(">")
        else:
            raise RegionError(f"region {text!r}: {clause.strip()!r} must compare one axis with one number")
        out.append((axis, 1.0 if upper else -1.0, value))
    return out


def select_region(part: Part, region: Region | str | None) -> Part:
    """The part of ``part`` inside ``region``; straddling triangles are clipped.

    Parameters
    ----------
    part : Part
    region : Region, str or None
        None returns the part unchanged.

    Returns
    -------
    Part
        A mesh keeps its winding; a point cloud keeps the points (and normals) inside.

    Raises
    ------
    RegionError
        When nothing of the part lies inside the region.
    """
    if region is None:
        return part
    if isinstance(region, str):
        region = parse_region(region)
    if not part.is_mesh:
        keep = region.contains(part.vertices)
        if not keep.any():
            _raise_empty(part, region)
        normals = None if part.vertex_normals is None else part.vertex_normals[keep]
        return Part(part.vertices[keep], part.faces, normals, part.name)
    vertices, faces = part.vertices, part.faces
    for axis, sign, value in zip(region.axis, region.sign, region.value):
        vertices, faces = clip_halfspace(vertices, faces, int(axis), float(sign), float(value))
        if len(faces) == 0:
            _raise_empty(part, region)
    # a region that only touches the part along a line or at a point leaves zero-area slivers
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    faces = faces[area > 0]
    if len(faces) == 0:
        _raise_empty(part, region)
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return Part(vertices[used], remap[faces], None, part.name, oriented=part.oriented)


def parse_masks(masks) -> tuple[Region, ...]:
    """The masks of ``[load] mask`` (``plan --mask``) parsed: each a region expression (module docstring).

    Raises
    ------
    RegionError
        Naming the mask that could not be read.
    """
    if isinstance(masks, (str, Region)):
        masks = (masks,)
    out = []
    for mask in masks:
        if isinstance(mask, Region):
            out.append(mask)
            continue
        try:
            out.append(parse_region(mask))
        except RegionError as exc:
            raise RegionError(f"mask {mask!r}: {exc}") from None
    return tuple(out)


def mask_out(part: Part, masks, part2frame: np.ndarray | None = None) -> tuple[Part, float]:
    """``part`` less what lies inside any of ``masks``: the surface left unpainted on purpose (a paint shop's
    masking: glass, running gear, an intake's grille), still there as an obstacle for the robot.

    Each mask is a convex region (:func:`parse_region`) in the part frame; ``part2frame`` is where the part
    frame sits in the frame of ``part``'s vertices (a cell plan masks the placed body with the masks written
    in the body's own frame), None for the same frame. The outside of a region of half-spaces ``h_1 .. h_k``
    is cut exactly as the pieces ``h_1 .. h_(i-1), not h_i``; the pieces' cut points on a shared edge are the
    same (:func:`_clip`), so the pieces are welded back into one mesh whose faces along each mask's
    boundary meet the rest by shared edges (the slicer and the areas follow the surface across them).

    Returns
    -------
    part : Part
        A mesh keeps its orientation (no file normals: cut faces have none); a point cloud keeps the points
        (and normals) outside every mask.
    left_out_mm2 : float
        The area the masks took, mm^2 (0 for a point cloud).

    Raises
    ------
    RegionError
        A mask that cannot be read, or masks that leave nothing to paint.
    """
    masks = parse_masks(masks)
    if not masks:
        return part, 0.0
    if part2frame is None:
        coords = part.vertices
    else:
        frame = np.asarray(part2frame, dtype=float)
        coords = (part.vertices - frame[:3, 3]) @ frame[:3, :3]
    if not part.is_mesh:
        keep = ~np.any([m.contains(coords) for m in masks], axis=0)
        if not keep.any():
            raise RegionError(f"{part.name}: the masks {_mask_text(masks)} cover all of it: nothing left to paint")
        normals = None if part.vertex_normals is None else part.vertex_normals[keep]
        return Part(part.vertices[keep], part.faces, normals, part.name), 0.0
    vertices, faces = part.vertices, part.faces
    for mask in masks:
        pieces = []
        rest = (vertices, coords, faces)
        for axis, sign, value in zip(mask.axis, mask.sign, mask.value):
            pieces.append(_clip(*rest, int(axis), -float(sign), float(value)))
            rest = _clip(*rest, int(axis), float(sign), float(value))
        vertices, coords, faces = _welded(pieces)
        if len(faces) == 0:
            raise RegionError(f"{part.name}: the masks {_mask_text(masks)} cover all of it: nothing left to paint")
    masked = Part(vertices, faces, None, part.name, oriented=part.oriented)
    left_out = max(float(part.area - masked.area), 0.0)
    if left_out == 0.0:
        log.warning("%s: the masks %s leave out none of its surface", part.name, _mask_text(masks))
    return masked, left_out


def _mask_text(masks) -> str:
    return ", ".join(repr(m.text) for m in masks)


def _welded(pieces) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pieces ``(vertices, coords, faces)`` of one mesh joined: equal points made one vertex, faces that
    collapse to a line or a point (a plane through a vertex leaves them) dropped, unused vertices dropped."""
    offsets = np.cumsum([0] + [len(v) for v, _, _ in pieces])
    vertices = np.vstack([v for v, _, _ in pieces])
    coords = np.vstack([c for _, c, _ in pieces])
    faces = np.vstack([f + o for (_, _, f), o in zip(pieces, offsets)]).astype(np.int64)
    unique, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    faces = inverse.reshape(-1)[faces]
    tri = unique[faces]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    distinct = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    faces = faces[distinct & (area > 0)]
    used = np.zeros(len(unique), dtype=bool)
    used[faces.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return unique[used], coords[first][used], remap[faces]


def not_floor_facing(part: Part, below_deg: float) -> np.ndarray:
    """(m,) bool: the mesh's faces that :func:`drop_floor_facing` keeps (their normal, by the file's winding, at
    most ``below_deg`` below the horizontal)."""
    tri = part.triangles
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    nz = np.divide(cross[:, 2], double_area, out=np.zeros(len(tri)), where=double_area > 0)
    return nz >= -math.sin(math.radians(below_deg))


def drop_floor_facing(part: Part, below_deg: float) -> tuple[Part, float]:
    """The part without the surface that faces the floor: faces (or, for a point cloud, points with normals)
    whose outward normal points more than ``below_deg`` below the horizontal, ``n_z < -sin(below_deg)``.

    Returns the part and the area left out, mm^2 (for a point cloud, 0: its points carry no area).

    Raises
    ------
    RegionError
        When all of the part faces the floor.
    """
    limit = -math.sin(math.radians(below_deg))
    if not part.is_mesh:
        if part.vertex_normals is None:
            return part, 0.0
        keep = part.vertex_normals[:, 2] >= limit
        if keep.all():
            return part, 0.0
        if not keep.any():
            raise RegionError(f"part {part.name!r}: all of it faces the floor ([collision] skip_floor_facing)")
        return Part(part.vertices[keep], part.faces, part.vertex_normals[keep], part.name), 0.0
    keep = not_floor_facing(part, below_deg)
    double_area = 2.0 * part.face_areas
    if keep.all():
        return part, 0.0
    if not keep.any():
        raise RegionError(f"part {part.name!r}: all of it faces the floor ([collision] skip_floor_facing)")
    left_out = float(0.5 * double_area[~keep].sum())
    return keep_faces(part, keep), left_out


def keep_faces(part: Part, keep: np.ndarray) -> Part:
    """The mesh part with only the faces where ``keep`` is True, and the vertices they use (their file
    normals with them); its orientation kept."""
    faces = part.faces[keep]
    used = np.zeros(len(part.vertices), dtype=bool)
    used[faces.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    normals = None if part.vertex_normals is None else part.vertex_normals[used]
    return Part(part.vertices[used], remap[faces], normals, part.name, oriented=part.oriented)


def _raise_empty(part: Part, region: Region):
    lo, hi = part.bounds
    span = ", ".join(f"{a} {lo[i]:.6g}..{hi[i]:.6g}" for a, i in _AXES.items())
    raise RegionError(f"{part.name}: region {region.text!r} contains no part of it (the part spans {span} mm)")


def clip_halfspace(
    vertices: np.ndarray, faces: np.ndarray, axis: int, sign: float, value: float
) -> tuple[np.ndarray, np.ndarray]:
    """Clip a triangle mesh to the half-space ``sign * (p[axis] - value) <= 0``.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    axis : int
    sign : float
        +1 keeps ``p[axis] <= value``, -1 keeps ``p[axis] >= value``.
    value : float

    Returns
    -------
    vertices : (n + k, 3) float
        The input vertices followed by one new vertex per cut edge, lying exactly on the plane. A cut edge
        shared by two triangles gets one vertex, so the clipped mesh stays connected.
    faces : (j, 3) int
        Faces inside (or clipped to) the half-space, wound as the originals.
    """
    vertices, _, faces = _clip(vertices, vertices, faces, axis, sign, value, canonical=False)
    return vertices, faces


def _clip(
    vertices: np.ndarray,
    coords: np.ndarray,
    faces: np.ndarray,
    axis: int,
    sign: float,
    value: float,
    canonical: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`clip_halfspace` with the half-space tested on ``coords`` (the same points in another frame, or
    ``vertices`` itself): returns the vertices, the coordinates (both with the cut points appended) and the
    faces. ``canonical``: a cut point is interpolated from the edge's lower-numbered end whichever side is kept,
    so clipping the same mesh to the two sides of a plane gives bit-identical points on their shared edges
    (:func:`mask_out` welds them); else from its inside end, as :func:`clip_halfspace` always has (its regions'
    cut points, and so the plans of the parts cut, stay the same to the last bit)."""
    s = sign * (coords[:, axis] - value)
    inside = s <= 0.0
    count = inside[faces].sum(axis=1)
    keep = faces[count == 3]
    one = faces[count == 1]
    two = faces[count == 2]
    # roll each clipped face so that its odd vertex comes first (a cyclic roll keeps the winding)
    one = _roll_first(one, inside[one])
    two = _roll_first(two, ~inside[two])
    # cut edges as (inside vertex, outside vertex); both faces of a shared edge name it the same way
    edges = np.concatenate([one[:, [0, 1]], one[:, [0, 2]], two[:, [1, 0]], two[:, [2, 0]]]).reshape(-1, 2)
    if len(edges) == 0:
        return vertices, coords, keep
    unique, inverse = unique_pairs(edges, return_inverse=True)
    inverse = inverse.reshape(-1)
    lo, hi = (unique.min(axis=1), unique.max(axis=1)) if canonical else (unique[:, 0], unique[:, 1])
    d = coords[:, axis] - value
    t = (d[lo] / (d[lo] - d[hi]))[:, None]
    ends = (t == 0.0, t == 1.0)

    def cut_points(points: np.ndarray) -> np.ndarray:
        cut = points[lo] + t * (points[hi] - points[lo])
        cut = np.where(ends[0], points[lo], cut)
        return np.where(ends[1], points[hi], cut)

    cut_coords = cut_points(coords)
    cut_coords[:, axis] = value
    cut = cut_coords if coords is vertices else cut_points(vertices)
    new_id = len(vertices) + inverse
    n1, n2 = len(one), len(two)
    p01_one, p02_one = new_id[:n1], new_id[n1 : 2 * n1]
    p01_two, p02_two = new_id[2 * n1 : 2 * n1 + n2], new_id[2 * n1 + n2 :]
    new_faces = [
        keep,
        np.stack([one[:, 0], p01_one, p02_one], axis=1),
        np.stack([p01_two, two[:, 1], two[:, 2]], axis=1),
        np.stack([p01_two, two[:, 2], p02_two], axis=1),
    ]
    new_vertices = np.vstack([vertices, cut])
    new_coords = new_vertices if coords is vertices else np.vstack([coords, cut_coords])
    return new_vertices, new_coords, np.vstack(new_faces).astype(np.int64)


def _roll_first(faces: np.ndarray, odd: np.ndarray) -> np.ndarray:
    first = np.argmax(odd, axis=1)
    idx = (first[:, None] + np.arange(3)[None, :]) % 3
    return np.take_along_axis(faces, idx, axis=1)


#: A face is covered when a face within ``covered_mm`` in front of it is this near parallel (|cos| of the
#: angle between their normals): a licence plate on a bumper, a handle on a door, the walls of a panel gap.
COVERED_MIN_COS = 0.8
#: The ray from a face's centre starts this far in front of it (past its own plane's rounding).
_RAY_START_MM = 0.5
#: Ray-triangle pairs tested at a time.
_PAIR_CHUNK = 2_000_000


#: How far outside a ray's span a face's plane may be crossed and the pair still go to the exact test, mm
#: (far above the rounding of the plane's crossing, so the prefilter never drops a pair the test would keep).
_PLANE_SLACK_MM = 1e-6


def covered_faces(part: Part, within_mm: float) -> np.ndarray:
    """(m,) bool: the mesh's faces with another face of the part in front of them within ``within_mm``, near
    parallel (:data:`COVERED_MIN_COS`), on the ray from the face's centre along its outward normal
    (``surface.normals.part_outward``): surface no gun reaches, hidden by a part lying on it
    (:func:`faces_in_front`)."""
    return faces_in_front(part, within_mm, min_cos=COVERED_MIN_COS)


def faces_in_front(part: Part, within_mm: float, obstacle: Part | None = None, min_cos: float = 0.0) -> np.ndarray:
    """(m,) bool: the faces of the mesh ``part`` whose ray from the centre along the outward normal
    (``surface.normals.part_outward``) meets a face of ``obstacle`` (default: the part itself; in the same
    frame) within ``within_mm``, that face's normal at least ``min_cos`` (|cos|) from the ray's: with 0 any
    face in front (the body within a gun's standoff in front of a recess's floor), with
    :data:`COVERED_MIN_COS` a face lying on it (:func:`covered_faces`).

    The ray is tested against the triangles whose bounding ball can meet it: the triangles are grouped by
    their circumradius (doubling bins), and each group's centres are searched within half the ray's length
    plus the group's largest radius of the ray's midpoint (``cKDTree.sparse_distance_matrix``); the
    candidates are intersected exactly (Moller-Trumbore). A face never meets its own ray (which starts in
    front of its plane)."""
    from scipy.spatial import cKDTree

    from sprayplan.surface.normals import face_normals, part_outward

    if not part.is_mesh or not within_mm > 0:
        return np.zeros(len(part.faces), bool)
    faces, normals = part_outward(part)
    tri = part.vertices[faces]
    centre = tri.mean(axis=1)
    length = float(within_mm) - _RAY_START_MM
    origin = centre + _RAY_START_MM * normals
    mid_tree = cKDTree(origin + 0.5 * length * normals)
    if obstacle is None:
        other, other_normals = tri, normals
    else:
        if not obstacle.is_mesh:
            return np.zeros(len(faces), bool)
        other = obstacle.vertices[obstacle.faces]
        other_normals = face_normals(obstacle.vertices, obstacle.faces)
    other_centre = other.mean(axis=1)
    radius = np.linalg.norm(other - other_centre[:, None, :], axis=2).max(axis=1)
    plane = np.einsum("ij,ij->i", other_normals, other[:, 0])  # each face's plane: {x : normal . x = plane}
    found_in_front = np.zeros(len(faces), bool)
    top = max(float(radius.max()), 1e-9)
    edges = [0.0]
    while edges[-1] < top:
        edges.append(max(1.0, 2.0 * edges[-1]))
    group = np.searchsorted(edges, radius, side="left")
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        found = mid_tree.sparse_distance_matrix(
            cKDTree(other_centre[members]), 0.5 * length + edges[g], output_type="ndarray"
        )
        rays, hit = found["i"], members[found["j"]]
        keep = ~found_in_front[rays]
        if obstacle is None:
            keep &= rays != hit
        rays, hit = rays[keep], hit[keep]
        facing = np.einsum("ij,ij->i", normals[rays], other_normals[hit])
        # near parallel (when asked), and the ray crosses the other face's plane within its length (most
        # candidates are the face's neighbours on the same sheet, whose plane lies behind the ray's start): two
        # dot products a pair spare the exact test on them; a pair kept here is decided by the exact test alone
        cross_at = (plane[hit] - np.einsum("ij,ij->i", other_normals[hit], origin[rays])) / np.where(
            facing == 0.0, 1.0, facing
        )
        keep = (
            (np.abs(facing) >= min_cos)
            & (facing != 0.0)
            & (cross_at >= -_PLANE_SLACK_MM)
            & (cross_at <= length + _PLANE_SLACK_MM)
        )
        rays, hit = rays[keep], hit[keep]
        for start in range(0, len(rays), _PAIR_CHUNK):
            r, h = rays[start : start + _PAIR_CHUNK], hit[start : start + _PAIR_CHUNK]
            found_in_front[r[_ray_hits(origin[r], normals[r], other[h], length)]] = True
    return found_in_front


def _ray_hits(origin: np.ndarray, direction: np.ndarray, tri: np.ndarray, length: float) -> np.ndarray:
    """(k,) bool: the ray ``origin + t direction``, 0 <= t <= length, meets the triangle (Moller-Trumbore;
    a ray in the triangle's plane meets nothing)."""
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    s = origin - tri[:, 0]
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = np.einsum("ij,ij->i", direction, q) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    return ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= length)


def painted_surface(part: Part, collision, masks=(), part2frame: np.ndarray | None = None) -> tuple[Part, dict]:
    """The surface a plan paints of a part its region stage cut: without what faces the floor (``[collision]
    skip_floor_facing``, :func:`drop_floor_facing`) and what other faces cover (``skip_covered``,
    :func:`covered_faces` within ``covered_mm``), both judged on the whole part, and without what ``masks``
    (``[load] mask``) cover (:func:`mask_out`, ``part2frame`` as there); and the areas left out, mm^2
    (``floor_facing_left_out_mm2``, ``covered_left_out_mm2``, ``masked_left_out_mm2``, each only when there
    is some).

    Raises
    ------
    RegionError
        When nothing is left, or a mask cannot be read.
    """
    part, left = _unmasked_painted_surface(part, collision)
    if masks:
        part, masked = mask_out(part, masks, part2frame)
        if masked > 0:
            left["masked_left_out_mm2"] = masked
    return part, left


def _unmasked_painted_surface(part: Part, collision) -> tuple[Part, dict]:
    if not part.is_mesh:
        if collision.skip_floor_facing:
            part, _ = drop_floor_facing(part, collision.floor_facing_deg)
        return part, {}
    drop = np.zeros(len(part.faces), bool)
    left: dict = {}
    area = part.face_areas
    if collision.skip_floor_facing:
        drop |= ~not_floor_facing(part, collision.floor_facing_deg)
        if drop.all():
            raise RegionError(f"part {part.name!r}: all of it faces the floor ([collision] skip_floor_facing)")
        if drop.any():
            left["floor_facing_left_out_mm2"] = float(area[drop].sum())
    if collision.skip_covered:
        covered = covered_faces(part, collision.covered_mm) & ~drop
        if covered.any():
            left["covered_left_out_mm2"] = float(area[covered].sum())
            drop |= covered
        if drop.all():
            raise RegionError(
                f"part {part.name!r}: nothing left to paint once the surface facing the floor and the surface "
                f"covered within {collision.covered_mm:g} mm are left out ([collision] skip_covered)"
            )
    return (keep_faces(part, ~drop) if drop.any() else part), left
