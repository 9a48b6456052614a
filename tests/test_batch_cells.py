"""Cell plans in a batch (``cell = ...`` in a ``[[job]]``): each job is ``sprayplan plan PART --cell CELL`` with its
files, programs and summary row (issue 18: the batch stage takes a cell plan)."""

from __future__ import annotations

import json

import numpy as np

from sprayplan.batch.summary import read_summary_csv
from sprayplan.cells.files import read_cell_plan
from sprayplan.cli import main
from sprayplan.export.stl import write_stl_binary
from tests.helpers import grid_box
from tests.test_cell_plan import CELL, SIZE

BATCH = """
[[job]]
parts = "box.stl"
cell = "small2.toml"
coating.thickness_um = 50
export.programs = ["rapid"]
"""


def test_a_cell_job_in_a_batch_is_the_cell_plan_run_alone(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "small2.toml").write_text(CELL)
    (folder / "box.stl").write_bytes(write_stl_binary(grid_box(n=6, size=SIZE).triangles))
    (folder / "batch.toml").write_text(BATCH)
    out = tmp_path / "out"
    assert main(["-q", "batch", str(folder / "batch.toml"), "-o", str(out), "--workers", "1"]) == 0
    (row,) = read_summary_csv(out / "summary.csv")
    assert row["status"] == "ok" and row["cell"] == "small2" and int(row["robots"]) == 2
    job = out / row["job_id"]
    for name in ("cell_plan.json", "waypoints.csv", "areas.csv", "cell.html", "coating.json"):
        assert (job / name).exists(), name
    assert (job / "programs" / "left" / "rapid" / "summary.json").exists()
    alone = tmp_path / "alone"
    argv = ["-q", "plan", str(folder / "box.stl"), "--cell", str(folder / "small2.toml"), "--thickness-um", "50"]
    assert main([*argv, "-o", str(alone)]) == 0
    a, b = read_cell_plan(job / "cell_plan.json"), read_cell_plan(alone / "cell_plan.json")
    for ra, rb in zip(a["robots"], b["robots"]):
        assert len(ra["strokes"]) == len(rb["strokes"])
        for sa, sb in zip(ra["strokes"], rb["strokes"]):
            assert np.array_equal(sa["q_rad"], sb["q_rad"]) and np.array_equal(sa["tcp_mm"], sb["tcp_mm"])
    film = json.loads((alone / "coating.json").read_text())["whole"]
    assert abs(float(row["film_share_in_spec"]) - film["share_in_spec"]) < 1e-9
    assert int(row["waypoints"]) == sum(len(s["tcp_mm"]) for r in b["robots"] for s in r["strokes"])
