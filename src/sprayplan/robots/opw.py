"""Six-axis industrial arms with a spherical wrist in the ortho-parallel ("OPW") form: parameters, presets, FK, IK.

The parameterisation is that of Brandstötter, Angerer and Hofbaur (2014, "An analytical solution of the inverse
kinematics problem of industrial serial manipulators with an ortho-parallel basis and a spherical wrist"):
seven lengths ``a1, a2, b, c1, c2, c3, c4`` (mm here) describe the arm in its *model zero* pose, standing
straight up, and each joint has a sign and an offset that map the maker's joint values onto the model's angles.
This module is written for sprayplan from that description; the equations below are derived here.

The model (frames as docs/CONVENTIONS.md; ``Rz``, ``Ry`` rotations about the base z and y axes)
------------------------------------------------------------------------------------------------
Joint values ``q`` (the controller's, rad) become model angles ``theta = sign * q + offset`` (per joint; a
maker whose axis turns the other way has sign -1, a maker whose zero is not the model's has an offset).

At model zero, axis 1 is the base z axis; axis 2 is parallel to the base y axis, at ``x = a1``, ``y = b``
(``b``: the sideways offset of the arm's plane), ``z = c1``; the upper arm (``c2``) stands vertically from axis
2 to axis 3; the forearm runs vertically up from axis 3 by ``c3`` to the wrist centre, offset by ``a2`` along x
(most arms: ``a2 < 0``, the forearm axis lies on the -x side of axis 3 when upright, above it when horizontal);
the flange is ``c4`` beyond the wrist centre along the forearm. Axes 4 and 6 then lie along the forearm, axis 5
parallel to y; axes 4, 5 and 6 meet at the wrist centre (the spherical wrist).

Forward kinematics (:func:`opw_fk`), with ``t23 = theta2 + theta3``:

- the wrist centre in the arm's plane: ``x' = a1 + c2 sin theta2 + c3 sin t23 + a2 cos t23``,
  ``z' = c1 + c2 cos theta2 + c3 cos t23 - a2 sin t23``; in the base frame ``C = Rz(theta1) (x', b, z')``.
  (A positive ``theta2`` or ``theta3`` tips the arm towards +x: ``Ry(t) (0, 0, 1) = (sin t, 0, cos t)``.)
- the forearm's frame is ``R0c = Rz(theta1) Ry(t23)``, the wrist adds ``Rce = Rz(theta4) Ry(theta5)
  Rz(theta6)`` (z-y-z Euler angles about the forearm axis, the bent wrist axis and the flange axis), so the
  flange is ``R = R0c Rce`` at ``p = C + c4 R (0, 0, 1)``.

The flange frame is z out of the flange along axis 6 (ABB's ``tool0``). At the maker's zero of every preset
here (forearm horizontal, pointing along +x) it is ``Ry(90 deg)``: z along +x, x pointing down. KUKA's
``$FLANGE`` names the out-of-flange axis x instead: it is this frame turned by ``Ry(-90 deg)`` about its own y.

Inverse kinematics (:func:`opw_ik`), how each step reads
--------------------------------------------------------
Given the flange pose ``R, p`` in the base frame:

1. *Wrist centre*: ``C = p - c4 R (0, 0, 1)``, which depends on the first three joints only.
2. *Axis 1 (shoulder, 2 branches)*: ``C = Rz(theta1) (x', b, z')`` means ``|C_xy|^2 = x'^2 + b^2``, so
   ``x' = +-sqrt(rho^2 - b^2)`` with ``rho = |C_xy|``, and ``theta1 = atan2(Cy, Cx) - atan2(b, x')``. ``x' >= 0``
   is *shoulder_front* (the wrist centre ahead of axis 1 in the arm's own plane), ``x' < 0`` *shoulder_back*
   (reaching over the top). No solution when ``rho < |b|``. With ``b = 0`` and the wrist centre on axis 1
   (``rho = 0``) ``theta1`` is free: it is taken as the value with ``q1 = 0`` and the solution is flagged singular.
3. *Axes 2 and 3 (elbow, 2 branches)*: in the arm's plane, relative to axis 2, the wrist centre is
   ``(u, v) = (x' - a1, z' - c1) = c2 e(theta2) + k e(theta2 + phi)`` with ``e(t) = (sin t, cos t)``, the
   forearm's length ``k = hypot(a2, c3)`` and ``phi = theta3 + psi3``, ``psi3 = atan2(a2, c3)`` (the forearm's
   offset as an angle). The law of cosines gives ``cos phi = (u^2 + v^2 - c2^2 - k^2) / (2 c2 k)``, so
   ``phi = +-acos(...)``: ``phi >= 0`` is *elbow_up* (with the front shoulder, the elbow above the line from
   axis 2 to the wrist centre), ``phi < 0`` *elbow_down*; no solution when ``|cos phi| > 1``. Then
   ``theta3 = phi - psi3`` and ``theta2 = atan2(u, v) - atan2(k sin phi, c2 + k cos phi)`` (the direction of
   the wrist centre less the angle the two links open at axis 2). A wrist centre on axis 2 (``u = v = 0``,
   possible only when ``c2 = k``) leaves ``theta2`` free: it is flagged singular.
4. *Axes 4, 5, 6 (wrist, 2 branches)*: ``M = R0c^T R = Rz(theta4) Ry(theta5) Rz(theta6)`` has third column
   ``(cos theta4 sin theta5, sin theta4 sin theta5, cos theta5)`` and third row ``(-sin theta5 cos theta6,
   sin theta5 sin theta6, cos theta5)``. So ``theta5 = atan2(+-hypot(m13, m23), m33)``; *wrist_noflip* takes
   ``theta5 >= 0`` with ``theta4 = atan2(m23, m13)``, ``theta6 = atan2(m32, -m31)``; *wrist_flip* is the same
   rotation with ``theta5`` negated and ``theta4``, ``theta6`` each turned by pi. Near a straight wrist
   (``|sin theta5|`` small) ``theta4`` and ``theta6`` are each ill conditioned but their sum is not: from the
   upper-left block, ``m21 - m12 = (1 + cos theta5) sin(theta4 + theta6)`` and ``m11 + m22 = (1 + cos theta5)
   cos(theta4 + theta6)`` (and ``m21 + m12``, ``m22 - m11`` give the difference, ``(cos theta5 - 1)`` times its
   sine and minus its cosine, near ``theta5 = pi``), so there ``theta6`` is the sum less ``theta4``, which keeps
   the pose exact to rounding however close the wrist is to straight. Where ``hypot(m13, m23)`` is at most
   ``singular_tol`` the wrist is singular (axes 4 and 6 in line, only the sum fixed): ``theta4`` is taken as
   the value with ``q4 = 0`` (a half turn from it on the flipped branch), ``theta5`` as 0 (or pi) and the
   solution is flagged singular.
5. *Joint values*: ``q = sign * (theta - offset)``, each in ``(-pi, pi]`` and then moved by the fewest whole
   turns into the joint limits (axes 4 and 6 of most arms turn more than once; the rule of
   :func:`~sprayplan.robots.ur_ik.nearest_equivalent` with the joint as its own seed). A solution is valid when
   it reaches the pose and every joint fits its limits.

Branch index ``4 * shoulder + 2 * wrist + elbow`` (the order of the UR solver's), labels in
:data:`BRANCH_LABELS`, e.g. 0 ``"shoulder_front/wrist_noflip/elbow_up"``.

Failure is data: a pose out of reach, a non-finite pose or a branch outside the limits is ``valid = False``
with ``q = 0`` (never NaN) and a reason; only a wrongly shaped or non-rigid pose raises.

Presets (:data:`PRESETS`, by name)
----------------------------------
Each preset lists the makers' published figures: the dimension drawing's lengths (mm), the axes' working
ranges (degrees) and maximum axis speeds (degrees/s), with the joint directions and zero positions of the
maker's controller. Where each number comes from is in the preset's ``source``; where a figure is not published
it is NaN (none are missing for the four presets). The figures were read from the makers' product
specifications as transcribed in ROS-Industrial's robot support packages (``abb_irb2400_support``,
``abb_irb4600_support``, ``kuka_kr6_support``), whose joint origins, axis directions, limits and velocities
restate them; the makers' PDFs themselves were not at hand to re-read.

The paint robot ABB IRB 5500 is not a preset: no dimension table of it was at hand to read the seven lengths
from, nor a statement that the axes of its hollow paint wrist meet in one point, which this solver needs.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sprayplan.errors import ConfigError, InputError, PartFileError
from sprayplan.robots.model import read_robot_toml
from sprayplan.robots.ur_ik import check_flange_poses

log = logging.getLogger(__name__)

TAU = 2.0 * math.pi
LENGTHS = ("a1", "a2", "b", "c1", "c2", "c3", "c4")
"""The seven lengths of the OPW parameterisation, mm."""

BRANCH_LABELS: tuple[str, ...] = tuple(
    f"{s}/{w}/{e}"
    for s in ("shoulder_front", "shoulder_back")
    for w in ("wrist_noflip", "wrist_flip")
    for e in ("elbow_up", "elbow_down")
)
"""Label of each branch index ``4 * shoulder + 2 * wrist + elbow``."""

_CHUNK = 8192  # poses solved at once, so the temporaries stay small
_ACOS_TOL = 1e-10  # how far beyond +-1 a cosine may be (rounding) before a branch is out of reach
_LIMIT_TOL = 1e-9  # rad of slack on the joint limits
_NEAR_STRAIGHT = 1e-3  # below this |sin theta5|, theta6 comes from the sum (difference) of theta4 and theta6


def _vector(values, name: str, fill: float | None = None) -> np.ndarray:
    if values is None:
        values = [fill] * 6
    try:
        out = np.array(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be 6 numbers, got {values!r}") from None
    if out.shape != (6,):
        raise ConfigError(f"{name} must be 6 numbers, got {out.size}")
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class OPWParameters:
    """An ortho-parallel arm with a spherical wrist (see the module docstring for the model).

    Attributes
    ----------
    name : str
    a1, a2, b, c1, c2, c3, c4 : float, mm
        The OPW lengths; ``c2 > 0`` and ``hypot(a2, c3) > 0``.
    offsets : (6,) float, rad
        ``theta = signs * q + offsets``: the model angle at the maker's zero (default 0).
    signs : (6,) float
        +1 or -1 per joint: -1 where the maker's positive direction turns the other way (default +1).
    lower, upper : (6,) float, rad
        Joint limits in the maker's joint values (default -2 pi .. 2 pi).
    max_speed : (6,) float, rad/s
        Maximum axis speeds; NaN where not published (default NaN).
    source : str
        Where the numbers come from.
    """

    name: str
    a1: float
    a2: float
    b: float
    c1: float
    c2: float
    c3: float
    c4: float
    offsets: np.ndarray = field(default=None)  # type: ignore[assignment]
    signs: np.ndarray = field(default=None)  # type: ignore[assignment]
    lower: np.ndarray = field(default=None)  # type: ignore[assignment]
    upper: np.ndarray = field(default=None)  # type: ignore[assignment]
    max_speed: np.ndarray = field(default=None)  # type: ignore[assignment]
    source: str = ""

    def __post_init__(self):
        for key in LENGTHS:
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise ConfigError(f"robot {self.name}: {key} must be a number (mm), got {value!r}")
            if not math.isfinite(value):
                raise ConfigError(f"robot {self.name}: {key} must be finite, got {value}")
            object.__setattr__(self, key, float(value))
        if not self.c2 > 0:
            raise ConfigError(f"robot {self.name}: c2 (upper arm length) must be positive, got {self.c2:g} mm")
        if math.hypot(self.a2, self.c3) == 0:
            raise ConfigError(f"robot {self.name}: a2 and c3 must not both be 0 (no forearm)")
        for key, fill in (("offsets", 0.0), ("signs", 1.0), ("lower", -TAU), ("upper", TAU), ("max_speed", math.nan)):
            object.__setattr__(self, key, _vector(getattr(self, key), f"robot {self.name}: {key}", fill))
        if not np.isfinite(self.offsets).all():
            raise ConfigError(f"robot {self.name}: offsets must be finite")
        if not np.isin(self.signs, (-1.0, 1.0)).all():
            raise ConfigError(f"robot {self.name}: signs must each be 1 or -1, got {self.signs.tolist()}")
        if np.isnan(self.lower).any() or np.isnan(self.upper).any() or np.any(self.lower > self.upper):
            raise ConfigError(f"robot {self.name}: each joint needs lower <= upper limits")
        if np.any(self.max_speed <= 0) or np.isinf(self.max_speed).any():
            raise ConfigError(f"robot {self.name}: max_speed must be positive (NaN where unknown)")

    @property
    def reach_mm(self) -> float:
        """The largest distance of the wrist centre from axis 2: ``c2 + hypot(a2, c3)``."""
        return self.c2 + math.hypot(self.a2, self.c3)

    def within_limits(self, q, tol: float = _LIMIT_TOL) -> np.ndarray:
        """(n,) bool: joint vectors (6,) or (n, 6) inside the limits."""
        q = np.atleast_2d(q)
        return ((q >= self.lower - tol) & (q <= self.upper + tol)).all(axis=-1)


@dataclass(frozen=True)
class OPWSolutions:
    """All eight solutions of :func:`opw_ik` for n flange poses.

    Attributes
    ----------
    q : (n, 8, 6) float, rad
        Joint values (the maker's), within the limits where valid, 0 elsewhere (never NaN).
    valid : (n, 8) bool
    reason : (n, 8) str
        ``""`` where valid, else ``"out of reach"``, ``"non-finite pose"``, ``"joint 5 limit"`` (the first
        joint no turn of which fits), or with ``reject_singular`` ``"wrist singular"``, ``"shoulder singular"``,
        ``"elbow singular"``.
    singular : (n, 8) bool
        The pose does not fix every joint (wrist, shoulder or elbow singular); see the module docstring for the
        value taken.
    branch_labels : tuple of 8 str
    """

    q: np.ndarray
    valid: np.ndarray
    reason: np.ndarray
    singular: np.ndarray
    branch_labels: tuple[str, ...] = BRANCH_LABELS

    def __len__(self) -> int:
        return len(self.q)


# ------------------------------------------------------------------------------------------ kinematics


def _rz(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    out = np.zeros(t.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out


def _ry(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    out = np.zeros(t.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 2], out[..., 2, 0], out[..., 2, 2], out[..., 1, 1] = c, s, -s, c, 1.0
    return out


def _joints(q) -> np.ndarray:
    out = np.asarray(q, dtype=float)
    if out.ndim == 1:
        out = out[None]
    if out.ndim != 2 or out.shape[1] != 6:
        raise InputError(f"q must have shape (6,) or (n, 6), got {np.shape(q)}")
    return out


def opw_fk(params: OPWParameters, q) -> np.ndarray:
    """The flange pose in the base frame, ``flange2base`` (n, 4, 4) mm, of joint values (6,) or (n, 6) rad."""
    q = _joints(q)
    t = q * params.signs + params.offsets
    t1, t2, t23 = t[:, 0], t[:, 1], t[:, 1] + t[:, 2]
    xp = params.a1 + params.c2 * np.sin(t2) + params.c3 * np.sin(t23) + params.a2 * np.cos(t23)
    zp = params.c1 + params.c2 * np.cos(t2) + params.c3 * np.cos(t23) - params.a2 * np.sin(t23)
    c1, s1 = np.cos(t1), np.sin(t1)
    rot = _rz(t1) @ _ry(t23) @ _rz(t[:, 3]) @ _ry(t[:, 4]) @ _rz(t[:, 5])
    out = np.zeros((len(q), 4, 4))
    out[:, :3, :3] = rot
    out[:, 0, 3] = xp * c1 - params.b * s1 + params.c4 * rot[:, 0, 2]
    out[:, 1, 3] = xp * s1 + params.b * c1 + params.c4 * rot[:, 1, 2]
    out[:, 2, 3] = zp + params.c4 * rot[:, 2, 2]
    out[:, 3, 3] = 1.0
    return out


def _wrap(x: np.ndarray) -> np.ndarray:
    """Angles into ``(-pi, pi]``."""
    return x - TAU * np.ceil((x - math.pi) * (1.0 / TAU))


def opw_ik(
    params: OPWParameters, flange2base, *, singular_tol: float = 1e-9, reject_singular: bool = False
) -> OPWSolutions:
    """All eight inverse kinematics solutions of an OPW arm for many flange poses at once.

    Parameters
    ----------
    params : OPWParameters
    flange2base : (4, 4) or (n, 4, 4) float, mm
        Flange poses in the base frame; rows holding NaN or inf are unreachable rows.
    singular_tol : float
        The wrist is singular where ``hypot(m13, m23)`` (``|sin theta5|``) is at most this; the shoulder and the
        elbow where the wrist centre is within ``singular_tol * reach_mm`` of axis 1 (with ``b = 0``) or axis 2.
    reject_singular : bool
        False (the robot interface's rule, as the UR solver): a singular solution is valid and flagged in
        ``singular``, its free joint chosen as the module docstring says. True: it is not valid, with the reason
        ``"wrist singular"`` (``"shoulder singular"``, ``"elbow singular"``).

    Returns
    -------
    OPWSolutions
        ``q (n, 8, 6)``, ``valid``, ``reason``, ``singular`` (n, 8).

    Raises
    ------
    InputError
        ``flange2base`` of the wrong shape, or a finite row that is not a rigid motion.

    Notes
    -----
    O(n), solved in chunks of 8192 poses; about 30 transcendental evaluations per pose.
    """
    poses = check_flange_poses(flange2base)
    if not (singular_tol >= 0 and math.isfinite(singular_tol)):
        raise ConfigError(f"singular_tol must be a non-negative number, got {singular_tol}")
    n = len(poses)
    q = np.zeros((n, 8, 6))
    valid = np.zeros((n, 8), dtype=bool)
    reason = np.full((n, 8), "", dtype="<U17")
    singular = np.zeros((n, 8), dtype=bool)
    for start in range(0, n, _CHUNK):
        part = slice(start, min(start + _CHUNK, n))
        _solve_chunk(
            params, poses[part], singular_tol, reject_singular, q[part], valid[part], reason[part], singular[part]
        )
    if n:
        log.debug("opw_ik %s: %d poses, %d of %d branches valid", params.name, n, int(valid.sum()), 8 * n)
    return OPWSolutions(q=q, valid=valid, reason=reason, singular=singular)


def _solve_chunk(params, poses, tol, reject_singular, q_out, valid_out, reason_out, singular_out) -> None:
    """Solve one chunk into the output views (m, 8, 6), (m, 8) x 3; shapes inside: (m, shoulder, elbow, wrist)."""
    m = len(poses)
    a1, a2, b, c1, c2, c3, c4 = (getattr(params, key) for key in LENGTHS)
    finite = (np.abs(poses) < 1e100).all(axis=(1, 2))
    if not finite.all():
        poses = np.where(finite[:, None, None], poses, np.eye(4))
    rot = poses[:, :3, :3]
    cx, cy, cz = (poses[:, i, 3] - c4 * rot[:, i, 2] for i in range(3))  # step 1: wrist centre, (m,)
    reach = params.reach_mm
    k = math.hypot(a2, c3)
    psi3 = math.atan2(a2, c3)
    sign = np.array([1.0, -1.0])

    with np.errstate(invalid="ignore", divide="ignore"):
        # step 2: axis 1, (m, 2) over the shoulder
        rho2 = cx * cx + cy * cy
        shoulder_ok = rho2 >= b * b * (1.0 - _ACOS_TOL)
        xp = np.sqrt(np.maximum(rho2 - b * b, 0.0))[:, None] * sign
        shoulder_free = (b == 0.0) & (np.sqrt(rho2) <= tol * reach)  # wrist centre on axis 1
        t1 = np.arctan2(cy, cx)[:, None] - np.arctan2(b, xp)
        t1 = np.where(shoulder_free[:, None], params.offsets[0] + np.array([0.0, math.pi]), t1)

        # step 3: axes 2 and 3, (m, 2, 2) over shoulder and elbow
        u = (xp - a1)[..., None]
        v = (cz - c1)[:, None, None]
        s2 = u * u + v * v
        cphi = (s2 - c2 * c2 - k * k) / (2.0 * c2 * k)
        elbow_ok = np.abs(cphi) <= 1.0 + _ACOS_TOL
        phi = np.arccos(np.clip(cphi, -1.0, 1.0)) * sign  # elbow_up: phi >= 0
        elbow_free = np.broadcast_to(np.sqrt(s2) <= tol * reach, phi.shape)  # wrist centre on axis 2
        t3 = phi - psi3
        t2 = np.arctan2(u, v) - np.arctan2(k * np.sin(phi), c2 + k * np.cos(phi))
        t23 = t2 + t3

        # step 4: the wrist, M = R0c^T R = Ry(t23)^T A with A = Rz(t1)^T R: A per shoulder (m, 2, 1), M per
        # shoulder and elbow (m, 2, 2); row i of A as (a[i][0], a[i][1], a[i][2]), one entry per column of R
        e1, f1 = np.cos(t1)[..., None], np.sin(t1)[..., None]
        e23, f23 = np.cos(t23), np.sin(t23)
        r = [[rot[:, i, j][:, None, None] for j in range(3)] for i in range(3)]
        a0 = [e1 * r[0][j] + f1 * r[1][j] for j in range(3)]
        a1 = [e1 * r[1][j] - f1 * r[0][j] for j in range(3)]
        a2 = r[2]

        def entry(i, j):  # entry (i, j) of M, 1-based as in the docstring
            if i == 1:
                return e23 * a0[j - 1] - f23 * a2[j - 1]
            if i == 2:
                return np.broadcast_to(a1[j - 1], e23.shape)
            return f23 * a0[j - 1] + e23 * a2[j - 1]

        m13, m23, m33, m31, m32 = entry(1, 3), entry(2, 3), entry(3, 3), entry(3, 1), entry(3, 2)
        h = np.hypot(m13, m23)
        wrist_free = h <= tol
        t5 = np.arctan2(h, m33)
        t4 = np.arctan2(m23, m13)
        t6 = np.arctan2(m32, -m31)
        near = h < _NEAR_STRAIGHT
        if near.any():  # theta6 from the sum (difference) with theta4; at a singular wrist theta4 at q4 = 0
            m11, m12, m21, m22 = entry(1, 1), entry(1, 2), entry(2, 1), entry(2, 2)
            t4 = np.where(wrist_free, params.offsets[3], t4)
            total = np.arctan2(m21 - m12, m11 + m22)  # theta4 + theta6, well conditioned for cos theta5 > -1
            difference = np.arctan2(-(m21 + m12), m22 - m11)  # theta4 - theta6, for cos theta5 < 1
            t6 = np.where(near, np.where(m33 >= 0, total - t4, t4 - difference), t6)
            t5 = np.where(wrist_free, np.where(m33 >= 0, 0.0, math.pi), t5)

    # each joint as the maker's value, wrapped and turned into its limits at its own smallest shape, then
    # assembled as (m, shoulder, elbow, wrist); wrist_flip: -theta5, theta4 + pi, theta6 + pi
    half = np.array([0.0, math.pi])
    angles = (
        t1[:, :, None, None],
        t2[..., None],
        t3[..., None],
        t4[..., None] + half,
        t5[..., None] * sign,
        t6[..., None] + half,
    )
    out = q_out.reshape(m, 2, 2, 2, 6).transpose(0, 1, 3, 2, 4)  # a view: index 4 * shoulder + 2 * wrist + elbow
    fits = np.ones((m, 2, 2, 2), dtype=bool)
    code = np.zeros((m, 2, 2, 2), dtype=np.uint8)
    for j, theta in enumerate(angles):
        joint = _wrap(params.signs[j] * (theta - params.offsets[j]))
        k_lo = np.ceil((params.lower[j] - _LIMIT_TOL - joint) * (1.0 / TAU))
        k_hi = np.floor((params.upper[j] + _LIMIT_TOL - joint) * (1.0 / TAU))
        fit = k_lo <= k_hi
        out[..., j] = joint + TAU * np.where(fit, np.clip(0.0, k_lo, k_hi), 0.0)  # the fewest turns
        code = np.where(fits & ~fit, np.uint8(1 + j), code)  # the first joint that fits no turn
        fits = fits & fit

    reached = (shoulder_ok & finite)[:, None, None, None] & elbow_ok[:, :, :, None]
    singular = shoulder_free[:, None, None, None] | elbow_free[..., None] | wrist_free[..., None]
    if reject_singular:
        for mask, value in (
            (wrist_free[..., None], 9),
            (shoulder_free[:, None, None, None], 8),
            (elbow_free[..., None], 7),
        ):
            code = np.where(fits & mask, np.uint8(value), code)
    code = np.where(reached, code, np.uint8(10))
    code[~finite] = 11
    code = code.transpose(0, 1, 3, 2).reshape(m, 8)
    ok = code == 0
    q_out[~ok] = 0.0
    valid_out[:] = ok
    reason_out[:] = _REASONS[code]
    singular_out[:] = (np.broadcast_to(singular, (m, 2, 2, 2)) & reached).transpose(0, 1, 3, 2).reshape(m, 8)


_REASONS = np.array(
    ["", *(f"joint {j + 1} limit" for j in range(6)), "elbow singular", "shoulder singular", "wrist singular"]
    + ["out of reach", "non-finite pose"]
)
"""The reasons of :func:`opw_ik` by code (0: valid)."""


# ------------------------------------------------------------------------------------------------ presets


def _deg(values) -> list[float]:
    return [math.radians(v) for v in values]


# ABB: axis 1 about +z; axes 2, 3, 5 about +y (forward / down); axes 4, 6 about the outward forearm axis
_ABB_SIGNS = [1, 1, 1, 1, 1, 1]
_ABB_OFFSETS = [0.0, 0.0, math.pi / 2, 0.0, 0.0, 0.0]  # ABB's zero: upper arm vertical, forearm horizontal

# IRB 4600 (every variant): working range and axis speeds
_IRB4600_AXES = dict(
    lower=_deg([-180, -90, -180, -400, -125, -400]),
    upper=_deg([180, 150, 75, 400, 120, 400]),
    max_speed=_deg([175, 175, 175, 250, 250, 360]),
)

PRESETS: dict[str, dict] = {
    "abb-irb2400-10": dict(
        a1=100.0,
        a2=-135.0,
        b=0.0,
        c1=615.0,
        c2=705.0,
        c3=755.0,
        c4=85.0,
        offsets=_ABB_OFFSETS,
        signs=_ABB_SIGNS,
        lower=_deg([-180, -100, -60, -200, -120, -400]),
        upper=_deg([180, 110, 65, 200, 120, 400]),
        max_speed=_deg([150, 150, 150, 360, 360, 450]),
        source=(
            "ABB Product specification IRB 2400, IRB 2400/10: dimension drawing (axis 2 615 mm "
            "above the base and 100 mm forward of axis 1, lower arm 705 mm, axis 4 135 mm above axis 3, axis 3 "
            "to the wrist centre 755 mm, wrist centre to the flange 85 mm), working range (axis 1 +-180, axis 2 "
            "+110/-100, axis 3 +65/-60, axis 4 +-200, axis 5 +-120, axis 6 +-400 deg) and axis speeds (150, 150, "
            "150, 360, 360, 450 deg/s); as restated in ROS-Industrial abb_irb2400_support (irb2400_macro.xacro)"
        ),
    ),
    "abb-irb4600-60-205": dict(
        a1=175.0,
        a2=-175.0,
        b=0.0,
        c1=495.0,
        c2=900.0,
        c3=960.0,
        c4=135.0,
        offsets=_ABB_OFFSETS,
        signs=_ABB_SIGNS,
        **_IRB4600_AXES,
        source=(
            "ABB Product specification IRB 4600, IRB 4600-60/2.05: dimension drawing (axis 2 "
            "495 mm above the base and 175 mm forward of axis 1, lower arm 900 mm, axis 4 175 mm above axis 3, "
            "axis 3 to the wrist centre 960 mm, wrist centre to the flange 135 mm), working range (axis 1 +-180, "
            "axis 2 +150/-90, axis 3 +75/-180, axis 4 +-400, axis 5 +120/-125, axis 6 +-400 deg) and axis speeds "
            "(175, 175, 175, 250, 250, 360 deg/s); as restated in ROS-Industrial abb_irb4600_support "
            "(irb4600_60_205_macro.xacro)"
        ),
    ),
    "abb-irb4600-40-255": dict(
        a1=175.0,
        a2=-175.0,
        b=0.0,
        c1=495.0,
        c2=1095.0,
        c3=1270.0,
        c4=135.0,
        offsets=_ABB_OFFSETS,
        signs=_ABB_SIGNS,
        **_IRB4600_AXES,
        source=(
            "ABB Product specification IRB 4600, IRB 4600-40/2.55: dimension drawing (axis 2 "
            "495 mm above the base and 175 mm forward of axis 1, lower arm 1095 mm, axis 4 175 mm above axis 3, "
            "axis 3 to the wrist centre 1270 mm, wrist centre to the flange 135 mm), working range and axis "
            "speeds as the 60/2.05's; as restated in ROS-Industrial abb_irb4600_support "
            "(irb4600_40_255_macro.xacro)"
        ),
    ),
    "kuka-kr6-r700-sixx": dict(
        a1=25.0,
        a2=-35.0,
        b=0.0,
        c1=400.0,
        c2=315.0,
        c3=365.0,
        c4=80.0,
        # KUKA: A1 turns about -z, A4 and A6 about the inward forearm axis; A2's zero is the upper arm
        # horizontal (A2 = -90 deg stands it up), A3's zero the forearm in line with it
        offsets=[0.0, math.pi / 2, 0.0, 0.0, 0.0, 0.0],
        signs=[-1, 1, 1, -1, 1, -1],
        lower=_deg([-170, -190, -120, -185, -120, -350]),
        upper=_deg([170, 45, 156, 185, 120, 350]),
        max_speed=_deg([360, 300, 360, 381, 388, 615]),
        source=(
            "KUKA Specification KR AGILUS sixx (KR 6 R700 sixx): dimension drawing (A2 400 mm above the base and "
            "25 mm forward of A1, link arm 315 mm, A4 35 mm above A3, A3 to the wrist centre 365 mm, wrist "
            "centre to the flange 80 mm), axis data (A1 +-170, A2 +45/-190, A3 +156/-120, A4 +-185, A5 +-120, "
            "A6 +-350 deg; speeds 360, 300, 360, 381, 388, 615 deg/s); as restated in "
            "ROS-Industrial kuka_kr6_support (kr6r700sixx_macro.xacro)"
        ),
    ),
}
"""The OPW arms known by name: the lengths (mm), offsets, signs, limits (rad) and speeds (rad/s) with sources."""


TOML_KEYS = {
    "kind": 'must be "opw"',
    "name": "the arm's name (default: the file's stem)",
    **{f"{key}_mm": "mm" for key in LENGTHS},
    "offsets_deg": "6 numbers: theta = sign * q + offset (default 0)",
    "signs": "6 numbers, each 1 or -1 (default 1)",
    "lower_deg": "6 numbers, joint limits (default -360)",
    "upper_deg": "6 numbers, joint limits (default 360)",
    "max_speed_deg_s": "6 numbers, axis speeds (default unknown)",
    "source": "where the numbers come from",
}
"""The keys of an OPW arm's TOML file (:func:`load_opw`) and what each takes."""


def load_opw(name_or_path: str | os.PathLike, setting: str = "robot") -> OPWParameters:
    """An OPW arm: a preset of :data:`PRESETS` by name, or a TOML file with ``kind = "opw"`` (keys :data:`TOML_KEYS`).

    Example file::

        kind = "opw"
        name = "my-arm"
        a1_mm = 100.0
        a2_mm = -135.0
        b_mm = 0.0
        c1_mm = 615.0
        c2_mm = 705.0
        c3_mm = 755.0
        c4_mm = 85.0
        offsets_deg = [0, 0, 90, 0, 0, 0]
        lower_deg = [-180, -100, -60, -200, -120, -400]
        upper_deg = [180, 110, 65, 200, 120, 400]

    Raises
    ------
    ConfigError
        An unknown name (the message lists the presets), first naming ``setting``.
    PartFileError
        A file that is missing, not TOML, has an unknown or missing key, or a bad value (one line naming the
        file and the key).
    """
    key = os.fspath(name_or_path)
    if key in PRESETS:
        return OPWParameters(name=key, **PRESETS[key])
    path = Path(key)
    if path.suffix.lower() != ".toml":
        raise ConfigError(f"{setting} {key!r} is not a known OPW arm: use one of {', '.join(PRESETS)} or a .toml file")
    data = read_robot_toml(path)
    if data.get("kind") != "opw":
        raise PartFileError(key, f'not an OPW arm: kind = "opw" is required, got {data.get("kind")!r}')
    unknown = sorted(set(data) - set(TOML_KEYS))
    if unknown:
        raise PartFileError(key, f"unknown key(s) {', '.join(unknown)}; known: {', '.join(TOML_KEYS)}")
    missing = [f"{k}_mm" for k in LENGTHS if f"{k}_mm" not in data]
    if missing:
        raise PartFileError(key, f"missing key(s) {', '.join(missing)}")

    def angles(name: str, scale: float = 1.0):
        if name not in data:
            return None
        values = data[name]
        if not isinstance(values, list) or len(values) != 6 or not all(_is_number(v) for v in values):
            raise PartFileError(key, f"{name} must be a list of 6 numbers, got {values!r}")
        return [math.radians(v) * scale for v in values]

    for length in LENGTHS:
        if not _is_number(data[f"{length}_mm"]):
            raise PartFileError(key, f"{length}_mm must be a number (mm), got {data[f'{length}_mm']!r}")
    signs = data.get("signs")
    if signs is not None and (not isinstance(signs, list) or not all(_is_number(v) for v in signs)):
        raise PartFileError(key, f"signs must be a list of 6 numbers, each 1 or -1, got {signs!r}")
    try:
        return OPWParameters(
            name=str(data.get("name", path.stem)),
            **{length: float(data[f"{length}_mm"]) for length in LENGTHS},
            offsets=angles("offsets_deg"),
            signs=signs,
            lower=angles("lower_deg"),
            upper=angles("upper_deg"),
            max_speed=angles("max_speed_deg_s"),
            source=str(data.get("source", key)),
        )
    except ConfigError as exc:
        raise PartFileError(key, str(exc)) from None


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_opw_file(name_or_path: str | os.PathLike) -> bool:
    """True when ``name_or_path`` is a ``.toml`` file meant as an OPW arm: it has a ``kind`` key (a D-H table has
    none) or an OPW length (``c2_mm``, ...); :func:`load_opw` then checks it. A broken file raises."""
    key = os.fspath(name_or_path)
    if not key.lower().endswith(".toml"):
        return False
    data = read_robot_toml(Path(key))
    return "kind" in data or any(f"{length}_mm" in data for length in LENGTHS)
