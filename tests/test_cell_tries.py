"""The tries a cell robot makes for a stroke (``cells.tries``): those that pass the robot's first axis go last;
the wrist unwound where a stroke would wind it to its limit (``cells.plan.solve_strokes``)."""

from __future__ import annotations

import numpy as np

from sprayplan.cells import load_cell
from sprayplan.cells.plan import solve_strokes
from sprayplan.cells.tries import AXIS_ONE_CLEARANCE_MM, ROLL_TRIES_DEG, TRACK_TRIES_MM, stroke_tries
from sprayplan.types import Stroke


def _across_the_roof(x_mm: float = 500.0, z_mm: float = 2100.0, standoff_mm: float = 200.0) -> Stroke:
    """A stroke across a flat roof at height ``z_mm``, from y = -900 to 900 mm at ``x_mm``, right under the
    first axis of line3's roof robot (its base over y = 0)."""
    y = np.linspace(-900.0, 900.0, 61)
    points = np.column_stack([np.full_like(y, x_mm), y, np.full_like(y, z_mm)])
    normals = np.tile([0.0, 0.0, 1.0], (len(y), 1))
    return Stroke(points, normals, points + standoff_mm * normals, spray_on=True, on_part=np.ones(len(y), bool))


def _axis_one_distance(cell_robot, track_mm, q) -> np.ndarray:
    """(n,) the flange's distance from the first axis at each waypoint, from the forward kinematics, mm."""
    out = []
    for t, j in zip(track_mm, q):
        robot = cell_robot.robot(float(t))
        flange = (robot.fk(j[None])[0] @ np.linalg.inv(robot.tcp2flange))[:3, 3]
        base = robot.base2world
        d = flange - base[:3, 3]
        out.append(np.linalg.norm(d - (d @ base[:3, 2]) * base[:3, 2]))
    return np.array(out)


def test_a_stroke_under_a_hung_robot_is_solved_off_its_first_axis():
    """Across the roof right under line3's roof robot, the try held at the stroke's middle (the first in track
    order) puts the first axis over the stroke, and the arm turns about it by nearly half a turn, fastest at the
    crossing. The tries are the same ones (a permutation of the track offsets and rolls), those off the axis first: the
    stroke is solved with its flange at least ``AXIS_ONE_CLEARANCE_MM`` from the first axis all along (the
    forward kinematics' answer), the first joint's steps under a half of the held try's."""
    roof = load_cell("line3").robots[0]
    stroke = _across_the_roof()
    tries = stroke_tries(roof, stroke)
    lo, hi = roof.track.range_mm
    along = (stroke.tcp - roof.base2cell[:3, 3]) @ roof.track.axis
    plain = []
    for base in (np.full(len(along), 0.5 * (along.min() + along.max())), along):
        for d in TRACK_TRIES_MM:
            t = np.clip(base + d, lo, hi)
            if not any(np.array_equal(t, u) for u, _ in plain):
                plain += [(t, r) for r in ROLL_TRIES_DEG]
    assert sorted((t.tobytes(), r) for t, r in tries) == sorted((t.tobytes(), r) for t, r in plain)
    assert tries[0][0][0] != plain[0][0][0]  # the middle's tries went back

    ((track, _, q, reach),) = solve_strokes(roof, [stroke])
    assert reach.all()
    assert _axis_one_distance(roof, track, q).min() >= AXIS_ONE_CLEARANCE_MM - 1e-6
    step = np.degrees(np.abs(np.diff(q[:, 0]))).max()  # the first joint's largest step, 30 mm of travel
    assert step < 10.0
    # the try held at the middle, as it was first before: the first axis over the stroke, the first joint
    # turning through 168 deg across it, fastest at the crossing
    held = [(t, r) for t, r in plain if np.array_equal(t, plain[0][0])]
    from sprayplan.cells import tries as cell_tries

    first = cell_tries._off_axis_one_first
    try:
        cell_tries._off_axis_one_first = lambda cell_robot, s, t: held
        ((track0, _, q0, reach0),) = solve_strokes(roof, [stroke])
    finally:
        cell_tries._off_axis_one_first = first
    assert reach0.all()
    assert _axis_one_distance(roof, track0, q0).min() < AXIS_ONE_CLEARANCE_MM / 2
    assert np.degrees(np.abs(np.diff(q0[:, 0]))).max() > 2.0 * step  # 17.9 against 4.4 deg


def test_tries_far_from_the_first_axis_keep_their_order():
    """A stroke along a car's side, far from every robot's first axis: the tries in their plain order."""
    left = load_cell("line3").robots[1]
    x = np.linspace(-1000.0, 1000.0, 41)
    points = np.column_stack([x, np.full_like(x, 900.0), np.full_like(x, 1000.0)])
    normals = np.tile([0.0, 1.0, 0.0], (len(x), 1))
    stroke = Stroke(points, normals, points + 200.0 * normals, spray_on=True, on_part=np.ones(len(x), bool))
    tries = stroke_tries(left, stroke)
    assert len(tries) == len({(t.tobytes(), r) for t, r in tries})
    middle = [t for t, _ in tries[: len(ROLL_TRIES_DEG)]]
    assert all(np.allclose(t, t[0]) for t in middle)  # held still first, at the middle of the stroke
    assert [r for _, r in tries[: len(ROLL_TRIES_DEG)]] == list(ROLL_TRIES_DEG)


def test_a_try_whose_joints_jump_gives_way_to_one_that_reaches_as_much_without(monkeypatch):
    """Across the roof with the roof robot 300 mm ahead of the stroke and the gun's roll 0, the first joint meets
    its limit where the stroke crosses the roof's middle and turns back by a whole turn between two waypoints:
    every waypoint reached, but the arm would spin at the roof. ``solve_strokes`` keeps a later try that
    reaches as many without a jump (the first whole one was kept before), and the jumping try alone is what it
    falls back to."""
    import sprayplan.cells.plan as cells_plan

    roof = load_cell("line3").robots[0]
    stroke = _across_the_roof()
    x = float(stroke.tcp[0, 0])
    ahead = (np.full(len(stroke), x + 300.0), 0.0)
    behind = (np.full(len(stroke), x - 300.0), 90.0)

    def solved(tries):
        monkeypatch.setattr(cells_plan, "stroke_tries", lambda cell_robot, s: tries)
        ((track, roll, q, reach),) = solve_strokes(roof, [stroke])
        return track, roll, q, reach

    track, roll, q, reach = solved([ahead])
    assert reach.all() and np.degrees(np.abs(np.diff(q, axis=0))).max() > 90.0  # the jumping try alone
    track, roll, q, reach = solved([ahead, behind])
    assert reach.all() and roll == 90.0 and np.array_equal(track, behind[0])
    assert np.degrees(np.abs(np.diff(q, axis=0))).max() < 90.0
    got = np.stack([roof.robot(t).fk(j[None])[0] for t, j in zip(track, q)])  # the gun where the stroke wants it
    np.testing.assert_allclose(got[:, :3, 3], stroke.tcp, atol=1e-6)


def test_a_stroke_keeps_the_try_that_goes_on_from_where_the_stroke_before_ends(monkeypatch):
    """Two strokes across the roof, the second back along the first. Its first try (the track 600 mm behind,
    the gun rolled 270 deg) reaches every waypoint with no jump along it, but starts with the sixth joint 174
    deg from where the first stroke ends (a transfer that turns the gun over at the roof); a later try (the
    same track, roll 90) starts 14 deg or less from it on every joint and is kept. Alone, the first try is
    kept all the same (nothing better reaches the stroke)."""
    import dataclasses

    import sprayplan.cells.plan as cells_plan

    roof = load_cell("line3").robots[0]
    out = _across_the_roof()
    back = dataclasses.replace(
        out, points=out.points[::-1].copy(), normals=out.normals[::-1].copy(), tcp=out.tcp[::-1].copy()
    )
    x = float(out.tcp[0, 0])
    n = len(out)
    behind = (np.full(n, x - 300.0), 90.0)
    turned, straight = (np.full(n, x - 600.0), 270.0), (np.full(n, x - 600.0), 90.0)

    def solved(second):
        monkeypatch.setattr(cells_plan, "stroke_tries", lambda cell_robot, s: [behind] if s is out else second)
        return solve_strokes(roof, [out, back])

    (_, _, q1, reach1), (track, roll, q2, reach2) = solved([turned, straight])
    assert reach1.all() and reach2.all() and roll == 90.0 and np.array_equal(track, straight[0])
    assert np.degrees(np.abs(q2[0] - q1[-1])).max() <= 90.0
    assert np.degrees(np.abs(np.diff(q2, axis=0))).max() <= 90.0
    got = np.stack([roof.robot(t).fk(j[None])[0] for t, j in zip(track, q2)])
    np.testing.assert_allclose(got[:, :3, 3], back.tcp, atol=1e-6)
    (_, _, q1, _), (_, roll, q2, reach2) = solved([turned])
    assert reach2.all() and roll == 270.0 and np.degrees(np.abs(q2[0] - q1[-1])).max() > 90.0


def _along_the_side(x0: float, x1: float, z_mm: float = 1100.0, standoff_mm: float = 200.0) -> Stroke:
    """A stroke along a car's flat side at y = 900 mm, from x0 to x1 at height ``z_mm`` (normals +y)."""
    x = np.linspace(x0, x1, 61)
    points = np.column_stack([x, np.full_like(x, 900.0), np.full_like(x, z_mm)])
    normals = np.tile([0.0, 1.0, 0.0], (len(x), 1))
    return Stroke(points, normals, points + standoff_mm * normals, spray_on=True, on_part=np.ones(len(x), bool))


def test_a_stroke_that_would_wind_the_wrist_to_its_limit_starts_a_turn_back(monkeypatch):
    """Along line3's left side the sixth axis turns by 2.2 rad over a 3 m stroke. Followed from where a stroke
    before left that axis a whole turn up (the nearest turns, as a run of strokes winds it), it would come within
    ``WRIST_MARGIN_RAD`` of its limit (400 deg): ``solve_strokes`` follows it from that axis a turn back instead,
    the stroke's first try and the joints of the stroke solved on its own; kept wound, the first try runs into
    the limit and another try is taken."""
    from sprayplan.cells import plan as cell_plan

    left = load_cell("line3").robots[1]
    stroke = _along_the_side(1500.0, -1500.0)
    ((track, roll, q, reach),) = solve_strokes(left, [stroke])
    assert reach.all() and roll == ROLL_TRIES_DEG[0]
    upper = left.robot(0.0).joint_limits[5, 1]
    seed = q[0].copy()
    seed[5] += 2.0 * np.pi  # the same pose, the sixth axis a turn up
    assert seed[5] < upper and q[:, 5].max() + 2.0 * np.pi > upper - cell_plan.WRIST_MARGIN_RAD
    ((track1, roll1, q1, reach1),) = solve_strokes(left, [stroke], seed=seed)
    assert reach1.all() and roll1 == roll
    np.testing.assert_array_equal(track1, track)
    np.testing.assert_allclose(q1, q, atol=1e-9)  # unwound: the stroke as solved on its own
    assert upper - q1[:, 5].max() >= cell_plan.WRIST_MARGIN_RAD
    monkeypatch.setattr(cell_plan, "WRIST_MARGIN_RAD", -np.inf)  # never unwound
    ((_, roll2, q2, reach2),) = solve_strokes(left, [stroke], seed=seed)
    assert reach2.all() and not (roll2 == roll and np.allclose(q2, q1))  # another try, or the same one wound
    assert np.abs(q2[0] - seed).max() < np.abs(q1[0] - seed).max()  # nearer the wound seed, as it was
