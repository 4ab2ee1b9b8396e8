"""The recorded walk the reflex network is identified from (seed 003 §III step 1).

One periodic stride of real walking on the planar model: joint angles, velocities and
accelerations, the measured ground reaction forces (GRF) with their centres of
pressure (CoP), and the joint moments from inverse dynamics. Pure functions of the
body and a sample rate; nothing is stepped.

Source: OpenSim example subject01 (Delp, Loan, Hoy, Zajac, Topp, Rosen, Thelen,
Anderson, Seth; opensim-org/opensim-models, CC BY 3.0), treadmill walking at 1.1 m/s:
planar inverse kinematics and two force plates. ``scripts/fit_planar_trial.py``
carries the figures over into ``stumble/gait/data/planar_trial.json`` (a Fourier
series per coordinate over the stride from right heel strike, the force-plate gait
events, and per foot the stance GRF in body weights and the CoP travel, 101 points).

Time base. The stride is rounded to a whole number of samples at ``rate_hz``
(1.235 s → 1235 samples at 1 kHz, a change below half a sample), so the walk is
exactly periodic on its grid: ``np.roll`` by k samples is a time shift of k/rate_hz.

Kinematics. Every angle (pelvis tilt, lumbar, hips, knees, ankles) is the subject's
Fourier series; velocities and accelerations are its analytic derivatives (smooth,
periodic, band-limited at 8 harmonics ≈ 6.5 Hz, the customary gait low-pass, Winter
2009 ch. 2), never differences. The pelvis *translation* is the subject's too:
``pelvis_ty`` and the ``pelvis_tx`` deviation from steady progression, carried from
OpenSim's pelvis origin to our pelvis origin (the hip centres) through the subject
model's hip offset and scaled by body height. Why not plant the feet as
``stumble.gait.playback`` does: its pelvis path follows the rolling contact of our
rigid de Leva foot (no toes joint, a shorter heel than the subject's shoe), whose
switches between heel, toe and the other foot put kinks in the path; as accelerations
they gave a horizontal residual of 0.9 body weights (RMS) against the measured GRF,
the subject's own pelvis motion 0.03. Planting is kept on average: the progression
speed is the one at which the material point of each foot under its CoP does not slide
(the point's forward velocity, weighted by the vertical force, averages zero), and the
height is the one at which that point lies on the floor (same weighting); how far it
strays is reported in ``RecordedWalk.info``. In this walk the model is on the floor
and not sliding to within those figures, not exactly.

GRF and CoP. The measured forward and vertical GRF, per foot, scaled by our body
weight over the subject's, act at a point of our sole: the subject's CoP relative to
the ankle (its travel from the first stance sample, which lies under the heel marker,
plus that marker's offset from the ankle in the subject01 model), scaled by our foot
length over the subject's, and clipped to the sole. Relative to the ankle rather than
from our heel, because the joint moments depend on where the force acts relative to
the joints; our heel sits 5.4 cm behind the ankle, the subject's heel marker 7.5 cm, so
the first few percent of stance (under 0.4 body weights) are clipped to our heel.

Inverse dynamics. ``mujoco.mj_inverse`` with every constraint disabled (no contacts,
no joint limits) gives ``qfrc_inverse``, the generalised force applied forces and
actuators must supply for the given qpos, qvel, qacc (gravity, the model's passive
joint damping and springs already accounted for); ``mj_applyFT`` gives the GRF's
generalised force J^T·F. Their difference is, on the joints, the moment the muscles or
servos of *this* model must supply, and on the root the residual: what the recorded
kinematics and forces leave unexplained.
"""

from __future__ import annotations

import copy
import csv
import json
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from stumble.body import Body
from stumble.errors import InputError
from stumble.gait.reference import FourierSeries

SIDES = ("r", "l")
JOINT_KEYS = {"hip": "hip_flexion", "knee": "knee_angle", "ankle": "ankle_angle"}
ROOT = ("pelvis_tx", "pelvis_ty", "pelvis_tilt")
RATE_RANGE_HZ = (50.0, 20000.0)
CSV_ROWS = 51  # issue 4: walking_moments.csv has 51 rows over the right stride


@dataclass(frozen=True)
class StanceCurves:
    """One foot's stance as measured: 101 points from heel strike to toe-off."""

    duration_s: float
    grf_forward_bw: np.ndarray  # forward GRF / subject body weight
    grf_vertical_bw: np.ndarray  # vertical GRF / subject body weight
    cop_forward_m: np.ndarray  # CoP travel (m) from the first stance sample, floor frame


@dataclass(frozen=True)
class PlanarTrial:
    """The embedded planar walking trial (``gait/data/planar_trial.json``)."""

    coordinates: dict[str, FourierSeries]  # rad; pelvis_ty m; pelvis_tx deviation m
    stride_s: float
    speed_m_per_s: float  # the subject's (belt speed plus pelvis drift)
    subject_height_m: float
    subject_mass_kg: float
    subject_foot_length_m: float  # heel to toe-tip marker
    hip_in_pelvis_m: np.ndarray  # (x forward, y up) in the subject01 pelvis frame
    heel_marker_from_ankle_m: np.ndarray  # (x forward, y up) in the foot frame
    events: dict[str, dict[str, float]]  # side -> heel_strike, toe_off (stride phase)
    stance: dict[str, StanceCurves]
    source: str
    metadata: dict = field(default_factory=dict)


@cache
def load_planar_trial() -> PlanarTrial:
    """The embedded subject01 planar trial."""
    text = resources.files("stumble.gait").joinpath("data/planar_trial.json").read_text()
    raw = json.loads(text)
    coords = {name: FourierSeries(c["a0"], np.array(c["a"]), np.array(c["b"]))
              for name, c in raw["coordinates"].items()}
    stance = {s: StanceCurves(v["duration_s"], np.array(v["grf_forward_bw"]),
                              np.array(v["grf_vertical_bw"]), np.array(v["cop_forward_m"]))
              for s, v in raw["stance"].items()}
    geo = raw["subject_model"]
    return PlanarTrial(coords, raw["stride_s"], raw["speed_m_per_s"], raw["subject_height_m"],
                       raw["subject_mass_kg"], raw["subject_foot_length_m"],
                       np.array(geo["hip_in_pelvis_m"]),
                       np.array(geo["heel_marker_from_ankle_m"]), raw["events"], stance,
                       raw["source"], raw.get("metadata", {}))


def fourier_derivatives(series: FourierSeries, time_s: np.ndarray,
                        stride_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value, first and second time derivative (units/s, units/s²) at ``time_s``."""
    k = np.arange(1, len(series.a) + 1)
    w = 2.0 * np.pi * k / stride_s  # rad/s of each harmonic
    arg = np.asarray(time_s, dtype=float)[:, None] * w
    c, s = np.cos(arg), np.sin(arg)
    x = series.a0 + (c * series.a + s * series.b).sum(-1)
    v = (w * (-s * series.a + c * series.b)).sum(-1)
    a = (-(w**2) * (c * series.a + s * series.b)).sum(-1)
    return x, v, a


@dataclass
class RecordedWalk:
    """One periodic stride from right heel strike on the planar model, sampled uniformly.

    Arrays have T = stride_s·rate_hz rows. World frame: x forward, z up; forces in N,
    positions in m, angles in rad with OpenSim signs (knee flexion negative, ankle
    dorsiflexion positive). ``moments_nm`` (keys ``hip_r``, ``knee_r``, ``ankle_r``,
    ``hip_l``, …, ``lumbar``) are the moments (N·m) the model's muscles or servos must
    supply, positive in the positive coordinate direction (hip flexor, knee extensor,
    ankle dorsiflexor, lumbar extensor); ``passive_nm`` are the model's own passive
    joint moments (damping, springs), so the net joint moment of biomechanics is their
    sum. ``residuals``: the root rows of the inverse dynamics, ``pelvis_tx`` and
    ``pelvis_ty`` as fractions of body weight, ``pelvis_tilt`` as a fraction of body
    weight × height.

    Every series is periodic on the grid (sample T is sample 0 again) except
    ``qpos[:, pelvis_tx]``, which advances by ``speed_m_per_s · stride_s`` per stride; the
    left stance straddles the end of the stride, so its CoP jumps back by that length
    there. ``info``: how the subject was carried onto this body (height and foot-length
    scales, the subject's speed) and how well the feet are planted (``cop_height_range_m``:
    height of our CoP point over stance; ``foot_slip_max_m``: largest gap between our
    CoP's path on the floor and the subject's).
    """

    body: Body
    rate_hz: float
    time_s: np.ndarray  # (T,) s, from 0 at right heel strike
    stride_s: float
    speed_m_per_s: float
    qpos: np.ndarray  # (T, nq)
    qvel: np.ndarray  # (T, nv)
    qacc: np.ndarray  # (T, nv)
    grf: dict[str, np.ndarray]  # side -> (T, 3) N, world, on the foot; 0 in swing
    cop: dict[str, np.ndarray]  # side -> (T, 3) m, world; 0 in swing
    stance: dict[str, np.ndarray]  # side -> (T,) bool
    heel_strike_s: dict[str, float]
    toe_off_s: dict[str, float]
    moments_nm: dict[str, np.ndarray]
    passive_nm: dict[str, np.ndarray]
    qfrc_joint: np.ndarray  # (T, nv) qfrc_inverse − J^T·GRF, N or N·m
    residuals: dict[str, np.ndarray]
    mass_kg: float
    body_weight_n: float
    source: str
    info: dict = field(default_factory=dict)

    @property
    def phase(self) -> np.ndarray:
        """(T,) stride phase in [0, 1), 0 at right heel strike."""
        return self.time_s / self.stride_s

    def residual_rms(self) -> dict[str, float]:
        """RMS over the stride of each root residual (fractions, see the class doc)."""
        return {k: float(np.sqrt(np.mean(v**2))) for k, v in self.residuals.items()}

    def at_percent(self, values: np.ndarray, percent: np.ndarray) -> np.ndarray:
        """A (T,) series of this walk at stride percentages (periodic linear interpolation)."""
        t = np.asarray(percent, dtype=float) / 100.0 * self.stride_s
        return np.interp(t, self.time_s, values, period=self.stride_s)


def _foot_sole(model: mujoco.MjModel, side: str) -> tuple[float, float, float]:
    """(heel x, toe-tip x, sole z) of a foot in its body frame, m, from its geom box."""
    g = model.geom(f"foot_{side}_geom")
    (cx, _, cz), (hx, _, hz) = g.pos, g.size
    return float(cx - hx), float(cx + hx), float(cz - hz)


def _slip(points: np.ndarray, grid: np.ndarray, travel: np.ndarray, scale: float) -> float:
    """Largest gap (m) between our CoP's path on the floor and the subject's (scaled).

    ``points``: (stance fraction, world x) of our CoP over one stance. Zero if our foot
    rolled on the floor exactly as the subject's did.
    """
    order = np.argsort(points[:, 0])
    u, x = points[order, 0], points[order, 1]
    gap = (x - x[0]) - scale * (np.interp(u, grid, travel) - np.interp(u[0], grid, travel))
    return round(float(np.abs(gap).max()), 4)


def _check(body: Body, rate_hz: float) -> None:
    if not body.planar:
        raise InputError("the recorded walk is for the planar model: build(planar=True)")
    lo, hi = RATE_RANGE_HZ
    if not np.isfinite(rate_hz) or not lo <= rate_hz <= hi:
        raise InputError(f"rate {rate_hz} Hz is outside {lo:g}-{hi:g} Hz")
    names = {body.model.joint(j).name for j in range(body.model.njnt)}
    missing = [n for n in (*ROOT, "lumbar_extension",
                           *(f"{j}_{s}" for j in JOINT_KEYS.values() for s in SIDES))
               if n not in names]
    if missing:
        raise InputError(f"the body has no joint {', '.join(missing)}")


def recorded_walk(body: Body, rate_hz: float = 1000.0) -> RecordedWalk:
    """The subject01 stride on ``body`` (planar), sampled at ``rate_hz`` (Hz).

    See the module docstring for the kinematics, the force placement and the inverse
    dynamics. The body's actuators are ignored (zero control).
    """
    _check(body, rate_hz)
    trial = load_planar_trial()
    m = copy.deepcopy(body.model)  # the caller's model keeps its flags
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    d = mujoco.MjData(m)
    n = round(trial.stride_s * rate_hz)
    stride = n / rate_hz
    t = np.arange(n) / rate_hz
    qpos, qvel, qacc = np.zeros((n, m.nq)), np.zeros((n, m.nv)), np.zeros((n, m.nv))

    def column(name: str) -> tuple[int, int]:
        j = m.joint(name)
        return int(j.qposadr[0]), int(j.dofadr[0])

    for name, series in trial.coordinates.items():
        if name in ("pelvis_tx", "pelvis_ty"):
            continue
        iq, iv = column(name)
        qpos[:, iq], qvel[:, iv], qacc[:, iv] = fourier_derivatives(series, t, stride)

    # pelvis translation: the subject's, moved from OpenSim's pelvis origin to the hip
    # centres (ours), scaled by height; offsets of mean speed and height come later
    scale = body.height_m / trial.subject_height_m
    tilt, tilt_v, tilt_a = fourier_derivatives(trial.coordinates["pelvis_tilt"], t, stride)
    ox, oy = trial.hip_in_pelvis_m
    c, s = np.cos(tilt), np.sin(tilt)
    hip = (ox * c - oy * s, ox * s + oy * c)  # hip offset in the world (x, z)
    dhip = (-hip[1], hip[0])  # d(hip)/d(tilt)
    for k, name in enumerate(("pelvis_tx", "pelvis_ty")):
        x, v, a = fourier_derivatives(trial.coordinates[name], t, stride)
        iq, iv = column(name)
        qpos[:, iq] = scale * (x + hip[k])
        qvel[:, iv] = scale * (v + dhip[k] * tilt_v)
        qacc[:, iv] = scale * (a + dhip[k] * tilt_a - hip[k] * tilt_v**2)
    iz = column("pelvis_ty")[0]
    qpos[:, iz] -= qpos[:, iz].mean()

    # measured forces on our body
    mass = float(m.body_subtreemass[0])
    weight = mass * float(np.linalg.norm(m.opt.gravity))
    phase = t / stride
    grid = np.linspace(0.0, 1.0, len(trial.stance["r"].grf_vertical_bw))
    foot_ids = {sd: m.body(f"foot_{sd}").id for sd in SIDES}
    sole = {sd: _foot_sole(m, sd) for sd in SIDES}
    ours_over_theirs = (sole["r"][1] - sole["r"][0]) / trial.subject_foot_length_m
    stance, force, local, stance_u = {}, {}, {}, {}
    hs_s, to_s = {}, {}
    for sd in SIDES:
        curves = trial.stance[sd]
        hs = trial.events[sd]["heel_strike"]
        frac = curves.duration_s / trial.stride_s
        u = ((phase - hs) % 1.0) / frac  # 0..1 over stance
        on = u <= 1.0
        stance_u[sd] = u
        stance[sd] = on
        hs_s[sd] = hs * stride
        to_s[sd] = ((hs + frac) % 1.0) * stride
        f = np.zeros((n, 3))
        f[on, 0] = np.interp(u[on], grid, curves.grf_forward_bw) * weight
        f[on, 2] = np.interp(u[on], grid, curves.grf_vertical_bw) * weight
        force[sd] = f
        travel = np.interp(u, grid, curves.cop_forward_m)
        from_ankle = ours_over_theirs * (travel + trial.heel_marker_from_ankle_m[0])
        heel, toe, z = sole[sd]
        local[sd] = np.stack([np.clip(from_ankle, heel, toe), np.zeros(n), np.full(n, z)], 1)

    # plant on average: the sole point under the CoP neither slides nor floats
    jacp = np.zeros((3, m.nv))
    slip_v, height, wsum = 0.0, 0.0, 0.0
    for k in range(n):
        d.qpos[:] = qpos[k]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        for sd in SIDES:
            if not stance[sd][k]:
                continue
            b = foot_ids[sd]
            p = d.xpos[b] + d.xmat[b].reshape(3, 3) @ local[sd][k]
            mujoco.mj_jac(m, d, jacp, None, p, b)
            w = force[sd][k, 2]
            slip_v += w * float(jacp[0] @ qvel[k])
            height += w * p[2]
            wsum += w
    speed = -slip_v / wsum
    ix, iv_x = column("pelvis_tx")
    qpos[:, ix] += speed * t
    qvel[:, iv_x] += speed
    qpos[:, iz] -= height / wsum

    # inverse dynamics
    qfrc = np.zeros((n, m.nv))
    passive = np.zeros((n, m.nv))
    cop = {sd: np.zeros((n, 3)) for sd in SIDES}
    point_x = {sd: [] for sd in SIDES}  # (stance fraction, world x unwrapped)
    point_z = {sd: [] for sd in SIDES}
    grf_q = np.zeros(m.nv)
    zero3 = np.zeros(3)
    for k in range(n):
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos[k], qvel[k], qacc[k]
        mujoco.mj_inverse(m, d)
        grf_q[:] = 0.0
        for sd in SIDES:
            if not stance[sd][k]:
                continue
            b = foot_ids[sd]
            p = d.xpos[b] + d.xmat[b].reshape(3, 3) @ local[sd][k]
            cop[sd][k] = p
            mujoco.mj_applyFT(m, d, force[sd][k], zero3, p, b, grf_q)
            wrap = stride * speed if phase[k] < hs_s[sd] / stride else 0.0
            point_x[sd].append((float(stance_u[sd][k]), float(p[0]) + wrap))
            point_z[sd].append(float(p[2]))
        qfrc[k] = d.qfrc_inverse - grf_q
        passive[k] = d.qfrc_passive
    if not np.all(np.isfinite(qfrc)):
        raise InputError("inverse dynamics of the recorded walk is not finite on this body")

    moments, pas = {}, {}
    for sd in SIDES:
        for key, joint in JOINT_KEYS.items():
            iv = column(f"{joint}_{sd}")[1]
            moments[f"{key}_{sd}"] = qfrc[:, iv].copy()
            pas[f"{key}_{sd}"] = passive[:, iv].copy()
    iv = column("lumbar_extension")[1]
    moments["lumbar"], pas["lumbar"] = qfrc[:, iv].copy(), passive[:, iv].copy()
    root = [column(r)[1] for r in ROOT]
    residuals = {"pelvis_tx": qfrc[:, root[0]] / weight, "pelvis_ty": qfrc[:, root[1]] / weight,
                 "pelvis_tilt": qfrc[:, root[2]] / (weight * body.height_m)}
    info = {
        "subject_speed_m_per_s": trial.speed_m_per_s,
        "height_scale": round(scale, 5),
        "foot_length_scale": round(ours_over_theirs, 5),
        "stride_rounded_by_s": round(stride - trial.stride_s, 6),
        # how well the feet are planted: the sole point under the CoP in stance
        "cop_height_range_m": {sd: [round(min(z), 4), round(max(z), 4)]
                               for sd, z in point_z.items()},
        "foot_slip_max_m": {sd: _slip(np.array(v), grid, trial.stance[sd].cop_forward_m,
                                      ours_over_theirs) for sd, v in point_x.items()},
    }
    return RecordedWalk(body, float(rate_hz), t, stride, float(speed), qpos, qvel, qacc, force,
                        cop, stance, hs_s, to_s, moments, pas, qfrc, residuals, mass, weight,
                        trial.source, info)


def write_moments_csv(walk: RecordedWalk, path: str | Path) -> Path:
    """Right-leg joint moments over the stride: ``percent`` 0, 2, …, 100 (51 rows).

    Columns ``percent``, ``hip_moment_nm``, ``knee_moment_nm``, ``ankle_moment_nm``: the
    ``moments_nm`` of the walk (N·m, OpenSim signs: hip flexor, knee extensor, ankle
    dorsiflexor positive), from right heel strike; 100 % is the next right heel strike.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    percent = np.linspace(0.0, 100.0, CSV_ROWS)
    cols = {f"{k}_moment_nm": walk.at_percent(walk.moments_nm[f"{k}_r"], percent)
            for k in ("hip", "knee", "ankle")}
    with path.open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["percent", *cols])
        for i, p in enumerate(percent):
            out.writerow([f"{p:g}", *(f"{v[i]:.4f}" for v in cols.values())])
    return path
