"""The 7 Hill-type muscles per leg of seed 003 §III, as MuJoCo muscle actuators.

Muscles (Murai & Yamane 2011 §III item 2): HAMS, GLU, TA, GAS, RF, VAS, SOL. Each is
``f = a · F_l(l) · F_v(v) · F_max`` (their eq. 1), which is the form of MuJoCo's muscle
gain, so each muscle is one MuJoCo ``muscle`` actuator on a fixed tendon.

Parameters: Geyer & Herr 2010 (IEEE TNSRE 18:263) for HAMS, GLU, TA, GAS, VAS and SOL,
RF from Song & Geyer 2015, as carried over in ``MUSCLES`` and ``LEVERS`` below (the
source files are H. Geyer's ``NMS_Model_MechInit.m`` and S. Song's parameter script, as
listed in shared/reference/muscles; the paper tables themselves were not read).

Choices (each a parameter or a documented constant):

- **Constant lever arms.** A fixed tendon has constant moment arms: each muscle-joint pair
  uses the source's (maximum) lever arm ``r``. Geyer's knee and ankle levers vary as
  r·cos(φ − φ_max), by at most ~25 % over the walking range.
- **Rigid tendon.** Fibre length changes by ρ·r·Δφ (Geyer's ρ lumps pennation and tendon
  compliance); the tendon itself is rigid. RF's two ρ (hip 0.3, knee 0.5) become one,
  the lever-weighted mean 0.39.
- **MuJoCo's curves.** F_l and F_v are MuJoCo's piecewise-quadratic curves
  (``force_length``, ``force_velocity`` below reproduce them exactly), with l_min/l_max
  fitted to Geyer's F_l = exp(c |(l − 1)/w|³), w = 0.56, c = ln 0.05, the eccentric
  plateau N = 1.5 and v_max from Geyer; the passive parallel element is MuJoCo's, sized
  to Geyer's F_PE at 1.34 l_opt. ``geyer_force_length`` gives Geyer's curve for
  comparison.
- **Activation** is a first-order filter of the excitation, τ = 10 ms (Geyer & Herr
  2010), with the 0.01 pre-activation floor.
- **Scaling.** Geyer's values are for a model of 80 kg and 1.80 m; F_max scales with
  body mass / 80 kg, l_opt, l_slack and lever arms with height / 1.80 m (our choice).

Joint angles: Geyer's inner angles (180° = straight hip and knee, ankle 90° = foot at a
right angle to the shank) map to our OpenSim coordinates as hip_flexion = 180° − φ_hip,
knee_angle = φ_knee − 180°, ankle_angle = 90° − φ_ankle.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

MUSCLE_NAMES = ("HAMS", "GLU", "TA", "GAS", "RF", "VAS", "SOL")  # seed 003 §III item 2
# Muscle sets of the planar body: seed 003's seven, or those seven and an iliopsoas (Geyer &
# Herr 2010's hip flexor HFL), without which RF is the only hip flexor and it also extends
# the knee (see docs/reflex.md, "Why the iliopsoas", for the evidence).
MUSCLE_SETS: dict[str, tuple[str, ...]] = {
    "seed": MUSCLE_NAMES,
    "hfl": (*MUSCLE_NAMES, "HFL"),
}
DEFAULT_MUSCLE_SET = "seed"
MODEL_MASS_KG = 80.0  # Geyer & Herr 2010 model (as we read their parameter file)
MODEL_HEIGHT_M = 1.80

# Geyer & Herr 2010 shared muscle constants (shared/reference/muscles README).
W_FL = 0.56  # width of F_l
C_FL = np.log(0.05)  # F_l is 0.05 at l = (1 ± w) l_opt
N_ECC = 1.5  # eccentric force plateau (F_v for fast lengthening)
K_CON = 5.0  # curvature of the concentric F_v
TAU_ACTIVATION_S = 0.01  # excitation-contraction coupling
PRE_ACTIVATION = 0.01  # minimum activation

# Passive elements the muscles leave out (seed 003 §IV.B): "a pair of weak spring and
# damper" at each ankle. Values are our choice: weak against the ~100 N·m of the ankle
# muscles in stance, enough to keep the light foot from flapping in swing.
ANKLE_STIFFNESS_NM_PER_RAD = 10.0
ANKLE_DAMPING_NMS_PER_RAD = 1.0
# The knee's spring-damper near its limit (seed 003 §IV.B) is the joint-limit constraint
# of every model joint (stumble.body.build.LIMIT_SOLREF), engaging at full extension.


@dataclass(frozen=True)
class Muscle:
    """One muscle: force in N, lengths in m, v_max in optimal lengths per s."""

    name: str
    f_max_n: float
    l_opt_m: float
    v_max: float
    l_slack_m: float
    rho: float  # fibre share of the MTU length change (Geyer's ρ)


# Geyer & Herr 2010 (via Geyer's NMS_Model_MechInit.m); RF: Song & Geyer 2015.
MUSCLES: dict[str, Muscle] = {
    "HAMS": Muscle("HAMS", 3000.0, 0.10, 12.0, 0.31, 0.7),
    "GLU": Muscle("GLU", 1500.0, 0.11, 12.0, 0.13, 0.5),
    "TA": Muscle("TA", 800.0, 0.06, 12.0, 0.24, 0.7),
    "GAS": Muscle("GAS", 1500.0, 0.05, 12.0, 0.40, 0.7),
    "RF": Muscle("RF", 1200.0, 0.08, 12.0, 0.35, (0.3 * 0.08 + 0.5 * 0.06) / 0.14),
    "VAS": Muscle("VAS", 6000.0, 0.08, 12.0, 0.23, 0.7),
    "SOL": Muscle("SOL", 4000.0, 0.04, 6.0, 0.26, 0.5),
    "HFL": Muscle("HFL", 2000.0, 0.11, 12.0, 0.10, 0.5),  # Geyer & Herr 2010 (iliopsoas)
}

# (muscle, joint) -> (lever arm m, Geyer reference angle deg at which l_CE = l_opt,
# sign of the action in our coordinate: +1 acts towards +angle, -1 towards -angle).
# Our coordinates: hip_flexion (+ flexion), knee_angle (+ extension, flexion negative),
# ankle_angle (+ dorsiflexion). Geyer & Herr 2010; RF Song & Geyer 2015.
LEVERS: dict[tuple[str, str], tuple[float, float, int]] = {
    ("HAMS", "hip"): (0.08, 155.0, -1),  # hip extensor
    ("HAMS", "knee"): (0.05, 180.0, -1),  # knee flexor
    ("GLU", "hip"): (0.10, 150.0, -1),  # hip extensor
    ("TA", "ankle"): (0.04, 110.0, +1),  # dorsiflexor
    ("GAS", "knee"): (0.05, 165.0, -1),  # knee flexor
    ("GAS", "ankle"): (0.05, 80.0, -1),  # plantarflexor
    ("RF", "hip"): (0.08, 170.0, +1),  # hip flexor
    ("RF", "knee"): (0.06, 125.0, +1),  # knee extensor
    ("VAS", "knee"): (0.06, 125.0, +1),  # knee extensor
    ("SOL", "ankle"): (0.05, 80.0, -1),  # plantarflexor
    ("HFL", "hip"): (0.10, 180.0, +1),  # hip flexor (Geyer & Herr 2010)
}


def geyer_to_coordinate(joint: str, phi_deg: float) -> float:
    """Geyer's inner joint angle (deg) as our coordinate (rad, OpenSim signs)."""
    if joint == "hip":
        return float(np.radians(180.0 - phi_deg))
    if joint == "knee":
        return float(np.radians(phi_deg - 180.0))
    if joint == "ankle":
        return float(np.radians(90.0 - phi_deg))
    raise KeyError(joint)


def geyer_force_length(l_norm: np.ndarray) -> np.ndarray:
    """Geyer & Herr 2010 F_l = exp(c |(l − 1)/w|³), l in optimal lengths."""
    return np.exp(C_FL * np.abs((np.asarray(l_norm) - 1.0) / W_FL) ** 3)


def geyer_force_velocity(v_norm: np.ndarray) -> np.ndarray:
    """Geyer & Herr 2010 F_v, v in v_max units (negative = shortening)."""
    v = np.asarray(v_norm, dtype=float)
    con = (1.0 + v) / (1.0 - K_CON * v)
    ecc = N_ECC + (N_ECC - 1.0) * (v - 1.0) / (7.56 * K_CON * v + 1.0)
    return np.where(v < 0.0, np.clip(con, 0.0, None), ecc)


# MuJoCo curve parameters fitted to Geyer's (see ``fit_mujoco_curves``; values rounded).
L_MIN = 0.32  # normalised length where MuJoCo's F_l reaches 0
L_MAX = 1.68
FV_MAX = N_ECC  # MuJoCo's eccentric plateau
FP_MAX = 0.74  # MuJoCo's passive force at l = (1 + l_max)/2 = 1.34 is F_P_MAX/2 · F_max,
# Geyer's F_PE = ((l − 1)/w)² F_max there is 0.37 F_max (our sizing)
LENGTH_RANGE_NORM = (0.5, 1.5)  # MuJoCo 'range': only sets the length scale (see below)


def force_length(l_norm: np.ndarray, lmin: float = L_MIN, lmax: float = L_MAX) -> np.ndarray:
    """MuJoCo's active force-length curve (mju_muscleGain): 0 at l_min and l_max, 1 at 1."""
    x = np.asarray(l_norm, dtype=float)
    a, b = 0.5 * (lmin + 1.0), 0.5 * (1.0 + lmax)
    out = np.select(
        [x <= a, x <= 1.0, x <= b],
        [0.5 * ((x - lmin) / (a - lmin)) ** 2, 1.0 - 0.5 * ((1.0 - x) / (1.0 - a)) ** 2,
         1.0 - 0.5 * ((x - 1.0) / (b - 1.0)) ** 2],
        0.5 * ((lmax - x) / (lmax - b)) ** 2)
    return np.where((x < lmin) | (x > lmax), 0.0, out)


def force_velocity(v_norm: np.ndarray, fvmax: float = FV_MAX) -> np.ndarray:
    """MuJoCo's force-velocity curve, v in v_max units (negative = shortening)."""
    v = np.asarray(v_norm, dtype=float)
    y = fvmax - 1.0
    return np.select([v <= -1.0, v <= 0.0, v <= y],
                     [0.0, (v + 1.0) ** 2, fvmax - (y - v) ** 2 / y], fvmax)


def passive_force(l_norm: np.ndarray, lmax: float = L_MAX,
                  fpmax: float = FP_MAX) -> np.ndarray:
    """MuJoCo's passive force-length curve, in units of F_max."""
    x = np.asarray(l_norm, dtype=float)
    b = 0.5 * (1.0 + lmax)
    return np.select([x <= 1.0, x <= b],
                     [0.0, 0.5 * fpmax * ((x - 1.0) / (b - 1.0)) ** 2],
                     fpmax * (0.5 + (x - b) / (b - 1.0)))


def fit_mujoco_curves() -> tuple[float, float]:
    """(l_min, l_max) of MuJoCo's F_l closest to Geyer's, least squares on 0.3-1.7."""
    from scipy.optimize import minimize_scalar

    x = np.linspace(0.3, 1.7, 281)
    target = geyer_force_length(x)
    r = minimize_scalar(lambda h: float(np.sum((force_length(x, 1 - h, 1 + h) - target) ** 2)),
                        bounds=(0.3, 0.9), method="bounded")
    return 1.0 - r.x, 1.0 + r.x


@dataclass(frozen=True)
class MuscleGeometry:
    """Where one muscle acts in a model: tendon coefficients and length scale."""

    name: str  # e.g. "SOL_r"
    muscle: Muscle
    joints: tuple[str, ...]  # model joint names, e.g. ("ankle_angle_r",)
    coef_m: tuple[float, ...]  # tendon length = Σ coef·q (m/rad); coef > 0: the muscle
    # lengthens with +q and pulls towards −q (joint torque = −coef · tension)
    l_ref_m: float  # tendon length at which l_CE = l_opt
    l0_m: float  # tendon length per optimal fibre length: l_opt / ρ
    f_max_n: float
    l_opt_m: float


_JOINT_OF = {"hip": "hip_flexion", "knee": "knee_angle", "ankle": "ankle_angle"}


def check_muscle_set(name: str) -> tuple[str, ...]:
    """The muscles of a named set; InputError if there is no such set."""
    from stumble.errors import InputError

    if name not in MUSCLE_SETS:
        raise InputError(f"muscle set {name!r} is not one of {', '.join(MUSCLE_SETS)}")
    return MUSCLE_SETS[name]


def geometry(side: str, height_m: float = MODEL_HEIGHT_M, mass_kg: float = MODEL_MASS_KG,
             names: tuple[str, ...] = MUSCLE_NAMES) -> list[MuscleGeometry]:
    """The muscles ``names`` of one leg (``side`` 'r' or 'l'), scaled to the person."""
    ls = height_m / MODEL_HEIGHT_M
    fs = mass_kg / MODEL_MASS_KG
    out = []
    for name in names:
        m = MUSCLES[name]
        joints, coef, ref = [], [], 0.0
        for (mus, joint), (r, phi_ref, action) in LEVERS.items():
            if mus != name:
                continue
            c = -action * r * ls  # acts towards -q  <=>  lengthens with +q
            joints.append(f"{_JOINT_OF[joint]}_{side}")
            coef.append(c)
            ref += c * geyer_to_coordinate(joint, phi_ref)
        out.append(MuscleGeometry(f"{name}_{side}", m, tuple(joints), tuple(coef), ref,
                                  m.l_opt_m * ls / m.rho, m.f_max_n * fs, m.l_opt_m * ls))
    return out


def add_muscles(spec: mujoco.MjSpec, height_m: float, mass_kg: float,
                names: tuple[str, ...] = MUSCLE_NAMES) -> list[MuscleGeometry]:
    """Add the muscles ``names`` of both legs (right first) as fixed tendons with MuJoCo
    muscle actuators."""
    geos = geometry("r", height_m, mass_kg, names) + geometry("l", height_m, mass_kg, names)
    r0, r1 = LENGTH_RANGE_NORM
    for g in geos:
        t = spec.add_tendon(name=f"{g.name}_tendon")
        for joint, c in zip(g.joints, g.coef_m, strict=True):
            t.wrap_joint(joint, c)
        a = spec.add_actuator(name=g.name, target=t.name, trntype=mujoco.mjtTrn.mjTRN_TENDON)
        a.set_to_muscle(timeconst=[TAU_ACTIVATION_S, TAU_ACTIVATION_S], tausmooth=0.0,
                        range=[r0, r1], force=g.f_max_n, scale=1.0, lmin=L_MIN, lmax=L_MAX,
                        vmax=g.muscle.v_max, fpmax=FP_MAX, fvmax=FV_MAX)
        # Geyer's activation is a plain first-order filter (no MuJoCo activation-level
        # dependence of the time constant): exact discretisation of τ ȧ = u − a.
        a.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
        a.dynprm = [TAU_ACTIVATION_S] + [0.0] * 9
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.ctrlrange = [PRE_ACTIVATION, 1.0]
        # MuJoCo: l_norm = range0 + (length − lengthrange0) / L0, L0 = Δlengthrange/Δrange;
        # with L0 = l_opt/ρ and l_norm = 1 at l_ref this puts l_CE = l_opt at Geyer's φ_ref.
        a.lengthrange = [g.l_ref_m + (r0 - 1.0) * g.l0_m, g.l_ref_m + (r1 - 1.0) * g.l0_m]
    return geos


def normalised_length(g: MuscleGeometry, tendon_length_m: np.ndarray) -> np.ndarray:
    """Fibre length in optimal lengths for a tendon length (rigid tendon)."""
    return 1.0 + (np.asarray(tendon_length_m) - g.l_ref_m) / g.l0_m


def normalised_velocity(g: MuscleGeometry, tendon_velocity_m_s: np.ndarray) -> np.ndarray:
    """Fibre velocity in v_max units (negative = shortening)."""
    return np.asarray(tendon_velocity_m_s) / (g.l0_m * g.muscle.v_max)


def muscle_force_n(g: MuscleGeometry, activation: np.ndarray, tendon_length_m: np.ndarray,
                   tendon_velocity_m_s: np.ndarray) -> np.ndarray:
    """Tension (N, positive pulling) of seed 003 eq. 1 plus the passive element."""
    ln = normalised_length(g, tendon_length_m)
    vn = normalised_velocity(g, tendon_velocity_m_s)
    return g.f_max_n * (np.asarray(activation) * force_length(ln) * force_velocity(vn)
                        + passive_force(ln))
