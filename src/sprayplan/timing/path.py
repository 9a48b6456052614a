"""A stroke's joint path time-optimal under the axes' limits and a gun-tip speed bound (toppra), checked densely.

The joint waypoints are joined by a cubic spline ``q(s)`` over a path parameter s whose knots are spaced by
the least time each segment can take (the gun tip at the stroke's fastest planned speed, every axis at its
speed limit; a spline over the tip's arc length overshoots wildly where the wrist turns fast over a short
stretch). toppra (reachability analysis, Pham & Pham 2018) finds the fastest ``s(t)`` from
rest to rest such that, at its grid points, every axis keeps ``|q'(s) sd| <= v_max`` and ``|q'(s) sdd +
q''(s) sd^2| <= a_max``, and the gun tip keeps ``|p'(s)| sd <= v_cap`` with ``p(s)`` the tip's position
(forward kinematics) and ``v_cap`` the planned tip speed of the segment (so a stroke never runs faster than its
paint speed). Between grid points ``sd^2`` is linear in s (constant ``sdd``), which toppra does not check.

So the result is checked at ``check_steps`` points per grid interval (evenly in time, both ends included)
against all three limits; an interval where one is exceeded is split at its middle (a new grid point, where
toppra then holds the limits too), and toppra runs again on the finer grid (at most ``max_rounds`` times). If limits are still exceeded
after that, the whole stroke is slowed uniformly in time by the factor that makes them hold: stretching time
by k divides speeds by k and accelerations by k^2, so every check then holds (``PathTiming.stretch``).

:func:`time_paths` times many paths at once, each as :func:`time_path` would alone: toppra's problem of every
path still refining is solved together in each round (``timing.reach``, toppra itself where that finds a stage
empty), and the tip speeds ``|p'(s)|`` of all their samples come from one call of ``tip_rate`` (the forward
kinematics differentiated along q'(s)) per group of strokes when it is given, else from central differences of
``tip``.

Work done once: q'(s), q''(s) and |p'(s)| at a grid point are kept through the rounds (a round evaluates only
the points it added), and a dense-check sample that is a grid point, or that the last round's check took
already (the final check's fractions include the rounds'), takes its |p'(s)| from there rather than from the
forward kinematics again. The spline's values, the samples and their ratios to the limits are compiled loops
(``timing.kernels``) with the arithmetic of scipy's spline evaluation and of the numpy forms
(:func:`_dense_samples_numpy`, kept here for paths that are not toppra's cubic splines; the ratios' numpy form
in tests/test_timing_speed.py): the same numbers bit for bit.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import toppra
from scipy.interpolate import PPoly
from toppra.constraint import JointAccelerationConstraint, LinearConstraint

from sprayplan.timing.kernels import dense_ratios, dense_samples, spline_values
from sprayplan.timing.limits import AxisLimits
from sprayplan.timing.reach import reach_paths

log = logging.getLogger(__name__)

#: Smallest knot step between two waypoints, s (waypoints where nothing moves).
MIN_STEP_S = 1e-5
#: The relative slack every dense check allows (floating point, not a tolerance of the limits).
CHECK_SLACK = 1e-9
#: Grid points near each end, as fractions of the first (last) half segment.
END_FRACTIONS = np.array([1e-4, 1e-3, 1e-2, 1e-1])
#: The final check looks again, with this many times the points, at the intervals within NEAR_LIMIT of a limit.
FINAL_FACTOR = 8
NEAR_LIMIT = 0.9
#: Samples per forward-kinematics call of the tip speeds.
SLOPE_CHUNK = 4096
#: Most dense-check samples held at once (over the strokes of a group; about 320 bytes each, in arrays kept
#: from group to group).
CHECK_BATCH = 50_000
#: Most grid points in one call of the reachability analysis (its inputs gathered, about 160 bytes each; each
#: path's rows, about 800 bytes a grid point, are made one path at a time).
REACH_BATCH = 20_000
#: How much below a violated bound a tightened bound is set (relative).
TIGHTEN_MARGIN = 0.01


@dataclass(frozen=True)
class PathTiming:
    """The time-optimal timing of one joint path.

    Attributes
    ----------
    t_s : (n,) float
        Time at each waypoint from the path's start (0), s; increasing.
    speed_mm_s : (n,) float
        The gun tip's speed at each waypoint, mm/s (0 at the two ends: rest to rest).
    duration_s : float
    rounds : int
        Grid refinements toppra needed (0: its first answer held everywhere).
    stretch : float
        The uniform time stretch applied after the rounds (1: none).
    worst : dict
        The largest ratio to its limit found by the last dense check (``velocity``, ``acceleration``,
        ``tip_speed``), after the stretch: at most 1.
    path : toppra.SplineInterpolator
        The joint path q(s) (s: the least time at the waypoints, see the module docstring).
    grid_s, grid_t, grid_sd, grid_sdd : (m,), (m,), (m,), (m - 1,) float
        The timing at toppra's grid points: s, the time, ds/dt there, and d2s/dt2 on each interval.
    """

    t_s: np.ndarray
    speed_mm_s: np.ndarray
    duration_s: float
    rounds: int
    stretch: float
    worst: dict
    path: object = None
    grid_s: np.ndarray = None  # type: ignore[assignment]
    grid_t: np.ndarray = None  # type: ignore[assignment]
    grid_sd: np.ndarray = None  # type: ignore[assignment]
    grid_sdd: np.ndarray = None  # type: ignore[assignment]

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The joints, their speeds and accelerations at times (k,) s within the duration: three (k, dof)."""
        t = np.clip(np.asarray(times, float), 0.0, self.duration_s)
        k = np.clip(np.searchsorted(self.grid_t, t, side="right") - 1, 0, len(self.grid_sdd) - 1)
        tau = t - self.grid_t[k]
        s = np.clip(self.grid_s[k] + self.grid_sd[k] * tau + 0.5 * self.grid_sdd[k] * tau**2, 0.0, self.grid_s[-1])
        v = self.grid_sd[k] + self.grid_sdd[k] * tau
        d1 = self.path(s, 1)
        return self.path(s), d1 * v[:, None], d1 * self.grid_sdd[k][:, None] + self.path(s, 2) * (v**2)[:, None]


class _SpeedBound(LinearConstraint):
    """Upper bounds on ``x = sd^2`` at the grid points: the axes' speeds and the gun tip's, each scaled."""

    def __init__(self, bound_x: np.ndarray, dof: int):
        super().__init__()
        self.bound_x = bound_x
        self.dof = dof

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        xbound = np.column_stack([np.zeros(len(gridpoints)), self.bound_x])
        return None, None, None, None, None, None, xbound


def _bounds(d1, slope, grid, s_way, cap, limits: AxisLimits, on_waypoint=None):
    """The upper bound of sd^2 at each grid point (every axis at its speed limit, the tip at its planned speed:
    at a waypoint the slower of its two segments') and the planned tip speed of each grid interval; ``d1``: q'(s)
    at the grid points, ``slope``: the tip's |p'(s)| there, ``on_waypoint``: which grid points are waypoints
    (``np.isin(grid, s_way)`` when not given)."""
    n = len(s_way)
    segment = np.clip(np.searchsorted(s_way, grid, side="right") - 1, 0, n - 2)  # the segment of each point
    if on_waypoint is None:
        on_waypoint = np.isin(grid, s_way)
    cap_grid = np.where(on_waypoint, np.minimum(cap[np.maximum(segment - 1, 0)], cap[segment]), cap[segment])
    cap_grid[-1] = cap[-1]
    with np.errstate(divide="ignore"):
        joint_x = np.min((limits.velocity[None, :] / np.abs(d1)) ** 2, axis=1)
        tip_x = (cap_grid / slope) ** 2
    return np.minimum(joint_x, tip_x), cap[segment[:-1]]


def _slope_function(tip: Callable, tip_rate: Callable | None):
    """``slopes([(path, s, d1[, q]), ...]) -> [(k,), ...]``: |p'(s)|, the gun tip's distance per unit of s at
    path positions s of each path (``d1``: q'(s) there, ``q``: q(s) there, each or None: then evaluated): from
    ``tip_rate`` exactly, in one call for all the paths, else central differences of ``tip``. With
    ``tip_rate``, ``slopes.rates(q, d1)`` is the same from the joints and their rates (k, dof) directly (else
    None)."""
    if tip_rate is None:

        def slopes(requests):
            return [_tip_slope(path, tip, s) for path, s, *_ in requests]

        slopes.rates = None
    else:

        def rates(q, d1):
            speed = np.empty(len(q))
            for k in range(0, len(q), SLOPE_CHUNK):  # chunks that stay in the cache
                speed[k : k + SLOPE_CHUNK] = np.linalg.norm(
                    tip_rate(q[k : k + SLOPE_CHUNK], d1[k : k + SLOPE_CHUNK])[1], axis=1
                )
            return speed

        def slopes(requests):
            if not requests:
                return []
            q = np.concatenate(
                [path(s) if len(rest) < 2 or rest[1] is None else rest[1] for path, s, *rest in requests]
            )
            d1 = np.concatenate([path(s, 1) if rest[0] is None else rest[0] for path, s, *rest in requests])
            return np.split(rates(q, d1), np.cumsum([len(r[1]) for r in requests])[:-1])

        slopes.rates = rates
    return slopes


def _tip_slope(path, tip: Callable, s: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """|p'(s)|: the gun tip's distance per unit of s (central differences of the forward kinematics)."""
    lo = np.maximum(s - h, path.path_interval[0])
    hi = np.minimum(s + h, path.path_interval[1])
    return np.linalg.norm(tip(path(hi)) - tip(path(lo)), axis=1) / (hi - lo)


def time_path(
    q: np.ndarray,
    cap_mm_s: np.ndarray,
    limits: AxisLimits,
    tip: Callable[[np.ndarray], np.ndarray],
    *,
    check_steps: int = 4,
    max_rounds: int = 2,
    knot_speeds: tuple | None = None,
    tip_rate: Callable | None = None,
) -> PathTiming:
    """Time a joint path from rest to rest, fastest within ``limits`` and the gun-tip speed bound.

    Parameters
    ----------
    q : (n, dof) float
        Joint vectors at the waypoints (n >= 2).
    cap_mm_s : (n - 1,) float
        The planned gun-tip speed on each segment: the timed tip never runs faster.
    limits : AxisLimits
    tip : callable
        ``tip(q (k, dof)) -> (k, 3)`` mm, the gun tip by forward kinematics.
    check_steps : int
        Dense check points per grid interval.
    max_rounds : int
        Most grid refinements before the uniform stretch.
    knot_speeds : (axis speeds (dof,), tip speed) or None
        The speeds that space the spline's knots (see the module docstring); None: ``limits.velocity`` and the
        largest of ``cap_mm_s``. The joint path between the waypoints depends on them: give the same ones to
        compare timings of one path under different limits.
    tip_rate : callable or None
        ``tip_rate(q (k, dof), dq (k, dof)) -> (positions (k, 3), rates (k, 3))``: the tip and its rate of
        change along joint rates dq (``robots.gantry.Gantry.gun_tip``); None: central differences of ``tip``.
    """
    return time_paths(
        [(q, cap_mm_s)],
        limits,
        tip,
        check_steps=check_steps,
        max_rounds=max_rounds,
        knot_speeds=knot_speeds,
        tip_rate=tip_rate,
    )[0]


class _Stroke:
    """One path's state while :func:`time_paths` refines its grid.

    Besides the grid, it keeps q'(s), q''(s) and the tip's |p'(s)| at every grid point (``grid_d1``,
    ``grid_d2``, ``grid_slope``): each round evaluates them only at the points it added (``added``: their
    indices in the grid, None for all of them), and the dense checks take them where a sample falls on a grid
    point. Each is a function of s alone, evaluated point by point, so the values are the ones a fresh
    evaluation at the whole grid gives."""

    def __init__(self, q, cap_mm_s, limits: AxisLimits, tip, knot_speeds, tip_q=None):
        q = np.asarray(q, float)
        n = len(q)
        cap = np.asarray(cap_mm_s, float)
        # knots spaced by the least time each segment can take (the tip, by forward kinematics, at the fastest
        # planned speed; every axis at its limit): the spline then does not overshoot where the joints move much
        # over a short stretch of the tip's path (a wrist turning near a singularity), and sd stays near 1 or
        # below (toppra's LP solver loses the feasible set where sd^2 grows large); ``tip_q``: tip(q) when known
        axis_speed, tip_speed = (limits.velocity, float(cap.max())) if knot_speeds is None else knot_speeds
        tip_step = np.linalg.norm(np.diff(tip(q) if tip_q is None else tip_q, axis=0), axis=1) / tip_speed
        axis_step = (np.abs(np.diff(q, axis=0)) / np.asarray(axis_speed, float)).max(axis=1)
        step = np.maximum(np.maximum(tip_step, axis_step), MIN_STEP_S)
        self.s_way = np.concatenate([[0.0], np.cumsum(step)])
        self.path = toppra.SplineInterpolator(self.s_way, q)
        self.spline = _spline_parts(self.path)
        # grid: the waypoints, the middle of every segment, and points closing in on the two ends (from rest,
        # the first interval's constant sdd takes twice the time of the same stretch at speed: small intervals
        # there keep that to what the acceleration limits really cost)
        grid = np.empty(2 * n - 1)
        grid[0::2] = self.s_way
        grid[1::2] = 0.5 * (self.s_way[:-1] + self.s_way[1:])
        head = grid[1] * END_FRACTIONS
        tail = grid[-1] - (grid[-1] - grid[-2]) * END_FRACTIONS[::-1]
        self.grid = np.concatenate([grid[:1], head, grid[1:-1], tail, grid[-1:]])
        self.on_waypoint = np.isin(self.grid, self.s_way)  # kept with the grid through its refinements
        self.cap = cap
        self.n = n
        self.rounds = 0
        self.done = False
        self.checked = None  # the last whole dense check's time fractions and |p'(s)| (_dense_check)
        self.added = None  # the grid points without values yet (indices; None: all)
        self.split = None  # the intervals the last round split (indices into the grid before it)

    def values(self, s: np.ndarray):
        """q(s), q'(s) and q''(s) at path positions s (k,): three (k, dof) (:func:`kernels.spline_values`, the
        numbers of the spline's own evaluation; that where the path is not a toppra spline)."""
        if self.spline is None:
            return self.path(s), self.path(s, 1), self.path(s, 2)
        dof = self.spline[1].shape[2]
        s = np.ascontiguousarray(s, dtype=float)
        q, d1, d2 = (np.empty((len(s), dof)) for _ in range(3))
        spline_values(*self.spline, s, q, d1, d2)
        return q, d1, d2

    def evaluate_grid(self):
        """q'(s) and q''(s) at the grid points without them: ``(s, d1, q)`` of those points, for their
        slopes."""
        s = self.grid if self.added is None else self.grid[self.added]
        q, d1, d2 = self.values(s)
        if self.added is None:
            self.grid_d1, self.grid_d2 = d1, d2
        else:
            self.grid_d1 = np.insert(self.grid_d1, self.split + 1, d1, axis=0)
            self.grid_d2 = np.insert(self.grid_d2, self.split + 1, d2, axis=0)
        return s, d1, q

    def take_slopes(self, slope):
        """The tip's |p'(s)| at the points :meth:`evaluate_grid` evaluated."""
        if self.added is None:
            self.grid_slope = slope
        else:
            self.grid_slope = np.insert(self.grid_slope, self.split + 1, slope)
        self.added = self.split = None

    def refine(self, split):
        """Split the grid intervals ``split`` (sorted indices) at their middles."""
        grid = self.grid
        middle = 0.5 * (grid[split] + grid[split + 1])
        self.grid = np.insert(grid, split + 1, middle)
        self.on_waypoint = np.insert(self.on_waypoint, split + 1, np.isin(middle, self.s_way))
        self.split = split
        self.added = split + 1 + np.arange(len(split))


def time_paths(
    paths,
    limits: AxisLimits,
    tip: Callable[[np.ndarray], np.ndarray],
    *,
    check_steps: int = 4,
    max_rounds: int = 2,
    knot_speeds: tuple | None = None,
    tip_rate: Callable | None = None,
) -> list[PathTiming]:
    """:func:`time_path` for many joint paths ``[(q, cap_mm_s), ...]``, each timed on its own (the same answer
    as one at a time); toppra's reachability analysis runs on all the paths of a refinement round together
    (``timing.reach``)."""
    slopes = _slope_function(tip, tip_rate)
    paths = [(np.asarray(q, float), cap) for q, cap in paths]
    strokes = [
        _Stroke(q, cap, limits, tip, knot_speeds, p) for (q, cap), p in zip(paths, _tips(tip, [q for q, _ in paths]))
    ]
    frac = np.linspace(0.0, 1.0, check_steps + 1)
    buffers = _Buffers()
    while True:
        todo = [st for st in strokes if not st.done]
        if not todo:
            break
        # q'(s), q''(s) and |p'(s)| at the grid points (only the ones the last round added: the others kept)
        requests = [(st.path, *st.evaluate_grid()) for st in todo]
        for st, slope in zip(todo, slopes(requests)):
            st.take_slopes(slope)
        inputs = []
        for st in todo:
            st.base_x, st.cap_interval = _bounds(
                st.grid_d1, st.grid_slope, st.grid, st.s_way, st.cap, limits, st.on_waypoint
            )
            inputs.append((st.grid, st.grid_d1, st.grid_d2, st.base_x))
        answers = []
        for group in _groups(inputs, [len(grid) for grid, _, _, _ in inputs], REACH_BATCH):
            answers += reach_paths(group, limits.acceleration)
        del inputs
        for st, sd in zip(todo, answers):
            if sd is None:  # a stage this analysis finds empty: toppra's own answer (or failure)
                sd = _toppra(st, limits)
            if sd is None or not np.isfinite(sd).all():
                raise RuntimeError(f"toppra found no parameterisation of a {st.n}-waypoint stroke from rest to rest")
            grid = st.grid
            ds = np.diff(grid)
            st.sd = sd = np.maximum(np.asarray(sd, float), 0.0)
            st.dt = 2.0 * ds / np.maximum(sd[:-1] + sd[1:], 1e-300)
            st.sdd = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
        for group in _groups(todo, [(len(st.grid) - 1) * len(frac) for st in todo]):
            rows = [np.arange(len(st.grid) - 1) for st in group]
            for st, ratios in zip(group, _dense_check(group, rows, frac, slopes, tip, limits, buffers)):
                st.ratios = ratios
        for st in todo:
            st.worst = [float(r.max(initial=0.0)) for r in st.ratios]
            if max(st.worst) <= 1.0 + CHECK_SLACK or st.rounds >= max_rounds:
                st.done = True
                continue
            st.rounds += 1
            # a limit exceeded between two grid points: the interval split at its middle (a new grid point,
            # where toppra holds every limit too)
            bad = np.maximum(np.maximum(st.ratios[0], st.ratios[1]), st.ratios[2])
            st.refine(np.flatnonzero(bad > 1.0 + CHECK_SLACK))
    # the final check: the intervals near a limit again, at FINAL_FACTOR times the points
    fine = np.linspace(0.0, 1.0, FINAL_FACTOR * check_steps + 1)
    for st in strokes:
        st.near = np.flatnonzero(np.maximum(np.maximum(*st.ratios[:2]), st.ratios[2]) > NEAR_LIMIT)
    again = [st for st in strokes if len(st.near)]
    for group in _groups(again, [len(st.near) * len(fine) for st in again]):
        near = [st.near for st in group]
        for st, ratios in zip(group, _dense_check(group, near, fine, slopes, tip, limits, buffers)):
            st.worst = [max(w, float(r.max(initial=0.0))) for w, r in zip(st.worst, ratios)]
    return [_finish(st, np.flatnonzero(st.on_waypoint)) for st in strokes]


def _tips(tip: Callable, qs: list) -> list:
    """``tip(q)`` of each joint path of ``qs``, from one call on all their waypoints (the forward kinematics
    of each waypoint on its own: the same numbers as a call per path)."""
    if not qs:
        return []
    return np.split(tip(np.concatenate(qs)), np.cumsum([len(q) for q in qs])[:-1])


def _spline_parts(path):
    """``(breaks, c, c', c'')``: a toppra spline's three piecewise polynomials (q, q', q'': the scipy ``PPoly``
    of its ``CubicSpline`` and its two derivatives) for :func:`kernels.spline_values`, or None where the path
    is not one (then its own evaluation is used)."""
    polys = [getattr(path, name, None) for name in ("cspl", "cspld", "cspldd")]
    if not all(isinstance(p, PPoly) and p.c.ndim == 3 and p.axis == 0 and p.extrapolate is True for p in polys):
        return None
    if [p.c.shape[0] for p in polys] != [4, 3, 2]:  # a cubic and its two derivatives
        return None
    breaks = np.ascontiguousarray(polys[0].x, dtype=float)
    if len(breaks) < 2 or any(not np.array_equal(p.x, breaks) for p in polys[1:]) or not (np.diff(breaks) > 0).all():
        return None
    return (breaks, *(np.ascontiguousarray(p.c, dtype=float) for p in polys))


def _groups(strokes: list, sizes: list, most: int | None = None):
    """The strokes in consecutive groups of at most ``most`` samples in all (``CHECK_BATCH`` unless given; a
    larger stroke alone): the dense checks' samples (and the reachability analysis's rows, ``REACH_BATCH``
    grid points) of one group at a time, so that their memory stays bounded on a large plan."""
    group, total = [], 0
    for st, size in zip(strokes, sizes):
        if group and total + size > (CHECK_BATCH if most is None else most):
            yield group
            group, total = [], 0
        group.append(st)
        total += size
    if group:
        yield group


def _toppra(st: _Stroke, limits: AxisLimits):
    """toppra's parameterisation of a stroke's current grid (sd at the grid points, or None)."""
    constraints = [_SpeedBound(st.base_x, limits.dof), JointAccelerationConstraint(limits.acceleration)]
    algorithm = toppra.algorithm.TOPPRA(constraints, st.path, gridpoints=st.grid, solver_wrapper="seidel")
    _, sd, _, _ = algorithm.compute_parameterization(0.0, 0.0, return_data=True)
    return sd


def _finish(st: _Stroke, wp: np.ndarray) -> PathTiming:
    """The uniform stretch if a limit still does not hold after the checks, and the timing at the waypoints
    (grid points ``wp``)."""
    worst = st.worst
    stretch = 1.0
    if max(worst) > 1.0 + CHECK_SLACK:
        stretch = max(worst[0], np.sqrt(worst[1]), worst[2]) * (1.0 + CHECK_SLACK)
        log.debug("a stroke's limits held only after stretching its time by %.6g", stretch)
        worst = [worst[0] / stretch, worst[1] / stretch**2, worst[2] / stretch]
    t_grid = np.concatenate([[0.0], np.cumsum(st.dt)]) * stretch
    sd = st.sd / stretch
    return PathTiming(
        t_s=t_grid[wp],
        speed_mm_s=st.grid_slope[wp] * sd[wp],
        duration_s=float(t_grid[-1]),
        rounds=st.rounds,
        stretch=float(stretch),
        worst={"velocity": worst[0], "acceleration": worst[1], "tip_speed": worst[2]},
        path=st.path,
        grid_s=st.grid,
        grid_t=t_grid,
        grid_sd=sd,
        grid_sdd=st.sdd / stretch**2,
    )


class _Buffers:
    """The arrays of a dense check's samples (:func:`_dense_check`), kept from group to group and grown when a
    group needs more."""

    def __init__(self):
        self.size = self.dof = -1

    def take(self, total: int, dof: int) -> tuple:
        """s, v, slope (total,); d1, d2 (total, dof); fresh (total,) int; q_fresh, d1_fresh (total, dof)."""
        if total > self.size or dof != self.dof:
            self.size, self.dof = max(total, 1), dof
            n = self.size
            self.arrays = (
                np.empty(n), np.empty(n), np.empty(n), np.empty((n, dof)), np.empty((n, dof)),
                np.empty(n, np.int64), np.empty((n, dof)), np.empty((n, dof)),
            )  # fmt: skip
        return tuple(a[:total] for a in self.arrays)


def _dense_check(
    group: list, rows: list, frac: np.ndarray, slopes, tip: Callable, limits: AxisLimits, buffers: _Buffers
) -> list:
    """The dense check of a group of strokes, each over its grid intervals ``rows`` (indices): per stroke, the
    largest ratio to its limit of joint speed, joint acceleration and tip speed on each interval, (k,) each,
    over ``len(frac)`` samples evenly in time across it (:func:`_dense_samples_numpy`, :func:`_dense_ratios`).

    The samples of the whole group lie in one set of arrays, stroke after stroke; the tip's |p'(s)| of the
    samples that are not grid points (whose is known, :class:`_Stroke`) comes from one ``slopes.rates`` call
    for the group (or central differences of ``tip`` per stroke). The arrays are ``buffers``', used again by
    the next group (fresh pages for every group cost more than the samples)."""
    m = len(frac)
    dof = limits.dof
    sizes = [len(k) * m for k in rows]
    s, v, slope, d1, d2, fresh, q_fresh, d1_fresh = buffers.take(int(sum(sizes)), dof)
    spans = []  # each stroke's samples and its fresh ones: (start, end, fresh start, fresh end)
    start = done = 0
    for st, k, size in zip(group, rows, sizes):
        k = np.ascontiguousarray(k, dtype=np.int64)
        at = slice(start, start + size)
        if st.spline is not None:
            out = (s[at], v[at], d1[at], d2[at], slope[at])
            earlier, same_as = _earlier_slopes(st, frac)
            count = dense_samples(
                *st.spline, st.grid, st.sd, st.sdd, st.dt, k, frac, st.grid_slope, earlier, same_as, out,
                fresh[done:], q_fresh[done:], d1_fresh[done:],
            )  # fmt: skip
        else:
            s[at], v[at], d1[at], d2[at], known = _dense_samples_numpy(st, k, frac)
            slope[at] = np.where(known >= 0, st.grid_slope[known], np.nan)
            new = np.flatnonzero(known < 0)
            count = len(new)
            fresh[done : done + count] = new
            q_fresh[done : done + count] = st.path(s[at][new])
            d1_fresh[done : done + count] = d1[at][new]
        fresh[done : done + count] += start
        spans.append((start, start + size, done, done + count))
        start += size
        done += count
    fresh = fresh[:done]
    if slopes.rates is not None:
        slope[fresh] = slopes.rates(q_fresh[:done], d1_fresh[:done])
    else:
        for st, (_, _, lo, hi) in zip(group, spans):
            slope[fresh[lo:hi]] = _tip_slope(st.path, tip, s[fresh[lo:hi]])
    out = []
    for st, k, (lo, hi, _, _) in zip(group, rows, spans):
        whole = len(k) == len(st.sdd)  # every interval (k is then 0, 1, ...)
        sdd, cap = (st.sdd, st.cap_interval) if whole else (st.sdd[k], st.cap_interval[k])
        out.append(_dense_ratios(d1[lo:hi], d2[lo:hi], v[lo:hi], sdd, slope[lo:hi], m, limits, cap))
        if whole:  # a whole check: its |p'(s)| for a later check of the same timing
            st.checked = (frac, slope[lo:hi].reshape(len(k), m).copy())
    return out


def _earlier_slopes(st: _Stroke, frac: np.ndarray):
    """The tip's |p'(s)| of the stroke's last whole dense check (``checked``; taken on its current timing when
    the rounds are over), and for each of ``frac`` the column there of the same time fraction (-1: none)."""
    same_as = np.full(len(frac), -1, np.int64)
    if st.checked is None or not st.done:
        return np.empty((1, 1)), same_as
    earlier_frac, earlier = st.checked
    column = np.clip(np.searchsorted(earlier_frac, frac), 0, len(earlier_frac) - 1)
    same_as[:] = np.where(earlier_frac[column] == frac, column, -1)
    return earlier, same_as


def _dense_samples_numpy(st: _Stroke, k: np.ndarray, frac: np.ndarray):
    """The samples of a dense check over a stroke's grid intervals ``k``, each from s0 to s1, starting at speed
    sd0 and accelerating at sdd for dt: ``frac`` points evenly in time across each, flattened interval by
    interval: their positions s, speeds sd, q'(s), q''(s), and the grid point each is (its first sample at s0,
    its last at s1; -1 for none). The straightforward form of :func:`kernels.dense_samples` (for a path that
    is not a toppra spline, and for the tests)."""
    grid = st.grid
    s0, s1, sd0, sdd, dt = grid[k], grid[k + 1], st.sd[k], st.sdd[k], st.dt[k]
    tau = dt[:, None] * frac[None, :]
    s = s0[:, None] + sd0[:, None] * tau + 0.5 * sdd[:, None] * tau**2
    s = np.clip(s, s0[:, None], s1[:, None])
    v = sd0[:, None] + sdd[:, None] * tau
    rows, m = s.shape
    known = np.full((rows, m), -1)
    ends = ((0, s0, k),) if m == 1 else ((0, s0, k), (m - 1, s1, k + 1))
    for col, at, point in ends:
        known[:, col] = np.where(s[:, col] == at, point, -1)
    flat = s.reshape(-1)
    return flat, v.reshape(-1), st.path(flat, 1), st.path(flat, 2), known.reshape(-1)


def _dense_ratios(d1, d2, v, sdd, slope, m: int, limits: AxisLimits, cap_interval):
    """Per grid interval (``m`` samples each), the largest ratio of joint speed, joint acceleration and tip
    speed to its limit (``d1``, ``d2``: q'(s), q''(s) at the samples, ``v``: sd there, ``slope``: the tip's
    |p'(s)|), each local peak refined by the parabola through it and its two neighbours
    (:func:`kernels.dense_ratios`; ``tests/test_timing_speed.py`` keeps the numpy form it must equal)."""
    out = tuple(np.empty(len(sdd)) for _ in range(3))
    dense_ratios(
        np.ascontiguousarray(d1, dtype=float),
        np.ascontiguousarray(d2, dtype=float),
        np.ascontiguousarray(v, dtype=float),
        np.ascontiguousarray(sdd, dtype=float),
        np.ascontiguousarray(slope, dtype=float),
        np.ascontiguousarray(limits.velocity, dtype=float),
        np.ascontiguousarray(limits.acceleration, dtype=float),
        np.ascontiguousarray(cap_interval, dtype=float),
        m,
        *out,
    )
    return out
