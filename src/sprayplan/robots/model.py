"""Robot models as data: standard Denavit-Hartenberg chains with joint limits, and forward kinematics.

A model is a :class:`RobotModel`: the D-H table of seed 000's eq. 10 (standard convention: ``Rot(z, theta)
Trans(z, d) Trans(x, a) Rot(x, alpha)`` per joint), joint offsets and limits. Presets:

``ur5``
    Universal Robots' published table (d1 89.159, a2 -425, a3 -392.25, d4 109.15, d5 94.65, d6 82.3 mm;
    alpha = [pi/2, 0, 0, pi/2, -pi/2, 0]); joints -2 pi .. 2 pi but the elbow, -pi .. pi (below).
``ur5-seed``
    Seed 000's table 1: the same robot with rounded values and a2 = 425, a3 = 392.3 (the opposite sign
    convention). Its joint vector q' reaches the pose of the ``ur5`` joint vector q when
    ``q' = q + (0, pi, 0, -pi, 0, 0)``: negating a2 and a3 turns frames 2 and 3 by pi about their z axes, which
    theta2 + pi puts in and theta4 - pi takes out again (tests/test_kinematics.py checks it).
``ur5e``
    Universal Robots' UR5e table (d1 162.5, a2 -425, a3 -392.2, d4 133.3, d5 99.7, d6 99.6 mm).
``r5150``
    The Lab-Volt R5150 of seed 001, table 2: d1 255.55, a2 190, a3 190, d5 115 mm, alpha1 = alpha4 = pi/2,
    joint ranges -185..153, -32..149, -147..51, -5..180, -360..360 degrees.

Joint speed and acceleration limits (``max_velocity``, ``max_acceleration``; the timing stage,
:mod:`sprayplan.timing`):

UR5, UR5e (and ``ur5-seed``, the same arm)
    180 deg/s on every joint: Universal Robots' technical specifications of the UR5 (CB3: "all joints 180
    deg/s") and of the UR5e (base, shoulder, elbow and the three wrists 180 deg/s). UR publishes no joint
    acceleration limit; the acceleration is 80.2 deg/s^2 (1.4 rad/s^2), the default joint acceleration of
    URScript's ``movej`` (``movej(q, a=1.4, v=1.05)``, the URScript manual), which is also what
    ``[export] joint_acceleration_deg_s2`` writes into the programs. A cell that runs its arm harder sets
    its own figures (``[timing]`` or a robot TOML).
R5150
    Seed 001 gives no speeds and the maker's (Lab-Volt) data sheet was not available: 90 deg/s and
    180 deg/s^2 on every joint are an assumption (a small, geared, stepper-driven teaching arm), marked as such;
    give a real arm's figures in a robot TOML.

Joint position limits of the UR arms: Universal Robots' specifications give +-360 degrees on every joint, but
near +-180 degrees the elbow folds the forearm onto the upper arm and the arm is in self-collision whatever the
other joints do, so the elbow's free range is -pi .. pi and an elbow past it can only be reached through that
fold (the ROS-Industrial UR descriptions limit it the same way for that reason). The collision model has no
upper-arm-against-forearm pair, so the presets limit the elbow (``ELBOW_LIMIT``) instead: every plan's elbow
stays on the side of the fold it starts on.

A user model is a TOML file (see :func:`load_robot`).
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sprayplan.checks import check_input_file
from sprayplan.errors import ConfigError, PartFileError

TAU = 2.0 * math.pi


def _frozen(values, name: str, n: int | None = None) -> np.ndarray:
    out = np.array(values, dtype=float).reshape(-1)
    if n is not None and len(out) != n:
        raise ConfigError(f"{name} must have {n} values, got {len(out)}")
    if not np.isfinite(out).all():
        raise ConfigError(f"{name} must be finite numbers")
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class RobotModel:
    """A serial robot as a standard D-H table.

    Attributes
    ----------
    name : str
    d, a : (dof,) float, mm
    alpha : (dof,) float, rad
    theta_offset : (dof,) float, rad
        Added to the joint value to give the D-H theta (0 for the presets).
    lower, upper : (dof,) float, rad
        Joint limits.
    base2world : (4, 4) float, mm
        Where the robot's base stands in the world (the cell); identity by default.
    tool2flange : (4, 4) float, mm
        The tool (gun) on the flange; identity by default.
    max_velocity : (dof,) float, rad/s, or None
        Each joint's speed limit (None: not known; the timing stage then refuses the model).
    max_acceleration : (dof,) float, rad/s^2, or None
        Each joint's acceleration limit (None: not known).
    """

    name: str
    d: np.ndarray
    a: np.ndarray
    alpha: np.ndarray
    theta_offset: np.ndarray = field(default=None)  # type: ignore[assignment]
    lower: np.ndarray = field(default=None)  # type: ignore[assignment]
    upper: np.ndarray = field(default=None)  # type: ignore[assignment]
    base2world: np.ndarray = field(default=None)  # type: ignore[assignment]
    tool2flange: np.ndarray = field(default=None)  # type: ignore[assignment]
    max_velocity: np.ndarray | None = None
    max_acceleration: np.ndarray | None = None

    def __post_init__(self):
        for name in ("base2world", "tool2flange"):
            value = np.eye(4) if getattr(self, name) is None else np.array(getattr(self, name), dtype=float)
            if value.shape != (4, 4) or not np.isfinite(value).all():
                raise ConfigError(f"{name} must be a finite 4x4 transform")
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        d = _frozen(self.d, "d")
        dof = len(d)
        object.__setattr__(self, "d", d)
        object.__setattr__(self, "a", _frozen(self.a, "a", dof))
        object.__setattr__(self, "alpha", _frozen(self.alpha, "alpha", dof))
        offset = np.zeros(dof) if self.theta_offset is None else self.theta_offset
        object.__setattr__(self, "theta_offset", _frozen(offset, "theta_offset", dof))
        lower = np.full(dof, -TAU) if self.lower is None else self.lower
        upper = np.full(dof, TAU) if self.upper is None else self.upper
        object.__setattr__(self, "lower", _frozen(lower, "lower", dof))
        object.__setattr__(self, "upper", _frozen(upper, "upper", dof))
        if np.any(self.lower > self.upper):
            raise ConfigError(f"robot {self.name}: a lower joint limit exceeds its upper limit")
        for name, key in (("max_velocity", "max_velocity_deg_s"), ("max_acceleration", "max_acceleration_deg_s2")):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, check_rate_limits(getattr(self, name), key, dof, scale=180 / math.pi))

    @property
    def dof(self) -> int:
        """Number of joints."""
        return len(self.d)

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """(n,) bool: joint vectors inside the limits."""
        q = np.atleast_2d(q)
        return ((q >= self.lower - tol) & (q <= self.upper + tol)).all(axis=-1)


def check_rate_limits(values, setting: str, n: int, scale: float = 1.0) -> np.ndarray:
    """(n,) float, read-only: speed or acceleration limits, one per axis, each positive and finite.

    ``setting`` names the key in messages; ``scale`` turns the values into the setting's unit for the message
    (180 / pi for a limit in rad held as deg).

    Raises
    ------
    ConfigError
        ``"max_velocity_deg_s must be 6 positive finite numbers (one per joint), got [180, 0, ...]"``.
    """
    try:
        out = np.array(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"{setting} must be {n} positive finite numbers (one per joint), got {values!r}") from None
    if len(out) != n or not (np.isfinite(out).all() and (out > 0).all()):
        shown = "[" + ", ".join(f"{v * scale:.6g}" for v in out) + "]"
        raise ConfigError(f"{setting} must be {n} positive finite numbers (one per joint), got {shown}")
    out.flags.writeable = False
    return out


def dh_transforms(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """Link transforms ``{i-1}T{i}`` of seed 000's eq. 10 for many joint vectors.

    Parameters
    ----------
    model : RobotModel
    q : (n, dof) float, rad

    Returns
    -------
    (n, dof, 4, 4) float
    """
    q = np.asarray(q, dtype=float).reshape(-1, model.dof)
    theta = q + model.theta_offset
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(model.alpha), np.sin(model.alpha)
    out = np.zeros(q.shape + (4, 4))
    out[..., 0, 0] = ct
    out[..., 0, 1] = -st * ca
    out[..., 0, 2] = st * sa
    out[..., 0, 3] = model.a * ct
    out[..., 1, 0] = st
    out[..., 1, 1] = ct * ca
    out[..., 1, 2] = -ct * sa
    out[..., 1, 3] = model.a * st
    out[..., 2, 1] = sa
    out[..., 2, 2] = ca
    out[..., 2, 3] = model.d
    out[..., 3, 3] = 1.0
    return out


def fk(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """Forward kinematics: the flange pose in the robot base frame, ``flange2base`` (seed 000, eq. 11).

    Parameters
    ----------
    model : RobotModel
    q : (dof,) or (n, dof) float, rad

    Returns
    -------
    (n, 4, 4) float, mm
    """
    links = dh_transforms(model, q)
    out = links[:, 0]
    for i in range(1, model.dof):
        out = out @ links[:, i]
    return out


def fk_point(model: RobotModel, q: np.ndarray, point, dq: np.ndarray | None = None):
    """Where a point fixed on the flange lies in the robot base frame, ``(flange2base @ [point, 1])[:3]``, for
    many joint vectors, and (with ``dq``) its rate of change along joint directions ``dq``.

    The same transform as :func:`fk` applied to one point, link by link from the flange inwards (a rotation
    about x by alpha, the shift a along x, the rotation about z by theta, the shift d along z), without forming
    4x4 matrices; the rate is the same chain differentiated (forward mode), exact rather than a finite
    difference.

    Parameters
    ----------
    model : RobotModel
    q : (n, dof) float, rad
    point : (3,) float, mm, in the flange frame
    dq : (n, dof) float or None
        Joint rates (any unit per unit of the curve's parameter).

    Returns
    -------
    (n, 3) float, mm; with ``dq`` also (n, 3), mm per unit of the parameter
    """
    q = np.asarray(q, dtype=float).reshape(-1, model.dof)
    theta = q + model.theta_offset
    ct, st = np.cos(theta), np.sin(theta)
    n = len(q)
    x, y, z = (np.full(n, float(v)) for v in np.asarray(point, dtype=float))
    rate = dq is not None
    if rate:
        dq = np.asarray(dq, dtype=float).reshape(-1, model.dof)
        dx, dy, dz = np.zeros(n), np.zeros(n), np.zeros(n)
    for i in range(model.dof - 1, -1, -1):
        ca, sa = math.cos(model.alpha[i]), math.sin(model.alpha[i])
        if sa != 0.0:  # Rot(x, alpha); none at alpha = 0
            y, z = ca * y - sa * z, sa * y + ca * z
            if rate:
                dy, dz = ca * dy - sa * dz, sa * dy + ca * dz
        if model.a[i] != 0.0:
            x = x + model.a[i]
        c, s = ct[:, i], st[:, i]
        x, y = c * x - s * y, s * x + c * y
        if model.d[i] != 0.0:
            z = z + model.d[i]
        if rate:
            w = dq[:, i]
            dx, dy = c * dx - s * dy - y * w, s * dx + c * dy + x * w
    position = np.column_stack([x, y, z])
    return (position, np.column_stack([dx, dy, dz])) if rate else position


def fk_world(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """The tool's pose in the world, ``tool2world = base2world @ flange2base @ tool2flange``, (n, 4, 4)."""
    return model.base2world @ fk(model, q) @ model.tool2flange


def flange_target(model: RobotModel, tool2world: np.ndarray) -> np.ndarray:
    """The flange pose in the base frame that puts the tool at ``tool2world``: the input of inverse kinematics."""
    return np.linalg.inv(model.base2world) @ np.asarray(tool2world, dtype=float) @ np.linalg.inv(model.tool2flange)


def transform_from_xyz_rpy(xyz_mm, rpy_deg) -> np.ndarray:
    """A 4x4 transform from a translation and seed 001's eq. 9 angles ``Rot(x) Rot(y) Rot(z)`` in degrees."""
    from sprayplan.surface.poses import matrix_from_rpy

    out = np.eye(4)
    out[:3, :3] = matrix_from_rpy(np.radians(np.asarray(rpy_deg, dtype=float)))[0]
    out[:3, 3] = np.asarray(xyz_mm, dtype=float)
    return out


def _deg(values) -> list[float]:
    return [math.radians(v) for v in values]


#: UR5 / UR5e joint limits (see the module docstring): 180 deg/s (technical specifications), 1.4 rad/s^2
#: (URScript ``movej``'s default acceleration).
UR_RATES = dict(max_velocity=[math.pi] * 6, max_acceleration=[1.4] * 6)
#: R5150: assumed (seed 001 gives no speeds; see the module docstring).
R5150_RATES = dict(max_velocity=_deg([90.0] * 5), max_acceleration=_deg([180.0] * 5))

#: The UR arms' elbow limits (joint 3), rad: the fold at +-pi is a self-collision (module docstring).
ELBOW_LIMIT = math.pi
#: UR5 / UR5e joint position limits: +-2 pi but the elbow's +-pi.
UR_LIMITS = dict(
    lower=[-2 * math.pi, -2 * math.pi, -ELBOW_LIMIT, -2 * math.pi, -2 * math.pi, -2 * math.pi],
    upper=[2 * math.pi, 2 * math.pi, ELBOW_LIMIT, 2 * math.pi, 2 * math.pi, 2 * math.pi],
)

PRESETS = {
    "ur5": dict(
        d=[89.159, 0, 0, 109.15, 94.65, 82.3],
        a=[0, -425.0, -392.25, 0, 0, 0],
        alpha=[math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0],
        **UR_LIMITS,
        **UR_RATES,
    ),
    "ur5-seed": dict(
        d=[89.2, 0, 0, 109.2, 94.7, 82.3],
        a=[0, 425.0, 392.3, 0, 0, 0],
        alpha=[math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0],
        **UR_LIMITS,
        **UR_RATES,
    ),
    "ur5e": dict(
        d=[162.5, 0, 0, 133.3, 99.7, 99.6],
        a=[0, -425.0, -392.2, 0, 0, 0],
        alpha=[math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0],
        **UR_LIMITS,
        **UR_RATES,
    ),
    "r5150": dict(
        d=[255.55, 0, 0, 0, 115.0],
        a=[0, 190.0, 190.0, 0, 0],
        alpha=[math.pi / 2, 0, 0, math.pi / 2, 0],
        lower=_deg([-185, -32, -147, -5, -360]),
        upper=_deg([153, 149, 51, 180, 360]),
        **R5150_RATES,
    ),
}


def read_robot_toml(path: str | os.PathLike) -> dict:
    """A robot TOML file's table; a missing, unreadable or broken file is a one-line ``PartFileError``."""
    check_input_file(path)
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise PartFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise PartFileError(path, f"not a readable TOML file ({exc})") from None


def load_robot(name_or_path: str | os.PathLike, setting: str = "robot") -> RobotModel:
    """A robot model from a preset name (``ur5``, ``ur5-seed``, ``ur5e``, ``r5150``) or a TOML file.

    The TOML file has ``name``, and lists ``d_mm``, ``a_mm``, ``alpha_deg`` and optionally ``theta_offset_deg``,
    ``lower_deg``, ``upper_deg``, one value per joint; optionally the base in the world and the tool on the
    flange as ``base_xyz_mm``, ``base_rpy_deg``, ``tool_xyz_mm``, ``tool_rpy_deg`` (three values each; angles
    as seed 001's eq. 9, ``Rot(x) Rot(y) Rot(z)``); optionally the joints' speed and acceleration limits
    ``max_velocity_deg_s`` and ``max_acceleration_deg_s2`` (one positive value per joint).

    A TOML file may also start from a preset: ``preset = "ur5"`` takes that preset's table and limits, and
    the file's keys override them (e.g. only ``max_velocity_deg_s`` for a slower arm).

    ``setting`` names the option or key the name came from (``--robot``), first in the message of an
    unknown name.

    Raises
    ------
    ConfigError
        An unknown preset name: ``"--robot 'ur10' is not a known robot: use one of ur5, ... or a .toml file"``.
    PartFileError
        A TOML file that is missing, broken or incomplete.
    """
    key = os.fspath(name_or_path)
    if key in PRESETS:
        return RobotModel(name=key, **PRESETS[key])
    path = Path(key)
    if path.suffix.lower() != ".toml":
        raise ConfigError(f"{setting} {key!r} is not a known robot: use one of {', '.join(PRESETS)} or a .toml file")
    data = read_robot_toml(path)
    known = {"name", "d_mm", "a_mm", "alpha_deg", "theta_offset_deg", "lower_deg", "upper_deg"}
    known |= {"base_xyz_mm", "base_rpy_deg", "tool_xyz_mm", "tool_rpy_deg", "preset"}
    known |= {"max_velocity_deg_s", "max_acceleration_deg_s2"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise PartFileError(key, f"unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    try:
        base = {}
        if "preset" in data:
            if data["preset"] not in PRESETS:
                raise ConfigError(f"preset must be one of {', '.join(PRESETS)}, got {data['preset']!r}")
            base = _preset_table(data["preset"])
        data = {**base, **data}
        dof = len(data["d_mm"])
        rates = {
            name: _deg(_limit_list(data[toml], toml))
            for name, toml in (("max_velocity", "max_velocity_deg_s"), ("max_acceleration", "max_acceleration_deg_s2"))
            if toml in data
        }
        return RobotModel(
            name=str(data.get("name", path.stem)),
            d=data["d_mm"],
            a=data["a_mm"],
            alpha=_deg(data["alpha_deg"]),
            theta_offset=_deg(data.get("theta_offset_deg", [0.0] * dof)),
            lower=_deg(data["lower_deg"]) if "lower_deg" in data else None,
            upper=_deg(data["upper_deg"]) if "upper_deg" in data else None,
            base2world=transform_from_xyz_rpy(data.get("base_xyz_mm", [0, 0, 0]), data.get("base_rpy_deg", [0, 0, 0])),
            tool2flange=transform_from_xyz_rpy(data.get("tool_xyz_mm", [0, 0, 0]), data.get("tool_rpy_deg", [0, 0, 0])),
            **rates,
        )
    except KeyError as exc:
        raise PartFileError(key, f"missing key {exc.args[0]}") from None
    except (ConfigError, TypeError, ValueError) as exc:
        raise PartFileError(key, str(exc)) from None


def _limit_list(values, setting: str) -> list[float]:
    """A TOML list of limits as floats (a non-list or a non-number is an error naming the key)."""
    if not isinstance(values, list) or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in values):
        raise ConfigError(f"{setting} must be a list of positive finite numbers (one per joint), got {values!r}")
    return [float(v) for v in values]


def _preset_table(name: str) -> dict:
    """A preset as the keys of a robot TOML file (degrees), for ``preset = "..."``."""
    model = RobotModel(name=name, **PRESETS[name])
    out = {
        "d_mm": model.d.tolist(),
        "a_mm": model.a.tolist(),
        "alpha_deg": np.degrees(model.alpha).tolist(),
        "lower_deg": np.degrees(model.lower).tolist(),
        "upper_deg": np.degrees(model.upper).tolist(),
    }
    out["max_velocity_deg_s"] = np.degrees(model.max_velocity).tolist()
    out["max_acceleration_deg_s2"] = np.degrees(model.max_acceleration).tolist()
    return out
