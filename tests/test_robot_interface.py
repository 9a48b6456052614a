"""The robot interface (robots/interface.py): every implementation is a Robot, fk(ik(T)) == T for every valid
solution, the joints a pose was made from are among its solutions, unreachable poses are data, limits hold,
and forward kinematics matches values worked out by hand from the D-H tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sprayplan.errors import ConfigError, InputError
from sprayplan.robots.gantry import Gantry, build_gantry, load_gun
from sprayplan.robots.interface import (
    ROBOT_NAMES,
    GantryRobot,
    IKSolutions,
    R5150Arm,
    Robot,
    URArm,
    nearest_turns,
    robot_from_name,
)
from sprayplan.robots.model import RobotModel, load_robot

# every implementation: (name, tool); the gantries also as six-axis views at a fixed platform
CASES = [
    ("ur5", None),
    ("ur5", "wa101"),
    ("ur5e", None),
    ("ur5-seed", "wa101"),
    ("r5150", None),
    ("gantry-ur5", None),
    ("gantry-ur5e", "wa101"),
    ("gantry-ur5@", None),
]
PLATFORM = np.array([1200.0, -300.0, 1800.0])
TRAVEL = 3000.0  # mm: the test samples gantry positions within +-TRAVEL (the gantry's own travel is unlimited)
POS_TOL = 1e-6  # mm; the round trip is exact up to rounding (about 1e-12 mm)
ROT_TOL = 1e-9  # rad


def make(name, tool):
    if name.endswith("@"):
        robot = robot_from_name(name[:-1], tool)
        return robot.at_platform(PLATFORM)
    return robot_from_name(name, tool)


def rotation_angle(r_a, r_b):
    """Angle of the rotation between two rotation stacks, accurate for small angles."""
    e = np.einsum("nji,njk->nik", r_a, r_b)
    v = np.stack([e[:, 2, 1] - e[:, 1, 2], e[:, 0, 2] - e[:, 2, 0], e[:, 1, 0] - e[:, 0, 1]], axis=1) / 2
    return np.arctan2(np.linalg.norm(v, axis=1), (np.trace(e, axis1=1, axis2=2) - 1) / 2)


def random_joints(robot, n, seed):
    limits = np.clip(robot.joint_limits, -TRAVEL, TRAVEL)
    return np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], (n, robot.dof))


def solve(robot, poses, q):
    """ik of poses made from q: the nine-axis gantry is redundant, so it is told where its platform was."""
    if isinstance(robot, GantryRobot):
        return robot.ik(poses, platform_mm=q[:, 6:])
    return robot.ik(poses)


def joint_distance(robot, a, b):
    """Largest per-axis difference, revolute axes modulo 2 pi."""
    d = np.abs(a - b)
    turned = np.abs((a - b + math.pi) % (2 * math.pi) - math.pi)
    return np.where(robot.linear_axes, d, turned).max(axis=-1)


# -------------------------------------------------------------------------------------- the protocol


@pytest.mark.parametrize("name,tool", CASES)
def test_every_implementation_is_a_robot(name, tool):
    robot = make(name, tool)
    assert isinstance(robot, Robot)
    assert isinstance(robot.name, str) and robot.name
    assert robot.joint_limits.shape == (robot.dof, 2)
    assert np.all(robot.joint_limits[:, 0] <= robot.joint_limits[:, 1])
    assert robot.linear_axes.shape == (robot.dof,) and robot.linear_axes.dtype == bool
    assert robot.base2world.shape == (4, 4) and robot.tcp2flange.shape == (4, 4)
    assert robot.fk(np.zeros(robot.dof)).shape == (1, 4, 4)
    assert robot.within_limits(np.zeros((3, robot.dof))).shape == (3,)


def test_a_bare_model_is_not_a_robot():
    assert not isinstance(load_robot("ur5"), Robot)  # a D-H table has no fk or ik of its own


def test_dof_and_linear_axes():
    assert [make(n, t).dof for n, t in CASES] == [6, 6, 6, 6, 5, 9, 9, 6]
    gantry = robot_from_name("gantry-ur5")
    assert gantry.linear_axes.tolist() == [False] * 6 + [True] * 3
    assert np.isinf(gantry.joint_limits[6:]).all()  # the seed gives no travel limits
    assert not robot_from_name("ur5").linear_axes.any()


# -------------------------------------------------------------------------------------- inverse kinematics


@pytest.mark.parametrize("name,tool", CASES)
def test_fk_of_every_valid_solution_is_the_pose(name, tool):
    robot = make(name, tool)
    q = random_joints(robot, 400, seed=1)
    poses = robot.fk(q)
    sols = solve(robot, poses, q)
    assert isinstance(sols, IKSolutions)
    assert sols.q.shape[0] == 400 and sols.q.shape[2] == robot.dof
    assert sols.valid.shape == sols.reason.shape == sols.singular.shape == sols.axis_error_rad.shape
    assert len(sols.branch_labels) == sols.q.shape[1]
    rows, cols = np.nonzero(sols.valid)
    assert len(rows) > 400  # most poses have several valid solutions
    reached = robot.fk(sols.q[rows, cols])
    assert np.linalg.norm(reached[:, :3, 3] - poses[rows, :3, 3], axis=1).max() < POS_TOL
    assert rotation_angle(reached[:, :3, :3], poses[rows, :3, :3]).max() < ROT_TOL
    assert np.all(sols.reason[sols.valid] == "")
    assert np.all(sols.reason[~sols.valid] != "")
    assert np.isfinite(sols.q).all()


@pytest.mark.parametrize("name,tool", CASES)
def test_the_original_joints_are_among_the_solutions(name, tool):
    robot = make(name, tool)
    q = random_joints(robot, 400, seed=2)
    poses = robot.fk(q)
    if isinstance(robot, R5150Arm):
        # the R5150 solver takes theta1 = atan2(py, px): joints that reach back over the base axis are not found
        radial = np.einsum("ni,ni->n", poses[:, :2, 3], np.stack([np.cos(q[:, 0]), np.sin(q[:, 0])], axis=1))
        q, poses = q[radial > 1e-6], poses[radial > 1e-6]
        assert len(q) > 250
    sols = solve(robot, poses, q)
    distance = joint_distance(robot, sols.q, q[:, None, :])
    found = (sols.valid & (distance < 1e-6)).any(axis=1)
    assert found.all(), np.flatnonzero(~found)[:5]


@pytest.mark.parametrize("name,tool", CASES)
def test_every_valid_solution_is_within_the_limits(name, tool):
    robot = make(name, tool)
    q = random_joints(robot, 300, seed=3)
    sols = solve(robot, robot.fk(q), q)
    assert robot.within_limits(sols.q[sols.valid]).all()


@pytest.mark.parametrize("name,tool", CASES)
def test_far_and_broken_poses_are_invalid_rows_not_exceptions(name, tool):
    robot = make(name, tool)
    if isinstance(robot, GantryRobot):  # with unlimited travel nothing is out of reach: give it travel
        robot = GantryRobot(robot.gantry, travel_mm=[[-TRAVEL, TRAVEL]] * 3)
    q = random_joints(robot, 2, seed=4)
    poses = np.concatenate([robot.fk(q), np.broadcast_to(np.eye(4), (3, 4, 4))])
    poses[2, :3, 3] = (1e5, 0.0, 0.0)  # 100 m away
    poses[3, :3, 3] = (0.0, -2e5, 3e4)
    poses[4, 0, 3] = np.nan
    if isinstance(robot, GantryRobot):  # the first two at their own platforms, the rest at the default one
        platform = robot.default_platform(poses)
        platform[:2] = q[:, 6:]
        sols = robot.ik(poses, platform_mm=platform)
    else:
        sols = robot.ik(poses)
    assert sols.valid[:2].any(axis=1).all()
    assert not sols.valid[2:].any()
    assert sols.reachable.tolist() == [True, True, False, False, False]
    assert set(sols.reason[2:4].ravel()) == {"out of reach"}
    assert set(sols.reason[4]) == {"non-finite pose"}
    assert sols.pose_reason().tolist() == ["", "", "out of reach", "out of reach", "non-finite pose"]
    assert np.isfinite(sols.q).all()


def test_wrongly_shaped_input_raises_input_error():
    robot = robot_from_name("ur5")
    with pytest.raises(InputError):
        robot.ik(np.eye(3))
    with pytest.raises(InputError):
        robot.fk(np.zeros(5))
    with pytest.raises(InputError):
        robot_from_name("gantry-ur5").ik(np.eye(4), platform_mm=[1.0, 2.0])


def test_ur_joint_limits_narrower_than_a_turn_move_joints_in_or_give_a_reason():
    ur5 = load_robot("ur5")
    lower, upper = ur5.lower.copy(), ur5.upper.copy()
    lower[0], upper[0] = 0.0, 2 * math.pi  # q1 only non-negative: ur_ik's (-pi, pi] needs a turn added
    lower[2], upper[2] = -0.5, 0.5  # the elbow nearly straight
    narrow = RobotModel("ur5-narrow", ur5.d, ur5.a, ur5.alpha, lower=lower, upper=upper)
    robot = URArm(narrow)
    q = random_joints(robot, 300, seed=5)
    sols = robot.ik(robot.fk(q))
    assert robot.within_limits(sols.q[sols.valid]).all()
    assert (sols.q[sols.valid][:, 0] >= 0).all()
    found = (sols.valid & (joint_distance(robot, sols.q, q[:, None, :]) < 1e-6)).any(axis=1)
    assert found.all()
    assert "joint limit" in set(sols.reason.ravel())  # the other elbow branch is out of the q3 range


def test_ik_solutions_are_read_only():
    sols = robot_from_name("ur5").ik(robot_from_name("ur5").fk(np.zeros(6)))
    with pytest.raises(ValueError):
        sols.q[0, 0, 0] = 1.0
    with pytest.raises(AttributeError):
        sols.valid = None


# -------------------------------------------------------------------------------------- the R5150's five axes


def test_r5150_reports_the_gun_axis_it_cannot_reach():
    robot = robot_from_name("r5150")
    q = np.radians([[30.0, 60.0, -80.0, 40.0, 10.0], [-50.0, 40.0, -60.0, 30.0, -100.0]])
    poses = robot.fk(q)
    # tilt the gun about the horizontal radial direction through its tip: the axis leaves the arm's plane
    tilt = 0.1
    tilted = poses.copy()
    for i, theta1 in enumerate(q[:, 0]):
        u = np.array([math.cos(theta1), math.sin(theta1), 0.0])
        k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        rot = np.eye(3) + math.sin(tilt) * k + (1 - math.cos(tilt)) * k @ k
        tilted[i, :3, :3] = rot @ poses[i, :3, :3]
    normal = np.stack([-np.sin(q[:, 0]), np.cos(q[:, 0]), np.zeros(2)], axis=1)  # of the arm plane
    expected = np.arcsin(np.abs(np.einsum("ni,ni->n", tilted[:, :3, 2], normal)))
    assert (expected > 0.01).all()

    sols = robot.ik(tilted)
    assert not sols.valid.any()
    assert all(r.startswith("gun axis off by 5.") for r in sols.reason[:, 0])  # e.g. "... by 5.12 deg"
    assert all("joint 3 limit" in r for r in sols.reason[:, 1])  # elbow down: out of joint 3's range first
    np.testing.assert_allclose(sols.axis_error_rad, np.broadcast_to(expected[:, None], (2, 2)), atol=1e-9)

    lenient = R5150Arm(axis_tol_rad=0.2)  # e.g. eq. 22's tolerance of the gantry's SQP is 5 deg
    sols = lenient.ik(tilted)
    assert sols.valid[:, 0].all()  # the elbow-up branch, within the joint ranges
    reached = lenient.fk(sols.q[:, 0])
    np.testing.assert_allclose(reached[:, :3, 3], tilted[:, :3, 3], atol=1e-9)  # the position is exact
    axis_angle = np.arccos(np.clip(np.einsum("ni,ni->n", reached[:, :3, 2], tilted[:, :3, 2]), -1, 1))
    np.testing.assert_allclose(axis_angle, expected, atol=1e-7)
    # exact poses have no axis error
    assert np.abs(robot.ik(poses).axis_error_rad).max() < 1e-9


def test_r5150_takes_no_gun():
    with pytest.raises(ConfigError, match="r5150"):
        robot_from_name("r5150", "wa101")
    assert isinstance(robot_from_name("r5150", "none"), R5150Arm)


# -------------------------------------------------------------------------------------- the gantry


def test_gantry_at_a_platform_is_the_arm_with_that_base():
    gantry = robot_from_name("gantry-ur5")
    view = gantry.at_platform(PLATFORM)
    assert isinstance(view, URArm) and view.dof == 6
    q6 = random_joints(view, 50, seed=6)
    q9 = np.concatenate([q6, np.broadcast_to(PLATFORM, (50, 3))], axis=1)
    np.testing.assert_allclose(view.fk(q6), gantry.fk(q9), atol=1e-9)
    poses = gantry.fk(q9)
    a, b = gantry.ik(poses, platform_mm=PLATFORM), view.ik(poses)
    assert (a.valid == b.valid).all()
    np.testing.assert_allclose(a.q[..., :6], b.q, atol=1e-12)
    assert (a.q[a.valid][:, 6:] == PLATFORM).all()


def test_gantry_default_platform_and_travel():
    gantry = GantryRobot(build_gantry(), travel_mm=[[-2000, 2000], [-2000, 2000], [0, 2500]])
    q = random_joints(gantry, 200, seed=7)
    poses = gantry.fk(q)
    sols = gantry.ik(poses)  # each pose's own platform beside its flange point
    platform = gantry.default_platform(poses)
    assert gantry.within_limits(np.concatenate([np.zeros((200, 6)), platform], axis=1)).all()
    rows, cols = np.nonzero(sols.valid)
    assert sols.reachable.mean() > 0.9
    np.testing.assert_allclose(sols.q[rows, cols, 6:], platform[rows])
    np.testing.assert_allclose(gantry.fk(sols.q[rows, cols]), poses[rows], atol=1e-6)
    # a platform outside the travel is data, and at_platform refuses it
    outside = gantry.ik(poses[:3], platform_mm=[0.0, 0.0, 3000.0])
    assert not outside.valid.any() and set(outside.reason.ravel()) == {"gantry travel limit"}
    with pytest.raises(ConfigError):
        gantry.at_platform([0.0, 0.0, 3000.0])


def test_build_gantry_is_the_hard_coded_gantry():
    q9 = random_joints(robot_from_name("gantry-ur5"), 20, seed=8)
    old = Gantry(robot=load_robot("ur5"), gun=load_gun("wa101"))
    np.testing.assert_allclose(build_gantry().gun2world(q9), old.gun2world(q9), atol=0)
    assert build_gantry("ur5e", "none").robot.name == "ur5e"
    with pytest.raises(ConfigError, match="ur5, ur5e"):
        build_gantry("r5150")
    with pytest.raises(ConfigError):
        build_gantry("ur5", "spraycan")


# -------------------------------------------------------------------------------------- factory and helpers


def test_factory_names_and_unknown_name():
    for name in ROBOT_NAMES:
        assert robot_from_name(name).name == name
    with pytest.raises(ConfigError) as info:
        robot_from_name("kuka")
    message = str(info.value)
    assert "\n" not in message and "kuka" in message
    assert all(name in message for name in ROBOT_NAMES)
    with pytest.raises(ConfigError):
        robot_from_name("ur5", "spraycan")


def test_nearest_turns_leaves_linear_axes_alone():
    gantry = robot_from_name("gantry-ur5")
    q = np.array([3.0, 0, 0, 0, 0, -3.0, 10.0, 20.0, 30.0])
    seed = np.array([-3.0, 0, 0, 0, 0, 3.0, 5000.0, -5000.0, 0.0])
    out = nearest_turns(gantry, q, seed)
    np.testing.assert_allclose(out, [3.0 - 2 * math.pi, 0, 0, 0, 0, 2 * math.pi - 3.0, 10.0, 20.0, 30.0])


# -------------------------------------------------------------------------------------- by hand, from the D-H tables


def test_forward_kinematics_against_values_worked_out_by_hand():
    # UR5 at q = 0: frame 1 is Rx(90) at height d1, a2 and a3 run along the base x axis, d4 and d6 along -y
    # (z1 = z3 = z5 = -y), d5 along -z (z4 = -z); the flange is rotated by Rx(90).
    rx90 = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    t = robot_from_name("ur5").fk(np.zeros(6))[0]
    np.testing.assert_allclose(t[:3, 3], [-425 - 392.25, -109.15 - 82.3, 89.159 - 94.65], atol=1e-9)
    np.testing.assert_allclose(t[:3, :3], rx90, atol=1e-12)
    # UR5 upright, q2 = -90 deg: the arm points up, x4 = -z, d5 along -x
    t = robot_from_name("ur5").fk([0, -math.pi / 2, 0, 0, 0, 0])[0]
    np.testing.assert_allclose(t[:3, 3], [-94.65, -109.15 - 82.3, 89.159 + 425 + 392.25], atol=1e-9)
    # the WA-101 gun, Trans(5.5, 94.5, 165.5) on the flange: seen from the base (Rx(90)) (5.5, -165.5, 94.5)
    t = robot_from_name("ur5", "wa101").fk(np.zeros(6))[0]
    np.testing.assert_allclose(t[:3, 3], [-817.25 + 5.5, -191.45 - 165.5, -5.491 + 94.5], atol=1e-9)
    # UR5e at q = 0
    t = robot_from_name("ur5e").fk(np.zeros(6))[0]
    np.testing.assert_allclose(t[:3, 3], [-425 - 392.2, -133.3 - 99.6, 162.5 - 99.7], atol=1e-9)
    # R5150 at q = 0: the arm stretched along x at the shoulder height, the tool d5 straight down
    t = robot_from_name("r5150").fk(np.zeros(5))[0]
    np.testing.assert_allclose(t[:3, 3], [380.0, 0.0, 255.55 - 115.0], atol=1e-9)
    np.testing.assert_allclose(t[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)
    # R5150 turned to +y with pitch 90 deg: the tool horizontal, away from the base axis
    t = robot_from_name("r5150").fk([math.pi / 2, 0, 0, math.pi / 2, 0])[0]
    np.testing.assert_allclose(t[:3, 3], [0.0, 380.0 + 115.0, 255.55], atol=1e-9)
    np.testing.assert_allclose(t[:3, 2], [0.0, 1.0, 0.0], atol=1e-12)
    # gantry at (1000, 500, 2000), arm at q = 0, WA-101: base2world = Trans(t) Rx(180); the TCP is rotated by
    # Rx(180) Rx(90) = Rx(-90), so the gun offset (5.5, 94.5, 165.5) is (5.5, 165.5, -94.5) in the world
    t = robot_from_name("gantry-ur5").fk([0, 0, 0, 0, 0, 0, 1000, 500, 2000])[0]
    np.testing.assert_allclose(t[:3, 3], [1000 - 817.25 + 5.5, 500 + 191.45 + 165.5, 2000 + 5.491 - 94.5], atol=1e-9)
    np.testing.assert_allclose(t[:3, :3], [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-12)
