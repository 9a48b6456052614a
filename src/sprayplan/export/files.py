"""Writers for result files. Every file is written to a temporary name and renamed when complete, so a failure
never leaves a partial output file behind."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np

from sprayplan.errors import PartFileError
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

    name = os.fspath(path)
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
