"""Human joint strength (stumble.body.strength): Anderson et al. 2007's torque surfaces."""

import math

import mujoco
import numpy as np
import pytest

from stumble.body import build
from stumble.body.strength import (
    ANDERSON_2007,
    Strength,
    eccentric_peak_velocity,
    max_torque,
    peak_isometric_nm,
    velocity_factor,
)
from stumble.errors import InputError

WH = 70.0 * 9.81 * 1.75  # the default body's weight × height, N·m


def test_peak_isometric_is_c1_times_weight_height():
    peaks = peak_isometric_nm(70.0, 1.75)
    assert peaks["hip_extension"] == pytest.approx(0.161 * WH, abs=0.1)  # 193.5 N·m
    assert peaks["ankle_plantarflexion"] == pytest.approx(0.095 * WH, abs=0.1)  # 114.2
    assert peaks["ankle_dorsiflexion"] == pytest.approx(39.7, abs=0.1)
    assert len(peaks) == 6
    # the any-body rule: strength scales with body weight × height
    assert peak_isometric_nm(90.0, 1.90)["knee_extension"] == pytest.approx(
        peaks["knee_extension"] * 90.0 * 1.90 / (70.0 * 1.75), abs=0.1)


def test_older_and_female_hip_and_knee_are_weaker():
    young, older = peak_isometric_nm(70.0, 1.75), peak_isometric_nm(70.0, 1.75, age="older")
    for ex in ("hip_extension", "hip_flexion", "knee_extension", "knee_flexion"):
        assert older[ex] < young[ex]
    female = peak_isometric_nm(70.0, 1.75, sex="female")
    assert female["knee_flexion"] < young["knee_flexion"]


def test_angle_law_is_the_papers_cosine():
    c1, c2, c3 = ANDERSON_2007[("knee", "extension", "male", "young")][:3]
    at = lambda th: float(max_torque("knee", "extension", th, 0.0, 70.0, 1.75))  # noqa: E731
    assert at(c3) == pytest.approx(c1 * WH)
    assert at(c3 + math.pi / (3 * c2)) == pytest.approx(0.5 * c1 * WH)  # cos 60°
    # far from the optimum the cosine is clipped at the floor (5 % of the peak)
    assert at(c3 + 2.0) == pytest.approx(0.05 * c1 * WH)


def test_velocity_law_c4_and_c5_are_the_75_and_50_percent_speeds():
    c = np.array(ANDERSON_2007[("hip", "flexion", "male", "young")])
    assert float(velocity_factor(c, c[3])) == pytest.approx(0.75)
    assert float(velocity_factor(c, c[4])) == pytest.approx(0.5)
    assert float(velocity_factor(c, 0.0)) == pytest.approx(1.0)
    # eccentric: the paper's branch, and held at its peak beyond it (our choice)
    v = float(eccentric_peak_velocity(c)[0])
    assert 0.5 < v < 5.0
    held = velocity_factor(c, np.array([-v, -2 * v, -4 * v]), v_hold=v)
    assert np.allclose(held, held[0]) and held[0] > 1.0
    assert float(velocity_factor(c, -4 * v)) < held[0]  # as printed it falls again


def test_servo_body_limits_follow_angle_and_velocity():
    body = build(planar=False, actuation="servos")
    m = body.model
    d = mujoco.MjData(m)
    s = Strength.for_model(m, 70.0, 1.75)
    names = sorted(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in s.ids)
    assert names == ["ankle_angle_l", "ankle_angle_r", "hip_flexion_l", "hip_flexion_r",
                     "knee_angle_l", "knee_angle_r"]
    s.apply(m, d)
    knee = m.actuator("knee_angle_r").id
    c_ext = ANDERSON_2007[("knee", "extension", "male", "young")]
    c_flex = ANDERSON_2007[("knee", "flexion", "male", "young")]
    # straight knee, at rest: a positive (extending) torque is the knee extensors'
    assert m.actuator_forcerange[knee, 1] == pytest.approx(
        c_ext[0] * WH * math.cos(c_ext[1] * (0.0 - c_ext[2])))
    assert m.actuator_forcerange[knee, 0] == pytest.approx(
        -c_flex[0] * WH * math.cos(c_flex[1] * (0.0 - c_flex[2])))
    # our knee flexes negative: at 60° of flexion the extensors are near their optimum
    qadr = m.jnt_qposadr[m.joint("knee_angle_r").id]
    d.qpos[qadr] = -math.radians(60.0)
    s.apply(m, d)
    assert m.actuator_forcerange[knee, 1] > 0.95 * c_ext[0] * WH
    # extending fast (concentric for the extensors) weakens them
    d.qvel[m.jnt_dofadr[m.joint("knee_angle_r").id]] = 4.0
    s.apply(m, d)
    assert m.actuator_forcerange[knee, 1] < 0.6 * c_ext[0] * WH
    # the strength scale multiplies every limit
    s2 = Strength.for_model(m, 70.0, 1.75, scale=0.5)
    lo, hi = s.limits(d.qpos, d.qvel)
    lo2, hi2 = s2.limits(d.qpos, d.qvel)
    assert np.allclose(hi2, 0.5 * hi) and np.allclose(lo2, 0.5 * lo)


def test_bad_strength_inputs_are_named():
    body = build(planar=False, actuation="servos")
    with pytest.raises(InputError, match="age group 'ancient'"):
        Strength.for_model(body.model, 70.0, 1.75, age="ancient")
    with pytest.raises(InputError, match="eccentric branch 'x'"):
        Strength.for_model(body.model, 70.0, 1.75, eccentric="x")


def test_trip_with_human_strength_stays_within_it_and_reports_push_off():
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    r = simulate_trip(Scenario(swing_fraction=0.2, strength_model="anderson2007",
                               duration_after_trip_s=1.0))
    s = r.summary
    assert s["strength_model"] == "anderson2007" and s["population"] == "young"
    push = s["support_peak_moments_nm"]
    assert set(push) == {"hip_extension", "hip_flexion", "knee_flexion", "knee_extension",
                         "ankle_plantarflexion", "ankle_dorsiflexion"}
    peaks = peak_isometric_nm(70.0, 1.75)
    # a servo never exceeds the exertion's strength (eccentric at most ~1.2 x isometric)
    for name in ("hip_extension", "knee_flexion", "ankle_plantarflexion"):
        assert 0.0 < push[name] <= 1.25 * peaks[name]
    fixed = simulate_trip(Scenario(swing_fraction=0.2, duration_after_trip_s=1.0)).summary
    # the fixed limits let the support hip push far past a person's strength
    assert fixed["support_peak_moments_nm"]["hip_extension"] > 1.1 * peaks["hip_extension"]


def test_older_population_is_weaker_and_slower():
    from stumble.control.fsm_params import FSMParams
    from stumble.control.make import trip_controller
    from stumble.pipeline import simulate_trip
    from stumble.trip import POPULATIONS, Scenario

    older = POPULATIONS["older"]
    assert older.age == "older" and older.preferred_speed_m_per_s == 1.17
    sc = Scenario(swing_fraction=0.2, population="older", duration_after_trip_s=0.5)
    ctl = trip_controller(sc.validated(), "elevating", None, None, None, 0.0)
    assert ctl.p.latency_s["sup.ankle_angle"] == pytest.approx(
        FSMParams().latency_s["sup.ankle_angle"] + 0.011)  # Pijnappels et al. 2005 (EBR)
    # torque develops 30 % slower (Thelen et al. 1996): 50 ms from activation to torque
    # become 71 ms, for every response
    assert ctl.p.activation_to_torque_s == pytest.approx(0.050 / 0.7)
    assert ctl.p.delay("sup.hip_flexion") == pytest.approx(0.050 + 0.050 / 0.7)
    young = trip_controller(Scenario(swing_fraction=0.2).validated(), "elevating", None,
                            None, None, 0.0)
    assert young.p.activation_to_torque_s == 0.050
    m = simulate_trip(sc).body.model
    hip = m.actuator("hip_flexion_l").id
    ratio = (ANDERSON_2007[("hip", "extension", "male", "older")][0]
             / ANDERSON_2007[("hip", "extension", "male", "young")][0])
    assert m.actuator_forcerange[hip, 0] == pytest.approx(-300.0 * ratio)


def test_scale_strength_multiplies_servo_limits_and_muscle_fmax():
    """A scenario's strength scale: every servo's torque limit and every muscle's F_max
    (gainprm[2] and biasprm[2] of a MuJoCo muscle) times the scale, nothing else."""
    from stumble.body.strength import scale_strength

    servos = build().model
    limits = servos.actuator_forcerange.copy()
    scale_strength(servos, 0.5)
    assert np.array_equal(servos.actuator_forcerange, 0.5 * limits)
    assert np.abs(limits).max() == 300.0  # the fixed hip limit, N·m
    muscles = build(planar=True, actuation="muscles").model
    is_muscle = muscles.actuator_gaintype == mujoco.mjtGain.mjGAIN_MUSCLE
    assert is_muscle.sum() == 14  # seed 003's seven a leg, build's default set
    fmax, gain0 = muscles.actuator_gainprm[:, 2].copy(), muscles.actuator_gainprm[:, 0].copy()
    scale_strength(muscles, 2.0)
    assert np.array_equal(muscles.actuator_gainprm[is_muscle, 2], 2.0 * fmax[is_muscle])
    assert np.array_equal(muscles.actuator_biasprm[is_muscle, 2],
                          muscles.actuator_gainprm[is_muscle, 2])
    assert np.array_equal(muscles.actuator_gainprm[:, 0], gain0)
