"""BVH reading and retargeting onto the model's joint conventions."""

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stumble.body.joints import JOINTS_3D, SEGMENT_DIRECTION, expand, rotation_matrix
from stumble.errors import InputError
from stumble.gait.bvh import (
    basis_matrix,
    bvh_to_coordinates,
    default_segment,
    hinge_angles,
    joint_world_frames,
    read_bvh,
)

# A leg-and-arm skeleton in T-pose, y up, z forward (so the body's left is +x), in cm.
# (name, parent, offset); every joint has 3 rotation channels "Zrotation Xrotation
# Yrotation", the root 3 position channels before them.
SKELETON = [
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("LeftUpLeg", "Hips", (10.0, 0.0, 0.0)),
    ("LeftLeg", "LeftUpLeg", (0.0, -45.0, 0.0)),
    ("LeftFoot", "LeftLeg", (0.0, -43.0, 0.0)),
    ("LeftToeBase", "LeftFoot", (0.0, -6.0, 14.0)),
    ("RightUpLeg", "Hips", (-10.0, 0.0, 0.0)),
    ("RightLeg", "RightUpLeg", (0.0, -45.0, 0.0)),
    ("RightFoot", "RightLeg", (0.0, -43.0, 0.0)),
    ("RightToeBase", "RightFoot", (0.0, -6.0, 14.0)),
    ("Spine", "Hips", (0.0, 10.0, 0.0)),
    ("Chest", "Spine", (0.0, 25.0, 0.0)),
    ("Neck", "Chest", (0.0, 20.0, 0.0)),
    ("Head", "Neck", (0.0, 8.0, 0.0)),
    ("LeftShoulder", "Chest", (4.0, 17.0, 0.0)),
    ("LeftArm", "LeftShoulder", (14.0, 0.0, 0.0)),
    ("LeftForeArm", "LeftArm", (28.0, 0.0, 0.0)),
    ("LeftHand", "LeftForeArm", (26.0, 0.0, 0.0)),
    ("RightShoulder", "Chest", (-4.0, 17.0, 0.0)),
    ("RightArm", "RightShoulder", (-14.0, 0.0, 0.0)),
    ("RightForeArm", "RightArm", (-28.0, 0.0, 0.0)),
    ("RightHand", "RightForeArm", (-26.0, 0.0, 0.0)),
]
END_SITES = {"LeftToeBase": (0.0, 0.0, 5.0), "RightToeBase": (0.0, 0.0, 5.0),
             "Head": (0.0, 18.0, 0.0), "LeftHand": (18.0, 0.0, 0.0),
             "RightHand": (-18.0, 0.0, 0.0)}
ORDER = "ZXY"  # rotation channel order of every joint


def _bvh_text(frames, root_pos=(0.0, 95.0, 0.0), scale=1.0, order=ORDER, dt=1 / 60,
              skeleton=SKELETON, end_sites=END_SITES, root="Hips"):
    """BVH text of ``skeleton``; ``frames`` is a list of {joint: {axis letter: degrees}}."""
    children = {}
    for name, parent, _ in skeleton:
        children.setdefault(parent, []).append(name)
    offsets = {name: np.array(off) * scale for name, _, off in skeleton}
    lines = ["HIERARCHY"]

    def emit(name, depth):
        pad = "\t" * depth
        lines.append(f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {name}")
        lines.append(pad + "{")
        o = offsets[name]
        lines.append(f"{pad}\tOFFSET {o[0]:.6f} {o[1]:.6f} {o[2]:.6f}")
        rot = " ".join(f"{a}rotation" for a in order)
        pos = "Xposition Yposition Zposition " if depth == 0 else ""
        lines.append(f"{pad}\tCHANNELS {6 if depth == 0 else 3} {pos}{rot}")
        for child in children.get(name, []):
            emit(child, depth + 1)
        if name in end_sites:
            e = np.array(end_sites[name]) * scale
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{",
                          f"{pad}\t\tOFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}", f"{pad}\t}}"])
        lines.append(pad + "}")

    emit(root, 0)
    lines.extend(["MOTION", f"Frames: {len(frames)}", f"Frame Time: {dt:.8f}"])
    for frame in frames:
        values = []
        for name, parent, _ in skeleton:
            if parent is None:
                values += [v * scale for v in frame.get("root_pos", root_pos)]
            angles = frame.get(name, {})
            values += [angles.get(a, 0.0) for a in order]
        lines.append(" ".join(f"{v:.6f}" for v in values))
    return "\n".join(lines) + "\n"


def _retarget(tmp_path, frames, name="walk.bvh", **kw):
    text_kw = {k: kw.pop(k) for k in ("root_pos", "scale", "order", "skeleton", "end_sites")
               if k in kw}
    path = tmp_path / name
    path.write_text(_bvh_text(frames, **text_kw))
    return bvh_to_coordinates(read_bvh(path), **kw)


def _deg(motion, name, frame=0):
    return float(np.degrees(motion.columns[name][frame]))


# ------------------------------------------------------------------------ reading


def test_read_bvh_structure_and_frame_time(tmp_path):
    path = tmp_path / "t.bvh"
    path.write_text(_bvh_text([{}, {}, {}], dt=0.01))
    bvh = read_bvh(path)
    assert [j.name for j in bvh.joints] == [s[0] for s in SKELETON]
    assert bvh.n_frames == 3 and bvh.motion.shape == (3, 6 + 3 * (len(SKELETON) - 1))
    assert bvh.frame_time_s == pytest.approx(0.01)
    np.testing.assert_allclose(bvh.time_s, [0.0, 0.01, 0.02])
    leg = bvh.joints[bvh.index("LeftLeg")]
    assert bvh.joints[leg.parent].name == "LeftUpLeg"
    np.testing.assert_allclose(leg.offset, [0.0, -45.0, 0.0])
    assert leg.channels == ("Zrotation", "Xrotation", "Yrotation")
    np.testing.assert_allclose(bvh.joints[bvh.index("Head")].end_sites[0], [0.0, 18.0, 0.0])


@pytest.mark.parametrize("order", ["ZXY", "XYZ", "YZX"])
def test_channel_order_is_intrinsic_as_written(tmp_path, order):
    angles = {"Z": 25.0, "X": -40.0, "Y": 60.0}
    path = tmp_path / "o.bvh"
    path.write_text(_bvh_text([{"LeftUpLeg": angles}], order=order))
    bvh = read_bvh(path)
    rot, pos = joint_world_frames(bvh)
    k = bvh.index("LeftUpLeg")
    expected = Rotation.from_euler(order, [angles[a] for a in order], degrees=True).as_matrix()
    np.testing.assert_allclose(rot[0, k], expected, atol=1e-9)
    # the knee sits at the hip plus the rotated thigh offset
    knee = bvh.index("LeftLeg")
    np.testing.assert_allclose(pos[0, knee], pos[0, k] + expected @ [0.0, -45.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(pos[0, 0], [0.0, 95.0, 0.0])


GOOD = _bvh_text([{}, {}])


def _break(text, old, new, count=1):
    assert old in text
    return text.replace(old, new, count)


@pytest.mark.parametrize(("text", "fragment"), [
    ("", "empty"),
    ("MOTION\nFrames: 1\nFrame Time: 0.1\n0\n", "HIERARCHY"),
    (GOOD.replace("\t}\n", "\n", 1), "unbalanced braces"),
    (GOOD.replace("MOTION", "}\nMOTION"), "unbalanced braces"),
    (GOOD.replace("MOTION", ""), "MOTION"),
    (GOOD.rstrip("\n").rsplit(" ", 1)[0] + "\n", "values, expected"),
    (GOOD.rstrip("\n").rsplit(" ", 1)[0] + " abc\n", "not a number"),
    (GOOD.rstrip("\n").rsplit(" ", 1)[0] + " nan\n", "not finite"),
    (GOOD.replace("Frame Time: 0.01666667", "Frame Time: 0"), "not a motion-capture rate"),
    (GOOD.replace("Frame Time: 0.01666667", "Frame Time: -0.1"), "not a motion-capture rate"),
    (GOOD.replace("Frame Time: 0.01666667", "Frame Time: 1e-300"), "a frame time of 1e-300 s"),
    (GOOD.replace("Frame Time: 0.01666667", "Frame Time: 1e300"), "a frame time of 1e300 s"),
    (GOOD.split("MOTION")[0] + "MOTION\nFrames: 2\nFrame Time: 0.01\n", "no rows of motion"),
    (GOOD.replace("CHANNELS 3 Zrotation", "CHANNELS 3 Wrotation", 1), "unknown channel"),
    (GOOD.replace("OFFSET 0.000000 -45.000000", "OFFSET zero -45.000000", 1), "not a number"),
    (GOOD.replace("JOINT RightUpLeg", "JOINT LeftUpLeg"), "appears twice"),
    # 5000 nested joints: refused at 200, before Python's recursion limit
    ("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 0\n"
     + "".join(f"JOINT J{k}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n" for k in range(5000))
     + "}\n" * 5001 + "MOTION\nFrames: 1\nFrame Time: 0.01\n\n", "nested more than 200 deep"),
])
def test_malformed_bvh_raises_one_line_error_naming_the_file(tmp_path, text, fragment):
    path = tmp_path / "bad.bvh"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        read_bvh(path)
    msg = str(info.value)
    assert msg.startswith("bad.bvh: ") and "\n" not in msg
    assert fragment in msg


def test_missing_bvh_file(tmp_path):
    with pytest.raises(InputError, match=r"^nope\.bvh: file not found"):
        read_bvh(tmp_path / "nope.bvh")


# ----------------------------------------------------------------------- mapping


@pytest.mark.parametrize(("name", "segment"), [
    ("Hips", "pelvis"), ("mixamorig:Hips", "pelvis"), ("Spine2", "torso"),
    ("LowerBack", "torso"), ("Neck", "head"), ("Head", "head"),
    ("LeftUpLeg", "thigh_l"), ("LHipJoint", "thigh_l"), ("RightThigh", "thigh_r"),
    ("mixamorig:LeftLeg", "shank_l"), ("LeftShin", "shank_l"), ("thigh_l", "thigh_l"),
    ("Bip01 R Calf", "shank_r"), ("LeftFoot", "foot_l"), ("RightToeBase", "toes_r"),
    ("LeftToe", "toes_l"), ("LeftArm", "upper_arm_l"), ("RightUpperArm", "upper_arm_r"),
    ("LeftForeArm", "forearm_l"), ("RightHand", "hand_r"), ("LeftShoulder", None),
    ("LeftHandIndex1", None), ("Reference", None),
    # DAZ and Poser names
    ("lShldr", "upper_arm_l"), ("rForeArm", "forearm_r"), ("lThigh", "thigh_l"),
    ("rShin", "shank_r"), ("hip", "pelvis"), ("abdomen", "torso"), ("lCollar", None),
    ("LeftCollar", None), ("LeftElbow", "forearm_l"), ("RightWrist", "hand_r"),
    ("LeftHip", "thigh_l"), ("RightKnee", "shank_r"), ("LeftAnkle", "foot_l"),
])
def test_default_segment_names(name, segment):
    assert default_segment(name) == segment


def test_basis_matrix_default_and_handedness():
    c = basis_matrix()
    # our x = BVH z (forward), our y = BVH x (left), our z = BVH y (up)
    np.testing.assert_allclose(c @ [0, 0, 1], [1, 0, 0])
    np.testing.assert_allclose(c @ [1, 0, 0], [0, 1, 0])
    np.testing.assert_allclose(c @ [0, 1, 0], [0, 0, 1])
    for up, fwd in [("y", "z"), ("z", "y"), ("z", "-x"), ("-y", "x"), ("x", "-z")]:
        m = basis_matrix(up, fwd)
        assert np.linalg.det(m) == pytest.approx(1.0)
        np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)
    with pytest.raises(InputError):
        basis_matrix("y", "y")
    with pytest.raises(InputError):
        basis_matrix("up", "z")


def test_hinge_angles_recovers_every_joint_of_the_table():
    rng = np.random.default_rng(3)
    groups = {}
    for name, jname, _, axis, _ in expand(JOINTS_3D):
        groups.setdefault(jname, []).append((name, axis))
    for jname, hinges in groups.items():
        axes = [a for _, a in hinges]
        truth = rng.uniform(-1.2, 1.2, size=(50, len(axes)))
        truth[:, 1:2] *= 0.8 if len(axes) == 3 else 1.0  # keep away from gimbal lock
        rot = np.broadcast_to(np.eye(3), (50, 3, 3))
        for i, a in enumerate(axes):
            rot = rot @ rotation_matrix(a, truth[:, i])
        np.testing.assert_allclose(hinge_angles(rot, axes), truth, atol=1e-9, err_msg=jname)


# -------------------------------------------------------------------- retargeting


def test_t_pose_gives_abducted_arms_and_neutral_legs(tmp_path):
    m = _retarget(tmp_path, [{}])
    assert m.source == "walk.bvh" and m.in_degrees_source
    for s in "rl":
        assert _deg(m, f"shoulder_adduction_{s}") == pytest.approx(-90.0, abs=1e-6)
        assert _deg(m, f"shoulder_flexion_{s}") + _deg(m, f"shoulder_rotation_{s}") == \
            pytest.approx(0.0, abs=1e-6)  # gimbal lock: only the sum is defined
        for name in ("elbow_flexion", "pro_sup", "wrist_flexion", "wrist_deviation",
                     "hip_flexion", "hip_adduction", "hip_rotation", "knee_angle",
                     "knee_rotation", "ankle_angle", "subtalar_angle", "mtp_angle"):
            assert _deg(m, f"{name}_{s}") == pytest.approx(0.0, abs=1e-6), name
    for name in ("pelvis_tilt", "pelvis_list", "pelvis_rotation", "lumbar_extension",
                 "lumbar_bending", "lumbar_rotation", "neck_flexion", "neck_bending",
                 "neck_rotation"):
        assert _deg(m, name) == pytest.approx(0.0, abs=1e-6), name
    assert m.columns["pelvis_ty"][0] == pytest.approx(0.95)  # cm guessed from the leg


def test_lowering_the_arms_from_t_pose_gives_zero_shoulder_angles(tmp_path):
    # LeftArm points along +x (left); rotating -90 deg about BVH z brings it down (-y).
    m = _retarget(tmp_path, [{"LeftArm": {"Z": -90.0}, "RightArm": {"Z": 90.0}}])
    for s in "rl":
        for name in ("shoulder_flexion", "shoulder_adduction", "shoulder_rotation"):
            assert _deg(m, f"{name}_{s}") == pytest.approx(0.0, abs=1e-6), name


def test_hip_flexion_moves_the_knee_forward(tmp_path):
    # -30 deg about BVH x swings the thigh's distal end towards +z (forward)
    frames = [{}, {"LeftUpLeg": {"X": -30.0}, "RightUpLeg": {"X": -30.0}}]
    path = tmp_path / "hip.bvh"
    path.write_text(_bvh_text(frames))
    bvh = read_bvh(path)
    _, pos = joint_world_frames(bvh)
    knee = bvh.index("LeftLeg")
    assert pos[1, knee, 2] > pos[0, knee, 2] + 20.0  # the knee really moved forward
    m = bvh_to_coordinates(bvh)
    for s in "rl":
        assert _deg(m, f"hip_flexion_{s}", 1) == pytest.approx(30.0, abs=1e-6)
        assert _deg(m, f"hip_adduction_{s}", 1) == pytest.approx(0.0, abs=1e-6)
        assert _deg(m, f"hip_rotation_{s}", 1) == pytest.approx(0.0, abs=1e-6)
        assert _deg(m, f"knee_angle_{s}", 1) == pytest.approx(0.0, abs=1e-6)


def test_knee_flexion_is_negative_and_dorsiflexion_positive(tmp_path):
    # +45 deg about BVH x swings the shank's distal end backwards (knee flexion);
    # -20 deg about BVH x lifts the toes (dorsiflexion)
    m = _retarget(tmp_path, [{"LeftLeg": {"X": 45.0}, "LeftFoot": {"X": -20.0},
                              "RightLeg": {"X": 45.0}, "RightFoot": {"X": 15.0}}])
    assert _deg(m, "knee_angle_l") == pytest.approx(-45.0, abs=1e-6)
    assert _deg(m, "knee_angle_r") == pytest.approx(-45.0, abs=1e-6)
    assert _deg(m, "ankle_angle_l") == pytest.approx(20.0, abs=1e-6)
    assert _deg(m, "ankle_angle_r") == pytest.approx(-15.0, abs=1e-6)
    assert _deg(m, "subtalar_angle_l") == pytest.approx(0.0, abs=1e-6)


def test_hip_adduction_positive_on_both_sides(tmp_path):
    # the left knee moving right (-x) and the right knee moving left (+x) is adduction
    m = _retarget(tmp_path, [{"LeftUpLeg": {"Z": -10.0}, "RightUpLeg": {"Z": 10.0}}])
    assert _deg(m, "hip_adduction_l") == pytest.approx(10.0, abs=1e-6)
    assert _deg(m, "hip_adduction_r") == pytest.approx(10.0, abs=1e-6)
    assert _deg(m, "hip_flexion_l") == pytest.approx(0.0, abs=1e-6)


def test_elbow_flexion_90_degrees_in_t_pose(tmp_path):
    # palms down in a T-pose: elbow flexion swings the forearm forward (+z) in the
    # horizontal plane, i.e. about BVH y: -90 on the left arm (+x), +90 on the right
    m = _retarget(tmp_path, [{"LeftForeArm": {"Y": -90.0}, "RightForeArm": {"Y": 90.0}}])
    for s in "rl":
        assert _deg(m, f"elbow_flexion_{s}") == pytest.approx(90.0, abs=1e-6)
        assert _deg(m, f"pro_sup_{s}") == pytest.approx(0.0, abs=1e-6)
        assert _deg(m, f"shoulder_adduction_{s}") == pytest.approx(-90.0, abs=1e-6)
    # the opposite rotation would hyperextend the elbow: negative
    m = _retarget(tmp_path, [{"LeftForeArm": {"Y": 30.0}}])
    assert _deg(m, "elbow_flexion_l") == pytest.approx(-30.0, abs=1e-6)


def test_pelvis_pose_and_position_in_opensim_convention(tmp_path):
    frames = [{"root_pos": (10.0, 90.0, 50.0)},
              {"root_pos": (10.0, 90.0, 50.0), "Hips": {"Y": 90.0}},
              {"root_pos": (0.0, 90.0, 0.0), "Hips": {"X": 10.0}},
              {"root_pos": (0.0, 90.0, 0.0), "Hips": {"Z": 10.0}}]
    m = _retarget(tmp_path, frames)
    assert m.columns["pelvis_tx"][0] == pytest.approx(0.5)  # BVH z (forward)
    assert m.columns["pelvis_ty"][0] == pytest.approx(0.9)  # BVH y (up)
    assert m.columns["pelvis_tz"][0] == pytest.approx(-0.1)  # BVH +x is left; tz is right
    # turning left (counter-clockwise seen from above) is + pelvis_rotation
    assert _deg(m, "pelvis_rotation", 1) == pytest.approx(90.0, abs=1e-6)
    # +10 about BVH x (our +y, left) tips the pelvis' top forward; the tilt axis is -y
    assert _deg(m, "pelvis_tilt", 2) == pytest.approx(-10.0, abs=1e-6)
    # +10 about BVH z (forward) drops the left side: list about +x is +10
    assert _deg(m, "pelvis_list", 3) == pytest.approx(10.0, abs=1e-6)
    np.testing.assert_allclose(m.time_s, np.arange(4) / 60.0, rtol=1e-6)


def test_segment_directions_reproduce_the_bvh_bones(tmp_path):
    """Forward kinematics with our conventions points every limb along the BVH bone."""
    rng = np.random.default_rng(7)
    frames = []
    for _ in range(20):
        f = {"Hips": dict(zip("ZXY", rng.uniform(-40, 40, 3), strict=True))}
        for j in ("LeftUpLeg", "RightUpLeg", "Chest", "LeftArm", "RightArm", "Spine"):
            f[j] = dict(zip("ZXY", rng.uniform(-35, 35, 3), strict=True))
        for j in ("LeftLeg", "RightLeg"):
            f[j] = {"X": rng.uniform(0, 90)}
        frames.append(f)
    path = tmp_path / "r.bvh"
    path.write_text(_bvh_text(frames))
    bvh = read_bvh(path)
    m = bvh_to_coordinates(bvh)
    _, pos = joint_world_frames(bvh)
    c = basis_matrix()

    def rot(names, axes):
        r = np.broadcast_to(np.eye(3), (20, 3, 3))
        for n, a in zip(names, axes, strict=True):
            r = r @ rotation_matrix(a, m.columns[n])
        return r

    table = {jname: [] for _, jname, _, _, _ in expand(JOINTS_3D)}
    for name, jname, _, axis, _ in expand(JOINTS_3D):
        table[jname].append((name, axis))
    pelvis = rot(["pelvis_tilt", "pelvis_list", "pelvis_rotation"],
                 [(0, -1, 0), (1, 0, 0), (0, 0, 1)])

    def joint(jname):
        return rot([n for n, _ in table[jname]], [a for _, a in table[jname]])

    for s, side in (("l", "Left"), ("r", "Right")):
        thigh = pelvis @ joint(f"hip_{s}")
        shank = thigh @ joint(f"knee_{s}")
        for seg_rot, a, b in ((thigh, "UpLeg", "Leg"), (shank, "Leg", "Foot")):
            bone = (pos[:, bvh.index(side + b)] - pos[:, bvh.index(side + a)]) @ c.T
            bone /= np.linalg.norm(bone, axis=1, keepdims=True)
            np.testing.assert_allclose(seg_rot @ SEGMENT_DIRECTION["thigh"], bone, atol=1e-9)
        torso = pelvis @ joint("chest")
        upper = torso @ joint(f"shoulder_{s}")
        bone = (pos[:, bvh.index(side + "ForeArm")] - pos[:, bvh.index(side + "Arm")]) @ c.T
        bone /= np.linalg.norm(bone, axis=1, keepdims=True)
        np.testing.assert_allclose(upper @ SEGMENT_DIRECTION["upper_arm"], bone, atol=1e-9)


def test_up_and_forward_axes_are_parameters(tmp_path):
    """The same motion written with z up and y forward retargets identically."""
    frames = [{"Hips": {"Y": 20.0, "X": 5.0}, "LeftUpLeg": {"X": -30.0, "Z": 8.0},
               "LeftLeg": {"X": 40.0}, "LeftForeArm": {"Y": -60.0},
               "RightArm": {"Z": 50.0, "Y": 10.0}, "root_pos": (3.0, 92.0, 40.0)}]
    ref = _retarget(tmp_path, frames)
    # z-up, y-forward file: new = M @ old with old x (left) -> -x, old y (up) -> z,
    # old z (forward) -> y. Rotation angles about old x become angles about -x, etc.
    m_ = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    skeleton = [(n, p, tuple(m_ @ o)) for n, p, o in SKELETON]
    end_sites = {k: tuple(m_ @ v) for k, v in END_SITES.items()}
    new_frames = []
    for f in frames:
        g = {"root_pos": tuple(m_ @ f["root_pos"])}
        for j, ang in f.items():
            if j != "root_pos":
                g[j] = {"X": -ang.get("X", 0.0), "Z": ang.get("Y", 0.0), "Y": ang.get("Z", 0.0)}
        new_frames.append(g)
    # channel order must follow the same physical axes: old Z,X,Y -> new Y,X,Z
    other = _retarget(tmp_path, new_frames, name="zup.bvh", order="YXZ", up="z", forward="y",
                      skeleton=skeleton, end_sites=end_sites)
    assert set(other.columns) == set(ref.columns)
    for name in ref.columns:
        np.testing.assert_allclose(other.columns[name], ref.columns[name], atol=1e-9,
                                   err_msg=name)


@pytest.mark.parametrize(("scale", "unit"), [(1.0, 0.01), (0.01, 1.0), (1 / 2.54, 0.0254),
                                             (10.0, 0.001)])
def test_length_unit_is_guessed_from_the_leg(tmp_path, scale, unit):
    m = _retarget(tmp_path, [{"root_pos": (0.0, 95.0, 20.0)}], scale=scale)
    assert m.columns["pelvis_ty"][0] == pytest.approx(0.95, rel=1e-6)
    assert m.columns["pelvis_tx"][0] == pytest.approx(0.20, rel=1e-6)
    explicit = _retarget(tmp_path, [{"root_pos": (0.0, 95.0, 20.0)}], scale=scale,
                         length_unit_m=unit)
    assert explicit.columns["pelvis_ty"][0] == pytest.approx(0.95, rel=1e-6)


def test_missing_segments_leave_their_coordinates_out(tmp_path):
    path = tmp_path / "legs.bvh"
    path.write_text(_bvh_text([{}]))
    bvh = read_bvh(path)
    legs_only = {"Hips": "pelvis", "LeftUpLeg": "thigh_l", "LeftLeg": "shank_l",
                 "LeftFoot": "foot_l"}
    m = bvh_to_coordinates(bvh, name_map=legs_only)
    assert {"hip_flexion_l", "knee_angle_l", "ankle_angle_l", "pelvis_tx"} <= set(m.columns)
    assert not any(k.endswith("_r") for k in m.columns)
    assert "lumbar_extension" not in m.columns and "mtp_angle_l" not in m.columns
    with pytest.raises(InputError, match=r"^legs\.bvh: name_map .*unknown segment"):
        bvh_to_coordinates(bvh, name_map={"Hips": "hips"})
    with pytest.raises(InputError, match=r"^legs\.bvh: name_map names joint 'Nope'"):
        bvh_to_coordinates(bvh, name_map={"Nope": "pelvis"})


def test_prefixed_names_and_extra_joints(tmp_path):
    text = _bvh_text([{"LeftUpLeg": {"X": -30.0}}])
    for name, _, _ in SKELETON:
        text = text.replace(f" {name}\n", f" mixamorig:{name}\n")
    path = tmp_path / "mixamo.bvh"
    path.write_text(text)
    m = bvh_to_coordinates(read_bvh(path))
    assert _deg(m, "hip_flexion_l") == pytest.approx(30.0, abs=1e-6)


def test_arm_raised_above_horizontal_reads_as_abduction_beyond_90(tmp_path):
    # +20 about BVH z lifts the left arm (+x) above the horizontal: 110 deg of abduction,
    # not flexion and rotation of 180 deg
    m = _retarget(tmp_path, [{"LeftArm": {"Z": 20.0}, "RightArm": {"Z": -20.0}}])
    for s in "rl":
        assert _deg(m, f"shoulder_adduction_{s}") == pytest.approx(-110.0, abs=1e-6)
        assert _deg(m, f"shoulder_flexion_{s}") == pytest.approx(0.0, abs=1e-6)
        assert _deg(m, f"shoulder_rotation_{s}") == pytest.approx(0.0, abs=1e-6)


def test_forearm_twist_is_pronation_on_both_sides(tmp_path):
    # palms down in a T-pose; +30 about BVH x turns both palms backwards (pronation)
    m = _retarget(tmp_path, [{"LeftForeArm": {"X": 30.0}, "RightForeArm": {"X": 30.0}}])
    for s in "rl":
        assert _deg(m, f"pro_sup_{s}") == pytest.approx(30.0, abs=1e-6)
        assert _deg(m, f"elbow_flexion_{s}") == pytest.approx(0.0, abs=1e-6)


def test_splayed_rest_legs_like_the_cmu_skeleton(tmp_path):
    """Rest legs tilted 20 deg outwards (feet rigid with them) read as hip abduction;
    the channels that bring them vertical give zero hip adduction and subtalar angle."""
    tilt = np.radians(20.0)
    r = np.array([[np.cos(tilt), -np.sin(tilt), 0.0], [np.sin(tilt), np.cos(tilt), 0.0],
                  [0.0, 0.0, 1.0]])  # +20 deg about BVH z: the left leg swings out (+x)
    mirror = np.diag([-1.0, 1.0, 1.0])
    skeleton = []
    for name, parent, off in SKELETON:
        if name in ("LeftLeg", "LeftFoot", "LeftToeBase"):
            off = tuple(r @ off)
        elif name in ("RightLeg", "RightFoot", "RightToeBase"):
            off = tuple(mirror @ r @ mirror @ off)
        skeleton.append((name, parent, off))
    m = _retarget(tmp_path, [{}, {"LeftUpLeg": {"Z": -20.0}, "RightUpLeg": {"Z": 20.0}}],
                  skeleton=skeleton)
    for s in "rl":
        assert _deg(m, f"hip_adduction_{s}", 0) == pytest.approx(-20.0, abs=1e-6)
        for name in ("hip_adduction", "hip_flexion", "knee_angle", "ankle_angle",
                     "subtalar_angle", "mtp_angle"):
            assert _deg(m, f"{name}_{s}", 1) == pytest.approx(0.0, abs=1e-6), name
        assert _deg(m, f"subtalar_angle_{s}", 0) == pytest.approx(0.0, abs=1e-6)


def test_hinge_angles_prefers_the_solution_inside_the_ranges():
    axes = [(0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
    truth = np.array([[0.1, -1.9, 0.2]])  # adduction beyond -90 deg
    rot = rotation_matrix(axes[0], truth[:, 0]) @ rotation_matrix(axes[1], truth[:, 1]) @ \
        rotation_matrix(axes[2], truth[:, 2])
    ranges = [np.radians(r) for r in ((-60, 180), (-180, 30), (-90, 70))]
    np.testing.assert_allclose(hinge_angles(rot, axes, ranges), truth, atol=1e-9)
    plain = hinge_angles(rot, axes)  # without ranges: the smaller first and third angles
    assert np.abs(plain[0, [0, 2]]).sum() < 0.5


def test_frame_count_that_disagrees_is_a_note(tmp_path):
    path = tmp_path / "cut.bvh"
    path.write_text(GOOD.replace("Frames: 2", "Frames: 207"))
    bvh = read_bvh(path)
    assert bvh.n_frames == 2
    assert bvh.notes == ("cut.bvh: 'Frames: 207' but the file has 2 rows of motion; the rows "
                         "are used",)


def test_poser_collar_shoulder_elbow_names_map_the_arms(tmp_path):
    # Poser / 3ds Max CMU: LeftCollar (clavicle), LeftShoulder (upper arm), LeftElbow, ...
    rename = {"LeftShoulder": "LeftCollar", "LeftArm": "LeftShoulder",
              "LeftForeArm": "LeftElbow", "LeftHand": "LeftWrist",
              "RightShoulder": "RightCollar", "RightArm": "RightShoulder",
              "RightForeArm": "RightElbow", "RightHand": "RightWrist"}
    skeleton = [(rename.get(n, n), rename.get(p, p), o) for n, p, o in SKELETON]
    ends = {rename.get(k, k): v for k, v in END_SITES.items()}
    m = _retarget(tmp_path, [{"LeftShoulder": {"Z": 20.0}, "RightShoulder": {"Z": -20.0}}],
                  skeleton=skeleton, end_sites=ends)
    for s in "rl":
        assert _deg(m, f"shoulder_adduction_{s}") == pytest.approx(-110.0, abs=1e-6)


def test_a_bvh_whose_joints_map_to_nothing_is_an_error(tmp_path):
    names = {n: f"Bone{i}" for i, (n, _, _) in enumerate(SKELETON)}
    skeleton = [(names[n], names.get(p), o) for n, p, o in SKELETON]
    ends = {names[k]: v for k, v in END_SITES.items()}
    path = tmp_path / "bones.bvh"
    frames = [{"root_pos": (0.0, 95.0, 0.0)}, {"root_pos": (0.0, 95.0, 1.0)}]
    text = _bvh_text(frames, skeleton=[(n, p, o) for n, p, o in skeleton], end_sites=ends,
                     root="Bone0")
    path.write_text(text)
    with pytest.raises(InputError) as info:
        bvh_to_coordinates(read_bvh(path))
    assert str(info.value).startswith("bones.bvh: no joint maps to a leg (joints: Bone0, Bone1, "
                                      "Bone2, Bone3, Bone4 and 16 more)")


# ----------------------------------------------------- axes, walking direction, rest pose


def _walk_frames(n=48, dt=1 / 30, heading_deg=0.0, speed_cm_s=120.0):
    """A stylised walk (hips, knees, ankles, a pelvis sway), facing and moving along the
    BVH direction rotated ``heading_deg`` about Y from +Z."""
    turn = Rotation.from_euler("Y", heading_deg, degrees=True)
    frames = []
    for k in range(n):
        t = k * dt
        ph = 2 * np.pi * t / 1.1
        d = speed_cm_s * t
        hips = turn * Rotation.from_euler("ZXY", [0.0, 3.0 + 2.0 * np.sin(2 * ph),
                                                  4.0 * np.sin(ph)], degrees=True)
        z, x, y = hips.as_euler("ZXY", degrees=True)
        frames.append({
            "root_pos": tuple(turn.apply([0.0, 95.0 + 1.5 * np.cos(2 * ph), d])),
            "Hips": {"Z": z, "X": x, "Y": y},
            "LeftUpLeg": {"X": -22.0 * np.sin(ph) - 5.0, "Z": 3.0 * np.cos(ph)},
            "RightUpLeg": {"X": 22.0 * np.sin(ph) - 5.0, "Z": -3.0 * np.cos(ph)},
            "LeftLeg": {"X": 30.0 + 28.0 * np.sin(ph + 2.0)},
            "RightLeg": {"X": 30.0 + 28.0 * np.sin(ph + 2.0 + np.pi)},
            "LeftFoot": {"X": -8.0 * np.sin(ph + 1.0)},
            "RightFoot": {"X": 8.0 * np.sin(ph + 1.0)},
            "Spine": {"X": 4.0 + 2.0 * np.sin(2 * ph)},
        })
    return frames


LEG_NAMES = [f"{j}_{s}" for j in ("hip_flexion", "hip_adduction", "knee_angle", "ankle_angle")
             for s in "rl"]


def test_a_walk_along_minus_x_reads_as_a_heading_of_the_pelvis(tmp_path):
    ahead = _retarget(tmp_path, _walk_frames(), name="z.bvh")
    sideways = _retarget(tmp_path, _walk_frames(heading_deg=-90.0), name="minus_x.bvh")
    assert sideways.notes == ()  # the skeleton faces +z at rest: the usual axes
    for name in [*LEG_NAMES, "pelvis_ty"]:
        np.testing.assert_allclose(sideways.columns[name], ahead.columns[name], atol=1e-9,
                                   err_msg=name)
    # the pelvis is the same but for a heading of -90 deg about the vertical
    from stumble.gait.files import _pelvis_rotation

    r_side = _pelvis_rotation(sideways.columns, 48)
    r_ahead = _pelvis_rotation(ahead.columns, 48)
    np.testing.assert_allclose(r_side, rotation_matrix((0.0, 0.0, 1.0), -np.pi / 2) @ r_ahead,
                               atol=1e-9)
    # 1.2 m/s for 47/30 s: forward in one file, to the right (OpenSim +z) in the other
    assert ahead.columns["pelvis_tx"][-1] == pytest.approx(1.88, abs=0.01)
    assert sideways.columns["pelvis_tz"][-1] == pytest.approx(1.88, abs=0.01)


def test_z_up_files_are_detected(tmp_path):
    m_ = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    skeleton = [(n, p, tuple(m_ @ o)) for n, p, o in SKELETON]
    end_sites = {k: tuple(m_ @ v) for k, v in END_SITES.items()}
    frames = []
    for f in _walk_frames(12):
        g = {"root_pos": tuple(m_ @ f["root_pos"])}
        for j, ang in f.items():
            if j != "root_pos":
                g[j] = {"X": -ang.get("X", 0.0), "Z": ang.get("Y", 0.0), "Y": ang.get("Z", 0.0)}
        frames.append(g)
    ref = _retarget(tmp_path, _walk_frames(12))
    zup = _retarget(tmp_path, frames, name="zup.bvh", order="YXZ", skeleton=skeleton,
                    end_sites=end_sites)
    assert zup.notes == ("zup.bvh: axes read from the skeleton: z up, y forward",)
    for name in LEG_NAMES:
        np.testing.assert_allclose(zup.columns[name], ref.columns[name], atol=1e-9)
    explicit = _retarget(tmp_path, frames, name="zup.bvh", order="YXZ", skeleton=skeleton,
                         end_sites=end_sites, up="z", forward="y")
    assert explicit.notes == ()


def _reoriented_bvh(path, frames, skeleton, end_sites):
    """The motion of ``frames`` written with every joint frame turned so that its first
    child's OFFSET lies along +x: the layout of Bandai-Namco's skeleton, whose zero pose
    (all channels 0) is no upright pose."""
    upright = path.with_name("upright.bvh")
    upright.write_text(_bvh_text(frames, skeleton=skeleton, end_sites=end_sites))
    bvh = read_bvh(upright)
    rot, pos = joint_world_frames(bvh)
    q = []
    for k, j in enumerate(bvh.joints):
        kids = [c for c in bvh.joints if c.parent == k]
        ref = kids[-1].offset if kids else (j.end_sites[0] if j.end_sites else np.array([1.0,
                                                                                         0, 0]))
        if j.name == "Hips":
            ref = bvh.joints[bvh.index("Spine")].offset
        x = ref / np.linalg.norm(ref)
        a = np.cross(x, [0.3, 0.5, 0.8])
        a /= np.linalg.norm(a)
        q.append(np.column_stack([x, a, np.cross(x, a)]))  # q @ [1, 0, 0] = x
    lines = ["HIERARCHY"]
    children = {}
    for k, j in enumerate(bvh.joints):
        children.setdefault(j.parent, []).append(k)

    def emit(k, depth):
        j = bvh.joints[k]
        pad = "  " * depth
        off = j.offset if j.parent < 0 else q[j.parent].T @ j.offset
        lines.append(f"{pad}{'ROOT' if j.parent < 0 else 'JOINT'} {j.name}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {off[0]:.9f} {off[1]:.9f} {off[2]:.9f}")
        pos_ch = "Xposition Yposition Zposition " if j.parent < 0 else ""
        lines.append(f"{pad}  CHANNELS {6 if j.parent < 0 else 3} {pos_ch}Zrotation "
                     "Xrotation Yrotation")
        for c in children.get(k, []):
            emit(c, depth + 1)
        for e in j.end_sites:
            e2 = q[k].T @ e
            lines.extend([f"{pad}  End Site", f"{pad}  {{",
                          f"{pad}    OFFSET {e2[0]:.9f} {e2[1]:.9f} {e2[2]:.9f}", f"{pad}  }}"])
        lines.append(pad + "}")

    emit(0, 0)
    lines += ["MOTION", f"Frames: {bvh.n_frames}", f"Frame Time: {bvh.frame_time_s:.8f}"]
    for f in range(bvh.n_frames):
        vals = list(pos[f, 0])
        for k, j in enumerate(bvh.joints):
            world = rot[f, k] @ q[k]
            local = world if j.parent < 0 else (rot[f, j.parent] @ q[j.parent]).T @ world
            vals += list(Rotation.from_matrix(local).as_euler("ZXY", degrees=True))
        lines.append(" ".join(f"{v:.9f}" for v in vals))
    path.write_text("\n".join(lines) + "\n")
    return upright


def test_a_rest_pose_that_is_not_upright_reads_through_the_motion(tmp_path):
    # a skeleton whose foot bone slopes as ours (FOOT_BONE_SLOPE_DEG), so both readings
    # agree on the neutral ankle
    from stumble.gait.bvh import FOOT_BONE_SLOPE_DEG

    drop = 14.0 * np.tan(np.radians(FOOT_BONE_SLOPE_DEG))
    skeleton = [(n, p, (0.0, -drop, 14.0) if n.endswith("ToeBase") else o)
                for n, p, o in SKELETON]
    frames = _walk_frames(40)
    bandai = tmp_path / "bandai.bvh"
    upright = _reoriented_bvh(bandai, frames, skeleton, END_SITES)
    ref = bvh_to_coordinates(read_bvh(upright))
    got = bvh_to_coordinates(read_bvh(bandai))
    assert any("the rest pose is not upright" in n for n in got.notes)
    for name in [*LEG_NAMES, "pelvis_tilt", "pelvis_list", "pelvis_rotation",
                 "lumbar_extension"]:
        np.testing.assert_allclose(np.degrees(got.columns[name]),
                                   np.degrees(ref.columns[name]), atol=0.05, err_msg=name)


@pytest.mark.parametrize("up, forward", [("q", "auto"), ("-q", "auto"), ("nan", "auto"),
                                         ("y", "w")])
def test_an_unknown_axis_name_gets_one_line(tmp_path, up, forward):
    """``--up``/``--forward`` of one unknown letter: one line naming it (an unknown single
    letter once reached a KeyError)."""
    bad = up if forward == "auto" else forward
    says = rf"BVH (up|forward) axis '{re.escape(bad)}' is not one of"
    with pytest.raises(InputError, match=says):
        _retarget(tmp_path, [{}], up=up, forward=forward)
