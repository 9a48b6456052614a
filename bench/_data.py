"""Where the benchmarks find their third-party data.

The benchmarks read the full shared data set, which includes files the repository does not bundle (the
GPL-3.0 DTC ship hull): ``$SPRAYPLAN_TESTDATA`` if it is set, else ``shared/testdata`` beside the clone
(``<repo>/../shared/testdata``). The tests do not use this: they read the permissive subset bundled in
``tests/data``.

The bench scripts are run as ``python bench/bench_NAME.py``, so this folder is first on ``sys.path`` and
``from _data import testdata_dir`` works from each of them.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def testdata_dir() -> Path:
    """The shared test data folder (meshes/, pointclouds/, tsplib/); exits with a one-line message if absent."""
    env = os.environ.get("SPRAYPLAN_TESTDATA")
    path = Path(env) if env else REPO.parent / "shared" / "testdata"
    if not path.is_dir():
        where = "SPRAYPLAN_TESTDATA" if env else "the default location (no SPRAYPLAN_TESTDATA set)"
        raise SystemExit(
            f"benchmark data not found at {path} ({where}): put shared/testdata beside the clone "
            "or set SPRAYPLAN_TESTDATA to its folder"
        )
    return path


def meshes_dir() -> Path:
    """``testdata_dir() / "meshes"``."""
    return testdata_dir() / "meshes"


def builds_at_once(argv: list[str], base: str | None):
    """Run ``argv`` (a bench script and its child's arguments) once per build at the same time, this checkout's
    ``src`` (``new``) and, with ``base``, another checkout's, each with its ``src`` first on ``PYTHONPATH``;
    yield ``(build, result)`` as each ends, the result the JSON of its last line of output."""
    import json
    import subprocess
    import sys

    builds = {"new": REPO / "src"} | ({"base": Path(base).resolve() / "src"} if base else {})
    running = {
        build: subprocess.Popen(
            [sys.executable, *argv], env=dict(os.environ, PYTHONPATH=str(src)), stdout=subprocess.PIPE, text=True
        )
        for build, src in builds.items()
    }
    for build, proc in running.items():
        out, _ = proc.communicate()
        yield build, json.loads(out.strip().splitlines()[-1])


#: The two car bodies of the cell benchmarks: their file under testdata and their up axis.
CAR_BODIES = {"bmw": ("meshes/bmw_m6_body_m_yup.ply", "y"), "suv": ("meshes/gazebo_suv_body_m.ply", "z")}


def cell_plan_model(folder, part: str):
    """A cell plan folder written with ``--collisions`` read back (``cells.files.cell_plan_from_file``), its body
    (``part``: a key of :data:`CAR_BODIES`) placed in the plan's cell again, the painted surface and the
    collision model built as ``cells.plan.plan_cell`` builds them: ``(plan, placed, painted, config, arms)``,
    ``config`` the plan's ``[collision]`` settings with the check on."""
    import dataclasses

    from sprayplan.cells.collide import cell_arms
    from sprayplan.cells.files import cell_plan_from_file
    from sprayplan.cells.plan import area_surface
    from sprayplan.cells.spec import load_cell, place_part
    from sprayplan.io.load import load_part
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import painted_surface

    plan = cell_plan_from_file(Path(folder) / "cell_plan.json")
    path, up = CAR_BODIES[part]
    placed = place_part(load_part(testdata_dir() / path, units="m", up=up), load_cell(plan.cell.name))
    painted, _ = painted_surface(oriented_part(placed.part), plan.job.collision)
    painted, _ = area_surface(painted)
    config = dataclasses.replace(plan.job.collision, check=True)
    return plan, placed, painted, config, cell_arms(plan.cell, painted, config)
