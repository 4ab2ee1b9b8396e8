"""Speed of one FSM trip against raw MuJoCo stepping of the same model (same process).

Run:  python benchmarks/bench_trip.py [--swing F] [--speed V] [--contact points|penalty|soft]
Prints the trip's physics wall time, the same number of plain ``mj_step`` calls on the
same model from the same initial state with no controller, their ratio (target ≤ 1.3)
and the trip's speed-up over real time (target ≥ 20). Without a controller the body
collapses and has fewer foot contacts, so that ratio also measures different physics;
the time spent inside ``mj_step`` during the trip gives the controller's own overhead.
"""

from __future__ import annotations

import argparse

from against_raw import time_against_raw

from stumble.trip import Scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--swing", type=float, default=0.2)
    ap.add_argument("--speed", type=float, default=1.2)
    ap.add_argument("--contact", default="points", choices=("points", "penalty", "soft"))
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    sc = Scenario(swing_fraction=args.swing, speed_m_per_s=args.speed, contact=args.contact,
                  duration_after_trip_s=2.0)
    t = time_against_raw(sc, args.repeats)
    r, rec = t.result, t.result.recording
    best_trip, best_phys, best_raw = t.trip_s, t.physics_s, t.raw_s
    sim_s = r.summary["sim_time_s"]
    print(f"contact {args.contact}: {rec.steps} steps, {sim_s:.2f} s simulated "
          f"({r.summary['stop_reason']})")
    print(f"trip (controller, sensors, recording): {best_trip:.3f} s")
    print(f"raw mj_step, same model and steps:     {best_raw:.3f} s")
    print(f"ratio trip / raw: {best_trip / best_raw:.2f}   (target <= 1.3)")
    print(f"mj_step inside the trip: {best_phys:.3f} s; controller, sensors and recording "
          f"add {best_trip / best_phys - 1:.0%}")
    print(f"faster than real time: {sim_s / best_trip:.1f}x   (target >= 20)")


if __name__ == "__main__":
    main()
