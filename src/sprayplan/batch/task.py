"""One job of a batch as a worker runs it: the main job into a folder, and its summary row.

This is the only code that runs on a worker (a local process or a Dask worker): it gets a :class:`Task`
(plain data: the part's path, or its bytes when they were shipped, and the settings), runs
``job.run_job``, writes the same files ``sprayplan plan`` writes plus ``job.json`` (the job's id, its
settings and its row) into the folder it is given, and returns the row. A failure of the job is a row with
``status = "failed"`` and a one-line error, never an exception; a job past its deadline stops at its next
progress report (:class:`JobTimeout`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import resource
import shutil
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field

#: The file in each job folder that makes it complete: its id, settings and summary row (written last).
JOB_FILE = "job.json"
#: Row statuses.
OK, FAILED = "ok", "failed"


@dataclass(frozen=True)
class Task:
    """What a worker needs to run one job (picklable, no open files).

    Attributes
    ----------
    job_id, name : str
    part : str
        The part file as the batch names it (absolute), also how plan.json names it.
    part_sha256 : str
        Its bytes' hash when the batch was read: a part changed or deleted since is a failed job.
    settings : dict
        ``config.job_to_dict`` of the job's settings.
    overrides : dict
        The settings the batch file gave (``section.key`` -> value), copied into the row.
    data : bytes or None
        The part's bytes, shipped with the task (Dask, small parts); None: the worker reads ``part``.
    timeout_s : float or None
        Wall time the job may take on the worker.
    cell : str or None
        A cell plan's cell (``batch.spec.BatchJob.cell``: a preset's name or a cell TOML's text); None: the
        gantry's main job.
    """

    job_id: str
    name: str
    part: str
    part_sha256: str
    settings: dict
    overrides: dict = field(default_factory=dict)
    data: bytes | None = None
    timeout_s: float | None = None
    cell: str | None = None


class JobTimeout(Exception):
    """The job ran past its timeout (raised from its progress hook, between two units of work)."""


def rss_mb(pid: int | str = "self") -> float | None:
    """A process's resident memory in MB (Linux ``/proc/PID/statm``; this one by default), None where it
    cannot be read (another system, or the process is gone)."""
    try:
        with open(f"/proc/{pid}/statm") as handle:
            pages = int(handle.read().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


class PeakMemory:
    """The peak resident memory of this process while a block runs, sampled every ``every_s`` seconds.

    A process that runs one job (the local engine's) would also have it from ``getrusage``; a Dask worker
    runs many, so the peak is sampled over the job's own run. Where ``/proc`` is missing, ``getrusage``'s
    lifetime peak is reported.
    """

    def __init__(self, every_s: float = 0.05):
        self.every_s = every_s
        self.peak_mb = 0.0
        self._stop = threading.Event()
        self._thread = None

    def _sample(self) -> None:
        while True:
            now = rss_mb()
            if now is not None:
                self.peak_mb = max(self.peak_mb, now)
            if self._stop.wait(self.every_s):
                return

    def __enter__(self):
        if rss_mb() is None:
            return self
        self._thread = threading.Thread(target=self._sample, name="sprayplan-peak-memory", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        if self._thread is None:
            scale = 1e3 if sys.platform != "darwin" else 1.0  # ru_maxrss: kB on Linux, bytes on macOS
            self.peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale / 1e6
            return False
        self._stop.set()
        self._thread.join()
        now = rss_mb()
        self.peak_mb = max(self.peak_mb, now or 0.0)
        return False


def _deadline_hook(timeout_s: float | None):
    """A ``progress(stage, done, total)`` hook raising :class:`JobTimeout` once ``timeout_s`` has passed."""
    if timeout_s is None:
        return None
    end = time.monotonic() + timeout_s

    def progress(stage: str, done: int, total: int) -> None:
        if time.monotonic() > end:
            raise JobTimeout(f"timed out after {timeout_s:g} s (in the {stage} stage)")

    return progress


@contextlib.contextmanager
def _part_file(task: Task):
    """The path to load the part from: the batch's file (its hash checked), or the shipped bytes in a
    temporary file of the same name."""
    from sprayplan.batch.spec import file_sha256
    from sprayplan.errors import PartFileError

    if task.data is None:
        try:
            digest, _ = file_sha256(task.part)
        except FileNotFoundError:
            raise PartFileError(task.part, "no such file (deleted since the batch was read?)") from None
        except OSError as exc:
            raise PartFileError(task.part, f"cannot read ({exc.strerror or exc})") from None
        if digest != task.part_sha256:
            raise PartFileError(task.part, "changed since the batch was read (its bytes' hash differs)")
        yield task.part
        return
    folder = tempfile.mkdtemp(prefix="sprayplan-part-")
    try:
        path = os.path.join(folder, os.path.basename(task.part))
        with open(path, "wb") as handle:
            handle.write(task.data)
        yield path
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def one_line(text) -> str:
    return " ".join(str(text).split())


def error_text(exc: BaseException) -> str:
    """A failed job's error in one line: an input error as it is, anything else with its type."""
    from sprayplan.errors import InputError

    if isinstance(exc, (InputError, JobTimeout)):
        return one_line(exc)
    if isinstance(exc, MemoryError):
        return "out of memory (MemoryError)"
    if isinstance(exc, OSError):
        return one_line(f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}")
    return one_line(f"internal error: {type(exc).__name__}: {exc}")


def _figures(result, folder) -> dict:
    """The figures of a finished job a process engineer compares (from its totals and coating.json)."""
    from types import SimpleNamespace

    from sprayplan.view.html import flagged_waypoints

    totals = result.totals
    flags = flagged_waypoints(SimpleNamespace(plan=result.plan, job=result.job))
    row = {
        "stations": totals["stations"],
        "strokes": totals["strokes"],
        "waypoints": totals["waypoints"],
        "unreachable_waypoints": totals["unreachable_waypoints"],
        "flagged_waypoints": sum(len(texts) for reason, (_, texts) in flags.items() if reason != "unassigned"),
        "unassigned_points": totals["unassigned_points"],
        "cycle_time_s": totals["cycle_time_s"],
        "planning_time_s": totals["planning_time_s"],
    }
    coating = os.path.join(folder, "coating.json")
    if os.path.exists(coating):
        with open(coating, encoding="utf-8") as handle:
            report = json.load(handle)
        painted, paint = report["painted"], report["paint"]
        row |= {
            "film_mean_um": painted["mean_um"],
            "film_std_over_mean": painted["cv"],
            "film_share_in_spec": painted["share_in_spec"],
            "paint_used_ml": paint["wet_paint_ml"],
        }
    return row


def failed_row(task: Task, error: str, **figures) -> dict:
    """The row of a job that failed outside :func:`run_task` (its worker died, it was stopped)."""
    row = {"job_id": task.job_id, "name": task.name, "part": task.part, "settings": dict(task.overrides)}
    return row | {"status": FAILED, "error": one_line(error)} | figures


def _run_cell(task: Task, path: str, folder) -> dict:
    """A cell plan's job (``sprayplan plan PART --cell CELL``, with its programs when ``[export] programs`` names
    any) into ``folder``; its figures for the summary row."""
    from sprayplan.batch.spec import cell_from_text
    from sprayplan.cells.files import write_cell_plan
    from sprayplan.cells.plan import plan_cell
    from sprayplan.config import job_from_dict
    from sprayplan.io.load import load_part

    job = job_from_dict(task.settings)
    part = load_part(path, units=job.load.units, up=job.load.up)
    if path != task.part:
        part = dataclasses.replace(part, name=os.path.basename(task.part))
    plan = plan_cell(part, cell_from_text(task.cell), job, progress=_deadline_hook(task.timeout_s))
    target = job.coating.thickness_um if job.coating.thickness_um is not None else 50.0
    programs = []
    if job.export.programs:
        from sprayplan.programs.arms import build_cell_programs

        programs = build_cell_programs(plan, plan.job or job, tuple(job.export.programs))
    os.makedirs(folder, exist_ok=True)
    write_cell_plan(folder, plan, target, job.coating.tolerance_um)
    if programs:
        from sprayplan.programs.arms import write_cell_programs

        write_cell_programs(os.path.join(folder, "programs"), programs, plan.job or job)
    report = plan.report
    robots = report["robots"].values()
    row = {
        "cell": plan.cell.name,
        "robots": len(plan.robots),
        "strokes": sum(r["strokes"] for r in robots),
        "waypoints": sum(r["waypoints"] for r in robots),
        "unreachable_waypoints": sum(r["unreached_waypoints"] for r in robots),
        "cycle_time_s": report["cycle_time_s"],
        "planning_time_s": round(sum(plan.timings_s.values()), 3),
    }
    film = report.get("film")
    if film:
        row |= {
            "film_mean_um": film["whole"]["mean_um"],
            "film_std_over_mean": film["whole"]["std_um"] / film["whole"]["mean_um"],
            "film_share_in_spec": film["whole"]["share_in_spec"],
            "measuring_points_in_spec": film["report"].get("measuring_points", {}).get("share_in_spec"),
        }
    return row


def run_task(task: Task, folder, placed=None) -> dict:
    """Run one job into ``folder`` (created; the caller moves it into place) and return its summary row.

    ``placed``: where ``folder`` goes once complete (named by the robot programs' summary). The row holds
    the job's id, name, part, settings, ``status`` (``ok`` or ``failed``), ``error``, the figures, the
    wall time and the peak memory. On failure ``folder`` may hold partial files: the caller removes it.
    """
    from sprayplan.config import job_from_dict
    from sprayplan.job import run_job, write_outputs

    began = time.perf_counter()
    row = {"job_id": task.job_id, "name": task.name, "part": task.part, "settings": dict(task.overrides)}
    path = task.part
    with PeakMemory() as memory:
        try:
            with _part_file(task) as path:
                if task.cell is not None:  # a cell plan's job
                    row |= {"status": OK, "error": ""} | _run_cell(task, path, folder)
                else:
                    from sprayplan.parallel import single_process

                    with single_process():  # the batch runs jobs side by side: one process each by default
                        result = run_job(path, job_from_dict(task.settings), progress=_deadline_hook(task.timeout_s))
                    if path != task.part:  # shipped bytes: named as the batch's file, as `sprayplan plan` names it
                        plan = dataclasses.replace(result.plan, name=task.part)
                        result = dataclasses.replace(result, plan=plan, source=task.part)
                    write_outputs(folder, result, part_file=task.part, placed=placed)
                    row |= {"status": OK, "error": ""} | _figures(result, folder)
        except Exception as exc:  # a failed job is a row; the other jobs go on
            row |= {"status": FAILED, "error": error_text(exc).replace(path, task.part)}  # a shipped part by its name
    row |= {"job_time_s": round(time.perf_counter() - began, 3), "peak_memory_mb": round(memory.peak_mb, 1)}
    if row["status"] == OK:
        from sprayplan.export.files import atomic_output

        with atomic_output(os.path.join(folder, JOB_FILE), "w", encoding="utf-8") as handle:
            json.dump({"job_id": task.job_id, "settings": task.settings, "row": row}, handle, indent=1)
    return row


def read_folder_files(folder) -> dict[str, bytes]:
    """Every file under ``folder`` by its path relative to it (``/``-separated): a job's files shipped back."""
    out = {}
    for root, _, names in os.walk(folder):
        for name in names:
            full = os.path.join(root, name)
            with open(full, "rb") as handle:
                out[os.path.relpath(full, folder).replace(os.sep, "/")] = handle.read()
    return out


def run_task_remote(task: Task, placed: str | None = None) -> tuple[dict, dict[str, bytes]]:
    """:func:`run_task` on a worker that may not see the batch's output folder: the job runs in a temporary
    folder and its files come back with the row (none for a failed job); ``placed`` as for run_task."""
    scratch = tempfile.mkdtemp(prefix="sprayplan-job-")
    try:
        folder = os.path.join(scratch, task.job_id)
        row = run_task(task, folder, placed)
        files = read_folder_files(folder) if row["status"] == OK else {}
        return row, files
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
