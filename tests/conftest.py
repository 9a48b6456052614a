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
