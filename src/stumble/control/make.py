"""The controller a scenario names, made for the walk it takes over from.

``trip_controller``: SCA 2009's state machines, seed 003's network or Geyer & Herr 2010's
reflexes for a trip; ``walk_controller``: a reflex controller for a walk;
``muscle_set_of``: the muscles a reflex controller drives. A new controller is made here
(and named in ``stumble.trip.CONTROLLERS``); the physics loop (``stumble.sim``) stays as
it is: it steps any ``sim.Controller``.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco

from stumble.control.fsm import TripFSM
from stumble.control.fsm_params import FSMParams, default_params
from stumble.errors import InputError
from stumble.gait.playback import Playback, stride_phase
from stumble.trip import POPULATIONS, Scenario


def trip_controller(sc: Scenario, strategy: str | None, params: FSMParams | None,
                    network, pb: Playback, t_trip: float, trunk_balance: bool = True,
                    gh2010=None):
    """The scenario's controller taking over from the walk ``pb`` at ``t_trip`` (s):
    ``params`` the state machines' (default ``fsm_params.default_params`` for the
    scenario's strength model and recovery rule), ``network`` seed 003's
    (default the shipped one), ``gh2010`` Geyer & Herr's parameters (default shipped);
    the scenario's delay scale and population applied."""
    response_only = sc.delays == "response"
    if sc.controller == "reflex":
        return network_controller(network, pb, t_trip, sc.delay_scale, trunk_balance,
                                  response_only)
    if sc.controller == "gh2010":
        return walk_controller("gh2010", pb, t_trip, gh2010, delay_scale=sc.delay_scale,
                               response_only=response_only)
    p = params or default_params(sc.strength_model, sc.recovery)
    if p.delay_scale != 1.0 and p.delay_scale != sc.delay_scale:  # not silently replaced
        raise InputError(f"the state machines' parameters carry delay_scale "
                         f"{p.delay_scale:g}: give it as the scenario's delay scale "
                         f"({sc.delay_scale:g}) instead")
    p = replace(p, delay_scale=sc.delay_scale)
    pop = POPULATIONS[sc.population]
    if pop.extra_latency_s:  # the population's slower responses (trip.POPULATIONS)
        p = replace(p, latency_s={k: v + pop.extra_latency_s.get(k, 0.0)
                                  for k, v in p.latency_s.items()})
    if pop.activation_scale != 1.0:  # and slower torque development
        p = replace(p, activation_to_torque_s=p.activation_to_torque_s * pop.activation_scale)
    return TripFSM(strategy, sc.side, sc.speed_m_per_s, p)


def network_controller(network, pb: Playback, t: float, delay_scale: float,
                       trunk_balance: bool, response_only: bool = False):
    """The reflex network (given or shipped) taking over from the walk at time ``t`` (s),
    its delays (and its trunk balance's) × ``delay_scale``; ``response_only``: its touch
    response's alone."""
    from stumble.control.reflex.controller import ReflexController, TrunkBalance
    from stumble.control.reflex.identify import default_network, history_before

    net = network or default_network()
    if response_only:
        if (net.info or {}).get("touch_response") is None and delay_scale != 1.0:
            raise InputError("--delays response slows the touch response, and this "
                             "network has none (the placement-touch, placement-foot, "
                             "placement-both and past-* networks have one)")
        net = net.with_delay_scale(delay_scale, response_only=True)
        delay_scale = 1.0  # the nerves and the trunk balance at their own
    else:
        net = net.with_delay_scale(delay_scale)
    history = None
    if net.walk_rates is not None:
        history = history_before(net.walk_rates, stride_phase(pb, t),
                                 2 * net.topology.max_lag + 2, net.topology.rate_hz)
    balance = None
    if trunk_balance:  # its vestibulospinal latency scales with the nerve delays
        balance = TrunkBalance.from_info(net.info, TrunkBalance.DELAY_S * delay_scale,
                                         net.topology.rate_hz)
    return ReflexController(net, history, balance)


def network_steps_per_tick(net, m: mujoco.MjModel) -> int:
    """Physics steps per network tick; InputError if the model's step does not divide it
    (``network.steps_per_tick``; also checked with the scenario, ``Scenario.validated``)."""
    from stumble.control.reflex.network import steps_per_tick

    return steps_per_tick(m.opt.timestep, net.topology.rate_hz)


def walk_controller(kind: str, pb: Playback, t: float, params=None, network=None,
                    delay_scale: float = 1.0, trunk_balance: bool = True,
                    response_only: bool = False):
    """The reflex controller ``kind`` (``network``: seed 003's; ``gh2010``) taking over
    from the walk at time ``t`` (s), its delays × ``delay_scale`` (``response_only``:
    those of the response to a touch alone, ``Scenario.delays``)."""
    if kind == "gh2010":
        from stumble.control.reflex.gh2010 import GH2010Controller, shipped_params

        p = params or shipped_params()
        p = (replace(p, delay_scale=1.0, response_delay_scale=delay_scale) if response_only
             else replace(p, delay_scale=delay_scale, response_delay_scale=1.0))
        return GH2010Controller(p)
    if kind == "network":
        return network_controller(network, pb, t, delay_scale, trunk_balance, response_only)
    raise InputError(f"reflex controller {kind!r} is not 'network' or 'gh2010'")


def muscle_set_of(kind: str, network=None) -> str:
    """The body's muscle set a reflex controller drives (GH2010: with the iliopsoas;
    the network: the set it was identified for)."""
    if kind == "gh2010":
        return "hfl"
    from stumble.control.reflex.identify import default_network

    return (network or default_network()).muscle_set
