"""Cells as data: the robots of a paint cell, where they stand, and where the part stands (issue 18; schema in
docs/cells.md).

A cell file is TOML::

    name = "line3"
    floor_z_mm = 0.0                 # the floor (or conveyor) plane, cell frame, mm

    [part]                           # where the part stands (all optional)
    align = "length-x"               # turn the part about z so its longer side runs along x; or "as-is"
    position_mm = [0, 0]             # where its bounding box's centre goes in x, y
    lift_mm = 0.0                    # its lowest point this far above the floor (a skid)
    yaw_deg = 0.0                    # a turn about z after the alignment

    [[robot]]
    name = "roof"                    # unique in the cell
    model = "abb-irb4600-60-205"     # any name of ``sprayplan robots``, or a robot .toml
    tool = "wa101"                   # a gun preset; "none" for the bare flange
    base_mm = [0, 0, 2700]           # the base frame's origin in the cell
    base_rpy_deg = [180, 0, 0]       # its orientation: roll, pitch, yaw about the cell's x, y, z (extrinsic)
    reach_mm = 2050                  # optional: the flange's reach from the base origin (else measured by FK)
    track = {axis = "x", range_mm = [-3000, 3000], speed_mm_s = 1000}   # optional linear track
    lift = {above_part_mm = 1600, range_mm = [3300, 4300]}   # optional: the base's height set per part

A ``gantry-ur5`` (or ``gantry-ur5e``) robot is seed 000's nine-axis gantry: it has no base pose of its own (the
gantry frame is the cell frame) and takes no track.

Everything is checked when the file is read (:func:`load_cell`), each problem one :class:`ConfigError` that
names the file: an unknown key, robot or tool, a track of zero length, two robots at the same place. What needs
the part is checked when the part is placed (:func:`place_part`): a robot whose base stands inside the part's
bounding box, a part that no robot reaches at all. A part partly out of reach is not an error: which surface
is unreached is data of the plan.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from dataclasses import dataclass, field
from importlib import resources

import numpy as np
from scipy.spatial.transform import Rotation

from sprayplan.checks import check_input_file
from sprayplan.errors import ConfigError
from sprayplan.types import Part

#: Two robots' bases (over their tracks) closer than this are "at the same place", mm.
MIN_BASE_GAP_MM = 300.0
#: The gun axis error the five-axis R5150 is allowed in a cell (it cannot turn the gun out of its vertical
#: plane), degrees: seed 000's axis tolerance, as the gantry job allows its SQP fallback.
R5150_AXIS_TOL_DEG = 5.0
#: Track positions sampled for the checks that walk a track.
TRACK_SAMPLES = 33
_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
_CELL_KEYS = {"name", "description", "floor_z_mm", "part", "robot"}
_PART_KEYS = {"align", "position_mm", "lift_mm", "yaw_deg"}
_ROBOT_KEYS = {"name", "model", "tool", "base_mm", "base_rpy_deg", "reach_mm", "track", "lift"}
_TRACK_KEYS = {"axis", "range_mm", "speed_mm_s"}
_LIFT_KEYS = {"above_part_mm", "range_mm"}


@dataclass(frozen=True)
class Track:
    """A linear track: the base moves by ``s * axis`` for ``s`` in ``range_mm``, at up to ``speed_mm_s``."""

    axis: np.ndarray
    range_mm: tuple[float, float]
    speed_mm_s: float

    def positions(self, n: int = TRACK_SAMPLES) -> np.ndarray:
        """(n,) track positions evenly over the range, mm."""
        return np.linspace(self.range_mm[0], self.range_mm[1], n)


@dataclass(frozen=True)
class Lift:
    """A height axis set once per part, before the work (a roof robot's lift, as a line that paints bodies of
    several heights has): the base's height is the part's top plus ``above_part_mm``, kept within
    ``range_mm`` (cell frame z, mm); the robot's ``base_mm`` height is where it stands before a part is placed."""

    above_part_mm: float
    range_mm: tuple[float, float]

    def height_mm(self, part_top_mm: float) -> float:
        """The base's height over a part whose highest point is at ``part_top_mm``."""
        return float(np.clip(part_top_mm + self.above_part_mm, *self.range_mm))


@dataclass(frozen=True)
class CellRobot:
    """One robot of a cell.

    Attributes
    ----------
    name, model, tool : str
    base2cell : (4, 4) float, mm
        The base frame at track position 0 (identity for a gantry).
    reach_mm : float
        The flange's farthest distance from the base origin (NaN for a gantry: its reach is its travel).
    track : Track or None
    lift : Lift or None
        A height set per part (:func:`place_part` sets ``base2cell``'s height by it).
    """

    name: str
    model: str
    tool: str
    base2cell: np.ndarray
    reach_mm: float
    track: Track | None = None
    lift: Lift | None = None

    @property
    def is_gantry(self) -> bool:
        return self.model.startswith("gantry-")

    def base_path_mm(self, n: int = TRACK_SAMPLES) -> np.ndarray:
        """(k, 3) the base origin over the track (one point without a track), mm."""
        origin = self.base2cell[:3, 3]
        if self.track is None:
            return origin[None, :]
        return origin + self.track.positions(n)[:, None] * self.track.axis

    def robot(self, track_mm: float = 0.0):
        """The :class:`~sprayplan.robots.interface.Robot` with its base at track position ``track_mm``."""
        from sprayplan.robots.interface import robot_from_name

        arm = robot_from_name(self.model, None if self.is_gantry and self.tool == "wa101" else self.tool)
        if self.is_gantry:
            return arm
        if self.model == "r5150":  # five axes reach a gun axis only within a tolerance (seed 000's 5 degrees)
            arm = dataclasses.replace(arm, axis_tol_rad=math.radians(R5150_AXIS_TOL_DEG))
        base = self.base2cell.copy()
        if self.track is not None:
            base[:3, 3] += track_mm * self.track.axis
        return at_base(arm, base)


@dataclass(frozen=True)
class Cell:
    """A paint cell (module docstring): its robots, the floor, and how the part is placed.

    ``place = "cell"`` places the part by the ``[part]`` rules; ``"file"`` keeps it where its file has it (the
    file's frame is the cell's: :func:`single_robot_cell`)."""

    name: str
    robots: tuple
    floor_z_mm: float = 0.0
    align: str = "length-x"
    position_mm: tuple[float, float] = (0.0, 0.0)
    lift_mm: float = 0.0
    yaw_deg: float = 0.0
    source: str = ""
    place: str = "cell"
    description: str = field(default="", compare=False)

    @property
    def is_gantry(self) -> bool:
        return len(self.robots) == 1 and self.robots[0].is_gantry


def _presets_dir():
    return resources.files("sprayplan.cells").joinpath("presets")


def list_cells() -> list[str]:
    """The names of the cells shipped with the package."""
    return sorted(p.name.removesuffix(".toml") for p in _presets_dir().iterdir() if p.name.endswith(".toml"))


def load_cell(name_or_path: str | os.PathLike, setting: str = "--cell") -> Cell:
    """The cell preset called ``name_or_path`` (:func:`list_cells`) or the cell file at that path.

    Raises
    ------
    ConfigError
        An unknown preset, an unreadable file, or any bad key or value (the message names the file).
    """
    text = os.fspath(name_or_path)
    if text.endswith(".toml") or os.sep in text:
        check_input_file(text, error=lambda n, problem: ConfigError(f"{n}: cannot read the cell file: {problem}"))
        try:
            with open(text, "rb") as handle:
                data = tomllib.load(handle)
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise ConfigError(f"{text}: not a readable cell file ({exc})") from None
        return cell_from_dict(data, source=text)
    entry = _presets_dir().joinpath(f"{text}.toml")
    if not entry.is_file():
        raise ConfigError(
            f"{setting} {text!r} is not a known cell: use one of {', '.join(list_cells())} or a .toml file"
        )
    return cell_from_dict(tomllib.loads(entry.read_text(encoding="utf-8")), source=f"cell {text}")


def _number(value, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{where}: must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ConfigError(f"{where}: must be above 0, got {value!r}")
    return float(value)


def _vector(value, n: int, where: str) -> np.ndarray:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise ConfigError(f"{where}: must be a list of {n} numbers, got {value!r}")
    return np.array([_number(v, where) for v in value])


def _unknown(table: dict, known: set, where: str) -> None:
    extra = sorted(set(table) - known)
    if extra:
        raise ConfigError(f"{where}: unknown key {extra[0]!r} (known: {', '.join(sorted(known))})")


def _track(table, where: str) -> Track:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: must be a table with axis, range_mm and speed_mm_s")
    _unknown(table, _TRACK_KEYS, where)
    axis = table.get("axis", "x")
    if isinstance(axis, str):
        if axis not in _AXES:
            raise ConfigError(f"{where}.axis: must be x, y, z or a list of 3 numbers, got {axis!r}")
        vec = np.array(_AXES[axis])
    else:
        vec = _vector(axis, 3, f"{where}.axis")
        norm = np.linalg.norm(vec)
        if not norm > 0:
            raise ConfigError(f"{where}.axis: must not be zero")
        vec = vec / norm
    if "range_mm" not in table:
        raise ConfigError(f"{where}.range_mm: missing (the track's two ends, mm)")
    lo, hi = _vector(table["range_mm"], 2, f"{where}.range_mm")
    if not hi > lo:
        raise ConfigError(f"{where}.range_mm: the track has zero or negative length ({lo:g} .. {hi:g} mm)")
    speed = _number(table.get("speed_mm_s", 1000.0), f"{where}.speed_mm_s", positive=True)
    return Track(vec, (float(lo), float(hi)), speed)


def _lift(table, base_z: float, where: str) -> Lift:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: must be a table with above_part_mm and range_mm")
    _unknown(table, _LIFT_KEYS, where)
    if "above_part_mm" not in table:
        raise ConfigError(f"{where}.above_part_mm: missing (the base's height over the part's top, mm)")
    above = _number(table["above_part_mm"], f"{where}.above_part_mm", positive=True)
    if "range_mm" not in table:
        raise ConfigError(f"{where}.range_mm: missing (the lowest and highest base heights, mm)")
    lo, hi = _vector(table["range_mm"], 2, f"{where}.range_mm")
    if not hi > lo:
        raise ConfigError(f"{where}.range_mm: the lift has zero or negative length ({lo:g} .. {hi:g} mm)")
    if not lo <= base_z <= hi:
        raise ConfigError(f"{where}.range_mm: the base's height {base_z:g} mm (base_mm) is outside {lo:g} .. {hi:g}")
    return Lift(above, (float(lo), float(hi)))


def at_base(arm, base2world: np.ndarray):
    """The arm with its base at ``base2world`` (the R5150 keeps its base in its D-H model)."""
    if "base2world" in {f.name for f in dataclasses.fields(arm)}:
        return dataclasses.replace(arm, base2world=base2world)
    return dataclasses.replace(arm, model=dataclasses.replace(arm.model, base2world=base2world))


def measured_reach_mm(robot, samples: int = 4096, seed: int = 0) -> float:
    """The flange's farthest distance from the base origin over ``samples`` random joint vectors within the
    limits (seeded), mm: a lower bound of the true reach, within a few mm of it at the default count."""
    rng = np.random.default_rng(seed)
    limits = np.asarray(robot.joint_limits, dtype=float)
    lo = np.clip(limits[:, 0], -math.pi, math.pi)
    hi = np.clip(limits[:, 1], -math.pi, math.pi)
    q = lo + rng.random((samples, len(lo))) * (hi - lo)
    base = np.linalg.inv(robot.base2world)
    flange = base @ robot.fk(q) @ np.linalg.inv(robot.tcp2flange)
    return float(np.linalg.norm(flange[:, :3, 3], axis=1).max())


def _robot(table, where: str) -> CellRobot:
    from sprayplan.robots.interface import robot_from_name

    if not isinstance(table, dict):
        raise ConfigError(f"{where}: must be a table")
    _unknown(table, _ROBOT_KEYS, where)
    name = table.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"{where}.name: every robot needs a name")
    where = f"robot {name!r}"
    model = table.get("model")
    if not isinstance(model, str):
        raise ConfigError(f"{where}.model: missing (a name of `sprayplan robots` or a robot .toml)")
    tool = table.get("tool", "wa101")
    if not isinstance(tool, str):
        raise ConfigError(f"{where}.tool: must be a gun preset name, got {tool!r}")
    try:
        arm = robot_from_name(model, None if model == "r5150" and tool == "wa101" else tool)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    gantry = model.startswith("gantry-")
    if gantry:
        for key in ("base_mm", "base_rpy_deg", "track", "reach_mm", "lift"):
            if key in table:
                raise ConfigError(f"{where}.{key}: a gantry robot has no base pose, track or reach of its own")
        return CellRobot(name, model, tool, np.eye(4), math.nan)
    base = np.eye(4)
    base[:3, 3] = _vector(table.get("base_mm", [0.0, 0.0, 0.0]), 3, f"{where}.base_mm")
    rpy = _vector(table.get("base_rpy_deg", [0.0, 0.0, 0.0]), 3, f"{where}.base_rpy_deg")
    base[:3, :3] = Rotation.from_euler("xyz", rpy, degrees=True).as_matrix()
    track = _track(table["track"], f"{where}.track") if "track" in table else None
    lift = _lift(table["lift"], float(base[2, 3]), f"{where}.lift") if "lift" in table else None
    if "reach_mm" in table:
        reach = _number(table["reach_mm"], f"{where}.reach_mm", positive=True)
    else:
        reach = measured_reach_mm(at_base(arm, np.eye(4)))
    model_tool = "none" if model == "r5150" else tool
    return CellRobot(name, model, model_tool, base, reach, track, lift)


def _base_paths(robot: CellRobot) -> np.ndarray:
    """(k, 3) the base origin over its track, and over its lift's whole range where it has one, mm."""
    path = robot.base_path_mm()
    if robot.lift is None:
        return path
    heights = np.linspace(*robot.lift.range_mm, 9)
    return np.concatenate([np.column_stack([path[:, :2], np.full(len(path), h)]) for h in heights])


def _segment_gap(a: np.ndarray, b: np.ndarray) -> float:
    """The least distance between two sampled base paths ((k, 3) and (l, 3)), mm."""
    return float(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2).min())


def cell_from_dict(data: dict, source: str = "") -> Cell:
    """A :class:`Cell` from a cell file's tables (module docstring); ``source`` names the file in errors."""
    where = source or "cell"
    try:
        if not isinstance(data, dict):
            raise ConfigError("a cell file is a TOML table")
        _unknown(data, _CELL_KEYS, "cell")
        name = data.get("name", os.path.basename(source).removesuffix(".toml") or "cell")
        if not isinstance(name, str):
            raise ConfigError(f"name: must be text, got {name!r}")
        floor = _number(data.get("floor_z_mm", 0.0), "floor_z_mm")
        part = data.get("part", {})
        if not isinstance(part, dict):
            raise ConfigError("[part]: must be a table")
        _unknown(part, _PART_KEYS, "[part]")
        align = part.get("align", "length-x")
        if align not in ("length-x", "as-is"):
            raise ConfigError(f"[part].align: must be 'length-x' or 'as-is', got {align!r}")
        position = _vector(part.get("position_mm", [0.0, 0.0]), 2, "[part].position_mm")
        lift = _number(part.get("lift_mm", 0.0), "[part].lift_mm")
        if lift < 0:
            raise ConfigError(
                f"[part].lift_mm: must not be negative (the part would stand below the floor), got {lift:g}"
            )
        yaw = _number(part.get("yaw_deg", 0.0), "[part].yaw_deg")
        tables = data.get("robot")
        if not isinstance(tables, list) or not tables:
            raise ConfigError("a cell needs at least one [[robot]]")
        robots = tuple(_robot(t, f"robot {i + 1}") for i, t in enumerate(tables))
        names = [r.name for r in robots]
        for i, n in enumerate(names):
            if n in names[:i]:
                raise ConfigError(f"robot {n!r}: two robots have that name")
        if any(r.is_gantry for r in robots) and len(robots) > 1:
            raise ConfigError("a gantry robot is a cell of its own: it cannot share a cell with other robots")
        for i, a in enumerate(robots):
            for b in robots[:i]:
                gap = _segment_gap(_base_paths(a), _base_paths(b))
                if gap < MIN_BASE_GAP_MM:
                    raise ConfigError(
                        f"robots {b.name!r} and {a.name!r} stand at the same place (their bases come within "
                        f"{gap:.0f} mm, under {MIN_BASE_GAP_MM:.0f} mm)"
                    )
        description = data.get("description", "")
        return Cell(
            name,
            robots,
            floor,
            align,
            (float(position[0]), float(position[1])),
            lift,
            yaw,
            source,
            description=str(description),
        )
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


@dataclass(frozen=True)
class PlacedPart:
    """A part in the cell frame.

    Attributes
    ----------
    part : Part
        Its vertices in the cell frame, mm.
    part2cell : (4, 4) float
        Where the part frame sits in the cell: ``part.vertices = part2cell @ original``.
    reach_share : (r,) float
        The share of the part's vertices within each robot's reach sphere over its track (a coarse first
        look, before inverse kinematics).
    cell : Cell
        The cell as it stands for this part: each robot with a ``lift`` at its height over the part
        (:func:`lifted_cell`); the cell given otherwise.
    """

    part: Part
    part2cell: np.ndarray
    reach_share: np.ndarray
    cell: Cell


def lifted_cell(cell: Cell, part_top_mm: float) -> Cell:
    """``cell`` with every robot that has a :class:`Lift` at its height over a part whose top is at
    ``part_top_mm`` (cell frame z, mm)."""
    robots = []
    for r in cell.robots:
        if r.lift is not None:
            base = r.base2cell.copy()
            base[2, 3] = r.lift.height_mm(part_top_mm)
            r = dataclasses.replace(r, base2cell=base)
        robots.append(r)
    return dataclasses.replace(cell, robots=tuple(robots))


def place_part(part: Part, cell: Cell) -> PlacedPart:
    """The part in the cell frame (the cell's ``[part]`` rules), the robots with a lift set to its height
    (:func:`lifted_cell`), checked against the robots.

    Raises
    ------
    ConfigError
        A robot whose base (anywhere on its track) stands inside the part's bounding box, or a part no robot
        reaches at all (no vertex within any robot's reach of its base path). Both name the cell file.
    """
    if cell.place == "file":
        return _checked(part, np.eye(4), cell)
    v = np.asarray(part.vertices, dtype=float)
    turn = 0.0
    if cell.align == "length-x":
        ext = v.max(axis=0) - v.min(axis=0)
        turn = 90.0 if ext[1] > ext[0] else 0.0
    rot = Rotation.from_euler("z", turn + cell.yaw_deg, degrees=True).as_matrix()
    part2cell = np.eye(4)
    part2cell[:3, :3] = rot
    turned = v @ rot.T
    lo, hi = turned.min(axis=0), turned.max(axis=0)
    shift = np.array(
        [
            cell.position_mm[0] - (lo[0] + hi[0]) / 2,
            cell.position_mm[1] - (lo[1] + hi[1]) / 2,
            cell.floor_z_mm + cell.lift_mm - lo[2],
        ]
    )
    part2cell[:3, 3] = shift
    normals = None if part.vertex_normals is None else part.vertex_normals @ rot.T
    return _checked(Part(turned + shift, part.faces, normals, part.name, oriented=part.oriented), part2cell, cell)


def _checked(placed: Part, part2cell: np.ndarray, cell: Cell) -> PlacedPart:
    """The placed part checked against the robots (:func:`place_part`'s errors), the lifts set to it."""
    where = cell.source or f"cell {cell.name}"
    if cell.is_gantry:
        return PlacedPart(placed, part2cell, np.ones(1), cell)
    box_lo, box_hi = placed.vertices.min(axis=0), placed.vertices.max(axis=0)
    cell = lifted_cell(cell, float(box_hi[2]))
    from scipy.spatial import cKDTree

    tree = cKDTree(placed.vertices)
    shares = []
    for robot in cell.robots:
        path = robot.base_path_mm()
        inside = np.all((path > box_lo) & (path < box_hi), axis=1)
        if inside.any():
            raise ConfigError(
                f"{where}: robot {robot.name!r} stands inside the part (its base at "
                f"{np.round(path[np.argmax(inside)]).tolist()} mm is within the part's bounding box)"
            )
        near = np.zeros(len(placed.vertices), bool)
        for hits in tree.query_ball_point(path, robot.reach_mm):
            near[hits] = True
        shares.append(near.mean())
    shares = np.array(shares)
    if not (shares > 0).any():
        raise ConfigError(f"{where}: the part {placed.name!r} is out of every robot's reach")
    return PlacedPart(placed, part2cell, shares, cell)


def single_robot_cell(model: str, tool: str | None = None) -> Cell:
    """A cell of one fixed-base robot (``sprayplan plan --robot ur5``): its base frame is the part file's frame
    (the part stays where its file has it), no track; ``tool`` a gun preset (default ``wa101``; the R5150 takes
    none). Raises :class:`ConfigError` for an unknown robot or a gantry, naming ``--robot``."""
    tool = "none" if model == "r5150" else (tool or "wa101")
    try:
        robot = _robot({"name": model, "model": model, "tool": tool}, "--robot")
    except ConfigError as exc:
        raise ConfigError(f"--robot {model!r}: {str(exc).split(': ', 1)[-1]}") from None
    if robot.is_gantry:
        raise ConfigError(f"--robot {model!r}: a gantry is planned without a cell")
    return Cell(name=model, robots=(robot,), align="as-is", source=f"--robot {model}", place="file")
