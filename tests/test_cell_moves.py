"""How a cell robot moves between its runs, in the timing and in the schedule: a routed transfer timed leg by
leg from rest to rest (the programs stop at every route node), the move into a run ending with the programs'
approach to its start (the run-up's start where it has one), no axis faster than its limit anywhere along a scheduled timeline (no jump), and the schedule's
wait search giving the wait-by-wait answer."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from sprayplan.cells import load_cell
from sprayplan.cells import schedule as sched
from sprayplan.cells.collide import cell_arms
from sprayplan.cells.plan import plan_cell
from sprayplan.cells.timing import _Axes, _leads, cell_limits, program_back_offs, time_cell, with_times
from sprayplan.config import JobConfig
from sprayplan.timing.moves import point_to_point
from tests.helpers import grid_box
from tests.test_cell_plan import CELL, SIZE

pytest.importorskip("coal")


@pytest.fixture(scope="module")
def routed(tmp_path_factory):
    """The two-robot box planned with ``[collision] check`` (its left robot's transfers routed round the box)
    and a 50 um target; each robot's timing."""
    folder = tmp_path_factory.mktemp("moves")
    (folder / "small2.toml").write_text(CELL)
    cell = load_cell(folder / "small2.toml")
    job = JobConfig().replace(coating={"thickness_um": 50.0}, collision={"check": True})
    plan = plan_cell(grid_box(n=8, size=SIZE), cell, job)
    return plan, time_cell(plan.cell, plan.robots, plan.job)


def _transfers(work):
    start = 0
    for s in work.strokes:
        rows = np.arange(start, start + len(s))
        start += len(s)
        if not s.spray_on:
            yield rows[work.reachable[rows]], start


def _checked_back_off(cr, arm, axes, job, limits):
    """The programs' back-off from a run's end at ``axes`` as the timing takes it (``cells.timing.program_back_offs``),
    checked here on its own terms: the gun tip moved straight back along the gun axis by approach_mm or a
    half, quarter or eighth of it, the orientation and the track kept; and its seconds: the longer of the joint
    move and the line at the approach speed. Returns (backed-off axes, seconds)."""
    from sprayplan.programs.build import APPROACH_TRIES

    moved, seconds = program_back_offs(cr, job, limits)(axes)
    here, there = arm.target_poses(np.vstack([axes, moved]))
    step = there[:3, 3] - here[:3, 3]
    distance = float(np.linalg.norm(step))
    assert min(abs(distance - share * job.export.approach_mm) for share in APPROACH_TRIES) < 1e-6
    assert np.allclose(step, -distance * here[:3, 2], atol=1e-6)
    assert np.allclose(there[:3, :3], here[:3, :3], atol=1e-9) and np.array_equal(moved[6:], axes[6:])
    line = distance / job.export.approach_speed_mm_s
    assert seconds == pytest.approx(max(point_to_point(axes, moved, limits).duration_s, line), rel=1e-12)
    return moved, seconds


def test_a_routed_transfer_is_timed_leg_by_leg_and_ends_with_the_approach(routed):
    """Every transfer row after the first is reached by a rest-to-rest move from the row before (the
    programs stop at every route node), so the rows' times step by those moves' durations; the last move goes
    to the approach pose of the next run's start (its run-up's start where it has one) and on along the
    approach line, as the programs move. Some transfers are routed (more than two rows), and a run-up follows
    some."""
    from sprayplan.programs.arms import ArmCell

    plan, timed = routed
    legs = ups = 0
    for cr, work, tm in zip(plan.cell.robots, plan.robots, timed):
        axes, limits = _Axes(cr), cell_limits(cr, plan.job.timing)
        arm = ArmCell(cr, plan.job.paths.standoff_mm)
        q = axes.of(work)
        lead, _ = _leads(work, axes)
        for rows, after in _transfers(work):
            if len(rows) < 3:
                continue
            for a, b in itertools.pairwise(rows[1:]):
                expected = point_to_point(q[a], q[b], limits).duration_s
                if b == rows[-1]:
                    goal = q[b]
                    if after < len(q) and np.isfinite(lead[after, 0]).all():
                        goal, ups = lead[after, 0], ups + 1
                    moved, seconds = _checked_back_off(cr, arm, goal, plan.job, limits)
                    expected = point_to_point(q[a], moved, limits).duration_s + seconds
                assert tm.t_s[b] - tm.t_s[a] == pytest.approx(expected, rel=1e-9, abs=1e-9)
                legs += 1
    assert legs > 0 and ups > 0


def test_no_axis_moves_faster_than_its_limit_along_the_scheduled_timelines(routed):
    """Between any two knots of every robot's scheduled timeline (its runs, run-ups, routed transfers, waits
    and park), no joint and no track moves faster than its velocity limit: the timeline never jumps."""
    plan, timed = routed
    robots = with_times(plan.robots, timed)
    arms = cell_arms(plan.cell, plan.part, plan.job.collision)
    tracks = [None if r.track is None else r.track.speed_mm_s for r in plan.cell.robots]
    ranges = [None if r.track is None else tuple(r.track.range_mm) for r in plan.cell.robots]
    motion = plan.job.motion
    schedule = sched.schedule_cell(
        robots, arms, motion.gun_speed_mm_s, motion.transfer_speed_mm_s, plan.job.collision.clearance_mm, tracks,
        times=[r.t_s for r in robots], track_ranges=ranges,
    )  # fmt: skip
    for cr, line in zip(plan.cell.robots, schedule.timelines):
        limits = cell_limits(cr, plan.job.timing)
        axes = line.knot_q if cr.track is None else np.column_stack([line.knot_q, line.knot_track])
        dt = np.diff(line.knot_t)
        assert (dt > 0).all()
        speed = np.abs(np.diff(axes, axis=0)) / dt[:, None]
        assert (speed <= limits.velocity * (1 + 1e-6) + 1e-9).all(), cr.name


def _wait_by_wait(stroke, hold, earlier, clearance_mm):
    """The reference: every wait in turn, the hold checked over all its samples, the stroke over all of its."""
    per = round(sched.WAIT_STEP_S / sched.DT_S)
    g0, m = stroke.first, len(stroke.segments)
    for k in range(int(sched.MAX_WAIT_S / sched.WAIT_STEP_S) + 1):
        held = np.arange(g0, g0 + k * per)
        for other in earlier:
            if (
                len(held)
                and (sched._gaps(hold, np.zeros(len(held), int), other, other.rows(held), clearance_mm) < 0).any()
            ):
                return None
        rows = np.arange(m)
        if not any((sched._gaps(stroke, rows, other, other.rows(g0 + k * per + rows), clearance_mm) < 0).any()
                   for other in earlier):  # fmt: skip
            return k * per * sched.DT_S
    return None


def _path(rng, arm, keys: int, samples: int, centre) -> tuple[np.ndarray, np.ndarray]:
    """Joints (samples, 6) straight between ``keys`` random configurations about ``centre``, track 0."""
    frames = centre + rng.uniform(-0.8, 0.8, (keys, 6))
    t = np.linspace(0.0, keys - 1, samples)
    q = np.array([np.interp(t, np.arange(keys), frames[:, j]) for j in range(6)]).T
    return q, np.zeros(samples)


def test_the_wait_search_gives_the_wait_by_wait_answer(routed, monkeypatch):
    """On random motions of the two box robots reaching over the box towards each other, the search
    (:func:`cells.schedule._wait_for`: the hold's new samples per wait, the stroke by chunks, the chunk that
    refused the last wait first) finds the same least wait as checking every sample at every wait, or None
    with it; the cases cover no wait, a wait, and none found."""
    plan, _ = routed
    monkeypatch.setattr(sched, "MAX_WAIT_S", 15.0)
    arms = cell_arms(plan.cell, plan.part, plan.job.collision)
    left, right = arms
    rng = np.random.default_rng(3)
    reach = np.array([0.0, 0.6, 0.3, 0.0, 0.5, 0.0])  # leaning forward, over the box
    answers = []
    for _ in range(24):
        q, t = _path(rng, right, 6, 400, reach)
        earlier = [sched._Sampled.of(right, q, t)]
        first = int(rng.integers(0, 200))
        qs, ts = _path(rng, left, 3, int(rng.integers(20, 120)), reach)
        stroke = sched._Sampled.of(left, qs, ts, first=first)
        hold = sched._Sampled.of(left, qs[:1], ts[:1])
        got = sched._wait_for(stroke, hold, earlier, 30.0)
        assert got == _wait_by_wait(stroke, hold, earlier, 30.0)
        answers.append(got)
    assert None in answers and 0.0 in answers and any(a not in (None, 0.0) for a in answers)


def test_back_offs_kept_between_timings_at_other_speeds_time_the_same(routed):
    """Timed at another gun speed (as the flow fit times every share) with the back-offs of a first timing
    kept (``time_cell``'s ``back_offs``), every time stamp equals a timing that solves them afresh, and the
    second timing solves none more."""
    from sprayplan.cells.fit import scaled_job

    plan, timed = routed
    kept: dict = {}
    first = time_cell(plan.cell, plan.robots, plan.job, kept)
    assert all(np.array_equal(a.t_s, b.t_s) for a, b in zip(first, timed))
    solved = {name: len(found) for name, found in kept.items()}
    assert sum(solved.values()) > 0
    slower = scaled_job(plan.job, 0.5, 100.0)
    again = time_cell(plan.cell, plan.robots, slower, kept)
    fresh = time_cell(plan.cell, plan.robots, slower)
    assert all(np.array_equal(a.t_s, b.t_s) for a, b in zip(again, fresh))
    assert {name: len(found) for name, found in kept.items()} == solved
    assert max(a.cycle_s for a in again) > max(a.cycle_s for a in first)


def test_a_timeline_with_run_ups_has_one_configuration_at_each_time(routed):
    """The schedule's rows with the run-ups added (``cells.schedule.with_leads``): a transfer's last row, which
    the robot reaches at the run-up's start, holds the run-up's joints and track, so that the timeline (which
    keeps the first of rows at one time, ``_knots``) goes through the run-up rather than skipping it; and some
    run-ups follow a transfer. (At a run-out's end the run-out's row comes first and is the one kept.)"""
    plan, timed = routed
    robots = with_times(plan.robots, timed)
    checked = 0
    for w in robots:
        starts = np.cumsum([0] + [len(s) for s in w.strokes])[:-1]
        t0, q, track, _, keep = sched.with_leads(
            w, np.asarray(w.t_s, float), np.asarray(w.q, float), np.asarray(w.track_mm, float), starts
        )
        same = np.flatnonzero(np.abs(np.diff(t0)) <= 1e-9)
        for i in same:
            if keep[i] and not keep[i + 1]:  # a waypoint's row, then a run-up's row at its time
                assert np.allclose(q[i], q[i + 1], atol=1e-12) and track[i] == track[i + 1], (w.name, i)
                checked += 1
    assert checked > 0


def test_a_back_off_of_a_robot_without_a_track_given_a_track_axis_is_timed_on_its_joints(routed, monkeypatch):
    """The schedule asks ``program_back_offs`` with a track position appended for every robot (``np.r_[q,
    track]``); for a robot without a track its limits have only the arm's axes, and the move was timed over
    one axis more than the limits give (ruckig read a limit past their end: a failure, or a time from an
    arbitrary limit). With the track axis at 0 the answer is the joints-only one, that axis unmoved."""
    plan, _ = routed
    cr = next(r for r in plan.cell.robots if r.track is None)
    work = plan.robots[list(plan.cell.robots).index(cr)]
    limits = cell_limits(cr, plan.job.timing)
    assert len(limits.velocity) == 6
    q = work.q[np.flatnonzero(work.reachable)[0]]
    import sprayplan.cells.timing as cells_timing

    def timed(start, target, lim):  # a move's axes and its limits agree (ruckig does not check it)
        assert len(start) == len(target) == len(lim.velocity) == len(lim.acceleration)
        return point_to_point(start, target, lim)

    monkeypatch.setattr(cells_timing, "point_to_point", timed)
    six = program_back_offs(cr, plan.job, limits)(q)
    seven = program_back_offs(cr, plan.job, limits)(np.r_[q, 0.0])
    assert six is not None and seven is not None
    np.testing.assert_array_equal(seven[0], np.r_[six[0], 0.0])
    assert seven[1] == six[1] and np.isfinite(six[1])
