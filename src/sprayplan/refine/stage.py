"""The ``refine`` stage of the main job: speeds tuned to the film, touch-up rounds, added stations.

With a film target and ``[tuning] tune_speed``, the finished plan's time factors are fitted to its simulated
film (``tuning.tune_speeds``); then, for ``touch_up_rounds`` rounds, touch-up strokes are aimed at the patches
still under-painted (``touchup``), run from the planned stations or from new ones (``extend``), and every
speed is tuned again, from the factors the round before found (1 on the added strokes) and with at most
``touch_up_iterations`` evaluations. With touch-up rounds the first tuning stops there too, and is continued
to ``iterations`` evaluations in all when no round follows. Only the appended strokes' columns of the deposit
matrix are computed in a round.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit
from scipy import sparse

from sprayplan.coating.stage import plan_paths_in_order, process_for
from sprayplan.coating.thickness import deposit_matrix
from sprayplan.config import JobConfig, RefineConfig
from sprayplan.progress import Progress, per_stage
from sprayplan.refine.added_stations import reach_share
from sprayplan.refine.extend import ADDED_STROKE_STATIONS, with_added_strokes
from sprayplan.refine.touchup import TOUCH_UP_MIN_DWELL, aim_touch_ups, touch_up_strokes
from sprayplan.refine.tuning import TuningConfig, tune_speeds, tuned_film
from sprayplan.robots.stage import gantry_for
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Paths, Plan


def tuning_settings(settings: RefineConfig) -> TuningConfig:
    """The speed tuning's own settings (``tuning.TuningConfig``) from the job's ``[tuning]`` section, which holds
    every one of its fields under the same name."""
    return TuningConfig(**{f.name: getattr(settings, f.name) for f in dataclasses.fields(TuningConfig)})


def lower_dwell(paths: Paths, settings: RefineConfig) -> np.ndarray:
    """(waypoints,) the tuning's lower bounds of the time factors over ``paths.strokes`` one after another:
    ``min_dwell``, and ``TOUCH_UP_MIN_DWELL`` on touch-up strokes."""
    return np.concatenate(
        [np.full(len(s), TOUCH_UP_MIN_DWELL if s.kind == "touch-up" else settings.min_dwell) for s in paths.strokes]
        or [np.zeros(0)]
    )


def tune_plan(part, plan: Plan, job: JobConfig, progress: Progress | None = None) -> tuple[Plan, dict, object, object]:
    """With a film target and ``tune_speed``: the plan with a time factor at every waypoint chosen from the
    simulated film (``coating.tune_speeds``), and, for ``touch_up_rounds`` rounds, touch-up strokes aimed at
    the patches still under-painted (``coating.touchup``), run from the nearest station, after which all
    speeds are tuned again. Returns the plan and a summary (the film predicted before and after, the
    factors' range, the touch-up strokes added), the tuned plan's film (a ``CoatingResult``, what
    :func:`simulate_plan` gives for it, taken from the tuning's deposit matrix) and the last
    ``tuning.Tuning`` (its samples and deposit matrix, for tuning again within the robot's limits,
    ``refine.limits``). The plan's own strokes keep their geometry and joints. Without a target or with
    ``tune_speed`` off: the plan unchanged, {}, None and None."""
    settings = job.tuning
    if job.coating.thickness_um is None or not settings.tune_speed or not plan.stations:
        return plan, {}, None, None
    target = job.coating.thickness_um
    tolerance = job.coating.tolerance
    process = process_for(job)
    config = tuning_settings(settings)
    coating = job.coating.simulation(job.motion)
    radius = process.pattern.radius_mm
    report = per_stage(progress, "refine")

    def tuned(plan_, earlier=None, earlier_dwell=None, iterations=None):
        """The plan's speeds tuned, with at most ``iterations`` evaluations (default ``[tuning] iterations``);
        ``earlier``: a list holding the plan it extends, its samples and deposit matrix, emptied once the new
        matrix is made (so that the earlier one is freed before the tuning); ``earlier_dwell``: that plan's
        tuned time factors, where the solver starts from (1 on the added strokes)."""
        paths = plan_paths_in_order(plan_, job.paths.standoff_mm, job.paths.spacing or 0.0)
        lower = lower_dwell(paths, settings)
        deposit, initial, round_config = None, None, config
        if iterations is not None:
            round_config = dataclasses.replace(config, iterations=iterations)
        if earlier is not None:
            is_new = appended_waypoints(plan_, earlier[0])
            deposit = extended_deposit(part, plan_, *earlier, process, coating)
            earlier.clear()
            if earlier_dwell is not None:
                initial = np.ones(len(is_new))
                initial[~is_new] = earlier_dwell
        return tune_speeds(
            part,
            paths,
            process,
            target,
            tolerance,
            config=round_config,
            coating=coating,
            lower=lower,
            initial=initial,
            deposit=deposit,
            progress=report,
        )

    # with touch-up rounds the first tuning stops at touch_up_iterations (the rounds go on from it); if no
    # round follows it is continued to ``iterations`` evaluations in all
    short = min(settings.touch_up_iterations, settings.iterations) if settings.touch_up_rounds else None
    tuning = tuned(plan, iterations=short)
    first = tuning.summary(target, tolerance)
    planned_stations = len(plan.stations)
    rounds = 0
    for _ in range(settings.touch_up_rounds):
        extra = touch_up_strokes(
            tuning.samples,
            tuning.after_um,
            tuning.tuned,
            target,
            tolerance,
            standoff_mm=job.paths.standoff_mm,
            step_mm=job.paths.step_mm,
            lead_mm=radius,
            min_area_mm2=radius * radius / 4.0,
        )
        if not extra:
            break
        spare = settings.touch_up_stations - (len(plan.stations) - planned_stations)
        if settings.touch_up_aim:
            extra = aim_touch_ups(
                part,
                extra,
                tuning.samples,
                tuning.after_um,
                tuning.tuned,
                target,
                tolerance,
                process=process,
                coating=coating,
                standoff_mm=job.paths.standoff_mm,
                reach=_reach_from(plan, job, spare > 0),
            )
        before = len(tuning.paths.strokes)
        previous, plan = plan, with_added_strokes(plan, extra, job, new_stations=spare)
        if sum(len(st.strokes) for st in plan.stations) == before:
            break  # the arm reaches none of them
        earlier = [previous, tuning.samples, tuning.deposit_mm]
        dwell = np.concatenate([st.dwell for st in tuning.paths.strokes])
        tuning = None  # the earlier deposit matrix is freed once the extended one is made
        tuning = tuned(plan, earlier, dwell, iterations=short)
        rounds += 1
    if rounds == 0 and short is not None and short < settings.iterations:
        tuning = tune_speeds(
            part,
            tuning.paths,
            process,
            target,
            tolerance,
            config=dataclasses.replace(config, iterations=settings.iterations - short),
            coating=coating,
            lower=lower_dwell(tuning.paths, settings),
            initial=np.concatenate([st.dwell for st in tuning.paths.strokes]),
            deposit=(tuning.samples, tuning.deposit_mm),
            progress=report,
        )
    strokes = iter(tuning.paths.strokes)
    stations = tuple(dataclasses.replace(st, strokes=tuple(next(strokes) for _ in st.strokes)) for st in plan.stations)
    summary = tuning.summary(target, tolerance)
    summary["before"] = first["before"]
    summary["touch_up_strokes"] = sum(1 for s in tuning.paths.strokes if s.kind == "touch-up")
    film = dataclasses.replace(tuned_film(tuning, process, coating), name=plan.name)
    return dataclasses.replace(plan, stations=stations), summary, film, tuning


def _reach_from(plan: Plan, job: JobConfig, new_stations: bool):
    """A function of a stroke: the largest share of its waypoints the arm reaches exactly from one of the
    stations ``extend.with_added_strokes`` offers it to (the nearest ``ADDED_STROKE_STATIONS``) or, with
    ``new_stations``, from a new station at the plan's gantry height (whether the budget of new stations
    then runs out is not foreseen)."""
    gantry = gantry_for(job.kinematics)
    platforms = np.array([st.platform_mm for st in plan.stations])
    height = float(np.median(platforms[:, 2])) if new_stations else None
    to_flange = np.linalg.inv(gantry.gun.gun2flange)

    def reach(stroke):
        poses = stroke_poses(stroke)
        # the stations with_added_strokes offers the stroke to: the nearest to its flange positions
        centre = (poses @ to_flange)[:, :2, 3].mean(axis=0)
        order = np.argsort(np.linalg.norm(platforms[:, :2] - centre, axis=1), kind="stable")
        return reach_share(gantry, poses, platforms[order[:ADDED_STROKE_STATIONS]], height)

    return reach


def appended_waypoints(plan: Plan, earlier: Plan) -> np.ndarray:
    """(waypoints,) bool over ``plan``'s strokes in order: the waypoints of strokes appended to ``earlier``'s
    stations (stations matched by ``index``; a new station's strokes are all appended)."""
    before = {st.index: len(st.strokes) for st in earlier.stations}
    flags = [np.full(len(s), j >= before.get(st.index, 0)) for st in plan.stations for j, s in enumerate(st.strokes)]
    return np.concatenate(flags) if flags else np.zeros(0, bool)


def extended_deposit(part, plan: Plan, earlier: Plan, samples, deposit_mm, process, coating):
    """The deposit matrix of ``plan`` (``coating.deposit_matrix``) from that of ``earlier``, a plan whose
    stations ``plan`` extends with strokes appended at their ends and new stations inserted into the visiting
    order (stations matched by ``index``): only the added strokes' columns are computed, on the earlier
    samples (the film of a time step does not depend on the other strokes). Returns (samples, matrix)."""
    before = {st.index: len(st.strokes) for st in earlier.stations}
    added = [s for st in plan.stations for j, s in enumerate(st.strokes) if j >= before.get(st.index, 0)]
    is_new = appended_waypoints(plan, earlier)
    return samples, with_added_columns(
        part, deposit_mm, samples, np.flatnonzero(~is_new), added, np.flatnonzero(is_new), process, coating
    )


def with_added_columns(part, deposit_mm, samples, kept_at, added, added_at, process, coating) -> sparse.csr_matrix:
    """A deposit matrix grown by the columns of ``added`` strokes: ``deposit_mm``'s columns go to ``kept_at``,
    the added strokes' waypoints (their columns computed here, on the same ``samples``: the film of a time step
    does not depend on the other strokes) to ``added_at`` (:func:`merged_columns`)."""
    if not added:
        return deposit_mm
    _, new_mm = deposit_matrix(part, Paths(tuple(added), 0.0, 0.0, part.name), process, config=coating, samples=samples)
    return merged_columns(deposit_mm, new_mm, np.asarray(kept_at, np.int64), np.asarray(added_at, np.int64))


def merged_columns(first, second, first_at, second_at) -> sparse.csr_matrix:
    """The CSR matrix whose columns ``first_at`` are ``first``'s and ``second_at`` are ``second``'s (each
    increasing; together every column once), built row by row by merging the two rows' entries
    (``_merge_rows``): the matrix ``hstack([first, second])`` with its columns put in place gave, with no
    copies in between."""
    first, second = first.tocsr(), second.tocsr()
    first.sort_indices()
    second.sort_indices()
    shape = (first.shape[0], len(first_at) + len(second_at))
    wide = max(shape[1], first.nnz + second.nnz) > np.iinfo(np.int32).max
    data, indices, indptr = _merge_rows(
        first.indptr, first.indices, first.data, second.indptr, second.indices, second.data,
        np.asarray(first_at, np.int64), np.asarray(second_at, np.int64), np.zeros(0, np.int64 if wide else np.int32),
    )  # fmt: skip
    return sparse.csr_matrix((data, indices, indptr), shape=shape)


@njit(cache=True, nogil=True)
def _merge_rows(p1, i1, d1, p2, i2, d2, at1, at2, index_like):
    rows = len(p1) - 1
    total = (p1[rows] - p1[0]) + (p2[rows] - p2[0])
    indptr = np.zeros(rows + 1, index_like.dtype)
    indices = np.empty(total, index_like.dtype)
    data = np.empty(total, np.float64)
    out = 0
    for r in range(rows):
        a, a_end = p1[r], p1[r + 1]
        b, b_end = p2[r], p2[r + 1]
        while a < a_end or b < b_end:
            if b >= b_end or (a < a_end and at1[i1[a]] < at2[i2[b]]):
                indices[out] = at1[i1[a]]
                data[out] = d1[a]
                a += 1
            else:
                indices[out] = at2[i2[b]]
                data[out] = d2[b]
                b += 1
            out += 1
        indptr[r + 1] = out
    return data, indices, indptr
