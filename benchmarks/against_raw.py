"""Shared by the trip benchmarks: a trip's wall time beside raw ``mj_step`` of its model
(``time_against_raw``) or beside a bare loop replaying its recorded controls
(``time_against_replay``)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

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


_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def bare_replay(model: mujoco.MjModel, rec) -> tuple[float, float, mujoco.MjData]:
    """Step ``model`` from the trip's first state along its recorded controls, servo
    gains, torque limits and trip forces (``simulate_trip(..., log_controls=True)``),
    doing nothing else: held controls as one ``mj_step`` with nstep per block, a forced
    step one at a time.
    Returns the wall and CPU times (s) and the final data."""
    m = model
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, rec.initial_state, _FULL)
    mujoco.mj_forward(m, d)
    forces = {step: (body, row) for step, body, row in (rec.forces or [])}
    last_forced = max(forces, default=-1)
    blocks = rec.controls
    ends = [b[0] for b in blocks[1:]] + [rec.steps]
    gain, bias, limit = m.actuator_gainprm, m.actuator_biasprm, m.actuator_forcerange
    pool = mj_rollout.Rollout(nthread=0)
    nstate = mujoco.mj_stateSize(m, _FULL)
    cpu0 = time.process_time()
    t0 = time.perf_counter()
    for (first, ctrl, (g, b, lim)), end in zip(blocks, ends, strict=True):
        gain[:, 0] = g
        bias[:, :3] = b
        limit[:] = lim  # the servos' torque limits (human strength, refreshed by the trip)
        n = end - first
        if ctrl.ndim == 2:  # per-step controls: natively, as the trip steps them
            state = np.empty((1, nstate))
            mujoco.mj_getState(m, d, state[0], _FULL)
            states = np.empty((1, n, nstate))
            pool.rollout_.rollout([m], [d], n, int(mujoco.mjtState.mjSTATE_CTRL), state,
                                  d.qacc_warmstart[None].copy(), ctrl.reshape(1, n, m.nu),
                                  states, None, None)
            mujoco.mj_setState(m, d, states[0, -1], _FULL)
            continue
        d.ctrl[:] = ctrl
        if not forces or not any(s in forces for s in range(first, end)):
            if forces and first > last_forced:
                d.xfrc_applied[:] = 0.0  # the trip switched its force off here
            mujoco.mj_step(m, d, n)
            continue
        for s in range(first, end):
            if s in forces:
                body, row = forces[s]
                d.xfrc_applied[body] = row
            mujoco.mj_step(m, d)
    return time.perf_counter() - t0, time.process_time() - cpu0, d


@dataclass
class ReplayTiming:
    """Min-of-N wall times (s) of one scenario against its bare replay."""

    trip_s: float  # the run loop: controller, sensors, recording, physics
    physics_s: float  # of which inside MuJoCo
    replay_s: float  # the bare loop along the same controls, gains and forces
    trip_cpu_s: float  # the run loop's CPU time (less sensitive to other load)
    replay_cpu_s: float
    simulate_trip_s: float  # the whole simulate_trip call (build, walk, run, analysis)
    replay_error_m: float  # max |qpos| difference at the end, trip vs replay
    result: TripResult


def time_against_replay(sc: Scenario, repeats: int) -> ReplayTiming:
    """Run the trip ``repeats`` times (after one warm-up), each time with its bare replay;
    the minimum of each figure."""
    simulate_trip(sc)  # warm: imports, the walk, the model build path
    best = [float("inf")] * 6
    err = 0.0
    r = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = simulate_trip(sc, log_controls=True)
        whole = time.perf_counter() - t0
        rec = r.recording
        replay, replay_cpu, d = bare_replay(r.body.model, rec)
        err = float(np.abs(d.qpos - rec.qpos[-1]).max())
        best = [min(b, v) for b, v in zip(best, (
            rec.wall_time_s, rec.physics_time_s, replay, rec.cpu_time_s, replay_cpu, whole),
            strict=True)]
    return ReplayTiming(best[0], best[1], best[2], best[3], best[4], best[5], err, r)
