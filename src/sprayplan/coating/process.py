"""Process parameters (pattern, paint flow, gun speed, solids, transfer efficiency) and the named presets.

Presets are TOML files in ``sprayplan/coating/presets/`` (one per preset, the file name is the preset name)::

    name = "seed000_circle"
    description = "..."
    [pattern]          # SprayPattern fields
    kind = "parabolic"
    radius_mm = 50.0
    standoff_mm = 113.0
    [process]          # Process fields
    flow_ml_min = 200.0
    speed_mm_s = 350.0
    solids_fraction = 0.4
    transfer_efficiency = 0.65
    [bell]             # optional: rotary-bell settings (seed 003, tables 1-3)
    speed_krpm = 40.0
    ...

Any other top-level table (such as the seed's per-track tables) is kept, unread, in ``Process.extra``.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

from sprayplan.checks import check_input_file
from sprayplan.coating.patterns import SprayPattern, pattern_from_dict
from sprayplan.errors import ConfigError

#: mL/min -> mm^3/s
ML_MIN_TO_MM3_S = 1000.0 / 60.0


@dataclass(frozen=True)
class BellSettings:
    """Settings of a rotary electrostatic bell (seed 003, section 5 and tables 1-3).

    Attributes
    ----------
    speed_krpm : float
        Bell cup speed "AM", thousands of revolutions per minute.
    shaping_air1_l_min : float
        "SA1", L/min (the seed: air 1 drives the turbine that turns the bell).
    shaping_air2_l_min : float
        "SA2", L/min (the seed: air 2 is the shaping air around the cup).
    voltage_kv : float
        "HV", the bell's electrostatic voltage, kV.
    cup_radius_mm : float
        Radius of the bell cup's edge where droplets leave it (not in the seed: 32.5 mm, a 65 mm cup).
    """

    speed_krpm: float = 40.0
    shaping_air1_l_min: float = 250.0
    shaping_air2_l_min: float = 180.0
    voltage_kv: float = 60.0
    cup_radius_mm: float = 32.5

    def __post_init__(self):
        for key in ("speed_krpm", "shaping_air1_l_min", "shaping_air2_l_min", "voltage_kv", "cup_radius_mm"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"bell {key} must be a number >= 0, got {value}")
            object.__setattr__(self, key, float(value))


@dataclass(frozen=True)
class Process:
    """What the gun does while a stroke sprays.

    Attributes
    ----------
    pattern : SprayPattern
    flow_ml_min : float
        Wet paint flow rate, mL/min (cc/min).
    speed_mm_s : float
        Gun (tool tip) speed along the strokes, mm/s.
    solids_fraction : float
        Volume fraction of the paint that stays in the dry film, in (0, 1].
    transfer_efficiency : float
        Share of the sprayed solids that lands on the target, in (0, 1].
    name : str
    bell : BellSettings or None
        Rotary-bell settings (used by the droplet model), when the gun is a bell.
    extra : dict
        Preset tables this class does not read (kept for the user).
    """

    pattern: SprayPattern
    flow_ml_min: float = 200.0
    speed_mm_s: float = 350.0
    solids_fraction: float = 0.4
    transfer_efficiency: float = 0.65
    name: str = ""
    bell: BellSettings | None = None
    extra: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        if not isinstance(self.pattern, SprayPattern):
            raise ConfigError("process pattern must be a SprayPattern")
        for key in ("flow_ml_min", "speed_mm_s"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{key} must be a number >= 0, got {value}")
        if not self.speed_mm_s > 0:
            raise ConfigError(f"speed_mm_s must be positive, got {self.speed_mm_s}")
        for key in ("solids_fraction", "transfer_efficiency"):
            value = getattr(self, key)
            if not (math.isfinite(value) and 0 < value <= 1):
                raise ConfigError(f"{key} must be in (0, 1], got {value}")
        for key in ("flow_ml_min", "speed_mm_s", "solids_fraction", "transfer_efficiency"):
            object.__setattr__(self, key, float(getattr(self, key)))

    @property
    def flow_mm3_s(self) -> float:
        """Wet paint flow, mm^3/s."""
        return self.flow_ml_min * ML_MIN_TO_MM3_S

    @property
    def volume_rate_mm3_s(self) -> float:
        """Dry-film volume rate that reaches the part: flow x solids x efficiency, mm^3/s."""
        return self.flow_mm3_s * self.solids_fraction * self.transfer_efficiency

    def with_(self, **changes) -> Process:
        """A copy with some fields changed (``pattern``, ``flow_ml_min``, ``speed_mm_s``, ...)."""
        return replace(self, **changes)


@dataclass(frozen=True)
class StrokeOverride:
    """Per-stroke process settings that replace the process's own for one stroke (None: keep it).

    Attributes
    ----------
    flow_ml_min : float or None
    speed_mm_s : float or None
    spray_on : bool or None
        False turns a spray stroke off; a transfer stroke (``spray_on`` False in the plan) never sprays.
    """

    flow_ml_min: float | None = None
    speed_mm_s: float | None = None
    spray_on: bool | None = None

    def __post_init__(self):
        if self.flow_ml_min is not None and not (math.isfinite(self.flow_ml_min) and self.flow_ml_min >= 0):
            raise ConfigError(f"stroke flow_ml_min must be >= 0, got {self.flow_ml_min}")
        if self.speed_mm_s is not None and not (math.isfinite(self.speed_mm_s) and self.speed_mm_s > 0):
            raise ConfigError(f"stroke speed_mm_s must be positive, got {self.speed_mm_s}")


def _presets_dir():
    return resources.files("sprayplan.coating").joinpath("presets")


def list_presets() -> list[str]:
    """Names of the bundled presets (the TOML files in ``sprayplan/coating/presets``), sorted."""
    return sorted(p.name[:-5] for p in _presets_dir().iterdir() if p.name.endswith(".toml"))


def load_preset(name_or_path: str | os.PathLike, setting: str = "process") -> Process:
    """A process from a bundled preset name (``"seed000_circle"``, ``"bell003"``) or a TOML file path.

    ``setting`` names the option or key the name came from (``coating.process``, ``--process``), first in the
    message of an unknown name.

    Raises
    ------
    ConfigError
        Unknown preset name, unreadable file, or bad keys and values.
    """
    text_name = os.fspath(name_or_path)
    if text_name.endswith(".toml") or os.sep in text_name:
        path = Path(text_name)
        check_input_file(path, error=lambda name, problem: ConfigError(f"{name}: cannot read the preset: {problem}"))
        try:
            table = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise ConfigError(f"{path}: cannot read the preset: {exc}") from exc
        return process_from_dict(table, source=str(path))
    entry = _presets_dir().joinpath(f"{text_name}.toml")
    if not entry.is_file():
        raise ConfigError(
            f"{setting} {text_name!r} is not a known process preset: use one of {', '.join(list_presets())}"
            " or a .toml file"
        )
    return process_from_dict(tomllib.loads(entry.read_text(encoding="utf-8")), source=text_name)


def process_from_dict(table: dict, source: str = "") -> Process:
    """Build a :class:`Process` from a preset's tables (see the module docstring)."""
    where = f"{source}: " if source else ""
    if "pattern" not in table:
        raise ConfigError(f"{where}a preset needs a [pattern] table")
    try:
        pattern_table = dict(table["pattern"])
        pattern_table.setdefault("name", str(table.get("name", source)))
        pattern = pattern_from_dict(pattern_table)
        proc_table = dict(table.get("process", {}))
        known = {"flow_ml_min", "speed_mm_s", "solids_fraction", "transfer_efficiency"}
        unknown = sorted(set(proc_table) - known)
        if unknown:
            raise ConfigError(f"unknown process key(s): {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        bell = BellSettings(**table["bell"]) if "bell" in table else None
    except TypeError as exc:
        raise ConfigError(f"{where}{exc}") from exc
    except ConfigError as exc:
        raise ConfigError(f"{where}{exc}") from exc
    extra = {k: v for k, v in table.items() if k not in ("pattern", "process", "bell", "name", "description")}
    name = str(table.get("name", source))
    return Process(pattern=pattern, name=name, bell=bell, extra=extra, **proc_table)


def process_to_toml(process: Process, description: str = "") -> str:
    """A preset file's text for a process (for example one whose pattern was fitted)."""
    lines = [f"name = {_toml_value(process.name or process.pattern.name or 'custom')}"]
    if description:
        lines.append(f"description = {_toml_value(description)}")
    lines += ["", "[pattern]"]
    lines += [f"{k} = {_toml_value(v)}" for k, v in process.pattern.to_dict().items()]
    lines += ["", "[process]"]
    for key in ("flow_ml_min", "speed_mm_s", "solids_fraction", "transfer_efficiency"):
        lines.append(f"{key} = {_toml_value(getattr(process, key))}")
    if process.bell is not None:
        lines += ["", "[bell]"]
        for key in BellSettings.__dataclass_fields__:
            lines.append(f"{key} = {_toml_value(getattr(process.bell, key))}")
    return "\n".join(lines) + "\n"


def _toml_value(value) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(float(value)) if isinstance(value, float) else str(value)
