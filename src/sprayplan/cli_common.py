"""Helpers shared by the command-line modules."""

from __future__ import annotations

import contextlib
import logging
import time

log = logging.getLogger("sprayplan.cli")


@contextlib.contextmanager
def stage(name: str):
    """Log a stage's start and its duration (shown with ``-v``)."""
    start = time.perf_counter()
    log.info("%s ...", name)
    yield
    log.info("%s done in %.2f s", name, time.perf_counter() - start)
