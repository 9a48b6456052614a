"""A batch file (TOML, schema in docs/batch.md) read into jobs: parts, their settings, and sweeps.

Every setting goes through the process TOML's own machinery (``config.job_from_toml``, ``job_from_dict``), so
a name or a value that ``sprayplan plan -c`` refuses is refused here too, with the batch file and the key
named on one line. A job's id is its readable name plus a short hash of the part file's bytes and its whole
settings, so that the same part with the same settings always gets the same folder.
"""

from __future__ import annotations

import glob
import hashlib
import itertools
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from sprayplan.config import SECTIONS, JobConfig, job_from_dict, job_from_toml, job_to_dict
from sprayplan.errors import ConfigError, InputError, PartFileError

#: The keys of a ``[[job]]`` table besides the settings' tables.
JOB_KEYS = ("parts", "name", "config", "sweep", "cell")
#: The engine settings a batch file may hold in ``[batch]`` (the command line's flags win).
BATCH_KEYS = ("workers", "timeout_s", "job_memory_mb", "ship_mb")
#: Characters kept in a job id's readable part (others become ``_``).
_UNSAFE = re.compile(r"[^A-Za-z0-9._=,+-]+")
#: Length of the hash in a job id (hex digits).
HASH_DIGITS = 10


@dataclass(frozen=True)
class BatchJob:
    """One job of a batch: a part file and every setting of the main job.

    Attributes
    ----------
    job_id : str
        ``name`` plus the first :data:`HASH_DIGITS` hex digits of the SHA-256 of the part's bytes and the
        settings: the job's folder name.
    name : str
        The readable name: the job's ``name`` (default the part file's stem) and the swept values.
    part : str
        The part file, absolute.
    part_sha256 : str
        The hash of the part file's bytes when the batch was read (a worker checks it again).
    part_bytes : int
        The part file's size.
    config : JobConfig
    settings : dict
        The settings the batch file gave this job (``section.key`` -> value, sweeps included), for the
        summary's columns.
    cell : str or None
        A cell plan (``sprayplan plan --cell``): a preset's name, or a cell TOML file's text; None for the
        gantry's plan.
    """

    job_id: str
    name: str
    part: str
    part_sha256: str
    part_bytes: int
    config: JobConfig
    settings: dict = field(default_factory=dict)
    cell: str | None = None


@dataclass(frozen=True)
class Batch:
    """A batch file read: its jobs in order and its ``[batch]`` engine settings."""

    path: str
    jobs: tuple[BatchJob, ...]
    options: dict = field(default_factory=dict)


def _flat(table: dict, prefix: str = "") -> dict:
    """Nested settings tables -> ``{"section.key": value}`` (``mode`` stays at the top)."""
    out = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flat(value, name + "."))
        else:
            out[name] = value
    return out


def _nested(flat: dict) -> dict:
    out: dict = {}
    for name, value in flat.items():
        section, _, key = name.partition(".")
        if key:
            out.setdefault(section, {})[key] = value
        else:
            out[section] = value
    return out


def _settings_of(table: dict, where: str) -> dict:
    """The settings' tables of a ``[defaults]`` or ``[[job]]`` table, flat; an unknown table is an error."""
    settings = {}
    for key, value in table.items():
        if key in JOB_KEYS:
            continue
        if key == "mode":
            settings["mode"] = value
        elif key in SECTIONS:
            if not isinstance(value, dict):
                raise ConfigError(f"{where}.{key} must be a table of [{key}] settings")
            settings.update(_flat(value, key + "."))
        else:
            known = ", ".join((*JOB_KEYS, "mode", *SECTIONS))
            raise ConfigError(f"{where}.{key}: unknown key; known: {known}")
    return settings


def _sweep_of(table, where: str) -> dict:
    """A sweep table (``paths.spacing_mm = [30, 35]``) -> ``{"paths.spacing_mm": [30, 35]}``, checked."""
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise ConfigError(f"{where}.sweep must be a table of lists (paths.spacing_mm = [30, 35, 40])")
    flat = _flat(table)
    for name, values in flat.items():
        section = name.partition(".")[0]
        if name != "mode" and (section not in SECTIONS or "." not in name):
            raise ConfigError(f"{where}.sweep.{name}: not a setting (section.key, or mode)")
        if not isinstance(values, list):
            raise ConfigError(f"{where}.sweep.{name} must be a list of values, got {values!r}")
        if not values:
            raise ConfigError(f"{where}.sweep.{name}: an empty sweep (give at least one value)")
    return flat


def _config(base: JobConfig, settings: dict) -> JobConfig:
    """``base`` with ``settings`` applied, through the process TOML's reader (the same checks)."""
    data = job_to_dict(base)
    for name, value in _nested(settings).items():
        if isinstance(value, dict):
            data[name] = {**data.get(name, {}), **value}
        else:
            data[name] = value
    return job_from_dict(data)


def _value_text(value) -> str:
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    if isinstance(value, (list, tuple)):
        return ",".join(_value_text(v) for v in value)
    return str(value)


def job_hash(part_sha256: str, config: JobConfig) -> str:
    """The hash of a part's bytes (their SHA-256) and a job's whole settings: a job id's tail."""
    text = json.dumps(job_to_dict(config), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(f"{part_sha256}\n{text}".encode()).hexdigest()[:HASH_DIGITS]


def readable_name(name: str, swept: dict) -> str:
    """A job's readable name: ``name`` and each swept setting's key and value, safe as a folder name."""
    words = [name] + [f"{key.rpartition('.')[2]}={_value_text(v)}" for key, v in swept.items()]
    text = _UNSAFE.sub("_", "-".join(words)).strip("._-") or "job"
    return text[:96]


def file_sha256(path) -> tuple[str, int]:
    """The SHA-256 of a file's bytes and its size (read in 1 MiB blocks)."""
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as handle:
        while block := handle.read(1 << 20):
            digest.update(block)
            size += len(block)
    return digest.hexdigest(), size


def _parts(patterns, folder: Path, where: str) -> list[str]:
    """A job's part files: paths or glob patterns, relative to the batch file's folder; each must match."""
    if isinstance(patterns, str):
        patterns = [patterns]
    if not isinstance(patterns, list) or not patterns or not all(isinstance(p, str) and p for p in patterns):
        raise ConfigError(f"{where}.parts must be a part file or a list of files or glob patterns")
    found = []
    for pattern in patterns:
        full = os.path.join(folder, os.path.expanduser(pattern))
        if glob.has_magic(pattern):
            matches = sorted(p for p in glob.glob(full, recursive=True) if os.path.isfile(p))
            if not matches:
                raise ConfigError(f"{where}.parts: {pattern!r} matches no file")
        else:
            if not os.path.isfile(full):
                problem = "is not a file" if os.path.exists(full) else "no such file"
                raise ConfigError(f"{where}.parts: {pattern}: {problem}")
            matches = [full]
        found += [os.path.abspath(p) for p in matches]
    return list(dict.fromkeys(found))


def _stem(path: str) -> str:
    """A part file's name without its suffix (and ``.gz``): ``hood.ply.gz`` -> ``hood``."""
    name = os.path.basename(path)
    return Path(name[:-3] if name.lower().endswith(".gz") else name).stem


def _base_config(table: dict, folder: Path, where: str) -> JobConfig | None:
    path = table.get("config")
    if path is None:
        return None
    if not isinstance(path, str) or not path:
        raise ConfigError(f"{where}.config must be a process TOML file")
    return job_from_toml(os.path.join(folder, os.path.expanduser(path)))


def _cell_of(table: dict, folder: Path, where: str) -> str | None:
    """A job's ``cell``: a preset's name, or a cell TOML file (relative to the batch file) read into its text;
    checked as ``plan --cell`` checks it."""
    from sprayplan.cells import list_cells, load_cell

    value = table.get("cell")
    if value is None:
        return None
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{where}.cell must be a cell preset ({', '.join(list_cells())}) or a cell TOML file")
    preset = value in list_cells()
    path = value if preset else os.path.join(folder, os.path.expanduser(value))
    cell = load_cell(path, setting=f"{where}.cell")
    if cell.is_gantry:
        raise ConfigError(f"{where}.cell: {cell.name} is the gantry cell (leave cell out to plan it)")
    if preset:
        return value
    with open(path, encoding="utf-8") as handle:
        return handle.read()


def cell_from_text(text: str):
    """The cell of a job's ``cell`` (:func:`_cell_of`): a preset by name, or a cell TOML file's text."""
    import tempfile

    from sprayplan.cells import list_cells, load_cell

    if text in list_cells():
        return load_cell(text)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "cell.toml")
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(text)
        return load_cell(path)


def _options(table, where: str) -> dict:
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise ConfigError(f"{where} must be a table")
    unknown = sorted(set(table) - set(BATCH_KEYS))
    if unknown:
        raise ConfigError(f"{where}.{unknown[0]}: unknown key; known: {', '.join(BATCH_KEYS)}")
    return dict(table)


def jobs_from_dict(data: dict, folder) -> tuple[list[BatchJob], dict]:
    """The jobs of a batch file's tables (relative paths from ``folder``) and its ``[batch]`` settings.

    Raises
    ------
    ConfigError
        Naming the table and key: an unknown table, setting or sweep key, a bad value, an empty sweep, a part
        that matches no file, two jobs with the same id.
    """
    folder = Path(folder)
    unknown = sorted(set(data) - {"defaults", "sweep", "job", "batch"})
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown table; known: defaults, sweep, job, batch")
    options = _options(data.get("batch"), "[batch]")
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        raise ConfigError("[defaults] must be a table")
    misplaced = sorted(set(defaults) & {"parts", "name", "sweep"})  # a cell may be a default
    if misplaced:
        where = "[sweep] at the top" if misplaced[0] == "sweep" else "a [[job]]"
        raise ConfigError(f"defaults.{misplaced[0]}: belongs in {where}, not in [defaults]")
    default_settings = _settings_of(defaults, "defaults")
    default_base = _base_config(defaults, folder, "defaults")
    top_sweep = _sweep_of(data.get("sweep"), "")
    tables = data.get("job")
    if not isinstance(tables, list) or not tables or not all(isinstance(t, dict) for t in tables):
        raise ConfigError("job: give at least one [[job]] table with its parts")
    jobs: list[BatchJob] = []
    seen: dict[str, str] = {}
    hashes: dict[str, tuple[str, int]] = {}
    for number, table in enumerate(tables, 1):
        where = f"job {number}"
        if "parts" not in table:
            raise ConfigError(f"{where}.parts: required (a part file or glob pattern, or a list of them)")
        name = table.get("name")
        if name is not None and (not isinstance(name, str) or not name.strip()):
            raise ConfigError(f"{where}.name must be a non-empty string")
        base = _base_config(table, folder, where) or default_base or JobConfig()
        cell = _cell_of(table if "cell" in table else defaults, folder, where if "cell" in table else "defaults")
        settings = {**default_settings, **_settings_of(table, where)}
        sweep = {**top_sweep, **_sweep_of(table.get("sweep"), where)}
        try:
            fixed = _config(base, settings)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        points = [dict(zip(sweep, values)) for values in itertools.product(*sweep.values())]
        for part in _parts(table["parts"], folder, where):
            if part not in hashes:
                try:
                    hashes[part] = file_sha256(part)
                except OSError as exc:
                    raise PartFileError(part, f"cannot read ({exc.strerror or exc})") from None
            digest, size = hashes[part]
            for point in points:
                try:
                    config = _config(fixed, point)
                except ConfigError as exc:
                    shown = ", ".join(f"{k} = {v!r}" for k, v in point.items())
                    raise ConfigError(f"{where} (sweep {shown}): {exc}") from None
                label = readable_name(name or _stem(part), point)
                key = digest if cell is None else hashlib.sha256(f"{digest}\n{cell}".encode()).hexdigest()
                job_id = f"{label}-{job_hash(key, config)}"
                if job_id in seen:
                    raise ConfigError(
                        f"{where}: duplicate job id {job_id} (the same part and settings as {seen[job_id]})"
                    )
                seen[job_id] = f"{where}, {os.path.basename(part)}"
                jobs.append(BatchJob(job_id, label, part, digest, size, config, {**settings, **point}, cell))
    return jobs, options


def read_batch(path) -> Batch:
    """Read a batch file (TOML; docs/batch.md) into its jobs, checking every part and setting first.

    Raises
    ------
    PartFileError
        Naming the batch file: it is missing or not TOML, or any error of :func:`jobs_from_dict`.
    """
    import tomllib

    from sprayplan.checks import check_input_file

    name = check_input_file(path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise PartFileError(name, f"not a readable TOML file ({exc})") from None
    try:
        jobs, options = jobs_from_dict(data, Path(os.path.abspath(path)).parent)
    except InputError as exc:
        raise PartFileError(name, str(exc)) from None
    for key, value in options.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise PartFileError(name, f"[batch].{key} must be a number > 0, got {value!r}")
    if "workers" in options and options["workers"] != int(options["workers"]):
        raise PartFileError(name, f"[batch].workers must be a whole number, got {options['workers']!r}")
    return Batch(os.fspath(path), tuple(jobs), options)
