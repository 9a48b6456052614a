"""The main job as one line of stages (sprayplan.job): the Python route equals the command line, errors name
their stage and part, progress comes stage by stage."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.config import JobConfig
from sprayplan.errors import InputError, StageError
from sprayplan.job import STAGES, run_job

REGION = "x > -250"


@pytest.fixture(scope="module")
def both_routes(testdata, tmp_path_factory):
    """A part with a film target planned twice: by ``sprayplan plan`` and by ``run_job`` from Python."""
    part = testdata / "meshes" / "reach_curved_part.ply"
    cli_out = tmp_path_factory.mktemp("cli")
    code = main(
        ["-q", "plan", str(part), "--units", "m", "--region", REGION, "--thickness-um", "50", "-o", str(cli_out)]
    )
    assert code == 0
    py_out = tmp_path_factory.mktemp("py")
    job = JobConfig().replace(load={"units": "m", "region": REGION}, coating={"thickness_um": 50.0})
    calls = []
    result = run_job(part, job, outdir=py_out, progress=lambda *a: calls.append(a))
    return cli_out, py_out, result, calls


def _without_times(data: dict) -> dict:
    data = dict(data)
    data["totals"] = {k: v for k, v in data["totals"].items() if k != "planning_time_s"}
    return data


def test_the_python_route_and_the_command_line_give_the_same_plan_and_film(both_routes):
    cli_out, py_out, result, _ = both_routes
    cli_plan = json.loads((cli_out / "plan.json").read_text())
    py_plan = json.loads((py_out / "plan.json").read_text())
    assert _without_times(cli_plan) == _without_times(py_plan)
    assert (cli_out / "waypoints.csv").read_bytes() == (py_out / "waypoints.csv").read_bytes()
    assert (cli_out / "thickness.csv").read_bytes() == (py_out / "thickness.csv").read_bytes()
    assert json.loads((cli_out / "coating.json").read_text()) == json.loads((py_out / "coating.json").read_text())
    # the film target took effect on the Python route too: the spacing and speed were chosen, the speeds tuned
    assert result.chosen and result.job.paths.spacing_mm == pytest.approx(result.chosen["spacing_mm"])
    assert result.tuning and result.film is not None
    dwell = np.concatenate([s.dwell for s in result.plan.strokes])
    assert np.ptp(dwell) > 0


def test_progress_reports_every_stage_in_order(both_routes):
    *_, calls = both_routes
    started = [stage for stage, done, total in calls if (done, total) == (0, 0)]
    assert started == [s.name for s in STAGES] + ["outputs"]
    # the counted stages report each unit once, up to their total
    for name in ("kinematics", "ordering"):
        counts = [(done, total) for stage, done, total in calls if stage == name and total > 0]
        assert counts and counts[-1][0] == counts[-1][1]
        assert [d for d, _ in counts] == list(range(1, counts[-1][1] + 1))
    # the outputs stage counts the report's images, from none drawn to all of them
    counts = [(done, total) for stage, done, total in calls if stage == "outputs" and total > 0]
    assert [d for d, _ in counts] == list(range(counts[-1][1] + 1))


def test_until_stops_after_that_stage(testdata):
    part = testdata / "meshes" / "reach_curved_part.ply"
    job = JobConfig().replace(load={"units": "m", "region": REGION})
    state = run_job(part, job, until="stations")
    assert state.layout is not None and state.plan is None
    assert list(state.timings_s) == [s.name for s in STAGES[:5]]
    with pytest.raises(InputError, match="until must be one of"):
        run_job(part, job, until="nothing")


def test_a_stage_error_names_the_stage_and_the_part(testdata):
    part = testdata / "meshes" / "reach_curved_part.ply"
    with pytest.raises(StageError, match=r"^region: .*reach_curved_part.ply") as info:
        run_job(part, JobConfig().replace(load={"units": "m", "region": "z > 99999"}))
    assert info.value.stage == "region"
    with pytest.raises(StageError, match=r"^load: .*no_such_part.stl"):
        run_job(part.parent / "no_such_part.stl")


def test_a_bug_inside_a_stage_keeps_its_type_and_gains_a_note(testdata, monkeypatch):
    import sprayplan.job as job_module

    def broken(state, progress):
        raise ZeroDivisionError("boom")

    stages = tuple(job_module.Stage(s.name, broken if s.name == "ordering" else s.run) for s in STAGES)
    monkeypatch.setattr(job_module, "STAGES", stages)
    with pytest.raises(ZeroDivisionError) as info:
        run_job(
            testdata / "meshes" / "reach_curved_part.ply", JobConfig().replace(load={"units": "m", "region": REGION})
        )
    assert any("ordering stage" in note and "reach_curved_part" in note for note in info.value.__notes__)


def test_the_command_line_names_the_stage_in_one_line(testdata, tmp_path, capsys):
    part = testdata / "meshes" / "reach_curved_part.ply"
    code = main(["plan", str(part), "--units", "m", "--region", "z > 99999", "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    # led by the option the user gave, then the stage and the part
    assert code == 2 and err.count("\n") == 1 and err.startswith("sprayplan: error: --region: region: ")
    assert not (tmp_path / "out" / "plan.json").exists()


def test_every_stage_result_is_frozen_and_read_only(both_routes):
    import dataclasses

    *_, result, _ = both_routes
    arrays = [
        result.part.vertices,
        result.strokes[0].points,
        result.layout.platform_mm,
        result.layout.unassigned,
        result.plan.stations[0].q9,
        result.plan.stations[0].method,
        result.plan.stations[0].reachable,
        result.plan.home_mm,
        result.film.thickness_mm,
        result.film.points,
    ]
    for array in arrays:
        assert not array.flags.writeable
        if len(array):
            with pytest.raises(ValueError, match="read-only"):
                array[0] = array[0]
    for frozen in (result, result.layout, result.ordered, result.plan, result.plan.stations[0], result.film):
        with pytest.raises(dataclasses.FrozenInstanceError):
            frozen.name = "changed"  # type: ignore[misc]
