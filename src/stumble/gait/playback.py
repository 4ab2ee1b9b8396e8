"""Kinematic playback of a gait on a model: joint angles → qpos, qvel, feet on the ground.

Joint angles and pelvis orientation come from the gait; the pelvis *position* is
computed so the feet obey the ground (SCA 2009 §4.2 adjusts the pelvis height the
same way): vertically, the lowest sole point of either foot is put on the floor;
horizontally, the pelvis moves so that the contact point of each loaded foot does not
slide (a foot's weight falls from 1 to 0 as its lowest point rises from 0 to
``LOAD_HEIGHT_M`` above the other foot's). The recorded pelvis translations are not
used: the model's segment lengths differ from the subject's, and treadmill data have
none. Velocities are central differences of the positions, so physics can start at any
frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from stumble.body import Body
from stumble.body.joints import PELVIS_ROTATIONS, rotation_matrix
from stumble.errors import InputError
from stumble.gait import events as gait_events
from stumble.gait.reference import ReferenceGait, load_reference

LOAD_HEIGHT_M = 0.01  # a foot this far above the lower one carries no weight
IK_ITERATIONS = 10
SMOOTH_CUTOFF_HZ = 6.0  # Winter 2009: gait kinematics low-passed at about 6 Hz
DECAY_S = 0.08  # leg corrections relax toward the data with this time constant (ours)
# Our choice: a touching-down foot is planted at once (its lowest point put on the floor),
# which steps the hips, knees, ankles and pelvis position within one frame; in what is
# shown (``Playback.shown``: plots and video) the step is spread over this time, a raised
# cosine centred on it (``blend_touchdowns``). The states (trips' starts, motion files)
# keep it: a file of the blended walk reads back 3.7 % slow (its feet roll less).
TOUCHDOWN_BLEND_S = 0.08
DAMPING = 1e-4  # m²/rad²: a 1 cm foot error outweighs about 1 rad of leg correction
# Leg joints the foot planting may correct, each with the joint that undoes its effect
# on the foot's orientation (all sagittal axes are -y; adduction and subtalar share x).
LEG_IK_PLANAR = (("hip_flexion", "ankle_angle"), ("knee_angle", "ankle_angle"))
LEG_IK_3D = (*LEG_IK_PLANAR, ("hip_adduction", "subtalar_angle"))
SAMPLE_HZ = 200.0  # playback frame rate (also of resampled gait files)


@dataclass
class Playback:
    """A gait played on a model: per-frame state and the gait events."""

    body: Body
    time_s: np.ndarray  # (T,)
    qpos: np.ndarray  # (T, nq)
    qvel: np.ndarray  # (T, nv)
    coordinates: dict[str, np.ndarray]  # joint angles (rad) per model joint, (T,)
    events: gait_events.GaitEvents
    speed_m_per_s: float
    stride_s: float
    source: str
    retarget: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # one-line remarks on the input
    # qpos with each touchdown's planting step spread over TOUCHDOWN_BLEND_S, for plots
    # and video (``shown``); None: qpos (nothing planted)
    shown_qpos: np.ndarray | None = None

    def swing_fraction(self, side: str, t: float) -> float | None:
        """Fraction of the swing of ``side`` at time t (0 toe-off, 1 heel strike), or None."""
        return self.events.swing_fraction(side, t)

    def crop(self, t0: float, t1: float) -> Playback:
        """The frames with t0 <= t <= t1, time rebased to start at 0, events kept inside."""
        sel = (self.time_s >= t0 - 1e-9) & (self.time_s <= t1 + 1e-9)
        t = self.time_s[sel] - self.time_s[sel][0]
        shift = self.time_s[sel][0]

        def keep(xs: list[float]) -> list[float]:
            return [float(x - shift) for x in xs if t0 - 1e-9 <= x <= t1 + 1e-9]

        ev = gait_events.GaitEvents({s: keep(v) for s, v in self.events.heel_strike_s.items()},
                                    {s: keep(v) for s, v in self.events.toe_off_s.items()})
        return Playback(self.body, t, self.qpos[sel], self.qvel[sel],
                        {k: v[sel] for k, v in self.coordinates.items()}, ev,
                        self.speed_m_per_s, self.stride_s, self.source, dict(self.retarget),
                        list(self.notes),
                        None if self.shown_qpos is None else self.shown_qpos[sel])

    def shown(self) -> Playback:
        """The playback as plots and video show it: ``shown_qpos`` for ``qpos`` (and the
        joint coordinates), the rest the same."""
        if self.shown_qpos is None:
            return self
        m = self.body.model
        coords = {n: self.shown_qpos[:, m.jnt_qposadr[m.joint(n).id]] for n in self.coordinates}
        return replace(self, qpos=self.shown_qpos, coordinates=coords, shown_qpos=None)

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(qpos, qvel) at time t, linearly interpolated between frames."""
        if not self.time_s[0] <= t <= self.time_s[-1]:
            raise InputError(f"time {t} s is outside the playback {self.time_s[0]}-"
                             f"{self.time_s[-1]} s")
        i = int(np.clip(np.searchsorted(self.time_s, t) - 1, 0, len(self.time_s) - 2))
        w = (t - self.time_s[i]) / (self.time_s[i + 1] - self.time_s[i])
        q = (1 - w) * self.qpos[i] + w * self.qpos[i + 1]
        if not self.body.planar:
            q[3:7] /= np.linalg.norm(q[3:7])
        return q, (1 - w) * self.qvel[i] + w * self.qvel[i + 1]


def pelvis_quaternion(tilt: np.ndarray, lst: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """(T, 4) quaternions (w, x, y, z) of the OpenSim pelvis tilt, list, rotation (rad)."""
    r = (rotation_matrix(PELVIS_ROTATIONS[0].axis, tilt)
         @ rotation_matrix(PELVIS_ROTATIONS[1].axis, lst)
         @ rotation_matrix(PELVIS_ROTATIONS[2].axis, rot))
    q = np.zeros((len(r), 4))
    for i, m in enumerate(r):
        mujoco.mju_mat2Quat(q[i], m.ravel())
    return q


def _sole_points(body: Body, qpos: np.ndarray) -> dict[str, np.ndarray]:
    """World positions (T, 96, 3) of each foot's sole points for the given qpos frames."""
    m = body.model
    d = mujoco.MjData(m)
    ids = {s: np.array([m.site(n).id for n in body.foot_points[s]]) for s in ("r", "l")}
    out = {s: np.zeros((len(qpos), len(v), 3)) for s, v in ids.items()}
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        for s, v in ids.items():
            out[s][k] = d.site_xpos[v]
    return out


def anchor_root(body: Body, qpos: np.ndarray, dt: float) -> dict[str, np.ndarray]:
    """Set the pelvis position in ``qpos`` (in place) so the feet roll on the ground.

    A foot's load falls from 1 to 0 as it rises ``LOAD_HEIGHT_M`` above the other.
    Returns the sole points (T, n, 3) per foot after placement.
    """
    planar = body.planar
    ix, iz = (0, 1) if planar else (0, 2)
    qpos[:, ix] = 0.0
    qpos[:, iz] = 0.0
    if not planar:
        qpos[:, 1] = 0.0
    pts = _sole_points(body, qpos)
    low = {s: p[:, :, 2].min(axis=1) for s, p in pts.items()}
    floor = np.minimum(low["r"], low["l"])
    qpos[:, iz] = -floor
    # horizontal: velocity of each foot's lowest material point, weighted by load
    n = len(qpos)
    vel = np.zeros((n, 2))
    wsum = np.zeros(n)
    for s, p in pts.items():
        w = np.clip(1.0 - (low[s] - floor) / LOAD_HEIGHT_M, 0.0, 1.0)
        k = p[:, :, 2].argmin(axis=1)
        idx = np.arange(n)
        nxt = np.minimum(idx + 1, n - 1)
        prv = np.maximum(idx - 1, 0)
        v = (p[nxt, k, :2] - p[prv, k, :2]) / ((nxt - prv)[:, None] * dt)
        vel += w[:, None] * v
        wsum += w
    vel /= np.maximum(wsum, 1e-9)[:, None]
    root_v = -vel
    pos = np.concatenate([[0.0, 0.0]], axis=None)
    xy = np.vstack([pos, pos + np.cumsum(0.5 * (root_v[1:] + root_v[:-1]) * dt, axis=0)])
    qpos[:, ix] = xy[:, 0]
    if not planar:
        qpos[:, 1] = xy[:, 1]
    for s in pts:
        pts[s] = pts[s] + np.stack([xy[:, 0], xy[:, 1] if not planar else 0 * xy[:, 0],
                                    -floor], axis=1)[:, None, :]
    return pts


def stance_mask(events: gait_events.GaitEvents, side: str, time_s: np.ndarray) -> np.ndarray:
    """True where ``side`` is in stance: from each heel strike to the next toe-off.

    Before the first event the state is the opposite of what that event starts.
    """
    marks = sorted([(t, True) for t in events.heel_strike_s[side]]
                   + [(t, False) for t in events.toe_off_s[side]])
    if not marks:
        return np.ones(len(time_s), dtype=bool)
    on = np.full(len(time_s), not marks[0][1])
    for t, state in marks:
        on[time_s >= t] = state
    return on


def plant_feet(body: Body, qpos: np.ndarray, events: gait_events.GaitEvents,
               time_s: np.ndarray) -> np.ndarray:
    """Keep every stance foot planted (in place): returns the leg correction (T,) in rad.

    The subject's angles on our proportions cannot keep both feet of a double stance on
    the floor without sliding (the model's legs reach differently). Each frame starts
    from the data with the previous frame's corrections, the leg corrections decaying
    with time constant ``DECAY_S``. Damped Gauss-Newton steps then move the pelvis
    (free) and, damped by ``DAMPING``, the hip flexion and knee angle (3D: and hip
    adduction) of both legs, the ankle (subtalar) undoing their effect on the foot's
    orientation, until the lowest sole point of every foot in stance is back where that
    material point was in the previous frame, on the floor. Corrections (a few degrees)
    appear in double stance and fade after it.
    """
    m = body.model
    d = mujoco.MjData(m)
    site = {s: np.array([m.site(n).id for n in body.foot_points[s]]) for s in ("r", "l")}
    on = {s: stance_mask(events, s, time_s) for s in ("r", "l")}
    root_q = [0, 1] if body.planar else [0, 1, 2]  # x, (y,) z; planar qpos 1 is z
    root_v = root_q
    rows = [0, 2] if body.planar else [0, 1, 2]
    pairs = LEG_IK_PLANAR if body.planar else LEG_IK_3D
    cols = {}  # side -> (columns of its leg joints, compensating joint per column)
    qa, va = list(root_q), list(root_v)
    comp_q, comp_v = [], []
    for side in ("r", "l"):
        cols[side] = []
        for joint, comp in pairs:
            j, c = m.joint(f"{joint}_{side}"), m.joint(f"{comp}_{side}")
            cols[side].append(len(qa))
            qa.append(int(j.qposadr[0]))
            va.append(int(j.dofadr[0]))
            comp_q.append(int(c.qposadr[0]))
            comp_v.append(int(c.dofadr[0]))
    qa, va = np.array(qa), np.array(va)
    nr = len(root_q)
    damp = np.diag([1e-9] * nr + [DAMPING] * (len(qa) - nr))
    jacp = np.zeros((3, m.nv))
    leg_cols, comp_cols = np.ix_(rows, va), np.ix_(rows, comp_v)  # built once: np.ix_ is slow
    data_q = qpos.copy()
    correction = np.zeros(len(qpos))
    dt = float(np.mean(np.diff(time_s)))
    keep = float(np.exp(-dt / DECAY_S))
    offset = np.zeros(len(qa))  # current correction: root position, then leg angles
    planted: dict[str, tuple[int, np.ndarray] | None] = {"r": None, "l": None}

    def apply(k: int, off: np.ndarray) -> np.ndarray:
        q = data_q[k].copy()
        q[qa] += off
        np.subtract.at(q, comp_q, off[nr:])  # the foot keeps its orientation
        return q

    for k in range(len(qpos)):
        if k > 0:  # the pelvis keeps its offset; the legs relax toward the data
            offset[nr:] *= keep
            offset[:nr] = qpos[k - 1, qa[:nr]] - data_q[k - 1, qa[:nr]]
        d.qpos[:] = apply(k, offset)
        mujoco.mj_kinematics(m, d)
        targets = []
        for s in ("r", "l"):
            if not on[s][k]:
                planted[s] = None
                continue
            if planted[s] is None:  # touchdown: plant the lowest point where it is
                i = int(site[s][np.argmin(d.site_xpos[site[s], 2])])
                goal = d.site_xpos[i].copy()
            else:
                i, goal = planted[s]
            targets.append((s, i, np.array([goal[0], goal[1], 0.0])))
        for _ in range(IK_ITERATIONS):
            if not targets:
                break
            mujoco.mj_comPos(m, d)
            jrows, errs = [], []
            for _s, i, goal in targets:
                mujoco.mj_jac(m, d, jacp, None, d.site_xpos[i], int(m.site_bodyid[i]))
                jac = jacp[leg_cols]
                jac[:, nr:] -= jacp[comp_cols]
                jrows.append(jac)
                errs.append((goal - d.site_xpos[i])[rows])
            jac, err = np.vstack(jrows), np.concatenate(errs)
            if np.abs(err).max() < 1e-5:
                break
            step = np.linalg.solve(jac.T @ jac + damp, jac.T @ err)
            step[nr:] = np.clip(step[nr:], -0.05, 0.05)  # rad per iteration
            offset += step
            d.qpos[:] = apply(k, offset)
            mujoco.mj_kinematics(m, d)
        for s, _i, _goal in targets:  # the lowest point now, for the next frame
            j = int(site[s][np.argmin(d.site_xpos[site[s], 2])])
            planted[s] = (j, d.site_xpos[j].copy())
        qpos[k] = d.qpos
        correction[k] = float(np.abs(offset[nr:]).max())
    return correction


def blend_touchdowns(time_s: np.ndarray, qpos: np.ndarray, correction: np.ndarray,
                     events: gait_events.GaitEvents,
                     blend_s: float = TOUCHDOWN_BLEND_S) -> np.ndarray:
    """``qpos`` with the step that planting a touching-down foot makes spread over ``blend_s``.

    ``correction`` is what ``plant_feet`` added to ``qpos`` (T, nq). At each heel strike
    (the first frame k of a stance, as ``stance_mask``) the step of the correction from
    frame k-1 to k, less the mean of its changes over the frames either side, is taken
    out and put back as a raised cosine from 0 to 1 over ``blend_s`` centred between the
    two frames. Frames outside those windows are unchanged.
    """
    out = qpos.copy()
    n = len(time_s)
    for side in ("r", "l"):
        for hs in events.heel_strike_s[side]:
            k = int(np.searchsorted(time_s, hs))  # the first frame with time_s >= hs
            if not 2 <= k <= n - 2:
                continue
            c = correction
            step = (c[k] - c[k - 1]) - 0.5 * ((c[k - 1] - c[k - 2]) + (c[k + 1] - c[k]))
            mid = 0.5 * (time_s[k - 1] + time_s[k])
            x = np.clip((time_s - (mid - 0.5 * blend_s)) / blend_s, 0.0, 1.0)
            ramp = 0.5 - 0.5 * np.cos(np.pi * x)
            after = (np.arange(n) >= k).astype(float)
            out += (ramp - after)[:, None] * step[None, :]
    return out


def smooth_positions(body: Body, qpos: np.ndarray, dt: float,
                     cutoff_hz: float = SMOOTH_CUTOFF_HZ) -> None:
    """Zero-phase low-pass (4th-order Butterworth) of pelvis position and joint angles.

    The sole is a grid of points, so a rolling foot is a rolling polygon and the planted
    pelvis path has small kinks at 200 Hz; differentiated, they would make the initial
    velocities of a physics run jitter. Velocities are therefore differentiated from
    positions low-passed at about 6 Hz, as gait kinematics customarily are (Winter
    2009, ch. 2); the positions themselves keep the planted feet exactly. The
    quaternion (already smooth) is left alone.
    """
    from scipy.signal import butter, filtfilt

    if len(qpos) < 16 or cutoff_hz >= 0.5 / dt:
        return
    b, a = butter(2, cutoff_hz * 2.0 * dt)  # filtfilt doubles the order: 4th, zero phase
    cols = list(range(2 if body.planar else 3)) + [
        int(body.model.jnt_qposadr[body.model.joint(n).id]) for n in body.joints]
    qpos[:, cols] = filtfilt(b, a, qpos[:, cols], axis=0, padtype="odd",
                             padlen=min(len(qpos) - 1, 3 * max(len(a), len(b)) * 10))


def qvel_from_qpos(body: Body, qpos: np.ndarray, dt: float) -> np.ndarray:
    """Central-difference velocities (T, nv) of a qpos trajectory (free joints handled)."""
    m = body.model
    n = len(qpos)
    qvel = np.zeros((n, m.nv))
    for k in range(n):
        a, b = max(k - 1, 0), min(k + 1, n - 1)
        mujoco.mj_differentiatePos(m, qvel[k], (b - a) * dt, qpos[a], qpos[b])
    return qvel


def build_qpos(body: Body, coords: dict[str, np.ndarray], n: int) -> np.ndarray:
    """(n, nq) qpos from coordinate arrays; joints absent from ``coords`` stay at 0."""
    m = body.model
    qpos = np.zeros((n, m.nq))
    for name in body.joints:
        if name in coords:
            qpos[:, m.jnt_qposadr[m.joint(name).id]] = coords[name]
    zero = np.zeros(n)
    tilt = coords.get("pelvis_tilt", zero)
    if body.planar:
        qpos[:, 2] = tilt
    else:
        qpos[:, 3:7] = pelvis_quaternion(tilt, coords.get("pelvis_list", zero),
                                         coords.get("pelvis_rotation", zero))
    return qpos


def play(body: Body, time_s: np.ndarray, coords: dict[str, np.ndarray], source: str,
         speed_m_per_s: float | None = None, stride_s: float | None = None,
         plant: bool = True) -> Playback:
    """Play joint-angle series on ``body``: place the pelvis, plant the feet, find events.

    Velocities are central differences of the positions low-passed at
    ``SMOOTH_CUTOFF_HZ`` (``smooth_positions``). ``plant=False`` keeps the joint angles
    exactly as given (no foot-planting corrections; the pelvis is still placed by the
    feet). When planted, ``shown_qpos`` has the step of planting a touching-down foot
    spread over ``TOUCHDOWN_BLEND_S`` (``blend_touchdowns``), for plots and video.
    """
    if len(time_s) < 2:
        raise InputError(f"{source}: {len(time_s)} sample(s); playing needs at least 2")
    dt = float(np.mean(np.diff(time_s)))
    qpos = build_qpos(body, coords, len(time_s))
    anchor_root(body, qpos, dt)
    ev = gait_events.detect(body, qpos, time_s)
    data = qpos.copy()
    lift = plant_feet(body, qpos, ev, time_s) if plant else np.zeros(len(time_s))
    smooth = qpos.copy()
    smooth_positions(body, smooth, dt)
    qvel = qvel_from_qpos(body, smooth, dt)
    if speed_m_per_s is None:
        dur = time_s[-1] - time_s[0]
        speed_m_per_s = float((qpos[-1, 0] - qpos[0, 0]) / dur)
    if stride_s is None:
        stride_s = ev.mean_stride_s()
    shown = blend_touchdowns(time_s, qpos, qpos - data, ev) if plant else None
    joint_coords = {n: qpos[:, body.model.jnt_qposadr[body.model.joint(n).id]]
                    for n in body.joints}
    return Playback(body, time_s, qpos, qvel, joint_coords, ev, speed_m_per_s, stride_s, source,
                    {"joint_correction_max_deg": round(float(np.degrees(lift.max())), 3)},
                    shown_qpos=shown)


def stride_length(body: Body, gait: ReferenceGait, hip_scale: float, stride_s: float) -> float:
    """Distance (m) the pelvis travels over one stride of the reference on this body."""
    time_s = np.arange(0.0, 3.0 * stride_s, 1.0 / SAMPLE_HZ)
    pb = play(body, time_s, gait.angles(time_s / stride_s, hip_scale=hip_scale), "")
    i, j = np.searchsorted(time_s, [stride_s, 2.0 * stride_s])
    return float((pb.qpos[j, 0] - pb.qpos[i, 0]) * stride_s / (time_s[j] - time_s[i]))


def walk(body: Body, speed_m_per_s: float | None = None, duration_s: float = 4.0,
         gait: ReferenceGait | None = None) -> Playback:
    """Play the reference gait at a speed (default: the subject's) for ``duration_s``.

    The stride length comes from the speed (``ReferenceGait.stride_length_at``); the hip
    flexion excursion is scaled (secant iterations) until the model's stride has it.
    """
    gait = gait or load_reference()
    speed = gait.speed_m_per_s if speed_m_per_s is None else float(speed_m_per_s)
    if not np.isfinite(duration_s) or duration_s <= 0 or duration_s > 600:
        raise InputError(f"duration {duration_s} s is outside 0-600 s")
    target = gait.stride_length_at(speed, body.height_m)
    stride_s = target / speed

    def err(scale: float) -> float:
        return stride_length(body, gait, scale, stride_s) - target

    s0, s1 = 1.0, 1.1
    e0, e1 = err(s0), err(s1)
    for _ in range(8):
        if abs(e1) < 2e-3 * target or e1 == e0:
            break
        s0, s1, e0 = s1, s1 - e1 * (s1 - s0) / (e1 - e0), e1
        if not 0.3 < s1 < 2.5:
            raise InputError(f"cannot reach a stride of {target:.2f} m on this body")
        e1 = err(s1)
    # one extra stride either side (the gait is periodic): no edge effects in the foot
    # planting, the event detection or the velocity filter; then crop to [0, duration]
    n0 = int(np.ceil(stride_s * SAMPLE_HZ))
    time_s = np.arange(-n0, round(duration_s * SAMPLE_HZ) + n0 + 1) / SAMPLE_HZ
    pb = play(body, time_s, gait.angles(time_s / stride_s, hip_scale=s1),
              "reference: " + gait.source, speed_m_per_s=speed, stride_s=stride_s)
    pb = pb.crop(0.0, duration_s)
    origin = pb.qpos[0, :1 if body.planar else 2].copy()  # start at x = 0 (3D: and y)
    for q in (pb.qpos, pb.shown_qpos):
        if q is not None:
            q[:, :len(origin)] -= origin
    pb.retarget["hip_flexion_scale"] = round(s1, 5)
    pb.retarget["stride_length_m"] = round(target, 5)
    return pb


def foot_slip(pb: Playback, side: str, near_m: float = 0.01) -> list[float]:
    """Horizontal slip (m) of a foot in each of its complete stances.

    The path length of the foot's lowest material point while that point is within
    ``near_m`` of the floor (rolling contact has none; sliding is the rest).
    """
    pts = _sole_points(pb.body, pb.qpos)[side]
    k = pts[:, :, 2].argmin(axis=1)
    n = len(pb.time_s)
    idx = np.arange(n - 1)
    step = np.linalg.norm(pts[idx + 1, k[:-1], :2] - pts[idx, k[:-1], :2], axis=1)
    on = pts[idx, k[:-1], 2] < near_m
    out = []
    for t_a in pb.events.heel_strike_s[side]:
        offs = [t for t in pb.events.toe_off_s[side] if t > t_a]
        if not offs:
            continue
        sel = (pb.time_s[:-1] >= t_a) & (pb.time_s[:-1] < offs[0]) & on
        out.append(float(step[sel].sum()))
    return out


def stride_phase(pb: Playback, t: float) -> float:
    """Fraction of the stride (from right heel strike) at time ``t`` (s) of a playback."""
    hs = np.asarray(pb.events.heel_strike_s["r"])
    before = hs[hs <= t]
    after = hs[hs > t]
    if len(before) and len(after):
        return float((t - before[-1]) / (after[0] - before[-1]))
    return float(((t - (before[-1] if len(before) else after[0])) / pb.stride_s) % 1.0)
