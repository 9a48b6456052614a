r"""Speeds tuned to the film: a time factor at every waypoint, chosen from the simulated film.

Spacing and a constant speed (``spacing``) make the film even between parallel strokes on a flat panel. On a
real part the strokes bend, bunch, run off edges and meet at station hand-overs, and the film drifts off target
there. The film is linear in the time the gun spends on each stretch of path, so the speeds can be corrected
from the model itself: give every waypoint i of a spray stroke a time factor w_i (``Stroke.dwell``; the gun
crosses a segment at the planned speed divided by the mean of its ends' factors) and choose

    w = argmin  sum_s a_s rho(d((A w - T)_s / tol))  +  sum_(i, i+1 in a stroke) (lambda' (w_(i+1) - w_i) / tol)^2
        subject to  w_min <= w_i <= w_max,     d(u) = sign(u) max(|u| - b, 0)

where A is :func:`~sprayplan.coating.thickness.deposit_matrix` (film at every surface sample per unit time
factor, exact: the tuned plan's simulated film is ``A w``), T the target, tol the tolerance, a_s the samples'
area over their mean, rho the Huber loss (rho(r) = r^2 for |r| <= 1, 2 |r| - 1 beyond: with the dead band,
quadratic up to 1 + b tolerances from the target and linear beyond, so that a few
samples no path can reach, such as a lip facing away from every stroke, do not drag their neighbours out of
spec), d a dead band of ``band`` = b tolerances round the target (a film already that close costs nothing, so
the solver spends the speeds on the samples near or out of spec: on reach_curved_part b = 0.3 puts 98.5 % of
the painted area in spec against 98.1 % with b = 0, at a std/mean of 0.032 against 0.038, see
docs/benchmarks.md), and the second sum keeps the speed from jumping between waypoints (lambda' = ``smoothing`` times
sqrt(samples / waypoints) times the target, so the two sums weigh alike whatever the sizes). Only samples
the plan paints with w = 1 (at least ``painted_fraction`` of the target) enter the sum. Solved by
``scipy.optimize.least_squares`` (trust region reflective, LSMR steps on the sparse matrix).

This goes beyond the seeds: seed 003 checks the film after planning, seed 000 fixes the overlap; neither
changes the speed along a stroke.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import sparse
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from sprayplan.checks import check_dwell_bounds
from sprayplan.coating.process import Process
from sprayplan.coating.sampling import SurfaceSamples, gun_samples
from sprayplan.coating.thickness import CoatingConfig, CoatingResult, deposit_matrix
from sprayplan.errors import ConfigError
from sprayplan.heap import release_freed_memory
from sprayplan.refine.system import UM_PER_MM, System, _residuals
from sprayplan.types import Part, Paths, read_only

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TuningConfig:
    """Settings of :func:`tune_speeds`.

    Attributes
    ----------
    min_dwell, max_dwell : float
        Bounds of the time factors: 0.5 and 2 let the gun run at up to twice and down to half its planned
        speed.
    smoothing : float
        Weight of the speed's changes between neighbouring waypoints (see the module's formula); larger is
        smoother, 0 lets every waypoint choose alone.
    iterations : int
        Most evaluations of the solver.
    loss : {"huber", "linear"}
        ``huber``: film errors beyond the tolerance count linearly (the default); ``linear``: plain least
        squares.
    painted_fraction : float
        Samples whose untuned film is at least this fraction of the target are tuned for.
    band : float
        Film errors up to this many tolerances cost nothing (the dead band b of the module's formula);
        0 <= band < 1.
    """

    min_dwell: float = 0.5
    max_dwell: float = 2.0
    smoothing: float = 0.1
    iterations: int = 30
    loss: str = "huber"
    painted_fraction: float = 0.1
    band: float = 0.3

    def __post_init__(self):
        check_dwell_bounds(self.min_dwell, self.max_dwell)
        if not (math.isfinite(self.smoothing) and self.smoothing >= 0):
            raise ConfigError(f"smoothing must be a number >= 0, got {self.smoothing}")
        if int(self.iterations) < 1:
            raise ConfigError(f"iterations must be >= 1, got {self.iterations}")
        if self.loss not in ("huber", "linear"):
            raise ConfigError(f"loss must be huber or linear, got {self.loss!r}")
        if isinstance(self.band, bool) or not (
            isinstance(self.band, (int, float)) and math.isfinite(self.band) and 0 <= self.band < 1
        ):
            raise ConfigError(f"band must be in [0, 1), got {self.band}")
        if not 0 <= self.painted_fraction < 1:
            raise ConfigError(f"painted_fraction must be in [0, 1), got {self.painted_fraction}")


@dataclass(frozen=True)
class Tuning:
    """What :func:`tune_speeds` found.

    Attributes
    ----------
    paths : Paths
        The strokes with their time factors (``Stroke.dwell``); geometry unchanged.
    before_um, after_um : (n,) float
        The film at the surface samples with every factor 1 and with the tuned factors, um.
    area_mm2 : (n,) float
        The samples' areas.
    tuned : (n,) bool
        The samples tuned for.
    samples : SurfaceSamples
        The surface samples (points, normals, faces) the film is known at.
    deposit_mm : scipy.sparse.csr_matrix
        The deposit matrix used (:func:`~sprayplan.coating.thickness.deposit_matrix`, mm per unit factor).
    """

    paths: Paths
    before_um: np.ndarray
    after_um: np.ndarray
    area_mm2: np.ndarray
    tuned: np.ndarray
    samples: SurfaceSamples
    deposit_mm: sparse.csr_matrix

    def __post_init__(self):
        read_only(self)

    def summary(self, target_um: float, tolerance_um: float) -> dict:
        """Area-weighted std / mean and share in spec of the tuned samples, before and after; the range of
        the time factors."""
        out = {}
        w = self.area_mm2[self.tuned]
        for name, film in (("before", self.before_um), ("after", self.after_um)):
            t = film[self.tuned]
            mean = float(np.average(t, weights=w)) if w.sum() > 0 else float("nan")
            std = float(np.sqrt(np.average((t - mean) ** 2, weights=w))) if w.sum() > 0 else float("nan")
            inside = (t >= target_um - tolerance_um) & (t <= target_um + tolerance_um)
            out[name] = {
                "mean_um": mean,
                "cv": std / mean if mean > 0 else float("nan"),
                "share_in_spec": float(w[inside].sum() / w.sum()) if w.sum() > 0 else float("nan"),
            }
        dwell = np.concatenate([s.dwell for s in self.paths.strokes if s.spray_on] or [np.ones(0)])
        out["dwell_min"] = float(dwell.min()) if len(dwell) else 1.0
        out["dwell_max"] = float(dwell.max()) if len(dwell) else 1.0
        return out


def tune_speeds(
    part: Part,
    paths: Paths,
    process: Process,
    target_um: float,
    tolerance_um: float = 5.0,
    *,
    config: TuningConfig | None = None,
    coating: CoatingConfig | None = None,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    initial: np.ndarray | None = None,
    deposit: tuple[SurfaceSamples, sparse.csr_matrix] | None = None,
    progress=None,
) -> Tuning:
    """Time factors at the waypoints of ``paths`` that bring the simulated film to ``target_um``.

    Parameters
    ----------
    part : Part
    paths : Paths
        Any plan; its strokes' own time factors are replaced.
    process : Process
        As for :func:`~sprayplan.coating.thickness.simulate` (its speed is the planned speed).
    target_um, tolerance_um : float
        The film specification; the tolerance is the Huber loss's scale.
    config : TuningConfig, optional
    coating : CoatingConfig, optional
        The film model's settings (as for ``simulate``).
    lower : (waypoints,) float, optional
        Per-waypoint lower bounds of the factors, over all of ``paths.strokes`` one after another, in place of
        ``config.min_dwell`` (touch-up strokes may go lower than the plan's own; where the robot cannot make
        the planned speed, :mod:`sprayplan.refine.limits` raises them to the time factor it can make).
    upper : (waypoints,) float, optional
        Per-waypoint upper bounds in place of ``config.max_dwell``, each at least its lower bound.
    initial : (waypoints,) float, optional
        The factors the solver starts from (clipped to the bounds); default 1 everywhere.
    deposit : (SurfaceSamples, csr_matrix), optional
        The samples and deposit matrix of these paths when already known (``deposit_matrix``'s result, mm);
        otherwise computed.
    progress : callable, optional
        ``progress(done, total)``: after each batch of the deposit matrix (when computed here), then after
        each of the solver's evaluations (``total`` = ``config.iterations``, its most).

    Returns
    -------
    Tuning
    """
    config = TuningConfig() if config is None else config
    if not (math.isfinite(target_um) and target_um > 0 and math.isfinite(tolerance_um) and tolerance_um > 0):
        raise ConfigError(f"need target_um > 0 and tolerance_um > 0, got {target_um}, {tolerance_um}")
    if deposit is None:
        deposit = deposit_matrix(part, paths, process, config=coating, progress=progress)
    samples, deposit_mm = deposit
    if deposit_mm.shape[1] != sum(len(s) for s in paths.strokes):
        raise ConfigError(f"the deposit matrix has {deposit_mm.shape[1]} columns, the paths other waypoints")
    deposit_mm = deposit_mm.tocsr()
    n = deposit_mm.shape[1]
    starts = np.r_[0, np.cumsum([len(s) for s in paths.strokes])]
    free = np.zeros(n, bool)
    for stroke, start in zip(paths.strokes, starts):
        free[start : start + len(stroke)] = stroke.spray_on
    before = _film_um(deposit_mm, np.ones(n))
    tuned = (samples.area_mm2 > 0) & (before >= config.painted_fraction * target_um)
    dwell = np.ones(n)
    low = np.full(n, config.min_dwell) if lower is None else np.asarray(lower, float)
    high = np.full(n, config.max_dwell) if upper is None else np.asarray(upper, float)
    if low.shape != (n,) or not (np.isfinite(low) & (low > 0)).all():
        raise ConfigError(f"lower must hold one finite bound > 0 per waypoint ({n})")
    if high.shape != (n,) or not (np.isfinite(high) & (high >= low)).all():
        raise ConfigError(f"upper must hold one finite bound per waypoint ({n}), each at least its lower bound")
    first = np.ones(n) if initial is None else np.asarray(initial, float)
    if first.shape != (n,) or not np.isfinite(first).all():
        raise ConfigError(f"initial must hold one finite factor per waypoint ({n})")
    if tuned.any() and free.any():
        dwell[free] = _solve(
            deposit_mm, samples.area_mm2, tuned, free, starts, target_um, tolerance_um, config, low, high, first,
            progress, (CoatingConfig() if coating is None else coating).threads(),
        )  # fmt: skip
    after = _film_um(deposit_mm, dwell)
    release_freed_memory()  # the solver's copies of the Jacobian (sprayplan.heap)
    strokes = tuple(s.with_dwell(dwell[a : a + len(s)]) for s, a in zip(paths.strokes, starts))
    log.info(
        "speeds tuned: %d waypoints, time factors %.3g-%.3g",
        int(free.sum()),
        float(dwell[free].min()) if free.any() else 1.0,
        float(dwell[free].max()) if free.any() else 1.0,
    )
    return Tuning(
        Paths(strokes, paths.standoff_mm, paths.spacing_mm, paths.name),
        before,
        after,
        samples.area_mm2,
        tuned,
        samples,
        deposit_mm,
    )


def tuned_film(tuning: Tuning, process: Process, coating: CoatingConfig | None = None) -> CoatingResult:
    """The film the tuned paths leave, from the tuning's own deposit matrix: what
    :func:`~sprayplan.coating.thickness.simulate` returns for ``tuning.paths`` (same samples, film, stroke
    times, flows, paint and deposits), without computing the film a second time."""
    coating = CoatingConfig() if coating is None else coating
    paths = tuning.paths
    _, times, flows = gun_samples(
        paths, process, None, coating.max_step_mm, coating.speed_along, coating.max_speed_ratio
    )
    dwell = np.concatenate([s.dwell for s in paths.strokes]) if paths.strokes else np.zeros(0)
    samples = tuning.samples
    per_waypoint = (samples.area_mm2 @ tuning.deposit_mm) * dwell  # dry volume from each waypoint's factor, mm^3
    stroke_of = np.repeat(np.arange(len(paths.strokes)), [len(s) for s in paths.strokes])
    return CoatingResult(
        samples.points,
        samples.normals,
        samples.area_mm2,
        samples.faces,
        np.asarray(tuning.deposit_mm @ dwell).ravel(),
        times,
        flows,
        flows * times / 60.0,
        np.bincount(stroke_of, per_waypoint, len(paths.strokes)),
        process,
        paths.name,
        samples.part_face,
    )


def _solve(
    deposit_mm, area, tuned, free, starts, target, tol, config: TuningConfig, low, high, first, progress=None, workers=1
) -> np.ndarray:
    rows = np.flatnonzero(tuned)
    cols = np.flatnonzero(free)
    weight = area[rows] / area[rows].mean()
    # neighbouring free waypoints of the same stroke
    position = np.full(len(free), -1)
    position[cols] = np.arange(len(cols))
    same_stroke = np.ones(len(free) - 1, bool)
    same_stroke[starts[1:-1][(starts[1:-1] > 0) & (starts[1:-1] < len(free))] - 1] = False
    pairs = np.flatnonzero(free[:-1] & free[1:] & same_stroke)
    scale = config.smoothing * math.sqrt(len(rows) / len(cols)) * target / tol
    system = System(deposit_mm, rows, position, len(cols), 1.0 / tol, position[pairs], scale, workers)
    target_vec = np.r_[np.full(len(rows), target / tol), np.zeros(len(pairs))]
    low, high = low[cols], high[cols]
    if (high - low < 1e-12).all():
        return high.copy()
    # least_squares wants each lower bound strictly below its upper one: a fixed factor gets a sliver of room
    low_solver = np.minimum(low, high - 1e-9)
    n_fit = len(rows)
    huber = config.loss == "huber"

    def loss(z):
        """rho(z = r^2) and its two derivatives: the samples' terms area-weighted (Huber or squared), the
        smoothness terms squared."""
        out = np.empty((3, len(z)))
        out[0], out[1], out[2] = z, 1.0, 0.0
        if huber:
            fz = z[:n_fit]
            big = fz > 1.0
            root = np.sqrt(fz[big])
            head = out[:, :n_fit]
            head[0, big] = 2.0 * root - 1.0
            head[1, big] = 1.0 / root
            head[2, big] = -0.5 / (fz[big] * root)
        out[:, :n_fit] *= weight
        return out

    residual, jacobian = _residuals(system, target_vec, float(config.band))
    if progress is not None:
        evaluations = 0
        plain = residual

        def residual(x):
            nonlocal evaluations
            evaluations += 1
            progress(min(evaluations, int(config.iterations)), int(config.iterations))
            return plain(x)

    # LSMR's dot products are short and many: one BLAS thread (two stall each other on a busy machine); the
    # system's products run on ``workers`` threads of their own (System.pool)
    with threadpool_limits(limits=1, user_api="blas"), system.threads():
        result = least_squares(
            residual,
            np.clip(first[cols], low_solver, high),
            jac=jacobian,
            bounds=(low_solver, high),
            method="trf",
            tr_solver="lsmr",
            loss=loss,
            max_nfev=int(config.iterations),
        )
    return np.clip(result.x, low, high)


def _film_um(deposit_mm: sparse.csr_matrix, dwell: np.ndarray) -> np.ndarray:
    """The film in um at every sample for time factors ``dwell``: ``(deposit_mm * 1000) @ dwell``, summed as
    scipy's CSR product of the scaled matrix sums it, without the scaled copy."""
    return _scaled_matvec(deposit_mm.indptr, deposit_mm.indices, deposit_mm.data, UM_PER_MM, np.asarray(dwell, float))


@njit(cache=True, nogil=True)
def _scaled_matvec(indptr, indices, data, factor, x):
    out = np.empty(len(indptr) - 1)
    for r in range(len(indptr) - 1):
        total = 0.0
        for k in range(indptr[r], indptr[r + 1]):
            total += (data[k] * factor) * x[indices[k]]
        out[r] = total
    return out
