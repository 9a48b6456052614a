"""Work shared between the job's process and one helper process, on the machine's second core.

The joint solves of a plan are per station and independent (each station's arm starts from home, the
touch-ups of a round are fitted to each station on their own), but they are Python and SLSQP, which hold
the interpreter's lock: threads would take turns, not share the cores. :func:`shared_map` runs such
items in the job's own process and in one helper process at the same time, each taking the next item when
it is done with one, and gives the results in the items' order. Every item is computed by the same code from
the same arguments wherever it runs, so the result is the same as computing them one after another (the
tests compare them bit for bit).

The helper is a fresh interpreter (``python -c``; a fork of a process whose thread pools or BLAS threads hold
a lock can hang, and multiprocessing's ``spawn`` would import the caller's main module again, running a
script without a ``__main__`` guard twice) and is kept for the rest of the process, so a job pays its start
once (about 1 s of the other core, taken while the job loads and slices the part when :func:`start_helper` is
called at the job's start). If the helper dies (killed, out of memory),
the items it did not finish are computed in the job's process; its errors are raised in the job's process.

How many processes: :func:`process_count` (a setting, else 2 where the machine has 2 or more cores). A batch
that runs several jobs side by side sets 1, so that the jobs do not oversubscribe the cores.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import os
import pickle
import subprocess
import sys
import threading
from multiprocessing.connection import Connection

log = logging.getLogger(__name__)

#: Modules imported in the helper as it starts, so that its first item does not pay for them.
HELPER_IMPORTS = (
    "sprayplan.robots.stage",
    "sprayplan.refine.extend",
    "sprayplan.timing.stage",
    "sprayplan.view.report",
)
#: Functions the helper runs when the job calls :func:`warm_helper` (after the refine stage, whose tuning
#: is the job's peak of memory: the timing's compiled kernels take about 80 MB), so that the pieces of the
#: later stages given to it do not pay for setting them up.
HELPER_WARM_UPS = (("sprayplan.timing.stage", "warm_up"), ("sprayplan.view.report", "warm_up"))

_lock = threading.Lock()
_MISSING = object()
#: In the helper: its BLAS thread limits (they hold while this object lives).
_helper_limits = None
_helper: Helper | None = None


class HelperLost(Exception):
    """The helper process is not there (it could not start, or it died)."""


_single = threading.local()


def process_count(setting: int | None = None) -> int:
    """Processes to share work between: ``setting`` when given, else 2 on a machine with 2 or more cores (the
    job's own and one helper) unless inside :func:`single_process`, else 1."""
    if os.name != "posix":  # the helper's pipes are passed as POSIX file descriptors
        return 1
    if setting is not None:
        return max(1, int(setting))
    if getattr(_single, "depth", 0):
        return 1
    return 2 if (os.cpu_count() or 1) >= 2 else 1


@contextlib.contextmanager
def single_process():
    """Within it, the default (a setting of None) is 1 process: a batch runs its jobs side by side, each in a
    process of its own, and a helper for each would oversubscribe the cores. An explicit setting still counts."""
    _single.depth = getattr(_single, "depth", 0) + 1
    try:
        yield
    finally:
        _single.depth -= 1


class Helper:
    """One helper process: ``python -c`` running :func:`_serve` on two pipes of its own (nothing of the
    caller's main module is imported in it, whatever started the job), importing sprayplan from where this
    process imports it. :meth:`call` sends a function and its argument and waits for the result; the log
    records the helper made on the way are handled here as if made here."""

    def __init__(self):
        import sprayplan

        to_child, from_parent = os.pipe()
        to_parent, from_child = os.pipe()
        root = os.path.dirname(os.path.dirname(os.path.abspath(sprayplan.__file__)))
        env = dict(os.environ)
        # the helper's BLAS runs with the thread count this process's runs with now, whatever the environment
        # says: the joint solves' last digits depend on it, and a library may have changed the environment
        # after this process's BLAS started (dask's LocalCluster sets OPENBLAS_NUM_THREADS=1 in its parent's
        # environment: a helper started after it solved differently)
        threads = _blas_threads()
        for name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
            env.pop(name, None)
        if threads is not None:
            env["SPRAYPLAN_HELPER_BLAS_THREADS"] = str(threads)
        env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
        code = f"from sprayplan.parallel import _serve; _serve({to_child}, {from_child})"
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-c", code], pass_fds=(to_child, from_child), env=env, stdin=subprocess.DEVNULL
            )
        finally:
            os.close(to_child)
            os.close(from_child)
        self.send = Connection(from_parent, readable=False)
        self.receive = Connection(to_parent, writable=False)
        self.busy = threading.Lock()
        # the helper says when its imports are done; until then the job keeps its pieces (a piece sent to a
        # helper still starting would wait for it, and a small job would end up waiting too)
        self.ready = threading.Event()
        threading.Thread(target=self._wait_ready, name="sprayplan-helper-ready", daemon=True).start()

    def _wait_ready(self) -> None:
        with self.busy:
            try:
                self.receive.recv_bytes()
            except (OSError, EOFError):
                pass  # a helper that died starting: the first call finds out
            self.ready.set()

    def call(self, function, item):
        """``function(item)`` in the helper. Raises what the function raised, or :class:`HelperLost`."""
        try:
            message = pickle.dumps((function, item), protocol=pickle.HIGHEST_PROTOCOL)
        except (pickle.PicklingError, TypeError, AttributeError) as exc:  # work that cannot be shipped stays here
            raise HelperLost(f"cannot send {getattr(function, '__name__', function)!r}: {exc}") from None
        with self.busy:
            try:
                self.send.send_bytes(message)
                ok, value, records = pickle.loads(self.receive.recv_bytes())
            except (OSError, EOFError) as exc:
                raise HelperLost(str(exc) or type(exc).__name__) from None
        for record in records:  # as if logged here: only those this process's loggers let through
            logger = logging.getLogger(record.name)
            if logger.isEnabledFor(record.levelno):
                logger.handle(record)
        if not ok:
            raise value
        return value

    def close(self) -> None:
        for end in (self.send, self.receive):
            try:
                end.close()
            except OSError:
                pass
        try:  # it ends when it reads the closed pipe; one still busy (a warm-up) holds no work of the job's
            self.process.wait(timeout=0.1)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


def _blas_threads() -> int | None:
    """The thread count this process's BLAS libraries run with now (``threadpoolctl``; the smallest when they
    differ), or None when it cannot be told."""
    try:
        from threadpoolctl import threadpool_info

        counts = [lib["num_threads"] for lib in threadpool_info() if lib.get("user_api") == "blas"]
    except Exception:  # no answer: the helper keeps what its environment gives it
        return None
    return min(counts) if counts else None


class _Records(logging.Handler):
    def __init__(self):
        super().__init__(logging.INFO)
        self.records: list[logging.LogRecord] = []

    def emit(self, record):
        record.msg, record.args = record.getMessage(), None  # the text, not arguments that may not pickle
        record.exc_info = record.exc_text = None
        self.records.append(record)


def _serve(read_fd: int, write_fd: int) -> None:
    """The helper's loop: read a pickled ``(function, item)``, send back ``(ok, result or error, log
    records)``, until the job's process closes its end."""
    import importlib
    import signal

    # Ctrl-C reaches the whole process group: the job's process handles it (one line) and ends the helper by
    # closing its pipes, so the helper itself ignores it rather than print a traceback
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    receive, send = Connection(read_fd, writable=False), Connection(write_fd, readable=False)
    records = _Records()
    root = logging.getLogger()
    root.addHandler(records)
    root.setLevel(logging.INFO)
    for name in HELPER_IMPORTS:
        importlib.import_module(name)
    global _helper_limits
    if os.environ.get("SPRAYPLAN_HELPER_BLAS_THREADS"):
        import scipy.linalg  # noqa: F401  (both BLAS libraries loaded, so that both are set)
        from threadpoolctl import threadpool_limits

        _helper_limits = threadpool_limits(limits=int(os.environ["SPRAYPLAN_HELPER_BLAS_THREADS"]), user_api="blas")
    send.send_bytes(b"ready")
    while True:
        try:
            function, item = pickle.loads(receive.recv_bytes())
        except (EOFError, OSError):
            return
        records.records = []
        try:
            answer = (True, function(item))
        except Exception as exc:  # the job's process raises it
            answer = (False, exc)
        try:
            data = pickle.dumps((*answer, records.records), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # an error or result that does not pickle: its text
            data = pickle.dumps((False, RuntimeError(f"{type(exc).__name__}: {exc}"), []))
        send.send_bytes(data)


def _get_helper() -> Helper:
    global _helper
    with _lock:
        if _helper is None:
            try:
                _helper = Helper()
            except (OSError, ValueError) as exc:
                raise HelperLost(str(exc)) from None
        return _helper


def start_helper(processes: int) -> None:
    """Start the helper process now (it imports sprayplan in the background) when ``processes`` > 1, so that
    it is ready when :func:`shared_map` first needs it."""
    if processes > 1:
        try:
            _get_helper()
        except HelperLost as exc:
            log.info("no helper process (%s): the work stays in this process", exc)


def _warm_up(_) -> None:
    import importlib

    for module, name in HELPER_WARM_UPS:
        try:
            getattr(importlib.import_module(module), name)()
        except Exception:  # only a head start: the real work sets it up if this did not
            log.debug("helper warm-up %s.%s failed", module, name, exc_info=True)


def warm_helper() -> None:
    """Have the helper (when running) set up the later stages' kernels and drawing now, in the background
    (:data:`HELPER_WARM_UPS`); work sent to it meanwhile waits its turn."""
    helper = _helper
    if helper is None:
        return

    def run():
        try:
            helper.call(_warm_up, None)
        except HelperLost:
            pass

    threading.Thread(target=run, name="sprayplan-helper-warm-up", daemon=True).start()


def stop_helper() -> None:
    """Stop the helper process (a new one is started when next needed)."""
    global _helper
    with _lock:
        helper, _helper = _helper, None
    if helper is not None:
        helper.close()


atexit.register(stop_helper)


_COMMON: dict = {}


def _keep_common(args) -> None:
    key, common = args
    _COMMON.clear()  # one map's at a time
    _COMMON[key] = common


def _drop_common(_) -> None:
    _COMMON.clear()


def _with_common(args):
    key, function, item = args
    return function(_COMMON[key], item)


@contextlib.contextmanager
def finished_on_error(finish):
    """Around work done while a :func:`shared_start` map (or what wraps one) runs: if the work raises,
    ``finish()`` is called first (its own errors dropped), so that the helper's pieces are waited for before
    the error goes on. ``finish`` may be None."""
    try:
        yield
    except BaseException:
        if finish is not None:
            with contextlib.suppress(Exception):
                finish()
        raise


def shared_map(function, items, processes: int = 1, done=None, common=_MISSING) -> list:
    """``[function(item) for item in items]`` (``function(common, item)`` when ``common`` is given: data all
    items need, sent to the helper once), computed by this process and (when ``processes`` > 1 and there
    are two items or more) one helper process at the same time, each taking the next item in order when it is
    free. ``function`` and the items must pickle (a module-level function and plain data).

    ``done(count)``, when given, is called in this process for each count of items finished, 1 to n in turn
    (after each item this process finishes, for it and the helper's finished since, and at the end). An exception raised by ``function`` is raised here
    (the first one in the items' order); a helper that dies leaves its items to this process."""
    return shared_start(function, items, processes, done, common).finish()


def shared_start(function, items, processes: int = 1, done=None, common=_MISSING) -> SharedMap:
    """:func:`shared_map` begun: the helper starts on the items now (when ``processes`` > 1 and there are two
    or more), while this process does other work; ``.finish()`` then takes part in the rest and returns the
    results. A map started must be finished."""
    shared = SharedMap(function, items, processes, done, common)
    shared.start()
    return shared


class SharedMap:
    """The state of one :func:`shared_start` map: the items, the results so far, the helper's feed."""

    def __init__(self, function, items, processes, done, common):
        self.items = list(items)
        self.function, self.common, self.done = function, common, done
        self.results: list = [None] * len(self.items)
        self.errors: dict[int, BaseException] = {}
        self.finished = [False] * len(self.items)
        self.next = 0
        self.reported = 0
        self.guard = threading.Lock()
        self.feeder = None
        self.sent_common = False
        self.shared = processes > 1 and len(self.items) >= 2

    def _call_here(self, item):
        if self.common is _MISSING:
            return self.function(item)
        return self.function(self.common, item)

    def _take(self):
        with self.guard:
            i = self.next
            if i >= len(self.items):
                return None
            self.next = i + 1
            return i

    def _put(self, i, value=None, error=None):
        with self.guard:
            if error is not None:
                self.errors[i] = error
            else:
                self.results[i] = value
            self.finished[i] = True

    def _compute_here(self, i):
        try:
            self._put(i, self._call_here(self.items[i]))
        except BaseException as exc:  # raised by finish()
            self._put(i, error=exc)

    def start(self) -> None:
        if self.shared:
            self.feeder = threading.Thread(target=self._feed, name="sprayplan-helper-feed", daemon=True)
            self.feeder.start()

    def _feed(self):
        try:
            self._feed_items()
        finally:
            if self.sent_common and _helper is not None:
                try:  # the helper lets go of the common data
                    _helper.call(_drop_common, None)
                except HelperLost:
                    pass

    def _feed_items(self):
        sent = self.common is _MISSING
        key = id(self)
        try:
            helper = _get_helper()
        except HelperLost:
            return  # no helper: this process does every piece
        while not helper.ready.wait(0.01):  # the pieces go to this process until the helper is ready
            with self.guard:
                if self.next >= len(self.items):
                    return
        while (i := self._take()) is not None:
            try:
                helper = _get_helper()
                if not sent:  # the common data, once
                    self.sent_common = True
                    helper.call(_keep_common, (key, self.common))
                    sent = True
                if self.common is _MISSING:
                    value = helper.call(self.function, self.items[i])
                else:
                    value = helper.call(_with_common, (key, self.function, self.items[i]))
            except HelperLost as exc:  # it could not start, or it died: its item is done here
                log.warning("the helper process stopped (%s): the rest of the work stays in this process", exc)
                stop_helper()
                self._compute_here(i)
                return
            except BaseException as exc:  # the item's own error, raised by finish()
                self._put(i, error=exc)
            else:
                self._put(i, value)

    def finish(self) -> list:
        """Take part in the items left, wait for the helper's, and return the results in order (or raise the
        first item's error)."""
        try:
            while (i := self._take()) is not None:
                self._compute_here(i)
                self._report()
        finally:  # a progress callback that stops the job (a batch's deadline) stops the helper's feed too
            with self.guard:
                self.next = len(self.items)
            if self.feeder is not None:
                self.feeder.join()
        if self.errors:
            raise self.errors[min(self.errors)]
        self._report()
        return self.results

    def _report(self) -> None:
        """``done(count)`` for each count reached since the last report, one at a time (1, 2, ..., n)."""
        if self.done is None:
            return
        now = sum(self.finished)
        while self.reported < now:
            self.reported += 1
            self.done(self.reported)
