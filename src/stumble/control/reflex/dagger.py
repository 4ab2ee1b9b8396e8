"""Closed-loop identification of the seed's network: DAgger with a reflex expert.

Seed 003 identifies its network from one recorded walk (``identify``); in closed loop
the body then drifts to states the walk never visited, where the network has never been
told what to do, and it sinks. DAgger (Ross, Gordon & Bagnell 2011) closes that gap: run
the network in closed loop, have an expert say at every state the network visits what
the muscles should have done, add those labelled states to the training data and train
again; the states come from the network's own walking, so what it learns is what it
needs. The expert is the Geyer & Herr 2010 walker fitted on this body
(``stumble.control.reflex.gh2010``): a controller of the same muscles with the same
kind of afferents.

What the network learns. Its excitation plus the trunk-lean addition
(``controller.TrunkBalance``, here with the expert's own lean laws and gains) drives
the muscles; the network is trained towards the expert's excitation *without* its
trunk-lean terms, so network + addition reproduce the expert. The first pass is pure
expert (β = 1), later passes hand the body to the network for a growing share of
``MIX_SEGMENT_S`` segments (β = ``BETA_DECAY`` ** pass): the expert recovers what the
network starts, and labels it. Each pass runs one episode from each of several
played-back walks (``EPISODE_SPEEDS``, 1.0-1.3 m/s) and is judged by its mean objective
from as many (``JUDGE_SPEEDS``): shown two starts and judged from one, the network
walked from that one only. The network keeps the seed's structure,
delays and identified input scaling; it is trained on the union of the identification
data (the recorded walk, seed 003's) and every closed-loop pass, by the same squared
excitation error and L-BFGS as ``identify.train``.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize

from stumble.control.reflex.controller import ReflexController, TrunkBalance
from stumble.control.reflex.gh2010 import GH2010Controller, GH2010Params
from stumble.control.reflex.network import Network
from stumble.sim import Context

# The training loss (ours; seed 003 back-propagates a squared error, ``identify.train``):
# ``squared``, half the squared excitation error, as the identification and the shipped
# networks' DAgger; ``cross-entropy``, the binary cross-entropy of the excitation in (0, 1)
# against the expert's, whose gradient at a motor neuron's input is u − y: a motor
# neuron driven to σ ≈ 0 still learns. Under the squared error its gradient carries a
# factor u(1 − u) and vanishes there: the shipped DAgger network ``placement`` holds its
# HAMS below 0.005 in 99 % of ticks of its expert's walk, where the expert fires HAMS to
# about 0.3 in late swing (docs/reflex-fits.md, "A dead hamstring motor neuron").
LOSSES = ("squared", "cross-entropy")
MIX_SEGMENT_S = 0.05  # the body changes hands between network and expert at most this often
BETA_DECAY = 0.8  # β (the expert's share of segments) is BETA_DECAY ** pass
EPISODE_S = 8.0  # closed-loop walking per episode
# m/s of the walks played back before each pass's episodes, one episode each; the
# shipped network's (the first shipped one took 1.1 and 1.3 and walked from 1.2 only)
EPISODE_SPEEDS = (1.0, 1.1, 1.2, 1.3)


class Mixed:
    """Runs the network and the expert side by side on the same sensors; one of them
    drives the body in each segment; the expert's output is recorded as labels."""

    name = "reflex"
    uses_sensors = False

    def __init__(self, student: ReflexController, expert: GH2010Controller, beta: float,
                 rng: np.random.Generator, segment_s: float = MIX_SEGMENT_S):
        self.student, self.expert, self.beta, self.rng = student, expert, beta, rng
        self.segment_s = segment_s
        self.labels: list[tuple[int, np.ndarray]] = []  # (first tick, (n, 2, nm))
        self.log = student.log

    def start(self, ctx: Context) -> None:
        """Start both; the period is the expert's (the network can plan that far)."""
        self.expert.lean_free = np.zeros(0)
        self.expert.start(ctx)
        act = ctx.data.act.copy()
        self.student.block_request = self.expert.period_steps  # both plan the same block
        self.student.start(ctx)
        if self.student.block != self.expert.period_steps:
            raise ValueError(f"the network cannot plan {self.expert.period_steps} ticks ahead")
        if self.beta >= 1.0:  # the expert drives: it sets the starting activation
            ctx.data.act[:] = act
        self.period_steps = self.expert.period_steps
        self.per_segment = max(1, round(self.segment_s / (self.period_steps
                                                          * ctx.model.opt.timestep)))
        self.blocks = 0
        self.use_expert = True

    def update(self, ctx: Context) -> np.ndarray:
        """Both plan the next block; the chosen one's plan is returned."""
        if self.blocks % self.per_segment == 0:
            self.use_expert = bool(self.rng.random() < self.beta)
        self.blocks += 1
        k = self.student.k
        s_plan = self.student.update(ctx).copy()
        e_plan = self.expert.update(ctx).copy()
        nm = self.student.nm
        self.labels.append((k, self.expert.lean_free.reshape(-1, 2, nm)))
        return e_plan if self.use_expert else s_plan

    def observe(self, rows: np.ndarray) -> None:
        """Both store the block's sensor rows."""
        self.student.observe(rows)
        self.expert.observe(rows)

    def state(self) -> str:
        """Which controller drives."""
        return "expert" if self.use_expert else "network"


@dataclass
class Episode:
    """One closed-loop pass: the network's inputs per tick and the expert's labels."""

    inputs: np.ndarray  # (T, 2, n_inputs) standardised delayed inputs, per interneuron tick
    targets: np.ndarray  # (T, 2, nm) expert excitation without trunk-lean terms
    mask: np.ndarray  # (T,) bool: ticks with a label and a full delay history
    walked_s: float = 0.0
    # a trip episode's trip: {"swing": fraction, "set": the obstacle was set, "touched":
    # the tripped foot touched it}; None: a walking episode
    trip: dict | None = None


def balance_of(params: GH2010Params, delay_s: float = TrunkBalance.DELAY_S) -> TrunkBalance:
    """The trunk-lean addition carrying the expert's own lean laws and gains."""
    return TrunkBalance(params.kp_trunk, params.kd_trunk, params.lean_ref, delay_s,
                        rectified=True, k_lean=params.k_lean,
                        stance_load=params.stance_load,
                        k_bw=params.k_bw if params.wiring == "seed003" else 0.0,
                        k_place=params.k_place, place_a0=params.place_a0,
                        place_cd=params.place_cd, place_cv=params.place_cv)


def collect(net: Network, params: GH2010Params, beta: float, seed: int,
            speed_m_per_s: float, duration_s: float = EPISODE_S, pushes=(),
            trip: float | None = None) -> Episode:
    """One episode of walking under the mixture, from the played-back walk; ``pushes``:
    (start s, duration s, force N) on the pelvis, + forward (``trip.PelvisPushes``), so
    that the states after a push are visited and labelled too. ``trip``: a swing fraction;
    the left foot (the strategy map's, ``trip.Scenario``'s leg) is tripped by the 10 cm
    obstacle at that fraction of its first swing
    after ``TRIP_WALK_IN_S`` of the mixture's own walk, as ``simulate_trip`` trips an
    own-gait walk, and the episode goes on from the trip (a trip that cannot be set at
    that instant, the toe over the box, leaves the walk untripped); not with ``pushes``."""
    if trip is not None and pushes:
        raise ValueError("an episode is tripped or pushed, not both")
    from stumble.analysis import WalkStop, fall_height_m
    from stumble.body.contact import DEFAULT_MODE as DEFAULT_CONTACT
    from stumble.body.contact import rest_support_foot
    from stumble.control.reflex.fit_walk import FIT_TIMESTEP_S
    from stumble.control.reflex.identify import history_before
    from stumble.gait.playback import stride_phase
    from stumble.gait.walk_cache import WALK_BEFORE_TRIP_S, body_and_walk
    from stumble.sim import Sensors, run

    body, pb = body_and_walk(1.75, 70.0, "male", DEFAULT_CONTACT, round(speed_m_per_s, 4),
                             FIT_TIMESTEP_S, True, net.muscle_set)
    import mujoco

    t0 = next(t for t in pb.events.heel_strike_s["r"] if t >= WALK_BEFORE_TRIP_S)
    if trip is not None:  # the same body with the obstacle, parked under the floor
        body = _trip_body(body, pb.state_at(t0)[0], net.muscle_set)
    m = body.model
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = pb.state_at(t0)
    rest_support_foot(m, d, planar=True)
    history = history_before(net.walk_rates, stride_phase(pb, t0),
                             2 * net.topology.max_lag + 2, net.topology.rate_hz)
    student = ReflexController(net, history, balance_of(params))
    student.trace = {"inputs": [], "balance": []}
    mix = Mixed(student, GH2010Controller(params), beta, np.random.default_rng(seed))
    stop = WalkStop(fall_height_m(body.model))
    force = {}
    if pushes:
        from stumble.trip import PelvisPushes

        pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        force = {"trip_force": PelvisPushes(pushes), "force_body": pelvis,
                 "force_point": lambda dd: dd.xipos[pelvis]}
    ctx = Context(m, d, body, Sensors(), 0.0)
    tripped = None
    if trip is None:
        rec = run(ctx, mix, duration_s, stop=stop, **force)
    else:
        rec, tripped = _tripped(ctx, mix, body, trip, duration_s, stop)
    x = np.concatenate(student.trace["inputs"], axis=0)
    T, nm = len(x), student.nm
    y = np.full((T, 2, nm), 0.01)
    mask = np.zeros(T, bool)
    lag = int(net.topology.max_lag)
    for k, lab in mix.labels:
        n = min(len(lab), T - k)
        if n > 0:
            y[k:k + n] = lab[:n]
            mask[k:k + n] = True
    # before the first label the network ran on the walk's history (no labels); from it
    # on, every motor path reads interneurons of the history or later: all are traced
    first = int(mix.labels[0][0]) if mix.labels else T
    assert first >= lag, "the history must cover the longest path"
    mask[:first] = False
    return Episode(x, np.clip(y, 0.01, 0.99), mask, float(rec.time_s[-1]), tripped)


TRIP_WALK_IN_S = 2.0  # a trip episode's own walk before the tripped swing (s; ours)
TRIP_SWINGS = (0.05, 0.75)  # the swing fractions trip episodes draw from: the strategy map's
TRIP_SIDE = "l"  # the tripped foot: the strategy map's (``trip.Scenario``'s default leg)


def _trip_body(base, qpos: np.ndarray, muscle_set: str):
    """``base`` (the planar body of the walk) built again with the trips' obstacle box,
    parked under the floor in the tripped foot's lane (``simulate_trip``'s own start)."""
    from stumble.body.build import build
    from stumble.trip import (
        OBSTACLE_DEPTH_M,
        OBSTACLE_HEIGHT_M,
        OBSTACLE_WIDTH_M,
        park_obstacle,
        toe_front,
    )

    body = build(planar=True, height_m=1.75, mass_kg=70.0, sex="male",
                 contact=base.contact, timestep_s=base.model.opt.timestep,
                 obstacle=(0.0, OBSTACLE_HEIGHT_M, OBSTACLE_DEPTH_M, OBSTACLE_WIDTH_M, 0.0),
                 actuation="muscles", muscle_set=muscle_set)
    park_obstacle(body.model, toe_front(base, qpos, TRIP_SIDE)[2])
    return body


def _tripped(ctx: Context, mix: Mixed, body, swing: float, duration_s: float, stop):
    """Run the mixture to ``swing`` of the tripped leg's first swing after
    ``TRIP_WALK_IN_S``, set the obstacle before the toe and run on to ``duration_s`` in
    all; the last run's recording and what the trip did (``Episode.trip``)."""
    from stumble.analysis import TripTimer
    from stumble.errors import TripNotSet
    from stumble.sim import run
    from stumble.trip import Scenario, obstacle_at, place_obstacle

    timer = TripTimer(TRIP_SIDE, swing, TRIP_WALK_IN_S, stop.fall_height_m)
    rec = run(ctx, mix, duration_s, stop=timer)
    left = duration_s - float(ctx.data.time)
    what = {"swing": swing, "set": False, "touched": False}
    if rec.stop_reason != "trip" or left <= 0.0:
        return rec, what
    try:
        box = obstacle_at(body, ctx.data.qpos.copy(), Scenario(
            controller="reflex", start="playback", mechanism="obstacle", swing_fraction=swing,
            leg={"l": "left", "r": "right"}[TRIP_SIDE]))
    except TripNotSet:
        box = None
    if box is not None:
        place_obstacle(ctx.model, box, ctx.data)
    rec = run(ctx, mix, left, stop=stop, resume=True)
    side = 0 if TRIP_SIDE == "r" else 1
    what.update({"set": box is not None, "touched": bool(rec.foot_on_obstacle[:, side].any())})
    return rec, what


def _set_loss_grad(net: Network, xd: np.ndarray, tgt: np.ndarray, wt: np.ndarray,
                   loss: str = "squared") -> tuple[float, np.ndarray, float]:
    """One (inputs, target, weight) set's share of ``_loss_grad`` (``LOSSES``): its
    weighted loss, its gradient and its weight."""
    u, cache_ = net.forward(xd)
    err = (u - tgt) * wt[:, None]
    if loss == "cross-entropy":  # ∂L/∂z = u − y: no vanishing where σ saturates
        z = cache_["z"]  # −[y log σ(z) + (1 − y) log(1 − σ(z))] = log(1 + e^z) − y z
        ce = (np.logaddexp(0.0, z) - tgt * z) * wt[:, None]
        return float(ce.sum()), net.gradient_z(xd, err, cache_), float(wt.sum())
    return 0.5 * float((err * (u - tgt)).sum()), net.gradient(xd, err, cache_), float(wt.sum())


def _sum_sets(parts) -> tuple[float, np.ndarray]:
    """The loss and gradient from the sets' shares, summed in the sets' order: the same
    numbers wherever each share was computed."""
    loss, grad, n = 0.0, 0.0, 0.0
    for loss_k, grad_k, n_k in parts:
        loss += loss_k
        grad = grad + grad_k
        n += n_k
    return loss / n, grad / n


def _loss_grad(net: Network, data: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
               loss: str = "squared"):
    """Weighted excitation error (``LOSSES``) over (inputs (T, n_in), target, weight)
    sets."""
    return _sum_sets(_set_loss_grad(net, *s, loss) for s in data)


def _set_worker(conn) -> None:
    """A ``SetPool`` process: holds its sets, and on each theta sends back their shares."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops it
    sets: list = []
    net, loss = None, "squared"
    while True:
        msg = conn.recv()
        try:
            if msg[0] == "add":
                sets += msg[1]
            elif msg[0] == "net":
                net, loss = msg[1], msg[2]
            elif msg[0] == "eval":
                net.unpack(msg[1])
                conn.send(("ok", [(k, _set_loss_grad(net, *s, loss)) for k, s in sets]))
            else:
                return
        except Exception as e:  # handed to the parent, which raises it
            conn.send(("error", f"{type(e).__name__}: {e}"))


class SetPool:
    """The training sets spread over ``processes`` (this one and ``processes`` − 1
    workers), set k on process k mod ``processes``: each loss and gradient is computed
    where its sets live, at once, and summed in the sets' order, so that training gives
    the numbers of ``_loss_grad`` in one process, bit for bit, in about 1/``processes``
    of the time (the sets are alike in size; 1.7 times as fast on two processes,
    ``benchmarks/bench_dagger.py``). That needs OpenBLAS's idle threads to sleep at once,
    which ``import stumble`` asks for before NumPy loads OpenBLAS (``stumble/__init__``):
    where NumPy was loaded first they spin on the other process's core, and two
    processes train no faster than one (the same numbers). ``close`` stops the workers."""

    def __init__(self, processes: int):
        import multiprocessing

        ctx = multiprocessing.get_context()
        self.n = max(1, int(processes))
        self._conns, self._procs = [], []
        self._local: list = []  # (k, set) of this process's share
        self._held: list = []  # every set handed out, in order (to check ``hold``'s data)
        self._count = 0
        self.loss = "squared"
        for _ in range(self.n - 1):
            mine, theirs = ctx.Pipe()
            proc = ctx.Process(target=_set_worker, args=(theirs,), daemon=True)
            proc.start()
            theirs.close()
            self._conns.append(mine)
            self._procs.append(proc)

    def hold(self, data: list) -> None:
        """Hand out the sets of ``data`` not held yet (``data`` only grows, in order: the
        sets held must be its first, the same objects, or ValueError)."""
        if len(data) < self._count or any(
                a is not b for a, b in zip(data[:self._count], self._held, strict=True)):
            raise ValueError("SetPool.hold: the data must start with the sets it holds")
        self._held += data[self._count:]
        new: list[list] = [[] for _ in range(self.n)]
        for k in range(self._count, len(data)):
            new[k % self.n].append((k, data[k]))
        self._local += new[0]
        for conn, sets in zip(self._conns, new[1:], strict=True):
            if sets:
                conn.send(("add", sets))
        self._count = len(data)

    def start(self, net: Network, loss: str = "squared") -> None:
        """The network whose free parameters each ``loss_grad`` sets (its structure), and
        the loss (``LOSSES``)."""
        self.loss = loss
        for conn in self._conns:
            conn.send(("net", net, loss))

    def loss_grad(self, net: Network, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """``_loss_grad`` over the held sets of ``net`` with ``theta`` unpacked."""
        for conn in self._conns:
            conn.send(("eval", theta))
        parts = {k: _set_loss_grad(net, *s, self.loss) for k, s in self._local}
        for conn in self._conns:
            status, got = conn.recv()
            if status != "ok":
                raise RuntimeError(f"a training worker failed: {got}")
            parts.update(got)
        return _sum_sets(parts[k] for k in range(self._count))

    def close(self) -> None:
        """Stop the workers."""
        for conn in self._conns:
            try:
                conn.send(("stop",))
            except (BrokenPipeError, OSError):
                pass
        for proc in self._procs:
            proc.join(timeout=5)
            if proc.is_alive():
                proc.terminate()
        self._conns, self._procs = [], []


def train_on(net: Network, data, iterations: int = 300,
             pool: SetPool | None = None, loss: str = "squared") -> tuple[Network, float]:
    """L-BFGS from the network's weights on the data by ``loss`` (``LOSSES``); returns
    the trained copy and the loss. ``pool``: its processes share the work (the same
    numbers)."""
    if loss not in LOSSES:
        raise ValueError(f"loss {loss!r}: one of {', '.join(LOSSES)}")
    net = replace(net, info=dict(net.info))
    theta0 = net.pack()
    if pool is not None:
        pool.hold(data)
        pool.start(net, loss)

    def fun(th):
        net.unpack(th)
        return (pool.loss_grad(net, th) if pool is not None
                else _loss_grad(net, data, loss))

    res = minimize(fun, theta0, jac=True, method="L-BFGS-B",
                   options={"maxiter": iterations, "maxfun": 2 * iterations})
    net.unpack(res.x)
    return net, float(res.fun)


@dataclass
class DaggerResult:
    """The refined network and what each pass did."""

    network: Network
    history: list[dict] = field(default_factory=list)
    wall_time_s: float = 0.0
    expert: str = "the shipped seed003-wired GH2010 (data/gh2010_seed003.json)"
    pushes: tuple = ()  # the pelvis pushes every episode and judged walk went through
    loss: str = "squared"  # the training loss (``LOSSES``)
    trips: int = 0  # trip episodes per pass (``collect``'s ``trip``)


def ident_data(net: Network, ident) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The identification's periodic data in ``train_on``'s form (both legs)."""
    return [(net.delayed_inputs(ident.signals[k]), ident.excitation[k],
             np.ones(ident.excitation.shape[1])) for k in range(2)]


EVAL_S = 10.0  # each pass's network walks this long from each judging start to be judged
JUDGE_SPEEDS = (1.0, 1.1, 1.2, 1.3)  # m/s: the starts a pass is judged from (mean cost)
PASSES = 8


def _collect_job(args) -> Episode:
    """One episode (a top-level function for worker processes)."""
    net, params, beta, seed, speed, pushes, trip = args
    return collect(net, params, beta, seed, speed, pushes=pushes, trip=trip)


def _judge_walk(args) -> tuple[float, dict, dict]:
    """One of ``judge``'s walks, (network, start m/s, s, pushes): (cost, terms, summary);
    a pushed walk's cost is ``fit_walk.push_term``'s."""
    from stumble.control.reflex.fit_walk import (
        FIT_TIMESTEP_S,
        effort_of,
        push_term,
        walk_cost,
    )
    from stumble.pipeline import simulate_walk

    net, v, duration_s, pushes = args
    r = simulate_walk("network", duration_s, v, network=net, timestep_s=FIT_TIMESTEP_S,
                      pushes=pushes)
    if pushes:
        return push_term(r.summary), {}, r.summary
    cost, terms = walk_cost(r.summary, effort_of(r))
    return cost, terms, r.summary


def judge(net: Network, speeds: tuple[float, ...] = JUDGE_SPEEDS, pool=None,
          duration_s: float = EVAL_S, pushes=()) -> dict:
    """The walking objective of the network on its own (``fit_walk.walk_cost``) over
    ``duration_s`` from each start speed of ``speeds`` (m/s): the mean cost, the figures
    of the first and the time walked from each. ``pool``: an executor that runs the
    walks (the same numbers). ``pushes``: the network also walks ``fit_walk.PUSH_WALK_S``
    from the first start through these pelvis pushes, and the part not walked adds
    ``fit_walk.push_term`` to the cost (as ``reflex fit --pushes`` does)."""
    from stumble.control.reflex.fit_walk import PUSH_WALK_S

    jobs = [(net, v, duration_s, ()) for v in speeds]
    if pushes:
        jobs.append((net, speeds[0], PUSH_WALK_S, tuple(pushes)))
    rows = list(pool.map(_judge_walk, jobs) if pool is not None else map(_judge_walk, jobs))
    pushed = rows.pop() if pushes else None
    _cost, terms, s = rows[0]
    out = {"cost": float(np.mean([c for c, _t, _s in rows])
                         + (pushed[0] if pushed else 0.0)), "walked_s": s["walked_s"],
           "speed_m_per_s": s["speed_m_per_s"], "rmse_deg": s["rmse_deg"],
           "stance_fraction": s["stance_fraction"], "terms": terms,
           "walked_s_by_start": {str(v): r[2]["walked_s"]
                                 for v, r in zip(speeds, rows, strict=True)}}
    if pushed:
        out["push_term"] = pushed[0]
        out["pushed_walked_s"] = pushed[2]["walked_s"]
    return out


def dagger(net: Network, ident, params: GH2010Params, passes: int = PASSES, seed: int = 0,
           workers: int = 1, progress=None, episode_speeds: tuple = EPISODE_SPEEDS,
           judge_speeds: tuple = JUDGE_SPEEDS, expert: str | None = None,
           out_dir=None, pushes=(), loss: str = "squared", trips: int = 0) -> DaggerResult:
    """Refine ``net`` by DAgger with the GH2010 expert ``params`` (module docstring;
    ``expert``: what it is, for the record, default the shipped one's name); each pass's
    episodes start from the walks at ``episode_speeds`` (m/s), its network is judged by
    ``judge`` from ``judge_speeds`` and the best of them is returned. ``out_dir``: each
    pass's row is appended to ``passes.jsonl`` there as it ends, and the best network so
    far saved as ``best_network.npz`` (a stopped fit loses nothing). ``pushes``: every
    episode walks through these pelvis pushes ((start s, duration s, force N), e.g.
    ``fit_walk.PUSHES``) and ``judge`` walks through them too (none: as before).
    ``loss``: the training loss (``LOSSES``). ``trips``: each pass also runs this many
    trip episodes (``collect``'s ``trip``, without pushes), from the walks at
    ``episode_speeds`` in turn, each at a swing fraction drawn uniformly from
    ``TRIP_SWINGS`` (by ``seed`` and pass), so that the states a trip leads to are
    labelled too; an expert with a stumbling corrective reflex (``expert-touch``) drives
    its share of them through it (the labels are its walking laws alone)."""
    from concurrent.futures import ProcessPoolExecutor
    from pathlib import Path

    from stumble.jsonio import dumps

    t0 = time.perf_counter()
    base = ident_data(net, ident)
    data: list = []
    pushes = tuple(tuple(q) for q in pushes)
    out = DaggerResult(net) if expert is None else DaggerResult(net, expert=expert)
    out.pushes, out.loss, out.trips = pushes, loss, trips
    sets = SetPool(workers) if workers > 1 else None  # training, the same numbers
    pool = ProcessPoolExecutor(workers) if workers > 1 else None
    try:
        best_cost = judge(net, judge_speeds, pool=pool, pushes=pushes)["cost"]
        for i in range(passes):
            beta = BETA_DECAY ** i
            jobs = [(net, params, beta, seed * 1000 + 10 * i + j, speed, pushes, None)
                    for j, speed in enumerate(episode_speeds)]
            draw = np.random.default_rng([seed, i, 7])  # the trips' swing fractions
            jobs += [(net, params, beta, 10**6 + seed * 1000 + 10 * i + j,
                      episode_speeds[j % len(episode_speeds)], (),  # (trips: no pushes)
                      round(float(draw.uniform(*TRIP_SWINGS)), 3)) for j in range(trips)]
            tic = time.perf_counter()
            eps = list(pool.map(_collect_job, jobs) if pool else map(_collect_job, jobs))
            collect_s = time.perf_counter() - tic
            for ep in eps:
                for side in range(2):
                    data.append((ep.inputs[:, side], ep.targets[:, side],
                                 ep.mask.astype(float)))
            tic = time.perf_counter()
            net, fit_loss = train_on(net, base + data, pool=sets, loss=loss)
            train_s = time.perf_counter() - tic
            net.info["balance"] = balance_of(params).to_info()
            tic = time.perf_counter()
            judged = judge(net, judge_speeds, pool=pool, pushes=pushes)
            row = {"pass": i, "beta": beta, "loss": fit_loss,
                   "samples": int(sum(w.sum() for _x, _y, w in data)),
                   "episodes_walked_s": [ep.walked_s for ep in eps], **judged,
                   **({"trips": [{**ep.trip, "walked_s": round(ep.walked_s, 3)}
                                 for ep in eps if ep.trip is not None]} if trips else {}),
                   "wall_time_s": round(time.perf_counter() - t0, 1),
                   "collect_s": round(collect_s, 1), "train_s": round(train_s, 1),
                   "judge_s": round(time.perf_counter() - tic, 1)}
            if row["cost"] < best_cost:
                best_cost, out.network = row["cost"], net
                if out_dir is not None:  # written whole, then renamed
                    net.save(Path(out_dir) / ".best_network.tmp.npz")
                    os.replace(Path(out_dir) / ".best_network.tmp.npz",
                               Path(out_dir) / "best_network.npz")
            out.history.append(row)
            if out_dir is not None:
                with open(Path(out_dir) / "passes.jsonl", "a") as f:
                    f.write(dumps(row) + "\n")
            if progress is not None:
                progress(row)
    finally:
        if pool is not None:
            pool.shutdown()
        if sets is not None:
            sets.close()
    out.wall_time_s = time.perf_counter() - t0
    return out
