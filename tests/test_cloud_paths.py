"""Point-cloud preprocessing, slicing into section polylines, and normals of sampling points (seed 003)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from sprayplan.config import PathConfig
from sprayplan.errors import ConfigError, DataError
from sprayplan.io.load import load_part
from sprayplan.paths import cloud_normals as cn
from sprayplan.paths import cloud_slicing as cs
from sprayplan.paths import cloudprep as cp
from sprayplan.surface.filling import sample_even

# ---------------------------------------------------------------------------------------------------- helpers


def frozen(array):
    """A read-only copy: a function that changes its input in place fails on it."""
    out = np.array(array, dtype=float)
    out.flags.writeable = False
    return out


def segment_distance(points, a, b):
    """Distance of each point to the nearest of the segments a[i]-b[i], and that segment's index."""
    ab = b - a
    t = np.einsum("psj,sj->ps", points[:, None] - a[None], ab) / np.maximum(np.einsum("sj,sj->s", ab, ab), 1e-300)
    foot = a[None] + np.clip(t, 0, 1)[..., None] * ab[None]
    d = np.linalg.norm(points[:, None] - foot, axis=2)
    return d.min(axis=1), d.argmin(axis=1)


def signed_area(poly2):
    x, y = poly2[:, 0], poly2[:, 1]
    return 0.5 * float((x * np.roll(y, -1) - np.roll(x, -1) * y).sum())


def angle_deg(a, b):
    """Angle between unit vectors up to sign, degrees."""
    return np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", a, b)), 0, 1)))


def sphere_points(count, radius, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(count, 3))
    return radius * v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def reach(testdata):
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    points, _ = sample_even(part.triangles, 3.0, seed=0)
    mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
    return part, mesh, points


@pytest.fixture(scope="module")
def milk(testdata):
    return load_part(testdata / "pointclouds" / "pcl_milk.pcd", units="m").vertices


# ---------------------------------------------------------------------------------------------------- slicing, real part

REACH_OFFSETS = np.arange(-750.0, 751.0, 50.0)
HALF = 2.0


def _true_section(mesh, offset):
    lines, faces = trimesh.intersections.mesh_plane(mesh, [0, 1, 0], [0, offset, 0], return_faces=True)
    ny = np.clip(np.abs(mesh.face_normals[faces][:, 1]), 0, 0.999)
    return lines, ny / np.sqrt(1 - ny**2)  # slope: in-plane shift per mm of distance from the plane


def test_reach_slices_unsmoothed_are_projections_within_the_slope_bound(reach):
    """Without smoothing every point is a slab point projected onto its plane: within half_thickness * cot of
    the angle between surface and plane (the slope) of the true mesh section."""
    _, mesh, points = reach
    offsets = REACH_OFFSETS[np.abs(REACH_OFFSETS) <= 700]  # the outer planes cut the sheet's oblique edge
    sections = cs.slice_cloud(frozen(points), [0, 1, 0], offsets, HALF, gap_mm=40.0, smooth_points=1)
    tree = cKDTree(points)
    for offset, polylines in zip(offsets, sections):
        poly = np.concatenate(polylines)
        assert np.allclose(poly[:, 1], offset)
        d, _ = tree.query(poly)
        assert d.max() <= HALF + 1e-9  # each point is a cloud point moved along the normal by <= half
        lines, slope = _true_section(mesh, offset)
        dist, seg = segment_distance(poly, lines[:, 0], lines[:, 1])
        assert np.all(dist <= HALF * slope[seg] + 0.3), offset


def test_reach_slices_smoothed_follow_the_true_section_in_order(reach):
    _, mesh, points = reach
    sections = cs.slice_cloud(points, [0, 1, 0], REACH_OFFSETS, HALF, gap_mm=40.0)
    u, _ = cs.plane_frame(points, np.array([0.0, 1.0, 0.0]))
    assert u[0] > 0.95 and abs(u[1]) < 1e-12  # in the plane, along the hood (x), signed positive
    assert len(sections) == len(REACH_OFFSETS)
    for offset, polylines in zip(REACH_OFFSETS, sections):
        assert len(polylines) == 1  # the sheet has no hole wider than 40 mm
        poly = polylines[0]
        assert np.allclose(poly[:, 1], offset)
        assert poly[-1] @ u > poly[0] @ u  # open polylines run with increasing travel coordinate
        lines, slope = _true_section(mesh, offset)
        dist, seg = segment_distance(poly, lines[:, 0], lines[:, 1])
        if abs(offset) <= 700:  # the outer planes cut the sheet's oblique edge
            # the slope bound, plus the moving average's rounding of the part's rolled edges (radius ~5 mm)
            assert np.all(dist <= HALF * slope[seg] + 3.5), offset
            assert np.percentile(dist, 95) < 0.7
        # a correct order follows the section: its length matches; a shuffled order zig-zags and is longer
        length = np.linalg.norm(np.diff(poly, axis=0), axis=1).sum()
        true_length = np.linalg.norm(lines[:, 1] - lines[:, 0], axis=1).sum()
        assert 0.95 < length / true_length < 1.03
        assert np.linalg.norm(np.diff(poly, axis=0), axis=1).max() < 20.0


def test_reach_pieces_are_sorted_by_travel_and_split_at_gaps(reach):
    _, _, points = reach
    gap = 9.0  # below some random gaps of a 4 mm slab through a 3 mm sampling: several pieces
    travel = np.array([-1.0, 0.0, 0.0])
    sections = cs.slice_cloud(points, [0, 1, 0], REACH_OFFSETS, HALF, gap_mm=gap, travel=travel, smooth_points=1)
    assert sum(len(s) for s in sections) > len(sections)
    for polylines in sections:
        starts = [float((p @ travel).min()) for p in polylines]
        assert starts == sorted(starts)
        for p in polylines:
            assert len(p) >= 3
            assert np.linalg.norm(np.diff(p, axis=0), axis=1).max() <= gap + 1e-9
            assert p[-1] @ travel >= p[0] @ travel
        # pieces are separated by more than the gap
        for a in range(len(polylines)):
            for b in range(a + 1, len(polylines)):
                assert cKDTree(polylines[a]).query(polylines[b])[0].min() > gap


# ---------------------------------------------------------------------------------------------------- slicing, shapes


def cylinder_cloud(radius=100.0, height=200.0, spacing=2.0, seed=1):
    rng = np.random.default_rng(seed)
    count = int(2 * np.pi * radius * height / spacing**2)
    angle = rng.uniform(0, 2 * np.pi, count)
    z = rng.uniform(-height / 2, height / 2, count)
    return np.stack([radius * np.cos(angle), radius * np.sin(angle), z], axis=1)


@pytest.mark.parametrize("normal_sign", [1.0, -1.0])
def test_cylinder_gives_one_closed_ccw_polyline_per_plane(normal_sign):
    points = cylinder_cloud()
    normal = np.array([0.0, 0.0, normal_sign])
    offsets = normal_sign * np.array([-60.0, 0.0, 60.0])
    sections = cs.slice_cloud(points, normal, offsets, 1.5, gap_mm=20.0)
    for offset, polylines in zip(offsets, sections):
        assert len(polylines) == 1
        poly = polylines[0]
        assert np.allclose(poly @ normal, offset)
        radius = np.linalg.norm(poly[:, :2], axis=1)
        assert np.all(np.abs(radius - 100.0) < 0.5)
        steps = np.linalg.norm(np.diff(poly, axis=0), axis=1)
        closing = np.linalg.norm(poly[-1] - poly[0])
        assert 0 < closing < 20.0 and steps.max() < 20.0  # the start is not repeated
        assert abs(steps.sum() + closing - 2 * np.pi * 100) < 0.02 * 2 * np.pi * 100  # once round, in order
        # counter-clockwise seen from the tip of the plane normal
        assert normal_sign * signed_area(poly[:, :2]) > 0.9 * np.pi * 100**2
        # monotone angle: every step turns the same way round the axis
        ang = np.unwrap(np.arctan2(poly[:, 1], poly[:, 0]))
        assert np.all(normal_sign * np.diff(ang) > -1e-3)


def test_torus_gives_two_concentric_closed_polylines():
    rng = np.random.default_rng(11)
    big, small, count = 150.0, 40.0, 60000
    a, b = rng.uniform(0, 2 * np.pi, count), rng.uniform(0, 2 * np.pi, count)
    ring = big + small * np.cos(b)
    points = np.stack([ring * np.cos(a), ring * np.sin(a), small * np.sin(b)], axis=1)
    (polylines,) = cs.slice_cloud(points, [0, 0, 1], [0.0], 1.0, gap_mm=20.0, travel=[1, 0, 0])
    assert len(polylines) == 2
    outer, inner = polylines  # sorted by the smallest x: the outer circle reaches x = -190 first
    assert np.allclose(np.linalg.norm(outer[:, :2], axis=1), big + small, atol=0.5)
    assert np.allclose(np.linalg.norm(inner[:, :2], axis=1), big - small, atol=0.5)
    for poly in polylines:
        assert signed_area(poly[:, :2]) > 0  # both counter-clockwise seen from +z
        assert np.argmin(poly[:, 0]) == 0  # a closed polyline starts at its smallest travel coordinate


def u_cloud(noise=0.3, spacing=1.5, seed=2):
    """An extruded U (not a graph over x): arms x = +-50, z 0..100, joined by a half circle of radius 50."""
    rng = np.random.default_rng(seed)
    arm, arc = 100.0, np.pi * 50.0
    length = 2 * arm + arc
    width = 40.0
    count = int(length * width / spacing**2)
    s = rng.uniform(0, length, count)
    y = rng.uniform(-width / 2, width / 2, count)
    x = np.where(s < arm, -50.0, np.where(s > arm + arc, 50.0, -50.0 * np.cos((s - arm) / 50.0)))
    z = np.where(s < arm, arm - s, np.where(s > arm + arc, s - arm - arc, -50.0 * np.sin((s - arm) / 50.0)))
    points = np.stack([x, y, z], axis=1) + rng.normal(scale=noise, size=(count, 3))
    return points, length


def test_u_section_is_ordered_along_the_u():
    points, length = u_cloud()
    (polylines,) = cs.slice_cloud(points, [0, 1, 0], [0.0], 1.0, gap_mm=10.0, travel=[1, 0, 0])
    assert len(polylines) == 1
    poly = polylines[0]
    # from the tip of the left arm to the tip of the right arm
    assert np.linalg.norm(poly[0][[0, 2]] - [-50, 100]) < 3.0
    assert np.linalg.norm(poly[-1][[0, 2]] - [50, 100]) < 3.0
    steps = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    assert steps.max() < 4.0  # consecutive points are close: no jump between the arms
    assert abs(steps.sum() - length) < 0.05 * length  # and no zig-zag
    # it goes down the left arm, round the bottom and up the right arm: the arc angle is monotone
    below = poly[:, 2] < 0
    bottom = np.unwrap(np.arctan2(poly[below, 2], poly[below, 0]))
    assert np.all(np.diff(bottom) > -0.05)
    assert np.all(np.diff(poly[poly[:, 0] < -45, 2]) < 1.0)  # left arm: z decreases
    assert np.all(np.diff(poly[poly[:, 0] > 45, 2]) > -1.0)  # right arm: z increases


def test_u_section_smoothing_removes_slab_zigzag():
    points, _ = u_cloud(noise=0.6)
    raw = cs.slice_cloud(points, [0, 1, 0], [0.0], 1.0, gap_mm=10.0, smooth_points=1)[0][0]
    smooth = cs.slice_cloud(points, [0, 1, 0], [0.0], 1.0, gap_mm=10.0)[0][0]

    def wiggle(poly):  # mean distance of a point from the chord of its two neighbours
        a, b, c = poly[:-2], poly[1:-1], poly[2:]
        chord = c - a
        return np.mean(np.linalg.norm(np.cross(b - a, chord), axis=1) / np.linalg.norm(chord, axis=1).clip(1e-9))

    assert wiggle(smooth) < 0.5 * wiggle(raw)
    assert len(smooth) == len(raw)


def strip_with_hole(hole=(200.0, 300.0), seed=3):
    rng = np.random.default_rng(seed)
    pts = np.stack([rng.uniform(0, 500, 40000), rng.uniform(-50, 50, 40000), np.zeros(40000)], axis=1)
    pts[:, 2] = 0.0005 * (pts[:, 0] - 250) ** 2  # gently curved
    return pts[(pts[:, 0] < hole[0]) | (pts[:, 0] > hole[1])]


@pytest.mark.parametrize("gap, pieces", [(60.0, 2), (99.0, 2), (101.0, 1), (150.0, 1)])
def test_hole_splits_pieces_only_when_wider_than_gap(gap, pieces):
    points = strip_with_hole()
    (polylines,) = cs.slice_cloud(points, [0, 1, 0], [0.0], 1.0, gap_mm=gap)
    assert len(polylines) == pieces
    for p in polylines:
        assert np.all(np.diff(p[:, 0]) > -1.0)  # every piece runs with increasing travel (x)
    starts = [p[:, 0].min() for p in polylines]
    assert starts == sorted(starts)
    if pieces == 2:
        assert polylines[0][:, 0].max() < 200 and polylines[1][:, 0].min() > 300


def test_hole_pieces_follow_a_reversed_travel():
    (polylines,) = cs.slice_cloud(strip_with_hole(), [0, 1, 0], [0.0], 1.0, gap_mm=50.0, travel=[-1, 0, 0.2])
    assert len(polylines) == 2
    assert polylines[0][:, 0].min() > 300  # sorted by the travel coordinate -x
    for p in polylines:
        assert p[0, 0] > p[-1, 0]


def test_slice_edge_cases_and_errors():
    points = cylinder_cloud()
    empty = cs.slice_cloud(points, [0, 0, 1], [500.0, 0.0], 1.0, gap_mm=15.0)
    assert empty[0] == [] and len(empty[1]) == 1
    with pytest.raises(ConfigError):
        cs.slice_cloud(points, [0, 0, 0], [0.0], 1.0, gap_mm=15.0)
    with pytest.raises(ConfigError):
        cs.slice_cloud(points, [0, 0, 1], [0.0], 0.0, gap_mm=15.0)
    with pytest.raises(ConfigError):
        cs.slice_cloud(points, [0, 0, 1], [0.0], 1.0, gap_mm=-1.0)
    with pytest.raises(ConfigError):
        cs.slice_cloud(points, [0, 0, 1], [0.0], 1.0, gap_mm=15.0, travel=[0, 0, 2])
    with pytest.raises(DataError):
        cs.slice_cloud(points[:, :2], [0, 0, 1], [0.0], 1.0, gap_mm=15.0)


def test_moving_average_keeps_open_ends_and_wraps_closed():
    seq = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0], [3.0, 1.0], [4.0, 0.0]])
    out = cs.moving_average(seq, 3, closed=False)
    assert np.allclose(out[[0, -1]], seq[[0, -1]])
    assert np.allclose(out[2], seq[1:4].mean(axis=0))
    ring = np.stack(
        [np.cos(np.linspace(0, 2 * np.pi, 12, endpoint=False)), np.sin(np.linspace(0, 2 * np.pi, 12, endpoint=False))],
        1,
    )
    wrapped = cs.moving_average(ring, 3, closed=True)
    assert np.allclose(wrapped[0], ring[[11, 0, 1]].mean(axis=0))
    assert np.allclose(np.linalg.norm(wrapped, axis=1), np.linalg.norm(wrapped[0]))  # symmetric: no seam


# ---------------------------------------------------------------------------------------------------- normals


def test_normals_on_a_sphere_agree_with_the_radial_direction():
    cloud = sphere_points(6000, 200.0, seed=4)
    query = sphere_points(300, 200.0, seed=5)  # sampling points that are not cloud points
    radial = query / 200.0
    tri = cn.neighbour_triangle_normals(frozen(query), frozen(cloud), k=8)
    plane = cn.plane_fit_normals(query, cloud, k=12)
    assert np.allclose(np.linalg.norm(tri, axis=1), 1) and np.allclose(np.linalg.norm(plane, axis=1), 1)
    assert angle_deg(tri, radial).max() < 4.0
    assert angle_deg(plane, radial).max() < 4.0
    own = cn.neighbour_triangle_normals(cloud[:200], cloud)  # cloud points: Q itself is not its own neighbour
    assert angle_deg(own, cloud[:200] / 200.0).max() < 3.0


def grid_cloud(curved: bool):
    x, y = np.meshgrid(np.arange(-20, 21) * 2.0, np.arange(-20, 21) * 2.0)
    z = (x**2 + y**2) / (2 * 150.0) if curved else np.zeros_like(x)
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    if curved:
        true = np.stack([-x.ravel() / 150.0, -y.ravel() / 150.0, np.ones(x.size)], axis=1)
    else:
        true = np.tile([0.0, 0.0, 1.0], (x.size, 1))
    rotation = trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])[:3, :3]  # tilt: not just the z axis
    return points @ rotation.T, (true / np.linalg.norm(true, axis=1, keepdims=True)) @ rotation.T


@pytest.mark.parametrize("weighting", ["area", "inverse_area"])
@pytest.mark.parametrize("curved", [False, True])
def test_triangle_normal_weightings_on_a_regular_grid(weighting, curved):
    points, true = grid_cloud(curved)
    normals = cn.neighbour_triangle_normals(points, points, k=8, weighting=weighting)
    limit = 1e-4 if not curved else 1.0
    assert angle_deg(normals, true).max() < limit  # corners and edges too: the wrapping triangle is skipped


def test_inverse_area_needs_the_hidden_neighbour_rule_on_a_curved_grid():
    """Without dropping the neighbours hidden behind nearer ones, the seed's 1/S weight lets the needle
    triangles along a grid's edges dominate; the area weight barely notices them."""
    points, true = grid_cloud(True)
    raw_inverse = cn.neighbour_triangle_normals(points, points, weighting="inverse_area", min_fan_angle_rad=0)
    raw_area = cn.neighbour_triangle_normals(points, points, weighting="area", min_fan_angle_rad=0)
    assert angle_deg(raw_inverse, true).max() > 20.0
    assert angle_deg(raw_area, true).max() < 3.0


def test_inverse_area_weighting_follows_the_smallest_triangle():
    """The seed's 1/S weight: a fan of one tiny, tilted triangle and big flat ones leans to the tiny one."""
    q = np.zeros((1, 3))
    ring = np.array([[10, 0, 0], [0, 10, 0], [-10, 0, 0], [0, -10, 0], [0.3, -0.3, 0.6]], dtype=float)
    area = cn.neighbour_triangle_normals(q, ring, k=5, weighting="area")[0]
    inverse = cn.neighbour_triangle_normals(q, ring, k=5, weighting="inverse_area")[0]
    z = np.array([0.0, 0.0, 1.0])
    assert abs(area @ z) > abs(inverse @ z)
    assert np.degrees(np.arccos(abs(area @ z))) < 10
    with pytest.raises(ConfigError):
        cn.neighbour_triangle_normals(q, ring, weighting="volume")


# ---------------------------------------------------------------------------------------------------- preprocessing


def test_outlier_removal_on_the_milk_scan(milk):
    rng = np.random.default_rng(6)
    low, high = milk.min(axis=0), milk.max(axis=0)
    centre, size = (low + high) / 2, (high - low)
    far = centre + rng.uniform(-1.5, 1.5, size=(60, 3)) * size
    far = far[cKDTree(milk).query(far)[0] > 50.0]
    cloud = frozen(np.concatenate([milk, far]))
    keep = cp.remove_outliers(cloud, k=16, std_ratio=2.0)
    assert np.all(np.diff(keep) > 0)
    assert not np.any(keep >= len(milk))  # every injected outlier is gone
    assert len(keep) >= 0.95 * len(milk)


def test_smoothing_pulls_noisy_plane_points_to_the_plane():
    rng = np.random.default_rng(7)
    xy = rng.uniform(0, 100, size=(5000, 2))
    noisy = np.column_stack([xy, rng.normal(scale=0.3, size=5000)])
    inner = np.all((xy > 10) & (xy < 90), axis=1)
    once = cp.smooth(frozen(noisy), 5.0)
    twice = cp.smooth(noisy, 5.0, iterations=2)
    rms = lambda p: np.sqrt(np.mean(p[inner, 2] ** 2))
    assert rms(once) < 0.5 * rms(noisy)
    assert rms(twice) < rms(once)
    assert np.abs(once[:, :2] - noisy[:, :2]).max() < 0.3  # moved across the surface, hardly along it
    lonely = cp.smooth(np.array([[0, 0, 0], [100, 0, 1], [0, 100, 2], [100, 100, 3], [50, 50, 9.0]]), 5.0)
    assert np.allclose(lonely[:, 2], [0, 1, 2, 3, 9])  # fewer than 4 neighbours: unchanged


def test_smoothing_a_sphere_reduces_noise_with_the_plane_fit_bias_only():
    radius, r = 100.0, 12.0
    points = sphere_points(4000, radius, seed=8)
    noisy = points * (1 + np.random.default_rng(9).normal(scale=0.005, size=(4000, 1)))
    out = cp.smooth(noisy, r)
    before, after = np.linalg.norm(noisy, axis=1), np.linalg.norm(out, axis=1)
    assert after.std() < 0.5 * before.std()
    # a plane through a cap's mean lies about r^2 / (4 R) inside the sphere: that much shrinking, no more
    bias = r**2 / (4 * radius)
    assert 0 < before.mean() - after.mean() < 1.5 * bias


def test_space_sampling_properties(milk):
    rng = np.random.default_rng(10)
    overlap = np.concatenate([milk, milk[::2] + rng.normal(scale=0.05, size=(len(milk[::2]), 3))])
    keep = cp.space_sample(frozen(overlap))  # the seed's 0.4 mm
    kept = overlap[keep]
    assert len(cKDTree(kept).query_pairs(0.4)) == 0
    dropped = np.setdiff1d(np.arange(len(overlap)), keep)
    assert cKDTree(kept).query(overlap[dropped])[0].max() <= 0.4
    assert np.all(keep < len(milk)) or len(keep) > 0.95 * len(milk)  # the second scan is the one dropped
    assert np.sum(keep >= len(milk)) < 0.01 * len(milk)
    coarse = cp.space_sample(milk, 3.0)
    assert 0 in coarse and len(coarse) < 0.5 * len(milk)  # greedy in file order: the first point stays
    assert len(cKDTree(milk[coarse]).query_pairs(3.0)) == 0
    with pytest.raises(ConfigError):
        cp.space_sample(milk, 0.0)


def test_fill_gaps_fills_small_gaps_and_leaves_holes():
    x = np.r_[0.0, 1.0, 2.0, 7.0, 8.0, 58.0, 59.0, 62.5]
    line = frozen(np.column_stack([x, 0.5 * x, np.zeros_like(x)]))
    out = cp.fill_gaps(line, max_gap_mm=10.0, step_mm=1.0)
    # originals kept, in order
    pos = [int(np.flatnonzero(np.all(np.isclose(out, p), axis=1))[0]) for p in line]
    assert pos == sorted(pos) and pos[0] == 0 and pos[-1] == len(out) - 1
    steps = np.linalg.norm(np.diff(out, axis=0), axis=1)
    big = steps > 1.0 * np.hypot(1, 0.5) + 1e-9
    assert big.sum() == 1  # only the 50 mm hole is left
    assert np.isclose(steps[big][0], 50 * np.hypot(1, 0.5))
    assert np.allclose(np.cross(out[1:] - out[:-1], [1, 0.5, 0]), 0)  # inserted points lie on the line
    # the 5 mm gap: 2 -> 7 along x at most 1 apart; the 3.5 mm one: 59 -> 62.5
    assert np.sum((out[:, 0] > 2) & (out[:, 0] < 7)) == np.ceil(5 * np.hypot(1, 0.5)) - 1
    closed = cp.fill_gaps(np.array([[0, 0, 0], [5, 0, 0], [5, 5, 0.0]]), 10.0, 1.0, closed=True)
    assert np.linalg.norm(np.diff(np.vstack([closed, closed[:1]]), axis=0), axis=1).max() <= 1.0 + 1e-9
    with pytest.raises(ConfigError):
        cp.fill_gaps(line, 10.0, 0.0)


def test_preprocess_chains_the_steps(milk):
    points, kept = cp.preprocess(frozen(milk), tolerance_mm=2.0)
    assert len(points) == len(kept) and np.all(np.diff(kept) > 0)
    assert len(points) < len(milk)
    assert np.abs(points - milk[kept]).max() < 5.0  # smoothing moves points only a little
    assert len(cKDTree(points).query_pairs(2.0)) == 0
    same, idx = cp.preprocess(milk, smooth_iterations=0, tolerance_mm=1e-6)
    assert np.array_equal(same, milk[idx])  # without smoothing the points are the input's
    with pytest.raises(ConfigError):
        cp.preprocess(milk, outlier_k=0)


def test_scanned_normals_are_smoothed_along_the_sections(testdata):
    from sprayplan.paths.planner import plan_paths

    cloud = load_part(testdata / "pointclouds" / "pcl_milk.pcd", units="m")

    def tip_over_contact(config):
        ratios = []
        for s in plan_paths(cloud, config).spray_strokes:
            if s.on_part.any():
                ratios.append(s.length_mm / np.linalg.norm(np.diff(s.points, axis=0), axis=1).sum())
        return np.array(ratios)

    # raw neighbour-triangle normals turn about 10 degrees per step on this scan: the gun tip would run 7 to 13
    # times as far as the contact point; averaged over 25 mm it runs at most about twice as far (a carton's
    # corners add a quarter circle of the standoff each)
    # (the gun's own smoothing along the strokes, gun_smooth_mm, off: this is the sections' normals alone)
    raw = tip_over_contact(PathConfig(spacing_mm=37.19, cloud_normal_smooth_mm=0.0, gun_smooth_mm=0.0))
    smooth = tip_over_contact(PathConfig(spacing_mm=37.19, gun_smooth_mm=0.0))
    assert raw.min() > 5.0 and smooth.max() < 2.0
    # both (the defaults): the gun turns over a spray diameter, the tip runs about as far as the contact point
    assert tip_over_contact(PathConfig(spacing_mm=37.19)).max() < smooth.max()


def test_smooth_normals_keep_the_surface_and_drop_the_noise():
    from sprayplan.paths.pieces import smooth_normals

    rng = np.random.default_rng(1)
    angle = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    points = 300.0 * np.column_stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)])
    radial = points / 300.0
    noisy = radial + rng.normal(0, 0.15, radial.shape)
    noisy /= np.linalg.norm(noisy, axis=1)[:, None]
    out = smooth_normals(points, noisy, 25.0, closed=True)
    err_in = np.degrees(np.arccos(np.clip((noisy * radial).sum(1), -1, 1)))
    err_out = np.degrees(np.arccos(np.clip((out * radial).sum(1), -1, 1)))
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)
    # about 10 points in the window: the noise falls by about sqrt(10), the median angle to under 0.45 of it
    assert np.median(err_out) < 0.45 * np.median(err_in)
    # noise-free normals of a circle stay as they are (up to the window's half-angle) and an open end too
    clean = smooth_normals(points, radial, 25.0, closed=True)
    assert np.degrees(np.arccos(np.clip((clean * radial).sum(1), -1, 1))).max() < 0.1
    np.testing.assert_array_equal(smooth_normals(points, noisy, 0.0), noisy)
