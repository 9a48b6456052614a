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
