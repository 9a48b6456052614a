"""The main job's progress hook: a stage reports ``(stage, done, total)`` to a callback as it works.

The library never prints; the command line turns these calls into a progress display (``cli.common``).
``(stage, 0, 0)`` says that a stage has started (``job.run_job`` sends it; a stage ends when the next one
starts, or the job returns). A stage that counts its work then reports ``(stage, done, total)``: ``total``
units (layers, stations, film batches, tuning rounds), ``done`` counting up to it.
"""

from __future__ import annotations

from collections.abc import Callable

#: ``progress(stage, done, total)``.
Progress = Callable[[str, int, int], None]


def no_progress(stage: str, done: int, total: int) -> None:
    """The callback of a job run without a display."""


def counted(progress: Progress | None, stage: str, total: int):
    """A function of no arguments that reports one more unit of ``stage`` done each time it is called."""
    progress = progress or no_progress
    done = 0

    def step() -> None:
        nonlocal done
        done += 1
        progress(stage, done, total)

    return step


def per_stage(progress: Progress | None, stage: str):
    """A ``progress(done, total)`` callback for a stage's library function, reporting under ``stage``; None
    when there is nothing to report to."""
    if progress is None:
        return None
    return lambda done, total: progress(stage, done, total)
