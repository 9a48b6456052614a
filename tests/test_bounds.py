"""Bounds of work and nonsense data (issue 13): each bad setting is a one-line error naming the setting and the
bound, raised by the up-front check, before the heavy work starts."""

from __future__ import annotations

import json
import math
import tracemalloc

import numpy as np
import pytest

from sprayplan import checks
from sprayplan.config import FilmConfig, JobConfig, OutputConfig, PathConfig, TargetsConfig, job_from_dict
from sprayplan.errors import ConfigError, DataError, InputError, PartFileError
from sprayplan.types import Part
from tests.helpers import plate

#: Most memory (bytes) a refused call may allocate. The checks run once the inputs they estimate from exist (the
#: film samples before the gun samples' check: 86 MiB here; 500,000 droplets' start: 84 MiB), while starting any
#: refused work (3.4e7 gun samples, 1e10 droplet steps, millions of layers) needs gigabytes. Memory, not time, so
#: that the test means the same on a loaded machine.
REFUSED_PEAK_BYTES = 256 * 2**20


def fast(call, error=InputError):
    """Run ``call``, expecting ``error`` before the work starts; the message (one line)."""
    tracemalloc.start()
    try:
        with pytest.raises(error) as info:
            call()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(info.value)
    assert "\n" not in message
    assert peak < REFUSED_PEAK_BYTES, f"{peak / 2**20:.0f} MiB allocated: the check came after the work ({message})"
    return message


@pytest.fixture(scope="module")
def big_plate():
    return plate(0, 2000, 0, 1500, 250)


# ------------------------------------------------------------------------------------------------ static bounds


@pytest.mark.parametrize(
    ("section", "key", "value", "bound"),
    [
        ("paths", "edge_passes", 1_000_000, "at most 100"),
        ("paths", "edge_passes", 101, "at most 100"),
        ("paths", "layers", 1e9, "at most 10000"),
        ("paths", "layers", 10_001, "at most 10000"),
        ("paths", "points_per_section", 10**9, "at most 100000"),
        ("paths", "step_mm", 1e-9, ">= 0.01"),
        ("paths", "spacing_mm", 1e-6, ">= 0.01"),
        ("targets", "spacing_mm", 1e-6, ">= 0.01"),
        ("targets", "h_min_mm", 1e-6, ">= 0.01"),
        ("output", "samples", 1e11, "at most 1000000"),
        ("coating", "batch", 10**9, "at most 65536"),
        ("coating", "occlusion_pixels", 10**6, "at most 1024"),
        ("coating", "workers", 10**4, "at most 64"),
        ("coating", "max_step_mm", 1e-9, ">= 0.01"),
        ("coating", "sample_edge_mm", 1e-9, ">= 0.01"),
    ],
)
def test_static_bounds_name_the_key_and_the_bound(section, key, value, bound):
    message = fast(lambda: job_from_dict({section: {key: value}}), ConfigError)
    assert key in message and bound in message, message
    assert section in message, message


@pytest.mark.parametrize(
    ("section", "key", "value"),
    [
        ("paths", "edge_passes", 100),
        ("paths", "layers", 10_000),
        ("paths", "points_per_section", 100_000),
        ("paths", "step_mm", 0.01),
        ("output", "samples", 1_000_000),
        ("coating", "batch", 65_536),
        ("coating", "sample_edge_mm", 0),
    ],
)
def test_the_bound_itself_is_accepted(section, key, value):
    job = job_from_dict({section: {key: value}})
    assert getattr(getattr(job, section), key) == value


def test_unknown_process_names_the_key_and_the_presets():
    message = fast(lambda: FilmConfig(process="bogus"), ConfigError)
    assert "coating.process" in message and "bogus" in message
    assert "seed000_circle" in message and "bell003" in message and ".toml" in message
    assert FilmConfig(process="my_process.toml").process == "my_process.toml"


def test_defaults_stay_inside_the_bounds():
    JobConfig()  # nothing raised
    assert checks.MAX_LAYERS >= 1000 and checks.MAX_WAYPOINTS >= 1_000_000


# ------------------------------------------------------------------------------------------- part-dependent


def test_layers_from_the_spacing_are_checked_before_slicing(big_plate):
    from sprayplan.paths.planner import plan_paths

    message = fast(lambda: plan_paths(big_plate, PathConfig(spacing_mm=0.05)), ConfigError)
    assert message.startswith("paths.spacing_mm 0.05 would make")
    assert "layers" in message and "1500 mm" in message and "at most 1e+04" in message
    assert "use paths.spacing_mm >= 0.15" in message


def test_spacing_from_a_tiny_spray_radius_names_where_it_comes_from(big_plate):
    from sprayplan.paths.planner import plan_paths

    message = fast(lambda: plan_paths(big_plate, PathConfig(spray_radius_mm=0.01)), ConfigError)
    assert "spray_radius_mm" in message and "layers" in message


def test_waypoints_from_the_step_are_checked_before_slicing(big_plate):
    from sprayplan.paths.planner import plan_paths

    message = fast(lambda: plan_paths(big_plate, PathConfig(spacing_mm=1.0, step_mm=0.01)), ConfigError)
    assert message.startswith("paths.step_mm 0.01 would make")
    assert "waypoints" in message and "mm^2" in message and "at most 5e+06" in message
    value = float(message.rsplit(">= ", 1)[1])
    # the value asked for is accepted by the same check
    from sprayplan.paths.layers import check_layer_work

    check_layer_work(0.0, 1500.0, PathConfig(spacing_mm=1.0, step_mm=value), big_plate.area)
    with pytest.raises(ConfigError):
        check_layer_work(0.0, 1500.0, PathConfig(spacing_mm=1.0, step_mm=value / 2), big_plate.area)


def test_points_per_section_times_layers_is_bounded(big_plate):
    from sprayplan.paths.planner import plan_paths

    config = PathConfig(layers=1000, points_per_section=100_000)
    message = fast(lambda: plan_paths(big_plate, config), ConfigError)
    assert message.startswith("paths.points_per_section 100000 would make")
    assert "use paths.points_per_section <=" in message


def test_real_settings_pass_the_checks():
    from sprayplan.paths.layers import check_layer_work

    # a whole car body: about 12 m^2 over 5 m, 40 mm apart, 5 mm steps, and finer
    for spacing, step in ((40.0, 5.0), (10.0, 1.0)):
        check_layer_work(0.0, 5000.0, PathConfig(spacing_mm=spacing, step_mm=step, edge_passes=3), 12e6)


def test_even_sampling_names_the_spacing_and_the_part(big_plate):
    from sprayplan.surface.targets import make_targets

    message = fast(lambda: make_targets(big_plate, TargetsConfig(spacing_mm=0.05)), ConfigError)
    assert message.startswith("targets.spacing_mm 0.05 would make")
    assert "candidates of the even sampling" in message and "3e+06 mm^2" in message
    assert "at most 2e+07" in message and "use targets.spacing_mm >= 0.68" in message


def test_even_sampling_low_level_message_names_the_setting():
    from sprayplan.surface.filling import sample_even

    triangles = plate(0, 1000, 0, 1000, 500).triangles
    message = fast(lambda: sample_even(triangles, 0.01), ConfigError)
    assert "targets.spacing_mm" in message and "candidates" in message and ">=" in message


@pytest.mark.parametrize("fill", ["point", "line"])
def test_dfs_filling_names_h_min(big_plate, fill):
    from sprayplan.surface.targets import make_targets

    message = fast(lambda: make_targets(big_plate, TargetsConfig(fill=fill, h_min_mm=0.02)), ConfigError)
    assert message.startswith("targets.h_min_mm 0.02 would make") and "use targets.h_min_mm >=" in message


def test_dfs_estimate_is_above_what_the_filling_makes():
    from sprayplan.surface.filling import dfs_point_estimate, fill_dfs

    part = plate(0, 500, 0, 500, 50)
    for mode in ("point", "line"):
        points, _ = fill_dfs(part.triangles, 4.0, mode)
        assert len(points) <= dfs_point_estimate(part.area, 4.0, mode)


def test_film_samples_are_checked_before_splitting_the_mesh(big_plate):
    from sprayplan.coating.process import load_preset
    from sprayplan.coating.thickness import CoatingConfig, simulate
    from sprayplan.paths.planner import plan_paths

    paths = plan_paths(plate(0, 300, 0, 300, 100), PathConfig())
    process = load_preset("seed000_circle")
    message = fast(lambda: simulate(big_plate, paths, process, config=CoatingConfig(sample_edge_mm=0.01)), ConfigError)
    assert message.startswith("coating.sample_edge_mm 0.01 would make") and "film samples" in message
    long = plan_paths(big_plate, PathConfig(spacing_mm=10.0, step_mm=50.0))
    message = fast(lambda: simulate(big_plate, long, process, config=CoatingConfig(max_step_mm=0.01)), ConfigError)
    assert message.startswith("coating.max_step_mm 0.01 would make") and "gun samples" in message


def test_report_samples_bounded():
    from sprayplan.coating.report import _measuring_points

    painted = np.ones(10, bool)
    message = fast(lambda: _measuring_points(10**11, painted, np.ones(10), 0), ConfigError)
    assert "output.samples" in message and "1000000" in message
    with pytest.raises(ConfigError):
        OutputConfig(samples=10**11)


# ------------------------------------------------------------------------------------------------ ruled


def _ruled(**changes):
    from sprayplan.paths.ruled_toml import ruled_job_from_dict

    data = {
        "curve_a": {"type": "line", "start": [0, 0, 0], "end": [200, 0, 0]},
        "curve_b": {"type": "line", "start": [0, 100, 0], "end": [200, 100, 0]},
        "path": {"passes": 5, **changes},
    }
    data["path"] = {k: v for k, v in data["path"].items() if v is not None}
    return ruled_job_from_dict(data, "job.toml")


def test_ruled_passes_bounded():
    message = fast(lambda: _ruled(passes=10**9), PartFileError)
    assert message.startswith("job.toml") and "passes" in message and "at most 10000" in message


def test_ruled_step_and_spot_checked_before_sampling():
    from sprayplan.paths.ruled import ruled_paths

    job = _ruled(passes=10_000, step_mm=0.01)
    message = fast(lambda: ruled_paths(job), ConfigError)
    assert message.startswith("path.step_mm 0.01 would make") and "waypoints" in message
    job = _ruled(passes=None, spot_diameter_mm=1e-4)
    message = fast(lambda: ruled_paths(job), ConfigError)
    assert (
        message.startswith("path.spot_diameter_mm")
        and "passes" in message
        and "use path.spot_diameter_mm >=" in message
    )
    assert len(ruled_paths(_ruled()).spray_strokes) == 5


# ------------------------------------------------------------------------------------------------ droplets


def test_droplet_counts_bounded():
    from sprayplan.coating.droplet import DropletConfig, simulate_droplets

    assert "at most 1000000" in fast(lambda: DropletConfig(count=10**9), ConfigError)
    assert "use dt_s >=" in fast(lambda: simulate_droplets(DropletConfig(dt_s=1e-12)), ConfigError)
    config = DropletConfig(count=500_000, max_time_s=0.2, dt_s=1e-5)
    message = fast(lambda: simulate_droplets(config), ConfigError)
    assert message.startswith("droplet count 500000 would make") and "use count <=" in message
    DropletConfig()  # the default is fine


# ------------------------------------------------------------------------------------------------ coordinates


@pytest.mark.parametrize("value", [1e300, 1e120, 1e8, np.nan, np.inf, -np.inf])
def test_part_refuses_absurd_coordinates(value):
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, value]])
    message = fast(lambda: Part(vertices, np.array([[0, 1, 2]]), name="bad.stl"), DataError)
    assert message.startswith("bad.stl: vertex 3") and "1e+07 mm" in message


def test_part_at_the_bound_is_fine_and_faces_are_checked():
    Part(np.array([[0.0, 0, 0], [1e7, 0, 0], [0, -1e7, 0]]), np.array([[0, 1, 2]]))
    message = fast(lambda: Part(np.zeros((3, 3)), np.array([[0, 1, 3]]), name="p"), DataError)
    assert message.startswith("p: face 0") and "3 vertices" in message


# ------------------------------------------------------------------------------------------------ poses


def _mirror():
    pose = np.eye(4)
    pose[:3, 3] = [400.0, 100.0, 300.0]
    pose[2, 2] = -1.0  # det -1
    return pose


def _good(ur5):
    from sprayplan.robots.model import fk

    return fk(ur5, np.array([[0.1, -1.2, 1.3, -1.5, -1.4, 0.2]]))[0]


@pytest.fixture(scope="module")
def ur5():
    from sprayplan.robots.model import load_robot

    return load_robot("ur5")


def test_mirror_pose_is_an_error_naming_the_row(ur5):
    from sprayplan.robots.ur_ik import ik_path, ur_ik

    poses = np.stack([_good(ur5), _good(ur5), _mirror()])
    for call in (lambda: ur_ik(ur5, poses), lambda: ik_path(ur5, poses)):
        message = fast(call, DataError)
        assert message.startswith("flange2base row 2") and "determinant -1" in message
    assert ur_ik(ur5, poses[:2]).valid.any(axis=1).all()


def test_sheared_pose_and_bad_last_row():
    bad = np.eye(4)
    bad[0, 1] = 0.5
    assert "not orthonormal" in fast(lambda: checks.check_poses(bad, "poses"), DataError)
    bad = np.eye(4)
    bad[3, 0] = 1.0
    assert "last row" in fast(lambda: checks.check_poses(bad, "poses"), DataError)
    nan = np.full((4, 4), np.nan)
    assert "row 1" in fast(lambda: checks.check_poses(np.stack([np.eye(4), nan]), "poses"), DataError)
    assert checks.check_poses(np.stack([np.eye(4), nan]), "poses", allow_nan=True).shape == (2, 4, 4)


def test_interface_and_gantry_refuse_mirrors_and_nan_platforms():
    from sprayplan.robots.gantry import build_gantry, solve_gantry_path
    from sprayplan.robots.interface import robot_from_name

    robot = robot_from_name("gantry-ur5", "wa101")
    message = fast(lambda: robot.ik(np.stack([np.eye(4), _mirror()])), DataError)
    assert message.startswith("tcp2world row 1")
    gantry = build_gantry("ur5", "wa101")
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])  # gun pointing down
    pose[:3, 3] = [0.0, 0.0, 500.0]
    message = fast(lambda: solve_gantry_path(gantry, pose[None], np.array([np.nan, 0.0, 0.0])), DataError)
    assert message.startswith("platform must be") and "NaN" in message
    message = fast(lambda: solve_gantry_path(gantry, _mirror()[None], np.zeros(3)), DataError)
    assert message.startswith("gun2world row 0")
    message = fast(lambda: robot.ik(pose, platform_mm=[np.nan, 0, 0]), DataError)
    assert message.startswith("platform_mm")


def test_seed_q_message_names_it_and_shows_the_values(ur5):
    from sprayplan.robots.ur_ik import ik_path

    message = fast(lambda: ik_path(ur5, _good(ur5), seed_q=[np.nan, 0, 0, 0, 0, 0]), ConfigError)
    assert message.startswith("seed_q must be 6 finite numbers") and "nan, 0, 0, 0, 0, 0" in message
    message = fast(lambda: ik_path(ur5, _good(ur5), seed_q=[1, 2]), ConfigError)
    assert "2 value(s): 1, 2" in message


def test_unknown_robot_names_the_setting_and_lists_the_robots():
    from sprayplan.robots.model import load_robot

    message = fast(lambda: load_robot("ur10", "--robot"), ConfigError)
    assert message.startswith("--robot 'ur10'") and "ur5, " in message and "r5150" in message
    assert load_robot("ur10" if False else "ur5").name == "ur5"


def test_unknown_process_preset_names_the_setting():
    from sprayplan.coating.process import load_preset

    message = fast(lambda: load_preset("bogus", "--process"), ConfigError)
    assert message.startswith("--process 'bogus'") and "seed000_circle" in message


# ------------------------------------------------------------------------------------------------ paths.json


@pytest.mark.parametrize("normal", [[math.nan, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
def test_paths_json_bad_normals_name_the_stroke_and_waypoint(tmp_path, normal):
    from sprayplan.export.paths_json import read_paths_json, write_paths_json
    from sprayplan.paths.planner import plan_paths

    paths = plan_paths(plate(0, 300, 0, 300, 100), PathConfig())
    target = tmp_path / "paths.json"
    write_paths_json(target, paths)
    data = json.loads(target.read_text())
    data["strokes"][1]["normals"][3] = normal
    target.write_text(json.dumps(data))
    message = fast(lambda: read_paths_json(target), PartFileError)
    assert message.startswith(str(target)) and "stroke 1 waypoint 3" in message and "normal" in message


def test_paths_json_absurd_coordinates(tmp_path):
    from sprayplan.export.paths_json import read_paths_json, write_paths_json
    from sprayplan.paths.planner import plan_paths

    paths = plan_paths(plate(0, 300, 0, 300, 100), PathConfig())
    target = tmp_path / "paths.json"
    write_paths_json(target, paths)
    assert len(read_paths_json(target).strokes) == len(paths.strokes)
    data = json.loads(target.read_text())
    data["strokes"][0]["tcp"][0] = [1e300, 0.0, 0.0]
    target.write_text(json.dumps(data))
    message = fast(lambda: read_paths_json(target), PartFileError)
    assert "stroke 0 waypoint 0: tcp" in message
