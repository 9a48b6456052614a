"""Helpers shared by the command-line modules."""

from __future__ import annotations

import contextlib
import logging
import time

from sprayplan.errors import ConfigError

log = logging.getLogger("sprayplan.cli")


@contextlib.contextmanager
def stage(name: str):
    """Log a stage's start and its duration (shown with ``-v``)."""
    start = time.perf_counter()
    log.info("%s ...", name)
    yield
    log.info("%s done in %.2f s", name, time.perf_counter() - start)


def parse_direction(text: str):
    if text in ("auto", "x", "y", "z"):
        return text
    try:
        values = tuple(float(v) for v in text.replace(" ", "").split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise ConfigError(f"--direction must be auto, x, y, z or 'dx,dy,dz', got {text!r}")
    return values


def parse_edge_passes(text):
    """``--edge-passes``: auto or a whole number >= 0."""
    if text is None or text == "auto":
        return text
    try:
        value = int(text)
    except ValueError:
        raise ConfigError(f"--edge-passes must be auto or a whole number >= 0, got {text!r}") from None
    if value < 0:
        raise ConfigError(f"--edge-passes must be auto or a whole number >= 0, got {text!r}")
    return value
