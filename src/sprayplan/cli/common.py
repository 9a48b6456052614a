"""Helpers shared by the command-line modules."""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import time

from sprayplan.errors import ConfigError, InputError

log = logging.getLogger("sprayplan.cli")


@contextlib.contextmanager
def stage(name: str):
    """Log a stage's start and its duration (shown with ``-v``)."""
    start = time.perf_counter()
    log.info("%s ...", name)
    yield
    log.info("%s done in %.2f s", name, time.perf_counter() - start)


class UsageError(InputError):
    """The command line itself is wrong (argparse's complaint): an unknown option, a bad choice, a missing one."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse, but a wrong command line raises :class:`UsageError` (one line, no usage block) instead of
    printing the usage and exiting; ``--help`` still prints the usage. Subparsers are of this class too."""

    def error(self, message: str):
        text = " ".join(message.split())
        if text.startswith("argument "):  # "argument --units: invalid choice: ..." -> "--units: invalid ..."
            text = text[len("argument ") :]
        for lead, tail in (
            ("the following arguments are required: ", "required"),
            ("unrecognized arguments: ", "unknown"),
        ):
            if text.startswith(lead):  # "the following arguments are required: part" -> "part: required"
                text = f"{text[len(lead) :]}: {tail}"
        command = self.prog.split(" ", 1)[1] if " " in self.prog else ""
        raise UsageError(f"{text} (see 'sprayplan {command + ' ' if command else ''}--help')")


def output_option(value, option: str = "-o"):
    """An output path option as given; an empty one is an error naming the option."""
    if value is not None and not os.fspath(value).strip():
        raise ConfigError(f"{option}: an empty path (give a file or folder name)")
    return value


def check_outputs(outputs, inputs, folder: bool = False) -> None:
    """Before a command runs: each output ``(path, option)`` can be written (a folder with ``folder``), and
    none is an input ``(path, label)`` or another output (``export.files.check_output``, ``refuse_inputs``)."""
    from sprayplan.export.files import check_output, refuse_inputs

    outputs = [(path, option) for path, option in outputs if path is not None]
    for path, option in outputs:
        check_output(output_option(path, option), folder=folder)
    refuse_inputs(outputs, inputs)


def check_folder_outputs(outdir, names, option: str, inputs) -> None:
    """:func:`check_outputs` for the outputs ``names`` inside the folder ``outdir``: ``report`` is a folder
    (``export.job_files.OUTPUT_FOLDERS``), the others files."""
    from sprayplan.export.job_files import OUTPUT_FOLDERS

    paths = [(os.path.join(outdir, name), option) for name in names]
    check_outputs([p for p, name in zip(paths, names) if name not in OUTPUT_FOLDERS], inputs)
    check_outputs([p for p, name in zip(paths, names) if name in OUTPUT_FOLDERS], inputs, folder=True)


def file_input(value: str | None) -> str | None:
    """An option that names either a preset or a file (``--robot``, ``--tool``, ``--process``): the file, if
    it is one."""
    return value if isinstance(value, str) and value and os.path.exists(value) else None


def check_count(option: str, value: int | None, least: int = 1) -> None:
    """A whole-number option the command line uses itself: at least ``least``."""
    if value is not None and value < least:
        raise ConfigError(f"{option}: must be a whole number >= {least}, got {value}")


def parse_numbers(option: str, text: str, count: int, what: str) -> tuple[float, ...]:
    """``'a,b,c'`` -> ``count`` finite numbers, or an error naming the option and what it wants."""
    try:
        values = tuple(float(v) for v in text.replace(" ", "").split(","))
    except ValueError:
        values = ()
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"{option}: give {count} finite numbers {what}, got {text!r}")
    return values


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
