"""The reflex network as a trip controller: one network, never switched (seed 003 §IV.B).

At every network tick (1 kHz by default) each muscle's fibre stretch, stretch velocity
and tension, sensed by MuJoCo (``stumble.body.sensors``), become receptor rates;
each spinal segment's interneurons see those rates as old as their afferent paths, and
each muscle's excitation comes from interneuron outputs as old as their efferent paths.
MuJoCo's muscle actuators then do activation dynamics and eq. 1 in C. The lumbar servo
holds the trunk at its angle at the trip (seed 003 §IV.B: upper body on PD servos).

No path is shorter than its afferent plus efferent delay (17 ms at the nominal
velocities), so the excitations of the next ``block`` ticks are already fixed by the
state sensed so far. The controller therefore hands the physics loop a whole block of
per-tick controls, which MuJoCo steps natively (``mujoco.rollout``), takes back the
block's sensor rows, and evaluates receptors and network once per block, vectorised:
the same numbers as tick by tick (``block=1``), at a fraction of the Python cost.

Before the trip the buffers are filled from the walking data the network was identified
from, at the same phase of the gait, so the first 50 ms after the trip see the walk
that led up to it (the seed replays the walk and its inverse dynamics until the trip).
"""

from __future__ import annotations

import math

import numpy as np

from stumble.body.muscles import MUSCLE_NAMES
from stumble.control.reflex.kernels import kernels
from stumble.control.reflex.network import Network
from stumble.control.reflex.receptors import (
    IA_BASE,
    IA_STRETCH_GAIN,
    IA_VELOCITY_EXPONENT,
    IA_VELOCITY_GAIN,
    IB_FORCE_N,
    IB_GAIN,
    II_BASE,
    II_STRETCH_GAIN,
    GTOFilter,
    gto_static,
)
from stumble.errors import InputError
from stumble.sim import CONTACT_FORCE_MIN_N, NATIVE_BLOCKS_MAX, Context, native_scratch

SIDES = ("r", "l")
# the spindles' constants in the order the compiled receptors take them (``kernels``)
_RATE_GAINS = (IA_VELOCITY_GAIN, IA_STRETCH_GAIN, IA_BASE, II_BASE, II_STRETCH_GAIN)


class TrunkBalance:
    """The trunk-lean reflexes of Geyer & Herr 2010 (vestibular), an addition to seed 003.

    Seed 003 does not say what holds the trunk up: its network senses the muscles only,
    and without a sense of the trunk's pitch the planar body pitches forward within half
    a second of walking (measured). Geyer & Herr 2010 hold it with the stance leg's hip
    muscles: hip extensors (GLU, HAMS) get g = k_p (θ − θ_ref) + k_d θ̇ of the trunk's
    forward lean θ, the hip flexor (HFL, or RF without one) −g, in proportion to the
    leg's share of the body's load; with ``rectified`` each gets only its positive part,
    as in Geyer & Herr (extensors [g]+, flexor [−g]+). ``k_lean`` adds their swing law
    for the hip flexor, k_lean (θ − θ_ref), to a leg whose load is below ``stance_load``
    body weights, and ``k_bw`` their double-support law: on the rear leg while both are
    loaded, GLU −k_bw and the flexor +k_bw times the front leg's load in body weights.
    With ``k_place`` not 0 it also carries the expert's swing-leg placement
    (``GH2010Params.k_place``, our addition after Song & Geyer 2015): on a leg below
    ``stance_load`` whose leg (pelvis to ankle) is ahead of vertical by α, the flexor
    k_place·[α_tgt − α]+ and GLU k_place·[α − α_tgt]+, α_tgt = place_a0 + place_cd·d +
    place_cv·v (d the centre of mass ahead of the other ankle, v its forward speed).
    Defaults: k_p 1.91 /rad, k_d 0.2 s/rad, θ_ref 0.105 rad as reported in
    reimplementations of Geyer & Herr 2010 (not re-checked against the paper's table),
    unrectified, no swing, double-support or placement term; a closed-loop-refined
    network carries its own (``from_info``). Lean, pitch rate, loads, feet, pelvis and
    centre of mass arrive through one vestibulospinal latency (``delay_s``, our choice
    20 ms).
    """

    DELAY_S = 0.02  # vestibulospinal latency (our choice)

    def __init__(self, kp_per_rad: float = 1.91, kd_s_per_rad: float = 0.2,
                 lean_ref_rad: float = 0.105, delay_s: float = DELAY_S,
                 rate_hz: float = 1000.0, rectified: bool = False, k_lean: float = 0.0,
                 stance_load: float = 0.1, k_bw: float = 0.0, k_place: float = 0.0,
                 place_a0: float = 0.35, place_cd: float = 0.0, place_cv: float = 0.0):
        self.kp, self.kd, self.ref = kp_per_rad, kd_s_per_rad, lean_ref_rad
        self.rectified, self.k_lean, self.stance_load = rectified, k_lean, stance_load
        self.k_bw = k_bw
        self.k_place, self.place_a0 = k_place, place_a0  # per rad, rad
        self.place_cd, self.place_cv = place_cd, place_cv  # rad/m, rad per m/s
        self._place_lay = self._place_cols = None
        self.lag = max(1, round(delay_s * rate_hz))
        self.weight_n = 686.7  # set by ``bind``
        self._lay = self._cols = None  # the sensor layout ``sense`` reads, its columns
        self.bind(MUSCLE_NAMES)

    def to_info(self) -> dict:
        """The gains, for a network file's ``info`` (the delay is the caller's)."""
        info = {"kp_per_rad": self.kp, "kd_s_per_rad": self.kd, "lean_ref_rad": self.ref,
                "rectified": self.rectified, "k_lean": self.k_lean,
                "stance_load": self.stance_load, "k_bw": self.k_bw}
        if self.k_place:  # (files without placement stay as they were)
            info.update(k_place=self.k_place, place_a0=self.place_a0,
                        place_cd=self.place_cd, place_cv=self.place_cv)
        return info

    @classmethod
    def from_info(cls, info: dict | None, delay_s: float = DELAY_S,
                  rate_hz: float = 1000.0) -> TrunkBalance:
        """The balance a network file names (``info['balance']``), or the default."""
        gains = dict((info or {}).get("balance") or {})
        return cls(delay_s=delay_s, rate_hz=rate_hz, **gains)

    def bind(self, muscles: tuple[str, ...], weight_n: float | None = None) -> None:
        """Drive one leg's ``muscles`` (in actuator order): extensors +, the flexor −."""
        self.flexor = "HFL" if "HFL" in muscles else "RF"
        self.mus = np.zeros(len(muscles))
        self.ext = np.zeros(len(muscles))
        self.flex = np.zeros(len(muscles))
        for name, sign in (("GLU", 1.0), ("HAMS", 1.0), (self.flexor, -1.0)):
            self.mus[muscles.index(name)] = sign
        self.ext[[muscles.index("GLU"), muscles.index("HAMS")]] = 1.0
        self.flex[muscles.index(self.flexor)] = 1.0
        self.cols = np.array([muscles.index(n) for n in ("GLU", "HAMS", self.flexor)])
        self.ds = np.zeros(len(muscles))  # double support: GLU −, flexor +
        self.ds[muscles.index("GLU")], self.ds[muscles.index(self.flexor)] = -1.0, 1.0
        if weight_n is not None:
            self.weight_n = weight_n

    def sense_cols(self, lay) -> np.ndarray:
        """The sensor columns ``sense`` reads: the torso's axis x and z, its pitch rate,
        the feet's vertical forces and the ankles' x."""
        if self._lay is not lay:
            self._lay, self._cols = lay, np.concatenate([
                lay.torso_z[[0, 2]], [lay.torso_angvel[1]], lay.foot_force[:, 2],
                lay.foot_pos[:, 0]])
        return self._cols

    def sense(self, rows: np.ndarray, lay) -> np.ndarray:
        """(n, 6) lean (rad), pitch rate (rad/s), the right and left feet's vertical loads
        (N) and their ankles' forward positions (m), from sensor rows (n, nsensordata)."""
        g = rows[:, self.sense_cols(lay)]
        out = np.empty((len(rows), 6))
        out[:, 0] = np.arctan2(g[:, 0], g[:, 1])  # forward lean (z axis towards +x)
        out[:, 1] = g[:, 2]  # pitch rate about +y
        out[:, 2:4] = -g[:, 3:5]  # vertical loads
        out[:, 4:6] = g[:, 5:7]
        return out

    def place_cols(self, lay) -> np.ndarray:
        """The sensor columns ``place_sense`` reads: the pelvis' x and z, the ankles' x,
        their z, the centre of mass' x and forward speed."""
        if self._place_lay is not lay:
            self._place_lay, self._place_cols = lay, np.concatenate([
                lay.pelvis[[0, 2]], lay.foot_pos[:, 0], lay.foot_pos[:, 2],
                [lay.com[0], lay.com_vel[0]]])
        return self._place_cols

    def place_sense(self, rows: np.ndarray, lay) -> np.ndarray:
        """(n, 5) each leg's angle from vertical α (rad, pelvis to ankle, forward +), the
        centre of mass ahead of the other leg's ankle (m, 2) and its forward speed (m/s),
        from sensor rows (n, nsensordata): the placement's senses."""
        r = rows[:, self.place_cols(lay)]  # pelvis x, z, ankle x (2), ankle z (2), COM x, vx
        out = np.empty((len(rows), 5))
        np.arctan2(r[:, 2:4] - r[:, :1], r[:, 1:2] - r[:, 4:6], out=out[:, 0:2])
        np.subtract(r[:, 6:7], r[:, 3:1:-1], out=out[:, 2:4])
        out[:, 4] = r[:, 7]
        return out

    def place_cols_drive(self, placed: np.ndarray, loads: np.ndarray) -> np.ndarray:
        """The placement's drive of GLU, HAMS and the flexor (n, 2, 3) from the delayed
        ``place_sense`` rows (n, 5) and the feet's loads (n, 2; N)."""
        alpha = placed[:, 0:2]
        e = self.k_place * (self.place_a0 + self.place_cd * placed[:, 2:4]
                            + self.place_cv * placed[:, 4:5] - alpha)
        on = (loads < self.stance_load * self.weight_n) & (alpha > 0.0)
        out = np.zeros((len(placed), 2, 3))
        out[:, :, 2] = on * np.maximum(e, 0.0)
        out[:, :, 0] = on * np.maximum(-e, 0.0)
        return out

    def drive(self, sensed: np.ndarray) -> np.ndarray:
        """(n, 2, n_muscles) excitation from (n, 6) delayed lean, rate, loads, ankles."""
        out = np.zeros((len(sensed), 2, len(self.mus)))
        out[:, :, self.cols] = self.drive_cols(sensed)
        return out

    def drive_cols(self, sensed: np.ndarray) -> np.ndarray:
        """``drive`` of the muscles it reaches only, (n, 2, 3): GLU, HAMS, the flexor
        (``cols``); the other muscles' drive is zero."""
        kern = kernels()
        if kern is not None:  # the same numbers, compiled (``kernels``)
            out = np.empty((len(sensed), 2, 3))
            kern["balance_cols"](sensed, float(self.kp), float(self.kd), float(self.ref),
                                 bool(self.rectified), float(self.k_lean),
                                 self.stance_load * self.weight_n, float(self.k_bw),
                                 float(self.weight_n), out)
            return out
        lean = sensed[:, 0] - self.ref
        g = self.kp * lean + self.kd * sensed[:, 1]  # (n,)
        fz = sensed[:, 2:4]
        total = fz[:, 0] + fz[:, 1]
        pos = total > 0.0
        share = np.where(pos[:, None], fz / np.where(pos, total, 1.0)[:, None], 0.5)
        out = np.empty((len(sensed), 2, 3))
        if self.rectified:
            ext = np.maximum(g, 0.0)[:, None] * share
            out[:, :, 0] = ext
            out[:, :, 1] = ext
            out[:, :, 2] = np.maximum(-g, 0.0)[:, None] * share
        else:
            gs = g[:, None] * share
            out[:, :, 0] = gs
            out[:, :, 1] = gs
            out[:, :, 2] = -gs
        if self.k_lean:
            swing = fz < self.stance_load * self.weight_n
            out[:, :, 2] += swing * (self.k_lean * lean)[:, None]
        if self.k_bw:
            on = fz > self.stance_load * self.weight_n
            x = sensed[:, 4:6]
            rear = on & on[:, ::-1] & (x < x[:, ::-1])
            bw = self.k_bw * fz[:, ::-1] / self.weight_n * rear
            out[:, :, 0] -= bw  # GLU
            out[:, :, 2] += bw  # the flexor
        return out


class TouchResponse:
    """The stumbling corrective reaction, an addition to seed 003's network (ours), as
    ``TrunkBalance`` is: what a foot's touch by anything but the floor makes the legs do.

    A touch that starts (a touched tick after an untouched one, the foot's last response
    over) triggers, ``latency_s`` later, for ``hold_s`` the touched leg's ``ipsi``
    excitations, then for ``after_s`` its ``after`` ones, and throughout both the other
    leg's ``contra`` ones: per muscle, added to the network's excitation (after the trunk
    balance, before the clip to 0.01-1). With ``by_foot`` (as ``GH2010Params.scr_phase``
    foot) a touch of the foot ahead of the other (its ankle's x at the touch; late swing)
    triggers the ``*_ahead`` sets instead: people flex the tripped leg early in swing
    and extend it late (Eng et al. 1994, Schillings et al. 2000); ``hold_ahead_s`` and
    ``after_ahead_s``, when given, are those sets' own durations (default the others').

    In people a trip in swing brings the swing leg's knee and hip flexors and ankle
    dorsiflexors in about 60-80 ms, then its extensors (Eng, Winter & Patla 1994, Exp
    Brain Res 102:339; Zehr & Stein 1999, Prog Neurobiol 58:185), and the support leg's
    plantarflexors and hip extensors push off (Pijnappels et al. 2005, J Biomech 38:627).
    The pattern is not given here but fitted in closed loop
    (``fit_walk.network_space(touch_response=True)``), from 0: a network without a
    response, or with every gain 0, runs as before, bit for bit.

    ``latency_s`` 0.065 s: the biceps femoris' onset 64 ms after a trip (Eng et al. 1994,
    seed 003 §IV.A), as ``GH2010Params.scr_latency_s``; ``hold_s`` and ``after_s`` (s)
    our choices or fitted.
    """

    LATENCY_S = 0.065  # Eng et al. 1994 (seed 003 §IV.A): BF 64 ms after a trip
    SETS = ("ipsi", "after", "contra")
    AHEAD_SETS = ("ipsi_ahead", "after_ahead", "contra_ahead")  # ``by_foot``
    CROSS = "cross"  # the recovery step's set (``cross_hold_s``)
    # the touched foot has landed when its vertical load exceeds this share of body
    # weight (ours; as ``GH2010Params.stance_load``'s 0.1), sensed through the sole's
    # afferent delay (``Topology.load_lag``, as GH2010's crossing reads a delayed load)
    LAND_LOAD = 0.1

    def __init__(self, muscles: tuple[str, ...], gains: dict | None = None,
                 latency_s: float = LATENCY_S, hold_s: float = 0.1, after_s: float = 0.1,
                 rate_hz: float = 1000.0, by_foot: bool = False,
                 hold_ahead_s: float | None = None, after_ahead_s: float | None = None,
                 cross_hold_s: float | None = None):
        gains = gains or {}
        # the recovery step (``cross_hold_s`` given): when the touched foot lands after its
        # touch (``LAND_LOAD``), the other leg's ``cross`` set for ``cross_hold_s``, its
        # swing over the obstacle (ours; as Geyer & Herr's crossing gains here)
        self.cross = cross_hold_s is not None
        self.by_foot = bool(by_foot)
        if not self.by_foot and (hold_ahead_s is not None or after_ahead_s is not None):
            raise InputError("touch response: hold_ahead_s and after_ahead_s are for a "
                             "response by the foot's place (by_foot)")
        if (hold_ahead_s is None) != (after_ahead_s is None):
            raise InputError("touch response: give hold_ahead_s and after_ahead_s both, or "
                             "neither")
        self.sets = (self.SETS + (self.AHEAD_SETS if self.by_foot else ())
                     + ((self.CROSS,) if self.cross else ()))
        unknown = set(gains) - set(self.sets)
        if unknown:
            raise InputError(f"touch response: unknown gain set(s) {sorted(unknown)}")
        self.muscles = tuple(muscles)
        self.gains = {k: {m: float((gains.get(k) or {}).get(m, 0.0)) for m in self.muscles}
                      for k in self.sets}
        for k, g in gains.items():
            bad = set(g) - set(self.muscles)
            if bad:
                raise InputError(f"touch response: {k} names muscles the network does not "
                                 f"drive: {sorted(bad)}")
            for m, v in g.items():
                if not (isinstance(v, (int, float)) and np.isfinite(v)):
                    raise InputError(f"touch response: {k} gain of {m} is {v!r}, not a "
                                     "finite number")
        for name, v, lo in (("latency_s", latency_s, 0.02), ("hold_s", hold_s, 0.0),
                            ("after_s", after_s, 0.0), ("hold_ahead_s", hold_ahead_s, 0.0),
                            ("after_ahead_s", after_ahead_s, 0.0),
                            ("cross_hold_s", cross_hold_s, 0.0)):
            if v is not None and not (isinstance(v, (int, float)) and np.isfinite(v)
                                      and lo <= v <= 5.0):
                raise InputError(f"touch response: {name} = {v} is not within {lo}-5 s")
        self.latency_s, self.hold_s, self.after_s = latency_s, hold_s, after_s
        # the ahead sets' own durations (None: hold_s and after_s, as every file before)
        self.hold_ahead_s, self.after_ahead_s = hold_ahead_s, after_ahead_s
        self.lag = max(1, round(latency_s * rate_hz))  # ticks
        self.hold = round(hold_s * rate_hz)
        self.after = round(after_s * rate_hz)
        self.hold_ahead = self.hold if hold_ahead_s is None else round(hold_ahead_s * rate_hz)
        self.after_ahead = (self.after if after_ahead_s is None
                            else round(after_ahead_s * rate_hz))
        self.span = max(self.hold + self.after, self.hold_ahead + self.after_ahead)
        self.cross_hold_s = cross_hold_s
        self.cross_hold = 0 if cross_hold_s is None else round(cross_hold_s * rate_hz)
        self.w = np.array([[self.gains[k][m] for m in self.muscles] for k in self.sets])

    @property
    def on(self) -> bool:
        """Whether any gain is not 0."""
        return bool(np.any(self.w))

    def to_info(self) -> dict:
        """The response, for a network file's ``info['touch_response']``."""
        return {"latency_s": self.latency_s, "hold_s": self.hold_s, "after_s": self.after_s,
                **({"by_foot": True} if self.by_foot else {}),
                **{k: v for k, v in (("hold_ahead_s", self.hold_ahead_s),
                                     ("after_ahead_s", self.after_ahead_s),
                                     ("cross_hold_s", self.cross_hold_s)) if v is not None},
                **{k: dict(self.gains[k]) for k in self.sets}}

    @classmethod
    def from_info(cls, info: dict | None, muscles: tuple[str, ...],
                  rate_hz: float = 1000.0) -> TouchResponse | None:
        """The response a network file names (``info['touch_response']``), or None."""
        d = (info or {}).get("touch_response")
        if d is None:
            return None
        d = dict(d)
        gains = {k: d.pop(k) for k in cls.SETS + cls.AHEAD_SETS + (cls.CROSS,) if k in d}
        unknown = set(d) - {"latency_s", "hold_s", "after_s", "by_foot", "hold_ahead_s",
                            "after_ahead_s", "cross_hold_s"}
        if unknown:
            raise InputError(f"touch response: unknown field(s) {sorted(unknown)}")
        return cls(muscles, gains, rate_hz=rate_hz, **d)

    def drive(self, first: int, n: int, onsets: np.ndarray,
              ahead: np.ndarray | None = None,
              landings: np.ndarray | None = None) -> np.ndarray | None:
        """The excitation (n, 2, n_muscles) it adds at ticks first … first+n−1, given each
        foot's last touch onset (tick; −inf when none), with ``by_foot`` whether that
        foot was ahead of the other then, and with ``cross`` each foot's landing after its
        touch (tick; −inf when none), or None when it adds nothing."""
        out = None
        ticks = np.arange(first, first + n)
        if self.cross and landings is not None:
            for side in range(2):
                land = landings[side]
                if not math.isfinite(land) or first >= land + self.cross_hold:
                    continue
                c = (ticks >= land) & (ticks < land + self.cross_hold)
                if c.any():
                    if out is None:
                        out = np.zeros((n, 2, len(self.muscles)))
                    out[c, 1 - side] += self.w[-1]
        for side in range(2):
            o = onsets[side]
            if not math.isfinite(o) or first >= o + self.lag + self.span:
                continue
            ahead_sets = self.by_foot and ahead is not None and ahead[side]
            hold, after = ((self.hold_ahead, self.after_ahead) if ahead_sets
                           else (self.hold, self.after))
            t = ticks - (int(o) + self.lag)
            a = (t >= 0) & (t < hold)
            b = (t >= hold) & (t < hold + after)
            if not (a.any() or b.any()):
                continue
            if out is None:
                out = np.zeros((n, 2, len(self.muscles)))
            w = self.w[len(self.SETS):] if ahead_sets else self.w
            out[a, side] += w[0]
            out[b, side] += w[1]
            out[a | b, 1 - side] += w[2]
        return out

    def end_tick(self, onsets: np.ndarray, landings: np.ndarray | None = None) -> float:
        """The first tick from which ``drive`` adds nothing, given each foot's last touch
        onset and (``cross``) landing (ticks; −inf when none): −inf without either."""
        end = -math.inf
        for side in range(2):
            o = onsets[side]
            if math.isfinite(o):
                end = max(end, o + self.lag + self.span)
            if self.cross and landings is not None and math.isfinite(landings[side]):
                end = max(end, landings[side] + self.cross_hold)
        return end

    def running(self, tick: int, onset: float) -> bool:
        """Whether a response from ``onset`` is still pending or running at ``tick``."""
        return np.isfinite(onset) and tick < onset + self.lag + self.span


class ReflexController:
    """Seed 003's neuromuscular network driving the planar body's muscles (7 per leg, or 8
    with the iliopsoas)."""

    name = "reflex"
    uses_sensors = False  # reads the sensor rows of each block (``observe``) instead

    def __init__(self, network: Network,
                 history: tuple[np.ndarray, np.ndarray] | None = None,
                 balance: TrunkBalance | None = None, block: int | None = None):
        """``history``: the receptor rates (N, 2, n_signals) of the walk before the trip,
        oldest first, sides r and l, and the tendon-organ filter state before them (from
        ``identify.history_before``); ``balance``: the stance hips' trunk-lean reflex
        (None: off); ``block``: ticks evaluated at once (default: as many as the
        shortest reflex path allows; 1: tick by tick)."""
        self.net = network
        self.history = history
        self.balance = balance
        self.block_request = block
        self.trace: dict | None = None  # {"inputs": [...], "balance": [...]} when tracing
        self.nm = network.topology.n_muscles
        self.excitation = np.zeros((2, self.nm))
        self.log: list[tuple[str, float]] = []
        self.response = self._response_of(network)

    @staticmethod
    def _response_of(network: Network) -> TouchResponse | None:
        """The network's touch response (``info['touch_response']``) when any gain of it
        is not 0, else None (the network runs as without one)."""
        t = network.topology
        r = TouchResponse.from_info(network.info, t.muscles, t.rate_hz)
        return r if r is not None and r.on else None

    # ---- set-up -----------------------------------------------------------------
    def _bind(self, ctx: Context) -> None:
        m = ctx.model
        geos = {g.name: g for g in ctx.body.muscles}
        muscles = self.net.topology.muscles
        body_muscles = tuple(g.name[:-2] for g in ctx.body.muscles if g.name.endswith("_r"))
        if body_muscles != muscles:
            raise InputError(f"the network drives {', '.join(muscles)} but the body has "
                             f"{', '.join(body_muscles)}")
        self.act_ids = np.array([[m.actuator(f"{mus}_{s}").id for mus in muscles]
                                 for s in SIDES])
        g = [geos[f"{mus}_{s}"] for s in SIDES for mus in muscles]
        if self.balance is not None:
            self.balance.bind(muscles, float(m.body_mass.sum()) * 9.81)
        self.lumbar = m.actuator("lumbar_extension").id
        self.lumbar_q = m.jnt_qposadr[m.joint("lumbar_extension").id]
        self.torso = m.body("torso").id
        self.body_weight_n = float(m.body_mass.sum()) * 9.81
        ids = self.act_ids.ravel()
        lo = int(ids[0])  # the 14 muscles are contiguous actuators: read through a slice
        self.act_slice = (slice(lo, lo + ids.size) if np.array_equal(
            ids, np.arange(lo, lo + ids.size)) else ids)
        # fibre stretch (mm) = k_mm·(tendon length − l_ref); its rate likewise (rigid tendon)
        self.k_mm = np.array([1000.0 * x.l_opt_m / x.l0_m for x in g])
        self.l_ref = np.array([x.l_ref_m for x in g])
        self._bind_network()

    def _bind_network(self) -> None:
        """Ring buffers and index arrays of the network (no model needed)."""
        t = self.net.topology
        net = self.net
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
        # ticks whose output is fixed by what has been sensed: the shortest path
        self.a_min = int(self.in_lag.min())
        longest = self.a_min + int(self.c_lag.min())
        if self.balance is not None:
            longest = min(longest, self.balance.lag)
        self.block = max(1, min(self.block_request or longest, longest))
        per_step = getattr(self, "per_step", 1)  # ticks a physics step holds (``start``)
        if per_step > 1:
            self.block = max(per_step, self.block - self.block % per_step)
        self.n_buf = t.max_lag + 2 * self.block + self.a_min + 2
        # flat ring buffers (slot, side, channel) and the offsets of what each reads
        self.sig_buf = np.zeros(self.n_buf * 2 * n_sig)
        self.hid_buf = np.zeros(self.n_buf * 2 * SH)
        self.sig_row, self.hid_row = 2 * n_sig, 2 * SH
        self.in_off = np.array([s * n_sig + in_sig for s in range(2)])  # (2, n_in)
        self.hid_off = np.array([s * SH + units for s in range(2)])  # (2, C·H)
        self.w, self.b, self.c = net.w, net.b, net.c
        nm = self.nm
        mv = np.zeros((len(conns) * H, nm))  # path weights -> motor neurons
        for k, (_s, j, _lag) in enumerate(conns):
            mv[k * H:(k + 1) * H, j] = net.v[k]
        self.mv = mv
        self._in_at: dict[int, np.ndarray] = {}  # ``_gather_idx``'s, per ring slot
        self._in_bufs: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # ``_in_scratch``'s
        self._mn_at: dict[int, np.ndarray] = {}
        self._slots_at: dict[tuple[int, int], np.ndarray] = {}  # ``_slots``'
        self._bal_at: dict[tuple[int, int], np.ndarray] = {}  # balance buffer rows
        self.k = 0  # ticks sensed so far
        self.h_done = 0  # interneuron ticks evaluated so far
        self.gto = GTOFilter(1.0 / t.rate_hz, 2 * nm)
        self.ib_cols = slice(2, 3 * nm, 3)
        self.contact = t.contact
        self.touch_sig = t.touch_signal  # the touch afferent's signal, or None
        # per-tick sensed state of the current block, and the block's excitations
        self.sensed = np.zeros((self.block, 3, 2 * nm))  # length, velocity, force
        self.loads = np.zeros((self.block, 2))
        self.touches = np.zeros((self.block, 2))  # each foot touched (1) or not (0)
        # the touch response's trigger: each foot's last touch onset (tick), touched now
        self._onsets = np.full(2, -np.inf)
        self._was_touched = np.zeros(2, dtype=bool)
        self._ahead = np.zeros(2, dtype=bool)  # each foot ahead of the other at its onset
        self._landings = np.full(2, -np.inf)  # each touched foot's landing after its onset
        self._resp_end: float | None = None  # ``response.end_tick`` of these (None: anew)
        self.exc_block = np.zeros((self.block, 2, nm))
        self._nb_ticks = np.arange(self.block)
        self.block_start = 0
        if self.balance is not None:
            self.bal_buf = np.zeros((self.balance.lag + self.block + 1, 6))
        # the placement's senses (``TrunkBalance.k_place``), rows as the balance's
        self.place_buf = (np.zeros((len(self.bal_buf), 5)) if self.balance is not None
                          and self.balance.k_place else None)
        # the compiled block's (``_next_block_compiled``) scratch and constants
        self._scratch = tuple(np.empty((self.block, 2 * self.nm)) for _ in range(7))
        self._no_balance = np.zeros((0, 2, 3))
        self._out_bufs = (np.empty((self.block, 2, len(self.c_lag))),
                          np.empty((self.block, 2, self.nm)))
        self._bal_cols = (self.balance.cols.astype(np.int64) if self.balance is not None
                          else np.zeros(3, dtype=np.int64))
        self._touch_q = -1 if self.touch_sig is None else int(self.touch_sig)
        self._bal_scratch = (np.empty(self.block, dtype=np.int64),
                             np.empty((self.block, 6)), np.empty((self.block, 2, 3)))
        self._no_place = np.zeros((0, 5))
        self._bal_par = None  # the balance's numbers for the compiled block (``start``)
        self._meta = np.zeros(16, dtype=np.int64)  # the NumPy loops' arguments
        self._resp_args = None  # the touch response's numbers for ``run_blocks``
        # ``run_blocks``' last block's excitations and controls
        self._run_exc = (np.empty((self.block, 2, nm)), np.empty((self.block, 2 * nm)))

    # views made on each use, not kept: a deep copy (``pipeline.WalkInCache``) copies
    # arrays one by one, and a kept view would then no longer see its array
    _sig2d = property(lambda self: self.sig_buf.reshape(self.n_buf, -1),
                      doc="The signals' ring as (slot, 2·n_signals).")
    _hid2d = property(lambda self: self.hid_buf.reshape(self.n_buf, -1),
                      doc="The interneurons' ring as (slot, 2·S·H).")
    _place_or_none = property(
        lambda self: self.place_buf if self.place_buf is not None else self._no_place,
        doc="The placement's ring, or one of no rows.")

    # ---- the network over a range of ticks --------------------------------------------
    def _push_signals(self, first: int, rates: np.ndarray) -> None:
        """Store rates (n, 2, n_signals) of ticks first, first+1, …"""
        n = len(rates)
        z = ((rates - self.net.mean) * self.inv_std).reshape(n, -1)
        self.sig_buf.reshape(self.n_buf, -1)[self._slots(first, n)] = z

    def _slots(self, first: int, n: int) -> np.ndarray:
        """Ring slots of ticks first … first+n−1 (kept per first slot and n)."""
        key = (first % self.n_buf, n)
        slots = self._slots_at.get(key)
        if slots is None:
            slots = self._slots_at[key] = (first + np.arange(n)) % self.n_buf
        return slots

    def _gather_idx(self, cache: dict, lag: np.ndarray, row: int, off: np.ndarray,
                    first: int, n: int) -> np.ndarray:
        """Flat indices (n, 2, len(lag)) into a ring buffer of rows ``row`` long of what
        ticks first … first+n−1 read, each channel ``off`` ``lag`` ticks back; a whole
        block's kept in ``cache`` per ring slot (the same few slots recur)."""
        key = first % self.n_buf
        idx = cache.get(key) if n == self.block else None
        if idx is None:
            ticks = np.arange(first, first + n)
            idx = ((ticks[:, None, None] - lag) % self.n_buf) * row + off
            if n == self.block:
                cache[key] = idx
        return idx

    def _interneurons(self, upto: int) -> None:
        """Evaluate interneurons of ticks h_done … upto−1 (their inputs are sensed)."""
        if upto <= self.h_done:
            return
        n = upto - self.h_done
        kern = kernels()
        if kern is not None:  # the same gather, compiled (into kept buffers unless traced)
            x, h = (self._in_scratch(n) if self.trace is None else
                    (np.empty((n, 2, len(self.in_lag))), np.empty((n, 2, self.w.shape[1]))))
            kern["ring_take"](self.sig_buf, self.h_done, self.in_lag, self.in_off,
                              self.sig_row, self.n_buf, x)
        else:
            idx = self._gather_idx(self._in_at, self.in_lag, self.sig_row, self.in_off,
                                   self.h_done, n)
            x = self.sig_buf.take(idx)  # (n, 2, n_inputs): the delayed standardised inputs
            h = np.empty((n, 2, self.w.shape[1]))
        if self.trace is not None:
            self.trace["inputs"].append(x)
        np.matmul(x, self.w, out=h)  # h = tanh(x @ w + b), (n, 2, S·H)
        np.add(h, self.b, out=h)
        np.tanh(h, out=h)
        if kern is not None:
            kern["store_rows"](h, self.hid_buf.reshape(self.n_buf, -1), self.h_done)
        else:
            self.hid_buf.reshape(self.n_buf, -1)[self._slots(self.h_done, n)] = h.reshape(n, -1)
        self.h_done = upto

    def _in_scratch(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Kept buffers for ``n`` ticks' delayed inputs (n, 2, n_inputs) and interneurons
        (n, 2, S·H) (the compiled path untraced; the same few n recur)."""
        got = self._in_bufs.get(n)
        if got is None:
            got = self._in_bufs[n] = (np.empty((n, 2, len(self.in_lag))),
                                      np.empty((n, 2, self.w.shape[1])))
        return got

    def _motor(self, first: int, n: int) -> np.ndarray:
        """Excitation (n, 2, 7) of ticks first … first+n−1."""
        idx = self._gather_idx(self._mn_at, self.c_lag, self.hid_row, self.hid_off,
                               first, n)
        return 1.0 / (1.0 + np.exp(-(self.hid_buf.take(idx) @ self.mv + self.c)))

    def _tick(self, rates: np.ndarray) -> np.ndarray:
        """One tick from given rates (2, n_signals), Ib filtered: its excitation (2, 7)."""
        k = self.k
        self._push_signals(k, rates[None])
        self._interneurons(k + 1)
        self.k = k + 1
        return self._motor(k, 1)[0]

    def _rates(self, sensed: np.ndarray, loads: np.ndarray) -> np.ndarray:
        """Receptor rates (n, 2, n_signals) from sensed (n, 3, 14) muscle states."""
        n = len(sensed)
        d_mm = self.k_mm * (sensed[:, 0] - self.l_ref)  # fibre stretch, mm
        v_mm = self.k_mm * sensed[:, 1]  # fibre stretch velocity, mm/s
        ia = (IA_VELOCITY_GAIN * np.copysign(np.abs(v_mm) ** IA_VELOCITY_EXPONENT, v_mm)
              + IA_STRETCH_GAIN * d_mm + IA_BASE)
        ib, self.gto.z = self.gto.block(gto_static(-sensed[:, 2]))
        out = np.empty((n, 2, self.net.topology.n_signals))
        nm3 = 3 * self.nm
        out[:, :, 0:nm3:3] = np.maximum(ia, 0.0).reshape(n, 2, -1)
        out[:, :, 1:nm3:3] = np.maximum(II_BASE + II_STRETCH_GAIN * d_mm, 0.0).reshape(n, 2, -1)
        out[:, :, 2:nm3:3] = ib.reshape(n, 2, -1)
        if self.contact:
            out[:, :, nm3] = loads / self.body_weight_n
        if self.touch_sig is not None:
            out[:, :, self.touch_sig] = self.touches[:n]
        return out

    def _next_block_compiled(self, kern: dict) -> None:
        """``_next_block`` with its elementwise steps compiled (``kernels``): one call
        where NumPy's own loops can be called from it (``kernels.numpy_loops``), else a
        few fused calls around NumPy's transcendentals and matrix products (the same
        numbers either way)."""
        k, nb = self.k, self.block
        if kern["loops"] is not None and self._fused:
            return self._next_block_fused(kern)
        if k > self.block_start:  # the ticks sensed since the last block: receptors, pushed
            first, n = self.block_start, k - self.block_start
            d, v, absv, fin = (a[:n] for a in self._scratch[:4])
            kern["net_pre"](self.sensed[:n], self.k_mm, self.l_ref, IB_FORCE_N, d, v, absv,
                            fin)
            p = np.power(absv, IA_VELOCITY_EXPONENT, out=self._scratch[5][:n])
            g = np.log(fin, out=self._scratch[6][:n])
            kern["ib_push"](g, IB_GAIN, self.gto.b, self.gto.a, self.gto.z,
                            self._scratch[4][:n], d, v, p, self.loads[:n], self.body_weight_n,
                            self.contact, self.net.mean, self.inv_std, self._sig2d, first,
                            _RATE_GAINS, self.touches[:n], self._touch_q)
        hid, t = self._out_bufs
        upto = k + self.a_min
        if upto > self.h_done:  # ``_interneurons``, fused (untraced: this path)
            n = upto - self.h_done
            x, h = self._in_scratch(n)
            kern["ring_take"](self.sig_buf, self.h_done, self.in_lag, self.in_off,
                              self.sig_row, self.n_buf, x)
            np.matmul(x, self.w, out=h)  # h = tanh(x @ w + b), (n, 2, S·H)
            np.add(h, self.b, out=h)
            np.tanh(h, out=h)
            kern["store_take"](h, self._hid2d, self.h_done, self.hid_buf, k, self.c_lag,
                               self.hid_off, self.hid_row, self.n_buf, hid)
            self.h_done = upto
        else:
            self._interneurons(upto)
            kern["ring_take"](self.hid_buf, k, self.c_lag, self.hid_off, self.hid_row,
                              self.n_buf, hid)
        np.matmul(hid, self.mv, out=t)  # (hid @ mv, into a kept buffer)
        kern["net_drive"](t, self.c)
        e = np.exp(t, out=t)
        self.exc_block = np.empty((nb, 2, self.nm))
        self.ctrl_block = np.empty((nb, 2 * self.nm))
        # the plan's rows too, when a tick is a step and the muscles are one slice
        plan = self.plan if self._plan_in_kernel else self._no_plan
        if self.balance is not None:  # ``drive_cols`` and ``place_cols_drive``, added
            rows, sensed, bal = self._bal_scratch
            kern["bal_out"](self.bal_buf, k - self.balance.lag, self._bal_par,
                            self._place_or_none, rows, sensed, bal, e, self._bal_cols,
                            self.exc_block, self.ctrl_block, plan, self._plan_rows,
                            self._act_first, self._held)
        else:
            kern["net_out"](e, self._no_balance, self._bal_cols, self.exc_block,
                            self.ctrl_block, plan, self._plan_rows, self._act_first,
                            self._held)
        self._plan_done = self._plan_in_kernel
        if self.response is not None:
            self._add_response(k, nb)
        self.block_start = k

    def _fusable(self) -> bool:
        """Whether the block can be one compiled call: the weights C-contiguous (the
        matrix products then NumPy's own calls, strides and all)."""
        return all(a.flags.c_contiguous and a.dtype == np.float64
                   for a in (self.w, self.mv, self.b, self.c))

    def _next_block_fused(self, kern: dict) -> None:
        """``_next_block_compiled`` as one compiled call (``kernels.net_update``), then
        the touch response."""
        k, nb = self.k, self.block
        first, n_r = self.block_start, k - self.block_start
        upto = k + self.a_min
        n_h = upto - self.h_done
        x, h = self._in_scratch(n_h) if n_h > 0 else self._in_scratch(1)
        self.exc_block = np.empty((nb, 2, self.nm))
        self.ctrl_block = np.empty((nb, 2 * self.nm))
        bal = self.balance
        hid, t = self._out_bufs
        rows, sensed, bal_drive = self._bal_scratch
        kern["net_update"](
            kern["loops"], self._meta, n_r > 0, first, n_r, self.sensed, self.k_mm,
            self.l_ref, IB_FORCE_N, self._scratch, IA_VELOCITY_EXPONENT, IB_GAIN,
            self.gto.b, self.gto.a, self.gto.z, self.loads, self.body_weight_n,
            self.contact, self.net.mean, self.inv_std, self._sig2d, _RATE_GAINS,
            self.touches, self._touch_q, n_h, self.h_done, self.sig_buf, self.in_lag,
            self.in_off, self.sig_row, self.n_buf, x, h, self.w, self.b, self._hid2d,
            self.hid_buf, k, self.c_lag, self.hid_off, self.hid_row, hid, self.mv, t,
            self.c, bal is not None, k - bal.lag if bal is not None else 0,
            self.bal_buf if bal is not None else self._no_rows, self._bal_par_or_none,
            self._place_or_none, rows, sensed, bal_drive, self._bal_cols, self.exc_block,
            self.ctrl_block, self.plan if self._plan_in_kernel else self._no_plan,
            self._plan_rows, self._act_first, self._held, self._no_balance)
        if n_h > 0:
            self.h_done = upto
        self._plan_done = self._plan_in_kernel
        if self.response is not None:
            self._add_response(k, nb)
        self.block_start = k

    def _sense_touches(self) -> None:
        """Sense the feet's obstacle contacts (a model without an obstacle: never touched)
        when the touch afferent or the touch response needs them."""
        need = self.touch_sig is not None or self.response is not None
        self._touch_cols = self._obstacle_cols if need else None
        if self.response is not None and self.response.lag < self.block:
            raise InputError(f"touch response: latency {self.response.latency_s} s is "
                             f"shorter than the network's block of {self.block} ticks")

    def _touch_onsets(self, k0: int, n: int, rows: np.ndarray) -> None:
        """Note each foot's touch onsets among the block's n sensed ticks from k0 (their
        sensor rows): a touched tick after an untouched one, once the foot's last response
        is over; and whether the foot was then ahead of the other (its ankle's x)."""
        touched = self.touches[:n] > 0.0
        if not touched.any() and not self._was_touched.any():
            return
        for side in range(2):
            was = self._was_touched[side]
            for i in range(n):
                now = touched[i, side]
                if now and not was and not self.response.running(k0 + i,
                                                                 self._onsets[side]):
                    self._onsets[side] = k0 + i
                    self._resp_end = None
                    x = rows[i, self.lay.foot_pos[:, 0]]
                    self._ahead[side] = x[side] > x[1 - side]
                was = now
            self._was_touched[side] = was

    def _touch_landings(self, k0: int, n: int, rows: np.ndarray) -> None:
        """Note the first tick among the block's n sensed ticks at which a touched foot
        bears ``TouchResponse.LAND_LOAD`` of body weight, its response under way, as the
        tick its landing is sensed: the sole's afferent delay later
        (``Topology.load_lag``; the recovery step's trigger)."""
        r = self.response
        for side in range(2):
            o = self._onsets[side]
            if not math.isfinite(o) or self._landings[side] >= o:
                continue  # no touch, or landed already since it
            load = -rows[:, self.lay.foot_force[side, 2]]
            after = np.arange(k0, k0 + n) >= o + r.lag
            hit = np.flatnonzero(after & (load > r.LAND_LOAD * self.body_weight_n))
            if hit.size:
                self._landings[side] = k0 + int(hit[0]) + self.net.topology.load_lag()
                self._resp_end = None

    def _add_response(self, k: int, nb: int) -> None:
        """Add the touch response to the block's excitations and clip its controls again
        (blocks it does not reach are left as they were)."""
        if self._resp_end is None:  # (kept until an onset or a landing changes)
            self._resp_end = self.response.end_tick(self._onsets, self._landings)
        if k >= self._resp_end:
            return  # no response under way (``drive`` would add nothing)
        r = self.response.drive(k, nb, self._onsets, self._ahead, self._landings)
        if r is None:
            return
        self.exc_block += r
        self.ctrl_block = np.minimum(np.maximum(self.exc_block.reshape(nb, -1), 0.01), 1.0)
        self._plan_done = False  # ``update`` writes the plan from the controls

    def _next_block(self) -> None:
        """Sense the finished block, then fix the excitations of the next one."""
        kern = kernels()
        if kern is not None and self.trace is None:
            return self._next_block_compiled(kern)
        k, nb = self.k, self.block
        if k > self.block_start:  # the ticks sensed since the last block
            n = k - self.block_start
            self._push_signals(self.block_start, self._rates(self.sensed[:n], self.loads[:n]))
        self._interneurons(k + self.a_min)
        self.exc_block = self._motor(k, nb)
        if self.balance is not None:
            sensed = self.bal_buf[self._bal_rows(k - self.balance.lag, nb)]
            bal = self.balance.drive_cols(sensed)
            if self.place_buf is not None:
                bal += self.balance.place_cols_drive(
                    self.place_buf[self._bal_rows(k - self.balance.lag, nb)], sensed[:, 2:4])
            if self.trace is not None:
                full = np.zeros((nb, 2, self.nm))
                full[:, :, self.balance.cols] = bal
                self.trace["balance"].append((k, full))
            self.exc_block[:, :, self.balance.cols] += bal
        self.ctrl_block = np.minimum(np.maximum(self.exc_block.reshape(nb, -1), 0.01), 1.0)
        if self.response is not None:
            self._add_response(k, nb)
        self.block_start = k

    def _bal_rows(self, first: int, n: int) -> np.ndarray:
        """Rows of the balance's ring buffer of ticks first … first+n−1 (kept per first
        row and n)."""
        size = len(self.bal_buf)
        key = (first % size, n)
        rows = self._bal_at.get(key)
        if rows is None:
            rows = self._bal_at[key] = (first + self._nb_ticks[:n]) % size
        return rows

    # ---- Controller protocol ---------------------------------------------------------
    def start(self, ctx: Context) -> None:
        """Bind to the model, fill the buffers with the walk before the trip."""
        from stumble.control.reflex.network import tick_ratio

        # steps per tick (a step that divides the 1 ms tick) or ticks per step (a step of
        # whole ticks; the block then a whole number of steps, ``_bind_network``)
        self.every, self.per_step = tick_ratio(ctx.model.opt.timestep,
                                               self.net.topology.rate_hz)
        self._bind(ctx)
        self.lay = lay = ctx.body.sensors
        self._obs_cols = np.concatenate([lay.muscle_length, lay.muscle_velocity,
                                         lay.muscle_force, lay.foot_force[:, 2]])
        self._n_mus3 = 3 * len(lay.muscle_length)
        self._obstacle_cols = lay.obstacle_found
        self._sense_touches()
        self._bal_sense_cols = (self.balance.sense_cols(lay) if self.balance is not None
                                else None)
        self._bal_g = np.empty((self.block * self.every, 7))
        self._place_d = np.empty((2, self.block * self.every, 2))  # ``place_pre``'s
        self._place_cols = (self.balance.place_cols(lay) if self.place_buf is not None
                            else np.zeros(8, dtype=np.int64))
        self._no_cols, self._no_lean = np.zeros(0, dtype=np.int64), np.zeros(0)
        self._no_rows, self._no_alpha = np.zeros((0, 6)), np.zeros((0, 2))
        self._lean_buf = np.empty(self.block * self.every)
        self._alpha_buf = np.empty((self.block * self.every, 2))
        self._fused = self._fusable()
        if self.balance is not None:
            b = self.balance
            self._bal_par = np.array([
                float(b.kp), float(b.kd), float(b.ref), 1.0 if b.rectified else 0.0,
                float(b.k_lean), b.stance_load * b.weight_n, float(b.k_bw),
                float(b.weight_n), float(b.k_place), float(b.place_a0), float(b.place_cd),
                float(b.place_cv)])
        self._bal_par_or_none = self._bal_par if self._bal_par is not None else np.zeros(12)
        self.period_steps = self.block * self.every // self.per_step
        if self.history is not None:
            hist, gto_state = self.history
            ib = hist[:, :, self.ib_cols].reshape(len(hist), -1)  # (N, 2·nm): r, then l
            self.gto.z[:] = gto_state  # the walk's steady state (the filter is slow, 5 s)
            rates = hist.copy()
            kern = kernels()
            if kern is not None:  # the tendon organs' filter, tick by tick (compiled)
                y = np.empty_like(ib)
                kern["gto_steps"](self.gto.b, self.gto.a, self.gto.z,
                                  np.ascontiguousarray(ib), y)
                rates[:, :, self.ib_cols] = y.reshape(len(hist), 2, -1)
            else:
                for k in range(len(hist)):  # the tendon organs' filter, tick by tick
                    rates[k][:, self.ib_cols] = self.gto.step(ib[k]).reshape(2, -1)
            # then the network, a block of ticks at a time (the numbers of ``_tick``
            # tick by tick: each tick's interneurons read inputs already pushed)
            for first in range(0, len(hist), self.block):
                n = min(self.block, len(hist) - first)
                self._push_signals(self.k, rates[first:first + n])
                self._interneurons(self.k + n)
                self.k += n
            if len(hist):
                self.excitation = self._motor(self.k - 1, 1)[0]
            # muscles start at the activity the network held during the walk (the
            # excitation, filtered by the 10 ms activation, is within a few % of it)
            act = ctx.model.actuator_actadr[self.act_ids]
            ctx.data.act[act] = np.clip(self.excitation, 0.01, 1.0)
        if self.balance is not None:  # before the trip: the lean and loads of this instant
            self.bal_buf[:] = self.balance.sense(ctx.data.sensordata[None], self.lay)[0]
        if self.place_buf is not None:
            self.place_buf[:] = self.balance.place_sense(ctx.data.sensordata[None],
                                                         self.lay)[0]
        self.block_start = self.k
        self.lumbar_target = float(ctx.data.qpos[self.lumbar_q])
        ctx.data.ctrl[self.lumbar] = self.lumbar_target
        self.plan = np.empty((self.period_steps, ctx.model.nu))
        self._no_plan = np.empty((0, ctx.model.nu))
        self._plan_in_kernel = isinstance(self.act_slice, slice)
        # each physics step holds its first tick's excitations (``update``)
        self._plan_rows = np.arange(self.period_steps) * self.per_step // self.every
        self._act_first = self.act_slice.start if self._plan_in_kernel else 0
        self.log.append(("reflex", 0.0))

    def update(self, ctx: Context) -> np.ndarray:
        """The next block's controls (period_steps, nu), fixed by what has been sensed."""
        self._plan_done = False
        self._held = ctx.data.ctrl
        self._next_block()
        self.excitation = self.exc_block[-1]
        if self._plan_done:
            return self.plan
        self.plan[:] = ctx.data.ctrl
        if self.per_step > 1:  # each step holds its first tick's excitations
            self.plan[:, self.act_slice] = self.ctrl_block[::self.per_step]
        else:
            self.plan[:, self.act_slice] = (self.ctrl_block if self.every == 1
                                            else np.repeat(self.ctrl_block, self.every,
                                                           axis=0))
        return self.plan

    def observe(self, rows: np.ndarray) -> None:
        """Store the muscle states (and loads, lean) sensed at each tick of the block."""
        kern = kernels()
        if kern is not None:  # the same numbers, compiled where elementwise (``kernels``)
            return self._observe_compiled(kern, rows)
        if self.per_step > 1:  # the ticks of a step sense its row
            ticks = np.repeat(rows, self.per_step, axis=0)
        else:
            ticks = rows[::self.every] if self.every > 1 else rows
        n = len(ticks)
        k0 = self.k
        if self._touch_cols is not None:
            np.minimum(ticks[:, self._touch_cols], 1.0, out=self.touches[:n])
            if self.response is not None:
                self._touch_onsets(k0, n, ticks)
                if self.response.cross:
                    self._touch_landings(k0, n, ticks)
        g = ticks[:, self._obs_cols]  # muscle lengths, velocities, forces; feet's loads
        self.sensed[:n] = g[:, :self._n_mus3].reshape(n, 3, -1)
        if self.contact:
            self.loads[:n] = -g[:, self._n_mus3:]
        if self.balance is not None:
            self.bal_buf[self._bal_rows(k0, n)] = self.balance.sense(ticks, self.lay)
        if self.place_buf is not None:
            self.place_buf[self._bal_rows(k0, n)] = self.balance.place_sense(ticks, self.lay)
        self.k = k0 + n

    def _observe_compiled(self, kern: dict, rows: np.ndarray) -> None:
        """``observe`` in two compiled calls around NumPy's arctan2 (the same numbers);
        the touch response's Python only in blocks with a touch."""
        per_step, every = self.per_step, self.every
        n = len(rows) * per_step if per_step > 1 else -(-len(rows) // every)
        k0 = self.k
        bal = self.balance is not None
        if kern["loops"] is not None:  # one call, NumPy's arctan2 loop in it
            touched = kern["net_sense"](
                kern["loops"], self._meta, rows, per_step, every, n, self._obs_cols,
                self._n_mus3, self.contact, self.sensed, self.loads,
                self._bal_sense_cols if bal else self._no_cols, self._bal_g,
                self._touch_cols if self._touch_cols is not None else self._no_cols,
                self.touches, self._place_cols, self._place_d, self._place_or_none, k0,
                self._lean_buf, self._alpha_buf, self.bal_buf if bal else self._no_rows,
                self._no_alpha)
            self._touch_response_sense(touched, rows, k0, n)
            self.k = k0 + n
            return
        g, d = self._bal_g[:n], self._place_d[:, :n]
        touched = kern["observe_all"](
            rows, per_step, every, n, self._obs_cols, self._n_mus3, self.contact,
            self.sensed, self.loads, self._bal_sense_cols if bal else self._no_cols, g,
            self._touch_cols if self._touch_cols is not None else self._no_cols,
            self.touches, self._place_cols, d, self._place_or_none, k0)
        self._touch_response_sense(touched, rows, k0, n)
        kern["observe_store"](g, np.arctan2(g[:, 0], g[:, 1]) if bal else self._no_lean,
                              self.bal_buf if bal else self._no_rows,
                              np.arctan2(d[0], d[1]) if self.place_buf is not None
                              else self._no_alpha, self._place_or_none, k0)
        self.k = k0 + n

    def run_blocks(self, physics, n: int, guard) -> tuple | None:
        """Up to ``n`` whole blocks, the physics included, in one compiled call
        (``kernels.net_run``; ``sim.Controller``): the numbers of ``update``, the block's
        rollout and ``observe``, block by block, bit for bit. None where the block is not
        one compiled call (no kernels or NumPy's loops, a trace), the ticks are not yet
        in step with the blocks (the first block after ``start``), or the touch response
        has a recovery step (``cross_hold_s``; its onsets and drive are compiled too).
        Returns (states, sensor rows, controls, blocks run): views of kept buffers, good
        until the next call."""
        kern = kernels()
        if (kern is None or kern["loops"] is None or self.trace is not None
                or not self._fused or not self._plan_in_kernel or n < 1):
            return None
        k, nb = self.k, self.block
        if k - self.block_start != nb or k + self.a_min - self.h_done != nb:
            return None
        r = self.response
        if r is not None and r.cross:
            return None
        resp_on = r is not None and self._touch_cols is not None
        if self._resp_args is None or self._resp_args[0] is not r:
            ints = (np.array([r.lag, r.hold, r.after, r.hold_ahead, r.after_ahead, r.span,
                              int(r.by_foot)], dtype=np.int64) if r is not None
                    else np.zeros(7, dtype=np.int64))
            self._resp_args = (r, np.ascontiguousarray(r.w if r is not None
                                                       else np.zeros((3, self.nm))), ints,
                               np.ascontiguousarray(self.lay.foot_pos[:, 0], dtype=np.int64),
                               np.empty((nb, 2, self.nm)))
        _r, resp_w, resp_int, foot_x, resp_out = self._resp_args
        ps = self.period_steps
        n = min(n, NATIVE_BLOCKS_MAX)
        states, rows, plans = native_scratch(physics, NATIVE_BLOCKS_MAX * ps)
        ctr = np.array([k, self.block_start, self.h_done], dtype=np.int64)
        bal = self.balance
        x, h = self._in_scratch(nb)
        hid, t = self._out_bufs
        bal_rows, sensed, bal_drive = self._bal_scratch
        exc, ctrl = self._run_exc
        n_tick = ps * self.per_step if self.per_step > 1 else -(-ps // self.every)
        has_bal = bal is not None
        done = kern["net_run"](
            physics.addr, physics.warnings, physics.ctrl, physics.sensordata, n, ps,
            n_tick, states, rows, plans, guard.cols if guard is not None else self._no_cols,
            guard.fall_height_m if guard is not None else -np.inf,
            guard.foot_col if guard is not None else -1,
            guard is not None and guard.foot_on, CONTACT_FORCE_MIN_N, ctr,
            self.a_min, bal.lag if has_bal else 0,
            resp_on, resp_w, resp_int, self._onsets, self._ahead, self._was_touched, foot_x,
            resp_out,
            kern["loops"], self._meta, self.sensed, self.k_mm, self.l_ref, IB_FORCE_N,
            self._scratch, IA_VELOCITY_EXPONENT, IB_GAIN, self.gto.b, self.gto.a,
            self.gto.z, self.loads, self.body_weight_n, self.contact, self.net.mean,
            self.inv_std, self._sig2d, _RATE_GAINS, self.touches, self._touch_q,
            self.sig_buf, self.in_lag, self.in_off, self.sig_row, self.n_buf, x, h, self.w,
            self.b, self._hid2d, self.hid_buf, self.c_lag, self.hid_off, self.hid_row, hid,
            self.mv, t, self.c, has_bal, self.bal_buf if has_bal else self._no_rows,
            self._bal_par_or_none, self._place_or_none, bal_rows, sensed, bal_drive,
            self._bal_cols, exc, ctrl, self._plan_rows, self._act_first, self._no_balance,
            self.per_step, self.every, self._obs_cols, self._n_mus3,
            self._bal_sense_cols if has_bal else self._no_cols, self._bal_g,
            self._touch_cols if self._touch_cols is not None else self._no_cols,
            self._place_cols, self._place_d, self._lean_buf, self._alpha_buf,
            self._no_alpha)
        self.k, self.block_start, self.h_done = (int(v) for v in ctr)
        self.exc_block, self.ctrl_block = exc.copy(), ctrl.copy()
        self.excitation = self.exc_block[-1]
        last = slice((done - 1) * ps, done * ps)
        self.plan[:] = plans[last]
        self._held = physics.ctrl
        self._plan_done = True
        self._resp_end = None  # (onsets may have changed)
        return states[:done * ps], rows[:done * ps], plans[:done * ps], done

    def _touch_response_sense(self, touched: bool, rows: np.ndarray, k0: int,
                              n: int) -> None:
        """The touch response's onsets and landings among a block's ``n`` ticks from
        ``k0`` (Python, in blocks with a touch, one just ended or a crossing to watch)."""
        if self.response is not None and self._touch_cols is not None and (
                touched or self._was_touched[0] or self._was_touched[1]
                or self.response.cross):
            per_step, every = self.per_step, self.every
            ticks = np.repeat(rows, per_step, axis=0) if per_step > 1 else rows[::every]
            self._touch_onsets(k0, n, ticks)
            if self.response.cross:
                self._touch_landings(k0, n, ticks)

    def state(self) -> str:
        """The network has one state."""
        return "reflex"

    def touch_settings(self) -> Network:
        """What ``retouch`` takes: the network."""
        return self.net

    def walk_key(self) -> str:
        """What the walk before a first touch depends on: every weight of the network but
        the touch afferent's (a touch rate of 0 adds nothing) and the touch response's
        (``info['touch_response']``), its standardisation and settings, the trunk balance
        and the block (a digest)."""
        import hashlib

        net, t = self.net, self.net.topology
        w = net.w.copy()
        w[t.touch_inputs()] = 0.0
        h = hashlib.sha256(repr((t, sorted((net.info or {}).get("balance", {}).items()),
                                 self.block_request, self.balance is None)).encode())
        for a in (w, net.b, net.v, net.c, net.mean, net.std):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()

    def retouch(self, net: Network) -> None:
        """Go on with ``net``, which differs from the present network only in the touch
        afferent's weights and the touch response: before a touch those add nothing, so a
        walk to that instant is the same with either (``pipeline.WalkInCache``)."""
        before = self.walk_key()
        was, self.net = self.net, net
        if self.walk_key() != before:
            self.net = was
            raise ValueError("retouch: the networks differ in more than the touch "
                             "afferent's weights and the touch response")
        self.w = net.w
        self._fused = self._fusable() if hasattr(self, "_fused") else False
        self.response = self._response_of(net)
        self._resp_end = None
        self._sense_touches()
