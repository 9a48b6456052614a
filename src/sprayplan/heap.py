"""Large arrays served from memory the process has freed, not from fresh pages (glibc only).

glibc's ``malloc`` gives every block above its mmap threshold (32 MB at most by default) pages of their own
and returns them to the kernel when the block is freed; the next array of that size gets fresh pages, which
the kernel faults in and zeroes page by page on first write. The film's deposit matrix and the speed
tuning's Jacobians are such blocks, made and freed tens of times a plan: on the car body a copy of its 130 MB
Jacobian took 97 ms with fresh pages and 33 ms with reused ones. :func:`reuse_freed_memory` raises the mmap
threshold and the trim threshold to 1 GiB, so that freed blocks stay in the heap and are used again (the
process keeps up to that much freed memory instead of returning it at once: the peak is about the same, the
resident size after a peak stays nearer it).

It changes the whole process's allocator, so the library never calls it on its own: the command line does
(``cli.main``), and so does each local batch job's process; a program that calls ``run_job`` may call it
first to plan as fast as ``sprayplan plan`` does. The freed memory kept is handed back to the kernel
(:func:`release_freed_memory`, glibc's ``malloc_trim``) after every stage of the main job and after each
speed tuning, where the big blocks of a stage are freed.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import logging
import sys

log = logging.getLogger(__name__)

#: glibc's mallopt parameters (malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3

#: Blocks up to this size come from the heap, and up to this much freed memory stays in it.
THRESHOLD_BYTES = 1 << 30


@functools.cache
def _libc():
    """glibc, or None (off Linux, or another C library); looked up once."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.mallopt, libc.malloc_trim  # noqa: B018 (glibc has both)
    except (OSError, AttributeError):
        return None
    return libc


def release_freed_memory() -> bool:
    """Hand the memory the process has freed back to the kernel (glibc's ``malloc_trim(0)``); returns
    whether any was (False off glibc)."""
    libc = _libc()
    if libc is None:
        return False
    libc.malloc_trim.argtypes = [ctypes.c_size_t]
    libc.malloc_trim.restype = ctypes.c_int
    return bool(libc.malloc_trim(0))


def reuse_freed_memory() -> bool:
    """Make glibc's ``malloc`` serve blocks up to ``THRESHOLD_BYTES`` from the heap and keep that much freed
    memory for reuse. Returns whether it did (False off Linux, or with another C library)."""
    libc = _libc()
    if libc is None:
        return False
    mallopt = libc.mallopt
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    done = bool(mallopt(M_MMAP_THRESHOLD, THRESHOLD_BYTES)) and bool(mallopt(M_TRIM_THRESHOLD, THRESHOLD_BYTES))
    log.debug("large blocks from the heap: %s", done)
    return done
