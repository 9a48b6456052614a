"""Region selection: parsing, exact clipping, nothing outside, area conservation."""

from __future__ import annotations

import numpy as np
import pytest

from sprayplan.demo import car_roof
from sprayplan.errors import RegionError
from sprayplan.io.load import load_part
from sprayplan.surface.region import clip_halfspace, parse_region, select_region
from sprayplan.types import Part


def grid_square(n=10, size=10.0):
    xs = np.linspace(0, size, n + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    faces = np.concatenate([np.stack([a, a + n + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + 1], 1)])
    return Part(vertices, faces, None, "square")


@pytest.mark.parametrize(
    "text, axes, signs, values",
    [
        ("z > 1000", [2], [-1], [1000]),
        ("x<=5 AND y >= -2.5e1", [0, 1], [1, -1], [5, -25]),
        ("-500 < x < 500", [0, 0], [-1, 1], [-500, 500]),
        ("1000 < z", [2], [-1], [1000]),
        ("box(0, 1, 2, 10, 11, 12)", [0, 0, 1, 1, 2, 2], [-1, 1, -1, 1, -1, 1], [0, 10, 1, 11, 2, 12]),
    ],
)
def test_parse_region(text, axes, signs, values):
    region = parse_region(text)
    np.testing.assert_array_equal(region.axis, axes)
    np.testing.assert_array_equal(region.sign, signs)
    np.testing.assert_array_equal(region.value, values)


@pytest.mark.parametrize(
    "text", ["", "z >", "w > 3", "z > 1 and", "1 < 2", "x < y", "box(1,2,3)", "box(5,0,0,1,1,1)", "z > inf"]
)
def test_bad_region_expressions_raise(text):
    with pytest.raises(RegionError):
        parse_region(text)


def test_clip_is_exact_on_a_square():
    square = grid_square()
    part = select_region(square, "x < 3.3 and y > 1.25")
    assert part.area == pytest.approx(3.3 * 8.75, rel=1e-12)
    assert part.vertices[:, 0].max() == 3.3 and part.vertices[:, 1].min() == 1.25


def test_shared_cut_edges_get_one_vertex():
    square = grid_square()
    vertices, faces = clip_halfspace(square.vertices, square.faces, 0, 1.0, 3.3)
    used = np.unique(faces)
    # the cut at x = 3.3 crosses 10 rows of cells: 11 vertical grid lines... one vertex per crossed edge
    cut = vertices[used][np.isclose(vertices[used, 0], 3.3)]
    assert len(cut) == len(np.unique(cut, axis=0))
    assert len(cut) == 10 + 1 + 10  # 11 horizontal edges and 10 diagonals are crossed


def test_winding_is_kept_when_clipping():
    roof = car_roof(resolution_mm=100.0)
    part = select_region(roof, "z > 1000")
    tri = part.triangles
    normal_z = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2]
    assert (normal_z > 0).all()


def test_area_inside_plus_outside_equals_total(testdata):
    # the whole BMW body (69,930 triangles, z from -563 to 680 mm once turned z up): the plane cuts doors,
    # pillars, mirrors and wheel arches
    car = load_part(testdata / "meshes" / "bmw_m6_body_m_yup.ply", units="m", up="y")
    inside = select_region(car, "z > 100")
    outside = select_region(car, "z < 100")
    assert len(inside.faces) > 10_000 and len(outside.faces) > 10_000
    assert inside.area + outside.area == pytest.approx(car.area, rel=1e-9)
    assert inside.vertices[:, 2].min() == 100.0
    assert outside.vertices[:, 2].max() == 100.0


def test_box_region_on_real_part(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    box = select_region(part, "box(-900, -400, -100, -300, 400, 1000)")
    assert parse_region("box(-900, -400, -100, -300, 400, 1000)").contains(box.vertices).all()
    assert 0 < box.area < part.area


def test_point_cloud_region_filters_points():
    rng = np.random.default_rng(1)
    points = rng.random((1000, 3)) * 100
    cloud = Part(points, np.zeros((0, 3)), None, "cloud")
    kept = select_region(cloud, "x > 50 and z <= 20")
    expected = points[(points[:, 0] > 50) & (points[:, 2] <= 20)]
    np.testing.assert_array_equal(kept.vertices, expected)


def test_empty_region_names_the_part_and_its_extent():
    with pytest.raises(RegionError, match=r"square: region 'z > 5' contains no part .* z 0\.\.0 mm"):
        select_region(grid_square(), "z > 5")
    # touching the part along a line only is empty too
    with pytest.raises(RegionError):
        select_region(grid_square(), "x >= 10")


def _sheet(x0, x1, y0, y1, z, step=10.0, tilt_deg=0.0) -> tuple[np.ndarray, np.ndarray]:
    """A flat grid sheet at height z facing +z (tilted about the x axis by ``tilt_deg``): (vertices, faces)."""
    from tests.helpers import plate

    sheet = plate(x0, x1, y0, y1, step)
    v = sheet.vertices.copy()
    a = np.radians(tilt_deg)
    yc = (y0 + y1) / 2.0
    v[:, 1], v[:, 2] = yc + (v[:, 1] - yc) * np.cos(a), z + (v[:, 1] - yc) * np.sin(a)
    return v, sheet.faces


def _stack(*sheets) -> Part:
    """The sheets as one part, wound as built (``oriented``: two parallel sheets alone have no outside of
    their own, and the vote about their centroid would turn them apart)."""
    vertices, faces, start = [], [], 0
    for v, f in sheets:
        vertices.append(v)
        faces.append(f + start)
        start += len(v)
    return Part(np.vstack(vertices), np.vstack(faces), None, "sheets", oriented=True)


def test_covered_faces_are_those_under_a_near_parallel_face_within_the_distance():
    """A bumper (a 400 x 200 mm sheet) with a licence plate (100 x 50 mm) 8 mm in front of it: the bumper's
    faces whose centres lie under the plate are covered, no other; the plate's own faces are not. The same
    plate 25 mm out (beyond 20 mm), or turned by 60 degrees (|cos| 0.5 < 0.8), covers nothing."""
    from sprayplan.surface.region import covered_faces

    bumper = _sheet(-200, 200, -100, 100, 0.0)
    centres = bumper[0][bumper[1]].mean(axis=1)
    under = (np.abs(centres[:, 0]) < 50) & (np.abs(centres[:, 1]) < 25)
    plate_at = _sheet(-50, 50, -25, 25, 8.0, step=5.0)
    covered = covered_faces(_stack(bumper, plate_at), 20.0)
    n = len(bumper[1])
    np.testing.assert_array_equal(covered[:n], under)
    assert under.sum() == 100 and not covered[n:].any()
    assert not covered_faces(_stack(bumper, _sheet(-50, 50, -25, 25, 25.0, step=5.0)), 20.0).any()
    assert not covered_faces(_stack(bumper, _sheet(-50, 50, -25, 25, 8.0, step=5.0, tilt_deg=60.0)), 20.0).any()
    assert covered_faces(_stack(bumper, _sheet(-50, 50, -25, 25, 25.0, step=5.0)), 30.0)[:n].sum() == 100


def test_the_bodys_covered_faces_agree_with_trimeshs_rays(testdata):
    """On the BMW body: 300 covered faces and 300 others, each tested with trimesh's own rays (every hit along
    the normal): a covered face has a near-parallel face within 20 mm in front of it, the others none. The
    licence plate and the door handles cover more than 0.1 m^2 of it."""
    import trimesh

    from sprayplan.surface import normals as nm
    from sprayplan.surface.region import COVERED_MIN_COS, covered_faces

    body = nm.oriented_part(load_part(testdata / "meshes" / "bmw_m6_body_m_yup.ply", units="m", up="y"))
    covered = covered_faces(body, 20.0)
    assert body.face_areas[covered].sum() > 0.1e6
    normals = nm.face_normals(body.vertices, body.faces)
    mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
    centres = body.triangles.mean(axis=1)
    rng = np.random.default_rng(3)
    for expected in (True, False):
        pick = rng.choice(np.flatnonzero(covered == expected), 300, replace=False)
        origins = centres[pick] + 0.5 * normals[pick]
        where, ray, hit = mesh.ray.intersects_location(origins, normals[pick], multiple_hits=True)
        distance = np.einsum("ij,ij->i", where - origins[ray], normals[pick][ray])
        near = (distance >= 0) & (distance <= 19.5) & (hit != pick[ray])
        near &= np.abs(np.einsum("ij,ij->i", normals[hit], normals[pick][ray])) >= COVERED_MIN_COS
        found = np.zeros(len(pick), bool)
        found[ray[near]] = True
        assert found.all() if expected else not found.any()


def test_faces_in_front_finds_any_face_ahead_within_the_distance_of_the_part_or_an_obstacle():
    """A floor (400 x 200 mm, facing up) under a lid 100 mm above it, turned 60 degrees (no cover by
    :func:`covered_faces`' rule, |cos| 0.5): the floor's faces whose upward ray meets the lid are in front of
    it within 150 mm and not within 90 mm; the lid's are not. Given the floor alone and the lid as an obstacle,
    the same floor faces are found; without the obstacle none."""
    from sprayplan.surface.region import COVERED_MIN_COS, faces_in_front

    floor = _sheet(-200, 200, -100, 100, 0.0)
    lid = _sheet(-50, 50, -25, 25, 100.0, step=5.0, tilt_deg=60.0)
    both = _stack(floor, lid)
    n = len(floor[1])
    centres = floor[0][floor[1]].mean(axis=1)
    # the lid spans x in [-50, 50] and, turned about the x axis through y = 0, y in [-12.5, 12.5] seen from
    # below, rising from z 100 - 21.65 to 100 + 21.65 mm
    under = (np.abs(centres[:, 0]) < 50) & (np.abs(centres[:, 1]) < 12.5)
    ahead = faces_in_front(both, 150.0)
    np.testing.assert_array_equal(ahead[:n], under)
    assert under.sum() > 0 and not ahead[n:].any()
    assert not faces_in_front(both, 70.0).any()  # the lid's lowest edge is 78 mm up
    assert not faces_in_front(both, 150.0, min_cos=COVERED_MIN_COS).any()
    alone = _stack(floor)
    np.testing.assert_array_equal(faces_in_front(alone, 150.0, obstacle=both), under)
    assert not faces_in_front(alone, 150.0).any()


def test_the_bodys_faces_in_front_agree_with_trimeshs_rays(testdata):
    """On the SUV body, every face tested with trimesh's own rays (every hit along the normal): a face has
    some face within 143 mm in front of it (the standoff and the clearance) exactly when
    :func:`faces_in_front` says so."""
    import trimesh

    from sprayplan.surface import normals as nm
    from sprayplan.surface.region import faces_in_front

    body = nm.oriented_part(load_part(testdata / "meshes" / "gazebo_suv_body_m.ply", units="m"))
    ahead = faces_in_front(body, 143.0)
    assert 0 < ahead.sum() < len(ahead)
    normals = nm.face_normals(body.vertices, body.faces)
    mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
    origins = body.triangles.mean(axis=1) + 0.5 * normals
    where, ray, hit = mesh.ray.intersects_location(origins, normals, multiple_hits=True)
    distance = np.einsum("ij,ij->i", where - origins[ray], normals[ray])
    near = (distance >= 0) & (distance <= 142.5) & (hit != ray)
    found = np.zeros(len(normals), bool)
    found[ray[near]] = True
    # a hit within a micrometre of the ray's end or of an edge may go either way
    edge = (distance >= 142.4) & (distance <= 142.6)
    unsure = np.zeros(len(normals), bool)
    unsure[ray[edge]] = True
    np.testing.assert_array_equal(ahead[~unsure], found[~unsure])


def test_the_painted_surface_leaves_out_what_faces_the_floor_and_what_is_covered():
    from sprayplan.config import CollisionConfig
    from sprayplan.surface.region import painted_surface

    bumper = _sheet(-200, 200, -100, 100, 0.0)
    part = _stack(bumper, _sheet(-50, 50, -25, 25, 8.0, step=5.0))
    painted, left = painted_surface(part, CollisionConfig())
    assert left == {"covered_left_out_mm2": pytest.approx(100 * 50.0)}  # 100 faces of 50 mm^2 under the plate
    assert len(painted.faces) == len(part.faces) - 100
    same, nothing = painted_surface(part, CollisionConfig(skip_covered=False))
    assert same is part and nothing == {}
    with pytest.raises(RegionError, match="covered"):
        top, faces = _sheet(0, 10, 0, 10, 5.0)
        painted_surface(_stack(_sheet(0, 10, 0, 10, 0.0), (top, faces[:, ::-1])), CollisionConfig())  # face to face


# --- masks ([load] mask, plan --mask): surface left unpainted, cut out exactly ---------------------------------


def _boundary_edges(faces):
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    return unique[count == 1]


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


@pytest.mark.parametrize(
    "masks, hole_area",
    [
        (["box(2.5, 3.3, -1, 6.1, 7.7, 1)"], 3.6 * 4.4),  # a window inside the square
        (["x > 7.25"], 2.75 * 10.0),  # a strip at its edge
        (["box(2.5, 3.3, -1, 6.1, 7.7, 1)", "3 < x < 5 and y < 5"], 3.6 * 4.4 + 2.0 * 5.0 - 2.0 * 1.7),  # overlapping
    ],
)
def test_a_mask_cuts_out_exactly_its_area_and_the_rest_stays_one_welded_mesh(masks, hole_area):
    from sprayplan.surface.region import mask_out, parse_masks

    square = grid_square(n=10, size=10.0)
    kept, left_out = mask_out(square, masks)
    assert left_out == pytest.approx(hole_area, rel=1e-9)
    assert kept.area == pytest.approx(100.0 - hole_area, rel=1e-9)
    regions = parse_masks(masks)
    centres = kept.triangles.mean(axis=1)
    for region in regions:
        assert not region.contains(centres, tol_mm=-1e-9).any()  # no face's centre strictly inside a mask
    # welded: every edge that bounds the kept surface lies on the square's rim or on a mask's plane, none on
    # a seam between the pieces the outside of a mask is cut into
    rim_or_plane = np.isclose(kept.vertices[:, :2], 0.0, atol=1e-12) | np.isclose(kept.vertices[:, :2], 10.0)
    on_plane = np.zeros(len(kept.vertices), bool)
    for region in regions:
        for axis, value in zip(region.axis, region.value):
            on_plane |= np.isclose(kept.vertices[:, axis], value, atol=1e-9)
    ends = _boundary_edges(kept.faces)
    assert (rim_or_plane.any(axis=1) | on_plane)[ends].all()
    assert len(np.unique(kept.faces, axis=0)) == len(kept.faces)


def test_a_mask_in_the_part_frame_cuts_a_placed_part_where_it_cuts_the_part():
    from sprayplan.surface.region import mask_out

    square = grid_square(n=8, size=10.0)
    rot = _rotation([0.3, -0.5, 1.0], 0.9)
    part2frame = np.eye(4)
    part2frame[:3, :3], part2frame[:3, 3] = rot, [120.0, -40.0, 7.0]
    placed = Part(square.vertices @ rot.T + part2frame[:3, 3], square.faces, None, "placed")
    masks = ["box(1.6, 2.7, -1, 4.4, 8.9, 1)"]  # no vertex on its planes: the turned frame rounds those
    here, left_here = mask_out(square, masks)
    there, left_there = mask_out(placed, masks, part2frame)
    assert left_there == pytest.approx(left_here, rel=1e-9) and len(there.faces) == len(here.faces)
    back = (there.vertices - part2frame[:3, 3]) @ rot  # the placed result taken back to the part frame
    assert np.sort(back[there.faces].mean(axis=1), axis=0) == pytest.approx(
        np.sort(here.vertices[here.faces].mean(axis=1), axis=0), abs=1e-9
    )


def test_a_mask_keeps_the_winding_of_the_faces_it_cuts():
    from sprayplan.surface.normals import outward_face_normals
    from sprayplan.surface.region import mask_out

    part = car_roof()
    lo, hi = part.bounds
    mid = (lo + hi) / 2
    box = f"box({mid[0] - 200}, {mid[1] - 100}, {lo[2] - 1}, {mid[0] + 200}, {mid[1] + 100}, {hi[2] + 1})"
    kept, left_out = mask_out(part, [box])
    assert left_out > 0 and kept.area == pytest.approx(part.area - left_out, rel=1e-9)
    from scipy.spatial import cKDTree

    faces, normals = outward_face_normals(part.vertices, part.faces)
    part = Part(part.vertices, faces, None, part.name)
    kept, _ = mask_out(part, [box])
    tri = kept.triangles
    cut_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    _, near = cKDTree(part.triangles.mean(axis=1)).query(tri.mean(axis=1))
    # every kept face is wound as the face it was cut from (a flipped one would point into the part)
    assert (np.einsum("ij,ij->i", cut_normals, normals[near]) > 0).all()


def test_masks_that_cover_everything_or_cannot_be_read_are_errors_naming_the_mask():
    from sprayplan.surface.region import mask_out

    square = grid_square()
    with pytest.raises(RegionError, match="cover all of it"):
        mask_out(square, ["box(-1, -1, -1, 11, 11, 1)"])
    with pytest.raises(RegionError, match="cover all of it"):
        mask_out(square, ["x < 6", "x > 4"])
    with pytest.raises(RegionError, match="mask 'q > 3'"):
        mask_out(square, ["z > 0", "q > 3"])


def test_a_mask_drops_a_cloud_s_points_inside_it():
    from sprayplan.surface.region import mask_out

    rng = np.random.default_rng(3)
    points = rng.uniform(0, 10, size=(500, 3))
    cloud = Part(points, np.zeros((0, 3), int), np.tile([0.0, 0.0, 1.0], (500, 1)), "cloud")
    kept, left_out = mask_out(cloud, ["x < 5 and y < 5"])
    inside = (points[:, 0] <= 5) & (points[:, 1] <= 5)
    assert left_out == 0.0 and np.array_equal(kept.vertices, points[~inside])
    assert len(kept.vertex_normals) == len(kept.vertices)


def test_a_job_s_masks_are_checked_when_the_job_is_made():
    from sprayplan.config import LoadConfig
    from sprayplan.errors import ConfigError

    assert LoadConfig(mask=["z > 3", "box(0,0,0,1,1,1)"]).mask == ("z > 3", "box(0,0,0,1,1,1)")
    for bad in ("z > 3", [3], ["x >> 2"], ["box(1,0,0,0,1,1)"]):
        with pytest.raises(ConfigError, match="load.mask"):
            LoadConfig(mask=bad)
