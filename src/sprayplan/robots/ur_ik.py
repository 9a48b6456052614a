"""Closed-form inverse kinematics of UR-type arms (seed 000, section 4.1), all eight branches, vectorised.

A UR-type arm is a standard D-H chain with ``alpha = (pi/2, 0, 0, pi/2, -pi/2, 0)``, ``a1 = a4 = a5 = a6 = 0``
and ``d2 = d3 = 0``: joints 2, 3 and 4 are parallel. ``d1, a2, a3, d4, d5, d6`` are free, so the UR5, the UR5e
and seed 000's table 1 (``ur5-seed``, whose ``a2, a3`` have the opposite sign) are all solved here.

The solution, written for this module (frames as in :mod:`sprayplan.robots.model`; ``n, o, a`` are the x, y, z
axes of the flange and ``p`` its origin, all in the base frame; ``D-H theta = q + theta_offset``):

1. The wrist centre (origin of frame 5) is ``p5 = p - d6 a``. Its component along ``z1 = (sin q1, -cos q1, 0)``
   is ``d4``, so with ``rho, psi`` its polar coordinates in the base x-y plane
   ``q1 = psi + pi/2 +- atan2(sqrt(rho^2 - d4^2), d4)`` (the two *shoulder* branches; none when ``rho < |d4|``).
2. ``z1`` seen from the flange is ``(cos q6 sin q5, -sin q6 sin q5, cos q5)``, so with ``zx = n.z1``,
   ``zy = o.z1``, ``c5 = a.z1``: ``q5 = +-atan2(hypot(zx, zy), c5)`` (the two *wrist* branches) and
   ``q6 = atan2(-zy / sin q5, zx / sin q5)``. When ``|sin q5| <= singular_tol`` the wrist is singular: only
   ``q4 +- q6`` is determined, ``q6`` is taken from ``q6_desired`` and the solution is flagged. (``q6`` also
   places the origin of frame 4 on a circle of radius ``d5``; where the arm cannot reach that point with
   ``q6_desired``, the nearest ``q6`` with which it can is taken instead, see :func:`_singular_theta6`.)
3. Frame 4: ``x4 = cos q5 (cos q6 n - sin q6 o) - sin q5 a``, origin ``p4 = p5 + d5 (sin q6 n + cos q6 o)``. In
   the arm plane of frame 1 (``x1 = (cos q1, sin q1, 0)``, ``y1 = base z``) the origin of frame 4 is
   ``X + iY = e^{i q2} (a2 + a3 e^{i q3})``, giving ``cos q3`` and ``q3 = +-atan2(sqrt(1 - cos^2 q3), cos q3)``
   (the two *elbow* branches; none when ``|cos q3| > 1``), ``q2 = atan2(Y, X) - atan2(a3 sin q3, a2 + a3 cos q3)``
   and ``q4 = atan2(x4.y1, x4.x1) - q2 - q3``.

Branch index ``b = 4 * shoulder + 2 * wrist + elbow``, each bit a sign choice (labels in :data:`BRANCH_LABELS`,
e.g. index 0 ``"shoulder_left/wrist_up/elbow_up"``, 5 ``"shoulder_right/wrist_up/elbow_down"``):

- shoulder bit 0 ``shoulder_left``: ``+`` in step 1, the wrist centre on the ``-x1`` side of the shoulder (the
  side where ``q = 0`` stretches a UR5, whose ``a2, a3`` are negative); bit 1 ``shoulder_right``: ``-``, the
  ``+x1`` side.
- wrist bit 0 ``wrist_up``: ``q5`` in ``[0, pi]``; bit 1 ``wrist_down``: ``q5`` in ``[-pi, 0]``.
- elbow bit 0 ``elbow_up``: ``q3`` in ``[0, pi]``; bit 1 ``elbow_down``: ``q3`` in ``[-pi, 0]``. With
  ``a2 a3 > 0`` (UR5, UR5e, ur5-seed) and the wrist centre on the ``-x1`` side, ``q3 > 0`` puts the elbow
  above the line from the shoulder to the wrist.

The bits are sign choices, so the same physical arm configuration has the same branch index on ``ur5`` and on
``ur5-seed`` (whose joint vector differs by ``(0, pi, 0, -pi, 0, 0)``).

Angles are returned in ``(-pi, pi]``. UR joints reach ``+-2 pi``: nothing here wraps a joint silently into
``+-pi`` for the caller; :func:`nearest_equivalent` picks the turn (``q``, ``q + 2 pi`` or ``q - 2 pi``) within the
limits that is nearest to a seed, and :func:`ik_path` uses it along a trajectory. Failure is data: unreachable
branches are ``valid = False`` with ``q = 0``, never NaN and never an exception.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from sprayplan.checks import check_poses
from sprayplan.errors import ConfigError, InputError
from sprayplan.robots.model import RobotModel

log = logging.getLogger(__name__)

TAU = 2.0 * math.pi
UR_ALPHA = np.array([math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0])
BRANCH_LABELS: tuple[str, ...] = tuple(
    f"{s}/{w}/{e}"
    for s in ("shoulder_left", "shoulder_right")
    for w in ("wrist_up", "wrist_down")
    for e in ("elbow_up", "elbow_down")
)
"""Label of each branch index ``4 * shoulder + 2 * wrist + elbow``."""

_CHUNK = 8192  # poses solved at once: the temporaries (about 40 arrays of up to 8 x 8192 floats) stay in cache
_ACOS_TOL = 1e-10  # how far beyond +-1 a cosine may be (rounding) before a branch is unreachable
_LIMIT_TOL = 1e-9  # rad of slack on the joint limits


@dataclass(frozen=True)
class URSolutions:
    """All eight closed-form solutions of a UR-type arm for n flange poses.

    Attributes
    ----------
    q : (n, 8, 6) float, rad
        Joint vectors in ``(-pi, pi]``, branch ``b`` in ``q[:, b]``; 0 where not valid (never NaN).
    valid : (n, 8) bool
        The branch reaches the pose and each of its joints has a turn within the model's limits.
    wrist_singular : (n, 8) bool
        ``|sin q5| <= singular_tol``: ``q6`` was not determined by the pose and is ``q6_desired`` (or, where the
        arm cannot reach the pose with that, the nearest ``q6`` with which it can).
    branch_labels : tuple of 8 str
        ``"shoulder_*/wrist_*/elbow_*"`` for each branch index, see :data:`BRANCH_LABELS`.
    """

    q: np.ndarray
    valid: np.ndarray
    wrist_singular: np.ndarray
    branch_labels: tuple[str, ...] = BRANCH_LABELS

    def __len__(self) -> int:
        return len(self.q)


@dataclass(frozen=True)
class IKPath:
    """One joint vector per waypoint of a trajectory, chosen for continuity.

    Attributes
    ----------
    q : (n, 6) float, rad
        The chosen joint vectors, each joint the turn nearest the previous waypoint (may leave ``(-pi, pi]``
        within the limits); 0 where not reachable.
    reachable : (n,) bool
    branch : (n,) int
        Branch index (see :data:`BRANCH_LABELS`), -1 where not reachable.
    branch_change : (n,) bool
        The branch differs from that of the previous reachable waypoint.
    jump : (n,) bool
        Some joint moves more than ``jump_rad`` from the previous reachable waypoint.
    max_step_rad : (n,) float, rad
        The largest joint move from the previous reachable waypoint (0 for the first reachable one and for
        unreachable ones).
    """

    q: np.ndarray
    reachable: np.ndarray
    branch: np.ndarray
    branch_change: np.ndarray
    jump: np.ndarray
    max_step_rad: np.ndarray

    def __len__(self) -> int:
        return len(self.q)


def check_ur_model(model: RobotModel) -> None:
    """Raise :class:`ConfigError` unless ``model`` has the UR structure this module solves.

    The structure: 6 joints, ``alpha = (pi/2, 0, 0, pi/2, -pi/2, 0)``, ``a1 = a4 = a5 = a6 = 0``,
    ``d2 = d3 = 0``, ``a2 != 0`` and ``a3 != 0``.
    """
    if model.dof != 6:
        raise ConfigError(f"robot {model.name}: UR inverse kinematics needs 6 joints, the model has {model.dof}")
    problems = []
    if not np.allclose(model.alpha, UR_ALPHA, rtol=0.0, atol=1e-9):
        problems.append("alpha must be (90, 0, 0, 90, -90, 0) degrees")
    if np.any(np.abs(model.a[[0, 3, 4, 5]]) > 1e-9):
        problems.append("a1, a4, a5, a6 must be 0")
    if np.any(np.abs(model.d[[1, 2]]) > 1e-9):
        problems.append("d2, d3 must be 0")
    if abs(model.a[1]) < 1e-9 or abs(model.a[2]) < 1e-9:
        problems.append("a2 and a3 must not be 0")
    if problems:
        raise ConfigError(f"robot {model.name} is not a UR-type arm: {'; '.join(problems)}")


def check_flange_poses(flange2base) -> np.ndarray:
    """Flange poses as float ``(n, 4, 4)``: a wrong shape or a finite row that is not a rigid motion raises
    (``InputError`` naming the row); rows holding NaN or inf are kept (the solvers' unreachable rows)."""
    poses = np.asarray(flange2base, dtype=float)
    if poses.shape == (4, 4):
        poses = poses[None]
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise InputError(f"flange2base must be (4, 4) or (n, 4, 4), got shape {poses.shape}")
    # a mirror or a sheared rotation is not a pose: an error naming the row, not a "reachable" answer
    check_poses(poses, "flange2base", allow_nan=True)
    return poses


def _wrap(x: np.ndarray) -> np.ndarray:
    """Angles into ``(-pi, pi]``: ``x - 2 pi k`` with ``k = ceil((x - pi) / (2 pi))`` (cheaper than ``np.mod``)."""
    return x - TAU * np.ceil((x - math.pi) * (1.0 / TAU))


def _turn_range(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest whole-turn counts ``k`` with ``q + 2 pi k`` within the limits (float arrays)."""
    k_lo = np.ceil((lower - _LIMIT_TOL - q) / TAU)
    k_hi = np.floor((upper + _LIMIT_TOL - q) / TAU)
    return k_lo, k_hi


def nearest_equivalent(q, seed, lower, upper) -> np.ndarray:
    """Each joint's turn ``q + 2 pi k`` within the limits that is nearest to the seed.

    With the UR range of ``+-2 pi`` and ``q`` in ``(-pi, pi]`` the choice is among ``q``, ``q + 2 pi`` and
    ``q - 2 pi``; any whole number of turns is considered, so wider ranges work too. Nothing is wrapped into
    ``+-pi``.

    Parameters
    ----------
    q : (..., dof) float, rad
    seed : (..., dof) float, rad
        Broadcast against ``q``.
    lower, upper : (dof,) float, rad
        Joint limits.

    Returns
    -------
    (...) + (dof,) float, rad
        The chosen turns, of the broadcast shape. A joint for which no turn fits the limits keeps its value
        ``q`` (the caller's validity check reports it; :func:`ur_ik` marks such branches not valid).
    """
    q = np.asarray(q, dtype=float)
    seed = np.asarray(seed, dtype=float)
    q, seed = np.broadcast_arrays(q, seed)
    k_lo, k_hi = _turn_range(q, np.asarray(lower, dtype=float), np.asarray(upper, dtype=float))
    return nearest_in_turns(q, seed, k_lo, k_hi)


def nearest_in_turns(q, seed, k_lo, k_hi) -> np.ndarray:
    """:func:`nearest_equivalent` with the turn counts' range (``_turn_range`` of ``q`` and the limits) given:
    a path's ranges are computed once for all its waypoints, and each waypoint's seed (the previous joints)
    costs three small operations."""
    k = np.clip(np.rint((seed - q) / TAU), k_lo, k_hi)
    k = np.where(k_lo <= k_hi, k, 0.0)
    return q + TAU * k


def ur_ik(model: RobotModel, flange2base, *, q6_desired=0.0, singular_tol: float = 1e-9) -> URSolutions:
    """All eight closed-form inverse kinematics solutions of a UR-type arm, for many flange poses at once.

    Parameters
    ----------
    model : RobotModel
        A UR-type D-H chain (see :func:`check_ur_model`), any ``d1, a2, a3, d4, d5, d6`` and theta offsets.
    flange2base : (4, 4) or (n, 4, 4) float, mm
        Flange poses in the base frame; the rotation part must be a rotation.
    q6_desired : float or (n,) float, rad
        ``q6`` for a singular wrist (where the pose does not determine it); where the arm cannot reach the
        pose with it, the nearest ``q6`` that can is used.
    singular_tol : float
        The wrist is singular where ``|sin q5|`` is at most this.

    Returns
    -------
    URSolutions
        ``q (n, 8, 6)``, ``valid (n, 8)``, ``wrist_singular (n, 8)``. Poses out of reach, non-finite poses and
        branches outside the joint limits are ``valid = False`` with ``q = 0``.

    Raises
    ------
    ConfigError
        The model is not of the UR structure.
    InputError
        ``flange2base`` or ``q6_desired`` has the wrong shape.

    Notes
    -----
    Cost: O(n), about 25 transcendental evaluations per pose; poses are solved in chunks of 8192, so the
    temporaries stay small and in cache (the result itself takes 400 bytes per pose).
    """
    check_ur_model(model)
    poses = check_flange_poses(flange2base)
    n = len(poses)
    q6d = np.asarray(q6_desired, dtype=float)
    if q6d.ndim > 1 or (q6d.ndim == 1 and len(q6d) != n):
        raise InputError(f"q6_desired must be a number or have one value per pose ({n}), got shape {q6d.shape}")
    q6d = np.broadcast_to(q6d, (n,))
    q = np.empty((n, 8, 6))
    valid = np.empty((n, 8), dtype=bool)
    singular = np.empty((n, 8), dtype=bool)
    for start in range(0, n, _CHUNK):
        part = slice(start, min(start + _CHUNK, n))
        _solve_chunk(model, poses[part], q6d[part], singular_tol, q[part], valid[part], singular[part])
    if n:
        log.debug("ur_ik: %d poses, %d of %d branches valid", n, int(valid.sum()), 8 * n)
    return URSolutions(q=q, valid=valid, wrist_singular=singular)


def _solve_chunk(model, poses, q6d, singular_tol, q_out, valid_out, singular_out) -> None:
    """Solve one chunk of poses into the given output views, (m, 8, 6), (m, 8), (m, 8)."""
    m = len(poses)
    d1, d4, d5, d6 = model.d[0], model.d[3], model.d[4], model.d[5]
    a2, a3 = model.a[1], model.a[2]
    off = model.theta_offset
    finite = (np.abs(poses) < 1e100).all(axis=(1, 2))  # False for NaN, inf and sizes that would overflow
    if not finite.all():
        poses = np.where(finite[:, None, None], poses, np.eye(4))
    # flange axes and origin, (m, 3) each; the (m, 1) columns broadcast against the 2 shoulder branches
    nx, ny, nz = (poses[:, i, 0:1] for i in range(3))
    ox, oy, oz = (poses[:, i, 1:2] for i in range(3))
    ax, ay, az = (poses[:, i, 2:3] for i in range(3))
    wx = poses[:, 0, 3:4] - d6 * ax
    wy = poses[:, 1, 3:4] - d6 * ay
    wz = poses[:, 2, 3:4] - d6 * az

    with np.errstate(invalid="ignore", divide="ignore"):
        # step 1: shoulder, (m, 2)
        rho2 = wx * wx + wy * wy
        disc = rho2 - d4 * d4
        shoulder_ok = (d4 * d4 <= rho2 * (1.0 + _ACOS_TOL) ** 2)[:, 0] & finite
        phi = np.arctan2(np.sqrt(np.maximum(disc, 0.0)), d4)
        t1 = np.arctan2(wy, wx) + math.pi / 2 + np.concatenate([phi, -phi], axis=1)
        c1, s1 = np.cos(t1), np.sin(t1)

        # step 2: wrist, (m, 2) per shoulder, then (m, 2, 2) with the wrist sign last
        zx = nx * s1 - ny * c1
        zy = ox * s1 - oy * c1
        c5 = ax * s1 - ay * c1
        s5 = np.hypot(zx, zy)  # |sin q5|
        t5 = np.arctan2(s5, c5)
        sing = s5 <= singular_tol  # (m, 2)
        inv = 1.0 / np.maximum(s5, 1e-300)
        c6u = zx * inv  # wrist_up: sin q5 = +s5
        s6u = -zy * inv
        t6u = np.arctan2(-zy, zx)
        n_x1 = nx * c1 + ny * s1  # flange axes and wrist centre in the arm plane (x1, y1 = base z)
        o_x1 = ox * c1 + oy * s1
        a_x1 = ax * c1 + ay * s1
        w_x1 = wx * c1 + wy * s1
        if sing.any():
            rows, cols = np.nonzero(sing)
            t6s = _singular_theta6(
                q6d[rows] + off[5],
                w_x1[rows, cols],
                wz[rows, 0] - d1,
                n_x1[rows, cols],
                nz[rows, 0],
                o_x1[rows, cols],
                oz[rows, 0],
                d5,
                abs(abs(a2) - abs(a3)),
                abs(a2) + abs(a3),
            )
            t6u[rows, cols] = t6s
            c6u[rows, cols] = np.cos(t6s)
            s6u[rows, cols] = np.sin(t6s)
        sign = np.array([1.0, -1.0])
        # wrist_down (sin q5 = -s5) turns q6 by pi, except where singular (the same q6 for both)
        flip = np.where(sing[..., None], 1.0, sign)  # (m, 2, 2)
        c6 = c6u[..., None] * flip
        s6 = s6u[..., None] * flip
        t6 = t6u[..., None] + np.where(flip < 0, math.pi, 0.0)
        t5 = t5[..., None] * sign  # (m, 2, 2)
        s5s = s5[..., None] * sign  # signed sin q5
        c5b = c5[..., None]
        n_x1 = n_x1[..., None]
        o_x1 = o_x1[..., None]
        a_x1 = a_x1[..., None]

        # step 3: frame 4 and the planar arm, (m, 2, 2)
        x4_x1 = c5b * (c6 * n_x1 - s6 * o_x1) - s5s * a_x1
        x4_z = c5b * (c6 * nz[..., None] - s6 * oz[..., None]) - s5s * az[..., None]
        t234 = np.arctan2(x4_z, x4_x1)
        big_x = w_x1[..., None] + d5 * (s6 * n_x1 + c6 * o_x1)
        big_y = (wz - d1)[..., None] + d5 * (s6 * nz[..., None] + c6 * oz[..., None])
        c3 = (big_x * big_x + big_y * big_y - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
        elbow_ok = np.abs(c3) <= 1.0 + _ACOS_TOL
        c3 = np.clip(c3, -1.0, 1.0)
        s3 = np.sqrt((1.0 - c3) * (1.0 + c3))
        t3 = np.arctan2(s3, c3)
        gamma = np.arctan2(big_y, big_x)
        beta = np.arctan2(a3 * s3, a2 + a3 * c3)

    # each joint wrapped into (-pi, pi] at its smallest shape, then assembled as (m, 2, 2, 2, 6):
    # shoulder, wrist, elbow
    t3 = t3[..., None] * sign  # (m, 2, 2, 2)
    t2 = gamma[..., None] - beta[..., None] * sign  # elbow_down: sin q3 < 0 turns beta's sign
    out = q_out.reshape(m, 2, 2, 2, 6)
    out[..., 0] = _wrap(t1 - off[0])[:, :, None, None]
    out[..., 1] = _wrap(t2 - off[1])
    out[..., 2] = _wrap(t3 - off[2])
    out[..., 3] = _wrap(t234[..., None] - t2 - t3 - off[3])
    out[..., 4] = _wrap(t5 - off[4])[..., None]
    out[..., 5] = _wrap(t6 - off[5])[..., None]

    ok = shoulder_ok[:, None, None, None] & elbow_ok[..., None]
    ok = np.broadcast_to(ok, (m, 2, 2, 2)).reshape(m, 8)
    if np.any(model.upper - model.lower < TAU - 2 * _LIMIT_TOL):  # some turn may not fit: check the limits
        k_lo, k_hi = _turn_range(q_out, model.lower, model.upper)
        ok = ok & (k_lo <= k_hi).all(axis=-1)
    valid_out[:] = ok
    singular_out[:] = np.broadcast_to(sing[:, :, None, None], (m, 2, 2, 2)).reshape(m, 8) & ok
    q_out[~ok] = 0.0


def _singular_theta6(desired, x5, y5, n_x, n_y, o_x, o_y, d5, r_min, r_max) -> np.ndarray:
    """D-H theta6 for a singular wrist: ``desired`` where the arm reaches the pose with it, else the nearest that does.

    At ``sin q5 = 0`` the flange x and y axes lie in the arm plane and the origin of frame 4 is
    ``W(theta6) = W5 + d5 (sin theta6 n + cos theta6 o)`` (arm-plane coordinates), a circle of radius ``d5``
    about the wrist centre ``W5``: ``|W|^2 = |W5|^2 + d5^2 + 2 d5 R cos(theta6 - mu)`` with
    ``R cos mu = W5.o``, ``R sin mu = W5.n``. The planar arm reaches ``W`` for ``r_min <= |W| <= r_max``, an
    interval of ``cos(theta6 - mu)``, i.e. two arcs ``|theta6 - mu| in [lo, hi]``; the desired angle is clamped
    into them. Where no angle reaches, ``desired`` is returned (the elbow check then fails).

    Parameters
    ----------
    desired : (k,) float, rad
    x5, y5, n_x, n_y, o_x, o_y : (k,) float
        Wrist centre (mm, relative to the shoulder) and flange x, y axes in arm-plane coordinates.
    d5, r_min, r_max : float, mm

    Returns
    -------
    (k,) float, rad
    """
    wn = x5 * n_x + y5 * n_y
    wo = x5 * o_x + y5 * o_y
    k = 2.0 * d5 * np.hypot(wn, wo)
    base = x5 * x5 + y5 * y5 + d5 * d5
    flat = k <= 1e-9 * base  # |W| does not depend on theta6
    k = np.where(flat, 1.0, k)
    lo = np.arccos(np.clip((r_max * r_max - base) / k, -1.0, 1.0))
    hi = np.arccos(np.clip((r_min * r_min - base) / k, -1.0, 1.0))
    empty = ((r_min * r_min - base) / k > 1.0) | ((r_max * r_max - base) / k < -1.0)
    mu = np.arctan2(wn, wo)
    delta = _wrap(desired - mu)
    inside = (np.abs(delta) >= lo) & (np.abs(delta) <= hi)
    clamped = mu + np.where(delta < 0, -1.0, 1.0) * np.clip(np.abs(delta), lo, hi)
    return np.where(flat | empty | inside, desired, clamped)


def _check_vector(value, name: str, default: float) -> np.ndarray:
    if value is None:
        return np.full(6, default)
    try:
        out = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be 6 finite numbers (rad), got {value!r}") from None
    if out.shape != (6,) or not np.isfinite(out).all():
        shown = ", ".join(f"{v:g}" for v in out[:12]) + (", ..." if out.size > 12 else "")
        raise ConfigError(f"{name} must be 6 finite numbers (rad), got {out.size} value(s): {shown}")
    return out


def ik_path(
    model: RobotModel,
    flange2base,
    *,
    seed_q=None,
    weights=None,
    jump_rad: float = 0.5,
    q6_desired=None,
) -> IKPath:
    """Joint vectors along a trajectory: at each waypoint the branch nearest the previous joint vector.

    All poses are solved at once with :func:`ur_ik`; then, in order, each waypoint takes the valid branch whose
    :func:`nearest_equivalent` (turns chosen relative to the previous joint vector) has the smallest weighted
    Euclidean distance ``sqrt(sum(w (q - q_prev)^2))`` to the previous chosen joint vector (seed 000, section
    4.1: "the smallest Euler distance from the initial joint angle sequence"). The first waypoint is compared
    with ``seed_q``. Every branch change and jump is reported, nothing is hidden.

    Parameters
    ----------
    model : RobotModel
        A UR-type arm.
    flange2base : (n, 4, 4) float, mm
        Flange poses in the base frame, in trajectory order.
    seed_q : (6,) float, rad, optional
        The joint vector before the first waypoint (default zeros).
    weights : (6,) float, optional
        Non-negative weight of each joint in the distance (default ones).
    jump_rad : float, rad
        A joint move larger than this between consecutive reachable waypoints is a jump.
    q6_desired : float or (n,) float, rad, optional
        ``q6`` for a singular wrist; by default the previous waypoint's ``q6`` (``seed_q[5]`` for the first).

    Returns
    -------
    IKPath

    Notes
    -----
    The choice is sequential: a Python loop over the waypoints with numpy over the 8 branches per step, about
    15 us per waypoint (some 1.5 s for 100,000 waypoints), after one vectorised :func:`ur_ik` call. A singular
    waypoint with the default ``q6_desired`` is solved again on its own with the previous ``q6``.
    """
    poses = check_flange_poses(flange2base)
    n = len(poses)
    seed = _check_vector(seed_q, "seed_q", 0.0)
    w = _check_vector(weights, "weights", 1.0)
    if np.any(w < 0):
        raise ConfigError("weights must not be negative")
    if not (jump_rad > 0 and math.isfinite(jump_rad)):
        raise ConfigError(f"jump_rad must be a positive number, got {jump_rad}")
    follow_q6 = q6_desired is None
    sols = ur_ik(model, poses, q6_desired=0.0 if follow_q6 else q6_desired)
    cand, valid, singular = sols.q, sols.valid, sols.wrist_singular
    lower, upper = model.lower, model.upper

    q_path = np.zeros((n, 6))
    branch = np.full(n, -1, dtype=int)
    prev = seed
    for i in range(n):
        ok = valid[i]
        if not ok.any():
            continue
        qi = cand[i]
        if follow_q6 and singular[i].any():
            qi = ur_ik(model, poses[i], q6_desired=prev[5]).q[0]
        k_lo, k_hi = _turn_range(qi, lower, upper)
        k = np.minimum(np.maximum(np.rint((prev - qi) * (1.0 / TAU)), k_lo), k_hi)
        turned = qi + TAU * k
        diff = turned - prev
        dist = (diff * diff) @ w
        dist[~ok] = np.inf
        b = int(np.argmin(dist))
        branch[i] = b
        prev = q_path[i] = turned[b]

    reachable = branch >= 0
    idx = np.flatnonzero(reachable)
    branch_change = np.zeros(n, dtype=bool)
    max_step = np.zeros(n)
    if len(idx) > 1:
        branch_change[idx[1:]] = branch[idx[1:]] != branch[idx[:-1]]
        max_step[idx[1:]] = np.abs(q_path[idx[1:]] - q_path[idx[:-1]]).max(axis=1)
    jump = max_step > jump_rad
    if n:
        log.debug(
            "ik_path: %d waypoints, %d unreachable, %d branch changes, %d jumps",
            n,
            n - len(idx),
            int(branch_change.sum()),
            int(jump.sum()),
        )
    return IKPath(
        q=q_path, reachable=reachable, branch=branch, branch_change=branch_change, jump=jump, max_step_rad=max_step
    )
