"""``sprayplan batch BATCH.toml -o OUTDIR``: many jobs, locally or on a Dask cluster (docs/batch.md)."""

from __future__ import annotations

import contextlib
import os
import sys
import time

from sprayplan.cli.common import check_count, check_outputs
from sprayplan.errors import ConfigError

ENGINES = ("local", "dask")
#: How long ``--scheduler ADDRESS`` may take to answer before it is an error.
CONNECT_TIMEOUT_S = 10.0


def add_batch_parser(sub, common) -> None:
    parser = sub.add_parser(
        "batch",
        parents=[common],
        help="many parts and parameter sweeps: OUTDIR/<job-id>/ each, OUTDIR/summary.csv",
        description="Run the main job for every part and setting a batch file lists (docs/batch.md), one "
        "folder per job, on this machine or a Dask cluster. A re-run skips the jobs already complete. Exit "
        "code 0: every job succeeded; 1: some failed (summary.csv says which); 2: a bad batch file or option.",
    )
    parser.add_argument("batch", help="the batch file (TOML)")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.add_argument("--engine", choices=ENGINES, help="local processes (default) or dask")
    parser.add_argument(
        "--scheduler", metavar="ADDRESS", help="dask: a running scheduler (tcp://HOST:PORT); default: a local cluster"
    )
    parser.add_argument("--workers", type=int, help="processes (local) or local cluster workers (default: cores)")
    parser.add_argument("--force", action="store_true", help="run jobs already complete in OUTDIR again")
    parser.add_argument("--timeout-s", type=float, help="wall time a job may take (default: none)")
    parser.add_argument(
        "--job-memory-mb", type=float, help="local: memory a job may use (killed past it; caps the workers)"
    )
    parser.add_argument("--ship-mb", type=float, help="dask: parts up to this size travel with their task (8)")
    parser.set_defaults(func=cmd_batch)


def _positive(option: str, value) -> None:
    if value is not None and not value > 0:
        raise ConfigError(f"{option}: must be a number > 0, got {value:g}")


@contextlib.contextmanager
def dask_client(address: str | None, workers: int | None):
    """A ``dask.distributed.Client``: of the scheduler at ``address``, or of a LocalCluster of ``workers``
    single-threaded worker processes started (and stopped) for the run."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ConfigError("--engine dask: dask is not installed (pip install 'sprayplan[dask]')") from None
    if address is not None:
        try:
            client = Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError(f"--scheduler {address}: cannot connect ({' '.join(str(exc).split())})") from None
        with client:
            yield client
        return
    import logging

    cluster = LocalCluster(
        n_workers=workers or os.cpu_count() or 1,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    with cluster, Client(cluster) as client:
        yield client


class BatchProgress:
    """Jobs done / total with the running time: a tqdm bar on a terminal, else a line per job on stdout."""

    def __init__(self, quiet: bool = False, tty: bool | None = None, stream=None):
        self.quiet = quiet
        self.tty = sys.stderr.isatty() if tty is None else tty
        self.stream = sys.stdout if stream is None else stream
        self.began = time.perf_counter()
        self._bar = None
        self.failed = 0

    def __call__(self, done: int, total: int, row: dict) -> None:
        self.failed += row["status"] != "ok"
        if self.quiet:
            return
        if self.tty:
            from tqdm import tqdm

            if self._bar is None:
                self._bar = tqdm(total=total, desc="batch", unit="job", leave=False, dynamic_ncols=True)
            self._bar.set_postfix(failed=self.failed, refresh=False)
            self._bar.update(done - self._bar.n)
            return
        elapsed = time.perf_counter() - self.began
        what = "reused" if row.get("reused") else row["status"]
        print(f"sprayplan: batch {done}/{total} in {elapsed:.1f} s: {row['job_id']} {what}", file=self.stream,
              flush=True)  # fmt: skip

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def cmd_batch(args) -> int:
    from sprayplan.batch import read_batch, run_batch
    from sprayplan.batch.summary import SUMMARY_FILES

    check_outputs([(args.output, "-o")], [(args.batch, "batch")], folder=True)
    check_count("--workers", args.workers)
    for option in ("timeout_s", "job_memory_mb", "ship_mb"):
        _positive("--" + option.replace("_", "-"), getattr(args, option))
    engine = args.engine or ("dask" if args.scheduler else "local")
    if args.scheduler is not None and engine != "dask":
        raise ConfigError("--scheduler: only with --engine dask")
    batch = read_batch(args.batch)
    check_outputs([(os.path.join(args.output, name), "-o") for name in SUMMARY_FILES], [(args.batch, "batch")])
    given = {k: getattr(args, k) for k in ("workers", "timeout_s", "job_memory_mb", "ship_mb")}
    options = {**batch.options, **{k: v for k, v in given.items() if v is not None}}
    if "workers" in options:
        options["workers"] = int(options["workers"])
    display = BatchProgress(quiet=getattr(args, "quiet", False))
    with contextlib.ExitStack() as stack:
        client = stack.enter_context(dask_client(args.scheduler, options.get("workers"))) if engine == "dask" else None
        try:
            result = run_batch(batch, args.output, client, force=args.force, progress=display, **options)
        finally:
            display.close()
    reused = sum(1 for row in result.rows if row.get("reused"))
    for row in result.rows:
        if row["status"] != "ok":
            print(f"sprayplan: failed: {row['job_id']}: {row['error']}", file=sys.stderr)
    ok = len(result.rows) - result.failed
    print(
        f"{len(result.rows)} jobs: {ok} ok ({reused} reused), {result.failed} failed -> "
        f"{os.path.join(args.output, 'summary.csv')}"
    )
    return result.exit_code
