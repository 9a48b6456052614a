"""The main job, one straight line: ``run_job(part_or_path, JobConfig) -> JobResult``.

The stages run in the order of :data:`STAGES`; each is a short function here of the previous stages' result
(a :class:`JobState`) and its own config section, calling the stage's module:

=============  ======================================================  ===========================
stage          what it does                                            module
=============  ======================================================  ===========================
load           the part file -> a ``Part`` in mm, z up                 ``io.load``
region         the part cut to ``[load] region``                       ``surface.region``
film target    spacing and gun speed for ``[coating] thickness_um``    ``coating.stage``
paths          spray strokes (paths mode) or target points (points)    ``paths.planner``, ``surface.targets``
stations       gantry stations, their tour, the work of each           ``stations.stage``
ordering       each station's strokes in order, with transfers         ``ordering.stage``
kinematics     the nine axes at every waypoint                         ``robots.stage``
refine         speeds tuned to the film, touch-ups, added stations     ``refine.stage``
collision      waypoints and motions checked, repaired, or flagged     ``collision.repair``
timing         time stamps within the joints' limits, the cycle time   ``timing.stage``
film           the film the final plan leaves                          ``coating.stage``
totals         lengths, counts, cycle time                             ``export.summary``
programs       ``[export] programs``: robot programs, in memory        ``programs.stage``
=============  ======================================================  ===========================

Writing the files (plan.json, waypoints.csv, the film files) is ``export.write_job``; ``run_job`` does it
last when given an output folder, and then the robot programs into OUT/programs/<format>/ (built, and with
``[export] strict`` refused, before anything is written).

Errors: bad input raised inside a stage comes out as a :class:`~sprayplan.errors.StageError` (an
``InputError``) whose message names the stage and the part; any other exception keeps its type and gains a
note naming them. Progress: ``progress(stage, 0, 0)`` as each stage starts, and ``progress(stage, done,
total)`` from the long stages as they work (layers sliced, stations ordered and solved, film batches, the
tuning's solver evaluations).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from sprayplan.config import JobConfig
from sprayplan.errors import InputError, StageError
from sprayplan.heap import release_freed_memory
from sprayplan.parallel import process_count, start_helper, warm_helper
from sprayplan.progress import Progress, no_progress, per_stage
from sprayplan.types import Part, Plan

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class JobState:
    """What the stages have made so far (each stage returns a copy with its own result filled in).

    Attributes
    ----------
    job : JobConfig
        The settings; the ``film target`` stage replaces the spacing and gun speed for a film target.
    source : str or Part
        A part file's path, or a part given in memory.
    part : Part or None
        The part in mm, z up, cut to its region (and without the surface facing the floor, ``[collision]
        skip_floor_facing``).
    whole : Part or None
        The whole part as loaded, which the robot must not hit (the collision stage).
    chosen : dict
        The spacing and speed chosen for a film target ({} without one).
    strokes : tuple of Stroke
        The spray work: strokes (paths mode) or one-waypoint strokes at the targets (points mode).
    layout, ordered
        The stations' and the ordering's results (``stations.stage.StationLayout``,
        ``ordering.stage.OrderedStations``).
    plan : Plan or None
    tuning : dict
        The refine stage's summary ({} when it did not run); with timing, its ``within_limits`` entry
        (``refine.limits``).
    tuned : refine.tuning.Tuning or None
        The last speed tuning (its samples and deposit matrix), when the speeds were tuned.
    collisions : dict
        The collision stage's summary ({} when it did not run).
    cell : collision.cell.CellCollision or None
        The cell's collision model, made by the stations stage when it chooses the stations' heights with it
        (``collision.heights``) and used again by the collision stage.
    timing : timing.stage.PlanTiming or None
        The plan's time stamps and achievable speeds (None with ``[timing] enabled = false``).
    film : coating.CoatingResult or None
        The final plan's film (None when not simulated).
    totals : dict
    programs : tuple of programs.stage.Built
        The robot programs of ``[export] programs``, in memory (written by the outputs stage).
    timings_s : dict
        Wall seconds of each stage run.
    """

    job: JobConfig
    source: object
    part: Part | None = None
    whole: Part | None = None
    chosen: dict = field(default_factory=dict)
    strokes: tuple = ()
    layout: object = None
    ordered: object = None
    plan: Plan | None = None
    tuning: dict = field(default_factory=dict)
    tuned: object = None
    collisions: dict = field(default_factory=dict)
    cell: object = None
    timing: object = None
    film: object = None
    totals: dict = field(default_factory=dict)
    programs: tuple = ()
    timings_s: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The part's name (its file) for messages."""
        if self.part is not None:
            return self.part.name
        return self.source.name if isinstance(self.source, Part) else os.fspath(self.source)

    @property
    def part_file(self) -> str | None:
        """The part's file when the job was given one."""
        return None if isinstance(self.source, Part) else os.fspath(self.source)

    def gantry(self):
        """The job's robot (``robots.stage.gantry_for``)."""
        from sprayplan.robots.stage import gantry_for

        return gantry_for(self.job.kinematics)


#: The result of :func:`run_job`: the last state, every stage's result in it.
JobResult = JobState


def _load(state: JobState, progress: Progress) -> JobState:
    if isinstance(state.source, Part):
        return dataclasses.replace(state, part=state.source)
    from sprayplan.io.load import load_part

    load = state.job.load
    return dataclasses.replace(state, part=load_part(state.source, units=load.units, up=load.up))


def _region(state: JobState, progress: Progress) -> JobState:
    from sprayplan.surface.region import painted_surface, select_region

    part = select_region(state.part, state.job.load.region)
    part, left_out = painted_surface(part, state.job.collision, state.job.load.mask)
    totals = {**state.totals, **{k: round(v, 3) for k, v in left_out.items()}}
    return dataclasses.replace(state, part=part, whole=state.part, totals=totals)


def _film_target(state: JobState, progress: Progress) -> JobState:
    from sprayplan.coating.stage import meet_thickness

    job, chosen = meet_thickness(state.job)
    if chosen:
        log.info(
            "for %.4g um: spacing %.4g mm, gun speed %.4g mm/s",
            chosen["target_um"],
            chosen["spacing_mm"],
            chosen["gun_speed_mm_s"],
        )
    return dataclasses.replace(state, job=job, chosen=chosen)


def _paths(state: JobState, progress: Progress) -> JobState:
    job = state.job
    if job.mode == "paths":
        from sprayplan.paths.planner import plan_paths

        strokes = plan_paths(state.part, job.paths, per_stage(progress, "paths")).spray_strokes
    else:
        from sprayplan.stations.stage import target_strokes
        from sprayplan.surface.targets import make_targets

        strokes = target_strokes(make_targets(state.part, job.targets), job.paths.standoff_mm)
    if not strokes:
        raise InputError(f"{state.name}: nothing to paint")
    return dataclasses.replace(state, strokes=tuple(strokes))


def _stations(state: JobState, progress: Progress) -> JobState:
    from sprayplan.stations.stage import stations_stage

    job, gantry = state.job, state.gantry()
    layout = stations_stage(state.strokes, job, gantry, state.name)
    if not (job.collision.check and job.stations.platform_z_mm is None and job.collision.platform_search_mm > 0):
        return dataclasses.replace(state, layout=layout)
    # the heights chosen with the collision model (the part as a whole, as the collision stage checks it)
    from sprayplan.collision.cell import CellCollision
    from sprayplan.collision.heights import choose_heights

    cell = CellCollision(gantry, state.whole if state.whole is not None else state.part, job.collision)
    layout, choice = choose_heights(layout, cell, gantry, job.collision)
    totals = {**state.totals, "station_heights": choice.summary()}
    return dataclasses.replace(state, layout=layout, cell=cell, totals=totals)


def _ordering(state: JobState, progress: Progress) -> JobState:
    from sprayplan.ordering.stage import ordering_stage

    return dataclasses.replace(state, ordered=ordering_stage(state.layout, state.job, progress))


def _kinematics(state: JobState, progress: Progress) -> JobState:
    from sprayplan.robots.stage import kinematics_stage

    plan = kinematics_stage(state.ordered, state.job, state.gantry(), state.part.name, progress)
    return dataclasses.replace(state, plan=plan)


def _refine(state: JobState, progress: Progress) -> JobState:
    from sprayplan.refine.stage import tune_plan

    plan, summary, film, tuned = tune_plan(state.part, state.plan, state.job, progress)
    return dataclasses.replace(state, plan=plan, tuning=summary, film=film, tuned=tuned)


def _collision(state: JobState, progress: Progress) -> JobState:
    if not state.job.collision.check:
        return state
    from sprayplan.collision.repair import collision_stage

    whole = state.whole if state.whole is not None else state.part
    plan, summary = collision_stage(state.plan, whole, state.job, state.gantry(), progress, cell=state.cell)
    return dataclasses.replace(state, plan=plan, collisions=summary)


def _timing(state: JobState, progress: Progress) -> JobState:
    if not state.job.timing.enabled:
        return state
    from sprayplan.timing.stage import time_plan

    job, gantry = state.job, state.gantry()
    if state.tuned is None or job.tuning.limit_rounds == 0:
        return dataclasses.replace(state, timing=time_plan(state.plan, job, gantry, progress))
    # the speed tuning again within the speeds the robot makes, timed after each round
    from sprayplan.refine.limits import tune_within_limits

    done = tune_within_limits(
        state.part, state.plan, state.tuned, job, lambda plan: time_plan(plan, job, gantry, progress),
        per_stage(progress, "timing"),
    )  # fmt: skip
    tuning = {**state.tuning, "within_limits": done.summary}
    return dataclasses.replace(state, plan=done.plan, timing=done.timing, tuned=done.tuning, tuning=tuning)


def _film(state: JobState, progress: Progress) -> JobState:
    job = state.job
    if not (job.output.simulate or job.film_target):
        return state
    timed = state.timing is not None and job.timing.film_at_timed_speeds
    if state.tuned is not None:  # the tuning's deposit matrix gives the film, at the tuned or the timed speeds
        from sprayplan.refine.limits import film_of

        return dataclasses.replace(state, film=film_of(state.tuned, state.plan, state.timing if timed else None, job))
    if state.film is not None and not timed:
        return state  # a tuned plan's film is known already (the tuning's deposit matrix)
    from sprayplan.coating.stage import simulate_plan

    plan = state.plan
    if timed:  # the film at the speeds the robot makes
        from sprayplan.timing.stage import real_plan

        plan = real_plan(plan, state.timing)
    return dataclasses.replace(state, film=simulate_plan(state.part, plan, job, progress))


def _totals(state: JobState, progress: Progress) -> JobState:
    from sprayplan.export.summary import plan_totals

    totals = {**state.totals, **plan_totals(state.plan, state.job)}
    if state.collisions:
        totals["collisions"] = state.collisions
    if state.timing is not None:
        totals["cycle_time_length_over_speed_s"] = totals["cycle_time_s"]
        totals["cycle_time_s"] = round(state.timing.cycle_time_s, 3)
        totals["timing"] = state.timing.summary(state.plan, state.job)
    if state.chosen:
        totals["chosen_for_thickness"] = state.chosen
    if state.tuning:
        totals["speed_tuning"] = state.tuning
    return dataclasses.replace(state, totals=totals)


def _programs(state: JobState, progress: Progress) -> JobState:
    if not state.job.export.programs:
        return state
    from sprayplan.programs.stage import build

    plan = program_plan(state)
    return dataclasses.replace(state, programs=tuple(build(plan, state.job, f) for f in state.job.export.programs))


def program_plan(state: JobState) -> Plan:
    """The plan the robot programs carry: with timing, at the speeds the robot makes (each waypoint's timed
    time factor, ``timing.stage.real_plan``: the planned speed where the robot keeps it, lower where not)."""
    if state.timing is None:
        return state.plan
    from sprayplan.timing.stage import real_plan

    return real_plan(state.plan, state.timing)


def write_outputs(outdir, state: JobState, progress=None, part_file=None, placed=None) -> None:
    """The outputs: the job's files and pictures (``progress(done, total)`` while the report is drawn), then
    its robot programs (OUT/programs/<format>/).

    ``part_file``: the part's file as plan.json names it (default: the file the job read); ``placed``: where
    ``outdir`` will be once moved in (a batch writes each job into a temporary folder first), named by the
    programs' summary."""
    from sprayplan.export.job_files import write_job

    write_job(outdir, state, part_file=part_file, progress=progress)
    if state.programs:
        from sprayplan.programs.stage import default_folder, write_built

        plan_file = os.path.abspath(os.path.join(outdir if placed is None else placed, "plan.json"))
        write_built(default_folder(outdir), list(state.programs), program_plan(state), state.job, plan_file)


@dataclass(frozen=True)
class Stage:
    """One stage of the main job: its name and the function from the state before it to the state after."""

    name: str
    run: Callable[[JobState, Progress], JobState]


#: The main job's stages, in order.
STAGES = (
    Stage("load", _load),
    Stage("region", _region),
    Stage("film target", _film_target),
    Stage("paths", _paths),
    Stage("stations", _stations),
    Stage("ordering", _ordering),
    Stage("kinematics", _kinematics),
    Stage("refine", _refine),
    Stage("collision", _collision),
    Stage("timing", _timing),
    Stage("film", _film),
    Stage("totals", _totals),
    Stage("programs", _programs),
)


def run_job(
    source, job: JobConfig | None = None, outdir=None, progress: Progress | None = None, until: str | None = None
) -> JobResult:
    """Run the main job on a part: every stage of :data:`STAGES` in order, then write the files.

    Parameters
    ----------
    source : str, os.PathLike or Part
        A part file (read with ``[load] units`` and ``up``), or a part already in memory (in mm, z up; its
        ``[load] region`` is still applied).
    job : JobConfig, optional
        Every setting; default ``JobConfig()``.
    outdir : str or os.PathLike, optional
        When given, plan.json and waypoints.csv (and the film files when there is a film) are written there
        (``export.write_job``), each atomically, and the robot programs of ``[export] programs`` into
        ``outdir/programs/<format>/``.
    progress : callable, optional
        ``progress(stage, done, total)``.
    until : str, optional
        Stop after this stage (a name in :data:`STAGES`; ``"kinematics"`` gives the plan without refinement,
        film or totals); nothing is written.

    Returns
    -------
    JobResult
        The plan, its film (None without a target or ``[output] simulate``), its totals, the settings used,
        and every stage's time.

    Raises
    ------
    StageError
        Bad input found by a stage; the message names the stage and the part. Unreachable waypoints are
        not errors: they are flagged in the plan.
    """
    job = JobConfig() if job is None else job
    if not isinstance(job, JobConfig):
        raise InputError(f"job must be a JobConfig, got {type(job).__name__}")
    names = [stage.name for stage in STAGES]
    if until is not None and until not in names:
        raise InputError(f"until must be one of {', '.join(names)}, got {until!r}")
    progress = progress or no_progress
    state = JobState(job=job, source=source)
    if until is None or names.index(until) >= names.index("kinematics"):
        # the joint solves' helper process starts on the other core while the part is loaded and sliced
        start_helper(process_count(job.kinematics.processes))
    start = time.perf_counter()
    for stage in STAGES:
        state = _run_stage(stage, state, progress)
        if stage.name == until:
            return state
        if stage.name == "refine":  # past the job's peak of memory: the helper sets up the timing and drawing
            warm_helper()
    totals = {**state.totals, "planning_time_s": round(time.perf_counter() - start, 3)}
    state = dataclasses.replace(state, totals=totals)
    if outdir is not None:

        def outputs(s: JobState, p: Progress) -> JobState:
            write_outputs(outdir, s, lambda done, total: p("outputs", done, total))
            return s

        state = _run_stage(Stage("outputs", outputs), state, progress)
    return state


def _run_stage(stage: Stage, state: JobState, progress: Progress) -> JobState:
    progress(stage.name, 0, 0)
    began = time.perf_counter()
    log.info("%s ...", stage.name)
    try:
        after = stage.run(state, progress)
    except StageError:
        raise
    except InputError as exc:
        raise StageError(stage.name, state.name, exc) from exc
    except Exception as exc:
        exc.add_note(f"sprayplan: in the {stage.name} stage of {state.name}")
        raise
    seconds = time.perf_counter() - began
    release_freed_memory()  # a stage's big arrays are freed at its end (sprayplan.heap)
    log.info("%s done in %.2f s", stage.name, seconds)
    return dataclasses.replace(after, timings_s={**after.timings_s, stage.name: round(seconds, 3)})
