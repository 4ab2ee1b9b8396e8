"""Speed of state-machine trips against a bare loop that replays their controls (same process).

Run:  python benchmarks/bench_trip.py [--contact lumped|points|penalty|soft] [--repeats N]
      [--timestep S] [--duration S] [--cases all|one] [--recovery walk_on|step]

For each case (an elevating and a lowering trip, force and obstacle, at 1.2 m/s, the
scenario's default duration unless ``--duration``), it runs the whole ``simulate_trip``
``--repeats`` times after a warm-up (the walk cached, imports done), keeping every
block's controls, servo gains and trip forces, and replays them on the same model from
the same first state with a bare loop that does nothing else (``against_raw.bare_replay``:
one ``mj_step`` with nstep per block). It prints, as the minimum over the repeats:

- the trip's run loop (controller, sensors, recording, physics) and the bare replay,
  and their ratio (issue 10: at most 1.3);
- the trip's speed over real time (issue 10: at least 20×);
- the whole warm ``simulate_trip`` (build, walk from cache, run, analysis; issue 10:
  at most 0.3 s for a 3 s trip: ``--duration 3``);
- the replay's end state against the trip's (0: the same physics, step for step).

Ratios matter more than seconds: other work on the machine slows both sides alike, and
the CPU-time ratio (this process' own time, ``time.process_time``) is the least
sensitive to it. The load average is printed before and after.
"""

from __future__ import annotations

import argparse
import os

from against_raw import time_against_replay

from stumble.trip import Scenario

CASES = ((0.2, "force"), (0.65, "force"), (0.2, "obstacle"), (0.65, "obstacle"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--contact", default="lumped",
                    choices=("lumped", "points", "penalty", "soft"))
    ap.add_argument("--speed", type=float, default=1.2)
    ap.add_argument("--timestep", type=float, default=None, help="default: the scenario's")
    ap.add_argument("--duration", type=float, default=None, help="default: the scenario's")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--strength", choices=("fixed", "anderson2007"), default="fixed",
                    help="the servos' torque limits (Scenario.strength_model)")
    ap.add_argument("--cases", choices=("all", "one"), default="all")
    ap.add_argument("--recovery", choices=("walk_on", "step"), default="walk_on",
                    help="Scenario.recovery: walk_on (the default, 6 s after the trip) or "
                    "step (the run stops 1 s after the recovery step)")
    args = ap.parse_args()
    print(f"load average before {os.getloadavg()[0]:.2f}; contact {args.contact}")
    print(f"{'case':24s} {'sim s':>6s} {'loop s':>7s} {'replay s':>8s} {'ratio':>6s} "
          f"{'cpu ratio':>9s} {'x real':>7s} {'x real cpu':>10s} {'whole s':>8s} "
          f"{'end diff':>8s}")
    worst = {"ratio": 0.0, "cpu_ratio": 0.0, "speedup": float("inf"),
             "cpu_speedup": float("inf"), "whole": 0.0}
    for f, mech in CASES[:1] if args.cases == "one" else CASES:
        given = {k: v for k, v in (("timestep_s", args.timestep),
                                   ("duration_after_trip_s", args.duration)) if v is not None}
        sc = Scenario(swing_fraction=f, mechanism=mech, speed_m_per_s=args.speed,
                      strength_model=args.strength, recovery=args.recovery,
                      contact=args.contact, **given)
        t = time_against_replay(sc, args.repeats)
        s = t.result.summary
        ratio, speedup = t.trip_s / t.replay_s, s["sim_time_s"] / t.trip_s
        cpu_ratio, cpu_speedup = t.trip_cpu_s / t.replay_cpu_s, s["sim_time_s"] / t.trip_cpu_s
        now = {"ratio": ratio, "cpu_ratio": cpu_ratio, "speedup": speedup,
               "cpu_speedup": cpu_speedup, "whole": t.simulate_trip_s}
        worst = {k: (min if "speedup" in k else max)(worst[k], now[k]) for k in worst}
        name = f"{s['strategy']} {mech} {f}"
        print(f"{name:24s} {s['sim_time_s']:6.2f} {t.trip_s:7.3f} {t.replay_s:8.3f} "
              f"{ratio:6.2f} {cpu_ratio:9.2f} {speedup:7.1f} {cpu_speedup:10.1f} "
              f"{t.simulate_trip_s:8.3f} {t.replay_error_m:8.1e}  ({s['stop_reason']})")
    print(f"worst: trip / bare replay {worst['ratio']:.2f} wall, {worst['cpu_ratio']:.2f} CPU "
          f"(target <= 1.3); {worst['speedup']:.1f}x real time wall, "
          f"{worst['cpu_speedup']:.1f}x CPU (target >= 20); whole simulate_trip "
          f"{worst['whole']:.3f} s")
    print(f"load average after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
