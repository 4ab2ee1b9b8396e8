"""Plots of the reflex controller: the identification fit (seed 003 Fig. 2) and the
muscle tensions of a trip against walking (seed 003 Fig. 5)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FuncFormatter, MaxNLocator

from stumble.body.muscles import MUSCLE_NAMES


def plot_activity_fit(path: Path, percent: np.ndarray, target: np.ndarray,
                      network: np.ndarray, events: dict[str, float], title: str,
                      muscles: tuple[str, ...] = MUSCLE_NAMES) -> None:
    """Identified (dotted) and network (solid) activity per muscle over the stride.

    ``target``/``network``: (T, n_muscles) activity in 0-1; ``events``: label -> percent.
    """
    fig, axes = plt.subplots(len(muscles), 1, figsize=(7.5, 1.5 * len(muscles)), sharex=True)
    for j, (ax, name) in enumerate(zip(axes, muscles, strict=True)):
        ax.plot(percent, target[:, j], ":", color="tab:blue", lw=2.0,
                label="identified (inverse dynamics + static optimisation)")
        ax.plot(percent, network[:, j], "-", color="tab:red", lw=1.3, label="network")
        ax.set_ylabel(name, rotation=0, ha="right", va="center")
        top = max(0.1, float(max(target[:, j].max(), network[:, j].max())) * 1.15)
        ax.set_ylim(0.0, top)
        for label, x in events.items():
            ax.axvline(x, color="0.3" if "R" in label else "0.6",
                       ls="-" if "HS" in label else "--", lw=0.8)
        ax.grid(alpha=0.3)
    for label, x in events.items():
        axes[0].text(x, axes[0].get_ylim()[1], label, ha="center", va="bottom", fontsize=8)
    axes[-1].set_xlabel("% of stride from right heel strike")
    axes[0].legend(loc="upper left", bbox_to_anchor=(0.0, 1.9), ncol=2, fontsize=8,
                   frameon=False)
    fig.suptitle(title, fontsize=10, y=0.995)
    fig.tight_layout(rect=(0, 0, 1, 0.965))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_muscle_tensions(path: Path, t_trip: np.ndarray, f_trip: np.ndarray,
                         t_walk: np.ndarray, f_walk: np.ndarray, sides: tuple[str, str],
                         title: str, muscles: tuple[str, ...] = MUSCLE_NAMES) -> None:
    """Tension (N) per muscle of both legs: this trip (solid) and walking (dotted).

    ``f_*``: (T, 2, n_muscles) tensions of the (tripped, support) legs; time 0 the trip.
    """
    fig, axes = plt.subplots(len(muscles), 2, figsize=(9.0, 1.5 * len(muscles)), sharex=True)
    for col, label in enumerate(sides):
        for j, name in enumerate(muscles):
            ax = axes[j, col]
            ax.plot(t_walk, f_walk[:, col, j], ":", color="tab:blue", lw=1.8,
                    label="walking without trip")
            ax.plot(t_trip, f_trip[:, col, j], "-", color="tab:red", lw=1.2, label="trip")
            ax.axvline(0.0, color="k", lw=0.8)
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(name, rotation=0, ha="right", va="center")
        axes[0, col].set_title(label, fontsize=10)
        axes[-1, col].set_xlabel("time from the trip (s)")
    axes[0, 0].legend(loc="upper left", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_objective(path: Path, history: list[dict], title: str) -> None:
    """A closed-loop fit's objective per generation: best so far, the generation's best
    and median (log scale), and the best's time walked, or, for a trip stage, how many of
    its trips the best recovers and takes as people do."""
    gen = [h["generation"] for h in history]
    mark = {"marker": "o", "ms": 3} if len(gen) < 25 else {}  # a short fit's lines show
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7.0, 5.5), sharex=True,
                                  gridspec_kw={"height_ratios": (3, 1)})
    ax.semilogy(gen, [h["best"] for h in history], "-", color="tab:red", lw=1.8,
                label="best so far", **mark)
    ax.semilogy(gen, [h["generation_best"] for h in history], ".", color="tab:orange",
                ms=4, label="generation's best")
    ax.semilogy(gen, [h["generation_median"] for h in history], "-", color="0.6", lw=0.8,
                label="generation's median")
    ax.set_ylabel("objective J")
    plain = FuncFormatter(lambda y, _pos: f"{y:g}")  # 675, not 6.75 × 10²
    ax.yaxis.set_major_formatter(plain)
    ax.yaxis.set_minor_formatter(plain)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    if any("trips_recovered" in h["terms"] for h in history):  # a trip stage: its trips
        n = max(sum(k.startswith("trip_") for k in h["terms"]) for h in history)
        for key, label, color in (("trips_recovered", "recovered", "tab:green"),
                                  ("trips_human_strategy", "human strategy (window trips)",
                                   "tab:purple")):
            if any(key in h["terms"] for h in history):
                ax2.step(gen, [h["terms"].get(key, np.nan) for h in history], where="post",
                         color=color, label=label, **mark)
        ax2.set_ylim(-0.5, n + 0.5)
        ax2.set_ylabel(f"best's trips (of {n})")
        ax2.legend(fontsize=7, loc="upper left")
    else:
        walked = [h["terms"].get("walked_s", np.nan) for h in history]
        ax2.plot(gen, walked, "-", color="tab:blue", **mark)
        ax2.set_ylabel("best walks (s)")
    ax2.set_xlabel("generation")
    ax2.xaxis.set_major_locator(MaxNLocator(integer=True))
    if max(gen) - min(gen) < 5:  # a few generations: each one ticked, half a step aside
        ax2.set_xticks(range(min(gen), max(gen) + 1))
        ax2.set_xlim(min(gen) - 0.5, max(gen) + 0.5)
    ax2.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_passes(path: Path, history: list[dict]) -> None:
    """The closed-loop refinement of the network per DAgger pass: the walking objective of
    the network on its own (log scale), how long it walks, and the training loss."""
    k = [h["pass"] for h in history]
    fig, (ax, ax2, ax3) = plt.subplots(3, 1, figsize=(7.0, 6.5), sharex=True)
    ax.semilogy(k, [h["cost"] for h in history], "o-", color="tab:red")
    ax.set_ylabel("objective J")
    ax.grid(alpha=0.3, which="both")
    ax2.plot(k, [h["walked_s"] for h in history], "o-", color="tab:blue")
    ax2.set_ylabel("walks (s of 10)")
    ax2.grid(alpha=0.3)
    ax3.semilogy(k, [h["loss"] for h in history], "o-", color="0.4")
    ax3.set_ylabel("imitation loss")
    ax3.set_xlabel("DAgger pass (the expert's share β falls each pass)")
    ax3.grid(alpha=0.3, which="both")
    fig.suptitle("closed-loop refinement of the reflex network", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
