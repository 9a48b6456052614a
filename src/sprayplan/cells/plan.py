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
   chose by hand per area), the waypoints facing away from their area left out
   (:func:`~sprayplan.cells.seams.facing_runs`), the pieces joined by spray-off transfers;
5. **kinematics**: each stroke solved by its robot (:func:`~sprayplan.cells.tries.stroke_tries`): first with
   the track held still through the stroke, at the middle of its extent along the track plus an offset; then
   with the track moving with the gun (a coordinated external axis, as paint lines run their rail robots
   along a car): at every waypoint the base stands at the gun tip's own position along the track plus an
   offset. Offsets 0, then 300 and 600 mm either side, clipped to the track's ends, each with the gun turned
   about its axis by 0, 90, 180 and 270 degrees; the tries whose flange passes near the robot's first axis
   (its shoulder singularity: a roof robot over a stroke across the roof) go last. The first try that reaches
   every waypoint with no joint jumping, between two of them or from where the stroke before ends, is kept;
   else the first whole one (:func:`solve_strokes`). Held still the track costs the stroke nothing at the
   timed speeds (a track that follows the gun accelerates with every change of its speed, far slower than
   the arm); one base position does not reach both ends of a 4 m stroke along a car's side, which then
   follows the gun. Along the stroke the branch nearest the previous waypoint's joints is followed
   (``robots.interface.follow_solutions``), each stroke's wrist a whole turn back from where the stroke
   before left it where that keeps it off its limits (:func:`solve_strokes`). Unreached waypoints are data
   (``reachable`` False);
6. **film**: the strokes of all robots together over the whole body, cut to the runs of waypoints their
   robot reaches (:func:`reached_strokes`: an unreached waypoint leaves its surface bare), their speeds tuned
   to the target by
   ``refine.tuning.tune_speeds`` (``[tuning] tune_speed``) in one least-squares problem, so the film where two
   robots' areas meet is tuned like any other; then, for ``[tuning] touch_up_rounds`` rounds, touch-up strokes
   aimed at the patches still under-painted, bare ones on surface a robot reaches included
   (:func:`touch_up_targets`, ``refine.touchup.touch_up_strokes``), each given to the robot
   that reaches most of it (:func:`with_touch_ups`), and all speeds tuned again; then reported over the whole
   body, per area, per robot and along every seam, with seed 003's 420 measuring points (``[output]
   samples``).

**The seam rule: feather where the surface goes on, overlap at edges; then tune** (``seams = "feather"``, the
default). The planner runs every stroke past the edge of its piece (its lead-in and lead-out,
``[paths] edge_margin_mm``) and adds edge passes beyond edges that run with the strokes, so that the film does
not thin out at a part's edge. At a seam the surface does not end: the neighbouring piece goes on, painted by
its own strokes, and those extensions would paint it a second time. So a stroke's extension stops at its first
waypoint that lies over another piece's surface facing the same way
(:class:`~sprayplan.cells.seams.SeamGuard`, :func:`~sprayplan.cells.seams.feathered`), and an edge pass keeps
only what is not over another piece; at a true edge of the body, or at a corner
where the next face turns away (a roof's edge over a side), the extensions stay. Both sides then end at the
seam, each leaving the tapered half of its spray there, and the whole-body tuning evens out the rest.
``seams = "overlap"`` keeps every extension (each side paints over the seam by a lead-out, and the tuning
has to take the doubled film back). ``docs/cells.md`` compares the two on the car body.

Without ``[collision] check`` the cycle time of each robot is its path length over its speeds (spray strokes
at their tuned speeds, transfers at ``[motion] transfer_speed_mm_s``), and the cell's is the longest robot's
(robots of a line work at the same time); every face has one robot, and a robot's strokes stay over its own
share, but the arms' swept spaces are not compared. With it (``--collisions``):

- the areas' reach counts a face only where a robot reaches it free of the part and the floor
  (:func:`~sprayplan.cells.reach.reach_matrix` with the cell's :func:`~sprayplan.cells.collide.cell_arms`), so
  surface reached only through the body (the inner faces of the sills under a car) is unreached, as data;
  with ``[collision] repair``, a face no try along its normal reaches free is tried with the gun tilted by up
  to ``piece_tilt_deg`` (:func:`~sprayplan.cells.reach.reach_tilts`) and counts as reached, though below any
  face reached straight;
- before the film, every robot's strokes are checked and repaired, then cut to what the robot paints free
  (:func:`~sprayplan.cells.collide.freed_cell`, :func:`~sprayplan.cells.repair.free_work`; a run of
  waypoints in collision or unreached solved again on its own, tilted where it must be): a waypoint still
  in collision, or unreached, is left out with the spray off and the runs on either side are joined by a
  transfer, so the film is made only by what the robots can paint, touch-ups cut the same way; after the
  film, the whole plan is checked again for the report (:func:`~sprayplan.cells.collide.check_cell`: what is
  left in collision is in the transfers between runs);
- then every stretch gets its run-up and run-out (:mod:`~sprayplan.cells.runups`, ``[timing] run_up_mm``, with
  the timing; checked against the body here), the robots are timed, and the robots are scheduled
  (:mod:`~sprayplan.cells.schedule`): the robot with the longest work first, a later robot waits,
  spray off, before a stroke that would bring it within the clearance of an earlier one, each robot parks
  when done, and the times of every waypoint, the waits and the cell's cycle time (the longest robot's, with
  its waits, no step faster than its axis and track speeds) go into the plan.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from sprayplan.cells.film import film_at_timed_speeds, film_report, timed_film_summary
from sprayplan.cells.reach import reach_matrix, reach_tilts
from sprayplan.cells.repair import repaired_work
from sprayplan.cells.seams import SEAM_STEP_MM, SeamGuard, cut_stroke, facing_runs, feathered, true_runs
from sprayplan.cells.spec import Cell, place_part
from sprayplan.cells.tries import JOINT_JUMP_RAD, rot_z, start_joints, stroke_tries
from sprayplan.cells.work import RobotWork, joined_transfers, transfer_stroke, with_tuned_dwell
from sprayplan.config import JobConfig
from sprayplan.errors import ConfigError, InputError
from sprayplan.paths.polyline import polyline_length
from sprayplan.progress import Progress, no_progress, per_stage
from sprayplan.surface.areas import AreaAssignment, Areas, assign_areas, segment_areas
from sprayplan.surface.poses import stroke_poses
from sprayplan.types import Part, Paths

log = logging.getLogger(__name__)


def whole_area(part: Part) -> tuple[Areas, AreaAssignment]:
    """One area, the whole painted surface, for the one robot of a single-robot cell (no split: the job's
    ``[paths]`` slice it as a whole, in the direction they say)."""
    from sprayplan.surface.normals import part_outward

    _, normals = part_outward(part)
    area = part.face_areas
    mean = (normals * area[:, None]).sum(axis=0)
    norm = np.linalg.norm(mean)
    m = len(part.faces)
    areas = Areas(np.zeros(m, np.int64), ("all",), ("all",), np.array([area.sum()]),
                  (mean / norm if norm > 0 else mean)[None, :], normals)  # fmt: skip
    return areas, AreaAssignment(np.zeros(m, np.int64), np.zeros(1, np.int64), np.ones(1), np.zeros(1, bool),
                                 np.array([area.sum()]), 0.0)  # fmt: skip


#: A piece of an area under this many spray-circle areas is not sliced on its own: it is too small for a
#: stroke and is painted by the spray of its neighbours.
MIN_PIECE_CIRCLES = 1.0


@dataclass(frozen=True)
class CellPlan:
    """A whole body painted by the robots of a cell (module docstring).

    Attributes
    ----------
    cell : Cell
    part : Part or None
        The painted surface in the cell frame (floor-facing surface left out); None for given strokes
        (:func:`plan_strokes`), as are ``areas`` and ``assignment``.
    part2cell : (4, 4) float
    areas : Areas
    assignment : AreaAssignment
    robots : tuple of RobotWork
    film : CoatingResult or None
    report : dict
        The film over the whole body, per area, per robot and per seam; cycle times; counts.
    timings_s : dict
        Wall seconds of each step.
    name : str
        What was planned (the part's name when there is a part).
    job : JobConfig or None
        The settings the plan was made with, the gun speed and spacing chosen for the film target among them
        (what the robot programs carry, ``programs.arms``).
    timed_film : CoatingResult or None
        The film the robots leave at their timed speeds (``report["film"]["at_timed_speeds"]`` in brief), when
        the plan was timed with a film target; not read back from ``cell_plan.json``.
    obstacle : Part or None
        The surface the arms must not hit: the whole body as placed, the surface left unpainted with it (facing
        the floor, covered, or masked by ``[load] mask``); None: ``part`` (:attr:`collision_part`). Not read
        back from ``cell_plan.json``.
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
    name: str = ""
    job: object = field(default=None, compare=False)
    timed_film: object = field(default=None, compare=False)
    obstacle: object = field(default=None, compare=False)

    @property
    def collision_part(self):
        """The surface the arms are checked against: :attr:`obstacle`, else :attr:`part`."""
        return self.part if self.obstacle is None else self.obstacle


def _sub_part(part: Part, keep: np.ndarray, name: str) -> Part:
    from sprayplan.surface.region import keep_faces

    return dataclasses.replace(keep_faces(part, keep), vertex_normals=None, name=name)


#: The wrist's roll axes of a six-axis arm (the fourth and sixth), which turn more than a whole turn each way.
WRIST_JOINTS = (3, 5)
#: A spray stroke followed from where the stroke before ends that takes a wrist axis nearer its limit than
#: this (rad) is followed again from there with that axis unwound by a whole turn (:func:`solve_strokes`).
WRIST_MARGIN_RAD = math.radians(60.0)


def solve_strokes(cell_robot, strokes, seed=None) -> list[tuple[np.ndarray, float, np.ndarray, np.ndarray]]:
    """For each stroke a (track positions, roll) try and the joints along it (module docstring, step 5):
    ``(track_mm (n,), roll_deg, q (n, 6), reachable (n,))`` a stroke.

    Every try of every stroke is solved, one call of the IK a try index, with the base at track position 0 and
    the poses moved back along the track instead; then the strokes are taken in order, each followed from the
    joints where the spray stroke before it ends (``robots.interface.follow_solutions``). A spray stroke keeps
    the first try that reaches all its waypoints with no joint jumping by more than :data:`JOINT_JUMP_RAD`,
    neither between two waypoints (a first joint at its limit turned back by a whole turn, an arm turned over)
    nor from where the stroke before ends (the transfer between them; over the SUV in ``line3`` the roof robot
    took the same point from two track positions 600 mm apart and turned over at the roof, a transfer no route
    freed); failing the last, the first whole try with no jump along it; failing that, the first whole try;
    else the first that reaches the most.

    **The wrist unwound.** The fourth and sixth axes of an industrial arm turn 400 deg each way; following the
    nearest turns from stroke to stroke, a side robot's wrist winds up (on the SUV in ``line3`` the right robot's
    sixth axis went down a turn more than the left's mirror image, its 5th percentile at -6.27 rad against a
    limit of -6.98), until a stroke runs it into its limit and the try is lost. So a spray stroke that comes
    within :data:`WRIST_MARGIN_RAD` of a wrist axis's limit, followed from ``seed``, is followed again with each
    wrist axis beyond half a turn turned a whole turn back (the same pose: the transfer before it turns the
    wrist round, its gun off), and that one is kept if it is as good (the jumps as above, from the unwound
    joints) and further from the limits.

    ``seed``: the joints the first stroke is followed from, as where a stroke before ended; default
    :func:`~sprayplan.cells.tries.start_joints`, and the first spray stroke keeps any start."""
    from sprayplan.robots.interface import follow_solutions

    arm = cell_robot.robot(0.0)
    axis = np.zeros(3) if cell_robot.track is None else cell_robot.track.axis
    tries = [stroke_tries(cell_robot, s) for s in strokes]
    poses = [stroke_poses(s) for s in strokes]

    def moved(i: int, k: int) -> np.ndarray:
        track, roll = tries[i][k]
        out = poses[i] @ rot_z(roll)
        out[:, :3, 3] -= track[:, None] * axis
        return out

    counts = [np.zeros(len(t), int) for t in tries]  # waypoints reached, per stroke and try
    for k in range(max((len(t) for t in tries), default=0)):
        mine = [i for i in range(len(strokes)) if k < len(tries[i]) and len(strokes[i])]
        if not mine:
            break
        blocks = [moved(i, k) for i in mine]
        reached = arm.ik(np.concatenate(blocks)).reachable
        ends = np.cumsum([0] + [len(b) for b in blocks])
        for j, i in enumerate(mine):
            counts[i][k] = int(reached[ends[j] : ends[j + 1]].sum())
    out = []
    first = seed is None  # no spray stroke before: the first keeps any start
    seed = start_joints(arm.dof) if seed is None else np.asarray(seed, float)
    limits = arm.joint_limits
    wrist = [j for j in WRIST_JOINTS if j < arm.dof and limits[j, 1] - limits[j, 0] > 2 * math.tau - 1e-9]

    def wrist_margin(q):
        if not wrist or not len(q):
            return math.inf
        return float(np.minimum(q[:, wrist] - limits[wrist, 0], limits[wrist, 1] - q[:, wrist]).min())

    def unwound(start) -> list:
        """``[start]``, then ``start`` with each wrist axis beyond half a turn moved a whole turn back, if any."""
        out_ = np.array(start, float)
        for j in wrist:
            if abs(out_[j]) > math.pi:
                out_[j] -= math.copysign(math.tau, out_[j])
        return [start] if np.array_equal(out_, start) else [start, out_]

    for i, s in enumerate(strokes):
        n = len(s)
        if not n or not counts[i].any():
            out.append((tries[i][0][0] if tries[i] else np.zeros(n), 0.0, np.zeros((n, arm.dof)), np.zeros(n, bool)))
            continue
        whole = [k for k in range(len(tries[i])) if counts[i][k] == n]
        chosen = None  # (rank: 0 no jump at all, 1 none along it, 2 whole), try, joints, reached
        starts = [seed] if first or not s.spray_on else unwound(seed)
        for k in whole:
            sols = arm.ik(moved(i, k))
            best = None  # (rank, -wrist margin) of the start kept: the seed's unless it runs near a limit
            for j, start in enumerate(starts):
                if j and best[1] <= -WRIST_MARGIN_RAD:
                    break
                q, branch = follow_solutions(arm, sols, start)
                along = q[branch >= 0]
                jumps = len(along) > 1 and np.abs(np.diff(along, axis=0)).max() > JOINT_JUMP_RAD
                rank = 2 if jumps else 0 if first or np.abs(along[0] - start).max() <= JOINT_JUMP_RAD else 1
                key = (rank, -wrist_margin(along))
                if best is None or key < best:
                    best, got = key, (q, branch)
            rank = best[0]
            q, branch = got
            if chosen is None or rank < chosen[0]:
                chosen = (rank, k, q, branch >= 0)
            if rank == 0 or not s.spray_on:  # (a transfer's ends become its neighbours': joined_transfers)
                break
        if chosen is None:  # no try reaches every waypoint: the first that reaches the most
            k = int(np.argmax(counts[i]))
            q, branch = follow_solutions(arm, arm.ik(moved(i, k)), seed)
            chosen = (3, k, q, branch >= 0)
        _, k, q, reach = chosen
        if reach.any() and s.spray_on:
            seed = q[np.flatnonzero(reach)[-1]]
            first = False
        out.append((*tries[i][k], q, reach))
    return out


def _robot_work(
    cell_robot,
    index: int,
    part: Part,
    areas: Areas,
    assignment: AreaAssignment,
    job: JobConfig,
    guard=None,
    away: dict | None = None,
):
    """One robot's strokes over its share of every area, solved (:func:`solved_work`). ``away``: when given (a
    cell of several robots, its areas segmented), the waypoints of a stroke facing away from its area are left
    out (:func:`~sprayplan.cells.seams.facing_runs`), and ``away[robot name]`` counts them (``{"strokes"`` cut
    or left out, ``"path_mm"}``)."""
    from sprayplan.paths.planner import plan_paths

    radius = job.paths.spray_radius_mm
    labels = len(assignment.robot_area_mm2) + 1  # piece labels: area * labels + robot + 1 (SeamGuard)
    strokes, area_of = [], []
    if away is not None:
        away[cell_robot.name] = {"strokes": 0, "path_mm": 0.0}
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
        for whole in feathered(paths.strokes, guard, a * labels + index + 1):
            kept = [whole]
            if away is not None:
                kept, path_mm = facing_runs(whole, areas.normal[a])
                if path_mm > 0:
                    away[cell_robot.name]["strokes"] += 1
                    away[cell_robot.name]["path_mm"] += path_mm
            for s in kept:
                if strokes:
                    strokes.append(transfer_stroke(strokes[-1], s))
                    area_of.append(-1)
                strokes.append(s)
                area_of.append(a)
    return solved_work(cell_robot, strokes, area_of)


def solved_work(cell_robot, strokes, area_of) -> RobotWork:
    """A robot's strokes (with the area of each, -1 for transfers) solved by its inverse kinematics
    (:func:`solve_strokes`), the transfers joined to their neighbours (:func:`joined_transfers`)."""
    track, roll, qs, ok = [], [], [], []
    for t, r, q, reach in solve_strokes(cell_robot, strokes):
        track.append(t)
        roll.append(np.full(len(q), r))
        qs.append(q)
        ok.append(reach)
    if not strokes:
        empty = np.zeros(0)
        return RobotWork(cell_robot.name, cell_robot.model, (), np.zeros(0, np.int64), empty, empty,
                         np.zeros((0, 6)), np.zeros(0, bool))  # fmt: skip
    work = RobotWork(
        name=cell_robot.name,
        model=cell_robot.model,
        strokes=tuple(strokes),
        area=np.array(area_of, dtype=np.int64),
        track_mm=np.concatenate(track),
        roll_deg=np.concatenate(roll),
        q=np.concatenate(qs),
        reachable=np.concatenate(ok),
    )
    return joined_transfers(work)


def plan_strokes(strokes, cell: Cell, name: str = "") -> CellPlan:
    """Given strokes (a ruled surface's passes, ``paths.ruled``) solved by the one robot of ``cell``: joints at
    every waypoint, no part, no areas, no film (seed 001's joint tables in one command)."""
    if len(cell.robots) != 1 or cell.is_gantry:
        raise ConfigError("given strokes are planned for one fixed-base robot (--robot), not a cell of several")
    start = time.perf_counter()
    work = solved_work(cell.robots[0], list(strokes), [-1 if not s.spray_on else 0 for s in strokes])
    report = {
        "robots": {work.name: {"strokes": sum(1 for s in strokes if s.spray_on), "waypoints": work.waypoints,
                               "unreached_waypoints": int((~work.reachable).sum())}},
        "areas": 0,
    }  # fmt: skip
    return CellPlan(cell, None, np.eye(4), None, None, (work,), None, report,
                    {"kinematics": round(time.perf_counter() - start, 3)}, name)  # fmt: skip


def reached_strokes(robots) -> tuple[list, list]:
    """The spray the robots can make: every spray stroke cut to its runs of reached waypoints (a run of one
    waypoint sprays nothing, so it is left out), all robots one after another. Returns the strokes and, for
    each, ``(robot, stroke, first waypoint, end)`` where it came from. The film is predicted from these, so a
    waypoint no robot reaches leaves its surface bare instead of painted in the model."""
    out, owners = [], []
    for r_i, r in enumerate(robots):
        at = 0
        for s_i, s in enumerate(r.strokes):
            n = len(s)
            if s.spray_on:
                for a, b in true_runs(r.reachable[at : at + n]):
                    out.append(cut_stroke(s, a, b))
                    owners.append((r_i, s_i, a, b))
            at += n
    return out, owners


def spray_path_by_area(robots, n_areas: int, reached_only: bool = True) -> np.ndarray:
    """(n_areas,) mm: the spray path of the robots' spray strokes over each area, along the surface points
    they aim at (a gun tilted by a repair aims at the same ones; touch-ups, of no area, left out): over their
    runs of reached waypoints (:func:`reached_strokes`), or with ``reached_only`` False the whole of every
    stroke. The whole path planned before the collision step and the reached path after it say what the step
    took from each area (``report["collisions"]["areas"]``)."""
    out = np.zeros(n_areas)
    if reached_only:
        strokes, owners = reached_strokes(robots)
        pairs = [(s, robots[r_i].area[s_i]) for s, (r_i, s_i, _a, _b) in zip(strokes, owners)]
    else:
        pairs = [(s, r.area[i]) for r in robots for i, s in enumerate(r.strokes)]
    for stroke, k in pairs:
        if 0 <= k < n_areas and stroke.kind == "spray" and len(stroke) > 1:
            out[int(k)] += polyline_length(stroke.points)
    return out


def extended_deposit(part, strokes, owners, old_owners, samples, old_mm, process, coating):
    """The deposit matrix of the reached strokes ``strokes`` (``owners`` as :func:`reached_strokes` gives them)
    from the last tuning's (``old_owners``, its samples and matrix), after touch-ups were appended to the robots:
    the columns of every run the last tuning had are taken over and only the new runs' computed
    (``refine.stage.with_added_columns``). Returns ``(samples, matrix)``, or None when a run of the last tuning
    is gone (then the matrix is made anew)."""
    from sprayplan.refine.stage import with_added_columns

    where = {owner: k for k, owner in enumerate(owners)}
    if any(owner not in where for owner in old_owners):
        return None
    starts = np.r_[0, np.cumsum([len(s) for s in strokes])]
    is_old = np.zeros(len(strokes), bool)
    is_old[[where[o] for o in old_owners]] = True
    old_at = np.concatenate([np.arange(starts[where[o]], starts[where[o] + 1]) for o in old_owners] or [[]])
    if len(old_at) != old_mm.shape[1] or not (np.diff(old_at) > 0).all():
        return None
    new = [s for s, keep in zip(strokes, is_old) if not keep]
    new_at = np.concatenate([np.arange(starts[k], starts[k + 1]) for k in np.flatnonzero(~is_old)] or [[]])
    return samples, with_added_columns(part, old_mm, samples, old_at, new, new_at, process, coating)


def touch_up_targets(samples, tuned: np.ndarray, face_robot: np.ndarray) -> np.ndarray:
    """(n,) bool: the film samples a cell plan's touch-ups may aim at: those the tuning counted (``tuned``: some
    paint with every time factor 1) and those on a face some robot reaches (``face_robot`` >= 0, the areas'
    assignment), bare or not.

    The single-robot job aims touch-ups only at the painted samples: there the bare surface is what the
    region and the stations leave out on purpose. In a cell every face a robot reaches is to be painted, and
    the bare surface there is what the collision step cut (a run in collision or whose approach would meet the
    body) or a stroke's one try did not reach: 2.0 % of the BMW's area in ``line3`` with ``--collisions`` (0.5 %
    without), 9.2 % of the SUV's, none of it aimed at before. Aimed at, the BMW's bare share went only from 2.0
    to 1.9 %: the touch-ups over it meet the body as the strokes did and are cut or dropped the same way
    (docs/benchmarks.md, "Session 20")."""
    face = samples.part_face
    if face is None:
        return tuned
    reached = np.zeros(len(face), bool)
    on = face >= 0
    reached[on] = face_robot[face[on]] >= 0
    return tuned | reached


def _append(arrays: dict, track, roll, q, ok) -> None:
    """One more stroke (not of an area) on a robot's arrays, as :func:`solve_strokes` gives it."""
    arrays["area"].append([-1])
    arrays["track"].append(track)
    arrays["roll"].append(np.full(len(q), roll))
    arrays["q"].append(q)
    arrays["ok"].append(ok)


def touch_up_order(strokes: list, start, labels=None) -> list:
    """``(label, reversed)`` of ``strokes`` in the order of a greedy nearest-neighbour tour from ``start`` ((3,)
    mm, or None: from the first stroke's start): each next stroke is the one whose start or end (gun tip) is
    nearest the end of the last, run backwards when its end is nearer. ``labels`` default to the indices."""
    labels = list(range(len(strokes))) if labels is None else list(labels)
    if not strokes:
        return []
    ends = np.array([[s.tcp[0], s.tcp[-1]] for s in strokes])  # (n, 2, 3)
    left = np.ones(len(strokes), bool)
    at = ends[0, 0] if start is None else np.asarray(start, float)
    out = []
    for _ in range(len(strokes)):
        d = np.linalg.norm(ends - at, axis=2)  # (n, 2)
        d[~left] = np.inf
        k, back = np.unravel_index(int(np.argmin(d)), d.shape)
        left[k] = False
        out.append((labels[k], bool(back)))
        at = ends[k, 1 - back]
    return out


def with_touch_ups(cell: Cell, robots: tuple, extra: list):
    """The robots with touch-up strokes (``refine.touchup``) added, each to the robot whose inverse kinematics
    reaches most of its waypoints (at least two), after a spray-off transfer from that robot's last stroke;
    ``(robots, how many were added)``, or None when no robot reaches any of them.

    A robot's touch-ups are painted in the order of a nearest-neighbour tour from the end of its last stroke
    (:func:`touch_up_order`), each run whichever way starts nearer: the patches are found all over the body,
    and in the order found the transfers between them crossed it (on the BMW in ``line3`` most of the
    transfers left in collision were between two touch-ups)."""
    if not extra:
        return None
    solved = [solve_strokes(cr, extra) for cr in cell.robots]
    counts = np.array([[int(r[3].sum()) for r in per_robot] for per_robot in solved])  # (robots, strokes)
    best = np.argmax(counts, axis=0)
    grown = [list(r.strokes) for r in robots]
    arrays = [
        {"area": [r.area], "track": [r.track_mm], "roll": [r.roll_deg], "q": [r.q], "ok": [r.reachable]} for r in robots
    ]
    added = 0
    tours = []
    for r in range(len(robots)):
        mine = [k for k in range(len(extra)) if best[k] == r and counts[r, k] >= 2]
        start = grown[r][-1].tcp[-1] if grown[r] else None
        tours += [(r, k, back) for k, back in touch_up_order([extra[k] for k in mine], start, mine)]
    for r, k, back in tours:
        track, roll, q, ok = solved[r][k]
        stroke = extra[k]
        if back:
            stroke, track, q, ok = stroke.reversed(), track[::-1], q[::-1], ok[::-1]
        pieces = [stroke]
        if grown[r]:
            transfer = transfer_stroke(grown[r][-1], stroke)
            pieces.insert(0, transfer)
            (solved_transfer,) = solve_strokes(cell.robots[r], [transfer])
            _append(arrays[r], *solved_transfer)
        grown[r].extend(pieces)
        _append(arrays[r], track, roll, q, ok)
        added += 1
    if not added:
        return None
    out = []
    for r, a, strokes in zip(robots, arrays, grown):
        out.append(
            joined_transfers(
                dataclasses.replace(
                    r,
                    strokes=tuple(strokes),
                    area=np.concatenate([np.asarray(x, np.int64) for x in a["area"]]),
                    track_mm=np.concatenate([np.asarray(x, float) for x in a["track"]]),
                    roll_deg=np.concatenate([np.asarray(x, float) for x in a["roll"]]),
                    q=np.concatenate([np.asarray(x, float).reshape(-1, r.q.shape[1]) for x in a["q"]]),
                    reachable=np.concatenate([np.asarray(x, bool) for x in a["ok"]]),
                )
            )
        )
    return tuple(out), added


#: Before a cell of several robots splits the painted surface into areas, its faces are split until no edge is
#: longer than this, mm (:func:`area_surface`).
AREA_EDGE_MM = 200.0


def schedule_aids(cell, arms, part: Part, job: JobConfig) -> tuple[list, list]:
    """``(backs, routers)`` for ``cells.schedule.scheduled``: each robot's programs' back-off at a run's end
    (``cells.timing.program_back_offs``) and its router (``cells.routes.CellRouter`` against ``part``, the
    part in the cell frame), so that the schedule moves each robot to its park as its program does. (Built
    here: the schedule importing them would close an import cycle through the routes, which ask the schedule
    for parks.)"""
    from sprayplan.cells.routes import CellRouter
    from sprayplan.cells.timing import cell_limits, program_back_offs

    backs = [program_back_offs(r, job, cell_limits(r, job.timing)) for r in cell.robots]
    return backs, [CellRouter(r, a, part, job.collision) for r, a in zip(cell.robots, arms)]


def area_surface(painted: Part) -> tuple[Part, np.ndarray]:
    """The painted surface as a cell of several robots splits it among them: every face with an edge longer
    than :data:`AREA_EDGE_MM` split (:func:`~sprayplan.surface.subdivide.split_part`); and for each face the
    face of ``painted`` it lies in.

    A robot's reach is scored at a face's centre (:func:`~sprayplan.cells.reach.reach_matrix`) and a face
    goes to one robot whole, so a face larger than a robot's margin of reach (the SUV's are up to 1.4 m long)
    went whole to a robot that reaches its centre but not its far end (the bottom band of the SUV's rear hatch,
    19 % of it in spec). Split, such a face is shared along the line where the reach changes, as a finely
    meshed body's is; a car body meshed finer than this (the BMW's) is not changed."""
    from sprayplan.surface.subdivide import split_part

    return split_part(painted, AREA_EDGE_MM)


#: The seam rules :func:`plan_cell` takes (module docstring).
SEAM_RULES = ("feather", "overlap")


def film_settings(job: JobConfig) -> dict:
    """The keywords :func:`~sprayplan.cells.film.film_report` takes from a cell plan's settings: the measuring
    points and the depth a recess is judged within (the standoff plus the collision clearance)."""
    return {
        "samples": job.output.samples or 420,
        "seed": 0,
        "recess_mm": job.paths.standoff_mm + job.collision.clearance_mm,
    }


def plan_cell(
    part: Part, cell: Cell, job: JobConfig, progress: Progress | None = None, seams: str = "feather"
) -> CellPlan:
    """Plan a whole body in a cell of fixed-base arms (module docstring); ``seams`` is the seam rule.

    Raises
    ------
    ConfigError
        For a gantry cell (``sprayplan plan`` plans those), a point cloud, or the placement's errors
        (:func:`~sprayplan.cells.spec.place_part`).
    """
    from sprayplan.coating.stage import meet_thickness, process_for
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import painted_surface

    progress = progress or no_progress
    if seams not in SEAM_RULES:
        raise ConfigError(f"seams: must be one of {', '.join(SEAM_RULES)}, got {seams!r}")
    if cell.is_gantry:
        raise ConfigError(f"cell {cell.name!r} is the gantry cell: `sprayplan plan` without --cell plans it")
    if not part.is_mesh:
        raise ConfigError(f"{part.name}: a cell plan needs a mesh (areas are found on meshes)")
    if job.collision.check:  # before the work: every arm needs its link sizes
        from sprayplan.collision.arms import arm_radii

        for r in cell.robots:
            arm_radii(r.model)
    arms = None
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
    cell = placed.cell  # its lifts at their heights over this part
    # oriented once, as a whole: each robot's share then keeps the body's outward side (a share voted on
    # alone can turn a piece of the nose inward)
    whole = oriented_part(placed.part)
    painted, left_out = painted_surface(whole, job.collision)
    # the arms must not hit any of the body: the surface left unpainted (facing the floor, covered, or masked
    # by [load] mask, in the part's own frame) is there all the same
    obstacle = whole
    if job.load.mask:
        from sprayplan.surface.region import mask_out

        painted, masked = mask_out(painted, job.load.mask, placed.part2cell)
        left_out["masked_left_out_mm2"] = masked
    if len(cell.robots) > 1:
        painted, _ = area_surface(painted)
    begin("areas")
    job, chosen = meet_thickness(job)
    if job.collision.check:
        from sprayplan.cells.collide import cell_arms

        arms = cell_arms(cell, obstacle, job.collision)
    if len(cell.robots) == 1:
        areas, assignment = whole_area(painted)
    else:
        areas = segment_areas(painted)
        tilts = ()  # tilted tries where the plan paints tilted: its pieces solved again (cells.repair)
        if job.collision.check and job.collision.repair:
            tilts = reach_tilts(job.collision.piece_tilt_deg)
        reach = reach_matrix(cell, painted, areas.face_normals, job.paths.standoff_mm, arms=arms, tilts_deg=tilts)
        assignment = assign_areas(areas, painted.face_areas, reach)
    begin("paths and kinematics")
    guard = None
    if seams == "feather":
        labels = len(cell.robots) + 1
        guard = SeamGuard(
            painted, areas.face_area * labels + assignment.face_robot + 1, areas.face_normals, SEAM_STEP_MM
        )
    away = {} if len(cell.robots) > 1 else None  # the waypoints facing away from their areas, left out
    robots = tuple(_robot_work(r, i, painted, areas, assignment, job, guard, away) for i, r in enumerate(cell.robots))
    if away and any(v["strokes"] for v in away.values()):
        log.info(
            "strokes facing away from their areas, cut or left out: %s",
            ", ".join(f"{k} {v['strokes']} ({v['path_mm'] / 1000:.2f} m)" for k, v in away.items()),
        )
    freed: dict = {}  # per robot: the repairs', the cut's and the routes' counts (--collisions)
    unrouted: dict = {}  # per robot: the transfers no route freed (cells.routes.routed_work)

    def free(robots_, repair=None, since=None):
        """``robots_`` cut to what they paint free of the body (``cells.collide.freed_cell``), the counts kept."""
        from sprayplan.cells.collide import freed_cell

        robots_, counts = freed_cell(
            cell,
            robots_,
            arms,
            job.collision,
            repair,
            obstacle,
            job.paths.standoff_mm,
            unrouted,
            since,
            approach_mm=job.export.approach_mm,
        )
        for name, entry in counts.items():
            mine = freed.setdefault(name, {})
            for key, value in entry.items():
                mine[key] = value if key.startswith("strokes_") else mine.get(key, 0) + value
        return robots_

    if job.collision.check:
        begin("collisions")
        path_before = spray_path_by_area(robots, len(areas), reached_only=False)  # mm, for the report
        robots = free(robots, repaired_work)
        path_after = spray_path_by_area(robots, len(areas))
        log.info(
            "collision step: spray path kept per area %s",
            ", ".join(f"{n} {a / b:.0%}" for n, a, b in zip(areas.names, path_after, path_before) if b > 0),
        )
    begin("film")
    report = {
        "spray_radius_mm": job.paths.spray_radius_mm,
        "floor_facing_left_out_mm2": round(left_out.get("floor_facing_left_out_mm2", 0.0), 1),
        "covered_left_out_mm2": round(left_out.get("covered_left_out_mm2", 0.0), 1),
        **({"masked_left_out_mm2": round(left_out["masked_left_out_mm2"], 1)} if job.load.mask else {}),
        **(
            {"facing_away_left_out": {k: {**v, "path_mm": round(v["path_mm"], 1)} for k, v in away.items()}}
            if away is not None
            else {}
        ),
    }
    plan = CellPlan(cell, painted, placed.part2cell, areas, assignment, robots, None, report, timings, job=job,
                    obstacle=obstacle)  # fmt: skip
    target = job.coating.thickness_um
    everything, film_owners = reached_strokes(robots)
    if not everything:
        raise InputError(f"{part.name}: no robot of cell {cell.name!r} has anything to paint")
    paths = Paths(tuple(everything), job.paths.standoff_mm, job.paths.spacing or 0.0, part.name)
    process = process_for(job)
    coating = job.coating.simulation(job.motion)
    film = tuning = None
    if target is not None and job.tuning.tune_speed:
        from sprayplan.refine.stage import tuning_settings
        from sprayplan.refine.touchup import TOUCH_UP_MIN_DWELL, touch_up_strokes
        from sprayplan.refine.tuning import tune_speeds, tuned_film

        earlier: list = []  # the last tuning's owners, samples and deposit matrix, for the next round

        def tuned(robots_):
            strokes, owners_ = reached_strokes(robots_)
            lower = np.concatenate(
                [np.full(len(s), TOUCH_UP_MIN_DWELL if s.kind == "touch-up" else job.tuning.min_dwell) for s in strokes]
            )
            paths_ = Paths(tuple(strokes), job.paths.standoff_mm, job.paths.spacing or 0.0, part.name)
            deposit = extended_deposit(painted, strokes, owners_, *earlier, process, coating) if earlier else None
            earlier.clear()  # the earlier matrix is freed before the tuning
            tuning_ = tune_speeds(
                painted,
                paths_,
                process,
                target,
                job.coating.tolerance,
                config=tuning_settings(job.tuning),
                coating=coating,
                lower=lower,
                deposit=deposit,
                progress=per_stage(progress, "film"),
            )
            earlier[:] = [owners_, tuning_.samples, tuning_.deposit_mm]
            return tuning_, with_tuned_dwell(robots_, tuning_.paths.strokes, owners_)

        tuning, robots = tuned(robots)
        added = 0
        for _ in range(job.tuning.touch_up_rounds):
            radius = job.paths.spray_radius_mm
            extra = touch_up_strokes(
                tuning.samples,
                tuning.after_um,
                touch_up_targets(tuning.samples, tuning.tuned, assignment.face_robot),
                target,
                job.coating.tolerance,
                standoff_mm=job.paths.standoff_mm,
                step_mm=job.paths.step_mm,
                lead_mm=radius,
                min_area_mm2=radius * radius / 4.0,
            )
            grown = with_touch_ups(cell, robots, extra)
            if grown is None:
                break
            before = {r.name: len(r.strokes) for r in robots}
            robots, count = grown
            if job.collision.check:  # the touch-ups cut to what they paint free, as the strokes were
                robots = free(robots, since=before)
            added += count
            tuning = None  # (its deposit matrix lives on in ``earlier`` until the extended one is made)
            tuning, robots = tuned(robots)
        report["touch_up_strokes"] = added
        film = tuned_film(tuning, process, coating)
        film_owners = earlier[0]
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
                    "unreached_waypoints": int((~r.reachable).sum())
                    + freed.get(r.name, {}).get("left_out_unreached", 0),
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
        report["film"] = film_report(plan, target, job.coating.tolerance, **film_settings(job))
    if job.collision.check:
        from sprayplan.cells.collide import check_cell

        begin("collision check")
        robots, report["collisions"] = check_cell(plan, job.collision, arms=arms)
        for name, entry in freed.items():
            report["collisions"]["robots"][name].update(entry)
        report["collisions"]["left_out_waypoints"] = {
            key: int(sum(entry.get(key, 0) for entry in freed.values()))
            for key in ("left_out_in_collision", "left_out_unreached", "left_out_alone", "left_out_unapproachable")
        }
        report["collisions"]["areas"] = {
            name: {
                "spray_path_mm": round(float(path_before[k]), 1),
                "kept_mm": round(float(path_after[k]), 1),
                "kept_share": round(float(path_after[k] / path_before[k]), 4) if path_before[k] > 0 else None,
            }
            for k, name in enumerate(areas.names)
        }
        plan = dataclasses.replace(plan, robots=robots)
    if job.timing.enabled and job.timing.run_up_mm > 0:
        from sprayplan.cells.runups import with_run_ups

        begin("run-ups")
        robots, report["run_ups"] = with_run_ups(
            cell, plan.robots, job, arms if job.collision.check else None, obstacle if job.collision.check else None
        )
        plan = dataclasses.replace(plan, robots=robots)
    if job.timing.enabled:
        from sprayplan.cells.timing import timed_cell

        begin("timing")
        timed_work = None
        if job.timing.fit_flow and tuning is not None and target is not None:
            from sprayplan.cells.fit import fit_cell_flow

            job, timed_work, process, film = fit_cell_flow(plan, job, tuning, film_owners, everything, coating, report)
            plan = dataclasses.replace(plan, job=job, film=film)
        if job.tuning.limit_rounds and tuning is not None and target is not None:
            from sprayplan.cells.limits import tune_cell_within_limits
            from sprayplan.cells.timing import time_cell
            from sprayplan.refine.tuning import tuned_film

            backs: dict = {}  # the programs' back-offs, the same in every round
            robots, timed_work, tuning, report["within_limits"] = tune_cell_within_limits(
                painted, robots, tuning, film_owners, job, process, coating,
                lambda robots_: time_cell(cell, robots_, job, backs), timed_work,
            )  # fmt: skip
            film = tuned_film(tuning, process, coating)
            plan = dataclasses.replace(plan, robots=robots, film=film)
            report["film"] = film_report(plan, target, job.coating.tolerance, **film_settings(job))
        robots = timed_cell(cell, robots, job, report, timed_work)
        plan = dataclasses.replace(plan, robots=robots)
        if film is not None and target is not None:
            timed = film_at_timed_speeds(plan, film_owners, tuning, everything, process, coating)
            plan = dataclasses.replace(plan, timed_film=timed)
            report["film"]["at_timed_speeds"] = timed_film_summary(
                dataclasses.replace(plan, film=timed),
                target,
                job.coating.tolerance,
                report["film"]["report"]["measuring_points"]["indices"],
            )
    if job.collision.check:
        begin("schedule")
        from sprayplan.cells.schedule import scheduled

        robots = scheduled(cell, robots, arms, job, *schedule_aids(cell, arms, obstacle, job))
        report["schedule"] = robots[1]
        robots = robots[0]
        if not report["collisions"]["robots_kept_apart"].startswith("in space"):
            left = sum(report["schedule"]["conflicts"].values())
            report["collisions"]["robots_kept_apart"] = (
                "in time (the schedule's waits)"
                if not left
                else f"not proven: {left} samples of the schedule too close"
            )
        report["cycle_time_s"] = report["schedule"]["cycle_time_s"]
        for name, seconds in report["schedule"]["robot_time_s"].items():
            entry = report["robots"][name]
            entry.setdefault("length_over_speed_s", entry["cycle_time_s"])
            entry["cycle_time_s"] = seconds
        report["cycle_time_rule"] = (
            "the schedule's: each robot's timed work with its waits and its park"
            if job.timing.enabled
            else "the schedule's: path length over speed per robot with its waits"
        )
        plan = dataclasses.replace(plan, robots=robots)
    begin(None)
    return dataclasses.replace(plan, report=report, timings_s=timings)
