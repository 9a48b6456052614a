"""plan.json round trips: a plan written and read back is the same plan, field by field and byte for byte."""

from __future__ import annotations

import copy
import dataclasses
import json
import re

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.config import JobConfig
from sprayplan.errors import PartFileError
from sprayplan.export.job_files import write_job
from sprayplan.export.plan_json import plan_to_dict, write_plan
from sprayplan.export.plan_read import plan_file_from_dict, plan_from_dict, read_plan_file
from sprayplan.job import run_job
from sprayplan.types import Plan, StationPlan, Stroke
from tests.helpers import BARE_NORMALS


def assert_same(a, b, where: str = "plan") -> None:
    """Fail unless ``a`` and ``b`` are equal in every dataclass field, recursively: arrays of the same dtype and
    shape, floats bit for bit (NaN in the same places, the sign of zero kept), scalars of the same type."""
    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, tuple):
        assert len(a) == len(b), f"{where}: {len(a)} != {len(b)} items"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert (a.dtype, a.shape) == (b.dtype, b.shape), f"{where}: {a.dtype}{a.shape} != {b.dtype}{b.shape}"
        if a.dtype == object:
            assert [type(v) for v in a.flat] == [type(v) for v in b.flat], f"{where}: element types differ"
            assert a.tolist() == b.tolist(), f"{where}: values differ"
        elif a.dtype.kind == "f":
            nan = np.isnan(a)
            assert (nan == np.isnan(b)).all(), f"{where}: NaN in other places"
            bits = a.view(np.uint64 if a.itemsize == 8 else np.uint32)
            other = b.view(bits.dtype)
            assert (bits[~nan] == other[~nan]).all(), f"{where}: values differ"
        else:
            assert (a == b).all(), f"{where}: values differ"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def changed(value):
    """A value of the same kind as ``value`` that differs from it (or None when there is nothing to change)."""
    if isinstance(value, np.ndarray):
        if value.size == 0:
            return None
        out = value.copy()
        flat = out.reshape(-1)
        flat[0] = {"b": lambda v: not v, "O": lambda v: "sqp" if v != "sqp" else "analytic"}.get(
            out.dtype.kind, lambda v: 1.5 if np.isnan(v) else np.nextafter(v, np.inf)
        )(flat[0])
        return out
    if isinstance(value, tuple):
        return value[:-1]
    if isinstance(value, bool):
        return not value
    if isinstance(value, int):
        return value + 1
    if isinstance(value, str):
        return value + "x"
    raise AssertionError(f"no change for {value!r}")


def with_field(obj, name, value):
    """A copy of a frozen dataclass with one field set, bypassing its validation."""
    out = copy.copy(obj)
    object.__setattr__(out, name, value)
    return out


def test_the_comparison_sees_every_field():
    plan = _hand_made()
    station = plan.stations[0]
    stroke = station.strokes[0]
    assert_same(plan, plan)
    cases = [(plan, None), (station, lambda st: with_field(plan, "stations", (st, *plan.stations[1:])))]
    outer = cases[1][1]
    cases.append((stroke, lambda s: outer(with_field(station, "strokes", (s, *station.strokes[1:])))))
    seen = set()
    for obj, wrap in cases:
        for f in dataclasses.fields(obj):
            new = changed(getattr(obj, f.name))
            if new is None:
                continue
            other = with_field(obj, f.name, new)
            with pytest.raises(AssertionError):
                assert_same(plan, other if wrap is None else wrap(other))
            seen.add((type(obj).__name__, f.name))
    # a changed dtype alone is a difference too
    with pytest.raises(AssertionError):
        assert_same(plan, with_field(plan, "home_mm", plan.home_mm.astype(np.float32)))
    assert {(cls.__name__, f.name) for cls in (Plan, StationPlan, Stroke) for f in dataclasses.fields(cls)} <= seen


@pytest.fixture(scope="module")
def reach(testdata, tmp_path_factory):
    """A plan of part of the reach test part (with unreachable waypoints: the gun on every normal), written
    with write_job: (result, folder)."""
    job = JobConfig().replace(load={"units": "m", "region": "x > -250"}, paths=BARE_NORMALS)
    result = run_job(testdata / "meshes" / "reach_curved_part.ply", job, until="totals")
    out = tmp_path_factory.mktemp("reach")
    write_job(out, result)
    return result, out


@pytest.fixture(scope="module")
def coated(testdata, tmp_path_factory):
    """The same with a film target: tuned speeds, touch-ups and an added station."""
    job = JobConfig().replace(
        load={"units": "m", "region": "x > -300"}, coating={"thickness_um": 50.0}, paths=BARE_NORMALS
    )
    result = run_job(testdata / "meshes" / "reach_curved_part.ply", job, until="totals")
    out = tmp_path_factory.mktemp("coated")
    write_job(out, result)
    return result, out


def _round_trip(result, out, tmp_path):
    read = read_plan_file(out / "plan.json")
    assert_same(result.plan, read.plan)
    assert read.job == result.job and read.totals == json.loads(json.dumps(result.totals))
    again = tmp_path / "again"
    write_plan(again, read.plan, read.job, read.totals, read.part_file, read.film, read.timing)
    for name in ("plan.json", "waypoints.csv"):
        assert (again / name).read_bytes() == (out / name).read_bytes(), name
    return read


def test_a_plan_reads_back_equal(reach, tmp_path):
    result, out = reach
    plan = result.plan
    assert not all(st.reachable.all() for st in plan.stations)  # unreachable waypoints are in the test
    read = _round_trip(result, out, tmp_path)
    assert read.film is None and read.part_file.endswith("reach_curved_part.ply")


def test_a_tuned_plan_with_touch_ups_reads_back_equal(coated, tmp_path):
    result, out = coated
    plan = result.plan
    kinds = {s.kind for s in plan.strokes}
    assert kinds == {"spray", "transfer", "touch-up"}
    assert any((s.dwell != 1.0).any() for s in plan.strokes)
    assert len(plan.stations) > len(result.layout.index)  # a station added for touch-ups
    read = _round_trip(result, out, tmp_path)
    assert read.totals["speed_tuning"]["touch_up_strokes"] > 0
    assert read.film["spec"]["target_um"] == 50.0 and "strokes" not in read.film
    assert read.film["painted"]["mean_um"] == json.loads((out / "coating.json").read_text())["painted"]["mean_um"]


def _hand_made() -> Plan:
    pts = np.array([[0.0, 0.0, 0.0], [10.0, 0.1, -0.0], [20.0, 1 / 3, 1e-300]])
    up = np.tile([0.0, 0.0, 1.0], (3, 1))
    spray = Stroke(pts, up, pts + 113.0 * up, True, [True, True, False], 4, [1.0, 0.5, 2.0 / 3.0])
    move = Stroke(pts[::-1], up, pts[::-1] + 113.0 * up, False, [False] * 3, -1)
    q9 = np.arange(54, dtype=float).reshape(6, 9) / 7.0
    q9[1] = np.nan  # unreachable: no joints
    q9[4, :3] = np.nan  # unreachable, with numbers left in the gantry axes
    station = StationPlan(
        3,
        [1.0, 2.0, 3.5],
        (spray, move),
        q9,
        [True, False, True, True, False, True],
        ["analytic", "", "sqp", "analytic", "", "analytic"],
        [0.0, np.nan, 0.1, 1e-9, np.nan, 2.0],
        [0.0, np.nan, 0.2, 0.0, np.nan, 5.0],
        [False, False, True, False, False, False],
    )
    return Plan((station,), [0.0, -5.0, 100.0], [[1.0, 2.0, 3.0], [np.pi, np.e, -1e10]], "hand-made")


def test_a_hand_made_plan_with_unreachable_waypoints_reads_back_equal(tmp_path):
    plan, job = _hand_made(), JobConfig()
    write_plan(tmp_path, plan, job, {"stations": 1, "max_position_error_mm": None})
    text = (tmp_path / "plan.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    data = json.loads(text)
    assert data["stations"][0]["strokes"][0]["joints"][1] == [None] * 9
    read = read_plan_file(tmp_path / "plan.json")
    assert_same(plan, read.plan)
    assert read.job == job and read.part_file is None and read.film is None
    assert_same(plan, plan_from_dict(plan_to_dict(plan, job, {}))[0])


def test_inf_is_written_as_null_and_read_as_nan(tmp_path):
    plan = _hand_made()
    station = plan.stations[0]
    errors = station.position_error_mm.copy()
    errors[0] = np.inf
    plan = dataclasses.replace(plan, stations=(dataclasses.replace(station, position_error_mm=errors),))
    data = json.loads(json.dumps(plan_to_dict(plan, JobConfig(), {}), allow_nan=False))
    assert data["stations"][0]["strokes"][0]["position_error_mm"][0] is None
    assert np.isnan(plan_from_dict(data)[0].stations[0].position_error_mm[0])


def _broken(data: dict, path: tuple, value=KeyError):
    """A copy of ``data`` with the item at ``path`` removed (KeyError) or set to ``value``."""
    data = copy.deepcopy(data)
    table = data
    for key in path[:-1]:
        table = table[key]
    if value is KeyError:
        del table[path[-1]]
    else:
        table[path[-1]] = value
    return data


@pytest.mark.parametrize(
    "path, value, message",
    [
        (("settings",), KeyError, "missing key settings"),
        (("stations",), KeyError, "missing key stations"),
        (("home_mm",), KeyError, "missing key home_mm"),
        (("totals",), KeyError, "missing key totals"),
        (("stations", 0, "platform_mm"), KeyError, r"missing key stations\[0\].platform_mm"),
        (("stations", 0, "strokes", 1, "dwell"), KeyError, r"missing key stations\[0\].strokes\[1\].dwell"),
        (("stations", 0, "strokes", 0, "kind"), KeyError, r"missing key stations\[0\].strokes\[0\].kind"),
        (("stations", 0, "strokes", 0, "joints"), KeyError, r"missing key stations\[0\].strokes\[0\].joints"),
        (("stations", 0, "strokes", 0, "method"), KeyError, r"missing key stations\[0\].strokes\[0\].method"),
        (("stations",), {}, "stations: must be a list, got an object"),
        (("stations", 0, "station"), "3", r"stations\[0\].station: must be a whole number, got a string"),
        (("stations", 0, "strokes", 0, "layer"), True, r"strokes\[0\].layer: must be a whole number, got true"),
        (("stations", 0, "strokes", 0, "spray_on"), 1, r"strokes\[0\].spray_on: must be true or false"),
        (("stations", 0, "strokes", 0, "points", 1, 0), "1", r"strokes\[0\].points: must hold numbers or null"),
        (("stations", 0, "strokes", 0, "tcp", 1), [1.0, 2.0], r"strokes\[0\].tcp: must be 3 lists of 3 numbers"),
        (("stations", 0, "strokes", 0, "dwell"), [1.0], r"strokes\[0\].dwell: must be 3 numbers"),
        (("stations", 0, "strokes", 0, "dwell", 0), -1.0, r"strokes\[0\]: dwell must be positive"),
        (("stations", 0, "strokes", 0, "on_part", 0), 0, r"strokes\[0\].on_part: must hold true or false"),
        (("stations", 0, "strokes", 1, "method", 0), "ik", r"stations\[0\]: method must be one of"),
        (("stations", 0, "strokes", 0, "kind"), "paint", r"strokes\[0\]: kind must be one of"),
        (("settings", "paths", "spacing_mm"), "wide", "settings: "),
        (("settings", "plan"), {"spacing_mm": 40.0}, r"settings: the \[plan\] table was split"),
        (("part_file",), 3, "part_file: must be a string or null"),
    ],
)
def test_a_broken_plan_file_names_the_key(tmp_path, path, value, message):
    write_plan(tmp_path, _hand_made(), JobConfig(), {})
    data = _broken(json.loads((tmp_path / "plan.json").read_text()), path, value)
    (tmp_path / "plan.json").write_text(json.dumps(data))
    with pytest.raises(PartFileError, match=message) as info:
        read_plan_file(tmp_path / "plan.json")
    assert str(info.value).startswith(str(tmp_path / "plan.json") + ": ") and "\n" not in str(info.value)
    with pytest.raises(PartFileError, match=message):
        plan_file_from_dict(data, str(tmp_path / "plan.json"))


@pytest.mark.parametrize(
    "change, message",
    [
        ({"version": 1}, "plan file version 1: this sprayplan reads version 2"),
        ({"version": "2"}, "plan file version '2': this sprayplan reads version 2"),
        ({"format": "sprayplan.paths"}, 'not a sprayplan plan file .expected "format": "sprayplan.plan", version 2'),
    ],
)
def test_simulate_refuses_a_broken_plan_in_one_line(tmp_path, capsys, change, message):
    write_plan(tmp_path, _hand_made(), JobConfig(), {})
    data = json.loads((tmp_path / "plan.json").read_text())
    (tmp_path / "plan.json").write_text(json.dumps({**data, **change}))
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["simulate", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(tmp_path / "plan.json") in err
    assert re.search(message, err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_simulate_names_a_missing_key_in_one_line(tmp_path, capsys):
    write_plan(tmp_path, _hand_made(), JobConfig(), {})
    data = _broken(json.loads((tmp_path / "plan.json").read_text()), ("stations", 0, "strokes", 1, "points"))
    (tmp_path / "plan.json").write_text(json.dumps(data))
    assert main(["simulate", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"sprayplan: error: {tmp_path / 'plan.json'}: missing key stations[0].strokes[1].points"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.json", "waypoints.csv"]
