"""What the viewer and the report draw: a plan, its film (or its bare part) and its summaries, gathered once from
a finished job (:func:`scene_from_result`) or from a plan folder on disk (:func:`scene_from_folder`); both give
the same scene for the same plan, so ``sprayplan view OUT/`` draws what ``sprayplan plan -o OUT`` drew."""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import numpy as np

from sprayplan.errors import InputError, PartFileError
from sprayplan.types import Plan, read_only

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Surface:
    """A surface to draw: vertices (mm), triangles over them ((0, 3) for a point cloud), unit normals at the
    vertices, the area each vertex stands for (mm^2) and the film at each (um; None for a bare part)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    area_mm2: np.ndarray
    thickness_um: np.ndarray | None = None

    def __post_init__(self):
        read_only(self)


@dataclass(frozen=True)
class Scene:
    """Everything a picture of a plan shows.

    Attributes
    ----------
    name : str
        The part's name.
    plan : Plan
    job : config.JobConfig
        The settings the plan was made with (the speeds, the robot, the film's spec).
    totals : dict
        plan.json's totals.
    surface : Surface or None
        The film on the part's surface samples, or the bare part when no film was simulated (None when
        neither is at hand: a folder whose part file is gone).
    film : dict or None
        The film's report (coating.json: ``spec``, ``painted``, ``all``, ``measuring_points`` with their
        ``indices`` into the surface's vertices, ``paint``); None without a film.
    target_um, tolerance_um : float
        The film's spec (50 +- 5 um without a target, as coating.json's).
    painted_fraction : float
        A vertex with at least this share of the target counts as painted (coating.json's).
    working_radius_mm : float
        The radius of a gantry station's working circle (the arm's working cylinder).
    notes : tuple of str
        What the pictures cannot show (no film simulated, the part file missing).
    """

    name: str
    plan: Plan
    job: object
    totals: dict
    surface: Surface | None
    film: dict | None
    target_um: float
    tolerance_um: float
    painted_fraction: float
    working_radius_mm: float
    notes: tuple = ()
    timing: object = None

    @property
    def painted(self) -> np.ndarray | None:
        """(n,) bool: the surface's painted vertices (coating.json's rule), or None without a film."""
        s = self.surface
        if s is None or s.thickness_um is None:
            return None
        return (s.area_mm2 > 0) & (s.thickness_um >= self.painted_fraction * self.target_um)

    @property
    def measuring_points(self) -> np.ndarray | None:
        """Indices of seed 003's measuring points into the surface's vertices, when the plan asked for them."""
        if self.film is None or self.surface is None or self.surface.thickness_um is None:
            return None
        table = self.film.get("measuring_points")
        if not isinstance(table, dict) or "indices" not in table:
            return None
        return np.asarray(table["indices"], dtype=np.int64)


def vertex_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """A third of the area of every triangle at each vertex, mm^2 (``coating.sampling``'s weights for a mesh)."""
    out = np.zeros(len(vertices))
    if len(faces):
        tri = vertices[faces]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        np.add.at(out, faces.ravel(), np.repeat(area / 3.0, 3))
    return out


def _spec(job, film: dict | None) -> tuple[float, float, float]:
    if film is not None and isinstance(film.get("spec"), dict):
        spec = film["spec"]
        return float(spec["target_um"]), float(spec["tolerance_um"]), float(spec.get("painted_fraction", 0.1))
    target = job.coating.thickness_um if job.coating.thickness_um is not None else 50.0
    return float(target), float(job.coating.tolerance_um), 0.1


def _working_radius(job) -> float:
    from sprayplan.robots.stage import gantry_for

    return float(gantry_for(job.kinematics).workspace.radius_mm)


def _bare(part) -> Surface:
    vertices = np.asarray(part.vertices, float)
    faces = np.asarray(part.faces, np.int64).reshape(-1, 3)
    normals = getattr(part, "vertex_normals", None)
    if normals is None or len(normals) != len(vertices):
        normals = vertex_normals(vertices, faces)
    area = vertex_areas(vertices, faces) if len(faces) else np.ones(len(vertices))
    return Surface(vertices, faces, np.asarray(normals, float), area)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) unit normals at the vertices: the sum of the area-weighted normals of their triangles."""
    out = np.zeros_like(vertices)
    if len(faces):
        tri = vertices[faces]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        for k in range(3):
            np.add.at(out, faces[:, k], n)
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, length, out=np.zeros_like(out), where=length > 0)


def make_scene(
    plan, job, totals: dict, film=None, report: dict | None = None, part=None, notes=(), timing=None
) -> Scene:
    """A scene from a plan and its settings, its film (``coating.CoatingResult``, or None: the bare ``part``
    is drawn grey) and the film's report (computed when None); ``timing``: its time stamps and achievable
    speeds (``timing.stage.PlanTiming`` or ``export.plan_read.WaypointTimes``), when it was timed."""
    notes = list(notes)
    surface = None
    if film is not None:
        if report is None:
            from sprayplan.export.film import film_report

            report = film_report(film, job, job.output.samples)
        faces = np.asarray(film.faces, np.int64).reshape(-1, 3)
        surface = Surface(film.points, faces, film.normals, film.area_mm2, film.thickness_um)
    else:
        report = None
        notes.append(NO_FILM)
        if part is not None:
            surface = _bare(part)
    return _scene(plan, job, totals, surface, report, notes, timing)


def _scene(plan, job, totals: dict, surface: Surface | None, report: dict | None, notes, timing=None) -> Scene:
    target, tolerance, painted = _spec(job, report)
    name = os.path.basename(plan.name)
    return Scene(
        name,
        plan,
        job,
        dict(totals),
        surface,
        report,
        target,
        tolerance,
        painted,
        _working_radius(job),
        tuple(notes),
        _times_only(timing),
    )


def _times_only(timing):
    """What the pictures take of a plan's timing: its time stamps and achievable speeds (the same from a job
    and from plan.json)."""
    if timing is None:
        return None
    from sprayplan.export.plan_read import WaypointTimes

    return WaypointTimes(tuple(timing.t_s), tuple(timing.speed_mm_s))


NO_FILM = "no film was simulated: the part is drawn grey (plan with --simulate or --thickness-um)"


def scene_from_result(result, report: dict | None = None) -> Scene:
    """The scene of a finished job (``job.JobResult``); ``report``: its film's report when already computed
    (``export.film.film_report``)."""
    if result.film is not None and report is None:
        from sprayplan.export.film import film_report

        report = film_report(result.film, result.job, result.job.output.samples, result.chosen)
    return make_scene(
        result.plan, result.job, result.totals, result.film, report, result.part, timing=getattr(result, "timing", None)
    )


def scene_from_folder(folder: str | os.PathLike) -> Scene:
    """The scene of a plan folder: its plan.json, and its thickness.ply and coating.json when it has them (a
    film from ``sprayplan plan`` or ``sprayplan simulate``; else the part file plan.json names, loaded with the
    plan's settings and cut to its region, drawn grey).

    Raises
    ------
    InputError
        ``folder`` is not a folder, or holds no plan.json.
    PartFileError
        plan.json (or a film file) is broken or of another version, naming the file.
    """
    from sprayplan.export.film import read_thickness_ply
    from sprayplan.export.plan_read import read_plan_file

    given = os.fspath(folder)
    if not os.path.isdir(given):
        raise InputError(
            f"{given}: not a plan folder ({'no such folder' if not os.path.exists(given) else 'not a folder'})"
        )
    plan_path = os.path.join(given, "plan.json")
    if not os.path.exists(plan_path):
        raise InputError(f"{given}: not a plan folder (no plan.json in it)")
    read = read_plan_file(plan_path)
    job = read.job
    ply, coating = os.path.join(given, "thickness.ply"), os.path.join(given, "coating.json")
    notes = []
    surface, report = None, None
    present = [os.path.exists(p) for p in (ply, coating)]
    if all(present):
        report = _read_coating(coating)
        film = read_thickness_ply(ply)
        area = film.area_mm2 if film.area_mm2 is not None else vertex_areas(film.points, film.faces)
        surface = Surface(film.points, film.faces, film.normals, area, film.thickness_um)
        _check_indices(report, len(film.points), coating)
    else:
        if any(present) or read.film is not None:
            missing = " and ".join(os.path.basename(p) for p, here in zip((ply, coating), present) if not here)
            notes.append(f"{missing} missing: the film cannot be drawn, the part is drawn grey")
        else:
            notes.append(NO_FILM)
        surface = _part_from_file(read.part_file, job, notes)
    return _scene(read.plan, job, read.totals, surface, report, notes, read.timing)


def _read_coating(path: str) -> dict:
    import json

    from sprayplan.checks import check_input_file

    name = check_input_file(path)
    try:
        with open(path, encoding="utf-8") as handle:
            data = json.load(handle)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise PartFileError(name, f"not a coating.json ({type(exc).__name__}: {exc})") from None
    spec = data.get("spec") if isinstance(data, dict) else None
    if not (
        isinstance(spec, dict)
        and all(isinstance(spec.get(k), int | float) for k in ("target_um", "tolerance_um"))
        and spec["target_um"] > 0
        and spec["tolerance_um"] >= 0
    ):
        raise PartFileError(name, "not a coating.json (no spec with a positive target_um and a tolerance_um)")
    return data


def _check_indices(report: dict, n: int, path: str) -> None:
    table = report.get("measuring_points")
    if isinstance(table, dict) and "indices" in table:
        index = np.asarray(table["indices"])
        if index.ndim != 1 or (len(index) and (index.dtype.kind not in "iu" or index.min() < 0 or index.max() >= n)):
            raise PartFileError(path, f"measuring_points.indices are not indices of thickness.ply's {n} vertices")


def _part_from_file(part_file: str | None, job, notes: list) -> Surface | None:
    from sprayplan.io.load import load_part
    from sprayplan.surface.region import painted_surface, select_region

    if not part_file:
        notes.append("the plan was made from a part in memory: the part is not drawn")
        return None
    if not os.path.isfile(part_file):
        notes.append(f"the part file {part_file} is gone: the part is not drawn")
        return None
    try:
        part = select_region(load_part(part_file, units=job.load.units, up=job.load.up), job.load.region)
        # the surface the plan paints, as its region stage cut it
        part, _ = painted_surface(part, job.collision, job.load.mask)
    except InputError as exc:
        notes.append(f"the part file could not be read again ({exc}): the part is not drawn")
        return None
    return _bare(part)
