"""DAgger's building blocks (stumble.control.reflex.dagger): the mixed controller's
episodes, labelled by the expert whoever drives, and training on them."""

from dataclasses import replace

import numpy as np
import pytest

from stumble.control.reflex.dagger import collect, train_on
from stumble.control.reflex.gh2010 import shipped_params
from stumble.control.reflex.identify import default_network


@pytest.fixture(scope="module")
def episodes():
    net, expert = default_network("closed-loop"), shipped_params("seed003")
    return net, {beta: collect(net, expert, beta, seed=3, speed_m_per_s=1.2,
                               duration_s=0.6) for beta in (1.0, 0.0)}


def test_an_episode_is_labelled_by_the_expert_whoever_drives(episodes):
    """0.6 s from the 1.2 m/s walk: one row of inputs per tick, the expert's excitation as
    the label of every tick after the walk's history, within (0.01, 0.99)."""
    net, eps = episodes
    for beta, ep in eps.items():
        T = len(ep.inputs)
        assert ep.walked_s == pytest.approx(0.6, abs=0.002), beta
        assert ep.inputs.shape[1] == 2 and ep.targets.shape == (T, 2, len(net.topology.muscles))
        assert 0.5 * T < ep.mask.sum() < T  # the history's ticks carry no label
        assert not ep.mask[: int(net.topology.max_lag)].any()
        assert ep.targets.min() >= 0.01 and ep.targets.max() <= 0.99
        assert np.isfinite(ep.inputs).all()
    # the expert drives (β = 1) or the network does (β = 0): the same start, other bodies
    a, b = eps[1.0], eps[0.0]
    assert not np.allclose(a.inputs[a.mask][-50:], b.inputs[b.mask][-50:])


def test_training_on_the_labels_lowers_the_loss(episodes):
    """A few L-BFGS iterations on one episode bring the network closer to its labels."""
    from stumble.control.reflex.dagger import _loss_grad

    net, eps = episodes
    ep = eps[0.0]
    data = [(ep.inputs[:, side], ep.targets[:, side], ep.mask.astype(float))
            for side in range(2)]
    before, _g = _loss_grad(net, data)
    trained, after = train_on(net, data, iterations=15)
    assert after < before and _loss_grad(trained, data)[0] == pytest.approx(after)
    assert trained is not net and net.pack().tolist() != trained.pack().tolist()


def test_training_on_two_processes_gives_the_same_numbers(episodes):
    """``SetPool``: the sets split over this process and a worker, each loss and gradient
    summed in the sets' order: the one-process loss, gradient and trained weights, bit
    for bit (the shipped closed-loop networks re-run on any number of workers)."""
    from stumble.control.reflex.dagger import SetPool, _loss_grad

    net, eps = episodes
    data = [(ep.inputs[:, side], ep.targets[:, side], ep.mask.astype(float))
            for ep in eps.values() for side in range(2)]
    pool = SetPool(2)
    try:
        pool.hold(data[:3])
        pool.hold(data)  # the sets come as DAgger's passes add them
        pool.start(net)
        loss, grad = pool.loss_grad(net, net.pack())
        ref_loss, ref_grad = _loss_grad(net, data)
        assert loss == ref_loss and np.array_equal(grad, ref_grad)
        a, la = train_on(net, data, iterations=5)
        b, lb = train_on(net, data, iterations=5, pool=pool)
        assert la == lb and np.array_equal(a.pack(), b.pack())
        with pytest.raises(ValueError, match="the sets it holds"):
            pool.hold(data[1:])  # not the data it holds
        workers = list(pool._procs)
        assert len(workers) == 1 and workers[0].is_alive()
    finally:
        pool.close()
    assert not workers[0].is_alive()


def test_judging_on_workers_gives_the_same_figures():
    """``judge(pool=...)``: the walks from each start run on worker processes, the
    figures those of one process (2 s walks here)."""
    from concurrent.futures import ProcessPoolExecutor

    from stumble.control.reflex import dagger as D

    net = default_network("placement")
    alone = D.judge(net, (1.1, 1.3), duration_s=2.0)
    with ProcessPoolExecutor(2) as pool:
        shared = D.judge(net, (1.1, 1.3), pool=pool, duration_s=2.0)
    assert shared == alone and alone["walked_s_by_start"] == {"1.1": 2.0, "1.3": 2.0}


def test_a_pushed_episode_is_the_same_walk_until_the_push(episodes):
    """``collect(pushes=...)``: the expert's episode (β = 1) with a backward push on the
    pelvis at 0.3 s senses what the unpushed one sensed until the push, then other
    states, still labelled (DAgger's ``--pushes`` episodes)."""
    net, eps = episodes
    pushed = collect(net, shipped_params("seed003"), 1.0, seed=3, speed_m_per_s=1.2,
                     duration_s=0.6, pushes=((0.3, 0.2, -200.0),))
    plain = eps[1.0]
    assert pushed.inputs.shape == plain.inputs.shape
    assert np.array_equal(pushed.inputs[:290], plain.inputs[:290])
    assert not np.allclose(pushed.inputs[-50:], plain.inputs[-50:])
    assert np.array_equal(pushed.mask, plain.mask)


def test_judging_through_pushes_adds_the_part_not_walked():
    """``judge(pushes=...)``: one more walk, from the first start through the pushes;
    the part of it not walked adds ``push_term`` to the cost. The DAgger network
    ``placement`` falls after the first of ``PUSHES`` (3 s)."""
    from stumble.control.reflex import dagger as D
    from stumble.control.reflex.fit_walk import PUSHES, W_FALL, push_term

    net = default_network("placement")
    plain = D.judge(net, (1.2,), duration_s=2.0)
    pushed = D.judge(net, (1.2,), duration_s=2.0, pushes=PUSHES)
    assert "push_term" not in plain
    assert 3.0 < pushed["pushed_walked_s"] < 6.0
    # by time or by way, the smaller share walked (here the way)
    by_time = push_term({"walked_s": pushed["pushed_walked_s"], "distance_m": 1e9})
    assert 0.0 < by_time <= pushed["push_term"] < W_FALL
    assert pushed["cost"] == pytest.approx(plain["cost"] + pushed["push_term"])


def test_each_pass_is_written_as_it_ends(tmp_path, monkeypatch):
    """``dagger(out_dir=...)``: every pass's row is appended to ``passes.jsonl`` when it
    ends and the best network so far saved whole (``best_network.npz``), so that a
    stopped closed-loop fit loses nothing (episodes, training and judging shortened)."""
    import json

    from stumble.control.reflex import dagger as D
    from stumble.control.reflex.network import Network

    net, expert = default_network("closed-loop"), shipped_params("seed003")
    costs = iter([50.0, 40.0, 45.0])  # the start, pass 0 (better), pass 1 (worse)
    monkeypatch.setattr(D, "judge",
                        lambda n, speeds, pool=None, pushes=(): {"cost": next(costs)})
    monkeypatch.setattr(D, "_collect_job",
                        lambda a: collect(*a[:5], duration_s=0.3, pushes=a[5]))
    monkeypatch.setattr(D, "train_on",
                        lambda n, data, pool=None, loss="squared":
                        (train_on(n, data, 2, loss=loss)[0], 0.5))
    monkeypatch.setattr(D, "ident_data", lambda n, ident: [])
    res = D.dagger(net, None, expert, passes=2, episode_speeds=(1.2,), judge_speeds=(1.2,),
                   out_dir=tmp_path)
    rows = [json.loads(x) for x in (tmp_path / "passes.jsonl").read_text().splitlines()]
    assert [r["pass"] for r in rows] == [0, 1] and [r["cost"] for r in rows] == [40.0, 45.0]
    best = Network.load(tmp_path / "best_network.npz")
    assert np.array_equal(best.pack(), res.network.pack())  # pass 0's, the best
    assert not list(tmp_path.glob(".*tmp*"))


def test_the_balance_carries_the_experts_placement():
    """An expert with swing-leg placement hands it to the network's addition
    (``balance_of``): the addition senses what the expert's placement law senses, from
    the same sensor rows, and drives the flexor and GLU by the same law."""
    import mujoco

    from stumble.body.build import build
    from stumble.control.reflex.controller import TrunkBalance
    from stumble.control.reflex.dagger import balance_of
    from stumble.control.reflex.gh2010 import GH2010Controller, load_params
    from stumble.sim import Context, Sensors

    params = replace(load_params("knee-walk"), wiring="seed003")
    assert params.k_place > 0.1
    bal = balance_of(params)
    info = bal.to_info()
    assert (info["k_place"], info["place_a0"]) == (params.k_place, params.place_a0)
    again = TrunkBalance.from_info({"balance": info})
    assert (again.k_place, again.place_cd) == (params.k_place, params.place_cd)
    assert "k_place" not in TrunkBalance().to_info()  # files without it stay as they were
    # the same senses as the expert's, on a body mid-stride
    body = build(planar=True, actuation="muscles", muscle_set="hfl")
    m = body.model
    d = mujoco.MjData(m)
    d.qpos[m.jnt_qposadr[m.joint("hip_flexion_r").id]] = 0.4
    d.qpos[m.jnt_qposadr[m.joint("hip_flexion_l").id]] = -0.2
    mujoco.mj_forward(m, d)
    ex = GH2010Controller(replace(params, place_cd=0.2, place_cv=0.1))
    ex.start(Context(m, d, body, Sensors(), 0.0))
    rows = d.sensordata[None].copy()
    sensed = bal.place_sense(rows, body.sensors)
    assert np.allclose(sensed, ex._channels(rows)[0, -5:])
    assert sensed[0, 0] > 0.2 and sensed[0, 1] < 0.0  # right leg ahead, left behind
    # the law: a swing leg short of its target flexes, past it extends; stance, behind: 0
    bal = TrunkBalance(k_place=0.5, place_a0=0.3, stance_load=0.1)
    placed = np.array([[0.1, 0.4, 0.0, 0.0, 1.2], [0.1, -0.1, 0.0, 0.0, 1.2]])
    loads = np.array([[0.0, 0.0], [700.0, 0.0]])
    out = bal.place_cols_drive(placed, loads)
    assert np.allclose(out[0, 0], [0.0, 0.0, 0.1]) and np.allclose(out[0, 1], [0.05, 0, 0])
    assert not out[1].any()


def test_pushes_without_the_closed_loop_fit_are_refused_in_one_line(capsys, tmp_path):
    """``reflex fit --pushes`` for the network is DAgger's (``--closed-loop``) or the
    walking fit's (``--walk-es``): alone, one line naming both, exit 2, nothing fitted."""
    from stumble.cli import main

    assert main(["reflex", "fit", "--pushes", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--pushes also for --closed-loop" in err
    assert not (tmp_path / "x" / "network.npz").exists()


def test_the_cross_entropy_gradient_is_its_loss_s_slope(episodes):
    """``_loss_grad(..., 'cross-entropy')``: the gradient matches central differences of
    the loss along a random direction of the free parameters."""
    from stumble.control.reflex.dagger import _loss_grad

    net, eps = episodes
    ep = eps[1.0]
    data = [(ep.inputs[:, side], ep.targets[:, side], ep.mask.astype(float))
            for side in range(2)]
    net = replace(net, info=dict(net.info))
    theta = net.pack()
    loss, grad = _loss_grad(net, data, "cross-entropy")
    step = np.random.default_rng(0).normal(size=theta.size)
    step *= 1e-5 / np.linalg.norm(step)
    net.unpack(theta + step)
    up = _loss_grad(net, data, "cross-entropy")[0]
    net.unpack(theta - step)
    down = _loss_grad(net, data, "cross-entropy")[0]
    assert (up - down) / 2 == pytest.approx(float(grad @ step), rel=1e-4)
    assert loss > 0.0


def test_cross_entropy_revives_a_motor_neuron_driven_off(episodes):
    """A muscle's motor neuron biased to σ ≈ 0 (c = −25) where the expert fires it: under
    the squared error its gradient carries u(1 − u) ≈ 0 and training leaves it off; under
    the cross-entropy (∂L/∂z = u − y) the same training brings it up to the labels."""
    net, eps = episodes
    ep = eps[1.0]
    data = [(ep.inputs[:, side], ep.targets[:, side], ep.mask.astype(float))
            for side in range(2)]
    j = list(net.topology.muscles).index("TA")
    dead = replace(net, c=net.c.copy(), info=dict(net.info))
    dead.c[j] = -25.0
    label = np.mean([y[w > 0, j].mean() for _x, y, w in data])
    assert label > 0.05  # the expert fires TA through the walk

    def mean_ta(n):
        return np.mean([n.forward(x)[0][w > 0, j].mean() for x, _y, w in data])

    assert mean_ta(dead) < 1e-6
    squared, _l = train_on(dead, data, iterations=10)
    crossed, _l = train_on(dead, data, iterations=10, loss="cross-entropy")
    assert mean_ta(squared) < 1e-4
    assert mean_ta(crossed) > 0.5 * label


def test_an_unknown_loss_is_refused(episodes):
    net, eps = episodes
    ep = eps[1.0]
    with pytest.raises(ValueError, match="loss 'l1': one of squared, cross-entropy"):
        train_on(net, [(ep.inputs[:, 0], ep.targets[:, 0], ep.mask.astype(float))],
                 iterations=1, loss="l1")


def test_loss_without_the_closed_loop_fit_is_refused_in_one_line(capsys, tmp_path):
    """``reflex fit --loss`` is DAgger's: without ``--closed-loop``, one line, exit 2."""
    from stumble.cli import main

    assert main(["reflex", "fit", "--loss", "cross-entropy", "--out",
                 str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--loss is for --closed-loop" in err
    assert not (tmp_path / "x" / "network.npz").exists()


def test_cross_entropy_on_two_processes_gives_the_same_numbers(episodes):
    """``SetPool.start(net, 'cross-entropy')``: the workers use the loss they are given,
    the one-process cross-entropy and its gradient bit for bit."""
    from stumble.control.reflex.dagger import SetPool, _loss_grad

    net, eps = episodes
    data = [(ep.inputs[:, side], ep.targets[:, side], ep.mask.astype(float))
            for ep in eps.values() for side in range(2)]
    pool = SetPool(2)
    try:
        pool.hold(data)
        pool.start(net, "cross-entropy")
        loss, grad = pool.loss_grad(net, net.pack())
    finally:
        pool.close()
    ref_loss, ref_grad = _loss_grad(net, data, "cross-entropy")
    assert loss == ref_loss and np.array_equal(grad, ref_grad)
    assert loss != _loss_grad(net, data)[0]  # not the squared error


def test_the_command_line_offers_the_losses_dagger_has():
    from stumble.cli import _parser
    from stumble.control.reflex.dagger import LOSSES

    fit = next(a for a in _parser()._subparsers._group_actions[0].choices["reflex"]
               ._subparsers._group_actions[0].choices["fit"]._actions if a.dest == "loss")
    assert tuple(fit.choices) == LOSSES


def test_a_trip_episode_trips_the_left_foot_and_goes_on_labelled():
    """``collect(trip=0.1)``: the expert with a touch response (``expert-touch``, β = 1)
    walks the same walk as untripped until the left foot's first swing after
    ``TRIP_WALK_IN_S``; at 0.1 of it the obstacle is set before the toe, the foot touches
    it, the expert recovers (it does every own-gait trip to 0.35 of swing) and every tick
    after the history is labelled to the episode's end."""
    from stumble.control.reflex import dagger as D
    from stumble.control.reflex.gh2010 import load_params

    net, expert = default_network("cross-entropy"), load_params("expert-touch")
    tripped = collect(net, expert, 1.0, seed=3, speed_m_per_s=1.2, duration_s=4.0, trip=0.1)
    plain = collect(net, expert, 1.0, seed=3, speed_m_per_s=1.2, duration_s=4.0)
    assert tripped.trip == {"swing": 0.1, "set": True, "touched": True}
    assert plain.trip is None
    assert tripped.walked_s == pytest.approx(4.0, abs=0.003)
    assert np.array_equal(tripped.mask, plain.mask) and tripped.mask[-1]
    # the same states until the trip (after TRIP_WALK_IN_S), other ones after it
    k = int(1000 * D.TRIP_WALK_IN_S)
    assert np.array_equal(tripped.inputs[:k], plain.inputs[:k])
    assert not np.allclose(tripped.inputs[-200:], plain.inputs[-200:])


def test_trip_episodes_without_the_closed_loop_fit_are_refused_in_one_line(capsys, tmp_path):
    """``reflex fit --trip-episodes`` is DAgger's: without ``--closed-loop``, or out of
    0-20, one line, exit 2, nothing fitted."""
    from stumble.cli import main

    for extra, says in (([], "--trip-episodes is for --closed-loop"),
                        (["--closed-loop", "--trip-episodes", "21"],
                         "--trip-episodes 21: must be 0-20")):
        args = ["reflex", "fit", "--trip-episodes", "2", *extra, "--out", str(tmp_path / "x")]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err
    assert not (tmp_path / "x" / "network.npz").exists()


def test_each_pass_records_its_trip_episodes(tmp_path, monkeypatch):
    """``dagger(trips=2)``: each pass runs two trip episodes besides its walks, at swing
    fractions drawn in 0.05-0.75 by seed and pass (the same draw again for the same
    seed), each recorded in the pass's row (here 0.3 s episodes: no trip is reached)."""
    import json

    from stumble.control.reflex import dagger as D

    net, expert = default_network("closed-loop"), shipped_params("seed003")
    monkeypatch.setattr(D, "judge", lambda n, speeds, pool=None, pushes=(): {"cost": 1.0})
    monkeypatch.setattr(D, "_collect_job", lambda a: collect(*a[:5], duration_s=0.3,
                                                             pushes=a[5], trip=a[6]))
    monkeypatch.setattr(D, "train_on", lambda n, data, pool=None, loss="squared": (n, 0.5))
    monkeypatch.setattr(D, "ident_data", lambda n, ident: [])
    swings = []
    for run in ("a", "b"):
        out = tmp_path / run
        out.mkdir()
        res = D.dagger(net, None, expert, passes=2, episode_speeds=(1.2,),
                       judge_speeds=(1.2,), out_dir=out, trips=2)
        rows = [json.loads(x) for x in (out / "passes.jsonl").read_text().splitlines()]
        assert res.trips == 2 and [len(r["episodes_walked_s"]) for r in rows] == [3, 3]
        swings.append([t["swing"] for r in rows for t in r["trips"]])
        assert all(0.05 <= s <= 0.75 for s in swings[-1]) and len(set(swings[-1])) == 4
        assert all(not t["set"] for r in rows for t in r["trips"])
    assert swings[0] == swings[1]


def test_an_episode_is_not_both_tripped_and_pushed():
    """``collect(trip=..., pushes=...)`` is refused: a trip episode runs without pushes."""
    net, expert = default_network("closed-loop"), shipped_params("seed003")
    with pytest.raises(ValueError, match="tripped or pushed, not both"):
        collect(net, expert, 1.0, seed=3, speed_m_per_s=1.2, duration_s=0.3, trip=0.2,
                pushes=((0.1, 0.1, -200.0),))
