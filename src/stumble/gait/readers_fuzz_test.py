"""A small bounded fuzz of the motion readers: random bytes and random mutations of valid
.mot/.sto and BVH files give a one-line InputError naming the file, or a valid result;
never another exception, never a hang.

Bounded in count (``CASES`` per kind) and in time (``CASE_S`` per case, an alarm, and
``TOTAL_S`` for the test); the seed is fixed, so a failure names a case that reproduces.
"""

import signal
import time

import numpy as np
import pytest

from stumble.body import build
from stumble.errors import InputError
from stumble.gait.bvh import bvh_to_coordinates, read_bvh
from stumble.gait.files import play_motion, read_motion
from stumble.gait.readers import Motion, read_mot, write_storage
from stumble.gait.reference import load_reference

SEED = 20240512
CASES = 60  # per kind of input
CASE_S = 5.0  # a case running longer is a hang
TOTAL_S = 60.0  # the whole test stops starting cases after this
PLAYED = 6  # mutated files that read cleanly and are also played (the slow stage)
JUNK = ["nan", "inf", "-inf", "1e309", "1e300", "1e-300", "-1", "0", "", "{", "}", "=",
        "endheader", "MOTION", "Frames:", "Frame Time:", "ROOT", "JOINT", "End Site",
        "CHANNELS", "OFFSET", "time", "99999999999999999999", "\t", "  ", "é", "\x00",
        "-0", "+", "1,5", "0x10", "knee_angle_r", "nRows=-1", "inDegrees=no"]


class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang


def _valid_mot(tmp_path) -> bytes:
    gait = load_reference()
    t = np.arange(0.0, 1.4, 1 / 60)
    path = tmp_path / "seed.mot"
    cols = gait.angles(t / gait.stride_s)
    cols["pelvis_tx"] = 1.1 * t
    write_storage(path, t, cols)
    return path.read_bytes()


def _valid_sto(tmp_path) -> bytes:
    t = np.arange(0.0, 1.4, 0.01)
    names = ["/jointset/hip_r/hip_flexion_r/value", "/jointset/knee_r/knee_angle_r/value",
             "/jointset/hip_r/hip_flexion_r/speed", "/forceset/soleus_r/activation"]
    rows = "\n".join("\t".join(f"{v:.6g}" for v in (tk, 0.3 * np.sin(6 * tk),
                                                    -0.5 - 0.4 * np.sin(6 * tk), 1.8, 0.2))
                     for tk in t)
    text = ("Coordinates\ninDegrees=no\nnColumns=9\nnRows=1350\nDataType=double\nversion=3\n"
            "endheader\ntime\t" + "\t".join(names) + "\n" + rows + "\n")
    return text.encode()


def _valid_bvh() -> bytes:
    from stumble.gait.bvh_test import _bvh_text, _walk_frames

    return _bvh_text(_walk_frames(n=45), dt=1 / 30).encode()


def _mutate(data: bytes, rng: np.random.Generator) -> bytes:
    """One to four random edits of lines, tokens or bytes."""
    for _ in range(int(rng.integers(1, 5))):
        op = int(rng.integers(0, 8))
        lines = data.split(b"\n")
        if op == 0 and len(lines) > 1:  # drop a line
            del lines[int(rng.integers(len(lines)))]
        elif op == 1:  # duplicate a line
            k = int(rng.integers(len(lines)))
            lines.insert(k, lines[k])
        elif op == 2 and len(lines) > 1:  # swap two lines
            i, j = rng.integers(len(lines), size=2)
            lines[i], lines[j] = lines[j], lines[i]
        elif op == 3:  # replace a token with junk
            k = int(rng.integers(len(lines)))
            toks = lines[k].split()
            if toks:
                toks[int(rng.integers(len(toks)))] = JUNK[int(rng.integers(len(JUNK)))].encode()
                lines[k] = b"\t".join(toks)
        elif op == 4:  # truncate
            data = data[: int(rng.integers(len(data) + 1))]
            continue
        elif op == 5:  # random bytes somewhere
            k = int(rng.integers(len(data) + 1))
            data = data[:k] + rng.bytes(int(rng.integers(1, 16))) + data[k:]
            continue
        elif op == 6:  # scale every number of a line (units, huge values, zero steps)
            k = int(rng.integers(len(lines)))
            f = float(rng.choice([0.0, -1.0, 1e3, 1e-300, 1e300, 57.3]))
            out = []
            for tok in lines[k].split():
                try:
                    out.append(f"{float(tok) * f:.6g}".encode())
                except ValueError:
                    out.append(tok)
            lines[k] = b"\t".join(out)
        else:  # remove a line's last value (ragged rows)
            k = int(rng.integers(len(lines)))
            lines[k] = lines[k].rsplit(b"\t", 1)[0].rsplit(b" ", 1)[0]
        data = b"\n".join(lines)
    return data


def _check_motion(m: Motion) -> None:
    assert m.n_frames >= 2 and np.all(np.diff(m.time_s) > 0)
    assert np.isfinite(m.time_s).all()
    for k, v in m.columns.items():
        assert v.shape == m.time_s.shape and np.isfinite(v).all(), k


def _one_case(path, kind: str, played: list[int], body) -> str:
    """Read (and map) one file; ``ok`` or ``error``; anything else raises."""
    try:
        if kind == "bvh":
            _check_motion(bvh_to_coordinates(read_bvh(path)))
        else:
            _check_motion(read_mot(path))
        motion = read_motion(path)
        _check_motion(motion)
        if played[0] < PLAYED:
            played[0] += 1
            pb = play_motion(body, motion)
            assert np.isfinite(pb.qpos).all() and np.isfinite(pb.stride_s)
        return "ok"
    except InputError as exc:
        msg = str(exc)
        assert "\n" not in msg and msg, repr(msg)
        assert msg.startswith(f"{path.name}:") or msg.startswith("--duration"), msg
        return "error"


def test_fuzzed_motion_files_give_one_line_errors_or_valid_results(tmp_path):
    rng = np.random.default_rng(SEED)
    body = build()
    seeds = {"mot": _valid_mot(tmp_path), "sto": _valid_sto(tmp_path), "bvh": _valid_bvh()}
    old = signal.signal(signal.SIGALRM, _alarm)
    start = time.monotonic()
    outcomes = {"ok": 0, "error": 0}
    played = [0]
    try:
        for kind, seed_bytes in seeds.items():
            for case in range(2 * CASES):
                if time.monotonic() - start > TOTAL_S:
                    break
                data = rng.bytes(int(rng.integers(0, 400))) if case % 2 == 0 else \
                    _mutate(seed_bytes, rng)
                if case % 2 == 0 and case % 4 == 0:  # random bytes behind a real header
                    data = seed_bytes[: int(rng.integers(0, 200))] + data
                path = tmp_path / f"case{case}.{kind}"
                path.write_bytes(data)
                signal.setitimer(signal.ITIMER_REAL, CASE_S)
                try:
                    outcomes[_one_case(path, kind, played, body)] += 1
                except Hang:
                    pytest.fail(f"{kind} case {case} (seed {SEED}) ran over {CASE_S} s")
                except Exception as exc:  # any other exception is the failure looked for
                    pytest.fail(f"{kind} case {case} (seed {SEED}): {type(exc).__name__}: {exc}")
                finally:
                    signal.setitimer(signal.ITIMER_REAL, 0.0)
    finally:
        signal.signal(signal.SIGALRM, old)
    # the fuzz reached both outcomes: some files were still valid, most were refused
    assert outcomes["ok"] >= 5 and outcomes["error"] >= 100, outcomes
    assert played[0] >= 1
