"""Gait events from kinematics: heel strike and toe-off per foot, and swing fractions.

Zeni, Richards & Higginson 2008 (Gait & Posture 27:710), the coordinate-based method:
heel strike when the heel is furthest in front of the pelvis, toe-off when the toe tip
is furthest behind it. Independent of the vertical fit of the feet to the ground, and
validated by Zeni et al. against force plates in treadmill and overground walking; on
the subject01 trial it falls within 2 % of the stride of the force-plate events
(playback_test.py). Extrema closer than ``MIN_STRIDE_FRACTION`` of the mean spacing
or less prominent than ``MIN_PROMINENCE_M`` are ignored. At either end of a motion an
extremum has no far side to measure its prominence against: there it counts when it is
``MIN_PROMINENCE_M`` prominent on its inner side and the signal has turned back by
``EDGE_TURN_M`` before the file ends (``_edge_peaks``; ours).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

MIN_PROMINENCE_M = 0.05  # the heel/toe excursion about the pelvis is 0.3-0.5 m
MIN_EVENT_SPACING_S = 0.35  # two heel strikes of one foot are a stride (> 0.8 s) apart
# an extremum at a file's end counts once the heel or toe has turned back by this much
# (m, about the pelvis) before the end (ours). Measured on the reference walk at 0.8-1.4
# m/s: the toe turns back 1 cm 25-55 ms after toe-off, the heel 20-25 ms after heel
# strike; an event later in a file than that is not found
EDGE_TURN_M = 0.01


@dataclass
class GaitEvents:
    """Heel strikes and toe-offs (s) per side, 'r' and 'l'."""

    heel_strike_s: dict[str, list[float]]
    toe_off_s: dict[str, list[float]]

    def swing_fraction(self, side: str, t: float) -> float | None:
        """0 at toe-off, 1 at the next heel strike; None in stance or without events."""
        to = [x for x in self.toe_off_s[side] if x <= t]
        if not to:
            return None
        hs = [x for x in self.heel_strike_s[side] if x > to[-1]]
        if not hs or t > hs[0]:
            return None
        return float((t - to[-1]) / (hs[0] - to[-1]))

    def strides_s(self, side: str) -> np.ndarray:
        """Durations of the complete strides (heel strike to heel strike) of a side."""
        return np.diff(self.heel_strike_s[side])

    def mean_stride_s(self) -> float:
        """Mean stride time over both sides (NaN if no complete stride)."""
        s = np.concatenate([self.strides_s("r"), self.strides_s("l")])
        return float(s.mean()) if len(s) else float("nan")

    def stride_estimate_s(self) -> tuple[float | None, str]:
        """Stride time (s) from the events that exist, and how it was found.

        The mean complete stride (heel strike to heel strike of one foot) of both sides;
        without one, twice the mean step (a heel strike to the next one of the other
        foot, else a toe-off to the next of the other foot); without a step, None.
        """
        mean = self.mean_stride_s()
        if np.isfinite(mean):
            return mean, "complete strides"
        for events, what in ((self.heel_strike_s, "heel strikes"), (self.toe_off_s, "toe-offs")):
            marks = sorted([(t, "r") for t in events["r"]] + [(t, "l") for t in events["l"]])
            steps = [b[0] - a[0] for a, b in itertools.pairwise(marks) if a[1] != b[1]]
            if steps:
                return 2.0 * float(np.mean(steps)), f"twice the step between {what}"
        return None, "no step"

    def stance_fraction(self) -> float:
        """Mean share of a stride spent in stance, over complete strides of both sides."""
        fr = []
        for side in ("r", "l"):
            hs, to = self.heel_strike_s[side], self.toe_off_s[side]
            for a, b in itertools.pairwise(hs):
                off = [x for x in to if a < x < b]
                if off:
                    fr.append((off[0] - a) / (b - a))
        return float(np.mean(fr)) if fr else float("nan")

    def stance_fraction_from(self, stride_s: float) -> float | None:
        """Mean stance time over ``stride_s``: heel strike to the next toe-off of one foot,
        for files too short for a complete stride; None without such a pair."""
        fr = []
        for side in ("r", "l"):
            for hs in self.heel_strike_s[side]:
                offs = [x for x in self.toe_off_s[side] if x > hs]
                if offs and offs[0] - hs < stride_s:
                    fr.append((offs[0] - hs) / stride_s)
        return float(np.mean(fr)) if fr else None

    def to_json(self) -> dict:
        """The events as JSON-ready lists (s, rounded to 0.1 ms)."""
        return {side: {"toe_off_s": [round(x, 4) for x in self.toe_off_s[side]],
                       "heel_strike_s": [round(x, 4) for x in self.heel_strike_s[side]]}
                for side in ("r", "l")}


def foot_heights(body, qpos: np.ndarray) -> dict[str, np.ndarray]:
    """Height (m) of each foot's lowest sole point per frame."""
    from stumble.gait.playback import _sole_points

    return {s: p[:, :, 2].min(axis=1) for s, p in _sole_points(body, qpos).items()}


def heel_toe_x(body, qpos: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Forward position (m) of each foot's heel and toe tip relative to the pelvis."""
    from stumble.gait.playback import _sole_points

    out = {}
    for side, p in _sole_points(body, qpos).items():
        heel = p[:, :6, 0].mean(axis=1) - qpos[:, 0]  # first row of the grid: the heel
        toe = p[:, -6:, 0].mean(axis=1) - qpos[:, 0]  # last row: the toe tip
        out[side] = (heel, toe)
    return out


def detect(body, qpos: np.ndarray, time_s: np.ndarray) -> GaitEvents:
    """Heel strikes and toe-offs of both feet in a played-back motion (Zeni et al. 2008)."""
    from scipy.signal import find_peaks

    dt = float(np.mean(np.diff(time_s)))
    spacing = max(1, round(MIN_EVENT_SPACING_S / dt))
    hs: dict[str, list[float]] = {}
    to: dict[str, list[float]] = {}
    for side, (heel, toe) in heel_toe_x(body, qpos).items():
        i_hs = _edge_peaks(heel, find_peaks(heel, distance=spacing,
                                            prominence=MIN_PROMINENCE_M)[0], spacing)
        i_to = _edge_peaks(-toe, find_peaks(-toe, distance=spacing,
                                            prominence=MIN_PROMINENCE_M)[0], spacing)
        hs[side] = [float(time_s[i]) for i in i_hs]
        to[side] = [float(time_s[i]) for i in i_to]
    return GaitEvents(hs, to)


def _edge_peaks(x: np.ndarray, peaks: np.ndarray, spacing: int) -> np.ndarray:
    """``peaks`` of ``x`` with the maximum before its end, and the one after its start,
    where they qualify: at least ``spacing`` samples from the nearest peak, at least
    ``MIN_PROMINENCE_M`` above the lowest point between it and that peak (or the far
    end), and with ``x`` back down by ``EDGE_TURN_M`` at the file's end (start)."""
    n = len(x)
    out = [int(i) for i in peaks]
    for forward in (True, False):
        y = x if forward else x[::-1]
        mine = [i if forward else n - 1 - i for i in out]
        last = max(mine) if mine else -spacing
        lo = last + spacing
        if lo >= n - 1:
            continue
        j = lo + int(np.argmax(y[lo:]))
        inner = y[max(last, 0):j + 1].min()
        if j < n - 1 and y[j] - y[-1] >= EDGE_TURN_M and y[j] - inner >= MIN_PROMINENCE_M:
            out.append(j if forward else n - 1 - j)
    return np.array(sorted(out), dtype=int)
