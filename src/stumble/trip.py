"""The trip: when and how the swing foot is stopped (SCA 2009 §4.2-4.3).

A ``Scenario`` names the tripped leg, the instant as a fraction of that leg's swing,
the walking speed and the mechanism:

- ``force``: the tripping forces of SCA 2009 eq. 2-3 on the swing toe;
- ``obstacle``: a rigid box on the path, placed so the swing toe strikes it at the
  requested swing fraction; foot and box collide physically and the box stays.

and where the walk before the trip comes from (``start``):

- ``playback``: the recorded walk is played back up to the trip instant and the
  controller takes over there (SCA 2009 §4.3; seed 003 §IV.B, whose CASE 1 and CASE 2
  are instants of the recording);
- ``own``: the controller takes over from the played-back walk at right heel strike,
  walks ``walk_in_s`` on its own, and the trip comes at the requested fraction of its
  own next swing of the tripped leg (the fraction of the mean of its last two swings).
  A walker's response to a trip then starts from its own gait, as a person's does; a
  reflex walker that takes over at an arbitrary instant of someone else's stride falls
  without any trip (GH2010, 14 of 15 instants, docs/reflex.md "Where the walk before a
  reflex trip comes from").

It also says what a scenario's seed does to the initial state (``perturb_initial_state``)
and which servo strength its body, age group and scale get (``servo_strength``).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from stumble.errors import InputError, TripNotSet
from stumble.gait.reference import check_speed

if TYPE_CHECKING:
    from stumble.body import Body
    from stumble.body.strength import Strength

# SCA 2009 §4.3, after Pijnappels et al. 2004 (inverse dynamics and force plates).
FX_MAX_N = 170.0  # SCA 2009 eq. 2: peak horizontal (backward) tripping force
FZ_MAX_N = 70.0  # SCA 2009 eq. 3: peak vertical tripping force
T_TRIP_S = 0.114  # SCA 2009 §4.3: collision duration
# Eq. 2 as printed, exp(-(t - T_c)^2 / (T_trip/6)), divides a squared time by a time
# and is not dimensionless; its Figure 5 shows a bell that rises and falls within
# T_trip. We read it as a Gaussian of standard deviation T_trip/6 (±3σ spans the
# collision), the natural reading; ``sigma_s`` is a parameter.
SIGMA_OVER_T_TRIP = 1.0 / 6.0

SWING_RANGE = (0.05, 0.9)  # the range of trip instants (fraction of swing)
OBSTACLE_HEIGHT_M = 0.10  # default; trip experiments used 8 and 14 cm (reference README)
OBSTACLE_DEPTH_M = 0.10  # along the walking direction (our choice)
OBSTACLE_GAP_M = 0.002  # the obstacle's near face this far ahead of the toe at the trip
OBSTACLE_WIDTH_M = 0.14  # across: the tripped foot's lane only, as the pop-up obstacles
# of trip experiments (Schillings et al. 2000; Pijnappels et al. 2004); a wide board would
# lie under the stance foot for trips before mid swing (our choice)
MECHANISMS = ("force", "obstacle")
LEGS = ("left", "right")
# SCA 2009 state machines; seed 003's reflex network; Geyer & Herr 2010's reflexes
CONTROLLERS = ("fsm", "reflex", "gh2010")
MUSCLE_CONTROLLERS = ("reflex", "gh2010")  # on the planar musculoskeletal body
MAX_SEED = 2**63 - 1  # seeds are stored as 64-bit integers (study results)
# Physics step (s) when a scenario names none. The state machines: 2 ms gives the 1 ms
# outcome (recovered or fell) in all 48 trips of the grid and the same strategy, variant
# and outcome in 45 (docs/trips.md "Trips"). The seed's network: 2 ms (its 1 ms ticks two to a
# step, ``network.tick_ratio``) gives the 1 ms strategy and outcome in all 45 trips of
# the strategy map from the recording and in 42 of the 45 in its own gait (0.5 ms: 43),
# and its walks within 0.3 deg RMSE (docs/speed.md "Speed"); its fits keep 1 ms
# (``fit_walk.FIT_TIMESTEP_S``). GH2010: the step its set was fitted at
# (``GH2010Params.timestep_s``), 2 ms for the shipped default (``knee-2ms-dense-wide-s3``;
# a test holds the two equal).
DEFAULT_TIMESTEP_S = {"fsm": 0.002, "reflex": 0.002, "gh2010": 0.002}
TIMESTEP_RANGE_S = (0.0002, 0.005)  # any controller
# The largest step at which each controller is stable (s). The state machines: on four
# trips the support ankle peaks at 5.7 rad/s at 1 ms, 12 at 2 ms, 48 at 3 ms (chatter;
# 339 rad/s at 5 ms), so 2 ms. The reflex controllers' own rules (the network's tick,
# ``check_gh2010_timestep``) are checked in ``Scenario.validated``.
MAX_TIMESTEP_S = {"fsm": 0.002}
STARTS = ("playback", "own")
# where each controller's walk before the trip comes from when a scenario names none:
# the state machines from the recording (they do not walk on their own); both reflex
# walkers from their own gait, where they recover (issue 9; the seed's network was from
# the recording until 2026-12-06: seed 003's CASE 1 and CASE 2 are instants of its
# recording, ``start="playback"``, where no network recovers)
DEFAULT_START = {"fsm": "playback", "reflex": "own", "gh2010": "own"}
WALK_IN_S = 4.0  # own start: seconds walked before the trip's swing (our choice: GH2010's
# stride settles within two strides of taking over)
WALK_IN_RANGE_S = (2.0, 30.0)


@dataclass(frozen=True)
class Population:
    """A preset of who trips: the strength table's age group, latencies added to the
    state machines' responses (s, by ``FSMParams.latency_s`` key), the preferred walking
    speed (m/s, the default speed of ``stumble trip`` and ``stumble study``) and how much
    longer their torque takes to build once a muscle is active (a factor on
    ``FSMParams.activation_to_torque_s``)."""

    age: str
    extra_latency_s: dict
    preferred_speed_m_per_s: float
    sources: str
    activation_scale: float = 1.0


# Older adults develop joint torque more slowly: Thelen, Schultz, Alexander & Ashton-Miller
# 1996 (J Gerontol A 51:M226) measured maximal rates of isometric ankle torque development
# 25-36 % lower in healthy old (72 y) than young (23 y) adults. We take the middle, 30 %,
# and read it as the time to a given torque 1/(1 - 0.30) = 1.43 times as long: the state
# machines' activation-to-torque interval (SCA 2009's 50 ms) becomes 71 ms (our choice
# of how to carry their figure over; ``Population.activation_scale``).
OLDER_RTD_DROP = 0.30


POPULATIONS = {
    # the project's default body and speeds (the recorded subject walks 1.2 m/s)
    "young": Population("young", {}, 1.2, "Anderson et al. 2007 (18-25 y)"),
    # healthy older adults: strength, Anderson et al. 2007 (> 65 y); the support limb's
    # responses, Pijnappels, Bobbert & van Dieen 2005 (Exp Brain Res 160:326: 60-80 ms in
    # young and older alike, soleus 11 ms later in the older); preferred speed, Tirosh &
    # Sparrow 2004 (69 y: 1.17 m/s against 1.29 m/s at 25 y); slower torque development,
    # Thelen et al. 1996 (OLDER_RTD_DROP)
    "older": Population("older", {"sup.ankle_angle": 0.011}, 1.17,
                        "Anderson et al. 2007 (> 65 y); Pijnappels et al. 2005 (EBR); "
                        "Tirosh & Sparrow 2004; Thelen et al. 1996",
                        activation_scale=1.0 / (1.0 - OLDER_RTD_DROP)),
}
STRENGTH_MODELS = ("anderson2007", "fixed")  # stumble.body.strength
RECOVERY_RULES = ("step", "walk_on")  # Scenario.recovery
# physics after the trip when the scenario names none (Scenario.duration_after_trip_s):
# the state machines walking on, 6 s (issue 11: walking on until the time budget ends,
# default 6 s after the trip); otherwise 3 s (the reflex controllers' "still walking 3 s
# after the trip", issue 9; the 1 s rule stops 1 s after the recovery step anyway)
# what ``Scenario.delay_scale`` multiplies (``Scenario.delays``)
DELAYS = ("all", "response")
WALK_ON_DURATION_S = 6.0
DURATION_S = 3.0


GH2010_MAX_STEP_S = 0.001  # the step of a GH2010 set that names none (``fitted_s``)


def check_gh2010_timestep(timestep_s: float, fitted_s: float = GH2010_MAX_STEP_S) -> None:
    """InputError unless the time step divides the step the GH2010 set was fitted at
    (``GH2010Params.timestep_s``; 1 ms for every shipped set but the ``knee-2ms`` ones,
    and the default for a set that names none): a set's trip outcomes are
    those of the step it was fitted at (docs/speed.md "Speed": at 2 ms the 1 ms sets walk alike
    but recover 22 of the 45 trips instead of 26, 29 of the 45 the same)."""
    n = round(fitted_s / timestep_s)
    if timestep_s > fitted_s + 1e-12 or abs(n * timestep_s - fitted_s) > 1e-9:
        raise InputError(f"the gh2010 controller needs a time step that divides "
                         f"{1e3 * fitted_s:g} ms (its gains were fitted at "
                         f"{1e3 * fitted_s:g} ms), got {1e3 * timestep_s:g} ms")


@dataclass(frozen=True)
class TripForce:
    """SCA 2009 eq. 2-3: backward Gaussian and vertical sine on the swing toe, in N.

    F_x(t) = -F_x^max exp(-(t - T_c)² / (2σ²)),  F_z(t) = F_z^max sin(2π t / T_trip),
    for 0 <= t <= T_trip after the collision, zero otherwise; T_c = T_trip / 2.
    """

    fx_max_n: float = FX_MAX_N
    fz_max_n: float = FZ_MAX_N
    t_trip_s: float = T_TRIP_S
    sigma_s: float = T_TRIP_S * SIGMA_OVER_T_TRIP

    def __call__(self, t_s: np.ndarray | float) -> np.ndarray:
        """(…, 3) force in world axes at ``t_s`` seconds after the collision."""
        t = np.asarray(t_s, dtype=float)
        inside = (t >= 0.0) & (t <= self.t_trip_s)
        tc = 0.5 * self.t_trip_s  # SCA 2009 §4.3: T_c = 0.5 T_trip
        fx = -self.fx_max_n * np.exp(-((t - tc) ** 2) / (2.0 * self.sigma_s**2))
        fz = self.fz_max_n * np.sin(2.0 * np.pi * t / self.t_trip_s)
        out = np.zeros((*t.shape, 3))
        out[..., 0] = np.where(inside, fx, 0.0)
        out[..., 2] = np.where(inside, fz, 0.0)
        return out

    def impulse_ns(self) -> np.ndarray:
        """Impulse (N·s) of the whole collision, x and z."""
        t = np.linspace(0.0, self.t_trip_s, 2001)
        return np.trapezoid(self(t), t, axis=0)


class PelvisPushes:
    """Horizontal forces on the pelvis (N, + forward) over windows of the walk: ``pushes``
    of (start s, duration s, force N), from the controller's start; the sum of those on
    at ``t`` (a ``sim.run`` trip force, applied at the pelvis's centre of mass)."""

    def __init__(self, pushes) -> None:
        self.pushes = tuple((float(a), float(b), float(f)) for a, b, f in pushes)
        for a, b, f in self.pushes:
            if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(f) and a >= 0 and b > 0):
                raise InputError(f"a push ({a}, {b}, {f}) needs a start >= 0 s, a duration "
                                 "> 0 s and a finite force (N)")
        self.t_trip_s = max((a + b for a, b, _f in self.pushes), default=0.0)

    def __call__(self, t: float) -> np.ndarray:
        return np.array([sum(f for a, b, f in self.pushes if a <= t < a + b), 0.0, 0.0])

    def active(self, t0: float, t1: float) -> bool:
        """Whether any push is on within [t0, t1] (s): outside, the loop steps natively."""
        return any(a <= t1 and t0 < a + b for a, b, _f in self.pushes)

    def next_on_s(self, t: float) -> float:
        """The first time from ``t`` (s) at which a push is on (inf: none left): before
        it, whole blocks may run in one compiled call (``sim.run``)."""
        return min((max(a, t) for a, b, _f in self.pushes if t < a + b), default=np.inf)


@dataclass(frozen=True)
class Scenario:
    """One trip: who, when, how fast, by what. SI units; degrees only at the edges."""

    swing_fraction: float = 0.2
    speed_m_per_s: float = 1.2
    leg: str = "left"
    mechanism: str = "force"
    obstacle_height_m: float = OBSTACLE_HEIGHT_M
    controller: str = "fsm"
    strategy: str = "auto"
    seed: int = 0
    height_m: float = 1.75
    mass_kg: float = 70.0
    sex: str = "male"
    contact: str = "lumped"
    # seconds of physics after the trip at most; None: WALK_ON_DURATION_S for the state
    # machines walking on, DURATION_S otherwise (``resolved``)
    duration_after_trip_s: float | None = None
    delay_scale: float = 1.0  # multiplies every response latency
    # which latencies ``delay_scale`` multiplies (``DELAYS``; ours, a parameter): all,
    # every delay of the controller (the reflex controllers' nerves and reflex loops,
    # their walk-in too: the default), or response, only those of the response to the
    # trip (the reflex controllers' touch response: the network's ``TouchResponse``,
    # Geyer & Herr's stumbling corrective reflex and crossing step), the walk's reflexes
    # at their own delays. The state machines' delays are all their response's: for
    # them the two are the same
    delays: str = "all"
    strength_scale: float = 1.0  # multiplies every servo torque limit and muscle F_max
    # servo torque limits: fixed (build.TORQUE_LIMIT_NM × build.body_scale, the default
    # until the state machines are retuned on human strength) or anderson2007 (hip, knee
    # and ankle by angle and velocity, stumble.body.strength; docs/trips.md "Human strength")
    strength_model: str = "fixed"
    population: str = "young"  # POPULATIONS: young or older
    # what "recovered" means for the state machines: walk_on (the default since
    # 2026-12-03, issue 11: still walking upright at the end of duration_after_trip_s,
    # at least 4 steps after the recovery step, as the reflex controllers walk on) or
    # step (1 s after the recovery step the trunk is upright and the COM over the feet,
    # the run stopping there: the default before)
    recovery: str = "walk_on"
    timestep_s: float | None = None  # physics step; None: the controller's (DEFAULT_TIMESTEP_S)
    start: str | None = None  # playback or own (module docstring); None: DEFAULT_START
    walk_in_s: float = WALK_IN_S  # own start: walked before the trip's swing (s)
    force: TripForce = field(default_factory=TripForce)

    def resolved(self, gh2010_step_s: float | None = None) -> Scenario:
        """The scenario with the controller's default time step (``gh2010_step_s``: the
        step the GH2010 set to be run was fitted at, default the shipped default set's),
        start and duration if it names none."""
        sc = self
        if sc.timestep_s is None and sc.controller == "gh2010" and gh2010_step_s:
            sc = replace(sc, timestep_s=gh2010_step_s)
        if sc.duration_after_trip_s is None:
            walk_on = sc.controller == "fsm" and sc.recovery == "walk_on"
            sc = replace(sc, duration_after_trip_s=WALK_ON_DURATION_S if walk_on
                         else DURATION_S)
        if sc.timestep_s is None:
            sc = replace(sc, timestep_s=DEFAULT_TIMESTEP_S.get(sc.controller, 0.001))
        if sc.start is None:
            sc = replace(sc, start=DEFAULT_START.get(sc.controller, "playback"))
        return sc

    def validated(self, gh2010_step_s: float | None = None) -> Scenario:
        """The scenario with its defaults resolved (``resolved``), or InputError naming the
        first bad field. ``gh2010_step_s``: the step the GH2010 set to be run was fitted
        at (``GH2010Params.timestep_s``; default the shipped default set's, 2 ms)."""
        if self.timestep_s is None or self.start is None or self.duration_after_trip_s is None:
            return self.resolved(gh2010_step_s).validated(gh2010_step_s)
        lo, hi = SWING_RANGE
        if not np.isfinite(self.swing_fraction) or not lo <= self.swing_fraction <= hi:
            raise InputError(f"swing fraction {self.swing_fraction} is outside {lo}-{hi}")
        check_speed(self.speed_m_per_s)
        if self.leg not in LEGS:
            raise InputError(f"leg {self.leg!r} is not 'left' or 'right'")
        if self.mechanism not in MECHANISMS:
            raise InputError(f"mechanism {self.mechanism!r} is not 'force' or 'obstacle'")
        if not np.isfinite(self.obstacle_height_m) or not 0.02 <= self.obstacle_height_m <= 0.3:
            raise InputError(f"obstacle height {self.obstacle_height_m} m is outside 0.02-0.3 m")
        if self.strategy not in ("auto", "elevating", "lowering"):
            raise InputError(f"strategy {self.strategy!r} is not auto, elevating or lowering")
        if self.controller not in CONTROLLERS:
            raise InputError(f"controller {self.controller!r} is not one of "
                             f"{', '.join(CONTROLLERS)}")
        if self.controller in MUSCLE_CONTROLLERS and self.strategy != "auto":
            raise InputError(f"the {self.controller} controller is not told a strategy: it "
                             "emerges (use strategy auto)")
        if self.start not in STARTS:
            raise InputError(f"start {self.start!r} is not 'playback' or 'own'")
        if self.start == "own" and self.controller not in MUSCLE_CONTROLLERS:
            raise InputError(f"the {self.controller} controller does not walk on its own: "
                             "use start playback")
        lo_w, hi_w = WALK_IN_RANGE_S
        if not np.isfinite(self.walk_in_s) or not lo_w <= self.walk_in_s <= hi_w:
            raise InputError(f"walk-in {self.walk_in_s} s is outside {lo_w:g}-{hi_w:g} s")
        if not 0.2 <= self.delay_scale <= 5.0:
            raise InputError(f"delay scale {self.delay_scale} is outside 0.2-5")
        if self.delays not in DELAYS:
            raise InputError(f"delays {self.delays!r} is not one of {', '.join(DELAYS)}")
        if not 0.1 <= self.strength_scale <= 5.0:
            raise InputError(f"strength scale {self.strength_scale} is outside 0.1-5")
        if self.strength_model not in STRENGTH_MODELS:
            raise InputError(f"strength model {self.strength_model!r} is not one of "
                             f"{', '.join(STRENGTH_MODELS)}")
        if self.recovery not in RECOVERY_RULES:
            raise InputError(f"recovery rule {self.recovery!r} is not step or walk_on")
        if self.population not in POPULATIONS:
            raise InputError(f"population {self.population!r} is not one of "
                             f"{', '.join(POPULATIONS)}")
        if self.population != "young" and self.controller in MUSCLE_CONTROLLERS:
            raise InputError(f"population {self.population} is defined for the state "
                             f"machines (fsm), not the {self.controller} controller")
        if self.strength_model != "fixed" and self.controller in MUSCLE_CONTROLLERS:
            raise InputError(f"strength model {self.strength_model} is for the state "
                             f"machines' servos (fsm), not the {self.controller} controller's "
                             "muscles")
        if self.recovery != "walk_on" and self.controller in MUSCLE_CONTROLLERS:
            from stumble.analysis import WALK_ON_S  # analysis imports this module

            raise InputError(f"recovery rule {self.recovery} is for the state machines "
                             f"(fsm); the {self.controller} controller recovers when still "
                             f"walking {WALK_ON_S:g} s after the trip")
        lo_dt, hi_dt = TIMESTEP_RANGE_S
        if not np.isfinite(self.timestep_s) or not lo_dt <= self.timestep_s <= hi_dt:
            raise InputError(f"time step {self.timestep_s} s is outside {lo_dt}-{hi_dt} s")
        limit = MAX_TIMESTEP_S.get(self.controller)
        if limit is not None and self.timestep_s > limit + 1e-12:
            raise InputError(f"time step {self.timestep_s} s is not stable for the "
                             f"{self.controller} controller (at most {limit} s)")
        if not 0.5 <= self.duration_after_trip_s <= 20.0:
            raise InputError(f"duration {self.duration_after_trip_s} s is outside 0.5-20 s")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or not (
                0 <= self.seed <= MAX_SEED):
            raise InputError(f"seed {self.seed!r} is not a whole number from 0 to {MAX_SEED} "
                             "(2^63 - 1)")
        if self.controller == "reflex":  # the shipped network's tick (a network file's own
            from stumble.control.reflex.network import steps_per_tick  # is checked on load)

            steps_per_tick(self.timestep_s)
        if self.controller == "gh2010":
            check_gh2010_timestep(self.timestep_s, gh2010_step_s or DEFAULT_TIMESTEP_S["gh2010"])
        return self

    @property
    def side(self) -> str:
        """Model side suffix of the tripped leg: 'l' or 'r'."""
        return self.leg[0]

    def with_(self, **changes) -> Scenario:
        """A copy with some fields changed."""
        return replace(self, **changes)


def trip_time(events, side: str, swing_fraction: float, after_s: float = 0.0) -> float:
    """The first instant after ``after_s`` at which ``side`` is at ``swing_fraction`` of swing."""
    for to in events.toe_off_s[side]:
        if to < after_s:
            continue
        hs = [t for t in events.heel_strike_s[side] if t > to]
        if hs:
            return float(to + swing_fraction * (hs[0] - to))
    raise InputError(f"the walk has no complete swing of the {side} leg after {after_s} s")


# ---- where the obstacle stands ------------------------------------------------------
# per thread (studies may run trips in threads): model id -> (model, scratch MjData)
_SCRATCH = threading.local()
_SCRATCH_MAX = 8  # models whose scratch data are kept (a study's bodies and walks)


def posed(m: mujoco.MjModel, qpos: np.ndarray) -> mujoco.MjData:
    """Scratch data of ``m`` in pose ``qpos``, its kinematics computed (positions and
    frames only). Kept per model's sizes and reused: an ``MjData`` costs about 0.4 ms to
    make in MuJoCo 4.0's Python bindings, whatever the model, and serves any model of its
    sizes (``build``'s copies); valid until the next call for a model of those sizes."""
    kept = getattr(_SCRATCH, "kept", None)
    if kept is None:
        kept = _SCRATCH.kept = OrderedDict()
    hit = kept.get(id(m))
    if hit is None or hit[0] is not m:
        # a copy of a kept model (``build`` hands out copies) shares its scratch data:
        # an ``MjData`` serves any model of the same sizes
        sizes = _sizes(m)
        same = next((dd for mm, dd in kept.values() if _sizes(mm) == sizes), None)
        hit = kept[id(m)] = (m, same if same is not None else mujoco.MjData(m))
        while len(kept) > _SCRATCH_MAX:
            kept.popitem(last=False)
    else:
        kept.move_to_end(id(m))
    d = hit[1]
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    return d


def _sizes(m: mujoco.MjModel) -> tuple[int, ...]:
    """The sizes an ``MjData`` is made for (MuJoCo's ``mjMODEL_INTS``, which a model's
    copy shares)."""
    return tuple(int(getattr(m, f)) for f in _SIZE_FIELDS)


_SIZE_FIELDS = tuple(f for f in ("nq", "nv", "nu", "na", "nbody", "nbvh", "nbvhstatic",
                                 "nbvhdynamic", "njnt", "ngeom", "nsite", "ncam", "nlight",
                                 "nflex", "nflexnode", "nflexvert", "nflexedge",
                                 "nflexelem", "nmesh", "nskin", "nhfield", "ntex", "nmat",
                                 "npair", "nexclude", "neq", "ntendon", "nwrap", "nsensor",
                                 "nnumeric", "ntext", "ntuple", "nkey", "nmocap",
                                 "nplugin", "nuserdata", "nsensordata", "nM", "nB", "nC",
                                 "nD", "nJmom", "ntree", "ngravcomp", "nemax", "njmax",
                                 "nconmax", "nuser_body", "nstack", "nbuffer", "narena")
                    if hasattr(mujoco.MjModel, f))


def toe_front(body: Body, qpos: np.ndarray, side: str) -> tuple[float, float, float]:
    """Forward-most x, lowest z and mean y of a foot's boxes, for one pose."""
    m = body.model
    d = posed(m, qpos)
    xs, zs, ys = [], [], []
    for name in (f"foot_{side}_geom", f"toes_{side}_geom"):
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
        if gid < 0:
            continue
        half = m.geom_size[gid]
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                            for sz in (-1, 1)]) * half
        world = d.geom_xpos[gid] + corners @ d.geom_xmat[gid].reshape(3, 3).T
        xs.append(world[:, 0].max())
        zs.append(world[:, 2].min())
        ys.append(world[:, 1].mean())
    return float(max(xs)), float(min(zs)), float(np.mean(ys))


def check_clear_of_stance(body: Body, qpos: np.ndarray, side: str, box) -> None:
    """InputError if the obstacle's footprint would overlap the stance foot."""
    m = body.model
    d = posed(m, qpos)
    from stumble.body.contact import sole_positions  # (``Scenario`` alone stays light)

    pts = sole_positions(m, d, body.foot_points[side], body.planar)[:, :2]
    x0, _h, depth, width, y0 = box
    inside = ((pts[:, 0] > x0) & (pts[:, 0] < x0 + depth)
              & (np.abs(pts[:, 1] - y0) < 0.5 * width))
    if inside.any():
        raise TripNotSet("the obstacle would stand under the stance foot at this instant")


def obstacle_at(body: Body, qpos: np.ndarray, sc: Scenario, who: str = "the"):
    """The obstacle box (near face x, height, depth, width, lane y) just ahead of the
    tripped toe in pose ``qpos``; InputError if the toe is over it or the box would stand
    under the stance foot."""
    front, low, lane = toe_front(body, qpos, sc.side)
    if low > sc.obstacle_height_m - 0.01:
        raise TripNotSet(f"at {sc.swing_fraction} of swing {who} toe is {low:.3f} m up, "
                         f"not 0.01 m below a {sc.obstacle_height_m} m obstacle's top: it "
                         "would clear it")
    box = (front + OBSTACLE_GAP_M, sc.obstacle_height_m, OBSTACLE_DEPTH_M,
           OBSTACLE_WIDTH_M, lane)
    check_clear_of_stance(body, qpos, {"l": "r", "r": "l"}[sc.side], box)
    return box


def place_obstacle(m: mujoco.MjModel, box, d: mujoco.MjData | None = None) -> None:
    """Move the model's obstacle box to ``box`` (``obstacle_at``'s form; the model's box
    keeps its size), then bring ``d`` up to date if given. A trip builds its obstacle at
    the origin and moves it (``build`` compiles one model for every trip of a body); the
    same physics as a box compiled in place (the 48-trip grid, checked)."""
    x0, h, depth, _w, y0 = box
    m.geom_pos[m.geom("obstacle").id] = [x0 + 0.5 * depth, y0, 0.5 * h]
    if d is not None:
        mujoco.mj_forward(m, d)


def park_obstacle(m: mujoco.MjModel, lane_y: float) -> None:
    """Put the obstacle under the floor in the foot's lane (it touches only the feet),
    until ``place_obstacle``."""
    m.geom_pos[m.geom("obstacle").id] = [0.5 * OBSTACLE_DEPTH_M, lane_y, -1.0]


# The scenario's seed and strength, set on the physics before the run
SEED_ANGLE_SD_RAD = np.radians(0.5)  # per joint angle, seed != 0 (our choice)
SEED_VELOCITY_SD_RAD_S = 0.05  # per joint angular velocity, seed != 0 (our choice)


def perturb_initial_state(body: Body, data: mujoco.MjData, seed: int) -> None:
    """Seed 0: the playback state as it is. Any other seed adds independent Gaussian
    noise to every joint angle (SD 0.5°) and angular velocity (SD 0.05 rad/s), so repeated
    trips sample the variability of real steps; the same seed gives the same numbers."""
    if seed == 0:
        return
    m = body.model
    rng = np.random.default_rng(seed)
    q = [m.jnt_qposadr[m.joint(n).id] for n in body.joints]
    v = [m.jnt_dofadr[m.joint(n).id] for n in body.joints]
    data.qpos[q] += rng.normal(0.0, SEED_ANGLE_SD_RAD, len(q))
    data.qvel[v] += rng.normal(0.0, SEED_VELOCITY_SD_RAD_S, len(v))


def servo_strength(m: mujoco.MjModel, sc: Scenario, reflex: bool) -> Strength | None:
    """The servos' human strength (``stumble.body.strength``) for the scenario's body,
    age group and strength scale; None for muscles and for the fixed limits (which an
    older population scales by Anderson et al. 2007's older/young ratios)."""
    from stumble.body import strength  # (not at import: ``Scenario`` alone stays light)

    age = POPULATIONS[sc.population].age
    if reflex:
        return None
    if sc.strength_model != "anderson2007":
        if age != "young":
            strength.age_fixed_limits(m, sc.sex, age)
        return None
    return strength.Strength.for_model(m, sc.mass_kg, sc.height_m, sc.sex, age,
                                       sc.strength_scale)
