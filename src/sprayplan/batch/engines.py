"""Where a batch's jobs run: a pool of local processes, or a Dask cluster.

Both engines take ``(task, staging, placed)`` triples (``batch.task.Task``; the folder to write the job into,
and where it goes once complete) and yield ``(task, row, files)`` as jobs finish, in any order: ``files`` is
None when the job wrote into its staging folder itself (the local engine), else the job's files by relative
path (Dask: a worker need not see the output folder). A job that fails, however it fails, is a row.

``local``: one fresh process per job, at most ``workers`` at a time, forked from a server that has the
library imported already (so a job starts in milliseconds, not seconds). The parent watches each one: a
process that dies (a crash, the kernel's out-of-memory killer, a kill) fails its job only; one past the
job's memory cap (``job_memory_mb``, read from ``/proc``) or far past its timeout is killed.

``dask``: ``client.submit`` of :func:`batch.task.run_task_remote` per job. Dask retries a job whose worker
died on another worker (the scheduler's ``allowed-failures``, 3 by default) and then reports it
(``KilledWorker``); its own memory management (the nanny's ``memory_limit``) restarts a worker that
outgrows it. A part's bytes travel with its task when the file is at most ``ship_mb``; a larger part is read
by the worker from its path, which must then be on storage the workers share.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import shutil
import time
import uuid
from collections.abc import Iterator

from sprayplan.batch.task import Task, failed_row, rss_mb, run_task, run_task_remote
from sprayplan.heap import reuse_freed_memory

log = logging.getLogger(__name__)

#: Modules the local engine's fork server imports once, so that each job's process starts with them.
PRELOAD = [
    "numpy", "scipy.spatial", "scipy.optimize", "trimesh", "sprayplan.batch.task", "sprayplan.job",
    "sprayplan.io.load", "sprayplan.surface.region", "sprayplan.paths.planner", "sprayplan.stations.stage",
    "sprayplan.ordering.stage", "sprayplan.robots.stage", "sprayplan.refine.stage", "sprayplan.coating.stage",
    "sprayplan.export.summary", "sprayplan.export.job_files", "sprayplan.export.plan_json", "sprayplan.view.html",
]  # fmt: skip
#: A local job still running this long past its timeout (it did not reach a progress report) is killed.
KILL_GRACE_S = 5.0
#: Parts up to this size (MB) travel with their Dask task by default.
SHIP_MB = 8.0


def available_memory_mb() -> float | None:
    """Memory the machine can still give (``MemAvailable`` of ``/proc/meminfo``), None where unknown."""
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) / 1e3
    except (OSError, ValueError, IndexError):
        pass
    return None


def local_workers(workers: int | None, jobs: int, job_memory_mb: float | None = None) -> int:
    """How many local processes to run: ``workers`` (default: the core count), at most one per job, and with
    ``job_memory_mb`` at most as many as the available memory holds (at least one)."""
    count = workers or os.cpu_count() or 1
    if job_memory_mb:
        free = available_memory_mb()
        if free is not None:
            fits = max(1, int(free // job_memory_mb))
            if fits < count:
                log.info("%d workers: %.0f MB available, %.0f MB a job", fits, free, job_memory_mb)
            count = min(count, fits)
    return max(1, min(count, jobs))


def _context():
    if "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(PRELOAD)
        return context
    return multiprocessing.get_context("spawn")


def _child(conn, task: Task, staging: str, placed: str) -> None:
    """A local job's process: run the job, send its row."""
    reuse_freed_memory()  # as the command line does: the process is the job's own
    try:
        row = run_task(task, staging, placed)
    except BaseException as exc:  # interrupted: still a row, so the parent knows
        row = failed_row(task, f"stopped ({type(exc).__name__})")
    conn.send(row)
    conn.close()


def _death(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        import signal

        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        hint = " (killed: out of memory?)" if -exitcode == signal.SIGKILL else ""
        return f"the job's process died ({name}){hint}"
    return f"the job's process ended without a result (exit code {exitcode})"


def run_local(items, workers: int, job_memory_mb: float | None = None, poll_s: float = 0.2) -> Iterator:
    """Run ``(task, staging, placed)`` items in local processes, ``workers`` at a time; yields
    ``(task, row, None)`` as each ends. Every process still running when the caller stops is killed."""
    from multiprocessing.connection import wait

    context = _context()
    pending = list(items)[::-1]
    running: dict = {}  # conn -> (process, task, started)
    try:
        while pending or running:
            while pending and len(running) < workers:
                task, staging, placed = pending.pop()
                receive, send = context.Pipe(duplex=False)
                process = context.Process(
                    target=_child, args=(send, task, staging, placed), name=f"sprayplan-{task.job_id}"
                )
                process.start()
                send.close()
                running[receive] = (process, task, time.monotonic())
            ready = wait(list(running) + [p.sentinel for p, _, _ in running.values()], timeout=poll_s)
            for conn, (process, task, started) in list(running.items()):
                row = None
                if conn in ready or process.sentinel in ready:
                    try:
                        row = conn.recv() if conn.poll() else None
                    except (EOFError, OSError):
                        row = None
                    if row is None:
                        process.join(1.0)
                        if process.is_alive():
                            continue
                        row = failed_row(task, _death(process.exitcode))
                else:
                    late = task.timeout_s is not None and time.monotonic() - started > task.timeout_s + KILL_GRACE_S
                    rss = rss_mb(process.pid) if job_memory_mb else None
                    if late:
                        row = failed_row(task, f"timed out after {task.timeout_s:g} s (killed)")
                    elif rss is not None and rss > job_memory_mb:
                        row = failed_row(task, f"out of memory: over job_memory_mb = {job_memory_mb:g} MB (killed)")
                    else:
                        continue
                    process.kill()
                process.join()
                conn.close()
                del running[conn]
                yield task, row, None
    finally:
        for conn, (process, _, _) in running.items():
            process.kill()
            process.join()
            conn.close()


def run_dask(client, items, ship_mb: float = SHIP_MB) -> Iterator:
    """Run ``(task, staging, placed)`` items on a Dask cluster; yields ``(task, row, files)`` as each ends
    (``files`` empty for a failed job). Unfinished futures are cancelled when the caller stops."""
    import dataclasses

    from distributed import as_completed

    futures = {}
    batch = uuid.uuid4().hex[:8]
    try:
        for task, _, placed in items:
            data = None
            try:
                if os.path.getsize(task.part) <= ship_mb * 1e6:
                    with open(task.part, "rb") as handle:
                        data = handle.read()
            except OSError:
                data = None  # gone since the batch was read: the worker reports it
            shipped = dataclasses.replace(task, data=data)
            key = f"sprayplan-{task.job_id}-{batch}"
            futures[client.submit(run_task_remote, shipped, placed, key=key, pure=False)] = task
        for future in as_completed(list(futures)):
            task = futures.pop(future)
            try:
                row, files = future.result()
            except Exception as exc:  # the worker died (KilledWorker), the task was cancelled, a comm failed
                row, files = failed_row(task, f"worker failed: {type(exc).__name__}: {exc}"), {}
            yield task, row, files
    finally:
        if futures:
            client.cancel(list(futures))


def write_files(folder: str, files: dict[str, bytes]) -> None:
    """Write a job's shipped-back files into its staging folder."""
    for name, data in files.items():
        path = os.path.join(folder, *name.split("/"))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as handle:
            handle.write(data)


def remove_folder(folder: str) -> None:
    shutil.rmtree(folder, ignore_errors=True)
