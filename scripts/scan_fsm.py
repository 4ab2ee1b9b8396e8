"""Scan one state-machine parameter over values on issue 11's grid (reproducible, 2 cores).

For a parameter set (a shipped name or a file, ``stumble trip --params``) and one
tunable name (``fsm_params.TUNABLE``) or push-off cap (``fsm_params.CAP_SETTINGS``, N·m
on the reference body, e.g. ``push_off_rec_hip_limit_nm``), each value runs the 48-trip
grid (force and obstacle, swing 0.05-0.75, 1.0/1.2/1.4 m/s) walking on 6 s after the trip
(the default ``recovered``), and prints:

- the trips walked on, and of them those with the trunk within 26° at recovery-foot
  contact (van den Bogert et al. 2002);
- flight against double support as ``stumble validate`` counts it
  (``stumble.validate.people_fly``): the recovered window trips at 1.4 m/s that fly, by
  strategy, and the recovered trips at 1.0 m/s that fly (people: none);
- the median recovery step of those elevating window flights (toe-off to heel contact;
  SCA 2009 §5.1: 0.59 s in the motion capture, 0.65 s in the paper's simulation), and
  of the lowering window flights the median time from the trip to the recovery leg's
  contact (SCA 2009 §5.2: 0.57 s and 0.72 s);
- the support limb's push-off over the grid's nine mid-swing obstacle trips (as
  ``stumble validate`` reads it: peak hip extension, knee flexion and ankle plantarflexion
  in the first 300 ms, medians in N·m; Pijnappels et al. 2005: 52, 54 and 204);
- the walks on that never settle (``tune_fsm.unsettled``: no steady gait within the 6 s,
  or a heading more than ``tune_fsm.HEADING_LIMIT_DEG`` from the walk before);
- with ``--bodies``, the six bodies' 96 trips at 1.2 m/s walked on (issue 11: at least
  90 %), those within 26°, the largest trunk tilt at recovery-foot contact among them,
  and their walks on that never settle.

Each value's figures are appended to ``--out`` (JSON lines) as soon as they are measured.
Deterministic: the same set, name and values give the same figures.

Run:  python scripts/scan_fsm.py --params upright --name elev_sup_ankle_fast
      --values=-3,-5,-6,-8 [--bodies] [--strength fixed|anderson2007] [--workers 2]
      [--out scan.jsonl]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

from stumble.control.fsm_params import CAP_SETTINGS, TUNABLE, check_setting, load_params
from stumble.errors import InputError
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario
from stumble.validate import (
    PUSH_OFF_MECHANISM,
    PUSH_OFF_NM,
    PUSH_OFF_SWING,
    TRUNK_TILT_MAX_DEG,
    people_fly,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from tune_fsm import BODY_GRID, FULL_GRID, unsettled  # the searches' own grids and test

WALK_ON_S = 6.0
_JOB: dict = {}


def _init(params: str, name: str, strength: str) -> None:
    _JOB.update(params=params, name=name, strength=strength)


def _trip(job: tuple) -> dict:
    """One trip of the grid with the set and the value (``job``: value, grid point)."""
    value, (f, v, mech, *body) = job
    p = load_params(_JOB["params"])
    p = (replace(p, **{_JOB["name"]: value}) if _JOB["name"] in CAP_SETTINGS
         else p.with_values({_JOB["name"]: value}))
    kw = {} if not body else {"height_m": body[0], "mass_kg": body[1], "sex": body[2]}
    s = simulate_trip(Scenario(swing_fraction=f, speed_m_per_s=v, mechanism=mech,
                               recovery="walk_on", duration_after_trip_s=WALK_ON_S,
                               strength_model=_JOB["strength"], **kw),
                      params=p).summary
    return {"value": value, "swing": f, "speed": v, "mechanism": mech, "body": body,
            "recovered": bool(s["recovered"]), "strategy": s["strategy"],
            "variant": s["variant"], "tilt": s["trunk_tilt_at_recovery_contact_deg"],
            "recovery_step_s": s["durations_s"]["recovery_step"],
            "trip_to_recovery_contact_s": s["durations_s"]["trip_to_recovery_contact"],
            "push_off_nm": s.get("support_peak_moments_nm") or {},
            "unsettled": unsettled(s)}


def figures(value: float, rows: list[dict]) -> dict:
    """The scan's figures for one value from its trips."""
    grid = [r for r in rows if not r["body"]]
    rec = [r for r in grid if r["recovered"]]
    within = [r for r in rec if r["tilt"] is not None and r["tilt"] <= TRUNK_TILT_MAX_DEG]
    out = {"value": value, "grid_walked_on": len(rec), "grid_within_26": len(within),
           "of": len(grid), "largest_tilt_deg": max((r["tilt"] or 0.0 for r in rec),
                                                    default=None),
           "grid_unsettled": sum(r["unsettled"] for r in rec)}
    for strategy in ("elevating", "lowering"):
        win = [r for r in rec if r["strategy"] == strategy
               and people_fly(r["speed"], strategy, r["swing"])]
        out[f"flight_1.4_{strategy}"] = [sum(r["variant"] == "flight" for r in win), len(win)]
    slow = [r for r in rec if people_fly(r["speed"], r["strategy"], r["swing"]) is False]
    out["flight_1.0"] = [sum(r["variant"] == "flight" for r in slow), len(slow)]
    steps = [r["recovery_step_s"] for r in rec if r["variant"] == "flight"
             and r["strategy"] == "elevating" and r["recovery_step_s"] is not None
             and people_fly(r["speed"], "elevating", r["swing"])]  # validate's window
    out["elevating_flight_step_s"] = (round(statistics.median(steps), 3) if steps else None)
    lows = [r["trip_to_recovery_contact_s"] for r in rec if r["variant"] == "flight"
            and r["strategy"] == "lowering" and r["trip_to_recovery_contact_s"] is not None
            and people_fly(r["speed"], "lowering", r["swing"])]  # SCA 2009 §5.2's duration
    out["lowering_flight_contact_s"] = (round(statistics.median(lows), 3) if lows else None)
    lo, hi = PUSH_OFF_SWING
    nine = [r for r in grid if r["mechanism"] == PUSH_OFF_MECHANISM
            and lo - 1e-9 <= r["swing"] <= hi + 1e-9]
    out["push_off_median_nm"] = {
        name: (round(statistics.median(vals), 1) if vals else None)
        for name, _mean in PUSH_OFF_NM
        for vals in [[r["push_off_nm"][name] for r in nine
                      if r["push_off_nm"].get(name) is not None]]}
    bodies = [r for r in rows if r["body"]]
    if bodies:
        out["bodies_walked_on"] = sum(r["recovered"] for r in bodies)
        out["bodies_within_26"] = sum(r["recovered"] and r["tilt"] is not None
                                      and r["tilt"] <= TRUNK_TILT_MAX_DEG for r in bodies)
        out["bodies_of"] = len(bodies)
        out["bodies_largest_tilt_deg"] = max((r["tilt"] or 0.0 for r in bodies
                                              if r["recovered"]), default=None)
        out["bodies_unsettled"] = sum(r["unsettled"] for r in bodies)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", default="upright", help="a shipped set or a file")
    ap.add_argument("--name", required=True, help="a tunable name (fsm_params.TUNABLE) or a "
                    "push-off cap (fsm_params.CAP_SETTINGS, N·m on the reference body)")
    ap.add_argument("--values", required=True, help="comma-separated values")
    ap.add_argument("--bodies", action="store_true", help="also the six bodies' 96 trips")
    ap.add_argument("--strength", choices=("fixed", "anderson2007"), default="fixed",
                    help="the servos' torque limits (Scenario.strength_model; the sets "
                    "tuned on human strength are anderson2007_walk_on and anderson2007)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None, help="append each value's figures (JSON lines)")
    args = ap.parse_args()
    try:
        if args.name not in TUNABLE and args.name not in CAP_SETTINGS:
            raise InputError(f"--name {args.name!r} is not a tunable name or a push-off cap "
                             f"({', '.join(CAP_SETTINGS)})")
        try:
            values = [float(x) for x in args.values.split(",")]
        except ValueError:
            raise InputError(f"--values {args.values!r} is not a comma-separated list of "
                             "numbers") from None
        if args.name in CAP_SETTINGS:
            for x in values:
                check_setting(args.name, x, "--values")
        else:
            lo, hi = TUNABLE[args.name][1:]
            bad = [x for x in values if not lo <= x <= hi]
            if bad:
                raise InputError(f"--values {bad[0]:g} is outside {args.name}'s "
                                 f"{lo:g}-{hi:g}")
        load_params(args.params)
    except InputError as e:
        sys.exit(f"scan_fsm: {e}")
    grid = FULL_GRID + (BODY_GRID if args.bodies else [])
    with ProcessPoolExecutor(args.workers, initializer=_init,
                             initargs=(args.params, args.name, args.strength)) as ex:
        for value in values:
            t0 = time.perf_counter()
            rows = list(ex.map(_trip, [(value, g) for g in grid], chunksize=2))
            fig = {"params": args.params, "strength": args.strength, "name": args.name,
                   **figures(value, rows),
                   "wall_s": round(time.perf_counter() - t0, 1)}
            print(json.dumps(fig), flush=True)
            if args.out:
                with open(args.out, "a") as fh:
                    fh.write(json.dumps(fig) + "\n")


if __name__ == "__main__":
    main()
