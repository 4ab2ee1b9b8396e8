"""The result store of a study: one row per run, written as runs finish, crash-safe.

Layout of a study directory::

    DIR/runs/journal-<session>.jsonl   rows of the runs just finished, one JSON line each,
                                       appended and flushed as each run finishes
    DIR/runs/part-<time>-<id>.parquet  rows moved out of a journal (every PART_ROWS rows
                                       and at the end), written to a temporary name and
                                       renamed, so a part is either whole or absent
    DIR/results.parquet                every run of the study, in grid order (at the end)
    DIR/errors/<key>.txt               the traceback of each run that raised

A killed study (Ctrl-C, SIGTERM, even SIGKILL) loses no run whose row reached the
journal: the next session reads the parts and the journals (a half-written last line is
ignored), moves leftover journals into a part and runs only what is missing. A row moved
into a part whose journal was not yet deleted appears twice; rows are deduplicated by key.
One study at a time may use a directory (``DIR/.lock``).
"""

from __future__ import annotations

import json
import os
import time
import uuid
from pathlib import Path

from stumble.errors import StumbleError
from stumble.jsonio import dumps

PART_ROWS = 500  # rows per Parquet part (a journal is moved into a part at this size)


def require_pyarrow():
    """The ``pyarrow`` module, or a one-line StumbleError saying how to install it."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise StumbleError("writing study results needs pyarrow, a stumble dependency: "
                           "pip install pyarrow (or reinstall stumble)") from None
    return pyarrow


def write_parquet(path: Path, rows: list[dict]) -> None:
    """Write rows (dicts; columns the union of their keys) atomically to ``path``."""
    pa = require_pyarrow()
    import pyarrow.parquet as pq

    columns: dict[str, None] = {}
    for r in rows:
        columns.update(dict.fromkeys(r))
    table = pa.Table.from_pylist([{c: r.get(c) for c in columns} for r in rows])
    for i, name in enumerate(table.column_names):  # all None: a type from the name
        if pa.types.is_null(table.schema.field(i).type):
            table = table.set_column(i, name, table.column(i).cast(_null_type(pa, name)))
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "wb") as f:
            pq.write_table(table, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


UNIT_SUFFIXES = ("_s", "_m", "_m_per_s", "_deg", "_kg", "_scale", "_n")


def _null_type(pa, name: str):
    """Type of a column with no value yet: a number if its name carries a unit, else text."""
    numeric = name.endswith(UNIT_SUFFIXES) or ".".join(name.split(".")[:-1]).endswith(
        UNIT_SUFFIXES)
    return pa.float64() if numeric else pa.string()


def read_parquet_rows(path: Path) -> list[dict]:
    """The rows of a Parquet file as dicts."""
    require_pyarrow()
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()


def _read_journal(path: Path) -> list[dict]:
    rows = []
    try:
        text = path.read_text()
    except FileNotFoundError:
        return rows
    for line in text.splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue  # the half-written last line of a killed session
        if isinstance(row, dict) and "key" in row:
            rows.append(row)
    return rows


def _better(new: dict, old: dict | None) -> bool:
    """Which of two rows of one key to keep: one without an error, else the newer."""
    return old is None or not (new.get("error") and not old.get("error"))


class _Lock:
    """An exclusive advisory lock on ``DIR/.lock`` (POSIX; no lock elsewhere)."""

    def __init__(self, path: Path):
        self.path = path
        self.fd = None

    def acquire(self) -> None:
        try:
            import fcntl
        except ImportError:  # not POSIX: no lock
            return
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            pid = os.read(fd, 32).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise StumbleError(f"{self.path.parent} is in use by another stumble study "
                               f"(pid {pid}); wait for it or choose another --out") from None
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self.fd = fd

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing releases the flock
            self.fd = None


class Store:
    """Rows of a study directory by run key; ``add`` makes a row durable at once.

    Use as a context manager: entering locks the directory and reads what is there,
    leaving moves the journal into a part and unlocks.
    """

    def __init__(self, out: Path):
        self.out = Path(out)
        self.runs = self.out / "runs"
        self.rows: dict[str, dict] = {}
        self._lock = _Lock(self.out / ".lock")
        self._journal: Path | None = None
        self._file = None
        self._pending: list[dict] = []

    def __enter__(self) -> Store:
        require_pyarrow()
        try:
            self.runs.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise StumbleError(f"{self.out}: cannot make the study directory "
                               f"({e.strerror or e})") from None
        self._lock.acquire()
        try:
            self._load()
        except BaseException:
            self._lock.release()
            raise
        return self

    def __exit__(self, *exc) -> None:
        try:
            self.flush_part()
        finally:
            self._lock.release()

    def inherited_fds(self) -> tuple[int, ...]:
        """Descriptors a forked worker must close (the lock stays the parent's alone)."""
        return () if self._lock.fd is None else (self._lock.fd,)

    def _load(self) -> None:
        for tmp in self.runs.glob(".*.tmp"):  # a part being written when a session died
            tmp.unlink(missing_ok=True)
        for part in sorted(self.runs.glob("part-*.parquet")):
            try:
                rows = read_parquet_rows(part)
            except Exception as e:  # not written by us (parts are renamed whole)
                raise StumbleError(f"{part}: unreadable result part ({e}); move it "
                                   "away and run again") from None
            for row in rows:
                self._keep(row)
        leftovers = sorted(self.runs.glob("journal-*.jsonl"), key=lambda p: p.stat().st_mtime)
        rescued = []
        for j in leftovers:
            for row in _read_journal(j):
                self._keep(row)
                rescued.append(row)
        if rescued:  # a killed session's journal: into a part, then away
            write_parquet(self._part_name(), rescued)
        for j in leftovers:
            j.unlink(missing_ok=True)

    def _keep(self, row: dict) -> None:
        key = row["key"]
        if _better(row, self.rows.get(key)):
            self.rows[key] = row

    def _part_name(self) -> Path:
        return self.runs / f"part-{time.time_ns():020d}-{uuid.uuid4().hex[:8]}.parquet"

    def add(self, row: dict, traceback_text: str | None = None) -> None:
        """Record one finished run: appended to the journal and flushed before returning."""
        if self._file is None:
            self._journal = self.runs / f"journal-{uuid.uuid4().hex[:12]}.jsonl"
            self._file = open(self._journal, "a", encoding="utf-8")
        self._file.write(dumps(row) + "\n")
        self._file.flush()
        self._pending.append(row)
        self._keep(row)
        if traceback_text:
            errors = self.out / "errors"
            errors.mkdir(exist_ok=True)
            (errors / f"{row['key']}.txt").write_text(traceback_text)
        if len(self._pending) >= PART_ROWS:
            self.flush_part()

    def flush_part(self) -> None:
        """Move the journal's rows into a Parquet part (atomic), then delete the journal."""
        if self._file is None:
            return
        self._file.close()
        self._file = None
        if self._pending:
            write_parquet(self._part_name(), self._pending)
        self._journal.unlink(missing_ok=True)
        self._pending = []


def load_results(out: Path) -> list[dict]:
    """Every row stored in a study directory (parts and journals), one per run key.

    For reading a study while it runs or after it was killed; ``DIR/results.parquet``
    is the finished study."""
    runs = Path(out) / "runs"
    rows: dict[str, dict] = {}
    for part in sorted(runs.glob("part-*.parquet")):
        for row in read_parquet_rows(part):
            if _better(row, rows.get(row["key"])):
                rows[row["key"]] = row
    for j in sorted(runs.glob("journal-*.jsonl")):
        for row in _read_journal(j):
            if _better(row, rows.get(row["key"])):
                rows[row["key"]] = row
    return list(rows.values())
