"""Parameters of the finite-state-machine trip controllers (SCA 2009 §3-5).

Joint targets are in degrees in *our* convention (OpenSim signs: hip flexion +, knee
flexion −, ankle dorsiflexion +, shoulder flexion +, shoulder adduction + (so
abduction −), elbow flexion +), keyed by role:

- ``rec.*``: the recovery leg (elevating: the tripped leg; lowering, after Leg Swap:
  the other leg), ``sup.*``: the support leg, ``trip.*``: the tripped leg (Leg Swap);
- ``arm_c.*`` / ``arm_i.*``: the arm contralateral / ipsilateral to the tripped leg;
- ``"hold"`` instead of a number keeps the angle the joint had when it entered the
  state; ``"attitude"`` makes the hip hold the pelvis attitude in the world (the stance
  hip "maintains the torso attitude", SCA 2009 §4.3, as in SIMBICON).

Where SCA 2009 took a target from its own trip motion capture (which we do not have),
the value below is grounded in the literature or in the paper's figures; the reason
is beside it. Everything here can be overridden (``FSMParams(**changes)``).
"""

from __future__ import annotations

import copy
import difflib
import functools
import hashlib
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

ACTIVATION_TO_TORQUE_S = 0.050  # SCA 2009 §4.3: 50 ms from muscle activation to torque

# Muscle-response latencies after the trip (s), before the 50 ms offset is added.
LATENCY_S = {
    # push-off reaction of the support leg, SCA 2009 §3.1 (Pijnappels et al. 2005)
    "sup.hip_flexion": 0.050,  # hamstrings burst ~50 ms (hip extension)
    # gluteal burst ~80 ms: SCA 2009 §3.1 has it extend the support hip with the
    # hamstrings; ours times the hip's frontal-plane (abduction) response with it, the
    # gluteus medius's, and its extension with the hamstrings' 50 ms (the earlier burst)
    "sup.hip_adduction": 0.080,
    "sup.knee_angle": 0.120,  # quadriceps ~120 ms (knee extension)
    "sup.ankle_angle": 0.075,  # triceps surae ~75 ms (plantarflexion)
    # elevating strategy, recovery (tripped) leg, SCA 2009 §3.2 (Schillings et al. 2000)
    "elev.rec.knee_angle": 0.064,  # biceps femoris ~64 ms flexes the knee
    "elev.rec.knee_extend": 0.154,  # rectus femoris ~154 ms extends it for touch-down
    "elev.rec.hip_flexion": 0.064,  # taken with the BF burst (the paper gives no hip timing)
    # tibialis anterior: SCA 2009 §3.2 "about 75 msec after the push-off reaction";
    # ambiguous (after the push-off reaction's start, ~50 ms, or after the collision).
    # Ours: 75 ms after the collision, as the paper's other latencies; the other reading
    # is about 0.125 s (set latency_s["elev.rec.ankle_angle"] to it)
    "elev.rec.ankle_angle": 0.075,
    # lowering strategy, tripped leg, SCA 2009 §3.3 (Schillings et al. 2000)
    "low.trip.knee_angle": 0.062,  # rectus femoris ~62 ms
    "low.trip.hip_flexion": 0.087,  # biceps femoris ~87 ms
    "low.trip.ankle_angle": 0.040,  # tibialis anterior and soleus ~40 ms
    # arms, SCA 2009 §3.4 (Pijnappels et al. 2008: within 100 ms)
    "arms": 0.100,
}

# SCA 2009 §4.5 gains (N·m/rad) in Passive Reaction; ×1.5 once recovery starts;
# support hip 1500 in Single Support After Trip. k_d = 0.1 k_p (SCA 2009 §4.5).
KP_PASSIVE = {"swing_hip": 500.0, "support_hip": 1000.0, "knee": 300.0, "ankle": 300.0,
              "mtp": 100.0}
RECOVERY_GAIN_FACTOR = 1.5  # SCA 2009 §4.5: "increased by a factor of approximately 1.5"
KP_SSAT_SUPPORT_HIP = 1500.0  # SCA 2009 §4.5
# High gains that hold chest, neck and wrists at their trip-instant angles (SCA 2009
# §4.6 gives no number; ours) and the arm servos (ours).
KP_UPPER = {"lumbar": 1500.0, "neck": 300.0, "wrist": 100.0, "pro_sup": 50.0,
            "shoulder": 150.0, "elbow": 80.0}
# hip adduction of the swing leg, hip rotation of both (ours)
KP_HIP_OUT_OF_PLANE = 600.0
# the stance hip's adduction while it holds the pelvis's list (ours; by default the
# swing leg's, as it was before it had a gain of its own)
KP_STANCE_HIP_ROLL = KP_HIP_OUT_OF_PLANE
KP_KNEE_ROTATION = 200.0  # the knee's axial DOF (ours)
KP_SUBTALAR = 300.0  # (ours)

# Compensation torque on the support ankle (SCA 2009 eq. 4, §5): τ_c = k_c (v_z^d − v_z)
KC_SLOW = 50.0  # N·m·s/m, slow walking (0.75-1.0 m/s), SCA 2009 §5
KC_FAST = 300.0  # N·m·s/m, fast walking (about 1.4 m/s), SCA 2009 §5
VZ_TARGET_M_PER_S = 1.2  # SCA 2009 §5
KC_SPEEDS = (1.0, 1.4)  # k_c ramps linearly between these speeds (our reading of §5)


def _targets() -> dict[str, dict[str, float | str]]:
    """Target angles per state (degrees, our convention), see the module docstring."""
    t = _state_targets()
    # the walk on's swing (ours) starts as the recovery step's, with its own values so
    # that a search (WALK_ON) may change the one without the other
    t["step_swing"] = dict(t["single_support_after_trip"])
    return t


def _state_targets() -> dict[str, dict[str, float | str]]:
    """The targets of the states of SCA 2009 and of ours (``_targets``)."""
    return {
        "passive_reaction": {
            # SCA 2009 §4.3: try to maintain walking; swing knee free (no torque, Perry
            # 1992), swing hip carries on forward, support leg keeps its stance posture
            "rec.hip_flexion": 25.0,  # the hip flexion of terminal swing in our reference
            "sup.hip_flexion": "attitude", "sup.hip_adduction": "attitude",
            "sup.knee_angle": "hold", "sup.ankle_angle": "hold",
        },
        "clearance_elevating": {
            # Push-off targets of the support leg, SCA 2009 §4.5: hip 0, knee 5, ankle 60
            # (their convention: angles of flexion; we map knee 5° flexion -> -5 and ankle
            # 60° -> 60° of plantarflexion = -60, past the -50° limit on purpose: the
            # target acts as a strong plantarflexion bias, as §4.5 explains for targets
            # beyond the angles reached).
            # The support hip keeps the pelvis attitude (SCA 2009 §4.3: "maintains the
            # torso attitude"); its 0° push-off target of §4.5, in our joint convention,
            # would pull the trunk forward whenever the stance thigh is behind the body.
            # Set "sup.hip_flexion": 0.0 to use it literally.
            "sup.hip_flexion": "attitude", "sup.knee_angle": -5.0,
            # tuned (TUNED_WITH, after these tables) from SCA's 60° of plantarflexion
            "sup.ankle_angle": -23.014702706544988,
            "sup.hip_adduction": "attitude",
            # Recovery leg lifted over the obstacle. SCA 2009 §4.5: a knee that reaches
            # 120° in mocap gets a 135° target; elevating recoveries reach 90-110° of
            # knee flexion and 60-80° of hip flexion (Eng et al. 1994; Schillings 2000).
            "rec.hip_flexion": 80.0, "rec.knee_angle": -125.0, "rec.ankle_angle": 15.0,
        },
        "clearance_extend": {
            # after the rectus femoris burst the recovery knee extends for touch-down
            # tuned (TUNED_WITH, after these tables)
            "rec.knee_angle": -16.810831716786787, "rec.hip_flexion": 30.50555188108346,
        },
        "leg_swap": {
            # SCA 2009 §4.4: extension torques put the tripped leg on the ground at once,
            # ankle dorsiflexed (TA with SOL at 40 ms, TA again at 60 ms)
            # tuned (TUNED_WITH, after these tables)
            "trip.hip_flexion": 0.1271285661235737,
            "trip.knee_angle": -6.210334022020902,
            "trip.ankle_angle": -6.119957134993348,
            "sup.hip_flexion": "attitude", "sup.hip_adduction": "attitude",
            "sup.knee_angle": "hold", "sup.ankle_angle": "hold",
        },
        "clearance_lowering": {
            # roles swapped: the tripped leg supports and pushes off, the other clears
            # tuned: the lowering push-off is mild (ankle 6° dorsiflexed): the body must roll
            # over the tripped foot for the other leg to step over (SCA's -60° stalls it
            # on tiptoe)
            "sup.hip_flexion": "attitude",
            "sup.knee_angle": -5.0,
            "sup.ankle_angle": 6.37351312930106,
            "sup.hip_adduction": "attitude",
            # tuned (TUNED_WITH, after these tables)
            "rec.hip_flexion": 65.18563063218879,
            "rec.knee_angle": -90.06382007483776,
            "rec.ankle_angle": 22.132934285808464,
        },
        "flight": {
            # SCA 2009 §4.3: front leg extended for the landing, rear leg flexed
            "rec.hip_flexion": 40.0, "rec.knee_angle": -10.0, "rec.ankle_angle": 5.0,
            "sup.hip_flexion": -10.0, "sup.knee_angle": -60.0, "sup.ankle_angle": -10.0,
        },
        "fall": {
            # SCA 2009 §4.3: the front swing leg extended for landing
            # (the hip flexion is replaced by the world-frame placement, land_thigh_deg)
            # tuned (TUNED_WITH, after these tables)
            "rec.hip_flexion": 40.0, "rec.knee_angle": -17.477139331178105, "rec.ankle_angle": 5.0,
            "sup.hip_adduction": "attitude",
            "sup.ankle_angle": -13.916144963531217,  # tuned (TUNED_WITH, after these tables)
        },
        "double_support": {
            # SCA 2009 §4.3: front leg keeps the torso attitude and its length; the rear
            # leg flexes and moves forward
            "rec.hip_flexion": "attitude", "rec.hip_adduction": "attitude",
            "rec.knee_angle": -8.0, "rec.ankle_angle": "hold",
            "sup.hip_flexion": 35.0, "sup.knee_angle": -70.0, "sup.ankle_angle": 5.0,
        },
        "double_support_lowering": {
            # Double Support of the lowering strategy (ours): the rear leg is the tripped
            # one, lowered just behind the obstacle, so its swing forward must cross it as a
            # trailing limb. With Double Support's 70° of knee flexion its toe caught the
            # box again for 25-35 ms (obstacle trips at 0.75 of swing, 1.2-1.4 m/s, fell ~2 s
            # later; with these targets it grazes it for 15-25 ms and they recover).
            # The knee flexes as in the elevating clearance (90-110° reached, Eng et al.
            # 1994; Schillings et al. 2000; the grid gives the same result for -100 to
            # -125), the ankle dorsiflexes the toe up (tibialis anterior, as there).
            "rec.hip_flexion": "attitude", "rec.hip_adduction": "attitude",
            "rec.knee_angle": -8.0, "rec.ankle_angle": "hold",
            # tuned (TUNED_WITH, after these tables)
            "sup.hip_flexion": 38.93799535690255,
            "sup.knee_angle": -114.27566256101204,
            "sup.ankle_angle": 15.0,
        },
        "single_support_after_trip": {
            # SCA 2009 §4.3: stance hip keeps the torso attitude, stance knee extended,
            # the swing leg moves forward flexed
            "rec.hip_flexion": "attitude", "rec.hip_adduction": "attitude",
            "rec.knee_angle": -5.0, "rec.ankle_angle": "hold",
            # tuned (TUNED_WITH, after these tables)
            "sup.hip_flexion": 49.64305621255319, "sup.knee_angle": -75.0, "sup.ankle_angle": 10.0,
        },
        "single_support_after_trip_lowering": {
            # Single Support After Trip of the lowering strategy (ours): the swing leg is
            # the tripped one, lowered behind the obstacle, and it swings forward over it
            # as a trailing limb (SCA 2009's lowering ends at the recovery step, before
            # this swing). With the targets above (knee 75°) its toe caught the box again
            # in every obstacle trip at 0.55 of swing, 1.0-1.4 m/s, and the body fell
            # ~0.6 s after the recovery step. A trailing limb crossing an obstacle flexes
            # its knee further than in walking (Chou & Draganich 1997, J Biomech 30:331;
            # their angles were not read: the values here are ours), so
            # the knee and ankle start from Double Support's crossing targets
            # (double_support_lowering: its knee flexion and toe-up ankle), the hip from
            # the one above; tuned (TUNED_WITH[1], after these tables).
            "rec.hip_flexion": "attitude", "rec.hip_adduction": "attitude",
            "rec.knee_angle": -5.0, "rec.ankle_angle": "hold",
            "sup.hip_flexion": 54.2833383224508, "sup.knee_angle": -114.92914976535079,
            "sup.ankle_angle": 14.837084858419807,
        },
        "step_push": {
            # ours, used when walk_on_push_s > 0: after a walk-on landing both feet are
            # down for that long and the trailing leg pushes off (people's double
            # support, about 0.1 s a step at 1.2 m/s, Perry 1992), then it swings
            "rec.hip_flexion": "attitude", "rec.hip_adduction": "attitude",
            "rec.knee_angle": -5.0, "rec.ankle_angle": "hold",
            "sup.hip_flexion": "hold", "sup.knee_angle": -20.0, "sup.ankle_angle": -15.0,
        },
        "step_reach": {
            # ours: the swing leg reaches forward for the next step (SCA 2009 stops at
            # Single Support After Trip, "empirically set so that balance is recovered");
            # its hip target gets the balance feedback below
            # tuned (TUNED_WITH, after these tables)
            "sup.hip_flexion": 20.0, "sup.knee_angle": -11.420425435765583, "sup.ankle_angle": 0.0,
            "rec.hip_flexion": "attitude", "rec.hip_adduction": "attitude",
            "rec.knee_angle": -5.0,
        },
    }


def _arms() -> dict[str, dict[str, float | str]]:
    """Arm responses (SCA 2009 §3.4, §4.6; Roos et al. 2008): contralateral forward,
    ipsilateral sideways, then walking swing after the landing. Magnitudes ours, from
    the ranges Roos et al. report (contralateral shoulder flexion 40-60°,
    ipsilateral abduction 30-50°)."""
    return {
        "response": {"arm_c.shoulder_flexion": 55.0, "arm_c.elbow_flexion": 40.0,
                     "arm_i.shoulder_adduction": -45.0, "arm_i.shoulder_flexion": 10.0,
                     "arm_i.elbow_flexion": 30.0},
        "walking": {"arm_c.shoulder_flexion": 10.0, "arm_c.elbow_flexion": 25.0,
                    "arm_i.shoulder_adduction": -8.0, "arm_i.shoulder_flexion": -10.0,
                    "arm_i.elbow_flexion": 20.0},
    }


# The free targets and gains a search may change (scripts/tune_fsm.py), each with its
# range: name -> (path in FSMParams, low, high). The targets are the ones SCA 2009 took
# from its own motion capture; their ranges come from the literature of the defaults'
# comments above.
SPACE = {
    "low_sup_ankle": (("targets_deg", "clearance_lowering", "sup.ankle_angle"), -60.0, 10.0),
    "elev_sup_ankle": (("targets_deg", "clearance_elevating", "sup.ankle_angle"), -60.0, 0.0),
    "fall_rec_knee": (("targets_deg", "fall", "rec.knee_angle"), -25.0, -3.0),
    "fall_sup_ankle": (("targets_deg", "fall", "sup.ankle_angle"), -30.0, 10.0),
    "ext_rec_hip": (("targets_deg", "clearance_extend", "rec.hip_flexion"), 20.0, 60.0),
    "ext_rec_knee": (("targets_deg", "clearance_extend", "rec.knee_angle"), -45.0, -8.0),
    "low_rec_hip": (("targets_deg", "clearance_lowering", "rec.hip_flexion"), 40.0, 80.0),
    "low_rec_knee": (("targets_deg", "clearance_lowering", "rec.knee_angle"), -125.0, -70.0),
    "ssat_sup_hip": (("targets_deg", "single_support_after_trip", "sup.hip_flexion"), 30.0,
                     65.0),
    "reach_sup_knee": (("targets_deg", "step_reach", "sup.knee_angle"), -20.0, -3.0),
    "kc_slow": (("kc_slow",), 0.0, 100.0),
    "kc_fast": (("kc_fast",), 0.0, 300.0),
    "reach_thigh_deg": (("reach_thigh_deg",), -5.0, 15.0),
    "land_thigh_deg": (("land_thigh_deg",), -5.0, 30.0),
    "balance_cd": (("balance_cd_rad_per_m",), 0.2, 0.8),
    "balance_cv": (("balance_cv_rad_s_per_m",), 0.1, 0.5),
    "ssat_swing_s": (("ssat_swing_s",), 0.2, 0.45),
    "clear_margin_m": (("clear_margin_m",), 0.06, 0.2),
    "swap_trip_hip": (("targets_deg", "leg_swap", "trip.hip_flexion"), -10.0, 20.0),
    "swap_trip_ankle": (("targets_deg", "leg_swap", "trip.ankle_angle"), -10.0, 20.0),
    "swap_trip_knee": (("targets_deg", "leg_swap", "trip.knee_angle"), -20.0, 0.0),
    "low_rec_ankle": (("targets_deg", "clearance_lowering", "rec.ankle_angle"), 0.0, 25.0),
    "ds_low_sup_knee": (("targets_deg", "double_support_lowering", "sup.knee_angle"), -125.0,
                        -90.0),
    "ds_low_sup_hip": (("targets_deg", "double_support_lowering", "sup.hip_flexion"), 15.0,
                       50.0),
    # the tripped leg crossing the obstacle as a trailing limb after a lowering recovery
    # step (single_support_after_trip_lowering; knee 90-125° as ds_low_sup_knee)
    "ssat_low_sup_hip": (("targets_deg", "single_support_after_trip_lowering",
                          "sup.hip_flexion"), 30.0, 65.0),
    "ssat_low_sup_knee": (("targets_deg", "single_support_after_trip_lowering",
                           "sup.knee_angle"), -125.0, -75.0),
    "ssat_low_sup_ankle": (("targets_deg", "single_support_after_trip_lowering",
                            "sup.ankle_angle"), 0.0, 25.0),
}
# servo gains (N·m/rad), searched with --gains: with human strength (Anderson et al.
# 2007) the servos saturate, and how hard each joint is driven matters
GAINS = {
    "kp_support_hip": (("kp_passive", "support_hip"), 300.0, 2000.0),
    "kp_swing_hip": (("kp_passive", "swing_hip"), 150.0, 1500.0),
    "kp_knee": (("kp_passive", "knee"), 100.0, 800.0),
    "kp_ankle": (("kp_passive", "ankle"), 100.0, 800.0),
    "recovery_gain_factor": (("recovery_gain_factor",), 1.0, 2.5),
    "kp_ssat_support_hip": (("kp_ssat_support_hip",), 400.0, 3000.0),
}

# The walk on's gait (issue 11, "settles into a steady gait toward the speed they had
# before the trip"; ours, all off or equal to the recovery step's by default):
# scripts/tune_fsm.py --walk-on-gait W searches these.
WALK_ON = {
    "walk_on_push_s": (("walk_on_push_s",), 0.0, 0.2),
    "push_sup_ankle": (("targets_deg", "step_push", "sup.ankle_angle"), -30.0, 15.0),
    "push_sup_knee": (("targets_deg", "step_push", "sup.knee_angle"), -45.0, -3.0),
    "swing_sup_hip": (("targets_deg", "step_swing", "sup.hip_flexion"), 20.0, 60.0),
    "swing_sup_knee": (("targets_deg", "step_swing", "sup.knee_angle"), -100.0, -40.0),
    "swing_sup_ankle": (("targets_deg", "step_swing", "sup.ankle_angle"), -5.0, 20.0),
    "walk_on_speed_gain": (("walk_on_speed_gain_rad_s_per_m",), 0.0, 0.5),
    "walk_on_speed_ramp": (("walk_on_speed_ramp_steps",), 0.0, 6.0),
    "walk_on_speed_feedforward": (("walk_on_speed_feedforward",), 0.0, 1.5),
    "walk_on_speed_ref": (("walk_on_speed_ref_m_per_s",), 0.9, 1.5),
    "walk_on_swing_min_s": (("walk_on_swing_min_s",), 0.0, 0.45),
}
# Flight at fast walking (issue 11; ours, off by default): the elevating support ankle's
# Clearance target plantarflexed further at fast walking, phased in with the walking
# speed as k_c is (FSMParams.speed_weight). Set by a scan (scripts/scan_fsm.py).
FLIGHT = {
    "elev_sup_ankle_fast": (("elev_sup_ankle_fast_deg",), -30.0, 0.0),
    # the lowering strategy's Fall (its own table, ``fall_lowering``, made from ``fall``
    # by ``FSMParams.at_speed``): offsets (deg) at the fast end of kc_speeds
    **{f"low_fall_{key}_fast": (("low_fall_fast_deg", key), lo, hi)
       for key, (lo, hi) in {"sup_ankle": (-45.0, 0.0), "sup_knee": (-40.0, 0.0),
                             "rec_knee": (-35.0, 0.0), "rec_ankle": (-20.0, 10.0)}.items()},
}
# which target of the lowering Fall each ``low_fall_fast_deg`` offset moves
# (the recovery hip is not among them: in Fall it follows the foot placement,
# ``land_thigh_deg``); a target ``fall`` leaves as it was starts from the lowering
# Clearance's (the state before Fall)
LOW_FALL_FAST_TARGETS = {"sup_ankle": "sup.ankle_angle", "sup_knee": "sup.knee_angle",
                         "rec_knee": "rec.knee_angle", "rec_ankle": "rec.ankle_angle"}
# The elevating Flight's targets (SCA 2009 §4.3's, never searched before 2026-12-07,
# when Flight first ran: ``flight_from_fall``); the recovery hip follows the foot
# placement there (``land_thigh_deg``). scripts/tune_fsm.py --flight-targets searches
# these and the lowering's (``LOWERING_FLIGHT``'s ``fl_low_*``); the ranges are ours, as
# the lowering's.
ELEV_FLIGHT = {
    f"fl_{key.replace('.', '_').replace('_angle', '').replace('_flexion', '')}":
    (("targets_deg", "flight", key), lo, hi)
    for key, (lo, hi) in {"rec.knee_angle": (-60.0, -3.0), "rec.ankle_angle": (-15.0, 20.0),
                          "sup.hip_flexion": (-30.0, 40.0), "sup.knee_angle": (-110.0, -5.0),
                          "sup.ankle_angle": (-40.0, 20.0)}.items()}
# Flight in the lowering strategy by the compensation of SCA 2009 eq. 4 (issue 11; ours,
# off by default): its own k_c at fast walking, the COM's lead over the lowered foot
# before it acts, and the lowering's own Flight table (``flight_lowering``, from
# ``flight``: the landing of a lowering flight, whose legs' roles differ from the
# elevating's). scripts/tune_fsm.py --only lowering_flight searches them.
LOWERING_FLIGHT = {
    "kc_lowering_fast": (("kc_lowering_fast",), 0.0, 500.0),
    "lowering_push_ahead": (("lowering_push_ahead_m",), -0.3, 0.4),
    **{f"fl_low_{key.replace('.', '_').replace('_angle', '').replace('_flexion', '')}":
       (("targets_deg", "flight_lowering", key), lo, hi)
       for key, (lo, hi) in {"rec.knee_angle": (-60.0, -3.0),
                             "rec.ankle_angle": (-15.0, 20.0),
                             "sup.hip_flexion": (-30.0, 40.0),
                             "sup.knee_angle": (-110.0, -5.0),
                             "sup.ankle_angle": (-40.0, 20.0)}.items()},
}
# The frontal plane (issue 11; ours, never searched before 2026-12-06): SIMBICON's
# coronal foot placement (Yin et al. 2007) and the hips' out-of-plane gains. Under the
# push-off caps most falls are sideways (the COM 0.3-1.5 m to the side at the fall):
# scripts/tune_fsm.py --lateral searches these.
LATERAL = {
    "balance_cd_lat": (("balance_cd_lat_rad_per_m",), 0.0, 1.5),
    "balance_cv_lat": (("balance_cv_lat_rad_s_per_m",), 0.0, 1.0),
    "kp_hip_out_of_plane": (("kp_hip_out_of_plane",), 200.0, 2000.0),
    "kp_stance_hip_roll": (("kp_stance_hip_roll",), 200.0, 3000.0),
}
# tables a search may create from another (``with_values``): the lowering's own Flight
DERIVED_TABLES = {"flight_lowering": "flight"}
# every name a parameter file may set
TUNABLE = {**SPACE, **GAINS, **WALK_ON, **FLIGHT, **LOWERING_FLIGHT, **LATERAL,
           **ELEV_FLIGHT}

# How the values marked "tuned" were found: CMA-ES (the cmaes package, seeded) over the
# 24 targets and 6 gains of SPACE and GAINS, from the earlier tuned values (random and
# local searches, seeds 1, 3 and 11; scripts/fsm_start_walk_on.json), on the 48-trip
# grid, each trip counted recovered only if still walking 6 s after it with at least 4
# steps after the recovery step (Scenario.recovery walk_on); 16 generations of 12
# candidates, 40 min on 2 cores with other work running (TUNED_WITH[0]). Then, once the
# tripped leg crosses the obstacle after a lowering recovery step with targets of its own
# (single_support_after_trip_lowering), the 12 lowering-only targets (tune_fsm.LOWERING:
# no gain, nothing an elevating trip uses) refined on the grid's 18 lowering trips under
# the same rule, from the values above and the new targets' starting ones
# (scripts/fsm_start_lowering.json): CMA-ES, first step 0.05 of each range, 20
# generations of 12, 13 min on one core (TUNED_WITH[1]; 12 -> 15 of the 18, its best from
# the seventh generation on).
TUNED_WITH = ("python scripts/tune_fsm.py --method cma --gains --grid full --walk-on 6 "
              "--generations 16 --popsize 12 --workers 2 --seed 3 "
              "--around \"$(cat scripts/fsm_start_walk_on.json)\"",
              "python scripts/tune_fsm.py --method cma --only lowering --grid lowering "
              "--walk-on 6 --sigma 0.05 --generations 20 --popsize 12 --workers 1 --seed 6 "
              "--around \"$(cat scripts/fsm_start_lowering.json)\"")


ATTITUDE_DAMPING = ("joint", "pelvis")  # FSMParams.attitude_damping


@dataclass
class FSMParams:
    """Every number of the trip controllers; override any field to experiment."""

    targets_deg: dict = field(default_factory=_targets)
    arms_deg: dict = field(default_factory=_arms)
    latency_s: dict = field(default_factory=lambda: dict(LATENCY_S))
    activation_to_torque_s: float = ACTIVATION_TO_TORQUE_S
    delay_scale: float = 1.0
    # tuned (TUNED_WITH, after these tables) from SCA 2009 §4.5's KP_PASSIVE, ×1.5 and 1500
    kp_passive: dict = field(default_factory=lambda: dict(
        KP_PASSIVE, support_hip=1243.3062412476338, swing_hip=634.1790891375344,
        knee=463.42703567397234, ankle=180.10312463995103))
    recovery_gain_factor: float = 1.3634434740904624  # tuned
    kp_ssat_support_hip: float = 2076.452647925406  # tuned
    kp_upper: dict = field(default_factory=lambda: dict(KP_UPPER))
    kp_hip_out_of_plane: float = KP_HIP_OUT_OF_PLANE
    kp_stance_hip_roll: float = KP_STANCE_HIP_ROLL
    kp_knee_rotation: float = KP_KNEE_ROTATION
    kp_subtalar: float = KP_SUBTALAR
    # gains are the reference body's (70 kg, 1.75 m); dynamic: scaled to each body by
    # m·h (k_d/k_p by √h), stumble.control.pd.ServoBank; none: the same for every body
    body_scaling: str = "dynamic"
    # what damps the pelvis attitude the stance hip holds: "joint", the hip servo's own
    # damping on the hip's joint rate (as tuned: in stance the hip extends at 1-2 rad/s as
    # the body passes over the foot, and that damping leaves the pelvis 10-16° forward of
    # its reference in the walk after a recovery), or "pelvis": the pelvis's pitch and roll
    # rates in the world, as SIMBICON's torso PD (Yin et al. 2007), through the servo's
    # target (an experiment: not tuned, docs/fsm-fits.md "Where it stands")
    attitude_damping: str = "joint"  # ATTITUDE_DAMPING
    # Issue 11, people's support hip pushes off with a peak extension moment of ~52 N·m
    # in the first 300 ms (Pijnappels et al. 2005), ours ~280 N·m: in Clearance the
    # stance hip's attitude servo arrests the pelvis, which the trip pitches forward
    # (5-7° by 0.12 s: its target error gives ~200 N·m, the joint damping the rest).
    # push_off_hip_limit_nm caps that hip's servo moment (N·m, reference body, scaled as
    # the gains) while it holds the attitude in the push-off (fsm.PUSH_OFF_STATES), to
    # let the trunk rotate as people do; None: the servo's own limit. An experiment:
    # measured, it loses recoveries and tilts the trunk further (docs/fsm-fits.md,
    # "Where it stands").
    push_off_hip_limit_nm: float | None = None
    # push_off_rec_hip_limit_nm caps the recovery (tripped) hip's servo moment (N·m,
    # reference body, scaled as the gains) in the push-off (fsm.PUSH_OFF_STATES); None:
    # the servo's own limit (300 N·m). Reason (issue 11): swinging the tripped leg
    # through at up to 300 N·m, the recovery hip's reaction pitches the pelvis, and the
    # support hip's attitude servo arrests it with 5 times the 52 N·m of people's
    # push-off (Pijnappels et al. 2005). People's hip flexors cannot give 300 N·m: for
    # our reference body Anderson et al. 2007 (J Biomech 40:3105, Table 3, young men)
    # give 136 N·m isometric, about a third of it at 6 rad/s. Ours: a constant cap, not
    # their curve. Searched under 60 N·m, the grid walks on after 46 of 48 with the
    # support hip at 142 N·m (docs/fsm-fits.md, "Where it stands": "Targets and gains
    # searched under the cap"); scripts/tune_fsm.py --rec-hip-cap NM.
    push_off_rec_hip_limit_nm: float | None = None
    # push_off_sup_knee_limit_nm caps the support knee's servo moment (N·m, reference
    # body, scaled as the gains) in the push-off (fsm.PUSH_OFF_STATES); None: the servo's
    # own limit (250 N·m). Reason (issue 11): as the body rises over the support leg in
    # the push-off, that knee extends at ~1.6 rad/s and its servo's damping (k_d 0.1 k_p,
    # SCA 2009 §4.5) resists with a flexion moment of ~100 N·m under `hip_cap`, where
    # people's peak is 54 N·m (Pijnappels et al. 2005). Ours: a constant cap; 80 N·m is
    # within 1.5 times their mean (docs/fsm-fits.md, "The support knee capped");
    # scripts/tune_fsm.py --sup-knee-cap NM.
    push_off_sup_knee_limit_nm: float | None = None
    # trunk_attitude k: until the recovery foot lands (fsm.PRE_LANDING_STATES) the lumbar
    # extends against k times the torso's forward pitch in the world since the trip
    # (0: off, SCA 2009 §4.6's chest held at its trip-instant angle to the pelvis).
    # Reason: the trunk's tilt at recovery-foot contact separates recoveries from falls
    # and people's recoveries keep it within about 23-26° (van den Bogert et al. 2002),
    # while the torso ours pitches with the pelvis; SIMBICON (Yin et al. 2007) controls
    # the torso in the world frame. Ours, not tuned: 0.3 keeps the 48-trip grid's
    # recoveries and brings the largest tilt from 32.4° to 25.8° (docs/fsm-fits.md,
    # "Where it stands").
    trunk_attitude: float = 0.0
    # SCA 2009 §5 uses 50 and 300 for slow and fast walking; on our body 300 lifts the
    # support foot off and stalls the recovery; tuned (TUNED_WITH above; 39.5 and 66.7
    # before the tuning for walking on)
    kc_slow: float = 28.999344653119145  # tuned
    kc_fast: float = 89.97148071517134  # tuned
    kc_speeds: tuple[float, float] = KC_SPEEDS
    vz_target_m_per_s: float = VZ_TARGET_M_PER_S
    # Strategy rule (issue: elevating below 0.3 of swing, lowering above 0.5). Between,
    # humans use either (Schillings et al. 2000); we choose elevating up to the threshold
    # (0.5, inclusive): on our body it recovers mid-swing trips that lowering does not
    # (10 of 12 against 5 of 12 at 0.45-0.5, both mechanisms, 1.0-1.4 m/s).
    elevating_below: float = 0.3
    lowering_above: float = 0.5
    strategy_threshold: float = 0.5
    # The swing leg reaches for the next step once its foot passes the stance foot, or
    # after this long in Single Support After Trip (ours).
    ssat_swing_s: float = 0.41473080650451816  # tuned
    # SIMBICON balance feedback on the landing leg (Yin et al. 2007: c_d 0-0.5 rad/m,
    # c_v 0.2-0.5 rad·s/m in their gaits); ours within those ranges.
    reach_thigh_deg: float = 2.229794173410217  # θ_0 of the swing thigh (tuned)
    land_thigh_deg: float = -1.7510830016397998  # θ_0, Fall and Flight (tuned)
    balance_cd_rad_per_m: float = 0.694323281325778  # tuned
    balance_cv_rad_s_per_m: float = 0.22172295391208885  # tuned
    # Walking on (step_reach) toward the speed before the trip (ours): the reaching thigh
    # also leans forward by k_s·(v − v_trip), v the COM's forward speed and v_trip the
    # speed walked before the trip, so a faster gait places its foot further ahead and
    # brakes (a speed error beside SIMBICON's speed term, Yin et al. 2007). 0: off.
    walk_on_speed_gain_rad_s_per_m: float = 0.0
    # ... phased in over this many walk-on landings (ours): the gain is k_s·min(1, n/N)
    # after n landings (0 for the first walk-on step), so the first steps regain balance
    # and the later ones the speed. 0: the whole gain from the first step.
    walk_on_speed_ramp_steps: float = 0.0
    # Walking on at the speed before the trip by feedforward (ours): SIMBICON's speed
    # term c_v·v becomes c_v·(v − f·(v_trip − v_ref)), so the walk on's own steady speed
    # v_ref (where it settles whatever the speed before: 1.15-1.19 m/s for the upright
    # set before it had this, docs/fsm-fits.md "Walking on, upright") moves toward v_trip by
    # the fraction f without a larger feedback gain (in SIMBICON's steady gait c_v·v is
    # what holds the thigh's angle, so f = 1 moves the steady speed all the way); phased
    # in as k_s is.
    # f = 0: off.
    walk_on_speed_feedforward: float = 0.0
    walk_on_speed_ref_m_per_s: float = 1.17
    # The slowest speed the walk on aims for (ours, 2026-12-04): both speed terms above take
    # max(v_trip, this) for v_trip. The walk-on gait was tuned on trips at 1.0-1.4 m/s;
    # aiming it at slower walking makes it fall or stop: force trips at swing 0.05-0.75
    # with the default `upright` set walk on after 15 of 15 at 1.0 m/s but 4 of 15 at
    # 0.9 and 1 of 15 at 0.8 when it aims at the speed before the trip. Trips at 1.0 m/s
    # and faster are unchanged bit for bit.
    walk_on_speed_floor_m_per_s: float = 1.0
    # Walking on with double support (ours): after each walk-on landing the trailing leg
    # pushes off for this long (targets step_push) before it swings. 0: off, the swing
    # starts at the landing (SIMBICON's gait, Yin et al. 2007).
    walk_on_push_s: float = 0.0
    # The walk on's swing lasts at least this long before the leg reaches (ours): a
    # slower cadence, as people's steps (0.53-0.65 s at 1.4-1.0 m/s in our walk). 0: the
    # leg reaches once its foot passes the stance foot, as in the recovery step.
    walk_on_swing_min_s: float = 0.0
    # Flight at fast walking (``FLIGHT``; ours, 0 off): the elevating support ankle's
    # Clearance target (elev_sup_ankle) plantarflexes this much further (deg, negative)
    # at the fast end of kc_speeds, phased in with the walking speed as k_c is. SCA 2009
    # §5 gets its flights at about 1.4 m/s from k_c = 300 (eq. 4) on the same ankle; on
    # our body and walk on that loses most recoveries (29 of 48 walk on with upright),
    # so the push is raised through the target instead, where double support at 1.0 m/s
    # is untouched (weight 0).
    elev_sup_ankle_fast_deg: float = 0.0
    # Flight in the lowering strategy at fast walking (``FLIGHT``; ours, all 0 off): the
    # lowering Fall's targets (``LOW_FALL_FAST_TARGETS``: the lowered, now support, leg's
    # ankle and knee, the recovery leg's knee and ankle) move by these offsets (deg)
    # at the fast end of kc_speeds, phased in with the walking speed as k_c is, in a
    # table of the lowering's own (``fall_lowering``, from ``fall``). The support ankle
    # pushes the body off the floor, and the recovery leg lands on a flexed knee, as in
    # a running step (SCA 2009 §3.3: "a flight phase or double support phase might
    # occur"; seed 000 Table 1: 3 of 7 lowering trips fly at 1.44 m/s).
    low_fall_fast_deg: dict[str, float] = field(
        default_factory=lambda: dict.fromkeys(LOW_FALL_FAST_TARGETS, 0.0))
    # Flight in the lowering strategy by SCA 2009's own law (``LOWERING_FLIGHT``; ours:
    # None and -1 m leave the lowering as the elevating). k_c of the lowering Clearance
    # at the fast end of kc_speeds (N·m·s/m; None: kc_fast). SCA 2009 §5 uses 300 at
    # fast walking for both strategies; on our body the lowered leg's push then flies in
    # 9 of the 10 lowering trips at 1.4 m/s, while the elevating trips lose their
    # recoveries at that gain (``kc_fast``'s comment), hence a gain of the lowering's own.
    kc_lowering_fast: float | None = None
    # ... which acts only once the COM is this far ahead of the lowered (support) foot (m,
    # for the reference body, times h / 1.75 m for another, ``scaled_to``; ours; -1: from
    # the start of Clearance, as SCA 2009). Pushed at once, the lowered
    # leg, still ahead of the COM, throws the body up (the COM 0.12 m higher, its forward
    # speed 1.3 -> 0.5 m/s at k_c 300: measured); people's push-off follows the tripped
    # leg's touch-down (SCA 2009 §3.3: the soleus burst of the push-off about 110 ms after
    # the collision) when the body has passed over it.
    lowering_push_ahead_m: float = -1.0
    balance_cd_lat_rad_per_m: float = 0.5
    balance_cv_lat_rad_s_per_m: float = 0.3
    # The recovery leg extends for touch-down (rectus femoris; Fall) only once its toe is
    # this far past where the trip stopped the swing foot: the obstacle's 0.10 m depth
    # and 2 cm to spare (ours; the controller knows where it tripped, not the obstacle).
    clear_margin_m: float = 0.11489045028742148  # tuned
    # COM vertical velocity below which the COM "starts to fall" (SCA 2009 §4.3)
    fall_vz_m_per_s: float = 0.0
    # Flight from Fall (ours; a setting): SCA 2009 §4.3 enters Flight when "the stance leg
    # leaves the ground during Clearance". Our support foot leaves the floor later, in
    # Fall, and lands again before the recovery foot (a hop: double support at the
    # recovery landing). With this on, a support foot off the floor for
    # ``flight_lift_s`` in Fall, the recovery foot in the air, starts Flight too (rear leg
    # flexed, front leg extended), and the recovery foot lands from the air.
    flight_from_fall: bool = False
    flight_lift_s: float = 0.012  # ours: three 4 ms samples, not a flicker

    def delay(self, key: str) -> float:
        """Latency + activation-to-torque offset, times the delay scale (s)."""
        return (self.latency_s[key] + self.activation_to_torque_s) * self.delay_scale

    def values(self) -> dict[str, float]:
        """The tunable values by name (``TUNABLE``: ``SPACE``, ``GAINS``, ``WALK_ON``,
        ``FLIGHT``)."""
        out = {}
        for name, (path, _lo, _hi) in TUNABLE.items():
            out[name] = (self._table(path[1])[path[2]] if path[0] == "targets_deg"
                         else getattr(self, path[0])[path[1]] if len(path) == 2
                         else getattr(self, path[0]))
        if out["kc_lowering_fast"] is None:  # (None: the elevating's)
            out["kc_lowering_fast"] = self.kc_fast
        return out

    def _table(self, state: str) -> dict:
        """A state's targets; a derived table (``DERIVED_TABLES``) not set: its source's."""
        if state not in self.targets_deg and state in DERIVED_TABLES:
            return self.targets_deg[DERIVED_TABLES[state]]
        return self.targets_deg[state]

    def with_values(self, values: dict[str, float]) -> FSMParams:
        """A copy with tunable values (``TUNABLE`` names) set; KeyError names an
        unknown one."""
        p = copy.deepcopy(self)
        # a derived table's values after its source's: one equal to the source's (new)
        # value needs no table of its own, one that differs starts from the new source
        derived = [n for n in values if TUNABLE[n][0][0] == "targets_deg"
                   and TUNABLE[n][0][1] in DERIVED_TABLES]
        for name in [*(n for n in values if n not in derived), *derived]:
            value = values[name]
            path = TUNABLE[name][0]
            if path[0] == "targets_deg":
                if path[1] not in p.targets_deg and path[1] in DERIVED_TABLES:
                    if value == p._table(path[1])[path[2]]:
                        continue  # (the source's value: no table of its own needed)
                    p.targets_deg[path[1]] = dict(p.targets_deg[DERIVED_TABLES[path[1]]])
                p.targets_deg[path[1]][path[2]] = value
            elif len(path) == 2:  # kp_passive, low_fall_fast_deg
                getattr(p, path[0])[path[1]] = value
            else:
                setattr(p, path[0], value)
        if self.kc_lowering_fast is None and p.kc_lowering_fast == p.kc_fast:
            p.kc_lowering_fast = None  # (the elevating's, as ``values`` reads it)
        return p

    def scaled_to(self, height_m: float) -> FSMParams:
        """These parameters for a body ``height_m`` tall, under dynamic similarity with the
        reference body (1.75 m): SIMBICON's position gains (rad/m) over the body's length
        scale ℓ = h / 1.75 m, its velocity gains (rad·s/m) over √ℓ (speeds scale as √(gℓ)),
        the COM's lead before the lowering's push (m) times ℓ."""
        ell = height_m / 1.75
        return replace(self, balance_cd_rad_per_m=self.balance_cd_rad_per_m / ell,
                       balance_cv_rad_s_per_m=self.balance_cv_rad_s_per_m / ell ** 0.5,
                       walk_on_speed_gain_rad_s_per_m=(self.walk_on_speed_gain_rad_s_per_m
                                                       / ell ** 0.5),
                       walk_on_speed_ref_m_per_s=self.walk_on_speed_ref_m_per_s * ell ** 0.5,
                       walk_on_speed_floor_m_per_s=(self.walk_on_speed_floor_m_per_s
                                                    * ell ** 0.5),
                       lowering_push_ahead_m=(self.lowering_push_ahead_m * ell
                                              if self.lowering_push_ahead_m > -1.0
                                              else self.lowering_push_ahead_m),
                       balance_cd_lat_rad_per_m=self.balance_cd_lat_rad_per_m / ell,
                       balance_cv_lat_rad_s_per_m=self.balance_cv_lat_rad_s_per_m / ell ** 0.5)

    def speed_weight(self, speed_m_per_s: float) -> float:
        """0 at or below the slow end of ``kc_speeds``, 1 at or above the fast end,
        linear between (our reading of SCA 2009 §5's slow and fast walking)."""
        lo, hi = self.kc_speeds
        return min(max((speed_m_per_s - lo) / (hi - lo), 0.0), 1.0)

    def kc(self, speed_m_per_s: float, strategy: str = "elevating") -> float:
        """Compensation coefficient at a walking speed (SCA 2009 §5, interpolated), for a
        strategy (the lowering's fast end ``kc_lowering_fast`` when set)."""
        w = self.speed_weight(speed_m_per_s)
        fast = (self.kc_lowering_fast if strategy == "lowering"
                and self.kc_lowering_fast is not None else self.kc_fast)
        return (1 - w) * self.kc_slow + w * fast

    def at_speed(self, speed_m_per_s: float) -> FSMParams:
        """These parameters for a trip at ``speed_m_per_s``: the elevating support
        ankle's Clearance target with ``elev_sup_ankle_fast_deg`` phased in, and the
        lowering Fall's own table with ``low_fall_fast_deg`` (itself when all are 0)."""
        low = {k: v for k, v in self.low_fall_fast_deg.items() if v}
        if not self.elev_sup_ankle_fast_deg and not low:
            return self
        w = self.speed_weight(speed_m_per_s)
        p = copy.deepcopy(self)
        p.targets_deg["clearance_elevating"]["sup.ankle_angle"] += (
            w * self.elev_sup_ankle_fast_deg)
        if low:
            fall = p.targets_deg.setdefault("fall_lowering", dict(p.targets_deg["fall"]))
            for key, offset in low.items():
                target = LOW_FALL_FAST_TARGETS[key]
                start = fall.get(target,
                                 p.targets_deg["clearance_lowering"].get(target, "hold"))
                if not isinstance(start, float | int):
                    raise ValueError(f"fall target {target} is {start!r}, not an angle: "
                                     f"low_fall_{key}_fast cannot move it")
                fall[target] = start + w * offset
        return p

    def strategy_for(self, swing_fraction: float) -> str:
        """``auto``: elevating below 0.3 of swing, lowering above 0.5; in between, elevating
        up to ``strategy_threshold`` (inclusive)."""
        if swing_fraction < self.elevating_below:
            return "elevating"
        if swing_fraction > self.lowering_above:
            return "lowering"
        return "elevating" if swing_fraction <= self.strategy_threshold else "lowering"


# The targets and gains tuned on human strength (``--strength anderson2007``), with the
# command that found them (CMA-ES, seeded; ``fit`` in the file): under the 1 s rule
# (``Scenario.recovery`` step), and walking on 6 s with the trunk within 26° (walk_on,
# the default rule; searched from the upright set, two stages)
HUMAN_STRENGTH_FILE = Path(__file__).parent / "data" / "fsm_anderson2007.json"
HUMAN_STRENGTH_WALK_ON_FILE = Path(__file__).parent / "data" / "fsm_anderson2007_walk_on.json"


def human_strength_params(recovery: str = "walk_on") -> FSMParams:
    """The state machines' parameters for human strength and a recovery rule
    (``default_params("anderson2007", recovery)``): walking on, the set searched walking
    on (``HUMAN_STRENGTH_WALK_ON_FILE``, with its settings); under ``step`` the defaults
    with the values ``scripts/tune_fsm.py --strength anderson2007`` found
    (``HUMAN_STRENGTH_FILE``)."""
    return default_params("anderson2007", recovery)


# Walking on upright (issue 11): the trunk limit of 26° at recovery-foot contact
# (trunk_attitude 0.3 in its settings) and the walk on's own gait (WALK_ON), searched
# under --recovery walk_on; the command that found it and its figures are its "fit".
UPRIGHT_FILE = Path(__file__).parent / "data" / "fsm_upright.json"

# Flight in both strategies at fast walking (issue 11): the upright set with the lowering
# strategy's flight (LOWERING_FLIGHT) and its lowering targets searched on it, walking on
# with the trunk within 26°; the commands that found it and its figures are its "fit".
FLIGHT_FILE = Path(__file__).parent / "data" / "fsm_flight.json"

# The targets and gains tuned under the 1 s rule (``Scenario.recovery`` step): the
# class defaults of FSMParams, the default set until 2026-12-03 (an empty file: it
# changes nothing).
STEP_FILE = Path(__file__).parent / "data" / "fsm_step.json"

# The push-off with the recovery hip capped (issue 11): the targets and gains searched
# from ``flight`` with push_off_rec_hip_limit_nm 60 in its settings, against the support
# limb's push-off beyond people's (scripts/tune_fsm.py --rec-hip-cap 60 --push-off 1; the
# command and its figures are its "fit"). The support hip pushes off with half of
# flight's moment, but it walks on after fewer of the six bodies' trips and flies less:
# an experiment, not the default (docs/fsm-fits.md, "Where it stands").
HIP_CAP_FILE = Path(__file__).parent / "data" / "fsm_hip_cap.json"

# The push-off with the support knee capped (issue 11): the targets and gains searched
# from ``flight`` with push_off_sup_knee_limit_nm 80 in its settings (scripts/tune_fsm.py
# --sup-knee-cap 80; the commands and their figures are its "fit"). The support knee
# pushes off within 1.5 times people's, and it keeps flight's figures for issue 11 (47 of
# 48, the bodies 87 of 96, the flights); the hip is flight's. The default from
# 2026-12-06 to 2026-12-07 (docs/fsm-fits.md, "Where it stands").
KNEE_CAP_FILE = Path(__file__).parent / "data" / "fsm_knee_cap.json"

# Flights that land the recovery foot from the air (issue 11): the knee-capped set with
# ``flight_from_fall`` on, the lowering Clearance's push at about SCA 2009's strength
# (k_c 350 at 1.4 m/s, §5: 300) and the landing after a flight searched with it (the
# commands and their figures are its "fit"). 47 of 48 and the bodies' 87 of 96 walk on,
# and at 1.4 m/s 4 of 6 elevating and 3 of 5 lowering window recoveries fly (none at
# 1.0 m/s); the default on 2026-12-07 (docs/fsm-fits.md, "Lowering flights").
FLIGHT_FROM_FALL_FILE = Path(__file__).parent / "data" / "fsm_flight_from_fall.json"

# The recovery hip capped in the push-off (issue 11): ``flight_from_fall`` searched with
# push_off_rec_hip_limit_nm 200 in its settings, then the cap raised by hand to 230 N·m,
# the lowest of a scan at which every recovery keeps the trunk within 26° (the commands
# and their figures are its "fit"). The support hip pushes off at 204 N·m against
# flight_from_fall's 275 (people: 52); 47 of 48 and the bodies' 90 of 96 walk on, and the
# flights are flight_from_fall's. The default since 2026-12-07 (docs/fsm-fits.md, "The
# recovery-hip cap shipped").
REC_HIP_CAP_FILE = Path(__file__).parent / "data" / "fsm_rec_hip_cap.json"

# Both hips capped in the push-off (issue 11): ``rec_hip_cap`` with the support hip's
# attitude servo capped at 150 N·m and the recovery hip's at 160 N·m, searched under
# those caps (the commands and their figures are its "fit"). The support hip pushes off
# at 150 N·m (people: 52); 47 of 48 and the bodies' 88 of 96 walk on within 26°, with
# the flights of ``rec_hip_cap``; not the default: its largest tilt over the bodies is
# 25.98°, 0.02° inside the limit (docs/fsm-fits.md, "Below 204 N·m").
SUP_HIP_CAP_FILE = Path(__file__).parent / "data" / "fsm_sup_hip_cap.json"

SHIPPED = {"flight": FLIGHT_FILE,  # named parameter sets (load_params)
           "upright": UPRIGHT_FILE, "step": STEP_FILE,
           "anderson2007_walk_on": HUMAN_STRENGTH_WALK_ON_FILE,
           "anderson2007": HUMAN_STRENGTH_FILE, "hip_cap": HIP_CAP_FILE,
           "knee_cap": KNEE_CAP_FILE, "flight_from_fall": FLIGHT_FROM_FALL_FILE,
           "rec_hip_cap": REC_HIP_CAP_FILE, "sup_hip_cap": SUP_HIP_CAP_FILE}
# The set a trip runs with when none is named (issue 11: recovered means walking on; the
# rec_hip_cap set walks on after 47 of the 48 grid trips and 90 of the six bodies' 96
# with the trunk within 26°, its support knee pushes off within 1.5 times people's and
# its hip at 204 N·m, and at 1.4 m/s the recovery foot lands from a flight in both
# strategies; ``flight_from_fall`` earlier on 2026-12-07, whose support hip pushes off at
# 275 N·m; ``knee_cap`` from 2026-12-06, whose push-off foot hops but never flies;
# ``flight`` from 2026-12-05, whose knee pushes off at ~150 N·m; ``upright`` until
# 2026-12-05)
DEFAULT_SET = "rec_hip_cap"
# the set a trip runs with when none is named, by (strength model, recovery rule)
DEFAULT_SETS = {("fixed", "walk_on"): DEFAULT_SET, ("fixed", "step"): DEFAULT_SET,
                ("anderson2007", "walk_on"): "anderson2007_walk_on",
                ("anderson2007", "step"): "anderson2007"}
# The settings a parameter file may carry beside its tunable values (its top-level
# "settings" object): FSMParams fields that no search varies but that a set was found
# with (scripts/tune_fsm.py writes its --trunk-attitude and --attitude-damping there).
SETTINGS = ("trunk_attitude", "attitude_damping", "push_off_hip_limit_nm",
            "push_off_rec_hip_limit_nm", "push_off_sup_knee_limit_nm", "flight_from_fall")
# the settings that cap a servo's moment in the push-off (N·m > 0, or None: off)
CAP_SETTINGS = ("push_off_hip_limit_nm", "push_off_rec_hip_limit_nm",
                "push_off_sup_knee_limit_nm")


def check_trunk_attitude(value, where: str) -> float:
    """``value`` as a trunk_attitude (a finite number >= 0), or InputError naming
    ``where`` and the value."""
    from stumble.errors import InputError

    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value) and value >= 0)
    if not ok:
        raise InputError(f"{where}: trunk_attitude = {value!r} is not a finite number >= 0")
    return float(value)


def check_setting(name: str, value, where: str):
    """``value`` as the setting ``name`` (``SETTINGS``), or InputError naming ``where``,
    the setting and the value."""
    from stumble.errors import InputError

    if name == "trunk_attitude":
        return check_trunk_attitude(value, where)
    if name in CAP_SETTINGS:
        ok = value is None or (isinstance(value, (int, float)) and not isinstance(value, bool)
                               and math.isfinite(value) and value > 0)
        if not ok:
            raise InputError(f"{where}: {name} = {value!r} is not a number of N·m > 0 "
                             f"(or null: the servo's own limit)")
        return None if value is None else float(value)
    if name == "flight_from_fall":
        if not isinstance(value, bool):
            raise InputError(f"{where}: flight_from_fall = {value!r} is not true or false")
        return value
    if name == "attitude_damping":
        if not isinstance(value, str) or value not in ATTITUDE_DAMPING:
            raise InputError(f"{where}: attitude_damping = {value!r} is not one of "
                             f"{', '.join(ATTITUDE_DAMPING)}")
        return value
    raise InputError(f"{where}: unknown setting {name!r} (known: {', '.join(SETTINGS)})")


@dataclass(frozen=True)
class ParamsFile:
    """A state-machine parameter file as read: what was asked for (a path or a shipped
    name), the file read, the SHA-256 of its bytes and the parameters it gives."""

    name: str
    path: Path
    sha256: str
    params: FSMParams

    def record(self) -> dict:
        """What a study records of it (study.json ``params``): the file, its SHA-256, the
        tunable values used (``FSMParams.values``, the file's and the defaults') and the
        settings."""
        return {"path": self.name, "file": str(self.path.resolve()), "sha256": self.sha256,
                "values": self.params.values(),
                "settings": {k: getattr(self.params, k) for k in SETTINGS}}


def read_params(path_or_name) -> ParamsFile:
    """``load_params`` with the file it read and that file's SHA-256."""
    from stumble.errors import InputError

    path = Path(SHIPPED.get(str(path_or_name), path_or_name))
    if not path.exists():
        raise InputError(f"{path_or_name}: no such file, nor a shipped state-machine set "
                         f"({', '.join(SHIPPED)})")
    try:
        data = path.read_bytes()
        doc = json.loads(data)
        values = doc["params"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"{path_or_name}: not a state-machine parameter file with "
                         f"\"params\" ({type(e).__name__})") from None
    if not isinstance(values, dict):
        raise InputError(f"{path_or_name}: \"params\" is not an object of named values")
    for key in doc:  # other keys are ignored (a search's score, its command), but not a
        near = difflib.get_close_matches(str(key), ("params", "settings"), 1, 0.7)
        if near and key != near[0]:  # misspelt one of the two that are read
            raise InputError(f"{path_or_name}: unknown key {key!r} (did you mean "
                             f"{near[0]!r}?)")
    space, off = TUNABLE, _own_values()
    for name, value in values.items():
        if name not in space:
            raise InputError(f"{path_or_name}: unknown parameter {name!r}")
        lo, hi = space[name][1:]
        # within its search range, or FSMParams' own value (an option's "off", as
        # lowering_push_ahead -1, which every search's --out file carries)
        if (not isinstance(value, (int, float)) or isinstance(value, bool)
                or not (lo <= value <= hi or value == off[name])):
            raise InputError(f"{path_or_name}: {name} = {value!r} is outside {lo:g}-{hi:g}")
    settings = doc.get("settings", {})
    if not isinstance(settings, dict):
        raise InputError(f"{path_or_name}: \"settings\" is not an object of named values")
    checked = {name: check_setting(name, value, str(path_or_name))
               for name, value in settings.items()}
    p = replace(FSMParams().with_values(values), **checked)
    return ParamsFile(str(path_or_name), path, hashlib.sha256(data).hexdigest(), p)


def shipped_sets_text() -> str:
    """The shipped sets' names for a help text, the default first: "rec_hip_cap (the
    default), flight, ..." (``SHIPPED``, ``DEFAULT_SET``; each set's file says what it
    is, docs/trips.md "Parameter sets" compares them)."""
    rest = [n for n in SHIPPED if n != DEFAULT_SET]
    return ", ".join([f"{DEFAULT_SET} (the default)", *rest])


def default_params(strength_model: str = "fixed", recovery: str = "walk_on") -> FSMParams:
    """The state machines' parameters when none are given, for a strength model and a
    recovery rule (``DEFAULT_SETS``; ``rec_hip_cap`` on fixed torque limits); a copy:
    each file is read once."""
    return copy.deepcopy(_shipped(DEFAULT_SETS[(strength_model, recovery)]))


@functools.cache
def _own_values() -> dict[str, float]:
    """FSMParams' own tunable values (``values``), read once."""
    return FSMParams().values()


@functools.cache
def _shipped(name: str) -> FSMParams:
    return load_params(name)


def load_params(path_or_name) -> FSMParams:
    """The defaults with the tunable values of a JSON file (``{"params": {name: value}}``,
    as ``scripts/tune_fsm.py --out`` writes it) or of a shipped set by name
    (``SHIPPED``), and the file's optional ``"settings"`` (``{"trunk_attitude": k,
    "attitude_damping": "joint"|"pelvis"}``, ``SETTINGS``); InputError names a bad file,
    an unknown name or a value out of range."""
    return read_params(path_or_name).params
