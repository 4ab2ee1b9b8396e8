"""Build the 3D (42 DOF) and planar human models in code with ``mujoco.MjSpec``."""

from __future__ import annotations

import copy
from collections import OrderedDict
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from stumble.body import anthropometry as anth
from stumble.body import contact as foot_contact
from stumble.body import muscles
from stumble.body import sensors as body_sensors
from stumble.body.joints import JOINTS_3D, JOINTS_PLANAR, PELVIS_ROTATIONS, expand
from stumble.errors import InputError

# Collision bit masks, as the model is built. A pair collides when (contype_a &
# conaffinity_b) or (contype_b & conaffinity_a). Segments never collide with each other.
# The compiled model turns every collision the masks allow into an explicit pair and
# clears the masks (``_world_pairs``): the same contacts, without MuJoCo's broad phase.
GROUND = 1  # floor and obstacles: contype
SEGMENT = 1  # body segments: conaffinity (touch the ground -> a fall)
FOOT_OBSTACLE = 8  # foot volumes that only hit obstacles (the grid handles the floor)

# PD servo gains for the default build (the trip controllers set their own).
# SCA 2009 §4.5 Passive Reaction: support hip 1000, knee and ankle 300, toes 100
# N·m/rad; the upper-body values are our choice ("high gains", SCA 2009 §4.6).
DEFAULT_KP_NM_PER_RAD = {
    "lumbar": 1000.0, "neck": 300.0, "shoulder": 300.0, "elbow": 150.0, "pro_sup": 50.0,
    "wrist": 50.0, "hip": 1000.0, "knee": 300.0, "ankle": 300.0, "subtalar": 300.0,
    "mtp": 100.0,
}
KD_OVER_KP_S = 0.1  # SCA 2009 §4.5: k_d = 0.1 k_p
# Peak joint torques (N·m) used as actuator force limits; our choice, set near the
# largest net joint moments reported in fast walking and trip recovery (Winter 2009
# ch. 5; Pijnappels et al. 2004) with margin, for the reference body (70 kg, 1.75 m) and
# scaled by ``body_scale`` (body weight × height, as human strength scales: Anderson et
# al. 2007 normalise their joint torques so).
TORQUE_LIMIT_NM = {
    "lumbar": 300.0, "neck": 50.0, "shoulder": 80.0, "elbow": 50.0, "pro_sup": 10.0,
    "wrist": 20.0, "hip": 300.0, "knee": 250.0, "ankle": 250.0, "subtalar": 100.0,
    "mtp": 50.0,
}
# Passive limit torques: MuJoCo joint-limit constraints made soft enough to act as
# the steep passive moments near the end of a human range of motion (time constant
# 20 ms, critically damped). Our choice; Riener & Edrich 1999 describe such moments.
LIMIT_SOLREF = (0.02, 1.0)

SEGMENT_RGBA = (0.55, 0.65, 0.80, 1.0)
LEFT_RGBA = (0.42, 0.50, 0.66, 1.0)  # left limbs a shade darker, so the legs read apart
FOOT_RGBA = (0.25, 0.25, 0.30, 1.0)


REFERENCE_BODY = (70.0, 1.75)  # kg, m: the body the gains and limits were set on


def body_scale(mass_kg: float, height_m: float) -> float:
    """How a body's joint torques scale against the reference body's: m·h / (70 kg ·
    1.75 m). Under dynamic similarity (the same motion in units of √(h/g)) gravity's and
    inertia's joint moments both scale so; it is also how human strength scales (Anderson
    et al. 2007 normalise maximal joint torque by body weight × height)."""
    return mass_kg * height_m / (REFERENCE_BODY[0] * REFERENCE_BODY[1])


def _gain_key(hinge: str) -> str:
    for key in ("pro_sup", "subtalar", "lumbar", "neck", "shoulder", "elbow", "wrist",
                "hip", "knee", "ankle", "mtp"):
        if hinge.startswith(key):
            return key
    raise KeyError(hinge)


@dataclass
class Body:
    """A compiled human model and its description.

    ``joints`` lists the internal DOF (hinges) in model order; ``segments`` maps each
    segment name to its mass in kg; ``contact`` is the foot-contact mode.
    """

    model: mujoco.MjModel
    planar: bool
    height_m: float
    mass_kg: float
    sex: str
    contact: str
    joints: list[str]
    segments: dict[str, float]
    foot_points: dict[str, list[str]] = field(default_factory=dict)
    muscles: list = field(default_factory=list)  # stumble.body.muscles.MuscleGeometry
    sensors: body_sensors.SensorLayout | None = None  # where each sensor sits in a row
    muscle_set: str = ""  # the muscle set ("seed", "hfl"), or "" without muscles

    @property
    def dof(self) -> int:
        """Degrees of freedom of the whole model (root included)."""
        return int(self.model.nv)

    def describe(self) -> dict:
        """JSON-ready description (what ``stumble model --json`` prints)."""
        m = self.model
        return {
            "model": "planar" if self.planar else "3d",
            "nq": int(m.nq),
            "nv": int(m.nv),
            "nu": int(m.nu),
            "dof": self.dof,
            "internal_dof": len(self.joints),
            "root": [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
                     for j in range(m.njnt) if m.jnt_bodyid[j] == 1
                     and mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) not in self.joints],
            "joints": list(self.joints),
            "joint_ranges_deg": {
                name: [round(float(np.degrees(v)), 3) for v in m.jnt_range[m.joint(name).id]]
                for name in self.joints
            },
            "actuators": [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i)
                          for i in range(m.nu)],
            "height_m": self.height_m,
            "mass_kg": round(float(m.body_mass.sum()), 6),
            "sex": self.sex,
            "contact": self.contact,
            "contact_points_per_foot": {k: len(v) for k, v in self.foot_points.items()},
            "segments": {k: round(v, 6) for k, v in self.segments.items()},
            "timestep_s": float(m.opt.timestep),
        }


@dataclass(frozen=True)
class _Layout:
    """Joint centres and segment inertias of one person at the zero pose."""

    seg: dict[str, anth.Segment]
    ankle_h: float
    hip_h: float
    hip_y: float
    chest_z: float  # chest joint above the hip centres
    neck_z: float  # neck joint above the chest joint
    shoulder: np.ndarray  # right shoulder centre in the torso frame
    foot_len: float
    foot_w: float
    heel_x: float
    mtp: np.ndarray  # MTP joint in the foot frame
    lengths: dict[str, float]


def _layout(height: float, mass: float, sex: str) -> _Layout:
    L = {n: anth.segment_length(n, height, sex) for n in anth._LENGTH_MM}
    down, fwd = (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)
    seg = {n: anth.segment(n, height, mass, sex, down)
           for n in ("upper_arm", "forearm", "hand", "thigh", "shank")}
    ankle_h = anth.ANKLE_HEIGHT_H * height
    hip_h = ankle_h + L["shank"] + L["thigh"]
    # Pelvis = de Leva lower trunk (OMPH-MIDH), frame at MIDH: CoM measured from OMPH.
    lt = anth.segment("lower_trunk", height, mass, sex, down)
    seg["pelvis"] = anth.Segment("pelvis", lt.mass_kg, lt.length_m,
                                 np.array([0.0, 0.0, L["lower_trunk"]]) + lt.com_m,
                                 lt.inertia_kgm2)
    # Torso = middle + upper trunk, frame at OMPH; both measured from their cranial end.
    mt = anth.segment("middle_trunk", height, mass, sex, down)
    ut = anth.segment("upper_trunk", height, mass, sex, down)
    seg["torso"] = anth.combine("torso", [
        (mt, np.array([0.0, 0.0, L["middle_trunk"]])),
        (ut, np.array([0.0, 0.0, L["middle_trunk"] + L["upper_trunk"]])),
    ])
    chest_z = L["lower_trunk"]
    neck_z = L["middle_trunk"] + L["upper_trunk"]
    # Head (VERT-MIDG) hangs from the vertex at the top of the standing height.
    hd = anth.segment("head", height, mass, sex, down)
    head_top = height - (hip_h + chest_z + neck_z)
    seg["head"] = anth.Segment("head", hd.mass_kg, head_top,
                               np.array([0.0, 0.0, head_top]) + hd.com_m, hd.inertia_kgm2)
    shoulder = np.array([0.0, -0.8 * 0.5 * anth.SHOULDER_WIDTH_H * height,
                         anth.SHOULDER_HEIGHT_H * height - hip_h - chest_z])
    # SJC at 80 % of half the biacromial breadth (our choice; acromion is lateral of SJC).
    # Foot: de Leva HEEL-TTIP, split at the MTP joint into hind/mid-foot and toes.
    foot_len = L["foot"]
    ft = anth.segment("foot", height, mass, sex, fwd)
    heel_x = -anth.HEEL_BEHIND_ANKLE_FOOT * foot_len
    mtp = np.array([heel_x + anth.MTP_FROM_HEEL_FOOT * foot_len, 0.0, -0.65 * ankle_h])
    # MTP centre 35 % of the ankle height above the sole (our choice, about 2.4 cm).
    foot_com = np.array([heel_x + ft.com_m[0], 0.0, -0.5 * ankle_h])  # z: our choice
    share = anth.TOES_MASS_SHARE
    toes_len = foot_len * (1.0 - anth.MTP_FROM_HEEL_FOOT)
    toes_com = np.array([0.5 * toes_len, 0.0, -0.35 * ankle_h + 0.5 * 0.35 * ankle_h])
    m_toes = share * ft.mass_kg
    m_foot = ft.mass_kg - m_toes
    # Keep the whole-foot CoM where de Leva puts it.
    c_foot = (ft.mass_kg * foot_com - m_toes * (mtp + toes_com)) / m_foot
    seg["foot"] = anth.Segment("foot", m_foot, foot_len - toes_len, c_foot,
                               ft.inertia_kgm2 * (1.0 - share))
    seg["toes"] = anth.Segment("toes", m_toes, toes_len, toes_com, ft.inertia_kgm2 * share)
    return _Layout(seg, ankle_h, hip_h, anth.HIP_HALF_WIDTH_H * height, chest_z, neck_z,
                   shoulder, foot_len, anth.FOOT_WIDTH_H * height, heel_x, mtp, L)


def _add_body(parent, name: str, pos, s: anth.Segment):
    b = parent.add_body(name=name, pos=list(map(float, pos)))
    b.mass = float(s.mass_kg)
    b.ipos = [float(v) for v in s.com_m]
    b.inertia = [float(v) for v in s.inertia_kgm2]
    b.explicitinertial = True
    return b


def _capsule(body, name: str, a, b, radius: float, rgba=None):
    if rgba is None:
        rgba = LEFT_RGBA if "_l_" in name else SEGMENT_RGBA
    g = body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                      fromto=[*map(float, a), *map(float, b)], size=[radius, 0.0, 0.0])
    g.contype, g.conaffinity, g.density, g.rgba = 0, SEGMENT, 0.0, list(rgba)
    return g


def _hinges(body, side: str, joint_names: list[str], axes: dict, ranges: dict):
    for name in joint_names:
        lo, hi = np.radians(ranges[name])
        j = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=list(axes[name]),
                           range=[float(lo), float(hi)])
        j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        j.solref_limit = list(LIMIT_SOLREF)
        j.armature = 0.01  # kg·m², numerical regularisation of light distal segments
        j.damping = [0.5, 0.0, 0.0]  # N·m·s/rad, passive joint damping (our choice)


_COMPILED: OrderedDict[tuple, Body] = OrderedDict()  # build's last few results
_COMPILED_MAX = 8


def build(planar: bool = False, height_m: float = 1.75, mass_kg: float = 70.0,
          sex: str = "male", contact: str = foot_contact.DEFAULT_MODE,
          timestep_s: float = 0.001,
          obstacle: tuple[float, float, float, float, float] | None = None,
          actuation: str = "servos", muscle_set: str = muscles.DEFAULT_MUSCLE_SET) -> Body:
    """Compile the 3D (42 DOF) or planar human for a person of the given size.

    The same arguments give a copy of the same model (the last few compiled ones are kept
    per process: compiling takes 17 ms, a copy 1 ms); see ``compile_body`` for the
    arguments.
    """
    try:
        key = (planar, float(height_m), float(mass_kg), sex, contact, float(timestep_s),
               None if obstacle is None else tuple(map(float, obstacle)), actuation,
               muscle_set)
        hit = _COMPILED.get(key)
    except (TypeError, ValueError):  # a bad argument: compile_body says what is wrong
        hit, key = None, None
    if hit is None:
        hit = compile_body(planar, height_m, mass_kg, sex, contact, timestep_s, obstacle,
                           actuation, muscle_set)
        if key is not None:
            _COMPILED[key] = hit
            while len(_COMPILED) > _COMPILED_MAX:
                _COMPILED.popitem(last=False)
    else:
        _COMPILED.move_to_end(key)
    return replace(hit, model=copy.copy(hit.model), joints=list(hit.joints),
                   segments=dict(hit.segments),
                   foot_points={k: list(v) for k, v in hit.foot_points.items()},
                   muscles=list(hit.muscles))


def compile_body(planar: bool = False, height_m: float = 1.75, mass_kg: float = 70.0,
                 sex: str = "male", contact: str = foot_contact.DEFAULT_MODE,
                 timestep_s: float = 0.001,
                 obstacle: tuple[float, float, float, float, float] | None = None,
                 actuation: str = "servos",
                 muscle_set: str = muscles.DEFAULT_MUSCLE_SET,
                 world_pairs: bool = True) -> Body:
    """Compile the 3D (42 DOF) or planar human for a person of the given size (always
    anew; ``build`` keeps the last few).

    ``world_pairs``: the segments' and feet's collisions with the floor and obstacle as
    explicit pairs, the bit masks cleared (the default; see ``_world_pairs``); False
    leaves them to MuJoCo's broad phase, the same dynamics bit for bit, slower (kept
    for the test that says so, and for ``benchmarks/bench_reflex.py --broad-phase``).

    ``muscle_set`` (muscles only): ``"seed"`` (seed 003's seven per leg) or ``"hfl"``
    (those and an iliopsoas, Geyer & Herr 2010's HFL); see ``stumble.body.muscles``.
    ``actuation``: ``"servos"`` (a PD position servo per DOF) or, planar only,
    ``"muscles"`` (seed 003 §III: 7 Hill-type muscles per leg on hips, knees and ankles,
    ``stumble.body.muscles``; a PD servo on the lumbar joint; weak ankle springs).

    ``obstacle``: (near face x, height, depth, width, centre y) in m of a rigid box on
    the floor; feet and segments collide with it. Height in m, mass
    in kg. ``contact``: ``"points"`` (96 sole points per foot with
    the SCA 2009 §4.2 penalty law, resolved by MuJoCo), ``"penalty"`` (the same law in
    Python, ``stumble.body.contact.PenaltyContact``) or ``"soft"`` (MuJoCo's soft
    contact on foot boxes); see ``stumble.body.contact``.
    """
    anth.check_person(height_m, mass_kg, sex)
    foot_contact.check_mode(contact)
    if actuation not in ("servos", "muscles"):
        raise InputError(f"actuation {actuation!r} is not 'servos' or 'muscles'")
    if actuation == "muscles" and not planar:
        raise InputError("the muscle model is planar (seed 003): use planar=True")
    lay = _layout(height_m, mass_kg, sex)
    s = _Layout_spec(planar, timestep_s)
    world = s.worldbody
    floor = world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
    floor.contype, floor.conaffinity = GROUND, 0
    floor.material = "floor"
    floor.friction = [foot_contact.FRICTION, 0.005, 0.0001]
    if obstacle is not None:
        x0, h, depth, width, y0 = map(float, obstacle)
        box = world.add_geom(name="obstacle", type=mujoco.mjtGeom.mjGEOM_BOX,
                             pos=[x0 + 0.5 * depth, y0, 0.5 * h],
                             size=[0.5 * depth, 0.5 * width, 0.5 * h])
        box.contype, box.conaffinity = GROUND | FOOT_OBSTACLE, 0
        box.rgba = [0.75, 0.45, 0.2, 1.0]
        box.friction = [foot_contact.FRICTION, 0.005, 0.0001]

    joints = JOINTS_PLANAR if planar else JOINTS_3D
    flat = expand(joints)
    axes = {h[0]: h[3] for h in flat}
    ranges = {h[0]: h[4] for h in flat}
    by_child: dict[str, list[str]] = {}
    for name, _j, child, _a, _r in flat:
        by_child.setdefault(child, []).append(name)
    segs = dict(lay.seg)
    if planar:
        segs = _lump_planar(lay)

    pelvis = _add_body(world, "pelvis", (0.0, 0.0, lay.hip_h), segs["pelvis"])
    if planar:
        for name, typ, axis in (("pelvis_tx", mujoco.mjtJoint.mjJNT_SLIDE, (1, 0, 0)),
                                ("pelvis_ty", mujoco.mjtJoint.mjJNT_SLIDE, (0, 0, 1)),
                                (PELVIS_ROTATIONS[0].name, mujoco.mjtJoint.mjJNT_HINGE,
                                 PELVIS_ROTATIONS[0].axis)):
            pelvis.add_joint(name=name, type=typ, axis=list(map(float, axis)))
    else:
        pelvis.add_freejoint(name="pelvis")
    _capsule(pelvis, "pelvis_geom", (0, -lay.hip_y, 0.03), (0, lay.hip_y, 0.03), 0.07)
    pelvis.add_site(name="pelvis_site", pos=[0, 0, 0], size=[0.01, 0, 0])

    torso = _add_body(pelvis, "torso", (0.0, 0.0, lay.chest_z), segs["torso"])
    _hinges(torso, "", by_child["torso"], axes, ranges)
    tz = lay.neck_z
    _capsule(torso, "torso_geom", (0, 0, 0.06), (0, 0, tz - 0.08), 0.12)
    _capsule(torso, "shoulders_geom", (0, lay.shoulder[1], lay.shoulder[2]),
             (0, -lay.shoulder[1], lay.shoulder[2]), 0.055)
    if planar:
        _capsule(torso, "head_geom", (0, 0, tz + lay.seg["head"].length_m - 0.11),
                 (0, 0, tz + lay.seg["head"].length_m - 0.10), 0.10)
    else:
        head = _add_body(torso, "head", (0.0, 0.0, tz), segs["head"])
        _hinges(head, "", by_child["head"], axes, ranges)
        top = lay.seg["head"].length_m
        _capsule(head, "head_geom", (0, 0, top - 0.12), (0, 0, top - 0.10), 0.10)
        _capsule(head, "neck_geom", (0, 0, 0.0), (0, 0, top - 0.2), 0.05)
        for side, sign in (("r", 1.0), ("l", -1.0)):
            sh = lay.shoulder * np.array([1.0, sign, 1.0])
            ua = _add_body(torso, f"upper_arm_{side}", sh, segs["upper_arm"])
            _hinges(ua, side, by_child[f"upper_arm_{side}"], axes, ranges)
            lu = lay.lengths["upper_arm"]
            _capsule(ua, f"upper_arm_{side}_geom", (0, 0, 0), (0, 0, -lu), 0.045)
            fa = _add_body(ua, f"forearm_{side}", (0, 0, -lu), segs["forearm"])
            _hinges(fa, side, by_child[f"forearm_{side}"], axes, ranges)
            lf = lay.lengths["forearm"]
            _capsule(fa, f"forearm_{side}_geom", (0, 0, 0), (0, 0, -lf), 0.038)
            hd = _add_body(fa, f"hand_{side}", (0, 0, -lf), segs["hand"])
            _hinges(hd, side, by_child[f"hand_{side}"], axes, ranges)
            _capsule(hd, f"hand_{side}_geom", (0, 0, -0.01), (0, 0, -lay.lengths["hand"]),
                     0.035)

    foot_points: dict[str, list[str]] = {}
    pair_weights: list[float] = []
    for side, sign in (("r", -1.0), ("l", 1.0)):
        th = _add_body(pelvis, f"thigh_{side}", (0, sign * lay.hip_y, 0), segs["thigh"])
        _hinges(th, side, by_child[f"thigh_{side}"], axes, ranges)
        lt = lay.lengths["thigh"]
        _capsule(th, f"thigh_{side}_geom", (0, 0, -0.05), (0, 0, -lt), 0.065)
        sh = _add_body(th, f"shank_{side}", (0, 0, -lt), segs["shank"])
        _hinges(sh, side, by_child[f"shank_{side}"], axes, ranges)
        ls = lay.lengths["shank"]
        _capsule(sh, f"shank_{side}_geom", (0, 0, -0.02), (0, 0, -ls + 0.06), 0.048)
        ft = _add_body(sh, f"foot_{side}", (0, 0, -ls), segs["foot"])
        _hinges(ft, side, by_child[f"foot_{side}"], axes, ranges)
        toes = None
        if not planar:
            toes = _add_body(ft, f"toes_{side}", lay.mtp, segs["toes"])
            _hinges(toes, side, by_child[f"toes_{side}"], axes, ranges)
        foot_points[side], w = foot_contact.add_foot(
            s, ft, toes, side, contact, lay.heel_x, lay.mtp, lay.foot_len, lay.foot_w,
            lay.ankle_h)
        pair_weights += w

    hinges = [h[0] for h in flat]
    muscle_geometry = []
    if actuation == "muscles":
        _actuators(s, [h for h in hinges if h.startswith("lumbar")], mass_kg, height_m)
        muscle_geometry = muscles.add_muscles(s, height_m, mass_kg,
                                              muscles.check_muscle_set(muscle_set))
        for side in ("r", "l"):
            j = s.joint(f"ankle_angle_{side}")
            j.stiffness = [muscles.ANKLE_STIFFNESS_NM_PER_RAD, 0.0, 0.0]
            j.damping = [muscles.ANKLE_DAMPING_NMS_PER_RAD, 0.0, 0.0]
    else:
        _actuators(s, hinges, mass_kg, height_m)
    body_sensors.add_sensors(s, foot_points, [a.name for a in s.actuators],
                             [g.name for g in muscle_geometry], obstacle is not None)
    if world_pairs:
        _world_pairs(s)
    model = s.compile()
    foot_contact.configure(model, np.array(pair_weights))
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    internal = [n for n in names if n in axes]
    masses = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b): float(model.body_mass[b])
              for b in range(1, model.nbody)}
    return Body(model, planar, height_m, mass_kg, sex, contact, internal, masses, foot_points,
                muscle_geometry, body_sensors.layout(model, [g.name for g in muscle_geometry]),
                muscle_set if actuation == "muscles" else "")


def _bodies(body) -> list:
    """A spec's bodies from ``body`` down, in the compiled model's order (pre-order)."""
    out = [body]
    for child in body.bodies:
        out += _bodies(child)
    return out


def _welded_to_world(s: mujoco.MjSpec, body) -> bool:
    """Whether no joint lies between a spec's body and the world (MuJoCo does not collide
    such a body with the world's geoms)."""
    while body is not s.worldbody:
        if body.joints:
            return False
        body = body.parent
    return True


def _world_pairs(s: mujoco.MjSpec) -> None:
    """Turn each collision of a world geom (the floor, an obstacle) with a body's geom
    that the bit masks allow into an explicit pair, then clear every bit mask.

    Why (ours, for speed): the segments only ever touch the world's geoms, but while
    their masks let them collide MuJoCo's broad phase bounds and sorts every body every
    step. With pairs it only frames the geoms: the planar model's walking step (2 ms)
    takes about 7 % less (``benchmarks/bench_reflex.py --broad-phase``).
    The contacts are the same, to the bit, in the same order: body by body (pairs are
    sorted by body pair when compiled, keeping the order added within one, so a foot's
    sole pairs come first, as MuJoCo takes predefined pairs before the broad phase's),
    within a body by (geom of the lower type, the other) as MuJoCo sorts a body pair's
    contacts, and with the parameters MuJoCo mixes for two geoms (``mj_contactParam``:
    condim and friction the larger; solref and solimp mixed, exact only for equal
    values and weights, which are required here). ``build_test`` steps both models
    through falls and an obstacle under a standing foot (``lumped`` and ``soft``, planar
    and 3D; planar ``points``) and compares every contact and state. The guards are
    stricter than MuJoCo (they ignore its weld, parent and exclude filters).
    """
    bodies = _bodies(s.worldbody)
    masked = [(b, g) for b in bodies for g in b.geoms if g.contype or g.conaffinity]
    for i, (b1, g1) in enumerate(masked):  # only the world's geoms may meet a body's
        for b2, g2 in masked[i + 1:]:
            if (b1 is not s.worldbody and b2 is not b1
                    and (g1.contype & g2.conaffinity or g2.contype & g1.conaffinity)):
                raise ValueError(f"geoms {g1.name} and {g2.name}: bodies that collide with "
                                 "each other, which _world_pairs does not turn into pairs")
    world = [g for b, g in masked if b is s.worldbody]
    for body in bodies[1:]:
        pairs, welded = [], _welded_to_world(s, body)
        for gb in body.geoms:
            for gw in world:
                if not (gw.contype & gb.conaffinity or gb.contype & gw.conaffinity):
                    continue
                if (gw.priority != gb.priority or gw.solmix != gb.solmix
                        or list(gw.solref) != list(gb.solref)
                        or list(gw.solimp) != list(gb.solimp) or gw.margin or gb.margin
                        or gw.gap or gb.gap or welded):
                    raise ValueError(f"pair {gw.name}/{gb.name}: a body welded to the world "
                                     "or parameters MuJoCo would mix, which an explicit "
                                     "pair does not copy")
                fr = [max(a, b) for a, b in zip(gw.friction, gb.friction, strict=True)]
                # geom ids, as compiled, rise in these ranks (the world's geoms first)
                rw, rb = (0, world.index(gw)), (1, body.geoms.index(gb))
                low_first = int(gw.type) <= int(gb.type)
                pairs.append(((rw, rb) if low_first else (rb, rw), gw, gb, fr))
        for _key, gw, gb, fr in sorted(pairs, key=lambda p: p[0]):
            p = s.add_pair(name=f"{gw.name}_{gb.name}", geomname1=gw.name,
                           geomname2=gb.name, condim=max(gw.condim, gb.condim))
            p.friction = [fr[0], fr[0], fr[1], fr[2], fr[2]]
            p.solref, p.solimp = list(gw.solref), list(gw.solimp)
    for _body, g in masked:
        g.contype, g.conaffinity = 0, 0


def _Layout_spec(planar: bool, timestep_s: float) -> mujoco.MjSpec:
    s = mujoco.MjSpec()
    s.modelname = "stumble_planar" if planar else "stumble_3d"
    s.option.timestep = timestep_s
    s.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    s.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC  # friction cones of the point contacts
    s.option.impratio = foot_contact.IMPRATIO
    s.option.tolerance = foot_contact.SOLVER_TOLERANCE
    s.compiler.degree = False
    tex = s.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                        rgb1=[0.82, 0.82, 0.80], rgb2=[0.68, 0.68, 0.66], width=128, height=128)
    # (small textures: every trip copies its model, textures and all; the sky is a smooth
    # gradient, 32 pixels a side draw it as 256 did)
    s.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                  builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.55, 0.7, 0.9],
                  rgb2=[0.95, 0.95, 0.97], width=32, height=32)
    mat = s.add_material(name="floor", texrepeat=[1, 1], reflectance=0.0)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
    s.visual.headlight.ambient = [0.45, 0.45, 0.45]
    s.visual.headlight.diffuse = [0.6, 0.6, 0.6]
    return s


def _lump_planar(lay: _Layout) -> dict[str, anth.Segment]:
    """Planar model: head and arms lumped into the torso, toes into the foot."""
    segs = dict(lay.seg)
    z_neck = np.array([0.0, 0.0, lay.neck_z])
    parts = [(lay.seg["torso"], np.zeros(3)), (lay.seg["head"], z_neck)]
    for side in (1.0, -1.0):
        sh = lay.shoulder * np.array([1.0, side, 1.0])
        parts.append((lay.seg["upper_arm"], sh))
        parts.append((lay.seg["forearm"], sh - [0, 0, lay.lengths["upper_arm"]]))
        parts.append((lay.seg["hand"], sh - [0, 0, lay.lengths["upper_arm"]
                                             + lay.lengths["forearm"]]))
    segs["torso"] = anth.combine("torso", parts)
    segs["foot"] = anth.combine("foot", [(lay.seg["foot"], np.zeros(3)),
                                         (lay.seg["toes"], lay.mtp)])
    return segs


def _actuators(s: mujoco.MjSpec, hinges: list[str], mass_kg: float,
               height_m: float) -> None:
    """One PD position servo per internal DOF: τ = kp(ctrl − θ) − kd θ̇ (SCA 2009 eq. 1),
    its torque limit scaled by ``body_scale``."""
    scale = body_scale(mass_kg, height_m)
    for name in hinges:
        key = _gain_key(name)
        kp = DEFAULT_KP_NM_PER_RAD[key]
        a = s.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        a.set_to_position(kp=kp, kv=KD_OVER_KP_S * kp)
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        lim = TORQUE_LIMIT_NM[key] * scale
        a.forcerange = [-lim, lim]
