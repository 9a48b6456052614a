"""The Lab-Volt R5150 five-axis arm of seed 001: closed-form kinematics and the geometric inverse kinematics.

The robot is the ``r5150`` preset of :mod:`sprayplan.robots.model` (seed 001, table 2: d1 255.55, a2 190,
a3 190, d5 115 mm, alpha1 = alpha4 = pi/2). This module gives

- :func:`r5150_position`: seed 001's eq. 3 (table 3, rows 10-12), the tool-tip position in closed form;
- :func:`r5150_orientation`: table 3, rows 1-9, the (n, o, a) columns of the tool rotation;
- :func:`r5150_ik`: the geometric inverse kinematics of eqs. 4-8 for a position, a pitch and a roll;
- :func:`r5150_pitch_roll`: the position, pitch and roll nearest a full pose (what five axes can reach of it);
- the seed's table 4 (case 1) and table 5 (case 2) as arrays, and :func:`check_seed_table`, the forward
  kinematics residual of such a table.

Pitch and roll
--------------
With ``theta234 = theta2 + theta3 + theta4``, table 3 gives the tool's approach vector (its z axis)
``a = (c1 s234, s1 s234, -c234)``: it lies in the arm's vertical plane (azimuth theta1). The *pitch* is the
angle ``theta234`` itself: pitch 0 is the tool pointing straight down (as in every row of the seed's table 4),
pitch pi/2 points it horizontally away from the base axis, pitch pi straight up. The *roll* is theta5, the
rotation about the approach vector: ``R(q) = R(q with theta5 = 0) @ Rot(z, roll)``.

How the garbled equations 4-8 are read
--------------------------------------
eq. 4, printed ``gamma = theta1 + theta2 + theta3``
    The joint indices are shifted by one: the pitch is ``gamma = theta2 + theta3 + theta4``, the three
    parallel pitch joints (figure 6 of the seed), which is the angle in eq. 3's ``s234`` and ``c234``.
eq. 5, printed ``cos(gamma) = T(3,3)``, ``rw = rg - d5 cos(gamma)``, ``zw = zg - d5 sin(gamma)``
    ``T(3,3)`` is the approach vector's z component ``az = -cos(theta234)``. The printed wrist-point formulas
    hold for the angle of the approach vector above the horizontal, ``gamma' = theta234 - pi/2``. Written with
    the pitch: ``rw = r - d5 sin(pitch)`` and ``zw = z + d5 cos(pitch)``, where ``r = hypot(px, py)``; this is
    eq. 3 solved for the wrist (``r = rw + d5 s234``, ``z = zw - d5 c234``).
eq. 6, printed ``cos(theta3) = ((zw - d1)^2 + rw^2 - a2^2 - a3^2) / (2 a2 a3)``, ``sin(theta2) = sqrt(1 -
cos(theta3)^2)``, ``theta3 = atan2(sin(theta3), cos(theta2))``
    The law of cosines for the planar two-link arm; both later subscripts 2 should be 3:
    ``s3 = -/+ sqrt(1 - c3^2)`` (elbow up / down) and ``theta3 = atan2(s3, c3)``.
eq. 7, printed ``theta2 = atan2((zw - d1), rw) - atan2(a3 sin(theta3) + a2 + a3 cos(theta3))``
    The "+" after ``a3 sin(theta3)`` is a lost comma: ``theta2 = atan2(zw - d1, rw) - atan2(a3 s3, a2 + a3 c3)``.
eq. 8, ``theta4 = gamma - theta2 - theta3``
    As printed. theta1 = atan2(py, px) and theta5 = roll complete the solution.

Elbow branches: ``"up"`` takes ``theta3 <= 0`` (in the arm plane the elbow lies above the shoulder-wrist line
while the upper arm points away from the base axis); it is the branch of table 4 and the one joint 3's range
(-147..51 deg) mostly allows. ``"down"`` takes ``theta3 >= 0``. The solver does not reach back over the base
axis (theta1 + pi with the arm bent backwards): theta1 is always atan2(py, px), moved by 2 pi into joint 1's
range when that is possible. Near the base axis (r -> 0) theta1, and with it the plane of the pitch, is
ill-defined.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.errors import ConfigError, InputError
from sprayplan.robots.model import TAU, RobotModel, fk, load_robot

ELBOWS = ("up", "down", "auto")

# Seed 001, table 4 (case 1), as printed: X, Y, Z, q5, q4, q3, q2, q1 (the headers are shuffled, see
# docs/seed-notes.md: the columns are x, theta4, theta3, theta2, theta1, z, y, theta5).
_TABLE4_PRINTED = np.array(
    [
        [150, 58.6357, -123.2727, 64.6370, 33.6901, 150, 100, 90],
        [150, 26.3787, -55.9851, 29.6064, 63.4349, 150, 300, 90],
        [180, 22.6238, -51.7705, 29.1467, 58.1726, 160, 290, 90],
        [180, 50.8499, -112.2357, 61.3857, 31.4296, 160, 110, 90],
        [210, 43.1768, -100.2380, 57.0612, 29.7449, 170, 120, 90],
        [210, 17.6261, -44.8717, 27.2456, 53.1301, 170, 280, 90],
        [240, 10.7679, -34.0003, 23.2324, 48.3665, 180, 270, 90],
        [240, 35.2449, -86.9383, 51.6934, 28.4429, 180, 130, 90],
        [270, 26.5837, -71.6373, 45.0536, 27.4076, 190, 140, 90],
        [270, -1.7549, -11.5209, 13.2758, 43.9191, 190, 260, 90],
    ]
)

# Seed 001, table 5 (case 2): rows 1, 2, 3 and 10 as printed: X, Y, Z, q5, q4, q3, q2, q1.
_TABLE5_PRINTED = np.array(
    [
        [172, 162, 300, 43.69, 96.24, -116.44, 64.31, 0],
        [300, 162, 300, 28.43, 66.30, -81.62, 59.70, 0],
        [192, 182, 300, 43.42, 88.24, -108.14, 64.73, 0],
        [300, 255.4, 300, 40.41, 49.41, -55.01, 50.59, 0],
    ]
)


# --------------------------------------------------------------------------------------------------- helpers


def _check_model(model: RobotModel | None) -> RobotModel:
    """The R5150 preset when ``model`` is None; else ``model`` after checking it has the R5150's structure."""
    if model is None:
        return load_robot("r5150")
    half = np.pi / 2
    ok = (
        model.dof == 5
        and np.allclose(model.alpha, [half, 0, 0, half, 0], atol=1e-12)
        and np.allclose(model.a[[0, 3, 4]], 0, atol=1e-12)
        and np.allclose(model.d[1:4], 0, atol=1e-12)
        and np.allclose(model.theta_offset, 0, atol=1e-12)
    )
    if not ok:
        raise ConfigError(
            f"robot {model.name!r} is not an R5150-type arm: the closed-form R5150 kinematics need 5 joints, "
            "alpha = (90, 0, 0, 90, 0) deg, a1 = a4 = a5 = 0, d2 = d3 = d4 = 0 and no joint offsets"
        )
    return model


def _check_q(q) -> np.ndarray:
    out = np.array(q, dtype=float)
    if out.ndim == 1:
        out = out[None, :]
    if out.ndim != 2 or out.shape[1] != 5:
        raise InputError(f"q must have shape (5,) or (n, 5), got {np.shape(q)}")
    return out


def _wrap_into(values: np.ndarray, lower: float, upper: float) -> np.ndarray:
    """``values`` moved by the fewest whole turns into [lower, upper] where that is possible; else left alone."""
    turns = np.where(
        values > upper,
        np.floor((upper - values) / TAU),  # the fewest turns down that pass under the upper limit
        np.ceil((lower - values) / TAU),  # the fewest turns up that pass the lower limit (0 when inside)
    )
    turns = np.where((values >= lower) & (values <= upper), 0.0, turns)
    shifted = values + turns * TAU
    return np.where((shifted >= lower) & (shifted <= upper), shifted, values)


# --------------------------------------------------------------------------------------- forward kinematics


def r5150_position(q, *, model: RobotModel | None = None) -> np.ndarray:
    """Tool-tip position of seed 001's eq. 3 (table 3, rows 10-12).

    ``r = a2 c2 + a3 c23 + d5 s234``, ``px = r c1``, ``py = r s1``, ``pz = d1 + a2 s2 + a3 s23 - d5 c234``. It
    equals the translation of the D-H forward kinematics ``fk(load_robot("r5150"), q)``.

    Parameters
    ----------
    q : (5,) or (n, 5) float, rad
        theta1 .. theta5.
    model : RobotModel, optional
        An R5150-type model (default: the ``r5150`` preset); only d1, a2, a3 and d5 are used.

    Returns
    -------
    (n, 3) float, mm
    """
    model = _check_model(model)
    q = _check_q(q)
    d1, a2, a3, d5 = model.d[0], model.a[1], model.a[2], model.d[4]
    t1, t2 = q[:, 0], q[:, 1]
    t23 = t2 + q[:, 2]
    t234 = t23 + q[:, 3]
    r = a2 * np.cos(t2) + a3 * np.cos(t23) + d5 * np.sin(t234)
    z = d1 + a2 * np.sin(t2) + a3 * np.sin(t23) - d5 * np.cos(t234)
    return np.stack([r * np.cos(t1), r * np.sin(t1), z], axis=1)


def r5150_orientation(q) -> np.ndarray:
    """Tool rotation of seed 001's table 3, rows 1-9: the columns n, o, a.

    ::

        nx = c1 c234 c5 + s1 s5    ox = s1 c5 - c1 c234 s5    ax = c1 s234
        ny = s1 c234 c5 - c1 s5    oy = -s1 c234 s5 - c1 c5   ay = s1 s234
        nz = s234 c5               oz = -s234 s5              az = -c234

    Every entry is as printed in table 3 except ``ny``: the table prints ``s1 s234 c5 - c1 s5``, which disagrees
    with the D-H product of eq. 1 (and is not a rotation: n would not be a unit vector); the D-H product gives
    ``s1 c234 c5 - c1 s5``, the y counterpart of ``nx``, which is used here. tests/test_r5150.py checks both
    statements against ``fk``.

    Parameters
    ----------
    q : (5,) or (n, 5) float, rad

    Returns
    -------
    (n, 3, 3) float
        The rotation part of ``base2tool``: columns n, o, a (the tool's x, y, z axes in the base frame).
    """
    q = _check_q(q)
    c1, s1 = np.cos(q[:, 0]), np.sin(q[:, 0])
    t234 = q[:, 1] + q[:, 2] + q[:, 3]
    c234, s234 = np.cos(t234), np.sin(t234)
    c5, s5 = np.cos(q[:, 4]), np.sin(q[:, 4])
    out = np.empty((len(q), 3, 3))
    out[:, 0, 0] = c1 * c234 * c5 + s1 * s5
    out[:, 1, 0] = s1 * c234 * c5 - c1 * s5
    out[:, 2, 0] = s234 * c5
    out[:, 0, 1] = s1 * c5 - c1 * c234 * s5
    out[:, 1, 1] = -s1 * c234 * s5 - c1 * c5
    out[:, 2, 1] = -s234 * s5
    out[:, 0, 2] = c1 * s234
    out[:, 1, 2] = s1 * s234
    out[:, 2, 2] = -c234
    return out


# --------------------------------------------------------------------------------------- inverse kinematics


@dataclass(frozen=True)
class R5150Solution:
    """Joint values for R5150 targets, one row per target; failures are data.

    Attributes
    ----------
    q : (n, 5) float, rad
        theta1 .. theta5. Never NaN: all zeros where the target is out of reach or not finite; where only joint
        limits are violated, the computed (out-of-range) values, so a caller can see how far off they are.
    reachable : (n,) bool
        The target is reached with every joint inside the model's limits.
    reason : (n,) str
        ``""`` when reachable; else ``"out of reach"`` (the wrist point is farther from the shoulder than
        a2 + a3 or nearer than |a2 - a3|), ``"non-finite target"``, or the violated limits, e.g.
        ``"joint 2 limit"`` or ``"joint 2 limit, joint 4 limit"``.
    elbow : (n,) str
        The elbow branch of each row, ``"up"`` (theta3 <= 0) or ``"down"`` (theta3 >= 0).
    """

    q: np.ndarray
    reachable: np.ndarray
    reason: np.ndarray
    elbow: np.ndarray

    def __post_init__(self):
        for name in ("q", "reachable", "reason", "elbow"):
            getattr(self, name).flags.writeable = False


def _solve_branch(
    model: RobotModel, position: np.ndarray, pitch: np.ndarray, roll: np.ndarray, up: bool, tol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One elbow branch of eqs. 4-8 for all rows: (q, reachable, reason)."""
    n = len(position)
    d1, a2, a3, d5 = model.d[0], model.a[1], model.a[2], model.d[4]
    finite = np.isfinite(position).all(axis=1) & np.isfinite(pitch) & np.isfinite(roll)
    px, py, pz = np.where(finite[:, None], position, 0.0).T
    gamma = np.where(finite, pitch, 0.0)
    theta5 = np.where(finite, roll, 0.0)

    theta1 = np.arctan2(py, px)
    r = np.hypot(px, py)
    rw = r - d5 * np.sin(gamma)  # eq. 5, read with the pitch (see the module docstring)
    zw = pz + d5 * np.cos(gamma) - d1  # wrist height above the shoulder axis
    c3 = (rw * rw + zw * zw - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)  # eq. 6
    in_reach = finite & (np.abs(c3) <= 1.0 + 1e-12)
    c3 = np.clip(c3, -1.0, 1.0)
    s3 = np.sqrt((1.0 - c3) * (1.0 + c3))
    if up:
        s3 = -s3
    theta3 = np.arctan2(s3, c3)
    theta2 = np.arctan2(zw, rw) - np.arctan2(a3 * s3, a2 + a3 * c3)  # eq. 7
    theta4 = gamma - theta2 - theta3  # eq. 8

    q = np.stack([theta1, theta2, theta3, theta4, theta5], axis=1)
    for j in range(5):
        q[:, j] = _wrap_into(q[:, j], model.lower[j], model.upper[j])
    violated = (q < model.lower - tol) | (q > model.upper + tol)
    q[~in_reach] = 0.0

    reason = np.full(n, "", dtype=object)
    reason[~finite] = "non-finite target"
    reason[finite & ~in_reach] = "out of reach"
    limited = in_reach & violated.any(axis=1)
    for i in np.flatnonzero(limited):
        reason[i] = ", ".join(f"joint {j + 1} limit" for j in np.flatnonzero(violated[i]))
    reachable = in_reach & ~violated.any(axis=1)
    return q, reachable, reason


def r5150_ik(
    position,
    pitch,
    roll,
    *,
    elbow: str = "up",
    model: RobotModel | None = None,
    limit_tol_rad: float = 1e-9,
) -> R5150Solution:
    """Geometric inverse kinematics of seed 001 (eqs. 4-8): joint values for a tool position, pitch and roll.

    theta1 = atan2(py, px); the wrist point in the arm plane is ``rw = r - d5 sin(pitch)``,
    ``zw = pz + d5 cos(pitch)``; theta2 and theta3 solve the planar two-link arm (a2, a3) for the wrist point
    with the chosen elbow; theta4 = pitch - theta2 - theta3; theta5 = roll. Each joint is then moved by whole
    turns into its range when that is possible (the pose does not change). The module docstring says how each
    garbled equation of the seed was read.

    Parameters
    ----------
    position : (3,) or (n, 3) float, mm
        Tool-tip positions in the robot base frame.
    pitch : float or (n,) float, rad
        ``theta2 + theta3 + theta4``: the tool's angle from straight down (0) in the arm's vertical plane,
        positive tilting the tool away from the base axis; the approach vector is
        ``(cos(theta1) sin(pitch), sin(theta1) sin(pitch), -cos(pitch))``.
    roll : float or (n,) float, rad
        theta5, the rotation of the tool about its approach vector.
    elbow : {"up", "down", "auto"}
        ``"up"``: theta3 <= 0 (the seed's table 4); ``"down"``: theta3 >= 0; ``"auto"``: per target, "up" when
        it is reachable, else "down" when that is, else the "up" result with its reason.
    model : RobotModel, optional
        An R5150-type model (default: the ``r5150`` preset with table 2's joint ranges).
    limit_tol_rad : float
        Slack on the joint limits.

    Returns
    -------
    R5150Solution
        Out-of-reach targets and joint-limit violations are rows with ``reachable = False`` and a reason, never
        exceptions; ``q`` holds no NaN.

    Raises
    ------
    InputError
        ``position``, ``pitch`` or ``roll`` of the wrong shape.
    ConfigError
        An unknown ``elbow`` or a model that is not R5150-like.
    """
    if elbow not in ELBOWS:
        raise ConfigError(f"elbow must be one of {', '.join(ELBOWS)}, got {elbow!r}")
    model = _check_model(model)
    position = np.array(position, dtype=float)
    if position.ndim == 1:
        position = position[None, :]
    if position.ndim != 2 or position.shape[1] != 3:
        raise InputError(f"position must have shape (3,) or (n, 3), got {position.shape}")
    n = len(position)
    try:
        pitch = np.broadcast_to(np.asarray(pitch, dtype=float), (n,))
        roll = np.broadcast_to(np.asarray(roll, dtype=float), (n,))
    except ValueError:
        raise InputError(
            f"pitch and roll must be scalars or have shape ({n},), got {np.shape(pitch)} and {np.shape(roll)}"
        ) from None

    q, reachable, reason = _solve_branch(model, position, pitch, roll, elbow != "down", limit_tol_rad)
    branch = np.full(n, "down" if elbow == "down" else "up", dtype=object)
    if elbow == "auto":
        q_d, ok_d, _ = _solve_branch(model, position, pitch, roll, False, limit_tol_rad)
        use = ~reachable & ok_d
        q[use], reachable[use], reason[use], branch[use] = q_d[use], True, "", "down"
    return R5150Solution(q=q, reachable=reachable, reason=reason.astype(str), elbow=branch.astype(str))


def r5150_pitch_roll(tool2base) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The position, pitch and roll that bring the R5150's tool nearest a full pose (the input of :func:`r5150_ik`).

    Five axes reach a position and an approach vector only in the arm's vertical plane (azimuth
    ``theta1 = atan2(py, px)``, as :func:`r5150_ik` takes it), with any roll about it. From the wanted rotation
    ``R``: ``R = Rz(theta1) Rx(pi/2) Rz(pitch) Rx(pi/2) Rz(roll)`` when the pose is reachable, so with
    ``F = Rz(theta1) Rx(pi/2)`` and ``a' = F^T a`` (the wanted approach vector in frame 1, whose x-y plane is
    the arm plane) the pitch is ``atan2(a'_x, -a'_y)``: the in-plane direction nearest the wanted axis, so the
    remaining axis error is the angle between the axis and the plane, ``asin(|a'_z|)``. The roll is the angle
    about the reached axis that minimises the remaining rotation: with ``M = (F Rz(pitch) Rx(pi/2))^T R``,
    ``roll = atan2(M_yx - M_xy, M_xx + M_yy)``. A reachable pose is returned exactly.

    Parameters
    ----------
    tool2base : (4, 4) or (n, 4, 4) float, mm
        Wanted tool poses in the robot base frame.

    Returns
    -------
    position : (n, 3) float, mm
    pitch, roll : (n,) float, rad
    """
    poses = np.asarray(tool2base, dtype=float)
    if poses.shape == (4, 4):
        poses = poses[None]
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise InputError(f"tool2base must have shape (4, 4) or (n, 4, 4), got {poses.shape}")
    n = len(poses)
    theta1 = np.arctan2(poses[:, 1, 3], poses[:, 0, 3])
    c, s = np.cos(theta1), np.sin(theta1)
    first = np.zeros((n, 3, 3))  # Rz(theta1) Rx(pi/2)
    first[:, 0, 0], first[:, 0, 2] = c, s
    first[:, 1, 0], first[:, 1, 2] = s, -c
    first[:, 2, 1] = 1.0
    rest = first.transpose(0, 2, 1) @ poses[:, :3, :3]
    pitch = np.arctan2(rest[:, 0, 2], -rest[:, 1, 2])
    cp, sp = np.cos(pitch), np.sin(pitch)
    second = np.zeros((n, 3, 3))  # Rz(pitch) Rx(pi/2)
    second[:, 0, 0], second[:, 0, 2] = cp, sp
    second[:, 1, 0], second[:, 1, 2] = sp, -cp
    second[:, 2, 1] = 1.0
    m = second.transpose(0, 2, 1) @ rest
    roll = np.arctan2(m[:, 1, 0] - m[:, 0, 1], m[:, 0, 0] + m[:, 1, 1])
    return poses[:, :3, 3].copy(), pitch, roll


# ------------------------------------------------------------------------------------------- seed tables


def table4_points() -> np.ndarray:
    """Seed 001, table 4 (case 1): the ten tool-tip points, re-ordered per docs/seed-notes.md.

    The printed columns "X", "q2", "q3" are x, y, z.

    Returns
    -------
    (10, 3) float, mm
    """
    return _TABLE4_PRINTED[:, [0, 6, 5]].copy()


def table4_joints() -> np.ndarray:
    """Seed 001, table 4 (case 1): the ten joint rows in degrees as printed, re-ordered per docs/seed-notes.md.

    The printed columns "q4", "q5", "Z", "Y", "q1" are theta1 .. theta5 (theta5 = 90 deg in every row; it does
    not move the tool tip). Every row has theta2 + theta3 + theta4 = 0 to the printed rounding: pitch 0.

    Returns
    -------
    (10, 5) float, deg
    """
    return _TABLE4_PRINTED[:, [4, 3, 2, 1, 7]].copy()


def table5_points() -> np.ndarray:
    """Seed 001, table 5 (case 2): the four printed rows (1, 2, 3 and 10), columns X, Y, Z as printed.

    Returns
    -------
    (4, 3) float, mm
    """
    return _TABLE5_PRINTED[:, :3].copy()


def table5_joints() -> np.ndarray:
    """Seed 001, table 5 (case 2): the joint rows in degrees, read as theta1 .. theta5 = "q5" .. "q1".

    Of all 720 assignments of the point and joint columns this reading comes closest to the listed points,
    yet it misses rows 1-3 by 4.35, 3.02 and 1.29 mm (row 10 by 0.05 mm): the table is not self-consistent
    (see :func:`check_seed_table` and docs/seed-notes.md).

    Returns
    -------
    (4, 5) float, deg
    """
    return _TABLE5_PRINTED[:, 3:].copy()


def check_seed_table(points, joints_deg, *, model: RobotModel | None = None) -> np.ndarray:
    """Forward kinematics residual of a seed table: how far each joint row puts the tool tip from its point.

    Parameters
    ----------
    points : (n, 3) float, mm
    joints_deg : (n, 5) float, deg
        theta1 .. theta5, as a table prints them.
    model : RobotModel, optional
        Default: the ``r5150`` preset.

    Returns
    -------
    (n,) float, mm
        ``|fk(radians(joints_deg)) - points|`` per row.
    """
    model = _check_model(model)
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    q = np.radians(_check_q(joints_deg))
    if len(q) != len(points):
        raise InputError(f"points and joints_deg must have the same number of rows, got {len(points)} and {len(q)}")
    return np.linalg.norm(fk(model, q)[:, :3, 3] - points, axis=1)
