"""A batch's summary: OUTDIR/summary.csv and OUTDIR/summary.json, one row per job (docs/batch.md)."""

from __future__ import annotations

import csv
import io
import json
import os

#: The columns of summary.csv before the settings' columns.
LEAD = ("job_id", "name", "part", "status", "error", "reused")
#: The figures of each job, after the settings' columns (empty where a job has none: no film, or failed).
FIGURES = (
    "film_mean_um",
    "film_std_over_mean",
    "film_share_in_spec",
    "measuring_points_in_spec",
    "paint_used_ml",
    "cycle_time_s",
    "stations",
    "cell",
    "robots",
    "strokes",
    "waypoints",
    "unreachable_waypoints",
    "flagged_waypoints",
    "unassigned_points",
    "planning_time_s",
    "job_time_s",
    "peak_memory_mb",
)
SUMMARY_FILES = ("summary.csv", "summary.json")


def setting_columns(rows) -> list[str]:
    """Every setting any job's row names (``section.key``), in the order they first appear."""
    return list(dict.fromkeys(key for row in rows for key in row.get("settings", {})))


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return ",".join(_cell(v) for v in value)
    if isinstance(value, float):
        return repr(value)
    return str(value)


def summary_csv(rows) -> str:
    """summary.csv's text: the lead columns, one column per setting, the figures."""
    settings = setting_columns(rows)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*LEAD, *settings, *FIGURES])
    for row in rows:
        given = row.get("settings", {})
        writer.writerow(
            [_cell(row.get(k)) for k in LEAD]
            + [_cell(given.get(k)) for k in settings]
            + [_cell(row.get(k)) for k in FIGURES]
        )
    return out.getvalue()


def summary_dict(rows) -> dict:
    """summary.json's content: counts and the rows (settings as a table in each)."""
    counts = {status: sum(1 for r in rows if r["status"] == status) for status in ("ok", "failed", "not run")}
    return {"sprayplan_batch_summary": 1, "jobs": len(rows), **{k.replace(" ", "_"): v for k, v in counts.items()},
            "rows": [dict(r) for r in rows]}  # fmt: skip


def write_summary(outdir, rows) -> list[str]:
    """Write summary.csv and summary.json into ``outdir``, both or neither."""
    from sprayplan.export.files import staged_files

    paths = [os.path.join(outdir, name) for name in SUMMARY_FILES]
    with staged_files(paths) as (csv_path, json_path):
        with open(csv_path, "w", encoding="utf-8", newline="") as handle:
            handle.write(summary_csv(rows))
        with open(json_path, "w", encoding="utf-8") as handle:
            json.dump(summary_dict(rows), handle, indent=1, allow_nan=True)
    return paths


def read_summary_csv(path) -> list[dict]:
    """summary.csv read back: one dict of strings per row."""
    with open(path, encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle))
