"""Crash safety of a study: SIGKILL it several times, finish it, compare with a clean run.

Run:  python scripts/kill_test.py [--kills 5] [--seed 13]

A real study (force and obstacle trips at 6 instants and 3 speeds, 36 trips of 1 s of
physics each, 2 local workers) is started with ``stumble study`` and killed with SIGKILL
at random moments (seeded), ``--kills`` times; after each kill the rows stored are counted
(``load_results``) and the next session must find every one of them done ("N done
before"). It then runs to the end, and the same study runs uninterrupted in another
directory: the two results.parquet must hold the same rows, bit for bit, but the wall
times and the checksums (which cover them).
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from stumble.study.store import load_results

ARGS = ["--swing", "0.1:0.6:6", "--speed", "1.0,1.2,1.4", "--mechanism", "force,obstacle",
        "--duration", "1",
        "--workers", "2", "--quiet", "--no-plots"]
WALL = {"wall_time_s", "run_wall_time_s", "checksum"}


def study(out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "stumble.cli", "study", "--out", str(out),
                             *ARGS], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=5)
    ap.add_argument("--seed", type=int, default=13)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        out, clean = Path(tmp) / "killed", Path(tmp) / "clean"
        lost, stored_log = 0, []
        stored = 0
        for k in range(args.kills):
            p = study(out)
            time.sleep(float(rng.uniform(4.0, 8.0)))
            p.kill()
            _, err = p.communicate()
            before = int(re.search(r"(\d+) done before", err).group(1)) if "done before" in \
                err else stored
            lost += max(0, stored - before)
            stored = len(load_results(out))
            stored_log.append(stored)
            print(f"kill {k + 1}: {before} found done at the start, {stored} stored after "
                  "the kill")
        p = study(out)
        _, err = p.communicate()
        before = int(re.search(r"(\d+) done before", err).group(1))
        lost += max(0, stored - before)
        print(f"final session: {before} found done, exit {p.returncode}")
        q = study(clean)
        q.communicate()
        a = pq.read_table(out / "results.parquet").to_pylist()
        b = pq.read_table(clean / "results.parquet").to_pylist()
        same = [{k: v for k, v in r.items() if k not in WALL} for r in a] == [
            {k: v for k, v in r.items() if k not in WALL} for r in b]
        print(f"{args.kills} SIGKILLs; rows lost: {lost}; {len(a)} rows; identical to the "
              f"uninterrupted study (but wall times): {same}")


if __name__ == "__main__":
    main()
