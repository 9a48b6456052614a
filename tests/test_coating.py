"""Tests of the coating stage: deposition models, film thickness, occlusion, spacing, fitting, droplets."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.integrate import trapezoid

from sprayplan.coating import (
    CoatingConfig,
    DropletConfig,
    Process,
    SprayPattern,
    StrokeOverride,
    bell_field,
    bell_potential,
    choose_spacing_and_speed,
    coating_report,
    drag_factor,
    film_across,
    fit_density,
    fit_droplets,
    fit_stroke_profile,
    list_presets,
    load_preset,
    process_from_dict,
    process_to_toml,
    ripple_cv,
    shot_thickness,
    simulate,
    simulate_droplets,
)
from sprayplan.coating.droplet import acceleration, integrate
from sprayplan.coating.report import share_interval
from sprayplan.config import PathConfig
from sprayplan.errors import ConfigError, InputError
from sprayplan.export.film import write_thickness_csv, write_thickness_ply
from sprayplan.io.load import load_part
from sprayplan.paths.planner import plan_paths
from sprayplan.types import Part, Paths, Stroke, Targets
from tests.helpers import plate

PATTERNS = {
    "flat": SprayPattern("flat", 50.0, 113.0),
    "parabolic": SprayPattern("parabolic", 50.0, 113.0),
    "beta": SprayPattern("beta", 60.0, 150.0, beta=3.5),
    "beta_low": SprayPattern("beta", 40.0, 113.0, beta=1.4),
    "gaussian": SprayPattern("gaussian", 60.0, 113.0, sigma_mm=18.0),
    "double_beta": SprayPattern("double_beta", a_mm=30.0, b_mm=70.0, beta1=2.5, beta2=1.6, standoff_mm=200.0),
}


def merge(*parts: Part) -> Part:
    vertices, faces, offset = [], [], 0
    for part in parts:
        vertices.append(part.vertices)
        faces.append(part.faces + offset)
        offset += len(part.vertices)
    return Part(np.concatenate(vertices), np.concatenate(faces), None, "merged")


def straight_stroke(start, end, standoff, step=5.0, spray_on=True) -> Stroke:
    """A stroke over the plane z = 0 from start to end (x, y), gun above at ``standoff``."""
    length = math.dist(start, end)
    count = max(round(length / step) + 1, 2)
    t = np.linspace(0.0, 1.0, count)[:, None]
    pts = np.column_stack([np.array(start) + t * (np.array(end) - np.array(start)), np.zeros(count)])
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    return Stroke(pts, normals, pts + standoff * normals, spray_on)


# ------------------------------------------------------------------------------------------- patterns


@pytest.mark.parametrize("name", sorted(PATTERNS))
def test_patterns_integrate_to_the_volume_rate(name):
    pattern = PATTERNS[name]
    r = pattern.support_radius_mm
    step = r / 400.0
    g = np.arange(-r, r + step / 2, step)
    x, y = np.meshgrid(g, g)
    integral = pattern.density(x.ravel(), y.ravel()).sum() * step * step
    assert integral == pytest.approx(1.0, abs=4e-3)
    process = Process(pattern, flow_ml_min=240.0, solids_fraction=0.5, transfer_efficiency=0.7)
    rate = process.volume_rate_mm3_s * integral
    assert rate == pytest.approx(240.0 * 1000 / 60 * 0.5 * 0.7, rel=4e-3)


@pytest.mark.parametrize("name", sorted(PATTERNS))
def test_profile_is_the_density_integrated_along_the_travel(name):
    pattern = PATTERNS[name]
    r = pattern.support_radius_mm
    x = np.linspace(-r, r, 20001)
    for y in (0.0, 0.3 * r, 0.7 * r):
        numeric = trapezoid(pattern.density(x, np.full_like(x, y)), x)
        assert pattern.profile([y])[0] == pytest.approx(numeric, rel=3e-3, abs=1e-9)
    assert pattern.profile([1.01 * r])[0] == 0.0


def test_double_beta_is_elliptical_and_peaks_on_the_axis():
    p = PATTERNS["double_beta"]
    assert p.density([0.0], [0.0])[0] > p.density([10.0], [0.0])[0] > 0
    assert p.density([29.9], [0.0])[0] > 0 and p.density([30.1], [0.0])[0] == 0
    assert p.density([0.0], [69.9])[0] > 0 and p.density([0.0], [70.1])[0] == 0
    assert p.density([20.0], [60.0])[0] == 0  # outside the ellipse (x/a)^2 + (y/b)^2 > 1


# --------------------------------------------------------------------------------------------- thickness


@pytest.fixture(scope="module")
def big_plate():
    return plate(-320, 320, -220, 220, 2.5)


def test_mass_balance_on_a_plate_that_catches_all_the_spray(big_plate):
    process = Process(
        PATTERNS["parabolic"], flow_ml_min=180.0, speed_mm_s=120.0, solids_fraction=0.45, transfer_efficiency=0.7
    )
    strokes = (
        straight_stroke((-150, -60), (150, -60), 113.0),
        straight_stroke((150, 0), (-150, 40), 113.0),
        straight_stroke((-150, 40), (-150, 120), 113.0, spray_on=False),
    )
    result = simulate(big_plate, Paths(strokes, 113.0, 50.0), process, config=CoatingConfig(occlusion="none"))
    spray_time = (300.0 + math.hypot(300, 40)) / 120.0
    expected = 180.0 * 1000.0 / 60.0 * 0.45 * 0.7 * spray_time
    deposited = float((result.thickness_mm * result.area_mm2).sum())
    assert deposited == pytest.approx(expected, rel=0.01)
    assert result.stroke_deposit_mm3.sum() == pytest.approx(deposited, rel=1e-6)
    assert result.stroke_paint_ml[2] == 0.0 and result.stroke_deposit_mm3[2] == 0.0
    assert result.stroke_paint_ml[0] == pytest.approx(180.0 * 300.0 / 120.0 / 60.0)


def test_thickness_scales_as_one_over_speed(big_plate):
    paths = Paths((straight_stroke((-100, 0), (100, 0), 113.0),), 113.0, 50.0)
    slow = simulate(big_plate, paths, Process(PATTERNS["gaussian"], speed_mm_s=100.0))
    fast = simulate(big_plate, paths, Process(PATTERNS["gaussian"], speed_mm_s=300.0))
    painted = slow.thickness_mm > 1e-4
    assert painted.sum() > 100
    np.testing.assert_allclose(fast.thickness_mm[painted] * 3.0, slow.thickness_mm[painted], rtol=1e-5)


@pytest.mark.parametrize("name", ["parabolic", "gaussian", "double_beta"])
def test_a_very_short_stroke_reproduces_the_pattern(name):
    pattern = PATTERNS[name]
    h = pattern.standoff_mm
    part = plate(-90, 90, -90, 90, 3.0)
    duration, length = 2.0, 0.01
    stroke = Stroke(
        np.array([[-length / 2, 0, 0], [length / 2, 0, 0]]),
        np.tile([0, 0, 1.0], (2, 1)),
        np.array([[-length / 2, 0, h], [length / 2, 0, h]]),
    )
    process = Process(pattern, flow_ml_min=120.0, speed_mm_s=length / duration)
    result = simulate(part, Paths((stroke,), h, 50.0), process)
    x, y = part.vertices[:, 0], part.vertices[:, 1]
    expected = process.volume_rate_mm3_s * duration * pattern.density(x, y)
    # away from the edge of a truncated pattern, where a rounding error switches a point in or out
    off_edge = (pattern.shape(x * 0.99, y * 0.99) > 0) == (pattern.shape(x * 1.01, y * 1.01) > 0)
    assert off_edge.mean() > 0.95
    np.testing.assert_allclose(result.thickness_mm[off_edge], expected[off_edge], rtol=2e-3, atol=1e-4 * expected.max())


def test_film_scales_with_distance_and_incidence():
    """A gun twice as far spreads the same pattern twice as wide; a tilted plate gets the cosine law."""
    pattern = PATTERNS["parabolic"]
    h = pattern.standoff_mm
    pts = np.column_stack([np.linspace(-90, 90, 61), np.zeros(61), np.zeros(61)])
    up = np.tile([0.0, 0.0, 1.0], (61, 1))
    far = shot_thickness(pts, up, [0, 0, 2 * h], [0, 0, -1], pattern, 100.0, 1.0, along=[1, 0, 0])
    scaled = pattern.scaled(2.0)
    np.testing.assert_allclose(far, 100.0 * scaled.density(pts[:, 0], pts[:, 1]), rtol=1e-9, atol=1e-15)
    # the axis point of a plate tilted by 40 degrees: flux times cos(40)
    tilt = math.radians(40.0)
    normal = np.array([[math.sin(tilt), 0.0, math.cos(tilt)]])
    centre = shot_thickness(np.zeros((1, 3)), normal, [0, 0, h], [0, 0, -1], pattern, 100.0, 1.0)
    assert centre[0] == pytest.approx(100.0 * pattern.density([0.0], [0.0])[0] * math.cos(tilt), rel=1e-9)
    # a surface facing away gets nothing
    assert shot_thickness(np.zeros((1, 3)), -up[:1], [0, 0, h], [0, 0, -1], pattern, 100.0, 1.0)[0] == 0.0


@pytest.mark.parametrize("preset", ["seed000_circle", "seed000_flat"])
def test_parallel_strokes_at_the_chosen_spacing_are_even(preset):
    process = load_preset(preset)
    choice = choose_spacing_and_speed(process, 50.0)
    process = process.with_(speed_mm_s=choice.speed_mm_s)
    s = choice.spacing_mm
    part = plate(-260, 260, -260, 260, 2.0)
    strokes = []
    count = int(np.ceil((150.0 + 2.0 * process.pattern.radius_mm) / s))
    for k, y in enumerate(np.arange(-count, count + 1) * s):
        a, b = (-360.0, y), (360.0, y)
        strokes.append(straight_stroke(a, b, 113.0) if k % 2 == 0 else straight_stroke(b, a, 113.0))
    result = simulate(part, Paths(tuple(strokes), 113.0, s), process)
    inner = (np.abs(part.vertices[:, 0]) < 150) & (np.abs(part.vertices[:, 1]) < 150)
    t = result.thickness_um[inner]
    assert t.std() / t.mean() <= 0.03
    assert t.mean() == pytest.approx(50.0, rel=0.02)
    assert choice.cv <= 0.01
    # seed 000's fixed overlap 0.4 is less even for these patterns
    assert ripple_cv(process.pattern, 49.19) > 3 * choice.cv


def test_planned_paths_paint_a_plate_evenly_up_to_its_edges():
    # the planner's edge passes (past the edges along the strokes) and leads (past the strokes' ends) give a
    # flat plate the in-panel film everywhere, edges and corners included; without edge passes the film
    # thins out along the first and last strokes
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process, 50.0)
    process = process.with_(speed_mm_s=choice.speed_mm_s)
    part = plate(0.0, 600.0, 0.0, 400.0, 5.0)
    config = CoatingConfig(occlusion="none")
    paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, direction="y"))
    whole = coating_report(simulate(part, paths, process, config=config))["all"]
    assert whole["share_in_spec"] == 1.0
    assert whole["cv"] <= 0.02
    bare = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, direction="y", edge_passes=0))
    thin = coating_report(simulate(part, bare, process, config=config))["all"]
    assert thin["share_in_spec"] < 0.95 and thin["min_um"] < 0.6 * 50.0


def test_speed_puts_the_mean_on_target_for_any_spacing():
    process = load_preset("bell003")
    choice = choose_spacing_and_speed(process, 42.0)
    y = np.linspace(0, choice.spacing_mm, 400, endpoint=False)
    mean_um = process.volume_rate_mm3_s / choice.speed_mm_s * film_across(process.pattern, choice.spacing_mm, y).mean()
    assert mean_um * 1000.0 == pytest.approx(42.0, rel=1e-3)


@pytest.mark.parametrize("method", ["zbuffer", "raster", "rays"])
def test_occluded_points_get_nothing(method):
    if method == "rays":
        import trimesh

        if not trimesh.ray.has_embree:
            pytest.importorskip("rtree")
    lower = plate(-200, 200, -200, 200, 5.0, z=0.0)
    upper = plate(-200, 0, -200, 200, 20.0, z=30.0)  # covers x < 0, coarse triangles
    part = merge(lower, upper)
    strokes = [straight_stroke((-300, y), (300, y), 143.0) for y in (-40.0, 0.0, 40.0)]
    strokes = [Stroke(s.points + [0, 0, 30.0], s.normals, s.tcp, True) for s in strokes]
    result = simulate(
        part, Paths(tuple(strokes), 113.0, 40.0), Process(PATTERNS["parabolic"]), config=CoatingConfig(occlusion=method)
    )
    v = result.points
    low = v[:, 2] == 0.0
    shadow = low & (v[:, 0] < -20) & (v[:, 0] > -160) & (np.abs(v[:, 1]) < 40)  # seen from no gun position
    lit = low & (v[:, 0] > 20) & (np.abs(v[:, 1]) < 40)
    top = (v[:, 2] == 30.0) & (v[:, 0] < -20) & (np.abs(v[:, 1]) < 40)
    assert np.all(result.thickness_mm[shadow] == 0.0)
    assert np.all(result.thickness_mm[lit] > 0.0)
    assert np.all(result.thickness_mm[top] > 0.0)
    unoccluded = simulate(
        part, Paths(tuple(strokes), 113.0, 40.0), Process(PATTERNS["parabolic"]), config=CoatingConfig(occlusion="none")
    )
    assert np.all(unoccluded.thickness_mm[shadow] > 0.0)
    np.testing.assert_allclose(result.thickness_mm[lit], unoccluded.thickness_mm[lit])


def test_transfers_and_overrides():
    part = plate(-200, 200, -150, 150, 5.0)
    strokes = (
        straight_stroke((-100, -40), (100, -40), 113.0),
        straight_stroke((100, -40), (100, 40), 113.0, spray_on=False),
        straight_stroke((100, 40), (-100, 40), 113.0),
    )
    paths = Paths(strokes, 113.0, 80.0)
    process = Process(PATTERNS["parabolic"], speed_mm_s=200.0)
    base = simulate(part, paths, process)
    off = simulate(part, paths, process, overrides={2: StrokeOverride(spray_on=False)})
    first_only = simulate(part, Paths(strokes[:1], 113.0, 80.0), process)
    np.testing.assert_allclose(off.thickness_mm, first_only.thickness_mm, rtol=1e-6, atol=1e-12)
    slow = simulate(
        part, paths, process, overrides=[None, StrokeOverride(flow_ml_min=500.0), StrokeOverride(speed_mm_s=100.0)]
    )
    assert slow.stroke_flow_ml_min[1] == 0.0  # a transfer never sprays, whatever its flow
    assert slow.stroke_deposit_mm3[2] == pytest.approx(2.0 * base.stroke_deposit_mm3[2], rel=1e-5)
    with pytest.raises(ConfigError):
        simulate(part, paths, process, overrides={7: StrokeOverride(spray_on=False)})


def test_real_curved_panel(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process)
    paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, step_mm=10.0))
    result = simulate(
        part, paths, process.with_(speed_mm_s=choice.speed_mm_s), config=CoatingConfig(speed_along="surface")
    )
    report = coating_report(result, samples=420, edge_band_mm=60.0)
    sprayed_solids = float(result.stroke_paint_ml.sum()) * process.solids_fraction * process.transfer_efficiency
    assert 0.5 * sprayed_solids < report["paint"]["dry_film_on_part_ml"] <= sprayed_solids * 1.001
    assert report["interior"]["mean_um"] == pytest.approx(50.0, rel=0.1)
    assert report["interior"]["cv"] < report["painted"]["cv"]
    assert len(report["measuring_points"]["indices"]) == 420
    json.dumps(report)


# ------------------------------------------------------------------------------------------ report, files


def test_report_statistics_and_files(tmp_path, big_plate):
    paths = Paths((straight_stroke((-100, 0), (100, 0), 113.0),), 113.0, 50.0)
    result = simulate(big_plate, paths, Process(PATTERNS["parabolic"], speed_mm_s=100.0))
    t = result.thickness_um
    report = coating_report(result, target_um=float(np.median(t[t > 5])), tolerance_um=5.0, samples=30, seed=4)
    painted = t >= 0.1 * report["spec"]["target_um"]
    w = result.area_mm2[painted]
    assert report["painted"]["mean_um"] == pytest.approx((t[painted] * w).sum() / w.sum())
    inside = np.abs(t[painted] - report["spec"]["target_um"]) <= 5.0
    assert report["painted"]["share_in_spec"] == pytest.approx(w[inside].sum() / w.sum())
    again = coating_report(result, target_um=report["spec"]["target_um"], samples=30, seed=4)
    assert again["measuring_points"]["indices"] == report["measuring_points"]["indices"]
    assert all(painted[i] for i in report["measuring_points"]["indices"])
    at = t[report["measuring_points"]["indices"]]
    spec = report["spec"]["target_um"]
    k = int((np.abs(at - spec) <= 5.0).sum())
    assert report["measuring_points"]["share_in_spec_ci95"] == pytest.approx(share_interval(k, 30), abs=1e-15)

    csv = tmp_path / "film.csv"
    write_thickness_csv(csv, result)
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert csv.read_text().splitlines()[0] == "x,y,z,thickness_um"
    np.testing.assert_allclose(table[:, 3], t, atol=1e-3)

    import trimesh

    ply = tmp_path / "film.ply"
    write_thickness_ply(ply, result)
    mesh = trimesh.load(ply, process=False)
    assert len(mesh.vertices) == len(result.points) and len(mesh.faces) == len(result.faces)
    np.testing.assert_allclose(mesh.metadata["_ply_raw"]["vertex"]["data"]["thickness_um"], t, rtol=1e-6, atol=1e-3)
    assert mesh.visual.vertex_colors.shape == (len(t), 4)


# ---------------------------------------------------------------------------------------------- presets


def test_presets_hold_the_seed_parameters(tmp_path):
    assert {"seed000_circle", "seed000_flat", "bell003"} <= set(list_presets())
    circle = load_preset("seed000_circle")
    assert circle.pattern.radius_mm == 50.0 and circle.pattern.standoff_mm == 113.0
    bell = load_preset("bell003")
    assert (bell.bell.speed_krpm, bell.bell.shaping_air1_l_min, bell.bell.shaping_air2_l_min, bell.bell.voltage_kv) == (
        40.0,
        250.0,
        180.0,
        60.0,
    )
    assert bell.extra["tracks"]["roof_and_tail"]["flow_ml_min"][:4] == [290.0, 240.0, 300.0, 200.0]
    assert bell.extra["tracks"]["left"]["flow_ml_min"][-1] == 0.0  # the transfer track
    path = tmp_path / "mine.toml"
    path.write_text(process_to_toml(bell.with_(name="mine")))
    back = load_preset(path)
    assert back.pattern == bell.pattern and back.flow_ml_min == bell.flow_ml_min and back.bell == bell.bell
    with pytest.raises(ConfigError):
        process_from_dict({"pattern": {"kind": "beta", "radius_mm": 50.0, "colour": 1}})
    with pytest.raises(ConfigError):
        load_preset("no_such_preset")


# ---------------------------------------------------------------------------------------------- fitting


@pytest.mark.parametrize(
    "truth, kw",
    [
        (SprayPattern("beta", 55.0, 113.0, beta=2.7), {}),
        (SprayPattern("gaussian", 70.0, 113.0, sigma_mm=21.0), {}),
        (SprayPattern("parabolic", 45.0, 113.0), {}),
        (
            SprayPattern("double_beta", a_mm=35.0, b_mm=80.0, beta1=2.2, beta2=1.7, standoff_mm=113.0),
            {"a_mm": 35.0, "beta1": 2.2},
        ),
    ],
)
def test_fitting_recovers_known_parameters(truth, kw):
    y = np.linspace(-120, 120, 97)
    q, speed, centre = 950.0, 250.0, 6.5
    thickness_um = q / speed * truth.profile(y - centre) * 1000.0
    fit = fit_stroke_profile(
        y, thickness_um, speed, truth.kind, standoff_mm=113.0, flow_ml_min=200.0, solids_fraction=0.5, **kw
    )
    assert fit.volume_rate_mm3_s == pytest.approx(q, rel=1e-3)
    assert fit.centre_mm == pytest.approx(centre, abs=0.05)
    for key, value in truth.to_dict().items():
        if isinstance(value, float):
            assert getattr(fit.pattern, key) == pytest.approx(value, rel=0.01), key
    assert fit.transfer_efficiency == pytest.approx(q / (200 * 1000 / 60 * 0.5), rel=1e-3)


def test_fitting_a_noisy_measurement_stays_close():
    truth = SprayPattern("beta", 55.0, 113.0, beta=2.7)
    y = np.linspace(-100, 100, 81)
    t = 800.0 / 200.0 * truth.profile(y) * 1000.0
    noisy = t + np.random.default_rng(1).normal(0.0, 0.01 * t.max(), len(t))
    fit = fit_stroke_profile(y, noisy, 200.0, "beta")
    assert fit.pattern.radius_mm == pytest.approx(55.0, rel=0.05)
    assert fit.volume_rate_mm3_s == pytest.approx(800.0, rel=0.02)


def test_density_fit_recovers_a_two_dimensional_pattern():
    truth = SprayPattern("double_beta", a_mm=40.0, b_mm=90.0, beta1=2.0, beta2=3.0, standoff_mm=200.0)
    g = np.arange(-100.0, 100.5, 4.0)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    fit = fit_density(x, y, truth.density(x, y), "double_beta", standoff_mm=200.0)
    for key in ("a_mm", "b_mm", "beta1", "beta2"):
        assert getattr(fit.pattern, key) == pytest.approx(getattr(truth, key), rel=0.01), key


# --------------------------------------------------------------------------------------------- droplets


def test_drag_factor_follows_eq_22():
    re = np.array([0.0, 1.0, 125.0, 999.0, 1000.0, 5000.0])
    np.testing.assert_allclose(drag_factor(re), [1.0, 1 + 1 / 6, 1 + 25 / 6, 1 + 999 ** (2 / 3) / 6, 18.3, 91.5])


def test_a_drop_in_still_air_falls_as_stokes_predicts():
    config = DropletConfig(dt_s=1e-6, gravity_m_s2=(0.0, 0.0, -9.81), density_kg_m3=1000.0)
    d = np.array([10e-6])
    mass = 1000.0 * math.pi / 6.0 * d**3
    mu = config.air_viscosity_pa_s
    tau = mass[0] / (3.0 * math.pi * mu * d[0])
    terminal = mass[0] * 9.81 / (3.0 * math.pi * mu * d[0])
    steps = 4000
    _, _, history = integrate(
        np.array([[0.0, 0.0, 0.1]]),
        np.zeros((1, 3)),
        d,
        mass,
        np.zeros(1),
        config,
        field=False,
        air=False,
        steps=steps,
        record_every=500,
    )
    re = d[0] * terminal * config.air_density_kg_m3 / mu
    assert re < 1e-2  # Stokes regime: f = 1 + Re^(2/3) / 6 ~ 1
    for t, x, v in history[1:]:
        fall = terminal * (1.0 - math.exp(-t / tau))
        drop = terminal * (t - tau * (1.0 - math.exp(-t / tau)))
        assert -v[0, 2] == pytest.approx(fall, rel=3e-3)
        assert 0.1 - x[0, 2] == pytest.approx(drop, rel=5e-3)
        assert v[0, 0] == 0.0 and v[0, 1] == 0.0
    assert -history[-1][2][0, 2] == pytest.approx(terminal, rel=3e-3)


def test_a_charged_drop_in_the_field_alone_is_accelerated_along_e():
    config = DropletConfig(gravity_m_s2=(0.0, 0.0, 0.0), dt_s=1e-7)
    x0 = np.array([[0.05, 0.02, 0.12], [0.0, 0.0, 0.05]])
    d = np.full(2, 30e-6)
    mass = config.density_kg_m3 * math.pi / 6.0 * d**3
    charge = config.charge_to_mass_c_kg * mass
    e = bell_field(x0, 60e3, 0.0325, 0.2)
    acc = acceleration(np.zeros((2, 3)), np.zeros((2, 3)), d, mass, charge, e, config)
    np.testing.assert_allclose(acc, charge[:, None] * e / mass[:, None], rtol=1e-12)
    _, _, history = integrate(x0, np.zeros((2, 3)), d, mass, charge, config, air=False, steps=1, record_every=1)
    v1 = history[-1][2]
    np.testing.assert_allclose(v1, config.dt_s * charge[:, None] * e / mass[:, None], rtol=1e-12)
    cos = np.einsum("ij,ij->i", v1, e) / (np.linalg.norm(v1, axis=1) * np.linalg.norm(e, axis=1))
    np.testing.assert_allclose(cos, 1.0)
    assert e[1, 2] < 0  # below the bell the field points down to the grounded part


def test_bell_field_is_minus_the_gradient_of_its_potential():
    args = (60e3, 0.0325, 0.2)
    pts = np.array([[0.03, -0.04, 0.1], [0.1, 0.05, 0.02], [0.0, 0.0, 0.15]])
    eps = 1e-6
    grad = np.stack(
        [
            (bell_potential(pts + eps * np.eye(3)[k], *args) - bell_potential(pts - eps * np.eye(3)[k], *args))
            / (2 * eps)
            for k in range(3)
        ],
        axis=1,
    )
    np.testing.assert_allclose(bell_field(pts, *args), -grad, rtol=1e-5)
    plane = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.0]])
    np.testing.assert_allclose(bell_potential(plane, *args), 0.0, atol=1e-6)
    assert bell_potential(np.array([[0.0, 0.0, 0.2 - 0.0325]]), *args)[0] == pytest.approx(60e3)


def test_seeded_droplet_runs_repeat_and_give_a_pattern():
    config = DropletConfig(count=60, seed=3, max_time_s=0.05)
    a, b = simulate_droplets(config), simulate_droplets(config)
    np.testing.assert_array_equal(a.landing_mm, b.landing_mm)
    assert a.transfer_efficiency == b.transfer_efficiency
    assert 0.0 < a.transfer_efficiency <= 1.0
    c = simulate_droplets(DropletConfig(count=60, seed=4, max_time_s=0.05))
    assert not np.array_equal(np.nan_to_num(a.landing_mm), np.nan_to_num(c.landing_mm))
    fit = fit_droplets(a, "gaussian", half_width_mm=250.0, cell_mm=25.0)
    assert fit.pattern.standoff_mm == config.standoff_mm
    assert fit.transfer_efficiency == a.transfer_efficiency


def test_targets_instead_of_vertices_are_hidden_too():
    lower = plate(-200, 200, -200, 200, 5.0, z=0.0)
    upper = plate(-200, 0, -200, 200, 20.0, z=30.0)
    part = merge(lower, upper)
    strokes = tuple(
        Stroke(s.points + [0, 0, 30.0], s.normals, s.tcp, True)
        for s in (straight_stroke((-300, y), (300, y), 143.0) for y in (-40.0, 0.0, 40.0))
    )
    pts = np.array([[-100.0, 0.0, 0.0], [100.0, 0.0, 0.0], [-100.0, 0.0, 30.0]])
    targets = Targets(pts, np.tile([0.0, 0.0, 1.0], (3, 1)))
    result = simulate(part, Paths(strokes, 113.0, 40.0), Process(PATTERNS["parabolic"]), targets=targets)
    assert result.thickness_mm[0] == 0.0 and result.thickness_mm[1] > 0 and result.thickness_mm[2] > 0


# ----------------------------------------------------------------------------------------- surface samples


def test_a_coarse_mesh_is_split_finely_enough_for_the_film():
    from sprayplan.coating.sampling import surface_samples

    # a 400 x 300 panel of two triangles: its four corners alone cannot say how much of it is in spec
    panel = Part(np.array([[0, 0, 0], [400, 0, 0], [400, 300, 0], [0, 300, 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    samples = surface_samples(panel, max_edge_mm=10.0)
    edges = samples.points[samples.faces] - samples.points[np.roll(samples.faces, 1, axis=1)]
    assert np.linalg.norm(edges, axis=2).max() <= 10.0 + 1e-9
    assert samples.area_mm2.sum() == pytest.approx(400 * 300)
    assert len(np.unique(samples.points.round(6), axis=0)) == len(samples.points)  # shared vertices merged
    np.testing.assert_allclose(samples.normals, [[0, 0, 1.0]] * len(samples.points), atol=1e-12)
    # on a coarse curved mesh the new vertices take the original vertex normals, interpolated: a cylinder of
    # radius 200 in 12 facets keeps normals within the facets' span and of unit length
    angle = np.linspace(0, np.pi / 2, 13)
    ring = np.stack([200 * np.sin(angle), np.zeros(13), 200 * np.cos(angle)], 1)
    vertices = np.vstack([ring, ring + [0, 300, 0]])
    faces = np.array([[i, i + 13, i + 1] for i in range(12)] + [[i + 1, i + 13, i + 14] for i in range(12)])
    cylinder = Part(vertices, faces)
    curved = surface_samples(cylinder, max_edge_mm=10.0)
    original = surface_samples(cylinder, max_edge_mm=0.0).normals
    np.testing.assert_allclose(np.linalg.norm(curved.normals, axis=1), 1.0)
    # along the first ring's chords the normal is the linear blend of the two end vertices' normals
    edge = np.flatnonzero(np.abs(curved.points[:, 1]) < 1e-9)
    assert len(edge) > 12 * 4
    for k in edge:
        p = curved.points[k]
        i = min(int(np.searchsorted(angle, np.arctan2(p[0], p[2]), side="right")) - 1, 11)
        t = np.linalg.norm(p - ring[i]) / np.linalg.norm(ring[i + 1] - ring[i])
        blend = (1 - t) * original[i] + t * original[i + 1]
        np.testing.assert_allclose(curved.normals[k], blend / np.linalg.norm(blend), atol=1e-9)
    assert surface_samples(panel, max_edge_mm=0.0).points.shape == (4, 3)


def test_film_statistics_on_a_coarse_panel_match_a_fine_one():
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process, 50.0)
    process = process.with_(speed_mm_s=choice.speed_mm_s)
    coarse = Part(np.array([[0, 0, 0], [600, 0, 0], [600, 400, 0], [0, 400, 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    fine = plate(0.0, 600.0, 0.0, 400.0, 5.0)
    config = PathConfig(spacing_mm=choice.spacing_mm, direction="y", edge_passes=0)
    paths = plan_paths(fine, config)
    a = coating_report(simulate(coarse, paths, process, config=CoatingConfig(occlusion="none", sample_edge_mm=5.0)))
    b = coating_report(simulate(fine, paths, process, config=CoatingConfig(occlusion="none", sample_edge_mm=0.0)))
    for key in ("mean_um", "share_in_spec", "cv"):
        assert a["all"][key] == pytest.approx(b["all"][key], rel=0.02, abs=0.005)


def test_a_notched_plate_is_painted_evenly_round_the_notch():
    # a 600 x 400 plate with a 240 x 150 notch cut into its top edge: the layers across the notch stop at its
    # sides, and the edge along the notch's bottom runs with the strokes, between two layers
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process, 50.0)
    process = process.with_(speed_mm_s=choice.speed_mm_s)
    full = plate(0.0, 600.0, 0.0, 400.0, 5.0)
    centre = full.vertices[full.faces].mean(axis=1)
    keep = ~((centre[:, 0] > 180) & (centre[:, 0] < 420) & (centre[:, 1] > 250))
    part = Part(full.vertices, full.faces[keep])
    paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, direction="y"))
    # an inner edge pass runs through the notch, off the part, a spacing above the last layer below it
    below = max(
        float(np.median(s.points[s.on_part, 1]))
        for s in paths.spray_strokes
        if s.on_part.any() and np.median(s.points[s.on_part, 1]) < 250 and np.ptp(s.points[s.on_part, 0]) > 500
    )
    in_notch = [
        s
        for s in paths.spray_strokes
        if np.any(
            ~s.on_part
            & (s.points[:, 0] > 250)
            & (s.points[:, 0] < 350)
            & (np.abs(s.points[:, 1] - below - choice.spacing_mm) < 1e-6)
        )
    ]
    assert in_notch
    film = coating_report(simulate(part, paths, process, config=CoatingConfig(occlusion="none")))["all"]
    # the notch's bottom edge too: without the inner pass it falls to about 33 um
    assert film["share_in_spec"] == 1.0 and film["cv"] <= 0.02 and film["min_um"] >= 45.0
    bare = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, direction="y", edge_passes=0))
    thin = coating_report(simulate(part, bare, process, config=CoatingConfig(occlusion="none")))["all"]
    assert thin["share_in_spec"] < 0.95


def test_a_cloud_without_normals_is_simulated_with_normals_facing_the_gun():
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process, 50.0)
    process = process.with_(speed_mm_s=choice.speed_mm_s)
    mesh = plate(0.0, 400.0, 0.0, 300.0, 5.0, flip=True)  # normals -z: the gun paints from below
    paths = plan_paths(mesh, PathConfig(spacing_mm=choice.spacing_mm, direction="y"))
    cloud = Part(mesh.vertices, np.zeros((0, 3)), None, "cloud")
    film = simulate(cloud, paths, process, config=CoatingConfig(occlusion="none"))
    inside = (np.abs(film.points[:, 0] - 200) < 150) & (np.abs(film.points[:, 1] - 150) < 100)
    assert np.all(film.thickness_um[inside] == pytest.approx(50.0, rel=0.03))
    with pytest.raises(InputError):  # nothing to tell the outside by
        simulate(cloud, Paths((), 113.0, 37.0), process)


@pytest.mark.parametrize("inside, count", [(0, 420), (395, 420), (420, 420), (7, 30), (1, 1)])
def test_the_measuring_points_share_interval_is_wilsons(inside, count):
    """The 95 % interval of a share measured at random points against Wilson's score interval worked out here,
    and it holds the share measured."""
    z = 1.959963984540054  # the normal distribution's 97.5 % quantile
    p = inside / count
    centre = (p + z * z / (2 * count)) / (1 + z * z / count)
    half = z / (1 + z * z / count) * math.sqrt(p * (1 - p) / count + z * z / (4 * count * count))
    lo, hi = share_interval(inside, count)
    assert (lo, hi) == pytest.approx((centre - half, centre + half), abs=1e-12)
    assert lo <= p <= hi
    assert share_interval(0, 0) == [0.0, 1.0]
