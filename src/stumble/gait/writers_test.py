"""Motion files out (stumble.gait.writers): OpenSim .mot and muscles.sto, BVH; read back by
our readers, by an independent BVH reader (bvhio) and by OpenSim itself when installed."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stumble.body import build
from stumble.errors import InputError
from stumble.gait.bvh import bvh_to_coordinates, hinge_angles, read_bvh
from stumble.gait.files import read_motion
from stumble.gait.playback import build_qpos, play
from stumble.gait.readers import read_mot
from stumble.gait.reference import load_reference
from stumble.gait.writers import (
    GAIT10DOF_COORDINATES,
    GAIT2392_COORDINATES,
    opensim_coordinates,
    opensim_muscle_name,
    write_bvh,
    write_mot,
    write_muscles_sto,
)

REFERENCE = Path(__file__).resolve().parents[4] / "shared" / "reference"
GAIT = load_reference()


def _played(planar: bool, duration_s: float = 1.4, height_m: float = 1.75):
    body = build(planar=planar, height_m=height_m)
    t = np.arange(0.0, duration_s, 0.005)
    coords = GAIT.angles(t / GAIT.stride_s + 0.1)
    return body, play(body, t, coords, "test")


@pytest.fixture(scope="module")
def walk3d():
    return _played(False)


@pytest.fixture(scope="module")
def walk_planar():
    return _played(True)


# ------------------------------------------------------------------------- OpenSim


def test_mot_has_gait2392_names_signs_degrees_and_a_valid_header(tmp_path, walk3d):
    body, pb = walk3d
    path = tmp_path / "motion.mot"
    write_mot(path, body, pb.time_s, pb.qpos)
    lines = path.read_text().splitlines()
    names = lines[6].split("\t")
    assert lines[:6] == ["stumble motion (gait2392 coordinates)", "version=1",
                         f"nRows={len(pb.time_s)}", f"nColumns={len(names)}", "inDegrees=yes",
                         "endheader"]
    assert names[:24] == ["time", *GAIT2392_COORDINATES]
    assert len(names) == 1 + len(body.joints) + 6  # every DOF once, pelvis in six
    m = read_mot(path)
    knee = np.degrees(m.columns["knee_angle_r"])
    assert knee.min() < -55.0 and knee.max() < 5.0  # OpenSim: flexion negative
    # pelvis origin of gait2392: 0.0661 m (scaled by hip width) above our hip-joint midpoint,
    # 0.0707 m ahead of it, turned with the pelvis tilt
    tilt = np.radians(np.degrees(m.columns["pelvis_tilt"]))
    s = 0.08511 / 0.0835
    lift = m.columns["pelvis_ty"] - pb.qpos[:, 2]
    np.testing.assert_allclose(lift, s * (0.0661 * np.cos(tilt) + 0.0707 * np.sin(tilt)),
                               atol=2e-3)
    assert m.columns["pelvis_tx"][-1] - m.columns["pelvis_tx"][0] > 1.2  # walks forward


def test_mot_round_trip_keeps_every_coordinate(tmp_path, walk3d):
    body, pb = walk3d
    path = tmp_path / "motion.mot"
    write_mot(path, body, pb.time_s, pb.qpos)
    coords = read_motion(path).columns
    qpos = build_qpos(body, coords, len(pb.time_s))
    m = body.model
    for name in ["pelvis_tilt", *body.joints]:
        adr = m.jnt_qposadr[m.joint(name).id] if name != "pelvis_tilt" else None
        if adr is None:
            continue
        np.testing.assert_allclose(np.degrees(qpos[:, adr]), np.degrees(pb.qpos[:, adr]),
                                   atol=1e-8, err_msg=name)
    # the pelvis orientation (a quaternion inside) comes back to 1e-8 deg too
    rel = Rotation.from_quat(qpos[:, [4, 5, 6, 3]]).inv() * Rotation.from_quat(
        pb.qpos[:, [4, 5, 6, 3]])
    assert np.degrees(rel.magnitude()).max() < 1e-6


def test_planar_mot_uses_gait10dof18musc_names(tmp_path, walk_planar):
    body, pb = walk_planar
    path = tmp_path / "motion.mot"
    write_mot(path, body, pb.time_s, pb.qpos)
    lines = path.read_text().splitlines()
    assert lines[0] == "stumble motion (gait10dof18musc coordinates)"
    assert lines[6].split("\t") == ["time", *GAIT10DOF_COORDINATES]
    back = opensim_coordinates(body, pb.qpos)
    m = read_mot(path)
    for k, v in back.items():
        np.testing.assert_allclose(m.columns[k], v, atol=1e-9, err_msg=k)


def test_writers_refuse_bad_shapes(tmp_path, walk3d):
    body, pb = walk3d
    with pytest.raises(InputError, match=r"^m\.mot: qpos must be"):
        write_mot(tmp_path / "m.mot", body, pb.time_s, pb.qpos[:, :5])
    bad = pb.qpos.copy()
    bad[3, 7] = np.nan
    with pytest.raises(InputError, match=r"^m\.bvh: qpos has NaN"):
        write_bvh(tmp_path / "m.bvh", body, pb.time_s, bad)
    uneven = pb.time_s.copy()
    uneven[5:] += 0.001
    with pytest.raises(InputError, match=r"^m\.bvh: BVH needs uniformly sampled frames"):
        write_bvh(tmp_path / "m.bvh", body, uneven, pb.qpos)


def test_muscles_sto_holds_activation_and_force_per_muscle(tmp_path):
    t = np.linspace(0.0, 0.1, 11)
    names = [opensim_muscle_name(n) for n in ("SOL_r", "HAMS_l")]
    assert names == ["soleus_r", "hamstrings_l"]
    act = np.column_stack([np.linspace(0.01, 1.0, 11), np.full(11, 0.2)])
    force = np.column_stack([np.linspace(0.0, 900.0, 11), np.full(11, 40.0)])
    path = tmp_path / "muscles.sto"
    write_muscles_sto(path, t, names, act, force)
    lines = path.read_text().splitlines()
    assert "inDegrees=no" in lines
    m = read_mot(path)
    assert list(m.columns) == ["/forceset/soleus_r/activation",
                               "/forceset/hamstrings_l/activation",
                               "/forceset/soleus_r|tendon_force",
                               "/forceset/hamstrings_l|tendon_force"]
    np.testing.assert_allclose(m.columns["/forceset/soleus_r/activation"], act[:, 0])
    np.testing.assert_allclose(m.columns["/forceset/soleus_r|tendon_force"], force[:, 0])
    with pytest.raises(InputError, match=r"^muscles\.sto: activation and force must be"):
        write_muscles_sto(path, t, names, act[:, :1], force)


# ----------------------------------------------------------------------------- BVH


LEG_JOINTS = [("Hips", "LeftUpLeg", "hip_l"), ("LeftUpLeg", "LeftLeg", "knee_l"),
              ("LeftLeg", "LeftFoot", "ankle_l"), ("Hips", "RightUpLeg", "hip_r"),
              ("RightUpLeg", "RightLeg", "knee_r"), ("RightLeg", "RightFoot", "ankle_r")]


def _hinges(joint: str):
    from stumble.body.joints import JOINTS_3D, expand

    return [(n, a, r) for n, j, _c, a, r in expand(JOINTS_3D) if j == joint]


def test_bvh_reads_back_with_our_reader(tmp_path, walk3d):
    body, pb = walk3d
    path = tmp_path / "motion.bvh"
    write_bvh(path, body, pb.time_s, pb.qpos)
    text = path.read_text()
    assert text.startswith("HIERARCHY\nROOT Hips\n{\n  OFFSET 0.000000 0.000000 0.000000\n"
                           "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
                           "Yrotation\n")
    bvh = read_bvh(path)
    assert bvh.n_frames == len(pb.time_s) and bvh.frame_time_s == pytest.approx(0.005)
    assert [j.name for j in bvh.joints][:3] == ["Hips", "Spine", "Head"]
    back = bvh_to_coordinates(bvh)
    assert back.notes == ()  # Y up, +Z forward, an upright rest pose: nothing to say
    for name in body.joints:
        np.testing.assert_allclose(np.degrees(back.columns[name]),
                                   np.degrees(pb.coordinates[name]), atol=1e-4, err_msg=name)
    # lengths in cm: the hips at the model's hip height
    assert back.columns["pelvis_ty"].mean() == pytest.approx(pb.qpos[:, 2].mean(), abs=1e-6)


def test_bvh_reads_back_with_bvhio_within_half_a_degree(tmp_path, walk3d):
    bvhio = pytest.importorskip("bvhio")
    body, pb = walk3d
    path = tmp_path / "motion.bvh"
    write_bvh(path, body, pb.time_s, pb.qpos)
    root = bvhio.readAsHierarchy(str(path))
    joints = {j: root.filter(j)[0] for pair in LEG_JOINTS for j in pair[:2]}
    root.loadRestPose()
    rest = {n: _matrix(j.RotationWorld) for n, j in joints.items()}
    to_ours = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # BVH -> ours
    worst = 0.0
    for f in range(0, len(pb.time_s), 7):
        root.loadPose(f)
        world = {n: _matrix(j.RotationWorld) @ rest[n].T for n, j in joints.items()}
        for parent, child, joint in LEG_JOINTS:
            rel = to_ours @ world[parent].T @ world[child] @ to_ours.T
            hinges = _hinges(joint)
            angles = hinge_angles(rel[None], [h[1] for h in hinges],
                                  [tuple(np.radians(h[2])) for h in hinges])[0]
            for (name, _a, _r), value in zip(hinges, angles, strict=True):
                worst = max(worst, abs(np.degrees(value - pb.coordinates[name][f])))
    assert worst < 0.5


def _matrix(q) -> np.ndarray:
    return Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()


def test_planar_bvh_has_the_legs_and_trunk(tmp_path, walk_planar):
    body, pb = walk_planar
    path = tmp_path / "motion.bvh"
    write_bvh(path, body, pb.time_s, pb.qpos)
    bvh = read_bvh(path)
    assert {j.name for j in bvh.joints} == {"Hips", "Spine", "LeftUpLeg", "LeftLeg",
                                            "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot"}
    back = bvh_to_coordinates(bvh)
    for name in body.joints:
        np.testing.assert_allclose(np.degrees(back.columns[name]),
                                   np.degrees(pb.coordinates[name]), atol=1e-4, err_msg=name)
    np.testing.assert_allclose(back.columns["pelvis_tilt"], pb.qpos[:, 2], atol=1e-6)


# ------------------------------------------------------------- OpenSim, installed


MODELS = REFERENCE / "models"


def _osim_foot_heights(osim, model_path: Path, mot: Path) -> np.ndarray:
    """Per frame, the lower foot's height (m): min over calcn and toes origins of each
    foot, the lower foot; and check that every model coordinate is in the file and within
    its range."""
    model = osim.Model(str(model_path))
    state = model.initSystem()
    table = osim.TimeSeriesTable(str(mot))
    labels = list(table.getColumnLabels())
    coords = model.getCoordinateSet()
    deg = table.getTableMetaDataAsString("inDegrees") == "yes"
    columns = {}
    for i in range(coords.getSize()):
        c = coords.get(i)
        assert c.getName() in labels, f"{c.getName()} is not in {mot.name}"
        v = table.getDependentColumn(c.getName()).to_numpy()
        if deg and c.getMotionType() == 1:  # rotational
            v = np.radians(v)
        lo, hi = c.getRangeMin(), c.getRangeMax()
        assert lo - 1e-9 <= v.min() and v.max() <= hi + 1e-9, c.getName()
        columns[c.getName()] = v
    feet = [("calcn_r", "toes_r"), ("calcn_l", "toes_l")]
    bodies = model.getBodySet()
    out = []
    for k in range(table.getNumRows()):
        for name, v in columns.items():
            coords.get(name).setValue(state, float(v[k]), False)
        model.assemble(state)
        model.realizePosition(state)
        lows = [min(bodies.get(b).getPositionInGround(state).get(1) for b in pair)
                for pair in feet]
        out.append(min(lows))
    return np.array(out)


@pytest.mark.parametrize(("planar", "model_file", "real_ik"), [
    (False, "subject01_simbody.osim", "subject01_walk1_ik.mot"),
    (True, "subject01_planar.osim", "subject01_walk_planar_ik.mot"),
])
def test_opensim_accepts_the_motion_and_its_stance_foot_stays_on_the_floor(
        tmp_path, planar, model_file, real_ik):
    osim = pytest.importorskip("opensim")
    if not (MODELS / model_file).exists() or not (REFERENCE / "walking" / real_ik).exists():
        pytest.skip("shared/reference models or walking data are not present")
    # the floor: where the subject's own IK puts the lower foot on this model
    floor = float(np.median(_osim_foot_heights(osim, MODELS / model_file,
                                               REFERENCE / "walking" / real_ik)))
    # a stumble person with the model's legs: hip to sole = hip to calcn + the floor height
    model = osim.Model(str(MODELS / model_file))
    state = model.initSystem()
    leg = (model.getJointSet().get("hip_r").getParentFrame().getPositionInGround(state).get(1)
           - model.getBodySet().get("calcn_r").getPositionInGround(state).get(1) + floor)
    ours_175 = float(build(planar=planar).model.body("pelvis").pos[2])
    body, pb = _played(planar, height_m=1.75 * leg / ours_175)
    mot = tmp_path / "motion.mot"
    write_mot(mot, body, pb.time_s[::4], pb.qpos[::4])
    ours = _osim_foot_heights(osim, MODELS / model_file, mot)
    assert np.abs(ours - floor).max() < 0.03
