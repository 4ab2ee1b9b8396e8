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
- ``set``: the shipped parameter set the design starts from (default ``flight``);
- ``targets``: ``{state: {joint: degrees}}`` merged into the set's ``targets_deg`` (e.g.
  ``{"clearance_elevating": {"rec.hip_flexion": 60}}``; ``"sup.hip_flexion": 0`` is
  SCA 2009 §4.5's literal push-off target instead of the pelvis attitude);
- ``fields``: ``{FSMParams field: value}`` replaced in the set (e.g. ``{"kc_fast": 45}``);
- ``ankle_k``: N·m per rad of the pelvis's forward tilt past its reference added to the
  support ankle's plantarflexion in the push-off states (negative: dorsiflexion), in
  every state before the recovery foot lands with ``"ankle_states": "pre_landing"``, of
  the torso's forward pitch past its tilt at the trip with ``"ankle_torso": true``;
- ``ext_only``: the support hip's cap (``sup_cap``) limits extension only, flexion free;
- ``lumbar_deg``: the walk before the trip played with the lumbar extended this many
  degrees more than the recording (the trunk more upright; its walks cached apart, in
  ``$STUMBLE_CACHE_DIR``'s ``lumbar_<deg>`` directory). One value per invocation: the
  designs of one run must share it.

Runs the 48-trip grid (force and obstacle, 0.05-0.75 of swing, 1.0/1.2/1.4 m/s; the
``flight`` set unless ``set`` names another, walking on 6 s) on 2 processes and prints
the trips walked on and the support limb's median peak moments over the nine mid-swing
obstacle trips of ``stumble validate``'s rows (0.25-0.45 of swing).

Run:  python scripts/probe_push_off.py DESIGN [DESIGN ...]
      e.g. python scripts/probe_push_off.py '{}' '{"gain": 0.5}' '{"rec_cap": 150}'
           python scripts/probe_push_off.py '{"set": "hip_cap", "knee_cap": 80}'
"""

from __future__ import annotations

import copy
import json
import math
import multiprocessing as mp
import os
import sys
from dataclasses import replace

import numpy as np

from stumble.control import fsm as F
from stumble.control.fsm_params import FSMParams, load_params
from stumble.errors import InputError
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario

SWINGS = (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75)
GRID = [(mech, f, v) for mech in ("force", "obstacle") for f in SWINGS
        for v in (1.0, 1.2, 1.4)]
KEYS = {"gain", "window", "rec_cap", "ref_deg", "knee_cap", "sup_cap", "states", "set",
        "targets", "fields", "ankle_k", "ankle_states", "ankle_torso", "ext_only",
        "lumbar_deg"}
DESIGN: dict = {}
_start, _write, _cap = F.TripFSM.start, F.TripFSM._write, F.TripFSM._cap_servo
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
    k = DESIGN.get("ankle_k")
    states = F.PRE_LANDING_STATES if DESIGN.get("ankle_states") == "pre_landing" else PUSH_OFF
    if k and st in states:
        if DESIGN.get("ankle_torso"):
            ahead = self.torso_ref - F.attitude_of(self._torso_xmat)[0]
        else:
            ahead = self.att_ref[0] - F.attitude_of(self._pelvis_xmat)[0]
        i = self.bank.index[f"ankle_angle_{self.roles['sup']}"]
        self._ctrl[i] -= k * max(0.0, ahead) / max(self.kp[i], 1e-6)  # + plantarflexion


def cap_servo(self, target, name, cap_nm, attitude_only=False) -> None:
    if not (DESIGN.get("ext_only") and attitude_only):
        _cap(self, target, name, cap_nm, attitude_only)
        return
    i, b = self.bank.index[name], self.bank
    kp = b.gain_scale * self.kp[i]
    if self.mode[i] != F.ATT_PITCH or kp <= 0.0:
        return
    kd = b.kd_over_kp * kp
    q, qd = float(self._qpos[b.qadr[i]]), float(self._qvel[b.vadr[i]])
    c = cap_nm * b.gain_scale
    if kp * (target[i] - q) - kd * qd < -c:  # extension past the cap
        target[i] = q + (-c + kd * qd) / kp


def lumbar_walk(deg: float) -> None:
    """Play the walk before the trip with the lumbar ``deg`` more extended, cached apart."""
    from stumble.gait import reference, walk_cache

    base = walk_cache.cache_dir()
    if base is not None:
        os.environ[walk_cache.CACHE_ENV] = str(base / f"lumbar_{deg:g}")
    angles = reference.ReferenceGait.angles

    def extended(self, phase, names=None, hip_scale=1.0):
        out = angles(self, phase, names, hip_scale)
        if "lumbar_extension" in out:
            out["lumbar_extension"] = out["lumbar_extension"] + math.radians(deg)
        return out
    reference.ReferenceGait.angles = extended


def run(job):
    design, (mech, f, v) = job
    DESIGN.clear()
    DESIGN.update(design)
    F.PUSH_OFF_STATES = (F.PRE_LANDING_STATES if design.get("states") == "pre_landing"
                         else PUSH_OFF)
    params = load_params(design.get("set", "flight"))
    if design.get("targets"):
        targets = copy.deepcopy(params.targets_deg)
        for state, joints in design["targets"].items():
            targets.setdefault(state, {}).update(joints)
        params = replace(params, targets_deg=targets)
    if design.get("fields"):
        params = replace(params, **design["fields"])
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
        fields = d.get("fields", {})
        if not isinstance(fields, dict) or set(fields) - set(FSMParams.__dataclass_fields__):
            raise InputError(f"design {arg!r}: fields must name FSMParams fields")
        targets = d.get("targets", {})
        if not (isinstance(targets, dict)
                and all(isinstance(v, dict) for v in targets.values())):
            raise InputError(f"design {arg!r}: targets is {{state: {{joint: degrees}}}}")
        designs.append(d)
    lumbar = {d.get("lumbar_deg", 0.0) for d in designs}
    if len(lumbar) > 1:
        raise InputError("the designs of one run must share lumbar_deg")
    if lumbar and (deg := lumbar.pop()):
        lumbar_walk(float(deg))
    F.TripFSM.start, F.TripFSM._write, F.TripFSM._cap_servo = start, write, cap_servo
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
