"""Speed of the reflex controllers against the engine's limit (run on demand).

Run:  python benchmarks/bench_reflex.py [--repeats N] [--parts]

For a reflex trip (CASE 1 of seed 003: obstacle at 0.13 of swing, 1.2 m/s; the network
the default one, ``past-support`` since 2026-12-07 (``past-swing`` and
``placement-both`` before, the same walk), and the open-loop one for comparison with the figures
before 2026-12-04) and a 10 s and a 20 s walk of each reflex controller (``network``:
the default one, from the 1.2 m/s walk, and the closed-loop one, the default before, for
comparison; ``gh2010``, the default set, ``knee-2ms-dense-wide-s3`` at its 2 ms since
2026-12-05, and ``knee``, the default before, at its 1 ms), it
times the whole ``sim.run`` loop and a bare loop that replays the recorded controls on
the same model from the same state after the controller's start, doing nothing else
(``mj_step`` per control row): the physical limit of this engine for that motion. CPU
time of this process, best of N, so that other work on the machine matters less.
With ``--broad-phase`` it prints instead the bare replay of 10 s walks on the model as
built against its twin whose floor contacts go through MuJoCo's broad phase
(``broad_phase``). With ``--parts`` it prints instead where a block's time goes, for the
network's CASE 1 trip and 10 s walk and Geyer & Herr's: wall time per block (µs, over
all blocks) of the network's blocks run natively (``ReflexController.run_blocks``:
several blocks, the physics included, in one compiled call), and of the blocks run one
by one: the controller's update and its one compiled call in it (``kernels.net_update``
/ ``gh_update``), its sensing (``observe``), the physics block
(``sim._Stepper.advance``); then the recording (``_Buffers.extend``), the stop rule, and
the whole loop (each part timed around its call, which adds about a microsecond a call).
Prints per run: steps (of 1 or 2 ms: the network runs at 2 ms by default since
2026-12-04, at 1 ms for comparison; the default GH2010 set was fitted at 2 ms),
simulated seconds, µs per step of each, their ratio (the
issue's targets: at most 1.5× for the network) and the speed-up over real time (10 s
walk and trip: 50×; 20 s walk: 25×), beside the bare replay's own: the most this engine
allows for that motion.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

import stumble.pipeline as pipeline
from stumble.sim import run as sim_run
from stumble.trip import Scenario


def _logged(*a, **k):
    k["log_controls"] = True
    return sim_run(*a, **k)


def replay_cpu_s(result, rec=None, end_qpos: list | None = None) -> float:
    """CPU seconds of a bare loop replaying the recorded controls (of ``rec``, default the
    result's recording); appends the end state's ``qpos`` to ``end_qpos`` if given."""
    rec, m = rec or result.recording, result.body.model
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, rec.initial_state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ends = [*[s for s, _c, _g in rec.controls][1:], rec.steps]
    t0 = time.process_time()
    for (first, ctrl, (gain, bias, _limits)), end in zip(rec.controls, ends, strict=True):
        m.actuator_gainprm[:, 0] = gain
        m.actuator_biasprm[:, :3] = bias
        rows = np.atleast_2d(ctrl)
        for k in range(end - first):
            d.ctrl[:] = rows[min(k, len(rows) - 1)]
            mujoco.mj_step(m, d)
    took = time.process_time() - t0
    if end_qpos is not None:
        end_qpos.append(d.qpos.copy())
    return took


def measure(label: str, make, repeats: int, whole: bool = False) -> None:
    """Best-of-N CPU time of a run and of its bare replay; ``whole``: an own-gait trip
    (``simulate_trip``: the walk to the trip and the trip, set-up included) against the
    bare replay of both runs."""
    pipeline.run = _logged
    best_run = best_raw = float("inf")
    result = None
    for _ in range(repeats):
        t0 = time.process_time()
        result = make()
        best_run = min(best_run, time.process_time() - t0)
        best_raw = min(best_raw, replay_cpu_s(result) + (
            replay_cpu_s(result, result.walk_recording) if whole else 0.0))
    pipeline.run = sim_run
    runs = [result.recording, *([result.walk_recording] if whole else [])]
    sim_s = sum(float(r.time_s[-1]) for r in runs)
    steps = sum(r.steps for r in runs)
    dt_ms = 1e3 * result.body.model.opt.timestep
    last = (("recovered" if result.summary["recovered"] else "not recovered") if whole
            else f"loop wall {result.recording.wall_time_s:.2f} s")  # (wall, the last run)
    print(f"{label:40s} {steps:6d} steps of {dt_ms:g} ms {sim_s:5.2f} s simulated | run "
          f"{1e6 * best_run / steps:6.1f} us/step, bare replay "
          f"{1e6 * best_raw / steps:6.1f} us/step, ratio {best_run / best_raw:4.2f} | "
          f"{sim_s / best_run:5.1f}x real time, the bare replay {sim_s / best_raw:5.1f}x "
          f"({last})")


def parts() -> None:
    """Where a block's time goes (``--parts``; module docstring)."""
    import collections

    import stumble.analysis as analysis
    import stumble.sim as sim
    from stumble.control.reflex.controller import ReflexController
    from stumble.control.reflex.gh2010 import GH2010Controller
    from stumble.control.reflex.kernels import kernels

    took: collections.Counter = collections.Counter()
    calls: collections.Counter = collections.Counter()
    kern = kernels() or {}
    undo = []

    def timed(owner, name, key, setter=setattr, getter=getattr):
        f = getter(owner, name)

        def g(*a, **k):
            t0 = time.perf_counter()
            out = f(*a, **k)
            took[key] += time.perf_counter() - t0
            calls[key] += 1
            return out
        setter(owner, name, g)
        undo.append((owner, name, f, setter))

    for cls in (ReflexController, GH2010Controller):
        timed(cls, "update", "update")
        timed(cls, "observe", "observe")
    for cls in (ReflexController, GH2010Controller):
        def natively(self, *a, _f=cls.run_blocks):  # blocks and their physics in one call
            t0 = time.perf_counter()
            got = _f(self, *a)
            if got is not None:
                took["blocks run natively (run_blocks)"] += time.perf_counter() - t0
                calls["native"] += got[3]
            return got
        undo.append((cls, "run_blocks", cls.run_blocks, setattr))
        cls.run_blocks = natively
    for name in ("net_update", "gh_update"):
        if name in kern:
            timed(kern, name, "one compiled call (in update)", dict.__setitem__,
                  dict.__getitem__)
    timed(sim._Stepper, "advance", "physics block (advance)")
    timed(sim._Buffers, "extend", "recording (extend)")
    timed(analysis.StopRule, "__call__", "stop rule")
    timed(analysis.StopRule, "block", "stop rule (bulk)")
    case1 = Scenario(controller="reflex", start="playback", mechanism="obstacle",
                     swing_fraction=0.13, speed_m_per_s=1.2, duration_after_trip_s=3.0)
    runs = (("network, CASE 1 trip", lambda: pipeline.simulate_trip(case1).recording),
            ("network, 10 s walk", lambda: pipeline.simulate_walk(
                "network", 10.0, speed_m_per_s=1.2).recording),
            ("gh2010, CASE 1 trip", lambda: pipeline.simulate_trip(case1.with_(
                controller="gh2010", start="playback")).recording),
            ("gh2010, 10 s walk", lambda: pipeline.simulate_walk("gh2010", 10.0).recording))
    print("wall time per block (µs), each part timed around its call")
    for label, run in runs:
        run()  # warm: caches, compiled kernels
        took.clear()
        calls.clear()
        rec = run()
        n = calls["update"] + calls["native"]  # blocks
        print(f"{label} ({rec.steps} steps in {n} blocks, {calls['native']} of them "
              "natively):")
        for key, v in took.items():
            print(f"  {key:36s} {1e6 * v / n:7.1f}")
        print(f"  {'the whole loop':36s} {1e6 * rec.wall_time_s / n:7.1f}")
    for owner, name, f, setter in undo:
        setter(owner, name, f)


def broad_phase(repeats: int) -> None:
    """The bare replay of 10 s walks on the model as built (the feet's and segments'
    collisions with the floor as explicit pairs) and on its twin that leaves them to
    MuJoCo's broad phase (``compile_body(world_pairs=False)``): µs per step, best of N,
    the two alternating; the end states must agree to the bit."""
    import dataclasses

    from stumble.body.build import compile_body

    pipeline.run = _logged
    for kind, kw in (("network", {"speed_m_per_s": 1.2}), ("gh2010", {})):
        result = pipeline.simulate_walk(kind, 10.0, **kw)
        b = result.body
        twin = compile_body(b.planar, b.height_m, b.mass_kg, b.sex, b.contact,
                            float(b.model.opt.timestep), actuation="muscles",
                            muscle_set=b.muscle_set, world_pairs=False)
        masks = dataclasses.replace(result, body=twin)
        best = {"pairs": float("inf"), "broad phase": float("inf")}
        ends: list = []
        for _ in range(repeats):
            for key, res in (("pairs", result), ("broad phase", masks)):
                best[key] = min(best[key], replay_cpu_s(res, end_qpos=ends))
        if not all(np.array_equal(e, ends[0]) for e in ends):
            raise SystemExit(f"{kind}: the two models' end states differ")
        steps = result.recording.steps
        print(f"10 s walk ({kind}), {steps} steps of {1e3 * b.model.opt.timestep:g} ms: "
              + ", ".join(f"{k} {1e6 * v / steps:5.2f} us/step" for k, v in best.items())
              + f"; the pairs take {best['pairs'] / best['broad phase']:.3f} of the time")
    pipeline.run = sim_run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--parts", action="store_true",
                    help="where a block's time goes (see the module docstring)")
    ap.add_argument("--broad-phase", action="store_true",
                    help="the bare replay with the floor's contacts as explicit pairs "
                         "(as built) against MuJoCo's broad phase (see broad_phase)")
    args = ap.parse_args()
    if args.parts:
        return parts()
    if args.broad_phase:
        return broad_phase(args.repeats)
    print("CPU time of this process, best of", args.repeats, "(the run includes building "
          "the body and the walk's set-up; the walk before is cached)")
    sc = Scenario(controller="reflex", start="playback", mechanism="obstacle", swing_fraction=0.13,
                  speed_m_per_s=1.2, duration_after_trip_s=3.0)
    pipeline.simulate_trip(sc)  # warm the walk cache
    measure("reflex trip (network), CASE 1", lambda: pipeline.simulate_trip(sc), args.repeats)
    at1 = sc.with_(timestep_s=0.001)
    pipeline.simulate_trip(at1)
    measure("reflex trip (network, 1 ms), CASE 1", lambda: pipeline.simulate_trip(at1),
            args.repeats)
    from stumble.control.reflex.identify import default_network

    open_loop = default_network("open-loop")
    pipeline.simulate_trip(sc, network=open_loop)
    measure("reflex trip (open-loop network), CASE 1",
            lambda: pipeline.simulate_trip(sc, network=open_loop), args.repeats)
    # from the recording, as the seed's CASE 1 (its own-gait default would add the 4 s
    # walk-in to the run's time, not to its steps)
    gh = sc.with_(controller="gh2010", start="playback")
    pipeline.simulate_trip(gh)
    measure("reflex trip (gh2010), CASE 1", lambda: pipeline.simulate_trip(gh), args.repeats)
    # the default until 2026-12-05 (``knee``), fitted at 1 ms, at its own step
    from stumble.control.reflex.gh2010 import load_params

    knee = load_params("knee")
    pipeline.simulate_trip(gh, gh2010=knee)
    measure("reflex trip (gh2010 knee, 1 ms), CASE 1",
            lambda: pipeline.simulate_trip(gh, gh2010=knee), args.repeats)
    # whole trips in the walker's own gait (both reflex controllers' default start): the
    # walk to the trip (4 s and the swing) and 3 s after it, 0.10 of swing at 1.2 m/s
    own = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.10,
                   speed_m_per_s=1.2, start="own")
    for label, sc_own, kw in (("own-gait trip (network)", own, {}),
                              ("own-gait trip (gh2010)", own.with_(controller="gh2010"), {}),
                              ("own-gait trip (gh2010 knee, 1 ms)",
                               own.with_(controller="gh2010"), {"gh2010": knee})):
        pipeline.simulate_trip(sc_own, **kw)
        measure(label, lambda s=sc_own, k=kw: pipeline.simulate_trip(s, **k), args.repeats,
                whole=True)
    # the walks: GH2010 from the recording's speed; the default network and the
    # closed-loop one, from the 1.2 m/s walk (the open-loop network falls within a
    # second), at the default step (2 ms) and at 1 ms, the step before 2026-12-04
    net, closed = default_network(), default_network("closed-loop")
    for kind, label, kw in (
            ("network", "network", {"network": net, "speed_m_per_s": 1.2}),
            ("network", "network, 1 ms", {"network": net, "speed_m_per_s": 1.2,
                                          "timestep_s": 0.001}),
            ("network", "closed-loop network", {"network": closed, "speed_m_per_s": 1.2}),
            ("gh2010", "gh2010", {}),
            ("gh2010", "gh2010 knee, 1 ms", {"params": knee})):
        pipeline.simulate_walk(kind, 1.0, **kw)
        for dur in (10.0, 20.0):
            measure(f"{dur:.0f} s walk ({label})",
                    lambda k=kind, t=dur, kw=kw: pipeline.simulate_walk(k, t, **kw),
                    args.repeats)


if __name__ == "__main__":
    main()
