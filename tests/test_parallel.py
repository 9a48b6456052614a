"""Work shared with a helper process (``sprayplan.parallel``, issue 17): the same results as one process.

- ``shared_map`` gives ``[f(x) for x in items]`` in order, raises the first item's error, reports progress, and
  finishes the work in the job's process when the helper dies;
- the helper imports nothing of the caller's main module, and its log records reach the job's logging;
- on a real part, the kinematics stage and the touch-ups fitted to the stations give the same plan, bit for
  bit, with one process and with two.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from sprayplan import parallel
from sprayplan.parallel import shared_map

pytestmark = pytest.mark.skipif(parallel.process_count(2) < 2, reason="the helper needs POSIX pipes")


def _square(x):
    return x * x


def _pid(_):
    return os.getpid()


def _fails_on_three(x):
    if x == 3:
        raise ValueError(f"item {x} is bad")
    return x


def _logs(x):
    import time

    time.sleep(0.05)
    logging.getLogger("sprayplan.test_parallel").warning("item %d seen in process %d", x, os.getpid())
    return x


def _slow_pid(x):
    import time

    time.sleep(0.05)
    return x, os.getpid()


def _kills_helper(x):
    """Kills its own process when run in the helper (whose parent is the test's process)."""
    import time

    if os.getppid() == int(os.environ.get("SPRAYPLAN_TEST_PARENT", "-1")):
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.05)
    return x + 100


def _ready_helper():
    """A helper started and done with its imports (until then the job's process keeps every piece)."""
    parallel.start_helper(2)
    assert parallel._helper.ready.wait(60)


def test_shared_map_is_the_list_in_order_and_uses_the_helper():
    _ready_helper()
    items = list(range(40))
    assert shared_map(_square, items, processes=2) == [x * x for x in items]
    seen = shared_map(_slow_pid, range(12), processes=2)
    assert [x for x, _ in seen] == list(range(12))
    pids = {pid for _, pid in seen}
    assert os.getpid() in pids and len(pids) == 2  # both processes took items
    assert shared_map(_pid, range(5), processes=1) == [os.getpid()] * 5  # one process: all here
    assert shared_map(_square, [], processes=2) == []


def test_shared_map_raises_the_items_error_and_reports_progress():
    counts = []
    with pytest.raises(ValueError, match="item 3 is bad"):
        shared_map(_fails_on_three, range(8), processes=2)
    assert shared_map(_square, range(6), processes=2, done=counts.append) == [0, 1, 4, 9, 16, 25]
    assert counts == [1, 2, 3, 4, 5, 6]  # each count once, in turn


def test_the_helpers_log_records_reach_the_jobs_logging(caplog):
    parallel.stop_helper()
    _ready_helper()
    with caplog.at_level(logging.WARNING, logger="sprayplan"):
        shared_map(_logs, range(6), processes=2)
    texts = [r.getMessage() for r in caplog.records if r.name == "sprayplan.test_parallel"]
    assert len(texts) == 6
    assert any(f"in process {os.getpid()}" not in t for t in texts)  # some were logged in the helper


def _logs_info(x):
    logging.getLogger("sprayplan.test_parallel").info("item %d seen in process %d", x, os.getpid())
    return x


def test_the_helpers_records_below_the_jobs_level_are_dropped():
    """A record the helper logs below the level the job's loggers let through (the command line shows
    warnings; the helper logs at INFO) is not handed to the job's handlers: the command line's stderr stays one
    line."""
    parallel.stop_helper()
    _ready_helper()
    seen = []
    handler = logging.Handler()  # level NOTSET, as the command line's stderr handler
    handler.emit = seen.append
    logger = logging.getLogger("sprayplan.test_parallel")
    logger.addHandler(handler)
    old_level = logger.level
    logger.setLevel(logging.WARNING)
    try:
        shared_map(_logs_info, range(6), processes=2)
        shared_map(_logs, range(6), processes=2)
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old_level)
    assert all(r.levelno >= logging.WARNING for r in seen)
    assert len(seen) == 6  # the warnings, from both processes


def test_a_dead_helper_leaves_its_items_to_the_job(monkeypatch, caplog):
    parallel.stop_helper()
    monkeypatch.setenv("SPRAYPLAN_TEST_PARENT", str(os.getpid()))
    _ready_helper()
    with caplog.at_level(logging.WARNING, logger="sprayplan.parallel"):
        got = shared_map(_kills_helper, range(6), processes=2)
    assert got == [x + 100 for x in range(6)]
    assert any("helper process stopped" in r.getMessage() for r in caplog.records)
    assert shared_map(_square, range(4), processes=2) == [0, 1, 4, 9]  # a new helper is started


def test_a_script_without_a_main_guard_runs_once(tmp_path):
    """The helper does not import the caller's main module (multiprocessing's spawn would run it again)."""
    marks = tmp_path / "marks.txt"
    script = tmp_path / "script.py"
    script.write_text(
        textwrap.dedent(
            f"""
            from sprayplan.parallel import shared_map
            from tests.test_parallel import _square
            with open({str(marks)!r}, "a") as handle:
                handle.write("run\\n")
            print(shared_map(_square, range(5), processes=2))
            """
        )
    )
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[0, 1, 4, 9, 16]"
    assert marks.read_text() == "run\n"


def _same_plan(a, b):
    assert [st.index for st in a.stations] == [st.index for st in b.stations]
    for sa, sb in zip(a.stations, b.stations):
        np.testing.assert_array_equal(sa.platform_mm, sb.platform_mm)
        np.testing.assert_array_equal(sa.q9, sb.q9)
        np.testing.assert_array_equal(sa.reachable, sb.reachable)
        np.testing.assert_array_equal(sa.position_error_mm, sb.position_error_mm)
        assert list(sa.method) == list(sb.method)
        assert len(sa.strokes) == len(sb.strokes)
        for ka, kb in zip(sa.strokes, sb.strokes):
            np.testing.assert_array_equal(ka.tcp, kb.tcp)
            assert ka.kind == kb.kind


def test_the_plan_and_its_touch_ups_are_the_same_with_one_process_and_two(testdata):
    """The real curved panel: the kinematics stage (every station from home) and touch-ups aimed at its lip's
    underside, fitted to the stations and to new ones, with the solves in one process and shared with the
    helper: the same stations, strokes and joints bit for bit."""
    from sprayplan.coating.sampling import surface_samples
    from sprayplan.config import JobConfig
    from sprayplan.io.load import load_part
    from sprayplan.refine.extend import with_added_strokes
    from sprayplan.refine.touchup import touch_up_strokes
    from tests.helpers import planned

    _ready_helper()  # so that the helper takes pieces from the start
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    plans = {}
    for processes in (1, 2):
        job = JobConfig().replace(coating={"thickness_um": 50.0}, kinematics={"processes": processes})
        plans[processes] = planned(part, job)
    assert len(plans[1].stations) >= 2
    _same_plan(plans[1], plans[2])
    samples = surface_samples(part)
    lip = (samples.normals[:, 0] > 0.6) & (samples.normals[:, 2] < -0.2)
    film = np.where(lip, 20.0, 50.0)
    kw = dict(standoff_mm=113.0, step_mm=10.0, lead_mm=50.0, min_area_mm2=625.0)
    strokes = touch_up_strokes(samples, film, np.ones(len(film), bool), 50.0, 5.0, **kw)
    extended = {}
    for processes in (1, 2):
        job = JobConfig().replace(coating={"thickness_um": 50.0}, kinematics={"processes": processes})
        extended[processes] = with_added_strokes(plans[1], strokes, job, new_stations=2)
    assert len(extended[1].stations) > len(plans[1].stations)  # new stations were placed
    _same_plan(extended[1], extended[2])
    # the timing: the stretches timed in parts, some in the helper, give the same time stamps and figures
    from sprayplan.robots.gantry import Gantry
    from sprayplan.timing.stage import time_plan

    timed = {}
    for processes in (1, 2):
        job = JobConfig().replace(kinematics={"processes": processes})
        timed[processes] = time_plan(extended[1], job, Gantry())
    assert timed[1].cycle_time_s > 0 and timed[1].cycle_time_s == timed[2].cycle_time_s
    for field in ("t_s", "speed_mm_s"):
        for a, b in zip(getattr(timed[1], field), getattr(timed[2], field)):
            np.testing.assert_array_equal(a, b)
    assert timed[1].worst == timed[2].worst


def test_a_batch_job_runs_in_one_process_unless_told_otherwise():
    from sprayplan.parallel import process_count, single_process

    assert process_count(None) == (2 if (os.cpu_count() or 1) >= 2 else 1)
    with single_process():
        assert process_count(None) == 1
        assert process_count(2) == 2  # an explicit setting still counts
    assert process_count(1) == 1


def test_the_helper_runs_blas_with_the_jobs_thread_count(monkeypatch):
    """A library that changes the environment after the job's BLAS started (dask's LocalCluster sets
    OPENBLAS_NUM_THREADS=1 in its parent's environment) does not change the helper's BLAS: it runs with the
    thread count the job's libraries run with, so that its solves give the job's numbers."""
    import scipy.linalg  # noqa: F401  (both BLAS libraries loaded here)
    from threadpoolctl import threadpool_info

    parallel.stop_helper()
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    _ready_helper()
    here = sorted((lib["internal_api"], lib["num_threads"]) for lib in threadpool_info() if lib["user_api"] == "blas")
    try:
        seen = shared_map(_blas_threads, range(4), processes=2)
    finally:
        parallel.stop_helper()  # the next test's helper starts with the environment restored
    assert all(threads == here for threads in seen), (here, seen)


def _blas_threads(_):
    import numpy  # noqa: F401  (its BLAS loaded)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_info

    return sorted((lib["internal_api"], lib["num_threads"]) for lib in threadpool_info() if lib["user_api"] == "blas")


def test_work_that_fails_beside_a_started_map_waits_for_it_and_raises_its_own_error():
    """``finished_on_error``: a file that fails to write while the helper draws pictures waits for the map
    to end (no helper work left running) and the file's error is the one raised, not the map's."""
    from sprayplan.parallel import finished_on_error, shared_start

    _ready_helper()
    started = shared_start(_slow_pid, range(8), processes=2)
    with pytest.raises(OSError, match="disk full"):
        with finished_on_error(started.finish):
            raise OSError("disk full")
    assert all(started.finished) and not started.feeder.is_alive()
    failing = shared_start(_fails_on_three, range(6), processes=2)
    with pytest.raises(OSError, match="disk full"):  # the map's own error is dropped
        with finished_on_error(failing.finish):
            raise OSError("disk full")
    with finished_on_error(None):  # nothing started: nothing to wait for
        pass


def _pid_with(common, _):
    return common, os.getpid()


def test_a_small_map_does_not_wait_for_a_helper_still_starting():
    """Until the helper says its imports are done the job keeps every piece, and a map with common data does
    not wait for the helper to let go of data it was never sent."""
    parallel.stop_helper()
    parallel.start_helper(2)
    got = shared_map(_pid_with, range(3), processes=2, common="shared")
    assert got == [("shared", os.getpid())] * 3
    assert not parallel._helper.ready.is_set()  # done before the helper finished its imports
