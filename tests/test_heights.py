"""Station heights chosen with the collision model (``collision.heights``), on the BMW body's roof."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("coal")

from sprayplan.collision.heights import SAMPLES, SLACK, pick, raises
from sprayplan.config import CollisionConfig, JobConfig
from sprayplan.job import run_job
from sprayplan.robots.ur_ik import ur_ik
from sprayplan.surface.poses import stroke_poses

#: Part of the BMW body's roof: the seed's mid-cylinder height puts the arm's elbow into it.
ROOF = {"units": "m", "up": "y", "region": "z > 550 and x > 0 and x < 800"}


@pytest.fixture(scope="module")
def roof(testdata):
    path = testdata / "meshes" / "bmw_m6_body_m_yup.ply"
    seed = run_job(path, JobConfig().replace(load=ROOF), until="kinematics")
    chosen = run_job(path, JobConfig().replace(load=ROOF, collision={"check": True}), until="kinematics")
    return seed, chosen


def test_raises_are_the_steps_up_to_the_search():
    assert np.array_equal(
        raises(CollisionConfig(platform_search_mm=200, platform_search_step_mm=50)), [0, 50, 100, 150, 200]
    )
    assert np.array_equal(raises(CollisionConfig(platform_search_mm=120, platform_search_step_mm=50)), [0, 50, 100])
    assert np.array_equal(raises(CollisionConfig(platform_search_mm=0)), [0])


def test_pick_takes_the_lowest_height_near_the_best():
    assert pick(np.array([0.4, 0.6, 0.9, 0.91, 0.8])) == 2
    assert pick(np.array([0.4, 0.6, 0.85, 0.91, 0.8])) == 3
    assert pick(np.array([0.0, 0.0])) == 0


def test_only_the_heights_change_and_each_is_the_best_by_the_exact_check(roof):
    seed, chosen = roof
    a, b = seed.layout, chosen.layout
    assert a.index == b.index
    for pa, pb in zip(a.pieces, b.pieces, strict=True):
        assert len(pa) == len(pb) and all(np.array_equal(x.tcp, y.tcp) for x, y in zip(pa, pb))
    assert np.array_equal(a.platform_mm[:, :2], b.platform_mm[:, :2])
    raised = b.platform_mm[:, 2] - a.platform_mm[:, 2]
    summary = chosen.totals["station_heights"]
    assert np.allclose(summary["raised_mm"], raised, atol=1e-3)
    assert (raised > 0).any(), "the case must have a station the seed's height puts in collision"
    # the score again, from coal's exact check of every branch (not the yes/no screen the stage uses)
    cell, gantry, config = chosen.cell, chosen.gantry(), chosen.job.collision
    lifts = raises(config)
    for s, pieces in enumerate(a.pieces):
        poses = np.concatenate([stroke_poses(p) for p in pieces])
        poses = poses[np.unique(np.linspace(0, len(poses) - 1, min(SAMPLES, len(poses))).astype(int))]
        score = []
        for lift in lifts:
            platform = a.platform_mm[s] + [0.0, 0.0, lift]
            solutions = ur_ik(gantry.robot, gantry.flange_targets(poses, platform))
            shares = []
            for i in range(len(poses)):
                q = solutions.q[i, solutions.valid[i]]
                if not len(q):
                    shares.append(0.0)
                    continue
                q9 = np.column_stack([q, np.broadcast_to(platform, (len(q), 3))])
                shares.append(float(np.mean(~cell.check(q9).in_collision)))
            score.append(np.mean(shares))
        score = np.array(score)
        good = np.flatnonzero(score >= score.max() - SLACK)
        assert raised[s] == pytest.approx(lifts[good[0]])
        assert score[good[0]] >= score[0]


def test_the_plan_at_the_chosen_heights_hits_the_part_less(roof):
    seed, chosen = roof
    cell = chosen.cell
    hits, reached = [], []
    for state in (seed, chosen):
        q9 = np.concatenate([st.q9[st.reachable] for st in state.plan.stations])
        hits.append(int(cell.collides(q9).sum()))
        reached.append(len(q9))
    assert hits[0] > 0
    assert hits[1] <= hits[0] / 4
    assert reached[1] >= 0.9 * reached[0]  # the raise costs little reach


def test_a_set_gantry_height_is_kept(testdata):
    path = testdata / "meshes" / "bmw_m6_body_m_yup.ply"
    job = JobConfig().replace(load=ROOF, collision={"check": True}, stations={"platform_z_mm": 1400.0})
    state = run_job(path, job, until="stations")
    assert np.all(state.layout.platform_mm[:, 2] == 1400.0)
    assert "station_heights" not in state.totals and state.cell is None
