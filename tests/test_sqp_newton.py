"""The SQP's Newton first try (``robots.sqp_newton``) against what it replaces (issue 17's "same plans").

- its derivatives, and the errors of eqs. 21-22 with the gradients SLSQP is given, equal central
  differences of forward kinematics (the gantry's whole eq. 8 chain);
- on problems like a stroke's (the reference one waypoint step from the tolerance), each Newton answer holds
  eqs. 21-22 and the joint limits, and costs no more on eq. 20 than SLSQP's answer to the same problem;
- along a path, Newton first gives no fewer reachable waypoints, no higher eq. 20 total, and every SQP
  waypoint within the tolerances;
- the per-waypoint analytic choice with the turn ranges computed once is the old per-waypoint
  ``nearest_equivalent`` choice, bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import sprayplan.robots.gantry as gantry_module
from sprayplan.robots.gantry import Gantry, pose_errors, solve_gantry_path, solve_sqp
from sprayplan.robots.model import fk
from sprayplan.robots.sqp_newton import _cross, chain_frames, pose_errors_first_order, second_derivative_along
from sprayplan.robots.ur_ik import nearest_equivalent, ur_ik
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Stroke

AXIS_TOL = math.radians(5.0)
H = 113.0


def _offset(gantry):
    return gantry.gun.gun2flange @ gantry.gun.target2gun


def _target_and_axis(gantry, q):
    robot = gantry.robot
    axes, origins, end = chain_frames(robot.d, robot.a, robot.alpha, robot.theta_offset, q, _offset(gantry))
    return axes, origins, end[:3, 3], end[:3, 2]


@pytest.mark.parametrize("seed", range(6))
def test_slsqps_errors_and_gradients_are_those_of_forward_kinematics(seed):
    """SLSQP's constraint values and gradients (``pose_errors_first_order``) are eqs. 21-22 computed with the
    gantry's forward kinematics (``target2world``, the whole chain with the gantry and ``Rot(x, pi)``) and
    their central differences over all nine axes."""
    gantry = Gantry()
    rng = np.random.default_rng(40 + seed)
    x = np.r_[rng.uniform(-3.0, 3.0, 6), rng.uniform(-500.0, 500.0, 3)]
    # a wanted pose a few mm and degrees from the achieved one
    achieved = gantry.target2world(x)[0]
    turn = Rotation.from_rotvec(rng.normal(size=3) * 0.05).as_matrix()
    wanted = achieved.copy()
    wanted[:3, :3] = turn @ achieved[:3, :3]
    wanted[:3, 3] += rng.normal(size=3) * 3.0
    jac_e = np.zeros((3, 9))
    jac_e[:, 6:] = np.eye(3)
    flip = np.array([1.0, -1.0, -1.0])
    first = pose_errors_first_order(gantry.robot, _offset(gantry), wanted[:3, 3], flip * wanted[:3, 2], x, jac_e)
    distance, grad_1, cos_angle, grad_2 = first[3], first[5], first[6], first[9]
    position, axis = (e[0] for e in pose_errors(gantry.target2world(x), wanted))
    assert distance == pytest.approx(position, abs=1e-9)
    assert math.acos(cos_angle) == pytest.approx(axis, abs=1e-12)
    # relative tolerance: the position error is a few mm while its gradient is ~1000 mm/rad, so the central
    # difference's own truncation error (h^2 / 6 times |de/dq|^3 / |e|^2) is ~1e-5 on a value of ~900
    h = np.array([1e-6] * 6 + [1e-4] * 3)
    for i in range(9):
        step = np.eye(9)[i] * h[i]
        plus = pose_errors(gantry.target2world(x + step), wanted)
        minus = pose_errors(gantry.target2world(x - step), wanted)
        assert grad_1[i] == pytest.approx((plus[0][0] - minus[0][0]) / (2 * h[i]), rel=1e-7, abs=1e-6)
        assert grad_2[i] == pytest.approx((plus[1][0] - minus[1][0]) / (2 * h[i]), rel=1e-7, abs=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_the_chain_and_its_derivatives_match_forward_kinematics(seed):
    gantry = Gantry()
    rng = np.random.default_rng(seed)
    q = rng.uniform(-3.0, 3.0, 6)
    axes, origins, p, z = _target_and_axis(gantry, q)
    wanted = fk(gantry.robot, q)[0] @ _offset(gantry)
    np.testing.assert_allclose(p, wanted[:3, 3], atol=1e-9)
    np.testing.assert_allclose(z, wanted[:3, 2], atol=1e-12)
    jp, jz = _cross(axes, p - origins), _cross(axes, np.broadcast_to(z, (6, 3)))
    h = 1e-6
    v = rng.normal(size=3)
    for i in range(6):
        step = np.eye(6)[i] * h
        _, _, p_plus, z_plus = _target_and_axis(gantry, q + step)
        _, _, p_minus, z_minus = _target_and_axis(gantry, q - step)
        np.testing.assert_allclose(jp[i], (p_plus - p_minus) / (2 * h), atol=1e-5)
        np.testing.assert_allclose(jz[i], (z_plus - z_minus) / (2 * h), atol=1e-8)

    # second derivatives along v: the central difference of the first derivatives along v
    def point_rows(a, o, p, z):
        return _cross(a, p - o)

    def axis_rows(a, o, p, z):
        return _cross(a, np.broadcast_to(z, (6, 3)))

    for rows_of, atol in ((point_rows, 1e-4), (axis_rows, 1e-7)):
        rows = rows_of(axes, origins, p, z)
        exact = second_derivative_along(axes, rows, v)
        numeric = np.empty((6, 6))
        for i in range(6):
            step = np.eye(6)[i] * h
            plus = rows_of(*_target_and_axis(gantry, q + step)) @ v
            minus = rows_of(*_target_and_axis(gantry, q - step)) @ v
            numeric[i] = (plus - minus) / (2 * h)
        np.testing.assert_allclose(exact, numeric, atol=atol)
        np.testing.assert_allclose(exact, exact.T)


def _cost(x, reference, k_d=0.1):
    dq, dt = x[:6] - reference[:6], x[6:] - reference[6:]
    return float(dq @ dq + k_d * dt @ dt)


def _stroke_like_problems(count, seed=3):
    """References that reach a pose exactly, and wanted poses one waypoint step (8-15 mm, 1-6 deg) away."""
    gantry = Gantry()
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        reference = np.r_[rng.uniform(-2.5, 2.5, 6), rng.uniform(-300, 300, 3)]
        achieved = gantry.target2world(reference)[0]
        direction = rng.normal(size=3)
        wanted = achieved.copy()
        wanted[:3, 3] += direction / np.linalg.norm(direction) * rng.uniform(8.0, 15.0)
        axis = rng.normal(size=3)
        angle = math.radians(rng.uniform(1.0, 6.0))
        wanted[:3, :3] = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix() @ achieved[:3, :3]
        out.append((wanted, reference))
    return gantry, out


def test_newton_answers_hold_the_tolerances_and_cost_no_more_than_slsqps():
    gantry, problems = _stroke_like_problems(40)
    answered = 0
    for wanted, reference in problems:
        newton = gantry_module._newton_try(gantry, wanted, reference, 0.1, 5.0, AXIS_TOL)
        old = solve_sqp(gantry, wanted, reference, k_d=0.1, reference_q9=reference, newton_first=False)
        if newton is None:
            continue
        answered += 1
        position, axis = pose_errors(gantry.target2world(newton.q9), wanted)
        assert position[0] <= 5.0 * (1 + 1e-9) and axis[0] <= AXIS_TOL * (1 + 1e-9)
        assert gantry.robot.within_limits(newton.q9[:6]).all()
        if old.success:
            # SLSQP may stop a hair outside the tolerance (it is checked to 1e-6), which is all it can gain
            assert _cost(newton.q9, reference) <= _cost(old.q9, reference) * (1 + 1e-6) + 1e-9
    assert answered >= 30  # the first try serves most of these problems


def _line(y: float, count: int = 41) -> Stroke:
    pts = np.column_stack([np.linspace(-400.0, 400.0, count), np.full(count, y), np.zeros(count)])
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    return Stroke(pts, normals, pts + H * normals)


def _eq20_total(path, platform, seed_q):
    previous, total = seed_q, 0.0
    for i in np.flatnonzero(path.reachable):
        if path.method[i] == "sqp":
            total += _cost(path.q9[i], np.r_[previous, platform])
        previous = path.q9[i, :6]
    return total


def test_along_a_path_newton_first_is_no_worse_than_slsqp_alone(monkeypatch):
    monkeypatch.setattr(gantry_module, "_sqp_memo", type(gantry_module._sqp_memo)())
    gantry = Gantry()
    platform = gantry.platform_beside([[0.0, 0.0, 0.0]], [0.0, 0.0])[0]  # the strokes pass the core: SQP there
    poses = np.concatenate([stroke_poses(_line(y)) for y in (0.0, 30.0, -30.0)])
    home = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0])
    new = solve_gantry_path(gantry, poses, platform, seed_q=home)
    old = solve_gantry_path(gantry, poses, platform, seed_q=home, newton_first=False)
    assert (new.method == "sqp").sum() >= 10
    assert new.reachable.sum() >= old.reachable.sum()
    sqp = new.method == "sqp"
    assert (new.position_error_mm[sqp] <= 5.0 * (1 + 1e-6)).all()
    assert (new.axis_error_deg[sqp] <= 5.0 * (1 + 1e-6)).all()
    assert _eq20_total(new, platform, home) <= _eq20_total(old, platform, home) * (1 + 1e-6) + 1e-9


def _old_analytic_choice(gantry, gun2world, platform, seed_q):
    """The loop before: every waypoint's turns by ``nearest_equivalent`` and its limits by ``within_limits``."""
    robot = gantry.robot
    solutions = ur_ik(robot, gantry.flange_targets(gun2world, platform))
    previous, out = seed_q, []
    for i in range(len(gun2world)):
        candidates = nearest_equivalent(solutions.q[i], np.broadcast_to(previous, (8, 6)), robot.lower, robot.upper)
        valid = solutions.valid[i] & robot.within_limits(candidates)
        distance = np.where(valid, np.linalg.norm(candidates - previous, axis=1), np.inf)
        previous = candidates[int(np.argmin(distance))]
        out.append(previous)
    return np.array(out)


@pytest.mark.parametrize("seed_q", [[0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0], [6.0, -6.0, 2.0, 5.5, -6.1, 6.2]])
def test_the_analytic_choice_is_the_old_one_bit_for_bit(seed_q):
    gantry = Gantry()
    platform = gantry.platform_beside([[0.0, 0.0, 0.0]], [0.0, 1.0])[0]  # half a radius aside: all analytic
    poses = np.concatenate([stroke_poses(_line(y, 61)) for y in (0.0, 40.0)])
    path = solve_gantry_path(gantry, poses, platform, seed_q=np.array(seed_q))
    assert (path.method == "analytic").all()
    np.testing.assert_array_equal(path.q9[:, :6], _old_analytic_choice(gantry, poses, platform, np.array(seed_q)))


def test_a_remembered_newton_answer_is_the_answer(monkeypatch):
    monkeypatch.setattr(gantry_module, "_sqp_memo", type(gantry_module._sqp_memo)())
    gantry, problems = _stroke_like_problems(1)
    wanted, reference = problems[0]
    options = dict(k_d=0.1, position_tol_mm=5.0, axis_tol_rad=AXIS_TOL)
    first = gantry_module.remembered_newton(gantry, wanted, reference, **options)
    again = gantry_module.remembered_newton(gantry, wanted, reference.copy(), **options)
    fresh = gantry_module._newton_try(gantry, wanted, reference, **options)
    assert first is again and first is not None
    np.testing.assert_array_equal(first.q9, fresh.q9)
    other = gantry_module.remembered_newton(gantry, wanted, reference + np.r_[np.zeros(6), 1.0, 0, 0], **options)
    assert other is not first and len(gantry_module._sqp_memo) == 2
