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
  the foot's normal force / body weight enters segments S1 and S2.

Delays are whole samples of the network's rate (1 kHz by default, so within 0.5 ms).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stumble.body.muscles import MUSCLE_NAMES, MUSCLE_SETS
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
CONTACT_NERVE_M = {"S1": 1.35, "S2": 1.32}  # sole to S1/S2 (our estimate: SOL's + 7 cm)
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

    @property
    def segments(self) -> tuple[str, ...]:
        """The spinal segments bound to these muscles, cranial first."""
        return tuple(seg for seg in ALL_SEGMENTS
                     if any(seg in NERVE_LENGTH_M[mus] for mus in self.muscles))

    @property
    def n_muscles(self) -> int:
        """Muscles per leg."""
        return len(self.muscles)

    @property
    def n_signals(self) -> int:
        """Signals per leg: 3 per muscle, plus the foot contact when enabled."""
        return 3 * self.n_muscles + (1 if self.contact else 0)

    def inputs(self) -> list[tuple[int, int, int]]:
        """(segment index, signal index, afferent delay in samples) of every input."""
        out = []
        for s, seg in enumerate(self.segments):
            for j, mus in enumerate(self.muscles):
                if seg in NERVE_LENGTH_M[mus]:
                    lag = self._samples(NERVE_LENGTH_M[mus][seg] / self.afferent_m_per_s)
                    out += [(s, 3 * j + k, lag) for k in range(len(SIGNALS))]
            if self.contact and seg in CONTACT_NERVE_M:
                lag = self._samples(CONTACT_NERVE_M[seg] / self.afferent_m_per_s)
                out.append((s, 3 * self.n_muscles, lag))
        return out

    def connections(self) -> list[tuple[int, int, int]]:
        """(segment index, muscle index, efferent delay in samples) of every motor path."""
        out = []
        segs = self.segments
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
        return (max(lag for *_x, lag in self.inputs())
                + max(lag for *_x, lag in self.connections()))


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

    def with_delay_scale(self, scale: float) -> Network:
        """A copy whose every nerve delay is ``scale`` times as long (slower nerves)."""
        t = self.topology
        slower = Topology(t.rate_hz, t.hidden, t.contact, t.afferent_m_per_s / scale,
                          t.efferent_m_per_s / scale, t.muscles)
        return Network(slower, self.w, self.b, self.v, self.c, self.mean, self.std,
                       dict(self.info), self.walk_rates)

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
        units = self.units_of()
        conns = self.topology.connections()
        hd = np.stack([np.roll(h[:, units[k]], lag, axis=0)
                       for k, (_s, _j, lag) in enumerate(conns)], axis=1)  # (T, C, H)
        z = np.zeros((len(h), self.topology.n_muscles))
        contrib = np.einsum("tch,ch->tc", hd, self.v)
        for k, (_s, j, _lag) in enumerate(conns):
            z[:, j] += contrib[:, k]
        z += self.c
        u = 1.0 / (1.0 + np.exp(-z))
        return u, {"h": h, "hd": hd, "u": u}

    def gradient(self, xd: np.ndarray, du: np.ndarray, cache: dict) -> np.ndarray:
        """Gradient of a loss with ∂L/∂u = ``du`` (T, 7), in ``pack`` layout."""
        u, h, hd = cache["u"], cache["h"], cache["hd"]
        dz = du * u * (1.0 - u)  # (T, 7)
        conns = self.topology.connections()
        units = self.units_of()
        js = np.array([j for _s, j, _lag in conns])
        dcontrib = dz[:, js]  # (T, C)
        dv = np.einsum("tc,tch->ch", dcontrib, hd)
        dhd = dcontrib[:, :, None] * self.v[None]  # (T, C, H)
        dh = np.zeros_like(h)
        for k, (_s, _j, lag) in enumerate(conns):
            dh[:, units[k]] += np.roll(dhd[:, k], -lag, axis=0)
        dpre = dh * (1.0 - h ** 2)
        dw = (xd.T @ dpre) * self._mask(self.topology)
        m = self._mask(self.topology).astype(bool)
        return np.concatenate([dw[m], dpre.sum(axis=0), dv.ravel(), dz.sum(axis=0)])

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
                 afferent_m_per_s=t.afferent_m_per_s, efferent_m_per_s=t.efferent_m_per_s,
                 muscles=np.array(t.muscles), segments=np.array(t.segments),
                 info=np.array(json.dumps(self.info)),
                 walk_rates=np.zeros(0) if self.walk_rates is None else self.walk_rates)

    @classmethod
    def load(cls, path: str | Path) -> Network:
        """Read a network written by ``save``; InputError if it is not one."""
        path = Path(path)
        if not path.is_file():
            raise InputError(f"network file {path} does not exist")
        try:
            z = np.load(path, allow_pickle=False)
            muscles = tuple(str(s) for s in z["muscles"])
            if muscles not in MUSCLE_SETS.values():
                raise InputError(f"{path} is a network of unknown muscles {muscles}")
            t = Topology(float(z["rate_hz"]), int(z["hidden"]), bool(z["contact"]),
                         float(z["afferent_m_per_s"]), float(z["efferent_m_per_s"]), muscles)
            net = cls(t, z["w"], z["b"], z["v"], z["c"], z["mean"], z["std"],
                      json.loads(str(z["info"])))
            if "walk_rates" in z and z["walk_rates"].size:
                net.walk_rates = z["walk_rates"]
        except (OSError, KeyError, ValueError, json.JSONDecodeError) as e:
            raise InputError(f"{path} is not a stumble reflex network ({e})") from None
        if net.w.shape != (len(t.inputs()), len(t.segments) * t.hidden):
            raise InputError(f"{path} is a network of another layout")
        return net

    @property
    def muscle_set(self) -> str:
        """The body muscle set this network drives (``stumble.body.muscles``)."""
        return next(k for k, v in MUSCLE_SETS.items() if v == self.topology.muscles)
