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
kinematics differentiated along q'(s)) when it is given, else from central differences of ``tip``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import toppra
from toppra.constraint import JointAccelerationConstraint, LinearConstraint

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
#: Most dense-check samples held at once (over the strokes of a group; about 300 bytes each).
CHECK_BATCH = 50_000
#: Most grid points in one batch of the reachability analysis (about 1.2 kB each).
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


def _bounds(d1, slope, grid, s_way, cap, limits: AxisLimits):
    """The upper bound of sd^2 at each grid point (every axis at its speed limit, the tip at its planned speed:
    at a waypoint the slower of its two segments') and the planned tip speed of each grid interval; ``d1``: q'(s)
    at the grid points, ``slope``: the tip's |p'(s)| there."""
    n = len(s_way)
    segment = np.clip(np.searchsorted(s_way, grid, side="right") - 1, 0, n - 2)  # the segment of each point
    on_waypoint = np.isin(grid, s_way)
    cap_grid = np.where(on_waypoint, np.minimum(cap[np.maximum(segment - 1, 0)], cap[segment]), cap[segment])
    cap_grid[-1] = cap[-1]
    with np.errstate(divide="ignore"):
        joint_x = np.min((limits.velocity[None, :] / np.abs(d1)) ** 2, axis=1)
        tip_x = (cap_grid / slope) ** 2
    return np.minimum(joint_x, tip_x), cap[segment[:-1]]


def _slope_function(tip: Callable, tip_rate: Callable | None):
    """``slopes([(path, s, d1), ...]) -> [(k,), ...]``: |p'(s)|, the gun tip's distance per unit of s at path
    positions s of each path (``d1``: q'(s) there, or None): from ``tip_rate`` exactly, in one call for all
    the paths, else central differences of ``tip``."""
    if tip_rate is None:

        def slopes(requests):
            return [_tip_slope(path, tip, s) for path, s, _ in requests]

    else:

        def slopes(requests):
            if not requests:
                return []
            q = np.concatenate([path(s) for path, s, _ in requests])
            d1 = np.concatenate([path(s, 1) if d1 is None else d1 for path, s, d1 in requests])
            speed = np.empty(len(q))
            for k in range(0, len(q), SLOPE_CHUNK):  # chunks that stay in the cache
                speed[k : k + SLOPE_CHUNK] = np.linalg.norm(
                    tip_rate(q[k : k + SLOPE_CHUNK], d1[k : k + SLOPE_CHUNK])[1], axis=1
                )
            return np.split(speed, np.cumsum([len(s) for _, s, _ in requests])[:-1])

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
    """One path's state while :func:`time_paths` refines its grid."""

    def __init__(self, q, cap_mm_s, limits: AxisLimits, tip, knot_speeds):
        q = np.asarray(q, float)
        n = len(q)
        cap = np.asarray(cap_mm_s, float)
        # knots spaced by the least time each segment can take (the tip, by forward kinematics, at the fastest
        # planned speed; every axis at its limit): the spline then does not overshoot where the joints move much
        # over a short stretch of the tip's path (a wrist turning near a singularity), and sd stays near 1 or
        # below (toppra's LP solver loses the feasible set where sd^2 grows large)
        axis_speed, tip_speed = (limits.velocity, float(cap.max())) if knot_speeds is None else knot_speeds
        tip_step = np.linalg.norm(np.diff(tip(q), axis=0), axis=1) / tip_speed
        axis_step = (np.abs(np.diff(q, axis=0)) / np.asarray(axis_speed, float)).max(axis=1)
        step = np.maximum(np.maximum(tip_step, axis_step), MIN_STEP_S)
        self.s_way = np.concatenate([[0.0], np.cumsum(step)])
        self.path = toppra.SplineInterpolator(self.s_way, q)
        # grid: the waypoints, the middle of every segment, and points closing in on the two ends (from rest,
        # the first interval's constant sdd takes twice the time of the same stretch at speed: small intervals
        # there keep that to what the acceleration limits really cost)
        grid = np.empty(2 * n - 1)
        grid[0::2] = self.s_way
        grid[1::2] = 0.5 * (self.s_way[:-1] + self.s_way[1:])
        head = grid[1] * END_FRACTIONS
        tail = grid[-1] - (grid[-1] - grid[-2]) * END_FRACTIONS[::-1]
        self.grid = np.concatenate([grid[:1], head, grid[1:-1], tail, grid[-1:]])
        self.cap = cap
        self.n = n
        self.rounds = 0
        self.done = False


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
    strokes = [_Stroke(q, cap, limits, tip, knot_speeds) for q, cap in paths]
    frac = np.linspace(0.0, 1.0, check_steps + 1)
    while True:
        todo = [st for st in strokes if not st.done]
        if not todo:
            break
        d1 = [st.path(st.grid, 1) for st in todo]
        inputs = []
        for st, d, slope in zip(todo, d1, slopes([(st.path, st.grid, d) for st, d in zip(todo, d1)])):
            st.base_x, st.cap_interval = _bounds(d, slope, st.grid, st.s_way, st.cap, limits)
            inputs.append((st.grid, d, st.path(st.grid, 2), st.base_x))
        answers = []
        for group in _groups(inputs, [len(grid) for grid, _, _, _ in inputs], REACH_BATCH):
            answers += reach_paths(group, limits.acceleration)
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
            samples = [
                _dense_samples(st.path, st.grid[:-1], st.grid[1:], st.sd[:-1], st.sdd, st.dt, frac) for st in group
            ]
            for st, sm, slope in zip(
                group, samples, slopes([(st.path, sm.s, sm.d1) for st, sm in zip(group, samples)])
            ):
                st.ratios = _dense_ratios(sm, slope, st.sdd, len(frac), limits, st.cap_interval)
        for st in todo:
            st.worst = [float(r.max(initial=0.0)) for r in st.ratios]
            if max(st.worst) <= 1.0 + CHECK_SLACK or st.rounds >= max_rounds:
                st.done = True
                continue
            st.rounds += 1
            # a limit exceeded between two grid points: the interval split at its middle (a new grid point,
            # where toppra holds every limit too)
            grid = st.grid
            bad = np.maximum(np.maximum(st.ratios[0], st.ratios[1]), st.ratios[2])
            split = np.flatnonzero(bad > 1.0 + CHECK_SLACK)
            st.grid = np.insert(grid, split + 1, 0.5 * (grid[split] + grid[split + 1]))
    # the final check: the intervals near a limit again, at FINAL_FACTOR times the points
    fine = np.linspace(0.0, 1.0, FINAL_FACTOR * check_steps + 1)
    for st in strokes:
        st.near = np.flatnonzero(np.maximum(np.maximum(*st.ratios[:2]), st.ratios[2]) > NEAR_LIMIT)
    again = [st for st in strokes if len(st.near)]
    for group in _groups(again, [len(st.near) * len(fine) for st in again]):
        samples = []
        for st in group:
            k = st.near
            samples.append(_dense_samples(st.path, st.grid[k], st.grid[k + 1], st.sd[k], st.sdd[k], st.dt[k], fine))
        for st, sm, slope in zip(group, samples, slopes([(st.path, sm.s, sm.d1) for st, sm in zip(group, samples)])):
            ratios = _dense_ratios(sm, slope, st.sdd[st.near], len(fine), limits, st.cap_interval[st.near])
            st.worst = [max(w, float(r.max(initial=0.0))) for w, r in zip(st.worst, ratios)]
    waypoints = [np.flatnonzero(np.isin(st.grid, st.s_way)) for st in strokes]
    speeds = slopes([(st.path, st.grid[wp], None) for st, wp in zip(strokes, waypoints)])
    return [_finish(st, wp, speed) for st, wp, speed in zip(strokes, waypoints, speeds)]


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


def _finish(st: _Stroke, wp: np.ndarray, slope: np.ndarray) -> PathTiming:
    """The uniform stretch if a limit still does not hold after the checks, and the timing at the waypoints
    (grid points ``wp``, the tip's |p'(s)| there ``slope``)."""
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
        speed_mm_s=slope * sd[wp],
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


@dataclass(frozen=True)
class _Samples:
    """A dense check's samples: per grid interval ``len(frac)`` points evenly in time, flattened."""

    s: np.ndarray  # (k * m,) path positions
    v: np.ndarray  # (k * m,) sd there
    d1: np.ndarray  # (k * m, dof) q'(s)
    d2: np.ndarray  # (k * m, dof) q''(s)


def _dense_samples(path, s0, s1, sd0, sdd, dt, frac) -> _Samples:
    """The samples of a dense check over grid intervals from s0 to s1 (starting at speed sd0, accelerating at
    sdd for dt): ``frac`` points evenly in time across each."""
    tau = dt[:, None] * frac[None, :]
    s = s0[:, None] + sd0[:, None] * tau + 0.5 * sdd[:, None] * tau**2
    s = np.clip(s, s0[:, None], s1[:, None])
    v = sd0[:, None] + sdd[:, None] * tau
    flat = s.reshape(-1)
    return _Samples(flat, v.reshape(-1), path(flat, 1), path(flat, 2))


def _dense_ratios(samples: _Samples, slope, sdd, m: int, limits: AxisLimits, cap_interval):
    """Per grid interval, the largest ratio of joint speed, joint acceleration and tip speed to its limit over
    its ``m`` samples (``slope``: the tip's |p'(s)| at them), each local peak refined by the parabola through it
    and its two neighbours."""
    d1, v = samples.d1, samples.v[:, None]
    vel = d1 * v
    acc = d1 * np.repeat(sdd, m)[:, None] + samples.d2 * v**2
    shape = (len(sdd), m, -1)
    rv = _peaks((np.abs(vel) / limits.velocity).reshape(shape))
    ra = _peaks((np.abs(acc) / limits.acceleration).reshape(shape))
    tip_speed = slope * np.abs(samples.v)
    rc = _peaks((tip_speed.reshape(len(sdd), -1) / cap_interval[:, None])[:, :, None])
    return rv, ra, rc


def _peaks(r: np.ndarray) -> np.ndarray:
    """(k,) the largest value of each interval's samples ``r`` (k, m, a) (m samples evenly in time, a axes),
    each interior local maximum raised to the top of the parabola through it and its neighbours."""
    out = r.max(axis=(1, 2))
    if r.shape[1] >= 3:
        left, mid, right = r[:, :-2], r[:, 1:-1], r[:, 2:]
        bend = 2.0 * mid - left - right
        peak = (mid >= left) & (mid >= right) & (bend > 0)
        top = mid + np.where(peak, (right - left) ** 2 / (8.0 * np.where(peak, bend, 1.0)), 0.0)
        out = np.maximum(out, top.max(axis=(1, 2)))
    return out
