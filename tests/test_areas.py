"""Automatic areas (surface.areas), cells as data (cells.spec) and the reach matrix (cells.reach): issue 18."""

from __future__ import annotations

import numpy as np
import pytest

from sprayplan.cells import cell_from_dict, list_cells, load_cell, place_part
from sprayplan.cells.reach import reach_matrix
from sprayplan.errors import ConfigError
from sprayplan.io.load import load_part
from sprayplan.surface.areas import DIRECTIONS, assign_areas, face_adjacency, segment_areas
from sprayplan.surface.normals import outward_face_normals
from sprayplan.surface.region import drop_floor_facing
from sprayplan.types import Part
from tests.helpers import grid_box


def test_a_box_splits_into_its_six_sides_and_the_areas_partition_the_surface():
    box = grid_box()
    areas = segment_areas(box, min_share=0.0)
    assert sorted(areas.direction) == sorted(DIRECTIONS)
    assert len(areas.face_area) == len(box.faces) and areas.face_area.min() == 0
    assert areas.area_mm2.sum() == pytest.approx(box.area, rel=1e-12)
    for k, name in enumerate(areas.direction):
        mine = areas.face_area == k
        assert np.allclose(areas.face_normals[mine], DIRECTIONS[name], atol=1e-12)
        assert areas.area_mm2[k] == pytest.approx(box.face_areas[mine].sum())
    # in order of decreasing area: the two 400 x 200 sides first
    assert np.all(np.diff(areas.area_mm2) <= 1e-9)
    assert set(areas.direction[:2]) == {"top", "bottom"}


def test_islands_merge_into_the_neighbour_they_share_most_edge_with():
    box = grid_box()
    areas = segment_areas(box, min_share=0.0)
    # the two 200 x 100 ends are 2 x 20000 of 280000 mm^2: under 8 % they are islands
    merged = segment_areas(box, min_share=0.08)
    assert len(merged) == 4
    assert merged.area_mm2.sum() == pytest.approx(box.area)
    # an end shares 200 mm with the top and bottom and 100 mm with each side: it joins top or bottom
    ends = [k for k, d in enumerate(areas.direction) if d.startswith("end")]
    for k in ends:
        into = np.unique(merged.face_area[areas.face_area == k])
        assert len(into) == 1
        assert merged.direction[into[0]] in ("top", "bottom")


def test_an_island_never_joins_a_patch_facing_away_from_it():
    """_merge_islands: patch 1 (an island facing -x) shares 300 mm with patch 0 (facing +x, its back) and 50
    mm with patch 2 (facing up): it joins 2. Bordering only its back it stays an area; a sliver under
    OPPOSED_KEPT of the island size joins its back all the same."""
    from sprayplan.surface.areas import OPPOSED_KEPT, _merge_islands

    comp = np.array([0, 0, 1, 2, 2])  # faces 0-1 patch 0, face 2 patch 1, faces 3-4 patch 2
    centres = np.zeros((5, 3))
    normals = np.array([[1.0, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0], [0, 0, 1.0]])

    def merged(face_area, pairs, length, limit):
        facing = np.zeros((3, 3))
        np.add.at(facing, comp, normals * np.asarray(face_area)[:, None])
        return _merge_islands(comp, np.asarray(face_area, float), np.array(pairs), np.array(length, float),
                              centres, limit, facing)  # fmt: skip

    got = merged([50, 50, 10, 50, 50], [[1, 2], [2, 3]], [300, 50], limit=20)
    assert got[2] == got[3] != got[0]
    # without the facing, the longest border wins: the old rule
    plain = _merge_islands(comp, np.array([50, 50, 10, 50, 50.0]), np.array([[1, 2], [2, 3]]),
                           np.array([300, 50.0]), centres, 20.0)  # fmt: skip
    assert plain[2] == plain[0]
    alone = merged([50, 50, 10, 50, 50], [[1, 2], [3, 4]], [300, 50], limit=20)
    assert len(np.unique(alone)) == 3 and alone[2] not in (alone[0], alone[3])
    sliver = merged([50, 50, 0.5 * OPPOSED_KEPT * 20, 50, 50], [[1, 2], [3, 4]], [300, 50], limit=20)
    assert sliver[2] == sliver[0]


@pytest.mark.parametrize("mask", [(), ("box(-930, -1700, 0, 870, 1970, 660)",)])
def test_no_area_of_the_suv_holds_both_sides_of_its_bumpers(testdata, mask):
    """The SUV's bumpers are thin: each one's face and back meet along its lower edge, and the face (under 3 %
    of the surface) had joined its back, so that one area faced both ways (31 % of it facing more than 120 deg
    from its mean normal). Every area now faces one way: under 5 % of each faces away from its mean normal."""
    from sprayplan.cells.plan import area_surface
    from sprayplan.config import CollisionConfig
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import mask_out, painted_surface

    suv = load_part(testdata / "meshes" / "gazebo_suv_body_m.ply", units="m")
    placed = place_part(suv, load_cell("line3"))
    painted, _ = painted_surface(oriented_part(placed.part), CollisionConfig(check=True))
    if mask:
        painted, _ = mask_out(painted, mask, placed.part2cell)
    part, _ = area_surface(painted)
    areas = segment_areas(part)
    away = np.einsum("ij,ij->i", areas.face_normals, areas.normal[areas.face_area]) < -0.5
    share = np.bincount(areas.face_area, part.face_areas * away, len(areas)) / areas.area_mm2
    assert share.max() < 0.05
    # the faces of the body's ends (the bumpers' faces) lie in areas facing out of the body at that end (all
    # but slivers: 6 faces of 354 at the -x end)
    x = part.triangles.mean(axis=1)[:, 0]
    nx = areas.face_normals[:, 0]
    for end, sign in ((x.min(), -1.0), (x.max(), 1.0)):
        face = (np.abs(x - end) < 150.0) & (sign * nx > 0.7)
        assert part.face_areas[face].sum() > 0.2e6
        out = sign * areas.normal[areas.face_area[face], 0] > 0.3
        assert part.face_areas[face][out].sum() > 0.95 * part.face_areas[face].sum()
    assert areas.area_mm2.sum() == pytest.approx(part.area)


def test_face_adjacency_pairs_each_shared_edge_once():
    box = grid_box(n=3)
    pairs, length = face_adjacency(box.faces, box.vertices)
    # a closed triangle mesh: every edge is shared by two faces, edges = 3 m / 2
    assert len(pairs) == 3 * len(box.faces) // 2
    assert len(np.unique(pairs, axis=0)) == len(pairs)
    for (a, b), ell in zip(pairs[:50], length[:50]):
        shared = set(box.faces[a]) & set(box.faces[b])
        assert len(shared) == 2
        p, q = box.vertices[list(shared)]
        assert ell == pytest.approx(np.linalg.norm(p - q))


def test_assignment_follows_the_reach_and_splits_where_no_robot_reaches_all():
    box = grid_box()
    areas = segment_areas(box, min_share=0.0)
    m = len(box.faces)
    centres = box.triangles.mean(axis=1)
    reach = np.zeros((2, m))
    reach[0, centres[:, 1] > 0] = 1.0  # robot 0 reaches the +y half
    reach[1, centres[:, 1] < 1e-9] = 0.5  # robot 1 the -y half and the middle
    got = assign_areas(areas, box.face_areas, reach)
    side_py = areas.direction.index("side +y")
    side_my = areas.direction.index("side -y")
    assert got.area_robot[side_py] == 0 and not got.split[side_py]
    assert got.area_robot[side_my] == 1 and not got.split[side_my]
    top = areas.direction.index("top")
    assert got.split[top] and got.area_share[top] == pytest.approx(0.5)
    on_top = areas.face_area == top
    expected = np.where(centres[:, 1] > 0, 0, 1)
    assert np.array_equal(got.face_robot[on_top], expected[on_top])
    # every face is painted by a robot that reaches it; the surface is conserved
    assert np.all(reach[got.face_robot, np.arange(m)] > 0)
    assert got.robot_area_mm2.sum() + got.unreached_mm2 == pytest.approx(box.area)
    # swapping the robots swaps the answer
    swapped = assign_areas(areas, box.face_areas, reach[::-1])
    assert np.array_equal(swapped.face_robot, 1 - got.face_robot)


def test_unreached_surface_is_data():
    box = grid_box()
    areas = segment_areas(box, min_share=0.0)
    centres = box.triangles.mean(axis=1)
    reach = (centres[:, 2] > -49.0)[None, :].astype(float)  # nothing reaches the bottom
    got = assign_areas(areas, box.face_areas, reach)
    bottom = areas.direction.index("bottom")
    assert got.area_robot[bottom] == -1
    assert got.unreached_mm2 == pytest.approx(areas.area_mm2[bottom])
    assert np.all(got.face_robot[areas.face_area == bottom] == -1)


def test_a_point_cloud_or_a_bad_share_is_refused():
    cloud = Part(np.random.default_rng(0).random((20, 3)), np.zeros((0, 3), int), name="cloud")
    with pytest.raises(ConfigError, match="point cloud"):
        segment_areas(cloud)
    with pytest.raises(ConfigError, match="min_share"):
        segment_areas(grid_box(), min_share=1.5)


# ------------------------------------------------------------------------------------------------- cells


def test_presets_load_and_name_their_robots():
    assert {"gantry-ur5", "line3", "line3-tall", "sides2"} <= set(list_cells())
    line3 = load_cell("line3")
    assert [r.name for r in line3.robots] == ["roof", "left", "right"]
    assert all(r.track is not None and r.reach_mm > 2000 for r in line3.robots)
    assert load_cell("gantry-ur5").is_gantry


def test_measured_reach_is_the_farthest_flange_point():
    robot = load_cell("line3").robots[0]
    arm = robot.robot(0.0)
    rng = np.random.default_rng(1)
    lim = arm.joint_limits
    q = lim[:, 0] + rng.random((2000, 6)) * (lim[:, 1] - lim[:, 0])
    flange = np.linalg.inv(arm.base2world) @ arm.fk(q) @ np.linalg.inv(arm.tcp2flange)
    assert np.linalg.norm(flange[:, :3, 3], axis=1).max() <= robot.reach_mm + 1.0


def _cell(**robots):
    return {"name": "t", "robot": [dict(name=k, **v) for k, v in robots.items()]}


@pytest.mark.parametrize(
    "data, message",
    [
        (_cell(a={"model": "no-such-arm"}), "unknown robot"),
        (
            _cell(a={"model": "abb-irb2400-10", "track": {"axis": "x", "range_mm": [100, 100]}}),
            "zero or negative length",
        ),
        (_cell(a={"model": "abb-irb2400-10"}, b={"model": "abb-irb2400-10", "base_mm": [100, 0, 0]}), "same place"),
        (_cell(a={"model": "abb-irb2400-10", "colour": "red"}), "unknown key 'colour'"),
        (_cell(a={"model": "abb-irb2400-10", "base_mm": [0, float("nan"), 0]}), "finite number"),
        ({"name": "t", "robot": []}, "at least one"),
        (_cell(a={"model": "gantry-ur5"}, b={"model": "abb-irb2400-10", "base_mm": [3000, 0, 0]}), "gantry"),
        (_cell(a={"model": "gantry-ur5", "lift": {"above_part_mm": 100, "range_mm": [0, 10]}}), "gantry robot"),
        (
            _cell(a={"model": "abb-irb2400-10", "lift": {"above_part_mm": 1000, "range_mm": [0, 0]}}),
            "lift.range_mm: the lift has zero or negative length",
        ),
        (
            _cell(a={"model": "abb-irb2400-10", "lift": {"above_part_mm": 0, "range_mm": [0, 100]}}),
            "lift.above_part_mm: must be above 0",
        ),
        (
            _cell(
                a={
                    "model": "abb-irb2400-10",
                    "base_mm": [0, 0, 500],
                    "lift": {"above_part_mm": 9, "range_mm": [0, 100]},
                }
            ),
            "outside 0 .. 100",
        ),
        (_cell(a={"model": "abb-irb2400-10", "lift": {"above_part_mm": 9}}), "lift.range_mm: missing"),
        (_cell(a={"model": "abb-irb2400-10", "lift": {"range_mm": [0, 1], "speed": 3}}), "unknown key 'speed'"),
        (
            _cell(
                a={
                    "model": "abb-irb2400-10",
                    "base_mm": [0, 0, 3000],
                    "lift": {"above_part_mm": 9, "range_mm": [0, 4000]},
                },
                b={"model": "abb-irb2400-10", "base_mm": [100, 0, 0]},
            ),
            "same place",
        ),
    ],
)
def test_bad_cells_name_the_file_and_the_problem(data, message):
    with pytest.raises(ConfigError, match=message) as err:
        cell_from_dict(data, source="my_cell.toml")
    assert str(err.value).startswith("my_cell.toml: ")
    assert "\n" not in str(err.value)


def test_a_cell_file_is_read_and_a_broken_one_refused(tmp_path):
    good = tmp_path / "two.toml"
    good.write_text('name = "two"\n[[robot]]\nname = "a"\nmodel = "abb-irb2400-10"\nbase_mm = [0, 2000, 0]\n')
    assert load_cell(good).robots[0].base2cell[1, 3] == 2000
    broken = tmp_path / "broken.toml"
    broken.write_text("[[robot]\n")
    with pytest.raises(ConfigError, match="broken.toml"):
        load_cell(broken)
    with pytest.raises(ConfigError, match="not a known cell"):
        load_cell("no-such-cell")


@pytest.fixture(scope="module")
def bmw(testdata):
    return load_part(testdata / "meshes" / "bmw_m6_body_m_yup.ply", units="m", up="y")


def test_a_part_is_placed_along_x_on_its_skid(testdata):
    suv = load_part(testdata / "meshes" / "gazebo_suv_body_m.ply", units="m")  # y along the car
    cell = load_cell("line3")
    placed = place_part(suv, cell)
    lo, hi = placed.part.bounds
    ext = hi - lo
    assert ext[0] > ext[1]
    assert cell.lift_mm == 500.0  # line3's skid
    assert lo[2] == pytest.approx(cell.floor_z_mm + cell.lift_mm, abs=1e-9)
    assert (lo[:2] + hi[:2]) / 2 == pytest.approx([0.0, 0.0], abs=1e-9)
    moved = placed.part2cell[:3, :3] @ suv.vertices.T + placed.part2cell[:3, 3:4]
    assert np.allclose(moved.T, placed.part.vertices, atol=1e-9)
    assert np.all(placed.reach_share > 0)


def test_a_lift_sets_its_robot_above_each_part_within_its_range(testdata, bmw):
    """A roof robot on a lift (line3's robots, the roof one given ``lift``) stands ``above_part_mm`` over each
    body's top (1.74 and 2.34 m high on the skid), the other robots where the file has them; a part so tall that
    the lift would pass its range stops at its top."""
    import tomllib
    from importlib import resources

    data = tomllib.loads(resources.files("sprayplan.cells").joinpath("presets", "line3.toml").read_text())
    data["robot"][0]["lift"] = {"above_part_mm": 1600.0, "range_mm": [3300.0, 4300.0]}
    cell = cell_from_dict(data, source="lifted.toml")
    suv = load_part(testdata / "meshes" / "gazebo_suv_body_m.ply", units="m")
    roof = cell.robots[0]
    assert roof.lift is not None and cell.robots[1].lift is None
    for body in (bmw, suv):
        placed = place_part(body, cell)
        top = placed.part.vertices[:, 2].max()
        bases = [r.base2cell for r in placed.cell.robots]
        assert bases[0][2, 3] == pytest.approx(top + roof.lift.above_part_mm)
        assert roof.lift.range_mm[0] <= bases[0][2, 3] <= roof.lift.range_mm[1]
        assert np.array_equal(bases[0][:3, :3], roof.base2cell[:3, :3]) and np.array_equal(bases[0][:2, 3], [0, 0])
        assert all(np.array_equal(b, r.base2cell) for b, r in zip(bases[1:], cell.robots[1:]))
    tall = Part(suv.vertices * [1.0, 1.0, 2.0], suv.faces, name="tall")
    assert place_part(tall, cell).cell.robots[0].base2cell[2, 3] == roof.lift.range_mm[1]
    # without a lift the base stays where the file has it
    del data["robot"][0]["lift"]
    fixed = cell_from_dict(data, source="fixed.toml")
    assert np.array_equal(place_part(suv, fixed).cell.robots[0].base2cell, fixed.robots[0].base2cell)
    # line3's own lift: 3.7 m over the BMW (its top + 1.8 m is below the range), 1.8 m over the SUV's top
    line3 = load_cell("line3")
    assert line3.robots[0].base2cell[2, 3] == 3700.0
    assert place_part(bmw, line3).cell.robots[0].base2cell[2, 3] == 3700.0
    placed = place_part(suv, line3)
    assert placed.cell.robots[0].base2cell[2, 3] == pytest.approx(placed.part.vertices[:, 2].max() + 1800.0)
    assert placed.cell.robots[0].base2cell[2, 3] > 4100.0


def test_a_robot_inside_the_part_or_a_part_out_of_reach_is_refused(bmw):
    inside = cell_from_dict(_cell(a={"model": "abb-irb2400-10", "base_mm": [0, 0, 300]}), source="in.toml")
    with pytest.raises(ConfigError, match="in.toml: robot 'a' stands inside the part"):
        place_part(bmw, inside)
    far = cell_from_dict(_cell(a={"model": "abb-irb2400-10", "base_mm": [0, 20000, 0]}), source="far.toml")
    with pytest.raises(ConfigError, match="far.toml: .* out of every robot's reach"):
        place_part(bmw, far)


def _assert_seed_split(body: Part, cell_name: str) -> None:
    """Seed 003, section 5, in cell ``cell_name``: the top to the roof robot, each side to its own, every
    reached face reached by its robot, under 2 % of the outer surface unreached (the inner faces of the sills,
    which face the car's middle under it, aside: no robot beside the car paints them straight on)."""
    from sprayplan.cells.plan import area_surface

    placed = place_part(body, load_cell(cell_name))
    cell = placed.cell  # its lifts set over this body, as plan_cell sets them
    part, _ = area_surface(drop_floor_facing(placed.part, 45.0)[0])  # as plan_cell splits it
    areas = segment_areas(part)
    reach = reach_matrix(cell, part, areas.face_normals, standoff_mm=113.0)
    got = assign_areas(areas, part.face_areas, reach)
    names = [r.name for r in cell.robots]
    first = {d: areas.direction.index(d) for d in ("top", "side +y", "side -y")}
    assert names[got.area_robot[first["top"]]] == "roof"
    assert names[got.area_robot[first["side +y"]]] == "left"
    assert names[got.area_robot[first["side -y"]]] == "right"
    assert got.robot_area_mm2.sum() + got.unreached_mm2 == pytest.approx(part.area)
    centres = part.triangles.mean(axis=1)
    inner = areas.face_normals[:, 1] * centres[:, 1] < -0.5 * np.abs(centres[:, 1])  # facing the middle plane
    unreached = got.face_robot < 0
    assert part.face_areas[unreached & ~inner].sum() < 0.02 * part.area
    assert got.unreached_mm2 < 0.06 * part.area
    assert np.all(reach[got.face_robot[got.face_robot >= 0], np.flatnonzero(got.face_robot >= 0)] > 0)


def test_line3_splits_the_bmw_like_the_seed(bmw):
    """Seed 003, section 5: roof and rear to one robot, each side to its own."""
    _assert_seed_split(bmw, "line3")


@pytest.mark.parametrize("cell_name", ["line3", "line3-tall"])
def test_line3_and_line3_tall_split_the_suv_like_the_seed(testdata, cell_name):
    """The SUV (about 1.84 m tall): its roof to the roof robot and each side to its own, as in seed 003, in
    line3 (its roof robot lifted to 1.8 m over the SUV's top, 4.14 m) and in line3-tall (the body on the
    floor)."""
    suv = load_part(testdata / "meshes" / "gazebo_suv_body_m.ply", units="m")
    assert 1700.0 < np.ptp(suv.vertices[:, 2]) < 2000.0  # z up in its file
    _assert_seed_split(suv, cell_name)


def test_reach_scores_are_inverse_kinematics_answers(bmw):
    """A face scored reached has a pose the robot solves, one scored 0 has none, at the face itself."""
    cell = load_cell("sides2")
    part, _ = drop_floor_facing(place_part(bmw, cell).part, 45.0)
    _, normals = outward_face_normals(part.vertices, part.faces)
    rng = np.random.default_rng(3)
    pick = rng.choice(len(part.faces), 300, replace=False)
    sub = Part(part.vertices, part.faces[pick], name="sub")
    exact = reach_matrix(cell, sub, normals[pick], 113.0, cluster_mm=0.0)
    grouped = reach_matrix(cell, part, normals, 113.0)[:, pick]
    assert ((exact > 0) == (grouped > 0)).mean() > 0.9
    from sprayplan.surface.poses import poses_at

    centres = sub.triangles.mean(axis=1)
    robot = cell.robots[0]
    arm = robot.robot(0.0)
    for f in np.flatnonzero(exact[0] > 0)[:20]:
        tip = centres[f] + 113.0 * normals[pick][f]
        s = np.clip((tip - robot.base2cell[:3, 3]) @ robot.track.axis, *robot.track.range_mm)
        solved = False
        for offset in (0.0, -500.0, 500.0):
            shift = np.clip(s + offset, *robot.track.range_mm)
            moved = dataclasses_replace_base(arm, robot, shift)
            for roll in (0.0, 90.0, 180.0, 270.0):
                c, sn = np.cos(np.radians(roll)), np.sin(np.radians(roll))
                rz = np.array([[c, -sn, 0, 0], [sn, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
                pose = poses_at(tip[None], normals[pick][f][None])[0] @ rz
                sols = moved.ik(pose[None])
                for q in sols.q[0][sols.valid[0]]:
                    assert np.allclose(moved.fk(q[None])[0], pose, atol=1e-6)
                    solved = True
        assert solved


def dataclasses_replace_base(arm, robot, shift):
    import dataclasses

    base = robot.base2cell.copy()
    base[:3, 3] += shift * robot.track.axis
    return dataclasses.replace(arm, base2world=base)


# ------------------------------------------------------------------------------------------------- command line


def _run(argv, capsys):
    from sprayplan.cli import main

    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_areas_command_writes_one_row_a_painted_face(testdata, tmp_path, capsys):
    import csv

    out = tmp_path / "areas.csv"
    suv = testdata / "meshes" / "gazebo_suv_body_m.ply"
    code, text, err = _run(["-q", "areas", suv, "--units", "m", "--cell", "sides2", "-o", out], capsys)
    assert code == 0, err
    rows = list(csv.DictReader(out.open()))
    part = load_part(suv, units="m")
    from sprayplan.cells.plan import AREA_EDGE_MM, area_surface
    from sprayplan.config import CollisionConfig
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import painted_surface

    placed = place_part(part, load_cell("sides2")).part
    painted, _ = painted_surface(oriented_part(placed), CollisionConfig())  # as plan_cell paints it
    split, parent = area_surface(painted)
    assert len(split.faces) > len(painted.faces)  # the SUV's long faces are split for the areas
    tri = split.triangles
    assert np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max() <= AREA_EDGE_MM
    np.testing.assert_allclose(np.bincount(parent, split.face_areas, len(painted.faces)), painted.face_areas, rtol=1e-9)
    assert len(rows) == len(split.faces)
    assert sum(float(r["face_area_mm2"]) for r in rows) == pytest.approx(painted.area, rel=1e-4)
    faces = np.array([int(r["face"]) for r in rows])
    # one row a piece: every painted face of the loaded part, as many times as it was split
    assert np.array_equal(np.unique(faces, return_counts=True)[1], np.bincount(parent))
    assert faces.max() < len(placed.faces)
    assert {r["robot"] for r in rows} <= {"left", "right", ""}
    assert all((r["robot"] == "") == (r["robot_index"] == "-1") for r in rows)
    assert "areas of" in text and str(out) in text


def test_areas_command_with_the_collision_model_reaches_no_more_and_needs_link_sizes(
    testdata, tmp_path, capsys, monkeypatch
):
    import csv

    from sprayplan.cells import collide
    from sprayplan.io.load import load_part

    pytest.importorskip("coal")
    suv = testdata / "meshes" / "gazebo_suv_body_m.ply"
    plain, checked = tmp_path / "plain.csv", tmp_path / "checked.csv"
    assert _run(["-q", "areas", suv, "--units", "m", "--cell", "sides2", "-o", plain], capsys)[0] == 0
    tilted = tmp_path / "tilted.csv"
    base = ["-q", "areas", suv, "--units", "m", "--cell", "sides2", "--collisions"]
    seen = []
    plain_arms = collide.cell_arms
    monkeypatch.setattr(
        collide, "cell_arms", lambda cell, part, config: seen.append(part) or plain_arms(cell, part, config)
    )
    code, _, err = _run([*base, "--piece-tilt-deg", "0", "-o", checked], capsys)
    assert code == 0, err
    # the arms are checked against the whole body, the surface facing the floor (not painted) too
    assert seen[0].area == pytest.approx(load_part(suv, units="m").area, rel=1e-9)
    code, _, err = _run([*base, "-o", tilted], capsys)
    assert code == 0, err
    a, b, c = (list(csv.DictReader(f.open())) for f in (plain, checked, tilted))
    assert [r["face"] for r in a] == [r["face"] for r in b] == [r["face"] for r in c]
    reached = np.array([r["robot"] != "" for r in a])
    reached_free = np.array([r["robot"] != "" for r in b])
    reached_tilted = np.array([r["robot"] != "" for r in c])
    assert not (reached_free & ~reached).any()  # the model only takes reach away
    assert reached_free.sum() < reached.sum()  # and on this body it does (1,002 faces reached against 594)
    # the gun tilted by up to 40 degrees (the default) gives some of it back, and takes none away
    assert not (reached_free & ~reached_tilted).any() and reached_tilted.sum() > reached_free.sum()
    # a cell of a robot the collision model has no link sizes for: one line, exit 2, nothing written
    ur = tmp_path / "ur.toml"
    ur.write_text('[[robot]]\nname = "a"\nmodel = "ur5"\nbase_mm = [0, 1500, 0]\n')
    out = tmp_path / "ur.csv"
    code, _, err = _run(["areas", suv, "--units", "m", "--cell", ur, "--collisions", "-o", out], capsys)
    assert code == 2 and "no link sizes" in err and len(err.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--cell", "no-such-cell"], "not a known cell"),
        (["--min-share", "2"], "--min-share"),
        (["--standoff-mm", "nan"], "--standoff-mm"),
        (["--floor-facing-deg", "nan"], "--floor-facing-deg"),
        (["--piece-tilt-deg", "90"], "--piece-tilt-deg"),
    ],
)
def test_areas_bad_options_are_one_line_and_write_nothing(testdata, tmp_path, capsys, extra, words):
    out = tmp_path / "areas.csv"
    suv = testdata / "meshes" / "gazebo_suv_body_m.ply"
    code, _, err = _run(["areas", suv, "--units", "m", "-o", out, *extra], capsys)
    assert code == 2
    assert words in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_a_broken_cell_file_is_one_line(testdata, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[robot]]\nname = "a"\nmodel = "abb-irb2400-10"\ntrack = {axis = "x", range_mm = [5, 5]}\n')
    code, _, err = _run(["cells", bad], capsys)
    assert code == 2 and "bad.toml" in err and "zero or negative length" in err
    out = tmp_path / "a.csv"
    code, _, err = _run(["areas", testdata / "meshes" / "gazebo_suv_body_m.ply", "--cell", bad, "-o", out], capsys)
    assert code == 2 and not out.exists()


def test_a_split_areas_seam_moves_to_where_both_robots_reach_well():
    box = grid_box()
    areas = segment_areas(box, min_share=0.0)
    centres = box.triangles.mean(axis=1)
    top = areas.direction.index("top")
    on_top = areas.face_area == top
    x = centres[:, 0]
    reach = np.zeros((2, len(box.faces)))
    reach[0, x < 150.0] = 1.0  # robot 0 reaches most of the top, weakly near its far end
    reach[0, (x > 50.0) & (x < 150.0)] = 0.25
    reach[1, x > 0.0] = 1.0  # robot 1 reaches the +x half well
    got = assign_areas(areas, box.face_areas, reach)
    assert got.area_robot[top] == 0 and got.split[top]
    weak = on_top & (x > 50.0) & (x < 150.0)
    assert np.all(got.face_robot[weak] == 1)  # robot 0's weak band goes to the robot that reaches it well
    assert np.all(got.face_robot[on_top & (x < 0.0)] == 0)
    # without the rule (robust 0) the band stays with robot 0, the seam at the edge of its reach
    edge = assign_areas(areas, box.face_areas, reach, robust=0.0)
    assert np.all(edge.face_robot[weak] == 0)


def test_a_robot_that_reaches_an_area_only_tilted_does_not_take_it_from_one_that_reaches_most_of_it_straight():
    """``assign_areas`` with tilt-only scores (``TILTED``): the top goes to robot 1, which reaches 3/4 of it
    along the normal, not to robot 0, which reaches all of it but only tilted; the quarter robot 1 does not
    reach goes to robot 0 (tilted is reached). Counting tilt-only faces as covered would give robot 0 the top."""
    from sprayplan.surface.areas import TILTED

    box = grid_box()
    areas = segment_areas(box, min_share=0.0)
    x = box.triangles.mean(axis=1)[:, 0]
    top = areas.direction.index("top")
    on_top = areas.face_area == top
    reach = np.zeros((2, len(box.faces)))
    reach[0, on_top] = TILTED
    reach[1, on_top & (x > -100.0)] = 0.5
    got = assign_areas(areas, box.face_areas, reach)
    assert got.area_robot[top] == 1 and got.split[top]
    assert np.all(got.face_robot[on_top & (x > -100.0)] == 1)
    assert np.all(got.face_robot[on_top & (x < -100.0)] == 0)
    # an area no robot reaches straight goes to the one that reaches more of it tilted
    reach[1] = 0.0
    reach[1, on_top & (x > 0.0)] = TILTED
    assert assign_areas(areas, box.face_areas, reach).area_robot[top] == 0
    # counted as covered like any other face (the rule this replaces), the tilted robot takes the top
    reach[1, on_top & (x > -100.0)] = 0.5
    flat = np.where(reach > 0, 1.0, 0.0)
    flat[1] = reach[1]
    assert assign_areas(areas, box.face_areas, flat).area_robot[top] == 0


def test_with_the_collision_model_a_face_reached_only_through_the_body_is_not_reached(bmw):
    """``reach_matrix(arms=...)``: a face keeps its score where one of its tries has a valid branch free of the
    part and the floor (coal's exact check of that configuration says so), and scores 0 where every valid
    branch of every try collides, such as the inner face of a sill under the car."""
    pytest.importorskip("coal")
    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.reach import ROLLS_DEG, TRACK_OFFSETS_MM
    from sprayplan.config import CollisionConfig
    from sprayplan.surface.poses import poses_at

    cell = load_cell("line3")
    part, _ = drop_floor_facing(place_part(bmw, cell).part, 45.0)
    _, normals = outward_face_normals(part.vertices, part.faces)
    arms = cell_arms(cell, part, CollisionConfig(check=True))
    centres = part.triangles.mean(axis=1)
    # faces low on the left side, where the inner sill faces inwards (-y) and the outer one outwards
    bottom = part.vertices[:, 2].min()
    low = np.flatnonzero((centres[:, 2] < bottom + 250.0) & (centres[:, 1] > 700.0) & (np.abs(centres[:, 0]) < 800.0))
    pick = np.random.default_rng(5).choice(low, 120, replace=False)
    sub = Part(part.vertices, part.faces[pick], name="sub")
    plain = reach_matrix(cell, sub, normals[pick], 113.0, cluster_mm=0.0)
    checked = reach_matrix(cell, sub, normals[pick], 113.0, cluster_mm=0.0, arms=arms)
    kept = checked > 0
    np.testing.assert_array_equal(checked[kept], plain[kept])
    assert np.all(checked <= plain)
    lost = (plain > 0) & ~kept
    assert lost[1].sum() >= 5 and kept[1].sum() >= 5  # the left robot: both kinds among these faces
    assert np.all(normals[pick][lost[1], 1] < 0.5)  # what it loses does not face it

    robot, arm = cell.robots[1], arms[1]
    solver = robot.robot(0.0)

    def free_tries(f: int) -> tuple[int, int]:
        """(valid branches of all tries, of them free by the exact check) of face ``f`` of ``sub``."""
        tip = centres[pick][f] + 113.0 * normals[pick][f]
        along = float((tip - robot.base2cell[:3, 3]) @ robot.track.axis)
        valid = free = 0
        for offset in TRACK_OFFSETS_MM:
            s = float(np.clip(along + offset, *robot.track.range_mm))
            for roll in ROLLS_DEG:
                c, sn = np.cos(np.radians(roll)), np.sin(np.radians(roll))
                rz = np.array([[c, -sn, 0, 0], [sn, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
                pose = poses_at(tip[None], normals[pick][f][None])[0] @ rz
                pose[:3, 3] -= s * robot.track.axis
                sols = solver.ik(pose[None])
                q = sols.q[0][sols.valid[0]]
                valid += len(q)
                if len(q):
                    free += int((~arm.check(q, np.full(len(q), s)).collides).sum())
        return valid, free

    for f in np.flatnonzero(lost[1])[:8]:
        valid, free = free_tries(int(f))
        assert valid > 0 and free == 0
    for f in np.flatnonzero(kept[1])[:8]:
        assert free_tries(int(f))[1] > 0

    # tilted tries (reach_tilts): the faces reached straight keep their scores, some lost ones come back at
    # TILTED, and each of those has a tilted pose (the gun turned about the pose's x or y axis through the
    # face's target, built here with scipy) that the robot reaches free
    from scipy.spatial.transform import Rotation

    from sprayplan.cells.reach import reach_tilts
    from sprayplan.surface.areas import TILTED

    tilts = reach_tilts(40.0)
    assert tilts == tuple((axis, a) for axis in (0, 1) for a in (20.0, -20.0, 40.0, -40.0)) and reach_tilts(0.0) == ()
    tilted = reach_matrix(cell, sub, normals[pick], 113.0, cluster_mm=0.0, arms=arms, tilts_deg=tilts)
    np.testing.assert_array_equal(tilted[kept], checked[kept])
    back = (tilted > 0) & ~kept
    assert back[1].sum() >= 1 and np.all(tilted[back] == TILTED) and np.all(checked[kept] > TILTED)

    def tilted_free(f: int) -> bool:
        target = centres[pick][f]
        straight = poses_at((target + 113.0 * normals[pick][f])[None], normals[pick][f][None])[0]
        along = float((straight[:3, 3] - robot.base2cell[:3, 3]) @ robot.track.axis)  # as the straight tries
        for axis, angle in tilts:
            pose = straight.copy()
            pose[:3, :3] = straight[:3, :3] @ Rotation.from_rotvec(np.radians(angle) * np.eye(3)[axis]).as_matrix()
            pose[:3, 3] = target - 113.0 * pose[:3, 2]
            for offset in TRACK_OFFSETS_MM:
                s = float(np.clip(along + offset, *robot.track.range_mm))
                for roll in ROLLS_DEG:
                    c, sn = np.cos(np.radians(roll)), np.sin(np.radians(roll))
                    rz = np.array([[c, -sn, 0, 0], [sn, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
                    moved = pose @ rz
                    moved[:3, 3] -= s * robot.track.axis
                    sols = solver.ik(moved[None])
                    q = sols.q[0][sols.valid[0]]
                    if len(q) and (~arm.check(q, np.full(len(q), s)).collides).any():
                        return True
        return False

    for f in np.flatnonzero(back[1])[:4]:
        assert tilted_free(int(f))


def test_a_cell_files_description_is_its_description_and_it_is_placed_by_its_rules():
    import tomllib
    from importlib import resources

    for name in ("line3", "line3-tall", "sides2"):
        text = resources.files("sprayplan.cells").joinpath("presets", f"{name}.toml").read_text()
        cell = load_cell(name)
        assert cell.description == tomllib.loads(text)["description"] != ""
        assert cell.place == "cell"
