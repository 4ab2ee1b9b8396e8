"""Throughput of a small study with 1 and with 2 workers: trips per second, parallel efficiency.

Run:  python benchmarks/bench_study.py [--swing SPEC] [--speed SPEC] [--workers 1,2]
      [--recovery walk_on|step]

The study (default: force trips at 8 instants from 0.05 to 0.75 of swing, at 1.0 and
1.3 m/s, 16 trips; ``--recovery`` the scenarios' rule: walk_on, the default, runs 6 s
after each trip, step stops 1 s after the recovery step, as every trip did before
2026-12-03) runs end to end as ``stumble study`` runs it, into a fresh directory
each time: with 1 worker in this process, with N > 1 in a process pool; the best of
``--repeats`` runs counts. Every run starts with an empty in-memory walk cache, so each
worker loads its own walks as in a real study, from the on-disk cache
(``stumble.gait.walk_cache``) as a user's second study would (``STUMBLE_CACHE_DIR=off``
to compute them).
Parallel efficiency = (trips/s with N workers) / (N × trips/s with 1). The load average
is printed too: other work on the machine lowers the figures.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from stumble.gait import walk_cache
from stumble.study.grid import Grid, parse_values
from stumble.study.runner import run_study


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--swing", default="0.05:0.75:8")
    ap.add_argument("--speed", default="1.0,1.3")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    ap.add_argument("--repeats", type=int, default=2, help="best of this many (default 2)")
    ap.add_argument("--recovery", choices=("walk_on", "step"), default="walk_on")
    args = ap.parse_args()
    scenarios = Grid({"swing": parse_values("swing", args.swing),
                      "speed": parse_values("speed", args.speed),
                      "recovery": [args.recovery]}).scenarios()
    counts = [int(w) for w in args.workers.split(",")]
    print(f"{len(scenarios)} trips; {os.cpu_count()} cores; load average before "
          f"{os.getloadavg()[0]:.2f}")
    rates = {}
    for n in counts:
        wall = float("inf")
        for _ in range(args.repeats):
            walk_cache.body_and_walk.cache_clear()  # each run loads its walks (forks inherit it)
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                res = run_study(scenarios, Path(tmp) / "s", workers=n, progress=False)
                wall = min(wall, time.perf_counter() - t0)
                rows = list(res.rows)  # read before the directory goes
        errors = sum(bool(r["error"]) for r in rows)
        rates[n] = len(scenarios) / wall
        sim = sum(r.get("sim_time_s") or 0.0 for r in rows)
        print(f"{n} worker(s): {wall:6.1f} s, {rates[n]:.2f} trips/s, "
              f"{sim / wall:.1f} s simulated per s, {errors} errors")
    base = rates.get(1)
    for n in counts:
        if base and n > 1:
            print(f"parallel efficiency with {n} workers: {rates[n] / (n * base):.2f}"
                  "   (target >= 0.9)")
    print(f"load average after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
