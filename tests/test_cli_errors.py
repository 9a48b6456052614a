"""The command line's error contract: one line on stderr naming the file or option, exit code 2 (1 for a bug,
130 for Ctrl-C), no traceback, and no output created or changed; outputs go in all or nothing."""

from __future__ import annotations

import dataclasses
import errno
import os
import shutil
import warnings
from pathlib import Path

import pytest

import sprayplan.job
from sprayplan.cli import main
from sprayplan.errors import InputError, OutputError
from sprayplan.export.files import staged_files, staged_folder

RULED = Path(__file__).resolve().parents[1] / "examples" / "ruled" / "case1_table4.toml"
TRAY_PLAN = ["--up", "y", "--region", "z > 3.1", "--spacing-mm", "40", "--step-mm", "20"]


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def snapshot(folder) -> dict:
    """Every file and folder under ``folder`` (hidden ones too), with its bytes."""
    found = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs:
            found[os.path.relpath(os.path.join(root, name), folder) + "/"] = None
        for name in files:
            path = os.path.join(root, name)
            with open(path, "rb") as handle:
                found[os.path.relpath(path, folder)] = handle.read()
    return found


def one_error(err: str, *words: str) -> str:
    """The single error line (asserted so), which contains each of ``words``."""
    lines = err.strip("\n").splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("sprayplan: error: "), err
    assert "Traceback" not in err and "usage:" not in err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.fixture
def tray(testdata, tmp_path):
    """A copy of the tray part in an otherwise empty folder."""
    part = tmp_path / "tray.stl"
    shutil.copyfile(testdata / "meshes" / "tray_bottom_mm_ascii.stl", part)
    return part


@pytest.fixture(scope="module")
def planned(testdata, tmp_path_factory):
    """A plan folder of the tray with its film (plan.json, waypoints.csv, thickness.*, coating.json)."""
    out = tmp_path_factory.mktemp("planned") / "plan"
    part = testdata / "meshes" / "tray_bottom_mm_ascii.stl"
    assert main(["-q", "plan", str(part), *TRAY_PLAN, "--simulate", "-o", str(out)]) == 0
    return out


@pytest.fixture
def prev(planned, tmp_path):
    """A fresh copy of the planned folder, as an earlier run left it, in tmp_path/prev."""
    copy = tmp_path / "prev"
    shutil.copytree(planned, copy)
    return copy


# --- the command line itself -------------------------------------------------------------------------------


def test_bare_sprayplan_prints_its_usage_on_stderr(capsys):
    code, out, err = run(capsys)
    assert code == 2 and out == ""
    assert err.startswith("usage: sprayplan") and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "argv, words",
    [
        (["plan", "part.stl", "--units", "furlong", "-o", "x"], ["--units", "furlong"]),
        (["targets", "part.stl"], ["-o/--output", "required"]),
        (["targets", "part.stl", "-o", "x.csv", "--frobnicate"], ["--frobnicate"]),
        (["paths", "part.stl", "-o", "x.json", "--layers", "many"], ["--layers", "many"]),
        (["bogus"], ["COMMAND", "bogus"]),
    ],
)
def test_argparse_errors_are_one_line_without_the_usage(tmp_path, capsys, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    one_error(err, *words)
    assert snapshot(tmp_path) == {}


def test_help_still_shows_the_usage(capsys):
    with pytest.raises(SystemExit) as info:
        main(["plan", "--help"])
    assert info.value.code == 0 and capsys.readouterr().out.startswith("usage: sprayplan plan")


# --- output paths -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "command",
    [
        ["targets", "{part}"],
        ["paths", "{part}"],
        ["plan", "{part}"],
        ["fk", "{part}"],
        ["ik", "{part}"],
        ["demo"],
    ],
)
def test_an_empty_output_path_names_the_option(tray, tmp_path, capsys, command):
    before = snapshot(tmp_path)
    code, _, err = run(capsys, *[a.format(part=tray) for a in command], "-o", "")
    assert code == 2
    assert one_error(err, "empty").startswith("sprayplan: error: -o: ")
    assert snapshot(tmp_path) == before


def test_an_output_that_is_the_input_is_refused(tray, tmp_path, capsys, monkeypatch):
    (tmp_path / "sub").mkdir()
    os.symlink(tray, tmp_path / "link.stl")
    before = snapshot(tmp_path)
    for spelling in (tray, tmp_path / "sub" / ".." / "tray.stl", tmp_path / "link.stl"):
        code, out, err = run(capsys, "targets", tray, "-o", spelling)
        assert code == 2 and out == ""
        one_error(err, str(spelling), "-o", "input")
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "targets", "tray.stl", "-o", "./tray.stl")
    assert code == 2
    one_error(err, "./tray.stl", "input")
    assert snapshot(tmp_path) == before  # the part byte for byte, nothing beside it


def test_outputs_that_are_inputs_of_the_other_commands_are_refused(tray, tmp_path, capsys, prev):
    table = tmp_path / "t.csv"
    table.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n")
    before = snapshot(tmp_path)
    cases = [
        (["fk", table, "-o", table], [str(table), "joints"]),
        (["ik", table, "-o", table], [str(table), "poses"]),
        (["paths", "--ruled", RULED, "-o", tmp_path / "p.json", "--table", tmp_path / "p.json"], ["given twice"]),
        (["paths", "--ruled", RULED, "-o", RULED], [str(RULED), "--ruled"]),
        (["plan", prev / "thickness.ply", "-o", prev], [str(prev / "thickness.ply"), "input part"]),
        (["simulate", prev, "--part", prev / "thickness.ply"], [str(prev / "thickness.ply"), "--part"]),
    ]
    for argv, words in cases:
        code, _, err = run(capsys, *argv)
        assert code == 2, argv
        one_error(err, *words)
    assert snapshot(tmp_path) == before


def test_a_folder_where_a_file_goes_and_a_file_where_a_folder_goes(tray, tmp_path, capsys):
    (tmp_path / "folder").mkdir()
    (tmp_path / "folder" / "inside.txt").write_text("keep")
    before = snapshot(tmp_path)
    code, _, err = run(capsys, "targets", tray, "-o", tmp_path / "folder")
    assert code == 2
    one_error(err, str(tmp_path / "folder"), "is a folder")
    code, _, err = run(capsys, "plan", tray, "-o", tray)
    assert code == 2
    one_error(err, str(tray), "not a folder")
    assert snapshot(tmp_path) == before


def test_an_output_under_a_regular_file(tray, tmp_path, capsys):
    (tmp_path / "file.txt").write_text("a file, not a folder")
    before = snapshot(tmp_path)
    for argv in (
        ["targets", tray, "-o", tmp_path / "file.txt" / "x.csv"],
        ["plan", tray, "-o", tmp_path / "file.txt" / "out"],
        ["paths", "--ruled", RULED, "-o", tmp_path / "p.json"] + ["--table", tmp_path / "file.txt" / "t.csv"],
    ):
        code, _, err = run(capsys, *argv)
        assert code == 2
        one_error(err, str(tmp_path / "file.txt"), "not a folder")
    assert snapshot(tmp_path) == before


def test_a_read_only_folder(tray, tmp_path, capsys, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    if os.geteuid() == 0:  # root may write anyway: the folder answers root as it answers any other user
        real = os.access

        def access(path, mode, *args, **kwargs):
            if os.path.realpath(path) == os.path.realpath(locked) and mode & os.W_OK:
                return False
            return real(path, mode, *args, **kwargs)

        monkeypatch.setattr(os, "access", access)
    try:
        code, _, err = run(capsys, "targets", tray, "-o", locked / "x.csv")
        assert code == 2
        one_error(err, str(locked / "x.csv"))
        assert os.listdir(locked) == []
    finally:
        locked.chmod(0o755)


def _disk_full(writer):
    """``writer`` that writes a little of its file, then fails as a full disk does."""

    def full(path, *args, **kwargs):
        with open(path, "w") as handle:
            handle.write("half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.fspath(path))

    return full


def test_a_full_disk_names_the_output_and_keeps_the_old_file(tray, tmp_path, capsys, monkeypatch):
    import sprayplan.export.files

    out = tmp_path / "x.csv"
    out.write_text("the previous targets\n")
    before = snapshot(tmp_path)
    monkeypatch.setattr(sprayplan.export.files, "write_targets_csv", _disk_full(None))
    code, _, err = run(capsys, "targets", tray, "--up", "y", "--spacing-mm", "20", "-o", out)
    assert code == 2
    assert one_error(err, "No space left on device").startswith(f"sprayplan: error: {out}: ")
    assert snapshot(tmp_path) == before


def test_paths_and_table_are_written_both_or_neither(tmp_path, capsys, monkeypatch):
    import sprayplan.export.tables

    ruled = RULED
    (tmp_path / "p.json").write_text("old paths")
    before = snapshot(tmp_path)
    monkeypatch.setattr(sprayplan.export.tables, "write_table_csv", _disk_full(None))
    code, _, err = run(capsys, "paths", "--ruled", ruled, "-o", tmp_path / "p.json", "--table", tmp_path / "t.csv")
    assert code == 2
    one_error(err, str(tmp_path / "t.csv"), "No space left on device")
    assert snapshot(tmp_path) == before  # the json not replaced, no table, no temporary file
    monkeypatch.undo()
    code, _, _ = run(capsys, "paths", "--ruled", ruled, "-o", tmp_path / "p.json", "--table", tmp_path / "t.csv")
    assert code == 0
    assert (tmp_path / "p.json").read_text() != "old paths" and (tmp_path / "t.csv").stat().st_size > 0
    assert sorted(os.listdir(tmp_path)) == ["p.json", "t.csv"]


def test_table_only_with_ruled(tray, tmp_path, capsys):
    code, _, err = run(capsys, "paths", tray, "-o", tmp_path / "p.json", "--table", tmp_path / "t.csv")
    assert code == 2
    one_error(err, "--table", "--ruled")
    assert sorted(os.listdir(tmp_path)) == ["tray.stl"]


# --- options the command line checks itself ---------------------------------------------------------------


@pytest.mark.parametrize(
    "argv, option",
    [
        (["ik", "{poses}", "-o", "{out}", "--seed-joints", "a,b"], "--seed-joints"),
        (["ik", "{poses}", "-o", "{out}", "--seed-joints", "0,0,0,0,0"], "--seed-joints"),
        (["ik", "{poses}", "-o", "{out}", "--seed-joints", "0,0,0,0,0,nan"], "--seed-joints"),
        (["ik", "{poses}", "-o", "{out}", "--platform", "a,b,c"], "--platform"),
        (["ik", "--robot", "gantry-ur5", "{poses}", "-o", "{out}", "--platform", "1,2"], "--platform"),
        (["plan", "{part}", "-o", "{out}", "--samples", "0"], "--samples"),
        (["simulate", "{prev}", "--samples", "0"], "--samples"),
    ],
)
def test_the_cli_own_values_are_checked_first(tray, tmp_path, capsys, prev, argv, option):
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,z,rx,ry,rz\n400,100,300,3.14159,0,0\n")
    before = snapshot(tmp_path)
    values = {"poses": poses, "out": tmp_path / "out.csv", "part": tray, "prev": prev}
    code, out, err = run(capsys, *[a.format(**values) for a in argv])
    assert code == 2 and out == ""
    assert one_error(err).startswith(f"sprayplan: error: {option}: ")
    assert snapshot(tmp_path) == before


# --- the main job: nothing lost -----------------------------------------------------------------------------


def _failing_stage(name: str, exc: BaseException):
    """job.STAGES with the stage ``name`` raising ``exc``."""

    def fail(state, progress):
        raise exc

    return tuple(dataclasses.replace(s, run=fail) if s.name == name else s for s in sprayplan.job.STAGES)


def test_an_existing_plan_folder_survives_a_failing_rerun(tray, tmp_path, capsys, prev, monkeypatch):
    before = snapshot(tmp_path)
    # refused before running: the samples, and a bad process found late, in the film stage
    for extra in (["--simulate", "--samples", "0"], ["--simulate", "--process", "bogus"]):
        code, _, err = run(capsys, "-q", "plan", tray, *TRAY_PLAN, *extra, "-o", prev)
        assert code == 2
        one_error(err)
        assert snapshot(tmp_path) == before
    # bad input found in the last stage, after the plan is made
    monkeypatch.setattr(sprayplan.job, "STAGES", _failing_stage("totals", InputError("something is wrong")))
    code, _, err = run(capsys, "-q", "plan", tray, *TRAY_PLAN, "-o", prev)
    assert code == 2
    one_error(err, "totals", "something is wrong")
    assert snapshot(tmp_path) == before


def test_a_full_disk_while_writing_the_plan_keeps_the_old_folder(tray, tmp_path, capsys, prev, monkeypatch):
    import sprayplan.export.plan_json

    before = snapshot(tmp_path)
    monkeypatch.setattr(sprayplan.export.plan_json, "write_waypoints_csv", _disk_full(None))  # after plan.json
    code, _, err = run(capsys, "-q", "plan", tray, *TRAY_PLAN, "-o", prev)
    assert code == 2
    assert one_error(err, "No space left on device").startswith(f"sprayplan: error: {prev}: ")
    assert snapshot(tmp_path) == before
    # and into a new folder: nothing is created, not even its parents
    code, _, err = run(capsys, "-q", "plan", tray, *TRAY_PLAN, "-o", tmp_path / "new" / "deeper")
    assert code == 2
    one_error(err, str(tmp_path / "new" / "deeper"), "No space left on device")
    assert snapshot(tmp_path) == before


def test_a_good_rerun_replaces_the_whole_folder(tray, tmp_path, capsys, prev):
    old = snapshot(prev)
    code, _, _ = run(capsys, "-q", "plan", tray, *TRAY_PLAN, "--step-mm", "25", "-o", prev)
    assert code == 0
    new = snapshot(prev)
    # the old film files went with the old folder; the pictures are of the new plan
    assert "report/" in new
    assert sorted(n for n in new if not n.startswith("report/")) == [
        "plan.html",
        "plan.json",
        "waypoints.csv",
    ]
    assert "report/film_histogram.png" in old and "report/film_histogram.png" not in new  # no film, no histogram
    assert new["plan.json"] != old["plan.json"]
    assert sorted(os.listdir(tmp_path)) == ["prev", "tray.stl"]  # nothing left beside it


def test_an_internal_error_is_one_line_and_exit_1(tray, tmp_path, capsys, prev, monkeypatch):
    monkeypatch.setattr(sprayplan.job, "STAGES", _failing_stage("region", ZeroDivisionError("division by zero")))
    before = snapshot(tmp_path)
    code, _, err = run(capsys, "-q", "plan", tray, "-o", prev)
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("sprayplan: internal error: ZeroDivisionError: division by zero")
    assert "region stage" in lines[0] and "run with -v for the traceback" in lines[0]
    code, _, err = run(capsys, "-q", "-v", "plan", tray, "-o", prev)
    assert code == 1
    assert err.startswith("Traceback (most recent call last)") and "ZeroDivisionError" in err
    assert err.strip().splitlines()[-1].startswith("sprayplan: internal error: ZeroDivisionError")
    assert snapshot(tmp_path) == before


def test_ctrl_c_is_130_and_leaves_nothing(tray, tmp_path, capsys, prev, monkeypatch):
    monkeypatch.setattr(sprayplan.job, "STAGES", _failing_stage("region", KeyboardInterrupt()))
    before = snapshot(tmp_path)
    code, _, err = run(capsys, "-q", "plan", tray, "-o", prev)
    assert code == 130 and err.strip() == "sprayplan: interrupted"
    assert snapshot(tmp_path) == before


def test_simulate_writes_its_film_files_all_or_none(tmp_path, capsys, prev, monkeypatch):
    import sprayplan.export.film

    (prev / "notes.txt").write_text("the user's own file")
    before = snapshot(tmp_path)
    monkeypatch.setattr(sprayplan.export.film, "write_thickness_csv", _disk_full(None))  # after thickness.ply
    code, _, err = run(capsys, "simulate", prev, "--thickness-um", "40")
    assert code == 2
    one_error(err, str(prev), "No space left on device")
    assert snapshot(tmp_path) == before
    monkeypatch.undo()
    code, _, _ = run(capsys, "simulate", prev, "--thickness-um", "40")
    assert code == 0
    after = snapshot(tmp_path)
    outside = lambda files: sorted(n for n in files if not n.startswith("prev/report/"))
    assert outside(after) == outside(before)  # the same files, nothing left beside them
    # the film views show the sides that face the most painted area, which a new spec may change
    report = lambda files: sorted(n for n in files if n.startswith("prev/report/"))
    assert len(report(after)) == len(report(before))
    assert after["prev/plan.html"] != before["prev/plan.html"]  # drawn again with the new film
    for name in ("plan.json", "waypoints.csv", "notes.txt"):
        assert after[f"prev/{name}"] == before[f"prev/{name}"]
    assert after["prev/coating.json"] != before["prev/coating.json"]  # the 40 um spec


def test_demo_leaves_an_existing_folder_when_it_fails(tmp_path, capsys, monkeypatch):
    out = tmp_path / "demo"
    out.mkdir()
    (out / "roof.stl").write_text("an earlier demo's roof")
    before = snapshot(tmp_path)
    monkeypatch.setattr(sprayplan.job, "STAGES", _failing_stage("paths", InputError("no strokes")))
    code, out_text, err = run(capsys, "-q", "demo", "-o", out)
    assert code == 2 and "demo part" not in out_text
    one_error(err, "no strokes")
    assert snapshot(tmp_path) == before


# --- warnings -----------------------------------------------------------------------------------------------


def test_library_warnings_are_logged_not_printed(tray, tmp_path, capsys, monkeypatch):
    import numpy as np

    import sprayplan.surface.targets

    make = sprayplan.surface.targets.make_targets
    calls = []

    def noisy(*args, **kwargs):
        calls.append(1)
        warnings.warn(f"a library complains ({len(calls)})", RuntimeWarning, stacklevel=1)
        np.log(np.zeros(1))  # numpy's own RuntimeWarning: divide by zero
        return make(*args, **kwargs)

    monkeypatch.setattr(sprayplan.surface.targets, "make_targets", noisy)
    argv = ["targets", tray, "--up", "y", "--spacing-mm", "20", "-o", tmp_path / "t.csv"]
    code, out, err = run(capsys, *argv)
    assert code == 0 and err == "" and "targets" in out
    code, _, err = run(capsys, "-v", *argv)
    assert code == 0 and "a library complains (2)" in err and "Traceback" not in err


# --- the staging itself -------------------------------------------------------------------------------------


def test_staged_folder_keeps_files_it_does_not_own(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "plan.json").write_text("old plan")
    (out / "coating.json").write_text("old film")
    (out / "notes.txt").write_text("mine")
    with staged_folder(out, ("plan.json", "coating.json")) as stage:
        (stage / "plan.json").write_text("new plan")
    assert snapshot(out) == {"plan.json": b"new plan", "notes.txt": b"mine"}  # the stale film removed
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_staged_folder_restores_the_old_folder_when_the_move_fails(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "plan.json").write_text("old plan")
    real = os.rename
    moves = []

    def rename(a, b):
        moves.append((a, b))
        if len(moves) == 2:  # the old folder moved aside; moving the new one in fails
            raise OSError(errno.EIO, os.strerror(errno.EIO), os.fspath(a))
        return real(a, b)

    monkeypatch.setattr(os, "rename", rename)
    with pytest.raises(OutputError, match=f"{out}: cannot write"):
        with staged_folder(out, ("plan.json",)) as stage:
            (stage / "plan.json").write_text("new plan")
    monkeypatch.undo()
    assert snapshot(tmp_path) == {"out/": None, "out/plan.json": b"old plan"}


def test_staged_files_put_back_the_first_when_the_second_fails(tmp_path, monkeypatch):
    first, second = tmp_path / "a.json", tmp_path / "b.csv"
    first.write_text("old a")
    second.write_text("old b")
    real = os.rename
    failed = []

    def rename(a, b):
        if os.fspath(b) == os.fspath(second) and not failed:  # moving the new second file in fails, once
            failed.append(a)
            raise OSError(errno.EIO, os.strerror(errno.EIO), os.fspath(a))
        return real(a, b)

    monkeypatch.setattr(os, "rename", rename)
    with pytest.raises(OutputError):
        with staged_files([first, second]) as (a, b):
            a.write_text("new a")
            b.write_text("new b")
    monkeypatch.undo()
    assert failed and snapshot(tmp_path) == {"a.json": b"old a", "b.csv": b"old b"}
