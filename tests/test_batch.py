"""Batches (sprayplan.batch, ``sprayplan batch``): a small batch of the tray plate (a sweep of two spacings,
one job with a film) plus a broken file, run on the local engine, on a Dask LocalCluster and on a scheduler
and workers started as separate processes; each gives the files and figures of running the job alone with
``sprayplan plan``. Resume, --force, a killed job, a timeout, and bad batch files."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from sprayplan.batch import read_batch, run_batch
from sprayplan.batch.summary import FIGURES, read_summary_csv
from sprayplan.cli import main

SRC = Path(__file__).resolve().parents[1] / "src"
TRAY = "tray_bottom_mm_ascii.stl"
BATCH = """
[defaults.output]
viewer = false
report = false

[[job]]
parts = ["tray*.stl"]
[job.sweep]
paths.spacing_mm = [60, 100]

[[job]]
parts = "broken.stl"

[[job]]
parts = "tray_bottom_mm_ascii.stl"
name = "tray-film"
paths.spacing_mm = 100
output.simulate = true
coating.sample_edge_mm = 25
"""
#: Row entries that differ from run to run (times, memory) or by how the row came about.
VARYING = ("planning_time_s", "job_time_s", "peak_memory_mb", "reused")


def _folder(testdata, tmp: Path, text: str = BATCH) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    shutil.copy(testdata / "meshes" / TRAY, tmp / TRAY)
    (tmp / "broken.stl").write_text("solid x\nfacet normal 0 0 1\nendsolid\n")
    (tmp / "batch.toml").write_text(text)
    return tmp / "batch.toml"


@pytest.fixture(scope="module")
def batch_file(testdata, tmp_path_factory) -> Path:
    return _folder(testdata, tmp_path_factory.mktemp("batch"))


@pytest.fixture(scope="module")
def local_run(batch_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "out"
    code = main(["-q", "batch", str(batch_file), "-o", str(out), "--workers", "2"])
    return code, out


def _rows(out: Path) -> dict:
    data = json.loads((out / "summary.json").read_text())
    return {row["job_id"]: row for row in data["rows"]}


def _stable(row: dict) -> dict:
    return {k: v for k, v in row.items() if k not in VARYING}


def _plan(folder: Path) -> dict:
    data = json.loads((folder / "plan.json").read_text())
    data["totals"].pop("planning_time_s")
    return data


def _toml_value(value) -> str:
    return json.dumps(value) if not isinstance(value, bool) else ("true" if value else "false")


def _process_toml(settings: dict) -> str:
    """A process TOML of a job's batch settings (``section.key`` -> value), for ``sprayplan plan -c``."""
    tables: dict = {}
    for name, value in settings.items():
        section, key = name.split(".")
        tables.setdefault(section, {})[key] = value
    return "".join(
        f"[{section}]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in keys.items())
        for section, keys in tables.items()
    )


@pytest.fixture(scope="module")
def alone(local_run, tmp_path_factory) -> dict:
    """Each job of the batch run alone with ``sprayplan plan -c`` (its settings as a process TOML)."""
    _, out = local_run
    folders = {}
    for job_id, row in _rows(out).items():
        work = tmp_path_factory.mktemp("alone")
        (work / "process.toml").write_text(_process_toml(row["settings"]))
        code = main(["-q", "plan", row["part"], "-c", str(work / "process.toml"), "-o", str(work / "out")])
        folders[job_id] = (code, work / "out")
    return folders


def test_the_local_engine_runs_every_job_and_isolates_the_broken_one(local_run, batch_file):
    code, out = local_run
    assert code == 1  # some failed
    rows = _rows(out)
    jobs = read_batch(batch_file).jobs
    assert list(rows) == [job.job_id for job in jobs] and len(rows) == 4
    failed = [row for row in rows.values() if row["status"] == "failed"]
    assert [row["name"] for row in failed] == ["broken"]
    assert "broken.stl" in failed[0]["error"] and "\n" not in failed[0]["error"]
    assert not (out / failed[0]["job_id"]).exists()
    for row in rows.values():
        if row["status"] == "ok":
            assert json.loads((out / row["job_id"] / "job.json").read_text())["job_id"] == row["job_id"]
    # the sweep: one job per value, named by it; the hash differs with the settings
    swept = sorted(row["settings"]["paths.spacing_mm"] for row in rows.values() if "spacing_mm=" in row["name"])
    assert swept == [60, 100]
    # summary.csv holds the same rows as summary.json
    table = read_summary_csv(out / "summary.csv")
    assert [r["job_id"] for r in table] == list(rows)
    for r in table:
        for key in FIGURES:
            value = rows[r["job_id"]].get(key)
            assert r[key] == ("" if value is None else repr(value) if isinstance(value, float) else str(value))
    # no temporary folders are left
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []


def test_each_job_equals_the_same_job_run_alone_with_sprayplan_plan(local_run, alone):
    _, out = local_run
    rows = _rows(out)
    for job_id, (code, folder) in alone.items():
        row = rows[job_id]
        if row["status"] == "failed":
            assert code == 2
            continue
        assert code == 0
        assert _plan(out / job_id) == _plan(folder)
        assert (out / job_id / "waypoints.csv").read_bytes() == (folder / "waypoints.csv").read_bytes()
        totals = _plan(folder)["totals"]
        for key in ("stations", "strokes", "waypoints", "unreachable_waypoints", "cycle_time_s"):
            assert row[key] == totals[key]
        if (folder / "coating.json").exists():
            coating = json.loads((folder / "coating.json").read_text())
            assert json.loads((out / job_id / "coating.json").read_text()) == coating
            assert row["film_mean_um"] == coating["painted"]["mean_um"]
            assert row["film_std_over_mean"] == coating["painted"]["cv"]
            assert row["film_share_in_spec"] == coating["painted"]["share_in_spec"]
            assert row["paint_used_ml"] == coating["paint"]["wet_paint_ml"]
        else:
            assert "film_mean_um" not in row
    assert any((folder / "coating.json").exists() for _, folder in alone.values())


def test_a_rerun_skips_complete_jobs_and_force_runs_them_again(local_run, batch_file, tmp_path):
    _, first = local_run
    out = tmp_path / "out"
    shutil.copytree(first, out)
    before = {p.name: (p / "plan.json").stat().st_mtime_ns for p in out.iterdir() if (p / "plan.json").exists()}
    assert main(["-q", "batch", str(batch_file), "-o", str(out)]) == 1
    rows = _rows(out)
    assert [r["reused"] for r in rows.values() if r["status"] == "ok"] == [True, True, True]
    assert {k: _stable(v) for k, v in rows.items()} == {k: _stable(v) for k, v in _rows(first).items()}
    assert {name: (out / name / "plan.json").stat().st_mtime_ns for name in before} == before
    # a folder of the job's id that is not complete (no job.json) is not skipped
    incomplete = next(iter(before))
    (out / incomplete / "job.json").unlink()
    # --force runs every job again and replaces the folders once complete
    assert main(["-q", "batch", str(batch_file), "-o", str(out), "--force", "--workers", "2"]) == 1
    rows = _rows(out)
    assert not any(r["reused"] for r in rows.values())
    assert {k: _stable(v) for k, v in rows.items()} == {k: _stable(v) for k, v in _rows(first).items()}
    assert all((out / name / "plan.json").stat().st_mtime_ns != t for name, t in before.items())
    assert (out / incomplete / "job.json").exists()


def _same_as_local(local_run, out: Path) -> None:
    expected = {k: _stable(v) for k, v in _rows(local_run[1]).items()}
    assert {k: _stable(v) for k, v in _rows(out).items()} == expected
    for job_id, row in expected.items():
        if row["status"] == "ok":
            assert _plan(out / job_id) == _plan(local_run[1] / job_id)


def test_a_dask_local_cluster_gives_the_same_summary(local_run, batch_file, tmp_path):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, Client(cluster) as client:
        result = run_batch(read_batch(batch_file), tmp_path / "out", client)
    assert result.exit_code == 1
    _same_as_local(local_run, tmp_path / "out")
    # the broken part's bytes travelled with the task: its error names the batch's file, not a worker's copy
    failed = next(r for r in result.rows if r["status"] == "failed")
    assert str(batch_file.parent / "broken.stl") in failed["error"]


def _env() -> dict:
    path = os.environ.get("PYTHONPATH", "")
    return {**os.environ, "PYTHONPATH": str(SRC) + (os.pathsep + path if path else "")}


@pytest.fixture
def dask_processes(tmp_path):
    """A ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1 (no nanny: killing one kills the
    worker), stopped at the end; yields the scheduler's address."""
    info = tmp_path / "scheduler.json"
    started = []

    def start(*args):
        process = subprocess.Popen(
            [sys.executable, "-m", "dask", *args],
            env=_env(),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        started.append(process)
        return process

    try:
        start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(info))
        for _ in range(600):
            if info.exists() and info.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        common = ["--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"]
        for _ in range(2):
            start("worker", address, *common)
        yield address
    finally:
        for process in started[::-1]:
            if process.poll() is None:
                process.terminate()
        for process in started:
            try:
                process.wait(20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def test_a_scheduler_and_workers_as_separate_processes_give_the_same_summary(
    local_run, batch_file, tmp_path, dask_processes
):
    address = dask_processes
    out = tmp_path / "out"
    code = main(["-q", "batch", str(batch_file), "-o", str(out), "--scheduler", address])
    assert code == 1
    _same_as_local(local_run, out)


def test_a_dask_worker_killed_mid_batch_loses_no_job(batch_file, tmp_path, dask_processes):
    from distributed import Client

    address = dask_processes
    out = tmp_path / "out"
    with Client(address, timeout="30s") as client:
        client.wait_for_workers(2, timeout=60)
        pids = client.run(os.getpid)
        outcome = {}
        runner = threading.Thread(
            target=lambda: outcome.setdefault("result", run_batch(read_batch(batch_file), out, client))
        )
        runner.start()
        victim = None
        for _ in range(600):
            busy = [addr for addr, keys in client.processing().items() if keys]
            if busy:
                victim = busy[0]
                break
            time.sleep(0.1)
        assert victim is not None
        os.kill(pids[victim], signal.SIGKILL)
        runner.join(300)
    result = outcome["result"]
    assert [r["job_id"] for r in result.rows] == [j.job_id for j in read_batch(batch_file).jobs]
    for row in result.rows:
        assert row["status"] in ("ok", "failed") and (row["status"] == "ok" or row["error"])
        assert (out / row["job_id"] / "job.json").exists() == (row["status"] == "ok")
    # the job on the dead worker ran again on the other one
    assert [r["name"] for r in result.rows if r["status"] == "failed"] == ["broken"]


ONE = """
[[job]]
parts = "tray_bottom_mm_ascii.stl"
paths.spacing_mm = 100
output.viewer = false
output.report = false
"""


def test_a_killed_local_job_is_failed_and_leaves_no_folder_a_rerun_would_skip(testdata, tmp_path):
    import multiprocessing

    batch = read_batch(_folder(testdata, tmp_path / "in", ONE + "output.simulate = true\n"))
    out = tmp_path / "out"
    outcome = {}
    runner = threading.Thread(target=lambda: outcome.setdefault("result", run_batch(batch, out)))
    runner.start()
    child = None
    for _ in range(600):
        child = next((p for p in multiprocessing.active_children() if p.name.startswith("sprayplan-")), None)
        if child is not None:
            break
        time.sleep(0.05)
    assert child is not None
    # killed as soon as the job starts writing its folder (in the middle of its work; a fixed delay let a job on a
    # quiet machine finish first, or killed it before it wrote anything)
    for _ in range(60000):
        if not child.is_alive() or any(out.glob(".*.tmp")):
            break
        time.sleep(0.001)
    os.kill(child.pid, signal.SIGKILL)
    runner.join(120)
    (row,) = outcome["result"].rows
    assert row["status"] == "failed" and "SIGKILL" in row["error"]
    assert sorted(p.name for p in out.iterdir()) == ["summary.csv", "summary.json"]
    # the re-run runs it (nothing complete to skip)
    (row,) = run_batch(batch, out).rows
    assert row["status"] == "ok" and not row["reused"]


def test_a_stale_temporary_folder_is_not_a_complete_job_and_is_removed(testdata, tmp_path):
    batch = read_batch(_folder(testdata, tmp_path / "in", ONE))
    job_id = batch.jobs[0].job_id
    out = tmp_path / "out"
    stale = out / f".{job_id}.99999.tmp"
    stale.mkdir(parents=True)
    (stale / "plan.json").write_text("{")
    assert main(["-q", "batch", str(batch.path), "-o", str(out)]) == 0  # every job succeeded
    (row,) = json.loads((out / "summary.json").read_text())["rows"]
    assert row["status"] == "ok" and not row["reused"]
    assert not stale.exists() and json.loads((out / job_id / "plan.json").read_text())["format"] == "sprayplan.plan"


def test_a_job_past_its_timeout_is_reported(testdata, tmp_path):
    batch = read_batch(_folder(testdata, tmp_path / "in", ONE))
    (row,) = run_batch(batch, tmp_path / "out", timeout_s=0.01).rows
    assert row["status"] == "failed" and row["error"].startswith("timed out after 0.01 s")
    assert not (tmp_path / "out" / row["job_id"]).exists()


def test_a_local_job_past_its_memory_cap_is_killed_and_reported(testdata, tmp_path):
    batch = read_batch(_folder(testdata, tmp_path / "in", ONE))
    (row,) = run_batch(batch, tmp_path / "out", job_memory_mb=1).rows  # a Python process alone is more
    assert row["status"] == "failed" and row["error"].startswith("out of memory: over job_memory_mb = 1 MB")
    assert not (tmp_path / "out" / row["job_id"]).exists()


def test_progress_off_a_terminal_is_one_line_per_job_with_the_count_and_time():
    import io

    from sprayplan.cli.batch import BatchProgress

    stream = io.StringIO()
    show = BatchProgress(tty=False, stream=stream)
    show(1, 2, {"job_id": "a-1", "status": "ok", "reused": True})
    show(2, 2, {"job_id": "b-2", "status": "failed"})
    lines = stream.getvalue().splitlines()
    assert [line.split(": ", 2)[2] for line in lines] == ["a-1 reused", "b-2 failed"]
    assert [line.split(" in ")[0] for line in lines] == ["sprayplan: batch 1/2", "sprayplan: batch 2/2"]
    assert show.failed == 1


def test_a_part_deleted_after_the_batch_was_read_is_a_failed_job(testdata, tmp_path):
    batch = read_batch(_folder(testdata, tmp_path / "in", ONE))
    (tmp_path / "in" / TRAY).unlink()
    (row,) = run_batch(batch, tmp_path / "out").rows
    assert row["status"] == "failed" and "no such file" in row["error"]


def test_the_job_id_is_stable_and_follows_the_part_bytes_and_settings(testdata, tmp_path):
    first = read_batch(_folder(testdata, tmp_path / "a", ONE)).jobs[0]
    again = read_batch(_folder(testdata, tmp_path / "b", ONE)).jobs[0]
    assert first.job_id == again.job_id and first.job_id.startswith("tray_bottom_mm_ascii-")
    other = read_batch(_folder(testdata, tmp_path / "c", ONE.replace("= 100", "= 90"))).jobs[0]
    assert other.job_id != first.job_id
    with open(tmp_path / "a" / TRAY, "ab") as handle:
        handle.write(b"\n")
    assert read_batch(tmp_path / "a" / "batch.toml").jobs[0].job_id != first.job_id


BAD = {
    "unknown setting": ("paths.spacing = 3", "spacing"),
    "bad value": ("paths.step_mm = -1", "step_mm"),
    "sweep of no setting": ("[job.sweep]\npaths.nothing_mm = [1, 2]", "nothing_mm"),
    "sweep of no section": ("[job.sweep]\nnowhere.x = [1, 2]", "nowhere.x"),
    "empty sweep": ("[job.sweep]\npaths.spacing_mm = []", "empty sweep"),
    "bad sweep value": ("[job.sweep]\npaths.spacing_mm = [60, -5]", "spacing_mm"),
    "missing part": ('[[job]]\nparts = "missing.stl"', "missing.stl"),
    "glob matching nothing": ('[[job]]\nparts = "*.obj"', "*.obj"),
    "duplicate job ids": (ONE, "duplicate job id"),
    "unknown table": ("[nonsense]\nx = 1", "nonsense"),
    "bad engine setting": ("[batch]\nworkers = 1.5", "[batch].workers"),
    "parts in the defaults": ('[defaults]\nparts = "x.stl"', "defaults.parts"),
    "unknown cell": ('cell = "no-such-cell"', "no-such-cell"),
    "the gantry as a cell": ('cell = "gantry-ur5"', "gantry cell"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_batch_file_is_one_line_exit_2_and_nothing_written(case, testdata, tmp_path, capsys):
    extra, named = BAD[case]
    top = extra.startswith("[") and not extra.startswith(("[[", "[job."))  # a top-level table goes first
    text = f"{extra}\n{ONE}" if top else f"{ONE}\n{extra}\n"
    batch = _folder(testdata, tmp_path / "in", text)
    out = tmp_path / "out"
    assert main(["batch", str(batch), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"sprayplan: error: {batch}: ") and named in err
    assert not out.exists()


def test_an_unreachable_scheduler_is_one_line_exit_2(testdata, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("sprayplan.cli.batch.CONNECT_TIMEOUT_S", 1.0)
    batch = _folder(testdata, tmp_path / "in", ONE)
    out = tmp_path / "out"
    assert main(["batch", str(batch), "-o", str(out), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--scheduler tcp://127.0.0.1:9: cannot connect" in err
    assert not out.exists()


def test_the_example_batch_file_reads():
    batch = read_batch(Path(__file__).resolve().parents[1] / "examples" / "batch.toml")
    assert len(batch.jobs) == 7 and batch.options == {"timeout_s": 1800}
    assert sorted({(j.config.paths.spacing_mm, j.config.motion.gun_speed_mm_s) for j in batch.jobs[:6]}) == [
        (s, v) for s in (40.0, 50.0, 60.0) for v in (300.0, 400.0)
    ]
    assert batch.jobs[6].config.load.units == "m" and batch.jobs[6].config.coating.thickness_um == 50
