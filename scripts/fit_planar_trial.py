"""Fit the embedded planar walking trial from the OpenSim subject01 recording.

Writes ``src/stumble/gait/data/planar_trial.json``, the figures the reflex network is
identified from (``stumble.control.reflex.walking``):

- one stride from right heel strike (0.618 -> 1.853 s, force plates) of every planar
  coordinate as a Fourier series in stride phase (``FourierSeries``, the layout of
  ``reference_gait.json``). Angles in rad, OpenSim signs; ``pelvis_ty`` in m;
  ``pelvis_tx`` is the periodic deviation (m) from steady progression at
  ``speed_m_per_s``. A stride of real data does not close exactly (lumbar extension
  drifts ~5 deg over it): the drift, a linear ramp over the stride, is removed before
  the fit and reported in ``metadata.drift_removed``;
- the gait events (phase) from the force plates (vertical force > 20 N);
- per foot, the stance-phase ground reaction force (forward and vertical, in body
  weights) and the centre-of-pressure travel (m) from its first stance sample, each
  resampled to 101 points over stance. The trial is on a treadmill: the CoP is
  reported in the frame of the belt (plate CoP + belt speed × time), the travel an
  overground walker's CoP makes on the floor. Its last few samples, under 0.05 body
  weights before toe-off, run past the toe marker (0.33 m against a 0.28 m foot): the
  plate's CoP is unreliable at such small loads, and users clip it to the sole;
- the subject's foot length (heel to toe-tip marker, from the trc) and two offsets of
  the subject01 planar model (hip centre in the pelvis frame, heel marker from the
  ankle), so the pelvis motion and the CoP can be carried onto another body.

Only these figures are carried over; the data files stay in ``shared/reference``.

Run from the repository root:  python scripts/fit_planar_trial.py [REFERENCE_DIR]
"""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fit_reference_gait import (
    CREDIT,
    FORCE_THRESHOLD_N,
    SUBJECT_HEIGHT_M,
    plate_events,
    treadmill_speed,
)

from stumble.gait.readers import read_mot
from stumble.gait.reference import FourierSeries

HARMONICS = 8  # as the 3D fit: up to 6.5 Hz at this stride (Winter 2009 low-passes gait
# kinematics at about 6 Hz); residual RMS reported in metadata
SUBJECT_MASS_KG = 72.6  # subject01 (shared/reference/README.md; sum of subject01_planar.osim)
G = 9.80665  # m/s², standard gravity (as OpenSim)
STANCE_POINTS = 101
COORDINATES = ("pelvis_tilt", "pelvis_tx", "pelvis_ty", "hip_flexion_r", "knee_angle_r",
               "ankle_angle_r", "hip_flexion_l", "knee_angle_l", "ankle_angle_l",
               "lumbar_extension")


def plate_columns(grf_path: Path) -> dict[str, str]:
    """Column prefix of the plate under each foot (OpenSim z points right: CoP z > 0)."""
    grf = read_mot(grf_path)
    out = {}
    for prefix in ("", "1_"):
        on = grf.columns[f"{prefix}ground_force_vy"] > FORCE_THRESHOLD_N
        out["r" if np.median(grf.columns[f"{prefix}ground_force_pz"][on]) > 0 else "l"] = prefix
    return out


def subject_geometry(osim_path: Path) -> dict[str, list[float]]:
    """Sagittal (x forward, y up) offsets of the subject01 planar model, in m.

    ``hip_in_pelvis_m``: the right hip centre in the pelvis frame (the pelvis_ty/tx
    origin); ``heel_marker_from_ankle_m``: the R.Heel marker from the ankle centre in
    the talus frame (subtalar offset plus the marker's place on the calcaneus).
    """
    root = ET.parse(osim_path).getroot()

    def offset(joint: str, parent: bool) -> np.ndarray:
        for j in root.iter():
            if j.tag.endswith("Joint") and j.get("name") == joint:
                frames = list(j.iter("PhysicalOffsetFrame"))
                return np.array(frames[0 if parent else 1].findtext("translation").split(),
                                dtype=float)
        raise SystemExit(f"{osim_path.name}: no joint {joint}")

    heel = next(mk for mk in root.iter("Marker") if mk.get("name") == "R.Heel")
    if not heel.findtext("socket_parent_frame").endswith("calcn_r"):
        raise SystemExit("R.Heel is not on calcn_r")
    marker = np.array(heel.findtext("location").split(), dtype=float)
    ankle = offset("ankle_r", parent=False)  # ankle centre in the talus (0 0 0)
    to_heel = offset("subtalar_r", parent=True) - ankle + marker - offset("subtalar_r", False)
    return {"hip_in_pelvis_m": np.round(offset("hip_r", parent=True)[:2], 5).tolist(),
            "heel_marker_from_ankle_m": np.round(to_heel[:2], 5).tolist()}


def foot_length(trc_path: Path) -> float:
    """The subject's foot length (m): heel to toe-tip marker, median over the trial."""
    lines = trc_path.read_text().splitlines()
    names = [n for n in lines[3].split("\t")[2:] if n]
    rows = np.array([[float(x) for x in ln.split("\t")[: 2 + 3 * len(names)]]
                     for ln in lines[6:] if ln.strip()])
    lengths = []
    for side in ("R", "L"):
        h, t = names.index(f"{side}.Heel"), names.index(f"{side}.Toe.Tip")
        d = rows[:, 2 + 3 * t: 5 + 3 * t] - rows[:, 2 + 3 * h: 5 + 3 * h]
        lengths.append(np.median(np.linalg.norm(d, axis=1)) / 1000.0)
    return float(np.mean(lengths))


def stance_curves(grf_path: Path, prefix: str, t_on: float, t_off: float,
                  belt_m_per_s: float) -> dict[str, list[float]]:
    """Forward and vertical GRF (BW) and belt-frame CoP travel (m) over one stance.

    ``t_on`` is the first sample above the threshold, ``t_off`` the first below it; the
    curves span the samples in between (101 points, linear interpolation).
    """
    grf = read_mot(grf_path)
    t = grf.time_s
    on = (t >= t_on - 1e-9) & (t < t_off - 1e-9)
    ts = t[on]
    grid = np.linspace(ts[0], ts[-1], STANCE_POINTS)
    bw = SUBJECT_MASS_KG * G

    def col(name: str) -> np.ndarray:
        return np.interp(grid, ts, grf.columns[f"{prefix}{name}"][on])

    cop = col("ground_force_px") + belt_m_per_s * (grid - grid[0])  # OpenSim x forward
    return {"grf_forward_bw": np.round(col("ground_force_vx") / bw, 5).tolist(),
            "grf_vertical_bw": np.round(col("ground_force_vy") / bw, 5).tolist(),
            "cop_forward_m": np.round(cop - cop[0], 5).tolist()}


def vertical_peaks(fz: np.ndarray) -> tuple[float, float, float]:
    """First peak (first half of stance), second peak (second half) and the valley between."""
    n = len(fz)
    i1 = int(np.argmax(fz[: n // 2]))
    i2 = n // 2 + int(np.argmax(fz[n // 2:]))
    return float(fz[i1]), float(fz[i2]), float(fz[i1:i2 + 1].min())


def main(ref: Path) -> None:
    walking = ref / "walking"
    grf_path = walking / "subject01_walk1_grf.mot"
    events = plate_events(grf_path)
    prefix = plate_columns(grf_path)
    hs_r = events["r"]["heel_strike"]
    t0, stride = hs_r[0], hs_r[1] - hs_r[0]
    belt = treadmill_speed(walking / "subject01_walk.trc")

    ik = read_mot(walking / "subject01_walk_planar_ik.mot")
    t = ik.time_s
    if t[0] > t0 or t[-1] < t0 + stride:
        raise SystemExit("the planar IK does not cover the right stride")
    sel = (t >= t0 - 1e-9) & (t <= t0 + stride + 1e-9)
    phase = (t[sel] - t0) / stride
    coords, residual, drift = {}, {}, {}
    speed = belt
    for name in COORDINATES:
        v = ik.columns[name]
        jump = float(np.interp(t0 + stride, t, v) - np.interp(t0, t, v))
        if name == "pelvis_tx":  # treadmill: progression = belt + the pelvis' own drift
            speed = belt + jump / stride
        values = v[sel] - jump * phase
        series = FourierSeries.fit(phase % 1.0, values, HARMONICS)
        scale = 1.0 if name in ("pelvis_tx", "pelvis_ty") else float(np.degrees(1.0))
        unit = "m" if scale == 1.0 else "deg"
        rms = np.sqrt(np.mean((series(phase) - values) ** 2))
        residual[name] = f"{scale * rms:.4f} {unit}"
        a0 = 0.0 if name == "pelvis_tx" else series.a0  # tx: deviation about the mean
        coords[name] = {"a0": a0, "a": series.a.tolist(), "b": series.b.tolist()}
        drift[name] = f"{scale * jump:.4f} {unit}"

    def ph(x: float) -> float:
        return round((x - t0) / stride % 1.0, 4)

    stance, ev, checks = {}, {}, {}
    for side, e in events.items():
        hs = next(x for x in e["heel_strike"] if t0 - 1e-9 <= x < t0 + stride)
        to = next(x for x in e["toe_off"] if x > hs)
        curves = stance_curves(grf_path, prefix[side], hs, to, belt)
        stance[side] = {"duration_s": round(to - hs, 5), "plate": prefix[side] or "0",
                        **curves}
        ev[side] = {"heel_strike": ph(hs), "toe_off": ph(to)}
        own_stride = np.diff(e["heel_strike"])[0]
        p1, p2, valley = vertical_peaks(np.array(curves["grf_vertical_bw"]))
        checks[side] = {"stride_s": round(float(own_stride), 5),
                        "stance_fraction": round((to - hs) / float(own_stride), 4),
                        "vertical_peaks_bw": [round(p1, 3), round(p2, 3)],
                        "vertical_valley_bw": round(valley, 3),
                        "cop_travel_m": round(max(curves["cop_forward_m"]), 4)}
    out = {
        "source": CREDIT + "; planar IK subject01_walk_planar_ik.mot, force plates "
                  "subject01_walk1_grf.mot, markers subject01_walk.trc, "
                  "model subject01_planar.osim",
        "fitted_by": "scripts/fit_planar_trial.py",
        "harmonics": HARMONICS,
        "phase_zero": "right heel strike",
        "units": "angles rad (OpenSim signs); pelvis_ty m; pelvis_tx m, deviation from "
                 "steady progression; forces in body weights; CoP travel m",
        "stride_s": round(stride, 5),
        "speed_m_per_s": round(speed, 4),
        "subject_height_m": SUBJECT_HEIGHT_M,
        "subject_mass_kg": SUBJECT_MASS_KG,
        "subject_foot_length_m": round(foot_length(walking / "subject01_walk.trc"), 4),
        "subject_model": {**subject_geometry(ref / "models" / "subject01_planar.osim"),
                          "from": "subject01_planar.osim (x forward, y up)"},
        "events": ev,
        "stance": stance,
        "metadata": {"belt_speed_m_per_s": round(belt, 4),
                     "fit_residual_rms": residual,
                     "drift_removed": drift,
                     "force_plate_events_s": events,
                     "force_threshold_n": FORCE_THRESHOLD_N,
                     "gravity_m_per_s2": G,
                     "per_side": checks},
        "coordinates": coords,
    }
    dest = Path(__file__).resolve().parents[1] / "src/stumble/gait/data/planar_trial.json"
    dest.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {dest}: stride {stride:.4f} s, speed {speed:.3f} m/s (belt {belt:.3f}), "
          f"events {ev}")
    for side, c in checks.items():
        print(f"  {side}: {c}")
    print(f"  fit residual RMS {residual}")
    print(f"  drift removed {drift}")


if __name__ == "__main__":
    default = Path(__file__).resolve().parents[2] / "shared" / "reference"
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else default)
