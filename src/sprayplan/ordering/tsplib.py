"""Reader of TSPLIB95 instances (``.tsp``) and tours (``.opt.tour``) with 2-D coordinates.

Only what the benchmarks and tests need: ``NODE_COORD_SECTION`` with ``EUC_2D`` (or ``CEIL_2D``, ``ATT``,
``GEO``: their coordinates are read, the distance rule is not applied: :func:`read_tsplib` returns points) and
``TOUR_SECTION``. TSPLIB numbers nodes from 1; the arrays returned here are 0-based.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sprayplan.checks import check_input_file
from sprayplan.errors import PartFileError


def _sections(path: Path) -> tuple[dict[str, str], dict[str, list[str]]]:
    """Header keywords and the token lists of the data sections of a TSPLIB file."""
    check_input_file(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise PartFileError(path, f"cannot read the file ({exc.strerror or exc})") from None
    header: dict[str, str] = {}
    sections: dict[str, list[str]] = {}
    current: list[str] | None = None
    for raw in text.splitlines():
        line = raw.strip()
        if not line:
            continue
        if line == "EOF":
            break
        key = line.split(":", 1)[0].strip().upper()
        if key.endswith("_SECTION"):
            current = sections.setdefault(key, [])
            continue
        if ":" in line and current is None:
            header[key] = line.split(":", 1)[1].strip()
            continue
        if current is None:
            raise PartFileError(path, f"unexpected line outside any section: {line[:60]!r}")
        current.extend(line.split())
    return header, sections


def _read_coords(path: Path) -> np.ndarray:
    header, sections = _sections(path)
    tokens = sections.get("NODE_COORD_SECTION")
    if tokens is None:
        raise PartFileError(path, "no NODE_COORD_SECTION (only coordinate instances are supported)")
    if len(tokens) % 3:
        raise PartFileError(path, "NODE_COORD_SECTION must hold 'index x y' triples")
    try:
        table = np.array(tokens, dtype=float).reshape(-1, 3)
    except ValueError:
        raise PartFileError(path, "NODE_COORD_SECTION holds a value that is not a number") from None
    index = table[:, 0].astype(int) - 1
    n = len(table)
    if "DIMENSION" in header and int(header["DIMENSION"]) != n:
        raise PartFileError(path, f"DIMENSION says {header['DIMENSION']} nodes, NODE_COORD_SECTION has {n}")
    if not np.array_equal(np.sort(index), np.arange(n)):
        raise PartFileError(path, "node numbers must be 1..n, each once")
    points = np.empty((n, 2))
    points[index] = table[:, 1:]
    return points


def _read_tour(path: Path, n: int) -> np.ndarray:
    _, sections = _sections(path)
    tokens = sections.get("TOUR_SECTION")
    if tokens is None:
        raise PartFileError(path, "no TOUR_SECTION")
    try:
        values = [int(t) for t in tokens]
    except ValueError:
        raise PartFileError(path, "TOUR_SECTION holds a value that is not an integer") from None
    if -1 in values:
        values = values[: values.index(-1)]
    tour = np.array(values, dtype=np.intp) - 1
    if len(tour) != n or not np.array_equal(np.sort(tour), np.arange(n)):
        raise PartFileError(path, f"the tour is not a permutation of the instance's {n} nodes")
    return tour


def read_tsplib(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a TSPLIB instance and, if it lies beside it, its optimal tour.

    Parameters
    ----------
    path : str or os.PathLike
        A ``NAME.tsp`` file. ``NAME.opt.tour`` in the same folder, if present, is read too.

    Returns
    -------
    points : (n, 2) float
        Node coordinates, 0-based in TSPLIB's node order.
    optimum_tour : (n,) int or None
        The optimal tour as a 0-based permutation, or None when there is no ``.opt.tour`` file.

    Raises
    ------
    PartFileError
        If a file cannot be read or is not a coordinate instance / a permutation tour.
    """
    path = Path(path)
    points = _read_coords(path)
    name = path.name[: -len(".tsp")] if path.name.endswith(".tsp") else path.stem
    tour_path = path.with_name(name + ".opt.tour")
    tour = _read_tour(tour_path, len(points)) if tour_path.is_file() else None
    return points, tour
