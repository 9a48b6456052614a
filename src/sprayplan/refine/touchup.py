"""Touch-up strokes: extra passes aimed at the patches the plan leaves under-painted.

Tuning the speeds (``tuning``) can only move paint the strokes deliver. A surface that faces away from
every stroke, such as a rolled lip, a flange turned down or a step under a styling line, gets grazing spray
whatever the speeds. A painter touches such places up with a pass aimed at them, and this module does the
same from the simulated film:

1. The under-painted samples (film below target - tolerance, among the samples tuned for) are joined into
   patches. Two samples are joined when they are neighbours (a mesh edge, or for a cloud two points within
   twice the median spacing) and their normals differ by less than ``max_turn_deg``, so a patch faces one
   way.
2. Every patch of at least ``min_area_mm2`` becomes one stroke along its longest extent (the principal axis
   of its points, area-weighted). Each waypoint sits at the area-weighted centroid of the patch's samples
   within one step of it along the axis (near the surface, not on it: ``on_part`` is False), aims along
   their mean normal (smoothed over five waypoints), and stands ``standoff`` off it. Straight leads of
   ``lead_mm`` extend both ends.

The strokes are returned with ``kind = "touch-up"``. The main job then runs each one from the nearest
station and tunes all speeds again; a touch-up's time factors may go down to ``TOUCH_UP_MIN_DWELL``, so a
pass that turns out to do more harm than good is run fast and paints little.

A patch that curls round more than a quarter turn in the plane of its principal axes gets one straight-ish
stroke along its main extent, which serves it less well. Patches are not split.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import sparse
from scipy.ndimage import uniform_filter1d
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from sprayplan.coating.sampling import SurfaceSamples
from sprayplan.surface import normals as nm
from sprayplan.types import Stroke

#: The smallest time factor the speed tuning may give a touch-up stroke's waypoints (20 times its speed).
TOUCH_UP_MIN_DWELL = 0.05


def touch_up_strokes(
    samples: SurfaceSamples,
    film_um: np.ndarray,
    tuned: np.ndarray,
    target_um: float,
    tolerance_um: float,
    *,
    standoff_mm: float,
    step_mm: float,
    lead_mm: float,
    min_area_mm2: float,
    max_turn_deg: float = 30.0,
) -> list[Stroke]:
    """Strokes aimed at the under-painted patches of a film (see the module docstring).

    Parameters
    ----------
    samples : SurfaceSamples
        Where the film is known (``tuning.Tuning.samples``).
    film_um : (n,) float
        The film there.
    tuned : (n,) bool
        The samples that count (the painted ones).
    target_um, tolerance_um : float
    standoff_mm, step_mm, lead_mm : float
        The strokes' standoff, waypoint spacing and lead length at each end.
    min_area_mm2 : float
        Smaller patches get no stroke.
    max_turn_deg : float
        Neighbours whose normals differ more are not joined.

    Returns
    -------
    list of Stroke
        Largest patch first.
    """
    under = tuned & (samples.area_mm2 > 0) & (film_um < target_um - tolerance_um)
    if not under.any():
        return []
    pairs = _neighbours(samples, under)
    similar = np.einsum("ij,ij->i", samples.normals[pairs[:, 0]], samples.normals[pairs[:, 1]]) > np.cos(
        np.radians(max_turn_deg)
    )
    pairs = pairs[similar]
    n = len(samples.points)
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    label = np.where(under, label, -1)
    patches = [np.flatnonzero(label == k) for k in np.unique(label[under])]
    patches = [p for p in patches if samples.area_mm2[p].sum() >= min_area_mm2]
    patches.sort(key=lambda p: -samples.area_mm2[p].sum())
    out = []
    for patch in patches:
        stroke = _patch_stroke(samples, patch, standoff_mm, step_mm, lead_mm)
        if stroke is not None:
            out.append(stroke)
    return out


def _neighbours(samples: SurfaceSamples, under: np.ndarray) -> np.ndarray:
    """(k, 2) int: neighbouring pairs of under-painted samples."""
    if len(samples.faces):
        f = samples.faces
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        return edges[under[edges[:, 0]] & under[edges[:, 1]]]
    index = np.flatnonzero(under)
    if len(index) < 2:
        return np.zeros((0, 2), np.int64)
    spacing = float(np.median(cKDTree(samples.points).query(samples.points[index], 2)[0][:, 1]))
    local = cKDTree(samples.points[index]).query_pairs(2.0 * spacing, output_type="ndarray")
    return index[local] if len(local) else np.zeros((0, 2), np.int64)


def _patch_stroke(samples: SurfaceSamples, patch: np.ndarray, standoff: float, step: float, lead: float):
    points, normals, area = samples.points[patch], samples.normals[patch], samples.area_mm2[patch]
    centre = np.average(points, axis=0, weights=area)
    _, _, axes = np.linalg.svd((points - centre) * np.sqrt(area)[:, None], full_matrices=False)
    axis = axes[0]
    coord = (points - centre) @ axis
    stations = np.arange(coord.min(), coord.max() + 0.5 * step, step)
    way_p, way_n = [], []
    for s in stations:
        near = np.abs(coord - s) <= step
        if near.any():
            way_p.append(np.average(points[near], axis=0, weights=area[near]))
            way_n.append(np.average(normals[near], axis=0, weights=area[near]))
    if len(way_p) < 2:
        return None
    way_p, way_n = np.array(way_p), np.array(way_n)
    if len(way_p) >= 5:
        way_p = uniform_filter1d(way_p, 5, axis=0, mode="nearest")
        way_n = uniform_filter1d(way_n, 5, axis=0, mode="nearest")
    way_n = nm.unit(way_n)
    keep = np.r_[True, np.linalg.norm(np.diff(way_p, axis=0), axis=1) > 1e-6]
    way_p, way_n = way_p[keep], way_n[keep]
    if len(way_p) < 2:
        return None
    start = nm.unit((way_p[0] - way_p[1])[None])[0]
    end = nm.unit((way_p[-1] - way_p[-2])[None])[0]
    count = max(1, int(np.ceil(lead / step))) if lead > 0 else 0
    offsets = lead * np.arange(1, count + 1) / max(count, 1)
    lead_in = (way_p[0] + offsets[:, None] * start)[::-1]
    lead_out = way_p[-1] + offsets[:, None] * end
    pts = np.vstack([lead_in, way_p, lead_out])
    nrm = np.vstack([np.repeat(way_n[:1], count, 0), way_n, np.repeat(way_n[-1:], count, 0)])
    # the waypoints are centroids near the patch, not points of the surface: on_part is False throughout
    return Stroke(pts, nrm, pts + standoff * nrm, True, np.zeros(len(pts), bool), -1, None, "touch-up")


#: Tilts tried for a touch-up's aim about its direction of travel, degrees (``aim_touch_ups``).
AIM_TILTS_DEG = (-40.0, -20.0, 0.0, 20.0, 40.0)

#: Time factors a candidate aim is scored at (the speed tuning rescales whichever is kept).
AIM_SCALES = (0.25, 0.5, 1.0, 2.0)


def tilted(stroke: Stroke, degrees: float, standoff_mm: float, across: bool = False) -> Stroke:
    """The stroke with its aim turned by ``degrees`` about its direction of travel at every waypoint (the
    waypoints stay; the gun moves round them at the standoff). Positive turns follow the right-hand rule
    about the direction of travel: at each waypoint the chord between its neighbours, or the stroke's
    overall direction where that chord is zero or along the normal. With ``across``, the turn is about the
    axis across the travel (normal x travel) instead: the gun leans forward or back along the stroke, a
    positive turn bringing the aim's axis toward the direction of travel. A stroke without a direction (fewer
    than two distinct waypoints) is returned unchanged."""
    overall = stroke.points[-1] - stroke.points[0] if len(stroke) else np.zeros(3)
    if degrees == 0.0 or len(stroke) < 2 or np.linalg.norm(overall) < 1e-9:
        return stroke
    tangent = np.gradient(stroke.points, axis=0)
    tangent = tangent - np.einsum("ij,ij->i", tangent, stroke.normals)[:, None] * stroke.normals
    flat = np.linalg.norm(tangent, axis=1) < 1e-9 * max(np.linalg.norm(overall), 1.0)
    if flat.any():
        fallback = overall[None] - (stroke.normals[flat] @ overall)[:, None] * stroke.normals[flat]
        tangent[flat] = fallback
    good = np.linalg.norm(tangent, axis=1) > 1e-12
    tangent = nm.unit(np.where(good[:, None], tangent, 0.0))
    angle = np.radians(degrees)
    # about the travel t: n cos + (t x n) sin; about the axis across it, s = n x t: (s x n) = t
    turned = stroke.normals * np.cos(angle) + (tangent if across else np.cross(tangent, stroke.normals)) * np.sin(angle)
    normals = np.where(good[:, None], nm.unit(turned), stroke.normals)
    return Stroke(
        stroke.points,
        normals,
        stroke.points + standoff_mm * normals,
        stroke.spray_on,
        stroke.on_part,
        stroke.layer,
        stroke.dwell,
        stroke.kind,
    )


def misfit(film_um: np.ndarray, area_mm2: np.ndarray, target_um: float, tolerance_um: float) -> np.ndarray:
    """Area-weighted squared excess of the film over half the tolerance either side of the target, per film
    (the last axis holds the samples): what an aim is chosen to reduce."""
    excess = np.maximum(np.abs(film_um - target_um) - 0.5 * tolerance_um, 0.0)
    return (area_mm2 * excess * excess).sum(axis=-1)


#: The candidates' film is scored with time steps and visibility views this many times farther apart than the
#: film's own (a score picks a tilt; the chosen strokes' film is computed at the film's own steps).
AIM_COARSER = 2.0


def scoring_film(coating, process):
    """The film settings the aims are scored with: ``coating``'s with ``AIM_COARSER`` times its time step and
    its distance between visibility views (their defaults: the pattern radius / 10 and / 2.5)."""
    from sprayplan.coating.thickness import CoatingConfig

    coating = CoatingConfig() if coating is None else coating
    radius = process.pattern.radius_mm
    step = radius / 10.0 if coating.max_step_mm is None else coating.max_step_mm
    views = radius / 2.5 if coating.occlusion_step_mm is None else coating.occlusion_step_mm
    return dataclasses.replace(coating, max_step_mm=AIM_COARSER * step, occlusion_step_mm=AIM_COARSER * views)


def aim_touch_ups(
    part,
    strokes: list[Stroke],
    samples: SurfaceSamples,
    film_um: np.ndarray,
    tuned: np.ndarray,
    target_um: float,
    tolerance_um: float,
    *,
    process,
    coating,
    standoff_mm: float,
    tilts_deg: tuple = AIM_TILTS_DEG,
    reach=None,
) -> list[Stroke]:
    """Each touch-up turned to the aim that helps the film most.

    Aiming along a patch's normal is not always best: on a narrow step between two surfaces already in spec,
    the pass also paints its neighbours. Each stroke is tried turned about its direction of travel by each of
    ``tilts_deg``; its deposit is computed with the film model (``deposit_matrix``, occlusion included, at
    :func:`scoring_film`'s coarser steps) and
    added to the film at each of ``AIM_SCALES`` times its speed's worth, and the tilt whose best scale lowers
    :func:`misfit` over the ``tuned`` samples most is kept. With ``reach`` (a function of a stroke giving the
    share of its waypoints the robot can reach), only tilts the robot reaches at least half of, or failing
    that the best reached, are chosen from. A stroke no allowed tilt improves keeps its aim (the speed tuning
    decides how much of it to run). Returns the strokes in the same order.
    """
    from sprayplan.coating.thickness import deposit_matrix
    from sprayplan.types import Paths

    if not strokes:
        return []
    candidates = [tilted(s, t, standoff_mm) for s in strokes for t in tilts_deg]
    _, matrix = deposit_matrix(
        part,
        Paths(tuple(candidates), standoff_mm, 0.0),
        process,
        config=scoring_film(coating, process),
        samples=samples,
    )
    # the film each candidate adds at unit time factors, on the tuned samples
    bounds = np.r_[0, np.cumsum([len(c) for c in candidates])]
    owner = np.repeat(np.arange(len(candidates)), np.diff(bounds))
    per_candidate = sparse.csr_matrix(
        (np.ones(len(owner)), (np.arange(len(owner)), owner)), shape=(len(owner), len(candidates))
    )
    added = (matrix @ per_candidate).tocsc()  # mm at unit time factors, samples x candidates
    scales = np.asarray(AIM_SCALES)
    gain = np.zeros(len(candidates))
    for c in range(len(candidates)):  # only the samples a candidate reaches change
        span = slice(added.indptr[c], added.indptr[c + 1])
        rows, more = added.indices[span], 1000.0 * added.data[span]
        counted = tuned[rows]
        if not counted.any():
            continue
        rows, more = rows[counted], more[counted]
        film, area = film_um[rows], samples.area_mm2[rows]
        now = misfit(film, area, target_um, tolerance_um)
        gain[c] = now - misfit(film[None] + scales[:, None] * more[None], area, target_um, tolerance_um).min()
    gain = gain.reshape(len(strokes), len(tilts_deg))
    out = []
    for k, stroke in enumerate(strokes):
        mine = candidates[k * len(tilts_deg) : (k + 1) * len(tilts_deg)]
        best = _best_tilt(gain[k], mine, reach)
        out.append(stroke if best is None else mine[best])
    return out


def _best_tilt(gain: np.ndarray, candidates: list, reach) -> int | None:
    """The index of the candidate with the largest gain among those allowed (with ``reach``: reached at
    ``min(0.5, the best reached share)`` or more; the first of equal gains), or None when it gains nothing.

    The shares are computed lazily, with the same answer as computing them all: no reach when nothing gains;
    then the candidates in the order of their gains (the first of equal gains first), the first one reached
    at half its waypoints or more being allowed whatever the others reach; only when one is reached less than
    that are all the shares needed."""
    if gain.max(initial=-np.inf) <= 0:
        return None
    if reach is None:
        return int(np.argmax(gain))
    order = sorted(range(len(gain)), key=lambda j: (-gain[j], j))
    j = order[0]
    first = reach(candidates[j])
    if first >= 0.5:
        return j
    share = np.array([first if i == j else reach(c) for i, c in enumerate(candidates)])
    score = np.where(share >= min(0.5, share.max()), gain, -np.inf)
    best = int(np.argmax(score))
    return best if score[best] > 0 else None
