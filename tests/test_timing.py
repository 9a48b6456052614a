"""Timing within the joints' limits (sprayplan.timing): the limits hold between toppra's grid points, the gun tip
never runs faster than planned, a loose straight stroke runs at its speed, tighter limits never make a stroke
faster, the plan's time stamps increase and read back, and bad limits are one-line errors."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.config import JobConfig
from sprayplan.errors import ConfigError
from sprayplan.export.plan_read import read_plan_file
from sprayplan.job import run_job
from sprayplan.paths.speed import segment_speeds
from sprayplan.robots.model import load_robot
from sprayplan.robots.stage import HOME_JOINTS
from sprayplan.timing.limits import AxisLimits
from sprayplan.timing.moves import point_to_point
from sprayplan.timing.path import time_path
from sprayplan.timing.stage import real_plan
from tests.helpers import spray_stretches

REACH = {"units": "m", "region": "x > -250"}
#: Slack of a limit in the finite-difference checks below: the differences of a sampled trajectory over steps
#: of 1/40000 of its duration (the check itself is exact to CHECK_SLACK; the differences are not).
FD_SLACK = 2e-3


@pytest.fixture(scope="module")
def reach(testdata):
    """The reach part planned and timed (no film), with its robot."""
    job = JobConfig().replace(load=REACH, output={"viewer": False, "report": False})
    state = run_job(testdata / "meshes" / "reach_curved_part.ply", job, until="timing")
    return state, state.gantry()


def _tip(gantry):
    return lambda q: gantry.gun2world(q)[:, :3, 3]


def _spray_runs(state, count=6):
    """The first ``count`` stretches of spray strokes of the reach plan the timing follows, of more than 3
    waypoints, with their planned tip speeds."""
    return spray_stretches(state.plan, state.job, min_waypoints=4, count=count)


def _limits(state, gantry):
    from sprayplan.timing.stage import plan_limits

    return plan_limits(gantry, state.job)


def _finite_difference_check(timed, limits, tip, cap):
    """Sample the timed stroke at 40001 times, differentiate numerically: the largest ratio of joint speed,
    joint acceleration and tip speed to its limit (the tip's against the cap of the segment it is in)."""
    t = np.linspace(0.0, timed.duration_s, 40001)
    q, _, _ = timed.sample(t)
    dt = t[1] - t[0]
    qd = np.diff(q, axis=0) / dt
    qdd = np.diff(q, 2, axis=0) / dt**2
    p = tip(q)
    v_tip = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    # the segment (between waypoints) each sample interval lies in, by the waypoints' time stamps
    seg = np.clip(np.searchsorted(timed.t_s, 0.5 * (t[1:] + t[:-1]), side="right") - 1, 0, len(cap) - 1)
    return (
        float((np.abs(qd) / limits.velocity).max()),
        float((np.abs(qdd) / limits.acceleration).max()),
        float((v_tip / cap[seg]).max()),
    )


def test_limits_hold_between_grid_points(reach):
    """Resampled 40000 times per stroke and differentiated numerically, every axis stays within its speed and
    acceleration limit and the tip within its planned speed (toppra alone holds them at its grid points only)."""
    state, gantry = reach
    limits = _limits(state, gantry)
    tip = _tip(gantry)
    runs = _spray_runs(state)
    assert len(runs) >= 4
    tightened = 0
    for q, cap in runs:
        timed = time_path(q, cap, limits, tip)
        tightened += timed.rounds > 0
        assert max(timed.worst.values()) <= 1.0 + 1e-9
        velocity, acceleration, tip_speed = _finite_difference_check(timed, limits, tip, cap)
        assert velocity <= 1.0 + FD_SLACK
        assert acceleration <= 1.0 + FD_SLACK
        assert tip_speed <= 1.0 + FD_SLACK
    assert tightened, "no stroke needed tightening: the dense check was not exercised"


def test_without_tightening_the_limits_break_between_grid_points(reach):
    """The reason for the dense check: toppra's own answer (no rounds, no stretch) exceeds a limit between its
    grid points on some stroke of the reach part."""
    state, gantry = reach
    limits = _limits(state, gantry)
    worst = 0.0
    for q, cap in _spray_runs(state):
        timed = time_path(q, cap, limits, _tip(gantry), max_rounds=0)
        if timed.stretch > 1.0:
            worst = max(worst, timed.stretch)
    assert worst > 1.0


def test_straight_stroke_with_loose_limits_runs_at_the_planned_speed(reach):
    """The gantry's x axis carrying a still arm 500 mm at 400 mm/s, with limits far beyond what that needs:
    length / speed (the start and stop from rest cost only what a 1e9 mm/s^2 acceleration costs)."""
    _, gantry = reach
    tip = _tip(gantry)
    x = np.linspace(0.0, 500.0, 51)
    q = np.column_stack([np.tile(HOME_JOINTS, (51, 1)), x, np.zeros(51), np.full(51, 1500.0)])
    loose = AxisLimits(np.full(9, 1e6), np.full(9, 1e9))
    timed = time_path(q, np.full(50, 400.0), loose, tip)
    length = float(np.linalg.norm(np.diff(tip(q), axis=0), axis=1).sum())
    assert length == pytest.approx(500.0, rel=1e-12)
    assert timed.duration_s == pytest.approx(length / 400.0, rel=1e-5)
    assert timed.duration_s >= length / 400.0
    np.testing.assert_allclose(timed.speed_mm_s[1:-1], 400.0, rtol=1e-5)
    # the same stroke with the gantry's real acceleration takes longer, by what starting and stopping cost
    real = AxisLimits(np.full(9, 1e6), np.r_[np.full(6, 1e9), np.full(3, 500.0)])
    slower = time_path(q, np.full(50, 400.0), real, tip)
    # accelerating to 400 mm/s at 500 mm/s^2 and back costs v / a = 0.8 s over running at speed
    assert slower.duration_s == pytest.approx(length / 400.0 + 400.0 / 500.0, rel=2e-2)


def test_a_tighter_limit_never_shortens_a_stroke(reach):
    """Halving one axis's speed or acceleration limit, or the planned tip speed, never makes a stroke faster
    (on the same joint path: the spline's knots kept)."""
    state, gantry = reach
    limits = _limits(state, gantry)
    tip = _tip(gantry)
    for q, cap in _spray_runs(state, 4):
        knots = (limits.velocity, float(cap.max()))  # the same joint path between the waypoints every time
        base = time_path(q, cap, limits, tip, knot_speeds=knots).duration_s
        for axis in (0, 3, 5):
            for field in ("velocity", "acceleration"):
                values = getattr(limits, field).copy()
                values[axis] *= 0.5
                tighter = dataclasses.replace(limits, **{field: values})
                longer = time_path(q, cap, tighter, tip, knot_speeds=knots).duration_s
                assert longer >= base * (1 - 1e-9), (axis, field)
        slower_cap = time_path(q, 0.5 * cap, limits, tip, knot_speeds=knots).duration_s
        assert slower_cap >= base * (1 - 1e-9)


def test_point_to_point_move_within_limits_on_the_joint_line():
    limits = AxisLimits(np.r_[np.full(6, math.pi), np.full(3, 250.0)], np.r_[np.full(6, 1.4), np.full(3, 500.0)])
    start = np.r_[HOME_JOINTS, 0.0, 0.0, 1500.0]
    target = np.r_[HOME_JOINTS + np.array([1.0, -0.4, 0.8, 0.1, -2.0, 0.3]), 900.0, -300.0, 1400.0]
    move = point_to_point(start, target, limits)
    delta = np.abs(target - start)
    # no axis can be faster than its bang-bang profile from rest to rest
    lower = np.where(
        delta <= limits.velocity**2 / limits.acceleration,
        2 * np.sqrt(delta / limits.acceleration),
        delta / limits.velocity + limits.velocity / limits.acceleration,
    )
    assert move.duration_s == pytest.approx(lower.max(), rel=1e-6)
    q, qd, qdd = move.sample(np.linspace(0.0, move.duration_s, 2001))
    assert (np.abs(qd) <= limits.velocity * (1 + 1e-9)).all()
    assert (np.abs(qdd) <= limits.acceleration * (1 + 1e-9)).all()
    np.testing.assert_allclose(q[0], start, atol=1e-9)
    np.testing.assert_allclose(q[-1], target, atol=1e-9)
    # phase synchronisation: every sample on the straight joint line from start to target
    share = (q - start) / (target - start)
    np.testing.assert_allclose(share, np.broadcast_to(share[:, :1], share.shape), atol=1e-9)
    assert point_to_point(start, start, limits).duration_s == 0.0


def test_plan_time_stamps_increase_and_add_up(reach):
    state, _ = reach
    timing = state.timing
    stamps = []
    for st, t in zip(state.plan.stations, timing.t_s):
        assert len(t) == len(st)
        assert np.isnan(t[~st.reachable]).all() and np.isfinite(t[st.reachable]).all()
        stamps.append(t[st.reachable])
        start = 0
        for s in st.strokes:
            sl = slice(start, start + len(s))
            start += len(s)
            if s.spray_on and st.reachable[sl].all() and len(s) > 1:
                assert (np.diff(t[sl]) > 0).all()  # a spray stroke never stands still inside
    order = np.concatenate(stamps)
    assert (np.diff(order) >= 0).all()
    assert order[-1] < timing.cycle_time_s
    parts = timing.spray_time_s + timing.transfer_time_s + timing.station_move_time_s
    assert timing.cycle_time_s == pytest.approx(parts, rel=1e-12)
    # each stroke is at least as slow as planned: the robot never runs faster than the plan's speeds
    for st, times, planned in zip(state.plan.stations, timing.stroke_time_s, timing.planned_stroke_time_s):
        for s, real, wanted in zip(st.strokes, times, planned):
            if s.spray_on:
                assert real >= wanted * (1 - 1e-9)


def test_film_time_factors_are_the_real_times(reach):
    """The film's time factors give each stroke exactly its timed duration, and never less time than planned."""
    state, _ = reach
    timing = state.timing
    motion = state.job.motion
    film_plan = real_plan(state.plan, timing)
    for st, st_film, t in zip(state.plan.stations, film_plan.stations, timing.t_s):
        start = 0
        for s, sf in zip(st.strokes, st_film.strokes):
            sl = slice(start, start + len(s))
            start += len(s)
            if not s.spray_on or not st.reachable[sl].all() or len(s) < 2:
                continue
            jumps = np.abs(np.diff(st.q9[sl, :6], axis=0)).max(axis=1) > math.radians(state.job.timing.joint_jump_deg)
            if jumps.any():
                continue
            base = np.linalg.norm(np.diff(s.tcp, axis=0), axis=1) / segment_speeds(
                s.tcp, s.points, motion.gun_speed_mm_s, motion.speed_along, motion.max_speed_ratio
            )
            film_time = float((base * 0.5 * (sf.dwell[:-1] + sf.dwell[1:])).sum())
            assert film_time == pytest.approx(t[sl][-1] - t[sl][0], rel=1e-9)
            assert (sf.dwell >= s.dwell * (1 - 1e-6)).all()


def test_totals_and_read_back(testdata, tmp_path):
    """plan.json and waypoints.csv carry the time stamps; read back they are the job's, bit for bit."""
    job = JobConfig().replace(load=REACH, output={"viewer": False, "report": False})
    out = tmp_path / "out"
    state = run_job(testdata / "meshes" / "reach_curved_part.ply", job, outdir=out)
    totals = state.totals
    assert totals["cycle_time_s"] == pytest.approx(state.timing.cycle_time_s, abs=1e-3)
    assert totals["cycle_time_length_over_speed_s"] > 0
    assert totals["cycle_time_s"] >= totals["cycle_time_length_over_speed_s"]
    summary = totals["timing"]
    assert 0 < summary["slowed_waypoints"] <= summary["spray_waypoints"]
    read = read_plan_file(out / "plan.json")
    assert read.timing is not None
    for a, b in zip(read.timing.t_s, state.timing.t_s):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(read.timing.speed_mm_s, state.timing.speed_mm_s):
        np.testing.assert_array_equal(a, b)
    assert read.totals["cycle_time_s"] == totals["cycle_time_s"]
    import csv

    with open(out / "waypoints.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    stamps = np.concatenate(state.timing.t_s)
    assert len(rows) == len(stamps)
    written = np.array([float(r["t_s"]) if r["t_s"] else np.nan for r in rows])
    np.testing.assert_allclose(written, stamps, rtol=1e-9, equal_nan=True)


def test_disabled_timing_keeps_length_over_speed(testdata):
    job = JobConfig().replace(load=REACH, timing={"enabled": False})
    state = run_job(testdata / "meshes" / "reach_curved_part.ply", job, until="totals")
    assert state.timing is None
    assert "timing" not in state.totals and "cycle_time_length_over_speed_s" not in state.totals


def test_robot_models_have_limits():
    for name in ("ur5", "ur5e", "ur5-seed", "r5150"):
        model = load_robot(name)
        assert len(model.max_velocity) == model.dof and (model.max_velocity > 0).all()
        assert len(model.max_acceleration) == model.dof and (model.max_acceleration > 0).all()
    np.testing.assert_allclose(load_robot("ur5").max_velocity, math.pi)  # 180 deg/s, UR's data sheet


def test_robot_toml_overrides_limits(tmp_path):
    path = tmp_path / "slow_ur5.toml"
    path.write_text('preset = "ur5"\nmax_velocity_deg_s = [90, 90, 90, 120, 120, 120]\n')
    model = load_robot(path)
    np.testing.assert_allclose(np.degrees(model.max_velocity), [90, 90, 90, 120, 120, 120])
    np.testing.assert_allclose(model.max_acceleration, load_robot("ur5").max_acceleration)
    np.testing.assert_array_equal(model.d, load_robot("ur5").d)


def test_robot_without_limits_cannot_be_timed(tmp_path):
    from sprayplan.timing.limits import arm_limits

    path = tmp_path / "bare.toml"
    path.write_text(
        "d_mm = [89.159, 0, 0, 109.15, 94.65, 82.3]\na_mm = [0, -425, -392.25, 0, 0, 0]\n"
        "alpha_deg = [90, 0, 0, 90, -90, 0]\n"
    )
    with pytest.raises(ConfigError, match="max_velocity_deg_s"):
        arm_limits(load_robot(path))


@pytest.mark.parametrize("value", ["0", "-180", "nan", "inf"])
def test_bad_robot_limit_through_the_cli(tmp_path, capsys, value):
    robot = tmp_path / "bad.toml"
    robot.write_text(f'preset = "ur5"\nmax_velocity_deg_s = [180, 180, {value}, 180, 180, 180]\n')
    joints = tmp_path / "joints.csv"
    joints.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n")
    out = tmp_path / "poses.csv"
    code = main(["fk", str(joints), "--robot", str(robot), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sprayplan: error: ")
    assert "bad.toml" in lines[0] and "max_velocity_deg_s" in lines[0]
    assert not out.exists()


@pytest.mark.parametrize(
    "setting",
    [
        "gantry_max_velocity_mm_s = [250, 0, 250]",
        "gantry_max_acceleration_mm_s2 = [500, nan, 500]",
        "arm_max_acceleration_deg_s2 = [80, 80, 80, 80, 80, -1]",
        "arm_max_velocity_deg_s = [180, 180, 180]",
    ],
)
def test_bad_timing_setting_through_the_cli(testdata, tmp_path, capsys, setting):
    config = tmp_path / "process.toml"
    config.write_text(f"[timing]\n{setting}\n")
    out = tmp_path / "out"
    part = testdata / "meshes" / "reach_curved_part.ply"
    code = main(["-q", "plan", str(part), "--units", "m", "-c", str(config), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sprayplan: error: ")
    assert "timing." + setting.split(" =")[0] in lines[0]
    assert not out.exists()
