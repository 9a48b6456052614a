"""The refine stage's speed work keeps the same plans (issue 17): each faster computation against the one it
replaced, which is kept here as the reference.

- the reach of many gantry positions in one inverse-kinematics call (poses beyond the arm's length left out)
  equals one call a position, and the new
  stations placed from it (``stations_for_strokes``) and the touch-ups' reach (``reach_share``) are the same;
"""

from __future__ import annotations

import numpy as np
import pytest

from sprayplan.refine import added_stations
from sprayplan.refine.added_stations import _candidates, _reached, _scores, reach_share, stations_for_strokes
from sprayplan.robots.gantry import Gantry
from sprayplan.robots.ur_ik import ur_ik
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Stroke

H = 113.0


def _reference_reached(gantry: Gantry, gun2world: np.ndarray, platform: np.ndarray) -> np.ndarray:
    """(n,) bool: the reach from one position, one inverse-kinematics call (as before)."""
    solutions = ur_ik(gantry.robot, gantry.flange_targets(gun2world, platform))
    ok = np.zeros(len(gun2world), dtype=bool)
    for k in range(solutions.q.shape[1]):
        ok |= solutions.valid[:, k] & gantry.robot.within_limits(solutions.q[:, k])
    return ok


def _reference_reach_share(gantry, gun2world, platforms, height_mm=None, max_radius=1.25) -> float:
    """``reach_share`` as before: the positions one after another, stopping at a full reach."""
    platforms = np.atleast_2d(np.asarray(platforms, dtype=float)).reshape(-1, 3)
    if height_mm is not None:
        centre = (gun2world @ np.linalg.inv(gantry.gun.gun2flange))[:, :2, 3].mean(axis=0)
        rings = _candidates(centre, gantry.workspace.radius_mm, max_radius)
        platforms = np.vstack([platforms, np.column_stack([rings, np.full(len(rings), float(height_mm))])])
    best = 0.0
    for platform in platforms:
        best = max(best, float(_reference_reached(gantry, gun2world, platform).mean()))
        if best == 1.0:
            break
    return best


def _reference_scores(gantry, gun2world, height_mm, max_radius=1.25):
    """The (candidates x strokes) counts and scores of ``stations_for_strokes`` as before: one position and
    one stroke at a time."""
    radius = gantry.workspace.radius_mm
    to_flange = np.linalg.inv(gantry.gun.gun2flange)
    flange = [poses @ to_flange for poses in gun2world]
    centres = np.array([f[:, :2, 3].mean(axis=0) for f in flange])
    spans = np.array([np.linalg.norm(f[:, :2, 3] - c, axis=1).max() for f, c in zip(flange, centres)])
    candidates = np.vstack([_candidates(c, radius, max_radius) for c in centres])
    platforms = np.column_stack([candidates, np.full(len(candidates), float(height_mm))])
    counts = np.zeros((len(candidates), len(flange)))
    score = np.zeros_like(counts)
    for s, (poses, f) in enumerate(zip(gun2world, flange)):
        near = np.flatnonzero(np.linalg.norm(candidates - centres[s], axis=1) <= max_radius * radius + spans[s])
        for c in near:
            ok = _reference_reached(gantry, poses, platforms[c])
            if ok.any():
                recommended = gantry.region(f[:, :3, 3], platforms[c]) == 2
                counts[c, s] = ok.sum()
                score[c, s] = ok.sum() + 0.5 * (ok & recommended).sum()
    return counts, score


def _lips(seed: int, count: int = 6) -> list[np.ndarray]:
    """Gun poses of short strokes on surfaces facing every way round a 3 m square, some within the arm's reach
    from a station at 600 mm and some not."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        n = int(rng.integers(5, 40))
        centre = rng.uniform(-1500, 1500, 3) * [1, 1, 0.2]
        direction = rng.normal(size=3)
        normal = rng.normal(size=3)
        normal -= normal @ direction / (direction @ direction) * direction
        normal /= np.linalg.norm(normal)
        direction /= np.linalg.norm(direction)
        points = centre + np.linspace(-150, 150, n)[:, None] * direction
        normals = np.tile(normal, (n, 1))
        out.append(stroke_poses(Stroke(points, normals, points + H * normals, True, None, -1, None, "touch-up")))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_reach_of_many_positions_at_once_is_each_positions_reach(seed, monkeypatch):
    gantry = Gantry()
    rng = np.random.default_rng(seed)
    poses = np.concatenate(_lips(seed))
    platforms = np.column_stack([rng.uniform(-1500, 1500, (40, 2)), np.full(40, 600.0)])
    expected = np.array([_reference_reached(gantry, poses, p) for p in platforms])
    assert expected.any() and not expected.all()  # a test that some positions reach and some do not
    assert np.array_equal(_reached(gantry, poses, platforms), expected)
    monkeypatch.setattr(added_stations, "_POSES", 7 * len(poses) + 3)  # blocks of 7 positions
    assert np.array_equal(_reached(gantry, poses, platforms), expected)
    assert _reached(gantry, poses, np.zeros((0, 3))).shape == (0, len(poses))
    far = poses + np.pad(np.full((len(poses), 3, 1), 1e5), ((0, 0), (0, 1), (3, 0)))  # every pose out of reach
    assert not _reached(gantry, far, platforms).any()
    assert not any(_reference_reached(gantry, far, p).any() for p in platforms[:3])


@pytest.mark.parametrize("seed", [0, 3])
def test_reach_share_is_the_best_positions_share_as_before(seed):
    gantry = Gantry()
    rng = np.random.default_rng(seed)
    for poses in _lips(seed):
        stations = np.column_stack([rng.uniform(-1500, 1500, (2, 2)), np.full(2, 600.0)])
        for height in (None, 600.0):
            assert reach_share(gantry, poses, stations, height) == _reference_reach_share(
                gantry, poses, stations, height
            )


@pytest.mark.parametrize("seed", [0, 1])
def test_stations_for_strokes_scores_and_places_as_before(seed):
    gantry = Gantry()
    strokes = _lips(seed, 8)
    counts, score = _reference_scores(gantry, strokes, 600.0)
    assert counts.any()
    platforms, got_counts, got_score = _scores(gantry, strokes, 600.0, 1.25)
    assert np.array_equal(got_counts, counts) and np.array_equal(got_score, score)
    # the greedy cover over the reference scores places the same stations
    sizes = np.array([len(p) for p in strokes], dtype=float)
    useful = counts >= 0.5 * sizes
    left = np.ones(len(strokes), dtype=bool)
    expected = []
    while left.any() and len(expected) < 4:
        gain = np.where(useful & left, score, 0.0).sum(axis=1)
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        taken = np.flatnonzero(useful[best] & left)
        left[taken] = False
        expected.append((best, tuple(int(s) for s in taken), int(counts[best, taken].sum())))
    placed = stations_for_strokes(gantry, strokes, 600.0, max_stations=4)
    assert len(placed) == len(expected) >= 1
    for station, (best, taken, reached) in zip(placed, expected):
        assert np.array_equal(station.platform_mm, platforms[best])
        assert (station.strokes, station.reached) == (taken, reached)


@pytest.mark.parametrize("name", ["ur5", "ur5e", "ur5-seed"])
def test_no_joint_vector_puts_the_flange_beyond_the_arm_length(name):
    from sprayplan.robots.model import fk, load_robot

    robot = load_robot(name)
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.lower, robot.upper, (20000, 6))
    reach = np.linalg.norm(fk(robot, q)[:, :3, 3], axis=1)
    length = added_stations.arm_length_mm(robot)
    assert reach.max() <= length - 1.0
    assert reach.max() > 0.8 * (length - 1.0)  # and the bound is not loose enough to keep everything
