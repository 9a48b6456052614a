"""sprayplan.heap: large arrays from freed memory (glibc)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from sprayplan import heap


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**20


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_a_freed_large_array_is_kept_and_used_again():
    assert heap.reuse_freed_memory()
    block = np.ones(200 * 2**20 // 8)  # 200 MB, every page written
    held = _rss_mb()
    del block
    kept = _rss_mb()
    again = np.ones(180 * 2**20 // 8)  # a little smaller: small blocks made meanwhile may split the freed one
    reused = _rss_mb()
    del again
    # without it glibc gives the 200 MB back on free (an mmap of its own) and takes fresh pages again
    assert held - kept < 50
    assert reused - kept < 50


def test_off_linux_it_does_nothing(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    heap._libc.cache_clear()
    assert heap.reuse_freed_memory() is False
    heap._libc.cache_clear()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_released_memory_goes_back_to_the_kernel():
    assert heap.reuse_freed_memory()
    block = np.ones(200 * 2**20 // 8)
    del block
    kept = _rss_mb()
    assert heap.release_freed_memory()
    assert kept - _rss_mb() > 150  # the 200 MB kept for reuse are given back


def test_off_linux_nothing_is_released(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    heap._libc.cache_clear()
    assert heap.release_freed_memory() is False
    heap._libc.cache_clear()
