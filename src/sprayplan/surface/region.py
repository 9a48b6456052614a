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

import math
import re
from dataclasses import dataclass

import numpy as np

from sprayplan.errors import RegionError
from sprayplan.surface.pairs import unique_pairs
from sprayplan.types import Part

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
    s = sign * (vertices[:, axis] - value)
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
        return vertices, keep
    unique, inverse = unique_pairs(edges, return_inverse=True)
    inverse = inverse.reshape(-1)
    v_in, v_out = vertices[unique[:, 0]], vertices[unique[:, 1]]
    s_in, s_out = s[unique[:, 0]], s[unique[:, 1]]
    t = s_in / (s_in - s_out)
    cut = v_in + t[:, None] * (v_out - v_in)
    cut[:, axis] = value
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
    return np.vstack([vertices, cut]), np.vstack(new_faces).astype(np.int64)


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
    (``surface.normals.part_outward``): surface no gun reaches, hidden by a part lying on it.

    The ray is tested against the triangles whose bounding ball can meet it: the triangles are grouped by
    their circumradius (doubling bins), and each group's centres are searched within half the ray's length
    plus the group's largest radius of the ray's midpoint (``cKDTree.sparse_distance_matrix``); the
    candidates are intersected exactly (Moller-Trumbore)."""
    from scipy.spatial import cKDTree

    from sprayplan.surface.normals import part_outward

    if not part.is_mesh or not within_mm > 0:
        return np.zeros(len(part.faces), bool)
    faces, normals = part_outward(part)
    tri = part.vertices[faces]
    centre = tri.mean(axis=1)
    radius = np.linalg.norm(tri - centre[:, None, :], axis=2).max(axis=1)
    length = float(within_mm) - _RAY_START_MM
    origin = centre + _RAY_START_MM * normals
    mid_tree = cKDTree(origin + 0.5 * length * normals)
    plane = np.einsum("ij,ij->i", normals, tri[:, 0])  # each face's plane: {x : normal . x = plane}
    covered = np.zeros(len(faces), bool)
    top = max(float(radius.max()), 1e-9)
    edges = [0.0]
    while edges[-1] < top:
        edges.append(max(1.0, 2.0 * edges[-1]))
    group = np.searchsorted(edges, radius, side="left")
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        found = mid_tree.sparse_distance_matrix(
            cKDTree(centre[members]), 0.5 * length + edges[g], output_type="ndarray"
        )
        rays, hit = found["i"], members[found["j"]]
        keep = (rays != hit) & ~covered[rays]
        rays, hit = rays[keep], hit[keep]
        facing = np.einsum("ij,ij->i", normals[rays], normals[hit])
        # near parallel, and the ray crosses the other face's plane within its length (most candidates are
        # the face's neighbours on the same sheet, whose plane lies behind the ray's start): two dot products
        # a pair spare the exact test on them; a pair kept here is decided by the exact test alone
        cross_at = (plane[hit] - np.einsum("ij,ij->i", normals[hit], origin[rays])) / np.where(
            facing == 0.0, 1.0, facing
        )
        keep = (
            (np.abs(facing) >= COVERED_MIN_COS)
            & (cross_at >= -_PLANE_SLACK_MM)
            & (cross_at <= length + _PLANE_SLACK_MM)
        )
        rays, hit = rays[keep], hit[keep]
        for start in range(0, len(rays), _PAIR_CHUNK):
            r, h = rays[start : start + _PAIR_CHUNK], hit[start : start + _PAIR_CHUNK]
            covered[r[_ray_hits(origin[r], normals[r], tri[h], length)]] = True
    return covered


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


def painted_surface(part: Part, collision) -> tuple[Part, dict]:
    """The surface a plan paints of a part its region stage cut: without what faces the floor (``[collision]
    skip_floor_facing``, :func:`drop_floor_facing`) and what other faces cover (``skip_covered``,
    :func:`covered_faces` within ``covered_mm``), both judged on the whole part; and the areas left out, mm^2
    (``floor_facing_left_out_mm2``, ``covered_left_out_mm2``, each only when there is some).

    Raises
    ------
    RegionError
        When nothing is left.
    """
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
