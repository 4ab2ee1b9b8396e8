"""Reference gait, speed relation, kinematic playback, gait events."""

from pathlib import Path

import numpy as np
import pytest

from stumble.body import build
from stumble.errors import InputError
from stumble.gait.playback import TOUCHDOWN_BLEND_S, foot_slip, play, stance_mask, walk
from stumble.gait.reference import FourierSeries, check_speed, load_reference

REFERENCE = Path(__file__).resolve().parents[4] / "shared" / "reference"


@pytest.fixture(scope="module")
def body3d():
    return build()


@pytest.fixture(scope="module")
def playback3d(body3d):
    return walk(body3d, duration_s=4.0)


def test_fourier_fit_recovers_a_known_series():
    phase = np.linspace(0.0, 1.0, 50, endpoint=False)
    values = 0.3 + 0.2 * np.cos(2 * np.pi * phase) - 0.1 * np.sin(6 * np.pi * phase)
    s = FourierSeries.fit(phase, values, harmonics=4)
    assert s.a0 == pytest.approx(0.3)
    assert s.a[0] == pytest.approx(0.2)
    assert s.b[2] == pytest.approx(-0.1)
    assert s(0.25) == pytest.approx(0.3 - 0.1 * np.sin(1.5 * np.pi))


def test_reference_gait_matches_the_subject01_figures():
    g = load_reference()
    assert g.stride_s == pytest.approx(1.235, abs=0.01)  # force plates: 0.617 -> 1.852 s
    assert g.speed_m_per_s == pytest.approx(1.10, abs=0.03)  # treadmill belt from heel markers
    assert g.stance_fraction == pytest.approx(0.63, abs=0.02)  # reference README: ~64 %
    knee = np.degrees(g.coordinates["knee_angle_r"](np.linspace(0, 1, 201)))
    assert knee.min() == pytest.approx(-70.0, abs=5.0)  # peak swing flexion ~70 deg
    assert knee.max() > -5.0
    hip = np.degrees(g.coordinates["hip_flexion_r"](np.linspace(0, 1, 201)))
    assert hip.max() == pytest.approx(22.0, abs=4.0) and hip.min() == pytest.approx(-22.0, abs=4.0)


def test_arms_swing_in_counter_phase_with_the_legs():
    g = load_reference()
    ph = np.linspace(0, 1, 101)
    a = g.angles(ph)
    # right arm forward when the left leg is forward
    assert np.corrcoef(a["shoulder_flexion_r"], a["hip_flexion_l"])[0, 1] > 0.95
    assert np.corrcoef(a["shoulder_flexion_r"], a["hip_flexion_r"])[0, 1] < -0.8
    assert np.degrees(np.ptp(a["shoulder_flexion_r"])) == pytest.approx(30.0, abs=0.5)


@pytest.mark.skipif(not REFERENCE.is_dir(), reason="shared/reference is not present")
def test_fit_reproduces_the_recorded_angles():
    from stumble.gait.readers import read_mot

    g = load_reference()
    ik = read_mot(REFERENCE / "walking" / "subject01_walk1_ik.mot")
    t0 = g.metadata["force_plate_events_s"]["r"]["heel_strike"][0]
    phase = (ik.time_s - t0) / g.stride_s % 1.0
    for name in ("hip_flexion_r", "knee_angle_l", "ankle_angle_r", "pelvis_tilt"):
        err = np.degrees(g.coordinates[name](phase) - ik.columns[name])
        assert np.sqrt(np.mean(err**2)) < 0.5


def test_stride_length_follows_the_speed_relation():
    g = load_reference()
    l1, l2 = g.stride_length_at(1.0, 1.75), g.stride_length_at(1.5, 1.75)
    assert l2 / l1 == pytest.approx(1.5**0.42)  # Grieve 1968; Kuo 2001
    assert g.stride_length_at(1.0, 1.90) / l1 == pytest.approx(1.90 / 1.75)


@pytest.mark.parametrize("speed", [0.5, 1.7, float("nan")])
def test_speed_out_of_range_is_an_error(speed):
    with pytest.raises(InputError, match="speed"):
        check_speed(speed)


@pytest.mark.parametrize("planar", [False, True])
@pytest.mark.parametrize("speed", [0.7, 1.6])
def test_playback_walks_at_the_requested_speed_with_planted_feet(planar, speed):
    body = build(planar=planar)
    pb = walk(body, speed, duration_s=4.0)
    advance = (pb.qpos[-1, 0] - pb.qpos[0, 0]) / pb.time_s[-1]
    assert advance == pytest.approx(speed, rel=0.03)
    assert pb.stride_s == pytest.approx(load_reference().stride_length_at(speed, 1.75) / speed)
    from stumble.gait.playback import _sole_points

    pts = _sole_points(body, pb.qpos)
    t = pb.time_s
    for side in ("r", "l"):
        low = pts[side][:, :, 2].min(axis=1)
        stance = stance_mask(pb.events, side, t)
        landing = t < TOUCHDOWN_BLEND_S  # a heel strike just before the walk was cropped
        for hs in pb.events.heel_strike_s[side]:
            landing |= (t >= hs - 1e-9) & (t < hs + TOUCHDOWN_BLEND_S - 1e-9)
        assert np.all(np.abs(low[stance & ~landing]) < 0.01)  # no float or penetration > 1 cm
        # the touching-down foot comes down over TOUCHDOWN_BLEND_S (measured: from 2.0 cm)
        assert np.all((low[stance & landing] > -0.01) & (low[stance & landing] < 0.03))
        slips = foot_slip(pb, side)
        assert slips and max(slips) < 0.02  # no sliding beyond 2 cm per step


def test_foot_planting_blends_in_without_a_jump_at_touchdown(playback3d, body3d):
    # planting a touching-down foot at once moved the hips by 2.3-2.6 deg, the ankles by
    # 3.7-3.8 deg and the pelvis by 4.4 cm forward and 1.5 cm down within one 5 ms sample
    pb, m = playback3d.shown(), body3d.model
    gait = load_reference()
    t = pb.time_s
    angles = gait.angles(t / pb.stride_s, hip_scale=pb.retarget["hip_flexion_scale"])
    data = play(body3d, t, angles, "", plant=False)  # the same angles, not planted
    for side in ("r", "l"):
        for joint in ("hip_flexion", "knee_angle", "ankle_angle"):
            adr = m.jnt_qposadr[m.joint(f"{joint}_{side}").id]
            step = np.degrees(np.abs(np.diff(pb.qpos[:, adr])))
            steps_data = np.degrees(np.abs(np.diff(data.qpos[:, adr])))
            # measured: at most 1.23 times the data's largest step (the ankles at push-off)
            assert step.max() < 1.3 * steps_data.max(), (joint, side, step.max())
            if joint == "hip_flexion":  # measured 2.5 and 2.7 times
                assert step.max() < 3.0 * np.median(step), (side, step.max())
    forward = np.diff(pb.qpos[:, 0])
    assert forward.max() < 2.0 * np.median(forward)  # measured 1.87 times
    assert np.abs(np.diff(pb.qpos[:, 2])).max() < 0.003  # m; measured 2.25 mm (data: 2.05)
    # the trips start from the walk with the step kept: the same but near heel strikes
    kept = playback3d  # its state: the step kept
    near = t < 0.5 * TOUCHDOWN_BLEND_S  # a heel strike just before the walk was cropped
    for hs in (*pb.events.heel_strike_s["r"], *pb.events.heel_strike_s["l"]):
        near |= np.abs(t - hs) < 0.5 * TOUCHDOWN_BLEND_S + 0.005
    np.testing.assert_array_equal(kept.qpos[~near, 2:], pb.qpos[~near, 2:])
    shift = kept.qpos[~near, :2] - pb.qpos[~near, :2]  # x, y: both start at 0
    assert np.ptp(shift, axis=0).max() < 1e-12
    np.testing.assert_array_equal(kept.qvel, pb.qvel)
    adr = m.jnt_qposadr[m.joint("ankle_angle_l").id]
    assert np.degrees(np.abs(np.diff(kept.qpos[:, adr]))).max() > 3.0


def test_stance_fraction_is_that_of_the_data(playback3d):
    # kinematic events (Zeni et al. 2008) vs the force plates' 0.633
    assert playback3d.events.stance_fraction() == pytest.approx(0.633, abs=0.04)
    assert playback3d.stride_s == pytest.approx(1.23, abs=0.03)


def test_events_alternate_and_swing_fraction_runs_0_to_1(playback3d):
    ev = playback3d.events
    for side in ("r", "l"):
        assert len(ev.heel_strike_s[side]) >= 3 and len(ev.toe_off_s[side]) >= 3
        to = ev.toe_off_s[side][0]
        hs = next(t for t in ev.heel_strike_s[side] if t > to)
        assert ev.swing_fraction(side, to) == pytest.approx(0.0)
        assert ev.swing_fraction(side, hs) == pytest.approx(1.0)
        assert ev.swing_fraction(side, 0.5 * (to + hs)) == pytest.approx(0.5, abs=0.01)
        assert ev.swing_fraction(side, hs + 0.05) is None  # stance
    # the right foot's toe-off comes about 0.64 of a stride after its heel strike
    hs_r, to_r = ev.heel_strike_s["r"][0], next(
        t for t in ev.toe_off_s["r"] if t > ev.heel_strike_s["r"][0])
    assert (to_r - hs_r) / playback3d.stride_s == pytest.approx(0.65, abs=0.04)


def test_velocities_are_smoothed_derivatives_of_positions(playback3d, body3d):
    import mujoco

    pb = playback3d
    m = body3d.model
    knee = m.jnt_dofadr[m.joint("knee_angle_r").id]
    raw = np.zeros((len(pb.time_s) - 2, m.nv))
    for k in range(1, len(pb.time_s) - 1):
        dt = pb.time_s[k + 1] - pb.time_s[k - 1]
        mujoco.mj_differentiatePos(m, raw[k - 1], dt, pb.qpos[k - 1], pb.qpos[k + 1])
    # the 6 Hz low-passed derivative follows the raw one (knee peaks at ~6 rad/s) away
    # from touchdowns, where the foot planting leaves a kink the filter rounds off
    t = pb.time_s[1:-1]
    strikes = np.concatenate([pb.events.heel_strike_s[s] for s in ("r", "l")])
    away = np.min(np.abs(t[:, None] - strikes[None, :]), axis=1) > 0.05
    err = pb.qvel[1:-1, knee] - raw[:, knee]
    assert np.sqrt(np.mean(err[away] ** 2)) < 0.2
    # and integrated, the velocities give back the motion (within 2 degrees)
    swing = np.trapezoid(pb.qvel[:, knee], pb.time_s)
    qa = m.jnt_qposadr[m.joint("knee_angle_r").id]
    assert np.degrees(abs(swing - (pb.qpos[-1, qa] - pb.qpos[0, qa]))) < 2.0
    # ... and the pelvis moves forward smoothly at about the walking speed
    vx = pb.qvel[20:-20, 0]
    assert vx.min() > 0.7 and vx.max() < 1.6
    assert np.mean(vx) == pytest.approx(1.10, abs=0.05)
    k = len(pb.time_s) // 2
    q, v = pb.state_at(pb.time_s[k])
    assert np.allclose(q, pb.qpos[k]) and np.allclose(v, pb.qvel[k])


@pytest.mark.skipif(not REFERENCE.is_dir(), reason="shared/reference is not present")
@pytest.mark.parametrize("planar", [False, True])
def test_kinematic_events_match_the_force_plates(planar):
    """Events from the recorded planar trial played on our models vs its force plates."""
    from stumble.gait.playback import SAMPLE_HZ, play
    from stumble.gait.readers import read_mot

    body = build(planar=planar)
    ik = read_mot(REFERENCE / "walking" / "subject01_walk_planar_ik.mot")
    t = np.arange(ik.time_s[0], ik.time_s[-1], 1.0 / SAMPLE_HZ)
    coords = {k: np.interp(t, ik.time_s, v) for k, v in ik.columns.items()
              if k in body.joints or k == "pelvis_tilt"}
    pb = play(body, t, coords, "subject01 planar")
    plates = load_reference().metadata["force_plate_events_s"]
    for side in ("r", "l"):
        for kind, ours in (("heel_strike", pb.events.heel_strike_s[side]),
                           ("toe_off", pb.events.toe_off_s[side])):
            measured = [x for x in plates[side][kind] if t[0] + 0.1 < x < t[-1] - 0.1]
            assert measured
            for x in measured:  # every force-plate event has a kinematic one within 40 ms
                assert min(abs(np.array(ours) - x)) < 0.04, (side, kind, x, ours)
