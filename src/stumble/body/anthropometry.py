"""Segment inertial parameters (de Leva 1996) scaled to a person's height, mass and sex.

Sources, carried over as figures:

- Mass fractions, centre-of-mass positions and radii of gyration: de Leva P. (1996)
  *Adjustments to Zatsiorsky-Seluyanov's segment inertia parameters*, J Biomech
  29:1223-1230, Table 4 (via BMClab ``BSP_ZdeLeva.txt``, CC BY 4.0).
- Segment lengths: de Leva (1996) Table 1, mean lengths of the reference subjects
  (male stature 1741 mm, female 1735 mm), scaled by stature.
- Body widths and heights not in de Leva: Winter D.A. (2009) *Biomechanics and Motor
  Control of Human Movement*, 4th ed., Fig. 4.1 (after Drillis & Contini 1966), as
  fractions of height H.
- Joint centre offsets of the foot and pelvis: OpenSim subject01 model (Delp et al.,
  CC BY 3.0; subject height about 1.76 m from the head-top marker), as fractions of
  the foot length or of height.

Radii of gyration are about the segment's sagittal (medio-lateral), transverse
(antero-posterior) and longitudinal axes, as a fraction of segment length. Our
segment frames (x forward, y left, z up at the zero pose) map them as: upright
segments y=sagittal, x=transverse, z=longitudinal; the foot x=longitudinal,
y=sagittal, z=transverse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stumble.errors import InputError

# de Leva 1996 Table 4: mass %, CoM % of length from the first end point (proximal
# or cranial), radius of gyration % (sagittal, transverse, longitudinal).
# name: (mass_F, mass_M, com_F, com_M, (rg_F sag, trans, long), (rg_M sag, trans, long))
_DE_LEVA = {
    "head": (6.68, 6.94, 58.94, 59.76, (33.0, 35.9, 31.8), (36.2, 37.6, 31.2)),  # VERT-MIDG
    # SUPR-XYPH, XYPH-OMPH, OMPH-MIDH
    "upper_trunk": (15.45, 15.96, 20.77, 29.99, (74.6, 50.2, 71.8), (71.6, 45.4, 65.9)),
    "middle_trunk": (14.65, 16.33, 45.12, 45.02, (43.3, 35.4, 41.5), (48.2, 38.3, 46.8)),
    "lower_trunk": (12.47, 11.17, 49.20, 61.15, (43.3, 40.2, 44.4), (61.5, 55.1, 58.7)),
    "upper_arm": (2.55, 2.71, 57.54, 57.72, (27.8, 26.0, 14.8), (28.5, 26.9, 15.8)),  # SJC-EJC
    "forearm": (1.38, 1.62, 45.59, 45.74, (26.1, 25.7, 9.4), (27.6, 26.5, 12.1)),  # EJC-WJC
    "hand": (0.56, 0.61, 74.74, 79.00, (53.1, 45.4, 33.5), (62.8, 51.3, 40.1)),  # WJC-MET3
    "thigh": (14.78, 14.16, 36.12, 40.95, (36.9, 36.4, 16.2), (32.9, 32.9, 14.9)),  # HJC-KJC
    "shank": (4.81, 4.33, 43.52, 43.95, (26.7, 26.3, 9.2), (25.1, 24.6, 10.2)),  # KJC-AJC
    "foot": (1.29, 1.37, 40.14, 44.15, (29.9, 27.9, 13.9), (25.7, 24.5, 12.4)),  # HEEL-TTIP
}

# de Leva 1996 Table 1: mean segment lengths in mm of the reference subjects (F, M).
_LENGTH_MM = {
    "head": (200.2, 203.3),
    "upper_trunk": (142.5, 170.7),
    "middle_trunk": (205.3, 215.5),
    "lower_trunk": (181.5, 145.7),
    "upper_arm": (275.1, 281.7),
    "forearm": (264.3, 268.9),
    "hand": (78.0, 86.2),
    "thigh": (368.5, 422.2),
    "shank": (432.3, 434.0),
    "foot": (228.3, 258.1),
}
_STATURE_MM = (1735.0, 1741.0)  # de Leva 1996 Table 1 reference statures (F, M)

# Winter 2009 Fig. 4.1 (Drillis & Contini 1966), fractions of height H.
ANKLE_HEIGHT_H = 0.039
FOOT_WIDTH_H = 0.055
SHOULDER_WIDTH_H = 0.259  # biacromial
SHOULDER_HEIGHT_H = 0.818
HIP_WIDTH_H = 0.191

# OpenSim subject01 model (about 1.76 m): hip joint centres 0.0856 m either side of
# the mid-line, 0.0724 m behind the pelvis origin between the ASIS; heel (calcaneus
# origin) 0.0543 m behind the ankle; metatarsophalangeal joint 0.184 m ahead of the
# heel, i.e. 0.21 and 0.73 of de Leva's 258 mm foot.
HIP_HALF_WIDTH_H = 0.0856 / 1.76
HEEL_BEHIND_ANKLE_FOOT = 0.21
MTP_FROM_HEEL_FOOT = 0.73
# Share of the de Leva foot mass in the toe segment: OpenSim gait2392 / subject01
# (toes 0.209 kg of calcaneus+toes 1.416 kg).
TOES_MASS_SHARE = 0.209 / (1.207 + 0.209)

HEIGHT_RANGE_M = (1.0, 2.3)
MASS_RANGE_KG = (20.0, 250.0)


@dataclass(frozen=True)
class Segment:
    """Inertial parameters of one rigid segment in its own frame.

    ``com_m`` is the centre of mass relative to the segment's proximal joint, and
    ``inertia_kgm2`` the principal moments about the centre of mass (x, y, z).
    """

    name: str
    mass_kg: float
    length_m: float
    com_m: np.ndarray
    inertia_kgm2: np.ndarray


def check_person(height_m: float, mass_kg: float, sex: str) -> None:
    """Raise InputError unless height, mass and sex describe a plausible adult."""
    if not np.isfinite(height_m) or not HEIGHT_RANGE_M[0] <= height_m <= HEIGHT_RANGE_M[1]:
        lo, hi = HEIGHT_RANGE_M
        raise InputError(f"height {height_m} m is outside {lo}-{hi} m")
    if not np.isfinite(mass_kg) or not MASS_RANGE_KG[0] <= mass_kg <= MASS_RANGE_KG[1]:
        raise InputError(f"mass {mass_kg} kg is outside {MASS_RANGE_KG[0]}-{MASS_RANGE_KG[1]} kg")
    if sex not in ("male", "female"):
        raise InputError(f"sex {sex!r} is not 'male' or 'female'")


def segment_length(name: str, height_m: float, sex: str) -> float:
    """Length in m of a de Leva segment for a person of the given height and sex."""
    k = 1 if sex == "male" else 0
    return _LENGTH_MM[name][k] / _STATURE_MM[k] * height_m


def _rg(name: str, sex: str) -> np.ndarray:
    k = 1 if sex == "male" else 0
    return np.asarray(_DE_LEVA[name][4 + k]) / 100.0


# The segments of the whole body (paired ones twice); de Leva's female percentages add
# to 99.99 %, so fractions are normalised to sum to exactly 1.
_WHOLE_BODY = ("head", "upper_trunk", "middle_trunk", "lower_trunk") + 2 * (
    "upper_arm", "forearm", "hand", "thigh", "shank", "foot")


def mass_fraction(name: str, sex: str) -> float:
    """Fraction of total body mass in a de Leva segment (normalised to sum to 1)."""
    k = 1 if sex == "male" else 0
    return _DE_LEVA[name][k] / sum(_DE_LEVA[n][k] for n in _WHOLE_BODY)


def _principal(name: str, mass: float, length: float, sex: str, long_axis: str) -> np.ndarray:
    sag, trans, lon = _rg(name, sex) * length
    if long_axis == "z":  # upright segment: x antero-posterior, y medio-lateral
        r = np.array([trans, sag, lon])
    else:  # foot along x
        r = np.array([lon, sag, trans])
    return mass * r**2


def segment(name: str, height_m: float, mass_kg: float, sex: str,
            direction: tuple[float, float, float]) -> Segment:
    """One de Leva segment, its CoM placed along ``direction`` from the proximal end."""
    k = 1 if sex == "male" else 0
    length = segment_length(name, height_m, sex)
    m = mass_fraction(name, sex) * mass_kg
    d = np.asarray(direction, dtype=float)
    com = d * _DE_LEVA[name][2 + k] / 100.0 * length
    long_axis = "x" if abs(d[0]) > 0.5 else "z"
    return Segment(name, m, length, com, _principal(name, m, length, sex, long_axis))


def combine(name: str, parts: list[tuple[Segment, np.ndarray]]) -> Segment:
    """Lump segments (each with its frame origin offset) into one rigid body.

    Uses the parallel-axis theorem; principal axes of all parts are assumed aligned
    with the common frame (true for the upright trunk parts).
    """
    masses = np.array([s.mass_kg for s, _ in parts])
    coms = np.array([s.com_m + off for s, off in parts])
    m = masses.sum()
    c = (masses[:, None] * coms).sum(axis=0) / m
    inertia = np.zeros(3)
    for (s, _), r in zip(parts, coms, strict=True):
        d = r - c
        inertia += s.inertia_kgm2 + s.mass_kg * (d @ d - d**2)
    length = sum(s.length_m for s, _ in parts)
    return Segment(name, float(m), float(length), c, inertia)
