"""Walking and tripping under the shipped Geyer & Herr 2010 reflexes (closed-loop fitted;
the default ``stumble/control/reflex/data/gh2010_knee.json``, ``--params knee``),
from the played-back walk and in their own gait, and under the closed-loop network; the
open-loop network's strategies are tested in controller_test.py."""

import numpy as np
import pytest

from stumble.pipeline import simulate_trip, simulate_walk
from stumble.trip import Scenario


@pytest.mark.parametrize("wiring", ["gh2010", "seed003"])
def test_gh2010_walks_five_seconds_without_falling(wiring):
    """The shipped fits of both wirings (seed003: the network's DAgger expert)."""
    from stumble.control.reflex.gh2010 import shipped_params

    s = simulate_walk("gh2010", 5.0, params=shipped_params(wiring)).summary
    assert not s["fell"] and s["walked_s"] == pytest.approx(5.0)
    assert s["strides"] >= (2 if wiring == "gh2010" else 1)  # 1.34 s and 1.77 s strides
    assert 0.9 <= s["speed_m_per_s"] <= 1.4
    assert 0.55 <= s["stance_fraction"] <= 0.70


@pytest.mark.parametrize(("controller", "swing", "strategy"), [
    ("gh2010", 0.13, "elevating"), ("gh2010", 0.56, "lowering")])
def test_gh2010_takes_the_seeds_strategies_without_being_told(controller, swing, strategy):
    """Seed 003's CASE 1 (0.13 of swing) and CASE 2 (0.56), obstacle, 1.2 m/s."""
    from stumble.control.reflex.gh2010 import shipped_params

    # the seed's instants of the recording and the same fractions of its own swing, with
    # the walking fit the default's touch stage started from (``knee-walk``; a touch
    # stage changes what follows a touch, so the strategies are the walker's)
    params = shipped_params(walking_only=True)
    for start in ("playback", "own"):
        r = simulate_trip(Scenario(controller=controller, mechanism="obstacle",
                                   swing_fraction=swing, speed_m_per_s=1.2, start=start),
                          gh2010=params)
        assert r.summary["strategy"] == strategy, start
        assert [st["name"] for st in r.summary["states"]] == ["reflex"]  # never switched


def test_gh2010_walks_on_untripped_in_its_own_gait_and_from_the_recording():
    """A trip of no force at 0.2 of the left swing: in its own gait (the default start) the
    default walks on 3 s, and taking over from the recording too (a verdict the 3 s rule
    missed until 2026-12-04: the samples' time, summed from the recording's, fell short
    of 3 s by rounding), where the earlier trip fit (``--params trip``) falls within 1 s."""
    from stumble.control.reflex.gh2010 import load_params
    from stumble.trip import TripForce

    none = TripForce(fx_max_n=0.0, fz_max_n=0.0)
    own = simulate_trip(Scenario(controller="gh2010", mechanism="force", force=none,
                                 swing_fraction=0.2)).summary
    assert own["start"] == "own" and own["recovered"] and own["sim_time_s"] == 3.0
    played = Scenario(controller="gh2010", mechanism="force", force=none,
                      swing_fraction=0.2, start="playback")
    default = simulate_trip(played).summary
    assert default["recovered"] and default["stop_reason"] == "recovered"
    assert default["sim_time_s"] == 3.0
    trip = simulate_trip(played, gh2010=load_params("trip")).summary
    assert trip["fell"] and trip["fall_time_s"] < 1.0


@pytest.mark.parametrize(("swing", "speed"), [(0.05, 1.0), (0.25, 1.2)])
def test_gh2010_recovers_from_early_swing_trips_in_its_own_gait(swing, speed):
    """The default set, a 10 cm obstacle: elevating, still walking 3 s after the trip
    (docs/gh2010.md "Where it stands": 33 of the 45 trips recover)."""
    s = simulate_trip(Scenario(controller="gh2010", mechanism="obstacle",
                               swing_fraction=swing, speed_m_per_s=speed)).summary
    assert s["strategy"] == "elevating" and s["recovered"] and not s["fell"]
    assert s["sim_time_s"] == pytest.approx(3.0)


def test_the_foot_phase_set_recovers_a_late_swing_trip_by_lowering():
    """``--params knee-foot`` (the touch's response by the foot's phase, on the default's
    walk): tripped at 0.60 of its own swing at 1.2 m/s it lowers the tripped foot behind
    the box, steps over with the other and walks on; the default falls there."""
    from stumble.control.reflex.gh2010 import load_params

    sc = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=0.6,
                  speed_m_per_s=1.2)
    s = simulate_trip(sc, gh2010=load_params("knee-foot")).summary
    assert s["strategy"] == "lowering" and s["recovered"] and not s["fell"]
    assert s["durations_s"]["trip_to_recovery_contact"] < 1.0
    d = simulate_trip(sc).summary
    assert d["strategy"] == "lowering" and d["fell"]


def test_the_2ms_set_runs_at_2ms_and_recovers_an_early_trip_knee_falls_from():
    """``--params knee-2ms`` (``knee``'s touch stage refitted at a 2 ms step) runs at its
    own step, and at 0.10 of swing, 1.2 m/s, it walks on where ``knee`` (the default until
    2026-12-05, at its 1 ms) falls (docs/speed.md "Speed": 30 of the 45 against 26)."""
    from stumble.control.reflex.gh2010 import load_params

    p = load_params("knee-2ms")
    assert p.timestep_s == 0.002
    sc = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=0.1,
                  speed_m_per_s=1.2)
    s = simulate_trip(sc, gh2010=p).summary
    assert s["steps"] == 1500  # 3 s of 2 ms steps
    assert s["strategy"] == "elevating" and s["recovered"]
    d = simulate_trip(sc, gh2010=load_params("knee")).summary
    assert d["steps"] < 3000 and d["fell"]


@pytest.mark.parametrize("name, before, swing, speed", [
    ("knee-2ms-dense", "knee-2ms", 0.45, 1.0),  # a trip of the 45, not of its fit
    ("knee-2ms-dense-wide", "knee-2ms-dense", 0.3, 1.2),  # one of its wide twelve
    ("knee-2ms-dense-wide-s3", "knee-2ms-dense", 0.45, 1.4),  # of the 45, not the twelve
])
def test_each_later_2ms_touch_stage_recovers_a_trip_its_start_does_not(name, before, swing,
                                                                        speed):
    """``--params knee-2ms-dense`` (a second touch stage on ``knee-2ms``, fitted on trips
    at 1.1 and 1.3 m/s) and ``knee-2ms-dense-wide`` (a third, on the wide twelve; and
    by another seed, ``-s3``, the default) run at
    2 ms, walk as the set they started from (the touch's reflexes alone were fitted), and
    walk on from a trip where that set does not (docs/gh2010.md "Geyer & Herr 2010")."""
    from stumble.control.reflex.gh2010 import TOUCH_FIELDS, load_params

    p, q = load_params(name), load_params(before)
    assert p.timestep_s == q.timestep_s == 0.002
    assert all(getattr(p, f) == getattr(q, f) for f in p.to_json()
               if f not in TOUCH_FIELDS)
    sc = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=swing,
                  speed_m_per_s=speed)
    s = simulate_trip(sc, gh2010=p).summary
    assert s["strategy"] == "elevating" and s["recovered"]
    d = simulate_trip(sc, gh2010=q).summary
    assert d["strategy"] == "elevating" and not d["recovered"]


def test_own_start_trips_at_the_fraction_of_the_walkers_own_swing():
    s = simulate_trip(Scenario(controller="gh2010", mechanism="obstacle",
                               swing_fraction=0.3, walk_in_s=3.0)).summary
    w = s["walk_in"]
    assert not w["fell"] and w["toe_off_s"] >= 3.0
    assert 0.4 <= w["swing_s"] <= 0.6 and 1.0 <= w["stride_s"] <= 1.4  # its own gait
    assert 0.9 <= w["speed_m_per_s"] <= 1.2
    # the trip comes at 0.3 of the swing, to the controller's 5 ms block
    assert s["trip_time_s"] - w["toe_off_s"] == pytest.approx(0.3 * w["swing_s"], abs=0.006)
    assert s["walking_stride_s"] == w["stride_s"]


@pytest.mark.parametrize("speed", [None, 1.0, 1.2, 1.4])
def test_the_shipped_closed_loop_network_walks_from_every_start(speed):
    """`stumble reflex fit --closed-loop --seed 0`, shipped as `--network closed-loop`:
    5 s from the played-back walk (None: the recording's 1.10 m/s, the default), no
    fall, a human speed and stance; its DAgger started episodes from, and judged each
    pass from, the 1.0-1.3 m/s walks (1.4 was not among them)."""
    from stumble.control.reflex.identify import default_network

    net = default_network("closed-loop")
    assert "HFL" in net.topology.muscles and net.topology.contact
    s = simulate_walk("network", 5.0, speed_m_per_s=speed, network=net).summary
    assert not s["fell"] and s["walked_s"] == pytest.approx(5.0)
    assert 0.9 <= s["speed_m_per_s"] <= 1.4
    assert 0.55 <= s["stance_fraction"] <= 0.70


@pytest.mark.parametrize(("name", "swing", "strategy"), [
    *((n, sw, st) for n in ("closed-loop", "placement", "placement-es", "placement-walk")
      for sw, st in ((0.13, "elevating"), (0.56, "lowering"))),
    ("placement-touch", 0.13, "elevating"),  # its CASE 2 falls before the foot is down
    ("placement-foot", 0.13, "elevating"), ("placement-foot", 0.56, "lowering"),
    ("placement-both", 0.13, "elevating"), ("placement-both", 0.56, "lowering"),
])
def test_the_closed_loop_network_takes_the_seeds_strategies(swing, strategy, name):
    """Seed 003's CASE 1 and CASE 2 (obstacle, 1.2 m/s, from the recording, the seed's
    way) under the closed-loop networks: never switched."""
    from stumble.control.reflex.identify import default_network

    r = simulate_trip(Scenario(controller="reflex", start="playback", mechanism="obstacle",
                               swing_fraction=swing, speed_m_per_s=1.2),
                      network=default_network(name))
    assert r.summary["start"] == "playback" and r.summary["strategy"] == strategy
    assert [st["name"] for st in r.summary["states"]] == ["reflex"]


def test_the_closed_loop_network_recovers_an_early_trip_in_its_own_gait():
    """0.05 of its own swing, 1.2 m/s start: elevating, still walking 3 s after the trip
    (docs/reflex-network.md "The shipped networks": 10 of the 45 own-gait trips recover)."""
    from stumble.control.reflex.identify import default_network

    s = simulate_trip(Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.05,
                               start="own"), network=default_network("closed-loop")).summary
    assert s["strategy"] == "elevating" and s["recovered"] and not s["fell"]
    assert s["sim_time_s"] == pytest.approx(3.0)


def test_the_es_refined_network_walks_closest_to_the_recording():
    """``--network placement-es`` (``placement`` refined by two CMA-ES stages at the 2 ms
    step): 20 s from the recording at 0.9-1.4 m/s, stance 0.55-0.70, its stance knee off
    the stop, the knee within 10 deg of the recorded stride, hip within 8 and ankle at
    10.0 (docs/reflex-fits.md: 7.3/9.2/10.0 deg; ``placement`` 8.6/19.4/8.9); in its own gait its
    toe
    is low in late swing, so a trip at 0.60 of swing is set, and it lowers."""
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-es")
    fit = net.info["fit"]
    assert fit["command"].startswith("stumble reflex fit --controller network --walk-es")
    assert fit["from"]["its_fit"]["command"].startswith(
        "stumble reflex fit --controller network --walk-es placement")
    s = simulate_walk("network", 20.0, network=net).summary
    assert not s["fell"] and 0.9 <= s["speed_m_per_s"] <= 1.4
    assert 0.55 <= s["stance_fraction"] <= 0.70 and s["knee_hyperextension_deg"] < 0.5
    rm = s["rmse_deg"]
    assert rm["hip_flexion"] < 8.0 and rm["knee_angle"] < 10.0 and rm["ankle_angle"] < 10.1
    t = simulate_trip(Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.6,
                               speed_m_per_s=1.2, start="own"), network=net).summary
    assert t["toe_height_at_trip_m"] < 0.05 and t["strategy"] == "lowering"


def test_cli_names_the_closed_loop_network(tmp_path):
    from stumble.cli import main

    assert main(["reflex", "walk", "--network", "closed-loop", "--speed", "1.2",
                 "--duration", "1", "--no-video", "--out", str(tmp_path / "w")]) == 0


def test_the_default_network_is_past_support_and_walks(tmp_path):
    """Since 2026-12-07 a reflex trip or walk given no network runs ``past-support``
    (``identify.DEFAULT_NETWORK``; ``past-swing`` earlier that day, ``placement-both``
    from 2026-12-05), which walks; the
    open-loop identification, seed 003's own method, stays ``--network open-loop`` and
    falls within a second; the identification's figures stay the open-loop network's."""
    import json

    from stumble.cli import main
    from stumble.control.reflex.identify import (
        DEFAULT_NETWORK,
        default_network,
        fit_summary,
    )

    assert DEFAULT_NETWORK == "past-support" and default_network() is default_network(
        "past-support")
    assert fit_summary() == dict(default_network("open-loop").info)
    assert main(["reflex", "walk", "--duration", "3", "--no-video",
                 "--out", str(tmp_path / "d")]) == 0
    d = json.loads((tmp_path / "d" / "summary.json").read_text())
    assert d["walked_s"] == pytest.approx(3.0) and not d["fell"]
    assert main(["reflex", "walk", "--network", "open-loop", "--duration", "3",
                 "--no-video", "--out", str(tmp_path / "o")]) == 0
    o = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert o["fell"] and o["walked_s"] < 1.0


@pytest.mark.parametrize("speed", [1.0, 1.4])
def test_the_placing_expert_walks_from_slow_and_fast_starts(speed):
    """``expert-placement`` (seed003-wired, fitted with ``--starts 1.0,1.4``): 5 s from
    the 1.0 and 1.4 m/s walks, no fall, the knees straight at most (docs/reflex-network.md: 20 s
    from each of 1.0-1.4 m/s, RMSE 7.1/11.1/7.5°)."""
    from stumble.control.reflex.gh2010 import load_params

    p = load_params("expert-placement")
    assert p.wiring == "seed003" and p.k_place > 0.1
    s = simulate_walk("gh2010", 5.0, speed_m_per_s=speed, params=p).summary
    assert not s["fell"] and s["walked_s"] == pytest.approx(5.0)
    assert 1.1 <= s["speed_m_per_s"] <= 1.3 and s["knee_hyperextension_deg"] < 0.1
    assert max(s["rmse_deg"].values()) < 12.0


def test_the_placement_network_walks_closer_to_the_recording(tmp_path):
    """``--network placement``: DAgger from the placing expert, whose placement law the
    network's addition carries; 10 s from the recording's walk, no fall, hip and ankle
    RMSE within 10°, every joint closer than the default network's (15.5/22.0/9.1°)."""
    import json

    from stumble.cli import main
    from stumble.control.reflex.gh2010 import load_params
    from stumble.control.reflex.identify import default_network

    net, expert = default_network("placement"), load_params("expert-placement")
    bal = net.info["balance"]
    assert (bal["k_place"], bal["place_a0"]) == (expert.k_place, expert.place_a0)
    assert main(["reflex", "walk", "--network", "placement", "--duration", "10",
                 "--no-video", "--out", str(tmp_path / "w")]) == 0
    s = json.loads((tmp_path / "w" / "summary.json").read_text())
    assert not s["fell"] and s["walked_s"] == pytest.approx(10.0)
    r = s["rmse_deg"]
    assert r["hip_flexion"] < 10.0 and r["ankle_angle"] < 10.0 and r["knee_angle"] < 20.0
    assert 0.55 <= s["stance_fraction"] <= 0.70 and 0.9 <= s["speed_m_per_s"] <= 1.4


def test_the_walk_held_network_walks_within_ten_degrees_at_every_joint():
    """``--network placement-walk`` (``placement-es`` with each joint's RMSE beyond 9.7 deg
    charged, ``--track-limit``): 20 s from the recording at 0.9-1.4 m/s, stance
    0.55-0.70, hip, knee and ankle each within 10 deg of the recorded stride
    (docs/reflex-network.md:
    6.8/9.7/9.9 deg), the issue's walking target; its record names its start by name."""
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-walk")
    fit = net.info["fit"]
    assert fit["track_limit_deg"] == 9.7 and fit["from"]["network"] == "placement-es"
    assert "--walk-es placement-es" in fit["command"] and "--track-limit 9.7" in fit["command"]
    s = simulate_walk("network", 20.0, network=net).summary
    assert not s["fell"] and 0.9 <= s["speed_m_per_s"] <= 1.4
    assert 0.55 <= s["stance_fraction"] <= 0.70
    assert max(s["rmse_deg"][j] for j in ("hip_flexion", "knee_angle", "ankle_angle")) < 10.0


def test_the_touch_network_walks_as_its_start_and_recovers_an_early_trip_it_could_not():
    """``--network placement-touch``: ``placement-walk`` with a touch response fitted in
    two touch stages (``--touch-only``), so its walk is ``placement-walk``'s bit for bit;
    tripped in its own gait at 0.10 of swing (1.2 m/s) it elevates and walks on 3 s,
    where ``placement-walk`` falls (docs/reflex-network.md: 17 of the 45 against 0)."""
    from stumble.control.reflex.controller import TouchResponse
    from stumble.control.reflex.identify import default_network

    touch, walk = default_network("placement-touch"), default_network("placement-walk")
    assert TouchResponse.from_info(touch.info, touch.topology.muscles).on
    fit = touch.info["fit"]
    assert fit["touch_only"] and fit["from"]["its_fit"]["touch_only"]
    assert fit["from"]["its_fit"]["from"]["network"] == "placement-walk"
    a, b = (simulate_walk("network", 2.0, network=n).recording.qpos for n in (touch, walk))
    assert np.array_equal(a, b)
    sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.10,
                  speed_m_per_s=1.2, start="own")
    s = simulate_trip(sc, network=touch).summary
    assert s["strategy"] == "elevating" and s["recovered"] and not s["fell"]
    assert not simulate_trip(sc, network=walk).summary["recovered"]


def test_the_network_with_a_response_by_the_foots_place_lowers_a_late_trip():
    """``--network placement-foot`` (the touch response by the foot's place, two touch
    stages on ``placement-walk``): tripped in its own gait at 0.70 of swing (1.2 m/s) it
    lowers and walks on 3 s, its walk ``placement-walk``'s; but at 3 s it has not got past
    the box, so it is not recovered (since 2026-12-07: 9 of the 45 and none by lowering,
    12 and 3 counted as the fits that made it counted, ``past_obstacle=False``)."""
    from stumble.control.reflex.controller import TouchResponse
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-foot")
    assert TouchResponse.from_info(net.info, net.topology.muscles).by_foot
    assert net.info["fit"]["from"]["its_fit"]["from"]["network"] == "placement-walk"
    sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.70,
                  speed_m_per_s=1.2, start="own")
    s = simulate_trip(sc, network=net).summary
    assert s["strategy"] == "lowering" and not s["recovered"] and not s["fell"]
    assert s["stop_reason"] == "not past the obstacle"
    assert simulate_trip(sc, network=net, past_obstacle=False).summary["recovered"]


@pytest.mark.parametrize(("swing", "speed", "strategy"),
                         [(0.10, 1.2, "elevating"), (0.70, 1.0, "lowering")])
def test_placement_both_recovers_early_and_late_trips_with_both_strategies(
        swing, speed, strategy):
    """``--network placement-both`` (the default until 2026-12-07): ``placement-touch``'s
    response for a touch of the foot behind, ``placement-foot``'s sets and durations for
    the foot ahead, nothing fitted (``--generations 0``), its walk ``placement-walk``'s
    bit for bit.
    Tripped in its own gait at 0.10 of swing (1.2 m/s) it elevates and at 0.70 (1.0 m/s)
    it lowers, each time walking on 3 s past the box (docs/reflex-network.md: 18 of the
    45, 1 by lowering)."""
    from stumble.control.reflex.controller import TouchResponse
    from stumble.control.reflex.identify import default_network

    net, touch, foot = (default_network(n) for n in ("placement-both", "placement-touch",
                                                       "placement-foot"))
    r, rt, rf = (TouchResponse.from_info(n.info, n.topology.muscles)
                 for n in (net, touch, foot))
    assert r.by_foot and r.gains["ipsi"] == rt.gains["ipsi"] and r.hold == rt.hold
    assert r.gains["contra_ahead"] == rf.gains["contra_ahead"] and r.hold_ahead == rf.hold
    fit = net.info["fit"]
    assert fit["generations"] == 0 and fit["ahead_from"]["network"] == "placement-foot"
    assert "--ahead-from placement-foot --generations 0" in fit["command"]
    s = simulate_trip(Scenario(controller="reflex", mechanism="obstacle", swing_fraction=swing,
                               speed_m_per_s=speed, start="own"), network=net).summary
    assert s["strategy"] == strategy and s["recovered"] and not s["fell"]


def test_placement_boths_chain_of_commands_is_read_from_its_file():
    """``scripts/network_chain.py`` (``reproduce.stages``): the commands that made
    ``placement-both``, oldest
    first, from ``placement`` (shipped) through six CMA-ES stages, each ``--out`` the next
    one's start, the last the combination by ``--ahead-from`` with no search; a network
    without CMA-ES stages is one clear error."""
    import importlib.util
    import subprocess
    import sys
    from pathlib import Path

    from stumble.control.reflex.identify import NETWORK_NAMES, default_network

    path = Path(__file__).resolve().parents[4] / "scripts" / "network_chain.py"
    spec = importlib.util.spec_from_file_location("network_chain", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    from stumble.control.reflex.reproduce import stages

    fit = default_network("placement-both").info["fit"]
    st = stages(fit)
    assert len(st) == 6 and st[0].start == "placement"
    assert [s.start for s in st[1:]] == ["es1/network.npz", "placement-es",
                                         "placement-walk", "tr3/network.npz",
                                         "placement-touch"]
    assert st[-1].ahead_from == "placement-foot"
    lines = mod.commands(fit, set(NETWORK_NAMES))
    cmds = [ln for ln in lines if ln.startswith("stumble ")]
    assert "--out es1/" in cmds[0] and "--out tr3/" in cmds[3]
    assert "--out placement-walk/  # shipped as 'placement-walk'" in cmds[2]
    assert "--ahead-from placement-foot --generations 0" in cmds[-1]
    r = subprocess.run([sys.executable, str(path), "placement"], capture_output=True,
                       text=True)
    assert r.returncode == 2 and "records no CMA-ES stage" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("controller", ["reflex", "gh2010"])
def test_delays_response_slows_the_touch_response_and_not_the_walk(controller):
    """``Scenario.delays`` response: ``delay_scale`` multiplies the touch response's
    delays alone (the network's ``TouchResponse``, Geyer & Herr's stumbling corrective
    reflex and crossing step). The walk to the trip is the same as at × 1, and at × 1.5
    the trip at 0.10 of swing, 1.2 m/s, that each default recovers is a fall; with
    every delay × 1.5 the network falls in the walk-in, before the trip."""
    from dataclasses import replace

    from stumble.control.reflex.gh2010 import GH2010Params, shipped_params
    from stumble.control.reflex.identify import default_network
    from stumble.errors import InputError

    sc = Scenario(controller=controller, mechanism="obstacle", swing_fraction=0.1,
                  speed_m_per_s=1.2, start="own")
    a = simulate_trip(sc)
    one = simulate_trip(sc.with_(delays="response"))  # × 1: the same run, bit for bit
    assert np.array_equal(one.recording.qpos, a.recording.qpos)
    a = a.summary
    b = simulate_trip(sc.with_(delay_scale=1.5, delays="response")).summary
    assert a["recovered"] and b["fell"] and b["delays"] == "response"
    assert b["walk_in"] == a["walk_in"] and b["trip_time_s"] == a["trip_time_s"]
    if controller == "reflex":
        c = simulate_trip(sc.with_(delay_scale=1.5)).summary
        assert c["walk_in"]["fell"] and c["trip_time_s"] is None
        with pytest.raises(InputError, match="this network has none"):  # no response
            simulate_trip(sc.with_(delay_scale=1.5, delays="response"),
                          network=default_network("placement-walk"))
    else:
        p = shipped_params()
        q = replace(p, response_delay_scale=1.5)  # a run's setting, not a parameter:
        assert q.to_json() == p.to_json() and "response_delay_scale" not in p.free()
        with pytest.raises(InputError, match="unknown GH2010 parameter"):
            GH2010Params.from_json({**p.to_json(), "response_delay_scale": 2.0})
        # the walk to a first touch does not depend on it, but a controller's taps do:
        # a walk-in cached with one is not gone on with the other (``retouch`` refuses)
        from stumble.control.reflex.gh2010 import GH2010Controller

        assert GH2010Controller(q).walk_key() != GH2010Controller(p).walk_key()


def test_the_experts_touch_stage_recovers_a_trip_the_expert_falls_from(capsys, tmp_path):
    """``--params expert-touch`` (``reflex fit --wiring seed003 --trips --params
    expert-placement --touch-only ...``): the network's expert, seed003-wired, with the
    touch's reflexes fitted, walks as the expert (the touch's reflexes alone changed) and
    walks on from the trip at 0.10 of swing, 1.2 m/s, where the expert falls. A seed003
    trip stage without a seed003-wired start is one line and exit 2."""
    from stumble.cli import main
    from stumble.control.reflex.gh2010 import TOUCH_FIELDS, load_params

    p, q = load_params("expert-touch"), load_params("expert-placement")
    assert p.wiring == q.wiring == "seed003"
    assert all(getattr(p, f) == getattr(q, f) for f in p.to_json() if f not in TOUCH_FIELDS)
    sc = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=0.1,
                  speed_m_per_s=1.2)
    s = simulate_trip(sc, gh2010=p).summary
    assert s["strategy"] == "elevating" and s["recovered"]
    assert not simulate_trip(sc, gh2010=q).summary["recovered"]
    for argv, words in ((["--wiring", "seed003", "--trips"],
                         "--trips --wiring seed003 starts from a seed003-wired set"),
                        (["--wiring", "seed003", "--trips", "--params", "knee"],
                         "is wired gh2010: the trip stage starts from a seed003-wired set")):
        assert main(["reflex", "fit", "--controller", "gh2010", *argv,
                     "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err


def test_the_network_fitted_past_the_box_lowers_and_gets_past_it():
    """``--network past-foot``: ``placement-foot``'s two touch stages re-run on
    ``placement-walk`` with ``--past-obstacle`` (recorded in each command), its walk
    ``placement-walk``'s bit for bit. Tripped in its own gait at 0.65 of swing (1.0 m/s)
    it lowers and walks on 3 s with both ankles past the box (docs/reflex-network.md: 23
    of the 45, 14 of the 28 held out)."""
    from stumble.control.reflex.identify import default_network

    net, walk = default_network("past-foot"), default_network("placement-walk")
    fit = net.info["fit"]
    assert "--past-obstacle" in fit["command"] and fit["past_obstacle"]
    assert "--past-obstacle" in fit["from"]["its_fit"]["command"]
    assert fit["from"]["its_fit"]["from"]["network"] == "placement-walk"
    a, b = (simulate_walk("network", 2.0, network=n).recording.qpos for n in (net, walk))
    assert np.array_equal(a, b)
    r = simulate_trip(Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.65,
                               speed_m_per_s=1.0, start="own"), network=net)
    assert r.summary["strategy"] == "lowering" and r.summary["recovered"]
    m = r.body.model
    box = m.geom("obstacle").id
    assert r.summary["stop_reason"] == "recovered"
    assert r.recording.com[-1, 0] > m.geom_pos[box, 0] + m.geom_size[box, 0]


def test_the_network_that_swings_the_other_leg_recovers_lowering_trips_past_foot_does_not():
    """``--network past-swing`` (the default for part of 2026-12-07): ``past-foot`` with its
    response to a touch of the foot ahead swinging the other leg through (``contra_ahead``:
    HFL 1, GLU -1, HAMS -1, VAS -1, set by hand, ``reflex fit --set-response``, recorded;
    the fit had braced that leg, GLU 1 and HFL -1), every other gain ``past-foot``'s and
    its walk ``placement-walk``'s bit for bit. Tripped in its own gait at 0.70 of swing,
    1.2 m/s, ``past-foot`` does not recover; ``past-swing`` lowers and walks on 3 s past
    the box (docs/reflex-network.md: 30 of the 45, 8 by lowering; ``past-foot`` 23, 1)."""
    from stumble.control.reflex.identify import default_network

    net, before = default_network("past-swing"), default_network("past-foot")
    fit = net.info["fit"]
    assert ("--set-response contra_ahead.GLU=-1,contra_ahead.HFL=1,contra_ahead.HAMS=-1,"
            "contra_ahead.VAS=-1 --generations 0") in fit["command"]
    assert fit["from"]["network"] == "past-foot" and fit["generations"] == 0
    mine, theirs = net.info["touch_response"], before.info["touch_response"]
    assert {k: mine["contra_ahead"][k] for k in ("HFL", "GLU", "HAMS", "VAS")} == {
        "HFL": 1.0, "GLU": -1.0, "HAMS": -1.0, "VAS": -1.0}
    assert (theirs["contra_ahead"]["GLU"], theirs["contra_ahead"]["HFL"]) == (1.0, -1.0)
    assert {k: v for k, v in mine.items() if k != "contra_ahead"} == {
        k: v for k, v in theirs.items() if k != "contra_ahead"}
    a, b = (simulate_walk("network", 2.0, network=n).recording.qpos
            for n in (net, default_network("placement-walk")))
    assert np.array_equal(a, b)
    sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.7,
                  speed_m_per_s=1.2, start="own")
    assert not simulate_trip(sc, network=before).summary["recovered"]
    r = simulate_trip(sc, network=net)
    assert r.summary["strategy"] == "lowering" and r.summary["stop_reason"] == "recovered"
    m = r.body.model
    box = m.geom("obstacle").id
    assert r.recording.com[-1, 0] > m.geom_pos[box, 0] + m.geom_size[box, 0]


def test_the_support_glu_and_tripped_vas_set_by_hand_recover_two_trips_past_swing_loses():
    """``--network past-support`` (the default since 2026-12-07, twenty-fourth session):
    ``past-swing`` with, after a touch of the foot behind, the support leg's GLU on
    (``contra``: 1, fitted 0.07) and the tripped leg's VAS off (``ipsi``: 0, fitted -0.46),
    set by hand and recorded; every other gain and every weight ``past-swing``'s, its walk
    ``placement-walk``'s bit for bit. Of the 45 it gains two trips (docs/reflex-network.md:
    32, 9 by lowering, against 30): 0.40 of swing at 1.2 m/s and 0.75 at 1.0 m/s, where
    ``past-swing`` takes the same strategy (elevating, lowering) and falls; each recovers
    past the box."""
    from stumble.control.reflex.identify import default_network

    net, before = default_network("past-support"), default_network("past-swing")
    fit = net.info["fit"]
    assert "--set-response contra.GLU=1,ipsi.VAS=0 --generations 0" in fit["command"]
    assert fit["from"]["network"] == "past-swing" and fit["generations"] == 0
    mine, theirs = net.info["touch_response"], before.info["touch_response"]
    assert (mine["contra"]["GLU"], mine["ipsi"]["VAS"]) == (1.0, 0.0)
    assert theirs["contra"]["GLU"] == pytest.approx(0.0736, abs=1e-4)
    assert theirs["ipsi"]["VAS"] == pytest.approx(-0.4635, abs=1e-4)
    changed = {"contra": "GLU", "ipsi": "VAS"}
    for name, value in mine.items():
        if name in changed:
            assert {m: g for m, g in value.items() if m != changed[name]} == {
                m: g for m, g in theirs[name].items() if m != changed[name]}
        else:
            assert value == theirs[name]
    assert set(mine) == set(theirs)
    for k in ("w", "b", "v", "c", "mean", "std"):
        assert np.array_equal(getattr(net, k), getattr(before, k))
    a, b = (simulate_walk("network", 2.0, network=n).recording.qpos
            for n in (net, default_network("placement-walk")))
    assert np.array_equal(a, b)
    for swing, speed, strategy in ((0.4, 1.2, "elevating"), (0.75, 1.0, "lowering")):
        sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=swing,
                      speed_m_per_s=speed, start="own")
        lost = simulate_trip(sc, network=before).summary
        assert lost["strategy"] == strategy and lost["stop_reason"] == "fell"
        r = simulate_trip(sc, network=net)
        assert r.summary["strategy"] == strategy
        assert r.summary["stop_reason"] == "recovered"
        m = r.body.model
        box = m.geom("obstacle").id
        assert r.recording.com[-1, 0] > m.geom_pos[box, 0] + m.geom_size[box, 0]


@pytest.mark.parametrize("name", ["past-swing", "past-support"])
def test_the_recorded_set_response_stage_remakes_the_shipped_network(name, tmp_path):
    """A network's recorded command (``--set-response ... --generations 0`` from the one
    before: ``past-foot`` for ``past-swing``, ``past-swing`` for ``past-support``), run
    again, writes the shipped network: weights and response equal."""
    import shlex

    from stumble.cli import main
    from stumble.control.reflex.identify import default_network
    from stumble.control.reflex.network import Network

    shipped = default_network(name)
    argv = shlex.split(shipped.info["fit"]["command"].replace("DIR", str(tmp_path / "o")))
    assert argv[:3] == ["stumble", "reflex", "fit"]
    assert main([*argv[1:], "--no-video", "--workers", "1"]) == 0
    made = Network.load(tmp_path / "o" / "network.npz")
    assert made.info["touch_response"] == shipped.info["touch_response"]
    for k in ("w", "b", "v", "c", "mean", "std"):
        assert np.array_equal(getattr(made, k), getattr(shipped, k))


def test_a_touch_stage_records_its_hand_set_gains_and_trunk_limit_exactly(tmp_path):
    """``reflex fit --set-response`` on a response given a recovery step first
    (``--cross-step``: its ``cross`` set, checked in the order the fit builds it) and
    ``--max-tilt``: the command records each value exactly (a gain of 0.123456789, a limit
    of 26.5 deg), the fit's record holds them, the workers' objective was given the limit,
    and the recorded gains parse back to the same numbers."""
    import shlex

    from stumble.cli import main
    from stumble.control.reflex import fit_walk
    from stumble.control.reflex.network import Network

    assert main(["reflex", "fit", "--walk-es", "past-swing", "--touch-only",
                 "--touch-response", "--scr-phase", "foot", "--cross-step",
                 "--set-response", "cross.HFL=0.123456789,contra.GLU=-1", "--generations", "0",
                 "--trip-set", "wide", "--recovery-cost", "10", "--past-obstacle",
                 "--max-tilt", "26.5", "--workers", "1", "--no-video",
                 "--out", str(tmp_path / "o")]) == 0
    net = Network.load(tmp_path / "o" / "network.npz")
    fit = net.info["fit"]
    assert "--set-response cross.HFL=0.123456789,contra.GLU=-1 " in fit["command"]
    assert "--past-obstacle --max-tilt 26.5 " in fit["command"]
    assert fit["max_tilt_deg"] == 26.5 and fit_walk._EVAL["max_tilt_deg"] == 26.5
    resp = net.info["touch_response"]
    assert resp["cross"]["HFL"] == 0.123456789 and resp["contra"]["GLU"] == -1.0
    argv = shlex.split(fit["command"])
    got = fit_walk.parse_set_response(argv[argv.index("--set-response") + 1])
    assert got == {"cross": {"HFL": 0.123456789}, "contra": {"GLU": -1.0}}
