"""One robot interface for the kinematics stage: :class:`Robot`, its :class:`IKSolutions`, and the implementations.

Every robot the planner drives is a :class:`Robot`: joint vectors ``q`` of ``dof`` axes (rad for revolute axes,
mm for the linear ones named by ``linear_axes``), forward kinematics to the tool centre point (TCP, the gun tip
the stages aim) in the world, and inverse kinematics that returns *all* its solutions with a validity mask.
Later stages hold a :class:`Robot` and never ask which one it is.

Frames (docs/CONVENTIONS.md, ``A2B @ p_A = p_B``): ``base2world`` is where the robot's base stands in the world,
``tcp2flange`` the TCP on the flange (the gun's ``gun2flange``, identity for a bare flange), and ``fk`` returns
``tcp2world = base2world @ flange2base(q) @ tcp2flange``, the TCP's pose in the world, mm. ``ik`` takes such
poses.

Implementations (use :func:`robot_from_name`):

``URArm`` (``ur5``, ``ur5e``, ``ur5-seed``)
    The closed-form solution of :func:`sprayplan.robots.ur_ik.ur_ik`: 8 branches per pose (labels
    :data:`~sprayplan.robots.ur_ik.BRANCH_LABELS`), each joint moved by whole turns into its limits.
``R5150Arm`` (``r5150``)
    The five-axis arm of seed 001, :func:`sprayplan.robots.r5150.r5150_ik` for both elbows (2 solutions per
    pose). Five axes reach a position and a gun axis in the arm's vertical plane only: ``ik`` of a full pose
    solves for the position, the in-plane gun axis nearest the wanted one and the best roll about it
    (:func:`~sprayplan.robots.r5150.r5150_pitch_roll`), reports the remaining angle between the reached and the
    wanted gun axis in ``axis_error_rad``, and marks a solution valid only when that angle is at most the arm's
    ``axis_tol_rad`` (default 1e-6 rad; the roll about the axis is then exact too). The solver does not reach
    back over the base axis (see :mod:`sprayplan.robots.r5150`): poses that only such a configuration reaches
    are ``"out of reach"``. Its TCP is the D-H frame 5 (the seed's tool tip, d5 = 115 mm): no gun is added.
``OPWArm`` (``abb-irb2400-10``, ``abb-irb4600-60-205``, ``abb-irb4600-40-255``, ``kuka-kr6-r700-sixx``)
    Six-axis industrial arms with a spherical wrist, :func:`sprayplan.robots.opw.opw_ik`: 8 branches per pose
    (labels :data:`~sprayplan.robots.opw.BRANCH_LABELS`), joints in the maker's values, moved by whole turns into
    the limits; ``max_speed`` gives the maker's axis speeds. Not yet usable in ``sprayplan plan``.
``GantryRobot`` (``gantry-ur5``, ``gantry-ur5e``)
    Seed 000's nine axes, ``q = (q1..q6 rad, tx, ty, tz mm)`` as in :mod:`sprayplan.robots.gantry`; its base is
    the world (``base2world`` identity). The three gantry axes make it redundant, so ``ik`` takes the platform
    position ``platform_mm`` ((3,) or (n, 3) mm); without it each pose gets
    :meth:`Gantry.platform_beside <sprayplan.robots.gantry.Gantry.platform_beside>` of its flange point (half the
    working cylinder's radius aside, at mid-height), moved into the gantry's travel. For a fixed platform,
    :meth:`GantryRobot.at_platform` returns the hanging arm as a six-axis :class:`URArm` with that
    ``base2world``; its solutions are ``q[:, :, :6]`` of the gantry's. The gantry's travel limits are unknown
    (the seed gives none): ``travel_mm`` is ``+-inf`` unless set.

Failure is data: an unreachable pose gives ``valid = False`` on every solution with a ``reason``; only a wrongly
shaped input raises (:class:`~sprayplan.errors.InputError`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from sprayplan.checks import check_points, check_poses
from sprayplan.errors import ConfigError, InputError
from sprayplan.robots.gantry import GANTRY_ARMS, Gantry, build_gantry, load_gun
from sprayplan.robots.model import TAU, RobotModel, fk, load_robot
from sprayplan.robots.opw import PRESETS as OPW_PRESETS
from sprayplan.robots.opw import OPWParameters, is_opw_file, load_opw, opw_fk, opw_ik
from sprayplan.robots.r5150 import r5150_ik, r5150_pitch_roll
from sprayplan.robots.ur_ik import BRANCH_LABELS, check_ur_model, nearest_equivalent, ur_ik

LIMIT_TOL = 1e-9
"""Slack (rad or mm) on the joint limits in :meth:`Robot.within_limits`."""


@dataclass(frozen=True)
class IKSolutions:
    """All inverse kinematics solutions of a robot for n poses, k per pose; failures are data.

    Attributes
    ----------
    q : (n, k, dof) float
        Joint vectors (rad, mm on linear axes), solution ``j`` of pose ``i`` in ``q[i, j]``. Within the joint
        limits where valid; finite everywhere (0 where the pose is out of reach), meaningful only where valid.
    valid : (n, k) bool
        The solution reaches the pose (see ``axis_error_rad``) with every axis within its limits.
    reason : (n, k) str
        ``""`` where valid; else why not: ``"out of reach"``, ``"non-finite pose"``, ``"joint limit"`` (or
        ``"joint 2 limit"`` where the robot names the joint), ``"gun axis off by 3.2 deg"`` (R5150),
        ``"gantry travel limit"``.
    singular : (n, k) bool
        The pose does not fix every joint (a UR wrist at ``sin q5 = 0``, the R5150 on its base axis); the
        solution is one of many.
    axis_error_rad : (n, k) float
        Angle between the reached and the wanted gun (TCP z) axis: 0 for the six- and nine-axis robots, which
        reach a pose exactly; for the R5150 what its five axes cannot reach (0 where out of reach).
    branch_labels : tuple of k str
        What each solution index means, e.g. ``"shoulder_left/wrist_up/elbow_up"`` or ``"elbow_up"``.
    """

    q: np.ndarray
    valid: np.ndarray
    reason: np.ndarray
    singular: np.ndarray
    axis_error_rad: np.ndarray
    branch_labels: tuple[str, ...]

    def __post_init__(self):
        n, k = self.valid.shape
        if self.q.shape[:2] != (n, k) or self.reason.shape != (n, k) or len(self.branch_labels) != k:
            raise ValueError("IKSolutions: q, valid, reason and branch_labels disagree in shape")
        for name in ("q", "valid", "reason", "singular", "axis_error_rad"):
            getattr(self, name).flags.writeable = False

    def __len__(self) -> int:
        return len(self.q)

    @property
    def reachable(self) -> np.ndarray:
        """(n,) bool: some solution of the pose is valid."""
        return self.valid.any(axis=1)

    def pose_reason(self) -> np.ndarray:
        """(n,) str: ``""`` for a reachable pose, else the reason of its first solution."""
        return np.where(self.reachable, "", self.reason[:, 0])


@runtime_checkable
class Robot(Protocol):
    """What the kinematics stage needs of a robot (see the module docstring for the frames and the implementations).

    Attributes
    ----------
    name : str
    dof : int
    joint_limits : (dof, 2) float
        Lower and upper limit of each axis, rad (mm for linear axes); may be infinite for a linear axis.
    linear_axes : (dof,) bool
        The axes measured in mm (the gantry's); the others are revolute, in rad.
    base2world : (4, 4) float, mm
    tcp2flange : (4, 4) float, mm
    """

    name: str

    @property
    def dof(self) -> int: ...

    @property
    def joint_limits(self) -> np.ndarray: ...

    @property
    def linear_axes(self) -> np.ndarray: ...

    @property
    def base2world(self) -> np.ndarray: ...

    @property
    def tcp2flange(self) -> np.ndarray: ...

    def fk(self, q) -> np.ndarray:
        """``tcp2world`` (n, 4, 4) mm of joint vectors ``q`` (dof,) or (n, dof)."""
        ...

    def ik(self, tcp2world) -> IKSolutions:
        """All solutions for TCP poses (4, 4) or (n, 4, 4) mm in the world; never raises for a pose."""
        ...

    def within_limits(self, q) -> np.ndarray:
        """(n,) bool: joint vectors (dof,) or (n, dof) inside the limits (with :data:`LIMIT_TOL`)."""
        ...


# ------------------------------------------------------------------------------------------------- helpers


def _poses(tcp2world) -> np.ndarray:
    poses = np.asarray(tcp2world, dtype=float)
    if poses.shape == (4, 4):
        poses = poses[None]
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise InputError(f"tcp2world must have shape (4, 4) or (n, 4, 4), got {poses.shape}")
    # NaN rows are unreachable rows; a mirror or a sheared rotation is an error naming the row
    check_poses(poses, "tcp2world", allow_nan=True)
    return poses


def _joints(q, dof: int) -> np.ndarray:
    out = np.asarray(q, dtype=float)
    if out.ndim == 1:
        out = out[None]
    if out.ndim != 2 or out.shape[1] != dof:
        raise InputError(f"q must have shape ({dof},) or (n, {dof}), got {np.shape(q)}")
    return out


def _within(q, limits: np.ndarray) -> np.ndarray:
    q = _joints(q, len(limits))
    return ((q >= limits[:, 0] - LIMIT_TOL) & (q <= limits[:, 1] + LIMIT_TOL)).all(axis=-1)


def _finite(poses: np.ndarray) -> np.ndarray:
    return (np.abs(poses) < 1e100).all(axis=(1, 2))  # False for NaN and inf


def _transform(value, name: str) -> np.ndarray:
    out = np.array(np.eye(4) if value is None else value, dtype=float)
    if out.shape != (4, 4) or not np.isfinite(out).all():
        raise ConfigError(f"{name} must be a finite 4x4 transform")
    out.flags.writeable = False
    return out


def _axis_angle(achieved: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Angle between the z axes of pose stacks, rad: ``atan2(|a x b|, a . b)``, accurate near 0 (arccos is not)."""
    a, b = achieved[:, :3, 2], wanted[:, :3, 2]
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ni,ni->n", a, b))


def nearest_turns(robot: Robot, q, seed) -> np.ndarray:
    """Each revolute joint of ``q`` (..., dof) moved by whole turns within the limits to be nearest ``seed``.

    Linear axes are left alone. Use it to follow a trajectory: the solutions of :meth:`Robot.ik` keep their
    turns as solved (UR joints reach +-2 pi, so a joint and the joint plus a turn are both valid).
    """
    q = np.asarray(q, dtype=float)
    limits = robot.joint_limits
    turned = nearest_equivalent(q, seed, limits[:, 0], limits[:, 1])
    return np.where(robot.linear_axes, np.broadcast_to(q, turned.shape), turned)


def follow_solutions(robot: Robot, sols: IKSolutions, seed=None) -> tuple[np.ndarray, np.ndarray]:
    """One solution per pose along a trajectory: the valid one nearest the previous chosen joints.

    Each solution's revolute joints are first moved by whole turns within the limits towards the previous
    joints (:func:`nearest_turns`); the first pose is compared with ``seed`` (default zeros). Unreachable poses
    are skipped (the next pose is compared with the last reachable one).

    Returns
    -------
    q : (n, dof) float
        The chosen joints, 0 where no solution is valid.
    branch : (n,) int
        The chosen solution's index, -1 where none is valid.
    """
    n, _k, dof = sols.q.shape
    prev = np.zeros(dof) if seed is None else _joints(seed, dof)[0]
    q = np.zeros((n, dof))
    branch = np.full(n, -1)
    for i in np.flatnonzero(sols.reachable):
        turned = nearest_turns(robot, sols.q[i], prev)
        dist = np.where(sols.valid[i], ((turned - prev) ** 2).sum(axis=1), np.inf)
        branch[i] = int(np.argmin(dist))
        prev = q[i] = turned[branch[i]]
    return q, branch


def _ur_solutions(model: RobotModel, flange2base: np.ndarray) -> IKSolutions:
    """:func:`ur_ik` as :class:`IKSolutions`: joints moved into the limits, reasons per branch."""
    n = len(flange2base)
    finite = _finite(flange2base)
    sols = ur_ik(model, flange2base)
    q, valid = sols.q, sols.valid
    if np.any(model.lower > -math.pi) or np.any(model.upper < math.pi):  # (-pi, pi] may leave the limits
        q = nearest_equivalent(q, q, model.lower, model.upper)  # the fewest turns into the limits
        valid = valid & model.within_limits(q.reshape(-1, 6), LIMIT_TOL).reshape(n, 8)
    reason = np.full((n, 8), "", dtype="<U16")
    reason[~valid] = "out of reach"
    if np.any(model.upper - model.lower < TAU):  # some turn may not fit: tell the limits from the reach
        wide = dataclasses.replace(model, lower=np.full(6, -TAU), upper=np.full(6, TAU))
        reason[~valid & ur_ik(wide, flange2base).valid] = "joint limit"
    reason[~finite] = "non-finite pose"
    q = np.where(valid[..., None], q, 0.0)
    return IKSolutions(
        q=q,
        valid=valid,
        reason=reason,
        singular=sols.wrist_singular & valid,
        axis_error_rad=np.zeros((n, 8)),
        branch_labels=BRANCH_LABELS,
    )


# ---------------------------------------------------------------------------------------- implementations


@dataclass(frozen=True)
class URArm:
    """A UR-type arm (:func:`~sprayplan.robots.ur_ik.check_ur_model`) standing at ``base2world``: 6 axes, 8 branches.

    Attributes
    ----------
    model : RobotModel
    tcp2flange : (4, 4) float, mm
        The TCP on the flange (default: the model's ``tool2flange``).
    base2world : (4, 4) float, mm
        Default: the model's ``base2world``.
    name : str
        Default: the model's name.
    """

    model: RobotModel
    tcp2flange: np.ndarray = field(default=None)  # type: ignore[assignment]
    base2world: np.ndarray = field(default=None)  # type: ignore[assignment]
    name: str = ""

    def __post_init__(self):
        check_ur_model(self.model)
        tcp = self.model.tool2flange if self.tcp2flange is None else self.tcp2flange
        base = self.model.base2world if self.base2world is None else self.base2world
        object.__setattr__(self, "tcp2flange", _transform(tcp, "tcp2flange"))
        object.__setattr__(self, "base2world", _transform(base, "base2world"))
        object.__setattr__(self, "name", self.name or self.model.name)

    @property
    def dof(self) -> int:
        return 6

    @property
    def joint_limits(self) -> np.ndarray:
        return np.stack([self.model.lower, self.model.upper], axis=1)

    @property
    def linear_axes(self) -> np.ndarray:
        return np.zeros(6, dtype=bool)

    def fk(self, q) -> np.ndarray:
        return self.base2world @ fk(self.model, _joints(q, 6)) @ self.tcp2flange

    def ik(self, tcp2world) -> IKSolutions:
        poses = _poses(tcp2world)
        flange = np.linalg.inv(self.base2world) @ np.where(_finite(poses)[:, None, None], poses, np.nan)
        return _ur_solutions(self.model, flange @ np.linalg.inv(self.tcp2flange))

    def within_limits(self, q) -> np.ndarray:
        return _within(q, self.joint_limits)


@dataclass(frozen=True)
class R5150Arm:
    """The Lab-Volt R5150 (seed 001): 5 axes, 2 elbow branches; a full pose is reached up to its gun axis error.

    Attributes
    ----------
    model : RobotModel
        An R5150-type model (default: the ``r5150`` preset); its ``base2world`` places it. Its TCP is the D-H
        frame 5 (``tcp2flange`` identity).
    axis_tol_rad : float
        A solution is valid only when the reached gun axis is within this angle of the wanted one.
    name : str
    """

    model: RobotModel = field(default_factory=lambda: load_robot("r5150"))
    axis_tol_rad: float = 1e-6
    name: str = ""

    def __post_init__(self):
        if not (self.axis_tol_rad >= 0 and math.isfinite(self.axis_tol_rad)):
            raise ConfigError(f"axis_tol_rad must be a non-negative number, got {self.axis_tol_rad}")
        r5150_ik(np.zeros(3), 0.0, 0.0, model=self.model)  # raises ConfigError for a model of another shape
        object.__setattr__(self, "name", self.name or self.model.name)

    @property
    def dof(self) -> int:
        return 5

    @property
    def joint_limits(self) -> np.ndarray:
        return np.stack([self.model.lower, self.model.upper], axis=1)

    @property
    def linear_axes(self) -> np.ndarray:
        return np.zeros(5, dtype=bool)

    @property
    def base2world(self) -> np.ndarray:
        return self.model.base2world

    @property
    def tcp2flange(self) -> np.ndarray:
        return np.eye(4)

    def fk(self, q) -> np.ndarray:
        return self.model.base2world @ fk(self.model, _joints(q, 5))

    def ik(self, tcp2world) -> IKSolutions:
        poses = _poses(tcp2world)
        n = len(poses)
        finite = _finite(poses)
        local = np.linalg.inv(self.model.base2world) @ np.where(finite[:, None, None], poses, np.eye(4))
        position, pitch, roll = r5150_pitch_roll(local)
        q = np.zeros((n, 2, 5))
        valid = np.zeros((n, 2), dtype=bool)
        reason = np.full((n, 2), "", dtype=object)
        axis = np.zeros((n, 2))
        for j, elbow in enumerate(("up", "down")):
            sol = r5150_ik(position, pitch, roll, elbow=elbow, model=self.model, limit_tol_rad=LIMIT_TOL)
            reached = sol.reason != "out of reach"
            axis_j = _axis_angle(fk(self.model, sol.q), local)
            axis_j = np.where(reached, axis_j, 0.0)
            off = axis_j > self.axis_tol_rad
            q[:, j] = sol.q
            valid[:, j] = sol.reachable & ~off
            reason[:, j] = sol.reason
            for i in np.flatnonzero(off & sol.reachable):
                reason[i, j] = f"gun axis off by {math.degrees(axis_j[i]):.3g} deg"
            axis[:, j] = axis_j
        reason[~finite] = "non-finite pose"
        valid[~finite] = False
        singular = np.broadcast_to((np.hypot(position[:, 0], position[:, 1]) < 1e-9)[:, None], (n, 2)) & valid
        return IKSolutions(
            q=q,
            valid=valid,
            reason=reason.astype(str),
            singular=singular.copy(),
            axis_error_rad=axis,
            branch_labels=("elbow_up", "elbow_down"),
        )

    def within_limits(self, q) -> np.ndarray:
        return _within(q, self.joint_limits)


@dataclass(frozen=True)
class GantryRobot:
    """Seed 000's nine axes, ``q = (q1..q6 rad, tx, ty, tz mm)``: a UR-type arm hanging from an x/y/z gantry.

    Attributes
    ----------
    gantry : Gantry
        The arm, the gun (the TCP is the gun, ``tcp2flange = gun2flange``) and the working cylinder.
    travel_mm : (3, 2) float, mm
        Lower and upper travel of tx, ty, tz (default unlimited: the seed gives none).
    name : str
    """

    gantry: Gantry = field(default_factory=build_gantry)
    travel_mm: np.ndarray = field(default=None)  # type: ignore[assignment]
    name: str = ""

    def __post_init__(self):
        check_ur_model(self.gantry.robot)
        travel = np.array([[-np.inf, np.inf]] * 3 if self.travel_mm is None else self.travel_mm, dtype=float)
        if travel.shape != (3, 2) or np.isnan(travel).any() or np.any(travel[:, 0] > travel[:, 1]):
            raise ConfigError("travel_mm must be 3 rows of (lower, upper) mm with lower <= upper")
        travel.flags.writeable = False
        object.__setattr__(self, "travel_mm", travel)
        object.__setattr__(self, "name", self.name or f"gantry-{self.gantry.robot.name}")

    @property
    def dof(self) -> int:
        return 9

    @property
    def joint_limits(self) -> np.ndarray:
        arm = self.gantry.robot
        return np.concatenate([np.stack([arm.lower, arm.upper], axis=1), self.travel_mm])

    @property
    def linear_axes(self) -> np.ndarray:
        return np.arange(9) >= 6

    @property
    def base2world(self) -> np.ndarray:
        return np.eye(4)

    @property
    def tcp2flange(self) -> np.ndarray:
        return self.gantry.gun.gun2flange

    def fk(self, q) -> np.ndarray:
        return self.gantry.gun2world(_joints(q, 9))

    def default_platform(self, tcp2world) -> np.ndarray:
        """(n, 3) mm: the platform ``ik`` uses without ``platform_mm``, per pose (see the module docstring)."""
        poses = _poses(tcp2world)
        flange = (poses @ np.linalg.inv(self.tcp2flange))[:, :3, 3]
        platform = self.gantry.platform_beside(np.where(np.isfinite(flange), flange, 0.0))
        return np.clip(platform, self.travel_mm[:, 0], self.travel_mm[:, 1])

    def ik(self, tcp2world, platform_mm=None) -> IKSolutions:
        """All 8 arm branches per pose with the gantry at ``platform_mm`` ((3,) or (n, 3) mm; default
        :meth:`default_platform`). A platform outside the travel makes every branch ``"gantry travel limit"``."""
        poses = _poses(tcp2world)
        n = len(poses)
        if platform_mm is None:
            platform = self.default_platform(poses)
        else:
            try:
                platform = np.broadcast_to(np.asarray(platform_mm, dtype=float), (n, 3))
            except ValueError:
                raise InputError(f"platform_mm must have shape (3,) or ({n}, 3), got {np.shape(platform_mm)}") from None
            check_points(platform, "platform_mm")
        finite = _finite(poses) & np.isfinite(platform).all(axis=1)
        safe = np.where(finite[:, None], platform, 0.0)
        flange = self.gantry.flange_targets(np.where(finite[:, None, None], poses, np.nan), safe)
        arm = _ur_solutions(self.gantry.robot, flange)
        in_travel = _within(safe, self.travel_mm) & finite
        valid = arm.valid & in_travel[:, None]
        reason = arm.reason.astype("<U20")
        reason[~in_travel & finite] = "gantry travel limit"
        reason[~finite] = "non-finite pose"
        q = np.concatenate([arm.q, np.broadcast_to(safe[:, None, :], (n, 8, 3))], axis=2)
        return IKSolutions(
            q=np.where(valid[..., None], q, 0.0),
            valid=valid,
            reason=reason,
            singular=arm.singular & valid,
            axis_error_rad=arm.axis_error_rad.copy(),
            branch_labels=arm.branch_labels,
        )

    def at_platform(self, platform_mm) -> URArm:
        """The hanging arm with the gantry fixed at ``platform_mm`` (3,) mm: a six-axis :class:`URArm` whose
        ``base2world`` is ``Trans(t) Rot(x, pi)`` (eq. 8) and whose TCP is the gun."""
        platform = np.asarray(platform_mm, dtype=float)
        if platform.shape != (3,) or not np.isfinite(platform).all():
            raise InputError(f"platform_mm must be 3 finite numbers, got shape {platform.shape}")
        if not _within(platform, self.travel_mm)[0]:
            raise ConfigError(f"platform {platform.tolist()} mm is outside the gantry's travel")
        return URArm(
            self.gantry.robot,
            tcp2flange=self.gantry.gun.gun2flange,
            base2world=self.gantry.base2world(platform)[0],
            name=f"{self.name}@({platform[0]:g}, {platform[1]:g}, {platform[2]:g})",
        )

    def within_limits(self, q) -> np.ndarray:
        return _within(q, self.joint_limits)


@dataclass(frozen=True)
class OPWArm:
    """A six-axis industrial arm in the OPW form (:mod:`sprayplan.robots.opw`) at ``base2world``: 8 branches.

    Attributes
    ----------
    params : OPWParameters
        Lengths, joint offsets and signs, limits (the maker's joint values) and speeds.
    tcp2flange : (4, 4) float, mm
        The TCP on the flange (z out of the flange, see :mod:`sprayplan.robots.opw`); default the bare flange.
    base2world : (4, 4) float, mm
        Default identity.
    name : str
        Default the parameters' name.
    reject_singular : bool
        False (default): singular solutions are valid and flagged, as for the UR arms; True: they are not valid
        (reason ``"wrist singular"`` and so on), see :func:`~sprayplan.robots.opw.opw_ik`.
    """

    params: OPWParameters
    tcp2flange: np.ndarray = field(default=None)  # type: ignore[assignment]
    base2world: np.ndarray = field(default=None)  # type: ignore[assignment]
    name: str = ""
    reject_singular: bool = False

    def __post_init__(self):
        if not isinstance(self.params, OPWParameters):
            raise ConfigError(f"OPWArm needs OPWParameters, got {type(self.params).__name__}")
        object.__setattr__(self, "tcp2flange", _transform(self.tcp2flange, "tcp2flange"))
        object.__setattr__(self, "base2world", _transform(self.base2world, "base2world"))
        object.__setattr__(self, "name", self.name or self.params.name)

    @property
    def dof(self) -> int:
        return 6

    @property
    def joint_limits(self) -> np.ndarray:
        return np.stack([self.params.lower, self.params.upper], axis=1)

    @property
    def linear_axes(self) -> np.ndarray:
        return np.zeros(6, dtype=bool)

    @property
    def max_speed(self) -> np.ndarray:
        """(6,) rad/s: the maker's maximum axis speeds (NaN where not published)."""
        return self.params.max_speed

    def fk(self, q) -> np.ndarray:
        return self.base2world @ opw_fk(self.params, _joints(q, 6)) @ self.tcp2flange

    def ik(self, tcp2world) -> IKSolutions:
        poses = _poses(tcp2world)
        flange = np.linalg.inv(self.base2world) @ np.where(_finite(poses)[:, None, None], poses, np.nan)
        sols = opw_ik(self.params, flange @ np.linalg.inv(self.tcp2flange), reject_singular=self.reject_singular)
        return IKSolutions(
            q=sols.q,
            valid=sols.valid,
            reason=sols.reason,
            singular=sols.singular & sols.valid,
            axis_error_rad=np.zeros(sols.valid.shape),
            branch_labels=sols.branch_labels,
        )

    def within_limits(self, q) -> np.ndarray:
        return _within(q, self.joint_limits)


# ------------------------------------------------------------------------------------------------- factory

ROBOT_NAMES = ("ur5", "ur5e", "ur5-seed", "r5150", "gantry-ur5", "gantry-ur5e", *OPW_PRESETS)
"""The names :func:`robot_from_name` knows."""


def robot_from_name(name: str, tool: str | None = None) -> Robot:
    """The robot called ``name`` (one of :data:`ROBOT_NAMES`) with the gun preset ``tool`` as its TCP.

    The industrial arms (``abb-irb2400-10``, ``abb-irb4600-60-205``, ``abb-irb4600-40-255``, ``kuka-kr6-r700-sixx``) are
    :class:`OPWArm` of the presets in :data:`sprayplan.robots.opw.PRESETS`. A ``.toml`` path is an OPW arm
    when the file says ``kind = "opw"`` (:func:`sprayplan.robots.opw.load_opw`), else a UR-type D-H table
    (:func:`sprayplan.robots.model.load_robot`).

    ``tool`` is a gun of :data:`sprayplan.robots.gantry.GUNS`: for an arm, ``None`` is the bare flange; for a
    gantry, ``None`` is seed 000's ``wa101``; the R5150's TCP is its tool tip, so it takes only ``None`` or
    ``"none"``.

    Raises
    ------
    ConfigError
        An unknown name (the message lists the known ones) or tool, or a gun on the R5150.
    PartFileError
        A robot file that is missing or broken.
    """
    is_file = str(name).lower().endswith(".toml")
    if name not in ROBOT_NAMES and not is_file:
        raise ConfigError(f"unknown robot {name!r}: use one of {', '.join(ROBOT_NAMES)} or a robot .toml file")
    if name == "r5150":
        if tool not in (None, "none"):
            raise ConfigError(f"robot r5150 takes no --tool (its TCP is the seed's tool tip), got {tool!r}")
        return R5150Arm()
    if name.startswith("gantry-"):
        arm = name.removeprefix("gantry-")
        assert arm in GANTRY_ARMS
        return GantryRobot(build_gantry(arm, tool or "wa101"), name=name)
    tcp = None if tool is None else load_gun(tool).gun2flange
    if name in OPW_PRESETS or (is_file and is_opw_file(name)):
        return OPWArm(load_opw(name), tcp2flange=tcp)
    return URArm(load_robot(name), tcp2flange=tcp)
