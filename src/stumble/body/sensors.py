"""The MuJoCo sensors every model carries, and how to read a row of them.

The physics loop (``stumble.sim``) steps MuJoCo in native blocks and gets one row of
``sensordata`` per step. Everything the controllers, the recording and the outcome need
is a sensor, so no Python runs per step:

- per foot: the net ground force on the foot and toes (contact sensor, ``netforce``
  reduction, world frame) and its point of application (the centre of pressure); the
  number of foot-obstacle contacts and the obstacle's net force on the foot; the foot
  body's position; four sole corners (heel
  and toe tip, both edges: the sole's bounding box);
- the number of floor contacts of any other segment (all floor contacts minus the
  feet's: a fall);
- the whole-body centre of mass and its velocity; the pelvis position; the torso's long
  axis and angular velocity (trunk lean and its rate);
- the hip, knee and ankle flexion angles and velocities of both legs;
- per actuator its force; per muscle also its length and velocity (the receptors'
  inputs).

MuJoCo computes sensors at the start of a step, from the state the step starts at, so
a row holds the sensors of the state before that step's integration.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

SIDES = ("r", "l")
LEG_JOINTS = ("hip_flexion", "knee_angle", "ankle_angle")
# sole corners among the 96 reference points (16 along × 6 across, heel first)
CORNER_SITES = (0, 5, 90, 95)


@dataclass(frozen=True)
class SensorLayout:
    """Where each quantity sits in a ``sensordata`` row (index arrays)."""

    foot_found: np.ndarray  # (2,) number of floor contacts of each foot
    foot_force: np.ndarray  # (2, 3) net floor force on each foot, world frame, N
    foot_cop: np.ndarray  # (2, 3) its point of application, m
    floor_found: int  # number of floor contacts of any geom
    obstacle_found: np.ndarray | None  # (2,) foot-obstacle contacts (None: no obstacle)
    obstacle_force: np.ndarray | None  # (2, 3) net obstacle force on each foot, world, N
    com: np.ndarray  # (3,)
    com_vel: np.ndarray  # (3,)
    pelvis: np.ndarray  # (3,)
    torso_z: np.ndarray  # (3,) the torso's long axis in the world
    torso_angvel: np.ndarray  # (3,) rad/s, world frame
    foot_pos: np.ndarray  # (2, 3) foot body origins (the ankles)
    sole: np.ndarray  # (2, 4, 3) sole corners
    joint_angle: np.ndarray  # (2, 3) rad, hip, knee, ankle of each leg (OpenSim signs)
    joint_velocity: np.ndarray  # (2, 3) rad/s
    actuator_force: np.ndarray  # (nu,) N or N·m, MuJoCo sign (muscles: negative = pull)
    muscle_length: np.ndarray  # (n_muscles,) m, actuator (tendon) lengths
    muscle_velocity: np.ndarray  # (n_muscles,) m/s
    muscle_force: np.ndarray  # (n_muscles,) N, MuJoCo sign (negative = pulling)
    size: int
    # one gather of everything ``stumble.sim.Sensors`` reads, in the order it reads: feet's
    # vertical force (2), feet's obstacle contacts (2), floor contacts (1), feet's floor
    # contacts (2), COM (3), its velocity (3), pelvis height (1), torso axis (3), torso
    # angular velocity (3), ankles (6), sole corners (24)
    decode_index: np.ndarray = None


def add_sensors(spec: mujoco.MjSpec, foot_points: dict[str, list[str]],
                actuators: list[str], muscles: list[str], obstacle: bool) -> None:
    """Add the standard sensors to a model spec (before compiling)."""
    S, Ob = mujoco.mjtSensor, mujoco.mjtObj

    def add(name: str, typ, objtype=None, objname: str = "", **kw):
        s = spec.add_sensor(name=name, type=typ)
        if objtype is not None:
            s.objtype, s.objname = objtype, objname
        for k, v in kw.items():
            setattr(s, k, v)
        return s

    def contact(name: str, data: str, reduce: int, **match):
        # intprm: [data field bits, reduction, num] (MuJoCo's mjtConDataField order)
        bits = 0
        for field in data.split():
            bits |= 1 << int(getattr(mujoco.mjtConDataField, f"mjCONDATA_{field.upper()}"))
        s = add(name, S.mjSENS_CONTACT)
        for key, (typ, obj) in match.items():
            if key == "first":
                s.objtype, s.objname = typ, obj
            else:
                s.reftype, s.refname = typ, obj
        s.intprm[0], s.intprm[1], s.intprm[2] = bits, reduce, 1
        return s

    for side in SIDES:
        contact(f"floor_{side}", "found force pos", 3,  # 3: netforce reduction
                first=(Ob.mjOBJ_XBODY, f"foot_{side}"), second=(Ob.mjOBJ_GEOM, "floor"))
    contact("floor_all", "found", 0, first=(Ob.mjOBJ_GEOM, "floor"))
    if obstacle:
        for side in SIDES:
            contact(f"obstacle_{side}", "found force", 3,  # 3: netforce reduction
                    first=(Ob.mjOBJ_XBODY, f"foot_{side}"), second=(Ob.mjOBJ_GEOM, "obstacle"))
    add("com", S.mjSENS_SUBTREECOM, Ob.mjOBJ_BODY, "pelvis")
    add("com_vel", S.mjSENS_SUBTREELINVEL, Ob.mjOBJ_BODY, "pelvis")
    add("pelvis", S.mjSENS_FRAMEPOS, Ob.mjOBJ_XBODY, "pelvis")
    add("torso_z", S.mjSENS_FRAMEZAXIS, Ob.mjOBJ_XBODY, "torso")
    add("torso_angvel", S.mjSENS_FRAMEANGVEL, Ob.mjOBJ_XBODY, "torso")
    for side in SIDES:
        add(f"foot_{side}", S.mjSENS_FRAMEPOS, Ob.mjOBJ_XBODY, f"foot_{side}")
        for k in CORNER_SITES:
            add(f"corner_{side}_{k}", S.mjSENS_FRAMEPOS, Ob.mjOBJ_SITE, foot_points[side][k])
    for side in SIDES:
        for j in LEG_JOINTS:
            add(f"{j}_{side}_angle", S.mjSENS_JOINTPOS, Ob.mjOBJ_JOINT, f"{j}_{side}")
            add(f"{j}_{side}_velocity", S.mjSENS_JOINTVEL, Ob.mjOBJ_JOINT, f"{j}_{side}")
    for name in actuators:
        add(f"{name}_force", S.mjSENS_ACTUATORFRC, Ob.mjOBJ_ACTUATOR, name)
    for name in muscles:
        add(f"{name}_length", S.mjSENS_ACTUATORPOS, Ob.mjOBJ_ACTUATOR, name)
        add(f"{name}_velocity", S.mjSENS_ACTUATORVEL, Ob.mjOBJ_ACTUATOR, name)


def layout(model: mujoco.MjModel, muscles: list[str]) -> SensorLayout:
    """The index arrays of the standard sensors of a compiled model (every actuator's
    force; ``muscles``: the actuators whose length and velocity are sensed)."""

    def at(name: str, n: int | None = None) -> np.ndarray:
        s = model.sensor(name)
        a = int(model.sensor_adr[s.id])
        return np.arange(a, a + (n or int(model.sensor_dim[s.id])))

    floor = [at(f"floor_{s}") for s in SIDES]
    has_obstacle = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, "obstacle_r") >= 0
    lay = SensorLayout(
        foot_found=np.array([f[0] for f in floor]),
        foot_force=np.array([f[1:4] for f in floor]),
        foot_cop=np.array([f[4:7] for f in floor]),
        floor_found=int(at("floor_all")[0]),
        obstacle_found=(np.array([at(f"obstacle_{s}")[0] for s in SIDES])
                        if has_obstacle else None),
        obstacle_force=(np.array([at(f"obstacle_{s}")[1:4] for s in SIDES])
                        if has_obstacle else None),
        com=at("com"), com_vel=at("com_vel"), pelvis=at("pelvis"), torso_z=at("torso_z"),
        torso_angvel=at("torso_angvel"),
        foot_pos=np.array([at(f"foot_{s}") for s in SIDES]),
        sole=np.array([[at(f"corner_{s}_{k}") for k in CORNER_SITES] for s in SIDES]),
        joint_angle=np.array([[at(f"{j}_{s}_angle")[0] for j in LEG_JOINTS] for s in SIDES]),
        joint_velocity=np.array([[at(f"{j}_{s}_velocity")[0] for j in LEG_JOINTS]
                                 for s in SIDES]),
        actuator_force=np.array([at(f"{model.actuator(i).name}_force")[0]
                                 for i in range(model.nu)], dtype=int),
        muscle_length=np.array([at(f"{n}_length")[0] for n in muscles], dtype=int),
        muscle_velocity=np.array([at(f"{n}_velocity")[0] for n in muscles], dtype=int),
        muscle_force=np.array([at(f"{n}_force")[0] for n in muscles], dtype=int),
        size=int(model.nsensordata))
    ob = lay.obstacle_found if lay.obstacle_found is not None else lay.foot_found
    index = np.concatenate([lay.foot_force[:, 2], ob, [lay.floor_found], lay.foot_found,
                            lay.com, lay.com_vel, lay.pelvis[2:], lay.torso_z,
                            lay.torso_angvel, lay.foot_pos.ravel(), lay.sole.ravel()])
    return replace(lay, decode_index=index.astype(int))
