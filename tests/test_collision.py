"""Collision checks of the cell (issue 16, part 1): distances from coal against values known by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("coal")

from sprayplan.collision.bodies import link_bodies
from sprayplan.collision.cell import CellCollision
from sprayplan.collision.settings import CollisionConfig
from sprayplan.config import JobConfig
from sprayplan.errors import ConfigError, DataError
from sprayplan.io.load import load_part
from sprayplan.robots.gantry import build_gantry
from sprayplan.robots.model import load_robot
from sprayplan.surface.region import select_region
from sprayplan.types import Part
from tests.helpers import planned

HOME = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0])
MOUNT_Z = 2500.0
# hanging at home the arm points straight down: the wrist-2 and wrist-3 capsules' lowest points are
# d1 + |a2| + |a3| + d5 + the wrist radius below the mount (UR5 table, robots.model)
LOWEST_AT_HOME = MOUNT_Z - (89.159 + 425.0 + 392.25 + 94.65 + 40.0)


def plate(z: float = 0.0, half: float = 2000.0, centre=(0.0, 0.0)) -> Part:
    x, y = centre
    vertices = np.array(
        [[x - half, y - half, z], [x + half, y - half, z], [x + half, y + half, z], [x - half, y + half, z]]
    )
    return Part(vertices, np.array([[0, 1, 2], [0, 2, 3]]), name="plate")


def q9(q6=HOME, platform=(0.0, 0.0, MOUNT_Z)) -> np.ndarray:
    return np.concatenate([q6, platform])


def pair_distance(found, a: str, b: str) -> float:
    return float(found.distance_mm[0, found.pairs.index((a, b))])


@pytest.fixture(scope="module")
def gantry():
    return build_gantry("ur5")


def test_capsule_against_floor_is_its_lowest_point_by_hand(gantry):
    cell = CellCollision(gantry, plate(0.0), CollisionConfig(floor_offset_mm=1.0))
    q = q9(HOME + np.array([0.3, 0.4, -0.5, 0.2, 0.6, 0.0]))
    found = cell.distances(q)
    segments = cell.capsule_segments(q)[0]
    for body, ends in zip(cell.capsules, segments):
        by_hand = ends[:, 2].min() - body.radius_mm - (-1.0)
        assert pair_distance(found, body.name, "floor") == pytest.approx(by_hand, abs=1e-6)
    assert pair_distance(found, "tcp", "floor") == pytest.approx(cell.tcp(q)[0, 2] + 1.0)


def test_home_far_above_a_plate_is_free_with_the_known_gap(gantry):
    cell = CellCollision(gantry, plate(0.0))
    result = cell.distances(q9())
    part = [i for i, (_, b) in enumerate(result.pairs) if b == "part"]
    assert result.distance_mm[0, part].min() == pytest.approx(LOWEST_AT_HOME, abs=1e-6)
    assert (result.slack_mm > 0).all()


def test_wrist_driven_into_the_plate_names_the_wrists(gantry):
    cell = CellCollision(gantry, plate(LOWEST_AT_HOME + 5.0))  # 5 mm into the wrists, the gun 5 mm above
    found = cell.distances(q9())
    touching = {a for (a, b), d in zip(found.pairs, found.distance_mm[0]) if b == "part" and d < 0}
    assert touching == {"wrist_2", "wrist_3"}
    column, _ = found.worst()
    assert found.pairs[column[0]][0] in touching and found.pairs[column[0]][1] == "part"


def _plate_facing_the_gun(cell, q, ahead_mm: float) -> Part:
    gun2world = cell.gantry.gun2world(q[None])[0]
    corners = np.array([[-300.0, -300.0], [300.0, -300.0], [300.0, 300.0], [-300.0, 300.0]])
    local = np.column_stack([corners, np.full(4, ahead_mm), np.ones(4)])
    return Part((gun2world @ local.T).T[:, :3], np.array([[0, 1, 2], [0, 2, 3]]), name="facing")


def test_the_spray_cone_is_free_space(gantry):
    q = q9()
    probe = CellCollision(gantry, plate(0.0))
    standoff = gantry.gun.spray_distance_mm
    cell = CellCollision(gantry, _plate_facing_the_gun(probe, q, standoff), CollisionConfig(floor_z_mm=0.0))
    found = cell.distances(q)
    # the gun's body ends at the nozzle's plane: the surface at the standoff is exactly the standoff away
    assert pair_distance(found, "gun", "part") == pytest.approx(standoff, abs=1e-6)
    assert (found.slack_mm > 0).all()
    close = CellCollision(gantry, _plate_facing_the_gun(probe, q, 10.0), CollisionConfig(floor_z_mm=0.0))
    found = close.distances(q)
    assert pair_distance(found, "gun", "part") == pytest.approx(10.0, abs=1e-6)
    column, distance = found.worst()
    assert found.pairs[column[0]] == ("gun", "part") and distance[0] == pytest.approx(10.0, abs=1e-6)


def test_floor_rule(gantry):
    # the part far aside and high; the floor 10 mm above the wrists' lowest point
    part = plate(1000.0, half=100.0, centre=(5000.0, 0.0))
    cell = CellCollision(gantry, part, CollisionConfig(floor_z_mm=LOWEST_AT_HOME + 10.0 - 1600.0))
    q = q9(platform=(0.0, 0.0, MOUNT_Z - 1600.0))
    found = cell.distances(q)
    below = {a for (a, b), d in zip(found.pairs, found.distance_mm[0]) if b == "floor" and d < 0}
    assert below == {"wrist_2", "wrist_3", "gun"}
    assert pair_distance(found, "wrist_2", "floor") == pytest.approx(-10.0, abs=1e-6)
    column, _ = found.worst()
    assert found.pairs[column[0]][1] == "floor"
    # the nozzle too: here above the floor
    assert pair_distance(found, "tcp", "floor") == pytest.approx(cell.tcp(q)[0, 2] - cell.floor_z_mm)
    with pytest.raises(ConfigError, match="collision.floor_z_mm"):
        CellCollision(gantry, part, CollisionConfig(floor_z_mm=1000.5))


def _body_points(cell, q):
    """Capsule ends pushed out by their radius along the capsule's local x and y, and the boxes' corners."""
    poses = cell.body_poses(q)
    points = []
    for k, body in enumerate(cell.capsules):
        for end in (-0.5, 0.5):
            for dx, dy in ((1, 0), (0, 1), (-1, 0), (0, -1)):
                local = np.array([dx * body.radius_mm, dy * body.radius_mm, end * body.length_mm, 1.0])
                points.append(poses[:, k] @ local)
    return np.stack(points, axis=1)[..., :3]


def test_motion_checks_are_no_further_apart_than_the_step(gantry):
    cell = CellCollision(gantry, plate(0.0), CollisionConfig(motion_step_mm=10.0))
    q_a = q9()
    q_b = q_a + np.array([0.5, -0.3, 0.4, 0.6, -0.5, 0.7, 50.0, -30.0, 20.0])
    checks = cell.motion_checks(q_a, q_b)
    assert np.allclose(checks[0], q_a) and np.allclose(checks[-1], q_b)
    moved = np.linalg.norm(np.diff(_body_points(cell, checks), axis=0), axis=-1).max()
    assert moved <= 10.0
    # far above the plate the advancement takes longer steps, never one its slack does not allow
    fractions, slacks, _, _ = cell.check_motion(q_a, q_b)
    assert fractions[0] == 0.0 and fractions[-1] == 1.0 and (slacks >= 0).all()
    path = q_a + fractions[:, None] * (q_b - q_a)
    moved = np.linalg.norm(np.diff(_body_points(cell, path), axis=0), axis=-1).max(axis=1)
    assert (moved <= np.maximum(10.0, slacks[:-1] + 5.0) + 1e-9).all()
    assert len(fractions) < len(checks)


def test_a_motion_through_the_plate_is_caught_between_clear_ends(gantry):
    # the arm swings about the shoulder through hanging straight down, where its wrists are 10 mm into the
    # plate; at both ends, 0.6 rad to either side, it is well clear
    cell = CellCollision(gantry, plate(LOWEST_AT_HOME + 10.0, half=3000.0))
    q_a, q_b = q9(HOME - [0.0, 0.6, 0, 0, 0, 0]), q9(HOME + [0.0, 0.6, 0, 0, 0, 0])
    assert (cell.distances(np.stack([q_a, q_b])).slack_mm > 0).all()
    fractions, slacks, _, pair = cell.check_motion(q_a, q_b)
    assert slacks.min() < 0 and pair[1] == "part" and 0 < fractions[-1] < 1


def test_a_real_plan_gets_one_entry_per_waypoint(testdata, gantry):
    job = JobConfig().replace(load={"units": "m", "region": "x > -250"})
    plan = planned(testdata / "meshes" / "reach_curved_part.ply", job)
    part = select_region(load_part(testdata / "meshes" / "reach_curved_part.ply", units="m"), "x > -250")
    cell = CellCollision(gantry, part)
    result = cell.check_waypoints(plan)
    n = sum(len(s.q9) for s in plan.stations)
    for name in ("station", "checked", "in_collision", "distance_mm", "body_a", "body_b", "part_distance_mm"):
        assert len(getattr(result, name)) == n
    reachable = np.concatenate([s.reachable for s in plan.stations])
    assert (result.checked == reachable).all()
    assert np.isfinite(result.distance_mm[result.checked]).all()
    assert (result.body_a[result.in_collision] != "").all()
    assert not result.in_collision[~result.checked].any()
    assert (result.station == np.concatenate([np.full(len(s.q9), i) for i, s in enumerate(plan.stations)])).all()
    again = cell.distances(np.concatenate([s.q9 for s in plan.stations])[result.checked][:5])
    # the least body distance of a fresh check is the one reported (to rounding: the two sum in other orders)
    assert np.all(again.distance_mm.min(axis=1) <= result.distance_mm[result.checked][:5] + 1e-9)


@pytest.mark.parametrize(
    "settings, key",
    [
        ({"clearance_mm": -1.0}, "collision.clearance_mm"),
        ({"clearance_mm": math.nan}, "collision.clearance_mm"),
        ({"gun_radius_mm": 0.0}, "collision.gun_radius_mm"),
        ({"floor_offset_mm": -5.0}, "collision.floor_offset_mm"),
        ({"motion_step_mm": math.inf}, "collision.motion_step_mm"),
        ({"clearance_mm": 2.0, "motion_step_mm": 10.0}, "collision.motion_step_mm"),
        ({"floor_z_mm": "low"}, "collision.floor_z_mm"),
        ({"cloud_radius_mm": 0.0}, "collision.cloud_radius_mm"),
        ({"cloud_radius_mm": math.nan}, "collision.cloud_radius_mm"),
    ],
)
def test_bad_settings_name_the_key(settings, key):
    with pytest.raises(ConfigError, match=key):
        CollisionConfig(**settings)


def test_bad_inputs(gantry):
    cloud = Part(np.zeros((3, 3)), np.zeros((0, 3), int), name="scan")  # one distinct point: no spacing
    with pytest.raises(DataError, match="point cloud"):
        CellCollision(gantry, cloud)
    with pytest.raises(ConfigError, match="link sizes"):
        link_bodies(load_robot("r5150"))
    with pytest.raises(ConfigError, match="collision.gun_radius_mm"):
        CellCollision(gantry, plate(), CollisionConfig(gun_radius_mm=200.0))
    cell = CellCollision(gantry, plate())
    with pytest.raises(DataError, match="q9"):
        cell.distances([0.0] * 8)


def test_a_clearance_override_is_checked_like_the_setting(gantry):
    cell = CellCollision(gantry, plate())
    with pytest.raises(ConfigError, match="collision.clearance_mm"):
        cell.check_motion(q9(), q9(), clearance_mm=-3.0)
    with pytest.raises(ConfigError, match="collision.motion_step_mm"):
        cell.check_motion(q9(), q9(), clearance_mm=1.0)
