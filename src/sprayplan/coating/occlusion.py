"""Occlusion: which surface points a gun can see (no part of the mesh between the gun tip and the point).

The test is made from *views*: gun positions taken along each stroke every ``step_mm`` of travel; every gun
sample uses the view nearest to it on its own stroke (``step_mm = 0``: every gun sample is its own view).
These methods give, for each view, the surface samples it cannot see:

``zbuffer`` (numpy)
    A depth map of the pattern's footprint (``pixels`` x ``pixels`` over the square of half side
    R x ``search_factor`` on the pattern plane) is filled, with perspective, by *splatting* the mesh as points:
    its vertices, plus points on a barycentric grid inside the triangles too big to put a vertex in every
    pixel they cover (circumradius over half a pixel on the surface); each pixel keeps its nearest depth. A
    sample is hidden when it lies more than a bias behind its pixel's depth; the bias (1 mm plus sqrt(2) pixel
    widths on the surface times the tangent of the incidence angle) absorbs the depth change of the sample's
    own surface across a pixel. Occluders thinner than the bias in depth, or much nearer the gun than the
    surface (and so sparser than a pixel), can leak paint.
``raster`` (compiled, ``coating.kernels``)
    The same depth test, with the mesh's triangles rasterised into the depth map (pixel centres, depth
    interpolated as 1/z, exact for planar triangles in perspective): no holes.
``rays``
    A ray from the gun to each sample, intersected with the mesh by ``trimesh.ray`` (Intel Embree through
    the optional ``embreex`` package when it is installed, else trimesh's own triangle tests, which need
    ``rtree``); hidden when the first hit is nearer than the sample by more than 1 mm.

``auto`` (default)
    ``rays`` when trimesh finds Embree (the ``embreex`` package), else ``raster``.

Triangles or points that reach behind the gun's plane are ignored by the depth-map methods, and both miss
occlusion at grazing incidence, where the bias grows. Measured on reach_curved_part.ply (bench_coating.py,
section 2), against exact rays at every time step: Embree rays at 20 mm views capture 99 % of the hidden
film; ``raster`` 14 % (it never hid paint that reaches the part on more than 5 samples); ``zbuffer`` 100 % of
the amount, but on the wrong samples about half of the time (41 samples hidden that are not). On a plate
under a plate (normal incidence) all three are exact.
"""

from __future__ import annotations

import logging
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.coating import kernels
from sprayplan.errors import ConfigError

log = logging.getLogger(__name__)

METHODS = ("auto", "zbuffer", "raster", "rays", "none")

#: depth slabs of the cone between the gun and the aim ball, each covered by one ball query
_SLABS = 1
#: rasterisation works on this many (view, triangle) pairs at a time
_PAIR_CHUNK = 1_500_000


@dataclass(frozen=True)
class Views:
    """Gun positions at which visibility is tested.

    Attributes
    ----------
    position : (v, 3) float, mm
    axis, along, across : (v, 3) float
        Gun axis (towards the surface), travel direction and ``axis x along``, unit.
    aim : (v, 3) float, mm
        Where the axis meets the surface (the stroke's contact point).
    reach_mm : (v,) float
        Radius around ``aim`` within which the view's gun samples can deposit paint.
    of_gun : (k,) int
        The view of each gun sample.
    """

    position: np.ndarray
    axis: np.ndarray
    along: np.ndarray
    across: np.ndarray
    aim: np.ndarray
    reach_mm: np.ndarray
    of_gun: np.ndarray


@dataclass(frozen=True)
class Occlusion:
    """Surface samples hidden from each view, as sorted keys ``view * n_samples + sample``.

    Attributes
    ----------
    of_gun : (k,) int
        The view of each gun sample.
    hidden_keys : (p,) int64, sorted
    view_has_hidden : (v,) bool
    n_samples : int
    method : str
        The method used (``auto`` resolved).
    """

    of_gun: np.ndarray
    hidden_keys: np.ndarray
    view_has_hidden: np.ndarray
    n_samples: int
    method: str = "none"

    def visible(self, sample: np.ndarray, gun: np.ndarray) -> np.ndarray:
        """(p,) bool: whether each (sample, gun sample) pair sees each other."""
        out = np.ones(len(sample), dtype=bool)
        if not len(self.hidden_keys):
            return out
        view = self.of_gun[gun]
        check = np.flatnonzero(self.view_has_hidden[view])
        if len(check):
            keys = view[check].astype(np.int64) * self.n_samples + sample[check]
            pos = np.searchsorted(self.hidden_keys, keys)
            pos = np.minimum(pos, len(self.hidden_keys) - 1)
            out[check] = self.hidden_keys[pos] != keys
        return out


def make_views(guns, step_mm: float, reach_mm: np.ndarray) -> Views:
    """One view every ``step_mm`` of gun travel along each stroke (0: every gun sample is a view).

    Parameters
    ----------
    guns : GunSamples
    step_mm : float
    reach_mm : (k,) float
        Deposit radius of each gun sample around its aim point.
    """
    k = len(guns.position)
    if step_mm <= 0 or k == 0:
        of_gun = np.arange(k)
        rep = of_gun
        extra = np.zeros(k)
    else:
        seg = np.linalg.norm(np.diff(guns.position, axis=0), axis=1)
        same = guns.stroke[1:] == guns.stroke[:-1]
        seg = np.where(same, seg, 0.0)
        travel = np.concatenate([[0.0], np.cumsum(seg)])
        start = np.concatenate([[True], ~same])
        travel -= np.maximum.accumulate(np.where(start, travel, 0.0))
        bucket = np.floor(travel / step_mm + 0.5).astype(np.int64)
        new = np.concatenate([[True], (bucket[1:] != bucket[:-1]) | ~same])
        of_gun = np.cumsum(new) - 1
        # representative: the gun sample nearest the bucket's centre
        err = np.abs(travel - bucket * step_mm)
        order = np.lexsort((err, of_gun))
        first = np.concatenate([[True], of_gun[order][1:] != of_gun[order][:-1]])
        rep = order[first]
        extra = np.full(len(rep), 0.5 * step_mm + 1e-9)
    return Views(
        guns.position[rep],
        guns.axis[rep],
        guns.along[rep],
        np.cross(guns.axis[rep], guns.along[rep]),
        guns.aim[rep],
        _max_per_view(reach_mm, of_gun, len(rep)) + extra,
        of_gun,
    )


def _max_per_view(values: np.ndarray, of_gun: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(n)
    np.maximum.at(out, of_gun, values)
    return out


def compute_occlusion(
    method: str,
    samples,
    vertices: np.ndarray,
    faces: np.ndarray,
    views: Views,
    pattern_standoff_mm: float,
    half_width_mm: float,
    *,
    pixels: int = 24,
    sample_tree: cKDTree | None = None,
    batch: int = 256,
    workers: int = 1,
    samples_are_vertices: bool = False,
) -> Occlusion:
    """Hidden (view, sample) pairs by the chosen method.

    Parameters
    ----------
    method : {"zbuffer", "rays", "none"}
    samples : SurfaceSamples
        Points (n, 3) and normals (n, 3) whose visibility is tested.
    vertices : (nv, 3) float, mm
    faces : (m, 3) int
        The mesh that can hide them.
    views : Views
    pattern_standoff_mm : float
        h: the pattern plane's distance, where the depth map lies.
    half_width_mm : float
        Half side of the depth map on the pattern plane.
    pixels : int
        Depth map size (``zbuffer``, ``raster``).
    sample_tree : cKDTree, optional
        A tree over ``samples.points`` (built when not given).
    batch : int
        Views handled at a time.
    workers : int
        Threads for the depth-map methods (Embree runs its own threads).
    samples_are_vertices : bool
        The samples are ``vertices`` (in that order): the z-buffer then finds the (view, sample) pairs among
        its splat pairs instead of querying them again.
    """
    if method not in METHODS:
        raise ConfigError(f"occlusion must be one of {', '.join(METHODS)}, got {method!r}")
    n = len(samples.points)
    nv = len(views.position)
    empty = Occlusion(views.of_gun, np.zeros(0, np.int64), np.zeros(nv, bool), n)
    if method == "none" or len(faces) == 0 or nv == 0:
        return empty
    tree = cKDTree(samples.points) if sample_tree is None else sample_tree
    tri = vertices[faces]
    pixel_mm = 2.0 * half_width_mm / pixels
    depth = float(np.median(np.einsum("ij,ij->i", views.aim - views.position, views.axis)))
    pixel_on_surface = pixel_mm * depth / pattern_standoff_mm
    if method == "auto":
        method = resolve_auto()
    origin = samples.points.mean(axis=0)
    frames = _frames(views, origin)
    sample_cols = (samples.points - origin).T.astype(np.float32)
    if method == "rays":
        intersector = _ray_intersector(vertices, faces)
    elif method == "raster":
        centres = tri.mean(axis=1)
        radius = float(np.linalg.norm(tri - centres[:, None, :], axis=2).max())
        corner_cols = (vertices - origin).T.astype(np.float32)
    else:
        centres = splat_points(vertices, tri, pixel_on_surface)
        radius = 0.0
        centre_cols = (centres - origin).T.astype(np.float32)
    if method == "zbuffer":
        centre_tree = cKDTree(centres)
    elif method == "raster":
        # triangles found by their centres in a grid of cells about a quarter of the views' reach
        grid = kernels.CellGrid(centres, max(float(np.median(views.reach_mm)) / 2.0, 4.0 * radius, 1.0))
        aim_depth = np.einsum("ij,ij->i", views.aim - views.position, views.axis)
        # the triangles in the grid's order: centres, and corners as float32 rows relative to the origin
        centres_g = np.ascontiguousarray(centres[grid.order])
        corners_g = np.ascontiguousarray(corner_cols.T[faces[grid.order]].reshape(-1, 9))
    h32, half32 = np.float32(pattern_standoff_mm), np.float32(half_width_mm)
    to_pixel32 = np.float32(pixels / (2.0 * float(half_width_mm)))
    pixel_scale32 = np.float32(2.0 * float(half_width_mm) / pixels)
    normals = np.ascontiguousarray(samples.normals, dtype=np.float64)

    def one(start):
        sl = slice(start, min(start + batch, nv))
        if method == "rays":
            view_idx, sample_idx = _view_sample_pairs(views, sl, tree)
            hid = _hidden_by_rays(intersector, samples, views, view_idx, sample_idx)
            return view_idx[hid].astype(np.int64) * n + sample_idx[hid]
        zbuf = np.full((sl.stop - sl.start) * pixels * pixels, np.inf)
        if method == "raster":
            view_idx, sample_idx = _view_sample_pairs(views, sl, tree)
            kernels.raster_depths(
                sl.start, sl.stop, views.position, views.axis, views.aim, views.reach_mm, aim_depth, centres_g,
                radius, grid.start, grid.low, grid.dims, grid.cell, corners_g, frames, h32, half32, to_pixel32,
                int(pixels), zbuf,
            )  # fmt: skip
        else:
            pv, pt, in_ball = _frustum_pairs(centres, centre_tree, radius, views, sl, pattern_standoff_mm)
            if samples_are_vertices:
                own = in_ball & (pt < n)
                view_idx, sample_idx = pv[own], pt[own]
            else:
                view_idx, sample_idx = _view_sample_pairs(views, sl, tree)
            for c in range(0, len(pv), _PAIR_CHUNK):
                chunk = slice(c, c + _PAIR_CHUNK)
                _splat(centre_cols, frames, pv[chunk], pt[chunk], sl.start, (h, half, m), zbuf)
        hid = kernels.hidden_by_depth(
            zbuf, sample_cols, normals, frames, sl.start, view_idx, sample_idx, h32, half32, to_pixel32,
            int(pixels), pixel_scale32, np.float32(math.sqrt(2.0)),
        )  # fmt: skip
        return view_idx[hid].astype(np.int64) * n + sample_idx[hid]

    h, half, m = float(pattern_standoff_mm), float(half_width_mm), int(pixels)
    starts = range(0, nv, batch)
    if workers > 1 and len(starts) > 1 and method != "rays":
        with ThreadPoolExecutor(max_workers=workers) as pool:
            hidden = list(pool.map(one, starts))
    else:
        hidden = [one(start) for start in starts]
    keys = np.sort(np.concatenate(hidden)) if hidden else np.zeros(0, np.int64)
    has = np.zeros(nv, bool)
    has[np.unique(keys // max(n, 1))] = True
    log.debug("occlusion (%s): %d views, %d hidden (view, sample) pairs", method, nv, len(keys))
    return Occlusion(views.of_gun, keys, has, n, method)


def resolve_auto() -> str:
    """The method ``auto`` stands for: ``rays`` when trimesh has Embree, else ``raster``."""
    import trimesh

    return "rays" if trimesh.ray.has_embree else "raster"


def _circumradius(tri: np.ndarray) -> np.ndarray:
    a = np.linalg.norm(tri[:, 1] - tri[:, 2], axis=1)
    b = np.linalg.norm(tri[:, 2] - tri[:, 0], axis=1)
    c = np.linalg.norm(tri[:, 0] - tri[:, 1], axis=1)
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return a * b * c / np.maximum(2.0 * area2, 1e-300)


def _frames(views: Views, origin: np.ndarray) -> np.ndarray:
    """(15, v) float32: per view the rows axis, along, across (each with its offset -vec . position), then the
    gun position, all relative to ``origin``: a point p projects to z = a . p + row 3, and so on."""
    pos = views.position - origin
    rows = []
    for vec in (views.axis, views.along, views.across):
        rows += [vec[:, 0], vec[:, 1], vec[:, 2], -np.einsum("ij,ij->i", vec, pos)]
    rows += [pos[:, 0], pos[:, 1], pos[:, 2]]
    return np.array(rows, dtype=np.float32)


def _view_sample_pairs(views: Views, sl: slice, tree: cKDTree) -> tuple[np.ndarray, np.ndarray]:
    """(view, sample) pairs of the batch: samples within each view's reach of its aim point."""
    reach = views.reach_mm[sl]
    pairs = cKDTree(views.aim[sl]).sparse_distance_matrix(tree, float(reach.max()), output_type="ndarray")
    view_idx = pairs["i"].astype(np.int64) + sl.start
    sample_idx = pairs["j"].astype(np.int64)
    keep = pairs["v"] <= views.reach_mm[view_idx]
    return view_idx[keep], sample_idx[keep]


def _project(cols: np.ndarray, index: np.ndarray, frames: np.ndarray, view_idx: np.ndarray, h: float):
    """Depth along the axis and pattern-plane coordinates (float32, mm) of points ``cols[:, index]`` (3, p)
    seen from views."""
    px, py, pz = np.take(cols, index, axis=1)
    g = np.take(frames, view_idx, axis=1)
    z = px * g[0] + py * g[1] + pz * g[2] + g[3]
    scale = np.float32(h) / np.where(z > 1e-6, z, np.float32(1e-6))
    x = (px * g[4] + py * g[5] + pz * g[6] + g[7]) * scale
    y = (px * g[8] + py * g[9] + pz * g[10] + g[11]) * scale
    return z, x, y


def _frustum_pairs(centres, centre_tree, radius, views: Views, sl: slice, h: float):
    """(view, primitive, in the aim ball) for the primitives (centre, bounding radius) that can hide a sample.

    A sample paired with a view lies within ``reach`` of the view's aim point, so whatever can hide it lies
    in the cone from the gun tip tangent to that ball, or in the ball: the ball is one query, the cone's
    narrow part (depth below aim depth - reach) is covered by ``_SLABS`` balls along the axis.
    """
    aim_depth = np.einsum("ij,ij->i", views.aim[sl] - views.position[sl], views.axis[sl])
    reach = views.reach_mm[sl]
    found = cKDTree(views.aim[sl]).sparse_distance_matrix(
        centre_tree, float(reach.max()) + radius, output_type="ndarray"
    )
    v = found["i"].astype(np.int64)
    keep = found["v"] <= reach[v] + radius
    pairs_v, pairs_t = [v[keep] + sl.start], [found["j"][keep].astype(np.int64)]
    flags = [np.ones(int(keep.sum()), bool)]
    near_end = float(np.max(aim_depth - reach))
    for k in range(_SLABS):
        if near_end <= 0:
            break
        z0, z1 = near_end * k / _SLABS, near_end * (k + 1) / _SLABS
        centre = views.position[sl] + views.axis[sl] * (0.5 * (z0 + z1))
        cone = float(np.max(reach / np.maximum(aim_depth, 1e-9))) * z1
        ball = math.hypot(0.5 * (z1 - z0), cone + radius) + radius
        found = cKDTree(centre).sparse_distance_matrix(centre_tree, ball, output_type="ndarray")
        v = found["i"].astype(np.int64)
        t = found["j"].astype(np.int64)
        rel = centres[t] - views.position[v + sl.start]
        cz = np.einsum("ij,ij->i", rel, views.axis[v + sl.start])
        own = (cz >= z0) & ((cz < z1) if k < _SLABS - 1 else True) & (cz < aim_depth[v] - reach[v])
        lateral2 = np.einsum("ij,ij->i", rel, rel) - cz * cz
        within = reach[v] * np.maximum(cz + radius, 0.0) / np.maximum(aim_depth[v], 1e-9) + radius
        own &= lateral2 <= within * within
        pairs_v.append(v[own] + sl.start)
        pairs_t.append(t[own])
        flags.append(np.zeros(int(own.sum()), bool))
    return np.concatenate(pairs_v), np.concatenate(pairs_t), np.concatenate(flags)


def splat_points(vertices: np.ndarray, tri: np.ndarray, pixel_mm: float) -> np.ndarray:
    """The mesh as points dense enough to put one in every pixel of side ``pixel_mm`` that the mesh covers.

    A square pixel holds a disc of radius pixel / 2, so a mesh whose triangles' circumradius is at most
    that has a vertex in every pixel it covers; larger triangles get points on a barycentric grid, at most
    0.7 pixel apart. (p, 3) float, mm: the vertices first.
    """
    edge = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    parts = [vertices]
    big = _circumradius(tri) > 0.5 * pixel_mm
    steps = np.where(big, np.ceil(edge / max(0.7 * pixel_mm, 1e-9)), 1).astype(np.int64)
    for n in np.unique(steps[steps > 1]):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        corner = ((i == 0) & (j == 0)) | ((i == n) & (j == 0)) | ((i == 0) & (j == n))
        keep = (i + j <= n) & ~corner
        wa, wb = i[keep] / n, j[keep] / n
        w = np.stack([1.0 - wa - wb, wa, wb], axis=1)
        parts.append(np.einsum("pk,tkc->tpc", w, tri[steps == n]).reshape(-1, 3))
    return np.concatenate(parts)


def _splat(cols, frames, pv, pt, first_view: int, grid, zbuf) -> None:
    """Splat (view, point) pairs into ``zbuf``: the nearest depth of the points in each pixel."""
    h, half, m = grid
    z, x, y = _project(cols, pt, frames, pv, h)
    px = np.floor((x + half) * (m / (2.0 * half))).astype(np.int64)
    py = np.floor((y + half) * (m / (2.0 * half))).astype(np.int64)
    ok = (z > 1.0) & (px >= 0) & (px < m) & (py >= 0) & (py < m)
    index = (pv[ok] - first_view) * (m * m) + py[ok] * m + px[ok]
    np.minimum.at(zbuf, index, z[ok].astype(np.float64))


def _ray_intersector(vertices: np.ndarray, faces: np.ndarray):
    import trimesh

    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    try:
        return mesh.ray
    except Exception as exc:
        raise ConfigError(f"occlusion='rays' needs embreex or rtree installed: {exc}") from exc


def _hidden_by_rays(intersector, samples, views: Views, view_idx, sample_idx) -> np.ndarray:
    """(p,) bool: pairs whose gun-to-sample ray hits the mesh more than 1 mm before the sample."""
    if not len(view_idx):
        return np.zeros(0, bool)
    origin = views.position[view_idx]
    target = samples.points[sample_idx]
    vec = target - origin
    dist = np.linalg.norm(vec, axis=1)
    direction = vec / np.maximum(dist, 1e-12)[:, None]
    _, ray_index, location = intersector.intersects_id(origin, direction, multiple_hits=False, return_locations=True)
    hidden = np.zeros(len(view_idx), bool)
    if len(ray_index):
        hit = np.linalg.norm(location - origin[ray_index], axis=1)
        hidden[ray_index[hit < dist[ray_index] - 1.0]] = True
    return hidden
