"""Measure a state-machine design for issue 11 (one process, one core).

A design is ``baseline`` (FSMParams' own values, the ``step`` set) or a JSON object of
FSMParams fields on them (``kp_support_hip`` sets ``kp_passive["support_hip"]``). Runs
validate's eight window trips (obstacle, 0.05-0.75 of swing, 1.1 m/s; under the 1 s
rule, as validate ran them before 2026-12-03) and the 48-trip grid (force and obstacle,
0.05-0.75 of swing, 1.0/1.2/1.4 m/s) under the 1 s rule and walking on 6 s, and
prints the recoveries, the support limb's median peak moments in the first 300 ms and
the largest trunk tilt at recovery-foot contact over the recoveries.

Run:  python scripts/measure_fsm_designs.py DESIGN OUT.json
      e.g. python scripts/measure_fsm_designs.py '{"trunk_attitude": 0.3}' t03.json
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace

from stumble.control.fsm_params import FSMParams
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario

SWINGS = (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75)
GRID = [(mech, f, v) for mech in ("force", "obstacle") for f in SWINGS for v in (1.0, 1.2, 1.4)]
WINDOW = [("obstacle", f, 1.1) for f in SWINGS]
KEYS = ("strategy", "recovered", "fell", "trunk_tilt_at_recovery_contact_deg",
        "support_peak_moments_nm", "recovery_contact_s", "steps_after_recovery_step")


def design(name: str) -> FSMParams:
    p = FSMParams()
    if name == "baseline":
        return p
    kw = json.loads(name)
    if "kp_support_hip" in kw:
        p.kp_passive["support_hip"] = kw.pop("kp_support_hip")
    return replace(p, **kw)


def trips(cases, params, **extra) -> list[dict]:
    out = []
    for mech, f, v in cases:
        s = simulate_trip(Scenario(mechanism=mech, swing_fraction=f, speed_m_per_s=v,
                                   **extra), params=params).summary
        out.append({"mech": mech, "swing": f, "speed": v, **{k: s[k] for k in KEYS}})
    return out


def summarise(res: dict) -> str:
    def med(rows, k):
        v = sorted(r["support_peak_moments_nm"][k] for r in rows
                   if r["support_peak_moments_nm"])
        return f"{v[len(v) // 2]:.0f} ({v[0]:.0f}-{v[-1]:.0f})" if v else "n/a"

    out = [f"design {res['design']} ({res['wall_s']} s)"]
    for key in ("window", "grid_step", "grid_walk"):
        rows = res[key]
        rc = [r for r in rows if r["recovered"]]
        tilts = [r["trunk_tilt_at_recovery_contact_deg"] for r in rc
                 if r["trunk_tilt_at_recovery_contact_deg"] is not None]
        pool = rows if key == "window" else rc  # validate: every window trip's moments
        out.append(f" {key}: recovered {len(rc)}/{len(rows)}; hip ext {med(pool, 'hip_extension')}"
                   f", knee flex {med(pool, 'knee_flexion')}, ankle pf "
                   f"{med(pool, 'ankle_plantarflexion')}; largest tilt "
                   f"{max(tilts) if tilts else 'n/a'}")
    return "\n".join(out)


def main(name: str, out: str) -> None:
    t0, p = time.time(), design(name)
    res = {"design": name, "window": trips(WINDOW, p, recovery="step"),
           "grid_step": trips(GRID, p, recovery="step"),
           "grid_walk": trips(GRID, p, recovery="walk_on", duration_after_trip_s=6.0)}
    res["wall_s"] = round(time.time() - t0, 1)
    with open(out, "w") as fh:
        json.dump(res, fh, indent=1)
    print(summarise(res))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
