"""Gantry stations placed for strokes that the plan's stations cannot reach (touch-ups).

The circle cover (``partition``) places stations over the part's outline, so that the arm reaches down onto
the part. A surface that faces sideways or downwards (the underside of a curled lip, a step facing away) is
sprayed with the gun pointing sideways or up, from beside the part: the arm needs its base outside the part,
past the edge the surface faces. This module finds such positions at a given gantry height.

For every stroke, candidate gantry positions lie on rings around its flange positions' centre (radii 0 to
``max_radius`` times the working radius R, every R/8, in 16 directions). For each candidate and each stroke
near it, the analytic inverse kinematics (``ur_ik``, with the joint limits) tells which waypoints the arm
reaches exactly from there; a waypoint in the working cylinder's recommended region counts half as much again
(seed 000's preference for the region). A greedy cover then takes the candidate that reaches the most
waypoints of the strokes still without a station, gives it the strokes it reaches at least half of, and
repeats, up to ``max_stations``.

This is a screening: the caller solves the strokes' joints from the chosen positions (``solve_gantry_path``)
and cuts what the arm still misses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.robots.gantry import Gantry

#: Candidate rings: radii in steps of R/8, directions.
RING_STEP = 1.0 / 8.0
DIRECTIONS = 16


@dataclass(frozen=True)
class AddedStation:
    """A gantry position for some of the strokes.

    Attributes
    ----------
    platform_mm : (3,) float
        Gantry position.
    strokes : tuple of int
        Indices of the strokes it takes.
    reached : int
        Their waypoints the analytic inverse kinematics reaches from it.
    """

    platform_mm: np.ndarray
    strokes: tuple
    reached: int


def _reached(gantry: Gantry, gun2world: np.ndarray, platforms: np.ndarray) -> np.ndarray:
    """(k, n) bool: for each of k gantry positions (k, 3), the waypoints with an exact analytic solution within
    the joint limits from there. All (position, waypoint) pairs go to ``ur_ik`` together, in blocks of about
    ``_POSES`` poses (each pose is solved on its own: the answer does not depend on the blocks)."""
    from sprayplan.robots.ur_ik import ur_ik

    platforms = np.asarray(platforms, dtype=float).reshape(-1, 3)
    n = len(gun2world)
    out = np.zeros((len(platforms), n), dtype=bool)
    if not (n and len(platforms)):
        return out
    world2base = np.linalg.inv(gantry.base2world(platforms))  # (k, 4, 4)
    to_flange = np.linalg.inv(gantry.gun.gun2flange)
    per_block = max(1, _POSES // n)
    length = arm_length_mm(gantry.robot)
    for start in range(0, len(platforms), per_block):
        block = slice(start, start + per_block)
        # eq. 14 for every pair, the products in the order of Gantry.flange_targets
        flange = ((world2base[block, None] @ gun2world[None]) @ to_flange).reshape(-1, 4, 4)
        # only poses within the arm's length can be reached: the others need no inverse kinematics
        near = np.flatnonzero(np.einsum("ij,ij->i", flange[:, :3, 3], flange[:, :3, 3]) <= length * length)
        solutions = ur_ik(gantry.robot, flange[near])
        within = gantry.robot.within_limits(solutions.q)  # (poses, branches)
        ok = np.zeros(len(flange), dtype=bool)
        ok[near] = (solutions.valid & within).any(axis=1)
        out[block] = ok.reshape(-1, n)
    return out


def arm_length_mm(robot) -> float:
    """An upper bound of the distance between the base frame's origin and the flange's over every joint
    vector: each D-H link moves the origin by sqrt(d^2 + a^2), plus 1 mm for rounding."""
    return float(np.hypot(robot.d, robot.a).sum()) + 1.0


#: Poses given to the inverse kinematics at once by ``_reached`` (its temporaries: about 1 kB a pose).
_POSES = 32_768


def _candidates(centre: np.ndarray, radius: float, max_radius: float) -> np.ndarray:
    """(k, 2) candidate xy positions on rings round ``centre``."""
    rings = radius * RING_STEP * np.arange(1, round(max_radius / RING_STEP) + 1)
    angles = 2.0 * np.pi * np.arange(DIRECTIONS) / DIRECTIONS
    ring = rings[:, None, None] * np.stack([np.cos(angles), np.sin(angles)], -1)[None]
    return centre + np.vstack([[0.0, 0.0], ring.reshape(-1, 2)])


def reach_share(
    gantry: Gantry, gun2world: np.ndarray, platforms: np.ndarray, height_mm: float | None = None, max_radius=1.25
) -> float:
    """The largest share of a stroke's waypoints the arm reaches exactly (analytic inverse kinematics) from
    any of the given gantry positions, and, with ``height_mm``, from any candidate position for a new station
    at that height (see the module docstring)."""
    platforms = np.atleast_2d(np.asarray(platforms, dtype=float)).reshape(-1, 3)
    if height_mm is not None:
        centre = (gun2world @ np.linalg.inv(gantry.gun.gun2flange))[:, :2, 3].mean(axis=0)
        rings = _candidates(centre, gantry.workspace.radius_mm, max_radius)
        platforms = np.vstack([platforms, np.column_stack([rings, np.full(len(rings), float(height_mm))])])
    if not len(platforms) or not len(gun2world):
        return 0.0
    return float(_reached(gantry, gun2world, platforms).mean(axis=1).max())


def stations_for_strokes(
    gantry: Gantry,
    gun2world: list[np.ndarray],
    height_mm: float,
    *,
    max_stations: int,
    max_radius: float = 1.25,
) -> list[AddedStation]:
    """Gantry positions at height ``height_mm`` from which the arm reaches the given strokes.

    Parameters
    ----------
    gantry : Gantry
    gun2world : list of (n_i, 4, 4) float, mm
        The strokes' gun poses.
    height_mm : float
        The gantry's height (the plan's).
    max_stations : int
        At most this many positions.
    max_radius : float
        Candidates lie up to this many working radii from a stroke's flange centre.

    Returns
    -------
    list of AddedStation
        In the order found (most waypoints first); strokes no candidate reaches are in none.
    """
    if max_stations <= 0 or not gun2world:
        return []
    platforms, counts, score = _scores(gantry, gun2world, height_mm, max_radius)
    sizes = np.array([len(p) for p in gun2world], dtype=float)
    useful = counts >= 0.5 * sizes  # a candidate takes a stroke it reaches at least half of
    out: list[AddedStation] = []
    left = np.ones(len(gun2world), dtype=bool)
    while left.any() and len(out) < max_stations:
        gain = np.where(useful & left, score, 0.0).sum(axis=1)
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        taken = np.flatnonzero(useful[best] & left)
        left[taken] = False
        out.append(AddedStation(platforms[best].copy(), tuple(int(s) for s in taken), int(counts[best, taken].sum())))
    return out


def _scores(gantry: Gantry, gun2world: list[np.ndarray], height_mm: float, max_radius: float):
    """The candidate positions (k, 3) of :func:`stations_for_strokes` and, per candidate and stroke (k, s),
    the stroke's waypoints reached from there and their score (recommended ones count 1.5)."""
    radius = gantry.workspace.radius_mm
    to_flange = np.linalg.inv(gantry.gun.gun2flange)
    flange = [poses @ to_flange for poses in gun2world]
    centres = np.array([f[:, :2, 3].mean(axis=0) for f in flange])
    spans = np.array([np.linalg.norm(f[:, :2, 3] - c, axis=1).max() for f, c in zip(flange, centres)])
    candidates = np.vstack([_candidates(c, radius, max_radius) for c in centres])
    platforms = np.column_stack([candidates, np.full(len(candidates), float(height_mm))])
    counts = np.zeros((len(candidates), len(flange)))
    score = np.zeros_like(counts)
    for s, (poses, f) in enumerate(zip(gun2world, flange)):
        near = np.flatnonzero(np.linalg.norm(candidates - centres[s], axis=1) <= max_radius * radius + spans[s])
        ok = _reached(gantry, poses, platforms[near])  # (near, waypoints)
        points = f[:, :3, 3]
        region = gantry.region(np.tile(points, (len(near), 1)), np.repeat(platforms[near], len(points), axis=0))
        recommended = region.reshape(len(near), len(points)) == 2
        counts[near, s] = ok.sum(axis=1)
        score[near, s] = ok.sum(axis=1) + 0.5 * (ok & recommended).sum(axis=1)
    return platforms, counts, score
