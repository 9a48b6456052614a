"""A whole part painted by the robots of a cell (cells.plan, cells.files, ``sprayplan plan --cell``): issue 18."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from sprayplan.cells import load_cell
from sprayplan.cells.files import read_cell_plan
from sprayplan.cells.plan import plan_cell
from sprayplan.cli import main
from sprayplan.config import JobConfig
from sprayplan.errors import ConfigError
from sprayplan.export.stl import write_stl_binary
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
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
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
    assert main(argv) == 0
    return {"out": out, "cell": cell, "part": part, "plan": read_cell_plan(out / "cell_plan.json")}


def test_every_reached_waypoint_is_where_the_robot_puts_the_gun(planned):
    """FK(q) at the stroke's track position, with its roll, is the waypoint's gun pose."""
    cell = load_cell(planned["cell"])
    checked = 0
    for robot, work in zip(cell.robots, planned["plan"]["robots"]):
        assert work["name"] == robot.name
        for s in work["strokes"]:
            ok = s["reachable"]
            if not ok.any():
                continue
            want = poses_at(s["tcp_mm"][ok], s["normals"][ok]) @ _rot_z(s["roll_deg"])
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
    # the samples no robot reaches stand for about the surface the area map leaves unreached
    assert unreached == pytest.approx(report["unreached_surface_mm2"], rel=0.1, abs=1000.0)
    assert film["report"]["measuring_points"]["count"] == 420
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
        (["--program", "rapid"], "--program: not available with --cell"),
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
    """areas.png and film.png: images of the figure's size (a person looks at them; see docs/cells.md)."""
    import matplotlib.image

    for name in ("areas.png", "film.png"):
        image = matplotlib.image.imread(planned["out"] / name)
        assert image.shape[:2] == (540, 1260)
        assert image[..., :3].std() > 0.05  # not a blank page

