"""The collision stage of the main job: the fast check against coal's exact distances, the motion proof, the
repairs, the floor rule, and the flags in the plan's files."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

pytest.importorskip("coal")

from sprayplan.cli.main import main
from sprayplan.collision.broadphase import surface_samples
from sprayplan.collision.cell import CellCollision
from sprayplan.collision.motion import motion_bound_mm
from sprayplan.collision.repair import REPAIRS, collision_stage
from sprayplan.config import CollisionConfig, JobConfig
from sprayplan.errors import RegionError
from sprayplan.export.plan_read import read_plan_file
from sprayplan.io.load import load_part
from sprayplan.robots.gantry import build_gantry, pose_errors
from sprayplan.surface.poses import stroke_poses
from sprayplan.surface.region import drop_floor_facing
from sprayplan.types import TRANSFER_REPAIRS, Part
from tests.helpers import planned

REACH = {"units": "m", "region": "x > -250"}


@pytest.fixture(scope="module")
def gantry():
    return build_gantry("ur5")


@pytest.fixture(scope="module")
def reach(testdata):
    path = testdata / "meshes" / "reach_curved_part.ply"
    job = JobConfig().replace(load=REACH)
    return path, load_part(path, units="m"), planned(path, job), job


def test_surface_samples_cover_every_point_of_the_surface(testdata):
    part = load_part(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    samples = surface_samples(part, cover_mm=6.0)
    rng = np.random.default_rng(3)
    tri = part.triangles
    pick = rng.integers(0, len(tri), 20000)
    a, b = rng.random((2, len(pick)))
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    points = tri[pick, 0] + a[:, None] * (tri[pick, 1] - tri[pick, 0]) + b[:, None] * (tri[pick, 2] - tri[pick, 0])
    gap, _ = samples.tree.query(points)
    assert gap.max() <= 6.0 + 1e-9


def test_fast_check_agrees_with_every_exact_distance(reach, gantry):
    _, whole, plan, _ = reach
    cell = CellCollision(gantry, whole)
    q9 = np.concatenate([s.q9 for s in plan.stations])[np.concatenate([s.reachable for s in plan.stations])]
    rng = np.random.default_rng(0)
    # the plan's own waypoints and the same waypoints with the arm thrown about (many of them in collision)
    wild = q9[rng.integers(0, len(q9), 150)].copy()
    wild[:, :6] += rng.normal(0.0, 0.6, (len(wild), 6))
    q = np.vstack([q9[:: max(1, len(q9) // 150)], wild])
    fast = cell.check(q)
    exact = cell.distances(q)
    slack = exact.slack_mm
    assert (fast.in_collision == (slack < 0).any(axis=1)).all()
    assert fast.in_collision.any() and not fast.in_collision.all()
    assert (cell.collides(q) == (slack < 0).any(axis=1)).all()  # the yes/no check gives the same answers
    assert (cell.collides(q, extra_mm=15.0) == (slack < 15.0).any(axis=1)).all()
    true_least = slack.min(axis=1)
    assert (fast.slack_mm <= true_least + 1e-6).all()  # a lower bound everywhere
    assert np.allclose(fast.slack_mm[fast.exact], true_least[fast.exact])  # and exact where it says so
    part_columns = [i for i, (_, b) in enumerate(exact.pairs) if b == "part"]
    part_true = exact.distance_mm[:, part_columns].min(axis=1)
    assert (fast.part_distance_mm <= part_true + 1e-6).all()


def test_a_motion_the_proof_calls_free_is_free_when_checked_densely(reach, gantry):
    _, whole, plan, _ = reach
    cell = CellCollision(gantry, whole)
    st = plan.stations[0]
    q9 = st.q9[st.reachable]
    rng = np.random.default_rng(1)
    tried = 0
    for i in rng.integers(0, len(q9) - 1, 100):
        a, b = q9[i], q9[i + 1] + np.r_[rng.normal(0, 0.002, 6), 0, 0, 0]
        checks = cell.check(np.vstack([a, b]), margin_mm=100.0)
        bound = motion_bound_mm(a, b, cell.reach_radii_mm)[0]
        if (checks.slack_mm.sum() - bound) / 2 < 0:
            continue
        tried += 1
        s = np.linspace(0, 1, 41)[:, None]
        dense = cell.distances(a + s * (b - a)).slack_mm
        assert dense.min() >= (checks.slack_mm.sum() - bound) / 2 - 1e-6
    assert tried >= 10


@pytest.fixture(scope="module")
def repaired(reach, gantry):
    _, whole, plan, job = reach
    job = job.replace(collision={"clearance_mm": 40.0})
    return whole, plan, job, *collision_stage(plan, whole, job, gantry)


def test_repairs_keep_the_spray_and_free_what_they_claim(repaired, gantry):
    whole, before, job, after, summary = repaired
    cell = CellCollision(gantry, whole, job.collision)
    assert summary["in_collision_before_repair"] > 0, "the case must have something to repair"
    assert summary["repaired"] + summary["flagged_waypoints"] >= 1
    tol_mm, tol_rad = job.kinematics.position_tol_mm, math.radians(job.kinematics.axis_tol_deg)
    for old, new in zip(before.stations, after.stations):
        assert len(old.strokes) == len(new.strokes)
        routed = np.zeros(len(new), bool)
        start = 0
        for a, b in zip(old.strokes, new.strokes):
            # spray strokes and the transfers left as planned keep their waypoints; a re-routed transfer is
            # its route (tests/test_transfers.py)
            if set(new.repair[start : start + len(b)]) & set(TRANSFER_REPAIRS):
                assert b.kind == "transfer"
                routed[start : start + len(b)] = True
            else:
                assert np.array_equal(a.tcp, b.tcp) and np.array_equal(a.normals, b.normals)
            start += len(b)
        if routed.any():
            assert not new.collision[routed].any() and not new.motion_collision[routed].any()
            continue  # the rows below are compared one to one
        assert (new.reachable >= old.reachable).all()  # nothing reached before is lost
        fixed = new.repair != ""
        assert set(new.repair[fixed]) <= set(REPAIRS)
        if fixed.any():
            exact = cell.distances(new.q9[fixed]).slack_mm
            assert (exact >= 0).all()
            assert not new.collision[fixed].any()
        # every waypoint a repair moved meets the seed's tolerance against the pose the plan asked for, and
        # its recorded errors are the true ones
        moved = (new.q9 != old.q9).any(axis=1)
        wanted = np.concatenate([stroke_poses(s) for s in new.strokes]) @ gantry.gun.target2gun
        position, axis = pose_errors(gantry.target2world(new.q9), wanted)
        assert (position[moved] <= tol_mm + 1e-6).all()
        assert (axis[moved] <= tol_rad + 1e-9).all()
        assert np.allclose(new.position_error_mm[moved], position[moved], atol=1e-9)
        assert np.allclose(new.axis_error_deg[moved], np.degrees(axis[moved]), atol=1e-9)
        assert (new.method[moved] == "analytic").all()
        # what is still flagged really is in collision
        if new.collision.any():
            assert (cell.distances(new.q9[new.collision]).slack_mm < 0).any(axis=1).all()
    flagged = sum(int(st.collision.sum()) for st in after.stations)
    assert flagged == summary["flagged_waypoints"]
    # every waypoint repaired is named; so are (when not named already) those a freed motion inside a spray
    # stroke arrives at, counted apart
    named = sum(int(np.isin(st.repair, REPAIRS).sum()) for st in after.stations)
    assert summary["repaired"] <= named <= summary["repaired"] + summary["motions_repaired"]
    assert summary["motions_repaired"] == sum(summary["motions_repaired_by"].values())


def test_the_stage_repeats(repaired, gantry):
    whole, before, job, after, summary = repaired
    again, summary_again = collision_stage(before, whole, job, gantry)
    assert summary_again == summary
    for a, b in zip(after.stations, again.stations):
        assert np.array_equal(a.q9, b.q9) and np.array_equal(a.repair, b.repair)


def test_floor_facing_surface_is_left_out_with_its_area():
    # a closed unit cube, 100 mm, outward winding: the bottom (normal -z) faces the floor
    v = np.array([[x, y, z] for z in (0, 100) for y in (0, 100) for x in (0, 100)], float)
    f = np.array(
        [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7], [0, 4, 2],
         [2, 4, 6], [1, 3, 5], [3, 7, 5]]
    )  # fmt: skip
    cube = Part(v, f, name="cube")
    kept, left_out = drop_floor_facing(cube, 45.0)
    assert left_out == pytest.approx(100.0 * 100.0)
    assert len(kept.faces) == 10
    assert kept.area == pytest.approx(cube.area - 1e4)
    assert drop_floor_facing(cube, 90.0)[1] == 0.0  # nothing points more than 90 degrees below
    # a face 30 degrees below the horizontal stays at 45 and goes at 20
    tilt = math.radians(30)
    n = np.array([math.cos(tilt), 0.0, -math.sin(tilt)])
    u = np.array([0.0, 1.0, 0.0])
    w = np.cross(n, u)
    tri = Part(np.array([np.zeros(3), 50 * u, 50 * w]) if np.cross(50 * u, 50 * w) @ n > 0 else
               np.array([np.zeros(3), 50 * w, 50 * u]), np.array([[0, 1, 2]]), name="tilted")  # fmt: skip
    assert drop_floor_facing(tri, 45.0)[1] == 0.0
    with pytest.raises(RegionError, match="faces the floor"):
        drop_floor_facing(tri, 20.0)  # all of it


def test_plan_files_carry_the_flags_and_read_back(testdata, tmp_path):
    out = tmp_path / "out"
    code = main(
        ["plan", str(testdata / "meshes" / "reach_curved_part.ply"), "--units", "m", "--region", "x > -250",
         "-o", str(out), "--no-viewer", "--no-report", "--collisions"]
    )  # fmt: skip
    assert code == 0
    data = json.loads((out / "plan.json").read_text())
    summary = data["totals"]["collisions"]
    assert summary["waypoints_checked"] > 0
    back = read_plan_file(out / "plan.json").plan
    flagged = sum(int(st.collision.sum()) for st in back.stations)
    assert flagged == summary["flagged_waypoints"]
    checked = sum(int(np.isfinite(st.collision_distance_mm).sum()) for st in back.stations)
    assert checked == summary["waypoints_checked"]
    with open(out / "waypoints.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert sum(int(r["collision"]) for r in rows) == flagged
    # a repaired waypoint, and the waypoint a repaired motion in a stroke arrives at, carry their repair
    assert sum(r["repair"] not in ("", *TRANSFER_REPAIRS) for r in rows) == (
        summary["repaired"] + summary["motions_repaired"]
    )
    routed = sum(r["repair"] in TRANSFER_REPAIRS for r in rows)
    assert (routed > 0) == (summary["transfers_rerouted"] > 0)
    assert sum(r["collision_distance_mm"] != "" for r in rows) == checked
    # the viewer's summary panel and its flagged layer say the same
    from sprayplan.view.html import flagged_waypoints
    from sprayplan.view.scene import scene_from_folder
    from sprayplan.view.summary import summary_rows

    scene = scene_from_folder(out)
    table = dict(dict(summary_rows(scene))["collisions"])
    assert table["left flagged"] == f"{flagged:,}" and table["repaired"] == f"{summary['repaired']:,}"
    moving = sum(int((st.reachable & (st.collision | st.motion_collision)).sum()) for st in back.stations)
    assert len(flagged_waypoints(scene)["collision"][1]) == moving


def test_strict_refuses_a_plan_left_in_collision(testdata, tmp_path, capsys):
    out = tmp_path / "strict"
    # a clearance no arm near this part can keep, and no repairs: flagged for sure
    args = ["plan", str(testdata / "meshes" / "reach_curved_part.ply"), "--units", "m", "--region", "x > -250",
            "-o", str(out), "--no-viewer", "--no-report", "--strict", "--collisions"]  # fmt: skip
    config = tmp_path / "c.toml"
    config.write_text("[collision]\nclearance_mm = 150.0\nmotion_step_mm = 10.0\nrepair = false\n")
    code = main([*args, "--config", str(config)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "--strict" in err[0] and "collision" in err[0]
    assert not out.exists()


@pytest.mark.parametrize(
    "text, key",
    [
        ("[collision]\nclearance_mm = -5\n", "collision.clearance_mm"),
        ("[collision]\nfloor_facing_deg = 120\n", "collision.floor_facing_deg"),
        ("[collision]\ntilt_deg = nan\n", "collision.tilt_deg"),
        ("[collision]\npiece_tilt_deg = 75\n", "collision.piece_tilt_deg"),
        ("[collision]\npiece_tilt_deg = nan\n", "collision.piece_tilt_deg"),
        ("[collision]\ncell_detour_iterations = -1\n", "collision.cell_detour_iterations"),
        ("[collision]\nrepair = 1\n", "collision.repair"),
        ("[collision]\nplatform_search_mm = -50\n", "collision.platform_search_mm"),
        ("[collision]\nplatform_search_mm = nan\n", "collision.platform_search_mm"),
        ("[collision]\nplatform_search_step_mm = 0\n", "collision.platform_search_step_mm"),
        (
            "[collision]\nplatform_search_mm = 100000\nplatform_search_step_mm = 1\n",
            "collision.platform_search_step_mm",
        ),
    ],
)
def test_bad_collision_settings_exit_2_naming_the_key(testdata, tmp_path, capsys, text, key):
    config = tmp_path / "c.toml"
    config.write_text(text)
    out = tmp_path / "o"
    code = main(
        ["plan", str(testdata / "meshes" / "tray_bottom_mm_ascii.stl"), "-o", str(out), "--config", str(config)]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and key in err[0]
    assert not out.exists()


def test_a_floor_above_the_part_is_a_config_error(testdata, tmp_path, capsys):
    config = tmp_path / "c.toml"
    config.write_text("[collision]\ncheck = true\nfloor_z_mm = 100000\n")
    out = tmp_path / "o"
    code = main(
        ["plan", str(testdata / "meshes" / "tray_bottom_mm_ascii.stl"), "-o", str(out), "--config", str(config)]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "collision.floor_z_mm" in err[0]
    assert not out.exists()


def test_checks_can_be_turned_off(reach):
    path, _, _, job = reach
    from sprayplan.job import run_job

    result = run_job(path, job.replace(collision={"check": False}), until="collision")
    assert "collision" in result.timings_s
    assert not any(st.collision.any() or np.isfinite(st.collision_distance_mm).any() for st in result.plan.stations)


def test_collision_config_is_the_job_section():
    assert JobConfig().collision == CollisionConfig()
    assert not JobConfig().collision.check  # opt-in (``--collisions``) until the stage is fast


def test_a_point_cloud_plan_is_checked_against_the_cloud(testdata):
    from sprayplan.job import run_job

    cloud = testdata / "pointclouds" / "reach_part_normals_ascii.pcd"
    job = JobConfig().replace(
        load={"units": "m"}, collision={"check": True, "repair": False}, timing={"enabled": False}
    )
    result = run_job(cloud, job, until="totals")
    summary = result.totals["collisions"]
    assert summary["checked"] and summary["waypoints_checked"] == sum(
        int(s.reachable.sum()) for s in result.plan.stations
    )
    flagged = sum(int(s.collision.sum()) for s in result.plan.stations)
    assert flagged == summary["flagged_waypoints"] == summary["in_collision_before_repair"] > 0


def test_the_distance_grid_and_the_tree_bound_the_true_distance_from_below(testdata):
    import trimesh

    part = load_part(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    samples = surface_samples(part, cover_mm=6.0)
    rng = np.random.default_rng(5)
    lo, hi = part.bounds
    x = rng.uniform(lo - 150.0, hi + 150.0, (3000, 3))
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    _, true, _ = trimesh.proximity.closest_point(mesh, x)
    grid = samples.grid.lower_bound_mm(x)
    assert (grid <= true + 1e-6).all()
    nearest, _ = samples.tree.query(x)
    _, above = samples.grid.bounds_mm(x)
    inside = np.isfinite(above)
    assert inside.mean() > 0.5 and (above[inside] >= nearest[inside] - 1e-6).all()  # an upper bound too
    bound = samples.lower_bound_mm(x, upper_mm=60.0)
    assert (bound <= np.minimum(true, 60.0) + 1e-6).all()
    near = true < 40.0
    assert near.any() and (bound[near] >= true[near] - 6.0 - 1e-6).all()  # within the cover where it counts


def test_the_summary_line_says_when_collisions_were_not_checked():
    from types import SimpleNamespace

    from sprayplan.cli.plan import summary_line

    totals = {"stations": 1, "strokes": 2, "waypoints": 3, "unreachable_waypoints": 0, "unassigned_points": 0,
              "spray_length_mm": 1000.0, "transfer_length_mm": 10.0, "platform_travel_mm": 0.0,
              "cycle_time_s": 5.0, "planning_time_s": 1.0}  # fmt: skip
    unchecked = summary_line(SimpleNamespace(totals=totals, film=None), "out").splitlines()
    assert len(unchecked) == 1 and unchecked[0].endswith("; collisions not checked (--collisions checks them)")
    counts = {"flagged_waypoints": 4, "flagged_motions": 5, "repaired": 6, "in_collision_before_repair": 10,
              "clearance_mm": 30.0}  # fmt: skip
    checked = summary_line(SimpleNamespace(totals={**totals, "collisions": counts}, film=None), "out").splitlines()
    assert checked[1].startswith("collisions: 4 waypoints and 5 motions flagged, 6 of 10 repaired")
