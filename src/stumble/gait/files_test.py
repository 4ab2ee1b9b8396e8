"""Motion files in (stumble.gait.files): reading any format, time spans, turning walks onto
+x, short files, and the alignment of a recorded trip."""

from dataclasses import replace

import numpy as np
import pytest

from stumble.body import build
from stumble.body.joints import PELVIS_ROTATIONS, rotation_matrix
from stumble.errors import InputError
from stumble.gait.bvh import hinge_angles
from stumble.gait.files import (
    MAX_PLAY_S,
    _pelvis_rotation,
    align_reference,
    play_motion,
    read_motion,
    straighten,
    stride_period_s,
    walking_heading,
)
from stumble.gait.playback import walk
from stumble.gait.readers import Motion, write_storage
from stumble.gait.reference import load_reference
from stumble.gait.writers import opensim_coordinates, write_mot
from stumble.trip import Scenario

GAIT = load_reference()
SPEED = GAIT.speed_m_per_s


def test_the_heading_is_held_where_the_file_stands_before_it_walks(tmp_path):
    """Standing 3 s, then walking and turning at 20 deg/s: before the walking the heading
    is that of its start (it was the end line extended back, -25 deg at t = 0)."""
    t = np.arange(0.0, 7.0, 0.01)
    cols = _gait_columns(t, lambda t: np.radians(20.0) * np.clip(t - 3.0, 0.0, None))
    standing = t < 3.0
    for k in ("pelvis_tx", "pelvis_tz"):
        cols[k] = np.where(standing, 0.0, cols[k] - cols[k][np.argmax(~standing)])
    heading = np.degrees(walking_heading(read_motion(_mot(tmp_path, t, cols, "stand.mot"))))
    assert np.ptp(heading[t < 1.5]) < 1e-9  # held (the walk is seen from 2.4 s: a stride
    # centred there reaches past 3 s)
    assert abs(heading[0]) < 12.0  # the walk's heading half a stride in, not -25


@pytest.fixture(scope="module")
def body3d():
    return build()


def _gait_columns(t, heading_rad=None, speed=SPEED):
    """The embedded gait at the times ``t`` as OpenSim coordinates (rad, m), walking along
    ``heading_rad(t)`` (default +x) at ``speed``."""
    cols = GAIT.angles(t / GAIT.stride_s)
    heading = np.zeros_like(t) if heading_rad is None else heading_rad(t)
    if heading_rad is not None:  # the pelvis turned by a world yaw
        rot = rotation_matrix((0.0, 0.0, 1.0), heading) @ _pelvis_rotation(cols, len(t))
        angles = hinge_angles(rot, [h.axis for h in PELVIS_ROTATIONS],
                              [tuple(np.radians(h.range_deg)) for h in PELVIS_ROTATIONS])
        for i, h in enumerate(PELVIS_ROTATIONS):
            cols[h.name] = np.unwrap(angles[:, i])
    steps = np.diff(t, prepend=t[0])
    cols["pelvis_tx"] = np.cumsum(speed * np.cos(heading) * steps)
    cols["pelvis_tz"] = -np.cumsum(speed * np.sin(heading) * steps)  # OpenSim z: right
    cols["pelvis_ty"] = 0.95 + 0.0 * t
    return cols


def _mot(tmp_path, t, cols, name="gait.mot"):
    path = tmp_path / name
    write_storage(path, t, cols)
    return path


def test_read_motion_maps_each_format_and_refuses_others(tmp_path):
    t = np.arange(0.0, 1.0, 0.01)
    path = _mot(tmp_path, t, _gait_columns(t))
    motion = read_motion(path)
    assert {"hip_flexion_r", "knee_angle_l", "pelvis_tilt"} <= set(motion.columns)
    planar = read_motion(path, planar=True)
    assert "hip_adduction_r" not in planar.columns and "knee_angle_r" in planar.columns
    other = tmp_path / "gait.trc"
    other.write_text("x")
    with pytest.raises(InputError, match=r"^gait\.trc: unknown motion format '\.trc'"):
        read_motion(other)


def test_a_walk_along_minus_x_plays_as_the_walk_along_plus_x(tmp_path, body3d):
    t = np.arange(0.0, 3.0, 0.01)
    ahead = read_motion(_mot(tmp_path, t, _gait_columns(t), "ahead.mot"))
    back = read_motion(_mot(tmp_path, t, _gait_columns(t, lambda t: np.pi + 0 * t), "back.mot"))
    straight = straighten(back)
    assert straight.notes[-1] == ("back.mot: walks along a heading of 180 deg, turning 0 deg "
                                  "in all; played along +x (speed and events along the "
                                  "walking direction)")
    for k in ("pelvis_tilt", "pelvis_list", "pelvis_rotation"):
        np.testing.assert_allclose(straight.columns[k], ahead.columns[k], atol=1e-6)
    assert straighten(ahead) is ahead  # already along +x: untouched
    pa, pb = play_motion(body3d, ahead), play_motion(body3d, back)
    assert pb.speed_m_per_s == pytest.approx(pa.speed_m_per_s, rel=1e-3)
    for side in "rl":
        np.testing.assert_allclose(pb.events.heel_strike_s[side], pa.events.heel_strike_s[side],
                                   atol=0.011)


def test_a_turning_walk_is_played_along_its_path(tmp_path, body3d):
    t = np.arange(0.0, 4.0, 0.01)
    path = _mot(tmp_path, t, _gait_columns(t, lambda t: np.radians(22.5) * t), "turn.mot")
    pb = play_motion(body3d, read_motion(path))
    assert pb.notes[0].startswith("turn.mot: walks along a heading of 0 deg, turning 90 deg in "
                                  "all"), pb.notes[0]  # 22.5 deg/s for 3.99 s
    straight = play_motion(body3d, read_motion(_mot(tmp_path, t, _gait_columns(t), "s.mot")))
    assert pb.speed_m_per_s == pytest.approx(straight.speed_m_per_s, rel=0.03)
    assert len(pb.events.heel_strike_s["r"]) == len(straight.events.heel_strike_s["r"])


@pytest.fixture(scope="module")
def own_walks(body3d, tmp_path_factory):
    """The package's own straight walks (stumble walk --speed 1.1, 1.5) as its motion.mot
    writes them, read back: (playback, motion) per speed."""
    out = {}
    for speed in (1.1, 1.5):
        pb = walk(body3d, speed)
        path = tmp_path_factory.mktemp("walk") / "motion.mot"
        write_mot(path, body3d, pb.time_s, pb.qpos)
        out[speed] = pb, read_motion(path)
    return out


@pytest.mark.parametrize("speed", [1.1, 1.5])
def test_the_packages_own_straight_walk_is_read_back_straight(own_walks, body3d, speed):
    # the pelvis sways about 3 cm to each side once a stride (0.8-1.0 Hz); a 1 Hz low-pass
    # let it through, read a heading of -11 deg turning 1 deg (-10, turning 10 at 1.5
    # m/s) and turned the pelvis by up to 11 deg
    pb, motion = own_walks[speed]
    assert stride_period_s(motion) == pytest.approx(pb.stride_s, rel=0.01)
    heading = np.degrees(walking_heading(motion))
    assert np.abs(heading).max() < 2.0  # the walk drifts 1.25 deg to the right
    assert np.ptp(heading) < 0.2
    assert straighten(motion) is motion
    again = play_motion(body3d, motion)
    assert not any("walks along" in n for n in again.notes), again.notes
    # and at its own speed (the walk blended at each touchdown read back 4 % slower)
    assert again.speed_m_per_s == pytest.approx(pb.speed_m_per_s, rel=0.01)
    written = opensim_coordinates(body3d, again.qpos)
    for k in ("pelvis_rotation", "pelvis_list", "pelvis_tilt"):  # file precision: 1e-11 deg
        np.testing.assert_allclose(written[k], motion.columns[k], atol=1e-9)


def test_a_slow_walk_read_back_keeps_its_last_toe_off(body3d, tmp_path):
    """stumble walk --speed 0.8 (4 s) ends 80 ms after the right foot's toe-off: read back,
    that toe-off was missed, the foot stayed planted to the end, the walk read 0.765 m/s
    and its joints moved by up to 8 deg (events._edge_peaks)."""
    pb = walk(body3d, 0.8)
    path = tmp_path / "motion.mot"
    write_mot(path, body3d, pb.time_s, pb.qpos)
    again = play_motion(body3d, read_motion(path))
    for side in ("r", "l"):
        for kind in ("toe_off_s", "heel_strike_s"):
            want, got = getattr(pb.events, kind)[side], getattr(again.events, kind)[side]
            assert len(got) == len(want), (side, kind, want, got)
            np.testing.assert_allclose(got, want, atol=0.035)
    assert pb.events.toe_off_s["r"][-1] > pb.time_s[-1] - 0.1  # the case: near the end
    assert again.speed_m_per_s == pytest.approx(0.8, rel=0.01)
    assert again.retarget["joint_correction_max_deg"] < 3.0


def test_the_packages_own_walk_turned_is_straightened_back(own_walks):
    """Its pelvis path and orientation turned by a world yaw of 22.5 deg/s: straightened,
    it is the straight walk again, sway and all."""
    _pb, motion = own_walks[1.1]
    t, cols = motion.time_s, motion.columns
    turn = np.radians(22.5) * t
    rot = rotation_matrix((0.0, 0.0, 1.0), turn) @ _pelvis_rotation(cols, len(t))
    angles = hinge_angles(rot, [h.axis for h in PELVIS_ROTATIONS],
                          [tuple(np.radians(h.range_deg)) for h in PELVIS_ROTATIONS])
    turned = dict(cols)
    for i, h in enumerate(PELVIS_ROTATIONS):
        turned[h.name] = np.unwrap(angles[:, i])
    vx, vy = np.gradient(cols["pelvis_tx"], t), np.gradient(-cols["pelvis_tz"], t)
    steps = np.diff(t, prepend=t[0])
    turned["pelvis_tx"] = cols["pelvis_tx"][0] + np.cumsum(
        (vx * np.cos(turn) - vy * np.sin(turn)) * steps)
    turned["pelvis_tz"] = -(-cols["pelvis_tz"][0] + np.cumsum(
        (vx * np.sin(turn) + vy * np.cos(turn)) * steps))
    straight = straighten(replace(motion, columns=turned))
    assert straight.notes[-1].startswith(f"{motion.source}: walks along a heading of -1 deg, "
                                         "turning 90 deg in all")
    diff = {k: np.degrees(straight.columns[k] - cols[k])
            for k in ("pelvis_rotation", "pelvis_list", "pelvis_tilt")}
    # the walk's own drift (1.25 deg to the right) is part of its heading: taken out too
    assert 0.5 < np.median(diff["pelvis_rotation"]) < 1.5
    # else the same pelvis, sway and all: within 0.63 deg (the sway, turned with the walk,
    # leaks into the stride's displacement: 22.5 deg/s x 3 cm / 1.1 m/s), 0.06 and 0.09 deg
    spread = {k: np.abs(d - np.median(d)).max() for k, d in diff.items()}
    assert spread["pelvis_rotation"] < 1.0, spread
    assert spread["pelvis_list"] < 0.2 and spread["pelvis_tilt"] < 0.2, spread


def test_a_file_of_one_stride_plays_on_its_steps_and_less_is_an_error(tmp_path, body3d):
    t = np.arange(0.0, 1.2, 1 / 60)  # about subject01_walk1_ik.mot: 1.2 s at 60 Hz
    pb = play_motion(body3d, read_motion(_mot(tmp_path, t, _gait_columns(t))))
    assert np.isfinite(pb.stride_s) and pb.stride_s == pytest.approx(GAIT.stride_s, rel=0.05)
    assert any("no complete stride of one foot; stride" in n and "period of the hips" in n
               for n in pb.notes)
    # the package's own 0.7 m/s walk, 1.5 s of its 1.594 s stride: the steps said 1.71 s
    # (less than one stride: refused); the hips' period 1.597 s
    slow = walk(body3d, 0.7, duration_s=1.5)
    write_mot(tmp_path / "slow.mot", body3d, slow.time_s, slow.qpos)
    again = play_motion(body3d, read_motion(tmp_path / "slow.mot"))
    assert again.stride_s == pytest.approx(slow.stride_s, rel=0.01)
    short = np.arange(0.0, 0.5, 1 / 60)
    with pytest.raises(InputError, match=r"^gait\.mot: 0\.48 s is less than one stride"):
        play_motion(body3d, read_motion(_mot(tmp_path, short, _gait_columns(short))))


def test_as_recorded_keeps_the_file_angles_and_times(tmp_path, body3d):
    t = np.arange(0.0, 1.5, 1 / 60)
    motion = read_motion(_mot(tmp_path, t, _gait_columns(t)))
    pb = play_motion(body3d, motion, as_recorded=True)
    np.testing.assert_allclose(pb.time_s, t)
    for k in ("hip_flexion_r", "knee_angle_l", "ankle_angle_r"):
        np.testing.assert_array_equal(pb.coordinates[k], motion.columns[k])
    planted = play_motion(body3d, motion)
    assert len(planted.time_s) == 297  # resampled at 200 Hz: 0 to 1.48 s
    assert planted.retarget["joint_correction_max_deg"] > 0.1


def test_time_spans_are_checked(tmp_path, body3d):
    t = np.arange(0.0, 2.0, 0.01)
    motion = read_motion(_mot(tmp_path, t, _gait_columns(t)))
    with pytest.raises(InputError, match=r"--duration 5\.0 s is longer than gait\.mot"):
        play_motion(body3d, motion, duration_s=5.0)
    long = Motion(np.arange(0.0, 700.0, 0.5), {k: np.zeros(1400) for k in ("knee_angle_r",)},
                  True, "long.mot")
    with pytest.raises(InputError, match=rf"^long\.mot: lasts 699\.5 s; stumble plays at most "
                                         rf"{MAX_PLAY_S:g} s"):
        play_motion(body3d, long)
    one = Motion(np.array([0.0, 1e-3]), {"knee_angle_r": np.zeros(2)}, True, "one.bvh")
    with pytest.raises(InputError, match=r"^one\.bvh: 1 sample\(s\) in 0\.001 s; playing needs "
                                         r"at least 2"):
        play_motion(body3d, one)


# ------------------------------------------------------------------- trip reference


def test_a_reference_is_aligned_by_the_swing_fraction_or_by_its_time(tmp_path):
    t = np.arange(0.0, 3.0, 0.01)
    motion = read_motion(_mot(tmp_path, t, _gait_columns(t)))
    sc = Scenario(swing_fraction=0.4, leg="left")
    by_time = align_reference(motion, sc, how="time")
    np.testing.assert_allclose(by_time.time_s, t)
    assert set(by_time.columns) == {"pelvis_tilt", "hip_flexion_r", "hip_flexion_l",
                                    "knee_angle_r", "knee_angle_l", "ankle_angle_r",
                                    "ankle_angle_l"}
    by_swing = align_reference(motion, sc)
    shift = t[0] - by_swing.time_s[0]
    note = by_swing.notes[-1]
    to, hs = (float(x) for x in note.split("swing from ")[1].rstrip(" s)").split(" to "))
    assert shift == pytest.approx(to + 0.4 * (hs - to), abs=1e-3)
    assert 0.3 < hs - to < 0.6  # a swing: about 37 % of the 1.2 s stride


def test_a_reference_without_usable_columns_or_overlap_is_an_error(tmp_path):
    sc = Scenario()
    arms = Motion(np.array([0.0, 1.0]), {"hip_adduction_r": np.zeros(2)}, True, "arms.mot")
    with pytest.raises(InputError, match=r"^arms\.mot: none of the joint pitches of SCA 2009 "
                                         r"Table 2"):
        align_reference(arms, sc, how="time")
    before = Motion(np.array([-2.0, -1.0]), {"knee_angle_r": np.zeros(2)}, True, "early.mot")
    with pytest.raises(InputError, match=r"^early\.mot: its time \(-2\.00 to -1\.00 s from its "
                                         r"trip\) does not overlap the simulated trip "
                                         r"\(0 to 6 s\)"):
        align_reference(before, sc, how="time")
