"""Time factors at the waypoints (Stroke.dwell) and speeds tuned to the film (sprayplan.refine.tuning)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sprayplan.coating import (
    CoatingConfig,
    Process,
    SprayPattern,
    choose_spacing_and_speed,
    coating_report,
    deposit_matrix,
    load_preset,
    simulate,
)
from sprayplan.config import PathConfig
from sprayplan.errors import ConfigError
from sprayplan.io.load import load_part
from sprayplan.paths.planner import plan_paths
from sprayplan.paths.speed import segment_speeds, stroke_time
from sprayplan.refine.touchup import TOUCH_UP_MIN_DWELL, touch_up_strokes
from sprayplan.refine.tuning import TuningConfig, tune_speeds
from sprayplan.surface.region import select_region
from sprayplan.types import Part, Paths, Stroke
from tests.helpers import plate


def nm_unit(v):
    return v / np.linalg.norm(v)


H = 113.0
PATTERN = SprayPattern("parabolic", 50.0, H)


def line(y: float, x0: float = -150.0, x1: float = 150.0, step: float = 10.0) -> Stroke:
    count = round(abs(x1 - x0) / step) + 1
    pts = np.column_stack([np.linspace(x0, x1, count), np.full(count, y), np.zeros(count)])
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    return Stroke(pts, normals, pts + H * normals)


@pytest.fixture(scope="module")
def panel():
    return plate(-260, 260, -200, 200, 5.0)


def strokes_on(ys, **kw) -> Paths:
    strokes = [line(y, **kw) for y in ys]
    strokes = [s if k % 2 == 0 else s.reversed() for k, s in enumerate(strokes)]
    transfers = [
        Stroke(
            np.array([a.points[-1], b.points[0]]), np.tile([0.0, 0, 1], (2, 1)), np.array([a.tcp[-1], b.tcp[0]]), False
        )
        for a, b in itertools.pairwise(strokes)
    ]
    order = [strokes[0]]
    for t, s in zip(transfers, strokes[1:]):
        order += [t, s]
    return Paths(tuple(order), H, 40.0)


def test_the_film_is_linear_in_the_time_factors(panel):
    paths = strokes_on([-60.0, -15.0, 35.0])
    process = Process(PATTERN, speed_mm_s=300.0)
    samples, matrix = deposit_matrix(panel, paths, process)
    rng = np.random.default_rng(3)
    dwell = rng.uniform(0.5, 2.0, matrix.shape[1])
    starts = np.r_[0, np.cumsum([len(s) for s in paths.strokes])]
    tuned = Paths(tuple(s.with_dwell(dwell[a : a + len(s)]) for s, a in zip(paths.strokes, starts)), H, 40.0)
    film = simulate(panel, tuned, process).thickness_mm
    predicted = np.asarray(matrix @ dwell).ravel()
    assert film.max() > 1e-3
    np.testing.assert_allclose(predicted, film, rtol=1e-5, atol=1e-9)
    # transfers paint nothing: their waypoints' columns are empty
    transfer_cols = np.concatenate([np.arange(a, a + len(s)) for s, a in zip(paths.strokes, starts) if not s.spray_on])
    assert matrix[:, transfer_cols].nnz == 0
    np.testing.assert_allclose(samples.points, simulate(panel, paths, process).points)


def test_doubling_every_factor_doubles_the_time_and_the_film(panel):
    paths = strokes_on([-30.0, 20.0])
    slow = Paths(tuple(s.with_dwell(np.full(len(s), 2.0)) for s in paths.strokes), H, 40.0)
    process = Process(PATTERN, speed_mm_s=250.0)
    base, doubled = simulate(panel, paths, process), simulate(panel, slow, process)
    sprayed = base.stroke_flow_ml_min > 0
    np.testing.assert_allclose(doubled.stroke_time_s[sprayed], 2 * base.stroke_time_s[sprayed], rtol=1e-12)
    np.testing.assert_allclose(doubled.thickness_mm, 2 * base.thickness_mm, rtol=1e-5, atol=1e-12)
    s = slow.strokes[0]
    assert stroke_time(s.tcp, s.points, 250.0, dwell=s.dwell) == pytest.approx(2 * s.length_mm / 250.0)


def test_a_segment_runs_at_the_speed_over_the_mean_of_its_ends_factors():
    stroke = line(0.0, -20.0, 20.0, 10.0).with_dwell([1.0, 2.0, 0.5, 1.0, 1.0])
    speeds = segment_speeds(stroke.tcp, stroke.points, 300.0, dwell=stroke.dwell)
    np.testing.assert_allclose(speeds, 300.0 / np.array([1.5, 1.25, 0.75, 1.0]))
    # run backwards or cut, every segment keeps its speed
    back = stroke.reversed()
    np.testing.assert_allclose(segment_speeds(back.tcp, back.points, 300.0, dwell=back.dwell), speeds[::-1])
    cut = stroke.part(slice(1, 4))
    np.testing.assert_allclose(segment_speeds(cut.tcp, cut.points, 300.0, dwell=cut.dwell), speeds[1:3])


@pytest.mark.parametrize("dwell", [[1.0, 0.0, 1.0], [1.0, np.nan, 1.0], [1.0, 1.0], [1.0, -2.0, 1.0]])
def test_bad_time_factors_are_refused(dwell):
    stroke = line(0.0, -10.0, 10.0, 10.0)
    with pytest.raises(ValueError, match="dwell"):
        stroke.with_dwell(dwell)


def test_tuning_brings_an_uneven_film_onto_target(panel):
    # strokes too far apart for the pattern (ripple) and too fast for 50 um
    paths = strokes_on([-105.0, -45.0, 15.0, 75.0], x0=-200.0, x1=200.0)
    process = Process(PATTERN, speed_mm_s=420.0)
    config = TuningConfig(min_dwell=0.5, max_dwell=2.0)
    tuning = tune_speeds(panel, paths, process, 50.0, 5.0, config=config)
    summary = tuning.summary(50.0, 5.0)
    assert summary["before"]["mean_um"] < 45.0
    assert abs(summary["after"]["mean_um"] - 50.0) < abs(summary["before"]["mean_um"] - 50.0)
    assert summary["after"]["share_in_spec"] > summary["before"]["share_in_spec"] + 0.2
    assert summary["after"]["cv"] < summary["before"]["cv"]
    dwell = np.concatenate([s.dwell for s in tuning.paths.strokes])
    assert dwell.min() >= 0.5 - 1e-12 and dwell.max() <= 2.0 + 1e-12
    # geometry unchanged; transfers keep factor 1
    for old, new in zip(paths.strokes, tuning.paths.strokes):
        np.testing.assert_array_equal(old.tcp, new.tcp)
        if not new.spray_on:
            np.testing.assert_array_equal(new.dwell, 1.0)
    # the prediction is the film the tuned plan leaves
    film = simulate(panel, tuning.paths, process).thickness_um
    np.testing.assert_allclose(film, tuning.after_um, rtol=1e-5, atol=1e-6)
    # it repeats exactly
    again = tune_speeds(panel, paths, process, 50.0, 5.0, config=config)
    np.testing.assert_array_equal(np.concatenate([s.dwell for s in again.paths.strokes]), dwell)


def test_smoothing_limits_the_change_between_neighbouring_waypoints(panel):
    paths = strokes_on([-105.0, -45.0, 15.0, 75.0], x0=-200.0, x1=200.0)
    process = Process(PATTERN, speed_mm_s=420.0)

    def roughness(smoothing):
        tuning = tune_speeds(panel, paths, process, 50.0, 5.0, config=TuningConfig(smoothing=smoothing))
        return max(float(np.abs(np.diff(s.dwell)).max()) for s in tuning.paths.strokes if s.spray_on)

    assert roughness(1.0) < roughness(0.0)


def test_tuning_settings_are_checked():
    for bad in (
        {"min_dwell": 0.01},
        {"max_dwell": 0.9},
        {"max_dwell": 50.0},
        {"smoothing": -1.0},
        {"iterations": 0},
        {"loss": "l1"},
    ):
        with pytest.raises(ConfigError):
            TuningConfig(**bad)
    with pytest.raises(ConfigError):
        tune_speeds(plate(0, 10, 0, 10, 5.0), strokes_on([0.0]), Process(PATTERN), 50.0, 0.0)


def test_tuning_on_the_real_curved_panel(testdata):
    part = select_region(load_part(testdata / "meshes" / "reach_curved_part.ply", units="m"), "x > -700")
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process, 50.0)
    paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, step_mm=10.0))
    process = process.with_(speed_mm_s=choice.speed_mm_s)
    coating = CoatingConfig(sample_edge_mm=0.0)
    tuning = tune_speeds(part, paths, process, 50.0, 5.0, coating=coating)
    before = coating_report(simulate(part, paths, process, config=coating))["painted"]
    after = coating_report(simulate(part, tuning.paths, process, config=coating))["painted"]
    assert after["share_in_spec"] > before["share_in_spec"]
    assert after["cv"] < before["cv"]
    assert math.isclose(after["mean_um"], 50.0, rel_tol=0.05)
    film = simulate(part, tuning.paths, process, config=coating).thickness_um
    np.testing.assert_allclose(film, tuning.after_um, rtol=1e-4, atol=1e-4)


def test_equal_bounds_leave_the_speeds_alone(panel):
    paths = strokes_on([-30.0, 20.0])
    tuning = tune_speeds(panel, paths, Process(PATTERN), 50.0, 5.0, config=TuningConfig(min_dwell=1.0, max_dwell=1.0))
    assert all((s.dwell == 1.0).all() for s in tuning.paths.strokes)
    np.testing.assert_allclose(tuning.after_um, tuning.before_um)


def test_time_factors_survive_paths_json(tmp_path):
    from sprayplan.export.paths_json import read_paths_json, write_paths_json

    paths = strokes_on([-30.0, 20.0])
    rng = np.random.default_rng(0)
    tuned = Paths(tuple(s.with_dwell(rng.uniform(0.5, 2.0, len(s))) for s in paths.strokes), H, 40.0)
    write_paths_json(tmp_path / "paths.json", tuned)
    back = read_paths_json(tmp_path / "paths.json")
    for a, b in zip(tuned.strokes, back.strokes):
        np.testing.assert_allclose(b.dwell, a.dwell, atol=1e-6)


# ------------------------------------------------------------------------------------------- touch-ups


FLANGE_NORMAL = np.array([math.sin(math.radians(60)), 0.0, math.cos(math.radians(60))])


def flanged_panel() -> Part:
    """A 400 x 300 mm panel (z = 0, normal +z) with a 60 mm flange turned down 60 degrees along x = 200, its
    normal ``FLANGE_NORMAL`` (outwards and up)."""
    top = plate(-200, 200, -150, 150, 5.0)
    side = plate(0, 60, -150, 150, 5.0)  # (s, y): s runs down the flange
    s_, y = side.vertices[:, 0], side.vertices[:, 1]
    down = np.array([math.cos(math.radians(60)), 0.0, -math.sin(math.radians(60))])
    side_v = np.column_stack([200.0 + s_ * down[0], y, s_ * down[2]])
    faces = side.faces
    tri = side_v[faces]
    if np.cross(tri[0, 1] - tri[0, 0], tri[0, 2] - tri[0, 0]) @ FLANGE_NORMAL < 0:
        faces = faces[:, ::-1]
    return Part(np.vstack([top.vertices, side_v]), np.vstack([top.faces, faces + len(top.vertices)]), None, "flanged")


def test_touch_ups_aim_at_a_flange_the_strokes_miss():
    part = flanged_panel()
    ys = np.arange(-140.0, 141.0, 35.0)
    strokes = [
        Stroke(pts, np.tile([0.0, 0, 1], (len(pts), 1)), pts + H * np.array([0.0, 0, 1]))
        # run out 50 mm past the flange's edge, as a lead does: the flange gets grazing spray
        for pts in (np.column_stack([np.linspace(-180, 250, 44), np.full(44, y), np.zeros(44)]) for y in ys)
    ]
    paths = Paths(tuple(strokes), H, 35.0)
    process = Process(PATTERN, speed_mm_s=float(choose_spacing_and_speed(Process(PATTERN), 50.0).speed_mm_s))
    tuning = tune_speeds(part, paths, process, 50.0, 5.0)
    flange = (tuning.samples.points[:, 0] > 201.0) & (tuning.samples.points[:, 2] < -5.0)
    assert tuning.tuned[flange].mean() > 0.5  # painted ...
    assert np.median(tuning.after_um[flange]) < 45.0  # ... but by grazing spray only
    extra = touch_up_strokes(
        tuning.samples,
        tuning.after_um,
        tuning.tuned,
        50.0,
        5.0,
        standoff_mm=H,
        step_mm=10.0,
        lead_mm=50.0,
        min_area_mm2=625.0,
    )
    assert all(s.kind == "touch-up" for s in extra)
    aimed = [s for s in extra if nm_unit(s.normals.mean(axis=0)) @ FLANGE_NORMAL > 0.95]
    assert len(aimed) == 1, "the flange should get one touch-up stroke"  # (the top's short edges get theirs)
    first = aimed[0]
    assert first.kind == "touch-up" and first.spray_on
    np.testing.assert_allclose(first.tcp, first.points + H * first.normals)
    assert (first.normals @ FLANGE_NORMAL > 0.95).all()
    middle = first.points[5:-5]  # leads of 50 mm at 10 mm steps at each end
    # near the flange's plane, within its width
    assert np.abs((middle - [200.0, 0, 0]) @ FLANGE_NORMAL).max() < 2.0
    assert (middle[:, 2] < 0).all() and (middle[:, 2] > -60 * math.sin(math.radians(60))).all()
    assert np.ptp(first.points[:, 1]) > 200.0  # along the flange
    steps = np.linalg.norm(np.diff(middle, axis=0), axis=1)
    assert np.median(steps) == pytest.approx(10.0, rel=0.2)
    # with the touch-up (factors free down to TOUCH_UP_MIN_DWELL) the flange comes into spec
    both = Paths((*paths.strokes, *extra), H, 35.0)
    lower = np.concatenate([np.full(len(s), TOUCH_UP_MIN_DWELL if s.kind == "touch-up" else 0.5) for s in both.strokes])
    again = tune_speeds(part, both, process, 50.0, 5.0, lower=lower)
    inside = (again.after_um[flange] >= 45) & (again.after_um[flange] <= 55)
    before_inside = (tuning.after_um[flange] >= 45) & (tuning.after_um[flange] <= 55)
    assert inside.mean() > before_inside.mean() + 0.3
    assert again.summary(50, 5)["after"]["share_in_spec"] > tuning.summary(50, 5)["after"]["share_in_spec"]
    main_dwell = np.concatenate([s.dwell for s in again.paths.strokes if s.kind != "touch-up"])
    assert main_dwell.min() >= 0.5 - 1e-9


def test_no_touch_ups_where_the_film_is_in_spec(panel):
    paths = strokes_on([-60.0, -15.0, 35.0])
    tuning = tune_speeds(panel, paths, Process(PATTERN, speed_mm_s=300.0), 50.0, 5.0)
    film = np.full(len(tuning.samples.points), 50.0)
    kw = dict(standoff_mm=H, step_mm=10.0, lead_mm=50.0, min_area_mm2=625.0)
    assert touch_up_strokes(tuning.samples, film, tuning.tuned, 50.0, 5.0, **kw) == []
    # and a patch smaller than the least area gets none either
    small = film.copy()
    small[np.linalg.norm(tuning.samples.points[:, :2], axis=1) < 10.0] = 20.0
    assert touch_up_strokes(tuning.samples, small, np.ones(len(film), bool), 50.0, 5.0, **kw) == []


def test_lower_bounds_are_checked(panel):
    paths = strokes_on([0.0])
    with pytest.raises(ConfigError, match="lower"):
        tune_speeds(panel, paths, Process(PATTERN), 50.0, 5.0, lower=np.zeros(3))


def test_plan_settings_of_the_tuning_are_checked():
    from sprayplan.config import RefineConfig

    for bad in (
        {"touch_up_rounds": -1},
        {"touch_up_rounds": 1.5},
        {"min_dwell": 0.0},
        {"max_dwell": 0.5},
        {"tune_speed": "yes"},
    ):
        with pytest.raises(ConfigError):
            RefineConfig(**bad)
