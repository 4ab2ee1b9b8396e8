"""The result store of a study: one row per run, written as runs finish, crash-safe.

Layout of a study directory::

    DIR/runs/journal-<session>.jsonl   rows of the runs just finished, one JSON line each,
                                       appended and flushed as each run finishes
    DIR/runs/part-<time>-<id>.parquet  rows moved out of a journal (every PART_ROWS rows
                                       and at the end), written to a temporary name and
                                       renamed, so a part is either whole or absent
    DIR/runs/corrupt-<name>            a part that cannot be read, or a journal that held
                                       bad lines, moved aside (their runs are run again)
    DIR/results.parquet                every run of the study, in grid order (at the end)
    DIR/errors/<key>.txt               the traceback of each run that raised

A killed study (Ctrl-C, SIGTERM, even SIGKILL) loses no run whose row reached the
journal: the next session reads the parts and the journals (a half-written last line is
ignored), moves leftover journals into a part and runs only what is missing. A row moved
into a part whose journal was not yet deleted appears twice; rows are deduplicated by key.
One study at a time may use a directory (``DIR/.lock``).

Every row carries ``checksum``, the first 16 hex digits of the SHA-256 of its other
fields (``row_checksum``). A journal line that is not UTF-8 JSON, whose checksum does not
match (an edited row), or whose values have the wrong types (a text ``recovered``, a seed
beyond 64 bits) is skipped with a one-line warning naming the file and line, and its run
is run again: a directory never gets stuck on a bad row. Parquet parts are binary and
written whole by the store; their checksum column is there for readers to check.

Nothing here holds all the rows of a study: the store keeps the keys of the finished runs
(8 bytes each), and ``write_results`` builds ``results.parquet`` from the parts a chunk
of rows at a time.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import re
import sys
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from stumble.errors import StumbleError
from stumble.jsonio import dumps
from stumble.outdir import check_writable

PART_ROWS = 500  # rows per Parquet part (a journal is moved into a part at this size)
STUDY_FILES = ("results.parquet", "study.json")  # written in DIR at the end
RESULT_CHUNK_ROWS = 20_000  # rows of results.parquet assembled at a time (one row group)
MAX_LINE_BYTES = 1_000_000  # a journal line longer than this is not a row of ours
MAX_WARNINGS = 20  # bad rows named one by one; past this, one line counts the rest
INT64 = (-(2**63), 2**63 - 1)
KEY = re.compile(r"[0-9a-f]{16}")
BOOL_COLUMNS = ("recovered", "fell", "diverged", "timed_out")
INT_COLUMNS = ("seed", "steps")
TEXT_COLUMNS = ("key", "checksum", "controller", "leg", "mechanism", "strategy_mode", "sex",
                "contact", "strategy", "variant", "error", "stumble_version", "stop_reason",
                "states", "strength_model", "population", "recovery", "params_sha256")
UNIT_SUFFIXES = ("_s", "_m", "_m_per_s", "_deg", "_kg", "_scale", "_n", "_nm", "_fraction")

Warn = Callable[[str], None]


def warn_stderr(message: str) -> None:
    """A warning as one line on stderr."""
    print(f"stumble: warning: {message}", file=sys.stderr)


def require_pyarrow():
    """The ``pyarrow`` module, or a one-line StumbleError saying how to install it."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise StumbleError("writing study results needs pyarrow, a stumble dependency: "
                           "pip install pyarrow (or reinstall stumble)") from None
    return pyarrow


# ---------------------------------------------------------------- rows


def _canonical_value(v):
    if isinstance(v, float) and v.is_integer() and abs(v) < 2**53:
        return int(v)  # 1.0 and 1 are the same number (Parquet may widen ints)
    return v


def row_checksum(row: dict) -> str:
    """16 hex digits of SHA-256 over the row's non-empty fields but ``checksum``, as
    canonical JSON (sorted keys; integral floats as integers)."""
    fields = {k: _canonical_value(v) for k, v in row.items()
              if k != "checksum" and v is not None}
    text = json.dumps(fields, sort_keys=True, separators=(",", ":"), allow_nan=False,
                      ensure_ascii=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def with_checksum(row: dict) -> dict:
    """The row with its ``checksum`` set (last column)."""
    row = {k: v for k, v in row.items() if k != "checksum"}
    row["checksum"] = row_checksum(row)
    return row


def _numeric_column(name: str) -> bool:
    """Whether a column holds numbers by its name: it carries a unit suffix."""
    parent = ".".join(name.split(".")[:-1])
    return name.endswith(UNIT_SUFFIXES) or parent.endswith(UNIT_SUFFIXES)


def row_problem(row) -> str | None:
    """Why a row read back is not one of ours (None if it is): its key, checksum, types."""
    if not isinstance(row, dict):
        return f"not a JSON object but {type(row).__name__}"
    key = row.get("key")
    if not isinstance(key, str) or not KEY.fullmatch(key):
        return f"key {key!r} is not 16 hex digits"
    for name, v in row.items():
        if not isinstance(name, str):
            return "a column name is not text"
        if v is None:
            continue
        if isinstance(v, bool):
            if name in INT_COLUMNS or name in TEXT_COLUMNS or _numeric_column(name):
                return f"{name} = {v!r} has the wrong type"
        elif isinstance(v, int):
            if not INT64[0] <= v <= INT64[1]:
                return f"{name} = {v} does not fit in 64 bits"
            if name in BOOL_COLUMNS or name in TEXT_COLUMNS:
                return f"{name} = {v!r} has the wrong type"
        elif isinstance(v, float):
            if not math.isfinite(v):
                return f"{name} = {v!r} is not finite"
            if name in BOOL_COLUMNS or name in TEXT_COLUMNS or name in INT_COLUMNS:
                return f"{name} = {v!r} has the wrong type"
        elif isinstance(v, str):
            if name in BOOL_COLUMNS or name in INT_COLUMNS or _numeric_column(name):
                return f"{name} = {v[:40]!r} is text, not a value of its type"
        else:
            return f"{name} holds a {type(v).__name__}, not a value"
    if "checksum" not in row:
        return "it has no checksum"
    if row["checksum"] != row_checksum(row):
        return "its checksum does not match (the row was edited)"
    return None


def _no_constants(name: str):
    raise ValueError(f"{name} is not a number in strict JSON")


def read_journal(path: Path, warn: Warn | None = None) -> tuple[list[dict], int]:
    """The good rows of a journal and how many lines were skipped (each with a warning
    naming the file and line; a half-written last line of a killed session silently)."""
    warn = warn or warn_stderr
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return [], 0
    except OSError as e:
        warn(f"{path}: cannot be read ({e.strerror or e}); its rows are run again")
        return [], 1
    lines = data.split(b"\n")
    complete = data.endswith(b"\n")
    if complete:
        lines = lines[:-1]
    rows, bad = [], 0
    for i, raw in enumerate(lines, start=1):
        last_partial = i == len(lines) and not complete
        why = None
        if len(raw) > MAX_LINE_BYTES:
            why = f"longer than {MAX_LINE_BYTES} bytes"
        else:
            try:
                row = json.loads(raw.decode("utf-8"), parse_constant=_no_constants)
                why = row_problem(row)
            except UnicodeDecodeError:
                why = "not UTF-8 text"
            except (ValueError, RecursionError) as e:
                why = "not a JSON row" if last_partial else f"not a JSON row ({str(e)[:60]})"
        if why is None:
            rows.append(row)
        elif not (last_partial and why.startswith("not a JSON row")):
            bad += 1
            if bad <= MAX_WARNINGS:
                key = _key_hint(raw)
                warn(f"{path} line {i}{key}: {why}; row skipped, its run will be run again")
    if bad > MAX_WARNINGS:
        warn(f"{path}: {bad - MAX_WARNINGS} more bad lines skipped")
    return rows, bad


def _key_hint(raw: bytes) -> str:
    m = re.search(rb'"key"\s*:\s*"([0-9a-f]{16})"', raw[:4096])
    return f" (key {m.group(1).decode()})" if m else ""


# ---------------------------------------------------------------- Parquet


def _column(pa, name: str, values: list):
    """One Arrow column; a column of mixed types (not written by us) as text."""
    try:
        arr = pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        if all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
               for v in values):
            arr = pa.array([None if v is None else float(v) for v in values], pa.float64())
        else:
            arr = pa.array([None if v is None else v if isinstance(v, str) else json.dumps(v)
                            for v in values], pa.string())
    if pa.types.is_null(arr.type):  # all None: a type from the name
        arr = arr.cast(_null_type(pa, name))
    return arr


def rows_table(rows: list[dict]):
    """An Arrow table of rows (dicts; columns the union of their keys, first seen first)."""
    pa = require_pyarrow()
    columns: dict[str, None] = {}
    for r in rows:
        columns.update(dict.fromkeys(r))
    return pa.table({c: _column(pa, c, [r.get(c) for r in rows]) for c in columns})


def _atomic_parquet(path: Path, write: Callable) -> None:
    """Call ``write(file)`` on a temporary file next to ``path``, fsync, rename over it."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_parquet(path: Path, rows: list[dict]) -> None:
    """Write rows (dicts; columns the union of their keys) atomically to ``path``."""
    require_pyarrow()
    import pyarrow.parquet as pq

    table = rows_table(rows)
    _atomic_parquet(Path(path), lambda f: pq.write_table(table, f))


def _null_type(pa, name: str):
    """Type of a column with no value yet: a number if its name carries a unit, else text."""
    if name in BOOL_COLUMNS:
        return pa.bool_()
    return pa.float64() if _numeric_column(name) else pa.string()


def read_parquet_rows(path: Path) -> list[dict]:
    """The rows of a Parquet file as dicts."""
    require_pyarrow()
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()


def iter_parquet_rows(path: Path, columns: list[str] | None = None,
                      batch_rows: int = 10_000) -> Iterator[dict]:
    """The rows of a Parquet file one at a time (a batch in memory at most); ``columns``:
    only these (those the file lacks are left out)."""
    require_pyarrow()
    import pyarrow.parquet as pq

    f = pq.ParquetFile(path)
    if columns is not None:
        columns = [c for c in columns if c in f.schema_arrow.names]
    for batch in f.iter_batches(batch_size=batch_rows, columns=columns):
        yield from batch.to_pylist()


def keys_to_ints(keys: Iterable) -> np.ndarray:
    """16-hex-digit run keys as uint64 (a key that is not one becomes 0, never a run's)."""
    out = []
    for k in keys:
        try:
            out.append(int(k, 16) if isinstance(k, str) and KEY.fullmatch(k) else 0)
        except ValueError:
            out.append(0)
    return np.array(out, dtype=np.uint64)


def contains(sorted_keys: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """Which of ``keys`` are in ``sorted_keys`` (both uint64; by binary search, which
    NumPy 2.0's ``isin`` gets wrong for 64-bit unsigned keys)."""
    if not len(sorted_keys):
        return np.zeros(len(keys), bool)
    idx = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return sorted_keys[idx] == keys


# ---------------------------------------------------------------- the store


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
    """The finished runs of a study directory by key; ``add`` makes a row durable at once.

    Use as a context manager: entering locks the directory and indexes what is there
    (``done``: keys as uint64, sorted; ``done_ok``: those whose row has no error;
    ``controllers``: the controllers of its rows, None when a part does not say), leaving
    moves the journal into a part and unlocks.
    """

    def __init__(self, out: Path, warn: Warn | None = None):
        self.out = Path(out)
        self.runs = self.out / "runs"
        self.warn = warn or warn_stderr
        self.done = np.zeros(0, np.uint64)
        self.done_ok = np.zeros(0, np.uint64)
        self.controllers: set[str] | None = set()
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
        check_writable(self.runs, "study directory")
        for name in STUDY_FILES:  # a directory in their place fails only at the end
            if (self.out / name).is_dir():
                raise StumbleError(f"{self.out / name} is a directory: the study writes "
                                   "that file (move it, or give another --out)")
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

    def _set_aside(self, path: Path, why: str) -> None:
        target = path.with_name(f"corrupt-{path.name}")
        with contextlib.suppress(OSError):
            os.replace(path, target)
        self.warn(f"{path}: {why}; moved to {target.name}, its runs will be run again")

    def _load(self) -> None:
        import pyarrow.parquet as pq

        for tmp in self.runs.glob(".*.tmp"):  # a part being written when a session died
            tmp.unlink(missing_ok=True)
        keys, errs = [], []
        for part in sorted(self.runs.glob("part-*.parquet")):
            try:
                names = pq.read_schema(part).names
                cols = ["key", *(c for c in ("error", "controller") if c in names)]
                t = pq.read_table(part, columns=cols)
            except Exception as e:  # not written by us (parts are renamed whole)
                self._set_aside(part, f"unreadable result part ({type(e).__name__})")
                continue
            keys.append(keys_to_ints(t.column("key").to_pylist()))
            errs.append(np.asarray(t.column("error").is_valid()) if "error" in cols
                        else np.zeros(t.num_rows, bool))
            self._note_controllers(t.column("controller").to_pylist()
                                   if "controller" in cols else None)
        leftovers = sorted(self.runs.glob("journal-*.jsonl"), key=lambda p: p.stat().st_mtime)
        rescued = []
        for j in leftovers:
            rows, bad = read_journal(j, self.warn)
            rescued += rows
            if bad:
                with contextlib.suppress(OSError):
                    os.replace(j, j.with_name(f"corrupt-{j.name}"))
        if rescued:  # a killed session's journal: into a part, then away
            write_parquet(self._part_name(), rescued)
            keys.append(keys_to_ints(r["key"] for r in rescued))
            errs.append(np.array([bool(r.get("error")) for r in rescued], bool))
            self._note_controllers([r.get("controller") for r in rescued])
        for j in leftovers:
            j.unlink(missing_ok=True)
        k = np.concatenate(keys) if keys else np.zeros(0, np.uint64)
        e = np.concatenate(errs) if errs else np.zeros(0, bool)
        self.done = np.unique(k)
        self.done_ok = np.unique(k[~e])

    def _note_controllers(self, names: list | None) -> None:
        """Add a part's controllers to ``controllers`` (None: a part without them)."""
        if names is None or any(not isinstance(n, str) for n in names):
            self.controllers = None
        elif self.controllers is not None:
            self.controllers |= set(names)

    def _part_name(self) -> Path:
        return self.runs / f"part-{time.time_ns():020d}-{uuid.uuid4().hex[:8]}.parquet"

    def add(self, row: dict, traceback_text: str | None = None) -> None:
        """Record one finished run: appended to the journal and flushed before returning."""
        row = with_checksum(row)
        if self._file is None:
            self._journal = self.runs / f"journal-{uuid.uuid4().hex[:12]}.jsonl"
            self._file = open(self._journal, "a", encoding="utf-8")
        self._file.write(dumps(row) + "\n")
        self._file.flush()
        self._pending.append(row)
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


# ---------------------------------------------------------------- results.parquet


def _unified_schema(pa, schemas: list):
    """One schema for all parts: each column's type where they agree, numbers widened to
    float64, text where they disagree otherwise; columns in the order first seen."""
    types: dict[str, list] = {}
    for s in schemas:
        for f in s:
            types.setdefault(f.name, []).append(f.type)
    fields = []
    for name, ts in types.items():
        known = {t for t in ts if not pa.types.is_null(t)}
        if not known:
            t = _null_type(pa, name)
        elif len(known) == 1:
            t = known.pop()
        elif all(pa.types.is_integer(t) or pa.types.is_floating(t) for t in known):
            t = pa.float64()
        else:
            t = pa.string()
        fields.append(pa.field(name, t))
    return pa.schema(fields)


def _conform(pa, table, schema):
    """``table`` with ``schema``'s columns in order (missing ones empty), cast to its types."""
    cols = []
    for f in schema:
        if f.name in table.column_names:
            col = table.column(f.name)
            cols.append(col if col.type == f.type else col.cast(f.type))
        else:
            cols.append(pa.nulls(table.num_rows, f.type))
    return pa.table(cols, schema=schema)


def write_results(out: Path, grid_keys: np.ndarray, path: Path | None = None) -> tuple[int, int]:
    """Write ``results.parquet``: the best stored row of each run of the grid, in grid
    order, a chunk at a time; returns (rows written, distinct stored runs not in the grid).

    ``grid_keys``: the study's run keys as uint64 (``keys_to_ints``), in grid order,
    without duplicates. Of two rows of one run, one without an error wins, else the
    newer. The memory used is a few arrays of the stored rows' count and one chunk."""
    pa = require_pyarrow()
    import pyarrow.parquet as pq

    runs = Path(out) / "runs"
    path = Path(path) if path is not None else Path(out) / "results.parquet"
    parts = sorted(runs.glob("part-*.parquet"))
    order = np.argsort(grid_keys, kind="stable")
    sorted_keys = grid_keys[order]
    pos_l, part_l, row_l, err_l, schemas, others = [], [], [], [], [], []
    for i, part in enumerate(parts):
        names = pq.read_schema(part).names
        t = pq.read_table(part, columns=["key", "error"] if "error" in names else ["key"])
        keys = keys_to_ints(t.column("key").to_pylist())
        idx_c = np.minimum(np.searchsorted(sorted_keys, keys), max(len(sorted_keys) - 1, 0))
        found = contains(sorted_keys, keys)
        others.append(keys[~found])
        rows = np.flatnonzero(found)
        pos_l.append(order[idx_c[rows]])
        part_l.append(np.full(len(rows), i))
        row_l.append(rows)
        err_l.append(np.asarray(t.column("error").is_valid())[rows] if "error" in names
                     else np.zeros(len(rows), bool))
        schemas.append(pq.read_schema(part))
    other = len(np.unique(np.concatenate(others))) if others else 0
    if not parts:
        _atomic_parquet(path, lambda f: pq.write_table(pa.table({}), f))
        return 0, 0
    pos, part_i, row_i, err = (np.concatenate(x) for x in (pos_l, part_l, row_l, err_l))
    seq = np.arange(len(pos))  # parts are named by time: later is newer
    pick = np.lexsort((seq, ~err, pos))  # per position: error-free last, newest last
    last = np.ones(len(pick), bool)
    last[:-1] = pos[pick][1:] != pos[pick][:-1]
    best = pick[last]  # in grid order
    schema = _unified_schema(pa, schemas)

    def write(f) -> None:
        with pq.ParquetWriter(f, schema) as w:
            for start in range(0, len(best), RESULT_CHUNK_ROWS):
                chunk = best[start:start + RESULT_CHUNK_ROWS]
                pieces, where = [], []
                for p in np.unique(part_i[chunk]):
                    sel = chunk[part_i[chunk] == p]
                    t = pq.read_table(parts[p]).take(pa.array(row_i[sel]))
                    pieces.append(_conform(pa, t, schema))
                    where.append(pos[sel])
                table = pa.concat_tables(pieces)
                w.write_table(table.take(pa.array(np.argsort(np.concatenate(where)))))

    _atomic_parquet(path, write)
    return len(best), other


def load_results(out: Path, warn: Warn | None = None) -> list[dict]:
    """Every row stored in a study directory (parts and journals), one per run key.

    For reading a small study while it runs or after it was killed (it holds every row);
    ``DIR/results.parquet`` is the finished study."""
    runs = Path(out) / "runs"
    rows: dict[str, dict] = {}
    for part in sorted(runs.glob("part-*.parquet")):
        for row in read_parquet_rows(part):
            if _better(row, rows.get(row["key"])):
                rows[row["key"]] = row
    for j in sorted(runs.glob("journal-*.jsonl")):
        for row in read_journal(j, warn)[0]:
            if _better(row, rows.get(row["key"])):
                rows[row["key"]] = row
    return list(rows.values())
