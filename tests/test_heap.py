"""sprayplan.heap: large arrays from freed memory (glibc)."""

from __future__ import annotations

import sys

import pytest

from sprayplan import heap

#: Run in a fresh interpreter: what the allocator does with a freed block depends on the heap's state, which a
#: long test session (numba compiling, earlier tests' arrays) leaves fragmented in its own way.
_MEASURE = """
import numpy as np
from sprayplan import heap

def rss_mb():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**20

assert heap.reuse_freed_memory()
block = np.ones(200 * 2**20 // 8)  # 200 MB, every page written
held = rss_mb()
del block
kept = rss_mb()
again = np.ones(180 * 2**20 // 8)  # a little smaller: small blocks made meanwhile may split the freed one
reused = rss_mb()
del again
assert heap.release_freed_memory()
print(held - kept, reused - kept, kept - rss_mb())
"""


def _measured() -> tuple[float, float, float]:
    """In a fresh interpreter: (MB given back on free, MB grown by a slightly smaller array made after it, MB
    given back by ``release_freed_memory``)."""
    import subprocess

    done = subprocess.run([sys.executable, "-c", _MEASURE], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return tuple(float(v) for v in done.stdout.split())


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_a_freed_large_array_is_kept_and_used_again():
    freed, grown, _ = _measured()
    # without it glibc gives the 200 MB back on free (an mmap of its own) and takes fresh pages again
    assert freed < 50
    assert grown < 50


def test_off_linux_it_does_nothing(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    heap._libc.cache_clear()
    assert heap.reuse_freed_memory() is False
    heap._libc.cache_clear()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_released_memory_goes_back_to_the_kernel():
    _, _, released = _measured()
    assert released > 150  # the 200 MB kept for reuse are given back


def test_off_linux_nothing_is_released(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    heap._libc.cache_clear()
    assert heap.release_freed_memory() is False
    heap._libc.cache_clear()
