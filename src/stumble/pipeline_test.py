"""One trip end to end: both mechanisms, the summary contract, the CLI files."""

import json

import mujoco
import numpy as np
import pytest

from stumble.cli import main
from stumble.errors import InputError
from stumble.pipeline import simulate_trip
from stumble.trip import FX_MAX_N, T_TRIP_S, Scenario

SUMMARY_KEYS = ("controller", "strategy", "variant", "recovered", "fell", "diverged",
                "swing_fraction", "speed_m_per_s", "mechanism", "trip_time_s", "states",
                "durations_s", "trunk_tilt_at_recovery_contact_deg", "rmse_deg", "sim_time_s",
                "wall_time_s", "steps", "angular_momentum_kg_m2_per_s")


def test_force_mechanism_applies_eq_2_3_to_the_swing_toe():
    r = simulate_trip(Scenario(swing_fraction=0.3, mechanism="force", duration_after_trip_s=0.6))
    rec = r.recording
    f = rec.trip_force
    assert f[:, 0].min() == pytest.approx(-FX_MAX_N, rel=0.02)
    assert np.all(f[rec.time_s > T_TRIP_S + 0.006] == 0.0)
    for key in SUMMARY_KEYS:
        assert key in r.summary


def test_obstacle_is_struck_by_the_swing_foot_and_stays():
    r = simulate_trip(Scenario(swing_fraction=0.3, mechanism="obstacle",
                               duration_after_trip_s=0.6))
    m = r.body.model
    box = m.geom("obstacle").id
    assert m.geom_size[box][2] * 2 == pytest.approx(0.10)  # default 10 cm high
    rec = r.recording
    side = 1  # left leg tripped by default
    hit = np.flatnonzero(rec.foot_on_obstacle[:, side])
    assert hit.size and rec.time_s[hit[0]] < 0.05  # the toe strikes it at once
    assert np.all(rec.trip_force == 0.0)  # no force model: the collision is physical
    # the foot does not pass through the box: while lower than its top it stays behind
    d = mujoco.MjData(m)
    face = m.geom_pos[box][0] - m.geom_size[box][0]
    for q in rec.qpos:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        toe = d.geom_xpos[m.geom("toes_l_geom").id]
        if toe[2] < 2 * m.geom_size[box][2] - 0.02:
            assert not (face + 0.03 < toe[0] < face + 2 * m.geom_size[box][0] - 0.03)


def test_a_toe_above_the_obstacle_is_an_error():
    with pytest.raises(InputError, match="would clear it"):
        # at 0.2 of swing the foot's lowest point is ~4 cm up: a 3 cm box cannot catch it
        simulate_trip(Scenario(swing_fraction=0.2, mechanism="obstacle", obstacle_height_m=0.03))


def test_cli_trip_writes_the_named_files(tmp_path, capsys):
    out = tmp_path / "t"
    assert main(["trip", "--swing", "0.2", "--out", str(out), "--no-video", "--duration",
                 "0.8"]) == 0
    s = json.loads((out / "summary.json").read_text())
    for key in SUMMARY_KEYS:
        assert key in s
    assert s["strategy"] == "elevating" and s["controller"] == "fsm"
    assert s["states"][0] == {"name": "passive_reaction", "start_s": 0.0}
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    for col in ("time_s", "state", "knee_angle_l_deg", "com_x_m", "com_vz_m_per_s",
                "foot_l_on_floor", "trip_force_x_n", "angular_momentum_y_kg_m2_per_s"):
        assert col in header
    assert (out / "trajectories.png").stat().st_size > 10_000
    # OpenSim and BVH: 1 s of walk, then the trip (time 0), at the recording's rate (every
    # 2 steps of 2 ms: 250 Hz)
    from stumble.gait.bvh import read_bvh
    from stumble.gait.readers import read_mot

    mot = read_mot(out / "motion.mot")
    n_rec = len((out / "timeseries.csv").read_text().splitlines()) - 1
    assert np.diff(mot.time_s) == pytest.approx(0.004)
    assert mot.n_frames == n_rec + 250 and mot.time_s[250] == pytest.approx(0.0)
    assert mot.time_s[0] == pytest.approx(-1.0)
    assert read_bvh(out / "motion.bvh").n_frames == mot.n_frames
    # the trip's own motion.mot as its reference (OpenSim path names, time 0 the trip):
    # the joint pitches agree with themselves
    text = (out / "motion.mot").read_text()
    for n in ("hip_flexion_l", "knee_angle_l", "ankle_angle_r"):
        text = text.replace(f"\t{n}\t", f"\t/jointset/x/{n}/value\t")
    (tmp_path / "ref.mot").write_text(text)
    again = tmp_path / "again"
    assert main(["trip", "--swing", "0.2", "--out", str(again), "--no-video", "--duration",
                 "0.8", "--reference", str(tmp_path / "ref.mot"), "--reference-align",
                 "time"]) == 0
    rmse = json.loads((again / "summary.json").read_text())["rmse_deg"]
    assert set(rmse) >= {"lead_hip", "lead_knee", "trail_ankle"}
    assert max(rmse.values()) < 0.05


def test_cli_trip_walks_on_six_seconds_by_default_and_step_gives_the_earlier_defaults(
        tmp_path):
    """Issue 11's defaults: the upright set, recovered meaning still walking 6 s after the
    trip with at least 4 steps after the recovery step; ``--params step --recovery
    step`` stops 1 s after the recovery step, as every trip did before."""
    assert main(["trip", "--swing", "0.2", "--out", str(tmp_path / "a"), "--no-video"]) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["recovery"] == "walk_on" and s["recovered"] and not s["fell"]
    assert s["sim_time_s"] > 5.9 and s["steps_after_recovery_step"] >= 4
    assert s["trunk_tilt_at_recovery_contact_deg"] <= 26.0
    assert main(["trip", "--swing", "0.2", "--out", str(tmp_path / "b"), "--no-video",
                 "--params", "step", "--recovery", "step"]) == 0
    b = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert b["recovery"] == "step" and b["recovered"]
    assert b["sim_time_s"] < 3.0


def test_cli_trip_reference_errors_are_one_line(tmp_path, capsys):
    ref = tmp_path / "arms.mot"
    ref.write_text("r\nendheader\ntime\tshoulder_flexion_r\thip_adduction_r\n0\t1\t2\n"
                   "0.01\t1\t2\n")
    argv = ["trip", "--out", str(tmp_path / "o"), "--reference-align", "time", "--reference"]
    assert main([*argv, str(ref)]) == 2
    err = capsys.readouterr().err
    assert err == ("stumble: arms.mot: none of the joint pitches of SCA 2009 Table 2 "
                   "(pelvis_tilt, hip_flexion_r, hip_flexion_l, knee_angle_r, ...) to compare "
                   "with\n")
    late = tmp_path / "late.mot"
    late.write_text("r\nendheader\ntime\tknee_angle_l\n10\t-5\n10.01\t-6\n")
    assert main([*argv, str(late)]) == 2
    assert capsys.readouterr().err == (
        "stumble: late.mot: its time (10.00 to 10.01 s from its trip) does not overlap the "
        "simulated trip (0 to 6 s)\n")
    assert not (tmp_path / "o").exists()  # refused before anything ran


def test_cli_trip_bad_input_is_one_line(tmp_path, capsys):
    assert main(["trip", "--swing", "0.99", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "swing fraction" in err and len(err.splitlines()) == 1


def test_rmse_against_a_reference_motion():
    base = simulate_trip(Scenario(swing_fraction=0.2, duration_after_trip_s=0.5))
    m, rec = base.body.model, base.recording
    coords = {n: rec.qpos[:, m.jnt_qposadr[m.joint(n).id]] + np.radians(5.0)
              for n in ("hip_flexion_l", "knee_angle_l", "hip_flexion_r")}
    ref = {"time_s": rec.time_s, **{k: np.degrees(v) for k, v in coords.items()}}
    again = simulate_trip(Scenario(swing_fraction=0.2, duration_after_trip_s=0.5), reference=ref)
    r = again.summary["rmse_deg"]
    # the same motion shifted by 5 degrees: 5 degrees of RMSE on every joint given
    assert r == {"lead_hip": pytest.approx(5.0, abs=1e-3),
                 "lead_knee": pytest.approx(5.0, abs=1e-3),
                 "trail_hip": pytest.approx(5.0, abs=1e-3)}
