"""Geyer & Herr 2010's reflexes: the laws against the paper's equations, the delays."""

import mujoco
import numpy as np
import pytest

from stumble.body import build
from stumble.control.reflex.delays import DelayLine
from stumble.control.reflex.gh2010 import GH2010Controller, GH2010Params
from stumble.sim import Context, Sensors


@pytest.fixture(scope="module")
def bound():
    """A GH2010 controller bound to the planar body with the iliopsoas."""
    body = build(planar=True, actuation="muscles", muscle_set="hfl")
    m = body.model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    c = GH2010Controller(GH2010Params())
    c.start(Context(m, d, body, Sensors(), 0.0))
    return c


def _laws(c, F, L, knee, knee_v, load, x, lean, lean_v, touch=(0.0, 0.0)):
    """The excitations (2, nm) of a steady state: every tap reads these channels (F, L
    (2, nm); the rest per leg (2,) or scalars)."""
    c.delay.fill(np.concatenate([np.ravel(F), np.ravel(L), knee, knee_v, load, x, touch,
                                 [lean_v, lean]]))
    return c._excitations(c.delay.read(1)).reshape(2, c.nm)


def test_stance_and_swing_laws_are_the_papers(bound):
    c, p, ix = bound, bound.p, bound.idx
    nm = c.nm
    rng = np.random.default_rng(3)
    F = rng.uniform(0.0, 0.6, (2, nm))
    L = rng.uniform(0.5, 1.2, (2, nm))
    knee = np.array([0.05, 0.9])  # right nearly straight, left flexed (rad)
    knee_v = np.array([-1.0, 2.0])  # right extending
    load = np.array([0.9, 0.0])  # right in stance (body weights), left in swing
    x_feet = np.array([0.1, 0.4])
    lean, lean_v = 0.2, -0.3
    u = _laws(c, F, L, knee, knee_v, load, x_feet, lean, lean_v)
    pos = lambda v: max(v, 0.0)  # noqa: E731
    clip = lambda v: min(max(v, 0.01), 1.0)  # noqa: E731
    r, left = 0, 1
    bal = p.kp_trunk * (lean - p.lean_ref) + p.kd_trunk * lean_v
    share = 1.0  # the right leg carries all the load
    # stance (right leg), Geyer & Herr 2010
    assert u[r, ix["SOL"]] == pytest.approx(clip(p.s0 + p.g_sol * F[r, ix["SOL"]]))
    assert u[r, ix["TA"]] == pytest.approx(clip(
        p.s0 + p.g_ta * pos(L[r, ix["TA"]] - p.l_off_ta) - p.g_sol_ta * F[r, ix["SOL"]]))
    assert u[r, ix["GAS"]] == pytest.approx(clip(p.s0 + p.g_gas * F[r, ix["GAS"]]))
    assert u[r, ix["VAS"]] == pytest.approx(clip(
        p.s0_vas + p.g_vas * F[r, ix["VAS"]] - p.k_phi * pos(p.phi_off - knee[r])))
    assert u[r, ix["GLU"]] == pytest.approx(clip(p.s0_bal + pos(bal) * share))
    assert u[r, ix["HAMS"]] == pytest.approx(clip(p.s0_bal + pos(bal) * share))
    assert u[r, ix["HFL"]] == pytest.approx(clip(p.s0_bal + pos(-bal) * share))
    assert u[r, ix["RF"]] == pytest.approx(p.s0)
    # swing (left leg)
    assert u[left, ix["HFL"]] == pytest.approx(clip(
        p.s0 + p.g_hfl * pos(L[left, ix["HFL"]] - p.l_off_hfl)
        - p.g_ham_hfl * pos(L[left, ix["HAMS"]] - p.l_off_ham) + p.k_lean * (lean - p.lean_ref)))
    assert u[left, ix["GLU"]] == pytest.approx(clip(p.s0 + p.g_glu * F[left, ix["GLU"]]))
    assert u[left, ix["HAMS"]] == pytest.approx(clip(p.s0 + p.g_ham * F[left, ix["HAMS"]]))
    assert u[left, ix["TA"]] == pytest.approx(clip(
        p.s0 + p.g_ta * pos(L[left, ix["TA"]] - p.l_off_ta)))
    for name in ("SOL", "GAS", "VAS", "RF"):
        assert u[left, ix[name]] == pytest.approx(p.s0)


def test_the_trailing_leg_of_double_support_shifts_glu_to_hfl(bound):
    """Double support: the rear leg's GLU loses and its HFL gains k_bw · the front leg's
    load (body weights), Geyer & Herr 2010."""
    c, p, ix = bound, bound.p, bound.idx
    nm = c.nm
    F, L = np.zeros((2, nm)), np.ones((2, nm))
    args = (np.full(2, 0.5), np.zeros(2), np.array([0.5, 0.5]))
    lean = p.lean_ref  # no trunk-lean drive
    both = _laws(c, F, L, *args, np.array([0.0, 0.3]), lean, 0.0)
    assert both[0, ix["GLU"]] == pytest.approx(max(p.s0_bal - p.k_bw * 0.5, 0.01))
    assert both[0, ix["HFL"]] == pytest.approx(p.s0_bal + p.k_bw * 0.5)
    assert both[1, ix["GLU"]] == pytest.approx(p.s0_bal)  # the front leg: no shift


def test_delays_are_five_ten_and_twenty_ms(bound):
    """Hip muscles 5 ms, knee (VAS) 10 ms, ankle 20 ms at the 1 ms step (Geyer & Herr
    2010); the controller plans 5 ms at a time."""
    c, ix = bound, bound.idx
    lags, at = c.delay.lags, c.at
    assert c.period_steps == 5
    for name, lag in (("GLU", 5), ("HAMS", 5), ("HFL", 5), ("VAS", 10), ("SOL", 20),
                      ("GAS", 20), ("TA", 20)):
        for leg in (0, 1):
            assert lags[at[("F", leg, ix[name])]] == lags[at[("L", leg, ix[name])]] == lag
    assert lags[at[("F_sol_ta", 0)]] == 20 and lags[at[("gate", 0, ix["SOL"])]] == 5


def test_seed003_wiring_delays_each_law_by_its_table_one_path():
    """The expert of the network: SOL's own loop through S2 (1.25 m both ways), SOL onto
    TA through S1, the contact afferents (1.32 m to S2) onto SOL and through L4 (1.43 m)
    onto VAS, the knee stop as VAS's own loop; no HAMS-onto-HFL law; HFL ungated."""
    body = build(planar=True, actuation="muscles", muscle_set="hfl")
    m = body.model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    c = GH2010Controller(GH2010Params(wiring="seed003"))
    c.start(Context(m, d, body, Sensors(), 0.0))
    ix, lags, at = c.idx, c.delay.lags, c.at
    ms = lambda length_aff, length_eff: round(1000 * (length_aff / 57.6 + length_eff / 52.4))  # noqa: E731
    assert lags[at[("F", 0, ix["SOL"])]] == ms(1.25, 1.25)
    assert lags[at[("F_sol_ta", 1)]] == ms(1.28, 1.05)
    assert lags[at[("gate", 0, ix["SOL"])]] == ms(1.32, 1.25)
    assert lags[at[("knee", 0)]] == lags[at[("F", 0, ix["VAS"])]] == ms(0.64, 0.64)
    assert ("L_ham_flex", 0) not in at and ("ds_load", 0) not in at
    assert lags[at[("gate", 1, ix["VAS"])]] == ms(1.43, 0.64)
    assert c.gated[ix["VAS"]] and not c.gated[ix["HFL"]] and c.gated[ix["GLU"]]
    assert c.period_steps == ms(0.22, 0.22)  # HFL's own loop through L3 is the shortest


def test_delay_line_reads_each_channel_at_its_lag():
    line = DelayLine(np.array([3, 5]), block=3)
    line.push(np.column_stack([np.arange(10.0), 100 + np.arange(10.0)]))
    out = line.read(3)  # ticks 10, 11, 12
    assert out[:, 0].tolist() == [7.0, 8.0, 9.0]
    assert out[:, 1].tolist() == [105.0, 106.0, 107.0]
    with pytest.raises(ValueError, match="longer than the shortest lag"):
        DelayLine(np.array([3, 5]), block=4)


def test_params_round_trip_and_refuse_bad_values():
    from stumble.errors import InputError

    p = GH2010Params(g_sol=0.8)
    assert GH2010Params.from_json(p.to_json()) == p
    assert p.with_vector(p.vector()) == p
    with pytest.raises(InputError, match="unknown GH2010 parameter"):
        GH2010Params.from_json({"g_nothing": 1.0})
    with pytest.raises(InputError, match="g_sol must be a finite number"):
        GH2010Params.from_json({"g_sol": float("nan")})


def _obstacle_body():
    """The planar body with the iliopsoas and an obstacle (so the reflex can be touched)."""
    body = build(planar=True, actuation="muscles", muscle_set="hfl", obstacle=(
        1.0, 0.1, 0.1, 0.14, 0.0))
    d = mujoco.MjData(body.model)
    mujoco.mj_forward(body.model, d)
    return body, body.model, d


def test_stumble_reflex_excites_the_tripped_legs_flexors_and_the_support_legs_push():
    """A touch on the left foot's front: after scr_latency_s (65 ms, Eng et al. 1994),
    left HAMS, TA and HFL and right SOL, GAS and GLU each gain their g_scr, for
    scr_hold_s after the last sensed touch, and left VAS from scr_vas_after_s after that
    for as long; with the paper's gains (zero) nothing."""
    body, m, d = _obstacle_body()
    gains = dict(g_scr_ham=0.11, g_scr_ta=0.12, g_scr_flex=0.13, g_scr_sol=0.14,
                 g_scr_gas=0.15, g_scr_glu=0.16, g_scr_vas=0.17)
    c = GH2010Controller(GH2010Params(**gains, scr_hold_s=0.1, scr_vas_after_s=0.05))
    c.start(Context(m, d, body, Sensors(), 0.0))
    ix, nm = c.idx, c.nm
    F = np.full((2, nm), 0.2)
    L = np.full((2, nm), 0.8)
    args = (F, L, np.array([0.3, 0.3]), np.zeros(2), np.array([0.0, 0.0]),
            np.array([0.0, 0.3]), 0.1, 0.0)  # both legs in swing: no stance laws
    quiet = _laws(c, *args)
    touched = _laws(c, *args, touch=(0.0, 1.0))  # the left foot (index 1) touched
    du = touched - quiet
    expect = np.zeros((2, nm))
    expect[1, [ix["HAMS"], ix["TA"], ix["HFL"]]] = [0.11, 0.12, 0.13]
    expect[0, [ix["SOL"], ix["GAS"], ix["GLU"]]] = [0.14, 0.15, 0.16]
    np.testing.assert_allclose(du, expect, atol=1e-12)
    lag = c.delay.lags[c.at[("touch", 1)]]
    assert lag == 65  # ticks of 1 ms
    # the touch ends now: sensed 65 ticks later, the response lasts 100 ticks after that
    row = np.concatenate([np.ravel(F), np.ravel(L), [0.3, 0.3], [0.0, 0.0], [0.0, 0.0],
                          [0.0, 0.3], [0.0, 0.0], [0.0, 0.1]])
    on, vas = [], []
    for _ in range(260):
        c.delay.push(row[None])
        u = c._excitations(c.delay.read(1)).reshape(2, nm)
        on.append(u[1, ix["HAMS"]] - quiet[1, ix["HAMS"]] > 0.05)
        vas.append(u[1, ix["VAS"]] - quiet[1, ix["VAS"]] > 0.05)
    on, vas = np.array(on), np.array(vas)
    assert on[:160].all() and not on[170:].any()
    assert not vas[:60].any() and vas[120:210].all() and not vas[220:].any()
    paper = GH2010Controller(GH2010Params())
    paper.start(Context(m, d, body, Sensors(), 0.0))
    np.testing.assert_allclose(_laws(paper, *args, touch=(0.0, 1.0)), _laws(paper, *args))


def test_load_from_any_counts_a_foot_at_rest_on_the_obstacle_as_loaded():
    """``load_from`` any: the obstacle's vertical force on a foot joins the floor's in
    that leg's load (body weights), so that a foot on the box is in stance; ``floor``
    (the default, the shipped fits') reads the floor alone; a bad value is refused."""
    from stumble.body.sensors import layout
    from stumble.errors import InputError

    body, m, d = _obstacle_body()
    lay = layout(m, [])
    loads = {}
    for src in ("floor", "any"):
        c = GH2010Controller(GH2010Params(load_from=src))
        c.start(Context(m, d, body, Sensors(), 0.0))
        row = np.zeros((1, m.nsensordata))
        row[0, lay.foot_force[0, 2]] = -0.3 * c.weight_n  # right foot: 0.3 on the floor
        row[0, lay.obstacle_force[1, 2]] = -0.7 * c.weight_n  # left foot: 0.7 on the box
        ch = c._channels(row)[0]
        loads[src] = ch[c._c_load:c._c_load + 2]
    np.testing.assert_allclose(loads["floor"], [0.3, 0.0], atol=1e-12)
    np.testing.assert_allclose(loads["any"], [0.3, 0.7], atol=1e-12)
    with pytest.raises(InputError, match="load_from 'box' is not one of floor, any"):
        GH2010Params.from_json({"load_from": "box"})


def test_stumble_reflex_by_foot_phase_reverses_with_where_the_foot_was():
    """``scr_phase`` foot: a touch with the tripped foot behind the other gives the
    flexion set (HAMS, TA, HFL); ahead of it, the extension set (RF, SOL: Eng et al.
    1994's lowering muscles; GLU, HAMS); the support leg's push in both; the phase held
    from the touch's onset however the feet move after it; ``any``: both sets at every
    phase."""
    body, m, d = _obstacle_body()
    gains = dict(g_scr_ham=0.11, g_scr_ta=0.12, g_scr_flex=0.13, g_scr_sol=0.14,
                 g_scr_gas=0.15, g_scr_glu=0.16, g_scr_ext_rf=0.21, g_scr_ext_sol=0.22,
                 g_scr_ext_glu=0.23, g_scr_ext_ham=0.24)

    def response(phase, x_left, then=None, ahead=0.0):
        c = GH2010Controller(GH2010Params(**gains, scr_phase=phase, scr_hold_s=0.3,
                                          scr_ahead_m=ahead))
        c.start(Context(m, d, body, Sensors(), 0.0))
        nm = c.nm
        F, L = np.full((2, nm), 0.2), np.full((2, nm), 0.8)
        args = (F, L, np.array([0.3, 0.3]), np.zeros(2), np.zeros(2),
                np.array([0.0, x_left]), 0.1, 0.0)
        quiet = _laws(c, *args)
        c._touched[:] = False  # (``_laws`` fills the delays: the touch starts now)
        c._scr_since[:] = np.inf
        du = _laws(c, *args, touch=(0.0, 1.0)) - quiet
        if then is not None:  # the foot passes the other, the touch goes on: held
            row = np.concatenate([np.ravel(F), np.ravel(L), [0.3, 0.3], np.zeros(2),
                                  np.zeros(2), [0.0, then], [0.0, 1.0], [0.0, 0.1]])
            for _ in range(80):
                c.delay.push(row[None])
                u = c._excitations(c.delay.read(1)).reshape(2, nm)
            du = u - quiet
        return c.idx, du

    ix, du = response("foot", -0.2)  # the left foot 0.2 m behind the right
    expect = np.zeros_like(du)
    expect[1, [ix["HAMS"], ix["TA"], ix["HFL"]]] = [0.11, 0.12, 0.13]
    expect[0, [ix["SOL"], ix["GAS"], ix["GLU"]]] = [0.14, 0.15, 0.16]
    np.testing.assert_allclose(du, expect, atol=1e-12)
    _, held = response("foot", -0.2, then=0.3)
    np.testing.assert_allclose(held, expect, atol=1e-12)
    _, du = response("foot", 0.3)  # ahead
    expect[1] = 0.0
    expect[1, [ix["RF"], ix["SOL"], ix["GLU"], ix["HAMS"]]] = [0.21, 0.22, 0.23, 0.24]
    np.testing.assert_allclose(du, expect, atol=1e-12)
    _, du = response("any", 0.3)
    expect[1, [ix["HAMS"], ix["TA"], ix["HFL"]]] = [0.11 + 0.24, 0.12, 0.13]
    np.testing.assert_allclose(du, expect, atol=1e-12)
    # ``scr_ahead_m``: "ahead" past a threshold: at -0.3 m a foot 0.2 m behind is ahead
    ext = expect.copy()
    ext[1] = 0.0
    ext[1, [ix["RF"], ix["SOL"], ix["GLU"], ix["HAMS"]]] = [0.21, 0.22, 0.23, 0.24]
    _, du = response("foot", -0.2, ahead=-0.3)
    np.testing.assert_allclose(du, ext, atol=1e-12)
    _, du = response("foot", -0.4, ahead=-0.3)  # 0.4 m behind: the flexion set
    flex = ext.copy()
    flex[1] = 0.0
    flex[1, [ix["HAMS"], ix["TA"], ix["HFL"]]] = [0.11, 0.12, 0.13]
    np.testing.assert_allclose(du, flex, atol=1e-12)
    from stumble.errors import InputError

    with pytest.raises(InputError, match="scr_phase 'late' is not one of any, foot"):
        GH2010Params.from_json({"scr_phase": "late"})


def test_crossing_step_after_a_touch_launches_the_other_legs_step_when_a_foot_lands():
    """The crossing step: nothing before a touch; a sensed touch arms both legs and marks
    the obstacle cross_ahead_m ahead of the touched ankle; when the touched (left) foot
    lands short of the mark (a lowering), the right leg, behind it, gets g_cross_* on HFL,
    HAMS, TA and GAS for cross_hold_s; when the right lands after that, the left, still
    behind the mark, gets them; once each. A left foot landing beyond the mark (elevating)
    launches the right's step, and the right's landing then launches nothing."""
    body, m, d = _obstacle_body()
    gains = dict(g_cross_flex=0.11, g_cross_ham=0.12, g_cross_ta=0.13, g_cross_gas=0.14,
                 cross_hold_s=0.05, cross_ahead_m=0.25)
    c = GH2010Controller(GH2010Params(**gains))
    c.start(Context(m, d, body, Sensors(), 0.0))
    ix, nm = c.idx, c.nm
    F, L = np.full((2, nm), 0.2), np.full((2, nm), 0.8)

    def row(load, touch=(0.0, 0.0), x_left=0.3):
        return np.concatenate([np.ravel(F), np.ravel(L), [0.3, 0.3], [0.0, 0.0], load,
                               [0.0, x_left], touch, [0.0, 0.1]])

    def drive(rows):
        """The crossing part of each tick's excitations (ticks, 2, nm)."""
        out = []
        for r in rows:
            c.delay.push(r[None])
            out.append(c._stumble(c.delay.read(1))[0])
        return np.array(out)

    expect = np.zeros(nm)
    expect[[ix["HFL"], ix["HAMS"], ix["TA"], ix["GAS"]]] = [0.11, 0.12, 0.13, 0.14]
    left_off, both_on = [0.9, 0.0], [0.9, 0.9]  # loads (body weights): right, left
    # walking, no touch: the left foot lands, nothing happens
    quiet = drive([row(left_off)] * 10 + [row(both_on)] * 80)
    assert not quiet.any()
    # the left foot touches the box in swing (sensed 65 ms later), then lands 100 ms on
    lag = c.delay.lags[c.at[("touch", 1)]]
    rows = ([row(left_off, (0.0, 1.0))] * 20 + [row(left_off)] * 100 + [row(both_on)] * 30
            + [row([0.0, 0.9])] * 100 + [row(both_on)] * 100)
    u = drive(rows)
    on_r, on_l = u[:, 0].any(axis=1), u[:, 1].any(axis=1)
    land_l = int(np.argmax(on_r))  # the right's drive starts with the left's landing,
    lag_load = c.delay.lags[c.at[("vest_load", 1)]]  # as sensed through the hip delay
    assert lag < 120 <= land_l <= 120 + lag_load
    np.testing.assert_allclose(u[land_l:land_l + 50, 0], np.tile(expect, (50, 1)))
    assert on_r.sum() == 50 and not on_l[:land_l + 50].any()
    land_r = int(np.argmax(on_l))  # the left's, with the right's landing after it
    assert 250 <= land_r <= 250 + lag_load
    np.testing.assert_allclose(u[land_r:land_r + 50, 1], np.tile(expect, (50, 1)))
    assert on_l.sum() == 50  # once each per touch
    # elevating: the left foot lands 0.4 m on, beyond the mark: the right crosses, and
    # its landing launches nothing for the left
    rows = ([row(left_off, (0.0, 1.0))] * 20 + [row(left_off)] * 100
            + [row(both_on, x_left=0.7)] * 30 + [row([0.0, 0.9], x_left=0.7)] * 100
            + [row(both_on, x_left=0.7)] * 100)
    u = drive(rows)
    on_r, on_l = u[:, 0].any(axis=1), u[:, 1].any(axis=1)
    assert on_r.sum() == 50 and 120 <= int(np.argmax(on_r)) <= 120 + lag_load
    assert not on_l.any()
    assert GH2010Params(**gains).crossing and not GH2010Params().crossing
    from stumble.errors import InputError

    with pytest.raises(InputError, match="cross_hold_s is a time and must be >= 0"):
        GH2010Params.from_json({"cross_hold_s": -0.1})


def test_a_cached_walk_in_gives_the_same_trip_as_walking_it_again():
    """``pipeline.WalkInCache``: trips whose parameters differ only in the reflexes a
    touch triggers share the walk to the trip; going on from the cached walk with the
    other reflexes gives the same numbers, bit for bit, as walking it again (here a
    late-swing trip, where the reflexes act); other walking gains are not served from it,
    and ``retouch`` refuses them."""
    from dataclasses import replace

    from stumble.control.reflex.gh2010 import load_params
    from stumble.pipeline import WalkInCache, simulate_trip
    from stumble.trip import Scenario

    a = load_params("walk")
    a = replace(a, scr_phase="foot", load_from="any", g_scr_ham=0.2, g_scr_ta=0.2,
                g_scr_flex=0.2, g_scr_ext_rf=0.2, g_cross_flex=0.2)
    b = replace(a, g_scr_ham=0.7, g_scr_ext_rf=0.0, g_scr_ext_glu=0.5, scr_hold_s=0.3,
                g_cross_flex=0.6, cross_hold_s=0.3)
    sc = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=0.65,
                  speed_m_per_s=1.2, duration_after_trip_s=1.5)
    fresh = simulate_trip(sc, gh2010=b)
    cache = WalkInCache()
    first = simulate_trip(sc, gh2010=a, walk_in_cache=cache)
    again = simulate_trip(sc, gh2010=b, walk_in_cache=cache)
    assert len(cache) == 1
    for k in ("qpos", "qvel", "activation", "foot_force", "sensordata"):
        assert np.array_equal(getattr(fresh.recording, k), getattr(again.recording, k)), k
    assert not np.array_equal(first.recording.qpos, again.recording.qpos)  # they acted
    assert fresh.summary["walk_in"] == again.summary["walk_in"]
    for k in ("recovered", "strategy", "sim_time_s", "trunk_tilt_at_recovery_contact_deg"):
        assert fresh.summary[k] == again.summary[k], k
    # another walking gain: another walk, not the cached one
    c = replace(b, g_sol=b.g_sol * 1.01)
    simulate_trip(sc, gh2010=c, walk_in_cache=cache)
    assert len(cache) == 2
    ctl = GH2010Controller(b)
    with pytest.raises(ValueError, match="more than the touch"):
        ctl.p = b
        ctl.retouch(c)


def test_a_set_runs_at_the_step_it_was_fitted_at():
    """A set fitted at 2 ms (``reflex fit --timestep 0.002``; the default set since
    2026-12-05) walks and trips at 2 ms by default and at 1 ms when asked (a step that
    divides its own); a 1 ms set refuses 2 ms, naming the step."""
    from dataclasses import replace

    from stumble.control.reflex.gh2010 import load_params
    from stumble.errors import InputError
    from stumble.pipeline import simulate_trip, simulate_walk
    from stumble.trip import Scenario

    p1 = load_params("knee")  # fitted at 1 ms
    p2 = replace(p1, timestep_s=0.002)
    assert "timestep_s" not in p1.to_json()  # the files before the step option
    assert GH2010Params.from_json(p2.to_json()).timestep_s == 0.002
    with pytest.raises(InputError, match="timestep_s"):
        GH2010Params.from_json({**p2.to_json(), "timestep_s": 0.05})
    walk = simulate_walk("gh2010", 1.0, params=p2)
    assert walk.recording.steps == 500 and not walk.summary["fell"]
    assert simulate_walk("gh2010", 0.5, params=p2, timestep_s=0.001).recording.steps == 500
    with pytest.raises(InputError, match=r"divides 1 ms.*got 2 ms"):
        simulate_walk("gh2010", 1.0, params=p1, timestep_s=0.002)
    trip = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=0.3)
    with pytest.raises(InputError, match="got 2 ms"):
        simulate_trip(replace(trip, timestep_s=0.002), gh2010=p1)
    r = simulate_trip(trip)  # the default set, at its 2 ms
    assert r.summary["steps"] == 1500  # 3 s after the trip at 2 ms
    # a verdict at the end of the 3 s (the steps' summed time falls short of 3.0 s by
    # rounding: no verdict was reached until 2026-12-04)
    assert r.summary["stop_reason"] in ("recovered", "stopped walking")


@pytest.mark.parametrize("field, value, says", [
    ("scr_latency_s", 1e9, "scr_latency_s = 1000000000.0 is outside 0-2"),
    ("g_sol", 1e300, "g_sol = 1e+300 is outside 0-100"),
    ("g_vas", -1.0, "g_vas = -1.0 is outside 0-100"),
    ("s0", -5, "s0 = -5 is outside 0-1"),
    ("scr_hold_s", 1e12, "scr_hold_s = 1000000000000.0 is outside 0-2"),
    ("delay_scale", 0, "delay_scale = 0 is outside 0.001-10"),
    ("lean_ref", 40.0, "lean_ref = 40.0 is outside -10-10"),
])
def test_a_parameter_file_with_a_nonsense_value_gets_one_line(tmp_path, field, value, says):
    """A GH2010 parameter file's values outside their sanity ranges (``FILE_RANGES``) are
    refused in one line naming the field (a latency of 1e9 s once asked for a 178 TiB
    delay line); every shipped set lies within them."""
    import json

    from stumble.control.reflex.gh2010 import NAMED, load_params, named_file
    from stumble.errors import InputError

    for name in NAMED:
        load_params(name)
    doc = json.loads(named_file("knee-2ms-dense-wide-s3").read_text())
    doc["params"][field] = value
    f = tmp_path / "gh.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(InputError) as e:
        load_params(f)
    assert says in str(e.value) and "\n" not in str(e.value)
