"""Shared fixtures: where the third-party test data lives.

The real parts the tests use are bundled in ``tests/data`` (meshes/, pointclouds/, tsplib/; permissive
licences only, listed with their origins in ``tests/data/MANIFEST.md``), so a fresh clone needs nothing beside
it. The benchmarks in ``bench/`` read a larger shared set instead (see ``bench/_data.py``).
"""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TESTDATA = REPO / "tests" / "data"


@pytest.fixture(scope="session")
def testdata() -> Path:
    """The folder of real third-party parts bundled with the tests (meshes/, pointclouds/, tsplib/)."""
    return TESTDATA


@pytest.fixture(scope="session")
def planned_with_film(testdata, tmp_path_factory) -> Path:
    """The reach part (x > -250) planned for a 50 um film with 60 measuring points, its pictures with it: a
    plan folder written by ``sprayplan plan`` (shared by the viewer's tests)."""
    from sprayplan.cli import main

    out = tmp_path_factory.mktemp("planned")
    part = testdata / "meshes" / "reach_curved_part.ply"
    # the speeds tuned at the planned speeds, not again within the UR's joint limits (which keep this part far
    # above 50 um, docs/benchmarks.md): the viewer's tests want a film mostly in spec, whose colours they check
    config = tmp_path_factory.mktemp("config") / "process.toml"
    config.write_text("[tuning]\nlimit_rounds = 0\n")
    argv = ["-q", "plan", str(part), "--units", "m", "--region", "x > -250", "--thickness-um", "50", "-c", str(config)]
    assert main([*argv, "--samples", "60", "-o", str(out)]) == 0
    return out
