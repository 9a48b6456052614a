"""Robot programs of a cell plan, one per robot (programs.arms, ``sprayplan plan --cell ... --program``): issue 18."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from sprayplan.cells import load_cell
from sprayplan.cells.files import read_cell_plan
from sprayplan.cli import main
from sprayplan.config import JobConfig
from sprayplan.export.stl import write_stl_binary
from sprayplan.programs.arms import ArmCell, abb_config, arm_config_bits, kuka_status_turn
from sprayplan.programs.check import check_program
from sprayplan.programs.stage import read_programs
from sprayplan.robots.gantry import load_gun
from sprayplan.robots.opw import PRESETS, load_opw, opw_fk
from tests.helpers import grid_box
from tests.test_cell_plan import CELL, SIZE

FORMATS = ("rapid", "krl")


#: The same cell with KUKA arms (nearer the box: their reach is 0.7 m), for KRL.
KUKA_CELL = CELL.replace("abb-irb2400-10", "kuka-kr6-r700-sixx").replace("900.0", "560.0")


def _run(folder, text, fmt):
    cell = folder / "small2.toml"
    cell.write_text(text)
    part = folder / "box.stl"
    part.write_bytes(write_stl_binary(grid_box(n=8, size=SIZE).triangles))
    out = folder / "out"
    argv = ["-q", "plan", str(part), "--cell", str(cell), "--thickness-um", "50", "-o", str(out)]
    assert main([*argv, "--program", fmt]) == 0
    return {"out": out, "cell": load_cell(cell), "plan": read_cell_plan(out / "cell_plan.json"), "part": part,
            "toml": cell, "fmt": fmt}  # fmt: skip


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The small two-robot box planned with a 50 um target: with ABB arms and RAPID programs, and with KUKA
    arms and KRL programs (one run each for the module)."""
    return {
        "rapid": _run(tmp_path_factory.mktemp("abb"), CELL, "rapid"),
        "krl": _run(tmp_path_factory.mktemp("kuka"), KUKA_CELL, "krl"),
    }


@pytest.fixture(scope="module")
def written(runs):
    return runs["rapid"]


def _random_joints(params, n, rng):
    lower = np.maximum(params.lower, -np.pi)
    upper = np.minimum(params.upper, np.pi)
    return rng.uniform(lower, upper, size=(n, 6))


@pytest.mark.parametrize("name", list(PRESETS))
@pytest.mark.parametrize("fmt", FORMATS)
def test_configuration_data_give_the_joints_back(name, fmt):
    """Random joints: the configuration data of their pose name one solution, and it is the joints (turns aside):
    RAPID's cfx or KRL's S tells the eight branches apart."""
    from sprayplan.cells.spec import cell_from_dict

    cell = cell_from_dict({"name": "one", "robot": [{"name": "a", "model": name, "base_mm": [0, 0, 0]}]})
    arm = ArmCell(cell.robots[0], 200.0)
    rng = np.random.default_rng(7)
    q = _random_joints(load_opw(name), 300, rng)
    poses = arm.poses(q, np.zeros(0))
    config = arm.config_data(q, fmt)
    back, ok = arm.config_solutions(poses, np.zeros(0), config, fmt)
    assert ok.all()
    assert np.allclose(np.angle(np.exp(1j * (back - q))), 0.0, atol=1e-7)
    # every valid solution of one pose has its own configuration number
    sols = arm.solutions(poses, np.zeros(0))
    column = 3 if fmt == "rapid" else 0
    for i in range(len(q)):
        valid = sols.q[i][sols.valid[i]]
        numbers = arm.config_data(valid, fmt)[:, column]
        assert len(set(numbers.tolist())) == len(valid)


@pytest.mark.parametrize("name", list(PRESETS))
def test_the_configuration_bits_are_the_wrist_centre_and_axis_5(name):
    """The wrist centre behind axis 1, recomputed from the flange pose (c4 back along the flange axis, in the
    plane axis 1 turns), and axis 5's sign read off the joints are where ABB's cfx and KUKA's S put them."""
    params = load_opw(name)
    rng = np.random.default_rng(3)
    q = _random_joints(params, 500, rng)
    flange = opw_fk(params, q)
    centre = flange[:, :3, 3] - params.c4 * flange[:, :3, 2]
    t1 = q[:, 0] * params.signs[0] + params.offsets[0]
    x_plane = centre[:, 0] * np.cos(t1) + centre[:, 1] * np.sin(t1)
    back, behind, wrist = arm_config_bits(params, q)
    assert np.array_equal(back, x_plane < 0)
    assert np.array_equal(wrist, q[:, 4] < -1e-9)
    cfx = abb_config(params, q)[:, 3]
    assert np.array_equal(cfx, 4 * (x_plane < 0) + 2 * behind + (q[:, 4] < -1e-9))
    status, turn = kuka_status_turn(params, q).T
    assert np.array_equal(status & 1, (x_plane < 0).astype(int))
    assert np.array_equal((status >> 2) & 1, (q[:, 4] <= 1e-9).astype(int))
    assert np.array_equal(turn, ((q < -1e-9) * (1 << np.arange(6))).sum(axis=1))
    # the two elbow solutions of a pose lie on either side of the lower arm
    from sprayplan.robots.opw import opw_ik

    sols = opw_ik(params, flange[:50])
    bits = np.array([arm_config_bits(params, sols.q[:, j])[1] for j in range(8)]).T  # (50, 8)
    for i in range(50):
        ok = sols.valid[i]
        if ok.all():
            assert bits[i].sum() == 4


def test_an_abb_arm_at_its_zero_is_configuration_0():
    for name in ("abb-irb2400-10", "abb-irb4600-60-205"):
        params = load_opw(name)
        assert abb_config(params, np.radians([0, 0, 0, 0, 30, 0])).tolist() == [[0, 0, 0, 0]]
        assert abb_config(params, np.radians([0, 0, 0, 0, -30, 0]))[0, 3] == 1


def _expected_poses(plan, cell, robot_index):
    """Every waypoint's TCP pose in the cell frame from cell_plan.json alone: the base moved along the track,
    the OPW chain, the gun, the standoff (|tcp - point|) along the gun axis; and the track and whether sprayed."""
    cr = cell.robots[robot_index]
    work = plan["robots"][robot_index]
    params = load_opw(cr.model)
    gun = load_gun(cr.tool).gun2flange
    poses, tracks, spray, reach = [], [], [], []
    for s in work["strokes"]:
        standoff = np.linalg.norm(s["tcp_mm"] - s["points_mm"], axis=1)
        for j in range(len(s["tcp_mm"])):
            base = cr.base2cell.copy()
            if cr.track is not None:
                base[:3, 3] += s["track_mm"][j] * np.asarray(cr.track.axis)
            target = np.eye(4)
            target[2, 3] = standoff[j]
            poses.append(base @ opw_fk(params, s["q_rad"][j])[0] @ gun @ target)
            tracks.append(s["track_mm"][j])
            spray.append(s["kind"] != "transfer")
            reach.append(bool(s["reachable"][j]))
    return np.array(poses), np.array(tracks), np.array(spray), np.array(reach)


def _lead_poses(plan, cell, robot_index, poses):
    """The run-ups' starts and run-outs' ends of a robot from cell_plan.json alone (its ``leads``: waypoint,
    side, joints, track), by the same chain as :func:`_expected_poses` with their waypoint's standoff; and
    their waypoints and sides."""
    cr = cell.robots[robot_index]
    work = plan["robots"][robot_index]
    leads = work.get("leads")
    if leads is None or not len(leads["waypoint"]):
        return np.zeros((0, 4, 4)), np.zeros(0, int), np.zeros(0, int)
    params = load_opw(cr.model)
    gun = load_gun(cr.tool).gun2flange
    standoff = np.concatenate([np.linalg.norm(s["tcp_mm"] - s["points_mm"], axis=1) for s in work["strokes"]])
    out = []
    for k, q, track in zip(leads["waypoint"], leads["q_rad"], leads["track_mm"]):
        base = cr.base2cell.copy()
        if cr.track is not None:
            base[:3, 3] += track * np.asarray(cr.track.axis)
        target = np.eye(4)
        target[2, 3] = standoff[k]
        out.append(base @ opw_fk(params, q)[0] @ gun @ target)
    return np.array(out), np.asarray(leads["waypoint"], int), np.asarray(leads["side"], int)


@pytest.mark.parametrize("fmt", FORMATS)
def test_each_robots_program_read_back_moves_to_its_waypoints(runs, fmt):
    """The programs read back by their own strict readers: every linear target is a reached spray waypoint of
    its robot (pose from cell_plan.json's joints, 0.01 mm / 0.01 deg), a run-up's start or a run-out's end of
    the plan, or an approach / retract on the gun axis of a waypoint or of a run-up's start or run-out's end;
    the track is the external axis; every reached spray waypoint is moved to except those the summary lists as
    left out; every run-up and run-out of the plan is made but those the summary counts as left out."""
    written = runs[fmt]
    plan, cell = written["plan"], written["cell"]
    job = JobConfig()
    for i, cr in enumerate(cell.robots):
        folder = written["out"] / "programs" / cr.name / fmt
        axes = 0 if cr.track is None else 1
        read = read_programs(folder, job, fmt, axes)
        poses, tracks, spray, reach = _expected_poses(plan, cell, i)
        leads, _, _ = _lead_poses(plan, cell, i, poses)
        want = np.flatnonzero(spray & reach)
        axis_bases = np.concatenate([poses[want], leads])
        hit, leads_hit = set(), set()
        for move in read.moves:
            assert len(move.external_mm) == axes
            if move.kind != "linear":
                continue
            d = np.linalg.norm(poses[want, :3, 3] - move.pose[:3, 3], axis=1)
            near = np.flatnonzero(d <= 0.01)  # (two strokes may meet at one point with other gun axes)
            if len(near):
                r = np.einsum("nji,jk->nik", poses[want[near], :3, :3], move.pose[:3, :3])
                angle = np.degrees(np.arccos(np.clip((np.trace(r, axis1=1, axis2=2) - 1) / 2, -1, 1)))
                assert angle.min() <= 0.01
                k = int(want[near[np.argmin(angle)]])
                if axes:
                    assert abs(move.external_mm[0] - tracks[k]) <= 1e-3
                hit.add(k)
                continue
            d = np.linalg.norm(leads[:, :3, 3] - move.pose[:3, 3], axis=1) if len(leads) else np.zeros(0)
            if (d <= 0.01).any():  # a run-up's start or a run-out's end
                leads_hit.add(int(np.argmin(d)))
                continue
            # an approach or retract: on the gun axis of a waypoint, a run-up's start or a run-out's end, behind it
            rel = move.pose[:3, 3] - axis_bases[:, :3, 3]
            along = np.einsum("ij,ij->i", rel, axis_bases[:, :3, 2])
            off = np.linalg.norm(rel - along[:, None] * axis_bases[:, :3, 2], axis=1)
            assert ((off <= 0.01) & (along < 0)).any()
        summary = json.loads((folder / "summary.json").read_text())
        counts = summary["counts"]
        assert len(leads) > 0 and counts["run_ups"] + counts["run_outs"] > 0
        assert len(leads_hit) == counts["run_ups"] + counts["run_outs"]
        assert counts["run_ups"] + counts["run_outs"] + counts["run_ups_left_out"] == len(leads)
        unapproachable = len(summary["left_out"]["unapproachable_waypoints"])
        duplicates = summary["counts"]["duplicate_waypoints"]
        assert len(hit) >= len(want) - unapproachable - duplicates
        assert len(hit) <= len(want)
        assert summary["left_out"]["colliding_waypoints"] == []  # planned without --collisions


def test_a_wrong_configuration_in_a_program_fails_the_check(written, tmp_path):
    """Change one target's cfx in the left robot's RAPID: the read-back check finds it."""
    import shutil

    from sprayplan.programs.arms import arm_plan
    from sprayplan.programs.model import LINEAR

    src = written["out"] / "programs" / "left" / "rapid"
    folder = tmp_path / "rapid"
    shutil.copytree(src, folder)
    module = sorted(p for p in folder.glob("*.mod") if not p.name.endswith("_main.mod"))[0]
    lines = module.read_text().splitlines()
    k = next(n for n, line in enumerate(lines) if "MoveL [[" in line)
    parts = lines[k].split("],[")
    cf = parts[2].split(",")  # [cf1, cf4, cf6, cfx]
    cf[3] = str((int(cf[3]) + 2) % 8)
    parts[2] = ",".join(cf)
    lines[k] = "],[".join(parts)
    module.write_text("\n".join(lines) + "\n")
    # the plan the program was written from, rebuilt from the same cell plan in memory
    from sprayplan.cells.plan import plan_cell
    from sprayplan.io.load import load_part

    job = JobConfig().replace(coating={"thickness_um": 50.0})
    plan = plan_cell(load_part(str(written["part"])), written["cell"], job)
    arm = ArmCell(written["cell"].robots[0], plan.job.paths.standoff_mm)
    robot_plan = arm_plan(plan.robots[0], arm)
    good = check_program(read_programs(src, plan.job, "rapid", 1), robot_plan, plan.job, arm)
    assert good.ok, good.failures[:3]
    bad = check_program(read_programs(folder, plan.job, "rapid", 1), robot_plan, plan.job, arm)
    assert not bad.ok and any("configuration" in f for f in bad.failures)
    assert sum(m.kind == LINEAR for m in read_programs(folder, plan.job, "rapid", 1).moves) > 0


def test_urscript_or_a_five_axis_robot_in_a_cell_is_exit_2_and_nothing_written(written, tmp_path, capsys):
    out = tmp_path / "o"
    args = ["plan", str(written["part"]), "--cell", str(written["part"].parent / "small2.toml"), "-o", str(out)]
    assert main([*args, "--program", "urscript"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "urscript" in err[0]
    five = tmp_path / "five.toml"
    five.write_text('name = "five"\n[[robot]]\nname = "r"\nmodel = "r5150"\nbase_mm = [0.0, 600.0, 0.0]\n')
    argv = ["plan", str(written["part"]), "--cell", str(five), "-o", str(out), "--program", "krl"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "five-axis" not in err[0] and "5 axes" in err[0]
    assert not out.exists()


def test_the_fixed_robot_has_no_external_axis_and_the_track_robot_one(runs):
    text = (runs["rapid"]["out"] / "programs" / "right" / "rapid").glob("*_001.mod")
    body = next(text).read_text()
    assert "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]" in body
    left = next((runs["krl"]["out"] / "programs" / "left" / "krl").glob("*_001.dat")).read_text()
    e1 = [float(line.split("E1 ")[1].split(",")[0]) for line in left.splitlines() if "E1 " in line]
    lo, hi = runs["krl"]["cell"].robots[0].track.range_mm
    assert e1 and all(lo - 1e-6 <= v <= hi + 1e-6 for v in e1) and len(set(e1)) > 1


@pytest.mark.parametrize("fmt", FORMATS)
def test_the_schedules_waits_are_in_the_programs_before_their_strokes(runs, tmp_path, fmt):
    """A robot whose schedule waits before some strokes (``RobotWork.wait_s``, as ``cells.schedule`` sets it):
    each wait is written once, before the approach of its stroke's first run, read back there, and the check
    fails when a written wait is changed."""
    import dataclasses

    from sprayplan.cells.plan import plan_cell
    from sprayplan.io.load import load_part
    from sprayplan.programs.arms import arm_plan, build_cell_programs, write_cell_programs

    written = runs[fmt]
    job = JobConfig()
    plan = plan_cell(load_part(str(written["part"])), written["cell"], job)
    work = plan.robots[1]
    spray = [i for i, s in enumerate(work.strokes) if s.spray_on]
    waits = np.zeros(len(work.strokes))
    waits[spray[1]], waits[spray[3]] = 2.5, 0.75
    plan = dataclasses.replace(plan, robots=(plan.robots[0], dataclasses.replace(work, wait_s=waits)))
    built = build_cell_programs(plan, plan.job, (fmt,))
    write_cell_programs(tmp_path / "programs", built, plan.job)
    folder = tmp_path / "programs" / "right" / fmt
    read = read_programs(folder, plan.job, fmt, 0)
    got = sorted(m.wait_s for m in read.moves if m.wait_s > 0)
    assert got == [0.75, 2.5]
    text = "".join(p.read_text() for p in sorted(folder.iterdir()) if p.suffix in (".mod", ".src"))
    word = "WaitTime \\InPos, " if fmt == "rapid" else "WAIT SEC "
    assert text.count(word) == 2 and f"{word}2.500" in text
    arm = ArmCell(written["cell"].robots[1], plan.job.paths.standoff_mm)
    robot_plan = arm_plan(plan.robots[1], arm)
    assert check_program(read, robot_plan, plan.job, arm).ok
    for path in folder.iterdir():
        if path.suffix in (".mod", ".src") and word + "2.500" in path.read_text():
            path.write_text(path.read_text().replace(word + "2.500", word + "1.500"))
    bad = check_program(read_programs(folder, plan.job, fmt, 0), robot_plan, plan.job, arm)
    assert not bad.ok and any("waits 1.5 s" in f for f in bad.failures)


@pytest.mark.parametrize("fmt", FORMATS)
def test_export_of_a_cell_plan_folder_writes_the_same_programs(runs, tmp_path, capsys, fmt):
    """``sprayplan export OUT --format rapid`` on a cell plan folder rebuilds each robot's programs from
    cell_plan.json alone (its settings: the gun speed the plan chose): the same files, and read back the same
    moves (the joints kept to 1e-12 rad in the file move a blend's last written digit at most)."""
    written = runs[fmt]
    out = tmp_path / "progs"
    assert main(["-q", "export", str(written["out"]), "--format", fmt, "-o", str(out)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and all("read back and checked" in line for line in lines)
    for robot in ("left", "right"):
        mine = out / robot / fmt
        theirs = written["out"] / "programs" / robot / fmt
        names = sorted(p.name for p in theirs.iterdir() if p.name != "summary.json")
        assert names == sorted(p.name for p in mine.iterdir() if p.name != "summary.json")
        axes = 1 if robot == "left" else 0
        a = read_programs(mine, JobConfig(), fmt, axes).moves
        b = read_programs(theirs, JobConfig(), fmt, axes).moves
        assert len(a) == len(b)
        for m, n in zip(a, b):
            assert (m.kind, m.config, len(m.events), m.wait_s) == (n.kind, n.config, len(n.events), n.wait_s)
            assert np.allclose(m.external_mm, n.external_mm, atol=1e-4)
            assert abs(m.speed_mm_s - n.speed_mm_s) <= 1e-3 and abs(m.blend_mm - n.blend_mm) <= 2e-4
            if m.kind == "linear":
                assert np.allclose(m.pose, n.pose, atol=1e-4)
            else:
                assert np.allclose(m.joints, n.joints, atol=1e-8)


def test_export_of_a_cell_plan_without_settings_or_with_urscript_is_exit_2(written, tmp_path, capsys):
    import shutil

    folder = tmp_path / "old"
    shutil.copytree(written["out"], folder, ignore=shutil.ignore_patterns("programs"))
    assert main(["export", str(folder), "--format", "urscript"]) == 2
    assert "urscript" in capsys.readouterr().err
    data = json.loads((folder / "cell_plan.json").read_text())
    del data["settings"]
    (folder / "cell_plan.json").write_text(json.dumps(data))
    assert main(["export", str(folder), "--format", "rapid"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cell_plan.json" in err[0] and "settings" in err[0]
    assert not (folder / "programs").exists()


def test_the_cell_viewer_draws_the_plan(written):
    """cell.html: the strokes drawn are each robot's spray strokes' gun tips (nothing thinned on this box), each
    robot's faces are its areas, the film's colours lie within the film's range, the bases are where the cell
    puts them."""
    from sprayplan.view.cell_html import PLOT_ID
    from sprayplan.view.html import read_viewer_figure

    page = (written["out"] / "cell.html").read_text()
    traces, _ = read_viewer_figure(page, PLOT_ID)
    by_name = {t["name"]: t for t in traces}
    plan = written["plan"]
    for i, cr in enumerate(written["cell"].robots):
        t = by_name[f"{cr.name} strokes"]
        drawn = np.column_stack([t["x"], t["y"], t["z"]]).astype(float)
        drawn = drawn[np.isfinite(drawn).all(axis=1)]
        tips = np.vstack([s["tcp_mm"] for s in plan["robots"][i]["strokes"] if s["kind"] != "transfer"])
        assert drawn.shape == tips.shape and np.allclose(drawn, tips, atol=0.01)
        base = by_name[next(n for n in by_name if n.startswith(f"{cr.name} base"))]
        assert np.allclose([base["x"][0], base["y"][0], base["z"][0]], cr.base_path_mm()[0], atol=0.01)
    summary = json.loads(page.split("id='sprayplan-summary'>")[1].split("</script>")[0])
    assert summary["drawn"]["drawn_waypoints"] == summary["drawn"]["waypoints"]
    areas = list(csv_rows(written["out"] / "areas.csv"))
    for cr in written["cell"].robots:
        faces = sum(1 for row in areas if row["robot"] == cr.name)
        assert len(by_name[f"areas: {cr.name}"]["i"]) == faces
    film = by_name["film (um)"]["intensity"]
    coating = json.loads((written["out"] / "coating.json").read_text())
    assert film.min() >= coating["whole"]["min_um"] - 1e-3 and film.max() <= coating["whole"]["max_um"] + 1e-3


def csv_rows(path):
    import csv

    with open(path, newline="") as handle:
        yield from csv.DictReader(handle)


@pytest.mark.parametrize("robot, formats", [("ur5", FORMATS), ("kuka-kr6-r700-sixx", ("krl",))])
def test_one_fixed_robot_gets_its_programs_checked(tmp_path, robot, formats):
    """``plan --robot NAME --program krl --program rapid``: a UR arm (the gantry's convention for its data) and
    the KUKA arm (axes 1, 4, 6 turning the other way) get programs that read back as the plan; no external axis."""
    from sprayplan.types import Part

    plate = grid_box(n=4, size=(240.0, 160.0, 20.0))
    part = tmp_path / "plate.stl"
    part.write_bytes(write_stl_binary(Part(plate.vertices + [420.0, 0.0, 60.0], plate.faces).triangles))
    out = tmp_path / "out"
    argv = ["-q", "plan", str(part), "--robot", robot, "--spacing-mm", "40"]
    assert main([*argv, *(a for f in formats for a in ("--program", f)), "-o", str(out)]) == 0
    plan = read_cell_plan(out / "cell_plan.json")
    reached = sum(int(s["reachable"].sum()) for s in plan["robots"][0]["strokes"] if s["kind"] != "transfer")
    for fmt in formats:
        summary = json.loads((out / "programs" / robot / fmt / "summary.json").read_text())
        assert summary["check"]["waypoints"] > 0.9 * reached
        read = read_programs(out / "programs" / robot / fmt, JobConfig(), fmt, 0)
        assert all(len(m.external_mm) == 0 for m in read.moves)


def test_program_motions_are_checked_with_the_collision_model(written, tmp_path):
    """``plan --cell ... --collisions --program rapid``: the program's joint moves, approaches, retracts, run-ups
    and run-outs are sampled and checked (``summary.json``: ``counts.program_motions``), one motion each; and a motion ending in
    the box is found, one between two poses clear of it is not."""
    pytest.importorskip("coal")
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.plan import plan_cell
    from sprayplan.io.load import load_part
    from sprayplan.programs.arms import motions_checked
    from sprayplan.programs.model import JOINT, Move

    out = tmp_path / "out"
    argv = ["-q", "plan", str(written["part"]), "--cell", str(written["part"].parent / "small2.toml")]
    assert main([*argv, "--collisions", "--program", "rapid", "-o", str(out)]) == 0
    for robot in ("left", "right"):
        folder = out / "programs" / robot / "rapid"
        found = json.loads((folder / "summary.json").read_text())["counts"]["program_motions"]
        axes = 1 if robot == "left" else 0
        moves = read_programs(folder, JobConfig(), "rapid", axes).moves
        counts = json.loads((folder / "summary.json").read_text())["counts"]
        expected = sum(1 for m in moves[1:] if m.kind == "joint") + 2 * sum(
            1 for a, b in itertools.pairwise(moves) if a.kind == "joint" and b.kind == "linear"
        )  # joint moves, approaches and retracts
        expected += counts["run_ups"] + counts["run_outs"]
        assert found["motions_checked"] == expected and found["samples"] >= expected
        # the plan's waypoints still in collision are left out, each listed
        data = read_cell_plan(out / "cell_plan.json")
        work = next(r for r in data["robots"] if r["name"] == robot)
        hit = sum(int((s["collides"] & s["reachable"]).sum()) for s in work["strokes"] if s["kind"] != "transfer")
        left = json.loads((folder / "summary.json").read_text())["left_out"]["colliding_waypoints"]
        assert len(left) == hit
    # a constructed motion: from the start joints into the box's middle, and a small turn of axis 1 up high
    job = JobConfig().replace(collision={"check": True})
    plan = plan_cell(load_part(str(written["part"])), written["cell"], job)
    (arm,) = cell_arms(written["cell"], plan.part, job.collision)[1:]
    cell = ArmCell(written["cell"].robots[1], 0.0)
    inside = np.eye(4)
    inside[:3, :3] = np.diag([1.0, -1.0, -1.0])
    inside[:3, 3] = plan.part.vertices.mean(axis=0)
    q, ok = cell.joints_on_branch(inside[None], np.zeros(0), 0, cell.home_joints)
    assert ok[0]
    home = cell.home_joints
    turned = home + np.r_[0.2, 0, 0, 0, 0, 0]
    at = lambda joints: Move(JOINT, "transfer", np.eye(4), joints, np.zeros(0))
    hit = motions_checked(arm, [at(home), at(q[0])])
    clear = motions_checked(arm, [at(home), at(turned)])
    assert hit["motions_in_collision"] == 1 and clear["motions_in_collision"] == 0


def test_an_abb_arm_gets_no_krl_and_a_kuka_arm_no_rapid(runs, tmp_path, capsys):
    """Each maker's controller runs its own format: the other is refused with one line, before any planning."""
    for fmt, run in (("krl", runs["rapid"]), ("rapid", runs["krl"])):
        out = tmp_path / fmt
        argv = ["plan", str(run["part"]), "--cell", str(run["toml"]), "--program", fmt, "-o", str(out)]
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"not {fmt}" in err[0] and "left" in err[0]
        assert not out.exists()
        assert main(["export", str(run["out"]), "--format", fmt, "-o", str(out)]) == 2
        assert f"not {fmt}" in capsys.readouterr().err
        assert not out.exists()


def test_view_of_a_cell_folder_names_its_viewer(written, capsys):
    assert main(["view", str(written["out"])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cell.html" in err[0]


def _split_at(work, i: int, m: int, flip: bool):
    """``work`` with spray stroke ``i`` cut in two that share its waypoint ``m`` (the first ends there, the
    second starts there again), joined by a transfer: the second on the same joints, or with the wrist turned
    over (axis 4 +-180 degrees, axis 5 negated, axis 6 +-180: the same gun pose on another branch)."""
    import dataclasses

    from sprayplan.cells.seams import cut_stroke
    from sprayplan.cells.work import transfer_stroke

    starts = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
    a, b = starts[i], starts[i + 1]
    stroke = work.strokes[i]
    first, second = cut_stroke(stroke, 0, m + 1), cut_stroke(stroke, m, b - a)
    rows = [np.arange(a, a + m + 1), np.array([a + m, a + m]), np.arange(a + m, b)]
    q = [work.q[r].copy() for r in rows]
    if flip:
        turn = np.where(q[2][:, 3] > 0, -np.pi, np.pi)
        q[2][:, 3] += turn
        q[2][:, 4] *= -1.0
        q[2][:, 5] += np.where(q[2][:, 5] > 0, -np.pi, np.pi)
        q[1][1] = q[2][0]
    pick = lambda x: np.concatenate([x[:a], *(x[r] for r in rows), x[b:]])
    joints = np.concatenate([work.q[:a], *q, work.q[b:]])
    strokes = work.strokes[:i] + (first, transfer_stroke(first, second), second) + work.strokes[i + 1 :]
    area = np.concatenate([work.area[:i], [work.area[i], -1, work.area[i]], work.area[i + 1 :]])
    return dataclasses.replace(
        work, strokes=strokes, area=area, q=joints, track_mm=pick(work.track_mm), roll_deg=pick(work.roll_deg),
        reachable=pick(work.reachable), collides=None, t_s=None, wait_s=None,
        lead_q=pick(work.lead_q), lead_track_mm=pick(work.lead_track_mm), lead_s=None,
    )  # fmt: skip


def _a_whole_stroke(written):
    """The small box planned again: ``(job, plan, the right robot's work, the rows where its strokes start,
    the index of its first spray stroke of 8 waypoints or more, all reached)``."""
    from sprayplan.cells.plan import plan_cell
    from sprayplan.io.load import load_part

    job = JobConfig()
    plan = plan_cell(load_part(str(written["part"])), written["cell"], job)
    work = plan.robots[1]
    starts = np.r_[0, np.cumsum([len(s) for s in work.strokes])]
    i = next(
        k
        for k, s in enumerate(work.strokes)
        if s.spray_on and len(s) >= 8 and work.reachable[starts[k] : starts[k + 1]].all()
    )
    return job, plan, work, starts, i


@pytest.mark.parametrize("flip", [False, True])
def test_a_stroke_that_starts_where_the_one_before_ended_reads_back_as_its_own(written, tmp_path, flip):
    """A cell robot's stroke may start at the gun pose where the stroke before ended (a run solved on its own
    with its free neighbour, ``cells.repair.free_work``), on the same joints or another branch: the read-back
    check takes each run for its own stroke, so the programs pass and every spray waypoint is moved to."""
    import dataclasses

    from sprayplan.programs.arms import arm_plan, build_cell_programs

    job, plan, work, starts, i = _a_whole_stroke(written)
    m = len(work.strokes[i]) // 2
    split = _split_at(work, i, m, flip)
    arm = ArmCell(written["cell"].robots[1], plan.job.paths.standoff_mm)
    at = starts[i] + m  # the shared waypoint: the first stroke's last, the second's first (two rows on)
    assert np.allclose(arm.poses(split.q[[at]], [])[0], arm.poses(split.q[[at + 3]], [])[0], atol=1e-9)
    assert (arm.branches(split.q[[at]])[0] != arm.branches(split.q[[at + 3]])[0]) == flip
    assert ((split.q >= arm.lower - 1e-9) & (split.q <= arm.upper + 1e-9)).all()
    results = []
    for robot in (work, split):
        built = build_cell_programs(dataclasses.replace(plan, robots=(plan.robots[0], robot)), job, ("rapid",))
        folder = tmp_path / f"rapid{len(results)}"
        folder.mkdir()
        for name, text in built[1].builts[0].files.items():
            (folder / name).write_text(text)
        results.append(check_program(read_programs(folder, job, "rapid", 0), arm_plan(robot, arm), job, arm))
    whole, result = results
    assert whole.ok and result.ok, result.failures[:3]
    # the same waypoints moved to and left out, the shared one twice (once for each stroke)
    assert result.waypoints == whole.waypoints + 1 and len(result.left_out) == len(whole.left_out)


@pytest.mark.parametrize("flip", [False, True])
def test_a_stroke_starting_where_an_unapproachable_end_was_reads_back_as_its_own(written, tmp_path, monkeypatch, flip):
    """The shared waypoint of a stroke cut in two (as in the test above) left out of the first stroke's run
    because its retract is out of reach there (``build._back_off``: on the first stroke's branch only), while
    the second stroke starts there: the approach ends at a pose that the first stroke's unmatched last waypoint
    has too, and the check must take the second stroke's (the run goes on along it), not be shifted by one
    waypoint onto the first's (the masked SUV's roof program in session 31: 10 mm off, 200 differences)."""
    import dataclasses

    from sprayplan.programs import build
    from sprayplan.programs.arms import arm_plan, build_cell_programs

    job, plan, work, starts, i = _a_whole_stroke(written)
    m = len(work.strokes[i]) // 2
    split = _split_at(work, i, m, flip)
    at = starts[i] + m  # the first stroke's last waypoint; the second stroke's first is three rows on
    arm = ArmCell(written["cell"].robots[1], plan.job.paths.standoff_mm)
    cut = dataclasses.replace(plan, robots=(plan.robots[0], split))
    left_out = lambda b: {(w["stroke"], w["waypoint"]) for w in b.builts[0].program.report["unapproachable_waypoints"]}
    before = left_out(build_cell_programs(cut, job, ("rapid",))[1])
    plain = build._back_off
    monkeypatch.setattr(
        build, "_back_off", lambda cell, cfg, poses, q9, k: None if k == at else plain(cell, cfg, poses, q9, k)
    )
    built = build_cell_programs(cut, job, ("rapid",))[1]
    assert left_out(built) - before == {(i, m)}  # the first stroke's last waypoint, and only it
    folder = tmp_path / "rapid"
    folder.mkdir()
    for name, text in built.builts[0].files.items():
        (folder / name).write_text(text)
    result = check_program(read_programs(folder, job, "rapid", 0), arm_plan(split, arm), job, arm)
    assert result.ok, result.failures[:3]
    # the second stroke's first waypoint moved to, the first stroke's last the one left out
    assert (0, int(at)) in result.left_out and (0, int(at) + 3) not in result.left_out


def test_a_stroke_cut_between_two_waypoints_whose_run_up_starts_at_the_last_one_reads_back(written, tmp_path):
    """A stroke cut between waypoints m and m + 1 (``cells.repair.free_work``), the first piece running out to
    waypoint m + 1's pose and the second's run-up starting at waypoint m's (``cells.runups`` along the stroke):
    the second run's approach ends at the pose of the first's last waypoint, and the read-back must take it for
    the run-up's start, not for that waypoint (the masked SUV's roof program in session 32: one waypoint off,
    10 mm, 200 differences)."""
    import dataclasses

    from sprayplan.cells.seams import cut_stroke
    from sprayplan.cells.work import transfer_stroke
    from sprayplan.programs.arms import arm_plan, build_cell_programs

    job, plan, work, starts, i = _a_whole_stroke(written)
    a, b = starts[i], starts[i + 1]
    m = (b - a) // 2
    stroke = work.strokes[i]
    first, second = cut_stroke(stroke, 0, m + 1), cut_stroke(stroke, m + 1, b - a)
    rows = [np.arange(a, a + m + 1), np.array([a + m, a + m + 1]), np.arange(a + m + 1, b)]
    pick = lambda x: np.concatenate([x[:a], *(x[r] for r in rows), x[b:]])
    lead_q, lead_track = pick(work.lead_q).copy(), pick(work.lead_track_mm).copy()
    last, start = a + m, a + m + 3  # the first piece's last waypoint, the second's first (after the transfer)
    lead_q[last, 1], lead_q[start, 0] = work.q[a + m + 1], work.q[a + m]
    lead_track[last, 1], lead_track[start, 0] = work.track_mm[a + m + 1], work.track_mm[a + m]
    cut = dataclasses.replace(
        work,
        strokes=work.strokes[:i] + (first, transfer_stroke(first, second), second) + work.strokes[i + 1 :],
        area=np.concatenate([work.area[:i], [work.area[i], -1, work.area[i]], work.area[i + 1 :]]),
        q=pick(work.q), track_mm=pick(work.track_mm), roll_deg=pick(work.roll_deg), reachable=pick(work.reachable),
        collides=None, t_s=None, wait_s=None, lead_q=lead_q, lead_track_mm=lead_track, lead_s=None,
    )  # fmt: skip
    arm = ArmCell(written["cell"].robots[1], plan.job.paths.standoff_mm)
    poses = arm.poses(cut.q, [])
    assert np.allclose(arm.poses(lead_q[[start], 0], [])[0], poses[last], atol=1e-9)
    built = build_cell_programs(dataclasses.replace(plan, robots=(plan.robots[0], cut)), job, ("rapid",))[1]
    program = built.builts[0]
    assert program.program.report["run_ups"] >= 1 and program.program.report["run_outs"] >= 1
    folder = tmp_path / "rapid"
    folder.mkdir()
    for name, text in program.files.items():
        (folder / name).write_text(text)
    result = check_program(read_programs(folder, job, "rapid", 0), arm_plan(cut, arm), job, arm)
    assert result.ok, result.failures[:3]
    assert (0, int(last)) not in result.left_out and (0, int(start)) not in result.left_out


def test_a_scheduled_robots_programs_start_and_end_where_the_schedule_has_it(written, tmp_path):
    """With the cell's schedule (``cells.schedule.scheduled``): each robot's program starts where the schedule
    has it at time 0 and ends at the park the schedule gives it (joints and track), both read back from
    cell_plan.json and from the program, and the programs pass their read-back check."""
    import dataclasses

    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.files import cell_plan_dict, cell_plan_from_file
    from sprayplan.cells.plan import plan_cell, schedule_aids
    from sprayplan.cells.schedule import scheduled
    from sprayplan.config import CollisionConfig
    from sprayplan.io.load import load_part
    from sprayplan.programs.arms import build_cell_programs, write_cell_programs

    job = JobConfig()
    plan = plan_cell(load_part(str(written["part"])), written["cell"], job)
    arms = cell_arms(plan.cell, plan.part, CollisionConfig(check=True))
    robots, summary = scheduled(plan.cell, plan.robots, arms, plan.job, *schedule_aids(plan.cell, arms, plan.part, job))
    # the robot with the longest work goes first and never waits (cells.schedule, step 2)
    first = summary["priority"][0]
    own = {n: t - summary["waits"][n]["waited_s"] for n, t in summary["robot_time_s"].items()}
    assert sorted(summary["priority"]) == sorted(r.name for r in plan.cell.robots)
    assert summary["waits"][first]["waited_s"] == 0 and own[first] == max(own.values())
    # and whatever the cell's order: the robots given the other way round are scheduled the same
    turned = dataclasses.replace(plan.cell, robots=plan.cell.robots[::-1])
    _, back = scheduled(
        turned, plan.robots[::-1], arms[::-1], plan.job, *schedule_aids(turned, arms[::-1], plan.part, job)
    )
    assert back["priority"] == summary["priority"] and back["waits"] == summary["waits"]
    assert back["cycle_time_s"] == summary["cycle_time_s"]
    (tmp_path / "cell_plan.json").write_text(json.dumps(cell_plan_dict(dataclasses.replace(plan, robots=robots))))
    back = cell_plan_from_file(tmp_path / "cell_plan.json")
    built = build_cell_programs(back, back.job, ("rapid",))
    write_cell_programs(tmp_path / "programs", built, back.job)  # raises if a program read back is not its plan
    for k, (cr, work) in enumerate(zip(plan.cell.robots, robots)):
        np.testing.assert_allclose(back.robots[k].ends_q, work.ends_q, atol=1e-11)
        np.testing.assert_allclose(back.robots[k].ends_track_mm, work.ends_track_mm, atol=1e-6)
        # the park is not where the work ended, and it is free of the part
        park, at = work.ends_q[1], work.ends_track_mm[1:]
        assert not np.allclose(park, work.q[-1]) and not arms[k].check(park[None], at).collides[0]
        axes = 0 if cr.track is None else 1
        read = read_programs(tmp_path / "programs" / cr.name / "rapid", back.job, "rapid", axes)
        for move, row in ((read.moves[0], 0), (read.moves[-1], 1)):
            assert move.kind == "joint"
            np.testing.assert_allclose(move.joints, work.ends_q[row], atol=1e-7)
            if axes:
                assert move.external_mm[0] == pytest.approx(work.ends_track_mm[row], abs=1e-3)


def test_a_park_route_is_moved_through_read_back_and_kept_in_cell_plan_json(written, tmp_path):
    """A robot whose schedule routes it to its end park (``RobotWork.park_route_q``, ``cells.schedule``) moves
    through the route's nodes (joint moves, with the track) after its last retract and before the park; the
    plan keeps the route through cell_plan.json, the program reads back equal to it, and a program whose
    route is not the plan's fails the check."""
    import dataclasses

    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.files import cell_plan_dict, cell_plan_from_file
    from sprayplan.cells.plan import plan_cell
    from sprayplan.cells.schedule import scheduled
    from sprayplan.config import CollisionConfig
    from sprayplan.io.load import load_part
    from sprayplan.programs.arms import arm_plan, build_cell_programs, write_cell_programs

    job = JobConfig()
    plan = plan_cell(load_part(str(written["part"])), written["cell"], job)
    arms = cell_arms(plan.cell, plan.part, CollisionConfig(check=True))
    robots, _ = scheduled(plan.cell, plan.robots, arms, plan.job)
    work = robots[0]
    nodes = np.vstack([work.q[-1] + 0.1, (work.q[-1] + work.ends_q[1]) / 2])  # two nodes on the way
    tracks = np.r_[work.track_mm[-1], (work.track_mm[-1] + work.ends_track_mm[1]) / 2]
    routed = dataclasses.replace(work, park_route_q=nodes, park_route_track_mm=tracks)
    robots = (routed, *robots[1:])
    (tmp_path / "cell_plan.json").write_text(json.dumps(cell_plan_dict(dataclasses.replace(plan, robots=robots))))
    back = cell_plan_from_file(tmp_path / "cell_plan.json")
    np.testing.assert_allclose(back.robots[0].park_route_q, nodes, atol=1e-11)
    np.testing.assert_allclose(back.robots[0].park_route_track_mm, tracks, atol=1e-6)
    assert back.robots[1].park_route_q is None
    built = build_cell_programs(back, back.job, ("rapid",))
    write_cell_programs(tmp_path / "programs", built, back.job)  # raises if a program read back is not its plan
    cr = plan.cell.robots[0]
    axes = 0 if cr.track is None else 1
    read = read_programs(tmp_path / "programs" / cr.name / "rapid", back.job, "rapid", axes)
    *_, retract, one, two, park, end = read.moves  # (the station's end, then the program's: the same park)
    assert retract.kind == "linear" and [one.kind, two.kind, park.kind, end.kind] == ["joint"] * 4
    np.testing.assert_allclose([one.joints, two.joints, park.joints], [*nodes, work.ends_q[1]], atol=1e-7)
    if axes:
        np.testing.assert_allclose([one.external_mm[0], two.external_mm[0]], tracks, atol=1e-3)
    # the program of the routed plan against the plan with another route: not its plan
    arm = ArmCell(cr, back.job.paths.standoff_mm)
    other = dataclasses.replace(back.robots[0], park_route_q=nodes[::-1].copy())
    assert check_program(read, arm_plan(back.robots[0], arm), back.job, arm).ok
    failed = check_program(read, arm_plan(other, arm), back.job, arm)
    assert not failed.ok and "not the plan's route" in str(failed.failures[0])
