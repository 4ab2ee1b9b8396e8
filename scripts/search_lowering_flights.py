"""CMA-ES over the lowering strategy's values on its 18 trips alone, for lowering flights.

Run:  python scripts/search_lowering_flights.py --around FILE --out FILE [--seed S]
      [--generations N] [--flight W] [--sigma S]

The first step of the ``flight_from_fall`` set (issue 11; docs/fsm-fits.md, "Lowering
flights"). It searches what ``tune_fsm.py --only lowering_flight --flight-targets``
searches (the lowering strategy's targets, its Fall's offsets at fast walking, its
push and its Flight table), with the same ranges and start, but on the 18 lowering
trips alone (force and obstacle at 0.55/0.65/0.75 of swing, 1.0/1.2/1.4 m/s, walking on
6 s) and with its own score: each trip walked on with the trunk within 26° at
recovery-foot contact counts 1, a lowering flight that walks on at 1.4 m/s W more, and
any lowering flight at 1.0 m/s W less (people keep double support there; SCA 2009
Table 1). Unlike ``tune_fsm.py`` it has no time-survived tie-break. ``--out`` is
rewritten with the best so far at every improvement (a ``--params`` file).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import tune_fsm as T  # the search spaces and their ranges

from stumble.control.fsm_params import load_params
from stumble.errors import InputError
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario

NAMES = list(dict.fromkeys((*T.LOWERING, *T.LOWERING_FAST, *T.LOWERING_FLIGHT)))
RANGES = {k: T.TUNABLE[k][1:] for k in NAMES}
TRIPS = [(mech, f, v) for f, v, mech in T.LOWERING_GRID]  # tune_fsm.py --grid lowering's
MAX_TILT_DEG = 26.0  # van den Bogert et al. 2002 (issue 11)
_BASE = None


def values_of(u: np.ndarray) -> dict:
    """The searched values (their units) of a point of the unit cube."""
    return {k: RANGES[k][0] + float(np.clip(ui, 0, 1)) * (RANGES[k][1] - RANGES[k][0])
            for k, ui in zip(NAMES, u, strict=True)}


def run(job) -> tuple[bool, bool, float]:
    """(walked on within the tilt, a lowering flight, speed) of one trip under a point."""
    u, (mech, f, v) = job
    s = simulate_trip(Scenario(mechanism=mech, swing_fraction=f, speed_m_per_s=v),
                      params=_BASE.with_values(values_of(u))).summary
    tilt = s["trunk_tilt_at_recovery_contact_deg"]
    ok = bool(s["recovered"]) and tilt is not None and tilt <= MAX_TILT_DEG
    return ok, s["variant"] == "flight" and s["strategy"] == "lowering", v


def score(res, weight: float) -> float:
    """Trips walked on, W more per lowering flight walked on at 1.4 m/s, W less per
    lowering flight at 1.0 m/s."""
    out = 0.0
    for ok, fl, v in res:
        out += ok
        if v == 1.4 and fl and ok:
            out += weight
        if v == 1.0 and fl:
            out -= weight
    return out


def main() -> None:
    global _BASE
    from cmaes import CMA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--around", required=True, help="the start, a --params file")
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--generations", type=int, default=13)
    ap.add_argument("--flight", type=float, default=3.0, help="W (default 3)")
    ap.add_argument("--sigma", type=float, default=0.1,
                    help="initial step, a fraction of each range (default 0.1)")
    args = ap.parse_args()
    try:
        start = json.loads(Path(args.around).read_text())
        if not isinstance(start, dict) or not isinstance(start.get("params"), dict):
            raise InputError("not a parameter file (no \"params\" object)")
        _BASE = load_params(args.around)
    except (OSError, ValueError, InputError) as e:
        sys.exit(f"search_lowering_flights: --around {args.around}: {e}")
    out_dir = Path(args.out).resolve().parent
    if not out_dir.is_dir():
        sys.exit(f"search_lowering_flights: --out {args.out}: no directory {out_dir}")
    if args.generations < 1 or not args.sigma > 0 or not args.flight >= 0:
        sys.exit("search_lowering_flights: --generations must be >= 1, --sigma > 0, "
                 "--flight >= 0")
    v0 = _BASE.values()
    x0 = np.array([(v0[k] - RANGES[k][0]) / (RANGES[k][1] - RANGES[k][0])
                   for k in NAMES]).clip(0, 1)
    es = CMA(mean=x0, sigma=args.sigma, bounds=np.array([[0, 1]] * len(NAMES)),
             seed=args.seed, population_size=12)
    best = (-1e9, "")
    t0 = time.time()
    with mp.get_context("fork").Pool(2) as pool:
        for g in range(args.generations):
            us = [es.ask() for _ in range(es.population_size)]
            out = pool.map(run, [(u, t) for u in us for t in TRIPS])
            told = []
            for i, u in enumerate(us):
                res = out[i * len(TRIPS):(i + 1) * len(TRIPS)]
                sc = score(res, args.flight)
                told.append((u, -sc))
                if sc > best[0]:
                    fast = [r for r in res if r[2] == 1.4]
                    what = (f"walked on {sum(r[0] for r in res)} of 18; at 1.4 m/s "
                            f"{sum(r[0] for r in fast)}, {sum(r[0] and r[1] for r in fast)} "
                            f"of them flights; flights at 1.0 m/s "
                            f"{sum(r[1] for r in res if r[2] == 1.0)}")
                    best = (sc, what)
                    Path(args.out).write_text(json.dumps({
                        "note": f"search_lowering_flights.py {' '.join(sys.argv[1:])}: "
                                f"generation {g}: {what}",
                        "params": {**start["params"], **values_of(u)},
                        "settings": start.get("settings", {})}, indent=1))
            es.tell(told)
            print(f"gen {g} best of gen {-min(s for _, s in told):.1f} overall "
                  f"{best[0]:.1f} {best[1]} ({time.time() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
