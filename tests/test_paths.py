"""Spray paths by slicing (seed 003 sections 2-3) on real parts: spacing, surface, coverage, holes, zig-zag."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from sprayplan.cli import main
from sprayplan.config import PathConfig
from sprayplan.errors import ConfigError, InputError
from sprayplan.export.paths_json import read_paths_json, write_paths_json
from sprayplan.io.load import load_part
from sprayplan.paths.frame import slicing_frame, surface_covariance
from sprayplan.paths.mesh_sections import point_segment_distance
from sprayplan.paths.planner import plan_paths
from sprayplan.surface.filling import sample_uniform
from sprayplan.surface.region import select_region
from sprayplan.types import Part
from tests.helpers import containing_face, on_mesh, plate


@pytest.fixture(scope="module")
def reach(testdata):
    return load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")


@pytest.fixture(scope="module")
def tray_top(testdata):
    # the tray is a y-up plate 3.175 mm thick: its top face, holes and all
    return select_region(load_part(testdata / "meshes" / "tray_bottom_mm_ascii.stl", up="y"), "z > 3.1")


@pytest.fixture(scope="module")
def reach_paths(reach):
    return plan_paths(reach, PathConfig())


def layer_spacings(paths):
    """Median distance from each layer's on-part points to the next layer's polylines."""
    layers = {}
    for s in paths.spray_strokes:
        if s.on_part.any():  # edge passes lie past the part's edge
            layers.setdefault(s.layer, []).append(s)
    keys = sorted(layers)
    out = []
    for a, b in itertools.pairwise(keys):
        query = np.vstack([s.points[s.on_part] for s in layers[a]])
        seg_a = np.vstack([s.points[:-1] for s in layers[b]])
        seg_b = np.vstack([s.points[1:] for s in layers[b]])
        out.append(float(np.median(point_segment_distance(query, seg_a, seg_b, k=16))))
    return np.array(out)


def test_adjacent_strokes_are_the_spacing_apart_on_the_flat_tray(tray_top):
    paths = plan_paths(tray_top, PathConfig(spacing_mm=30.0))
    spacing = layer_spacings(paths)
    assert len(spacing) >= 10
    # edge passes past the far edge take the place of a closing layer: every pair is the spacing apart
    np.testing.assert_allclose(spacing, 30.0, rtol=0.02)


def test_without_edge_passes_a_last_layer_closes_the_far_edge(tray_top):
    paths = plan_paths(tray_top, PathConfig(spacing_mm=30.0, edge_passes=0))
    assert all(s.on_part.any() for s in paths.spray_strokes)
    spacing = layer_spacings(paths)
    np.testing.assert_allclose(spacing[:-1], 30.0, rtol=0.02)
    assert spacing[-1] <= 30.0 * 1.02


def test_adjacent_strokes_are_the_spacing_apart_on_the_curved_part(reach_paths):
    d = reach_paths.spacing_mm
    assert d == pytest.approx(49.186, abs=1e-3)  # seed 000: r = 50 mm, overlap 0.4
    spacing = layer_spacings(reach_paths)
    # every pair, the far flange too (the march measures the gap both ways, so a narrowing section does not
    # look farther away than it is; there is no closing layer, edge passes carry on past the edge)
    assert len(spacing) >= 25
    np.testing.assert_allclose(spacing, d, rtol=0.01)


def test_uniform_planes_are_equally_spaced(reach):
    paths = plan_paths(reach, PathConfig(spacing_mode="uniform", direction="x", spacing_mm=40.0))
    heights = sorted({round(float(s.points[s.on_part][0, 0]), 6) for s in paths.spray_strokes if s.on_part.any()})
    np.testing.assert_allclose(np.diff(heights), 40.0, atol=1e-6)
    for stroke in paths.spray_strokes:  # every on-part point of a stroke lies in its plane
        if not stroke.on_part.any():
            continue
        assert np.ptp(stroke.points[stroke.on_part, 0]) < 1e-6


def test_tcp_is_point_plus_standoff_times_normal(reach_paths):
    for stroke in reach_paths.strokes:
        np.testing.assert_allclose(stroke.tcp, stroke.points + 113.0 * stroke.normals, atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(stroke.normals, axis=1), 1.0, atol=1e-9)


def test_contact_points_lie_on_the_surface(reach, reach_paths):
    points = np.vstack([s.points[s.on_part] for s in reach_paths.spray_strokes])
    assert len(points) > 1000
    assert on_mesh(points, reach.vertices, reach.faces).all()


def test_normals_point_out_like_the_faces(reach, reach_paths):
    from sprayplan.surface.normals import outward_face_normals

    _, face_n = outward_face_normals(reach.vertices, reach.faces)
    points = np.vstack([s.points[s.on_part] for s in reach_paths.spray_strokes])
    normals = np.vstack([s.normals[s.on_part] for s in reach_paths.spray_strokes])
    face = containing_face(points, reach.vertices, reach.faces)
    assert (face >= 0).all()
    # interpolated vertex normals lie within 90 degrees of the face the point lies on, except on the rolled
    # rim where the sheet folds through more than 90 degrees within one ring of faces
    dots = np.einsum("ij,ij->i", normals, face_n[face])
    vertex_n = trimesh.Trimesh(reach.vertices, reach.faces, process=False).vertex_normals
    smooth = (np.einsum("fkj,fj->fk", vertex_n[reach.faces], face_n) > np.cos(np.radians(45))).all(axis=1)
    assert smooth[face].mean() > 0.9
    assert (dots[smooth[face]] > 0).all()


@pytest.mark.parametrize("part_name", ["reach", "tray_top"])
def test_spray_covers_the_region(request, part_name):
    part = request.getfixturevalue(part_name)
    config = PathConfig()
    paths = plan_paths(part, config)
    contacts = np.vstack([s.points[s.on_part] for s in paths.spray_strokes])
    probes, _ = sample_uniform(part.triangles, 100_000, np.random.default_rng(0))
    distance = cKDTree(contacts).query(probes)[0]
    assert (distance <= config.spray_radius_mm).mean() >= 0.995


def test_no_spray_on_stroke_crosses_a_hole_wider_than_the_spray(tray_top):
    # with a 10 mm spray the tray's slots (12.7 x 44.5 mm) are wider than the spray; its small holes are not
    config = PathConfig(spray_radius_mm=5.0, spacing_mm=8.0, step_mm=1.0, edge_margin_mm=0.0)
    paths = plan_paths(tray_top, config)
    widest_bridge = 0.0
    split_somewhere = False
    for stroke in paths.spray_strokes:
        on = on_mesh(stroke.points, tray_top.vertices, tray_top.faces, tol=1e-7)
        off_runs = np.flatnonzero(np.diff(np.r_[1, on.astype(int), 1]) != 0).reshape(-1, 2)
        for start, stop in off_runs:
            if start == 0 or stop == len(on):
                continue  # off the part at the ends: beyond the edge
            length = np.linalg.norm(stroke.points[stop] - stroke.points[start - 1])
            widest_bridge = max(widest_bridge, length)
    for a, b in zip(paths.strokes, paths.strokes[1:]):
        if not b.spray_on and a.layer >= 0:
            split_somewhere = True
    assert split_somewhere
    assert widest_bridge <= 2 * config.spray_radius_mm + 1e-6
    bridged = [s for s in paths.spray_strokes if (~s.on_part[1:-1]).any()]
    assert bridged  # the small holes are sprayed across


def test_zig_zag_and_transfers(reach, reach_paths):
    _, travel = slicing_frame(surface_covariance(reach.triangles), "auto")
    strokes = reach_paths.strokes
    assert strokes[0].spray_on and strokes[-1].spray_on
    for a, b in itertools.pairwise(strokes):
        assert a.spray_on != b.spray_on  # spray, transfer, spray, ...
        np.testing.assert_allclose(a.tcp[-1], b.tcp[0], atol=1e-9)
    # the main stroke of each layer runs against the one of the layer before
    longest = {}
    for s in reach_paths.spray_strokes:
        if s.layer not in longest or s.length_mm > longest[s.layer].length_mm:
            longest[s.layer] = s
    signs = []
    for k in sorted(longest):
        chord = longest[k].points[-1] - longest[k].points[0]
        straight = abs(chord @ travel) > 0.5 * longest[k].length_mm  # not a U-shaped section
        signs.append(np.sign(chord @ travel) if straight else 0)
    pairs = [(a, b) for a, b in itertools.pairwise(signs) if a and b]
    assert len(pairs) >= 20
    assert all(a == -b for a, b in pairs)


def test_lead_in_and_lead_out_extend_past_the_edge(reach):
    exact = 0
    for stroke in plan_paths(reach, PathConfig(edge_passes=0)).spray_strokes:  # no edge pass joined to a stroke
        if np.array_equal(stroke.points[0], stroke.points[-1]) or not stroke.on_part.any():
            continue  # a closed loop has no ends; an edge pass has no on-part point
        inside = np.flatnonzero(stroke.on_part)
        first, last = inside[0], inside[-1]
        for end, edge in ((stroke.points[0], stroke.points[first]), (stroke.points[-1], stroke.points[last])):
            # the margin (50 mm), plus how far a cut-off rim (at most 25 mm of arc) reached along the lead
            lead = np.linalg.norm(end - edge)
            assert 50.0 - 1e-6 <= lead <= 75.0 + 1e-6
            exact += lead == pytest.approx(50.0, abs=1e-6)
    assert exact >= 10


def test_a_rolled_edge_is_not_followed(reach):
    # the reach part's long sides end in a rim turned over by more than 90 degrees within about 17 mm: the
    # strokes leave the face along its tangent (normals within 45 degrees of the face's) and pass the rim
    trimmed = 0
    for stroke in plan_paths(reach, PathConfig(edge_passes=0)).spray_strokes:
        inside = np.flatnonzero(stroke.on_part)
        if len(inside) < 10 or np.array_equal(stroke.points[0], stroke.points[-1]):
            continue
        for lead, face in ((slice(0, inside[0]), inside[0]), (slice(inside[-1] + 1, None), inside[-1])):
            assert (stroke.normals[lead] @ stroke.normals[face] > 1 - 1e-9).all()  # the lead keeps the normal
        ends = stroke.normals[inside[[0, -1]]]
        mid = stroke.normals[inside[len(inside) // 2]]
        assert (ends @ mid > np.cos(np.radians(100))).all()
        trimmed += np.linalg.norm(stroke.points[0] - stroke.points[inside[0]]) > 50.0 + 1e-6
    assert trimmed >= 10
    raw = plan_paths(reach, PathConfig(rim_mm=0.0, edge_passes=0, gun_smooth_mm=0.0))
    turned = [s for s in raw.spray_strokes if s.on_part.sum() >= 10]
    # followed to the end, the same strokes swing the gun round the rim
    assert sum(s.normals[0] @ s.normals[len(s) // 2] < np.cos(np.radians(60)) for s in turned) >= 10


def test_edge_passes_continue_the_spacing_past_the_edge():
    d = 30.0
    part = plate(0.0, 400.0, 0.0, 220.0, 5.0)  # strokes run along x, layers across y
    paths = plan_paths(part, PathConfig(spacing_mm=d, direction="y"))
    on = [s for s in paths.spray_strokes if s.on_part.any()]
    edge = [s for s in paths.spray_strokes if not s.on_part.any()]
    first, last = min(s.layer for s in on), max(s.layer for s in on)
    ys = sorted(float(np.median(s.points[s.on_part, 1])) for s in on)
    # the layers keep the spacing up to the far edge (220 = 15 + 6 x 30 + 25: no closing layer at 220)
    np.testing.assert_allclose(ys, 15.0 + d * np.arange(len(ys)), atol=1e-6)
    for s in edge:
        # in the plate's plane extended past its edge, with its normal, whole spacings from the outer layer
        np.testing.assert_allclose(s.points[:, 2], 0.0, atol=1e-9)
        np.testing.assert_allclose(s.normals, [[0.0, 0.0, 1.0]] * len(s), atol=1e-9)
        y = s.points[:, 1]
        assert np.ptp(y) < 1e-9
        assert (y[0] < 0.0) if s.layer < first else (y[0] > 220.0)
        k = s.layer - last if s.layer > last else first - s.layer
        assert abs(y[0] - (ys[-1] if s.layer > last else ys[0])) == pytest.approx(k * d)
    # auto: pass j spacings out is j d - s past the edge (s: outer layer to edge) and paints the part while
    # that is under the spray radius, 50 mm: before, s = 15 gives ceil(65 / 30) - 1 = 2; after, s = 25 also 2
    assert sorted({s.layer for s in edge}) == [0, 1, last + 1, last + 2]
    two = plan_paths(part, PathConfig(spacing_mm=d, direction="y", edge_passes=3)).spray_strokes
    assert sorted({s.layer for s in two if not s.on_part.any()}) == [0, 1, 2, last + 2, last + 3, last + 4]
    bare = plan_paths(part, PathConfig(spacing_mm=d, direction="y", edge_passes=0)).spray_strokes
    assert all(s.on_part.any() for s in bare)
    # without passes the march closes the far edge (25 mm left, over half a spacing) with a layer at the edge
    assert sorted(float(np.median(s.points[s.on_part, 1])) for s in bare)[-1] == pytest.approx(220.0, abs=1e-3)


def test_waypoints_are_the_step_apart(reach_paths):
    for stroke in reach_paths.spray_strokes:
        assert np.linalg.norm(np.diff(stroke.points, axis=0), axis=1).max() <= 10.0 + 1e-6


def test_arc_interpolation_between_section_samples(reach):
    config = PathConfig(points_per_section=20, interpolate="arc", step_mm=5.0, split_angle_deg=None)
    paths = plan_paths(reach, config)
    single = 0
    for stroke in paths.spray_strokes:
        on = np.flatnonzero(stroke.on_part)
        assert np.linalg.norm(np.diff(stroke.points, axis=0), axis=1).max() <= 5.0 + 1e-6
        if not len(on) or not (~stroke.on_part[on[0] : on[-1] + 1]).any():
            continue  # an edge pass, or no interpolated point (cannot happen with 20 samples on a long section)
        inner = stroke.on_part[on[0] : on[-1] + 1]
        runs_of_samples = np.count_nonzero(np.diff(np.r_[0, inner.astype(int)]) == 1)
        if stroke.length_mm > 500 and runs_of_samples == 20:  # one section piece: exactly its 20 samples
            single += 1
        assert np.linalg.norm(np.diff(stroke.points, axis=0), axis=1).max() <= 5.0 + 1e-6
        assert on_mesh(stroke.points[stroke.on_part], reach.vertices, reach.faces).all()
    assert single >= 10


def test_json_round_trip_and_schema(reach_paths, tmp_path):
    path = tmp_path / "paths.json"
    write_paths_json(path, reach_paths, {"direction": "auto"})
    data = json.loads(path.read_text())
    assert data["units"] == "mm" and data["format"] == "sprayplan.paths"
    assert data["summary"]["strokes"] == len(reach_paths.spray_strokes)
    back = read_paths_json(path)
    assert len(back.strokes) == len(reach_paths.strokes)
    for a, b in zip(back.strokes, reach_paths.strokes):
        np.testing.assert_allclose(a.tcp, b.tcp, atol=1e-4)
        assert a.spray_on == b.spray_on and (a.on_part == b.on_part).all()


def test_cli_paths_writes_the_file_and_summary(testdata, tmp_path, capsys):
    out = tmp_path / "paths.json"
    code = main(
        [
            "paths",
            str(testdata / "meshes" / "reach_curved_part.ply"),
            "--units",
            "m",
            "-o",
            str(out),
            "--direction",
            "0,1,0",
            "--spacing-mm",
            "60",
            "--standoff-mm",
            "150",
            "--edge-margin-mm",
            "20",
        ]
    )
    stdout = capsys.readouterr().out
    assert code == 0 and "strokes" in stdout and "spray" in stdout and "transfer" in stdout
    data = json.loads(out.read_text())
    assert data["settings"]["standoff_mm"] == 150.0 and data["settings"]["spacing_mm"] == 60.0
    stroke = data["strokes"][0]
    np.testing.assert_allclose(
        np.array(stroke["tcp"]), np.array(stroke["points"]) + 150 * np.array(stroke["normals"]), atol=1e-3
    )


def test_bad_path_options(testdata, tmp_path, capsys):
    part = str(testdata / "meshes" / "reach_curved_part.ply")
    for extra in (["--direction", "1,2"], ["--layers", "3", "--spacing-mm", "5"], ["--step-mm", "0"]):
        code = main(["paths", part, "--units", "m", "-o", str(tmp_path / "p.json"), *extra])
        err = capsys.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "p.json").exists()
    with pytest.raises(ConfigError):
        PathConfig(direction=(0, 0, 0))
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ConfigError, match="gun_smooth_mm"):
            PathConfig(gun_smooth_mm=bad)


def test_spacing_larger_than_a_tiny_part_still_gives_one_layer():
    from sprayplan.types import Part

    square = Part(
        np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]), None, "sq"
    )
    paths = plan_paths(square, PathConfig(spacing_mm=100.0))
    assert len(paths.spray_strokes) == 1
    with pytest.raises(InputError):
        plan_paths(Part(np.zeros((3, 3)), np.zeros((0, 3)), None, "empty"), PathConfig())


# ----------------------------------------------------------------------------------------- point clouds


def test_mesh_and_sampled_cloud_give_nearby_strokes(reach):
    from sprayplan.surface.filling import sample_even
    from sprayplan.types import Part

    # a 4 mm cloud (59k points; 3 mm, 104k points, took 2.4 times as long and was closer to the mesh's strokes)
    points, _ = sample_even(reach.triangles, 4.0, seed=0)
    cloud = Part(points, np.zeros((0, 3)), None, "cloud")
    config = PathConfig(spacing_mode="uniform", direction="x", spacing_mm=50.0, split_angle_deg=None, edge_passes=0)
    mesh_paths, cloud_paths = plan_paths(reach, config), plan_paths(cloud, config)
    assert len(cloud_paths.spray_strokes) == len(mesh_paths.spray_strokes)

    def distances(a, b):
        query = np.vstack([s.points[s.on_part] for s in a.spray_strokes])
        seg_a = np.vstack([s.points[:-1] for s in b.spray_strokes])
        seg_b = np.vstack([s.points[1:] for s in b.spray_strokes])
        return point_segment_distance(query, seg_a, seg_b, k=16)

    for d in (distances(cloud_paths, mesh_paths), distances(mesh_paths, cloud_paths)):
        # slab sections are smoothed over a few points: the part's 5 mm rolled rims are cut by a few mm
        assert np.median(d) < 1.5 and np.percentile(d, 90) < 3.0 and np.percentile(d, 99) < 10.0


@pytest.mark.parametrize(
    "name, normals, smooth",
    [
        ("pcl_milk.pcd", "triangles", None),
        ("pcl_milk.pcd", "plane", 5.0),
        ("reach_part_normals_ascii.pcd", "triangles", None),
    ],
)
def test_paths_on_real_clouds(testdata, name, normals, smooth):
    cloud = load_part(testdata / "pointclouds" / name, units="m")
    config = PathConfig(spacing_mm=20.0, standoff_mm=100.0, cloud_normals=normals, cloud_smooth_mm=smooth)
    paths = plan_paths(cloud, config)
    assert paths.spray_strokes
    tree = cKDTree(cloud.vertices)
    spacing = float(np.median(tree.query(cloud.vertices, k=2)[0][:, 1]))
    for stroke in paths.spray_strokes:
        np.testing.assert_allclose(stroke.tcp, stroke.points + 100.0 * stroke.normals, atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(stroke.normals, axis=1), 1.0, atol=1e-9)
        if not stroke.on_part.any():
            continue  # an edge pass, past the part's edge
        # contact points come from the cloud's slab sections: near the scanned points
        near = tree.query(stroke.points[stroke.on_part])[0]
        assert np.percentile(near, 95) <= 4 * spacing


def test_cli_ruled_surface_writes_paths_and_the_seed_table(tmp_path, capsys):
    from tests.conftest import REPO

    out, table = tmp_path / "ruled.json", tmp_path / "table.csv"
    code = main(
        [
            "paths",
            "--ruled",
            str(REPO / "examples" / "ruled" / "case1_table4.toml"),
            "-o",
            str(out),
            "--table",
            str(table),
        ]
    )
    assert code == 0 and "strokes" in capsys.readouterr().out
    rows = np.loadtxt(table, delimiter=",", skiprows=1)
    # seed 001, table 4, read with its columns in the order that the R5150 forward kinematics confirms
    expected = [
        [150, 100, 150],
        [150, 300, 150],
        [180, 290, 160],
        [180, 110, 160],
        [210, 120, 170],
        [210, 280, 170],
        [240, 270, 180],
        [240, 130, 180],
        [270, 140, 190],
        [270, 260, 190],
    ]
    np.testing.assert_allclose(rows[:, 1:], expected, atol=1e-9)
    assert len(read_paths_json(out).spray_strokes) == 5


def test_stroke_frames_and_rpy(reach_paths):
    from sprayplan.surface.poses import matrix_from_rpy, rpy_from_matrix, stroke_frames

    stroke = max(reach_paths.spray_strokes, key=lambda s: s.length_mm)
    frames = stroke_frames(stroke.points, stroke.normals)
    np.testing.assert_allclose(frames[:, :, 2], -stroke.normals, atol=1e-12)  # gun z along -normal
    np.testing.assert_allclose(np.linalg.det(frames), 1.0, atol=1e-12)
    travel = np.gradient(stroke.points, axis=0)
    assert (np.einsum("ij,ij->i", frames[:, :, 0], travel) > 0).all()  # x along the direction of travel
    np.testing.assert_allclose(matrix_from_rpy(rpy_from_matrix(frames)), frames, atol=1e-12)
    # eq. 9 by hand for one rotation: Rot(x, a) Rot(y, b) Rot(z, c)
    a, b, c = 0.3, -0.7, 1.1
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    np.testing.assert_allclose(rpy_from_matrix((rx @ ry @ rz)[None])[0], [a, b, c], atol=1e-12)


def test_closed_surfaces_have_no_edge_to_pass():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=300.0)
    part = Part(sphere.vertices, sphere.faces, None, "sphere")
    paths = plan_paths(part, PathConfig(spacing_mm=40.0, direction="z"))
    assert all(s.on_part.any() for s in paths.spray_strokes)
    # with no edge pass to take over, the march closes the far end with a last layer (here at the pole)
    from sprayplan.paths.frame import layer_offsets

    def samples(offset):  # a flat strip across the planes: sections are lines at y = offset
        return np.column_stack([np.linspace(0, 100, 11), np.full(11, offset), np.zeros(11)])

    def distance(query, offset):
        return float(np.median(np.abs(query[:, 1] - offset)))

    config = PathConfig(spacing_mm=30.0)
    open_ = layer_offsets(0.0, 220.0, config, samples, distance)
    closed = layer_offsets(0.0, 220.0, config, samples, distance, closed_part=True)
    np.testing.assert_allclose(open_, 15.0 + 30.0 * np.arange(7), atol=1e-6)
    np.testing.assert_allclose(closed, [*open_, 220.0], atol=1e-3)
    # the same sphere cut open at its equator: passes past the cut, none past the closed pole
    half = select_region(part, "z > 0")
    open_paths = plan_paths(half, PathConfig(spacing_mm=40.0, direction="z"))
    edge = [s for s in open_paths.spray_strokes if not s.on_part.any()]
    assert edge and all(s.points[:, 2].max() < 1.0 for s in edge)


def test_the_march_goes_on_past_a_gap_in_the_part():
    from sprayplan.paths.frame import GAP_PROBE, layer_offsets

    def samples(offset):  # a flat strip across the planes with no surface for 100 < y < 180
        if 100.0 < offset < 180.0:
            return np.zeros((0, 3))
        return np.column_stack([np.linspace(0, 100, 11), np.full(11, offset), np.zeros(11)])

    def distance(query, offset):
        if not len(samples(offset)):
            return np.inf
        return float(np.median(np.abs(query[:, 1] - offset)))

    offsets = np.array(layer_offsets(0.0, 400.0, PathConfig(spacing_mm=30.0), samples, distance))
    assert all(len(samples(o)) for o in offsets)
    np.testing.assert_allclose(offsets[:3], [15.0, 45.0, 75.0], atol=1e-6)
    after = offsets[offsets > 180.0]
    # half a spacing past the far edge (found to a twentieth of the spacing), then the spacing again
    assert 180.0 + 15.0 - GAP_PROBE * 30.0 - 1e-9 <= after[0] <= 180.0 + 15.0 + 1e-9
    np.testing.assert_allclose(np.diff(after), 30.0, atol=1e-3)
    assert after[-1] > 400.0 - 30.0
    # two plates in one plane with a gap between them: both are sliced the spacing apart, not edge-passed
    strips = [plate(0.0, 400.0, y0, y0 + 300.0, 20.0) for y0 in (0.0, 500.0)]
    part = Part(
        np.vstack([p.vertices for p in strips]),
        np.vstack([strips[0].faces, strips[1].faces + len(strips[0].vertices)]),
        None,
        "two strips",
    )
    paths = plan_paths(part, PathConfig(spacing_mm=30.0, direction="y"))
    ys = sorted({round(float(np.median(s.points[s.on_part, 1])), 3) for s in paths.spray_strokes if s.on_part.any()})
    far = np.array([y for y in ys if y > 400.0])
    assert len(far) >= 9 and far.min() < 500.0 + 30.0 and far.max() > 800.0 - 30.0
    np.testing.assert_allclose(np.diff(far), 30.0, rtol=0.02)


def test_boundaries_of_meshes_and_clouds():
    from sprayplan.paths.cloud_sections import cloud_boundary
    from sprayplan.paths.edges import mesh_boundary

    part = plate(0.0, 200.0, 0.0, 100.0, 10.0)
    ring = mesh_boundary(part.vertices, part.faces, 2.0)
    on_edge = np.minimum.reduce([ring[:, 0], 200.0 - ring[:, 0], ring[:, 1], 100.0 - ring[:, 1]])
    np.testing.assert_allclose(on_edge, 0.0, atol=1e-9)
    assert (
        np.max(cKDTree(ring).query(np.column_stack([np.linspace(0, 200, 101), np.zeros(101), np.zeros(101)]))[0]) <= 1.0
    )
    assert len(mesh_boundary(*_sphere(), 2.0)) == 0
    # a cloud sampled from the plate: its edge points are at the plate's edges, few inside
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(0, 200, 8000), rng.uniform(0, 100, 8000), np.zeros(8000)])
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    edge = cloud_boundary(points, normals, cKDTree(points))
    margin = np.minimum.reduce([points[:, 0], 200 - points[:, 0], points[:, 1], 100 - points[:, 1]])
    assert np.percentile(margin[edge], 95) < 4.0  # within about two point spacings (1.6 mm) of the edge
    assert edge[margin < 0.5].mean() > 0.8 and edge[margin > 5.0].mean() < 0.01


def _sphere():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=100.0)
    return np.asarray(sphere.vertices), np.asarray(sphere.faces)


def _tent(half_angle_deg: float = 20.0) -> Part:
    """Two flat faces meeting in a ridge along y at x = 0, each falling away at ``half_angle_deg``: the
    normals turn by twice that across the ridge."""
    part = plate(-300, 300, -150, 150, 5.0)
    vertices = part.vertices.copy()
    vertices[:, 2] = -np.tan(np.radians(half_angle_deg)) * np.abs(vertices[:, 0])
    return Part(vertices, part.faces, None, "tent")


def test_the_gun_turns_through_a_ridge_over_the_smoothing_width():
    """Across a 40 degree ridge the gun's axis turns at most 40 degrees x step / width per step (the slope of a
    step smoothed by a triangle of that half-width), not all at once; a width away from the ridge it is the
    face's normal; the contact points stay on the faces and the tcp on the smoothed axis."""
    tent = _tent(20.0)
    slope = np.radians(20.0)
    face = {1: np.array([np.sin(slope), 0.0, np.cos(slope)]), -1: np.array([-np.sin(slope), 0.0, np.cos(slope)])}
    for width in (0.0, 50.0, 100.0):
        config = PathConfig(direction="y", spacing_mm=60.0, gun_smooth_mm=width, edge_passes=0, edge_margin_mm=0.0)
        paths = plan_paths(tent, config)
        crossing = [s for s in paths.spray_strokes if s.points[:, 0].min() < -200 and s.points[:, 0].max() > 200]
        assert len(crossing) >= 4
        for s in crossing:
            assert np.allclose(s.points[:, 2], -np.tan(slope) * np.abs(s.points[:, 0]), atol=1e-6)
            assert np.allclose(s.tcp, s.points + config.standoff_mm * s.normals, atol=1e-9)
            assert np.allclose(np.linalg.norm(s.normals, axis=1), 1.0)
            turn = np.degrees(np.arccos(np.clip(np.sum(s.normals[1:] * s.normals[:-1], axis=1), -1, 1)))
            step = np.linalg.norm(np.diff(s.points, axis=0), axis=1)
            far = np.abs(s.points[:, 0]) > width + 2 * config.step_mm
            side = np.sign(s.points[far, 0]).astype(int)
            expected = np.array([face[k] for k in side])
            assert np.allclose(s.normals[far], expected, atol=1e-9)
            if width == 0.0:
                assert turn.max() > 19.9  # the bare normals jump at the ridge (half at its vertex, half after)
            else:
                # the triangle's slope is 1 / width: 40 degrees spread over the width, a little more where
                # the averaged unit vectors are made unit again
                assert (turn / step).max() <= 40.0 / width * 1.05
                assert turn.sum() == pytest.approx(40.0, abs=0.5)
