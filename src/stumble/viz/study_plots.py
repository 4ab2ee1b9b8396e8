"""Plots of a study: strategy map, outcome map, fall rate against a delay or strength scale
or the obstacle height.

The maps put the trip instant (fraction of swing) across and the walking speed up, one
panel per controller and mechanism. Runs that share a cell (seeds, legs, scales, bodies)
are pooled: a cell then shows a fraction and its count.

The plots draw from a ``Tally`` (counts per cell), filled one row at a time, so a study
of a million runs is plotted without holding its rows.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LinearSegmentedColormap, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from stumble.study.runner import outcome

# Strategy windows of human trips (fraction of swing): SCA 2009 §3 after Schillings et al.
# 2000, and Murai & Yamane 2011 §IV.A
PUBLISHED_WINDOWS = (
    (0.05, 0.25, "elevating"),
    (0.30, 0.50, "either"),
    (0.55, 0.75, "lowering"),
)
ELEVATING_COLOR = "#e08214"
LOWERING_COLOR = "#2166ac"
OUTCOME_COLORS = {"recovered": "#1a9850", "fell": "#d73027", "diverged": "#762a83",
                  "neither": "#fee08b", "not set": "#c6dbef", "timeout": "#636363",
                  "error": "#bdbdbd"}
RDYLGN = colormaps["RdYlGn"]
SHORT = {"fell": "fell", "diverged": "div.", "neither": "not yet", "not set": "×",
         "timeout": "timeout", "error": "error"}
LEGEND = {"neither": "neither (not recovered in time)",
          "not set": "not set (no room for the trip at that instant)"}
FACETS = ("controller", "mechanism")  # one panel per combination present
POOLED = ("leg", "strategy_mode", "obstacle_height_m", "delay_scale", "delays",
          "strength_scale", "height_m", "mass_kg", "sex", "contact", "seed",
          "duration_after_trip_s", "timestep_s")
# the axes a fall rate is drawn against when they vary (force trips have no obstacle
# height: None, left out)
SCALES = ("delay_scale", "strength_scale", "obstacle_height_m")
PLOT_COLUMNS = ("swing_fraction", "speed_m_per_s", *FACETS, *POOLED, "strategy", "error",
                "timed_out", "diverged", "recovered", "fell", "not_set")  # what they read


@dataclass
class Cell:
    """The runs of one map cell, counted."""

    runs: int = 0
    raised: int = 0  # rows with an error text (diverged ones too)
    elevating: int = 0  # strategies taken by runs without an error
    lowering: int = 0
    other: int = 0
    outcomes: Counter = field(default_factory=Counter)
    first: str = ""  # the outcome of the cell's first run

    def add(self, r: dict) -> None:
        what = outcome(r)
        if not self.runs:
            self.first = what
        self.runs += 1
        self.outcomes[what] += 1
        if r.get("error"):
            self.raised += 1
        elif r.get("strategy"):
            s = r["strategy"]
            if s == "elevating":
                self.elevating += 1
            elif s == "lowering":
                self.lowering += 1
            else:
                self.other += 1


@dataclass
class Tally:
    """What the study plots need, counted one row at a time."""

    panels: dict = field(default_factory=lambda: defaultdict(dict))  # facet → (v, s) → Cell
    swings: set = field(default_factory=set)
    speeds: set = field(default_factory=set)
    # (facet, column) → its values within that panel: a column pooled where one panel's
    # cells hold several (a default that differs by controller is not pooled)
    pooled_values: dict = field(default_factory=lambda: defaultdict(set))
    outcomes: Counter = field(default_factory=Counter)
    # (scale, controller, mechanism, delays, other scales' values) → value → [falls, runs]
    fall: dict = field(default_factory=lambda: defaultdict(lambda: defaultdict(lambda: [0, 0])))

    def add(self, r: dict) -> None:
        if r.get("swing_fraction") is None or r.get("speed_m_per_s") is None:
            return
        swing, speed = float(r["swing_fraction"]), float(r["speed_m_per_s"])
        self.swings.add(swing)
        self.speeds.add(speed)
        facet = tuple(r.get(f) for f in FACETS)
        self.panels[facet].setdefault((speed, swing), Cell()).add(r)
        for name in POOLED:
            seen = self.pooled_values[(facet, name)]
            if r.get(name) is not None and len(seen) <= 1000:
                seen.add(r.get(name))
        what = outcome(r)
        self.outcomes[what] += 1
        if what in ("error", "timeout", "not set"):  # no trip to count a fall of
            return
        for scale in SCALES:
            if r.get(scale) is None:
                continue
            others = tuple(r.get(o) for o in SCALES if o != scale)
            delays = r.get("delays") or "all"  # what the delay scale multiplies
            entry = self.fall[(scale, *facet, delays, *others)][float(r[scale])]
            entry[0] += what == "fell"
            entry[1] += 1

    @classmethod
    def of(cls, rows: Iterable[dict]) -> Tally:
        """The tally of some rows (any iterable: one pass)."""
        t = cls()
        for r in rows:
            t.add(r)
        return t

    def empty(self) -> bool:
        return not self.panels

    def varying_scales(self) -> list[str]:
        """The delay and strength scales and the obstacle height that take more than one
        value among the trips a fall rate counts (set and run: a force trip's height,
        None, and a height whose every trip was not set are not values)."""
        seen = defaultdict(set)
        for (scale, *_rest), by_x in self.fall.items():
            seen[scale].update(by_x)
        return [s for s in SCALES if len(seen[s]) > 1]

    def facets(self) -> list[tuple]:
        return sorted(self.panels, key=lambda k: tuple(str(x) for x in k))

    def pooled(self) -> bool:
        """Whether any cell of any panel holds more than one run."""
        return any(c.runs > 1 for cells in self.panels.values() for c in cells.values())


def _edges(values: list[float], pad: float) -> np.ndarray:
    v = np.asarray(sorted(values), dtype=float)
    if len(v) == 1:
        return np.array([v[0] - pad, v[0] + pad])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _pooled_note(t: Tally) -> str:
    """The columns some panel pools over, each with its most values in one panel."""
    most = defaultdict(int)
    for (_facet, name), values in t.pooled_values.items():
        most[name] = max(most[name], len(values))
    parts = [f"{name} ({most[name]})" for name in POOLED if most[name] > 1]
    return "pooled over " + ", ".join(parts) if parts else ""


def _grid_of(cells: dict) -> tuple[list[float], list[float]]:
    return sorted({s for _, s in cells}), sorted({v for v, _ in cells})


def _figure(n: int, t: Tally) -> tuple[Figure, list]:
    w = min(max(4.5, 0.42 * len(t.swings) + 2.2), 11.0)
    h = min(max(2.6, 0.45 * len(t.speeds) + 1.9), 7.0)
    fig = Figure(figsize=(w * n + 1.4, h + 0.5), constrained_layout=True)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    return fig, list(axes)


def _panel_axes(ax, swings, speeds, title: str) -> tuple[np.ndarray, np.ndarray]:
    xe, ye = _edges(swings, 0.025), _edges(speeds, 0.05)
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel("trip instant [fraction of swing]")
    ax.set_ylabel("walking speed [m/s]")
    ax.set_yticks(speeds)
    ax.set_title(title, fontsize=10)
    return xe, ye


def _windows_strip(ax) -> None:
    """The published strategy windows as a strip above the panel (SCA 2009 §3)."""
    strip = ax.inset_axes([0.0, 1.0, 1.0, 0.07], sharex=ax)
    for lo, hi, name in PUBLISHED_WINDOWS:
        color = {"elevating": ELEVATING_COLOR, "lowering": LOWERING_COLOR}.get(name, "0.85")
        strip.axvspan(lo, hi, color=color, alpha=0.55, lw=0)
        strip.text(0.5 * (lo + hi), 0.5, name, ha="center", va="center", fontsize=7,
                   clip_on=True)
    strip.set_yticks([])
    strip.set_ylabel("humans\n(SCA 2009 §3)", rotation=0, ha="right", va="center", fontsize=7)
    strip.tick_params(labelbottom=False, bottom=False)
    for s in strip.spines.values():
        s.set_visible(False)


def _dark(cmap, value: float) -> bool:
    """Whether a colour map's colour at ``value`` (0-1) needs white text."""
    r, g, b, _ = cmap(value)
    return 0.299 * r + 0.587 * g + 0.114 * b < 0.5


def _annotate(ax, x: float, y: float, text: str, dark: bool, n_cells: int) -> None:
    size = 8 if n_cells <= 60 else 6 if n_cells <= 150 else 0
    if size:
        ax.text(x, y, text, ha="center", va="center", fontsize=size,
                color="white" if dark else "black")


def _tally(rows) -> Tally:
    return rows if isinstance(rows, Tally) else Tally.of(rows)


def plot_strategy_map(path, rows: Tally | Iterable[dict], caption: str = "") -> Path:
    """Swing fraction × speed → strategy taken (fraction elevating where runs are pooled).

    A strip above each panel shows the human windows of SCA 2009 §3. Grey cells: every
    run of the cell raised an error, or took no strategy that could be classified."""
    t = _tally(rows)
    facets = t.facets()
    fig, axes = _figure(len(facets), t)
    cmap = LinearSegmentedColormap.from_list("strategy", [LOWERING_COLOR, "#f7f7f7",
                                                          ELEVATING_COLOR])
    mesh = None
    for ax, facet in zip(axes, facets, strict=True):
        ctrl, mech = facet
        cells = t.panels[facet]
        swings, speeds = _grid_of(cells)
        xe, ye = _panel_axes(ax, swings, speeds, f"{ctrl}, {mech} trips")
        frac = np.full((len(speeds), len(swings)), np.nan)
        for (v, sw), c in cells.items():
            i, j = speeds.index(v), swings.index(sw)
            taken = c.elevating + c.lowering + c.other
            dark = False
            if taken:
                k = c.elevating
                frac[i, j] = k / taken
                n = "" if taken == 1 else f" ({taken})"
                label = (f"E{n}" if k == taken else f"L{n}" if c.lowering == taken
                         else f"E {k}/{taken}")
                dark = _dark(cmap, frac[i, j])
            else:  # every run raised or was not set, or none could be classified
                label = ("error" if c.raised == c.runs else
                         "×" if c.raised + c.outcomes["not set"] == c.runs else "–")
            _annotate(ax, sw, v, label, dark, len(cells))
        ax.pcolormesh(xe, ye, np.zeros_like(frac), cmap=ListedColormap(["#bdbdbd"]))
        mesh = ax.pcolormesh(xe, ye, np.ma.masked_invalid(frac), cmap=cmap, vmin=0, vmax=1,
                             edgecolors="white", linewidth=0.6)
        _windows_strip(ax)
    cb = fig.colorbar(mesh, ax=axes, shrink=0.9, pad=0.02)
    cb.set_label("fraction elevating")
    cb.set_ticks([0, 0.5, 1], labels=["lowering", "mixed", "elevating"])
    note = _pooled_note(t)
    fig.suptitle("Strategy taken: E elevating, L lowering, – none read from the motion, "
                 "× not set (grey: no strategy)"
                 + ("; (n): runs in the cell; "
                 "E k/n: k of n elevating" if t.pooled() else "")
                 + "".join(f"\n{x}" for x in (note, caption) if x), fontsize=10)
    fig.savefig(path, dpi=110)
    return Path(path)


def plot_outcome_map(path, rows: Tally | Iterable[dict], caption: str = "") -> Path:
    """Swing fraction × speed → recovered / fell / diverged / neither / timeout / error.

    One run per cell: its outcome as a colour. Pooled runs: the fraction recovered, with
    "recovered/runs" written in the cell (runs that raised, timed out or were not set
    left out)."""
    t = _tally(rows)
    facets = t.facets()
    fig, axes = _figure(len(facets), t)
    pooled = t.pooled()
    mesh = None
    for ax, facet in zip(axes, facets, strict=True):
        ctrl, mech = facet
        cells = t.panels[facet]
        swings, speeds = _grid_of(cells)
        xe, ye = _panel_axes(ax, swings, speeds, f"{ctrl}, {mech} trips")
        if not pooled:
            code = np.full((len(speeds), len(swings)), np.nan)
            for (v, sw), c in cells.items():
                i, j = speeds.index(v), swings.index(sw)
                code[i, j] = list(OUTCOME_COLORS).index(c.first)
                if c.first != "recovered":
                    _annotate(ax, sw, v, SHORT[c.first],
                              c.first in ("fell", "diverged", "timeout"), len(cells))
            cmap = ListedColormap(list(OUTCOME_COLORS.values()))
            ax.pcolormesh(xe, ye, np.ma.masked_invalid(code), cmap=cmap, vmin=-0.5,
                          vmax=len(OUTCOME_COLORS) - 0.5, edgecolors="white", linewidth=0.6)
            continue
        frac = np.full((len(speeds), len(swings)), np.nan)
        for (v, sw), c in cells.items():
            i, j = speeds.index(v), swings.index(sw)
            ok = (c.runs - c.outcomes["error"] - c.outcomes["timeout"]
                  - c.outcomes["not set"])
            dark = False
            if ok:
                frac[i, j] = c.outcomes["recovered"] / ok
                label = f"{c.outcomes['recovered']}/{ok}"
                dark = _dark(RDYLGN, frac[i, j])
            else:
                label = ("error" if c.outcomes["error"] else
                         "×" if c.outcomes["not set"] else "timeout")
            _annotate(ax, sw, v, label, dark, len(cells))
        ax.pcolormesh(xe, ye, np.zeros_like(frac), cmap=ListedColormap(["#bdbdbd"]))
        mesh = ax.pcolormesh(xe, ye, np.ma.masked_invalid(frac), cmap=RDYLGN, vmin=0,
                             vmax=1, edgecolors="white", linewidth=0.6)
    if pooled:
        cb = fig.colorbar(mesh, ax=axes, shrink=0.9, pad=0.02)
        cb.set_label("fraction recovered")
    else:
        handles = [Patch(color=c, label=f"{LEGEND.get(k, k)} ({t.outcomes[k]})")
                   for k, c in OUTCOME_COLORS.items() if t.outcomes[k]]
        fig.legend(handles=handles, loc="outside right center", fontsize=8, frameon=False)
    note = _pooled_note(t)
    fig.suptitle("Outcome" + (": recovered / trips set and run without error" if pooled
                               else "")
                 + "".join(f"\n{x}" for x in (note, caption) if x), fontsize=10)
    fig.savefig(path, dpi=110)
    return Path(path)


def wilson_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a binomial proportion k/n (Wilson 1927)."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    # it holds p (lo <= p <= hi); the min and max take out rounding at k = 0 and k = n
    return min(p, max(0.0, centre - half)), max(p, min(1.0, centre + half))


def plot_fall_rate(path, rows: Tally | Iterable[dict], scales: list[str],
                   caption: str = "") -> Path:
    """Fall rate (falls / trips set and run without error, 95 % Wilson interval) against
    each scale.

    ``scales``: any of ``delay_scale``, ``strength_scale`` and ``obstacle_height_m`` (m).
    One line per controller and mechanism (and per value of the other axes that vary)."""
    t = _tally(rows)
    fig = Figure(figsize=(5.2 * len(scales) + 0.6, 3.8), constrained_layout=True)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(scales), squeeze=False)[0]
    labels = {"delay_scale": "delay scale (× every latency)",
              "strength_scale": "strength scale (× every torque limit)",
              "obstacle_height_m": "obstacle height (m)"}
    kinds = {k[3] for k in t.fall}  # what the delay scale multiplies (``delays``)
    if kinds == {"response"}:
        labels["delay_scale"] = "delay scale (× the response's latencies)"
    elif len(kinds) > 1:
        labels["delay_scale"] = "delay scale (× every latency, or the response's)"
    for ax, scale in zip(axes, scales, strict=True):
        others = [o for o in SCALES if o != scale]
        shown = [o for o in others if o in scales]
        lines: dict[tuple, dict[float, list[int]]] = defaultdict(lambda: defaultdict(
            lambda: [0, 0]))
        for (sc, ctrl, mech, delays, *other_vals), by_x in t.fall.items():
            if sc != scale:
                continue
            g = (ctrl, mech, delays, *(v for o, v in zip(others, other_vals, strict=True)
                                       if o in shown))
            for x, (falls, runs) in by_x.items():
                lines[g][x][0] += falls
                lines[g][x][1] += runs
        for g, by_x in sorted(lines.items(), key=lambda kv: tuple(str(x) for x in kv[0])):
            xs = sorted(by_x)
            k = [by_x[x][0] for x in xs]
            n = [by_x[x][1] for x in xs]
            p = [a / b for a, b in zip(k, n, strict=True)]
            ci = [wilson_interval(a, b) for a, b in zip(k, n, strict=True)]
            err = np.array([[pi - lo for pi, (lo, _) in zip(p, ci, strict=True)],
                            [hi - pi for pi, (_, hi) in zip(p, ci, strict=True)]])
            label = f"{g[0]}, {g[1]}" + (", the response's delays only"
                                         if g[2] == "response" else "") + "".join(
                _other_label(o, v) for o, v in zip(shown, g[3:], strict=True))
            ax.errorbar(xs, p, yerr=err, marker="o", capsize=3, label=label)
        if scale != "obstacle_height_m":  # the scales' 1: as the person is
            ax.axvline(1.0, color="0.6", ls=":", lw=1)
        else:  # ticks at the heights run
            ax.set_xticks(sorted({x for by_x in lines.values() for x in by_x}))
        ax.set_ylim(-0.03, 1.03)
        ax.set_xlabel(labels.get(scale, scale))
        ax.set_ylabel("fall rate (falls / runs)")
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
    fig.suptitle("Fall rate, 95 % Wilson intervals\n(runs that raised, timed out or were "
                 "not set are left out)" + (f"\n{caption}" if caption else ""), fontsize=10)
    fig.savefig(path, dpi=110)
    return Path(path)


def _other_label(axis: str, value) -> str:
    """A line's value of another axis, for its legend."""
    if axis == "obstacle_height_m":
        return "" if value is None else f", box {value:g} m"
    return f", {axis.split('_')[0]} ×{value:g}"


def write_study_plots(out: Path, rows: Tally | Iterable[dict], caption: str = "") -> list[str]:
    """strategy_map.png and outcome_map.png; fall_rate.png when a delay or strength scale
    or the obstacle height varies. ``rows``: a Tally, or rows (any iterable, read once);
    ``caption``: a line under each title (the study's parameter file). Returns the names
    written."""
    out = Path(out)
    t = _tally(rows)
    if t.empty():
        return []
    plot_strategy_map(out / "strategy_map.png", t, caption)
    plot_outcome_map(out / "outcome_map.png", t, caption)
    written = ["strategy_map.png", "outcome_map.png"]
    scales = t.varying_scales()
    if scales:
        plot_fall_rate(out / "fall_rate.png", t, scales, caption)
        written.append("fall_rate.png")
    return written
