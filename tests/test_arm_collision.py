"""Collision checks of a cell's industrial arms (collision.arms): the bodies follow the kinematics, distances
agree with an independent computation, motions are sampled finely enough, and two robots' swept spaces are
bounded from below (issue 18: no collisions, the robots of a line kept apart in space)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from sprayplan.cells.spec import cell_from_dict
from sprayplan.collision.arms import (
    ARM_BODIES,
    ArmCollision,
    arm_radii,
    check_robot,
    opw_points,
    separation,
    swept_points,
)
from sprayplan.errors import ConfigError
from sprayplan.robots.opw import PRESETS, load_opw, opw_fk
from sprayplan.surface.poses import poses_at
from tests.helpers import grid_box

pytest.importorskip("coal")

CELL = {
    "name": "two",
    "robot": [
        {
            "name": "left",
            "model": "abb-irb2400-10",
            "tool": "wa101",
            "base_mm": [0.0, 1000.0, 0.0],
            "base_rpy_deg": [0.0, 0.0, -90.0],
            "track": {"axis": "x", "range_mm": [-400.0, 400.0]},
        },
        {
            "name": "right",
            "model": "abb-irb2400-10",
            "tool": "wa101",
            "base_mm": [0.0, -1000.0, 0.0],
            "base_rpy_deg": [0.0, 0.0, 90.0],
        },
    ],
}


def _random_q(params, n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(np.maximum(params.lower, -np.pi), np.minimum(params.upper, np.pi), size=(n, 6))


def _segment_distance(tree, a, b):
    """The distance of the segment a-b to a point set (its k-d tree), over points 0.5 mm apart on the segment."""
    t = np.linspace(0.0, 1.0, max(2, int(np.linalg.norm(b - a) / 0.5) + 1))
    return tree.query(a + t[:, None] * (b - a))[0].min()


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_the_bodies_chain_ends_at_the_wrist_centre_and_the_flange_of_the_kinematics(name):
    """opw_points' wrist centre is the flange less c4 along its z axis, by opw_fk; every body's length is the
    OPW length it stands for, whatever the joints."""
    params = load_opw(name)
    q = _random_q(params, 200, 1)
    points = opw_points(params, q)
    flange = opw_fk(params, q)
    centre = flange[:, :3, 3] - params.c4 * flange[:, :3, 2]
    np.testing.assert_allclose(points[:, 5], centre, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(points[:, 3] - points[:, 2], axis=1), params.c2, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(points[:, 4] - points[:, 3], axis=1), abs(params.a2), rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(points[:, 5] - points[:, 4], axis=1), params.c3, rtol=1e-12)
    # the forearm's offset is square to the forearm
    np.testing.assert_allclose(
        np.einsum("ij,ij->i", points[:, 4] - points[:, 3], points[:, 5] - points[:, 4]), 0.0, atol=1e-6
    )


def _arm(part, floor=-1000.0, robot=0):
    cell = cell_from_dict(CELL)
    return cell.robots[robot], ArmCollision(cell.robots[robot], part, floor, clearance_mm=30.0)


def test_segments_are_in_the_cell_frame_at_the_track_position():
    """The gun segment starts at the flange of the arm's own FK at its base and track position."""
    part = grid_box(n=4, size=(400.0, 400.0, 400.0))
    cell_robot, arm = _arm(part)
    q = _random_q(arm.params, 20, 2)
    track = np.linspace(-400, 400, 20)
    segments = arm.segments(q, track)
    for i in range(len(q)):
        robot = cell_robot.robot(float(track[i]))
        tcp = robot.fk(q[i])[0]
        flange = tcp @ np.linalg.inv(robot.tcp2flange)
        np.testing.assert_allclose(segments[i, 6, 0], flange[:3, 3], atol=1e-9)
    np.testing.assert_allclose(arm.tcp(q, track)[3], cell_robot.robot(float(track[3])).fk(q[3])[0][:3, 3], atol=1e-9)


def test_the_distance_to_the_part_is_the_capsules_own():
    """For configurations near a box, the checked distance of the body that comes nearest equals the distance
    of that capsule to the box's surface computed here by brute force (the box's surface points)."""
    part = grid_box(n=20, size=(600.0, 600.0, 600.0))
    _cell_robot, arm = _arm(part)
    q = _random_q(arm.params, 3000, 3)
    found = arm.check(q, np.zeros(len(q)))
    segments = arm.segments(q, np.zeros(len(q)))
    rng = np.random.default_rng(0)
    # dense points on the box's surface
    face = rng.integers(0, len(part.faces), 200_000)
    w = rng.dirichlet(np.ones(3), 200_000)
    surface = np.einsum("nk,nkd->nd", w, part.vertices[part.faces[face]])
    tree = cKDTree(surface)
    inside = np.all(np.abs(segments.reshape(-1, 3)) < 300.0, axis=1).reshape(len(q), -1).any(axis=1)
    near = np.flatnonzero((found.other == "part") & (found.distance_mm < 45.0) & (found.distance_mm > 0) & ~inside)[:8]
    assert len(near) >= 3, "the random configurations should bring some arm near the box"
    for i in near:
        b = found.body[i]
        a, e = segments[i, b]
        brute = _segment_distance(tree, a, e) - arm.radii[b]
        assert found.distance_mm[i] == pytest.approx(brute, abs=3.0)
    free = np.flatnonzero(~found.collides)
    assert len(free) > 10
    for i in free[:20]:
        gaps = [_segment_distance(tree, *segments[i, b]) - arm.radii[b] for b in range(1, 7)]
        assert min(gaps) > arm.clearance_mm - 3.0


def test_the_floor_counts_every_body_but_the_base():
    part = grid_box(n=4, size=(200.0, 200.0, 200.0))
    part = type(part)(part.vertices + [0.0, 0.0, 2000.0], part.faces, name="high box")
    _cell_robot, arm = _arm(part, floor=0.0)
    q = _random_q(arm.params, 300, 4)
    found = arm.check(q, np.zeros(len(q)))
    segments = arm.segments(q, np.zeros(len(q)))
    lowest = (segments[..., 2].min(axis=2) - arm.radii)[:, 1:].min(axis=1)
    tcp = arm.tcp(q, np.zeros(len(q)))[:, 2]
    expected = (lowest < 0.0) | (tcp < 0.0)
    assert expected.any() and (~expected).any()
    np.testing.assert_array_equal(found.collides, expected)


def test_the_yes_no_check_gives_the_full_checks_answers():
    """``ArmCollision.collides`` (the repairs' screen: floor first, then only the bodies bounded below the
    clearance, a row done at its first hit) answers as ``check(...).collides`` does, part and floor alike."""
    part = grid_box(n=10, size=(600.0, 600.0, 600.0))
    part = type(part)(part.vertices + [0.0, 0.0, 400.0], part.faces, name="raised box")
    _cell_robot, arm = _arm(part, floor=0.0)
    q = _random_q(arm.params, 2000, 11)
    track = np.random.default_rng(12).uniform(-400.0, 400.0, len(q))
    full = arm.check(q, track)
    np.testing.assert_array_equal(arm.collides(q, track), full.collides)
    kinds = set(full.other[full.collides])
    assert {"part", "floor"} <= kinds and (~full.collides).sum() > 50


def test_screened_repairs_are_the_repairs_of_the_whole_search(tmp_path, monkeypatch):
    """Screening the candidates in batches drops only candidates the full check would refuse: the repaired
    joints, track positions, rolls and counts are the same as without the screen."""
    import sprayplan.cells.plan as cells_plan
    from sprayplan.cells.collide import check_cell
    from sprayplan.config import JobConfig

    _, plan, _ = _box_cell(tmp_path)  # a box on which a stroke in collision has a free try
    config = JobConfig().collision
    screened, report = check_cell(plan, config, cells_plan.repaired_work)
    import sprayplan.cells.repair as cells_repair

    monkeypatch.setattr(cells_repair, "_screened", lambda arm, ordered, colliding: ordered)
    whole, report_whole = check_cell(plan, config, cells_plan.repaired_work)
    assert report == report_whole
    assert sum(r["strokes_repaired"] for r in report["robots"].values()) >= 1
    for a, b in zip(screened, whole):
        for name in ("q", "track_mm", "roll_deg", "reachable", "collides"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_motions_are_checked_at_most_one_step_apart():
    """Between consecutive configurations of a motion's grid (waypoints included) no body end moves more than
    the motion step."""
    part = grid_box(n=4, size=(200.0, 200.0, 200.0))
    _cell_robot, arm = _arm(part)
    rng = np.random.default_rng(5)
    q = np.cumsum(rng.normal(0, 0.05, (30, 6)), axis=0)
    track = np.cumsum(rng.normal(0, 20.0, 30))
    reachable = np.ones(30, bool)
    reachable[10] = False
    joints, tracks, owner = arm.motion_configs(q, track, reachable)
    assert 9 not in owner and 10 not in owner
    for i in np.unique(owner):
        configs = np.concatenate([q[i : i + 1], joints[owner == i], q[i + 1 : i + 2]])
        t = np.concatenate([track[i : i + 1], tracks[owner == i], track[i + 1 : i + 2]])
        ends = arm.segments(configs, t)
        moved = np.linalg.norm(np.diff(ends, axis=0), axis=-1).max()
        assert moved <= arm.motion_step_mm + 1e-9


def _arm_over_box():
    """The first robot of :data:`CELL` with a 300 mm box within its reach."""
    part = grid_box(n=6, size=(300.0, 300.0, 300.0))
    return _arm(type(part)(part.vertices + [0.0, 150.0, 1300.0], part.faces, name="box in reach"))[1]


def test_the_slack_proof_flags_the_same_motions_as_the_whole_grid():
    """Leaving out the configurations a waypoint's slack proves free flags the same motions as checking every
    configuration of every motion's grid, and checks far fewer; an unreached waypoint is not checked."""
    arm = _arm_over_box()
    rng = np.random.default_rng(7)
    q = np.cumsum(rng.normal(0, 0.04, (120, 6)), axis=0) + [0.0, 0.0, 0.0, 0.0, 0.3, 0.0]
    track = np.cumsum(rng.normal(0, 10.0, 120))
    reachable = np.ones(120, bool)
    reachable[40] = False
    result = check_robot(arm, q, track, reachable)
    joints, tracks, owner = arm.motion_configs(q, track, reachable)
    full = np.zeros(119, bool)
    full[np.unique(owner[arm.check(joints, tracks).collides])] = True
    ends = result.waypoint.collides
    full |= ends[:-1] | ends[1:]
    assert full.any() and (~full).sum() > 20
    np.testing.assert_array_equal(result.motion_collides, full)
    assert result.motion_checked < len(joints) / 2
    assert np.isnan(result.waypoint.slack_mm[40]) and not result.waypoint.collides[40]


def test_the_yes_no_plan_check_gives_check_robots_answer():
    """``plan_collides`` (the repairs' test of a try) answers as ``check_robot`` does (any waypoint or motion
    in collision), on plans free, hit at a waypoint, and hit only between waypoints; its slacks are lower bounds
    on the full check's."""
    from sprayplan.collision.arms import plan_collides

    arm = _arm_over_box()
    rng = np.random.default_rng(7)
    q = np.cumsum(rng.normal(0, 0.04, (400, 6)), axis=0) + [0.0, 0.0, 0.0, 0.0, 0.3, 0.0]
    track = np.cumsum(rng.normal(0, 10.0, 400))
    reachable = rng.random(400) > 0.05
    full = arm.check(q, track)
    bound = arm.slack_bound(q, track)
    assert np.all(bound <= full.slack_mm + 1e-9)
    # plans along the walk (free, or hit at a waypoint), and plans of three free configurations near the box
    # far apart in joints (their motions cross it)
    plans = [(q[i : i + 9], track[i : i + 9], reachable[i : i + 9]) for i in range(0, 392, 8)]
    pool = _random_q(arm.params, 600, 21)
    pool_found = arm.check(pool, np.zeros(len(pool)))
    near = np.flatnonzero(~pool_found.collides & (pool_found.slack_mm < 150.0))
    for _ in range(12):
        rows = rng.choice(near, 3, replace=False)
        plans.append((pool[rows], np.zeros(3), np.ones(3, bool)))
    kinds = {"free": 0, "waypoint": 0, "motion only": 0}
    for plan_q, plan_track, plan_reached in plans:
        found = check_robot(arm, plan_q, plan_track, plan_reached)
        expected = bool(found.waypoint.collides.any() or found.motion_collides.any())
        assert plan_collides(arm, plan_q, plan_track, plan_reached) == expected
        kind = "waypoint" if found.waypoint.collides.any() else ("motion only" if expected else "free")
        kinds[kind] += 1
    assert all(count >= 2 for count in kinds.values()), kinds


def test_separation_is_a_lower_bound_close_to_the_true_gap():
    """Two robots' swept spaces: the bound is below the least gap between any two of their capsules (brute
    force over every pair of configurations), and within the bound's own error of it."""
    part = grid_box(n=4, size=(200.0, 200.0, 200.0))
    _, left = _arm(part, robot=0)
    _, right = _arm(part, robot=1)
    rng = np.random.default_rng(6)
    qa = np.cumsum(rng.normal(0, 0.02, (15, 6)), axis=0) + [0.0, 0.3, 0.0, 0.0, 0.5, 0.0]
    qb = np.cumsum(rng.normal(0, 0.02, (15, 6)), axis=0) + [0.0, 0.3, 0.0, 0.0, 0.5, 0.0]
    ta, tb = np.zeros(15), np.zeros(15)
    ok = np.ones(15, bool)
    sa, sb = swept_points(left, qa, ta, ok), swept_points(right, qb, tb, ok)
    bound = separation(sa, sb)
    seg_a, seg_b = left.segments(qa, ta), right.segments(qb, tb)
    t = np.linspace(0, 1, 60)
    pa = (seg_a[..., :1, :] + t[:, None] * (seg_a[..., 1:, :] - seg_a[..., :1, :])).reshape(15, 7, -1, 3)
    pb = (seg_b[..., :1, :] + t[:, None] * (seg_b[..., 1:, :] - seg_b[..., :1, :])).reshape(15, 7, -1, 3)
    true = np.inf
    for i in range(7):
        for j in range(7):
            a = pa[:, i].reshape(-1, 3)
            b = pb[:, j].reshape(-1, 3)
            d = np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1)).min()
            true = min(true, d - left.radii[i] - right.radii[j])
    assert bound <= true
    assert true - bound <= sa[2] + sb[2] + 2 * 25.0 * np.sqrt(3) + 5.0
    # the same robot against itself has no gap
    assert separation(sa, sa) < 0


def test_an_arm_without_link_sizes_is_refused():
    with pytest.raises(ConfigError, match="no link sizes"):
        arm_radii("my-arm")
    assert len(arm_radii("abb-irb4600-60-205")) == len(ARM_BODIES)


def test_a_cell_plan_with_collisions_flags_each_waypoint_as_its_own_check_does(tmp_path):
    """`sprayplan plan --cell FILE --collisions`: cell_plan.json, waypoints.csv and the report carry the same
    flags, and they are the flags of each robot's joints read back and checked again here."""
    import csv

    from sprayplan.cells import load_cell
    from sprayplan.cells.files import read_cell_plan
    from sprayplan.cli import main
    from sprayplan.export.stl import write_stl_binary
    from sprayplan.io.load import load_part
    from tests.test_cell_plan import CELL as SMALL_CELL

    cell_file = tmp_path / "small2.toml"
    cell_file.write_text(SMALL_CELL)
    part_file = tmp_path / "box.stl"
    size = (700.0, 200.0, 250.0)  # a box on which a stroke in collision has a free try
    part_file.write_bytes(write_stl_binary(grid_box(n=8, size=size).triangles))
    out = tmp_path / "out"
    assert main(["-q", "plan", str(part_file), "--cell", str(cell_file), "--collisions", "-o", str(out)]) == 0
    plan = read_cell_plan(out / "cell_plan.json")
    report = plan["report"]["collisions"]
    rows = list(csv.DictReader(open(out / "waypoints.csv")))
    cell = load_cell(cell_file)
    part = load_part(str(part_file))
    placed = type(part)(part.vertices @ plan["part"]["part2cell"][:3, :3].T + plan["part"]["part2cell"][:3, 3],
                        part.faces, name="placed")  # fmt: skip
    total = 0
    for robot, work in zip(cell.robots, plan["robots"]):
        q = np.concatenate([s["q_rad"] for s in work["strokes"]])
        track = np.concatenate([s["track_mm"] for s in work["strokes"]])
        ok = np.concatenate([s["reachable"] for s in work["strokes"]])
        flags = np.concatenate([s["collides"] for s in work["strokes"]])
        arm = ArmCollision(robot, placed, cell.floor_z_mm)
        again = check_robot(arm, q, track, ok)
        np.testing.assert_array_equal(flags, again.waypoint.collides)
        assert report["robots"][work["name"]]["waypoints_in_collision"] == int(flags.sum())
        assert report["robots"][work["name"]]["waypoints_checked"] == int(ok.sum())
        csv_flags = np.array([int(r["collides"]) for r in rows if r["robot"] == work["name"]], bool)
        np.testing.assert_array_equal(csv_flags, flags)
        total += int(flags.sum())
        # cut to what the arm paints free before the film: every spray waypoint reached and free
        spray = np.concatenate([np.full(len(st["tcp_mm"]), st["kind"] != "transfer") for st in work["strokes"]])
        assert spray.any() and ok[spray].all() and not flags[spray].any()
        # the schedule's times: in both files, each stroke's wait before it, the cycle the longest robot's
        t_s = np.concatenate([st["t_s"] for st in work["strokes"]])
        csv_t = np.array([float(r["t_s"]) for r in rows if r["robot"] == work["name"]])
        np.testing.assert_allclose(csv_t, t_s, atol=1e-6)
        assert np.all(np.diff(t_s) >= -1e-9)
        assert t_s[-1] <= plan["report"]["cycle_time_s"] + 1e-3  # the report rounds to ms
        mine = plan["report"]["robots"][work["name"]]
        assert t_s[-1] <= mine["cycle_time_s"] + 1e-3 and mine["cycle_time_s"] >= mine["length_over_speed_s"] - 1e-3
        waited = sum(st["wait_s"] for st in work["strokes"])
        assert plan["report"]["schedule"]["waits"][work["name"]]["waited_s"] == pytest.approx(waited, abs=1e-3)
        # the repairs' joints still put the gun where the stroke wants it, at the waypoint's track and roll
        for st in work["strokes"]:
            good = st["reachable"]
            if good.any():
                want = poses_at(st["tcp_mm"][good], st["normals"][good]) @ _rolls(st["roll_deg"][good])
                got = np.stack([robot.robot(t).fk(j[None])[0] for t, j in zip(st["track_mm"][good], st["q_rad"][good])])
                np.testing.assert_allclose(got[:, :3, 3], want[:, :3, 3], atol=1e-6)
                np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], atol=1e-9)
    repaired = report["robots"]["left"]["strokes_repaired"]
    assert 1 <= repaired <= report["robots"]["left"]["strokes_in_collision"]
    # runs still in collision after the repairs: left out, or solved on their own (the gun tilted if need be)
    resolved = sum(r["waypoints_resolved"] for r in report["robots"].values())
    assert report["left_out_waypoints"]["left_out_in_collision"] + resolved > 0
    assert report["waypoints_in_collision"] == total
    gap = report["robot_gap_mm"]["left-right"]
    assert (gap > 0) == (report["robots_kept_apart"].startswith("in space"))
    # what the collision step took from each area: what is kept is the plan's spray path over that area
    kept = report["areas"]
    assert list(kept) == [a["name"] for a in plan["areas"]]
    for k, entry in enumerate(kept.values()):
        path = 0.0
        for work in plan["robots"]:
            for st in work["strokes"]:
                if st["kind"] == "spray" and st["area"] == k:
                    steps = np.linalg.norm(np.diff(st["points_mm"], axis=0), axis=1)
                    good = st["reachable"]
                    path += float(steps[good[:-1] & good[1:]].sum())
        assert entry["kept_mm"] == pytest.approx(path, abs=0.1)
        assert 0.0 < entry["kept_mm"] <= entry["spray_path_mm"] and entry["kept_share"] == pytest.approx(
            entry["kept_mm"] / entry["spray_path_mm"], abs=1e-4
        )


def test_collisions_asked_for_an_arm_without_link_sizes_is_one_line_and_no_output(tmp_path, capsys):
    """`plan --robot ur5 --collisions`: refused before planning, exit 2, one line naming the robot, no folder."""
    from sprayplan.cli import main
    from sprayplan.export.stl import write_stl_binary

    part_file = tmp_path / "box.stl"
    part_file.write_bytes(write_stl_binary(grid_box(n=4, size=(300.0, 300.0, 100.0)).triangles))
    out = tmp_path / "out"
    assert main(["-q", "plan", str(part_file), "--robot", "ur5", "--collisions", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'ur5' has no link sizes" in err[0]
    assert not out.exists()


def _box_cell(tmp_path, size=(700.0, 200.0, 250.0)):
    """The small two-robot cell of ``tests.test_cell_plan`` planned (no collision check) over a box of ``size``
    (the default: a box on which some strokes collide and some have a free try): ``(cell, plan, arms)``."""
    import sprayplan.cells.plan as cells_plan
    from sprayplan.cells import load_cell
    from sprayplan.cells.collide import cell_arms
    from sprayplan.config import JobConfig
    from tests.test_cell_plan import CELL as SMALL_CELL

    cell_file = tmp_path / "small2.toml"
    cell_file.write_text(SMALL_CELL)
    cell = load_cell(cell_file)
    plan = cells_plan.plan_cell(grid_box(n=8, size=size), cell, JobConfig())
    return cell, plan, cell_arms(plan.cell, plan.part, JobConfig().collision)


def _rolls(deg) -> np.ndarray:
    """(n, 4, 4): turns about z by ``deg`` (n,) degrees."""
    c, s_ = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    out = np.broadcast_to(np.eye(4), (len(c), 4, 4)).copy()
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s_, s_, c
    return out


def test_a_plan_cut_to_its_free_runs_paints_only_where_the_arm_is_free(tmp_path):
    """``free_work``: every spray waypoint it keeps is reached and free and every motion inside a spray stroke
    is free; each kept stroke is a run of its stroke's waypoints; kept and left out add up to the spray
    waypoints there were; each transfer is the joint move from the end of one run to the start of the next."""
    from sprayplan.cells.repair import free_work

    _, plan, arms = _box_cell(tmp_path)
    work, arm = plan.robots[0], arms[0]
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    assert found.waypoint.collides.any() and (~work.reachable).any()
    freed, counts = free_work(work, found)
    again = check_robot(arm, freed.q, freed.track_mm, freed.reachable)
    starts = np.r_[0, np.cumsum([len(s) for s in freed.strokes])]
    spray = np.concatenate([np.full(len(s), s.spray_on) for s in freed.strokes])
    assert freed.reachable.all() and not again.waypoint.collides[spray].any()
    old_tcp = {i: s.tcp for i, s in enumerate(work.strokes) if s.spray_on}
    for i, s in enumerate(freed.strokes):
        a, b = starts[i], starts[i + 1]
        if s.spray_on:
            assert len(s) >= 2 and not again.motion_collides[a : b - 1].any()
            # a run of one of the stroke's own waypoints, in order
            assert any(np.array_equal(tcp[k : k + len(s)], s.tcp) for tcp in old_tcp.values() for k in range(len(tcp)))
        else:
            assert len(s) == 2 and freed.strokes[i - 1].spray_on and freed.strokes[i + 1].spray_on
            np.testing.assert_array_equal(freed.q[a], freed.q[a - 1])
            np.testing.assert_array_equal(freed.q[b - 1], freed.q[b])
            np.testing.assert_array_equal(s.tcp, [freed.strokes[i - 1].tcp[-1], freed.strokes[i + 1].tcp[0]])
    was_spray = np.concatenate([np.full(len(s), s.spray_on) for s in work.strokes])
    assert counts["left_out_in_collision"] == int((found.waypoint.collides & work.reachable & was_spray).sum())
    assert counts["left_out_unreached"] == int((~work.reachable & was_spray).sum())
    assert counts["left_out_in_collision"] > 0
    assert int(spray.sum()) + sum(counts.values()) == int(was_spray.sum())


def test_runs_start_and_end_where_the_programs_back_off_free(tmp_path):
    """``free_work`` with ``backs`` (``CellRouter.backs_free``): every kept run starts and ends at a waypoint
    from which the gun's back-off along its axis (the programs' approach and retract, ``approach_mm`` or the
    first shorter share the arm reaches) and the move there are free by the full check; a run is only cut at
    its ends (what is kept of it is the run without ``backs`` less waypoints at either end whose back-off is
    not free), and kept and left out add up."""
    from sprayplan.cells.repair import free_work
    from sprayplan.cells.routes import CellRouter
    from sprayplan.config import JobConfig
    from sprayplan.programs.build import APPROACH_TRIES

    cell, plan, arms = _box_cell(tmp_path)
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    router = CellRouter(robot, arm, plan.part, JobConfig().collision)
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    plain, _ = free_work(work, found)
    freed, counts = free_work(work, found, None, lambda q, t: router.backs_free(q, t, 50.0))
    assert counts["left_out_unapproachable"] > 0
    was_spray = np.concatenate([np.full(len(s), s.spray_on) for s in work.strokes])
    spray = np.concatenate([np.full(len(s), s.spray_on) for s in freed.strokes])
    assert int(spray.sum()) + sum(counts.values()) == int(was_spray.sum())

    def back_free(q, t):
        pose = router.pose(q, t)
        for share in APPROACH_TRIES:
            moved = pose.copy()
            moved[:3, 3] -= 50.0 * share * pose[:3, 2]
            back = router.solve(moved, t, q)
            if back is not None:
                np.testing.assert_allclose(router.pose(back, t), moved, atol=1e-6)
                checked = check_robot(arm, np.vstack([q, back]), np.full(2, t), np.ones(2, bool))
                return not (checked.waypoint.collides.any() or checked.motion_collides.any())
        return False

    starts = np.r_[0, np.cumsum([len(s) for s in freed.strokes])]
    ends = [k for i, s in enumerate(freed.strokes) if s.spray_on for k in (starts[i], starts[i + 1] - 1)]
    assert all(back_free(freed.q[k], freed.track_mm[k]) for k in ends)
    # each kept run lies inside a run of the plain cut, and no waypoint cut from its ends backs off free
    plain_starts = np.r_[0, np.cumsum([len(s) for s in plain.strokes])]
    plain_runs = [(plain_starts[i], s) for i, s in enumerate(plain.strokes) if s.spray_on]
    cut_free = 0
    for s in freed.strokes:
        if not s.spray_on:
            continue
        at, whole = next(
            (a, r) for a, r in plain_runs for k in range(len(r)) if np.array_equal(r.tcp[k : k + len(s)], s.tcp)
        )
        k = next(k for k in range(len(whole)) if np.array_equal(whole.tcp[k : k + len(s)], s.tcp))
        cut = [*range(k), *range(k + len(s), len(whole))]
        cut_free += sum(back_free(plain.q[at + j], plain.track_mm[at + j]) for j in cut)
    assert cut_free == 0


def test_transfers_in_collision_are_routed_free_and_the_gun_is_where_the_waypoints_say(tmp_path):
    """``routed_work``: a transfer in collision that gets a route has nodes and motions free (the check's own
    answer), its ends unchanged, every node's gun pose the one its waypoint (tip, normal, roll) gives, and
    the same seed gives the same routes."""
    from sprayplan.cells.repair import free_work
    from sprayplan.cells.routes import routed_work
    from sprayplan.config import JobConfig

    cell, plan, arms = _box_cell(tmp_path)
    config = JobConfig().collision
    work, arm = plan.robots[0], arms[0]
    freed, _ = free_work(work, check_robot(arm, work.q, work.track_mm, work.reachable))
    before = check_robot(arm, freed.q, freed.track_mm, freed.reachable)
    routed, counts = routed_work(cell.robots[0], freed, arm, plan.part, config, 200.0)
    again, _ = routed_work(cell.robots[0], freed, arm, plan.part, config, 200.0)
    np.testing.assert_array_equal(routed.q, again.q)
    assert counts["transfers_routed"] >= 1 and counts["transfers_in_collision"] >= counts["transfers_routed"]
    after = check_robot(arm, routed.q, routed.track_mm, routed.reachable)
    assert after.motion_collides.sum() < before.motion_collides.sum()
    old_starts = np.r_[0, np.cumsum([len(s) for s in freed.strokes])]
    new_starts = np.r_[0, np.cumsum([len(s) for s in routed.strokes])]
    routes = 0
    for i, (old, new) in enumerate(zip(freed.strokes, routed.strokes)):
        a, b = new_starts[i], new_starts[i + 1]
        np.testing.assert_array_equal(routed.q[a], freed.q[old_starts[i]])
        np.testing.assert_array_equal(routed.q[b - 1], freed.q[old_starts[i + 1] - 1])
        if len(new) == len(old):
            continue
        routes += 1
        assert not new.spray_on and not after.motion_collides[a : b - 1].any()
        robot = cell.robots[0]
        got = np.stack([robot.robot(t).fk(q[None])[0] for t, q in zip(routed.track_mm[a:b], routed.q[a:b])])
        want = poses_at(new.tcp, new.normals) @ _rolls(routed.roll_deg[a:b])
        np.testing.assert_allclose(got[:, :3, 3], want[:, :3, 3], atol=1e-6)
        np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], atol=1e-9)
    assert routes == counts["transfers_routed"]
    # the robot's programs move through every route's waypoints, on the route's joints, and read back as the plan
    import dataclasses

    from sprayplan.programs.arms import build_cell_programs, write_cell_programs

    built = build_cell_programs(dataclasses.replace(plan, robots=(routed, *plan.robots[1:])), plan.job, ("rapid",))
    write_cell_programs(tmp_path / "programs", built, plan.job)  # raises if a program read back is not the plan
    moves = [m for m, _ in built[0].builts[0].program.sequence() if m.role == "route"]
    inner = np.concatenate(
        [routed.q[a + 1 : b - 1] for a, b, s in zip(new_starts, new_starts[1:], routed.strokes) if not s.spray_on]
    )
    assert len(moves) == len(inner) > 0
    np.testing.assert_allclose(np.stack([m.joints for m in moves]), inner, atol=1e-12)


def test_a_transfer_nothing_shorter_frees_goes_out_to_a_park_and_back(tmp_path):
    """The ``home`` route (``CellRouter.home``): with no retract, via or search, the transfers in collision on
    the box are all routed out to a park and back; the nodes are parks the schedule offers from the two ends
    (or those ends backed off), the ends are kept, and every motion of the routed work is free."""
    import dataclasses

    from sprayplan.cells.repair import free_work
    from sprayplan.cells.routes import CellRouter, routed_work
    from sprayplan.config import JobConfig

    cell, plan, arms = _box_cell(tmp_path)
    config = dataclasses.replace(JobConfig().collision, retract_mm=[], via_height_mm=None, cell_detour_iterations=0)
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    freed, _ = free_work(work, check_robot(arm, work.q, work.track_mm, work.reachable))
    routed, counts = routed_work(robot, freed, arm, plan.part, config, 200.0)
    assert counts["transfers_in_collision"] >= 2
    assert counts["routed_home"] == counts["transfers_routed"] == counts["transfers_in_collision"]
    after = check_robot(arm, routed.q, routed.track_mm, routed.reachable)
    assert not after.motion_collides.any() and not after.waypoint.collides.any()
    router = CellRouter(robot, arm, plan.part, config)
    starts = np.r_[0, np.cumsum([len(s) for s in routed.strokes])]
    old_starts = np.r_[0, np.cumsum([len(s) for s in freed.strokes])]
    for i, (old, new) in enumerate(zip(freed.strokes, routed.strokes)):
        if len(new) == len(old):
            continue
        a, b = starts[i], starts[i + 1]
        np.testing.assert_array_equal(routed.q[[a, b - 1]], freed.q[[old_starts[i], old_starts[i + 1] - 1]])
        parks = [
            *router._parks(routed.q[a], routed.track_mm[a]),
            *router._parks(routed.q[b - 1], routed.track_mm[b - 1]),
        ]
        inner = routed.q[a + 1 : b - 1]
        assert len(inner) in (1, 2)  # no retract lengths: the parks alone
        for q in inner:
            assert any(np.array_equal(q, p) for p, _ in parks)


def _routing_case(tmp_path):
    """The box cell's robot, its work cut to what it paints free, its router, the rows where its strokes start,
    its (joints, track) rows and the indices of its transfers between two spray strokes."""
    from sprayplan.cells.repair import free_work
    from sprayplan.cells.routes import CellRouter
    from sprayplan.config import JobConfig

    cell, plan, arms = _box_cell(tmp_path)
    config = JobConfig().collision
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    freed, _ = free_work(work, check_robot(arm, work.q, work.track_mm, work.reachable))
    router = CellRouter(robot, arm, plan.part, config)
    starts = np.r_[0, np.cumsum([len(s) for s in freed.strokes])]
    pairs = np.column_stack([freed.q, freed.track_mm])
    transfers = [i for i, s in enumerate(freed.strokes) if not s.spray_on and 0 < i < len(freed.strokes) - 1]
    return plan, config, robot, arm, freed, router, starts, pairs, transfers


def test_transfers_are_routed_the_way_the_programs_make_them(tmp_path, monkeypatch):
    """With ``approach_mm`` (the programs' retract and approach), a transfer is checked as the program makes it:
    one whose joint move is free but whose way through the backed-off poses is not (the leg between them
    blocked here, the rest the real model) is routed between the backed-off poses (its first and last nodes),
    so that every leg the program makes is free; without ``approach_mm`` it is left as it was."""
    import dataclasses

    from sprayplan.cells.routes import CellRouter, routed_work

    plan, config, robot, arm, freed, router, starts, pairs, transfers = _routing_case(tmp_path)
    edges = router._edges_free(pairs[starts[transfers]], pairs[starts[transfers] + 1])
    backs = router.backed_off(pairs, starts[transfers], edges, 50.0)
    k = min(backs)  # a transfer whose joint move is free and whose ends back off
    i, back_a, back_b = transfers[k], *backs[k]

    def blocked(x, y):
        return (np.allclose(x, back_a) and np.allclose(y, back_b)) or (
            np.allclose(x, back_b) and np.allclose(y, back_a)
        )

    real_edges, real_free = CellRouter._edges_free, CellRouter.free

    def edges_free(self, a, b):
        out = real_edges(self, a, b)
        return out & ~np.array([blocked(x, y) for x, y in zip(a, b)], bool)

    def free(self, q_a, t_a, nodes, tracks, q_b, t_b):
        chain = np.column_stack([np.vstack([q_a, nodes, q_b]), np.r_[t_a, tracks, t_b]])
        return real_free(self, q_a, t_a, nodes, tracks, q_b, t_b) and not any(map(blocked, chain[:-1], chain[1:]))

    monkeypatch.setattr(CellRouter, "_edges_free", edges_free)
    monkeypatch.setattr(CellRouter, "free", free)
    without, _ = routed_work(robot, freed, arm, plan.part, config, 200.0, approach_mm=0.0)
    assert len(without.strokes[i]) == 2  # its joint move is free: left alone
    routed, counts = routed_work(robot, freed, arm, plan.part, config, 200.0, approach_mm=50.0)
    new_starts = np.r_[0, np.cumsum([len(s) for s in routed.strokes])]
    a, b = new_starts[i], new_starts[i + 1]
    way = np.column_stack([routed.q[a:b], routed.track_mm[a:b]])
    assert len(way) >= 4 and counts["transfers_routed"] >= 1
    np.testing.assert_allclose(way[[0, -1]], pairs[[starts[i], starts[i] + 1]])
    np.testing.assert_allclose(way[1], back_a)
    np.testing.assert_allclose(way[-2], back_b)
    assert real_free(router, way[0, :-1], way[0, -1], way[1:-1, :-1], way[1:-1, -1], way[-1, :-1], way[-1, -1])
    assert not any(map(blocked, way[:-1], way[1:]))
    # a route always has a node: between two ends whose joint move is free, the search's shortened path has
    # none, and no route is given (the programs' way there is what stays in collision)
    bare = dataclasses.replace(config, retract_mm=(), via_height_mm=None)
    q_a, q_b = freed.q[starts[i]], freed.q[starts[i] + 1]
    t_a, t_b = freed.track_mm[starts[i]], freed.track_mm[starts[i] + 1]
    found = CellRouter(robot, arm, plan.part, bare).route(q_a, t_a, q_b, t_b)
    assert found is None or (found[0] == "home" and len(found[1]) >= 1)


@pytest.mark.parametrize("way_free", [True, False])
def test_a_route_from_the_ends_is_kept_only_with_the_programs_back_offs_free(tmp_path, monkeypatch, way_free):
    """A transfer no route between the backed-off poses frees, routed from its ends themselves: the program
    still backs off at both ends, so the route is kept only when ``A, A backed off, route, B backed off, B`` is
    free, and then those are its nodes; else the transfer is left in collision, its key in ``failed``."""
    from sprayplan.cells.routes import CellRouter, routed_work

    plan, config, robot, arm, freed, router, starts, pairs, transfers = _routing_case(tmp_path)
    backs = router.backed_off(pairs, starts[transfers], np.ones(len(transfers), bool), 50.0)
    k = min(backs)
    i, back_a, back_b = transfers[k], *backs[k]
    end_a, end_b = pairs[starts[i]], pairs[starts[i] + 1]
    via = 0.5 * (back_a + back_b)  # the route "found" from the ends: one node

    def edges_free(self, a, b):  # the joint move A -> B and the leg between the backed-off poses blocked
        hit = [
            {tuple(np.round(x, 9)), tuple(np.round(y, 9))} in ({tuple(np.round(end_a, 9)), tuple(np.round(end_b, 9))},
                                                              {tuple(np.round(back_a, 9)), tuple(np.round(back_b, 9))})
            for x, y in zip(a, b)
        ]  # fmt: skip
        return ~np.array(hit, bool)

    asked = []

    def free(self, q_a, t_a, nodes, tracks, q_b, t_b):
        asked.append(np.column_stack([nodes, tracks]))
        return way_free

    def route(self, q_a, t_a, q_b, t_b, seed=0, search=True):
        if not search:  # between the backed-off poses: nothing
            return None
        return "via", via[None, :-1], via[-1:]

    monkeypatch.setattr(CellRouter, "_edges_free", edges_free)
    monkeypatch.setattr(CellRouter, "_states_free", lambda self, s: np.ones(len(s), bool))
    monkeypatch.setattr(CellRouter, "free", free)
    monkeypatch.setattr(CellRouter, "route", route)
    failed: set = set()
    routed, counts = routed_work(robot, freed, arm, plan.part, config, 200.0, failed=failed, approach_mm=50.0)
    assert counts["transfers_in_collision"] == 1 and counts["transfers_routed"] == int(way_free)
    # ``only``: the transfers a drop made; the others are not looked at
    _, elsewhere = routed_work(robot, freed, arm, plan.part, config, 200.0, approach_mm=50.0, only={i + 2})
    assert elsewhere["transfers_in_collision"] == 0
    checked = [a for a in asked if len(a) == 3]
    assert checked, "the program's way through the route was checked"
    np.testing.assert_allclose(checked[-1], [back_a, via, back_b])
    new_starts = np.r_[0, np.cumsum([len(s) for s in routed.strokes])]
    way = np.column_stack([routed.q, routed.track_mm])[new_starts[i] : new_starts[i + 1]]
    key = pairs[starts[i] : starts[i] + 2].tobytes()
    if way_free:
        np.testing.assert_allclose(way, [end_a, back_a, via, back_b, end_b])
        assert key not in failed
    else:
        np.testing.assert_allclose(way, [end_a, end_b])
        assert key in failed


def test_a_touch_up_round_checks_only_the_strokes_it_added(tmp_path):
    """``_tail_checked`` (a touch-up round's check of the strokes appended): the flags from the last waypoint
    before the new strokes on are the whole check's; the rows before it are returned free."""
    from sprayplan.cells.collide import _tail_checked

    _, plan, arms = _box_cell(tmp_path)
    work, arm = plan.robots[0], arms[0]
    whole = check_robot(arm, work.q, work.track_mm, work.reachable)
    since = len(work.strokes) // 2
    first = sum(len(s) for s in work.strokes[:since]) - 1
    tail = _tail_checked(arm, work, since)
    assert whole.waypoint.collides[first:].any() and whole.waypoint.collides[:first].any()
    np.testing.assert_array_equal(tail.waypoint.collides[first:], whole.waypoint.collides[first:])
    np.testing.assert_array_equal(tail.motion_collides[first:], whole.motion_collides[first:])
    assert not tail.waypoint.collides[:first].any() and not tail.motion_collides[:first].any()


def test_runs_in_collision_solved_on_their_own_are_free_and_painted(tmp_path):
    """``free_work`` with ``resolve``: the runs in collision that get a try of their own are painted (fewer
    waypoints left out, by exactly those resolved), and every spray waypoint and motion inside a stroke is
    still free, each resolved piece's gun where its waypoints say."""
    from sprayplan.cells.repair import free_work, resolved_piece
    from tests.test_cell_plan import SIZE

    cell, plan, arms = _box_cell(tmp_path, SIZE)
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    _, left = free_work(work, found)
    pieced, counts = free_work(work, found, lambda piece, seed: resolved_piece(robot, arm, piece, seed))
    assert counts["pieces_resolved"] >= 1
    # every waypoint resolved was left out before, in collision or unreached
    after = counts["left_out_in_collision"] + counts["left_out_unreached"] + counts["waypoints_resolved"]
    assert after == left["left_out_in_collision"] + left["left_out_unreached"]
    again = check_robot(arm, pieced.q, pieced.track_mm, pieced.reachable)
    starts = np.r_[0, np.cumsum([len(s) for s in pieced.strokes])]
    for i, s in enumerate(pieced.strokes):
        a, b = starts[i], starts[i + 1]
        if s.spray_on:
            assert not again.waypoint.collides[a:b].any() and not again.motion_collides[a : b - 1].any()
        else:
            np.testing.assert_array_equal(pieced.q[a], pieced.q[a - 1])
            np.testing.assert_array_equal(pieced.q[b - 1], pieced.q[b])
    got = np.stack([robot.robot(t).fk(j[None])[0] for t, j in zip(pieced.track_mm, pieced.q)])
    tcp = np.concatenate([s.tcp for s in pieced.strokes])
    normals = np.concatenate([s.normals for s in pieced.strokes])
    want = poses_at(tcp, normals) @ _rolls(pieced.roll_deg)
    np.testing.assert_allclose(got[:, :3, 3], want[:, :3, 3], atol=1e-6)
    np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], atol=1e-9)


def test_a_piece_no_try_frees_whole_is_painted_in_halves(tmp_path, monkeypatch):
    """A piece ``resolve`` cannot free whole (here: any longer than 4 waypoints, the rest the real solve) is
    tried in halves sharing their middle waypoint, down to ``SPLIT_DEPTH`` levels: more waypoints are painted
    than without halves, by exactly the count resolved, and every spray waypoint and motion is still free."""
    import sprayplan.cells.repair as repair
    from sprayplan.cells.repair import free_work, resolved_piece
    from tests.test_cell_plan import SIZE

    cell, plan, arms = _box_cell(tmp_path, SIZE)
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    asked = []

    def short_only(piece, seed):
        asked.append(len(piece))
        return resolved_piece(robot, arm, piece, seed) if len(piece) <= 4 else None

    monkeypatch.setattr(repair, "SPLIT_DEPTH", 0)
    _, whole = free_work(work, found, short_only)
    first = list(asked)
    monkeypatch.setattr(repair, "SPLIT_DEPTH", 2)
    asked.clear()
    halved, counts = free_work(work, found, short_only)
    assert max(first) >= 6 and len(asked) > len(first)
    # the halves of a piece of n waypoints have n + 1 between them (the middle one shared)
    long = [n for n in first if n >= 6]
    assert all(any(asked[i : i + 2] == [(n + 2) // 2, n - n // 2] for i in range(len(asked))) for n in long[:1])
    assert counts["waypoints_resolved"] > whole["waypoints_resolved"]
    assert (
        counts["left_out_in_collision"] + counts["left_out_unreached"] + counts["waypoints_resolved"]
        == whole["left_out_in_collision"] + whole["left_out_unreached"] + whole["waypoints_resolved"]
    )
    again = check_robot(arm, halved.q, halved.track_mm, halved.reachable)
    starts = np.r_[0, np.cumsum([len(s) for s in halved.strokes])]
    for i, s in enumerate(halved.strokes):
        if s.spray_on:
            a, b = starts[i], starts[i + 1]
            assert not again.waypoint.collides[a:b].any() and not again.motion_collides[a : b - 1].any()


def test_a_piece_no_untilted_try_frees_is_painted_with_the_gun_tilted_round_its_targets(tmp_path):
    """``resolved_piece`` with the standoff: the runs no (track, roll, branch) try frees get the gun tilted
    (``piece_tilts`` of the default ``piece_tilt_deg``), so more waypoints are painted than without; a tilted
    piece aims at its own targets (the same points), its gun at the standoff along its new axis, that axis turned by one of the tilts,
    sideways (within the plane across the travel) or along the travel (within the plane of the normal and the
    travel), and the arm's FK at the tilted poses, free of the body."""
    from sprayplan.cells.repair import free_work, piece_tilts, resolved_piece
    from tests.test_cell_plan import SIZE

    cell, plan, arms = _box_cell(tmp_path, SIZE)
    standoff = plan.job.paths.standoff_mm
    tilts = piece_tilts(plan.job.collision.piece_tilt_deg)
    assert tilts == tuple((across, a) for across in (False, True) for a in (20.0, -20.0, 40.0, -40.0))
    assert piece_tilts(0.0) == ()
    work, arm, robot = plan.robots[1], arms[1], cell.robots[1]
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    pieces = []

    def resolve(piece, seed):
        got = resolved_piece(robot, arm, piece, seed, standoff, tilts)
        pieces.append((piece, got))
        return got

    _, flat = free_work(work, found, lambda piece, seed: resolved_piece(robot, arm, piece, seed, standoff))
    tilted, counts = free_work(work, found, resolve)
    assert counts["pieces_tilted"] >= 1 and counts["waypoints_resolved"] > flat["waypoints_resolved"]
    assert counts["left_out_in_collision"] < flat["left_out_in_collision"]
    for piece, got in pieces:
        if got is None or got[3] is piece:
            continue
        aimed = got[3]
        np.testing.assert_array_equal(aimed.points, piece.points)
        np.testing.assert_allclose(aimed.tcp, aimed.points + standoff * aimed.normals, atol=1e-9)
        turned = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", aimed.normals, piece.normals), -1, 1)))
        assert any(np.allclose(turned, abs(t), atol=1e-6) for _, t in tilts)
        travel = np.gradient(piece.points, axis=0)
        travel -= np.einsum("ij,ij->i", travel, piece.normals)[:, None] * piece.normals
        change = aimed.normals - piece.normals
        sideways = np.abs(np.einsum("ij,ij->i", change, travel)).max() < 1e-6
        along = np.abs(np.einsum("ij,ij->i", change, np.cross(piece.normals, travel))).max() < 1e-6
        assert sideways != along
        q, track, roll = got[0], got[1], got[2]
        fk = np.stack([robot.robot(t).fk(j[None])[0] for t, j in zip(track, q)])
        want = poses_at(aimed.tcp, aimed.normals) @ _rolls(np.full(len(q), roll))
        np.testing.assert_allclose(fk[:, :3, 3], want[:, :3, 3], atol=1e-6)
        assert not check_robot(arm, q, track, np.ones(len(q), bool)).waypoint.collides.any()
    # the tilted plan's strokes are its pieces: every spray waypoint free, the tilted pieces among its strokes
    again = check_robot(arm, tilted.q, tilted.track_mm, tilted.reachable)
    spray = np.concatenate([np.full(len(s), s.spray_on) for s in tilted.strokes])
    assert not again.waypoint.collides[spray].any()
    kept = [s for s in tilted.strokes if s.spray_on]
    aimed = [got[3] for piece, got in pieces if got is not None and got[3] is not piece]
    assert aimed and all(any(s is a for s in kept) for a in aimed)


def test_an_unreached_run_solved_on_its_own_is_painted_from_the_joints_before_it(tmp_path):
    """``free_work`` with ``resolve``: a run of waypoints the stroke's one try does not reach (here made so by
    marking a free run unreached) is solved on its own like a run in collision: where it gets a try, its
    waypoints are painted (left out unreached drops by exactly those resolved), its solve starts from the
    joints of the last reached waypoint before it, and the arm's FK puts the gun on its targets."""
    import dataclasses

    from sprayplan.cells.repair import free_work, resolved_piece
    from tests.test_cell_plan import SIZE

    cell, plan, arms = _box_cell(tmp_path, SIZE)
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    free = work.reachable & ~found.waypoint.collides
    starts = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
    # the middle fifth of the first spray stroke that is free all along, marked unreached
    i = next(
        k for k, s in enumerate(work.strokes) if s.spray_on and len(s) >= 10 and free[starts[k] : starts[k + 1]].all()
    )
    a, n = starts[i], len(work.strokes[i])
    lo, hi = a + 2 * n // 5, a + 3 * n // 5
    reach = work.reachable.copy()
    reach[lo:hi] = False
    marked = dataclasses.replace(work, reachable=reach)
    _, left = free_work(marked, found)
    assert left["left_out_unreached"] == (~reach).sum() and (~reach).sum() >= hi - lo
    seeds = []

    def resolve(piece, seed):
        seeds.append((piece, seed))
        return resolved_piece(robot, arm, piece, seed)

    pieced, counts = free_work(marked, found, resolve)
    around = work.strokes[i].points[lo - a - 1 : hi - a + 1]  # the run with a reached waypoint either side
    mine = [(p, s) for p, s in seeds if len(p) == len(around) and np.array_equal(p.points, around)]
    assert len(mine) == 1
    np.testing.assert_array_equal(mine[0][1], work.q[lo - 1])  # from the reached waypoint just before
    _, plain = free_work(work, found, lambda piece, seed: resolved_piece(robot, arm, piece, seed))
    assert counts["left_out_unreached"] == plain["left_out_unreached"] < left["left_out_unreached"]
    got = np.stack([robot.robot(t).fk(j[None])[0] for t, j in zip(pieced.track_mm, pieced.q)])
    tcp = np.concatenate([s.tcp for s in pieced.strokes])
    normals = np.concatenate([s.normals for s in pieced.strokes])
    want = poses_at(tcp, normals) @ _rolls(pieced.roll_deg)
    np.testing.assert_allclose(got[:, :3, 3], want[:, :3, 3], atol=1e-6)
    painted = np.concatenate([s.points for s in pieced.strokes if s.spray_on])
    for p in work.strokes[i].points[lo - a : hi - a]:
        assert np.min(np.linalg.norm(painted - p, axis=1)) < 1e-9


def test_touch_ups_no_route_reaches_free_are_dropped_and_their_neighbours_joined(tmp_path):
    """``unrouted_runs`` names the touch-up a failed transfer leads into (the keys ``routed_work`` keeps);
    ``without_strokes`` takes it and its transfers out: the spray strokes left are the others in their order,
    with every waypoint's joints as before, and each transfer joins the end of the stroke before to the start of
    the one after (the gun's tip and the joints at both ends are its neighbours')."""
    import dataclasses

    from sprayplan.cells.collide import unrouted_runs
    from sprayplan.cells.work import without_strokes

    _, plan, _ = _box_cell(tmp_path)
    work = plan.robots[0]
    spray = [i for i, s in enumerate(work.strokes) if s.spray_on]
    assert len(spray) >= 5
    first = spray[2] - 1  # the "touch-up round" starts at the transfer before the third spray stroke
    strokes = list(work.strokes)
    for i in spray[2:]:
        strokes[i] = dataclasses.replace(strokes[i], kind="touch-up")
    work = dataclasses.replace(work, strokes=tuple(strokes))
    starts = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
    pairs = np.column_stack([work.q, work.track_mm])
    into = spray[3] - 1  # the transfer into the fourth spray stroke, a touch-up
    assert not work.strokes[into].spray_on and len(work.strokes[into]) == 2
    failed = {pairs[starts[into] : starts[into] + 2].tobytes(), b"another transfer"}
    assert unrouted_runs(work, failed, first) == [spray[3]]
    assert unrouted_runs(work, set(), first) == []
    assert unrouted_runs(work, failed, spray[3] + 1) == []  # before the round: not a touch-up to drop
    # outside a touch-up round any run may go: the one the failed transfer leads into, unless its start state
    # was blamed already (a run after it was dropped and the new transfer from it failed again): then the run
    # before it
    into_planned = spray[1] - 1
    failed.add(pairs[starts[into_planned] : starts[into_planned] + 2].tobytes())
    assert unrouted_runs(work, failed, first) == [spray[3]]  # in a round the planned stroke stays
    blamed = set()
    assert unrouted_runs(work, failed, 0, touch_ups_only=False, blamed=blamed) == [spray[1], spray[3]]
    assert blamed == {pairs[starts[into_planned]].tobytes(), pairs[starts[into]].tobytes()}
    assert unrouted_runs(work, failed, 0, touch_ups_only=False, blamed=blamed) == [spray[0], spray[2]]

    out = without_strokes(work, [spray[3]])
    kept = [s for s in out.strokes if s.spray_on]
    assert [s for s in kept] == [work.strokes[i] for i in spray if i != spray[3]]
    new_starts = np.r_[0, np.cumsum([len(s) for s in out.strokes])]
    old_rows = {i: np.arange(starts[i], starts[i + 1]) for i in spray}
    k = 0
    for j, s in enumerate(out.strokes):
        rows = np.arange(new_starts[j], new_starts[j + 1])
        if s.spray_on:
            i = [i for i in spray if i != spray[3]][k]
            np.testing.assert_array_equal(out.q[rows], work.q[old_rows[i]])
            k += 1
        else:
            before, after = out.strokes[j - 1], out.strokes[j + 1]
            np.testing.assert_array_equal(s.tcp[0], before.tcp[-1])
            np.testing.assert_array_equal(s.tcp[-1], after.tcp[0])
            for mine, theirs in ((rows[0], rows[0] - 1), (rows[-1], rows[-1] + 1)):
                if out.reachable[theirs]:  # (this plan is not cut: some waypoints are unreached)
                    np.testing.assert_array_equal(out.q[mine], out.q[theirs])
    assert len(out.q) == len(out.track_mm) == len(out.reachable) == new_starts[-1] and len(out.area) == len(out.strokes)
    assert without_strokes(work, []) is work


def _run_chain(n: int):
    """A one-robot work of ``n`` spray runs of two waypoints in a row, joined by transfers; run ``k``'s joints
    start at ``[k, 0, ...]`` and end at ``[k + 0.5, 0, ...]``, so a transfer's ends tell which runs it joins."""
    from sprayplan.cells.work import RobotWork, joined_transfers, transfer_stroke
    from sprayplan.types import Stroke

    strokes, area, q = [], [], []
    for k in range(n):
        tcp = np.array([[100.0 * k, 0.0, 0.0], [100.0 * k + 50.0, 0.0, 0.0]])
        run = Stroke(
            tcp - [0, 0, 200.0], np.tile([0.0, 0.0, 1.0], (2, 1)), tcp, spray_on=True, on_part=np.ones(2, bool)
        )
        if strokes:
            strokes.append(transfer_stroke(strokes[-1], run))
            area.append(-1)
            q += [np.zeros(6), np.zeros(6)]
        strokes.append(run)
        area.append(0)
        q += [np.r_[k, np.zeros(5)], np.r_[k + 0.5, np.zeros(5)]]
    m = len(q)
    work = RobotWork(
        "r", "stub", tuple(strokes), np.array(area), np.zeros(m), np.zeros(m), np.array(q), np.ones(m, bool)
    )
    return joined_transfers(work)


def test_runs_are_dropped_until_no_transfer_no_route_frees_is_left():
    """``dropped_unrouted`` goes on round after round until no transfer of the plan is one no route frees (it
    stopped after 10 rounds up to session 25, and the SUV kept 12 transfers in collision). The stub routes
    free a transfer between neighbouring runs only (every transfer a drop makes fails), and the one from run 5
    into run 6 fails from the start: the drops then alternate after and before (``unrouted_runs``' blame) until
    the runs before run 12 are gone, 12 rounds (at 10, the transfer from run 0 into run 11 was left); what is left is runs 12..19 in order, every transfer free."""
    from sprayplan.cells.collide import dropped_unrouted

    work = _run_chain(20)

    def ends(w, i):
        starts = np.r_[0, np.cumsum([len(s) for s in w.strokes])]
        return w.q[starts[i], 0], w.q[starts[i] + 1, 0]  # the run before's end, the run after's start

    def key(w, i):
        starts = np.r_[0, np.cumsum([len(s) for s in w.strokes])]
        return np.column_stack([w.q, w.track_mm])[starts[i] : starts[i] + 2].tobytes()

    calls = []

    def route(w, only):
        calls.append(sorted(only))
        for i in only:
            a, b = ends(w, i)
            if b - np.floor(a) != 1:  # not neighbours
                failed.add(key(w, i))
        return w, {"transfers_routed": 1, "transfers_in_collision": 1}

    into_6 = 2 * 6 - 1
    assert ends(work, into_6) == (5.5, 6.0)
    failed = {key(work, into_6)}
    out, counts, dropped, dropped_mm, rounds = dropped_unrouted(work, route, failed)
    assert rounds == len(calls) == 12 and dropped == 12  # runs 6, 5, 7, 4, ..., 11, 0
    assert dropped_mm == pytest.approx(12 * 50.0)
    assert counts == {"transfers_routed": 12}  # summed over the rounds, the ones in collision counted after
    runs = [s for s in out.strokes if s.spray_on]
    assert [s.tcp[0, 0] for s in runs] == [100.0 * k for k in range(12, 20)]
    transfers = [i for i, s in enumerate(out.strokes) if not s.spray_on]
    assert all(key(out, i) not in failed for i in transfers)
    # in a touch-up round (``first`` > 0) only touch-ups go: here none is, so nothing is dropped
    same, _, none, _, no_rounds = dropped_unrouted(work, route, {key(work, into_6)}, first=3)
    assert same is work and none == no_rounds == 0


def test_a_home_route_may_go_out_from_the_raised_ends(tmp_path, monkeypatch):
    """``CellRouter.home`` tries the parks from the ends raised as the ``via`` route raises them (backed off,
    then up to the safe height) after the ends and the ends backed off: with parks offered only from a pose
    at the safe height, the route found is ``[A backed off, A raised, P, (P',) B raised, B backed off]``,
    those poses where the via route puts them (the forward kinematics' answer) and the whole route free."""
    import dataclasses

    plan, config, robot, arm, _, router, starts, pairs, transfers = _routing_case(tmp_path)
    config = dataclasses.replace(config, retract_mm=[50.0])
    from sprayplan.cells.routes import CellRouter

    router = CellRouter(robot, arm, plan.part, config)
    plain = router._parks
    raised = []  # the raised poses' joints of the transfer tried: the only places parks are offered from

    def from_raised_only(q, t):
        return plain(q, t) if any(np.array_equal(q, r) for r in raised) else []

    monkeypatch.setattr(router, "_parks", from_raised_only)
    found = 0
    for i in transfers:
        s = starts[i]
        (q_a, t_a), (q_b, t_b) = (pairs[s, :-1], pairs[s, -1]), (pairs[s + 1, :-1], pairs[s + 1, -1])
        ups = [router._raised(q_a, t_a), router._raised(q_b, t_b)]
        if any(u is None or len(u) != 2 or np.allclose(u[0], u[1]) for u in ups):
            continue  # an end the via route does not raise (backed off, it is at the safe height already)
        raised[:] = [u[-1] for u in ups]
        route = router.home(q_a, t_a, q_b, t_b)
        if route is None:
            continue
        found += 1
        nodes, tracks = route
        assert router.free(q_a, t_a, nodes, tracks, q_b, t_b)
        up_a, up_b = router._raised(q_a, t_a), router._raised(q_b, t_b)
        np.testing.assert_array_equal(nodes[:2], up_a)
        np.testing.assert_array_equal(nodes[-2:], up_b[::-1])
        for q, t, end in ((nodes[1], tracks[1], q_a), (nodes[-2], tracks[-2], q_b)):
            pose, below = router.pose(q, t), router.pose(end, t)
            assert pose[2, 3] >= router.safe_z_mm - 1e-6
            np.testing.assert_allclose(pose[:3, :3], below[:3, :3], atol=1e-9)  # the gun's orientation kept
        assert len(nodes) in (5, 6)
    assert found >= 1


def test_the_gun_drawn_out_towards_the_base_and_a_park_route_from_it(tmp_path):
    """``CellRouter.drawn_out``: the gun moved the distance horizontally straight towards the robot's first
    axis (at its track position), its orientation kept (FK of the joints returned). ``park_route``: its first
    way is the gun drawn out by ``OUT_MM[0]`` where that node and its moves are free; any way it returns is free
    by the full check."""
    from sprayplan.cells.routes import OUT_MM, CellRouter
    from sprayplan.config import JobConfig

    cell, plan, arms = _box_cell(tmp_path)
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    router = CellRouter(robot, arm, plan.part, JobConfig().collision)
    ok = np.flatnonzero(work.reachable)
    checked = 0
    for i in ok[:: max(1, len(ok) // 25)]:
        q, t = work.q[i], float(work.track_mm[i])
        pose = router.pose(q, t)
        base = robot.base2cell[:3, 3] + (0.0 if robot.track is None else t * np.asarray(robot.track.axis, float))
        out = router.drawn_out(q, t, 200.0)
        if out is None:
            continue
        moved = router.pose(out, t)
        np.testing.assert_allclose(moved[:3, :3], pose[:3, :3], atol=1e-9)
        step = moved[:3, 3] - pose[:3, 3]
        assert step[2] == pytest.approx(0.0, abs=1e-6) and np.linalg.norm(step) == pytest.approx(200.0, abs=1e-6)
        towards = (base - pose[:3, 3])[:2]
        assert np.dot(step[:2], towards) / np.linalg.norm(towards) == pytest.approx(200.0, abs=1e-6)
        checked += 1
    assert checked >= 10
    from sprayplan.cells.schedule import park_joints

    kinds = []
    for i in ok[:: max(1, len(ok) // 12)]:
        q, t = work.q[i], float(work.track_mm[i])
        park, at = park_joints(arm, q, t)
        found = router.park_route(q, t, park, at)
        if found is None:
            continue
        kind, nodes, tracks = found
        assert router.free(q, t, nodes, tracks, park, at)
        first = router.drawn_out(q, t, OUT_MM[0])
        if first is not None and router.free(q, t, first[None], np.r_[t], park, at):
            assert kind == "out" and np.allclose(nodes, first[None])
        kinds.append(kind)
    assert "out" in kinds


def test_the_out_route_backs_off_then_draws_the_gun_out_towards_the_base(tmp_path):
    """``CellRouter.candidates``' ``out`` routes (one per ``OUT_MM``): nodes ``[A backed off, A drawn out, B
    drawn out, B backed off]``: the first the gun at A moved back along its axis by the first retract length,
    the second that pose moved the distance horizontally towards the base, orientation kept (FK of the joints),
    and the same from B in reverse; tried after ``retract`` and ``via``."""
    from sprayplan.cells.routes import OUT_MM, CellRouter
    from sprayplan.config import JobConfig

    cell, plan, arms = _box_cell(tmp_path)
    work, arm, robot = plan.robots[0], arms[0], cell.robots[0]
    config = JobConfig().collision
    router = CellRouter(robot, arm, plan.part, config)
    ok = np.flatnonzero(work.reachable)
    back = config.retract_mm[0]
    seen = 0
    for i, j in zip(ok[:-1:40], ok[1::40]):
        (qa, ta), (qb, tb) = (work.q[i], float(work.track_mm[i])), (work.q[j], float(work.track_mm[j]))
        found = list(router.candidates(qa, ta, qb, tb))
        kinds = [k for k, *_ in found]
        outs = [(nodes, tracks) for k, nodes, tracks in found if k == "out"]
        assert kinds == sorted(kinds, key=["retract", "via", "out"].index)
        for nodes, tracks in outs:
            assert len(nodes) == 4 and np.allclose(tracks, [ta, ta, tb, tb])
            for q, t, end, step in ((qa, ta, nodes[0], nodes[1]), (qb, tb, nodes[3], nodes[2])):
                pose, p_end, p_out = router.pose(q, t), router.pose(end, t), router.pose(step, t)
                np.testing.assert_allclose(p_end[:3, 3], pose[:3, 3] - back * pose[:3, 2], atol=1e-6)
                np.testing.assert_allclose(p_out[:3, :3], pose[:3, :3], atol=1e-9)
                moved = p_out[:3, 3] - p_end[:3, 3]
                assert moved[2] == pytest.approx(0.0, abs=1e-6)
                assert np.linalg.norm(moved) in [pytest.approx(d, abs=1e-6) for d in OUT_MM]
            seen += 1
    assert seen >= 3


def test_repair_candidates_that_turn_the_arm_over_from_the_joints_before_come_last(tmp_path):
    """``cells.repair._candidates``: every (try, branch) that reaches the waypoints, those with no joint
    jumping by more than ``JOINT_JUMP_RAD`` from the joints before (``seed``) and none along them first, then
    those that jump only from the seed, then those that jump along; within each, the tries in their order.
    Recounted from each candidate's joints, from the arm's start joints and from the first joints of a
    candidate that others start more than a jump away from (so that both kinds are there and the order is
    not the tries' alone)."""
    from sprayplan.cells.repair import _candidates
    from sprayplan.cells.tries import JOINT_JUMP_RAD, start_joints, stroke_tries

    cell, plan, _ = _box_cell(tmp_path)
    robot, work = cell.robots[0], plan.robots[0]
    stroke = next(s for s in work.strokes if s.spray_on)
    arm = robot.robot(0.0)
    tries = [(t.tobytes(), r) for t, r in stroke_tries(robot, stroke)]
    none = np.zeros(len(stroke), bool)
    ordered = _candidates(robot, arm, stroke, start_joints(arm.dof), none)
    starts = np.array([qb[ok][0] for qb, ok, _, _ in ordered])
    apart = (np.abs(starts[:, None] - starts[None]).max(axis=2) > JOINT_JUMP_RAD).any(axis=1)
    other = starts[int(np.flatnonzero(apart)[-1])]
    for seed in (start_joints(arm.dof), other):
        got = _candidates(robot, arm, stroke, seed, none)
        assert len(got) == len(ordered) > 1  # the same candidates, another order
        ranks, order = [], []
        for qb, ok, t, r in got:
            along = qb[ok]
            jumps = len(along) > 1 and np.abs(np.diff(along, axis=0)).max() > JOINT_JUMP_RAD
            ranks.append(2 if jumps else int(np.abs(along[0] - seed).max() > JOINT_JUMP_RAD))
            order.append(tries.index((t.tobytes(), r)))
        assert ranks == sorted(ranks)
        for rank in set(ranks):
            within = [k for k, rk in zip(order, ranks) if rk == rank]
            assert within == sorted(within)
    assert ranks[0] == 0 and 1 in ranks
    assert order != sorted(order)  # the seed's own candidate moved ahead of earlier tries


def test_a_run_about_to_be_dropped_is_solved_again_continuous_with_the_run_before(tmp_path):
    """``cells.repair.rescued_run``: from the joints a run before ended at, the run solved again with no joint
    jumping by more than ``JOINT_JUMP_RAD`` from them nor along it, every waypoint reached at its pose (the
    forward kinematics' answer, the roll kept), free of the part (the full check) and backed off free at its
    ends where ``backs`` says; nearest the seed of all such candidates; None where ``backs`` frees no end."""
    from sprayplan.cells.repair import _candidates, rescued_run
    from sprayplan.cells.tries import JOINT_JUMP_RAD
    from sprayplan.collision.arms import plan_collides

    cell, plan, arms = _box_cell(tmp_path)
    robot, work, arm = cell.robots[0], plan.robots[0], arms[0]
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    starts = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
    spray = [
        i
        for i, s in enumerate(work.strokes)
        if s.spray_on and work.reachable[starts[i] : starts[i + 1]].all()
        and not found.waypoint.collides[starts[i] : starts[i + 1]].any()
    ]  # fmt: skip
    i = spray[1]
    stroke, seed = work.strokes[i], work.q[starts[spray[0] + 1] - 1]  # the end of the free run before
    got = rescued_run(robot, arm, stroke, seed)
    assert got is not None
    qb, t, roll = got
    assert np.abs(qb[0] - seed).max() <= JOINT_JUMP_RAD and np.abs(np.diff(qb, axis=0)).max() <= JOINT_JUMP_RAD
    assert not plan_collides(arm, qb, t, np.ones(len(qb), bool))
    fk = np.stack([robot.robot(tt).fk(j[None])[0] for tt, j in zip(t, qb)])
    want = poses_at(stroke.tcp, stroke.normals) @ _rolls(np.full(len(qb), roll))
    np.testing.assert_allclose(fk[:, :3, 3], want[:, :3, 3], atol=1e-6)
    np.testing.assert_allclose(fk[:, :3, :3], want[:, :3, :3], atol=1e-6)
    smooth = _candidates(robot, robot.robot(0.0), stroke, seed, np.ones(len(stroke), bool), smooth=True)
    steps = [np.abs(c[0][0] - seed).max() for c in smooth]
    assert steps == sorted(steps) and np.abs(qb[0] - seed).max() >= steps[0] - 1e-12
    assert max(steps) <= JOINT_JUMP_RAD
    # the back-offs: asked at the run's first and last waypoints only, and a run whose ends no back-off frees is
    # not saved
    asked = []

    def backs(q, tr):
        asked.append(len(q))
        return np.zeros(len(q), bool)

    assert rescued_run(robot, arm, stroke, seed, backs) is None and set(asked) == {2}
    same = rescued_run(robot, arm, stroke, seed, lambda q, tr: np.ones(len(q), bool))
    np.testing.assert_array_equal(same[0], qb)


def test_a_run_solved_again_is_kept_and_its_transfers_routed_again():
    """``dropped_unrouted`` with ``rescue`` (``rescued``): the run the failed transfer leads into is solved again
    from the end of the run before in place of being dropped, its transfers made plain again (``with_run``: ends
    joined to the new joints, other rows as they were) and routed again, and kept only where both are free;
    where the one into it is not, the run is dropped as it would have been, and not solved again; where the one
    out of it is not, the runs after it are solved again in turn from the end of the one before, up to
    ``RESCUE_CHAIN``, and kept together where every transfer is then free. The stub route frees a
    transfer whose joints move less than 0.75 (neighbouring runs: 0.5), except the one into run 6 named failed
    at the start."""
    from functools import partial

    from sprayplan.cells.collide import dropped_unrouted, rescued

    work = _run_chain(10)

    def starts(w):
        return np.r_[0, np.cumsum([len(s) for s in w.strokes])]

    def key(w, i):
        s = starts(w)[i]
        return np.column_stack([w.q, w.track_mm])[s : s + 2].tobytes()

    def route(w, only):
        calls.append(sorted(only))
        for i in only:
            a = starts(w)[i]
            if abs(w.q[a + 1, 0] - w.q[a, 0]) >= 0.75:
                failed.add(key(w, i))
        return w, {"transfers_routed": 1}

    into_6 = 2 * 6 - 1
    calls, failed = [], {key(work, into_6)}
    plain, _, plain_dropped, _, _ = dropped_unrouted(work, route, failed)
    assert plain_dropped >= 1
    for shift, kept in ((0.1, True), (0.8, False), (-0.3, "chain")):
        seeds, calls = [], []
        failed = {key(work, into_6)}

        def solve(run, seed, shift=shift, seeds=seeds):
            seeds.append((run, seed[0]))
            if run is work.strokes[12]:
                return np.array([np.r_[6 + shift, np.zeros(5)], np.r_[6.5 + shift, np.zeros(5)]]), np.zeros(2), 0.0
            if shift < 0 and any(run is work.strokes[k] for k in (14, 16, 18)):  # on from the run before's end
                return (
                    np.array([np.r_[seed[0] + 0.5, np.zeros(5)], np.r_[seed[0] + 1.0, np.zeros(5)]]),
                    np.zeros(2),
                    0.0,
                )
            return None

        rescue = partial(rescued, solve=solve, route=route, failed=failed)
        out, counts, dropped, _, rounds = dropped_unrouted(work, route, failed, rescue=rescue)
        assert seeds[0] == (work.strokes[12], 5.5)  # from the end of run 5
        assert sum(r is work.strokes[12] for r, _ in seeds) == 1  # solved again once only
        assert calls[0] == [into_6, into_6 + 2]  # the transfers either side routed again
        runs = [s for s in out.strokes if s.spray_on]
        transfers = [i for i, s in enumerate(out.strokes) if not s.spray_on]
        assert all(key(out, i) not in failed for i in transfers)
        planned = [work.strokes[k] for k in range(0, 19, 2)]
        order = [next(j for j, p in enumerate(planned) if p is r) for r in runs]
        assert order == sorted(order)  # the runs kept are planned runs, in their order
        if kept == "chain":  # run 6 ends 0.8 short of run 7: runs 7, 8 and 9 go on from it in turn (the last)
            assert counts["runs_solved_again"] == 1 and dropped == 0 and rounds == 1
            assert [r for r, _ in seeds] == [work.strokes[k] for k in (12, 14, 16, 18)]
            for k, begin in ((12, 5.7), (14, 6.7), (16, 7.7), (18, 8.7)):
                np.testing.assert_allclose(out.q[starts(out)[k] : starts(out)[k + 1], 0], [begin, begin + 0.5])
            np.testing.assert_array_equal(out.q[: starts(out)[into_6] + 1], work.q[: starts(out)[into_6] + 1])
        elif kept:
            assert counts["runs_solved_again"] == 1 and dropped == 0 and rounds == 1
            assert counts["transfers_routed"] == 1 and out.strokes[12] is work.strokes[12]
            rows = np.arange(starts(out)[12], starts(out)[13])
            np.testing.assert_allclose(out.q[rows, 0], [6.1, 6.6])
            np.testing.assert_allclose(out.q[starts(out)[into_6] : starts(out)[into_6] + 2, 0], [5.5, 6.1])
            np.testing.assert_allclose(out.q[starts(out)[13] : starts(out)[13] + 2, 0], [6.6, 7.0])
            others = np.setdiff1d(np.arange(len(out.q)), np.r_[rows, starts(out)[into_6] + 1, starts(out)[13]])
            np.testing.assert_array_equal(out.q[others], work.q[others])
        else:  # as without the rescue
            assert counts["runs_solved_again"] == 0 and dropped == plain_dropped
            assert [s for s in out.strokes if s.spray_on] == [s for s in plain.strokes if s.spray_on]
            np.testing.assert_array_equal(out.q, plain.q)
