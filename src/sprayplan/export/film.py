"""The film files of a plan: coating.json (the report), thickness.ply (a coloured mesh), thickness.csv."""

from __future__ import annotations

import json
import os

import numpy as np

from sprayplan.config import JobConfig


def film_report(result, job: JobConfig, samples: int | None = None, chosen: dict | None = None) -> dict:
    """The film's report (``coating.coating_report``) against the job's spec (50 +- 5 um without a target)."""
    from sprayplan.coating.report import coating_report

    target = job.coating.thickness_um if job.coating.thickness_um is not None else 50.0
    report = coating_report(result, target_um=target, tolerance_um=job.coating.tolerance_um, samples=samples)
    report["process"] = job.coating.process
    if chosen:
        report["chosen"] = chosen
    return report


def write_coating(outdir, result, job: JobConfig, report: dict) -> list[str]:
    """Write OUTDIR/thickness.ply, thickness.csv and coating.json (the report, :func:`film_report`); returns
    the paths written."""
    from sprayplan.coating.report import write_thickness_csv, write_thickness_ply
    from sprayplan.export.files import atomic_output

    target = job.coating.thickness_um if job.coating.thickness_um is not None else 50.0
    outdir = os.fspath(outdir)
    paths = [os.path.join(outdir, name) for name in ("thickness.ply", "thickness.csv", "coating.json")]
    write_thickness_ply(paths[0], result, target, job.coating.tolerance_um)
    write_thickness_csv(paths[1], result)
    with atomic_output(paths[2], "w", encoding="utf-8") as handle:
        json.dump(_finite(report), handle, indent=1)
        handle.write("\n")
    return paths


def _finite(value):
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _finite(value.tolist())
    return value
