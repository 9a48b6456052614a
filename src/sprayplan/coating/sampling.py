"""Where the film is computed and when the gun sprays: surface samples and the spray path as time steps.

The plan's strokes become time steps: each stroke's tool-tip polyline is subdivided to at most ``max_step_mm``,
and at speed v every node gets the time dt = (half its two adjacent segments) / v, so the steps of a stroke add
up to its length / v. Transfer strokes and strokes whose flow is 0 give no time steps.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.coating.process import Process, StrokeOverride
from sprayplan.errors import ConfigError, InputError
from sprayplan.paths.speed import segment_speeds
from sprayplan.surface import normals as nm
from sprayplan.surface.pairs import unique_rows
from sprayplan.surface.subdivide import subdivide_to_size
from sprayplan.types import Part, Paths, Targets, read_only


@dataclass(frozen=True)
class SurfaceSamples:
    """Points where thickness is computed.

    Attributes
    ----------
    points : (n, 3) float, mm
    normals : (n, 3) float
        Unit, outward.
    area_mm2 : (n,) float
        Surface area each point stands for (a third of its adjacent triangles' area for mesh vertices).
    faces : (m, 3) int
        Triangles over the points (mesh vertices), or (0, 3).
    part_face : (n,) int or None
        Meshes: for each sample, a face of the part it lies on (a sample on an edge lies on each of its
        faces: one of them), -1 for a vertex of no face; None for clouds and given targets.
    """

    points: np.ndarray
    normals: np.ndarray
    area_mm2: np.ndarray
    faces: np.ndarray
    part_face: np.ndarray | None = None

    def __post_init__(self):
        read_only(self)


@dataclass(frozen=True)
class GunSamples:
    """The spray-on path as time steps.

    Attributes
    ----------
    position : (k, 3) float, mm
        Gun tip.
    axis : (k, 3) float
        Unit gun axis, towards the surface (-normal of the plan).
    along : (k, 3) float
        Unit travel direction, perpendicular to the axis.
    aim : (k, 3) float, mm
        The plan's contact point (where the axis meets the surface).
    dt_s : (k,) float, s
    volume_rate_mm3_s : (k,) float
        Dry-film volume rate Q.
    stroke : (k,) int
        Index of the stroke in ``paths.strokes``.
    node, node_share : (k, 4) int and float, or None
        With ``gun_samples(..., nodes=True)``: how each time step depends on the waypoints' time factors
        (``Stroke.dwell``). A step's time is half of each adjacent sub-segment's, and a sub-segment's time is
        its planned time times the mean of its segment's two waypoints' factors, so
        ``dt(w) = dt * sum_c node_share[:, c] * w[node[:, c]]`` (``node``: waypoint index counted over all of
        ``paths.strokes``; the shares add up to 1, and ``dt`` is the step's time with ``w`` = 1).
    """

    position: np.ndarray
    axis: np.ndarray
    along: np.ndarray
    aim: np.ndarray
    dt_s: np.ndarray
    volume_rate_mm3_s: np.ndarray
    stroke: np.ndarray
    node: np.ndarray | None = None
    node_share: np.ndarray | None = None


def surface_samples(
    part: Part, targets: Targets | None = None, max_edge_mm: float = 0.0, facing: Paths | None = None
) -> SurfaceSamples:
    """Surface samples of a part: its mesh vertices (or cloud points), or the given targets.

    Parameters
    ----------
    part : Part
    targets : Targets, optional
        A sampling of the part to use instead of its vertices; each point stands for ``part.area / n``
        (clouds: the area estimated from the point spacing).
    max_edge_mm : float
        Meshes: split triangles until no edge is longer than this (0: never), so that a coarse mesh (a CAD
        export with long thin triangles, a panel of two triangles) is sampled finely enough for the film's
        statistics; the new vertices take the normals interpolated from the original vertices.
    facing : Paths, optional
        A point cloud without normals gets PCA normals (k-d tree neighbourhoods of four point spacings), each
        turned to agree with the normal of the nearest contact point of these paths: the side the gun paints
        is the outside. Without paths such a cloud is an error.

    Raises
    ------
    InputError
        A point cloud without normals and no targets.
    """
    faces = np.zeros((0, 3), np.int64)
    if part.is_mesh:
        faces, face_n = nm.part_outward(part)
    if targets is not None:
        pts = np.asarray(targets.points, float)
        total = part.area if part.is_mesh else _cloud_area(part.vertices).sum()
        return SurfaceSamples(
            pts,
            np.asarray(targets.normals, float),
            np.full(len(pts), total / max(len(pts), 1)),
            np.zeros((0, 3), np.int64),
        )
    if part.is_mesh:
        normals = nm.vertex_normals(part.vertices, faces, face_n)
        vertices, parent = part.vertices, np.arange(len(faces))
        if max_edge_mm > 0:
            vertices, faces, normals, parent = _subdivided(vertices, faces, normals, float(max_edge_mm))
        tri = vertices[faces]
        face_area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        area = np.bincount(faces.ravel(), np.repeat(face_area / 3.0, 3), len(vertices))
        last = _last_face(faces, len(vertices))
        part_face = np.where(last >= 0, parent[np.maximum(last, 0)], -1)
        return SurfaceSamples(vertices, normals, area, faces, part_face)
    normals = part.vertex_normals
    if normals is None:
        points = [s.points for s in facing.strokes if s.spray_on and len(s)] if facing is not None else []
        if not points or len(part.vertices) < 3:
            raise InputError(f"{part.name}: a point cloud needs normals for a coating simulation")
        normals = _cloud_normals(
            part.vertices, np.vstack(points), np.vstack([s.normals for s in facing.strokes if s.spray_on and len(s)])
        )
    return SurfaceSamples(part.vertices, normals, _cloud_area(part.vertices), faces)


def _cloud_normals(points: np.ndarray, aim: np.ndarray, aim_normals: np.ndarray) -> np.ndarray:
    """PCA normals of a cloud, each turned to agree with the normal at the nearest of the ``aim`` points."""
    tree = cKDTree(points)
    spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
    normals = nm.pca_normals(points, 4.0 * max(spacing, 1e-9), tree=tree, center="mean")
    nearest = cKDTree(aim).query(points)[1]
    flip = np.einsum("ij,ij->i", normals, aim_normals[nearest]) < 0
    return np.where(flip[:, None], -normals, normals)


def _last_face(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n_vertices,) int: for each vertex, the face of its last write when every face's corner 0 is written,
    then every corner 1, then 2 (-1: a vertex of no face)."""
    at = np.full(n_vertices, -1, np.int64)
    at[faces.T.ravel()] = np.arange(faces.size)
    return np.where(at >= 0, at % max(len(faces), 1), -1)


def _subdivided(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray, max_edge: float):
    """A mesh split until no edge is longer than ``max_edge``, with vertex normals interpolated linearly over
    each original triangle (shared vertices merged); and for each new face, the given face it lies in."""
    edges = vertices[faces] - vertices[np.roll(faces, 1, axis=1)]
    if len(faces) == 0 or np.linalg.norm(edges, axis=2).max() <= max_edge:
        return vertices, faces, normals, np.arange(len(faces))
    new_v, new_f, index = subdivide_to_size(vertices, faces, max_edge, max_rounds=30)
    scale = max(float(np.abs(vertices).max()), 1.0) * 1e-9
    _, first, inverse = unique_rows(np.round(new_v / scale).astype(np.int64))
    new_f = inverse.reshape(-1)[new_f]
    new_v = new_v[first]
    # Each vertex's normal from the barycentric coordinates of one face corner it is, in its face's original
    # triangle. Every face's corners would give the same value but for rounding; the one kept is the corner
    # that wrote it last when every corner of every face was written in turn (corner 0 of every face, then
    # corner 1, then 2): the same bits, computed once a vertex instead of three times a face.
    at = np.full(len(new_v), -1, np.int64)
    at[new_f.T.ravel()] = np.arange(new_f.size)  # the last write of each vertex
    written = np.flatnonzero(at >= 0)
    corner, face = np.divmod(at[written], len(new_f))
    tri = faces[index[face]]
    a, b, c = (vertices[tri[:, k]] for k in range(3))
    p = new_v[new_f[face, corner]]
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = np.where(np.abs(d00 * d11 - d01 * d01) > 0, d00 * d11 - d01 * d01, 1.0)
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    w0 = 1.0 - w1 - w2
    out = np.zeros((len(new_v), 3))
    out[written] = (
        w0[:, None] * normals[tri[:, 0]] + w1[:, None] * normals[tri[:, 1]] + w2[:, None] * normals[tri[:, 2]]
    )
    return new_v, new_f, nm.unit(out), index


def _cloud_area(points: np.ndarray, k: int = 8) -> np.ndarray:
    """(n,) float, mm^2: area per cloud point, pi d_k^2 / k from the distance d_k to the k-th neighbour."""
    k = min(k, len(points) - 1)
    if k < 1:
        return np.ones(len(points))
    dist, _ = cKDTree(points).query(points, k + 1)
    return np.pi * dist[:, -1] ** 2 / k


def gun_samples(
    paths: Paths,
    process: Process,
    overrides: Mapping[int, StrokeOverride] | Sequence[StrokeOverride | None] | None = None,
    max_step_mm: float | None = None,
    speed_along: str = "surface",
    max_speed_ratio: float = 3.0,
    nodes: bool = False,
) -> tuple[GunSamples, np.ndarray, np.ndarray]:
    """Time steps of the spray-on path, and each stroke's duration and flow.

    Parameters
    ----------
    paths : Paths
    process : Process
    overrides : mapping or sequence of StrokeOverride, optional
        Per-stroke settings by stroke index (``paths.strokes`` order).
    max_step_mm : float, optional
        Longest travel between two time steps; None: the pattern radius / 10.
    speed_along : {"tcp", "surface"}
        The speed is the gun tip's (``tcp``: a robot moving its tool at a constant speed), or the contact
        point's on the surface (``surface``: the tip speeds up over convex bends and slows down in concave
        ones, as the plan's per-waypoint speeds ask; see ``sprayplan.paths.speed``).
    max_speed_ratio : float
        With ``surface``: the tip's speed stays within [v / ratio, v ratio].
    nodes : bool
        Leave out the strokes' time factors (``Stroke.dwell``: every waypoint's is taken as 1) and return
        instead how each time step depends on them (``GunSamples.node``, ``node_share``): what
        :mod:`sprayplan.refine.tuning` needs.

    Returns
    -------
    guns : GunSamples
    stroke_time_s : (s,) float
    stroke_flow_ml_min : (s,) float
    """
    step = process.pattern.radius_mm / 10.0 if max_step_mm is None else float(max_step_mm)
    per = _stroke_settings(paths, process, overrides)
    parts, times, flows = [], [], []
    first = 0  # index of the stroke's first waypoint over all strokes
    for index, (stroke, (flow, speed, on)) in enumerate(zip(paths.strokes, per)):
        dwell = None if nodes else stroke.dwell
        seg_speed = segment_speeds(stroke.tcp, stroke.points, speed, speed_along, max_speed_ratio, dwell)
        seg_len = np.linalg.norm(np.diff(stroke.tcp, axis=0), axis=1)
        times.append(float((seg_len / seg_speed).sum()))
        flows.append(flow if on else 0.0)
        if on and flow > 0 and len(stroke) >= 2:
            q = flow * 1000.0 / 60.0 * process.solids_fraction * process.transfer_efficiency
            parts.append(_stroke_samples(stroke, step, seg_speed, q, index, first if nodes else None))
        first += len(stroke)
    if parts:
        cols = [np.concatenate([p[c] for p in parts]) for c in range(9 if nodes else 7)]
    else:
        cols = [np.zeros((0, 3))] * 4 + [np.zeros(0), np.zeros(0), np.zeros(0, np.int64)]
        cols += [np.zeros((0, 4), np.int64), np.zeros((0, 4))] if nodes else []
    return GunSamples(*cols), np.array(times, float), np.array(flows, float)


def _stroke_settings(paths: Paths, process: Process, overrides) -> list[tuple[float, float, bool]]:
    n = len(paths.strokes)
    if overrides is None:
        table = {}
    elif isinstance(overrides, Mapping):
        table = dict(overrides)
    else:
        if len(overrides) != n:
            raise ConfigError(f"overrides must have one entry per stroke ({n}), got {len(overrides)}")
        table = {i: o for i, o in enumerate(overrides) if o is not None}
    bad = [i for i in table if not 0 <= int(i) < n]
    if bad:
        raise ConfigError(f"override for stroke {bad[0]}, but the plan has {n} strokes")
    out = []
    for i, stroke in enumerate(paths.strokes):
        o = table.get(i, StrokeOverride())
        flow = process.flow_ml_min if o.flow_ml_min is None else float(o.flow_ml_min)
        speed = process.speed_mm_s if o.speed_mm_s is None else float(o.speed_mm_s)
        on = stroke.spray_on and (o.spray_on is None or bool(o.spray_on))
        out.append((flow, speed, on))
    return out


def _stroke_samples(stroke, step: float, seg_speed: np.ndarray, q: float, index: int, first: int | None = None):
    tcp, nrm, pts = stroke.tcp, stroke.normals, stroke.points
    seg = np.linalg.norm(np.diff(tcp, axis=0), axis=1)
    # a segment a hair longer than a multiple of the step (a waypoint spacing equal to it, rounded in a file)
    # is not split once more: the film then does not depend on the last digit of the plan's coordinates
    sub = np.maximum(np.ceil(seg / step - 1e-3).astype(np.int64), 1)
    seg_of = np.repeat(np.arange(len(seg)), sub)
    frac = (np.arange(sub.sum()) - np.repeat(np.cumsum(sub) - sub, sub)) / np.repeat(sub, sub)
    frac = np.concatenate([frac, [1.0]])
    seg_of = np.concatenate([seg_of, [len(seg) - 1]])

    def lerp(arr):
        return arr[seg_of] + (arr[seg_of + 1] - arr[seg_of]) * frac[:, None]

    position, aim = lerp(tcp), lerp(pts)
    axis = -nm.unit(lerp(nrm))
    steps = np.repeat(seg / sub / seg_speed, sub)  # time on each sub-segment
    dt = (np.concatenate([steps, [0.0]]) + np.concatenate([[0.0], steps])) / 2.0
    along = np.gradient(position, axis=0) if len(position) > 2 else np.repeat(np.diff(position, axis=0), 2, axis=0)
    along = along - np.einsum("ij,ij->i", along, axis)[:, None] * axis
    norm = np.linalg.norm(along, axis=1)
    fallback = np.cross(axis, np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    along = np.where(norm[:, None] > 1e-9, along / np.maximum(norm, 1e-12)[:, None], nm.unit(fallback))
    keep = dt > 0
    k = int(keep.sum())
    out = (position[keep], axis[keep], along[keep], aim[keep], dt[keep], np.full(k, q), np.full(k, index))
    if first is None:
        return out
    # time step j: half of sub-segment j - 1 (segment seg_of[j - 1]) and half of sub-segment j (seg_of[j]);
    # a sub-segment's time is shared by its segment's two waypoints
    before = np.concatenate([[0.0], steps]) / 4.0
    after = np.concatenate([steps, [0.0]]) / 4.0
    seg_before = np.concatenate([[0], seg_of[:-1]])
    node = first + np.column_stack([seg_before, seg_before + 1, seg_of, seg_of + 1])
    share = np.column_stack([before, before, after, after]) / np.where(dt > 0, dt, 1.0)[:, None]
    return (*out, node[keep], share[keep])
