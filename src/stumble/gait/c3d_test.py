"""Plug-in Gait joint angles from C3D files (needs the optional ezc3d package)."""

import numpy as np
import pytest

from stumble.body import build
from stumble.errors import InputError
from stumble.gait.files import play_motion, read_motion
from stumble.gait.reference import load_reference

ezc3d = pytest.importorskip("ezc3d")
GAIT = load_reference()


def _c3d(path, labels, values, rate=100.0):
    """A C3D with POINTs ``labels`` holding ``values`` (3, n_points, n_frames)."""
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    pts = np.ones((4, len(labels), values.shape[2]))
    pts[:3] = values
    c["data"]["points"] = pts
    c.write(str(path))
    return path


def _pig_walk(path, seconds=2.5, rate=100.0, prefix=""):
    """The embedded gait written as Plug-in Gait outputs (degrees, PiG signs)."""
    t = np.arange(0.0, seconds, 1.0 / rate)
    a = {k: np.degrees(v) for k, v in GAIT.angles(t / GAIT.stride_s).items()}
    labels, values = [], []
    for side, s in (("L", "l"), ("R", "r")):
        labels += [f"{prefix}{side}HipAngles", f"{prefix}{side}KneeAngles",
                   f"{prefix}{side}AnkleAngles"]
        values += [[a[f"hip_flexion_{s}"], a[f"hip_adduction_{s}"], a[f"hip_rotation_{s}"]],
                   [-a[f"knee_angle_{s}"], 0 * t + 2.0, 0 * t - 3.0],  # PiG: flexion +
                   [a[f"ankle_angle_{s}"], 0 * t, 0 * t]]
    labels += [f"{prefix}LPelvisAngles", f"{prefix}LASI"]
    values += [[-a["pelvis_tilt"], 0 * t + 1.0, 0 * t], [0 * t + 100.0, 0 * t, 0 * t + 900.0]]
    return _c3d(path, labels, np.array(values).transpose(1, 0, 2), rate), a


def test_plug_in_gait_angles_play_as_a_walk(tmp_path):
    path, a = _pig_walk(tmp_path / "walk.c3d", seconds=3.0, prefix="Anna:")
    motion = read_motion(path)
    assert {"hip_flexion_l", "hip_adduction_r", "knee_angle_r", "ankle_angle_l",
            "pelvis_tilt"} <= set(motion.columns)
    np.testing.assert_allclose(np.degrees(motion.columns["knee_angle_r"]), a["knee_angle_r"],
                               atol=1e-3)  # C3D stores floats
    np.testing.assert_allclose(np.degrees(motion.columns["pelvis_tilt"]), a["pelvis_tilt"],
                               atol=1e-3)
    pb = play_motion(build(), motion)
    assert pb.speed_m_per_s == pytest.approx(1.1, abs=0.15)
    assert len(pb.events.heel_strike_s["r"]) >= 2 and len(pb.events.toe_off_s["l"]) >= 2


def test_invalid_frames_are_cut_at_the_ends_and_interpolated_inside(tmp_path):
    path, _a = _pig_walk(tmp_path / "gaps.c3d")
    c = ezc3d.c3d(str(path))
    pts = c["data"]["points"]
    pts[:3, :3, :10] = 0.0  # PiG writes 0 where it has no angle
    pts[:3, :3, 100:104] = np.nan
    c["data"]["points"] = pts
    c.write(str(path))
    motion = read_motion(path)
    assert motion.time_s[0] == pytest.approx(0.1) and motion.n_frames == 240
    assert any("10 frame(s) at the start and 0 at the end have no valid angles" in n
               for n in motion.notes)
    assert any("up to 4 invalid frames inside the trial interpolated" in n for n in motion.notes)
    assert np.isfinite(motion.columns["hip_flexion_l"]).all()


def test_a_c3d_with_markers_only_says_what_is_missing(tmp_path):
    path = _c3d(tmp_path / "markers.c3d", ["LASI", "RASI", "LPSI"], np.random.default_rng(1)
                .normal(size=(3, 3, 50)) + 500.0)
    with pytest.raises(InputError) as info:
        read_motion(path)
    assert str(info.value) == ("markers.c3d: no Plug-in Gait joint angles (LHipAngles, "
                               "LKneeAngles, LAnkleAngles, ...); it holds 3 markers (LASI, "
                               "RASI, LPSI) and no angles: run Plug-in Gait (or OpenSim IK) on "
                               "it first")


def test_a_file_that_is_not_c3d_is_one_line(tmp_path):
    path = tmp_path / "bad.c3d"
    path.write_bytes(b"not a c3d file at all")
    with pytest.raises(InputError, match=r"^bad\.c3d: not a readable C3D file \("):
        read_motion(path)
