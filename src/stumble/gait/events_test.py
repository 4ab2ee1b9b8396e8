"""Gait events (stumble.gait.events): extrema at a motion's ends."""

import numpy as np
from scipy.signal import find_peaks

from stumble.gait.events import EDGE_TURN_M, MIN_PROMINENCE_M, _edge_peaks


def _peaks(x: np.ndarray, spacing: int = 35) -> list[int]:
    inner = find_peaks(x, distance=spacing, prominence=MIN_PROMINENCE_M)[0]
    return _edge_peaks(x, inner, spacing).tolist()


def test_a_maximum_just_before_the_end_counts_once_the_signal_has_turned():
    t = np.arange(0.0, 2.0, 0.01)  # 100 Hz, a 1 s stride, excursion +-0.2 m
    ends = 1.75 + 0.08  # the last maximum (1.75 s) 80 ms before the end
    x = 0.2 * np.sin(2 * np.pi * (t - 0.5))
    cut = t <= ends
    # find_peaks alone misses it: nothing beyond it to be prominent against
    assert find_peaks(x[cut], distance=35, prominence=MIN_PROMINENCE_M)[0].tolist() == [75]
    assert _peaks(x[cut]) == [75, 175]
    # at the maximum itself, or before the signal has turned by EDGE_TURN_M: not yet
    assert _peaks(x[t <= 1.75]) == [75]
    drop = 0.2 - 0.2 * np.cos(2 * np.pi * 0.02)  # 20 ms after the maximum
    assert drop < EDGE_TURN_M
    assert _peaks(x[t <= 1.77]) == [75]


def test_a_maximum_just_after_the_start_counts_too():
    t = np.arange(0.0, 2.0, 0.01)
    x = 0.2 * np.sin(2 * np.pi * (t + 0.15))  # maxima at 0.1 s and 1.1 s
    assert find_peaks(x, distance=35, prominence=MIN_PROMINENCE_M)[0].tolist() == [110]
    assert _peaks(x) == [10, 110]


def test_a_standing_end_adds_no_event():
    t = np.arange(0.0, 2.0, 0.01)
    x = np.where(t < 1.25, 0.2 * np.sin(2 * np.pi * (t - 0.5)), 0.2)  # stops at a maximum
    assert _peaks(x) == [75]
    x = np.where(t < 1.4, 0.2 * np.sin(2 * np.pi * (t - 0.5)), 0.2 * np.sin(2 * np.pi * 0.9))
    assert _peaks(x) == [75]  # stops on the way down: no maximum after the last
