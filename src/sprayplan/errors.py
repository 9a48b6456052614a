"""The few exception types a user of sprayplan can meet.

Bad input (a broken file, a bad option, an empty region, an output path that cannot be written) raises an
:class:`InputError`; the command line turns it into a one-line message and exit code 2. Failures that are
expected inside a plan (an unreachable waypoint) are never exceptions: they are data in the stage's result.
"""

from __future__ import annotations

import os


class SprayplanError(Exception):
    """Base class of every exception sprayplan raises on purpose."""


class InputError(SprayplanError, ValueError):
    """The user's input cannot be used: the message says what is wrong and where."""


class PartFileError(InputError):
    """A part file is missing, empty, of an unknown kind, or its content is broken.

    Parameters
    ----------
    path : str or os.PathLike
        The file, named first in the message.
    problem : str
        What is wrong, in words a user can act on.
    """

    def __init__(self, path: str | os.PathLike, problem: str):
        self.path = os.fspath(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class ConfigError(InputError):
    """An option or a configuration value is out of range or inconsistent."""


class RegionError(InputError):
    """A region expression cannot be parsed, or it selects nothing of the part."""


class StageError(InputError):
    """Bad input found inside a stage of the main job (``sprayplan.job``): names the stage and the part.

    Parameters
    ----------
    stage : str
        The stage's name (``load``, ``paths``, ...).
    part : str
        The part's name or file.
    cause : InputError
        What the stage raised; its message follows the stage's name (and the part's, when the message does
        not name it already).
    """

    def __init__(self, stage: str, part: str, cause: Exception):
        self.stage = stage
        self.part = part
        self.cause = cause
        message = str(cause)
        where = stage if not part or part in message else f"{stage}: {part}"
        super().__init__(f"{where}: {message}")


class DataError(InputError):
    """An array or value handed to a function is malformed: not numbers, the wrong shape, NaN or inf, too few."""


class OutputError(InputError):
    """An output path cannot be used: missing, a folder where a file is wanted, unwritable, or an input too.

    Parameters
    ----------
    path : str or os.PathLike
        The output as the user named it, first in the message.
    problem : str
        What is wrong with it.
    """

    def __init__(self, path: str | os.PathLike, problem: str):
        self.path = os.fspath(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
