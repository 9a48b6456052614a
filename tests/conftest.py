"""Shared fixtures: where the third-party test data lives.

The real parts used by the tests are not part of this repository: they live in ``shared/testdata`` beside the
clone (``../shared/testdata`` from the repository root), or wherever ``SPRAYPLAN_TESTDATA`` points.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _testdata_dir() -> Path:
    env = os.environ.get("SPRAYPLAN_TESTDATA")
    return Path(env) if env else REPO.parent / "shared" / "testdata"


@pytest.fixture(scope="session")
def testdata() -> Path:
    """The folder of real third-party parts (meshes/, pointclouds/, tsplib/)."""
    path = _testdata_dir()
    if not (path / "MANIFEST.md").is_file():
        pytest.fail(
            f"test data not found at {path}: put shared/testdata beside the clone "
            "or set SPRAYPLAN_TESTDATA to its folder"
        )
    return path
