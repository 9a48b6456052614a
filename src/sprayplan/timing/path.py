"""A stroke's joint path time-optimal under the axes' limits and a gun-tip speed bound (toppra), checked densely.

The joint waypoints are joined by a cubic spline ``q(s)`` over a path parameter s from 0 to 1 whose knots are
spaced by the least time each segment can take (the gun tip at its planned speed, every axis at its speed
limit; a spline over the tip's arc length overshoots wildly where the wrist turns fast over a short stretch). toppra (reachability analysis, Pham & Pham 2018) finds the fastest ``s(t)`` from
rest to rest such that, at its grid points, every axis keeps ``|q'(s) sd| <= v_max`` and ``|q'(s) sdd +
q''(s) sd^2| <= a_max``, and the gun tip keeps ``|p'(s)| sd <= v_cap`` with ``p(s)`` the tip's position
(forward kinematics) and ``v_cap`` the planned tip speed of the segment (so a stroke never runs faster than its
paint speed). Between grid points ``sd^2`` is linear in s (constant ``sdd``), which toppra does not check.

So the result is checked at ``check_steps`` points per grid interval (evenly in time, both ends included)
against all three limits; where one is exceeded by a factor r > 1, the path-speed bound at the interval's two
grid points is lowered by r (by sqrt(r) for an acceleration) and toppra runs again (at most ``max_rounds`` times). If limits are still exceeded
after that, the whole stroke is slowed uniformly in time by the factor that makes them hold: stretching time
by k divides speeds by k and accelerations by k^2, so every check then holds (``PathTiming.stretch``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import toppra
from toppra.constraint import JointAccelerationConstraint, LinearConstraint

from sprayplan.timing.limits import AxisLimits

log = logging.getLogger(__name__)

#: Smallest knot step between two waypoints, s (waypoints where nothing moves).
MIN_STEP_S = 1e-6
#: The relative slack every dense check allows (floating point, not a tolerance of the limits).
CHECK_SLACK = 1e-9
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
        Tightening rounds toppra needed (0: its first answer held everywhere).
    stretch : float
        The uniform time stretch applied after the rounds (1: none).
    worst : dict
        The largest ratio to its limit found by the last dense check (``velocity``, ``acceleration``,
        ``tip_speed``), after the stretch: at most 1.
    """

    t_s: np.ndarray
    speed_mm_s: np.ndarray
    duration_s: float
    rounds: int
    stretch: float
    worst: dict


class _SpeedBound(LinearConstraint):
    """Upper bounds on ``x = sd^2`` at the grid points: the axes' speeds and the gun tip's, each scaled."""

    def __init__(self, bound_x: np.ndarray, dof: int):
        super().__init__()
        self.bound_x = bound_x
        self.dof = dof

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        xbound = np.column_stack([np.zeros(len(gridpoints)), self.bound_x])
        return None, None, None, None, None, None, xbound


def _tip_slope(path, tip: Callable, s: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """|p'(s)|: the gun tip's distance per unit of s (central differences of the forward kinematics)."""
    lo = np.maximum(s - h, path.path_interval[0])
    hi = np.minimum(s + h, path.path_interval[1])
    return np.linalg.norm(tip(path(hi)) - tip(path(lo)), axis=1) / (hi - lo)


def time_path(
    q: np.ndarray,
    tcp: np.ndarray,
    cap_mm_s: np.ndarray,
    limits: AxisLimits,
    tip: Callable[[np.ndarray], np.ndarray],
    *,
    check_steps: int = 4,
    max_rounds: int = 6,
) -> PathTiming:
    """Time a joint path from rest to rest, fastest within ``limits`` and the gun-tip speed bound.

    Parameters
    ----------
    q : (n, dof) float
        Joint vectors at the waypoints (n >= 2).
    tcp : (n, 3) float, mm
        The planned gun tip at the waypoints (its arc length is the path parameter).
    cap_mm_s : (n - 1,) float
        The planned gun-tip speed on each segment: the timed tip never runs faster.
    limits : AxisLimits
    tip : callable
        ``tip(q (k, dof)) -> (k, 3)`` mm, the gun tip by forward kinematics.
    check_steps : int
        Dense check points per grid interval.
    max_rounds : int
        Most tightening rounds before the uniform stretch.
    """
    q = np.asarray(q, float)
    n, dof = q.shape
    cap = np.asarray(cap_mm_s, float)
    # knots spaced by the least time each segment can take (the tip at its planned speed, every axis at its
    # limit), so that the spline does not overshoot where the joints move much over a short stretch of the
    # tip's path (a wrist turning near a singularity); the parameter runs from 0 to 1: toppra's LP solver
    # loses the feasible set where sd^2 grows large
    tip_step = np.linalg.norm(np.diff(np.asarray(tcp, float), axis=0), axis=1) / cap
    axis_step = (np.abs(np.diff(q, axis=0)) / limits.velocity).max(axis=1)
    step = np.maximum(np.maximum(tip_step, axis_step), MIN_STEP_S)
    s_way = np.concatenate([[0.0], np.cumsum(step)])
    s_way = s_way / s_way[-1]
    path = toppra.SplineInterpolator(s_way, q)
    # grid: the waypoints and the middle of every segment
    grid = np.empty(2 * n - 1)
    grid[0::2] = s_way
    grid[1::2] = 0.5 * (s_way[:-1] + s_way[1:])
    cap_grid = np.empty(len(grid))
    cap_grid[1::2] = cap
    cap_grid[0::2] = np.minimum(np.concatenate([cap[:1], cap]), np.concatenate([cap, cap[-1:]]))
    cap_interval = np.repeat(cap, 2)  # the segment each grid interval lies in
    d1 = np.abs(path(grid, 1))
    with np.errstate(divide="ignore"):
        joint_x = np.min((limits.velocity[None, :] / d1) ** 2, axis=1)
        tip_x = (cap_grid / _tip_slope(path, tip, grid)) ** 2
    base_x = np.minimum(joint_x, tip_x)
    scale_v = np.ones(len(grid))
    acceleration = JointAccelerationConstraint(limits.acceleration)
    ds = np.diff(grid)
    frac = np.linspace(0.0, 1.0, check_steps + 1)
    rounds = 0
    while True:
        constraints = [_SpeedBound(base_x * scale_v**2, dof), acceleration]
        algorithm = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, solver_wrapper="seidel")
        _, sd, _, _ = algorithm.compute_parameterization(0.0, 0.0, return_data=True)
        if sd is None or not np.isfinite(sd).all():
            raise RuntimeError(f"toppra found no parameterisation of a {n}-waypoint stroke from rest to rest")
        sd = np.maximum(np.asarray(sd, float), 0.0)
        dt = 2.0 * ds / np.maximum(sd[:-1] + sd[1:], 1e-300)
        sdd = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
        ratios = _dense_check(path, tip, grid, sd, sdd, dt, frac, limits, cap_interval)
        worst = [float(r.max(initial=0.0)) for r in ratios]
        if max(worst) <= 1.0 + CHECK_SLACK or rounds >= max_rounds:
            break
        rounds += 1
        # a speed over its bound by r: the path speed there down by r; an acceleration over by r: by sqrt(r)
        # (the q'' sd^2 part falls by r, and slower ends of the interval ask less of q' sdd)
        bad = np.maximum(np.maximum(ratios[0], ratios[2]), np.sqrt(ratios[1]))
        over = np.flatnonzero(bad > 1.0 + CHECK_SLACK)
        factor = 1.0 / (bad[over] * (1.0 + TIGHTEN_MARGIN))
        np.minimum.at(scale_v, over, scale_v[over] * factor)
        np.minimum.at(scale_v, over + 1, scale_v[over + 1] * factor)
    stretch = 1.0
    if max(worst) > 1.0 + CHECK_SLACK:
        stretch = max(worst[0], np.sqrt(worst[1]), worst[2]) * (1.0 + CHECK_SLACK)
        log.debug("a stroke's limits held only after stretching its time by %.6g", stretch)
        worst = [worst[0] / stretch, worst[1] / stretch**2, worst[2] / stretch]
    t_grid = np.concatenate([[0.0], np.cumsum(dt)]) * stretch
    sd = sd / stretch
    wp = slice(0, None, 2)
    speed = _tip_slope(path, tip, grid[wp]) * sd[wp]
    return PathTiming(
        t_s=t_grid[wp],
        speed_mm_s=speed,
        duration_s=float(t_grid[-1]),
        rounds=rounds,
        stretch=float(stretch),
        worst={"velocity": worst[0], "acceleration": worst[1], "tip_speed": worst[2]},
    )


def _dense_check(path, tip, grid, sd, sdd, dt, frac, limits: AxisLimits, cap_interval):
    """Per grid interval, the largest ratio of joint speed, joint acceleration and tip speed to its limit, over
    ``frac`` points evenly in time across the interval (s(t) with constant sdd)."""
    tau = dt[:, None] * frac[None, :]
    s = grid[:-1, None] + sd[:-1, None] * tau + 0.5 * sdd[:, None] * tau**2
    s = np.clip(s, grid[:-1, None], grid[1:, None])
    v = sd[:-1, None] + sdd[:, None] * tau
    flat = s.reshape(-1)
    d1 = path(flat, 1)
    d2 = path(flat, 2)
    vel = d1 * v.reshape(-1, 1)
    acc = d1 * np.repeat(sdd, len(frac))[:, None] + d2 * (v.reshape(-1, 1) ** 2)
    m = len(frac)
    rv = (np.abs(vel) / limits.velocity).max(axis=1).reshape(-1, m).max(axis=1)
    ra = (np.abs(acc) / limits.acceleration).max(axis=1).reshape(-1, m).max(axis=1)
    tip_speed = _tip_slope(path, tip, flat) * np.abs(v.reshape(-1))
    rc = (tip_speed.reshape(-1, m) / cap_interval[:, None]).max(axis=1)
    return rv, ra, rc
