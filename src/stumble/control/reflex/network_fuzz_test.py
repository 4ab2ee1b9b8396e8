"""A small, bounded, deterministic fuzz of the study-file and network-file readers.

Random bytes and random mutations of a valid TOML study file and of the shipped
``network.npz`` go through ``load_toml`` (then the grid's count and every scenario's
check) and ``Network.load``. Each must give a valid result or an InputError of one line
naming the file, never another exception and never a hang (a case longer than
``CASE_LIMIT_S`` fails). Bounded by ``CASES`` per family and ``BUDGET_S`` per test; the
random generator is seeded, so a failure comes back the same.
"""

import io
import math
import signal
import textwrap
import time
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from stumble.control.reflex.network import Network
from stumble.errors import InputError
from stumble.study.grid import MAX_RUNS, check_scenario, load_toml

CASES = 120  # per family
BUDGET_S = 4.0  # per test: stop early past it (at least 40 cases are asserted)
CASE_LIMIT_S = 5.0  # one case longer than this is a hang
SEED = 13

STUDY = textwrap.dedent("""\
    description = "fuzz seed"
    swing = "0.05:0.75:4"
    speed = [0.8, 1.1, 1.4]
    mechanism = ["force", "obstacle"]
    obstacle-height = [0.08, 0.14]
    delay_scale = "1:2:3"
    controller = "fsm"
    repeats = 2
    """).encode()
TOKENS = [b"nan", b"inf", b"-inf", b"-1", b"0", b"1e309", b"9" * 30, b'"x"', b"[]", b"{}",
          b"[[1]]", b'"1:2:0"', b'"1:2:100001"', b"true", b"1.5", b'"0.05:0.9:100000"',
          b"\xff", b"\x00", b"=", b"[", b'"', b"\n", b"seed = 1\n", b"repeats = 1000000\n",
          b"1979-05-27", b"07:32:00", b"1979-05-27T07:32:00Z"]  # TOML dates and times


class Hang(Exception):
    pass


@contextmanager
def time_limit(seconds: float):
    """Raise Hang in this (main) thread after ``seconds``."""
    def alarm(signum, frame):
        raise Hang(f"no answer after {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def mutate_bytes(rng: np.random.Generator, data: bytes, tokens=()) -> bytes:
    """One to four random edits: flip, delete, insert, duplicate, truncate, token."""
    b = bytearray(data)
    for _ in range(int(rng.integers(1, 5))):
        op = int(rng.integers(0, 6 if tokens else 5))
        i = int(rng.integers(0, max(1, len(b))))
        if op == 0 and b:
            b[i % len(b)] ^= 1 << int(rng.integers(0, 8))
        elif op == 1:
            del b[i:i + int(rng.integers(1, 64))]
        elif op == 2:
            b[i:i] = rng.bytes(int(rng.integers(1, 16)))
        elif op == 3:
            j = int(rng.integers(0, max(1, len(b))))
            b[i:i] = b[j:j + int(rng.integers(1, 64))]
        elif op == 4:
            del b[i:]
        else:
            b[i:i] = tokens[int(rng.integers(0, len(tokens)))]
    return bytes(b)


def check_one_line(e: InputError, path: Path) -> None:
    text = str(e)
    assert "\n" not in text and str(path.name) in text, text


def run_cases(make_case, check, tmp_path: Path) -> int:
    """Run up to CASES cases within BUDGET_S; returns how many ran."""
    t0 = time.monotonic()
    n = 0
    for n in range(1, CASES + 1):
        path = make_case(n)
        start = time.monotonic()
        with time_limit(CASE_LIMIT_S):
            try:
                check(path)
            except InputError as e:
                check_one_line(e, path)
        assert time.monotonic() - start < CASE_LIMIT_S
        if time.monotonic() - t0 > BUDGET_S:
            break
    return n


def check_study(path: Path) -> None:
    """A study file read (errors name the file), counted and (when small) every scenario
    checked (errors name the value: the CLI says the same for a command-line axis)."""
    grid = load_toml(path)
    try:
        n = grid.checked_count()
        assert 1 <= n <= MAX_RUNS
        if n <= 2000:
            for sc in grid.iter_scenarios():
                check_scenario(sc)
    except InputError as e:
        assert "\n" not in str(e) and str(e)


def test_fuzz_study_files(tmp_path):
    rng = np.random.default_rng(SEED)
    f = tmp_path / "study.toml"
    f.write_bytes(STUDY)
    check_study(f)  # the seed file itself is valid

    def case(n: int) -> Path:
        data = rng.bytes(int(rng.integers(0, 400))) if n % 5 == 0 else mutate_bytes(
            rng, STUDY, TOKENS)
        f.write_bytes(data)
        return f

    assert run_cases(case, check_study, tmp_path) >= 40


def shipped_npz() -> bytes:
    from stumble.control.reflex.identify import SHIPPED

    return (Path(__file__).resolve().parent / "data"
            / SHIPPED).read_bytes()


def check_network(path: Path) -> None:
    net = Network.load(path)
    for a in (net.w, net.b, net.v, net.c, net.mean, net.std):
        assert np.isfinite(a).all()
    assert (net.std > 0).all() and net.topology.rate_hz > 0


def test_fuzz_network_bytes(tmp_path):
    """Random bytes, and bytes of the shipped network flipped, cut, inserted."""
    rng = np.random.default_rng(SEED)
    original = shipped_npz()
    f = tmp_path / "network.npz"

    def case(n: int) -> Path:
        if n % 6 == 0:
            f.write_bytes(rng.bytes(int(rng.integers(0, 2000))))
        elif n % 6 == 1:
            f.write_bytes(b"PK\x03\x04" + rng.bytes(int(rng.integers(0, 2000))))
        else:
            f.write_bytes(mutate_bytes(rng, original))
        return f

    assert run_cases(case, check_network, tmp_path) >= 40


def _mutate_array(rng: np.random.Generator, a: np.ndarray) -> np.ndarray:
    op = int(rng.integers(0, 9))
    if op == 0 and a.size and a.dtype.kind in "fiub":
        b = a.astype(float).copy()
        b.flat[int(rng.integers(0, b.size))] = [np.nan, np.inf, -np.inf, 0.0, 1e308][
            int(rng.integers(0, 5))]
        return b
    if op == 1:
        return a.ravel()[: max(0, a.size - int(rng.integers(1, 4)))]
    if op == 2:
        return np.concatenate([a.ravel(), a.ravel()[: int(rng.integers(1, 4))]])
    if op == 3:
        return a.astype(np.int32) if a.dtype.kind in "fiub" else a
    if op == 4:
        return np.array([str(x) for x in a.ravel()[:5]])
    if op == 5:
        return np.zeros((0,))
    if op == 6:
        return a.reshape(1, *a.shape) if a.ndim < 3 else a
    if op == 7:
        return np.array(rng.normal() * 10.0 ** int(rng.integers(-3, 6)))
    return np.zeros(a.shape, dtype=bool)


def test_fuzz_network_arrays(tmp_path):
    """The shipped network's arrays changed one or two at a time: shapes, types, NaN,
    zeros, entries dropped, added or renamed, stored or compressed."""
    rng = np.random.default_rng(SEED)
    with np.load(io.BytesIO(shipped_npz())) as z:
        arrays = {k: z[k] for k in z.files}
    names = sorted(arrays)
    f = tmp_path / "network.npz"

    def case(n: int) -> Path:
        d = dict(arrays)
        for _ in range(int(rng.integers(1, 3))):
            name = names[int(rng.integers(0, len(names)))]
            op = int(rng.integers(0, 10))
            if op == 0:
                d.pop(name, None)
            elif op == 1:
                d[f"extra{int(rng.integers(0, 9))}"] = np.zeros(3)
            elif name in d:
                d[name] = _mutate_array(rng, d[name])
        (np.savez_compressed if n % 2 else np.savez)(f, **d)
        return f

    assert run_cases(case, check_network, tmp_path) >= 40


def test_fuzz_zip_directories(tmp_path):
    """Archives whose member names and sizes are random: nothing is inflated past the
    limit, whatever the directory says."""
    rng = np.random.default_rng(SEED)
    f = tmp_path / "network.npz"
    original = shipped_npz()

    def case(n: int) -> Path:
        with zipfile.ZipFile(io.BytesIO(original)) as src, zipfile.ZipFile(
                f, "w", zipfile.ZIP_STORED) as dst:
            for info in src.infolist():
                data = src.read(info)
                name = info.filename
                if rng.random() < 0.2:
                    name = ["w.npy", "x.npy", "b", "../b.npy", "info.npy"][int(rng.integers(0, 5))]
                if rng.random() < 0.2:
                    data = mutate_bytes(rng, data)
                if name in dst.namelist():
                    continue
                dst.writestr(name, data)
        return f

    assert run_cases(case, check_network, tmp_path) >= 40
    assert math.isfinite(CASE_LIMIT_S)


if __name__ == "__main__":  # pragma: no cover
    pytest.main([__file__, "-q"])
