"""Every config section rejects bad values at construction with one line naming the key and what it takes."""

from __future__ import annotations

import dataclasses
import math

import pytest

from sprayplan.config import (
    SECTIONS,
    JobConfig,
    KinematicsConfig,
    LoadConfig,
    StationsConfig,
    job_from_dict,
    job_from_toml,
    job_to_dict,
)
from sprayplan.errors import ConfigError, PartFileError


def _numeric_fields():
    for name, cls in SECTIONS.items():
        for f in dataclasses.fields(cls):
            kind = str(f.type).replace(" ", "").removesuffix("|None")
            if kind in ("float", "int", "bool"):
                yield name, cls, f.name, kind


@pytest.mark.parametrize(("section", "cls", "key", "kind"), list(_numeric_fields()))
def test_wrong_types_are_refused_naming_the_key(section, cls, key, kind):
    bad = ["1", None if kind == "bool" else "x", [1.0]]
    bad += [1, 0.0] if kind == "bool" else [True, math.nan, math.inf]
    for value in bad:
        if value is None:
            continue
        with pytest.raises(ConfigError, match=rf"^{section}\.{key} must be ") as info:
            cls(**{key: value})
        assert "\n" not in str(info.value)


def test_whole_numbers_take_no_fractions():
    for name, cls in SECTIONS.items():
        for f in dataclasses.fields(cls):
            if str(f.type).replace(" ", "").removesuffix("|None") == "int":
                with pytest.raises(ConfigError, match=rf"{name}\.{f.name} must be a whole number"):
                    cls(**{f.name: 1.5})


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: LoadConfig(units="furlong"), "load.units must be one of mm, cm, m, in, got 'furlong'"),
        (lambda: LoadConfig(up="w"), "load.up must be one of z, y, x, got 'w'"),
        (lambda: LoadConfig(units=["mm"]), "load.units must be a string"),
        (lambda: LoadConfig(region=5), "load.region must be a string or none"),
        (lambda: LoadConfig(region="  "), "load.region must be a region expression"),
        (lambda: KinematicsConfig(k_d=-5), "kinematics.k_d must be a number >= 0, got -5.0"),
        (lambda: KinematicsConfig(robot="ur10"), "kinematics.robot must be one of gantry-ur5, gantry-ur5e"),
        (lambda: KinematicsConfig(axis_tol_deg=0.0), "kinematics.axis_tol_deg must be a number from"),
        (lambda: StationsConfig(seed="abc"), "stations.seed must be a whole number, got 'abc'"),
        (lambda: StationsConfig(seed=-1), "stations.seed must be a number >= 0"),
        (lambda: StationsConfig(home_mm=(0, 0)), "stations.home_mm must be three numbers"),
        (lambda: StationsConfig(home_mm=(0, 0, math.nan)), "stations.home_mm must be three finite numbers"),
        (lambda: JobConfig(mode="lines"), "mode must be one of paths, points, got 'lines'"),
        (lambda: JobConfig(load="mm"), "JobConfig.load must be a LoadConfig"),
        (lambda: JobConfig().replace(tuning={"touch_up_rounds": 11}), "tuning.touch_up_rounds must be a number"),
        (lambda: JobConfig().replace(coating={"occlusion": "xray"}), "coating.occlusion must be one of"),
        (lambda: JobConfig().replace(motion={"speed_along": "air"}), "motion.speed_along must be one of"),
        (lambda: JobConfig().replace(painting={}), "unknown section 'painting'"),
        (lambda: JobConfig().replace(paths={"direction": ["mm"]}), "paths.direction must be auto, x, y, z or three"),
        (lambda: JobConfig().replace(paths={"direction": (0, 0, 0)}), "paths.direction must be"),
        (lambda: JobConfig().replace(paths={"streamline_deg": ["a", 1]}), "paths.streamline_deg must be [alpha_min"),
        (lambda: JobConfig().replace(paths={"split_angle_deg": 1e12}), "paths.split_angle_deg must be an angle"),
        (
            lambda: JobConfig().replace(targets={"spray_radius_mm": 1e308}),
            "targets.spray_radius_mm must be at most 1e+07",
        ),
    ],
)
def test_bad_values_give_one_line(make, words):
    with pytest.raises(ConfigError) as info:
        make()
    assert words in str(info.value) and "\n" not in str(info.value)


def test_good_values_are_kept_as_their_type():
    k = KinematicsConfig(k_d=1, position_tol_mm=2)
    assert isinstance(k.k_d, float) and k.k_d == 1.0 and isinstance(k.position_tol_mm, float)
    s = StationsConfig(seed=3.0, home_mm=[1, 2, 3])
    assert isinstance(s.seed, int) and s.seed == 3 and s.home_mm == (1.0, 2.0, 3.0)


def test_settings_round_trip_through_plain_data():
    job = JobConfig(mode="points").replace(
        load={"units": "m", "region": "z > 10"},
        paths={"direction": (1.0, 0.0, 0.0), "spacing_mm": 40.0},
        stations={"home_mm": (1.0, 2.0, 3.0)},
        coating={"thickness_um": 60.0},
        tuning={"band": 0.2},
    )
    assert job_from_dict(job_to_dict(job)) == job
    assert job_from_dict(job_to_dict(JobConfig())) == JobConfig()


def test_the_toml_names_the_file_the_table_and_the_key(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text('[kinematics]\nk_d = "fast"\n')
    with pytest.raises(PartFileError, match=r"p.toml: kinematics.k_d must be a finite number, got 'fast'"):
        job_from_toml(path)
    path.write_text("[plan]\nk_d = 0.2\nthickness_um = 50\n")
    with pytest.raises(
        PartFileError, match=r"\[plan\] table was split.*k_d -> \[kinematics\].*thickness_um -> \[coating\]"
    ):
        job_from_toml(path)
    path.write_text("[tuning]\nband = true\n")
    with pytest.raises(PartFileError, match="tuning.band must be a finite number, got True"):
        job_from_toml(path)
    path.write_bytes(b"\xff\xfe[load]\n")
    with pytest.raises(PartFileError, match="not a readable TOML file"):
        job_from_toml(path)
    with pytest.raises(PartFileError, match="is a folder"):
        job_from_toml(tmp_path)


def test_the_tuning_section_carries_every_setting_of_the_speed_tuning():
    from sprayplan.config import RefineConfig
    from sprayplan.refine.stage import tuning_settings
    from sprayplan.refine.tuning import TuningConfig

    section = RefineConfig(min_dwell=0.3, max_dwell=3.0, band=0.2, smoothing=0.5, iterations=7, loss="linear")
    tuning = tuning_settings(section)
    assert tuning == TuningConfig(
        min_dwell=0.3, max_dwell=3.0, band=0.2, smoothing=0.5, iterations=7, loss="linear", painted_fraction=0.1
    )
