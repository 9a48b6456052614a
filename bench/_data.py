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
