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

import math

import numpy as np

from stumble.body.muscles import MUSCLE_NAMES
from stumble.control.reflex.network import Network
from stumble.control.reflex.receptors import (
    IA_BASE,
    IA_STRETCH_GAIN,
    IA_VELOCITY_EXPONENT,
    IA_VELOCITY_GAIN,
    II_BASE,
    II_STRETCH_GAIN,
    GTOFilter,
    gto_static,
)
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

    DELAY_S = 0.02  # vestibulospinal latency (our choice)

    def __init__(self, kp_per_rad: float = 1.91, kd_s_per_rad: float = 0.2,
                 lean_ref_rad: float = 0.105, delay_s: float = DELAY_S,
                 rate_hz: float = 1000.0):
        self.kp, self.kd, self.ref = kp_per_rad, kd_s_per_rad, lean_ref_rad
        self.lag = max(1, round(delay_s * rate_hz))
        self.buf = np.zeros((self.lag + 1, 2))
        self.k = 0
        self.tid = -1
        self.mus = np.zeros(len(MUSCLE_NAMES))
        for name, sign in (("GLU", 1.0), ("HAMS", 1.0), ("RF", -1.0)):
            self.mus[MUSCLE_NAMES.index(name)] = sign

    def excitation(self, ctx: Context) -> np.ndarray:
        """(2, 7) excitation to add for the sides r, l (a buffer reused every call)."""
        d = ctx.data
        if self.tid < 0:
            self.tid = ctx.model.body("torso").id
            self.out = np.zeros((2, len(MUSCLE_NAMES)))
        xm = d.xmat[self.tid]
        lean = math.atan2(xm[2], xm[8])  # torso z axis leaning towards +x: forward, rad
        rate = d.cvel[self.tid, 1]  # pitch rate about +y (forward lean), rad/s
        i = self.k % len(self.buf)
        self.buf[i, 0], self.buf[i, 1] = lean, rate
        lean_d, rate_d = self.buf[(self.k - self.lag) % len(self.buf)]
        self.k += 1
        drive = self.kp * (lean_d - self.ref) + self.kd * rate_d
        f = ctx.sensors.foot_force_n
        fr, fl = f["r"], f["l"]
        total = fr + fl
        if total <= 0.0:
            self.out[:] = 0.0
            return self.out
        np.multiply(self.mus, drive * fr / total, out=self.out[0])
        np.multiply(self.mus, drive * fl / total, out=self.out[1])
        return self.out


class ReflexController:
    """Seed 003's neuromuscular network driving the 14 muscles of the planar body."""

    name = "reflex"
    # foot loads (trunk balance, contact afferents) at 200 Hz, as the recording: the
    # network itself reads the muscles at every tick
    sensor_hz = 200.0

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
        self.body_weight_n = float(m.body_mass.sum()) * 9.81
        ids = self.act_ids.ravel()
        # the 14 muscles are contiguous actuators: read them through a slice (a view)
        lo = int(ids[0])
        self.act_slice = (slice(lo, lo + ids.size) if np.array_equal(
            ids, np.arange(lo, lo + ids.size)) else ids)
        # receptor constants per muscle (flat r then l): stretch and its rate in mm, mm/s
        self.k_mm = (1000.0 * self.l_opt / self.l0).ravel()
        self.l_ref_flat = self.l_ref.ravel()
        self._bind_network()

    def _bind_network(self) -> None:
        """Ring buffers and index arrays of the network (no model needed)."""
        t = self.net.topology
        net = self.net
        self.dt = 1.0 / t.rate_hz
        n_sig = t.n_signals
        self.inv_std = 1.0 / net.std
        ins = t.inputs()
        self.in_lag = np.array([lag for _s, _sig, lag in ins])
        in_sig = np.array([sig for _s, sig, _lag in ins])
        conns = t.connections()
        H = t.hidden
        SH = net.w.shape[1]
        self.c_lag = np.repeat([lag for _s, _j, lag in conns], H)
        units = net.units_of().ravel()  # (C·H,)
        self.n_buf = t.max_lag + 2
        # flat ring buffers (slot, side, channel) and the offsets of what each reads
        self.sig_buf = np.zeros(self.n_buf * 2 * n_sig)
        self.hid_buf = np.zeros(self.n_buf * 2 * SH)
        self.sig_row, self.hid_row = 2 * n_sig, 2 * SH
        self.in_off = np.array([s * n_sig + in_sig for s in range(2)])  # (2, n_in)
        self.hid_off = np.array([s * SH + units for s in range(2)])  # (2, C·H)
        self.w, self.b, self.c = net.w, net.b, net.c
        # motor-neuron sum: weights of each path times its segment's interneurons -> muscle
        mv = np.zeros((len(conns) * H, len(MUSCLE_NAMES)))
        for k, (_s, j, _lag) in enumerate(conns):
            mv[k * H:(k + 1) * H, j] = net.v[k]
        self.mv = mv
        self.k = 0
        self.gto = GTOFilter(self.dt, 2 * len(MUSCLE_NAMES))
        self.rates = np.zeros((2, n_sig))
        self.contact = t.contact

    def _tick(self, rates: np.ndarray) -> np.ndarray:
        """Push one sample of rates (2, n_signals); returns excitation (2, 7)."""
        n, k = self.n_buf, self.k
        slot = k % n
        self.sig_buf[slot * self.sig_row:(slot + 1) * self.sig_row] = (
            (rates - self.net.mean) * self.inv_std).ravel()
        x = self.sig_buf.take(((k - self.in_lag) % n) * self.sig_row + self.in_off)
        h = np.tanh(x @ self.w + self.b)  # (2, S·H) interneurons
        self.hid_buf[slot * self.hid_row:(slot + 1) * self.hid_row] = h.ravel()
        hd = self.hid_buf.take(((k - self.c_lag) % n) * self.hid_row + self.hid_off)
        self.k = k + 1
        return 1.0 / (1.0 + np.exp(-(hd @ self.mv + self.c)))

    def _rates(self, ctx: Context) -> np.ndarray:
        d = ctx.data
        sl = self.act_slice
        d_mm = self.k_mm * (d.actuator_length[sl] - self.l_ref_flat)  # fibre stretch, mm
        v_mm = self.k_mm * d.actuator_velocity[sl]  # fibre stretch velocity, mm/s
        out = self.rates  # (2, n_signals): per muscle Ia, II, Ib; r then l
        ia = np.copysign(np.abs(v_mm) ** IA_VELOCITY_EXPONENT, v_mm)
        ia *= IA_VELOCITY_GAIN
        ia += IA_STRETCH_GAIN * d_mm + IA_BASE
        out[:, 0:21:3] = np.maximum(ia, 0.0).reshape(2, -1)
        out[:, 1:21:3] = np.maximum(II_BASE + II_STRETCH_GAIN * d_mm, 0.0).reshape(2, -1)
        out[:, 2:21:3] = self.gto.step(gto_static(-d.actuator_force[sl])).reshape(2, -1)
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
            ib = hist[:, :, 2:21:3].reshape(len(hist), -1)  # (N, 14): r muscles, l muscles
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
        exc = self._tick(self._rates(ctx))
        if self.balance is not None:
            exc += self.balance.excitation(ctx)
        self.excitation = exc
        np.clip(exc.ravel(), 0.01, 1.0, out=ctx.data.ctrl[self.act_slice])

    def _apply(self, ctx: Context) -> None:
        d = ctx.data
        d.ctrl[self.act_slice] = np.clip(self.excitation.ravel(), 0.01, 1.0)
        d.ctrl[self.lumbar] = self.lumbar_target

    def state(self) -> str:
        """The network has one state."""
        return "reflex"
