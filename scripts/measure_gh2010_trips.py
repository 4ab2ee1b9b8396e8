"""The 45 own-gait obstacle trips of a GH2010 parameter file (``stumble study`` takes none),
or of a network (``--network FILE|NAME``: the seed's controller).

The grid of ``stumble study --controller gh2010 --mechanism obstacle --swing
0.05:0.75:15 --speed 1.0,1.2,1.4`` (10 cm box, the walker's own gait, 3 s after the
trip), run by ``simulate_trip`` in this one process, for a ``gh2010.json`` (or a
shipped set's name, or nothing: the default set); ``--start playback`` trips the
recording instead.
Prints the strategy map (E elevating, L lowering, - neither, x not set; * recovered),
the recoveries of 45 (and the falls, those in the walk-in before the trip apart), the
human strategy in the 30 window trips (elevating at
0.05-0.25, lowering at 0.55-0.75) and the lowering-window recoveries; ``--out FILE``
writes each trip's figures as JSON. ``--grid held-out``: 28 other trips instead, none of
them among the 45 or a trip stage's (swing 0.075-0.725 in steps of 0.05 at 1.1 and
1.3 m/s; the human windows 0.075-0.225 and 0.575-0.725), to check a fit chosen by its
figures on the 45.

Run:  python scripts/measure_gh2010_trips.py [PARAMS | --network FILE|NAME]
      [--start own|playback] [--grid main|held-out] [--delay-scale K]
      [--delays all|response] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from stumble.control.reflex.fit_walk import human_strategy
from stumble.control.reflex.gh2010 import load_params, shipped_params
from stumble.errors import TripNotSet
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario

SWINGS = tuple(round(float(s), 2) for s in np.linspace(0.05, 0.75, 15))
SPEEDS = (1.0, 1.2, 1.4)
GRIDS = {"main": (SWINGS, SPEEDS),
         "held-out": (tuple(round(float(s), 3) for s in np.linspace(0.075, 0.725, 14)),
                      (1.1, 1.3))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("params", nargs="?", default=None)
    ap.add_argument("--out", default=None)
    ap.add_argument("--start", choices=("own", "playback"), default="own",
                    help="the walk tripped: the walker's own (default) or the recording's")
    ap.add_argument("--grid", choices=tuple(GRIDS), default="main",
                    help="the 45 trips (main) or 28 others (held-out)")
    ap.add_argument("--network", default=None, metavar="FILE|NAME",
                    help="trip the seed's network instead (a network.npz or a shipped "
                    "name); not with PARAMS")
    ap.add_argument("--delay-scale", type=float, default=1.0, metavar="K",
                    help="every reflex delay times K, the walk-in's too (Scenario."
                    "delay_scale; default 1), or the touch response's alone (--delays "
                    "response)")
    ap.add_argument("--delays", choices=("all", "response"), default="all",
                    help="what --delay-scale multiplies (Scenario.delays): all (default) "
                    "or response, the touch response's delays alone")
    args = ap.parse_args()
    swings, speeds = GRIDS[args.grid]
    if args.network is not None and args.params is not None:
        ap.error("give PARAMS (a GH2010 set) or --network, not both")
    net = p = None
    if args.network is not None:
        from pathlib import Path

        from stumble.cli import _network_arg

        net = _network_arg(Path(args.network))
    else:
        p = shipped_params("gh2010") if args.params is None else load_params(args.params)
    t0 = time.perf_counter()
    rows = []
    for v in speeds:
        for s in swings:
            sc = Scenario(controller="gh2010" if net is None else "reflex",
                          mechanism="obstacle", swing_fraction=s,
                          speed_m_per_s=v, start=args.start,
                          delay_scale=args.delay_scale, delays=args.delays)
            try:
                summ = simulate_trip(sc, gh2010=p, network=net).summary
                row = {"swing": s, "speed": v, "set": True,
                       "tripped": summ.get("trip_time_s") is not None,
                       "strategy": summ.get("strategy"),
                       "recovered": bool(summ.get("recovered")),
                       "fell": bool(summ.get("fell")),
                       "fell_before_trip": bool(summ.get("fell_before_trip")),
                       "stop_reason": summ.get("stop_reason")}
            except TripNotSet as e:
                row = {"swing": s, "speed": v, "set": False, "strategy": None,
                       "recovered": False, "error": str(e)}
            rows.append(row)
    wall = time.perf_counter() - t0
    print("speed | " + " ".join(f"{s:.2f}" for s in swings))
    for v in speeds:
        cells = []
        for r in (r for r in rows if r["speed"] == v):
            c = ("x" if not r["set"] else {"elevating": "E", "lowering": "L"}.get(
                r["strategy"], "-")) + ("*" if r["recovered"] else "")
            cells.append(f"{c:>4}")
        print(f"{v:5.1f} | " + " ".join(cells))
    window = [r for r in rows if human_strategy(r["swing"]) is not None]
    human = sum(r["strategy"] == human_strategy(r["swing"]) for r in window)
    low = [r for r in rows if human_strategy(r["swing"]) == "lowering"]
    early = [r for r in rows if human_strategy(r["swing"]) == "elevating"]
    rec = sum(r["recovered"] for r in rows)
    figures = {
        "recovered": rec, "of": len(rows),
        "fell": sum(bool(r.get("fell")) for r in rows),
        "fell_in_walk_in": sum(bool(r.get("fell_before_trip")) for r in rows),
        "human_strategy": human, "window_trips": len(window),
        "human_early": sum(r["strategy"] == "elevating" for r in early),
        "human_late": sum(r["strategy"] == "lowering" for r in low),
        "lowering_window_recovered": sum(r["recovered"] for r in low),
        "lowering_window_recovered_by_lowering": sum(
            r["recovered"] and r["strategy"] == "lowering" for r in low),
        "not_set": sum(not r["set"] for r in rows),
        "wall_time_s": round(wall, 1)}
    print(json.dumps(figures))
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"params": args.params, "network": args.network, "figures": figures,
                       "trips": rows}, f, indent=1)


if __name__ == "__main__":
    main()
