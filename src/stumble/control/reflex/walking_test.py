"""The recorded walk of the reflex identification: embedded trial, kinematics, inverse dynamics."""

import csv
from pathlib import Path

import numpy as np
import pytest

from stumble.body import build
from stumble.control.reflex.walking import (
    fourier_derivatives,
    load_planar_trial,
    recorded_walk,
    write_moments_csv,
)
from stumble.errors import InputError
from stumble.gait.reference import FourierSeries

REFERENCE = Path(__file__).resolve().parents[5] / "shared" / "reference"
WALKING = REFERENCE / "walking"


@pytest.fixture(scope="module")
def body():
    return build(planar=True)


@pytest.fixture(scope="module")
def walk(body):
    return recorded_walk(body, rate_hz=1000.0)


def _peaks(fz: np.ndarray) -> tuple[float, float, float]:
    half = len(fz) // 2
    i1, i2 = int(np.argmax(fz[:half])), half + int(np.argmax(fz[half:]))
    return float(fz[i1]), float(fz[i2]), float(fz[i1:i2 + 1].min())


def test_embedded_trial_has_the_force_plate_figures():
    tr = load_planar_trial()
    assert tr.stride_s == pytest.approx(1.235, abs=0.005)  # right plate: 0.618 -> 1.853 s
    assert tr.events["r"]["heel_strike"] == 0.0
    for side in ("r", "l"):
        st = tr.stance[side]
        frac = st.duration_s / tr.stride_s
        # toe-off is heel strike plus the stance measured on the plate
        assert tr.events[side]["toe_off"] == pytest.approx(
            (tr.events[side]["heel_strike"] + frac) % 1.0, abs=1e-3)
        assert len(st.grf_vertical_bw) == len(st.cop_forward_m) == 101
    # reference README: stance ≈ 64 % of the stride (right: 0.792 s of 1.235 s)
    assert tr.stance["r"].duration_s / tr.stride_s == pytest.approx(0.64, abs=0.01)
    # reference README: vertical force peaks ≈ 1.07 and 1.08 BW with a 0.83 valley
    p1, p2, valley = _peaks(tr.stance["r"].grf_vertical_bw)
    assert p1 == pytest.approx(1.07, abs=0.015)
    assert p2 == pytest.approx(1.08, abs=0.015)
    assert valley == pytest.approx(0.83, abs=0.015)
    # the left foot lands at about half the stride (0.509)
    assert tr.events["l"]["heel_strike"] == pytest.approx(0.5, abs=0.02)
    # CoP rolls forward from heel toward the toes, by most of a foot length
    cop = tr.stance["r"].cop_forward_m
    assert cop[0] == 0.0 and cop[85] == pytest.approx(0.25, abs=0.03)


def test_fourier_derivatives_are_the_time_derivatives():
    s = FourierSeries(0.1, np.array([0.3, -0.2]), np.array([0.05, 0.1]))
    t = np.linspace(0.0, 2.0, 401)
    x, v, a = fourier_derivatives(s, t, stride_s=1.2)
    assert x == pytest.approx(s(t / 1.2))
    assert v[1:-1] == pytest.approx((x[2:] - x[:-2]) / (t[2] - t[0]), abs=2e-3)
    assert a[1:-1] == pytest.approx((v[2:] - v[:-2]) / (t[2] - t[0]), abs=2e-2)


def test_walk_is_one_exactly_periodic_stride_on_a_uniform_grid(body, walk):
    m = body.model
    n = len(walk.time_s)
    assert n == 1235 and walk.stride_s == pytest.approx(n / 1000.0)
    assert np.diff(walk.time_s) == pytest.approx(np.full(n - 1, 1e-3))
    assert walk.qpos.shape == (n, m.nq) and walk.qvel.shape == walk.qacc.shape == (n, m.nv)
    dt = 1e-3
    # one sample past the end is the first sample again (pelvis_tx advances a stride)
    nxt = walk.qpos[-1] + walk.qvel[-1] * dt + 0.5 * walk.qacc[-1] * dt**2
    nxt[0] -= walk.speed_m_per_s * walk.stride_s
    assert nxt == pytest.approx(walk.qpos[0], abs=1e-5)
    # velocities and accelerations are the derivatives of the positions (periodic)
    q = walk.qpos.copy()
    q[:, 0] -= walk.speed_m_per_s * walk.time_s
    dq = (np.roll(q, -1, 0) - np.roll(q, 1, 0)) / (2 * dt)
    dq[:, 0] += walk.speed_m_per_s
    assert dq == pytest.approx(walk.qvel, abs=1e-3)
    dv = (np.roll(walk.qvel, -1, 0) - np.roll(walk.qvel, 1, 0)) / (2 * dt)
    assert dv == pytest.approx(walk.qacc, abs=0.05)  # rad/s², accelerations up to ~100
    assert walk.speed_m_per_s == pytest.approx(1.1, abs=0.05)  # subject01: 1.09 m/s
    assert walk.heel_strike_s["r"] == 0.0
    assert walk.toe_off_s["r"] / walk.stride_s == pytest.approx(0.64, abs=0.01)


def test_measured_forces_scaled_to_our_body_weight(walk):
    fz = walk.grf["r"][:, 2] / walk.body_weight_n
    assert fz.max() == pytest.approx(1.08, abs=0.02)  # reference README: 1.07 / 1.08 BW
    total = (walk.grf["r"][:, 2] + walk.grf["l"][:, 2]) / walk.body_weight_n
    assert total.mean() == pytest.approx(1.0, abs=0.01)  # weight carried over the stride
    for side in ("r", "l"):
        swing = ~walk.stance[side]
        assert np.all(walk.grf[side][swing] == 0.0) and np.all(walk.cop[side][swing] == 0.0)
        assert walk.stance[side].mean() == pytest.approx(0.63, abs=0.02)
    both = walk.stance["r"] & walk.stance["l"]
    assert both.mean() == pytest.approx(0.26, abs=0.03)  # two double supports of ~13 %
    # the CoP lies on the floor, within the model's planting (a few cm)
    for side in ("r", "l"):
        assert np.abs(walk.cop[side][walk.stance[side], 2]).max() < 0.03


def test_moments_have_the_normal_walking_shape(walk):
    kg = walk.mass_kg
    pct = walk.phase * 100.0
    hip, knee, ankle = (walk.moments_nm[f"{j}_r"] / kg for j in ("hip", "knee", "ankle"))
    # Winter 2009 (Biomechanics and Motor Control of Human Movement, 4th ed., ch. 5),
    # normal cadence: plantarflexor peak about 1.5 N·m/kg late in stance. OpenSim signs:
    # plantarflexor moments are NEGATIVE (ankle dorsiflexion is the positive direction).
    assert -1.7 < ankle.min() < -1.2
    assert 40.0 < pct[np.argmin(ankle)] < 60.0
    assert np.abs(ankle[pct > 70]).max() < 0.1  # swing: the foot's weight only
    # hip: extensor (negative) after heel strike, flexor (positive) before toe-off
    assert hip[(pct > 5) & (pct < 20)].min() < -0.5
    assert hip[(pct > 45) & (pct < 62)].max() > 0.4
    # knee: extensor (positive) in loading response; peaks below ~1.2 N·m/kg (Winter)
    assert knee[(pct > 8) & (pct < 22)].max() > 0.15
    for series in (hip, knee):
        assert np.abs(series).max() < 1.2
    # the passive terms of our model (joint damping) are small beside the moments
    assert np.abs(walk.passive_nm["knee_r"]).max() < 0.1 * np.abs(walk.moments_nm["knee_r"]).max()


def test_residuals_show_kinematics_and_forces_agree(walk):
    rms = walk.residual_rms()
    assert rms["pelvis_ty"] < 0.05  # vertical: below 5 % of body weight (RMS)
    assert rms["pelvis_tx"] < 0.05
    assert abs(walk.residuals["pelvis_ty"].mean()) < 0.005  # weight balanced over the stride
    assert np.abs(walk.residuals["pelvis_ty"]).max() < 0.15


def test_moments_csv_has_51_rows_over_the_right_stride(walk, tmp_path):
    path = write_moments_csv(walk, tmp_path / "out" / "walking_moments.csv")
    rows = list(csv.reader(path.open()))
    assert rows[0] == ["percent", "hip_moment_nm", "knee_moment_nm", "ankle_moment_nm"]
    assert len(rows) == 52
    table = np.array(rows[1:], dtype=float)
    assert table[:, 0] == pytest.approx(np.linspace(0, 100, 51))
    assert table[0, 1:] == pytest.approx(table[-1, 1:], abs=1e-3)  # periodic
    k = int(np.argmin(table[:, 3]))
    assert table[k, 3] == pytest.approx(walk.moments_nm["ankle_r"].min(), rel=0.03)


def test_other_rates_and_bad_input(body):
    w = recorded_walk(body, rate_hz=200.0)
    assert len(w.time_s) == 247 and w.stride_s == pytest.approx(1.235)
    with pytest.raises(InputError, match="rate"):
        recorded_walk(body, rate_hz=0.0)
    with pytest.raises(InputError, match="planar"):
        recorded_walk(build(planar=False), rate_hz=1000.0)


@pytest.mark.skipif(not WALKING.is_dir(), reason="shared/reference is not present")
def test_embedded_figures_match_the_recorded_files():
    from stumble.gait.readers import read_mot

    tr = load_planar_trial()
    ik = read_mot(WALKING / "subject01_walk_planar_ik.mot")
    grf = read_mot(WALKING / "subject01_walk1_grf.mot")
    t0 = tr.metadata["force_plate_events_s"]["r"]["heel_strike"][0]
    # the force plates: right heel strikes 1.235 s apart, vertical force at mid-stance
    fy = grf.columns["ground_force_vy"]  # plate 0 carries the right foot
    t = grf.time_s
    on = np.flatnonzero(fy > 20.0)
    assert t[on[np.argmax(np.diff(on) > 1) + 1]] == pytest.approx(t0, abs=2e-3)
    st = tr.stance["r"]
    mid = t0 + 0.5 * (st.duration_s - 1.0 / 600.0)
    bw = tr.subject_mass_kg * 9.80665
    assert np.interp(mid, t, fy) / bw == pytest.approx(st.grf_vertical_bw[50], abs=0.01)
    # the Fourier fit reproduces the angles of the stride within a degree
    sel = (ik.time_s >= t0) & (ik.time_s <= t0 + tr.stride_s)
    ph = (ik.time_s[sel] - t0) / tr.stride_s
    for name in ("hip_flexion_r", "knee_angle_r", "ankle_angle_r", "lumbar_extension"):
        err = tr.coordinates[name](ph) - ik.columns[name][sel]
        drift = float(tr.metadata["drift_removed"][name].split()[0])
        assert np.degrees(np.abs(err).max()) < 1.0 + abs(drift)
