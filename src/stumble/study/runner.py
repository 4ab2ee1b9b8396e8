"""Running a study: one trip per scenario on local processes or a Dask cluster.

``run_study(scenarios, out)`` checks every scenario, runs what ``out`` does not hold yet
and writes ``out/results.parquet``. Each run is ``run_one(scenario)``, which never raises
an ``Exception``: a run that raises (bad conditions for that scenario) or diverges is a
row saying so, and a run longer than its wall-time limit (``run_timeout_s``, default
``RUN_TIMEOUT_S``) is stopped and becomes a ``timeout`` row. Scenarios are streamed: a
study of a million runs holds their keys (8 bytes each), never all its scenarios or rows.
Executors:

- ``workers == 1``: in this process, one run after the other;
- ``workers > 1`` (default: all cores): a ``ProcessPoolExecutor``; a worker process that
  dies (a crash in C, out of memory) is replaced, and the runs it might have been
  running are retried one at a time, so only the run that kills a worker is an error row;
- ``scheduler="tcp://host:8786"``: a Dask distributed cluster (``pip install
  "stumble[cluster]"``; the workers need stumble installed too). Same rows.

Rows are deterministic: the same scenario gives the same numbers on any executor,
except the wall times (``wall_time_s``, ``run_wall_time_s``).
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stumble import __version__
from stumble.control.fsm_params import FSMParams, ParamsFile
from stumble.errors import StumbleError, TripNotSet
from stumble.jsonio import dumps, strict
from stumble.study.grid import Grid, check_scenario, run_key, scenario_fields
from stumble.study.store import (
    Store,
    Warn,
    contains,
    iter_parquet_rows,
    read_parquet_rows,
    require_pyarrow,
    write_results,
)
from stumble.trip import Scenario

CONNECT_TIMEOUT_S = 20.0  # waiting for a Dask scheduler to answer
# Per-run wall-time limit (s): a trip takes 1-10 s here (20 s of physics at the smallest
# time step about 2 min), so a run ten minutes long is stuck, not slow.
RUN_TIMEOUT_S = 600.0
# A run past its limit is stopped at its next Python instruction; a worker process whose
# run is stuck inside C even this long after that exits, and the run becomes a timeout row.
HARD_KILL_GRACE_S = 30.0
# Scenario columns whose names clash with a summary field of another meaning.
RENAMED = {"strategy": "strategy_mode"}  # the mode asked for; ``strategy`` is the one taken


def default_workers() -> int:
    """All the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def _plain(v):
    """A JSON- and Parquet-friendly value: NumPy scalars to Python, lists to JSON text."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (list, tuple)):
        return dumps(v, default=_json_default)
    return strict(v)


def _json_default(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)


def flatten(d: dict, prefix: str = "") -> dict:
    """Nested dicts to ``parent.child`` columns; lists to JSON strings."""
    out = {}
    for k, v in d.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, f"{name}."))
        else:
            out[name] = _plain(v)
    return out


def scenario_columns(sc: Scenario) -> dict:
    """The scenario's fields as row columns (the obstacle height only for obstacle trips)."""
    d = flatten(scenario_fields(sc))
    if sc.mechanism != "obstacle":
        d["obstacle_height_m"] = None
    return {RENAMED.get(k, k): v for k, v in d.items()}


def one_line(e: BaseException) -> str:
    """``Type: message`` on one line, at most 500 characters."""
    text = " ".join(f"{type(e).__name__}: {e}".split())
    return text if len(text) <= 500 else text[:497] + "..."


def make_row(sc: Scenario, summary: dict | None, error: str | None,
             run_wall_time_s: float) -> dict:
    """One row: key, every scenario parameter, every summary field (flattened), error."""
    row = {"key": run_key(sc), **scenario_columns(sc)}
    for k, v in flatten(summary or {}).items():
        row.setdefault(k, v)  # a scenario field the summary repeats: the scenario's value
    row["timed_out"] = bool(row.get("timed_out", False))
    row["error"] = error
    row["run_wall_time_s"] = round(run_wall_time_s, 4)
    row["stumble_version"] = __version__
    return row


NO_OUTCOME = {"recovered": False, "fell": False, "diverged": False}


def error_row(sc: Scenario, error: str, run_wall_time_s: float = 0.0) -> dict:
    """The row of a run that produced no summary."""
    return make_row(sc, NO_OUTCOME, error, run_wall_time_s)


def timeout_row(sc: Scenario, timeout_s: float, run_wall_time_s: float) -> dict:
    """The row of a run stopped at its wall-time limit."""
    return make_row(sc, {**NO_OUTCOME, "timed_out": True},
                    f"RunTimeout: the run took more than {timeout_s:g} s (--run-timeout) "
                    "and was stopped", run_wall_time_s)


class RunTimeout(BaseException):
    """Raised inside a run that passed its wall-time limit."""


_IN_POOL_WORKER = False  # set in local worker processes: a stuck run may end the process


def _async_raise(tid: int, exc) -> None:
    """Raise ``exc`` in thread ``tid`` at its next Python instruction (None: cancel)."""
    ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(tid),
                                               None if exc is None else ctypes.py_object(exc))


class _Deadlines:
    """One watchdog thread per process for the runs' wall-time limits.

    Past its deadline a run's thread gets RunTimeout; in a pool worker the process ends
    if the run is still armed ``HARD_KILL_GRACE_S`` later (a run stuck inside C)."""

    def __init__(self):
        self.pid = None
        self.thread = None
        self.cond = threading.Condition()
        self.armed: dict[int, list] = {}  # token → [thread id, deadline, fired, kill at]
        self.count = 0

    def _loop(self, cond: threading.Condition, armed: dict) -> None:
        with cond:
            while True:
                now = time.monotonic()
                soonest = None
                for e in armed.values():
                    if not e[2] and now >= e[1]:
                        e[2] = True
                        _async_raise(e[0], RunTimeout)
                    if e[2] and e[3] is not None and now >= e[3]:
                        os._exit(124)  # the parent sees a dead worker, records a timeout
                    t = e[3] if e[2] else e[1]
                    if t is not None:
                        soonest = t if soonest is None else min(soonest, t)
                cond.wait(None if soonest is None else max(0.0, soonest - now))

    def arm(self, seconds: float) -> int:
        """Start the clock of the calling thread's run; returns its token."""
        if self.pid != os.getpid() or self.thread is None:  # first use, or a forked child
            self.pid, self.cond, self.armed = os.getpid(), threading.Condition(), {}
            self.thread = threading.Thread(target=self._loop, args=(self.cond, self.armed),
                                           daemon=True, name="stumble-run-timeout")
            self.thread.start()
        now = time.monotonic()
        with self.cond:
            self.count += 1
            kill = now + seconds + HARD_KILL_GRACE_S if _IN_POOL_WORKER else None
            self.armed[self.count] = [threading.get_ident(), now + seconds, False, kill]
            self.cond.notify()
            return self.count

    def disarm(self, token: int) -> None:
        """Stop the clock; a RunTimeout fired but not yet delivered is cancelled."""
        with self.cond:
            e = self.armed.pop(token, None)
            if e is not None and e[2]:
                _async_raise(e[0], None)


_DEADLINES = _Deadlines()


class _Watchdog:
    """The wall-time limit of one run in the calling thread; ``stop`` may be called twice."""

    def __init__(self, seconds: float | None):
        self.token = _DEADLINES.arm(seconds) if seconds else None

    def stop(self) -> None:
        if self.token is not None:
            _DEADLINES.disarm(self.token)  # a RunTimeout delivered in here: called again
            self.token = None


def run_one(sc: Scenario, timeout_s: float | None = None,
            params: FSMParams | None = None) -> tuple[dict, str | None]:
    """Simulate one trip; return (row, traceback text or None). Never raises an Exception.

    ``timeout_s``: wall-time limit (None or 0: none); past it the run is stopped and its
    row is a timeout row. ``params``: the state machines' parameters (None: the
    defaults ``simulate_trip`` chooses)."""
    from stumble import pipeline

    t0 = time.perf_counter()
    tb = None
    guard = _Watchdog(timeout_s)
    try:
        try:
            summary = pipeline.simulate_trip(sc, params=params).summary
            error = None
        except TripNotSet as e:  # an outcome, not an error: the foot passes over the box
            summary = {**NO_OUTCOME, "not_set": True, "not_set_reason": str(e)}
            error = None
        except Exception as e:
            summary = dict(NO_OUTCOME)
            error = one_line(e)
            tb = traceback.format_exc()
        finally:
            guard.stop()
    except RunTimeout:
        guard.stop()
        return timeout_row(sc, timeout_s, time.perf_counter() - t0), None
    return make_row(sc, summary, error, time.perf_counter() - t0), tb


# ---------------------------------------------------------------- executors

Result = tuple[dict, str | None]


def _serial(todo: Iterable[Scenario], timeout_s: float | None,
            params: FSMParams | None = None) -> Iterator[Result]:
    for sc in todo:
        yield run_one(sc, timeout_s, params)


def _worker_init(parent_pid: int, close_fds: tuple[int, ...] = ()) -> None:
    """In each worker: Ctrl-C is the parent's business; exit if the parent is gone.

    ``close_fds``: descriptors inherited through fork that only the parent may hold (the
    study directory's lock)."""
    global _IN_POOL_WORKER
    _IN_POOL_WORKER = True
    for fd in close_fds:
        with contextlib.suppress(OSError):
            os.close(fd)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)

    def watch() -> None:
        while True:
            time.sleep(1.0)
            if os.getppid() != parent_pid:  # the study was killed: do not linger
                os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


def _pool(workers: int, close_fds: tuple[int, ...] = ()) -> ProcessPoolExecutor:
    # fork: workers start at once and share what the parent imported (MuJoCo, the pipeline)
    fork = sys.platform.startswith("linux")
    ctx = multiprocessing.get_context("fork") if fork else None
    return ProcessPoolExecutor(workers, mp_context=ctx, initializer=_worker_init,
                               initargs=(os.getpid(), close_fds if fork else ()))


class _Shield:
    """While on, SIGINT and SIGTERM are ignored (main thread only): once a study is
    stopping, a second Ctrl-C must not cut its clean-up short."""

    def __init__(self):
        self.old: dict | None = None

    def on(self) -> None:
        if self.old is None and threading.current_thread() is threading.main_thread():
            sigs = (signal.SIGINT, signal.SIGTERM)
            self.old = {sig: signal.signal(sig, signal.SIG_IGN) for sig in sigs}

    def off(self) -> None:
        if self.old is not None:
            for sig, handler in self.old.items():
                signal.signal(sig, handler)
            self.old = None


def _stop_pool(ex: ProcessPoolExecutor) -> None:
    """Cancel what is queued and end the workers now (their runs are not finished)."""
    shield = _Shield()
    shield.on()
    try:
        _terminate(ex)
    finally:
        shield.off()


def _terminate(ex: ProcessPoolExecutor) -> None:
    ex.shutdown(wait=False, cancel_futures=True)
    if hasattr(ex, "terminate_workers"):  # Python >= 3.14
        ex.terminate_workers()
        return
    procs = list((getattr(ex, "_processes", None) or {}).values())
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout=2.0)


def _isolated(sc: Scenario, close_fds: tuple[int, ...], timeout_s: float | None,
              params: FSMParams | None = None) -> Result:
    """Run one scenario alone in a fresh worker; a dead worker makes it an error row (a
    timeout row when it died past the time limit)."""
    ex = _pool(1, close_fds)
    t0 = time.perf_counter()
    try:
        return ex.submit(run_one, sc, timeout_s, params).result()
    except BrokenProcessPool:
        took = time.perf_counter() - t0
        if timeout_s and took >= timeout_s:
            return timeout_row(sc, timeout_s, took), None
        return error_row(sc, "WorkerDied: the worker process died running this trip "
                         "(a crash inside the simulation, or out of memory)", took), None
    finally:
        _stop_pool(ex)


def _local(todo: Iterator[Scenario], workers: int, close_fds: tuple[int, ...] = (),
           timeout_s: float | None = None, params: FSMParams | None = None
           ) -> Iterator[Result]:
    """A process pool, at most 2 × workers runs queued; a dead worker breaks the pool, the
    runs it may have held are retried one at a time, and a new pool goes on."""
    todo = iter(todo)
    held: deque[Scenario] = deque()  # taken from ``todo`` but not yet submitted

    def take() -> Scenario | None:
        return held.popleft() if held else next(todo, None)

    while True:
        ex = _pool(workers, close_fds)
        running: dict = {}
        suspects: list[Scenario] = []
        broken = False
        try:
            while not broken:
                while len(running) < 2 * workers:
                    sc = take()
                    if sc is None:
                        break
                    try:
                        running[ex.submit(run_one, sc, timeout_s, params)] = sc
                    except BrokenProcessPool:  # a worker died since the last wait
                        held.appendleft(sc)
                        broken = True
                        break
                if not running:
                    break
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in done:
                    sc = running.pop(fut)
                    try:
                        yield fut.result()
                    except BrokenProcessPool:
                        suspects.append(sc)
                        broken = True
            suspects.extend(running.values())  # they were running when the pool broke
            running.clear()
        finally:
            if running or broken or held:
                _stop_pool(ex)
            else:
                ex.shutdown(wait=True)
        for sc in suspects:  # which of them killed the worker: each alone
            yield _isolated(sc, close_fds, timeout_s, params)
        if not broken:
            return


def check_scheduler_address(address: str) -> None:
    """StumbleError unless ``address`` is a Dask scheduler's, [protocol://]host:port (or
    an in-process ``inproc://`` one), read by distributed's own parsers: a malformed one
    given to ``Client`` leaves a half-made client that stalls the exit for 40 s."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    text = address.strip()
    try:
        scheme, loc = parse_address(text if "://" in text else f"tcp://{text}")
        get_backend(scheme)
        if scheme != "inproc":
            parse_host_port(loc)
    except (ValueError, TypeError) as e:
        raise StumbleError(f"--scheduler {address!r} is not a Dask scheduler address "
                           f"[protocol://]host:port, e.g. tcp://10.0.0.5:8786 ({e})") from None


def _dask_client(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise StumbleError("--scheduler needs Dask: pip install \"stumble[cluster]\"") from None
    check_scheduler_address(address)
    try:
        return Client(address, timeout=f"{CONNECT_TIMEOUT_S}s", set_as_default=False)
    except Exception as e:
        raise StumbleError(f"cannot reach the Dask scheduler at {address} ({one_line(e)})"
                           ) from None


def _dask(todo: Iterator[Scenario], client, timeout_s: float | None = None,
          params: ParamsFile | None = None) -> Iterator[Result]:
    from distributed import as_completed

    def window() -> int:
        try:
            threads = sum(client.nthreads().values())
        except Exception:
            threads = 1
        return max(64, 4 * threads)

    todo = iter(todo)
    running: dict = {}
    ac = as_completed(loop=client.loop)  # the client is not the default one
    size, sized_at = window(), time.monotonic()

    def refill() -> None:
        nonlocal size, sized_at
        if time.monotonic() - sized_at > 10.0:  # the cluster may have grown
            size, sized_at = window(), time.monotonic()
        while len(running) < size:
            sc = next(todo, None)
            if sc is None:
                return
            # the parameters' SHA in the task key: studies of other parameters on the
            # same cluster never share a task
            suffix = "" if params is None else f"-{params.sha256[:16]}"
            fut = client.submit(run_one, sc, timeout_s,
                                None if params is None else params.params,
                                key=f"stumble-trip-{run_key(sc)}{suffix}", pure=False)
            running[fut.key] = (fut, sc)
            ac.add(fut)

    try:
        refill()
        for fut in ac:
            _, sc = running.pop(fut.key)
            if fut.status == "finished":
                yield fut.result()
            elif fut.status == "error":  # e.g. KilledWorker: it killed workers repeatedly
                yield error_row(sc, one_line(fut.exception())), None
            # cancelled (the scheduler lost it): not finished; the next session runs it
            fut.release()
            refill()
    finally:
        if running:
            with contextlib.suppress(Exception):
                client.cancel([f for f, _ in running.values()])


# ---------------------------------------------------------------- progress


def _clock(s: float) -> str:
    s = round(s)
    if s >= 3600:
        return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
    return f"{s // 60}:{s % 60:02d}"


class Progress:
    """A one-line progress bar with rate and ETA on a terminal; a line per ~10 % otherwise."""

    def __init__(self, total: int, stream=None, enabled: bool = True):
        self.total = total
        self.done = 0
        self.errors = 0
        self.stream = stream or sys.stderr
        self.enabled = enabled and total > 0
        self.tty = self.enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.monotonic()
        self._last = 0.0
        self._last_pct = -1

    def update(self, row: dict) -> None:
        self.done += 1
        self.errors += bool(row.get("error"))
        if not self.enabled:
            return
        now = time.monotonic()
        pct = int(100 * self.done / self.total)
        if self.tty and (now - self._last > 0.2 or self.done == self.total):
            self.stream.write("\r" + self.line() + "\033[K")
            self.stream.flush()
            self._last = now
        elif not self.tty and (pct // 10 > self._last_pct // 10 or now - self._last > 60):
            self.stream.write(self.line() + "\n")
            self.stream.flush()
            self._last, self._last_pct = now, pct

    def line(self) -> str:
        elapsed = time.monotonic() - self.t0
        frac = self.done / self.total if self.total else 1.0
        bar = "#" * int(24 * frac) + "." * (24 - int(24 * frac))
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = _clock((self.total - self.done) / rate) if rate > 0 else "--:--"
        err = f", {self.errors} errors" if self.errors else ""
        return (f"[{bar}] {self.done}/{self.total} {100 * frac:3.0f}%  {rate:.2f} trips/s  "
                f"elapsed {_clock(elapsed)}  ETA {eta}{err}")

    def close(self) -> None:
        if self.tty and self.done:
            self.stream.write("\n")
            self.stream.flush()


# ---------------------------------------------------------------- the study


class StudyInterrupted(StumbleError):
    """The study was stopped (Ctrl-C, SIGTERM); every finished run is stored."""


@dataclass
class StudyResult:
    """What a study produced (its rows are in ``out/results.parquet``, in grid order)."""

    runs: int  # runs of the study (rows of results.parquet)
    ran: int  # run in this session
    before: int  # finished before this session
    out: Path
    other_rows: int  # runs in the directory from scenarios not in this study

    @property
    def results(self) -> Path:
        """``out/results.parquet``."""
        return self.out / "results.parquet"

    @property
    def rows(self) -> list[dict]:
        """Every row, in grid order (read from results.parquet; for small studies)."""
        return read_parquet_rows(self.results)


class _Scenarios:
    """The study's scenarios, re-iterable: a Grid is streamed again each time, anything
    else is held as a list. ``scan`` checks each and returns their keys."""

    def __init__(self, scenarios: Grid | Iterable[Scenario]):
        self.grid = scenarios if isinstance(scenarios, Grid) else None
        self.items = None if self.grid is not None else list(scenarios)
        if self.grid is not None:
            self.grid.checked_count()

    def __iter__(self) -> Iterator[Scenario]:
        return self.grid.iter_scenarios() if self.grid is not None else iter(self.items)

    def scan(self) -> np.ndarray:
        """Every scenario checked (InputError naming the first bad one); keys as uint64.
        Also notes which controllers run (``controllers``; ``has_fsm``: a state machine)."""
        keys = []
        self.controllers: set[str] = set()
        for sc in self:
            check_scenario(sc)
            keys.append(int(run_key(sc), 16))
            self.controllers.add(sc.controller)
        self.has_fsm = "fsm" in self.controllers
        return np.array(keys, dtype=np.uint64)


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM (a batch system stopping the job) ends the study as Ctrl-C does."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def run_study(scenarios: Grid | Iterable[Scenario], out: Path, workers: int | None = None,
              scheduler: str | None = None, retry_errors: bool = False,
              progress: bool = True, on_start: Callable[[str], None] | None = None,
              metadata: dict | None = None, run_timeout_s: float | None = RUN_TIMEOUT_S,
              warn: Warn | None = None, params: ParamsFile | None = None) -> StudyResult:
    """Check every scenario, run those ``out`` does not hold yet, write results.parquet.

    ``scenarios``: a Grid (streamed) or scenarios. ``workers``: local processes (default
    all cores; 1 runs in this process). ``scheduler``: a Dask scheduler address instead.
    ``retry_errors``: run again the scenarios whose stored row has an error.
    ``run_timeout_s``: per-run wall-time limit (None or 0: none). ``metadata`` goes into
    ``out/study.json``; ``warn`` receives one-line warnings (bad journal rows).
    ``params``: the state machines' parameters of every run (``fsm_params.read_params``),
    recorded in study.json (``params``: path, SHA-256, values); a directory holds the
    runs of one parameter set: resuming it with other parameters (or none, or with
    parameters when it was made without) is a one-line StumbleError.
    Raises StudyInterrupted (all finished runs stored) on Ctrl-C or SIGTERM.
    """
    source = _Scenarios(scenarios)
    keys = source.scan()  # before the directory is touched
    _, first = np.unique(keys, return_index=True)
    unique = np.zeros(len(keys), bool)
    unique[first] = True
    require_pyarrow()
    if scheduler is not None and workers is not None:
        raise StumbleError("--workers is for local processes; a Dask cluster has its own")
    workers = workers or default_workers()
    if workers < 1:
        raise StumbleError(f"--workers {workers}: at least 1")
    if run_timeout_s is not None and not (math.isfinite(run_timeout_s) and run_timeout_s >= 0):
        raise StumbleError(f"--run-timeout {run_timeout_s}: a number of seconds >= 0")
    client = _dask_client(scheduler) if scheduler is not None else None
    out = Path(out)
    shield = _Shield()
    n_runs = int(unique.sum())
    fsm = None if params is None else params.params
    try:
        with Store(out, warn) as store:
            _check_same_params(out, params, bool(len(store.done)))
            metadata = {**(metadata or {}), **_defaults_metadata(out, store, source, params)}
            _write_study_json(out, n_runs, metadata)
            stored_any = contains(store.done, keys)
            finished = contains(store.done_ok, keys) if retry_errors else stored_any
            todo_mask = unique & ~finished
            n_todo = int(todo_mask.sum())
            before = n_runs - n_todo
            stored_before = int((unique & stored_any).sum())
            where = (f"the Dask cluster at {scheduler}" if client is not None else
                     "this process" if min(workers, n_todo) == 1 else
                     f"{min(workers, n_todo)} local processes")
            msg = (f"study: {n_runs} runs, {before} done before, {n_todo} to run"
                   + (f" on {where}" if n_todo else "") + f"; results in {out}")
            (on_start or (lambda m: print(m, file=sys.stderr)))(msg)
            bar = Progress(n_todo, enabled=progress)
            todo = (sc for sc, go in zip(source, todo_mask, strict=True) if go)
            if client is not None:
                runs = _dask(todo, client, run_timeout_s, params)
            elif workers == 1 or n_todo <= 1:
                runs = _serial(todo, run_timeout_s, fsm)
            else:
                import stumble.pipeline  # noqa: F401  (imported once, shared by the forks)

                runs = _local(todo, min(workers, n_todo), store.inherited_fds(), run_timeout_s,
                              fsm)
            retried = ({int(k) for k in keys[todo_mask & stored_any]} if retry_errors
                       else set())
            ran = new = 0
            try:
                with _sigterm_as_interrupt(), contextlib.closing(runs):
                    for row, tb in runs:
                        if params is not None:  # the parameter file's, in every row
                            row["params_sha256"] = params.sha256
                        store.add(row, tb)
                        ran += 1
                        new += int(row["key"], 16) not in retried
                        bar.update(row)
            except KeyboardInterrupt:
                shield.on()  # finish storing, whatever else arrives
                bar.close()
                raise StudyInterrupted(
                    f"interrupted: {stored_before + new} of {n_runs} runs are stored in {out}; "
                    "run the same command again to do the rest") from None
            bar.close()
    finally:
        if client is not None:
            with contextlib.suppress(Exception):
                client.close()
        shield.off()
    written, other = write_results(out, keys[unique])
    return StudyResult(written, ran, before, out, other)


def _stored_params_sha(out: Path) -> tuple[bool, str | None]:
    """(whether out/study.json exists, the SHA-256 of the parameter file it records or
    None); an unreadable study.json records none."""
    path = out / "study.json"
    if not path.exists():
        return False, None
    try:
        sha = json.loads(path.read_text()).get("params", {}).get("sha256")
    except (OSError, ValueError, AttributeError):
        return True, None
    return True, sha if isinstance(sha, str) else None


def _check_same_params(out: Path, params: ParamsFile | None, has_runs: bool) -> None:
    """StumbleError when ``out`` was made with other state-machine parameters than
    ``params`` (run keys name scenarios, not parameters: the runs must not mix)."""
    exists, before = _stored_params_sha(out)
    now = None if params is None else params.sha256
    if before == now or not (exists or has_runs):
        return
    made = (f"with --params of SHA-256 {before[:16]}" if before is not None
            else "without --params")
    asked = (f"--params {params.name} (SHA-256 {now[:16]})" if params is not None
             else "no --params")
    raise StumbleError(f"{out} holds a study made {made}; it cannot be resumed with "
                       f"{asked}: give another --out")


def default_params_record() -> dict:
    """The state-machine parameter sets a trip runs with when none is given, by strength
    model and recovery rule (``fsm_params.DEFAULT_SETS``): name and SHA-256 of each."""
    from stumble.control.fsm_params import DEFAULT_SETS, read_params

    return {f"{strength} {rule}": {"name": name, "sha256": read_params(name).sha256}
            for (strength, rule), name in DEFAULT_SETS.items()}


# the shipped sets a reflex trip runs when none is given: the network (``identify.
# DEFAULT_NETWORK``) and Geyer & Herr's parameters (``gh2010.SHIPPED``)
REFLEX_DEFAULTS = ("reflex", "gh2010")


def reflex_defaults_record(controllers) -> dict:
    """The shipped network and GH2010 set the reflex ``controllers`` run by default:
    name and SHA-256 of each file (the defaults changed on 2026-12-04)."""
    import hashlib
    from importlib import resources

    def shipped(c: str) -> str:
        if c == "reflex":
            from stumble.control.reflex.identify import DEFAULT_NETWORK, NETWORK_NAMES

            return NETWORK_NAMES[DEFAULT_NETWORK]
        from stumble.control.reflex.gh2010 import SHIPPED

        return SHIPPED["gh2010"]

    data = resources.files("stumble.control.reflex") / "data"
    out = {}
    for c in controllers:
        try:
            name = shipped(c)
        except ImportError:  # the controller is not available: its runs are errors
            out[c] = {"name": None, "sha256": None}
            continue
        out[c] = {"name": name,
                  "sha256": hashlib.sha256((data / name).read_bytes()).hexdigest()}
    return out


def _study_record(out: Path) -> dict | None:
    """``out``'s study.json as read (None: there is none); StumbleError when it cannot
    be read or is not a JSON object (the runs beside it cannot be resumed without it)."""
    path = out / "study.json"
    if not path.exists():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise StumbleError(f"{path} cannot be read ({one_line(e)}); the runs in {out} "
                           "cannot be resumed without it: give another --out") from None
    if not isinstance(doc, dict):
        raise StumbleError(f"{path} is not a study record (a JSON object); the runs in "
                           f"{out} cannot be resumed without it: give another --out")
    return doc


def _defaults_metadata(out: Path, store, source, params: ParamsFile | None) -> dict:
    """study.json's records of the default sets (``fsm_default_params``: the state
    machines' without ``--params``; ``reflex_default_params``: the network and GH2010 set,
    by controller) for this grid's controllers and for those with runs in ``out``;
    StumbleError when ``out`` holds runs of a controller made with other default sets
    (or none recorded): run keys name scenarios, not parameters, so the runs must not
    mix. A controller without runs there is never a reason to refuse the directory."""
    prev = _study_record(out) if len(store.done) else None
    stored = store.controllers  # None: some part does not say: assume every controller
    checked = prev is not None  # runs, and a record of how they were made

    def has_runs(controller: str) -> bool:
        return checked and (stored is None or controller in stored)

    def check(before, now, controller: str, what: str) -> None:
        if has_runs(controller) and before != now:
            raise StumbleError(f"{out} holds {controller} runs made with other default "
                               f"{what} parameters (another version's); it cannot be "
                               "resumed: give another --out")

    prev = prev or {}
    meta = {}
    fsm = prev.get("fsm_default_params")
    if params is not None:
        meta["params"] = params.record()
    elif source.has_fsm:  # the sets this version's state machines run by default
        now_fsm = default_params_record()
        check(fsm, now_fsm, "fsm", "state-machine")
        fsm = now_fsm
    if fsm is not None and params is None and (source.has_fsm or has_runs("fsm")):
        meta["fsm_default_params"] = fsm
    before = prev.get("reflex_default_params")
    reflex = dict(before) if isinstance(before, dict) else {}
    grid = sorted(source.controllers & set(REFLEX_DEFAULTS))
    now = reflex_defaults_record(grid) if grid else {}
    for c in grid:  # the network and GH2010 set a reflex trip runs by default
        check(reflex.get(c), now[c], c, "reflex")
    reflex.update(now)
    reflex = {c: v for c, v in reflex.items() if c in now or has_runs(c)}
    if reflex:
        meta["reflex_default_params"] = reflex
    return meta


def _write_study_json(out: Path, runs: int, metadata: dict | None) -> None:
    d = {"stumble_version": __version__, "runs": runs, **(metadata or {})}
    tmp = out / ".study.json.tmp"
    tmp.write_text(dumps(d, indent=1) + "\n")
    os.replace(tmp, out / "study.json")


# ---------------------------------------------------------------- the summary table


def outcome(row: dict) -> str:
    """timeout, not set (the trip could not be set at that instant: the tripped toe over
    the obstacle), error, diverged, recovered, fell or neither (no recovery within the
    time)."""
    if row.get("timed_out"):
        return "timeout"
    if row.get("not_set"):
        return "not set"
    if row.get("error") and not row.get("diverged"):
        return "error"
    if row.get("diverged"):
        return "diverged"
    if row.get("recovered"):
        return "recovered"
    if row.get("fell"):
        return "fell"
    return "neither"


OUTCOMES = ("recovered", "fell", "diverged", "neither", "not set", "timeout", "error")
SUMMARY_COLUMNS = ("controller", "strategy", "timed_out", "error", "diverged", "recovered",
                   "fell", "not_set")  # what summary_table and outcome read


def summary_table(rows: Iterable[dict]) -> str:
    """Runs and outcomes per strategy taken (and per controller when there are several).

    One pass over ``rows``: an iterator (``iter_results``) keeps memory flat."""
    counts: dict[tuple[str, str], dict[str, int]] = {}
    for r in rows:
        g = counts.setdefault((str(r.get("controller")), r.get("strategy") or "-"),
                              dict.fromkeys(OUTCOMES, 0))
        g[outcome(r)] += 1
    by_ctrl = len({c for c, _ in counts}) > 1
    groups: dict[str, dict[str, int]] = {}
    for (ctrl, strategy), g in counts.items():
        name = f"{ctrl} {strategy}" if by_ctrl else strategy
        tot = groups.setdefault(name, dict.fromkeys(OUTCOMES, 0))
        for k, v in g.items():
            tot[k] += v
    total = dict.fromkeys(OUTCOMES, 0)
    for g in groups.values():
        for k, v in g.items():
            total[k] += v
    head = ["strategy", "runs", *OUTCOMES]
    body = [[name, sum(g.values()), *g.values()] for name, g in sorted(groups.items())]
    body.append(["all", sum(total.values()), *total.values()])
    width = [max(len(str(x)) for x in col) for col in zip(head, *body, strict=True)]
    lines = ["  ".join(str(x).ljust(w) if i == 0 else str(x).rjust(w)
                       for i, (x, w) in enumerate(zip(line, width, strict=True)))
             for line in (head, *body)]
    lines.insert(1, "  ".join("-" * w for w in width))
    lines.insert(len(lines) - 1, lines[1])
    return "\n".join(lines)


def iter_results(out: Path, columns: Iterable[str] | None = None) -> Iterator[dict]:
    """The rows of ``out/results.parquet`` one at a time (``columns``: only these)."""
    return iter_parquet_rows(Path(out) / "results.parquet",
                             None if columns is None else list(columns))
