"""A Newton first try for the SQP of seed 000 section 4.2 (eqs. 20-22), with exact derivatives.

The problem of :func:`sprayplan.robots.gantry.solve_sqp`: over the six joints and the gantry position
``x = (q, t)``, minimise eq. 20, ``f(x) = |q - q0|^2 + K_d |t - t0|^2``, subject to::

    h1(x) = |p(x) - p*| - P <= 0            (eq. 21: the spray target within P mm)
    h2(x) = arccos(z(x) . z*) - A <= 0      (eq. 22: the gun axis within A rad)

and the joint limits, with ``p`` the spray target's position and ``z`` the gun's axis in the world. Where
the reference ``x0`` is near the tolerance (the previous waypoint's joints, one waypoint step away), the
minimum lies on the tolerance boundary close to it, and Newton's method on the Karush-Kuhn-Tucker
conditions, started at ``x0``, finds it in a few steps: each step solves the quadratic model (the
Lagrangian's exact Hessian, the constraints linearised) with the active set chosen among the subsets of
{h1, h2, the nearer limit of each joint within ``LIMIT_MARGIN`` of one}, and a line search on the l1 merit
function keeps the steps from cycling. The derivatives come from the geometric Jacobian of the D-H chain:
for revolute joint i with axis ``a_i`` through ``o_i`` (frame i-1's z axis and origin),
``dp/dq_i = a_i x (p - o_i)``, ``dz/dq_i = a_i x z``, and for ``i <= j``
``d2p/dq_i dq_j = a_i x (a_j x (p - o_j))``, ``d2z/dq_i dq_j = a_i x (a_j x z)``.

The answer is given only as a strict local minimum: the KKT conditions hold to a tight tolerance, the
multipliers are not negative, the Lagrangian's Hessian is positive definite on the active constraints'
tangent space, and the joints are inside their limits. Anything else (no convergence in ``MAX_STEPS``, no
active set, a saddle) returns None, and the caller runs SLSQP as before.
"""

from __future__ import annotations

import functools
import math

import numpy as np

#: Rot(x, pi) of eq. 8 as a 3x3 rotation: the robot hangs upside down from the gantry.
_FLIP = np.array([1.0, -1.0, -1.0])
#: Newton steps before giving up.
MAX_STEPS = 25
#: The longest step (rad, mm) taken: the quadratic model is local.
MAX_STEP = (0.5, 100.0)
#: Converged when the step is below this (rad, mm) and the KKT residual below GRADIENT_TOL.
STEP_TOL = 1e-9
GRADIENT_TOL = 1e-6
#: How far the answer may lie outside eqs. 21 and 22 (mm, rad).
FEASIBLE_TOL = (1e-9, 1e-12)


def _cross(a, b):
    """Row-wise cross products of (..., 3) arrays (np.cross's checks cost more than the product here)."""
    return a[..., _YZX] * b[..., _ZXY] - a[..., _ZXY] * b[..., _YZX]


_YZX = np.array([1, 2, 0])
_ZXY = np.array([2, 0, 1])
_UPPER = np.triu(np.ones((6, 6), dtype=bool))


def chain_frames(d, a, alpha, theta_offset, q, offset2flange):
    """Joint axes and origins of a D-H chain, and the pose of a frame fixed on its flange.

    Parameters
    ----------
    d, a, alpha, theta_offset : (6,) float
        The standard D-H table (mm, rad).
    q : (6,) float, rad
    offset2flange : (4, 4) float, mm
        The frame on the flange (for the spray target: ``gun2flange @ target2gun``).

    Returns
    -------
    axes, origins : (6, 3) float
        Joint i's axis (frame i-1's z axis) and a point on it (frame i-1's origin), in the base frame.
    end : (4, 4) float
        ``offset2base``.
    """
    fixed, with_cos, with_sin = _link_parts(np.concatenate([d, a, alpha]).tobytes())
    theta = q + theta_offset
    links = fixed + np.cos(theta)[:, None, None] * with_cos + np.sin(theta)[:, None, None] * with_sin
    frames = np.empty((7, 4, 4))
    frames[0] = np.eye(4)
    for i in range(6):
        np.matmul(frames[i], links[i], out=frames[i + 1])
    return frames[:6, :3, 2], frames[:6, :3, 3], frames[6] @ offset2flange


@functools.lru_cache(maxsize=16)
def _link_parts(table: bytes):
    """The D-H link transforms of eq. 10 as ``fixed + cos(theta) with_cos + sin(theta) with_sin``, (6, 4, 4)
    each, for a table given as the bytes of ``d, a, alpha``."""
    d, a, alpha = np.frombuffer(table).reshape(3, -1)
    ca, sa = np.cos(alpha), np.sin(alpha)
    fixed, with_cos, with_sin = np.zeros((3, len(d), 4, 4))
    with_cos[:, 0, 0], with_sin[:, 0, 1], with_sin[:, 0, 2], with_cos[:, 0, 3] = 1.0, -ca, sa, a
    with_sin[:, 1, 0], with_cos[:, 1, 1], with_cos[:, 1, 2], with_sin[:, 1, 3] = 1.0, ca, -sa, a
    fixed[:, 2, 1], fixed[:, 2, 2], fixed[:, 2, 3], fixed[:, 3, 3] = sa, ca, d, 1.0
    return fixed, with_cos, with_sin


def second_derivative_along(axes, rows, v):
    """``sum_k v_k d2u_k / dq_i dq_j`` (6, 6) for a point or axis u whose first derivatives are ``rows``
    (``du/dq_j = a_j x w_j``): for i <= j the second derivative is ``a_i x du/dq_j``, and
    ``(a_i x r) . v = (v x a_i) . r``."""
    out = _cross(np.broadcast_to(v, axes.shape), axes) @ rows.T
    return np.where(_UPPER, out, out.T)


def pose_errors_first_order(robot, offset2flange, wanted_p, flip_wanted_z, x, jac_e):
    """Eqs. 21 and 22 at ``x = (q, t)`` and their exact gradients over the nine axes (the module's formulas).

    ``flip_wanted_z`` is the wanted gun axis in the arm's base frame (``Rot(x, pi)`` of the world's);
    ``jac_e`` (3, 9) holds the identity in its last three columns (the gantry moves the target as it moves)
    and gets the spray target's position Jacobian in its first six. Returns the joint axes (6, 3), the
    target's and the gun axis's derivatives in the base frame (6, 3 each), the position error (mm), its unit
    vector (0 at no error), its gradient (9,), the cosine and sine of the axis error, the cosine's gradient
    over the joints (6,) and the axis error's gradient (9,) (0 where the error is 0: the angle has no
    derivative there)."""
    axes, origins, end = chain_frames(robot.d, robot.a, robot.alpha, robot.theta_offset, x[:6], offset2flange)
    p_b, z_b = end[:3, 3], end[:3, 2]
    jac = _cross(axes, np.stack([p_b - origins, np.broadcast_to(z_b, (6, 3))]))
    jp, jz = jac[0], jac[1]
    # eq. 21: h1 = |e| - P with e the spray target's error in the world, t + Rot(x, pi) p_b - p*
    error = x[6:] + _FLIP * p_b - wanted_p
    distance = math.sqrt(error @ error)
    jac_e[:, :6] = (jp * _FLIP).T
    unit = error / distance if distance > TINY else np.zeros(3)
    grad_1 = jac_e.T @ unit
    # eq. 22: h2 = angle - A, the angle between the gun axis and the wanted one, arccos(c)
    cos_angle = min(max(float(flip_wanted_z @ z_b), -1.0), 1.0)
    sin_angle = math.sqrt(1.0 - cos_angle * cos_angle)
    grad_c = jz @ flip_wanted_z
    grad_2 = np.zeros(9)
    if sin_angle > TINY:
        grad_2[:6] = -grad_c / sin_angle
    return axes, jp, jz, distance, unit, grad_1, cos_angle, sin_angle, grad_c, grad_2


def newton_sqp(robot, offset2flange, wanted_p, wanted_z, reference, *, k_d, position_tol_mm, axis_tol_rad):
    """The minimum of eq. 20 under eqs. 21-22 and the joint limits by Newton's method on the KKT
    conditions, started at the reference; or None.

    Parameters
    ----------
    robot : RobotModel
        The arm hanging from the gantry (``Rot(x, pi)`` under the carriage).
    offset2flange : (4, 4) float, mm
        The spray target on the flange, ``gun2flange @ target2gun``.
    wanted_p, wanted_z : (3,) float
        The wanted spray target's position (mm) and gun axis (unit) in the world.
    reference : (9,) float
        ``x0`` of eq. 20 (previous joints, rad; the station's gantry position, mm), the first iterate.

    Returns
    -------
    ((9,) float, int) or None
        The minimum and the number of Newton steps; None when the method does not reach a strict local
        minimum inside the joint limits.
    """
    weights = np.array([1.0] * 6 + [k_d] * 3)
    reference = np.asarray(reference, dtype=float)
    x = reference.copy()
    flip_wanted_z = _FLIP * wanted_z
    hess_f = np.diag(2.0 * weights)
    lower, upper = robot.lower, robot.upper
    mu = np.zeros(2)
    penalty = np.zeros(2)
    active: tuple = ()
    jac_e = np.zeros((3, 9))
    jac_e[:, 6:] = np.eye(3)
    steps = 0
    for _ in range(MAX_STEPS):
        steps += 1
        first = pose_errors_first_order(robot, offset2flange, wanted_p, flip_wanted_z, x, jac_e)
        axes, jp, jz, distance, unit, grad_1, cos_angle, sin_angle, grad_c, grad_2 = first
        # the Lagrangian's Hessian: eq. 20's, and the constraints' weighted by their multipliers
        hess = hess_f.copy()
        if mu[0] > 0.0 and distance > TINY:
            across = (jac_e - np.outer(unit, unit @ jac_e)) / distance
            hess += mu[0] * (jac_e.T @ across)
            hess[:6, :6] += mu[0] * second_derivative_along(axes, jp, _FLIP * unit)
        if mu[1] > 0.0 and sin_angle > TINY:
            curvature = second_derivative_along(axes, jz, flip_wanted_z)
            hess[:6, :6] -= mu[1] * (curvature / sin_angle + (cos_angle / sin_angle**3) * np.outer(grad_c, grad_c))
        # the constraints, linearised: the two of the pose, and the nearer limit of joints near one
        near = np.flatnonzero(np.minimum(x[:6] - lower, upper - x[:6]) < LIMIT_MARGIN)
        rows = np.zeros((2 + len(near), 9))
        rows[0], rows[1] = grad_1, grad_2
        values = np.empty(len(rows))
        values[0] = distance - position_tol_mm
        values[1] = math.acos(cos_angle) - axis_tol_rad
        for m, j in enumerate(near):
            if x[j] - lower[j] < upper[j] - x[j]:
                rows[2 + m, j], values[2 + m] = -1.0, lower[j] - x[j]
            else:
                rows[2 + m, j], values[2 + m] = 1.0, x[j] - upper[j]
        grad_f = 2.0 * weights * (x - reference)
        found = _quadratic_step(hess, grad_f, rows, values, active)
        if found is None:
            return None
        step, multipliers, active = found
        converged = (
            np.abs(step).max() < STEP_TOL
            and values[0] <= FEASIBLE_TOL[0]
            and values[1] <= FEASIBLE_TOL[1]
            and np.abs(grad_f + multipliers @ rows).max() < GRADIENT_TOL
        )
        mu = multipliers[:2]
        if converged:
            break
        longest = max(np.abs(step[:6]).max() / MAX_STEP[0], np.abs(step[6:]).max() / MAX_STEP[1])
        if longest > 1.0:
            step = step / longest  # the quadratic model is local
        # a line search on the l1 merit function f + sum rho_i max(h_i, 0), rho_i above the multipliers
        penalty = np.maximum(penalty, 2.0 * mu + 1e-6)
        merit = _cost(x, reference, weights) + penalty @ np.maximum(values[:2], 0.0)
        alpha = 1.0
        for _ in range(LINE_SEARCH_HALVINGS):
            trial = x + alpha * step
            if _merit(
                robot,
                offset2flange,
                wanted_p,
                flip_wanted_z,
                trial,
                reference,
                weights,
                penalty,
                position_tol_mm,
                axis_tol_rad,
            ) <= merit + 1e-12 * abs(merit):
                break
            alpha *= 0.5
        else:
            return None
        x = trial
        # a joint near a limit carries it as an equality once it is active: keep the active set's meaning
        active = tuple(i for i in active if i < 2)
    else:
        return None
    x[:6] = np.clip(x[:6], lower, upper)
    if not _positive_on_tangent(hess, rows[multipliers > 0.0]):
        return None
    return x, steps


#: Halvings of a step before the line search gives up.
LINE_SEARCH_HALVINGS = 12


def _cost(x, reference, weights) -> float:
    """Eq. 20."""
    d = x - reference
    return float(d @ (weights * d))


def _merit(
    robot, offset2flange, wanted_p, flip_wanted_z, x, reference, weights, penalty, position_tol_mm, axis_tol_rad
):
    """The l1 merit function at x: eq. 20 plus the penalised violations of eqs. 21 and 22."""
    _, _, end = chain_frames(robot.d, robot.a, robot.alpha, robot.theta_offset, x[:6], offset2flange)
    error = x[6:] + _FLIP * end[:3, 3] - wanted_p
    position = math.sqrt(error @ error) - position_tol_mm
    axis = math.acos(min(max(float(flip_wanted_z @ end[:3, 2]), -1.0), 1.0)) - axis_tol_rad
    return _cost(x, reference, weights) + penalty[0] * max(position, 0.0) + penalty[1] * max(axis, 0.0)


#: Below this (mm, rad) the error's direction is not defined: the constraint is far from active.
TINY = 1e-9
#: Joints nearer a limit than this (rad) carry it as a constraint of the Newton step.
LIMIT_MARGIN = 0.5
#: At most this many constraints in a Newton step (2 of the pose, the rest joint limits): 2^n active sets.
MAX_CONSTRAINTS = 6


def _quadratic_step(hess, grad_f, rows, values, first=()):
    """The minimum of ``grad_f . s + s H s / 2`` subject to ``values + rows @ s <= 0``, its multipliers and
    its active set.

    The active set is chosen among the subsets of the constraints, ``first`` (the previous step's) and then
    the smallest first: the first whose multipliers are not negative and whose other constraints hold. With
    ``H^-1`` applied once, each subset costs a solve of its own size (the Schur complement). None when no
    subset does, or ``H`` is singular.
    """
    m = len(rows)
    if m > MAX_CONSTRAINTS:
        return None
    try:
        solved = np.linalg.solve(hess, np.column_stack([grad_f, rows.T]))
    except np.linalg.LinAlgError:
        return None
    free, across = solved[:, 0], solved[:, 1:]  # H^-1 g, H^-1 A^T
    schur = rows @ across  # A H^-1 A^T
    offset = values - rows @ free  # the active constraints' multipliers solve schur_SS mu_S = offset_S
    tol = np.full(m, 1e-12)
    tol[:2] = FEASIBLE_TOL
    for subset in _subsets(m, first):
        mu = np.zeros(m)
        if subset:
            index = list(subset)
            solved = _small_solve(schur, offset, index)
            if solved is None or min(solved) < 0.0:
                continue
            mu[index] = solved
        step = -free - across @ mu
        violated = values + rows @ step > tol
        violated[list(subset)] = False  # the active ones hold as equalities, up to rounding
        if violated.any():
            continue
        return step, mu, subset
    return None


def _small_solve(matrix, rhs, index):
    """``matrix[index, index]^-1 rhs[index]`` (a list), by hand for one or two unknowns; None if singular."""
    if len(index) == 1:
        i = index[0]
        return None if matrix[i, i] == 0.0 else [rhs[i] / matrix[i, i]]
    if len(index) == 2:
        i, j = index
        a, b, c, d = matrix[i, i], matrix[i, j], matrix[j, i], matrix[j, j]
        det = a * d - b * c
        if abs(det) <= 1e-14 * (abs(a * d) + abs(b * c)):
            return None
        return [(d * rhs[i] - b * rhs[j]) / det, (a * rhs[j] - c * rhs[i]) / det]
    try:
        return list(np.linalg.solve(matrix[np.ix_(index, index)], rhs[index]))
    except np.linalg.LinAlgError:
        return None


def _subsets(m: int, first=()):
    """``first``, then all subsets of range(m), smallest first."""
    from itertools import combinations

    if all(i < m for i in first):
        yield tuple(first)
    for size in range(m + 1):
        yield from combinations(range(m), size)


def _positive_on_tangent(hess, active_grads) -> bool:
    """The Hessian is positive definite on the null space of the active constraints' gradients."""
    if len(active_grads):
        _, s, vt = np.linalg.svd(active_grads)
        if s.min() <= 1e-12 * max(s.max(), 1.0):
            return False
        basis = vt[len(active_grads) :].T
        hess = basis.T @ hess @ basis
    return bool(np.linalg.eigvalsh(hess).min() > 0.0)
