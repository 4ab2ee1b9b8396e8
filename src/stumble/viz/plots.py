"""Static plots of gait results (PNG files, matplotlib Agg, no pyplot state).

Every figure is a standalone :class:`matplotlib.figure.Figure` on an Agg canvas, so nothing
leaks between calls and nothing needs a display.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from stumble.errors import InputError

__all__ = ["plot_joint_angles"]

DPI = 150
FIGSIZE_IN = (6.0, 8.0)

# (joint key stem, y label with the sign meaning)
_PANELS: tuple[tuple[str, str], ...] = (
    ("hip_flexion", "hip flexion (+) [deg]"),
    ("knee_angle", "knee angle (flexion −) [deg]"),
    ("ankle_angle", "ankle dorsiflexion (+) [deg]"),
)
# a fourth panel when the curves include it (the planar walks: ``analysis.foot_angles``)
_FOOT_PANEL = ("foot_angle", "foot to floor, toe up (+) [deg]")
# and one more for the trunk, one curve without sides (``analysis.trunk_lean``)
_TRUNK_PANEL = ("trunk_lean", "trunk lean, forward (+) [deg]")
_SIDES: tuple[tuple[str, str, str, str], ...] = (
    # suffix, legend name, colour, line style
    ("r", "right", "tab:blue", "-"),
    ("l", "left", "tab:red", "--"),
)
# the trunk panel's one curve, dash-dotted so its recorded curve is told from the right's
_NO_SIDE = (("", "trunk", "tab:green", "-."),)
SD_VISIBLE_DEG = 0.5  # a ±SD band narrower than this everywhere is not drawn (nor listed):
# at 0.5 deg it is about as wide as the curve on a panel of some 80 deg


def _key(stem: str, side: str) -> str:
    """A curve's key: ``<stem>_<side>``, or the stem for a panel without sides."""
    return f"{stem}_{side}" if side else stem


def _curve(name: str, values, n: int, what: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float).reshape(-1)
    if arr.shape[0] != n:
        raise InputError(
            f"{what} '{name}' has {arr.shape[0]} samples but cycle_percent has {n}"
        )
    return arr


def _toe_off(events: Mapping | None) -> dict[str, float]:
    """Toe-off percentages per side ('r', 'l') from an events dict, skipping missing/NaN."""
    if not events:
        return {}
    raw = events.get("toe_off_percent") or {}
    out: dict[str, float] = {}
    for side in ("r", "l"):
        value = raw.get(side)
        if value is None:
            continue
        value = float(value)
        if np.isfinite(value):
            out[side] = value
    return out


def plot_joint_angles(
    path,
    cycle_percent: np.ndarray,
    angles_deg: Mapping[str, np.ndarray],
    events: Mapping | None = None,
    title: str | None = None,
    spread_deg: Mapping[str, np.ndarray] | None = None,
    reference_deg: Mapping[str, np.ndarray] | None = None,
    reference_label: str = "recorded",
) -> Path:
    """Plot hip, knee and ankle angles over the gait cycle into a PNG; return its path.

    ``angles_deg`` maps keys such as ``hip_flexion_r`` or ``knee_angle_l`` to curves sampled
    at ``cycle_percent`` (0–100 %); right is drawn solid, left dashed, and missing keys are
    skipped. ``spread_deg`` (same keys) adds a ±SD band around each curve (where it is
    ``SD_VISIBLE_DEG`` wide somewhere: a played-back walk repeats itself). ``events`` may
    hold ``{"toe_off_percent": {"r": 62.0, "l": 12.0}}`` for vertical toe-off lines.
    ``reference_deg`` (same keys) draws a reference stride (e.g. the recorded one) under
    the curves in grey, labelled ``reference_label``.
    Keys ``foot_angle_<side>`` (the planar walks' foot angle to the floor) add a fourth
    panel, and the key ``trunk_lean`` (the trunk's forward lean, no sides) one more. The
    image is about 6×8 in at 150 dpi (900×1200 pixels), 8/3 in taller per added panel.
    """
    path = Path(path)
    x = np.asarray(cycle_percent, dtype=float).reshape(-1)
    n = x.shape[0]
    if n < 2:
        raise InputError(f"cycle_percent needs at least 2 samples, got {n}")
    spread_deg = spread_deg or {}
    toe_off = _toe_off(events)

    keys = (*angles_deg, *(reference_deg or {}))
    foot = any(k.startswith(_FOOT_PANEL[0]) for k in keys)
    trunk = _TRUNK_PANEL[0] in keys
    panels = (*_PANELS, *((_FOOT_PANEL,) if foot else ()), *((_TRUNK_PANEL,) if trunk else ()))
    size = (FIGSIZE_IN[0], FIGSIZE_IN[1] * len(panels) / len(_PANELS))
    fig = Figure(figsize=size, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    try:
        axes = fig.subplots(len(panels), 1, sharex=True)
        legend: dict[str, object] = {}  # one figure legend, first handle per label
        for ax, (stem, ylabel) in zip(axes, panels, strict=True):
            drawn = False
            sides = _NO_SIDE if stem == _TRUNK_PANEL[0] else _SIDES
            for side, side_name, _colour, style in sides:
                ref = (reference_deg or {}).get(_key(stem, side))
                if ref is not None:
                    ax.plot(x, _curve(_key(stem, side), ref, n, "reference curve"),
                            color="0.25", linestyle=style, linewidth=1.0, alpha=0.8,
                            label=f"{reference_label} {side_name}")
            for side, side_name, colour, style in sides:
                key = _key(stem, side)
                if key not in angles_deg or angles_deg[key] is None:
                    continue
                y = _curve(key, angles_deg[key], n, "angle curve")
                ax.plot(x, y, color=colour, linestyle=style, linewidth=1.6, label=side_name)
                sd = (None if spread_deg.get(key) is None
                      else np.abs(_curve(key, spread_deg[key], n, "spread curve")))
                if sd is not None and float(np.nanmax(sd)) >= SD_VISIBLE_DEG:
                    ax.fill_between(x, y - sd, y + sd, color=colour, alpha=0.18, linewidth=0,
                                    label=f"{side_name} ±SD")
                drawn = True
            for side, side_name, colour, _style in _SIDES:
                if side in toe_off:
                    ax.axvline(toe_off[side], color=colour, linestyle=":", linewidth=1.2,
                               label=f"toe-off {side_name}")
            if not drawn:
                ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center",
                        va="center", color="0.5")
            ax.set_ylabel(ylabel)
            ax.axhline(0.0, color="0.6", linewidth=0.6)
            ax.grid(True, alpha=0.35)
            ax.set_xlim(0.0, 100.0)
            for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
                legend.setdefault(label, handle)
        axes[-1].set_xlabel("gait cycle [%]")
        if legend:
            fig.legend(list(legend.values()), list(legend.keys()), loc="outside lower center",
                       ncol=min(len(legend), 3), fontsize="small", frameon=False)
        if title:
            fig.suptitle(title)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=DPI, format="png")
    finally:
        fig.clear()
    return path
