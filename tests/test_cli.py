"""The command line, run in-process: outputs, summaries, and one-line errors with exit code 2."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sprayplan import __version__
from sprayplan.cli import main
from sprayplan.export.stl import write_stl_binary


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_help_and_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    assert "targets" in capsys.readouterr().out
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert __version__ in capsys.readouterr().out


def test_targets_writes_the_csv(testdata, tmp_path, capsys):
    out = tmp_path / "deep" / "t.csv"
    code, stdout, _ = run(
        capsys,
        "targets",
        str(testdata / "meshes" / "tray_bottom_mm_ascii.stl"),
        "-o",
        str(out),
        "--up",
        "y",
        "--spacing-mm",
        "10",
    )
    assert code == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "x,y,z,nx,ny,nz"
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert f"{len(table)} targets" in stdout and str(out) in stdout
    np.testing.assert_allclose(np.linalg.norm(table[:, 3:], axis=1), 1.0, atol=1e-8)
    # the tray turned z-up is a 3.175 mm plate: every target is on its top, bottom or rim
    assert table[:, 2].min() >= -1e-6 and table[:, 2].max() <= 3.175 + 1e-6


def test_spray_radius_and_overlap_set_the_spacing(testdata, tmp_path, capsys):
    code, stdout, _ = run(
        capsys,
        "targets",
        str(testdata / "meshes" / "reach_curved_part.ply"),
        "--units",
        "m",
        "-o",
        str(tmp_path / "t.csv"),
        "--spray-radius-mm",
        "50",
        "--overlap",
        "0.4",
    )
    assert code == 0 and "spacing 49.19 mm" in stdout


def test_region_keeps_every_target_inside(testdata, tmp_path, capsys):
    out = tmp_path / "r.csv"
    code, _, _ = run(
        capsys,
        "targets",
        str(testdata / "meshes" / "reach_curved_part.ply"),
        "--units",
        "m",
        "-o",
        str(out),
        "--region",
        "z > 100 and x < -400",
        "--fill",
        "line",
        "--spacing-mm",
        "20",
    )
    assert code == 0
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert table[:, 2].min() >= 100 - 1e-9 and table[:, 0].max() <= -400 + 1e-9


def test_demo_runs_on_the_bundled_roof(tmp_path, capsys, monkeypatch):
    import sprayplan.demo

    # the whole demo (targets, plan for 50 um, speeds tuned to the film, touch-ups, simulated film) runs as
    # ``sprayplan demo`` does, on one corner quarter of the roof (4 stations, two of its edges and a corner, so
    # the tuning and touch-ups have work to do): the full roof took 89 s run alone (34 s for this) and 83 s in
    # the whole suite (10 s for this), and nothing checked here needs all of it
    full_region = sprayplan.demo.DEMO_REGION
    monkeypatch.setattr(sprayplan.demo, "DEMO_REGION", f"{full_region} and x > 0 and y > 0")
    code, stdout, _ = run(capsys, "demo", "-o", str(tmp_path))
    assert code == 0
    assert (tmp_path / "roof.stl").stat().st_size > 84
    table = np.loadtxt(tmp_path / "targets.csv", delimiter=",", skiprows=1)
    assert table[:, 2].min() >= 1000 - 1e-9  # seed 000's region z > 1000
    # the demo used the region it was given: targets on the x > 0, y > 0 quarter only, and all of it
    assert table[:, 0].min() >= -1e-9 and table[:, 1].min() >= -1e-9
    span = np.ptp(table[:, :2], axis=0)
    assert 1250 < span[0] <= 2635 / 2 and 900 < span[1] <= 1959 / 2
    assert "targets" in stdout and "stations" in stdout and "film: mean" in stdout
    for name in ("plan.json", "waypoints.csv", "coating.json", "thickness.ply", "thickness.csv", "plan.html"):
        assert (tmp_path / name).stat().st_size > 0
    assert (tmp_path / "report" / "report.md").exists()
    # the plan names the part where it is, not the staging folder it was planned in
    assert json.loads((tmp_path / "plan.json").read_text())["part"] == str(tmp_path / "roof.stl")
    # the roof the demo wrote, with the demo's own region, is the seed's whole 2635 x 1959 mm roof: its
    # targets (the demo's targets step, 1 s) cover all of it
    roof = str(tmp_path / "roof.stl")
    code, _, _ = run(capsys, "targets", roof, "--region", full_region, "-o", str(tmp_path / "t.csv"))
    assert code == 0
    table = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    assert table[:, 2].min() >= 1000 - 1e-9
    span = np.ptp(table[:, :2], axis=0)
    assert 2500 < span[0] <= 2635 and 1800 < span[1] <= 1959


def _bad_inputs(tmp_path, testdata):
    tray = (testdata / "meshes" / "tray_bottom_mm_ascii.stl").read_bytes()
    cases = {
        "missing.stl": None,
        "empty.stl": b"",
        "part.step": b"ISO-10303-21;",
        "truncated.stl": write_stl_binary(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]] * 3, float))[:-20],
        "words.xyz": b"1 2 3\n4 five 6\n",
        "nan.xyz": b"1 2 3\nnan 5 6\n",
        "inf.stl": write_stl_binary(np.array([[[0, 0, 0], [1, 0, 0], [np.inf, 1, 0]]], float)),
        "flat.stl": write_stl_binary(np.array([[[0, 0, 0], [1, 1, 1], [2, 2, 2]]], float)),
        "cut.stl": tray[: len(tray) // 2],
    }
    for name, data in cases.items():
        if data is not None:
            (tmp_path / name).write_bytes(data)
    return list(cases)


@pytest.mark.parametrize(
    "name, words",
    [
        ("missing.stl", "no such file"),
        ("empty.stl", "empty"),
        ("part.step", "unknown file type"),
        ("truncated.stl", "truncated"),
        ("words.xyz", "line 2"),
        ("nan.xyz", "NaN"),
        ("inf.stl", "infinite"),
        ("flat.stl", "positive area"),
        ("cut.stl", "truncated"),
    ],
)
def test_bad_files_give_one_line_and_exit_2(testdata, tmp_path, capsys, name, words):
    _bad_inputs(tmp_path, testdata)
    out = tmp_path / "out.csv"
    code, _stdout, err = run(capsys, "targets", str(tmp_path / name), "-o", str(out))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("sprayplan: error: ") and name in lines[0] and words in lines[0]
    assert "Traceback" not in err and not out.exists()
    assert not list(tmp_path.glob(".out.csv*"))


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--region", "z > 99999"], "contains no part"),
        (["--region", "q > 1"], "cannot read"),
        (["--spacing-mm", "10", "--overlap", "0.4"], "not both"),
        (["--overlap", "1.5"], "overlap"),
        (["--spacing-mm", "-3"], "spacing_mm"),
    ],
)
def test_bad_options_give_one_line_and_exit_2(testdata, tmp_path, capsys, extra, words):
    out = tmp_path / "out.csv"
    part = str(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    code, _, err = run(capsys, "targets", part, "-o", str(out), *extra)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and words in err and not out.exists()


@pytest.mark.parametrize(
    "command, extra, words",
    [
        ("paths", ["--edge-passes", "many"], "--edge-passes"),
        ("paths", ["--edge-passes", "-1"], "--edge-passes"),
        ("paths", ["--rim-mm", "-2"], "rim_mm"),
        ("plan", ["--edge-passes", "1.5"], "--edge-passes"),
    ],
)
def test_bad_edge_options_give_one_line_and_exit_2(testdata, tmp_path, capsys, command, extra, words):
    out = tmp_path / ("paths.json" if command == "paths" else "plan")
    part = str(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    code, _, err = run(capsys, command, part, "--up", "y", "-o", str(out), *extra)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and words in err and not out.exists()


def test_edge_and_speed_options_reach_the_plan(testdata, tmp_path, capsys):
    part = str(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    args = ["--up", "y", "--region", "z > 3.1", "--spacing-mm", "40", "--step-mm", "20"]
    code, _, _ = run(capsys, "paths", part, *args, "-o", str(tmp_path / "none.json"), "--edge-passes", "0")
    assert code == 0
    data = json.loads((tmp_path / "none.json").read_text())
    assert data["settings"]["edge_passes"] == 0
    assert all(any(s["on_part"]) for s in data["strokes"] if s["spray_on"])
    code, _, _ = run(capsys, "plan", part, *args, "-o", str(tmp_path / "plan"), "--speed-along", "tcp")
    assert code == 0
    plan = json.loads((tmp_path / "plan" / "plan.json").read_text())
    assert plan["settings"]["motion"]["speed_along"] == "tcp" and plan["settings"]["paths"]["edge_passes"] == "auto"
    for station in plan["stations"]:
        for stroke in station["strokes"]:
            assert set(stroke["tcp_speed_mm_s"]) == {stroke["speed_mm_s"]}  # one tip speed per stroke


def test_a_new_plan_takes_the_old_plans_programs_with_it(testdata, tmp_path, capsys):
    part = str(testdata / "meshes" / "reach_curved_part.ply")
    out = tmp_path / "out"
    base = ["-q", "plan", part, "--units", "m", "--no-viewer", "--no-report", "-o", str(out)]
    code, _, _ = run(capsys, *base[:-2], "--region", "x > -150", "--program", "rapid", *base[-2:])
    assert code == 0 and (out / "programs" / "rapid" / "summary.json").exists()
    (out / "notes.txt").write_text("the user's own file")  # so the folder is not replaced whole
    code, _, _ = run(capsys, *base[:-2], "--region", "x > -160", *base[-2:])
    assert code == 0
    # the programs were of the old plan: they are gone, the user's file is kept
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "plan.json", "waypoints.csv"]


def test_a_mask_leaves_its_surface_unpainted_and_a_bad_one_is_exit_2(testdata, tmp_path, capsys):
    from sprayplan.export.plan_read import read_plan_file

    part = str(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    out = tmp_path / "plan"
    code, stdout, _ = run(capsys, "plan", part, "--up", "y", "--mask", "x > 180", "--mask", "y < 60", "-o", str(out))
    assert code == 0 and "surface masked (--mask) left out" in stdout
    data = json.loads((out / "plan.json").read_text())
    assert data["totals"]["masked_left_out_mm2"] > 0.0
    read = read_plan_file(out / "plan.json")
    assert read.job.load.mask == ("x > 180", "y < 60")  # kept with the plan's settings, read back
    plan = read.plan
    spray = [s for s in plan.strokes if s.spray_on]
    on = np.concatenate([s.points[s.on_part] for s in spray])
    off = np.concatenate([s.points[~s.on_part] for s in spray])
    # the strokes paint the tray but the masked parts: on the part only outside the masks (the lead-ins and
    # -outs run on past the mask's edges as past any edge, over the masking)
    assert len(on) > 100 and on[:, 0].max() <= 180.0 + 1e-6 and on[:, 1].min() >= 60.0 - 1e-6
    assert len(off) and (off[:, 0].max() > 180.0 or off[:, 1].min() < 60.0)
    for extra, words in ((["--mask", "q > 3"], "--mask"), (["--mask", "x > -5"], "nothing left to paint")):
        bad = tmp_path / "bad"
        code, _, err = run(capsys, "plan", part, "--up", "y", *extra, "-o", str(bad))
        assert code == 2 and len(err.strip().splitlines()) == 1 and words in err and not bad.exists(), err
