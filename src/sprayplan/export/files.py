"""Writers for result files, and how outputs are put in place: all or nothing.

Every file is written to a temporary name and renamed when complete (:func:`atomic_output`), so a failure never
leaves a partial output file behind. A command's outputs go in as a set: :func:`staged_files` (single files:
``targets -o``, ``paths -o --table``) and :func:`staged_folder` (a job's folder: ``plan -o``, ``demo``,
``simulate``) write them all beside their places first and move them in only when every one is written; an
existing output is replaced only then, and left as it was when anything fails. :func:`check_output` and
:func:`refuse_inputs` are the checks a command makes on its outputs before it runs.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

import numpy as np

from sprayplan.checks import check_input_file
from sprayplan.errors import OutputError, PartFileError
from sprayplan.types import Targets


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, mode: str = "w", **kwargs):
    """Open ``path`` for writing through a temporary file that replaces it only on success.

    Parents are created as needed. On any exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.part")
    try:
        with open(tmp, mode, **kwargs) as handle:
            yield handle
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def os_problem(exc: OSError) -> str:
    """An OS error in words, without the path (the message names the path itself)."""
    return exc.strerror or str(exc) or type(exc).__name__


def check_output(path: str | os.PathLike, folder: bool = False) -> None:
    """Check, before a command runs, that ``path`` can take its output (a file, or a folder with ``folder``).

    Raises
    ------
    OutputError
        Naming ``path``: an empty path, a folder where a file goes (or the other way round), a device or pipe,
        a parent that is a file, a parent that cannot be written.
    """
    name = os.fspath(path)
    if not name:
        raise OutputError("''", "an empty path")
    target = Path(name)
    if target.exists():
        if folder and not target.is_dir():
            raise OutputError(name, "exists and is not a folder (give a folder for the outputs)")
        if not folder and target.is_dir():
            raise OutputError(name, "is a folder (give a file name)")
        if not folder and not target.is_file():
            raise OutputError(name, "is not a regular file")
    parent = Path(os.path.abspath(name)).parent
    while not parent.exists() and not parent.is_symlink():
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(name, f"{parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(name, f"cannot write in {parent} (permission denied)")


def _same(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """True when the two paths are one file (after links and ``..``), existing or not."""
    with contextlib.suppress(OSError):
        if os.path.samefile(a, b):
            return True
    return os.path.realpath(a) == os.path.realpath(b)


def refuse_inputs(outputs, inputs) -> None:
    """Refuse outputs that are inputs too (or the same output twice), before anything runs.

    Parameters
    ----------
    outputs : iterable of (path, label)
        Every file the command will write, and how the user named it (``-o``, ``--table``, ...).
    inputs : iterable of (path, label)
        Every file it reads (None entries are skipped).

    Raises
    ------
    OutputError
        Naming the output: it is the input given as ``label``.
    """
    outputs = [(p, label) for p, label in outputs if p]
    inputs = [(p, label) for p, label in inputs if p]
    for i, (out, label) in enumerate(outputs):
        for source, source_label in inputs:
            if _same(out, source):
                raise OutputError(out, f"the output ({label}) is also the input {source_label}: give another output")
        for other, other_label in outputs[:i]:
            if _same(out, other):
                raise OutputError(out, f"given twice, as {other_label} and {label}")


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; returns those created, outermost first."""
    missing = []
    while not folder.exists() and not folder.is_symlink():
        missing.append(folder)
        folder = folder.parent
    for made in reversed(missing):
        made.mkdir()
    return list(reversed(missing))


def _remove_made(made: list[Path]) -> None:
    for folder in reversed(made):
        with contextlib.suppress(OSError):
            folder.rmdir()


def _place(moves) -> None:
    """Move each ``(new, final, aside)`` into place (``new`` None: remove ``final``), an old ``final`` moved into
    the folder ``aside`` first; on any failure everything is put back as it was."""
    moved, placed = [], []
    try:
        for k, (new, final, aside) in enumerate(moves):
            if final.exists() or final.is_symlink():
                old = aside / f".{k}.old"
                os.rename(final, old)
                moved.append((old, final))
            if new is not None:
                os.rename(new, final)
                placed.append(final)
    except BaseException as exc:
        for final in reversed(placed):
            with contextlib.suppress(OSError):
                if final.is_dir() and not final.is_symlink():  # a folder of outputs (report/)
                    shutil.rmtree(final)
                else:
                    os.unlink(final)
        for old, final in reversed(moved):
            try:
                os.rename(old, final)
            except OSError:  # cannot be put back: keep it where it is, and say where
                problem = os_problem(exc) if isinstance(exc, OSError) else type(exc).__name__
                raise _Stranded(final, f"cannot write ({problem}); the previous file is kept as {old}") from exc
        raise


class _Stranded(OutputError):
    """A move failed and an old output could not be put back: its temporary folder must be kept."""


def _fresh_folder(parent: Path, name: str, suffix: str) -> Path:
    """Create a new hidden folder ``.NAME.PID.SUFFIX`` in ``parent`` (numbered when taken); the umask applies."""
    for k in range(1000):
        folder = parent / f".{name}.{os.getpid()}{'' if k == 0 else f'.{k}'}.{suffix}"
        try:
            folder.mkdir()
            return folder
        except FileExistsError:
            continue
    raise FileExistsError(f"{parent / name}: no free temporary name beside it")


def _output_error(exc: OSError, name: str) -> OutputError:
    return OutputError(name, f"cannot write ({os_problem(exc)})")


@contextlib.contextmanager
def staged_files(paths):
    """Write a set of files all or nothing: yields one temporary path per path (beside it) to write to.

    When the block ends without an exception every file is moved into place (an existing one is replaced only
    then); when it raises, or a move fails, no path is created or changed and the temporary files are removed.
    Missing parent folders are created (and removed again on failure).

    Raises
    ------
    OutputError
        For an OS error while writing or moving, naming the output it was about.
    """
    names = [os.fspath(p) for p in paths]
    finals = [Path(name) for name in names]
    made: list[Path] = []
    stages: list[Path] = []
    name = names[0] if names else ""
    try:
        for final, given in zip(finals, names):
            name = given  # named if creating its folder fails
            made += _make_parents(final.parent)
            stages.append(_fresh_folder(final.parent, final.name, "tmp"))
        temps = [stage / final.name for stage, final in zip(stages, finals)]
        name = names[0] if names else ""
        try:
            yield temps
        except OSError as exc:
            name = _named(exc, zip(stages, names), name)
            raise
        for temp, name in zip(temps, names):
            if not temp.exists():
                raise OutputError(name, "was not written")
        name = ", ".join(names)
        _place(list(zip(temps, finals, stages)))
    except OSError as exc:
        _cleanup(stages, made)
        raise _output_error(exc, name) from exc
    except BaseException as exc:
        _cleanup(stages, made, exc)
        raise
    _cleanup(stages, [])


def _named(exc: OSError, pairs, default: str) -> str:
    """The output an OS error on a temporary file was about."""
    if exc.filename is not None:
        where = Path(os.fspath(exc.filename)).parent
        for stage, name in pairs:
            if where == stage:
                return name
    return default


def _cleanup(stages, made, exc: BaseException | None = None) -> None:
    if isinstance(exc, _Stranded):
        return  # the previous output is in there
    for stage in stages:
        shutil.rmtree(stage, ignore_errors=True)
    _remove_made(made)


@contextlib.contextmanager
def staged_folder(folder: str | os.PathLike, own: tuple[str, ...], whole: bool = True):
    """Write a folder's outputs all or nothing: yields a temporary folder beside ``folder`` to write them into.

    When the block ends without an exception the written files are moved into ``folder``:

    - ``folder`` missing: the temporary folder becomes it;
    - ``folder`` holding nothing but files named in ``own`` (an earlier run's outputs) and ``whole``: it is
      replaced as a whole (the old one moved aside, the new one moved in, then the old one deleted), so no
      earlier output is left beside the new ones;
    - otherwise (other files in it, the working folder, or not ``whole``): the new files replace their
      namesakes, the other ``own`` files there are removed, and every other file is left alone.

    When the block raises, or a move fails, ``folder`` is left byte for byte as it was (restored), nothing is
    created, and the temporary folder is removed.

    Raises
    ------
    OutputError
        For an OS error while writing or moving, naming ``folder`` (or the file in it).
    """
    given = os.fspath(folder)
    target = Path(os.path.realpath(given))
    made: list[Path] = []
    stage = None
    try:
        made = _make_parents(target.parent)
        stage = _fresh_folder(target.parent, target.name, "tmp")
        try:
            yield stage
        except OSError as exc:
            raise _output_error(exc, given) from exc
        _commit_folder(stage, target, own, whole)
    except OSError as exc:
        _cleanup([stage] if stage else [], made)
        raise _output_error(exc, given) from exc
    except BaseException as exc:
        _cleanup([stage] if stage else [], made, exc)
        raise
    _cleanup([stage] if stage.exists() else [], [])


def _commit_folder(stage: Path, target: Path, own: tuple[str, ...], whole: bool) -> None:
    if not (target.exists() or target.is_symlink()):
        os.rename(stage, target)
        return
    if not target.is_dir():
        raise OutputError(target, "exists and is not a folder")
    present = sorted(os.listdir(target))
    cwd = Path.cwd().resolve()
    in_use = cwd == target or target in cwd.parents
    if whole and not in_use and set(present) <= set(own):
        aside = _fresh_folder(target.parent, target.name, "old")
        os.rename(target, aside / "old")
        try:
            os.rename(stage, target)
        except BaseException as exc:
            try:
                os.rename(aside / "old", target)
            except OSError:  # cannot be put back: keep it where it is, and say where
                problem = os_problem(exc) if isinstance(exc, OSError) else type(exc).__name__
                raise _Stranded(target, f"cannot write ({problem}); the previous folder is kept as {aside}") from exc
            shutil.rmtree(aside, ignore_errors=True)
            raise
        shutil.rmtree(aside, ignore_errors=True)
        return
    new = sorted(os.listdir(stage))
    stale = [name for name in present if name in own and name not in new]
    aside = stage / ".old"
    aside.mkdir()
    _place([(stage / name, target / name, aside) for name in new] + [(None, target / name, aside) for name in stale])


def write_targets_csv(path: str | os.PathLike, targets: Targets) -> None:
    """Write targets as CSV with the header ``x,y,z,nx,ny,nz`` (mm, unit outward normals), one row a point."""
    table = np.hstack([targets.points, targets.normals])
    with atomic_output(path, "w", newline="") as handle:
        handle.write("x,y,z,nx,ny,nz\n")
        np.savetxt(handle, table, fmt=["%.6f"] * 3 + ["%.9f"] * 3, delimiter=",")


def read_targets_csv(path: str | os.PathLike) -> Targets:
    """Read a CSV written by :func:`write_targets_csv`."""
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return Targets(table[:, :3], table[:, 3:6])


def read_json_file(path: str | os.PathLike, fmt: str, what: str, versions: tuple[int, ...] | None = None) -> dict:
    """Read a sprayplan JSON file and check its ``"format"`` (and its ``"version"`` when ``versions`` is given).

    Raises
    ------
    PartFileError
        When the file is missing, not JSON, not of that format, or of a version not in ``versions`` (``what``
        names it in the message, which lists the versions read).
    """
    import json

    name = check_input_file(path)  # a folder or a named pipe is refused before it is opened
    try:
        with open(path, encoding="utf-8") as handle:
            data = json.load(handle)
    except FileNotFoundError:
        raise PartFileError(name, "no such file") from None
    except (OSError, ValueError) as exc:
        raise PartFileError(name, f"not a readable JSON file ({exc})") from None
    reads = "" if versions is None else f", version {' or '.join(map(str, versions))}"
    if not isinstance(data, dict) or data.get("format") != fmt:
        raise PartFileError(name, f'not a sprayplan {what} file (expected "format": "{fmt}"{reads})')
    version = data.get("version")
    if versions is not None and not (type(version) is int and version in versions):
        raise PartFileError(
            name, f"{what} file version {version!r}: this sprayplan reads version {' or '.join(map(str, versions))}"
        )
    return data
