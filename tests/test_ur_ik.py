"""Closed-form UR inverse kinematics (seed 000, section 4.1): fk(ik(T)) == T on every branch, special poses,
turn choice within +-2 pi, continuity along a trajectory, and the seed's table 1 against the UR5."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from sprayplan.errors import ConfigError, InputError
from sprayplan.robots.model import RobotModel, fk, load_robot
from sprayplan.robots.ur_ik import BRANCH_LABELS, ik_path, nearest_equivalent, ur_ik

UR_MODELS = ["ur5", "ur5e", "ur5-seed"]
SEED_SHIFT = np.array([0.0, math.pi, 0.0, -math.pi, 0.0, 0.0])  # ur5 q -> ur5-seed q' for the same pose


# ---------------------------------------------------------------- independent references used by the tests


def pose_errors(t_a, t_b):
    """Position distance (mm) and rotation angle (rad) between pose stacks, accurate for small angles."""
    pos = np.linalg.norm(t_a[:, :3, 3] - t_b[:, :3, 3], axis=1)
    e = np.einsum("nji,njk->nik", t_a[:, :3, :3], t_b[:, :3, :3])
    v = np.stack([e[:, 2, 1] - e[:, 1, 2], e[:, 0, 2] - e[:, 2, 0], e[:, 1, 0] - e[:, 0, 1]], axis=1) / 2
    cos = (np.trace(e, axis1=1, axis2=2) - 1) / 2
    return pos, np.arctan2(np.linalg.norm(v, axis=1), cos)


def angle_diff(a, b):
    """|a - b| modulo 2 pi, in [0, pi]."""
    return np.abs((np.asarray(a) - b + math.pi) % (2 * math.pi) - math.pi)


def check_valid_branches(model, poses, sols, pos_tol=1e-6, rot_tol=1e-9):
    """fk of every valid branch reproduces its pose."""
    rows, cols = np.nonzero(sols.valid)
    assert len(rows) > 0
    pos, rot = pose_errors(fk(model, sols.q[rows, cols]), poses[rows])
    assert pos.max() < pos_tol, pos.max()
    assert rot.max() < rot_tol, rot.max()


def arm_plane_reach(model, q):
    """Distance from the shoulder (origin of frame 1) to the origin of frame 4 in the arm plane, mm."""
    a2, a3 = model.a[1], model.a[2]
    return np.sqrt(a2 * a2 + a3 * a3 + 2 * a2 * a3 * np.cos(q[:, 2]))


def rot_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


# ---------------------------------------------------------------- forward kinematics and the models


def test_fk_known_poses():
    ur5 = load_robot("ur5")
    np.testing.assert_allclose(fk(ur5, np.zeros(6))[0, :3, 3], [-817.25, -191.45, -5.491], atol=1e-9)
    upright = fk(ur5, [0, -math.pi / 2, 0, -math.pi / 2, 0, 0])[0]
    assert upright[2, 3] == pytest.approx(1001.059, abs=1e-9)


def test_seed_table_matches_ur5_within_its_rounding():
    ur5, seed = load_robot("ur5"), load_robot("ur5-seed")
    q = np.random.default_rng(7).uniform(-2 * math.pi, 2 * math.pi, (2000, 6))
    pos, rot = pose_errors(fk(ur5, q), fk(seed, q + SEED_SHIFT))
    assert pos.max() < 0.5
    assert rot.max() < 1e-9  # rounding the lengths does not turn the flange
    # the branch bits are sign choices, so both models give the same physical solution the same branch index
    poses = fk(ur5, q)
    a, b = ur_ik(ur5, poses), ur_ik(seed, poses)
    both = a.valid & b.valid
    assert both.sum() > 0.9 * a.valid.sum()
    # away from the wrist, elbow and shoulder singularities, where the rounded lengths (< 0.05 mm) move the
    # joints but little; the branches of a pair differ there by at least 0.4 rad
    shoulder_gap = np.abs(np.sin((a.q[:, 0, 0] - a.q[:, 4, 0]) / 2))[:, None]
    well_posed = both & (np.abs(np.sin(a.q[..., 4])) > 0.2) & (np.abs(np.sin(a.q[..., 2])) > 0.2) & (shoulder_gap > 0.2)
    assert well_posed.sum() > 0.7 * both.sum()
    assert angle_diff(a.q[well_posed] + SEED_SHIFT, b.q[well_posed]).max() < 0.05


def test_non_ur_models_are_refused():
    with pytest.raises(ConfigError, match="6 joints"):
        ur_ik(load_robot("r5150"), np.eye(4))
    ur5 = load_robot("ur5")
    bad_alpha = RobotModel("bad", d=ur5.d, a=ur5.a, alpha=[math.pi / 2, 0, 0, -math.pi / 2, -math.pi / 2, 0])
    with pytest.raises(ConfigError, match="alpha"):
        ur_ik(bad_alpha, np.eye(4))
    bad_d = RobotModel("bad", d=[89.0, 10.0, 0, 109, 94, 82], a=ur5.a, alpha=ur5.alpha)
    with pytest.raises(ConfigError, match="d2, d3"):
        ur_ik(bad_d, np.eye(4))
    with pytest.raises(InputError, match="shape"):
        ur_ik(ur5, np.eye(3))


# ---------------------------------------------------------------- fk(ik(T)) == T


@pytest.mark.parametrize("name", UR_MODELS)
def test_every_valid_branch_reproduces_the_pose(name):
    model = load_robot(name)
    rng = np.random.default_rng(zlib.crc32(name.encode()))  # a seed that does not change between runs
    q = rng.uniform(-2 * math.pi, 2 * math.pi, (10_000, 6))
    poses = fk(model, q)
    sols = ur_ik(model, poses)
    assert sols.q.shape == (10_000, 8, 6) and sols.valid.shape == (10_000, 8)
    assert np.isfinite(sols.q).all()
    assert (sols.q > -math.pi).all() and (sols.q <= math.pi).all()
    check_valid_branches(model, poses, sols)
    # the generating joint vector is one of the solutions, up to whole turns
    found = ((angle_diff(sols.q, q[:, None, :]).max(axis=2) < 1e-6) & sols.valid).any(axis=1)
    assert found.mean() >= 0.999
    # elbow solutions come in pairs; well inside the workspace all eight branches reach
    counts = sols.valid.sum(axis=1)
    assert (counts % 2 == 0).all() and counts.min() >= 2
    interior = (arm_plane_reach(model, q) > 250) & (arm_plane_reach(model, q) < 600)
    assert interior.sum() > 1000
    assert (counts[interior] == 8).all()
    # the 8 branches are different solutions (no branch repeated away from singularities)
    generic = interior & ~sols.wrist_singular.any(axis=1)
    q8 = sols.q[generic]
    pair_gap = angle_diff(q8[:, :, None, :], q8[:, None, :, :]).max(axis=3) + np.eye(8) * 10
    assert pair_gap.min() > 1e-6


def test_theta_offsets_are_honoured():
    ur5 = load_robot("ur5")
    offset = np.array([0.3, -math.pi / 2, 0.2, -math.pi / 2, 0.1, -0.4])
    model = RobotModel("ur5-offset", d=ur5.d, a=ur5.a, alpha=ur5.alpha, theta_offset=offset)
    q = np.random.default_rng(3).uniform(-2 * math.pi, 2 * math.pi, (500, 6))
    poses = fk(model, q)
    sols = ur_ik(model, poses)
    check_valid_branches(model, poses, sols)
    found = ((angle_diff(sols.q, q[:, None, :]).max(axis=2) < 1e-6) & sols.valid).any(axis=1)
    assert found.mean() >= 0.99


def test_joint_limits_make_branches_invalid():
    ur5 = load_robot("ur5")
    lower = np.array([-math.pi, -math.pi, -2.0, -2 * math.pi, -math.pi / 2, -2 * math.pi])
    upper = np.array([math.pi, 0.0, 2.0, 2 * math.pi, math.pi / 2, 2 * math.pi])
    model = RobotModel("ur5-narrow", d=ur5.d, a=ur5.a, alpha=ur5.alpha, lower=lower, upper=upper)
    q = np.random.default_rng(4).uniform(lower, upper, (2000, 6))
    poses = fk(model, q)
    full, limited = ur_ik(ur5, poses), ur_ik(model, poses)
    assert not (limited.valid & ~full.valid).any()
    assert limited.valid.sum() < 0.7 * full.valid.sum()
    turned = nearest_equivalent(limited.q, 0.0, lower, upper)[limited.valid]
    assert model.within_limits(turned).all()
    # the branches found invalid have some joint with no turn inside the limits
    rejected = full.valid & ~limited.valid
    q_rej = full.q[rejected]
    fits = (
        (q_rej[:, None, :] + 2 * math.pi * np.arange(-2, 3)[:, None] >= lower - 1e-9)
        & (q_rej[:, None, :] + 2 * math.pi * np.arange(-2, 3)[:, None] <= upper + 1e-9)
    ).any(axis=1)
    assert (~fits.all(axis=1)).all()


# ---------------------------------------------------------------- special poses


@pytest.mark.parametrize("q5", [0.0, math.pi])
def test_wrist_singular_takes_q6_desired(q5):
    ur5 = load_robot("ur5")
    rng = np.random.default_rng(5)
    q = rng.uniform(-2 * math.pi, 2 * math.pi, (300, 6))
    q[:, 4] = q5
    poses = fk(ur5, q)
    sols = ur_ik(ur5, poses, q6_desired=0.7)
    check_valid_branches(ur5, poses, sols)
    flagged = sols.wrist_singular
    assert not (flagged & ~sols.valid).any()
    assert flagged.any(axis=1).all()  # the generating shoulder stays reachable whatever q6_desired
    # q6 is q6_desired, or, where the arm cannot reach the pose with it, the nearest q6 with which it can:
    # one that puts the arm at the edge of its reach (upper arm and forearm in line)
    q6_is_desired = np.abs(sols.q[..., 5] - 0.7) < 1e-12
    assert (q6_is_desired & flagged).sum() > 0.5 * flagged.sum()
    at_edge = np.abs(np.sin(sols.q[..., 2])) < 1e-6
    assert (q6_is_desired | at_edge)[flagged].all()
    # only the generating shoulder's z1 is parallel to the flange z axis: flags are per shoulder
    per_shoulder = flagged.reshape(-1, 2, 4)
    assert ((per_shoulder == per_shoulder[:, :, :1]) | ~sols.valid.reshape(-1, 2, 4)).all()
    # with q6_desired = the generating q6, the generating q itself is found
    exact = ur_ik(ur5, poses, q6_desired=q[:, 5])
    found = ((angle_diff(exact.q, q[:, None, :]).max(axis=2) < 1e-6) & exact.valid).any(axis=1)
    assert found.mean() >= 0.99


def test_wrist_centre_on_base_axis_is_out_of_reach():
    """A UR wrist centre is always |d4| away from the base z axis: on the axis no branch reaches, no NaN."""
    ur5 = load_robot("ur5")
    poses = np.repeat(np.eye(4)[None], 3, axis=0)
    poses[:, 2, 3] = [300.0, 500.0, 800.0]
    poses[:, 2, 3] += ur5.d[5]  # flange z along base z: wrist centre at (0, 0, z)
    sols = ur_ik(ur5, poses)
    assert not sols.valid.any()
    assert np.isfinite(sols.q).all() and (sols.q == 0).all()


def test_shoulder_singular_branches_coincide():
    """Wrist centre's projection at distance |d4| from the base axis: the two shoulder solutions are one."""
    ur5 = load_robot("ur5")
    rng = np.random.default_rng(6)
    q1 = rng.uniform(-math.pi, math.pi, 400)
    heights = rng.uniform(-300, 700, 400)
    z1 = np.stack([np.sin(q1), -np.cos(q1), np.zeros_like(q1)], axis=1)
    centre = ur5.d[3] * z1 + np.stack([np.zeros_like(q1), np.zeros_like(q1), heights], axis=1)
    rot = fk(ur5, rng.uniform(-math.pi, math.pi, (400, 6)))[:, :3, :3]  # any rotations
    poses = np.zeros((400, 4, 4))
    poses[:, :3, :3] = rot
    poses[:, :3, 3] = centre + ur5.d[5] * rot[:, :, 2]
    poses[:, 3, 3] = 1
    sols = ur_ik(ur5, poses)
    left, right = sols.valid[:, :4], sols.valid[:, 4:]
    np.testing.assert_array_equal(left, right)
    assert left.any(axis=1).mean() > 0.5
    np.testing.assert_allclose(angle_diff(sols.q[:, :4, 0], q1[:, None])[left], 0, atol=1e-6)
    assert angle_diff(sols.q[:, :4], sols.q[:, 4:])[left].max() < 1e-5
    check_valid_branches(ur5, poses, sols)


def test_beyond_reach_and_broken_poses_have_no_valid_branch():
    ur5 = load_robot("ur5")
    far = np.eye(4)
    far[:3, 3] = [1500.0, 300.0, 200.0]
    nan_pose = np.full((4, 4), np.nan)
    inf_pose = np.eye(4)
    inf_pose[0, 3] = np.inf
    sols = ur_ik(ur5, np.stack([far, nan_pose, inf_pose]))
    assert not sols.valid.any() and not sols.wrist_singular.any()
    assert np.isfinite(sols.q).all() and (sols.q == 0).all()
    path = ik_path(ur5, np.stack([far, nan_pose]))
    assert not path.reachable.any() and (path.branch == -1).all() and np.isfinite(path.q).all()


@pytest.mark.parametrize("name", UR_MODELS)
def test_arm_straight_elbow_branches_coincide(name):
    model = load_robot(name)
    rng = np.random.default_rng(8)
    q = rng.uniform(-math.pi, math.pi, (200, 6))
    q[:, 2] = 0.0  # upper arm and forearm in line: the boundary of the reach
    q[:, 4] = np.where(np.abs(np.sin(q[:, 4])) < 0.1, 1.0, q[:, 4])
    poses = fk(model, q)
    sols = ur_ik(model, poses)
    check_valid_branches(model, poses, sols)
    match = (angle_diff(sols.q, q[:, None, :]).max(axis=2) < 1e-6) & sols.valid
    assert match.any(axis=1).all()
    # the generating shoulder/wrist pair has both elbow branches valid and equal to the generating q
    pair = match.reshape(-1, 4, 2).any(axis=2)
    assert (pair.sum(axis=1) >= 1).all()
    both = sols.valid.reshape(-1, 4, 2)
    assert both[pair].all()
    pairs = sols.q.reshape(-1, 4, 2, 6)[pair]
    assert angle_diff(pairs[:, 0], pairs[:, 1]).max() < 1e-6
    # the other pairs still come as two (different) elbow branches or not at all
    np.testing.assert_array_equal(both[..., 0], both[..., 1])


def test_branch_labels_follow_the_sign_bits():
    assert len(BRANCH_LABELS) == 8 and len(set(BRANCH_LABELS)) == 8
    assert BRANCH_LABELS[0] == "shoulder_left/wrist_up/elbow_up"
    assert BRANCH_LABELS[7] == "shoulder_right/wrist_down/elbow_down"
    ur5 = load_robot("ur5")
    q = np.random.default_rng(9).uniform(-2 * math.pi, 2 * math.pi, (3000, 6))
    poses = fk(ur5, q)
    sols = ur_ik(ur5, poses)
    centre = poses[:, :3, 3] - ur5.d[5] * poses[:, :3, 2]  # wrist centre, origin of frame 5
    for b, label in enumerate(BRANCH_LABELS):
        ok = sols.valid[:, b] & ~sols.wrist_singular[:, b]
        q1, q3, q5 = sols.q[ok, b, 0], sols.q[ok, b, 2], sols.q[ok, b, 4]
        assert (q5 >= 0).all() if "wrist_up" in label else (q5 <= 0).all()
        assert (q3 >= 0).all() if "elbow_up" in label else (q3 <= 0).all()
        # shoulder_left: wrist centre on the -x1 side of the shoulder, x1 = (cos q1, sin q1, 0)
        side = centre[ok, 0] * np.cos(q1) + centre[ok, 1] * np.sin(q1)
        assert (side <= 1e-9).all() if "shoulder_left" in label else (side >= -1e-9).all()


# ---------------------------------------------------------------- turns within +-2 pi


def test_nearest_equivalent_picks_the_turn_within_limits():
    tau = 2 * math.pi
    lower, upper = np.full(6, -tau), np.full(6, tau)
    q = np.array([3.0, -3.0, -0.1, 0.1, -0.5, math.pi])
    seed = np.array([-3.0, 3.0, 6.0, -6.0, 0.2, -3.0])
    expected = np.array([3.0 - tau, -3.0 + tau, -0.1 + tau, 0.1 - tau, -0.5, math.pi - tau])
    np.testing.assert_allclose(nearest_equivalent(q, seed, lower, upper), expected)
    # q + 2 pi would be nearer the seed but is beyond 2 pi; the same with a narrower range
    assert nearest_equivalent(0.1, 6.2, lower[0], upper[0]) == pytest.approx(0.1)
    narrow_up = np.array([tau, tau, 6.0, tau, tau, tau])
    assert nearest_equivalent(q, seed, lower, narrow_up)[2] == pytest.approx(-0.1)
    # broadcasting: one seed for many joint vectors
    many = nearest_equivalent(np.tile(q, (4, 1)), seed, lower, upper)
    np.testing.assert_allclose(many, np.tile(expected, (4, 1)))
    # a joint whose range has no turn of q keeps q
    assert nearest_equivalent(np.array([2.0]), np.array([0.0]), np.array([-1.0]), np.array([1.0]))[0] == 2.0


def test_nearest_equivalent_matches_brute_force():
    rng = np.random.default_rng(10)
    tau = 2 * math.pi
    lower = np.array([-tau, -tau, -math.pi, -4 * math.pi, -1.0, -tau])
    upper = np.array([tau, tau, math.pi, 4 * math.pi, 5.0, tau])
    q = rng.uniform(-math.pi, math.pi, (5000, 6))
    seed = rng.uniform(-3 * tau, 3 * tau, (5000, 6))
    got = nearest_equivalent(q, seed, lower, upper)
    cands = q[..., None] + tau * np.arange(-3, 4)
    inside = (cands >= lower[:, None] - 1e-9) & (cands <= upper[:, None] + 1e-9)
    dist = np.where(inside, np.abs(cands - seed[..., None]), np.inf)
    best = np.take_along_axis(cands, dist.argmin(axis=-1)[..., None], axis=-1)[..., 0]
    best = np.where(inside.any(axis=-1), best, q)  # no turn fits: q is kept
    assert not inside.any(axis=-1).all()  # that case is exercised
    np.testing.assert_allclose(got, best, atol=1e-12)
    fits = inside.any(axis=-1)
    assert ((got >= lower - 1e-9) & (got <= upper + 1e-9))[fits].all()


# ---------------------------------------------------------------- paths


def test_straight_line_is_continuous():
    ur5 = load_robot("ur5")
    q0 = np.array([0.4, -1.3, 1.7, -1.9, -1.4, 0.6])
    start = fk(ur5, q0)[0]
    direction = np.array([0.55, 0.6, -0.58])
    direction /= np.linalg.norm(direction)
    poses = np.repeat(start[None], 200, axis=0)
    poses[:, :3, 3] += np.linspace(0, 400, 200)[:, None] * direction
    path = ik_path(ur5, poses, seed_q=q0)
    assert path.reachable.all()
    assert not path.branch_change.any() and not path.jump.any()
    assert len(set(path.branch)) == 1
    np.testing.assert_allclose(path.q[0], q0, atol=1e-9)
    assert path.max_step_rad.max() < 0.05
    pos, rot = pose_errors(fk(ur5, path.q), poses)
    assert pos.max() < 1e-6 and rot.max() < 1e-9


def test_path_choice_is_the_nearest_valid_branch():
    """Each waypoint's joint vector is the weighted-nearest turn of a valid branch; flags agree with q."""
    ur5 = load_robot("ur5")
    rng = np.random.default_rng(11)
    q = rng.uniform(-2 * math.pi, 2 * math.pi, (60, 6))
    q[1:] = q[:-1] + rng.normal(0, 0.3, (59, 6))  # a wandering path with some large moves
    poses = fk(ur5, q)
    poses[20, :3, 3] = [3000.0, 0, 0]  # out of reach
    weights = np.array([3.0, 2.0, 1.5, 1.0, 0.5, 0.2])
    seed = np.full(6, 0.5)
    path = ik_path(ur5, poses, seed_q=seed, weights=weights, jump_rad=0.4)
    assert not path.reachable[20] and path.branch[20] == -1 and (path.q[20] == 0).all()
    assert path.reachable.sum() == 59
    sols = ur_ik(ur5, poses)
    prev = seed
    prev_branch = None
    for i in np.flatnonzero(path.reachable):
        turned = nearest_equivalent(sols.q[i], prev, ur5.lower, ur5.upper)
        dist = np.where(sols.valid[i], ((turned - prev) ** 2 * weights).sum(axis=1), np.inf)
        assert ((path.q[i] - prev) ** 2 * weights).sum() == pytest.approx(dist.min(), rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(path.q[i], turned[path.branch[i]], atol=1e-12)
        step = 0.0 if prev_branch is None else np.abs(path.q[i] - prev).max()
        assert path.max_step_rad[i] == pytest.approx(step)
        assert path.jump[i] == (step > 0.4)
        assert path.branch_change[i] == (prev_branch is not None and path.branch[i] != prev_branch)
        prev, prev_branch = path.q[i], path.branch[i]
    assert path.jump.any()  # the wander does jump somewhere: the flags are not trivially False
    assert ur5.within_limits(path.q[path.reachable]).all()
    pos, rot = pose_errors(fk(ur5, path.q[path.reachable]), poses[path.reachable])
    assert pos.max() < 1e-6 and rot.max() < 1e-9


def test_path_keeps_q6_through_a_singular_wrist():
    ur5 = load_robot("ur5")
    q = np.tile(np.array([0.3, -1.2, 1.5, -1.8, 0.0, 0.0]), (30, 1))
    q[:, 0] += np.linspace(0, 0.6, 30)
    q[:, 3] += np.linspace(0, 0.9, 30)  # q4 + q6 changes; q6 alone is not determined by the poses
    poses = fk(ur5, q)
    seed = np.array([0.3, -1.2, 1.5, -1.8, 0.0, 5.5])
    path = ik_path(ur5, poses, seed_q=seed)
    assert path.reachable.all()
    np.testing.assert_allclose(path.q[:, 5], 5.5, atol=1e-12)  # the seed's q6, kept as a turn within +-2 pi
    assert not path.jump.any() and not path.branch_change.any()
    pos, rot = pose_errors(fk(ur5, path.q), poses)
    assert pos.max() < 1e-6 and rot.max() < 1e-9


def test_path_rejects_bad_options():
    ur5 = load_robot("ur5")
    poses = fk(ur5, np.zeros(6))
    with pytest.raises(ConfigError):
        ik_path(ur5, poses, seed_q=[0, 0, 0])
    with pytest.raises(ConfigError):
        ik_path(ur5, poses, weights=[1, 1, 1, 1, 1, -1])
    with pytest.raises(ConfigError):
        ik_path(ur5, poses, jump_rad=0)
