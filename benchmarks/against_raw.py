"""Shared by the trip benchmarks: a trip's wall time beside raw ``mj_step`` of its model."""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco

from stumble.pipeline import TripResult, simulate_trip
from stumble.trip import Scenario


@dataclass
class Timing:
    """Best-of-N wall times (s) of one scenario."""

    trip_s: float  # the whole loop: controller, sensors, recording, physics
    physics_s: float  # of which inside mj_step
    raw_s: float  # the same number of plain mj_step calls, no controller
    result: TripResult


def time_against_raw(sc: Scenario, repeats: int, activation: float = 0.0) -> Timing:
    """Run the trip ``repeats`` times, and each time as many raw steps of the same model
    from the same initial state (muscle activations set to ``activation``)."""
    best = [float("inf")] * 3
    r = None
    for _ in range(repeats):
        r = simulate_trip(sc)
        rec = r.recording
        m = r.body.model
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:] = rec.qpos[0], rec.qvel[0]
        d.act[:] = activation
        t0 = time.perf_counter()
        for _ in range(rec.steps):
            mujoco.mj_step(m, d)
        raw = time.perf_counter() - t0
        best = [min(best[0], rec.wall_time_s), min(best[1], rec.physics_time_s),
                min(best[2], raw)]
    return Timing(best[0], best[1], best[2], r)
