r"""Film thickness on a part's surface from a plan's spray strokes.

The formula
-----------
A surface sample S (unit outward normal n) collects, from the plan's spray-on path sampled at gun positions
G_j (axis a_j, towards the surface; travel direction u_j; time step dt_j; dry-film volume rate Q_j)::

    T(S) = sum_j  V_j(S) Q_j dt_j  F(x_j, y_j)  (h / z_j)^2  cos(alpha_j) / cos(theta_j)

    v_j = S - G_j,   z_j = v_j . a_j  (depth along the axis),   (x_j, y_j) = (h / z_j) (v_j . u_j, v_j . (a_j x u_j))
    cos(theta_j) = z_j / |v_j|,   cos(alpha_j) = -(v_j . n) / |v_j|,
    so  (h / z)^2 cos(alpha) / cos(theta) = -h^2 (v . n) / z^3

with F the pattern's density (1/mm^2, integral 1) on the plane at the pattern's standoff h, (x_j, y_j) the
point where the ray from the gun through S crosses that plane, and V_j(S) = 1 when the gun sees S, 0 when the
part hides it (module ``occlusion``) or when S faces away (cos alpha <= 0) or lies behind the gun (z <= 0).
The time steps come from the plan: each stroke's tool-tip polyline, subdivided to at most ``max_step_mm``,
at speed v gives every node the time dt = (half its two adjacent segments) / v, so the steps add up to the
stroke's length / v. Transfer strokes (``spray_on`` False) and strokes whose flow is 0 paint nothing.

Derivation. Treat the gun as a point source at G: paint travels on straight rays, so the volume sent into a
small solid angle dOmega around a ray is the same at every distance. On the pattern plane the ray meets the
plane at distance l = h / cos(theta) and at an angle theta to the plane's normal (the axis), so dOmega covers
the plane area dA_p = l^2 dOmega / cos(theta) = h^2 dOmega / cos^3(theta); the volume rate into dOmega is
therefore Q F(x, y) dA_p. The same dOmega meets the surface at distance d = |v| at the incidence angle alpha
between the ray and the surface normal, covering dA_s = d^2 dOmega / cos(alpha). The film growth rate on the
surface is the volume rate over that area:

    dT/dt = Q F(x, y) dA_p / dA_s = Q F(x, y) (h^2 / cos^3 theta) cos(alpha) / d^2
          = Q F(x, y) (h / z)^2 cos(alpha) / cos(theta)         (d cos(theta) = z)

The common engineering form "(h/d)^2 times the cosine of the incidence" is this with d read as the depth z
along the axis and the 1 / cos(theta) obliquity factor left out (the paraxial form); the full form keeps it,
so that on the pattern's own plane (z = h, alpha = theta) it gives back exactly Q F: a stationary gun
reproduces its pattern, and on a plate that catches all the spray the deposited volume is Q times the spray
time (mass balance). Paint is conserved along rays; drops that would land on a hidden point are lost (they
hit the occluder, which is itself painted only if it is a sample facing the gun).

Output thickness is in mm inside (``thickness_mm``); reports and files give um (``thickness_um``).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from sprayplan.checks import MAX_FILM_SAMPLES, MIN_STEP_MM, check_work, round_up
from sprayplan.coating import kernels
from sprayplan.coating.occlusion import METHODS, compute_occlusion, make_views
from sprayplan.coating.patterns import SprayPattern
from sprayplan.coating.process import Process, StrokeOverride
from sprayplan.coating.sampling import GunSamples, SurfaceSamples, gun_samples, surface_samples
from sprayplan.errors import ConfigError
from sprayplan.surface import normals as nm
from sprayplan.types import Part, Paths, Targets, read_only

log = logging.getLogger(__name__)

#: Largest side of the occlusion depth map (a view costs pixels^2), gun samples per batch (memory: about 200
#: bytes x batch x samples per footprint), and threads.
MAX_OCCLUSION_PIXELS = 1024
MAX_BATCH = 65_536
MAX_WORKERS = 64


@dataclass(frozen=True)
class CoatingConfig:
    """Numerical settings of :func:`simulate`.

    Attributes
    ----------
    max_step_mm : float or None
        Longest gun travel between two time steps; longer plan segments are subdivided (never coarsened).
        None: the pattern radius / 10.
    occlusion : {"auto", "zbuffer", "raster", "rays", "none"}
        How hidden points are found (see ``sprayplan.coating.occlusion``); ``auto``: Embree rays when
        ``embreex`` is installed, else ``raster`` (a numpy depth map).
    occlusion_step_mm : float or None
        Gun travel between two visibility views; 0: every time step; None: the pattern radius / 2.5.
    occlusion_pixels : int
        Side of the depth map (``zbuffer``, ``raster``), pixels.
    speed_along : {"tcp", "surface"}
        Whether the process speed is the contact point's (the default, as the plan's) or the gun tip's (see
        :func:`gun_samples`).
    max_speed_ratio : float
        With ``surface``: the gun tip's speed stays within [v / ratio, v ratio] (``sprayplan.paths.speed``).
    sample_edge_mm : float or None
        The film is computed at the mesh's vertices after splitting its triangles until no edge is longer
        than this (``surface_samples``); None: the pattern radius / 5; 0: the vertices as they are.
    search_factor : float
        Surface samples are gathered within the pattern radius (scaled to the stroke's standoff) times this
        around each aim point; > 1 leaves room for surfaces that curve away from the gun.
    batch : int
        Gun samples handled at a time (memory: about 200 bytes x batch x samples per footprint, per worker).
    workers : int or None
        Threads that handle batches; None: the number of cores, at most 4. The result does not depend on it
        (up to the order of floating-point additions).
    """

    max_step_mm: float | None = None
    occlusion: str = "auto"
    occlusion_step_mm: float | None = None
    occlusion_pixels: int = 16
    speed_along: str = "surface"
    max_speed_ratio: float = 3.0
    sample_edge_mm: float | None = None
    search_factor: float = 1.15
    batch: int = 4096
    workers: int | None = None

    def threads(self) -> int:
        """``workers``, or by default the number of cores, at most 4 (the film's threads; the speed tuning's
        products use as many)."""
        return int(self.workers) if self.workers is not None else min(os.cpu_count() or 1, 4)

    def __post_init__(self):
        if self.occlusion not in METHODS:
            raise ConfigError(f"occlusion must be one of {', '.join(METHODS)}, got {self.occlusion!r}")
        if self.max_step_mm is not None and not (math.isfinite(self.max_step_mm) and self.max_step_mm > 0):
            raise ConfigError(f"max_step_mm must be positive, got {self.max_step_mm}")
        if self.occlusion_step_mm is not None and not self.occlusion_step_mm >= 0:
            raise ConfigError(f"occlusion_step_mm must be >= 0, got {self.occlusion_step_mm}")
        if not self.search_factor >= 1.0:
            raise ConfigError(f"search_factor must be >= 1, got {self.search_factor}")
        if self.speed_along not in ("tcp", "surface"):
            raise ConfigError(f"speed_along must be tcp or surface, got {self.speed_along!r}")
        if self.sample_edge_mm is not None and not (math.isfinite(self.sample_edge_mm) and self.sample_edge_mm >= 0):
            raise ConfigError(f"sample_edge_mm must be a number >= 0, got {self.sample_edge_mm}")
        if not (math.isfinite(self.max_speed_ratio) and self.max_speed_ratio >= 1.0):
            raise ConfigError(f"max_speed_ratio must be >= 1, got {self.max_speed_ratio}")
        if int(self.occlusion_pixels) < 4 or int(self.batch) < 1:
            raise ConfigError("occlusion_pixels must be >= 4 and batch >= 1")
        for name, value, low in (
            ("max_step_mm", self.max_step_mm, MIN_STEP_MM),
            ("sample_edge_mm", self.sample_edge_mm, MIN_STEP_MM),
        ):
            if value is not None and value != 0 and value < low:
                raise ConfigError(
                    f"{name} must be {'0 or ' * (name == 'sample_edge_mm')}a number >= {low:g}, got {value!r}"
                )
        for name, high in (("occlusion_pixels", MAX_OCCLUSION_PIXELS), ("batch", MAX_BATCH), ("workers", MAX_WORKERS)):
            value = getattr(self, name)
            if value is not None and value > high:
                raise ConfigError(f"{name} must be at most {high}, got {value!r}")


@dataclass(frozen=True)
class CoatingResult:
    """Film thickness on the surface samples, and the paint each stroke used.

    Attributes
    ----------
    points, normals, area_mm2, faces
        The surface samples (see :class:`SurfaceSamples`).
    thickness_mm : (n,) float, mm
        Dry film thickness at each sample.
    stroke_time_s : (s,) float
        Duration of each stroke of the plan at its speed (transfers included).
    stroke_flow_ml_min : (s,) float
        Wet paint flow of each stroke (0 for transfers and strokes turned off).
    stroke_paint_ml : (s,) float
        Wet paint each stroke sprayed, mL.
    stroke_deposit_mm3 : (s,) float
        Dry film volume each stroke left on the samples (sum of thickness x area), mm^3.
    process : Process
    name : str
    part_face : (n,) int or None
        For each sample, a face of the part it lies on (:class:`SurfaceSamples`), or None.
    """

    points: np.ndarray
    normals: np.ndarray
    area_mm2: np.ndarray
    faces: np.ndarray
    thickness_mm: np.ndarray
    stroke_time_s: np.ndarray
    stroke_flow_ml_min: np.ndarray
    stroke_paint_ml: np.ndarray
    stroke_deposit_mm3: np.ndarray
    process: Process
    name: str = ""
    part_face: np.ndarray | None = None

    def __post_init__(self):
        read_only(self)

    @property
    def thickness_um(self) -> np.ndarray:
        """(n,) float: the dry film thickness in um."""
        return self.thickness_mm * 1000.0


# ---------------------------------------------------------------------------------------- deposit


def film_rate(points, normals, position, axis, along, pattern: SprayPattern, volume_rate_mm3_s) -> np.ndarray:
    """Film growth rate at surface points from gun positions (the formula of the module docstring).

    Parameters
    ----------
    points, normals : (p, 3) float
        Surface points (mm) and unit outward normals.
    position, axis, along : (p, 3) or (3,) float
        Gun tip (mm), unit axis towards the surface, unit travel direction (perpendicular to the axis).
    pattern : SprayPattern
    volume_rate_mm3_s : float or (p,) float

    Returns
    -------
    (p,) float, mm/s
        Without occlusion.
    """
    v = np.asarray(points, float) - position
    axis = np.broadcast_to(np.asarray(axis, float), v.shape)
    along = np.broadcast_to(np.asarray(along, float), v.shape)
    z = np.einsum("ij,ij->i", v, axis)
    zs = np.where(z > 1e-9, z, 1.0)
    h = pattern.standoff_mm
    x = np.einsum("ij,ij->i", v, along) * h / zs
    y = np.einsum("ij,ij->i", v, np.cross(axis, along)) * h / zs
    cos_term = -np.einsum("ij,ij->i", v, normals)
    rate = volume_rate_mm3_s * pattern.density(x, y) * h * h * cos_term / zs**3
    return np.where((z > 1e-9) & (cos_term > 0), rate, 0.0)


def shot_thickness(
    points, normals, position, axis, pattern: SprayPattern, volume_rate_mm3_s: float, duration_s: float, along=None
) -> np.ndarray:
    """Film left by a stationary gun held for ``duration_s`` (no occlusion): (n,) float, mm.

    ``along`` (the pattern's x direction) defaults to any unit vector perpendicular to the axis.
    """
    axis = nm.unit(np.asarray(axis, float).reshape(1, 3))[0]
    if along is None:
        along = np.cross(axis, [1.0, 0, 0] if abs(axis[0]) < 0.9 else [0, 1.0, 0])
    along = nm.unit(np.asarray(along, float).reshape(1, 3))[0]
    return film_rate(points, normals, position, axis, along, pattern, volume_rate_mm3_s) * duration_s


def simulate(
    part: Part,
    paths: Paths,
    process: Process,
    *,
    overrides: Mapping[int, StrokeOverride] | Sequence[StrokeOverride | None] | None = None,
    config: CoatingConfig | None = None,
    targets: Targets | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> CoatingResult:
    """Dry film thickness left on a part by a plan.

    Parameters
    ----------
    part : Part
        The part painted (mm); its mesh also hides points from the gun (occlusion).
    paths : Paths
        The plan: ``tcp`` is the gun tip, ``-normals`` the gun axis, ``points`` the aim points.
    process : Process
        Pattern, flow, speed, solids, efficiency; the pattern's standoff is the plane it is defined on.
    overrides : mapping or sequence of StrokeOverride, optional
        Per-stroke flow, speed, on/off.
    config : CoatingConfig, optional
    targets : Targets, optional
        Compute at these points instead of the mesh vertices.
    progress : callable, optional
        ``progress(done, total)`` after each batch of gun samples.

    Returns
    -------
    CoatingResult
    """
    config = CoatingConfig() if config is None else config
    setup = _setup(part, paths, process, overrides, config, targets, nodes=False)
    samples, n = setup.samples, len(setup.samples.points)
    thickness = np.zeros(n)
    deposit = np.zeros(len(paths.strokes))
    if setup.occlusion is not None:
        count = 0
        for part_film, part_deposit, pairs in _in_batches(setup, _summed, progress):
            thickness += part_film
            deposit += part_deposit
            count += pairs
        log.debug("coating: %d gun samples, %d surface samples, %d pairs", len(setup.guns.position), n, count)
    paint = setup.flows * setup.times / 60.0
    return CoatingResult(
        samples.points,
        samples.normals,
        samples.area_mm2,
        samples.faces,
        thickness,
        setup.times,
        setup.flows,
        paint,
        deposit,
        process,
        paths.name or part.name,
        samples.part_face,
    )


def deposit_matrix(
    part: Part,
    paths: Paths,
    process: Process,
    *,
    overrides: Mapping[int, StrokeOverride] | Sequence[StrokeOverride | None] | None = None,
    config: CoatingConfig | None = None,
    samples: SurfaceSamples | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[SurfaceSamples, sparse.csr_matrix]:
    """The film as a linear function of the waypoints' time factors (``Stroke.dwell``).

    Returns the surface samples of :func:`simulate` and a sparse (samples x waypoints) matrix ``A``, mm per
    unit time factor, with the waypoints of all ``paths.strokes`` one after another: the film for time
    factors ``w`` is ``A @ w`` (exactly :func:`simulate`'s for strokes with ``dwell = w``), because a time
    step's duration is linear in its segments' factors (``GunSamples.node_share``) and the film is linear in
    the time steps. The strokes' own ``dwell`` is not used.

    ``samples``: the surface samples of an earlier call on the same part (its first result), to add columns
    for more strokes without sampling the part again; by default the part is sampled as :func:`simulate`
    does. ``progress(done, total)`` is called after each batch of gun samples.
    """
    config = CoatingConfig() if config is None else config
    setup = _setup(part, paths, process, overrides, config, None, nodes=True, samples=samples)
    n = len(setup.samples.points)
    waypoints = int(sum(len(s) for s in paths.strokes))
    entries = []
    if setup.occlusion is not None:
        entries = _in_batches(setup, _deposit_entries, progress)
    # repeated (sample, waypoint) entries (a waypoint's gun samples in two batches) are summed
    return setup.samples, kernels.csr_from_entries(entries, (n, waypoints))


def _deposit_entries(setup: _Setup, sl: slice, vt: np.ndarray, gt: np.ndarray):
    """One batch's (sample, waypoint, mm) entries of the deposit matrix, each (sample, waypoint) once.

    Each pair's film (``_pairs``' formula) times each of its gun sample's shares of its waypoints' time factors
    (``node_share`` at ``node``, four a gun sample), summed per (sample, waypoint) over the batch's gun samples
    in order (``kernels.deposit_entries``; the sparse product ``P @ S`` of the (samples x gun samples) film
    and the (gun samples x waypoints) shares, summed in the same order)."""
    grid, occ = setup.grid, setup.occlusion
    kind, params = kernels.pattern_code(setup.pattern)
    return kernels.deposit_entries(
        sl.start, sl.stop, setup.guns.aim, setup.reach, setup.points_g, grid.order, grid.rank, grid.start,
        grid.low, grid.dims, grid.cell, vt, gt, kind, params, np.float32(setup.pattern.standoff_mm), occ.of_gun,
        occ.hidden_keys, occ.view_has_hidden, setup.guns.node, setup.guns.node_share,
    )  # fmt: skip


@dataclass(frozen=True)
class _Setup:
    samples: SurfaceSamples
    guns: GunSamples
    times: np.ndarray
    flows: np.ndarray
    pattern: SprayPattern
    grid: kernels.CellGrid | None = None
    reach: np.ndarray | None = None
    occlusion: object = None  # None: nothing to compute (no gun samples or no surface samples)
    batch: int = 4096
    workers: int = 1
    strokes: int = 0
    points_g: np.ndarray | None = None  # the samples' points in the grid's order


def _setup(part, paths, process, overrides, config: CoatingConfig, targets, nodes: bool, samples=None) -> _Setup:
    """Surface samples (unless given), gun samples and occlusion: what the film's sum runs over."""
    if samples is None:
        edge = process.pattern.radius_mm / 5.0 if config.sample_edge_mm is None else config.sample_edge_mm
        if targets is None and part.is_mesh and edge > 0:
            _check_sample_count(part, edge, config)
        samples = surface_samples(part, targets, edge, facing=paths)
    _check_gun_samples(paths, process, config)
    guns, times, flows = gun_samples(
        paths, process, overrides, config.max_step_mm, config.speed_along, config.max_speed_ratio, nodes=nodes
    )
    pattern = process.pattern
    if not (len(guns.position) and len(samples.points)):
        return _Setup(samples, guns, times, flows, pattern)
    tree = cKDTree(samples.points)
    depth = np.einsum("ij,ij->i", guns.aim - guns.position, guns.axis)
    reach = pattern.support_radius_mm * np.maximum(depth, 1.0) / pattern.standoff_mm * config.search_factor + 1.0
    occ_step = pattern.radius_mm / 2.5 if config.occlusion_step_mm is None else config.occlusion_step_mm
    views = make_views(guns, occ_step, reach)
    half = pattern.support_radius_mm * config.search_factor + 0.5 * occ_step * pattern.standoff_mm / max(
        float(np.median(depth)), 1.0
    )
    workers = config.threads()
    on_vertices = targets is None and part.is_mesh
    occlusion = compute_occlusion(
        config.occlusion if part.is_mesh else "none",
        samples,
        # the film's own mesh (the part's, split finer when coarse) hides points: its vertices are the samples
        samples.points if on_vertices else part.vertices,
        samples.faces if on_vertices else part.faces,
        views,
        pattern.standoff_mm,
        half,
        pixels=int(config.occlusion_pixels),
        sample_tree=tree,
        workers=workers,
        samples_are_vertices=on_vertices,
    )
    # the samples in a grid of cells half a gun sample's median reach wide, for the film's pairs
    grid = kernels.CellGrid(samples.points, float(np.median(reach)) / 2.0)
    return _Setup(
        samples, guns, times, flows, pattern, grid, reach, occlusion, int(config.batch), workers, len(paths.strokes),
        np.ascontiguousarray(samples.points[grid.order]),
    )  # fmt: skip


def _check_sample_count(part: Part, edge: float, config: CoatingConfig) -> None:
    """Refuse, before splitting the mesh, a sample edge that would make more surface samples than
    ``MAX_FILM_SAMPLES`` (about 1.2 area / edge^2 vertices once no edge is longer than ``edge``)."""
    count = max(1.2 * part.area / edge**2, float(len(part.vertices)))
    lowest = math.sqrt(1.2 * part.area / MAX_FILM_SAMPLES)
    setting = (
        "coating.sample_edge_mm" if config.sample_edge_mm is not None else "coating.sample_edge_mm (None: radius / 5)"
    )
    check_work(
        count,
        MAX_FILM_SAMPLES,
        "film samples",
        setting,
        edge,
        f"{part.area:.4g} mm^2",
        f"use coating.sample_edge_mm >= {round_up(lowest)}",
    )


def _check_gun_samples(paths: Paths, process: Process, config: CoatingConfig) -> None:
    """Refuse, before sampling the plan, a time step that would make more gun samples than ``MAX_FILM_SAMPLES``."""
    step = process.pattern.radius_mm / 10.0 if config.max_step_mm is None else float(config.max_step_mm)
    length = sum(float(np.linalg.norm(np.diff(s.tcp, axis=0), axis=1).sum()) for s in paths.spray_strokes)
    count = length / step + sum(len(s.tcp) for s in paths.spray_strokes)
    check_work(
        count,
        MAX_FILM_SAMPLES,
        "gun samples",
        "coating.max_step_mm",
        step,
        f"{length:.4g} mm of spray strokes",
        f"use coating.max_step_mm >= {round_up(length / MAX_FILM_SAMPLES)}",
    )


def _in_batches(setup: _Setup, reduce, progress=None) -> list:
    """``reduce(setup, sl, vt, gt)`` over slices ``sl`` of ``setup.batch`` gun samples, on ``setup.workers``
    threads (the kernels release the GIL); ``vt``, ``gt`` are the float32 rows of the samples and the gun
    samples the film kernels read (:func:`_pair_rows`). ``progress(done, total)`` after each batch, from the
    calling thread."""
    guns = setup.guns
    vt, gt = _pair_rows(setup)

    def one(start):
        return reduce(setup, slice(start, min(start + setup.batch, len(guns.position))), vt, gt)

    starts = range(0, len(guns.position), setup.batch)
    if setup.workers > 1 and len(starts) > 1:
        with ThreadPoolExecutor(max_workers=setup.workers) as pool:
            results = pool.map(one, starts)
            out = []
            for result in results:  # in order, as each batch is done
                out.append(result)
                if progress is not None:
                    progress(len(out), len(starts))
            return out
    out = []
    for start in starts:
        out.append(one(start))
        if progress is not None:
            progress(len(out), len(starts))
    return out


def _pair_rows(setup: _Setup) -> tuple[np.ndarray, np.ndarray]:
    """The float32 rows the film kernels read: ``vt`` (n, 6), the samples' coordinates relative to their
    centroid and their normals, in the order of ``setup.grid``; ``gt`` (7 or 13, k), the gun samples' tip (same origin), Q dt, axis and, for a
    pattern that is not round, its along and across axes.

    The formula of the module docstring is evaluated in float32 on these (``kernels._pair_value``), and each
    pair's film returned in float64."""
    guns, samples = setup.guns, setup.samples
    origin = samples.points.mean(axis=0)
    # a row a sample, in the grid's order
    vt = np.hstack([samples.points - origin, samples.normals]).astype(np.float32)[setup.grid.order]
    pos = guns.position - origin
    rows = [pos[:, 0], pos[:, 1], pos[:, 2], guns.volume_rate_mm3_s * guns.dt_s]
    rows += [guns.axis[:, 0], guns.axis[:, 1], guns.axis[:, 2]]
    if setup.pattern.kind == "double_beta":  # a round pattern needs no pattern axes
        across = np.cross(guns.axis, guns.along)
        rows += [guns.along[:, 0], guns.along[:, 1], guns.along[:, 2], across[:, 0], across[:, 1], across[:, 2]]
    return vt, np.array(rows, dtype=np.float32)


def _summed(setup: _Setup, sl: slice, vt: np.ndarray, gt: np.ndarray):
    """Film per sample, dry volume per stroke and the number of pairs of one batch of gun samples (every
    sample within a gun sample's reach of its aim point, ``kernels.film_sums``)."""
    grid, occ = setup.grid, setup.occlusion
    kind, params = kernels.pattern_code(setup.pattern)
    film = np.zeros(len(setup.samples.points))  # in the grid's order
    deposit = np.zeros(setup.strokes)
    count = kernels.film_sums(
        sl.start, sl.stop, setup.guns.aim, setup.reach, setup.points_g, grid.rank, grid.start, grid.low,
        grid.dims, grid.cell, vt, gt, kind, params, np.float32(setup.pattern.standoff_mm), occ.of_gun,
        occ.hidden_keys, occ.view_has_hidden, setup.guns.stroke, setup.samples.area_mm2[grid.order], film,
        deposit,
    )  # fmt: skip
    return film[grid.rank], deposit, count
