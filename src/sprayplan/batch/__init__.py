"""Batches of jobs: many parts and parameter sweeps, on the local machine or a Dask cluster (docs/batch.md).

``read_batch(path)`` reads a batch file into its jobs; ``run_batch(jobs, outdir, client=None)`` runs them,
one folder per job, with ``summary.csv`` and ``summary.json``; ``sprayplan batch`` is the command line.
"""

from sprayplan.batch.run import BatchResult, run_batch
from sprayplan.batch.spec import Batch, BatchJob, jobs_from_dict, read_batch

__all__ = ["Batch", "BatchJob", "BatchResult", "jobs_from_dict", "read_batch", "run_batch"]
