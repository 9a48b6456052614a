"""Ruled surfaces between two boundary curves and their spray paths (seed 001)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from sprayplan.errors import PartFileError
from sprayplan.export.tables import write_table_csv
from sprayplan.paths.ruled import (
    Arc,
    Line,
    PointCurve,
    Polyline,
    RuledJob,
    RuledPathConfig,
    RuledSurface,
    cartesian_table,
    ruled_paths,
)
from sprayplan.paths.ruled_toml import load_ruled
from sprayplan.robots.r5150 import table4_joints, table4_points
from sprayplan.surface.coverage import spacing_for_overlap

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "ruled"

# Seed 001, table 4 (its columns re-read as docs/seed-notes.md says), from the R5150 module
TABLE4_XYZ = table4_points()
TABLE4_THETA_DEG = table4_joints()  # theta1..theta5
TABLE5_LISTED = {1: (172, 162, 300), 2: (300, 162, 300), 3: (192, 182, 300), 10: (300, 255.4, 300)}


def r5150_position(theta1, theta2, theta3, theta4):
    """Seed 001 eq. 3 (degrees in, mm out): the R5150's tool tip."""
    d1, a2, a3, d5 = 255.55, 190.0, 190.0, 115.0
    t1, t2, t3, t4 = np.radians([theta1, theta2, theta3, theta4])
    r = a2 * np.cos(t2) + a3 * np.cos(t2 + t3) + d5 * np.sin(t2 + t3 + t4)
    z = d1 + a2 * np.sin(t2) + a3 * np.sin(t2 + t3) - d5 * np.cos(t2 + t3 + t4)
    return np.stack([r * np.cos(t1), r * np.sin(t1), z], axis=-1)


def write(tmp_path, text, name="job.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def job_of(curve_a, curve_b, **settings):
    gun = settings.pop("gun_side", (0.0, 0.0, 1.0))
    outward = settings.pop("outward_from", None)
    return RuledJob(RuledSurface(curve_a, curve_b, gun, outward), RuledPathConfig(**settings), "test")


def solve_uv(surface, point):
    """(u, v) with S(u, v) = point, found independently of the path code (grid start, then least squares)."""
    uu, vv = np.meshgrid(np.linspace(0, 1, 401), np.linspace(0, 1, 41), indexing="ij")
    grid = surface.evaluate(uu.ravel(), vv.ravel())
    i = int(np.argmin(np.linalg.norm(grid - point, axis=1)))
    fit = least_squares(
        lambda x: surface.evaluate(x[0], x[1])[0] - point,
        [uu.ravel()[i], vv.ravel()[i]],
        bounds=([0, 0], [1, 1]),
        xtol=1e-15,
        ftol=1e-15,
        gtol=1e-15,
    )
    return fit.x, float(np.linalg.norm(fit.fun))


# ------------------------------------------------------------------------------------------------ the seed's tables


def test_case1_reproduces_table4_in_order():
    job = load_ruled(EXAMPLES / "case1_table4.toml")
    assert job.config.passes == 5 and job.config.standoff_mm == 0
    paths = ruled_paths(job)
    assert len(paths.spray_strokes) == 5
    np.testing.assert_allclose(cartesian_table(paths), TABLE4_XYZ, rtol=0, atol=1e-9)


def test_case1_points_are_the_table4_joint_rows_under_r5150_kinematics():
    """The column reading in the module docstring: the printed joint columns give our points by eq. 3."""
    table = cartesian_table(ruled_paths(load_ruled(EXAMPLES / "case1_table4.toml")))
    theta = TABLE4_THETA_DEG
    fk = r5150_position(theta[:, 0], theta[:, 1], theta[:, 2], theta[:, 3])
    np.testing.assert_allclose(fk, table, atol=1e-3)
    np.testing.assert_allclose(theta[:, 1] + theta[:, 2] + theta[:, 3], 0.0, atol=2e-4)  # tool straight down


def test_case2_reproduces_the_listed_rows_of_table5():
    table = cartesian_table(ruled_paths(load_ruled(EXAMPLES / "case2_table5.toml")))
    assert table.shape == (10, 3)
    for row, xyz in TABLE5_LISTED.items():
        np.testing.assert_allclose(table[row - 1], xyz, rtol=0, atol=1e-9)


def test_table_csv_numbers_rows_from_one(tmp_path):
    paths = ruled_paths(load_ruled(EXAMPLES / "case1_table4.toml"))
    out = tmp_path / "sub" / "table4.csv"
    write_table_csv(out, paths)
    with open(out, newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["n", "x", "y", "z"]
    assert [int(r[0]) for r in rows[1:]] == list(range(1, 11))
    np.testing.assert_allclose(np.array(rows[1:], dtype=float)[:, 1:], TABLE4_XYZ, atol=1e-6)
    assert rows[1] == ["1", "150", "100", "150"]


# ------------------------------------------------------------------------------------------------ surface invariants


def fan_job():
    return job_of(
        Line([0, 0, 0], [200, 0, 0]), PointCurve([100, 150, 0]), spot_diameter_mm=40, step_mm=30, standoff_mm=50
    )


def polyline_job():
    a = Polyline([[0, 0, 0], [100, 0, 20], [200, 50, 0], [300, 50, 10]])
    b = Arc.through_points([0, 200, 60], [150, 260, 90], [300, 200, 60])
    return job_of(a, b, spot_diameter_mm=60, overlap=0.3, standoff_mm=120, direction="across", step_mm=15)


JOBS = {
    "arc_to_line": lambda: load_ruled(EXAMPLES / "arc_to_line.toml"),
    "cylinder_band": lambda: load_ruled(EXAMPLES / "cylinder_band.toml"),
    "case1": lambda: load_ruled(EXAMPLES / "case1_table4.toml"),
    "case2": lambda: load_ruled(EXAMPLES / "case2_table5.toml"),  # its cross product points down: turned up
    "fan": fan_job,
    "polyline_to_arc": polyline_job,
}


@pytest.mark.parametrize("name", sorted(JOBS))
def test_points_lie_on_the_surface_with_unit_gun_side_normals(name):
    job = JOBS[name]()
    surface = job.surface
    paths = ruled_paths(job)
    for stroke in paths.strokes:
        assert np.array_equal(stroke.tcp, stroke.points + paths.standoff_mm * stroke.normals)
        np.testing.assert_allclose(np.linalg.norm(stroke.normals, axis=1), 1.0, atol=1e-12)
        if surface.outward_from is None:
            assert np.all(stroke.normals @ surface.gun_side >= 0)
        else:
            assert np.all(np.einsum("ij,ij->i", stroke.normals, stroke.points - surface.outward_from) > 0)
    points = np.vstack([s.points for s in paths.strokes])
    normals = np.vstack([s.normals for s in paths.strokes])
    for k in np.linspace(0, len(points) - 1, min(len(points), 120)).astype(int):
        (u, v), residual = solve_uv(surface, points[k])
        assert residual < 1e-7
        near = [b for b in surface.breaks if abs(u - b) < 1e-7]
        u = near[0] if near else u  # at a corner: the documented side, the segment after it
        for tangent in surface.tangents(u, v):
            length = np.linalg.norm(tangent)
            assert abs(float(normals[k] @ tangent[0])) <= 1e-9 * max(length, 1.0)


@pytest.mark.parametrize("name", sorted(JOBS))
def test_analytic_tangents_match_finite_differences(name):
    surface = JOBS[name]().surface
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0.01, 0.99, 50), rng.uniform(0, 1, 50)
    h = 1e-6
    s_u, s_v = surface.tangents(u, v)
    fd_u = (surface.evaluate(u + h, v) - surface.evaluate(u - h, v)) / (2 * h)
    fd_v = (surface.evaluate(u, v + h) - surface.evaluate(u, v - h)) / (2 * h)
    corner = np.zeros(len(u), dtype=bool)
    for b in surface.breaks:
        corner |= np.abs(u - b) < 2 * h
    scale = max(surface.curve_a.length_mm, surface.curve_b.length_mm, 1.0)
    np.testing.assert_allclose(s_u[~corner], fd_u[~corner], atol=1e-6 * scale)
    np.testing.assert_allclose(s_v, fd_v, atol=1e-6 * scale)


@pytest.mark.parametrize("name", sorted(JOBS))
def test_normals_do_not_depend_on_which_curve_is_a(name):
    job = JOBS[name]()
    surface = job.surface
    swapped = RuledSurface(surface.curve_b, surface.curve_a, surface.gun_side, surface.outward_from)
    rng = np.random.default_rng(1)
    u, v = rng.uniform(0, 1, 200), rng.uniform(0.01, 0.99, 200)
    np.testing.assert_allclose(swapped.evaluate(u, 1 - v), surface.evaluate(u, v), atol=1e-9)
    np.testing.assert_allclose(swapped.normals(u, 1 - v), surface.normals(u, v), atol=1e-9)


def test_cone_normals_are_the_analytic_ones():
    radius, height = 120.0, 90.0
    job = job_of(Arc([0, 0, 0], radius), PointCurve([0, 0, height]), spot_diameter_mm=50, step_mm=20)
    paths = ruled_paths(job)
    for stroke in paths.spray_strokes:
        base = stroke.points[np.argmin(stroke.points[:, 2])]
        theta = math.atan2(base[1], base[0])
        expected = np.array([height * math.cos(theta), height * math.sin(theta), radius])
        np.testing.assert_allclose(
            stroke.normals, np.tile(expected / np.linalg.norm(expected), (len(stroke), 1)), atol=1e-9
        )  # the apex (v = 1) included
        np.testing.assert_allclose(stroke.points[[0, -1]][:, 2].max(), height)


def test_point_curve_makes_a_fan():
    job = fan_job()
    paths = ruled_paths(job)
    apex = np.array([100.0, 150.0, 0.0])
    passes = paths.spray_strokes
    for k, stroke in enumerate(passes):
        apex_end = stroke.points[-1] if k % 2 == 0 else stroke.points[0]
        np.testing.assert_allclose(apex_end, apex, atol=1e-12)
        np.testing.assert_allclose(stroke.normals, np.tile([0, 0, 1.0], (len(stroke), 1)), atol=1e-12)
    starts = np.array([s.points[0] if k % 2 == 0 else s.points[-1] for k, s in enumerate(passes)])
    assert np.all(starts[:, 1] == 0) and np.all(np.diff(starts[:, 0]) > 0)


# ------------------------------------------------------------------------------------------------ spacing and order


@pytest.mark.parametrize("direction", ["rulings", "across"])
@pytest.mark.parametrize("overlap", [0.0, 0.25, 0.4, 0.7])
def test_flat_rectangle_passes_are_the_set_spacing_apart(direction, overlap):
    spot = 80.0
    d = spacing_for_overlap(overlap, spot / 2)
    width, height = 1000.0, 300.0  # A: the x axis, B: 300 mm up in y
    job = job_of(
        Line([0, 0, 0], [width, 0, 0]),
        Line([0, height, 0], [width, height, 0]),
        spot_diameter_mm=spot,
        overlap=overlap,
        direction=direction,
        standoff_mm=100,
    )
    paths = ruled_paths(job)
    passes = paths.spray_strokes
    axis = 0 if direction == "rulings" else 1
    extent = width if direction == "rulings" else height
    offsets = np.array([s.points[0, axis] for s in passes])
    assert all(np.ptp(s.points[:, axis]) == 0 for s in passes)  # straight passes of constant offset
    np.testing.assert_allclose(np.diff(offsets), d, rtol=0, atol=1e-9)
    assert paths.spacing_mm == pytest.approx(d, abs=1e-12)
    margin_low, margin_high = offsets[0], extent - offsets[-1]
    assert margin_low == pytest.approx(margin_high, abs=1e-9) and 0 <= margin_low < d / 2
    along = [s.points[-1] - s.points[0] for s in passes]
    signs = np.sign([a[1 - axis] for a in along])
    assert np.all(signs[:-1] == -signs[1:]) and np.all(signs != 0)
    for stroke in passes:
        np.testing.assert_allclose(stroke.tcp[:, 2], 100.0)


def test_transfers_are_spray_off_and_join_the_passes():
    paths = ruled_paths(load_ruled(EXAMPLES / "arc_to_line.toml"))
    kinds = [s.spray_on for s in paths.strokes]
    assert kinds == [True, False] * (len(kinds) // 2) + [True]
    for k in range(1, len(paths.strokes), 2):
        before, transfer, after = paths.strokes[k - 1], paths.strokes[k], paths.strokes[k + 1]
        assert not transfer.spray_on and transfer.layer == -1 and not transfer.on_part.any()
        np.testing.assert_allclose(transfer.tcp[0], before.tcp[-1], atol=1e-9)
        np.testing.assert_allclose(transfer.tcp[-1], after.tcp[0], atol=1e-9)
    assert [s.layer for s in paths.spray_strokes] == list(range(len(paths.spray_strokes)))


def test_ruling_passes_are_the_spacing_apart_along_the_longer_curve():
    job = load_ruled(EXAMPLES / "arc_to_line.toml")  # arc 628 mm, line 424 mm
    paths = ruled_paths(job)
    d = spacing_for_overlap(0.4, 50.0)
    on_arc = np.array([s.points[0] if k % 2 == 0 else s.points[-1] for k, s in enumerate(paths.spray_strokes)])
    angles = np.arctan2(on_arc[:, 1], on_arc[:, 0])
    np.testing.assert_allclose(np.linalg.norm(on_arc[:, :2], axis=1), 400.0, atol=1e-9)
    np.testing.assert_allclose(np.diff(angles) * 400.0, d, atol=1e-9)
    assert angles[0] == pytest.approx(math.pi / 2 - angles[-1], abs=1e-12)  # centred


def test_closed_band_goes_all_the_way_round():
    radius = 150.0
    job = job_of(Arc([0, 0, 0], radius), Arc([0, 0, 400], radius), spot_diameter_mm=80, outward_from=(0, 0, 200))
    passes = ruled_paths(job).spray_strokes
    d = spacing_for_overlap(0.4, 40.0)
    assert len(passes) == math.ceil(2 * math.pi * radius / d)
    bottoms = np.array([s.points[0] if k % 2 == 0 else s.points[-1] for k, s in enumerate(passes)])
    gaps = np.diff(np.unwrap(np.arctan2(bottoms[:, 1], bottoms[:, 0]))) * radius
    np.testing.assert_allclose(gaps, 2 * math.pi * radius / len(passes), atol=1e-9)
    assert np.all(gaps <= d)
    for stroke in passes:
        radial = stroke.points * [1, 1, 0] / radius
        np.testing.assert_allclose(stroke.normals, radial, atol=1e-12)


def test_one_way_passes_all_run_from_a_to_b():
    job = load_ruled(EXAMPLES / "case2_table5.toml")
    passes = ruled_paths(job).spray_strokes
    assert all(s.points[-1, 0] == 300 for s in passes)


# ------------------------------------------------------------------------------------------------ curves


@pytest.mark.parametrize("normal", [(0, 0, 1), (0, 0, -1), (1, 0, 0), (1, 2, 3)])
@pytest.mark.parametrize("start_deg, end_deg", [(0, 90), (30, -120), (-45, 315)])
def test_arc_lies_on_its_circle_uniform_in_arc_length(normal, start_deg, end_deg):
    center, radius = np.array([10.0, -20.0, 30.0]), 250.0
    arc = Arc(center, radius, normal, math.radians(start_deg), math.radians(end_deg - start_deg))
    u = np.linspace(0, 1, 41)
    points = arc.evaluate(u)
    unit = np.asarray(normal, float) / np.linalg.norm(normal)
    np.testing.assert_allclose(np.linalg.norm(points - center, axis=1), radius, atol=1e-9)
    np.testing.assert_allclose((points - center) @ unit, 0.0, atol=1e-9)
    chords = np.linalg.norm(np.diff(points, axis=0), axis=1)
    np.testing.assert_allclose(chords, chords[0], atol=1e-9)
    sweep = math.radians(abs(end_deg - start_deg))
    assert chords[0] == pytest.approx(2 * radius * math.sin(sweep / 80), abs=1e-9)
    assert arc.length_mm == pytest.approx(radius * sweep)
    turn = np.cross(points[0] - center, points[1] - center) @ unit
    assert np.sign(turn) == np.sign(end_deg - start_deg)


@pytest.mark.parametrize("angles_deg", [(0, 200, 300), (300, 10, 100), (170, 90, -100), (-30, 179, 181)])
def test_arc_through_three_points_runs_through_the_middle_one(angles_deg):
    center, radius = np.array([5.0, 6.0, 7.0]), 40.0
    e1, e2 = np.array([0.0, 1.0, 0.0]), np.array([0.6, 0.0, 0.8])  # a tilted plane
    a, m, b = (center + radius * (math.cos(math.radians(t)) * e1 + math.sin(math.radians(t)) * e2) for t in angles_deg)
    arc = Arc.through_points(a, m, b)
    np.testing.assert_allclose(arc.evaluate([0.0, 1.0]), [a, b], atol=1e-9)
    np.testing.assert_allclose(arc.center, center, atol=1e-9)
    points = arc.evaluate(np.linspace(0, 1, 20001))
    assert np.min(np.linalg.norm(points - m, axis=1)) < 2 * arc.length_mm / 20000
    turn = [(t - angles_deg[0]) % 360 for t in angles_deg[1:]]
    expected = turn[1] if turn[0] < turn[1] else 360 - turn[1]  # the way round that meets the middle point
    assert arc.length_mm == pytest.approx(radius * math.radians(expected), rel=1e-12)


def test_arc_through_three_points_and_circle(tmp_path):
    a, m, b = np.array([0.0, 0, 5]), np.array([50.0, 30, 5]), np.array([100.0, 0, 5])
    arc = Arc.through_points(a, m, b)
    u = np.linspace(0, 1, 2001)
    points = arc.evaluate(u)
    np.testing.assert_allclose(points[[0, -1]], [a, b], atol=1e-9)
    assert np.min(np.linalg.norm(points - m, axis=1)) < arc.length_mm / 1000
    assert np.all(points[1:-1, 1] > 0)  # the side of the mid point
    np.testing.assert_allclose(np.linalg.norm(points - arc.center, axis=1), arc.radius_mm, atol=1e-9)
    path = write(
        tmp_path,
        """
[curve_a]
type = "circle"
center = [0, 0, 0]
radius = 80
start_angle_deg = 90
[curve_b]
type = "point"
at = [0, 0, 100]
[path]
passes = 8
""",
    )
    circle = load_ruled(path).surface.curve_a
    assert circle.closed
    points = circle.evaluate(np.linspace(0, 1, 9))
    np.testing.assert_allclose(points[0], [0, 80, 0], atol=1e-12)
    np.testing.assert_allclose(points[0], points[-1], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(np.diff(points, axis=0), axis=1), 2 * 80 * math.sin(math.pi / 8))


def test_polyline_in_2d_gets_z_and_is_uniform_in_arc_length(tmp_path):
    path = write(
        tmp_path,
        """
[curve_a]
type = "polyline"
points = [[0, 0], [100, 0], [100, 50]]
z = 20
[curve_b]
type = "polyline"
points = [[0, 100, 40], [150, 100]]
[path]
spot_diameter_mm = 30
""",
    )
    job = load_ruled(path)
    a, b = job.surface.curve_a, job.surface.curve_b
    np.testing.assert_array_equal(a.vertices[:, 2], 20.0)
    np.testing.assert_array_equal(b.vertices, [[0, 100, 40], [150, 100, 0]])
    np.testing.assert_allclose(
        a.evaluate([0, 0.5, 2 / 3, 1]), [[0, 0, 20], [75, 0, 20], [100, 0, 20], [100, 50, 20]], atol=1e-12
    )
    np.testing.assert_allclose(a.breaks, [2 / 3])
    u = np.linspace(0, 1, 7)
    np.testing.assert_allclose(np.linalg.norm(np.diff(a.evaluate(u), axis=0), axis=1), 25.0, atol=1e-12)


def test_polyline_closed_flag_returns_to_start():
    line = Polyline([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 0, 0]])
    assert line.closed and line.length_mm == pytest.approx(20 + math.sqrt(200))


# ------------------------------------------------------------------------------------------------ bad files


GOOD = """
[curve_a]
type = "line"
start = [0, 0, 0]
end = [100, 0, 0]
[curve_b]
type = "line"
start = [0, 100, 0]
end = [100, 100, 0]
[path]
spot_diameter_mm = 40
"""


@pytest.mark.parametrize(
    "text, key",
    [
        ("[curve_a\ntype = 'line'", "TOML"),
        (GOOD + "spacing_mm = 3\n", "path.spacing_mm"),
        (GOOD.replace("end = [100, 0, 0]", "end = [100, 0, 0]\nradius = 4"), "curve_a.radius"),
        (GOOD + "[extra]\n", "extra"),
        (GOOD.split("[curve_b]")[0] + "[path]\nspot_diameter_mm = 40\n", "curve_b"),
        (GOOD.replace("spot_diameter_mm = 40", "spot_diameter_mm = -40"), "spot_diameter_mm"),
        (GOOD.replace("spot_diameter_mm = 40", "spot_diameter_mm = 40\noverlap = 1.0"), "overlap"),
        (GOOD.replace("spot_diameter_mm = 40", "spot_diameter_mm = 40\noverlap = 1.5"), "overlap"),
        (GOOD.replace("spot_diameter_mm = 40", "standoff_mm = 10"), "spot_diameter_mm"),
        (GOOD.replace("spot_diameter_mm = 40", "passes = 3\noverlap = 0.2"), "path.passes"),
        (GOOD.replace("spot_diameter_mm = 40", "passes = 2.5"), "path.passes"),
        (GOOD.replace("spot_diameter_mm = 40", "spot_diameter_mm = '40'"), "path.spot_diameter_mm"),
        (GOOD.replace("start = [0, 0, 0]", "start = [0, 0]"), "curve_a.start"),
        (GOOD.replace('type = "line"\nstart = [0, 100, 0]', 'type = "spline"\nstart = [0, 100, 0]'), "curve_b.type"),
        (GOOD.replace("direction", "x") + 'direction = "diagonal"\n', "direction"),
        (GOOD.replace("[0, 100, 0]", "[0, 0, 0]").replace("[100, 100, 0]", "[100, 0, 0]"), "span no surface"),
        (
            GOOD.replace(
                'type = "line"\nstart = [0, 100, 0]\nend = [100, 100, 0]',
                'type = "arc"\ncenter = [0, 0, 0]\nradius = -5\nstart_angle_deg = 0\nend_angle_deg = 9',
            ),
            "radius",
        ),
    ],
)
def test_bad_files_raise_part_file_error_naming_the_file(tmp_path, text, key):
    path = write(tmp_path, text, "broken_job.toml")
    with pytest.raises(PartFileError) as info:
        load_ruled(path)
    message = str(info.value)
    assert message.startswith(str(path)) and "\n" not in message
    assert key in message


def test_missing_file_is_a_part_file_error(tmp_path):
    with pytest.raises(PartFileError, match="not found"):
        load_ruled(tmp_path / "nope.toml")
    with pytest.raises(PartFileError, match="directory"):
        load_ruled(tmp_path)
    with pytest.raises(PartFileError, match="usable file name"):
        load_ruled(str(tmp_path / "a\x00b.toml"))
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(b"name = '\xe9'\n")
    with pytest.raises(PartFileError, match="UTF-8"):
        load_ruled(bad)


def test_good_file_loads_with_documented_defaults(tmp_path):
    job = load_ruled(write(tmp_path, GOOD, "plate.toml"))
    config = job.config
    assert (config.overlap, config.passes, config.standoff_mm, config.direction, config.step_mm, config.zigzag) == (
        0.4,
        None,
        0.0,
        "rulings",
        None,
        True,
    )
    assert config.spacing_mm == pytest.approx(spacing_for_overlap(0.4, 20.0))
    np.testing.assert_array_equal(job.surface.gun_side, [0, 0, 1])
    assert job.name == "plate"
    assert all(len(s) == 2 for s in ruled_paths(job).spray_strokes)  # a ruling's two ends only
