"""The robots of a cell worked on side by side (``cells.each``, ``[collision] workers``): the calls' results in
their order, from other processes, errors raised; a cell plan with collisions the same on one process as on
two."""

from __future__ import annotations

import logging
import multiprocessing
import os

import numpy as np
import pytest

from sprayplan.cells import load_cell
from sprayplan.cells.each import each_robot, worker_count
from sprayplan.cells.plan import plan_cell
from sprayplan.config import JobConfig
from sprayplan.errors import ConfigError
from sprayplan.export.stl import write_stl_binary
from sprayplan.io.load import load_part
from tests.helpers import grid_box
from tests.test_cell_plan import CELL, SIZE

FORK = "fork" in multiprocessing.get_all_start_methods()


def _square_and_pid(x):
    return x * x, os.getpid()


def _fails(x):
    raise ValueError(f"robot {x} failed")


def test_results_come_back_in_the_calls_order_whatever_order_they_run_in():
    calls = [(_square_and_pid, (x,)) for x in range(5)]
    sizes = [1, 50, 3, 40, 2]  # started largest first
    out = each_robot(calls, workers=2, sizes=sizes)
    assert [r for r, _ in out] == [0, 1, 4, 9, 16]
    pids = {p for _, p in out}
    if FORK:
        assert os.getpid() not in pids and 1 <= len(pids) <= 2
    alone = each_robot(calls, workers=1)
    assert [r for r, _ in alone] == [0, 1, 4, 9, 16] and {p for _, p in alone} == {os.getpid()}


def test_an_error_in_a_robots_call_is_raised_to_the_caller():
    with pytest.raises(ValueError, match="robot 1 failed"):
        each_robot([(_square_and_pid, (0,)), (_fails, (1,))], workers=2)


def test_worker_count_is_capped_by_the_calls():
    assert worker_count(8, 3) == 3 and worker_count(1, 3) == 1 and worker_count(None, 1) == 1


@pytest.mark.parametrize("bad", [0, -1, 1000])
def test_a_bad_worker_count_is_refused_naming_the_key(bad):
    with pytest.raises(ConfigError, match="workers"):
        JobConfig().replace(collision={"workers": bad})


@pytest.mark.skipif(not FORK, reason="the robots run side by side only where processes fork")
def test_a_cell_plan_with_collisions_is_the_same_on_one_process_and_on_two(tmp_path):
    """The two-robot box with ``[collision] check``: every robot's joints, track, reach, strokes and run-ups,
    and the collision and run-up reports, equal with ``workers = 1`` and ``workers = 2``."""
    pytest.importorskip("coal")
    (tmp_path / "small2.toml").write_text(CELL)
    (tmp_path / "box.stl").write_bytes(write_stl_binary(grid_box(n=8, size=SIZE).triangles))
    cell, part = load_cell(tmp_path / "small2.toml"), load_part(str(tmp_path / "box.stl"))
    plans = [
        plan_cell(
            part, cell, JobConfig().replace(coating={"thickness_um": 50.0}, collision={"check": True, "workers": w})
        )
        for w in (1, 2)
    ]
    one, two = plans
    for a, b in zip(one.robots, two.robots):
        for key in ("q", "track_mm", "reachable", "collides", "lead_q", "lead_track_mm"):
            assert np.array_equal(getattr(a, key), getattr(b, key), equal_nan=True), (a.name, key)
        assert [(s.kind, s.spray_on, len(s)) for s in a.strokes] == [(s.kind, s.spray_on, len(s)) for s in b.strokes]
    assert one.report["collisions"] == two.report["collisions"]
    assert one.report["run_ups"] == two.report["run_ups"]
    assert one.report["collisions"]["robots"]["left"]["strokes_in_collision"] > 0  # the repairs had work
    for entry in one.report["collisions"]["robots"].values():  # a dropped run had a spray path to lose
        assert (entry["runs_dropped"] > 0) == (entry["runs_dropped_mm"] > 0)
        assert (entry["touch_ups_dropped"] > 0) == (entry["touch_ups_dropped_mm"] > 0)
    assert one.report["film"]["whole"]["share_in_spec"] == two.report["film"]["whole"]["share_in_spec"]


def _killed(x):
    if os.getpid() != PARENT[0]:
        os.kill(os.getpid(), 9)  # a child killed, as by the kernel's out-of-memory killer
    return x + 1


PARENT = [os.getpid()]


@pytest.mark.skipif(not FORK, reason="the robots run side by side only where processes fork")
def test_a_killed_robot_process_has_its_work_done_again_in_the_planner(caplog):
    caplog.set_level(logging.WARNING, logger="sprayplan.cells.each")  # (a CLI test before may quieten the root)
    PARENT[0] = os.getpid()
    out = each_robot([(_killed, (1,)), (_killed, (2,))], workers=2)
    assert out == [2, 3]
    assert "ended abruptly" in caplog.text
