"""The embedded reference gait: real human walking as a Fourier series per coordinate.

Source: OpenSim example subject01 (Delp, Loan, Hoy, Zajac, Topp, Rosen, Thelen,
Anderson, Seth; opensim-org/opensim-models, CC BY 3.0), 3D inverse kinematics of one
treadmill stride. ``scripts/fit_reference_gait.py`` fits the coefficients and the gait
events (from the measured ground reaction forces) into ``data/reference_gait.json``;
only those figures are carried over, not the data files.

Phase 0 is right heel strike; every angle is in radians with OpenSim signs.

Walking at another speed: stride length follows the preferred speed-step length
relation of human walking, step length ∝ v^0.42 (Grieve 1968; Kuo 2001, J Biomech Eng
123:264), scaled with body height and anchored at the subject's own stride; cadence
is then speed / stride length. Joint patterns keep their shape; the hip flexion
excursion is scaled so the model's stride has that length (``stumble.gait.playback``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cache
from importlib import resources

import numpy as np

from stumble.errors import InputError

SPEED_RANGE_M_PER_S = (0.7, 1.6)  # the range the issue asks for; outside it the
# step-length relation and a single reference pattern are no longer a fair description
STEP_LENGTH_EXPONENT = 0.42  # Grieve 1968; Kuo 2001: step length ∝ speed^0.42

# Arm swing (subject01 has no arm data). The arm swings with the contralateral leg:
# shoulder flexion follows the opposite hip's flexion, scaled to a peak-to-peak
# excursion of 2·SHOULDER_AMPLITUDE about SHOULDER_MEAN, elbow flexion likewise.
# Values are our choice, within the sagittal excursions reported for free-speed
# walking by Murray, Sepic & Barnard 1967 (J Bone Joint Surg 49A:272), shoulder about
# 30° and elbow about 20° peak to peak; not re-checked against the paper's tables.
SHOULDER_MEAN_DEG = -5.0
SHOULDER_AMPLITUDE_DEG = 15.0
ELBOW_MEAN_DEG = 20.0
ELBOW_AMPLITUDE_DEG = 10.0
SHOULDER_ABDUCTION_DEG = 6.0  # arms held slightly away from the body (our choice)


@dataclass(frozen=True)
class FourierSeries:
    """x(φ) = a0 + Σ_k a_k cos(2πkφ) + b_k sin(2πkφ), φ the gait-cycle phase in [0, 1)."""

    a0: float
    a: np.ndarray
    b: np.ndarray

    def __call__(self, phase: np.ndarray | float) -> np.ndarray:
        """Value at ``phase`` (any real; periodic with period 1)."""
        ph = np.asarray(phase, dtype=float)[..., None]
        k = np.arange(1, len(self.a) + 1)
        w = 2.0 * np.pi * k * ph
        return self.a0 + (np.cos(w) * self.a).sum(-1) + (np.sin(w) * self.b).sum(-1)

    def derivative(self, phase: np.ndarray | float) -> np.ndarray:
        """dx/dφ at ``phase``."""
        ph = np.asarray(phase, dtype=float)[..., None]
        k = np.arange(1, len(self.a) + 1)
        w = 2.0 * np.pi * k * ph
        return (2.0 * np.pi * k * (-np.sin(w) * self.a + np.cos(w) * self.b)).sum(-1)

    @classmethod
    def fit(cls, phase: np.ndarray, values: np.ndarray, harmonics: int) -> FourierSeries:
        """Least-squares fit of ``harmonics`` harmonics to samples at ``phase``."""
        k = np.arange(1, harmonics + 1)
        w = 2.0 * np.pi * np.asarray(phase)[:, None] * k
        basis = np.hstack([np.ones((len(phase), 1)), np.cos(w), np.sin(w)])
        coef, *_ = np.linalg.lstsq(basis, values, rcond=None)
        return cls(float(coef[0]), coef[1:harmonics + 1], coef[harmonics + 1:])


@dataclass(frozen=True)
class ReferenceGait:
    """One stride of real walking: coordinate curves, timing and gait events."""

    coordinates: dict[str, FourierSeries]
    stride_s: float
    speed_m_per_s: float
    subject_height_m: float
    events: dict[str, dict[str, float]]  # side -> {"heel_strike", "toe_off"} phase
    source: str
    metadata: dict = field(default_factory=dict)

    @property
    def stride_length_m(self) -> float:
        """The subject's stride length (speed × stride time)."""
        return self.speed_m_per_s * self.stride_s

    @property
    def stance_fraction(self) -> float:
        """Mean share of the stride each foot is on the ground (from the force plates)."""
        fr = [(ev["toe_off"] - ev["heel_strike"]) % 1.0 for ev in self.events.values()]
        return float(np.mean(fr))

    def angles(self, phase: np.ndarray | float, names: list[str] | None = None,
               hip_scale: float = 1.0) -> dict[str, np.ndarray]:
        """Coordinate values (rad) at ``phase``, arms included; hip flexion excursion × scale."""
        ph = np.asarray(phase, dtype=float)
        out = {}
        for name, series in self.coordinates.items():
            if names is not None and name not in names:
                continue
            v = series(ph)
            if name.startswith("hip_flexion") and hip_scale != 1.0:
                v = series.a0 + hip_scale * (v - series.a0)
            out[name] = v
        for side, other in (("r", "l"), ("l", "r")):
            hip = self.coordinates[f"hip_flexion_{other}"]
            u = _unit_swing(hip, ph)
            arm = {
                f"shoulder_flexion_{side}": SHOULDER_MEAN_DEG + SHOULDER_AMPLITUDE_DEG * u,
                f"elbow_flexion_{side}": ELBOW_MEAN_DEG + ELBOW_AMPLITUDE_DEG * u,
                f"shoulder_adduction_{side}": -SHOULDER_ABDUCTION_DEG + 0.0 * u,
            }
            for k, v in arm.items():
                if names is None or k in names:
                    out[k] = np.radians(v)
        return out

    def stride_length_at(self, speed_m_per_s: float, height_m: float) -> float:
        """Stride length (m) at a speed for a person of a height (Grieve 1968; Kuo 2001)."""
        check_speed(speed_m_per_s)
        ratio = speed_m_per_s / self.speed_m_per_s
        return self.stride_length_m * (height_m / self.subject_height_m) * (
            ratio ** STEP_LENGTH_EXPONENT)


def _unit_swing(hip: FourierSeries, phase: np.ndarray) -> np.ndarray:
    """The hip flexion curve rescaled to [-1, 1] over the cycle."""
    grid = np.linspace(0.0, 1.0, 201)
    g = hip(grid)
    lo, hi = g.min(), g.max()
    return 2.0 * (hip(phase) - lo) / (hi - lo) - 1.0


def check_speed(speed_m_per_s: float) -> None:
    """Raise InputError unless the speed lies in the supported walking range."""
    lo, hi = SPEED_RANGE_M_PER_S
    if not np.isfinite(speed_m_per_s) or not lo <= speed_m_per_s <= hi:
        raise InputError(f"speed {speed_m_per_s} m/s is outside the walking range {lo}-{hi} m/s")


@cache
def load_reference() -> ReferenceGait:
    """The embedded subject01 reference gait."""
    text = resources.files("stumble.gait").joinpath("data/reference_gait.json").read_text()
    raw = json.loads(text)
    coords = {name: FourierSeries(c["a0"], np.array(c["a"]), np.array(c["b"]))
              for name, c in raw["coordinates"].items()}
    return ReferenceGait(coords, raw["stride_s"], raw["speed_m_per_s"], raw["subject_height_m"],
                         raw["events"], raw["source"], raw.get("metadata", {}))
