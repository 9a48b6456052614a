"""``run_batch``: many jobs into one output folder, on the local machine or a Dask cluster, resumable.

Each job goes into ``OUTDIR/<job-id>/`` with the files ``sprayplan plan`` writes and ``job.json`` (its id,
settings and summary row). A job's folder is written under a temporary name beside it and renamed when
complete, so a folder named by a job's id is always a finished job: a re-run skips it (``force`` runs it
again and replaces it only once the new one is complete), and an interrupted job leaves only a temporary
folder, removed by the next run. A failed job gets no folder, only its row.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from sprayplan.batch.spec import Batch, BatchJob, read_batch
from sprayplan.batch.task import FAILED, JOB_FILE, OK, Task
from sprayplan.config import job_to_dict
from sprayplan.errors import ConfigError

log = logging.getLogger(__name__)

#: The status of a job a stopped batch did not finish.
NOT_RUN = "not run"


@dataclass(frozen=True)
class BatchResult:
    """What :func:`run_batch` did: one row per job, in the batch's order (as in summary.csv)."""

    outdir: str
    rows: tuple[dict, ...]

    @property
    def failed(self) -> int:
        return sum(1 for row in self.rows if row["status"] != OK)

    @property
    def exit_code(self) -> int:
        """0 when every job succeeded, 1 when some failed."""
        return 1 if self.failed else 0


def completed_row(folder: Path, job_id: str) -> dict | None:
    """The row stored in a complete job folder of this id, None when there is none."""
    try:
        with open(folder / JOB_FILE, encoding="utf-8") as handle:
            stored = json.load(handle)
    except (OSError, ValueError):
        return None
    if not isinstance(stored, dict) or stored.get("job_id") != job_id or not isinstance(stored.get("row"), dict):
        return None
    return stored["row"]


def _remove_stale(outdir: Path, job_id: str) -> None:
    """Temporary folders an interrupted run left for this job."""
    for stale in outdir.glob(f".{job_id}.*.tmp"):
        shutil.rmtree(stale, ignore_errors=True)
    for stale in outdir.glob(f"..{job_id}.*.tmp"):  # write_job's own staging inside a killed job's
        shutil.rmtree(stale, ignore_errors=True)


def _remove_staging(staging: Path) -> None:
    """A job's staging folder, and the staging folder its own writer made beside it (``.{staging}.{pid}.tmp``),
    which a job killed while writing leaves behind."""
    from sprayplan.batch import engines

    engines.remove_folder(str(staging))
    for nested in staging.parent.glob(f".{staging.name}.*.tmp"):
        shutil.rmtree(nested, ignore_errors=True)


def _place(staging: Path, final: Path) -> None:
    """Move a complete job folder into place; an older folder of the same id is replaced only then."""
    if final.exists() or final.is_symlink():
        old = final.with_name(f".{final.name}.{os.getpid()}.old")
        os.rename(final, old)
        try:
            os.rename(staging, final)
        except BaseException:
            os.rename(old, final)
            raise
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.rename(staging, final)


def _task(job: BatchJob, timeout_s: float | None) -> Task:
    return Task(job.job_id, job.name, job.part, job.part_sha256, job_to_dict(job.config), job.settings,
                None, timeout_s, job.cell)  # fmt: skip


def _jobs(jobs) -> tuple[BatchJob, ...]:
    if isinstance(jobs, (str, os.PathLike)):
        jobs = read_batch(jobs)
    if isinstance(jobs, Batch):
        jobs = jobs.jobs
    jobs = tuple(jobs)
    if not all(isinstance(job, BatchJob) for job in jobs):
        raise ConfigError("jobs must be BatchJob items (sprayplan.batch.read_batch), a Batch or a batch file")
    ids = [job.job_id for job in jobs]
    if len(set(ids)) != len(ids):
        twice = next(i for i in ids if ids.count(i) > 1)
        raise ConfigError(f"jobs: duplicate job id {twice}")
    return jobs


def run_batch(
    jobs: Batch | Sequence[BatchJob] | str | os.PathLike,
    outdir,
    client=None,
    *,
    workers: int | None = None,
    force: bool = False,
    timeout_s: float | None = None,
    job_memory_mb: float | None = None,
    ship_mb: float | None = None,
    progress: Callable[[int, int, dict], None] | None = None,
) -> BatchResult:
    """Run every job of a batch into ``outdir``, skipping those already complete there.

    Parameters
    ----------
    jobs : Batch, sequence of BatchJob, or a batch file's path
        (``batch.read_batch``).
    outdir : str or os.PathLike
        The batch's folder: ``<job-id>/`` per job, ``summary.csv``, ``summary.json``.
    client : dask.distributed.Client, optional
        Run on that cluster; None: a pool of local processes.
    workers : int, optional
        Local processes at a time (default: the core count, capped by ``job_memory_mb``).
    force : bool
        Run jobs whose folder is complete again (the new folder replaces the old one when complete).
    timeout_s : float, optional
        Wall time a job may take; past it the job stops at its next progress report and is a failed row
        (the local engine kills one that does not stop within ``engines.KILL_GRACE_S``).
    job_memory_mb : float, optional
        Memory a local job may use: a process past it is killed (a failed row), and fewer workers run when
        the available memory does not hold ``workers`` of them.
    ship_mb : float, optional
        Dask: parts up to this size travel with their task (default ``engines.SHIP_MB``); larger ones are
        read by the workers from their path.
    progress : callable, optional
        ``progress(done, total, row)`` after each job (skipped ones included).

    Returns
    -------
    BatchResult
        The rows; ``exit_code`` 0 when all succeeded, 1 when some failed.
    """
    from sprayplan.batch import engines
    from sprayplan.batch.summary import write_summary
    from sprayplan.export.files import check_output

    jobs = _jobs(jobs)
    check_output(outdir, folder=True)
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    items = []
    began = time.perf_counter()
    for job in jobs:
        final = out / job.job_id
        stored = None if force else completed_row(final, job.job_id)
        if stored is not None:
            rows[job.job_id] = {**stored, "reused": True}
            continue
        _remove_stale(out, job.job_id)
        staging = out / f".{job.job_id}.{os.getpid()}.tmp"
        items.append((_task(job, timeout_s), str(staging), str(final)))
    done = 0
    for row in rows.values():
        done += 1
        if progress is not None:
            progress(done, len(jobs), row)
    if client is None:
        count = engines.local_workers(workers, len(items), job_memory_mb)
        finished = engines.run_local(items, count, job_memory_mb) if items else iter(())
    else:
        finished = engines.run_dask(client, items, engines.SHIP_MB if ship_mb is None else ship_mb)
    try:
        for task, row, files in finished:
            staging, final = Path(out / f".{task.job_id}.{os.getpid()}.tmp"), out / task.job_id
            row = {**row, "reused": False}
            if row["status"] == OK:
                try:
                    if files is not None:
                        engines.write_files(str(staging), files)
                    _place(staging, final)
                except OSError as exc:
                    row = {**row, "status": FAILED, "error": f"{final}: cannot put the job's folder in place ({exc})"}
            _remove_staging(staging)
            rows[task.job_id] = row
            done += 1
            log.info("%d/%d %s: %s %s", done, len(jobs), task.job_id, row["status"], row.get("error", ""))
            if progress is not None:
                progress(done, len(jobs), row)
    finally:
        with contextlib.suppress(Exception):
            finished.close()
        for task, staging, _ in items:
            if task.job_id not in rows:
                _remove_staging(Path(staging))
        ordered = tuple(rows.get(job.job_id) or _not_run(job) for job in jobs)
        write_summary(out, ordered)
        log.info("batch of %d jobs in %.1f s", len(jobs), time.perf_counter() - began)
    return BatchResult(os.fspath(outdir), ordered)


def _not_run(job: BatchJob) -> dict:
    return {"job_id": job.job_id, "name": job.name, "part": job.part, "settings": dict(job.settings),
            "status": NOT_RUN, "error": "the batch stopped before this job finished", "reused": False}  # fmt: skip
