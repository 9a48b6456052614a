"""Section polylines (seed 003 sections 2.1.1-2.1.3, 3.2.1, 3.2.3): invariants of every polyline function."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest

from sprayplan.errors import ConfigError
from sprayplan.paths.curvature import curvature
from sprayplan.paths.interpolation import interpolate, interpolate_with_normals
from sprayplan.paths.polyline import polyline_length, resample, streamline
from sprayplan.paths.segmentation import feature_points, one_sided_derivatives, split_at

DEG = math.pi / 180.0


def _rotation(seed: int) -> np.ndarray:
    """A fixed random rotation matrix (det +1)."""
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _dense_path(corners: np.ndarray, step: float, closed: bool) -> tuple[np.ndarray, list[int]]:
    """Points every ``step`` along the polygon through ``corners``; also the indices of the corners."""
    chain = np.vstack([corners, corners[:1]]) if closed else corners
    pts, corner_idx = [], []
    for a, b in pairwise(chain):
        k = round(float(np.linalg.norm(b - a)) / step)
        corner_idx.append(len(pts))
        pts.extend(a + (b - a) * j / k for j in range(k))
    if not closed:
        corner_idx.append(len(pts))
        pts.append(chain[-1])
    return np.array(pts), corner_idx


def _circle(radius, angles, rotation, centre):
    local = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros_like(angles)], axis=1)
    return local @ rotation.T + centre


SQUARE = np.array([[0.0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]])


# ------------------------------------------------------------------------------------------ streamline


def test_streamline_open_square_keeps_exactly_the_corners():
    rot = _rotation(1)
    pts, corners = _dense_path(SQUARE, 0.25, closed=False)  # U shape: 3 sides, corners at both ends
    kept = streamline(pts @ rot.T + [5, -3, 2], 170 * DEG, 180 * DEG)
    assert kept.tolist() == corners
    np.testing.assert_allclose(pts[kept], SQUARE)


@pytest.mark.parametrize("shift", [0, 7, 20])
def test_streamline_closed_square_keeps_exactly_the_corners(shift):
    pts, _ = _dense_path(SQUARE, 0.5, closed=True)
    pts = np.roll(pts, -shift, axis=0)  # start at a corner (0) or in the middle of a side
    kept = streamline(pts, 170 * DEG, 180 * DEG, closed=True)
    assert len(kept) == 4
    assert sorted(map(tuple, pts[kept].round(12))) == sorted(map(tuple, SQUARE))


def test_streamline_closed_triangle_keeps_its_corners():
    tri = np.array([[0.0, 0, 0], [12, 0, 1], [3, 9, -2]])
    pts = np.vstack([a + (b - a) * j / 40 for a, b in zip(tri, np.roll(tri, -1, axis=0)) for j in range(40)])
    kept = streamline(pts, 170 * DEG, 180 * DEG, closed=True)
    assert kept.tolist() == [0, 40, 80]


def test_streamline_removes_duplicates():
    zigzag = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 1, 0], [2, 2, 0]])  # 90 degree turns only
    with_dups = np.vstack([zigzag[:3], zigzag[2:3], zigzag[3:], zigzag[4:]])  # P2 twice, end point twice
    kept = streamline(with_dups, 170 * DEG, 180 * DEG)
    assert kept.tolist() == [0, 1, 3, 4, 6]
    np.testing.assert_array_equal(with_dups[kept], zigzag)


def test_streamline_with_thresholds_that_never_match_keeps_everything():
    rng = np.random.default_rng(4)
    angles = np.sort(rng.uniform(0, 1.9 * np.pi, 200))
    pts = _circle(30.0, angles, _rotation(2), np.zeros(3))  # turning angles are small: alpha near 180 deg
    assert streamline(pts, 10 * DEG, 20 * DEG).tolist() == list(range(200))
    assert streamline(pts, 10 * DEG, 20 * DEG, closed=True).tolist() == list(range(200))


def test_streamline_collinear_points_collapse_to_the_ends():
    t = np.sort(np.random.default_rng(5).uniform(0, 1, 50))
    pts = np.array([1.0, 2, 3]) + t[:, None] * np.array([3.0, -1, 2])
    assert streamline(pts, 170 * DEG, 180 * DEG).tolist() == [0, 49]


def test_streamline_is_sequential_against_the_last_kept_point():
    # On a dense arc each single turn is tiny; the seed's loop measures the angle from the last KEPT point,
    # so it deletes until that angle leaves [alpha_min, alpha_max], and keeps points about every 20 deg.
    angles = np.linspace(0, np.pi, 200)  # no kept angle falls exactly on a threshold
    pts = _circle(10.0, angles, np.eye(3), np.zeros(3))
    lo, hi = 170 * DEG, 180 * DEG
    kept = streamline(pts, lo, hi)
    assert 5 <= len(kept) <= 12
    kept_set = set(kept.tolist())
    last = 0
    for i in range(1, len(pts) - 1):
        a, b = pts[i] - pts[last], pts[i + 1] - pts[i]
        alpha = math.pi - math.acos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))
        assert (i in kept_set) == (not lo <= alpha <= hi)
        if i in kept_set:
            last = i


def test_streamline_rejects_bad_thresholds_and_keeps_input():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    pts.flags.writeable = False
    with pytest.raises(ConfigError):
        streamline(pts, 180 * DEG, 170 * DEG)
    with pytest.raises(ConfigError):
        streamline(pts, -0.1, 1.0)
    assert streamline(pts, 170 * DEG, 180 * DEG).tolist() == [0, 2]


# ------------------------------------------------------------------------------------------- curvature


@pytest.fixture
def tilted_arc():
    rng = np.random.default_rng(7)
    radius = 7.3
    angles = np.cumsum(rng.uniform(0.05, 0.4, 25))  # uneven spacing, less than a full turn
    rot = _rotation(3)
    return _circle(radius, angles, rot, np.array([4.0, -2.0, 9.0])), radius, rot[:, 2]


def test_curvature_on_a_tilted_circle_is_one_over_r(tilted_arc):
    pts, radius, normal = tilted_arc
    c = curvature(pts, plane_normal=normal)
    np.testing.assert_allclose(c, 1.0 / radius, rtol=1e-9)  # interior and both end points
    # the automatic (best-fit) normal gives the same magnitude
    np.testing.assert_allclose(np.abs(curvature(pts)), 1.0 / radius, rtol=1e-9)


def test_curvature_closed_circle_wraps_around():
    rng = np.random.default_rng(8)
    angles = np.sort(rng.uniform(0, 2 * np.pi, 40))
    rot = _rotation(9)
    pts = _circle(3.0, angles, rot, np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(curvature(pts, closed=True, plane_normal=rot[:, 2]), 1 / 3.0, rtol=1e-9)


def test_curvature_sign_flips_with_direction(tilted_arc):
    pts, radius, normal = tilted_arc
    np.testing.assert_allclose(curvature(pts[::-1], plane_normal=normal), -1.0 / radius, rtol=1e-9)
    np.testing.assert_allclose(curvature(pts, plane_normal=-normal), -1.0 / radius, rtol=1e-9)
    auto = curvature(pts)
    np.testing.assert_allclose(curvature(pts[::-1]), -auto[::-1], rtol=1e-9)


def test_curvature_sign_follows_the_turn_direction():
    s_curve = np.array([[0.0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0], [4, 0, 0]])  # left turn, then right turns
    c = curvature(s_curve, plane_normal=[0, 0, 1])
    assert c[1] > 0 and c[2] < 0 and c[3] < 0


def test_curvature_of_a_straight_line_is_zero():
    t = np.sort(np.random.default_rng(1).uniform(0, 10, 12))
    pts = t[:, None] * np.array([1.0, 2.0, -0.5])
    for endpoint in ("circle", "seed"):
        assert np.all(curvature(pts, endpoint=endpoint) == 0)
    assert np.all(curvature(pts[:2]) == 0)


def test_curvature_seed_endpoint_matches_hand_computation():
    radius = 5.0
    angles = np.array([0.0, 0.5, 0.8, 1.3, 1.45])  # counter-clockwise in the xy plane, uneven
    pts = _circle(radius, angles, np.eye(3), np.zeros(3))
    c = curvature(pts, endpoint="seed", plane_normal=[0, 0, 1])

    def three_point(a, b, c_):
        ab, bc, ac = b - a, c_ - b, c_ - a
        cross_z = ab[0] * bc[1] - ab[1] * bc[0]
        return 2 * cross_z / (np.linalg.norm(ab) * np.linalg.norm(bc) * np.linalg.norm(ac))

    # P0 = (R, 0); the tangent there is +y (towards P1); P0- lies on it at distance |P0P1| / 2 = R sin(th1 / 2)
    # in the other direction. Then 4 S / (abc) simplifies to 2 sin(th1 / 2) / |P0- P1|.
    th1 = angles[1]
    p_minus = np.array([radius, -radius * math.sin(th1 / 2), 0.0])
    expected_start = 2 * math.sin(th1 / 2) / np.linalg.norm(pts[1] - p_minus)
    assert c[0] == pytest.approx(expected_start, rel=1e-12)
    assert c[0] == pytest.approx(three_point(p_minus, pts[0], pts[1]), rel=1e-12)
    # at the end the virtual point continues forward along the tangent of the circle through the last three
    d = angles[-1] - angles[-2]
    tangent = np.array([-math.sin(angles[-1]), math.cos(angles[-1]), 0.0])
    p_plus = pts[-1] + radius * math.sin(d / 2) * tangent
    assert c[-1] == pytest.approx(2 * math.sin(d / 2) / np.linalg.norm(p_plus - pts[-2]), rel=1e-12)
    np.testing.assert_allclose(c[1:-1], 1 / radius, rtol=1e-9)
    # the seed's construction is not exact on a circle (about 2 / 3R for dense samples)
    assert c[0] < 0.9 / radius


def test_curvature_rejects_bad_options():
    pts = np.eye(3)
    with pytest.raises(ConfigError):
        curvature(pts, endpoint="spline")
    with pytest.raises(ConfigError):
        curvature(pts, plane_normal=[0, 0, 0])


# --------------------------------------------------------------------------------- derivatives, features


def _helix(n):
    x = np.linspace(0, 1, n)
    u = 4 * np.pi * (x + 0.08 * np.sin(2 * np.pi * x))  # non-uniform parameter spacing
    r, c = 5.0, 1.5
    pts = np.stack([r * np.cos(u), r * np.sin(u), c * u], axis=1)
    tangent = np.stack([-r * np.sin(u), r * np.cos(u), np.full_like(u, c)], axis=1) / math.hypot(r, c)
    return pts, tangent


def test_one_sided_derivatives_are_second_order_on_a_helix():
    errors = []
    for n in (101, 201, 401):
        pts, tangent = _helix(n)
        d_minus, d_plus = one_sided_derivatives(pts)
        err_minus = np.linalg.norm(d_minus[2:] - tangent[2:], axis=1).max()
        err_plus = np.linalg.norm(d_plus[:-2] - tangent[:-2], axis=1).max()
        errors.append(max(err_minus, err_plus))
    assert errors[-1] < 1e-3
    for coarse, fine in pairwise(errors):
        assert 3.3 < coarse / fine < 4.7  # halving the spacing divides the error by about 4


def test_one_sided_derivatives_at_the_ends():
    pts = np.array([[0.0, 0, 0], [2, 0, 0], [2, 3, 0], [2, 3, 4]])
    d_minus, d_plus = one_sided_derivatives(pts)
    assert np.all(np.isnan(d_minus[0])) and np.all(np.isnan(d_plus[-1]))
    np.testing.assert_allclose(d_minus[1], [1, 0, 0])  # chord difference
    np.testing.assert_allclose(d_plus[-2], [0, 0, 1])
    # exact on a straight line with uneven spacing
    line = np.array([0.0, 0.3, 1.0, 2.5, 2.6])[:, None] * np.array([[3.0, 4.0, 0.0]])
    d_minus, d_plus = one_sided_derivatives(line)
    np.testing.assert_allclose(d_minus[1:], np.tile([0.6, 0.8, 0], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(d_plus[:-1], np.tile([0.6, 0.8, 0], (4, 1)), atol=1e-12)


def test_feature_points_find_corners_and_nothing_on_a_circle():
    corners = np.array([[0.0, 0, 0], [10, 0, 0], [10, 10, 0]])
    pts, idx = _dense_path(corners, 1.0, closed=False)
    assert feature_points(pts, 0.5, 45 * DEG).tolist() == [idx[1]]
    u_pts, u_idx = _dense_path(SQUARE, 0.5, closed=False)
    assert feature_points(u_pts, 0.5, 45 * DEG).tolist() == u_idx[1:-1]
    sq, sq_idx = _dense_path(SQUARE, 0.5, closed=True)
    assert feature_points(sq, 0.5, 45 * DEG, closed=True).tolist() == sq_idx
    angles = np.sort(np.random.default_rng(2).uniform(0, 2 * np.pi, 120))
    circle = _circle(20.0, angles, _rotation(5), np.zeros(3))
    assert feature_points(circle, 0.5, 45 * DEG).size == 0
    assert feature_points(circle, 0.5, 45 * DEG, closed=True).size == 0


def test_split_at_shares_the_cut_points():
    pts, _ = _dense_path(SQUARE, 1.0, closed=False)  # U shape, 31 points, corners at 10 and 20
    pieces = split_at(pts, [20, 10, 10, 0])
    assert [len(p) for p in pieces] == [11, 11, 11]
    np.testing.assert_array_equal(pieces[0][-1], pieces[1][0])
    np.testing.assert_array_equal(np.vstack([pieces[0], pieces[1][1:], pieces[2][1:]]), pts)
    whole = split_at(pts, [])
    assert len(whole) == 1 and np.array_equal(whole[0], pts) and whole[0] is not pts


def test_split_at_closed_gives_one_piece_per_cut():
    pts, _ = _dense_path(SQUARE, 1.0, closed=True)  # 40 points, corners at 0, 10, 20, 30
    pts = np.roll(pts, -5, axis=0)  # corners now at 5, 15, 25, 35
    pieces = split_at(pts, [35, 5, 15, 25], closed=True)
    assert len(pieces) == 4 and all(len(p) == 11 for p in pieces)
    for piece in pieces:  # each piece is one straight side, corner to corner
        assert polyline_length(piece) == pytest.approx(10.0)
        assert streamline(piece, 170 * DEG, 180 * DEG).tolist() == [0, 10]
    single = split_at(pts, [15], closed=True)
    assert len(single) == 1 and len(single[0]) == 41
    np.testing.assert_array_equal(single[0][0], single[0][-1])
    assert len(split_at(pts, [], closed=True)) == 1
    with pytest.raises(ConfigError):
        split_at(pts, [40])


# ------------------------------------------------------------------------------------------ resampling


def _arc_position(points, seg, t, closed):
    """Arc length of each resampled point from its segment index and parameter, checked to lie on it."""
    chain = np.vstack([points, points[:1]]) if closed else points
    seg_len = np.linalg.norm(np.diff(chain, axis=0), axis=1)
    start = np.concatenate([[0.0], np.cumsum(seg_len)])
    return start[seg] + t * seg_len[seg]


@pytest.mark.parametrize("closed", [False, True])
def test_resample_points_lie_on_the_polyline_equally_spaced(closed):
    rng = np.random.default_rng(11)
    pts = np.cumsum(rng.normal(size=(15, 3)), axis=0)
    out, seg, t = resample(pts, count=23, closed=closed)
    assert out.shape == (23, 3) and seg.dtype.kind == "i"
    assert np.all((t >= 0) & (t <= 1))
    chain = np.vstack([pts, pts[:1]]) if closed else pts
    np.testing.assert_allclose(out, (1 - t)[:, None] * chain[seg] + t[:, None] * chain[seg + 1], atol=1e-12)
    s = _arc_position(pts, seg, t, closed)
    total = polyline_length(pts, closed=closed)
    gaps = np.diff(np.append(s, total) if closed else s)  # a closed loop's last gap runs back to the start
    np.testing.assert_allclose(gaps, total / (23 if closed else 22), rtol=1e-9)
    np.testing.assert_array_equal(out[0], pts[0])
    if not closed:
        np.testing.assert_array_equal(out[-1], pts[-1])


def test_resample_a_line_with_uneven_vertices_has_equal_gaps():
    t_in = np.array([0.0, 0.05, 0.1, 0.5, 0.51, 0.9, 1.0])
    pts = np.array([2.0, 1.0, -1.0]) + t_in[:, None] * np.array([30.0, -12.0, 7.0])
    out, _, _ = resample(pts, count=9)
    gaps = np.linalg.norm(np.diff(out, axis=0), axis=1)
    np.testing.assert_allclose(gaps, gaps.mean(), rtol=1e-9)


def test_resample_step_spacing():
    pts = np.array([[0.0, 0, 0], [10, 0, 0], [10, 7, 0]])  # length 17
    out, seg, t = resample(pts, step_mm=3.0)
    assert len(out) == 7  # ceil(17 / 3) = 6 intervals of 17 / 6 <= 3
    s = _arc_position(pts, seg, t, False)
    np.testing.assert_allclose(np.diff(s), 17 / 6, rtol=1e-9)
    out, _, _ = resample(pts, step_mm=1.0)  # a whole number of steps: no extra point
    assert len(out) == 18
    np.testing.assert_allclose(out[10], [10, 0, 0], atol=1e-12)


def test_resample_closed_loop_uses_the_closing_segment():
    out, seg, _ = resample(SQUARE, count=8, closed=True)
    expected = [[0, 0], [5, 0], [10, 0], [10, 5], [10, 10], [5, 10], [0, 10], [0, 5]]
    np.testing.assert_allclose(out[:, :2], expected, atol=1e-12)
    assert seg[-1] == 3  # on the closing segment [P_3, P_0]
    out, _, _ = resample(SQUARE, step_mm=3.0, closed=True)
    assert len(out) == 14  # ceil(40 / 3) points, spacing 40 / 14, start not repeated
    assert not np.allclose(out[-1], out[0])


def test_resample_rejects_bad_options():
    with pytest.raises(ConfigError):
        resample(SQUARE)
    with pytest.raises(ConfigError):
        resample(SQUARE, step_mm=1.0, count=5)
    with pytest.raises(ConfigError):
        resample(SQUARE, count=1)
    with pytest.raises(ConfigError):
        resample(SQUARE, step_mm=-1.0)


def test_polyline_length():
    assert polyline_length(SQUARE) == pytest.approx(30.0)
    assert polyline_length(SQUARE, closed=True) == pytest.approx(40.0)
    assert polyline_length(SQUARE[:1]) == 0.0


# --------------------------------------------------------------------------------------- interpolation


def _contains_in_order(dense, sparse):
    """Indices of the rows of ``sparse`` found (exactly) in ``dense``, in increasing order."""
    idx, start = [], 0
    for p in sparse:
        hits = np.flatnonzero(np.all(dense[start:] == p, axis=1))
        assert hits.size, f"input point {p} missing from the interpolated path"
        idx.append(start + hits[0])
        start = idx[-1] + 1
    return idx


def test_line_interpolation_stays_on_the_segments():
    rng = np.random.default_rng(3)
    pts = np.cumsum(rng.normal(scale=4.0, size=(8, 3)), axis=0)
    out = interpolate(pts, 0.7)
    idx = _contains_in_order(out, pts)
    assert idx[0] == 0 and idx[-1] == len(out) - 1
    assert np.all(np.linalg.norm(np.diff(out, axis=0), axis=1) <= 0.7 * (1 + 1e-9))
    for i, (a, b) in enumerate(pairwise(idx)):
        d = pts[i + 1] - pts[i]
        rel = out[a : b + 1] - pts[i]
        off_line = np.linalg.norm(np.cross(rel, d), axis=1) / np.linalg.norm(d)
        assert off_line.max() < 1e-9
        assert np.all(np.diff(rel @ d) > 0)  # moving forward along the segment


def test_arc_interpolation_stays_on_the_circle():
    rng = np.random.default_rng(6)
    radius, centre, rot = 12.0, np.array([3.0, -4.0, 5.0]), _rotation(4)
    angles = np.cumsum(rng.uniform(0.3, 0.8, 8))  # 8 uneven points, less than a full turn
    pts = _circle(radius, angles, rot, centre)
    out = interpolate(pts, 0.5, method="arc")
    _contains_in_order(out, pts)
    np.testing.assert_allclose(np.linalg.norm(out - centre, axis=1), radius, rtol=1e-9)
    local = (out - centre) @ rot
    assert np.abs(local[:, 2]).max() < 1e-9  # in the circle's plane
    phi = np.unwrap(np.arctan2(local[:, 1], local[:, 0]))
    assert np.all(np.diff(phi) > 0)  # always the short way round, in the direction of travel
    assert np.all(np.linalg.norm(np.diff(out, axis=0), axis=1) <= 0.5 * (1 + 1e-9))
    assert len(out) > len(interpolate(pts, 0.5)) - 8  # arcs are longer than chords, never fewer pieces


def test_arc_interpolation_of_three_points_uses_their_circle():
    # the first segment uses the circle through P0, P1, P2, not a line
    pts = np.array([[10.0, 0, 0], [0, 10, 0], [-10, 0, 0]])
    out = interpolate(pts, 1.0, method="arc")
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 10.0, rtol=1e-12)
    assert out[:, 1].min() >= -1e-12  # the upper half circle


def test_arc_interpolation_uses_the_circle_through_the_previous_point():
    pts = np.array([[0.0, 0, 0], [10, 0, 0], [15, 5, 0], [15, 20, 0]])  # not on one circle
    out = interpolate(pts, 0.5, method="arc")
    idx = _contains_in_order(out, pts)

    def centre_2d(a, b, c):  # perpendicular bisectors, solved directly
        m = np.array([b[:2] - a[:2], c[:2] - b[:2]])
        rhs = 0.5 * np.array([b[:2] @ b[:2] - a[:2] @ a[:2], c[:2] @ c[:2] - b[:2] @ b[:2]])
        return np.append(np.linalg.solve(m, rhs), 0.0)

    for seg, triple in [(0, (0, 1, 2)), (1, (0, 1, 2)), (2, (1, 2, 3))]:
        centre = centre_2d(*pts[list(triple)])
        radius = np.linalg.norm(pts[triple[0]] - centre)
        piece = out[idx[seg] : idx[seg + 1] + 1]
        assert len(piece) > 2
        np.testing.assert_allclose(np.linalg.norm(piece - centre, axis=1), radius, rtol=1e-9)


def test_arc_interpolation_falls_back_to_lines_when_collinear():
    t = np.array([0.0, 1.0, 2.5, 4.0, 7.0])
    pts = np.array([1.0, 1.0, 1.0]) + t[:, None] * np.array([1.0, 2.0, 2.0]) / 3.0
    np.testing.assert_allclose(interpolate(pts, 0.4, method="arc"), interpolate(pts, 0.4), atol=1e-12)
    # a straight part after an arc is also kept straight
    mixed = np.array([[0.0, 0, 0], [1, 1, 0], [2, 2, 0], [3, 3, 0]])
    out = interpolate(mixed, 0.3, method="arc")
    np.testing.assert_allclose(out[:, 0], out[:, 1], atol=1e-12)


def test_interpolated_normals_are_slerped():
    pts = np.array([[0.0, 0, 0], [10, 0, 0], [10, 10, 0]])
    normals = np.array([[0.0, 0, 1], [0, 1, 1], [1, 0, 0]])
    out, nrm = interpolate_with_normals(pts, normals, 1.0)
    assert len(out) == len(nrm) == 21
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(nrm[0], [0, 0, 1])
    np.testing.assert_allclose(nrm[10], np.array([0, 1, 1]) / math.sqrt(2), rtol=1e-12)
    np.testing.assert_allclose(nrm[-1], [1, 0, 0])
    # constant angular speed along the first segment: the angle from n0 grows linearly with the distance
    angle = np.arccos(np.clip(nrm[:11] @ np.array([0.0, 0, 1]), -1, 1))
    np.testing.assert_allclose(angle, np.linspace(0, np.pi / 4, 11), atol=1e-12)
    # and the normals stay in the plane of the two end normals
    assert np.abs(nrm[:11, 0]).max() < 1e-12


def test_interpolate_rejects_bad_options():
    with pytest.raises(ConfigError):
        interpolate(SQUARE, 0.0)
    with pytest.raises(ConfigError):
        interpolate(SQUARE, 1.0, method="spline")
