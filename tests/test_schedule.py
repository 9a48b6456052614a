"""The robots of a cell kept apart in time (cells.schedule; issue 18, section 3): segment distances against a
dense sampling, the timelines against the plan's own timing, waits only before strokes, and the gaps and
conflicts the schedule reports recounted independently."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from sprayplan.cells import load_cell
from sprayplan.cells import schedule as sched
from sprayplan.cells.plan import plan_cell
from sprayplan.config import CollisionConfig, JobConfig
from tests.helpers import grid_box

pytest.importorskip("coal")


def _dense(p1, q1, p2, q2, n=801):
    t = np.linspace(0.0, 1.0, n)[:, None]
    a = p1 + t * (q1 - p1)
    b = p2 + t * (q2 - p2)
    return cKDTree(b).query(a)[0].min()


def test_segment_distances_are_the_least_distance_of_the_two_segments():
    rng = np.random.default_rng(0)
    p1, q1, p2, q2 = (rng.uniform(-500, 500, (300, 3)) for _ in range(4))
    q2[:20] = p2[:20] + (q1[:20] - p1[:20]) * 0.7  # parallel pairs
    q1[20:30] = p1[20:30]  # a point against a segment
    q2[30:35], q1[30:35] = p2[30:35], p1[30:35]  # two points
    got = sched.segment_distances(p1, q1, p2, q2)
    for i in range(len(got)):
        length = np.linalg.norm(q1[i] - p1[i]) + np.linalg.norm(q2[i] - p2[i])
        sampled = _dense(p1[i], q1[i], p2[i], q2[i])
        assert got[i] <= sampled + 1e-9
        assert got[i] >= sampled - length / 800.0 - 1e-9


@pytest.fixture(scope="module")
def box_plan(tmp_path_factory):
    from tests.test_cell_plan import CELL, SIZE

    folder = tmp_path_factory.mktemp("sched")
    (folder / "small2.toml").write_text(CELL)
    cell = load_cell(folder / "small2.toml")
    plan = plan_cell(grid_box(n=8, size=SIZE), cell, JobConfig())
    from sprayplan.cells.collide import cell_arms

    return plan, cell_arms(cell, plan.part, CollisionConfig(check=True))


def test_the_timelines_are_the_plans_timing_with_waits_only_before_strokes(box_plan):
    plan, arms = box_plan
    tracks = [None if r.track is None else r.track.speed_mm_s for r in plan.cell.robots]
    ranges = [None if r.track is None else tuple(r.track.range_mm) for r in plan.cell.robots]
    got = sched.schedule_cell(plan.robots, arms, 400.0, 1000.0, 30.0, tracks, track_ranges=ranges)
    for k, (work, line) in enumerate(zip(plan.robots, got.timelines)):
        path = sched.waypoint_times(work, 400.0, 1000.0)
        assert path[-1] == pytest.approx(work.cycle_time_s(400.0, 1000.0), rel=1e-12)
        # no step faster than the path's speed, the arm's axis speeds and the track's speed allow
        t0 = sched.waypoint_times(work, 400.0, 1000.0, arms[k].params.max_speed, tracks[k])
        q, track = sched._held(work.q, work.track_mm, work.reachable)
        joint = (np.abs(np.diff(q, axis=0)) / arms[k].params.max_speed).max(axis=1)
        rail = np.abs(np.diff(track)) / tracks[k] if tracks[k] else np.zeros(len(q) - 1)
        np.testing.assert_allclose(np.diff(t0), np.maximum.reduce([np.diff(path), joint, rail]), atol=1e-12)
        assert (joint > np.diff(path) + 1e-9).any()  # the axis speeds do matter somewhere in this plan
        starts = np.cumsum([0] + [len(s) for s in work.strokes])[:-1]
        wait_before = np.zeros(len(t0))
        wait_before[starts] = line.wait_s
        # each waypoint is reached at its own time plus the waits before every stroke started before it
        shifted = np.r_[0.0, np.cumsum(wait_before)[:-1]]
        np.testing.assert_allclose(line.arrive_s, t0 + shifted, atol=1e-9)
        if k == 0:
            assert not line.wait_s.any()  # the first robot never waits
        # then it parks: a joint move at its axis speeds to the park configuration; the first robot at the
        # first candidate, a later one at the first candidate whose move and hold keep clear of the earlier
        # robots (every candidate before it not clear)
        ends = None if tracks[k] is None else tuple(plan.cell.robots[k].track.range_mm)
        tries = sched.park_candidates(arms[k], q[-1], float(track[-1]), _others(plan.robots, arms, k), ends, tracks[k])
        parks = list(itertools.islice(tries, sched.PARK_TRIES))
        got_park = line.at(np.array([line.end_s + 5.0]))
        index = next(
            i for i, (p, t) in enumerate(parks) if np.allclose(p, got_park[0][0]) and t == pytest.approx(got_park[1][0])
        )
        park, at = parks[index]
        if k == 0:
            assert index == 0
        else:
            done = t0[-1] + line.wait_s.sum()
            earlier = [
                sched._Sampled.of(arms[i], *got.timelines[i].at(sched._grid(0.0, got.timelines[i].end_s) * sched.DT_S))
                for i in range(k)
            ]
            horizon = max(got.timelines[i].end_s for i in range(k))

            end, there = q[-1], float(track[-1])
            clear = [
                sched._park_clear(
                    arms[k],
                    [done, done + sched._move_s(arms[k], end, p, there, t, tracks[k])],
                    [end, p],
                    [there, t],
                    earlier,
                    horizon,
                    30.0,
                )
                for p, t in parks
            ]
            assert not any(clear[:index])
            assert clear[index] or not any(clear)
        moved = float((np.abs(park - q[-1]) / arms[k].params.max_speed).max())
        rail = abs(at - track[-1]) / tracks[k] if tracks[k] else 0.0
        done = t0[-1] + line.wait_s.sum()
        assert line.end_s == pytest.approx(done + max(moved, rail, sched.MIN_PARK_S))
        np.testing.assert_allclose(line.at(np.array([line.end_s + 5.0]))[0][0], park)
        assert line.at(np.array([line.end_s + 5.0]))[1][0] == pytest.approx(at)
        assert at == pytest.approx(track[-1]) or (ends is not None and min(abs(at - e) for e in ends) < 1e-9)
        assert not arms[k].check(park[None], [at]).collides[0]
        s = np.linspace(0.0, 1.0, 200)
        along = q[-1] + s[:, None] * (park - q[-1])
        assert not arms[k].check(along, track[-1] + s * (at - track[-1])).collides.any()  # the move there is free
    assert got.cycle_time_s == pytest.approx(max(tl.end_s for tl in got.timelines))


def _others(works, arms, k):
    """The points of every robot's work but robot ``k``'s, that its park keeps away from."""
    return np.concatenate(
        [sched.work_points(arm, *sched._held(w.q, w.track_mm, w.reachable)) for i, (w, arm) in
         enumerate(zip(works, arms)) if i != k]
    )  # fmt: skip


def _sampled_points(arm, q, track):
    """Points every 2 mm along each capsule, with their radii."""
    seg = arm.segments(q, track)[0]
    points, radii = [], []
    for k, (a, b) in enumerate(seg):
        n = max(2, int(np.linalg.norm(b - a) / 2.0) + 1)
        t = np.linspace(0, 1, n)[:, None]
        points.append(a + t * (b - a))
        radii.append(np.full(n, arm.radii[k]))
    return np.concatenate(points), np.concatenate(radii)


def test_the_reported_gap_and_conflicts_are_recounted_and_waits_take_conflicts_away(box_plan, monkeypatch):
    plan, arms = box_plan
    got = sched.schedule_cell(plan.robots, arms, 400.0, 1000.0, 30.0)
    # the least gap, recounted at a few samples by points along the capsules
    a, b = got.timelines
    times = np.arange(0.0, got.cycle_time_s, 0.05)
    qa, ta = a.at(times)
    qb, tb = b.at(times)
    ends_a, ends_b = arms[0].segments(qa, ta), arms[1].segments(qb, tb)
    gaps = sched.pair_gaps(ends_a, np.asarray(arms[0].radii), ends_b, np.asarray(arms[1].radii))
    worst = np.argsort(gaps)[:5]
    for i in worst:
        pa, ra = _sampled_points(arms[0], qa[i : i + 1], ta[i : i + 1])
        pb, rb = _sampled_points(arms[1], qb[i : i + 1], tb[i : i + 1])
        d = np.linalg.norm(pa[:, None] - pb[None], axis=2) - ra[:, None] - rb[None]
        assert gaps[i] == pytest.approx(d.min(), abs=1.5)
    assert got.least_gap_mm["left-right"] == pytest.approx(float(gaps.min()), abs=0.05)
    # without waits (none allowed) the same plan has more samples in conflict
    monkeypatch.setattr(sched, "MAX_WAIT_S", 0.0)
    naive = sched.schedule_cell(plan.robots, arms, 400.0, 1000.0, 30.0)
    assert not any(tl.wait_s.any() for tl in naive.timelines)
    assert naive.conflicts["left-right"] > got.conflicts["left-right"]
    assert got.summary()["kept_apart"] == (got.conflicts["left-right"] == 0)


def _facing_works(from_the_middle: bool = False):
    """Two robots facing each other over a small box, each painting the top across the middle (from its own side,
    or ``from_the_middle``: starting 150 mm past the centre, so that the two start where the other does) and back,
    then a stroke on its own side: ``(works, arms)``."""
    from sprayplan.cells.plan import RobotWork
    from sprayplan.cells.spec import cell_from_dict
    from sprayplan.collision.arms import ArmCollision
    from sprayplan.types import Stroke

    cell = cell_from_dict(
        {
            "name": "two",
            "robot": [
                {"name": "a", "model": "abb-irb2400-10", "base_mm": [0.0, 900.0, 0.0], "base_rpy_deg": [0, 0, -90]},
                {"name": "b", "model": "abb-irb2400-10", "base_mm": [0.0, -900.0, 0.0], "base_rpy_deg": [0, 0, 90]},
            ],
        }
    )
    part = grid_box(n=4, size=(200.0, 200.0, 100.0))
    works, arms = [], []
    for k, robot in enumerate(cell.robots):
        side = 1.0 if k == 0 else -1.0
        # a stroke across the middle (y from the robot's side to 150 mm past the centre) and back, then a stroke
        # 500 mm aside on the robot's own side
        y = np.r_[np.linspace(side * 400, -side * 150, 30), np.linspace(-side * 150, side * 400, 30)]
        if from_the_middle:
            y = y[30:]
        strokes = []
        for xs, ys in ((np.zeros(len(y)), y), (np.linspace(500.0, 600.0, 10), np.full(10, side * 400.0))):
            pts = np.column_stack([xs, ys, np.full(len(ys), 700.0)])
            normals = np.tile([0.0, 0.0, 1.0], (len(ys), 1))
            strokes.append(Stroke(pts - [0, 0, 113.0], normals, pts, spray_on=True, on_part=np.ones(len(ys), bool)))
        strokes.insert(1, Stroke(
            np.stack([strokes[0].points[-1], strokes[1].points[0]]), np.stack([strokes[0].normals[-1]] * 2),
            np.stack([strokes[0].tcp[-1], strokes[1].tcp[0]]), spray_on=False, on_part=np.zeros(2, bool)))  # fmt: skip
        tcp = np.concatenate([s.tcp for s in strokes])
        normals = np.concatenate([s.normals for s in strokes])
        from sprayplan.robots.interface import follow_solutions
        from sprayplan.surface.poses import poses_at

        arm = robot.robot(0.0)
        sols = arm.ik(poses_at(tcp, normals))
        q, branch = follow_solutions(arm, sols, np.radians([0, 0, 0, 0, 30, 0]))
        assert (branch >= 0).all()
        works.append(RobotWork(robot.name, robot.model, tuple(strokes), np.array([0, -1, 0]), np.zeros(len(tcp)),
                               np.zeros(len(tcp)), q, np.ones(len(tcp), bool)))  # fmt: skip
        arms.append(ArmCollision(robot, part, -500.0))
    return works, arms


def test_a_wait_keeps_a_later_robot_out_of_an_earlier_ones_way(monkeypatch):
    """Two robots facing each other over a small box, each painting the top across the middle: the second waits
    until the first is done with the place they share, and the schedule is then free of conflicts."""
    works, arms = _facing_works()
    got = sched.schedule_cell(works, arms, 400.0, 1000.0, 30.0)
    monkeypatch.setattr(sched, "MAX_WAIT_S", 0.0)
    naive = sched.schedule_cell(works, arms, 400.0, 1000.0, 30.0)
    assert naive.conflicts["a-b"] > 0  # both at the middle at the same time
    assert got.conflicts["a-b"] == 0 and got.summary()["kept_apart"]
    first_stroke_s = works[0].cycle_time_s(400.0, 1000.0)
    assert got.timelines[1].wait_s[0] > 0  # b waits before its first stroke
    assert got.least_gap_mm["a-b"] >= 30.0  # the clearance, and more by the motion bound
    assert got.cycle_time_s > naive.cycle_time_s and got.cycle_time_s <= first_stroke_s + naive.cycle_time_s + 1.0


def test_the_robot_first_in_priority_never_waits_and_the_result_stays_in_the_robots_order():
    """The same two facing robots scheduled b first: b never waits and a does; the timelines, the waits and the
    pair keys stay in the robots' own order (a's timeline has a's waypoints), and the schedule is free of
    conflicts either way."""
    works, arms = _facing_works()
    b = works[1]  # b paints the middle stroke alone: fewer waypoints than a
    works = [works[0], replace(b, strokes=b.strokes[:1], track_mm=b.track_mm[:60], roll_deg=b.roll_deg[:60],
                               q=b.q[:60], reachable=b.reachable[:60])]  # fmt: skip
    ab = sched.schedule_cell(works, arms, 400.0, 1000.0, 30.0)
    ba = sched.schedule_cell(works, arms, 400.0, 1000.0, 30.0, priority=[1, 0])
    assert ab.summary()["priority"] == ["a", "b"] and ba.summary()["priority"] == ["b", "a"]
    assert list(ba.waits) == ["a", "b"] and list(ba.conflicts) == ["a-b"]
    for got, first, later in ((ab, 0, 1), (ba, 1, 0)):
        assert got.conflicts["a-b"] == 0
        assert got.timelines[first].wait_s.sum() == 0 and got.timelines[later].wait_s.sum() > 0
        assert [len(line.arrive_s) for line in got.timelines] == [len(w.q) for w in works]
        np.testing.assert_allclose(got.timelines[1].at(np.array([0.0]))[0][0], works[1].q[0])
    # b alone (shorter, no wait) ends sooner than a with its wait
    assert ba.timelines[1].end_s < ab.timelines[1].end_s


def test_a_robot_with_no_work_is_scheduled_idle_and_the_other_never_waits():
    """A cell robot given no area (no strokes, no waypoints) has an empty timeline and is left out of the checks
    (its pair has no gap and no conflict); the other robot's schedule is its own timing, no wait, and the cycle
    is its time."""
    works, arms = _facing_works()
    b = works[1]
    idle = replace(b, strokes=(), area=np.zeros(0, np.int64), track_mm=np.zeros(0), roll_deg=np.zeros(0),
                   q=np.zeros((0, 6)), reachable=np.zeros(0, bool))  # fmt: skip
    for order in (None, [1, 0]):
        got = sched.schedule_cell([works[0], idle], arms, 400.0, 1000.0, 30.0, priority=order)
        assert len(got.timelines[1].arrive_s) == 0 and got.timelines[1].end_s == 0.0
        assert got.timelines[0].wait_s.sum() == 0 and got.conflicts["a-b"] == 0 and got.least_gap_mm["a-b"] is None
        assert got.cycle_time_s == got.timelines[0].end_s > works[0].cycle_time_s(400.0, 1000.0) - 1e-9


def test_a_robot_that_would_meet_another_where_both_start_starts_parked():
    """Both robots start at the middle of the box: held at its first waypoint the second meets the first at time
    0 whatever it waits, so it starts parked, waits there, and the schedule is free of conflicts."""
    works, arms = _facing_works(from_the_middle=True)
    got = sched.schedule_cell(works, arms, 400.0, 1000.0, 30.0)
    assert got.conflicts["a-b"] == 0 and got.timelines[1].wait_s[0] > 0
    q, track = works[1].q, works[1].track_mm
    home, _ = sched.park_joints(arms[1], q[0], float(track[0]), _others(works, arms, 1))
    np.testing.assert_allclose(got.timelines[1].at(np.array([0.0, got.timelines[1].wait_s[0]]))[0], [home, home])
    assert len(got.timelines[1].arrive_s) == len(q) and got.timelines[1].arrive_s[0] > got.timelines[1].wait_s[0]
    np.testing.assert_allclose(got.timelines[0].at(np.array([0.0]))[0][0], works[0].q[0])  # the first does not
    # held at their first waypoints the two would be closer than the clearance
    a, b = (arm.segments(w.q[:1], w.track_mm[:1]) for arm, w in zip(arms, works))
    assert sched.pair_gaps(a, np.asarray(arms[0].radii), b, np.asarray(arms[1].radii))[0] < 30.0


def test_a_park_keeps_away_from_the_other_robots_work(box_plan):
    """With the points of another robot's work where the park farthest from the part would be, the park chosen
    is another one, farther from those points, and still free of the part."""
    plan, arms = box_plan
    work, arm = plan.robots[0], arms[0]
    q, track = sched._held(work.q, work.track_mm, work.reachable)
    alone, _ = sched.park_joints(arm, q[-1], float(track[-1]))
    ends = arm.segments(alone[None], track[-1:])[0, 3:].reshape(-1, 3)  # the forearm, wrist, flange and gun
    away = np.column_stack([ends, np.full(len(ends), 50.0)])  # another robot's capsules where this one would park
    kept, _ = sched.park_joints(arm, q[-1], float(track[-1]), away)
    assert not np.allclose(kept, alone)
    from scipy.spatial.distance import cdist

    near = cdist(arm.segments(kept[None], track[-1:])[0, 3:].reshape(-1, 3), ends).min()
    assert near > 100.0 and not arm.check(kept[None], track[-1:]).collides[0]


def test_a_park_goes_to_a_track_end_when_the_other_robots_work_is_where_the_robot_ended(box_plan):
    """With another robot's work over every park at the robot's last track position, the park chosen is at an
    end of its track, farther from that work than any park there, its move (joints and track together) free of
    the part and timed at the track's speed."""
    import itertools

    plan, arms = box_plan
    work, arm, track_cfg = plan.robots[0], arms[0], plan.cell.robots[0].track
    q, track = sched._held(work.q, work.track_mm, work.reachable)
    last = float(track[-1])
    rows = []
    for a1, a2, a3 in itertools.product(sched.PARK_AXIS1_DEG, sched.PARK_AXIS2_DEG, sched.PARK_AXIS3_DEG):
        r = q[-1].copy()
        r[:3], r[4] = np.radians([a1, a2, a3]), np.radians(30.0)
        rows.append(r)
    rows = np.array(rows)
    ends = arm.segments(rows, np.full(len(rows), last)).reshape(-1, 3)
    away = np.column_stack([ends, np.full(len(ends), 20.0)])  # another robot's capsules over every park here
    park, at = sched.park_joints(arm, q[-1], last, away, tuple(track_cfg.range_mm), track_cfg.speed_mm_s)
    assert at != last and min(abs(at - e) for e in track_cfg.range_mm) < 1e-9
    from scipy.spatial.distance import cdist

    def gap(r, t):
        return cdist(arm.segments(r[None], [t])[0].reshape(-1, 3), ends).min()

    assert gap(park, at) > max(gap(r, last) for r in rows) + 100.0
    s = np.linspace(0.0, 1.0, 400)
    assert not arm.check(q[-1] + s[:, None] * (park - q[-1]), last + s * (at - last)).collides.any()
    assert sched._move_s(arm, q[-1], park, last, at, track_cfg.speed_mm_s) >= abs(at - last) / track_cfg.speed_mm_s


@pytest.mark.parametrize("j, first", [(0, 0), (3, 0), (20, 0), (200, 1), (9, 5)])
def test_the_strokes_a_wait_is_tried_before_are_every_stroke_back_once_the_nearest_first(j, first):
    """``_backtrack``: every stroke from ``first`` to ``j`` once; ``j`` and the ``BACKTRACK`` strokes before it
    first, in order; then ``first`` among the far ones before any stroke skipped."""
    got = sched._backtrack(j, first)
    assert sorted(got) == list(range(first, j + 1))
    near = list(range(j, max(first - 1, j - sched.BACKTRACK - 1), -1))
    assert got[: len(near)] == near
    if j - first > sched.BACKTRACK:
        sparse = got[len(near) : got.index(first) + 1]
        assert all(a > b for a, b in itertools.pairwise(sparse)) and len(sparse) < j - first - sched.BACKTRACK


def test_a_later_robot_parks_where_its_move_and_hold_keep_clear_of_the_earlier_robots(box_plan):
    """``park_candidates`` and ``_park_clear``: an earlier robot standing where the later one's first park
    would put its gun makes that park not clear, and a later candidate is clear, its hold recounted here (no
    capsule of it within the clearance of the earlier robot's)."""
    plan, arms = box_plan
    work, arm = plan.robots[0], arms[0]
    q, track = sched._held(work.q, work.track_mm, work.reachable)
    parks = list(sched.park_candidates(arm, q[-1], float(track[-1])))
    first, at = parks[0]
    assert len(parks) > 2 and np.allclose(first, sched.park_joints(arm, q[-1], float(track[-1]))[0])
    done, move = 10.0, sched._move_s(arm, q[-1], first, float(track[-1]), at)
    # an "earlier robot": a ball of 60 mm standing, to 40 s, over the first park's gun
    there = arm.segments(first[None], [at])[0, -1].mean(axis=0)
    g = sched._grid(0.0, 40.0)
    centre = np.tile(there, (len(g), 1))
    segments = np.stack([centre, centre], axis=1)[:, None]  # (m, 1, 2, 3)
    radii = np.array([60.0])
    other = sched._Sampled(0, segments, radii, sched._moves(segments), centre - 60.0, centre + 60.0)
    end, rail = q[-1], float(track[-1])
    assert not sched._park_clear(arm, [done, done + move], [end, first], [rail, at], [other], 40.0, 30.0)
    clear = [
        sched._park_clear(
            arm, [done, done + sched._move_s(arm, end, p, rail, t)], [end, p], [rail, t], [other], 40.0, 30.0
        )
        for p, t in parks[1:]
    ]
    assert any(clear)
    chosen, chosen_at = parks[1 + clear.index(True)]
    # recounted: the chosen park, and 400 configurations along the move there, keep the clearance from the ball
    s_ = np.linspace(0.0, 1.0, 400)
    joints = q[-1] + s_[:, None] * (chosen - q[-1])
    caps = arm.segments(joints, float(track[-1]) + s_ * (chosen_at - float(track[-1])))  # (400, b, 2, 3)
    ball = np.broadcast_to(there, caps[:, :, 0].shape)
    gaps = sched.segment_distances(caps[:, :, 0], caps[:, :, 1], ball, ball) - np.asarray(arm.radii, float) - 60.0
    assert gaps.min() >= 30.0
    # and the first park, held, does not
    caps = arm.segments(first[None], [at])[0]
    ball = np.broadcast_to(there, caps[:, 0].shape)
    assert (
        sched.segment_distances(caps[:, 0], caps[:, 1], ball, ball) - np.asarray(arm.radii, float) - 60.0
    ).min() < 30.0


def _drawn_back(dq2: float, seconds: float):
    """A stand-in for the programs' back-off (``cells.timing.program_back_offs``): axis 2 turned back by
    ``dq2`` rad, taking ``seconds``; the axes it was given are kept to check the calls."""
    asked = []

    def back(axes):
        asked.append(np.array(axes, float))
        moved = np.array(axes, float)
        moved[1] -= dq2
        return moved, seconds

    return back, asked


def test_a_robot_retracts_before_it_parks_and_its_park_is_chosen_from_the_retract(box_plan):
    """With the programs' back-offs (``backs``), each robot's timeline ends with the retract from its last
    waypoint (a knot at the backed-off joints, the back-off's seconds after the work is done), then the park
    move from there: the park is the first of ``park_candidates`` from the backed-off joints whose move is
    clear (the first robot: the first of them), its time from there, the move from there free of the part. A
    program makes that move (``programs.build``: the retract, then the joint move to the park); the schedule
    chose the park by the move from the last waypoint before, which the programs never make."""
    plan, arms = box_plan
    tracks = [None if r.track is None else r.track.speed_mm_s for r in plan.cell.robots]
    ranges = [None if r.track is None else tuple(r.track.range_mm) for r in plan.cell.robots]
    backs = [_drawn_back(0.15, 1.25) for _ in plan.robots]
    got = sched.schedule_cell(
        plan.robots,
        arms,
        400.0,
        1000.0,
        30.0,
        tracks,
        track_ranges=ranges,
        priority=[0, 1],
        backs=[b for b, _ in backs],
    )
    plain = sched.schedule_cell(plan.robots, arms, 400.0, 1000.0, 30.0, tracks, track_ranges=ranges, priority=[0, 1])
    for k, (work, line) in enumerate(zip(plan.robots, got.timelines)):
        q, track = sched._held(work.q, work.track_mm, work.reachable)
        last = q[-1].copy()
        last[1] -= 0.15
        assert any(np.allclose(a, np.r_[q[-1], track[-1]]) for a in backs[k][1])  # asked at the last waypoint
        done = float(line.arrive_s[-1])
        np.testing.assert_allclose(line.knot_q[-2], last, atol=1e-12)
        assert line.knot_t[-2] == pytest.approx(done + 1.25)
        park, at = line.knot_q[-1], float(line.knot_track[-1])
        if k == 0:
            first, where = next(sched.park_candidates(arms[0], last, float(track[-1]), _others(plan.robots, arms, 0),
                                                      ranges[0], tracks[0]))  # fmt: skip
            np.testing.assert_allclose(park, first)
            assert at == pytest.approx(where)
        move = sched._move_s(arms[k], last, park, float(track[-1]), at, tracks[k])
        assert line.end_s == pytest.approx(done + 1.25 + move)
        s = np.linspace(0.0, 1.0, 200)
        assert not arms[k].check(last + s[:, None] * (park - last), track[-1] + s * (at - track[-1])).collides.any()
        # the same work otherwise: the waypoints' times are the plain schedule's
        np.testing.assert_allclose(line.arrive_s, plain.timelines[k].arrive_s, atol=1e-9)


def test_a_robot_that_starts_parked_comes_in_to_its_first_approach_pose():
    """With the programs' back-offs, a robot that starts parked has its park chosen for the move to the
    approach pose of its first waypoint (the backed-off joints), and reaches its first waypoint the move's
    time plus the approach's after the wait (the program: park, joint move to the approach pose, approach)."""
    works, arms = _facing_works(from_the_middle=True)
    back, asked = _drawn_back(0.2, 0.75)
    got = sched.schedule_cell(works, arms, 400.0, 1000.0, 30.0, backs=[None, back])
    q, track = works[1].q, works[1].track_mm
    entry = q[0].copy()
    entry[1] -= 0.2
    assert any(np.allclose(a, np.r_[q[0], track[0]]) for a in asked)
    home, _ = sched.park_joints(arms[1], entry, float(track[0]), _others(works, arms, 1))
    line = got.timelines[1]
    np.testing.assert_allclose(line.knot_q[0], home)
    assert got.conflicts["a-b"] == 0 and line.wait_s[0] > 0
    assert line.arrive_s[0] == pytest.approx(line.wait_s[0] + sched._move_s(arms[1], home, entry) + 0.75)


class _StubRouter:
    """Stands in for ``cells.routes.CellRouter`` in the schedule: one node, half way between the retract and
    the park, for every park asked about."""

    def __init__(self):
        self.asked = []

    def park_route(self, q_a, t_a, park, t_park, seed=0):
        self.asked.append((np.array(q_a), float(t_a), np.array(park), float(t_park)))
        return "stub", ((np.asarray(q_a) + np.asarray(park)) / 2)[None], np.r_[(t_a + t_park) / 2]


def test_a_park_no_joint_move_reaches_free_is_reached_through_a_route(box_plan, monkeypatch):
    """Where the joint move from the end of a robot's work to its park is not free (``move_free``, here made
    to say so), the robot goes there through the route its router gives: the node is a row of its timeline,
    each leg a joint move at the axis speeds, and the node is what ``Timeline.park_route_q`` hands to the
    programs; where the move is free, no route is asked for."""
    plan, arms = box_plan
    tracks = [None if r.track is None else r.track.speed_mm_s for r in plan.cell.robots]
    ranges = [None if r.track is None else tuple(r.track.range_mm) for r in plan.cell.robots]
    routers = [_StubRouter(), _StubRouter()]
    monkeypatch.setattr(sched, "move_free", lambda arm, *args: arm is not arms[1])
    got = sched.schedule_cell(
        plan.robots, arms, 400.0, 1000.0, 30.0, tracks, track_ranges=ranges, priority=[0, 1], routers=routers
    )
    assert not routers[0].asked and got.timelines[0].park_route_q is None
    (q_a, t_a, park, t_park), *_ = routers[1].asked
    line = got.timelines[1]
    node = (q_a + park) / 2
    np.testing.assert_allclose(line.park_route_q, node[None])
    np.testing.assert_allclose(line.knot_q[-2:], [node, park])
    assert line.knot_track[-1] == pytest.approx(t_park)
    done = float(line.arrive_s[-1])
    legs = sched._move_s(arms[1], q_a, node, t_a, (t_a + t_park) / 2, tracks[1]) + sched._move_s(
        arms[1], node, park, (t_a + t_park) / 2, t_park, tracks[1]
    )
    assert line.end_s == pytest.approx(done + legs)
    assert line.knot_t[-2] == pytest.approx(
        done + sched._move_s(arms[1], q_a, node, t_a, (t_a + t_park) / 2, tracks[1])
    )


def test_a_move_is_free_when_no_sample_at_the_programs_step_collides(box_plan):
    """``move_free`` samples a joint move as the programs' check does (``programs.arms.MOTION_STEP_RAD``): a
    move through a configuration in collision is not free, one that stays where the work ended is."""
    from sprayplan.programs.arms import MOTION_STEP_RAD

    assert sched.MOVE_STEP_RAD == MOTION_STEP_RAD
    plan, arms = box_plan
    work, arm = plan.robots[0], arms[0]
    q, track = sched._held(work.q, work.track_mm, work.reachable)
    t = float(track[-1])
    assert sched.move_free(arm, q[-1], q[-1], t, t)
    # the shoulder turned forward, step by step, until the arm is in the box: the move there is not free
    hit = q[-1].copy()
    while not arm.collides(hit[None], [t])[0]:
        hit[1] += 0.05
        assert hit[1] < arm.params.upper[1]
    assert not sched.move_free(arm, q[-1], hit, t, t)
    park, at = sched.park_joints(arm, q[-1], float(track[-1]))
    assert sched.move_free(arm, q[-1], park, float(track[-1]), at) == (
        not arm.collides(
            q[-1] + np.linspace(0, 1, 2001)[:, None] * (park - q[-1]), np.full(2001, float(track[-1]))
        ).any()
    )


def _passing_ball(centre, far, t_in: float, t_out: float, end_s: float, radius: float = 60.0):
    """An "earlier robot" (``_Sampled``, grid samples from 0 to ``end_s``): a ball of ``radius`` mm that stands
    at ``far``, comes in to ``centre`` at 1 m/s to be there from ``t_in`` to ``t_out``, and goes back."""
    g = sched._grid(0.0, end_s)
    t = g * sched.DT_S
    travel = float(np.linalg.norm(np.asarray(far) - centre)) / 1000.0
    share = np.clip(np.minimum((t - (t_in - travel)) / travel, ((t_out + travel) - t) / travel), 0.0, 1.0)
    points = np.asarray(far)[None] + share[:, None] * (np.asarray(centre) - far)[None]
    segments = np.stack([points, points], axis=1)[:, None]  # (m, 1, 2, 3)
    return sched._Sampled(0, segments, np.array([radius]), sched._moves(segments), points - radius, points + radius)


def test_a_park_way_an_earlier_robot_crosses_is_freed_by_a_wait_before_the_last_stroke(box_plan):
    """``_end_wait``: an earlier robot passing through the way to the park just as the work ends (a ball there
    from 1 s before to 3 s after) leaves no park clear at once (``_park_clear``); a wait before the last
    stroke frees the stroke, the way and the hold together: with it the last stroke and the way keep the
    clearance from the ball, recounted every 0.01 s with the ball where it is between its samples, and a wait
    one step shorter is not clear."""
    plan, arms = box_plan
    work, arm = plan.robots[0], arms[0]
    q, track = sched._held(work.q, work.track_mm, work.reachable)
    t0 = sched.waypoint_times(work, 400.0, 1000.0, arm.params.max_speed)
    starts = np.cumsum([0] + [len(s) for s in work.strokes])[:-1]
    chosen = np.zeros(len(starts))
    park, at = sched.park_joints(arm, q[-1], float(track[-1]))
    way = sched._park_way(arm, q[-1], float(track[-1]), None, park, at, None, None)
    offsets, way_q, way_track, route = way
    assert route is None and len(offsets) == 1
    np.testing.assert_allclose(way_q[-1], park)
    assert offsets[-1] == pytest.approx(sched._move_s(arm, q[-1], park, float(track[-1]), at))
    done = float(t0[-1])
    middle = arm.segments(((q[-1] + park) / 2)[None], [(float(track[-1]) + at) / 2])[0, -1].mean(axis=0)
    ball = _passing_ball(middle, middle + [0.0, 0.0, 2500.0], done - 1.0, done + 3.0, done + 40.0)
    knots = sched._way_knots(done, q[-1], float(track[-1]), way)
    assert not sched._park_clear(arm, *knots, [ball], done + 40.0, 30.0)
    found = sched._end_wait(arm, t0, q, track, starts, chosen, way, done + 40.0, [ball], 30.0)
    assert found is not None
    first, wait = found
    assert first == len(starts) - 1 and wait > 0
    assert (wait / sched.WAIT_STEP_S) == pytest.approx(round(wait / sched.WAIT_STEP_S))
    # recounted: the last stroke and the way after the wait, sampled finely, keep the clearance from the ball
    times = np.r_[t0[starts[first] :], done + offsets] + wait
    joints = np.vstack([q[starts[first] :], way_q])
    rails = np.r_[track[starts[first] :], way_track]
    fine = np.arange(times[0], times[-1], 0.01)
    caps = arm.segments(*sched._configs(fine, times, joints, rails))
    # the ball between its samples where it is, linear as it moves (its grid starts at 0)
    grid = np.arange(len(ball.segments)) * sched.DT_S
    centre = np.stack([np.interp(fine, grid, ball.segments[:, 0, 0, c]) for c in range(3)], axis=1)
    gaps = sched.segment_distances(caps[:, :, 0], caps[:, :, 1], centre[:, None], centre[:, None])
    assert (gaps - np.asarray(arm.radii, float)[None] - 60.0).min() >= 30.0
    assert sched._park_clear(
        arm, *sched._way_knots(done + wait, q[-1], float(track[-1]), way), [ball], done + 40.0, 30.0
    )
    shorter = sched._way_knots(done + wait - sched.WAIT_STEP_S, q[-1], float(track[-1]), way)
    assert not sched._park_clear(arm, *shorter, [ball], done + 40.0, 30.0)


def test_a_robot_waits_before_its_last_stroke_when_no_park_way_is_clear(box_plan, monkeypatch):
    """In the schedule, a later robot none of whose parks' ways is clear when its work ends (``_park_clear``
    made to say so) takes the first park whose way a wait before a last stroke frees (``_end_wait``, here
    giving 2 s before the last stroke for the second park): its timeline waits there in place of the wait it
    had, its other waits as they were, and ends with that park's way."""
    plan, arms = box_plan
    tracks = [None if r.track is None else r.track.speed_mm_s for r in plan.cell.robots]
    ranges = [None if r.track is None else tuple(r.track.range_mm) for r in plan.cell.robots]
    plain = sched.schedule_cell(plan.robots, arms, 400.0, 1000.0, 30.0, tracks, track_ranges=ranges)
    asked = []

    def end_wait(arm, t0, q, track, starts, chosen, way, *args):
        asked.append(way)
        return (len(starts) - 1, 2.0) if len(asked) == 2 else None

    monkeypatch.setattr(sched, "_park_clear", lambda *args: False)
    monkeypatch.setattr(sched, "_end_wait", end_wait)
    got = sched.schedule_cell(plan.robots, arms, 400.0, 1000.0, 30.0, tracks, track_ranges=ranges)
    assert len(asked) == 2  # the later robot only; the first park's way not freed, the second's freed
    line, before = got.timelines[1], plain.timelines[1]
    assert line.wait_s[-1] == 2.0
    np.testing.assert_allclose(line.wait_s[:-1], before.wait_s[:-1])
    n_last = len(plan.robots[1].strokes[-1])
    # (the arrival at a stroke's first waypoint is before its wait, the rest after it)
    assert line.arrive_s[-n_last] == pytest.approx(before.arrive_s[-n_last])
    np.testing.assert_allclose(line.arrive_s[1 - n_last :], before.arrive_s[1 - n_last :] - before.wait_s[-1] + 2.0)
    offsets, way_q, way_track, _ = asked[1]
    np.testing.assert_allclose(line.knot_q[-len(way_q) :], way_q)
    np.testing.assert_allclose(line.knot_track[-len(way_q) :], way_track)
    assert line.end_s == pytest.approx(line.arrive_s[-1] + offsets[-1])
    np.testing.assert_allclose(got.timelines[0].knot_t, plain.timelines[0].knot_t)  # the first robot unchanged
