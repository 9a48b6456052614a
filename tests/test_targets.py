"""Target points (seed 000, section 2): filling, even sampling, normals, orientation, poses, overlap, compression."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.integrate import quad
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from sprayplan.config import TargetsConfig
from sprayplan.demo import car_roof
from sprayplan.errors import ConfigError
from sprayplan.io.load import load_part
from sprayplan.surface import compress, coverage, filling, poses
from sprayplan.surface import normals as nm
from sprayplan.surface.region import select_region
from sprayplan.surface.targets import make_targets
from sprayplan.types import Part
from tests.helpers import barycentric_inside, plate

SEED_TRIANGLE = np.array([[[10.0, 10.0, 0.0], [520.0, 100.0, 0.0], [260.0, 410.0, 0.0]]])  # seed 000, fig. 4


# ---------------------------------------------------------------- independent references used by the tests


def reference_dfs(tri, h_min, mode):
    """The seed's recursion written plainly: Heron's formula as printed, depth first."""
    out = []

    def visit(a, b, c):
        l1, l2, l3 = np.linalg.norm(b - a), np.linalg.norm(c - b), np.linalg.norm(a - c)
        e = (l1 + l2 + l3) / 2
        s = np.sqrt(max(e * (e - l1) * (e - l2) * (e - l3), 0.0))
        if s < max(l1, l2, l3) * h_min / 2:
            return
        o = (a + b + c) / 3
        out.append(o)
        if mode == "line":
            for v in (a, b, c):
                length = np.linalg.norm(v - o)
                k = 1
                while k * h_min < length - 1e-9:
                    out.append(o + k * h_min / length * (v - o))
                    k += 1
        visit(o, a, b)
        visit(o, b, c)
        visit(o, c, a)

    visit(*tri)
    return np.array(out)


def winding_number(points, triangles, chunk=8):
    """Generalised winding number (solid angles, Van Oosterom & Strackee): 1 inside a closed mesh, 0 outside."""
    out = []
    for start in range(0, len(points), chunk):
        p = points[start : start + chunk, None, None, :]
        v = triangles[None] - p
        a, b, c = v[:, :, 0], v[:, :, 1], v[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = np.einsum("pij,pij->pi", a, np.cross(b, c))
        dot = lambda x, y: np.einsum("pij,pij->pi", x, y)
        den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la
        out.append(2 * np.arctan2(det, den).sum(axis=1) / (4 * np.pi))
    return np.concatenate(out)


# ---------------------------------------------------------------- DFS filling (section 2.2)


@pytest.mark.parametrize("mode", ["point", "line"])
@pytest.mark.parametrize("h_min", [20.0, 7.5])
def test_dfs_matches_the_plain_recursion(mode, h_min):
    points, face = filling.fill_dfs(SEED_TRIANGLE, h_min, mode)
    expected = reference_dfs(SEED_TRIANGLE[0], h_min, mode)
    assert len(points) == len(expected)
    order = np.lexsort(points.T)
    np.testing.assert_allclose(points[order], expected[np.lexsort(expected.T)], atol=1e-9)
    assert (face == 0).all()


def test_dfs_points_lie_in_their_triangles(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    for mode in ("point", "line"):
        points, face = filling.fill_dfs(part.triangles, 5.0, mode)
        assert len(points) > len(part.faces)
        assert barycentric_inside(points, part.triangles[face]).all()


def test_line_filling_fills_more_than_point_filling():
    point, _ = filling.fill_dfs(SEED_TRIANGLE, 2.0, "point")
    line, _ = filling.fill_dfs(SEED_TRIANGLE, 2.0, "line")
    assert len(line) > 3 * len(point)


def test_dfs_refuses_a_spacing_that_would_explode():
    with pytest.raises(ConfigError, match="more than"):
        filling.fill_dfs(SEED_TRIANGLE * 1e4, 1e-3, "line")


# ---------------------------------------------------------------- even sampling


def test_poisson_disk_select_is_the_sequential_greedy_and_maximal():
    rng = np.random.default_rng(3)
    points = rng.random((4000, 3)) * np.array([100, 100, 5])
    keep = filling.poisson_disk_select(points, 4.0)
    greedy, blocked = [], np.zeros(len(points), bool)
    tree = cKDTree(points)
    for i in range(len(points)):
        if not blocked[i]:
            greedy.append(i)
            blocked[tree.query_ball_point(points[i], 4.0)] = True
    np.testing.assert_array_equal(keep, greedy)
    kept_tree = cKDTree(points[keep])
    assert kept_tree.query(points[keep], k=2)[0][:, 1].min() > 4.0
    assert kept_tree.query(points)[0].max() <= 4.0  # maximal: every candidate is covered


def test_even_sampling_on_a_real_part(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    points, face = filling.sample_even(part.triangles, 10.0, seed=5)
    assert barycentric_inside(points, part.triangles[face]).all()
    nn = cKDTree(points).query(points, k=2)[0][:, 1]
    assert nn.min() > 10.0
    # density of a random close packing of disks: between 0.4 and 0.7 points per spacing^2
    assert 0.4 < len(points) * 100.0 / part.area < 0.7
    again, _ = filling.sample_even(part.triangles, 10.0, seed=5)
    np.testing.assert_array_equal(points, again)
    other, _ = filling.sample_even(part.triangles, 10.0, seed=6)
    assert not np.array_equal(points[: len(other)], other[: len(points)])


# ---------------------------------------------------------------- normals and orientation (section 2.3)


# closed, non-convex solids: the tray (a 3.175 mm plate with 23 through holes) and featuretype (pockets and
# bosses); both files are wound outward, as trimesh's positive volume for them says
CLOSED_SOLIDS = [("tray_bottom_mm_ascii.stl", "mm"), ("featuretype_binary.stl", "in")]


@pytest.mark.parametrize("name, units", CLOSED_SOLIDS)
def test_scrambled_winding_is_restored_on_a_closed_solid(testdata, name, units):
    solid = load_part(testdata / "meshes" / name, units=units)
    assert trimesh.Trimesh(solid.vertices, solid.faces, process=False).volume > 0
    rng = np.random.default_rng(0)
    flip = rng.random(len(solid.faces)) < 0.3
    scrambled = np.where(flip[:, None], solid.faces[:, ::-1], solid.faces)
    faces, normals = nm.outward_face_normals(solid.vertices, scrambled)
    np.testing.assert_array_equal(normals, nm.face_normals(solid.vertices, solid.faces))
    assert trimesh.Trimesh(solid.vertices, faces, process=False).volume > 0


def test_scrambled_open_sheet_faces_up():
    roof = select_region(car_roof(resolution_mm=100.0), "z > 1000")
    flip = np.random.default_rng(1).random(len(roof.faces)) < 0.5
    _faces, normals = nm.outward_face_normals(roof.vertices, np.where(flip[:, None], roof.faces[:, ::-1], roof.faces))
    assert (normals[:, 2] > 0).all()


def test_every_closed_solid_target_normal_is_its_outward_face_normal(testdata):
    # a closed manifold whose faces are consistently wound (every edge traversed once each way) and whose
    # signed volume is positive has every face normal pointing out: check both for all faces, then that
    # every target takes its face's normal (the tray: a closed manifold of genus 23 as loaded)
    tray = load_part(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    faces, face_n = nm.outward_face_normals(tray.vertices, tray.faces)
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    forward = {tuple(e) for e in directed.tolist()}
    assert len(forward) == len(directed)
    assert all((b, a) in forward for a, b in forward)
    assert trimesh.Trimesh(tray.vertices, faces, process=False).volume > 0
    targets = make_targets(tray, TargetsConfig(spacing_mm=5.0))
    assert len(targets) > 3000
    np.testing.assert_array_equal(targets.normals, face_n[targets.face_index])


@pytest.mark.parametrize("name, units", CLOSED_SOLIDS)
def test_closed_solid_targets_point_out_of_the_solid(testdata, name, units):
    solid = load_part(testdata / "meshes" / name, units=units)
    targets = make_targets(solid, TargetsConfig(spacing_mm=5.0))
    pick = np.random.default_rng(2).choice(len(targets), 160, replace=False)
    p, n = targets.points[pick], targets.normals[pick]
    # 0.5 mm: well inside the tray's 3.175 mm plate; an offset through a wall would fail the test, not pass it
    eps = 0.5
    outside = winding_number(p + eps * n, solid.triangles)
    inside = winding_number(p - eps * n, solid.triangles)
    np.testing.assert_allclose(outside, 0.0, atol=1e-6)
    np.testing.assert_allclose(inside, 1.0, atol=1e-6)


def test_normals_are_unit_and_match_faces_on_smooth_regions(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    even = make_targets(part, TargetsConfig(spacing_mm=5.0, compress="none"))
    np.testing.assert_allclose(np.linalg.norm(even.normals, axis=1), 1.0, atol=1e-12)
    _faces, face_n = nm.outward_face_normals(part.vertices, part.faces)
    np.testing.assert_allclose(even.normals, face_n[even.face_index])
    # PCA normals: where every neighbour within r lies on faces within 3 deg of each other, the fitted plane
    # is a weighted mean of nearly parallel planes, so its normal must lie within 3 deg of the face normal
    radius = 15.0
    pca = make_targets(part, TargetsConfig(spacing_mm=5.0, compress="none", normals="pca", normal_radius_mm=radius))
    np.testing.assert_array_equal(pca.points, even.points)
    tree = cKDTree(even.points)
    own = face_n[even.face_index]
    smooth = np.array(
        [
            np.min(own[nb] @ own[i]) > np.cos(np.radians(3.0))
            for i, nb in enumerate(tree.query_ball_point(even.points, radius))
        ]
    )
    assert smooth.mean() > 0.5
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", pca.normals, own), -1, 1)))
    assert angle[smooth].max() < 3.0


def test_dfs_vertex_normals_follow_the_mesh(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    targets = make_targets(part, TargetsConfig(fill="point", spacing_mm=10.0, compress="none"))
    is_vertex = targets.face_index == -1
    assert is_vertex.sum() == len(part.vertices)
    faces, face_n = nm.outward_face_normals(part.vertices, part.faces)
    reference = nm.vertex_normals(part.vertices, faces, face_n)
    assert (np.einsum("ij,ij->i", targets.normals[is_vertex], reference) > 0).all()
    np.testing.assert_allclose(np.linalg.norm(targets.normals, axis=1), 1.0, atol=1e-9)


def torus_points(n, major=300.0, minor=100.0, seed=0):
    rng = np.random.default_rng(seed)
    u, v = rng.random(n) * 2 * np.pi, rng.random(n) * 2 * np.pi
    centre = np.stack([major * np.cos(u), major * np.sin(u), np.zeros(n)], 1)
    normal = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], 1)
    return centre + minor * normal, normal


def test_centroid_rule_fails_on_a_torus_where_the_robust_methods_do_not():
    points, true_normal = torus_points(6000)
    pca = nm.pca_normals(points, 40.0, center="mean")
    by_centroid = nm.orient_centroid(points, pca)
    by_propagation = nm.orient_propagate(points, pca)
    inner = np.einsum("ij,ij->i", points, true_normal) < 0  # the inner ring faces the centroid
    assert (np.einsum("ij,ij->i", by_centroid[inner], true_normal[inner]) < 0).mean() > 0.9
    assert (np.einsum("ij,ij->i", by_propagation, true_normal) > 0).all()
    # and on a torus mesh, the mesh method keeps every face outward
    mesh = trimesh.creation.torus(major_radius=300.0, minor_radius=100.0)
    targets = make_targets(Part(mesh.vertices, mesh.faces, None, "torus"), TargetsConfig(spacing_mm=20.0))
    ring = np.hypot(targets.points[:, 0], targets.points[:, 1])
    radial = np.stack([targets.points[:, 0] / ring, targets.points[:, 1] / ring, np.zeros(len(ring))], 1)
    tube_centre = 300.0 * radial
    assert (np.einsum("ij,ij->i", targets.normals, targets.points - tube_centre) > 0).all()


def test_point_cloud_normals_agree_with_the_files_normals(testdata):
    cloud = load_part(testdata / "pointclouds" / "reach_part_normals_ascii.pcd", units="m")
    ours = make_targets(cloud, TargetsConfig(spacing_mm=50.0, compress="none", orient="propagate"))
    dots = np.einsum("ij,ij->i", ours.normals, cloud.vertex_normals)
    well_defined = np.abs(dots) > 0.5  # 262 sparse points: a few lie on the rim where no plane fits
    assert well_defined.mean() > 0.9
    assert (dots[well_defined] > 0).all()


@pytest.mark.parametrize("name", ["pcl_car6.pcd", "pcl_milk.pcd", "pcl_car6.derived.xyz"])
def test_targets_from_real_clouds(testdata, name):
    cloud = load_part(testdata / "pointclouds" / name, units="m")
    targets = make_targets(cloud, TargetsConfig(spacing_mm=20.0))
    np.testing.assert_allclose(np.linalg.norm(targets.normals, axis=1), 1.0, atol=1e-9)
    # compressed targets are real cloud points, at most one per eq. 7 cell
    assert cKDTree(cloud.vertices).query(targets.points)[0].max() == 0.0
    cells = np.round(targets.points / compress.grid_step(20.0))
    assert len(np.unique(cells, axis=0)) == len(targets)


# ---------------------------------------------------------------- poses (section 2.4)


def test_rodrigues_turns_z_onto_the_axis():
    rng = np.random.default_rng(4)
    axes = nm.unit(rng.normal(size=(500, 3)))
    axes = np.vstack([axes, [[0, 0, 1], [0, 0, -1], [1e-14, 0, -1]]])
    rot = poses.rotation_from_z(axes)
    np.testing.assert_allclose(rot @ np.array([0, 0, 1.0]), nm.unit(axes), atol=1e-12)
    np.testing.assert_allclose(rot @ rot.transpose(0, 2, 1), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-12)
    # the same rotation as scipy's, built from the axis-angle of z x a
    angle = np.arccos(np.clip(axes[:500, 2], -1, 1))
    axis = nm.unit(np.cross([0, 0, 1.0], axes[:500]))
    np.testing.assert_allclose(rot[:500], Rotation.from_rotvec(axis * angle[:, None]).as_matrix(), atol=1e-12)


def test_tool_pose_puts_the_gun_at_the_standoff_looking_at_the_point():
    points = np.array([[0.0, 0, 0], [100, 50, 20]])
    normals = nm.unit(np.array([[0.0, 0, 1], [1, 1, 0]]))
    tool2part = poses.tool_poses(points, normals, 113.0)
    np.testing.assert_allclose(tool2part[:, :3, 3], points + 113.0 * normals)
    np.testing.assert_allclose(tool2part[:, :3, 2], -normals, atol=1e-12)
    # the gun's z axis reaches the surface point after the standoff
    np.testing.assert_allclose(tool2part[:, :3, 3] + 113.0 * tool2part[:, :3, 2], points, atol=1e-9)


# ---------------------------------------------------------------- overlap (section 2.5, eq. 6)


def lens_by_quadrature(d, r):
    def chord(x):
        return 2 * max(0.0, min(np.sqrt(max(r * r - x * x, 0)), np.sqrt(max(r * r - (x - d) ** 2, 0))))

    return quad(chord, d - r, r, limit=200)[0] if d < 2 * r else 0.0


@pytest.mark.parametrize("d", [0.0, 5.0, 30.0, 49.186, 70.0, 99.0, 100.0, 150.0])
def test_overlap_ratio_is_lens_area_over_one_circle(d):
    r = 50.0
    expected = lens_by_quadrature(d, r) / (np.pi * r * r)
    assert coverage.overlap_ratio(d, r) == pytest.approx(expected, abs=1e-7)


def test_spacing_for_overlap_inverts_eq6():
    for p in (0.0, 0.1, 0.4, 0.75, 0.99):
        d = coverage.spacing_for_overlap(p, 50.0)
        assert coverage.overlap_ratio(d, 50.0) == pytest.approx(p, abs=1e-12)
    # the seed's setting: r = 50 mm, overlap 0.4
    assert coverage.spacing_for_overlap(0.4, 50.0) == pytest.approx(49.186, abs=1e-3)
    with pytest.raises(ConfigError):
        coverage.spacing_for_overlap(1.0, 50.0)


# ---------------------------------------------------------------- compression (eq. 7)


def test_grid_compression_is_eq7():
    rng = np.random.default_rng(7)
    points = rng.random((5000, 3)) * 300
    normals = nm.unit(rng.normal(size=(5000, 3)))
    out, out_n = compress.compress_grid(points, normals, 49.19)
    k = np.floor(49.19 / np.sqrt(3))
    assert k == 28
    np.testing.assert_array_equal(out, np.unique(np.round(points / k) * k, axis=0))
    np.testing.assert_allclose(np.linalg.norm(out_n, axis=1), 1.0)
    # every original point is within half a cell diagonal of its node
    assert cKDTree(out).query(points)[0].max() <= k * np.sqrt(3) / 2 + 1e-9


def test_surface_compression_keeps_one_real_point_per_cell(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    dense = make_targets(part, TargetsConfig(fill="line", spacing_mm=30.0, compress="none"))
    kept = make_targets(part, TargetsConfig(fill="line", spacing_mm=30.0, compress="surface"))
    grid = make_targets(part, TargetsConfig(fill="line", spacing_mm=30.0, compress="grid"))
    assert len(kept) == len(grid) < len(dense)
    # kept points are real targets: on the surface with their own normals
    dist, idx = cKDTree(dense.points).query(kept.points)
    assert dist.max() == 0.0
    np.testing.assert_array_equal(kept.normals, dense.normals[idx])
    # grid nodes are off the surface; the surface variant is not
    assert cKDTree(dense.points).query(grid.points)[0].max() > 1.0


def test_seeded_targets_repeat(testdata):
    part = load_part(testdata / "meshes" / "noether_raw_scan_mesh.ply", units="m")
    a = make_targets(part, TargetsConfig(spacing_mm=10.0, seed=11))
    b = make_targets(part, TargetsConfig(spacing_mm=10.0, seed=11))
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.normals, b.normals)


def _box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """A closed box, wound outward: (vertices, faces)."""
    box = trimesh.creation.box(bounds=np.array([lo, hi], float))
    return np.asarray(box.vertices, float), np.asarray(box.faces, np.int64)


def _assembly():
    """A closed box (1000 x 600 x 400 mm about the origin) and, beside its +y side, a flat panel in the plane
    y = 320 and a trough (a 60 degree arc of a cylinder of radius 300 mm, its hollow facing +y, away from the
    box), both wound towards the box: (vertices, faces, panel faces, trough faces)."""
    v_box, f_box = _box([-500, -300, -200], [500, 300, 200])
    sheet = plate(-400, 400, -150, 150, 25.0)
    v_panel = np.column_stack([sheet.vertices[:, 0], np.full(len(sheet.vertices), 320.0), sheet.vertices[:, 1]])
    arc = plate(-400, 400, -np.pi / 6, np.pi / 6, np.pi / 60)
    v_arc = arc.vertices.copy()
    theta = arc.vertices[:, 1]
    v_arc[:, 1] = 620.0 - 300.0 * np.cos(theta)
    v_arc[:, 2] = 300.0 * np.sin(theta) + 600.0  # above the panel
    pieces, faces, start = [v_box], [f_box], len(v_box)
    for v, f in ((v_panel, sheet.faces), (v_arc, arc.faces)):
        f = f.copy()
        if nm.face_normals(v, f)[:, 1].mean() > 0:
            f = f[:, ::-1]
        assert nm.face_normals(v, f)[:, 1].max() < 0  # wound towards -y, the box
        pieces.append(v)
        faces.append(f + start)
        start += len(v)
    n_box, n_panel = len(f_box), len(sheet.faces)
    panel = np.arange(n_box, n_box + n_panel)
    trough = np.arange(n_box + n_panel, n_box + n_panel + len(arc.faces))
    return np.vstack(pieces), np.vstack(faces), panel, trough


def test_the_pieces_of_an_assembly_face_away_from_the_whole():
    """Beside a closed box, a trough (about its own centroid the vote is clear and wrong: its hollow faces
    away from the box, so its outward normals point at its own centroid) is turned to face away from the box
    by the vote about the whole part's centroid; a flat panel (its own vote balanced) keeps its file's
    winding, towards the box, as a flat sheet always does. Alone, each keeps its own vote."""
    vertices, faces, panel, trough = _assembly()
    _, normals = nm.outward_face_normals(vertices, faces)
    assert (normals[panel, 1] < -0.99).all()
    assert (normals[trough, 1] > 0.8).all()  # the arc's normals lean up to 30 degrees off +y
    n_box = panel[0]
    np.testing.assert_array_equal(normals[:n_box], nm.face_normals(vertices, faces[:n_box]))  # the box as it was
    for piece in (panel, trough):
        _, alone = nm.outward_face_normals(vertices, faces[piece])
        assert (alone[:, 1] < -0.8).all()  # alone: the file's winding (panel), its own centroid's vote (trough)


def test_a_piece_cut_from_an_oriented_part_keeps_its_faces():
    """An oriented part's pieces are not oriented again: the trough cut from the oriented assembly keeps the
    assembly's outward side, where a vote over the trough alone turns it towards the box."""
    from sprayplan.surface.region import select_region

    vertices, faces, _, trough = _assembly()
    whole = nm.oriented_part(Part(vertices, faces, None, "assembly"))
    assert whole.oriented
    cut = select_region(whole, "z > 400")
    assert cut.oriented and len(cut.faces) == len(trough)
    faces_out, normals = nm.part_outward(cut)
    np.testing.assert_array_equal(faces_out, cut.faces)
    assert (normals[:, 1] > 0.8).all()
    _, voted = nm.outward_face_normals(cut.vertices, cut.faces)
    assert (voted[:, 1] < -0.8).all()  # without the flag: turned towards the box


def test_the_car_bodies_pieces_face_where_rays_escape(testdata):
    """On both car bodies, every open piece of at least 0.05 m^2 faces the side its rays escape from: rays
    cast from 100 of its faces along the outward normal hit the body no more often than rays cast the other
    way (by more than a fifth). The BMW's two sill strips, which voted inward about their own centroids
    (escape 24 % in front, 98 % behind), are the pieces this guards."""
    for name, kw in (("bmw_m6_body_m_yup.ply", {"units": "m", "up": "y"}), ("gazebo_suv_body_m.ply", {"units": "m"})):
        body = load_part(testdata / "meshes" / name, **kw)
        faces, normals = nm.outward_face_normals(body.vertices, body.faces)
        _, component = nm.consistent_winding(faces)
        mesh = trimesh.Trimesh(body.vertices, faces, process=False)
        centres = body.vertices[faces].mean(axis=1)
        area = mesh.area_faces
        rng = np.random.default_rng(0)
        checked = 0
        for c in np.flatnonzero(np.bincount(component, area) >= 0.05e6):
            idx = np.flatnonzero(component == c)
            pick = rng.choice(idx, min(100, len(idx)), replace=False)
            escape = []
            for side in (1.0, -1.0):
                d = side * normals[pick]
                escape.append(1.0 - mesh.ray.intersects_any(centres[pick] + 0.5 * d, d).mean())
            assert escape[0] >= escape[1] - 0.2, (name, int(c), escape)
            checked += 1
        assert checked >= 3
