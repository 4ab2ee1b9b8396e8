"""The files of a trip: summary.json, timeseries.csv, trajectories.png, filmstrip, video."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

from stumble.errors import InputError
from stumble.pipeline import TripResult

VIDEO_FPS = 25.0
WALK_SHOWN_S = 1.0  # walking shown in the video before the trip


def write_summary(out: Path, result: TripResult) -> None:
    """``summary.json``: the outcome and metrics (see ``stumble.pipeline``)."""
    (out / "summary.json").write_text(json.dumps(result.summary, indent=1) + "\n")


def write_timeseries(out: Path, result: TripResult) -> None:
    """``timeseries.csv``: time, state, joint angles (deg), COM, contacts, trip force."""
    rec, body = result.recording, result.body
    m = body.model
    header = ["time_s", "state", "pelvis_x_m", "pelvis_y_m", "pelvis_z_m",
              *[f"{j}_deg" for j in body.joints],
              "com_x_m", "com_y_m", "com_z_m", "com_vx_m_per_s", "com_vy_m_per_s",
              "com_vz_m_per_s", "foot_r_on_floor", "foot_l_on_floor",
              "trip_force_x_n", "trip_force_y_n", "trip_force_z_n"]
    adr = [m.jnt_qposadr[m.joint(j).id] for j in body.joints]
    with (out / "timeseries.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for k in range(len(rec.time_s)):
            w.writerow([round(float(rec.time_s[k]), 4), rec.state[k],
                        *np.round(rec.qpos[k, :3], 5),
                        *np.round(np.degrees(rec.qpos[k, adr]), 3),
                        *np.round(rec.com[k], 5), *np.round(rec.com_vel[k], 4),
                        int(rec.foot_on_floor[k, 0]), int(rec.foot_on_floor[k, 1]),
                        *np.round(rec.trip_force[k], 3)])


def frames_at_states(result: TripResult, most: int = 7) -> tuple[list[np.ndarray], list[str]]:
    """qpos at the first entry of each state (as SCA 2009 Figures 7-9), then the end."""
    rec = result.recording
    qs, labels, seen = [], [], set()
    for name, t in result.states:
        if name in seen or len(qs) >= most:
            continue
        seen.add(name)
        k = min(int(np.searchsorted(rec.time_s, t + 0.03)), len(rec.time_s) - 1)
        qs.append(rec.qpos[k])
        labels.append(f"{name.replace('_', ' ')} ({t:.2f} s)")
    end = result.summary.get("stop_reason", "")
    qs.append(rec.qpos[-1])
    labels.append(f"end: {end} ({rec.time_s[-1]:.2f} s)")
    return qs, labels


def write_media(out: Path, result: TripResult, video: bool, progress: bool) -> list[str]:
    """trajectories.png always; filmstrip.png and trip.mp4 when rendering works."""
    from stumble.viz.trip_plots import plot_trajectories

    s = result.summary
    rec = result.recording
    title = (f"{s['strategy']} ({s['variant']}), {s['mechanism']} trip at "
             f"{s['swing_fraction']:.2f} of swing, {s['speed_m_per_s']} m/s: "
             f"{'recovered' if s['recovered'] else 'fell' if s['fell'] else 'no recovery'}")
    plot_trajectories(out / "trajectories.png", result.body.model, rec.time_s, rec.qpos,
                      result.scenario.side, s["strategy"], result.states, title)
    written = ["trajectories.png"]
    if not video:
        return written
    from stumble.viz.render import render_frames, render_video, save_filmstrip, video_available

    ok, why = video_available()
    if not ok:
        print(f"stumble: {why}", file=sys.stderr)
        return written
    qs, labels = frames_at_states(result)
    frames = render_frames(result.body.model, np.array(qs), width=480, height=480,
                           distance=3.0)
    save_filmstrip(out / "filmstrip.png", frames, labels)
    written.append("filmstrip.png")
    step = max(1, round(1.0 / (VIDEO_FPS * float(np.mean(np.diff(rec.time_s))))))
    # one second of the walk before the trip (played back), then the physics
    t_trip = s["trip_time_s"]
    before = np.arange(max(0.0, t_trip - WALK_SHOWN_S), t_trip - 1e-9, 1.0 / VIDEO_FPS)
    walk_q = [result.playback.state_at(t)[0] for t in before]
    qpos = np.vstack([*walk_q, rec.qpos[::step]]) if walk_q else rec.qpos[::step]
    overlay = ([f"t = {t - t_trip:5.2f} s  walking" for t in before]
               + [f"t = {t:5.2f} s  {st.replace('_', ' ')}"
                  for t, st in zip(rec.time_s[::step], rec.state[::step], strict=True)])
    render_video(out / "trip.mp4", result.body.model, qpos, VIDEO_FPS, overlay=overlay,
                 progress=progress)
    written.append("trip.mp4")
    return written


def prepare_dir(out: Path) -> Path:
    """Create the output directory or raise a one-line InputError."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot create output directory {out}: {e.strerror}") from None
    return out

