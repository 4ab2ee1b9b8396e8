"""Probe the support hip's push-off moment of the state machines (issue 11): the
controller patched, nothing built (docs/fsm-fits.md, sixteenth session).

Each design is a JSON object of:

- ``gain``: the support hip's k_p times this in the push-off states (Clearance, Leg
  Swap), for ``window`` s from their start (default: all of them), then as before;
- ``rec_cap``: the recovery hip's servo moment capped at this many N·m (reference body)
  in the push-off states (Passive Reaction, Clearance, Leg Swap): since the seventeenth
  session the parameter ``FSMParams.push_off_rec_hip_limit_nm``, no longer a patch;
- ``ref_deg``: the pelvis attitude's reference moved this many degrees anterior of its
  tilt at the trip (negative: posterior);
- ``knee_cap``: the support knee's servo moment capped at this many N·m in the push-off
  states (``FSMParams.push_off_sup_knee_limit_nm``, eighteenth session);
- ``sup_cap``: the support hip's servo moment capped at this many N·m in the push-off
  states (``FSMParams.push_off_hip_limit_nm``);
- ``states``: ``"pre_landing"`` applies the caps in every state before the recovery foot
  lands (``fsm.PRE_LANDING_STATES``: the push-off's, Flight and Fall), not only the
  push-off's;
- ``set``: the shipped parameter set the design starts from (default ``flight``).

Runs the 48-trip grid (force and obstacle, 0.05-0.75 of swing, 1.0/1.2/1.4 m/s; the
``flight`` set unless ``set`` names another, walking on 6 s) on 2 processes and prints
the trips walked on and the support limb's median peak moments over the nine mid-swing
obstacle trips of ``stumble validate``'s rows (0.25-0.45 of swing).

Run:  python scripts/probe_push_off.py DESIGN [DESIGN ...]
      e.g. python scripts/probe_push_off.py '{}' '{"gain": 0.5}' '{"rec_cap": 150}'
           python scripts/probe_push_off.py '{"set": "hip_cap", "knee_cap": 80}'
"""

from __future__ import annotations

import json
import math
import multiprocessing as mp
import sys
from dataclasses import replace

import numpy as np

from stumble.control import fsm as F
from stumble.control.fsm_params import load_params
from stumble.errors import InputError
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario

SWINGS = (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75)
GRID = [(mech, f, v) for mech in ("force", "obstacle") for f in SWINGS
        for v in (1.0, 1.2, 1.4)]
KEYS = {"gain", "window", "rec_cap", "ref_deg", "knee_cap", "sup_cap", "states", "set"}
DESIGN: dict = {}
_start, _write = F.TripFSM.start, F.TripFSM._write
PUSH_OFF = F.PUSH_OFF_STATES


def start(self, ctx) -> None:
    _start(self, ctx)
    if DESIGN.get("ref_deg"):
        self.att_ref = (self.att_ref[0] - math.radians(DESIGN["ref_deg"]), self.att_ref[1])
        self._write(ctx)


def write(self, ctx) -> None:
    st, t = self._state, ctx.sensors.t
    gain = DESIGN.get("gain")
    if gain is not None and st in ("clearance", "leg_swap"):
        i = self.bank.index[f"hip_flexion_{self.roles['sup']}"]
        if getattr(self, "_probe_key", None) != (st, i):  # the state's own k_p
            self._probe_key, self._probe_kp, self._probe_t0 = (st, i), float(self.kp[i]), t
        inside = t - self._probe_t0 < DESIGN.get("window", math.inf)
        want = self._probe_kp * (gain if inside else 1.0)
        if self.kp[i] != want:
            self.kp[i], self._gains_dirty = want, True
    _write(self, ctx)


def run(job):
    design, (mech, f, v) = job
    DESIGN.clear()
    DESIGN.update(design)
    F.PUSH_OFF_STATES = (F.PRE_LANDING_STATES if design.get("states") == "pre_landing"
                         else PUSH_OFF)
    params = load_params(design.get("set", "flight"))
    for key, field in (("rec_cap", "push_off_rec_hip_limit_nm"),
                       ("knee_cap", "push_off_sup_knee_limit_nm"),
                       ("sup_cap", "push_off_hip_limit_nm")):
        if key in design:
            params = replace(params, **{field: design[key]})
    s = simulate_trip(Scenario(mechanism=mech, swing_fraction=f, speed_m_per_s=v),
                      params=params).summary
    pk = s.get("support_peak_moments_nm") or {}
    return (mech, f, bool(s.get("recovered")), pk.get("hip_extension"),
            pk.get("knee_flexion"), pk.get("ankle_plantarflexion"))


def main(argv: list[str]) -> int:
    designs = []
    for arg in argv:
        try:
            d = json.loads(arg)
        except json.JSONDecodeError as e:
            raise InputError(f"design {arg!r} is not JSON: {e.msg}") from None
        if not isinstance(d, dict) or set(d) - KEYS:
            raise InputError(f"design {arg!r}: a JSON object of {', '.join(sorted(KEYS))}")
        designs.append(d)
    F.TripFSM.start, F.TripFSM._write = start, write
    with mp.get_context("fork").Pool(2) as pool:
        for d in designs:
            out = pool.map(run, [(d, g) for g in GRID])
            mid = [o for o in out if o[0] == "obstacle" and 0.25 - 1e-9 <= o[1] <= 0.45 + 1e-9]
            med = [round(float(np.median([o[k] for o in mid]))) for k in (3, 4, 5)]
            print(json.dumps(d), f"walked on {sum(o[2] for o in out)} of 48; mid-swing "
                  f"obstacle trips' hip/knee/ankle {med[0]}/{med[1]}/{med[2]} N·m", flush=True)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except InputError as e:
        sys.exit(f"probe_push_off: {e}")
