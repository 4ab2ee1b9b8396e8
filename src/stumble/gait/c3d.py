"""Read the Plug-in Gait joint angles of a C3D file (needs the optional ``ezc3d`` package).

Vicon's Plug-in Gait (PiG) model stores its joint-angle outputs in a C3D file as POINTs
named ``LHipAngles``, ``LKneeAngles``, ``LAnkleAngles``, ``LPelvisAngles`` (and ``R...``),
each with X, Y, Z = the first, second and third angle of the joint in degrees (Vicon,
*Plug-in Gait Reference Guide*: hip flexion +, adduction +, internal rotation +; knee
flexion +; ankle dorsiflexion +; pelvis anterior tilt +). They map onto our (OpenSim
gait2392) coordinates as:

=================  ==============================================
PiG output         stumble coordinate
=================  ==============================================
?HipAngles X Y Z   hip_flexion, hip_adduction, hip_rotation (same signs)
?KneeAngles X      knee_angle = -X (OpenSim counts flexion negative)
?AnkleAngles X     ankle_angle (dorsiflexion +)
LPelvisAngles X    pelvis_tilt = -X (OpenSim's tilt is + backwards)
=================  ==============================================

Choices: the knee's varus/valgus and rotation, the foot progression and ankle Y/Z, and the
pelvic obliquity and rotation are not used (our knee has no varus DOF; PiG's pelvic
obliquity and rotation are relative to the lab's walking direction). Labels may carry a
subject prefix (``Anna:LHipAngles``). Frames that PiG marks invalid (all three values 0
or non-finite) inside the trial are interpolated, with a note; invalid frames at the ends
are cut off.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stumble.errors import InputError
from stumble.gait.readers import Motion, check_file, check_time, listed

# PiG output -> (column index, our coordinate, sign); "?" is L or R.
PIG_ANGLES: dict[str, tuple[tuple[int, str, float], ...]] = {
    "HipAngles": ((0, "hip_flexion", 1.0), (1, "hip_adduction", 1.0),
                  (2, "hip_rotation", 1.0)),
    "KneeAngles": ((0, "knee_angle", -1.0),),
    "AnkleAngles": ((0, "ankle_angle", 1.0),),
}
PIG_PELVIS = ("PelvisAngles", 0, "pelvis_tilt", -1.0)  # the left output (both are alike)
MIN_VALID_SHARE = 0.5  # a PiG output invalid in more than half of the frames is an error


def read_c3d(path: str | Path) -> Motion:
    """Plug-in Gait joint angles of a C3D file as a :class:`Motion` (rad, s).

    Raises :class:`InputError` (one line, naming the file) without ``ezc3d``, for a file
    that is not a C3D, and for a C3D without PiG joint-angle outputs (one that holds only
    markers says so).
    """
    path = Path(path)
    name = path.name
    check_file(path)
    try:
        import ezc3d
    except ImportError:
        raise InputError(f"{name}: reading C3D needs the optional ezc3d package "
                         "(pip install 'stumble[c3d]')") from None
    try:
        c3d = ezc3d.c3d(str(path))
        labels = list(c3d["parameters"]["POINT"]["LABELS"]["value"])
        rate = float(np.ravel(c3d["parameters"]["POINT"]["RATE"]["value"])[0])
        points = np.asarray(c3d["data"]["points"], dtype=float)
    except Exception as exc:  # ezc3d raises plain RuntimeError/IndexError on bad files
        raise InputError(f"{name}: not a readable C3D file ({_one_line(exc)})") from None
    if points.ndim != 3 or points.shape[1] != len(labels):
        raise InputError(f"{name}: its POINT data do not match its {len(labels)} labels")
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"{name}: POINT:RATE {rate:g} Hz is not a frame rate")
    short = {lab.split(":")[-1].strip(): i for i, lab in enumerate(labels)}
    wanted = [f"{s}{out}" for s in "LR" for out in PIG_ANGLES]
    if not any(w in short for w in wanted):
        markers = [lab for lab in short if not lab.endswith(("Angles", "Force", "Moment",
                                                            "Power"))]
        raise InputError(f"{name}: no Plug-in Gait joint angles ({', '.join(wanted[:3])}, "
                         f"...); it holds {len(markers)} markers ({listed(markers, 3)}) and "
                         "no angles: run Plug-in Gait (or OpenSim IK) on it first")
    n_frames = points.shape[2]
    columns: dict[str, np.ndarray] = {}
    valid = np.ones(n_frames, dtype=bool)
    series = []
    for side in "LR":
        for out, maps in PIG_ANGLES.items():
            if f"{side}{out}" in short:
                series.append((f"{side}{out}", maps, side.lower()))
    pelvis_label = f"L{PIG_PELVIS[0]}" if f"L{PIG_PELVIS[0]}" in short else (
        f"R{PIG_PELVIS[0]}" if f"R{PIG_PELVIS[0]}" in short else None)
    if pelvis_label:
        series.append((pelvis_label, ((PIG_PELVIS[1], PIG_PELVIS[2], PIG_PELVIS[3]),), ""))
    notes = []
    for label, maps, side in series:
        xyz = points[:3, short[label], :]
        ok = np.isfinite(xyz).all(axis=0) & (np.abs(xyz).sum(axis=0) > 0.0)
        if ok.mean() < MIN_VALID_SHARE:
            raise InputError(f"{name}: {label} is valid in only {100 * ok.mean():.0f} % of "
                             "the frames")
        valid &= ok
        for k, coord, sign in maps:
            key = f"{coord}_{side}" if side else coord
            columns[key] = (label, k, sign, ok)
    idx = np.flatnonzero(valid)
    first, last = int(idx[0]), int(idx[-1])
    if first > 0 or last < n_frames - 1:
        notes.append(f"{name}: {first} frame(s) at the start and {n_frames - 1 - last} at "
                     "the end have no valid angles; cut off")
    frames = np.arange(first, last + 1)
    out: dict[str, np.ndarray] = {}
    gaps = 0
    for key, (label, k, sign, ok) in columns.items():
        v = points[k, short[label], :].astype(float)
        good = ok[frames]
        gaps = max(gaps, int((~good).sum()))
        v = np.interp(frames, frames[good], v[frames][good])
        out[key] = np.radians(sign * v)
    if gaps:
        notes.append(f"{name}: up to {gaps} invalid frames inside the trial interpolated")
    time_s, time_notes = check_time(name, frames / rate)
    return Motion(time_s=time_s, columns=out, in_degrees_source=True, source=name,
                  notes=tuple(notes + time_notes))


def _one_line(exc: Exception) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 80 else text[:77] + "..."
