"""Motion files in: read any supported file onto the model and play it.

:func:`read_motion` reads an OpenSim ``.mot``/``.sto``, a ``.bvh`` or a Plug-in Gait
``.c3d`` and maps it onto the model's coordinates (with one-line notes on what was
ignored or converted). :func:`play_motion` checks the time span, turns a walk that
travels along any heading onto +x (:func:`straighten`), plays it on the body and checks
that it covers a stride. The command line's ``--gait`` and ``--reference`` use them.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from stumble.body import Body
from stumble.body.joints import PELVIS_ROTATIONS, hinge_names, rotation_matrix
from stumble.errors import InputError
from stumble.gait.playback import SAMPLE_HZ, Playback, play
from stumble.gait.readers import (
    PELVIS_TRANSLATIONS,
    Motion,
    check_file,
    map_coordinates,
    read_mot,
)

FORMATS = {".mot": "OpenSim", ".sto": "OpenSim", ".bvh": "BVH", ".c3d": "C3D"}
MAX_PLAY_S = 600.0  # longest motion played (s), as for the reference gait
MIN_TRAVEL_M = 0.5  # a pelvis travelling less than this is on a treadmill or in place
STRIDE_RANGE_S = (0.5, 2.5)  # strides looked for in the joint angles (s): running to a slow walk
FALLBACK_STRIDE_S = 1.2  # our choice: the heading window when the angles show no stride
MIN_LAG_OVERLAP_S = 0.5  # a lag is tried only if this much of the file overlaps itself
MAX_PERIOD_HZ = 200.0  # the stride is looked for in the angles resampled at most this fast
MIN_TURN_DEG = 5.0  # walks whose heading stays within this of +x are played as they are
MIN_STRIDE_SHARE = 0.9  # a file must last this share of its stride (one stride: 1.0)


def model_coordinates(planar: bool) -> list[str]:
    """Names of the coordinates a motion can drive on the 3D or planar model."""
    if planar:
        return ["pelvis_tx", "pelvis_ty", "pelvis_tilt", *hinge_names(planar=True)]
    return [*(h.name for h in PELVIS_ROTATIONS), *PELVIS_TRANSLATIONS, *hinge_names()]


def read_motion(path: str | Path, planar: bool = False, model: str = "auto",
                up: str = "auto", forward: str = "auto") -> Motion:
    """A motion file's coordinates on the 3D (or planar) model, checked, with notes.

    ``model`` is the OpenSim model family of a ``.mot``/``.sto`` (``auto``, ``gait2392``,
    ``gait10dof18musc``, ``rajagopal``; see ``readers.map_coordinates``); ``up`` and
    ``forward`` the axes of a ``.bvh`` (``auto`` reads them from the motion).
    """
    path = Path(path)
    check_file(path)  # a pipe or device is refused whatever its name
    suffix = path.suffix.lower()
    if suffix != ".bvh" and (up != "auto" or forward != "auto"):  # not silently ignored
        raise InputError(f"{path.name}: --up and --forward are for .bvh files (a {suffix} "
                         "file's axes are its format's)")
    if suffix not in (".mot", ".sto") and model != "auto":
        raise InputError(f"{path.name}: --model is for .mot and .sto files (a {suffix} "
                         "file is read onto gait2392's coordinates)")
    names = model_coordinates(planar)
    if suffix in (".mot", ".sto"):
        return map_coordinates(read_mot(path), names, family=model)
    if suffix == ".bvh":
        from stumble.gait.bvh import bvh_to_coordinates, read_bvh

        motion = bvh_to_coordinates(read_bvh(path), up=up, forward=forward)
    elif suffix == ".c3d":
        from stumble.gait.c3d import read_c3d

        motion = read_c3d(path)
    else:
        raise InputError(f"{path.name}: unknown motion format {suffix!r} (use .mot, .sto, "
                         ".bvh or .c3d)")
    return map_coordinates(motion, names, family="gait2392")


def _pelvis_rotation(cols: dict[str, np.ndarray], n: int) -> np.ndarray:
    zero = np.zeros(n)
    r = np.eye(3)
    for h in PELVIS_ROTATIONS:
        r = r @ rotation_matrix(h.axis, cols.get(h.name, zero))
    return r


def stride_period_s(motion: Motion) -> float | None:
    """The stride time (s) of a motion from its joint angles alone, or None.

    The signal is the right minus the left hip flexion (else knee, else ankle; else one
    side's), which repeats every stride and is reversed half a stride later. The stride is
    the first lag in ``STRIDE_RANGE_S`` at which the signal best matches itself (a local
    maximum of the correlation over the overlap, at least 0.5); in a file too short for
    that, twice the first lag at which it best matches its reverse (a local minimum, at
    most -0.5). Both to a fraction of a sample (a parabola through the extremum).
    """
    cols, t = motion.columns, motion.time_s
    signal = None
    for joint in ("hip_flexion", "knee_angle", "ankle_angle"):
        right, left = cols.get(f"{joint}_r"), cols.get(f"{joint}_l")
        if right is not None and left is not None:
            signal = right - left
            break
        if signal is None:
            signal = right if right is not None else left
    if signal is None or len(t) < 3:
        return None
    dt = max(float(np.median(np.diff(t))), 1.0 / MAX_PERIOD_HZ)
    if not np.isfinite(dt) or t[-1] - t[0] < 3 * dt:
        return None
    s = np.interp(np.arange(t[0], t[-1] + 0.5 * dt, dt), t, signal)
    if not np.isfinite(s).all():
        return None
    s = s - s.mean()
    n = len(s)
    shortest, longest = (round(x / dt) for x in STRIDE_RANGE_S)
    last = min(longest, n - max(3, round(MIN_LAG_OVERLAP_S / dt)))  # lags tried, in samples
    if last < 2:
        return None
    # Pearson's correlation of s[:-k] with s[k:] for every lag k, from sums (the products
    # by FFT): sums and sums of squares of the overlapping parts from cumulative sums
    spec = np.fft.rfft(s, 2 * n)
    prod = np.fft.irfft(spec * np.conj(spec), 2 * n)[:last + 2]
    cum, cum2 = (np.concatenate([[0.0], np.cumsum(x)]) for x in (s, s * s))
    lag = np.arange(last + 2)
    m = n - lag
    sa, sb = cum[n - lag], cum[n] - cum[lag]
    var_a, var_b = cum2[n - lag] - sa * sa / m, cum2[n] - cum2[lag] - sb * sb / m
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = (prod - sa * sb / m) / np.sqrt(var_a * var_b)
    corr[~(var_a * var_b > 1e-12 * cum2[n] ** 2)] = np.nan

    def first_extremum(sign: float, lags: range) -> float | None:
        for k in lags:
            c0, c1, c2 = sign * corr[k - 1:k + 2]
            if np.isfinite([c0, c1, c2]).all() and c1 >= 0.5 and c1 >= c0 and c1 > c2:
                den = c0 - 2.0 * c1 + c2  # the vertex of a parabola through k-1, k, k+1
                return (k + (0.5 * (c0 - c2) / den if den != 0 else 0.0)) * dt
        return None

    full = first_extremum(1.0, range(max(2, shortest), last + 1))
    if full is not None:
        return full
    half = first_extremum(-1.0, range(max(2, shortest // 2), min(longest // 2, last) + 1))
    return None if half is None else 2.0 * half


def walking_heading(motion: Motion) -> np.ndarray | None:
    """The walking direction (rad, from +x towards +y = OpenSim's -z) at each sample.

    At each instant, the direction in which the pelvis (``pelvis_tx``, ``pelvis_tz``)
    travels over the stride centred there (:func:`stride_period_s`, else
    ``FALLBACK_STRIDE_S``): the path's average over a whole stride, so the sway within a
    stride, which repeats every stride, cancels. Within half a stride of either end of the
    walking, where no whole stride is centred, a straight line fitted to the heading over
    the nearest stride is extended; beyond that (a file that stands before or after it
    walks) the heading is held. A file shorter than a stride walks along its overall
    displacement. None when the pelvis path is missing or the pelvis barely moves.
    """
    cols, t = motion.columns, motion.time_s
    if "pelvis_tx" not in cols or "pelvis_tz" not in cols or len(t) < 3:
        return None
    fwd, left = cols["pelvis_tx"], -cols["pelvis_tz"]
    stride = stride_period_s(motion) or FALLBACK_STRIDE_S
    half = 0.5 * stride
    inside = (t - half >= t[0] - 1e-9) & (t + half <= t[-1] + 1e-9)
    tc = t[inside]
    dx = np.interp(tc + half, t, fwd) - np.interp(tc - half, t, fwd)
    dy = np.interp(tc + half, t, left) - np.interp(tc - half, t, left)
    moving = np.hypot(dx, dy) / stride > 0.1  # m/s
    if moving.sum() < 2:
        dx, dy = fwd[-1] - fwd[0], left[-1] - left[0]
        if np.hypot(dx, dy) / max(t[-1] - t[0], 1e-9) <= 0.1:
            return None
        return np.full(len(t), np.arctan2(dy, dx))
    tm = tc[moving]
    hm = np.unwrap(np.arctan2(dy[moving], dx[moving]))
    heading = np.interp(t, tm, hm)
    for edge, near, end, step in ((t < tm[0], tm <= tm[0] + stride, 0, -half),
                                  (t > tm[-1], tm >= tm[-1] - stride, -1, half)):
        if edge.any():
            slope, icpt = (np.polyfit(tm[near], hm[near], 1) if near.sum() >= 2
                           else (0.0, hm[end]))
            reach = np.clip(t[edge], min(tm[end], tm[end] + step), max(tm[end], tm[end] + step))
            heading[edge] = slope * reach + icpt
    return heading


def straighten(motion: Motion) -> Motion:
    """The motion turned so that it walks along +x, with a note; else unchanged.

    The walking direction is :func:`walking_heading`: the direction the pelvis travels
    over the stride centred at each instant, so the sway within a stride stays in the
    pelvis. A walk that travels at least ``MIN_TRAVEL_M`` with a heading that leaves +x by
    more than ``MIN_TURN_DEG`` (a walk along -x, a turn, a figure 8) has that heading
    removed from its pelvis orientation at every instant (a world yaw), and its pelvis path
    made straight; so speed and gait events come out along the walking direction. Joint
    angles are untouched.
    """
    cols = motion.columns
    if "pelvis_tx" not in cols or "pelvis_tz" not in cols:
        return motion
    t = motion.time_s
    if len(t) < 3:
        return motion
    fwd, left = cols["pelvis_tx"], -cols["pelvis_tz"]
    if np.hypot(fwd[-1] - fwd[0], left[-1] - left[0]) < MIN_TRAVEL_M:
        return motion
    heading = walking_heading(motion)
    if heading is None or np.degrees(np.abs(heading)).max() <= MIN_TURN_DEG:
        return motion
    from stumble.gait.bvh import hinge_angles

    rot = rotation_matrix(PELVIS_ROTATIONS[2].axis, -heading) @ _pelvis_rotation(cols, len(t))
    angles = hinge_angles(rot, [h.axis for h in PELVIS_ROTATIONS],
                          [tuple(np.radians(h.range_deg)) for h in PELVIS_ROTATIONS])
    out = dict(cols)
    for i, h in enumerate(PELVIS_ROTATIONS):
        out[h.name] = np.unwrap(angles[:, i])
    vf = np.gradient(fwd, t) * np.cos(heading) + np.gradient(left, t) * np.sin(heading)
    vl = -np.gradient(fwd, t) * np.sin(heading) + np.gradient(left, t) * np.cos(heading)
    steps = np.diff(t)
    out["pelvis_tx"] = fwd[0] + np.concatenate([[0.0], np.cumsum(0.5 * (vf[1:] + vf[:-1])
                                                                 * steps)])
    out["pelvis_tz"] = -(left[0] + np.concatenate([[0.0], np.cumsum(0.5 * (vl[1:] + vl[:-1])
                                                                    * steps)]))
    turn = np.degrees(heading[-1] - heading[0])
    note = (f"{motion.source}: walks along a heading of {np.degrees(heading[0]):.0f} deg, "
            f"turning {turn:.0f} deg in all; played along +x (speed and events along the "
            "walking direction)")
    return replace(motion, columns=out, notes=(*motion.notes, note))


def _uniform(t: np.ndarray) -> bool:
    steps = np.diff(t)
    return bool(np.abs(steps - steps.mean()).max() <= 1e-6 * steps.mean() + 1e-9)


def play_motion(body: Body, motion: Motion, duration_s: float | None = None,
                as_recorded: bool = False) -> Playback:
    """Play a motion read by :func:`read_motion` on ``body``; its notes go to the playback.

    The motion starts at its first sample and lasts ``duration_s`` (default: the whole
    file, at most ``MAX_PLAY_S``). By default it is turned onto +x (:func:`straighten`),
    resampled at ``SAMPLE_HZ`` and its stance feet planted (``playback.play``).
    ``as_recorded`` keeps the file's joint angles exactly: no turning, no foot planting,
    and the file's own sample times when they are uniform. A motion shorter than
    ``MIN_STRIDE_SHARE`` of its stride, or without a heel strike of each foot, is an
    :class:`InputError` (below one stride); with fewer than two heel strikes of a foot the
    stride is the period of the joint angles (``stride_period_s``), else twice the step
    (``GaitEvents.stride_estimate_s``), with a note.
    """
    src = motion.source
    if motion.n_frames < 2:
        raise InputError(f"{src}: {motion.n_frames} sample(s); playing needs at least 2")
    t = motion.time_s - motion.time_s[0]
    if duration_s is not None:
        if not np.isfinite(duration_s) or duration_s <= 0:
            raise InputError(f"--duration must be positive, got {duration_s}")
        if duration_s > t[-1] + 1e-9:
            raise InputError(f"--duration {duration_s} s is longer than {src} ({t[-1]:.3f} s)")
    else:
        duration_s = float(t[-1])
    if duration_s > MAX_PLAY_S:
        raise InputError(f"{src}: lasts {duration_s:.4g} s; stumble plays at most "
                         f"{MAX_PLAY_S:g} s (give --duration)")
    notes = list(motion.notes)
    if not as_recorded:
        motion = straighten(motion)
        notes = list(motion.notes)
    wanted = set(body.joints) | {h.name for h in PELVIS_ROTATIONS}
    if as_recorded and _uniform(t):
        n = int(np.searchsorted(t, duration_s + 1e-9))
        time_s = t[:n]
        coords = {k: v[:n] for k, v in motion.columns.items() if k in wanted}
    else:
        time_s = np.arange(0.0, duration_s + 1e-9, 1.0 / SAMPLE_HZ)
        coords = {k: np.interp(time_s, t, v) for k, v in motion.columns.items() if k in wanted}
    if len(time_s) < 2:
        raise InputError(f"{src}: {len(time_s)} sample(s) in {duration_s:g} s; playing needs "
                         "at least 2")
    pb = play(body, time_s, coords, f"file: {src}", plant=not as_recorded)
    stride, how = pb.events.stride_estimate_s()
    if how != "complete strides":  # a step or two: the hips' own period is the better guess
        period = stride_period_s(motion)  # (0.7 m/s, 1.5 s: 1.597 s, the steps 1.71, true 1.594)
        if period is not None:
            stride, how = period, "the period of the hips' flexion"
    hs = {s: len(pb.events.heel_strike_s[s]) for s in ("r", "l")}
    if stride is None or duration_s < MIN_STRIDE_SHARE * stride:
        span = "" if stride is None else f" of {stride:.2f} s"
        raise InputError(f"{src}: {duration_s:.2f} s is less than one stride{span} of walking "
                         f"(heel strikes found: right {hs['r']}, left {hs['l']})")
    if not np.isfinite(pb.stride_s):
        pb.stride_s = stride
        notes.append(f"{src}: no complete stride of one foot; stride {stride:.3f} s taken as "
                     f"{how}")
    pb.notes = notes
    return pb


TABLE2_COORDINATES = ("pelvis_tilt", *(f"{j}_{s}" for j in ("hip_flexion", "knee_angle",
                                                           "ankle_angle") for s in ("r", "l")))


def align_reference(motion: Motion, scenario, how: str = "swing",
                    duration_s: float | None = None) -> Motion:
    """A recorded trip's SCA 2009 Table 2 coordinates with time 0 at its trip.

    ``how="swing"`` (default): the reference's trip instant is the first toe-off of the
    scenario's tripped leg plus ``scenario.swing_fraction`` of that swing (toe-off to the
    next heel strike), its events found by playing it on the scenario's body; so the
    reference and the simulation trip at the same fraction of swing. ``how="time"``:
    the file's own time 0 is the trip. A reference without any Table 2 coordinate
    (pelvis_tilt, hip_flexion, knee_angle, ankle_angle), or whose aligned time does not
    overlap 0 to ``duration_s`` (default: the scenario's), is an :class:`InputError`.
    """
    from stumble.body import build

    src = motion.source
    usable = {k: v for k, v in motion.columns.items() if k in TABLE2_COORDINATES}
    if not usable:
        raise InputError(f"{src}: none of the joint pitches of SCA 2009 Table 2 "
                         f"({', '.join(TABLE2_COORDINATES[:4])}, ...) to compare with")
    notes = list(motion.notes)
    shift = 0.0
    if how == "swing":
        body = build(planar=scenario.controller == "reflex", height_m=scenario.height_m,
                     mass_kg=scenario.mass_kg, sex=scenario.sex)
        try:
            pb = play_motion(body, motion, as_recorded=True)
        except InputError as exc:
            raise InputError(f"{exc} (or give --reference-align time)") from None
        side = scenario.side
        ev = pb.events
        swing = next(((to, hs) for to in ev.toe_off_s[side] for hs in ev.heel_strike_s[side]
                      if hs > to), None)
        if swing is None:
            leg = {"l": "left", "r": "right"}[side]
            raise InputError(f"{src}: no complete swing of the {leg} leg (toe-off, then heel "
                             "strike) to align the trip by; give --reference-align time")
        to, hs = swing
        shift = float(pb.time_s[0] + motion.time_s[0] + to
                      + scenario.swing_fraction * (hs - to))
        notes.append(f"{src}: its trip taken at {shift:.3f} s ({scenario.swing_fraction:g} "
                     f"of the swing from {motion.time_s[0] + to:.3f} to "
                     f"{motion.time_s[0] + hs:.3f} s)")
    elif how != "time":
        raise InputError(f"unknown reference alignment {how!r} (swing or time)")
    t = motion.time_s - shift
    end = scenario.resolved().duration_after_trip_s if duration_s is None else duration_s
    if min(t[-1], end) <= max(t[0], 0.0):
        raise InputError(f"{src}: its time ({t[0]:.2f} to {t[-1]:.2f} s from its trip) does "
                         f"not overlap the simulated trip (0 to {end:g} s)")
    return replace(motion, time_s=t, columns=usable, notes=tuple(notes))
