"""Human joint strength: the servos' torque limits from maximal voluntary joint torque.

Anderson, Madigan & Nussbaum 2007 (J Biomech 40:3105, "Maximum voluntary joint torque
as a function of joint angle and angular velocity: model development and application to
the lower limb") measured hip, knee and ankle flexion and extension torque on an
isokinetic dynamometer in young (18–25 y), middle-aged (55–65 y) and older (> 65 y) men
and women, and fitted each exertion with

    T(θ, ω) = C1 · m g h · max(0, cos(C2 (θ − C3))) · f(ω)

    f(ω) = (2 C4 C5 + ω (C5 − 3 C4)) / (2 C4 C5 + ω (2 C5 − 4 C4))            ω ≥ 0
    f(ω) = (2 C4 C5 − ω (C5 − 3 C4)) / (2 C4 C5 − ω (2 C5 − 4 C4)) · (1 − C6 ω)  ω < 0

with θ the joint angle (rad: hip flexion, knee flexion, ankle dorsiflexion positive), ω
the angular velocity (rad/s, positive shortening the exerting muscles: concentric), m the
body mass, h the height and g = 9.81 m/s² (the torque is normalised by body weight ×
height, so a body's strength scales with m·h: the "any body" rule). C4 and C5 are the
concentric velocities at 75 % and 50 % of the isometric torque. Their Table 3 (mean
coefficients) is below, as tabulated in RBDL's ``Millard2016TorqueMuscle``
(``Anderson2007Table3Mean``; the paper's table itself was not read).

Our choices, each a field of ``Strength`` (and an argument of ``max_torque``):

- ``eccentric``: ``hold`` (default) keeps the eccentric branch at its peak beyond the
  lengthening velocity where the fitted curve peaks (the fit falls again at high
  lengthening speeds, outside the data; muscles do not weaken when stretched faster),
  ``paper`` uses the fitted curve as printed.
- ``floor``: a limit never below this fraction of the exertion's peak isometric torque
  (default 0.05), so that no servo goes limp at the edge of the fit's range.
- ``period_s``: the limits are refreshed every 10 ms (default) and held between, as
  muscle force itself follows its drive with a 10-40 ms lag; refreshing at every 2 ms
  step costs a third of the physics time.

Only the sagittal hip, knee and ankle have a dataset here; every other joint keeps
``stumble.body.build.TORQUE_LIMIT_NM`` (our choice), scaled by ``build.body_scale``.
With those fixed limits (``fixed``, the state machines' default) an age group other than young
scales each hip, knee and ankle limit by the ratio of that exertion's peak isometric
torque to the young's (``age_fixed_limits``).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from stumble.errors import InputError

G_M_PER_S2 = 9.81  # Anderson et al. 2007 normalise by body weight × height
AGES = ("young", "middle", "older")  # 18–25, 55–65, > 65 years (Anderson et al. 2007)
SEXES = ("male", "female")
MODELS = ("anderson2007", "fixed")  # "fixed": TORQUE_LIMIT_NM × build.body_scale
ECCENTRIC = ("hold", "paper")

# Anderson et al. 2007 Table 3, mean C1..C6 per (joint, exertion, sex, age):
# C1 (torque / (m g h)), C2 (1/rad), C3 (rad), C4, C5 (rad/s), C6 (s/rad).
ANDERSON_2007 = {
    ("hip", "extension", "male", "young"): (0.161, 0.958, 0.932, 1.578, 3.190, 0.242),
    ("hip", "extension", "female", "young"): (0.181, 0.697, 1.242, 1.567, 3.164, 0.164),
    ("hip", "extension", "male", "middle"): (0.171, 0.922, 1.176, 1.601, 3.236, 0.320),
    ("hip", "extension", "female", "middle"): (0.140, 0.830, 1.241, 1.444, 2.919, 0.317),
    ("hip", "extension", "male", "older"): (0.144, 0.896, 1.125, 1.561, 3.152, 0.477),
    ("hip", "extension", "female", "older"): (0.138, 0.707, 1.542, 1.613, 3.256, 0.360),
    ("hip", "flexion", "male", "young"): (0.113, 0.738, -0.214, 2.095, 4.267, 0.218),
    ("hip", "flexion", "female", "young"): (0.127, 0.650, -0.350, 2.136, 4.349, 0.156),
    ("hip", "flexion", "male", "middle"): (0.107, 0.712, -0.192, 2.038, 4.145, 0.206),
    ("hip", "flexion", "female", "middle"): (0.091, 0.812, -0.196, 2.145, 4.366, 0.186),
    ("hip", "flexion", "male", "older"): (0.101, 0.762, -0.269, 1.875, 3.819, 0.296),
    ("hip", "flexion", "female", "older"): (0.081, 0.625, -0.422, 2.084, 4.245, 0.196),
    ("knee", "extension", "male", "young"): (0.163, 1.258, 1.133, 1.517, 3.952, 0.095),
    ("knee", "extension", "female", "young"): (0.159, 1.187, 1.274, 1.393, 3.623, 0.173),
    ("knee", "extension", "male", "middle"): (0.156, 1.225, 1.173, 1.518, 3.954, 0.266),
    ("knee", "extension", "female", "middle"): (0.128, 1.286, 1.141, 1.332, 3.469, 0.233),
    ("knee", "extension", "male", "older"): (0.137, 1.310, 1.067, 1.141, 3.152, 0.386),
    ("knee", "extension", "female", "older"): (0.124, 1.347, 1.140, 1.066, 2.855, 0.464),
    ("knee", "flexion", "male", "young"): (0.087, 0.869, 0.522, 2.008, 5.233, 0.304),
    ("knee", "flexion", "female", "young"): (0.080, 0.873, 0.635, 1.698, 4.412, 0.175),
    ("knee", "flexion", "male", "middle"): (0.081, 0.986, 0.523, 1.830, 4.777, 0.230),
    ("knee", "flexion", "female", "middle"): (0.060, 0.967, 0.402, 1.693, 4.410, 0.349),
    ("knee", "flexion", "male", "older"): (0.069, 0.838, 0.437, 1.718, 4.476, 0.414),
    ("knee", "flexion", "female", "older"): (0.060, 0.897, 0.445, 1.121, 2.922, 0.389),
    ("ankle", "plantarflexion", "male", "young"): (0.095, 1.391, 0.408, 0.987, 3.558, 0.295),
    ("ankle", "plantarflexion", "female", "young"): (0.104, 1.399, 0.424, 0.862, 3.109, 0.189),
    ("ankle", "plantarflexion", "male", "middle"): (0.114, 1.444, 0.551, 0.593, 2.128, 0.350),
    ("ankle", "plantarflexion", "female", "middle"): (0.093, 1.504, 0.381, 0.860, 3.126, 0.349),
    ("ankle", "plantarflexion", "male", "older"): (0.106, 1.465, 0.498, 0.490, 1.767, 0.571),
    ("ankle", "plantarflexion", "female", "older"): (0.125, 1.299, 0.580, 0.587, 1.819, 0.348),
    ("ankle", "dorsiflexion", "male", "young"): (0.033, 1.510, -0.187, 0.699, 1.940, 0.828),
    ("ankle", "dorsiflexion", "female", "young"): (0.027, 1.079, -0.302, 0.864, 2.399, 0.771),
    ("ankle", "dorsiflexion", "male", "middle"): (0.028, 1.293, -0.284, 0.634, 1.759, 0.999),
    ("ankle", "dorsiflexion", "female", "middle"): (0.024, 1.308, -0.254, 0.596, 1.654, 1.006),
    ("ankle", "dorsiflexion", "male", "older"): (0.029, 1.419, -0.174, 0.561, 1.558, 1.198),
    ("ankle", "dorsiflexion", "female", "older"): (0.022, 1.096, -0.369, 0.458, 1.242, 1.401),
}

# Our model's hinges against the dataset's convention: (joint, exertion of a positive
# servo torque, exertion of a negative one, sign of the dataset's angle in ours).
# hip_flexion: + flexion; knee_angle: + extension (flexion is negative); ankle_angle:
# + dorsiflexion (stumble.body.joints).
HINGES = {
    "hip_flexion": ("hip", "flexion", "extension", 1.0),
    "knee_angle": ("knee", "extension", "flexion", -1.0),
    "ankle_angle": ("ankle", "dorsiflexion", "plantarflexion", 1.0),
}
PERIOD_S = 0.01  # default: the limits refreshed every 10 ms (ours; module docstring)
FLOOR = 0.05  # default: never below 5 % of the exertion's peak isometric torque (ours)
_V_GRID = np.linspace(0.0, 20.0, 2001)  # rad/s: where the eccentric branch's peak is found


def check(model: str, sex: str, age: str, eccentric: str = "hold") -> None:
    """InputError naming the first unknown strength model, sex, age group or branch."""
    if model not in MODELS:
        raise InputError(f"strength model {model!r} is not one of {', '.join(MODELS)}")
    if sex not in SEXES:
        raise InputError(f"sex {sex!r} is not male or female")
    if age not in AGES:
        raise InputError(f"age group {age!r} is not one of {', '.join(AGES)}")
    if eccentric not in ECCENTRIC:
        raise InputError(f"eccentric branch {eccentric!r} is not hold or paper")


def velocity_factor(c: np.ndarray, omega, v_hold=None) -> np.ndarray:
    """Anderson et al. 2007's torque-velocity factor f(ω) (ω rad/s, + concentric) for
    coefficient rows ``c`` (…, 6); ``v_hold`` (rad/s): lengthening faster than this is
    taken at this speed (``eccentric_peak_velocity`` for the ``hold`` branch)."""
    c4, c5, c6 = c[..., 3], c[..., 4], c[..., 5]
    w = np.asarray(omega, dtype=float)
    if v_hold is not None:
        w = np.maximum(w, -np.asarray(v_hold))
    a = 2.0 * c4 * c5
    conc = (a + w * (c5 - 3.0 * c4)) / (a + w * (2.0 * c5 - 4.0 * c4))
    ecc = (a - w * (c5 - 3.0 * c4)) / (a - w * (2.0 * c5 - 4.0 * c4)) * (1.0 - c6 * w)
    return np.maximum(np.where(w >= 0.0, conc, ecc), 0.0)


def eccentric_peak_velocity(c: np.ndarray) -> np.ndarray:
    """The lengthening speed (rad/s, 0-20) at which each row's fitted eccentric branch
    peaks."""
    c = np.atleast_2d(np.asarray(c, dtype=float))
    v = _V_GRID[:, None]
    a = 2.0 * c[:, 3] * c[:, 4]
    with np.errstate(divide="ignore", invalid="ignore"):
        f = ((a + v * (c[:, 4] - 3.0 * c[:, 3])) / (a + v * (2.0 * c[:, 4] - 4.0 * c[:, 3]))
             * (1.0 + c[:, 5] * v))
    f = np.where(np.isfinite(f) & (f > 0), f, -np.inf)
    return _V_GRID[np.argmax(f, axis=0)]


def max_torque(joint: str, exertion: str, angle_rad, velocity_rad_s, mass_kg: float,
               height_m: float, sex: str = "male", age: str = "young",
               eccentric: str = "hold", floor: float = FLOOR) -> np.ndarray:
    """Maximal voluntary torque (N·m, ≥ 0) of one exertion at the dataset's angle (rad)
    and velocity (rad/s, + concentric), Anderson et al. 2007."""
    c = np.array(ANDERSON_2007[(joint, exertion, sex, age)])
    weight_height = mass_kg * G_M_PER_S2 * height_m
    theta = np.asarray(angle_rad, dtype=float)
    shape = np.maximum(np.cos(c[1] * (theta - c[2])), 0.0)
    hold = eccentric_peak_velocity(c)[0] if eccentric == "hold" else None
    t = c[0] * weight_height * shape * velocity_factor(c, velocity_rad_s, hold)
    return np.maximum(t, floor * c[0] * weight_height)


def peak_isometric_nm(mass_kg: float, height_m: float, sex: str = "male",
                      age: str = "young") -> dict[str, float]:
    """Each exertion's largest isometric torque (N·m), "hip_extension", …, for a body."""
    check("anderson2007", sex, age)
    wh = mass_kg * G_M_PER_S2 * height_m
    return {f"{j}_{ex}": round(c[0] * wh, 1) for (j, ex, s, a), c in ANDERSON_2007.items()
            if s == sex and a == age}


def age_fixed_limits(m: mujoco.MjModel, sex: str = "male", age: str = "young") -> None:
    """Scale the fixed hip, knee and ankle torque limits of model ``m`` by Anderson et al.
    2007's ratio of each exertion's peak isometric torque in ``age`` to the young's."""
    check("anderson2007", sex, age)
    for i in range(m.nu):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or ""
        if name[:-2] not in HINGES or m.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        joint, plus, minus, _s = HINGES[name[:-2]]
        for col, ex in ((0, minus), (1, plus)):
            m.actuator_forcerange[i, col] *= (ANDERSON_2007[(joint, ex, sex, age)][0]
                                              / ANDERSON_2007[(joint, ex, sex, "young")][0])


@dataclass
class Strength:
    """Per-actuator strength of a servo body: each step's torque limits from the joint's
    angle and velocity (Anderson et al. 2007), times ``scale``."""

    ids: np.ndarray  # actuator indices
    qadr: np.ndarray
    vadr: np.ndarray
    angle_sign: np.ndarray  # the dataset's angle = sign · ours
    pos: np.ndarray  # (n, 6) coefficients of the positive-torque exertion
    neg: np.ndarray  # (n, 6) of the negative one
    weight_height: float  # m g h (N·m)
    scale: float = 1.0
    eccentric: str = "hold"
    floor: float = FLOOR
    period_s: float = PERIOD_S

    def __post_init__(self) -> None:
        # one row per exertion: the negative-torque ones first, then the positive ones
        c = np.vstack([self.neg, self.pos])
        n = len(self.ids)
        self._n = n
        self._peak = self.scale * c[:, 0] * self.weight_height
        self._c2, self._c3, self._c6 = c[:, 1], c[:, 2], c[:, 5]
        self._a = 2.0 * c[:, 3] * c[:, 4]
        self._b1, self._b2 = c[:, 4] - 3.0 * c[:, 3], 2.0 * c[:, 4] - 4.0 * c[:, 3]
        self._hold = (eccentric_peak_velocity(c) if self.eccentric == "hold"
                      else np.full(2 * n, np.inf))
        self._sense = np.concatenate([-np.ones(n), np.ones(n)])  # concentric sense
        self._sign2 = np.concatenate([self.angle_sign, self.angle_sign])
        self._q2 = np.concatenate([self.qadr, self.qadr])
        self._v2 = np.concatenate([self.vadr, self.vadr])

    @classmethod
    def for_model(cls, m: mujoco.MjModel, mass_kg: float, height_m: float,
                  sex: str = "male", age: str = "young", scale: float = 1.0,
                  eccentric: str = "hold", floor: float = FLOOR) -> Strength:
        """The strength of every hip, knee and ankle servo of model ``m``."""
        check("anderson2007", sex, age, eccentric)
        ids, qadr, vadr, sign, pos, neg = [], [], [], [], [], []
        for i in range(m.nu):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or ""
            hinge = name[:-2]
            if hinge not in HINGES or m.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
                continue
            joint, plus, minus, s = HINGES[hinge]
            j = m.actuator_trnid[i, 0]
            ids.append(i)
            qadr.append(m.jnt_qposadr[j])
            vadr.append(m.jnt_dofadr[j])
            sign.append(s)
            pos.append(ANDERSON_2007[(joint, plus, sex, age)])
            neg.append(ANDERSON_2007[(joint, minus, sex, age)])
        return cls(np.array(ids, dtype=int), np.array(qadr, dtype=int),
                   np.array(vadr, dtype=int), np.array(sign), np.array(pos).reshape(-1, 6),
                   np.array(neg).reshape(-1, 6), mass_kg * G_M_PER_S2 * height_m,
                   scale, eccentric, floor)

    def limits(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(largest negative torque ≥ 0, largest positive torque ≥ 0), N·m, per actuator
        at joint angles ``qpos`` and velocities ``qvel`` (ours)."""
        theta = self._sign2 * qpos[self._q2]
        # + concentric: moving the way the exertion's torque pushes
        w = np.maximum(self._sense * qvel[self._v2], -self._hold)
        u = np.abs(w)
        f = (self._a + u * self._b1) / (self._a + u * self._b2)
        f *= 1.0 + self._c6 * np.maximum(-w, 0.0)  # eccentric: × (1 − C6 ω)
        shape = np.cos(self._c2 * (theta - self._c3))
        t = self._peak * np.maximum(np.maximum(shape, 0.0) * np.maximum(f, 0.0), self.floor)
        return t[:self._n], t[self._n:]

    def apply(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """Write the current limits into the servos' force ranges."""
        lo, hi = self.limits(d.qpos, d.qvel)
        m.actuator_forcerange[self.ids, 0] = -lo
        m.actuator_forcerange[self.ids, 1] = hi


def scale_strength(m: mujoco.MjModel, scale: float) -> None:
    """Multiply every servo's torque limit and every muscle's F_max by ``scale``."""
    m.actuator_forcerange[:] *= scale
    muscle = m.actuator_gaintype == mujoco.mjtGain.mjGAIN_MUSCLE
    m.actuator_gainprm[muscle, 2] *= scale
    m.actuator_biasprm[muscle, 2] *= scale
