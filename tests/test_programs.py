"""Robot programs (sprayplan.programs, issue 15): URScript, RAPID and KRL written for real plans, read back by
their own strict readers and checked move by move and by their film against the plan."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.config import JobConfig
from sprayplan.programs.check import check_program
from sprayplan.programs.model import ProgramError
from sprayplan.programs.stage import export_plan, read_programs
from tests.helpers import BARE_NORMALS, BARE_NORMALS_TOML

FORMATS = ("urscript", "rapid", "krl")
ROOF_REGION = "box(-450, -350, 1000, 450, 350, 2000)"


def plan_of(part, job):
    from sprayplan.job import run_job

    return run_job(part, job, until="kinematics")


@pytest.fixture(scope="module")
def plans(testdata):
    """Three plans of the gantry-UR5 cell: a corner of the demo roof (2 stations), the reach part (2 stations,
    SQP moving the gantry up to 45 mm within a station, unreachable spray waypoints) and the tray (a flat panel
    with holes, 1 station); the reach part and the tray with the gun on every normal (``BARE_NORMALS``: the
    tray's plan then has the few SQP waypoints that RAPID and KRL follow as the plan's film does)."""
    from sprayplan.demo import car_roof
    from sprayplan.io.load import load_part
    from sprayplan.surface.region import select_region

    roof = car_roof(resolution_mm=50.0)
    roof_job = JobConfig().replace(
        load={"region": ROOF_REGION}, paths={"spacing_mm": 150.0, "step_mm": 50.0, "direction": "y"}
    )
    reach = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    reach_job = JobConfig().replace(load={"units": "m", "region": "x > -250"}, paths=BARE_NORMALS)
    tray = load_part(testdata / "meshes" / "tray_bottom_mm_ascii.stl", up="y")
    tray_job = JobConfig().replace(
        load={"up": "y", "region": "z > 3.1"}, paths={"spacing_mm": 40.0, "step_mm": 20.0, **BARE_NORMALS}
    )
    out = {}
    for name, part, job in (("roof", roof, roof_job), ("reach", reach, reach_job), ("tray", tray, tray_job)):
        state = plan_of(part, job)
        out[name] = (select_region(part, job.load.region), state.job, state.plan)
    return out


@pytest.fixture(scope="module")
def exported(plans, tmp_path_factory):
    """``exported(name, fmt)``: (folder, built, summary, read, check) of a plan's programs, made once."""
    cache = {}
    root = tmp_path_factory.mktemp("programs")

    def get(name, fmt, **export):
        key = (name, fmt, tuple(sorted(export.items())))
        if key not in cache:
            _part, job, plan = plans[name]
            job = job.replace(export=export) if export else job
            folder = root / f"{name}-{len(cache)}"
            (built,), (summary,) = export_plan(plan, job, [fmt], folder)
            read = read_programs(folder / fmt, job, fmt)
            cache[key] = (folder / fmt, built, summary, read, check_program(read, plan, job), job)
        return cache[key]

    return get


def spray_reachable(plan) -> int:
    return sum(
        int((st.reachable & np.concatenate([[s.spray_on] * len(s) for s in st.strokes])).sum()) for st in plan.stations
    )


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("name", ["roof", "reach", "tray"])
def test_every_program_reads_back_as_its_plan(plans, exported, name, fmt):
    folder, _built, summary, read, result, _job = exported(name, fmt)
    _, _, plan = plans[name]
    assert result.failures == []
    assert result.runs > 0 and result.waypoints > 0
    # poses within 0.01 mm and 0.01 deg, joints within 1e-6 rad, speeds within the written digits, the gun's
    # switching points within 0.01 mm, the gantry's axes, blends within 40 % of the shorter segment
    assert result.max_position_mm <= 0.01 and result.max_angle_deg <= 0.01
    assert result.max_joint_rad <= 1e-6 and result.max_speed_mm_s <= 1e-4
    assert result.max_gun_mm <= 0.01 and result.max_external_mm <= 1e-3
    assert 0 < result.max_blend_share <= 0.4
    # every reachable spray waypoint is programmed, or listed in summary.json as left out (and only those)
    assert result.duplicates == summary["counts"]["duplicate_waypoints"]
    listed = {(w["station"], w["stroke"], w["waypoint"]) for key in ("gantry_offset_waypoints", "unapproachable_waypoints")
              for w in summary["left_out"][key]}  # fmt: skip
    assert {_where(plan, order, k) for order, k in result.left_out} == listed
    # the summary's files are the folder's, with their sizes and move counts
    on_disk = {p.name: p.stat().st_size for p in folder.iterdir() if p.name != "summary.json"}
    assert {f["file"]: f["bytes"] for f in summary["files"]} == on_disk
    assert sum(f["moves"] for f in summary["files"]) == summary["moves"] == len(read.moves)


def _where(plan, order, k):
    st = plan.stations[order]
    start = 0
    for i, s in enumerate(st.strokes):
        if k < start + len(s):
            return order, i, k - start
        start += len(s)
    raise AssertionError(k)


def test_the_nine_axis_plan_drives_the_gantry_in_rapid_and_krl(plans, exported):
    """The reach plan moves the gantry between its stations and, by SQP, within them: RAPID's eax_a..c and
    KRL's E1..E3 follow it target by target; URScript holds each station's and leaves out the waypoints where
    the plan moves it farther than ur_gantry_offset_mm."""
    _, _, plan = plans["reach"]
    moved = [np.linalg.norm(st.q9[st.reachable, 6:] - st.platform_mm, axis=1).max() for st in plan.stations]
    assert max(moved) > 10.0 and len(plan.stations) == 2
    for fmt in ("rapid", "krl"):
        read = exported("reach", fmt)[3]
        ext = np.array([m.external_mm for m in read.moves])
        assert np.ptp(ext[:, 0]) > 100 and len(np.unique(np.round(ext, 3), axis=0)) > 20
    summary = exported("reach", "urscript")[2]
    assert summary["left_out"]["gantry_offset_waypoints"]
    offsets = [st.q9[:, 6:] - st.platform_mm for st in plan.stations]
    for w in summary["left_out"]["gantry_offset_waypoints"]:
        k = _index(plan, w)
        assert np.linalg.norm(offsets[w["station"]][k]) > 2.0


def _index(plan, w) -> int:
    st = plan.stations[w["station"]]
    return sum(len(s) for s in st.strokes[: w["stroke"]]) + w["waypoint"]


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("name", ["roof", "reach", "tray"])
def test_the_film_of_a_program_read_back_is_the_plans(plans, exported, name, fmt):
    """The film predicted from the program as read back (its poses, speeds, gun signals and leads) against the
    plan's as its joints run it, over the waypoints the program sprays: the same deposit within 0.1 %, and no
    sample more than 0.1 % of the thickest film apart. The occlusion model is off for the sample-by-sample
    comparison: its views are placed by the gun's travel, so a sample on a shadow's border may flip with a
    micrometre of rounding (docs/programs.md); the deposit is compared with it on too."""
    from sprayplan.coating.stage import simulate_plan
    from sprayplan.programs.film import compare, program_paths, reference_paths, simulate_paths

    part, job, plan = plans[name]
    *_, read, result, job = exported(name, fmt)
    plain = job.replace(coating={"occlusion": "none"})
    program = program_paths(read, job, vias=result.via_moves)
    reference = reference_paths(plan, job, fmt, result.left_out)
    found = compare(simulate_paths(part, *program, plain), simulate_paths(part, *reference, plain))
    assert found["volume_difference"] <= 1e-3 and found["max_difference"] <= 1e-3
    if name == "tray":  # with the occlusion model on; and, where the program leaves nothing out (RAPID and
        # KRL move the gantry as SQP does), the plan's own film: its deposit
        film = simulate_paths(part, *program, job)
        assert compare(film, simulate_paths(part, *reference, job))["volume_difference"] <= 1e-3
        if fmt != "urscript":
            assert not result.left_out
            assert compare(film, simulate_plan(part, plan, job))["volume_difference"] <= 1e-3


def test_a_wrong_program_is_caught_by_the_checks(plans, exported, tmp_path):
    """Each kind of mistake, made in a written program, is found: the checks are not vacuous."""
    _, job, plan = plans["roof"]
    folder = exported("roof", "rapid")[0]
    module = sorted(folder.glob("sprayplan_0*.mod"))[0]
    text = module.read_text()
    moves = [i for i, line in enumerate(text.split("\n")) if line.strip().startswith("MoveL")]

    def mutated(change, line=moves[5]):
        copy = tmp_path / f"m{len(list(tmp_path.iterdir()))}"
        shutil.copytree(folder, copy)
        lines = text.split("\n")
        lines[line] = change(lines[line])
        (copy / module.name).write_text("\n".join(lines))
        return check_program(read_programs(copy, job, "rapid"), plan, job).failures

    x = re.search(r"\[\[(-?[\d.]+),", text.split("\n")[moves[5]]).group(1)
    assert any("from the pose" in f for f in mutated(lambda s: s.replace(f"[[{x},", f"[[{float(x) + 0.02:.4f},", 1)))
    assert any(
        "speed" in f
        for f in mutated(
            lambda s: re.sub(r"\], \[([\d.]+),500", lambda m: f"], [{float(m.group(1)) + 0.01:.4f},500", s)
        )
    )
    assert any(
        "blend" in f
        for f in mutated(
            lambda s: re.sub(
                r"\[FALSE,([\d.]+),([\d.]+),([\d.]+),([\d.]+),([\d.]+),",
                r"[FALSE,99.0000,99.0000,99.0000,\4,99.0000,",
                s,
            )
        )
    )
    assert any(
        "configuration data" in f
        for f in mutated(
            lambda s: re.sub(
                r"\],\[(-?\d+),(-?\d+),(-?\d+),(\d)\],",
                lambda m: f"],[{m.group(1)},{m.group(2)},{m.group(3)},{(int(m.group(4)) + 1) % 8}],",
                s,
            )
        )
    )
    assert any(
        "external axes" in f
        for f in mutated(
            lambda s: re.sub(
                r"\],\[(-?[\d.]+),(-?[\d.]+),(-?[\d.]+),9E\+09",
                lambda m: f"],[{float(m.group(1)) + 0.01:.4f},{m.group(2)},{m.group(3)},9E+09",
                s,
            )
        )
    )
    trigger = next(i for i, line in enumerate(text.split("\n")) if "TriggIO" in line)
    assert any(
        "gun" in f
        for f in mutated(
            lambda s: re.sub(r"trGun1, ([\d.]+)", lambda m: f"trGun1, {float(m.group(1)) + 0.05:.4f}", s), trigger
        )
    )
    joint = next(
        i for i, line in enumerate(text.split("\n")) if "MoveAbsJ" in line and "-90.000000,0.000000,-90.0" not in line
    )
    assert any(
        "joint target" in f
        for f in mutated(
            lambda s: re.sub(r"\[\[(-?[\d.]+),", lambda m: f"[[{float(m.group(1)) + 0.0001:.6f},", s, count=1), joint
        )
    )


def test_the_urscript_and_krl_checks_catch_a_changed_value(plans, exported, tmp_path):
    _, job, plan = plans["roof"]
    ur = exported("roof", "urscript")[0]
    copy = tmp_path / "ur"
    shutil.copytree(ur, copy)
    script = sorted(copy.glob("*_station_01.script"))[0]
    lines = script.read_text().split("\n")
    k = next(i for i, line in enumerate(lines) if line.strip().startswith("movep") and "r=0.0000000" not in line)
    lines[k] = re.sub(r"v=([\d.]+)", lambda m: f"v={float(m.group(1)) + 0.001:.7f}", lines[k])
    script.write_text("\n".join(lines))
    assert any("speed" in f for f in check_program(read_programs(copy, job, "urscript"), plan, job).failures)
    krl = exported("roof", "krl")[0]
    copy = tmp_path / "krl"
    shutil.copytree(krl, copy)
    dat = copy / "sprayplan_001.dat"
    text = dat.read_text()
    changed = re.sub(r"T (\d+),E1", lambda m: f"T {int(m.group(1)) ^ 1},E1", text, count=3)
    dat.write_text(changed)
    assert any("configuration data" in f for f in check_program(read_programs(copy, job, "krl"), plan, job).failures)


# --- what every program holds -------------------------------------------------------------------------------


def test_each_format_has_its_frame_lines(exported):
    ur = exported("roof", "urscript")[0]
    for script in ur.glob("*.script"):
        lines = script.read_text().split("\n")
        assert lines[0] == f"def {script.stem}():" and lines[-2] == f"{script.stem}()" and lines[-1] == ""
        assert lines[-3] == "end"
        assert "set_tcp(p[0.0055000, 0.0945000, 0.2785000," in lines[3]  # T_tool then T_dis, in metres
    rapid = exported("roof", "rapid")[0]
    for module in rapid.glob("*.mod"):
        text = module.read_text()
        assert "%%%" not in text
        lines = text.split("\n")
        assert lines[0] == f"MODULE {module.stem}" and lines[-2] == "ENDMODULE"
        assert f"  PROC {'main' if module.stem.endswith('main') else module.stem}()" in lines and "  ENDPROC" in lines
    main_text = (rapid / "sprayplan_main.mod").read_text()
    assert "PERS tooldata tSprayGun := [TRUE,[[5.5000,94.5000,278.5000],[1.000000000," in main_text
    krl = exported("roof", "krl")[0]
    main_src = (krl / "sprayplan.src").read_text().split("\n")
    assert main_src[2] == "DEF sprayplan( )" and main_src[-2] == "END"
    assert main_src[3:6] == [";FOLD INI", "  BAS (#INITMOV,0 )", ";ENDFOLD (INI)"]
    assert "  TOOL_DATA[1]={X 5.5000,Y 94.5000,Z 278.5000,A 0.000000,B 0.000000,C 0.000000}" in main_src
    for src in krl.glob("sprayplan_*.src"):
        assert (krl / f"{src.stem}.dat").exists()
        assert src.read_text().split("\n")[-2] == "END"


def test_numbers_are_written_fixed_whatever_the_locale(plans, tmp_path):
    import locale

    _, job, plan = plans["tray"]
    first = tmp_path / "a"
    export_plan(plan, job, FORMATS, first)
    number = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:E\+09)?(?![\w.])")
    for path in first.rglob("*"):
        if path.suffix in (".mod", ".src", ".dat", ".script"):
            text = path.read_text()
            for cell in re.findall(r"-?\d+\.\d+(?:[eE][+-]?\d+)?", text):
                assert "e" not in cell.lower()
            assert number.search(text)
    saved = locale.setlocale(locale.LC_ALL)
    for name in ("de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8", "C.UTF-8"):
        try:
            locale.setlocale(locale.LC_ALL, name)
            break
        except locale.Error:
            continue
    try:
        second = tmp_path / "b"
        export_plan(plan, job, FORMATS, second)
    finally:
        locale.setlocale(locale.LC_ALL, saved)
    for path in first.rglob("*"):
        if path.is_file() and path.name != "summary.json":
            assert path.read_bytes() == (second / path.relative_to(first)).read_bytes()


def test_poses_convert_to_each_formats_conventions():
    from scipy.spatial.transform import Rotation

    from sprayplan.programs.model import kuka_abc, matrix_from_abc, matrix_from_wxyz, quaternion_wxyz, rotvec

    about_z = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    np.testing.assert_allclose(quaternion_wxyz(about_z), [np.sqrt(0.5), 0, 0, np.sqrt(0.5)], atol=1e-12)  # w first
    np.testing.assert_allclose(matrix_from_wxyz([np.sqrt(0.5), 0, 0, np.sqrt(0.5)]), about_z, atol=1e-12)
    # KUKA A, B, C: Rz(A) Ry(B) Rx(C)
    r = (
        Rotation.from_euler("z", 30, degrees=True)
        * Rotation.from_euler("y", 20, degrees=True)
        * Rotation.from_euler("x", 10, degrees=True)
    )
    np.testing.assert_allclose(kuka_abc(r.as_matrix()), [30, 20, 10], atol=1e-9)
    np.testing.assert_allclose(matrix_from_abc([30, 20, 10]), r.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(rotvec(about_z), [0, 0, np.pi / 2], atol=1e-12)


def test_rapid_configuration_data_follow_the_joints():
    from sprayplan.programs.model import branch_bits, krl_status_turn, rapid_config

    q = np.radians([[100.0, -45.0, 30.0, -190.0, 20.0, 359.0], [-10.0, -90.0, -30.0, 45.0, -20.0, -1.0]])
    np.testing.assert_array_equal(rapid_config(q, [0, 7])[:, :3], [[1, -3, 3], [-1, 0, -1]])
    # cfx = 4 shoulder + 2 elbow + wrist from the UR branch index 4 shoulder + 2 wrist + elbow
    assert [int(v) for v in rapid_config(q, [5, 2])[:, 3]] == [4 + 2, 1]
    assert [tuple(int(b) for b in branch_bits(5))] == [(1, 1, 0)]
    np.testing.assert_array_equal(krl_status_turn(q, [5, 2]), [[1 + 2, 0b001010], [4, 0b110111]])


def test_files_are_split_to_their_limits(plans, exported):
    _, _job, plan = plans["reach"]
    ur = exported("reach", "urscript", ur_max_moves=40)
    assert ur[4].failures == []
    scripts = [s for s in ur[3].scripts]
    assert len(scripts) > len(plan.stations) and max(s["count"] for s in scripts) <= 40
    assert [s["station"] for s in scripts] == sorted(
        (s["station"] for s in scripts), key=[st.index for st in plan.stations].index
    )
    rapid = exported("reach", "rapid", rapid_max_lines=120)
    assert rapid[4].failures == []
    modules = [f for f in rapid[2]["files"] if f["file"] != "sprayplan_main.mod"]
    assert len(modules) > 3 and max(f["lines"] for f in modules) <= 120
    calls = re.findall(r"^    (sprayplan_\d{3});$", (rapid[0] / "sprayplan_main.mod").read_text(), re.M)
    assert calls == [f["file"][:-4] for f in modules]
    krl = exported("reach", "krl", krl_max_moves=40)
    assert krl[4].failures == []
    subs = [f for f in krl[2]["files"] if f["file"].endswith(".src") and f["file"] != "sprayplan.src"]
    assert len(subs) > 3 and max(f["moves"] for f in subs) <= 40


@pytest.mark.parametrize("fmt", FORMATS)
def test_long_gun_leads_and_no_leads_are_placed_exactly(exported, fmt):
    """A lead longer than a move puts the off signal several moves before the run's end, and the approach
    slows so that the opening lead fits on it; no lead switches at the stop points."""
    slow = exported("roof", fmt, lead_on_s=0.5, lead_off_s=0.4)
    assert slow[4].failures == [] and slow[4].max_gun_mm <= 0.01
    transfer, approach = slow[1].program.stations[0].moves[1:3]
    length = np.linalg.norm(approach.pose[:3, 3] - transfer.pose[:3, 3])
    assert approach.role == "approach" and approach.speed_mm_s == pytest.approx(min(250.0, length / 0.5))
    none = exported("roof", fmt, lead_on_s=0.0, lead_off_s=0.0)
    assert none[4].failures == []
    runs = [m for st in none[1].program.stations for m in st.moves if m.events]
    assert all(d == 0.0 and m.blend_mm == 0.0 for m in runs for d, _ in m.events)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # rapidchecker 0.1.5 calls pyparsing's old names
def test_rapidchecker_accepts_the_rapid_of_a_small_plan(plans, tmp_path):
    """The independent RAPID grammar of the ``rapidchecker`` package (slow: about 30 ms a line) parses every
    module of a small plan, with TriggIO/TriggL and with the Paint variant, split into modules."""
    rapidchecker = pytest.importorskip("rapidchecker.check")
    from sprayplan.demo import car_roof

    job = JobConfig().replace(load={"region": "box(100, 100, 1000, 400, 400, 2000)"},
                              paths={"spacing_mm": 100.0, "step_mm": 80.0, "direction": "y"})  # fmt: skip
    plan = plan_of(car_roof(resolution_mm=50.0), job).plan
    for paint in (False, True):
        cfg = {"rapid_paint": paint, "rapid_max_lines": 50}
        folder = tmp_path / str(paint)
        export_plan(plan, job.replace(export=cfg), ["rapid"], folder)
        modules = sorted((folder / "rapid").glob("*.mod"))
        assert len(modules) >= 3
        text = ""
        for module in modules:
            assert rapidchecker.check_format(module.read_text()) == [], module.name
            text += module.read_text()
        assert (
            check_program(
                read_programs(folder / "rapid", job.replace(export=cfg), "rapid"), plan, job.replace(export=cfg)
            ).failures
            == []
        )
        assert ("PaintL" in text) == paint and ("TriggL" in text) != paint


# --- strict readers -----------------------------------------------------------------------------------------

UR_SEQUENCE = "step,station,script,x_mm,y_mm,z_mm\n0,home,,0.0,0.0,0.0\n1,0,t_station_01.script,0.0,0.0,1800.0\n2,home,,0.0,0.0,0.0\n"
UR_SCRIPT = """def t_station_01():
  # a hand-written station script
  set_tcp(p[0.0055, 0.0945, 0.2785, 0.0, 0.0, 0.0])
  part_frame = p[0.0, 0.0, 1.8, 3.141592654, 0.0, 0.0]
  set_standard_digital_out(0, False)
  set_standard_digital_out(1, False)
  while not get_standard_digital_in(0):
    sync()
  end
  movej([0.0, -1.5708, 0.0, -1.5708, 0.0, 0.0], a=1.4, v=1.0, r=0)
  movel(pose_trans(part_frame, p[0.1, 0.2, 1.3, 3.14, 0.0, 0.0]), a=1.2, v=0.25, r=0.0)
  set_standard_digital_out(0, True)
  movep(pose_trans(part_frame, p[0.15, 0.2, 1.3, 3.14, 0.0, 0.0]), a=1.2, v=0.4, r=0.0)
  set_standard_digital_out(0, False)
  set_standard_digital_out(1, True)
end
t_station_01()
"""
RAPID_MAIN = """MODULE t_main
  PERS tooldata tSprayGun := [TRUE,[[5.5,94.5,278.5],[1,0,0,0]],[1,[5.5,94.5,165.5],[1,0,0,0],0,0,0]];
  PERS wobjdata wPart := [FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  VAR triggdata trGun1;
  VAR triggdata trGun2;
  PROC main()
    ConfJ\\On;
    ConfL\\On;
    SetDO doGun, 0;
    t_001;
  ENDPROC
ENDMODULE
"""
RAPID_PART = """MODULE t_001
  PROC t_001()
    ! a hand-written module
    MoveAbsJ [[0,-90,0,-90,0,0],[0,0,1800,9E+09,9E+09,9E+09]], [500,60,250,60], fine, tSprayGun\\WObj:=wPart;
    TriggIO trGun1, 12.5\\DOp:=doGun, 1;
    TriggL [[100,200,1300],[0,1,0,0],[0,0,0,0],[0,0,1800,9E+09,9E+09,9E+09]], [250,500,5000,1000], trGun1, fine, tSprayGun\\WObj:=wPart;
    MoveL [[150,200,1300],[0,1,0,0],[0,0,0,0],[0,0,1800,9E+09,9E+09,9E+09]], [400,500,5000,1000], [FALSE,4,4,4,0.4,4,0.4], tSprayGun\\WObj:=wPart;
  ENDPROC
ENDMODULE
"""
KRL_MAIN = """&ACCESS RVP
&REL 1
DEF t( )
;FOLD INI
  BAS (#INITMOV,0 )
;ENDFOLD (INI)
  TOOL_DATA[1]={X 5.5,Y 94.5,Z 278.5,A 0.0,B 0.0,C 0.0}
  BASE_DATA[1]={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}
  $TOOL=TOOL_DATA[1]
  $BASE=BASE_DATA[1]
  $OUT[1]=FALSE
  BAS (#VEL_PTP,30 )
  t_001( )
END
"""
KRL_SRC = """&ACCESS RVP
&REL 1
DEF t_001( )
  ; a hand-written subprogram
  PTP XJ1
  $VEL.CP=0.25
  TRIGGER WHEN PATH=-12.5 DELAY=0 DO $OUT[1]=TRUE
  LIN XP2
  $VEL.CP=0.4
  $APO.CDIS=4.0
  LIN XP3 C_DIS
END
"""
KRL_DAT = """&ACCESS RVP
&REL 1
DEFDAT t_001
  DECL E6AXIS XJ1={A1 0.0,A2 -90.0,A3 0.0,A4 -90.0,A5 0.0,A6 0.0,E1 0.0,E2 0.0,E3 1800.0,E4 0.0,E5 0.0,E6 0.0}
  DECL E6POS XP2={X 100.0,Y 200.0,Z 1300.0,A 0.0,B 0.0,C 180.0,S 2,T 10,E1 0.0,E2 0.0,E3 1800.0,E4 0.0,E5 0.0,E6 0.0}
  DECL E6POS XP3={X 150.0,Y 200.0,Z 1300.0,A 0.0,B 0.0,C 180.0,S 2,T 10,E1 0.0,E2 0.0,E3 1800.0,E4 0.0,E5 0.0,E6 0.0}
ENDDAT
"""
HAND = {
    "urscript": {"t_stations.csv": UR_SEQUENCE, "t_station_01.script": UR_SCRIPT},
    "rapid": {"t_main.mod": RAPID_MAIN, "t_001.mod": RAPID_PART},
    "krl": {"t.src": KRL_MAIN, "t_001.src": KRL_SRC, "t_001.dat": KRL_DAT},
}
T_JOB = JobConfig().replace(export={"name": "t"})

BROKEN = [
    (
        "urscript",
        "t_station_01.script",
        "t_station_01()\n",
        "",
        "must end with 'end' and the call",
    ),  # defined, never called
    ("urscript", "t_station_01.script", "    sync()\n", "", "the wait for the ready input"),
    (
        "urscript",
        "t_station_01.script",
        "  set_standard_digital_out(1, True)\n",
        '  textmsg("done")\n',
        "unknown statement",
    ),
    ("urscript", "t_station_01.script", "v=0.4,", "v=0,4,", "not a number"),
    ("urscript", "t_station_01.script", "movel(pose_trans(part_frame, p[0.1", "movel((p[0.1", "unknown statement"),
    (
        "urscript",
        "t_station_01.script",
        "p[0.15, 0.2, 1.3, 3.14, 0.0, 0.0]",
        "p[0.15, 0.2, 1.3, 3.14, 0.0]",
        "6 numbers",
    ),
    (
        "urscript",
        "t_station_01.script",
        "  set_standard_digital_out(0, True)",
        "  set_standard_digital_out(5, True)",
        "not the gun's",
    ),
    ("urscript", "t_station_01.script", "  movej", "\tmovej", "tabs"),
    ("urscript", "t_stations.csv", "1,0,t_station_01", "2,0,t_station_01", "expected step 1"),
    (
        "rapid",
        "t_001.mod",
        "MODULE t_001",
        "%%%\nVERSION:1\n%%%\nMODULE t_001",
        "MODULE t_001",
    ),  # the header rapidchecker rejects too
    ("rapid", "t_001.mod", "  ENDPROC\n", "", "ENDPROC"),
    ("rapid", "t_001.mod", "    ! a hand-written module\n", "    WaitTime 1;\n", "unknown statement"),
    (
        "rapid",
        "t_001.mod",
        "[0,1,0,0],[0,0,0,0],[0,0,1800,9E+09,9E+09,9E+09]], [400",
        "[0,1,0],[0,0,0,0],[0,0,1800,9E+09,9E+09,9E+09]], [400",
        "quaternion",
    ),
    ("rapid", "t_001.mod", "    TriggIO trGun1, 12.5\\DOp:=doGun, 1;\n", "", "TriggIO"),
    ("rapid", "t_001.mod", "[FALSE,4,4,4,0.4,4,0.4]", "[FALSE,0,4,4,0.4,4,0.4]", "zonedata"),
    (
        "rapid",
        "t_001.mod",
        "[0,0,0,0],[0,0,1800,9E+09,9E+09,9E+09]], [400",
        "[0,0,0,9],[0,0,1800,9E+09,9E+09,9E+09]], [400",
        "robconf",
    ),
    (
        "rapid",
        "t_001.mod",
        "fine, tSprayGun\\WObj:=wPart;\n    MoveL",
        "fine, tSprayGun\\WObj:=wPart\n    MoveL",
        "end with ';'",
    ),
    ("rapid", "t_001.mod", "[400,500,5000,1000]", "[400,500,5000,1000", "unbalanced"),
    ("rapid", "t_main.mod", "    t_001;\n", "    t_001;\n    Stop;\n", "unknown statement"),
    ("krl", "t_001.src", "END\n", "", "END"),
    ("krl", "t_001.src", "  LIN XP3 C_DIS", "  LIN XP4 C_DIS", "not declared"),
    ("krl", "t_001.src", "$VEL.CP=0.4", "$VEL.CP=-0.4", "$VEL.CP"),
    ("krl", "t_001.src", "  ; a hand-written subprogram\n", "  HALT\n", "unknown statement"),
    (
        "krl",
        "t_001.dat",
        "C 180.0,S 2,T 10,E1 0.0,E2 0.0,E3 1800.0,E4 0.0,E5 0.0,E6 0.0}\n  DECL E6POS XP3",
        "C 180.0,T 10,E1 0.0,E2 0.0,E3 1800.0,E4 0.0,E5 0.0,E6 0.0}\n  DECL E6POS XP3",
        "fields",
    ),
    ("krl", "t_001.src", "C_DIS\nEND", "C_DIS\n  TRIGGER WHEN PATH=-1.0 DELAY=0 DO $OUT[1]=FALSE\nEND", "TRIGGER"),
    ("krl", "t.src", ";FOLD INI\n", "", "INI fold"),
    (
        "krl",
        "t_001.dat",
        "E3 1800.0,E4 0.0,E5 0.0,E6 0.0}\nENDDAT",
        "E3 1800.0,E4 0.0,E5 0.0,E6 0.0}\n  DECL E6POS XP9={X 1.0,Y 1.0,Z 1.0,A 0.0,B 0.0,C 0.0,S 2,T 10,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}\nENDDAT",
        "declared but not used",
    ),
]


def _write(folder: Path, files: dict) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (folder / name).write_text(text)
    return folder


@pytest.mark.parametrize("fmt", FORMATS)
def test_hand_written_programs_read(fmt, tmp_path):
    read = read_programs(_write(tmp_path, HAND[fmt]), T_JOB, fmt)
    assert [m.kind for m in read.moves] == ["joint", "linear", "linear"]
    assert read.moves[1].events and read.moves[1].events[0][1] is True
    np.testing.assert_allclose(read.tool2flange[:3, 3], [5.5, 94.5, 278.5])


@pytest.mark.parametrize("fmt, name, old, new, words", BROKEN)
def test_strict_readers_refuse_broken_programs(fmt, name, old, new, words, tmp_path):
    files = dict(HAND[fmt])
    assert old in files[name], old
    files[name] = files[name].replace(old, new, 1)
    with pytest.raises(ProgramError) as info:
        read_programs(_write(tmp_path, files), T_JOB, fmt)
    message = str(info.value)
    assert name in message and words in message, message
    assert len(message.splitlines()) == 1


# --- the command line ---------------------------------------------------------------------------------------


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def reach_folder(testdata, tmp_path_factory):
    """``sprayplan plan`` of the reach part (its unreachable spray waypoints: the gun on every normal) with every
    program format."""
    root = tmp_path_factory.mktemp("cli")
    out = root / "plan"
    part = testdata / "meshes" / "reach_curved_part.ply"
    (root / "bare.toml").write_text(BARE_NORMALS_TOML)
    argv = [
        "-q",
        "plan",
        str(part),
        "--units",
        "m",
        "--region",
        "x > -250",
        "-o",
        str(out),
        "-c",
        str(root / "bare.toml"),
    ]
    assert main([*argv, *(a for f in FORMATS for a in ("--program", f))]) == 0
    return out


def _left_out_count(folder) -> int:
    """How many unreachable spray waypoints the plan's programs left out (the same in every format)."""
    summary = json.loads((folder / "programs" / FORMATS[0] / "summary.json").read_text())
    return len(summary["left_out"]["unreachable_waypoints"])


def test_plan_with_programs_writes_them_as_its_last_stage(reach_folder, capsys):
    data = json.loads((reach_folder / "plan.json").read_text())
    assert data["settings"]["export"]["programs"] == list(FORMATS)
    counts = []
    for fmt in FORMATS:
        summary = json.loads((reach_folder / "programs" / fmt / "summary.json").read_text())
        assert summary["program_format"] == fmt and summary["moves"] > 0
        counts.append(len(summary["left_out"]["unreachable_waypoints"]))
        assert all(
            set(w) == {"station", "stroke", "waypoint", "tcp_mm"} for w in summary["left_out"]["unreachable_waypoints"]
        )
    # every format lists the same unreachable spray waypoints: some, and no more than the plan's unreachable ones
    assert len(set(counts)) == 1 and 0 < counts[0] <= data["totals"]["unreachable_waypoints"]


def test_export_reports_left_out_waypoints_on_stderr(reach_folder, tmp_path, capsys):
    out = tmp_path / "progs"
    code, stdout, err = run(capsys, "export", reach_folder, "--format", "rapid", "--format", "krl", "-o", out)
    assert code == 0
    lines = err.strip().splitlines()
    assert all(line.startswith("sprayplan: warning: ") and "all in summary.json" in line for line in lines)
    for fmt in ("rapid", "krl"):
        n = _left_out_count(reach_folder)
        assert (
            f"sprayplan: warning: {fmt}: {n} spray waypoints unreachable in the plan left out with the gun off" in err
        )
    assert stdout.count(" moves, ") == 2 and sorted(os.listdir(out)) == ["krl", "rapid"]
    # the same files as the plan's own export
    for name in os.listdir(out / "rapid"):
        if name != "summary.json":
            assert (out / "rapid" / name).read_bytes() == (reach_folder / "programs" / "rapid" / name).read_bytes()


def snapshot(folder) -> dict:
    found = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs:
            found[os.path.relpath(os.path.join(root, name), folder) + "/"] = None
        for name in files:
            path = os.path.join(root, name)
            found[os.path.relpath(path, folder)] = Path(path).read_bytes()
    return found


def test_strict_refuses_a_plan_with_unreachable_spray_waypoints(reach_folder, tmp_path, capsys):
    copy = tmp_path / "plan"
    shutil.copytree(reach_folder, copy)
    before = snapshot(tmp_path)
    code, stdout, err = run(capsys, "export", copy, "--format", "urscript", "--strict")
    assert code == 2 and stdout == ""
    line = err.strip()
    assert len(line.splitlines()) == 1 and line.startswith(
        f"sprayplan: error: --strict: {_left_out_count(reach_folder)} spray waypoints"
    )
    assert snapshot(tmp_path) == before


def test_a_plan_json_without_an_export_table_reads_with_the_defaults(reach_folder, tmp_path):
    from sprayplan.config import ExportConfig
    from sprayplan.export.plan_read import read_plan_file

    data = json.loads((reach_folder / "plan.json").read_text())
    del data["settings"]["export"]
    (tmp_path / "plan.json").write_text(json.dumps(data))
    assert read_plan_file(tmp_path / "plan.json").job.export == ExportConfig()


def test_an_unwritable_output_folder_is_one_line_and_nothing_written(reach_folder, tmp_path, capsys, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir()
    real = os.access
    monkeypatch.setattr(
        os,
        "access",
        lambda p, m, *a, **k: False if os.path.realpath(p) == str(locked) and m & os.W_OK else real(p, m, *a, **k),
    )
    code, _, err = run(capsys, "export", reach_folder, "--format", "krl", "-o", locked / "programs")
    assert code == 2 and len(err.strip().splitlines()) == 1 and str(locked / "programs") in err
    assert os.listdir(locked) == []


def test_a_program_that_reads_back_wrong_is_a_bug_and_writes_nothing(reach_folder, tmp_path, capsys, monkeypatch):
    import sprayplan.programs.rapid as rapid

    monkeypatch.setattr(rapid, "_zone", lambda blend_mm: "[FALSE,99,99,99,9.9,99,9.9]" if blend_mm > 0 else "fine")
    copy = tmp_path / "plan"
    shutil.copytree(reach_folder, copy)
    shutil.rmtree(copy / "programs")
    before = snapshot(tmp_path)
    code, _, err = run(capsys, "export", copy, "--format", "rapid")
    assert code == 1 and "internal error: ProgramCheckError" in err and "blend" in err
    assert str(copy / "programs" / "rapid") in err  # which program (with a cell: which robot's)
    assert snapshot(tmp_path) == before


def test_kuka_angles_at_gimbal_lock_read_back_as_the_same_rotation():
    from scipy.spatial.transform import Rotation

    from sprayplan.programs.model import angle_between_deg, kuka_abc, matrix_from_abc

    r = (Rotation.from_euler("z", 40, degrees=True) * Rotation.from_euler("y", 90, degrees=True)).as_matrix()
    abc = kuka_abc(r)
    assert abs(abc[1] - 90) < 1e-6 and abc[2] == 0
    assert angle_between_deg(matrix_from_abc(abc), r) < 1e-6
