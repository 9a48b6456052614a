"""Gun-tip speeds that hold the contact point's speed (sprayplan.paths.speed) and their use in the film."""

from __future__ import annotations

import numpy as np
import pytest

from sprayplan.errors import ConfigError
from sprayplan.paths.speed import segment_speeds, stroke_time, waypoint_speeds

V, H = 400.0, 113.0


def arc(radius: float, outward: bool, count: int = 30):
    """Contact points on a circle in the x-z plane, normals out of (or into) it, and the gun tips."""
    angle = np.linspace(-0.6, 0.6, count)
    radial = np.stack([np.sin(angle), np.zeros(count), np.cos(angle)], axis=1)
    points = radius * radial
    normals = radial if outward else -radial
    return points, points + H * normals


@pytest.mark.parametrize("radius", [150.0, 400.0, 2000.0])
def test_over_a_convex_bend_the_tip_runs_faster_by_its_longer_radius(radius):
    points, tcp = arc(radius, outward=True)
    speeds = segment_speeds(tcp, points, V, "surface")
    # equal angles: the tip's chords are (r + h) / r times the contact point's
    expected = V * min((radius + H) / radius, 3.0)
    np.testing.assert_allclose(speeds, expected, rtol=1e-9)
    # the contact point then moves at V: the stroke takes its surface length / V
    surface = np.linalg.norm(np.diff(points, axis=0), axis=1).sum()
    assert stroke_time(tcp, points, V, "surface") == pytest.approx(surface / V, rel=1e-9)


def test_in_a_concave_bend_the_tip_slows_down():
    points, tcp = arc(300.0, outward=False)
    np.testing.assert_allclose(segment_speeds(tcp, points, V, "surface"), V * (300.0 - H) / 300.0, rtol=1e-9)


def test_speeds_are_clipped_where_the_contact_point_stops():
    # a sharp convex corner: the contact point stays while the gun swings through 90 degrees
    angle = np.linspace(0.0, np.pi / 2, 10)
    normals = np.stack([np.sin(angle), np.zeros(10), np.cos(angle)], axis=1)
    points = np.zeros((10, 3))
    tcp = points + H * normals
    np.testing.assert_allclose(segment_speeds(tcp, points, V, "surface", max_ratio=2.5), 2.5 * V)
    # and a concave one: the tip stays while the contact point sweeps
    np.testing.assert_allclose(segment_speeds(points + 1.0 * normals, H * normals, V, "surface"), V / 3.0)


def test_tip_speed_mode_and_straight_strokes_keep_the_speed():
    points, tcp = arc(150.0, outward=True)
    np.testing.assert_allclose(segment_speeds(tcp, points, V, "tcp"), V)
    line = np.stack([np.linspace(0, 500, 51), np.zeros(51), np.zeros(51)], axis=1)
    np.testing.assert_allclose(segment_speeds(line + [0, 0, H], line, V, "surface"), V)


def test_waypoint_speeds_are_the_speed_on_the_way_to_each_waypoint():
    points, tcp = arc(150.0, outward=True, count=7)
    points[4:] *= 1.5  # a step in the surface changes the ratio on segments 3 and later
    seg = segment_speeds(tcp, points, V, "surface")
    way = waypoint_speeds(tcp, points, V, "surface")
    assert len(way) == len(tcp)
    np.testing.assert_array_equal(way[1:], seg)
    assert way[0] == seg[0]
    assert waypoint_speeds(tcp[:1], points[:1], V).tolist() == [V]


def test_bad_settings():
    points, tcp = arc(150.0, outward=True)
    with pytest.raises(ConfigError):
        segment_speeds(tcp, points, V, "gun")
    with pytest.raises(ConfigError):
        segment_speeds(tcp, points, V, "surface", max_ratio=0.5)
