"""Robot models, the nine-axis gantry + UR5 (seed 000 sections 3-4), SQP fallback, and the fk / ik commands."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.errors import ConfigError, PartFileError
from sprayplan.robots.gantry import Gantry, Workspace, pose_errors, solve_gantry_path, trans
from sprayplan.robots.model import fk, fk_world, flange_target, load_robot
from sprayplan.robots.ur_ik import ur_ik


def test_fk_is_vectorised_and_matches_single_calls():
    robot = load_robot("ur5")
    q = np.random.default_rng(0).uniform(-3, 3, (50, 6))
    many = fk(robot, q)
    assert many.shape == (50, 4, 4)
    for i in (0, 17, 49):
        np.testing.assert_allclose(many[i], fk(robot, q[i])[0], atol=1e-12)
    # D-H chain by hand for one joint vector (seed 000, eq. 10)
    out = np.eye(4)
    for theta, d, a, alpha in zip(q[3], robot.d, robot.a, robot.alpha):
        link = np.array(
            [
                [np.cos(theta), -np.sin(theta) * np.cos(alpha), np.sin(theta) * np.sin(alpha), a * np.cos(theta)],
                [np.sin(theta), np.cos(theta) * np.cos(alpha), -np.cos(theta) * np.sin(alpha), a * np.sin(theta)],
                [0, np.sin(alpha), np.cos(alpha), d],
                [0, 0, 0, 1],
            ]
        )
        out = out @ link
    np.testing.assert_allclose(many[3], out, atol=1e-9)


def test_robot_from_toml_and_bad_files(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(
        'name = "my ur5"\nd_mm = [89.159, 0, 0, 109.15, 94.65, 82.3]\na_mm = [0, -425, -392.25, 0, 0, 0]\n'
        "alpha_deg = [90, 0, 0, 90, -90, 0]\nlower_deg = [-360, -360, -180, -360, -360, -360]\n"
    )
    custom, preset = load_robot(path), load_robot("ur5")
    q = np.random.default_rng(1).uniform(-3, 3, (10, 6))
    np.testing.assert_allclose(fk(custom, q), fk(preset, q), atol=1e-9)
    assert custom.lower[2] == pytest.approx(-math.pi)
    # base and tool transforms: the tool's world pose, and back to the flange target
    placed = tmp_path / "placed.toml"
    extra = "base_xyz_mm = [1000, 0, 500]\nbase_rpy_deg = [180, 0, 0]\ntool_xyz_mm = [0, 0, 200]\n"
    placed.write_text(path.read_text() + extra)
    robot = load_robot(placed)
    tool = fk_world(robot, q)
    np.testing.assert_allclose(
        tool[:, :3, 3],
        (trans(1000, 0, 500) @ np.diag([1, -1, -1, 1]) @ fk(preset, q) @ trans(0, 0, 200))[:, :3, 3],
        atol=1e-9,
    )
    np.testing.assert_allclose(flange_target(robot, tool), fk(preset, q), atol=1e-9)
    (tmp_path / "bad.toml").write_text("d_mm = [1, 2]\nspeed = 3\n")
    with pytest.raises(PartFileError, match="unknown key"):
        load_robot(tmp_path / "bad.toml")
    with pytest.raises(ConfigError):
        load_robot("kuka")


def test_workspace_cylinder_is_the_largest_of_eq13():
    space = Workspace()
    # the seed: theta = -0.54 rad, radius 727 mm, height 602 mm
    assert space.theta == pytest.approx(-0.54, abs=0.005)
    assert space.radius_mm == pytest.approx(727, abs=1.0)
    assert space.height_mm == pytest.approx(602, abs=1.0)
    # independent: the volume on a fine grid of angles is never larger than at the analytic optimum
    grid = np.linspace(-1.5, 0.5, 20001)
    volume = np.pi * (850 * np.cos(grid)) ** 2 * (163 - 850 * np.sin(grid))
    assert volume.max() <= space.volume(space.theta) * (1 + 1e-12)
    assert grid[np.argmax(volume)] == pytest.approx(space.theta, abs=1e-4)


def test_eq8_gun_pose_and_spray_target():
    gantry = Gantry()
    q9 = np.array([0.3, -1.2, 1.1, -0.5, 1.3, 0.2, 1000.0, 500.0, 1500.0])
    expected = trans(1000, 500, 1500) @ np.diag([1, -1, -1, 1]) @ fk(gantry.robot, q9[:6])[0]
    expected = expected @ trans(5.5, 94.5, 165.5) @ trans(0, 0, 113)
    np.testing.assert_allclose(gantry.target2world(q9)[0], expected, atol=1e-9)
    gun = gantry.gun2world(q9)[0]
    target = gantry.target2world(q9)[0]
    np.testing.assert_allclose(target[:3, 3], gun[:3, 3] + 113.0 * gun[:3, 2], atol=1e-9)
    # eq. 14: the flange pose that puts the gun there is the robot's own forward kinematics
    np.testing.assert_allclose(gantry.flange_targets(gun[None], q9[6:])[0], fk(gantry.robot, q9[:6])[0], atol=1e-9)


def test_workspace_regions_around_the_base_axis():
    gantry = Gantry()
    platform = np.array([0.0, 0.0, 2000.0])
    shoulder = 2000.0 - gantry.robot.d[0]
    mid = shoulder - 200.0
    points = np.array(
        [
            [0, 0, mid],
            [50, 0, mid],
            [300, 0, mid],
            [0, 700, mid],
            [800, 0, mid],
            [300, 0, shoulder + 200],
            [300, 0, shoulder - 500],
        ]
    )
    np.testing.assert_array_equal(gantry.region(points, platform), [1, 1, 2, 2, 0, 0, 0])


def line_of_gun_poses(gantry, platform, start, end, count):
    """Gun poses along a straight line, gun pointing straight down (toward -z)."""
    tcp = np.linspace(start, end, count)
    poses = np.zeros((count, 4, 4))
    poses[:, :3, :3] = np.diag([1.0, -1.0, -1.0])
    poses[:, :3, 3] = tcp
    poses[:, 3, 3] = 1
    return poses


def test_gantry_path_in_the_recommended_region_is_analytic_and_smooth():
    gantry = Gantry()
    platform = np.array([0.0, 0.0, 1500.0])
    # spray targets 113 mm below the gun, in the cylinder, 300 mm beside the base axis
    poses = line_of_gun_poses(gantry, platform, [300, -300, 1350.0], [300, 300, 1350.0], 61)
    path = solve_gantry_path(gantry, poses, platform)
    assert (path.region == 2).all() and path.reachable.all()
    assert (path.method == "analytic").all()
    assert not path.branch_change.any() and not path.jump.any()
    assert path.position_error_mm.max() < 1e-6 and path.axis_error_deg.max() < 1e-6
    np.testing.assert_allclose(path.q9[:, 6:], np.broadcast_to(platform, (61, 3)))


def test_sqp_meets_its_constraints_inside_the_core():
    gantry = Gantry()
    platform = np.array([0.0, 0.0, 1500.0])
    # the flange straight under the base axis, the non-recommended core: with the gun pointing down, the
    # flange sits at tcp + (-5.5, 94.5, 165.5) (T_tool of the WA-101 turned by Rot(x, pi))
    poses = line_of_gun_poses(gantry, platform, [5.5 - 40, -94.5 + 20, 1300.0], [5.5 + 40, -94.5 - 20, 1300.0], 9)
    path = solve_gantry_path(gantry, poses, platform)
    assert (path.region == 1).all()
    assert (path.method == "sqp").all() and path.reachable.all()
    assert path.position_error_mm.max() <= 5.0 + 1e-6
    assert path.axis_error_deg.max() <= 5.0 + 1e-6
    # the solution is what forward kinematics says it is
    achieved = gantry.target2world(path.q9)
    wanted = poses @ gantry.gun.target2gun
    position, _axis = pose_errors(achieved, wanted)
    np.testing.assert_allclose(position, path.position_error_mm, atol=1e-9)


def write_csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(f"{v:.12g}" for v in r) for r in rows) + "\n")


def test_cli_fk_then_ik_round_trip(tmp_path, capsys):
    q = np.random.default_rng(3).uniform(-2.5, 2.5, (20, 6))
    write_csv(tmp_path / "q.csv", [f"q{i}" for i in range(1, 7)], q)
    assert main(["fk", str(tmp_path / "q.csv"), "-o", str(tmp_path / "p.csv"), "--tool", "wa101"]) == 0
    assert main(["ik", str(tmp_path / "p.csv"), "-o", str(tmp_path / "back.csv"), "--tool", "wa101", "--all"]) == 0
    capsys.readouterr()
    table = np.genfromtxt(tmp_path / "back.csv", delimiter=",", names=True)
    for i in range(20):  # every generating joint vector is among the solutions of its pose (up to 2 pi)
        rows = table[table["pose"] == i + 1]
        sols = np.stack([rows[f"q{j}"] for j in range(1, 7)], axis=1)
        diff = np.angle(np.exp(1j * (sols - q[i])))
        assert np.abs(diff).max(axis=1).min() < 1e-6


def test_cli_ik_reports_unreachable_rows(tmp_path, capsys):
    write_csv(
        tmp_path / "p.csv", ["x", "y", "z", "rx", "ry", "rz"], [[300, 200, 400, 3.1, 0, 0], [5000, 0, 0, 0, 0, 0]]
    )
    assert main(["ik", str(tmp_path / "p.csv"), "-o", str(tmp_path / "q.csv")]) == 0
    assert "1 of 2 poses reachable" in capsys.readouterr().out
    lines = (tmp_path / "q.csv").read_text().splitlines()
    assert lines[0].startswith("q1,q2,q3,q4,q5,q6,reachable")
    assert lines[2].startswith(",,,,,,0")


def test_cli_ik_r5150_reproduces_the_seed_table4(tmp_path, capsys):
    from sprayplan.robots.r5150 import table4_joints

    joints = np.radians(table4_joints())
    write_csv(tmp_path / "q.csv", [f"q{i}" for i in range(1, 6)], joints)
    assert main(["fk", "--robot", "r5150", str(tmp_path / "q.csv"), "-o", str(tmp_path / "p.csv")]) == 0
    assert main(["ik", "--robot", "r5150", str(tmp_path / "p.csv"), "-o", str(tmp_path / "back.csv")]) == 0
    capsys.readouterr()
    back = np.genfromtxt(tmp_path / "back.csv", delimiter=",", skip_header=1)[:, :5]
    np.testing.assert_allclose(back, joints, atol=1e-6)


def test_cli_gantry_ik_along_paths(tmp_path, capsys):
    from sprayplan.config import PathConfig
    from sprayplan.demo import car_roof
    from sprayplan.export.paths_json import write_paths_json
    from sprayplan.paths.planner import plan_paths
    from sprayplan.surface.region import select_region

    # strokes short enough (0.9 m plus lead-in and lead-out) to fit one working cylinder each
    roof = select_region(car_roof(resolution_mm=50.0), "box(-450, -350, 1000, 450, 350, 2000)")
    paths = plan_paths(roof, PathConfig(spacing_mm=150.0, step_mm=50.0, direction="y"))
    write_paths_json(tmp_path / "paths.json", paths)
    code = main(["ik", "--robot", "gantry-ur5", str(tmp_path / "paths.json"), "-o", str(tmp_path / "j.csv")])
    assert code == 0 and "waypoints reachable" in capsys.readouterr().out
    table = np.genfromtxt(tmp_path / "j.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert len(table) == sum(len(s) for s in paths.strokes)
    assert (table["reachable"] == 1).all()
    assert np.nanmax(table["position_error_mm"]) <= 5.0 + 1e-6
    assert np.nanmax(table["axis_error_deg"]) <= 5.0 + 1e-6


def test_cli_bad_joint_file(tmp_path, capsys):
    (tmp_path / "q.csv").write_text("a,b\n1,2\n")
    assert main(["fk", str(tmp_path / "q.csv"), "-o", str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "q1" in err and not (tmp_path / "p.csv").exists()


def test_ur_ik_of_gantry_flange_targets_contains_the_joints():
    gantry = Gantry()
    q9 = np.array([0.4, -1.0, 1.4, -1.9, -1.5, 0.7, 200.0, -100.0, 1800.0])
    flange = gantry.flange_targets(gantry.gun2world(q9), q9[6:])
    solutions = ur_ik(gantry.robot, flange)
    diff = np.angle(np.exp(1j * (solutions.q[0] - q9[:6])))
    assert (np.abs(diff).max(axis=1)[solutions.valid[0]] < 1e-9).any()


def test_the_ur_elbow_stays_on_its_side_of_the_fold():
    """The UR presets limit the elbow to -pi .. pi (past it the forearm folds onto the upper arm): every joint
    vector of the demo roof's plan keeps it there (with the +-2 pi of the data sheet, 3,160 of its 14,446
    reached waypoints had the elbow past the fold); the other joints keep +-2 pi."""
    from sprayplan.config import JobConfig
    from sprayplan.demo import DEMO_REGION, car_roof
    from sprayplan.job import run_job
    from sprayplan.robots.model import load_robot

    for name in ("ur5", "ur5e", "ur5-seed"):
        robot = load_robot(name)
        np.testing.assert_allclose([robot.lower[2], robot.upper[2]], [-np.pi, np.pi])
        np.testing.assert_allclose(np.delete(robot.upper, 2), 2 * np.pi)
    plan = run_job(car_roof(), JobConfig().replace(load={"region": DEMO_REGION}), until="kinematics").plan
    q = np.concatenate([st.q9[st.reachable] for st in plan.stations])
    assert len(q) > 10000
    assert np.abs(q[:, 2]).max() <= np.pi + 1e-9
