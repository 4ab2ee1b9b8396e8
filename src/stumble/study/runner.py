"""Running a study: one trip per scenario on local processes or a Dask cluster.

``run_study(scenarios, out)`` runs what ``out`` does not hold yet and returns every row
of the study. Each run is ``run_one(scenario)``, which never raises an ``Exception``: a
run that raises (bad conditions for that scenario, a controller that is not there) or
diverges is a row saying so. Executors:

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
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stumble import __version__
from stumble.errors import SimulationDiverged, StumbleError
from stumble.jsonio import dumps
from stumble.study.grid import run_key, scenario_fields
from stumble.study.store import Store, require_pyarrow, write_parquet
from stumble.trip import Scenario

CONNECT_TIMEOUT_S = 20.0  # waiting for a Dask scheduler to answer
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
    return v


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
    row["error"] = error
    row["run_wall_time_s"] = round(run_wall_time_s, 4)
    row["stumble_version"] = __version__
    return row


def error_row(sc: Scenario, error: str) -> dict:
    """The row of a run that produced no summary."""
    return make_row(sc, {"recovered": False, "fell": False, "diverged": False}, error, 0.0)


def run_one(sc: Scenario) -> tuple[dict, str | None]:
    """Simulate one trip; return (row, traceback text or None). Never raises an Exception."""
    from stumble import pipeline

    t0 = time.perf_counter()
    tb = None
    try:
        summary = pipeline.simulate_trip(sc).summary
        error = None
    except SimulationDiverged as e:
        summary = {"recovered": False, "fell": False, "diverged": True}
        error = one_line(e)
    except Exception as e:
        summary = {"recovered": False, "fell": False, "diverged": False}
        error = one_line(e)
        tb = traceback.format_exc()
    return make_row(sc, summary, error, time.perf_counter() - t0), tb


# ---------------------------------------------------------------- executors

Result = tuple[dict, str | None]


def _serial(todo: list[Scenario]) -> Iterator[Result]:
    for sc in todo:
        yield run_one(sc)


def _worker_init(parent_pid: int, close_fds: tuple[int, ...] = ()) -> None:
    """In each worker: Ctrl-C is the parent's business; exit if the parent is gone.

    ``close_fds``: descriptors inherited through fork that only the parent may hold (the
    study directory's lock)."""
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


def _isolated(sc: Scenario, close_fds: tuple[int, ...]) -> Result:
    """Run one scenario alone in a fresh worker; a dead worker makes it an error row."""
    ex = _pool(1, close_fds)
    try:
        return ex.submit(run_one, sc).result()
    except BrokenProcessPool:
        return error_row(sc, "WorkerDied: the worker process died running this trip "
                         "(a crash inside the simulation, or out of memory)"), None
    finally:
        _stop_pool(ex)


def _local(todo: list[Scenario], workers: int,
           close_fds: tuple[int, ...] = ()) -> Iterator[Result]:
    queue = list(reversed(todo))
    while queue:
        ex = _pool(workers, close_fds)
        running: dict = {}
        suspects: list[Scenario] = []
        broken = False
        try:
            while (queue or running) and not broken:
                while queue and len(running) < 2 * workers:
                    try:
                        running[ex.submit(run_one, queue[-1])] = queue[-1]
                    except BrokenProcessPool:  # a worker died since the last wait
                        broken = True
                        break
                    queue.pop()
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
            if running or broken or queue:
                _stop_pool(ex)
            else:
                ex.shutdown(wait=True)
        for sc in suspects:  # which of them killed the worker: each alone
            yield _isolated(sc, close_fds)


def _dask_client(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise StumbleError("--scheduler needs Dask: pip install \"stumble[cluster]\"") from None
    try:
        return Client(address, timeout=f"{CONNECT_TIMEOUT_S}s", set_as_default=False)
    except Exception as e:
        raise StumbleError(f"cannot reach the Dask scheduler at {address} ({one_line(e)})"
                           ) from None


def _dask(todo: list[Scenario], client) -> Iterator[Result]:
    from distributed import as_completed

    def window() -> int:
        try:
            threads = sum(client.nthreads().values())
        except Exception:
            threads = 1
        return max(64, 4 * threads)

    queue = list(reversed(todo))
    running: dict = {}
    ac = as_completed(loop=client.loop)  # the client is not the default one
    size, sized_at = window(), time.monotonic()

    def refill() -> None:
        nonlocal size, sized_at
        if time.monotonic() - sized_at > 10.0:  # the cluster may have grown
            size, sized_at = window(), time.monotonic()
        while queue and len(running) < size:
            sc = queue.pop()
            fut = client.submit(run_one, sc, key=f"stumble-trip-{run_key(sc)}", pure=False)
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
    """What a study produced: its rows in grid order and what this session ran."""

    rows: list[dict]
    ran: int
    before: int
    out: Path
    other_rows: int  # rows in the directory from scenarios not in this study


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


def run_study(scenarios: Iterable[Scenario], out: Path, workers: int | None = None,
              scheduler: str | None = None, retry_errors: bool = False,
              progress: bool = True, on_start: Callable[[str], None] | None = None,
              metadata: dict | None = None) -> StudyResult:
    """Run every scenario that ``out`` does not hold yet; return all rows in order.

    ``workers``: local processes (default all cores; 1 runs in this process).
    ``scheduler``: a Dask scheduler address instead. ``retry_errors``: run again the
    scenarios whose stored row has an error. ``metadata`` goes into ``out/study.json``.
    Raises StudyInterrupted (all finished runs stored) on Ctrl-C or SIGTERM.
    """
    scenarios = list(scenarios)
    keys = [run_key(sc) for sc in scenarios]
    unique = dict(zip(keys, scenarios, strict=True))
    require_pyarrow()
    if scheduler is not None and workers is not None:
        raise StumbleError("--workers is for local processes; a Dask cluster has its own")
    workers = workers or default_workers()
    if workers < 1:
        raise StumbleError(f"--workers {workers}: at least 1")
    client = _dask_client(scheduler) if scheduler is not None else None
    out = Path(out)
    shield = _Shield()
    try:
        with Store(out) as store:
            _write_study_json(out, unique, metadata)

            def finished(k: str) -> bool:
                row = store.rows.get(k)
                return row is not None and not (retry_errors and row.get("error"))

            todo = [sc for k, sc in unique.items() if not finished(k)]
            before = len(unique) - len(todo)
            where = (f"the Dask cluster at {scheduler}" if client is not None else
                     "this process" if min(workers, len(todo)) == 1 else
                     f"{min(workers, len(todo))} local processes")
            msg = (f"study: {len(unique)} runs, {before} done before, {len(todo)} to run"
                   + (f" on {where}" if todo else "") + f"; results in {out}")
            (on_start or (lambda m: print(m, file=sys.stderr)))(msg)
            bar = Progress(len(todo), enabled=progress)
            if client is not None:
                runs = _dask(todo, client)
            elif workers == 1 or len(todo) <= 1:
                runs = _serial(todo)
            else:
                import stumble.pipeline  # noqa: F401  (imported once, shared by the forks)

                runs = _local(todo, min(workers, len(todo)), store.inherited_fds())
            ran = 0
            try:
                with _sigterm_as_interrupt(), contextlib.closing(runs):
                    for row, tb in runs:
                        store.add(row, tb)
                        ran += 1
                        bar.update(row)
            except KeyboardInterrupt:
                shield.on()  # finish storing, whatever else arrives
                bar.close()
                stored = sum(k in store.rows for k in unique)
                raise StudyInterrupted(
                    f"interrupted: {stored} of {len(unique)} runs are stored in {out}; run "
                    "the same command again to do the rest") from None
            bar.close()
            rows = [store.rows[k] for k in unique if k in store.rows]
            other = len(store.rows) - len(rows)
    finally:
        if client is not None:
            with contextlib.suppress(Exception):
                client.close()
        shield.off()
    write_parquet(out / "results.parquet", rows)
    return StudyResult(rows, ran, before, out, other)


def _write_study_json(out: Path, unique: dict, metadata: dict | None) -> None:
    d = {"stumble_version": __version__, "runs": len(unique), **(metadata or {})}
    tmp = out / ".study.json.tmp"
    tmp.write_text(dumps(d, indent=1) + "\n")
    os.replace(tmp, out / "study.json")


# ---------------------------------------------------------------- the summary table


def outcome(row: dict) -> str:
    """error, diverged, recovered, fell or neither (no recovery within the time)."""
    if row.get("error") and not row.get("diverged"):
        return "error"
    if row.get("diverged"):
        return "diverged"
    if row.get("recovered"):
        return "recovered"
    if row.get("fell"):
        return "fell"
    return "neither"


OUTCOMES = ("recovered", "fell", "diverged", "neither", "error")


def summary_table(rows: list[dict]) -> str:
    """Runs and outcomes per strategy taken (and per controller when there are several)."""
    controllers = sorted({str(r.get("controller")) for r in rows})
    by_ctrl = len(controllers) > 1

    def label(r: dict) -> str:
        s = r.get("strategy") or "-"
        return f"{r.get('controller')} {s}" if by_ctrl else s

    groups: dict[str, dict[str, int]] = {}
    for r in rows:
        g = groups.setdefault(label(r), dict.fromkeys(OUTCOMES, 0))
        g[outcome(r)] += 1
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

