"""A cell's robots timed within their axes' limits (cells.timing; issue 18)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sprayplan.cells import load_cell
from sprayplan.cells.plan import plan_cell
from sprayplan.cells.spec import cell_from_dict
from sprayplan.cells.timing import ACCELERATION_TIME_S, _Axes, cell_limits, time_cell
from sprayplan.config import JobConfig, TimingConfig
from sprayplan.errors import ConfigError
from sprayplan.paths.speed import segment_speeds
from sprayplan.timing.stage import joint_runs
from tests.helpers import grid_box

CELL = {
    "name": "small2",
    "robot": [
        {
            "name": "left",
            "model": "abb-irb2400-10",
            "base_mm": [0.0, 900.0, 0.0],
            "base_rpy_deg": [0.0, 0.0, -90.0],
            "track": {"axis": "x", "range_mm": [-400.0, 400.0], "speed_mm_s": 600.0},
        },
        {"name": "right", "model": "abb-irb2400-10", "base_mm": [0.0, -900.0, 0.0], "base_rpy_deg": [0.0, 0.0, 90.0]},
    ],
}


@pytest.fixture(scope="module")
def box_plan():
    cell = cell_from_dict(CELL)
    job = JobConfig().replace(coating={"thickness_um": 50.0}, tuning={"touch_up_rounds": 0})
    plan = plan_cell(grid_box(n=8, size=(600.0, 300.0, 200.0)), cell, job)
    return cell, job, plan


def _stretches(work, jump_rad):
    """(stroke, its waypoint indices, a run) of every run of reached spray waypoints the timing follows."""
    start = 0
    for s in work.strokes:
        idx = np.arange(start, start + len(s))
        start += len(s)
        if s.spray_on:
            for run in joint_runs(work.reachable[idx], work.q[idx], jump_rad):
                if len(run) >= 2:
                    yield s, idx, run


def test_every_robot_is_timed_within_its_limits_and_its_planned_speeds(box_plan):
    cell, _, plan = box_plan
    job = plan.job  # with the gun speed chosen for the film target
    jump = np.radians(job.timing.joint_jump_deg)
    report = plan.report
    assert report["cycle_time_s"] == pytest.approx(max(r["cycle_time_s"] for r in report["robots"].values()))
    checked = 0
    for robot, work in zip(cell.robots, plan.robots):
        t = work.t_s
        lead_s = work.lead_s
        # every waypoint a time, never back in time; the first after its run-up (from time 0)
        assert t[0] == pytest.approx(lead_s[0, 0], abs=1e-12) and (np.diff(t) >= -1e-12).all()
        limits = cell_limits(robot, job.timing)
        axes = _Axes(robot)
        q = axes.of(work)
        leads = np.concatenate([work.lead_q, work.lead_track_mm[:, :, None]], axis=2) if axes.axis is not None else (
            work.lead_q)  # fmt: skip
        entry = report["robots"][work.name]
        assert entry["cycle_time_s"] == pytest.approx(max(t[-1], float((t + lead_s[:, 1]).max())), abs=1e-3)
        spray_planned = 0.0
        run_ups = 0
        for s, idx, run in _stretches(work, jump):
            dt = np.diff(t[idx[run]])
            assert (dt > 0).all()
            # the mean speed of every axis over a step is at most its top speed
            mean = np.abs(np.diff(q[idx[run]], axis=0)) / dt[:, None]
            assert (mean <= limits.velocity * (1 + 1e-6)).all()
            # the gun tip never runs faster than planned (its mean speed over each segment)
            cap = segment_speeds(
                s.tcp, s.points, job.motion.gun_speed_mm_s, job.motion.speed_along, job.motion.max_speed_ratio, s.dwell
            )[run[:-1]]
            tip = np.linalg.norm(np.diff(axes.tip(q[idx[run]]), axis=0), axis=1)
            assert (tip / dt <= cap * (1 + 1e-6)).all()
            spray_planned += float((tip / cap).sum())
            checked += len(run)
            # a run-up (run-out): within the axes' speeds and no faster than the first (last) planned speed
            for w, side, c in ((idx[run[0]], 0, cap[0]), (idx[run[-1]], 1, cap[-1])):
                if lead_s[w, side] > 0:
                    run_ups += 1
                    step = np.abs(q[w] - leads[w, side])
                    assert (step / lead_s[w, side] <= limits.velocity * (1 + 1e-6)).all()
                    tip = np.linalg.norm(axes.tip(q[w]) - axes.tip(leads[w, side]))
                    assert tip / lead_s[w, side] <= c * (1 + 1e-6)
                    spray_planned += tip / c
        # no faster than the planned speeds allow along the spray, and the moves take time as well
        assert entry["timing"]["spray_s"] >= spray_planned * (1 - 1e-9)
        assert entry["cycle_time_s"] >= entry["timing"]["spray_s"]
        assert entry["length_over_speed_s"] > 0
        assert run_ups > 0
    assert checked > 100


def test_a_slower_arm_takes_longer(box_plan):
    cell, _, plan = box_plan
    job = plan.job
    fast = time_cell(cell, plan.robots, job)
    slow_job = job.replace(timing={"arm_max_acceleration_deg_s2": [40.0] * 6, "track_max_acceleration_mm_s2": 50.0})
    slow = time_cell(cell, plan.robots, slow_job)
    for f, s in zip(fast, slow):
        assert s.cycle_s > f.cycle_s
        assert s.slowed >= f.slowed


def test_the_limits_of_a_cell_robot():
    cell = cell_from_dict(CELL)
    left, right = cell.robots
    arm = left.robot(0.0)
    limits = cell_limits(left, TimingConfig())
    # the maker's axis speeds, an assumed acceleration (top speed in ACCELERATION_TIME_S), then the track's
    np.testing.assert_allclose(limits.velocity[:6], arm.max_speed)
    np.testing.assert_allclose(limits.acceleration[:6], arm.max_speed / ACCELERATION_TIME_S)
    assert limits.velocity[6] == 600.0 and limits.acceleration[6] == 500.0
    assert cell_limits(right, TimingConfig()).dof == 6  # no track
    given = cell_limits(left, TimingConfig(arm_max_acceleration_deg_s2=(100.0,) * 6, track_max_acceleration_mm_s2=80.0))
    np.testing.assert_allclose(given.acceleration, np.r_[np.radians([100.0] * 6), 80.0])
    # a UR arm has its model's limits
    ur = cell_from_dict({"robot": [{"name": "a", "model": "ur5", "base_mm": [0.0, 500.0, 0.0]}]}).robots[0]
    np.testing.assert_allclose(cell_limits(ur, TimingConfig()).acceleration, [1.4] * 6)


def test_an_arm_without_known_speeds_is_refused(monkeypatch):
    cell = cell_from_dict(CELL)
    left = cell.robots[0]
    arm = left.robot(0.0)
    unknown = dataclasses.replace(arm.params, max_speed=np.full(6, np.nan))
    monkeypatch.setattr(type(left), "robot", lambda self, track_mm=0.0: dataclasses.replace(arm, params=unknown))
    with pytest.raises(ConfigError, match="arm_max_velocity_deg_s"):
        cell_limits(left, TimingConfig())


@pytest.mark.parametrize("bad", [0.0, -5.0, float("nan")])
def test_a_bad_track_acceleration_names_its_key(bad):
    with pytest.raises(ConfigError, match="timing.track_max_acceleration_mm_s2"):
        TimingConfig(track_max_acceleration_mm_s2=bad)


def test_without_timing_the_cycle_is_length_over_speed(box_plan):
    cell, job, _ = box_plan
    plan = plan_cell(grid_box(n=8, size=(600.0, 300.0, 200.0)), cell, job.replace(timing={"enabled": False}))
    assert all(r.t_s is None for r in plan.robots)
    assert "length over speed" in plan.report["cycle_time_rule"]


def test_line3_names_its_limits():
    cell = load_cell("line3")
    for robot in cell.robots:
        limits = cell_limits(robot, TimingConfig())
        assert limits.dof == 7 and np.isfinite(limits.velocity).all()


def test_the_deposit_after_touch_ups_takes_over_the_earlier_columns(box_plan):
    """``cells.plan.extended_deposit``: a touch-up round's matrix from the last one's columns and the new runs'
    own equals the matrix made anew (to rounding: batches of gun samples fall differently)."""
    from sprayplan.cells.plan import extended_deposit, reached_strokes, with_touch_ups
    from sprayplan.coating.stage import process_for
    from sprayplan.coating.thickness import deposit_matrix
    from sprayplan.types import Paths

    cell, _, plan = box_plan
    job = plan.job
    process, coating = process_for(job), job.coating.simulation(job.motion)
    strokes, owners = reached_strokes(plan.robots)
    samples, old = deposit_matrix(plan.part, Paths(tuple(strokes), 113.0, 0.0), process, config=coating)
    # two touch-ups: spray runs of the plan again, 15 mm higher
    extra = [dataclasses.replace(s, tcp=s.tcp + [0.0, 0.0, 15.0], kind="touch-up") for s in strokes[:2]]
    grown, added = with_touch_ups(cell, plan.robots, extra)
    assert added >= 1
    new_strokes, new_owners = reached_strokes(grown)
    assert len(new_strokes) > len(strokes)
    got_samples, got = extended_deposit(plan.part, new_strokes, new_owners, owners, samples, old, process, coating)
    assert got_samples is samples
    _, full = deposit_matrix(plan.part, Paths(tuple(new_strokes), 113.0, 0.0), process, config=coating, samples=samples)
    assert got.shape == full.shape and full.nnz > old.nnz
    lengths = np.array([len(x) for x in new_strokes])
    starts = np.r_[0, np.cumsum(lengths)]
    where = {o: k for k, o in enumerate(new_owners)}
    kept = np.concatenate([np.arange(starts[where[o]], starts[where[o] + 1]) for o in owners])
    added_cols = np.setdiff1d(np.arange(full.shape[1]), kept)
    # the earlier runs' columns are the earlier matrix's, and those of a matrix made anew (to rounding)
    assert abs(got[:, kept] - old).max() == 0.0
    assert abs(got[:, kept] - full[:, kept]).max() <= 1e-12 * abs(full).max()
    # the new runs' columns are the film of the new runs computed alone, put in their places
    added_runs = [x for x, o in zip(new_strokes, new_owners) if o not in set(owners)]
    _, alone = deposit_matrix(plan.part, Paths(tuple(added_runs), 113.0, 0.0), process, config=coating, samples=samples)
    assert abs(got[:, added_cols] - alone).max() == 0.0
    # against the matrix made anew: there the occlusion's depth map is sized by the median depth of all the
    # strokes (here of the new ones alone, 15 mm deeper), so pairs at its edges differ; the film they add
    # differs by a few per cent at the most at a run's ends, and by less than 1 % in all
    new_sum = np.asarray(got[:, added_cols].sum(axis=0)).ravel()
    full_sum = np.asarray(full[:, added_cols].sum(axis=0)).ravel()
    assert new_sum.sum() > 0
    assert abs(new_sum.sum() - full_sum.sum()) <= 0.01 * full_sum.sum()
    # a run of the earlier tuning that is gone: made anew
    assert extended_deposit(plan.part, new_strokes[1:], new_owners[1:], owners, samples, old, process, coating) is None


def test_the_film_at_the_timed_speeds_is_the_film_of_the_timed_time_factors(box_plan):
    """The report's film at the timed speeds against a simulation of the reached runs with time factors
    worked out here from the time stamps: on each timed stretch a waypoint's time (half of each step beside it)
    over its time at the process speed with factors 1."""
    from sprayplan.cells.plan import reached_strokes
    from sprayplan.coating.report import share_interval, weighted_stats
    from sprayplan.coating.stage import process_for
    from sprayplan.coating.thickness import simulate
    from sprayplan.types import Paths

    _, _, plan = box_plan
    job = plan.job
    motion = job.motion
    jump = np.radians(job.timing.joint_jump_deg)
    factors = []
    for work in plan.robots:
        w = np.concatenate([s.dwell for s in work.strokes])
        for s, idx, run in _stretches(work, jump):
            at_one = np.linalg.norm(np.diff(s.tcp, axis=0), axis=1) / segment_speeds(
                s.tcp, s.points, motion.gun_speed_mm_s, motion.speed_along, motion.max_speed_ratio
            )
            steps = np.diff(work.t_s[idx[run]])
            for k, i in enumerate(run):
                before = [k - 1] if k > 0 else []
                after = [k] if k < len(run) - 1 else []
                base = sum(at_one[run[j]] for j in before + after) / 2
                if base > 1e-12:
                    w[idx[i]] = sum(steps[j] for j in before + after) / 2 / base
        factors.append(w)
    strokes, owners = reached_strokes(plan.robots)
    starts = [np.r_[0, np.cumsum([len(s) for s in r.strokes])] for r in plan.robots]
    timed = [s.with_dwell(factors[r][starts[r][k] + a : starts[r][k] + b]) for s, (r, k, a, b) in zip(strokes, owners)]
    film = simulate(
        plan.part,
        Paths(tuple(timed), job.paths.standoff_mm, 0.0),
        process_for(job),
        config=job.coating.simulation(motion),
    )
    target, tol = job.coating.thickness_um, job.coating.tolerance
    want = weighted_stats(film.thickness_um, film.area_mm2, target - tol, target + tol)
    got = plan.report["film"]["at_timed_speeds"]
    assert got["whole"]["mean_um"] == pytest.approx(want["mean_um"], rel=1e-9)
    # the std comes from the variance, E[x^2] - E[x]^2, which magnifies the sums' rounding (the plan's from the
    # tuning's deposit matrix, this one simulated anew) by (mean / std)^2 over the mean's: the same 1e-9 there
    assert got["whole"]["std_um"] == pytest.approx(want["std_um"], abs=1e-9 * want["mean_um"] ** 2 / want["std_um"])
    # the robots never run faster than planned, so the film is thicker at the timed speeds, not thinner
    planned = plan.report["film"]["whole"]
    assert got["whole"]["mean_um"] > planned["mean_um"]
    points = plan.report["film"]["report"]["measuring_points"]
    assert got["measuring_points"]["count"] == points["count"] > 10  # at the planned film's points
    # the measuring points are the plan's own film at the timed speeds (the whole of which is the simulation's
    # above) at the planned film's points (the report's mean is a weighted one: the same sum, other rounding)
    want_points = plan.timed_film.thickness_um[points["indices"]].mean()
    assert got["measuring_points"]["mean_um"] == pytest.approx(want_points, rel=1e-12)
    at = plan.timed_film.thickness_um[points["indices"]]
    inside = int((np.abs(at - target) <= tol).sum())
    assert got["measuring_points"]["share_in_spec_ci95"] == share_interval(inside, len(at))
    assert (plan.timed_film.points == film.points).all()
    assert set(got["per_robot"]) == {r.name for r in plan.robots}
