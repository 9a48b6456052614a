"""The main job, ``sprayplan plan``: stations, ordering and nine-axis kinematics on real parts."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.config import SECTIONS, JobConfig, LoadConfig, OrderingConfig, PathConfig, job_from_toml
from sprayplan.errors import PartFileError
from sprayplan.export.summary import plan_totals
from sprayplan.io.load import load_part
from sprayplan.job import run_job
from sprayplan.robots.gantry import Gantry
from tests.conftest import REPO


def plan(part, job):
    """The plan of a part, without refinement (the main job up to its kinematics stage)."""
    return run_job(part, job, until="kinematics").plan


def test_process_toml_documents_every_default():
    assert job_from_toml(REPO / "examples" / "process.toml") == JobConfig()
    # every setting is there, set or (when its default is computed) commented out
    text = (REPO / "examples" / "process.toml").read_text()
    assert "\nmode = " in text
    for name, section in SECTIONS.items():
        body = text.split(f"\n[{name}]", 1)[1].split("\n[", 1)[0]
        for field in dataclasses.fields(section):
            assert f"\n{field.name} = " in body or f"\n# {field.name} = " in body, (name, field.name)


def test_bad_process_toml(tmp_path):
    (tmp_path / "p.toml").write_text("[paths]\nspacing = 40\n")
    with pytest.raises(PartFileError, match=r"p.toml: \[paths\]: unknown key\(s\) spacing"):
        job_from_toml(tmp_path / "p.toml")
    (tmp_path / "q.toml").write_text("[painting]\n")
    with pytest.raises(PartFileError, match="unknown table"):
        job_from_toml(tmp_path / "q.toml")


@pytest.fixture(scope="module")
def reach_plan(testdata, tmp_path_factory):
    out = tmp_path_factory.mktemp("plan")
    (out / "process.toml").write_text("[paths]\nspacing_mm = 80.0\nstep_mm = 20.0\n[motion]\ngun_speed_mm_s = 500.0\n")
    code = main(
        [
            "plan",
            str(testdata / "meshes" / "reach_curved_part.ply"),
            "--units",
            "m",
            "-o",
            str(out),
            "-c",
            str(out / "process.toml"),
            "--standoff-mm",
            "113",
        ]
    )
    assert code == 0
    return out, json.loads((out / "plan.json").read_text())


def test_plan_json_reads_back(reach_plan):
    _out, data = reach_plan
    assert data["format"] == "sprayplan.plan" and data["units"]["length"] == "mm"
    # settings: the TOML file and the flags both took effect
    assert data["settings"]["paths"]["spacing_mm"] == 80.0 and data["settings"]["motion"]["gun_speed_mm_s"] == 500.0
    assert data["settings"]["load"]["units"] == "m"
    totals = data["totals"]
    assert totals["stations"] == len(data["stations"]) >= 2
    spray = transfer = spray_time = 0.0
    waypoints = 0
    for station in data["stations"]:
        platform = np.array(station["platform_mm"])
        for stroke in station["strokes"]:
            tcp = np.array(stroke["tcp"])
            seg = np.linalg.norm(np.diff(tcp, axis=0), axis=1)
            length = float(seg.sum())
            spray, transfer = (spray + length, transfer) if stroke["spray_on"] else (spray, transfer + length)
            tip_speed = np.array(stroke["tcp_speed_mm_s"])
            assert len(tip_speed) == len(tcp)
            if stroke["spray_on"]:
                spray_time += float((seg / tip_speed[1:]).sum())
                # the contact point moves at the gun speed wherever the tip's speed is not clipped
                surface = np.linalg.norm(np.diff(np.array(stroke["points"]), axis=0), axis=1)
                free = (tip_speed[1:] > 500.0 / 3 + 1e-3) & (tip_speed[1:] < 500.0 * 3 - 1e-3) & (seg > 1e-6)
                np.testing.assert_allclose(surface[free] / (seg[free] / tip_speed[1:][free]), 500.0, rtol=1e-3)
                assert tip_speed.min() >= 500.0 / 3 - 1e-3 and tip_speed.max() <= 500.0 * 3 + 1e-3
            else:
                np.testing.assert_allclose(tip_speed, 1000.0)
            waypoints += len(tcp)
            for q, ok in zip(stroke["joints"], stroke["reachable"]):
                if ok:
                    assert len(q) == 9
                    # SQP may move the gantry slightly (the seed), at most 200 mm (solve_gantry_path's limit)
                    assert np.linalg.norm(np.array(q[6:]) - platform) <= 200.0 + 1e-9
            # the gun axis points at the surface point from the tcp, at the standoff
            np.testing.assert_allclose(tcp + 113.0 * np.array(stroke["tool_axis"]), stroke["points"], atol=1e-2)
    assert spray == pytest.approx(totals["spray_length_mm"], rel=1e-6)
    assert transfer == pytest.approx(totals["transfer_length_mm"], rel=1e-6)
    assert waypoints == totals["waypoints"]
    # the length-over-speed cycle time from its parts (the real one, within the joints' limits, is never less)
    expected = spray_time + transfer / 1000.0 + totals["platform_travel_mm"] / 250.0
    assert totals["cycle_time_length_over_speed_s"] == pytest.approx(expected, rel=1e-4)
    assert totals["cycle_time_s"] >= totals["cycle_time_length_over_speed_s"]
    # the gantry tour starts and ends at home and is the Manhattan length of its legs
    stops = np.array([data["home_mm"], *[s["platform_mm"] for s in data["stations"]], data["home_mm"]])
    assert totals["platform_travel_mm"] == pytest.approx(np.abs(np.diff(stops, axis=0)).sum(), rel=1e-6)


def test_waypoints_csv_matches_plan(reach_plan):
    out, data = reach_plan
    table = np.genfromtxt(out / "waypoints.csv", delimiter=",", names=True)
    assert len(table) == data["totals"]["waypoints"]
    number = lambda values: np.array([np.nan if v is None else v for v in values], float)
    rows = [
        (place, i, k, s)
        for place, st in enumerate(data["stations"])
        for i, s in enumerate(st["strokes"])
        for k in range(len(s["tcp"]))
    ]
    assert [tuple(r[:3]) for r in rows] == list(zip(table["station"], table["stroke"], table["waypoint"]))
    assert (table["spray_on"] == [s["spray_on"] for *_, s in rows]).all()
    assert (table["reachable"] == [s["reachable"][k] for _, _, k, s in rows]).all()
    # plan.json keeps every float; waypoints.csv 10 significant digits (6 for the errors and speeds)
    for names, key, digits in (
        (("x", "y", "z"), "tcp", 10),
        (("ax", "ay", "az"), "tool_axis", 10),
        (("q1", "q2", "q3", "q4", "q5", "q6", "tx", "ty", "tz"), "joints", 10),
    ):
        wanted = np.array([s[key][k] for _, _, k, s in rows], float)
        if key == "joints":
            wanted[table["reachable"] != 1] = np.nan  # empty cells where unreachable
        got = np.column_stack([table[n] for n in names])
        np.testing.assert_allclose(got, wanted, rtol=10.0 ** (1 - digits), atol=1e-12)
    for name, key in (
        ("position_error_mm", "position_error_mm"),
        ("axis_error_deg", "axis_error_deg"),
        ("speed_mm_s", "tcp_speed_mm_s"),
    ):
        wanted = number([s[key][k] for _, _, k, s in rows])
        np.testing.assert_allclose(table[name], wanted, rtol=1e-5, atol=1e-12)
    reachable = table["reachable"] == 1
    assert np.isnan(table["q1"][~reachable]).all() and np.isfinite(table["q1"][reachable]).all()


def test_joint_values_put_the_gun_where_the_plan_says(reach_plan):
    _, data = reach_plan
    gantry = Gantry()
    for station in data["stations"][:2]:
        for stroke in station["strokes"][:3]:
            ok = np.array(stroke["reachable"])
            q = np.array([j for j, r in zip(stroke["joints"], ok) if r], dtype=float)
            target = gantry.target2world(q)
            wanted = np.array(stroke["points"])[ok]
            error = np.linalg.norm(target[:, :3, 3] - wanted, axis=1)
            reported = np.array([np.nan if v is None else v for v in stroke["position_error_mm"]])[ok]
            np.testing.assert_allclose(error, reported, atol=1e-3)
            assert error.max() <= 5.0 + 1e-6


def test_every_car_body_point_is_assigned_or_reported(testdata):
    # a large, whole-body part: half of the BMW body (x > 0: 2.45 x 2.09 x 1.24 m of bonnet or boot, roof,
    # doors, sills, bumper), too big for one station, with surfaces facing every way
    from sprayplan.surface.region import painted_surface, select_region

    car = select_region(load_part(testdata / "meshes" / "bmw_m6_body_m_yup.ply", units="m", up="y"), "x > 0")
    job = JobConfig(paths=PathConfig(spacing_mm=150.0, step_mm=60.0))
    result = plan(car, job)
    totals = plan_totals(result, job)
    # every waypoint of the sliced strokes is either in a station's strokes or listed as unassigned (a stroke
    # handed from one station to the next repeats the hand-over waypoint, so compare sets)
    from sprayplan.paths.planner import plan_paths

    def rows(arrays):
        return {tuple(r) for r in np.round(np.vstack(arrays), 6)} if arrays else set()

    planned = rows([s.points for st in result.stations for s in st.strokes if s.spray_on])
    unassigned = rows([result.unassigned]) if len(result.unassigned) else set()
    # the job leaves out the surface facing the floor and the covered surface ([collision] skip_floor_facing,
    # skip_covered) before slicing
    painted, _ = painted_surface(car, job.collision)
    sliced = rows([s.points for s in plan_paths(painted, job.paths).spray_strokes])
    assert planned | unassigned == sliced and not planned & unassigned
    assert totals["stations"] >= 4
    # the sills, bumper and lower body face sideways and down: the hanging robot cannot paint all of them,
    # and says so waypoint by waypoint
    assert 0 < totals["unreachable_waypoints"] < totals["waypoints"]


def test_points_mode_visits_every_target(tmp_path):
    from sprayplan.demo import car_roof
    from sprayplan.surface.region import select_region
    from sprayplan.surface.targets import make_targets

    roof = select_region(car_roof(resolution_mm=50.0), "box(-700, -500, 1000, 700, 500, 2000)")
    job = JobConfig(
        load=LoadConfig(region=None),
        mode="points",
        ordering=OrderingConfig(tour="auto"),
    )
    result = plan(roof, job)
    visited = np.vstack([s.points for st in result.stations for s in st.strokes if s.spray_on])
    targets = make_targets(roof, job.targets)
    assert len(visited) + len(result.unassigned) == len(targets)
    # a permutation of the targets: each one exactly once
    assert len(np.unique(np.round(visited, 6), axis=0)) == len(visited)


def test_a_plan_repeats_exactly(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    job = JobConfig(paths=PathConfig(spacing_mm=100.0, step_mm=40.0))
    first, second = plan(part, job), plan(part, job)
    assert len(first.stations) == len(second.stations)
    for a, b in zip(first.stations, second.stations):
        np.testing.assert_array_equal(a.platform_mm, b.platform_mm)
        np.testing.assert_array_equal(np.nan_to_num(a.q9), np.nan_to_num(b.q9))
        assert len(a.strokes) == len(b.strokes)


def test_a_stroke_split_between_stations_is_sprayed_whole():
    from sprayplan.stations.stage import split_by_station
    from sprayplan.types import Stroke

    x = np.arange(0.0, 101.0, 10.0)
    points = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    stroke = Stroke(points, np.tile([0.0, 0.0, 1.0], (len(x), 1)), points + [0, 0, 113.0], True, None, 3)
    station = np.array([2, 2, 2, 2, 5, 5, 5, -1, -1, 5, 5])
    pieces = split_by_station(stroke, station)
    assert [k for k, _ in pieces] == [2, 5, 5]
    # the hand-over segment 30 -> 40 belongs to the first station's piece; a run ending at waypoints no station
    # takes stops there; every piece keeps the stroke's layer
    assert [p.points[[0, -1], 0].tolist() for _, p in pieces] == [[0.0, 40.0], [40.0, 60.0], [90.0, 100.0]]
    assert all(p.layer == 3 and p.spray_on for _, p in pieces)
    sprayed = sum(p.length_mm for _, p in pieces)
    assert sprayed == pytest.approx(100.0 - 30.0)  # all but the 60 -> 90 stretch through unassigned waypoints
