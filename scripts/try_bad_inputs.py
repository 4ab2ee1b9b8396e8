"""Bad inputs through every command, as a new user gives them; each result classified.

Run:  python scripts/try_bad_inputs.py [--jobs 2] [--json bad_inputs.json]

Every case runs ``python -m stumble.cli ...`` in a fresh process in its own temporary
directory, at most ``CASE_TIMEOUT_S`` seconds, and is classified:

- ``error``: exit status 2 and exactly one line on stderr starting ``stumble: ``;
- ``traceback``: a Python traceback on stderr;
- ``hang``: no answer within the time limit (killed);
- ``ok``: exit 0, and every JSON file written is strict JSON (no NaN/Infinity);
- ``bad-ok``: exit 0 but a JSON file written is not strict JSON;
- ``other``: anything else (another exit status, several lines).

The cases are built here, small files with the properties each needs (issue 13's classes:
seeds, output directories, network files, study seeds and journals, grid sizes, time
steps, time limits, motion files, study files). Study cases whose grid is valid run with
the trip replaced by a stand-in summary (``FAKE``), so the study machinery, not
physics, is what they try. Prints a table per class and the cases that were not clean.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
import zipfile
from collections import Counter, defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

CASE_TIMEOUT_S = 60.0
SHIPPED = Path(__file__).resolve().parents[1] / "src/stumble/control/reflex/data/network.npz"
FAKE = textwrap.dedent("""\
    import sys
    from types import SimpleNamespace
    from stumble import pipeline
    from stumble.cli import main

    def fake(sc, **kw):
        return SimpleNamespace(summary={"strategy": "elevating", "recovered": True,
                                        "fell": False, "diverged": False})

    pipeline.simulate_trip = fake
    sys.exit(main(sys.argv[1:]))
    """)


def shipped_arrays() -> dict:
    with np.load(SHIPPED) as z:
        return {k: z[k] for k in z.files}


def npz(path: Path, drop=(), **changes) -> None:
    arrays = {**shipped_arrays(), **changes}
    np.savez_compressed(path, **{k: v for k, v in arrays.items() if k not in drop})


def bomb(path: Path, gigabytes: float) -> None:
    """A network whose ``w`` inflates to ``gigabytes`` of zeros (about 1/1000 on disk)."""
    npz(path, drop=("w",))
    n = int(gigabytes * 2**30)
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED, allowZip64=True) as zf, zf.open(
            zipfile.ZipInfo("w.npy"), "w", force_zip64=True) as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False,
                                                 "shape": (n // 8,)})
        zeros = bytes(2**24)
        for _ in range(n // len(zeros)):
            f.write(zeros)


def mot(path: Path, times, angle_deg=10.0, header="inDegrees=yes") -> None:
    lines = ["Coordinates", "version=1", header, "endheader",
             "time\thip_flexion_r\tknee_angle_r"]
    lines += [f"{t!r}\t{angle_deg}\t{-angle_deg}" for t in times]
    path.write_text("\n".join(lines) + "\n")


def cases(work: Path) -> list[tuple[str, str, list[str], bool]]:
    """(class, name, argv, use FAKE) of every case; files made under ``work``."""
    out: list[tuple[str, str, list[str], bool]] = []

    def add(cls, name, argv, fake=False):
        out.append((cls, name, argv, fake))

    # seeds of trip and reflex fit
    for s in ["-1", "-100", str(2**63), str(2**64), "1.5", "abc", ""]:
        add("seed", f"trip --seed {s!r}", ["trip", "--no-video", "--seed", s, "--out", "o"])
    for s in ["-1", str(2**63), "x"]:
        add("seed", f"reflex fit --seed {s!r}", ["reflex", "fit", "--seed", s, "--out", "o"])
    # output directories
    (work / "afile").write_text("")
    commands = {"walk": ["walk", "--no-video"], "trip": ["trip", "--no-video"],
                "reflex fit": ["reflex", "fit"], "study": ["study"], "validate": ["validate"]}
    for name, argv in commands.items():
        add("out", f"{name} --out ''", [*argv, "--out", ""], name in ("study", "validate"))
        add("out", f"{name} --out /proc (not writable)", [*argv, "--out", "/proc"],
            name in ("study", "validate"))
        add("out", f"{name} --out a file", [*argv, "--out", str(work / "afile")],
            name in ("study", "validate"))
        add("out", f"{name} --out under a file", [*argv, "--out", str(work / "afile" / "x")],
            name in ("study", "validate"))
    # network files
    a = shipped_arrays()
    nets = {
        "truncated zip": lambda p: p.write_bytes(SHIPPED.read_bytes()[:50_000]),
        "a .npy": lambda p: p.write_bytes(b"\x93NUMPY" + SHIPPED.read_bytes()[6:200]),
        "b (35,)": lambda p: npz(p, b=np.zeros(35)),
        "b (36, 1)": lambda p: npz(p, b=np.zeros((36, 1))),
        "v (19, 5)": lambda p: npz(p, v=np.zeros((19, 5))),
        "v (18, 6)": lambda p: npz(p, v=np.zeros((18, 6))),
        "walk_rates (2, 9, 5)": lambda p: npz(p, walk_rates=np.zeros((2, 9, 5))),
        "walk_rates (3, 100, 21)": lambda p: npz(p, walk_rates=np.zeros((3, 100, 21))),
        "rate_hz 0": lambda p: npz(p, rate_hz=np.array(0.0)),
        "rate_hz NaN": lambda p: npz(p, rate_hz=np.array(np.nan)),
        "rate_hz -1000": lambda p: npz(p, rate_hz=np.array(-1000.0)),
        "rate_hz 1200 (the 2 ms step neither divides its tick nor is whole ticks)": lambda p: npz(
            p, rate_hz=np.array(1200.0)),
        "afferent speed 0": lambda p: npz(p, afferent_m_per_s=np.array(0.0)),
        "efferent speed inf": lambda p: npz(p, efferent_m_per_s=np.array(np.inf)),
        "hidden 0": lambda p: npz(p, hidden=np.array(0)),
        "hidden 2.5": lambda p: npz(p, hidden=np.array(2.5)),
        "NaN weights": lambda p: npz(p, w=np.where(a["w"] != 0, np.nan, 0.0)),
        "inf bias": lambda p: npz(p, c=np.full(7, np.inf)),
        "zero std": lambda p: npz(p, std=np.zeros(21)),
        "negative std": lambda p: npz(p, std=-np.ones(21)),
        "mean of 20": lambda p: npz(p, mean=np.zeros(20)),
        "NaN mean": lambda p: npz(p, mean=np.full(21, np.nan)),
        "weights outside blocks": lambda p: npz(p, w=np.ones((57, 36))),
        "no std": lambda p: npz(p, drop=("std",)),
        "no muscles": lambda p: npz(p, drop=("muscles",)),
        "extra entry": lambda p: npz(p, extra=np.zeros(3)),
        "text bias": lambda p: npz(p, c=np.array(["a"] * 7)),
        "unknown muscle": lambda p: npz(p, muscles=np.array(["HAMS", "GLU", "TA", "GAS", "RF",
                                                             "VAS", "XYZ"])),
        "six muscles": lambda p: npz(p, muscles=np.array(["HAMS", "GLU", "TA", "GAS", "RF",
                                                          "VAS"])),
        "info not JSON": lambda p: npz(p, info=np.array("{oops")),
        "a text file": lambda p: p.write_text("rate_hz = 1000\n"),
        "an empty file": lambda p: p.write_bytes(b""),
        "a directory": lambda p: p.mkdir(),
        "missing": lambda p: None,
        "2 MB that inflates to 2 GB": lambda p: bomb(p, 2.0),
        "Python objects": lambda p: np.savez(p, **{**a, "info": np.array([{"a": 1}],
                                                                          dtype=object)}),
    }
    rng = np.random.default_rng(13)
    raw = SHIPPED.read_bytes()
    for k in range(12):
        b = bytearray(raw)
        for _ in range(3):
            b[int(rng.integers(0, len(b)))] ^= 1 << int(rng.integers(0, 8))
        nets[f"3 bits flipped ({k})"] = lambda p, b=bytes(b): p.write_bytes(b)
    for name, make in nets.items():
        p = work / f"net-{len(out)}.npz"
        make(p)
        add("network", f"--network: {name}", ["trip", "--controller", "reflex", "--network",
                                               str(p), "--no-video", "--duration", "0.5",
                                               "--out", "o"])
    # touch stages: gains set by hand (reflex fit --set-response), a trunk limit (--max-tilt)
    for spec in ["", "contra.HFL", "contra.HFL=inf", "contra.HFL=-2", "contra.XYZ=1",
                 "nope.HFL=1", "contra.HFL=1,,", "contra=1"]:
        add("touch stage", f"reflex fit --set-response {spec!r}",
            ["reflex", "fit", "--walk-es", "past-foot", "--touch-only", "--touch-response",
             "--trip-set", "wide", "--set-response", spec, "--out", "o"])
    for t in ["nan", "2", "abc", "1e9"]:
        add("touch stage", f"reflex fit --max-tilt {t!r}",
            ["reflex", "fit", "--walk-es", "past-swing", "--touch-only", "--touch-response",
             "--trip-set", "wide", "--max-tilt", t, "--out", "o"])
    # study seeds, grid sizes, time steps, time limits
    for s in [str(2**63), str(2**64), "-1", "1e30", "0:18446744073709551615:2"]:
        add("study seed", f"study --seed {s}", ["study", "--seed", s, "--out", "s"], True)
    for text in [f"seed = {2**63 - 1}\nrepeats = 2\n", "seed = -5\n", f"seed = [1, {2**62}, -1]\n",
                 "repeats = 1000000\n", "repeats = -1\n", "seed = 18446744073709551616\n"]:
        f = work / f"study-{len(out)}.toml"
        f.write_text(text)
        add("study seed", f"study file: {text.strip()!r}", ["study", str(f), "--out", "s"], True)
    for argv in (["--swing", "0.05:0.9:1000", "--speed", "0.7:1.6:1000", "--repeats", "1000"],
                 ["--swing", "0.05:0.9:10000", "--speed", "0.7:1.6:10000"],
                 ["--swing", "0.05:0.9:100000", "--speed", "0.7:1.6:101"],
                 ["--swing", "0.05:0.9:100001"]):
        add("grid size", "study " + " ".join(argv), ["study", *argv, "--out", "s"], True)
    for dt in ["0.0003", "0.0007", "0.0015", "0.0045", "0.0006"]:  # (2 ms: whole ticks)
        add("time step", f"study --controller reflex --timestep {dt}",
            ["study", "--controller", "reflex", "--mechanism", "obstacle", "--timestep", dt,
             "--out", "s"], True)
    for t in ["-1", "nan", "abc", "inf", ""]:
        add("time limit", f"study --run-timeout {t!r}", ["study", "--run-timeout", t,
                                                         "--out", "s"], True)
    # motion files (--gait)
    fifo = work / "fifo.mot"
    os.mkfifo(fifo)
    gaits = {"a FIFO": str(fifo), "/dev/zero": "/dev/zero"}
    for name, times, kw in [("one sample", [0.0], {}),
                            ("frame time 1e-300", [0, 1e-300, 2e-300], {}),
                            ("frame time 1e300", [0, 1e300, 2e300], {}),
                            ("angles of 1e6 deg", np.arange(0, 2, 0.01), {"angle_deg": 1e6}),
                            ("time in ms", np.arange(0, 3000, 10.0), {}),
                            ("NaN angles", np.arange(0, 2, 0.01), {"angle_deg": float("nan")})]:
        p = work / f"gait-{len(gaits)}.mot"
        mot(p, times, **kw)
        gaits[name] = str(p)
    bvh = work / "nothing.bvh"
    bvh.write_text("HIERARCHY\nROOT Foo\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation "
                   "Yrotation\n End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 3\n"
                   "Frame Time: 0.01\n0 0 0\n0 0 0\n0 0 0\n")
    gaits["a BVH whose joints map to nothing"] = str(bvh)
    for name, p in gaits.items():
        add("gait", f"walk --gait {name}", ["walk", "--no-video", "--gait", p, "--out", "o"])
    # study files: random bytes and mutations of a valid one
    valid = b'swing = "0.05:0.75:3"\nspeed = [1.0, 1.2]\nmechanism = ["force", "obstacle"]\n'
    for k in range(20):
        b = bytearray(valid)
        if k % 4 == 0:
            b = bytearray(rng.bytes(int(rng.integers(1, 200))))
        else:
            for _ in range(int(rng.integers(1, 4))):
                i = int(rng.integers(0, len(b)))
                b[i:i + 1] = rng.choice([b"", b"\xff", b"nan", b"-", b"[", b"9" * 25, b'"', b":"])
        f = work / f"fuzz-{k}.toml"
        f.write_bytes(bytes(b))
        add("study file", f"study file mutation {k}", ["study", str(f), "--out", f"s{k}",
                                                       "--workers", "1", "--no-plots"], True)
    return out


def strict_json_ok(directory: Path) -> bool:
    for p in directory.rglob("*.json"):
        try:
            json.loads(p.read_text(), parse_constant=lambda c: (_ for _ in ()).throw(
                ValueError(c)))
        except (ValueError, OSError):
            return False
    return True


def run_case(work: Path, case) -> dict:
    cls, name, argv, fake = case
    cwd = Path(tempfile.mkdtemp(dir=work))
    cmd = ([sys.executable, "-c", FAKE, *argv] if fake
           else [sys.executable, "-m", "stumble.cli", *argv])
    t0 = time.monotonic()
    try:
        r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True,
                           timeout=CASE_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return {"class": cls, "case": name, "result": "hang", "seconds": CASE_TIMEOUT_S}
    err = r.stderr.strip().splitlines()
    if "Traceback (most recent call last)" in r.stderr:
        result = "traceback"
    elif r.returncode == 2 and len(err) == 1 and err[0].startswith("stumble: "):
        result = "error"
    elif r.returncode == 0:
        result = "ok" if strict_json_ok(cwd) else "bad-ok"
    else:
        result = "other"
    return {"class": cls, "case": name, "result": result, "exit": r.returncode,
            "stderr": err[-1][:300] if err else "", "seconds": round(time.monotonic() - t0, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        todo = cases(work)
        with ThreadPoolExecutor(args.jobs) as ex:
            results = list(ex.map(lambda c: run_case(work, c), todo))
    by_class: dict[str, Counter] = defaultdict(Counter)
    for r in results:
        by_class[r["class"]][r["result"]] += 1
    kinds = ["error", "ok", "traceback", "hang", "bad-ok", "other"]
    print(f"{'class':12s} {'cases':>5s} " + " ".join(f"{k:>9s}" for k in kinds))
    total = Counter()
    for cls, c in by_class.items():
        total.update(c)
        print(f"{cls:12s} {sum(c.values()):5d} " + " ".join(f"{c[k]:9d}" for k in kinds))
    print(f"{'all':12s} {sum(total.values()):5d} " + " ".join(f"{total[k]:9d}" for k in kinds))
    for r in results:
        if r["result"] not in ("error", "ok"):
            print(f"  {r['result']}: {r['case']}: {r.get('stderr', '')}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
