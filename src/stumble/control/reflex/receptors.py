"""Proprioceptors of seed 003 §III item 4: muscle spindles (Ia, II) and Golgi tendon organs (Ib).

Firing rates in impulses per second from a muscle's fibre stretch, stretch velocity and
tension. The forms are those listed in shared/reference/README.md; their status:

- Spindle Ia, after Prochazka & Gorassini 1998 (J Physiol 507:277) and Prochazka 1999:
  ``Ia = 4.3·sign(v)·|v|^0.6 + 2·d + k·EMG + 80`` with v the stretch velocity in mm/s
  and d the stretch in mm. The power law in velocity with exponent 0.5-0.6 is verified
  in that paper; the constants of this commonly used form are NOT verified against it.
  The fusimotor term k·EMG is left out by default (``K_EMG = 0``): the network gets the
  muscle's own activity through its tension (Ib) instead.
- Spindle II: ``II = 80 + 13.5·d`` (not verified).
- Golgi tendon organ Ib, after Lin & Crago 2002 and Elias et al. 2014:
  ``r = 60·ln(F / 4 N + 1)`` followed by the filter
  ``(1.7 s² + 2.58 s + 0.4) / (s² + 2.2 s + 0.4)`` (a published, usable form; Mileusnic &
  Loeb 2006, the seed's reference, was not read).

Stretch d is the fibre length minus its optimal length (our choice of reference), so
d = 0 at l_CE = l_opt. Rates are clipped at zero: a neuron does not fire negatively.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy import signal

try:  # lfilter's own kernel, without its argument checks: the same numbers, 6 µs less per
    # network block (controller_test.py checks it against lfilter)
    from scipy.signal._sigtools import _linear_filter
except ImportError:  # pragma: no cover - a SciPy without it: lfilter
    _linear_filter = None

IA_VELOCITY_GAIN = 4.3  # imp/s per (mm/s)^0.6 (Prochazka form, not verified)
IA_VELOCITY_EXPONENT = 0.6  # Prochazka & Gorassini 1998: 0.5-0.6 (verified)
IA_STRETCH_GAIN = 2.0  # imp/s per mm (not verified)
IA_BASE = 80.0  # imp/s (not verified)
K_EMG = 0.0  # fusimotor term left out (our choice)
II_BASE = 80.0  # imp/s (not verified)
II_STRETCH_GAIN = 13.5  # imp/s per mm (not verified)
IB_GAIN = 60.0  # imp/s (Lin & Crago 2002; Elias 2014)
IB_FORCE_N = 4.0  # N (Lin & Crago 2002; Elias 2014)
IB_FILTER_NUM = (1.7, 2.58, 0.4)  # Lin & Crago 2002; Elias 2014
IB_FILTER_DEN = (1.0, 2.2, 0.4)
SIGNALS = ("Ia", "II", "Ib")


def spindle_ia(stretch_m: np.ndarray, velocity_m_s: np.ndarray,
               emg: np.ndarray | float = 0.0, k_emg: float = K_EMG) -> np.ndarray:
    """Ia rate (imp/s) from fibre stretch (m) and stretch velocity (m/s)."""
    d = 1000.0 * np.asarray(stretch_m)
    v = 1000.0 * np.asarray(velocity_m_s)
    r = (IA_VELOCITY_GAIN * np.sign(v) * np.abs(v) ** IA_VELOCITY_EXPONENT
         + IA_STRETCH_GAIN * d + k_emg * np.asarray(emg) + IA_BASE)
    return np.maximum(r, 0.0)


def spindle_ii(stretch_m: np.ndarray) -> np.ndarray:
    """Group II rate (imp/s) from fibre stretch (m)."""
    return np.maximum(II_BASE + II_STRETCH_GAIN * 1000.0 * np.asarray(stretch_m), 0.0)


def gto_static(force_n: np.ndarray) -> np.ndarray:
    """Ib rate (imp/s) before the dynamic filter, from tension (N, pulling positive)."""
    return IB_GAIN * np.log(np.maximum(np.asarray(force_n), 0.0) / IB_FORCE_N + 1.0)


@functools.lru_cache(maxsize=8)
def _discrete(dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The Ib filter's numerator and denominator at ``dt_s`` (bilinear), read-only."""
    b, a, _ = signal.cont2discrete((IB_FILTER_NUM, IB_FILTER_DEN), dt_s, method="bilinear")
    b, a = np.asarray(b).ravel(), np.asarray(a).ravel()
    b.flags.writeable = a.flags.writeable = False
    return b, a


class GTOFilter:
    """The Ib transfer function, discretised (bilinear) at ``dt``; one state per channel."""

    def __init__(self, dt_s: float, channels: int):
        self.b, self.a = _discrete(float(dt_s))
        self.z = np.zeros((2, channels))  # direct form II transposed

    def reset(self, x: np.ndarray) -> None:
        """Start at steady state for a constant input ``x`` (DC gain 1)."""
        x = np.asarray(x, dtype=float)
        b, a = self.b, self.a
        # steady state of the transposed form: y = x (DC gain 1)
        self.z[1] = b[2] * x - a[2] * x
        self.z[0] = b[1] * x - a[1] * x + self.z[1]

    def block(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Filter samples (n, channels) from the state ``z``: (outputs, the state after
        them); ``z`` itself is left for the caller to update."""
        if _linear_filter is not None:
            return _linear_filter(self.b, self.a, x, 0, self.z)
        return signal.lfilter(self.b, self.a, x, axis=0, zi=self.z)

    def step(self, x: np.ndarray) -> np.ndarray:
        """Filter one sample of every channel."""
        b, a, z = self.b, self.a, self.z
        y = b[0] * x + z[0]
        z[0] = b[1] * x - a[1] * y + z[1]
        z[1] = b[2] * x - a[2] * y
        return y

    def steady_state(self, x: np.ndarray) -> np.ndarray:
        """Filter state (2, channels) at the first sample of the periodic steady-state
        response to a periodic series ``x`` (T, channels), solved exactly.

        The filter is slow (time constants 5 s and 0.5 s), so filtering a few periods
        from rest is not enough: with zero input the state after one period is Φ·z, so
        the periodic state z* = Φ·z* + z_T(0) is z* = (I − Φ)⁻¹ z_T(0), z_T(0) being the
        state after one period from rest.
        """
        x = np.asarray(x, dtype=float)
        _y, z_rest = signal.lfilter(self.b, self.a, x, axis=0, zi=np.zeros((2, x.shape[1])))
        zero = np.zeros((len(x), 1))
        phi = np.column_stack([signal.lfilter(self.b, self.a, zero, axis=0, zi=e[:, None])[1][:, 0]
                               for e in np.eye(2)])  # (2, 2): state after T, no input
        return np.linalg.solve(np.eye(2) - phi, z_rest)

    def periodic(self, x: np.ndarray) -> np.ndarray:
        """Filter a periodic series (T, channels): its exact steady-state response."""
        x = np.asarray(x, dtype=float)
        y, _z = signal.lfilter(self.b, self.a, x, axis=0, zi=self.steady_state(x))
        return y

    def state_at(self, x: np.ndarray, index: int, z0: np.ndarray | None = None) -> np.ndarray:
        """Steady-state filter state (2, channels) just before sample ``index`` of a
        periodic series ``x`` (T, channels); ``z0``: its ``steady_state``, if known."""
        x = np.asarray(x, dtype=float)
        z = self.steady_state(x) if z0 is None else z0
        index %= len(x)
        if index == 0:
            return z
        return signal.lfilter(self.b, self.a, x[:index], axis=0, zi=z)[1]


def rates(stretch_m: np.ndarray, velocity_m_s: np.ndarray, force_n: np.ndarray) -> np.ndarray:
    """(…, 3) Ia, II and static Ib rates (imp/s); Ib still to be filtered."""
    return np.stack([spindle_ia(stretch_m, velocity_m_s), spindle_ii(stretch_m),
                     gto_static(force_n)], axis=-1)
