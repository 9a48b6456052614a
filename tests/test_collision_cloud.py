"""A point cloud's collision body (a ball about every point, ``collision.spheres``): its distances against
coal's, its default radius, the fast check against the exact distances on a real cloud, a pose known to
collide with a synthetic cloud, and the stage on a cloud plan."""

from __future__ import annotations

import math

import coal
import numpy as np
import pytest

from sprayplan.collision.bodies import CapsuleBody
from sprayplan.collision.cell import CellCollision, capsule_local_pose
from sprayplan.collision.spheres import SphereSet, boxes_to_spheres, capsules_to_spheres, cloud_radius_mm
from sprayplan.config import CollisionConfig, JobConfig
from sprayplan.errors import DataError
from sprayplan.robots.gantry import build_gantry
from sprayplan.types import Part

HOME = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0])
MOUNT_Z = 2500.0
# hanging at home the arm points straight down: the wrist-2 and wrist-3 capsules' lowest points are
# d1 + |a2| + |a3| + d5 + the wrist radius below the mount (UR5 table, robots.model)
LOWEST_AT_HOME = MOUNT_Z - (89.159 + 425.0 + 392.25 + 94.65 + 40.0)


@pytest.fixture(scope="module")
def gantry():
    return build_gantry("ur5")


def grid_cloud(z: float, half: float = 600.0, step: float = 10.0) -> Part:
    """A square grid of points in the plane z, ``step`` apart."""
    xs = np.arange(-half, half + step / 2, step)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    return Part(np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)]), np.zeros((0, 3), int), name="grid")


def _coal_capsule(segment: np.ndarray, radius: float):
    body = CapsuleBody("c", 0, tuple(segment[0]), tuple(segment[1]), radius)
    pose = capsule_local_pose(body)
    return coal.Capsule(radius, body.length_mm), coal.Transform3s(pose[:3, :3], pose[:3, 3])


def _coal_to_balls(geometry, transform, points: np.ndarray, radius: float) -> float:
    ball = coal.Sphere(radius)
    return min(
        coal.distance(
            geometry, transform, ball, coal.Transform3s(np.eye(3), p), coal.DistanceRequest(), coal.DistanceResult()
        )
        for p in points
    )


def test_distances_to_the_balls_are_coals():
    rng = np.random.default_rng(7)
    points = rng.uniform(-200.0, 200.0, (300, 3))
    balls = SphereSet.of(points, 6.0)
    segments = rng.uniform(-320.0, 320.0, (40, 2, 3))
    radii = rng.uniform(5.0, 45.0, 40)
    ours = capsules_to_spheres(balls, segments, radii)
    theirs = np.array([_coal_to_balls(*_coal_capsule(s, r), points, 6.0) for s, r in zip(segments, radii)])
    assert ((ours < 0) == (theirs < 0)).all() and (theirs < 0).any() and (theirs > 0).any()
    free = theirs > 0  # coal's penetration depth is an estimate; only its sign is relied on
    assert np.allclose(ours[free], theirs[free], atol=1e-6)
    centres = rng.uniform(-320.0, 320.0, (25, 3))
    half = rng.uniform(10.0, 90.0, (25, 3))
    ours = boxes_to_spheres(balls, centres, half)
    theirs = np.array(
        [
            _coal_to_balls(coal.Box(*(2.0 * h)), coal.Transform3s(np.eye(3), c), points, 6.0)
            for c, h in zip(centres, half)
        ]
    )
    assert ((ours < 0) == (theirs < 0)).all() and (theirs < 0).any() and (theirs > 0).any()
    assert np.allclose(ours[theirs > 0], theirs[theirs > 0], atol=1e-6)


def test_the_default_radius_holds_a_regular_scan():
    cloud = grid_cloud(0.0, half=100.0, step=10.0)
    radius = cloud_radius_mm(cloud.vertices)
    assert radius == pytest.approx(10.0 / math.sqrt(2.0))
    # every point of the scanned square lies within the radius of a scan point (the balls hold the surface)
    rng = np.random.default_rng(2)
    surface = np.column_stack([rng.uniform(-100.0, 100.0, (5000, 2)), np.zeros(5000)])
    gap, _ = SphereSet.of(cloud.vertices, radius).tree.query(surface)
    assert gap.max() <= radius + 1e-9
    with pytest.raises(DataError):
        cloud_radius_mm(np.zeros((5, 3)))


def test_a_pose_known_to_collide_with_a_cloud(gantry):
    q = np.concatenate([HOME, [0.0, 0.0, MOUNT_Z]])
    radius = 5.0
    config = CollisionConfig(cloud_radius_mm=radius)
    # the balls' tops 3 mm into the wrists at home: the wrists collide, the gun does not touch
    into = CellCollision(gantry, grid_cloud(LOWEST_AT_HOME + 3.0 - radius), config)
    found = into.distances(q)
    touching = {a for (a, b), d in zip(found.pairs, found.distance_mm[0]) if b == "part" and d < 0}
    assert touching == {"wrist_2", "wrist_3"}
    assert into.check(q).in_collision[0] and into.collides(q)[0]
    # 200 mm lower the arm is clear, with the gap known: 195 mm below the wrists' capsules
    clear = CellCollision(gantry, grid_cloud(LOWEST_AT_HOME - 200.0), config)
    found = clear.distances(q)
    part = [i for i, (_, b) in enumerate(found.pairs) if b == "part"]
    assert found.distance_mm[0, part].min() == pytest.approx(200.0 - radius, abs=1e-6)
    assert not clear.check(q).in_collision[0] and not clear.collides(q)[0]
    assert clear.floor_z_mm == pytest.approx(LOWEST_AT_HOME - 200.0 - config.floor_offset_mm)


@pytest.fixture(scope="module")
def cloud_plan(testdata):
    from sprayplan.job import run_job

    cloud = testdata / "pointclouds" / "reach_part_normals_ascii.pcd"
    job = JobConfig().replace(load={"units": "m"}, timing={"enabled": False})
    return run_job(cloud, job, until="refine")


def test_fast_check_agrees_with_every_exact_distance_on_a_real_cloud(cloud_plan, gantry):
    cell = CellCollision(gantry, cloud_plan.whole)
    assert cell.spheres is not None and cell.spheres.radius_mm == pytest.approx(
        cloud_radius_mm(cloud_plan.whole.vertices)
    )
    q9 = np.concatenate([s.q9 for s in cloud_plan.plan.stations])
    q9 = q9[np.concatenate([s.reachable for s in cloud_plan.plan.stations])]
    rng = np.random.default_rng(0)
    wild = q9[rng.integers(0, len(q9), 120)].copy()
    wild[:, :6] += rng.normal(0.0, 0.6, (len(wild), 6))
    q = np.vstack([q9[:: max(1, len(q9) // 120)], wild])
    fast = cell.check(q)
    slack = cell.distances(q).slack_mm
    truth = (slack < 0).any(axis=1)
    assert (fast.in_collision == truth).all() and (cell.collides(q) == truth).all()
    assert truth.any() and not truth.all()
    assert (fast.slack_mm <= slack.min(axis=1) + 1e-6).all()
    assert np.allclose(fast.slack_mm[fast.exact], slack.min(axis=1)[fast.exact])


def test_a_cloud_plan_is_checked_and_repaired(cloud_plan, gantry):
    import dataclasses

    from sprayplan.collision.repair import collision_stage

    # the first two strokes of the first station: enough to repair, quick to check
    st = cloud_plan.plan.stations[0]
    n = sum(len(s) for s in st.strokes[:2])
    fields = {f.name: getattr(st, f.name) for f in dataclasses.fields(st)}
    cut = {k: v[:n] if isinstance(v, np.ndarray) and v.ndim and len(v) == len(st.q9) else v for k, v in fields.items()}
    cut["strokes"] = st.strokes[:2]
    plan = dataclasses.replace(cloud_plan.plan, stations=(dataclasses.replace(st, **cut),))
    after, summary = collision_stage(plan, cloud_plan.whole, cloud_plan.job, gantry)
    assert summary["checked"] and summary["in_collision_before_repair"] > 0 and summary["repaired"] > 0
    cell = CellCollision(gantry, cloud_plan.whole)
    got = after.stations[0]
    reached = got.reachable
    assert (cell.check(got.q9[reached]).in_collision == got.collision[reached]).all()
    assert (got.repair != "").sum() == summary["repaired"]
