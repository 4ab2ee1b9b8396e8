"""The finite-state-machine trip controllers of SCA 2009 §4.3-4.6 (elevating, lowering).

Elevating: Passive Reaction → Clearance → Flight → Single Support After Trip, or
Clearance → Fall → Double Support → Single Support After Trip when the stance foot
stays down and the COM starts to fall. Lowering: Passive Reaction → Leg Swap →
Clearance (legs swap roles) → the same ending. After Single Support After Trip the
person walks on (ours; SCA 2009 ends at the recovery step): ``step_reach`` places the
swing foot with SIMBICON's balance feedback (Yin et al. 2007), and at its touch-down the
legs swap for ``step_swing``, and so on; with ``walk_on_push_s`` a double support,
``step_push``, comes first, in which the trailing leg pushes off.

Every state sets, per joint, a PD target and gain (``stumble.control.pd``). The change
from Passive Reaction into the reaction states reaches each joint after that joint's
muscle-response latency plus 50 ms (SCA 2009 §4.3); later transitions act at once,
on contact and COM events. The stance hip holds the pelvis attitude in the world; the
support ankle adds the compensation torque of SCA 2009 eq. 4 during Clearance.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numpy as np

from stumble.control.fsm_params import ATTITUDE_DAMPING, FSMParams
from stumble.control.pd import ServoBank
from stumble.errors import InputError
from stumble.sim import CONTROL_HZ, Context

FIXED, HOLD, ATT_PITCH, ATT_ROLL = 0, 1, 2, 3
OTHER = {"r": "l", "l": "r"}
# the support leg's push-off, from the trip until the recovery foot lands or both feet
# are off (FSMParams.push_off_hip_limit_nm, push_off_rec_hip_limit_nm,
# push_off_sup_knee_limit_nm), and the states
# before the recovery foot lands (FSMParams.trunk_attitude)
PUSH_OFF_STATES = ("passive_reaction", "clearance", "leg_swap")
PRE_LANDING_STATES = (*PUSH_OFF_STATES, "flight", "fall")
TRUNK_RELEASE_S = 0.3  # trunk_attitude: the lumbar's return to its held angle (ours)


@dataclass(order=True)
class _Pending:
    time_s: float
    seq: int
    state: str = field(compare=False)
    key: str = field(compare=False)


def pelvis_attitude(data) -> tuple[float, float]:
    """Pelvis tilt (about −y, + posterior) and list (about +x) in the world, rad."""
    return attitude_of(data.xmat[1])


def attitude_of(xmat: np.ndarray) -> tuple[float, float]:
    """Tilt and list (rad) of a body from its world rotation matrix (9,), row-major."""
    zx, zy, zz = float(xmat[2]), float(xmat[5]), float(xmat[8])  # its z axis in the world
    return math.atan2(-zx, zz), math.atan2(-zy, zz)


class TripFSM:
    """SCA 2009 trip controller for one scenario; ``strategy`` elevating or lowering.

    ``params`` None: FSMParams' own values (the ``step`` set); a trip without parameters
    gets the shipped default set from ``control.make.trip_controller``."""

    name = "fsm"

    def __init__(self, strategy: str, tripped_side: str, speed_m_per_s: float,
                 params: FSMParams | None = None):
        self.p = (params or FSMParams()).at_speed(speed_m_per_s)
        if self.p.attitude_damping not in ATTITUDE_DAMPING:
            raise InputError(f"attitude damping {self.p.attitude_damping!r} is not one of "
                             f"{', '.join(ATTITUDE_DAMPING)}")
        self.strategy = strategy
        self.tripped = tripped_side
        self.kc = self.p.kc(speed_m_per_s, strategy)
        self.speed = speed_m_per_s  # the walk before the trip, m/s
        # the speed the walk on aims for: the walk's, but not below the floor
        self._walk_on_aim = max(speed_m_per_s, self.p.walk_on_speed_floor_m_per_s)
        self.log: list[tuple[str, float]] = []
        self._state = "walking"

    # ------------------------------------------------------------------ set-up
    def start(self, ctx: Context) -> None:
        """Take over at the trip: hold the current pose, schedule the reactions."""
        self.period_steps = max(1, round(1.0 / (CONTROL_HZ * ctx.model.opt.timestep)))
        self.bank = ServoBank(ctx.body, scaling=self.p.body_scaling)
        if self.p.body_scaling == "dynamic":  # SIMBICON's feedback in body lengths
            self.p = self.p.scaled_to(ctx.body.height_m)
        self._cache_views(ctx)
        nu = len(self.bank.names)
        self.mode = np.full(nu, HOLD)
        self.target = self.bank.angles(ctx.data).copy()
        self.kp = self.bank.kp.copy()
        self.att_ref = (pelvis_attitude(ctx.data)[0], 0.0)  # keep the tilt, level the list
        self.torso_ref = attitude_of(self._torso_xmat)[0]  # trunk_attitude's reference
        self._trunk_last: tuple[float, float] | None = None  # its last (t, lumbar target)
        self.pending: list[_Pending] = []
        self._seq = 0
        if self.strategy == "elevating":
            self.roles = {"rec": self.tripped, "sup": OTHER[self.tripped]}
        else:
            self.roles = {"trip": self.tripped, "sup": OTHER[self.tripped],
                          "rec": OTHER[self.tripped]}
        self.roles.update({"arm_c": OTHER[self.tripped], "arm_i": self.tripped})
        self._enter("passive_reaction", 0.0)
        self._apply_state_targets("passive_reaction", ctx.data)
        self._set_base_gains(recovery=False)
        # the swing knee carries no torque in Passive Reaction (SCA 2009 §4.3, Perry 1992)
        self._set_kp(f"knee_angle_{self.tripped}", 0.0)
        if self.strategy == "elevating":
            self._schedule_reactions("clearance_elevating", "elev.")
            self.t_extend = self.p.delay("elev.rec.knee_extend")
            self.t_react = min(self.p.delay(k) for k in self.p.latency_s
                               if k.startswith(("elev.", "sup.")))
        else:
            self._schedule_reactions("leg_swap", "low.")
            self.t_react = min(self.p.delay(k) for k in self.p.latency_s
                               if k.startswith("low."))
        for key in self.p.arms_deg["response"]:
            self._schedule("arms.response", key, self.p.delay("arms"))
        self.t_state = 0.0
        self.left_floor = {"r": False, "l": False}
        self._arms_walking = False
        self._walk_on_landings = 0  # walk-on landings so far (the speed terms' ramp)
        self._extended = False
        if self.strategy == "lowering":
            self.t_extend = float("inf")
        # where the trip stopped the swing foot: the recovery foot must pass it (+ margin)
        self.trip_point_x = self._toe_x(ctx, self.tripped)
        self._sup_off_s: float | None = None  # flight_from_fall: the support foot left
        self._flight_from_fall = False  # Flight entered from Fall
        self._crossed = False  # lowering: the tripped leg's swing has passed the obstacle
        self._write(ctx)

    def _cache_views(self, ctx: Context) -> None:
        """Views of the MuJoCo arrays read at every update, and the ids they are read at
        (name look-ups cost microseconds; MjData's arrays never move)."""
        m, d = ctx.model, ctx.data
        self._qpos, self._ctrl, self._qvel = d.qpos, d.ctrl, d.qvel
        self._att_prev = (-1.0, 0.0, 0.0)  # (t, tilt, list) at the last update
        self._xpos, self._site_xpos = d.xpos, d.site_xpos
        self._pelvis_xmat = d.xmat[m.body("pelvis").id]
        self._torso_xmat = d.xmat[m.body("torso").id]
        self._foot_id = {s: m.body(f"foot_{s}").id for s in OTHER}
        self._toe_sites = {s: np.array([m.site(n).id for n in ctx.body.foot_points[s][-6:]])
                           for s in OTHER}
        self._on = {"r": True, "l": True}
        self._gains_dirty = True
        self._att_dirty = True
        self._att: list[tuple[int, bool, float]] = []

    def _role_joint(self, key: str) -> str:
        role, joint = key.split(".", 1)
        return f"{joint}_{self.roles[role]}"

    def _set_kp(self, joint: str, kp: float) -> None:
        i = self.bank.index[joint]
        self.kp[i] = kp
        self._gains_dirty = True

    def _set_base_gains(self, recovery: bool) -> None:
        """SCA 2009 §4.5 gains; ×1.5 once recovery starts; upper body high gains."""
        p, f = self.p, (self.p.recovery_gain_factor if recovery else 1.0)
        for name, i in self.bank.index.items():
            if name.startswith("hip_flexion"):  # the hip that holds the attitude supports
                support = self.mode[i] == ATT_PITCH
                kp = p.kp_passive["support_hip" if support else "swing_hip"] * f
            elif name.startswith("hip_adduction"):
                kp = self._adduction_kp(i)
            elif name.startswith("hip_rotation"):
                kp = p.kp_hip_out_of_plane
            elif name.startswith("knee_angle"):
                kp = p.kp_passive["knee"] * f
            elif name.startswith("knee_rotation"):
                kp = p.kp_knee_rotation
            elif name.startswith("ankle_angle"):
                kp = p.kp_passive["ankle"] * f
            elif name.startswith("subtalar"):
                kp = p.kp_subtalar
            elif name.startswith("mtp"):
                kp = p.kp_passive["mtp"] * f
            else:
                key = name.split("_")[0]
                key = "pro_sup" if name.startswith("pro_sup") else key
                kp = p.kp_upper[key]
            self.kp[i] = kp
        self._gains_dirty = True

    # ------------------------------------------------------------------ commands
    def _command(self, state: str, key: str, data) -> None:
        """Apply one role-keyed target of a state to its joint now."""
        table = (self.p.arms_deg[state.split(".")[1]] if state.startswith("arms.")
                 else self.p.targets_deg[state])
        value = table[key]
        joint = self._role_joint(key)
        i = self.bank.index[joint]
        self._att_dirty = True
        if value == "hold":
            self.mode[i], self.target[i] = HOLD, float(data.qpos[self.bank.qadr[i]])
        elif value == "attitude":
            self.mode[i] = ATT_PITCH if "flexion" in joint else ATT_ROLL
        else:
            self.mode[i], self.target[i] = FIXED, np.radians(float(value))
        if joint.startswith("hip_adduction") and self.kp[i] != self._adduction_kp(i):
            self._set_kp(joint, self._adduction_kp(i))

    def _adduction_kp(self, i: int) -> float:
        """A hip adduction's gain: the stance hip's while it holds the pelvis's list, the
        swing hip's otherwise (``kp_stance_hip_roll``, ``kp_hip_out_of_plane``)."""
        p = self.p
        return p.kp_stance_hip_roll if self.mode[i] == ATT_ROLL else p.kp_hip_out_of_plane

    def _schedule(self, state: str, key: str, at_s: float) -> None:
        self._seq += 1
        heapq.heappush(self.pending, _Pending(at_s, self._seq, state, key))

    def _schedule_reactions(self, state: str, prefix: str) -> None:
        """Each joint of ``state`` switches after its latency (+50 ms, SCA 2009 §4.3)."""
        for key in self.p.targets_deg[state]:
            lat = prefix + key
            if lat in self.p.latency_s:
                at = self.p.delay(lat)
            elif key in self.p.latency_s:
                at = self.p.delay(key)
            else:
                at = min(self.p.delay(k) for k in self.p.latency_s if k.startswith(prefix))
            self._schedule(state, key, at)

    def _apply_state_targets(self, state: str, data) -> None:
        """Apply every target of a state now."""
        for key in self.p.targets_deg[state]:
            self._command(state, key, data)

    def _enter(self, state: str, t: float) -> None:
        self._state = state
        self.t_state = t
        self.log.append((state, round(t, 4)))

    def _switch(self, state: str, t: float, data, recovery_gains: bool = True,
                cancel: bool = True, targets: str | None = None) -> None:
        """An event-driven transition: cancel pending reactions, apply the targets now."""
        if cancel:
            self.pending = [p for p in self.pending if p.state.startswith("arms.")]
            heapq.heapify(self.pending)
        self._enter(state, t)
        self._apply_state_targets(targets or state, data)
        self._set_base_gains(recovery=recovery_gains)

    # ------------------------------------------------------------------ update
    def update(self, ctx: Context) -> None:
        """Run due reactions, take event transitions, refresh attitude and compensation
        (writes ctrl and gains, held until the next update)."""
        s, d, t = ctx.sensors, ctx.data, ctx.sensors.t
        pending = self.pending
        while pending and pending[0].time_s <= t:
            item = heapq.heappop(pending)
            self._command(item.state, item.key, d)
        self._on = on = s.foot_on_floor
        for side in ("r", "l"):
            if not on[side]:
                self.left_floor[side] = True
        if on[self.roles["sup"]]:
            self._sup_off_s = None
        self._transitions(ctx, t)
        self._write(ctx)

    def _transitions(self, ctx: Context, t: float) -> None:
        s, d, st = ctx.sensors, ctx.data, self._state
        on = self._on
        rec, sup = self.roles["rec"], self.roles["sup"]
        if st == "passive_reaction" and t >= self.t_react:
            self._enter("clearance" if self.strategy == "elevating" else "leg_swap", t)
            self._set_base_gains(recovery=True)
        elif st == "leg_swap" and on[self.tripped] and t > self.t_react + 0.02:
            self.roles = {**self.roles, "rec": OTHER[self.tripped], "sup": self.tripped}
            self.left_floor = {"r": False, "l": False}
            self._switch("clearance", t, d, targets="clearance_lowering")
            # the recovery knee extends after the flexion as in the elevating strategy
            # (rectus femoris 90 ms after biceps femoris, SCA 2009 §3.2)
            self.t_extend = t + (self.p.latency_s["elev.rec.knee_extend"]
                                 - self.p.latency_s["elev.rec.knee_angle"]) * self.p.delay_scale
        elif st == "clearance":
            # the rectus femoris extension (SCA 2009 §3.2), once the recovery foot is
            # past the stance foot by a margin: it must clear the obstacle first (ours)
            if not self._extended and t >= self.t_extend and self._rec_cleared(ctx):
                for key in ("rec.knee_angle", "rec.hip_flexion"):
                    self._command("clearance_extend", key, d)
                self._extended = True
            if not on[sup] and not on[rec]:
                self._switch("flight", t, d, targets=self._table("flight"))
            elif (s.com_vel[2] < self.p.fall_vz_m_per_s and t - self.t_state > 0.05
                  and self.left_floor[rec] and self._rec_cleared(ctx)):
                self._switch("fall", t, d, targets=self._table("fall"))
            elif (on[rec] and self.left_floor[rec] and t - self.t_state > 0.1
                  and self._ahead(ctx, rec, sup, 0.0)):
                self._switch("double_support", t, d, targets=self._table("double_support"))
        elif (st == "flight" and self._flight_from_fall and on[sup] and not on[rec]):
            # the hop that started Flight lands first: back to Fall (flight_from_fall)
            self._switch("fall", t, d, targets=self._table("fall"))
        elif st == "flight" and on[rec] and self._ahead(ctx, rec, sup, 0.0):
            self._switch("single_support_after_trip", t, d,
                         targets=self._table("single_support_after_trip"))
            self.left_floor[sup] = True
            self._set_kp(f"hip_flexion_{rec}", self.p.kp_ssat_support_hip)
        elif (st == "fall" and on[rec] and self.left_floor[rec]
              and self._ahead(ctx, rec, sup, 0.0)):
            self._switch("double_support", t, d, targets=self._table("double_support"))
        elif st == "fall" and self.p.flight_from_fall and not on[sup] and not on[rec]:
            # the support foot has left the floor in Fall (FSMParams.flight_from_fall)
            self._sup_off_s = t if self._sup_off_s is None else self._sup_off_s
            if t - self._sup_off_s >= self.p.flight_lift_s - 1e-9:
                self._switch("flight", t, d, targets=self._table("flight"))
                self._flight_from_fall = True
        elif st == "double_support" and not on[sup]:
            self._switch("single_support_after_trip", t, d,
                         targets=self._table("single_support_after_trip"))
            self._set_kp(f"hip_flexion_{rec}", self.p.kp_ssat_support_hip)
            self.left_floor[sup] = True
        elif (st == "single_support_after_trip" and self.strategy == "lowering"
              and not self._crossed
              and self._toe_x(ctx, sup) > self.trip_point_x + self.p.clear_margin_m):
            # the tripped leg's toe is past the obstacle: its swing goes on as in walking
            self._apply_state_targets("single_support_after_trip", d)
            self._crossed = True
        elif st == "step_push" and (t - self.t_state >= self.p.walk_on_push_s
                                    or not on[sup]):
            self._switch("step_swing", t, d, targets=self._swing_table())
            self._set_kp(f"hip_flexion_{rec}", self.p.kp_ssat_support_hip)
        elif st in ("single_support_after_trip", "step_swing") and (
                self._ahead(ctx, sup, rec, -0.05) or t - self.t_state > self.p.ssat_swing_s
        ) and (st != "step_swing" or t - self.t_state >= self.p.walk_on_swing_min_s):
            self._switch("step_reach", t, d, cancel=False)
            self._set_kp(f"hip_flexion_{rec}", self.p.kp_ssat_support_hip)
        elif (st == "step_reach" and on[sup] and self.left_floor[sup]
              and self._ahead(ctx, sup, rec, 0.0)):
            # the swing foot has landed in front: it becomes the stance leg (ours: the
            # walk goes on after the recovery, SIMBICON-style, Yin et al. 2007)
            self.roles = {**self.roles, "rec": sup, "sup": rec}
            self.left_floor = {"r": False, "l": False}
            self._walk_on_landings += 1
            if self.p.walk_on_push_s > 0.0:  # double support: the trailing leg pushes
                self._switch("step_push", t, d)
            else:
                self._switch("step_swing", t, d, targets=self._swing_table())
            self._set_kp(f"hip_flexion_{sup}", self.p.kp_ssat_support_hip)
            if not self._arms_walking:
                for name in self.p.arms_deg["walking"]:
                    self._command("arms.walking", name, d)
                self._arms_walking = True

    def _swing_table(self) -> str:
        """The walk-on swing's targets: ``step_swing`` when given, else Single Support
        After Trip's (the recovery step's swing)."""
        return "step_swing" if "step_swing" in self.p.targets_deg else \
            "single_support_after_trip"

    def _table(self, state: str) -> str:
        """The targets of a state: ``<state>_lowering`` when the lowering strategy has its
        own (the legs' roles differ: its rear leg is the tripped one, behind the obstacle)."""
        own = f"{state}_lowering"
        return own if self.strategy == "lowering" and own in self.p.targets_deg else state

    def _ahead(self, ctx: Context, a: str, b: str, margin: float) -> bool:
        """Foot ``a`` is more than ``margin`` m ahead of foot ``b``."""
        x, ids = self._xpos, self._foot_id
        return bool(x[ids[a], 0] > x[ids[b], 0] + margin)

    def _toe_x(self, ctx: Context, side: str) -> float:
        """World x of a foot's toe tip (front row of its sole points)."""
        return float(self._site_xpos[self._toe_sites[side], 0].mean())

    def _rec_cleared(self, ctx: Context) -> bool:
        """The recovery foot is ahead of the stance foot and its toe has passed the point
        where the trip stopped the swing foot by ``clear_margin_m`` (the obstacle)."""
        rec, sup = self.roles["rec"], self.roles["sup"]
        return bool(self._ahead(ctx, rec, sup, 0.0)
                    and self._toe_x(ctx, rec) > self.trip_point_x + self.p.clear_margin_m)

    def _attitude_joints(self) -> list[tuple[int, bool, float]]:
        """(actuator, pitch?, sign) of the joints that hold the pelvis attitude now."""
        if self._att_dirty:
            self._att = [(int(i), bool(self.mode[i] == ATT_PITCH),
                          1.0 if self.bank.names[i].endswith("_r") else -1.0)
                         for i in np.flatnonzero(self.mode >= ATT_PITCH)]
            self._att_dirty = False
        return self._att

    def _write(self, ctx: Context) -> None:
        """Attitude targets, compensation torque; write ctrl (and gains, when changed)."""
        q = self._qpos
        qadr = self.bank.qadr
        target = self.target.copy()
        tilt, lst = attitude_of(self._pelvis_xmat)
        d_tilt, d_list = tilt - self.att_ref[0], lst - self.att_ref[1]
        world_damping = self.p.attitude_damping == "pelvis"
        if world_damping:  # the attitude's rates, by difference since the last update
            t = ctx.sensors.t
            dt = t - self._att_prev[0]
            rates = ((tilt - self._att_prev[1]) / dt, (lst - self._att_prev[2]) / dt) \
                if 0.0 < dt < 0.05 else (0.0, 0.0)
            self._att_prev = (t, tilt, lst)
            qdot = self._qvel
            c = self.bank.kd_over_kp
        for i, pitch, sign in self._attitude_joints():
            # pitch: the hip flexes with the pelvis tilt error; roll: right adduction about
            # +x, left about -x
            target[i] = q[qadr[i]] + (d_tilt if pitch else sign * d_list)
            if world_damping:  # the servo's force kp·err − kd·q̇ becomes kp·err + kd·ω
                target[i] += c * ((rates[0] if pitch else sign * rates[1])
                                  + qdot[self.bank.vadr[i]])
        st = self._state
        if st in ("step_reach", "fall", "flight"):
            self._place_foot(ctx, target, tilt)
        if st in ("clearance", "single_support_after_trip", "step_swing",
                  "step_reach", "fall", "flight"):
            self._place_foot_laterally(ctx, target, lst)
        if self.p.trunk_attitude:
            self._hold_trunk(ctx, target, st)
        if st in PUSH_OFF_STATES:
            p, sup = self.p, self.roles["sup"]
            if p.push_off_hip_limit_nm is not None:
                self._cap_servo(target, f"hip_flexion_{sup}", p.push_off_hip_limit_nm,
                                attitude_only=True)
            if p.push_off_rec_hip_limit_nm is not None:
                self._cap_servo(target, f"hip_flexion_{self.roles['rec']}",
                                p.push_off_rec_hip_limit_nm)
            if p.push_off_sup_knee_limit_nm is not None:
                self._cap_servo(target, f"knee_angle_{sup}", p.push_off_sup_knee_limit_nm)
        if st == "clearance" and self._pushing(ctx):
            i = self.bank.index[f"ankle_angle_{self.roles['sup']}"]
            tau_c = self.kc * (self.p.vz_target_m_per_s - ctx.sensors.com_vel[2])  # eq. 4
            target[i] -= tau_c / max(self.kp[i], 1e-6)  # plantarflexion torque
        self._ctrl[:] = target
        if self._gains_dirty:
            self.bank.set_gains(self.kp)
            self._gains_dirty = False

    def _pushing(self, ctx: Context) -> bool:
        """Whether the compensation torque acts: always in the elevating Clearance; in the
        lowering's once the COM is ``lowering_push_ahead_m`` ahead of the lowered foot."""
        ahead = self.p.lowering_push_ahead_m
        if self.strategy != "lowering" or ahead <= -1.0:
            return True
        sup = self._xpos[self._foot_id[self.roles["sup"]], 0]
        return bool(ctx.sensors.com[0] - sup > ahead)

    def _hold_trunk(self, ctx: Context, target: np.ndarray, st: str) -> None:
        """``trunk_attitude``: until the recovery foot lands the lumbar extends against
        that fraction of the torso's forward pitch in the world since the trip (a spring
        of k·k_p on the torso's world pitch, as SIMBICON's torso control, Yin et al. 2007,
        here at the lumbar); afterwards its target returns to the held angle with time
        constant ``TRUNK_RELEASE_S``."""
        i = self.bank.index["lumbar_extension"]
        t = ctx.sensors.t
        if st in PRE_LANDING_STATES:
            err = attitude_of(self._torso_xmat)[0] - self.torso_ref  # + posterior
            target[i] = self._qpos[self.bank.qadr[i]] - self.p.trunk_attitude * err
            self._trunk_last = (t, float(target[i]))
        elif self._trunk_last is not None:
            t0, q0 = self._trunk_last
            w = math.exp(-(t - t0) / TRUNK_RELEASE_S)
            target[i] = self.target[i] + w * (q0 - self.target[i])

    def _cap_servo(self, target: np.ndarray, name: str, cap_nm: float,
                   attitude_only: bool = False) -> None:
        """Limit the servo ``name``'s moment |k_p(θ_d − θ) − k_d θ̇| to ``cap_nm``
        (reference body; scaled as the gains) by moving its target (the servo runs at
        every physics step, the target is rewritten at every control update);
        ``attitude_only``: only while it holds the pelvis attitude."""
        i = self.bank.index[name]
        if attitude_only and self.mode[i] != ATT_PITCH:
            return
        b = self.bank
        kp = b.gain_scale * self.kp[i]
        if kp <= 0.0:
            return
        kd = b.kd_over_kp * kp
        q, qd = float(self._qpos[b.qadr[i]]), float(self._qvel[b.vadr[i]])
        tau = kp * (target[i] - q) - kd * qd
        c = cap_nm * b.gain_scale
        if abs(tau) > c:
            target[i] = q + (math.copysign(c, tau) + kd * qd) / kp

    def _place_foot(self, ctx: Context, target: np.ndarray, tilt: float) -> None:
        """SIMBICON balance feedback (Yin et al. 2007) on the reaching leg's hip: the swing
        thigh's world angle θ = θ_0 + c_d·d + c_v·v, d the COM's offset from the stance
        ankle, v its velocity; sagittal on hip flexion, lateral on hip adduction."""
        s = ctx.sensors
        swing, stance = self.roles["rec"], self.roles["sup"]
        if self._state == "step_reach":
            swing, stance = self.roles["sup"], self.roles["rec"]
        dx = s.com[0] - self._xpos[self._foot_id[stance], 0]
        p = self.p
        i = self.bank.index[f"hip_flexion_{swing}"]
        # the swing thigh's angle in the world (SIMBICON): hip = thigh_world - pelvis tilt
        base = p.reach_thigh_deg if self._state == "step_reach" else p.land_thigh_deg
        thigh = (np.radians(base) + p.balance_cd_rad_per_m * dx
                 + p.balance_cv_rad_s_per_m * s.com_vel[0])
        if self._state == "step_reach":  # walking on, toward the speed before the trip
            n, ramp = self._walk_on_landings, p.walk_on_speed_ramp_steps
            w = min(1.0, n / ramp) if ramp > 0.0 else 1.0
            aim = self._walk_on_aim
            thigh += w * p.walk_on_speed_gain_rad_s_per_m * (s.com_vel[0] - aim)
            thigh -= (w * p.walk_on_speed_feedforward * p.balance_cv_rad_s_per_m
                      * (aim - p.walk_on_speed_ref_m_per_s))
        target[i] = thigh - tilt

    def _place_foot_laterally(self, ctx: Context, target: np.ndarray, lst: float) -> None:
        """SIMBICON coronal feedback: the swing thigh's world roll φ = c_d·dy + c_v·v_y
        (dy the COM's lateral offset from the stance ankle), so the foot lands under a
        COM that drifts sideways. Thigh roll = pelvis list + right adduction
        (− left adduction)."""
        s, p = ctx.sensors, self.p
        swing, stance = self.roles["rec"], self.roles["sup"]
        if self._state in ("single_support_after_trip", "step_swing", "step_reach"):
            swing, stance = self.roles["sup"], self.roles["rec"]
        dy = s.com[1] - self._xpos[self._foot_id[stance], 1]
        phi = p.balance_cd_lat_rad_per_m * dy + p.balance_cv_lat_rad_s_per_m * s.com_vel[1]
        j = self.bank.index[f"hip_adduction_{swing}"]
        target[j] = (phi - lst) if swing == "r" else (lst - phi)

    def state(self) -> str:
        """Current state name."""
        return self._state
