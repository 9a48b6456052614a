"""A whole part painted by the robots of a cell (cells.plan, cells.files, ``sprayplan plan --cell``): issue 18."""

from __future__ import annotations

import contextlib
import csv
import io

import numpy as np
import pytest

from sprayplan.cells import load_cell
from sprayplan.cells.files import read_cell_plan
from sprayplan.cells.plan import plan_cell
from sprayplan.cli import main
from sprayplan.config import JobConfig
from sprayplan.errors import ConfigError
from sprayplan.export.stl import write_stl_binary
from sprayplan.surface.normals import outward_face_normals
from sprayplan.surface.poses import poses_at
from tests.helpers import grid_box

CELL = """name = "small2"
[[robot]]
name = "left"
model = "abb-irb2400-10"
base_mm = [0.0, 900.0, 0.0]
base_rpy_deg = [0.0, 0.0, -90.0]
track = { axis = "x", range_mm = [-400.0, 400.0] }

[[robot]]
name = "right"
model = "abb-irb2400-10"
base_mm = [0.0, -900.0, 0.0]
base_rpy_deg = [0.0, 0.0, 90.0]
"""
SIZE = (600.0, 300.0, 200.0)


def _rot_z(deg):
    """(..., 4, 4) turns about z by ``deg`` (a number or an array: one a waypoint)."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    out = np.broadcast_to(np.eye(4), (*np.shape(deg), 4, 4)).copy()
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    return out


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The box planned with a 50 um target by `sprayplan plan --cell` (one run for the module)."""
    folder = tmp_path_factory.mktemp("cell")
    cell = folder / "small2.toml"
    cell.write_text(CELL)
    part = folder / "box.stl"
    part.write_bytes(write_stl_binary(grid_box(n=8, size=SIZE).triangles))
    out = folder / "out"
    argv = ["-q", "plan", str(part), "--cell", str(cell), "--thickness-um", "50", "--samples", "420", "-o", str(out)]
    said = io.StringIO()
    with contextlib.redirect_stdout(said):
        assert main(argv) == 0
    plan = read_cell_plan(out / "cell_plan.json")
    return {"out": out, "cell": cell, "part": part, "plan": plan, "stdout": said.getvalue()}


def test_every_reached_waypoint_is_where_the_robot_puts_the_gun(planned):
    """FK(q) at the waypoint's track position, with its roll, is the waypoint's gun pose."""
    cell = load_cell(planned["cell"])
    checked = 0
    for robot, work in zip(cell.robots, planned["plan"]["robots"]):
        assert work["name"] == robot.name
        for s in work["strokes"]:
            ok = s["reachable"]
            if not ok.any():
                continue
            want = poses_at(s["tcp_mm"][ok], s["normals"][ok]) @ _rot_z(s["roll_deg"][ok])
            got = np.stack([robot.robot(t).fk(q[None])[0] for t, q in zip(s["track_mm"][ok], s["q_rad"][ok])])
            arm = robot.robot(0.0)
            assert np.allclose(got[:, :3, 3], want[:, :3, 3], atol=1e-6)
            assert np.allclose(got[:, :3, :3], want[:, :3, :3], atol=1e-9)
            assert arm.within_limits(s["q_rad"][ok]).all()
            if robot.track is not None:  # the track within its ends, moving with the gun
                lo, hi = robot.track.range_mm
                assert np.all((s["track_mm"] >= lo - 1e-9) & (s["track_mm"] <= hi + 1e-9))
            else:
                assert np.all(s["track_mm"] == 0.0)
            checked += int(ok.sum())
    assert checked > 1000


def test_a_transfer_is_one_joint_move_between_its_neighbours(planned):
    """A transfer starts with the joints, track position and roll where the stroke before it ends and ends
    with those where the stroke after it starts (the arm never turns over in place at the surface)."""
    joined = 0
    for work in planned["plan"]["robots"]:
        strokes = work["strokes"]
        for before, transfer, after in zip(strokes, strokes[1:], strokes[2:]):
            if transfer["kind"] != "transfer":
                continue
            for mine, theirs, ok in ((0, before, before["reachable"][-1]), (-1, after, after["reachable"][0])):
                if not ok:
                    continue
                at = -1 if mine == 0 else 0
                np.testing.assert_array_equal(transfer["q_rad"][mine], theirs["q_rad"][at])
                assert transfer["track_mm"][mine] == theirs["track_mm"][at]
                assert transfer["roll_deg"][mine] == theirs["roll_deg"][at]
                joined += 1
    assert joined > 20


def test_a_version_1_plan_with_one_roll_a_stroke_reads_back(planned, tmp_path):
    """cell_plan.json version 1 gave one roll a stroke: read back, every waypoint of the stroke has it."""
    import json

    data = json.loads((planned["out"] / "cell_plan.json").read_text())
    assert data["version"] == 2
    data["version"] = 1
    for work in data["robots"]:
        for st in work["strokes"]:
            st["roll_deg"] = st["roll_deg"][-1]
    old = tmp_path / "cell_plan.json"
    old.write_text(json.dumps(data))
    back = read_cell_plan(old)
    for was, work in zip(data["robots"], back["robots"]):
        for st_was, st in zip(was["strokes"], work["strokes"]):
            np.testing.assert_array_equal(st["roll_deg"], np.full(len(st["tcp_mm"]), st_was["roll_deg"]))


def test_spray_strokes_lie_on_the_part_over_their_robots_faces(planned):
    """On-part points are on the box's surface; nearly all over faces the area map gives their robot."""
    plan = planned["plan"]
    half = np.asarray(SIZE) / 2.0
    rows = list(csv.DictReader(open(planned["out"] / "areas.csv")))
    face_robot = np.array([int(r["robot_index"]) for r in rows])
    box = grid_box(n=8, size=SIZE)
    # the part as placed: centred in x, y and standing on the floor
    placed = box.vertices + np.array([0.0, 0.0, half[2]])
    keep = np.cross(box.triangles[:, 1] - box.triangles[:, 0], box.triangles[:, 2] - box.triangles[:, 0])[:, 2]
    faces = box.faces[keep >= -1e-9 * np.abs(keep).max()]  # the bottom faces the floor and is left out
    assert len(faces) == len(face_robot)
    centres = placed[faces].mean(axis=1)
    from scipy.spatial import cKDTree

    tree = cKDTree(centres)
    own = total = 0
    for i, work in enumerate(plan["robots"]):
        for s in work["strokes"]:
            if s["kind"] != "spray":
                continue
            p = s["points_mm"]
            on = np.all(np.abs(p - [0, 0, half[2]]) <= half + 1e-6, axis=1)
            q = p[on] - [0, 0, half[2]]
            gap = np.min(np.abs(np.abs(q) - half), axis=1)  # distance to the nearest face plane of the box
            assert np.all(gap < 1e-6)
            _, f = tree.query(p[on])
            own += int((face_robot[f] == i).sum())
            total += int(on.sum())
    assert total > 1000 and own / total > 0.9


def test_the_film_is_reported_over_the_whole_body_per_area_robot_and_seam(planned):
    report = planned["plan"]["report"]
    film = report["film"]
    whole = film["whole"]
    box_area = SIZE[0] * SIZE[1] + 2 * SIZE[2] * (SIZE[0] + SIZE[1])  # top and four sides
    assert whole["area_mm2"] == pytest.approx(box_area, rel=1e-6)
    areas = sum(a["area_mm2"] for a in film["per_area"].values())
    robots = sum(r["area_mm2"] for r in film["per_robot"].values() if r.get("count"))
    unreached = film["unreached"].get("area_mm2", 0.0)
    assert areas == pytest.approx(whole["area_mm2"], rel=1e-9)
    assert robots + unreached == pytest.approx(whole["area_mm2"], rel=1e-9)
    assert film["reached"].get("area_mm2", 0.0) == pytest.approx(robots, rel=1e-9)
    in_spec = sum(r["share_in_spec"] * r["area_mm2"] for r in film["per_robot"].values() if r.get("count"))
    assert film["reached"]["share_in_spec"] == pytest.approx(in_spec / robots, rel=1e-9)
    # the samples no robot reaches stand for about the surface the area map leaves unreached
    assert unreached == pytest.approx(report["unreached_surface_mm2"], rel=0.1, abs=1000.0)
    points = film["report"]["measuring_points"]
    assert points["count"] == 420
    lo, hi = points["share_in_spec_ci95"]
    assert lo < points["share_in_spec"] <= hi <= 1.0
    # the viewer's page says it beside the share
    from sprayplan.view.summary import measured_interval

    assert measured_interval(points) in (planned["out"] / "cell.html").read_text()
    # the surface a gun faces square and the recessed surface share the whole; on a box nothing is recessed
    settings = planned["plan"]["settings"]
    depth = settings["paths"]["standoff_mm"] + settings["collision"]["clearance_mm"]
    assert film["open"]["recess_mm"] == pytest.approx(depth)
    assert film["open"]["area_mm2"] == pytest.approx(whole["area_mm2"], rel=1e-9)
    assert film["open"]["share_in_spec"] == pytest.approx(whole["share_in_spec"], rel=1e-9)
    assert film["recessed"]["count"] == 0
    from sprayplan.view.summary import open_surface

    assert open_surface(film) and open_surface(film) in (planned["out"] / "cell.html").read_text()
    # the command line says why the rest is out of spec
    from sprayplan.view.summary import out_of_spec_causes

    causes = film["out_of_spec"]
    assert sum(causes[k] for k in ("unreached", "recessed", "bare", "thin", "thick")) == pytest.approx(
        1.0 - whole["share_in_spec"], abs=1e-9
    )
    assert causes["recessed"] == 0.0 and out_of_spec_causes(film)
    assert any(line.startswith(out_of_spec_causes(film)) for line in planned["stdout"].splitlines())
    assert f"<p>{out_of_spec_causes(film)}</p>" in (planned["out"] / "cell.html").read_text()
    assert "left/right" in film["per_seam"] and film["per_seam"]["left/right"]["count"] > 0
    # the cell's cycle is its longest robot's
    assert report["cycle_time_s"] == max(r["cycle_time_s"] for r in report["robots"].values())
    # tuned to the target: most of the surface in spec
    assert whole["share_in_spec"] > 0.85
    assert abs(whole["mean_um"] - 50.0) < 5.0


def test_waypoints_csv_reads_back_as_the_plan(planned):
    rows = list(csv.DictReader(open(planned["out"] / "waypoints.csv")))
    plan = planned["plan"]
    k = 0
    for work in plan["robots"]:
        for i, s in enumerate(work["strokes"]):
            for j in range(len(s["tcp_mm"])):
                row = rows[k]
                assert (row["robot"], int(row["stroke"]), int(row["waypoint"])) == (work["name"], i, j)
                assert np.allclose([float(row[c]) for c in ("x_mm", "y_mm", "z_mm")], s["tcp_mm"][j], atol=1e-4)
                assert int(row["reachable"]) == int(s["reachable"][j])
                assert float(row["track_mm"]) == pytest.approx(s["track_mm"][j], abs=1e-4)
                if s["reachable"][j]:
                    q = [float(row[f"q{n + 1}"]) for n in range(6)]
                    assert np.allclose(q, s["q_rad"][j], atol=1e-8)
                k += 1
    assert k == len(rows)


def test_a_seeded_cell_plan_repeats(tmp_path):
    cell_file = tmp_path / "c.toml"
    cell_file.write_text(CELL)
    cell = load_cell(cell_file)
    box = grid_box(n=6, size=SIZE)
    a = plan_cell(box, cell, JobConfig())
    b = plan_cell(box, cell, JobConfig())
    for ra, rb in zip(a.robots, b.robots):
        assert np.array_equal(ra.q, rb.q) and np.array_equal(ra.reachable, rb.reachable)
        assert np.array_equal(ra.track_mm, rb.track_mm)
    assert np.array_equal(a.assignment.face_robot, b.assignment.face_robot)


def test_a_gantry_cell_or_a_point_cloud_is_not_a_cell_plan(tmp_path):
    box = grid_box(n=4, size=SIZE)
    with pytest.raises(ConfigError, match="gantry"):
        plan_cell(box, load_cell("gantry-ur5"), JobConfig())


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--tour", "ga"], "--tour: not available with --cell"),
        (["--region", "z > 10"], "--region: not available with --cell"),
    ],
)
def test_cell_plan_refuses_gantry_options(planned, tmp_path, capsys, extra, words):
    out = tmp_path / "o"
    code = main(["plan", str(planned["part"]), "--cell", str(planned["cell"]), "-o", str(out), *extra])
    err = capsys.readouterr().err
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_robot_inside_the_part_is_exit_2_and_nothing_written(planned, tmp_path, capsys):
    bad = tmp_path / "inside.toml"
    bad.write_text('[[robot]]\nname = "a"\nmodel = "abb-irb2400-10"\nbase_mm = [0, 0, 50]\n')
    out = tmp_path / "o"
    code = main(["plan", str(planned["part"]), "--cell", str(bad), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "inside.toml" in err and "inside the part" in err
    assert not out.exists()


def test_the_pictures_are_written(planned):
    """areas.png, film.png and film_timed.png: images of the figure's size (a person looks at them; see
    docs/cells.md); the film at the timed speeds, thicker than planned where the robots are slower, is not the
    planned film's picture."""
    import matplotlib.image

    images = {}
    for name in ("areas.png", "film.png", "film_timed.png"):
        image = matplotlib.image.imread(planned["out"] / name)
        assert image.shape[:2] == (585, 1440)
        assert image[..., :3].std() > 0.05  # not a blank page
        images[name] = image[..., :3]
    assert np.abs(images["film.png"] - images["film_timed.png"]).max() > 0.1


def test_the_film_is_made_only_by_reached_runs_and_their_tuning_goes_back():
    from sprayplan.cells.plan import RobotWork, reached_strokes, with_tuned_dwell
    from sprayplan.types import Stroke

    n = 9
    pts = np.column_stack([np.arange(n) * 10.0, np.zeros(n), np.zeros(n)])
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    spray = Stroke(pts, normals, pts + [0, 0, 100])
    transfer = Stroke(pts[:2], normals[:2], pts[:2] + [0, 0, 100], spray_on=False)
    reach = np.array([1, 1, 0, 1, 1, 1, 0, 0, 1, 1, 1], bool)  # 9 spray waypoints, then the transfer's 2
    work = RobotWork(
        "r", "m", (spray, transfer), np.array([0, -1]), np.zeros(11), np.zeros(2), np.zeros((11, 6)), reach
    )
    strokes, owners = reached_strokes((work,))
    assert owners == [(0, 0, 0, 2), (0, 0, 3, 6)]  # a lone reached waypoint sprays nothing; transfers never
    assert np.array_equal(strokes[1].tcp, spray.tcp[3:6])
    tuned = [s.with_dwell(np.full(len(s), 2.0 + k)) for k, s in enumerate(strokes)]
    (back,) = with_tuned_dwell((work,), tuned, owners)
    assert np.array_equal(back.strokes[0].dwell, [2, 2, 1, 3, 3, 3, 1, 1, 1])
    assert np.array_equal(back.strokes[1].dwell, [1, 1])


def test_spray_path_by_area_counts_reached_runs_of_spray_strokes_only():
    """The collision report's path per area: spray strokes only (not transfers, not touch-ups of no area),
    whole or over runs of two or more reached waypoints, each summed into its own area."""
    from sprayplan.cells.plan import RobotWork, spray_path_by_area
    from sprayplan.types import Stroke

    n = 9
    pts = np.column_stack([np.arange(n) * 10.0, np.zeros(n), np.zeros(n)])
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    spray = Stroke(pts, normals, pts + [0, 0, 100])
    other = Stroke(pts[:4] * 2.0, normals[:4], pts[:4] * 2.0 + [0, 0, 100])  # 3 steps of 20 mm, area 2
    transfer = Stroke(pts[:2], normals[:2], pts[:2] + [0, 0, 100], spray_on=False)
    touch = Stroke(pts[:3], normals[:3], pts[:3] + [0, 0, 100], kind="touch-up")
    reach = np.r_[[1, 1, 0, 1, 1, 1, 0, 0, 1], [1, 1, 1, 1], [1, 1], [1, 1, 1]].astype(bool)
    m = len(reach)
    work = RobotWork("r", "m", (spray, transfer, other, touch), np.array([0, -1, 2, -1]), np.zeros(m), np.zeros(m),
                     np.zeros((m, 6)), reach)  # fmt: skip
    # reached: waypoints 0-1 (10 mm) and 3-5 (20 mm) of area 0; the lone 8 sprays nothing
    np.testing.assert_allclose(spray_path_by_area((work,), 3), [30.0, 0.0, 60.0])
    np.testing.assert_allclose(spray_path_by_area((work, work), 3, reached_only=False), [160.0, 0.0, 120.0])


def test_spray_stops_where_the_surface_goes_on_as_another_piece_and_not_at_an_edge():
    """feathered / SeamGuard: a lead-out over the neighbouring piece (the surface goes on) is cut; one past the
    part's edge, or over a face turned 90 degrees (a corner), is kept."""
    from sprayplan.cells.seams import SeamGuard, feathered
    from sprayplan.types import Stroke

    box = grid_box(n=8, size=(400.0, 200.0, 100.0))
    _, normals = outward_face_normals(box.vertices, box.faces)
    centres = box.triangles.mean(axis=1)
    top = normals[:, 2] > 0.9
    label = np.where(top & (centres[:, 0] < 0), 1, 2)  # the top's -x half is piece 1, everything else 2
    guard = SeamGuard(box, label, normals, step_mm=20.0)
    x = np.arange(-150.0, 260.0, 10.0)  # along the top at y = 0 from piece 1 over piece 2 and past the edge
    pts = np.column_stack([x, np.zeros_like(x), np.full_like(x, 50.0)])
    n = np.tile([0.0, 0.0, 1.0], (len(x), 1))
    on = x < 0
    stroke = Stroke(pts, n, pts + [0, 0, 100], on_part=on)
    (kept,) = feathered([stroke], guard, 1)
    assert np.allclose(kept.points[:, 0], x[x < 0])  # the lead-out stops where the top goes on as piece 2
    # for piece 2, the same points lie on piece 1 before it: the lead-in is cut to what follows piece 1
    reverse = Stroke(pts, n, pts + [0, 0, 100], on_part=x >= 0)
    (back,) = feathered([reverse], guard, 2)
    assert back.points[0, 0] >= -20.0 - 1e-9 and back.points[-1, 0] == x[-1]  # its lead-out past the edge stays
    # an edge pass wholly past the part's edge (nothing faces up there): kept whole
    past = x > 220.0
    edge = Stroke(pts[past], n[past], pts[past] + [0, 0, 100], on_part=np.zeros(past.sum(), bool))
    (alone,) = feathered([edge], guard, 1)
    assert len(alone) == past.sum()
    # a lead-out past the top's +y edge, beside the side face (normal +y, 90 degrees off): kept
    y = np.arange(110.0, 160.0, 10.0)
    side = np.column_stack([np.full_like(y, -100.0), y, np.full_like(y, 50.0)])
    corner = Stroke(side, np.tile([0.0, 0.0, 1.0], (len(y), 1)), side + [0, 0, 100], on_part=np.zeros(len(y), bool))
    assert len(feathered([corner], guard, 1)[0]) == len(y)


def test_seams_without_a_cell_is_refused(planned, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["plan", str(planned["part"]), "--seams", "overlap", "-o", str(out)]) == 2
    assert "--seams: only with --cell" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("robot, dof", [("ur5", 6), ("r5150", 5)])
def test_plan_with_one_fixed_base_robot(tmp_path, robot, dof):
    """`plan --robot ur5` / `--robot r5150`: the part file's frame is the robot's base frame; every reached
    waypoint is where the arm puts the gun (the R5150 within its 5 degree axis tolerance), joints per axis."""
    from sprayplan.cells.spec import single_robot_cell
    from sprayplan.types import Part

    plate = grid_box(n=4, size=(240.0, 160.0, 20.0))
    part = tmp_path / "plate.stl"
    part.write_bytes(write_stl_binary(Part(plate.vertices + [420.0, 0.0, 60.0], plate.faces).triangles))
    out = tmp_path / "out"
    assert main(["-q", "plan", str(part), "--robot", robot, "--spacing-mm", "40", "-o", str(out)]) == 0
    data = read_cell_plan(out / "cell_plan.json")
    arm = single_robot_cell(robot).robots[0].robot()
    reached = 0
    for s in data["robots"][0]["strokes"]:
        assert s["q_rad"].shape == (len(s["tcp_mm"]), dof)
        ok = s["reachable"]
        if not ok.any():
            continue
        got = arm.fk(s["q_rad"][ok])
        want = poses_at(s["tcp_mm"][ok], s["normals"][ok])
        assert np.allclose(got[:, :3, 3], want[:, :3, 3], atol=1e-6)
        cos = np.einsum("ij,ij->i", got[:, :3, 2], want[:, :3, 2])
        assert np.all(cos >= np.cos(np.radians(5.0)) - 1e-12)
        reached += int(ok.sum())
    assert reached > 0
    rows = list(csv.DictReader(open(out / "waypoints.csv")))
    assert all((row["q6"] == "") == (dof == 5) for row in rows)


def test_robot_and_cell_together_or_an_unknown_robot_are_refused(planned, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["plan", str(planned["part"]), "--robot", "ur5", "--cell", "line3", "-o", str(out)]) == 2
    assert "--robot" in capsys.readouterr().err
    assert main(["plan", str(planned["part"]), "--robot", "ur99", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "ur99" in err and len(err.strip().splitlines()) == 1 and not out.exists()


def test_touch_ups_are_counted_and_carried_like_any_stroke(planned):
    plan = planned["plan"]
    kinds = [s["kind"] for r in plan["robots"] for s in r["strokes"]]
    assert kinds.count("touch-up") == plan["report"]["touch_up_strokes"]
    for r in plan["robots"]:
        for s in r["strokes"]:
            n = len(s["tcp_mm"])
            assert len(s["q_rad"]) == len(s["track_mm"]) == len(s["reachable"]) == len(s["dwell"]) == n


def test_touch_ups_are_visited_in_a_nearest_neighbour_tour_each_run_the_nearer_way():
    """``touch_up_order``: a permutation of the strokes; each next stroke is the nearest (by either end) of those
    left to where the last ended, run backwards exactly when its end is the nearer; checked against a brute
    force of every step on random strokes."""
    from sprayplan.cells.plan import touch_up_order
    from sprayplan.types import Stroke

    rng = np.random.default_rng(11)
    strokes = []
    for _ in range(25):
        tcp = rng.uniform(-2000, 2000, (2, 3))
        tcp = np.linspace(tcp[0], tcp[1], 5)
        strokes.append(Stroke(tcp - [0, 0, 100], np.tile([0.0, 0.0, 1.0], (5, 1)), tcp))
    start = np.array([0.0, 0.0, 500.0])
    labels = list(range(100, 125))
    order = touch_up_order(strokes, start, labels)
    assert sorted(k for k, _ in order) == labels
    at, left = start, set(range(25))
    for label, back in order:
        k = label - 100
        gaps = {j: min(np.linalg.norm(strokes[j].tcp[0] - at), np.linalg.norm(strokes[j].tcp[-1] - at)) for j in left}
        assert gaps[k] == min(gaps.values())
        assert back == (np.linalg.norm(strokes[k].tcp[-1] - at) < np.linalg.norm(strokes[k].tcp[0] - at))
        at = strokes[k].tcp[0] if back else strokes[k].tcp[-1]
        left.remove(k)
    assert touch_up_order([], start) == [] and touch_up_order(strokes[:1], None) == [(0, False)]


def test_touch_ups_aim_at_bare_surface_a_robot_reaches_and_not_at_unreached_surface():
    """``touch_up_targets``: the tuned samples, and every sample on a face some robot reaches; so a bare patch on
    reached surface gets a touch-up stroke, and one on surface no robot reaches gets none."""
    from sprayplan.cells.plan import touch_up_targets
    from sprayplan.coating.sampling import surface_samples
    from sprayplan.refine.touchup import touch_up_strokes

    part = grid_box(40, (2000.0, 400.0, 10.0))  # a plate, its top split at x = 0 below
    samples = surface_samples(part, max_edge_mm=0)
    top = outward_face_normals(part.vertices, part.faces)[1][:, 2] > 0.9
    centre_x = part.vertices[part.faces].mean(axis=1)[:, 0]
    face_robot = np.where(top & (centre_x < 0), 0, -1)  # only the top's x < 0 half is reached
    tuned = np.zeros(len(samples.points), bool)
    targets = touch_up_targets(samples, tuned, face_robot)
    on_reached = face_robot[samples.part_face] >= 0
    assert np.array_equal(targets, on_reached) and targets.any() and not targets.all()
    tuned[:5] = True
    assert np.array_equal(touch_up_targets(samples, tuned, face_robot), on_reached | tuned)
    film = np.zeros(len(samples.points))  # bare everywhere
    strokes = touch_up_strokes(
        samples, film, targets, 50.0, 5.0, standoff_mm=100.0, step_mm=20.0, lead_mm=0.0, min_area_mm2=100.0
    )
    assert strokes, "a bare patch on reached surface gets a touch-up"
    for s in strokes:
        assert (s.points[:, 0] < 0).all() and (s.points[:, 2] > 0).all()  # over the reached half of the top
    assert not touch_up_strokes(
        samples, film, tuned & False, 50.0, 5.0, standoff_mm=100.0, step_mm=20.0, lead_mm=0.0, min_area_mm2=100.0
    )


def test_seed_001_table_4_in_one_command(tmp_path):
    """`plan --ruled case1_table4_r5150.toml --robot r5150`: the ten points of seed 001's table 4 with its
    joints theta1..theta4 (theta5, the roll about the vertical tool axis, moves nothing and is free)."""
    from pathlib import Path

    from sprayplan.robots.r5150 import table4_joints, table4_points

    example = Path(__file__).resolve().parents[1] / "examples" / "ruled" / "case1_table4_r5150.toml"
    out = tmp_path / "t4"
    assert main(["-q", "plan", "--ruled", str(example), "--robot", "r5150", "-o", str(out)]) == 0
    rows = [r for r in csv.DictReader(open(out / "waypoints.csv")) if r["kind"] == "spray"]
    points = np.array([[float(r[c]) for c in ("x_mm", "y_mm", "z_mm")] for r in rows])
    q = np.degrees([[float(r[f"q{i}"]) for i in range(1, 6)] for r in rows])
    assert np.allclose(points, table4_points(), atol=1e-6)
    assert all(r["reachable"] == "1" and r["q6"] == "" for r in rows)
    assert np.allclose(q[:, :4], table4_joints()[:, :4], atol=0.01)  # the table prints 4 decimals


@pytest.mark.parametrize("axis", [[0, 0, 0], [0, 0], [0, float("nan"), 1]])
def test_a_bad_gun_axis_names_the_file(axis):
    from sprayplan.errors import InputError
    from sprayplan.paths.ruled_toml import ruled_job_from_dict

    data = {
        "curve_a": {"type": "line", "start": [0, 0, 0], "end": [100, 0, 0]},
        "curve_b": {"type": "line", "start": [0, 100, 0], "end": [100, 100, 0]},
        "path": {"passes": 2, "gun_axis": axis},
    }
    with pytest.raises(InputError, match="gun_axis") as err:
        ruled_job_from_dict(data, source="s.toml")
    assert "s.toml" in str(err.value)


def _box_with_arms_seen(monkeypatch, tmp_path):
    """The two-robot cell, the 6 x 6 grid box, and the list each part the arms' collision model is built
    against is appended to (``cells.collide.cell_arms`` watched)."""
    from sprayplan.cells import collide

    path = tmp_path / "c.toml"
    path.write_text(CELL)
    seen = []
    plain = collide.cell_arms
    monkeypatch.setattr(
        collide, "cell_arms", lambda cell_, part, config: seen.append(part) or plain(cell_, part, config)
    )
    return load_cell(path), grid_box(n=6, size=SIZE), seen


def test_a_masked_end_is_left_unpainted_and_stays_an_obstacle(monkeypatch, tmp_path):
    """``[load] mask`` (``plan --mask``) in a cell: the film, the areas and the strokes leave the masked end of
    the box out (its area reported), and the arms are checked against the whole box, the masked end and the
    bottom facing the floor too."""
    from sprayplan.config import CollisionConfig, LoadConfig
    from sprayplan.surface.region import parse_region

    cell, box, seen = _box_with_arms_seen(monkeypatch, tmp_path)
    job = JobConfig(load=LoadConfig(mask=("x > 150",)), collision=CollisionConfig(check=True))
    plan = plan_cell(box, cell, job)
    # the masked end in the part frame: its top 150 x 300, two sides 150 x 200, the end 300 x 200 (the bottom
    # faces the floor and is left out anyway)
    assert plan.report["masked_left_out_mm2"] == pytest.approx(150 * 300 + 2 * 150 * 200 + 300 * 200, rel=1e-9)
    to_part = np.linalg.inv(plan.part2cell)
    centres = plan.part.triangles.mean(axis=1) @ to_part[:3, :3].T + to_part[:3, 3]
    assert centres[:, 0].max() < 150.0  # no painted face in the mask
    assert plan.part.area == pytest.approx(2 * (600 * 200 + 300 * 200) + 600 * 300 - 165000.0, rel=1e-9)
    sprayed = np.concatenate([s.points for r in plan.robots for s in r.strokes if s.spray_on])
    in_part = sprayed @ to_part[:3, :3].T + to_part[:3, 3]
    # strokes run on past the mask's edge by the spray's radius, as past any edge (onto the masking), no further
    assert in_part[:, 0].max() <= 150.0 + job.paths.spray_radius_mm + 1e-6
    (obstacle,) = seen
    # the masked end and the bottom (600 x 300, facing the floor, not painted) are obstacles
    assert obstacle.area == pytest.approx(plan.part.area + 165000.0 + 600 * 300, rel=1e-9)
    assert plan.collision_part is obstacle  # and the check after the film and the programs' check use it too
    assert parse_region("x > 150").contains(obstacle.triangles.mean(axis=1) @ to_part[:3, :3].T + to_part[:3, 3]).any()


def test_the_arms_are_checked_against_the_surface_left_unpainted_too(monkeypatch, tmp_path):
    """The surface a cell plan leaves unpainted (facing the floor: a body's underside, the roof of an air
    intake) is still there: the arms' collision model and the checks after the plan get the whole body, and
    the film report judges recesses against it."""
    import dataclasses

    from sprayplan.cells.film import film_report
    from sprayplan.config import CollisionConfig
    from sprayplan.types import Part
    from tests.helpers import plate

    cell, box, seen = _box_with_arms_seen(monkeypatch, tmp_path)
    job = JobConfig(collision=CollisionConfig(check=True)).replace(coating={"thickness_um": 50.0})
    plan = plan_cell(box, cell, job)
    assert plan.report["floor_facing_left_out_mm2"] == pytest.approx(600 * 300, rel=1e-9)
    assert plan.part.area == pytest.approx(box.area - 600 * 300, rel=1e-9)  # the bottom is not painted
    (obstacle,) = seen
    assert obstacle.area == pytest.approx(box.area, rel=1e-9)  # but is an obstacle
    assert plan.collision_part is obstacle
    to_part = np.linalg.inv(plan.part2cell)
    centres = obstacle.triangles.mean(axis=1) @ to_part[:3, :3].T + to_part[:3, 3]
    assert np.isclose(centres[:, 2], box.vertices[:, 2].min()).sum() == 2 * 6 * 6  # the bottom's triangles
    # the film over the surface in front of which the body stands within the standoff and the clearance: none on
    # a box; with a 200 x 100 mm lid 100 mm over the middle of the top, the four top faces (100 x 50 mm) whose
    # centres it hangs over, and the film there is the film of those faces' samples
    film = plan.report["film"]
    assert film["recessed"]["count"] == 0 and film["open"]["area_mm2"] == pytest.approx(plan.part.area, rel=1e-9)
    lid = plate(-100, 100, -50, 50, 10.0)
    top = plan.part.vertices[:, 2].max()
    lid_v = np.column_stack([lid.vertices[:, :2], np.full(len(lid.vertices), top + 100.0)])
    lidded = Part(
        np.vstack([obstacle.vertices, lid_v]), np.vstack([obstacle.faces, lid.faces + len(obstacle.vertices)]),
        None, "lidded", oriented=True,
    )  # fmt: skip
    depth = job.paths.standoff_mm + job.collision.clearance_mm
    covered = film_report(dataclasses.replace(plan, obstacle=lidded), 50.0, 5.0, samples=None, recess_mm=depth)
    assert covered["recessed"]["area_mm2"] == pytest.approx(4 * 100 * 50, rel=1e-9)
    assert covered["open"]["area_mm2"] + covered["recessed"]["area_mm2"] == pytest.approx(plan.part.area, rel=1e-9)
    under = plan.film.part_face >= 0
    centre = plan.part.triangles.mean(axis=1)[plan.film.part_face[under]]
    inside = (np.abs(centre[:, 0]) < 100) & (np.abs(centre[:, 1]) < 50) & np.isclose(centre[:, 2], top)
    assert covered["recessed"]["count"] == inside.sum()
    assert covered["recessed"]["mean_um"] == pytest.approx(
        np.average(plan.film.thickness_um[under][inside], weights=plan.film.area_mm2[under][inside]), rel=1e-9
    )
    # the open surface some robot reaches: with the faces on the +x half given to no robot, the open samples
    # on the -x half
    unreached = plan.part.triangles.mean(axis=1)[:, 0] > 0
    lost = dataclasses.replace(plan.assignment, face_robot=np.where(unreached, -1, plan.assignment.face_robot))
    half = film_report(
        dataclasses.replace(plan, obstacle=lidded, assignment=lost), 50.0, 5.0, samples=None, recess_mm=depth
    )
    kept = ~inside & ~unreached[plan.film.part_face[under]]
    assert 0 < kept.sum() < (~inside).sum()
    assert half["open_reached"]["count"] == kept.sum()
    assert half["open_reached"]["area_mm2"] == pytest.approx(plan.film.area_mm2[under][kept].sum(), rel=1e-9)
    assert covered["open_reached"]["area_mm2"] == pytest.approx(covered["open"]["area_mm2"], rel=1e-9)
    # the surface out of spec by cause: each sample out of spec once, the first cause that holds
    causes = half["out_of_spec"]
    um, a = plan.film.thickness_um[under], plan.film.area_mm2[under]
    out = (um < 45.0) | (um > 55.0)
    lost = unreached[plan.film.part_face[under]]
    whole_area = plan.film.area_mm2.sum()
    assert causes["unreached"] == pytest.approx(a[out & lost].sum() / whole_area, rel=1e-9)
    assert causes["recessed"] == pytest.approx(a[out & ~lost & inside].sum() / whole_area, rel=1e-9)
    rest = out & ~lost & ~inside
    assert causes["bare"] == pytest.approx(a[rest & (um < 5.0)].sum() / whole_area, rel=1e-9)
    assert causes["thin"] == pytest.approx(a[rest & (um >= 5.0) & (um < 45.0)].sum() / whole_area, rel=1e-9)
    assert causes["thick"] == pytest.approx(a[rest & (um > 55.0)].sum() / whole_area, rel=1e-9)
    assert causes["unreached"] > 0 and causes["recessed"] + causes["thin"] + causes["thick"] > 0
    assert sum(causes[k] for k in ("unreached", "recessed", "bare", "thin", "thick")) == pytest.approx(
        1.0 - half["whole"]["share_in_spec"], abs=1e-12
    )


def _upright(plate_part, y_mm):
    """``plate_part`` (an x-y plate, normals +-z) stood up in the x-z plane at ``y_mm``: +z turns to +y."""
    v = plate_part.vertices
    return np.stack([v[:, 0], np.full(len(v), y_mm) + v[:, 2], -v[:, 1]], axis=1), plate_part.faces


def test_strokes_facing_away_from_their_area_are_left_out_and_counted(tmp_path):
    """An area holding a sliver of the part's other side (a back 20 mm behind its face, facing the other way):
    no stroke is planned on the back, the rest is, and ``away`` counts what was left out."""
    from sprayplan.cells.plan import _robot_work
    from sprayplan.cells.seams import facing_away
    from sprayplan.surface.areas import AreaAssignment, Areas
    from sprayplan.types import Part
    from tests.helpers import plate

    front_v, front_f = _upright(plate(-300.0, 300.0, -500.0, -300.0, 25.0), 0.0)
    back_v, back_f = _upright(plate(-100.0, 100.0, -380.0, -320.0, 20.0, flip=True), -20.0)
    part = Part(np.vstack([front_v, back_v]), np.vstack([front_f, back_f + len(front_v)]), name="face and back",
                oriented=True)  # fmt: skip
    m = len(part.faces)
    normals = outward_face_normals(part.vertices, part.faces)[1]
    assert np.allclose(normals[: len(front_f)], [0, 1, 0]) and np.allclose(normals[len(front_f) :], [0, -1, 0])
    areas = Areas(np.zeros(m, np.int64), ("side +y",), ("side +y",), np.array([part.face_areas.sum()]),
                  np.array([[0.0, 1.0, 0.0]]), normals)  # fmt: skip
    assignment = AreaAssignment(np.zeros(m, np.int64), np.array([0]), np.array([1.0]), np.array([False]),
                                np.array([part.face_areas.sum()]), 0.0)  # fmt: skip
    path = tmp_path / "small2.toml"
    path.write_text(CELL)
    robot = load_cell(path).robots[0]
    job = JobConfig()

    def spray_normals(work):
        return [s.normals.mean(axis=0) for s in work.strokes if s.spray_on]

    every = _robot_work(robot, 0, part, areas, assignment, job)  # nothing left out: the back is planned
    backs = [s for s in every.strokes if s.spray_on and facing_away(s, areas.normal[0]).all()]
    assert backs and all(n[1] < -0.99 for n in (s.normals.mean(axis=0) for s in backs))
    away: dict = {}
    kept = _robot_work(robot, 0, part, areas, assignment, job, away=away)
    assert all(n[1] > 0.99 for n in spray_normals(kept))
    assert len(spray_normals(kept)) == len(spray_normals(every)) - len(backs)
    length = sum(float(np.linalg.norm(np.diff(s.points, axis=0), axis=1).sum()) for s in backs)
    assert away == {"left": {"strokes": len(backs), "path_mm": pytest.approx(length)}}


def test_a_stroke_round_a_lip_keeps_only_its_runs_facing_the_area():
    """Along a sheet, round its lip (a half turn) and back along its other side 2.5 mm behind (the BMW's rear
    window sill): the stroke is cut to its runs within 120 deg of the area's normal, each waypoint kept
    as it was, and the path left out is the rest."""
    from sprayplan.cells.seams import facing_away, facing_runs
    from sprayplan.types import Stroke

    turn = np.radians(np.linspace(0.0, 180.0, 9))  # the lip: the normal turns from +y over +z to -y
    normals = np.vstack([np.tile([0.0, 1.0, 0.0], (10, 1)), np.stack([0 * turn, np.cos(turn), np.sin(turn)], 1)[1:-1],
                         np.tile([0.0, -1.0, 0.0], (8, 1))])  # fmt: skip
    x = np.r_[np.arange(10.0) * 20.0, np.full(7, 190.0), 180.0 - np.arange(8.0) * 20.0]
    points = np.stack([x, np.zeros(len(x)), np.zeros(len(x))], axis=1)
    n = len(points)
    stroke = Stroke(points, normals, points + 200.0 * normals, True, np.ones(n, bool), 0, np.ones(n), "spray")
    away = facing_away(stroke, np.array([0.0, 1.0, 0.0]))
    cos = normals @ [0.0, 1.0, 0.0]
    assert np.array_equal(away, cos < np.cos(np.radians(120.0)))
    kept, left_mm = facing_runs(stroke, np.array([0.0, 1.0, 0.0]))
    first_away = int(np.flatnonzero(away)[0])
    assert len(kept) == 1 and np.array_equal(kept[0].points, points[:first_away])
    assert np.array_equal(kept[0].tcp, stroke.tcp[:first_away]) and kept[0].kind == "spray"
    total = np.linalg.norm(np.diff(points, axis=0), axis=1).sum()
    assert left_mm == pytest.approx(total - np.linalg.norm(np.diff(points[:first_away], axis=0), axis=1).sum())
    assert facing_runs(stroke, np.zeros(3)) == ([stroke], 0.0)


@pytest.mark.parametrize("deg, away", [(0.0, False), (110.0, False), (130.0, True), (180.0, True)])
def test_facing_away_is_the_angle_of_each_normal_past_the_limit(deg, away):
    from types import SimpleNamespace

    from sprayplan.cells.seams import facing_away

    a = np.radians(deg + np.array([-5.0, 0.0, 5.0]))  # normals fanned about ``deg`` from +y, in the y-z plane
    stroke = SimpleNamespace(normals=np.stack([np.zeros(3), np.cos(a), np.sin(a)], axis=1))
    assert np.array_equal(facing_away(stroke, np.array([0.0, 2.0, 0.0])), np.full(3, away))
    assert not facing_away(stroke, np.zeros(3)).any()
