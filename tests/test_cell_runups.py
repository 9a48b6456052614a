"""Run-ups and run-outs of a cell robot's spray stretches (``cells.runups``, ``[timing] run_up_mm``): where they
are, how the timing, the schedule, cell_plan.json and the programs' check take them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sprayplan.cells import load_cell
from sprayplan.cells.files import cell_plan_from_file, write_cell_plan
from sprayplan.cells.plan import plan_cell
from sprayplan.cells.runups import RUN_UP_TRIES, robot_run_ups, stretch_ends
from sprayplan.cells.schedule import with_leads
from sprayplan.cells.timing import time_cell
from sprayplan.config import JobConfig
from sprayplan.export.stl import write_stl_binary
from sprayplan.io.load import load_part
from sprayplan.programs.arms import ArmCell
from tests.helpers import grid_box
from tests.test_cell_plan import CELL, SIZE


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The small two-robot box (the left arm on a track) planned in memory with a 50 um target."""
    folder = tmp_path_factory.mktemp("runups")
    (folder / "small2.toml").write_text(CELL)
    part = folder / "box.stl"
    part.write_bytes(write_stl_binary(grid_box(n=8, size=SIZE).triangles))
    cell = load_cell(folder / "small2.toml")
    job = JobConfig().replace(coating={"thickness_um": 50.0})
    return {"plan": plan_cell(load_part(str(part)), cell, job), "cell": cell, "job": job, "folder": folder}


def _arm(planned, k):
    return ArmCell(planned["plan"].cell.robots[k], planned["plan"].job.paths.standoff_mm)


def test_every_run_up_starts_straight_back_along_its_stretchs_first_segment(planned):
    """Each lead is at a stretch's end, on its side: the spray target at its joints (and track) is the end
    waypoint's moved by run_up_mm (or a half or a quarter of it) along the end segment's direction, outward,
    with the waypoint's orientation; its joints within the arm's limits; the track the waypoint's."""
    plan, job = planned["plan"], planned["job"]
    length = job.timing.run_up_mm
    made = 0
    for k, work in enumerate(plan.robots):
        arm = _arm(planned, k)
        has = np.isfinite(work.lead_q).all(axis=2)
        ends = {(w, side): other for w, other, side in stretch_ends(work)}
        assert {(int(w), int(s)) for w, s in zip(*np.nonzero(has))} <= set(ends)
        axes = np.column_stack([work.q, work.track_mm]) if arm.external_axes else work.q
        for (w, side), other in ends.items():
            if not has[w, side]:
                continue
            made += 1
            here, there = arm.target_poses(axes[[w, other]])
            lead_axes = work.lead_q[w, side][None]
            if arm.external_axes:
                lead_axes = np.column_stack([lead_axes, work.lead_track_mm[w, side : side + 1]])
            lead = arm.target_poses(lead_axes)[0]
            direction = (here[:3, 3] - there[:3, 3]) / np.linalg.norm(here[:3, 3] - there[:3, 3])
            step = lead[:3, 3] - here[:3, 3]
            distance = float(np.linalg.norm(step))
            assert min(abs(distance - length * t) for t in RUN_UP_TRIES) < 1e-6
            assert np.allclose(step, distance * direction, atol=1e-6)
            assert np.allclose(lead[:3, :3], here[:3, :3], atol=1e-9)
            assert arm.within_limits(work.lead_q[w, side][None])[0]
            assert work.lead_track_mm[w, side] == work.track_mm[w]
    counts = plan.report["run_ups"]["robots"].values()
    assert made > 0 and made == sum(c["full"] + c["shortened"] for c in counts) == sum(c["made"] for c in counts)
    assert made + sum(c["none"] for c in counts) == sum(len(stretch_ends(w)) for w in plan.robots)
    assert plan.report["run_ups"]["robots"]["left"]["full"] > 0


def test_the_timing_passes_a_run_ups_waypoint_at_speed(planned):
    """A stretch end with a run-up (run-out) is passed at speed: the timed tip speed there is above zero, the
    run-up takes time before it; the same plan without leads has the robot at rest there. Without leads the
    timing is what it was: every time stamp equal."""
    plan = planned["plan"]
    with_ = time_cell(plan.cell, plan.robots, plan.job)
    bare = tuple(dataclasses.replace(r, lead_q=None, lead_track_mm=None, lead_s=None) for r in plan.robots)
    without = time_cell(plan.cell, bare, plan.job)
    for work, a, b in zip(plan.robots, with_, without):
        has = np.isfinite(work.lead_q).all(axis=2)
        for side in (0, 1):
            at = np.flatnonzero(has[:, side] & np.isfinite(a.speed_mm_s))
            assert len(at)
            assert (a.speed_mm_s[at] > 1.0).all() and (a.lead_s[at, side] > 0).all()
            assert np.allclose(b.speed_mm_s[at], 0.0, atol=1e-6)
        assert (a.lead_s[~has] == 0).all() and b.lead_s.sum() == 0
    # leads off: the timing as before run-ups existed (the same numbers as a plan made with run_up_mm = 0)
    off = JobConfig().replace(coating={"thickness_um": 50.0}, timing={"run_up_mm": 0.0})
    plain = plan_cell(load_part(str(planned["folder"] / "box.stl")), planned["cell"], off)
    assert all(r.lead_q is None for r in plain.robots) and "run_ups" not in plain.report
    again = time_cell(plain.cell, plain.robots, plain.job)
    assert all(np.array_equal(r.t_s, tm.t_s) for r, tm in zip(plain.robots, again))


class _Hits:
    """A collision model that finds a run-up in collision where its line (the gun tip's first sample to its
    last, by forward kinematics) is longer than ``longest`` mm. The lines of many ends may come in one call,
    one after the other; each starts at its waypoint's own joints (a row equal to one of ``work``'s)."""

    def __init__(self, arm, longest, work):
        self.arm, self.longest = arm, longest
        self.starts = {row.tobytes() for row in np.asarray(work.q, float)}

    def collides(self, q, track):
        q = np.asarray(q, float)
        first = [i for i, row in enumerate(q) if row.tobytes() in self.starts]
        assert first and first[0] == 0
        out = np.zeros(len(q), bool)
        for a, b in zip(first, [*first[1:], len(q)]):
            ends = self.arm.poses(q[[a, b - 1]], [])[:, :3, 3]
            out[a:b] = np.linalg.norm(ends[1] - ends[0]) > self.longest
        return out


class _All:
    def collides(self, q, track):
        return np.ones(len(q), bool)


def test_a_run_up_in_collision_is_shortened_or_left_out(planned):
    """With a collision model that refuses every run-up longer than three quarters of run_up_mm, every one that
    the arm can make in full is made at half its length; with one that refuses all, none is made and each end
    counts."""
    plan, job = planned["plan"], planned["job"]
    work, cr = plan.robots[1], plan.cell.robots[1]
    arm = _arm(planned, 1)
    length = job.timing.run_up_mm
    free_q, _, free = robot_run_ups(cr, work, length, plan.job.paths.standoff_mm)
    q, _, counts = robot_run_ups(cr, work, length, plan.job.paths.standoff_mm, _Hits(arm, 0.75 * length, work))
    assert counts["full"] == 0 and counts["in_collision"] == free["full"]

    def made(leads, w, side):
        if not np.isfinite(leads[w, side]).all():
            return 0.0
        return float(np.linalg.norm(arm.poses(leads[w, side], [])[0, :3, 3] - arm.poses(work.q[w], [])[0, :3, 3]))

    for w, _, side in stretch_ends(work):  # each end as long as without the refusals, the full ones halved
        before = made(free_q, w, side)
        expected = 0.5 * length if abs(before - length) < 1e-6 else before
        assert made(q, w, side) == pytest.approx(expected, abs=1e-6)
    _, _, none = robot_run_ups(cr, work, job.timing.run_up_mm, plan.job.paths.standoff_mm, _All())
    assert none["full"] == none["shortened"] == 0 and none["none"] == len(stretch_ends(work))


def test_the_schedule_holds_a_wait_at_the_run_ups_start():
    """``with_leads``: a row before each run-up's waypoint and after each run-out's, at the timing's times;
    the waypoints' rows keep their times; a stroke that begins with a run-up begins at its row."""
    n = 6
    t0 = np.arange(n, dtype=float) * 10.0
    q = np.arange(n, dtype=float)[:, None] * np.ones((1, 6))
    track = np.arange(n, dtype=float) * 100.0
    lead_q = np.full((n, 2, 6), np.nan)
    lead_q[0, 0], lead_q[2, 1], lead_q[3, 0] = -1.0, 2.5, 2.75
    lead_s = np.zeros((n, 2))
    lead_s[0, 0], lead_s[2, 1], lead_s[3, 0] = 1.0, 2.0, 3.0
    lead_track = np.where(np.isfinite(lead_q[:, :, 0]), track[:, None], np.nan)
    work = type("W", (), {"lead_q": lead_q, "lead_s": lead_s, "lead_track_mm": lead_track})()
    times, joints, tracks, starts, keep = with_leads(work, t0, q, track, np.array([0, 3]))
    assert keep.sum() == n and np.array_equal(times[keep], t0) and np.array_equal(joints[keep], q)
    assert np.allclose(times, [-1.0, 0, 10, 20, 22, 27, 30, 40, 50])
    assert np.allclose(joints[:, 0], [-1.0, 0, 1, 2, 2.5, 2.75, 3, 4, 5])
    assert np.array_equal(tracks[~keep], [0.0, 200.0, 300.0])
    assert np.array_equal(starts, [0, 5])  # the second stroke begins at its run-up's row


def test_cell_plan_json_keeps_the_run_ups(planned, tmp_path):
    """Written and read back, every robot's run-ups are the same: joints to 1e-12 rad, track to 1e-6 mm,
    times to 1e-6 s, and the same ends have none."""
    write_cell_plan(tmp_path, planned["plan"])
    back = cell_plan_from_file(tmp_path / "cell_plan.json")
    for a, b in zip(planned["plan"].robots, back.robots):
        assert np.array_equal(np.isnan(a.lead_q), np.isnan(b.lead_q))
        has = np.isfinite(a.lead_q)
        assert np.allclose(a.lead_q[has], b.lead_q[has], atol=1e-12, rtol=0)
        assert np.allclose(a.lead_track_mm[has[:, :, 0]], b.lead_track_mm[has[:, :, 0]], atol=1e-6, rtol=0)
        assert np.allclose(a.lead_s, b.lead_s, atol=1e-6, rtol=0)


@pytest.mark.parametrize("bad", [-1.0, float("nan"), 5000.0])
def test_a_bad_run_up_length_names_its_key(bad, tmp_path, capsys):
    """``[timing] run_up_mm`` out of 0..1000 (or NaN): a ConfigError naming the key; through the CLI one line
    on stderr, exit code 2, nothing written."""
    from sprayplan.cli import main
    from sprayplan.config import TimingConfig
    from sprayplan.errors import ConfigError

    with pytest.raises(ConfigError, match="timing.run_up_mm"):
        TimingConfig(run_up_mm=bad)
    config = tmp_path / "job.toml"
    config.write_text(f"[timing]\nrun_up_mm = {bad if bad == bad else 'nan'}\n")
    part = tmp_path / "box.stl"
    part.write_bytes(write_stl_binary(grid_box(n=4, size=SIZE).triangles))
    out = tmp_path / "out"
    assert main(["plan", str(part), "--cell", "sides2", "--config", str(config), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run_up_mm" in err[0] and not out.exists()


def test_with_collisions_every_run_up_and_its_back_off_is_free(planned):
    """Planned with ``[collision] check`` (the box and the floor): every run-up's line (its joints sampled as
    the check samples them) is free, and so is the programs' back-off from its far end (``CellRouter.backs_free``,
    the approach or retract the programs make there); a back-off check that refuses every end leaves none."""
    pytest.importorskip("coal")
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.routes import CellRouter
    from sprayplan.cells.runups import _line_samples

    job = planned["job"].replace(collision={"check": True})
    plan = plan_cell(load_part(str(planned["folder"] / "box.stl")), planned["cell"], job)
    arms = cell_arms(plan.cell, plan.part, plan.job.collision)
    checked = 0
    for cr, work, arm in zip(plan.cell.robots, plan.robots, arms):
        router = CellRouter(cr, arm, plan.part, plan.job.collision)
        for w, side in zip(*np.nonzero(np.isfinite(work.lead_q).all(axis=2))):
            lead, t = work.lead_q[w, side], work.lead_track_mm[w, side]
            assert not arm.collides(_line_samples(work.q[w], lead), t).any()
            assert router.backs_free(lead[None], np.array([t]), plan.job.export.approach_mm)[0]
            checked += 1
    assert checked > 0 and checked == sum(c["made"] for c in plan.report["run_ups"]["robots"].values())
    cr, work = plan.cell.robots[1], plan.robots[1]
    _, _, counts = robot_run_ups(
        cr, work, job.timing.run_up_mm, plan.job.paths.standoff_mm, arms[1], lambda q, t: np.zeros(len(q), bool)
    )
    assert counts["full"] == counts["shortened"] == 0 and counts["back_off_not_free"] > 0


@pytest.mark.parametrize("change", ["start moved", "run-up speed", "run-out left out"])
def test_a_program_that_does_not_make_the_plans_run_up_fails_the_check(planned, tmp_path, change):
    """The right robot's RAPID built from the plan passes the read-back check; with a run-up's start moved by
    0.5 mm, a run-up at another speed, or a run-out left out (the retract then from the last waypoint's pose
    backed off from the run-out's end), it fails."""
    from sprayplan.programs.arms import arm_plan
    from sprayplan.programs.check import check_program
    from sprayplan.programs.rapid import write_rapid
    from sprayplan.programs.stage import build, configurations, read_programs

    plan = planned["plan"]
    arm = _arm(planned, 1)
    robot_plan = arm_plan(plan.robots[1], arm)
    built = build(robot_plan, plan.job, "rapid", False, arm)
    program = built.program

    def checked(prog, name):
        folder = tmp_path / name
        folder.mkdir()
        for file, text in write_rapid(prog, plan.job, configurations(prog, plan.job, "rapid", arm)).items():
            (folder / file).write_text(text)
        return check_program(read_programs(folder, plan.job, "rapid", 0), robot_plan, plan.job, arm)

    assert checked(program, "good").ok
    moves = list(program.stations[0].moves)
    k = next(i for i, m in enumerate(moves) if m.role == "run-up")
    if change == "start moved":
        pose = moves[k - 1].pose.copy()
        pose[0, 3] += 0.5
        moves[k - 1] = dataclasses.replace(moves[k - 1], pose=pose)
    elif change == "run-up speed":
        moves[k] = dataclasses.replace(moves[k], speed_mm_s=moves[k].speed_mm_s * 1.1)
    else:
        j = next(i for i, m in enumerate(moves) if m.role == "run-out")
        del moves[j]
    station = dataclasses.replace(program.stations[0], moves=tuple(moves))
    bad = checked(dataclasses.replace(program, stations=(station,)), "bad")
    assert not bad.ok


class _Router:
    """A stand-in for ``CellRouter``: backs off to the joints themselves with the track, and finds a move in
    collision exactly when either end differs from the waypoints' own joints (``plain``)."""

    def __init__(self, plain):
        self.plain = plain

    def _programs_back(self, q, t, distance_mm):
        return np.r_[q, t]

    def _edges_free(self, a, b):
        known = lambda s: any(np.array_equal(s[:-1], p) for p in self.plain)
        return np.array([known(x) and known(y) for x, y in zip(a, b)])


def test_a_move_between_runs_that_the_run_ups_put_in_collision_drops_them(planned):
    """``freed_junctions``: where the move between two stretches is free from the plain ends and not from
    their run-out and run-up, both are dropped (every such junction, counted); where the plain ends' move is
    not free either, the run-ups stay (they are not what puts it in collision)."""
    from sprayplan.cells.runups import freed_junctions

    work = planned["plan"].robots[1]
    ends = stretch_ends(work)
    plain = [work.q[k] for k, _, _ in ends]
    lead_q, dropped = freed_junctions(work, work.lead_q, _Router(plain), 50.0)
    junctions = [
        (a, b)
        for (a, _, sa), (b, _, sb) in zip(ends[1::2], ends[2::2])
        if np.isfinite(work.lead_q[a, 1]).all() or np.isfinite(work.lead_q[b, 0]).all()
    ]
    assert dropped == len(junctions) > 0  # (no routed transfer without the collision model)
    for a, b in junctions:
        assert not np.isfinite(lead_q[a, 1]).any() and not np.isfinite(lead_q[b, 0]).any()
    # the first stretch's run-up and the last's run-out are no junction's: they stay
    first, last = ends[0][0], ends[-1][0]
    assert np.array_equal(np.isfinite(lead_q[first, 0]), np.isfinite(work.lead_q[first, 0]))
    assert np.array_equal(np.isfinite(lead_q[last, 1]), np.isfinite(work.lead_q[last, 1]))
    # the plain ends' moves in collision too: nothing dropped
    kept, none = freed_junctions(work, work.lead_q, _Router([]), 50.0)
    assert none == 0 and np.array_equal(np.isnan(kept), np.isnan(work.lead_q))
