"""Gun-tip speed along a stroke: held constant, or varied so that the paint's contact point moves evenly.

The process speed v is either the gun tip's (``along="tcp"``: a robot moving its tool at a constant speed) or
the contact point's on the surface (``along="surface"``). Film thickness is the paint delivered per unit of
surface the spray passes over, so it is the contact point that must move at v: over a convex bend the gun tip
(``standoff`` above the surface) runs on a longer path than the contact point and must go faster, in a
concave bend slower. On segment i, from waypoint i to i + 1::

    v_tcp,i = v * |tcp_{i+1} - tcp_i| / |p_{i+1} - p_i|

clipped to [v / r, v r] with r = ``max_ratio``: at a sharp convex corner the contact point stops while the gun
swings round, and no robot should be asked for an unbounded speed (the corner then gets the paint of a gun
turning at v r). Along straight leads, bridges and flat faces v_tcp = v.

A stroke whose speeds were tuned to the film (``Stroke.dwell``, ``sprayplan.refine.tuning``) divides the
segment's speed by the mean of its two waypoints' time factors: v_i / ((w_i + w_{i+1}) / 2).
"""

from __future__ import annotations

import numpy as np

from sprayplan.errors import ConfigError

ALONG = ("tcp", "surface")


def segment_speeds(
    tcp: np.ndarray,
    points: np.ndarray,
    speed: float,
    along: str = "surface",
    max_ratio: float = 3.0,
    dwell: np.ndarray | None = None,
):
    """(n - 1,) gun-tip speed on each segment of a stroke, mm/s (see the module's formula); ``dwell`` (n,):
    the waypoints' time factors (None: all 1)."""
    if along not in ALONG:
        raise ConfigError(f"speed_along must be tcp or surface, got {along!r}")
    if not max_ratio >= 1.0:
        raise ConfigError(f"max_speed_ratio must be >= 1, got {max_ratio}")
    tcp_len = np.linalg.norm(np.diff(tcp, axis=0), axis=1)
    out = np.full(len(tcp_len), float(speed))
    if along == "surface" and len(tcp_len):
        surface_len = np.linalg.norm(np.diff(points, axis=0), axis=1)
        moving = tcp_len > 1e-9
        ratio = np.ones(len(tcp_len))
        ratio[moving] = tcp_len[moving] / np.maximum(surface_len[moving], tcp_len[moving] / max_ratio)
        out = speed * np.clip(ratio, 1.0 / max_ratio, max_ratio)
    if dwell is not None and len(out):
        dwell = np.asarray(dwell, float)
        out = out / (0.5 * (dwell[:-1] + dwell[1:]))
    return out


def waypoint_speeds(
    tcp: np.ndarray,
    points: np.ndarray,
    speed: float,
    along: str = "surface",
    max_ratio: float = 3.0,
    dwell: np.ndarray | None = None,
):
    """(n,) gun-tip speed on the way to each waypoint, mm/s (a robot's per-move speed); the first waypoint,
    which is approached from elsewhere, takes the speed of the first segment."""
    seg = segment_speeds(tcp, points, speed, along, max_ratio, dwell)
    if len(seg) == 0:
        return np.full(len(tcp), float(speed))
    return np.concatenate([seg[:1], seg])


def stroke_time(
    tcp: np.ndarray,
    points: np.ndarray,
    speed: float,
    along: str = "surface",
    max_ratio: float = 3.0,
    dwell: np.ndarray | None = None,
):
    """Time to run a stroke, s."""
    if len(tcp) < 2:
        return 0.0
    seg = segment_speeds(tcp, points, speed, along, max_ratio, dwell)
    return float((np.linalg.norm(np.diff(tcp, axis=0), axis=1) / seg).sum())
