"""The closed-loop walking objective and the seeded evolution strategy."""

import numpy as np
import pytest

from stumble.analysis import contact_events
from stumble.control.reflex.fit_walk import (
    W_FALL,
    cma_fit,
    evaluate_walk,
    gh2010_space,
    init_walk_eval,
    network_space,
    network_with,
    walk_cost,
)


def _summary(walked=10.0, distance=11.0, rmse=(5.0, 6.0, 7.0), speed=1.1, stance=0.62):
    return {"walked_s": walked, "duration_s": 10.0, "distance_m": distance,
            "rmse_deg": dict(zip(("hip_flexion", "knee_angle", "ankle_angle"), rmse,
                                 strict=True)),
            "speed_m_per_s": speed, "stance_fraction": stance, "diverged": False}


def test_walking_on_beats_falling_and_standing_still():
    walk, _ = walk_cost(_summary(), effort=0.05)
    fall, t_fall = walk_cost(_summary(walked=2.5, distance=2.8), effort=0.05)
    stand, t_stand = walk_cost(_summary(distance=0.3, speed=0.03), effort=0.01)
    assert walk < 2.0 < fall and walk < stand
    assert t_fall["fall"] == pytest.approx(W_FALL * 0.75)  # a quarter of the way
    assert t_stand["fall"] == pytest.approx(W_FALL * 0.97)  # standing covers no way


def test_each_joint_beyond_eight_degrees_costs_and_bands_are_free_inside():
    _base, t0 = walk_cost(_summary(rmse=(7.0, 7.0, 7.0)), effort=0.0)
    _worse, t1 = walk_cost(_summary(rmse=(7.0, 12.0, 7.0)), effort=0.0)
    assert t1["track"] - t0["track"] == pytest.approx(
        (np.sqrt((49 + 144 + 49) / 3) - 7.0) / 10.0 + (12.0 - 8.0) / 2.0)
    assert t0["speed"] == t0["stance"] == 0.0
    _, slow = walk_cost(_summary(speed=0.8), effort=0.0)
    assert slow["speed"] == pytest.approx(((1.0 - 0.8) / 0.1) ** 2)


def test_the_track_limit_costs_twenty_a_degree_beyond_it_only_when_asked():
    """``track_limit_deg`` (``--track-limit``): each joint's RMSE beyond it costs 20 a
    degree (knee 16.7 and ankle 13.5 against a limit of 10: 20 × (6.7 + 3.5)); none
    inside it, and no term without it."""
    _, plain = walk_cost(_summary(rmse=(9.0, 16.7, 13.5)), effort=0.0)
    cost, terms = walk_cost(_summary(rmse=(9.0, 16.7, 13.5)), effort=0.0,
                            track_limit_deg=10.0)
    assert "track_limit" not in plain
    assert terms["track_limit"] == pytest.approx(20.0 * (6.7 + 3.5))
    assert cost == pytest.approx(sum(plain.values()) + terms["track_limit"])
    _, inside = walk_cost(_summary(rmse=(9.0, 9.9, 10.0)), effort=0.0, track_limit_deg=10.0)
    assert inside["track_limit"] == 0.0


def test_the_foot_term_counts_only_when_asked_and_like_a_joint():
    plain, t_plain = walk_cost({**_summary(), "foot_angle_rmse_deg": 22.0}, effort=0.0)
    cost, terms = walk_cost({**_summary(), "foot_angle_rmse_deg": 22.0}, effort=0.0,
                            foot_angle=1.0)
    assert "foot" not in t_plain
    assert terms["foot"] == pytest.approx(22.0 / 10.0 + (22.0 - 8.0) / 2.0)
    assert cost - plain == pytest.approx(terms["foot"])
    _, none = walk_cost({**_summary(), "foot_angle_rmse_deg": None}, effort=0.0,
                        foot_angle=1.0)
    assert none["foot"] == 10.0  # no stride: as bad as a 10-degree-hinge miss
    from stumble.control.reflex.fit_walk import _fit_command

    walk = ((110, 15.0, ()),)
    assert "--foot-angle" not in _fit_command("gh2010", False, walk, None, 1)
    assert "--foot-angle --seed" in _fit_command("gh2010", False, walk, None, 1, foot_angle=1.0)
    _, five = walk_cost({**_summary(), "foot_angle_rmse_deg": 22.0}, effort=0.0,
                        foot_angle=5.0)
    assert five["foot"] == pytest.approx(5.0 * terms["foot"])
    assert "--foot-angle 5 " in _fit_command("gh2010", False, walk, None, 1, foot_angle=5.0)


def test_the_stance_weight_scales_the_stance_term_and_is_recorded_in_the_command():
    from stumble.control.reflex.fit_walk import _fit_command, fit_gh2010

    short = {**_summary(), "stance_fraction": 0.51}
    _, one = walk_cost(short, effort=0.0)
    _, twenty = walk_cost(short, effort=0.0, stance_weight=20.0)
    assert one["stance"] == pytest.approx(((0.57 - 0.51) / 0.05) ** 2)  # 1.44
    assert twenty["stance"] == pytest.approx(20.0 * one["stance"])
    _, inside = walk_cost({**_summary(), "stance_fraction": 0.6}, effort=0.0,
                          stance_weight=20.0)
    assert inside["stance"] == 0.0
    walk = ((110, 15.0, ()),)
    assert "--stance-weight" not in _fit_command("gh2010", False, walk, None, 1)
    assert "--stance-weight 20 " in _fit_command("gh2010", False, walk, None, 1,
                                                  stance_weight=20.0)
    with pytest.raises(ValueError, match="stance_weight"):
        fit_gh2010(stance_weight=-1.0)


def test_the_track_weight_scales_the_tracking_term_and_is_recorded_in_the_command():
    """``--track-weight W``: the tracking term times W (1 in every shipped fit)."""
    from stumble.control.reflex.fit_walk import _fit_command, fit_gh2010

    off = _summary(rmse=(9.0, 18.0, 11.0))
    _, one = walk_cost(off, effort=0.0)
    _, three = walk_cost(off, effort=0.0, track_weight=3.0)
    rms = np.sqrt((81 + 324 + 121) / 3) / 10.0
    assert one["track"] == pytest.approx(rms + (1 + 10 + 3) / 2.0)  # 8 deg hinge
    assert three["track"] == pytest.approx(3.0 * one["track"])
    walk = ((110, 15.0, ()),)
    assert "--track-weight" not in _fit_command("gh2010", False, walk, None, 1)
    assert "--track-weight 3 " in _fit_command("gh2010", False, walk, None, 1,
                                                track_weight=3.0)
    with pytest.raises(ValueError, match="track_weight"):
        fit_gh2010(track_weight=float("nan"))


def test_the_knee_weight_charges_hyperextension_and_is_recorded_in_the_command():
    """``--knee-weight W``: W per degree of the knees' mean extension beyond straight
    (off by default; ``knee-walk`` was fitted with 5); a walk's summary carries the
    measure; the Python API refuses it with ``touch_only`` as the command line does."""
    from stumble.control.reflex.fit_walk import _fit_command, fit_gh2010

    locked = {**_summary(), "knee_hyperextension_deg": 2.5}
    cost0, off = walk_cost(locked, effort=0.0)
    cost2, two = walk_cost(locked, effort=0.0, knee_weight=2.0)
    assert "knee" not in off and two["knee"] == pytest.approx(5.0)
    assert cost2 == pytest.approx(cost0 + 5.0)
    walk = ((110, 15.0, ()),)
    assert "--knee-weight" not in _fit_command("gh2010", False, walk, None, 1)
    assert "--knee-weight 2 " in _fit_command("gh2010", False, walk, None, 1,
                                               knee_weight=2.0)
    with pytest.raises(ValueError, match="knee_weight"):
        fit_gh2010(knee_weight=-1.0)
    with pytest.raises(ValueError, match="knee_weight weighs the walk"):
        fit_gh2010(knee_weight=2.0, trips=True, touch_only=True)


def test_a_walk_measures_its_knees_beyond_straight():
    """The pushed walker stands its stance knees on the +5° stop: a mean of 1-4° beyond
    straight over the walk (people: 0); the default, refitted from it with the knee term
    (``--knee-weight 5``), stays within 0.5° of straight."""
    from stumble.control.reflex.gh2010 import load_params
    from stumble.pipeline import simulate_walk

    s = simulate_walk("gh2010", 3.0, params=load_params("pushed")).summary
    assert 1.0 < s["knee_hyperextension_deg"] < 4.0
    assert simulate_walk("gh2010", 3.0).summary["knee_hyperextension_deg"] < 0.5


def test_the_stride_time_term_charges_strides_outside_the_band():
    from stumble.control.reflex.fit_walk import _fit_command

    def with_strides(period):
        return {**_summary(), "stride_s": period}

    _, inside = walk_cost(with_strides(1.2), effort=0.0, stride_time=True)
    _, long = walk_cost(with_strides(1.56), effort=0.0, stride_time=True)
    _, plain = walk_cost(with_strides(1.56), effort=0.0)
    assert inside["stride"] == 0.0 and "stride" not in plain
    assert long["stride"] == pytest.approx(((1.56 - 1.3) / 0.05) ** 2)
    _, none = walk_cost({**_summary(), "stride_s": None}, effort=0.0, stride_time=True)
    assert none["stride"] == 4.0  # no stride: as a stride 0.1 s outside the band
    walk = ((110, 15.0, ()),)
    assert "--stride-time" in _fit_command("gh2010", False, walk, None, 1, stride_time=True)


def _random_planar_poses(seed: int, n: int = 5):
    """(model, data) of the planar muscle body in ``n`` random poses (joints within
    ±0.4 rad), its kinematics computed: one pose per iteration."""
    import mujoco

    from stumble.body.build import build

    m = build(planar=True, actuation="muscles").model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    for _ in range(n):
        d.qpos[:] = 0.0
        d.qpos[2:] = rng.uniform(-0.4, 0.4, m.nq - 2)
        mujoco.mj_kinematics(m, d)
        yield m, d


def test_foot_angle_is_the_feet_pitch_in_the_world_and_tracked_on_the_walk():
    from stumble.analysis import foot_angles
    from stumble.pipeline import simulate_walk

    for m, d in _random_planar_poses(3):
        got = foot_angles(d.qpos.copy(), m)
        for side in ("r", "l"):
            R = d.xmat[m.body(f"foot_{side}").id].reshape(3, 3)
            assert got[f"foot_angle_{side}"] == pytest.approx(np.arctan2(R[2, 0], R[0, 0]))
    r = simulate_walk("gh2010", 3.0, 1.2)
    assert set(r.reference) >= {"foot_angle_r", "foot_angle_l"}
    assert 2.0 < r.summary["foot_angle_rmse_deg"] < 40.0
    assert 0.9 < r.summary["stride_s"] < 1.6  # the mean right stride


def test_trunk_lean_is_the_torsos_pitch_in_the_world_and_reported_on_the_walk():
    """``analysis.trunk_lean`` is the torso's forward lean from vertical (its long axis,
    the ``torso_z`` sensor, in the sagittal plane) for any pose; a reflex walk reports
    its trunk's RMSE against the recorded stride and its mean lean and range, the
    recorded stride leaning 12-16 degrees on our body."""
    from stumble.analysis import trunk_lean
    from stumble.pipeline import simulate_walk

    for m, d in _random_planar_poses(4):
        z = d.xmat[m.body("torso").id].reshape(3, 3)[:, 2]
        assert trunk_lean(d.qpos.copy(), m)["trunk_lean"] == pytest.approx(
            np.arctan2(z[0], z[2]))
    r = simulate_walk("gh2010", 3.0, 1.2)
    assert 12.0 < np.degrees(r.reference["trunk_lean"]).mean() < 16.0
    s = r.summary
    lo, hi = s["trunk_lean_range_deg"]
    assert lo < s["trunk_lean_deg"] < hi and 0.5 < s["trunk_rmse_deg"] < 20.0


def test_the_trunk_term_counts_only_when_asked_and_like_a_joint():
    """``trunk_weight`` (``--trunk-weight``): the trunk's RMSE costs as the foot's and a
    joint's do (its tenth, and half of each degree beyond 8), times the weight; no term
    without it; no stride: as a 10-degree-hinge miss."""
    summary = {**_summary(), "trunk_rmse_deg": 11.2}
    plain, t_plain = walk_cost(summary, effort=0.0)
    cost, terms = walk_cost(summary, effort=0.0, trunk_weight=3.0)
    assert "trunk" not in t_plain
    assert terms["trunk"] == pytest.approx(3.0 * (1.12 + (11.2 - 8.0) / 2.0))
    assert cost - plain == pytest.approx(terms["trunk"])
    _, none = walk_cost({**_summary(), "trunk_rmse_deg": None}, effort=0.0, trunk_weight=1.0)
    assert none["trunk"] == 10.0


def test_contact_events_need_a_lasting_touch_after_a_flight():
    t = np.arange(0.0, 2.0, 0.005)
    on = np.ones((len(t), 2), bool)
    on[(t > 0.30) & (t < 0.70), 0] = False  # a swing of 0.4 s, then a strike at 0.70
    on[(t > 1.00) & (t < 1.02), 0] = False  # a 20 ms scuff is no swing
    on[(t > 1.10) & (t < 1.60), 0] = False  # a swing ...
    on[(t >= 1.20) & (t < 1.204), 0] = True  # ... with a one-sample brush in it
    ev = contact_events(t, on)
    assert ev["r"]["heel_strike_s"] == pytest.approx([0.70, 1.60], abs=0.006)
    assert ev["r"]["toe_off_s"] == pytest.approx([0.30, 1.10], abs=0.006)
    assert ev["l"] == {"heel_strike_s": [], "toe_off_s": []}


def test_network_subset_starts_at_the_network_itself():
    from stumble.control.reflex.identify import default_network

    net = default_network()
    space = network_space(net)
    same = network_with(net, space.start)
    assert np.array_equal(same.v, net.v) and np.array_equal(same.c, net.c)
    assert np.array_equal(same.w, net.w)
    x = space.start.copy()
    x[space.names.index("gain_SOL")] = 2.0
    x[space.names.index("bias_TA")] = 0.5
    changed = network_with(net, x)
    sol = net.topology.muscles.index("SOL")
    assert changed.c[sol] == pytest.approx(2.0 * net.c[sol])
    assert changed.c[net.topology.muscles.index("TA")] == pytest.approx(
        net.c[net.topology.muscles.index("TA")] + 0.5)


def test_a_fit_is_reproduced_from_its_seed_whatever_the_workers():
    """Two generations of four 1 s walks: the same seed gives the same history, with one
    worker or two."""
    space = gh2010_space()
    runs = []
    for workers in (1, 2, 1):
        res = cma_fit(evaluate_walk, space, seed=5, generations=2, popsize=4, workers=workers,
                      initializer=init_walk_eval, initargs=("gh2010", 1.0, 1.2, {}))
        runs.append(([h["best"] for h in res.history], res.best_theta))
    assert runs[0][0] == runs[1][0] == runs[2][0]
    assert np.array_equal(runs[0][1], runs[1][1])
    other = cma_fit(evaluate_walk, space, seed=6, generations=1, popsize=4,
                    initializer=init_walk_eval, initargs=("gh2010", 1.0, 1.2, {}))
    assert not np.array_equal(other.best_theta, runs[0][1])


def test_the_trip_stage_fits_the_stumbling_reflex_from_the_walking_fit(tmp_path):
    """One generation of four candidates, each a 2 s walk and a trip in its own gait:
    the space adds the stumbling corrective reflex, which starts on, and the result says
    how to reproduce it."""
    import json

    from stumble.control.reflex.fit_walk import (
        CROSS_BOUNDS,
        SCR_BOUNDS,
        SCR_EXTENSION,
        fit_gh2010,
    )
    from stumble.control.reflex.gh2010 import CROSS_GAINS, SCR_GAINS, load_params

    assert not set(SCR_BOUNDS) & set(gh2010_space().names)  # walking fits: not in it
    res = fit_gh2010(seed=2, stages=((1, 2.0, ((0.1, 1.2),)),), popsize=4, trips=True,
                     out=tmp_path)
    # the same response at every phase (the walking fit's ``any``): no extension set
    assert set(SCR_BOUNDS) - set(SCR_EXTENSION) == set(res.space.names) & set(SCR_BOUNDS)
    assert "trip_0.1_1.2" in res.best_terms
    fitted = load_params(tmp_path / "gh2010.json")
    assert all(getattr(fitted, n) > 0.0 for n in SCR_GAINS if n not in SCR_EXTENSION)
    assert all(getattr(fitted, n) == 0.0 for n in SCR_EXTENSION)
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert "--trips" in fit["command"] and "--params" not in fit["command"]
    assert fit["from"] == "the shipped walking fit (gh2010_knee_walk.json)"
    # it starts from the walking fit the default's touch stage started from
    start = dict(zip(res.space.names, res.space.start, strict=True))
    assert all(start[n] == pytest.approx(getattr(load_params("knee-walk"), n))
               for n in ("g_sol", "g_vas", "l_off_ta"))
    # by the foot's phase: the extension set is fitted too, and the command says so
    res = fit_gh2010(seed=2, stages=((1, 2.0, ((0.1, 1.2),)),), popsize=4, trips=True,
                     out=tmp_path, scr_phase="foot")
    assert set(SCR_BOUNDS) <= set(res.space.names)
    fitted = load_params(tmp_path / "gh2010.json")
    assert fitted.scr_phase == "foot" and all(getattr(fitted, n) > 0.0 for n in SCR_GAINS)
    # the best so far, written as the fit runs, is a whole parameter set: phase and all
    assert load_params(tmp_path / "best.json") == fitted
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert "--scr-phase foot" in fit["command"] and fit["scr_phase"] == "foot"
    assert not set(CROSS_BOUNDS) & set(res.space.names)  # no crossing unless asked
    # with the crossing step: its gains join the space, start on, and the command says so
    res = fit_gh2010(seed=2, stages=((1, 2.0, ((0.1, 1.2),)),), popsize=4, trips=True,
                     out=tmp_path, crossing=True)
    assert set(CROSS_BOUNDS) <= set(res.space.names)
    fitted = load_params(tmp_path / "gh2010.json")
    assert fitted.crossing and all(getattr(fitted, n) > 0.0 for n in CROSS_GAINS)
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert "--crossing" in fit["command"] and fit["crossing"] is True
    with pytest.raises(ValueError, match="crossing is for the trip stage"):
        fit_gh2010(crossing=True)
    # the touch's reflexes alone: the walking gains stay the start's, bit for bit
    start = load_params("knee-walk")  # where a trip stage starts by default
    res = fit_gh2010(seed=2, stages=((1, 2.0, ((0.1, 1.2),)),), popsize=4, trips=True,
                     out=tmp_path, crossing=True, touch_only=True)
    assert set(res.space.names) == (set(SCR_BOUNDS) - set(SCR_EXTENSION)) | set(CROSS_BOUNDS)
    fitted = load_params(tmp_path / "gh2010.json")
    walking = [n for n in start.free() if n not in SCR_BOUNDS and n not in CROSS_BOUNDS]
    assert len(walking) > 20
    assert all(getattr(fitted, n) == getattr(start, n) for n in walking)
    assert all(getattr(fitted, n) > 0.0 for n in CROSS_GAINS)
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert "--crossing --touch-only" in fit["command"] and fit["touch_only"] is True
    with pytest.raises(ValueError, match="touch_only is for the trip stage"):
        fit_gh2010(touch_only=True)


def test_the_ta_bound_option_narrows_the_ta_length_reflex_only():
    """``ta_bound="paper"`` holds l_off_ta within 0.6-0.8 l_opt and g_ta within 0.5-1.5
    times the paper's; every other bound, and the default (``wide``, the shipped fits'),
    are as before; the command of such a fit says so."""
    from stumble.control.reflex.fit_walk import _fit_command
    from stumble.control.reflex.gh2010 import GH2010Params

    wide, paper = gh2010_space(), gh2010_space(ta_bound="paper")
    assert wide.names == paper.names and np.array_equal(wide.start, paper.start)
    i, j = wide.names.index("l_off_ta"), wide.names.index("g_ta")
    assert (wide.lo[i], wide.hi[i]) == (0.3, 1.5)
    assert (paper.lo[i], paper.hi[i]) == (0.6, 0.8)
    g = GH2010Params().g_ta
    assert (wide.lo[j], wide.hi[j]) == pytest.approx((0.2 * g, 5.0 * g))
    assert (paper.lo[j], paper.hi[j]) == pytest.approx((0.5 * g, 1.5 * g))
    others = [k for k in range(len(wide.names)) if k not in (i, j)]
    assert np.array_equal(wide.lo[others], paper.lo[others])
    assert np.array_equal(wide.hi[others], paper.hi[others])
    # a start outside the bounds (the shipped trip fit's 0.37 l_opt) is clipped into them
    far = gh2010_space(GH2010Params(l_off_ta=0.37, g_ta=1.9), ta_bound="paper")
    th = far.to_params(np.zeros(len(far.names)))
    assert th[i] == 0.6 and th[j] == pytest.approx(1.5 * g)
    with pytest.raises(ValueError):
        gh2010_space(ta_bound="tight")
    assert "--ta-bound" not in _fit_command("gh2010", False, ((110, 15.0, ()),), None, 1)
    assert "--ta-bound paper" in _fit_command("gh2010", False, ((110, 15.0, ()),), None, 1,
                                              "paper")


def test_the_strategy_cost_charges_a_window_trip_taken_otherwise_than_humans_do():
    """``--strategy-cost W``: a trip in the lowering window taken as elevating costs W
    more than taken as lowering, in the early window the other way round, between the
    windows and by default (0) nothing; a trip whose foot never came down (no strategy)
    is not the human one; the command of such a fit says so."""
    from stumble.control.reflex.fit_walk import (
        HUMAN_WINDOWS,
        W_STRATEGY,
        W_TRIP,
        _fit_command,
        human_strategy,
        trip_terms,
    )
    from stumble.validate import WINDOWS

    assert HUMAN_WINDOWS == tuple(w for w in WINDOWS if w[2] != "either")

    def cost(swing, walked, strategy, w=W_STRATEGY):
        return sum(trip_terms(swing, 1.2, walked, strategy, w).values())

    assert W_STRATEGY == 10.0
    assert cost(0.65, 3.0, "elevating") - cost(0.65, 3.0, "lowering") == 10.0
    assert cost(0.65, 1.5, "lowering") == pytest.approx(0.5 * W_TRIP)
    assert cost(0.65, 1.5, "elevating") == pytest.approx(0.5 * W_TRIP + 10.0)
    assert cost(0.15, 3.0, "lowering") - cost(0.15, 3.0, "elevating") == 10.0
    assert cost(0.75, 3.0, None) == cost(0.05, 0.0, None) - W_TRIP == 10.0
    assert cost(0.4, 3.0, "elevating") == cost(0.4, 3.0, "lowering") == 0.0
    assert cost(0.65, 3.0, "elevating", w=2.5) == 2.5
    # the default adds nothing: the terms are the trip's alone, as before the option
    assert trip_terms(0.65, 1.2, 3.0, "elevating") == {"trip_0.65_1.2": 0.0}
    assert trip_terms(0.65, 1.2, 1.5, None) == {"trip_0.65_1.2": pytest.approx(10.0)}
    assert [human_strategy(s) for s in (0.05, 0.25, 0.3, 0.5, 0.55, 0.75, 0.8)] == [
        "elevating", "elevating", None, None, "lowering", "lowering", None]
    stages = ((9, 10.0, ((0.1, 1.2),)),)
    assert "--strategy-cost" not in _fit_command("gh2010", True, stages, None, 1)
    assert "--strategy-cost 10 " in _fit_command("gh2010", True, stages, None, 1,
                                                 "paper", 10.0)


def test_the_trip_stage_records_its_strategy_cost(tmp_path):
    """One generation of two candidates, each a 1 s walk and a lowering-window trip: the
    strategy term is among the objective's terms and the fit records its weight."""
    import json

    from stumble.control.reflex.fit_walk import fit_gh2010

    with pytest.raises(ValueError):
        fit_gh2010(strategy_cost=-1.0, trips=True)
    with pytest.raises(ValueError):
        fit_gh2010(strategy_cost=5.0)
    res = fit_gh2010(seed=2, stages=((1, 1.0, ((0.65, 1.2),)),), popsize=2, trips=True,
                     out=tmp_path, strategy_cost=7.0)
    if res.best_terms["fall"] == 0.0:  # the trip was run: its strategy term is 0 or 7
        assert res.best_terms["strategy_0.65_1.2"] in (0.0, 7.0)
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert fit["strategy_cost"] == 7.0 and "--strategy-cost 7" in fit["command"]


def test_the_recovery_cost_charges_a_trip_not_walked_on_to_the_end():
    """``--recovery-cost W``: a trip walked on less than the whole 3 s costs W on top of
    its time term (2.9 s walked: nearly a recovery's credit without it); a recovery costs
    nothing; the default adds no term; the fit's command and the CLI say so."""
    from stumble.control.reflex.fit_walk import W_TRIP, WALK_ON_TRIP_S, _fit_command, trip_terms

    def cost(walked, w):
        return sum(trip_terms(0.4, 1.2, walked, "elevating", 0.0, w).values())

    assert cost(WALK_ON_TRIP_S, 20.0) == 0.0
    assert cost(2.9, 0.0) == pytest.approx(W_TRIP / 30.0)  # two thirds of a unit
    assert cost(2.9, 20.0) == pytest.approx(W_TRIP / 30.0 + 20.0)
    assert cost(0.0, 20.0) == pytest.approx(W_TRIP + 20.0)
    assert trip_terms(0.4, 1.2, 1.5, None) == {"trip_0.4_1.2": pytest.approx(10.0)}
    assert "unrecovered_0.4_1.2" in trip_terms(0.4, 1.2, 1.5, None, 0.0, 5.0)
    stages = ((9, 10.0, ((0.1, 1.2),)),)
    assert "--recovery-cost" not in _fit_command("gh2010", True, stages, None, 1)
    assert "--recovery-cost 20 " in _fit_command("gh2010", True, stages, None, 1,
                                                 recovery_cost=20.0)
    with pytest.raises(ValueError, match="recovery_cost must be"):
        fit_walk_gh2010(recovery_cost=-1.0, trips=True)
    with pytest.raises(ValueError, match="for the trip stage"):
        fit_walk_gh2010(recovery_cost=5.0)


def fit_walk_gh2010(**kw):
    from stumble.control.reflex.fit_walk import fit_gh2010

    return fit_gh2010(**kw)


@pytest.mark.parametrize("name", ["gh2010_trip.json", "gh2010_seed003.json",
                                  "gh2010_pushed_walk.json", "gh2010_pushed.json",
                                  "gh2010_knee_walk.json", "gh2010_knee.json",
                                  "gh2010_knee_foot.json", "gh2010_knee_2ms.json",
                                  "gh2010_knee_2ms_dense.json",
                                  "gh2010_knee_2ms_dense_wide.json",
                                  "gh2010_knee_2ms_dense_wide_s3.json",
                                  "gh2010_seed003_touch.json"])
def test_shipped_gh2010_fits_score_today_what_they_scored_in_their_fit(name):
    """Reproducibility guard: a shipped fit's own parameters, evaluated by today's
    objective on its last stage's walk and trips, give the cost its fit recorded (on this
    machine to the last bit; 1e-6 allowed for other CPUs' rounding, where the planar
    solver tolerance's change from 1e-8 to 1e-6 moved a walk's cost by 1e-3). The
    walking fit, ``gh2010_walk.json``, was made at the earlier tolerance and is not held
    to it: docs/gh2010.md "Reproducing the shipped fits"."""
    import json
    from importlib import resources

    from stumble.control.reflex.fit_walk import evaluate_walk, init_walk_eval
    from stumble.control.reflex.gh2010 import GH2010Params

    d = json.loads((resources.files("stumble.control.reflex") / "data" / name).read_text())
    p, fit = GH2010Params.from_json(d["params"]), d["fit"]
    trips = tuple((t["swing_fraction"], t["speed_m_per_s"])
                  for t in fit["stages"][-1]["trips"])
    crossing = fit.get("crossing", False)  # (a fit with the crossing step, the foot and
    # stride-time terms records them; earlier fits had none)
    space = gh2010_space(p, stumble_reflex=bool(trips), crossing=crossing,
                         placement=fit.get("placement", False))
    fixed = {n: v for n, v in p.to_json().items() if n not in space.names}
    init_walk_eval("gh2010", fit["stages"][-1]["walk_s"], fit["start_speed_m_per_s"],
                   fixed if trips else {"wiring": p.wiring}, trips, bool(trips),
                   fit.get("strategy_cost", 0.0), crossing, float(fit.get("foot_angle", 0)),
                   bool(fit.get("stride_time", False)),
                   float(fit.get("stance_weight", 1.0)),
                   recovery_cost=float(fit.get("recovery_cost", 0.0)),
                   placement=fit.get("placement", False), pushes=bool(fit.get("pushes")),
                   track_weight=float(fit.get("track_weight", 1.0)),
                   knee_weight=float(fit.get("knee_weight", 0.0)))
    cost, _terms = evaluate_walk(np.array([getattr(p, n) for n in space.names]))
    assert cost == pytest.approx(fit["cost"], rel=1e-6)


def test_the_dense_trip_set_is_thirty_trips_apart_from_the_maps_45():
    """``--trip-set dense``: swing 0.05-0.75 at 1.1 and 1.3 m/s, so that a stage fitted on
    it is measured on the strategy map's 45 (1.0, 1.2, 1.4 m/s) out of sample, and named
    in the fit's command."""
    from stumble.control.reflex.fit_walk import TRIP_SETS, _fit_command

    dense = TRIP_SETS["dense"]
    assert len(dense) == len(set(dense)) == 30
    assert {v for _s, v in dense} == {1.1, 1.3}
    assert min(s for s, _v in dense) == 0.05 and max(s for s, _v in dense) == 0.75
    assert not {v for _s, v in dense} & {1.0, 1.2, 1.4}
    assert "--trip-set dense " in _fit_command("gh2010", True, ((30, 10.0, dense),), None, 5)


def test_the_pool_is_apart_from_the_maps_45_and_the_held_out_28():
    """``--trip-set pool``: 116 trips at 1.05-1.35 m/s, swing 0.05-0.75 in steps of 0.025,
    none at the speeds of the strategy map (1.0/1.2/1.4) or of the held-out trips
    (1.1/1.3)."""
    from stumble.control.reflex.fit_walk import TRIP_SETS

    pool = TRIP_SETS["pool"]
    assert len(pool) == len(set(pool)) == 116
    assert {v for _s, v in pool} == {1.05, 1.15, 1.25, 1.35}
    assert min(s for s, _v in pool) == 0.05 and max(s for s, _v in pool) == 0.75
    assert sorted({s for s, _v in pool})[:3] == [0.05, 0.075, 0.1]


def _noisy_quadratic(arg):
    """A test objective: (θ − 1)² summed, plus the sample's mean when given one."""
    theta, sample = arg if isinstance(arg, tuple) else (arg, None)
    cost = float(np.sum((np.asarray(theta) - 1.0) ** 2))
    if sample is not None:
        cost += float(np.mean(sample))
    return cost, {"sampled": float(sample is not None)}


def test_candidates_spread_job_by_job_give_the_same_fit():
    """With workers, a fit evaluates each candidate as jobs (``WALK_SPLIT``): its walk,
    then, once it walks, each extra walk and each trip: the same history, best candidate
    and terms as whole candidates in one process (a touch stage: one generation of four,
    a 2 s walk and two trips; a walking fit with the pushes' walk: two generations of
    six, some falling); a candidate's jobs give ``evaluate_walk``'s J and terms, and a
    walker that falls has no jobs after its walk."""
    from stumble.control.reflex.fit_walk import fit_gh2010

    stages = ((1, 2.0, ((0.15, 1.2), (0.6, 1.2))),)
    runs = [fit_gh2010(seed=4, stages=stages, popsize=4, trips=True, touch_only=True,
                       crossing=True, recovery_cost=5.0, workers=w) for w in (1, 2)]
    one, two = runs
    assert [h["generation_median"] for h in one.history] == [
        h["generation_median"] for h in two.history]
    assert one.best_cost == two.best_cost and one.best_terms == two.best_terms
    assert np.array_equal(one.best_theta, two.best_theta)
    assert {"trip_0.15_1.2", "unrecovered_0.6_1.2", "trips_recovered"} <= set(one.best_terms)
    # a walking fit with an extra walk, from the paper's gains (most candidates fall)
    walking = [fit_gh2010(seed=2, stages=((2, 2.0, ()),), popsize=6, pushes=True,
                          workers=w) for w in (1, 2)]
    assert [h["generation_median"] for h in walking[0].history] == [
        h["generation_median"] for h in walking[1].history]
    assert walking[0].best_terms == walking[1].best_terms and "push" in walking[0].best_terms
    assert np.array_equal(walking[0].best_theta, walking[1].best_theta)
    # the jobs of a candidate with extra walks (the pushes, another start) and trips give
    # evaluate_walk's J and terms
    from stumble.control.reflex.fit_walk import (
        WALK_SPLIT,
        evaluate_walk,
        gh2010_space,
        init_walk_eval,
    )
    from stumble.control.reflex.gh2010 import load_params

    p = load_params("knee-walk").to_json()
    init_walk_eval("gh2010", 2.0, 1.2, p, trips=((0.15, 1.2),), pushes=True, starts=(1.0,),
                   placement=True, recovery_cost=5.0)
    space = gh2010_space(load_params("knee-walk"), placement=True)
    first_job, follow_jobs, run_job, combine = WALK_SPLIT
    first = run_job(first_job(space.start))
    assert first[1]["fall"] == 0.0 and first[2] == load_params("knee-walk").timestep_s
    jobs = follow_jobs(space.start, first)
    assert [j[0] for j in jobs] == ["extra", "extra", "trip"]
    split = combine(space.start, first, [run_job(j) for j in jobs])
    assert split == evaluate_walk(space.start)
    assert {"push", "start_1", "trip_0.15_1.2", "unrecovered_0.15_1.2"} <= set(split[1])
    # a walker that falls: nothing after its walk, every extra walk and trip lost
    fallen = space.start * 0.0 + space.lo
    first = run_job(first_job(fallen))
    assert first[1]["fall"] > 0.0 and follow_jobs(fallen, first) == []
    cost, terms = combine(fallen, first, [])
    assert (cost, terms) == evaluate_walk(fallen)
    assert terms["push"] > 0.0 and "trips_recovered" not in terms


def test_a_sampled_fit_judges_each_generation_on_its_sample_and_returns_the_mean():
    """``cma_fit(sample=...)``: every candidate of a generation gets that generation's
    sample; the result is the search's mean, judged without a sample (its whole set),
    the same from the same seed."""
    from stumble.control.reflex.fit_walk import Space, cma_fit

    space = Space(("a", "b"), np.zeros(2), np.ones(2), -5 * np.ones(2), 5 * np.ones(2))
    seen = []

    def sample(gen):
        seen.append(gen)
        return (float(gen),)

    res = cma_fit(_noisy_quadratic, space, seed=3, generations=30, popsize=6, sigma=0.5,
                  sample=sample)
    assert seen == list(range(30))
    assert [h["terms"]["sampled"] for h in res.history] == [1.0] * 30
    assert res.best_terms == {"sampled": 0.0}
    assert res.best_cost == pytest.approx(float(np.sum((res.best_theta - 1.0) ** 2)))
    assert np.allclose(res.best_theta, 1.0, atol=0.2)  # the mean found the minimum
    again = cma_fit(_noisy_quadratic, space, seed=3, generations=30, popsize=6, sigma=0.5,
                    sample=lambda g: (float(g),))
    assert np.array_equal(again.best_theta, res.best_theta)


def test_swing_leg_placement_is_off_by_default_and_fitted_only_when_asked():
    """``--placement``: the swing-leg placement's fields join the space only then, within
    their bounds; off (k_place 0) the controller is the paper's; on, a walk differs."""
    import dataclasses

    from stumble.control.reflex.fit_walk import PLACE_BOUNDS, _fit_command, fit_gh2010
    from stumble.control.reflex.gh2010 import PLACE_FIELDS, GH2010Params, shipped_params
    from stumble.pipeline import simulate_walk

    assert set(PLACE_BOUNDS) == set(PLACE_FIELDS) and GH2010Params().k_place == 0.0
    assert not set(PLACE_FIELDS) & set(gh2010_space().names)
    space = gh2010_space(shipped_params(), placement=True)
    assert set(PLACE_FIELDS) <= set(space.names)
    for n in PLACE_FIELDS:
        i = space.names.index(n)
        assert (space.lo[i], space.hi[i]) == PLACE_BOUNDS[n] and space.scale[i] > 0
    with pytest.raises(ValueError, match="walking law"):
        fit_gh2010(trips=True, touch_only=True, placement=True)
    assert "--placement" in _fit_command("gh2010", False, ((1, 10.0, ()),), None, 0,
                                         placement=True)
    p = shipped_params()
    off = simulate_walk("gh2010", 2.0, 1.2, params=p).summary
    on = simulate_walk("gh2010", 2.0, 1.2, params=dataclasses.replace(p, k_place=0.5)).summary
    assert off["walked_s"] == on["walked_s"] == 2.0
    assert on["distance_m"] != off["distance_m"]


def test_pelvis_pushes_slow_the_walk_and_cost_the_candidates_that_fall_after_them():
    """``--pushes`` (ours): a walk with backward pushes on the pelvis (``PUSHES``: 200 N for
    0.2 s at 3 and 6.5 s) is a second walk of each candidate, its part not walked costing
    as a fall. The earlier trip fit (``--params trip``) walks 10 s unpushed and after two
    100 N pushes, and falls within 3 s of a 300 N one; the push slows its centre of
    mass."""
    from stumble.control.reflex.fit_walk import (
        PUSH_WALK_S,
        PUSHES,
        _fit_command,
        fit_gh2010,
        push_term,
    )
    from stumble.control.reflex.gh2010 import load_params
    from stumble.errors import InputError
    from stumble.pipeline import simulate_walk
    from stumble.trip import PelvisPushes

    f = PelvisPushes(((1.0, 0.2, -100.0), (1.1, 0.5, 30.0)))
    assert f(0.99)[0] == 0.0 and f(1.05)[0] == -100.0 and f(1.15)[0] == -70.0
    assert f(1.5)[0] == 30.0 and f(1.6)[0] == 0.0 and f.t_trip_s == pytest.approx(1.6)
    assert f.active(0.9, 1.0) and f.active(1.55, 1.7) and not f.active(0.5, 0.99)
    assert not f.active(1.6, 2.0)
    with pytest.raises(InputError, match="duration"):
        PelvisPushes(((1.0, 0.0, -100.0),))
    assert all(start + dur < PUSH_WALK_S and force < 0 for start, dur, force in PUSHES)
    p = load_params("trip")
    mild = simulate_walk("gh2010", 10.0, 1.2, params=p,
                         pushes=((3.0, 0.2, -100.0), (6.0, 0.2, -100.0))).summary
    hard = simulate_walk("gh2010", 10.0, 1.2, params=p, pushes=((3.0, 0.2, -300.0),))
    assert mild["walked_s"] == 10.0 and not mild["fell"]
    assert hard.summary["fell"] and 3.0 < hard.summary["walked_s"] < 6.0
    rec = hard.recording
    before = rec.com_vel[(rec.time_s > 2.8) & (rec.time_s < 3.0), 0].mean()
    after = rec.com_vel[(rec.time_s > 3.2) & (rec.time_s < 3.4), 0].mean()
    assert after < before - 0.4  # 60 N·s on 70 kg: -0.86 m/s, less what the feet give back
    assert np.abs(rec.trip_force[rec.time_s < 2.9]).max() == 0.0
    assert push_term(None) == W_FALL and push_term(mild) == 0.0
    assert push_term(hard.summary) == pytest.approx(
        W_FALL * (1.0 - min(hard.summary["walked_s"] / PUSH_WALK_S,
                            hard.summary["distance_m"] / PUSH_WALK_S)))
    with pytest.raises(ValueError, match="touch_only"):
        fit_gh2010(trips=True, touch_only=True, pushes=True)
    assert "--pushes" in _fit_command("gh2010", False, ((1, 10.0, ()),), None, 0, pushes=True)
    init_walk_eval("gh2010", 10.0, 1.2, {"wiring": "gh2010"}, pushes=True)
    space = gh2010_space()
    x = np.array([getattr(p, n) for n in space.names])
    _cost, terms = evaluate_walk(x)
    assert terms["fall"] == 0.0 and terms["push"] >= 0.0


def test_the_pushed_sets_load_by_name_withstand_pushes_and_recover_mid_swing_trips():
    """The shipped pushed walking fit (``--params pushed-walk``: ``reflex fit --placement
    --pushes --seed 5``) walks 10 s through two 200 N pushes on the pelvis, as it was
    fitted to, where the earlier trip fit (``--params trip``) falls; the touch stages on it
    (``--params pushed``, the default for part of 2026-12-04) recover an obstacle trip at
    0.40 of swing (1.2 m/s, its own gait) that the earlier trip fit does not."""
    import json

    from stumble.control.reflex.fit_walk import PUSHES
    from stumble.control.reflex.gh2010 import NAMED, load_params, named_file, shipped_params
    from stumble.pipeline import simulate_trip, simulate_walk
    from stumble.trip import Scenario

    for name in NAMED:
        assert load_params(name) == load_params(str(named_file(name)))
    assert load_params("knee-2ms-dense-wide-s3") == shipped_params()  # the default
    assert load_params("knee") != shipped_params()  # the default until 2026-12-05
    from stumble.trip import DEFAULT_TIMESTEP_S  # a scenario runs it at its step

    assert DEFAULT_TIMESTEP_S["gh2010"] == shipped_params().timestep_s == 0.002
    assert load_params("knee-walk") == shipped_params(walking_only=True)
    assert named_file("nope") is None
    walk, pushed = load_params("pushed-walk"), load_params("pushed")
    fit = json.loads(named_file("pushed").read_text())["fit"]
    assert fit["touch_only"] and fit["from"]["its_fit"]["from"]["its_fit"]["pushes"]
    for n in ("g_sol", "g_vas", "k_place"):  # a touch stage keeps the walk's gains
        assert getattr(pushed, n) == getattr(walk, n)
    assert simulate_walk("gh2010", 10.0, 1.2, params=walk, pushes=PUSHES).summary[
        "walked_s"] == 10.0
    trip = load_params("trip")
    assert simulate_walk("gh2010", 10.0, 1.2, params=trip, pushes=PUSHES).summary["fell"]
    sc = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=0.4,
                  speed_m_per_s=1.2, start="own")
    a = simulate_trip(sc, gh2010=pushed).summary
    b = simulate_trip(sc, gh2010=trip).summary
    assert a["strategy"] == b["strategy"] == "elevating"
    assert a["recovered"] and not b["recovered"]


def test_a_pushed_walk_steps_natively_between_pushes_and_equals_stepping_every_step():
    """Between pushes the physics loop steps a block natively (``PelvisPushes.active``
    off), clearing the pelvis force: the walk is the same, bit for bit, as applying the
    (zero) force at every step, as the loop does for a trip's force."""
    from stumble.control.reflex.fit_walk import PUSHES
    from stumble.control.reflex.gh2010 import load_params
    from stumble.pipeline import simulate_walk
    from stumble.trip import PelvisPushes

    class EveryStep(PelvisPushes):
        active = None  # no window test: the force applied step by step to the last push

    p = load_params("pushed-walk")
    native = simulate_walk("gh2010", 8.0, 1.2, params=p, pushes=PUSHES).recording
    import stumble.pipeline as pipeline

    real = pipeline.PelvisPushes
    try:
        pipeline.PelvisPushes = EveryStep
        stepped = simulate_walk("gh2010", 8.0, 1.2, params=p, pushes=PUSHES).recording
    finally:
        pipeline.PelvisPushes = real
    assert len(native.time_s) == len(stepped.time_s) == 1601
    assert np.array_equal(native.qpos, stepped.qpos)
    assert np.abs(native.trip_force[:, 0]).max() == 200.0


def test_the_networks_expert_fit_starts_from_the_first_walking_fit_whatever_the_default(
        tmp_path):
    """``reflex fit --controller gh2010 --wiring seed003`` starts from the first walking
    fit (``gh2010.SEED003_START``, ``--params walk``), not from the default set, so that
    the shipped expert's fit reproduces after the default changed (2026-12-04)."""
    import json

    from stumble.control.reflex.fit_walk import fit_gh2010
    from stumble.control.reflex.gh2010 import NAMED, SEED003_START, load_params, shipped_params

    assert NAMED["walk"] == SEED003_START
    res = fit_gh2010(wiring="seed003", stages=((1, 0.5, ()),), popsize=2, out=tmp_path)
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert fit["from"] == f"the first walking fit ({SEED003_START})"
    assert fit["sigma0"] == [0.3]  # a walker's start: the smaller steps
    walk, default = load_params("walk"), shipped_params()
    start = dict(zip(res.space.names, res.space.start, strict=True))
    differ = [n for n in start if getattr(walk, n) != getattr(default, n)]
    assert len(differ) > 10
    assert all(start[n] == pytest.approx(getattr(walk, n)) for n in differ)


def test_a_walking_fit_from_a_parameter_set_refits_its_walk_and_keeps_its_touch(tmp_path,
                                                                                capsys):
    """``reflex fit --controller gh2010 --params NAME`` (no ``--trips``): the walk is
    refitted from the set, in steps of ``GH2010_SIGMA_TRIPS``, and the reflexes a touch
    triggers stay as the set has them; the result records where it started."""
    import json

    from stumble.control.reflex.fit_walk import GH2010_SIGMA_TRIPS, fit_gh2010
    from stumble.control.reflex.gh2010 import TOUCH_FIELDS, load_params, named_file

    start = load_params("pushed")
    start_fit = json.loads(named_file("pushed").read_text())["fit"]
    res = fit_gh2010(seed=3, stages=((1, 1.0, ()),), popsize=4, start=start,
                     start_fit=start_fit, placement=True, out=tmp_path)
    assert "k_place" in res.space.names and "g_scr_ta" not in res.space.names
    begin = dict(zip(res.space.names, res.space.start, strict=True))
    assert begin["g_sol"] == pytest.approx(start.g_sol)
    assert begin["k_place"] == pytest.approx(start.k_place)
    fitted = load_params(tmp_path / "gh2010.json")
    assert all(getattr(fitted, n) == getattr(start, n) for n in TOUCH_FIELDS)
    assert fitted.g_scr_ta > 0.0 and fitted.crossing
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert fit["sigma0"] == [GH2010_SIGMA_TRIPS] and fit["from"]["params"] == "--params"
    assert fit["from"]["its_fit"]["touch_only"] and "--trips" not in fit["command"]
    from stumble.cli import main
    from stumble.control.reflex.fit_walk import _fit_command

    # the command names the set (--params aside it would fit from the paper's values)
    assert "--wiring gh2010 --params pushed --placement --pushes" in _fit_command(
        "gh2010", False, ((1, 1.0, ()),), None, 3, placement=True, pushes=True,
        params="pushed")
    bad = {"--trips --params src/stumble/control/reflex/data/gh2010_seed003.json":
               "is wired seed003: the trip stage starts from a gh2010-wired set",
           "--expert walk": "are for --controller network",
           "--closed-loop": "are for --controller network"}
    capsys.readouterr()
    for opts, words in bad.items():
        assert main(["reflex", "fit", "--controller", "gh2010", *opts.split(),
                     "--out", str(tmp_path / "s")]) == 2, opts
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, (opts, err)
    assert not (tmp_path / "s").exists()
    # the network's DAgger expert: for --closed-loop, seed003-wired
    for opts, words in (("--expert walk", "--expert is for --closed-loop"),
                        ("--closed-loop --expert walk", "is wired gh2010"),
                        ("--closed-loop --expert nope.json", "does not exist")):
        assert main(["reflex", "fit", *opts.split(), "--out", str(tmp_path / "n")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, (opts, err)
    assert not (tmp_path / "n").exists()


def test_a_seed003_wired_set_refits_its_walk(tmp_path):
    """``reflex fit --controller gh2010 --wiring seed003 --params FILE`` (a seed003-wired
    file, as the network's expert) refits that walk from it, not from the first walking
    fit, and records where it started."""
    import json

    from stumble.control.reflex.fit_walk import fit_gh2010
    from stumble.control.reflex.gh2010 import SHIPPED, load_params, named_file, shipped_params

    expert = shipped_params("seed003")
    res = fit_gh2010(seed=1, stages=((1, 1.0, ()),), popsize=4, wiring="seed003",
                     start=expert, start_from={"params": "expert.json", "sha256": "x"},
                     out=tmp_path)
    start = np.array(res.space.start)
    assert np.allclose(start, [getattr(expert, n) for n in res.space.names])
    assert not np.allclose(start, [getattr(load_params("walk"), n) for n in res.space.names])
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert fit["from"]["params"] == "expert.json" and fit["wiring"] == "seed003"
    assert load_params(tmp_path / "gh2010.json").wiring == "seed003"
    assert named_file("knee") is not None and SHIPPED["seed003"].endswith("seed003.json")


def test_a_set_of_the_other_wiring_starts_a_walking_fit(tmp_path, capsys):
    """``--wiring seed003 --params knee-walk`` (a gh2010-wired set) starts a seed003-wired
    walking fit from the same gains, says so in one note, and records it: the written
    command rewires it again."""
    import json

    from stumble.cli import main
    from stumble.control.reflex.gh2010 import load_params

    assert main(["reflex", "fit", "--controller", "gh2010", "--wiring", "seed003",
                 "--params", "knee-walk", "--generations", "1", "--workers", "1",
                 "--no-video", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "note: --params knee-walk is wired gh2010: its gains start a seed003-wired" in err
    fit = json.loads((tmp_path / "gh2010.json").read_text())["fit"]
    assert fit["from"]["rewired_from"] == "gh2010" and fit["wiring"] == "seed003"
    assert "--wiring seed003 --params knee-walk" in fit["command"]
    fitted, start = load_params(tmp_path / "gh2010.json"), load_params("knee-walk")
    assert fitted.wiring == "seed003" and start.wiring == "gh2010"
    assert fitted.k_place == start.k_place  # not fitted without --placement


def test_other_starts_cost_what_they_do_not_walk(capsys, tmp_path):
    """``starts``: a candidate also walks 10 s from each other played-back walk, the part
    not walked costing as a fall; knee-walk's gains in the seed003 wiring walk on from
    the 1.0 m/s walk and fall within 1.5 s of taking over from the 1.3 m/s one."""
    from dataclasses import replace

    from stumble.cli import main
    from stumble.control.reflex.fit_walk import (
        W_FALL,
        evaluate_walk,
        gh2010_space,
        init_walk_eval,
    )
    from stumble.control.reflex.gh2010 import load_params

    params = replace(load_params("knee-walk"), wiring="seed003")
    space = gh2010_space(params)
    theta = np.array([getattr(params, n) for n in space.names])
    fixed = {n: v for n, v in params.to_json().items() if n not in space.names}
    init_walk_eval("gh2010", 1.0, 1.2, fixed, starts=(1.0, 1.3))
    cost, terms = evaluate_walk(theta)
    assert terms["fall"] == 0.0 and terms["start_1"] == 0.0
    assert 0.8 * W_FALL < terms["start_1.3"] < W_FALL  # fell within 2 s of the 10
    init_walk_eval("gh2010", 1.0, 1.2, fixed)
    alone, others = evaluate_walk(theta)
    assert "start_1.3" not in others and cost == pytest.approx(alone + terms["start_1.3"])
    for bad in ("2.0", "1.0,x", ""):
        assert main(["reflex", "fit", "--controller", "gh2010", "--starts", bad,
                     "--out", str(tmp_path / "s")]) == 2
        err = capsys.readouterr().err
        assert "--starts takes speeds of 0.7-1.6 m/s" in err and err.count("\n") == 1
    assert main(["reflex", "fit", "--starts", "1.0", "--out", str(tmp_path / "s")]) == 2
    assert "--starts, --timestep and --ta-bound are for --controller gh2010" in \
        capsys.readouterr().err


def test_the_fits_time_step_is_recorded_in_the_command_and_checked(capsys, tmp_path):
    """``--timestep S``: every walk and trip of the fit at S, recorded in the command and
    in the set (``GH2010Params.timestep_s``); out of range, one line and exit 2."""
    from stumble.cli import main
    from stumble.control.reflex.fit_walk import _fit_command

    walk = ((110, 15.0, ()),)
    assert "--timestep" not in _fit_command("gh2010", False, walk, None, 1)
    assert "--timestep 0.002 " in _fit_command("gh2010", False, walk, None, 1,
                                               timestep_s=0.002)
    assert main(["reflex", "fit", "--controller", "gh2010", "--timestep", "0.05",
                 "--out", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err
    assert "--timestep must be 0.0002-0.005 s, got 0.05" in err and err.count("\n") == 1


def test_the_networks_walking_es_from_the_command_line(tmp_path, capsys):
    """``reflex fit --controller network --walk-es NETWORK``: one generation writes a
    network that loads, whose record names its start (with the shipped file's hash) and
    the command that reproduces it; options of other fits are refused in one line."""
    import hashlib
    import json
    from importlib import resources

    from stumble.cli import main
    from stumble.control.reflex.identify import NETWORK_NAMES
    from stumble.control.reflex.network import Network

    out = tmp_path / "es"
    assert main(["reflex", "fit", "--walk-es", "placement", "--generations", "1",
                 "--timestep", "0.002", "--knee-weight", "5", "--trunk-weight", "2",
                 "--workers", "1", "--seed", "3", "--out", str(out)]) == 0
    net = Network.load(out / "network.npz")
    fit = net.info["fit"]
    shipped = (resources.files("stumble.control.reflex") / "data"
               / NETWORK_NAMES["placement"]).read_bytes()
    assert fit["from"] == {"network": "placement",
                           "sha256": hashlib.sha256(shipped).hexdigest()}
    assert fit["command"] == ("stumble reflex fit --controller network --walk-es placement "
                              "--knee-weight 5 --timestep 0.002 --trunk-weight 2 "
                              "--generations 1 --seed 3 --out DIR")
    assert fit["trunk_weight"] == 2.0 and fit["terms"]["trunk"] > 0.0
    assert fit["evaluations"] == 15 and len(fit["theta"]) == len(fit["parameters"]) == 44
    report = json.loads((out / "fit.json").read_text())
    assert report["walk_20s"]["controller"] == "network"
    for name in ("history.jsonl", "best.json", "objective.png"):
        assert (out / name).stat().st_size > 0
    capsys.readouterr()
    for argv, words in ((["--walk-es", "placement", "--trips"], "--trips is not for --walk-es"),
                        (["--walk-es", "no-such.npz"], "no-such.npz"),
                        (["--controller", "gh2010", "--walk-es", "placement"],
                         "--walk-es, --interneuron-biases, --sigma, --touch-afferent, "
                         "--touch-response, --trunk-weight and --track-limit are for "
                         "--controller network"),
                        (["--interneuron-biases"],
                         "--interneuron-biases, --sigma, --touch-afferent, --touch-response, "
                         "--trunk-weight and --track-limit are for --walk-es"),
                        (["--trunk-weight", "1"], "--trunk-weight and --track-limit are for "
                         "--walk-es"),
                        (["--walk-es", "placement", "--trunk-weight", "-1"],
                         "--trunk-weight must be a number in 0-100, got -1.0"),
                        (["--walk-es", "placement", "--touch-only", "--trip-set", "four",
                          "--trunk-weight", "1"],
                         "--trunk-weight weighs the walk: not with --touch-only"),
                        (["--walk-es", "placement", "--sigma", "0"],
                         "--sigma must be a number in (0, 5], got 0.0")):
        assert main(["reflex", "fit", *argv, "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err


def test_the_networks_es_with_trips_costs_each_trip_and_records_them(tmp_path, capsys):
    """``--walk-es ... --trip-set four``: every candidate that walks is tripped four
    times, in its own gait by default (``--trip-start own``), each trip a ``trip_terms``
    term; the record names the trips and the command carries the trip options, the start
    included; trip options without a trip set are refused in one line."""
    from stumble.cli import main
    from stumble.control.reflex.fit_walk import TRIP_SETS, W_TRIP
    from stumble.control.reflex.network import Network

    out = tmp_path / "es"
    assert main(["reflex", "fit", "--walk-es", "placement-es", "--generations", "1",
                 "--timestep", "0.002", "--trip-set", "four",
                 "--recovery-cost", "10", "--workers", "2", "--seed", "3",
                 "--out", str(out)]) == 0
    fit = Network.load(out / "network.npz").info["fit"]
    assert fit["trips"] == [list(t) for t in TRIP_SETS["four"]]
    assert fit["trip_start"] == "own" and fit["recovery_cost"] == 10.0
    assert "--trip-set four --recovery-cost 10 --trip-start own" in fit["command"]
    terms = fit["terms"]
    for swing, speed in TRIP_SETS["four"]:
        t = terms[f"trip_{swing}_{speed}"]
        assert 0.0 <= t <= W_TRIP  # the part of the 3 s not walked on
        assert terms[f"unrecovered_{swing}_{speed}"] == (10.0 if t > 0 else 0.0)
    assert 0 <= terms["trips_recovered"] <= 4
    capsys.readouterr()
    for argv, words in ((["--walk-es", "placement", "--recovery-cost", "5"],
                         "--recovery-cost needs --trip-set"),
                        (["--walk-es", "placement", "--trip-start", "own"],
                         "--trip-start needs --trip-set"),
                        (["--trip-start", "own"],
                         "--trip-start is for --walk-es (with --trip-set)")):
        assert main(["reflex", "fit", *argv, "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err


def test_shipped_fit_records_name_no_machine_paths():
    """The commands and starts recorded in the shipped sets and networks are what a user
    types (shipped names, or a chain's own run directories), never this machine's paths."""
    import json
    import re
    from importlib import resources

    from stumble.control.reflex.network import Network

    data = resources.files("stumble.control.reflex") / "data"
    texts = {p.name: p.read_text() for p in data.iterdir() if p.name.endswith(".json")}
    for p in data.iterdir():
        if p.name.endswith(".npz"):
            with resources.as_file(p) as f:
                texts[p.name] = json.dumps(Network.load(f).info)
    assert len(texts) >= 14
    for name, text in texts.items():
        assert not re.search(r"(^|[\s\"'])/(work|tmp|root|home)/", text), name


def test_the_networks_touch_stage_fits_the_touch_alone_and_keeps_the_walk(tmp_path, capsys):
    """``--walk-es NETWORK --touch-only --touch-response --trip-set four``: the subset is
    the touch response's gains and durations alone (``network_space(touch_only=True)``),
    so the fitted network walks as its start, bit for bit; the record and the command
    name the stage; a touch stage without trips, or with what weighs the walk, is one
    line of error."""
    from stumble.cli import main
    from stumble.control.reflex.identify import default_network
    from stumble.control.reflex.network import Network
    from stumble.pipeline import simulate_walk

    start = default_network("placement-es")
    space = network_space(start.with_touch_response(), touch_only=True, touch_response=True)
    assert len(space.names) == 3 * 8 + 2 and all(n.startswith("resp_") for n in space.names)
    with pytest.raises(ValueError, match="no touch afferent"):
        network_space(start, touch_only=True)
    out = tmp_path / "touch"
    assert main(["reflex", "fit", "--walk-es", "placement-es", "--touch-only",
                 "--touch-response", "--trip-set", "four", "--generations", "1",
                 "--workers", "2", "--seed", "2", "--out", str(out)]) == 0
    net = Network.load(out / "network.npz")
    fit = net.info["fit"]
    assert fit["touch_only"] and fit["touch_response"] and fit["parameters"] == list(space.names)
    assert "--touch-only --touch-response" in fit["command"]
    assert np.array_equal(net.w, start.w) and np.array_equal(net.c, start.c)
    assert net.info["balance"] == start.info["balance"]
    assert any(v for g in ("ipsi", "after", "contra")
               for v in net.info["touch_response"][g].values())
    walk, walk0 = (simulate_walk("network", 2.0, network=n).recording for n in (net, start))
    assert np.array_equal(walk.qpos, walk0.qpos)
    capsys.readouterr()
    for argv, words in ((["--touch-only"], "the touch stage needs --trip-set"),
                        (["--touch-only", "--trip-set", "four", "--starts", "1.0"],
                         "--starts weighs the walk: not with --touch-only"),
                        (["--scr-phase", "foot", "--trip-set", "four"],
                         "--scr-phase (network --walk-es) is for --touch-response")):
        assert main(["reflex", "fit", "--walk-es", "placement-es", *argv,
                     "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err


def _placement_walk_evaluated(**extra) -> tuple[float, dict]:
    """``evaluate_walk`` of ``placement-walk`` as it is (3 s from 1.2 m/s at 2 ms), set
    up with ``init_walk_eval``'s ``extra`` options (the extra walks of a network fit)."""
    import tempfile
    from pathlib import Path

    from stumble.control.reflex.fit_walk import evaluate_walk, init_walk_eval, network_space
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-walk")
    space = network_space(net, interneuron_biases=False)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "n.npz"
        net.save(path)
        init_walk_eval("network", 3.0, 1.2, {"network": str(path)}, timestep_s=0.002,
                       names=space.names, **extra)
        return evaluate_walk(space.start)


def test_delay_walks_cost_what_the_slower_walker_does_not_walk(capsys, tmp_path):
    """``delay_walks``: a candidate also walks 10 s from the same start with its delays
    × K, the part not walked costing as a fall. The network before delay walks (the
    ``placement-walk`` walk) walks 3 s at its own delays and falls within 2.5 s at
    × 1.1; bad scales, or the option given to another fit, are one line and exit 2."""
    from stumble.cli import main
    from stumble.control.reflex.fit_walk import W_FALL

    cost, terms = _placement_walk_evaluated(delay_walks=(1.1,))
    alone, others = _placement_walk_evaluated()
    assert terms["fall"] == 0.0 and terms["walked_s"] == 3.0
    assert 0.75 * W_FALL < terms["delay_1.1"] < W_FALL  # fell within 2.5 s of the 10
    assert "delay_1.1" not in others and cost == pytest.approx(alone + terms["delay_1.1"])
    for argv, words in ((["--walk-es", "placement", "--delay-walks", "4"],
                         "--delay-walks takes delay scales of 0.5-3 separated by commas"),
                        (["--walk-es", "placement", "--delay-walks", "1.5,x"],
                         "--delay-walks takes delay scales of 0.5-3"),
                        (["--controller", "gh2010", "--delay-walks", "1.5"],
                         "--delay-walks is for --controller network --walk-es"),
                        (["--delay-walks", "1.5"],
                         "--delay-walks is for --controller network --walk-es"),
                        (["--walk-es", "placement", "--touch-only", "--trip-set", "four",
                          "--delay-walks", "1.5"],
                         "--delay-walks weighs the walk: not with --touch-only")):
        assert main(["reflex", "fit", *argv, "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err


def test_network_pushes_cost_what_the_pushed_network_does_not_walk(capsys, tmp_path):
    """``reflex fit --controller network --walk-es NET --pushes``: each candidate also
    walks 10 s through the pelvis pushes (``PUSHES``), as Geyer & Herr's fits do, the part
    not walked costing as a fall. ``placement-walk`` walks 3 s unpushed and falls about
    1.9 s after the first push (3 s): half the pushed walk is lost. Refused with
    ``--touch-only`` in one line."""
    from stumble.cli import main
    from stumble.control.reflex.fit_walk import W_FALL

    _cost, terms = _placement_walk_evaluated(pushes=True)
    assert terms["fall"] == 0.0 and terms["walked_s"] == 3.0
    assert 0.4 * W_FALL < terms["push"] < 0.6 * W_FALL
    assert main(["reflex", "fit", "--walk-es", "placement", "--touch-only", "--trip-set",
                 "four", "--pushes", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--pushes weighs the walk: not with --touch-only" in err and err.count("\n") == 1
    # from the command line to the record: the start judged once (--generations 0)
    import json

    assert main(["reflex", "fit", "--walk-es", "placement-walk", "--pushes", "--generations",
                 "0", "--workers", "1", "--out", str(tmp_path / "p")]) == 0
    fit = json.loads((tmp_path / "p" / "fit.json").read_text())
    assert "--pushes" in fit["command"] and fit["pushes"] == [[3.0, 0.2, -200.0],
                                                              [6.5, 0.2, -200.0]]
    assert fit["terms"]["push"] > 0.4 * W_FALL  # the start falls after the first push


def test_a_trip_stage_counts_a_recovery_past_the_box_only_when_asked():
    """``trip_outcome``: the default network's lowering trip at 0.7 of swing (1.2 m/s),
    which at 3 s walks into the box again, counts as walked on 3 s by the rule the shipped
    fits were made under (its touch stages' 2 ms step), and short of it with
    ``past_obstacle`` (``--past-obstacle``,
    written into the fit's command)."""
    from stumble.control.reflex.fit_walk import (
        TRIP_STAGES,
        WALK_ON_TRIP_S,
        _fit_command,
        trip_outcome,
    )
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-both")
    before = trip_outcome("network", 0.7, 1.2, network=net, start="own", timestep_s=0.002)
    now = trip_outcome("network", 0.7, 1.2, network=net, start="own", timestep_s=0.002,
                       past_obstacle=True)
    assert before == (WALK_ON_TRIP_S, "lowering")
    assert now[1] == "lowering" and now[0] < WALK_ON_TRIP_S
    cmd = _fit_command("seed003", True, TRIP_STAGES, None, 0, past_obstacle=True)
    assert "--past-obstacle" in cmd
    assert "--past-obstacle" not in _fit_command("seed003", True, TRIP_STAGES, None, 0)


def test_a_recovery_with_the_trunk_past_the_limit_is_not_one_for_a_tilt_limited_stage():
    """``trip_outcome(max_tilt_deg=...)`` (``reflex fit --max-tilt``): ``past-swing``'s
    lowering trip at 0.70 of swing, 1.2 m/s recovers with the trunk 30.3 deg from vertical
    at recovery-foot contact: a recovery without a limit and within 35 deg, not within
    26 deg (people's, van den Bogert et al. 2002), where it costs as walked on 3 s but
    not recovered."""
    from stumble.control.reflex.fit_walk import WALK_ON_TRIP_S, trip_outcome
    from stumble.control.reflex.identify import default_network

    net = default_network("past-swing")
    kw = {"network": net, "start": "own", "timestep_s": 0.002, "past_obstacle": True}
    assert trip_outcome("network", 0.7, 1.2, **kw) == (WALK_ON_TRIP_S, "lowering")
    assert trip_outcome("network", 0.7, 1.2, max_tilt_deg=35.0, **kw)[0] == WALK_ON_TRIP_S
    walked, strategy = trip_outcome("network", 0.7, 1.2, max_tilt_deg=26.0, **kw)
    assert strategy == "lowering" and WALK_ON_TRIP_S - 0.01 < walked < WALK_ON_TRIP_S
