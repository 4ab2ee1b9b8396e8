"""Plots of one trip: SCA 2009 Figure 10 (foot path, pelvis, hip and knee pitch)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from stumble.analysis import PEOPLE_TRIP_ANGMOM_GAIN, pitch_angles_deg


def foot_com_path(model: mujoco.MjModel, qpos: np.ndarray, side: str) -> np.ndarray:
    """(T, 3) world position of a foot's centre of mass (foot and toes together)."""
    d = mujoco.MjData(model)
    ids = [model.body(f"foot_{side}").id]
    toes = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"toes_{side}")
    if toes >= 0:
        ids.append(toes)
    mass = model.body_mass[ids]
    out = np.zeros((len(qpos), 3))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        out[k] = (mass[:, None] * d.xipos[ids]).sum(axis=0) / mass.sum()
    return out


FOOT_PATH_S = 1.5  # s after the trip: the foot path panel's span (the recovery)


def plot_trajectories(path, model: mujoco.MjModel, time_s: np.ndarray, qpos: np.ndarray,
                      tripped: str, strategy: str, states: list[tuple[str, float]],
                      title: str = "", angmom: np.ndarray | None = None,
                      contact: tuple[float, float] | None = None) -> Path:
    """Leading foot COM path (x-z), pelvis, leading hip and knee pitch over time, and with
    ``angmom`` (T,) the whole-body forward angular momentum about the COM (kg·m²/s,
    ``TripResult.angular_momentum``'s y), the trip's ``contact`` (s, s) marked with its
    gain beside people's (Pijnappels et al. 2004).

    The leading leg is the recovery leg. Time 0 and the dashed line mark the trip;
    dotted lines mark the controller's state changes until it walks on (its ``step_*``
    states, shaded, one a step, are not marked). The foot's path is drawn over the
    first ``FOOT_PATH_S`` after the trip (the recovery, as SCA 2009 Fig. 10), not the
    walk on that may follow: metres of it would flatten the step to a line.
    """
    lead = tripped if strategy == "elevating" else {"r": "l", "l": "r"}[tripped]
    early = np.asarray(time_s) <= FOOT_PATH_S
    foot = foot_com_path(model, qpos[early] if early.any() else qpos, lead)
    ang = pitch_angles_deg(model, qpos, tripped, strategy)
    panels = [("pelvis", "pelvis pitch (+ posterior) [deg]"),
              ("lead_hip", "leading hip flexion [deg]"),
              ("lead_knee", "leading knee (flexion −) [deg]")]
    if angmom is not None:
        ang["angmom"] = np.asarray(angmom)
        panels.append(("angmom", "angular momentum, + fwd [kg·m²/s]"))
    fig = Figure(figsize=(3.25 * (1 + len(panels)), 3.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 1 + len(panels))
    ax = axes[0]
    ax.plot(foot[:, 0] - foot[0, 0], foot[:, 2], color="tab:blue")
    ax.plot(0.0, foot[0, 2], "o", color="tab:red", label="trip")
    ax.set_xlabel("forward [m] (from the foot at the trip)")
    ax.set_ylabel("height [m]")
    ax.set_title(f"leading ({'left' if lead == 'l' else 'right'}) foot COM, "
                 f"first {FOOT_PATH_S:g} s")
    top = float(foot[:, 2].max())
    ax.set_ylim(min(0.0, float(foot[:, 2].min())) - 0.05, top + 0.25 * max(top, 0.2))
    ax.legend(loc="upper right", fontsize=8)
    walk_on = next((t for name, t in states if name.startswith("step_")), None)
    for ax, (key, label) in zip(axes[1:], panels, strict=True):
        ax.plot(time_s, ang[key], color="tab:blue")
        ax.axvline(0.0, color="tab:red", ls="--", lw=1, label="trip")
        marked = [t for name, t in states[1:] if walk_on is None or t < walk_on]
        for k, t in enumerate(marked):
            ax.axvline(t, color="0.45", ls=":", lw=0.9,
                       label="state change" if k == 0 else None)
        if walk_on is not None:
            ax.axvspan(walk_on, float(time_s[-1]), color="0.92", zorder=0,
                       label="walking on")
        ax.set_xlabel("time since trip [s]")
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
    if angmom is not None and contact is not None:
        ax = axes[-1]
        a, b = (float(np.interp(s, time_s, ang["angmom"])) for s in contact)
        dots = ax.plot(contact, (a, b), "o", color="tab:orange", ms=4,
                       label=f"over the trip's contact: {b - a:+.1f}\n"
                             f"(people: +{PEOPLE_TRIP_ANGMOM_GAIN:g}, mid-swing)")
        ax.legend(handles=dots, loc="lower right", fontsize=7)
    axes[1].legend(loc="lower right", fontsize=8)
    axes[0].grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return Path(path)
