"""Joint conventions shared by both human models, the readers and the retargeting.

Frames. World and every segment frame at the zero pose: x forward (walking
direction), y to the body's left, z up. At the zero pose the person stands upright
with arms hanging, palms facing the thighs, feet pointing forward.

Angles follow OpenSim's gait models (gait2392 / subject01), so a ``.mot`` with the
subject01 coordinate names maps one to one: hip flexion +, knee flexion -, ankle
dorsiflexion +, lumbar extension +. Every sagittal angle is a rotation about -y
(OpenSim's +z, which points right), except neck flexion (head forward +, about +y).
Out-of-plane axes are mirrored for the left side, so that adduction, internal
rotation, inversion and pronation are positive on both sides, as in OpenSim.

A joint with several hinges applies them in the order listed (flexion, adduction,
rotation): R = R_1 · R_2 · R_3, the order of OpenSim's CustomJoint, so the first
hinge of every joint is its sagittal pitch.

Ranges of motion are the normal adult values of the American Academy of
Orthopaedic Surgeons (AAOS 1965, *Joint Motion: Method of Measuring and Recording*),
in degrees; where AAOS is silent the choice is stated beside the value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PITCH = (0.0, -1.0, 0.0)  # sagittal flexion/extension axis (OpenSim +z)
ROLL = (1.0, 0.0, 0.0)  # adduction / bending / inversion axis
YAW = (0.0, 0.0, 1.0)  # axial rotation


@dataclass(frozen=True)
class Hinge:
    """One rotational DOF: name (without side suffix), axis for the right side, range."""

    name: str
    axis: tuple[float, float, float]
    range_deg: tuple[float, float]


@dataclass(frozen=True)
class Joint:
    """A joint between ``parent`` and ``child`` segments made of 1-3 hinges."""

    name: str
    parent: str
    child: str
    hinges: tuple[Hinge, ...]
    sided: bool


def mirror_axis(axis: tuple[float, float, float]) -> tuple[float, float, float]:
    """Left-side axis of a right-side rotation axis (reflection through the x-z plane)."""
    return (-axis[0], axis[1], -axis[2])


# 16 joints, 36 internal DOF (SCA 2009 §4.1): chest, neck, shoulders, hips 3 DOF;
# elbows, wrists, knees, ankles 2 DOF; toes 1 DOF.
JOINTS_3D: tuple[Joint, ...] = (
    Joint("chest", "pelvis", "torso", (
        Hinge("lumbar_extension", PITCH, (-80.0, 25.0)),  # AAOS thoracolumbar flex 80, ext 25
        Hinge("lumbar_bending", ROLL, (-35.0, 35.0)),  # AAOS lateral flexion 35
        Hinge("lumbar_rotation", YAW, (-45.0, 45.0)),  # AAOS rotation 45
    ), sided=False),
    Joint("neck", "torso", "head", (
        Hinge("neck_flexion", (0.0, 1.0, 0.0), (-45.0, 45.0)),  # AAOS cervical flex/ext 45
        Hinge("neck_bending", ROLL, (-45.0, 45.0)),  # AAOS lateral flexion 45
        Hinge("neck_rotation", YAW, (-60.0, 60.0)),  # AAOS rotation 60
    ), sided=False),
    Joint("shoulder", "torso", "upper_arm", (
        Hinge("shoulder_flexion", PITCH, (-60.0, 180.0)),  # AAOS ext 60, flex 180
        Hinge("shoulder_adduction", ROLL, (-180.0, 30.0)),  # AAOS abd 180; add 30 (choice:
        # AAOS gives 75 horizontal adduction; in the frontal plane the trunk stops the arm)
        Hinge("shoulder_rotation", YAW, (-90.0, 70.0)),  # AAOS ext rot 90, int rot 70
    ), sided=True),
    Joint("elbow", "upper_arm", "forearm", (
        Hinge("elbow_flexion", PITCH, (0.0, 150.0)),  # AAOS flex 150
        Hinge("pro_sup", YAW, (-80.0, 80.0)),  # AAOS supination 80, pronation 80
    ), sided=True),
    Joint("wrist", "forearm", "hand", (
        Hinge("wrist_flexion", ROLL, (-70.0, 80.0)),  # AAOS ext 70, flex 80 (palm medial)
        Hinge("wrist_deviation", PITCH, (-30.0, 20.0)),  # AAOS ulnar 30, radial 20
    ), sided=True),
    Joint("hip", "pelvis", "thigh", (
        Hinge("hip_flexion", PITCH, (-30.0, 120.0)),  # AAOS ext 30, flex 120
        Hinge("hip_adduction", ROLL, (-45.0, 30.0)),  # AAOS abd 45, add 30
        Hinge("hip_rotation", YAW, (-45.0, 45.0)),  # AAOS ext rot 45, int rot 45
    ), sided=True),
    # The knee's second DOF is axial (internal/external) tibial rotation. The data
    # of subject01 has none, so playback holds it at 0; it is a small, passively
    # stiff DOF that lets the shank twist under the large swing-toe forces of a trip.
    # Range: choice, +-15 deg, a conservative share of the 30-40 deg available with
    # the knee flexed (tibial rotation is near zero at full extension).
    Joint("knee", "thigh", "shank", (
        Hinge("knee_angle", PITCH, (-135.0, 5.0)),  # AAOS flex 135; 5 hyperextension
        Hinge("knee_rotation", YAW, (-15.0, 15.0)),  # choice, see above
    ), sided=True),
    Joint("ankle", "shank", "foot", (
        Hinge("ankle_angle", PITCH, (-50.0, 20.0)),  # AAOS plantarflex 50, dorsiflex 20
        Hinge("subtalar_angle", ROLL, (-15.0, 35.0)),  # AAOS eversion 15, inversion 35
    ), sided=True),
    Joint("toe", "foot", "toes", (
        Hinge("mtp_angle", PITCH, (-45.0, 70.0)),  # AAOS 1st MTP flexion 45, extension 70
    ), sided=True),
)

# Planar model (seed 003 §III): hip, knee and ankle pitch per leg and lumbar extension.
JOINTS_PLANAR: tuple[Joint, ...] = (
    Joint("chest", "pelvis", "torso", (JOINTS_3D[0].hinges[0],), sided=False),
    Joint("hip", "pelvis", "thigh", (JOINTS_3D[5].hinges[0],), sided=True),
    Joint("knee", "thigh", "shank", (JOINTS_3D[6].hinges[0],), sided=True),
    Joint("ankle", "shank", "foot", (JOINTS_3D[7].hinges[0],), sided=True),
)

# Root (pelvis) orientation coordinates, OpenSim order: tilt, list, rotation.
PELVIS_ROTATIONS: tuple[Hinge, ...] = (
    Hinge("pelvis_tilt", PITCH, (-90.0, 90.0)),
    Hinge("pelvis_list", ROLL, (-90.0, 90.0)),
    Hinge("pelvis_rotation", YAW, (-180.0, 180.0)),
)

# Direction of each segment's long axis at the zero pose (from proximal to distal end).
SEGMENT_DIRECTION: dict[str, tuple[float, float, float]] = {
    "pelvis": (0.0, 0.0, 1.0),
    "torso": (0.0, 0.0, 1.0),
    "head": (0.0, 0.0, 1.0),
    "upper_arm": (0.0, 0.0, -1.0),
    "forearm": (0.0, 0.0, -1.0),
    "hand": (0.0, 0.0, -1.0),
    "thigh": (0.0, 0.0, -1.0),
    "shank": (0.0, 0.0, -1.0),
    "foot": (1.0, 0.0, 0.0),
    "toes": (1.0, 0.0, 0.0),
}

SIDES = ("r", "l")


def expand(joints: tuple[Joint, ...]) -> list[tuple[str, str, str, tuple[float, float, float],
                                                  tuple[float, float]]]:
    """Flatten joints to (hinge name, joint name, child segment, axis, range_deg) per side."""
    out = []
    for joint in joints:
        for side in SIDES if joint.sided else ("",):
            child = f"{joint.child}_{side}" if side else joint.child
            jname = f"{joint.name}_{side}" if side else joint.name
            for h in joint.hinges:
                axis = mirror_axis(h.axis) if side == "l" else h.axis
                name = f"{h.name}_{side}" if side else h.name
                out.append((name, jname, child, axis, h.range_deg))
    return out


def hinge_names(planar: bool = False) -> list[str]:
    """Names of the internal DOF in joint-table order (``Body.joints`` has model order)."""
    return [h[0] for h in expand(JOINTS_PLANAR if planar else JOINTS_3D)]


def rotation_matrix(axis: tuple[float, float, float], angle_rad: np.ndarray | float) -> np.ndarray:
    """Rotation matrix (or stack, shape (..., 3, 3)) of ``angle_rad`` about a unit ``axis``."""
    a = np.asarray(axis, dtype=float)
    ang = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(ang)[..., None, None], np.sin(ang)[..., None, None]
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)
