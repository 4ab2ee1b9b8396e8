"""The one loop that steps physics, its sensors and its recording.

Controllers see a ``Context`` (model, data, sensors, time since the trip) and write
actuator commands; they never step. The loop runs the controller every
``control_every`` physics steps (MuJoCo's PD servos run at every step in C), applies
the tripping force of a ``force`` scenario at every step while it lasts, records at
``RECORD_HZ`` and stops at the first outcome the ``stop`` callback reports, at the end
of the time budget, or when the physics diverges.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np

from stumble.body import Body

_NO_FORCE = np.zeros(3)
RECORD_HZ = 200.0
CONTROL_HZ = 500.0  # controller updates; the servos themselves run at every 1 ms step
CONTACT_FORCE_MIN_N = 1.0  # a foot with less total normal force is not "on the floor"


@dataclass
class Sensors:
    """What the controllers may read, refreshed before every controller update."""

    t: float = 0.0  # s since the trip
    foot_on_floor: dict[str, bool] = field(default_factory=lambda: {"r": True, "l": True})
    foot_on_obstacle: dict[str, bool] = field(default_factory=lambda: {"r": False, "l": False})
    foot_force_n: dict[str, float] = field(default_factory=lambda: {"r": 0.0, "l": 0.0})
    segment_on_floor: bool = False  # a body other than the feet touches the floor
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    com_vel: np.ndarray = field(default_factory=lambda: np.zeros(3))
    pelvis_height: float = 0.0


@dataclass
class Context:
    """The physics state a controller acts on."""

    model: mujoco.MjModel
    data: mujoco.MjData
    body: Body
    sensors: Sensors
    t0: float  # data.time at the trip


class Controller(Protocol):
    """A trip controller: ``start`` once at the trip, ``update`` at the control rate."""

    name: str

    def start(self, ctx: Context) -> None:
        """Take over at the trip instant."""

    def update(self, ctx: Context) -> None:
        """Read ``ctx.sensors``/``ctx.data``; write ``ctx.data.ctrl`` or servo gains."""

    def state(self) -> str:
        """Name of the current state (for the recording)."""


@dataclass
class Recording:
    """Time series at ``RECORD_HZ`` from the trip on (time 0 = the trip)."""

    time_s: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    com: np.ndarray
    com_vel: np.ndarray
    foot_on_floor: np.ndarray  # (T, 2): r, l
    foot_on_obstacle: np.ndarray  # (T, 2): r, l
    trip_force: np.ndarray  # (T, 3) N
    state: list[str]
    segment_on_floor: np.ndarray  # (T,)
    actuator_force: np.ndarray | None = None  # (T, nu) N or N·m (muscles: negative = pull)
    activation: np.ndarray | None = None  # (T, na) MuJoCo activation states (muscles: 0-1)
    steps: int = 0
    wall_time_s: float = 0.0
    physics_time_s: float = 0.0  # of which inside MuJoCo's step
    diverged: bool = False
    stop_reason: str = ""


class Geometry:
    """Which geoms belong to which foot, and which are the floor and obstacle."""

    def __init__(self, body: Body):
        m = body.model
        self.floor = m.geom("floor").id
        obst = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "obstacle")
        self.obstacle = obst
        self.side_of = np.full(m.ngeom, -1, dtype=int)  # 0 right foot, 1 left foot
        for g in range(m.ngeom):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[g]) or ""
            if name.startswith(("foot_", "toes_")):
                self.side_of[g] = 0 if name.endswith("_r") else 1
        self.is_segment = (self.side_of < 0) & (m.geom_bodyid > 0)


def read_sensors(ctx: Context, geo: Geometry) -> None:
    """Refresh ``ctx.sensors`` from the current data (contacts, COM, pelvis)."""
    m, d, s = ctx.model, ctx.data, ctx.sensors
    s.t = d.time - ctx.t0
    n = d.ncon
    force = np.zeros(2)
    on_obst = [False, False]
    seg_floor = False
    if n:
        g1 = d.contact.geom1[:n]
        g2 = d.contact.geom2[:n]
        other = np.where(g1 == geo.floor, g2, np.where(g2 == geo.floor, g1, -1))
        rows = np.flatnonzero(other >= 0)
        if rows.size:
            g = other[rows]
            side = geo.side_of[g]
            feet = side >= 0
            normal = d.efc_force[d.contact.efc_address[rows[feet]]]
            force = np.bincount(side[feet], weights=normal, minlength=2)[:2]
            seg_floor = bool(geo.is_segment[g[~feet]].any())
        if geo.obstacle >= 0:
            ob = np.where(g1 == geo.obstacle, g2, np.where(g2 == geo.obstacle, g1, -1))
            sides = geo.side_of[ob[ob >= 0]]
            on_obst = [bool((sides == 0).any()), bool((sides == 1).any())]
    penalty = getattr(ctx, "penalty", None)
    if penalty is not None:  # explicit penalty mode: the forces are ours, not MuJoCo's
        for k in range(2):  # 0 right, 1 left
            force[k] = penalty.force[penalty.side_index == k, 2].sum()
    s.foot_on_floor = {"r": bool(force[0] > CONTACT_FORCE_MIN_N),
                       "l": bool(force[1] > CONTACT_FORCE_MIN_N)}
    s.foot_on_obstacle = {"r": on_obst[0], "l": on_obst[1]}
    s.foot_force_n = {"r": float(force[0]), "l": float(force[1])}
    s.segment_on_floor = seg_floor
    mujoco.mj_subtreeVel(m, d)
    s.com = d.subtree_com[1].copy()
    s.com_vel = d.subtree_linvel[1].copy()
    s.pelvis_height = float(d.xpos[1, 2])


def run(ctx: Context, controller: Controller, duration_s: float,
        trip_force: Callable[[float], np.ndarray] | None = None, force_body: int = -1,
        force_point: Callable[[mujoco.MjData], np.ndarray] | None = None,
        stop: Callable[[Context, Recording, int], str] | None = None,
        control_every: int | None = None, penalty=None) -> Recording:
    """Step physics from the trip for up to ``duration_s``; returns the recording."""
    m, d = ctx.model, ctx.data
    dt = m.opt.timestep
    n_steps = round(duration_s / dt)
    rec_every = max(1, round(1.0 / (RECORD_HZ * dt)))
    control_every = control_every or max(1, round(1.0 / (CONTROL_HZ * dt)))
    # contacts, COM and pelvis: at every control update, or as often as the controller
    # asks (``sensor_hz``); the recording and the stop rule read them at RECORD_HZ
    sensor_every = max(control_every, round(1.0 / (getattr(controller, "sensor_hz", 1e9) * dt)))
    n_rec = n_steps // rec_every + 1
    rec = Recording(np.zeros(n_rec), np.zeros((n_rec, m.nq)), np.zeros((n_rec, m.nv)),
                    np.zeros((n_rec, 3)), np.zeros((n_rec, 3)), np.zeros((n_rec, 2), bool),
                    np.zeros((n_rec, 2), bool), np.zeros((n_rec, 3)), [""] * n_rec,
                    np.zeros(n_rec, bool), np.zeros((n_rec, m.nu)), np.zeros((n_rec, m.na)))
    geo = Geometry(ctx.body)
    ctx.penalty = penalty
    if penalty is not None:
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in penalty.body_ids]
        penalty.side_index = np.array([0 if n.endswith("_r") else 1 for n in names])
    mujoco.mj_forward(m, d)
    if penalty is not None:
        penalty.apply(d)
    read_sensors(ctx, geo)
    controller.start(ctx)
    forcing = trip_force is not None and force_body >= 0
    force_end_s = getattr(trip_force, "t_trip_s", duration_s)
    k_rec = 0
    wall0 = time.perf_counter()
    step = 0
    reason = "time"
    for step in range(n_steps + 1):
        t = d.time - ctx.t0
        if step % control_every == 0:
            if step % sensor_every == 0:
                read_sensors(ctx, geo)
            controller.update(ctx)
        f = _NO_FORCE
        if forcing:  # only while the collision lasts: nothing per step afterwards
            f = trip_force(t)
            if t > force_end_s:
                d.xfrc_applied[force_body] = 0.0
                forcing = False
            else:
                p = force_point(d)
                d.xfrc_applied[force_body, :3] = f
                d.xfrc_applied[force_body, 3:] = np.cross(p - d.xipos[force_body], f)
        if step % rec_every == 0 and k_rec < n_rec:
            if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
                rec.diverged, reason = True, "diverged"
                break
            rec.time_s[k_rec] = t
            rec.qpos[k_rec] = d.qpos
            rec.qvel[k_rec] = d.qvel
            rec.com[k_rec] = ctx.sensors.com
            rec.com_vel[k_rec] = ctx.sensors.com_vel
            rec.foot_on_floor[k_rec] = (ctx.sensors.foot_on_floor["r"],
                                        ctx.sensors.foot_on_floor["l"])
            rec.foot_on_obstacle[k_rec] = (ctx.sensors.foot_on_obstacle["r"],
                                           ctx.sensors.foot_on_obstacle["l"])
            rec.trip_force[k_rec] = f
            rec.state[k_rec] = controller.state()
            rec.segment_on_floor[k_rec] = ctx.sensors.segment_on_floor
            rec.actuator_force[k_rec] = d.actuator_force
            rec.activation[k_rec] = d.act
            k_rec += 1
            if stop is not None:
                why = stop(ctx, rec, k_rec)
                if why:
                    reason = why
                    break
        if step == n_steps:
            break
        tic = time.perf_counter()
        if penalty is not None:
            mujoco.mj_step1(m, d)
            penalty.apply(d)
            mujoco.mj_step2(m, d)
        else:
            mujoco.mj_step(m, d)
        rec.physics_time_s += time.perf_counter() - tic
        if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            rec.diverged, reason = True, "diverged"
            break
    rec.wall_time_s = time.perf_counter() - wall0
    rec.steps = step
    rec.stop_reason = reason
    for name in ("time_s", "qpos", "qvel", "com", "com_vel", "foot_on_floor",
                 "foot_on_obstacle", "trip_force", "segment_on_floor", "actuator_force",
                 "activation"):
        setattr(rec, name, getattr(rec, name)[:k_rec])
    rec.state = rec.state[:k_rec]
    return rec
