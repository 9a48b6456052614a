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


class ProgressDisplay:
    """The command line's view of the main job's progress hook (``sprayplan.progress``).

    On a terminal (stderr a TTY): a tqdm bar for the running stage, cleared when it ends, so that an error
    still leaves one line. Elsewhere (a log, a pipe): one line on stdout per stage as it ends, with its time,
    and, for a stage that counts its work, a line at most every ``every_s`` seconds while it runs.
    ``quiet``: nothing.
    """

    def __init__(self, quiet: bool = False, stream=None, tty: bool | None = None, every_s: float = 10.0):
        import sys

        self.quiet = quiet
        self.stream = sys.stdout if stream is None else stream
        self.tty = sys.stderr.isatty() if tty is None else tty
        self.every_s = every_s
        self._bar = None
        self._stage = None
        self._began = 0.0
        self._said = 0.0

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        now = time.perf_counter()
        if stage != self._stage:
            self._end(now)
            self._stage, self._began, self._said = stage, now, now
        if self.tty:
            self._show_bar(stage, done, total)
        elif total > 1 and done > 0 and now - self._said >= self.every_s:
            self._said = now
            print(f"sprayplan: {stage} {done}/{total}", file=self.stream, flush=True)

    def _show_bar(self, stage: str, done: int, total: int) -> None:
        from tqdm import tqdm

        if self._bar is None or (total and self._bar.total != total):
            self._close_bar()
            self._bar = tqdm(total=total or None, desc=stage, leave=False, unit="", dynamic_ncols=True)
        if done > self._bar.n:
            self._bar.update(done - self._bar.n)  # redrawn at most every tqdm's mininterval (0.1 s)

    def _close_bar(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def _end(self, now: float) -> None:
        """The running stage has ended (another began, or the job did)."""
        self._close_bar()
        if self._stage is not None and not self.tty:
            print(f"sprayplan: {self._stage} done in {now - self._began:.1f} s", file=self.stream, flush=True)
        self._stage = None

    def close(self, finished: bool = True) -> None:
        """The job has ended: report the last stage (when it finished) and clear what is shown."""
        if finished:
            self._end(time.perf_counter())
        else:
            self._close_bar()
            self._stage = None
