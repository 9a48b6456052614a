"""The paint's flow fitted to the speeds a cell's robots make (cells.fit, ``[timing] fit_flow``; issue 18)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sprayplan.cells.fit import FLOW_SHARES, fit_flow, scaled_job
from sprayplan.cells.plan import plan_cell
from sprayplan.cells.spec import cell_from_dict
from sprayplan.coating.process import load_preset
from sprayplan.coating.stage import meet_thickness, process_for
from sprayplan.config import FilmConfig, JobConfig
from sprayplan.errors import ConfigError
from tests.helpers import grid_box
from tests.test_cell_timing import CELL


def test_a_lower_flow_paints_the_same_film_slower():
    """With a film target the gun speed follows the flow (film = flow over speed and spacing): half the flow,
    half the speed, the same spacing."""
    job = JobConfig().replace(coating={"thickness_um": 50.0})
    own, chosen = meet_thickness(job)
    half, chosen_half = meet_thickness(job.replace(coating={"flow_ml_min": 100.0}))
    assert chosen["flow_ml_min"] == load_preset("seed000_circle").flow_ml_min == 200.0
    assert chosen_half["flow_ml_min"] == 100.0
    assert half.motion.gun_speed_mm_s == pytest.approx(own.motion.gun_speed_mm_s / 2, rel=1e-12)
    assert half.paths.spacing_mm == own.paths.spacing_mm
    assert process_for(half).flow_ml_min == 100.0 and process_for(own).flow_ml_min == 200.0


def test_scaled_job_keeps_flow_over_speed():
    job = JobConfig().replace(coating={"thickness_um": 50.0}, motion={"gun_speed_mm_s": 400.0})
    scaled = scaled_job(job, 0.35, 200.0)
    assert scaled.coating.flow_ml_min == pytest.approx(70.0)
    assert scaled.motion.gun_speed_mm_s == pytest.approx(140.0)
    assert process_for(scaled).flow_ml_min / process_for(scaled).speed_mm_s == pytest.approx(200.0 / 400.0)


@pytest.mark.parametrize("bad", [0.0, -5.0, float("nan"), float("inf")])
def test_a_bad_flow_names_its_key(bad):
    with pytest.raises(ConfigError, match="coating.flow_ml_min"):
        FilmConfig(flow_ml_min=bad)


def test_the_fit_keeps_the_most_in_spec_within_the_cycle_budget():
    """Synthetic timings: the cycle grows as the flow falls and the share in spec rises; the share kept is the
    one with the most in spec whose cycle is within the budget times the first's; the first share over the
    budget is reported and ends the search."""
    cycles = {1.0: 1000.0, 0.7: 1100.0, 0.5: 1300.0, 0.35: 1700.0, 0.25: 2300.0}
    in_spec = {1.0: 0.30, 0.7: 0.45, 0.5: 0.60, 0.35: 0.70, 0.25: 0.78}
    timed_at = []

    def share_of(job_):
        return round(job_.motion.gun_speed_mm_s / 400.0, 6)

    def time_at(job_):
        timed_at.append(share_of(job_))
        return [SimpleNamespace(cycle_s=cycles[share_of(job_)])]

    for budget, want in ((1.5, 0.5), (1.0, 1.0), (1.7, 0.35), (3.0, 0.25)):
        timed_at.clear()
        job = JobConfig().replace(motion={"gun_speed_mm_s": 400.0}, timing={"fit_cycle_budget": budget})
        fitted, timed, report = fit_flow(job, time_at, lambda job_, timed_: in_spec[share_of(job_)])
        within = [f for f in FLOW_SHARES if cycles[f] <= budget * cycles[1.0]]
        assert want == max(within, key=lambda f: in_spec[f])
        assert report["flow_share"] == want and timed[0].cycle_s == cycles[want]
        assert fitted.coating.flow_ml_min == pytest.approx(200.0 * want)
        assert fitted.motion.gun_speed_mm_s == pytest.approx(400.0 * want)
        assert report["cycle_budget_s"] == pytest.approx(budget * 1000.0)
        # every share within the budget, and the first beyond it (not measured), then no more
        over = [f for f in FLOW_SHARES if f not in within][:1]
        assert timed_at == within + over
        assert [t["flow_share"] for t in report["tried"]] == within + over
        assert [t.get("timed_share_in_spec") for t in report["tried"]] == [in_spec[f] for f in within] + [None] * len(
            over
        )
        assert [t.get("over_budget", False) for t in report["tried"]] == [False] * len(within) + [True] * len(over)


@pytest.mark.parametrize("bad", [0.5, float("nan"), 1e6])
def test_a_bad_cycle_budget_names_its_key(bad):
    from sprayplan.config import TimingConfig

    with pytest.raises(ConfigError, match="timing.fit_cycle_budget"):
        TimingConfig(fit_cycle_budget=bad)


@pytest.fixture(scope="module")
def fitted_and_not():
    cell = cell_from_dict(CELL)
    job = JobConfig().replace(coating={"thickness_um": 50.0}, tuning={"touch_up_rounds": 0})
    part = grid_box(n=8, size=(600.0, 300.0, 200.0))
    return plan_cell(part, cell, job), plan_cell(part, cell, job.replace(timing={"fit_flow": False}))


def test_a_fitted_cell_plan_is_the_plan_at_the_share_kept(fitted_and_not):
    fitted, own = fitted_and_not
    fit = fitted.report["flow_fit"]
    kept = next(t for t in fit["tried"] if t["flow_share"] == fit["flow_share"])
    # the job carries the flow and speed kept, both scaled by the same share: the same film target
    ratio = own.job.motion.gun_speed_mm_s / process_for(own.job).flow_ml_min
    assert fitted.job.motion.gun_speed_mm_s == pytest.approx(fit["flow_share"] * own.job.motion.gun_speed_mm_s)
    assert fitted.job.motion.gun_speed_mm_s / process_for(fitted.job).flow_ml_min == pytest.approx(ratio)
    assert fitted.report["chosen_for_thickness"]["flow_ml_min"] == pytest.approx(fit["flow_ml_min"])
    # the planned film does not change with the flow
    np.testing.assert_allclose(fitted.film.thickness_um, own.film.thickness_um, rtol=1e-12, atol=1e-12)
    # what the fit measured at the share kept is what the plan reports
    timed = fitted.report["film"]["at_timed_speeds"]["whole"]
    assert timed["share_in_spec"] == pytest.approx(kept["timed_share_in_spec"], abs=1e-6)
    assert fitted.report["cycle_time_s"] == pytest.approx(kept["timed_cycle_s"], abs=1e-3)
    # and at the share 1 it measured the unfitted plan
    first = fit["tried"][0]
    assert first["flow_share"] == 1.0
    own_timed = own.report["film"]["at_timed_speeds"]["whole"]
    assert first["timed_share_in_spec"] == pytest.approx(own_timed["share_in_spec"], abs=1e-6)
    assert first["timed_cycle_s"] == pytest.approx(own.report["cycle_time_s"], abs=1e-3)
    assert "flow_fit" not in own.report
    # the share kept has the most surface in spec of all within the cycle budget
    within = [t for t in fit["tried"] if not t.get("over_budget")]
    assert all(t["timed_cycle_s"] <= fit["cycle_budget_s"] + 1e-3 for t in within)
    assert kept["timed_share_in_spec"] == max(t["timed_share_in_spec"] for t in within)
    assert fit["cycle_budget_s"] == pytest.approx(1.5 * first["timed_cycle_s"], abs=2e-3)


def test_speeds_tuned_within_the_limits_are_the_speeds_the_robots_make():
    """``[tuning] limit_rounds`` with a cell: after the rounds no reached spray waypoint asks for more speed
    than its robot makes (its planned time factor is at least its timed one), so the plan's own film is the
    film at the timed speeds."""
    from sprayplan.cells.plan import reached_strokes
    from sprayplan.cells.timing import timed_factors
    from sprayplan.cells.work import owned

    cell = cell_from_dict(CELL)
    job = JobConfig().replace(coating={"thickness_um": 50.0}, tuning={"touch_up_rounds": 0, "limit_rounds": 2})
    plan = plan_cell(grid_box(n=8, size=(600.0, 300.0, 200.0)), cell, job)
    summary = plan.report["within_limits"]
    assert summary["rounds"] >= 1 and summary["capped_waypoints"] > 0
    timed = timed_factors(plan.robots, plan.job)
    planned = [np.concatenate([s.dwell for s in r.strokes]) for r in plan.robots]
    _, owners = reached_strokes(plan.robots)
    at, wanted = owned(timed, plan.robots, owners), owned(planned, plan.robots, owners)
    assert len(at) == len(wanted) > 100
    assert (at <= wanted * (1 + 1e-9)).all()
    film = plan.report["film"]
    assert film["whole"]["share_in_spec"] == pytest.approx(film["at_timed_speeds"]["whole"]["share_in_spec"], abs=0.005)
    assert film["whole"]["mean_um"] == pytest.approx(film["at_timed_speeds"]["whole"]["mean_um"], rel=0.01)


def test_owned_gathers_the_runs_in_the_tunings_order():
    robots = [SimpleNamespace(strokes=[np.zeros(3), np.zeros(2)]), SimpleNamespace(strokes=[np.zeros(4)])]
    values = [np.array([0, 1, 2, 3, 4]), np.array([10, 11, 12, 13])]
    from sprayplan.cells.work import owned

    got = owned(values, robots, [(1, 0, 1, 3), (0, 1, 0, 2), (0, 0, 0, 1)])
    assert got.tolist() == [11, 12, 3, 4, 0]
