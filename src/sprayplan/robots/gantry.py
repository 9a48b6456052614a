"""The nine-axis robot of seed 000: a UR5 hanging from a three-axis x/y/z gantry (sections 3-4, 6.4).

Pose of the spray target (eq. 8)::

    T = Trans(tx, ty, tz) Rot(x, pi) T_robot T_tool T_dis

with ``T_robot`` the UR5's ``flange2base`` (eq. 11), ``T_tool`` the gun on the flange (``gun2flange``) and
``T_dis`` the spray distance along the gun's z axis (``target2gun``). Here ``Trans(t) Rot(x, pi)`` is
``base2world``: the robot hangs upside down from the gantry carriage at ``t``.

Workspace (section 4, eq. 13): the largest cylinder ``V = pi (r cos theta)^2 (h0 - r sin theta)`` inside the
reach sphere of radius r = 850 mm around the shoulder, below the gantry's side wall h0 = 163 mm from the
sphere's centre. dV/dtheta = 0 gives ``3 r s^2 - 2 h0 s - r = 0`` in s = sin(theta), whose negative root
``s = (h0 - sqrt(h0^2 + 3 r^2)) / (3 r)`` is theta = -0.543 rad, radius 727.6 mm, height 602.4 mm: the seed's
-0.54 rad, 727 mm and 602 mm. Assumption (the seed's figure 13 is not in the text): the cylinder's axis is the base's z
axis, its top lies h0 above the shoulder toward the mount (73.8 mm above the mounting plane for the UR5's
d1 = 89.2 mm), its bottom r |sin theta| below the shoulder. Inside it, a core cylinder of 151 mm diameter
around the base axis is "not recommended" (the shoulder singularity).

Inverse kinematics of a waypoint (section 4): in the recommended region the analytic UR IK
(``robots.ur_ik``), branch chosen nearest the previous joints; elsewhere, or when the analytic solution fails,
SQP (scipy's SLSQP) over the six joints and the three gantry axes, minimising eq. 20 subject to eqs. 21-22.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from sprayplan.checks import check_points, check_poses
from sprayplan.errors import ConfigError, DataError
from sprayplan.robots.model import RobotModel, fk, fk_point, load_robot
from sprayplan.robots.sqp_newton import newton_sqp, pose_errors_first_order
from sprayplan.types import read_only

log = logging.getLogger(__name__)


def trans(x: float, y: float, z: float) -> np.ndarray:
    """4x4 translation."""
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


ROT_X_PI = np.diag([1.0, -1.0, -1.0, 1.0])  # Rot(x, pi) of eq. 8


@dataclass(frozen=True)
class Gun:
    """A spray gun on the flange.

    Attributes
    ----------
    name : str
    gun2flange : (4, 4) float, mm
        T_tool of eq. 8.
    spray_distance_mm : float
        T_dis = Trans(0, 0, spray_distance_mm): the spray target on the gun's z axis.
    """

    name: str
    gun2flange: np.ndarray
    spray_distance_mm: float

    @property
    def target2gun(self) -> np.ndarray:
        """T_dis."""
        return trans(0.0, 0.0, self.spray_distance_mm)


#: Seed 000's WA-101 gun: T_tool = Trans(5.5, 94.5, 165.5) mm, T_dis = Trans(0, 0, 113) mm.
GUNS = {"wa101": Gun("wa101", trans(5.5, 94.5, 165.5), 113.0), "none": Gun("none", np.eye(4), 0.0)}


def load_gun(name: str) -> Gun:
    """A gun preset (``wa101``, ``none``)."""
    if name not in GUNS:
        raise ConfigError(f"unknown tool {name!r}: use one of {', '.join(GUNS)}")
    return GUNS[name]


@dataclass(frozen=True)
class Workspace:
    """The recommended working cylinder of a hanging UR5 (seed 000, section 4, eq. 13).

    Attributes
    ----------
    reach_mm : float
        r, the radius of the reach sphere around the shoulder (UR5: 850 mm).
    wall_mm : float
        h0, from the sphere's centre up to the gantry's side wall (seed: 163 mm).
    core_diameter_mm : float
        The non-recommended core around the base axis (seed: 151 mm).
    """

    reach_mm: float = 850.0
    wall_mm: float = 163.0
    core_diameter_mm: float = 151.0

    @property
    def theta(self) -> float:
        """The angle of eq. 13 at which the cylinder's volume is largest, rad (negative: below the centre)."""
        r, h0 = self.reach_mm, self.wall_mm
        # dV/dtheta = 0  <=>  3 r s^2 - 2 h0 s - r = 0 with s = sin(theta); the negative root
        s = (2 * h0 - math.sqrt(4 * h0 * h0 + 12 * r * r)) / (6 * r)
        return math.asin(s)

    @property
    def radius_mm(self) -> float:
        """Cylinder radius r cos(theta)."""
        return self.reach_mm * math.cos(self.theta)

    @property
    def height_mm(self) -> float:
        """Cylinder height h0 - r sin(theta)."""
        return self.wall_mm - self.reach_mm * math.sin(self.theta)

    def volume(self, theta: float) -> float:
        """Eq. 13: V(theta) = pi (r cos theta)^2 (h0 - r sin theta), mm^3."""
        return math.pi * (self.reach_mm * math.cos(theta)) ** 2 * (self.wall_mm - self.reach_mm * math.sin(theta))


@dataclass(frozen=True)
class Gantry:
    """A UR-type robot hanging from a three-axis gantry, with a spray gun.

    Attributes
    ----------
    robot : RobotModel
    gun : Gun
    workspace : Workspace
    """

    robot: RobotModel = field(default_factory=lambda: load_robot("ur5"))
    gun: Gun = field(default_factory=lambda: GUNS["wa101"])
    workspace: Workspace = field(default_factory=Workspace)

    def base2world(self, platform: np.ndarray) -> np.ndarray:
        """(n, 4, 4): ``Trans(t) Rot(x, pi)`` for platform positions t (n, 3), mm."""
        platform = np.atleast_2d(np.asarray(platform, dtype=float))
        out = np.broadcast_to(ROT_X_PI, (len(platform), 4, 4)).copy()
        out[:, :3, 3] = platform
        return out

    def target2world(self, q9: np.ndarray) -> np.ndarray:
        """Eq. 8 for (n, 9) joint vectors (q1..q6 rad, tx, ty, tz mm): the spray target's pose, (n, 4, 4)."""
        q9 = np.atleast_2d(np.asarray(q9, dtype=float))
        return self.base2world(q9[:, 6:9]) @ fk(self.robot, q9[:, :6]) @ self.gun.gun2flange @ self.gun.target2gun

    def gun2world(self, q9: np.ndarray) -> np.ndarray:
        """The gun's pose (without T_dis), (n, 4, 4)."""
        q9 = np.atleast_2d(np.asarray(q9, dtype=float))
        return self.base2world(q9[:, 6:9]) @ fk(self.robot, q9[:, :6]) @ self.gun.gun2flange

    def gun_tip(self, q9: np.ndarray, dq9: np.ndarray | None = None):
        """The gun's origin in the world, ``gun2world(q9)[:, :3, 3]`` without the 4x4 products, (n, 3) mm; with
        joint rates ``dq9`` (n, 9) also its rate of change, (n, 3) (``robots.model.fk_point``)."""
        q9 = np.atleast_2d(np.asarray(q9, dtype=float))
        offset = self.gun.gun2flange[:3, 3]
        flip = ROT_X_PI[:3, :3].diagonal()
        if dq9 is None:
            return fk_point(self.robot, q9[:, :6], offset) * flip + q9[:, 6:9]
        dq9 = np.atleast_2d(np.asarray(dq9, dtype=float))
        p, dp = fk_point(self.robot, q9[:, :6], offset, dq9[:, :6])
        return p * flip + q9[:, 6:9], dp * flip + dq9[:, 6:9]

    def flange_targets(self, gun2world: np.ndarray, platform: np.ndarray) -> np.ndarray:
        """The flange poses in the robot base frame that put the gun at ``gun2world`` (eq. 14), (n, 4, 4)."""
        base2world = self.base2world(platform)
        return np.linalg.inv(base2world) @ gun2world @ np.linalg.inv(self.gun.gun2flange)

    def _cylinder(self, points: np.ndarray, platform: np.ndarray):
        """Radial distance from the base axis, height, and the cylinder's top and bottom, per world point."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        platform = np.broadcast_to(np.asarray(platform, dtype=float), points.shape)
        radial = np.hypot(points[:, 0] - platform[:, 0], points[:, 1] - platform[:, 1])
        shoulder_z = platform[:, 2] - self.robot.d[0]  # the robot hangs: its shoulder is d1 below the mount
        top = shoulder_z + self.workspace.wall_mm
        bottom = shoulder_z + self.workspace.reach_mm * math.sin(self.workspace.theta)
        return radial, points[:, 2], top, bottom

    def region(self, points: np.ndarray, platform: np.ndarray) -> np.ndarray:
        """Where world points lie for a platform position: 2 recommended, 1 inside the cylinder's
        non-recommended core, 0 outside the cylinder. (n,) int."""
        radial, z, top, bottom = self._cylinder(points, platform)
        inside = (radial <= self.workspace.radius_mm) & (z <= top) & (z >= bottom)
        core = radial < self.workspace.core_diameter_mm / 2.0
        return np.where(inside, np.where(core, 1, 2), 0)

    def distance_outside(self, points: np.ndarray, platform: np.ndarray) -> np.ndarray:
        """(n,) float, mm: how far world points lie outside the working cylinder (0 inside)."""
        radial, z, top, bottom = self._cylinder(points, platform)
        out_r = np.maximum(radial - self.workspace.radius_mm, 0.0)
        out_z = np.maximum(np.maximum(z - top, bottom - z), 0.0)
        return np.hypot(out_r, out_z)

    def platform_z_for(self, z_mm: float) -> float:
        """The gantry height that puts points at height ``z_mm`` in the middle of the working cylinder."""
        return float(self.platform_beside([[0.0, 0.0, z_mm]], [0.0, 0.0])[0, 2])

    def platform_beside(self, points: np.ndarray, across=(0.0, 1.0)) -> np.ndarray:
        """One platform position per world point, (n, 3) mm: half the cylinder's radius beside it along
        ``across`` (a unit vector in plan, (2,) or (n, 2)), at the height that puts the point in the middle of
        the working cylinder. Outside the non-recommended core and inside the cylinder, as :meth:`platform_for`
        places a stroke's station."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        across = np.broadcast_to(np.asarray(across, dtype=float), (len(points), 2))
        shoulder_to_mid = (self.workspace.wall_mm + self.workspace.reach_mm * math.sin(self.workspace.theta)) / 2
        out = np.empty((len(points), 3))
        out[:, :2] = points[:, :2] + across * (self.workspace.radius_mm / 2.0)
        out[:, 2] = points[:, 2] - shoulder_to_mid + self.robot.d[0]
        return out

    def platform_for(self, points: np.ndarray) -> np.ndarray:
        """A platform position (3,) for painting a group of world points (a stroke) from one place.

        In plan: beside the points' centre, half the cylinder's radius across their main direction, so that a
        straight stroke passes the base axis at a distance (outside the non-recommended core) and stays in
        the cylinder for up to ``2 sqrt(R^2 - (R/2)^2) = 1.73 R`` of its length. In height: the points' mean at
        the middle of the cylinder.
        """
        points = np.atleast_2d(np.asarray(points, dtype=float))
        centre = points.mean(axis=0)
        flat = points[:, :2] - centre[:2]
        if len(points) >= 2 and np.ptp(flat, axis=0).max() > 0:
            _, vectors = np.linalg.eigh(flat.T @ flat)
            along = vectors[:, -1]
        else:
            along = np.array([1.0, 0.0])
        across = np.array([-along[1], along[0]])
        if across[np.argmax(np.abs(across))] < 0:
            across = -across
        return self.platform_beside(centre, across)[0]


#: The arms :func:`build_gantry` hangs from the gantry: the UR-type presets of :mod:`sprayplan.robots.model`.
GANTRY_ARMS = ("ur5", "ur5e", "ur5-seed")


def build_gantry(arm: str = "ur5", tool: str = "wa101") -> Gantry:
    """The nine-axis gantry with a UR-type arm preset and a gun preset, with seed 000's working cylinder.

    ``build_gantry()`` is the seed's machine, ``Gantry(robot=load_robot("ur5"), gun=load_gun("wa101"))``.
    The working cylinder's reach (850 mm) is the UR5's; the UR5e's is the same.

    Raises
    ------
    ConfigError
        An arm that is not one of :data:`GANTRY_ARMS`, or an unknown tool.
    """
    if arm not in GANTRY_ARMS:
        raise ConfigError(f"unknown gantry arm {arm!r}: use one of {', '.join(GANTRY_ARMS)}")
    return Gantry(robot=load_robot(arm), gun=load_gun(tool))


def pose_errors(achieved: np.ndarray, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position error (mm, eq. 21) and axis error (rad, eq. 22: angle between the z axes) of poses (n,4,4)."""
    position = np.linalg.norm(achieved[..., :3, 3] - wanted[..., :3, 3], axis=-1)
    cos = np.clip(np.einsum("...i,...i->...", achieved[..., :3, 2], wanted[..., :3, 2]), -1.0, 1.0)
    return position, np.arccos(cos)


#: Whether :func:`solve_sqp` tries Newton's method first (see there).
NEWTON_FIRST = True


@dataclass(frozen=True)
class SQPResult:
    """One SQP solve: the nine axes, whether the constraints hold, and the errors."""

    q9: np.ndarray
    success: bool
    position_error_mm: float
    axis_error_rad: float
    iterations: int
    message: str


def solve_sqp(
    gantry: Gantry,
    target2world: np.ndarray,
    start_q9: np.ndarray,
    *,
    k_d: float = 0.1,
    position_tol_mm: float = 5.0,
    axis_tol_rad: float = math.radians(5.0),
    max_iter: int = 150,
    reference_q9: np.ndarray | None = None,
    newton_first: bool = NEWTON_FIRST,
) -> SQPResult:
    """Seed 000 section 4.2: SQP from the previous solution for a pose the analytic IK cannot serve.

    Minimises eq. 20, ``sum (theta_i - theta_i^0)^2 + K_d |t - t^0|^2`` (its square root has the same minimiser
    and is not smooth at the start), over the six joints and the gantry position t, subject to eq. 21 (the
    spray target within ``position_tol_mm``) and eq. 22 (the gun axis within ``axis_tol_rad``), and the joint
    limits. The printed eq. 20 calls K_d "the number of movements of the platform"; it is read as the weight
    that trades a millimetre of gantry travel against a radian of joint motion (default 0.1 rad^2/mm^2: 3.2 mm
    of gantry travel costs as much as 1 rad of joint motion, so the gantry moves only slightly, as the seed
    says; with a joint change of at most 2 pi per joint the gantry moves at most sqrt(6 (2 pi)^2 / K_d) = 49 mm).

    ``start_q9`` is the optimiser's first guess; ``reference_q9`` (default: the guess) holds the theta_i^0 and
    t^0 of eq. 20: the previous solution and the station's gantry position.

    With ``newton_first`` (the default), Newton's method on the KKT conditions with exact derivatives
    (:func:`sprayplan.robots.sqp_newton.newton_sqp`) is tried first, from the reference: about a tenth of an
    SLSQP solve's cost where the reference is one waypoint step from the tolerance boundary, as it is along a
    stroke. Its answer is kept when it is a strict local minimum within the joint limits whose eq. 20 cost is
    at most ``NEWTON_COST_LIMIT`` (a moderate move from the reference; a larger one may be a worse local
    minimum than SLSQP's, so SLSQP decides); otherwise SLSQP runs from ``start_q9`` as without it, given the
    constraints' exact gradients (the geometric Jacobian, as Newton's; finite differences cost ten forward
    kinematics an evaluation and answered fewer problems: docs/benchmarks.md, "Session 19").

    Returns
    -------
    SQPResult
        ``success`` is True only when both constraints hold at the returned point (checked by forward
        kinematics, whatever the optimiser reports).
    """
    guess = np.asarray(start_q9, dtype=float).reshape(9)
    start = guess if reference_q9 is None else np.asarray(reference_q9, dtype=float).reshape(9)
    wanted = np.asarray(target2world, dtype=float).reshape(4, 4)
    if newton_first:
        found = _newton_try(gantry, wanted, start, k_d, position_tol_mm, axis_tol_rad)
        if found is not None:
            return found
    cache: dict = {}
    offset2flange = gantry.gun.gun2flange @ gantry.gun.target2gun
    flip_wanted_z = ROT_X_PI[:3, :3].diagonal() * wanted[:3, 2]
    jac_e = np.zeros((3, 9))
    jac_e[:, 6:] = np.eye(3)

    def evaluate(x):
        """Eqs. 21 and 22 at x and their exact gradients (``sqp_newton.pose_errors_first_order``)."""
        key = x.tobytes()
        if key not in cache:
            first = pose_errors_first_order(gantry.robot, offset2flange, wanted[:3, 3], flip_wanted_z, x, jac_e)
            distance, grad_1, cos_angle, grad_2 = first[3], first[5], first[6], first[9]
            cache.clear()
            cache[key] = (distance, math.acos(cos_angle), grad_1, grad_2)
        return cache[key]

    def objective(x):
        dq = x[:6] - start[:6]
        dt = x[6:] - start[6:]
        return float(dq @ dq + k_d * dt @ dt)

    def objective_grad(x):
        return np.concatenate([2.0 * (x[:6] - start[:6]), 2.0 * k_d * (x[6:] - start[6:])])

    constraints = [
        {"type": "ineq", "fun": lambda x: position_tol_mm - evaluate(x)[0], "jac": lambda x: -evaluate(x)[2]},
        {"type": "ineq", "fun": lambda x: axis_tol_rad - evaluate(x)[1], "jac": lambda x: -evaluate(x)[3]},
    ]
    bounds = [(lo, hi) for lo, hi in zip(gantry.robot.lower, gantry.robot.upper)] + [(None, None)] * 3
    result = minimize(
        objective,
        guess,
        jac=objective_grad,
        method="SLSQP",
        bounds=bounds,
        constraints=constraints,
        options={"maxiter": max_iter, "ftol": 1e-10},
    )

    position, axis = (e[0] for e in pose_errors(gantry.target2world(result.x), wanted))
    ok = bool(position <= position_tol_mm * (1 + 1e-6) and axis <= axis_tol_rad * (1 + 1e-6))
    return SQPResult(result.x, ok, float(position), float(axis), int(result.nit), str(result.message))


#: The largest eq. 20 cost (rad^2, and mm^2 of gantry travel weighted by K_d) of a Newton answer that
#: :func:`solve_sqp` keeps without SLSQP: joints moved by about 3 rad in all, or the gantry by 10 mm. On the
#: demo roof's and the DTC hull's 1,654 SQP problems no kept answer cost more than SLSQP's; the first one that
#: did (with no limit) cost 57 against SLSQP's 27 (docs/benchmarks.md, "The kinematics stage").
NEWTON_COST_LIMIT = 10.0


def _newton_try(gantry: Gantry, wanted, reference, k_d, position_tol_mm, axis_tol_rad) -> SQPResult | None:
    """:func:`solve_sqp`'s Newton first try, as an SQPResult whose errors are checked by forward kinematics;
    None where SLSQP is to decide."""
    offset2flange = gantry.gun.gun2flange @ gantry.gun.target2gun
    found = newton_sqp(
        gantry.robot,
        offset2flange,
        wanted[:3, 3],
        wanted[:3, 2],
        reference,
        k_d=k_d,
        position_tol_mm=position_tol_mm,
        axis_tol_rad=axis_tol_rad,
    )
    if found is None:
        return None
    x, steps = found
    dq, dt = x[:6] - reference[:6], x[6:] - reference[6:]
    if float(dq @ dq + k_d * dt @ dt) > NEWTON_COST_LIMIT:
        return None
    position, axis = pose_errors(gantry.target2world(x), wanted)
    ok = bool(position[0] <= position_tol_mm * (1 + 1e-6) and axis[0] <= axis_tol_rad * (1 + 1e-6))
    if not ok:
        return None
    return SQPResult(x, True, float(position[0]), float(axis[0]), steps, "Newton on the KKT conditions")


#: How many SQP solves :func:`solve_gantry_path` remembers (about 1 kB each).
SQP_MEMO_SIZE = 20_000
_sqp_memo: OrderedDict = OrderedDict()
_sqp_memo_lock = threading.Lock()


def _gantry_key(gantry: Gantry) -> bytes:
    """The numbers an SQP solve of ``gantry`` depends on (its arm's geometry and limits, its gun), as bytes."""
    robot = gantry.robot
    parts = [robot.d, robot.a, robot.alpha, robot.theta_offset, robot.lower, robot.upper, robot.base2world]
    parts += [robot.tool2flange, gantry.gun.gun2flange, gantry.gun.target2gun]
    return b"".join(np.ascontiguousarray(p, dtype=np.float64).tobytes() for p in parts)


def _problem_key(gantry, gantry_key, target2world, arrays, options) -> bytes:
    """The bytes that identify an SQP problem: the gantry, the pose, the given arrays and the other options."""
    key_parts = [gantry_key if gantry_key is not None else _gantry_key(gantry)]
    key_parts += [np.ascontiguousarray(target2world, dtype=np.float64).tobytes()]
    key_parts += [b"" if a is None else np.ascontiguousarray(a, dtype=np.float64).tobytes() for a in arrays]
    key_parts += [repr(sorted((k, v) for k, v in options.items() if k != "reference_q9")).encode()]
    return b"|".join(key_parts)


_MISSING = object()


def _remember(key: bytes, solve):
    """``solve()``'s answer (an SQPResult or None), from the memory when ``key`` is in it."""
    with _sqp_memo_lock:
        found = _sqp_memo.get(key, _MISSING)
        if found is not _MISSING:
            _sqp_memo.move_to_end(key)
            return found
    result = solve()
    if result is not None:
        q9 = np.array(result.q9, dtype=float)
        q9.flags.writeable = False
        result = dataclasses.replace(result, q9=q9)
    with _sqp_memo_lock:
        _sqp_memo[key] = result
        while len(_sqp_memo) > SQP_MEMO_SIZE:
            _sqp_memo.popitem(last=False)
    return result


def remembered_sqp(gantry: Gantry, target2world, start_q9, *, gantry_key: bytes | None = None, **options) -> SQPResult:
    """:func:`solve_sqp`, remembered: the same problem (gantry, pose, start, reference and options, bit for bit)
    gives the remembered result instead of a new solve. The touch-ups solve a station's appended strokes
    again after each cut (``refine.extend``): the waypoints before a cut repeat their problems exactly, so
    their answers are the same as solving them again. The last ``SQP_MEMO_SIZE`` problems are kept."""
    arrays = (start_q9, options.get("reference_q9"))
    key = b"sqp|" + _problem_key(gantry, gantry_key, target2world, arrays, options)
    return _remember(key, lambda: solve_sqp(gantry, target2world, start_q9, **options))


def remembered_newton(
    gantry: Gantry, target2world, reference_q9, *, k_d, position_tol_mm, axis_tol_rad, gantry_key=None
) -> SQPResult | None:
    """:func:`solve_sqp`'s Newton first try alone (None where SLSQP is to decide), remembered as
    :func:`remembered_sqp` is. It needs no starting point: :func:`solve_gantry_path` looks for one (an
    exact solution with the gantry stepped aside) only where SLSQP runs."""
    options = dict(k_d=k_d, position_tol_mm=position_tol_mm, axis_tol_rad=axis_tol_rad)
    key = b"newton|" + _problem_key(gantry, gantry_key, target2world, (reference_q9,), options)
    wanted = np.asarray(target2world, dtype=float).reshape(4, 4)
    reference = np.asarray(reference_q9, dtype=float).reshape(9)
    return _remember(key, lambda: _newton_try(gantry, wanted, reference, **options))


#: Gantry steps tried (mm, in the plane) to find an exact starting point for SQP when the station has none.
ASIDE_STEPS = np.array([[150.0, 0, 0], [-150.0, 0, 0], [0, 150.0, 0], [0, -150.0, 0], [0, 0, 150.0], [0, 0, -150.0]])


def _shifted_starts(gantry: Gantry, gun2world: np.ndarray, platform: np.ndarray, previous: np.ndarray) -> list:
    """(9,) q9 starts that reach the pose exactly from a gantry position stepped aside (one per position, its
    branch nearest the previous joints), nearest the previous joints first."""
    from sprayplan.robots.ur_ik import nearest_equivalent, ur_ik

    trial = platform + ASIDE_STEPS
    flange = gantry.flange_targets(np.broadcast_to(gun2world, (len(trial), 4, 4)), trial)
    solutions = ur_ik(gantry.robot, flange)
    found = []
    for k in range(len(trial)):
        q = nearest_equivalent(
            solutions.q[k], np.broadcast_to(previous, (8, 6)), gantry.robot.lower, gantry.robot.upper
        )
        ok = solutions.valid[k] & gantry.robot.within_limits(q)
        if not ok.any():
            continue
        cost = np.where(ok, np.linalg.norm(q - previous, axis=1), np.inf)
        j = int(np.argmin(cost))
        found.append((float(cost[j]), k, np.concatenate([q[j], trial[k]])))
    return [start for _, _, start in sorted(found, key=lambda f: (f[0], f[1]))]


#: SLSQP is started from at most this many of the stepped-aside starts, the next only when one fails.
SHIFTED_TRIES = 3


@dataclass(frozen=True)
class GantryPath:
    """The nine-axis solution of a path, waypoint by waypoint (seed 000, figures 33-34).

    Attributes
    ----------
    q9 : (n, 9) float
        q1..q6 (rad) and the gantry position tx, ty, tz (mm); zeros where unreachable.
    reachable : (n,) bool
    method : (n,) str
        ``"analytic"``, ``"sqp"`` or ``""`` (unreachable).
    region : (n,) int
        Where the flange is: 2 recommended, 1 non-recommended core, 0 outside the working cylinder.
    position_error_mm : (n,) float
        Distance between the achieved and the wanted spray target (eq. 21).
    axis_error_deg : (n,) float
        Angle between the achieved and the wanted gun axis (eq. 22).
    branch : (n,) int
        The analytic branch used (-1 for SQP or unreachable).
    branch_change : (n,) bool
        The branch differs from the previous analytic waypoint's.
    jump : (n,) bool
        A joint moved by more than the jump threshold since the previous reachable waypoint.
    """

    q9: np.ndarray
    reachable: np.ndarray
    method: np.ndarray
    region: np.ndarray
    position_error_mm: np.ndarray
    axis_error_deg: np.ndarray
    branch: np.ndarray
    branch_change: np.ndarray
    jump: np.ndarray

    def __post_init__(self):
        read_only(self)


def solve_gantry_path(
    gantry: Gantry,
    gun2world: np.ndarray,
    platform: np.ndarray,
    *,
    seed_q: np.ndarray | None = None,
    jump_rad: float = 0.5,
    k_d: float = 0.1,
    position_tol_mm: float = 5.0,
    axis_tol_rad: float = math.radians(5.0),
    outside_policy: str = "analytic",
    sqp_reach_mm: float = 150.0,
    max_gantry_move_mm: float = 200.0,
    newton_first: bool = NEWTON_FIRST,
) -> GantryPath:
    """Joint values for a sequence of gun poses, with the gantry at the given positions.

    Parameters
    ----------
    gantry : Gantry
    gun2world : (n, 4, 4) float, mm
        Wanted gun poses (z axis toward the surface), in path order.
    platform : (n, 3) or (3,) float, mm
        Gantry position for each waypoint (a station's position repeated over its waypoints).
    seed_q : (6,) float, optional
        Joints to start near; default: the UR's "home" (0, -pi/2, 0, -pi/2, 0, 0).
    outside_policy : {"analytic", "sqp"}
        Outside the working cylinder: ``analytic`` uses the exact analytic solution when one exists (the
        cylinder is the seed's conservative "recommended" space; the arm still reaches beyond it), ``sqp``
        always goes to SQP there, as the seed does for its non-recommended area. The non-recommended core
        always goes to SQP.
    sqp_reach_mm : float
        SQP is tried outside the cylinder only within this distance of it; farther waypoints without an
        analytic solution are unreachable from the station (SQP would have to move the gantry a long way).
    max_gantry_move_mm : float
        The seed lets SQP move the gantry "slightly": a solution that moves it farther from the station is
        rejected and the waypoint reported unreachable.
    newton_first : bool
        Try Newton's method on the KKT conditions from the reference before SLSQP (see :func:`solve_sqp`);
        False: SLSQP alone, as before it was added.

    Returns
    -------
    GantryPath
        Unreachable waypoints are data (``reachable = False``), never exceptions.
    """
    from sprayplan.robots.ur_ik import _turn_range, nearest_in_turns, ur_ik

    gun2world = check_poses(np.asarray(gun2world, dtype=float).reshape(-1, 4, 4), "gun2world")
    n = len(gun2world)
    try:
        platform = np.broadcast_to(np.asarray(platform, dtype=float), (n, 3)).copy()
    except ValueError:
        raise DataError(f"platform must have shape (3,) or ({n}, 3), got {np.shape(platform)}") from None
    check_points(platform, "platform")
    if seed_q is not None:
        from sprayplan.robots.ur_ik import _check_vector

        seed_q = _check_vector(seed_q, "seed_q", 0.0)
    wanted_target = gun2world @ gantry.gun.target2gun
    # the working cylinder bounds where the robot's end (the flange) goes (seed 000, figure 25)
    flange_world = gun2world @ np.linalg.inv(gantry.gun.gun2flange)
    region = gantry.region(flange_world[:, :3, 3], platform)
    beyond = gantry.distance_outside(flange_world[:, :3, 3], platform)
    if outside_policy not in ("analytic", "sqp"):
        raise ConfigError(f"outside_policy must be analytic or sqp, got {outside_policy!r}")
    flange = gantry.flange_targets(gun2world, platform)
    solutions = ur_ik(gantry.robot, flange)
    robot = gantry.robot
    q9 = np.zeros((n, 9))
    reachable = np.zeros(n, dtype=bool)
    method = np.full(n, "", dtype=object)
    branch = np.full(n, -1)
    branch_change = np.zeros(n, dtype=bool)
    jump = np.zeros(n, dtype=bool)
    previous = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0]) if seed_q is None else np.asarray(seed_q)
    previous_branch = -1
    gantry_key = _gantry_key(gantry)
    # each joint's whole turns within the limits, for every branch of every waypoint at once
    k_lo, k_hi = _turn_range(solutions.q, robot.lower, robot.upper)
    low, high = robot.lower - 1e-9, robot.upper + 1e-9  # RobotModel.within_limits
    analytic_here = (region == 2) | ((region == 0) & (outside_policy == "analytic"))
    too_far = (region == 0) & (beyond > sqp_reach_mm)
    for i in range(n):
        candidates = nearest_in_turns(solutions.q[i], previous, k_lo[i], k_hi[i])
        valid = solutions.valid[i] & ((candidates >= low) & (candidates <= high)).all(axis=-1)
        any_valid = bool(valid.any())
        if too_far[i] and not any_valid:
            continue  # far outside the cylinder and no analytic solution: unreachable from this station
        if any_valid and analytic_here[i]:
            offset = candidates - previous
            distance = np.where(valid, np.sqrt((offset * offset).sum(axis=1)), np.inf)
            best = int(np.argmin(distance))
            q9[i, :6], q9[i, 6:] = candidates[best], platform[i]
            method[i], branch[i] = "analytic", best
            branch_change[i] = previous_branch >= 0 and best != previous_branch
            previous_branch = best
        else:
            reference = np.concatenate([previous, platform[i]])
            options = dict(k_d=k_d, position_tol_mm=position_tol_mm, axis_tol_rad=axis_tol_rad)
            result = None
            if newton_first:
                result = remembered_newton(gantry, wanted_target[i], reference, gantry_key=gantry_key, **options)
            if result is None:
                if valid.any():  # an analytic solution exists (near the core): start SQP from it
                    best = int(np.argmin(np.where(valid, np.linalg.norm(candidates - previous, axis=1), np.inf)))
                    starts = [np.concatenate([candidates[best], platform[i]])]
                else:  # none here: start from exact solutions with the gantry stepped aside, SQP brings it back
                    starts = _shifted_starts(gantry, gun2world[i], platform[i], previous)[:SHIFTED_TRIES]
                for start in starts or [reference]:  # the next start only where the one before failed
                    result = remembered_sqp(
                        gantry,
                        wanted_target[i],
                        start,
                        gantry_key=gantry_key,
                        reference_q9=reference,
                        newton_first=False,
                        **options,
                    )
                    if result.success and np.linalg.norm(result.q9[6:] - platform[i]) <= max_gantry_move_mm:
                        break
            if not result.success:
                log.info("waypoint %d: SQP failed (%s)", i, result.message)
                continue
            if np.linalg.norm(result.q9[6:] - platform[i]) > max_gantry_move_mm:
                log.info("waypoint %d: SQP would move the gantry more than %g mm", i, max_gantry_move_mm)
                continue
            q9[i] = result.q9
            method[i] = "sqp"
        reachable[i] = True
        jump[i] = bool(np.abs(q9[i, :6] - previous).max() > jump_rad) if i else False
        previous = q9[i, :6]
    achieved = gantry.target2world(q9)
    position, axis = pose_errors(achieved, wanted_target)
    position = np.where(reachable, position, np.nan)
    axis = np.where(reachable, np.degrees(axis), np.nan)
    return GantryPath(q9, reachable, method.astype(str), region, position, axis, branch, branch_change, jump)
