"""The film of a cell plan reported (``cells.plan.plan_cell``'s ``report["film"]``): over the whole body, per
area, per robot, along every seam and at seed 003's measuring points (:func:`film_report`), and the film the
robots leave at their timed speeds beside it (:func:`film_at_timed_speeds`, :func:`timed_film_summary`).

``plan`` is a ``cells.plan.CellPlan`` throughout (not imported: ``cells.plan`` imports this module)."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.cells.work import owned, runs_with_dwell
from sprayplan.surface.areas import face_adjacency
from sprayplan.types import Paths


def _stats(um: np.ndarray, area: np.ndarray, target: float, tol: float) -> dict:
    from sprayplan.coating.report import weighted_stats

    return weighted_stats(um, area, target - tol, target + tol)


def film_report(
    plan,
    target_um: float,
    tolerance_um: float,
    samples: int | None = 420,
    seed: int = 0,
    seams: bool = True,
    recess_mm: float | None = None,
) -> dict:
    """The film over the whole body, per area, per robot, over the surface some robot reaches (``reached``,
    the robots' shares together) and the surface none reaches (``unreached``), and (with ``seams``) along every
    seam (the samples within one spray radius of an edge between two robots' faces), and ``samples`` measuring
    points over the whole body (``coating.report.coating_report``; seed 003 measured 420).

    With ``recess_mm`` (the plan gives the gun's standoff plus the collision clearance) also over the
    ``recessed`` surface, the faces with the body (``CellPlan.collision_part``) in front of them within
    ``recess_mm`` along the outward normal (``surface.region.faces_in_front``: the floor and walls of an air
    intake, the walls of a door gap, a panel's back facing the body), where no gun can be held square at its
    standoff, and over the rest (``open``, with ``recess_mm``), and over the part of that some robot reaches
    (``open_reached``: what the cell can paint with a gun held square, apart from what its arms leave out),
    and the surface out of spec by cause (``out_of_spec``, :func:`out_of_spec`)."""
    from sprayplan.coating.report import coating_report

    film = plan.film
    um = film.thickness_um
    area = film.area_mm2
    # each film sample belongs to a face of the part it lies on (samples are the vertices of the subdivided
    # mesh, shared by neighbouring faces: at an area's edge either face is as right); a film without them
    # (read back, or of given targets) to the face whose centroid is nearest, which on a coarse mesh (the
    # SUV's triangles are up to 1.2 m long) puts many samples on a neighbouring face
    face = film.part_face
    if face is None or len(face) != len(film.points) or (face < 0).any() or (face >= len(plan.part.faces)).any():
        face = cKDTree(plan.part.triangles.mean(axis=1)).query(film.points)[1]
    area_of = plan.areas.face_area[face]
    robot_of = plan.assignment.face_robot[face]
    whole = coating_report(film, target_um, tolerance_um, samples=samples, seed=seed)
    out = {"whole": _stats(um, area, target_um, tolerance_um), "report": whole}
    out["per_area"] = {
        name: {
            **_stats(um[area_of == k], area[area_of == k], target_um, tolerance_um),
            "robot": _robot_name(plan, int(plan.assignment.area_robot[k])),
        }
        for k, name in enumerate(plan.areas.names)
    }
    out["per_robot"] = {
        r.name: _stats(um[robot_of == i], area[robot_of == i], target_um, tolerance_um)
        for i, r in enumerate(plan.cell.robots)
    }
    out["reached"] = _stats(um[robot_of >= 0], area[robot_of >= 0], target_um, tolerance_um)
    out["unreached"] = _stats(um[robot_of < 0], area[robot_of < 0], target_um, tolerance_um)
    if recess_mm is not None:
        from sprayplan.surface.region import faces_in_front

        recessed = faces_in_front(plan.part, recess_mm, obstacle=plan.collision_part)[face]
        out["open"] = {**_stats(um[~recessed], area[~recessed], target_um, tolerance_um), "recess_mm": recess_mm}
        out["recessed"] = _stats(um[recessed], area[recessed], target_um, tolerance_um)
        both = ~recessed & (robot_of >= 0)
        out["open_reached"] = _stats(um[both], area[both], target_um, tolerance_um)
        out["out_of_spec"] = out_of_spec(um, area, robot_of >= 0, recessed, target_um, tolerance_um)
    if not seams:
        return out
    pairs, _ = face_adjacency(plan.part.faces, plan.part.vertices)
    fr = plan.assignment.face_robot
    a, b = fr[pairs[:, 0]], fr[pairs[:, 1]]
    seam = (a != b) & (a >= 0) & (b >= 0)
    seams = {}
    if seam.any():
        centres = plan.part.triangles.mean(axis=1)
        mids = (centres[pairs[seam, 0]] + centres[pairs[seam, 1]]) / 2.0
        key = np.sort(np.stack([a[seam], b[seam]], axis=1), axis=1)
        radius = plan_radius(plan)
        for u, v in np.unique(key, axis=0):
            these = mids[(key[:, 0] == u) & (key[:, 1] == v)]
            near = cKDTree(these).query(film.points, distance_upper_bound=radius)[0] <= radius
            name = f"{_robot_name(plan, int(u))}/{_robot_name(plan, int(v))}"
            seams[name] = {**_stats(um[near], area[near], target_um, tolerance_um), "band_mm": radius}
    out["per_seam"] = seams
    return out


#: A film below this fraction of the target is bare (:func:`out_of_spec`): no stroke's spray reaches it.
BARE_FRACTION = 0.1


def out_of_spec(
    um: np.ndarray, area: np.ndarray, reached: np.ndarray, recessed: np.ndarray, target_um: float, tolerance_um: float
) -> dict:
    """The share of the whole area (``area``, the samples' areas) out of ``target_um`` +- ``tolerance_um``,
    split by cause, each sample out of spec counted once, under the first that holds: on surface no robot
    reaches (``unreached``: ``reached`` false), on recessed surface (``recessed``: no gun held square at its
    standoff), bare (``bare``: under :data:`BARE_FRACTION` of the target on open, reached surface: left out by
    the collision step or between the strokes), below the spec (``thin``), above it (``thick``). The five and
    the whole's share in spec add up to 1: what a person fixing the plan looks at first (a reach or a cell
    layout for ``unreached``, a hand-taught touch-up for ``recessed``, the strokes and the speeds for the
    rest)."""
    total = float(area.sum())
    lo, hi = target_um - tolerance_um, target_um + tolerance_um
    left = (um < lo) | (um > hi)
    out = {"rule": f"first of: unreached, recessed, bare (under {BARE_FRACTION:g} of the target), thin, thick"}
    for name, these in (
        ("unreached", ~reached),
        ("recessed", recessed),
        ("bare", um < BARE_FRACTION * target_um),
        ("thin", um < lo),
        ("thick", um > hi),
    ):
        mine = left & these
        out[name] = float(area[mine].sum() / total) if total > 0 else 0.0
        left &= ~these
    return out


def film_at_timed_speeds(plan, owners, tuning, strokes, process, coating):
    """The film the robots leave at their timed speeds (``plan.robots``' ``t_s``, :func:`~sprayplan.cells.
    timing.timed_factors`): the reached runs the film was predicted from (``owners``, as :func:`reached_strokes`
    gave them; ``strokes`` their strokes when there was no tuning) with the time factors of the timed speeds,
    from the last tuning's deposit matrix (``tuning``), or simulated anew without one."""
    from sprayplan.cells.timing import timed_factors

    runs = tuning.paths.strokes if tuning is not None else strokes
    timed = runs_with_dwell(runs, owned(timed_factors(plan.robots, plan.job), plan.robots, owners))
    paths = Paths(timed, plan.job.paths.standoff_mm, plan.job.paths.spacing or 0.0, plan.part.name)
    if tuning is not None:
        from sprayplan.refine.tuning import tuned_film

        return tuned_film(dataclasses.replace(tuning, paths=paths), process, coating)
    from sprayplan.coating.thickness import simulate

    return simulate(plan.part, paths, process, config=coating)


def timed_film_summary(plan, target_um: float, tolerance_um: float, points) -> dict:
    """The film at the timed speeds in brief (``plan.film``): over the whole body, per robot, and at the
    planned film's measuring points (``points``: their sample indices, so that both are measured at the same
    places)."""
    from sprayplan.coating.report import measured_stats

    full = film_report(plan, target_um, tolerance_um, samples=None, seams=False)
    at = np.asarray(points, dtype=np.int64)
    return {
        "rule": "each waypoint's time factor from the timed arrival times (the planned one off the timed stretches)",
        "whole": full["whole"],
        "per_robot": full["per_robot"],
        "measuring_points": measured_stats(
            plan.film.thickness_um[at], target_um - tolerance_um, target_um + tolerance_um
        ),
    }


def plan_radius(plan) -> float:
    return float(plan.report.get("spray_radius_mm", 50.0))


def _robot_name(plan, i: int) -> str:
    return plan.cell.robots[i].name if i >= 0 else ""
