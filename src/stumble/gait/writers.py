"""Motion files out: OpenSim ``.mot``/``.sto`` and BVH from a played or simulated motion.

Every function takes the body and its ``qpos`` trajectory (T, nq) at times ``time_s``
(T,) in s, as in ``Playback`` and ``Recording``:

- :func:`write_mot`: OpenSim coordinates (gait2392 names and signs for the 3D model,
  gait10dof18musc names for the planar one), pelvis translations in m, angles in
  degrees, a version-1 Storage header (:func:`opensim_coordinates`).
- :func:`write_muscles_sto`: activation and force per muscle (OpenSim 4 state and output
  names), e.g. from ``Recording.activation`` and ``Recording.actuator_force``.
- :func:`write_motion_csv`: the pelvis position and every angle in degrees, one row
  per frame, of a playback (``motion.csv``).
- :func:`write_bvh`: a standard hierarchy (root ``Hips``, Y up, +Z forward, X to the
  body's left, lengths in cm, ``Zrotation Xrotation Yrotation`` channels), whose zero
  pose is the model's (upright, arms hanging, feet forward).

The pelvis translations of the ``.mot`` are those of the OpenSim pelvis origin, placed so
that the hip joint centres coincide with ours: gait2392 puts them 0.0707 m behind and
0.0661 m below its pelvis origin, 0.0835 m to each side (gait2392_simbody.osim and
gait10dof18musc.osim, hip_r location in pelvis), scaled here by the ratio of our hip
half-width to 0.0835 m.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from stumble.body import Body
from stumble.body.joints import PELVIS_ROTATIONS, rotation_matrix
from stumble.errors import InputError
from stumble.gait.readers import write_storage

# gait2392_simbody.osim: hip_r in the pelvis frame (x forward, y up, z right), m
OPENSIM_HIP_IN_PELVIS_M = (-0.0707, -0.0661, 0.0835)
GAIT2392_COORDINATES = (
    "pelvis_tilt", "pelvis_list", "pelvis_rotation", "pelvis_tx", "pelvis_ty", "pelvis_tz",
    *(f"{c}_{s}" for s in ("r", "l") for c in ("hip_flexion", "hip_adduction", "hip_rotation",
                                               "knee_angle", "ankle_angle", "subtalar_angle",
                                               "mtp_angle")),
    "lumbar_extension", "lumbar_bending", "lumbar_rotation")
GAIT10DOF_COORDINATES = (
    "pelvis_tilt", "pelvis_tx", "pelvis_ty",
    *(f"{c}_{s}" for s in ("r", "l") for c in ("hip_flexion", "knee_angle", "ankle_angle")),
    "lumbar_extension")
# seed 003 muscles -> gait10dof18musc names (the nearest muscle of that model)
OPENSIM_MUSCLES = {"HAMS": "hamstrings", "GLU": "glut_max", "TA": "tib_ant", "GAS": "gastroc",
                   "RF": "rect_fem", "VAS": "vasti", "SOL": "soleus"}
# BVH: our segment bodies and the names written (the common Mixamo/CMU spelling)
BVH_NAMES = {"pelvis": "Hips", "torso": "Spine", "head": "Head",
             **{f"{seg}_{s}": f"{side}{name}" for s, side in (("l", "Left"), ("r", "Right"))
                for seg, name in (("upper_arm", "Arm"), ("forearm", "ForeArm"),
                                  ("hand", "Hand"), ("thigh", "UpLeg"), ("shank", "Leg"),
                                  ("foot", "Foot"), ("toes", "ToeBase"))}}
BVH_CM_PER_M = 100.0
# our axes (x forward, y left, z up) -> BVH axes (X left, Y up, Z forward)
_TO_BVH = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def opensim_muscle_name(name: str) -> str:
    """``"HAMS_r"`` -> ``"hamstrings_r"`` (gait10dof18musc); other names unchanged."""
    base, _, side = name.rpartition("_")
    return f"{OPENSIM_MUSCLES[base]}_{side}" if base in OPENSIM_MUSCLES else name


def _check(body: Body, time_s: np.ndarray, qpos: np.ndarray, what: str) -> np.ndarray:
    t = np.asarray(time_s, dtype=float)
    q = np.asarray(qpos, dtype=float)
    if t.ndim != 1 or q.shape != (t.size, body.model.nq):
        raise InputError(f"{what}: qpos must be (T, {body.model.nq}) for T = {t.size} times, "
                         f"got {q.shape}")
    if t.size < 2 or not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise InputError(f"{what}: time_s must be at least 2 finite, increasing times")
    if not np.isfinite(q).all():
        raise InputError(f"{what}: qpos has NaN or Inf values")
    return q


def _adr(body: Body, joint: str) -> int:
    return int(body.model.jnt_qposadr[body.model.joint(joint).id])


def opensim_coordinates(body: Body, qpos: np.ndarray) -> dict[str, np.ndarray]:
    """OpenSim coordinates (rad, m; (T,) each) of a qpos trajectory, in file order.

    3D: the gait2392 coordinates, then our other DOF under our names (neck, shoulders,
    elbows, wrists, knee rotation). Planar: the gait10dof18musc coordinates. Signs are
    OpenSim's, which ours follow (``stumble.body.joints``); pelvis_tx/ty/tz are the OpenSim
    pelvis origin in its ground (x forward, y up, z right; see the module docstring).
    """
    q = np.asarray(qpos, dtype=float)
    m = body.model
    scale = float(abs(m.body("thigh_l").pos[1])) / OPENSIM_HIP_IN_PELVIS_M[2]
    offset = scale * np.array([-OPENSIM_HIP_IN_PELVIS_M[0], 0.0, -OPENSIM_HIP_IN_PELVIS_M[1]])
    out: dict[str, np.ndarray] = {}
    if body.planar:
        tilt = q[:, _adr(body, "pelvis_tilt")]
        rot = rotation_matrix(PELVIS_ROTATIONS[0].axis, tilt)
        home = m.body("pelvis").pos  # the slide joints move the pelvis from here
        origin = np.stack([home[0] + q[:, _adr(body, "pelvis_tx")], np.zeros(len(q)),
                           home[2] + q[:, _adr(body, "pelvis_ty")]], axis=1) + rot @ offset
        out["pelvis_tilt"] = tilt
        out["pelvis_tx"], out["pelvis_ty"] = origin[:, 0], origin[:, 2]
        names = GAIT10DOF_COORDINATES
    else:
        from stumble.gait.bvh import hinge_angles

        rot = Rotation.from_quat(q[:, [4, 5, 6, 3]]).as_matrix()  # MuJoCo (w, x, y, z)
        angles = hinge_angles(rot, [h.axis for h in PELVIS_ROTATIONS],
                              [tuple(np.radians(h.range_deg)) for h in PELVIS_ROTATIONS])
        for i, h in enumerate(PELVIS_ROTATIONS):
            out[h.name] = np.unwrap(angles[:, i])
        origin = q[:, :3] + rot @ offset
        out["pelvis_tx"], out["pelvis_ty"], out["pelvis_tz"] = (origin[:, 0], origin[:, 2],
                                                                 -origin[:, 1])
        names = GAIT2392_COORDINATES
    for n in names:
        if n not in out:
            out[n] = q[:, _adr(body, n)]
    for n in body.joints:
        if n not in out:
            out[n] = q[:, _adr(body, n)]
    return out


def write_mot(path: str | Path, body: Body, time_s: np.ndarray, qpos: np.ndarray) -> None:
    """Write ``motion.mot``: the OpenSim coordinates of a motion (degrees, m), one row per
    time in ``time_s`` (s); see :func:`opensim_coordinates`. Raises ``InputError``."""
    q = _check(body, time_s, qpos, Path(path).name)
    coords = opensim_coordinates(body, q)
    model = "gait10dof18musc" if body.planar else "gait2392"
    write_storage(path, time_s, coords,
                  angle_names=[k for k in coords if not k.startswith("pelvis_t")
                               or k == "pelvis_tilt"],
                  title=f"stumble motion ({model} coordinates)")


def write_muscles_sto(path: str | Path, time_s: np.ndarray, names: Sequence[str],
                      activation: np.ndarray, force_n: np.ndarray) -> None:
    """Write ``muscles.sto``: per muscle its activation (0-1) and force (N, + pulling).

    ``names`` (n,) are written as given (see :func:`opensim_muscle_name`), as the OpenSim 4
    columns ``/forceset/<name>/activation`` and ``/forceset/<name>|tendon_force``;
    ``activation`` and ``force_n`` are (T, n) at ``time_s`` (T,) in s; ``inDegrees=no``.
    """
    a, f = np.asarray(activation, dtype=float), np.asarray(force_n, dtype=float)
    t = np.asarray(time_s, dtype=float)
    if a.shape != (t.size, len(names)) or f.shape != a.shape:
        raise InputError(f"{Path(path).name}: activation and force must be (T, {len(names)}) "
                         f"for T = {t.size}, got {a.shape} and {f.shape}")
    cols: dict[str, np.ndarray] = {}
    for i, n in enumerate(names):
        cols[f"/forceset/{n}/activation"] = a[:, i] + 0.0  # + 0.0: no "-0" in the file
    for i, n in enumerate(names):
        cols[f"/forceset/{n}|tendon_force"] = f[:, i] + 0.0
    write_storage(path, t, cols, in_degrees=False, title="stumble muscles")


def _bvh_tree(body: Body) -> list[tuple[int, int, str]]:
    """(body id, parent body id or -1, BVH name) in depth-first order, root first."""
    m = body.model
    ids = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b): b for b in range(1, m.nbody)}
    mapped = {ids[n]: name for n, name in BVH_NAMES.items() if n in ids}
    out: list[tuple[int, int, str]] = []

    def visit(b: int, parent: int) -> None:
        out.append((b, parent, mapped[b]))
        for c in range(1, m.nbody):
            if m.body_parentid[c] == b and c in mapped:
                visit(c, b)

    visit(ids["pelvis"], -1)
    return out


def _end_site(m: mujoco.MjModel, b: int) -> np.ndarray:
    """End Site of a leaf segment (our axes, m): the far end of its geoms along its bone."""
    from stumble.body.joints import SEGMENT_DIRECTION

    seg = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
    base = seg[:-2] if seg.endswith(("_r", "_l")) else seg
    d = np.asarray(SEGMENT_DIRECTION.get(base, (0.0, 0.0, 1.0)), dtype=float)
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == b]
    reach = max((float(m.geom_pos[g] @ d + m.geom_rbound[g]) for g in geoms), default=0.1)
    return d * reach


def write_bvh(path: str | Path, body: Body, time_s: np.ndarray, qpos: np.ndarray) -> None:
    """Write ``motion.bvh`` of a motion sampled uniformly at ``time_s`` (s).

    Root ``Hips`` (the pelvis, at the hip-joint midpoint) with position and rotation
    channels, then ``Spine``, ``Head``, ``Left/RightArm``, ``ForeArm``, ``Hand``,
    ``UpLeg``, ``Leg``, ``Foot``, ``ToeBase`` for the segments the model has; OFFSETs from
    the model in cm; Y up, +Z forward; each joint's rotation is its segment's rotation on
    its parent, as intrinsic Z-X-Y Euler angles in degrees. Raises ``InputError``.
    """
    path = Path(path)
    q = _check(body, time_s, qpos, path.name)
    t = np.asarray(time_s, dtype=float)
    steps = np.diff(t)
    if np.abs(steps - steps.mean()).max() > 1e-6 * steps.mean() + 1e-9:
        raise InputError(f"{path.name}: BVH needs uniformly sampled frames")
    m = body.model
    tree = _bvh_tree(body)
    d = mujoco.MjData(m)
    n = len(q)
    rot = np.zeros((n, m.nbody, 3, 3))
    root_pos = np.zeros((n, 3))
    for k in range(n):
        d.qpos[:] = q[k]
        mujoco.mj_kinematics(m, d)
        rot[k] = d.xmat.reshape(-1, 3, 3)
        root_pos[k] = d.xpos[tree[0][0]]
    channels = []
    for b, parent, _name in tree:
        local = rot[:, b] if parent < 0 else np.swapaxes(rot[:, parent], 1, 2) @ rot[:, b]
        in_bvh = _TO_BVH @ local @ _TO_BVH.T
        zxy = Rotation.from_matrix(in_bvh).as_euler("ZXY", degrees=True)
        zxy = np.unwrap(zxy, period=360.0, axis=0)
        if parent < 0:
            channels.append(root_pos @ _TO_BVH.T * BVH_CM_PER_M)
        channels.append(zxy)
    children = {b: [c for c, p, _ in tree if p == b] for b, _, _ in tree}
    lines = ["HIERARCHY"]

    def emit(b: int, parent: int, name: str, depth: int) -> None:
        pad = "  " * depth
        off = np.zeros(3) if parent < 0 else _TO_BVH @ m.body_pos[b] * BVH_CM_PER_M
        lines.append(f"{pad}{'ROOT' if parent < 0 else 'JOINT'} {name}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}")
        pos = "Xposition Yposition Zposition " if parent < 0 else ""
        lines.append(f"{pad}  CHANNELS {6 if parent < 0 else 3} {pos}"
                     "Zrotation Xrotation Yrotation")
        for c in children[b]:
            emit(c, b, next(nm for cb, _, nm in tree if cb == c), depth + 1)
        if not children[b]:
            e = _TO_BVH @ _end_site(m, b) * BVH_CM_PER_M
            lines.extend([f"{pad}  End Site", f"{pad}  {{",
                          f"{pad}    OFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}", f"{pad}  }}"])
        lines.append(pad + "}")

    emit(*tree[0], 0)
    frame_time = float(steps.mean())
    lines.extend(["MOTION", f"Frames: {n}", f"Frame Time: {frame_time:.8f}"])
    data = np.hstack(channels)
    lines.extend(" ".join(f"{v:.6f}" for v in row) for row in data)
    try:
        path.write_text("\n".join(lines) + "\n")
    except OSError as exc:
        raise InputError(f"{path.name}: cannot write the file ({exc.strerror or exc})") from exc


def _pelvis_angles(pb) -> dict[str, np.ndarray]:
    """Pelvis tilt, list and rotation (rad) from the playback's root orientation."""
    if pb.body.planar:
        return {"pelvis_tilt": pb.qpos[:, 2]}
    quat = pb.qpos[:, [4, 5, 6, 3]]  # scipy wants (x, y, z, w)
    ay, ax, az = Rotation.from_quat(quat).as_euler("YXZ").T  # R = Ry Rx Rz (intrinsic)
    return {"pelvis_tilt": -ay, "pelvis_list": ax, "pelvis_rotation": az}  # tilt is about -y


def write_motion_csv(path: Path, pb) -> None:
    """Write ``motion.csv`` of a played or simulated walk (a ``Playback``, or what
    ``outputs.walk_playback`` makes of a reflex walk): time_s, the pelvis position (m),
    the pelvis and joint angles (deg), one row per frame."""
    root = ["pelvis_tx", "pelvis_ty"] if pb.body.planar else ["pelvis_x", "pelvis_y", "pelvis_z"]
    pos_cols = ["pelvis_x_m", "pelvis_z_m"] if pb.body.planar else [
        "pelvis_x_m", "pelvis_y_m", "pelvis_z_m"]
    pelvis = _pelvis_angles(pb)
    header = ["time_s", *pos_cols, *[f"{k}_deg" for k in pelvis],
              *[f"{j}_deg" for j in pb.body.joints]]
    cols = [pb.time_s, *[pb.qpos[:, i] for i in range(len(root))],
            *[np.degrees(v) for v in pelvis.values()],
            *[np.degrees(pb.coordinates[j]) for j in pb.body.joints]]
    data = np.column_stack(cols)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(np.round(data, 6).tolist())


__all__ = [
    "BVH_NAMES",
    "GAIT10DOF_COORDINATES",
    "GAIT2392_COORDINATES",
    "OPENSIM_MUSCLES",
    "opensim_coordinates",
    "opensim_muscle_name",
    "write_bvh",
    "write_mot",
    "write_motion_csv",
    "write_muscles_sto",
]
