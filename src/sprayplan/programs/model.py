"""What every robot program is made of, whatever its format: moves, and the robot they are written for.

A program is a list of :class:`Move`: a linear move of the TCP to a pose (``movel``/``movep``, ``MoveL``/
``TriggL``, ``LIN``) or a joint move to joint values (``movej``, ``MoveAbsJ``, ``PTP``), each with its speed,
its blend radius (0: the robot stops at the target) and the gun events switched on the way. The writers
(``urscript``, ``rapid``, ``krl``) turn moves into text and their readers turn the text back into moves, so that
:mod:`sprayplan.programs.check` compares what a controller would run with the plan.

Frames and units (docs/programs.md): poses are the TCP's in the part frame (the plan's world), mm, as 4 x 4
``tcp2part``; joints q1..q6 in rad; the gantry's axes (external axes) in mm. The TCP is the spray target,
``gun2flange @ target2gun`` (seed 000's T_tool then T_dis). Each format converts once, at its boundary
(URScript metres and rotation vectors, RAPID quaternions scalar first, KRL A, B, C about Z, Y, X in degrees).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from sprayplan.errors import PartFileError
from sprayplan.robots.gantry import Gantry, trans
from sprayplan.robots.model import fk
from sprayplan.robots.ur_ik import nearest_equivalent, ur_ik

#: Move kinds.
LINEAR, JOINT = "linear", "joint"


@dataclass(frozen=True)
class Move:
    """One motion of a program.

    Attributes
    ----------
    kind : {"linear", "joint"}
    role : str
        What it is for: ``spray`` (to a plan waypoint), ``approach``, ``retract``, ``transfer`` (the joint move
        to an approach pose), ``home``, ``via`` (a point inserted on a spray segment to place a gun event), ``route`` (a joint move to a
        waypoint of a transfer the collision stage re-routed).
    pose : (4, 4) float, mm
        The TCP's pose at the target, in the part frame (for a joint move: the pose its joints give).
    joints : (6,) float, rad
        The arm's joints at the target (a linear move's are those its configuration data stand for).
    external_mm : (3,) float, mm
        The gantry's axes at the target.
    speed_mm_s : float
        TCP speed of a linear move (0 for joint moves, whose speed is a setting).
    blend_mm : float
        Blend radius at the target; 0: the robot stops there.
    events : tuple of (float, bool)
        Gun signals switched on the way: (distance before the target along the move, mm; on).
    source : tuple
        ``(station order, waypoint index in the station)`` for a move to a plan waypoint, else ().
    wait_s : float
        Seconds the robot stands still, the gun off, before the move (a cell schedule's wait before a stroke,
        ``cells.schedule``; written on the run's approach).
    """

    kind: str
    role: str
    pose: np.ndarray
    joints: np.ndarray
    external_mm: np.ndarray
    speed_mm_s: float = 0.0
    blend_mm: float = 0.0
    events: tuple = ()
    source: tuple = ()
    wait_s: float = 0.0


@dataclass(frozen=True)
class StationProgram:
    """The moves of one gantry station, in order: home, the runs (each: transfer, approach, spray moves,
    retract), home.

    Attributes
    ----------
    order : int
        The station's place in the visiting order.
    station : int
        Its number in the plan (``StationPlan.index``).
    platform_mm : (3,) float
    moves : tuple of Move
    """

    order: int
    station: int
    platform_mm: np.ndarray
    moves: tuple


@dataclass(frozen=True)
class CellProgram:
    """A whole plan as moves, ready for a writer.

    Attributes
    ----------
    stations : tuple of StationProgram
    home_mm : (3,) float
        The gantry's home, where it starts and ends.
    home_joints : (6,) float, rad
    tool2flange : (4, 4) float, mm
        The TCP on the flange.
    name : str
        The part's name.
    report : dict
        What the export left out or changed, and why (``summary.json``).
    home : Move
        The joint move home with the gantry at ``home_mm``: where a whole-cell program (RAPID, KRL) starts and
        ends.
    park : Move or None
        Where the program ends when not at ``home`` (a scheduled cell robot's park: ``programs.build.plan_ends``).
    external_axes : int
        How many external axes the moves carry: 3 for the gantry, 1 for a cell robot's track, 0 for a fixed base
        (``programs.arms``).
    external_note, frame_note : str
        What the external axes are and which frame the poses are in (the programs' header comments).
    gun_mm : (3,) float or None
        The gun body on the flange (the tool load's centre of gravity, mm); None: the gantry's gun.
    """

    stations: tuple
    home_mm: np.ndarray
    home_joints: np.ndarray
    tool2flange: np.ndarray
    name: str
    report: dict = field(default_factory=dict)
    home: Move | None = None
    external_axes: int = 3
    external_note: str = "the gantry in eax_a..eax_c / E1..E3 (mm)"
    frame_note: str = "the part frame"
    gun_mm: np.ndarray | None = None
    park: Move | None = None

    def sequence(self) -> list[tuple[Move, str | None]]:
        """Every move of a whole-cell program with a note where a station begins: home, each station's moves
        (each from and back to the arm's home, where the gantry moves), home."""
        out = [(self.home, "home")]
        for st in self.stations:
            p = ", ".join(fixed(v, 4) for v in st.platform_mm)
            note = f"station {st.order + 1} of {len(self.stations)} (plan station {st.station}), gantry at ({p}) mm"
            if self.external_axes != 3:  # a robot of a cell: its whole work is one station
                note = "the robot's work" + (f", track at {p} mm" if len(st.platform_mm) else "")
            out += [(move, note if k == 0 else None) for k, move in enumerate(st.moves)]
        return out + [(self.home if self.park is None else self.park, None)]


@dataclass(frozen=True)
class ReadMove:
    """A move as a reader found it in a program file (units and frames as :class:`Move`).

    Attributes
    ----------
    kind : {"linear", "joint"}
    pose : (4, 4) float or None
        A linear move's target (None for joint moves).
    joints : (6,) float or None
        A joint move's target, rad.
    external_mm : (3,) float or None
        The gantry's axes, where the format carries them (RAPID, KRL).
    speed_mm_s : float
        Linear moves: TCP speed.
    blend_mm : float
    events : tuple of (float, bool)
        Gun signals: (distance before the target, mm; on); the readers convert each format's trigger to this.
    config : tuple
        The configuration data of a linear target: RAPID ``(cf1, cf4, cf6, cfx)``, KRL ``(S, T)``, else ().
    where : str
        ``file:line`` of the move, for messages.
    wait_s : float
        A wait written before the move (RAPID ``WaitTime``, KRL ``WAIT SEC``), s.
    """

    kind: str
    pose: np.ndarray | None
    joints: np.ndarray | None
    external_mm: np.ndarray | None
    speed_mm_s: float
    blend_mm: float
    events: tuple = ()
    config: tuple = ()
    where: str = ""
    wait_s: float = 0.0


class ProgramError(PartFileError):
    """A program file that its reader does not accept (a syntax error, an unknown statement, a broken value):
    names the file and the line."""

    def __init__(self, path, line: int, problem: str):
        super().__init__(f"{path}:{line}" if line else path, problem)


# --- numbers ------------------------------------------------------------------------------------------------


def fixed(value: float, decimals: int) -> str:
    """``value`` with a fixed number of decimals, locale-independent, never ``-0.000`` (Python's formatting
    ignores the locale; a negative zero is written as a zero)."""
    text = f"{float(value):.{decimals}f}"
    if text.startswith("-") and not text.strip("-0."):
        text = text[1:]
    return text


def fixed_down(value: float, decimals: int) -> str:
    """``value`` (>= 0) rounded down to ``decimals`` as :func:`fixed` writes it: a blend radius written never
    exceeds the one computed."""
    scale = 10.0**decimals
    return fixed(math.floor(float(value) * scale + 1e-6) / scale, decimals)


def parse_number(text: str, where: tuple) -> float:
    """A finite decimal number (no ``inf``, ``nan`` or ``_``), else :class:`ProgramError` at ``where``
    (path, line)."""
    text = text.strip()
    if not _NUMBER.fullmatch(text):
        raise ProgramError(*where, f"not a number: {text!r}")
    value = float(text)
    if not math.isfinite(value):
        raise ProgramError(*where, f"not a finite number: {text!r}")
    return value


_NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?")


# --- rotations --------------------------------------------------------------------------------------------


def pose_from(position, rotation: Rotation) -> np.ndarray:
    """(4, 4) from a position (3,) and a scipy rotation."""
    out = np.eye(4)
    out[:3, :3] = rotation.as_matrix()
    out[:3, 3] = position
    return out


def quaternion_wxyz(matrix: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions scalar first (RAPID's order) of rotation matrices (..., 3, 3), with one sign
    for each rotation: the first component farther than 1e-9 from 0 positive (w >= 0 unless w is 0 as written,
    so that a half turn, whose w is 0 up to rounding, is written the same from rotations equal to rounding)."""
    q = Rotation.from_matrix(matrix).as_quat()  # scalar last
    q = np.concatenate([q[..., 3:], q[..., :3]], axis=-1)
    big = np.abs(q) > 1e-9
    first = np.argmax(big, axis=-1)
    lead = np.take_along_axis(q, first[..., None], axis=-1)
    return np.where(lead < 0, -q, q)


def matrix_from_wxyz(q) -> np.ndarray:
    """(3, 3) from a quaternion scalar first (normalised; the readers check its length first)."""
    q = np.asarray(q, float)
    return Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()


def kuka_abc(matrix: np.ndarray) -> np.ndarray:
    """(..., 3) KUKA's A, B, C in degrees: R = Rz(A) Ry(B) Rx(C) (intrinsic Z, Y', X''). At B = +-90 degrees
    (gimbal lock) only A -+ C is defined: C is 0 there (scipy's choice; the same rotation). An angle within 1e-7
    degrees of -180 is written +180 (the same turn), so that rotations equal to rounding are written alike."""
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Gimbal lock detected")
        abc = Rotation.from_matrix(matrix).as_euler("ZYX", degrees=True)
    return np.where(np.abs(abc + 180.0) < 1e-7, 180.0, abc)


def matrix_from_abc(abc_deg) -> np.ndarray:
    """(3, 3) from KUKA's A, B, C in degrees."""
    return Rotation.from_euler("ZYX", abc_deg, degrees=True).as_matrix()


def rotvec(matrix: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors (axis times angle, rad): URScript's orientation."""
    return Rotation.from_matrix(matrix).as_rotvec()


def matrix_from_rotvec(v) -> np.ndarray:
    return Rotation.from_rotvec(np.asarray(v, float)).as_matrix()


def angle_between_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) the rotation angle between rotation matrices (..., 3, 3), degrees (accurate near 0 and near 180:
    ``atan2`` of the relative rotation's sine and cosine)."""
    rel = np.swapaxes(np.asarray(a, float), -1, -2) @ np.asarray(b, float)
    cos = (np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0
    vee = np.stack(
        [rel[..., 2, 1] - rel[..., 1, 2], rel[..., 0, 2] - rel[..., 2, 0], rel[..., 1, 0] - rel[..., 0, 1]], -1
    )
    return np.degrees(np.arctan2(np.linalg.norm(vee, axis=-1) / 2.0, cos))


# --- the robot ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Cell:
    """The gantry and its arm as the programs see them: the TCP at the spray target.

    Attributes
    ----------
    gantry : Gantry
    """

    gantry: Gantry

    #: How many external axes the programs drive (the gantry's x, y, z).
    external_axes = 3

    @property
    def tool2flange(self) -> np.ndarray:
        """The TCP on the flange: the gun's T_tool, then its spray distance T_dis."""
        return self.gantry.gun.gun2flange @ self.gantry.gun.target2gun

    @property
    def spray_distance_mm(self) -> float:
        """From the gun tip to the spray target along the gun axis."""
        return self.gantry.gun.spray_distance_mm

    @property
    def home_joints(self) -> np.ndarray:
        """The arm's joints at home (where every station is solved from)."""
        from sprayplan.robots.stage import HOME_JOINTS

        return HOME_JOINTS.copy()

    def within_limits(self, q) -> np.ndarray:
        return self.gantry.robot.within_limits(q)

    def target_poses(self, q9) -> np.ndarray:
        """(n, 4, 4) the TCP in the part frame for the plan's nine axes (n, 9), by the plan's own chain (eq. 8 of
        seed 000): what the read-back check compares with."""
        return self.gantry.target2world(q9)

    def config_data(self, q6, fmt: str) -> np.ndarray:
        """(n, 4) RAPID ``[cf1, cf4, cf6, cfx]`` or (n, 2) KRL ``[S, T]`` of joints (n, 6)."""
        branch = self.branches(q6)
        return rapid_config(q6, branch) if fmt == "rapid" else krl_status_turn(q6, branch)

    def config_solutions(self, poses, external_mm, config: np.ndarray, fmt: str):
        """(n, 6) joints and (n,) bool valid: the closed-form solution of each pose (n, 4, 4) on the branch its
        configuration data (n, 4) or (n, 2) name, turns as solved (RAPID's cfx = 4 shoulder + 2 elbow + wrist,
        KRL's S = shoulder + 2 elbow + 4 wrist)."""
        config = np.asarray(config, int)
        if fmt == "rapid":
            cfx = config[:, 3]
            use = 4 * (cfx >> 2) + 2 * (cfx & 1) + ((cfx >> 1) & 1)
        else:
            status = config[:, 0]
            use = 4 * (status & 1) + 2 * ((status >> 2) & 1) + ((status >> 1) & 1)
        solutions = self.solutions(poses, external_mm)
        rows = np.arange(len(use))
        return solutions.q[rows, use], solutions.valid[rows, use]

    @property
    def lower(self) -> np.ndarray:
        return self.gantry.robot.lower

    @property
    def upper(self) -> np.ndarray:
        return self.gantry.robot.upper

    def base_poses(self, q6) -> np.ndarray:
        """(n, 4, 4) the TCP in the arm's base frame for joints (n, 6)."""
        return fk(self.gantry.robot, np.atleast_2d(q6)) @ self.tool2flange

    def poses(self, q6, external_mm) -> np.ndarray:
        """(n, 4, 4) the TCP in the part frame for joints (n, 6) with the gantry at (n, 3) or (3,)."""
        q6 = np.atleast_2d(np.asarray(q6, float))
        ext = np.broadcast_to(np.asarray(external_mm, float), (len(q6), 3))
        return self.gantry.base2world(ext) @ self.base_poses(q6)

    def solutions(self, poses, external_mm):
        """All eight closed-form solutions (``ur_ik.URSolutions``) of TCP poses (n, 4, 4) in the part frame
        with the gantry at (n, 3) or (3,)."""
        poses = np.asarray(poses, float).reshape(-1, 4, 4)
        ext = np.broadcast_to(np.asarray(external_mm, float), (len(poses), 3))
        flange = np.linalg.inv(self.gantry.base2world(ext)) @ poses @ np.linalg.inv(self.tool2flange)
        return ur_ik(self.gantry.robot, flange)

    def branches(self, q6) -> np.ndarray:
        """(n,) int: the closed-form branch (``ur_ik.BRANCH_LABELS``) each joint vector (n, 6) lies on."""
        q6 = np.atleast_2d(np.asarray(q6, float))
        flange = fk(self.gantry.robot, q6)
        solutions = ur_ik(self.gantry.robot, flange)
        diff = np.abs(np.angle(np.exp(1j * (solutions.q - q6[:, None, :])))).max(axis=2)
        return np.argmin(np.where(solutions.valid, diff, np.inf), axis=1)

    def joints_on_branch(self, poses, external_mm, branch: int, seed) -> tuple[np.ndarray, np.ndarray]:
        """Joints (n, 6) of TCP poses on one branch, each joint the turn nearest ``seed`` (6,) or (n, 6), and
        whether each is valid (reached, within the limits)."""
        solutions = self.solutions(poses, external_mm)
        q = solutions.q[:, branch]
        q = nearest_equivalent(q, np.broadcast_to(seed, q.shape), self.lower, self.upper)
        ok = solutions.valid[:, branch] & self.within_limits(q)
        return q, ok


def offset_along_z(pose: np.ndarray, distance_mm: float) -> np.ndarray:
    """The pose moved ``distance_mm`` back along its own z axis (away from the surface the gun points at)."""
    return pose @ trans(0.0, 0.0, -distance_mm)


# --- configuration data -------------------------------------------------------------------------------------


def branch_bits(branch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(shoulder, elbow, wrist) bits of ``ur_ik`` branch indices ``4 shoulder + 2 wrist + elbow``: 1 means
    shoulder_right, elbow_down, wrist_down."""
    branch = np.asarray(branch, int)
    return branch >> 2, branch & 1, (branch >> 1) & 1


def rapid_config(q6, branch) -> np.ndarray:
    """(n, 4) int RAPID ``[cf1, cf4, cf6, cfx]``: the quadrants ``floor(q / 90 deg)`` of axes 1, 4 and 6 and
    ``cfx = 4 shoulder + 2 elbow + wrist`` of the UR branch (docs/programs.md: a convention of ours for an arm
    that is not an ABB one)."""
    q6 = np.atleast_2d(np.asarray(q6, float))
    quadrant = np.floor(np.degrees(q6[:, [0, 3, 5]]) / 90.0 + 1e-12).astype(int)
    s, e, w = branch_bits(branch)
    return np.column_stack([quadrant, 4 * s + 2 * e + w])


def krl_status_turn(q6, branch) -> np.ndarray:
    """(n, 2) int KRL ``[S, T]``: ``S = shoulder + 2 elbow + 4 wrist`` of the UR branch (KUKA's bit order:
    overhead area, arm, wrist), ``T`` bit i set when axis i + 1 is negative."""
    q6 = np.atleast_2d(np.asarray(q6, float))
    s, e, w = branch_bits(branch)
    turn = ((q6 < -1e-9).astype(int) << np.arange(6)).sum(axis=1)  # a joint within 1e-9 rad of 0 is 0
    return np.column_stack([s + 2 * e + 4 * w, turn])


@dataclass(frozen=True)
class ReadProgram:
    """A program folder as its reader found it.

    Attributes
    ----------
    fmt : str
        ``urscript``, ``rapid`` or ``krl``.
    tool2flange : (4, 4) float, mm
        The TCP the program sets.
    frame : (4, 4) float, mm
        Where the poses' frame (the part frame) lies: RAPID's work object and KRL's base in the world; for
        URScript the first script's ``part_frame`` in the arm's base frame (each script's in ``scripts``).
    moves : tuple of ReadMove
        Every move, file after file in the order the program runs them.
    scripts : tuple of dict
        URScript: per script file, in the station sequence's order: ``file``, ``station`` (order), ``first``
        (its first move's index in ``moves``), ``count``, ``part_frame`` (4, 4), ``gantry_mm`` (3,), and the
        I/O it uses (``gun``, ``ready``, ``done``). () for the other formats.
    files : tuple of str
        The files read, in order.
    """

    fmt: str
    tool2flange: np.ndarray
    frame: np.ndarray
    moves: tuple
    scripts: tuple = ()
    files: tuple = ()
