"""Transfers in collision re-routed by the collision stage (``collision.transfers``): on a small synthetic
cell where the straight transfer between two spray strokes runs through a post standing on a plate."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

pytest.importorskip("coal")

from sprayplan.collision import transfers
from sprayplan.collision.cell import CellCollision
from sprayplan.collision.proof import motion_hits
from sprayplan.collision.repair import Repairer, collision_stage
from sprayplan.collision.transfers import Router, rrt_connect
from sprayplan.config import JobConfig
from sprayplan.paths.planner import transfer
from sprayplan.robots.gantry import build_gantry
from sprayplan.robots.stage import solve_strokes, station_plan
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import TRANSFER_REPAIRS, Part, Plan, Stroke

#: The transfer routes off (the waypoint repairs alone).
NO_ROUTES = {"retract_mm": [], "via_height_mm": None, "detour": False}

#: The gantry raised above the height the stations stage would give, so that the arm has room over the plate.
RAISE_MM = 450.0
BOX_FACES = np.array(
    [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7], [0, 4, 2],
     [2, 4, 6], [1, 3, 5], [3, 7, 5]]
)  # fmt: skip


def box(lo, hi):
    v = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])], float)
    return v, BOX_FACES


def plate_with_post(height_mm: float, x_mm: float = 0.0) -> Part:
    """An 800 x 500 mm plate (top at z = 0) with a 30 x 60 mm post of the given height at ``(x_mm, 0)``."""
    (v1, f1) = box([-400, -250, -20], [400, 250, 0])
    (v2, f2) = box([x_mm - 15, -30, 0], [x_mm + 15, 30, height_mm])
    return Part(np.vstack([v1, v2]), np.vstack([f1, f2 + 8]), name=f"plate, post {height_mm:g} mm")


def line_stroke(x0: float, x1: float, y: float = 0.0) -> Stroke:
    points = np.column_stack([np.linspace(x0, x1, 11), np.full(11, y), np.zeros(11)])
    normals = np.tile([0.0, 0.0, 1.0], (11, 1))
    return Stroke(points, normals, points + 113.0 * normals, True, np.ones(11, bool), 0)


@pytest.fixture(scope="module")
def gantry():
    return build_gantry("ur5")


def one_station(gantry, strokes) -> Plan:
    job = JobConfig()
    platform = gantry.platform_for(np.vstack([s.points for s in strokes])) + [0.0, 0.0, RAISE_MM]
    st = station_plan(0, platform, strokes, solve_strokes(gantry, strokes, platform, job.kinematics))
    assert st.reachable.all()
    return Plan((st,), platform, np.zeros((0, 3)))


@pytest.fixture(scope="module")
def plan(gantry):
    """One station: a stroke left of the post, the straight transfer over the plate, a stroke right of it."""
    a, b = line_stroke(-250.0, -150.0), line_stroke(150.0, 250.0)
    return one_station(gantry, (a, transfer(a, b, JobConfig().paths), b))


def dense_slack(cell: CellCollision, chain: np.ndarray, spacing_mm: float = 2.0) -> float:
    """The least exact slack (coal, every pair) along the joint-interpolated legs of ``chain``, checked at
    configurations no body point moves more than ``spacing_mm`` apart (an independent check of the proof)."""
    from sprayplan.collision.motion import motion_checks

    q = np.vstack([motion_checks(a, b, cell.reach_radii_mm, spacing_mm) for a, b in itertools.pairwise(chain)])
    return float(cell.distances(q).slack_mm.min())


def transfer_rows(st):
    start = len(st.strokes[0])
    return slice(start, start + len(st.strokes[1]))


def ends(st):
    """The joints the transfer joins: the first stroke's last and the last stroke's first."""
    return st.q9[len(st.strokes[0]) - 1], st.q9[len(st) - len(st.strokes[-1])]


def run(plan, gantry, height_mm, x_mm=0.0, **collision):
    whole = plate_with_post(height_mm, x_mm)
    job = JobConfig().replace(collision=collision) if collision else JobConfig()
    after, summary = collision_stage(plan, whole, job, gantry)
    return whole, job, after, summary


@pytest.mark.parametrize(
    "height_mm, settings, kind", [(150.0, {}, "retract"), (260.0, {"retract_mm": [50.0], "via_height_mm": 20.0}, "via")]
)
def test_a_colliding_transfer_is_rerouted_and_its_route_is_free_when_checked_densely(
    plan, gantry, height_mm, settings, kind
):
    whole, job, after, summary = run(plan, gantry, height_mm, **settings)
    cell = CellCollision(gantry, whole, job.collision)
    q_a, q_b = ends(plan.stations[0])
    assert dense_slack(cell, np.vstack([q_a, q_b])) < 0  # the straight move collides ...
    assert cell.check(plan.stations[0].q9[transfer_rows(plan.stations[0])]).in_collision.any()  # ... and the line
    st = after.stations[0]
    rows = transfer_rows(st)
    assert summary["transfers_in_collision"] == 1 and summary["transfers_rerouted_by"][kind] == 1
    assert summary["transfers_flagged"] == 0 and summary["flagged_motions"] == 0
    assert (st.repair[rows] == kind).all()
    assert not st.collision.any() and not st.motion_collision.any()
    # the route runs from the stroke before to the stroke after, and is free all along
    route = st.q9[rows]
    assert np.array_equal(route[0], q_a) and np.array_equal(route[-1], q_b)
    assert dense_slack(cell, route) >= 0
    # the strokes around it are kept, and the new transfer's waypoints are where its joints put the gun
    assert np.array_equal(st.strokes[0].tcp, plan.stations[0].strokes[0].tcp)
    assert np.array_equal(st.strokes[2].tcp, plan.stations[0].strokes[2].tcp)
    assert np.allclose(st.strokes[1].tcp, gantry.gun2world(route)[:, :3, 3], atol=1e-9)
    assert np.allclose(st.position_error_mm[rows], 0.0, atol=1e-6)


@pytest.fixture(scope="module")
def detoured(plan, gantry):
    """The post too high for the retracts, and the vias blocked by the gantry's column: a detour."""
    return run(plan, gantry, 300.0, detour_iterations=300)


def test_the_first_free_route_is_kept_in_order(plan, gantry, detoured):
    whole, job, after, summary = detoured
    assert summary["transfers_rerouted_by"]["detour"] == 1
    cell = CellCollision(gantry, whole, job.collision)
    router = Router(cell, whole)
    q_a, q_b = ends(plan.stations[0])
    tried = list(router.candidates(q_a, q_b))
    assert [k for k, _ in tried][:3] == ["retract"] * 3 and "via" in [k for k, _ in tried]
    for _, nodes in tried:  # every retract and via route before the detour really is in collision
        assert dense_slack(cell, np.vstack([q_a, nodes, q_b])) < 0
    route = after.stations[0].q9[transfer_rows(after.stations[0])]
    assert dense_slack(cell, route) >= 0
    assert dense_slack(cell, np.vstack([q_a, q_b])) < 0  # so not the straight joint move: the search's path
    assert len(route) > 2


def test_a_seeded_search_repeats_and_its_path_is_free():
    # a 2-D joint space with a wall from y = 0 to 0.8 at 0.4 < x < 0.6, walls checked exactly along each leg
    def states_free(q):
        q = np.atleast_2d(q)
        return ~((q[:, 0] > 0.4) & (q[:, 0] < 0.6) & (q[:, 1] < 0.8))

    def edges_free(a, b):
        s = np.linspace(0.0, 1.0, 201)[None, :, None]
        pts = a[:, None] + s * (b - a)[:, None]
        return states_free(pts.reshape(-1, 2)).reshape(len(a), -1).all(axis=1)

    args = ([0.1, 0.1], [0.9, 0.1], np.zeros(2), np.ones(2), states_free, edges_free, np.ones(2), 0.1, 500)
    first = rrt_connect(*args, np.random.default_rng(4))
    again = rrt_connect(*args, np.random.default_rng(4))
    other = rrt_connect(*args, np.random.default_rng(5))
    assert first is not None and np.array_equal(first, again)
    assert other is not None and not (len(other) == len(first) and np.array_equal(other, first))
    assert np.array_equal(first[0], [0.1, 0.1]) and np.array_equal(first[-1], [0.9, 0.1])
    assert states_free(first).all() and edges_free(first[:-1], first[1:]).all()


@pytest.mark.parametrize("seed", range(6))
def test_shortcut_keeps_the_farthest_free_node_as_checking_every_leg_would(seed):
    # a winding 2-D path among three walls; legs checked exactly; the reference checks every later leg
    walls = [(0.2, 0.3, 0.0, 0.7), (0.45, 0.55, 0.3, 1.0), (0.7, 0.8, 0.0, 0.7)]

    def states_free(q):
        q = np.atleast_2d(q)
        inside = [(q[:, 0] > x0) & (q[:, 0] < x1) & (q[:, 1] > y0) & (q[:, 1] < y1) for x0, x1, y0, y1 in walls]
        return ~np.any(inside, axis=0)

    checked = []

    def edges_free(a, b):
        checked.append(len(a))
        s = np.linspace(0.0, 1.0, 401)[None, :, None]
        pts = a[:, None] + s * (b - a)[:, None]
        return states_free(pts.reshape(-1, 2)).reshape(len(a), -1).all(axis=1)

    args = ([0.1, 0.1], [0.9, 0.1], np.zeros(2), np.ones(2), states_free, edges_free, np.ones(2), 0.03, 3000)
    path = rrt_connect(*args, np.random.default_rng(seed))
    assert path is not None and len(path) > 20
    checked.clear()
    short = transfers.shortcut(path, edges_free)
    calls = sum(checked)
    out, i = [0], 0
    while i < len(path) - 1:
        later = np.arange(i + 1, len(path))
        ok = edges_free(np.repeat(path[i][None], len(later), axis=0), path[later])
        i = int(later[np.flatnonzero(ok)[-1]])
        out.append(i)
    assert np.array_equal(short, path[out])
    assert edges_free(short[:-1], short[1:]).all() and len(short) < len(path)
    assert calls < sum(len(path) - 1 - k for k in out[:-1])  # fewer legs checked than the reference


def test_unwound_takes_out_whole_turns_only_within_the_limits(gantry):
    from sprayplan.collision.repair import unwound
    from sprayplan.robots.model import TAU

    robot = gantry.robot
    q_a = np.array([0.1, -1.0, 1.5, -0.5, 1.0, 0.2, 0.0, 0.0, 900.0])
    after = np.tile(q_a, (3, 1)) + [[0.0, 0.0, 0.0, TAU, 0.0, -TAU + 0.05, 0.0, 0.0, 0.0]]
    turns = unwound(robot, q_a, after)
    assert np.array_equal(turns, [0.0, 0.0, 0.0, -TAU, 0.0, TAU, 0.0, 0.0, 0.0])
    assert np.allclose(after[0] + turns, q_a + [0.0, 0.0, 0.0, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0])
    assert unwound(robot, q_a, after + [0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0]) is not None
    assert unwound(robot, q_a, np.tile(q_a, (2, 1))) is None  # nothing to take out
    beyond = after.copy()
    beyond[1, 5] = robot.upper[5] - 0.5 * TAU  # this row would leave the limits shifted by a whole turn
    assert unwound(robot, q_a, beyond) is None


def test_a_transfer_that_turns_a_joint_round_is_unwound(plan, gantry):
    """The stroke after the transfer given its shoulder a whole turn on (the same poses): the transfer's move then
    swings the arm round through the plate; the stage takes the turn back out and routes the
    transfer. (The elbow cannot take a whole turn: its limits are +-pi.)"""
    from sprayplan.robots.model import TAU

    st = plan.stations[0]
    after = slice(len(st) - len(st.strokes[-1]), len(st))
    q9 = st.q9.copy()
    q9[after, 1] += -TAU if q9[after, 1].max() > 0 else TAU
    assert gantry.robot.within_limits(q9[:, :6]).all()
    assert np.allclose(gantry.target2world(q9), gantry.target2world(st.q9), atol=1e-9)  # the same poses
    whirled = Plan((dataclasses.replace(st, q9=q9),), plan.home_mm, plan.unassigned)
    whole = plate_with_post(1.0)
    job = JobConfig()
    _, summary = collision_stage(plan, whole, job, gantry)
    assert summary["transfers_in_collision"] == 0  # as planned, the transfer is free
    result, summary = collision_stage(whirled, whole, job, gantry)
    assert summary["transfers_in_collision"] == 1 and summary["transfers_unwound"] == 1
    assert summary["transfers_flagged"] == 0 and summary["flagged_motions"] == 0
    new = result.stations[0]
    # the stroke after has its shoulder back where the plan had it, and every spray waypoint keeps its pose
    np.testing.assert_allclose(new.q9[len(new) - len(new.strokes[-1]) :], st.q9[after], atol=1e-12)
    np.testing.assert_array_equal(new.q9[: len(st.strokes[0])], st.q9[: len(st.strokes[0])])


def test_the_motion_flags_after_unwinding_are_the_plans_own(plan, gantry):
    """After whole turns are taken out (rows shifted, transfers routed), every motion flag the stage writes is
    what checking the written plan from scratch gives: no shift leaves a stale flag on a move it changed."""
    from sprayplan.collision.repair import _Station, flag_motions
    from sprayplan.robots.model import TAU

    st = plan.stations[0]
    after = slice(len(st) - len(st.strokes[-1]), len(st))
    q9 = st.q9.copy()
    q9[after, 1] += -TAU if q9[after, 1].max() > 0 else TAU
    whirled = Plan((dataclasses.replace(st, q9=q9),), plan.home_mm, plan.unassigned)
    whole = plate_with_post(1.0)
    job = JobConfig()
    result, summary = collision_stage(whirled, whole, job, gantry)
    assert summary["transfers_unwound"] == 1
    cell = CellCollision(gantry, whole, job.collision)
    works = []
    for new in result.stations:
        work = _Station.of(new)
        work.check(cell)
        works.append(work)
    flags, _, _ = flag_motions(cell, works)
    for new, fresh in zip(result.stations, flags):
        np.testing.assert_array_equal(new.motion_collision, fresh)


def test_the_stage_with_a_detour_repeats(plan, gantry, detoured):
    _, _, a, summary_a = detoured
    _, _, b, summary_b = run(plan, gantry, 300.0, detour_iterations=300)
    assert summary_a == summary_b
    assert np.array_equal(a.stations[0].q9, b.stations[0].q9)


def test_what_no_route_frees_stays_flagged(plan, gantry):
    # a post up to the gantry; the waypoint repairs' raised station, the vias (tried and found in collision
    # in test_the_first_free_route_is_kept_in_order) and the search kept short (time)
    settings = {"platform_raise_mm": 0.0, "retract_mm": [200.0], "via_height_mm": None, "detour_iterations": 5}
    _, _, after, summary = run(plan, gantry, 2000.0, **settings)
    st = after.stations[0]
    assert summary["transfers_in_collision"] == 1 and summary["transfers_flagged"] == 1
    assert summary["transfers_rerouted"] == 0
    assert [len(s) for s in st.strokes] == [len(s) for s in plan.stations[0].strokes]
    assert not set(st.repair) & set(TRANSFER_REPAIRS)
    assert (st.collision | st.motion_collision)[transfer_rows(st)].any()
    assert summary["flagged_motions"] == int(st.motion_collision.sum()) > 0


def test_a_transfer_whose_end_is_in_collision_is_flagged_without_a_search(gantry, monkeypatch):
    # a post under the end of the first stroke: its last waypoints stay in collision, so no route can help
    a, b = line_stroke(-250.0, -150.0), line_stroke(150.0, 250.0)
    plan = one_station(gantry, (a, transfer(a, b, JobConfig().paths), b))

    def no_search(*args, **kwargs):
        raise AssertionError("searched for a detour from a waypoint in collision")

    monkeypatch.setattr(transfers, "rrt_connect", no_search)
    settings = {"platform_raise_mm": 0.0, "retract_mm": [50.0], "via_height_mm": None}
    whole, job, after, summary = run(plan, gantry, 300.0, **settings, x_mm=-150.0)
    st = after.stations[0]
    assert st.collision[len(a) - 1]
    assert summary["transfers_in_collision"] == 1 and summary["transfers_end_in_collision"] == 1
    assert summary["transfers_flagged"] == 1 and summary["transfers_rerouted"] == 0
    assert [len(s) for s in st.strokes] == [len(s) for s in plan.stations[0].strokes]
    # the router itself gives up at once on an end in collision
    cell = CellCollision(gantry, whole, job.collision)
    q_a, q_b = ends(st)
    assert cell.check(q_a).in_collision[0]
    assert Router(cell, whole).route(q_a, q_b) is None


def test_a_rerouted_transfer_leaves_the_rest_of_its_station_as_it_was(gantry):
    # a, a transfer over the post (re-routed), b, a transfer clear of it, c; b's speeds tuned (dwell)
    job = JobConfig()
    a, b = line_stroke(-250.0, -150.0), line_stroke(150.0, 250.0).with_dwell(np.linspace(1.0, 2.0, 11))
    c = line_stroke(250.0, 150.0, y=120.0)
    plan = one_station(gantry, (a, transfer(a, b, job.paths), b, transfer(b, c, job.paths), c))
    _, _, after, summary = run(plan, gantry, 150.0)
    before, st = plan.stations[0], after.stations[0]
    assert summary["transfers_rerouted"] == 1 and summary["transfers_in_collision"] == 1
    assert st.strokes[0] is before.strokes[0] and all(x is y for x, y in zip(st.strokes[2:], before.strokes[2:]))
    assert np.array_equal(st.strokes[2].dwell, b.dwell)
    # rows after the route: shifted by its change of length, otherwise as planned unless a waypoint repair
    # changed them (their pose errors then measured again, against the same poses)
    shift = len(st.strokes[1]) - len(before.strokes[1])
    start = len(a) + len(before.strokes[1])
    old, new = np.arange(len(a)), np.arange(len(a))
    old, new = np.r_[old, np.arange(start, len(before))], np.r_[new, np.arange(start, len(before)) + shift]
    assert len(st) == len(before) + shift
    kept = st.repair[new] == ""
    assert kept.sum() >= len(c) + len(before.strokes[3])
    for name in ("q9", "position_error_mm", "axis_error_deg", "reachable", "method", "branch_change"):
        assert np.array_equal(getattr(st, name)[new][kept], getattr(before, name)[old][kept]), name
    assert np.isfinite(st.position_error_mm[st.reachable]).all()


def test_a_stroke_whose_only_problem_is_a_motion_is_repaired_within_the_seed_tolerance(plan, gantry):
    # the last stroke's waypoints all free, but its second half on another branch: the switch between two
    # waypoints sweeps the arm through the cell
    job = JobConfig().replace(collision=NO_ROUTES)
    whole = plate_with_post(150.0)
    cell = CellCollision(gantry, whole, job.collision)
    st = plan.stations[0]
    b = st.strokes[2]
    rows = np.arange(len(st) - len(b), len(st))
    q9 = np.array(st.q9)
    repairer = Repairer(cell, gantry, job.kinematics, job.collision)
    others = [
        q
        for kind, q in repairer.candidates(stroke_poses(b), st.platform_mm, q9[rows[0], :6], np.arange(len(b)))
        if kind == "branch"
    ]
    switch = next(q for q in others if not cell.check(q).in_collision.any() and motion_hits(cell, q9[rows[5]], q[6])[0])
    q9[rows[6:]] = switch[6:]
    broken = Plan((dataclasses.replace(st, q9=q9),), plan.home_mm, plan.unassigned)
    assert not cell.check(q9[rows]).in_collision.any()
    after, summary = collision_stage(broken, whole, job, gantry)
    fixed = after.stations[0]
    assert summary["flagged_motions_before_reroute"] >= 1
    assert summary["motions_repaired"] >= 1
    assert summary["motions_repaired"] == sum(summary["motions_repaired_by"].values())
    assert not fixed.motion_collision[rows[1:]].any()
    # the motions checked again after the repair (those with a moved end) and called free are free
    moved = np.flatnonzero((fixed.q9 != q9).any(axis=1))
    legs = np.unique(np.concatenate([moved - 1, moved]))
    legs = legs[(legs >= 0) & (legs + 1 < len(q9))]
    legs = legs[~fixed.motion_collision[legs + 1]]
    assert len(moved) and len(legs) >= len(moved)
    assert min(dense_slack(cell, fixed.q9[[k, k + 1]]) for k in legs) >= 0
    assert not motion_hits(cell, fixed.q9[rows[:-1]], fixed.q9[rows[1:]]).any()
    assert not cell.check(fixed.q9[rows]).in_collision.any()
    assert set(fixed.repair[rows][fixed.repair[rows] != ""]) <= {"branch", "roll", "tilt"}
    assert fixed.repair[rows[6]] != ""
    # the stroke's poses still within the seed's tolerances
    assert (fixed.position_error_mm[rows] <= job.kinematics.position_tol_mm).all()
    assert (fixed.axis_error_deg[rows] <= job.kinematics.axis_tol_deg).all()
