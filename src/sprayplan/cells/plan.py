"""A whole body painted by the robots of a cell: one plan a robot, one film over the whole body (issue 18,
sections 2-4; seed 003, section 5).

:func:`plan_cell` runs, for a part and a :class:`~sprayplan.cells.spec.Cell` of fixed-base arms (on tracks or
not):

1. **place**: the part in the cell (:func:`~sprayplan.cells.spec.place_part`), the surface that faces the floor
   left out (``[collision] skip_floor_facing``), as the main job does;
2. **film target**: spacing and gun speed for ``[coating] thickness_um`` (``coating.stage.meet_thickness``),
   the same for every robot (one paint, one gun);
3. **areas**: :func:`~sprayplan.surface.areas.segment_areas`, the reach of every robot
   (:func:`~sprayplan.cells.reach.reach_matrix`) and :func:`~sprayplan.surface.areas.assign_areas`;
4. **paths**: each robot's share of each area sliced on its own (``paths.planner.plan_paths`` with the job's
   ``[paths]``; ``direction = "auto"`` slices each piece across its own longest axis, the direction the seed
   chose by hand per area), the pieces joined by spray-off transfers;
5. **kinematics**: each stroke solved by its robot, the track moving with the gun (a coordinated external
   axis, as paint lines run their rail robots along a car): at every waypoint the base stands at the track
   position of the gun tip's own position along the track, plus an offset, clipped to the track's ends. The
   offsets tried are 0, then 300 and 600 mm either side, each with the gun turned about its axis by 0, 90,
   180 and 270 degrees; the first try that reaches every waypoint is kept, else the first that reaches the
   most. Along the stroke the branch nearest the previous waypoint's joints is followed
   (``robots.interface.follow_solutions``). Unreached waypoints are data (``reachable`` False). A fixed track
   per stroke was tried first and dropped: one base position does not reach both ends of a 4 m stroke along a
   car's side;
6. **film**: the strokes of all robots together over the whole body, their speeds tuned to the target by
   ``refine.tuning.tune_speeds`` (``[tuning] tune_speed``) in one least-squares problem, so the film where two
   robots' areas meet is tuned like any other; then reported over the whole body, per area, per robot and
   along every seam, with seed 003's 420 measuring points (``[output] samples``).

**The seam rule: overlap, tuned.** Each robot's strokes run past the edge of its share by the planner's lead-out
(``[paths] edge_margin_mm``, by default one spray radius), so near a seam both robots' spray tails land on
both sides; the whole-body speed tuning then sees the doubled film there and slows or speeds the strokes
near the seam to bring it back to the target. The alternative, feathering (stopping each side's last stroke
at the seam), leaves the seam under-painted by the half-profile each side loses unless the two tails are
placed to the millimetre; the overlap needs no such placement and the tuning corrects what it adds.
``docs/benchmarks.md`` ("Whole bodies in a cell") gives the film along every seam.

Collisions and joint-limited timing of fixed-base arms are not checked yet: the cycle time of each robot is
its path length over its speeds (spray strokes at their tuned speeds, transfers at ``[motion]
transfer_speed_mm_s``), and the cell's is the longest robot's (robots of a line work at the same time).
Robots keep apart in space: every face has one robot, and a robot's strokes stay over its own share.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.cells.reach import reach_matrix
from sprayplan.cells.spec import Cell, place_part
from sprayplan.config import JobConfig
from sprayplan.errors import ConfigError, InputError
from sprayplan.progress import Progress, no_progress, per_stage
from sprayplan.surface.areas import AreaAssignment, Areas, assign_areas, face_adjacency, segment_areas
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Part, Paths, Stroke

log = logging.getLogger(__name__)

#: Track positions tried about the one nearest a stroke's middle, mm.
TRACK_TRIES_MM = (0.0, -300.0, 300.0, -600.0, 600.0)
#: Rolls of the gun about its own axis tried, degrees.
ROLL_TRIES_DEG = (0.0, 90.0, 180.0, 270.0)
#: The joints a robot starts from (rad): elbow up, wrist bent (ABB's zero is a straight, singular wrist).
START_JOINTS = np.radians([0.0, 0.0, 0.0, 0.0, 30.0, 0.0])
#: A piece of an area under this many spray-circle areas is not sliced on its own: it is too small for a
#: stroke and is painted by the spray of its neighbours.
MIN_PIECE_CIRCLES = 1.0


@dataclass(frozen=True)
class RobotWork:
    """One robot's plan.

    Attributes
    ----------
    name, model : str
    strokes : tuple of Stroke
        Spray strokes and transfers in execution order (cell frame).
    area : (s,) int
        The area of each stroke (-1 for transfers).
    track_mm : (n,) float
        The track position at every waypoint of all strokes in order, mm (0 without a track).
    roll_deg : (s,) float
        The roll of the gun about its axis for the stroke.
    q : (n, 6) float
        The joints at every waypoint of all strokes in order, rad (0 where unreached).
    reachable : (n,) bool
    """

    name: str
    model: str
    strokes: tuple
    area: np.ndarray
    track_mm: np.ndarray
    roll_deg: np.ndarray
    q: np.ndarray
    reachable: np.ndarray

    @property
    def waypoints(self) -> int:
        return int(sum(len(s) for s in self.strokes))

    def cycle_time_s(self, speed_mm_s: float, transfer_speed_mm_s: float) -> float:
        """Path length over speed: spray strokes at ``speed_mm_s`` divided by their time factors, transfers
        at ``transfer_speed_mm_s``."""
        total = 0.0
        for s in self.strokes:
            seg = np.linalg.norm(np.diff(s.tcp, axis=0), axis=1)
            if s.spray_on:
                factor = (s.dwell[:-1] + s.dwell[1:]) / 2.0
                total += float((seg * factor).sum()) / speed_mm_s
            else:
                total += float(seg.sum()) / transfer_speed_mm_s
        return total


@dataclass(frozen=True)
class CellPlan:
    """A whole body painted by the robots of a cell (module docstring).

    Attributes
    ----------
    cell : Cell
    part : Part
        The painted surface in the cell frame (floor-facing surface left out).
    part2cell : (4, 4) float
    areas : Areas
    assignment : AreaAssignment
    robots : tuple of RobotWork
    film : CoatingResult or None
    report : dict
        The film over the whole body, per area, per robot and per seam; cycle times; counts.
    timings_s : dict
        Wall seconds of each step.
    """

    cell: Cell
    part: Part
    part2cell: np.ndarray
    areas: Areas
    assignment: AreaAssignment
    robots: tuple
    film: object = None
    report: dict = field(default_factory=dict)
    timings_s: dict = field(default_factory=dict)


def _sub_part(part: Part, keep: np.ndarray, name: str) -> Part:
    faces = part.faces[keep]
    used = np.zeros(len(part.vertices), bool)
    used[faces.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return Part(part.vertices[used], remap[faces], None, name)


def _transfer(a: Stroke, b: Stroke) -> Stroke:
    """A spray-off move from the end of ``a`` to the start of ``b`` (two waypoints)."""
    return Stroke(
        np.stack([a.points[-1], b.points[0]]),
        np.stack([a.normals[-1], b.normals[0]]),
        np.stack([a.tcp[-1], b.tcp[0]]),
        spray_on=False,
        on_part=np.zeros(2, bool),
    )


def _rot_z(angle_deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    return out


def _tries(cell_robot, stroke: Stroke) -> list[tuple[float, float]]:
    """The (track positions at the waypoints (n,) mm, roll deg) tries of a stroke, in the order they are
    preferred; offsets that the track's ends make the same as an earlier one are left out."""
    if cell_robot.track is None:
        return [(np.zeros(len(stroke)), r) for r in ROLL_TRIES_DEG]
    lo, hi = cell_robot.track.range_mm
    along = (stroke.tcp - cell_robot.base2cell[:3, 3]) @ cell_robot.track.axis
    tracks: list[np.ndarray] = []
    for d in TRACK_TRIES_MM:
        s = np.clip(along + d, lo, hi)
        if not any(np.array_equal(s, t) for t in tracks):
            tracks.append(s)
    return [(t, r) for t in tracks for r in ROLL_TRIES_DEG]


def _slice(sols, start: int, n: int):
    """Poses ``start .. start + n`` of an IKSolutions."""
    return dataclasses.replace(
        sols,
        **{
            f.name: getattr(sols, f.name)[start : start + n]
            for f in dataclasses.fields(sols)
            if isinstance(getattr(sols, f.name), np.ndarray)
        },
    )


def solve_strokes(cell_robot, strokes) -> list[tuple[float, float, np.ndarray, np.ndarray]]:
    """For each stroke, the first (track positions, roll) try that reaches all its waypoints, else the first
    that reaches the most, and the joints along it (module docstring, step 5): ``(track_mm (n,), roll_deg, q
    (n, 6), reachable (n,))`` a stroke.

    The tries go in rounds: round ``k`` solves try ``k`` of every stroke not yet reached whole, all in one
    call of the IK with the base at track position 0 and the poses moved back along the track instead."""
    from sprayplan.robots.interface import follow_solutions

    arm = cell_robot.robot(0.0)
    axis = np.zeros(3) if cell_robot.track is None else cell_robot.track.axis
    tries = [_tries(cell_robot, s) for s in strokes]
    poses = [stroke_poses(s) for s in strokes]
    best: list = [None] * len(strokes)  # (count, try index, IKSolutions of the stroke)
    pending = list(range(len(strokes)))
    for k in range(max((len(t) for t in tries), default=0)):
        pending = [i for i in pending if k < len(tries[i])]
        if not pending:
            break
        blocks = []
        for i in pending:
            track, roll = tries[i][k]
            moved = poses[i] @ _rot_z(roll)
            moved[:, :3, 3] -= track[:, None] * axis
            blocks.append(moved)
        sols = arm.ik(np.concatenate(blocks))
        start, still = 0, []
        for i, block in zip(pending, blocks):
            n = len(block)
            mine = _slice(sols, start, n)
            start += n
            count = int(mine.reachable.sum())
            if count and (best[i] is None or count > best[i][0]):
                best[i] = (count, k, mine)
            if count < n:
                still.append(i)
        pending = still
    out = []
    seed = START_JOINTS
    for i, s in enumerate(strokes):
        if best[i] is None:
            out.append((tries[i][0][0], 0.0, np.zeros((len(s), 6)), np.zeros(len(s), bool)))
            continue
        _, k, mine = best[i]
        q, branch = follow_solutions(arm, mine, seed)
        reach = branch >= 0
        if reach.any():
            seed = q[np.flatnonzero(reach)[-1]]
        out.append((*tries[i][k], q, reach))
    return out


def _robot_work(cell_robot, index: int, part: Part, areas: Areas, assignment: AreaAssignment, job: JobConfig):
    from sprayplan.paths.planner import plan_paths

    radius = job.paths.spray_radius_mm
    strokes, area_of = [], []
    for a in range(len(areas)):
        keep = (assignment.face_robot == index) & (areas.face_area == a)
        if not keep.any():
            continue
        if part.face_areas[keep].sum() < MIN_PIECE_CIRCLES * math.pi * radius * radius:
            continue
        piece = _sub_part(part, keep, f"{part.name}:{areas.names[a]}:{cell_robot.name}")
        try:
            paths = plan_paths(piece, job.paths)
        except InputError:
            log.info("%s: no section to paint", piece.name)
            continue
        for s in paths.strokes:
            if strokes and s.spray_on and strokes[-1].spray_on:
                strokes.append(_transfer(strokes[-1], s))
                area_of.append(-1)
            strokes.append(s)
            area_of.append(a if s.spray_on else -1)
    track, roll, qs, ok = [], [], [], []
    for t, r, q, reach in solve_strokes(cell_robot, strokes):
        track.append(t)
        roll.append(r)
        qs.append(q)
        ok.append(reach)
    n = sum(len(s) for s in strokes)
    return (
        RobotWork(
            name=cell_robot.name,
            model=cell_robot.model,
            strokes=tuple(strokes),
            area=np.array(area_of, dtype=np.int64),
            track_mm=np.concatenate(track) if track else np.zeros(0),
            roll_deg=np.array(roll, dtype=float),
            q=np.concatenate(qs) if qs else np.zeros((0, 6)),
            reachable=np.concatenate(ok) if ok else np.zeros(0, bool),
        )
        if n
        else RobotWork(
            cell_robot.name,
            cell_robot.model,
            (),
            np.zeros(0, np.int64),
            np.zeros(0),
            np.zeros(0),
            np.zeros((0, 6)),
            np.zeros(0, bool),
        )
    )


def _stats(um: np.ndarray, area: np.ndarray, target: float, tol: float) -> dict:
    from sprayplan.coating.report import weighted_stats

    return weighted_stats(um, area, target - tol, target + tol)


def film_report(plan: CellPlan, target_um: float, tolerance_um: float, samples: int = 420, seed: int = 0) -> dict:
    """The film over the whole body, per area, per robot and along every seam (the samples within one spray
    radius of an edge between two robots' faces), and ``samples`` measuring points over the whole body
    (``coating.report.coating_report``; seed 003 measured 420)."""
    from sprayplan.coating.report import coating_report

    film = plan.film
    um = film.thickness_um
    area = film.area_mm2
    # each film sample belongs to the part's face whose centroid is nearest (samples are the vertices of a
    # subdivided mesh, shared by neighbouring faces: at an area's edge either face is as right)
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
    out["unreached"] = _stats(um[robot_of < 0], area[robot_of < 0], target_um, tolerance_um)
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


def plan_radius(plan: CellPlan) -> float:
    return float(plan.report.get("spray_radius_mm", 50.0))


def _robot_name(plan: CellPlan, i: int) -> str:
    return plan.cell.robots[i].name if i >= 0 else ""


def plan_cell(part: Part, cell: Cell, job: JobConfig, progress: Progress | None = None) -> CellPlan:
    """Plan a whole body in a cell of fixed-base arms (module docstring).

    Raises
    ------
    ConfigError
        For a gantry cell (``sprayplan plan`` plans those), a point cloud, or the placement's errors
        (:func:`~sprayplan.cells.spec.place_part`).
    """
    from sprayplan.coating.stage import meet_thickness, process_for
    from sprayplan.surface.region import drop_floor_facing

    progress = progress or no_progress
    if cell.is_gantry:
        raise ConfigError(f"cell {cell.name!r} is the gantry cell: `sprayplan plan` without --cell plans it")
    if not part.is_mesh:
        raise ConfigError(f"{part.name}: a cell plan needs a mesh (areas are found on meshes)")
    timings: dict[str, float] = {}
    running: list = [None, time.perf_counter()]

    def begin(name: str | None) -> None:
        """The step before ``name`` ends (its wall time kept) and ``name`` starts (``progress(name, 0, 0)``)."""
        now = time.perf_counter()
        if running[0] is not None:
            timings[running[0]] = round(now - running[1], 3)
        running[:] = [name, now]
        if name is not None:
            progress(name, 0, 0)

    begin("place")

    placed = place_part(part, cell)
    painted = placed.part
    left_out = 0.0
    if job.collision.skip_floor_facing:
        painted, left_out = drop_floor_facing(painted, job.collision.floor_facing_deg)
    begin("areas")
    job, chosen = meet_thickness(job)
    areas = segment_areas(painted)
    reach = reach_matrix(cell, painted, areas.face_normals, job.paths.standoff_mm)
    assignment = assign_areas(areas, painted.face_areas, reach)
    begin("paths and kinematics")
    robots = tuple(_robot_work(r, i, painted, areas, assignment, job) for i, r in enumerate(cell.robots))
    begin("film")
    report = {"spray_radius_mm": job.paths.spray_radius_mm, "floor_facing_left_out_mm2": round(left_out, 1)}
    plan = CellPlan(cell, painted, placed.part2cell, areas, assignment, robots, None, report, timings)
    target = job.coating.thickness_um
    everything = [s for r in robots for s in r.strokes]
    if not any(s.spray_on for s in everything):
        raise InputError(f"{part.name}: no robot of cell {cell.name!r} has anything to paint")
    paths = Paths(tuple(everything), job.paths.standoff_mm, job.paths.spacing or 0.0, part.name)
    process = process_for(job)
    coating = job.coating.simulation(job.motion)
    film = None
    if target is not None and job.tuning.tune_speed:
        from sprayplan.refine.stage import tuning_settings
        from sprayplan.refine.tuning import tune_speeds, tuned_film

        tuning = tune_speeds(
            painted,
            paths,
            process,
            target,
            job.coating.tolerance,
            config=tuning_settings(job.tuning),
            coating=coating,
            progress=per_stage(progress, "film"),
        )
        tuned = iter(tuning.paths.strokes)
        robots = tuple(dataclasses.replace(r, strokes=tuple(next(tuned) for _ in r.strokes)) for r in robots)
        film = tuned_film(tuning, process, coating)
    elif target is not None or job.output.simulate:
        from sprayplan.coating.thickness import simulate

        film = simulate(painted, paths, process, config=coating, progress=per_stage(progress, "film"))
    begin("report")
    speed = job.motion.gun_speed_mm_s
    transfer = job.motion.transfer_speed_mm_s
    cycle = {r.name: round(r.cycle_time_s(speed, transfer), 3) for r in robots}
    report.update(
        {
            "chosen_for_thickness": chosen,
            "areas": len(areas),
            "robots": {
                r.name: {
                    "strokes": sum(1 for s in r.strokes if s.spray_on),
                    "waypoints": r.waypoints,
                    "unreached_waypoints": int((~r.reachable).sum()),
                    "painted_mm2": round(float(assignment.robot_area_mm2[i]), 1),
                    "cycle_time_s": cycle[r.name],
                }
                for i, r in enumerate(robots)
            },
            "unreached_surface_mm2": round(assignment.unreached_mm2, 1),
            "cycle_time_s": max(cycle.values()) if cycle else 0.0,
            "cycle_time_rule": "length over speed per robot; the cell's is the longest robot's",
        }
    )
    plan = dataclasses.replace(plan, robots=robots, film=film, report=report)
    if film is not None and target is not None:
        report["film"] = film_report(plan, target, job.coating.tolerance, samples=job.output.samples or 420, seed=0)
    begin(None)
    return dataclasses.replace(plan, report=report, timings_s=timings)
