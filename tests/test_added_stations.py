"""Touch-ups the planned stations cannot reach: new gantry stations (refine.added_stations, refine.extend), aims turned
to help the film (coating.touchup.aim_touch_ups) and the tuning's dead band."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sprayplan.coating import Process, SprayPattern, simulate
from sprayplan.errors import ConfigError
from sprayplan.refine.touchup import aim_touch_ups, misfit, tilted, touch_up_strokes
from sprayplan.refine.tuning import TuningConfig, tune_speeds
from sprayplan.robots.gantry import Gantry, pose_errors
from sprayplan.types import Paths, Stroke
from tests.helpers import plate

H = 113.0
PATTERN = SprayPattern("parabolic", 50.0, H)


@pytest.fixture(scope="module")
def reach(testdata):
    """The real curved panel planned for 50 um, and touch-ups aimed at its front lip's underside (the
    samples facing forward and down): the stations over the panel reach only part of them."""
    from sprayplan.coating.sampling import surface_samples
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from tests.helpers import planned as plan

    job = JobConfig().replace(coating={"thickness_um": 50.0})
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    samples = surface_samples(part)
    lip = (samples.normals[:, 0] > 0.6) & (samples.normals[:, 2] < -0.2)
    film = np.where(lip, 20.0, 50.0)
    kw = dict(standoff_mm=H, step_mm=10.0, lead_mm=50.0, min_area_mm2=625.0)
    strokes = touch_up_strokes(samples, film, np.ones(len(film), bool), 50.0, 5.0, **kw)
    assert strokes
    return part, job, plan(part, job), strokes


def touch_up_waypoints(plan_) -> int:
    return sum(len(s) for st in plan_.stations for s in st.strokes if s.kind == "touch-up")


def test_new_stations_reach_what_the_planned_ones_miss(reach):
    from sprayplan.refine.extend import with_added_strokes
    from sprayplan.surface.poses import stroke_poses as gun_poses

    _, job, planned, strokes = reach
    without = with_added_strokes(planned, strokes, job, new_stations=0)
    with_new = with_added_strokes(planned, strokes, job, new_stations=2)
    assert len(without.stations) == len(planned.stations)
    added = [st for st in with_new.stations if st.index not in {s.index for s in planned.stations}]
    assert 1 <= len(added) <= 2
    assert len({st.index for st in with_new.stations}) == len(with_new.stations)
    assert touch_up_waypoints(with_new) > touch_up_waypoints(without)
    gantry = Gantry()
    height = np.median([st.platform_mm[2] for st in planned.stations])
    for st in added:
        assert st.platform_mm[2] == pytest.approx(height)  # at the plan's gantry height
        assert all(s.kind == "touch-up" for s in st.strokes if s.spray_on)
        assert len(st.q9) == sum(len(s) for s in st.strokes)
        spray = np.concatenate([np.full(len(s), s.spray_on) for s in st.strokes])
        assert st.reachable[spray].all()
        # forward kinematics of the solved joints puts the spray target where it is wanted
        wanted = np.concatenate([gun_poses(s) for s in st.strokes])[spray] @ gantry.gun.target2gun
        position, axis = pose_errors(gantry.target2world(st.q9[spray]), wanted)
        assert position.max() <= job.kinematics.position_tol_mm * (1 + 1e-6)
        assert axis.max() <= math.radians(job.kinematics.axis_tol_deg) * (1 + 1e-6)
    # the planned stations keep their strokes and order; each new one sits where it adds the least travel
    kept = [st for st in with_new.stations if st.index in {s.index for s in planned.stations}]
    assert [st.index for st in kept] == [st.index for st in without.stations]
    for st in added:  # inserted in index order: compare with the tour as it was then
        planned_index = {p.index for p in planned.stations}
        then = [s for s in with_new.stations if s.index <= st.index or s.index in planned_index]
        others = [s for s in then if s is not st]
        stops = [planned.home_mm, *[s.platform_mm for s in others], planned.home_mm]
        extra = [
            np.abs(a - st.platform_mm).sum() + np.abs(st.platform_mm - b).sum() - np.abs(a - b).sum()
            for a, b in itertools.pairwise(stops)
        ]
        place = next(i for i, s in enumerate(then) if s is st)
        assert extra[place] == pytest.approx(min(extra))


def test_the_deposit_matrix_extends_over_a_new_station(reach):
    from sprayplan.coating import deposit_matrix
    from sprayplan.coating.stage import plan_paths_in_order, process_for
    from sprayplan.refine.extend import with_added_strokes
    from sprayplan.refine.stage import extended_deposit

    part, job, planned, strokes = reach
    process = process_for(job)
    samples, old = deposit_matrix(part, plan_paths_in_order(planned, H, 0.0), process)
    extended = with_added_strokes(planned, strokes, job, new_stations=2)
    assert len(extended.stations) > len(planned.stations)
    got = extended_deposit(part, extended, planned, samples, old, process, None)
    _, full = deposit_matrix(part, plan_paths_in_order(extended, H, 0.0), process)
    assert got[0] is samples and got[1].shape == full.shape
    assert abs(got[1] - full).max() <= 1e-6 * abs(full).max()


def test_a_station_is_placed_where_the_arm_reaches_a_stroke():
    from sprayplan.refine.added_stations import reach_share, stations_for_strokes
    from sprayplan.robots.gantry import solve_gantry_path
    from sprayplan.surface.poses import stroke_poses as gun_poses

    gantry = Gantry()
    # the underside of a lip 1.5 m from the gantry's origin, sprayed upwards and inwards
    count = 30
    points = np.column_stack([np.full(count, 1500.0), np.linspace(-150, 150, count), np.zeros(count)])
    normals = np.tile(np.array([0.85, 0.0, -0.45]) / math.hypot(0.85, 0.45), (count, 1))
    stroke = Stroke(points, normals, points + H * normals, True, None, -1, None, "touch-up")
    poses = gun_poses(stroke)
    height = 600.0
    assert reach_share(gantry, poses, np.array([[0.0, 0.0, height]])) == 0.0  # out of the origin's reach
    placed = stations_for_strokes(gantry, [poses], height, max_stations=3)
    assert len(placed) == 1 and placed[0].strokes == (0,) and placed[0].reached == count
    assert placed[0].platform_mm[2] == height
    assert reach_share(gantry, poses, np.zeros((0, 3)), height) == 1.0
    path = solve_gantry_path(gantry, poses, placed[0].platform_mm)
    assert path.reachable.all()
    position, _ = pose_errors(gantry.target2world(path.q9), poses @ gantry.gun.target2gun)
    assert position.max() < 1e-6
    assert stations_for_strokes(gantry, [poses], height, max_stations=0) == []
    # a stroke far above the gantry's reach gets no station
    high = Stroke(points + [0, 0, 5000.0], normals, points + [0, 0, 5000.0] + H * normals, True)
    assert stations_for_strokes(gantry, [gun_poses(high)], height, max_stations=3) == []


def test_tilted_turns_the_aim_about_the_direction_of_travel():
    count = 12
    points = np.column_stack([np.linspace(0, 110, count), np.zeros(count), np.zeros(count)])
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    stroke = Stroke(points, normals, points + H * normals, True, None, -1, None, "touch-up")
    turned = tilted(stroke, 30.0, H)
    np.testing.assert_array_equal(turned.points, stroke.points)
    np.testing.assert_allclose(np.linalg.norm(turned.normals, axis=1), 1.0)
    np.testing.assert_allclose(turned.normals @ [0.0, 0, 1], math.cos(math.radians(30)))
    np.testing.assert_allclose(turned.normals[:, 0], 0.0, atol=1e-12)  # still across the travel (+x)
    # right hand about +x turns +z towards -y
    np.testing.assert_allclose(turned.normals[:, 1], -math.sin(math.radians(30)))
    np.testing.assert_allclose(turned.tcp, turned.points + H * turned.normals)
    assert turned.kind == "touch-up"
    assert tilted(stroke, 0.0, H) is stroke
    # across: about the axis across the travel (+z x +x = +y), the aim's axis leans toward the travel (+x)
    leaned = tilted(stroke, 30.0, H, across=True)
    np.testing.assert_array_equal(leaned.points, stroke.points)
    np.testing.assert_allclose(leaned.normals, [[math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))]] * count)
    np.testing.assert_allclose(leaned.tcp, leaned.points + H * leaned.normals)


SLOPE = math.tan(math.radians(30.0))
SLOPE_NORMAL = np.array([SLOPE, 0.0, 1.0]) / math.hypot(SLOPE, 1.0)


def step_part():
    """A flat top (z = 0) for x <= 0, a 10 mm vertical wall at x = 0 facing +x, and below it a slope falling
    away at 30 degrees: a narrow wall between two wide surfaces, like the crease of a car's tail."""
    from sprayplan.types import Part

    top = plate(-160, 0, -150, 150, 5.0)
    slope = plate(0, 160, -150, 150, 5.0)
    slope_v = slope.vertices.copy()
    slope_v[:, 2] = -10.0 - SLOPE * slope_v[:, 0]
    ys = np.arange(-150.0, 150.1, 5.0)
    zs = np.array([0.0, -2.5, -5.0, -7.5, -10.0])
    grid = np.array([[0.0, y, z] for z in zs for y in ys])
    n_y = len(ys)
    faces = []
    for i in range(len(zs) - 1):
        for j in range(n_y - 1):
            a, b, c, d = i * n_y + j, i * n_y + j + 1, (i + 1) * n_y + j, (i + 1) * n_y + j + 1
            faces += [[a, c, b], [b, c, d]]
    faces = np.array(faces)
    tri = grid[faces[0]]
    if np.cross(tri[1] - tri[0], tri[2] - tri[0])[0] < 0:  # the wall faces +x
        faces = faces[:, ::-1]
    vertices = np.vstack([top.vertices, slope_v, grid])
    all_faces = np.vstack([top.faces, slope.faces + len(top.vertices), faces + len(top.vertices) + len(slope_v)])
    # one sheet: the shared edges' vertices welded, so that the faces are oriented alike
    unique, index = np.unique(np.round(vertices, 6), axis=0, return_inverse=True)
    return Part(unique, index.reshape(-1)[all_faces], None, "step")


def test_the_chosen_aim_is_the_one_the_film_model_favours():
    part = step_part()
    ys = np.arange(-140.0, 141.0, 35.0)
    strokes = []
    for y in ys:  # the top and the slope, each painted square on
        x = np.linspace(-200.0, -5.0, 40)
        pts = np.column_stack([x, np.full(40, y), np.zeros(40)])
        strokes.append(Stroke(pts, np.tile([0.0, 0, 1], (40, 1)), pts + H * np.array([0.0, 0, 1])))
        x = np.linspace(5.0, 200.0, 40)
        pts = np.column_stack([x, np.full(40, y), -10.0 - SLOPE * x])
        strokes.append(Stroke(pts, np.tile(SLOPE_NORMAL, (40, 1)), pts + H * SLOPE_NORMAL))
    process = Process(PATTERN, speed_mm_s=600.0)
    tuning = tune_speeds(part, Paths(tuple(strokes), H, 35.0), process, 50.0, 5.0)
    # one pass along the wall (travelling +y), aimed along its normal (+x); tilts turn the aim about +y, a
    # positive one aims upwards from below, along the slope rather than into it
    count = 30
    pts = np.column_stack([np.zeros(count), np.linspace(-145, 145, count), np.full(count, -5.0)])
    wall = Stroke(
        pts, np.tile([1.0, 0, 0], (count, 1)), pts + H * np.array([1.0, 0, 0]), True, None, -1, None, "touch-up"
    )
    tilts = (-20.0, 0.0, 20.0)
    args = (tuning.samples, tuning.after_um, tuning.tuned, 50.0, 5.0)
    (chosen,) = aim_touch_ups(part, [wall], *args, process=process, coating=None, standoff_mm=H, tilts_deg=tilts)
    # the gain of each tilt, from simulate (not the deposit matrix): the best scale's drop of the misfit
    area = tuning.samples.area_mm2[tuning.tuned]
    now = misfit(tuning.after_um[tuning.tuned], area, 50.0, 5.0)
    gains = []
    for tilt in tilts:
        candidate = tilted(wall, tilt, H)
        best = -np.inf
        for scale in (0.25, 0.5, 1.0, 2.0):
            run = candidate.with_dwell(np.full(count, scale))
            film = simulate(part, Paths((run,), H, 0.0), process).thickness_mm * 1000.0
            best = max(best, now - misfit(tuning.after_um[tuning.tuned] + film[tuning.tuned], area, 50.0, 5.0))
        gains.append(best)
    assert int(np.argmax(gains)) == 2 and gains[2] > gains[1] > 0  # aiming along the slope paints less of it
    np.testing.assert_allclose(chosen.normals, tilted(wall, 20.0, H).normals, atol=1e-12)
    # strokes aimed together get the aims they get alone (a second stroke, shorter and reversed, on the top)
    top = Stroke(*(a[:12] for a in (wall.points + [-60.0, 0, 5], wall.normals, wall.tcp + [-60.0, 0, 5])))
    top = Stroke(top.points, np.tile([0.0, 0, 1], (12, 1)), top.points + H * np.array([0.0, 0, 1])).reversed()
    together = aim_touch_ups(part, [top, wall], *args, process=process, coating=None, standoff_mm=H, tilts_deg=tilts)
    alone = aim_touch_ups(part, [top], *args, process=process, coating=None, standoff_mm=H, tilts_deg=tilts)
    np.testing.assert_allclose(together[0].normals, alone[0].normals, atol=1e-12)
    np.testing.assert_allclose(together[1].normals, chosen.normals, atol=1e-12)
    # only the tilts the robot reaches are chosen from
    only_zero = aim_touch_ups(
        part,
        [wall],
        *args,
        process=process,
        coating=None,
        standoff_mm=H,
        tilts_deg=tilts,
        reach=lambda s: 1.0 if np.allclose(s.normals, wall.normals) else 0.0,
    )
    np.testing.assert_allclose(only_zero[0].normals, wall.normals)


def test_a_film_inside_the_dead_band_keeps_its_speeds():
    panel = plate(-260, 260, -200, 200, 5.0)
    strokes = []
    for k, y in enumerate((-60.0, -15.0, 35.0)):
        pts = np.column_stack([np.linspace(-150, 150, 31), np.full(31, y), np.zeros(31)])
        s = Stroke(pts, np.tile([0.0, 0, 1], (31, 1)), pts + H * np.array([0.0, 0, 1]))
        strokes.append(s if k % 2 == 0 else s.reversed())
    paths = Paths(tuple(strokes), H, 40.0)
    process = Process(PATTERN, speed_mm_s=300.0)
    fixed = TuningConfig(min_dwell=1.0, max_dwell=1.0)
    first = tune_speeds(panel, paths, process, 50.0, 5.0, config=fixed)
    target = float(np.average(first.before_um[first.tuned], weights=first.samples.area_mm2[first.tuned]))
    counted = tune_speeds(panel, paths, process, target, 5.0, config=fixed).tuned  # the samples tuned for
    tol = 1.01 * np.abs(first.before_um[counted] - target).max() / 0.9  # all within 0.9 tolerances
    kept = tune_speeds(panel, paths, process, target, tol, config=TuningConfig(band=0.9))
    dwell = np.concatenate([s.dwell for s in kept.paths.strokes])
    np.testing.assert_allclose(dwell, 1.0, atol=1e-9)
    moved = tune_speeds(panel, paths, process, target, tol, config=TuningConfig(band=0.0))
    assert np.abs(np.concatenate([s.dwell for s in moved.paths.strokes]) - 1.0).max() > 1e-3
    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(ConfigError, match="band"):
            TuningConfig(band=bad)


def test_the_new_plan_settings_are_checked():
    from sprayplan.config import RefineConfig

    settings = RefineConfig()
    assert (settings.touch_up_stations, settings.band, settings.touch_up_aim) == (4, 0.3, True)
    for bad in (-1, 21, 1.5, "2"):
        with pytest.raises(ConfigError, match="touch_up_stations"):
            RefineConfig(touch_up_stations=bad)
    for bad in (-0.1, 1.0, float("nan"), "0.3", True):
        with pytest.raises(ConfigError, match="band"):
            RefineConfig(band=bad)
    with pytest.raises(ConfigError, match="touch_up_aim"):
        RefineConfig(touch_up_aim="yes")


def test_the_dead_bands_jacobian_is_the_derivative_of_its_residuals():
    from scipy import sparse

    from sprayplan.refine.system import System, _residuals

    rng = np.random.default_rng(3)
    deposit = sparse.random(30, 12, density=0.3, random_state=rng, format="csr") * 0.003  # mm: 3 um at most
    system = System(deposit, np.arange(30), np.arange(12), 12, 1.0, np.arange(10), 0.7)
    whole = system.csr()  # 30 film rows and 10 smoothness rows
    target = np.r_[rng.normal(2.0, 1.0, 30), np.zeros(10)]
    for band in (0.0, 0.3):
        residual, jacobian = _residuals(system, target, band)
        for _ in range(20):
            x = rng.uniform(0.5, 2.0, 12)
            r = residual(x)
            inside = np.abs((whole @ x - target)[:30]) <= band
            assert (r[:30][inside] == 0).all()  # the band costs nothing
            step = 1e-6
            numeric = np.column_stack(
                [(residual(x + step * e) - residual(x - step * e)) / (2 * step) for e in np.eye(12)]
            )
            # the kinks at |u| = band: compare rows away from them
            away = np.r_[np.abs(np.abs((whole @ x - target)[:30]) - band) > 1e-4, np.ones(10, bool)]
            np.testing.assert_allclose((jacobian(x) @ np.eye(12))[away], numeric[away], atol=1e-6)


def test_tune_plan_keeps_to_its_budget_of_new_stations(testdata):
    from sprayplan.coating.stage import meet_thickness
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.refine.stage import tune_plan
    from sprayplan.surface.region import select_region
    from tests.helpers import planned as plan

    part = select_region(load_part(testdata / "meshes" / "reach_curved_part.ply", units="m"), "x > -300")
    for budget, aim in ((0, False), (1, True)):
        job, _ = meet_thickness(
            JobConfig().replace(
                coating={"thickness_um": 50.0}, tuning={"touch_up_stations": budget, "touch_up_aim": aim}
            )
        )
        planned = plan(part, job)
        tuned, summary, _, _ = tune_plan(part, planned, job)
        assert summary["touch_up_strokes"] > 0
        assert len(planned.stations) <= len(tuned.stations) <= len(planned.stations) + budget
        assert len({st.index for st in tuned.stations}) == len(tuned.stations)
        touch = [(st, s) for st in tuned.stations for s in st.strokes if s.kind == "touch-up"]
        for st in tuned.stations:  # every touch-up spray waypoint is reachable
            spray = np.concatenate([np.full(len(s), s.kind == "touch-up" and s.spray_on) for s in st.strokes])
            assert st.reachable[spray].all()
        assert touch


def test_the_best_tilt_needs_few_reaches_and_is_the_one_of_all_shares():
    """``_best_tilt`` computes shares lazily; its choice is the full rule's (every share computed, allowed at
    min(0.5, best share), the first of the largest allowed gains, none unless it gains), ties and zeros
    included."""
    from sprayplan.refine.touchup import _best_tilt

    rng = np.random.default_rng(7)
    lazy_calls = all_calls = 0
    for _ in range(3000):
        n = int(rng.integers(1, 6))
        all_calls += n
        gain = rng.choice([-1.0, 0.0, 0.5, 1.0, 2.0], n) * rng.choice([1.0, rng.uniform(0.5, 2)], n)
        shares = rng.choice([0.0, 0.2, 0.49, 0.5, 0.8, 1.0], n)
        candidates = list(range(n))
        full = shares >= min(0.5, shares.max())
        score = np.where(full, gain, -np.inf)
        best = int(np.argmax(score))
        want = best if score[best] > 0 else None
        calls = []

        def reach(c, calls=calls, shares=shares):
            calls.append(c)
            return shares[c]

        assert _best_tilt(gain, candidates, reach) == want
        assert _best_tilt(gain, candidates, None) == (int(np.argmax(gain)) if gain.max() > 0 else None)
        assert len(calls) <= n
        lazy_calls += len(calls)
    assert lazy_calls < 0.75 * all_calls  # many choices need one share or none, not all of them


def test_the_tunings_after_touch_ups_start_from_the_round_befores_factors(testdata, monkeypatch):
    """After a touch-up round the speeds are tuned again from the factors the round before found (1 on the
    added strokes' waypoints) with at most ``touch_up_iterations`` evaluations; the first tuning starts
    from 1 everywhere, with as many; with no touch-ups to add, it is continued from its factors to
    ``iterations`` evaluations in all, on the same deposit matrix."""
    import sprayplan.refine.stage as stage
    from sprayplan.coating.stage import meet_thickness
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.surface.region import select_region
    from tests.helpers import planned as plan

    part = select_region(load_part(testdata / "meshes" / "reach_curved_part.ply", units="m"), "x > -300")
    job, _ = meet_thickness(
        JobConfig().replace(coating={"thickness_um": 50.0}, tuning={"touch_up_iterations": 7, "touch_up_rounds": 1})
    )
    calls = []
    tune = stage.tune_speeds

    def recording(part_, paths, *args, **kwargs):
        found = tune(part_, paths, *args, **kwargs)
        calls.append((paths, kwargs.get("initial"), kwargs["config"].iterations, found))
        return found

    monkeypatch.setattr(stage, "tune_speeds", recording)
    planned = plan(part, job)
    stage.tune_plan(part, planned, job)
    assert len(calls) == 2
    (_, first_initial, first_its, first), (paths, initial, its, _) = calls
    assert first_initial is None and first_its == 7 and its == 7
    # the second plan's strokes: the first's in their order (the same geometry), with the added ones (touch-ups
    # and their transfers) put in between
    old, j = first.paths.strokes, 0
    is_new = []
    for stroke in paths.strokes:
        same = j < len(old) and len(old[j]) == len(stroke) and np.array_equal(old[j].tcp, stroke.tcp)
        is_new.append(np.full(len(stroke), not same))
        j += same
    assert j == len(old)
    is_new = np.concatenate(is_new)
    assert is_new.any() and not is_new.all()
    earlier = np.concatenate([s.dwell for s in first.paths.strokes])
    assert (earlier != 1.0).any()  # the first round moved the factors
    np.testing.assert_array_equal(initial[~is_new], earlier)
    assert (initial[is_new] == 1.0).all()

    calls.clear()  # no touch-ups found: the first tuning goes on
    monkeypatch.setattr(stage, "touch_up_strokes", lambda *args, **kwargs: [])
    _, summary, _, last = stage.tune_plan(part, planned, job)
    assert [c[2] for c in calls] == [7, job.tuning.iterations - 7]
    (_, _, _, first), (paths, initial, _, second) = calls
    assert paths is first.paths and last is second
    np.testing.assert_array_equal(initial, np.concatenate([s.dwell for s in first.paths.strokes]))
    assert second.deposit_mm is first.deposit_mm and summary["touch_up_strokes"] == 0
