"""Robot programs for the robots of a cell (``sprayplan plan --cell NAME --program rapid``): one program a robot.

A robot's work in a cell plan (``cells.plan.RobotWork``: its strokes in order, the joints and the track position
at every waypoint) is written by the same builder, writers, readers and read-back check as the gantry's
programs (``programs.build``, ``programs.rapid``, ``programs.krl``, ``programs.check``), with two adapters:

- :class:`ArmCell` is the robot as the programs see it: the arm (an industrial OPW arm or a UR arm) at its base
  in the cell frame, its track as one external axis (``eax_a`` / ``E1``, mm along the track; none without a
  track), the TCP at the spray target (the gun tip, then the plan's standoff along the gun axis), and the
  configuration data of its joints;
- :func:`arm_plan` makes the robot's work a plan of one station (all its strokes, in the plan's order), with its
  home at the arm's start joints (``cells.tries.START_JOINTS``) and the track where the first waypoint has it.

Poses are the TCP's in the cell frame (the work object / base is the identity: the controller's world frame is
the cell's, the robot's base frame at ``base2cell``, moved along the track by the external axis). Waypoints the
plan leaves unreached or finds in collision (``--collisions``) are left out with the gun off, as the gantry's
unreachable ones are: a program never drives the arm into the body where the plan knows it would.

Configuration data of an industrial arm, read from the arm's geometry at the joints (:func:`arm_config_bits`):

- RAPID ``cfx`` (ABB's confdata, three properties coded 0..7): ``4 * (wrist centre behind axis 1) + 2 * (wrist
  centre behind the lower arm) + (axis 5 negative)``; ``cf1, cf4, cf6`` the quadrants of axes 1, 4, 6;
- KRL ``S`` (KUKA's status): bit 0 the wrist centre in the overhead area (behind axis 1), bit 1 the elbow on the
  side of the stretched arm where the arm stands at its home (axis 3 past the stretched position), bit 2 axis 5
  at or below 0; ``T`` bit i set where axis i + 1 is negative.

"Behind axis 1" is the wrist centre at ``x' < 0`` in the arm's own plane (axis 1 turned by its angle, OPW's
*shoulder_back*); "behind the lower arm" is the wrist centre on the other side of the line from axis 2 to axis 3
from where it is at the maker's zero (``sin phi <= 0`` with ``phi`` the forearm's angle to the upper arm, OPW's
*elbow_down*). A UR arm in a cell keeps the gantry's convention (``model.rapid_config``, ``model.krl_status_turn``:
ours, for an arm that is neither ABB nor KUKA).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sprayplan.errors import ConfigError
from sprayplan.programs.model import krl_status_turn, rapid_config
from sprayplan.robots.gantry import trans
from sprayplan.robots.ur_ik import nearest_equivalent

#: An external axis the programs drive for a robot on a track: the track position, mm.
TRACK_NOTE = "the track in eax_a / E1 (mm along the track)"
NO_AXES_NOTE = "no external axes (a fixed base)"
#: A joint this close to 0 (rad) counts as 0 for the signs in the configuration data: a plan read back from
#: its file (joints to 1e-12 rad) gives the same data.
ZERO_RAD = 1e-9


def _opw_params(arm):
    return getattr(arm, "params", None)


def arm_config_bits(params, q6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(back, behind, wrist) bool (n,) of an OPW arm's joints (n, 6): the wrist centre behind axis 1, the wrist
    centre behind the lower arm, axis 5 negative (module docstring; the geometry of ``robots.opw``)."""
    q6 = np.atleast_2d(np.asarray(q6, float))
    t = q6 * params.signs + params.offsets
    t2, t23 = t[:, 1], t[:, 1] + t[:, 2]
    x_plane = params.a1 + params.c2 * np.sin(t2) + params.c3 * np.sin(t23) + params.a2 * np.cos(t23)
    phi = t[:, 2] + math.atan2(params.a2, params.c3)
    return x_plane < 0.0, np.sin(phi) <= 0.0, q6[:, 4] < -ZERO_RAD


def abb_config(params, q6) -> np.ndarray:
    """(n, 4) int RAPID ``[cf1, cf4, cf6, cfx]`` of an OPW arm's joints (module docstring)."""
    q6 = np.atleast_2d(np.asarray(q6, float))
    quadrant = np.floor(np.degrees(q6[:, [0, 3, 5]]) / 90.0 + 1e-12).astype(int)
    back, behind, wrist = arm_config_bits(params, q6)
    return np.column_stack([quadrant, 4 * back + 2 * behind + wrist])


def kuka_status_turn(params, q6) -> np.ndarray:
    """(n, 2) int KRL ``[S, T]`` of an OPW arm's joints (module docstring)."""
    q6 = np.atleast_2d(np.asarray(q6, float))
    back, behind, _ = arm_config_bits(params, q6)
    status = back.astype(int) + 2 * (~behind).astype(int) + 4 * (q6[:, 4] <= ZERO_RAD).astype(int)
    turn = ((q6 < -ZERO_RAD).astype(int) << np.arange(6)).sum(axis=1)
    return np.column_stack([status, turn])


#: The program format each maker's controller runs (a preset's name starts with the maker).
MAKER_FORMATS = {"abb": "rapid", "kuka": "krl"}


def format_refusal(name: str, model: str, fmt: str) -> str | None:
    """Why robot ``name`` (``model``) gets no ``fmt`` program, or None: an ABB arm's controller runs RAPID and a
    KUKA arm's KRL (the other format's configuration data and axis conventions are not the arm's); URScript is
    the gantry's; a UR arm or an arm from a robot file takes RAPID or KRL with the gantry's convention."""
    if fmt == "urscript":
        return f"robot {name}: URScript is written for the gantry's UR arm; a cell's robots get rapid or krl"
    maker = str(model).split("-", 1)[0].lower()
    wanted = MAKER_FORMATS.get(maker)
    if wanted is not None and wanted != fmt:
        return f"robot {name} is an {maker.upper()} arm ({model}): its controller runs {wanted}, not {fmt}"
    return None


@dataclass(frozen=True)
class _Solutions:
    q: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True)
class ArmCell:
    """A robot of a cell as the programs see it (module docstring).

    Attributes
    ----------
    robot : cells.spec.CellRobot
    standoff_mm : float
        From the gun tip to the spray target (the plan's ``[paths] standoff_mm``).
    """

    robot: object
    standoff_mm: float
    arm: object = field(init=False, repr=False, compare=False)
    axis: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.robot.is_gantry:
            raise ConfigError(f"robot {self.robot.name}: a gantry's programs are the plan's (sprayplan export)")
        arm = self.robot.robot(0.0)
        if arm.dof != 6:
            raise ConfigError(
                f"robot {self.robot.name} ({self.robot.model}) has {arm.dof} axes: RAPID and KRL programs are "
                "written for six-axis arms"
            )
        object.__setattr__(self, "arm", arm)
        axis = np.zeros(3) if self.robot.track is None else np.asarray(self.robot.track.axis, float)
        object.__setattr__(self, "axis", axis)

    @property
    def name(self) -> str:
        return self.robot.name

    @property
    def external_axes(self) -> int:
        return 0 if self.robot.track is None else 1

    @property
    def target2gun(self) -> np.ndarray:
        return trans(0.0, 0.0, self.standoff_mm)

    @property
    def tool2flange(self) -> np.ndarray:
        """The TCP on the flange: the gun tip (the arm's TCP in the plan), then the standoff along its axis."""
        return self.arm.tcp2flange @ self.target2gun

    @property
    def spray_distance_mm(self) -> float:
        return self.standoff_mm

    @property
    def home_joints(self) -> np.ndarray:
        from sprayplan.cells.tries import start_joints

        return start_joints(6).copy()

    @property
    def lower(self) -> np.ndarray:
        return self.arm.joint_limits[:, 0]

    @property
    def upper(self) -> np.ndarray:
        return self.arm.joint_limits[:, 1]

    def program_fields(self) -> dict:
        """The ``CellProgram`` fields that say what this robot's programs are."""
        return {
            "external_axes": self.external_axes,
            "external_note": NO_AXES_NOTE if self.robot.track is None else TRACK_NOTE,
            "frame_note": f"the cell frame; robot {self.name}'s base at base2cell, moved along its track",
            "gun_mm": self.arm.tcp2flange[:3, 3].copy(),
        }

    def within_limits(self, q) -> np.ndarray:
        return self.arm.within_limits(q)

    def _track(self, external_mm, n: int) -> np.ndarray:
        ext = np.asarray(external_mm, float).reshape(-1, self.external_axes) if self.external_axes else None
        if ext is None:
            return np.zeros(n)
        return np.broadcast_to(ext[:, 0], (n,)) if len(ext) == 1 else ext[:, 0]

    def poses(self, q6, external_mm) -> np.ndarray:
        """(n, 4, 4) the TCP in the cell frame for joints (n, 6) with the track at (n, 1), (1,) or () mm."""
        q6 = np.atleast_2d(np.asarray(q6, float))
        out = self.arm.fk(q6) @ self.target2gun
        out[:, :3, 3] += self._track(external_mm, len(q6))[:, None] * self.axis
        return out

    def target_poses(self, q9) -> np.ndarray:
        """(n, 4, 4) the TCP for the plan's joints and track (n, 6 + axes), by the robot with its base moved to
        each waypoint's track position (``CellRobot.robot``), grouped by position."""
        q9 = np.atleast_2d(np.asarray(q9, float))
        track = q9[:, 6] if self.external_axes else np.zeros(len(q9))
        out = np.zeros((len(q9), 4, 4))
        for value in np.unique(track):
            rows = track == value
            out[rows] = self.robot.robot(float(value)).fk(q9[rows, :6]) @ self.target2gun
        return out

    def solutions(self, poses, external_mm) -> _Solutions:
        """All eight solutions of TCP poses (n, 4, 4) in the cell frame with the track at ``external_mm``."""
        poses = np.array(poses, float).reshape(-1, 4, 4)
        flange = poses @ np.linalg.inv(self.target2gun)
        flange[:, :3, 3] -= self._track(external_mm, len(poses))[:, None] * self.axis
        sols = self.arm.ik(flange)
        return _Solutions(np.asarray(sols.q), np.asarray(sols.valid))

    def branches(self, q6) -> np.ndarray:
        """(n,) int: the IK solution index each joint vector (n, 6) lies on."""
        q6 = np.atleast_2d(np.asarray(q6, float))
        solutions = self.solutions(self.poses(q6, np.zeros(self.external_axes)), np.zeros(self.external_axes))
        diff = np.abs(np.angle(np.exp(1j * (solutions.q - q6[:, None, :])))).max(axis=2)
        return np.argmin(np.where(solutions.valid, diff, np.inf), axis=1)

    def joints_on_branch(self, poses, external_mm, branch: int, seed) -> tuple[np.ndarray, np.ndarray]:
        solutions = self.solutions(poses, external_mm)
        q = nearest_equivalent(solutions.q[:, branch], np.broadcast_to(seed, solutions.q[:, branch].shape),
                               self.lower, self.upper)  # fmt: skip
        return q, solutions.valid[:, branch] & self.within_limits(q)

    def config_data(self, q6, fmt: str) -> np.ndarray:
        """(n, 4) RAPID ``[cf1, cf4, cf6, cfx]`` or (n, 2) KRL ``[S, T]`` of joints (n, 6) (module docstring)."""
        q6 = np.atleast_2d(np.asarray(q6, float))
        params = _opw_params(self.arm)
        if params is None:  # a UR arm: the gantry's convention
            branch = self.branches(q6)
            return rapid_config(q6, branch) if fmt == "rapid" else krl_status_turn(q6, branch)
        return abb_config(params, q6) if fmt == "rapid" else kuka_status_turn(params, q6)

    def config_solutions(self, poses, external_mm, config: np.ndarray, fmt: str):
        """(n, 6) joints and (n,) bool: the solution of each pose whose configuration data (cfx, or S) are the
        written ones (turns as solved); not valid where none is."""
        config = np.asarray(config, int)
        solutions = self.solutions(poses, external_mm)
        n, k = solutions.valid.shape
        flat = solutions.q.reshape(-1, 6)
        column = 3 if fmt == "rapid" else 0
        written = config[:, column]
        found = self.config_data(flat, fmt)[:, column].reshape(n, k)
        match = (found == written[:, None]) & solutions.valid
        pick = np.argmax(match, axis=1)
        rows = np.arange(n)
        return solutions.q[rows, pick], match[rows, pick]


@dataclass(frozen=True)
class ArmStation:
    """A robot's whole work as the one station of a plan (the fields ``programs.build`` reads)."""

    index: int
    strokes: tuple
    q9: np.ndarray
    reachable: np.ndarray
    platform_mm: np.ndarray
    repair: np.ndarray
    method: np.ndarray
    wait_s: np.ndarray | None = None
    collides: np.ndarray | None = None
    leads: np.ndarray | None = None  # (n, 2, 6 + axes): the run-ups' starts and run-outs' ends (NaN: none)


@dataclass(frozen=True)
class ArmPlan:
    """A robot's work as a plan for the programs: one station, its home where the track starts.

    Attributes
    ----------
    name : str
    stations : tuple of ArmStation
    home_mm : (axes,) float
    left_in_collision : int
        Waypoints the plan reaches but finds in collision, left out of the program.
    ends_joints : (2, 6) float or None
        Where the program starts and ends (rad) when the robot's work is scheduled (``RobotWork.ends_q``: where
        the cell's schedule has it when the cycle starts and ends); None: at the arm's home joints.
    ends_mm : (2, axes) float or None
        The track positions there (none for a fixed base), mm.
    park_route : tuple or None
        ``(joints (m, 6), track positions (m, axes))``: the nodes the program moves through (joint moves) after
        its last run, before its end park (``RobotWork.park_route_q``); None: straight to the park.
    """

    name: str
    stations: tuple
    home_mm: np.ndarray
    left_in_collision: int = 0
    ends_joints: np.ndarray | None = None
    ends_mm: np.ndarray | None = None
    park_route: tuple | None = None


#: The label (``StationPlan.repair``) of a routed transfer's waypoints in a cell robot's plan: a cell plan keeps
#: no route kind, and the programs treat every kind alike (``programs.build.route_moves``).
ROUTE_LABEL = "detour"


def routed_rows(strokes) -> np.ndarray:
    """(n,) object: :data:`ROUTE_LABEL` at the waypoints of every transfer with waypoints between its ends (one
    ``cells.routes`` routed: a joined transfer has two), empty elsewhere, so that the programs move through
    them (``programs.build.route_moves``) and the check asks for them."""
    labels = [np.full(len(s), ROUTE_LABEL if not s.spray_on and len(s) > 2 else "", dtype=object) for s in strokes]
    return np.concatenate(labels) if labels else np.zeros(0, dtype=object)


def arm_plan(work, cell: ArmCell, name: str = "") -> ArmPlan:
    """The plan of one robot's work (``cells.plan.RobotWork``) for :func:`programs.build.build_program`."""
    n = work.waypoints
    q9 = np.asarray(work.q, float).reshape(n, -1)
    if cell.external_axes:
        q9 = np.column_stack([q9, np.asarray(work.track_mm, float)])
    reachable = np.asarray(work.reachable, bool).copy()
    colliding = np.zeros(n, bool) if work.collides is None else np.asarray(work.collides, bool) & reachable
    home = q9[0, 6:].copy() if n else np.zeros(cell.external_axes)
    waits = None if work.wait_s is None else np.asarray(work.wait_s, float)
    leads = None
    if getattr(work, "lead_q", None) is not None:
        leads = np.asarray(work.lead_q, float)[:, :, :6]
        if cell.external_axes:
            leads = np.concatenate([leads, np.asarray(work.lead_track_mm, float)[:, :, None]], axis=2)
    station = ArmStation(
        0,
        tuple(work.strokes),
        q9,
        reachable,
        home,
        routed_rows(work.strokes),
        np.full(n, "analytic"),
        waits,
        colliding,
        leads,
    )
    ends_q, ends_mm = None, None
    if getattr(work, "ends_q", None) is not None:
        ends_q = np.asarray(work.ends_q, float).reshape(2, -1)
        track = np.asarray(work.ends_track_mm, float).reshape(2, 1)
        ends_mm = track if cell.external_axes else np.zeros((2, 0))
        home = ends_mm[0].copy()
    park_route = None
    if getattr(work, "park_route_q", None) is not None and len(work.park_route_q):
        route_q = np.asarray(work.park_route_q, float).reshape(len(work.park_route_q), -1)
        route_mm = np.asarray(work.park_route_track_mm, float).reshape(-1, 1)
        park_route = (route_q, route_mm if cell.external_axes else np.zeros((len(route_q), 0)))
    return ArmPlan(name or work.name, (station,), home, int(colliding.sum()), ends_q, ends_mm, park_route)


@dataclass(frozen=True)
class RobotPrograms:
    """One robot's programs of a cell plan, built in memory (``programs.stage.Built`` per format)."""

    robot: str
    plan: ArmPlan
    builts: tuple


def build_cell_programs(plan, job, formats, strict=None) -> list[RobotPrograms]:
    """Every robot's programs of a cell plan (``cells.plan.CellPlan``; ``job`` its settings, ``plan.job``: with
    the gun speed the plan chose) in memory, every refusal before anything is written.

    Raises
    ------
    ConfigError
        A robot no format here drives (the five-axis R5150, a gantry), or URScript for a cell robot.
    InputError
        With ``strict``: a spray waypoint a program would leave out.
    """
    from sprayplan.programs.stage import build

    for cr in plan.cell.robots:
        for fmt in formats:
            why = format_refusal(cr.name, cr.model, fmt)
            if why:
                raise ConfigError(f"--program {fmt}: {why}")
    out = []
    for cr, work in zip(plan.cell.robots, plan.robots):
        cell = ArmCell(cr, job.paths.standoff_mm)
        robot_plan = arm_plan(work, cell, f"{plan.name} {cr.name}".strip())
        builts = tuple(build(robot_plan, job, fmt, strict, cell) for fmt in formats)
        out.append(RobotPrograms(cr.name, robot_plan, builts))
    if job.collision.check and getattr(plan, "part", None) is not None:
        check_program_motions(plan, job, out)
    return out


#: The largest joint step (rad) between two samples of a program's motion checked for collisions.
MOTION_STEP_RAD = 0.02


def motions_checked(arm, moves) -> dict:
    """The program's motions that the plan did not check, sampled and checked with the collision model
    (``collision.arms.ArmCollision.collides``): every joint move (home, transfers between runs, routes) and
    every approach, retract, run-up and run-out, each from the move before it, its joints interpolated linearly
    (what a joint move does; the others are straight lines a few centimetres long, which the joints follow closely)
    at most :data:`MOTION_STEP_RAD` apart, the track with them. Spray moves are the plan's own waypoints and
    motions (checked by ``cells.collide``). Returns the counts and the first motions in collision."""
    rows, owners = [], []
    for k in range(1, len(moves)):
        move = moves[k]
        if move.kind == "linear" and move.role not in ("approach", "retract", "run-up", "run-out"):
            continue
        a, b = moves[k - 1], move
        steps = max(1, int(np.ceil(np.abs(b.joints - a.joints).max() / MOTION_STEP_RAD)))
        t = np.linspace(0.0, 1.0, steps + 1)[:, None]
        q = a.joints + t * (b.joints - a.joints)
        ea = np.asarray(a.external_mm, float).reshape(-1)
        eb = np.asarray(b.external_mm, float).reshape(-1)
        track = (ea[0] + t[:, 0] * (eb[0] - ea[0])) if len(ea) else np.zeros(len(t))
        rows.append((q, track))
        owners.append(k)
    if not rows:
        return {"motions_checked": 0, "samples": 0, "motions_in_collision": 0, "first_in_collision": []}
    q = np.concatenate([r[0] for r in rows])
    track = np.concatenate([r[1] for r in rows])
    hit = arm.collides(q, track)
    counts = np.cumsum([0] + [len(r[0]) for r in rows])
    bad = [owners[i] for i in range(len(rows)) if hit[counts[i] : counts[i + 1]].any()]
    return {
        "motions_checked": len(rows),
        "samples": len(q),
        "motions_in_collision": len(bad),
        "first_in_collision": [{"move": k, "role": moves[k].role} for k in bad[:20]],
    }


def check_program_motions(plan, job, built: list[RobotPrograms]) -> None:
    """With ``[collision] check`` and the part at hand: each robot's program motions (:func:`motions_checked`)
    checked against the part and the floor, the result in every format's report (``summary.json``'s
    ``counts.program_motions``)."""
    from sprayplan.cells.collide import cell_arms

    arms = cell_arms(plan.cell, plan.collision_part, job.collision)
    for robot, arm in zip(built, arms):
        if not robot.builts:
            continue
        moves = [m for m, _ in robot.builts[0].program.sequence()]
        found = motions_checked(arm, moves)
        for b in robot.builts:
            b.program.report["program_motions"] = found


def write_cell_programs(folder, built: list[RobotPrograms], job) -> list[dict]:
    """Write :func:`build_cell_programs`' programs into ``folder/<robot>/<format>/``, each read back and checked
    (``programs.stage.write_built``). Returns the summaries, each with its ``robot``."""
    import os

    from sprayplan.programs.stage import write_built

    out = []
    for robot in built:
        job_ = job
        for data in write_built(os.path.join(os.fspath(folder), robot.robot), list(robot.builts), robot.plan, job_):
            out.append({"robot": robot.robot, **data})
    return out
