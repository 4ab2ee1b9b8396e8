"""The trip: force model (SCA 2009 eq. 2-3), scenario checks, trip instant, obstacle."""

import numpy as np
import pytest

from stumble.errors import InputError
from stumble.trip import FX_MAX_N, FZ_MAX_N, T_TRIP_S, Scenario, TripForce, trip_time


def test_force_model_peaks_and_shape():
    f = TripForce()
    t = np.linspace(0.0, T_TRIP_S, 1141)
    F = f(t)
    assert F[:, 0].min() == pytest.approx(-FX_MAX_N, rel=1e-4)  # 170 N backward
    assert t[np.argmin(F[:, 0])] == pytest.approx(T_TRIP_S / 2, abs=1e-4)  # at T_c
    assert F[:, 2].max() == pytest.approx(FZ_MAX_N, rel=1e-4)  # 70 N up
    assert t[np.argmax(F[:, 2])] == pytest.approx(T_TRIP_S / 4, abs=1e-4)  # sine peak
    assert np.all(F[:, 1] == 0.0)
    # sigma = T_trip/6: the Gaussian is down to exp(-4.5) = 1.1 % of its peak at the ends
    assert F[0, 0] == pytest.approx(-FX_MAX_N * np.exp(-4.5), rel=1e-6)


def test_force_is_zero_outside_the_collision():
    f = TripForce()
    assert np.all(f(np.array([-0.01, T_TRIP_S + 0.001, 1.0])) == 0.0)


def test_force_impulse_matches_the_closed_form():
    f = TripForce()
    sigma = f.sigma_s
    expected_x = -FX_MAX_N * sigma * np.sqrt(2 * np.pi) * 0.9973  # ±3σ of a Gaussian
    assert f.impulse_ns()[0] == pytest.approx(expected_x, rel=1e-3)
    assert f.impulse_ns()[2] == pytest.approx(0.0, abs=1e-6)  # a full sine period


def test_force_width_is_a_parameter():
    wide = TripForce(sigma_s=T_TRIP_S / 3)
    assert abs(wide.impulse_ns()[0]) > abs(TripForce().impulse_ns()[0])


@pytest.mark.parametrize(("change", "word"), [
    ({"swing_fraction": 0.95}, "swing fraction"), ({"swing_fraction": 0.01}, "swing fraction"),
    ({"speed_m_per_s": 2.0}, "speed"), ({"leg": "middle"}, "leg"),
    ({"mechanism": "banana"}, "mechanism"), ({"obstacle_height_m": 0.5}, "obstacle height"),
    ({"strategy": "jump"}, "strategy"), ({"delay_scale": 0.0}, "delay scale"),
    ({"delays": "nerves"}, "delays 'nerves' is not one of all, response"),
    ({"timestep_s": 0.05}, "time step"),
])
def test_bad_scenarios_are_named(change, word):
    with pytest.raises(InputError, match=word):
        Scenario(**change).validated()


def test_trip_time_is_the_requested_fraction_of_swing():
    from stumble.gait.events import GaitEvents

    ev = GaitEvents({"l": [0.5, 1.7], "r": [1.1]}, {"l": [0.2, 1.3], "r": [0.7]})
    assert trip_time(ev, "l", 0.25) == pytest.approx(0.2 + 0.25 * 0.3)
    assert trip_time(ev, "l", 0.5, after_s=1.0) == pytest.approx(1.3 + 0.5 * 0.4)
    with pytest.raises(InputError):
        trip_time(ev, "l", 0.5, after_s=1.5)


def test_each_controller_has_its_default_step_and_the_state_machines_refuse_unstable_ones():
    assert Scenario().validated().timestep_s == 0.002
    assert Scenario(controller="reflex", mechanism="obstacle").validated().timestep_s == 0.002
    gh = Scenario(controller="gh2010", mechanism="obstacle")
    assert gh.validated().timestep_s == 0.002  # the default set's (knee-2ms-dense-wide-s3)
    assert gh.validated(gh2010_step_s=0.001).timestep_s == 0.001  # a 1 ms set's
    assert gh.with_(timestep_s=0.001).validated().timestep_s == 0.001  # divides 2 ms
    with pytest.raises(InputError, match="got 2 ms"):  # a 1 ms set refuses 2 ms
        gh.with_(timestep_s=0.002).validated(gh2010_step_s=0.001)
    with pytest.raises(InputError, match="not stable for the fsm controller"):
        Scenario(timestep_s=0.003).validated()
    assert Scenario(timestep_s=0.001).validated().timestep_s == 0.001


def test_start_own_is_for_walkers_and_the_walk_in_is_bounded():
    assert Scenario(controller="gh2010").validated().start == "own"
    assert Scenario(controller="reflex").validated().start == "own"  # both walkers: own gait
    assert Scenario().validated().start == "playback"
    with pytest.raises(InputError, match="fsm controller does not walk on its own"):
        Scenario(controller="fsm", start="own").validated()
    with pytest.raises(InputError, match="start 'walk'"):
        Scenario(controller="gh2010", start="walk").validated()
    with pytest.raises(InputError, match=r"walk-in 1\.0 s is outside 2-30 s"):
        Scenario(controller="gh2010", walk_in_s=1.0).validated()


def test_scenario_names_a_bad_strength_model_or_population():
    from stumble.trip import Scenario

    with pytest.raises(InputError, match="strength model 'weak'"):
        Scenario(strength_model="weak").validated()
    with pytest.raises(InputError, match="population 'teen'"):
        Scenario(population="teen").validated()
    with pytest.raises(InputError, match="population older is defined for the state machines"):
        Scenario(controller="gh2010", mechanism="obstacle", population="older").validated()


def test_recovery_rule_walk_on_asks_for_walking_to_the_end():
    from stumble.pipeline import _walk_on_s
    from stumble.trip import Scenario

    with pytest.raises(InputError, match="recovery rule 'stand'"):
        Scenario(recovery="stand").validated()
    sc = Scenario(recovery="walk_on", duration_after_trip_s=4.0).validated()
    assert _walk_on_s(sc, reflex=False) == pytest.approx(3.99)
    # the default (issue 11): walking on, 6 s after the trip
    assert Scenario().validated().recovery == "walk_on"
    assert Scenario().validated().duration_after_trip_s == 6.0
    assert _walk_on_s(Scenario().validated(), reflex=False) == pytest.approx(5.99)
    # the 1 s rule stops at the recovery step; the reflex controllers walk on 3 s
    assert _walk_on_s(Scenario(recovery="step").validated(), reflex=False) is None
    assert Scenario(recovery="step").validated().duration_after_trip_s == 3.0
    assert Scenario(controller="gh2010", mechanism="obstacle").validated(
        ).duration_after_trip_s == 3.0


def test_posed_reuses_one_scratch_data_per_model_with_fresh_kinematics():
    """``trip.posed``: the obstacle's set-up reads poses through one kept MjData per
    model's sizes (making one costs about 0.4 ms; ``build`` hands out copies), whose
    positions are those of a fresh MjData of that model in that pose, whatever pose or
    model it held before."""
    import mujoco
    import numpy as np

    from stumble.body import build
    from stumble.trip import posed

    body = build(planar=True, actuation="muscles")
    m = body.model
    q1, q2 = m.qpos0.copy(), m.qpos0.copy()
    q2[2] += 0.3  # another pose
    a = posed(m, q2)
    b = posed(m, q1)
    assert a is b  # the same scratch data
    fresh = mujoco.MjData(m)
    fresh.qpos[:] = q1
    mujoco.mj_kinematics(m, fresh)
    assert np.array_equal(b.xpos, fresh.xpos) and np.array_equal(b.site_xpos, fresh.site_xpos)
    other = build(planar=True, actuation="muscles").model  # a copy: the same sizes
    other.body_pos[1, 0] += 0.5  # (moved: its own kinematics in the shared data)
    c = posed(other, q1)
    assert c is b and not np.array_equal(c.xpos, fresh.xpos)
    mine = mujoco.MjData(other)
    mine.qpos[:] = q1
    mujoco.mj_kinematics(other, mine)
    assert np.array_equal(c.xpos, mine.xpos)
    servo = build(planar=False).model  # other sizes: its own data
    assert posed(servo, servo.qpos0) is not b


def test_a_seed_perturbs_joints_alone_and_the_same_seed_the_same_way():
    """Seed 0 leaves the played-back state as it is; any other seed adds Gaussian noise
    (SD 0.5 deg, 0.05 rad/s) to the joints only, not to the free pelvis, the same for
    the same seed."""
    import mujoco

    from stumble.body import build
    from stumble.trip import SEED_ANGLE_SD_RAD, SEED_VELOCITY_SD_RAD_S, perturb_initial_state

    body = build()
    m = body.model

    def state(seed):
        d = mujoco.MjData(m)
        perturb_initial_state(body, d, seed)
        return d.qpos.copy(), d.qvel.copy()

    q0, v0 = state(0)
    assert np.array_equal(q0, m.qpos0) and not v0.any()  # seed 0: as played back
    q1, v1 = state(7)
    # the pelvis's free joint is untouched; the 36 joints get the seed's draws, angles
    # first (SD 0.5 deg), then velocities (SD 0.05 rad/s), in the body's joint order
    assert np.array_equal(q1[:7], q0[:7]) and not v1[:6].any()
    rng = np.random.default_rng(7)
    qa = [m.jnt_qposadr[m.joint(n).id] for n in body.joints]
    va = [m.jnt_dofadr[m.joint(n).id] for n in body.joints]
    assert len(qa) == 36
    assert np.array_equal(q1[qa] - q0[qa], rng.normal(0.0, SEED_ANGLE_SD_RAD, 36))
    assert np.array_equal(v1[va], rng.normal(0.0, SEED_VELOCITY_SD_RAD_S, 36))
    assert SEED_ANGLE_SD_RAD == pytest.approx(np.radians(0.5)) and SEED_VELOCITY_SD_RAD_S == 0.05
    assert np.array_equal(q1, state(7)[0]) and not np.array_equal(q1, state(8)[0])


def test_obstacle_under_the_stance_foot_is_found_with_shared_planar_markers():
    """``check_clear_of_stance`` on the planar model with shared sole markers
    (``lumped``): the verdict the full grid's own 96 sites give (``points``) for boxes
    narrow across and along the stance foot, between its rows and columns."""
    import mujoco

    from stumble.body import build
    from stumble.errors import TripNotSet
    from stumble.trip import check_clear_of_stance

    lean, full = build(planar=True), build(planar=True, contact="points")
    q = np.zeros(lean.model.nq)  # the zero pose stands both feet on the floor
    d = mujoco.MjData(full.model)
    d.qpos[:] = q
    mujoco.mj_kinematics(full.model, d)
    pts = d.site_xpos[[full.model.site(n).id for n in full.foot_points["l"]], :2]
    verdicts = []
    for x0 in np.linspace(pts[:, 0].min() - 0.01, pts[:, 0].max() - 0.01, 9):
        for y0 in np.linspace(pts[:, 1].min() - 0.01, pts[:, 1].max() + 0.01, 9):
            box = (x0, 0.1, 0.02, 0.01, y0)  # 2 cm along, 1 cm across
            want = bool(((pts[:, 0] > x0) & (pts[:, 0] < x0 + 0.02)
                         & (np.abs(pts[:, 1] - y0) < 0.005)).any())
            try:
                check_clear_of_stance(lean, q, "l", box)
                got = False
            except TripNotSet:
                got = True
            assert got == want, (x0, y0)
            verdicts.append(got)
    assert any(verdicts) and not all(verdicts)  # both verdicts were tested
