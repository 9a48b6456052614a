"""Lab-Volt R5150 of seed 001: eq. 3 and table 3 against the D-H chain, the geometric IK, tables 4 and 5."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sprayplan.errors import ConfigError, InputError
from sprayplan.robots.model import RobotModel, dh_transforms, fk, load_robot
from sprayplan.robots.r5150 import (
    check_seed_table,
    r5150_ik,
    r5150_orientation,
    r5150_position,
    table4_joints,
    table4_points,
    table5_joints,
    table5_points,
)

MODEL = load_robot("r5150")
HALF_ULP_DEG = 0.5e-4  # the tables print angles to 4 decimals: each is within this of the value it stands for


def random_q(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(MODEL.lower, MODEL.upper, size=(n, 5))


def rot_z(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(angle.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out


def front_q(elbow: str, n: int = 3000, seed: int = 7) -> np.ndarray:
    """In-range joint vectors whose tool tip is in front of the base axis, with a clear elbow branch."""
    q = random_q(n, seed)
    t3 = np.degrees(q[:, 2])
    branch = (t3 < -1.0) if elbow == "up" else (t3 > 1.0)
    p = r5150_position(q)
    r_signed = p[:, 0] * np.cos(q[:, 0]) + p[:, 1] * np.sin(q[:, 0])  # eq. 3's r, with its sign
    q = q[branch & (r_signed > 1.0)]
    assert len(q) >= 100
    return q


# ------------------------------------------------------------------------------------------------ forward


def test_eq3_equals_dh_forward_kinematics():
    q = random_q(500, seed=1)
    np.testing.assert_allclose(r5150_position(q), fk(MODEL, q)[:, :3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(r5150_position(q[0]), fk(MODEL, q[0])[:, :3, 3], rtol=0, atol=1e-9)


def test_table3_orientation_equals_dh_rotation_except_printed_ny():
    q = random_q(500, seed=2)
    rot = fk(MODEL, q)[:, :3, :3]
    np.testing.assert_allclose(r5150_orientation(q), rot, rtol=0, atol=1e-12)

    # Table 3 prints ny = s1 s234 c5 - c1 s5; the D-H product has c234 where the table has s234.
    s1, c1 = np.sin(q[:, 0]), np.cos(q[:, 0])
    t234 = q[:, 1:4].sum(axis=1)
    c5, s5 = np.cos(q[:, 4]), np.sin(q[:, 4])
    printed_ny = s1 * np.sin(t234) * c5 - c1 * s5
    corrected_ny = s1 * np.cos(t234) * c5 - c1 * s5
    np.testing.assert_allclose(rot[:, 1, 0], corrected_ny, rtol=0, atol=1e-12)
    assert np.abs(rot[:, 1, 0] - printed_ny).max() > 0.5
    printed_n = np.stack([rot[:, 0, 0], printed_ny, rot[:, 2, 0]], axis=1)
    assert np.abs(np.linalg.norm(printed_n, axis=1) - 1).max() > 0.1  # the printed n is not even a unit vector


# ------------------------------------------------------------------------------------------------ inverse


@pytest.mark.parametrize("elbow", ["up", "down"])
def test_ik_round_trip_recovers_position_pitch_roll_and_q(elbow):
    q = front_q(elbow)
    p = r5150_position(q)
    pitch = q[:, 1:4].sum(axis=1)
    roll = q[:, 4]
    sol = r5150_ik(p, pitch, roll, elbow=elbow)

    assert sol.reachable.all(), sol.reason[~sol.reachable]
    assert (sol.reason == "").all() and (sol.elbow == elbow).all()
    np.testing.assert_allclose(sol.q, q, rtol=0, atol=1e-9)

    pose = fk(MODEL, sol.q)
    np.testing.assert_allclose(pose[:, :3, 3], p, rtol=0, atol=1e-9)
    # pitch: the approach vector of the definition (0 = straight down, in the arm plane at azimuth theta1)
    t1 = np.arctan2(p[:, 1], p[:, 0])
    approach = np.stack([np.cos(t1) * np.sin(pitch), np.sin(t1) * np.sin(pitch), -np.cos(pitch)], axis=1)
    np.testing.assert_allclose(pose[:, :3, 2], approach, rtol=0, atol=1e-12)
    # roll: a turn of the roll-0 tool frame about its own z axis
    q0 = sol.q.copy()
    q0[:, 4] = 0.0
    np.testing.assert_allclose(pose[:, :3, :3], fk(MODEL, q0)[:, :3, :3] @ rot_z(roll), rtol=0, atol=1e-12)


def test_ik_moves_joints_by_whole_turns_into_range():
    # theta1 = -183 deg is in range (-185..153) but atan2 gives +177; the pitch is given a turn away, the roll
    # two turns beyond joint 5's +-360 deg
    q = np.radians([[-183.0, 60.0, -100.0, 40.0, 10.0]])
    p = r5150_position(q)
    sol = r5150_ik(p, q[0, 1:4].sum() + 2 * math.pi, q[0, 4] + 4 * math.pi)
    assert sol.reachable.all()
    np.testing.assert_allclose(sol.q, q, rtol=0, atol=1e-9)
    # a roll inside joint 5's range is kept as given, even when another turn would be nearer zero
    sol = r5150_ik(p, q[0, 1:4].sum(), math.radians(-350.0))
    np.testing.assert_allclose(sol.q[0, 4], math.radians(-350.0), rtol=0, atol=1e-12)


def test_auto_elbow_takes_down_only_where_up_fails():
    q = front_q("down", seed=11)
    p = r5150_position(q)
    pitch, roll = q[:, 1:4].sum(axis=1), q[:, 4]
    up = r5150_ik(p, pitch, roll, elbow="up")
    down = r5150_ik(p, pitch, roll, elbow="down")
    auto = r5150_ik(p, pitch, roll, elbow="auto")
    assert up.reachable.any() and not up.reachable.all()  # the sample exercises both cases
    assert auto.reachable.all()
    np.testing.assert_array_equal(auto.elbow, np.where(up.reachable, "up", "down"))
    np.testing.assert_array_equal(auto.q, np.where(up.reachable[:, None], up.q, down.q))


# ------------------------------------------------------------------------------------------------ table 4


def lever_arms(q: np.ndarray) -> np.ndarray:
    """(n, 5): distance from each joint axis to the tool tip = |d p / d theta_i| (mm per rad)."""
    links = dh_transforms(MODEL, q)
    frame = np.broadcast_to(np.eye(4), (len(q), 4, 4))
    tip = fk(MODEL, q)[:, :3, 3]
    out = np.zeros((len(q), 5))
    for i in range(5):
        axis, origin = frame[:, :3, 2], frame[:, :3, 3]
        out[:, i] = np.linalg.norm(np.cross(axis, tip - origin), axis=1)
        frame = frame @ links[:, i]
    return out


def test_table4_rows_reproduce_with_fk_within_printed_rounding():
    # Each printed angle is within HALF_ULP_DEG of the angle it stands for; moving joint i by delta moves the
    # tip by at most delta times the tip's distance from axis i (first order; the second-order term is about
    # 1e-12 mm), so a self-consistent row misses its point by at most delta * sum of the lever arms: about
    # 1e-3 mm here. The points are printed as whole millimetres, exactly.
    joints = table4_joints()
    q = np.radians(joints)
    bound = math.radians(HALF_ULP_DEG) * lever_arms(q).sum(axis=1) + 1e-9
    residual = check_seed_table(table4_points(), joints)
    assert (bound < 1.5e-3).all()
    assert (residual <= bound).all(), (residual, bound)
    assert residual.max() < 4e-4  # what the rows really give (docs/seed-notes.md: within 3e-4 mm)
    # every row has the tool straight down (pitch 0) to the printed rounding
    assert np.abs(joints[:, 1:4].sum(axis=1)).max() <= 3 * HALF_ULP_DEG + 1e-9
    # the column order matters: the printed order (q5..q1 as theta1..theta5) misses by far
    printed_order = np.column_stack(
        [joints[:, 1], joints[:, 0], table4_points()[:, 2], table4_points()[:, 1], joints[:, 4]]
    )
    assert check_seed_table(table4_points(), printed_order).min() > 10.0


def test_table4_ik_of_points_with_pitch_zero_gives_printed_joints():
    joints = table4_joints()
    sol = r5150_ik(table4_points(), 0.0, math.radians(90.0), elbow="up")
    assert sol.reachable.all()
    # The seed's joints are the exact IK of whole-millimetre points, rounded to 4 decimals: so they differ from
    # the exact solution by at most half a unit of the last printed place.
    assert np.abs(np.degrees(sol.q) - joints).max() <= HALF_ULP_DEG + 1e-9
    # the other elbow gives other joints (the table used "up")
    down = r5150_ik(table4_points(), 0.0, math.radians(90.0), elbow="down")
    assert np.abs(np.degrees(down.q[:, 2]) - joints[:, 2]).min() > 10.0


# ------------------------------------------------------------------------------------------------ table 5


def test_table5_joint_rows_do_not_reproduce_their_points():
    points, joints = table5_points(), table5_joints()
    residual = check_seed_table(points, joints)
    np.testing.assert_allclose(residual, [4.3503, 3.0245, 1.2923, 0.0481], rtol=0, atol=1e-3)
    assert (residual[:3] > 1.0).all()
    # no other assignment of the printed columns does better: X, Y, Z and q5..q1 = theta1..theta5 is the closest
    printed = np.column_stack([points, joints])
    best = min(
        (check_seed_table(printed[:, list(pc)], printed[:, list(jc)]).sum(), pc, jc)
        for pc in itertools.permutations(range(3))
        for jc in itertools.permutations(range(3, 8))
    )
    assert best[1:] == ((0, 1, 2), (3, 4, 5, 6, 7))
    # and its theta1 is not the azimuth of rows 1-3 (printed to 2 decimals: 0.005 deg would be rounding)
    azimuth = np.degrees(np.arctan2(points[:, 1], points[:, 0]))
    np.testing.assert_allclose(np.abs(joints[:, 0] - azimuth), [0.4049, 0.0610, 0.0484, 0.0011], atol=1e-3)


# ------------------------------------------------------------------------------------------------ failures


def test_unreachable_targets_are_data_with_a_reason():
    q_shoulder = np.radians([[0.0, -50.0, -20.0, 70.0, 0.0]])  # needs theta2 = -50 deg, below -32 deg
    q_base = np.radians([[170.0, 60.0, -100.0, 40.0, 0.0]])  # azimuth 170 deg: outside -185..153 both ways
    good = np.radians([[20.0, 60.0, -100.0, 40.0, 0.0]])
    targets = np.vstack(
        [
            [1000.0, 0.0, 255.55],  # beyond a2 + a3 + d5
            r5150_position(q_shoulder)[0],
            r5150_position(q_base)[0],
            [np.nan, 0.0, 300.0],
            r5150_position(good)[0],
        ]
    )
    sol = r5150_ik(targets, 0.0, 0.0)
    assert sol.reachable.tolist() == [False, False, False, False, True]
    assert sol.reason.tolist() == ["out of reach", "joint 2 limit", "joint 1 limit", "non-finite target", ""]
    assert np.isfinite(sol.q).all()
    assert (sol.q[[0, 3]] == 0).all()
    np.testing.assert_allclose(sol.q[1, 1], math.radians(-50.0), atol=1e-9)  # the offending value is kept
    np.testing.assert_allclose(sol.q[4], good[0], atol=1e-9)
    # the other elbow needs theta2 = -70 deg there: "auto" cannot help and keeps the reason
    auto = r5150_ik(targets[1], 0.0, 0.0, elbow="auto")
    assert not auto.reachable[0] and auto.reason[0] == "joint 2 limit"


def test_bad_arguments_raise():
    with pytest.raises(InputError):
        r5150_ik(np.zeros((4, 2)), 0.0, 0.0)
    with pytest.raises(InputError):
        r5150_ik(np.zeros((4, 3)), np.zeros(3), 0.0)
    with pytest.raises(ConfigError):
        r5150_ik(np.zeros(3), 0.0, 0.0, elbow="left")
    with pytest.raises(ConfigError):
        r5150_ik(np.zeros(3), 0.0, 0.0, model=load_robot("ur5"))
    with pytest.raises(InputError):
        r5150_position(np.zeros((2, 6)))


def test_solution_is_frozen_and_uses_the_given_model():
    longer = RobotModel(
        name="r5150-long",
        d=MODEL.d,
        a=[0, 250.0, 190.0, 0, 0],
        alpha=MODEL.alpha,
        lower=MODEL.lower,
        upper=MODEL.upper,
    )
    q = np.radians([[20.0, 60.0, -100.0, 40.0, 0.0]])
    p = r5150_position(q, model=longer)
    np.testing.assert_allclose(p, fk(longer, q)[:, :3, 3], atol=1e-9)
    sol = r5150_ik(p, q[0, 1:4].sum(), 0.0, model=longer)
    np.testing.assert_allclose(sol.q, q, atol=1e-9)
    with pytest.raises(ValueError):
        sol.q[0, 0] = 1.0
