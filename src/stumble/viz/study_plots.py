"""Plots of a study: strategy map, outcome map, fall rate against a delay or strength scale.

The maps put the trip instant (fraction of swing) across and the walking speed up, one
panel per controller and mechanism. Runs that share a cell (seeds, legs, scales, bodies)
are pooled: a cell then shows a fraction and its count.
"""

from __future__ import annotations

import math
from collections import defaultdict
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
                  "neither": "#fee08b", "error": "#bdbdbd"}
RDYLGN = colormaps["RdYlGn"]
SHORT = {"fell": "fell", "diverged": "div.", "neither": "not yet", "error": "error"}
LEGEND = {"neither": "neither (not recovered in time)"}
FACETS = ("controller", "mechanism")  # one panel per combination present
POOLED = ("leg", "strategy_mode", "obstacle_height_m", "delay_scale", "strength_scale",
          "height_m", "mass_kg", "sex", "contact", "seed", "duration_after_trip_s",
          "timestep_s")


def _edges(values: list[float], pad: float) -> np.ndarray:
    v = np.asarray(sorted(values), dtype=float)
    if len(v) == 1:
        return np.array([v[0] - pad, v[0] + pad])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _facets(rows: list[dict]) -> dict[tuple, list[dict]]:
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        groups[tuple(r.get(f) for f in FACETS)].append(r)
    return dict(sorted(groups.items(), key=lambda kv: tuple(str(x) for x in kv[0])))


def _pooled_note(rows: list[dict]) -> str:
    parts = []
    for name in POOLED:
        vals = {r.get(name) for r in rows} - {None}
        if len(vals) > 1:
            parts.append(f"{name} ({len(vals)})")
    return "pooled over " + ", ".join(parts) if parts else ""


def _cells(rows: list[dict]) -> tuple[list[float], list[float], dict]:
    swings = sorted({float(r["swing_fraction"]) for r in rows})
    speeds = sorted({float(r["speed_m_per_s"]) for r in rows})
    cells: dict[tuple[int, int], list[dict]] = defaultdict(list)
    for r in rows:
        cells[(speeds.index(float(r["speed_m_per_s"])),
               swings.index(float(r["swing_fraction"])))].append(r)
    return swings, speeds, cells


def _pooled(facets: dict[tuple, list[dict]]) -> bool:
    """Whether any cell of any panel holds more than one run."""
    return any(len(c) > 1 for rs in facets.values() for c in _cells(rs)[2].values())


def _figure(n: int, rows_all: list[dict]) -> tuple[Figure, list]:
    swings = {r["swing_fraction"] for r in rows_all}
    speeds = {r["speed_m_per_s"] for r in rows_all}
    w = min(max(4.5, 0.42 * len(swings) + 2.2), 11.0)
    h = min(max(2.6, 0.45 * len(speeds) + 1.9), 7.0)
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


def plot_strategy_map(path, rows: list[dict]) -> Path:
    """Swing fraction × speed → strategy taken (fraction elevating where runs are pooled).

    A strip above each panel shows the human windows of SCA 2009 §3. Grey cells: every
    run of the cell raised an error, or took no strategy that could be classified."""
    facets = _facets(rows)
    fig, axes = _figure(len(facets), rows)
    cmap = LinearSegmentedColormap.from_list("strategy", [LOWERING_COLOR, "#f7f7f7",
                                                          ELEVATING_COLOR])
    mesh = None
    for ax, ((ctrl, mech), rs) in zip(axes, facets.items(), strict=True):
        swings, speeds, cells = _cells(rs)
        xe, ye = _panel_axes(ax, swings, speeds, f"{ctrl}, {mech} trips")
        frac = np.full((len(speeds), len(swings)), np.nan)
        for (i, j), cell in cells.items():
            taken = [r.get("strategy") for r in cell if r.get("strategy") and not r.get("error")]
            dark = False
            if taken:
                k = sum(s == "elevating" for s in taken)
                frac[i, j] = k / len(taken)
                n = "" if len(taken) == 1 else f" ({len(taken)})"
                label = (f"E{n}" if k == len(taken) else f"L{n}"
                         if k == 0 and all(s == "lowering" for s in taken)
                         else f"E {k}/{len(taken)}")
                dark = _dark(cmap, frac[i, j])
            else:  # every run raised, or none could be classified (an emergent strategy)
                label = "error" if all(r.get("error") for r in cell) else "unclassified"
            _annotate(ax, swings[j], speeds[i], label, dark, len(cells))
        ax.pcolormesh(xe, ye, np.zeros_like(frac), cmap=ListedColormap(["#bdbdbd"]))
        mesh = ax.pcolormesh(xe, ye, np.ma.masked_invalid(frac), cmap=cmap, vmin=0, vmax=1,
                             edgecolors="white", linewidth=0.6)
        _windows_strip(ax)
    cb = fig.colorbar(mesh, ax=axes, shrink=0.9, pad=0.02)
    cb.set_label("fraction elevating")
    cb.set_ticks([0, 0.5, 1], labels=["lowering", "mixed", "elevating"])
    note = _pooled_note(rows)
    fig.suptitle("Strategy taken: E elevating, L lowering" + ("; (n): runs in the cell; "
                 "E k/n: k of n elevating" if _pooled(facets) else "")
                 + (f"\n{note}" if note else ""), fontsize=10)
    fig.savefig(path, dpi=110)
    return Path(path)


def plot_outcome_map(path, rows: list[dict]) -> Path:
    """Swing fraction × speed → recovered / fell / diverged / neither / error.

    One run per cell: its outcome as a colour. Pooled runs: the fraction recovered, with
    "recovered/runs" written in the cell."""
    facets = _facets(rows)
    fig, axes = _figure(len(facets), rows)
    pooled = _pooled(facets)
    mesh = None
    for ax, ((ctrl, mech), rs) in zip(axes, facets.items(), strict=True):
        swings, speeds, cells = _cells(rs)
        xe, ye = _panel_axes(ax, swings, speeds, f"{ctrl}, {mech} trips")
        if not pooled:
            code = np.full((len(speeds), len(swings)), np.nan)
            for (i, j), cell in cells.items():
                what = outcome(cell[0])
                code[i, j] = list(OUTCOME_COLORS).index(what)
                if what != "recovered":
                    _annotate(ax, swings[j], speeds[i], SHORT[what], what in ("fell", "diverged"),
                              len(cells))
            cmap = ListedColormap(list(OUTCOME_COLORS.values()))
            ax.pcolormesh(xe, ye, np.ma.masked_invalid(code), cmap=cmap, vmin=-0.5,
                          vmax=len(OUTCOME_COLORS) - 0.5, edgecolors="white", linewidth=0.6)
            continue
        frac = np.full((len(speeds), len(swings)), np.nan)
        for (i, j), cell in cells.items():
            ok = [r for r in cell if outcome(r) != "error"]
            dark = False
            if ok:
                frac[i, j] = sum(outcome(r) == "recovered" for r in ok) / len(ok)
                label = f"{sum(outcome(r) == 'recovered' for r in ok)}/{len(ok)}"
                dark = _dark(RDYLGN, frac[i, j])
            else:
                label = "error"
            _annotate(ax, swings[j], speeds[i], label, dark, len(cells))
        ax.pcolormesh(xe, ye, np.zeros_like(frac), cmap=ListedColormap(["#bdbdbd"]))
        mesh = ax.pcolormesh(xe, ye, np.ma.masked_invalid(frac), cmap=RDYLGN, vmin=0,
                             vmax=1, edgecolors="white", linewidth=0.6)
    if pooled:
        cb = fig.colorbar(mesh, ax=axes, shrink=0.9, pad=0.02)
        cb.set_label("fraction recovered")
    else:
        counts = defaultdict(int)
        for r in rows:
            counts[outcome(r)] += 1
        handles = [Patch(color=c, label=f"{LEGEND.get(k, k)} ({counts[k]})")
                   for k, c in OUTCOME_COLORS.items() if counts[k]]
        fig.legend(handles=handles, loc="outside right center", fontsize=8, frameon=False)
    note = _pooled_note(rows)
    fig.suptitle("Outcome" + (": recovered / runs without error" if pooled else "")
                 + (f"\n{note}" if note else ""), fontsize=10)
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
    return max(0.0, centre - half), min(1.0, centre + half)


def plot_fall_rate(path, rows: list[dict], scales: list[str]) -> Path:
    """Fall rate (falls / runs without error, 95 % Wilson interval) against each scale.

    ``scales``: ``delay_scale`` and/or ``strength_scale``. One line per controller and
    mechanism (and per value of the other scale when both vary)."""
    fig = Figure(figsize=(5.2 * len(scales) + 0.6, 3.8), constrained_layout=True)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(scales), squeeze=False)[0]
    labels = {"delay_scale": "response delay scale (× every latency)",
              "strength_scale": "strength scale (× every torque limit)"}
    for ax, scale in zip(axes, scales, strict=True):
        others = [s for s in scales if s != scale]
        lines: dict[tuple, dict[float, list[dict]]] = defaultdict(lambda: defaultdict(list))
        for r in rows:
            if outcome(r) == "error":
                continue
            g = (r.get("controller"), r.get("mechanism"), *(r.get(o) for o in others))
            lines[g][float(r[scale])].append(r)
        for g, by_x in sorted(lines.items(), key=lambda kv: tuple(str(x) for x in kv[0])):
            xs = sorted(by_x)
            k = [sum(outcome(r) == "fell" for r in by_x[x]) for x in xs]
            n = [len(by_x[x]) for x in xs]
            p = [a / b for a, b in zip(k, n, strict=True)]
            ci = [wilson_interval(a, b) for a, b in zip(k, n, strict=True)]
            err = np.array([[pi - lo for pi, (lo, _) in zip(p, ci, strict=True)],
                            [hi - pi for pi, (_, hi) in zip(p, ci, strict=True)]])
            label = f"{g[0]}, {g[1]}" + "".join(
                f", {o.split('_')[0]} ×{v:g}" for o, v in zip(others, g[2:], strict=True))
            ax.errorbar(xs, p, yerr=err, marker="o", capsize=3, label=label)
        ax.axvline(1.0, color="0.6", ls=":", lw=1)
        ax.set_ylim(-0.03, 1.03)
        ax.set_xlabel(labels.get(scale, scale))
        ax.set_ylabel("fall rate (falls / runs)")
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
    fig.suptitle("Fall rate, 95 % Wilson intervals (runs that raised are left out)",
                 fontsize=10)
    fig.savefig(path, dpi=110)
    return Path(path)


def write_study_plots(out: Path, rows: list[dict]) -> list[str]:
    """strategy_map.png and outcome_map.png; fall_rate.png when a delay or strength scale
    varies. Returns the names written."""
    out = Path(out)
    rows = [r for r in rows if r.get("swing_fraction") is not None]
    if not rows:
        return []
    plot_strategy_map(out / "strategy_map.png", rows)
    plot_outcome_map(out / "outcome_map.png", rows)
    written = ["strategy_map.png", "outcome_map.png"]
    scales = [s for s in ("delay_scale", "strength_scale")
              if len({r.get(s) for r in rows}) > 1]
    if scales:
        plot_fall_rate(out / "fall_rate.png", rows, scales)
        written.append("fall_rate.png")
    return written
