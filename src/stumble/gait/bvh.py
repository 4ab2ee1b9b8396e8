"""Read BioVision Hierarchy (``.bvh``) motion capture and retarget it onto the model.

Reading (:func:`read_bvh`). The HIERARCHY gives a tree of joints, each with an OFFSET
from its parent (file length units) and CHANNELS (any of ``X/Y/Zposition`` and
``X/Y/Zrotation``, in any order); the MOTION section gives ``Frames:``, ``Frame Time:``
(s) and one row of channel values per frame (rotations in degrees). A joint's local
rotation is the product of its rotation channels in the order written (intrinsic):
``Zrotation Xrotation Yrotation`` means ``R = Rz · Rx · Ry``. Position channels replace
the matching OFFSET component (the usual reading for the root).

Retargeting (:func:`bvh_to_coordinates`).

1. Every joint's world rotation and position per frame: ``R_j = R_parent · R_local``.
2. Basis change. The BVH world has an ``up`` and a ``forward`` axis (default ``y`` up,
   ``z`` forward). Our world has x forward, y left, z up, so with the rows of ``C``
   being (forward, up × forward, up) in BVH coordinates, ``v_ours = C · v_bvh``; with
   the defaults our x = BVH z, our y = BVH x, our z = BVH y. ``C`` is a proper rotation,
   so a right-handed BVH stays right-handed. Rotations become ``C · R · Cᵀ``.
3. BVH joints are mapped to model segments by name (:func:`default_segment`); when
   several joints map to one segment the deepest in the tree wins (``Spine2`` over
   ``Spine``, ``LeftUpLeg`` over ``LHipJoint``, ``Head`` over ``Neck``). Without a
   pelvis name the ROOT is the pelvis.
4. Alignment. The BVH rest pose (all channels 0) need not be our zero pose (a T-pose has
   horizontal arms; ours hang). For each segment the rest-pose bone direction ``b`` is
   the vector from its joint to the joint of the next segment down the chain (thigh →
   shank, ..., torso → head), or else to the mean of its children / End Site. ``R_align``
   is the shortest-arc rotation taking ``SEGMENT_DIRECTION`` to ``b``; the segment
   orientation is ``S = C·R_bvh·Cᵀ · R_align``. The pelvis is not aligned (the rest pose is
   taken as an upright, forward-facing pelvis). Hand, foot and toes take their parent's
   ``R_align`` (straight wrists and neutral ankles in the rest pose): their bones do not
   fix their roll, and an ankle sits above the toes in every skeleton. Without the parent
   segment their own bone is used, for foot and toes only its heading.
5. Each model joint's rotation ``S_parentᵀ · S_child`` is split into its hinges (axes of
   ``expand(JOINTS_3D)``, composed ``R1 · R2 · R3``): an exact intrinsic Euler split for
   3 hinges (of its two solutions, the one inside the joint's range of motion), the
   least-squares best angles (max ``trace(Rᵀ·R1·R2)``) for 2, the least-squares angle
   for 1. Angle series are unwrapped over time.
6. The pelvis orientation gives ``pelvis_tilt/list/rotation`` (``PELVIS_ROTATIONS``);
   its position gives ``pelvis_tx`` (forward), ``pelvis_ty`` (up) and ``pelvis_tz``
   (to the RIGHT, OpenSim's convention), in m.
7. Length unit: given, or guessed as the one of ``LENGTH_UNITS_M`` (m, cm, mm, inch,
   CMU's 1/0.45 inch) that brings the rest-pose hip-to-ankle length closest to 0.9 m
   (half the skeleton height when there are no legs); outside 0.45-1.6 m it is an error.

A T-pose gives shoulder adduction -90 deg, which is the gimbal-lock pose of the
flexion-adduction-rotation sequence: there only the sum of flexion and rotation is
defined (as in OpenSim's CustomJoint).
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from stumble.body.joints import (
    JOINTS_3D,
    PELVIS_ROTATIONS,
    SEGMENT_DIRECTION,
    SIDES,
    expand,
    rotation_matrix,
)
from stumble.errors import InputError
from stumble.gait.readers import (
    MAX_STEP_S,
    MIN_STEP_S,
    Motion,
    _clip,
    listed,
    numeric_table,
    read_text,
)

_CHANNEL_NAMES = {c.lower(): c for c in ("Xposition", "Yposition", "Zposition",
                                         "Xrotation", "Yrotation", "Zrotation")}
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}

# Segment aliases, in the normalised form (lower case, letters and digits only).
# Unsided segments.
_UNSIDED_ALIASES: dict[str, tuple[str, ...]] = {
    "pelvis": ("hips", "hip", "pelvis"),
    "torso": ("spine", "spine1", "spine2", "spine3", "spine4", "chest", "chest1", "chest2",
              "upperchest", "lowerback", "upperback", "thorax", "torso", "abdomen",
              "abdomen2"),
    "head": ("neck", "neck1", "neck2", "upperneck", "lowerneck", "head"),
}
# Sided segments: the base is combined with "left"/"l" or "right"/"r" before or after it.
_SIDED_ALIASES: dict[str, tuple[str, ...]] = {
    "thigh": ("upleg", "upperleg", "thigh", "hipjoint", "hip", "femur"),
    "shank": ("leg", "lowerleg", "lowleg", "shin", "calf", "knee", "tibia"),
    "foot": ("foot", "ankle"),
    "toes": ("toebase", "toe", "toes", "toe0", "ball"),
    "upper_arm": ("arm", "upperarm", "uparm", "humerus", "shldr"),
    "forearm": ("forearm", "lowerarm", "lowarm", "elbow", "radius"),
    "hand": ("hand", "wrist"),
}
# Used only when no joint of that side maps to the segment by the names above: Poser's and
# the 3ds Max CMU conversion's LeftCollar / LeftShoulder / LeftElbow, where "Shoulder" is
# the upper arm (in CMU and Mixamo skeletons LeftShoulder is the clavicle, before LeftArm).
_SIDED_FALLBACK: dict[str, tuple[str, ...]] = {"upper_arm": ("shoulder",)}
_SIDE_WORDS = {"l": ("left", "l"), "r": ("right", "r")}
_PREFIX = re.compile(r"^(mixamorig\d*|bip0*1|biped|character\d*|ccbase|skel\d*|def)")
# Next segment down each chain (its joint fixes the rest-pose bone direction).
_DISTAL = {"torso": "head", "upper_arm": "forearm", "forearm": "hand", "thigh": "shank",
           "shank": "foot", "foot": "toes"}
# Segments assumed neutral on their parent in the rest pose (they copy its alignment).
_NEUTRAL_ON = {"hand": "forearm", "foot": "shank", "toes": "foot"}
# Length units to choose from (m per file unit); "cmu" is the CMU database's 1/0.45 inch.
LENGTH_UNITS_M = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "cmu": 0.0254 / 0.45}
_LEG_M = 0.9  # typical hip-to-ankle length of an adult, m


@dataclass(frozen=True, eq=False)
class BvhJoint:
    """One BVH joint.

    ``parent`` is the index of the parent joint (-1 for the ROOT); ``offset`` (3,) is the
    position in the parent frame in file units; ``channels`` are the channel names in
    file order (``"Xrotation"``, ``"Yposition"``, ...), stored in columns
    ``channel_start ...`` of :attr:`Bvh.motion`; ``end_sites`` are End Site offsets.
    """

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple[str, ...]
    channel_start: int
    end_sites: tuple[np.ndarray, ...]


@dataclass(frozen=True, eq=False)
class Bvh:
    """A parsed BVH file: joints in file order (parents first), ``frame_time_s`` (s),
    ``motion`` (F, C) channel values (degrees, file length units), the file name and
    one-line notes on what was repaired while reading."""

    joints: tuple[BvhJoint, ...]
    frame_time_s: float
    motion: np.ndarray
    source: str
    notes: tuple[str, ...] = ()

    @property
    def n_frames(self) -> int:
        """Number of frames F."""
        return int(self.motion.shape[0])

    @property
    def time_s(self) -> np.ndarray:
        """Frame times (F,) in s, starting at 0."""
        return np.arange(self.n_frames) * self.frame_time_s

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (KeyError if absent)."""
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise KeyError(name)


# --------------------------------------------------------------------------- reading


class _Tokens:
    """Tokens of the HIERARCHY section with their 1-based line numbers."""

    def __init__(self, source: str, lines: list[str]):
        self.source = source
        self.items: list[tuple[str, int, bool]] = []  # (text, line, is_name)
        for lineno, line in enumerate(lines, start=1):
            s = line.strip()
            m = re.match(r"(ROOT|JOINT)(?:\s+|$)(.*)$", s, re.IGNORECASE)
            if m:
                rest = m.group(2)
                name, brace, after = rest.partition("{")
                self.items.append((m.group(1).upper(), lineno, False))
                self.items.append((name.strip(), lineno, True))
                s = brace + after
            for tok in re.findall(r"[{}]|[^\s{}]+", s):
                self.items.append((tok, lineno, False))
        self.pos = 0

    def peek(self) -> tuple[str, int, bool] | None:
        return self.items[self.pos] if self.pos < len(self.items) else None

    def next(self, what: str) -> tuple[str, int, bool]:
        item = self.peek()
        if item is None:
            raise InputError(f"{self.source}: the HIERARCHY ends early, expected {what}")
        self.pos += 1
        return item

    def number(self, what: str) -> float:
        text, line, _ = self.next(what)
        try:
            v = float(text)
        except ValueError:
            raise InputError(f"{self.source}: line {line}: {what} {_clip(text)!r} is not a "
                             "number") from None
        if not math.isfinite(v):
            raise InputError(f"{self.source}: line {line}: {what} {text!r} is not finite")
        return v


MAX_DEPTH = 200  # joints nested deeper than this are refused (Python's recursion)


def _parse_hierarchy(source: str, lines: list[str]) -> tuple[list[dict], int]:
    """Joints (dicts, file order) and the total channel count."""
    tk = _Tokens(source, lines)
    first = tk.peek()
    if first is None or first[0].upper() != "HIERARCHY":
        raise InputError(f"{source}: no HIERARCHY section at the start (not a BVH file)")
    tk.next("HIERARCHY")
    root = tk.peek()
    if root is None or root[0] != "ROOT":
        where = f"line {root[1]}: " if root else ""
        raise InputError(f"{source}: {where}expected ROOT after HIERARCHY")
    joints: list[dict] = []
    n_channels = 0

    def parse_joint(parent: int, depth: int = 1) -> None:
        nonlocal n_channels
        _, kw_line, _ = tk.next("ROOT/JOINT")
        if depth > MAX_DEPTH:
            raise InputError(f"{source}: line {kw_line}: joints nested more than "
                             f"{MAX_DEPTH} deep (a skeleton has tens)")
        name, _, _ = tk.next("a joint name")
        if not name:
            raise InputError(f"{source}: line {kw_line}: joint without a name")
        if any(j["name"] == name for j in joints):
            raise InputError(f"{source}: line {kw_line}: joint name {_clip(name)!r} "
                             "appears twice")
        brace, line, _ = tk.next("'{'")
        if brace != "{":
            raise InputError(f"{source}: line {line}: expected '{{' after joint "
                             f"{_clip(name)!r}, found {_clip(brace)!r}")
        me = len(joints)
        joint = {"name": name, "parent": parent, "offset": None, "channels": (),
                 "start": 0, "ends": [], "line": kw_line}
        joints.append(joint)
        while True:
            item = tk.peek()
            if item is None:
                raise InputError(f"{source}: unbalanced braces: joint {_clip(name)!r} "
                                 f"opened on line {kw_line} is never closed")
            tok, line, is_name = item
            key = tok.upper() if not is_name else ""
            if key == "OFFSET":
                tk.next("OFFSET")
                joint["offset"] = np.array([tk.number("OFFSET value") for _ in range(3)])
            elif key == "CHANNELS":
                tk.next("CHANNELS")
                count_text, cline, _ = tk.next("a channel count")
                try:
                    count = int(count_text)
                except ValueError:
                    raise InputError(f"{source}: line {cline}: CHANNELS count "
                                     f"{_clip(count_text)!r} is not an integer") from None
                if not 0 <= count <= 6:
                    raise InputError(f"{source}: line {cline}: CHANNELS count {count} is "
                                     "not between 0 and 6")
                chans = []
                for _ in range(count):
                    ctext, cl, _ = tk.next("a channel name")
                    chan = _CHANNEL_NAMES.get(ctext.lower())
                    if chan is None:
                        raise InputError(f"{source}: line {cl}: unknown channel "
                                         f"{_clip(ctext)!r} (CHANNELS says {count})")
                    if chan in chans:
                        raise InputError(f"{source}: line {cl}: channel {chan} repeated")
                    chans.append(chan)
                joint["channels"] = tuple(chans)
                joint["start"] = n_channels
                n_channels += count
            elif key == "JOINT":
                parse_joint(me, depth + 1)
            elif key == "END":
                tk.next("End")
                site, sline, _ = tk.next("Site")
                if site.upper() != "SITE":
                    raise InputError(f"{source}: line {sline}: expected 'End Site'")
                b, bl, _ = tk.next("'{'")
                if b != "{":
                    raise InputError(f"{source}: line {bl}: expected '{{' after End Site")
                o, ol, _ = tk.next("OFFSET")
                if o.upper() != "OFFSET":
                    raise InputError(f"{source}: line {ol}: expected OFFSET in End Site")
                joint["ends"].append(np.array([tk.number("OFFSET value") for _ in range(3)]))
                c, cl, _ = tk.next("'}'")
                if c != "}":
                    raise InputError(f"{source}: line {cl}: unbalanced braces: expected '}}' "
                                     f"to close the End Site, found {_clip(c)!r}")
            elif tok == "}":
                tk.next("'}'")
                break
            elif tok == "{":
                raise InputError(f"{source}: line {line}: unbalanced braces: unexpected '{{'")
            else:
                raise InputError(f"{source}: line {line}: unexpected {_clip(tok)!r} in joint "
                                 f"{_clip(name)!r}")
        if joint["offset"] is None:
            raise InputError(f"{source}: line {kw_line}: joint {_clip(name)!r} has no OFFSET")

    parse_joint(-1)
    extra = tk.peek()
    if extra is not None:
        tok, line, _ = extra
        if tok == "}":
            raise InputError(f"{source}: line {line}: unbalanced braces: '}}' without '{{'")
        if tok == "ROOT":
            raise InputError(f"{source}: line {line}: a second ROOT (only one is supported)")
        raise InputError(f"{source}: line {line}: unexpected {_clip(tok)!r} after the ROOT "
                         "(expected MOTION)")
    if n_channels == 0:
        raise InputError(f"{source}: the hierarchy has no CHANNELS")
    return joints, n_channels


def read_bvh(path: str | Path) -> Bvh:
    """Parse a BVH file into a :class:`Bvh` (angles in degrees, lengths in file units).

    Raises :class:`InputError` (one line, naming the file) for a file that is missing,
    not regular, too large or empty (:func:`~stumble.gait.readers.read_text`), a missing
    HIERARCHY or MOTION section, unbalanced braces, unknown channels, a row whose value
    count differs from the channel count, non-numeric or non-finite values, no rows, and
    a ``Frame Time`` that is no motion-capture rate (0.1 ms to 1 s). A frame count that
    differs from ``Frames:`` is a note (the rows are used, as a truncated file's should).
    """
    path = Path(path)
    source = path.name
    text = read_text(path)
    lines = text.splitlines()
    notes: list[str] = []
    motion_at = next((i for i, ln in enumerate(lines) if ln.strip().upper() == "MOTION"), None)
    hier_lines = lines if motion_at is None else lines[:motion_at]
    joints, n_channels = _parse_hierarchy(source, hier_lines)
    if motion_at is None:
        raise InputError(f"{source}: no MOTION section after the HIERARCHY")

    # MOTION header
    rest = [(i + 1, ln.strip()) for i, ln in enumerate(lines) if i > motion_at and ln.strip()]
    if not rest:
        raise InputError(f"{source}: the MOTION section is empty (no 'Frames:' line)")
    lineno, s = rest[0]
    m = re.fullmatch(r"Frames\s*:\s*(\S+)", s, re.IGNORECASE)
    if not m:
        raise InputError(f"{source}: line {lineno}: expected 'Frames: <count>'")
    try:
        n_frames = int(m.group(1))
    except ValueError:
        raise InputError(f"{source}: line {lineno}: frame count {_clip(m.group(1))!r} is "
                         "not an integer") from None
    if n_frames < 1:
        raise InputError(f"{source}: line {lineno}: Frames: {n_frames} (at least 1 needed)")
    if len(rest) < 2:
        raise InputError(f"{source}: no 'Frame Time:' line after 'Frames:'")
    lineno, s = rest[1]
    m = re.fullmatch(r"Frame\s*Time\s*:\s*(\S+)", s, re.IGNORECASE)
    if not m:
        raise InputError(f"{source}: line {lineno}: expected 'Frame Time: <seconds>'")
    try:
        dt = float(m.group(1))
    except ValueError:
        raise InputError(f"{source}: line {lineno}: frame time {_clip(m.group(1))!r} is not "
                         "a number") from None
    if not (math.isfinite(dt) and MIN_STEP_S <= dt <= MAX_STEP_S):
        raise InputError(f"{source}: line {lineno}: a frame time of {m.group(1)} s is not a "
                         f"motion-capture rate ({MIN_STEP_S:g} to {MAX_STEP_S:g} s per frame)")

    rows, row_lines = [], []
    for lineno, s in rest[2:]:
        parts = s.split()
        if len(parts) != n_channels:
            raise InputError(f"{source}: line {lineno} has {len(parts)} values, expected "
                             f"{n_channels} (the channels of the hierarchy)")
        rows.append(parts)
        row_lines.append(lineno)
    if not rows:
        raise InputError(f"{source}: 'Frames: {n_frames}' but the file has no rows of motion")
    if len(rows) != n_frames:
        notes.append(f"{source}: 'Frames: {n_frames}' but the file has {len(rows)} rows of "
                     "motion; the rows are used")
    data = numeric_table(source, rows, row_lines, lambda k: f"value {k + 1}").reshape(
        len(rows), n_channels)
    frozen = tuple(
        BvhJoint(name=j["name"], parent=j["parent"], offset=j["offset"],
                 channels=j["channels"], channel_start=j["start"], end_sites=tuple(j["ends"]))
        for j in joints)
    return Bvh(joints=frozen, frame_time_s=dt, motion=data, source=source, notes=tuple(notes))


# ---------------------------------------------------------------------- kinematics


def _axis_rotations(axis: int, angle_rad: np.ndarray) -> np.ndarray:
    """Stack (F, 3, 3) of rotations by ``angle_rad`` (F,) about coordinate ``axis``."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    out = np.zeros((angle_rad.shape[0], 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[:, axis, axis] = 1.0
    out[:, i, i] = c
    out[:, j, j] = c
    out[:, i, j] = -s
    out[:, j, i] = s
    return out


def joint_world_frames(bvh: Bvh) -> tuple[np.ndarray, np.ndarray]:
    """World rotation (F, J, 3, 3) and position (F, J, 3) of every joint, BVH axes and units.

    Rotation channels compose in the order written (intrinsic, degrees); position
    channels replace the matching OFFSET component.
    """
    n_f, n_j = bvh.n_frames, len(bvh.joints)
    rot = np.empty((n_f, n_j, 3, 3))
    pos = np.empty((n_f, n_j, 3))
    for k, joint in enumerate(bvh.joints):
        local = np.broadcast_to(np.eye(3), (n_f, 3, 3)).copy()
        trans = np.broadcast_to(joint.offset, (n_f, 3)).copy()
        for c, chan in enumerate(joint.channels):
            values = bvh.motion[:, joint.channel_start + c]
            axis = _AXIS_INDEX[chan[0].lower()]
            if chan.endswith("rotation"):
                local = local @ _axis_rotations(axis, np.deg2rad(values))
            else:
                trans[:, axis] = values
        if joint.parent < 0:
            rot[:, k] = local
            pos[:, k] = trans
        else:
            p = joint.parent
            rot[:, k] = rot[:, p] @ local
            pos[:, k] = pos[:, p] + np.einsum("fij,fj->fi", rot[:, p], trans)
    return rot, pos


def _rest_positions(bvh: Bvh) -> np.ndarray:
    """Joint positions (J, 3) in the rest pose (all rotations 0), BVH axes and units."""
    out = np.zeros((len(bvh.joints), 3))
    for k, joint in enumerate(bvh.joints):
        out[k] = joint.offset + (out[joint.parent] if joint.parent >= 0 else 0.0)
    return out


def _unit_axis(text: str, what: str) -> np.ndarray:
    """The unit vector (3,) of a signed BVH axis name (``"y"``, ``"-z"``); InputError
    naming ``what`` (up, forward) otherwise."""
    m = re.fullmatch(r"\s*([+-]?)\s*([xyzXYZ])\s*", str(text))
    if not m:
        raise InputError(f"BVH {what} axis {text!r} is not one of x, y, z, -x, -y, -z")
    v = np.zeros(3)
    v[_AXIS_INDEX[m.group(2).lower()]] = -1.0 if m.group(1) == "-" else 1.0
    return v


def basis_matrix(up: str = "y", forward: str = "z") -> np.ndarray:
    """Proper rotation ``C`` (3, 3) with ``v_ours = C · v_bvh``.

    ``up`` and ``forward`` name BVH axes, optionally signed (``"y"``, ``"-z"``); our x is
    forward, z is up and y = z × x is the body's left.
    """
    u, f = _unit_axis(up, "up"), _unit_axis(forward, "forward")
    if abs(float(u @ f)) > 0.5:
        raise InputError(f"BVH up axis {up!r} and forward axis {forward!r} must differ")
    return np.vstack([f, np.cross(u, f), u])


# ------------------------------------------------------------------------ mapping


def _normalise(name: str) -> str:
    last = re.split(r"[:|]", name)[-1]
    return re.sub(r"[^a-z0-9]", "", last.lower())


def _alias_table(fallback: bool = False) -> dict[str, str]:
    table: dict[str, str] = {}
    if not fallback:
        for seg, aliases in _UNSIDED_ALIASES.items():
            for a in aliases:
                table[a] = seg
    for seg, aliases in (_SIDED_FALLBACK if fallback else _SIDED_ALIASES).items():
        for side, words in _SIDE_WORDS.items():
            for a in aliases:
                for w in words:
                    table.setdefault(w + a, f"{seg}_{side}")
                    table.setdefault(a + w, f"{seg}_{side}")
    return table


def default_segment(joint_name: str, fallback: bool = False) -> str | None:
    """Model segment of a BVH joint name under the default map, or None.

    Case, separators and namespaces are ignored (``mixamorig:LeftUpLeg``,
    ``Bip01 L Thigh``, ``thigh_l`` and ``LeftThigh`` all give ``thigh_l``). Recognised:
    Hips/Pelvis; Spine…/Chest/LowerBack/Thorax/Abdomen (torso); Neck/Head; Left/Right (or
    L/R) UpLeg/Thigh/HipJoint/Hip, Leg/Shin/Calf/Knee, Foot/Ankle, ToeBase/Toe,
    Arm/UpperArm/Shldr (DAZ), ForeArm/LowerArm/Elbow, Hand/Wrist. Clavicles
    (``LeftShoulder`` before ``LeftArm``, ``LeftCollar``) are not mapped. With
    ``fallback``, the names used only when a side has no other joint for that segment:
    ``LeftShoulder`` as the upper arm (Poser, 3ds Max CMU: Collar, Shoulder, Elbow).
    """
    table = _alias_table(fallback)
    key = _normalise(joint_name)
    if key in table:
        return table[key]
    stripped = _PREFIX.sub("", key)
    return table.get(stripped) if stripped else None


def model_segments() -> list[str]:
    """Names of the model segments a BVH joint can map to."""
    sided = {j.child for j in JOINTS_3D if j.sided}
    out = []
    for base in SEGMENT_DIRECTION:
        out.extend([f"{base}_{s}" for s in SIDES] if base in sided else [base])
    return out


def _segment_joints(bvh: Bvh, name_map: Mapping[str, str] | None) -> dict[str, int]:
    """Model segment -> BVH joint index (the deepest candidate per segment)."""
    depth = []
    for joint in bvh.joints:
        depth.append(0 if joint.parent < 0 else depth[joint.parent] + 1)
    candidates: dict[str, list[int]] = {}
    if name_map is None:
        for k, joint in enumerate(bvh.joints):
            seg = default_segment(joint.name)
            if seg is not None:
                candidates.setdefault(seg, []).append(k)
        primary = set(candidates)
        for k, joint in enumerate(bvh.joints):
            seg = default_segment(joint.name, fallback=True)
            if seg is not None and seg not in primary:
                candidates.setdefault(seg, []).append(k)
    else:
        valid = set(model_segments())
        names = {j.name: k for k, j in enumerate(bvh.joints)}
        for bvh_name, seg in name_map.items():
            if seg not in valid:
                raise InputError(f"{bvh.source}: name_map sends {_clip(bvh_name)!r} to unknown "
                                 f"segment {_clip(str(seg))!r} (segments: "
                                 f"{', '.join(sorted(valid))})")
            if bvh_name not in names:
                raise InputError(f"{bvh.source}: name_map names joint {_clip(bvh_name)!r}, "
                                 "which is not in the file")
            candidates.setdefault(seg, []).append(names[bvh_name])
    chosen = {seg: max(ks, key=lambda k: (depth[k], -k)) for seg, ks in candidates.items()}
    if "pelvis" not in chosen:
        if 0 in chosen.values():
            raise InputError(f"{bvh.source}: no joint maps to the pelvis and the ROOT "
                             f"{_clip(bvh.joints[0].name)!r} drives another segment; "
                             "pass name_map")
        chosen["pelvis"] = 0
    return chosen


def _is_descendant(bvh: Bvh, k: int, ancestor: int) -> bool:
    while k >= 0:
        k = bvh.joints[k].parent
        if k == ancestor:
            return True
    return False


def _shortest_arc(d: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) of least angle taking unit vector ``d`` to unit vector ``b``."""
    axis = np.cross(d, b)
    s, c = float(np.linalg.norm(axis)), float(d @ b)
    if s < 1e-12:
        if c > 0.0:
            return np.eye(3)
        e = np.eye(3)[int(np.argmin(np.abs(d)))]
        a = np.cross(d, e)
        a /= np.linalg.norm(a)
        return 2.0 * np.outer(a, a) - np.eye(3)
    return rotation_matrix(tuple(axis / s), math.atan2(s, c))


def _bone_vector(bvh: Bvh, k: int, distal: int | None, rest: np.ndarray) -> np.ndarray | None:
    """Rest-pose bone of joint ``k`` (BVH axes): to ``distal`` when it is a descendant, else
    to the mean of the nearest generation of children / End Sites not at the joint itself."""
    if distal is not None and _is_descendant(bvh, distal, k):
        vec = rest[distal] - rest[k]
        if np.linalg.norm(vec) > 1e-9:
            return vec
    frontier = [k]
    for _ in range(4):
        kids = [i for i, j in enumerate(bvh.joints) if j.parent in frontier]
        points = [rest[i] for i in kids]
        points += [rest[f] + e for f in frontier for e in bvh.joints[f].end_sites]
        if not points:
            return None
        vec = np.mean(points, axis=0) - rest[k]
        if np.linalg.norm(vec) > 1e-9:
            return vec
        frontier = kids
    return None


def _alignments(bvh: Bvh, segs: dict[str, int], rest: np.ndarray,
                c: np.ndarray) -> dict[str, np.ndarray]:
    """``R_align`` (3, 3) of every mapped segment (see the module docstring, step 4).

    Hand, foot and toes are taken to be neutral on their parent segment in the rest pose
    (they share its alignment) when the parent is mapped: their bones (to the fingers, the
    toes) do not fix their roll, and every common rest pose (T-pose, A-pose, the CMU
    skeleton with its splayed legs) has straight wrists and neutral ankles. Without the
    parent, the bone is used, and for foot and toes only its heading.
    """
    out: dict[str, np.ndarray] = {}
    for base in SEGMENT_DIRECTION:  # proximal segments first
        for side in (*SIDES, ""):
            seg = f"{base}_{side}" if side else base
            if seg not in segs:
                continue
            if base == "pelvis":
                out[seg] = np.eye(3)
                continue
            parent = _NEUTRAL_ON.get(base)
            parent_seg = None if parent is None else f"{parent}_{side}"
            if parent_seg in out:
                out[seg] = out[parent_seg]
                continue
            distal = _DISTAL.get(base)
            distal_seg = None if distal is None else (f"{distal}_{side}" if side else distal)
            vec = _bone_vector(bvh, segs[seg], segs.get(distal_seg), rest)
            if vec is None:
                out[seg] = np.eye(3)
                continue
            b = c @ vec
            d = np.asarray(SEGMENT_DIRECTION[base], dtype=float)
            if abs(d[2]) < 1e-9:  # nominally horizontal segment: keep only the heading
                flat = np.array([b[0], b[1], 0.0])
                if np.linalg.norm(flat) > 0.2 * np.linalg.norm(b):
                    b = flat
            out[seg] = _shortest_arc(d, b / np.linalg.norm(b))
    return out


# ------------------------------------------------------------------ decomposition


def _best_angle(m: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Angle (F,) about ``axis`` maximising trace(R(axis, θ)ᵀ · M) for a stack M (F, 3, 3)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    p = -np.einsum("ij,fji->f", k, m)
    q = np.einsum("ij,fji->f", k @ k, m)
    return np.arctan2(p, -q)


def _basis_signs(axes: list[np.ndarray]) -> tuple[str, np.ndarray] | None:
    """Euler sequence letters and signs when every axis is ± a distinct coordinate axis."""
    letters, signs = "", []
    for a in axes:
        i = int(np.argmax(np.abs(a)))
        if abs(abs(a[i]) - 1.0) > 1e-9 or np.count_nonzero(np.abs(a) > 1e-9) != 1:
            return None
        letters += "XYZ"[i]
        signs.append(float(np.sign(a[i])))
    if len(set(letters)) != len(letters):
        return None
    return letters, np.array(signs)


def hinge_angles(rot: np.ndarray, axes: list[tuple[float, float, float]],
                 ranges_rad: list[tuple[float, float]] | None = None) -> np.ndarray:
    """Hinge angles (F, n) in rad with ``R1(θ1)·…·Rn(θn) ≈ rot`` (F, 3, 3) for 1-3 hinges.

    Three hinges: exact intrinsic Euler split (axes must be ± distinct coordinate axes).
    Of its two solutions, (θ1, θ2, θ3) and (θ1+π, π-θ2, θ3+π), the one that leaves
    ``ranges_rad`` (lo, hi per hinge) least is taken, then the one with the smaller
    angles; so a shoulder abducted past 90 deg reads as adduction < -90 deg rather than
    as flexion and rotation of 180 deg. One or two hinges: the angles that maximise
    ``trace(rotᵀ · R1 · R2)`` (least squares in the Frobenius norm), found by
    alternating exact one-angle maximisations from an Euler start.
    """
    ax = [np.asarray(a, dtype=float) / np.linalg.norm(a) for a in axes]
    rot = np.asarray(rot, dtype=float)
    n = len(ax)
    if n == 1:
        return _best_angle(rot, ax[0])[:, None]
    if n == 2:
        seq = _basis_signs(ax)
        if seq is not None:
            third = ({"X", "Y", "Z"} - set(seq[0])).pop()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                e = Rotation.from_matrix(rot).as_euler(seq[0] + third)
            t1, t2 = e[:, 0] * seq[1][0], e[:, 1] * seq[1][1]
        else:
            t1 = t2 = np.zeros(rot.shape[0])
        for _ in range(12):
            t1 = _best_angle(rot @ np.swapaxes(rotation_matrix(tuple(ax[1]), t2), -1, -2), ax[0])
            t2 = _best_angle(np.swapaxes(rotation_matrix(tuple(ax[0]), t1), -1, -2) @ rot, ax[1])
        return np.stack([t1, t2], axis=1)
    if n == 3:
        seq = _basis_signs(ax)
        if seq is None:
            raise ValueError("3-hinge split needs axes that are ± distinct coordinate axes")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # gimbal lock (e.g. T-pose arms)
            first = Rotation.from_matrix(rot).as_euler(seq[0]) * seq[1]
        other = first + np.array([np.pi, 0.0, np.pi])
        other[:, 1] = np.pi - first[:, 1]
        other = (other + np.pi) % (2.0 * np.pi) - np.pi
        if other.size:
            other[other <= -np.pi] += 2.0 * np.pi

        def cost(theta: np.ndarray) -> np.ndarray:
            out = 1e-3 * np.abs(theta).sum(axis=1)
            if ranges_rad is not None:
                lo = np.array([r[0] for r in ranges_rad])
                hi = np.array([r[1] for r in ranges_rad])
                out = out + (np.maximum(lo - theta, 0.0) + np.maximum(theta - hi, 0.0)).sum(axis=1)
            return out

        pick = cost(other) < cost(first)
        return np.where(pick[:, None], other, first)
    raise ValueError(f"a joint has 1-3 hinges, not {n}")


# ---------------------------------------------------------------------- retarget


def _guess_unit(bvh: Bvh, segs: dict[str, int], rest: np.ndarray, c: np.ndarray) -> float:
    def length(a: str, b: str) -> float:
        return float(np.linalg.norm(rest[segs[b]] - rest[segs[a]]))

    # thigh + shank bone lengths: right whatever the rest pose folds
    legs = [length(f"thigh_{s}", f"shank_{s}") + length(f"shank_{s}", f"foot_{s}")
            for s in SIDES if all(f"{g}_{s}" in segs for g in ("thigh", "shank", "foot"))]
    legs += [length(f"thigh_{s}", f"foot_{s}") for s in SIDES
             if f"foot_{s}" in segs and f"thigh_{s}" in segs and f"shank_{s}" not in segs]
    if legs and max(legs) > 0.0:
        leg, how = max(legs), "leg length"
    else:
        points = [rest]
        points += [rest[k] + e for k, j in enumerate(bvh.joints) for e in j.end_sites]
        up = (np.vstack(points) @ c.T)[:, 2]
        leg, how = 0.5 * float(up.max() - up.min()), "half the skeleton height"
    if leg <= 0.0:
        raise InputError(f"{bvh.source}: cannot guess the length unit (the skeleton has no "
                         "height); pass length_unit_m")
    best = min(LENGTH_UNITS_M.values(), key=lambda u: abs(math.log(leg * u / _LEG_M)))
    if not 0.45 <= leg * best <= 1.6:
        raise InputError(f"{bvh.source}: cannot guess the length unit ({how} {leg:g} file "
                         "units fits none of m, cm, mm, in); pass length_unit_m")
    return best


# Model parent of each segment (the chain the alignment follows) and the chain's name.
_PARENT_SEGMENT = {"torso": "pelvis", "head": "torso", "upper_arm": "torso",
                   "forearm": "upper_arm", "hand": "forearm", "thigh": "pelvis",
                   "shank": "thigh", "foot": "shank", "toes": "foot"}
_CHAIN = {"torso": "spine", "head": "spine", "upper_arm": "arm", "forearm": "arm",
          "hand": "arm", "thigh": "leg", "shank": "leg", "foot": "leg", "toes": "leg"}
UPRIGHT_TOLERANCE_DEG = 60.0  # rest-pose legs and spine this close to vertical: upright
# At a neutral ankle our foot's bone (ankle to MTP joint) slopes down this much from the
# sole's forward axis (stumble.body.build, de Leva proportions: 0.135 m ahead, 0.044 m down)
FOOT_BONE_SLOPE_DEG = 18.2


def _split(seg: str) -> tuple[str, str]:
    """``"upper_arm_l"`` -> ``("upper_arm", "l")``; ``"torso"`` -> ``("torso", "")``."""
    return (seg[:-2], seg[-1]) if seg.endswith(("_r", "_l")) else (seg, "")


def _seg_name(base: str, side: str) -> str:
    return f"{base}_{side}" if side and base not in ("pelvis", "torso", "head") else base


def _parent_seg(seg: str) -> str:
    base, side = _split(seg)
    return _seg_name(_PARENT_SEGMENT[base], side)


def _distal_seg(seg: str) -> str | None:
    base, side = _split(seg)
    d = _DISTAL.get(base)
    return None if d is None else _seg_name(d, side)


def _bone_world(bvh: Bvh, segs: dict[str, int], seg: str, rot: np.ndarray,
                pos: np.ndarray) -> np.ndarray | None:
    """World bone of a segment (F, 3), BVH axes: to its distal segment's joint, else to the
    mean of its children and End Sites."""
    k = segs[seg]
    distal = _distal_seg(seg)
    if distal in segs and _is_descendant(bvh, segs[distal], k):
        return pos[:, segs[distal]] - pos[:, k]
    kids = [i for i, j in enumerate(bvh.joints) if j.parent == k]
    points = [pos[:, i] for i in kids]
    points += [pos[:, k] + rot[:, k] @ e for e in bvh.joints[k].end_sites]
    if not points:
        return None
    vec = np.mean(points, axis=0) - pos[:, k]
    return vec if np.linalg.norm(vec, axis=1).max() > 1e-9 else None


def _nearest_axis(vec: np.ndarray, exclude: int | None = None) -> tuple[str, float]:
    """The signed axis name ("y", "-z") nearest to ``vec`` (BVH axes) and its cosine."""
    v = np.array(vec, dtype=float)
    if exclude is not None:
        v[exclude] = 0.0
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        return "", 0.0
    i = int(np.argmax(np.abs(v)))
    return ("-" if v[i] < 0 else "") + "xyz"[i], abs(float(v[i])) / n


def detect_axes(bvh: Bvh, segs: dict[str, int], pos: np.ndarray,
                up: str | None = None) -> tuple[str, str, str]:
    """BVH ``up`` and ``forward`` axes read from the motion: ``(up, forward, how)``.

    Up: the mean direction from the feet (toes, feet or shanks) to the head (or torso,
    or pelvis) over all frames of ``pos`` (F, J, 3), snapped to the nearest signed axis.
    Forward: the body's facing, left × up with left the mean vector from the right to the
    left hip (or shoulder, or foot), snapped to the nearest axis across ``up``; without
    sided joints, the root's path. ``bvh_to_coordinates`` reads forward from the rest
    pose when that is upright (the alignment is relative to it; a walk along -x is then a
    heading of the pelvis), else from the motion. What cannot be read falls back to Y up
    and +Z forward (the common BVH convention), which ``how`` says. A given ``up`` is
    kept and only forward read.
    """
    def mean_pos(names: list[str]) -> np.ndarray | None:
        ks = [segs[n] for n in names if n in segs]
        return None if not ks else pos[:, ks].mean(axis=1)

    low = next((p for p in (mean_pos([f"toes_{s}" for s in SIDES] + [f"foot_{s}" for s in SIDES]),
                            mean_pos([f"shank_{s}" for s in SIDES])) if p is not None), None)
    high = next((p for p in (mean_pos(["head"]), mean_pos(["torso"]), mean_pos(["pelvis"]))
                 if p is not None), None)
    how = []
    if up is None:
        cos_up = 0.0
        if low is not None and high is not None:
            up, cos_up = _nearest_axis((high - low).mean(axis=0))
        if cos_up < 0.7:
            up = "y"
            how.append("up not readable from the skeleton: Y assumed")
    basis_matrix(up, "x" if up.lstrip("+-").lower() != "x" else "y")  # checks the name
    up = up.strip().lower().lstrip("+")
    ui = "xyz".index(up[-1])
    u = np.zeros(3)
    u[ui] = -1.0 if up.startswith("-") else 1.0
    left = None
    for a in ("thigh", "upper_arm", "foot"):
        pl, pr = mean_pos([f"{a}_l"]), mean_pos([f"{a}_r"])
        if pl is not None and pr is not None:
            left = (pl - pr).mean(axis=0)
            break
    forward, cos_f = ("", 0.0)
    if left is not None:
        forward, cos_f = _nearest_axis(np.cross(left, u), exclude=ui)
    if cos_f < 0.5:
        root = pos[:, 0]
        forward, cos_f = _nearest_axis(root[-1] - root[0], exclude=ui)
    if cos_f < 0.5:
        forward = {"y": "z", "-y": "z", "z": "x", "-z": "x", "x": "z", "-x": "z"}[up]
        how.append(f"facing not readable: {forward} forward assumed")
    return up, forward, "; ".join(how)


def _rest_is_upright(bvh: Bvh, segs: dict[str, int], rest: np.ndarray, c: np.ndarray) -> bool:
    """Whether the rest pose (all rotations 0) has vertical legs and spine (within
    ``UPRIGHT_TOLERANCE_DEG``): the usual T- or A-pose. Bandai-Namco's skeleton, whose
    bones rest along ±x, is not."""
    cos_tol = math.cos(math.radians(UPRIGHT_TOLERANCE_DEG))
    for seg, want in [*((f"{b}_{s}", -1.0) for b in ("thigh", "shank") for s in SIDES),
                      ("torso", 1.0)]:
        if seg not in segs:
            continue
        distal = _distal_seg(seg)
        vec = _bone_vector(bvh, segs[seg], segs.get(distal), rest)
        if vec is None:
            continue
        b = c @ vec
        if want * b[2] < cos_tol * np.linalg.norm(b):
            return False
    return True


def _alignments_from_motion(bvh: Bvh, segs: dict[str, int], rot: np.ndarray,
                            pos: np.ndarray, c: np.ndarray) -> dict[str, np.ndarray]:
    """``R_align`` of every mapped segment of a skeleton whose rest pose is not upright.

    The pelvis frame is fixed in the Hips joint's own frame by its bones: left from the
    right to the left hip joint, up toward the spine (or, without one, the mean world up),
    both averaged over the motion. Every other segment is aligned at one reference frame
    of its chain (leg, arm, spine: the frame where that chain's bones are closest to
    vertical): there its frame is its parent's, turned by the least rotation onto its
    bone, so its joint has no axial twist at that instant (our choice). The foot's bone
    (ankle to toe joint) is taken to slope down ``FOOT_BONE_SLOPE_DEG`` at a neutral
    ankle, as ours does. After that the BVH rotations carry every change, twists
    included.
    """
    cc = c.T
    out: dict[str, np.ndarray] = {}
    k0 = segs["pelvis"]
    rp = rot[:, k0]
    left = None
    for a in ("thigh", "upper_arm"):
        if f"{a}_l" in segs and f"{a}_r" in segs:
            w = pos[:, segs[f"{a}_l"]] - pos[:, segs[f"{a}_r"]]
            left = c @ np.einsum("fji,fj->i", rp, w) / len(w)
            break
    if "torso" in segs:  # the pelvis's own child on the way to the torso: a fixed OFFSET
        k = segs["torso"]
        while bvh.joints[k].parent not in (k0, -1):
            k = bvh.joints[k].parent
        w = pos[:, segs["torso"]] - pos[:, k0]
        upv = c @ bvh.joints[k].offset if np.linalg.norm(bvh.joints[k].offset) > 1e-9 else (
            c @ np.einsum("fji,fj->i", rp, w) / len(w))
    else:
        upv = c @ np.einsum("fji,j->i", rp, cc @ np.array([0.0, 0.0, 1.0])) / len(rp)
    if left is None or np.linalg.norm(left) < 1e-9:
        left = np.cross(upv, c @ np.einsum("fji,j->i", rp, cc @ np.array([1.0, 0.0, 0.0])))
    y = left / np.linalg.norm(left)
    z = upv - (upv @ y) * y
    z /= np.linalg.norm(z)
    out["pelvis"] = np.column_stack([np.cross(y, z), y, z])

    bones = {seg: _bone_world(bvh, segs, seg, rot, pos) for seg in segs if seg != "pelvis"}
    bones = {k: (v @ c.T) for k, v in bones.items() if v is not None}
    ref: dict[tuple[str, str], int] = {}
    for chain in ("leg", "arm", "spine"):
        for side in (*SIDES, ""):
            cost = np.zeros(len(rot))
            used = False
            for seg, b in bones.items():
                base, sd = _split(seg)
                if _CHAIN.get(base) != chain or sd != side or base in _NEUTRAL_ON:
                    continue
                want = np.asarray(SEGMENT_DIRECTION[base])
                cosang = (b @ want) / np.maximum(np.linalg.norm(b, axis=1), 1e-12)
                cost += np.arccos(np.clip(cosang, -1.0, 1.0))
                used = True
            if used:
                ref[(chain, side)] = int(np.argmin(cost))

    world = {seg: c @ rot[:, k] @ cc for seg, k in segs.items()}
    for base in SEGMENT_DIRECTION:  # proximal segments first
        for side in (*SIDES, ""):
            seg = _seg_name(base, side)
            if base == "pelvis" or seg not in segs or seg in out or (side == "") != (
                    base in ("torso", "head")):
                continue
            parent = _parent_seg(seg)
            while parent not in out and parent != "pelvis":
                parent = _parent_seg(parent)
            f = ref.get((_CHAIN[base], side), 0)
            s_parent = world[parent][f] @ out[parent]
            if seg not in bones:
                target = s_parent
            else:
                b = bones[seg][f] / np.linalg.norm(bones[seg][f])
                neutral = np.asarray(SEGMENT_DIRECTION[base], dtype=float)
                if base == "foot":
                    a = math.radians(FOOT_BONE_SLOPE_DEG)
                    neutral = np.array([math.cos(a), 0.0, -math.sin(a)])
                target = _shortest_arc(s_parent @ neutral, b) @ s_parent
            out[seg] = world[seg][f].T @ target
    return out


def bvh_to_coordinates(bvh: Bvh, name_map: Mapping[str, str] | None = None, up: str = "auto",
                       forward: str = "auto", length_unit_m: float | None = None) -> Motion:
    """Retarget a BVH motion onto the model's coordinates (see the module docstring).

    ``name_map`` maps BVH joint names to model segments (``"thigh_l"``, ``"torso"``, ...;
    see :func:`model_segments`) and replaces the default name recognition
    (:func:`default_segment`). ``up``/``forward`` name the BVH world axes (``"y"``,
    ``"-z"``, ...); ``"auto"`` reads them from the motion (:func:`detect_axes`). The
    length unit (m per file unit) is guessed when None: the one of ``LENGTH_UNITS_M`` that
    brings the hip-to-ankle length closest to 0.9 m. A rest pose that is not upright
    (:func:`_rest_is_upright`) is read through the motion instead
    (:func:`_alignments_from_motion`). Returns a :class:`Motion` with angles in rad,
    ``pelvis_tx/ty/tz`` in m (tx forward, ty up, tz right) and notes; joints whose parent
    or child segment is missing from the BVH are left out. A file whose joints drive no
    hip, knee or ankle is an :class:`InputError`.
    """
    if length_unit_m is not None and not (math.isfinite(length_unit_m) and length_unit_m > 0):
        raise InputError(f"{bvh.source}: length_unit_m must be positive, got {length_unit_m}")
    segs = _segment_joints(bvh, name_map)
    legs = sorted(s for s in segs if _split(s)[0] in ("thigh", "shank", "foot"))
    if not legs:
        names = [j.name for j in bvh.joints]
        raise InputError(f"{bvh.source}: no joint maps to a leg (joints: {listed(names)}); "
                         "the names understood are those of stumble.gait.bvh.default_segment, "
                         "or pass name_map")
    notes = list(bvh.notes)
    rot_b, pos_b = joint_world_frames(bvh)
    rest = _rest_positions(bvh)
    given = (up, forward)
    how = ""
    if up == "auto":
        up, _, how = detect_axes(bvh, segs, pos_b)
    _unit_axis(up, "up")  # a bad name is refused here, before it picks the side axis
    if forward != "auto":
        _unit_axis(forward, "forward")
    side = {"x": "y", "y": "z", "z": "x"}[up.strip().lstrip("+-").lower()[-1:]]
    upright = _rest_is_upright(bvh, segs, rest, basis_matrix(up, side))
    if forward == "auto":  # the facing of the rest pose the alignment reads, else the motion's
        _, forward, how_f = detect_axes(bvh, segs, rest[None] if upright else pos_b, up)
        how = "; ".join(h for h in (how, how_f) if h)
    if given != (up, forward) and (up, forward) != ("y", "z"):
        notes.append(f"{bvh.source}: axes read from the skeleton: {up} up, {forward} forward"
                     + (f" ({how})" if how else ""))
    elif how:
        notes.append(f"{bvh.source}: {how}")
    c = basis_matrix(up, forward)
    unit = _guess_unit(bvh, segs, rest, c) if length_unit_m is None else float(length_unit_m)

    if _rest_is_upright(bvh, segs, rest, c):
        aligns = _alignments(bvh, segs, rest, c)
    else:
        aligns = _alignments_from_motion(bvh, segs, rot_b, pos_b, c)
        notes.append(f"{bvh.source}: the rest pose is not upright (bones at rest point away "
                     "from vertical); segments aligned on the motion instead")
    frames = {seg: c @ rot_b[:, k] @ c.T @ aligns[seg] for seg, k in segs.items()}

    columns: dict[str, np.ndarray] = {}
    pelvis = frames["pelvis"]
    angles = hinge_angles(pelvis, [h.axis for h in PELVIS_ROTATIONS],
                          [tuple(np.radians(h.range_deg)) for h in PELVIS_ROTATIONS])
    for i, h in enumerate(PELVIS_ROTATIONS):
        columns[h.name] = np.unwrap(angles[:, i])
    p = pos_b[:, segs["pelvis"]] @ c.T * unit
    columns["pelvis_tx"], columns["pelvis_ty"], columns["pelvis_tz"] = p[:, 0], p[:, 2], -p[:, 1]

    parent_of: dict[str, str] = {}
    sided = {j.child for j in JOINTS_3D if j.sided}
    for joint in JOINTS_3D:
        for side in SIDES if joint.sided else ("",):
            jname = f"{joint.name}_{side}" if side else joint.name
            parent = joint.parent
            parent_of[jname] = f"{parent}_{side}" if side and parent in sided else parent
    groups: dict[str, list[tuple[str, str, tuple[float, float, float], tuple]]] = {}
    for name, jname, child, axis, range_deg in expand(JOINTS_3D):
        groups.setdefault(jname, []).append((name, child, axis, tuple(np.radians(range_deg))))
    for jname, hinges in groups.items():
        parent, child = parent_of[jname], hinges[0][1]
        if parent not in frames or child not in frames:
            continue
        rel = np.swapaxes(frames[parent], -1, -2) @ frames[child]
        angles = hinge_angles(rel, [h[2] for h in hinges], [h[3] for h in hinges])
        for i, (name, *_) in enumerate(hinges):
            columns[name] = np.unwrap(angles[:, i])
    if not any(n.split("_")[0] in ("hip", "knee", "ankle") for n in columns):
        raise InputError(f"{bvh.source}: its joints ({listed(sorted(segs))}) drive no hip, "
                         "knee or ankle of the model; pass name_map")
    return Motion(time_s=bvh.time_s, columns=columns, in_degrees_source=True,
                  source=bvh.source, notes=tuple(notes))


__all__ = [
    "LENGTH_UNITS_M",
    "Bvh",
    "BvhJoint",
    "basis_matrix",
    "bvh_to_coordinates",
    "default_segment",
    "detect_axes",
    "hinge_angles",
    "joint_world_frames",
    "model_segments",
    "read_bvh",
]
