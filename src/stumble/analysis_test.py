"""The outcome readers of ``stumble.analysis`` on synthetic sensor streams."""

from types import SimpleNamespace

import numpy as np
import pytest

from stumble.analysis import TripTimer, airborne_before_landing_s, variant

DT = 0.005  # the recording's sample (s)


def _feed(timer: TripTimer, left_on, t0: float = 0.0):
    """Run the timer over a left foot's floor contact (one bool per 5 ms sample); the
    time (s) of the sample it trips at, or None."""
    for i, on in enumerate(left_on):
        s = SimpleNamespace(t=t0 + i * DT, segment_on_floor=False, pelvis_height=0.9,
                            foot_on_floor={"l": bool(on), "r": True})
        if timer(s) == "trip":
            return s.t
    return None


def _strides(n: int, stance: int = 120, swing: int = 120, brush_at: int | None = None,
             brush: int = 2) -> list[bool]:
    """n strides of stance then swing (samples), the swing brushing the floor for
    ``brush`` samples ``brush_at`` samples after toe-off."""
    out = []
    for _ in range(n):
        sw = [False] * swing
        if brush_at is not None:
            sw[brush_at:brush_at + brush] = [True] * brush
        out += [True] * stance + sw
    return out


@pytest.mark.parametrize("brush_at", [None, 54])
def test_a_brush_of_the_swinging_foot_is_not_a_landing(brush_at):
    """Swings of 0.6 s (120 samples), with or without a 10 ms brush of the floor 0.27 s
    after toe-off (as a walker whose foot scuffs mid-swing): the swing is measured
    toe-off to lasting touch, 0.6 s, and the trip falls at 0.75 of it, 0.45 s after the
    toe-off; read brush to brush, swings of 0.27 and 0.32 s would trip it at 0.22 s."""
    timer = TripTimer("l", 0.75, after_s=2.0, fall_height_m=0.5)
    t = _feed(timer, _strides(4, brush_at=brush_at))
    assert timer.swings_s[-2:] == pytest.approx([0.6, 0.6])
    assert timer.trip_swing_s == pytest.approx(0.6)
    assert t - timer.toe_off_s == pytest.approx(0.45)
    assert timer.toe_off_s == pytest.approx(2 * 1.2 + 0.6)  # the first after 2 s


@pytest.mark.parametrize("brush_at", [None, 54])
def test_the_trip_timer_says_truly_until_when_nothing_but_a_fall_can_stop_the_walk(
        brush_at):
    """``TripTimer.quiet_until_s`` and ``watch_foot`` (what lets ``sim.run`` hand whole
    blocks to a compiled loop): at every sample, the trip comes no earlier than the time
    it gave at the sample before while the watched foot kept its contact; in a counted
    swing that time is the trip instant itself, and before the first sample nothing is
    promised."""
    timer = TripTimer("l", 0.75, after_s=2.0, fall_height_m=0.5)
    assert timer.quiet_until_s == 0.0 and timer.watch_foot is None
    promised = []
    tripped = None
    for i, on in enumerate(_strides(4, brush_at=brush_at)):
        q, w = timer.quiet_until_s, timer.watch_foot
        s = SimpleNamespace(t=i * DT, segment_on_floor=False, pelvis_height=0.9,
                            foot_on_floor={"l": bool(on), "r": True})
        why = timer(s)
        if w is not None and bool(on) == w[1]:  # the watched contact held: promise kept
            assert why == "" or s.t >= q - 1e-12
            promised.append(q)
        if why:
            tripped = s.t
            break
    assert tripped == pytest.approx(3.0 + 0.45)  # the first counted swing after 2 s
    assert min(q for q in promised if np.isfinite(q)) == pytest.approx(tripped)
    assert promised.count(np.inf) > 100  # in stance, and swings that do not count


def test_a_touch_lasting_three_samples_is_a_landing():
    """Three samples (15 ms, ``TOUCHDOWN_SAMPLES``) on the floor end the swing, dated
    from the first: 0.27 s swings of a foot that lands there and lifts again."""
    timer = TripTimer("l", 0.5, after_s=100.0, fall_height_m=0.5)
    assert _feed(timer, _strides(3, brush_at=54, brush=3)) is None
    assert timer.swings_s[0] == pytest.approx(0.27)


def test_steps_to_steady_counts_the_steps_until_two_in_a_row_walk_as_the_walk_on():
    """A recovery's walking on: the first of two steps in a row within 15 % of the gait's
    own step time (the median of its last four) and of the speed before the trip."""
    from stumble.analysis import steps_to_steady, walk_on_speed, walk_on_step_s

    settled = [(0.40, 1.2)] * 4
    assert walk_on_step_s(settled) == 0.40 and walk_on_speed(settled) == 1.2
    assert walk_on_speed([(0.5, 2.0), (0.4, 1.0), (0.4, 1.1), (0.4, 1.3), (0.4, 1.2)]) \
        == pytest.approx(1.15)  # the last four's median
    # long, fast steps first (elevating trips), then the gait settles
    assert steps_to_steady([(0.48, 1.40), (0.44, 1.42), (0.42, 1.30), *settled], 1.2) == 3
    assert steps_to_steady(settled, 1.2) == 1
    # one steady step between unsteady ones is not a steady gait
    assert steps_to_steady([(0.40, 1.2), (0.60, 1.2), (0.41, 1.25), *settled], 1.2) == 3
    # walking on far slower than before the trip never becomes steady
    assert steps_to_steady([(0.40, 0.9)] * 6, 1.2) is None
    assert steps_to_steady(settled[:3], 1.2) is None and walk_on_step_s(settled[:3]) is None
    # the tolerance is a parameter
    assert steps_to_steady([(0.40, 1.05)] * 5, 1.2) == 1
    assert steps_to_steady([(0.40, 1.05)] * 5, 1.2, tolerance=0.1) is None


def test_a_walk_on_recovery_reports_its_steps_and_when_its_gait_is_steady():
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    s = simulate_trip(Scenario(swing_fraction=0.15, recovery="walk_on",
                               duration_after_trip_s=6.0)).summary
    assert s["recovered"]
    steps = s["walk_on_steps"]
    assert len(steps) == s["steps_after_recovery_step"] >= 4
    assert all(0.2 < x["duration_s"] < 1.0 and 0.5 < x["speed_m_per_s"] < 2.0 for x in steps)
    assert 1 <= s["steps_to_steady_gait"] <= len(steps) - 1
    assert 0.3 < s["walk_on_step_s"] < 0.7
    assert s["walk_on_speed_m_per_s"] == pytest.approx(
        np.median([x["speed_m_per_s"] for x in steps[-4:]]), abs=1e-4)


def test_the_walk_on_reports_where_it_heads():
    """``walk_on_heading_deg`` and ``sideways_m``: a force trip at 0.25 of swing (1.2 m/s)
    walks on straight; one at 0.65 (1.4 m/s) walks on 27 deg to the right of the walk
    before, 2.6 m to the side after 6 s (the largest of the 48-trip grid with the
    ``knee_cap`` set, the default until 2026-12-07; ``flight_from_fall`` veers 6 deg
    there); the step speeds along x read the veer as slower (1.10 m/s, 1.23 along its
    path). The planar reflex body has no sideways: None."""
    from stumble.control.fsm_params import load_params
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    p = load_params("knee_cap")
    straight = simulate_trip(Scenario(mechanism="force", swing_fraction=0.25,
                                      speed_m_per_s=1.2), params=p).summary
    veers = simulate_trip(Scenario(mechanism="force", swing_fraction=0.65,
                                   speed_m_per_s=1.4), params=p).summary
    assert straight["recovered"] and veers["recovered"]
    assert abs(straight["walk_on_heading_deg"]) < 1.0 and abs(straight["sideways_m"]) < 0.2
    assert veers["walk_on_heading_deg"] == pytest.approx(-26.8, abs=0.5)
    assert veers["sideways_m"] == pytest.approx(-2.62, abs=0.05)
    along = veers["walk_on_speed_m_per_s"] / np.cos(np.radians(veers["walk_on_heading_deg"]))
    assert along == pytest.approx(1.23, abs=0.01)
    reflex = simulate_trip(Scenario(controller="reflex", swing_fraction=0.3)).summary
    assert reflex["walk_on_heading_deg"] is None and reflex["sideways_m"] is None


def test_walk_on_steps_counts_both_feet_striking_at_one_sample_as_one_step():
    """A reflex walker's trip ended with both feet landing at the same sample: one step,
    not a step of no time (which divided by zero and stopped a fit)."""
    from types import SimpleNamespace

    from stumble.analysis import walk_on_steps

    t = np.arange(0.0, 2.0, 0.005)
    on = np.zeros((len(t), 2), bool)
    on[(t >= 0.5) & (t < 0.7), 0] = True  # the recovery step at 0.5 s
    on[(t >= 1.0) & (t < 1.3), :] = True  # both feet strike at 1.0 s
    on[t >= 1.6, 1] = True
    rec = SimpleNamespace(time_s=t, foot_on_floor=on, qpos=np.c_[1.2 * t, np.zeros_like(t)])
    steps = walk_on_steps(rec, 0.5)
    assert [round(d, 3) for d, _v in steps] == [0.5, 0.6]
    assert all(abs(v - 1.2) < 1e-9 for _d, v in steps)


def test_fallen_rows_read_as_sensors_do():
    """``sim.fallen`` over a falling trip's sensor rows: per row what ``Sensors`` reads
    (a segment on the floor, or the pelvis below the height), and true at its end."""
    from stumble.control.reflex.identify import default_network
    from stumble.pipeline import simulate_trip
    from stumble.sim import Sensors, fallen
    from stumble.trip import Scenario

    # CASE 1 from the recording: placement-both falls (past-support, the default since
    # 2026-12-07, recovers, as past-swing did)
    r = simulate_trip(Scenario(controller="reflex", start="playback", mechanism="obstacle",
                               swing_fraction=0.13, speed_m_per_s=1.2),
                      network=default_network("placement-both"))
    rec, lay = r.recording, r.body.sensors
    h = 0.8 * float(np.median(rec.sensordata[:20, lay.decode_index[13]]))
    got = fallen(lay, rec.sensordata, h)
    want = [Sensors(lay, row).segment_on_floor or Sensors(lay, row).pelvis_height < h
            for row in rec.sensordata]
    assert got.tolist() == want
    assert r.summary["fell"] and got[-1] and not got[0]


def test_the_body_angular_momentum_is_conserved_in_flight_and_zero_in_translation():
    """``angular_momentum`` about the centre of mass: the body thrown in the air, its
    joints free, keeps it (gravity acts at the COM; the joints' torques are internal), and
    a body moving without rotating has none."""
    import mujoco

    from stumble.analysis import angular_momentum
    from stumble.body.build import build

    m = build().model
    m.opt.gravity[:] = (0.0, 0.0, -9.81)
    d = mujoco.MjData(m)
    d.qpos[2] = 5.0  # well above the floor
    rng = np.random.default_rng(0)
    d.qvel[:] = rng.normal(0.0, 1.0, m.nv)
    qs, vs = [], []
    for _ in range(100):  # 0.2 s at 2 ms
        qs.append(d.qpos.copy())
        vs.append(d.qvel.copy())
        mujoco.mj_step(m, d)
    ang = angular_momentum(m, np.array(qs), np.array(vs))
    assert np.abs(ang[0]).max() > 1.0  # it spins
    assert np.abs(ang - ang[0]).max() < 0.02 * np.abs(ang[0]).max()
    still = np.zeros((1, m.nv))
    still[0, :3] = (1.2, 0.3, -0.5)  # the root's translation only
    assert np.abs(angular_momentum(m, np.array(qs[:1]), still)).max() < 1e-9


def test_the_trips_contact_joins_gaps_shorter_than_20_ms():
    """``trip_contact_s``: the tripped foot's first contact with the box, its brief losses
    (a sample or two, sliding along the edge) joined; a later touch is not part of it."""
    from stumble.analysis import trip_contact_s

    t = np.arange(-0.1, 1.0, DT)
    on = np.zeros((len(t), 2), bool)
    on[(t >= 0.005) & (t < 0.03), 1] = True
    on[(t >= 0.04) & (t < 0.06), 1] = True  # 10 ms off in between: one contact
    on[(t >= 0.3) & (t < 0.35), 1] = True  # later, the foot touches the box again
    rec = SimpleNamespace(time_s=t, foot_on_obstacle=on, trip_force=np.zeros((len(t), 3)))
    a, b = trip_contact_s(rec, "l", "obstacle")
    assert a == pytest.approx(0.005) and b == pytest.approx(0.055)
    assert trip_contact_s(rec, "r", "obstacle") is None
    rec.trip_force[(t > -1e-9) & (t < 0.1 + 1e-9), 0] = -300.0  # the force trip: while it acts
    assert trip_contact_s(rec, "r", "force") == pytest.approx((0.0, 0.1))


def test_a_mid_swing_trip_gains_what_people_gain_and_the_support_leg_takes_it_all_out():
    """An obstacle trip at 0.35 of swing, 1.2 m/s (the ``knee_cap`` set, the default
    until 2026-12-07): over the foot's 56 ms on the box the body gains 10.9 kg·m²/s of
    forward angular momentum, within 5 % of people's 11.4 over mid-swing trips
    (Pijnappels et al. 2004); by the recovery foot's contact (0.42 s) the support leg has
    taken all of it out (-0.2). The default ``rec_hip_cap`` gains 10.8 and still holds
    2.5 at its later contact (0.448 s; ``flight_from_fall`` 2.7 at 0.456 s): its support
    leg takes most of it out."""
    from stumble.analysis import PEOPLE_TRIP_ANGMOM_GAIN
    from stumble.control.fsm_params import load_params
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    s = simulate_trip(Scenario(mechanism="obstacle", swing_fraction=0.35,
                               speed_m_per_s=1.2), params=load_params("knee_cap")).summary
    am = s["angular_momentum_kg_m2_per_s"]
    assert am["gained_in_contact"] == pytest.approx(10.89, abs=0.1)
    assert abs(am["gained_in_contact"] / PEOPLE_TRIP_ANGMOM_GAIN - 1.0) < 0.05
    assert am["contact_s"] == pytest.approx(0.056, abs=0.005)
    assert am["peak"] >= am["at_trip"] + am["gained_in_contact"] - 0.5
    assert s["recovery_contact_s"] == pytest.approx(0.42, abs=0.01)
    assert am["at_recovery_contact"] == pytest.approx(-0.2, abs=0.3)
    d = simulate_trip(Scenario(mechanism="obstacle", swing_fraction=0.35,
                               speed_m_per_s=1.2)).summary
    dam = d["angular_momentum_kg_m2_per_s"]
    assert dam["gained_in_contact"] == pytest.approx(10.81, abs=0.1)
    assert d["recovery_contact_s"] == pytest.approx(0.448, abs=0.01)
    assert 0.0 < dam["at_recovery_contact"] < 0.5 * dam["gained_in_contact"]
    assert dam["at_recovery_contact"] == pytest.approx(2.7, abs=0.3)


def test_a_body_that_walks_back_into_the_box_has_not_recovered():
    """The network ``placement-both``'s lowering trip at 0.7 of swing, 1.2 m/s: its
    tripped foot stands on the box, the body rocks back from it (the COM 0.4 m back by
    1.6 s), and at 3 s it walks into the box again, upright and advancing: "still
    walking", but not past the obstacle, so not recovered (2026-12-07); the fits' rule
    (``past_obstacle=False``) counts it as they did. An elevating trip that stepped over
    walks on 3 m past it."""
    from stumble.control.reflex.identify import default_network
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    net = default_network("placement-both")
    back = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.7,
                    speed_m_per_s=1.2)
    now = simulate_trip(back, network=net).summary
    assert not now["recovered"] and not now["fell"]
    assert now["stop_reason"] == "not past the obstacle"
    before = simulate_trip(back, network=net, past_obstacle=False).summary
    assert before["recovered"] and before["strategy"] == "lowering"
    over = simulate_trip(Scenario(controller="reflex", mechanism="obstacle",
                                  swing_fraction=0.1, speed_m_per_s=1.2))
    assert over.summary["recovered"]
    m = over.body.model
    box = m.geom("obstacle").id
    far = m.geom_pos[box, 0] + m.geom_size[box, 0]  # the box's far face, world x (m)
    assert over.recording.com[-1, 0] > far + 2.0


def test_the_variant_is_how_the_recovery_foot_lands():
    """``flight`` only when both feet are off the floor for the 20 ms before the recovery
    landing; a hop of the other foot that is down again by then, or a flicker at the
    takeover, is double support (both counted as time airborne)."""
    t = np.round(np.arange(0.0, 0.6, 0.004), 4)
    on = np.ones((len(t), 2), bool)

    def rec(off: list[tuple[float, float, int]]):
        f = on.copy()
        for a, b, col in off:
            f[(t >= a) & (t < b), col] = False
        return SimpleNamespace(time_s=t, foot_on_floor=f)

    swing = (0.0, 0.5, 1)  # the recovery foot in the air until it lands at 0.5 s
    hop = rec([swing, (0.30, 0.40, 0)])
    assert variant(hop, 0.5) == "double_support"
    assert airborne_before_landing_s(hop, 0.5) == pytest.approx(0.1)
    flight = rec([swing, (0.44, 0.52, 0)])
    assert variant(flight, 0.5) == "flight"
    assert airborne_before_landing_s(flight, 0.5) == pytest.approx(0.06)
    late = rec([swing, (0.49, 0.52, 0)])  # off only 12 ms before the landing
    assert variant(late, 0.5) == "double_support"
    flicker = rec([swing, (0.008, 0.02, 0)])
    assert variant(flicker, 0.5) == "double_support"
    assert airborne_before_landing_s(flicker, 0.5) == 0.0
    assert variant(flight, None) is None and airborne_before_landing_s(flight, None) is None
