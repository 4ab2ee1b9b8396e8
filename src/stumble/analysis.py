"""Outcome and metrics of a trip, from the recording (any controller).

- ``fell``: a body other than the feet touches the floor, or the pelvis drops below
  ``FALL_PELVIS_FRACTION`` of its standing height.
- ``recovered``: the recovery step has landed, the person has not fallen for
  ``RECOVERED_AFTER_S`` after it, and then (at the first instant from there on, where
  the run stops) the trunk is within ``UPRIGHT_DEG`` of vertical and the COM's ground
  projection is over the base of support (the feet on the floor, grown by
  ``BOS_MARGIN_M``); or, walking on (``StopRule.walk_on_s``), still walking at the
  verdict and, after an obstacle trip, past the obstacle.
- ``diverged``: the physics blew up (NaN, or MuJoCo's bad-acceleration warning).

The recovery step is the tripped leg's landing (elevating) or the other leg's landing
after it has left the floor (lowering). Metrics follow SCA 2009 §5: the duration of the
recovery step (toe-off to heel contact, elevating) or from the trip to the recovery
leg's contact (lowering), the step length, the trunk tilt at recovery-foot contact,
and the joint-pitch RMSE against a reference motion (Table 2's joints).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import mujoco
import numpy as np

from stumble.sim import Recording, Sensors, fallen
from stumble.trip import MUSCLE_CONTROLLERS, Scenario, posed

FALL_PELVIS_FRACTION = 0.55  # pelvis below 55 % of standing hip height: sitting, kneeling
RECOVERED_AFTER_S = 1.0  # the issue: no fall for 1 s after the recovery step lands
WALK_ON_S = 3.0  # reflex controllers: recovered = still walking this long after the trip
WALKING_MIN_M_PER_S = 0.5  # "walking": the COM advanced at least this fast over the last s
UPRIGHT_DEG = 35.0  # trunk tilt from vertical still called upright (ours)
BOS_MARGIN_M = 0.05  # base of support grown by this (ours)
SIDES = ("r", "l")
NOT_PAST = "not past the obstacle"  # the stop reason of a walk on that did not pass the box
# the stop reason of a state-machine walk on that was still walking at the end of its
# time, but had taken fewer than WALK_ON_STEPS steps after the recovery step
TOO_FEW_STEPS = "too few steps"
TOUCHDOWN_SAMPLES = 3  # a touch-down lasts this many recorded samples (15 ms), not a scuff
MIN_AIRBORNE_S = 0.1  # the recovery foot was in the air this long before it lands: a
# touch right after the trip is the trip's own scuff (ours)


def fall_height_m(model: mujoco.MjModel) -> float:
    """The pelvis height (m) below which the body has fallen: ``FALL_PELVIS_FRACTION`` of
    its height standing at the zero pose."""
    return FALL_PELVIS_FRACTION * float(model.body("pelvis").pos[2])


def trunk_tilt_deg(model: mujoco.MjModel, xmat: np.ndarray) -> float:
    """Angle (deg) between the torso's long axis and the vertical."""
    z = xmat[model.body("torso").id].reshape(3, 3)[:, 2]
    return float(np.degrees(np.arccos(np.clip(z[2], -1.0, 1.0))))


def tilt_of(torso_z: np.ndarray) -> float:
    """Angle (deg) between the torso's long axis (a world unit vector) and the vertical."""
    return float(np.degrees(np.arccos(np.clip(torso_z[2], -1.0, 1.0))))


def com_over_base(s: Sensors) -> bool:
    """COM ground projection inside the feet-on-floor footprint (the sole corners'
    bounding box), grown by a margin."""
    on = [k for k, side in enumerate(SIDES) if s.foot_on_floor[side]]
    if not on:
        return False
    p = s.sole[on].reshape(-1, 3)[:, :2]
    lo, hi = p.min(axis=0) - BOS_MARGIN_M, p.max(axis=0) + BOS_MARGIN_M
    return bool(np.all(s.com[:2] >= lo) and np.all(s.com[:2] <= hi))


_BULK_MIN = 8  # samples worth NumPy's overhead (``StopRule.block``)


@dataclass
class StopRule:
    """Stops a run at a fall, or once the person has recovered (see module docstring).

    ``strategy`` None: the controller was not told a strategy (the reflex network), and
    ``classified`` names the one that emerged, from the motion alone (seed 003 §V.B):
    elevating if the tripped foot's next floor contact (lasting 15 ms) is beyond the
    obstacle's far face ``far_x`` (it passed over), lowering if it touches down short of
    it; the recovery step is then the other leg's next landing.

    ``walk_on_s`` (the reflex controllers, which walk on by themselves): recovered
    means still walking that long after the trip: not fallen, upright, and the COM
    advancing at ``WALKING_MIN_M_PER_S`` or more over the last second; with ``past_x``
    (obstacle trips, since 2026-12-07) also both ankles past the box's far face. A body
    that stepped onto the box, went back and walks into it again at the verdict is
    "still walking" but has not got past what tripped it ("not past the obstacle").
    """

    strategy: str | None
    tripped: str
    fall_height_m: float
    far_x: float | None = None  # m, far face of the obstacle (emergent strategy only)
    landing_s: float | None = None
    fell_s: float | None = None
    recovered_s: float | None = None
    classified: str | None = None
    tripped_down_x: float | None = None  # m, heel x of the tripped foot's next contact
    tripped_down_s: float | None = None  # s, when it touched down
    _other_left: bool = False
    _down: int = 0
    _down_s: float = 0.0
    _down_x: float = 0.0
    _airborne_since: float | None = 0.0  # the swing foot is in the air at the trip
    walk_on_s: float | None = None
    past_x: float | None = None  # m, obstacle trips: the box's far face (see _walking_on)
    _com_x: list = field(default_factory=list)

    @property
    def quiet_until_s(self) -> float | None:
        """Before this time only a fall stops the run (``walk_on_s``: recovered is
        judged then), or None (a landing may end it at any time)."""
        return self.walk_on_s

    def block(self, lay, rows: np.ndarray, t: np.ndarray) -> tuple[int, str]:
        """The rule over samples in order (sensor ``rows``, times ``t``, s): the index
        of the one that stops the run and why, or (len(t), ""). The same verdicts and
        state as calling it on each; a stretch after the landing and before
        ``walk_on_s``, where only a fall can stop it, in bulk."""
        s, n, j = Sensors(), len(t), 0
        while j < n:
            if (self.walk_on_s is not None and self.landing_s is not None
                    and n - j >= _BULK_MIN):
                quiet = t[j:] < self.walk_on_s - 1e-9
                m = len(quiet) if quiet.all() else int(quiet.argmin())
                if m:
                    fall = fallen(lay, rows[j:j + m], self.fall_height_m)
                    f = int(fall.argmax()) if fall.any() else m
                    com_x = rows[j:j + f, lay.decode_index[7]]  # (``Sensors.com``'s x)
                    self._com_x += zip(t[j:j + f].tolist(), com_x.tolist(), strict=True)
                    if f < m:
                        self.fell_s = float(t[j + f])
                        return j + f, "fell"
                    j += m
                    continue
            why = self(s.set(lay, rows[j], float(t[j])))
            if why:
                return j, why
            j += 1
        return n, ""

    def __call__(self, s: Sensors) -> str:
        if s.segment_on_floor or s.pelvis_height < self.fall_height_m:
            self.fell_s = s.t
            return "fell"
        if self.walk_on_s is not None:
            return self._walking_on(s)
        if self.landing_s is None:
            self.landing_s = self._landing(s)
        elif s.t - self.landing_s >= RECOVERED_AFTER_S:
            if tilt_of(s.torso_z) < UPRIGHT_DEG and com_over_base(s):
                self.recovered_s = s.t
                return "recovered"
        return ""

    def _walking_on(self, s: Sensors) -> str:
        """Recovered once still walking ``walk_on_s`` after the trip (class docstring)
        and, with ``past_x``, with both ankles past the obstacle: a body that went back
        from the box and walks into it again has not recovered ("not past the
        obstacle")."""
        if self.landing_s is None:
            self.landing_s = self._landing(s)
        self._com_x.append((s.t, float(s.com[0])))
        if s.t < self.walk_on_s - 1e-9:  # (time summed step by step: 1500 × 2 ms < 3 s)
            return ""
        t_back = s.t - 1.0
        x_back = next(x for t, x in self._com_x if t >= t_back - 1e-9)
        if (tilt_of(s.torso_z) < UPRIGHT_DEG
                and s.com[0] - x_back >= WALKING_MIN_M_PER_S * 1.0):
            if self.past_x is not None and float(s.foot_pos[:, 0].min()) <= self.past_x:
                return NOT_PAST
            self.recovered_s = s.t
            return "recovered"
        return "stopped walking"

    def _landing(self, s: Sensors) -> float | None:
        """The recovery foot touches the floor in front of the other foot."""
        if self.strategy is None:
            return self._emergent_landing(s)
        rec = self.tripped if self.strategy == "elevating" else OTHER[self.tripped]
        return self._recovery_step(s, rec, need_left=self.strategy != "elevating")

    def _recovery_step(self, s: Sensors, rec: str, need_left: bool) -> float | None:
        """When ``rec`` lands ahead of the other foot: a touch-down of at least 15 ms
        after at least 0.1 s in the air (and, ``need_left``, after leaving the floor
        since the trip); the time returned is the contact's start."""
        if not s.foot_on_floor[rec]:
            self._other_left = True
            self._airborne_since = (s.t if self._airborne_since is None
                                    else self._airborne_since)
            self._down = 0
            return None
        i = SIDES.index(rec)
        ahead = s.foot_pos[i, 0] > s.foot_pos[1 - i, 0]
        flew = (self._airborne_since is not None
                and s.t - self._airborne_since >= MIN_AIRBORNE_S)
        if ahead and s.t > 0.02 and flew and (not need_left or self._other_left):
            self._down += 1
            if self._down == 1:
                self._down_s = s.t
            if self._down >= TOUCHDOWN_SAMPLES:  # a step, not a scuff: the contact's start
                return self._down_s
        else:
            self._down = 0
            self._airborne_since = None
        return None

    def _emergent_landing(self, s: Sensors) -> float | None:
        trip, other = self.tripped, OTHER[self.tripped]
        if self.classified is not None:  # lowering: the other leg's recovery step
            return self._recovery_step(s, other, need_left=True)
        if not (s.foot_on_floor[trip] and s.t > 0.02):
            self._down = 0
            return None
        if self._down == 0:  # where and when the contact starts
            self._down_s = s.t
            self._down_x = float(s.sole[SIDES.index(trip), :, 0].min())
        self._down += 1
        if self._down < TOUCHDOWN_SAMPLES:
            return None
        self.tripped_down_x, self.tripped_down_s = self._down_x, self._down_s
        if self._down_x > self.far_x:
            self.classified = "elevating"
            return self._down_s
        self.classified = "lowering"
        self._down, self._airborne_since, self._other_left = 0, None, False
        return None


OTHER = {"r": "l", "l": "r"}


# variant: the recovery foot lands from the air when both feet were off the floor for at
# least this long right before it (ours: five 4 ms samples, so that a foot lifting in the
# instant of the landing is not a flight)
FLIGHT_MIN_S = 0.02
TAKEOVER_S = 0.02  # the first samples after the trip, where a stance foot may flicker off


def variant(rec: Recording, landing_s: float | None) -> str | None:
    """``flight`` if the recovery foot lands from the air (both feet off the floor for the
    ``FLIGHT_MIN_S`` before its landing), else ``double_support`` (the other foot is on
    the floor when it lands, even after a hop of it before); None without a landing.
    SCA 2009 §3: "a flight phase or double support phase might occur followed by
    touchdown on the ground with the non-tripped leg"; their controllers' Flight state
    is left when that foot lands (§4.5). Until 2026-12-07 a hop of the push-off foot
    that landed again before the recovery foot counted as a flight (see
    ``airborne_before_landing_s``)."""
    if landing_s is None:
        return None
    t = rec.time_s
    airborne = ~rec.foot_on_floor[:, 0] & ~rec.foot_on_floor[:, 1]
    start, end = np.searchsorted(t, [landing_s - FLIGHT_MIN_S - 1e-9, landing_s - 1e-9])
    return "flight" if end > start and bool(airborne[start:end].all()) else "double_support"


def airborne_before_landing_s(rec: Recording, landing_s: float | None) -> float | None:
    """Seconds with both feet off the floor from the trip (after ``TAKEOVER_S``) to the
    recovery landing: a flight's, or a hop's of the push-off foot that lands again
    first; None without a landing."""
    if landing_s is None or len(rec.time_s) < 2:
        return None
    t = rec.time_s
    airborne = (~rec.foot_on_floor[:, 0] & ~rec.foot_on_floor[:, 1]
                & (t > TAKEOVER_S + 1e-9) & (t < landing_s - 1e-9))
    return round(float(airborne.sum() * np.median(np.diff(t))), 4)


def pitch_angles_deg(model: mujoco.MjModel, qpos: np.ndarray, tripped: str,
                     strategy: str) -> dict[str, np.ndarray]:
    """SCA 2009 Table 2's joint pitches (deg): pelvis, leading/trailing hip, knee, ankle.

    The leading leg is the recovery leg (elevating: the tripped leg; lowering: the other).
    """
    lead = tripped if strategy == "elevating" else OTHER[tripped]
    trail = OTHER[lead]
    out = {}
    if qpos.shape[1] == model.nq and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE:
        w, x, y, z = qpos[:, 3], qpos[:, 4], qpos[:, 5], qpos[:, 6]
        # pitch about -y (OpenSim tilt): the z axis' lean in the x-z plane
        zx = 2 * (x * z + w * y)
        zz = 1 - 2 * (x * x + y * y)
        out["pelvis"] = np.degrees(np.arctan2(-zx, zz))
    else:
        out["pelvis"] = np.degrees(qpos[:, 2])
    for label, side in (("lead", lead), ("trail", trail)):
        for joint in ("hip_flexion", "knee_angle", "ankle_angle"):
            adr = model.jnt_qposadr[model.joint(f"{joint}_{side}").id]
            out[f"{label}_{joint.split('_')[0]}"] = np.degrees(qpos[:, adr])
    return out


def table2_from_coordinates(coords: dict[str, np.ndarray], tripped: str,
                            strategy: str) -> dict[str, np.ndarray]:
    """SCA 2009 Table 2 pitches (deg) from coordinate series named as our model."""
    lead = tripped if strategy == "elevating" else OTHER[tripped]
    names = {"pelvis": "pelvis_tilt"}
    for label, side in (("lead", lead), ("trail", OTHER[lead])):
        for joint in ("hip_flexion", "knee_angle", "ankle_angle"):
            names[f"{label}_{joint.split('_')[0]}"] = f"{joint}_{side}"
    return {k: np.asarray(coords[c]) for k, c in names.items() if c in coords}


def rmse_deg(sim: dict[str, np.ndarray], sim_t: np.ndarray, ref: dict[str, np.ndarray],
             ref_t: np.ndarray) -> dict[str, float]:
    """RMSE (deg) per Table 2 joint over the overlap of two time series (t = 0 the trip)."""
    t_end = min(sim_t[-1], ref_t[-1])
    sel = (sim_t >= ref_t[0]) & (sim_t <= t_end)
    out = {}
    for k, v in sim.items():
        if k in ref and sel.any():
            r = np.interp(sim_t[sel], ref_t, ref[k])
            out[k] = float(np.sqrt(np.mean((v[sel] - r) ** 2)))
    return out


# ---- walking under a controller ------------------------------------------------------

WALK_JOINTS = ("hip_flexion", "knee_angle", "ankle_angle")
CYCLE_POINTS = 101  # a stride resampled to 0, 1, … 100 % (from heel strike)
# the planar foot's angle in the sagittal plane (rad, toe up +, 0 standing): the sum of
# the chain's pitch angles from the pelvis down (every planar hinge turns about one axis)
FOOT_CHAIN = ("pelvis_tilt", "hip_flexion", "knee_angle", "ankle_angle")


def foot_angles(qpos: np.ndarray, model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """``foot_angle_<side>`` of the planar model per row of ``qpos`` (rad, toe up +):
    what an obstacle meets first, toe or heel, depends on it."""
    adr = model.jnt_qposadr
    return {f"foot_angle_{s}": sum(qpos[..., adr[model.joint(
        j if j == "pelvis_tilt" else f"{j}_{s}").id]] for j in FOOT_CHAIN) for s in SIDES}


TRUNK_CHAIN = ("pelvis_tilt", "lumbar_extension")  # the planar torso's pitch, summed


def trunk_lean(qpos: np.ndarray, model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """``trunk_lean`` of the planar model per row of ``qpos`` (rad, forward +): the torso
    frame's pitch from vertical, −(pelvis tilt + lumbar extension), which is also the
    angle of its long axis (the ``torso_z`` sensor) in the sagittal plane. The recorded
    walk (subject01 on our body) leans 12–16° by it, 14° on average."""
    adr = model.jnt_qposadr
    return {"trunk_lean": -sum(qpos[..., adr[model.joint(j).id]] for j in TRUNK_CHAIN)}


@dataclass
class WalkStop:
    """Stops a walk at a fall (a segment on the floor, or the pelvis below
    ``fall_height_m``)."""

    fall_height_m: float
    fell_s: float | None = None
    quiet_until_s = float("inf")  # nothing but a fall stops a walk

    def block(self, lay, rows: np.ndarray, t: np.ndarray) -> tuple[int, str]:
        """The rule over samples (``StopRule.block``), in bulk."""
        if len(t) < _BULK_MIN:
            s = Sensors()
            for j in range(len(t)):
                if self(s.set(lay, rows[j], float(t[j]))):
                    return j, "fell"
            return len(t), ""
        fall = fallen(lay, rows, self.fall_height_m)
        if not fall.any():
            return len(t), ""
        f = int(fall.argmax())
        self.fell_s = float(t[f])
        return f, "fell"

    def __call__(self, s: Sensors) -> str:
        if s.segment_on_floor or s.pelvis_height < self.fall_height_m:
            self.fell_s = s.t
            return "fell"
        return ""


@dataclass
class TripTimer:
    """Stops a walk at the instant to trip it in its own gait: ``swing_fraction`` of the
    ``side`` leg's first swing that starts after ``after_s``, that swing's duration taken
    as the mean of the leg's last two (its toe-off to its heel strike, by floor load); or
    at a fall (``fall_height_m``, as ``WalkStop``). As ``contact_events`` reads them, a
    landing is a touch lasting ``TOUCHDOWN_SAMPLES`` samples (a shorter one is a brush
    of the swinging foot, and the swing goes on), dated from its first sample; swings
    shorter than ``MIN_AIRBORNE_S`` are scuffs and not counted."""

    side: str
    swing_fraction: float
    after_s: float
    fall_height_m: float
    fell_s: float | None = None
    swings_s: list = field(default_factory=list)
    toe_off_s: float | None = None  # the present swing's toe-off
    trip_swing_s: float | None = None  # the swing duration the trip instant used
    _landed: bool | None = None  # the foot in stance (a lasting touch since its toe-off)
    _down: int = 0  # samples the foot has been on the floor without a break
    _down_since: float = 0.0

    _on: bool | None = None  # the foot on the floor at the last sample

    @property
    def quiet_until_s(self) -> float:
        """Before this time only a fall stops the walk while the foot's floor contact
        stays as at the last sample (``watch_foot``): never while it is on the floor
        (a trip comes in swing, after a toe-off), ``toe_off_s`` + the trip's share of
        the swing in a swing that counts, never in one that does not; before ``after_s``
        in any case, and nothing is known before the first sample."""
        if self._on is None:
            return 0.0
        if (not self._on and self.toe_off_s is not None and self.toe_off_s >= self.after_s
                and self.swings_s):
            return max(self.after_s, self.toe_off_s + self.swing_fraction
                       * float(np.mean(self.swings_s[-2:])))
        return np.inf

    @property
    def watch_foot(self) -> tuple[int, bool] | None:
        """The foot whose floor contact ``quiet_until_s`` holds for (0 right, 1 left),
        and that contact at the last sample."""
        return None if self._on is None else (SIDES.index(self.side), self._on)

    def __call__(self, s: Sensors) -> str:
        if s.segment_on_floor or s.pelvis_height < self.fall_height_m:
            self.fell_s = s.t
            return "fell"
        on = s.foot_on_floor[self.side]
        self._on = on
        if self._landed is None:  # the first sample: a foot on the floor is in stance
            self._landed = on
        if on:
            if self._down == 0:
                self._down_since = s.t
            self._down += 1
            if self._down >= TOUCHDOWN_SAMPLES and not self._landed:
                self._landed = True
                if (self.toe_off_s is not None
                        and self._down_since - self.toe_off_s >= MIN_AIRBORNE_S):
                    self.swings_s.append(self._down_since - self.toe_off_s)
                self.toe_off_s = None
        else:
            if self._landed:
                self.toe_off_s = s.t
                self._landed = False
            self._down = 0
        if (not on and self.toe_off_s is not None and self.toe_off_s >= self.after_s
                and self.swings_s):
            swing = float(np.mean(self.swings_s[-2:]))
            if s.t >= self.toe_off_s + self.swing_fraction * swing:
                self.trip_swing_s = swing
                return "trip"
        return ""


def contact_events(time_s: np.ndarray, on_floor: np.ndarray) -> dict[str, dict[str, list]]:
    """Heel strikes and toe-offs (s) per side from the feet's floor contact (T, 2), as
    force plates would see them: contacts lasting at least ``TOUCHDOWN_SAMPLES`` samples,
    separated by at least ``MIN_AIRBORNE_S`` in the air (shorter gaps are scuffs, shorter
    touches are brushes); the contact a run starts in has no strike."""
    out = {}
    for k, side in enumerate(SIDES):
        c = np.concatenate([[False], on_floor[:, k].astype(bool), [False]])
        starts = np.flatnonzero(c[1:] & ~c[:-1])
        ends = np.flatnonzero(~c[1:] & c[:-1])  # index of the first sample off the floor
        keep = ends - starts >= TOUCHDOWN_SAMPLES
        starts, ends = starts[keep], ends[keep]
        hs, to = [], []
        for i in range(len(starts)):
            if i + 1 < len(starts):
                gap = time_s[starts[i + 1]] - time_s[min(ends[i], len(time_s) - 1)]
                if gap >= MIN_AIRBORNE_S:
                    to.append(float(time_s[ends[i]]))
                    hs.append(float(time_s[starts[i + 1]]))
            elif ends[i] < len(time_s) and time_s[-1] - time_s[ends[i]] >= MIN_AIRBORNE_S:
                to.append(float(time_s[ends[i]]))
        if len(starts) and starts[0] > 0 and (time_s[starts[0]] - time_s[0]) >= MIN_AIRBORNE_S:
            hs.insert(0, float(time_s[starts[0]]))  # the run started in the air
        out[side] = {"heel_strike_s": hs, "toe_off_s": to}
    return out


def stride_curves(time_s: np.ndarray, angles: dict[str, np.ndarray],
                  strikes: list[float]) -> dict[str, np.ndarray]:
    """Each series resampled over every stride between consecutive ``strikes``:
    (n_strides, 101) per name."""
    pct = np.linspace(0.0, 1.0, CYCLE_POINTS)
    out = {}
    for name, series in angles.items():
        rows = [np.interp(a + pct * (b - a), time_s, series)
                for a, b in itertools.pairwise(strikes)]
        out[name] = np.array(rows).reshape(len(rows), CYCLE_POINTS)
    return out


def reference_stride(pb) -> dict[str, np.ndarray]:
    """The played-back walk's mean right stride (a ``stumble.gait.playback.Playback``),
    101 points per leg joint and, on the planar body, per foot's angle (``foot_angles``)
    and the trunk's lean (``trunk_lean``; rad): what a reflex walk's RMSE is taken
    against."""
    names = [f"{j}_{s}" for j in WALK_JOINTS for s in SIDES]
    series = {n: pb.coordinates[n] for n in names}
    if pb.body.planar:
        series.update(foot_angles(pb.qpos, pb.body.model))
        series.update(trunk_lean(pb.qpos, pb.body.model))
    curves = stride_curves(pb.time_s, series, list(pb.events.heel_strike_s["r"]))
    return {n: c.mean(axis=0) for n, c in curves.items()}


def walk_metrics(rec: Recording, model: mujoco.MjModel, reference: dict[str, np.ndarray],
                 duration_s: float) -> dict:
    """The figures of a walk: time walked, fall, strides, speed, stance fraction and the
    joint-angle RMSE (deg) of every complete right stride against ``reference`` (the
    recorded stride, 101 points per ``<joint>_<side>``, rad), averaged over strides;
    where ``reference`` has ``foot_angle_<side>`` (``foot_angles``), the foot's angle
    RMSE (deg) too, averaged over both feet; ``stride_s``, the mean right stride (s);
    ``knee_hyperextension_deg``, the knees' mean extension beyond straight (deg); where
    ``reference`` has ``trunk_lean`` (``trunk_lean``), the trunk's RMSE (deg) against it
    and its mean forward lean and range over the strides (deg)."""
    t = rec.time_s
    ev = contact_events(t, rec.foot_on_floor)
    hs = ev["r"]["heel_strike_s"]
    strides = max(0, len(hs) - 1)
    x = rec.qpos[:, 0]
    if strides >= 1:
        span = hs[-1] - hs[0]
        speed = (np.interp(hs[-1], t, x) - np.interp(hs[0], t, x)) / span
    else:
        speed = (x[-1] - x[0]) / max(t[-1] - t[0], 1e-9) if len(t) > 1 else 0.0
    stance = []
    for k, side in enumerate(SIDES):
        s_hs = ev[side]["heel_strike_s"]
        for a, b in itertools.pairwise(s_hs):
            sel = (t >= a) & (t < b)
            if sel.any():
                stance.append(float(rec.foot_on_floor[sel, k].mean()))
    angles = {f"{j}_{s}": rec.qpos[:, model.jnt_qposadr[model.joint(f"{j}_{s}").id]]
              for j in WALK_JOINTS for s in SIDES}
    if "foot_angle_r" in reference:
        angles.update(foot_angles(rec.qpos, model))
    if "trunk_lean" in reference:
        angles.update(trunk_lean(rec.qpos, model))
    curves = stride_curves(t, angles, hs)
    rmse = {}
    if strides:
        for name, rows in curves.items():
            err = rows - reference[name][None]
            rmse[name] = float(np.degrees(np.sqrt((err ** 2).mean(axis=1))).mean())
    per_joint = {j: float(np.mean([rmse[f"{j}_{s}"] for s in SIDES])) for j in WALK_JOINTS
                 } if rmse else {}
    # the knees beyond straight (deg; 0 in people, whose knees do not hyperextend in gait;
    # the model's stop is at +5°, ``joints.JOINTS_3D``): mean over the walk and both knees
    knees = np.concatenate([angles[f"knee_angle_{s}"] for s in SIDES])
    hyper = float(np.degrees(np.maximum(knees, 0.0)).mean()) if len(knees) else 0.0
    feet = [rmse.pop(f"foot_angle_{s}") for s in SIDES if f"foot_angle_{s}" in rmse]
    foot = float(np.mean(feet)) if feet else None
    trunk_rmse = rmse.pop("trunk_lean", None)
    lean = (np.degrees(curves["trunk_lean"]) if strides and "trunk_lean" in curves
            else None)  # (strides, points): the complete strides' trunk
    walked = float(t[-1]) if len(t) else 0.0
    return {
        "walked_s": round(walked, 4),
        "distance_m": round(float(x[-1] - x[0]) if len(x) else 0.0, 4),
        "fell": rec.stop_reason == "fell",
        "diverged": rec.diverged,
        "duration_s": duration_s,
        "strides": strides,
        "stride_s": round(float(np.mean(np.diff(hs))), 4) if strides else None,
        "speed_m_per_s": round(float(speed), 4),
        "stance_fraction": None if not stance else round(float(np.mean(stance)), 4),
        "rmse_deg": {k: round(v, 3) for k, v in per_joint.items()},
        "rmse_deg_by_side": {k: round(v, 3) for k, v in rmse.items()},
        "foot_angle_rmse_deg": None if foot is None else round(foot, 3),
        "knee_hyperextension_deg": round(hyper, 3),
        **({} if "trunk_lean" not in reference else {
            "trunk_rmse_deg": None if trunk_rmse is None else round(trunk_rmse, 3),
            "trunk_lean_deg": None if lean is None else round(float(lean.mean()), 3),
            "trunk_lean_range_deg": None if lean is None else [
                round(float(lean.min()), 3), round(float(lean.max()), 3)]}),
        "events": ev,
    }


# A steady gait after a trip (our rule; the issue asks for the number of steps until the
# gait is steady and gives none): STEADY_RUN steps in a row, each lasting within
# STEADY_TOLERANCE of the gait the person walks on in (the median of the run's last
# STEADY_TAIL steps) and advancing the pelvis at within STEADY_TOLERANCE of the speed
# before the trip. The stride-to-stride variation of healthy walking is a few per cent
# (coefficient of variation of stride time; Hausdorff 2005, J NeuroEng Rehabil 2:19):
# 15 % is several times that, a step that is walking again. The step time is the walk
# on's own, not the walk's before the trip: a person may settle into another cadence.
STEADY_TOLERANCE = 0.15
STEADY_RUN = 2
STEADY_TAIL = 4


def walk_on_steps(rec: Recording, landing_s: float | None) -> list[tuple[float, float]]:
    """The steps after the recovery step (``landing_s``): (duration s, pelvis speed m/s)
    from each heel strike of either foot to the next, as force plates would see them
    (``contact_events``); their number is ``steps_after_recovery_step``."""
    if landing_s is None or not len(rec.time_s):
        return []
    ev = contact_events(rec.time_s, rec.foot_on_floor)
    after = sorted({t for side in ev.values() for t in side["heel_strike_s"]
                    if t > landing_s + 0.02})  # both feet striking at one sample: one step
    strikes = [landing_s, *after]
    x = rec.qpos[:, 0]
    out = []
    for a, b in itertools.pairwise(strikes):
        dx = float(np.interp(b, rec.time_s, x) - np.interp(a, rec.time_s, x))
        out.append((b - a, dx / (b - a)))
    return out


def _tail_median(steps: list[tuple[float, float]], column: int, tail: int) -> float | None:
    """The median of one column of the last ``tail`` steps, None with fewer."""
    if len(steps) < tail:
        return None
    return float(np.median([step[column] for step in steps[-tail:]]))


def walk_on_step_s(steps: list[tuple[float, float]], tail: int = STEADY_TAIL) -> float | None:
    """The step time (s) of the gait walked on in: the median of the last ``tail`` steps
    (``walk_on_steps``' figures), None with fewer."""
    return _tail_median(steps, 0, tail)


def walk_on_speed(steps: list[tuple[float, float]], tail: int = STEADY_TAIL) -> float | None:
    """The pelvis speed (m/s) of the gait walked on in: the median of the last ``tail``
    steps' (``walk_on_steps``' figures), None with fewer."""
    return _tail_median(steps, 1, tail)


def steps_to_steady(steps: list[tuple[float, float]], speed_m_per_s: float,
                    tolerance: float = STEADY_TOLERANCE, run: int = STEADY_RUN,
                    tail: int = STEADY_TAIL) -> int | None:
    """How many steps after the recovery step until the gait is steady: the number of the
    first of ``run`` steps in a row (1: the first step after the recovery step) each
    within ``tolerance`` of the walked-on step time (``walk_on_step_s``) and of
    ``speed_m_per_s``, the speed before the trip (``walk_on_steps``' figures); None when
    no such run occurs or there are fewer than ``tail`` steps."""
    step_s = walk_on_step_s(steps, tail)
    if step_s is None:
        return None
    ok = [abs(d / step_s - 1.0) <= tolerance and abs(v / speed_m_per_s - 1.0) <= tolerance
          for d, v in steps]
    for i in range(len(ok) - run + 1):
        if all(ok[i:i + run]):
            return i + 1
    return None


def walk_on_heading_deg(rec: Recording, landing_s: float | None,
                        steps: list[tuple[float, float]], planar: bool,
                        tail: int = STEADY_TAIL) -> float | None:
    """The direction the pelvis travels over the walk on's last ``tail`` steps
    (``walk_on_steps``' figures), in degrees from the direction walked before the trip
    (the x axis; + to the left); None with fewer steps or on a planar body."""
    if planar or landing_s is None or len(steps) < tail:
        return None
    durations = [d for d, _v in steps]
    a = landing_s + sum(durations[:-tail])
    b = landing_s + sum(durations)
    t, q = rec.time_s, rec.qpos
    dx = float(np.interp(b, t, q[:, 0]) - np.interp(a, t, q[:, 0]))
    dy = float(np.interp(b, t, q[:, 1]) - np.interp(a, t, q[:, 1]))
    return float(np.degrees(np.arctan2(dy, dx)))


def sideways_m(rec: Recording, planar: bool) -> float | None:
    """How far the pelvis moved sideways from the trip to the end of the run (m, + to the
    left of the direction walked before the trip, the x axis); None on a planar body."""
    if planar or not len(rec.time_s):
        return None
    return float(rec.qpos[-1, 1] - np.interp(0.0, rec.time_s, rec.qpos[:, 1]))


def angular_momentum(m: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """(T, 3) whole-body angular momentum about the centre of mass (kg·m²/s, world axes;
    its y component + when the body pitches forward, x forward and z up)."""
    d = mujoco.MjData(m)
    root = m.body("pelvis").id  # the skeleton's root: its subtree is the whole body
    out = np.zeros((len(qpos), 3))
    for k in range(len(qpos)):
        d.qpos[:] = qpos[k]
        d.qvel[:] = qvel[k]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        mujoco.mj_subtreeVel(m, d)
        out[k] = d.subtree_angmom[root]
    return out


# Pijnappels, Bobbert & van Dieën 2004 (J Biomech 37:1811, abstract): twelve young adults
# tripped over an obstacle in mid-swing all gained a similar forward angular momentum
# during the foot-obstacle contact, 11.4 on average (kg·m²/s: the abstract's unit is cut
# in the copy we read; the magnitude is a whole body's)
PEOPLE_TRIP_ANGMOM_GAIN = 11.4

# the end of the trip's contact: the first time after it starts that the tripped foot has
# been off the obstacle (or the trip force zero) for this long (ours: a foot that slides
# along the box's edge loses contact for a sample or two)
CONTACT_GAP_S = 0.02


def trip_contact_s(rec: Recording, side: str, mechanism: str) -> tuple[float, float] | None:
    """(start, end) of the trip's contact (s from the trip): the tripped foot on the
    obstacle, or the trip force acting (SCA 2009 eq. 2-3); None if there was none."""
    t = rec.time_s
    if mechanism == "obstacle":
        on = rec.foot_on_obstacle[:, 0 if side == "r" else 1].astype(bool)
    else:
        on = np.any(rec.trip_force != 0.0, axis=1)
    on = on & (t >= -CONTACT_GAP_S)
    idx = np.flatnonzero(on)
    if not len(idx):
        return None
    end = idx[0]
    for k in idx[1:]:
        if t[k] - t[end] > CONTACT_GAP_S:
            break
        end = k
    return float(t[idx[0]]), float(t[end])


def trip_angular_momentum(m: mujoco.MjModel, rec: Recording, side: str, mechanism: str,
                          landing_s: float | None) -> dict | None:
    """The body's forward-pitch angular momentum about its centre of mass (kg·m²/s, + pitching
    forward) around the trip: ``at_trip``, ``gained_in_contact`` over the trip's contact
    (``trip_contact_s``; Pijnappels et al. 2004, J Biomech 37:1811, measured it over the
    foot-obstacle contact of mid-swing trips), ``contact_s`` (that contact's length),
    ``peak`` until the recovery foot lands (or 1 s), and ``at_recovery_contact``; None
    without a trip."""
    t = rec.time_s
    span = trip_contact_s(rec, side, mechanism)
    if span is None or not len(t):
        return None
    upto = max(landing_s if landing_s is not None else 1.0, span[1]) + 1e-9
    keep = t <= upto
    lp = angular_momentum(m, rec.qpos[keep], rec.qvel[keep])[:, 1]
    tk = t[keep]
    a, b = (float(np.interp(s, tk, lp)) for s in span)
    after = tk >= 0.0
    r2 = lambda v: None if v is None else round(float(v), 2)  # noqa: E731
    return {"at_trip": r2(np.interp(0.0, tk, lp)), "gained_in_contact": r2(b - a),
            "contact_s": round(span[1] - span[0], 4),
            "peak": r2(lp[after].max()) if after.any() else None,
            "at_recovery_contact": r2(None if landing_s is None
                                      else np.interp(landing_s, tk, lp))}


SUPPORT_WINDOW_S = 0.3  # the window: the first 300 ms after the trip
# (servo hinge, exertion of a negative torque, of a positive one): stumble.body.joints
_EXERTIONS = (("hip_flexion", "hip_extension", "hip_flexion"),
              ("knee_angle", "knee_flexion", "knee_extension"),
              ("ankle_angle", "ankle_plantarflexion", "ankle_dorsiflexion"))


def support_peak_moments(m: mujoco.MjModel, rec: Recording, tripped_side: str,
                         window_s: float = SUPPORT_WINDOW_S,
                         swap_s: float | None = None) -> dict | None:
    """Peak servo moments (N·m, ≥ 0) of the support limb in the first ``window_s`` after
    the trip, by exertion (hip_extension, knee_flexion, ankle_plantarflexion, ...), as
    Pijnappels et al. 2005 report them: the leg not tripped, and from ``swap_s`` (s; a
    lowering trip's leg swap, when the tripped leg takes over the support and pushes off,
    SCA 2009 §4.4) the tripped leg; None for muscles (their forces are not joint
    moments) or without actuator forces."""
    if rec.actuator_force is None or not len(rec.time_s):
        return None
    t = rec.time_s
    inside = (t >= 0.0) & (t <= window_s + 1e-9)
    swapped = t >= (np.inf if swap_s is None else swap_s - 1e-9)
    parts = ((OTHER[tripped_side], inside & ~swapped), (tripped_side, inside & swapped))
    out = {}
    for hinge, minus, plus in _EXERTIONS:
        taus = []
        for side, rows in parts:
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{hinge}_{side}")
            if i < 0 or m.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
                return None
            taus.append(rec.actuator_force[rows, i])
        tau = np.concatenate(taus)
        out[minus] = round(float(max(0.0, -tau.min(initial=0.0))), 1)
        out[plus] = round(float(max(0.0, tau.max(initial=0.0))), 1)
    return out


WALK_ON_STEPS = 4  # recovery walk_on: steps after the recovery step (issue: at least 4)


def walk_in_summary(rec: Recording, timer: TripTimer, side: str) -> dict:
    """The controller's own walk before the trip (``side`` the leg to be tripped): how
    long (s), how fast (m/s), its stride (s)."""
    t = rec.time_s
    ev = contact_events(t, rec.foot_on_floor)[side]["heel_strike_s"]
    stride = float(np.mean(np.diff(ev[-3:]))) if len(ev) >= 2 else None
    late = t >= t[-1] - 2.0 if len(t) else t
    speed = (float((rec.com[late][-1, 0] - rec.com[late][0, 0])
                   / max(t[late][-1] - t[late][0], 1e-9)) if late.sum() > 1 else None)
    r4 = lambda v: None if v is None else round(v, 4)  # noqa: E731
    return {"walked_s": r4(float(t[-1]) if len(t) else 0.0), "stride_s": r4(stride),
            "swing_s": r4(timer.trip_swing_s), "toe_off_s": r4(timer.toe_off_s),
            "speed_m_per_s": r4(speed), "fell": timer.fell_s is not None}


def trip_summary(sc: Scenario, strategy: str, log: list, rec: Recording, stop: StopRule,
                 m: mujoco.MjModel, t_trip: float, swing_before_s: float | None,
                 stride_s: float, reference: dict | None) -> dict:
    """The trip's figures, ``summary.json`` (docs/trips.md): ``log`` the controller's
    (state, start s) list, ``t_trip`` the trip instant on the walk's clock (s),
    ``swing_before_s`` how long the tripped foot had been off the floor then (s),
    ``stride_s`` the walk's stride (s), ``reference`` a recorded trip's coordinates."""
    landing = stop.landing_s
    rec_side = sc.side if strategy == "elevating" else {"r": "l", "l": "r"}[sc.side]
    durations = {"recovery_step": None, "trip_to_recovery_contact": None}
    step_length = None
    tilt = None
    if landing is not None:
        k = int(np.searchsorted(rec.time_s, landing))
        k = min(k, len(rec.time_s) - 1)
        d = posed(m, rec.qpos[k])  # (the trip set-up's scratch data)
        tilt = round(trunk_tilt_deg(m, d.xmat), 2)
        other = {"r": "l", "l": "r"}[rec_side]
        step_length = round(float(d.xpos[m.body(f"foot_{rec_side}").id, 0]
                                  - d.xpos[m.body(f"foot_{other}").id, 0]), 4)
        if strategy == "elevating" and swing_before_s is not None:
            durations["recovery_step"] = round(swing_before_s + landing, 4)
        durations["trip_to_recovery_contact"] = round(landing, 4)
    rmse = None
    if reference is not None and strategy is not None:
        sim = pitch_angles_deg(m, rec.qpos, sc.side, strategy)
        ref = table2_from_coordinates(reference, sc.side, strategy)
        rmse = {k: round(v, 3) for k, v in rmse_deg(
            sim, rec.time_s, ref, np.asarray(reference["time_s"])).items()}
    diverged = rec.diverged
    fell = stop.fell_s is not None and not diverged
    planar = int(m.jnt_type[0]) != int(mujoco.mjtJoint.mjJNT_FREE)
    steps = walk_on_steps(rec, landing)  # one pass over the contacts for both figures
    n_after = None if landing is None or not len(rec.time_s) else len(steps)
    recovered = stop.recovered_s is not None and not diverged
    if sc.recovery == "walk_on" and sc.controller not in MUSCLE_CONTROLLERS:
        # the walking on: at least WALK_ON_STEPS steps after the recovery step
        recovered = recovered and n_after is not None and n_after >= WALK_ON_STEPS
    return {
        "controller": sc.controller,
        "strategy": strategy,
        "variant": variant(rec, landing),
        "airborne_before_landing_s": airborne_before_landing_s(rec, landing),
        "recovered": recovered,
        "fell": fell,
        "diverged": diverged,
        "swing_fraction": sc.swing_fraction,
        "speed_m_per_s": sc.speed_m_per_s,
        "mechanism": sc.mechanism,
        "leg": sc.leg,
        "obstacle_height_m": sc.obstacle_height_m if sc.mechanism == "obstacle" else None,
        "trip_time_s": round(t_trip, 4),
        "states": [{"name": n, "start_s": t} for n, t in log],
        "durations_s": durations,
        "recovery_step_length_m": step_length,
        "trunk_tilt_at_recovery_contact_deg": tilt,
        "recovery_contact_s": None if landing is None else round(landing, 4),
        "fall_time_s": None if stop.fell_s is None else round(stop.fell_s, 4),
        "rmse_deg": rmse,
        "sim_time_s": round(float(rec.time_s[-1]) if len(rec.time_s) else 0.0, 4),
        "wall_time_s": round(rec.wall_time_s, 4),
        "steps": rec.steps,
        "stop_reason": (TOO_FEW_STEPS if rec.stop_reason == "recovered" and not recovered
                        and not diverged else rec.stop_reason),
        "seed": sc.seed,
        "contact": sc.contact,
        "delay_scale": sc.delay_scale,
        "delays": sc.delays,
        "strength_scale": sc.strength_scale,
        "strength_model": sc.strength_model,
        "population": sc.population,
        "support_peak_moments_nm": support_peak_moments(
            m, rec, sc.side, swap_s=next((t0 for n, t0 in log if n == "clearance"), None)
            if strategy == "lowering" else None),
        "angular_momentum_kg_m2_per_s": trip_angular_momentum(m, rec, sc.side, sc.mechanism,
                                                              landing),
        "recovery": sc.recovery,
        "steps_after_recovery_step": n_after,
        "walking_stride_s": None if stride_s is None else round(stride_s, 4),
        "walk_on_steps": [{"duration_s": round(d, 4), "speed_m_per_s": round(v, 4)}
                          for d, v in steps],
        "walk_on_step_s": (None if (w := walk_on_step_s(steps)) is None else round(w, 4)),
        "walk_on_speed_m_per_s": (None if (u := walk_on_speed(steps)) is None
                                  else round(u, 4)),
        "steps_to_steady_gait": steps_to_steady(steps, sc.speed_m_per_s),
        "walk_on_heading_deg": (None if (h := walk_on_heading_deg(rec, landing, steps, planar))
                                is None else round(h, 2)),
        "sideways_m": None if (y := sideways_m(rec, planar)) is None else round(y, 4),
    }
