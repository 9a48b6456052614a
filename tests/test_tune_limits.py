"""Speeds tuned within the joints' limits (refine.limits), programs at the timed speeds, a robot TOML in the
main job: the tuned speeds never exceed the ones the robot makes, the film at the timed speeds is the one the
tuning predicted, the programs read back carry the timed speeds, a robot file's limits reach the timing, and
bad robot files are one-line errors."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.cli.plan import summary_line
from sprayplan.coating.stage import meet_thickness, simulate_plan
from sprayplan.config import JobConfig
from sprayplan.export.plan_json import tip_speeds
from sprayplan.export.plan_read import read_plan_file
from sprayplan.job import run_job
from sprayplan.programs.check import check_program
from sprayplan.programs.model import LINEAR
from sprayplan.programs.stage import read_programs
from sprayplan.refine.limits import plan_dwell
from sprayplan.timing.stage import real_plan

PART = "reach_curved_part.ply"
REACH = {"units": "m", "region": "x > -250"}
OUT = {"viewer": False, "report": False, "samples": 420}
#: Joint accelerations at which the arm makes the tuned speeds on some strokes and not on others (the UR's
#: 80.2 deg/s^2 keeps it far below them almost everywhere on this part).
FAST_ARM = {"arm_max_acceleration_deg_s2": [2000.0] * 6}


def _job(**sections) -> JobConfig:
    return JobConfig().replace(load=REACH, output=OUT, **sections)


@pytest.fixture(scope="module")
def tuned(testdata):
    """The reach part tuned to 50 um, then tuned again within its limits and timed, its film at the timed speeds."""
    job = _job(
        coating={"thickness_um": 50.0},
        tuning={"touch_up_rounds": 0, "limit_rounds": 2},
        timing={**FAST_ARM, "film_at_timed_speeds": True},
    )
    return job, run_job(testdata / "meshes" / PART, job, until="totals")


def _spray(plan) -> np.ndarray:
    return np.concatenate([np.full(len(s), s.spray_on) for s in plan.strokes])


def test_tuned_speeds_never_exceed_the_achievable_ones(tuned):
    _, state = tuned
    summary = state.tuning["within_limits"]
    assert summary["rounds"] >= 1 and summary["capped_waypoints"] > 0
    spray = _spray(state.plan)
    dwell, timed = plan_dwell(state.plan), np.concatenate(state.timing.dwell)
    # the plan's factor is at least the timed one: the gun is never asked to go faster than the robot makes it
    assert (dwell[spray] >= timed[spray]).all()
    # per segment: the plan's tip speed is at most the one the robot makes (at the timed factors, as the robot
    # programs run it), and the robot is slower than the plan's first tuning asked somewhere
    real = real_plan(state.plan, state.timing)
    checked = 0
    for planned, made in zip(state.plan.strokes, real.strokes):
        if planned.spray_on and len(planned) > 1:
            assert (tip_speeds(planned, state.job) <= tip_speeds(made, state.job) * (1 + 1e-12)).all()
            checked += len(planned)
    assert checked > 1000


def test_the_film_at_timed_speeds_is_the_one_the_tuning_predicted(tuned):
    _, state = tuned
    summary = state.tuning["within_limits"]
    predicted, timed = summary["predicted"], summary["timed"]
    assert timed["mean_um"] == pytest.approx(predicted["mean_um"], rel=0.01)
    assert timed["share_in_spec"] == pytest.approx(predicted["share_in_spec"], abs=0.01)
    # the job's film is the film at the timed speeds, as simulated afresh from the timed plan
    again = simulate_plan(state.part, real_plan(state.plan, state.timing), state.job)
    np.testing.assert_allclose(state.film.thickness_um, again.thickness_um, rtol=1e-6, atol=1e-6)
    # and the tuning did something: untuned within the limits, the film at the timed speeds is far from what
    # the tuning at the planned speeds predicted
    before = state.tuning["after"]
    assert abs(timed["mean_um"] - before["mean_um"]) > 5.0


def test_what_the_limits_make_impossible_is_said_and_nothing_else_changes(tuned):
    job, state = tuned
    summary = state.tuning["within_limits"]
    over = summary["over_spec"]
    # the arm cannot go fast enough on some strokes: too much paint there, said with where and how much
    assert (
        over["area_mm2"] > 0 and over["max_um"] > 55.0 and over["max_excess_um"] == pytest.approx(over["max_um"] - 55.0)
    )
    places = summary["places"]
    assert places and all(0 < p["speed_share"] < 1 for p in places if p["speed_share"] is not None)
    assert sum(p["over_spec_area_mm2"] for p in places) <= over["area_mm2"] + 1e-3 * len(places)  # rounded each
    for p in places:
        stroke = state.plan.stations[p["station"]].strokes[p["stroke"]]
        assert stroke.spray_on and p["capped_waypoints"] <= len(stroke)
    # flow, spacing and speed are the film target's choice, untouched
    assert state.job == meet_thickness(job)[0]
    # and the command line's summary says it
    shown = dataclasses.replace(state, totals={**state.totals, "planning_time_s": 1.0})
    line = summary_line(shown, "out").splitlines()[-1]
    assert line.startswith("speeds within the joints' limits: ") and f"{100 * over['share']:.1f}%" in line


def test_without_the_rounds_the_timed_film_is_not_the_predicted_one(testdata):
    """The same job with ``limit_rounds = 0``: the tuning ignores the limits, and the film at the timed speeds
    is far off the tuning's prediction (which the rounds above fix)."""
    job = _job(coating={"thickness_um": 50.0}, tuning={"touch_up_rounds": 0, "limit_rounds": 0}, timing=FAST_ARM)
    state = run_job(testdata / "meshes" / PART, job, until="timing")
    assert "within_limits" not in state.tuning
    timed = real_plan(state.plan, state.timing)
    spray = _spray(state.plan)
    assert (plan_dwell(timed)[spray] > plan_dwell(state.plan)[spray] * 1.01).sum() > 100


@pytest.fixture(scope="module")
def programmed(testdata, tmp_path_factory):
    """The reach part planned and timed with every program format (UR's default limits: slowed strokes)."""
    out = tmp_path_factory.mktemp("timed") / "plan"
    argv = ["-q", "plan", str(testdata / "meshes" / PART), "--units", "m", "--region", REACH["region"], "-o", str(out)]
    assert (
        main(
            [*argv, "--no-viewer", "--no-report", *(a for f in ("urscript", "rapid", "krl") for a in ("--program", f))]
        )
        == 0
    )
    return out


@pytest.mark.parametrize("fmt", ["urscript", "rapid", "krl"])
def test_programs_read_back_carry_the_timed_speeds(programmed, fmt):
    read = read_plan_file(programmed / "plan.json")
    assert read.timing is not None
    job, plan = read.job, read.plan
    timed = real_plan(plan, read.timing, job)
    program = read_programs(programmed / "programs" / fmt, job, fmt)
    # the programs are the timed plan's, move by move, speeds within the written digits
    result = check_program(program, timed, job)
    assert result.failures == [] and result.max_speed_mm_s <= 1e-4
    # and not the plan's planned speeds: where the robot is slower, the programs are slower
    assert check_program(program, plan, job).failures
    linear = [m for m in program.moves if m.kind == LINEAR]
    planned = max(float(tip_speeds(s, job).max()) for s in plan.strokes if s.spray_on)
    assert max(m.speed_mm_s for m in linear) <= max(planned, job.export.approach_speed_mm_s) * (1 + 1e-6)


def test_a_robot_files_lower_limits_give_a_longer_cycle(programmed, testdata, tmp_path):
    """A robot TOML with half the UR's joint accelerations, through ``[kinematics] robot_file``: every stroke
    and move takes longer, and plan.json names the file."""
    robot = tmp_path / "slow_ur5.toml"
    robot.write_text('preset = "ur5"\nmax_acceleration_deg_s2 = [40.1, 40.1, 40.1, 40.1, 40.1, 40.1]\n')
    config = tmp_path / "process.toml"
    config.write_text(f'[kinematics]\nrobot_file = "{robot.as_posix()}"\n')
    out = tmp_path / "slow"
    argv = ["-q", "plan", str(testdata / "meshes" / PART), "--units", "m", "--region", REACH["region"]]
    assert main([*argv, "-c", str(config), "-o", str(out), "--no-viewer", "--no-report"]) == 0
    fast = json.loads((programmed / "plan.json").read_text())
    slow = json.loads((out / "plan.json").read_text())
    assert slow["settings"]["kinematics"]["robot_file"] == robot.as_posix()
    assert fast["settings"]["kinematics"]["robot_file"] is None
    # the same plan's geometry and joints (the limits change no pose), timed slower
    assert slow["totals"]["cycle_time_length_over_speed_s"] == fast["totals"]["cycle_time_length_over_speed_s"]
    assert slow["totals"]["cycle_time_s"] > fast["totals"]["cycle_time_s"] * 1.2
    assert slow["totals"]["timing"]["spray_time_s"] > fast["totals"]["timing"]["spray_time_s"]


@pytest.mark.parametrize(
    "text, words",
    [
        ('preset = "ur5"\nmax_velocity_deg_s = [180, 180, 0, 180, 180, 180]\n', "max_velocity_deg_s"),
        ('preset = "ur5"\nmax_acceleration_deg_s2 = [80, 80, nan, 80, 80, 80]\n', "max_acceleration_deg_s2"),
        ('preset = "ur5"\nmax_acceleration_deg_s2 = [80, 80, -80, 80, 80, 80]\n', "max_acceleration_deg_s2"),
        ('preset = "ur5"\nmax_velocity_deg_s = [180, 180, 180]\n', "max_velocity_deg_s"),
        ('preset = "ur5"\nbase_xyz_mm = [0, 0, 100]\n', "base_"),
        ('preset = "r5150"\n', "6 joints"),
        ("preset = \n", "TOML"),
        (None, "no such file"),
    ],
)
@pytest.mark.parametrize("how", ["option", "setting"])
def test_a_bad_robot_file_is_one_line_and_nothing_written(testdata, tmp_path, capsys, text, words, how):
    robot = tmp_path / "my_ur5.toml"
    if text is not None:
        robot.write_text(text)
    out = tmp_path / "out"
    argv = ["-q", "plan", str(testdata / "meshes" / PART), "--units", "m", "-o", str(out)]
    if how == "option":
        argv += ["--robot-file", str(robot)]
    else:
        config = tmp_path / "process.toml"
        config.write_text(f'[kinematics]\nrobot_file = "{robot.as_posix()}"\n')
        argv += ["-c", str(config)]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sprayplan: error: ")
    assert "robot_file" in lines[0] and "my_ur5.toml" in lines[0] and words in lines[0]
    assert not out.exists()
