"""One trip from scenario to result: build, walk, trip, simulate, analyse.

``simulate_trip(scenario)`` composes the stages of DESIGN.md: the body
(``stumble.body``), the walk played back until the trip (``stumble.gait``), the trip
(``stumble.trip``), physics under a controller (``stumble.sim``) and the outcome
(``stumble.analysis``). Nothing here steps physics itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from stumble.analysis import (
    WALK_ON_S,
    StopRule,
    TripTimer,
    angular_momentum,
    fall_height_m,
    reference_stride,
    trip_summary,
    walk_in_summary,
)
from stumble.body import Body, build
from stumble.body.contact import DEFAULT_MODE as DEFAULT_CONTACT
from stumble.body.contact import PenaltyContact, rest_support_foot
from stumble.body.muscles import DEFAULT_MUSCLE_SET
from stumble.body.strength import scale_strength
from stumble.control.fsm_params import FSMParams, default_params
from stumble.control.make import (
    muscle_set_of,
    network_controller,
    network_steps_per_tick,
    trip_controller,
    walk_controller,
)
from stumble.errors import InputError
from stumble.gait.playback import Playback
from stumble.gait.reference import load_reference
from stumble.gait.walk_cache import WALK_BEFORE_TRIP_S, body_and_walk
from stumble.sim import Context, Recording, Sensors, run
from stumble.trip import (
    DEFAULT_TIMESTEP_S,
    MUSCLE_CONTROLLERS,
    OBSTACLE_DEPTH_M,
    OBSTACLE_GAP_M,
    OBSTACLE_WIDTH_M,
    PelvisPushes,
    Scenario,
    obstacle_at,
    park_obstacle,
    perturb_initial_state,
    place_obstacle,
    servo_strength,
    toe_front,
    trip_time,
)


@dataclass
class TripResult:
    """Everything a trip produced: the summary (JSON-ready), the recording, the model."""

    summary: dict
    recording: Recording
    body: Body
    playback: Playback
    scenario: Scenario
    states: list[tuple[str, float]] = field(default_factory=list)
    network: object = None  # the reflex network that ran (reflex controller only)
    walk_recording: Recording | None = None  # start own: the controller's walk to the trip
    _angmom: np.ndarray | None = field(default=None, repr=False)

    def angular_momentum(self) -> np.ndarray:
        """(T, 3) whole-body angular momentum about the COM over the recording (kg·m²/s,
        ``analysis.angular_momentum``), computed once for every file that shows it."""
        if self._angmom is None:
            rec = self.recording
            self._angmom = angular_momentum(self.body.model, rec.qpos, rec.qvel)
        return self._angmom


class WalkInCache:
    """Own-start walks to the trip instant, kept for trips that differ only in the
    reflexes a touch triggers (``gh2010.TOUCH_FIELDS``; a network's touch afferent and
    touch response): before the first touch those add nothing, so the walk is the same,
    bit for bit, and is run once. Keyed by the scenario and the controller's ``walk_key``
    (``GH2010Controller``, ``ReflexController``); each use resumes from a deep copy of the
    model, data, controller and walk recording. For fits of the touch's reflexes alone
    (``fit_walk.fit_gh2010(touch_only=True)``, ``fit_network_es(touch_only=True)``), whose
    every candidate walks the same."""

    def __init__(self) -> None:
        self._walks: dict = {}

    def __len__(self) -> int:
        return len(self._walks)

    def get(self, key):
        """A deep copy of what was put under ``key``, or None."""
        import copy

        hit = self._walks.get(key)
        return None if hit is None else copy.deepcopy(hit)

    def put(self, key, walked) -> None:
        """Keep a deep copy of ``walked`` under ``key``."""
        import copy

        self._walks[key] = copy.deepcopy(walked)


def simulate_trip(scenario: Scenario, params: FSMParams | None = None,
                  reference: dict | None = None, network=None,
                  trunk_balance: bool = True, gh2010=None,
                  log_controls: bool = False,
                  walk_in_cache: WalkInCache | None = None,
                  past_obstacle: bool = True) -> TripResult:
    """Walk, trip and recover (or fall): the whole pipeline for one scenario.

    Controller ``fsm`` (SCA 2009) drives the 3D human; ``reflex`` (seed 003) the planar
    musculoskeletal human, with ``network`` (a ``stumble.control.reflex.Network``) or the
    shipped one; ``gh2010`` the same body with Geyer & Herr 2010's reflexes
    (``gh2010``: ``GH2010Params``, default the shipped ones). The strategy of the reflex
    controllers is not chosen but classified from the motion.
    ``trunk_balance``: the reflex controller's stance-hip trunk-lean reflex
    (``stumble.control.reflex.controller.TrunkBalance``; our addition, on by default).

    ``reference``: optional {"time_s": (T,), "<coordinate>": (T,) deg} of a recorded trip
    (t = 0 the trip; coordinates named as our model: pelvis_tilt, hip_flexion_l, ...)
    for the joint-pitch RMSE of SCA 2009 Table 2. ``log_controls``: keep every block's
    controls, gains and trip forces in the recording (``stumble.sim.run``), for benchmarks
    that replay them. ``walk_in_cache`` (``gh2010`` or ``reflex``, own start): reuse the
    walk to the trip of an earlier trip whose parameters (GH2010's) or network differed
    only in the touch's reflexes (the same numbers as walking it again). ``past_obstacle``
    (obstacle trips): a recovery needs both ankles past the box at the verdict
    (``StopRule.past_x``; off only to re-run the fits made before the rule, 2026-12-07).
    """
    from stumble.control.reflex.gh2010 import fitted_timestep

    sc = scenario.validated(fitted_timestep(gh2010) if scenario.controller == "gh2010"
                            else None)
    reflex = sc.controller in MUSCLE_CONTROLLERS
    # the shipped set for the strength model and the recovery rule when none is given
    # (``fsm_params.DEFAULT_SETS``: rec_hip_cap on fixed limits, the sets tuned on
    # human strength)
    # (the reflex controllers' strategy emerges: no state-machine set to read)
    p = params or (None if reflex else default_params(sc.strength_model, sc.recovery))
    strategy = None
    if not reflex:
        strategy = p.strategy_for(sc.swing_fraction) if sc.strategy == "auto" else sc.strategy
    muscle_set = (muscle_set_of("network" if sc.controller == "reflex" else sc.controller,
                                network) if reflex else DEFAULT_MUSCLE_SET)
    base, pb = body_and_walk(sc.height_m, sc.mass_kg, sc.sex, sc.contact, sc.speed_m_per_s,
                             sc.timestep_s, reflex, muscle_set)
    own = sc.start == "own"
    if own:  # the controller takes over at right heel strike and walks to the trip
        t_start = next(t for t in pb.events.heel_strike_s["r"] if t >= WALK_BEFORE_TRIP_S)
    else:
        t_start = trip_time(pb.events, sc.side, sc.swing_fraction, after_s=WALK_BEFORE_TRIP_S)
    qpos, qvel = pb.state_at(t_start)
    front, low, lane = toe_front(base, qpos, sc.side)
    obstacle = None
    if sc.mechanism == "obstacle":
        # built at the origin (one compiled model for every trip of a body, ``build``)
        # and moved: where the trip puts it (playback) or parked under the floor until
        # the trip (own start; ``trip.place_obstacle``)
        obstacle = (0.0, sc.obstacle_height_m, OBSTACLE_DEPTH_M, OBSTACLE_WIDTH_M, 0.0)
        box = None if own else obstacle_at(base, qpos, sc)
    body = build(planar=reflex, height_m=sc.height_m, mass_kg=sc.mass_kg, sex=sc.sex,
                 contact=sc.contact, obstacle=obstacle, timestep_s=sc.timestep_s,
                 actuation="muscles" if reflex else "servos", muscle_set=muscle_set)
    m = body.model
    if obstacle is not None:
        if own:
            park_obstacle(m, lane)
        else:
            place_obstacle(m, box)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = qpos, qvel
    perturb_initial_state(body, d, sc.seed)
    if sc.contact in ("lumped", "points", "penalty"):
        rest_support_foot(m, d, reflex)
    scale_strength(m, sc.strength_scale)
    strength = servo_strength(m, sc, reflex)
    if strength is not None:
        strength.apply(m, d)
    ctx = Context(m, d, body, Sensors(), t0=0.0, strength=strength)
    controller = trip_controller(sc, strategy, p, network, pb, t_start, trunk_balance, gh2010)
    if sc.controller == "reflex":
        network_steps_per_tick(controller.net, m)
    fall_height = fall_height_m(body.model)
    walk_in = None
    if own:
        key = ((repr(sc), controller.walk_key()) if walk_in_cache is not None
               and hasattr(controller, "retouch") and not log_controls else None)
        hit = walk_in_cache.get(key) if key is not None else None
        if hit is not None:  # the same walk, with other touch reflexes: go on from it
            m, d, body, ctx, walked, walk_rec, walk_in = hit
            walked.retouch(controller.touch_settings())
            controller = walked
        else:
            timer = TripTimer(sc.side, sc.swing_fraction, sc.walk_in_s, fall_height)
            walk_rec = run(ctx, controller, sc.walk_in_s + WALK_IN_MARGIN_S, stop=timer)
            walk_in = walk_in_summary(walk_rec, timer, sc.side)
            if key is not None:
                walk_in_cache.put(key, (m, d, body, ctx, controller, walk_rec, walk_in))
        if walk_rec.stop_reason != "trip":
            return _no_trip(sc, controller, walk_rec, walk_in, body, pb)
        qpos = d.qpos.copy()
        front, low, _lane = toe_front(body, qpos, sc.side)
        if sc.mechanism == "obstacle":
            place_obstacle(m, obstacle_at(body, qpos, sc, who=f"the {sc.controller} "
                                          "walker's"), d)
        ctx.t0 = float(d.time)
    far_x = front + OBSTACLE_GAP_M + OBSTACLE_DEPTH_M  # force trips: a notional obstacle
    stop = StopRule(strategy, sc.side, fall_height, far_x=far_x,
                    walk_on_s=_walk_on_s(sc, reflex),
                    past_x=far_x if sc.mechanism == "obstacle" and past_obstacle else None)
    force_kwargs = {}
    if sc.mechanism == "force":
        toe = f"toes_{sc.side}" if not reflex else f"foot_{sc.side}"
        toe_body = m.body(toe).id
        tip_sites = np.array([m.site(n).id for n in body.foot_points[sc.side][-6:]])
        force_kwargs = {"trip_force": sc.force, "force_body": toe_body,
                        "force_point": lambda dd: dd.site_xpos[tip_sites].mean(axis=0)}
    penalty = PenaltyContact.for_body(body) if sc.contact == "penalty" else None
    rec = run(ctx, controller, sc.duration_after_trip_s, stop=stop, penalty=penalty,
              log_controls=log_controls, resume=own, **force_kwargs)
    strategy = strategy or stop.classified
    if own:
        before = ctx.t0 - walk_in["toe_off_s"]
        stride = walk_in["stride_s"]
    else:
        offs = [t for t in pb.events.toe_off_s[sc.side] if t <= t_start]
        before, stride = (t_start - offs[-1] if offs else None), pb.stride_s
    summary = trip_summary(sc, strategy, controller.log, rec, stop, body.model,
                           ctx.t0 if own else t_start, before, stride, reference)
    summary["start"] = sc.start
    summary["toe_height_at_trip_m"] = round(low, 4)  # the tripped foot's lowest point
    if walk_in is not None:
        summary["walk_in"] = walk_in
    states = list(controller.log)
    if reflex:  # one controller, no states: the filmstrip shows the events instead
        if sc.controller == "reflex":
            summary["trunk_balance"] = trunk_balance
        states = [("trip", 0.0)]
        if stop.tripped_down_s is not None:
            states.append((f"tripped foot down ({stop.classified})", stop.tripped_down_s))
        if stop.landing_s is not None and stop.landing_s != stop.tripped_down_s:
            states.append(("recovery step lands", stop.landing_s))
        summary["obstacle_far_x_m"] = round(far_x - float(qpos[0]), 4)
        summary["tripped_foot_down_x_m"] = (None if stop.tripped_down_x is None else
                                            round(stop.tripped_down_x - float(qpos[0]), 4))
    return TripResult(summary, rec, body, pb, sc, states,
                      controller.net if sc.controller == "reflex" else None,
                      walk_rec if own else None)


def _walk_on_s(sc: Scenario, reflex: bool) -> float | None:
    """How long after the trip a recovered person is still walking (StopRule.walk_on_s):
    the reflex controllers WALK_ON_S; the state machines with recovery walk_on the whole
    run (its last 10 ms aside, so that the verdict falls inside it); else None."""
    if reflex:
        return WALK_ON_S
    if sc.recovery == "walk_on":
        return max(sc.duration_after_trip_s - 0.01, 0.5)
    return None


WALK_IN_MARGIN_S = 3.0  # own start: the trip's swing must begin within this after walk_in_s


def _no_trip(sc: Scenario, controller, rec: Recording, walk_in: dict, body: Body,
             pb: Playback) -> TripResult:
    """The result of an own-start walk that fell (or never swung) before the trip."""
    why = "fell before the trip" if walk_in["fell"] else "no swing to trip"
    summary = {"controller": sc.controller, "strategy": None, "variant": None,
               "recovered": False, "fell": walk_in["fell"], "diverged": rec.diverged,
               "fell_before_trip": walk_in["fell"], "swing_fraction": sc.swing_fraction,
               "speed_m_per_s": sc.speed_m_per_s, "mechanism": sc.mechanism,
               "leg": sc.leg, "trip_time_s": None, "stop_reason": why,
               "sim_time_s": walk_in["walked_s"], "wall_time_s": round(rec.wall_time_s, 4),
               "steps": rec.steps, "seed": sc.seed, "contact": sc.contact,
               "delay_scale": sc.delay_scale, "delays": sc.delays,
               "strength_scale": sc.strength_scale, "start": sc.start, "walk_in": walk_in,
               "states": [{"name": n, "start_s": t} for n, t in controller.log]}
    return TripResult(summary, rec, body, pb, sc, [("walk", 0.0)],
                      controller.net if sc.controller == "reflex" else None)


@dataclass
class StepResult:
    """One walking step under the reflex network (seed 003 Fig. 3)."""

    rmse_deg: dict  # per coordinate: simulated vs recorded, over the step
    duration_s: float
    fell: bool
    recording: Recording
    body: Body
    reference_qpos: np.ndarray  # (T, nq) the recorded walk at the recording's times


def simulate_walking_step(network=None, trunk_balance: bool = True,
                          speed_m_per_s: float | None = None) -> StepResult:
    """One step (half a stride, from right heel strike) of walking under the network
    (default the open-loop identification's), from the played-back state, against the
    recorded walk (seed 003 §V.A, Fig. 3)."""
    from stumble.control.reflex.identify import default_network

    net = network or default_network("open-loop")  # the identification's Fig. 3
    speed = speed_m_per_s or load_reference().speed_m_per_s
    body, pb = body_and_walk(1.75, 70.0, "male", DEFAULT_CONTACT, round(speed, 4), 0.001, True,
                             net.muscle_set)
    m = body.model
    t0 = next(t for t in pb.events.heel_strike_s["r"] if t >= WALK_BEFORE_TRIP_S)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = pb.state_at(t0)
    rest_support_foot(m, d, planar=True)
    ctrl = network_controller(net, pb, t0, 1.0, trunk_balance)
    stop = StopRule("elevating", "l", fall_height_m(body.model))
    duration = 0.5 * pb.stride_s
    network_steps_per_tick(net, m)
    rec = run(Context(m, d, body, Sensors(), t0=0.0), ctrl, duration, stop=stop)
    ref = np.array([pb.state_at(t0 + t)[0] for t in rec.time_s])
    names = ["pelvis_tilt", *body.joints]
    adr = [m.jnt_qposadr[m.joint(n).id] for n in names]
    rmse = {n: round(float(np.degrees(np.sqrt(np.mean((rec.qpos[:, a] - ref[:, a]) ** 2)))), 2)
            for n, a in zip(names, adr, strict=True)}
    return StepResult(rmse, float(rec.time_s[-1]), stop.fell_s is not None, rec, body, ref)


@dataclass
class WalkResult:
    """A walk under a reflex controller from the played-back state at right heel strike."""

    summary: dict  # JSON-ready: analysis.walk_metrics plus the run's settings
    recording: Recording
    body: Body
    playback: Playback
    reference: dict  # the recorded stride: 101 points per <joint>_<side> (rad)
    controller: object = None


def simulate_walk(controller: str = "gh2010", duration_s: float = 20.0,
                  speed_m_per_s: float | None = None, params=None, network=None,
                  delay_scale: float = 1.0, trunk_balance: bool = True,
                  timestep_s: float | None = None, pushes=()) -> WalkResult:
    """Walk under a reflex controller (``gh2010`` or ``network``) from the played-back
    walk at right heel strike, for ``duration_s`` or until a fall; the summary gives time
    walked, strides, speed, stance fraction and joint RMSE against the recorded stride.
    ``timestep_s``: the physics step (s; default the controller's, as a trip's: for
    ``gh2010`` the step its set was fitted at). ``pushes``: (start s, duration s,
    force N) on the pelvis, + forward (``PelvisPushes``; none by default)."""
    from stumble.analysis import WalkStop, walk_metrics
    from stumble.control.reflex.gh2010 import fitted_timestep
    from stumble.gait.reference import check_speed
    from stumble.trip import check_gh2010_timestep

    if controller == "gh2010":
        fitted = fitted_timestep(params)
        timestep_s = fitted if timestep_s is None else timestep_s
        check_gh2010_timestep(timestep_s, fitted)
    elif timestep_s is None:
        timestep_s = DEFAULT_TIMESTEP_S["reflex"]

    speed = load_reference().speed_m_per_s if speed_m_per_s is None else speed_m_per_s
    check_speed(speed)
    if not 0.5 <= duration_s <= 600.0:
        raise InputError(f"duration {duration_s} s is outside 0.5-600 s")
    body, pb = body_and_walk(1.75, 70.0, "male", DEFAULT_CONTACT, round(float(speed), 4),
                             timestep_s, True, muscle_set_of(controller, network))
    m = body.model
    t0 = next(t for t in pb.events.heel_strike_s["r"] if t >= WALK_BEFORE_TRIP_S)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = pb.state_at(t0)
    rest_support_foot(m, d, planar=True)
    ctrl = walk_controller(controller, pb, t0, params, network, delay_scale, trunk_balance)
    if controller == "network":
        network_steps_per_tick(ctrl.net, m)
    stop = WalkStop(fall_height_m(body.model))
    force = {}
    if pushes:
        pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        force = {"trip_force": PelvisPushes(pushes), "force_body": pelvis,
                 "force_point": lambda dd: dd.xipos[pelvis]}
    rec = run(Context(m, d, body, Sensors(), t0=0.0), ctrl, duration_s, stop=stop, **force)
    ref = reference_stride(pb)
    summary = {"controller": controller, **walk_metrics(rec, m, ref, duration_s),
               "start_speed_m_per_s": speed, "delay_scale": delay_scale,
               "wall_time_s": round(rec.wall_time_s, 4), "steps": rec.steps,
               "recorded_stance_fraction": round(pb.events.stance_fraction(), 4)}
    return WalkResult(summary, rec, body, pb, ref, ctrl)
