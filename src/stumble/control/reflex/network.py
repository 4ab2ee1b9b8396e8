"""The spinal reflex network of seed 003 §III item 5, with its nerve delays (Table I).

Structure (Murai & Yamane 2011 §III; Murai, Yamane & Nakamura 2010). Per leg, six spinal
segments L2-S2 each bind the muscles Table I connects to them. A muscle's receptors
(spindle Ia and II, tendon organ Ib; ``receptors``) reach every segment it is bound to
through its afferent nerve, and every such segment drives the muscle's motor neurons
through its efferent nerve; each path is delayed by its nerve length over the conduction
velocity (muscle afferents 57.6 m/s, motor fibres 52.4 m/s; human sciatic nerve, 1994,
Muscle & Nerve). So muscle activity at t comes from the receptor state at t − t_d.

Neuron model and sizes (our choice; the seed does not give them):

- inputs are the three receptor rates of each bound muscle, standardised by their mean
  and spread over the walking data the network is identified from;
- each segment has ``hidden`` interneurons (default 6), h = tanh(W x + b): a few
  interneurons per segment is enough to shape the walking pattern from the bound
  muscles' state without memorising it (about 500 weights for 2 × 1235 samples);
- a muscle's motor neuron sums its bound segments' interneurons, each delayed by that
  segment's efferent path, and fires u = σ(Σ V h + c) in (0, 1): the excitation that
  MuJoCo's activation dynamics (τ = 10 ms) turns into the muscle activity of eq. 1;
- both legs use the same weights (left and right halves of the cord are mirror images);
- optional foot-contact afferents (the seed's proposed extension, §VI), off by default:
  the foot's normal force / body weight enters segments L4-S2;
- an optional touch afferent (ours, the same proposal's contact state): a touch of the
  foot by anything but the floor (1 while touched, else 0) enters segments L4-S1, the
  roots of the superficial peroneal nerve, whose cutaneous afferents from the foot's
  dorsum trigger the stumbling corrective reaction (Zehr & Stein 1999, Prog Neurobiol
  58:185). Walking data never hold a touch, so its weights are fitted in closed loop
  (``fit_walk.network_space``); a network gains it by ``Network.with_touch``.

Delays are whole samples of the network's rate (1 kHz by default, so within 0.5 ms).
"""

from __future__ import annotations

import functools
import json
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stumble.body.muscles import MUSCLE_NAMES, MUSCLE_SETS
from stumble.control.reflex.kernels import kernels
from stumble.control.reflex.receptors import SIGNALS
from stumble.errors import InputError

SEGMENTS = ("L2", "L3", "L4", "L5", "S1", "S2")  # seed 003 Table I
ALL_SEGMENTS = ("L1", *SEGMENTS)  # L1 binds only the optional iliopsoas (HFL)
# Seed 003 Table I: nerve length (m) between each muscle and spinal segment it is bound to.
NERVE_LENGTH_M: dict[str, dict[str, float]] = {
    "HAMS": {"L5": 0.57, "S1": 0.56, "S2": 0.55},
    "GLU": {"L5": 0.49, "S1": 0.48, "S2": 0.47},
    "TA": {"L4": 1.08, "L5": 1.06, "S1": 1.05},
    "GAS": {"S1": 1.13, "S2": 1.10},
    "RF": {"L2": 0.57, "L3": 0.55, "L4": 0.53},
    "VAS": {"L2": 0.68, "L3": 0.65, "L4": 0.64},
    "SOL": {"S1": 1.28, "S2": 1.25},
    # Iliopsoas (HFL, optional; not in Table I): psoas major from the anterior rami of
    # L1-L3 (lumbar plexus), iliacus from the femoral nerve (L2-L3). Our estimate, no
    # measured nerve length having been found: the psoas branches leave the roots just
    # outside their foramina, about 0.13 m from cord segments lying at the T11-L1
    # vertebrae (the cord ends at the L1-L2 disc); the iliacus branch leaves the femoral
    # nerve in the iliac fossa, about 0.35 m from the cord (Table I's femoral-nerve paths
    # to RF are 0.53-0.57 m, RF's motor point some 0.2 m further on); iliopsoas as one
    # muscle takes their mean, 0.24 m from L2, and Table I's 0.02 m per segment. A
    # parameter: ``HFL_NERVE_LENGTH_M``.
    "HFL": {"L1": 0.26, "L2": 0.24, "L3": 0.22},
}
HFL_NERVE_LENGTH_M = NERVE_LENGTH_M["HFL"]
AFFERENT_M_PER_S = 57.6  # human sciatic nerve, muscle afferents (1994, Muscle & Nerve)
EFFERENT_M_PER_S = 52.4  # human sciatic nerve, motor fibres (same source)
# Foot-contact afferents (seed 003 §VI's proposal): the sole's load through the tibial
# nerve's plantar branches, whose roots are L4-S3 (medial plantar L4-L5, lateral plantar
# S1-S2). Lengths are our estimate: to S1/S2 SOL's Table I length + 7 cm (SOL's motor
# point to the sole's nerve), to L4/L5 TA's + 0.35 m (TA's motor point in the upper shank
# to the sole).
CONTACT_NERVE_M = {"L4": 1.43, "L5": 1.41, "S1": 1.35, "S2": 1.32}
# Touch afferents (ours): the foot dorsum's skin through the superficial peroneal nerve,
# roots L4-S1. Lengths our estimate, as the sole's: TA's Table I length to each segment
# + 0.35 m (TA's motor point in the upper shank to the dorsum), a parameter.
TOUCH_NERVE_M = {"L4": 1.43, "L5": 1.41, "S1": 1.40}
HIDDEN_PER_SEGMENT = 6
RATE_HZ = 1000.0


@dataclass(frozen=True)
class Topology:
    """Which signals reach which segment, and with what delay, at a given rate."""

    rate_hz: float = RATE_HZ
    hidden: int = HIDDEN_PER_SEGMENT
    contact: bool = False
    afferent_m_per_s: float = AFFERENT_M_PER_S
    efferent_m_per_s: float = EFFERENT_M_PER_S
    muscles: tuple[str, ...] = MUSCLE_NAMES  # one leg's muscles, in actuator order
    touch: bool = False  # the touch afferent (``TOUCH_NERVE_M``)

    @property
    def segments(self) -> tuple[str, ...]:
        """The spinal segments bound to these muscles, cranial first."""
        return _derived(self)[0]

    def _segments(self) -> tuple[str, ...]:
        return tuple(seg for seg in ALL_SEGMENTS
                     if any(seg in NERVE_LENGTH_M[mus] for mus in self.muscles))

    @property
    def n_muscles(self) -> int:
        """Muscles per leg."""
        return len(self.muscles)

    @property
    def n_signals(self) -> int:
        """Signals per leg: 3 per muscle, plus the foot contact and the touch when
        enabled (in that order)."""
        return 3 * self.n_muscles + int(self.contact) + int(self.touch)

    @property
    def touch_signal(self) -> int | None:
        """The touch's signal index, or None without it."""
        return 3 * self.n_muscles + int(self.contact) if self.touch else None

    def inputs(self) -> list[tuple[int, int, int]]:
        """(segment index, signal index, afferent delay in samples) of every input."""
        return list(_derived(self)[1])

    def _inputs(self) -> list[tuple[int, int, int]]:
        out = []
        for s, seg in enumerate(self._segments()):
            for j, mus in enumerate(self.muscles):
                if seg in NERVE_LENGTH_M[mus]:
                    lag = self._samples(NERVE_LENGTH_M[mus][seg] / self.afferent_m_per_s)
                    out += [(s, 3 * j + k, lag) for k in range(len(SIGNALS))]
            if self.contact and seg in CONTACT_NERVE_M:
                lag = self._samples(CONTACT_NERVE_M[seg] / self.afferent_m_per_s)
                out.append((s, 3 * self.n_muscles, lag))
            if self.touch and seg in TOUCH_NERVE_M:
                lag = self._samples(TOUCH_NERVE_M[seg] / self.afferent_m_per_s)
                out.append((s, self.touch_signal, lag))
        return out

    def load_lag(self) -> int:
        """The sole's load afferent's shortest delay (samples: ``CONTACT_NERVE_M``'s
        shortest nerve), the network having the contact afferents or not."""
        return self._samples(min(CONTACT_NERVE_M.values()) / self.afferent_m_per_s)

    def touch_inputs(self) -> list[int]:
        """Indices of the touch afferent's inputs among ``inputs()`` (none without it)."""
        return [i for i, (_s, sig, _lag) in enumerate(self.inputs())
                if self.touch and sig == self.touch_signal]

    def connections(self) -> list[tuple[int, int, int]]:
        """(segment index, muscle index, efferent delay in samples) of every motor path."""
        return list(_derived(self)[2])

    def _connections(self) -> list[tuple[int, int, int]]:
        out = []
        segs = self._segments()
        for j, mus in enumerate(self.muscles):
            for seg, length in NERVE_LENGTH_M[mus].items():
                out.append((segs.index(seg), j, self._samples(length / self.efferent_m_per_s)))
        return out

    def path_delays_s(self) -> dict[tuple[str, str, str], float]:
        """Delay (s) of every reflex path (source muscle, segment, target muscle)."""
        out = {}
        for src in self.muscles:
            for seg, l_aff in NERVE_LENGTH_M[src].items():
                for dst in self.muscles:
                    segs2 = NERVE_LENGTH_M[dst]
                    if seg in segs2:
                        out[(src, seg, dst)] = (l_aff / self.afferent_m_per_s
                                                + segs2[seg] / self.efferent_m_per_s)
        return out

    def _samples(self, seconds: float) -> int:
        return round(seconds * self.rate_hz)

    @property
    def max_lag(self) -> int:
        """Longest afferent plus efferent delay, in samples."""
        return _derived(self)[3]


@functools.lru_cache(maxsize=64)
def _derived(t: Topology) -> tuple:
    """A topology's segments, inputs, connections and longest delay, worked out once
    (a topology is frozen, and every controller and fit reads them)."""
    ins, conns = tuple(t._inputs()), tuple(t._connections())
    return (t._segments(), ins, conns,
            max(lag for *_x, lag in ins) + max(lag for *_x, lag in conns))


def tick_ratio(timestep_s: float, rate_hz: float = RATE_HZ) -> tuple[int, int]:
    """(physics steps per network tick, network ticks per physics step): one of them is 1.
    InputError unless the time step divides a tick or is a whole number of ticks (the
    nerve delays are counted in ticks). With several ticks a step, the ticks of a step
    sense the step's one sensor row and the step holds its first tick's excitations
    (our choice: MuJoCo holds a control over a step)."""
    ratio = 1.0 / (rate_hz * timestep_s)
    every, per_step = max(1, round(ratio)), max(1, round(1.0 / ratio))
    if abs(every * timestep_s * rate_hz - 1.0) > 1e-6 and abs(
            timestep_s * rate_hz - per_step) > 1e-6:
        raise InputError(f"the reflex network ticks every {1e3 / rate_hz:g} ms: the time step "
                         f"({1e3 * timestep_s:g} ms) must divide it or be a whole number "
                         f"of ticks")
    return (every, 1) if ratio >= 1.0 - 1e-9 else (1, per_step)


def steps_per_tick(timestep_s: float, rate_hz: float = RATE_HZ) -> int:
    """Physics steps per network tick (1 when a step holds several ticks, ``tick_ratio``);
    InputError unless the time step divides a tick or is a whole number of ticks."""
    return tick_ratio(timestep_s, rate_hz)[0]


@dataclass
class Network:
    """Weights of the reflex network; shared by both legs."""

    topology: Topology
    w: np.ndarray  # (n_inputs, S·H), masked to each input's segment block
    b: np.ndarray  # (S·H,)
    v: np.ndarray  # (n_connections, H)
    c: np.ndarray  # (7,) motor neuron biases
    mean: np.ndarray  # (n_signals,) input standardisation
    std: np.ndarray
    info: dict = field(default_factory=dict)
    # (2, T, n_signals) receptor rates (Ib before its filter) over the identified stride,
    # from right heel strike: fills the delay buffers before a trip
    walk_rates: np.ndarray | None = None

    # ---- structure ---------------------------------------------------------------
    @classmethod
    def initial(cls, topology: Topology, mean: np.ndarray, std: np.ndarray,
                seed: int = 0) -> Network:
        """Small random weights (deterministic for a seed)."""
        rng = np.random.default_rng(seed)
        n_in, H = len(topology.inputs()), topology.hidden
        n_seg = len(topology.segments)
        fan = np.bincount([s for s, _x, _y in topology.inputs()], minlength=n_seg)
        w = rng.normal(0.0, 1.0, (n_in, n_seg * H))
        seg_of_input = np.array([s for s, _x, _y in topology.inputs()])
        w *= 1.0 / np.sqrt(fan[seg_of_input])[:, None]
        w *= cls._mask(topology)
        v = rng.normal(0.0, 0.3, (len(topology.connections()), H))
        return cls(topology, w, np.zeros(n_seg * H), v, np.zeros(topology.n_muscles),
                   np.asarray(mean, float), np.asarray(std, float))

    @staticmethod
    def _mask(topology: Topology) -> np.ndarray:
        H = topology.hidden
        ins = topology.inputs()
        mask = np.zeros((len(ins), len(topology.segments) * H))
        for i, (s, _sig, _lag) in enumerate(ins):
            mask[i, s * H:(s + 1) * H] = 1.0
        return mask

    def with_delay_scale(self, scale: float, response_only: bool = False) -> Network:
        """A copy whose every nerve delay is ``scale`` times as long (slower nerves), and
        its touch response's latency and durations too (as ``GH2010Params.delay_scale``
        scales its touch reflexes' holds); ``response_only``: the touch response's alone
        (``Scenario.delays`` response)."""
        t = self.topology
        slower = t if response_only else Topology(
            t.rate_hz, t.hidden, t.contact, t.afferent_m_per_s / scale,
            t.efferent_m_per_s / scale, t.muscles, t.touch)
        info = dict(self.info)
        if info.get("touch_response") is not None:
            info["touch_response"] = {**info["touch_response"], **{
                k: info["touch_response"][k] * scale
                for k in ("latency_s", "hold_s", "after_s", "hold_ahead_s", "after_ahead_s",
                          "cross_hold_s")
                if info["touch_response"].get(k) is not None}}
        return Network(slower, self.w, self.b, self.v, self.c, self.mean, self.std,
                       info, self.walk_rates)

    def with_touch(self) -> Network:
        """A copy with the touch afferent (``Topology.touch``), its weights 0: the same
        network until they are fitted. The touch is standardised as 0 mean, unit spread
        (walking holds none), and the walk's rates hold no touch."""
        from dataclasses import replace as _replace

        t = self.topology
        if t.touch:
            return self
        new = _replace(t, touch=True)
        old_rows = {(s, sig): i for i, (s, sig, _lag) in enumerate(t.inputs())}
        w = np.zeros((len(new.inputs()), self.w.shape[1]))
        for i, (s, sig, _lag) in enumerate(new.inputs()):
            if (s, sig) in old_rows:
                w[i] = self.w[old_rows[(s, sig)]]
        walk = self.walk_rates
        if walk is not None:
            walk = np.concatenate([walk, np.zeros((*walk.shape[:2], 1))], axis=2)
        return Network(new, w, self.b.copy(), self.v.copy(), self.c.copy(),
                       np.append(self.mean, 0.0), np.append(self.std, 1.0),
                       dict(self.info), walk)

    def with_touch_response(self, by_foot: bool = False) -> Network:
        """A copy with a touch response (``controller.TouchResponse``, in
        ``info['touch_response']``; ``by_foot``: its sets by the touched foot's place), its
        gains 0: the same network until they are fitted. One it has is kept; asked
        ``by_foot`` of one that is not, its sets and durations are copied to the foot
        ahead's (the same network still)."""
        from stumble.control.reflex.controller import TouchResponse

        have = (self.info or {}).get("touch_response")
        if have is not None and (have.get("by_foot") or not by_foot):
            return self
        if have is not None:
            return self._with_response({
                **have, "by_foot": True, "hold_ahead_s": have["hold_s"],
                "after_ahead_s": have["after_s"],
                **{f"{k}_ahead": dict(have[k]) for k in TouchResponse.SETS if k in have}})
        t = self.topology
        return self._with_response(TouchResponse(t.muscles, rate_hz=t.rate_hz,
                                                 by_foot=by_foot).to_info())

    def with_cross_step(self, hold_s: float = 0.2) -> Network:
        """A copy whose touch response has the recovery step's set (``TouchResponse``'s
        ``cross``: the other leg's excitations for ``hold_s`` from the touched foot's
        landing), its gains 0: the same network until they are fitted (one it has is
        kept). ``hold_s`` 0.2 s: ours, about the first half of a swing."""
        from stumble.control.reflex.controller import TouchResponse

        have = (self.info or {}).get("touch_response")
        if have is None:
            raise InputError("--cross-step: the network has no touch response "
                             "(--touch-response)")
        if have.get("cross_hold_s") is not None:
            return self
        return self._with_response({**have, "cross_hold_s": float(hold_s),
                                    TouchResponse.CROSS: {}})

    def with_response_gains(self, gains: dict) -> Network:
        """A copy whose touch response has these gains set by hand (``{set: {muscle:
        gain}}``, each within -1 to 1, as the fitted ones; ``reflex fit --set-response``),
        the rest as it was."""
        from stumble.control.reflex.controller import TouchResponse

        have = (self.info or {}).get("touch_response")
        if have is None:
            raise InputError("--set-response: the network has no touch response "
                             "(--touch-response)")
        sets = TouchResponse.from_info({"touch_response": have}, self.topology.muscles,
                                       self.topology.rate_hz).sets
        resp = dict(have)
        for k, g in gains.items():
            if k not in sets:
                raise InputError(f"--set-response: the response has no set {k!r} (it has "
                                 f"{', '.join(sets)})")
            for m, v in g.items():
                if m not in self.topology.muscles:
                    raise InputError(f"--set-response: {k}.{m}: the network drives "
                                     f"{', '.join(self.topology.muscles)}")
                if not (isinstance(v, (int, float)) and math.isfinite(v) and -1 <= v <= 1):
                    raise InputError(f"--set-response: {k}.{m} = {v!r} is not within -1 to 1")
            resp[k] = {**(have.get(k) or {}), **{m: float(v) for m, v in g.items()}}
        return self._with_response(resp)

    def _with_response(self, resp: dict) -> Network:
        """A copy with the touch response ``resp`` (``info['touch_response']``), checked."""
        from stumble.control.reflex.controller import TouchResponse

        t = self.topology
        TouchResponse.from_info({"touch_response": resp}, t.muscles, t.rate_hz)
        return Network(t, self.w, self.b, self.v, self.c, self.mean, self.std,
                       {**(self.info or {}), "touch_response": resp}, self.walk_rates)

    def with_ahead_response(self, other: Network) -> Network:
        """A copy whose touch response, by the foot's place, takes ``other``'s sets and
        durations for a touch of the foot ahead (its own for the foot behind): both must
        be the same walking network, ``other``'s response by the foot's place."""
        from stumble.control.reflex.controller import TouchResponse

        mine = (self.info or {}).get("touch_response")
        theirs = (other.info or {}).get("touch_response")
        if mine is None:
            raise InputError("--ahead-from: the starting network has no touch response")
        if theirs is None or not theirs.get("by_foot"):
            raise InputError("--ahead-from: that network has no touch response by the "
                             "foot's place (--scr-phase foot)")
        t = self.topology
        untouched = [i for i in range(len(self.w)) if i not in set(t.touch_inputs())]
        same = (t == other.topology and np.array_equal(self.w[untouched], other.w[untouched])
                and all(np.array_equal(getattr(self, k), getattr(other, k))
                        for k in ("b", "v", "c", "mean", "std"))
                and self.info.get("balance") == other.info.get("balance"))
        if not same:  # the walk before a touch (the touch afferent's weights aside)
            raise InputError("--ahead-from: that network walks differently from the start "
                             "(its weights, standardisation or trunk balance differ)")
        resp = {k: v for k, v in mine.items() if not k.endswith("_ahead")}
        resp.update(by_foot=True,
                    hold_ahead_s=theirs.get("hold_ahead_s", theirs["hold_s"]),
                    after_ahead_s=theirs.get("after_ahead_s", theirs["after_s"]),
                    **{k: dict(theirs[k]) for k in TouchResponse.AHEAD_SETS if k in theirs})
        return self._with_response(resp)

    def units_of(self) -> np.ndarray:
        """(n_connections, H) hidden-unit index read by each motor path."""
        H = self.topology.hidden
        return np.array([[s * H + k for k in range(H)]
                         for s, _j, _lag in self.topology.connections()])

    # ---- parameters as one vector (for optimisers) ------------------------------
    def pack(self) -> np.ndarray:
        """Free parameters as one vector (masked weights only)."""
        m = self._mask(self.topology).astype(bool)
        return np.concatenate([self.w[m], self.b, self.v.ravel(), self.c])

    def unpack(self, theta: np.ndarray) -> None:
        """Set the free parameters from ``pack``'s layout."""
        m = self._mask(self.topology).astype(bool)
        k = int(m.sum())
        self.w = np.zeros_like(self.w)
        self.w[m] = theta[:k]
        nb = self.b.size
        self.b = theta[k:k + nb].copy()
        nv = self.v.size
        self.v = theta[k + nb:k + nb + nv].reshape(self.v.shape).copy()
        self.c = theta[k + nb + nv:].copy()

    # ---- batch evaluation over periodic data (identification) -------------------
    def delayed_inputs(self, signals: np.ndarray) -> np.ndarray:
        """(T, n_inputs) standardised inputs, each shifted by its afferent delay."""
        x = (signals - self.mean) / self.std
        return np.stack([np.roll(x[:, sig], lag) for _s, sig, lag in self.topology.inputs()],
                        axis=1)

    def forward(self, xd: np.ndarray) -> tuple[np.ndarray, dict]:
        """Excitation (T, 7) from delayed inputs (T, n_inputs) of periodic data."""
        h = np.tanh(xd @ self.w + self.b)  # (T, S·H)
        kern = kernels()
        cache = {"h": h}
        if kern is not None:  # the same sums in the same order, without the copies
            segs, js, lags = self._path_arrays()
            z = np.empty((len(h), self.topology.n_muscles))
            kern["batch_z"](h, self.v, segs, js, lags, self.c, z)
        else:
            cache["hd"] = hd = self._path_units(h)
            z = np.zeros((len(h), self.topology.n_muscles))
            contrib = np.einsum("tch,ch->tc", hd, self.v)
            for k, (_s, j, _lag) in enumerate(self.topology.connections()):
                z[:, j] += contrib[:, k]
            z += self.c
        u = 1.0 / (1.0 + np.exp(-z))
        cache.update(u=u, z=z)
        return u, cache

    def _path_units(self, h: np.ndarray) -> np.ndarray:
        """(T, C, H): each motor path's units, ``lag`` ticks later (periodic data)."""
        T, H = len(h), self.topology.hidden
        conns = self.topology.connections()
        # laid out unit by unit, then tick by tick, path fastest, as the np.stack of
        # np.roll'd fancy-indexed columns it replaces was (einsum's sums follow the
        # layout: the shipped fits re-run bit for bit)
        paths = np.empty((len(conns), T, H))
        for k, (seg, _j, lag) in enumerate(conns):  # (np.roll's copies, into place)
            lag %= T
            paths[k, lag:] = h[:T - lag, seg * H:(seg + 1) * H]
            paths[k, :lag] = h[T - lag:, seg * H:(seg + 1) * H]
        hd = np.empty((H, T, len(conns)))
        hd[...] = paths.transpose(2, 1, 0)
        return hd.transpose(1, 2, 0)

    def gradient(self, xd: np.ndarray, du: np.ndarray, cache: dict) -> np.ndarray:
        """Gradient of a loss with ∂L/∂u = ``du`` (T, 7), in ``pack`` layout."""
        u = cache["u"]
        return self.gradient_z(xd, du * u * (1.0 - u), cache)

    def gradient_z(self, xd: np.ndarray, dz: np.ndarray, cache: dict) -> np.ndarray:
        """Gradient of a loss with ∂L/∂z = ``dz`` (T, 7), z the motor neurons' input
        (u = σ(z)), in ``pack`` layout."""
        h = cache["h"]
        kern = kernels()
        if "hd" in cache or kern is None:  # (a compiled forward's cache: its paths now)
            hd = cache["hd"] if "hd" in cache else self._path_units(h)
            dv, dpre = self._path_gradient(h, hd, dz)
        else:
            segs, js, lags = self._path_arrays()
            dv, dpre = np.empty(self.v.shape), np.empty(h.shape)
            kern["batch_dh"](h, np.ascontiguousarray(dz, dtype=float), self.v, segs, js,
                             lags, dv, dpre)
        mask = self._mask(self.topology)
        dw = (xd.T @ dpre) * mask
        return np.concatenate([dw[mask.astype(bool)], dpre.sum(axis=0), dv.ravel(),
                               dz.sum(axis=0)])

    def _path_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each motor path's segment, muscle and lag (ticks), as arrays."""
        conns = self.topology.connections()
        return tuple(np.array([c[i] for c in conns], dtype=np.int64) for i in range(3))

    def _path_gradient(self, h: np.ndarray, hd: np.ndarray,
                       dz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``gradient_z``'s path weights' gradient (C, H) and interneurons' input gradient
        (T, S·H), in NumPy (``kernels``' ``batch_dh`` does the same sums)."""
        conns = self.topology.connections()
        T, H = len(h), self.topology.hidden
        js = np.array([j for _s, j, _lag in conns])
        dcontrib = dz[:, js]  # (T, C)
        dv = np.einsum("tc,tch->ch", dcontrib, hd)
        dhd = dcontrib[:, :, None] * self.v[None]  # (T, C, H)
        dh = np.zeros_like(h)
        for k, (seg, _j, lag) in enumerate(conns):  # each path's units, ``lag`` earlier
            lag %= T  # (np.roll by −lag, added in place: the same sums in the same order)
            units = slice(seg * H, (seg + 1) * H)
            dh[:T - lag, units] += dhd[lag:, k]
            dh[T - lag:, units] += dhd[:lag, k]
        return dv, dh * (1.0 - h ** 2)

    def excitation(self, signals: np.ndarray) -> np.ndarray:
        """Excitation (T, 7) of one leg over periodic receptor signals (T, n_signals)."""
        return self.forward(self.delayed_inputs(signals))[0]

    # ---- files ------------------------------------------------------------------
    def save(self, path: str | Path) -> None:
        """Write the network to an ``.npz`` file."""
        t = self.topology
        np.savez_compressed(
                 path, w=self.w, b=self.b, v=self.v, c=self.c, mean=self.mean, std=self.std,
                 rate_hz=t.rate_hz, hidden=t.hidden, contact=t.contact,
                 **({"touch": True} if t.touch else {}),
                 afferent_m_per_s=t.afferent_m_per_s, efferent_m_per_s=t.efferent_m_per_s,
                 muscles=np.array(t.muscles), segments=np.array(t.segments),
                 info=np.array(json.dumps(self.info)),
                 walk_rates=np.zeros(0) if self.walk_rates is None else self.walk_rates)

    @classmethod
    def load(cls, path: str | Path, muscles: tuple[str, ...] | None = None) -> Network:
        """Read a network written by ``save``: of any muscle set of the body, or of
        ``muscles`` when given (per leg, in order); InputError naming the file and the
        problem if it is not one (``read_network_file``: nothing is loaded in full before
        its names, shapes, types and sizes are checked against the layout its own muscle
        list implies)."""
        path = Path(path)
        z = read_network_file(path)
        names = tuple(str(s) for s in z["muscles"])
        if names not in MUSCLE_SETS.values():
            sets = "; ".join(f"{k}: {', '.join(v)}" for k, v in MUSCLE_SETS.items())
            raise InputError(f"{path}: a network of the muscles {', '.join(names)}, not a "
                             f"muscle set of the body ({sets})")
        if muscles is not None and names != tuple(muscles):
            raise InputError(f"{path}: a network of the muscles {', '.join(names)}; this "
                             f"model has {', '.join(muscles)}")
        t = Topology(float(z["rate_hz"]), int(z["hidden"]), bool(z["contact"]),
                     float(z["afferent_m_per_s"]), float(z["efferent_m_per_s"]), names,
                     bool(z.get("touch", False)))
        walk = z.get("walk_rates")
        return cls(t, z["w"], z["b"], z["v"], z["c"], z["mean"], z["std"], z["info"],
                   walk if walk is not None and walk.size else None)

    @property
    def muscle_set(self) -> str:
        """The body muscle set this network drives (``stumble.body.muscles``)."""
        return next(k for k, v in MUSCLE_SETS.items() if v == self.topology.muscles)


# ---- the network file: checked before anything is loaded in full ---------------------
MAX_FILE_BYTES = 64 * 2**20  # a network.npz on disk (the shipped one: about 0.5 MB)
MAX_ARRAY_BYTES = 32 * 2**20  # one array inflated (walk_rates at 1 kHz: about 0.4 MB)
RATE_RANGE_HZ = (100.0, 10_000.0)  # network tick rate (ours: 1 kHz)
SPEED_RANGE_M_PER_S = (1.0, 200.0)  # nerve conduction (human: about 30-120 m/s)
HIDDEN_RANGE = (1, 64)  # interneurons per segment (ours: 6)
MAX_WALK_S = 10.0  # walk_rates: at most this long a stride at the network's rate
SCALARS = ("rate_hz", "hidden", "contact", "afferent_m_per_s", "efferent_m_per_s")
NAMES = ("muscles", "segments", "info")
ARRAYS = ("w", "b", "v", "c", "mean", "std")
OPTIONAL = ("walk_rates",)
OPTIONAL_SCALARS = ("touch",)  # absent in files written before it: False


def _entries(zf: zipfile.ZipFile, where: str) -> dict[str, zipfile.ZipInfo]:
    """The archive's members by array name, checked against the names and sizes allowed."""
    known = (*SCALARS, *NAMES, *ARRAYS, *OPTIONAL, *OPTIONAL_SCALARS)
    out: dict[str, zipfile.ZipInfo] = {}
    for info in zf.infolist():
        name = info.filename.removesuffix(".npy")
        if name not in known or not info.filename.endswith(".npy"):
            raise InputError(f"{where}: unexpected entry {info.filename!r} (a stumble network "
                             f"holds {', '.join(known)})")
        if name in out:
            raise InputError(f"{where}: entry {info.filename!r} appears twice")
        if info.file_size > MAX_ARRAY_BYTES:
            raise InputError(f"{where}: entry {name} inflates to {info.file_size} bytes, more "
                             f"than the {MAX_ARRAY_BYTES} bytes a network array may have")
        out[name] = info
    missing = [n for n in (*SCALARS, *NAMES, *ARRAYS) if n not in out]
    if missing:
        raise InputError(f"{where}: not a stumble reflex network (no {', '.join(missing)})")
    return out


def _header(zf: zipfile.ZipFile, info: zipfile.ZipInfo, where: str):
    """(shape, dtype) from an .npy member's header, without reading its data."""
    with zf.open(info) as f:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, _fortran, dtype = np.lib.format.read_array_header_1_0(f)
        elif version in ((2, 0), (3, 0)):
            shape, _fortran, dtype = np.lib.format.read_array_header_2_0(f)
        else:
            raise InputError(f"{where}: entry {info.filename}: .npy version {version}")
        header_bytes = f.tell()
    if dtype.hasobject:
        raise InputError(f"{where}: entry {info.filename} holds Python objects (refused: "
                         "a network holds numbers and names only)")
    if math.prod(shape) * dtype.itemsize != info.file_size - header_bytes:
        raise InputError(f"{where}: entry {info.filename}: its header ({shape}, {dtype}) "
                         f"does not match its {info.file_size} bytes")
    return tuple(shape), dtype


def _read(zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    with zf.open(info) as f:
        return np.lib.format.read_array(f, allow_pickle=False)


def _expect(name: str, shape, dtype, want_shape, kinds: str, where: str) -> None:
    if dtype.kind not in kinds:
        raise InputError(f"{where}: {name} has type {dtype}, not "
                         f"{'text' if kinds == 'U' else 'a number'}")
    if want_shape is not None and tuple(shape) != tuple(want_shape):
        raise InputError(f"{where}: {name} has shape {tuple(shape)}, expected "
                         f"{tuple(want_shape)} for this network's muscles and layout")


def _scalar(z: dict, name: str, lo: float, hi: float, where: str) -> float:
    v = float(z[name])
    if not (math.isfinite(v) and lo <= v <= hi):
        raise InputError(f"{where}: {name} = {v:g} is outside {lo:g}-{hi:g}")
    return v


def read_network_file(path: Path) -> dict:
    """The arrays of a network ``.npz``, each checked before it is read in full.

    The file must be a regular file of at most ``MAX_FILE_BYTES``, a zip archive whose
    members are exactly the network's arrays, each inflating to at most
    ``MAX_ARRAY_BYTES``; each member's ``.npy`` header (shape, type) is read and checked
    first against the layout the file's own ``muscles``, ``hidden`` and ``contact``
    imply, then its data: finite numbers, ``std`` > 0, weights only inside their
    segment blocks, ``rate_hz``, ``hidden`` and the conduction speeds in range.
    ``info`` comes back as a dict. InputError (one line naming the file) otherwise."""
    where = str(path)
    if not path.exists():
        raise InputError(f"network file {path} does not exist")
    if path.is_dir():
        raise InputError(f"{where} is a directory, not a network file (give its network.npz)")
    if not path.is_file():
        raise InputError(f"{where} is not a regular file")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise InputError(f"{where}: {size} bytes is more than a network file may have "
                         f"({MAX_FILE_BYTES})")
    try:
        with path.open("rb") as f:
            magic = f.read(6)
        if magic == b"\x93NUMPY":
            raise InputError(f"{where} is a single .npy array, not a network .npz (written by "
                             "`stumble reflex fit`)")
        if not magic.startswith(b"PK"):
            raise InputError(f"{where} is not a network .npz (not a zip archive; written by "
                             "`stumble reflex fit`)")
        with zipfile.ZipFile(path) as zf:
            return _checked(zf, _entries(zf, where), where)
    except InputError:
        raise
    except Exception as e:  # zip, zlib, .npy header or data errors: the file is bad
        text = " ".join(str(e).split())[:200]
        raise InputError(f"{where} is not a readable network .npz ({type(e).__name__}: "
                         f"{text})") from None


def _checked(zf: zipfile.ZipFile, entries: dict, where: str) -> dict:
    heads = {n: _header(zf, info, where) for n, info in entries.items()}
    for n in SCALARS:
        _expect(n, *heads[n], (), "fiub", where)
    for n in ("muscles", "segments"):
        _expect(n, *heads[n], None, "U", where)
        if len(heads[n][0]) != 1:
            raise InputError(f"{where}: {n} is not a list of names")
    _expect("info", *heads["info"], (), "U", where)
    z = {n: _read(zf, entries[n]) for n in (*SCALARS, *NAMES)}
    rate = _scalar(z, "rate_hz", *RATE_RANGE_HZ, where)
    hidden = _scalar(z, "hidden", *HIDDEN_RANGE, where)
    if not hidden.is_integer():
        raise InputError(f"{where}: hidden = {hidden:g} is not a whole number")
    for n in ("afferent_m_per_s", "efferent_m_per_s"):
        _scalar(z, n, *SPEED_RANGE_M_PER_S, where)
    if float(z["contact"]) not in (0.0, 1.0):
        raise InputError(f"{where}: contact = {z['contact']} is not true or false")
    muscles = tuple(str(s) for s in z["muscles"])
    unknown = [m for m in muscles if m not in NERVE_LENGTH_M]
    if not muscles or unknown or len(set(muscles)) != len(muscles):
        raise InputError(f"{where}: muscles {', '.join(muscles) or '(none)'}: each must be one "
                         f"of {', '.join(NERVE_LENGTH_M)}, once")
    try:
        info = json.loads(str(z["info"]))
    except json.JSONDecodeError:
        info = None
    if not isinstance(info, dict):
        raise InputError(f"{where}: info is not a JSON object")
    touch = False
    if "touch" in entries:
        _expect("touch", *heads["touch"], (), "fiub", where)
        z["touch"] = _read(zf, entries["touch"])
        if float(z["touch"]) not in (0.0, 1.0):
            raise InputError(f"{where}: touch = {z['touch']} is not true or false")
        touch = bool(float(z["touch"]))
    t = Topology(rate, int(hidden), bool(float(z["contact"])), muscles=muscles, touch=touch)
    if tuple(str(s) for s in z["segments"]) != t.segments:
        raise InputError(f"{where}: segments are not {', '.join(t.segments)} (those its "
                         "muscles are bound to)")
    S, H = len(t.segments), t.hidden
    want = {"w": (len(t.inputs()), S * H), "b": (S * H,), "v": (len(t.connections()), H),
            "c": (len(muscles),), "mean": (t.n_signals,), "std": (t.n_signals,)}
    for n, shape in want.items():
        _expect(n, *heads[n], shape, "fiu", where)
    if "walk_rates" in heads:
        shape, dtype = heads["walk_rates"]
        most = round(MAX_WALK_S * rate)
        if shape != (0,) and not (len(shape) == 3 and shape[0] == 2 and 1 <= shape[1] <= most
                                  and shape[2] == t.n_signals):
            raise InputError(f"{where}: walk_rates has shape {shape}, expected (0,) or (2, T, "
                             f"{t.n_signals}) with 1 <= T <= {most}")
        _expect("walk_rates", shape, dtype, None, "fiu", where)
    for n in (*ARRAYS, *OPTIONAL):
        if n in entries:
            a = _read(zf, entries[n]).astype(float)
            if not np.isfinite(a).all():
                raise InputError(f"{where}: {n} holds {np.count_nonzero(~np.isfinite(a))} "
                                 "non-finite values (NaN or infinity)")
            z[n] = a
    if (z["std"] <= 0).any():
        raise InputError(f"{where}: std has {np.count_nonzero(z['std'] <= 0)} values <= 0 "
                         "(each input is divided by its spread)")
    outside = np.count_nonzero(z["w"] * (1.0 - Network._mask(t)))
    if outside:
        raise InputError(f"{where}: w has {outside} weights outside their segment blocks")
    z["info"] = info
    return z
