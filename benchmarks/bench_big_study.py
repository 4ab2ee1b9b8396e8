"""Peak memory and time of a very large study: written, summarised and plotted.

Run:  python benchmarks/bench_big_study.py [--runs 1000000] [--out DIR]

The grid (swing × speed × delay scale × repeats, ``--runs`` runs in all, 10^6 by
default) goes through ``stumble study`` as a user runs it (in this process,
``--workers 1``), with the trip itself replaced by a deterministic stand-in summary of
the real one's fields (a real 10^6-run study is some 300 core-hours): what is measured is
the study machinery, its journal, parts, results.parquet, summary table and maps.
Prints the peak resident memory (``ru_maxrss``) after the imports and at the end, the
wall time, and the sizes written.
"""

from __future__ import annotations

import argparse
import math
import resource
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import stumble.pipeline as pipeline
from stumble.cli import main


def fake_summary(sc) -> dict:
    """The fields of a real trip's summary, deterministic in the scenario."""
    fell = sc.delay_scale * sc.swing_fraction >= 0.9
    strategy = "elevating" if sc.swing_fraction <= 0.5 else "lowering"
    return {
        "controller": sc.controller, "strategy": strategy, "variant": "double_support",
        "recovered": not fell, "fell": fell, "diverged": False,
        "swing_fraction": sc.swing_fraction, "speed_m_per_s": sc.speed_m_per_s,
        "mechanism": sc.mechanism, "leg": sc.leg, "obstacle_height_m": None,
        "trip_time_s": 0.8123, "states": [{"name": "passive_reaction", "start_s": 0.0},
                                          {"name": "clearance", "start_s": 0.112}],
        "durations_s": {"recovery_step": round(0.5 + sc.swing_fraction, 4),
                        "trip_to_recovery_contact": 0.61},
        "recovery_step_length_m": 0.6312, "trunk_tilt_at_recovery_contact_deg": 12.31,
        "recovery_contact_s": 0.61, "fall_time_s": 1.2 if fell else None, "rmse_deg": None,
        "sim_time_s": 3.0, "wall_time_s": 1.25, "steps": 3000, "stop_reason": "time",
        "seed": sc.seed, "contact": sc.contact, "delay_scale": sc.delay_scale,
        "strength_scale": sc.strength_scale, "walking_stride_s": 1.1234}


def peak_mb() -> float:
    """Peak resident memory of this process so far, MB (Linux: ru_maxrss in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main_bench() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1_000_000)
    ap.add_argument("--out", type=Path, default=None, help="study directory (default: temp)")
    args = ap.parse_args()
    repeats = max(1, math.ceil(args.runs / (100 * 10 * 10)))
    pipeline.simulate_trip = lambda sc, **kw: SimpleNamespace(summary=fake_summary(sc))
    import pyarrow.parquet as pq

    import stumble.viz.study_plots  # noqa: F401  (counted in the baseline)

    base = peak_mb()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp) / "big"
        t0 = time.perf_counter()
        code = main(["study", "--out", str(out), "--swing", "0.05:0.9:100", "--speed",
                     "0.7:1.6:10", "--delay-scale", "1:2:10", "--repeats", str(repeats),
                     "--workers", "1", "--quiet"])
        wall = time.perf_counter() - t0
        res = out / "results.parquet"
        meta = pq.ParquetFile(res).metadata
        parts = list((out / "runs").glob("part-*.parquet"))
        print(f"exit {code}; {meta.num_rows} rows x {meta.num_columns} columns in "
              f"results.parquet ({res.stat().st_size / 2**20:.0f} MB, {meta.num_row_groups} "
              f"row groups); {len(parts)} parts")
        print(f"wall time {wall:.0f} s ({1e6 * wall / meta.num_rows:.0f} us per run)")
        print(f"peak memory: {base:.0f} MB after the imports, {peak_mb():.0f} MB at the end")


if __name__ == "__main__":
    main_bench()
