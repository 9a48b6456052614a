"""The progress hook (sprayplan.progress) and the command line's display of it (cli.common.ProgressDisplay)."""

from __future__ import annotations

import io

from sprayplan.cli import main
from sprayplan.cli.common import ProgressDisplay
from sprayplan.job import STAGES
from sprayplan.progress import counted, per_stage


def test_counted_reports_each_unit_once():
    calls = []
    step = counted(lambda *a: calls.append(a), "kinematics", 3)
    for _ in range(3):
        step()
    assert calls == [("kinematics", 1, 3), ("kinematics", 2, 3), ("kinematics", 3, 3)]
    assert per_stage(None, "film") is None
    forward = []
    per_stage(lambda *a: forward.append(a), "film")(2, 5)
    assert forward == [("film", 2, 5)]


def test_plain_lines_say_when_each_stage_ends():
    out = io.StringIO()
    display = ProgressDisplay(stream=out, tty=False, every_s=0.0)
    display("paths", 0, 0)
    display("paths", 1, 2)
    display("paths", 2, 2)
    display("stations", 0, 0)
    display.close()
    lines = out.getvalue().splitlines()
    assert lines[0] == "sprayplan: paths 1/2" and lines[1] == "sprayplan: paths 2/2"
    assert lines[2].startswith("sprayplan: paths done in ") and lines[3].startswith("sprayplan: stations done in ")
    assert len(lines) == 4


def test_a_failed_job_does_not_report_its_last_stage_done():
    out = io.StringIO()
    display = ProgressDisplay(stream=out, tty=False)
    display("load", 0, 0)
    display("region", 0, 0)
    display.close(finished=False)
    lines = out.getvalue().splitlines()
    assert len(lines) == 1 and "load done" in lines[0] and "region" not in out.getvalue()


def test_quiet_shows_nothing_and_a_bar_writes_nothing_to_stdout(capsys):
    out = io.StringIO()
    quiet = ProgressDisplay(quiet=True, stream=out, tty=False)
    for stage in ("load", "paths"):
        quiet(stage, 0, 0)
    quiet.close()
    assert out.getvalue() == ""
    bar = ProgressDisplay(stream=out, tty=True)
    bar("kinematics", 0, 0)
    for done in range(1, 4):
        bar("kinematics", done, 3)
    bar.close()
    assert out.getvalue() == ""  # the bar is on stderr, and cleared at the end
    assert "kinematics" in capsys.readouterr().err


def test_the_plan_command_shows_every_stage_unless_quiet(testdata, tmp_path, capsys):
    part = str(testdata / "meshes" / "reach_curved_part.ply")
    args = ["plan", part, "--units", "m", "--region", "x > -200", "--spacing-mm", "80", "-o"]
    assert main([*args, str(tmp_path / "a")]) == 0
    captured = capsys.readouterr()
    done = [
        line.split(" done in ")[0].removeprefix("sprayplan: ")
        for line in captured.out.splitlines()
        if " done in " in line
    ]
    assert done == [s.name for s in STAGES] + ["outputs"]
    assert captured.err == ""
    assert main(["-q", *args, str(tmp_path / "b")]) == 0
    captured = capsys.readouterr()
    assert " done in " not in captured.out and captured.out.count("\n") == 1  # the summary line alone
