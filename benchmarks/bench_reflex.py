"""Speed of one reflex trip against raw MuJoCo stepping of the same model (same process).

Run:  python benchmarks/bench_reflex.py [--swing F] [--contact points|soft]
Prints the trip's wall time, the same number of plain ``mj_step`` calls on the same
planar musculoskeletal model from the same initial state with no controller, their
ratio (issue target ≤ 2) and the trip's speed-up over real time (target ≥ 25). The
network ticks at 1 kHz in Python; the muscles (activation and eq. 1) run in MuJoCo.
"""

from __future__ import annotations

import argparse

from against_raw import time_against_raw

from stumble.trip import Scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--swing", type=float, default=0.13)
    ap.add_argument("--speed", type=float, default=1.2)
    ap.add_argument("--contact", default="points", choices=("points", "soft"))
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=args.swing,
                  speed_m_per_s=args.speed, contact=args.contact, duration_after_trip_s=2.0)
    t = time_against_raw(sc, args.repeats, activation=0.05)
    r, rec = t.result, t.result.recording
    best_trip, best_phys, best_raw = t.trip_s, t.physics_s, t.raw_s
    sim_s = r.summary["sim_time_s"]
    print(f"reflex trip, contact {args.contact}: {rec.steps} steps, {sim_s:.2f} s simulated "
          f"({r.summary['stop_reason']}, {r.summary['strategy']})")
    print(f"trip (network, sensors, recording): {best_trip:.3f} s "
          f"({1e6 * best_trip / rec.steps:.1f} us/step)")
    print(f"raw mj_step, same model and steps:  {best_raw:.3f} s "
          f"({1e6 * best_raw / rec.steps:.1f} us/step)")
    print(f"ratio trip / raw: {best_trip / best_raw:.2f}   (target <= 2)")
    print(f"mj_step inside the trip: {best_phys:.3f} s; network, sensors and recording add "
          f"{best_trip / best_phys - 1:.0%}")
    print(f"faster than real time: {sim_s / best_trip:.1f}x   (target >= 25)")


if __name__ == "__main__":
    main()
