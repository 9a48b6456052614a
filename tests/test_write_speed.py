"""The plan folder's writers made faster write the same characters as their straightforward forms.

plan.json's text is made without its dict (``plan_json.plan_json_text``: floats through ``str`` of lists, the
tool axis from the normals' text), waypoints.csv's rows by one ``%`` operation a stroke, and the viewer's
flags a stroke at a time; each is checked here against the plain per-value form it replaced, on values that
catch a wrong change: negative zero, tiny and huge numbers, integers, NaN and infinity, empty strokes.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from sprayplan.config import JobConfig
from sprayplan.export import plan_json
from sprayplan.types import Plan, StationPlan, Stroke


def _awkward(rng, shape, finite: bool = False) -> np.ndarray:
    """Random floats over many magnitudes with zeros, negative zeros, integers and (unless ``finite``) NaN and
    infinities mixed in."""
    values = rng.normal(size=shape) * 10.0 ** rng.integers(-30, 30, size=shape)
    pick = rng.random(size=shape)
    values[pick < 0.05] = 0.0
    values[(pick >= 0.05) & (pick < 0.1)] = -0.0
    whole = (pick >= 0.1) & (pick < 0.15)
    values[whole] = np.round(values[whole] * 1e-25)  # integers, small ones mostly
    values[(pick >= 0.15) & (pick < 0.18)] = 1e16  # the repr changes to an exponent here
    values[(pick >= 0.18) & (pick < 0.2)] = 1e-5
    if not finite:
        values[(pick >= 0.2) & (pick < 0.25)] = np.nan
        values[(pick >= 0.25) & (pick < 0.28)] = np.inf
        values[(pick >= 0.28) & (pick < 0.3)] = -np.inf
    return values


def _json(value) -> str:
    return json.dumps(value, separators=(",", ":"), allow_nan=False)


@pytest.mark.parametrize("shape", [(0,), (0, 3), (1,), (7,), (1, 3), (6, 3), (5, 9), (3, 0)])
def test_the_float_text_is_what_json_writes_for_the_lists(shape):
    rng = np.random.default_rng(sum(shape) + 17 * len(shape))
    for finite in (True, False):
        for _ in range(20):
            values = _awkward(rng, shape, finite)
            assert plan_json._floats_json(values) == _json(plan_json._floats(values))
            assert plan_json._negated_json(plan_json._floats_json(values)) == _json(plan_json._floats(-values))


@pytest.mark.parametrize("fmt", [".10g", ".6g"])
@pytest.mark.parametrize("blank", [True, False])
def test_the_cells_are_formatted_as_format_formats_each_value(fmt, blank):
    rng = np.random.default_rng(3)
    for n in (0, 1, 2, 50, 1000):
        values = _awkward(rng, (n,))
        expected = [format(v, fmt) if np.isfinite(v) or not blank else "" for v in values.tolist()]
        assert plan_json._cells(values, fmt, blank) == expected
        assert plan_json._cells(np.full(n, np.nan), fmt, blank) == [("" if blank else "nan")] * n
    # "%" of a float is format's, for the specs the rows use
    values = _awkward(rng, (5000,)).tolist()
    for spec in (".10g", ".6g"):
        assert ("%" + spec + "|") * len(values) % tuple(values) == "".join(format(v, spec) + "|" for v in values)


def _stroke(rng, n: int, kind: str) -> Stroke:
    points = rng.normal(size=(n, 3)) * 1000.0
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) if n else 1.0
    normals[rng.random(size=(n, 3)) < 0.1] = -0.0
    normals[rng.random(size=(n, 3)) < 0.1] = 0.0
    return Stroke(
        points=points,
        normals=normals,
        tcp=points + 200.0 * normals,
        spray_on=kind != "transfer",
        on_part=rng.random(n) < 0.8,
        layer=int(rng.integers(-1, 4)),
        dwell=1.0 + rng.random(n) * (rng.random(n) < 0.5),
        kind=kind,
    )


def _station(rng, index: int, sizes: list[int]) -> StationPlan:
    kinds = ["spray", "transfer", "touch-up"]
    strokes = [_stroke(rng, n, kinds[k % 3]) for k, n in enumerate(sizes)]
    m = sum(sizes)
    pick = rng.random(m)
    reachable = pick > 0.2
    method = np.where(reachable, np.where(pick > 0.6, "analytic", "sqp"), "")
    q9 = _awkward(rng, (m, 9), finite=True)
    q9[~reachable] = np.nan
    error = np.where(reachable, np.abs(_awkward(rng, (m,), finite=True)) * (pick > 0.5), np.nan)
    axis = np.where(reachable, rng.random(m) * 0.05, np.nan)
    hit = rng.random(m) < 0.1
    distance = np.where(rng.random(m) < 0.7, rng.normal(size=m) * 30.0, np.nan)
    return StationPlan(
        index=index,
        platform_mm=rng.normal(size=3) * 1000.0,
        strokes=strokes,
        q9=q9,
        reachable=reachable,
        method=method,
        position_error_mm=error,
        axis_error_deg=axis,
        branch_change=rng.random(m) < 0.1,
        collision=hit,
        motion_collision=rng.random(m) < 0.1,
        collision_distance_mm=distance,
        collision_with=np.where(hit, 'elbow/part, 100% "odd"', ""),
        repair=np.where(rng.random(m) < 0.1, "branch", ""),
    )


@pytest.fixture(scope="module")
def plan_and_timing():
    rng = np.random.default_rng(11)
    stations = [_station(rng, 4, [5, 0, 3, 40, 1]), _station(rng, 1, [12, 7]), _station(rng, 2, [])]
    plan = Plan(stations=stations, home_mm=[0.0, -0.0, 1e16], unassigned=rng.normal(size=(4, 3)), name="part, ü")
    lengths = [len(st) for st in stations]
    timing = SimpleNamespace(
        t_s=[np.where(rng.random(n) < 0.9, np.cumsum(rng.random(n)), np.nan) for n in lengths],
        speed_mm_s=[np.where(rng.random(n) < 0.9, rng.random(n) * 500.0, np.nan) for n in lengths],
    )
    return plan, timing


def _reference_plan_dict(plan, job, totals, part_file, film, timing) -> dict:
    """plan_to_dict as it was written before the writer was made faster: one dict, stroke by stroke."""
    from sprayplan import __version__
    from sprayplan.coating import load_preset
    from sprayplan.config import job_to_dict

    floats = plan_json._floats
    flow = float(load_preset(job.coating.process).flow_ml_min)
    stations = []
    for place, st in enumerate(plan.stations):
        strokes, start = [], 0
        for i, s in enumerate(st.strokes):
            sl = slice(start, start + len(s))
            start += len(s)
            strokes.append(
                {
                    "index": i,
                    "spray_on": s.spray_on,
                    "kind": s.kind,
                    "layer": s.layer,
                    "tcp": floats(s.tcp),
                    "tool_axis": floats(-s.normals),
                    "points": floats(s.points),
                    "normals": floats(s.normals),
                    "on_part": s.on_part.tolist(),
                    "joints": floats(st.q9[sl]),
                    "reachable": st.reachable[sl].tolist(),
                    "method": st.method[sl].tolist(),
                    "position_error_mm": floats(st.position_error_mm[sl]),
                    "axis_error_deg": floats(st.axis_error_deg[sl]),
                    "branch_change": st.branch_change[sl].tolist(),
                    "collision": st.collision[sl].tolist(),
                    "motion_collision": st.motion_collision[sl].tolist(),
                    "collision_distance_mm": floats(st.collision_distance_mm[sl]),
                    "collision_with": st.collision_with[sl].tolist(),
                    "repair": st.repair[sl].tolist(),
                    "flow_ml_min": flow if s.spray_on else 0.0,
                    "speed_mm_s": job.motion.gun_speed_mm_s if s.spray_on else job.motion.transfer_speed_mm_s,
                    "tcp_speed_mm_s": floats(plan_json.tip_speeds(s, job)),
                    "dwell": floats(s.dwell),
                }
            )
            if timing is not None:
                strokes[-1]["t_s"] = floats(timing.t_s[place][sl])
                strokes[-1]["achievable_speed_mm_s"] = floats(timing.speed_mm_s[place][sl])
        stations.append(
            {"order": place, "station": st.index, "platform_mm": floats(st.platform_mm), "strokes": strokes}
        )
    return {
        "format": plan_json.FORMAT,
        "version": plan_json.VERSION,
        "sprayplan_version": __version__,
        "units": {"length": "mm", "angle": "rad", "time": "s", "errors": "mm and deg"},
        "part": plan.name,
        "part_file": part_file,
        "settings": plan_json._clean(job_to_dict(job)),
        "joints": list(plan_json.JOINTS),
        "home_mm": floats(plan.home_mm),
        "stations": stations,
        "unassigned_points": floats(plan.unassigned),
        "totals": plan_json._clean(totals),
        "film": None if film is None else plan_json.film_summary(film),
    }


@pytest.mark.parametrize("timed", [False, True])
def test_plan_json_is_the_text_of_the_plan_dict(plan_and_timing, timed):
    plan, timing = plan_and_timing
    timing = timing if timed else None
    job = JobConfig()
    totals = {"time_s": np.float64(12.5), "strokes": np.int64(9), "gap": float("nan"), "note": "a, b"}
    expected = _reference_plan_dict(plan, job, totals, "/parts/a b.ply", None, timing)
    data = plan_json.plan_to_dict(plan, job, totals, "/parts/a b.ply", None, timing)
    assert list(data) == list(expected)
    assert _json(data) == _json(expected)
    assert plan_json.plan_json_text(plan, job, totals, "/parts/a b.ply", None, timing) == _json(expected)


def test_plan_json_refuses_what_json_refuses(plan_and_timing):
    plan, _ = plan_and_timing
    job = JobConfig()
    for totals in ({"bad": object()}, {"bad": {1, 2}}):
        with pytest.raises(TypeError):
            json.dumps(plan_json.plan_to_dict(plan, job, totals), allow_nan=False)
        with pytest.raises(TypeError):
            plan_json.plan_json_text(plan, job, totals)


def _reference_waypoints_csv(plan, job, timing) -> str:
    """waypoints.csv as it was written before: each cell formatted on its own."""

    def cells(values, fmt, blank=True):
        values = np.asarray(values, dtype=np.float64)
        return [format(v, fmt) if np.isfinite(v) or not blank else "" for v in values.tolist()]

    header = (
        "station,stroke,waypoint,spray_on,x,y,z,ax,ay,az,q1,q2,q3,q4,q5,q6,tx,ty,tz,reachable,position_error_mm,"
        "axis_error_deg,speed_mm_s"
    )
    header += ",t_s,achievable_speed_mm_s" if timing is not None else ""
    header += ",collision,motion_collision,collision_distance_mm,collision_with,repair\n"
    lines = [header]
    for place, st in enumerate(plan.stations):
        start = 0
        for i, s in enumerate(st.strokes):
            n = len(s)
            sl = slice(start, start + n)
            start += n
            if not n:
                continue
            ok = st.reachable[sl]
            floats = np.column_stack([s.tcp, -s.normals, np.where(ok[:, None], st.q9[sl], np.nan)])
            columns = [[f"{place},{i},{j},{int(s.spray_on)}" for j in range(n)]]
            columns += [cells(floats[:, c], ".10g") for c in range(floats.shape[1])]
            columns.append([f"{int(v)}" for v in ok.tolist()])
            columns.append(cells(st.position_error_mm[sl], ".6g"))
            columns.append(cells(st.axis_error_deg[sl], ".6g"))
            columns.append(cells(plan_json.tip_speeds(s, job), ".6g", blank=False))
            if timing is not None:
                columns.append(cells(timing.t_s[place][sl], ".10g"))
                columns.append(cells(timing.speed_mm_s[place][sl], ".10g"))
            columns.append(
                [f"{int(c)},{int(m)}" for c, m in zip(st.collision[sl].tolist(), st.motion_collision[sl].tolist())]
            )
            columns.append(cells(st.collision_distance_mm[sl], ".6g"))
            columns.append([str(w) for w in st.collision_with[sl].tolist()])
            columns.append([str(r) for r in st.repair[sl].tolist()])
            lines.append("\n".join(map(",".join, zip(*columns))) + "\n")
    return "".join(lines)


@pytest.mark.parametrize("timed", [False, True])
def test_waypoints_csv_is_the_cell_by_cell_table(plan_and_timing, timed, tmp_path):
    plan, timing = plan_and_timing
    timing = timing if timed else None
    job = JobConfig()
    path = tmp_path / "waypoints.csv"
    plan_json.write_waypoints_csv(path, plan, job, timing)
    assert path.read_bytes() == _reference_waypoints_csv(plan, job, timing).encode()


def _reference_flags(scene) -> dict:
    """view.html.flagged_waypoints as it was written before: waypoint by waypoint."""
    kin = scene.job.kinematics
    out = {k: ([], []) for k in ("unreachable", "approximate", "branch change", "collision")}
    for st in scene.plan.stations:
        start = 0
        for i, s in enumerate(st.strokes):
            sl = slice(start, start + len(s))
            start += len(s)
            reach, err, axis = st.reachable[sl], st.position_error_mm[sl], st.axis_error_deg[sl]
            where = f"station {st.index}, stroke {i} ({s.kind}), waypoint "
            for j in np.flatnonzero(~reach):
                out["unreachable"][0].append(s.tcp[j])
                out["unreachable"][1].append(where + f"{j}: unreachable (no IK solution within the limits)")
            approx = reach & (st.method[sl] == "sqp") & ((np.nan_to_num(err) > 0.01) | (np.nan_to_num(axis) > 0.01))
            for j in np.flatnonzero(approx):
                out["approximate"][0].append(s.tcp[j])
                out["approximate"][1].append(
                    where + f"{j}: reached by SQP only within the tolerance: position error {err[j]:.2f} mm "
                    f"(<= {kin.position_tol_mm:g}), axis error {axis[j]:.2f} deg (<= {kin.axis_tol_deg:g})"
                )
            for j in np.flatnonzero(reach & st.branch_change[sl]):
                out["branch change"][0].append(s.tcp[j])
                out["branch change"][1].append(where + f"{j}: the arm changes its IK branch here (a flip)")
            hit, moving = st.collision[sl], st.motion_collision[sl]
            for j in np.flatnonzero(reach & (hit | moving)):
                what = []
                if hit[j]:
                    what.append(f"{st.collision_with[sl][j]} at {st.collision_distance_mm[sl][j]:.1f} mm")
                if moving[j]:
                    what.append("the motion into it")
                out["collision"][0].append(s.tcp[j])
                out["collision"][1].append(where + f"{j}: in collision, no repair freed it: " + "; ".join(what))
    return {k: (np.array(v[0]).reshape(-1, 3), v[1]) for k, v in out.items()}


def test_the_viewer_flags_the_same_waypoints_with_the_same_words(plan_and_timing):
    from sprayplan.view.html import flagged_waypoints

    plan, _ = plan_and_timing
    scene = SimpleNamespace(plan=plan, job=JobConfig())
    flags = flagged_waypoints(scene)
    expected = _reference_flags(scene)
    assert all(len(expected[k][1]) for k in expected)  # every reason occurs
    for reason, (where, texts) in expected.items():
        assert flags[reason][1] == texts
        assert flags[reason][0].dtype == where.dtype and flags[reason][0].shape == where.shape
        assert np.array_equal(flags[reason][0], where)
    assert flags["unassigned"][0].shape == (4, 3)
