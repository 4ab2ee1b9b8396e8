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

One exception to "controllers never step", made for speed: a controller whose blocks
are compiled (the reflex controllers' ``run_blocks``) may run several whole blocks in one
compiled call, stepping MuJoCo itself through this module's ``NativePhysics`` handle
exactly as ``mujoco.rollout`` steps a block (the same states and sensor rows, bit for
bit). ``run`` decides how many: only while nothing in them needs Python (no force, but
for one on in windows, ``next_on_s``, before its next window; no penalty contact or
strength model) and only before the stop rule's ``quiet_until_s``,
the time before which only a fall can end the run; the controller stops after any block
with a fall, a MuJoCo warning, a state not finite or a change of the foot the rule
watches (``FallGuard``). ``run`` then records and judges every sample of those blocks as
it does block by block. Why not a loop here that calls the controller's compiled block:
Numba cannot call a controller's compiled code from a generic, cached loop, and the
per-block Python it replaces was a third of a reflex walk's time (docs/speed.md, "Speed").
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from stumble.body import Body
from stumble.body.sensors import SensorLayout

RECORD_HZ = 200.0  # nearest whole number of steps: 250 Hz at 2 ms (every 2 steps)
CONTROL_HZ = 500.0  # default controller rate; the servos themselves run at every step
CONTACT_FORCE_MIN_N = 1.0  # a foot with less total normal force is not "on the floor"
_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
_CTRL = int(mujoco.mjtState.mjSTATE_CTRL)


class Sensors:
    """What controllers and the outcome read: one sensor row, decoded on access (SI).

    Without a row (``Sensors()``) it reads as a person standing on both feet.
    ``foot_normal_n`` overrides the feet's loads (the explicit ``penalty`` contact, whose
    forces MuJoCo does not see).
    """

    __slots__ = ("_v", "foot_normal_n", "lay", "row", "t")

    def __init__(self, lay: SensorLayout | None = None, row: np.ndarray | None = None,
                 t: float = 0.0, foot_normal_n: np.ndarray | None = None):
        self.set(lay, row, t, foot_normal_n)

    def set(self, lay: SensorLayout | None, row: np.ndarray | None, t: float,
            foot_normal_n: np.ndarray | None = None) -> Sensors:
        """Point at another row (no copy)."""
        self.lay, self.row, self.t, self.foot_normal_n = lay, row, t, foot_normal_n
        self._v = None
        return self

    @property
    def _values(self) -> np.ndarray:
        if self._v is None:
            self._v = (_STANDING if self.row is None
                       else self.row[self.lay.decode_index])
        return self._v

    @property
    def foot_force_n(self) -> dict[str, float]:
        """Vertical ground force on each foot (N)."""
        if self.foot_normal_n is not None:
            fr, fl = self.foot_normal_n
        else:
            v = self._values
            fr, fl = -v[0], -v[1]
        return {"r": float(fr), "l": float(fl)}

    @property
    def foot_on_floor(self) -> dict[str, bool]:
        """Each foot bears more than ``CONTACT_FORCE_MIN_N``."""
        f = self.foot_force_n
        return {"r": f["r"] > CONTACT_FORCE_MIN_N, "l": f["l"] > CONTACT_FORCE_MIN_N}

    @property
    def foot_on_obstacle(self) -> dict[str, bool]:
        """Each foot touches the obstacle."""
        if self.row is None or self.lay.obstacle_found is None:
            return {"r": False, "l": False}
        v = self._values
        return {"r": bool(v[2] > 0), "l": bool(v[3] > 0)}

    @property
    def segment_on_floor(self) -> bool:
        """A body other than the feet touches the floor (a fall)."""
        v = self._values
        return bool(v[4] - v[5] - v[6] > 0.5)

    com = property(lambda self: self._values[7:10], doc="Whole-body COM (m).")
    com_vel = property(lambda self: self._values[10:13], doc="COM velocity (m/s).")
    pelvis_height = property(lambda self: float(self._values[13]), doc="Pelvis height (m).")
    torso_z = property(lambda self: self._values[14:17], doc="Torso long axis (unit).")
    torso_angvel = property(lambda self: self._values[17:20], doc="Torso ω (rad/s, world).")
    foot_pos = property(lambda self: self._values[20:26].reshape(2, 3),
                        doc="Ankles (foot body origins), r and l (m).")
    sole = property(lambda self: self._values[26:50].reshape(2, 4, 3),
                    doc="Sole corners (2, 4, 3), r and l (m).")


# ``Sensors``' values a fall reads: the segments' floor contacts less the feet's (4, 5, 6)
# and the pelvis height (13)
FALL_VALUES = np.array([4, 5, 6, 13])


def fallen(lay: SensorLayout, rows: np.ndarray, fall_height_m: float) -> np.ndarray:
    """Per sensor row (n, nsensordata): a segment on the floor or the pelvis below
    ``fall_height_m`` (``Sensors.segment_on_floor``, ``pelvis_height``), vectorised."""
    v = rows[:, lay.decode_index[FALL_VALUES]]
    return (v[:, 0] - v[:, 1] - v[:, 2] > 0.5) | (v[:, 3] < fall_height_m)


# a person standing: both feet loaded, upright (what ``Sensors()`` reads without a row)
_STANDING = np.zeros(50)
_STANDING[[0, 1]] = -100.0
_STANDING[16] = 1.0


def decode(lay: SensorLayout, row: np.ndarray, t: float, out: Sensors | None = None,
           foot_normal_n: np.ndarray | None = None) -> Sensors:
    """``Sensors`` reading one sensor row (``out`` reused if given)."""
    return (out or Sensors()).set(lay, row, t, foot_normal_n)


def recorded(rec: Recording, lay: SensorLayout, k: int) -> Sensors:
    """The sensors of recorded sample ``k``."""
    return Sensors(lay, rec.sensordata[k], float(rec.time_s[k]))


@dataclass
class Context:
    """The physics state a controller acts on."""

    model: mujoco.MjModel
    data: mujoco.MjData
    body: Body
    sensors: Sensors
    t0: float  # data.time at the trip
    # the servos' torque limits by joint angle and velocity (stumble.body.strength),
    # refreshed every ``strength.period_s`` by ``run``; None: the fixed force ranges
    strength: object | None = None


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

    # Optional: ``run_blocks(physics, n, guard)`` runs up to ``n`` whole blocks, the
    # physics included, in one compiled call (``NativePhysics``): the numbers of ``update``,
    # a rollout of its controls and ``observe`` block by block, bit for bit. It returns
    # (states, sensor rows, controls, blocks run), or None where it cannot (``run`` then
    # goes on block by block); it may stop after any whole block, and must stop after
    # one in which ``guard`` says the run could end (``FallGuard``).


@dataclass(frozen=True)
class FallGuard:
    """What a compiled block loop checks after every step, to stop after that block:
    a segment on the floor or the pelvis below ``fall_height_m`` (``analysis.StopRule``'s
    fall); and, where ``foot_col`` is a sensor column (else −1), that foot's floor
    contact (its load beyond ``CONTACT_FORCE_MIN_N``) other than ``foot_on``, the stop
    rule's last (``analysis.TripTimer``). ``cols``: the sensor columns of ``Sensors``'
    values 4, 5, 6 (the segments' and the feet's floor contacts) and 13 (the pelvis
    height)."""

    cols: np.ndarray
    fall_height_m: float
    foot_col: int = -1
    foot_on: bool = False


class NativePhysics:
    """MuJoCo's step for a compiled loop: the addresses of ``mj_step`` and
    ``mj_getState``, of the model and data, and views of the data's controls, sensors
    and warning counters. ``native_physics`` builds it, or says why it cannot."""

    __slots__ = ("addr", "ctrl", "data", "nstate", "sensordata", "warnings")

    def __init__(self, addr: np.ndarray, data: mujoco.MjData, warnings: np.ndarray,
                 nstate: int):
        self.addr = addr  # int64: mj_step, mj_getState, model, data, the state's spec
        self.data = data  # kept alive while the views are used
        self.ctrl, self.sensordata = data.ctrl, data.sensordata
        self.warnings = warnings  # int32 (mjNWARNING, 2): lastinfo, number
        self.nstate = nstate


_LIB: dict = {}  # mj_step's and mj_getState's addresses, once per process

NATIVE_BLOCKS_MAX = 256  # blocks a compiled loop runs at most per call (its buffers' size)
_SCRATCH = threading.local()  # ``native_scratch``'s buffers, per thread and shape


def native_scratch(physics: NativePhysics, steps: int) -> tuple[np.ndarray, ...]:
    """Buffers for a compiled block loop of up to ``steps`` steps (states, sensor rows,
    controls), kept per thread and shape, not per controller (a controller's deep copy
    need not copy them): what a ``run_blocks`` returns is good until the next call."""
    kept = getattr(_SCRATCH, "bufs", None)
    if kept is None:
        kept = _SCRATCH.bufs = {}
    key = (steps, physics.nstate, len(physics.sensordata), len(physics.ctrl))
    got = kept.get(key)
    if got is None:
        got = kept[key] = (np.empty((steps, key[1])), np.empty((steps, key[2])),
                           np.empty((steps, key[3])))
    return got


def _mujoco_functions() -> tuple[int, int] | None:
    """The addresses of ``mj_step`` and ``mj_getState`` in the MuJoCo library the
    bindings load, or None (not found)."""
    if "fns" not in _LIB:
        import ctypes
        import glob
        import os

        fns = None
        here = os.path.dirname(mujoco.__file__)
        for path in sorted(glob.glob(os.path.join(here, "libmujoco.so*"))
                           + glob.glob(os.path.join(here, "libmujoco*.dylib"))
                           + glob.glob(os.path.join(here, "mujoco.dll"))):
            try:
                lib = ctypes.CDLL(path)
                fns = tuple(ctypes.cast(getattr(lib, f), ctypes.c_void_p).value
                            for f in ("mj_step", "mj_getState"))
                break
            except (OSError, AttributeError):
                continue
        _LIB["fns"] = fns
    return _LIB["fns"]


def _warning_offset() -> int:
    """Where ``mjData.warning`` sits in the struct, by the layout of the fields before it
    in MuJoCo's header (``mjdata.h``, MuJoCo 3.3-4.0)."""
    import ctypes

    class _Solver(ctypes.Structure):
        _fields_ = [("improvement", ctypes.c_double), ("gradient", ctypes.c_double),
                    ("lineslope", ctypes.c_double), ("nactive", ctypes.c_int),
                    ("nchange", ctypes.c_int), ("neval", ctypes.c_int),
                    ("nupdate", ctypes.c_int)]

    n_island, n_solver = 20, 200  # mjNISLAND, mjNSOLVER (mjmodel.h)

    class _Head(ctypes.Structure):
        _fields_ = [("narena", ctypes.c_int64), ("nbuffer", ctypes.c_int64),
                    ("nplugin", ctypes.c_int), ("pstack", ctypes.c_size_t),
                    ("pbase", ctypes.c_size_t), ("parena", ctypes.c_size_t),
                    ("threadpool", ctypes.c_size_t), ("threadlock", ctypes.c_bool),
                    ("maxuse_stack", ctypes.c_int64), ("maxuse_arena", ctypes.c_int64),
                    ("maxuse_con", ctypes.c_int), ("maxuse_efc", ctypes.c_int),
                    ("solver", _Solver * (n_island * n_solver)),
                    ("solver_niter", ctypes.c_int * n_island),
                    ("solver_nnz", ctypes.c_int * n_island),
                    ("solver_fwdinv", ctypes.c_double * 2),
                    ("warning", ctypes.c_int)]

    return _Head.warning.offset


def _warning_view(d: mujoco.MjData) -> np.ndarray | None:
    """An int32 view (mjNWARNING, 2: lastinfo, number) of ``d``'s warning counters
    (``_warning_offset``), checked once a process by writing through the bindings and
    reading through the view; None where that does not check out (another layout)."""
    import ctypes

    n = len(d.warning)
    if "warning_offset" not in _LIB:
        _LIB["warning_offset"] = _warning_offset()
        _LIB["warning_ok"] = None
    try:
        view = np.ctypeslib.as_array((ctypes.c_int32 * (2 * n)).from_address(
            d._address + _LIB["warning_offset"])).reshape(n, 2)
    except (AttributeError, ValueError, TypeError):
        return None
    if _LIB["warning_ok"] is None:
        kept = [(w.lastinfo, w.number) for w in d.warning]
        ok = True
        for trial in (1, 2):
            for i, w in enumerate(d.warning):
                w.lastinfo, w.number = 7919 * trial + i, 104729 * trial + i
            ok = ok and all(int(view[i, 0]) == 7919 * trial + i
                            and int(view[i, 1]) == 104729 * trial + i for i in range(n))
        for w, (a, b) in zip(d.warning, kept, strict=True):
            w.lastinfo, w.number = a, b
        _LIB["warning_ok"] = ok
    return view if _LIB["warning_ok"] else None


def native_physics(m: mujoco.MjModel, d: mujoco.MjData) -> NativePhysics | None:
    """``NativePhysics`` of ``m`` and ``d``, or None where a compiled loop cannot step
    them as ``mujoco.rollout`` does (no MuJoCo library found, another ``mjData``
    layout, or mocap bodies or equality constraints, which a rollout resets)."""
    fns = _mujoco_functions()
    if fns is None or m.nmocap or m.neq:
        return None
    warnings = _warning_view(d)
    if warnings is None:
        return None
    addr = np.array([fns[0], fns[1], m._address, d._address, int(_STATE)], dtype=np.int64)
    return NativePhysics(addr, d, warnings, mujoco.mj_stateSize(m, _STATE))


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
    sensordata: np.ndarray | None = None  # (T, nsensordata) the raw sensor rows
    steps: int = 0
    wall_time_s: float = 0.0
    cpu_time_s: float = 0.0  # this process' CPU time in the loop (less load-dependent)
    physics_time_s: float = 0.0  # of which inside MuJoCo (wall)
    diverged: bool = False
    stop_reason: str = ""
    controls: list | None = None  # (first step, ctrl rows, gains) per block, if logged
    forces: list | None = None  # (step, body, xfrc_applied row) per forced step, if logged
    initial_state: np.ndarray | None = None  # full physics state after start, if logged


@dataclass
class _Buffers:
    """Pre-allocated raw samples (state and sensor rows); decoded in bulk at the end."""

    n: int
    model: mujoco.MjModel
    nstate: int
    nsens: int
    k: int = 0

    def __post_init__(self) -> None:
        self.time = np.zeros(self.n)
        self.states = np.zeros((self.n, self.nstate))
        self.rows = np.zeros((self.n, self.nsens))
        self._runs: list[tuple[int, str]] = []  # (first sample, state name) per change

    def _name(self, k: int, name: str) -> None:
        if not self._runs or self._runs[-1][1] != name:
            self._runs.append((k, name))

    def add(self, t: float, state: np.ndarray, row: np.ndarray, name: str) -> None:
        k = self.k
        self.time[k], self.states[k], self.rows[k] = t, state, row
        self._name(k, name)
        self.k = k + 1

    def extend(self, t: np.ndarray, states: np.ndarray, rows: np.ndarray, name: str) -> None:
        """``add`` of several samples at once."""
        k, n = self.k, len(t)
        self.time[k:k + n], self.states[k:k + n], self.rows[k:k + n] = t, states, rows
        if n:
            self._name(k, name)
        self.k = k + n

    def truncate(self, n: int) -> None:
        """Keep the first ``n`` samples."""
        self.k = n
        while self._runs and self._runs[-1][0] >= n:
            self._runs.pop()

    @property
    def names(self) -> list[str]:
        """Each sample's state name."""
        ends = [k for k, _ in self._runs[1:]] + [self.k]
        return [name for (k0, name), k1 in zip(self._runs, ends, strict=True)
                for _ in range(k1 - k0)]

    def recording(self, lay: SensorLayout, force: Callable | None, loads) -> Recording:
        """The samples as a ``Recording`` (vectorised decoding of the sensor rows)."""
        m, k = self.model, self.k
        nq, nv, na = m.nq, m.nv, m.na
        st, rows, t = self.states[:k], self.rows[:k], self.time[:k]
        fz = -rows[:, lay.foot_force[:, 2]] if loads is None else loads[:k]
        seg = rows[:, lay.floor_found] - rows[:, lay.foot_found].sum(axis=1) > 0.5
        ob = (np.zeros((k, 2), bool) if lay.obstacle_found is None
              else rows[:, lay.obstacle_found] > 0)
        trip = np.zeros((k, 3)) if force is None else np.array([force(x) for x in t]
                                                               ).reshape(k, 3)
        return Recording(t.copy(), st[:, 1:1 + nq].copy(), st[:, 1 + nq:1 + nq + nv].copy(),
                         rows[:, lay.com].copy(), rows[:, lay.com_vel].copy(),
                         fz > CONTACT_FORCE_MIN_N, ob, trip, self.names, seg,
                         rows[:, lay.actuator_force].copy(),
                         st[:, 1 + nq + nv:1 + nq + nv + na].copy(), fz.copy(),
                         sensordata=rows.copy())


class _Stepper:
    """Advances MuJoCo by held or per-step controls; returns the sensor rows it saw."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, penalty=None):
        self.m, self.d, self.penalty = m, d, penalty
        self.nstate = mujoco.mj_stateSize(m, _STATE)
        self.state0 = np.zeros((1, self.nstate))
        self.warm0 = np.zeros((1, m.nv))
        self._pool = mj_rollout.Rollout(nthread=0)
        self._out: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # rollout outputs per n
        self.physics_s = 0.0
        # the rollout's start: views made once (each access of a data field makes one)
        self._state0_row, self._warm0_row = self.state0[0], self.warm0[0]
        self._warm_now = d.qacc_warmstart

    def state_now(self) -> np.ndarray:
        """The full-physics state now (a new array)."""
        out = np.zeros(self.nstate)
        mujoco.mj_getState(self.m, self.d, out, _STATE)
        return out

    def hold(self, n: int) -> None:
        """``n`` native steps with the controls held (``mj_step`` with nstep)."""
        tic = time.perf_counter()
        mujoco.mj_step(self.m, self.d, n)
        self.physics_s += time.perf_counter() - tic

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
            mujoco.mj_getState(m, d, self._state0_row, _STATE)
            self._warm0_row[:] = self._warm_now
            out = self._out.get(n)
            if out is None:  # reused: the caller is done with a block's rows
                st, rw = np.empty((1, n, self.nstate)), np.empty((1, n, m.nsensordata))
                out = self._out[n] = (st, rw, [m], [d], st[0], rw[0])
            states, rows, ms, ds, states0, rows0 = out
            self._pool.rollout_.rollout(ms, ds, n, _CTRL, self.state0, self.warm0, ctrl,
                                        states, rows, None)
            states, rows = states0, rows0
        self.physics_s += time.perf_counter() - tic
        return rows, states


def _quiet_blocks(stop, guard: FallGuard | None, lay: SensorLayout, t_now: float,
                  blocks_left: int, block_s: float) -> tuple[int, FallGuard | None]:
    """How many whole blocks a compiled loop may run from ``t_now`` (s since the trip):
    every sample of them before the stop rule's ``quiet_until_s`` (0 when the rule has
    none), at most ``blocks_left``; and the guard it checks, with the foot the rule
    watches (``watch_foot``: side 0 right / 1 left, its contact at the last sample)."""
    quiet_s = np.inf if stop is None else getattr(stop, "quiet_until_s", None)
    if quiet_s is None:
        return 0, guard
    watch = getattr(stop, "watch_foot", None)
    if watch is not None and guard is not None:
        guard = FallGuard(guard.cols, guard.fall_height_m,
                          int(lay.decode_index[watch[0]]), bool(watch[1]))
    fit = int((min(quiet_s, 1e9) - t_now) / block_s) - 1
    return min(blocks_left, fit), guard


def run(ctx: Context, controller: Controller, duration_s: float,
        trip_force: Callable[[float], np.ndarray] | None = None, force_body: int = -1,
        force_point: Callable[[mujoco.MjData], np.ndarray] | None = None,
        stop: Callable[[Sensors], str] | None = None, penalty=None,
        log_controls: bool = False, resume: bool = False) -> Recording:
    """Step physics from the trip for up to ``duration_s``; returns the recording.

    ``stop(sensors)`` sees every sample and returns a non-empty reason to stop.
    ``log_controls``: keep every block's controls and servo gains (for benchmarks that
    replay them on a bare loop). ``resume``: the controller goes on from an earlier run
    on the same data (its delays and state kept), not started again.
    """
    m, d, body = ctx.model, ctx.data, ctx.body
    lay = body.sensors
    dt = m.opt.timestep
    n_steps = round(duration_s / dt)
    rec_every = max(1, round(1.0 / (RECORD_HZ * dt)))
    stepper = _Stepper(m, d, penalty)
    buf = _Buffers(n_steps // rec_every + 1, m, stepper.nstate, m.nsensordata)
    sides = {0: "r", 1: "l"}
    if penalty is not None:
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in penalty.body_ids]
        penalty.side_index = np.array([0 if n.endswith("_r") else 1 for n in names])
    load_log: list[np.ndarray] | None = [] if penalty is not None else None

    def loads() -> np.ndarray | None:
        if penalty is None:
            return None
        return np.array([penalty.force[penalty.side_index == k, 2].sum() for k in sides])

    mujoco.mj_forward(m, d)
    if penalty is not None:
        penalty.apply(d)
    decode(lay, d.sensordata, d.time - ctx.t0, ctx.sensors, loads())
    if not resume:
        controller.start(ctx)
    period = max(1, int(getattr(controller, "period_steps", 0)
                        or round(1.0 / (CONTROL_HZ * dt))))
    observe = getattr(controller, "observe", None)
    forcing = trip_force is not None and force_body >= 0
    force_end_s = getattr(trip_force, "t_trip_s", duration_s)
    active = getattr(trip_force, "active", None)
    no_force = np.zeros(3)

    def force_at(t: float) -> np.ndarray:
        return trip_force(t) if trip_force is not None and 0.0 <= t <= force_end_s else no_force

    controls = [] if log_controls else None
    forces = [] if log_controls else None
    cpu0 = time.process_time()

    def apply_force(dd: mujoco.MjData) -> None:
        f = force_at(dd.time - ctx.t0)
        p = force_point(dd)
        dd.xfrc_applied[force_body, :3] = f
        dd.xfrc_applied[force_body, 3:] = np.cross(p - dd.xipos[force_body], f)
        if forces is not None:
            forces.append((round((dd.time - ctx.t0) / dt), force_body,
                           dd.xfrc_applied[force_body].copy()))

    wall0 = time.perf_counter()
    reason = "time"
    step = 0
    scratch = Sensors()
    now = np.zeros(stepper.nstate)
    sensordata = d.sensordata
    # MuJoCo's instability warnings (it resets the state and carries on after them)
    w_pos, w_vel, w_acc = (d.warning[int(w)] for w in (mujoco.mjtWarning.mjWARN_BADQPOS,
                                                       mujoco.mjtWarning.mjWARN_BADQVEL,
                                                       mujoco.mjtWarning.mjWARN_BADQACC))

    def unstable() -> bool:
        return bool(w_pos.number or w_vel.number or w_acc.number)

    def sample(state: np.ndarray, row: np.ndarray) -> str:
        """Record one sample (a full-physics state and its sensor row); the stop rule's
        verdict on it."""
        if not np.isfinite(state).all():
            return "diverged"
        t = float(state[0]) - ctx.t0
        buf.add(t, state, row, controller.state())
        f = loads()
        if load_log is not None:
            load_log.append(f)
        return stop(scratch.set(lay, row, t, f)) if stop is not None else ""

    stop_block = getattr(stop, "block", None) if stop is not None else None

    def sample_block(states: np.ndarray, rows: np.ndarray, first: int, end: int) -> str:
        """``sample`` of every recorded instant among the steps after ``first`` up to
        ``end`` of a stepped block (its per-step states and rows), in bulk; the first
        stop reason."""
        nonlocal next_rec
        if next_rec > end:
            return ""
        pick = slice(next_rec - first - 1, end - first, rec_every)
        st, rw = states[pick], rows[pick]
        n = len(st)
        next_rec += rec_every * n
        n_ok = n if np.isfinite(st).all() else int(np.isfinite(st).all(axis=1).argmin())
        k0 = buf.k
        t = st[:n_ok, 0] - ctx.t0
        buf.extend(t, st[:n_ok], rw[:n_ok], controller.state())
        if stop_block is not None:  # the rule's own loop over the samples
            j, why = stop_block(lay, rw[:n_ok], t)
            if why:
                buf.truncate(k0 + j + 1)
                return why
        elif stop is not None:
            for j in range(n_ok):
                why = stop(scratch.set(lay, rw[j], float(t[j])))
                if why:
                    buf.truncate(k0 + j + 1)
                    return why
        return "" if n_ok == n else "diverged"

    def sample_now() -> str:
        """``sample`` of the current state (held controls: no finiteness scan, MuJoCo's
        warnings say when the state went bad)."""
        mujoco.mj_getState(m, d, now, _STATE)
        t = float(now[0]) - ctx.t0
        buf.add(t, now, sensordata, controller.state())
        return stop(scratch.set(lay, sensordata, t)) if stop is not None else ""

    # the trip instant itself
    initial_state = stepper.state_now()
    why = sample(initial_state, sensordata)
    uses_sensors = getattr(controller, "uses_sensors", True)
    next_rec = rec_every
    strength = ctx.strength
    strength_every = max(1, round(strength.period_s / dt)) if strength is not None else 0
    next_strength = 0
    # several whole blocks in one compiled call (``Controller.run_blocks``) where nothing
    # in them needs Python: no force, penalty or strength, a stop rule that only a fall
    # can trigger until ``quiet_until_s`` (``FallGuard``)
    run_blocks = getattr(controller, "run_blocks", None)
    native = (native_physics(m, d) if run_blocks is not None and penalty is None
              and strength is None and not uses_sensors else None)
    guard = None
    if native is not None and stop is not None:
        fall_h = getattr(stop, "fall_height_m", None)
        guard = (None if fall_h is None else
                 FallGuard(np.asarray(lay.decode_index)[FALL_VALUES].astype(np.int64),
                           float(fall_h)))
        if guard is None:
            native = None
    next_on = getattr(trip_force, "next_on_s", None)  # a force on in windows (pushes)
    while not why and step < n_steps:
        if native is not None and (not forcing or next_on is not None):
            t_now = d.time - ctx.t0
            n_run, guard = _quiet_blocks(stop, guard, lay, t_now, (n_steps - step) // period,
                                         period * dt)
            if forcing:  # whole blocks before the force's next window
                n_run = min(n_run, int((min(next_on(t_now), 1e9) - t_now) / (period * dt)) - 1)
            got = None
            if n_run >= 1:
                tic = time.perf_counter()
                d.xfrc_applied[:] = 0.0  # (as a rollout of the blocks does)
                d.qfrc_applied[:] = 0.0
                got = run_blocks(native, n_run, guard)
            if got is not None:
                stepper.physics_s += time.perf_counter() - tic  # (the controller's too)
                states, rows, ctrls, done = got
                end = step + done * period
                if controls is not None:
                    gains = (m.actuator_gainprm[:, 0].copy(), m.actuator_biasprm[:, :3].copy(),
                             m.actuator_forcerange.copy())
                    controls += [(step + i * period, ctrls[i * period:(i + 1) * period].copy(),
                                  gains) for i in range(done)]
                why = sample_block(states, rows, step, end)
                step = end
                if not why and unstable():
                    why = "diverged"
                continue
        if uses_sensors:
            decode(lay, sensordata, d.time - ctx.t0, ctx.sensors, loads())
        plan = controller.update(ctx)
        if strength is not None and step >= next_strength:
            strength.apply(m, d)
            next_strength = step + strength_every
        n_block = min(period, n_steps - step)
        if controls is not None:
            gains = (m.actuator_gainprm[:, 0].copy(), m.actuator_biasprm[:, :3].copy(),
                     m.actuator_forcerange.copy())
            controls.append((step, d.ctrl.copy() if plan is None else plan[:n_block].copy(),
                             gains))
        if forcing and d.time - ctx.t0 > force_end_s:
            d.xfrc_applied[force_body] = 0.0
            forcing = False
        # a force that says it is off over this whole block (``active(t0, t1)``, as
        # pelvis pushes do between their windows) lets the block step natively
        pushing = forcing and (active is None or active(d.time - ctx.t0,
                                                        d.time - ctx.t0 + n_block * dt))
        if forcing and not pushing:
            d.xfrc_applied[force_body] = 0.0
        end = step + n_block
        if plan is None and not pushing and observe is None and penalty is None:
            # held controls: step natively from one recorded instant to the next
            while step < end:
                nxt = min(next_rec, end)
                stepper.hold(nxt - step)
                step = nxt
                if unstable():
                    why = "diverged"
                    break
                if step == next_rec:
                    next_rec += rec_every
                    why = sample_now()
                    if why:
                        break
        else:
            ctrl = None if plan is None else plan[:n_block]
            rows, states = stepper.advance(n_block, ctrl, apply_force if pushing else None,
                                           want_rows=True, want_states=True)
            if observe is not None:
                observe(rows)
            if penalty is None:
                why = sample_block(states, rows, step, end)
            while penalty is not None and next_rec <= end:  # (each sample its loads)
                k, next_rec = next_rec - step, next_rec + rec_every
                why = sample(states[k - 1], rows[k - 1])
                if why:
                    break
            step = end
            if not why and unstable():
                why = "diverged"
    rec = buf.recording(lay, force_at if trip_force is not None else None,
                        None if load_log is None else np.array(load_log))
    rec.wall_time_s = time.perf_counter() - wall0
    rec.cpu_time_s = time.process_time() - cpu0
    rec.physics_time_s = stepper.physics_s
    rec.steps = step
    rec.stop_reason = why or reason
    rec.diverged = rec.stop_reason == "diverged"
    rec.controls = controls
    rec.forces = forces
    rec.initial_state = initial_state if log_controls else None
    return rec
