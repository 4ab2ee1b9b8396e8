"""The files of a trip: summary.json, timeseries.csv, trajectories.png, filmstrip, video."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

from stumble.analysis import NOT_PAST, trip_contact_s
from stumble.jsonio import write_json
from stumble.outdir import output_dir
from stumble.pipeline import TripResult

VIDEO_FPS = 25.0
WALK_SHOWN_S = 1.0  # walking shown in the video before the trip


def write_summary(out: Path, result: TripResult) -> None:
    """``summary.json``: the outcome and metrics (``stumble.analysis.trip_summary``)."""
    write_json(out / "summary.json", result.summary)


def write_timeseries(out: Path, result: TripResult) -> None:
    """``timeseries.csv``: time, state, joint angles (deg), COM, contacts, trip force, the
    whole-body angular momentum about the COM (``analysis.angular_momentum``)."""
    rec, body = result.recording, result.body
    m = body.model
    ang = result.angular_momentum()
    header = ["time_s", "state", "pelvis_x_m", "pelvis_y_m", "pelvis_z_m",
              *[f"{j}_deg" for j in body.joints],
              "com_x_m", "com_y_m", "com_z_m", "com_vx_m_per_s", "com_vy_m_per_s",
              "com_vz_m_per_s", "foot_r_on_floor", "foot_l_on_floor",
              "trip_force_x_n", "trip_force_y_n", "trip_force_z_n",
              *[f"angular_momentum_{a}_kg_m2_per_s" for a in "xyz"]]
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
                        *np.round(rec.trip_force[k], 3), *np.round(ang[k], 4)])


def trip_motion(result: TripResult, before_s: float = WALK_SHOWN_S,
                shown: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Times (s, 0 at the trip) and qpos of a trip with ``before_s`` of its walk before it.

    The walk is the playback at the recording's sample interval, so the whole motion is
    uniformly sampled (for BVH); a trip in the controller's own gait (start own) shows
    the end of that walk, and a walk that never reached the trip all of it. ``shown``:
    the played-back walk as video shows it, each touchdown's planting step spread
    (``Playback.shown``; the motion files keep the step, as ``stumble walk``'s)."""
    rec = result.recording
    t_trip = result.summary["trip_time_s"]
    if t_trip is None:  # start own, no trip: the walk itself
        return rec.time_s, rec.qpos
    dt = float(np.mean(np.diff(rec.time_s))) if len(rec.time_s) > 1 else 0.005
    own = result.walk_recording
    if own is not None:  # its samples need not fall on the trip's grid: interpolated
        t = own.time_s - t_trip
        k = int(np.floor(min(before_s, -t[0]) / dt + 1e-9))
        t_walk = -dt * np.arange(k, 0, -1)
        walk_q = np.stack([np.interp(t_walk, t, own.qpos[:, j])
                           for j in range(own.qpos.shape[1])], axis=1)
        return np.concatenate([t_walk, rec.time_s]), np.vstack([walk_q, rec.qpos])
    k = int(np.floor(min(before_s, t_trip - result.playback.time_s[0]) / dt + 1e-9))
    t_walk = -dt * np.arange(k, 0, -1)
    pb = result.playback.shown() if shown else result.playback
    walk_q = [pb.state_at(t_trip + t)[0] for t in t_walk]
    qpos = np.vstack([*walk_q, rec.qpos]) if walk_q else rec.qpos
    return np.concatenate([t_walk, rec.time_s]), qpos


def write_motion_files(out: Path, body, time_s: np.ndarray, qpos: np.ndarray,
                       recording=None) -> list[str]:
    """``motion.mot`` and ``motion.bvh`` of a motion (``qpos`` (T, nq) at ``time_s`` (s),
    uniformly sampled) and, when ``recording`` has muscle activations, ``muscles.sto``
    (its activation and force per muscle); returns the names written."""
    import mujoco

    from stumble.gait.writers import opensim_muscle_name, write_bvh, write_mot, write_muscles_sto

    write_mot(out / "motion.mot", body, time_s, qpos)
    write_bvh(out / "motion.bvh", body, time_s, qpos)
    written = ["motion.mot", "motion.bvh"]
    m = body.model
    muscles = np.flatnonzero(m.actuator_gaintype == mujoco.mjtGain.mjGAIN_MUSCLE)
    rec = recording
    if (rec is not None and len(muscles) and rec.activation is not None
            and rec.activation.size and len(rec.time_s) > 1):
        names = [opensim_muscle_name(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i))
                 for i in muscles]
        act = rec.activation[:, m.actuator_actadr[muscles]]
        write_muscles_sto(out / "muscles.sto", rec.time_s, names, act,
                          -rec.actuator_force[:, muscles])
        written.append("muscles.sto")
    return written


def frames_at_states(result: TripResult, most: int = 7) -> tuple[list[np.ndarray], list[str]]:
    """qpos at the first entry of each state (as SCA 2009 Figures 7-9), then the end."""
    rec = result.recording
    qs, labels, seen = [], [], set()
    states = list(result.states)
    if result.scenario.controller in ("reflex", "gh2010") and len(rec.time_s):
        # one network state: show its events and the motion every 0.15 s between them
        marks = {round(t, 2) for _n, t in states}
        states += [(f"@{t:.2f}", t) for t in np.arange(0.15, rec.time_s[-1] - 0.05, 0.15)
                   if all(abs(t - m) > 0.05 for m in marks)]
        states.sort(key=lambda nt: nt[1])
    for name, t in states:
        if name in seen or len(qs) >= most:
            continue
        seen.add(name)
        k = min(int(np.searchsorted(rec.time_s, t + 0.03)), len(rec.time_s) - 1)
        qs.append(rec.qpos[k])
        labels.append(f"{t:.2f} s" if name.startswith("@")
                      else f"{name.replace('_', ' ')} ({t:.2f} s)")
    end = result.summary.get("stop_reason", "")
    qs.append(rec.qpos[-1])
    labels.append(f"end: {end} ({rec.time_s[-1]:.2f} s)")
    return qs, labels


def write_media(out: Path, result: TripResult, video: bool, progress: bool) -> list[str]:
    """trajectories.png always; filmstrip.png and trip.mp4 when rendering works."""
    from stumble.viz.trip_plots import plot_trajectories

    s = result.summary
    rec = result.recording
    variant = f" ({s['variant']})" if s.get("variant") else ""  # (none: no recovery step)
    behind = s.get("stop_reason") == NOT_PAST
    outcome = ("recovered" if s["recovered"] else "fell" if s["fell"]
               else "no recovery (walking, not past the obstacle)" if behind
               else "no recovery")
    title = (f"{s['strategy']}{variant}, {s['mechanism']} trip at "
             f"{s['swing_fraction']:.2f} of swing, {s['speed_m_per_s']} m/s: {outcome}")
    tripped = s["trip_time_s"] is not None
    if not tripped:  # start own: the walk never reached the trip
        title = f"no trip: the {s['controller']} walker {s['stop_reason']}"
    sc = result.scenario
    contact = trip_contact_s(rec, sc.side, sc.mechanism) if tripped else None
    plot_trajectories(out / "trajectories.png", result.body.model, rec.time_s, rec.qpos,
                      sc.side, s["strategy"], result.states, title,
                      angmom=result.angular_momentum()[:, 1], contact=contact)
    written = ["trajectories.png"]
    if result.scenario.controller in ("reflex", "gh2010") and tripped:
        write_muscle_tensions(out, result)
        written.append("muscle_tensions.png")
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
    # one second of the walk before the trip (played back), then the physics
    time_all, qpos_all = trip_motion(result, shown=True)
    step = max(1, round(1.0 / (VIDEO_FPS * float(np.mean(np.diff(time_all))))))
    n_walk = len(time_all) - len(rec.time_s)
    state = ["walking"] * n_walk + list(rec.state)
    qpos = qpos_all[::step]
    overlay = [f"t = {t:5.2f} s  {st.replace('_', ' ')}"
               for t, st in zip(time_all[::step], state[::step], strict=True)]
    render_video(out / "trip.mp4", result.body.model, qpos, 1.0 / (step * float(
        np.mean(np.diff(time_all)))), overlay=overlay, progress=progress)
    written.append("trip.mp4")
    return written


def prepare_dir(out: Path) -> Path:
    """Create the output directory, writable, or raise a one-line InputError."""
    return output_dir(out)


TENSION_WINDOW_S = (-0.1, 0.6)  # muscle_tensions.png: from before the trip to 0.6 s after


def write_muscle_tensions(out: Path, result: TripResult) -> None:
    """``muscle_tensions.png`` (seed 003 Fig. 5): tensions of a reflex trip vs walking."""
    from stumble.control.reflex.identify import default_network, leg_muscles
    from stumble.control.reflex.receptors import IB_FORCE_N, IB_GAIN
    from stumble.gait.playback import stride_phase
    from stumble.viz.reflex_plots import plot_muscle_tensions

    rec, m, s = result.recording, result.body.model, result.summary
    tripped = result.scenario.side
    legs = (tripped, {"r": "l", "l": "r"}[tripped])
    muscles = leg_muscles(result.body)
    ids = [[m.actuator(f"{mus}_{side}").id for mus in muscles] for side in legs]
    sel = rec.time_s <= TENSION_WINDOW_S[1]
    f_trip = np.stack([-rec.actuator_force[sel][:, row] for row in ids], axis=1)
    net = result.network or default_network()
    t_walk = np.arange(TENSION_WINDOW_S[0], TENSION_WINDOW_S[1], 0.002)
    f_walk = np.full((len(t_walk), 2, len(muscles)), np.nan)
    own = result.walk_recording
    if own is not None and s.get("walking_stride_s"):  # its own walk, one stride earlier
        t0 = s["trip_time_s"] - s["walking_stride_s"]
        for col, row in enumerate(ids):
            for j, a in enumerate(row):
                f_walk[:, col, j] = np.interp(t0 + t_walk, own.time_s,
                                              -own.actuator_force[:, a])
    elif net.walk_rates is not None and net.topology.muscles == muscles:
        T = net.walk_rates.shape[1]
        phase = stride_phase(result.playback, s["trip_time_s"]) + t_walk / result.playback.stride_s
        k = np.round(phase * T).astype(int) % T
        for col, side in enumerate(legs):
            ib = net.walk_rates["rl".index(side)][k][:, 2:3 * len(muscles):3]
            f_walk[:, col] = IB_FORCE_N * (np.exp(ib / IB_GAIN) - 1.0)  # invert Ib's law
    names = {"r": "right", "l": "left"}
    plot_muscle_tensions(
        out / "muscle_tensions.png", rec.time_s[sel], f_trip, t_walk, f_walk,
        (f"{names[legs[0]]} leg (tripped)", f"{names[legs[1]]} leg (support)"),
        f"muscle tension (N): trip at {s['swing_fraction']:.2f} of swing "
        f"({s['strategy'] or 'no strategy'}) vs walking", muscles)


def write_fit(out: Path, fit, video: bool = True, closed_loop=None) -> list[str]:
    """The files of ``stumble reflex fit``: network, figures of the fit, walking data, and
    one walking step under the network (seed 003 Fig. 3) in fit.json and walking_step.png;
    with ``closed_loop`` (``dagger.DaggerResult``) the refined network, its passes in
    fit.json and objective.png."""
    from stumble.control.reflex.walking import write_moments_csv
    from stumble.pipeline import simulate_walking_step
    from stumble.viz.reflex_plots import plot_activity_fit

    muscles = fit.network.topology.muscles
    net = fit.network if closed_loop is None else closed_loop.network
    net.save(out / "network.npz")
    if closed_loop is not None:
        fit.report["closed_loop"] = {
            "method": "DAgger with the GH2010 expert on seed 003's wiring "
                      "(stumble.control.reflex.dagger)",
            "expert": closed_loop.expert,
            **({"loss": closed_loop.loss} if closed_loop.loss != "squared" else {}),
            **({"pushes": [list(q) for q in closed_loop.pushes]} if closed_loop.pushes
               else {}),
            **({"trip_episodes": closed_loop.trips} if closed_loop.trips else {}),
            "passes": closed_loop.history, "wall_time_s": round(closed_loop.wall_time_s, 1)}
    step = simulate_walking_step(net)
    fit.report["walking_step"] = {
        "rmse_deg": step.rmse_deg, "duration_s": round(step.duration_s, 3),
        "fell": step.fell, "start": "right heel strike, subject's speed",
        "trunk_balance": True}
    write_json(out / "fit.json", fit.report)
    ident = fit.ident
    T = len(ident.time_s)
    pct = 100.0 * np.arange(T) / T
    walk = ident.walk
    events = {}
    for side, lab in (("r", "R"), ("l", "L")):
        for key, ev in (("heel_strike_s", "HS"), ("toe_off_s", "TO")):
            for t in np.atleast_1d(getattr(walk, key)[side]):
                events[f"{lab} {ev}"] = float(100.0 * (t % ident.stride_s) / ident.stride_s)
    r = fit.report
    plot_activity_fit(
        out / "activity_fit.png", pct, ident.activity[0], fit.activity_net[0], events,
        f"right-leg muscle activity: identified vs network (average error "
        f"{100 * r['avg_error']:.1f} %, max {100 * r['max_error']:.0f} %; seed 003: 2.0 %, 36 %)",
        muscles)
    write_moments_csv(walk, out / "walking_moments.csv")
    grid = np.linspace(0.0, 100.0, 51)
    ext = np.append(pct, 100.0)
    with (out / "walking_activity.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["percent", *[f"{mus}_{kind}" for mus in muscles
                                 for kind in ("target", "network")]])
        cols = []
        for j in range(len(muscles)):
            for series in (ident.activity[0, :, j], fit.activity_net[0, :, j]):
                cols.append(np.interp(grid, ext, np.append(series, series[0])))
        for i, p in enumerate(grid):
            w.writerow([round(float(p), 1), *[round(float(c[i]), 5) for c in cols]])
    written = ["network.npz", "fit.json", "activity_fit.png", "walking_moments.csv",
               "walking_activity.csv"]
    if closed_loop is not None and closed_loop.history:
        from stumble.viz.reflex_plots import plot_passes

        plot_passes(out / "objective.png", closed_loop.history)
        written.append("objective.png")
    if video and _walking_step_strip(out / "walking_step.png", step):
        written.append("walking_step.png")
    return written


def _walking_step_strip(path: Path, step) -> bool:
    """Seed 003 Fig. 3: the recorded step (top row) and the simulated one (bottom)."""
    from stumble.viz.render import render_frames, save_filmstrip, video_available

    ok, why = video_available()
    if not ok:
        print(f"stumble: {why}", file=sys.stderr)
        return False
    rec = step.recording
    ks = np.linspace(0, len(rec.time_s) - 1, 6).round().astype(int)
    qs = np.vstack([step.reference_qpos[ks], rec.qpos[ks]])
    frames = render_frames(step.body.model, qs, width=320, height=360, distance=2.6)
    labels = ([f"recorded {rec.time_s[k]:.2f} s" for k in ks]
              + [f"network {rec.time_s[k]:.2f} s" for k in ks])
    save_filmstrip(path, frames, labels, columns=len(ks))
    return True


def walk_playback(result):
    """A reflex walk (``pipeline.WalkResult``) as a ``Playback``, so that the writers of
    ``stumble walk`` (motion.csv, events.json, joint_angles.png, video) serve it too."""
    from stumble.gait.events import GaitEvents
    from stumble.gait.playback import Playback

    rec, body, s = result.recording, result.body, result.summary
    m = body.model
    coords = {j: rec.qpos[:, m.jnt_qposadr[m.joint(j).id]] for j in body.joints}
    ev = s["events"]
    events = GaitEvents({k: list(v["heel_strike_s"]) for k, v in ev.items()},
                        {k: list(v["toe_off_s"]) for k, v in ev.items()})
    stride = events.mean_stride_s()
    return Playback(body, rec.time_s, rec.qpos, rec.qvel, coords, events,
                    float(s["speed_m_per_s"]), stride if np.isfinite(stride) else 0.0,
                    f"reflex walk ({s['controller']})")


def write_reflex_walk(out: Path, result, video: bool, progress: bool) -> list[str]:
    """The files of ``stumble reflex walk``: motion.csv and events.json (as ``stumble
    walk`` writes them), summary.json, joint_angles.png (the simulated strides, mean ±
    SD, over the recorded stride) and walk.mp4."""
    from stumble.analysis import (
        CYCLE_POINTS,
        SIDES,
        WALK_JOINTS,
        foot_angles,
        stride_curves,
        trunk_lean,
    )
    from stumble.gait.writers import write_motion_csv
    from stumble.viz.plots import plot_joint_angles

    pb = walk_playback(result)
    s = result.summary
    write_motion_csv(out / "motion.csv", pb)
    events = {**pb.events.to_json(), "speed_m_per_s": s["speed_m_per_s"],
              "stride_s": None if not pb.stride_s else round(pb.stride_s, 4),
              "stance_fraction": s["stance_fraction"], "source": pb.source,
              "model": "planar", "retarget": {}}
    write_json(out / "events.json", events)
    write_json(out / "summary.json", {k: v for k, v in s.items() if k != "events"})
    rec, m = result.recording, result.body.model
    names = [f"{j}_{side}" for j in WALK_JOINTS for side in SIDES]
    angles = {n: rec.qpos[:, m.jnt_qposadr[m.joint(n).id]] for n in names}
    if result.body.planar:
        angles.update(foot_angles(rec.qpos, m))
        angles.update(trunk_lean(rec.qpos, m))
    curves = stride_curves(rec.time_s, angles, pb.events.heel_strike_s["r"])
    pct = np.linspace(0.0, 100.0, CYCLE_POINTS)
    have = s["strides"] > 0
    mean = {n: np.degrees(c.mean(axis=0)) for n, c in curves.items()} if have else {}
    sd = {n: np.degrees(c.std(axis=0)) for n, c in curves.items()} if have else {}
    ref = {n: np.degrees(v) for n, v in result.reference.items()}
    rm = s["rmse_deg"]
    title = (f"{s['controller']}: {s['strides']} strides, {s['speed_m_per_s']:.2f} m/s, "
             f"stance {s['stance_fraction'] or 0:.2f}\nRMSE hip {rm.get('hip_flexion', 0):.1f}°"
             f" knee {rm.get('knee_angle', 0):.1f}° ankle {rm.get('ankle_angle', 0):.1f}°"
             + (f" foot {s['foot_angle_rmse_deg']:.1f}°"
                if s.get("foot_angle_rmse_deg") is not None else "")
             + (f" trunk {s['trunk_rmse_deg']:.1f}° (lean {s['trunk_lean_deg']:.0f}°)"
                if s.get("trunk_rmse_deg") is not None else ""))
    plot_joint_angles(out / "joint_angles.png", pct, mean, title=title, spread_deg=sd,
                      reference_deg=ref)
    written = ["motion.csv", "events.json", "summary.json", "joint_angles.png",
               *write_motion_files(out, result.body, rec.time_s, rec.qpos, rec)]
    if video:
        from stumble.viz.render import render_video, video_available

        ok, why = video_available()
        if ok:
            step = max(1, round(1.0 / (VIDEO_FPS * float(np.mean(np.diff(rec.time_s))))))
            overlay = [f"t = {t:5.2f} s  {s['controller']}" for t in rec.time_s[::step]]
            render_video(out / "walk.mp4", m, rec.qpos[::step], VIDEO_FPS, overlay=overlay,
                         progress=progress)
            written.append("walk.mp4")
        else:
            print(f"stumble: {why}", file=sys.stderr)
    return written


def write_gh2010_fit(out: Path, res) -> tuple[list[str], object]:
    """The files of ``stumble reflex fit --controller gh2010`` besides the ones the fit
    writes as it runs (gh2010.json, history.jsonl): objective.png and fit.json with a
    20 s walk of the result (``pipeline.simulate_walk``)."""
    from stumble.control.reflex.gh2010 import load_params
    from stumble.jsonio import write_json
    from stumble.pipeline import simulate_walk
    from stumble.viz.reflex_plots import plot_objective

    params = load_params(out / "gh2010.json")
    walk = simulate_walk("gh2010", 20.0, params=params)
    import json

    report = json.loads((out / "gh2010.json").read_text())["fit"]
    report["walk_20s"] = {k: v for k, v in walk.summary.items() if k != "events"}
    write_json(out / "fit.json", report)
    plot_objective(out / "objective.png", res.history,
                   f"GH2010 closed-loop fit (seed {report['seed']}): objective "
                   f"{res.best_cost:.3f} after {res.evaluations} walks")
    return ["gh2010.json", "history.jsonl", "fit.json", "objective.png"], walk
