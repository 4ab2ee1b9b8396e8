"""The reflex network as a trip controller: one network, never switched (seed 003 §IV.B).

At every network tick (1 kHz by default) the controller reads each muscle's fibre
stretch, stretch velocity and tension from MuJoCo, turns them into receptor rates, pushes
them into a ring buffer, evaluates each spinal segment's interneurons on inputs as old as
their afferent paths, pushes those into a second ring buffer, and sets each muscle's
excitation from interneuron outputs as old as their efferent paths. MuJoCo's muscle
actuators then do activation dynamics and eq. 1 in C. The lumbar servo holds the trunk
at its angle at the trip (seed 003 §IV.B: upper body on PD servos).

Before the trip the buffers are filled from the walking data the network was identified
from, at the same phase of the gait, so the first 50 ms after the trip see the walk
that led up to it (the seed replays the walk and its inverse dynamics until the trip).
"""

from __future__ import annotations

import numpy as np

from stumble.body.muscles import MUSCLE_NAMES
from stumble.control.reflex.network import Network
from stumble.control.reflex.receptors import GTOFilter, gto_static, spindle_ia, spindle_ii
from stumble.sim import Context

SIDES = ("r", "l")


class TrunkBalance:
    """The stance hips' trunk-lean reflex of Geyer & Herr 2010 (vestibular), an addition.

    Seed 003 does not say what holds the trunk up: its network senses the muscles only,
    and without a sense of the trunk's pitch the planar body pitches forward within half
    a second of walking (measured). Geyer & Herr 2010 hold it with the stance leg's hip
    muscles: hip extensors (GLU, HAMS) get k_p (θ − θ_ref) + k_d θ̇ of the trunk's
    forward lean θ, the hip flexor (HFL; here RF) the negative, in proportion to the
    leg's share of the body weight. Gains as reported in reimplementations of Geyer &
    Herr 2010 (k_p 1.91 /rad, k_d 0.2 s/rad, θ_ref 0.105 rad; not re-checked against the
    paper's table), delayed by a vestibulospinal latency (``delay_s``, our choice 20 ms).
    """

    def __init__(self, kp_per_rad: float = 1.91, kd_s_per_rad: float = 0.2,
                 lean_ref_rad: float = 0.105, delay_s: float = 0.02, rate_hz: float = 1000.0):
        self.kp, self.kd, self.ref = kp_per_rad, kd_s_per_rad, lean_ref_rad
        self.lag = max(1, round(delay_s * rate_hz))
        self.buf = np.zeros((self.lag + 1, 2))
        self.k = 0
        self.mus = np.zeros(len(MUSCLE_NAMES))
        for name, sign in (("GLU", 1.0), ("HAMS", 1.0), ("RF", -1.0)):
            self.mus[MUSCLE_NAMES.index(name)] = sign

    def excitation(self, ctx: Context) -> np.ndarray:
        """(2, 7) excitation to add for the sides r, l."""
        m, d = ctx.model, ctx.data
        tid = m.body("torso").id
        zx, zz = d.xmat[tid, 2], d.xmat[tid, 8]  # torso z axis, world x and z parts
        lean = float(np.arctan2(zx, zz))  # forward lean, rad
        rate = float(d.cvel[tid, 1])  # pitch rate about +y (forward lean), rad/s
        self.buf[self.k % len(self.buf)] = (lean, rate)
        lean_d, rate_d = self.buf[(self.k - self.lag) % len(self.buf)]
        self.k += 1
        drive = self.kp * (lean_d - self.ref) + self.kd * rate_d
        f = ctx.sensors.foot_force_n
        total = max(f["r"] + f["l"], 1e-6)
        share = np.array([f["r"] / total, f["l"] / total])
        return share[:, None] * drive * self.mus[None, :]


class ReflexController:
    """Seed 003's neuromuscular network driving the 14 muscles of the planar body."""

    name = "reflex"

    def __init__(self, network: Network, history: np.ndarray | None = None,
                 balance: TrunkBalance | None = None):
        """``history``: (N, 2, n_signals) receptor rates of the walk before the trip,
        oldest first, sides r and l (from ``identify.history_before``); ``balance``: the
        stance hips' trunk-lean reflex (None: off)."""
        self.net = network
        self.history = history
        self.balance = balance
        self.excitation = np.zeros((2, len(MUSCLE_NAMES)))
        self.log: list[tuple[str, float]] = []

    # ---- set-up -----------------------------------------------------------------
    def _bind(self, ctx: Context) -> None:
        m = ctx.model
        body = ctx.body
        geos = {g.name: g for g in body.muscles}
        self.act_ids = np.array([[m.actuator(f"{mus}_{s}").id for mus in MUSCLE_NAMES]
                                 for s in SIDES])
        g = [[geos[f"{mus}_{s}"] for mus in MUSCLE_NAMES] for s in SIDES]
        self.l_ref = np.array([[x.l_ref_m for x in row] for row in g])
        self.l0 = np.array([[x.l0_m for x in row] for row in g])
        self.l_opt = np.array([[x.l_opt_m for x in row] for row in g])
        self.lumbar = m.actuator("lumbar_extension").id
        self.lumbar_q = m.jnt_qposadr[m.joint("lumbar_extension").id]
        t = self.net.topology
        self.dt = 1.0 / t.rate_hz
        ins = t.inputs()
        self.in_sig = np.array([sig for _s, sig, _lag in ins])
        self.in_lag = np.array([lag for _s, _sig, lag in ins])
        conns = t.connections()
        self.c_lag = np.array([lag for _s, _j, lag in conns])
        self.c_units = self.net.units_of()
        self.c_muscle = np.array([j for _s, j, _lag in conns])
        self.n_buf = t.max_lag + 2
        self.sig_buf = np.zeros((self.n_buf, 2, t.n_signals))
        self.hid_buf = np.zeros((self.n_buf, 2, self.net.w.shape[1]))
        self.k = 0
        self.gto = GTOFilter(self.dt, 2 * len(MUSCLE_NAMES))
        self.body_weight_n = float(m.body_mass.sum()) * 9.81
        self.contact = t.contact
        # motor-neuron sum as one matrix product: (C·H) -> 7 muscles
        H = t.hidden
        self.sum_mat = np.zeros((len(conns) * H, len(MUSCLE_NAMES)))
        for k, j in enumerate(self.c_muscle):
            self.sum_mat[k * H:(k + 1) * H, j] = 1.0

    def _tick(self, rates: np.ndarray) -> np.ndarray:
        """Push one sample of standardised rates (2, n_signals); returns excitation (2, 7)."""
        net, n = self.net, self.n_buf
        self.sig_buf[self.k % n] = (rates - net.mean) / net.std
        x = self.sig_buf[(self.k - self.in_lag) % n, :, self.in_sig]  # (n_in, 2)
        h = np.tanh(x.T @ net.w + net.b)  # (2, S·H)
        self.hid_buf[self.k % n] = h
        hd = self.hid_buf[(self.k - self.c_lag) % n]  # (C, 2, S·H)
        rows = np.arange(len(self.c_lag))[:, None]
        sel = hd[rows, :, self.c_units]  # (C, H, 2)
        z = (sel * net.v[:, :, None]).reshape(-1, 2).T @ self.sum_mat + net.c
        self.k += 1
        return 1.0 / (1.0 + np.exp(-z))

    def _rates(self, ctx: Context) -> np.ndarray:
        d = ctx.data
        ids = self.act_ids
        ln = 1.0 + (d.actuator_length[ids] - self.l_ref) / self.l0
        stretch = self.l_opt * (ln - 1.0)
        vel = self.l_opt * d.actuator_velocity[ids] / self.l0
        force = -d.actuator_force[ids]
        ib = self.gto.step(gto_static(force).ravel()).reshape(2, -1)
        out = np.empty((2, self.net.topology.n_signals))
        out[:, 0:21:3] = spindle_ia(stretch, vel)
        out[:, 1:21:3] = spindle_ii(stretch)
        out[:, 2:21:3] = ib
        if self.contact:
            f = ctx.sensors.foot_force_n
            out[:, 21] = [f["r"] / self.body_weight_n, f["l"] / self.body_weight_n]
        return out

    # ---- Controller protocol ---------------------------------------------------------
    def start(self, ctx: Context) -> None:
        """Bind to the model, fill the buffers with the walk before the trip."""
        self._bind(ctx)
        if self.history is not None:
            hist = np.asarray(self.history)
            ib = hist[:, :, 2:21:3].reshape(len(hist), -1)
            self.gto.reset(ib[0])
            for k in range(len(hist)):
                r = hist[k].copy()
                r[:, 2:21:3] = self.gto.step(ib[k]).reshape(2, -1)
                self.excitation = self._tick(r)
            # muscles start at the activity the network held during the walk (the
            # excitation, filtered by the 10 ms activation, is within a few % of it)
            act = ctx.model.actuator_actadr[self.act_ids]
            ctx.data.act[act] = np.clip(self.excitation, 0.01, 1.0)
        self.lumbar_target = float(ctx.data.qpos[self.lumbar_q])
        self.log.append(("reflex", 0.0))
        self._apply(ctx)

    def update(self, ctx: Context) -> None:
        """One network tick: sense, propagate, excite."""
        self.excitation = self._tick(self._rates(ctx))
        if self.balance is not None:
            self.excitation = self.excitation + self.balance.excitation(ctx)
        self._apply(ctx)

    def _apply(self, ctx: Context) -> None:
        d = ctx.data
        d.ctrl[self.act_ids] = np.clip(self.excitation, 0.01, 1.0)
        d.ctrl[self.lumbar] = self.lumbar_target

    def state(self) -> str:
        """The network has one state."""
        return "reflex"
