"""The one loop that steps physics, its sensors and its recording.

Controllers see a ``Context`` (model, data, sensors, time since the trip) and act once
per *block* of ``period_steps`` physics steps; they never step. ``update`` either writes
``data.ctrl`` (and servo gains), held over the block, or returns the block's per-step
controls as an array. Between updates MuJoCo advances natively: ``mj_step`` with
``nstep`` for held controls, ``mujoco.rollout`` for per-step ones. Everything read while
a block runs is a MuJoCo sensor (``stumble.body.sensors``): a controller that asks for
them (``observe``) gets the block's per-step sensor rows, and the recording takes its
samples (``RECORD_HZ``) from the same rows. The only per-step Python is the tripping
force of a ``force`` scenario while it lasts, and the explicit ``penalty`` contact.

The run stops at the first outcome the ``stop`` rule reports (it sees every sample), at
the end of the time budget, or when the physics diverges (NaN, or MuJoCo's
bad-acceleration warning).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from stumble.body import Body
from stumble.body.sensors import SensorLayout

RECORD_HZ = 200.0
CONTROL_HZ = 500.0  # default controller rate; the servos themselves run at every step
CONTACT_FORCE_MIN_N = 1.0  # a foot with less total normal force is not "on the floor"
_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
_CTRL = int(mujoco.mjtState.mjSTATE_CTRL)


@dataclass
class Sensors:
    """What controllers and the outcome read: one sensor row, decoded (SI units)."""

    t: float = 0.0  # s since the trip
    foot_on_floor: dict[str, bool] = field(default_factory=lambda: {"r": True, "l": True})
    foot_on_obstacle: dict[str, bool] = field(default_factory=lambda: {"r": False, "l": False})
    foot_force_n: dict[str, float] = field(default_factory=lambda: {"r": 0.0, "l": 0.0})
    segment_on_floor: bool = False  # a body other than the feet touches the floor
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    com_vel: np.ndarray = field(default_factory=lambda: np.zeros(3))
    pelvis_height: float = 0.0
    torso_z: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    torso_angvel: np.ndarray = field(default_factory=lambda: np.zeros(3))
    foot_pos: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))  # r, l ankles
    sole: np.ndarray = field(default_factory=lambda: np.zeros((2, 4, 3)))  # r, l corners


def decode(lay: SensorLayout, row: np.ndarray, t: float, out: Sensors | None = None,
           foot_normal_n: np.ndarray | None = None, index: np.ndarray | None = None,
           ) -> Sensors:
    """``Sensors`` from one sensor row; ``foot_normal_n`` overrides the feet's loads
    (the explicit ``penalty`` contact, whose forces MuJoCo does not see); ``index``: the
    layout's ``decode_index`` (pass it when decoding many rows)."""
    s = out or Sensors()
    v = row[lay.decode_index if index is None else index]
    fr, fl = (-v[0], -v[1]) if foot_normal_n is None else foot_normal_n
    s.t = t
    s.foot_force_n = {"r": float(fr), "l": float(fl)}
    s.foot_on_floor = {"r": bool(fr > CONTACT_FORCE_MIN_N), "l": bool(fl > CONTACT_FORCE_MIN_N)}
    if lay.obstacle_found is not None:
        s.foot_on_obstacle = {"r": bool(v[2] > 0), "l": bool(v[3] > 0)}
    s.segment_on_floor = bool(v[4] - v[5] - v[6] > 0.5)
    s.com, s.com_vel = v[7:10], v[10:13]
    s.pelvis_height = float(v[13])
    s.torso_z, s.torso_angvel = v[14:17], v[17:20]
    s.foot_pos = v[20:26].reshape(2, 3)
    s.sole = v[26:50].reshape(2, 4, 3)
    return s


@dataclass
class Context:
    """The physics state a controller acts on."""

    model: mujoco.MjModel
    data: mujoco.MjData
    body: Body
    sensors: Sensors
    t0: float  # data.time at the trip


class Controller(Protocol):
    """A trip controller: ``start`` once at the trip, ``update`` once per block.

    ``period_steps``: physics steps per block (read after ``start``). ``update`` writes
    ``ctx.data.ctrl`` (held over the block) and returns None, or returns the block's
    controls, (period_steps, nu). An optional ``observe(rows)`` receives the sensor rows
    (period_steps, nsensordata) of each block once it has been stepped.
    """

    name: str
    period_steps: int

    def start(self, ctx: Context) -> None:
        """Take over at the trip instant."""

    def update(self, ctx: Context) -> np.ndarray | None:
        """Read ``ctx.sensors``/``ctx.data``; write ``ctx.data.ctrl`` or return controls."""

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
    activation: np.ndarray | None = None  # (T, na) muscle activations (MuJoCo act)
    foot_force: np.ndarray | None = None  # (T, 2) N, vertical ground force per foot
    steps: int = 0
    wall_time_s: float = 0.0
    physics_time_s: float = 0.0  # of which inside MuJoCo
    diverged: bool = False
    stop_reason: str = ""
    controls: list | None = None  # (first step, ctrl rows, gains) per block, if logged


@dataclass
class _Buffers:
    """Pre-allocated recording arrays and the next free row."""

    n: int
    model: mujoco.MjModel
    k: int = 0

    def __post_init__(self) -> None:
        n, m = self.n, self.model
        self.rec = Recording(np.zeros(n), np.zeros((n, m.nq)), np.zeros((n, m.nv)),
                             np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 2), bool),
                             np.zeros((n, 2), bool), np.zeros((n, 3)), [""] * n,
                             np.zeros(n, bool), np.zeros((n, m.nu)), np.zeros((n, m.na)),
                             np.zeros((n, 2)))

    def add(self, t: float, qpos, qvel, act, s: Sensors, force, state: str, actuator_force):
        r, k = self.rec, self.k
        r.time_s[k], r.qpos[k], r.qvel[k], r.com[k], r.com_vel[k] = t, qpos, qvel, s.com, s.com_vel
        r.foot_on_floor[k] = s.foot_on_floor["r"], s.foot_on_floor["l"]
        r.foot_on_obstacle[k] = s.foot_on_obstacle["r"], s.foot_on_obstacle["l"]
        r.foot_force[k] = s.foot_force_n["r"], s.foot_force_n["l"]
        r.trip_force[k], r.state[k], r.segment_on_floor[k] = force, state, s.segment_on_floor
        r.actuator_force[k] = actuator_force
        r.activation[k] = act
        self.k = k + 1

    def trimmed(self) -> Recording:
        r, k = self.rec, self.k
        for name in ("time_s", "qpos", "qvel", "com", "com_vel", "foot_on_floor",
                     "foot_on_obstacle", "trip_force", "segment_on_floor", "actuator_force",
                     "activation", "foot_force"):
            setattr(r, name, getattr(r, name)[:k])
        r.state = r.state[:k]
        return r


class _Stepper:
    """Advances MuJoCo by held or per-step controls; returns the sensor rows it saw."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, penalty=None):
        self.m, self.d, self.penalty = m, d, penalty
        self.nstate = mujoco.mj_stateSize(m, _STATE)
        self.state0 = np.zeros((1, self.nstate))
        self._pool = mj_rollout.Rollout(nthread=0)
        self.physics_s = 0.0

    def _single(self, ctrl: np.ndarray | None, force=None) -> np.ndarray:
        m, d = self.m, self.d
        if ctrl is not None:
            d.ctrl[:] = ctrl
        if force is not None:
            force(d)
        if self.penalty is not None:
            mujoco.mj_step1(m, d)
            self.penalty.apply(d)
            mujoco.mj_step2(m, d)
        else:
            mujoco.mj_step(m, d)
        return d.sensordata

    def advance(self, n: int, ctrl: np.ndarray | None, force=None,
                want_rows: bool = False, want_states: bool = False):
        """Step ``n`` times; ``ctrl`` None: hold ``data.ctrl``; else (n, nu) per step.
        ``force(data)``: called before every step (then steps are taken one by one).
        Returns (sensor rows (n, ns) or only the last (1, ns), states (n, nstate) or None).
        """
        m, d = self.m, self.d
        tic = time.perf_counter()
        rows = states = None
        if force is not None or self.penalty is not None:
            rows = np.empty((n, m.nsensordata))
            states = np.empty((n, self.nstate))
            for i in range(n):
                rows[i] = self._single(None if ctrl is None else ctrl[i], force)
                mujoco.mj_getState(m, d, states[i], _STATE)
        elif ctrl is None and not want_rows and not want_states:
            mujoco.mj_step(m, d, n)
            rows = d.sensordata[None].copy()
        else:
            if ctrl is None:
                ctrl = np.repeat(d.ctrl[None], n, axis=0)
            ctrl = np.ascontiguousarray(ctrl, dtype=float).reshape(1, n, m.nu)
            mujoco.mj_getState(m, d, self.state0[0], _STATE)
            states = np.empty((1, n, self.nstate))
            rows = np.empty((1, n, m.nsensordata))
            self._pool.rollout_.rollout([m], [d], n, _CTRL, self.state0,
                                        d.qacc_warmstart[None].copy(), ctrl, states, rows,
                                        None)
            states, rows = states[0], rows[0]
        self.physics_s += time.perf_counter() - tic
        return rows, states


def run(ctx: Context, controller: Controller, duration_s: float,
        trip_force: Callable[[float], np.ndarray] | None = None, force_body: int = -1,
        force_point: Callable[[mujoco.MjData], np.ndarray] | None = None,
        stop: Callable[[Sensors], str] | None = None, penalty=None,
        log_controls: bool = False) -> Recording:
    """Step physics from the trip for up to ``duration_s``; returns the recording.

    ``stop(sensors)`` sees every sample and returns a non-empty reason to stop.
    ``log_controls``: keep every block's controls and servo gains (for benchmarks that
    replay them on a bare loop).
    """
    m, d, body = ctx.model, ctx.data, ctx.body
    lay = body.sensors
    dt = m.opt.timestep
    n_steps = round(duration_s / dt)
    rec_every = max(1, round(1.0 / (RECORD_HZ * dt)))
    buf = _Buffers(n_steps // rec_every + 1, m)
    stepper = _Stepper(m, d, penalty)
    sides = {0: "r", 1: "l"}
    if penalty is not None:
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in penalty.body_ids]
        penalty.side_index = np.array([0 if n.endswith("_r") else 1 for n in names])

    def loads() -> np.ndarray | None:
        if penalty is None:
            return None
        return np.array([penalty.force[penalty.side_index == k, 2].sum() for k in sides])

    mujoco.mj_forward(m, d)
    if penalty is not None:
        penalty.apply(d)
    decode(lay, d.sensordata, d.time - ctx.t0, ctx.sensors, loads())
    controller.start(ctx)
    period = max(1, int(getattr(controller, "period_steps", 0)
                        or round(1.0 / (CONTROL_HZ * dt))))
    observe = getattr(controller, "observe", None)
    forcing = trip_force is not None and force_body >= 0
    force_end_s = getattr(trip_force, "t_trip_s", duration_s)
    no_force = np.zeros(3)

    def force_at(t: float) -> np.ndarray:
        return trip_force(t) if forcing and 0.0 <= t <= force_end_s else no_force

    def apply_force(dd: mujoco.MjData) -> None:
        f = force_at(dd.time - ctx.t0)
        p = force_point(dd)
        dd.xfrc_applied[force_body, :3] = f
        dd.xfrc_applied[force_body, 3:] = np.cross(p - dd.xipos[force_body], f)

    controls = [] if log_controls else None
    wall0 = time.perf_counter()
    reason = "time"
    step = 0
    scratch = Sensors()
    index = lay.decode_index

    def sample(qpos, qvel, act, row, t) -> str:
        """Record one sample; the stop rule's verdict."""
        if not (np.all(np.isfinite(qpos)) and np.all(np.isfinite(qvel))):
            return "diverged"
        s = decode(lay, row, t, scratch, loads(), index)
        buf.add(t, qpos, qvel, act, s, force_at(t), controller.state(),
                row[lay.actuator_force])
        return stop(s) if stop is not None else ""

    # the trip instant itself
    why = sample(d.qpos, d.qvel, d.act, d.sensordata, d.time - ctx.t0)
    nq, nv, na = m.nq, m.nv, m.na
    while not why and step < n_steps:
        decode(lay, d.sensordata, d.time - ctx.t0, ctx.sensors, loads(), index)
        plan = controller.update(ctx)
        n_block = min(period, n_steps - step)
        if controls is not None:
            gains = (m.actuator_gainprm[:, 0].copy(), m.actuator_biasprm[:, :3].copy())
            controls.append((step, d.ctrl.copy() if plan is None else plan[:n_block].copy(),
                             gains))
        if forcing and d.time - ctx.t0 > force_end_s:
            d.xfrc_applied[force_body] = 0.0
            forcing = False
        # instants of this block that are recorded
        first_rec = (step // rec_every + 1) * rec_every
        rec_at = list(range(first_rec - step, n_block + 1, rec_every))
        if plan is None and not forcing and observe is None and penalty is None:
            done = 0  # held controls: step natively from one sample to the next
            for k in [*rec_at, n_block]:
                if k <= done:
                    continue
                rows, _ = stepper.advance(k - done, None)
                done = k
                if k in rec_at:
                    why = sample(d.qpos, d.qvel, d.act, rows[-1], d.time - ctx.t0)
                    if why:
                        break
        else:
            ctrl = None if plan is None else plan[:n_block]
            rows, states = stepper.advance(n_block, ctrl, apply_force if forcing else None,
                                           want_rows=True, want_states=True)
            if observe is not None:
                observe(rows)
            for k in rec_at:
                st = states[k - 1]
                t = st[0] - ctx.t0
                why = sample(st[1:1 + nq], st[1 + nq:1 + nq + nv],
                             st[1 + nq + nv:1 + nq + nv + na], rows[k - 1], t)
                if why:
                    break
        step += n_block
        if not why and d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            why = "diverged"
    rec = buf.trimmed()
    rec.wall_time_s = time.perf_counter() - wall0
    rec.physics_time_s = stepper.physics_s
    rec.steps = step
    rec.stop_reason = why or reason
    rec.diverged = rec.stop_reason == "diverged"
    rec.controls = controls
    return rec
