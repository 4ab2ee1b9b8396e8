"""The SCA 2009 state-machine controllers: strategy rule, latencies, transitions, falls."""

import json
import re

import numpy as np
import pytest

from stumble.control.fsm_params import FSMParams
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario


@pytest.mark.parametrize(("f", "strategy"), [
    (0.05, "elevating"), (0.25, "elevating"), (0.35, "elevating"), (0.45, "elevating"),
    (0.5, "elevating"), (0.55, "lowering"), (0.9, "lowering"),
])
def test_auto_strategy_by_swing_fraction(f, strategy):
    assert FSMParams().strategy_for(f) == strategy


def test_latencies_add_the_activation_offset_and_scale():
    p = FSMParams()
    assert p.delay("elev.rec.knee_angle") == pytest.approx(0.064 + 0.050)  # SCA 2009 §3.2
    p.delay_scale = 2.0
    assert p.delay("sup.ankle_angle") == pytest.approx(2 * (0.075 + 0.050))


def test_compensation_coefficient_follows_speed():
    from stumble.control.fsm_params import KC_FAST, KC_SLOW

    assert (KC_SLOW, KC_FAST) == (50.0, 300.0)  # SCA 2009 §5
    paper = FSMParams(kc_slow=KC_SLOW, kc_fast=KC_FAST)
    assert paper.kc(0.8) == pytest.approx(50.0)  # slow walking
    assert paper.kc(1.5) == pytest.approx(300.0)  # fast walking
    assert 50.0 < paper.kc(1.2) < 300.0
    ours = FSMParams()  # tuned values (see fsm_params.py)
    assert ours.kc(0.8) < ours.kc(1.2) < ours.kc(1.5) == pytest.approx(ours.kc_fast)


@pytest.fixture(scope="module")
def elevating():
    return simulate_trip(Scenario(swing_fraction=0.2, speed_m_per_s=1.0))


@pytest.fixture(scope="module")
def lowering():
    return simulate_trip(Scenario(swing_fraction=0.65, speed_m_per_s=1.0))


def test_elevating_sequence_follows_sca_2009(elevating):
    names = [s["name"] for s in elevating.summary["states"]]
    assert names[:2] == ["passive_reaction", "clearance"]
    assert names[2] in ("flight", "fall")
    nxt = {"flight": "single_support_after_trip", "fall": "double_support"}[names[2]]
    assert names[3] == nxt
    # Clearance starts with the earliest response: hamstrings 50 ms + 50 ms (SCA 2009)
    assert elevating.summary["states"][1]["start_s"] == pytest.approx(0.100, abs=0.003)
    assert elevating.summary["strategy"] == "elevating"


def test_lowering_sequence_follows_sca_2009(lowering):
    names = [s["name"] for s in lowering.summary["states"]]
    assert names[:3] == ["passive_reaction", "leg_swap", "clearance"]
    assert lowering.summary["strategy"] == "lowering"
    assert lowering.summary["variant"] in ("double_support", "flight")


def test_a_hop_is_no_flight_and_flight_from_fall_makes_one():
    """The force trip at 0.25 of swing, 1.4 m/s on the ``knee_cap`` set (the default
    until 2026-12-07): the push-off foot hops (both feet off 56 ms) but is down again
    when the recovery foot lands: double support, no Flight state. With
    ``flight_from_fall`` the hop starts Flight, and the recovery foot lands from the air."""
    from dataclasses import replace

    from stumble.control.fsm_params import load_params

    sc = Scenario(swing_fraction=0.25, speed_m_per_s=1.4)
    hop = simulate_trip(sc, params=load_params("knee_cap")).summary
    names = [s["name"] for s in hop["states"]]
    assert hop["variant"] == "double_support" and "flight" not in names
    assert hop["airborne_before_landing_s"] == pytest.approx(0.056, abs=0.01)
    fly = simulate_trip(sc, params=replace(load_params("knee_cap"),
                                           flight_from_fall=True)).summary
    names = [s["name"] for s in fly["states"]]
    assert fly["variant"] == "flight" and names[2:4] == ["fall", "flight"]
    assert fly["airborne_before_landing_s"] > 0.1
    # a Flight whose rear leg stays down (SCA 2009's table with the hip at -30°): the hop
    # lands before the recovery foot, and the controller goes back to Fall, not on in
    # Flight on a standing leg
    stay = replace(load_params("knee_cap"), flight_from_fall=True).with_values(
        {"fl_sup_knee": -5.0, "fl_sup_hip": -30.0, "fl_sup_ankle": -40.0})
    back = simulate_trip(sc.with_(swing_fraction=0.15), params=stay).summary
    names = [s["name"] for s in back["states"]]
    assert names[2:6] == ["fall", "flight", "fall", "double_support"]
    assert back["variant"] == "double_support"


def test_a_weak_body_falls():
    weak = simulate_trip(Scenario(swing_fraction=0.2, speed_m_per_s=1.2, strength_scale=0.1))
    assert weak.summary["fell"] and not weak.summary["recovered"]
    assert weak.summary["fall_time_s"] < 2.0


def test_same_inputs_give_the_same_numbers():
    a = simulate_trip(Scenario(swing_fraction=0.3, speed_m_per_s=1.2, duration_after_trip_s=0.6))
    b = simulate_trip(Scenario(swing_fraction=0.3, speed_m_per_s=1.2, duration_after_trip_s=0.6))
    assert (a.recording.qpos == b.recording.qpos).all()


@pytest.mark.parametrize(("f", "v", "mechanism", "strategy"), [
    (0.2, 1.2, "force", "elevating"), (0.15, 1.0, "obstacle", "elevating"),
    (0.75, 1.2, "force", "lowering"), (0.65, 1.2, "force", "lowering"),
    # the tripped leg, behind the box, crosses it in Double Support (double_support_lowering)
    (0.75, 1.4, "obstacle", "lowering"),
])
def test_trips_that_recover(f, v, mechanism, strategy):
    r = simulate_trip(Scenario(swing_fraction=f, speed_m_per_s=v, mechanism=mechanism))
    s = r.summary
    assert s["strategy"] == strategy
    assert s["recovered"] and not s["fell"] and not s["diverged"]
    assert s["recovery_contact_s"] is not None and s["sim_time_s"] >= s["recovery_contact_s"] + 1
    assert s["trunk_tilt_at_recovery_contact_deg"] < 45.0


def test_seed_perturbs_the_start_reproducibly_and_params_are_not_mutated():
    p = FSMParams()
    short = {"swing_fraction": 0.3, "duration_after_trip_s": 0.5}
    a = simulate_trip(Scenario(seed=7, delay_scale=1.5, **short), params=p)
    b = simulate_trip(Scenario(seed=7, **short))
    c = simulate_trip(Scenario(seed=0, **short))
    assert p.delay_scale == 1.0  # the caller's parameters are left alone
    assert (b.recording.qpos[0] != c.recording.qpos[0]).any()
    d = simulate_trip(Scenario(seed=7, **short))
    assert (b.recording.qpos == d.recording.qpos).all()
    assert a.summary["seed"] == 7


def test_lowering_double_support_has_its_own_targets():
    from stumble.control.fsm import TripFSM

    low, elev = (TripFSM(s, "l", 1.2) for s in ("lowering", "elevating"))
    assert low._table("double_support") == "double_support_lowering"
    assert elev._table("double_support") == "double_support"
    assert low._table("fall") == "fall"  # no lowering table of its own
    assert low._table("single_support_after_trip") == "single_support_after_trip_lowering"
    assert elev._table("single_support_after_trip") == "single_support_after_trip"


def test_lowering_tripped_leg_crosses_the_obstacle_then_swings_as_in_walking():
    """After a lowering recovery step the tripped leg, behind the box, swings over it with
    the crossing targets (knee flexed past 90°) and, once its toe is past the box, with
    Single Support After Trip's own; it grazes the box for at most 40 ms and walks on
    (0.55 of swing, 1.0 m/s: with the walking targets alone the swing caught the box and
    the body fell 1.1 s after the trip)."""
    r = simulate_trip(Scenario(swing_fraction=0.55, speed_m_per_s=1.0, mechanism="obstacle",
                               duration_after_trip_s=2.0, recovery="step"), params=FSMParams())
    s, rec = r.summary, r.recording
    assert s["strategy"] == "lowering" and s["recovered"] and not s["fell"]
    ssat = [k for k, st in enumerate(rec.state) if st == "single_support_after_trip"]
    assert ssat, "no Single Support After Trip"
    knee = np.degrees(rec.qpos[ssat, r.body.model.joint("knee_angle_l").qposadr[0]])
    assert knee.min() < -90.0  # the tripped (left) knee flexes to cross
    dt = rec.time_s[1] - rec.time_s[0]
    touching_s = rec.foot_on_obstacle[ssat[0]:, 1].sum() * dt
    assert touching_s <= 0.04, f"the tripped foot held on the box for {touching_s:.3f} s"


def test_gains_and_balance_feedback_scale_with_the_body():
    from stumble.body import build as build_body
    from stumble.body.build import body_scale
    from stumble.control.fsm_params import FSMParams
    from stumble.control.pd import ServoBank

    big = build_body(height_m=1.90, mass_kg=90.0, actuation="servos")
    scale = 90.0 * 1.90 / (70.0 * 1.75)
    assert body_scale(90.0, 1.90) == pytest.approx(scale)
    # torque limits scale as strength does (body weight x height)
    hip = big.model.actuator("hip_flexion_r").id
    assert big.model.actuator_forcerange[hip, 1] == pytest.approx(300.0 * scale)
    bank = ServoBank(big)
    bank.set_gains(np.full(len(bank.names), 1000.0))
    assert big.model.actuator_gainprm[hip, 0] == pytest.approx(1000.0 * scale)
    kd = -big.model.actuator_biasprm[hip, 2]
    assert kd / big.model.actuator_gainprm[hip, 0] == pytest.approx(0.1 * (1.90 / 1.75) ** 0.5)
    flat = ServoBank(big, scaling="none")
    flat.set_gains(np.full(len(flat.names), 1000.0))
    assert big.model.actuator_gainprm[hip, 0] == pytest.approx(1000.0)
    p = FSMParams().scaled_to(1.90)
    assert p.balance_cd_rad_per_m == pytest.approx(FSMParams().balance_cd_rad_per_m * 1.75 / 1.90)
    # speeds scale as sqrt(g h): the walk on's own steady speed too
    assert p.walk_on_speed_ref_m_per_s == pytest.approx(1.17 * (1.90 / 1.75) ** 0.5)
    assert FSMParams().scaled_to(1.75) == FSMParams()
    # the COM's lead before the lowering's push is a length; its "off" (-1) stays off
    assert FSMParams(lowering_push_ahead_m=0.07).scaled_to(1.5).lowering_push_ahead_m == \
        pytest.approx(0.06)
    assert FSMParams().scaled_to(1.5).lowering_push_ahead_m == -1.0


def test_tunable_values_and_the_human_strength_set():
    import json

    from stumble.control.fsm_params import (
        ELEV_FLIGHT,
        FLIGHT,
        GAINS,
        HUMAN_STRENGTH_FILE,
        LATERAL,
        LOWERING_FLIGHT,
        SPACE,
        WALK_ON,
        human_strength_params,
    )

    p = FSMParams()
    assert set(p.values()) == (set(SPACE) | set(GAINS) | set(WALK_ON) | set(FLIGHT)
                               | set(LOWERING_FLIGHT) | set(LATERAL) | set(ELEV_FLIGHT))
    assert len(SPACE) == 27
    assert p.with_values(p.values()) == p
    q = p.with_values({"kp_knee": 123.0, "ssat_swing_s": 0.3})
    assert q.kp_passive["knee"] == 123.0 and q.ssat_swing_s == 0.3
    assert p.kp_passive["knee"] == FSMParams().kp_passive["knee"] != 123.0  # untouched
    with pytest.raises(KeyError):
        p.with_values({"no_such_target": 1.0})
    shipped = json.loads(HUMAN_STRENGTH_FILE.read_text())
    assert "--strength anderson2007" in shipped["fit"]["command"]
    h = human_strength_params("step")
    # (a set tuned before a target was tunable keeps the default of that one)
    assert {k: h.values()[k] for k in shipped["params"]} == pytest.approx(shipped["params"])
    assert h != p
    for name, (_path, lo, hi) in {**SPACE, **GAINS}.items():
        assert lo <= h.values()[name] <= hi, name


def test_load_params_names_bad_files_and_values(tmp_path):
    import json

    from stumble.control.fsm_params import human_strength_params, load_params
    from stumble.errors import InputError

    assert load_params("anderson2007") == human_strength_params("step")
    # walking on (the default rule), the set searched walking on, with its settings
    on = human_strength_params("walk_on")
    assert on == load_params("anderson2007_walk_on") and on.trunk_attitude == 0.3
    good = tmp_path / "p.json"
    good.write_text(json.dumps({"params": {"kp_knee": 250.0}}))
    assert load_params(good).kp_passive["knee"] == 250.0
    for text, match in (("nope", "not a state-machine parameter file"),
                        ('{"params": {"kp_kne": 1}}', "unknown parameter 'kp_kne'"),
                        ('{"params": {"kp_knee": 5000}}', "kp_knee = 5000 is outside 100-800"),
                        ('{"params": [1]}', "is not an object")):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(InputError, match=match):
            load_params(bad)
    with pytest.raises(InputError, match="nosuch: no such file, nor a shipped state-machine"):
        load_params("nosuch")


def test_a_params_file_carries_its_settings(tmp_path):
    import hashlib
    import json

    from stumble.control.fsm_params import load_params, read_params
    from stumble.errors import InputError

    f = tmp_path / "t.json"
    f.write_text(json.dumps({"params": {"kp_knee": 250.0}, "settings": {"trunk_attitude": 0.3}}))
    p = load_params(f)
    assert p.trunk_attitude == 0.3 and p.kp_passive["knee"] == 250.0
    assert load_params("anderson2007").trunk_attitude == 0.0  # no settings: the default
    rec = read_params(f).record()
    assert rec["path"] == str(f) and rec["sha256"] == hashlib.sha256(f.read_bytes()).hexdigest()
    assert rec["values"]["kp_knee"] == 250.0
    assert rec["settings"] == {"trunk_attitude": 0.3, "attitude_damping": "joint",
                               "push_off_hip_limit_nm": None,
                               "push_off_rec_hip_limit_nm": None,
                               "push_off_sup_knee_limit_nm": None,
                               "flight_from_fall": False}
    f.write_text(json.dumps({"params": {}, "settings": {"attitude_damping": "pelvis"}}))
    assert load_params(f).attitude_damping == "pelvis" and load_params(f).trunk_attitude == 0.0
    for settings, match in (('{"trunk_attitude": -0.5}', "trunk_attitude = -0.5 is not"),
                            ('{"trunk_attitude": NaN}', "trunk_attitude = nan is not"),
                            ('{"trunk_attitude": Infinity}', "trunk_attitude = inf is not"),
                            ('{"trunk_attitude": "0.3"}', "trunk_attitude = '0.3' is not"),
                            ('{"trunk_attitude": true}', "trunk_attitude = True is not"),
                            ('{"trunk_atitude": 0.3}', "unknown setting 'trunk_atitude'"),
                            ('{"attitude_damping": "torso"}',
                             "attitude_damping = 'torso' is not one of joint, pelvis"),
                            ('{"attitude_damping": 1}', "attitude_damping = 1 is not one of"),
                            ('[0.3]', '"settings" is not an object')):
        bad = tmp_path / "bad.json"
        bad.write_text(f'{{"params": {{}}, "settings": {settings}}}')
        with pytest.raises(InputError, match=match) as e:
            load_params(bad)
        assert str(e.value).startswith(f"{bad}: ") and "\n" not in str(e.value)


def _tune_fsm():
    """scripts/tune_fsm.py as a module (its functions; no search is run)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / "scripts" / "tune_fsm.py"
    spec = importlib.util.spec_from_file_location("tune_fsm", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_tune_fsm_out_carries_its_settings_to_around_and_load_params(tmp_path, monkeypatch):
    import json
    import re

    from stumble.control.fsm_params import load_params
    from stumble.errors import InputError

    tune = _tune_fsm()
    monkeypatch.setattr(tune, "TRUNK_ATTITUDE", 0.4)
    monkeypatch.setattr(tune, "ATTITUDE_DAMPING", "pelvis")
    monkeypatch.setattr(tune, "REC_HIP_CAP", 60.0)
    best = ({"kp_knee": 250.0, "elev_sup_ankle": -30.0}, (40, 100.0, 40, 0.0, 0, 0.0, 2, 1))
    out = tmp_path / "best.json"
    rec = tune.out_record(best, 3, ["--trunk-attitude", "0.4"])
    assert rec["over_tilt"] == 2  # the walks on past --max-tilt, counted in the record
    assert rec["unsettled"] == 1  # the walks on that never settle (--unsettled)
    out.write_text(json.dumps(rec, indent=1))
    # the search's file is a parameter file: the values and the trunk attitude it ran with
    p = load_params(out)
    assert p.trunk_attitude == 0.4 and p.kp_passive["knee"] == 250.0
    assert p.attitude_damping == "pelvis" and p.push_off_rec_hip_limit_nm == 60.0
    assert p.targets_deg["clearance_elevating"]["sup.ankle_angle"] == -30.0
    assert p == tune.params_from(best[0])  # what the search measured
    # --around FILE (and the file's text) reads both back
    for around in (str(out), out.read_text()):
        values, settings = tune.read_around(around)
        assert values == best[0]
        assert settings == {"trunk_attitude": 0.4, "attitude_damping": "pelvis",
                            "push_off_rec_hip_limit_nm": 60.0,
                            "push_off_hip_limit_nm": None,
                            "push_off_sup_knee_limit_nm": None,
                               "flight_from_fall": False}
        with pytest.raises(InputError, match=re.escape(
                "--rec-hip-cap 80.0 conflicts with the --around file's "
                "settings.push_off_rec_hip_limit_nm 60.0")):
            tune.setting_of("push_off_rec_hip_limit_nm", 80.0, settings, "--rec-hip-cap")
        assert tune.setting_of("trunk_attitude", None, settings) == 0.4
        assert tune.setting_of("trunk_attitude", 0.4, settings) == 0.4
        assert tune.setting_of("attitude_damping", None, settings) == "pelvis"
        with pytest.raises(InputError, match=re.escape(
                "--trunk-attitude 0.3 conflicts with the --around file's "
                "settings.trunk_attitude 0.4")):
            tune.setting_of("trunk_attitude", 0.3, settings)
        with pytest.raises(InputError, match=re.escape(
                "--attitude-damping joint conflicts with the --around file's "
                "settings.attitude_damping pelvis")):
            tune.setting_of("attitude_damping", "joint", settings)
    # a bare object of names (scripts/fsm_start_*.json) has no settings: the option's or 0
    bare = tmp_path / "start.json"
    bare.write_text(json.dumps(best[0]))
    assert tune.read_around(str(bare)) == (best[0], {})
    assert tune.setting_of("trunk_attitude", None, {}) == 0.0
    assert tune.setting_of("trunk_attitude", 0.3, {}) == 0.3
    assert tune.setting_of("attitude_damping", None, {}) == "joint"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"params": {}, "settings": {"trunk_attitude": -1}}))
    with pytest.raises(InputError, match=f"{bad}: trunk_attitude = -1 is not"):
        tune.read_around(str(bad))
    bad.write_text(json.dumps({"params": {}, "settings": {"push_off_rec_hip_limit_nm": 0}}))
    with pytest.raises(InputError, match=f"{bad}: push_off_rec_hip_limit_nm = 0 is not a "
                       "number of N·m > 0"):
        load_params(bad)


@pytest.mark.parametrize("swing,strategy", [(0.2, "elevating"), (0.65, "lowering")])
def test_walks_on_for_six_seconds_after_the_trip(swing, strategy):
    s = simulate_trip(Scenario(swing_fraction=swing, recovery="walk_on",
                               duration_after_trip_s=6.0)).summary
    assert s["strategy"] == strategy and s["recovered"] and not s["fell"]
    assert s["sim_time_s"] > 5.9 and s["steps_after_recovery_step"] >= 4


@pytest.mark.parametrize(("swing", "aimed_walks_on"), [(0.4, True), (0.6, False)])
def test_slow_walkers_walk_on_at_the_walk_ons_slowest_aim(swing, aimed_walks_on):
    """At 0.8 m/s, below the 1.0-1.4 m/s the sets were tuned on, the walk on aims at
    ``walk_on_speed_floor_m_per_s`` (1.0 m/s), not at the speed before the trip: with the
    default ``rec_hip_cap`` the force trips at 0.4 and 0.6 of swing then walk on 6 s
    at about 1.03-1.06 m/s (``flight_from_fall`` the same; ``knee_cap``: 0.86-1.03;
    ``flight``: 0.94-1.07); aimed at 0.8 m/s the trip at 0.6 falls (the one at 0.4 walks
    on at 0.73 m/s, ``flight_from_fall``'s at 0.83; with ``knee_cap`` neither walks
    on)."""
    from dataclasses import replace

    from stumble.control.fsm_params import default_params

    sc = Scenario(swing_fraction=swing, speed_m_per_s=0.8)
    s = simulate_trip(sc).summary
    assert s["recovered"] and not s["fell"] and 0.84 < s["walk_on_speed_m_per_s"] < 1.15
    aimed = replace(default_params("fixed", "walk_on"), walk_on_speed_floor_m_per_s=0.0)
    a = simulate_trip(sc, params=aimed).summary
    assert a["recovered"] == aimed_walks_on
    if aimed_walks_on:  # walking on at the speed walked before, not the floor's
        assert a["walk_on_speed_m_per_s"] < 0.9 < s["walk_on_speed_m_per_s"]
    assert default_params("fixed", "walk_on").scaled_to(1.95).walk_on_speed_floor_m_per_s \
        == pytest.approx(1.0 * (1.95 / 1.75) ** 0.5)


def test_pelvis_attitude_damped_by_its_own_rate_keeps_the_trunk_up():
    """``attitude_damping`` pelvis (SIMBICON's torso PD on the world rate, an untuned
    option): the same early-swing trip recovers with the trunk at recovery contact about
    15° from vertical, against about 23° when the hip's own joint rate damps it."""
    from dataclasses import replace

    from stumble.errors import InputError

    sc = Scenario(swing_fraction=0.05, speed_m_per_s=1.2, mechanism="force", recovery="step")
    joint = simulate_trip(sc, params=FSMParams()).summary
    pelvis = simulate_trip(sc, params=replace(FSMParams(), attitude_damping="pelvis")).summary
    assert joint["recovered"] and pelvis["recovered"]
    assert pelvis["trunk_tilt_at_recovery_contact_deg"] < 16.0
    assert joint["trunk_tilt_at_recovery_contact_deg"] > 21.0
    with pytest.raises(InputError, match="attitude damping"):
        simulate_trip(sc, params=replace(FSMParams(), attitude_damping="torso"))


def test_trunk_attitude_keeps_the_trunk_within_peoples_tilt_at_recovery_contact():
    """``trunk_attitude`` 0.3 (issue 11): the window's lowering trip at 0.55 of swing,
    1.1 m/s, recovers as it does without it, its trunk at recovery-foot contact 25-26°
    from vertical instead of 32° (people: below about 23-26°, van den Bogert et al. 2002)
    because the lumbar extends before the landing; the support limb's push-off moments
    are those of the default's."""
    from dataclasses import replace

    sc = Scenario(swing_fraction=0.55, speed_m_per_s=1.1, mechanism="obstacle", recovery="step")
    base = simulate_trip(sc, params=FSMParams())
    trunk = simulate_trip(sc, params=replace(FSMParams(), trunk_attitude=0.3))
    b, t = base.summary, trunk.summary
    assert b["recovered"] and t["recovered"]
    assert b["trunk_tilt_at_recovery_contact_deg"] > 30.0
    assert t["trunk_tilt_at_recovery_contact_deg"] < min(
        26.5, b["trunk_tilt_at_recovery_contact_deg"] - 5.0)
    m = trunk.body.model
    j = m.jnt_qposadr[m.joint("lumbar_extension").id]
    k = np.searchsorted(trunk.recording.time_s, t["recovery_contact_s"])
    kb = np.searchsorted(base.recording.time_s, b["recovery_contact_s"])
    assert trunk.recording.qpos[k, j] > base.recording.qpos[kb, j] + np.radians(5.0)
    assert t["support_peak_moments_nm"]["ankle_plantarflexion"] == pytest.approx(
        b["support_peak_moments_nm"]["ankle_plantarflexion"], rel=0.1)


def test_push_off_hip_limit_caps_the_support_hip_in_the_first_300_ms():
    """``push_off_hip_limit_nm`` (issue 11 experiment): an early-swing elevating trip's
    support hip extends with at most the cap until the recovery step, against ~290 N·m
    uncapped (``flight_from_fall``, the default until its recovery hip was capped;
    people: ~52 N·m, Pijnappels et al. 2005)."""
    from dataclasses import replace

    from stumble.control.fsm_params import load_params

    sc = Scenario(swing_fraction=0.15, speed_m_per_s=1.1, mechanism="obstacle")
    base = simulate_trip(sc, params=load_params("flight_from_fall")).summary
    capped = simulate_trip(sc, params=replace(FSMParams(), push_off_hip_limit_nm=150.0)).summary
    assert base["support_peak_moments_nm"]["hip_extension"] > 250.0
    assert capped["support_peak_moments_nm"]["hip_extension"] <= 150.5
    assert capped["recovered"]


def test_push_off_rec_hip_limit_caps_the_recovery_hip_and_unloads_the_support_hip():
    """``push_off_rec_hip_limit_nm`` (issue 11): a mid-swing obstacle trip's recovery hip
    flexes with at most the cap in the push-off, and the support hip, which holds the
    pelvis against that hip's reaction, pushes off with far less (``flight`` uncapped:
    ~250 N·m; people ~52 N·m, Pijnappels et al. 2005)."""
    from dataclasses import replace

    import mujoco

    from stumble.control.fsm import PUSH_OFF_STATES
    from stumble.control.fsm_params import load_params

    sc = Scenario(swing_fraction=0.35, speed_m_per_s=1.2, mechanism="obstacle")
    flight = load_params("flight")
    base = simulate_trip(sc, params=flight)
    run = simulate_trip(sc, params=replace(flight, push_off_rec_hip_limit_nm=60.0))
    m, rec = run.body.model, run.recording
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"hip_flexion_{sc.side}")
    push = np.isin(np.asarray(rec.state), PUSH_OFF_STATES) & (rec.time_s >= 0.0)
    assert push.sum() > 20
    # the cap is applied at each 2 ms control update; the servo acts at every step
    assert rec.actuator_force[push, i].max() <= 60.0 * 1.1
    b = base.summary
    assert b["support_peak_moments_nm"]["hip_extension"] > 230.0
    assert run.summary["support_peak_moments_nm"]["hip_extension"] < 170.0
    assert run.summary["recovered"]


def test_push_off_sup_knee_limit_caps_the_support_knees_push_off():
    """``push_off_sup_knee_limit_nm`` (issue 11): after a mid-swing obstacle trip the
    support knee, extending under the push-off against its servo's damping, flexes with
    ~100 N·m under ``hip_cap`` (people ~54 N·m, Pijnappels et al. 2005); capped at
    80 N·m it stays within the cap in the push-off states and within 1.5 times people's
    in the first 300 ms."""
    from dataclasses import replace

    import mujoco

    from stumble.control.fsm import PUSH_OFF_STATES
    from stumble.control.fsm_params import load_params

    sc = Scenario(swing_fraction=0.35, speed_m_per_s=1.2, mechanism="obstacle")
    p = load_params("hip_cap")
    base = simulate_trip(sc, params=p).summary
    run = simulate_trip(sc, params=replace(p, push_off_sup_knee_limit_nm=80.0))
    m, rec = run.body.model, run.recording
    sup = {"r": "l", "l": "r"}[sc.side]
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"knee_angle_{sup}")
    push = np.isin(np.asarray(rec.state), PUSH_OFF_STATES) & (rec.time_s >= 0.0)
    assert push.sum() > 20
    assert np.abs(rec.actuator_force[push, i]).max() <= 80.0 * 1.1
    assert base["support_peak_moments_nm"]["knee_flexion"] > 90.0
    assert run.summary["support_peak_moments_nm"]["knee_flexion"] <= 81.0


@pytest.mark.parametrize(("name", "setting", "swing", "moment", "lo", "hi"), [
    # searched under a 60 N·m recovery-hip cap: the support hip near 150 N·m (flight ~250)
    ("hip_cap", "push_off_rec_hip_limit_nm", 0.35, "hip_extension", 120.0, 170.0),
    # searched under an 80 N·m support-knee cap: the knee within 1.5 times people's 54 N·m
    # (flight ~150); four of the nine mid-swing obstacle trips peak later, after the
    # push-off states, at 87-162 N·m, and the median of the nine is the cap's 80
    ("knee_cap", "push_off_sup_knee_limit_nm", 0.25, "knee_flexion", 60.0, 81.0),
])
def test_the_capped_sets_run_with_their_cap_and_push_off_below_flight(
        name, setting, swing, moment, lo, hi):
    """The shipped ``hip_cap`` and ``knee_cap`` sets carry their cap in their settings
    (and no other) and walk on after a mid-swing obstacle trip with the capped push-off
    moment in range (issue 11; Pijnappels et al. 2005)."""
    from stumble.control.fsm_params import CAP_SETTINGS, load_params, read_params

    p = load_params(name)
    assert {k: getattr(p, k) for k in CAP_SETTINGS if getattr(p, k) is not None} == \
        {setting: {"hip_cap": 60.0, "knee_cap": 80.0}[name]}
    assert read_params(name).record()["settings"][setting] == getattr(p, setting)
    s = simulate_trip(Scenario(swing_fraction=swing, speed_m_per_s=1.2, mechanism="obstacle"),
                      params=p).summary
    assert s["recovered"] and s["steps_after_recovery_step"] >= 4
    assert lo < s["support_peak_moments_nm"][moment] <= hi


def test_tune_fsm_only_lowering_runs_the_other_trips_once_with_the_same_score(monkeypatch):
    """--only lowering: the trips the start sends to elevating run once; a candidate's
    score is the same as running every trip (no LOWERING target acts on them)."""
    tune = _tune_fsm()
    grid = [(0.15, 1.2, "force"), (0.45, 1.2, "obstacle"), (0.65, 1.2, "force")]
    monkeypatch.setattr(tune, "GRID", grid)
    monkeypatch.setattr(tune, "WALK_ON_S", None)
    start = tune.params_from({}).values()
    # a candidate far from the start in every lowering target
    cand = {**start, **{k: lo + 0.9 * (hi - lo) for k, (_p, lo, hi) in tune.SPACE.items()
                        if k in tune.LOWERING}}
    whole = [tune.evaluate(x) for x in (start, cand)]
    active, fixed = tune.fixed_part(start)
    assert active == [2]  # the trip at 0.65 of swing
    monkeypatch.setattr(tune, "ACTIVE", active)
    monkeypatch.setattr(tune, "FIXED", fixed)
    assert [tune.evaluate(x) for x in (start, cand)] == whole
    assert whole[0] != whole[1]  # the candidate changes the lowering trip


def test_tune_fsm_gait_mismatch_compares_the_walk_on_with_the_walk_before(monkeypatch):
    """--walk-on-gait: |v/v0 - 1| + |T/T0 - 1| of the walk on against the walk before the
    trip (T0 half its stride), 1 without a walk on; a recovered trip adds W times its
    bonus, 1 - mismatch/0.4 (0 at least)."""
    tune = _tune_fsm()
    s = {"speed_m_per_s": 1.0, "walking_stride_s": 1.2, "walk_on_speed_m_per_s": 1.2,
         "walk_on_step_s": 0.45}
    assert tune.gait_mismatch(s) == pytest.approx(0.2 + 0.25)
    assert tune.gait_mismatch({**s, "walk_on_step_s": None}) == 1.0
    assert tune.gait_bonus({**s, "walk_on_speed_m_per_s": 1.1, "walk_on_step_s": 0.6}) \
        == pytest.approx(1 - 0.1 / 0.4)
    assert tune.gait_bonus(s) == 0.0  # 0.45 off: no bonus
    monkeypatch.setattr(tune, "GAIT_WEIGHT", 2.0)
    monkeypatch.setattr(tune, "GRID_FLOOR", None)
    assert tune.penalised((40, 100.0, 40, 12.5, 0, 0.0, 0, 0)) == pytest.approx((65.0, 100.0))
    monkeypatch.setattr(tune, "GAIT_WEIGHT", 0.0)
    assert tune.penalised((40, 100.0, 40, 12.0, 0, 0.0, 0, 0)) == (40, 100.0)


def test_tune_fsm_flight_score_rewards_flight_where_people_fly(monkeypatch):
    """--flight: a flight phase scores +1 at 1.4 m/s in its strategy's window (elevating
    0.05-0.3 of swing, lowering 0.55-0.75), -1 at 1.0 m/s, 0 elsewhere or without one;
    a recovered trip adds W times it."""
    tune = _tune_fsm()
    s = {"variant": "flight", "speed_m_per_s": 1.4, "swing_fraction": 0.15,
         "strategy": "elevating"}
    assert tune.flight_score(s) == 1
    assert tune.flight_score({**s, "variant": "double_support"}) == 0
    assert tune.flight_score({**s, "swing_fraction": 0.45}) == 0  # outside the window
    assert tune.flight_score({**s, "swing_fraction": 0.65, "strategy": "lowering"}) == 1
    assert tune.flight_score({**s, "swing_fraction": 0.25, "strategy": "lowering"}) == 0
    assert tune.flight_score({**s, "speed_m_per_s": 1.2}) == 0
    assert tune.flight_score({**s, "speed_m_per_s": 1.0}) == -1
    monkeypatch.setattr(tune, "GAIT_WEIGHT", 0.0)
    monkeypatch.setattr(tune, "GRID_FLOOR", None)
    monkeypatch.setattr(tune, "FLIGHT_WEIGHT", 0.5)
    assert tune.penalised((40, 100.0, 40, 0.0, 4, 0.0, 0, 0)) == pytest.approx((42.0, 100.0))


def test_tune_fsm_out_names_the_generation_that_found_its_best(tmp_path, monkeypatch):
    """--out records the generation whose candidate it holds, not the last one run."""
    import argparse
    import json

    tune = _tune_fsm()
    calls = iter(range(100))
    # the start scores 10, generation 0's candidates 21-24, every later one less
    monkeypatch.setattr(tune, "evaluate", lambda x: (
        (lambda n: (10 if n == 0 else 20 + n if n <= 4 else 5, 0.0, 0, 0.0, 0, 0.0, 0, 0))(
            next(calls))))
    monkeypatch.setattr(tune, "GRID", [(0.35, 1.2, "obstacle")])
    out = tmp_path / "best.json"
    args = argparse.Namespace(sigma=0.1, seed=1, popsize=4, generations=3, workers=1,
                              out=str(out))
    space = {k: tune.SPACE[k] for k in ("elev_sup_ankle", "ext_rec_hip")}
    tune._cma(args, tune.params_from({}).values(), space)
    rec = json.loads(out.read_text())
    assert rec["recovered"] == 24 and rec["generation"] == 0
    lines = (tmp_path / "best.generations.jsonl").read_text().splitlines()
    assert [json.loads(x)["generation"] for x in lines] == [0, 1, 2]


def test_tune_fsm_push_off_excess_measures_validates_nine_trips_against_pijnappels(
        monkeypatch):
    """--push-off: a mid-swing obstacle trip's excess over 1.5 × Pijnappels et al. 2005
    (hip 52, knee 54 N·m: 78 and 81); other trips and other bodies count 0."""
    tune = _tune_fsm()
    s = {"support_peak_moments_nm": {"hip_extension": 156.0, "knee_flexion": 40.5}}
    assert tune.push_off_excess(s, 0.35, "obstacle", []) == pytest.approx(1.0)
    s2 = {"support_peak_moments_nm": {"hip_extension": 78.0, "knee_flexion": 121.5}}
    assert tune.push_off_excess(s2, 0.25, "obstacle", []) == pytest.approx(0.5)
    assert tune.push_off_excess(s, 0.35, "force", []) == 0.0
    assert tune.push_off_excess(s, 0.55, "obstacle", []) == 0.0
    assert tune.push_off_excess(s, 0.35, "obstacle", [1.5, 45.0, "female"]) == 0.0
    monkeypatch.setattr(tune, "GAIT_WEIGHT", 0.0)
    monkeypatch.setattr(tune, "GRID_FLOOR", None)
    monkeypatch.setattr(tune, "FLIGHT_WEIGHT", 0.0)
    monkeypatch.setattr(tune, "PUSH_WEIGHT", 2.0)
    assert tune.penalised((40, 100.0, 40, 0.0, 0, 3.0, 0, 0)) == pytest.approx((34.0, 100.0))


def test_tune_fsm_knee_weight_and_bodies_floor(monkeypatch):
    """--push-off-knee K counts the knee's excess K times; --bodies-floor N loses 2 per
    body trip (those after the grid's 48) recovered below N."""
    tune = _tune_fsm()
    s = {"support_peak_moments_nm": {"hip_extension": 156.0, "knee_flexion": 121.5}}
    monkeypatch.setattr(tune, "KNEE_WEIGHT", 4.0)
    assert tune.push_off_excess(s, 0.35, "obstacle", []) == pytest.approx(1.0 + 4 * 0.5)
    for name, value in (("GAIT_WEIGHT", 0.0), ("GRID_FLOOR", 46), ("FLIGHT_WEIGHT", 0.0),
                        ("PUSH_WEIGHT", 0.0), ("BODIES_FLOOR", 87)):
        monkeypatch.setattr(tune, name, value)
    # 46 of the grid and 82 of the bodies: 5 body trips short of 87
    assert tune.penalised((128, 800.0, 46, 0.0, 0, 0.0, 0, 0)) == pytest.approx((118.0, 800.0))
    # the grid short by one as well
    assert tune.penalised((127, 800.0, 45, 0.0, 0, 0.0, 0, 0)) == pytest.approx((115.0, 800.0))
    monkeypatch.setattr(tune, "BODIES_FLOOR", None)
    assert tune.penalised((128, 800.0, 46, 0.0, 0, 0.0, 0, 0)) == pytest.approx((128.0, 800.0))


def test_tune_fsm_over_tilt_loses_the_walks_on_past_the_tilt(monkeypatch):
    """--over-tilt W: a trip that walks on with the trunk past --max-tilt at recovery-foot
    contact does not count (``counts``) and also loses W (``over_tilt``, the score's
    seventh field); a fall or a recovery within the tilt loses nothing."""
    tune = _tune_fsm()
    monkeypatch.setattr(tune, "MAX_TILT", 26.0)
    past = {"recovered": True, "trunk_tilt_at_recovery_contact_deg": 26.1}
    within = {**past, "trunk_tilt_at_recovery_contact_deg": 25.4}
    fell = {**past, "recovered": False}
    assert [tune.counts(s) for s in (past, within, fell)] == [False, True, False]
    assert [tune.over_tilt(s) for s in (past, within, fell)] == [True, False, False]
    monkeypatch.setattr(tune, "MAX_TILT", None)
    assert not tune.over_tilt(past)
    for name, value in (("GAIT_WEIGHT", 0.0), ("GRID_FLOOR", None), ("FLIGHT_WEIGHT", 0.0),
                        ("PUSH_WEIGHT", 0.0), ("BODIES_FLOOR", None),
                        ("OVER_TILT_WEIGHT", 3.0)):
        monkeypatch.setattr(tune, name, value)
    assert tune.penalised((135, 800.0, 47, 0.0, 0, 0.0, 2, 0)) == pytest.approx((129.0, 800.0))


def test_tune_fsm_unsettled_loses_the_walks_on_that_never_settle(monkeypatch):
    """--unsettled W: a trip that walks on (within the tilt or not) and never reaches a
    steady gait, or turns more than HEADING_LIMIT_DEG (20°) from the walk before, loses W
    (``unsettled``, the score's eighth field, where ``score_of`` puts it); a settled walk
    on, a fall or a recovery under the 1 s rule (no walk on) loses nothing."""
    tune = _tune_fsm()
    settled = {"recovered": True, "recovery": "walk_on", "steps_to_steady_gait": 5,
               "walk_on_heading_deg": -15.3}
    never = {**settled, "steps_to_steady_gait": None}
    turned = {**settled, "walk_on_heading_deg": 40.7}
    turned_right = {**settled, "walk_on_heading_deg": -40.7}
    at_limit = {**settled, "walk_on_heading_deg": 20.0}
    fell = {**never, "recovered": False, "walk_on_heading_deg": None}
    step_rule = {**never, "recovery": "step", "walk_on_heading_deg": None}
    assert [tune.unsettled(s) for s in (settled, never, turned, turned_right, at_limit,
                                        fell, step_rule)] == [
        False, True, True, True, False, False, False]
    # score_of: the walks on past the tilt in the seventh field, the unsettled in the eighth
    outcomes = [(True, 6.0, 0.5, 0, 0.0, False, True), (True, 6.0, 0.5, 0, 0.0, True, False),
                (True, 6.0, 0.5, 0, 0.0, False, True)]
    monkeypatch.setattr(tune, "trip_counts", lambda x, i: outcomes[i])
    assert tune.score_of({}, range(3))[6:] == (1, 2)
    for name, value in (("GAIT_WEIGHT", 0.0), ("GRID_FLOOR", None), ("FLIGHT_WEIGHT", 0.0),
                        ("PUSH_WEIGHT", 0.0), ("BODIES_FLOOR", None),
                        ("OVER_TILT_WEIGHT", 0.0), ("UNSETTLED_WEIGHT", 4.0)):
        monkeypatch.setattr(tune, name, value)
    assert tune.penalised((135, 800.0, 47, 0.0, 0, 0.0, 0, 2)) == pytest.approx((127.0, 800.0))
    monkeypatch.setattr(tune, "UNSETTLED_WEIGHT", 0.0)
    assert tune.penalised((135, 800.0, 47, 0.0, 0, 0.0, 0, 2)) == (135, 800.0)


def test_walk_on_with_double_support_takes_longer_steps():
    """``walk_on_push_s`` (ours): after each walk-on landing the trailing leg pushes off
    before it swings. An early-swing force trip at 1.2 m/s walks on in steps of about
    0.40 s without it and of about 0.5 s with it (the walk before: 0.58 s)."""
    sc = Scenario(swing_fraction=0.25, speed_m_per_s=1.2, mechanism="force",
                  recovery="walk_on", duration_after_trip_s=6.0)
    base = simulate_trip(sc, params=FSMParams()).summary
    p = FSMParams().with_values({"walk_on_push_s": 0.06, "push_sup_ankle": -5.0,
                                 "reach_thigh_deg": 5.0})
    push = simulate_trip(sc, params=p).summary
    assert base["recovered"] and push["recovered"]
    assert "step_push" not in {st["name"] for st in base["states"]}
    assert "step_push" in {st["name"] for st in push["states"]}
    assert base["walk_on_step_s"] < 0.42 < 0.47 < push["walk_on_step_s"]
    assert push["walk_on_step_s"] < base["walking_stride_s"] / 2


def test_walk_on_speed_gain_steers_the_walk_on_toward_the_speed_before_the_trip():
    """``walk_on_speed_gain_rad_s_per_m`` (ours): a trip at 1.0 m/s walks on at about
    1.19 m/s without it, and slower, nearer 1.0, with 0.1 rad·s/m."""
    sc = Scenario(swing_fraction=0.25, speed_m_per_s=1.0, mechanism="obstacle",
                  recovery="walk_on", duration_after_trip_s=6.0)
    base = simulate_trip(sc, params=FSMParams()).summary
    slow = simulate_trip(sc, params=FSMParams().with_values(
        {"walk_on_speed_gain": 0.1})).summary
    assert base["recovered"] and slow["recovered"]
    assert base["walk_on_speed_m_per_s"] > 1.17
    assert 1.0 < slow["walk_on_speed_m_per_s"] < base["walk_on_speed_m_per_s"] - 0.03


def test_walk_on_speed_ramp_phases_the_speed_gain_in_over_the_steps():
    """``walk_on_speed_ramp_steps`` (ours): with a ramp of 3 the first walk-on step runs
    without the speed gain (the same step as with k_s 0, to the last digit) and the
    later ones with it (a slower walk on than without it)."""
    sc = Scenario(swing_fraction=0.25, speed_m_per_s=1.0, mechanism="force",
                  recovery="walk_on", duration_after_trip_s=6.0)
    runs = [simulate_trip(sc, params=FSMParams().with_values(v)).summary for v in (
        {}, {"walk_on_speed_gain": 0.1}, {"walk_on_speed_gain": 0.1, "walk_on_speed_ramp": 3})]
    base, gain, ramp = runs
    assert all(s["recovered"] for s in runs)
    assert ramp["walk_on_steps"][0] == base["walk_on_steps"][0] != gain["walk_on_steps"][0]
    assert ramp["walk_on_steps"][1] != base["walk_on_steps"][1]
    assert ramp["walk_on_speed_m_per_s"] < base["walk_on_speed_m_per_s"] - 0.03


def test_walk_on_speed_feedforward_walks_on_at_the_speed_before_the_trip():
    """``walk_on_speed_feedforward`` (ours): the upright set, which has it (f 0.83, a
    ramp of 3.5 steps), walks on at 1.04 m/s after a force trip at 0.65 of swing at
    1.0 m/s and at 1.26 after one at 1.4; without it (f = 0) at 1.07 and 1.19."""
    from stumble.control.fsm_params import load_params

    up = load_params("upright")
    assert up.walk_on_speed_feedforward > 0.5
    off = up.with_values({"walk_on_speed_feedforward": 0.0})
    for v in (1.0, 1.4):
        sc = Scenario(swing_fraction=0.65, speed_m_per_s=v, mechanism="force",
                      recovery="walk_on", duration_after_trip_s=6.0)
        with_ff, without = (simulate_trip(sc, params=p).summary for p in (up, off))
        assert with_ff["recovered"] and without["recovered"]
        err = abs(with_ff["walk_on_speed_m_per_s"] - v)
        assert err < 0.15 and err < abs(without["walk_on_speed_m_per_s"] - v) - 0.03


def test_walk_on_swing_min_slows_the_walk_on_cadence():
    """``walk_on_swing_min_s`` (ours): the walk on's swing lasts at least that long, so its
    steps are longer: the upright set walks on after a lowering obstacle trip at 0.65 of
    swing, 1.2 m/s, in steps of 0.43 s, and in steps of 0.46 s with a swing of 0.25 s
    at least (the walk before: 0.58 s)."""
    from stumble.control.fsm_params import load_params

    up = load_params("upright")
    sc = Scenario(swing_fraction=0.65, speed_m_per_s=1.2, mechanism="obstacle",
                  recovery="walk_on", duration_after_trip_s=6.0)
    fast, slow = (simulate_trip(sc, params=p).summary for p in (
        up, up.with_values({"walk_on_swing_min_s": 0.25})))
    assert fast["recovered"] and slow["recovered"]
    assert slow["walk_on_step_s"] > fast["walk_on_step_s"] + 0.02
    assert slow["walk_on_step_s"] < slow["walking_stride_s"] / 2


def test_the_upright_set_walks_on_with_the_trunk_within_26_degrees():
    """The upright set, the default from 2026-12-03 to 2026-12-05 (issue 11): a lowering
    obstacle trip at 0.65 of swing, 1.2 m/s, walks on 6 s with the earlier default
    (``--params step``) with the trunk beyond 26° at recovery-foot contact (people:
    within about 23-26°, van den Bogert et al. 2002), and with the upright set within
    it, in longer steps (0.43 s against 0.41)."""
    from pathlib import Path

    from stumble.control.fsm_params import UPRIGHT_FILE, load_params

    up = load_params("upright")
    assert load_params("step") == FSMParams()
    assert up.trunk_attitude == 0.3 and up.walk_on_push_s > 0.0
    # the search that found it starts from a file of the repository, with its settings
    first, second, third = json.loads(UPRIGHT_FILE.read_text())["fit"]["commands"]
    assert "--around A.json" in second and "--out A.json" in first
    assert "--grid full+bodies" in second
    for cmd in (first, third):  # each starts from a file of the repository
        start = re.search(r"--around (\S+)", cmd).group(1)
        values, settings = _tune_fsm().read_around(
            str(Path(__file__).resolve().parents[3] / start))
        assert settings == {"trunk_attitude": 0.3, "attitude_damping": "joint"}
        assert set(values) >= {"walk_on_push_s", "swing_sup_hip", "low_rec_hip"}
        assert "--only walk_on" in cmd and "--max-tilt 26" in cmd
    assert values["walk_on_speed_feedforward"] == 1.0  # the third's start
    sc = Scenario(swing_fraction=0.65, speed_m_per_s=1.2, mechanism="obstacle",
                  recovery="walk_on", duration_after_trip_s=6.0)
    base = simulate_trip(sc, params=load_params("step")).summary
    upright = simulate_trip(sc, params=up).summary
    assert base["recovered"] and base["trunk_tilt_at_recovery_contact_deg"] > 26.0
    assert upright["recovered"] and upright["strategy"] == "lowering"
    assert upright["trunk_tilt_at_recovery_contact_deg"] <= 26.0
    assert upright["walk_on_step_s"] > base["walk_on_step_s"] + 0.01


def test_fast_push_lifts_the_support_foot_at_fast_walking_only():
    """``elev_sup_ankle_fast_deg`` (ours, issue 11): the elevating support ankle pushes
    further at fast walking, phased in as k_c is (0 at 1.0 m/s, all of it at 1.4). In the
    upright set (-5°; flight's elevating trips are the same) an elevating force trip at
    0.25 of swing, 1.4 m/s, pushes the support foot off the floor before the recovery
    foot lands, where without the push it stays down; the same trip at 1.0 m/s keeps it
    down. The foot lands again first, so the landing is in double support: counted a
    flight until 2026-12-07, a hop since (``analysis.variant``)."""
    from stumble.control.fsm_params import load_params

    p = load_params("upright")
    assert p.elev_sup_ankle_fast_deg == -5.0
    base = p.targets_deg["clearance_elevating"]["sup.ankle_angle"]
    for v, extra in ((0.9, 0.0), (1.0, 0.0), (1.2, -2.5), (1.4, -5.0), (1.6, -5.0)):
        at = p.at_speed(v).targets_deg["clearance_elevating"]["sup.ankle_angle"]
        assert at == pytest.approx(base + extra)
    assert p.targets_deg["clearance_elevating"]["sup.ankle_angle"] == base  # a copy
    off = p.with_values({"elev_sup_ankle_fast": 0.0})
    assert off.at_speed(1.4) is off
    sc = Scenario(swing_fraction=0.25, speed_m_per_s=1.4, mechanism="force")
    fast = simulate_trip(sc, params=p).summary
    still = simulate_trip(sc, params=off).summary
    assert fast["recovered"] and fast["variant"] == "double_support"
    assert fast["airborne_before_landing_s"] == pytest.approx(0.028, abs=0.01)
    assert still["recovered"] and still["airborne_before_landing_s"] == 0.0
    slow = simulate_trip(sc.with_(speed_m_per_s=1.0), params=p).summary
    assert slow["recovered"] and slow["airborne_before_landing_s"] == 0.0


def test_scan_fsm_counts_walk_ons_and_flights_as_validate_does():
    """scripts/scan_fsm.py's figures of one value: trips walked on (and within 26°),
    the recovered window trips at 1.4 m/s that fly by strategy, flights at 1.0 m/s, the
    elevating flights' median recovery step, the lowering flights' trip to recovery
    contact, the bodies walked on and the walks on that never settle."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / "scripts" / "scan_fsm.py"
    spec = importlib.util.spec_from_file_location("scan_fsm", path)
    scan = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(scan)

    def row(f, v, strategy, variant, rec=True, tilt=20.0, step=0.6, body=(),
            contact=None, mech="force", push=None, loose=False):
        return {"swing": f, "speed": v, "mechanism": mech, "body": list(body),
                "recovered": rec, "strategy": strategy, "variant": variant, "tilt": tilt,
                "recovery_step_s": step, "trip_to_recovery_contact_s": contact,
                "push_off_nm": push or {}, "unsettled": loose}

    rows = [row(0.15, 1.4, "elevating", "flight", step=0.58),
            row(0.25, 1.4, "elevating", "flight", step=0.62),
            row(0.05, 1.4, "elevating", "double_support", loose=True),
            row(0.35, 1.4, "elevating", "flight", step=0.9),  # outside the window
            row(0.65, 1.4, "lowering", "double_support", contact=0.5),
            row(0.75, 1.4, "lowering", "flight", contact=0.61),
            row(0.55, 1.4, "lowering", "flight", rec=False, contact=0.4),  # fell: not counted
            row(0.15, 1.0, "elevating", "flight", tilt=27.0),
            row(0.15, 1.2, "elevating", "double_support", tilt=22.0,
                body=(1.5, 45.0, "female"), loose=True),
            row(0.25, 1.2, "elevating", "double_support", rec=False, tilt=40.0,
                body=(1.5, 45.0, "female")),  # a fall's tilt is not a recovery's
            # a force trip in the push-off's swing window: not one of validate's nine
            row(0.35, 1.2, "elevating", "double_support", push={"hip_extension": 999.0})]
    fig = scan.figures(-5.0, rows)
    assert fig["grid_walked_on"] == 8 and fig["of"] == 9 and fig["grid_within_26"] == 7
    assert fig["flight_1.4_elevating"] == [2, 3] and fig["flight_1.4_lowering"] == [1, 2]
    assert fig["lowering_flight_contact_s"] == pytest.approx(0.61)  # the one that recovered
    assert fig["flight_1.0"] == [1, 1] and fig["largest_tilt_deg"] == 27.0
    assert fig["elevating_flight_step_s"] == pytest.approx(0.6)  # 0.58, 0.62 (0.9 at 0.35)
    assert fig["bodies_walked_on"] == 1 and fig["bodies_of"] == 2
    assert fig["bodies_largest_tilt_deg"] == 22.0
    assert fig["bodies_within_26"] == 1
    assert fig["grid_unsettled"] == 1 and fig["bodies_unsettled"] == 1
    past = row(0.35, 1.2, "elevating", "double_support", tilt=27.0, body=(1.9, 90.0, "male"))
    more = scan.figures(-5.0, [*rows, past])
    assert more["bodies_walked_on"] == 2 and more["bodies_within_26"] == 1
    # the push-off: validate's nine trips (obstacle, 0.25-0.45 of swing), medians in N·m
    assert fig["push_off_median_nm"]["hip_extension"] is None  # no obstacle trip
    push = [{"hip_extension": h, "knee_flexion": 80.0, "ankle_plantarflexion": 250.0}
            for h in (190.0, 204.0, 230.0, 300.0)]
    obst = [row(f, 1.2, "elevating", "double_support", mech="obstacle", push=p)
            for f, p in zip((0.25, 0.35, 0.45, 0.55), push, strict=True)]  # 0.55: not one
    med = scan.figures(-5.0, rows + obst)["push_off_median_nm"]
    assert med == {"hip_extension": 204.0, "knee_flexion": 80.0,
                   "ankle_plantarflexion": 250.0}


def test_a_trip_runs_the_default_set_of_its_strength_and_rule(monkeypatch):
    """Without ``params`` a trip runs ``fsm_params.DEFAULT_SETS``' set: rec_hip_cap
    on the fixed limits under either rule; on human strength the set searched walking on
    under the default rule, the 1 s rule's set under ``--recovery step``."""
    import stumble.pipeline as pipeline
    from stumble.control.fsm_params import default_params, human_strength_params, load_params

    seen = []

    class Stop(Exception):
        pass

    def fake(strength_model="fixed", recovery="walk_on"):
        seen.append((strength_model, recovery))
        raise Stop

    monkeypatch.setattr(pipeline, "default_params", fake)
    for strength in ("fixed", "anderson2007"):
        for rule in (None, "step"):
            kw = {} if rule is None else {"recovery": rule}
            with pytest.raises(Stop):
                simulate_trip(Scenario(strength_model=strength, **kw))
    assert seen == [("fixed", "walk_on"), ("fixed", "step"), ("anderson2007", "walk_on"),
                    ("anderson2007", "step")]
    up = load_params("rec_hip_cap")
    assert default_params() == default_params("fixed", "step") == up
    assert human_strength_params() == default_params("anderson2007", "walk_on") == \
        load_params("anderson2007_walk_on")
    assert default_params() is not default_params()  # each caller gets its own copy


def test_lowering_fall_offsets_at_fast_walking_push_into_flight():
    """``low_fall_fast_deg`` (ours, issue 11; all 0 in upright): the lowering
    Fall gets a table of its own, ``fall``'s targets moved by the offsets phased in with
    the speed as k_c is (none at 1.0 m/s); the elevating Fall keeps ``fall``. A support
    ankle pushing 35° further turns a lowering obstacle trip at 0.55 of swing, 1.4 m/s,
    into a flight (it falls: the offsets alone do not make a flight that recovers; the
    flight set's do with the lowering's own compensation, docs/fsm-fits.md "Flight"), and leaves
    the same trip at 1.0 m/s as it was."""
    from stumble.control.fsm_params import FLIGHT, LOW_FALL_FAST_TARGETS, load_params

    p = load_params("upright")
    assert not any(p.low_fall_fast_deg.values())
    assert {k for k in FLIGHT if k.startswith("low_fall_")} == {
        f"low_fall_{k}_fast" for k in LOW_FALL_FAST_TARGETS}
    push = p.with_values({"low_fall_sup_ankle_fast": -35.0, "low_fall_sup_knee_fast": -10.0})
    assert push.low_fall_fast_deg["sup_ankle"] == -35.0 and not p.low_fall_fast_deg["sup_ankle"]
    fall = p.targets_deg["fall"]
    at = push.at_speed(1.2).targets_deg
    assert at["fall_lowering"]["sup.ankle_angle"] == pytest.approx(fall["sup.ankle_angle"] - 17.5)
    # the support knee has no Fall target: it starts from the lowering Clearance's
    assert at["fall_lowering"]["sup.knee_angle"] == pytest.approx(
        p.targets_deg["clearance_lowering"]["sup.knee_angle"] - 5.0)
    assert at["fall"] == fall and "fall_lowering" not in push.targets_deg  # copies
    assert push.at_speed(1.0).targets_deg["fall_lowering"]["sup.ankle_angle"] == (
        fall["sup.ankle_angle"])
    sc = Scenario(swing_fraction=0.55, speed_m_per_s=1.4, mechanism="obstacle",
                  duration_after_trip_s=2.0)
    flies = simulate_trip(sc, params=push).summary
    keeps = simulate_trip(sc, params=p).summary
    assert flies["strategy"] == keeps["strategy"] == "lowering"
    assert flies["variant"] == "flight" and keeps["variant"] == "double_support"
    slow = sc.with_(speed_m_per_s=1.0)
    a, b = simulate_trip(slow, params=push).summary, simulate_trip(slow, params=p).summary
    assert a["recovered"] == b["recovered"] and a["recovery_contact_s"] == b["recovery_contact_s"]


def test_lowering_flight_parameters_default_to_the_elevating_law():
    """``kc_lowering_fast``, ``lowering_push_ahead_m`` and the ``flight_lowering`` table
    (ours, issue 11): unset they leave the lowering's compensation and Flight as the
    elevating's; set, k_c ramps from kc_slow to the lowering's own fast value, and a
    Flight target of the lowering's own makes its table from ``flight``."""
    p = FSMParams()
    assert p.kc_lowering_fast is None and p.lowering_push_ahead_m == -1.0
    for v in (0.9, 1.2, 1.4):
        assert p.kc(v, "lowering") == p.kc(v)
    assert p.values()["kc_lowering_fast"] == p.kc_fast
    own = p.with_values({"kc_lowering_fast": 300.0})
    assert own.kc(1.0, "lowering") == pytest.approx(own.kc_slow)  # slow: double support
    assert own.kc(1.4, "lowering") == pytest.approx(300.0)
    assert own.kc(1.2, "lowering") == pytest.approx((own.kc_slow + 300.0) / 2)
    assert own.kc(1.4) == pytest.approx(p.kc_fast)  # the elevating's unchanged
    # the Flight table: the flight's values need no table of their own
    same = p.with_values({"fl_low_sup_knee": p.targets_deg["flight"]["sup.knee_angle"]})
    assert "flight_lowering" not in same.targets_deg
    moved = p.with_values({"fl_low_sup_knee": -30.0})
    assert moved.targets_deg["flight_lowering"] == {**p.targets_deg["flight"],
                                                    "sup.knee_angle": -30.0}
    assert moved.targets_deg["flight"] == p.targets_deg["flight"]
    assert moved.values()["fl_low_sup_knee"] == -30.0


def test_the_flight_from_fall_set_lands_from_a_flight_at_fast_walking_only():
    """The shipped ``flight_from_fall`` set (issue 11): with the setting on and the
    lowering's push at about SCA 2009's strength, a lowering obstacle trip and an
    elevating force trip at 1.4 m/s land the recovery foot from the air (both feet off
    for 0.1 s and more before its landing, through the Flight state) and walk on 6 s;
    at 1.0 m/s the same trips land in double support (people keep it there, SCA 2009
    Table 1). Its fit starts from files of the repository."""
    from pathlib import Path

    from stumble.control.fsm_params import DEFAULT_SET, FLIGHT_FROM_FALL_FILE, load_params

    p = load_params("flight_from_fall")
    assert p.flight_from_fall and p.push_off_sup_knee_limit_nm == 80.0
    assert p.kc(1.4, "lowering") == pytest.approx(350, abs=1.0)  # SCA 2009 §5: 300
    for mech, swing, strategy in (("obstacle", 0.65, "lowering"), ("force", 0.25, "elevating")):
        fast, slow = (simulate_trip(Scenario(mechanism=mech, swing_fraction=swing,
                                             speed_m_per_s=v), params=p).summary
                      for v in (1.4, 1.0))
        assert fast["strategy"] == slow["strategy"] == strategy
        assert fast["recovered"] and slow["recovered"]
        assert fast["variant"] == "flight" and fast["airborne_before_landing_s"] > 0.1
        assert "flight" in [s["name"] for s in fast["states"]]
        assert slow["variant"] == "double_support" and slow["airborne_before_landing_s"] == 0.0
    # its fit: three commands, each starting from the one before's --out, the first from
    # the repository's start (k_c set by hand to 480, the setting on, the knee capped)
    commands = json.loads(FLIGHT_FROM_FALL_FILE.read_text())["fit"]["commands"]
    arounds = [re.search(r"--around (\S+)", c).group(1) for c in commands]
    outs = [re.search(r"--out (\S+)", c).group(1) for c in commands]
    assert arounds[1:] == outs[:-1] and "search_lowering_flights.py" in commands[0]
    start = json.loads((Path(__file__).resolve().parents[3] / arounds[0]).read_text())
    assert start["params"]["kc_lowering_fast"] == 480.0
    assert start["settings"]["flight_from_fall"] is True
    assert start["settings"]["push_off_sup_knee_limit_nm"] == 80.0
    assert DEFAULT_SET == "rec_hip_cap"  # searched from it; flight_from_fall the default
    # earlier on 2026-12-07


def _two_searches_and_a_scan(path) -> dict:
    """A shipped set's fit of two searches and a scan: the second search starts from the
    first's --out and the scan reads the second's; the first starts from a file of the
    repository, returned (read)."""
    from pathlib import Path

    commands = json.loads(path.read_text())["fit"]["commands"]
    arounds = [re.search(r"--around (\S+)", c).group(1) for c in commands[:2]]
    outs = [re.search(r"--out (\S+)", c).group(1) for c in commands[:2]]
    assert arounds[1] == outs[0] and "--params " + outs[1] in commands[2]
    return json.loads((Path(__file__).resolve().parents[3] / arounds[0]).read_text())


def test_the_rec_hip_cap_set_unloads_the_support_hip_and_keeps_the_trunk_within_26():
    """The shipped ``rec_hip_cap`` set, the default (issue 11): ``flight_from_fall``
    searched with the recovery hip's servo capped in the push-off, then the cap raised to
    230 N·m. After a mid-swing obstacle trip the recovery hip stays within the cap in the
    push-off states and the support hip, which holds the pelvis against that hip's
    reaction, pushes off far below flight_from_fall's (~270 N·m; people ~52 N·m,
    Pijnappels et al. 2005). The 1.50 m, 45 kg woman's force trip at 0.45 of swing,
    which walked on with the trunk 26.6° from vertical under the search's 200 N·m cap,
    walks on within van den Bogert et al. 2002's 26° at 230. Its fit starts from files of
    the repository."""
    from dataclasses import replace

    import mujoco

    from stumble.control.fsm import PUSH_OFF_STATES
    from stumble.control.fsm_params import DEFAULT_SET, REC_HIP_CAP_FILE, load_params

    p = load_params("rec_hip_cap")
    assert DEFAULT_SET == "rec_hip_cap"
    assert p.push_off_rec_hip_limit_nm == 230.0 and p.push_off_sup_knee_limit_nm == 80.0
    assert p.flight_from_fall
    sc = Scenario(swing_fraction=0.35, speed_m_per_s=1.2, mechanism="obstacle")
    run = simulate_trip(sc, params=p)
    before = simulate_trip(sc, params=load_params("flight_from_fall")).summary
    m, rec = run.body.model, run.recording
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"hip_flexion_{sc.side}")
    push = np.isin(np.asarray(rec.state), PUSH_OFF_STATES) & (rec.time_s >= 0.0)
    assert push.sum() > 20
    # the cap is applied at each 2 ms control update; the servo acts at every step
    assert rec.actuator_force[push, i].max() <= 230.0 * 1.1
    hip = run.summary["support_peak_moments_nm"]["hip_extension"]
    assert before["support_peak_moments_nm"]["hip_extension"] > 250.0
    assert hip < 220.0 and run.summary["recovered"]
    small = Scenario(swing_fraction=0.45, speed_m_per_s=1.2, mechanism="force",
                     height_m=1.5, mass_kg=45.0, sex="female")
    s = simulate_trip(small, params=p).summary
    assert s["recovered"] and s["trunk_tilt_at_recovery_contact_deg"] < 26.0
    capped200 = simulate_trip(small, params=replace(p, push_off_rec_hip_limit_nm=200.0))
    assert capped200.summary["trunk_tilt_at_recovery_contact_deg"] > 26.0
    # its fit: from the repository's start, flight_from_fall with the cap at 200 N·m
    start = _two_searches_and_a_scan(REC_HIP_CAP_FILE)
    assert start["settings"]["push_off_rec_hip_limit_nm"] == 200.0
    ff = load_params("flight_from_fall").values()
    assert start["params"] and all(ff[k] == v for k, v in start["params"].items())


def test_the_sup_hip_cap_set_pushes_off_within_its_hip_cap_and_still_flies():
    """The shipped ``sup_hip_cap`` set (issue 11, not the default): ``rec_hip_cap`` with
    the support hip's attitude servo capped at 150 N·m and the recovery hip's at 160 N·m
    in the push-off, searched under those caps. After a mid-swing obstacle trip (0.35 of
    swing, 1.2 m/s) the support hip pushes off at its cap (``rec_hip_cap`` ~204 N·m,
    people ~52, Pijnappels et al. 2005; over the nine such trips 150-166 N·m, the cap
    acting in the push-off states only) and the person walks on with the trunk within 26°; at
    1.4 m/s a lowering obstacle trip and an elevating force trip still land the recovery
    foot from a flight. Its fit starts from a file of the repository."""

    from stumble.control.fsm_params import DEFAULT_SET, SUP_HIP_CAP_FILE, load_params

    p = load_params("sup_hip_cap")
    assert DEFAULT_SET != "sup_hip_cap"
    assert (p.push_off_hip_limit_nm, p.push_off_rec_hip_limit_nm,
            p.push_off_sup_knee_limit_nm) == (150.0, 160.0, 80.0)
    s = simulate_trip(Scenario(swing_fraction=0.35, speed_m_per_s=1.2, mechanism="obstacle"),
                      params=p).summary
    before = simulate_trip(Scenario(swing_fraction=0.35, speed_m_per_s=1.2,
                                    mechanism="obstacle"),
                           params=load_params("rec_hip_cap")).summary
    assert s["recovered"] and s["trunk_tilt_at_recovery_contact_deg"] < 24.0
    assert s["support_peak_moments_nm"]["hip_extension"] <= 150.5
    assert before["support_peak_moments_nm"]["hip_extension"] > 190.0
    for mech, swing, strategy in (("obstacle", 0.65, "lowering"), ("force", 0.25, "elevating")):
        fast = simulate_trip(Scenario(mechanism=mech, swing_fraction=swing,
                                      speed_m_per_s=1.4), params=p).summary
        assert fast["recovered"] and fast["strategy"] == strategy
        assert fast["variant"] == "flight"
    start = _two_searches_and_a_scan(SUP_HIP_CAP_FILE)  # from rec_hip_cap, both hips capped
    assert start["settings"]["push_off_hip_limit_nm"] == 150.0
    assert start["settings"]["push_off_rec_hip_limit_nm"] == 160.0
    rhc = load_params("rec_hip_cap").values()
    assert start["params"] and all(rhc[k] == v for k, v in start["params"].items())


def test_the_flight_set_pushes_off_the_lowered_foot_at_fast_walking_only():
    """The flight set, the default from 2026-12-05 to 2026-12-06 (issue 11; ``knee_cap``,
    the default from 2026-12-06 to 2026-12-07, was searched from it under a support-knee
    cap): the lowering strategy's own compensation torque at fast walking (SCA 2009 eq.
    4, k_c 232 against the paper's 300, once the COM is 7 cm ahead of the lowered foot)
    and its own Flight targets. A lowering obstacle trip at 0.65 of swing, 1.4 m/s, then
    walks on 6 s after the lowered foot has left the floor (a hop: it lands again before
    the recovery foot, so double support, counted a flight until 2026-12-07), its
    recovery leg landing as soon after
    the trip as in SCA 2009's motion capture or simulation (§5.2: 0.57 and 0.72 s),
    where upright keeps the foot down; at 1.0 m/s both keep it. The searches that found
    it start from a file of the repository, with its settings."""
    from pathlib import Path

    from stumble.control.fsm_params import (
        FLIGHT_FILE,
        LOWERING_FLIGHT,
        load_params,
    )

    fl, up = load_params("flight"), load_params("upright")
    assert fl.kc(1.4, "lowering") == pytest.approx(231.8, abs=0.1)
    assert fl.kc(1.4) == up.kc(1.4) and fl.kc(1.0, "lowering") == up.kc(1.0)
    assert 0.0 < fl.lowering_push_ahead_m < 0.1 and "flight_lowering" in fl.targets_deg
    assert {k: v for k, v in fl.values().items() if k not in LOWERING_FLIGHT
            and k not in _tune_fsm().LOWERING and not k.startswith("low_fall_")
            } == {k: v for k, v in up.values().items() if k not in LOWERING_FLIGHT
                  and k not in _tune_fsm().LOWERING and not k.startswith("low_fall_")}
    first, second = json.loads(FLIGHT_FILE.read_text())["fit"]["commands"]
    start = re.search(r"--around (\S+)", first).group(1)
    values, settings = _tune_fsm().read_around(str(Path(__file__).resolve().parents[3] / start))
    assert settings == {"trunk_attitude": 0.3, "attitude_damping": "joint"}
    assert values["kc_lowering_fast"] == 300.0  # SCA 2009 §5's fast-walking k_c
    assert "--around A.json" in second and "--out A.json" in first
    assert all("--only lowering_flight" in c and "--max-tilt 26" in c for c in (first, second))
    sc = Scenario(swing_fraction=0.65, speed_m_per_s=1.4, mechanism="obstacle")
    flies, keeps = simulate_trip(sc, params=fl).summary, simulate_trip(sc, params=up).summary
    assert flies["strategy"] == keeps["strategy"] == "lowering"
    assert flies["recovered"] and flies["variant"] == "double_support"
    assert flies["airborne_before_landing_s"] == pytest.approx(0.068, abs=0.01)
    assert flies["trunk_tilt_at_recovery_contact_deg"] <= 26.0
    assert abs(flies["durations_s"]["trip_to_recovery_contact"] - 0.57) <= 0.72 - 0.57
    assert keeps["recovered"] and keeps["airborne_before_landing_s"] == 0.0
    slow = simulate_trip(sc.with_(speed_m_per_s=1.0), params=fl).summary
    assert slow["recovered"] and slow["airborne_before_landing_s"] == 0.0


def test_a_parameter_file_of_every_value_reads_back(tmp_path):
    """A search's ``--out`` file holds every tunable value, an option's "off" among them
    (``lowering_push_ahead`` -1 m, outside its search range): it reads back as the set it
    was written from; a value outside its range that is not the "off" one is refused in
    one line naming it."""
    from stumble.control.fsm_params import load_params
    from stumble.errors import InputError

    for p in (FSMParams(), load_params("flight"), load_params("upright")):
        f = tmp_path / "p.json"
        f.write_text(json.dumps({"params": p.values(),
                                 "settings": {"trunk_attitude": p.trunk_attitude}}))
        assert load_params(f) == p
    f.write_text(json.dumps({"params": {"lowering_push_ahead": -0.5}}))
    msg = "lowering_push_ahead = -0.5 is outside -0.3-0.4"
    with pytest.raises(InputError, match=re.escape(msg)):
        load_params(f)


def test_tune_fsm_searches_the_targets_and_the_walk_on_together():
    """``tune_fsm.py --only all+walk_on``: the targets (SPACE) and the walk on's values in one
    search (with ``--gains`` the six gains too); the other choices as before."""
    from stumble.control.fsm_params import GAINS, SPACE, WALK_ON

    t = _tune_fsm()
    both = t.search_space("all+walk_on", gains=True)
    assert set(both) == set(SPACE) | set(t.WALK_ON_NAMES) | set(GAINS)
    assert set(WALK_ON).isdisjoint(SPACE) and len(both) == len(SPACE) + len(WALK_ON) + len(
        GAINS)  # the reaching leg's two are targets of SPACE already
    assert set(t.search_space("all", gains=False)) == set(SPACE)
    assert set(t.search_space("walk_on", gains=False)) == set(t.WALK_ON_NAMES)
    assert set(t.search_space("lowering", gains=False)) == set(t.LOWERING) & set(SPACE)


def test_the_stance_hip_holds_the_pelvis_list_with_its_own_gain():
    """``kp_stance_hip_roll``: the stance hip's adduction holds the pelvis's list with a gain
    of its own (by default the swing leg's 600 N·m/rad). Three times stiffer, a force trip
    (0.25 of swing, 1.2 m/s) lists the pelvis less: at most 6.6° against 7.0° in the first
    1.5 s, a median 0.9° against 2.9° in the walk on after it."""
    from dataclasses import replace

    import mujoco

    from stumble.control.fsm import attitude_of

    sc = Scenario(mechanism="force", swing_fraction=0.25, speed_m_per_s=1.2)
    out = {}
    for kp in (FSMParams().kp_stance_hip_roll, 1800.0):
        r = simulate_trip(sc, params=replace(FSMParams(), kp_stance_hip_roll=kp))
        m, rec = r.body.model, r.recording
        d, pelvis = mujoco.MjData(m), m.body("pelvis").id
        lst = []
        for q in rec.qpos:
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            lst.append(abs(np.degrees(attitude_of(d.xmat[pelvis])[1])))
        lst = np.array(lst)
        early = rec.time_s < 1.5
        out[kp] = (r.summary["recovered"], lst[early].max(), np.median(lst[~early]))
    (ok0, max0, after0), (ok1, max1, after1) = out.values()
    assert ok0 and ok1
    assert max1 < max0 and after1 < 0.5 * after0, out


def test_tune_fsm_lateral_searches_the_frontal_plane_too():
    """``tune_fsm.py --lateral``: the coronal foot placement's gains and the hips'
    out-of-plane gains (LATERAL) join the search; without it they are not searched."""
    from stumble.control.fsm_params import LATERAL, SPACE, TUNABLE

    t = _tune_fsm()
    assert set(t.search_space("all", gains=False, lateral=True)) == set(SPACE) | set(LATERAL)
    assert set(LATERAL).isdisjoint(t.search_space("all+walk_on", gains=True))
    assert {TUNABLE[k][0][0] for k in LATERAL} == {
        "balance_cd_lat_rad_per_m", "balance_cv_lat_rad_s_per_m", "kp_hip_out_of_plane",
        "kp_stance_hip_roll"}
    p = FSMParams().with_values({"kp_stance_hip_roll": 1500.0, "balance_cv_lat": 0.4})
    assert (p.kp_stance_hip_roll, p.balance_cv_lat_rad_s_per_m) == (1500.0, 0.4)
    assert p.kp_hip_out_of_plane == FSMParams().kp_hip_out_of_plane


def test_the_help_texts_name_every_shipped_set_the_default_first(capsys):
    """``shipped_sets_text``: every name of ``SHIPPED`` once, the default first; the
    ``--params`` help of trip, study and validate is built from it, so a set added to
    ``SHIPPED`` is listed in each."""
    from stumble.cli import main
    from stumble.control.fsm_params import DEFAULT_SET, SHIPPED, shipped_sets_text

    text = shipped_sets_text()
    assert text.startswith(f"{DEFAULT_SET} (the default), ")
    names = [n.removesuffix(" (the default)") for n in text.split(", ")]
    assert sorted(names) == sorted(SHIPPED) and len(names) == len(SHIPPED)
    for command in ("trip", "study", "validate"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        out = " ".join(capsys.readouterr().out.split())
        assert all(n in out for n in SHIPPED), command
