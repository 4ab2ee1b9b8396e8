"""OpenSim Storage (.mot/.sto) reading, writing and mapping onto the model coordinates."""

from pathlib import Path

import numpy as np
import pytest

from stumble.body.joints import PELVIS_ROTATIONS, hinge_names
from stumble.errors import InputError
from stumble.gait import readers
from stumble.gait.readers import (
    Motion,
    check_time,
    detect_family,
    is_angle_column,
    map_coordinates,
    read_mot,
    read_text,
    write_storage,
)

WALKING = Path(__file__).resolve().parents[4] / "shared" / "reference" / "walking"
MODEL_3D = [*(h.name for h in PELVIS_ROTATIONS), "pelvis_tx", "pelvis_ty", "pelvis_tz",
            *hinge_names()]
MODEL_PLANAR = ["pelvis_tx", "pelvis_ty", "pelvis_tilt", *hinge_names(planar=True)]


def _reference(name: str) -> Path:
    path = WALKING / name
    if not path.exists():
        pytest.skip(f"reference data {path} is not present")
    return path


def _write(tmp_path, text: str, name: str = "gait.mot") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _mot_text(names, rows, header=None) -> str:
    if header is None:
        header = ["Coordinates", "version=1", f"nRows={len(rows)}",
                  f"nColumns={len(names)}", "inDegrees=yes"]
    lines = [*header, "endheader", "\t".join(names)]
    lines += ["\t".join(str(v) for v in row) for row in rows]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ reference data


def test_subject01_3d_ik_reads_73_rows_by_23_coordinates():
    m = read_mot(_reference("subject01_walk1_ik.mot"))
    assert isinstance(m, Motion)
    assert m.source == "subject01_walk1_ik.mot" and m.in_degrees_source
    assert m.time_s.shape == (73,) and m.n_frames == 73
    assert len(m.columns) == 23 and "time" not in m.columns
    assert m.time_s[0] == pytest.approx(0.4) and m.time_s[-1] == pytest.approx(1.6)
    assert np.all(np.diff(m.time_s) > 0)
    for side in "rl":
        knee = np.degrees(m.columns[f"knee_angle_{side}"])  # radians in the Motion
        assert -75.0 < knee.min() < -60.0 and -5.0 < knee.max() < 5.0
        hip = np.degrees(m.columns[f"hip_flexion_{side}"])
        assert -30.0 < hip.min() < -10.0 and 15.0 < hip.max() < 30.0
    assert np.abs(m.columns["knee_angle_r"]).max() < 1.4  # really radians
    # translations are not converted
    assert m.columns["pelvis_ty"].mean() == pytest.approx(1.04, abs=0.05)
    assert m.columns["pelvis_tx"][0] == pytest.approx(0.60162386)
    assert m.columns["pelvis_tilt"][0] == pytest.approx(np.radians(5.18629404))


def test_subject01_ik_maps_onto_the_3d_model():
    m = read_mot(_reference("subject01_walk1_ik.mot"))
    coords = map_coordinates(m, MODEL_3D).columns
    assert len(coords) == 23
    assert set(coords) <= set(MODEL_3D)
    np.testing.assert_array_equal(coords["hip_flexion_r"], m.columns["hip_flexion_r"])


def test_subject01_planar_ik_and_the_planar_model():
    m = read_mot(_reference("subject01_walk_planar_ik.mot"))
    assert m.n_frames == 151 and len(m.columns) == 10
    assert set(map_coordinates(m, MODEL_PLANAR).columns) == set(m.columns)
    # the 3D file on the planar model: 3D-only DOF are dropped, in one note
    ik3d = read_mot(_reference("subject01_walk1_ik.mot"))
    planar = map_coordinates(ik3d, MODEL_PLANAR)
    assert set(planar.columns) == set(MODEL_PLANAR)
    assert planar.notes == ("subject01_walk1_ik.mot: kept 10 coordinates; ignored 13 other "
                            "column(s): pelvis_list, pelvis_rotation, pelvis_tz, "
                            "hip_adduction_r, hip_rotation_r and 8 more",)


def test_grf_columns_are_not_angles():
    m = read_mot(_reference("subject01_walk1_grf.mot"))
    assert m.n_frames == 1501 and len(m.columns) == 18
    assert 700.0 < m.columns["ground_force_vy"].max() < 900.0  # N, unconverted
    assert m.columns["ground_torque_y"][0] == pytest.approx(13.53783445)  # N·m, unconverted
    assert not any(is_angle_column(n) for n in m.columns)


# ------------------------------------------------------------------ format details


@pytest.mark.parametrize(("name", "angle"), [
    ("hip_flexion_r", True), ("pelvis_tilt", True), ("pelvis_tx", False),
    ("pelvis_ty", False), ("knee_angle_l", True), ("ground_force_vx", False),
    ("1_ground_force_px", False), ("ground_torque_z", False), ("time", False),
    ("/jointset/hip_r/hip_flexion_r/value", True), ("/jointset/ground_pelvis/pelvis_tz/value",
                                                    False),
])
def test_angle_column_rule(name, angle):
    assert is_angle_column(name) is angle


def test_sto_in_radians_is_not_converted(tmp_path):
    text = _mot_text(["time", "knee_angle_r", "pelvis_ty"], [[0, -0.5, 1.0], [0.01, -0.6, 1.01]],
                     header=["version=1", "OpenSimVersion=4.1", "DataType=double",
                             "inDegrees=no"])
    m = read_mot(_write(tmp_path, text, "states.sto"))
    assert not m.in_degrees_source
    np.testing.assert_allclose(m.columns["knee_angle_r"], [-0.5, -0.6])
    np.testing.assert_allclose(m.columns["pelvis_ty"], [1.0, 1.01])


def test_space_separated_simm_style_file_without_indegrees(tmp_path):
    text = "walk\ndatacolumns 3\ndatarows 2\nendheader\ntime hip_flexion_r pelvis_tx\n" \
           "  0.0   10.0  0.5\n  0.1   20.0  0.6\n\n"
    m = read_mot(_write(tmp_path, text))
    assert m.in_degrees_source  # degrees assumed when inDegrees is absent
    np.testing.assert_allclose(np.degrees(m.columns["hip_flexion_r"]), [10.0, 20.0])
    np.testing.assert_allclose(m.columns["pelvis_tx"], [0.5, 0.6])


def test_opensim4_path_names_map_and_speeds_are_skipped(tmp_path):
    names = ["time", "/jointset/hip_r/hip_flexion_r/value", "/jointset/hip_r/hip_flexion_r/speed",
             "/jointset/ground_pelvis/pelvis_ty/value"]
    text = _mot_text(names, [[0, 0.1, 1.0, 0.9], [0.1, 0.2, 1.0, 0.91]],
                     header=["version=1", "inDegrees=no"])
    coords = map_coordinates(read_mot(_write(tmp_path, text, "s.sto")), MODEL_3D).columns
    assert set(coords) == {"hip_flexion_r", "pelvis_ty"}
    np.testing.assert_allclose(coords["hip_flexion_r"], [0.1, 0.2])


# ------------------------------------------------------------------------- errors

GOOD_NAMES = ["time", "hip_flexion_r", "pelvis_tx"]
GOOD_ROWS = [[0.0, 1.0, 0.5], [0.1, 2.0, 0.6], [0.2, 3.0, 0.7]]


@pytest.mark.parametrize(("text", "fragment"), [
    ("", "empty"),
    ("   \n\n", "empty"),
    ("version=1\ntime\thip_flexion_r\n0\t1\n", "endheader"),
    ("version=1\nendheader\n", "no column-name line"),
    (_mot_text(["t", "hip_flexion_r"], [[0, 1], [1, 2]]), "no 'time' column"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5], [0.1, "abc", 0.6]]),
     "line 9, column 'hip_flexion_r': 'abc' is not a number"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5], [0.1, 2.0]], header=["inDegrees=yes"]),
     "line 5 has 2 values, expected 3"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5], [0.0, 2.0, 0.6]]), "not after the previous time"),
    (_mot_text(GOOD_NAMES, [[0.1, 1.0, 0.5], [0.0, 2.0, 0.6]]), "not after the previous time"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5]]), "at least 2"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5], [0.1, "nan", 0.6]]), "not finite"),
    (_mot_text(GOOD_NAMES, GOOD_ROWS).replace("nRows=3", "nRows=three"), "not an integer"),
    (_mot_text(GOOD_NAMES, GOOD_ROWS).replace("inDegrees=yes", "inDegrees=maybe"),
     "neither yes nor no"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5], [1e-300, 2.0, 0.6], [2e-300, 3.0, 0.7]]),
     "a time step of 1e-300 s is not a motion-capture rate"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5], [1e300, 2.0, 0.6], [2e300, 3.0, 0.7]]),
     "a time step of 1e+300 s is not a motion-capture rate"),
    (_mot_text(GOOD_NAMES, [[0.0, 1.0, 0.5], [1e309, 2.0, 0.6]]), "not finite"),
])
def test_malformed_file_raises_one_line_error_naming_the_file(tmp_path, text, fragment):
    with pytest.raises(InputError) as info:
        read_mot(_write(tmp_path, text))
    msg = str(info.value)
    assert msg.startswith("gait.mot: ") and "\n" not in msg
    assert fragment in msg


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"^gone\.mot: file not found") as info:
        read_mot(tmp_path / "gone.mot")
    assert "\n" not in str(info.value)


def test_binary_file(tmp_path):
    path = tmp_path / "gait.mot"
    path.write_bytes(b"\xff\xfe\x00\x81garbage")
    with pytest.raises(InputError, match=r"^gait\.mot: not a text file"):
        read_mot(path)


# --------------------------------------------------------------------- round trip


def test_write_read_round_trip(tmp_path):
    t = np.linspace(0.0, 1.0, 61)
    cols = {"hip_flexion_r": 0.4 * np.sin(2 * np.pi * t), "knee_angle_r": -0.6 * t ** 2,
            "pelvis_tx": 1.2 * t + 0.1, "pelvis_ty": 0.95 + 0.01 * np.cos(t)}
    path = tmp_path / "out.mot"
    write_storage(path, t, cols)
    text = path.read_text().splitlines()
    assert text[:6] == ["out", "version=1", "nRows=61", "nColumns=5", "inDegrees=yes",
                        "endheader"]
    m = read_mot(path)
    assert m.notes == ()
    np.testing.assert_allclose(m.time_s, t, atol=1e-12)
    assert list(m.columns) == list(cols)
    for k, v in cols.items():
        np.testing.assert_allclose(m.columns[k], v, atol=1e-10, err_msg=k)
    # degrees in the file for angles, metres for translations
    row = text[7].split("\t")
    assert float(row[1]) == pytest.approx(np.degrees(cols["hip_flexion_r"][0]), abs=1e-9)
    assert float(row[3]) == pytest.approx(0.1)


def test_write_with_explicit_angle_names_and_without_degrees(tmp_path):
    t = np.array([0.0, 0.5])
    path = tmp_path / "x.mot"
    write_storage(path, t, {"custom": np.array([np.pi, 0.0]),
                            "hip_flexion_r": np.array([1.0, 2.0])}, angle_names={"custom"})
    row = path.read_text().splitlines()[7].split("\t")
    assert float(row[1]) == pytest.approx(180.0) and float(row[2]) == pytest.approx(1.0)
    write_storage(path, t, {"hip_flexion_r": np.array([1.0, 2.0])}, in_degrees=False)
    lines = path.read_text().splitlines()
    assert "inDegrees=no" in lines and float(lines[7].split("\t")[1]) == 1.0


@pytest.mark.parametrize(("time", "cols"), [
    ([0.0, 0.0], {"a": [1.0, 2.0]}),
    ([0.0], {"a": [1.0]}),
    ([0.0, 1.0], {"a": [1.0]}),
    ([0.0, 1.0], {"a b": [1.0, 2.0]}),
    ([0.0, 1.0], {"a": [np.nan, 2.0]}),
    ([0.0, 1.0], {}),
])
def test_write_rejects_bad_input(tmp_path, time, cols):
    with pytest.raises(InputError, match=r"^w\.mot: "):
        write_storage(tmp_path / "w.mot", np.array(time),
                      {k: np.array(v) for k, v in cols.items()})


def _motion(names, source="gait.mot"):
    t = np.array([0.0, 0.1])
    return Motion(time_s=t, columns={n: np.array([0.1, 0.2]) for n in names},
                  in_degrees_source=True, source=source)


# ------------------------------------------------------ leniency of OpenSim's own reader


def test_header_counts_that_disagree_are_notes_as_in_opensim(tmp_path):
    text = _mot_text(GOOD_NAMES, GOOD_ROWS).replace("nRows=3", "nRows=1350").replace(
        "nColumns=3", "nColumns=40")
    m = read_mot(_write(tmp_path, text))
    assert m.n_frames == 3
    assert m.notes == (
        "gait.mot: the header says nColumns=40 but the file has 3 columns; the data are used "
        "(as OpenSim does)",
        "gait.mot: the header says nRows=1350 but the file has 3 data rows; the data are used "
        "(as OpenSim does)")


def test_a_repeated_last_time_row_is_dropped(tmp_path):
    rows = [*GOOD_ROWS, [0.2, 3.0, 0.7]]
    m = read_mot(_write(tmp_path, _mot_text(GOOD_NAMES, rows)))
    np.testing.assert_allclose(m.time_s, [0.0, 0.1, 0.2])
    assert any("the last row repeats time 0.2 s; dropped" in n for n in m.notes)


def test_trailing_tabs_and_crlf_of_spreadsheet_exports(tmp_path):
    # the layout of opensim-models' Tutorial1/normal.mot: every line padded with tabs, CRLF
    text = _mot_text(GOOD_NAMES, GOOD_ROWS, header=["normal_gait", "version=1", "nRows=3",
                                                    "nColumns=3", "inDegrees=yes"])
    lines = [ln + "\t" * 5 for ln in text.splitlines()] + ["\t" * 22] * 4
    path = tmp_path / "gait.mot"
    path.write_bytes("\r\n".join(lines).encode() + b"\r\n")
    m = read_mot(path)
    assert list(m.columns) == ["hip_flexion_r", "pelvis_tx"] and m.n_frames == 3


def test_a_column_named_twice_keeps_the_first(tmp_path):
    names = ["time", "hip_flexion_r", "ground_force_vx", "ground_force_vx"]
    rows = [[0.0, 1.0, 5.0, 7.0], [0.1, 2.0, 6.0, 8.0]]
    m = read_mot(_write(tmp_path, _mot_text(names, rows)))
    np.testing.assert_allclose(m.columns["ground_force_vx"], [5.0, 6.0])
    assert m.notes == ("gait.mot: columns named twice, the first of each kept: "
                       "ground_force_vx",)


# ------------------------------------------------------------------ extra columns


def test_markers_forces_speeds_and_moco_columns_are_ignored_in_one_note(tmp_path):
    # the kinds of columns of gait2392's IK output (markers, forces), OpenSim 3 states
    # (speeds *_u), Moco solutions (activations, controls) and a 2D model's 'lumbar'
    names = ["time", "hip_flexion_r", "knee_angle_r", "R.ASIS_tx", "R.ASIS_ty",
             "ground_force_vx", "hip_flexion_r_u", "/forceset/soleus_r/activation",
             "/forceset/soleus_r", "/jointset/hip_r/hip_flexion_l/value",
             "/jointset/hip_r/hip_flexion_l/speed", "lumbar"]
    rows = [[0.0, 10, -20, 0.6, 1.07, 3.0, 1.0, 0.2, 0.1, 5, 0.1, 2],
            [0.01, 11, -21, 0.61, 1.07, 3.5, 1.1, 0.3, 0.2, 6, 0.1, 3]]
    motion = map_coordinates(read_mot(_write(tmp_path, _mot_text(names, rows))), MODEL_PLANAR)
    assert set(motion.columns) == {"hip_flexion_r", "knee_angle_r", "hip_flexion_l"}
    np.testing.assert_allclose(np.degrees(motion.columns["hip_flexion_l"]), [5, 6])
    assert motion.notes == ("gait.mot: kept 3 coordinates; ignored 8 other column(s): "
                            "/jointset/hip_r/hip_flexion_l/speed, R.ASIS_tx, R.ASIS_ty, "
                            "ground_force_vx, hip_flexion_r_u and 3 more",)


def test_a_file_without_leg_coordinates_is_refused():
    # arm26's IK output: two arm coordinates of another model
    m = _motion(["r_shoulder_elev", "r_elbow_flex"], "arm26_InverseKinematics.mot")
    with pytest.raises(InputError) as info:
        map_coordinates(m, MODEL_3D)
    assert str(info.value) == (
        "arm26_InverseKinematics.mot: no hip, knee or ankle coordinate of the model: its 2 "
        "columns (r_shoulder_elev, r_elbow_flex) are no leg coordinates (the model's are "
        "listed by `stumble model --json`)")
    with pytest.raises(InputError, match=r"its coordinates \(pelvis_tx, pelvis_tilt\) are "
                                         r"not the model's legs"):
        map_coordinates(_motion(["pelvis_tx", "pelvis_tilt"]), MODEL_3D)
    with pytest.raises(InputError, match=r"^gait\.mot: no hip, knee or ankle"):
        map_coordinates(_motion(["pro_sup_r", "arm_flex_r"]), ["pelvis_tx", "hip_flexion_r"])


def test_extra_model_coordinates_need_not_be_in_the_file():
    coords = map_coordinates(_motion(["knee_angle_r"]), MODEL_3D).columns
    assert list(coords) == ["knee_angle_r"]
    assert "knee_rotation_r" in MODEL_3D and "shoulder_flexion_r" in MODEL_3D


def test_rajagopal_arm_coordinates_are_renamed_or_ignored():
    m = _motion(["hip_flexion_r", "arm_flex_r", "arm_add_l", "arm_rot_r", "elbow_flex_l",
                 "pro_sup_r", "wrist_flex_r", "wrist_dev_l", "knee_angle_r_beta"])
    coords = map_coordinates(m, MODEL_3D).columns
    assert set(coords) == {"hip_flexion_r", "shoulder_flexion_r", "shoulder_adduction_l",
                           "shoulder_rotation_r", "elbow_flexion_l"}
    np.testing.assert_array_equal(coords["shoulder_flexion_r"], m.columns["arm_flex_r"])
    # without Rajagopal names, pro_sup_* is our own coordinate (e.g. a file we wrote)
    assert set(map_coordinates(_motion(["pro_sup_r", "elbow_flexion_r", "knee_angle_r"]),
                               MODEL_3D).columns) == {"pro_sup_r", "elbow_flexion_r",
                                                      "knee_angle_r"}


def test_written_file_maps_back(tmp_path):
    t = np.array([0.0, 0.1, 0.2])
    cols = {n: np.full(3, 0.1) for n in MODEL_3D}
    path = tmp_path / "all.mot"
    write_storage(path, t, cols)
    motion = map_coordinates(read_mot(path), MODEL_3D)
    assert set(motion.columns) == set(MODEL_3D) and motion.notes == ()
    np.testing.assert_allclose(motion.columns["pro_sup_l"], 0.1)


# ---------------------------------------------------------------- model conventions


def _walk_motion(knee_sign: float, extra=(), degrees=True, scale=1.0):
    """One second of a knee flexing 5-65 deg (sign: + flexion as Rajagopal, - as gait2392)."""
    t = np.linspace(0.0, 1.0, 61)
    knee = knee_sign * np.radians(35.0 - 30.0 * np.cos(2 * np.pi * t))
    hip = np.radians(20.0 * np.sin(2 * np.pi * t))
    cols = {"hip_flexion_r": hip * scale, "knee_angle_r": knee * scale,
            **{n: np.zeros_like(t) for n in extra}}
    return Motion(t, cols, degrees, "walk.mot")


def test_rajagopal_knee_is_detected_by_its_values_and_made_negative():
    m = _walk_motion(+1.0)
    assert detect_family(m)[0] == "rajagopal"
    out = map_coordinates(m, MODEL_3D)
    knee = np.degrees(out.columns["knee_angle_r"])
    assert knee.max() == pytest.approx(-5.0, abs=1e-6) and knee.min() == pytest.approx(-65.0)
    assert out.notes == ("walk.mot: read as a rajagopal motion (its knee angles are mostly "
                         "positive (median 35 deg, peak 65 deg)); knee flexion made negative, "
                         "as in gait2392",)


def test_rajagopal_is_detected_by_its_patella_coordinate_and_model_overrides():
    m = _walk_motion(+1.0, extra=["knee_angle_r_beta"])
    assert detect_family(m) == ("rajagopal", "its coordinates name Rajagopal's patella or "
                                             "walker knee")
    gait = _walk_motion(-1.0)
    assert detect_family(gait)[0] == "gait2392"
    np.testing.assert_array_equal(map_coordinates(gait, MODEL_3D).columns["knee_angle_r"],
                                  gait.columns["knee_angle_r"])
    # forcing the wrong family: the knee leaves its range, with the hint
    with pytest.raises(InputError) as info:
        map_coordinates(m, MODEL_3D, family="gait2392")
    assert str(info.value) == ("walk.mot: knee_angle_r reaches 65 deg, 60 deg outside its range "
                               "-135 to 5 deg (knee flexion counted positive? try --model "
                               "rajagopal)")
    # forcing rajagopal on a gait2392 motion: no hint to try the family already given
    with pytest.raises(InputError) as info:
        map_coordinates(gait, MODEL_3D, family="rajagopal")
    assert str(info.value).endswith("outside its range -135 to 5 deg")
    with pytest.raises(InputError, match="unknown model family 'osim'"):
        map_coordinates(gait, MODEL_3D, family="osim")


# ------------------------------------------------------------------ impossible values


def test_radians_header_over_degrees_is_converted_with_a_note():
    # OpenSim CMC writes inDegrees=no above angles in degrees: a hip at 20 "rad"
    m = _walk_motion(-1.0, degrees=False, scale=180.0 / np.pi)
    out = map_coordinates(m, MODEL_3D)
    assert np.degrees(out.columns["hip_flexion_r"]).max() == pytest.approx(20.0)
    assert out.notes == ("walk.mot: the header says inDegrees=no but knee_angle_r reaches "
                         "65, which only degrees can be; read as degrees",)


@pytest.mark.parametrize("degrees", [True, False])
def test_absurd_angles_are_refused(degrees):
    m = _walk_motion(-1.0, degrees=degrees)
    m.columns["hip_flexion_r"][10] = np.radians(1e6)
    with pytest.raises(InputError) as info:
        map_coordinates(m, MODEL_3D)
    assert str(info.value) == ("walk.mot: column 'hip_flexion_r' reaches 1e+06 deg, beyond "
                               "±360 deg: not a joint angle (wrong units or a corrupt column?)")


def test_time_in_milliseconds_is_converted_and_absurd_steps_refused():
    t, notes = check_time("walk.mot", np.arange(0.0, 3000.0, 1000.0 / 60.0))
    assert t[-1] == pytest.approx(2.98333, abs=1e-4)
    assert notes == ["walk.mot: the time steps are 16.6667, so the time column is in "
                     "milliseconds (60 Hz); converted to seconds"]
    for bad in ([0.0, 1e-300, 2e-300], [0.0, 1e300, 2e300], [0.0, 500.0, 1000.0]):
        with pytest.raises(InputError, match=r"^walk\.mot: a time step of .* is not a "
                                             r"motion-capture rate"):
            check_time("walk.mot", np.array(bad))
    with pytest.raises(InputError, match=r"^walk\.mot: 1 sample\(s\); a motion needs at "
                                         r"least 2"):
        check_time("walk.mot", np.array([0.0]))


# ------------------------------------------------------------- files that never end


def test_only_regular_files_of_bounded_size_are_read(tmp_path, monkeypatch):
    import os

    fifo = tmp_path / "gait.mot"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"^gait\.mot: not a regular file"):
        read_mot(fifo)  # returns at once: a FIFO is never opened
    if Path("/dev/zero").exists():
        with pytest.raises(InputError, match=r"^zero: not a regular file"):
            read_text("/dev/zero")
    big = tmp_path / "big.mot"
    big.write_text("x" * 2000)
    monkeypatch.setattr(readers, "MAX_FILE_BYTES", 1000)
    with pytest.raises(InputError, match=r"^big\.mot: 0 MiB is above the 0 MiB limit"):
        read_mot(big)
    (tmp_path / "d.mot").mkdir()
    with pytest.raises(InputError, match=r"^d\.mot: is a directory"):
        read_mot(tmp_path / "d.mot")


def test_a_gap_in_the_time_column_is_refused():
    t = np.concatenate([np.arange(0.0, 1.0, 0.01), [79.6, 79.61]])
    with pytest.raises(InputError) as info:
        check_time("gap.sto", t)
    assert str(info.value) == ("gap.sto: a gap of 78.61 s between the samples at 0.99 and "
                               "79.6 s (more than 1 s)")
