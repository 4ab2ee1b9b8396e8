"""Delayed sensors: a ring buffer of per-tick signals, read at per-channel lags.

A reflex reads its sensor as it was one neural delay ago. Every controller of this
package that runs on delayed signals stores each tick's sensed channels here and reads a
whole block of ticks at once: tick k of the block sees channel c as sensed at tick
k − lag[c]. With every lag at least as long as the block, what a block reads has been
sensed before the block starts (SCONE's delayed sensors, in spirit).
"""

from __future__ import annotations

import numpy as np


class DelayTaps:
    """A ring buffer of per-tick channels read through taps: (channel, lag) pairs, so one
    signal can reach several reflexes, each after its own path's delay."""

    def __init__(self, channels: int, taps: list[tuple[int, int]], block: int | None = None):
        self.cols = np.array([c for c, _l in taps], dtype=int)
        self.lags = np.array([lag for _c, lag in taps], dtype=int)
        if self.lags.ndim != 1 or np.any(self.lags < 1):
            raise ValueError("every lag must be at least one tick")
        shortest = int(self.lags.min())
        if block is not None and block > shortest:
            raise ValueError(f"a block of {block} ticks is longer than the shortest lag "
                             f"({shortest})")
        # ticks read at once: their reads are all sensed already (default: as many as can be)
        self.block = shortest if block is None else int(block)
        self.size = int(self.lags.max()) + self.block + 1
        self.buf = np.zeros((self.size, channels))
        self.k = 0
        # per (ring slot, ticks): the rows ``push`` writes, the flat indices ``read``
        # gathers (the same few recur; pure index arithmetic, the values are unchanged)
        self._push_at: dict[tuple[int, int], np.ndarray] = {}
        self._read_at: dict[tuple[int, int], np.ndarray] = {}

    def fill(self, values: np.ndarray) -> None:
        """A constant history: every past tick sensed ``values``."""
        self.buf[:] = np.asarray(values, dtype=float)

    def push(self, rows: np.ndarray) -> None:
        """Store the channels (n, channels) of the next n ticks."""
        n = len(rows)
        key = (self.k % self.size, n)
        slots = self._push_at.get(key)
        if slots is None:
            slots = self._push_at[key] = (self.k + np.arange(n)) % self.size
        self.buf[slots] = rows
        self.k += n

    def read(self, n: int) -> np.ndarray:
        """(n, taps): each tap's channel at its lag before each of the next n ticks."""
        return self.buf.take(self.read_index(n))

    def read_index(self, n: int) -> np.ndarray:
        """The flat indices into ``buf`` (n, taps) that ``read(n)`` gathers."""
        if n > self.block:
            raise ValueError(f"{n} ticks ahead is more than the shortest lag ({self.block})")
        key = (self.k % self.size, n)
        idx = self._read_at.get(key)
        if idx is None:
            ticks = self.k + np.arange(n)[:, None] - self.lags[None, :]
            idx = self._read_at[key] = (ticks % self.size) * self.buf.shape[1] + self.cols
        return idx


class DelayLine(DelayTaps):
    """Per-tick values of ``len(lags)`` signals, each read at its own lag (ticks): the
    taps of ``DelayTaps`` with one tap per channel, in a block of ``block`` ticks."""

    def __init__(self, lags: np.ndarray, block: int):
        lags = np.asarray(lags, dtype=int)
        super().__init__(len(lags), list(enumerate(lags.tolist())), block=block)
